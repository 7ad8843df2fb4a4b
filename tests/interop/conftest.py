"""Shared helpers for the tests that run the master and our FMUs against the FMI tools users
already run: fmpy, OMSimulator (command line and Python API) and the FMU Compliance Checker.

Where the tools are: the repository's `tests/third_party/` (its README lists what each is,
its version, where it came from and its licence), or the folder `SPURIO_THIRD_PARTY` names.

How the tools count time (what the comparisons below rely on):
- fmpy (`simulate_fmu`, CS) and `spurio run` compute the n-th communication point as
  start + n·h and record one row per point.
- OMSimulator accumulates t += h and writes every number with `%.12g`. For each
  communication point it writes a row after the FMUs' step and, when it then updates inputs
  (connected FMUs), another one: inputs and direct-feedthrough outputs differ between the two
  rows, states do not. When n·h falls short of the stop time in floating point (100 × 0.1 <
  10) it takes one more step of ~1e-15 s and prints its rows at the same rounded time.
- The FMU Compliance Checker accumulates t += h too and prints `%.16E`.
"""

import os
import pathlib
import subprocess

import numpy as np
import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]
FMU_DIR = pathlib.Path(os.environ.get("SPURIO_FMU_DIR", REPO / "build" / "fmus"))
SPURIO = REPO / "target" / "release" / "spurio"


THIRD_PARTY = pathlib.Path(os.environ.get("SPURIO_THIRD_PARTY", REPO / "tests" / "third_party"))
REFERENCE_FMUS = THIRD_PARTY / "reference-fmus" / "fmi2"
OMSIMULATOR = THIRD_PARTY / "omsimulator" / "bin" / "OMSimulator"
OMS_PYTHONPATH = THIRD_PARTY / "omsimulator" / "lib" / "x86_64-linux-gnu"
FMUCHECK = THIRD_PARTY / "fmuCheck.linux64"

# OMSimulator prints 12 significant digits (%.12g): a value read back is within half a unit
# of the 12th digit, i.e. a relative 5e-12 of the exact one.
OMS_RTOL = 5e-12


def require(path: pathlib.Path, what: str) -> pathlib.Path:
    assert path.exists(), f"{path} is missing: {what}"
    return path


def our_fmu(name: str) -> pathlib.Path:
    return require(FMU_DIR / f"{name}.fmu", "build the FMUs with scripts/build-fmus")


def our_fmus():
    return sorted(p.stem for p in FMU_DIR.glob("*.fmu"))


def spurio(*args, check=True) -> subprocess.CompletedProcess:
    require(SPURIO, "build it with scripts/build-fmus (cargo build --release)")
    result = subprocess.run(
        [str(SPURIO), *map(str, args)], capture_output=True, text=True, timeout=300
    )
    if check:
        assert result.returncode == 0, f"spurio {args} failed:\n{result.stdout}{result.stderr}"
    return result


def omsimulator(*args, cwd) -> subprocess.CompletedProcess:
    require(OMSIMULATOR, "see the third-party README (it needs Debian's libicu72)")
    result = subprocess.run(
        [str(OMSIMULATOR), *map(str, args)],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=cwd,
    )
    assert result.returncode == 0 and "error:" not in result.stdout + result.stderr, (
        f"OMSimulator {args} failed:\n{result.stdout}{result.stderr}"
    )
    return result


def oms_python(script: str, cwd) -> subprocess.CompletedProcess:
    """Runs `script` with OMSimulator's Python API (in a process of its own: the API keeps
    global state in its shared library)."""
    import sys

    env = dict(os.environ, PYTHONPATH=str(require(OMS_PYTHONPATH, "OMSimulator's Python API")))
    result = subprocess.run(
        [sys.executable, "-c", script],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=cwd,
        env=env,
    )
    assert result.returncode == 0, f"OMSimulator Python API failed:\n{result.stdout}{result.stderr}"
    return result


def read_csv(path) -> tuple[list[str], np.ndarray]:
    """A CSV with a quoted header (fmpy, spurio, OMSimulator, fmuCheck): names and rows."""
    path = pathlib.Path(path)
    lines = path.read_text().splitlines()
    names = [n.strip().strip('"') for n in lines[0].split(",")]
    # Names with commas (`A[1,2]`) are quoted: split the header on '","' instead.
    if lines[0].startswith('"'):
        names = lines[0].strip()[1:-1].split('","')
    rows = np.array(
        [[float(v) for v in line.split(",")] for line in lines[1:] if line.strip()],
        dtype=float,
    )
    return names, rows.reshape(len(rows), len(names))


def by_time(names, rows, keep: str) -> tuple[list[str], np.ndarray]:
    """OMSimulator's rows, one per printed time: `keep="first"` (after the step, before the
    inputs are updated) or `"last"` (after the inputs are updated)."""
    t = rows[:, 0]
    if keep == "first":
        mask = np.concatenate([[True], t[1:] != t[:-1]])
    else:
        mask = np.concatenate([t[1:] != t[:-1], [True]])
    return names, rows[mask]


def column(names, rows, name) -> np.ndarray:
    assert name in names, f"{name} not in {names}"
    return rows[:, names.index(name)]


def binary_step(h: float) -> float:
    """The power of two nearest to `h`: n·h is then exact, so every tool ends on the stop
    time without a tiny extra step."""
    return float(2.0 ** round(np.log2(h)))


def default_experiment(fmu) -> tuple[float, float]:
    """(stop time, step size) of an FMU's DefaultExperiment (stop 1, step stop/100 if not
    given)."""
    from fmpy import read_model_description

    de = read_model_description(str(fmu)).defaultExperiment
    stop = float(de.stopTime) if de is not None and de.stopTime is not None else 1.0
    step = float(de.stepSize) if de is not None and de.stepSize is not None else stop / 100
    return stop, step


def run_alone(fmu, workdir):
    """`fmu` as the one instance `m` of a system at its default experiment, run by `spurio
    run` and by fmpy's `simulate_fmu` (CS, a point every step): spurio's process, the names
    and rows of its results, fmpy's results and the stop time."""
    from fmpy import simulate_fmu

    stop, step = default_experiment(fmu)
    system = workdir / "system.toml"
    system.write_text(
        f'stop_time = {stop!r}\nstep_size = {step!r}\n'
        f'[[instance]]\nname = "m"\nfmu = "{fmu}"\n'
    )
    out = workdir / "spurio.csv"
    run = spurio("run", system, "--out", out)
    names, rows = read_csv(out)
    expected = simulate_fmu(
        str(fmu),
        fmi_type="CoSimulation",
        stop_time=stop,
        step_size=step,
        output_interval=step,
    )
    assert rows.shape[0] == len(expected), (rows[-3:], expected[-3:])
    np.testing.assert_allclose(rows[:, 0], expected["time"], rtol=0, atol=1e-12)
    return run, names, rows, expected, stop


def assert_ends_as_fmpy(model, run, rows, expected, stop, stair_reason: str):
    """Both runs end at the stop time, but the Reference FMU `Stair`'s, which asks to end the
    simulation at t = 9: both stop there, with the last point recorded, and spurio says why
    (`stair_reason`: how the FMI version asks)."""
    if model == "Stair":
        assert rows[-1, 0] == pytest.approx(9.0, abs=1e-12)
        assert expected["time"][-1] == pytest.approx(9.0, abs=1e-12)
        assert "asked to end the simulation at t = 9" in run.stdout
        assert stair_reason in run.stdout
    else:
        assert rows[-1, 0] == pytest.approx(stop, abs=1e-12)


@pytest.fixture
def workdir(tmp_path):
    return tmp_path


def oms_system(spec: dict, cwd) -> subprocess.CompletedProcess:
    """Runs the system `spec` in OMSimulator through its C API (oms_system.py: see there for
    the fields), in a process of its own as `oms_python` does."""
    import json

    return oms_python(
        f"import json, sys\nsys.path.insert(0, {str(pathlib.Path(__file__).parent)!r})\n"
        f"import oms_system\noms_system.main(json.loads({json.dumps(spec)!r}))\n",
        cwd,
    )
