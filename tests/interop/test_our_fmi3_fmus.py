"""Our FMI 3.0 FMUs (build/fmus/fmi3/) in OMSimulator 3.0, against fmpy.

What OMSimulator's FMI 3.0 importer accepts: it loads every one of them and runs the
Co-Simulation interface, but it reads and writes each input and output as one value
(`nValues = 1`), also for an array variable. An FMU whose inputs and outputs are scalars (or
arrays of one element) runs and matches fmpy; one with a larger array input, output or
calculated parameter is
refused by our `fmi3GetFloat64`/`fmi3SetFloat64` with the message "nValues = 1, but the 1
value references name N values" (logged through its callback), which is right (FMI 3.0.2 §2.2.6.2: `nValues` is the
number of elements of all the variables): the fault is the tool's, and those FMUs are to be
used in OMSimulator as FMI 2.0 (build/fmus/<Model>.fmu, scalars `x_hat[1]` …).
"""

import subprocess

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu

from conftest import (
    FMU_DIR,
    OMS_RTOL,
    OMSIMULATOR,
    binary_step,
    by_time,
    column,
    default_experiment,
    read_csv,
    require,
)

FMUS3 = sorted(p.stem for p in (FMU_DIR / "fmi3").glob("*.fmu"))


def signals(md):
    """The variables OMSimulator reads or writes every step: inputs, outputs, calculated
    parameters."""
    return [v for v in md.modelVariables
            if v.causality in ("input", "output", "calculatedParameter")]


def array_sizes(md):
    """The element counts of the signals that are arrays of more than one element."""
    return {int(np.prod(v.shape)) for v in signals(md) if v.shape and np.prod(v.shape) > 1}


def run_omsimulator(fmu, stop, step, workdir):
    out = workdir / "oms.csv"
    result = subprocess.run(
        [str(require(OMSIMULATOR, "see the third-party README")), str(fmu), "--mode=cs",
         f"--stopTime={stop!r}", f"--stepSize={step!r}", f"--resultFile={out.name}"],
        capture_output=True, text=True, timeout=300, cwd=workdir,
    )
    return result.stdout + result.stderr, out


def test_every_fmi3_fmu_is_tested():
    assert len(FMUS3) == 25, FMUS3


@pytest.mark.parametrize("name", FMUS3)
def test_omsimulator_runs_our_fmi3_fmus_or_is_refused_its_scalar_reads_of_arrays(name, workdir):
    fmu = FMU_DIR / "fmi3" / f"{name}.fmu"
    md = read_model_description(str(fmu))
    stop, step = default_experiment(fmu)
    step = binary_step(step)
    log, out = run_omsimulator(fmu, stop, step, workdir)
    assert "Loading FMI version 3" in log, log
    sizes = array_sizes(md)
    if sizes:
        assert any(f"nValues = 1, but the 1 value references name {n} values" in log
                   for n in sizes), log
        return
    assert "error:" not in log, log
    names, rows = by_time(*read_csv(out), keep="last")
    expected = simulate_fmu(str(fmu), stop_time=stop, step_size=step, output_interval=step)
    assert rows.shape[0] == len(expected)
    np.testing.assert_allclose(rows[:, 0], expected["time"], rtol=OMS_RTOL, atol=0)
    for v in signals(md):
        if v.causality != "output":
            continue
        got = column(names, rows, v.name)
        want = expected[v.name].astype(float).reshape(len(expected))
        np.testing.assert_allclose(got, want, rtol=OMS_RTOL, atol=0, err_msg=v.name)
