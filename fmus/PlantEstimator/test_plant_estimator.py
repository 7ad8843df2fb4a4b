"""`spurio package-estimator` and the PlantEstimator FMU through fmpy, FMI 2.0 and 3.0: the
GantryCrane's estimator (M, l, f_c free, as the README's `spurio identify` example) validates,
and run by fmpy on a closed-loop record with missing samples gives `spurio identify --method
ukf`'s trajectory (x̂, θ̂ and their standard deviations) to rounding; FMU states are taken and
restored, serialized states too (into the same instance and a fresh one); a plant's refusal
reaches the estimator's error with the plant's own message; a bad name, a missing variance or a plant without Model Exchange is refused before
anything is written."""

import subprocess
import zipfile

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.fmi2 import FMU2Slave
from fmpy import extract
from fmpy.validation import validate_fmu

from fmpy.fmi1 import FMICallException

from conftest import FMU_DIR, REPO, LogSink, fmu_path, make_callbacks

SPURIO = REPO / "target" / "release" / "spurio"
STOP = 20.0
STEP = 0.05
NOISE = "x=0.01,theta=0.01"
FREE = ["M", "l", "f_c"]
STATES = ["x", "theta", "v", "omega"]
# Samples whose measurements are missing (both channels), as empty cells for `spurio
# identify` and `y.<name>.valid` = false for the FMU.
MISSING = range(100, 112)
# The identify example of the README.
PLANT_ARGS = ["--free", ",".join(FREE), "--start", "M=1.01262,l=0.41208,f_c=0.536",
              "--set", "x0=0.2"]
# `spurio identify`'s column of each FMU output.
COLUMNS = {**{f"x_hat.{s}": f"x{i}" for i, s in enumerate(STATES)},
           **{f"theta_hat.{p}": p for p in FREE},
           **{f"sd.{s}": f"sd(x{i})" for i, s in enumerate(STATES)},
           **{f"sd.{p}": f"sd({p})" for p in FREE}}


def spurio(*args, check=True):
    assert SPURIO.is_file(), f"{SPURIO} is missing: build it with scripts/build-fmus"
    result = subprocess.run([str(SPURIO), *map(str, args)], capture_output=True, text=True,
                            cwd=REPO)
    if check:
        assert result.returncode == 0, result.stderr
    return result


def package(out, *extra, plant=None, check=True):
    plant = plant or fmu_path("GantryCrane")
    return spurio("package-estimator", plant, "--input", "U", "--output", "x", "--output",
                  "theta", *extra, "--name", "GantryCraneEstimator", "--out", out,
                  check=check)


@pytest.fixture(scope="module")
def crane(tmp_path_factory):
    """The record (20 s of the closed-loop identification run, samples 100–111 missing), the
    packaged estimator and `spurio identify --method ukf`'s trajectory on the record."""
    tmp = tmp_path_factory.mktemp("plant_estimator")
    system = (REPO / "examples/crane_identification/closed_loop.toml").read_text()
    system = system.replace("../../build/fmus", str(FMU_DIR)).replace(
        "stop_time = 40.0", f"stop_time = {STOP}")
    (tmp / "closed_loop.toml").write_text(system)
    spurio("run", tmp / "closed_loop.toml", "--out", tmp / "full.csv")
    lines = (tmp / "full.csv").read_text().splitlines()
    header = lines[0].replace('"', "").split(",")
    ix, iy1, iy2 = (header.index(c) for c in ("ctrl.u[1]", "sensor.y[1]", "sensor.y[2]"))
    rows = [line.split(",") for line in lines[1:]]
    with open(tmp / "record.csv", "w") as f:
        f.write("time,U,x,theta\n")
        for k, r in enumerate(rows):
            y = ("", "") if k in MISSING else (r[iy1], r[iy2])
            f.write(f"{r[0]},{r[ix]},{y[0]},{y[1]}\n")
    package(tmp / "out", "--noise", NOISE, *PLANT_ARGS)
    spurio("identify", fmu_path("GantryCrane"), "--data", tmp / "record.csv", "--input", "U",
           "--output", "x", "--output", "theta", *PLANT_ARGS, "--method", "ukf",
           "--noise", "0.01,0.01", "--out", tmp / "id")
    trajectory = np.genfromtxt(tmp / "id/trajectory.csv", delimiter=",", names=True,
                               deletechars="")
    data = np.genfromtxt(tmp / "record.csv", delimiter=",", names=True)
    signals = np.zeros(len(data), dtype=[("time", float), ("u.U", float), ("y.x", float),
                                         ("y.theta", float), ("y.x.valid", bool),
                                         ("y.theta.valid", bool)])
    signals["time"], signals["u.U"] = data["time"], data["U"]
    for name in ("x", "theta"):
        present = ~np.isnan(data[name])
        signals[f"y.{name}"] = np.where(present, data[name], 0.0)
        signals[f"y.{name}.valid"] = present
    return {"fmu": tmp / "out/GantryCraneEstimator.fmu",
            "fmu3": tmp / "out/fmi3/GantryCraneEstimator.fmu",
            "trajectory": trajectory, "signals": signals, "tmp": tmp}


def test_the_estimator_validates_and_carries_the_plant_and_its_names(crane):
    for path in (crane["fmu"], crane["fmu3"]):
        assert validate_fmu(str(path)) == [], path
    md = read_model_description(str(crane["fmu"]))
    units = {v.name: v.unit for v in md.modelVariables}
    assert md.modelName == "GantryCraneEstimator"
    assert md.coSimulation.modelIdentifier == "PlantEstimator"
    assert units["u.U"] == "N" and units["x_hat.x"] == "m" and units["theta_hat.M"] == "kg"
    assert units["innovation.theta"] == "rad"
    starts = {v.name: v.start for v in md.modelVariables}
    assert float(starts["theta0.l"]) == 0.41208 and float(starts["set.x0"]) == 0.2
    assert float(starts["noise.x"]) == 0.01
    with zipfile.ZipFile(crane["fmu"]) as z:
        names = z.namelist()
        page = z.read("documentation/index.html").decode()
    assert "resources/plant/modelDescription.xml" in names
    assert "resources/plant/binaries/linux64/GantryCrane.so" in names
    assert "theta_hat.f_c" in page and "GantryCrane" in page


@pytest.mark.parametrize("version", ["fmu", "fmu3"])
def test_fmpy_gives_spurio_identify_s_trajectory_to_rounding(crane, version):
    result = simulate_fmu(str(crane[version]), start_time=0.0, stop_time=STOP,
                          step_size=STEP, output_interval=STEP, input=crane["signals"],
                          output=list(COLUMNS) + ["innovation.x", "weight.x"])
    trajectory = crane["trajectory"]
    # Sample k (t_k) is processed by the step from t_k and shown at t_{k+1}.
    n = len(trajectory) - 1
    assert np.allclose(result["time"][1:n + 1], trajectory["time"][1:], rtol=0, atol=1e-9)
    worst = 0.0
    for output, column in COLUMNS.items():
        fmu, identify = result[output][1:n + 1], trajectory[column][:n]
        relative = np.abs(fmu - identify) / np.maximum(np.abs(identify), 1e-12)
        worst = max(worst, relative.max())
    print(f"{version}: max relative difference to spurio identify: {worst:.3g}")
    assert worst <= 1e-9
    # The missing samples: no innovation, weight 0; elsewhere weights in (0, 1].
    shown = [k + 1 for k in MISSING]
    assert np.all(result["innovation.x"][shown] == 0) and np.all(result["weight.x"][shown] == 0)
    present = [k + 1 for k in range(n) if k not in MISSING]
    assert np.all(result["weight.x"][present] > 0) and np.all(result["weight.x"][present] <= 1)
    # θ̂ moved from the starts (M 1.01262, l 0.41208) towards the truth (0.84385, 0.3434).
    assert result["theta_hat.M"][-1] < 0.95 and result["theta_hat.l"][-1] < 0.39


def test_an_fmu_state_taken_and_restored_continues_identically(crane):
    md = read_model_description(str(crane["fmu"]))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    unzipped = extract(str(crane["fmu"]))
    slave = FMU2Slave(guid=md.guid, unzipDirectory=unzipped,
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="est")
    slave.instantiate()
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    slave.exitInitializationMode()
    signals = crane["signals"]
    outputs = [vr[name] for name in COLUMNS]

    def step(k):
        slave.setReal([vr["u.U"], vr["y.x"], vr["y.theta"]],
                      [signals["u.U"][k], signals["y.x"][k], signals["y.theta"][k]])
        slave.setBoolean([vr["y.x.valid"], vr["y.theta.valid"]],
                         [bool(signals["y.x.valid"][k]), bool(signals["y.theta.valid"][k])])
        slave.doStep(currentCommunicationPoint=k * STEP, communicationStepSize=STEP)
        return slave.getReal(outputs)

    for k in range(40):
        step(k)
    state = slave.getFMUstate()
    serialized = slave.serializeFMUstate(state)
    first = [step(k) for k in range(40, 60)]
    slave.setFMUstate(state)
    again = [step(k) for k in range(40, 60)]
    assert first == again
    slave.freeFMUstate(state)
    # The serialized state, into this instance and into a fresh one never initialised.
    restored = slave.deSerializeFMUstate(serialized)
    slave.setFMUstate(restored)
    assert [step(k) for k in range(40, 60)] == first
    slave.freeFMUstate(restored)
    slave.terminate()
    slave.freeInstance()
    slave = FMU2Slave(guid=md.guid, unzipDirectory=unzipped,
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="fresh")
    slave.instantiate()
    restored = slave.deSerializeFMUstate(serialized)
    slave.setFMUstate(restored)
    assert [step(k) for k in range(40, 60)] == first
    slave.freeFMUstate(restored)
    slave.freeInstance()


def test_the_plant_s_own_message_reaches_the_estimator_s_error(crane):
    """θ₀ M = −1: GantryCrane refuses it (its fmi2Error and the message it logs); the
    estimator's fmi2Error quotes what the plant said."""
    md = read_model_description(str(crane["fmu"]))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    slave = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(crane["fmu"])),
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="est")
    sink = LogSink()
    callbacks = make_callbacks(sink)
    slave.instantiate(callbacks=callbacks)
    slave.setupExperiment(startTime=0.0)
    slave.setReal([vr["theta0.M"]], [-1.0])
    slave.enterInitializationMode()
    with pytest.raises(FMICallException) as e:
        slave.exitInitializationMode()
    assert e.value.status == 3
    errors = sink.texts(3)
    assert any("resources/plant" in t and "the FMU logged" in t
               and "`M` = -1 is below its minimum 0" in t for t in errors), errors
    slave.freeInstance()


@pytest.mark.parametrize("args, words", [
    (["--free", "M,Q", "--noise", NOISE], ["`Q`", "not a variable"]),
    (["--free", "M", "--noise", NOISE, "--set", "v=1"], ["`v`", "not a parameter"]),
    (["--free", "M", "--noise", "x=0.01"], ["no variance for `theta`"]),
    (["--free", "M", "--noise", "x=0.01,theta=0"], ["theta=0", "> 0"]),
    (["--free", "M", "--noise", "x=0.01,theta=0.01,z=1"], ["--noise z", "not among"]),
    (["--free", "M", "--noise", NOISE, "--start", "l=0.3"], ["--start l", "not among"]),
])
def test_bad_names_are_refused_before_anything_is_written(tmp_path, args, words):
    result = package(tmp_path / "out", *args, check=False)
    assert result.returncode != 0
    assert all(w in result.stderr for w in words), result.stderr
    assert not (tmp_path / "out").exists()


def test_a_missing_output_and_a_plant_without_model_exchange_are_refused(tmp_path):
    result = spurio("package-estimator", fmu_path("GantryCrane"), "--free", "M", "--input",
                    "U", "--output", "nope", "--noise", "nope=1", "--name", "E", "--out",
                    tmp_path / "out", check=False)
    assert result.returncode != 0 and "`nope`" in result.stderr, result.stderr
    result = package(tmp_path / "out", "--free", "M", "--noise", NOISE,
                     plant=fmu_path("SignalSource"), check=False)
    assert result.returncode != 0 and "Model Exchange" in result.stderr, result.stderr
    assert not (tmp_path / "out").exists()


def test_only_the_platforms_the_plant_has_are_packaged_and_a_dropped_one_is_said(tmp_path):
    # The plant with a win64 binary beside its linux64 one (bytes only: the packager copies).
    plant = tmp_path / "GantryCrane.fmu"
    with zipfile.ZipFile(fmu_path("GantryCrane")) as src, zipfile.ZipFile(plant, "w") as dst:
        for item in src.namelist():
            if not item.startswith(("binaries/win64/", "binaries/aarch64-linux/")):
                dst.writestr(item, src.read(item))
        dst.writestr("binaries/win64/GantryCrane.dll", b"MZ plant")
    libs = {}
    for platform, lib in (("win64", "PlantEstimator.dll"), ("aarch64-linux", "libPlantEstimator.so")):
        libs[platform] = tmp_path / platform
        libs[platform].mkdir()
        (libs[platform] / lib).write_bytes(b"estimator " + platform.encode())
    result = package(tmp_path / "out", "--free", "M", "--noise", NOISE, plant=plant,
                     *[a for p in libs for a in ("--platform-dir", f"{p}={libs[p]}")])
    assert "no aarch64-linux binary" in result.stderr and "win64" not in result.stderr
    with zipfile.ZipFile(tmp_path / "out/GantryCraneEstimator.fmu") as z:
        names = z.namelist()
        assert z.read("binaries/win64/PlantEstimator.dll") == b"estimator win64"
    assert "resources/plant/binaries/win64/GantryCrane.dll" in names
    assert not any(n.startswith("binaries/aarch64-linux/") for n in names)
    with zipfile.ZipFile(tmp_path / "out/fmi3/GantryCraneEstimator.fmu") as z:
        assert "binaries/x86_64-windows/PlantEstimator.dll" in z.namelist()
