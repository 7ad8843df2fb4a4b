"""LinearSystem.fmu and DistributedObserverPlant.fmu through fmpy: validation, the exact
discrete and continuous solutions without noise (to 1e-12), noise statistics, seeded
reproducibility, direct feedthrough, FMU state, bad covariances named, custom dimensions."""

import subprocess

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.validation import validate_fmu

from conftest import REPO, assert_initialization_fails_naming, fmu_path, init, open_slave, zoh

A = np.array([[0.5, 0.3], [-0.2, 0.8]])
B = np.array([[1.0], [0.5]])
C = np.array([[1.0, 2.0]])
D = np.array([[0.1]])
X0 = np.array([1.0, -0.5])


def matrix_starts(name, m):
    return {f"{name}[{i + 1},{j + 1}]": float(m[i, j]) for i in range(m.shape[0])
            for j in range(m.shape[1])}


def noise_free(a=A, b=B, c=C, d=D, x0=X0, **extra):
    start = {**matrix_starts("A", a), **matrix_starts("B", b), **matrix_starts("C", c),
             **matrix_starts("D", d), "Q[1,1]": 0.0, "Q[2,2]": 0.0, "R[1,1]": 0.0,
             "x0[1]": x0[0], "x0[2]": x0[1]}
    start.update(extra)
    return start


def run(slave, vr, u, h=0.1, t0=0.0, names=("y[1]", "y_clean[1]", "x[1]", "x[2]")):
    """Sets u[k] at each point, reads the outputs there, steps; returns the readings."""
    out = []
    t = t0
    refs = [vr[n] for n in names]
    for uk in u:
        slave.setReal([vr["u[1]"]], [uk])
        out.append(slave.getReal(refs))
        slave.doStep(t, h)
        t += h
    return np.array(out)


@pytest.mark.parametrize("name", ["LinearSystem", "DistributedObserverPlant"])
def test_validates_without_problems(name):
    assert validate_fmu(fmu_path(name)) == []


def open_configured(start, name="ls"):
    s, vr, sink = open_slave("LinearSystem", name)
    for k, v in start.items():
        if k in ("seed",):
            s.setInteger([vr[k]], [v])
        elif k == "continuous":
            s.setBoolean([vr[k]], [v])
        else:
            s.setReal([vr[k]], [v])
    init(s)
    return s, vr, sink


def test_discrete_without_noise_is_the_exact_recursion():
    u = np.sin(0.3 * np.arange(200)) + 0.5
    s, vr, _ = open_configured(noise_free())
    out = run(s, vr, u)
    s.freeInstance()
    x = X0.copy()
    worst = 0.0
    for k, uk in enumerate(u):
        y = C @ x + D[:, 0] * uk
        worst = max(worst, np.max(np.abs(out[k, 2:] - x)), abs(out[k, 0] - y[0]),
                    abs(out[k, 1] - y[0]))
        x = A @ x + B[:, 0] * uk
    print(f"discrete LinearSystem vs numpy recursion: max error {worst:.2e}")
    assert worst < 1e-12
    # and x_k = A^k x0 + sum A^(k-1-j) B u_j in closed form, at k = 50
    k = 50
    closed = np.linalg.matrix_power(A, k) @ X0 + sum(
        np.linalg.matrix_power(A, k - 1 - j) @ B[:, 0] * u[j] for j in range(k))
    assert np.max(np.abs(out[k, 2:] - closed)) < 1e-12


def test_continuous_without_noise_is_the_matrix_exponential_solution():
    ac = np.array([[0.0, 1.0], [-4.0, -0.8]])
    bc = np.array([[0.0], [2.0]])
    u, h, n = 0.7, 0.05, 200
    s, vr, _ = open_configured(noise_free(a=ac, b=bc, continuous=True))
    out = run(s, vr, [u] * n, h=h)
    s.freeInstance()
    exact = []
    for k in range(n):
        a, b = zoh(ac, bc, k * h)
        exact.append(a @ X0 + b[:, 0] * u)
    exact = np.array(exact)
    err = np.max(np.abs(out[:, 2:] - exact))
    print(f"continuous LinearSystem vs expm solution over {n} steps: max error {err:.2e}")
    assert err < 1e-12


def test_noise_statistics_of_the_default_variant():
    n = 20_000
    r = simulate_fmu(fmu_path("LinearSystem"), stop_time=n * 0.1, output_interval=0.1,
                     start_values={"seed": 3})
    x = np.stack([r["x[1]"], r["x[2]"]], axis=1)
    a = np.array([[0.9, 0.1], [0.0, 0.9]])
    w = x[1:] - x[:-1] @ a.T  # u = 0
    v = r["y[1]"] - r["y_clean[1]"]
    cov_w = np.cov(w.T)
    print(f"process noise covariance {cov_w.tolist()}, measurement variance {v.var():.5f}")
    assert np.allclose(np.diag(cov_w), 0.001, rtol=0.05)
    assert abs(cov_w[0, 1]) < 5e-5
    assert v.var() == pytest.approx(0.01, rel=0.05)
    assert np.array_equal(r["y_clean[1]"], r["x[1]"])


def test_distributed_observer_plant_is_paper_004s_system():
    md = read_model_description(fmu_path("DistributedObserverPlant"))
    start = {v.name: v.start for v in md.modelVariables}
    assert not any(v.causality == "input" for v in md.modelVariables)
    assert float(start["A[1,1]"]) == 1.005 and float(start["A[2,3]"]) == -0.08757
    assert float(start["A[3,2]"]) == 0.1248 and float(start["Q[2,2]"]) == 0.2
    assert float(start["R[1,1]"]) == 0.1 and float(start["x0[3]"]) == 1.0
    r = simulate_fmu(fmu_path("DistributedObserverPlant"), stop_time=100, output_interval=1.0)
    assert len(r) == 101 and r["x[1]"][0] == 1.0
    a = np.array([[1.005, 0, 0], [0, 0.9954, -0.08757], [0, 0.1248, 0.9945]])
    x = np.stack([r[f"x[{i}]"] for i in (1, 2, 3)], axis=1)
    w = x[1:] - x[:-1] @ a.T
    assert 0.1 < w.var() < 0.3
    assert np.array_equal(r["y_clean[2]"], r["x[2]"])


def test_same_seed_identical_other_seed_different_in_separate_instances():
    u = np.cos(0.1 * np.arange(300))
    results = []
    for name, seed in [("a", 5), ("b", 5), ("c", 6)]:
        s, vr, _ = open_configured({"seed": seed, "D[1,1]": 0.3}, name)
        results.append(run(s, vr, u))
    assert np.array_equal(results[0], results[1])
    assert not np.array_equal(results[0], results[2])


def test_feedthrough_reuses_the_measurement_noise_of_the_point():
    s, vr, _ = open_configured({"D[1,1]": 2.0})
    t = 0.0
    for k in range(50):
        s.setReal([vr["u[1]"]], [1.0])
        y1 = s.getReal([vr["y[1]"]])[0]
        s.setReal([vr["u[1]"]], [1.5])
        y2 = s.getReal([vr["y[1]"]])[0]
        assert y2 - y1 == pytest.approx(1.0, abs=1e-12)
        s.doStep(t, 0.1)
        t += 0.1
    s.freeInstance()


def test_fmu_state_replays_bit_for_bit():
    s, vr, _ = open_configured({"continuous": True, "Q[1,1]": 0.3})
    u = np.sin(0.2 * np.arange(100))
    run(s, vr, u[:40])
    state = s.getFMUstate()
    blob = s.serializeFMUstate(state)
    first = run(s, vr, u[40:], t0=4.0)
    s.setFMUstate(state)
    again = run(s, vr, u[40:], t0=4.0)
    s.setFMUstate(s.deSerializeFMUstate(blob))
    third = run(s, vr, u[40:], t0=4.0)
    assert np.array_equal(first, again) and np.array_equal(first, third)
    s.freeInstance()


@pytest.mark.parametrize(
    "start,name",
    [({"Q[1,2]": 0.5, "Q[2,1]": 0.5, "Q[1,1]": 0.1, "Q[2,2]": 0.1}, "Q"),  # indefinite
     ({"Q[1,2]": 0.01}, "Q"),  # not symmetric
     ({"R[1,1]": -0.5}, "R")],  # negative variance
)
def test_bad_covariance_is_an_error_naming_the_matrix(start, name):
    s, vr, sink = open_slave("LinearSystem")
    for k, v in start.items():
        s.setReal([vr[k]], [v])
    assert_initialization_fails_naming(s, sink, name)


def test_custom_dimensions_through_package_variant(tmp_path):
    spurio = REPO / "target" / "release" / "spurio"
    if not spurio.is_file():
        pytest.skip("target/release/spurio not built")
    subprocess.run(
        [str(spurio), "package-variant", "LinearSystem", "--set", "n=3", "--set", "m=2",
         "--set", "p=2", "--name", "LS322", "--lib-dir", str(REPO / "target" / "release"),
         "--out", str(tmp_path)],
        check=True, capture_output=True,
    )
    path = str(tmp_path / "LS322.fmu")
    assert validate_fmu(path) == []
    names = {v.name for v in read_model_description(path).modelVariables}
    assert {"u[2]", "y[2]", "x[3]", "B[3,2]", "D[2,2]", "R[2,2]"} <= names
    inputs = np.array([(0.0, 1.0, -1.0)],
                      dtype=[("time", np.float64), ("u[1]", np.float64), ("u[2]", np.float64)])
    r = simulate_fmu(path, stop_time=1.0, output_interval=0.1, input=inputs,
                     start_values={"Q[1,1]": 0.0, "Q[2,2]": 0.0, "Q[3,3]": 0.0})
    # chain x_i+ = 0.9 x_i + 0.1 x_i+1, input 1 drives x3, input 2 drives x2
    x = np.zeros(3)
    a = np.array([[0.9, 0.1, 0], [0, 0.9, 0.1], [0, 0, 0.9]])
    b = np.array([[0, 0], [0, 1.0], [1.0, 0]])
    for _ in range(10):
        x = a @ x + b @ np.array([1.0, -1.0])
    assert np.max(np.abs(np.array([r["x[1]"][-1], r["x[2]"][-1], r["x[3]"][-1]]) - x)) < 1e-12


# --- Model Exchange (continuous time): CVode against the analytic solution and Co-Simulation ---


from conftest import me_scenarios_of  # noqa: E402

me_scenarios = me_scenarios_of(__file__)
ME_SCENARIOS = me_scenarios.SCENARIOS


@pytest.mark.parametrize("scenario", [s for s in ME_SCENARIOS if s["fmu"] == "LinearSystem"
                                      and s["start_values"].get("continuous")],
                         ids=lambda s: s["name"])
def test_model_exchange_matches_the_analytic_solution(scenario):
    # (tests/fmpy/test_model_exchange.py compares every scenario with Co-Simulation)
    me = simulate_fmu(fmu_path("LinearSystem"), fmi_type="ModelExchange", solver="CVode",
                      relative_tolerance=1e-8, stop_time=scenario["stop_time"],
                      output_interval=scenario["output_interval"],
                      start_values=scenario["start_values"], output=scenario["outputs"])
    a, b = np.array(me_scenarios.A), np.array(me_scenarios.B)
    c, d = np.array(me_scenarios.C), np.array(me_scenarios.D)
    start = scenario["start_values"]
    x0, u = np.array([start["x0[1]"], start["x0[2]"]]), start["u[1]"]
    # x(t) = e^{At} x0 + ∫₀ᵗ e^{Aτ} dτ B u (independent Taylor expm)
    exact = np.array([zoh(a, b, t)[0] @ x0 + zoh(a, b, t)[1][:, 0] * u for t in me["time"]])
    x_error = max(np.max(np.abs(me[f"x[{i + 1}]"] - exact[:, i])) for i in range(2))
    y_exact = exact @ c[0] + d[0, 0] * u
    y_error = np.max(np.abs(me["y[1]"] - y_exact))
    print(f"{scenario['name']}: ME vs analytic, relative: x {x_error / np.max(np.abs(exact)):.2e}, "
          f"y {y_error / np.max(np.abs(y_exact)):.2e}")
    assert x_error < 1e-6 * np.max(np.abs(exact)) and y_error < 1e-6 * np.max(np.abs(y_exact))


def test_model_exchange_in_discrete_time_samples_at_time_events():
    """Discrete time (the default) through Model Exchange: der(x) = 0, x0 after
    initialisation, and a time event at each sample instant (sample_period = 0: the default
    experiment's 0.1 s) applying x+ = A x + B u with the input of the instant before."""
    from ctypes import POINTER, c_double
    from fmpy import read_model_description
    from fmpy.fmi2 import FMU2Model
    from fmpy import extract
    path = fmu_path("LinearSystem")
    md = read_model_description(path)
    assert md.modelExchange is not None and md.numberOfEventIndicators == 0
    vr = {v.name: v.valueReference for v in md.modelVariables}
    model = FMU2Model(guid=md.guid, unzipDirectory=extract(path),
                      modelIdentifier=md.modelExchange.modelIdentifier, instanceName="me")
    model.instantiate()
    model.setReal([vr["Q[1,1]"], vr["Q[2,2]"], vr["R[1,1]"], vr["x0[1]"], vr["u[1]"]],
                  [0.0, 0.0, 0.0, 2.0, 1.0])
    model.setupExperiment(startTime=0.0)
    model.enterInitializationMode()
    model.exitInitializationMode()
    info = model.newDiscreteStates()
    # (needed, terminate, nominals changed, values changed, next defined, next time)
    assert info[3] is False or info[3] == 0
    assert info[4] and info[5] == pytest.approx(0.1, abs=1e-15)
    model.enterContinuousTimeMode()
    derivatives = np.ones(2)
    model.getDerivatives(derivatives.ctypes.data_as(POINTER(c_double)), 2)
    assert list(derivatives) == [0.0, 0.0]
    assert model.getReal([vr["x[1]"], vr["x[2]"]]) == [2.0, 0.0]
    # the input changed between the instants is not the sample's
    model.setTime(0.05)
    model.setReal([vr["u[1]"]], [5.0])
    model.setTime(0.1)
    model.setReal([vr["u[1]"]], [3.0])
    model.enterEventMode()
    info = model.newDiscreteStates()
    assert info[3] and info[4] and info[5] == pytest.approx(0.2, abs=1e-15)
    # x+ = [0.9 x1 + 0.1 x2, 0.9 x2 + u(0)] = [1.8, 1.0]; y = x1
    assert model.getReal([vr["x[1]"], vr["x[2]"], vr["y[1]"]]) == [1.8, 1.0, 1.8]
    model.enterContinuousTimeMode()
    model.setTime(0.2)
    model.enterEventMode()
    model.newDiscreteStates()
    # with u(0.1) = 3
    assert model.getReal([vr["x[1]"], vr["x[2]"]]) == pytest.approx([1.72, 3.9], abs=1e-15)
    model.terminate()
    model.freeInstance()


def test_directional_derivatives_are_answered_in_initialization_mode():
    """FMI 2.0 allows fmi2GetDirectionalDerivative in Initialization Mode: the model is
    initialised from the current parameters first (on a Co-Simulation instance too), so
    dy[1]/dx[1] is C[1,1] there, not an error."""
    from fmpy import extract
    from fmpy.fmi2 import FMU2Model, FMU2Slave

    path = fmu_path("LinearSystem")
    md = read_model_description(path)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    c11 = float(next(v.start for v in md.modelVariables if v.name == "C[1,1]"))
    unzipped = extract(path)
    for cls, interface in [(FMU2Slave, md.coSimulation), (FMU2Model, md.modelExchange)]:
        fmu = cls(guid=md.guid, unzipDirectory=unzipped,
                  modelIdentifier=interface.modelIdentifier, instanceName="jacobian")
        fmu.instantiate()
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        assert fmu.getDirectionalDerivative([vr["y[1]"]], [vr["x[1]"]], [1.0]) == [c11]
        fmu.exitInitializationMode()
        fmu.terminate()
        fmu.freeInstance()
