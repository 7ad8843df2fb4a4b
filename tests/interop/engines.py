"""Our FMUs in the fixed-step masters of libcosim (the Open Simulation Platform's engine,
PyPI `libcosimpy`, which bundles `libcosimc`) and ecos (PyPI `ecospy`, in process and through
`proxyfmu`, out of process), and in rust-fmi's simulator `fmi-sim`, driven through the
cross-check scenario of each FMU (fmus/<Id>/crosscheck/: `_ref.opt` the experiment,
`_in.csv` the inputs), and compared with fmpy's run of the same scenario
(`scripts/crosscheck.py simulate`, as the `_ref.csv` were written); our SSP 1.0 exports of
the crane systems in libcosim and ecos, against fmpy's SSP runner.

How the scenario is applied (what fmpy does, `simulateCS`): the inputs at the start time are
set in initialization mode; before the step from t_k, the inputs at t_k (the last row of
`_in.csv` with time ≤ t_k: a change is written as two rows at the same time, before and
after) are set; the outputs are read after initialization and after each step, before the
next inputs are set. Both engines step on t_k = k·h, libcosim on an integer count of
nanoseconds (h = 0.05 s is 50 000 000 ns), ecos in double precision.
"""

from __future__ import annotations

import ctypes
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from fmpy import read_model_description

from conftest import REPO

sys.path.insert(0, str(REPO / "scripts"))
import crosscheck  # noqa: E402


@dataclass
class Scenario:
    """One FMU's cross-check scenario: the experiment, the inputs (names, Boolean or not, and
    the rows of `_in.csv`) and the outputs fmpy records (name → 'Real', 'Integer' or
    'Boolean')."""

    fmu: Path
    start: float
    stop: float
    step: float
    inputs: list[str]
    boolean_inputs: set[str]
    input_rows: np.ndarray
    outputs: dict[str, str]
    input_file: Path | None = None

    @property
    def steps(self) -> int:
        return int(round((self.stop - self.start) / self.step))

    def inputs_at(self, t: float) -> dict[str, float]:
        """The inputs held at `t` (sample and hold: the last row at or before `t`, within a
        billionth of a step, as fmpy's `Input` takes the value after a change)."""
        if not self.inputs:
            return {}
        times = self.input_rows[:, 0]
        row = int(np.searchsorted(times, t + 1e-9 * self.step, side="right")) - 1
        return dict(zip(self.inputs, self.input_rows[max(row, 0), 1:]))

    @property
    def grid(self) -> np.ndarray:
        return self.start + np.arange(self.steps + 1) * self.step


def scenario(fmu: Path) -> Scenario:
    md = crosscheck.md_of(fmu)
    folder = crosscheck.folder_of(fmu.stem, crosscheck.identifier(md))
    opt = crosscheck.read_opt(folder / f"{fmu.stem}_ref.opt")
    described = read_model_description(str(fmu))
    types = {v.name: v.type for v in described.modelVariables}
    inputs, rows = [], np.zeros((1, 1))
    in_csv = folder / f"{fmu.stem}_in.csv"
    if in_csv.exists():
        header, table = crosscheck.read_table(in_csv)
        inputs, rows = header[1:], np.array(table)
    outputs = {v.name: v.type for v in described.modelVariables
               if v.causality == "output" and v.type in ("Real", "Integer", "Boolean")}
    return Scenario(fmu, opt["StartTime"], opt["StopTime"], opt["StepSize"], inputs,
                    {n for n in inputs if types[n] == "Boolean"}, rows, outputs,
                    in_csv if inputs else None)


_FMPY: dict[Path, dict[str, np.ndarray]] = {}


def fmpy_result(sc: Scenario) -> dict[str, np.ndarray]:
    """fmpy's run of the scenario (Co-Simulation), one array per output and `time`; computed
    once per FMU and test session."""
    if sc.fmu not in _FMPY:
        folder = crosscheck.folder_of(sc.fmu.stem, crosscheck.identifier(crosscheck.md_of(sc.fmu)))
        result = crosscheck.simulate(sc.fmu, folder)
        _FMPY[sc.fmu] = {n: np.asarray(result[n], dtype=float) for n in result.dtype.names}
    return _FMPY[sc.fmu]


def relative_difference(a: np.ndarray, b: np.ndarray) -> float:
    """max |a − b| / max(|a|, |b|) over the points where either is non-zero (0 where both are)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    scale = np.maximum(np.abs(a), np.abs(b))
    diff = np.abs(a - b)
    return float(np.max(np.where(scale > 0, diff / np.where(scale > 0, scale, 1.0), 0.0),
                        initial=0.0))


def worst_difference(got: dict[str, np.ndarray], expected: dict[str, np.ndarray],
                     names) -> tuple[float, str]:
    """The largest relative difference over the columns `names`, and the column it is in."""
    worst, where = 0.0, ""
    for name in names:
        theirs = expected[name]
        if len(got[name]) == len(theirs) - 1:
            theirs = theirs[1:]  # a series without its initial sample (libcosim's Booleans)
        assert got[name].shape == theirs.shape, (name, got[name].shape, theirs.shape)
        d = relative_difference(got[name], theirs)
        if d > worst or not where:
            worst, where = max(worst, d), name
    return worst, where


# ---- libcosim -------------------------------------------------------------------------------

NANOSECONDS = 1_000_000_000


def libcosim_nanoseconds(seconds: float) -> int:
    """libcosim counts time in integer nanoseconds: the step of a scenario, exactly."""
    ns = round(seconds * NANOSECONDS)
    assert abs(ns / NANOSECONDS - seconds) <= 1e-15 * max(1.0, seconds), seconds
    return ns


def _libcosim_real_or_integer_samples(observer, slave: int, vr: int, kind: str,
                                      count: int) -> np.ndarray:
    """All `count` samples of one variable from libcosim's time-series observer, step 0
    (after initialization) included. libcosimpy 0.0.6's `time_series_real_samples` counts
    the step numbers equal to 0 as empty slots and drops as many samples from the end, so
    the initial one always costs the last: this calls `cosim_observer_slave_get_*_samples`
    itself."""
    from libcosimpy._internal import libcosimc
    from libcosimpy.CosimObserver import CosimObserver

    c_type = ctypes.c_double if kind == "Real" else ctypes.c_int
    name = "real" if kind == "Real" else "integer"
    function = getattr(libcosimc(), f"cosim_observer_slave_get_{name}_samples")
    function.argtypes = [ctypes.POINTER(CosimObserver), ctypes.c_int, ctypes.c_uint32,
                         ctypes.c_int64, ctypes.c_size_t, ctypes.POINTER(c_type),
                         ctypes.POINTER(ctypes.c_int64), ctypes.POINTER(ctypes.c_int64)]
    function.restype = ctypes.c_int64
    values = (c_type * count)()
    steps = (ctypes.c_int64 * count)()
    times = (ctypes.c_int64 * count)()
    got = function(observer.ptr(), slave, vr, 0, count, values, steps, times)
    assert got == count, f"libcosim gave {got} samples of {count}"
    assert list(steps) == list(range(count))
    return np.array(values[:], dtype=float)


def run_libcosim(sc: Scenario) -> dict[str, np.ndarray]:
    """The scenario in libcosim's fixed-step algorithm (`cosim_execution_create`, one local
    slave): inputs at the start as initial values, then through an override manipulator
    before each step; the outputs from a time-series observer (Real, Integer) and a last-value
    observer read after each step (Boolean: libcosim's time-series observer keeps Real and
    Integer series only, so they have no sample at the start)."""
    from libcosimpy.CosimEnums import CosimVariableType
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimManipulator import CosimManipulator
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    log_output_level(CosimLogLevel.ERROR)
    assert sc.start == 0.0, "libcosimpy starts every execution at t = 0"
    execution = CosimExecution.from_step_size(libcosim_nanoseconds(sc.step))
    slave = execution.add_local_slave(CosimLocalSlave(fmu_path=str(sc.fmu), instance_name="m"))
    assert slave >= 0, "libcosim could not load the FMU"
    vrs = {v.name.decode(): v.reference for v in execution.slave_variables(slave)}
    series = CosimObserver.create_time_series(buffer_size=sc.steps + 1)
    last = CosimObserver.create_last_value()
    override = CosimManipulator.create_override()
    for part in (series, last):
        execution.add_observer(part)
    execution.add_manipulator(override)
    kinds = {"Real": CosimVariableType.REAL, "Integer": CosimVariableType.INTEGER}
    for name, kind in sc.outputs.items():
        if kind in kinds:
            assert series.start_time_series(slave, vrs[name], kinds[kind])

    def set_inputs(values: dict[str, float], initial: bool):
        for name, value in values.items():
            if name in sc.boolean_inputs:
                ok = (execution.boolean_initial_value(slave, vrs[name], bool(value)) if initial
                      else override.slave_boolean_values(slave, [vrs[name]], [bool(value)]))
            else:
                ok = (execution.real_initial_value(slave, vrs[name], float(value)) if initial
                      else override.slave_real_values(slave, [vrs[name]], [float(value)]))
            assert ok, f"libcosim refused the input {name}"

    booleans = [n for n, kind in sc.outputs.items() if kind == "Boolean"]
    boolean_rows = []
    previous: dict[str, float] = {}
    for k in range(sc.steps):
        now = sc.inputs_at(sc.grid[k])
        set_inputs({n: v for n, v in now.items() if previous.get(n) != v}, initial=k == 0)
        previous = now
        assert execution.step(1), f"libcosim: step {k} failed"
        if booleans:
            boolean_rows.append(last.last_boolean_values(slave, [vrs[n] for n in booleans]))
    result = {"time": sc.grid}
    for name, kind in sc.outputs.items():
        if kind in kinds:
            result[name] = _libcosim_real_or_integer_samples(series, slave, vrs[name], kind,
                                                             sc.steps + 1)
    for i, name in enumerate(booleans):
        result[name] = np.array([row[i] for row in boolean_rows], dtype=float)
    return result


# ---- ecos -----------------------------------------------------------------------------------

def ecos_binaries() -> Path:
    """ecospy's folder of binaries (`ecos`, `proxyfmu`, `libecosc.so`)."""
    import ecospy

    return Path(ecospy.__file__).parent / "binaries"


def run_ecos(sc: Scenario, proxy: bool = False) -> dict[str, np.ndarray]:
    """The scenario in ecos's fixed-step algorithm (ecospy's `EcosSimulation`, one model `m`;
    with `proxy`, loaded as `proxyfmu://localhost?file=…`: the FMU runs in a `proxyfmu`
    process of its own): the inputs at the start as a parameter set applied at
    initialization, then set before each step; every output read after initialization and
    after each step."""
    from ecospy.EcosSimulation import EcosSimulation
    from ecospy.EcosSimulationStructure import EcosSimulationStructure
    from ecospy.lib import EcosLib

    EcosLib.set_log_level("err")
    uri = f"proxyfmu://localhost?file={sc.fmu}" if proxy else str(sc.fmu)
    rows = []

    def read(sim) -> list[float]:
        row = []
        for name, kind in sc.outputs.items():
            get = {"Real": sim.get_real, "Integer": sim.get_integer, "Boolean": sim.get_bool}
            row.append(float(get[kind](f"m::{name}")))
        return row

    def typed(name: str, value: float):
        return bool(value) if name in sc.boolean_inputs else float(value)

    with EcosSimulationStructure() as structure:
        structure.add_model("m", uri)
        initial = {f"m::{n}": typed(n, v) for n, v in sc.inputs_at(sc.grid[0]).items()}
        if initial:
            structure.add_parameter_set("inputs", initial)
        with EcosSimulation(structure=structure, step_size=sc.step) as sim:
            sim.init(start_time=sc.start, parameter_set="inputs" if initial else None)
            rows.append(read(sim))
            previous = sc.inputs_at(sc.grid[0])
            for k in range(sc.steps):
                now = sc.inputs_at(sc.grid[k])
                for name, value in now.items():
                    if previous.get(name) != value:
                        (sim.set_bool if name in sc.boolean_inputs else sim.set_real)(
                            f"m::{name}", typed(name, value))
                previous = now
                sim.step(1)
                rows.append(read(sim))
            times = sim.get_time()
            sim.terminate()
    assert math.isclose(times, sc.stop, rel_tol=1e-12), (times, sc.stop)
    table = np.array(rows, dtype=float)
    result = {"time": sc.grid}
    for i, name in enumerate(sc.outputs):
        result[name] = table[:, i]
    return result


def run_ecos_proxy(sc: Scenario) -> dict[str, np.ndarray]:
    return run_ecos(sc, proxy=True)


# ---- agreement --------------------------------------------------------------------------------

# What "equal to fmpy's" means (the tolerance asserted):
# - bit-identical (0) for an FMU whose step does not depend on the step's length in its last
#   bits: the discrete-time FMUs (they sample on their own clock, docs/README.md "Sampling"),
#   the estimators, the sources;
# - a relative 1e-11 for an FMU that integrates over the step (it has the parameter `h_max`,
#   its longest RK4 substep: GantryCrane, OpAmpFilter, WindGenerator): fmpy steps from k·h by
#   (k+1)·h − k·h, which differs from h in the last bits; ecos and fmi-sim by h; libcosim
#   from k·h_ns/10⁹ by the difference of two such points. The substeps differ by rounding,
#   the trajectories by rounding grown over the run (measured: at most 3.5e-12); driven
#   through fmpy's FMU2Slave on a tool's own points and steps (`tool_steps`), the FMU gives
#   the tool's numbers bit for bit (tested).
EXACT = 0.0
INTEGRATING_RTOL = 1e-11


def rounding_rtol(sc: Scenario) -> float:
    names = {v.name for v in read_model_description(str(sc.fmu)).modelVariables
             if v.causality == "parameter"}
    return INTEGRATING_RTOL if "h_max" in names else EXACT


def assert_equals_fmpy(sc: Scenario, got: dict[str, np.ndarray], tool: str,
                       names=None) -> float:
    """Every output of `got` (or those in `names`) equals fmpy's to `rounding_rtol`; returns
    the largest relative difference (printed, for the README's figures)."""
    expected = fmpy_result(sc)
    names = list(sc.outputs) if names is None else list(names)
    np.testing.assert_allclose(got["time"], expected["time"], rtol=1e-15, atol=0)
    worst, where = worst_difference(got, expected, names)
    rtol = rounding_rtol(sc)
    print(f"{tool} {sc.fmu.stem}: max relative difference to fmpy {worst:.3g} ({where})")
    assert worst <= rtol, f"{tool} {sc.fmu.stem}: {where} differs from fmpy by {worst:.3g} > {rtol}"
    return worst


# ---- SSP ------------------------------------------------------------------------------------

@dataclass
class SspRun:
    """An exported system: the .ssp, its stop time and step, the recorded variables
    (`instance.variable`) and the parameters of the system file (`instance.parameter` →
    value), which fmpy's SSP runner must be given (it ignores the SSD's bindings)."""

    ssp: Path
    stop: float
    step: float
    record: list[str]
    parameters: dict[str, float]

    @property
    def steps(self) -> int:
        return int(round(self.stop / self.step))


def export_ssp_1_0(system_toml: Path, workdir: Path) -> SspRun:
    """`system_toml` (examples/systems/…, FMUs under build/fmus) with absolute FMU paths,
    exported by `spurio ssp-export --ssp-version 1.0`."""
    import tomllib

    from conftest import FMU_DIR, spurio

    text = system_toml.read_text().replace("../../build/fmus/", f"{FMU_DIR}/")
    system = workdir / system_toml.name
    system.write_text(text)
    ssp = workdir / f"{system_toml.stem}.ssp"
    spurio("ssp-export", system, ssp, "--ssp-version", "1.0")
    parsed = tomllib.loads(text)
    parameters = {f"{i['name']}.{k}": float(v) for i in parsed["instance"]
                  for k, v in i.get("parameters", {}).items()}
    return SspRun(ssp, float(parsed["stop_time"]), float(parsed["step_size"]),
                  list(parsed["record"]), parameters)


def fmpy_ssp(run: SspRun) -> dict[str, np.ndarray]:
    """fmpy's SSP runner on the export (a Jacobi master): its row k holds the values after the
    step from t_k, i.e. at t_(k+1)."""
    from fmpy.ssp.simulation import simulate_ssp
    from fmpy.ssp.ssd import Parameter, ParameterSet

    parameters = ParameterSet(parameters=[Parameter(name=n, type="Real", value=v)
                                          for n, v in run.parameters.items()])
    result = simulate_ssp(str(run.ssp), stop_time=run.stop, step_size=run.step,
                          parameter_set=parameters)
    assert len(result) == run.steps
    return {n: np.asarray(result[n], dtype=float) for n in run.record}


def libcosim_ssp(run: SspRun) -> dict[str, np.ndarray]:
    """The export in libcosim (`cosim_ssp_fixed_step_execution_create`: the SSD's connections
    and parameter bindings, its fixed-step algorithm): the recorded variables after each
    step."""
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    log_output_level(CosimLogLevel.ERROR)
    execution = CosimExecution.from_ssp_file(str(run.ssp),
                                             step_size=libcosim_nanoseconds(run.step))
    slaves = {i.name.decode(): i.index for i in execution.slave_infos()}
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    where = []
    for name in run.record:
        instance, variable = name.split(".", 1)
        vrs = {v.name.decode(): v.reference for v in execution.slave_variables(slaves[instance])}
        where.append((slaves[instance], vrs[variable]))
    rows = []
    for k in range(run.steps):
        assert execution.step(1), f"libcosim: step {k} failed"
        rows.append([observer.last_real_values(s, [vr])[0] for s, vr in where])
    table = np.array(rows)
    return {n: table[:, i] for i, n in enumerate(run.record)}


def ecos_ssp(run: SspRun, parameter_set: str | None) -> dict[str, np.ndarray]:
    """The export in ecos (`ecos_simulation_create_from_ssp`, its fixed-step algorithm),
    initialized with the SSD's parameter set `parameter_set`: the recorded variables after
    each step."""
    from ecospy.EcosSimulation import EcosSimulation
    from ecospy.lib import EcosLib

    EcosLib.set_log_level("err")
    rows = []
    with EcosSimulation(ssp_path=str(run.ssp), step_size=run.step) as sim:
        sim.init(parameter_set=parameter_set)
        for _ in range(run.steps):
            sim.step(1)
            rows.append([sim.get_real(n.replace(".", "::", 1)) for n in run.record])
        sim.terminate()
    table = np.array(rows)
    return {n: table[:, i] for i, n in enumerate(run.record)}


# ---- fmi-sim --------------------------------------------------------------------------------

FMI_SIM = REPO / "target" / "tools" / "bin" / "fmi-sim"


def write_held_inputs(sc: Scenario, path: Path) -> Path:
    """The scenario's inputs as fmi-sim reads them to apply at each t_k exactly the value
    fmpy applies. fmi-sim, as fmusim, applies at t_k the value left of t_k (`after_event`
    false), interpolated linearly as v₀ + 1·(v₁ − v₀) (not v₁ in floating point): the
    cross-check file's pair of rows at a change (before, after) would reach it one step late,
    and a row per point would reach it rounded at a change. So a row per point t_k with the
    value held from t_k on, and at a change a row half a step before with the new value: each
    t_k then ends a segment whose ends hold the same value."""
    import csv

    def cells(t: float, held: dict[str, float]) -> list[str]:
        return [repr(float(t))] + [
            ("true" if held[n] else "false") if n in sc.boolean_inputs else repr(float(held[n]))
            for n in sc.inputs]

    with path.open("w", newline="") as f:
        out = csv.writer(f)
        out.writerow(["time"] + sc.inputs)
        previous = None
        for t in sc.grid:
            held = sc.inputs_at(t)
            if previous is not None and held != previous:
                out.writerow(cells(t - 0.5 * sc.step, held))
            out.writerow(cells(t, held))
            previous = held
    return path


def write_event_inputs(sc: Scenario, path: Path) -> Path:
    """The scenario's inputs for fmi-sim's Model Exchange: the cross-check file as it is (a
    change is two rows at one time: an input event, handled as fmpy handles it), and one row
    half a step after its last, holding the last value. fmi-sim 0.7.0 interpolates after an
    event between the row after it and the next: at a change on the last row that is two rows
    at one time, (t − t₀)/(t₁ − t₀) = 0/0, a NaN input, which our FMUs refuse (fmi-sim then
    ends with "Error: Error"; `test_fmi_sim.py` pins it)."""
    assert sc.input_file is not None
    text = sc.input_file.read_text().rstrip("\n").split("\n")
    last = text[-1].split(",", 1)[1]
    text.append(f"{float(sc.input_rows[-1, 0]) + 0.5 * sc.step!r},{last}")
    path.write_text("\n".join(text) + "\n")
    return path


def run_fmi_sim(sc: Scenario, fmu: Path, interface: str, workdir: Path):
    """`fmi-sim` on `fmu` (`interface`: co-simulation or model-exchange, forward Euler at the
    scenario's step) with the scenario's inputs, an output every step: (the process, its
    result by column, or None when it failed)."""
    import subprocess

    from conftest import require

    require(FMI_SIM, "scripts/setup builds it (cargo install fmi-sim into target/tools)")
    out = workdir / f"{fmu.stem}_{interface}.csv"
    args = [str(FMI_SIM), "--model", str(fmu), "-o", str(out)]
    if sc.inputs and interface == "model-exchange":
        args += ["-i", str(write_event_inputs(sc, workdir / f"{fmu.stem}_in.csv"))]
    elif sc.inputs:
        args += ["-i", str(write_held_inputs(sc, workdir / f"{fmu.stem}_in.csv"))]
    args += [interface, "-s", repr(sc.start), "-f", repr(sc.stop),
             "--output-interval", repr(sc.step), "-n", "0"]
    if interface == "model-exchange":
        args += ["--step", repr(sc.step)]
    run = subprocess.run(args, capture_output=True, text=True, timeout=300)
    if run.returncode != 0 or not out.exists():
        return run, None
    return run, read_fmi_sim_csv(out)


def read_fmi_sim_csv(path: Path) -> dict[str, np.ndarray]:
    """fmi-sim's result CSV (arrow's writer: a header of names, quoted where they need it;
    Booleans as true/false): one array per column."""
    import csv

    with path.open(newline="") as f:
        rows = list(csv.reader(f))
    names = rows[0]

    def number(text: str) -> float:
        return {"true": 1.0, "false": 0.0}.get(text, None) if text in ("true", "false") \
            else float(text)

    table = np.array([[number(v) for v in row] for row in rows[1:] if row], dtype=float)
    return {n: table[:, i] for i, n in enumerate(names)}


def fmpy_model_exchange(sc: Scenario) -> dict[str, np.ndarray]:
    """fmpy's Model Exchange run of the scenario with its forward Euler at the scenario's step
    (an output every step)."""
    from fmpy import simulate_fmu

    signals = None
    if sc.inputs:
        signals = np.array([tuple(r) for r in sc.input_rows],
                           dtype=[("time", np.float64)] + [(n, np.float64) for n in sc.inputs])
    result = simulate_fmu(str(sc.fmu), fmi_type="ModelExchange", solver="Euler",
                          start_time=sc.start, stop_time=sc.stop, step_size=sc.step,
                          output_interval=sc.step, input=signals)
    return {n: np.asarray(result[n], dtype=float) for n in result.dtype.names}


def fmpy_slave_stepped(sc: Scenario, points: np.ndarray,
                       steps: np.ndarray) -> dict[str, np.ndarray]:
    """The scenario stepped by hand through fmpy's FMU2Slave from the communication points
    `points` (t_0 … t_(n−1)) by the steps `steps`, inputs and outputs as fmpy's
    `simulate_fmu` handles them: the Real outputs."""
    from fmpy import extract
    from fmpy.fmi2 import FMU2Slave

    md = read_model_description(str(sc.fmu))
    vrs = {v.name: v.valueReference for v in md.modelVariables}
    slave = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(sc.fmu)),
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="m")
    slave.instantiate()
    slave.setupExperiment(startTime=float(points[0]))
    slave.enterInitializationMode()

    def set_inputs(t):
        for name, value in sc.inputs_at(t).items():
            slave.setReal([vrs[name]], [float(value)])

    reals = [n for n, kind in sc.outputs.items() if kind == "Real"]
    set_inputs(sc.grid[0])
    slave.exitInitializationMode()
    rows = [slave.getReal([vrs[n] for n in reals])]
    for k in range(sc.steps):
        set_inputs(sc.grid[k])
        slave.doStep(float(points[k]), float(steps[k]))
        rows.append(slave.getReal([vrs[n] for n in reals]))
    slave.terminate()
    slave.freeInstance()
    table = np.array(rows)
    result = {n: table[:, i] for i, n in enumerate(reals)}
    result["time"] = sc.grid
    return result


def tool_steps(sc: Scenario, tool: str) -> tuple[np.ndarray, np.ndarray]:
    """The communication points t_0 … t_(n−1) and steps a tool passes to fmi2DoStep."""
    n = sc.steps
    if tool == "fmpy":
        return sc.grid[:-1], np.diff(sc.grid)
    if tool == "libcosim":
        ns = libcosim_nanoseconds(sc.step)
        points = np.array([sc.start + k * ns / NANOSECONDS for k in range(n + 1)])
        return points[:-1], np.diff(points)
    assert tool in ("ecos", "fmi-sim"), tool
    return sc.grid[:-1], np.full(n, sc.step)
