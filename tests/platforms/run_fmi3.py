"""Runs every FMI 3.0 FMU (build/fmus/fmi3/) through the C driver built for FMI 3.0 (driver.c
x86_64-linux, x86_64-windows (wine) and aarch64-linux (qemu), with the model's cross-check
scenario, arrays set and read whole (`nValues`).

Pass criteria per FMU: the driver finds all 75 fmi3 functions; x86_64-linux reproduces
`<Model>_ref.csv` (the fmpy reference) within 1e-12 relative; on every platform the FMI 3.0
outputs are bit-identical to the FMI 2.0 driver's on the same platform (`<work>/out/<stem>.
<platform>.csv`, written by run_driver.py when it ran before); each other platform is
bit-identical to x86_64-linux or within 1e-12 with the cause in run_driver.EXPLAINED. A
variant FMU without its resources/variant.cfg must fail instantiation naming the file. The
resource path holds a non-ASCII letter (passed in UTF-8, as FMI 3.0 strings are).

    python3 tests/platforms/run_fmi3.py [--fmus build/fmus/fmi3] [--work target/platforms]
        [--only NAME ...] [--platforms linux64 win64 aarch64-linux]
"""

from __future__ import annotations

import itertools
import shutil
import sys
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
sys.path.insert(0, str(HERE))
import run_driver  # noqa: E402
from run_driver import (  # noqa: E402
    MAX_RELATIVE, PLATFORMS, compare, driver_name, log, read_outputs, read_reference)

TYPES = {"Float64": "r", "Int32": "i", "Boolean": "b"}


def elements(var: ET.Element) -> list[str]:
    """The FMI 2.0 names of a variable's elements, row-major (the name of a scalar)."""
    dims = [int(d.get("start", "1")) for d in var.findall("Dimension")]
    if not dims:
        return [var.get("name", "")]
    return [f"{var.get('name')}[{','.join(str(i + 1) for i in index)}]"
            for index in itertools.product(*(range(d) for d in dims))]


def write_scenario(xml: bytes, stem: str, own: Path, folder: Path) -> tuple[Path, str]:
    """The driver3 scenario of an FMI 3.0 model description with the model's own cross-check
    files; returns it and the model identifier."""
    root = ET.fromstring(xml)
    identifier = root.find("CoSimulation").get("modelIdentifier", "")
    folder.mkdir(parents=True, exist_ok=True)
    for suffix in ("_ref.opt", "_in.csv"):
        if (own / f"{stem}{suffix}").exists():
            shutil.copy(own / f"{stem}{suffix}", folder / f"{stem}{suffix}")
    lines = [f"token {root.get('instantiationToken')}", f"identifier {identifier}",
             f"opt {stem}_ref.opt"]
    if (folder / f"{stem}_in.csv").exists():
        lines.append(f"inputs {stem}_in.csv")
    starts, inputs, outputs = [], [], []
    for var in root.find("ModelVariables"):
        kind = TYPES.get(var.tag)
        if kind is None or var.get("causality") == "independent":
            continue
        vr, names = var.get("valueReference"), elements(var)
        causality = var.get("causality")
        if causality == "parameter" and var.get("start") is not None:
            values = var.get("start").split()
            values = [{"true": "1.0", "false": "0.0"}.get(v, v) for v in values]
            starts += [f"start {kind} {vr} {float(v)!r}" for v in values]
        elif causality == "input":
            inputs += [f"input {kind} {vr} {n}" for n in names]
        elif causality == "output":
            outputs += [f"output {kind} {vr} {n}" for n in names]
    path = folder / f"{stem}.scenario3"
    path.write_text("\n".join(lines + starts + inputs + outputs) + "\n")
    return path, identifier


def resource_path(platform: str, folder: Path) -> str:
    """The FMI 3.0 resourcePath (a native path ending in a separator)."""
    return run_driver.native_path(platform, folder) + ("\\" if platform == "win64" else "/")


def command(platform: str, bin_dir: Path, args: list[str]) -> list[str]:
    exe = str(bin_dir / driver_name(platform, fmi3=True))
    if platform == "win64":
        return [run_driver.wine(), exe, *args]
    if platform == "aarch64-linux":
        return ["qemu-aarch64", "-L", "/usr/aarch64-linux-gnu", exe, *args]
    return [exe, *args]


def missing_config_check(stem: str, identifier: str, folder: Path, scen: Path, bin_dir: Path,
                         env: dict[str, str], platforms: list[str], failures: list[str]) -> None:
    """A variant FMU given a resource folder without its variant.cfg must fail
    fmi3InstantiateCoSimulation with a message naming the file."""
    empty = folder.parent / f"{stem} without config" / "resources"
    empty.mkdir(parents=True, exist_ok=True)
    for platform in platforms:
        _, _, ext, _, tuple_ = PLATFORMS[platform]
        binary = folder / "binaries" / tuple_ / f"{identifier}.{ext}"
        out = folder.parent / f"{stem}.{platform}.noconfig.csv"
        result = run_driver.run(command(platform, bin_dir, [
            run_driver.native_path(platform, binary), resource_path(platform, empty),
            run_driver.native_path(platform, scen), run_driver.native_path(platform, out)]),
            env if platform == "win64" else None)
        if result.returncode != 3 or "variant.cfg" not in result.stderr:
            failures.append(f"{stem} {platform}: missing variant.cfg not reported "
                            f"(exit {result.returncode}): {result.stderr.strip()[-500:]}")


def main() -> int:
    args = run_driver.arguments(__doc__, REPO / "build" / "fmus" / "fmi3").parse_args()

    work, bin_dir, unpacked, env, fmus = run_driver.start(args, "unpacked FMI 3.0 FMUs é", "out3",
                                                          fmi3=True)
    if not fmus:
        return 1
    skipped = [f for f in fmus
               if not (REPO / "modelDescription" / "fmi3" / f"{f.stem}.xml").exists()]
    for fmu in skipped:
        log(f"skipped {fmu.name}: not a bundled FMU")
    failures: list[str] = []
    table = []
    for fmu in (f for f in fmus if f not in skipped):
        stem = fmu.stem
        folder = unpacked / stem
        with zipfile.ZipFile(fmu) as z:
            z.extractall(folder)
            xml = z.read("modelDescription.xml")
        (folder / "resources").mkdir(exist_ok=True)
        root = ET.fromstring(xml)
        identifier = root.find("CoSimulation").get("modelIdentifier", "")
        own = REPO / "fmus" / identifier / "crosscheck"
        scen, identifier = write_scenario(xml, stem, own, work / "scenarios3" / stem)
        reference = read_reference(own / f"{stem}_ref.csv")
        outputs = {}
        for platform in args.platforms:
            _, _, ext, _, tuple_ = PLATFORMS[platform]
            binary = folder / "binaries" / tuple_ / f"{identifier}.{ext}"
            if not binary.exists():
                failures.append(f"{stem}: no binary for {tuple_} in {fmu} (build it with "
                                "scripts/build-fmus, not --host-only)")
                continue
            out = work / "out3" / f"{stem}.{platform}.csv"
            cmd = command(platform, bin_dir, [
                run_driver.native_path(platform, binary),
                resource_path(platform, folder / "resources"),
                run_driver.native_path(platform, scen), run_driver.native_path(platform, out)])
            result, elapsed = run_driver.timed(cmd, platform, env)
            if result.returncode != 0:
                failures.append(f"{stem} {platform}: driver3 exit {result.returncode}: "
                                f"{result.stderr.strip()[-2000:]}")
                table.append((stem, platform, "FAIL", "", "", elapsed))
                continue
            header, rows = outputs[platform] = read_outputs(out)
            ref_rows = run_driver.in_driver_order(header, reference)
            if ref_rows is None:
                failures.append(f"{stem} {platform}: output columns differ from _ref.csv")
                continue
            twin = work / "out" / f"{stem}.{platform}.csv"
            vs_fmi2 = "FMI 2.0 not run"
            if twin.exists():
                c2 = compare(read_outputs(twin)[1], rows)
                vs_fmi2 = "identical" if c2["differing"] == 0 and c2["shape"] else "DIFFERS"
                if vs_fmi2 != "identical":
                    failures.append(f"{stem} {platform}: FMI 3.0 differs from FMI 2.0: {c2}")
            if platform == "linux64":
                vs_ref = compare(ref_rows, rows)
                if not (vs_ref["shape"] and vs_ref["max_rel"] <= MAX_RELATIVE):
                    failures.append(f"{stem} linux64 does not reproduce _ref.csv: {vs_ref}")
                table.append((stem, platform, "reference", vs_fmi2,
                              f"vs _ref.csv max rel {vs_ref['max_rel']:.3g}", elapsed))
                continue
            if "linux64" not in outputs:
                continue
            verdict, c = run_driver.versus_linux64(stem, platform, outputs["linux64"][1], rows,
                                                   failures)
            table.append((stem, platform, verdict, vs_fmi2,
                          f"{c['differing']}/{c['values']} differ, max rel {c['max_rel']:.3g}",
                          elapsed))
        if (folder / "resources" / "variant.cfg").exists():
            missing_config_check(stem, identifier, folder, scen, bin_dir, env, args.platforms,
                                 failures)

    return run_driver.report(
        ["FMI 3.0 FMU", "platform", "vs x86_64-linux", "vs FMI 2.0", "values", "driver s"],
        table, failures, f"{len(fmus)} FMI 3.0 FMUs on {len(args.platforms)} platforms")


if __name__ == "__main__":
    sys.exit(main())
