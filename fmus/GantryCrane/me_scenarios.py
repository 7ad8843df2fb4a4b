"""Model Exchange scenarios of GantryCrane.fmu: each is simulated by fmpy's CVode (relative
tolerance 1e-8) through Model Exchange and compared with the Co-Simulation FMU (RK4, 1 ms
substeps) on the same grid; `event_times` are the instants of the state events, computed
independently (`crane_reference` below: numpy RK4 with 0.5 ms steps and bisection on the
indicators to 1e-13 s)."""

import numpy as np

PARAMETERS = dict(M=0.84385, m=0.013, l=0.3434, J=1e-5, f_c=0.67, f_p=9.3e-6, g=9.8, U_max=17.0,
                  x_limit=0.5)


def crane_rhs(s, force, held, M, m, l, J, f_c, f_p, g, **_):
    """[ẋ, θ̇, ẍ, θ̈] of the crane, free or held against a stop (written from docs/models.md §2.1)."""
    x, th, v, om = s
    sin, cos = np.sin(th), np.cos(th)
    inertia = J + m * l * l
    if held:
        return np.array([0.0, om, 0.0, (-f_p * om - m * g * l * sin) / inertia])
    # [[M + m, −m l cos θ], [−m l cos θ, J + m l²]] [ẍ, θ̈] = [F − f_c ẋ − m l θ̇² sin θ, −f_p θ̇ − m g l sin θ]
    a11, a12, a22 = M + m, -m * l * cos, inertia
    b1 = force - f_c * v - m * l * om * om * sin
    b2 = -f_p * om - m * g * l * sin
    det = a11 * a22 - a12 * a12
    return np.array([v, om, (a22 * b1 - a12 * b2) / det, (a11 * b2 - a12 * b1) / det])


def crane_reference(s0, force, stop_time, h=5e-4, **p):
    """The crane from `s0` under a constant requested `force`, with its rail stops: RK4 steps
    of `h`, each event located by bisection on the step length to 1e-13 s. Returns the event
    times, a list of (time, what) and the final state."""
    p = {**PARAMETERS, **p}
    force = float(np.clip(force, -p["U_max"], p["U_max"]))
    limit = p["x_limit"]
    held = 0  # 0 free, ±1 held against the stop on that side

    def rk4(s, dt):
        k1 = crane_rhs(s, force, held, **p)
        k2 = crane_rhs(s + dt / 2 * k1, force, held, **p)
        k3 = crane_rhs(s + dt / 2 * k2, force, held, **p)
        k4 = crane_rhs(s + dt * k3, force, held, **p)
        return s + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)

    def indicator(s):
        free_xdd = crane_rhs(s, force, 0, **p)[2]
        if held:
            return held * free_xdd  # positive while pushed into the stop
        return min(limit - s[0], s[0] + limit)

    t, s, events = 0.0, np.array(s0, dtype=float), []
    while t < stop_time - 1e-12:
        dt = min(h, stop_time - t)
        nxt = rk4(s, dt)
        if indicator(nxt) < 0 or (held == 0 and indicator(s) > 0 and indicator(nxt) <= 0):
            lo, hi = 0.0, dt
            while hi - lo > 1e-13:
                mid = 0.5 * (lo + hi)
                if indicator(rk4(s, mid)) < 0 or (held == 0 and indicator(rk4(s, mid)) <= 0):
                    hi = mid
                else:
                    lo = mid
            s, t = rk4(s, hi), t + hi
            if held:
                held = 0
                events.append((t, "release"))
            else:
                side = np.sign(s[0])
                s[0] = side * limit
                if side * s[2] > 0:
                    s[2] = 0.0
                if side * crane_rhs(s, force, 0, **p)[2] >= 0:
                    held = int(side)
                events.append((t, "held" if held else "bounce"))
            continue
        s, t = nxt, t + dt
    return events, s


# One entry a scenario (the contract of tests/fmpy/test_model_exchange.py): start values,
# inputs, stop time, the outputs compared with Co-Simulation (RK4, 1 ms substeps, communication
# step = output_interval) and how closely, and the independent event times (1e-6 s).
_HIT = crane_reference([0.0, 0.0, 0.0, 0.0], 3.0, 2.0)[0]
_BOUNCES = crane_reference([0.45, 0.3, 0.5, 0.0], 0.02, 3.0)[0]
_STATES = ["x", "theta", "v", "omega"]

SCENARIOS = [
    # off the stops: CVode (1e-8) against RK4 (1 ms), measured 2.0e-6 relative
    dict(fmu="GantryCrane", name="free_swing", start_values={"theta0": 0.2}, stop_time=10.0,
         output_interval=0.01, outputs=_STATES, rtol=1e-5, atol=1e-6, event_times=[]),
    dict(fmu="GantryCrane", name="step_force", start_values={"U": 1.0},
         inputs=[(0.0, {"U": 1.0})], stop_time=1.0, output_interval=0.01, outputs=_STATES,
         rtol=1e-5, atol=1e-6, event_times=[]),
    # at a stop Co-Simulation resolves the contact to one RK4 substep (1 ms): measured 8e-4
    # of the largest value, so the agreement asked for is that of a 1 ms contact time
    dict(fmu="GantryCrane", name="rail_stop_sustained_push", start_values={"U": 3.0},
         inputs=[(0.0, {"U": 3.0})], stop_time=2.0, output_interval=0.01, outputs=_STATES,
         rtol=1e-2, atol=5e-3, event_times=[t for t, _ in _HIT]),
    dict(fmu="GantryCrane", name="held_and_released_by_the_swing",
         start_values={"U": 0.02, "x0": 0.45, "v0": 0.5, "theta0": 0.3},
         inputs=[(0.0, {"U": 0.02})], stop_time=3.0, output_interval=0.01, outputs=_STATES,
         rtol=1e-2, atol=5e-3, event_times=[t for t, _ in _BOUNCES]),
    # the defaults (what fmuCheck -k me runs, with forward Euler at ~output_interval / 10:
    # 1.2 s and 5 ms keep its growing swing within 1 %): the push as an input signal only
    dict(fmu="GantryCrane", name="push_into_the_stop_with_the_defaults",
         inputs=[(0.0, {"U": 3.0})], stop_time=1.2, output_interval=0.005, outputs=_STATES,
         rtol=1e-2, atol=5e-3, event_times=[t for t, _ in _HIT]),
]


def random_point(rng, start):
    """States anywhere on the rail and swinging, a force inside ±U_max (the Jacobian of the
    saturation is 0 beyond): for the directional-derivative check."""
    states = dict(x=rng.uniform(-0.4, 0.4), theta=rng.uniform(-1.5, 1.5), v=rng.uniform(-2, 2),
                  omega=rng.uniform(-4, 4))
    return states, {"U": rng.uniform(-15.0, 15.0)}
