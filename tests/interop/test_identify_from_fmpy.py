"""`spurio identify` on records another tool made: the Reference FMUs' VanDerPol μ, BouncingBall
e and Dahlquist k identified from fmpy's own simulation at the truth, plus seeded noise and
outliers, read back as a CSV through the command line.

Each case follows the library's synthetic one (identify/src/synthetic.rs): the same measured
output, sample step Δ, number of samples, noise σ and 5 % outliers of ±20 σ; the noise and the
outliers are drawn here by numpy (`default_rng(seed)`), not by the library's generator, and
fmpy integrates the data (CVode, relative tolerance 10⁻¹⁰, a point every Δ), so the data are
not the library's. fmpy's extra rows at BouncingBall's bounces are dropped: the UKF does not
learn e from a sample at a bounce's time (the last test, an expected failure, says why).

Done when (asserted per case, `--noise σ²` as the library's cases know R = σ²):
- offline (`--method ml --robust huber`): |θ̂ − θ| ≤ 1 % of θ, on the record of seed 28;
- online (`--method ukf --robust huber`): |θ̂ − θ| ≤ 2 se at the end of that record;
- `--robust none` misses the truth by more than the robust fit, offline and online: the ratio
  of their root-mean-square errors over the records of seeds 28 … 35 above 1.5 (the library's
  figure). One record decides this only by chance: the plain fit's error is the sum of a
  bias from the outliers and an error from the noise, which can cancel. On seed 28
  BouncingBall's plain ML is off by 5.7·10⁻⁵ (the outliers' bias −1.06·10⁻⁴, linearised, the
  noise's +1.63·10⁻⁴) against Huber's 2.0·10⁻⁴ (1.2 se); over seeds 0 … 19 the plain error is
  the larger on 18 to 19 of the 20 records per case and method. Each record's ratio is printed.
"""

import csv
import dataclasses

import numpy as np
import pytest

from conftest import REFERENCE_FMUS, require, spurio

# The seed of the noise and the outliers (numpy's default_rng): the accuracy record's, and the
# records over which the plain and the robust fits are compared.
SEED = 28
SEEDS = range(28, 36)
OUTLIER_FRACTION = 0.05
OUTLIER_SIZE = 20.0


@dataclasses.dataclass(frozen=True)
class Case:
    model: str
    parameter: str
    output: str
    truth: float
    start: float
    sigma: float
    samples: int
    step: float


CASES = [
    Case("VanDerPol", "mu", "x0", truth=1.3, start=1.0, sigma=0.02, samples=201, step=0.05),
    Case("BouncingBall", "e", "h", truth=0.8, start=0.7, sigma=0.01, samples=301, step=0.01),
    Case("Dahlquist", "k", "x", truth=1.5, start=1.2, sigma=0.005, samples=101, step=0.05),
]


def fmpy_record(case: Case, truth: float, event_rows=False) -> tuple[np.ndarray, np.ndarray]:
    """fmpy's run of the Reference FMU at `truth` (Model Exchange, CVode at 10⁻¹⁰): the
    measured output at t_k = k Δ, k < samples (an event's two rows at one time: the last),
    and with `event_rows` also fmpy's rows at the events between them."""
    from fmpy import simulate_fmu

    fmu = require(REFERENCE_FMUS / f"{case.model}.fmu", "the Reference FMUs (third-party README)")
    stop = (case.samples - 1) * case.step
    result = simulate_fmu(
        str(fmu),
        fmi_type="ModelExchange",
        start_values={case.parameter: truth},
        stop_time=stop,
        output_interval=case.step,
        relative_tolerance=1e-10,
        output=[case.output],
    )
    if event_rows:
        return result["time"], result[case.output]
    grid = np.arange(case.samples) * case.step
    # The row of each grid time: the last row within 10⁻⁹ of it.
    rows = [np.flatnonzero(np.abs(result["time"] - t) < 1e-9) for t in grid]
    assert all(len(r) > 0 for r in rows), "fmpy skipped a sample time"
    return grid, np.array([result[case.output][r[-1]] for r in rows])


def corrupt(clean: np.ndarray, sigma: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """`clean` + N(0, σ²) and, on 5 % of the samples, ±20 σ: the measurements and the
    outliers' indices."""
    rng = np.random.default_rng(seed)
    noise = sigma * rng.standard_normal(len(clean))
    wild = rng.uniform(size=len(clean)) < OUTLIER_FRACTION
    sign = np.where(rng.uniform(size=len(clean)) < 0.5, -1.0, 1.0)
    return clean + noise + np.where(wild, sign * OUTLIER_SIZE * sigma, 0.0), np.flatnonzero(wild)


def identify(case: Case, rig, method: str, robust: str, out) -> tuple[float, float]:
    """`spurio identify` on the record `rig`: θ̂ and its standard error from estimates.csv."""
    spurio(
        "identify", REFERENCE_FMUS / f"{case.model}.fmu",
        "--data", rig,
        "--output", f"{case.output}=measured",
        "--free", case.parameter,
        "--start", f"{case.parameter}={case.start}",
        "--method", method,
        "--robust", robust,
        "--noise", case.sigma**2,
        "--out", out,
    )  # fmt: skip
    with open(out / "estimates.csv", newline="") as f:
        (row,) = [r for r in csv.DictReader(f) if r["parameter"] == case.parameter]
    assert float(row["start"]) == case.start
    return float(row["estimate"]), float(row["standard_error"])


FITS = [(method, robust) for method in ("ml", "ukf") for robust in ("huber", "none")]


def identify_all(case: Case, record, seed: int, workdir) -> dict:
    """The four fits of `case` (FITS) from the fmpy record `(time, clean)` corrupted by
    `seed`."""
    time, clean = record
    measured, outliers = corrupt(clean, case.sigma, seed)
    assert len(outliers) >= 3, f"{len(outliers)} outliers"
    rig = workdir / f"rig-{seed}.csv"
    np.savetxt(
        rig, np.column_stack([time, measured]), delimiter=",", header="time,measured",
        comments="", fmt="%.17g",
    )  # fmt: skip
    return {
        (method, robust): identify(case, rig, method, robust, workdir / f"{seed}-{method}-{robust}")
        for method, robust in FITS
    }


def accuracy_misses(case: Case, fits: dict, truth: float) -> list[str]:
    """What of the robust fits misses `truth` (empty: offline within 1 %, online within 2 se),
    after printing the four fits."""
    for method, label in (("ml", "offline"), ("ukf", "online")):
        (value, se), (plain, plain_se) = fits[(method, "huber")], fits[(method, "none")]
        print(
            f"\n{case.model}.{case.parameter} {label} (truth {truth}, start {case.start}): "
            f"huber {value:.5f} ± {se:.2g}, none {plain:.5f} ± {plain_se:.2g}, error ratio "
            f"none/huber {abs(plain - truth) / abs(value - truth):.3g}",
            end="",
        )
    misses = []
    offline = fits[("ml", "huber")][0]
    if abs(offline - truth) > 0.01 * truth:
        misses.append(f"offline {offline} not within 1 % of {truth}")
    online, se = fits[("ukf", "huber")]
    if abs(online - truth) > 2 * se:
        misses.append(f"online {online} ± {se} not within 2 se of {truth}")
    return misses


@pytest.mark.parametrize("case", CASES, ids=lambda c: f"{c.model}.{c.parameter}")
def test_identified_from_fmpy_record(case, workdir):
    fits = identify_all(case, fmpy_record(case, case.truth), SEED, workdir)
    misses = accuracy_misses(case, fits, case.truth)
    assert not misses, misses


@pytest.mark.parametrize("case", CASES, ids=lambda c: f"{c.model}.{c.parameter}")
def test_robust_beats_none_on_fmpy_records(case, workdir):
    record = fmpy_record(case, case.truth)
    errors = np.array(
        [
            [fit[0] - case.truth for fit in identify_all(case, record, seed, workdir).values()]
            for seed in SEEDS
        ]
    )
    rms = dict(zip(FITS, np.sqrt(np.mean(errors**2, axis=0))))
    for i, (method, label) in enumerate((("ml", "offline"), ("ukf", "online"))):
        each = np.abs(errors[:, 2 * i + 1]) / np.abs(errors[:, 2 * i])
        ratio = rms[(method, "none")] / rms[(method, "huber")]
        print(
            f"\n{case.model}.{case.parameter} {label}: rms error huber {rms[(method, 'huber')]:.2g}, "
            f"none {rms[(method, 'none')]:.2g}, ratio {ratio:.3g}; per seed "
            + " ".join(f"{r:.3g}" for r in each),
            end="",
        )
        assert ratio > 1.5, f"{label}: --robust none {ratio:.3g} × the robust rms error"


def test_a_wrong_truth_fails(workdir):
    """The accuracy check can fail: Dahlquist's fits from fmpy's record at k = 1.5 judged
    against k = 1.53 (2 % off) miss both goals."""
    case = CASES[2]
    fits = identify_all(case, fmpy_record(case, case.truth), SEED, workdir)
    assert accuracy_misses(case, fits, case.truth) == []
    misses = accuracy_misses(case, fits, 1.53)
    assert [m.split()[0] for m in misses] == ["offline", "online"], misses


@pytest.mark.xfail(
    strict=True,
    reason="a sample at a bounce's time puts the UKF's sigma points on both sides of the "
    "bounce: the predicted velocity is bimodal (unscented mean 0.67 m/s, sd 5.0 m/s against "
    "7e-3 one sample before, on the clean record) and e's link to the state is lost",
)
def test_bouncing_ball_online_from_fmpy_record_with_event_rows(workdir):
    """fmpy's record of BouncingBall with its rows at the six bounces (t = 0.4515 … 2.8801 s)
    as well: the robust UKF gives e = 0.8082 ± 0.0024 (3.4 se off; 0.737 ± 0.13 on the clean
    record, e hardly learned); without them 0.79998 ± 0.00033; the EKF 0.80000 ± 0.00034 with
    them."""
    case = CASES[1]
    fits = identify_all(case, fmpy_record(case, case.truth, event_rows=True), SEED, workdir)
    online, se = fits[("ukf", "huber")]
    assert abs(online - case.truth) <= 2 * se, f"online {online} ± {se}"
