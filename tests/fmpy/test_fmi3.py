"""The FMI 3.0 FMUs (build/fmus/fmi3/<Model>.fmu, the same binaries as the FMI 2.0 ones):
fmpy validates and simulates every one, every one gives bit for bit the outputs of its FMI 2.0
twin on the model's cross-check scenario, and the runtime conformance checks through fmpy's
FMU3Slave (call order, unknown value reference, NaN, FMU state replay, interleaved instances,
arrays with nValues) hold."""

import sys

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave
from fmpy.validation import validate_fmu

from conftest import FMU_DIR, REPO, element_names

sys.path.insert(0, str(REPO / "scripts"))
import crosscheck  # noqa: E402

FMI3_DIR = FMU_DIR / "fmi3"
# The bundled variants: one committed FMI 3.0 model description each.
STEMS = [p.stem for p in sorted((REPO / "modelDescription" / "fmi3").glob("*.xml"))]


def fmi3_path(stem):
    path = FMI3_DIR / f"{stem}.fmu"
    assert path.is_file(), f"{path} is missing: build the FMUs with scripts/build-fmus"
    return str(path)


class Messages:
    """An fmi3LogMessageCallback that keeps what it is given."""

    def __init__(self):
        self.items = []

    def __call__(self, environment, status, category, message):
        self.items.append((status, category.decode(), message.decode()))

    def errors(self):
        return [m for s, _, m in self.items if s >= 3]


def slave3(stem, name="fmi3", messages=None):
    path = fmi3_path(stem)
    md = read_model_description(path)
    slave = FMU3Slave(guid=md.guid, unzipDirectory=extract(path),
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
    slave.instantiate(logMessage=messages)
    return slave, md


@pytest.mark.parametrize("stem", STEMS)
def test_fmpy_validates_and_simulates_every_fmi3_fmu(stem):
    path = fmi3_path(stem)
    assert validate_fmu(path) == []
    md = read_model_description(path)
    assert md.fmiVersion == "3.0" and md.coSimulation is not None
    assert md.guid == read_model_description(str(FMU_DIR / f"{stem}.fmu")).guid
    result = simulate_fmu(path, stop_time=float(md.defaultExperiment.stepSize) * 20)
    assert result["time"][-1] == pytest.approx(float(md.defaultExperiment.stepSize) * 20)
    outputs = [v for v in md.modelVariables if v.causality == "output"]
    assert set(result.dtype.names) == {"time"} | {v.name for v in outputs}
    for v in outputs:
        assert result[v.name].shape[1:] == tuple(v.shape or ())
        assert np.all(np.isfinite(result[v.name].astype(float)))


def drive(stem, version, inputs_table=None, experiment=None):
    """The model's cross-check scenario (fmus/<Id>/crosscheck/) stepped by hand, the same way
    for both versions: inputs (interpolated at each communication point) set before every
    step, every output element read after it. Returns {element name: values}.
    `inputs_table` ({"time" and element names: values}) and `experiment` ((start, stop, step))
    replace the scenario's when given (the reference results an FMU carries)."""
    path = str(FMU_DIR / f"{stem}.fmu") if version == 2 else fmi3_path(stem)
    md = read_model_description(path)
    folder = crosscheck.folder_of(stem, md.coSimulation.modelIdentifier)
    if experiment is None:
        opt = crosscheck.read_opt(folder / f"{stem}_ref.opt")
        experiment = opt["StartTime"], opt["StopTime"], opt["StepSize"]
    t0, t1, h = experiment
    table = {} if inputs_table is None else inputs_table
    in_csv = folder / f"{stem}_in.csv"
    if inputs_table is None and in_csv.exists():
        header, rows = crosscheck.read_table(in_csv)
        columns = np.array(rows).T
        table = {name: columns[k] for k, name in enumerate(header)}
    unzip = extract(path)
    variables = md.modelVariables
    inputs = [v for v in variables if v.causality == "input"]
    outputs = [v for v in variables if v.causality == "output"]
    if version == 2:
        s = FMU2Slave(guid=md.guid, unzipDirectory=unzip,
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="two")
        s.instantiate()
        s.setupExperiment(startTime=t0)
        s.enterInitializationMode()
    else:
        s = FMU3Slave(guid=md.guid, unzipDirectory=unzip,
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="three")
        s.instantiate()
        s.enterInitializationMode(startTime=t0)

    def set_inputs(t):
        for v in inputs:
            values = [float(np.interp(t, table["time"], table[n])) for n in element_names(v)]
            if v.type == "Boolean":
                s.setBoolean([v.valueReference], [x != 0 for x in values])
            elif version == 2:
                s.setReal([v.valueReference], values)
            else:
                s.setFloat64([v.valueReference], values)

    def read(into):
        for v in outputs:
            names = element_names(v)
            if version == 2:
                get = s.getBoolean if v.type == "Boolean" else (
                    s.getInteger if v.type == "Integer" else s.getReal)
                values = get([v.valueReference])
            else:
                get = {"Boolean": s.getBoolean, "Int32": s.getInt32}.get(v.type, s.getFloat64)
                values = get([v.valueReference], nValues=len(names))
            for n, x in zip(names, values):
                into.setdefault(n, []).append(float(x))

    set_inputs(t0)
    s.exitInitializationMode()
    result = {}
    read(result)
    n = int(round((t1 - t0) / h))
    for k in range(n):
        t = t0 + k * h
        set_inputs(t)
        s.doStep(currentCommunicationPoint=t, communicationStepSize=h)
        read(result)
    s.terminate()
    s.freeInstance()
    return result


@pytest.mark.parametrize("stem", STEMS)
def test_fmi3_outputs_equal_fmi2_bit_for_bit(stem):
    two, three = drive(stem, 2), drive(stem, 3)
    assert sorted(two) == sorted(three)
    for name in two:
        assert np.array_equal(np.array(two[name]), np.array(three[name])), name
    # The scenario moves something: the comparison is not of constants.
    assert any(np.ptp(v) > 0 for v in two.values()), stem


def test_call_order_unknown_references_and_nan_are_rejected_with_a_message():
    messages = Messages()
    s, md = slave3("GantryCrane", messages=messages)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    with pytest.raises(FMICallException):
        s.doStep(currentCommunicationPoint=0.0, communicationStepSize=0.01)
    assert "fmi3DoStep: illegal call sequence: not allowed in state Instantiated" in \
        messages.errors()[-1]
    with pytest.raises(FMICallException):
        s.enterStepMode()
    assert "has no event mode" in messages.errors()[-1]
    s.enterInitializationMode(startTime=0.0, stopTime=1.0)
    s.exitInitializationMode()
    with pytest.raises(FMICallException):
        s.getFloat64([4242])
    assert messages.errors()[-1].startswith("fmi3GetFloat64: unknown value reference 4242")
    with pytest.raises(FMICallException):
        s.setFloat64([vr["U"]], [float("nan")])
    assert "`U`" in messages.errors()[-1] and "NaN" in messages.errors()[-1]
    with pytest.raises(FMICallException):
        s.setFloat64([vr["x"]], [1.0])
    assert "an output: the FMU computes it" in messages.errors()[-1]
    with pytest.raises(FMICallException):
        s.getInt32([vr["x"]])
    assert "is of type Float64, not Int32" in messages.errors()[-1]
    # Nothing was lost: the instance steps on.
    s.setFloat64([vr["U"]], [1.0])
    _, terminate, early, last = s.doStep(currentCommunicationPoint=0.0, communicationStepSize=0.5)
    assert (terminate, early, last) == (False, False, 0.5)
    with pytest.raises(FMICallException):
        s.doStep(currentCommunicationPoint=0.5, communicationStepSize=1.0)
    assert "would pass stopTime" in messages.errors()[-1]
    assert s.getFloat64([0]) == [0.5]
    s.terminate()
    s.freeInstance()


def test_arrays_are_read_and_set_whole_with_n_values():
    messages = Messages()
    s, md = slave3("DualKalmanFilter", messages=messages)
    var = {v.name: v for v in md.modelVariables}
    two = read_model_description(str(FMU_DIR / "DualKalmanFilter.fmu"))
    start2 = {v.name: float(v.start) for v in two.modelVariables
              if v.type == "Real" and v.start is not None}
    a = var["A"]
    assert a.shape == (4, 4)
    s.enterInitializationMode(startTime=0.0)
    # The array's start list is the FMI 2.0 scalars' start values, row-major.
    assert s.getFloat64([a.valueReference], nValues=16) == [start2[n] for n in element_names(a)]
    # A set as one array of 16 values (row-major): read back element by element.
    new = [start2[n] + 0.5 * k for k, n in enumerate(element_names(a))]
    s.setFloat64([a.valueReference], new)
    assert s.getFloat64([a.valueReference], nValues=16) == new
    with pytest.raises(FMICallException):
        s.getFloat64([a.valueReference], nValues=15)
    assert "nValues = 15, but the 1 value references name 16 values" in messages.errors()[-1]
    with pytest.raises(FMICallException):
        s.setFloat64([a.valueReference], new[:4])
    # Two arrays and a scalar in one call.
    x_hat, y = var["x_hat"], var["y"]
    got = s.getFloat64([0, x_hat.valueReference, y.valueReference], nValues=1 + 4 + 2)
    assert got[0] == 0.0 and len(got) == 7
    s.exitInitializationMode()
    s.freeInstance()


def test_fmu_state_replay_and_serialization_give_the_same_future():
    s, md = slave3("KalmanFilter")
    vr = {v.name: v.valueReference for v in md.modelVariables}
    s.enterInitializationMode(startTime=0.0)
    s.exitInitializationMode()
    h = 0.001
    ys = np.sin(np.arange(40) * 0.3)
    for k in range(20):
        s.setFloat64([vr["y"]], [ys[k]])
        s.doStep(k * h, h)
    state = s.getFMUState()
    serialized = s.serializeFMUState(state)

    def future(slave):
        out = []
        for k in range(20, 40):
            slave.setFloat64([vr["y"]], [ys[k]])
            slave.doStep(k * h, h)
            out.append(slave.getFloat64([vr["x_hat"], vr["innovation"]], nValues=2))
        return out

    first = future(s)
    s.setFMUState(state)
    assert future(s) == first
    other, _ = slave3("KalmanFilter", name="other")
    copy = other.deserializeFMUState(serialized)
    other.setFMUState(copy)
    assert future(other) == first
    s.freeFMUState(state)
    other.freeFMUState(copy)
    s.freeInstance()
    other.freeInstance()


def test_interleaved_instances_equal_a_lone_one():
    def run(slaves, u):
        for s, _ in slaves:
            s.enterInitializationMode(startTime=0.0)
            s.exitInitializationMode()
        vr = {v.name: v.valueReference for v in slaves[0][1].modelVariables}
        out = [[] for _ in slaves]
        for k in range(200):
            for i, (s, _) in enumerate(slaves):
                s.setFloat64([vr["U"]], [u[i](k)])
                s.doStep(k * 0.01, 0.01)
                out[i].append(s.getFloat64([vr["x"], vr["theta"]]))
        for s, _ in slaves:
            s.freeInstance()
        return out

    push, pull = (lambda k: 5.0), (lambda k: -3.0 if k < 100 else 2.0)
    lone = run([slave3("GantryCrane", name="lone")], [push])[0]
    both = run([slave3("GantryCrane", name="a"), slave3("GantryCrane", name="b")], [push, pull])
    assert both[0] == lone
    assert both[1] != lone and abs(both[1][-1][0] - lone[-1][0]) > 0.01


FMI3_TUPLE = {"linux64": "x86_64-linux", "win64": "x86_64-windows",
              "aarch64-linux": "aarch64-linux"}


@pytest.mark.parametrize("stem", STEMS)
def test_the_fmi3_archive_carries_the_fmi2_binaries_under_platform_tuples(stem):
    """Same binaries (one library exports fmi2* and fmi3*), every platform of the build,
    under the FMI 3.0 tuples; the same page and variant configuration."""
    import zipfile

    with zipfile.ZipFile(FMU_DIR / f"{stem}.fmu") as two, zipfile.ZipFile(fmi3_path(stem)) as three:
        names2, names3 = set(two.namelist()), set(three.namelist())
        binaries2 = sorted(n for n in names2 if n.startswith("binaries/"))
        assert binaries2
        expected = {"binaries/" + FMI3_TUPLE[n.split("/")[1]] + "/" + n.split("/")[2]
                    for n in binaries2}
        assert {n for n in names3 if n.startswith("binaries/")} == expected
        for n in binaries2:
            folder, file = n.split("/")[1:]
            assert three.read(f"binaries/{FMI3_TUPLE[folder]}/{file}") == two.read(n), n
        for n in names2 - {"modelDescription.xml"} - set(binaries2):
            assert three.read(n) == two.read(n), n
        assert "documentation/index.html" in names3


def test_package_variant_writes_an_fmi3_variant_with_arrays_of_its_dimensions(tmp_path):
    import subprocess

    spurio = REPO / "target" / "release" / "spurio"
    assert spurio.is_file(), "build with scripts/build-fmus first"
    subprocess.run(
        [str(spurio), "package-variant", "KalmanFilter", "--set", "n=3", "--set", "m=1",
         "--set", "p=2", "--name", "Kf312", "--lib-dir", str(REPO / "target" / "release"),
         "--out", str(tmp_path)],
        check=True, capture_output=True,
    )
    path = str(tmp_path / "fmi3" / "Kf312.fmu")
    assert validate_fmu(path) == []
    md = read_model_description(path)
    shapes = {v.name: v.shape for v in md.modelVariables}
    assert (shapes["A"], shapes["B"], shapes["C"], shapes["x_hat"], shapes["y"]) == (
        (3, 3), (3, 1), (2, 3), (3,), (2,))
    assert md.guid == read_model_description(str(tmp_path / "Kf312.fmu")).guid
    result = simulate_fmu(path, stop_time=0.01)
    assert result["x_hat"].shape[1:] == (3,)
