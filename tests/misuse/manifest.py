#!/usr/bin/env python3
"""Unpacks an FMU for the misuse driver and writes what it needs to know as plain text.

    manifest.py FMU OUTDIR [cs]   ->  OUTDIR/<unpacked FMU>, OUTDIR/manifest.txt

(`cs`: an FMI 3.0 FMU to drive as Co-Simulation; without it, as Model Exchange.)

manifest.txt (one record a line, fields separated by a tab):
    label    <file stem of the FMU>
    id       <modelIdentifier>
    guid     <guid>
    library  <path of binaries/linux64/<id>.so>
    resources <file URI of the resources folder (FMI 3.0: its path, with a trailing /)>
    version  <2 or 3: the FMI version of the model description>
    me       <1 if the FMU offers Model Exchange too, else 0>
    nz       <numberOfEventIndicators>
    state    <vr of a continuous state> <vr of its derivative>   (ModelStructure order)
    var      <vr> <R|I|B|S> <causality> <variability> <min or -> <max or -> <name>
    count    <vr> <number of elements>   (FMI 3.0 arrays only; a scalar has 1)
    interface  cs   (FMI 3.0 driven as Co-Simulation: label fmi3-cs/<stem>), then
    cs_event_mode    <1 if its CoSimulation declares hasEventMode="true", else 0>
    cs_intermediate  <1 if it declares providesIntermediateUpdate="true", else 0>
An FMI 3.0 FMU (build/fmus/fmi3) gives the same records: its Float64/Int32/Boolean/String
variables as R/I/B/S (value reference 0, `time`, among them), the library under
binaries/x86_64-linux, the instantiationToken as guid.
Standard library only (the driver runs on a machine without the project's venv too).
"""
import pathlib
import sys
import xml.etree.ElementTree as ET
import zipfile

TYPES = {"Real": "R", "Integer": "I", "Boolean": "B", "String": "S", "Enumeration": "I"}


TYPES3 = {"Float64": "R", "Int32": "I", "Boolean": "B", "String": "S", "Enumeration": "I"}


def fmi3_lines(fmu: str, root: ET.Element, unpacked: pathlib.Path, co_simulation: bool) -> list:
    """The manifest of an FMI 3.0 model description (to drive as Co-Simulation or not)."""
    cs = root.find("CoSimulation")
    if cs is None:
        raise SystemExit(f"{fmu}: not a Co-Simulation FMU")
    model_id = cs.get("modelIdentifier")
    structure = root.find("ModelStructure")
    prefix = "fmi3-cs" if co_simulation else "fmi3"
    lines = [
        f"label\t{prefix}/{pathlib.Path(fmu).stem}",
        "version\t3",
        f"id\t{model_id}",
        f"guid\t{root.get('instantiationToken')}",
        f"library\t{unpacked / 'binaries' / 'x86_64-linux' / (model_id + '.so')}",
        f"resources\t{unpacked / 'resources'}/",
        f"me\t{int(root.find('ModelExchange') is not None)}",
        f"nz\t{len(structure.findall('EventIndicator'))}",
    ]
    if co_simulation:
        lines += [
            "interface\tcs",
            f"cs_event_mode\t{int(cs.get('hasEventMode') == 'true')}",
            f"cs_intermediate\t{int(cs.get('providesIntermediateUpdate') == 'true')}",
        ]
    variables = [v for v in root.find("ModelVariables") if v.tag in TYPES3]
    by_vr = {v.get("valueReference"): v for v in variables}
    for der in structure.iterfind("ContinuousStateDerivative"):
        state = by_vr[der.get("valueReference")].get("derivative")
        lines.append(f"state\t{state}\t{der.get('valueReference')}")
    for v in variables:
        lines.append(
            "\t".join(
                [
                    "var",
                    v.get("valueReference"),
                    TYPES3[v.tag],
                    v.get("causality", "local"),
                    v.get("variability", "continuous" if v.tag == "Float64" else "discrete"),
                    v.get("min", "-"),
                    v.get("max", "-"),
                    v.get("name"),
                ]
            )
        )
        dimensions = v.findall("Dimension")
        if dimensions:
            n = 1
            for d in dimensions:
                n *= int(d.get("start", "1"))
            lines.append(f"count\t{v.get('valueReference')}\t{n}")
    return lines


def main(fmu: str, out: str, co_simulation: bool = False) -> None:
    out_dir = pathlib.Path(out).resolve()
    unpacked = out_dir / "fmu"
    with zipfile.ZipFile(fmu) as archive:
        archive.extractall(unpacked)
    root = ET.parse(unpacked / "modelDescription.xml").getroot()
    if root.get("fmiVersion", "").startswith("3."):
        (out_dir / "manifest.txt").write_text("\n".join(fmi3_lines(fmu, root, unpacked, co_simulation)) + "\n")
        return
    cs = root.find("CoSimulation")
    if cs is None:
        raise SystemExit(f"{fmu}: not a Co-Simulation FMU")
    model_id = cs.get("modelIdentifier")
    lines = [
        f"label\t{pathlib.Path(fmu).stem}",
        "version\t2",
        f"id\t{model_id}",
        f"guid\t{root.get('guid')}",
        f"library\t{unpacked / 'binaries' / 'linux64' / (model_id + '.so')}",
        f"resources\t{(unpacked / 'resources').as_uri()}",
        f"me\t{int(root.find('ModelExchange') is not None)}",
        f"nz\t{root.get('numberOfEventIndicators', '0')}",
    ]
    scalars = list(root.iter("ScalarVariable"))
    for unknown in root.iterfind("ModelStructure/Derivatives/Unknown"):
        der = scalars[int(unknown.get("index")) - 1]
        state = scalars[int(der.find("Real").get("derivative")) - 1]
        lines.append(f"state\t{state.get('valueReference')}\t{der.get('valueReference')}")
    for sv in scalars:
        typed = next(child for child in sv if child.tag in TYPES)
        lines.append(
            "\t".join(
                [
                    "var",
                    sv.get("valueReference"),
                    TYPES[typed.tag],
                    sv.get("causality", "local"),
                    sv.get("variability", "continuous"),
                    typed.get("min", "-"),
                    typed.get("max", "-"),
                    sv.get("name"),
                ]
            )
        )
    (out_dir / "manifest.txt").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    if len(sys.argv) not in (3, 4) or sys.argv[3:] not in ([], ["cs"]):
        raise SystemExit("usage: manifest.py FMU OUTDIR [cs]")
    main(sys.argv[1], sys.argv[2], sys.argv[3:] == ["cs"])
