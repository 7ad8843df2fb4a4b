"""First crane experiment: free swing of GantryCrane.fmu from theta0 = 0.05 rad with U = 0,
simulated in fmpy (Co-Simulation, 10 ms communication step), written to CSV with the
measured pendulum period beside the linearised model's.

Usage: python examples/crane_free_swing.py <GantryCrane.fmu> <results folder>
"""

import pathlib
import sys

import numpy as np
from fmpy import simulate_fmu
from fmpy.util import write_csv


def main(fmu: str, out: str) -> None:
    out_dir = pathlib.Path(out)
    out_dir.mkdir(parents=True, exist_ok=True)
    result = simulate_fmu(
        fmu,
        fmi_type="CoSimulation",
        stop_time=20.0,
        output_interval=0.01,
        start_values={"theta0": 0.05},
        output=["x", "theta", "v", "omega"],
    )
    csv = out_dir / "crane_free_swing.csv"
    write_csv(str(csv), result)
    t, th = result["time"], result["theta"]
    i = np.where((th[:-1] < 0) & (th[1:] >= 0))[0]
    crossings = t[i] + (t[i + 1] - t[i]) * (-th[i]) / (th[i + 1] - th[i])
    period = float(np.mean(np.diff(crossings)))
    summary = out_dir / "crane_free_swing.md"
    summary.write_text(
        "# Crane free swing (theta0 = 0.05 rad, U = 0)\n\n"
        "| quantity | value |\n|---|---|\n"
        f"| measured period | {period:.5f} s |\n"
        "| linearised model (SPEC §6) | ≈ 1.17 s |\n"
        f"| final amplitude after 20 s | {np.max(np.abs(th[-200:])):.4f} rad |\n"
    )
    print(f"wrote {csv} and {summary}: period {period:.5f} s")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
