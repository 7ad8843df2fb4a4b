"""Runs every FMU through the C driver on linux64, win64 (wine) and aarch64-linux (qemu) and
compares each platform's outputs with linux64's and with the committed reference results.

Each `.fmu` of `--fmus` is used as packaged by scripts/build-fmus: it must carry
`binaries/linux64/<id>.so`, `binaries/win64/<id>.dll` and `binaries/aarch64-linux/<id>.so`
(a missing one fails). It is unpacked into a folder whose path has a space and a non-ASCII
letter (so the resource URI needs percent-encoding), and run with its cross-check scenario
(`fmus/<Id>/crosscheck/<Model>_in.csv` and `_ref.opt`, through scenario.py) by the driver built
for each platform from the one source driver.c. The driver loads the binary from the unpacked
FMU and gets the `file:` URI of its `resources` folder (`file:///Z:/…` under wine). Also
checked on every platform: instantiating a variant FMU whose `resources/variant.cfg` is
missing fails with a message naming the file.

Pass criteria per FMU: linux64 reproduces `<Model>_ref.csv` (the fmpy reference) within 1e-12
relative; each other platform is bit-identical to linux64, or differs by at most 1e-12 relative
with the cause explained in EXPLAINED below. Exit status 1 on any failure.

    python3 tests/platforms/run_driver.py [--fmus build/fmus] [--work target/platforms]
        [--only NAME ...] [--platforms linux64 win64 aarch64-linux]
"""

from __future__ import annotations

import argparse
import csv
import math
import os
import shutil
import struct
import subprocess
import sys
import time
import urllib.parse
import zipfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
sys.path.insert(0, str(HERE))
import scenario  # noqa: E402

PLATFORMS = {
    # platform: (C compiler, driver file name, binary extension, Rust target triple,
    #            FMI 3.0 binaries folder)
    "linux64": ("gcc", "driver", "so", "x86_64-unknown-linux-gnu", "x86_64-linux"),
    "win64": ("x86_64-w64-mingw32-gcc", "driver.exe", "dll", "x86_64-pc-windows-gnu",
              "x86_64-windows"),
    "aarch64-linux": ("aarch64-linux-gnu-gcc", "driver-aarch64", "so", "aarch64-unknown-linux-gnu",
                      "aarch64-linux"),
}
# Differences between platforms that are understood, per (FMU stem, platform): a text saying
# why. Only these may differ, and by at most MAX_RELATIVE.
# The transcendental functions (f64::sin, cos, exp, ln, acos, …) of Rust's std call the
# platform's C math library: glibc's on linux64 and aarch64-linux, MinGW-w64's on win64. None is
# correctly rounded in every case, and glibc's differ between the two architectures too (on
# x86-64 it picks FMA/AVX2 variants at load time, on AArch64 its own build), so a result may
# differ in the last bits.
LIBM = ("{what} come from the platform's C math library ({libm}), which may differ from "
        "linux64's glibc in the last bit; {where}")
RLS = dict(what="acos, ln and exp turning the identified poles into wn, zeta, overshoot and "
           "settling_time", where="those four outputs only (theta is bit-identical; the "
           "readout is not fed back): ≤ 1 ulp-level, max 6e-16 relative")
EXPLAINED: dict[tuple[str, str], str] = {
    ("GantryCrane", "win64"): LIBM.format(
        what="sin and cos of the load angle in the equations of motion", libm="MinGW-w64's",
        where="seen as 2 ulp in one value of the output omega (not in the cross-check scenario)"),
    ("RecursiveLeastSquares", "win64"): LIBM.format(libm="MinGW-w64's", **RLS),
    ("RecursiveLeastSquares", "aarch64-linux"): LIBM.format(libm="glibc's AArch64 build", **RLS),
}
MAX_RELATIVE = 1e-12


def log(text: str) -> None:
    print(text, flush=True)


def driver_name(platform: str, fmi3: bool = False) -> str:
    """The file name of the driver for `platform`: driver.c's FMI 3.0 build is driver3…."""
    name = PLATFORMS[platform][1]
    return name.replace("driver", "driver3", 1) if fmi3 else name


def build_driver(bin_dir: Path, platforms: list[str], fmi3: bool = False) -> None:
    """driver.c for each of `platforms`, for FMI 2.0 or (fmi3, -DFMI3) FMI 3.0."""
    bin_dir.mkdir(parents=True, exist_ok=True)
    flags = ["-O2", "-std=c99", "-Wall", "-Wextra", "-Werror", *(["-DFMI3"] if fmi3 else [])]
    for platform in platforms:
        libs = ["-lshell32"] if platform == "win64" else ["-ldl"]
        subprocess.run([PLATFORMS[platform][0], *flags, "-o",
                        str(bin_dir / driver_name(platform, fmi3)), str(HERE / "driver.c"), *libs],
                       check=True)


def prepare(args: argparse.Namespace, work: Path, bin_dir: Path,
            fmi3: bool = False) -> tuple[dict[str, str], list[Path]]:
    """Builds the driver (FMI 2.0: for every platform; fmi3: for --platforms) and, with win64,
    the ProcessPrng shim (wine 8 lacks it) and the wine prefix; returns the wine environment
    and the FMUs of --fmus (--only), logging when there is none."""
    built = args.platforms if fmi3 else list(PLATFORMS)
    build_driver(bin_dir, built, fmi3)
    if "win64" in built:
        subprocess.run(["x86_64-w64-mingw32-gcc", "-O2", "-Wall", "-Werror", "-shared", "-o",
                        str(bin_dir / "bcryptprimitives.dll"), str(HERE / "process_prng_shim.c"),
                        "-ladvapi32"], check=True)
    env = wine_env(work)
    if "win64" in args.platforms:
        run([wine(), "wineboot", "-i"], env)  # creates the prefix once
    fmus = sorted(p for p in args.fmus.glob("*.fmu") if not args.only or p.stem in args.only)
    if not fmus:
        log(f"no FMUs in {args.fmus} (run scripts/build-fmus)")
    return env, fmus


def wine_env(work: Path) -> dict[str, str]:
    env = dict(os.environ)
    env.update(WINEPREFIX=str(work / "wineprefix"), WINEDEBUG="-all",
               WINEDLLOVERRIDES="bcryptprimitives=n,b;mscoree,mshtml=")
    return env


def command(platform: str, bin_dir: Path, args: list[str]) -> list[str]:
    exe = str(bin_dir / driver_name(platform))
    if platform == "win64":
        return [wine(), exe, *args]
    if platform == "aarch64-linux":
        return ["qemu-aarch64", "-L", "/usr/aarch64-linux-gnu", exe, *args]
    return [exe, *args]


def wine() -> str:
    return shutil.which("wine64") or shutil.which("wine") or "/usr/lib/wine/wine64"


def native_path(platform: str, path: Path) -> str:
    """A path as the driver on `platform` sees it (wine maps Z: to /)."""
    return "Z:" + str(path).replace("/", "\\") if platform == "win64" else str(path)


def resource_uri(platform: str, folder: Path) -> str:
    path = ("/Z:" + str(folder)) if platform == "win64" else str(folder)
    return "file://" + urllib.parse.quote(path, safe="/:")


def packaged_platforms(fmu: Path, platforms: list[str]) -> tuple[str, bytes, list[str]]:
    """The model identifier, the model description and the platforms of `platforms` whose
    binary `fmu` lacks."""
    with zipfile.ZipFile(fmu) as z:
        xml = z.read("modelDescription.xml")
        identifier = scenario.parse(xml).identifier
        names = set(z.namelist())
    missing = [p for p in platforms
               if f"binaries/{p}/{identifier}.{PLATFORMS[p][2]}" not in names]
    return identifier, xml, missing


def read_reference(path: Path) -> tuple[list[str], list[list[float]]]:
    """A `<Model>_ref.csv`: header (time, then the outputs) and rows of numbers."""
    rows = list(csv.reader(path.read_text().splitlines()))
    return rows[0], [[float(x) for x in r] for r in rows[1:] if r]


def read_outputs(path: Path) -> tuple[list[str], list[list[float]]]:
    lines = path.read_text().splitlines()
    header = next(csv.reader([lines[0]]))
    rows = []
    for line in lines[1:]:
        if line.startswith("#"):
            continue
        cells = []
        for cell in line.split(","):
            if len(cell) == 16:
                cells.append(struct.unpack("<d", bytes.fromhex(cell)[::-1])[0])
            else:
                cells.append(float(int(cell)))
        rows.append(cells)
    return header, rows


def in_driver_order(header: list[str], reference) -> list[list[float]] | None:
    """The reference rows with their columns in the order of the driver's `header`, or None
    when the two name other columns. The driver writes the outputs in value-reference order,
    fmpy's reference the Boolean ones after the Real ones: they are matched by name."""
    names = [h.strip('"') for h in header]
    if sorted(names) != sorted(reference[0]) or names[:1] != reference[0][:1]:
        return None
    order = [reference[0].index(name) for name in names]
    return [[row[i] for i in order] for row in reference[1]]


def compare(ref: list[list[float]], other: list[list[float]]) -> dict:
    """max |Δ|, max relative difference and the number of differing values."""
    if len(ref) != len(other) or any(len(a) != len(b) for a, b in zip(ref, other)):
        return {"shape": False, "max_abs": math.inf, "max_rel": math.inf, "differing": -1,
                "values": 0}
    max_abs = max_rel = 0.0
    differing = values = 0
    for a_row, b_row in zip(ref, other):
        for a, b in zip(a_row, b_row):
            values += 1
            if struct.pack("<d", a) == struct.pack("<d", b):
                continue
            differing += 1
            if math.isnan(a) or math.isnan(b):
                max_abs = max_rel = math.inf
                continue
            d = abs(a - b)
            max_abs = max(max_abs, d)
            max_rel = max(max_rel, d / max(abs(a), abs(b)))
    return {"shape": True, "max_abs": max_abs, "max_rel": max_rel, "differing": differing,
            "values": values}


def run(cmd: list[str], env: dict[str, str] | None, timeout: float = 600) -> subprocess.CompletedProcess:
    return subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=timeout,
                          errors="replace")


def timed(cmd: list[str], platform: str,
          env: dict[str, str]) -> tuple[subprocess.CompletedProcess, str]:
    """Runs a driver command (with the wine environment `env` on win64): its result and the
    seconds it took, as the tables print them."""
    t0 = time.monotonic()
    result = run(cmd, env if platform == "win64" else None)
    return result, f"{time.monotonic() - t0:.1f}"


def arguments(doc: str, fmus: Path) -> argparse.ArgumentParser:
    """The options of both runners: the FMUs (default `fmus`), the work folder, the FMUs and
    platforms to run."""
    ap = argparse.ArgumentParser(description=doc, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--fmus", type=Path, default=fmus)
    ap.add_argument("--work", type=Path, default=REPO / "target" / "platforms")
    ap.add_argument("--only", nargs="*", default=[])
    ap.add_argument("--platforms", nargs="*", default=list(PLATFORMS))
    return ap


def start(args: argparse.Namespace, unpacked_name: str, out_name: str, fmi3: bool = False,
          fresh_out: bool = False) -> tuple[Path, Path, Path, dict[str, str], list[Path]]:
    """The work folder, its `bin` folder for the drivers, a fresh folder `unpacked_name` to
    unpack the FMUs into, the output folder `out_name` (emptied when `fresh_out`), and the
    environment and FMUs of `prepare`."""
    work = args.work.resolve()
    bin_dir = work / "bin"
    unpacked = work / unpacked_name
    out = work / out_name
    for d in (unpacked, out) if fresh_out else (unpacked,):
        shutil.rmtree(d, ignore_errors=True)
    for d in (unpacked, out):
        d.mkdir(parents=True, exist_ok=True)
    env, fmus = prepare(args, work, bin_dir, fmi3=fmi3)
    return work, bin_dir, unpacked, env, fmus


def versus_linux64(stem: str, platform: str, linux64: list[list[float]],
                   rows: list[list[float]], failures: list[str]) -> tuple[str, dict]:
    """A platform's outputs against linux64's: the verdict (`identical`, `explained` within
    MAX_RELATIVE with its cause in EXPLAINED, or `DIFFERS`, which is a failure) and the
    comparison."""
    c = compare(linux64, rows)
    ok = c["shape"] and (c["differing"] == 0 or (
        c["max_rel"] <= MAX_RELATIVE and (stem, platform) in EXPLAINED))
    verdict = "identical" if c["differing"] == 0 else ("explained" if ok else "DIFFERS")
    if not ok:
        failures.append(f"{stem} {platform}: {c}")
    return verdict, c


def report(header: list[str], table: list[tuple], failures: list[str], summary: str) -> int:
    """Logs the table, the failures and the summary; the exit status (1 on any failure)."""
    log("| " + " | ".join(header) + " |")
    log("|" + "---|" * len(header))
    for row in table:
        log("| " + " | ".join(row) + " |")
    for f in failures:
        log("FAIL " + f)
    log(f"{summary}: {'all passed' if not failures else f'{len(failures)} failures'}")
    return 1 if failures else 0


def main() -> int:
    ap = arguments(__doc__, REPO / "build" / "fmus")
    ap.add_argument("--panic-fmu", action="append", default=[],
                    help="PLATFORM=BINARY of the PanicTest FMU (panic_fmu/), checked on each")
    ap.add_argument("--panic-md", type=Path, help="PanicTest's modelDescription.xml")
    args = ap.parse_args()

    work, bin_dir, unpacked, env, fmus = start(args, "unpacked FMUs é", "out", fresh_out=True)
    if not fmus:
        return 1
    failures: list[str] = []
    table = []
    for fmu in fmus:
        stem = fmu.stem
        identifier, xml, missing = packaged_platforms(fmu, args.platforms)
        bundled = (REPO / "modelDescription" / f"{stem}.xml").exists()
        if missing and not bundled:
            log(f"skipped {fmu.name}: not a bundled FMU, and no binary for {', '.join(missing)}")
            continue
        if missing:
            failures.append(f"{stem}: no binary for {', '.join(missing)} in {fmu} (build it "
                            "with scripts/build-fmus, not --host-only)")
            continue
        folder = unpacked / stem
        with zipfile.ZipFile(fmu) as z:
            z.extractall(folder)
        (folder / "resources").mkdir(exist_ok=True)
        model = scenario.parse(xml)
        # A bundled model (one with a committed model description) has its cross-check files
        # in fmus/<identifier>/crosscheck/<stem>_*; another FMU (a variant packaged by a user)
        # gets generated inputs and no reference.
        own, reference = None, None
        if bundled:
            own = REPO / "fmus" / identifier / "crosscheck"
            if not (own / f"{stem}_ref.csv").exists():
                failures.append(f"{stem}: no cross-check reference {own / (stem + '_ref.csv')}")
                continue
            reference = read_reference(own / f"{stem}_ref.csv")
        scen = scenario.write(model, stem, work / "scenarios" / stem, own)
        outputs = {}
        for platform in args.platforms:
            ext = PLATFORMS[platform][2]
            binary = folder / "binaries" / platform / f"{identifier}.{ext}"
            out = work / "out" / f"{stem}.{platform}.csv"
            cmd = command(platform, bin_dir, [
                native_path(platform, binary), resource_uri(platform, folder / "resources"),
                native_path(platform, scen), native_path(platform, out)])
            t0 = time.monotonic()
            result = run(cmd, env if platform == "win64" else None)
            elapsed = time.monotonic() - t0
            if result.returncode != 0:
                failures.append(f"{stem} {platform}: driver exit {result.returncode}: "
                                f"{result.stderr.strip()[-2000:]}")
                table.append((stem, platform, "FAIL", "", "", "", "", f"{elapsed:.1f}"))
                continue
            outputs[platform] = read_outputs(out)
            header, rows = outputs[platform]
            ref_note = "no reference"
            if reference is not None:
                ref_rows = in_driver_order(header, reference)
                if ref_rows is None:
                    failures.append(f"{stem} {platform}: output columns differ from _ref.csv")
                    continue
                vs_ref = compare(ref_rows, rows)
                ref_note = (f"{vs_ref['differing']}/{vs_ref['values']}, max rel "
                            f"{vs_ref['max_rel']:.3g}")
                if platform == "linux64" and not (vs_ref["shape"]
                                                  and vs_ref["max_rel"] <= MAX_RELATIVE):
                    failures.append(f"{stem} linux64 does not reproduce _ref.csv: {vs_ref}")
            if platform == "linux64":
                n = len(outputs[platform][1])
                table.append((stem, platform, "reference", f"{n} rows", "", "", ref_note,
                              f"{elapsed:.1f}"))
                continue
            if "linux64" not in outputs:
                continue
            if outputs[platform][0] != outputs["linux64"][0]:
                failures.append(f"{stem} {platform}: different output columns")
                continue
            verdict, c = versus_linux64(stem, platform, outputs["linux64"][1],
                                        outputs[platform][1], failures)
            table.append((stem, platform, verdict, f"{c['differing']}/{c['values']}",
                          f"{c['max_abs']:.3g}", f"{c['max_rel']:.3g}", ref_note,
                          f"{elapsed:.1f}"))
        missing_config_check(stem, identifier, folder, scen, bin_dir, env, args.platforms,
                             failures)

    if "win64" in args.platforms:
        broken_export_check(fmus[0].stem, unpacked / fmus[0].stem, work, bin_dir, env, failures)
    if args.panic_fmu:
        panic_checks(args.panic_fmu, args.panic_md, work, bin_dir, env, failures)

    (work / "report.md").write_text("\n".join("| " + " | ".join(r) + " |" for r in table) + "\n")
    return report(["FMU", "platform", "vs linux64", "differing values", "max abs", "max rel",
                   "vs _ref.csv (differing, max rel)", "driver s"], table, failures,
                  f"{len(fmus)} FMUs on {len(args.platforms)} platforms")


def missing_config_check(stem: str, identifier: str, folder: Path, scen: Path, bin_dir: Path,
                         env: dict[str, str], platforms: list[str], failures: list[str]) -> None:
    """For a variant FMU (one with resources/variant.cfg): without that file, instantiation
    must fail and the message must name the file."""
    config = folder / "resources" / "variant.cfg"
    if not config.exists():
        return
    empty = folder.parent / f"{stem} without config" / "resources"
    empty.mkdir(parents=True, exist_ok=True)
    for platform in platforms:
        ext = PLATFORMS[platform][2]
        binary = folder / "binaries" / platform / f"{identifier}.{ext}"
        out = folder.parent / f"{stem}.{platform}.noconfig.csv"
        result = run(command(platform, bin_dir, [
            native_path(platform, binary), resource_uri(platform, empty),
            native_path(platform, scen), native_path(platform, out)]),
            env if platform == "win64" else None)
        if result.returncode != 3 or "variant.cfg" not in result.stderr:
            failures.append(f"{stem} {platform}: missing variant.cfg not reported "
                            f"(exit {result.returncode}): {result.stderr.strip()[-500:]}")


def broken_export_check(stem: str, folder: Path, work: Path, bin_dir: Path,
                        env: dict[str, str], failures: list[str]) -> None:
    """Negative control: a win64 DLL whose `fmi2DoStep` export is misnamed must fail the
    driver (exit 2, naming the symbol), so a broken win64 build cannot pass."""
    dll = next((folder / "binaries" / "win64").glob("*.dll"), None)
    if dll is None:
        failures.append(f"{stem}: no win64 DLL for the negative control")
        return
    data = dll.read_bytes()
    if b"fmi2DoStep\0" not in data:
        failures.append(f"{dll}: no fmi2DoStep export name to break")
        return
    broken = work / "broken" / dll.name
    broken.parent.mkdir(exist_ok=True)
    broken.write_bytes(data.replace(b"fmi2DoStep\0", b"fmi2DoStap\0"))
    scen = work / "scenarios" / stem / f"{stem}.scenario"
    result = run(command("win64", bin_dir, [
        native_path("win64", broken), resource_uri("win64", folder / "resources"),
        native_path("win64", scen), native_path("win64", work / "broken" / "out.csv")]), env)
    ok = result.returncode == 2 and "does not export fmi2DoStep" in result.stderr
    log(f"negative control, {stem} win64 DLL with a misnamed fmi2DoStep export: driver exit "
        f"{result.returncode}: {'detected' if ok else 'NOT DETECTED'}")
    if not ok:
        failures.append(f"broken win64 export not detected: exit {result.returncode}: "
                        f"{result.stderr.strip()[-500:]}")


def panic_checks(binaries: list[str], md: Path | None, work: Path, bin_dir: Path,
                 env: dict[str, str], failures: list[str]) -> None:
    """PanicTest through the C ABI: a model error must come back as fmi2Error (driver exit 4)
    and a panic as fmi2Fatal (exit 5), each with its message, on every platform."""
    if md is None:
        failures.append("--panic-fmu needs --panic-md")
        return
    model = scenario.parse(md.read_bytes())
    folder = work / "scenarios" / "PanicTest"
    folder.mkdir(parents=True, exist_ok=True)
    cases = {"panic": (13.0, 5, "unlucky input 13"), "error": (-200.0, 4, "below -100")}
    for case, (bad, code, message) in cases.items():
        (folder / f"{case}_in.csv").write_text(f"time,u\n0,1\n0.5,{bad}\n")
        scen = folder / f"{case}.scenario"
        scen.write_text(f"guid {model.guid}\nidentifier PanicTest\nexperiment 0 1 0.1\n"
                        f"inputs {case}_in.csv\ninput r 0 u\noutput r 1 y\n")
        for item in binaries:
            platform, _, binary = item.partition("=")
            out = folder / f"{case}.{platform}.csv"
            result = run(command(platform, bin_dir, [
                native_path(platform, Path(binary).resolve()),
                resource_uri(platform, folder), native_path(platform, scen),
                native_path(platform, out)]), env if platform == "win64" else None)
            rows = len(out.read_text().splitlines()) - 1 if out.exists() else 0
            ok = result.returncode == code and message in result.stderr and rows == 6
            log(f"PanicTest {case} on {platform}: driver exit {result.returncode}, "
                f"{rows} rows before the failing step: {'ok' if ok else 'FAIL'}")
            if not ok:
                failures.append(f"PanicTest {case} {platform}: exit {result.returncode} "
                                f"(want {code}), {rows} rows: {result.stderr.strip()[-800:]}")


if __name__ == "__main__":
    sys.exit(main())
