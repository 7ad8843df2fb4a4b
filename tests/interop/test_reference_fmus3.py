"""Every FMI 3.0 Co-Simulation Reference FMU runs in `spurio run` as in fmpy's `simulate_fmu`
(CS, no early return; spurio uses event mode where the FMU declares `hasEventMode`, fmpy
here does not): same points, same values (to 1e-12), at each FMU's own default experiment.
The FMUs with event mode also run as in fmpy with `use_event_mode=True`. Arrays (StateSpace's `y`) are recorded as their elements `y[1]`, `y[2]`,
… (1-based, row-major). `Stair` asks to end the simulation at t = 9 (`terminateSimulation`
in fmi3DoStep): both stop there, normally. `Clocks` (Scheduled Execution only) is refused
with a message that says why. A mixed system (FMI 2.0 and FMI 3.0 Feedthrough) passes
Real -> Float64, Integer -> Int32 and Boolean across the versions."""

import numpy as np
import pytest
from fmpy import read_model_description

from conftest import (THIRD_PARTY, REFERENCE_FMUS, assert_ends_as_fmpy, default_experiment, read_csv, require,
                      run_alone, spurio)

REFERENCE_FMUS_3 = THIRD_PARTY / "reference-fmus" / "fmi3"
CO_SIMULATION = ["BouncingBall", "Dahlquist", "Feedthrough", "Resource", "Stair", "StateSpace", "VanDerPol"]


def columns(fmu) -> list[tuple[str, str, tuple]]:
    """(column, variable, index) of every output fmpy records, arrays as their elements;
    not the aliases (`<Alias>`, the same value under another name), which spurio does not
    record by default."""
    out = []
    md = read_model_description(str(fmu))
    seen = set()
    for v in md.modelVariables:
        if v.causality != "output" or v.type in ("String", "Binary", "Clock"):
            continue
        if v.valueReference in seen:
            continue
        seen.add(v.valueReference)
        if not v.dimensions:
            out.append((v.name, v.name, ()))
            continue
        for index in np.ndindex(*v.shape):
            name = f"{v.name}[{','.join(str(i + 1) for i in index)}]"
            out.append((name, v.name, index))
    return out


def test_the_fmi3_reference_fmus_are_there():
    require(REFERENCE_FMUS_3, "see the third-party README")
    for model in CO_SIMULATION + ["Clocks"]:
        assert (REFERENCE_FMUS_3 / f"{model}.fmu").exists(), model


@pytest.mark.parametrize("model", CO_SIMULATION)
def test_spurio_run_matches_fmpy(model, workdir):
    fmu = REFERENCE_FMUS_3 / f"{model}.fmu"
    run, names, rows, expected, stop = run_alone(fmu, workdir)
    cols = columns(fmu)
    assert sorted(names) == sorted(["time"] + [f"m.{c}" for c, _, _ in cols])
    for column, variable, index in cols:
        got = rows[:, names.index(f"m.{column}")]
        want = expected[variable]
        want = want[(slice(None), *index)] if index else want
        np.testing.assert_allclose(got, want.astype(float), rtol=0, atol=1e-12, err_msg=column)
    assert_ends_as_fmpy(model, run, rows, expected, stop, "terminateSimulation = true")
    if model == "StateSpace":
        # y = C x + D u with C = D = I: y[i] > u[i] = 1, 2, 3 once x grows (x' = x + u).
        assert [n for n in names if n.startswith("m.y")] == ["m.y[1]", "m.y[2]", "m.y[3]"]
        assert rows[-1, names.index("m.y[3]")] > 3.0


EVENT_MODE = ["BouncingBall", "Feedthrough", "Stair", "StateSpace"]


@pytest.mark.parametrize("model", EVENT_MODE)
def test_spurio_event_mode_matches_fmpy_event_mode(model, workdir):
    """Both instantiate with eventModeUsed = true and run the event iteration after every
    step that needs one. fmpy samples a point again after each event iteration: its last
    value at each time is compared. fmpy goes on past Stair's terminateSimulation from the
    event iteration at t = 9 (spurio stops there): the points up to 9 are compared."""
    from fmpy import simulate_fmu

    fmu = REFERENCE_FMUS_3 / f"{model}.fmu"
    assert read_model_description(str(fmu)).coSimulation.hasEventMode
    stop, step = default_experiment(fmu)
    system = workdir / "system.toml"
    system.write_text(f'stop_time = {stop!r}\nstep_size = {step!r}\n[[instance]]\nname = "m"\nfmu = "{fmu}"\n')
    out = workdir / "spurio.csv"
    run = spurio("run", system, "--out", out)
    names, rows = read_csv(out)
    expected = simulate_fmu(str(fmu), fmi_type="CoSimulation", use_event_mode=True,
                            stop_time=stop, step_size=step, output_interval=step)
    time = expected["time"]
    expected = expected[np.r_[time[1:] != time[:-1], True]]
    if model == "Stair":
        assert expected["time"][-1] == pytest.approx(9.2, abs=1e-12)
        expected = expected[expected["time"] <= 9.0 + 1e-12]
    assert rows.shape[0] == len(expected)
    np.testing.assert_allclose(rows[:, 0], expected["time"], rtol=0, atol=1e-12)
    for column, variable, index in columns(fmu):
        got = rows[:, names.index(f"m.{column}")]
        want = expected[variable]
        want = want[(slice(None), *index)] if index else want
        np.testing.assert_allclose(got, want.astype(float), rtol=0, atol=1e-12, err_msg=column)
    assert_ends_as_fmpy(model, run, rows, expected, stop, "terminateSimulation = true")


def test_clocks_is_refused_with_the_reason(workdir):
    fmu = REFERENCE_FMUS_3 / "Clocks.fmu"
    system = workdir / "system.toml"
    system.write_text(f'stop_time = 1.0\nstep_size = 0.1\n[[instance]]\nname = "c"\nfmu = "{fmu}"\n')
    run = spurio("run", system, "--out", workdir / "out.csv", check=False)
    assert run.returncode != 0
    message = run.stdout + run.stderr
    assert "is not a Co-Simulation FMU" in message, message
    assert "Scheduled Execution" in message, message


def test_a_mixed_fmi2_fmi3_system_passes_values_across_versions(workdir):
    """FMI 2.0 Feedthrough -> FMI 3.0 Feedthrough -> FMI 2.0 Feedthrough: the values set on
    the first arrive unchanged at the last, at every point (Gauss-Seidel, direct feedthrough)."""
    fmu2 = REFERENCE_FMUS / "Feedthrough.fmu"
    fmu3 = REFERENCE_FMUS_3 / "Feedthrough.fmu"
    system = workdir / "mixed.toml"
    system.write_text(
        "stop_time = 1.0\nstep_size = 0.25\n"
        "connections = [\n"
        '  "a.Float64_continuous_output -> b.Float64_continuous_input",\n'
        '  "a.Int32_output -> b.Int32_input",\n'
        '  "a.Boolean_output -> b.Boolean_input",\n'
        '  "b.Float64_continuous_output -> c.Float64_continuous_input",\n'
        '  "b.Int32_output -> c.Int32_input",\n'
        '  "b.Boolean_output -> c.Boolean_input",\n'
        "]\n"
        'record = ["c.Float64_continuous_output", "c.Int32_output", "c.Boolean_output", "b.Int32_output"]\n'
        f'[[instance]]\nname = "a"\nfmu = "{fmu2}"\n'
        "parameters = { Float64_continuous_input = 2.5, Int32_input = -7, Boolean_input = true }\n"
        f'[[instance]]\nname = "b"\nfmu = "{fmu3}"\n'
        f'[[instance]]\nname = "c"\nfmu = "{fmu2}"\n'
    )
    out = workdir / "mixed.csv"
    spurio("run", system, "--out", out)
    names, rows = read_csv(out)
    assert names == ["time", "c.Float64_continuous_output", "c.Int32_output", "c.Boolean_output", "b.Int32_output"]
    assert rows.shape == (5, 5)
    np.testing.assert_array_equal(rows[:, 1:], [[2.5, -7, 1, -7]] * 5)
