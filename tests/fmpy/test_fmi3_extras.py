"""What every FMI 3.0 FMU (build/fmus/fmi3/<Model>.fmu) carries beside its model description
(master/cli/src/fmi3_extras): `terminalsAndIcons/terminalsAndIcons.xml` with its icon
(`icon.png`, `icon.svg`; FMI 3.0.2 §2.4.9) and the reference results of the layered standard
fmi-ls-ref (`extra/org.fmi-standard.fmi-ls-ref/`: `fmi-ls-manifest.xml`, `<Model>_out.csv`,
`<Model>_in.csv` where the model has inputs).

Checked: both XML files valid against the standard's schemas (master/inspect/schema/: the FMI 3.0 set
of fmu-manipulation-toolbox 2.0, the fmi-ls-ref manifest schema); every terminal member a
variable of the model description with a causality a `signal` allows, every input and output
in exactly one terminal; the icons a PNG and an SVG, the files drawn by
scripts/draw-icons.py; the reference outputs equal to what fmpy computes when it steps the
FMU with the reference inputs the FMU carries."""

import io
import subprocess
import sys
import zipfile

import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.util import read_csv
from lxml import etree
from PIL import Image

from conftest import FMU_DIR, REPO, element_names
from test_fmi3 import STEMS, drive, fmi3_path

SCHEMAS = REPO / "master" / "inspect" / "schema"
LS_REF = "extra/org.fmi-standard.fmi-ls-ref"
SIGNAL_CAUSALITIES = {"input", "output", "parameter", "calculatedParameter"}


def schema(path):
    return etree.XMLSchema(etree.parse(str(path)))


TERMINALS_XSD = schema(SCHEMAS / "fmi3" / "fmi3TerminalsAndIcons.xsd")
LS_REF_XSD = schema(SCHEMAS / "fmi-ls-ref" / "fmi3LayeredStandardReferenceManifest.xsd")


def archive(stem):
    with zipfile.ZipFile(fmi3_path(stem)) as z:
        return {name: z.read(name) for name in z.namelist()}


def validated(xsd, data):
    doc = etree.fromstring(data)
    xsd.assertValid(doc)
    return doc


def source_folder(stem, md):
    """fmus/<Id>/ of a bundled variant."""
    return REPO / "fmus" / md.coSimulation.modelIdentifier


def test_every_bundled_variant_is_checked():
    assert len(STEMS) == 25 and "GantryCrane" in STEMS and "TimeTable" in STEMS


@pytest.mark.parametrize("stem", STEMS)
def test_terminals_are_schema_valid_and_name_the_signals_of_the_model(stem):
    files = archive(stem)
    md = read_model_description(fmi3_path(stem))
    doc = validated(TERMINALS_XSD, files["terminalsAndIcons/terminalsAndIcons.xml"])
    assert doc.get("fmiVersion") == md.fmiVersion == "3.0"
    causality = {v.name: v.causality for v in md.modelVariables}
    terminals = doc.findall("Terminals/Terminal")
    names = [t.get("name") for t in terminals]
    assert len(set(names)) == len(names), names
    seen = []
    for t in terminals:
        members = t.findall("TerminalMemberVariable")
        assert members, t.get("name")
        member_names = [m.get("memberName") for m in members]
        assert None not in member_names and len(set(member_names)) == len(members)
        kinds = set()
        for m in members:
            variable = m.get("variableName")
            assert variable in causality, f"{t.get('name')}: no variable {variable}"
            assert m.get("variableKind") == "signal"
            assert causality[variable] in SIGNAL_CAUSALITIES
            kinds.add(causality[variable])
            seen.append(variable)
        # One causality per terminal: a terminal is a bus in one direction.
        assert len(kinds) == 1, (t.get("name"), kinds)
        assert t.get("matchingRule") in {"plug", "bus"}
        # Drawn outside the icon's edge on its side: inputs left, outputs right.
        drawn = t.find("TerminalGraphicalRepresentation")
        (kind,) = kinds
        assert drawn.get("iconBaseName") == kind
        x1, y1, x2, y2 = (float(drawn.get(a)) for a in ("x1", "y1", "x2", "y2"))
        assert (x1, x2) == ((-120.0, -100.0) if kind == "input" else (100.0, 120.0))
        assert -100 <= y1 < y2 <= 100 and y2 - y1 <= 20
        assert f"terminalsAndIcons/{kind}.png" in files
        assert f"terminalsAndIcons/{kind}.svg" in files
    signals = [v.name for v in md.modelVariables if v.causality in ("input", "output")]
    assert sorted(seen) == sorted(signals)


def test_the_natural_buses():
    def terminals(stem):
        doc = etree.fromstring(archive(stem)["terminalsAndIcons/terminalsAndIcons.xml"])
        return {t.get("name"): [m.get("variableName") for m in t.iter("TerminalMemberVariable")]
                for t in doc.iter("Terminal")}

    crane = terminals("GantryCrane")
    assert crane == {"inputs": ["U"], "outputs": ["x", "theta", "v", "omega", "U_applied"]}
    kf = terminals("DualKalmanFilter")
    assert kf["y"] == ["y", "y_valid"] and kf["x_hat"] == ["x_hat"] and kf["y_hat"] == ["y_hat"]
    assert terminals("StateFeedback")["x_hat"] == [f"x_hat[{i}]" for i in range(1, 5)]
    assert terminals("WindGenerator")["inputs"] == ["u_drive", "u_field"]
    assert terminals("TimeTable")["u"] == ["u", "u.valid", "u.held"]


def test_the_schemas_reject_what_the_standard_forbids():
    """The validation can fail: a terminal without its matching rule, a manifest without
    the experiment the fmi-ls-ref schema requires."""
    files = archive("KalmanFilter")
    text = files["terminalsAndIcons/terminalsAndIcons.xml"].replace(b' matchingRule="bus"', b"")
    assert not TERMINALS_XSD.validate(etree.fromstring(text))
    manifest = files[f"{LS_REF}/fmi-ls-manifest.xml"]
    doc = etree.fromstring(manifest)
    assert LS_REF_XSD.validate(doc)
    for e in doc.findall("Experiment"):
        doc.remove(e)
    assert not LS_REF_XSD.validate(doc)


@pytest.mark.parametrize("stem", STEMS)
def test_the_icon_is_the_models_png_and_svg(stem):
    files = archive(stem)
    md = read_model_description(fmi3_path(stem))
    doc = etree.fromstring(files["terminalsAndIcons/terminalsAndIcons.xml"])
    icon = doc.find("GraphicalRepresentation/Icon")
    assert icon is not None and [icon.get(a) for a in ("x1", "y1", "x2", "y2")] == [
        "-100", "-100", "100", "100"]
    png = Image.open(io.BytesIO(files["terminalsAndIcons/icon.png"]))
    png.verify()
    assert png.format == "PNG" and png.size == (128, 128)
    svg = etree.fromstring(files["terminalsAndIcons/icon.svg"])
    assert svg.tag == "{http://www.w3.org/2000/svg}svg" and svg.get("viewBox") == "0 0 100 100"
    folder = source_folder(stem, md)
    assert files["terminalsAndIcons/icon.png"] == (folder / "icon.png").read_bytes()
    assert files["terminalsAndIcons/icon.svg"] == (folder / "icon.svg").read_bytes()
    shared = REPO / "fmus" / "export" / "icons"
    for kind in ("input", "output"):
        name = f"terminalsAndIcons/{kind}.png"
        if name in files:
            assert files[name] == (shared / f"{kind}.png").read_bytes()
            assert Image.open(io.BytesIO(files[name])).size == (32, 32)


def test_the_committed_icons_are_what_the_script_draws():
    result = subprocess.run([sys.executable, str(REPO / "scripts" / "draw-icons.py"), "--check"],
                            capture_output=True, text=True)
    assert result.returncode == 0, result.stderr


def expanded(table, md, causality):
    """{element name: values} of the columns of `table` (fmpy's read_csv) for the variables
    of `causality`, arrays split into their elements."""
    out = {}
    for v in md.modelVariables:
        if v.causality != causality:
            continue
        column = table[v.name].reshape(len(table), -1)
        for k, name in enumerate(element_names(v)):
            out[name] = column[:, k]
    return out


@pytest.mark.parametrize("stem", STEMS)
def test_the_reference_results_are_what_fmpy_computes_from_the_reference_inputs(stem, tmp_path):
    files = archive(stem)
    md = read_model_description(fmi3_path(stem))
    manifest = validated(LS_REF_XSD, files[f"{LS_REF}/fmi-ls-manifest.xml"])
    experiment = manifest.find("Experiment")
    start, stop, step = (float(experiment.get(a)) for a in ("startTime", "stopTime", "stepSize"))
    de = md.defaultExperiment
    assert (start, stop, step) == (float(de.startTime), float(de.stopTime), float(de.stepSize))
    references = experiment.find("References").get("source")
    assert references == f"{stem}_out.csv"
    assert manifest.find("Related").get("source") == references
    stimuli = experiment.find("Stimuli")
    has_inputs = any(v.causality == "input" for v in md.modelVariables)
    assert (stimuli is not None) == has_inputs
    for name in [references] + ([stimuli.get("source")] if has_inputs else []):
        (tmp_path / name).write_bytes(files[f"{LS_REF}/{name}"])
    inputs = None
    if has_inputs:
        table = read_csv(tmp_path / stimuli.get("source"))
        inputs = {"time": table["time"], **expanded(table, md, "input")}
    got = drive(stem, 3, inputs_table=inputs, experiment=(start, stop, step))
    reference = read_csv(tmp_path / references)
    want = expanded(reference, md, "output")
    assert sorted(got) == sorted(want)
    n = int(round((stop - start) / step))
    assert len(reference) == n + 1
    np.testing.assert_allclose(reference["time"], start + step * np.arange(n + 1), rtol=1e-12)
    for name, values in want.items():
        np.testing.assert_allclose(got[name], values, rtol=1e-10, atol=1e-12, err_msg=name)
    # The scenario moves something: the comparison is not of constants.
    assert any(np.ptp(v) > 0 for v in want.values()), stem


def test_fmi3_fmus_are_compared_with_their_own_files():
    """The ls-ref files are those of the FMU's own scenario, not another variant's."""
    two = archive("Sensor2")
    one = archive("Sensor")
    assert f"{LS_REF}/Sensor2_out.csv" in two and f"{LS_REF}/Sensor_out.csv" not in two
    assert two[f"{LS_REF}/Sensor2_out.csv"].split(b"\n")[0] == b"time,y,y_clean,outlier"
    assert one[f"{LS_REF}/Sensor_out.csv"] != two[f"{LS_REF}/Sensor2_out.csv"]
    assert FMU_DIR.is_dir()


def test_the_reference_fmus_write_an_older_draft_of_the_manifest():
    """The Reference FMUs v0.0.41 (tests/third_party) list their results only as `<Related>`,
    with no `fmi-ls-description`: the fmi-ls-ref schema rejects that draft, ours passes."""
    fmu = REPO / "tests" / "third_party" / "reference-fmus" / "fmi3" / "BouncingBall.fmu"
    with zipfile.ZipFile(fmu) as z:
        theirs = etree.fromstring(z.read(f"{LS_REF}/fmi-ls-manifest.xml"))
    assert theirs.find("Related").get("role") == "result"
    assert not LS_REF_XSD.validate(theirs)
    errors = str(LS_REF_XSD.error_log)
    assert "fmi-ls-description" in errors and "Expected is ( Experiment )" in errors


def test_a_variant_packaged_on_request_has_terminals_but_no_reference_results(tmp_path):
    """`spurio package-variant` with other dimensions under a bundled variant's name: its own
    terminals (sized by its description) and the folder's icon, but not the bundled variant's
    reference results, which are not its own; the FMI 2.0 archive carries neither."""
    spurio = REPO / "target" / "release" / "spurio"
    assert spurio.is_file(), "build with scripts/build-fmus first"
    subprocess.run(
        [str(spurio), "package-variant", "KalmanFilter", "--set", "n=3", "--set", "p=2",
         "--name", "KalmanFilter", "--lib-dir", str(REPO / "target" / "release"),
         "--out", str(tmp_path)],
        check=True, capture_output=True,
    )
    with zipfile.ZipFile(tmp_path / "fmi3" / "KalmanFilter.fmu") as z:
        names = z.namelist()
        doc = validated(TERMINALS_XSD, z.read("terminalsAndIcons/terminalsAndIcons.xml"))
    assert "terminalsAndIcons/icon.png" in names and "terminalsAndIcons/icon.svg" in names
    assert not [n for n in names if n.startswith("extra/")], names
    assert doc.find("Terminals/Terminal[@name='y']") is not None
    with zipfile.ZipFile(tmp_path / "KalmanFilter.fmu") as z:
        assert not [n for n in z.namelist() if n.startswith(("terminalsAndIcons", "extra"))]
