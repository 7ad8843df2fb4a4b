"""Every FMI 2.0 Co-Simulation FMU of ours alone in libcosim 0.0.6 (libcosimpy, its fixed-step
algorithm) and in ecos 0.7.2 (ecospy, its fixed-step algorithm, in process and through
`proxyfmu`, out of process), on its cross-check scenario, against fmpy (engines.py says how
the scenario is applied and what tolerance "equal" means); and our SSP 1.0 export of the crane
systems (examples/systems/crane_sensor.toml, crane_step.toml) in both, against fmpy.

What the tools get wrong, pinned here (the README's interoperability section lists them):
- ecos 0.7.2's `proxyfmu` client reads each reply of the FMU's process into a buffer of 512
  bytes (src/proxyfmu/proxy_slave.cpp, `get_real`): a read of 62 or more Real variables in one
  call is cut off, and the values, and every reply after it, are garbage (zeros, or a
  segmentation fault). Through `proxyfmu` the two FMUs with more Real outputs than that
  (DkfRsKfGenerator: 115, DualKalmanFilterGenerator: 111) are compared on their first
  PROXYFMU_MAX_REALS outputs, and `test_proxyfmu_cuts_off_a_read_of_62_reals` pins the fault.
- libcosimpy 0.0.6's `time_series_real_samples` drops the last sample of a series read
  from step 0 (`test_libcosimpy_drops_the_last_sample_of_a_series_read_from_step_0`).
- ecos applies an SSD's parameter bindings only as a named parameter set chosen at
  initialization (`init(parameter_set=…)`; its command line chooses none): our export names
  each component's set after the component, so the crane's set is `crane`.
"""

import subprocess
import sys

import numpy as np
import pytest

from conftest import REPO, our_fmu, our_fmus
import engines

FMUS = our_fmus()
# The most Real variables ecos 0.7.2 reads through proxyfmu in one call (see above).
PROXYFMU_MAX_REALS = 61


def test_every_fmu_of_ours_is_run():
    assert len(FMUS) == 25, FMUS


@pytest.mark.parametrize("name", FMUS)
def test_libcosim_equals_fmpy(name):
    sc = engines.scenario(our_fmu(name))
    engines.assert_equals_fmpy(sc, engines.run_libcosim(sc), "libcosim")


@pytest.mark.parametrize("name", FMUS)
def test_ecos_equals_fmpy(name):
    sc = engines.scenario(our_fmu(name))
    engines.assert_equals_fmpy(sc, engines.run_ecos(sc), "ecos")


def test_libcosimpy_drops_the_last_sample_of_a_series_read_from_step_0():
    """libcosimpy 0.0.6's `time_series_real_samples` trims its result by the count of step
    numbers equal to 0, taken for empty slots: a series read from step 0 (after
    initialization) loses its last sample. engines.run_libcosim reads the series through
    libcosimc itself; this pins the wrapper's answer: the first n of n + 1."""
    from libcosimpy.CosimEnums import CosimVariableType
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    sc = engines.scenario(our_fmu("SignalSource"))
    steps = 10
    execution = CosimExecution.from_step_size(engines.libcosim_nanoseconds(sc.step))
    slave = execution.add_local_slave(CosimLocalSlave(fmu_path=str(sc.fmu), instance_name="m"))
    vr = {v.name.decode(): v.reference for v in execution.slave_variables(slave)}["y"]
    series = CosimObserver.create_time_series(buffer_size=steps + 1)
    execution.add_observer(series)
    assert series.start_time_series(slave, vr, CosimVariableType.REAL)
    assert execution.step(steps)
    times, numbers, values = series.time_series_real_samples(slave, vr, from_step=0,
                                                             sample_count=steps + 1)
    assert list(numbers) == list(range(steps))  # step `steps` is missing
    right = engines._libcosim_real_or_integer_samples(series, slave, vr, "Real", steps + 1)
    assert list(values) == list(right[:steps])
    assert np.array_equal(right, engines.fmpy_result(sc)["y"][: steps + 1])


INTEGRATING = ["GantryCrane", "OpAmpFilter", "WindGenerator"]


@pytest.mark.parametrize("name", INTEGRATING)
def test_an_integrating_fmu_differs_from_fmpy_only_by_the_steps_it_is_given(name):
    """The FMUs that integrate over the step (engines.INTEGRATING_RTOL) driven through
    fmpy's FMU2Slave on each tool's own communication points and steps give that tool's
    numbers bit for bit: fmpy's `simulate_fmu`, libcosim and ecos."""
    sc = engines.scenario(our_fmu(name))
    assert engines.rounding_rtol(sc) == engines.INTEGRATING_RTOL
    reals = [n for n, kind in sc.outputs.items() if kind == "Real"]
    for tool, run in [("fmpy", engines.fmpy_result), ("libcosim", engines.run_libcosim),
                      ("ecos", engines.run_ecos)]:
        driven = engines.fmpy_slave_stepped(sc, *engines.tool_steps(sc, tool))
        assert engines.worst_difference(driven, run(sc), reals)[0] == 0.0, tool
    assert engines.worst_difference(driven, engines.fmpy_result(sc), reals)[0] > 0.0


def proxy_readable(sc: engines.Scenario) -> engines.Scenario:
    """`sc` with its outputs cut to the first PROXYFMU_MAX_REALS Real ones (and every other)."""
    reals = [n for n, kind in sc.outputs.items() if kind == "Real"][:PROXYFMU_MAX_REALS]
    kept = {n: kind for n, kind in sc.outputs.items() if kind != "Real" or n in reals}
    return engines.Scenario(sc.fmu, sc.start, sc.stop, sc.step, sc.inputs, sc.boolean_inputs,
                            sc.input_rows, kept)


@pytest.mark.parametrize("name", FMUS)
def test_ecos_through_proxyfmu_equals_fmpy(name, workdir, monkeypatch):
    monkeypatch.chdir(workdir)  # proxyfmu writes logs/<instance>.txt where it is started
    sc = proxy_readable(engines.scenario(our_fmu(name)))
    engines.assert_equals_fmpy(sc, engines.run_ecos(sc, proxy=True), "ecos+proxyfmu")


PROXY_READ = """
import json, sys
sys.path.insert(0, {interop!r})
import engines
from test_libcosim_ecos import first_reals
print(json.dumps(first_reals(engines.Path({fmu!r}), {count}, proxy=True)))
"""


def first_reals(fmu, count: int, proxy: bool) -> dict[str, list[float]]:
    """The first `count` Real outputs of `fmu` over two steps of its scenario in ecos (through
    proxyfmu or not)."""
    sc = engines.scenario(fmu)
    reals = [n for n, kind in sc.outputs.items() if kind == "Real"][:count]
    sc = engines.Scenario(sc.fmu, sc.start, sc.start + 2 * sc.step, sc.step, sc.inputs,
                          sc.boolean_inputs, sc.input_rows, {n: "Real" for n in reals})
    got = engines.run_ecos(sc, proxy=proxy)
    return {n: [float(v) for v in got[n]] for n in reals}


def first_reals_in_a_process(fmu, count: int, cwd):
    """first_reals through proxyfmu in a process group of its own (the fault may end the
    process, and then its `proxyfmu` lives on, unzipping the FMU again and again: the group
    is killed after the run): the values, or None if the process died."""
    import json
    import os
    import signal

    process = subprocess.Popen(
        [sys.executable, "-c", PROXY_READ.format(interop=str(REPO / "tests" / "interop"),
                                                 fmu=str(fmu), count=count)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=cwd,
        start_new_session=True,
    )
    try:
        stdout, _ = process.communicate(timeout=120)
    finally:
        try:
            os.killpg(process.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    if process.returncode != 0:
        return None
    return json.loads(stdout.strip().splitlines()[-1])


def test_proxyfmu_cuts_off_a_read_of_62_reals(workdir, monkeypatch):
    """ecos 0.7.2 through proxyfmu: 61 Real outputs read per call come back right, 62 do not
    (the 512-byte reply buffer): every value read after a step is 0.0 (measured: every
    time), or the process dies (seen when the reads come one by one). When ecos reads them
    right, this fails: raise PROXYFMU_MAX_REALS."""
    monkeypatch.chdir(workdir)  # proxyfmu writes logs/<instance>.txt where it is started
    fmu = our_fmu("DkfRsKfGenerator")
    limit = PROXYFMU_MAX_REALS
    assert first_reals(fmu, limit, proxy=True) == first_reals(fmu, limit, proxy=False)
    right = first_reals(fmu, limit + 1, proxy=False)
    assert any(v != 0.0 for v in right["x_hat[1]"][1:])
    wrong = first_reals_in_a_process(fmu, limit + 1, workdir)
    if wrong is not None:
        assert all(v == 0.0 for values in wrong.values() for v in values[1:]), (
            "proxyfmu read 62 reals: no longer all zeros", wrong)


SYSTEMS = ["crane_sensor", "crane_step"]
# crane_sensor: what each sensor channel measures (sensor.u[i] ← crane output, y = u + noise,
# with y depending on u directly).
SENSED = {"sensor.y[1]": "crane.x", "sensor.y[2]": "crane.theta"}


def system(name, workdir):
    return engines.export_ssp_1_0(REPO / "examples" / "systems" / f"{name}.toml", workdir)


def measured_by_fmpy(run, expected):
    """What fmpy 0.3.32's SSP runner feeds each sensor channel in the step from t_k: the
    crane's output after the previous step, and 0.0 in the first (it starts every connector
    at 0.0 and sets no connection before the first step, so the outputs after initialization
    are never passed on)."""
    return {y: np.concatenate([[0.0], expected[u][:-1]]) for y, u in SENSED.items()
            if y in run.record}


def assert_ssp_equals_fmpy(tool, name, got, expected, run):
    worst, where = engines.worst_difference(got, expected, run.record)
    print(f"{tool} {name}.ssp: max relative difference to fmpy {worst:.3g} ({where})")
    assert worst <= engines.INTEGRATING_RTOL, (where, worst)
    assert np.ptp(got["crane.x"]) > 0.01  # the crane moved: its parameters were applied


@pytest.mark.parametrize("name", SYSTEMS)
def test_our_ssp_1_0_export_in_libcosim_equals_fmpy(name, workdir):
    """libcosim passes the crane's outputs after initialization to the sensor before the
    first step (fmpy passes 0.0) and records the sensor after its step, before the
    connections are updated (as fmpy does): with fmpy's first measurement corrected by the
    crane's initial output (x₀ = 0, θ₀ = 0.05), equal."""
    run = system(name, workdir)
    got, expected = engines.libcosim_ssp(run), engines.fmpy_ssp(run)
    initial = {"crane.x": run.parameters.get("crane.x0", 0.0),
               "crane.theta": run.parameters.get("crane.theta0", 0.0)}
    for y, fed in measured_by_fmpy(run, expected).items():
        libcosim_fed = np.concatenate([[initial[SENSED[y]]], expected[SENSED[y]][:-1]])
        expected[y] = expected[y] - fed + libcosim_fed
    assert_ssp_equals_fmpy("libcosim", name, got, expected, run)


@pytest.mark.parametrize("name", SYSTEMS)
def test_our_ssp_1_0_export_in_ecos_equals_fmpy(name, workdir):
    """ecos reads an output when asked, after the connections are updated: the sensor's y
    (which depends on u directly) then measures the crane's output after the step, where fmpy
    records the one it sampled; with that corrected, equal."""
    run = system(name, workdir)
    # the crane's bindings are the SSD's parameter set named `crane`
    got, expected = engines.ecos_ssp(run, parameter_set="crane"), engines.fmpy_ssp(run)
    for y, fed in measured_by_fmpy(run, expected).items():
        expected[y] = expected[y] - fed + expected[SENSED[y]]
    assert_ssp_equals_fmpy("ecos", name, got, expected, run)


def test_ecos_applies_no_ssd_parameter_binding_unless_its_set_is_named(workdir):
    """ecos 0.7.2 keeps an SSD's parameter bindings as named parameter sets and applies one
    only when `init` names it: without, the crane keeps its start values (U = 0, θ₀ = 0) and
    stays at rest."""
    run = system("crane_sensor", workdir)
    got = engines.ecos_ssp(run, parameter_set=None)
    assert np.all(got["crane.x"] == 0.0) and np.all(got["crane.theta"] == 0.0)
