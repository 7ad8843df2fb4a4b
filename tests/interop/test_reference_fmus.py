"""Every FMI 2.0 Reference FMU runs in `spurio run` as in fmpy's `simulate_fmu` (CS): same
points, same values (to 1e-12), at each FMU's own default experiment. `Stair` asks to end
the simulation at t = 9 (fmi2Discard with fmi2Terminated): both stop there, normally."""

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu

from conftest import REFERENCE_FMUS, default_experiment, read_csv, require, spurio

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
    # fmpy records the Real, Integer, Boolean and Enumeration outputs; so does spurio.
    outputs = [
        v.name
        for v in read_model_description(str(fmu)).modelVariables
        if v.causality == "output" and v.type != "String"
    ]
    assert names == ["time"] + [f"m.{n}" for n in outputs]
    assert rows.shape[0] == len(expected), (rows[-3:], expected[-3:])
    np.testing.assert_allclose(rows[:, 0], expected["time"], rtol=0, atol=1e-12)
    for j, name in enumerate(outputs, start=1):
        np.testing.assert_allclose(
            rows[:, j], expected[name].astype(float), rtol=0, atol=1e-12, err_msg=name
        )

    if model == "Stair":
        # Ends at 9, not at the stop time 10, with the last point recorded and the reason said.
        assert rows[-1, 0] == 9.0 and expected["time"][-1] == 9.0
        assert "asked to end the simulation at t = 9" in run.stdout
        assert "fmi2Terminated" in run.stdout
    else:
        assert rows[-1, 0] == pytest.approx(stop, abs=1e-12)
