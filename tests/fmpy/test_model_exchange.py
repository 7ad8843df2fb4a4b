"""Model Exchange, for every FMU whose committed model description declares <ModelExchange>:
fmpy validates the FMI 2.0 and FMI 3.0 FMU, CVode (relative tolerance 1e-8) integrating the
Model Exchange interface agrees with the Co-Simulation interface of the same FMU on each of the
FMU's scenarios (and with the FMI 3.0 Model Exchange run), the event times are where the FMU's
scenario says, and the analytic directional derivatives equal central finite differences of
fmi2GetDerivatives at random states and inputs (relative 1e-6).

A plant plugs in with `fmus/<Id>/me_scenarios.py`, which defines

    SCENARIOS = [
        dict(
            fmu="GantryCrane",             # the FMU (file stem in build/fmus/)
            name="free_swing",             # names the test
            stop_time=5.0,
            output_interval=0.01,          # also the Co-Simulation communication step
            start_values={"theta0": 0.2},  # optional
            inputs=[(0.0, {"U": 0.0}), (1.0, {"U": 0.0}), (1.0, {"U": 5.0})],  # optional rows;
                                           # a repeated time is a step
            outputs=["x", "theta"],        # compared ME vs CS
            rtol=1e-6, atol=1e-6,          # the agreement asked for (np.allclose)
            event_times=[2.345],           # optional: the state events CVode must locate (1e-6 s)
            check=None,                    # optional: check(me_result, cs_result) for more
        ),
    ]

and optionally `random_point(rng, start) -> (states, inputs)` (dicts name -> value) for the
directional-derivative check (default: the initial states and inputs, each moved by up to
half its nominal/magnitude, seeded).
"""

import sys
import zipfile
from ctypes import POINTER, c_double

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi2 import FMU2Model
from fmpy.validation import validate_fmu

from conftest import FMU_DIR, REPO

sys.path.insert(0, str(REPO / "scripts"))
import me_scenarios  # noqa: E402

CVODE_RTOL = 1e-8
# Central differences with a relative step of 1e-6 have a truncation error of ~1e-12 and a
# rounding error of ~1e-10 of the column's scale: 1e-6 is far above both.
DERIVATIVE_RTOL = 1e-6
RANDOM_POINTS = 20


STEMS = me_scenarios.stems(REPO)
SCENARIOS, SAMPLERS = me_scenarios.load(REPO)


def fmu_path(stem, fmi3=False):
    path = FMU_DIR / ("fmi3" if fmi3 else "") / f"{stem}.fmu"
    assert path.is_file(), f"{path} is missing: build the FMUs with scripts/build-fmus"
    return str(path)


def signals(rows):
    """fmpy's input array from scenario rows [(time, {name: value})]."""
    if not rows:
        return None
    names = sorted({n for _, values in rows for n in values})
    dtype = [("time", np.float64)] + [(n, np.float64) for n in names]
    return np.array([(t, *[values[n] for n in names]) for t, values in rows], dtype=dtype)


def fmi3_start_values(start, path):
    """FMI 2.0 structured start values (`A[1,2]`) as the FMI 3.0 arrays they are elements of
    (row-major, the other elements at their start values); scalars as they are."""
    arrays = {v.name: v for v in read_model_description(path).modelVariables if v.shape}
    out = {}
    for name, value in start.items():
        base, _, index = name.partition("[")
        if base not in arrays or not index:
            out[name] = value
            continue
        v = arrays[base]
        values = out.setdefault(base, [v._python_type(e) for e in str(v.start).split()])
        position = [int(i) - 1 for i in index.rstrip("]").split(",")]
        values[int(np.ravel_multi_index(position, v.shape))] = value
    return out


def simulate(s, fmi_type, fmi3=False):
    start = s.get("start_values", {})
    outputs = s["outputs"]
    if fmi3:  # the arrays the structured outputs are elements of
        outputs = list(dict.fromkeys(name.partition("[")[0] for name in outputs))
    options = dict(
        stop_time=s["stop_time"],
        output_interval=s["output_interval"],
        start_values=fmi3_start_values(start, fmu_path(s["fmu"], fmi3)) if fmi3 else start,
        input=signals(s.get("inputs")),
        output=outputs,
        fmi_type=fmi_type,
    )
    if fmi_type == "ModelExchange":
        options.update(solver="CVode", relative_tolerance=CVODE_RTOL)
    return simulate_fmu(fmu_path(s["fmu"], fmi3), **options)


def event_times(result):
    """The times fmpy's Model Exchange loop recorded twice: before and after an event."""
    t = result["time"]
    return t[1:][np.diff(t) == 0]


def column(result, name):
    """`name` of `result`; an FMI 2.0 structured name `x[2]` in an FMI 3.0 result is element 2
    of the array `x` (row-major)."""
    if name in result.dtype.names:
        return result[name]
    base, _, index = name.partition("[")
    values = result[base].reshape(len(result), -1)
    return values[:, int(index.rstrip("]").split(",")[0]) - 1]


def on_grid(result, name, times):
    """`name` of `result` at `times` (the last row at a time: after an event)."""
    t = result["time"]
    values_at = column(result, name)
    index = np.searchsorted(t, times, side="right") - 1
    exact = np.isclose(t[np.clip(index, 0, len(t) - 1)], times, rtol=0, atol=1e-12)
    values = np.interp(times, t, values_at)
    values[exact] = values_at[index[exact]]
    return values


def test_every_model_exchange_fmu_has_scenarios():
    covered = {s["fmu"] for s in SCENARIOS}
    missing = [stem for stem in STEMS if stem not in covered]
    assert not missing, f"no fmus/<Id>/me_scenarios.py scenario for {missing}"


@pytest.mark.parametrize("stem", STEMS)
@pytest.mark.parametrize("fmi3", [False, True], ids=["fmi2", "fmi3"])
def test_validate_fmu_finds_no_problem(stem, fmi3):
    path = fmu_path(stem, fmi3)
    assert validate_fmu(path) == []
    md = read_model_description(path)
    assert md.modelExchange is not None and md.coSimulation is not None
    assert len(md.derivatives) >= 1
    if fmi3:
        # fmpy does not read FMI 3.0's providesDirectionalDerivatives: the XML says it
        with zipfile.ZipFile(path) as z:
            xml = z.read("modelDescription.xml").decode()
        assert xml.count('providesDirectionalDerivatives="true"') == 2
    else:
        assert md.modelExchange.providesDirectionalDerivative
        assert md.coSimulation.providesDirectionalDerivative


@pytest.mark.parametrize("s", SCENARIOS, ids=lambda s: f"{s['fmu']}-{s['name']}")
def test_model_exchange_agrees_with_co_simulation(s):
    me = simulate(s, "ModelExchange")
    cs = simulate(s, "CoSimulation")
    me3 = simulate(s, "ModelExchange", fmi3=True)
    for name in s["outputs"]:
        me_values = on_grid(me, name, cs["time"])
        print(f"{s['fmu']} {s['name']} {name}: max |ME - CS| = "
              f"{np.max(np.abs(me_values - cs[name])):.3g}")
        assert np.allclose(me_values, cs[name], rtol=s["rtol"], atol=s["atol"]), (
            f"{name}: ME vs CS differ by up to {np.max(np.abs(me_values - cs[name])):.3g}"
        )
        # the FMI 3.0 interface is the same code: the same figures within the tolerance
        me3_values = on_grid(me3, name, cs["time"])
        assert np.allclose(me3_values, me_values, rtol=100 * CVODE_RTOL, atol=s["atol"])
    if "event_times" in s:
        found = event_times(me)
        expected = np.asarray(s["event_times"], dtype=float)
        assert len(found) == len(expected), f"events at {found}, expected {expected}"
        assert np.allclose(found, expected, rtol=0, atol=1e-6), f"{found} vs {expected}"
    if s.get("check"):
        s["check"](me, cs)


class Model:
    """An FMI 2.0 Model Exchange instance in Continuous-Time Mode, after initialization."""

    def __init__(self, stem, start_values):
        path = fmu_path(stem)
        self.md = read_model_description(path)
        self.fmu = FMU2Model(
            guid=self.md.guid,
            unzipDirectory=extract(path),
            modelIdentifier=self.md.modelExchange.modelIdentifier,
            instanceName="jacobian",
        )
        self.fmu.instantiate()
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        types = {v.name: v.type for v in self.md.modelVariables}
        for name, value in start_values.items():
            set_value = self.fmu.setBoolean if types[name] == "Boolean" else self.fmu.setReal
            set_value([self.vr[name]], [value])
        self.fmu.setupExperiment(startTime=0.0)
        self.fmu.enterInitializationMode()
        self.fmu.exitInitializationMode()
        while True:
            info = self.fmu.newDiscreteStates()
            if not info[0]:  # newDiscreteStatesNeeded
                break
        self.fmu.enterContinuousTimeMode()
        self.states = [d.variable.derivative.valueReference for d in self.md.derivatives]
        self.derivatives = [d.variable.valueReference for d in self.md.derivatives]
        self.inputs = [
            v.valueReference
            for v in self.md.modelVariables
            if v.causality == "input" and v.type == "Real"
        ]
        self.n = len(self.states)
        self.nominals = self.array(self.fmu.getNominalsOfContinuousStates)

    def array(self, get):
        out = np.zeros(self.n)
        get(out.ctypes.data_as(POINTER(c_double)), self.n)
        return out

    def point(self):
        x = self.array(self.fmu.getContinuousStates)
        u = np.array(self.fmu.getReal(self.inputs)) if self.inputs else np.zeros(0)
        return x, u

    def f(self, x, u):
        x = np.ascontiguousarray(x, dtype=float)
        self.fmu.setContinuousStates(x.ctypes.data_as(POINTER(c_double)), self.n)
        if len(u):
            self.fmu.setReal(self.inputs, list(u))
        return self.array(self.fmu.getDerivatives)

    def jacobian_column(self, known):
        return np.array(
            self.fmu.getDirectionalDerivative(self.derivatives, [known], [1.0])
        )


def random_point(stem, model, rng):
    """The scenario module's random_point, or the initial point moved by up to half of each
    state's nominal and each input's magnitude."""
    x0, u0 = model.point()
    if stem in SAMPLERS:
        states, inputs = SAMPLERS[stem](rng, dict(zip(model.states, x0)))
        by_name = {v.valueReference: v.name for v in model.md.modelVariables}
        x = np.array([states.get(by_name[r], x) for r, x in zip(model.states, x0)])
        u = np.array([inputs.get(by_name[r], u) for r, u in zip(model.inputs, u0)])
        return x, u
    x = x0 + 0.5 * model.nominals * rng.uniform(-1, 1, len(x0))
    u = u0 + 0.5 * np.maximum(np.abs(u0), 1.0) * rng.uniform(-1, 1, len(u0))
    return x, u


def scenario_start(stem):
    for s in SCENARIOS:
        if s["fmu"] == stem:
            return s.get("start_values", {})
    return {}


@pytest.mark.parametrize("stem", STEMS)
def test_directional_derivatives_equal_central_differences(stem):
    model = Model(stem, scenario_start(stem))
    rng = np.random.default_rng(15)
    worst = 0.0
    for _ in range(RANDOM_POINTS):
        x, u = random_point(stem, model, rng)
        model.f(x, u)
        knowns = [(r, i, True) for i, r in enumerate(model.states)] + [
            (r, i, False) for i, r in enumerate(model.inputs)
        ]
        for vr, i, is_state in knowns:
            value = x[i] if is_state else u[i]
            scale = model.nominals[i] if is_state else 1.0
            h = 1e-6 * max(abs(value), scale)
            plus, minus = (x.copy(), u.copy()), (x.copy(), u.copy())
            which = 0 if is_state else 1
            plus[which][i] += h
            minus[which][i] -= h
            fd = (model.f(*plus) - model.f(*minus)) / (2 * h)
            model.f(x, u)
            dd = model.jacobian_column(vr)
            error = np.max(np.abs(dd - fd)) / max(np.max(np.abs(fd)), 1.0)
            worst = max(worst, error)
            assert error < DERIVATIVE_RTOL, (
                f"{stem}: d der / d (vr {vr}) at x = {x}, u = {u}: {dd} vs {fd}"
            )
    print(f"{stem}: worst relative error of the directional derivatives {worst:.2e}")

