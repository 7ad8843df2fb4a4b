"""Missing samples in every estimator FMU, FMI 2.0 and 3.0 (docs/estimators.md, "Missing
samples"): `y_valid[j]` = false (RecursiveLeastSquares: `y_valid`, DistributedObserver:
`y_own_valid[j]`) is a missing sample. Each FMU is driven through fmpy on its cross-check
scenario (fmus/<Id>/crosscheck/) with a run of missing samples in the middle, during which the
measurement inputs hold garbage:

* every step returns OK and every output stays finite, and the garbage is ignored (the same
  outputs, bit for bit, with another garbage value);
* the Kalman filters' covariance grows while data is missing: the gain ‖x̂ − x⁻‖/‖e‖ of the
  first sample after the gap is larger than the one before it (x⁻ = A x̂ + B u from the
  parameters or the estimated model Â, B̂, the innovation e of one standard deviation /2 in
  each channel);
* the dual filters hold Θ̂ (every `A_hat`, `B_hat`) and RLS holds θ over the gap;
* with no missing sample (every `y_valid` true) the outputs are those of the FMUs before
  `y_valid` existed, bit for bit: `missing_samples_before.json` pins them, as the FMUs of
  dd24126 (the commit before missing samples) gave them on these scenarios: per FMU the
  SHA-256 of every output of every step (little-endian float64, row by row) and the last
  step's outputs written out (`repr`, for a readable difference). Pinned again with
  `PYTHONPATH=. python3 tests/fmpy/test_missing_samples.py --pin DIR`, DIR a build/fmus of
  that commit.
"""

import hashlib
import json
import pathlib
import sys

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave

from conftest import FMU_DIR, REPO, element_names

sys.path.insert(0, str(REPO / "scripts"))
import crosscheck  # noqa: E402

# stem -> the name of its measurement input (its validity input is `<name>_valid`)
ESTIMATORS = {
    "KalmanFilter": "y",
    "RobustKalmanFilter": "y",
    "RobustKalmanFilter2": "y",
    "RobustKalmanFilterInput": "y",
    "DistributedObserverCentralKalman": "y",
    "DualKalmanFilter": "y",
    "DualKalmanFilterGenerator": "y",
    "DkfRsKf": "y",
    "DkfRsKfGenerator": "y",
    "DkfRsKfInput": "y",
    "RecursiveLeastSquares": "y",
    "DistributedObserverAgent1": "y_own",
    "DistributedObserverAgent2": "y_own",
}
CASES = [(stem, version) for stem in ESTIMATORS for version in (2, 3)]
BEFORE = pathlib.Path(__file__).with_name("missing_samples_before.json")


def path_of(stem, version, folder=FMU_DIR):
    """The FMU `stem` of FMI `version` in `folder` (FMI 3.0: its fmi3/)."""
    path = pathlib.Path(folder) / ("" if version == 2 else "fmi3") / f"{stem}.fmu"
    assert path.is_file(), f"{path} is missing: build the FMUs with scripts/build-fmus"
    return str(path)


class Instance:
    """One FMU instance, FMI 2.0 or 3.0, addressed by the FMI 2.0 scalar names."""

    def __init__(self, path):
        self.md = read_model_description(path)
        self.version = 2 if self.md.fmiVersion.startswith("2") else 3
        cls = FMU2Slave if self.version == 2 else FMU3Slave
        self.s = cls(guid=self.md.guid, unzipDirectory=extract(path),
                     modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName="m")
        self.s.instantiate()
        self.variables = {}  # scalar name -> (variable, position)
        for v in self.md.modelVariables:
            for k, name in enumerate(element_names(v)):
                self.variables[name] = (v, k)
        self.inputs = [v for v in self.md.modelVariables if v.causality == "input"]
        self.outputs = [n for v in self.md.modelVariables if v.causality == "output"
                        for n in element_names(v)]
        self.values = {n: None for v in self.inputs for n in element_names(v)}

    def has(self, name):
        return name in self.variables

    def start(self, t0):
        if self.version == 2:
            self.s.setupExperiment(startTime=t0)
            self.s.enterInitializationMode()
        else:
            self.s.enterInitializationMode(startTime=t0)

    def set(self, name, value):
        self.values[name] = value

    def push(self):
        """Sets every input given since the start (whole arrays in FMI 3.0)."""
        for v in self.inputs:
            names = element_names(v)
            values = [self.values[n] for n in names]
            if any(x is None for x in values):
                continue
            if v.type == "Boolean":
                self.s.setBoolean([v.valueReference], [bool(x) for x in values])
            elif self.version == 2:
                self.s.setReal([v.valueReference], values)
            else:
                self.s.setFloat64([v.valueReference], values)

    def get(self, names):
        out = []
        for n in names:
            v, k = self.variables[n]
            if v.type == "Boolean":
                values = self.s.getBoolean([v.valueReference]) if self.version == 2 else \
                    self.s.getBoolean([v.valueReference], nValues=len(element_names(v)))
            elif self.version == 2:
                values = self.s.getReal([v.valueReference])
            else:
                values = self.s.getFloat64([v.valueReference], nValues=len(element_names(v)))
            out.append(float(values[k]))
        return np.array(out)

    def free(self):
        self.s.terminate()
        self.s.freeInstance()


def scenario(stem):
    """The cross-check scenario: (t0, h, steps, {input name: values at each step})."""
    fmu = pathlib.Path(path_of(stem, 2))
    folder = crosscheck.folder_of(stem, crosscheck.identifier(crosscheck.md_of(fmu)))
    opt = crosscheck.read_opt(folder / f"{stem}_ref.opt")
    t0, t1, h = opt["StartTime"], opt["StopTime"], opt["StepSize"]
    n = int(round((t1 - t0) / h))
    header, rows = crosscheck.read_table(folder / f"{stem}_in.csv")
    columns = np.array(rows).T
    times = [t0 + k * h for k in range(n + 1)]
    table = {name: [float(np.interp(t, columns[0], columns[i])) for t in times]
             for i, name in enumerate(header) if name != "time"}
    return t0, h, n, table


def gap_of(n):
    """The missing samples: 20 steps (a tenth of shorter runs) from the middle."""
    length = min(20, max(3, n // 10))
    return range(n // 2, n // 2 + length)


def model_matrices(inst):
    """(x names, A(prev outputs), B, C, D, u names, e names) for the gain: parameters of a
    Kalman filter, or the estimated model's outputs of a dual filter."""
    names = inst.variables
    xs = sorted((n for n in names if n.startswith("x_hat[")), key=lambda n: int(n[6:-1]))
    us = sorted((n for n in names if n.startswith("u[")), key=lambda n: int(n[2:-1]))
    ys = sorted((n for n in names if n.startswith("y[")), key=lambda n: int(n[2:-1]))
    dual = "A_hat[1,1]" in names
    prefix = "_hat" if dual else ""

    def matrix(letter, rows, cols):
        return np.array([[inst.get([f"{letter}{prefix}[{i + 1},{j + 1}]"])[0]
                          for j in range(cols)] for i in range(rows)]).reshape(rows, cols)

    return xs, us, ys, dual, lambda: (matrix("A", len(xs), len(xs)), matrix("B", len(xs), len(us)),
                                      matrix("C", len(ys), len(xs)), matrix("D", len(ys), len(us)))


def run(stem, version, missing=True, garbage=1e6, probe=False, folder=FMU_DIR, valid=None):
    """Drives the FMU through its scenario; with `missing`, the samples of `gap_of` are
    missing and their measurements `garbage`. Returns (outputs per step, gains): with
    `probe`, the measurement of the sample before the gap and of the one after it is the
    one-step prediction plus half a standard deviation per channel, and `gains` are
    ‖x̂ − x⁻‖/‖e‖ at those two samples. A list `valid` receives the validity inputs read
    back before each step (none for an FMU without them)."""
    measured = ESTIMATORS[stem]
    inst = Instance(path_of(stem, version, folder))
    t0, h, n, table = scenario(stem)
    gap = gap_of(n)
    inst.start(t0)
    for name, values in table.items():
        if inst.has(name):
            inst.set(name, values[0])
    inst.push()
    inst.s.exitInitializationMode()
    if probe:
        xs, us, ys, dual, matrices = model_matrices(inst)
        r = [inst.get([f"R[{j + 1},{j + 1}]"])[0] for j in range(len(ys))]
    steps, gains = [], []
    for k in range(n):
        for name, values in table.items():
            if not inst.has(name):
                continue
            is_measurement = name == measured or name.startswith(measured + "[")
            if missing and k in gap and is_measurement:
                inst.set(name, garbage)
            elif name.startswith(measured + "_valid"):
                inst.set(name, 0.0 if missing and k in gap else values[k])
            else:
                inst.set(name, values[k])
        probing = probe and k in (gap.start - 1, gap.stop)
        if probing:
            a, b, c, d = matrices()
            x_prev, u_prev = inst.get(xs), inst.get(us) if us else np.zeros(0)
            u_now = np.array([table[u][k] for u in us])
            x_prior = a @ x_prev + b @ u_prev
            prediction = c @ x_prior + d @ u_now
            for j, y in enumerate(ys):
                inst.set(y, prediction[j] + 0.5 * np.sqrt(r[j]))
        inst.push()
        if valid is not None:
            valid.append(inst.get([n for n in inst.values if n.startswith(measured + "_valid")]))
        inst.s.doStep(currentCommunicationPoint=t0 + k * h, communicationStepSize=h)
        outputs = inst.get(inst.outputs)
        assert np.all(np.isfinite(outputs)), f"{stem}: step {k}"
        steps.append(outputs)
        if probing:
            if dual:
                seen = inst.get([f"y_clean[{j + 1}]" for j in range(len(ys))]) \
                    if inst.has("y_clean[1]") else np.array([inst.values[y] for y in ys])
                e = seen - prediction
            else:
                e = inst.get([f"innovation[{j + 1}]" for j in range(len(ys))])
            gains.append(np.linalg.norm(inst.get(xs) - x_prior) / np.linalg.norm(e))
    names = inst.outputs
    inst.free()
    return names, np.array(steps), gains


@pytest.mark.parametrize("stem,version", CASES)
def test_missing_samples_give_finite_outputs_and_the_measurement_is_ignored(stem, version):
    names, one, _ = run(stem, version, garbage=1e6)
    _, other, _ = run(stem, version, garbage=-3.25)
    assert np.array_equal(one, other), "the measurement of a missing sample entered"
    _, full, _ = run(stem, version, missing=False)
    gap = gap_of(len(full))
    # something differs from the run with data (the gap is seen) ...
    assert not np.array_equal(one[gap.start], full[gap.start])
    held = [i for i, n in enumerate(names) if n.startswith(("A_hat", "B_hat", "theta"))]
    if held:
        # ... and the estimated model (Θ̂, θ) is held over the gap
        window = one[gap.start - 1:gap.stop, held]
        assert np.array_equal(window, np.repeat(window[:1], len(window), axis=0)), stem
        assert not np.array_equal(one[-1, held], one[gap.stop - 1, held]), "learning resumed"


KALMAN = [(s, v) for s, v in CASES if not s.startswith(("RecursiveLeast", "DistributedObserverA"))]


@pytest.mark.parametrize("stem,version", KALMAN)
def test_the_covariance_grows_while_data_is_missing(stem, version):
    _, _, (before, after) = run(stem, version, probe=True)
    assert np.isfinite(before) and np.isfinite(after)
    print(f"{stem} FMI {version}: gain {before:.4g} before the gap, {after:.4g} after it")
    assert after > 1.1 * before, f"{stem}: gain {before} before the gap, {after} after it"


def pin_of(outputs):
    """The pin of a run's outputs: the SHA-256 of every step's outputs (little-endian
    float64, row by row) and the last step's outputs."""
    table = np.asarray(outputs, dtype="<f8")
    return {"steps": len(table), "sha256": hashlib.sha256(table.tobytes()).hexdigest(),
            "last": [repr(float(v)) for v in table[-1]]}


# the estimators that existed before `y_valid` (a variant bundled since has no "before")
PINNED = json.loads(BEFORE.read_text())
PINNED_CASES = [(stem, version) for stem, version in CASES if stem in PINNED]


@pytest.mark.parametrize("stem,version", PINNED_CASES)
def test_without_missing_samples_the_outputs_are_those_of_before(stem, version):
    valid = []
    names, now, _ = run(stem, version, missing=False, valid=valid)
    # every sample present: each validity input read back true at every step
    flags = np.concatenate(valid)
    assert flags.size >= len(now) and np.all(flags == 1.0), f"{stem}: a y_valid was false"
    pinned = PINNED[stem]
    assert names == pinned["outputs"]
    got = pin_of(now)
    # the last step first: a difference there names the output and both numbers
    differing = [(n, p, g) for n, p, g in zip(names, pinned["last"], got["last"]) if p != g]
    assert not differing, f"{stem} FMI {version}: the last step differs (name, before, now): {differing}"
    assert got == {k: pinned[k] for k in ("steps", "sha256", "last")}, f"{stem} FMI {version}"


def pin(folder):
    """Writes `missing_samples_before.json` from the FMUs of `folder` (a build/fmus of
    dd24126, with fmi3/): FMI 2.0 and 3.0 must agree bit for bit."""
    pins = {}
    for stem in ESTIMATORS:
        if not (pathlib.Path(folder) / f"{stem}.fmu").exists():
            continue  # bundled after that build
        names, outputs, _ = run(stem, 2, missing=False, folder=folder)
        names3, outputs3, _ = run(stem, 3, missing=False, folder=folder)
        assert names == names3 and np.array_equal(outputs, outputs3), stem
        pins[stem] = {"outputs": names, **pin_of(outputs)}
    lines = [f" {json.dumps(stem)}: {json.dumps(pinned)}" for stem, pinned in pins.items()]
    BEFORE.write_text("{\n" + ",\n".join(lines) + "\n}\n")


if __name__ == "__main__":
    if len(sys.argv) != 3 or sys.argv[1] != "--pin":
        sys.exit("usage: test_missing_samples.py --pin DIR (a build/fmus of dd24126)")
    pin(sys.argv[2])
