"""The GantryCrane's estimator FMU (`spurio package-estimator`, packaged as in
fmus/PlantEstimator/test_plant_estimator.py) in the FMU Compliance Checker and in OMSimulator
(FMI 2.0 and 3.0): it passes the checker, its outputs there equal fmpy's on the same inputs
bit for bit, and OMSimulator's equal them to its printing.

fmuCheck (commit c704b98, FMI Library 2.0.3) feeds discrete Real inputs wrongly: its input
reader sets every discrete Real input to the value of the *first* Real column of the input
file (`interpData[i] = *v1` instead of `v1[i]` in fmi2_update_input_interpolation), and takes
the row before a sample whose time its accumulated `t + h` falls just short of. The
estimator's inputs `u.U`, `y.x`, `y.theta` are discrete (sampled at each step), so given the
closed-loop record fmuCheck gives it the force as both measurements, and the filter fits the
crane to those (before the filters held parameters to their declared ranges, the mass's sigma
point went below 0 and the plant refused it, fmi2Error at t = 2.95 s, reproduced exactly
through fmpy with those inputs); not the FMU's doing. Hence the
runs here give fmuCheck one Real column only (the force, at the time stamps fmuCheck's sum
reaches, so that it takes each row at its own step) with both measurements marked missing
(`y.<name>.valid` = 0: the filter predicts only), and no input file at all (the start values:
U = 0, measurements 0, present: the filter corrects on them)."""

import subprocess
import sys

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu

from conftest import (FMU_DIR, FMUCHECK, OMS_RTOL, REPO, by_time, oms_system, read_csv,
                      require, spurio)

sys.path.insert(0, str(REPO / "tests" / "platforms"))
import run_estimator  # noqa: E402

STOP, STEP = run_estimator.STOP, run_estimator.STEP


@pytest.fixture(scope="module")
def estimator(tmp_path_factory):
    """The estimator FMU and the closed-loop record (20 s every 0.05 s, samples 100–111
    missing), made as the platform tests make them (tests/platforms/run_estimator.py)."""
    tmp = tmp_path_factory.mktemp("estimator")
    fmu, fmu3, _ = run_estimator.prepare_estimator(FMU_DIR, None, tmp)
    record = np.genfromtxt(tmp / "record.csv", delimiter=",", names=True)
    return {"fmu": fmu, "fmu3": fmu3, "record": tmp / "record.csv", "force": record["U"],
            "measured": np.stack([record["x"], record["theta"]], axis=1)}


def fmucheck(fmu, out, *extra):
    check = subprocess.run(
        [str(require(FMUCHECK, "see the third-party README")), "-k", "cs", "-n", "0",
         "-h", repr(STEP), "-s", repr(STOP), "-o", str(out), *map(str, extra), str(fmu)],
        capture_output=True, text=True, timeout=300)
    report = check.stdout + check.stderr
    assert check.returncode == 0, report
    assert "0 Warning(s)" in report and "0 Error(s)" in report, report
    assert "0 warning(s) and error(s)" in report, report
    return read_csv(out)


@pytest.mark.parametrize("inputs", ["force, measurements missing", "start values"])
def test_fmucheck_passes_and_equals_fmpy(estimator, inputs, workdir):
    extra, signals = [], None
    if inputs.startswith("force"):
        force = estimator["force"]
        # fmuCheck's communication points: t_{k+1} = t_k + h, summed as it does.
        times = [0.0]
        for _ in force[1:]:
            times.append(times[-1] + STEP)
        infile = workdir / "in.csv"
        infile.write_text("time,u.U,y.x.valid,y.theta.valid\n" + "".join(
            f"{t!r},{float(u)!r},0,0\n" for t, u in zip(times, force)))
        extra = ["-i", infile]
        signals = np.zeros(len(force), dtype=[("time", float), ("u.U", float),
                                              ("y.x.valid", bool), ("y.theta.valid", bool)])
        signals["time"] = np.arange(len(force)) * STEP
        signals["u.U"] = force
    names, got = fmucheck(estimator["fmu"], workdir / "fmucheck.csv", *extra)
    assert got.shape[0] == round(STOP / STEP) + 1, got.shape
    assert got[-1, 0] == pytest.approx(STOP, abs=1e-9)
    expected = simulate_fmu(str(estimator["fmu"]), stop_time=STOP, step_size=STEP,
                            output_interval=STEP, input=signals, output=names[1:])
    worst = 0.0
    for j, name in enumerate(names[1:], start=1):
        a, b = got[:, j], expected[name]
        differ = a != b
        if differ.any():
            worst = max(worst, float(np.max(np.abs(a - b)[differ]
                                            / np.maximum(np.abs(a), np.abs(b))[differ])))
    print(f"fmuCheck ({inputs}) vs fmpy: max relative difference {worst:.3g} over "
          f"{got.shape[0]} rows x {len(names) - 1} outputs")
    # fmuCheck prints 17 significant digits, which read back to the same double.
    assert worst == 0.0
    # Predicting only, θ̂ stays at the start; corrected, it has moved.
    moved = abs(got[-1, names.index("theta_hat.M")] - 1.01262)
    assert (moved < 1e-12) if inputs.startswith("force") else (moved > 0.01)


@pytest.mark.parametrize("version", [2, 3], ids=["FMI 2.0", "FMI 3.0"])
def test_omsimulator_fed_by_a_time_table_equals_fmpy(estimator, version, workdir):
    """OMSimulator runs the estimator fed by the record as a TimeTable FMU (`spurio
    package-data`, hold: outputs U, x, theta and x.valid, theta.valid, false where a sample
    is missing) in a co-simulation system, both FMUs FMI 2.0 or both FMI 3.0 (every variable
    the system connects or records is a scalar, so OMSimulator's one-value reads of FMI 3.0
    arrays do not arise: test_our_fmi3_fmus.py); x̂, θ̂ and their standard deviations equal
    fmpy's on the same record to OMSimulator's printing (%.12g, OMS_RTOL)."""
    force, measured = estimator["force"], estimator["measured"]
    spurio("package-data", estimator["record"], "--name", "Record", "--out", workdir,
           "--lib-dir", REPO / "target" / "release", "--repo", REPO)
    fmu, data = ((estimator["fmu"], workdir / "Record.fmu") if version == 2 else
                 (estimator["fmu3"], workdir / "fmi3" / "Record.fmu"))
    assert read_model_description(str(fmu)).fmiVersion == f"{version}.0"
    assert read_model_description(str(data)).fmiVersion == f"{version}.0"
    oms_system({
        "instances": [{"name": "data", "fmu": str(data), "parameters": {}},
                      {"name": "est", "fmu": str(fmu), "parameters": {}}],
        "connections": [["data.U", "est.u.U"], ["data.x", "est.y.x"],
                        ["data.theta", "est.y.theta"], ["data.x.valid", "est.y.x.valid"],
                        ["data.theta.valid", "est.y.theta.valid"]],
        "model_exchange": None, "step": STEP, "stop": STOP, "out": "oms.csv"}, cwd=workdir)
    names, rows = by_time(*read_csv(workdir / "oms.csv"), keep="first")
    present = ~np.isnan(measured[:, 0])
    assert np.array_equal(np.flatnonzero(~present), run_estimator.MISSING)
    signals = np.zeros(len(force), dtype=[("time", float), ("u.U", float), ("y.x", float),
                                          ("y.theta", float), ("y.x.valid", bool),
                                          ("y.theta.valid", bool)])
    signals["time"] = np.arange(len(force)) * STEP
    signals["u.U"] = force
    signals["y.x"] = np.where(present, measured[:, 0], 0.0)
    signals["y.theta"] = np.where(present, measured[:, 1], 0.0)
    signals["y.x.valid"] = signals["y.theta.valid"] = present
    outputs = [f"{kind}.{n}" for kind in ("x_hat", "sd") for n in ("x", "theta", "v", "omega")]
    outputs += [f"{kind}.{n}" for kind in ("theta_hat", "sd") for n in ("M", "l", "f_c")]
    expected = simulate_fmu(str(fmu), stop_time=STOP, step_size=STEP,
                            output_interval=STEP, input=signals, output=outputs)
    assert rows.shape[0] == len(expected), (rows.shape, len(expected))
    worst = 0.0
    for name in outputs:
        got, want = rows[:, names.index(f"model.root.est.{name}")], expected[name]
        worst = max(worst, float(np.max(np.abs(got - want) / np.maximum(np.abs(want), 1e-300))))
    print(f"OMSimulator vs fmpy, FMI {version}.0: max relative difference {worst:.3g} over {rows.shape[0]} rows "
          f"x {len(outputs)} outputs (x̂, θ̂, sd)")
    assert worst <= OMS_RTOL
