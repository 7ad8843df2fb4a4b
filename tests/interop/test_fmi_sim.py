"""Our FMUs in rust-fmi's simulator `fmi-sim` 0.7.0 (crates.io; strict XML parsing, FMI 2.0 and
3.0; built by scripts/setup into target/tools), on each FMU's cross-check scenario, against
fmpy 0.3.32:

- Co-Simulation, FMI 2.0 (build/fmus) and FMI 3.0 (build/fmus/fmi3): against fmpy's
  Co-Simulation run of the FMI 2.0 FMU (the FMI 3.0 twins give it bit for bit:
  tests/fmpy/test_fmi3.py), to `engines.rounding_rtol`;
- Model Exchange where offered (GantryCrane, OpAmpFilter, WindGenerator, LinearSystem,
  LinearSystem2, DistributedObserverPlant): fmi-sim integrates with forward Euler at the
  output interval, against fmpy's Model Exchange run with its forward Euler at the same step.

The inputs are the scenario's, written one row per communication point
(`engines.write_held_inputs`: fmi-sim, as fmusim, applies the value left of an instant).
"""

import numpy as np
import pytest
from fmpy import read_model_description

from conftest import FMU_DIR, our_fmu, our_fmus
import engines

FMUS = our_fmus()
FMI3_DIR = FMU_DIR / "fmi3"


def offers_model_exchange(name):
    return read_model_description(str(our_fmu(name))).modelExchange is not None


ME_FMUS = [n for n in FMUS if offers_model_exchange(n)]


def test_the_model_exchange_fmus_are_the_expected_ones():
    assert ME_FMUS == ["DistributedObserverPlant", "GantryCrane", "LinearSystem",
                       "LinearSystem2", "OpAmpFilter", "WindGenerator"]


@pytest.mark.parametrize("name", FMUS)
def test_fmi2_co_simulation_equals_fmpy(name, workdir):
    sc = engines.scenario(our_fmu(name))
    run, got = engines.run_fmi_sim(sc, sc.fmu, "co-simulation", workdir)
    assert got is not None, run.stdout + run.stderr
    engines.assert_equals_fmpy(sc, got, "fmi-sim FMI 2.0 CS")


@pytest.mark.parametrize("name", ["GantryCrane", "OpAmpFilter", "WindGenerator"])
def test_an_integrating_fmu_in_fmi_sim_is_fmpy_on_fmi_sims_steps(name, workdir):
    """fmi-sim steps from k·h by h: the FMU driven so through fmpy's FMU2Slave gives
    fmi-sim's numbers bit for bit (and fmpy's `simulate_fmu`, stepping by (k+1)·h − k·h,
    differs from them by rounding: engines.INTEGRATING_RTOL)."""
    sc = engines.scenario(our_fmu(name))
    run, got = engines.run_fmi_sim(sc, sc.fmu, "co-simulation", workdir)
    assert got is not None, run.stdout + run.stderr
    driven = engines.fmpy_slave_stepped(sc, *engines.tool_steps(sc, "fmi-sim"))
    reals = [n for n, kind in sc.outputs.items() if kind == "Real"]
    assert engines.worst_difference(driven, got, reals)[0] == 0.0


# Forward Euler diverges on WindGenerator's electrical dynamics at its default step (0.1 s;
# fmpy's Euler fails there too, fmi2GetEventIndicators answering an error): 1 ms, for 1 s.
EULER_STEP = {"WindGenerator": (0.001, 1.0)}


def after_events(result, grid):
    """One row per communication point of `grid`: the last at that time (after the event
    handling there; an input event between the points, where the input file's times are not
    on the Euler grid, gives rows of its own, left out)."""
    t = result["time"]
    keep = np.concatenate([t[1:] != t[:-1], [True]]) & np.isin(t, grid)
    return {n: v[keep] for n, v in result.items()}


# Both integrate the same way; at WindGenerator's 1 ms the input events (on the scenario's
# 0.1 s grid, k·0.1 is not always k'·0.001) split Euler steps, whose lengths the two compute
# in different order: measured 2.8e-15 there, 0 elsewhere.
ME_RTOL = 1e-12


@pytest.mark.parametrize("name", ME_FMUS)
def test_fmi2_model_exchange_equals_fmpy(name, workdir):
    """fmi-sim's forward Euler against fmpy's, at each communication point after its events
    (both record a time twice at an event: before and after)."""
    sc = engines.scenario(our_fmu(name))
    if name in EULER_STEP:
        step, stop = EULER_STEP[name]
        sc = engines.Scenario(sc.fmu, sc.start, stop, step, sc.inputs, sc.boolean_inputs,
                              sc.input_rows, sc.outputs, sc.input_file)
    run, got = engines.run_fmi_sim(sc, sc.fmu, "model-exchange", workdir)
    assert got is not None, run.stdout + run.stderr
    got = after_events(got, sc.grid)
    expected = after_events(engines.fmpy_model_exchange(sc), sc.grid)
    np.testing.assert_array_equal(got["time"], expected["time"])
    assert len(got["time"]) == sc.steps + 1
    worst, where = engines.worst_difference(got, expected, sc.outputs)
    print(f"fmi-sim FMI 2.0 ME {name}: max relative difference to fmpy {worst:.3g} ({where})")
    assert worst <= ME_RTOL, (where, worst)
    assert any(np.ptp(got[n]) > 0 for n in sc.outputs)  # something moved


def test_a_change_on_the_last_input_row_ends_fmi_sim_model_exchange_in_error(workdir):
    """fmi-sim 0.7.0, Model Exchange: after an input event it interpolates between the row
    after the event and the next; a change on the last row (the crane's scenario changes U
    at t = 10, its stop time) is two rows at one time, (t − t₀)/(t₁ − t₀) = 0/0, and the NaN
    input is refused by the FMU: fmi-sim ends with "Error: Error" and writes no result.
    (`engines.write_event_inputs` adds a row after the stop time.)"""
    import subprocess

    sc = engines.scenario(our_fmu("GantryCrane"))
    rows = sc.input_rows
    assert rows[-1, 0] == rows[-2, 0] == sc.stop and rows[-1, 1] != rows[-2, 1]
    out = workdir / "out.csv"
    run = subprocess.run(
        [str(engines.FMI_SIM), "--model", str(sc.fmu), "-i", str(sc.input_file), "-o", str(out),
         "model-exchange", "-n", "0", "--output-interval", repr(sc.step)],
        capture_output=True, text=True, timeout=120, env={"RUST_BACKTRACE": "0"},
    )
    assert run.returncode != 0 and run.stderr.strip() == "Error: Error", run.stderr
    assert not out.exists()


FMI3_FMUS = sorted(p.stem for p in FMI3_DIR.glob("*.fmu"))


def refusal(description: str) -> str:
    """What fmi-sim 0.7.0 answers to an FMI 3.0 model description of ours. Its reader
    (fmi-schema 0.8.0) is strict and lacks attributes the standard's schema defines: a
    `<BaseUnit>`'s ampere and kelvin exponents are `A` and `K` (fmi3Unit.xsd), it knows `a`
    and `k`; a `<Float64>` variable carries fmi3RealBaseAttributes (quantity, unit,
    displayUnit, …) and `nominal` (fmi3Variable.xsd), it knows neither. The unit definitions
    come first in the file, so an `A` there is what it names."""
    import re

    if re.search(r"<BaseUnit[^>]*\sA=", description):
        return 'Error: unknown field "A" in element "BaseUnit"'
    assert re.search(r"<Float64\s[^>]*\sunit=", description)
    return 'Error: unknown field "unit" in element "FmiFloat64"'


def test_every_fmi3_fmu_of_ours_is_tried():
    assert len(FMI3_FMUS) == 25, FMI3_FMUS


@pytest.mark.parametrize("name", FMI3_FMUS)
def test_fmi_sim_refuses_our_fmi3_fmus_on_attributes_the_standard_defines(name, workdir):
    """Every FMI 3.0 FMU of ours (which fmpy validates against the standard's schemas and
    simulates: tests/fmpy/test_fmi3.py) is refused by fmi-sim 0.7.0 before it is loaded, in
    Co-Simulation and in Model Exchange, with the message `refusal` expects. When fmi-sim
    reads them, this fails: compare them with fmpy as the FMI 2.0 ones are."""
    import subprocess
    import zipfile

    fmu = FMI3_DIR / f"{name}.fmu"
    with zipfile.ZipFile(fmu) as z:
        expected = refusal(z.read("modelDescription.xml").decode())
    interfaces = ["co-simulation"] + (["model-exchange"] if name in ME_FMUS else [])
    for interface in interfaces:
        run = subprocess.run(
            [str(engines.FMI_SIM), "--model", str(fmu), "-o", str(workdir / "out.csv"),
             interface, "-n", "0", "-f", "0.1"],
            capture_output=True, text=True, timeout=120, env={"RUST_BACKTRACE": "0"},
        )
        assert run.returncode != 0 and run.stderr.strip() == expected, (interface, run.stderr)
