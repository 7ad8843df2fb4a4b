"""Sensor.fmu and Sensor2.fmu through fmpy: validation, the statistics of 10^5 samples
(outlier fraction, noise variance), bit-identical seeded runs in separate instances, one draw
per communication point under direct feedthrough, the outlier window, SNR mode, the ADC, FMU
state replay and bad parameters."""

import numpy as np
import pytest
from fmpy import simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.validation import validate_fmu

from conftest import assert_initialization_fails_naming, assert_set_rejected, fmu_path, init, open_slave, set_values, simulate_packaged

N = 100_000


def simulate(name="Sensor", n=N, h=0.1, **start):
    return simulate_packaged(name, n * h, h, start)


@pytest.mark.parametrize("name", ["Sensor", "Sensor2"])
def test_validates_without_problems(name):
    assert validate_fmu(fmu_path(name)) == []


def test_outlier_fraction_and_noise_variance_over_1e5_samples():
    eps, var = 0.05, 0.01
    r = simulate(seed=7, **{"epsilon[1]": eps, "variance[1]": var})
    assert len(r) == N + 1
    flags = r["outlier[1]"]
    fraction = flags.mean()
    sigma = np.sqrt(eps * (1 - eps) / len(r))
    e = r["y[1]"] - r["y_clean[1]"]
    noise = e[~flags]
    measured_var = noise.var()
    print(
        f"outlier fraction {fraction:.5f} (epsilon {eps}, 3 sigma {3 * sigma:.5f}); "
        f"noise variance {measured_var:.6f} (setting {var}, {100 * (measured_var / var - 1):+.2f} %)"
    )
    assert abs(fraction - eps) < 3 * sigma
    assert abs(measured_var / var - 1) < 0.02
    # outliers are heavy: U(0, 4.8) magnitudes, both signs
    spikes = e[flags]
    assert np.max(np.abs(spikes)) > 4.0 and np.min(spikes) < -4.0 and np.max(spikes) > 4.0
    assert np.mean(np.abs(spikes)) == pytest.approx(2.4, rel=0.05)


def test_snr_in_db_sets_the_variance():
    r = simulate(n=20_000, seed=3, **{"use_snr[1]": True, "snr_db[1]": 20.0,
                                      "signal_power[1]": 0.5, "epsilon[1]": 0.0})
    e = r["y[1]"] - r["y_clean[1]"]
    assert not r["outlier[1]"].any()
    assert e.var() == pytest.approx(0.005, rel=0.05)


def test_outliers_only_inside_their_window():
    r = simulate(n=2000, seed=5, **{"epsilon[1]": 0.2, "outlier_window[1]": True,
                                    "outlier_t_start[1]": 10.0, "outlier_t_end[1]": 50.0})
    t, flags = r["time"], r["outlier[1]"]
    assert not flags[(t < 10.0 - 1e-9) | (t >= 50.0 - 1e-9)].any()
    inside = flags[(t >= 10.0) & (t < 50.0 - 1e-9)]
    assert 0.1 < inside.mean() < 0.3


def run_slave(slave, vr, n, u, h=0.1, t0=0.0, names=("y[1]", "y_clean[1]")):
    out, flags = [], []
    t = t0
    refs = [vr[k] for k in names]
    for k in range(n):
        slave.setReal([vr["u[1]"]], [u(k)])
        out.append(slave.getReal(refs))
        flags.append(slave.getBoolean([vr["outlier[1]"]])[0])
        slave.doStep(t, h)
        t += h
    return np.array(out), np.array(flags)


def test_same_seed_is_bit_identical_in_two_instances_and_another_seed_differs():
    u = lambda k: np.sin(0.01 * k)
    slaves = []
    for name, seed in [("a", 11), ("b", 11), ("c", 12)]:
        s, vr, _ = open_slave("Sensor", name)
        s.setInteger([vr["seed"]], [seed])
        init(s)
        slaves.append(s)
    # interleaved, one step each in turn
    res = [[], [], []]
    t = 0.0
    for k in range(2000):
        for i, s in enumerate(slaves):
            s.setReal([vr["u[1]"]], [u(k)])
            res[i].append(s.getReal([vr["y[1]"]])[0])
            s.doStep(t, 0.1)
        t += 0.1
    a, b, c = (np.array(x) for x in res)
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)
    for s in slaves:
        s.freeInstance()
    # and a run alone (simulate_fmu, another process-level instance) gives the same samples
    inputs = np.array([(0.1 * k, u(k)) for k in range(2001)],
                      dtype=[("time", np.float64), ("u[1]", np.float64)])
    r = simulate_fmu(fmu_path("Sensor"), stop_time=199.9, output_interval=0.1,
                     start_values={"seed": 11}, input=inputs)
    # simulate_fmu records the outputs right after each step (computed with the input of the
    # step's start), so compare the noise + outlier part, y - y_clean
    noise = a - np.array([u(k) for k in range(2000)])
    assert np.allclose((r["y[1]"] - r["y_clean[1]"])[:2000], noise, rtol=0, atol=1e-12)


def test_one_draw_per_point_when_the_input_is_set_again():
    s, vr, _ = open_slave("Sensor")
    init(s)
    t = 0.0
    for k in range(100):
        s.setReal([vr["u[1]"]], [1.0])
        y1 = s.getReal([vr["y[1]"]])[0]
        y1b = s.getReal([vr["y[1]"]])[0]
        s.setReal([vr["u[1]"]], [4.0])
        y2 = s.getReal([vr["y[1]"]])[0]
        assert y1 == y1b
        assert y2 - y1 == pytest.approx(3.0, abs=1e-12)
        assert s.getReal([vr["y_clean[1]"]])[0] == 4.0
        s.doStep(t, 0.1)
        t += 0.1
    s.freeInstance()


def test_two_channels_have_independent_streams():
    r = simulate("Sensor2", n=20_000, seed=1, **{"epsilon[1]": 0.0, "epsilon[2]": 0.0})
    e1, e2 = r["y[1]"], r["y[2]"]
    assert abs(np.corrcoef(e1, e2)[0, 1]) < 0.03
    one = simulate("Sensor", n=20_000, seed=1, **{"epsilon[1]": 0.0})
    assert np.array_equal(one["y[1]"], e1)  # channel 1 of Sensor2 = Sensor with the same seed


def test_adc_quantisation_step():
    s, vr, _ = open_slave("Sensor")
    s.setInteger([vr["adc_bits[1]"]], [12])
    s.setReal([vr["adc_min[1]"], vr["adc_max[1]"], vr["variance[1]"], vr["epsilon[1]"]],
              [0.0, 3.3, 0.0, 0.0])
    init(s)
    q = 3.3 / 4096
    t = 0.0
    values = np.linspace(0.2, 3.1, 300)
    for v in values:
        s.setReal([vr["u[1]"]], [v])
        y = s.getReal([vr["y[1]"]])[0]
        code = y / q
        assert code == pytest.approx(round(code), abs=1e-9)
        assert abs(y - v) <= 0.5 * q + 1e-12
        s.doStep(t, 0.1)
        t += 0.1
    s.setReal([vr["u[1]"]], [50.0])
    assert s.getReal([vr["y[1]"]])[0] == pytest.approx(3.3 - q, abs=1e-12)
    s.freeInstance()


def test_fmu_state_replays_the_same_samples():
    s, vr, _ = open_slave("Sensor")
    init(s)
    run_slave(s, vr, 50, lambda k: 0.0)
    state = s.getFMUstate()
    blob = s.serializeFMUstate(state)
    u = lambda k: np.cos(0.1 * k)
    first = run_slave(s, vr, 100, u, t0=5.0)
    s.setFMUstate(state)
    again = run_slave(s, vr, 100, u, t0=5.0)
    s.setFMUstate(s.deSerializeFMUstate(blob))
    third = run_slave(s, vr, 100, u, t0=5.0)
    assert np.array_equal(first[0], again[0]) and np.array_equal(first[1], again[1])
    assert np.array_equal(first[0], third[0])
    s.freeInstance()


def test_epsilon_outside_0_1_is_an_error_naming_it():
    s, vr, sink = open_slave("Sensor")
    set_values(s, vr, {"epsilon[1]": 1.5})
    assert_initialization_fails_naming(s, sink, "epsilon[1]", "[0, 1]")


def test_negative_variance_is_an_error_naming_it():
    s, vr, sink = open_slave("Sensor2")
    assert_set_rejected(s, vr, sink, "variance[2]", -0.1)
    # inconsistent outlier magnitudes are caught at initialisation, naming the parameter
    s.setBoolean([vr["use_snr[2]"]], [True])
    s.setReal([vr["outlier_max[2]"]], [0.5])
    s.setReal([vr["outlier_min[2]"]], [1.0])
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    with pytest.raises(FMICallException):
        s.exitInitializationMode()
    assert any("outlier_max[2]" in t for t in sink.texts(3)), sink.messages
    s.freeInstance()
