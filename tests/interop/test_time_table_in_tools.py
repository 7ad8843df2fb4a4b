"""A table packaged by `spurio package-data` in the FMU Compliance Checker and in OMSimulator
(FMI 2.0 and 3.0): the checker finds nothing, and in both tools the outputs equal the table
at and between the sample times — hold exactly, linear to rounding (OMSimulator prints 12
significant digits: OMS_RTOL) — missing samples held and flagged invalid.

The table's sample times are decimal (0.1, 0.3, …), so the tools' communication points
(OMSimulator accumulates t += h) meet them within rounding, which the FMU's rule
(spurio_table::instant: within (1e-9 + i²ε) sampling intervals) takes as the sample time.
"""

import math
import subprocess
import sys

import numpy as np
import pytest

from conftest import FMUCHECK, OMS_RTOL, OMSIMULATOR, REPO, by_time, omsimulator, read_csv, require

sys.path.insert(0, str(REPO / "fmus" / "TimeTable"))
from table_reference import read  # noqa: E402

SPURIO = REPO / "target" / "release" / "spurio"

# 61 samples at 0.1 s of a rig: a force held in steps, a position following it, missing
# samples (empty cells, `nan`) in both columns.
TIMES = [round(0.1 * k, 10) for k in range(61)]
FORCE = [math.nan if k in (7, 30, 31) else float((k // 8) % 3 - 1) * 1.5 for k in range(61)]
X = [math.nan if k == 44 else round(math.sin(0.37 * k) * 0.2, 6) for k in range(61)]


def rig_csv():
    def cell(v, k):
        return "" if (math.isnan(v) and k % 2) else ("nan" if math.isnan(v) else repr(v))

    lines = ["time,force [N],x [m]"]
    lines += [f"{t!r},{cell(f, k)},{cell(x, k)}" for k, (t, f, x) in
              enumerate(zip(TIMES, FORCE, X))]
    return "\n".join(lines) + "\n"


def expected(t, u, linear):
    """Column `u` at time `t` (table_reference): ((value, valid), slope)."""
    value, valid, slope = read(u, TIMES, t, linear)
    return (value, float(valid)), slope


@pytest.fixture(scope="module")
def packaged(tmp_path_factory):
    require(SPURIO, "build it with scripts/build-fmus")
    fmus = {}
    for kind in ("hold", "linear"):
        tmp = tmp_path_factory.mktemp(kind)
        (tmp / "rig.csv").write_text(rig_csv())
        result = subprocess.run(
            [str(SPURIO), "package-data", str(tmp / "rig.csv"), "--name", "Rig",
             "--interpolation", kind, "--out", str(tmp),
             "--lib-dir", str(REPO / "target" / "release"), "--repo", str(REPO)],
            capture_output=True, text=True, timeout=300,
        )
        assert result.returncode == 0, result.stdout + result.stderr
        fmus[kind] = (tmp / "Rig.fmu", tmp / "fmi3" / "Rig.fmu")
    return fmus


def assert_equals_the_table(names, rows, kind, tool):
    """Every row equals the table at its time; returns max |output − table|."""
    worst = 0.0
    for row in rows:
        t = row[0]
        for name, u in (("force", FORCE), ("x", X)):
            (value, valid), slope = expected(t, u, kind == "linear")
            got = row[names.index(name)]
            assert row[names.index(f"{name}.valid")] == valid, (tool, name, t)
            if tool == "fmuCheck" and kind == "hold":
                assert got == value, (tool, name, t, got, value)
            # To rounding: of the printed value (OMS_RTOL) and of the printed time, along the
            # line (OMSimulator's accumulated t differs from its 12 printed digits).
            tolerance = OMS_RTOL * (abs(value) + abs(slope) * max(t, 1.0)) + 1e-15
            assert abs(got - value) <= tolerance, (tool, name, t, got, value)
            worst = max(worst, abs(got - value))
    print(f"{tool} {kind}: max |FMU - table| = {worst:.3g} over {len(rows)} rows")
    return worst


@pytest.mark.parametrize("kind", ["hold", "linear"])
def test_fmucheck_passes_and_reads_the_table(packaged, kind, workdir):
    fmu = packaged[kind][0]
    out = workdir / "fmucheck.csv"
    # Steps of 0.025 s: on every sample time and three points between.
    check = subprocess.run(
        [str(require(FMUCHECK, "see the third-party README")), "-k", "cs", "-n", "0",
         "-h", "0.025", "-s", "6.0", "-o", str(out), str(fmu)],
        capture_output=True, text=True, timeout=300,
    )
    report = check.stdout + check.stderr
    assert check.returncode == 0, report
    assert "0 Warning(s)" in report and "0 Error(s)" in report, report
    names, rows = read_csv(out)
    assert rows.shape[0] == 241, rows.shape
    worst = assert_equals_the_table(names, rows, kind, "fmuCheck")
    if kind == "hold":
        assert worst == 0.0


@pytest.mark.parametrize("version", [0, 1])
@pytest.mark.parametrize("kind", ["hold", "linear"])
def test_omsimulator_reads_the_table(packaged, kind, version, workdir):
    fmu = packaged[kind][version]
    out = workdir / "oms.csv"
    omsimulator(fmu, "--mode=cs", "--stopTime=6.0", "--stepSize=0.025",
                f"--resultFile={out.name}", cwd=workdir)
    names, rows = by_time(*read_csv(out), keep="last")
    assert rows.shape[0] == 241, rows.shape
    assert_equals_the_table(names, rows, kind, f"OMSimulator FMI {2 + version}")


def test_omsimulator_refuses_a_stop_past_the_data(packaged, workdir):
    out = workdir / "oms.csv"
    result = subprocess.run(
        [str(require(OMSIMULATOR, "see the third-party README")), str(packaged["hold"][0]), "--mode=cs", "--stopTime=6.5", "--stepSize=0.1",
         f"--resultFile={out.name}"],
        capture_output=True, text=True, timeout=300, cwd=workdir,
    )
    log = result.stdout + result.stderr
    assert "goes past the data, whose last sample is at 6" in log, log
