"""The cross-check scenarios (fmus/<Id>/crosscheck/, FMI cross-check layout; written by
scripts/crosscheck.py): every bundled FMU has one, its `_ref.opt` is the model description's
DefaultExperiment, it excites the model (outputs that change), and fmpy reproduces the
committed `_ref.csv` on linux64 (bit-identical, or within 1e-12 relative)."""

import sys

import numpy as np
import pytest
from fmpy import read_model_description

from conftest import FMU_DIR, REPO

sys.path.insert(0, str(REPO / "scripts"))
import crosscheck  # noqa: E402

# The bundled FMUs: one committed model description each (a variant packaged by a user
# into build/fmus is not one of them).
FMUS = [FMU_DIR / f"{p.stem}.fmu" for p in sorted((REPO / "modelDescription").glob("*.xml"))]
REL = 1e-12


def files(fmu):
    md = crosscheck.md_of(fmu)
    return crosscheck.folder_of(fmu.stem, crosscheck.identifier(md)), fmu.stem


@pytest.mark.parametrize("fmu", FMUS, ids=lambda p: p.stem)
def test_opt_is_the_default_experiment(fmu):
    folder, model = files(fmu)
    opt = crosscheck.read_opt(folder / f"{model}_ref.opt")
    de = read_model_description(str(fmu)).defaultExperiment
    assert (opt["StartTime"], opt["StopTime"], opt["StepSize"]) == (
        float(de.startTime), float(de.stopTime), float(de.stepSize))
    inputs = [v.name for v in read_model_description(str(fmu)).modelVariables
              if v.causality == "input"]
    if inputs:
        header, _ = crosscheck.read_table(folder / f"{model}_in.csv")
        assert header == ["time"] + inputs


@pytest.mark.parametrize("fmu", FMUS, ids=lambda p: p.stem)
def test_fmpy_reproduces_the_reference(fmu):
    folder, model = files(fmu)
    header, ref = crosscheck.read_table(folder / f"{model}_ref.csv")
    ref = np.array(ref)
    result = crosscheck.simulate(fmu, folder)
    assert list(result.dtype.names) == header
    got = np.array([[float(v) for v in row] for row in result])
    assert got.shape == ref.shape
    # time: fmpy's communication points (its last one may be 0.009999999999999998-style)
    outputs_ref, outputs_got = ref[:, 1:], got[:, 1:]
    scale = np.maximum(np.abs(outputs_ref), np.abs(outputs_got))
    diff = np.abs(outputs_ref - outputs_got)
    assert np.all(diff <= REL * scale), float(np.max(diff / np.where(scale > 0, scale, 1)))
    # the scenario excites the model: some output moves
    assert np.any(np.ptp(outputs_ref, axis=0) > 0), f"{model}: every output is constant"
