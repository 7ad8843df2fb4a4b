#!/usr/bin/env python3
"""Unpacks an FMU for the misuse driver and writes what it needs to know as plain text.

    manifest.py FMU OUTDIR   ->  OUTDIR/<unpacked FMU>, OUTDIR/manifest.txt

manifest.txt (one record a line, fields separated by a tab):
    label    <file stem of the FMU>
    id       <modelIdentifier>
    guid     <guid>
    library  <path of binaries/linux64/<id>.so>
    resources <file URI of the resources folder>
    me       <1 if the FMU offers Model Exchange too, else 0>
    nz       <numberOfEventIndicators>
    state    <vr of a continuous state> <vr of its derivative>   (ModelStructure order)
    var      <vr> <R|I|B|S> <causality> <variability> <min or -> <max or -> <name>
Standard library only (the driver runs on a machine without the project's venv too).
"""
import pathlib
import sys
import xml.etree.ElementTree as ET
import zipfile

TYPES = {"Real": "R", "Integer": "I", "Boolean": "B", "String": "S", "Enumeration": "I"}


def main(fmu: str, out: str) -> None:
    out_dir = pathlib.Path(out).resolve()
    unpacked = out_dir / "fmu"
    with zipfile.ZipFile(fmu) as archive:
        archive.extractall(unpacked)
    root = ET.parse(unpacked / "modelDescription.xml").getroot()
    cs = root.find("CoSimulation")
    if cs is None:
        raise SystemExit(f"{fmu}: not a Co-Simulation FMU")
    model_id = cs.get("modelIdentifier")
    lines = [
        f"label\t{pathlib.Path(fmu).stem}",
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
    if len(sys.argv) != 3:
        raise SystemExit("usage: manifest.py FMU OUTDIR")
    main(sys.argv[1], sys.argv[2])
