"""Every FMU of ours in the FMU Compliance Checker and in OMSimulator, against fmpy.

Each FMU runs to its default stop time at the power of two nearest its default step
(`binary_step`: n·h is exact, so fmpy's start + n·h and the tools' accumulated t += h agree
on every communication point and nobody takes a tiny last step). The timing case, each
FMU's own default step (0.1, 0.05, …, not exact in binary), is tested apart: there
OMSimulator's accumulated time falls short of the stop time and it takes a last step of
~1e-15 s. Our discrete-time FMUs sample on their own clock (docs/README.md, "Sampling": the
instants start + k·T, k an integer, compared within 1e-9·T), so that step takes no sample
and they match fmpy there too.
"""

import subprocess

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu

from conftest import (
    FMUCHECK,
    OMS_RTOL,
    binary_step,
    by_time,
    column,
    default_experiment,
    omsimulator,
    our_fmu,
    our_fmus,
    read_csv,
    require,
)

FMUS = our_fmus()


def test_every_fmu_of_ours_is_tested():
    assert len(FMUS) == 25, FMUS


def outputs(fmu):
    return [
        v.name
        for v in read_model_description(str(fmu)).modelVariables
        if v.causality == "output" and v.type != "String"
    ]


def fmpy_result(fmu, stop, step):
    return simulate_fmu(
        str(fmu), fmi_type="CoSimulation", stop_time=stop, step_size=step, output_interval=step
    )


@pytest.mark.parametrize("name", FMUS)
def test_fmucheck_passes_and_matches_fmpy(name, workdir):
    fmu = our_fmu(name)
    stop, step = default_experiment(fmu)
    step = binary_step(step)
    out = workdir / "fmucheck.csv"
    check = subprocess.run(
        [str(require(FMUCHECK, "see the third-party README")), "-k", "cs", "-n", "0", "-h", repr(step),
         "-s", repr(stop), "-o", str(out), str(fmu)],
        capture_output=True, text=True, timeout=300,
    )
    report = check.stdout + check.stderr
    assert check.returncode == 0, report
    assert "0 Warning(s)" in report and "0 Error(s)" in report, report
    assert "0 warning(s) and error(s)" in report, report

    names, rows = read_csv(out)
    expected = fmpy_result(fmu, stop, step)
    assert rows.shape[0] == len(expected)
    np.testing.assert_allclose(rows[:, 0], expected["time"], rtol=0, atol=1e-12)
    for name_ in outputs(fmu):
        np.testing.assert_allclose(
            column(names, rows, name_), expected[name_].astype(float), rtol=1e-15, atol=0,
            err_msg=name_,
        )


def omsimulator_result(fmu, stop, step, workdir):
    out = workdir / "oms.csv"
    omsimulator(
        fmu, "--mode=cs", f"--stopTime={stop!r}", f"--stepSize={step!r}",
        f"--resultFile={out.name}", cwd=workdir,
    )
    return read_csv(out)


def compare_with_fmpy(fmu, stop, step, workdir, rtol=OMS_RTOL):
    names, rows = by_time(*omsimulator_result(fmu, stop, step, workdir), keep="last")
    expected = fmpy_result(fmu, stop, step)
    assert rows.shape[0] == len(expected), (rows[-3:, 0], expected["time"][-3:])
    np.testing.assert_allclose(rows[:, 0], expected["time"], rtol=OMS_RTOL, atol=0)
    for name_ in outputs(fmu):
        np.testing.assert_allclose(
            column(names, rows, name_), expected[name_].astype(float), rtol=rtol, atol=0,
            err_msg=name_,
        )


def integration_rtol(fmu):
    """How closely two runs of `fmu` on communication grids that differ in the last bits can
    agree: exactly (the printed digits, OMS_RTOL) for fixed-step and discrete-time FMUs; for
    an FMU with error control (a parameter `rtol`, e.g. WindGenerator) each slightly different
    communication step moves the adaptive substeps, so the results differ by the integration
    error the tolerance allows — ten times `rtol`, the bound its page documents."""
    for variable in read_model_description(str(fmu)).modelVariables:
        if variable.name == "rtol" and variable.causality == "parameter":
            return max(OMS_RTOL, 10 * float(variable.start))
    return OMS_RTOL


@pytest.mark.parametrize("name", FMUS)
def test_omsimulator_matches_fmpy(name, workdir):
    fmu = our_fmu(name)
    stop, step = default_experiment(fmu)
    compare_with_fmpy(fmu, stop, binary_step(step), workdir)


@pytest.mark.parametrize("name", FMUS)
def test_omsimulator_matches_fmpy_at_the_default_step(name, workdir):
    """The FMU's own default step (not exact in binary): OMSimulator accumulates time and
    may end with a step of ~1e-15 s, fmpy does not; the discrete-time FMUs (LinearSystem,
    Sensor, the estimators) take no sample in that step, as in fmpy. The steps' lengths differ
    in the last bits: an FMU with error control agrees to its tolerance (integration_rtol)."""
    fmu = our_fmu(name)
    stop, step = default_experiment(fmu)
    compare_with_fmpy(fmu, stop, step, workdir, rtol=integration_rtol(fmu))
