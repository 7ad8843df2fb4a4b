"""A Model Exchange plant in OMSimulator beside our Co-Simulation FMUs: the crane system of
examples/systems/crane_sensor.toml (GantryCrane pushed with U = 0.5 N from theta0 = 0.05 rad,
observed by the two-channel Sensor2), built in OMSimulator with the crane in a solver system
of its own (CVode, relative tolerance 1e-8: OMSimulator integrates the crane's Model Exchange
interface, events included — the cart reaches the rail stop at 0.5 m) inside the
co-simulation master that steps the Sensor2 FMU: the same figures as the all-Co-Simulation
system run by `spurio run`, within the solver tolerance.

OMSimulator records each communication point twice (after the step, after the input update:
see conftest); the states and the sensor's outputs are compared on the rows after the update,
at the Gauss–Seidel run of `spurio run`. The crane's CS side integrates with RK4 substeps of at
most h_max = 1 ms; CVode's relative tolerance is 1e-8.
"""

import numpy as np
import pytest

from conftest import by_time, column, oms_python, our_fmu, read_csv, spurio

STEP = 0.0078125  # 2^-7: 256 steps to t = 2, exact in binary
STOP = 2.0
# OMSimulator records a Model Exchange FMU's values where CVode's step ended, up to one CVode
# step past the communication point (the difference to the CS run scales with CVode's largest
# step: 5e-4 m at its default 1 ms, 5e-5 at 0.1 ms, 5e-6 at 10 us): the bound is that step
# times each signal's largest rate, on top of the solvers' own agreement (7e-8 m where the
# steps land on the points).
H_MAX = 1e-4
SOLVERS = 1e-6

# OMSimulator's C API through its Python module: a weakly coupled (co-simulation) root system
# with the Sensor2 FMU and, for Model Exchange, a strongly coupled system of its own holding the
# crane with CVode. (Its SSP Python API cannot place one Model Exchange FMU beside Co-Simulation
# ones: with one solver unit it makes the root system strongly coupled, where Sensor2, a
# Co-Simulation FMU, is refused.)
OMS_RUN = """
import tempfile
from OMSimulator import Capi

def ok(status, what):
    assert status.value == 0, f"{{what}}: {{status}}"

ok(Capi.setCommandLineOption("--suppressPath=true"), "options")
ok(Capi.setTempDirectory(tempfile.mkdtemp()), "temp")
ok(Capi.newModel("model"), "newModel")
ok(Capi.addSystem("model.root", 1), "root (wc)")
crane = "model.root.crane"
if {model_exchange!r}:
    ok(Capi.addSystem("model.root.ode", 2), "ode (sc)")
    ok(Capi.setSolver("model.root.ode", 3), "cvode")
    ok(Capi.setTolerance("model.root.ode", 1e-8), "tolerance")
    ok(Capi.setVariableStepSize("model.root.ode", 1e-6, 1e-12, {h_max!r}), "step sizes")
    crane = "model.root.ode.crane"
ok(Capi.addSubModel(crane, {crane_fmu!r}), "crane")
ok(Capi.addSubModel("model.root.sensor", {sensor_fmu!r}), "sensor")
ok(Capi.addConnection(crane + ".x", "model.root.sensor.u[1]"), "x")
ok(Capi.addConnection(crane + ".theta", "model.root.sensor.u[2]"), "theta")
ok(Capi.setFixedStepSize("model.root", {step!r}), "step")
ok(Capi.setResultFile("model", {out!r}), "result file")
ok(Capi.setStopTime("model", {stop!r}), "stop time")
ok(Capi.instantiate("model"), "instantiate")
ok(Capi.setReal(crane + ".U", 0.5), "U")
ok(Capi.setReal(crane + ".theta0", 0.05), "theta0")
ok(Capi.initialize("model"), "initialize")
ok(Capi.simulate("model"), "simulate")
ok(Capi.terminate("model"), "terminate")
ok(Capi.delete("model"), "delete")
"""

NAMES = ["crane.x", "crane.theta", "sensor.y[1]", "sensor.y[2]"]


def omsimulator_run(workdir, model_exchange):
    out = "oms_me.csv" if model_exchange else "oms_cs.csv"
    result = oms_python(
        OMS_RUN.format(
            model_exchange=model_exchange, crane_fmu=str(our_fmu("GantryCrane")),
            sensor_fmu=str(our_fmu("Sensor2")), step=STEP, stop=STOP, out=out, h_max=H_MAX,
        ),
        cwd=workdir,
    )
    return result, by_time(*read_csv(workdir / out), keep="last")


def oms_column(names, rows, name):
    full = next((n for n in names if n.endswith("." + name) or n == name), None)
    assert full, f"{name} not in {names}"
    return column(names, rows, full)


def test_the_model_exchange_crane_in_omsimulator_gives_the_co_simulation_figures(workdir):
    from fmpy import read_model_description

    assert read_model_description(str(our_fmu("GantryCrane"))).modelExchange is not None
    _, (names, rows) = omsimulator_run(workdir, model_exchange=True)
    _, (cs_oms_names, cs_oms_rows) = omsimulator_run(workdir, model_exchange=False)
    system = workdir / "crane_sensor.toml"
    system.write_text(
        f'stop_time = {STOP!r}\nstep_size = {STEP!r}\nalgorithm = "gauss-seidel"\n'
        'connections = ["crane.x -> sensor.u[1]", "crane.theta -> sensor.u[2]"]\n'
        f'record = {NAMES!r}\n'.replace("'", '"')
        + f'[[instance]]\nname = "crane"\nfmu = "{our_fmu("GantryCrane")}"\n'
        'parameters = { U = 0.5, theta0 = 0.05 }\n'
        f'[[instance]]\nname = "sensor"\nfmu = "{our_fmu("Sensor2")}"\n'
    )
    spurio("run", system, "--out", workdir / "cs.csv")
    cs_names, cs_rows = read_csv(workdir / "cs.csv")
    times = cs_rows[:, 0]
    t = rows[:, 0]
    assert t[-1] == pytest.approx(STOP, abs=1e-9)
    # the crane moved, swung and reached the rail stop: the comparison is not of zeros
    assert np.max(column(cs_names, cs_rows, "crane.x")) == pytest.approx(0.5, abs=1e-12)
    # OMSimulator's all-CS run is spurio's to its printed precision; its ME run is not (the
    # crane was integrated by CVode, not by its own RK4)
    cs_oms = oms_column(cs_oms_names, cs_oms_rows, "crane.theta")
    me_oms = oms_column(names, rows, "crane.theta")
    assert len(cs_oms) == len(me_oms)
    assert np.max(np.abs(cs_oms - me_oms)) > 1e-10
    worst = {}
    for name, source in zip(NAMES, ["crane.x", "crane.theta", "crane.x", "crane.theta"]):
        me = np.interp(times, t, oms_column(names, rows, name))
        cs = column(cs_names, cs_rows, name)
        rate = np.max(np.abs(np.diff(column(cs_names, cs_rows, source)) / np.diff(times)))
        worst[name] = float(np.max(np.abs(me - cs)))
        bound = SOLVERS + 1.5 * H_MAX * rate
        assert worst[name] < bound, f"{name}: {worst[name]:.3g} (bound {bound:.3g})"
    print("OMSimulator ME crane vs spurio all-CS:", worst)
