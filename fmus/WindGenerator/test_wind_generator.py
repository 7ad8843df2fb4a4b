"""WindGenerator.fmu through fmpy: validation, the rated steady state from rest (≈ 1800 rpm,
≈ 240 V), the step responses of both references and their time constants, reference
clipping, the operating-point start, step-size independence, several instances, FMU state,
bad parameters named."""

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException
from fmpy.validation import validate_fmu

from conftest import (assert_initialization_fails_naming, assert_set_rejected, fmu_path, init,
                      open_initialized_pair, open_slave, simulate_packaged)

def simulate(rows, stop, h=0.01, **start):
    return simulate_packaged("WindGenerator", stop, h, start, rows, ["u_drive", "u_field"])


def time_constant(t, y, t_step):
    """Time from t_step until y covers 63.2 % of its change (linear interpolation)."""
    before = y[np.searchsorted(t, t_step - 1e-9)]
    final = y[-1]
    target = before + (1 - np.exp(-1)) * (final - before)
    after = t >= t_step - 1e-9
    tt, yy = t[after], y[after]
    rising = final > before
    k = np.argmax(yy >= target) if rising else np.argmax(yy <= target)
    t_cross = tt[k - 1] + (target - yy[k - 1]) / (yy[k] - yy[k - 1]) * (tt[k] - tt[k - 1])
    return t_cross - t_step


def step_experiments(h=0.01):
    """Drive step 8 → 10 V at t = 1 s (field 8 V) and field step 6 → 8 V at t = 1 s
    (drive 10 V), each from the steady state of the references before the step."""
    drive = simulate([(0, 8, 8), (1, 8, 8), (1, 10, 8)], 7.0, h, start_at_operating_point=True,
                     u_drive_0=8.0, u_field_0=8.0)
    field = simulate([(0, 10, 6), (1, 10, 6), (1, 10, 8)], 4.0, h, start_at_operating_point=True,
                     u_drive_0=10.0, u_field_0=6.0)
    return drive, field


def test_validates_without_problems():
    assert validate_fmu(fmu_path("WindGenerator")) == []


def test_rated_references_from_rest_give_1800_rpm_and_240_volts():
    r = simulate([(0, 10, 8)], 12.0, 0.1)
    speed, volts = r["speed"][-1], r["voltage"][-1]
    print(f"rated steady state from rest: {speed:.3f} rpm, {volts:.3f} V, "
          f"{r['frequency'][-1]:.4f} Hz, field {r['field_current'][-1]:.4f} A")
    assert r["speed"][0] == 0.0 and r["voltage"][0] == 0.0
    assert speed == pytest.approx(1800.0, rel=1e-3)
    assert volts == pytest.approx(240.0, rel=1e-3)
    assert r["frequency"][-1] == pytest.approx(60.0, rel=1e-3)
    assert r["field_current"][-1] == pytest.approx(0.5, rel=1e-3)
    assert r["T_m"][-1] == pytest.approx(r["T_e"][-1] + 5e-4 * 1800 * np.pi / 30, rel=1e-3)


def test_step_responses_have_the_documented_time_constants():
    drive, field = step_experiments()
    t = drive["time"]
    tau_speed = time_constant(t, drive["speed"], 1.0)
    tau_v_drive = time_constant(t, drive["voltage"], 1.0)
    tau_v_field = time_constant(field["time"], field["voltage"], 1.0)
    field_speed = field["speed"]
    print(f"time constants (63 %): speed after drive step {tau_speed:.3f} s, voltage after "
          f"drive step {tau_v_drive:.3f} s, voltage after field step {tau_v_field:.3f} s; "
          f"speed dip after field step {1800 - field_speed.min():.2f} rpm")
    assert drive["speed"][0] == pytest.approx(1440.0, rel=1e-9)
    assert drive["speed"][-1] == pytest.approx(1800.0, rel=2e-3)
    assert field["voltage"][0] == pytest.approx(180.0, rel=1e-9)
    assert field["voltage"][-1] == pytest.approx(240.0, rel=2e-3)
    assert tau_speed == pytest.approx(0.542, abs=0.01)
    assert tau_v_drive == pytest.approx(0.503, abs=0.01)
    assert tau_v_field == pytest.approx(0.221, abs=0.01)
    assert np.max(field["voltage"]) <= 240.0 * 1.001  # no overshoot


def test_references_are_clipped_to_0_10_volts():
    a = simulate([(0, 15, 12)], 1.0, 0.1)
    b = simulate([(0, 10, 10)], 1.0, 0.1)
    assert np.array_equal(a["speed"], b["speed"]) and np.array_equal(a["voltage"], b["voltage"])


@pytest.mark.parametrize("fixed_step_rk4,tolerance", [(True, 1e-9), (False, 1e-10)],
                         ids=["rk4", "adaptive"])
def test_trajectory_does_not_depend_on_the_communication_step(fixed_step_rk4, tolerance):
    # RK4's grid of h_max does not depend on the communication step (round-off apart); the
    # adaptive integrator's steps do, within its error (rtol = 7e-12: about 1e-11 of the rated
    # values).
    fine = simulate([(0, 7, 5)], 2.0, 0.01, fixed_step_rk4=fixed_step_rk4)
    coarse = simulate([(0, 7, 5)], 2.0, 0.1, fixed_step_rk4=fixed_step_rk4)
    for k, rated in (("speed", 1800), ("voltage", 240)):
        assert np.max(np.abs(fine[k][::10] - coarse[k])) < tolerance * rated


def run(slave, vr, n, u, h=0.1, t0=0.0):
    out = []
    t = t0
    for k in range(n):
        slave.setReal([vr["u_drive"], vr["u_field"]], list(u(k)))
        slave.doStep(t, h)
        t += h
        out.append(slave.getReal([vr["speed"], vr["voltage"]]))
    return np.array(out)


def test_two_instances_and_fmu_state():
    ua = lambda k: (10.0, 8.0)
    ub = lambda k: (6.0 + 3.0 * (k > 10), 5.0)
    a, vr, _ = open_slave("WindGenerator", "a")
    init(a)
    alone = run(a, vr, 30, ua)
    a.freeInstance()
    a, b, _ = open_initialized_pair("WindGenerator")
    ra, rb = [], []
    t = 0.0
    for k in range(30):
        ra.append(run(a, vr, 1, lambda _: ua(k), t0=t)[0])
        rb.append(run(b, vr, 1, lambda _: ub(k), t0=t)[0])
        t += 0.1
    assert np.array_equal(np.array(ra), alone)
    state = b.getFMUstate()
    blob = b.serializeFMUstate(state)
    first = run(b, vr, 20, ub, t0=3.0)
    b.setFMUstate(state)
    assert np.array_equal(run(b, vr, 20, ub, t0=3.0), first)
    b.setFMUstate(b.deSerializeFMUstate(blob))
    assert np.array_equal(run(b, vr, 20, ub, t0=3.0), first)
    a.freeInstance()
    b.freeInstance()


@pytest.mark.parametrize("name,value", [("J", -1.0), ("pole_pairs", 1e308), ("h_max", 1e-300),
                                        ("rtol", 0.5)])
def test_parameter_outside_its_declared_range_is_refused_when_set(name, value):
    s, vr, sink = open_slave("WindGenerator")
    assert_set_rejected(s, vr, sink, name, value, f"`{name}`", "its m")
    s.freeInstance()


@pytest.mark.parametrize("name,value", [("R_load", 0.0), ("h_max", 0.01), ("M_f", 3.0)])
def test_bad_parameter_is_an_error_naming_it(name, value):
    s, vr, sink = open_slave("WindGenerator")
    # h_max (RK4 unstable beyond about 2 ms) matters to the fixed-step integrator only
    s.setBoolean([vr["fixed_step_rk4"]], [name == "h_max"])
    s.setReal([vr[name]], [value])
    assert_initialization_fails_naming(s, sink, name)
