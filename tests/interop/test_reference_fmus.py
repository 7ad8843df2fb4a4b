"""Every FMI 2.0 Reference FMU runs in `spurio run` as in fmpy's `simulate_fmu` (CS): same
points, same values (to 1e-12), at each FMU's own default experiment. `Stair` asks to end
the simulation at t = 9 (fmi2Discard with fmi2Terminated): both stop there, normally."""

import numpy as np
import pytest
from fmpy import read_model_description

from conftest import REFERENCE_FMUS, assert_ends_as_fmpy, require, run_alone

REFERENCE = sorted(p.stem for p in REFERENCE_FMUS.glob("*.fmu"))


def test_the_reference_fmus_are_there():
    require(REFERENCE_FMUS, "see the third-party README")
    assert REFERENCE == [
        "BouncingBall",
        "Dahlquist",
        "Feedthrough",
        "Resource",
        "Stair",
        "VanDerPol",
    ]


@pytest.mark.parametrize("model", REFERENCE)
def test_spurio_run_matches_fmpy(model, workdir):
    fmu = REFERENCE_FMUS / f"{model}.fmu"
    run, names, rows, expected, stop = run_alone(fmu, workdir)
    # fmpy records the Real, Integer, Boolean and Enumeration outputs; so does spurio.
    outputs = [
        v.name
        for v in read_model_description(str(fmu)).modelVariables
        if v.causality == "output" and v.type != "String"
    ]
    assert names == ["time"] + [f"m.{n}" for n in outputs]
    for j, name in enumerate(outputs, start=1):
        np.testing.assert_allclose(
            rows[:, j], expected[name].astype(float), rtol=0, atol=1e-12, err_msg=name
        )
    assert_ends_as_fmpy(model, run, rows, expected, stop, "fmi2Terminated")
