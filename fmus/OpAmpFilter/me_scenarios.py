"""Model Exchange scenarios of OpAmpFilter for tests/fmpy/test_model_exchange.py.

A step into saturation: u = 20 V at 0.5 s drives v_C2 through the upper rail (the output stops
at 12 V while v_C2 goes on towards 20 V), then u = -20 V at 3 s takes it back through the
upper rail and down through the lower one. The expected event times are computed here,
independently of the FMU and of CVode, from the exact solution of the circuit, which is
affine in each mode (inside the rails and on a rail): x(t) = x_eq + exp(M t) (x0 - x_eq),
with the crossing of the rail found by bisection to 1e-13 s.
"""

import numpy as np

# The defaults of OpAmpFilterParameters (src/plants/opamp_filter.rs).
R1, R2 = 132_950.289_072_002_9, 59_271.933_150_219_34
C1, C2 = 4.7e-6, 1e-6
HIGH, LOW = 12.0, -12.0

STEPS = [(0.0, 0.0), (0.5, 20.0), (3.0, -20.0)]  # (from time, u)
STOP = 6.0


def affine(u, rail):
    """(M, c) of x' = M x + c on `rail` (None inside, else the output's voltage)."""
    g = 1.0 / R1 + 1.0 / R2
    if rail is None:  # y = v2
        m = np.array([[-g / C1, -1.0 / (R1 * C1)], [1.0 / (R2 * C2), 0.0]])
        c = np.array([u / (R1 * C1), 0.0])
    else:  # y = rail
        m = np.array([[-g / C1, 1.0 / (R2 * C1)], [1.0 / (R2 * C2), -1.0 / (R2 * C2)]])
        c = np.array([(u - rail) / (R1 * C1) - rail / (R2 * C1), rail / (R2 * C2)])
    return m, c


def flow(x0, u, rail, t):
    """The exact state after t seconds from x0."""
    m, c = affine(u, rail)
    x_eq = -np.linalg.solve(m, c)
    values, vectors = np.linalg.eig(m)
    expm = (vectors @ np.diag(np.exp(values * t)) @ np.linalg.inv(vectors)).real
    return x_eq + expm @ (x0 - x_eq)


def rail_of(v2):
    return HIGH if v2 >= HIGH else LOW if v2 <= LOW else None


def exact_event_times():
    """The times v_C2 crosses a rail, in order."""
    events, x, rail, t = [], np.zeros(2), None, 0.0
    bounds = [s[0] for s in STEPS[1:]] + [STOP]
    for (start, u), end in zip(STEPS, bounds):
        t = start
        while t < end:

            def z(s, x=x, u=u, rail=rail, t=t):
                v2 = flow(x, u, rail, s - t)[1]
                return np.array([HIGH - v2, v2 - LOW])

            grid = np.arange(t, end, 1e-3)
            grid = np.append(grid[1:], end)
            z0, crossed = z(t), None
            for s in grid:
                zs = z(s)
                if np.any(np.sign(zs) != np.sign(z0)) and np.all(z0 != 0):
                    crossed = s
                    break
            if crossed is None:
                x, t = flow(x, u, rail, end - t), end
                break
            a, b = crossed - 1e-3, crossed
            while b - a > 1e-13:
                mid = 0.5 * (a + b)
                if np.any(np.sign(z(mid)) != np.sign(z0)):
                    b = mid
                else:
                    a = mid
            x = flow(x, u, rail, b - t)
            t = b
            events.append(float(b))
            rail = rail_of(x[1])
    return events


INPUTS = [(0.0, {"u": 0.0}), (0.5, {"u": 0.0}), (0.5, {"u": 20.0}),
          (3.0, {"u": 20.0}), (3.0, {"u": -20.0}), (STOP, {"u": -20.0})]

STEP_INTO_SATURATION = dict(
    fmu="OpAmpFilter",
    name="step_into_saturation",
    stop_time=STOP,
    output_interval=0.01,
    # The CS side on a fine RK4 grid, so its error at the rails' kinks is below CVode's.
    start_values={"h_max": 1e-5},
    inputs=INPUTS,
    outputs=["y", "v_C1", "v_C2"],
    rtol=1e-6,
    atol=1e-6,
    # fmpy's loop also records the input's steps (time events) as events.
    event_times=sorted([0.5, 3.0] + exact_event_times()),
)

SCENARIOS = [
    STEP_INTO_SATURATION,
    # The same with the defaults (the CS side's RK4 at h_max = 1 ms), which is also the one
    # tests/interop runs in fmuCheck -k me (it cannot set start values).
    dict(STEP_INTO_SATURATION, name="step_into_saturation_defaults", start_values={},
         rtol=1e-5, atol=1e-5),
]
