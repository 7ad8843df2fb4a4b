"""GantryCrane.fmu through fmpy: validation, physics against the linearised model, step-size
independence, the rail stop, and FMI conformance (state machine, value references, GUID,
instances, FMU state, NaN inputs)."""

import ctypes

import numpy as np
import pytest
from fmpy import simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.validation import validate_fmu

from conftest import CRANE, LogSink, simulate_packaged, assert_initialization_fails_naming, assert_set_rejected, crane_linear_model, fmu_path, init, make_callbacks, open_slave, set_values, zoh

def linear_response(t, s0, u):
    """The linearised crane from `s0` under a constant force `u`, at the times `t`."""
    A, B = crane_linear_model(**CRANE)
    responses = []
    for ti in t:
        a, b = zoh(A, B, ti)
        responses.append(a @ s0 + b[:, 0] * u)
    return np.array(responses)


def simulate(step, stop, u=0.0, **start):
    return simulate_packaged(
        "GantryCrane", stop, step, start, [(0.0, u)], ["U"],
        fmi_type="CoSimulation", output=["x", "theta", "v", "omega", "U_applied"],
    )


def test_validates_without_problems(crane_fmu):
    assert validate_fmu(crane_fmu) == []


def test_simulates_in_co_simulation(crane_fmu):
    r = simulate(0.05, 2.0, theta0=0.05)
    assert r["time"][-1] == pytest.approx(2.0, abs=1e-9)
    assert len(r) == 41
    assert r["theta"][0] == 0.05
    assert np.all(np.isfinite(r["theta"]))


def test_free_swing_period_matches_the_linearised_model():
    r = simulate(0.001, 12.0, theta0=0.05)
    t, th = r["time"], r["theta"]
    i = np.where((th[:-1] < 0) & (th[1:] >= 0))[0]
    crossings = t[i] + (t[i + 1] - t[i]) * (-th[i]) / (th[i + 1] - th[i])
    period = np.mean(np.diff(crossings))
    A, _ = crane_linear_model(**CRANE)
    w = max(abs(np.linalg.eigvals(A).imag))
    linear_period = 2 * np.pi / w
    error = abs(period - linear_period) / linear_period
    print(f"free-swing period {period:.6f} s, linearised {linear_period:.6f} s, error {error:.3e}")
    assert error < 0.005


def test_one_newton_step_matches_the_linearised_model():
    r = simulate(0.01, 1.0, u=1.0)
    lin = linear_response(r["time"], np.zeros(4), 1.0)
    x_err = np.max(np.abs(r["x"] - lin[:, 0])) / np.max(np.abs(lin[:, 0]))
    th_err = np.max(np.abs(r["theta"] - lin[:, 1])) / np.max(np.abs(lin[:, 1]))
    print(f"1 N step: relative error x {x_err:.2e}, theta {th_err:.2e}")
    assert np.max(np.abs(r["x"])) < 0.5  # stays off the rail stop
    assert x_err < 2e-3
    assert th_err < 1e-2


def test_trajectory_does_not_depend_on_the_communication_step():
    fine = simulate(0.001, 5.0, u=0.5, theta0=0.1)
    coarse = simulate(0.05, 5.0, u=0.5, theta0=0.1)
    common = fine[::50]
    assert np.allclose(common["time"], coarse["time"], atol=1e-9)
    diff = max(np.max(np.abs(common[k] - coarse[k])) for k in ["x", "theta", "v", "omega"])
    print(f"max difference 1 ms vs 50 ms steps: {diff:.3e}")
    assert diff < 1e-6


def test_rail_stop_holds_the_cart_under_a_sustained_push():
    sink = LogSink()
    r = simulate_fmu(
        fmu_path("GantryCrane"),
        stop_time=5.0,
        output_interval=0.01,
        input=np.array([(0.0, 17.0)], dtype=[("time", np.float64), ("U", np.float64)]),
        debug_logging=True,
        logger=sink,
    )
    assert np.max(np.abs(r["x"])) <= 0.5
    assert r["x"][-1] == 0.5 and r["v"][-1] == 0.0
    hits = [t for t in sink.texts() if "rail end" in t]
    assert len(hits) == 1, sink.messages


def test_force_is_saturated():
    r = simulate(0.05, 0.5, u=100.0)
    assert np.all(r["U_applied"][1:] == 17.0)


# --- conformance through fmpy's FMU2Slave --------------------------------------------------


def test_wrong_call_order_is_an_error_with_a_log_line():
    slave, vr, sink = open_slave("GantryCrane")
    with pytest.raises(FMICallException) as e:
        slave.doStep(0.0, 0.01)
    assert e.value.status == 3
    assert any("fmi2DoStep" in t and "illegal call sequence" in t for t in sink.texts(3))
    with pytest.raises(FMICallException):
        slave.exitInitializationMode()
    # the rejected calls changed nothing: the normal sequence still works
    init(slave)
    slave.doStep(0.0, 0.01)
    slave.terminate()
    slave.freeInstance()


def test_unknown_value_reference_is_an_error():
    slave, vr, sink = open_slave("GantryCrane")
    init(slave)
    with pytest.raises(FMICallException):
        slave.getReal([999])
    assert any("unknown value reference 999" in t for t in sink.texts(3))
    with pytest.raises(FMICallException):
        slave.setReal([999], [1.0])
    with pytest.raises(FMICallException):
        slave.getInteger([vr["x"]])  # a Real read as Integer
    assert any("not Integer" in t for t in sink.texts(3))
    slave.freeInstance()


def test_fixed_parameter_cannot_change_after_initialisation():
    slave, vr, sink = open_slave("GantryCrane")
    init(slave)
    assert_set_rejected(slave, vr, sink, "M", 2.0, "`M`", "fixed parameter")
    slave.freeInstance()


def test_bad_parameter_is_named():
    slave, vr, sink = open_slave("GantryCrane")
    assert_set_rejected(slave, vr, sink, "l", -1.0)  # below min = 0
    set_values(slave, vr, {"x0": 0.9})
    assert_initialization_fails_naming(slave, sink, "x0")


def test_wrong_guid_gives_null():
    with pytest.raises(Exception, match="(?i)instantiate"):
        open_slave("GantryCrane", guid="{00000000-0000-0000-0000-000000000000}")


def test_wrong_guid_and_wrong_fmu_type_are_logged():
    import fmpy.fmi2 as f2
    from fmpy import extract, read_model_description

    path = fmu_path("GantryCrane")
    md = read_model_description(path)
    unzipdir = extract(path)
    slave = f2.FMU2Slave(guid="{bad}", unzipDirectory=unzipdir, modelIdentifier="GantryCrane", instanceName="g")
    sink = LogSink()
    callbacks = make_callbacks(sink)
    comp = slave.fmi2Instantiate(b"g", 1, b"{bad}", b"file:///tmp", ctypes.byref(callbacks), 0, 0)
    assert not comp
    assert any("GUID mismatch" in t for t in sink.texts(3))
    comp = slave.fmi2Instantiate(b"g", 2, md.guid.encode(), b"file:///tmp", ctypes.byref(callbacks), 0, 0)
    assert not comp
    assert any("fmuType must be fmi2ModelExchange (0) or fmi2CoSimulation (1), got 2" in t
               for t in sink.texts(3))
    # both interfaces are offered: Model Exchange instantiates
    comp = slave.fmi2Instantiate(b"g", 0, md.guid.encode(), b"file:///tmp", ctypes.byref(callbacks), 0, 0)
    assert comp
    slave.fmi2FreeInstance(comp)


def run(slave, vr, n, u, h=0.01, t0=0.0):
    out = []
    t = t0
    for k in range(n):
        slave.setReal([vr["U"]], [u(k)])
        slave.doStep(t, h)
        t += h
        out.append(slave.getReal([vr["x"], vr["theta"], vr["v"], vr["omega"]]))
    return np.array(out)


def test_two_interleaved_instances_equal_two_separate_runs():
    ua = lambda k: np.sin(0.1 * k)
    ub = lambda k: 2.0 if k < 50 else -1.0
    a, vr, _ = open_slave("GantryCrane", "a")
    init(a)
    alone_a = run(a, vr, 200, ua)
    a.freeInstance()
    b, vr, _ = open_slave("GantryCrane", "b")
    b.setReal([vr["theta0"]], [0.2])
    init(b)
    alone_b = run(b, vr, 200, ub)
    b.freeInstance()

    a, vr, _ = open_slave("GantryCrane", "a")
    b, _, _ = open_slave("GantryCrane", "b")
    b.setReal([vr["theta0"]], [0.2])
    init(a)
    init(b)
    ra, rb = [], []
    t = 0.0
    for k in range(200):
        a.setReal([vr["U"]], [ua(k)])
        b.setReal([vr["U"]], [ub(k)])
        a.doStep(t, 0.01)
        b.doStep(t, 0.01)
        t += 0.01
        ra.append(a.getReal([vr["x"], vr["theta"], vr["v"], vr["omega"]]))
        rb.append(b.getReal([vr["x"], vr["theta"], vr["v"], vr["omega"]]))
    assert np.array_equal(np.array(ra), alone_a)
    assert np.array_equal(np.array(rb), alone_b)
    a.freeInstance()
    b.freeInstance()


def test_fmu_state_and_serialization_replay_bit_for_bit():
    u = lambda k: 3.0 * np.cos(0.05 * k)
    slave, vr, _ = open_slave("GantryCrane")
    init(slave)
    run(slave, vr, 100, u)
    state = slave.getFMUstate()
    blob = slave.serializeFMUstate(state)
    first = run(slave, vr, 150, lambda k: u(k + 100), t0=1.0)

    slave.setFMUstate(state)
    again = run(slave, vr, 150, lambda k: u(k + 100), t0=1.0)
    assert np.array_equal(first, again)

    restored = slave.deSerializeFMUstate(blob)
    slave.setFMUstate(restored)
    third = run(slave, vr, 150, lambda k: u(k + 100), t0=1.0)
    assert np.array_equal(first, third)

    # a second instance restores the serialized state too
    other, _, _ = open_slave("GantryCrane", "other")
    init(other)
    st = other.deSerializeFMUstate(blob)
    other.setFMUstate(st)
    fourth = run(other, vr, 150, lambda k: u(k + 100), t0=1.0)
    assert np.array_equal(first, fourth)
    other.freeFMUstate(st)
    other.freeInstance()

    slave.freeFMUstate(state)
    slave.freeFMUstate(restored)
    slave.freeInstance()


def test_nan_input_is_rejected_and_not_integrated():
    slave, vr, sink = open_slave("GantryCrane")
    init(slave)
    before = run(slave, vr, 10, lambda k: 1.0)
    assert_set_rejected(slave, vr, sink, "U", float("nan"), "`U`", "NaN")
    # the input kept its last good value; stepping goes on
    slave.doStep(0.1, 0.01)
    x = slave.getReal([vr["x"], vr["U"]])
    assert np.isfinite(x[0]) and x[1] == 1.0
    slave.freeInstance()


def test_communication_point_mismatch_is_reported():
    slave, vr, sink = open_slave("GantryCrane")
    init(slave)
    with pytest.raises(FMICallException):
        slave.doStep(0.5, 0.01)
    assert any("expected currentCommunicationPoint = 0" in t for t in sink.texts(3))
    with pytest.raises(FMICallException):
        slave.doStep(0.0, -0.01)
    slave.freeInstance()


def test_reset_returns_to_start_values():
    slave, vr, _ = open_slave("GantryCrane")
    init(slave)
    first = run(slave, vr, 20, lambda k: 1.0)
    slave.reset()
    init(slave)
    second = run(slave, vr, 20, lambda k: 1.0)
    assert np.array_equal(first, second)
    slave.freeInstance()


# --- Model Exchange: fmpy's CVode against the Co-Simulation FMU and an independent reference --


import re  # noqa: E402

from conftest import me_scenarios_of  # noqa: E402

crane_scenarios = me_scenarios_of(__file__)
# (tests/fmpy/test_model_exchange.py runs every scenario against Co-Simulation and checks the
# event times; here: what the crane logs at its events and where the load ends up)


def simulate_me(start_values, stop_time):
    """fmpy's CVode (relative tolerance 1e-8) on the Model Exchange interface, events logged."""
    sink = LogSink()
    result = simulate_fmu(fmu_path("GantryCrane"), fmi_type="ModelExchange", solver="CVode",
                          relative_tolerance=1e-8, stop_time=stop_time, output_interval=0.01,
                          start_values=start_values, debug_logging=True, logger=sink)
    events = [(float(m.group(1)), m.group(2)) for m in
              (re.search(r"t = (\S+) s: the cart is (free on the rail after|free|held)", t)
               for t in sink.texts()) if m]
    return result, events


def test_model_exchange_logs_each_contact_change_at_the_reference_time():
    start = {"U": 0.02, "x0": 0.45, "v0": 0.5, "theta0": 0.3}
    me, events = simulate_me(start, 3.0)
    reference, _ = crane_scenarios.crane_reference([0.45, 0.3, 0.5, 0.0], 0.02, 3.0)
    kinds = {"bounce": "free on the rail after", "held": "held", "release": "free"}
    assert [k for _, k in events] == [kinds[k] for _, k in reference], (events, reference)
    errors = [abs(t - r) for (t, _), (r, _) in zip(events, reference)]
    print(f"held/released: {len(events)} events, largest time error {max(errors):.2e} s")
    assert max(errors) < 1e-6
    assert np.max(np.abs(me["x"])) <= 0.5 * (1 + 1e-9)  # the pre-event row: the located root


def test_model_exchange_holds_the_cart_at_the_stop_and_swings_like_the_reference():
    me, events = simulate_me({"U": 3.0}, 2.0)
    (hit, _), = crane_scenarios.crane_reference([0.0, 0.0, 0.0, 0.0], 3.0, 0.9)[0]
    _, final = crane_scenarios.crane_reference([0.0, 0.0, 0.0, 0.0], 3.0, 2.0)
    assert [k for _, k in events] == ["held"] and abs(events[0][0] - hit) < 1e-6
    end = me[-1]
    assert end["x"] == 0.5 and end["v"] == 0.0
    print(f"rail stop at {events[0][0]:.9f} s (reference {hit:.9f} s); final theta "
          f"{end['theta']:.9f} (reference {final[1]:.9f}), omega {end['omega']:.9f} "
          f"(reference {final[3]:.9f})")
    assert abs(end["theta"] - final[1]) < 1e-6 and abs(end["omega"] - final[3]) < 1e-5
