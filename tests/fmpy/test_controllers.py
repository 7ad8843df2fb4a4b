"""StateFeedback.fmu and AdaptiveStateFeedback.fmu through fmpy: validation, the placed poles
(checked with numpy on the FMU's own A, B and L), the closed loop with the nonlinear
GantryCrane FMU, bad poles and parameters, the adaptive controller's guards (unreachable
estimate, gain too large, NaN refused), instances and FMU state."""

import pathlib
import subprocess

import numpy as np
import pytest
from fmpy import simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.validation import validate_fmu

from conftest import CRANE, REPO, assert_set_rejected, crane_linear_model, fmu_path, init, open_initialized_pair, open_slave, set_values, zoh

TS = 0.05
N = 4
# The crane design (paper 000 §VII-B, docs/reference-values.md §6): continuous poles mapped by z = e^{s Ts}.
S_POLES = np.array([-1 + 0.5j, -1 - 0.5j, -1.5 + 5.2j, -1.5 - 5.2j])
Z_POLES = np.exp(S_POLES * TS)
REFERENCE_GAIN = np.array([0.982, 1.132, 1.027, 0.774])

def crane_zoh():
    """ZOH at TS of the crane linearisation."""
    return zoh(*crane_linear_model(**CRANE), TS)


def ackermann(A, B, poles):
    """L = [0 … 0 1] 𝒞⁻¹ φ(A), written independently of the Rust code."""
    n = A.shape[0]
    reach = np.hstack([np.linalg.matrix_power(A, k) @ B for k in range(n)])
    phi = np.real(np.poly(poles))
    phi_a = sum(c * np.linalg.matrix_power(A, n - k) for k, c in enumerate(phi))
    return np.linalg.solve(reach.T, np.eye(n)[:, -1]) @ phi_a


def names(prefix, rows, cols=None):
    if cols is None:
        return [f"{prefix}[{i + 1}]" for i in range(rows)]
    return [f"{prefix}[{i + 1},{j + 1}]" for i in range(rows) for j in range(cols)]


def max_pole_mismatch(got, want):
    got = list(got)
    worst = 0.0
    for w in want:
        k = int(np.argmin([abs(gz - w) for gz in got]))
        worst = max(worst, abs(got.pop(k) - w))
    return worst


# --- both FMUs --------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["StateFeedback", "AdaptiveStateFeedback"])
def test_validates_without_problems(name):
    assert validate_fmu(fmu_path(name)) == []


@pytest.mark.parametrize("name", ["StateFeedback", "AdaptiveStateFeedback"])
def test_simulates_in_fmpy(name):
    inputs = np.array([(0.0, 0.2)], dtype=[("time", np.float64), ("x_hat[1]", np.float64)])
    r = simulate_fmu(
        fmu_path(name),
        stop_time=1.0,
        output_interval=TS,
        input=inputs,
        output=["u[1]", "L[1,1]"],
    )
    assert len(r) == 21
    assert np.all(r["u[1]"] == -0.2 * r["L[1,1]"])
    assert r["L[1,1]"][0] == pytest.approx(REFERENCE_GAIN[0], abs=5e-4)


# --- StateFeedback -----------------------------------------------------------------------


def test_gain_places_the_requested_poles():
    slave, vr, _ = open_slave("StateFeedback")
    init(slave)
    A = np.array(slave.getReal([vr[k] for k in names("A", N, N)])).reshape(N, N)
    B = np.array(slave.getReal([vr[k] for k in names("B", N, 1)])).reshape(N, 1)
    L = np.array(slave.getReal([vr[k] for k in names("L", 1, N)])).reshape(1, N)
    re = slave.getReal([vr[k] for k in names("pole_re", N)])
    im = slave.getReal([vr[k] for k in names("pole_im", N)])
    requested = np.array(re) + 1j * np.array(im)
    slave.freeInstance()

    error = max_pole_mismatch(np.linalg.eigvals(A - B @ L), requested)
    print(f"max |eig(A − B L) − requested pole| = {error:.2e}")
    assert error < 1e-9
    # the defaults are the crane design of docs/reference-values.md §6, the model is the crane's ZOH
    assert max_pole_mismatch(requested, Z_POLES) < 1e-15
    A_ref, B_ref = crane_zoh()
    assert np.max(np.abs(A - A_ref)) < 1e-9 and np.max(np.abs(B - B_ref)) < 1e-9
    assert np.max(np.abs(L[0] - REFERENCE_GAIN)) < 5e-4
    assert np.max(np.abs(L[0] - ackermann(A, B, requested))) < 1e-9


def test_closed_loop_with_the_nonlinear_crane_settles():
    crane, cvr, _ = open_slave("GantryCrane", "crane")
    ctrl, kvr, _ = open_slave("StateFeedback", "controller")
    crane.setReal([cvr["x0"]], [0.2])
    init(crane)
    init(ctrl)
    state_vrs = [cvr[k] for k in ["x", "theta", "v", "omega"]]
    x_hat_vrs = [kvr[k] for k in names("x_hat", N)]
    t, last_outside, max_force = 0.0, 0.0, 0.0
    trajectory = []
    for _ in range(int(round(20.0 / TS))):
        s = crane.getReal(state_vrs)
        if abs(s[0]) >= 5e-3 or abs(s[1]) >= 0.01:
            last_outside = t
        ctrl.setReal(x_hat_vrs, s)
        (u,) = ctrl.getReal([kvr["u[1]"]])  # direct feedthrough: u for this x_hat
        assert np.isfinite(u)
        max_force = max(max_force, abs(u))
        crane.setReal([cvr["U"]], [u])
        crane.doStep(t, TS)
        ctrl.doStep(t, TS)
        t += TS
        trajectory.append((t, *s, u))
    settling = last_outside + TS
    print(f"closed loop: settled (|x| < 5 mm, |θ| < 0.01 rad for good) at {settling:.2f} s, max |U| = {max_force:.4f} N")
    assert settling < 15.0
    assert max_force <= 17.0
    final = crane.getReal(state_vrs)
    assert abs(final[0]) < 1e-3 and abs(final[1]) < 1e-3
    # the first input is −L x₀ exactly: the controller saw x_hat before the step
    assert trajectory[0][-1] == pytest.approx(-0.2 * REFERENCE_GAIN[0], abs=5e-4)
    crane.freeInstance()
    ctrl.freeInstance()


@pytest.mark.parametrize(
    "settings, reason",
    [
        # a pole outside the unit circle while stability is required
        ({"pole_re[1]": 1.2, "pole_im[1]": 0.0, "pole_im[2]": 0.0}, ["`pole_re[1]`, `pole_im[1]`", "unit circle"]),
        # a complex pole whose partner is not its conjugate
        ({"pole_im[2]": 0.3}, ["`pole_re[1]`, `pole_im[1]`", "conjugate"]),
        # an odd number of complex poles: the fourth has no partner
        ({"pole_im[3]": 0.0}, ["`pole_re[4]`, `pole_im[4]`", "conjugate"]),
        # B = 0: (A, B) not reachable
        ({f"B[{i},1]": 0.0 for i in range(1, 5)}, ["`A`, `B`", "not reachable"]),
        # limits the wrong way round
        ({"u_min": 5.0, "u_max": 1.0}, ["`u_max`", "greater than u_min"]),
    ],
    ids=["unstable", "not-conjugate", "unpaired", "unreachable", "limits"],
)
def test_bad_design_is_an_error_at_initialisation_naming_the_reason(settings, reason):
    slave, vr, sink = open_slave("StateFeedback")
    slave.setupExperiment(startTime=0.0)
    slave.setReal([vr[k] for k in settings], list(settings.values()))
    slave.enterInitializationMode()
    with pytest.raises(FMICallException) as e:
        slave.exitInitializationMode()
    assert e.value.status == 3
    errors = sink.texts(3)
    print(errors)
    assert any(all(r in t for r in reason) and "fmi2ExitInitializationMode" in t for t in errors), errors
    slave.freeInstance()


def test_unstable_poles_are_allowed_when_stability_is_not_required():
    slave, vr, _ = open_slave("StateFeedback")
    slave.setupExperiment(startTime=0.0)
    slave.setReal([vr["pole_re[1]"], vr["pole_im[1]"], vr["pole_im[2]"]], [1.2, 0.0, 0.0])
    slave.setBoolean([vr["require_stable"]], [False])
    slave.enterInitializationMode()
    slave.exitInitializationMode()
    A = np.array(slave.getReal([vr[k] for k in names("A", N, N)])).reshape(N, N)
    B = np.array(slave.getReal([vr[k] for k in names("B", N, 1)])).reshape(N, 1)
    L = np.array(slave.getReal([vr[k] for k in names("L", 1, N)])).reshape(1, N)
    want = [1.2, np.real(Z_POLES[0]), Z_POLES[2], Z_POLES[3]]
    assert max_pole_mismatch(np.linalg.eigvals(A - B @ L), want) < 1e-9
    slave.freeInstance()


def test_reference_term_and_saturation():
    slave, vr, _ = open_slave("StateFeedback")
    init(slave)
    L = np.array(slave.getReal([vr[k] for k in names("L", 1, N)]))
    slave.setReal([vr["x_hat[1]"], vr["x_ref[1]"]], [0.3, 0.1])
    (u,) = slave.getReal([vr["u[1]"]])
    assert u == pytest.approx(-L[0] * 0.2, rel=1e-14)
    slave.setReal([vr["x_hat[1]"], vr["x_ref[1]"]], [-100.0, 0.0])
    assert slave.getReal([vr["u[1]"]]) == [17.0]
    slave.setReal([vr["x_hat[1]"]], [100.0])
    assert slave.getReal([vr["u[1]"]]) == [-17.0]
    with pytest.raises(FMICallException):
        slave.setReal([vr["x_hat[2]"]], [float("nan")])
    slave.freeInstance()


def test_variant_of_other_dimensions_places_a_repeated_pole(tmp_path):
    spurio = REPO / "target" / "release" / "spurio"
    assert spurio.is_file(), "build with scripts/build-fmus first"
    subprocess.run(
        [str(spurio), "package-variant", "StateFeedback", "--set", "n=3", "--name", "MyFeedback",
         "--lib-dir", str(REPO / "target" / "release"), "--out", str(tmp_path)],
        check=True,
        capture_output=True,
    )
    path = str(tmp_path / "MyFeedback.fmu")
    assert validate_fmu(path) == []
    r = simulate_fmu(
        path,
        stop_time=0.1,
        output_interval=TS,
        input=np.array([(0.0, 1.0)], dtype=[("time", np.float64), ("x_hat[3]", np.float64)]),
        output=["u[1]", "L[1,1]", "L[1,2]", "L[1,3]"],
    )
    L = np.array([r[f"L[1,{j}]"][0] for j in (1, 2, 3)])
    A = np.eye(3) + np.diag([TS, TS], 1)
    B = np.array([[0.0], [0.0], [1.0]])
    # (z − 0.5)³: compare the characteristic polynomial (eigenvalues of a triple pole are
    # only accurate to ~ε^(1/3))
    assert np.max(np.abs(np.poly(A - B @ L[None, :]) - np.poly([0.5, 0.5, 0.5]))) < 1e-12
    assert r["u[1]"][0] == -L[2]


# --- AdaptiveStateFeedback ----------------------------------------------------------------


A_HAT = names("A_hat", N, N)
B_HAT = names("B_hat", N, 1)
GAIN = names("L", 1, N)


def adaptive_sequence():
    """(A_hat, B_hat, label) per step: good, B̂ = 0 (not reachable), good again, B̂ tiny
    (gain too large), an overflowing Â (not reachable), good."""
    A, B = crane_zoh()
    good = (A, 1.1 * B, "good")
    other = (A, 0.9 * B, "good")
    seq = [good] * 4 + [(A, 0 * B, "unreachable")] * 5 + [other] * 3
    seq += [(A, 1e-4 * B, "gain too large")] * 3 + [(1e200 * A, B, "overflow")] * 2 + [good] * 3
    return seq


def run_adaptive(slave, vr, seq, t0=0.0, k0=0):
    out = []
    t = t0
    for k, (A, B, _) in enumerate(seq):
        x = [0.2 * np.cos(0.3 * (k + k0)), 0.01, -0.05, 0.1]
        slave.setReal([vr[n] for n in names("x_hat", N) + A_HAT + B_HAT], x + list(A.ravel()) + list(B.ravel()))
        u = slave.getReal([vr["u[1]"]] + [vr[n] for n in GAIN])
        (rejected,) = slave.getInteger([vr["rejected_updates"]])
        (flag,) = slave.getBoolean([vr["estimate_rejected"]])
        status = slave.fmi2DoStep(slave.component, t, TS, 1)
        assert status in (0, 1), status
        t += TS
        out.append((*u, rejected, flag, status))
    return np.array(out)


def test_adaptive_keeps_the_last_good_gain_and_warns_once_per_episode():
    slave, vr, sink = open_slave("AdaptiveStateFeedback", logging_on=True)
    init(slave)
    seq = adaptive_sequence()
    out = run_adaptive(slave, vr, seq)
    u, gains, rejected, flag, status = out[:, 0], out[:, 1:5], out[:, 5], out[:, 6], out[:, 7]
    assert np.all(np.isfinite(out))

    A, B = crane_zoh()
    poles = Z_POLES
    good_gain = ackermann(A, 1.1 * B, poles)
    other_gain = ackermann(A, 0.9 * B, poles)
    labels = [s[2] for s in seq]
    for k, label in enumerate(labels):
        want = good_gain if k < 9 or k >= 17 else other_gain
        assert np.max(np.abs(gains[k] - want)) < 1e-9, (k, label, gains[k], want)
        assert flag[k] == (label != "good")
    # the bad spells: warning status on the first doStep of each episode only
    warned_steps = [k for k in range(len(seq)) if status[k] == 1]
    assert warned_steps == [4, 12], status
    warnings = sink.texts(1)
    print("\n".join(warnings))
    assert len(warnings) == 2, warnings
    assert "not reachable" in warnings[0] and "t = 0.2" in warnings[0]
    assert "bound" in warnings[1] and "t = 0.6" in warnings[1]
    assert rejected[-1] == 10
    # recovery is logged as an event (debug logging on)
    assert sum("usable again" in t for t in sink.texts(0)) == 2
    slave.freeInstance()


def test_adaptive_refuses_nan_estimates_and_goes_on():
    slave, vr, sink = open_slave("AdaptiveStateFeedback")
    init(slave)
    seq = adaptive_sequence()[:4]
    before = run_adaptive(slave, vr, seq)
    assert_set_rejected(slave, vr, sink, "A_hat[2,3]", float("nan"), "`A_hat[2,3]`", "finite")
    after = run_adaptive(slave, vr, seq, t0=4 * TS, k0=4)
    assert np.all(np.isfinite(after))
    assert np.array_equal(after[:, 1:5], before[:, 1:5])
    slave.freeInstance()


def test_adaptive_with_the_true_model_equals_state_feedback():
    fixed, fvr, _ = open_slave("StateFeedback", "fixed")
    adaptive, avr, _ = open_slave("AdaptiveStateFeedback", "adaptive")
    init(fixed)
    init(adaptive)
    for k in range(20):
        x = [0.2 * np.cos(0.3 * k), 0.01 * k, -0.05, 0.1]
        fixed.setReal([fvr[n] for n in names("x_hat", N)], x)
        adaptive.setReal([avr[n] for n in names("x_hat", N)], x)
        assert fixed.getReal([fvr["u[1]"]]) == adaptive.getReal([avr["u[1]"]])
        fixed.doStep(k * TS, TS)
        adaptive.doStep(k * TS, TS)
    fixed.freeInstance()
    adaptive.freeInstance()


def test_adaptive_recomputes_every_nth_step():
    slave, vr, _ = open_slave("AdaptiveStateFeedback")
    set_values(slave, vr, {"recompute_period": 3})
    init(slave)
    A, B = crane_zoh()
    seq = [(A, (1 + 0.1 * k) * B, "good") for k in range(7)]
    out = run_adaptive(slave, vr, seq)
    for k in range(7):
        due = 3 * (k // 3)
        want = ackermann(A, (1 + 0.1 * due) * B, Z_POLES)
        assert np.max(np.abs(out[k, 1:5] - want)) < 1e-9, k
    slave.freeInstance()


@pytest.mark.parametrize(
    "settings, reason",
    [
        ({"pole_re[3]": 1.5, "pole_im[3]": 0.0, "pole_im[4]": 0.0}, ["`pole_re[3]`, `pole_im[3]`", "unit circle"]),
        ({"pole_im[4]": 0.2}, ["conjugate"]),
        ({"u_min": 17.0}, ["`u_max`"]),
    ],
    ids=["unstable", "not-conjugate", "limits"],
)
def test_adaptive_bad_parameters_are_named(settings, reason):
    slave, vr, sink = open_slave("AdaptiveStateFeedback")
    slave.setupExperiment(startTime=0.0)
    slave.setReal([vr[k] for k in settings], list(settings.values()))
    slave.enterInitializationMode()
    with pytest.raises(FMICallException):
        slave.exitInitializationMode()
    assert any(all(r in t for r in reason) for t in sink.texts(3)), sink.messages
    with pytest.raises(FMICallException):
        slave.setInteger([vr["recompute_period"]], [0])  # below min = 1
    slave.freeInstance()


def test_adaptive_two_interleaved_instances_equal_two_separate_runs():
    seq_a = adaptive_sequence()
    A, B = crane_zoh()
    seq_b = [(A, (1 + 0.05 * k) * B, "good") for k in range(len(seq_a))]
    alone = []
    for name, seq in [("a", seq_a), ("b", seq_b)]:
        s, vr, _ = open_slave("AdaptiveStateFeedback", name)
        init(s)
        alone.append(run_adaptive(s, vr, seq))
        s.freeInstance()
    a, b, vr = open_initialized_pair("AdaptiveStateFeedback")
    ra, rb = [], []
    for k in range(len(seq_a)):
        ra.append(run_adaptive(a, vr, seq_a[k : k + 1], t0=k * TS, k0=k)[0])
        rb.append(run_adaptive(b, vr, seq_b[k : k + 1], t0=k * TS, k0=k)[0])
    assert np.array_equal(np.array(ra), alone[0])
    assert np.array_equal(np.array(rb), alone[1])
    a.freeInstance()
    b.freeInstance()


def test_adaptive_fmu_state_replays_bit_for_bit():
    seq = adaptive_sequence()
    split = 6  # inside the first bad episode
    slave, vr, sink = open_slave("AdaptiveStateFeedback")
    init(slave)
    run_adaptive(slave, vr, seq[:split])
    state = slave.getFMUstate()
    blob = slave.serializeFMUstate(state)
    warnings_before = len(sink.texts(1))
    first = run_adaptive(slave, vr, seq[split:], t0=split * TS, k0=split)
    warnings_first = sink.texts(1)[warnings_before:]

    slave.setFMUstate(state)
    again = run_adaptive(slave, vr, seq[split:], t0=split * TS, k0=split)
    assert np.array_equal(first, again)

    other, _, other_sink = open_slave("AdaptiveStateFeedback", "other")
    init(other)
    restored = other.deSerializeFMUstate(blob)
    other.setFMUstate(restored)
    third = run_adaptive(other, vr, seq[split:], t0=split * TS, k0=split)
    assert np.array_equal(first, third)
    # the restored instance is still inside the episode: it warns only for the next one
    assert other_sink.texts(1) == warnings_first
    assert len(warnings_first) == 1
    other.freeFMUstate(restored)
    other.freeInstance()
    slave.freeFMUstate(state)
    slave.freeInstance()
