"""The discrete FMUs sample on their own clock (docs/README.md#sampling), in fmpy.

A discrete FMU samples at t_0 + k·T (T = `sample_period`, k an integer, compared within
1e-9·T at the start), whatever the master's steps: LinearSystem (discrete time, rule "the step from t_k
processes the input set at t_k") and Sensor (rule "sample k when a step's end reaches t_k")
with fmpy stepping at T, T/2 and 2T, and with OMSimulator's timing (time accumulated by
t += h, then a last step of ~1e-15 s to the stop time) against fmpy's own t_0 + n·h.
"""

import numpy as np
from fmpy import simulate_fmu

from conftest import fmu_path, init, open_slave, set_values

T = 0.1
# The default LinearSystem: x₁⁺ = 0.9 x₁ + 0.1 x₂, x₂⁺ = 0.9 x₂ + u, y = x₁ (+ noise).
A = np.array([[0.9, 0.1], [0.0, 0.9]])
B = np.array([0.0, 1.0])
NOISE_OFF = {"Q[1,1]": 0.0, "Q[2,2]": 0.0, "R[1,1]": 0.0}


def stepped(name, steps, inputs=None, start=None, outputs=("x[1]", "x[2]")):
    """Steps FMU `name` through `steps` ((time, size) pairs) with fmpy's FMU2Slave, setting
    `u[1]` = inputs[i] before step i; returns the outputs read after each step."""
    slave, vr, _ = open_slave(name)
    set_values(slave, vr, start or {})
    init(slave, steps[0][0])
    rows = []
    for i, (t, h) in enumerate(steps):
        if inputs is not None:
            slave.setReal([vr["u[1]"]], [inputs[i]])
        slave.doStep(t, h)
        rows.append(slave.getReal([vr[n] for n in outputs]))
    slave.terminate()
    slave.freeInstance()
    return np.array(rows)


def regular(h, n):
    return [(k * h, h) for k in range(n)]


def recursion(u):
    """x_{k+1} = A x_k + B u_k from x_0 = 0: the states after each sample."""
    x, out = np.zeros(2), []
    for uk in u:
        x = A @ x + B * uk
        out.append(x.copy())
    return np.array(out)


U = np.sin(0.7 * np.arange(40)) + 0.5


def test_linear_system_at_the_sample_period_is_the_recursion():
    start = {**NOISE_OFF, "sample_period": T}
    got = stepped("LinearSystem", regular(T, 40), U, start)
    np.testing.assert_allclose(got, recursion(U), rtol=0, atol=1e-12)
    # The default period (0: the first step's size) gives the same, bit for bit.
    np.testing.assert_array_equal(stepped("LinearSystem", regular(T, 40), U, NOISE_OFF), got)


def test_linear_system_at_half_the_period_holds_every_other_step():
    # The input set at t_k + T/2 (here -5) must not be used: only the one at t_k is sampled.
    inputs = np.ravel([(uk, -5.0) for uk in U])
    start = {**NOISE_OFF, "sample_period": T}
    got = stepped("LinearSystem", regular(T / 2, 80), inputs, start)
    expected = np.repeat(recursion(U), 2, axis=0)  # x_{k+1} at t_k + T/2 and at t_{k+1}
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12)


def test_linear_system_at_twice_the_period_takes_two_samples_per_step():
    u = U[::2]
    start = {**NOISE_OFF, "sample_period": T}
    got = stepped("LinearSystem", regular(2 * T, 20), u, start)
    # Each step takes t_2j and t_2j+1 with its input held.
    expected = recursion(np.repeat(u, 2))[1::2]
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12)


def accumulated(h, stop):
    """OMSimulator's steps: t += h while t < stop (less than h/2 short of it), then one last
    step to the stop time."""
    steps, t = [], 0.0
    while stop - t > h / 2:
        steps.append((t, h))
        t += h
    if stop - t > 0:
        steps.append((t, stop - t))
    return steps


def test_accumulated_time_and_a_tiny_last_step_take_the_samples_fmpy_takes():
    steps = accumulated(T, 10.0)
    assert len(steps) == 101 and 0 < steps[-1][1] < 1e-13, steps[-1]
    for name, outputs in [("LinearSystem", ("y[1]", "x[1]", "x[2]")),
                          ("Sensor2", ("y[1]", "y[2]", "y_clean[1]"))]:
        start = {"sample_period": T}
        oms = stepped(name, steps, None, start, outputs)
        fmpy = simulate_fmu(fmu_path(name), fmi_type="CoSimulation", stop_time=10.0,
                            step_size=T, output_interval=T, start_values=start)
        assert len(fmpy) == 101  # t = 0 and the 100 points after each step
        for j, n in enumerate(outputs):
            # Noise on: one sample more would change every later value.
            np.testing.assert_array_equal(oms[:100, j], fmpy[n][1:], err_msg=n)
            # The last step of ~2e-14 s took no sample: the outputs hold.
            assert oms[100, j] == oms[99, j], n


def test_sensor_at_half_and_twice_the_period():
    start = {"sample_period": T}
    at_t = stepped("Sensor", regular(T, 20), None, start, ("y[1]",))[:, 0]
    assert len(set(at_t)) == 20  # a fresh noise draw at every point
    half = stepped("Sensor", regular(T / 2, 40), None, start, ("y[1]",))[:, 0]
    # At t_k + T/2 the sample of t_k holds (before the first instant: the initial draw).
    np.testing.assert_array_equal(half[1::2], at_t)
    np.testing.assert_array_equal(half[2::2], at_t[:-1])
    double = stepped("Sensor", regular(2 * T, 10), None, start, ("y[1]",))[:, 0]
    # A step of 2T draws at t + T and t + 2T and shows the second.
    np.testing.assert_array_equal(double, at_t[1::2])
