"""OpAmpFilter.fmu through fmpy: validation, the unit-step figures of paper 002's filter
measured from the FMU's output (ω_n, ζ, overshoot, 2 % settling time), clipping at the rails,
step-size independence, several instances, bad parameters named."""

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException
from fmpy.validation import validate_fmu

from conftest import (assert_initialization_fails_naming, assert_set_rejected, fmu_path, init, open_slave,
                      simulate_packaged)


def simulate(stop=5.0, h=1e-3, u=1.0, **start):
    return simulate_packaged("OpAmpFilter", stop, h, start, [(0.0, u)], ["u"])


def step_figures(t, y, final=1.0):
    """Peak time, overshoot and 2 % settling time measured from a sampled step response
    (parabolic refinement of the peak, linear interpolation of the last band crossing), and
    ζ, ω_n derived from them (ζ from the overshoot, ω_n from the peak time π/ω_d)."""
    k = int(np.argmax(y))
    a, b, c = y[k - 1], y[k], y[k + 1]
    h = t[1] - t[0]
    shift = 0.5 * (a - c) / (a - 2 * b + c)
    peak_time = t[k] + shift * h
    peak = b - 0.25 * (a - c) * shift
    overshoot = (peak - final) / final
    outside = np.where(np.abs(y - final) > 0.02 * final)[0]
    j = outside[-1]
    e0, e1 = abs(y[j] - final), abs(y[j + 1] - final)
    settling = t[j] + (e0 - 0.02 * final) / (e0 - e1) * h
    log = np.log(overshoot)
    zeta = -log / np.sqrt(np.pi**2 + log**2)
    omega_n = np.pi / peak_time / np.sqrt(1 - zeta**2)
    return omega_n, zeta, overshoot, settling, peak_time


def test_validates_without_problems():
    assert validate_fmu(fmu_path("OpAmpFilter")) == []


def test_unit_step_response_has_the_papers_figures():
    r = simulate(stop=5.0, h=1e-3)
    omega_n, zeta, overshoot, settling, peak_time = step_figures(r["time"], r["y"])
    print(
        f"op-amp unit step (FMU, 1 ms output): omega_n {omega_n:.5f} rad/s, zeta {zeta:.5f}, "
        f"overshoot {100 * overshoot:.3f} %, 2 % settling {settling:.4f} s, peak {peak_time:.4f} s"
    )
    close = lambda got, want: abs(got - want) / want < 0.005
    assert close(omega_n, 5.196), omega_n
    assert close(zeta, 0.4994), zeta
    assert close(overshoot, 0.163), overshoot
    assert close(settling, 1.55), settling
    assert r["y"][-1] == pytest.approx(1.0, abs=1e-4)


def test_output_clips_at_the_rails():
    r = simulate(stop=3.0, h=0.01, u=30.0)
    assert np.max(r["y"]) == 12.0
    assert r["y"][-1] == 12.0 and r["saturated"][-1]
    assert np.max(r["v_C2"]) > 12.0  # the + input goes on, the output does not
    r = simulate(stop=3.0, h=0.01, u=-30.0, V_sat_low=-5.0)
    assert np.min(r["y"]) == -5.0 and r["y"][-1] == -5.0


def test_response_does_not_depend_on_the_communication_step():
    fine = simulate(stop=2.0, h=0.001)
    coarse = simulate(stop=2.0, h=0.1)
    assert np.max(np.abs(fine["y"][::100] - coarse["y"])) < 1e-9


def test_component_values_set_the_transfer_function():
    # doubling both capacitors halves ω_n and keeps ζ: the peak comes twice as late
    base = step_figures(*(lambda r: (r["time"], r["y"]))(simulate(stop=5.0)))
    slow = simulate(stop=10.0, C1=9.4e-6, C2=2e-6)
    slow = step_figures(slow["time"], slow["y"])
    assert slow[0] == pytest.approx(base[0] / 2, rel=1e-3)
    assert slow[1] == pytest.approx(base[1], rel=1e-3)


def test_two_instances_interleaved_equal_separate_runs():
    def run(slaves, inputs):
        out = [[] for _ in slaves]
        t = 0.0
        for k in range(300):
            for i, (s, vr) in enumerate(slaves):
                s.setReal([vr["u"]], [inputs[i](k)])
                s.doStep(t, 0.01)
                out[i].append(s.getReal([vr["y"]])[0])
            t += 0.01
        return [np.array(o) for o in out]

    ua, ub = (lambda k: np.sin(0.05 * k)), (lambda k: 1.0 if k < 100 else -2.0)
    a, vr, _ = open_slave("OpAmpFilter", "a")
    init(a)
    (alone_a,) = run([(a, vr)], [ua])
    a.freeInstance()
    a, _, _ = open_slave("OpAmpFilter", "a")
    b, _, _ = open_slave("OpAmpFilter", "b")
    init(a)
    init(b)
    ra, rb = run([(a, vr), (b, vr)], [ua, ub])
    assert np.array_equal(ra, alone_a)
    assert rb[-1] == pytest.approx(-2.0, abs=0.05)
    a.freeInstance()
    b.freeInstance()


@pytest.mark.parametrize("name,value,bound", [("R1", 0.0, "below its minimum 1"),
                                              ("C2", -1e-6, "below its minimum"),
                                              ("h_max", 1e-300, "below its minimum"),
                                              ("v_C1_0", 1e308, "above its maximum 1000")])
def test_parameter_outside_its_declared_range_is_refused_when_set(name, value, bound):
    s, vr, sink = open_slave("OpAmpFilter")
    assert_set_rejected(s, vr, sink, name, value, f"`{name}`", bound)
    s.freeInstance()


@pytest.mark.parametrize("name,value", [("V_sat_low", 20.0), ("h_max", 0.5)])
def test_bad_parameter_is_an_error_naming_it(name, value):
    s, vr, sink = open_slave("OpAmpFilter")
    s.setReal([vr[name]], [value])
    assert_initialization_fails_naming(s, sink, name)
