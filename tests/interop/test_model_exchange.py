"""Every FMU of ours that declares Model Exchange, in the FMU Compliance Checker's Model
Exchange simulation (`fmuCheck -k me`: forward Euler at a fixed step, events checked at the
steps), on the first scenario of its `fmus/<Id>/me_scenarios.py` that sets no start value (see
tests/fmpy/test_model_exchange.py): no warning or error, and the result of fmpy's CVode on the
Model Exchange interface within the Euler method's accuracy.

The step is a power of two (`binary_step`) and the input rows are moved onto its grid."""

import importlib.util
import subprocess

import numpy as np
import pytest
from fmpy import simulate_fmu

from conftest import FMUCHECK, REPO, binary_step, column, our_fmu, read_csv, require

# fmuCheck integrates with forward Euler at h (error O(h)) and applies an input change one
# step late; at h ≈ output_interval / 10 that is well within 1 % of each output's range,
# while a wrong derivative, event indicator or discrete change is not.
EULER_RTOL = 0.01


def first_scenarios():
    """The first scenario without start values (fmuCheck has no way to set them) of each
    Model Exchange FMU."""
    stems = [
        p.stem
        for p in sorted((REPO / "modelDescription").glob("*.xml"))
        if "<ModelExchange " in p.read_text()
    ]
    scenarios = {}
    for path in sorted((REPO / "fmus").glob("*/me_scenarios.py")):
        spec = importlib.util.spec_from_file_location(f"me_scenarios_{path.parent.name}", path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        for s in module.SCENARIOS:
            if not s.get("start_values"):
                scenarios.setdefault(s["fmu"], s)
    return [scenarios[stem] for stem in stems if stem in scenarios]


SCENARIOS = first_scenarios()


def on_grid(rows, h):
    """The input rows with each time moved to the nearest step."""
    return [(round(t / h) * h, values) for t, values in rows]


@pytest.mark.parametrize("s", SCENARIOS, ids=lambda s: s["fmu"])
def test_fmucheck_me_passes_and_matches_fmpy_euler(s, workdir):
    fmu = our_fmu(s["fmu"])
    h = binary_step(s["output_interval"] / 10)
    stop = s["stop_time"]
    rows = on_grid(s.get("inputs") or [], h)
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
                            relative_tolerance=1e-8, output_interval=h, stop_time=stop,
                            input=signals, output=s["outputs"])
    assert got[-1, 0] == pytest.approx(stop, abs=1e-9)
    for name in s["outputs"]:
        reference = np.interp(got[:, 0], expected["time"], expected[name])
        scale = max(np.max(np.abs(expected[name])), 1e-12)
        error = np.max(np.abs(column(got_names, got, name) - reference)) / scale
        print(f"{s['fmu']} {name}: fmuCheck -k me vs fmpy CVode: {error:.2e} of the range")
        assert error < EULER_RTOL, f"{name}: {error:.3g}"
