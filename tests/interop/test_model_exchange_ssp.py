"""Model Exchange plants in OMSimulator beside our Co-Simulation FMUs (issue 15).

1. The crane system of examples/systems/crane_sensor.toml (GantryCrane pushed with U = 0.5 N
   from theta0 = 0.05 rad, observed by the two-channel Sensor2), built in OMSimulator with the
   crane in a solver system of its own (CVode, relative tolerance 1e-8: OMSimulator integrates
   the crane's Model Exchange interface, events included — the cart reaches the rail stop at
   0.5 m) inside the co-simulation master that steps the Sensor2 FMU: the same figures as the
   all-Co-Simulation system run by `spurio run`, within the solver tolerance.

   OMSimulator records each communication point twice (after the step, after the input
   update: see conftest); the states and the sensor's outputs are compared on the rows after
   the update, at the Gauss–Seidel run of `spurio run`. The crane's CS side integrates with
   RK4 substeps of at most h_max = 1 ms; CVode's relative tolerance is 1e-8.

2. Each ME plant (GantryCrane, OpAmpFilter, WindGenerator) in its bundled experiment with our
   CS sources, sensors, estimators (and the crane's adaptive controller), run by OMSimulator
   once all-CS and twice with the plant in CVode (maximum step 1 ms and 0.1 ms): the
   estimators' states and parameters converge to the all-CS figures as CVode's maximum step
   shrinks (first order: the difference is where OMSimulator reads the ME plant, see below).
   The fine run is also written as an SSP file (OMSimulator's `oms_export`: the CVode system
   nested in the co-simulation root, with its solver and fixed-step master annotations) and
   run by OMSimulator's command line: the same figures as the C-API run.
"""

import numpy as np
import pytest

from conftest import (
    OMS_RTOL,
    REPO,
    by_time,
    column,
    oms_system,
    omsimulator,
    our_fmu,
    read_csv,
    spurio,
)

STEP = 0.0078125  # 2^-7: 256 steps to t = 2, exact in binary
STOP = 2.0
# OMSimulator records a Model Exchange FMU's values where CVode's step ended, up to one CVode
# step past the communication point (the difference to the CS run scales with CVode's largest
# step: 5e-4 m at its default 1 ms, 5e-5 at 0.1 ms, 5e-6 at 10 us): the bound is that step
# times each signal's largest rate, on top of the solvers' own agreement (7e-8 m where the
# steps land on the points).
H_MAX = 1e-4
SOLVERS = 1e-6

# OMSimulator's C API through its Python module (oms_system.py): a weakly coupled
# (co-simulation) root system with the CS FMUs and, for Model Exchange, a strongly coupled
# system of its own holding the plant with CVode. (Its SSP Python API cannot place one Model
# Exchange FMU beside Co-Simulation ones: with one solver unit it makes the root system
# strongly coupled, where Sensor2, a Co-Simulation FMU, is refused.)

NAMES = ["crane.x", "crane.theta", "sensor.y[1]", "sensor.y[2]"]


def omsimulator_run(workdir, model_exchange):
    out = "oms_me.csv" if model_exchange else "oms_cs.csv"
    spec = {
        "instances": [
            {
                "name": "crane",
                "fmu": str(our_fmu("GantryCrane")),
                "parameters": {"U": ["Real", 0.5], "theta0": ["Real", 0.05]},
            },
            {"name": "sensor", "fmu": str(our_fmu("Sensor2")), "parameters": {}},
        ],
        "connections": [["crane.x", "sensor.u[1]"], ["crane.theta", "sensor.u[2]"]],
        "model_exchange": "crane" if model_exchange else None,
        "rtol": 1e-8,
        "h_max": H_MAX,
        "step": STEP,
        "stop": STOP,
        "out": out,
        # straight connections into the CVode system: the initial outputs reach the sensor
        "ports": False,
    }
    return oms_system(spec, cwd=workdir), by_time(*read_csv(workdir / out), keep="last")


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


# The bundled experiments with their Model Exchange plant in OMSimulator's CVode beside our
# Co-Simulation sensors and estimators (issue 15), shortened to keep the runs to about a
# second each: the system TOML, the plant instance, the stop time, CVode's finer maximum step,
# the estimates compared (the estimators' states and parameters; the robust cleaner's Huber
# weights are left out, they are no estimate) and parameters changed from the TOML's.
EXPERIMENTS = {
    # closed loop: crane -> Sensor2 (outliers) -> DualKalmanFilter -> AdaptiveStateFeedback
    "crane_adaptive": ("crane_adaptive/dkf.toml", "crane", 10.0, 1e-4, ("est.",), {}),
    # SignalSource step -> op-amp -> Sensor (noise) -> KalmanFilter -> RLS. The experiment's
    # 12-bit ADC is switched off: it rounds the reading, so a solver-sized difference of the
    # plant moves a sample by a whole LSB (7.3e-4 V) or not at all, and the difference to the
    # CS run stops shrinking with CVode's step (measured: the filtered output differs by
    # 7e-4 V at h_max 1e-4 and 4.5e-4 V at 1e-5).
    "opamp_identification": (
        "opamp_identification/system.toml", "opamp", 5.0, 1e-4, ("kf_y.", "rls.theta"),
        {"sensor": {"adc_bits[1]": 0}},
    ),
    # random references -> generator -> transducers -> Sensor2 card -> DKF, rsKF, DKF-rsKF
    "generator_identification": (
        "generator_identification/system.toml", "generator", 20.0, 1e-4,
        ("dkf.y_hat", "cleaner.y_hat", "dkf_rskf.y_hat"), {},
    ),
}
# CVode's maximum step of the coarse run; the fine one is 10x smaller.
H_COARSE = 1e-3
# The difference to the all-CS run is the solver's (OMSimulator reads the ME plant where
# CVode's last step ended, up to h_max past the communication point, see above): it shrinks in
# proportion to h_max, 10x per decade for a smooth estimator. Required: at least 5x per decade
# of h_max, for every estimate whose difference is above OMSimulator's printed precision; and
# at the fine step, agreement to 1 % of how far each signal moved in the run (measured: 0.34 %
# at worst, the crane's least-moving parameter estimate A_hat[2,2]; 0.07 % for the op-amp's and
# 0.04 % for the generator's; first-order ratios per decade of 6.1, 9.7 and 7.1 at worst).
CONVERGENCE_PER_DECADE = 5.0
FINE_OF_RANGE = 0.01


def experiment_spec(toml, plant, stop, model_exchange, h_max, out, ssp=None, overrides=None):
    """The system of an experiment TOML for oms_system.py: our packaged FMUs, the parameters
    (those of `overrides` {instance: {variable: value}} replaced) typed by each FMU's model
    description."""
    import tomllib

    from fmpy import read_model_description

    data = tomllib.loads(toml.read_text())
    instances = []
    for instance in data["instance"]:
        fmu = our_fmu(instance["fmu"].rsplit("/", 1)[-1].removesuffix(".fmu"))
        types = {v.name: v.type for v in read_model_description(str(fmu)).modelVariables}
        values = instance.get("parameters", {}) | (overrides or {}).get(instance["name"], {})
        parameters = {k: [types[k], v] for k, v in values.items()}
        instances.append({"name": instance["name"], "fmu": str(fmu), "parameters": parameters})
    return data, {
        "instances": instances,
        "connections": [[s.strip() for s in c.split("->")] for c in data["connections"]],
        "model_exchange": plant if model_exchange else None,
        "rtol": 1e-8,
        "h_max": h_max,
        "step": data["step_size"],
        "stop": stop,
        "out": str(out),
        "ssp": str(ssp) if ssp else None,
    }


@pytest.mark.parametrize("experiment", sorted(EXPERIMENTS))
def test_a_model_exchange_plant_beside_our_estimators_gives_the_co_simulation_estimates(
    experiment, workdir
):
    toml, plant, stop, h_fine, estimates, overrides = EXPERIMENTS[experiment]
    toml = REPO / "examples" / toml
    runs = {}
    for label, model_exchange, h_max in (
        ("cs", False, H_COARSE), ("coarse", True, H_COARSE), ("fine", True, h_fine),
    ):
        out = workdir / f"{label}.csv"
        ssp = workdir / "fine.ssp" if label == "fine" else None
        data, spec = experiment_spec(
            toml, plant, stop, model_exchange, h_max, out, ssp, overrides
        )
        oms_system(spec, cwd=workdir)
        runs[label] = by_time(*read_csv(out), keep="last")
    steps = round(stop / data["step_size"])
    for label, (_, rows) in runs.items():
        assert rows.shape[0] == steps + 1, (label, rows[-2:, 0])
        assert rows[-1, 0] == pytest.approx(stop, abs=1e-9)
    # the plant's outputs the co-simulation side reads, and the estimates
    fed = sorted({a for a, _ in spec["connections"] if a.startswith(plant + ".")})
    compared = [n for n in data["record"] if n.startswith(estimates)]
    assert fed and len(compared) >= 2, (fed, compared)
    figures = {}
    for name in fed + compared:
        cs = oms_column(*runs["cs"], name)
        coarse = np.max(np.abs(oms_column(*runs["coarse"], name) - cs))
        fine = np.max(np.abs(oms_column(*runs["fine"], name) - cs))
        floor = 4 * OMS_RTOL * np.max(np.abs(cs)) + 1e-300
        decades = np.log10(H_COARSE / h_fine)
        figures[name] = (float(coarse), float(fine), float(fine / np.ptp(cs)))
        # the estimate moved, and CVode's run differs from the plant's own integrator
        assert np.ptp(cs) > 0, name
        if name in fed:
            assert coarse > 100 * floor, f"{name}: ME and CS runs agree to {coarse:.3g}"
        assert fine <= max(coarse / CONVERGENCE_PER_DECADE**decades, floor), (
            f"{name}: {coarse:.3g} at h_max {H_COARSE:g}, {fine:.3g} at {h_fine:g}"
        )
        assert fine <= FINE_OF_RANGE * np.ptp(cs), f"{name}: {fine:.3g} of {np.ptp(cs):.3g}"
    print(f"{experiment}: max |ME - CS| at h_max {H_COARSE:g}, {h_fine:g}, of range:", figures)

    # The same model as an SSP file (oms_export: the ME plant in its CVode system, the
    # fixed-step master annotation on the root) run by OMSimulator's command line: the
    # figures of the C-API run, to the printed precision.
    omsimulator(workdir / "fine.ssp", f"--stopTime={stop!r}", "--resultFile=ssp.csv", cwd=workdir)
    ssp_names, ssp_rows = by_time(*read_csv(workdir / "ssp.csv"), keep="last")
    names, rows = runs["fine"]
    assert ssp_names == names and ssp_rows.shape == rows.shape
    np.testing.assert_allclose(ssp_rows, rows, rtol=OMS_RTOL, atol=1e-300)
