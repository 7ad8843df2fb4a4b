"""TimeTable.fmu and `spurio package-data` through fmpy, FMI 2.0 and 3.0: a recorded table
packaged as an FMU validates, declares its columns, units, time range and interpolation, and
its outputs equal the table at and between the sample times (hold: exactly; linear: to
rounding), missing samples held and flagged; bad tables, a missing table and times outside the
samples give their errors, naming the file, the line and the column."""

import math
import shutil
import subprocess
import zipfile

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave
from fmpy.validation import validate_fmu

from conftest import REPO, LogSink, fmu_path, make_callbacks
from table_reference import read

SPURIO = REPO / "target" / "release" / "spurio"

# A rig's record: decimal, slightly irregular sample times, a units row, missing samples
# (an empty cell, `nan`), a Boolean column.
RIG = """time,force,x,contact
s,N,[m],
0.0,0.5,0.0,true
0.1,1.25,0.01,true
0.2,,0.03,false
0.3,-2.0,nan,false
0.45,-1.5,0.045,true
0.6,0.75,0.05,true
0.7,3.0,0.07,true
"""
COLUMNS = ["force", "x", "contact"]


def table(text=RIG):
    """The table as (times, {column: values}), NaN for a missing sample, 1/0 for true/false."""
    words = {"": math.nan, "nan": math.nan, "true": 1.0, "false": 0.0}
    rows = [line.split(",") for line in text.strip().splitlines()[2:]]
    times = np.array([float(r[0]) for r in rows])
    values = {c: np.array([words[r[j + 1]] if r[j + 1] in words else float(r[j + 1])
                           for r in rows]) for j, c in enumerate(COLUMNS)}
    return times, values


def expected(t, times, u, linear):
    """The column `u` at time `t` (table_reference): (value, valid, held)."""
    value, valid, _ = read(u, times, t, linear)
    return value, valid, value


def package(tmp_path, text=RIG, interpolation="hold", name="RigData", check=True):
    assert SPURIO.is_file(), f"{SPURIO} is missing: build it with scripts/build-fmus"
    csv = tmp_path / "rig.csv"
    csv.write_text(text)
    out = tmp_path / "out"
    result = subprocess.run(
        [str(SPURIO), "package-data", str(csv), "--name", name, "--interpolation", interpolation,
         "--out", str(out), "--lib-dir", str(REPO / "target" / "release"), "--repo", str(REPO)],
        capture_output=True, text=True, timeout=300,
    )
    if check:
        assert result.returncode == 0, result.stdout + result.stderr
    return out / f"{name}.fmu", out / "fmi3" / f"{name}.fmu", result


@pytest.fixture(scope="module")
def packaged(tmp_path_factory):
    fmus = {}
    for kind in ("hold", "linear"):
        fmus[kind] = package(tmp_path_factory.mktemp(kind), interpolation=kind)[:2]
    return fmus


def test_the_bundled_fmu_validates():
    assert validate_fmu(fmu_path("TimeTable")) == []


@pytest.mark.parametrize("version", [0, 1])
def test_a_packaged_table_validates_and_declares_its_columns_and_time_range(packaged, version):
    fmu = str(packaged["hold"][version])
    assert validate_fmu(fmu) == []
    md = read_model_description(fmu)
    assert md.modelName == "RigData"
    assert md.defaultExperiment.startTime in ("0.0", "0", 0.0)
    assert float(md.defaultExperiment.stopTime) == 0.7
    units = {v.name: v.unit for v in md.modelVariables}
    assert units["force"] == "N" and units["x"] == "m" and units["force.held"] == "N"
    names = [v.name for v in md.modelVariables if v.causality != "independent"]
    assert names == ["force", "force.valid", "force.held", "x", "x.valid", "x.held",
                     "contact", "contact.valid", "contact.held", "interpolation"]
    assert "interpolation hold" in md.description and "0.7" in md.description
    with zipfile.ZipFile(fmu) as z:
        assert z.read("resources/rig.csv").decode() == RIG
        assert "interpolation = hold" in z.read("resources/variant.cfg").decode()


@pytest.mark.parametrize("version", [0, 1])
@pytest.mark.parametrize("kind", ["hold", "linear"])
def test_outputs_equal_the_table_at_and_between_samples(packaged, kind, version):
    fmu = str(packaged[kind][version])
    times, values = table()
    # Every sample time is a multiple of 0.05: steps of 0.025 land on each and between.
    h = 0.025
    r = simulate_fmu(fmu, stop_time=0.7, step_size=h, output_interval=h)
    assert len(r) == 29
    worst = 0.0
    for row in r:
        for c in COLUMNS:
            value, valid, held = expected(row["time"], times, values[c], kind == "linear")
            assert bool(row[f"{c}.valid"]) == valid, (c, row["time"])
            if kind == "hold":
                assert row[c] == value and row[f"{c}.held"] == held, (c, row["time"])
            worst = max(worst, abs(row[c] - value), abs(row[f"{c}.held"] - held))
    # Linear to rounding: a few ulps of the values (|u| ≤ 3).
    assert worst <= (0.0 if kind == "hold" else 8 * np.finfo(float).eps * 3), worst
    print(f"{kind} FMI {2 + version}: max |FMU - table| = {worst:.3g}")


def test_the_interpolation_parameter_overrides_the_packaged_one(packaged):
    times, values = table()
    r = simulate_fmu(str(packaged["hold"][0]), stop_time=0.7, step_size=0.025,
                     output_interval=0.025, start_values={"interpolation": 2})
    at = np.where(np.isclose(r["time"], 0.525))[0][0]
    assert r["force"][at] == pytest.approx(expected(0.525, times, values["force"], True)[0],
                                           rel=1e-15)
    assert r["force"][at] != -1.5


def test_times_outside_the_samples_are_errors(packaged):
    fmu = str(packaged["hold"][0])
    with pytest.raises(FMICallException):
        simulate_fmu(fmu, stop_time=0.8, step_size=0.05, output_interval=0.05)
    with pytest.raises(FMICallException):
        simulate_fmu(fmu, start_time=-0.1, stop_time=0.7, step_size=0.05)
    r = simulate_fmu(fmu, stop_time=0.7, step_size=0.1, output_interval=0.1)
    assert r["time"][-1] == pytest.approx(0.7) and r["force"][-1] == 3.0


def instantiate(fmu, tmp_path, damage=None):
    """An FMU2Slave of `fmu` unpacked into `tmp_path`, its resources damaged first by
    `damage(resources)`: (slave or None, log texts)."""
    md = read_model_description(str(fmu))
    unzipdir = extract(str(fmu), unzipdir=str(tmp_path / "unzipped"))
    if damage:
        damage(tmp_path / "unzipped" / "resources")
    slave = FMU2Slave(guid=md.guid, unzipDirectory=unzipdir,
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="rig")
    sink = LogSink()
    callbacks = make_callbacks(sink)
    try:
        slave.instantiate(callbacks=callbacks, loggingOn=True)
    except Exception:
        return None, sink.texts()
    slave._keepalive = callbacks
    return slave, sink.texts()


def test_a_missing_or_broken_table_is_refused_at_instantiation_naming_it(packaged, tmp_path):
    fmu = packaged["hold"][0]
    slave, log = instantiate(fmu, tmp_path / "a", lambda res: (res / "rig.csv").unlink())
    assert slave is None
    assert any("resources/rig.csv" in t and "No such file" in t for t in log), log
    slave, log = instantiate(
        fmu, tmp_path / "b",
        lambda res: (res / "rig.csv").write_text(RIG.replace("-1.5", "-1.5x")))
    assert slave is None
    assert any("rig.csv, line 7, column 2 (`force`): `-1.5x` is not a number" in t
               for t in log), log
    slave, log = instantiate(fmu, tmp_path / "c")
    assert slave is not None, log
    slave.freeInstance()


@pytest.mark.parametrize("text,words", [
    (RIG.replace("0.45,", "0.25,", 1).replace("0.3,", "0.35,", 1),
     "line 7, column 1 (`time`): time 0.25 does not increase (line 6 has 0.35)"),
    (RIG.replace("0.75", "zero"),
     "line 8, column 2 (`force`): `zero` is not a number"),
    (RIG.replace("time,", "t,", 1), "line 1: no `time` column"),
    (RIG.replace("force,x", "force,interpolation"),
     "column `interpolation` cannot be declared"),
])
def test_a_bad_table_is_refused_when_packaging_naming_line_and_column(tmp_path, text, words):
    fmi2, _, result = package(tmp_path, text=text, check=False)
    assert result.returncode != 0
    assert words in result.stderr, result.stderr
    assert not fmi2.exists()


def test_the_fmu_in_place_of_the_data_instance_gives_the_same_estimates(tmp_path):
    """examples/systems/rig_replay.toml (a data instance feeding a KalmanFilter, samples
    0.75–0.95 s missing) run by `spurio run` as it is and with the packaged table in place of
    the data instance: the filter's estimates are the same bit for bit, and so are `x.valid`,
    `x.held` and `x` wherever a sample is present (the FMU's `x` holds over the gap, where the
    data instance's is NaN)."""
    rig = REPO / "examples" / "systems" / "rig.csv"
    fmu, _, _ = package(tmp_path, text=rig.read_text(), name="Rig")
    kf = fmu_path("KalmanFilter")
    def system(stop, rig_instance):
        return f'''name = "rig_replay"
step_size = 0.05
{stop}
connections = ["rig.x.held -> kf.y[1]", "rig.x.valid -> kf.y_valid[1]"]
record = ["rig.x", "rig.x.valid", "rig.x.held", "kf.x_hat[1]", "kf.innovation[1]"]

[[instance]]
name = "kf"
fmu = "{kf}"
parameters = {{ "x0[1]" = 0.2, "R[1,1]" = 1e-5 }}

[[instance]]
name = "rig"
{rig_instance}
'''

    systems = {
        # the data instance: the stop time from the data (its last sample, 2 s)
        "data": system("", f'data = "{rig}"\ninterpolation = "hold"'),
        # the FMU: its default experiment says 2 s, a system names it
        "fmu": system("stop_time = 2.0", f'fmu = "{fmu}"'),
    }
    runs = {}
    for kind, text in systems.items():
        (tmp_path / f"{kind}.toml").write_text(text)
        out = tmp_path / f"{kind}.csv"
        result = subprocess.run([str(SPURIO), "run", str(tmp_path / f"{kind}.toml"), "--out",
                                 str(out)], capture_output=True, text=True, timeout=300)
        assert result.returncode == 0, result.stdout + result.stderr
        runs[kind] = np.genfromtxt(out, delimiter=",", names=True, deletechars="")
    data, fmu_run = runs["data"], runs["fmu"]
    assert len(data) == len(fmu_run) == 41
    for name in ["time", "rig.x.valid", "rig.x.held", "kf.x_hat[1]", "kf.innovation[1]"]:
        assert np.array_equal(data[name], fmu_run[name]), name
    missing = np.isnan(data["rig.x"])
    assert missing.sum() == 5
    assert np.array_equal(data["rig.x"][~missing], fmu_run["rig.x"][~missing])
    assert np.array_equal(fmu_run["rig.x"][missing], data["rig.x.held"][missing])
