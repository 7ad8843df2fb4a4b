"""Every FMU of ours that declares Model Exchange, in the FMU Compliance Checker's Model
Exchange simulation (`fmuCheck -k me`: forward Euler at a fixed step, events checked at the
steps), on the first scenario of its `fmus/<Id>/me_scenarios.py` whose start values are all
inputs (written as fmuCheck's input file: it sets no start value; see
tests/fmpy/test_model_exchange.py): no warning or error, and the result of fmpy's CVode on the
Model Exchange interface within the Euler method's accuracy.

The step is a power of two (`binary_step`) and the input rows are moved onto its grid."""

import subprocess
import sys

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu

from conftest import FMUCHECK, REPO, binary_step, column, our_fmu, read_csv, require

sys.path.insert(0, str(REPO / "scripts"))
import me_scenarios  # noqa: E402

# fmuCheck integrates with forward Euler at h (error O(h)) and applies an input change one
# step late; at h ≈ output_interval / 100 that is well within 1 % of each output's range,
# while a wrong derivative, event indicator or discrete change is not.
EULER_RTOL = 0.01


def usable_scenario(stem, fmu):
    """The first scenario of `stem` whose start values are all inputs (fmuCheck sets no start
    value, but reads inputs from a file): its input rows with those start values added."""
    inputs = {
        v.name for v in read_model_description(str(fmu)).modelVariables
        if v.causality == "input" and v.type == "Real"
    }
    for s in me_scenarios.load(REPO)[0]:
        start = s.get("start_values", {})
        if s["fmu"] != stem or not set(start) <= inputs:
            continue
        rows = [(t, {**start, **values}) for t, values in s.get("inputs") or []]
        if start and not rows:
            rows = [(0.0, dict(start)), (s["stop_time"], dict(start))]
        return s, rows
    return None, None


def on_grid(rows, h):
    """The input rows with each time moved to the nearest step."""
    return [(round(t / h) * h, values) for t, values in rows]


@pytest.mark.parametrize("stem", me_scenarios.stems(REPO))
def test_fmucheck_me_passes_and_matches_fmpy_cvode(stem, workdir):
    fmu = our_fmu(stem)
    s, rows = usable_scenario(stem, fmu)
    if s is None:
        pytest.skip(f"every scenario of {stem} sets parameters, which fmuCheck cannot")
    h = binary_step(s["output_interval"] / 100)
    stop = s["stop_time"]
    rows = on_grid(rows, h)
    names = sorted({n for _, values in rows for n in values})
    command = [str(require(FMUCHECK, "see the third-party README")), "-k", "me", "-n", "0",
               "-h", repr(h), "-s", repr(stop), "-o", str(workdir / "me.csv")]
    signals = None
    if rows:
        infile = workdir / "in.csv"
        infile.write_text(
            ",".join(["time", *names]) + "\n"
            + "".join(",".join(repr(v) for v in [t, *[x[n] for n in names]]) + "\n"
                      for t, x in rows)
        )
        command += ["-i", str(infile)]
        dtype = [("time", np.float64)] + [(n, np.float64) for n in names]
        signals = np.array([(t, *[x[n] for n in names]) for t, x in rows], dtype=dtype)
    check = subprocess.run(command + [str(fmu)], capture_output=True, text=True, timeout=300)
    report = check.stdout + check.stderr
    assert check.returncode == 0, report
    assert "0 Warning(s)" in report and "0 Error(s)" in report, report
    assert "0 warning(s) and error(s)" in report, report

    got_names, got = read_csv(workdir / "me.csv")
    expected = simulate_fmu(str(fmu), fmi_type="ModelExchange", solver="CVode",
                            relative_tolerance=1e-8, output_interval=s["output_interval"],
                            stop_time=stop, input=signals, output=s["outputs"])
    # fmuCheck writes one row per time, after the event there; fmpy also the one before
    # (the time events of a sampled system such as LinearSystem's discrete mode are jumps)
    expected = expected[np.append(np.diff(expected["time"]) > 0, True)]
    assert got[-1, 0] == pytest.approx(stop, abs=1e-9)
    for name in s["outputs"]:
        # fmuCheck's fine Euler grid interpolated onto fmpy's output points
        values = np.interp(expected["time"], got[:, 0], column(got_names, got, name))
        scale = max(np.max(np.abs(expected[name])), 1e-12)
        error = np.max(np.abs(values - expected[name])) / scale
        print(f"{s['fmu']} {name}: fmuCheck -k me vs fmpy CVode: {error:.2e} of the range")
        assert error < EULER_RTOL, f"{name}: {error:.3g}"
