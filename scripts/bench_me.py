"""The Model Exchange benchmark (scripts/bench-me): the same ME FMU run by spurio, fmpy (CVode)
and OMSimulator (CVODE) at equal accuracy, interleaved in one run.

Each case is swept over relative tolerances in every tool; each run's error is the largest,
over the outputs, of max |y − y_ref| / range(y_ref) on the output grid, against a reference
run of fmpy's CVode at relative tolerance 1e-12 (its own error is shown: against spurio at
1e-12). A tool's cost to reach an error E is its least median time over the tolerances whose
error is at most E. Times are wall times of the simulation in process, from the experiment's
setup (initialisation included) to the end, the outputs recorded into memory (spurio, fmpy)
or the result file (OMSimulator), the FMU unpacked and instantiated before:

- spurio: `model_exchange::simulate` timed by target/release/spurio-bench-me;
- fmpy: `simulate_fmu` on a pre-instantiated FMU (`fmu_instance`, reset between runs);
- OMSimulator: `oms_simulate` after `oms_instantiate` and `oms_initialize`
  (tests/bench/oms_me.py; CVODE's largest step is the output interval, as OMSimulator runs an
  ME FMU inside a co-simulation root).

The repetitions are interleaved: round r runs every (tool, tolerance) once, then round r + 1.

    scripts/bench-me            # every case, 5 rounds (a few minutes)
    scripts/bench-me --quick    # one round, two tolerances: checks that every part runs
    scripts/bench-me --rounds 9 --case VanDerPol
"""

import argparse
import json
import os
import pathlib
import subprocess
import sys
import tempfile
import time

import numpy as np
from fmpy import extract, instantiate_fmu, read_model_description, simulate_fmu

REPO = pathlib.Path(__file__).resolve().parent.parent
THIRD_PARTY = pathlib.Path(os.environ.get("SPURIO_THIRD_PARTY", REPO / "tests" / "third_party"))
BENCH_ME = REPO / "target" / "release" / "spurio-bench-me"
OMS_PYTHONPATH = THIRD_PARTY / "omsimulator" / "lib" / "x86_64-linux-gnu"

# (name, FMU, spurio's solvers (each a row), stop time, output interval, start values, outputs compared)
CASES = [
    ("VanDerPol", THIRD_PARTY / "reference-fmus" / "fmi2" / "VanDerPol.fmu", ["dopri5"], 20.0,
     0.1, {}, ["x0", "x1"]),
    # pushed into the rail stop: state events (hit, held, released)
    ("GantryCrane U=3", REPO / "build" / "fmus" / "GantryCrane.fmu", ["dopri5"], 10.0, 0.05,
     {"U": 3.0}, ["x", "theta", "v", "omega"]),
    # start-up: stiff (60 Hz stator currents), angle-wrap and torque-limit events
    ("WindGenerator", REPO / "build" / "fmus" / "WindGenerator.fmu", ["dopri5", "rodas4", "rodas3"], 10.0,
     0.1, {},
     ["speed", "voltage", "frequency", "field_current", "T_e", "i_d", "i_q"]),
]
TOLERANCES = [1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11]
TARGETS = [1e-4, 1e-6, 1e-8]
THEIRS = ["fmpy", "OMSimulator"]


def read_csv(path):
    """Times and columns of a CSV with a header of (quoted) names."""
    lines = pathlib.Path(path).read_text().splitlines()
    names = [n.strip().strip('"') for n in lines[0].split(",")]
    rows = np.array([[float(v) for v in line.split(",")] for line in lines[1:] if line.strip()])
    return {name.split(".")[-1]: rows[:, j] for j, name in enumerate(names)}


def error(result, reference, outputs):
    """max over outputs of max |y − y_ref| / range(y_ref), y taken at the reference's times
    (the last value printed at a time, for OMSimulator's two rows per time)."""
    t_ref = reference["time"]
    t = result["time"]
    # the last row of each time
    last = np.concatenate([t[1:] != t[:-1], [True]])
    t = t[last]
    worst = 0.0
    for name in outputs:
        y_ref = reference[name]
        span = max(np.ptp(y_ref), 1e-300)
        index = np.searchsorted(t, t_ref - 1e-9)
        if index.max() >= len(t) or np.abs(t[index] - t_ref).max() > 1e-9:
            raise RuntimeError(f"{name}: the output grid does not match the reference's")
        y = result[name][last][index]
        worst = max(worst, float(np.max(np.abs(y - y_ref)) / span))
    return worst


class Fmpy:
    """fmpy's CVode on one pre-instantiated FMU."""

    def __init__(self, fmu):
        self.md = read_model_description(str(fmu))
        self.unzip = extract(str(fmu))
        self.instance = instantiate_fmu(self.unzip, self.md, "ModelExchange")

    def run(self, rtol, stop, step, start_values, outputs):
        started = time.perf_counter()
        try:
            result = simulate_fmu(
                self.unzip, model_description=self.md, fmu_instance=self.instance,
                fmi_type="ModelExchange", solver="CVode", relative_tolerance=rtol,
                stop_time=stop, output_interval=step, start_values=start_values, output=outputs,
                record_events=False, validate=False,
            )
            seconds = time.perf_counter() - started
        finally:
            self.instance.reset()
        return seconds, {name: result[name] for name in result.dtype.names}


class Oms:
    """OMSimulator's worker process (tests/bench/oms_me.py)."""

    def __init__(self):
        env = dict(os.environ, PYTHONPATH=str(OMS_PYTHONPATH))
        self.process = subprocess.Popen(
            [sys.executable, str(REPO / "tests" / "bench" / "oms_me.py")], env=env,
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
        )

    def run(self, fmu, rtol, stop, step, start_values, outputs, out):
        request = dict(fmu=str(fmu), rtol=rtol, stop=stop, step=step, out=str(out),
                       outputs=outputs, parameters=start_values)
        self.process.stdin.write(json.dumps(request) + "\n")
        self.process.stdin.flush()
        line = ""
        while not line.startswith("oms_me: "):
            line = self.process.stdout.readline()
            if not line:
                raise RuntimeError("OMSimulator's worker ended")
        answer = json.loads(line[len("oms_me: "):])
        if "error" in answer:
            raise RuntimeError(f"OMSimulator: {answer['error']}")
        return answer["seconds"], read_csv(out)

    def close(self):
        self.process.stdin.close()
        self.process.wait()


def spurio(fmu, solver, rtol, stop, step, start_values, out):
    sets = [a for name, value in start_values.items() for a in ("--set", f"{name}={value}")]
    done = subprocess.run(
        [str(BENCH_ME), str(fmu), "--solver", solver, "--tolerance", str(rtol), "--stop-time",
         str(stop), "--step-size", str(step), "--out", str(out), *sets],
        capture_output=True, text=True,
    )
    if done.returncode != 0:
        raise RuntimeError(f"spurio-bench-me: {done.stderr}")
    seconds = float(done.stdout.split()[1])
    return seconds, read_csv(out)


def bench_case(case, rounds, tolerances, work, oms):
    name, fmu, solvers, stop, step, start_values, outputs = case
    ours = [f"spurio {solver}" for solver in solvers]
    tools = ours + THEIRS
    fm = Fmpy(fmu)
    _, tight = spurio(fmu, "dopri5", 1e-12, stop, step, start_values, work / "tight.csv")
    try:
        # CVode stops after 500 steps between two output points: at 1e-12 it is asked for
        # outputs 20 times as often, and the rows on the grid are kept.
        _, fine = fm.run(1e-12, stop, step / 20, start_values, outputs)
        on_grid = np.abs(fine["time"] / step - np.round(fine["time"] / step)) < 1e-9
        reference = {name: column[on_grid] for name, column in fine.items()}
        said = (f"fmpy CVode at 1e-12 (against spurio dopri5 at 1e-12: "
                f"{error(tight, reference, outputs):.1e})")
    except Exception as e:
        reference = tight
        said = f"spurio dopri5 at 1e-12 (fmpy CVode at 1e-12 fails: {str(e).strip()[-80:]})"
    print(f"\n{name} ({fmu.name}, 0 to {stop:g} s, outputs every {step:g} s): "
          f"reference {said}")
    times = {(tool, tol): [] for tool in tools for tol in tolerances}
    errors = {}
    for _ in range(rounds):
        for tol in tolerances:
            for tool in tools:
                try:
                    if tool in ours:
                        solver = tool.split()[1]
                        seconds, result = spurio(fmu, solver, tol, stop, step, start_values,
                                                 work / "spurio.csv")
                    elif tool == "fmpy":
                        seconds, result = fm.run(tol, stop, step, start_values, outputs)
                    else:
                        seconds, result = oms.run(fmu, tol, stop, step, start_values, outputs,
                                                  work / "oms.csv")
                except Exception as e:  # a tool that fails at a tolerance has no point there
                    errors[(tool, tol)] = float("nan")
                    print(f"  {tool} at {tol:g}: failed ({str(e).strip()[:200]})")
                    continue
                times[(tool, tol)].append(seconds)
                errors[(tool, tol)] = error(result, reference, outputs)
    medians = {k: float(np.median(v)) for k, v in times.items() if v}
    print(f"  {'rtol':>7}" + "".join(f"  {tool + ' error':>18} {'ms':>8}" for tool in tools))
    for tol in tolerances:
        cells = "".join(
            f"  {errors.get((tool, tol), float('nan')):18.1e} "
            f"{medians.get((tool, tol), float('nan')) * 1e3:8.3f}"
            for tool in tools
        )
        print(f"  {tol:7.0e}{cells}")
    print("  cost to reach error ≤ E (median ms at the cheapest tolerance that does; ×: the "
          "time over spurio's best):")
    for target in TARGETS:
        cost = {}
        for tool in tools:
            reached = [medians[(tool, tol)] for tol in tolerances
                       if (tool, tol) in medians and errors[(tool, tol)] <= target]
            cost[tool] = min(reached) if reached else float("nan")
        best = np.nanmin([cost[tool] for tool in ours]) if any(
            np.isfinite(cost[tool]) for tool in ours) else float("nan")
        print(f"    E = {target:.0e}: " + ", ".join(
            f"{tool} " + (f"{cost[tool] * 1e3:.3f} ms (×{cost[tool] / best:.2f})"
                          if np.isfinite(cost[tool]) else "not reached")
            for tool in tools))


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="one round, two tolerances")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--case", action="append", help="only the cases whose name starts so")
    args = parser.parse_args()
    rounds = 1 if args.quick else args.rounds
    tolerances = [1e-4, 1e-6] if args.quick else TOLERANCES
    cases = [c for c in CASES if not args.case or any(c[0].startswith(p) for p in args.case)]
    print(f"Model Exchange at equal accuracy: {rounds} interleaved round(s), medians; "
          f"tolerances {', '.join(f'{t:g}' for t in tolerances)}")
    oms = Oms()
    try:
        with tempfile.TemporaryDirectory(prefix="spurio-bench-me.") as work:
            for case in cases:
                bench_case(case, rounds, tolerances, pathlib.Path(work), oms)
    finally:
        oms.close()


if __name__ == "__main__":
    main()
