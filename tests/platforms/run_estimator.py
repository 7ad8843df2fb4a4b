"""Runs the GantryCrane's estimator FMU (`spurio package-estimator`, the PlantEstimator FMU
carrying the plant in resources/plant) through the C driver on linux64, win64 (wine) and
aarch64-linux (qemu), FMI 2.0 and 3.0, and compares the platforms.

The estimator is packaged as in fmus/PlantEstimator/test_plant_estimator.py (M, l, f_c free,
the README's identify example) from `--fmus`/GantryCrane.fmu, which must carry the three
platforms (scripts/build-fmus), with the PlantEstimator binaries of `--cross`
(target/cross/<triple>/release, built by scripts/build-cross) for win64 and aarch64-linux.
Its input is the closed-loop record of examples/crane_identification/closed_loop.toml (20 s,
every 0.05 s, samples 100–111 missing: `y.<name>.valid` 0), written in the cross-check layout
(`_in.csv`, `_ref.opt`) for the driver, which holds each row's inputs over its step.

Pass criteria: linux64 gives `spurio identify --method ukf`'s trajectory on the same record
(x̂, θ̂ and their standard deviations; sample k is processed by the step from t_k and shown
at t_{k+1}) within 1e-9 relative, as fmpy does in the pytest; win64 and aarch64-linux are
bit-identical to linux64, or within 1e-12 of each output's largest magnitude over the run
with the cause in EXPLAINED;
the FMI 3.0 run is bit-identical to the FMI 2.0 run on each platform. Exit status 1 on any
failure.

    python3 tests/platforms/run_estimator.py [--fmus build/fmus] [--work target/platforms]
        [--cross target/cross] [--platforms linux64 win64 aarch64-linux]
"""

from __future__ import annotations

import csv
import subprocess
import sys
import zipfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
sys.path.insert(0, str(HERE))
import run_driver  # noqa: E402
import run_fmi3  # noqa: E402
import scenario  # noqa: E402
from run_driver import PLATFORMS, compare, read_outputs  # noqa: E402

SPURIO = REPO / "target" / "release" / "spurio"
NAME = "GantryCraneEstimator"
STOP, STEP = 20.0, 0.05
FREE = ["M", "l", "f_c"]
STATES = ["x", "theta", "v", "omega"]
PLANT_ARGS = ["--free", ",".join(FREE), "--start", "M=1.01262,l=0.41208,f_c=0.536",
              "--set", "x0=0.2"]
MISSING = range(100, 112)
# `spurio identify`'s trajectory column of each estimator output.
COLUMNS = {**{f"x_hat.{s}": f"x{i}" for i, s in enumerate(STATES)},
           **{f"theta_hat.{p}": p for p in FREE},
           **{f"sd.{s}": f"sd(x{i})" for i, s in enumerate(STATES)},
           **{f"sd.{p}": f"sd({p})" for p in FREE}}
MAX_VS_IDENTIFY = 1e-9
# Why a platform may differ from linux64 (by at most MAX_RELATIVE of an output's range).
EXPLAINED = {
    "win64": "the plant's sin and cos of the load angle come from MinGW-w64's C math library, "
             "which may differ from glibc's in the last bit (run_driver.EXPLAINED, "
             "GantryCrane win64); the filter carries such a difference on through its "
             "sigma points: measured 3.9e-15 absolute, 4.2e-14 of an output's range",
}


def spurio(*args: object) -> None:
    result = subprocess.run([str(SPURIO), *map(str, args)], capture_output=True, text=True,
                            cwd=REPO)
    if result.returncode != 0:
        raise RuntimeError(f"spurio {' '.join(map(str, args[:2]))} failed: {result.stderr}")


def table_of(path: Path) -> tuple[list[str], list[list[str]]]:
    rows = list(csv.reader(path.read_text().splitlines()))
    return [h.strip('"') for h in rows[0]], [r for r in rows[1:] if r]


def prepare_estimator(fmus: Path, cross: Path | None, folder: Path) -> tuple[Path, Path, Path]:
    """The record `folder/record.csv` (time, U, x, theta; the missing samples empty), the
    cross-check files (`<NAME>_in.csv`, `_ref.opt`) in `folder/own`, the estimator FMUs in
    `folder/fmus` (with the win64 and aarch64-linux binaries of `cross`, unless None) and
    identify's trajectory in `folder/id`; returns the FMI 2.0 FMU, the FMI 3.0 FMU and the
    trajectory. Also what tests/interop/test_plant_estimator_in_tools.py runs on."""
    folder.mkdir(parents=True, exist_ok=True)
    system = (REPO / "examples/crane_identification/closed_loop.toml").read_text()
    system = system.replace("../../build/fmus", str(fmus.resolve())).replace(
        "stop_time = 40.0", f"stop_time = {STOP}")
    (folder / "closed_loop.toml").write_text(system)
    spurio("run", folder / "closed_loop.toml", "--out", folder / "full.csv")
    header, rows = table_of(folder / "full.csv")
    iu, ix, itheta = (header.index(c) for c in ("ctrl.u[1]", "sensor.y[1]", "sensor.y[2]"))
    record = ["time,U,x,theta"]
    driver_in = ["time,u.U,y.x,y.theta,y.x.valid,y.theta.valid"]
    for k, r in enumerate(rows):
        missing = k in MISSING
        record.append(f"{r[0]},{r[iu]},{'' if missing else r[ix]},"
                      f"{'' if missing else r[itheta]}")
        y = ("0", "0", "0") if missing else (r[ix], r[itheta], "1")
        driver_in.append(f"{r[0]},{r[iu]},{y[0]},{y[1]},{y[2]},{y[2]}")
    (folder / "record.csv").write_text("\n".join(record) + "\n")
    own = folder / "own"
    own.mkdir(exist_ok=True)
    (own / f"{NAME}_in.csv").write_text("\n".join(driver_in) + "\n")
    (own / f"{NAME}_ref.opt").write_text(
        f"StartTime, 0.0\nStopTime, {STOP!r}\nStepSize, {STEP!r}\nRelTol, 1e-6\n")
    platform_dirs = []
    for platform in ("win64", "aarch64-linux") if cross else ():
        platform_dirs += ["--platform-dir",
                          f"{platform}={cross.resolve() / PLATFORMS[platform][3] / 'release'}"]
    plant = fmus / "GantryCrane.fmu"
    outputs = ["--input", "U", "--output", "x", "--output", "theta"]
    spurio("package-estimator", plant, *outputs, *PLANT_ARGS, "--noise", "x=0.01,theta=0.01",
           "--name", NAME, "--out", folder / "fmus", *platform_dirs)
    spurio("identify", plant, "--data", folder / "record.csv", *outputs, *PLANT_ARGS,
           "--method", "ukf", "--noise", "0.01,0.01", "--out", folder / "id")
    return (folder / "fmus" / f"{NAME}.fmu", folder / "fmus" / "fmi3" / f"{NAME}.fmu",
            folder / "id" / "trajectory.csv")


def versus_identify(header: list[str], rows: list[list[float]], trajectory: Path) -> float:
    """The largest relative difference of the driver's x̂, θ̂ and standard deviations to
    identify's trajectory (driver row k+1 against trajectory row k)."""
    names, table = table_of(trajectory)
    columns = [h.strip('"') for h in header]
    worst = 0.0
    for k, line in enumerate(table[:len(rows) - 1]):
        for output, column in COLUMNS.items():
            want = float(line[names.index(column)])
            got = rows[k + 1][columns.index(output)]
            worst = max(worst, abs(got - want) / max(abs(want), 1e-12))
    return worst


def versus_linux64(platform: str, linux64: list[list[float]], rows: list[list[float]],
                   failures: list[str]) -> tuple[str, dict, float]:
    """A platform's outputs against linux64's: `identical`, or `explained` when the platform
    is in EXPLAINED and every output is within MAX_RELATIVE of its largest magnitude over
    the run (x̂ and the innovations cross zero, where a relative difference per value says
    nothing), or `DIFFERS` (a failure); the comparison and that largest difference."""
    c = compare(linux64, rows)
    of_range = 0.0
    if c["shape"]:
        for j in range(1, len(linux64[0])):
            scale = max(abs(r[j]) for r in linux64) or 1.0
            of_range = max(of_range, max(abs(a[j] - b[j]) for a, b in zip(linux64, rows))
                           / scale)
    if c["shape"] and c["differing"] == 0:
        return "identical", c, of_range
    if c["shape"] and platform in EXPLAINED and of_range <= run_driver.MAX_RELATIVE:
        return "explained", c, of_range
    failures.append(f"{NAME} {platform}: {c}, {of_range:.3g} of an output's range")
    return "DIFFERS", c, of_range


def main() -> int:
    ap = run_driver.arguments(__doc__, REPO / "build" / "fmus")
    ap.add_argument("--cross", type=Path, default=REPO / "target" / "cross")
    args = ap.parse_args()
    args.only = ["GantryCrane"]
    work = args.work.resolve()
    bin_dir = work / "bin"
    env, plants = run_driver.prepare(args, work, bin_dir)
    run_driver.build_driver(bin_dir, args.platforms, fmi3=True)
    if not plants:
        return 1
    folder = work / "estimator é"
    fmu2, fmu3, trajectory = prepare_estimator(args.fmus, args.cross, folder)
    failures: list[str] = []
    table = []
    outputs: dict[tuple[str, int], tuple[list[str], list[list[float]]]] = {}
    for version, fmu in ((2, fmu2), (3, fmu3)):
        unpacked = folder / f"unpacked FMI {version}"
        with zipfile.ZipFile(fmu) as z:
            z.extractall(unpacked)
            xml = z.read("modelDescription.xml")
        if version == 2:
            scen = scenario.write(scenario.parse(xml), NAME, folder / "scenario", folder / "own")
            identifier = scenario.parse(xml).identifier
        else:
            scen, identifier = run_fmi3.write_scenario(xml, NAME, folder / "own",
                                                       folder / "scenario3")
        for platform in args.platforms:
            _, _, ext, _, fmi3_folder = PLATFORMS[platform]
            binary = (unpacked / "binaries" / (platform if version == 2 else fmi3_folder)
                      / f"{identifier}.{ext}")
            if not binary.exists():
                failures.append(f"{NAME} FMI {version}: no {platform} binary {binary} (the "
                                "plant and the PlantEstimator need it: scripts/build-fmus)")
                continue
            out = folder / f"out.fmi{version}.{platform}.csv"
            resources = unpacked / "resources"
            cmd_args = [run_driver.native_path(platform, binary),
                        run_driver.resource_uri(platform, resources) if version == 2
                        else run_fmi3.resource_path(platform, resources),
                        run_driver.native_path(platform, scen),
                        run_driver.native_path(platform, out)]
            cmd = (run_driver.command if version == 2 else run_fmi3.command)(
                platform, bin_dir, cmd_args)
            result, elapsed = run_driver.timed(cmd, platform, env)
            if result.returncode != 0:
                failures.append(f"{NAME} FMI {version} {platform}: driver exit "
                                f"{result.returncode}: {result.stderr.strip()[-2000:]}")
                table.append((f"FMI {version}", platform, "FAIL", "", "", "", elapsed))
                continue
            header, rows = outputs[(platform, version)] = read_outputs(out)
            twin = ""
            if version == 3 and (platform, 2) in outputs:
                c2 = compare(outputs[(platform, 2)][1], rows)
                twin = "identical" if c2["shape"] and c2["differing"] == 0 else "DIFFERS"
                if twin != "identical":
                    failures.append(f"{NAME} {platform}: FMI 3.0 differs from FMI 2.0: {c2}")
            if platform == "linux64":
                worst = versus_identify(header, rows, trajectory)
                if not worst <= MAX_VS_IDENTIFY:
                    failures.append(f"{NAME} FMI {version} linux64: {worst:.3g} relative to "
                                    f"spurio identify (> {MAX_VS_IDENTIFY:g})")
                table.append((f"FMI {version}", platform, f"vs identify {worst:.3g}", "", "",
                              twin, elapsed))
                continue
            if ("linux64", version) not in outputs:
                continue
            verdict, c, of_range = versus_linux64(platform, outputs[("linux64", version)][1],
                                                  rows, failures)
            table.append((f"FMI {version}", platform, verdict,
                          f"{c['differing']}/{c['values']}",
                          f"{c['max_rel']:.3g} ({of_range:.3g} of range)", twin, elapsed))
    return run_driver.report(["FMI", "platform", "vs linux64", "differing values", "max rel",
                              "vs FMI 2.0", "driver s"], table, failures,
                             f"{NAME} on {len(args.platforms)} platforms")


if __name__ == "__main__":
    sys.exit(main())
