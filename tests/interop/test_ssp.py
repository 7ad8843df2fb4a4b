"""SSP both ways with OMSimulator, SSP 1.0 and 2.0.

- Our export of examples/systems/crane_sensor.toml runs in OMSimulator's command line (thanks
  to the exported `oms:FixedStepMaster` annotation, with `--stopTime`) and in its Python API,
  and gives what `spurio run` gives.
- SSP files written by OMSimulator's Python API (VanDerPol → Feedthrough from the Reference
  FMUs, and GantryCrane → Sensor2 of ours) run in `spurio run` and give what OMSimulator
  gives.

Timing conventions (see conftest): OMSimulator writes each communication point twice, after
the step (inputs still those set before it: what a Jacobi master records) and after the
inputs are updated (what a Gauss–Seidel master records); it prints `%.12g`. The systems run
at a step that is exact in binary, except in the timing case (step 0.1 to t = 1: OMSimulator's
last step of ~1e-15 s, in which Sensor2, sampling on its own clock, takes no sample).
"""

import pathlib
import re
import zipfile

import numpy as np
import pytest

from conftest import (
    OMS_PYTHONPATH,
    OMS_RTOL,
    REFERENCE_FMUS,
    REPO,
    by_time,
    column,
    oms_python,
    omsimulator,
    our_fmu,
    read_csv,
    require,
    spurio,
)

CRANE_SENSOR = REPO / "examples" / "systems" / "crane_sensor.toml"
VERSIONS = ["1.0", "2.0"]
# 2^-7: 256 steps to t = 2, exact in binary.
STEP = 0.0078125


def system_file(workdir, step=STEP, algorithm="jacobi", stop=2.0):
    """crane_sensor.toml with absolute FMU paths, at `step`, with `algorithm`, to `stop`."""
    text = CRANE_SENSOR.read_text()
    text = re.sub(r"(?m)^step_size = .*$", f"step_size = {step!r}", text)
    text = re.sub(r"(?m)^stop_time = .*$", f"stop_time = {stop!r}", text)
    text = re.sub(r'(?m)^algorithm = .*$', f'algorithm = "{algorithm}"', text)
    for name in ("GantryCrane", "Sensor2"):
        text = text.replace(f"../../build/fmus/{name}.fmu", str(our_fmu(name)))
    path = workdir / f"crane_sensor_{algorithm}.toml"
    path.write_text(text)
    return path


RECORDED = ["crane.x", "crane.theta", "sensor.y[1]", "sensor.y[2]"]


def assert_same(spurio_csv, oms_names, oms_rows, names=RECORDED, rtol=OMS_RTOL):
    """`spurio run`'s columns `names` equal OMSimulator's (whose names carry the system's
    prefix) at every communication point, to its printed precision."""
    s_names, s_rows = read_csv(spurio_csv)
    assert oms_rows.shape[0] == s_rows.shape[0], (oms_rows[-3:, 0], s_rows[-3:, 0])
    np.testing.assert_allclose(oms_rows[:, 0], s_rows[:, 0], rtol=OMS_RTOL, atol=1e-300)
    for name in names:
        oms_name = next((n for n in oms_names if n.endswith("." + name)), None)
        assert oms_name, f"{name} not in {oms_names}"
        np.testing.assert_allclose(
            column(oms_names, oms_rows, oms_name),
            column(s_names, s_rows, name),
            rtol=rtol,
            atol=1e-300,
            err_msg=name,
        )


def export(workdir, version, step=STEP, stop=2.0):
    ssp = workdir / f"crane_sensor_{version}.ssp"
    result = spurio(
        "ssp-export", system_file(workdir, step, stop=stop), ssp, "--ssp-version", version
    )
    assert f"OMSimulator {ssp} --stopTime {stop!r}" in result.stdout
    return ssp


@pytest.mark.parametrize("version", VERSIONS)
def test_our_ssd_follows_the_schema(version, workdir):
    from lxml import etree

    ssp = export(workdir, version)
    with zipfile.ZipFile(ssp) as z:
        ssd = etree.fromstring(z.read("SystemStructure.ssd"))
        assert sorted(z.namelist()) == [
            "SystemStructure.ssd",
            "resources/GantryCrane.fmu",
            "resources/Sensor2.fmu",
        ]
    # The SSP 2.0 schema OMSimulator ships (its `version` accepts 1.0 and 2.0).
    schema = etree.XMLSchema(
        file=str(OMS_PYTHONPATH / "OMSimulator" / "schema" / "ssp" / "SystemStructureDescription.xsd")
    )
    schema.assertValid(ssd)
    assert ssd.get("version") == version


def test_an_ssp_1_0_export_of_fmi3_types_follows_both_schemas(workdir):
    """The FMI 3.0 Reference FMU Feedthrough's Int8, UInt16 and Float32 connectors, which SSP
    1.0 does not have, are written as Integer and Real: the SSD follows the SSP 1.0 schema
    fmpy ships and OMSimulator's; a UInt64 connector refuses the export, naming the fix."""
    from lxml import etree

    feedthrough = require(REFERENCE_FMUS.parent / "fmi3" / "Feedthrough.fmu", "the Reference FMUs")
    connections = [
        "a.Int8_output -> b.Int8_input",
        "a.UInt16_output -> b.UInt16_input",
        "a.Float32_continuous_output -> b.Float32_continuous_input",
    ]

    def system(extra):
        path = workdir / "fmi3.toml"
        path.write_text(
            "stop_time = 1.0\nstep_size = 0.5\n"
            f"connections = {connections + extra!r}\n".replace("'", '"')
            + f'[[instance]]\nname = "a"\nfmu = "{feedthrough}"\n'
            + f'[[instance]]\nname = "b"\nfmu = "{feedthrough}"\n'
        )
        return path

    ssp = workdir / "fmi3.ssp"
    spurio("ssp-export", system([]), ssp, "--ssp-version", "1.0")
    with zipfile.ZipFile(ssp) as z:
        ssd = etree.fromstring(z.read("SystemStructure.ssd"))
    ns = {"ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription"}
    types = sorted(etree.QName(c[0]).localname for c in ssd.iterfind(".//ssd:Connector", ns))
    assert types == ["Integer"] * 4 + ["Real"] * 2
    import fmpy

    for xsd in (
        pathlib.Path(fmpy.__file__).parent / "ssp" / "schema" / "SystemStructureDescription.xsd",
        OMS_PYTHONPATH / "OMSimulator" / "schema" / "ssp" / "SystemStructureDescription.xsd",
    ):
        etree.XMLSchema(file=str(require(xsd, "the SSP schema"))).assertValid(ssd)

    refused = spurio(
        "ssp-export", system(["a.UInt64_output -> b.UInt64_input"]), ssp, "--ssp-version", "1.0",
        check=False,
    )
    assert refused.returncode != 0
    assert "component `a`, connector `UInt64_output`: its type UInt64" in refused.stderr
    assert "--ssp-version 2.0" in refused.stderr


@pytest.mark.parametrize("version", VERSIONS)
def test_our_ssp_runs_in_the_omsimulator_command_line(version, workdir):
    ssp = export(workdir, version)
    # No --stepSize: OMSimulator takes it from the exported oms:FixedStepMaster annotation.
    omsimulator(ssp, "--stopTime=2", "--resultFile=oms.csv", cwd=workdir)
    oms = read_csv(workdir / "oms.csv")
    jacobi = workdir / "jacobi.csv"
    spurio("run", ssp, "--out", jacobi)
    assert_same(jacobi, *by_time(*oms, keep="first"))
    # The same OMSimulator run, read after its input update, is a Gauss–Seidel run.
    gauss_seidel = workdir / "gauss_seidel.csv"
    spurio("run", system_file(workdir, algorithm="gauss-seidel"), "--out", gauss_seidel)
    assert_same(gauss_seidel, *by_time(*oms, keep="last"))


OMS_RUN = """
from OMSimulator import SSP
model = SSP({ssp!r})
instance = model.instantiate()
instance.setResultFile({out!r})
# The Python API reads the stop time of the DefaultExperiment but no step size annotation.
instance.setFixedStepSize({step!r})
instance.initialize()
instance.simulate()
instance.terminate()
instance.delete()
"""


@pytest.mark.parametrize("version", VERSIONS)
def test_our_ssp_runs_in_the_omsimulator_python_api(version, workdir):
    ssp = export(workdir, version)
    oms_python(OMS_RUN.format(ssp=str(ssp), out="oms.csv", step=STEP), cwd=workdir)
    jacobi = workdir / "jacobi.csv"
    spurio("run", ssp, "--out", jacobi)
    assert_same(jacobi, *by_time(*read_csv(workdir / "oms.csv"), keep="first"))


def test_our_ssp_where_omsimulator_takes_a_tiny_last_step(workdir):
    """Step 0.1 to t = 1: 10 × 0.1 < 1 in floating point, so OMSimulator ends with a step of
    ~1e-15 s; Sensor2 samples on its own clock (start + k·T) and takes no sample in it, so
    the run matches `spurio run` (start + n·h) to the printed precision."""
    ssp = export(workdir, "1.0", step=0.1, stop=1.0)
    omsimulator(ssp, "--stopTime=1", "--resultFile=oms.csv", cwd=workdir)
    # OMSimulator's last rows (printed at t = 1) come after its extra step; read after the
    # input update they are what a Gauss–Seidel run records at the stop time.
    gauss_seidel = workdir / "gauss_seidel.csv"
    gs = system_file(workdir, step=0.1, algorithm="gauss-seidel", stop=1.0)
    spurio("run", gs, "--out", gauss_seidel)
    assert_same(gauss_seidel, *by_time(*read_csv(workdir / "oms.csv"), keep="last"))


OMS_WRITE = """
from OMSimulator import SSP, CRef
model = SSP()
for name, path in {resources!r}:
    model.addResource(path, new_name="resources/" + name + ".fmu")
for instance, name in {components!r}:
    model.addComponent(CRef("default", instance), "resources/" + name + ".fmu")
for a, b in {connections!r}:
    model.addConnection(CRef("default", *a.split(".", 1)), CRef("default", *b.split(".", 1)))
for variable, value in {values!r}:
    model.setValue(CRef("default", *variable.split(".", 1)), value)
# A solver on the system only (not set on the components, which would make OMSimulator
# simulate them in ME mode): its stepSize is the step size spurio takes.
model.newSolver({{"name": "master", "method": "oms-ma", "stepSize": {step!r}}})
model.activeVariant.startTime = 0.0
model.activeVariant.stopTime = {stop!r}
model.export({ssp!r})
""" + OMS_RUN


def oms_written(workdir, version, resources, components, connections, values, step, stop):
    """An SSP written by OMSimulator's Python API and OMSimulator's result of it; for 1.0
    the version attributes are rewritten (the API writes 2.0 only; nothing else it writes
    differs from 1.0)."""
    ssp = workdir / "oms.ssp"
    oms_python(
        OMS_WRITE.format(
            resources=resources, components=components, connections=connections,
            values=values, step=step, stop=stop, ssp=str(ssp), out="oms.csv",
        ),
        cwd=workdir,
    )
    with zipfile.ZipFile(ssp) as z:
        entries = {n: z.read(n) for n in z.namelist()}
    ssd = entries["SystemStructure.ssd"].decode()
    assert 'version="2.0"' in ssd
    if version == "1.0":
        entries["SystemStructure.ssd"] = ssd.replace('version="2.0"', 'version="1.0"').encode()
        ssp = workdir / "oms_1.0.ssp"
        with zipfile.ZipFile(ssp, "w") as z:
            for n, data in entries.items():
                z.writestr(n, data)
    return ssp, read_csv(workdir / "oms.csv")


@pytest.mark.parametrize("version", VERSIONS)
def test_an_omsimulator_ssp_of_reference_fmus_runs_in_spurio(version, workdir):
    ssp, oms = oms_written(
        workdir,
        version,
        resources=[(n, str(REFERENCE_FMUS / f"{n}.fmu")) for n in ("VanDerPol", "Feedthrough")],
        components=[("vdp", "VanDerPol"), ("ft", "Feedthrough")],
        connections=[("vdp.x0", "ft.Float64_continuous_input")],
        values=[("vdp.mu", 1.5)],
        step=0.1,
        stop=10.0,
    )
    out = workdir / "spurio.csv"
    run = spurio("run", ssp, "--out", out)
    assert "step size 0.1 from OMSimulator's solver" in run.stderr
    assert_same(out, *by_time(*oms, keep="last"),
                names=["vdp.x0", "vdp.x1", "ft.Float64_continuous_output"])


@pytest.mark.parametrize("version", VERSIONS)
def test_an_omsimulator_ssp_of_our_fmus_runs_in_spurio(version, workdir):
    ssp, oms = oms_written(
        workdir,
        version,
        resources=[(n, str(our_fmu(n))) for n in ("GantryCrane", "Sensor2")],
        components=[("crane", "GantryCrane"), ("sensor", "Sensor2")],
        connections=[("crane.x", "sensor.u[1]"), ("crane.theta", "sensor.u[2]")],
        values=[("crane.U", 0.5), ("crane.theta0", 0.05)],
        step=STEP,
        stop=2.0,
    )
    out = workdir / "spurio.csv"
    spurio("run", ssp, "--out", out)
    # Gauss–Seidel (spurio's default) against OMSimulator after its input update.
    assert_same(out, *by_time(*oms, keep="last"))
