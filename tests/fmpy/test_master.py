"""The spurio master against fmpy: one FMU alone (simulate_fmu), a two-FMU system exported as
SSP (fmpy.ssp.simulate_ssp, Jacobi with its documented one-step shift) and a closed loop in
Gauss–Seidel order against a hand-written fmpy loop."""

import subprocess

import numpy as np
import pytest
from fmpy import simulate_fmu
from fmpy.ssp.simulation import simulate_ssp
from fmpy.ssp.ssd import Parameter, ParameterSet

from conftest import REPO, fmu_path, init, open_slave

SPURIO = REPO / "target" / "release" / "spurio"


def spurio(*args):
    result = subprocess.run([str(SPURIO), *map(str, args)], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    return result


def read_csv(path):
    return np.genfromtxt(path, delimiter=",", names=True, deletechars="")


def fmpy_crane_step(output_interval, output):
    """fmpy's run of the crane of examples/systems/crane_step.toml: 1 s under U = 1 N from
    θ₀ = 0.02 rad."""
    return simulate_fmu(
        fmu_path("GantryCrane"),
        stop_time=1.0,
        output_interval=output_interval,
        start_values={"U": 1.0, "theta0": 0.02},
        output=output,
    )


def test_one_fmu_equals_fmpy_simulate_fmu(tmp_path):
    out = tmp_path / "master.csv"
    spurio("run", REPO / "examples/systems/crane_step.toml", "--out", out)
    ours = read_csv(out)
    theirs = fmpy_crane_step(0.01, ["x", "theta", "v", "omega"])
    assert len(ours) == len(theirs) == 101
    assert np.max(np.abs(ours["time"] - theirs["time"])) < 1e-12
    for name in ["x", "theta", "v", "omega"]:
        diff = np.max(np.abs(ours["crane." + name] - theirs[name]))
        assert diff <= 1e-12, (name, diff)


def write_system(path, header, **instances):
    """Writes the system file `path`: `header`, then one instance per keyword, name=(FMU,
    inline table of parameters or None). Returns the path."""
    text = header
    for name, (fmu, parameters) in instances.items():
        text += f'\n[[instance]]\nname = "{name}"\nfmu = "{fmu_path(fmu)}"\n'
        if parameters:
            text += f"parameters = {parameters}\n"
    path.write_text(text)
    return path


CRANE_SENSOR = """
name = "crane_sensor"
stop_time = 2.0
step_size = 0.01
algorithm = "jacobi"
connections = ["crane.x -> sensor.u[1]", "crane.theta -> sensor.u[2]"]
record = ["crane.x", "crane.theta", "sensor.y[1]", "sensor.y[2]"]
"""


def test_two_fmus_equal_fmpy_ssp_after_the_jacobi_shift(tmp_path):
    system = write_system(
        tmp_path / "crane_sensor.toml", CRANE_SENSOR, crane=("GantryCrane", "{ U = 0.5 }"), sensor=("Sensor2", None)
    )
    ssp = tmp_path / "crane_sensor.ssp"
    spurio("ssp-export", system, ssp)
    out = tmp_path / "master.csv"
    spurio("run", system, "--out", out)
    ours = read_csv(out)
    # the same archive runs in the master too, with the same result
    out_ssp = tmp_path / "master_ssp.csv"
    spurio("run", ssp, "--out", out_ssp)
    assert out_ssp.read_text() == out.read_text()

    # fmpy ignores the SSD's parameter bindings: pass the same start value explicitly
    parameters = ParameterSet(parameters=[Parameter(name="crane.U", type="Real", value=0.5)])
    theirs = simulate_ssp(str(ssp), stop_time=2.0, step_size=0.01, parameter_set=parameters)
    # fmpy labels the values after the step t_k -> t_k+1 with t_k; the master records the
    # values at t_k: fmpy's row k is the master's row k + 1.
    n = len(theirs)
    assert n == 200 and len(ours) == 201
    for name in ["crane.x", "crane.theta", "sensor.y[1]", "sensor.y[2]"]:
        diff = np.max(np.abs(ours[name][1:] - theirs[name][:n]))
        assert diff <= 1e-12, (name, diff)
    assert np.max(np.abs(ours["crane.x"])) > 0.1  # something actually moved


CLOSED_LOOP = """
name = "crane_state_feedback"
stop_time = 6.0
step_size = 0.05
algorithm = "gauss-seidel"
connections = [
  "crane.x -> ctrl.x_hat[1]", "crane.theta -> ctrl.x_hat[2]",
  "crane.v -> ctrl.x_hat[3]", "crane.omega -> ctrl.x_hat[4]",
  "ctrl.u[1] -> crane.U",
]
record = ["crane.x", "crane.theta", "ctrl.u[1]"]
"""


def test_closed_loop_in_gauss_seidel_order_equals_an_fmpy_loop(tmp_path):
    system = write_system(
        tmp_path / "loop.toml", CLOSED_LOOP, crane=("GantryCrane", "{ x0 = 0.2 }"), ctrl=("StateFeedback", None)
    )
    out = tmp_path / "loop.csv"
    spurio("run", system, "--out", out)
    ours = read_csv(out)

    crane, cv, _ = open_slave("GantryCrane", "crane")
    ctrl, kv, _ = open_slave("StateFeedback", "ctrl")
    crane.setReal([cv["x0"]], [0.2])
    for s in (crane, ctrl):
        init(s)
    states = [cv[n] for n in ["x", "theta", "v", "omega"]]
    xs = [kv[f"x_hat[{i}]"] for i in range(1, 5)]
    rows = []
    for k in range(121):
        t = k * 0.05
        y = crane.getReal(states)
        ctrl.setReal(xs, y)
        u = ctrl.getReal([kv["u[1]"]])[0]
        crane.setReal([cv["U"]], [u])
        rows.append((y[0], y[1], u))
        if k < 120:
            crane.doStep(t, 0.05)
            ctrl.doStep(t, 0.05)
    rows = np.array(rows)
    assert len(ours) == 121
    assert np.max(np.abs(ours["crane.x"] - rows[:, 0])) <= 1e-12
    assert np.max(np.abs(ours["crane.theta"] - rows[:, 1])) <= 1e-12
    assert np.max(np.abs(ours["ctrl.u[1]"] - rows[:, 2])) <= 1e-12
    assert abs(ours["crane.x"][-1]) < 5e-3


def test_sweep_rows_equal_single_runs_and_aggregate(tmp_path):
    system = write_system(
        tmp_path / "crane_sensor.toml", CRANE_SENSOR, crane=("GantryCrane", "{ U = 0.5 }"), sensor=("Sensor2", None)
    )
    table = tmp_path / "sweep.csv"
    result = spurio(
        "sweep", system, "--vary", "sensor.seed=1..8",
        "--metric", "e_res(sensor.y[1], crane.x)", "--metric", "max_abs(sensor.y[2])",
        "--threads", "2", "--out", table,
    )
    runs = read_csv(table)
    assert len(runs) == 8
    # run seed 5 alone and compute the same metrics from its CSV
    single = write_system(
        tmp_path / "seed5.toml", CRANE_SENSOR, crane=("GantryCrane", "{ U = 0.5 }"), sensor=("Sensor2", "{ seed = 5 }")
    )
    out = tmp_path / "seed5.csv"
    spurio("run", single, "--out", out)
    r = read_csv(out)
    row = runs[runs["sensor.seed"] == 5][0]
    assert abs(row["e_res(sensor.y[1];crane.x)"] - np.mean((r["sensor.y[1]"] - r["crane.x"]) ** 2)) < 1e-12
    assert abs(row["max_abs(sensor.y[2])"] - np.max(np.abs(r["sensor.y[2]"]))) < 1e-12
    # the printed table is the mean ± std of the rows
    e = runs["e_res(sensor.y[1];crane.x)"]
    assert f"{np.mean(e):.6f} ± {np.std(e, ddof=1):.6f}" in result.stdout


MULTIRATE = """
stop_time = 1.0
step_size = 0.01
record = ["crane.x", "crane.theta"]

[[instance]]
name = "crane"
fmu = "{crane}"
step_multiple = 4
parameters = {{ U = 1.0, theta0 = 0.02 }}
"""


def test_multirate_instance_steps_every_n_base_steps(tmp_path):
    system = tmp_path / "multirate.toml"
    system.write_text(MULTIRATE.format(crane=fmu_path("GantryCrane")))
    out = tmp_path / "multirate.csv"
    spurio("run", system, "--out", out)
    ours = read_csv(out)
    theirs = fmpy_crane_step(0.04, ["x", "theta"])
    assert len(ours) == 101
    # at multiples of 4 base steps the crane has just stepped 0.04 s: same as fmpy at 0.04
    assert np.max(np.abs(ours["crane.x"][::4] - theirs["x"])) <= 1e-12
    # in between its outputs are held
    for k in range(1, 4):
        assert np.array_equal(ours["crane.x"][k::4], ours["crane.x"][0:-1:4][: len(ours["crane.x"][k::4])])
