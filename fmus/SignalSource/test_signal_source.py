"""SignalSource.fmu through fmpy: validation, every waveform's values (checked against
independent formulas), seeded reproducibility, output defined at the start time and after
each step, bad parameters named."""

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException
from fmpy.validation import validate_fmu

from conftest import assert_initialization_fails_naming, assert_set_rejected, fmu_path, open_slave, set_values, simulate_packaged

STEP, RANDOM_STEPS, PRBS, SINE, COSINE = 1, 2, 3, 4, 5


def simulate(stop=10.0, h=0.01, start_time=0.0, **start):
    return simulate_packaged("SignalSource", stop, h, start, start_time=start_time)


def test_validates_without_problems():
    assert validate_fmu(fmu_path("SignalSource")) == []


def test_step():
    r = simulate(stop=2.0, h=0.01, waveform=STEP, amplitude=2.0, offset=-1.0, step_time=0.5)
    expected = np.where(r["time"] >= 0.5 - 1e-9, 1.0, -1.0)
    assert np.array_equal(r["y"], expected)


@pytest.mark.parametrize("kind,fn", [(SINE, np.sin), (COSINE, np.cos)])
def test_sine_and_cosine(kind, fn):
    r = simulate(stop=3.0, h=0.01, waveform=kind, amplitude=1.5, offset=0.25, period=0.8,
                 phase=0.3)
    expected = 0.25 + 1.5 * fn(2 * np.pi * r["time"] / 0.8 + 0.3)
    assert np.max(np.abs(r["y"] - expected)) < 1e-12


def test_sine_at_the_start_time_and_after_each_step():
    r = simulate(start_time=1.0, stop=2.0, h=0.1, waveform=SINE, period=4.0)
    assert r["time"][0] == 1.0
    assert r["y"][0] == pytest.approx(1.0, abs=1e-15)  # sin(2π·1/4) at the start time
    assert np.allclose(r["y"], np.sin(2 * np.pi * r["time"] / 4.0), atol=1e-12)


def test_random_steps_hold_levels_for_random_times_in_range():
    r = simulate(stop=200.0, h=0.01, waveform=RANDOM_STEPS, amplitude=2.0, offset=5.0,
                 min_hold=1.0, max_hold=3.0, seed=4)
    y, t = r["y"], r["time"]
    assert np.all((y >= 3.0) & (y <= 7.0))
    switches = t[1:][np.diff(y) != 0]
    holds = np.diff(np.concatenate([[0.0], switches]))
    assert len(holds) > 50
    assert np.all(holds >= 1.0 - 0.011) and np.all(holds <= 3.0 + 0.011)
    assert np.mean(holds) == pytest.approx(2.0, rel=0.1)
    levels = y[np.concatenate([[0], np.where(np.diff(y) != 0)[0] + 1])]
    assert np.mean(levels) == pytest.approx(5.0, abs=0.3)


def lfsr_bits(order, taps, register, count):
    """Independent Fibonacci LFSR (feedback = XOR of the tap bits, shifted in at the bottom)."""
    bits = []
    for _ in range(count):
        b = 0
        for tap in taps:
            b ^= (register >> (tap - 1)) & 1
        register = ((register << 1) | b) & ((1 << order) - 1)
        bits.append(b)
    return np.array(bits)


def test_prbs_is_the_maximum_length_sequence():
    order, tb, seed = 7, 0.1, 3
    n_bits = 2 * (2**order - 1)
    r = simulate(stop=n_bits * tb, h=tb, waveform=PRBS, prbs_order=order, bit_period=tb,
                 amplitude=0.5, offset=1.0, seed=seed)
    bits = lfsr_bits(order, [7, 6], 1 + seed % (2**order - 1), n_bits)
    expected = np.where(bits == 1, 1.5, 0.5)
    assert np.array_equal(r["y"][:n_bits], expected)
    period = 2**order - 1
    assert np.array_equal(r["y"][:period], r["y"][period : 2 * period])
    assert np.sum(bits[:period]) == 2 ** (order - 1)


def test_same_seed_same_signal_other_seed_other_signal():
    a = simulate(stop=50.0, h=0.1, waveform=RANDOM_STEPS, seed=9)
    b = simulate(stop=50.0, h=0.1, waveform=RANDOM_STEPS, seed=9)
    c = simulate(stop=50.0, h=0.1, waveform=RANDOM_STEPS, seed=10)
    assert np.array_equal(a["y"], b["y"])
    assert not np.array_equal(a["y"], c["y"])
    # the signal does not depend on the communication step
    fine = simulate(stop=50.0, h=0.01, waveform=RANDOM_STEPS, seed=9)
    assert np.array_equal(fine["y"][::10], a["y"])


def test_fmu_state_restores_the_signal():
    s, vr, _ = open_slave("SignalSource")
    s.setInteger([vr["waveform"], vr["seed"]], [RANDOM_STEPS, 5])
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    t = 0.0
    for _ in range(100):
        s.doStep(t, 0.1)
        t += 0.1
    state = s.getFMUstate()
    blob = s.serializeFMUstate(state)

    def run(t):
        out = []
        for _ in range(200):
            s.doStep(t, 0.1)
            t += 0.1
            out.append(s.getReal([vr["y"]])[0])
        return out

    first = run(t)
    s.setFMUstate(state)
    assert run(t) == first
    s.setFMUstate(s.deSerializeFMUstate(blob))
    assert run(t) == first
    s.freeInstance()


@pytest.mark.parametrize(
    "name,value",
    [("period", 0.0), ("period", -1.0), ("min_hold", 0.0), ("bit_period", 1e-300),
     ("prbs_order", 30), ("amplitude", 1e308)],
)
def test_parameter_outside_its_declared_range_is_refused_when_set(name, value):
    s, vr, sink = open_slave("SignalSource")
    assert_set_rejected(s, vr, sink, name, value, f"`{name}`", "its m")
    s.freeInstance()


def test_random_steps_far_from_the_origin_fail_instead_of_hanging():
    s, vr, sink = open_slave("SignalSource")
    set_values(s, vr, {"waveform": RANDOM_STEPS})
    s.setupExperiment(startTime=1e12)
    s.enterInitializationMode()
    with pytest.raises(FMICallException):
        s.exitInitializationMode()
    assert any("t = 1000000000000 s" in t and "holds" in t for t in sink.texts(3)), sink.messages
    s.freeInstance()


@pytest.mark.parametrize(
    "waveform,name,value",
    [(RANDOM_STEPS, "max_hold", 0.5), (RANDOM_STEPS, "amplitude", -1.0)],
)
def test_bad_parameter_is_an_error_naming_it(waveform, name, value):
    s, vr, sink = open_slave("SignalSource")
    set_values(s, vr, {"waveform": waveform, name: value})
    assert_initialization_fails_naming(s, sink, name)


def test_unknown_waveform_is_rejected():
    s, vr, sink = open_slave("SignalSource")
    assert_set_rejected(s, vr, sink, "waveform", 7)
    s.freeInstance()
