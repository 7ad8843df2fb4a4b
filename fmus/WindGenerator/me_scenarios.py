"""Model Exchange scenarios of WindGenerator for tests/fmpy/test_model_exchange.py.

Start-up from rest at the rated references with a weaker motor (T_max = 2 N.m instead of
3.4, still above the 1.4 N.m the rated point needs), so that the motor torque reaches its
breakdown limit +T_max during the start-up and leaves it as the shaft catches up (two state
events); then the drive reference steps down to 6 V at 3 s. The angle's wrap-arounds (one per electrical turn, 60 a second at 1800 rpm) are state
events too. The Co-Simulation side runs its adaptive integrator at rtol 1e-10 so its error is
far below CVode's.
"""

import numpy as np

T_MAX = 2.0

# When the start-up with T_max = 2 N.m enters and leaves the torque limit, located without
# any FMU or solver (src/plants/wind_generator.rs, test
# start_up_with_a_weak_motor_enters_and_leaves_the_torque_limit_at_the_pinned_times: RK4 on
# 1 us steps and bisection of the indicator).
TORQUE_LIMIT_EVENTS = [0.0519131345, 0.9296098032]


def torque_events_agree(me, cs):
    """Each time CS sees the torque at a limit, ME holds it there too (and the other way
    round), away from the switching instants."""
    t = cs["time"]
    me_t_m = np.interp(t, me["time"], me["T_m"])
    on_limit_cs = np.isclose(np.abs(cs["T_m"]), T_MAX, rtol=0, atol=1e-9)
    on_limit_me = np.isclose(np.abs(me_t_m), T_MAX, rtol=0, atol=1e-6)
    assert on_limit_cs.any(), "the start-up never reached T_max"
    assert np.mean(on_limit_cs == on_limit_me) > 0.97
    # CVode locates both torque-limit events within 1e-6 s (the angle's turns are events too,
    # ~16 ms apart, so the nearest event to each expected time is the torque's).
    t_me = me["time"]
    events = t_me[1:][np.diff(t_me) == 0]
    for expected in TORQUE_LIMIT_EVENTS:
        error = np.min(np.abs(events - expected))
        assert error < 1e-6, f"no event within 1e-6 s of {expected} (nearest {error:.3g} s away)"


START_UP = dict(
    fmu="WindGenerator",
    name="start_up",
    stop_time=5.0,
    output_interval=0.01,
    start_values={"rtol": 1e-10, "T_max": T_MAX},
    inputs=[(0.0, {"u_drive": 10.0, "u_field": 8.0}), (3.0, {"u_drive": 10.0, "u_field": 8.0}),
            (3.0, {"u_drive": 6.0, "u_field": 8.0}), (5.0, {"u_drive": 6.0, "u_field": 8.0})],
    outputs=["speed", "voltage", "T_m", "T_e", "field_current", "i_d", "i_q"],
    rtol=1e-5,
    atol=1e-6,
    check=torque_events_agree,
)

SCENARIOS = [
    START_UP,
    # The defaults (T_max = 3.4 N.m: the torque stays off its limit; CS at rtol 7e-12), which is
    # also the one tests/interop runs in fmuCheck -k me (it cannot set start values).
    dict(START_UP, name="start_up_defaults", start_values={}, check=None),
]


def random_point(rng, start):
    """States across the working range (speeds up to 250 rad/s, currents of a few A) and
    references inside (0, 10) V, where they are not clipped."""
    states = {
        "i_d": rng.uniform(-2, 2),
        "i_q": rng.uniform(-2, 2),
        "field_current": rng.uniform(0, 1),
        "field_voltage": rng.uniform(0, 125),
        "omega_m": rng.uniform(0, 250),
        "theta_e": rng.uniform(0, 6),
        "omega_s": rng.uniform(0, 250),
        "omega_tach": rng.uniform(0, 250),
    }
    # keep the motor torque off its limits (the limit held since the last event is Linear)
    states["omega_s"] = states["omega_m"] + rng.uniform(-15, 15)
    inputs = {"u_drive": rng.uniform(0.5, 9.5), "u_field": rng.uniform(0.5, 9.5)}
    return states, inputs
