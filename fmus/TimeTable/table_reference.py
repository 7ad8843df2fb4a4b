"""What a table reads at a time, written out in Python independently of the Rust code
(spurio_table): the reference of the TimeTable tests in fmpy and in the other FMI tools.

At time t, with t_i the last sample at or before t (within 1e-9 of a sampling interval: the
rule of spurio_table::instant near the start of a table), a column u reads u_i (hold) or
u_i + (u_{i+1} − u_i)·((t − t_i)/(t_{i+1} − t_i)) (linear; exactly u_i within that rounding of
t_i); a missing sample (NaN) reads as the last present one, 0 before the first, and invalid.
"""

import math


def read(u, times, t, linear):
    """Column `u` (NaN: missing) of a table sampled at `times`, at time `t`: (value, valid,
    slope), `value` the FMU's output `c` (the held value where the column is missing), `valid`
    its `c.valid`, `slope` the line's slope there (0 for hold or next to a missing sample)."""
    def interval(i):
        return times[i] - times[i - 1] if i else times[1] - times[0]

    i = 0
    while i + 1 < len(times) and times[i + 1] <= t + 1e-9 * interval(i + 1):
        i += 1
    present = [k for k in range(i + 1) if not math.isnan(u[k])]
    held = u[present[-1]] if present else 0.0
    value, slope = u[i], 0.0
    if linear and i + 1 < len(times):
        slope = (u[i + 1] - u[i]) / (times[i + 1] - times[i])
        if t - times[i] > 1e-9 * interval(i):
            value = u[i] + (u[i + 1] - u[i]) * ((t - times[i]) / (times[i + 1] - times[i]))
    if math.isnan(value):
        return held, False, 0.0
    return value, True, (0.0 if math.isnan(slope) else slope)
