"""Shared helpers for the fmpy tests: where the FMUs are, logging callbacks, slaves."""

import itertools
import os
import pathlib
from ctypes import byref

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (
    FMU2Slave,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
)
from fmpy import calloc, free

REPO = pathlib.Path(__file__).resolve().parent
FMU_DIR = pathlib.Path(os.environ.get("SPURIO_FMU_DIR", REPO / "build" / "fmus"))

_extracted = {}


def element_names(variable):
    """The FMI 2.0 scalar names of a variable's elements (an FMI 3.0 array's, row-major)."""
    if not variable.shape:
        return [variable.name]
    return [f"{variable.name}[{','.join(str(i + 1) for i in index)}]"
            for index in itertools.product(*(range(d) for d in variable.shape))]


def fmu_path(name: str) -> str:
    path = FMU_DIR / f"{name}.fmu"
    assert path.is_file(), f"{path} is missing: build the FMUs with scripts/build-fmus"
    return str(path)


def simulate_packaged(name, stop, h, start, rows=None, inputs=(), **options):
    """fmpy's simulation of the packaged FMU `name` up to `stop` with outputs every `h` and
    the start values `start`; `rows` (time first, then one value a name of `inputs`) are its
    input signals; `options` go to `simulate_fmu` as they are."""
    signals = None
    if inputs:
        dtype = [("time", np.float64)] + [(n, np.float64) for n in inputs]
        signals = np.array(rows, dtype=dtype)
    return simulate_fmu(
        fmu_path(name),
        stop_time=stop,
        output_interval=h,
        start_values=start,
        input=signals,
        **options,
    )


class LogSink:
    """Collects (instance, status, category, message) from an FMU's logger callback."""

    def __init__(self):
        self.messages = []

    def __call__(self, env, instance, status, category, message):
        self.messages.append(
            (instance.decode(), status, category.decode(), message.decode())
        )

    def texts(self, status=None):
        return [m[3] for m in self.messages if status is None or m[1] == status]


# fmpy's native logger proxy keeps ONE process-wide pointer: the logger it wrapped last.
# Every FMU instantiated with fmpy's default callbacks (`simulate_fmu` without a logger) logs
# through that pointer, so each logger wrapped here is kept alive for the whole session:
# a freed one would be called by the next FMU that logs (a segmentation fault).
_WRAPPED_LOGGERS = []


def make_callbacks(sink: LogSink):
    """fmi2CallbackFunctions whose logger formats the variadic message (fmpy's native proxy)
    and hands it to `sink`."""
    from fmpy.logging import addLoggerProxy

    callbacks = fmi2CallbackFunctions()
    logger = fmi2CallbackLoggerTYPE(sink)
    _WRAPPED_LOGGERS.append(logger)
    callbacks.logger = logger
    callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
    callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
    addLoggerProxy(byref(callbacks))
    return callbacks


def open_slave(name, instance_name="instance", logging_on=False, guid=None):
    """An instantiated FMU2Slave of FMU `name`, its value references by name and its log."""
    path = fmu_path(name)
    if path not in _extracted:
        _extracted[path] = (read_model_description(path), extract(path))
    md, unzipdir = _extracted[path]
    slave = FMU2Slave(
        guid=guid or md.guid,
        unzipDirectory=unzipdir,
        modelIdentifier=md.coSimulation.modelIdentifier,
        instanceName=instance_name,
    )
    sink = LogSink()
    callbacks = make_callbacks(sink)
    slave.instantiate(callbacks=callbacks, loggingOn=logging_on)
    slave._spurio_keepalive = callbacks  # the FMU keeps the pointer: keep the object alive
    vr = {v.name: v.valueReference for v in md.modelVariables}
    return slave, vr, sink


def set_values(slave, vr, values):
    """Sets variables by name, each with the setter of its Python type (bool, int, float)."""
    for name, value in values.items():
        if isinstance(value, bool):
            slave.setBoolean([vr[name]], [value])
        elif isinstance(value, int):
            slave.setInteger([vr[name]], [value])
        else:
            slave.setReal([vr[name]], [value])


def assert_set_rejected(slave, vr, sink, name, value, *words):
    """Setting `name` to `value` fails, and a logged error holds all `words` (by default the
    name in backticks)."""
    with pytest.raises(FMICallException):
        set_values(slave, vr, {name: value})
    words = words or (f"`{name}`",)
    assert any(all(w in t for w in words) for t in sink.texts(3)), sink.messages


def init(slave, t0=0.0):
    """Sets up and initialises `slave` with its start values."""
    slave.setupExperiment(startTime=t0)
    slave.enterInitializationMode()
    slave.exitInitializationMode()


def open_initialized_pair(name):
    """Two initialised instances "a" and "b" of FMU `name`, and its value references by name."""
    a, vr, _ = open_slave(name, "a")
    b, _, _ = open_slave(name, "b")
    init(a)
    init(b)
    return a, b, vr


def assert_initialization_fails_naming(slave, sink, name, *words):
    """Initialising `slave` fails with fmi2Error and a logged error naming `name` in
    backticks (the parameter or matrix at fault) and holding all `words`; frees the slave."""
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    with pytest.raises(FMICallException) as e:
        slave.exitInitializationMode()
    assert e.value.status == 3
    words = (f"`{name}`", *words)
    assert any(all(w in t for w in words) for t in sink.texts(3)), sink.messages
    slave.freeInstance()


def expm(a: np.ndarray) -> np.ndarray:
    """Matrix exponential by scaling and squaring of a Taylor series (independent of the
    Rust implementation)."""
    norm = np.linalg.norm(a, 1)
    s = max(0, int(np.ceil(np.log2(norm))) + 1) if norm > 0 else 0
    a = a / 2**s
    result = np.eye(a.shape[0])
    term = np.eye(a.shape[0])
    for k in range(1, 30):
        term = term @ a / k
        result = result + term
    for _ in range(s):
        result = result @ result
    return result


def zoh(a, b, t):
    """Exact discretisation over `t` of ṡ = A s + B u with u held: (e^{At}, ∫₀ᵗ e^{Aτ} dτ B),
    both read from the matrix exponential of the augmented [[A, B], [0, 0]]."""
    n = a.shape[0]
    b = np.reshape(b, (n, -1))
    aug = np.zeros((n + b.shape[1],) * 2)
    aug[:n, :n] = a
    aug[:n, n:] = b
    e = expm(aug * t)
    return e[:n, :n], e[:n, n:]


# Annex A of paper 000, written out again here independently of the Rust code.
CRANE = dict(M=0.84385, m=0.013, l=0.3434, J=1e-5, f_c=0.67, f_p=9.3e-6, g=9.8)


def crane_linear_model(M, m, l, J, f_c, f_p, g):
    """Continuous linearisation ṡ = A s + B U of the crane, s = [x, θ, ẋ, θ̇]
    (paper 000 eqs 4–5): `crane_linear_model(**CRANE)`."""
    a11, a22, ml = M + m, J + m * l * l, m * l
    det = a11 * a22 - ml * ml
    A = np.array(
        [
            [0, 0, 1, 0],
            [0, 0, 0, 1],
            [0, -ml * ml * g / det, -a22 * f_c / det, -ml * f_p / det],
            [0, -a11 * ml * g / det, -ml * f_c / det, -a11 * f_p / det],
        ]
    )
    B = np.array([0, 0, a22 / det, ml / det])
    return A, B


@pytest.fixture
def crane_fmu():
    return fmu_path("GantryCrane")


def me_scenarios_of(test_file):
    """The `me_scenarios.py` next to `test_file` (a plant's Model Exchange scenarios), loaded
    under a name of its own, since every plant folder has one."""
    import importlib.util

    path = pathlib.Path(test_file).with_name("me_scenarios.py")
    spec = importlib.util.spec_from_file_location(f"me_scenarios_{path.parent.name}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
