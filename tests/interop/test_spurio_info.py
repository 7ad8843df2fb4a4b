"""`spurio info --json` says what fmpy's `read_model_description` reads: for our FMUs (FMI 2.0
in build/fmus, FMI 3.0 in build/fmus/fmi3) and every Reference FMU (FMI 2.0 and 3.0), the same
variables (FMI 3.0 aliases included, as fmpy lists them) with the same value reference,
causality, variability, initial, type, unit, start, min, max and description, and the same FMI
version, model name, GUID/instantiation token, generation tool, interfaces, default experiment
and C sources. And `spurio validate` accepts every one of them, as fmpy's `validate_fmu` does."""

import json
import zipfile
from xml.etree import ElementTree

import pytest
from fmpy import read_model_description, supported_platforms
from fmpy.validation import validate_fmu

from conftest import FMU_DIR, THIRD_PARTY, spurio

OURS = sorted(FMU_DIR.glob("*.fmu")) + sorted((FMU_DIR / "fmi3").glob("*.fmu"))
REFERENCE = sorted((THIRD_PARTY / "reference-fmus").glob("fmi*/*.fmu"))
FMUS = OURS + REFERENCE


def label(fmu):
    return f"{fmu.parent.name}/{fmu.stem}"


def test_the_fmus_are_there():
    assert len(OURS) >= 44, f"build the FMUs with scripts/build-fmus: {OURS}"
    assert len(REFERENCE) == 15, REFERENCE


def fmpy_unit(v):
    if v.unit is not None:
        return v.unit
    return v.declaredType.unit if v.declaredType is not None else None


@pytest.mark.parametrize("fmu", FMUS, ids=label)
def test_info_matches_fmpy(fmu):
    info = json.loads(spurio("info", fmu, "--json").stdout)
    md = read_model_description(str(fmu))

    assert info["fmi_version"] == md.fmiVersion
    assert info["model_name"] == md.modelName
    assert info["token"] == md.guid if md.fmiVersion == "2.0" else md.instantiationToken
    assert info["generation_tool"] == md.generationTool
    kinds = {i["kind"] for i in info["interfaces"]}
    assert kinds == {k for k, interface in [("ME", md.modelExchange), ("CS", md.coSimulation),
                                            ("SE", md.scheduledExecution)] if interface is not None}
    assert info["sources"] == ("c-code" in supported_platforms(str(fmu)))
    de = md.defaultExperiment
    if de is None:
        assert info["default_experiment"] is None
    else:
        for name in ["startTime", "stopTime", "stepSize", "tolerance"]:
            assert info["default_experiment"].get(name) == getattr(de, name), name

    with zipfile.ZipFile(fmu) as archive:
        root = ElementTree.fromstring(archive.read("modelDescription.xml"))
    written = {e.get("name"): e for e in root.find("ModelVariables")}

    ours = {v["name"]: v for v in info["variables"]}
    assert len(ours) == len(info["variables"]), "names are unique"
    assert set(ours) == {v.name for v in md.modelVariables}
    assert len(ours) == len(md.modelVariables)
    for v in md.modelVariables:
        o = ours[v.name]
        assert int(o["value_reference"]) == v.valueReference, v.name
        assert o["causality"] == v.causality, v.name
        assert o["variability"] == v.variability, v.name
        assert o["initial"] == v.initial, v.name
        assert o["type"].split("[")[0] == v.type, v.name
        assert o["unit"] == fmpy_unit(v), v.name
        assert o["start"] == v.start, v.name
        if v.type.startswith("UInt"):
            # fmpy 0.3.32 reads min and max only of types starting with Float or Int (and
            # Real, Enumeration): of a UInt variable, compare with the attributes as written.
            element = written[v.name]
            assert (o["min"], o["max"]) == (element.get("min"), element.get("max")), v.name
        else:
            assert o["min"] == v.min and o["max"] == v.max, v.name
        assert o["description"] == v.description, v.name
        alias = getattr(v, "alias", None)
        assert o["alias_of"] == (alias.name if alias is not None else None), v.name


@pytest.mark.parametrize("fmu", FMUS, ids=label)
def test_validate_agrees_with_fmpy(fmu):
    assert validate_fmu(str(fmu)) == []
    out = spurio("validate", fmu).stdout
    assert "valid FMI" in out and "error:" not in out, out
