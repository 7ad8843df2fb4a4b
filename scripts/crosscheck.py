"""The cross-check scenarios of the bundled FMUs, in the FMI cross-check layout.

Each bundled FMU `<Model>` (a variant too) has, in its FMU's folder `fmus/<Id>/crosscheck/`:

* `<Model>_ref.opt`  the experiment: `StartTime`, `StopTime`, `StepSize` (equal to the model
  description's `DefaultExperiment`) and `RelTol`;
* `<Model>_in.csv`   the inputs: a `time` column, then one column per input, named as the
  input (the Real inputs, then the Boolean ones as 1/0, held at their start value). Piecewise constant, with a row at every communication point `t₀ + k h` (computed
  as fmpy and the driver compute them); a change is written as two rows with the same `t`
  (the value before, then after). So fmpy's `Input` (which takes the value after an event,
  and interpolates with weights exactly 0 and 1 at a row's time) and a sample-and-hold master
  (the last row with time ≤ t) apply bit-identical values;
* `<Model>_ref.csv`  the reference outputs: `time`, then every output, after the start and
  after each step, computed by the linux64 FMU in fmpy (`simulate_fmu` with the `_in.csv` as
  input, output interval = step size). Numbers written with 17 significant digits, so they
  read back bit-identical.

    python3 scripts/crosscheck.py inputs [--only M ...]       # (re)write _in.csv and _ref.opt
    python3 scripts/crosscheck.py refs   [--fmus build/fmus]  # (re)write _ref.csv with fmpy
    python3 scripts/crosscheck.py tree --out build/crosscheck # the cross-check tree

`refs` needs fmpy; `tree` and `inputs` use the standard library only. The tree is
`<out>/fmus/2.0/cs/<platform>/spurio/<version>/<Model>/` with `<Model>.fmu`, `_in.csv`,
`_ref.csv` and `_ref.opt`, for each platform the FMU carries.
"""

from __future__ import annotations

import argparse
import csv
import io
import math
import re
import shutil
import sys
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
TOOL = "spurio"
# The platforms of the cross-check tree: folder name → binary inside the FMU.
PLATFORMS = {"linux64": "so", "win64": "dll", "aarch64-linux": "so"}
REL_TOL = 1e-6
# Number of input changes over a run (held in between).
SEGMENTS = 50

# How each model's inputs are excited: per input name (a regular expression matched against
# the whole name), (centre, amplitude); the centre `None` means the input's start value.
# A staircase: `centre + amplitude · (½ [t ≥ T/4] + ½ sin(1.7 j + 0.9 i))` on segment j of
# input i. Models with no entry use (start value, ½ max(1, |start|)).
EXCITATION: dict[str, list[tuple[str, float | None, float]]] = {
    # the crane: a force of a few newtons (limit ±17 N)
    "GantryCrane": [("U", 0.0, 2.0)],
    # the controllers: state estimates around the origin, the estimated model ±2 %
    "StateFeedback": [(r"x_hat\[\d\]", 0.0, 0.2), (r"x_ref\[\d\]", 0.0, 0.05)],
    "AdaptiveStateFeedback": [(r"x_hat\[\d\]", 0.0, 0.2), (r"[AB]_hat\[.*", None, -0.02)],
    # the generator: references 0–10 V around the rated ones
    "WindGenerator": [("u_drive", None, 1.0), ("u_field", None, 1.0)],
    "OpAmpFilter": [("u", 0.0, 1.0)],
}
# Inputs computed from others: the RLS identifies y_k = 1.5 y_{k-1} − 0.7 y_{k-2}
# + u_{k-1} + 0.5 u_{k-2} (a stable second-order system).
ARX = {"RecursiveLeastSquares": ("u", "y", (1.5, -0.7), (1.0, 0.5))}


def md_of(fmu: Path) -> ET.Element:
    with zipfile.ZipFile(fmu) as z:
        return ET.fromstring(z.read("modelDescription.xml"))


def identifier(md: ET.Element) -> str:
    cs = md.find("CoSimulation")
    if cs is None:
        raise ValueError("not a Co-Simulation FMU")
    return cs.get("modelIdentifier", "")


def experiment(md: ET.Element) -> tuple[float, float, float]:
    de = md.find("DefaultExperiment")
    if de is None or de.get("stepSize") is None:
        raise ValueError("no DefaultExperiment with a stepSize")
    return (float(de.get("startTime", "0")), float(de.get("stopTime", "1")),
            float(de.get("stepSize", "0")))


def inputs_of(md: ET.Element) -> list[tuple[str, float]]:
    """(name, start) of each Real input, then of each Boolean input (start 1 for true, 0 for
    false: the estimators' `y_valid[j]`, held at their start in the scenarios)."""
    out, flags = [], []
    for sv in md.iter("ScalarVariable"):
        if sv.get("causality") != "input":
            continue
        real, boolean = sv.find("Real"), sv.find("Boolean")
        if real is not None:
            out.append((sv.get("name", ""), float(real.get("start", "0"))))
        elif boolean is not None:
            flags.append((sv.get("name", ""), 1.0 if boolean.get("start") == "true" else 0.0))
        else:
            raise ValueError(f"input {sv.get('name')} is neither Real nor Boolean")
    return out + flags


def is_flag(md: ET.Element, name: str) -> bool:
    """Whether the input `name` is a Boolean."""
    return any(sv.get("name") == name and sv.find("Boolean") is not None
               for sv in md.iter("ScalarVariable"))


def folder_of(model: str, ident: str) -> Path:
    """`fmus/<Id>/crosscheck/` of a bundled model."""
    return REPO / "fmus" / ident / "crosscheck"


def cell(name: str) -> str:
    return f'"{name}"' if "," in name else name


def write_inputs(fmu: Path) -> Path:
    md = md_of(fmu)
    model, ident = fmu.stem, identifier(md)
    t0, t1, h = experiment(md)
    folder = folder_of(model, ident)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"{model}_ref.opt").write_text(
        f"StartTime, {t0!r}\nStopTime, {t1!r}\nStepSize, {h!r}\nRelTol, {REL_TOL!r}\n")
    ins = inputs_of(md)
    if not ins:
        (folder / f"{model}_in.csv").unlink(missing_ok=True)
        return folder
    n = int(round((t1 - t0) / h))
    hold = max(1, n // SEGMENTS)
    rules = EXCITATION.get(model, [])
    columns: dict[str, list[float]] = {}
    for i, (name, start) in enumerate(ins):
        if is_flag(md, name):
            columns[name] = [start] * (n + 1)
            continue
        rule = next((r for r in rules if re.fullmatch(r[0], name)), None)
        centre, amplitude = (start, 0.5 * max(1.0, abs(start))) if rule is None else (
            start if rule[1] is None else rule[1], rule[2])
        if rule is not None and rule[2] < 0:  # relative amplitude
            amplitude = -rule[2] * max(abs(start), 1e-3)
        values = []
        for k in range(n + 1):
            j = k // hold
            stepped = 0.5 if k * h >= 0.25 * (t1 - t0) else 0.0
            values.append(centre + amplitude * (stepped + 0.5 * math.sin(1.7 * j + 0.9 * i)))
        columns[name] = values
    if model in ARX:
        u, y, (a1, a2), (b1, b2) = ARX[model]
        uu, yy = columns[u], [0.0] * (n + 1)
        for k in range(n + 1):
            yy[k] = (a1 * yy[k - 1] + a2 * yy[k - 2] + b1 * uu[k - 1] + b2 * uu[k - 2]
                     if k >= 2 else 0.0)
        columns[y] = yy
    names = [name for name, _ in ins]
    rows = ["time," + ",".join(cell(x) for x in names)]
    previous = None
    for k in range(n + 1):
        t = t0 + k * h  # as fmpy and the driver compute the communication points
        now = [columns[x][k] for x in names]
        if previous is not None and now != previous:
            rows.append(",".join([repr(t)] + [repr(v) for v in previous]))
        rows.append(",".join([repr(t)] + [repr(v) for v in now]))
        previous = now
    (folder / f"{model}_in.csv").write_text("\n".join(rows) + "\n")
    return folder


def read_opt(path: Path) -> dict[str, float]:
    return {k.strip(): float(v) for k, v in
            (line.split(",") for line in path.read_text().splitlines() if line.strip())}


def read_table(path: Path) -> tuple[list[str], list[list[float]]]:
    """A cross-check CSV: header, then rows of numbers."""
    rows = list(csv.reader(io.StringIO(path.read_text())))
    return rows[0], [[float(x) for x in r] for r in rows[1:] if r]


def simulate(fmu: Path, folder: Path):
    """fmpy's result (a structured array) for the model's scenario."""
    import numpy as np
    from fmpy import simulate_fmu

    model = fmu.stem
    opt = read_opt(folder / f"{model}_ref.opt")
    signals = None
    in_csv = folder / f"{model}_in.csv"
    if in_csv.exists():
        header, rows = read_table(in_csv)
        signals = np.array([tuple(r) for r in rows],
                           dtype=[(name, np.float64) for name in header])
    return simulate_fmu(str(fmu), start_time=opt["StartTime"], stop_time=opt["StopTime"],
                        output_interval=opt["StepSize"], relative_tolerance=opt["RelTol"],
                        input=signals)


def write_refs(fmu: Path) -> Path:
    md = md_of(fmu)
    folder = folder_of(fmu.stem, identifier(md))
    result = simulate(fmu, folder)
    names = result.dtype.names
    lines = [",".join(cell(x) for x in names)]
    for row in result:
        lines.append(",".join(repr(float(v)) if isinstance(v, float) or hasattr(v, "dtype")
                              and v.dtype.kind == "f" else str(int(v)) for v in row))
    path = folder / f"{fmu.stem}_ref.csv"
    path.write_text("\n".join(lines) + "\n")
    return path


def version() -> str:
    text = (REPO / "Cargo.toml").read_text()
    m = re.search(r'^\[workspace\.package\][^\[]*?^version\s*=\s*"([^"]+)"', text, re.M | re.S)
    if m is None:
        m = re.search(r'^version\s*=\s*"([^"]+)"', text, re.M)
    if m is None:
        raise ValueError("no version in Cargo.toml")
    return m.group(1)


def write_tree(fmus: list[Path], out: Path) -> int:
    """The cross-check tree; returns the number of model folders written."""
    written = 0
    base = out / "fmus" / "2.0" / "cs"
    shutil.rmtree(base, ignore_errors=True)
    for fmu in fmus:
        md = md_of(fmu)
        ident = identifier(md)
        folder = folder_of(fmu.stem, ident)
        with zipfile.ZipFile(fmu) as z:
            members = set(z.namelist())
        for platform, ext in PLATFORMS.items():
            if f"binaries/{platform}/{ident}.{ext}" not in members:
                continue
            target = base / platform / TOOL / version() / fmu.stem
            target.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(fmu, target / fmu.name)
            for suffix in ("_in.csv", "_ref.csv", "_ref.opt"):
                source = folder / f"{fmu.stem}{suffix}"
                if source.exists():
                    shutil.copyfile(source, target / source.name)
                elif suffix != "_in.csv":
                    raise FileNotFoundError(f"{source} (python3 scripts/crosscheck.py refs)")
            written += 1
    return written


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("command", choices=["inputs", "refs", "tree"])
    ap.add_argument("--fmus", type=Path, default=REPO / "build" / "fmus")
    ap.add_argument("--out", type=Path, default=REPO / "build" / "crosscheck")
    ap.add_argument("--only", nargs="*", default=[])
    args = ap.parse_args()
    # The bundled FMUs (a committed model description each), not a user's variants.
    bundled = {p.stem for p in (REPO / "modelDescription").glob("*.xml")}
    fmus = sorted(p for p in args.fmus.glob("*.fmu")
                  if p.stem in bundled and (not args.only or p.stem in args.only))
    if not fmus:
        print(f"crosscheck: no FMUs in {args.fmus}", file=sys.stderr)
        return 1
    if args.command == "tree":
        n = write_tree(fmus, args.out)
        print(f"crosscheck: {n} model folders under {args.out / 'fmus/2.0/cs'}")
        return 0
    for fmu in fmus:
        path = write_inputs(fmu) if args.command == "inputs" else write_refs(fmu)
        print(f"{fmu.stem}: {path.relative_to(REPO)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
