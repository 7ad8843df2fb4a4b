#!/usr/bin/env python3
"""Unpacks an FMU (FMI 2.0 or 3.0) for the allocation driver and writes what it needs as text.

    manifest.py FMU OUTDIR   ->  OUTDIR/fmu/<unpacked FMU>, OUTDIR/manifest.txt

manifest.txt (one record a line, fields separated by a tab):
    label     <file stem of the FMU>
    version   <2 or 3>
    id        <modelIdentifier>
    token     <guid (2.0) or instantiationToken (3.0)>
    library   <path of the Linux x86-64 binary>
    resources <file URI (2.0) or path with a trailing slash (3.0) of the resources folder>
    step      <DefaultExperiment stepSize, else 0.01>
    var       <vr> <R|I|B|S> <causality> <variability> <number of values> <start> <min> <max> <name>
The start of an array lists its elements' start values, separated by spaces (one value: every
element starts there); "-" for a start, min or max the variable does not have. Standard
library only.
"""
import pathlib
import sys
import xml.etree.ElementTree as ET
import zipfile

TYPES2 = {"Real": "R", "Integer": "I", "Boolean": "B", "String": "S", "Enumeration": "I"}
TYPES3 = {"Float64": "R", "Int32": "I", "Boolean": "B", "String": "S"}


def variables2(root):
    for sv in root.iter("ScalarVariable"):
        typed = next(child for child in sv if child.tag in TYPES2)
        yield (sv.get("valueReference"), TYPES2[typed.tag], sv.get("causality", "local"),
               sv.get("variability", "continuous"), 1, typed.get("start"), typed.get("min"),
               typed.get("max"), sv.get("name"))


def variables3(root):
    for v in root.find("ModelVariables"):
        if v.tag not in TYPES3:
            raise SystemExit(f"{v.get('name')}: FMI 3.0 type {v.tag} not handled")
        count = 1
        for d in v.iter("Dimension"):
            count *= int(d.get("start"))
        start = v.get("start")
        if v.tag == "String":
            start = next((s.get("value") for s in v.iter("Start")), None)
        yield (v.get("valueReference"), TYPES3[v.tag], v.get("causality", "local"),
               v.get("variability", "continuous"), count,
               " ".join(start.split()) if start else None, v.get("min"), v.get("max"),
               v.get("name"))


def main(fmu: str, out: str) -> None:
    unpacked = pathlib.Path(out).resolve() / "fmu"
    zipfile.ZipFile(fmu).extractall(unpacked)
    root = ET.parse(unpacked / "modelDescription.xml").getroot()
    model_id = next(cs.get("modelIdentifier") for cs in root.iter("CoSimulation"))
    version = root.get("fmiVersion")[0]
    experiment = root.find("DefaultExperiment")
    step = experiment.get("stepSize") if experiment is not None else None
    if version == "2":
        token, platform, variables = root.get("guid"), "linux64", variables2(root)
        resources = (unpacked / "resources").as_uri()
    else:
        token, platform, variables = root.get("instantiationToken"), "x86_64-linux", variables3(root)
        resources = str(unpacked / "resources") + "/"
    lines = [
        f"label\t{pathlib.Path(fmu).stem}",
        f"version\t{version}",
        f"id\t{model_id}",
        f"token\t{token}",
        f"library\t{unpacked / 'binaries' / platform / (model_id + '.so')}",
        f"resources\t{resources}",
        f"step\t{step or '0.01'}",
    ]
    for vr, kind, causality, variability, count, start, low, high, name in variables:
        fields = [vr, kind, causality, variability, str(count), start or "-", low or "-",
                  high or "-", name]
        lines.append("\t".join(["var"] + fields))
    (unpacked.parent / "manifest.txt").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        raise SystemExit("usage: manifest.py FMU OUTDIR")
    main(sys.argv[1], sys.argv[2])
