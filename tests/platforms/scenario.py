"""Scenarios for the platform driver (driver.c), written from an FMU's modelDescription.xml.

A scenario is the driver's directive file plus, in the FMI cross-check layout, the inputs
`<Model>_in.csv` (a `time` column, then one column per input, named as the input) and the
options `<Model>_ref.opt` (`StartTime, …` / `StopTime, …` / `StepSize, …` / `RelTol, …`).
The bundled models' own files (fmus/<Id>/crosscheck/, written by scripts/crosscheck.py) are
used; for a model without them (an FMU under test that is not bundled) exciting inputs are
generated: each real input holds its start value, then steps at a quarter of the run, with a
sine on top.

Standard library only, so that any Python 3 runs it.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

TYPES = {"Real": "r", "Integer": "i", "Boolean": "b", "Enumeration": "i"}
MAX_STEPS = 1000


@dataclass
class Variable:
    name: str
    vr: int
    type: str  # r, i or b
    causality: str
    variability: str
    start: float | None
    min: float | None
    max: float | None


@dataclass
class Model:
    identifier: str
    guid: str
    variables: list[Variable] = field(default_factory=list)
    start_time: float = 0.0
    stop_time: float = 10.0
    step_size: float | None = None

    def of(self, causality: str) -> list[Variable]:
        return [v for v in self.variables if v.causality == causality and v.type]


def parse(xml: bytes | str) -> Model:
    """The parts of a model description the driver needs."""
    root = ET.fromstring(xml)
    cs = root.find("CoSimulation")
    if cs is None:
        raise ValueError("not a Co-Simulation FMU")
    model = Model(cs.get("modelIdentifier", ""), root.get("guid", ""))
    for sv in root.iter("ScalarVariable"):
        kind = next((c for c in sv if c.tag in TYPES or c.tag == "String"), None)
        if kind is None or kind.tag == "String":
            continue

        def number(key: str) -> float | None:
            text = kind.get(key)
            if text is None:
                return None
            if text in ("true", "false"):
                return 1.0 if text == "true" else 0.0
            return float(text)

        model.variables.append(
            Variable(
                name=sv.get("name", ""),
                vr=int(sv.get("valueReference", "0")),
                type=TYPES[kind.tag],
                causality=sv.get("causality", "local"),
                variability=sv.get("variability", "continuous"),
                start=number("start"),
                min=number("min"),
                max=number("max"),
            )
        )
    de = root.find("DefaultExperiment")
    if de is not None:
        model.start_time = float(de.get("startTime", "0"))
        model.stop_time = float(de.get("stopTime", "10"))
        if de.get("stepSize"):
            model.step_size = float(de.get("stepSize"))
    return model


def excitation(v: Variable, index: int, t: float, duration: float) -> float:
    """A step at a quarter of the run plus a sine, around the start value, kept in [min, max]."""
    s = v.start or 0.0
    a = 0.5 * max(1.0, abs(s))
    u = s + (a if t >= 0.25 * duration else 0.0)
    u += 0.5 * a * math.sin(2.0 * math.pi * (index + 1) * t / duration)
    if v.min is not None:
        u = max(u, v.min)
    if v.max is not None:
        u = min(u, v.max)
    return u


def write(model: Model, name: str, folder: Path, own: Path | None = None) -> Path:
    """Writes `<name>.scenario`, `<name>_in.csv` and `<name>_ref.opt` into `folder` (`name`:
    the FMU's file stem, e.g. a variant's); returns the scenario. `own`: a folder that may
    hold the model's own cross-check files."""
    folder.mkdir(parents=True, exist_ok=True)
    inputs = model.of("input")
    for v in inputs + model.of("output"):
        if any(c.isspace() or c == '"' for c in v.name):
            raise ValueError(f"{name}: variable name {v.name!r} has a space or a quote")
    own_in = own / f"{name}_in.csv" if own else None
    own_opt = own / f"{name}_ref.opt" if own else None
    if own_opt and own_opt.exists():
        opt = own_opt.read_text()
    else:
        h = model.step_size or (model.stop_time - model.start_time) / 500
        stop = min(model.stop_time, model.start_time + MAX_STEPS * h)
        opt = (
            f"StartTime, {model.start_time!r}\nStopTime, {stop!r}\n"
            f"StepSize, {h!r}\nRelTol, 1e-6\n"
        )
    (folder / f"{name}_ref.opt").write_text(opt)
    if own_in and own_in.exists():
        (folder / f"{name}_in.csv").write_text(own_in.read_text())
    else:
        values = dict(line.split(",") for line in opt.strip().splitlines())
        t0, t1 = float(values["StartTime"]), float(values["StopTime"])
        h = float(values["StepSize"])
        n = int(round((t1 - t0) / h))
        rows = ["time," + ",".join(f'"{v.name}"' if "," in v.name else v.name for v in inputs)]
        for k in range(n + 1):
            t = t0 + k * h
            cells = [repr(t)] + [
                repr(excitation(v, i, t - t0, t1 - t0)) for i, v in enumerate(inputs)
            ]
            rows.append(",".join(cells))
        (folder / f"{name}_in.csv").write_text("\n".join(rows) + "\n")
    lines = [
        f"# {name}: generated from its modelDescription.xml by tests/platforms/scenario.py",
        f"guid {model.guid}",
        f"identifier {model.identifier}",
        f"opt {name}_ref.opt",
        f"inputs {name}_in.csv",
    ]
    # Start values of the parameters (set before initialisation: exercises fmi2Set*).
    for v in model.of("parameter"):
        if v.start is not None and v.variability in ("fixed", "tunable"):
            lines.append(f"start {v.type} {v.vr} {v.start!r}")
    lines += [f"input {v.type} {v.vr} {v.name}" for v in inputs]
    lines += [f"output {v.type} {v.vr} {v.name}" for v in model.of("output")]
    path = folder / f"{name}.scenario"
    path.write_text("\n".join(lines) + "\n")
    return path
