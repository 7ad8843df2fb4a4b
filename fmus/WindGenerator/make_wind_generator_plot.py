"""Draws fmus/WindGenerator/img/wind_generator_steps.png: the speed and voltage responses of
WindGenerator.fmu (run in fmpy) to a step of each reference, with the 63 % times marked.

    .venv/bin/python fmus/WindGenerator/make_wind_generator_plot.py [path/to/WindGenerator.fmu]

Experiments (each from the steady state of the references before the step, t_step = 1 s):
  drive step  u_drive 8 → 10 V at u_field = 8 V   (1440 → 1800 rpm, ≈ 196 → 240 V)
  field step  u_field 6 → 8 V at u_drive = 10 V   (180 → 240 V at 1800 rpm)
"""

import pathlib
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from fmpy import simulate_fmu  # noqa: E402

HERE = pathlib.Path(__file__).resolve().parent
FMU = sys.argv[1] if len(sys.argv) > 1 else str(HERE.parents[1] / "build" / "fmus" / "WindGenerator.fmu")
DTYPE = [("time", np.float64), ("u_drive", np.float64), ("u_field", np.float64)]


def simulate(rows, stop, u_drive_0, u_field_0):
    return simulate_fmu(FMU, stop_time=stop, output_interval=0.01,
                        input=np.array(rows, dtype=DTYPE),
                        start_values={"start_at_operating_point": True,
                                      "u_drive_0": u_drive_0, "u_field_0": u_field_0})


def time_constant(t, y, t_step=1.0):
    before, final = y[np.searchsorted(t, t_step - 1e-9)], y[-1]
    target = before + (1 - np.exp(-1)) * (final - before)
    after = t >= t_step - 1e-9
    tt, yy = t[after], y[after]
    k = np.argmax(yy >= target) if final > before else np.argmax(yy <= target)
    t_cross = tt[k - 1] + (target - yy[k - 1]) / (yy[k] - yy[k - 1]) * (tt[k] - tt[k - 1])
    return t_cross - t_step, target


def main():
    drive = simulate([(0, 8, 8), (1, 8, 8), (1, 10, 8)], 6.0, 8.0, 8.0)
    field = simulate([(0, 10, 6), (1, 10, 6), (1, 10, 8)], 3.0, 10.0, 6.0)
    fig, axes = plt.subplots(2, 2, figsize=(10, 6), sharex="col")
    panels = [
        (axes[0, 0], drive, "speed", "speed [rpm]", "drive step u_drive 8 → 10 V (u_field = 8 V)"),
        (axes[1, 0], drive, "voltage", "voltage [V]", None),
        (axes[0, 1], field, "speed", "speed [rpm]", "field step u_field 6 → 8 V (u_drive = 10 V)"),
        (axes[1, 1], field, "voltage", "voltage [V]", None),
    ]
    for ax, r, key, label, title in panels:
        t, y = r["time"], r[key]
        ax.plot(t, y, lw=1.5)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        if title:
            ax.set_title(title, fontsize=10)
        if abs(y[-1] - y[0]) > 0.05 * abs(y[-1]):
            tau, level = time_constant(t, y)
            ax.axvline(1.0 + tau, color="C1", ls="--", lw=1)
            ax.plot([1.0 + tau], [level], "o", color="C1")
            ax.annotate(f"63 % at +{tau:.3f} s", (1.0 + tau, level), xytext=(8, -14),
                        textcoords="offset points", fontsize=9, color="C1")
            print(f"{title or ''} {key}: 63 % time {tau:.3f} s")
    for ax in axes[1]:
        ax.set_xlabel("time [s]")
    fig.suptitle("WindGenerator.fmu (fmpy): responses to reference steps at t = 1 s", fontsize=11)
    fig.tight_layout()
    out = HERE / "img" / "wind_generator_steps.png"
    out.parent.mkdir(exist_ok=True)
    fig.savefig(out, dpi=90)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
