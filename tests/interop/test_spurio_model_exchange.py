"""`spurio run <fmu> --interface me` (spurio's own solvers over the Model Exchange interface)
against fmpy's CVode run of the same FMU (relative tolerance 1e-8): every Reference FMU with
Model Exchange, FMI 2.0 and 3.0, and our own Model Exchange FMUs, which must also agree with
their Co-Simulation twins. Each output must match to 1e-6 of its range over the run; the
figures are printed (`pytest -s`). WindGenerator, stiff, takes fewer right-hand-side
evaluations with the Rosenbrock method than with the explicit one."""

import re
import subprocess

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu

from conftest import FMU_DIR, SPURIO, THIRD_PARTY, require

# spurio's tolerance: tighter than CVode's 1e-8, so that the difference measured is CVode's.
SPURIO_TOLERANCE = "1e-10"
AGREEMENT = 1e-6


def reference(version, model):
    return require(
        THIRD_PARTY / "reference-fmus" / version / f"{model}.fmu",
        "the Reference FMUs (see the third-party README)",
    )


def spurio_run(fmu, out, *args):
    result = subprocess.run(
        [str(SPURIO), "run", str(fmu), "--out", str(out), *map(str, args)],
        capture_output=True,
        text=True,
    )
    assert result.returncode == 0, result.stderr
    rows = np.genfromtxt(out, delimiter=",", names=True, deletechars="")
    return rows, result.stdout


def experiment(fmu):
    d = read_model_description(str(fmu)).defaultExperiment
    stop = float(d.stopTime) if d is not None and d.stopTime else 1.0
    step = float(d.stepSize) if d is not None and d.stepSize else stop / 500
    return stop, step


def cvode(fmu, stop, step, output=None, rtol=1e-8, start_values=None):
    return simulate_fmu(
        str(fmu),
        fmi_type="ModelExchange",
        solver="CVode",
        relative_tolerance=rtol,
        stop_time=stop,
        output_interval=step,
        record_events=False,
        output=output,
        start_values=start_values or {},
    )


def agreement(ours, theirs, names):
    """Largest |difference| / range of each output over the rows both have (by time)."""
    common, i, j = np.intersect1d(
        np.round(ours["time"], 9), np.round(theirs["time"], 9), return_indices=True
    )
    assert len(common) >= 0.9 * min(len(ours), len(theirs)), (len(ours), len(theirs))
    figures = {}
    for name in names:
        a, b = ours[name][i].astype(float), theirs[name][j].astype(float)
        span = max(np.ptp(b), np.max(np.abs(b)) * 1e-3, 1e-12)
        figures[name] = float(np.max(np.abs(a - b)) / span)
    return figures


def allowed_against_cvode(fmu, ours, theirs, names, stop, step, tight_rtol=1e-12, **options):
    """The agreement asked of spurio against CVode at 1e-8 for each output: 1e-6 of the range,
    or CVode's own error where it is larger (measured against CVode at `tight_rtol`, which
    spurio must then match to 1e-7). CVode at the tight tolerance runs only when needed."""
    if max(agreement(ours, theirs, names).values()) <= AGREEMENT:
        return dict.fromkeys(names, AGREEMENT)
    tight = cvode(fmu, stop, step, rtol=tight_rtol, **options)
    ours_tight = agreement(ours, tight, names)
    cvode_tight = agreement(theirs, tight, names)
    print("  against CVode at %g: spurio %s; CVode at 1e-8 %s" % (
        tight_rtol,
        ", ".join(f"{n} {v:.1e}" for n, v in ours_tight.items()),
        ", ".join(f"{n} {v:.1e}" for n, v in cvode_tight.items()),
    ))
    allowed = {}
    for name in names:
        allowed[name] = AGREEMENT
        if cvode_tight[name] > AGREEMENT:
            assert ours_tight[name] <= 1e-7, (name, ours_tight[name])
            allowed[name] = 1.1 * cvode_tight[name]
    return allowed


REFERENCE_CASES = [
    (version, model)
    for version in ("fmi2", "fmi3")
    for model in ("BouncingBall", "VanDerPol", "Dahlquist", "Stair", "Feedthrough", "Resource")
] + [("fmi3", "Roberts")]


def bouncing_ball(t, h0=1.0, g=9.81, e=0.7, v_min=0.1):
    """The Reference FMU BouncingBall in closed form at time t: (h, v)."""
    t_bounce = np.sqrt(2 * h0 / g)
    if t < t_bounce:
        return h0 - 0.5 * g * t * t, -g * t
    v = g * t_bounce
    while True:
        v *= e
        if v < v_min:
            return 0.0, 0.0
        if t < t_bounce + 2 * v / g:
            s = t - t_bounce
            return v * s - 0.5 * g * s * s, v - g * s
        t_bounce += 2 * v / g


@pytest.mark.parametrize("version,model", REFERENCE_CASES)
def test_reference_fmu_matches_fmpy_cvode(tmp_path, version, model):
    fmu = reference(version, model)
    stop, step = experiment(fmu)
    # Robertson's problem (to t = 1e8) is stiff: the explicit method stops at its step bound.
    solver = "rodas4" if model == "Roberts" else "dopri5"
    ours, said = spurio_run(
        fmu, tmp_path / "me.csv", "--interface", "me", "--tolerance", SPURIO_TOLERANCE,
        "--stop-time", stop, "--step-size", step, "--solver", solver,
    )
    # fmpy's CVode stops at its step bound (mxstep) on Robertson's problem at 1e-8: 1e-6 there.
    theirs = cvode(fmu, stop, step, rtol=1e-6 if model == "Roberts" else 1e-8)
    names = [n for n in ours.dtype.names if n != "time" and n in theirs.dtype.names]
    assert names, (ours.dtype.names, theirs.dtype.names)
    figures = agreement(ours, theirs, names)
    print(f"\n{version} {model}: max |spurio − CVode| / range: "
          + ", ".join(f"{n} {v:.1e}" for n, v in figures.items()) + f"\n  {said.strip()}")
    if model == "Roberts":
        # fmpy's CVode reaches 1e-6 only on Robertson's problem: spurio's rodas3 at 1e-12 is
        # the reference there (another method than the run's rodas4; shampine4, A- but not
        # L-stable, lets y2 drift by 2e-3 of its range at 1e-12 once its steps are long).
        tight, _ = spurio_run(
            fmu, tmp_path / "tight.csv", "--interface", "me", "--tolerance", "1e-12",
            "--stop-time", stop, "--step-size", step, "--solver", "rodas3",
        )
        ours_tight = agreement(ours, tight, names)
        cvode_tight = agreement(theirs, tight, names)
        print(f"  against rodas3 at 1e-12: spurio {ours_tight}; CVode at 1e-6 {cvode_tight}")
        allowed = {n: max(AGREEMENT, 1.1 * cvode_tight[n]) for n in names}
        assert max(ours_tight.values()) <= 1e-6, ours_tight
    elif model == "BouncingBall":
        allowed = dict.fromkeys(figures, AGREEMENT)
    else:
        allowed = allowed_against_cvode(fmu, ours, theirs, names, stop, step)
    if model == "BouncingBall":
        # CVode at 1e-8 places the late, slow bounces up to ~1e-6 s off (v off by 7.6e-6 m/s
        # at t = 2.48, 1.02e-6 of the range); spurio's run is checked against the closed form
        # instead, and against CVode within CVode's own error.
        exact = np.array([bouncing_ball(t) for t in ours["time"]])
        cvode_exact = np.array([bouncing_ball(t) for t in theirs["time"]])
        for k, name in enumerate(("h", "v")):
            span = np.ptp(exact[:, k])
            ours_error = np.max(np.abs(ours[name] - exact[:, k])) / span
            cvode_error = np.max(np.abs(theirs[name] - cvode_exact[:, k])) / span
            print(f"  {name}: spurio − closed form {ours_error:.1e}, CVode − closed form "
                  f"{cvode_error:.1e} of the range")
            assert ours_error <= 1e-8, (name, ours_error)
            allowed[name] = max(AGREEMENT, 1.1 * cvode_error)
    for name, value in figures.items():
        assert value <= allowed[name], f"{model} {name}: {value:e}"


LINEAR_CONTINUOUS = {
    "continuous": "true", "Q[1,1]": 0, "Q[2,2]": 0, "R[1,1]": 0, "u[1]": 1.0,
    "A[1,1]": -0.5, "A[1,2]": 1.0, "A[2,1]": -2.0, "A[2,2]": -0.3,
    "B[1,1]": 0.0, "B[2,1]": 1.0, "C[1,1]": 1.0, "C[1,2]": 0.5, "D[1,1]": 0.2,
}

# (FMU, FMI 3.0?, start values, agreement with the Co-Simulation twin asked by the FMU's page
# (its me_scenarios.py): the twins integrate with RK4 or exactly, their own way)
OUR_CASES = [
    # off the stops, free swing: CVode against RK4 at 1 ms, 2e-6 (page: rtol 1e-5)
    ("GantryCrane", False, {"theta0": 0.2}, 1e-5),
    ("GantryCrane", True, {"theta0": 0.2}, 1e-5),
    # pushed into the rail stop (state events; the RK4 twin clamps at its substeps: 1e-2)
    ("GantryCrane", False, {"U": 3.0}, 1e-2),
    # into saturation at the rails (state events), the twin's RK4 on a fine grid
    ("OpAmpFilter", False, {"u": 20.0, "h_max": 1e-5}, 1e-5),
    ("OpAmpFilter", True, {"u": 20.0, "h_max": 1e-5}, 1e-5),
    # start-up (angle-wrap and torque-limit events); the twin is DOP853 at 7e-12
    ("WindGenerator", False, {}, 1e-6),
    ("WindGenerator", True, {}, 1e-6),
    # continuous, exact matrix exponential in the twin
    ("LinearSystem", False, LINEAR_CONTINUOUS, 1e-6),
    # the defaults: discrete with noise, time events at the samples: the twin's samples exactly
    ("LinearSystem", True, {}, 0.0),
]


def our_fmu(stem, fmi3):
    return require(
        FMU_DIR / ("fmi3" if fmi3 else "") / f"{stem}.fmu",
        "build the FMUs with scripts/build-fmus",
    )


@pytest.mark.parametrize("stem,fmi3,start,twin_agreement", OUR_CASES)
def test_our_model_exchange_fmus_match_cvode_and_their_co_simulation_twins(
    tmp_path, stem, fmi3, start, twin_agreement
):
    fmu = our_fmu(stem, fmi3)
    stop, step = experiment(fmu)
    sets = [a for name, value in start.items() for a in ("--set", f"{name}={value}")]
    ours, said = spurio_run(
        fmu, tmp_path / "me.csv", "--interface", "me", "--tolerance", SPURIO_TOLERANCE,
        "--stop-time", stop, "--step-size", step, *sets,
    )
    twin, _ = spurio_run(
        fmu, tmp_path / "cs.csv", "--interface", "cs", "--stop-time", stop, "--step-size", step,
        *sets,
    )
    # the Co-Simulation run names its columns `<instance>.<variable>`
    twin = twin.copy()
    twin.dtype.names = [n.split(".", 1)[-1] for n in twin.dtype.names]
    names = [n for n in ours.dtype.names if n != "time"]
    against_twin = agreement(ours, twin, [n for n in names if n in twin.dtype.names])
    worst_twin = max(against_twin.values())
    title = f"{'FMI 3.0' if fmi3 else 'FMI 2.0'} {stem} {start or 'defaults'}"
    print(f"\n{title}: max |spurio ME − CS| / range {worst_twin:.1e}\n  {said.strip()}")
    assert worst_twin <= twin_agreement, against_twin
    if fmi3 and stem == "LinearSystem":
        return  # fmpy names FMI 3.0 arrays whole (`y`), not by element: the twin check suffices
    start_values = {k: (v == "true" if isinstance(v, str) else v) for k, v in start.items()}
    theirs = cvode(fmu, stop, step, output=names, start_values=start_values)
    against_cvode = agreement(ours, theirs, names)
    print(f"  max |spurio ME − CVode| / range {max(against_cvode.values()):.1e}")
    allowed = allowed_against_cvode(
        fmu, ours, theirs, names, stop, step, output=names, start_values=start_values
    )
    for name, value in against_cvode.items():
        assert value <= allowed[name], (name, value)


def right_hand_sides(said):
    """The right-hand sides and directional-derivative calls a run said it made."""
    rhs = int(re.search(r"(\d+) right-hand sides", said).group(1))
    products = int(re.search(r"\((\d+) directional-derivative calls\)", said).group(1))
    return rhs, products


def test_wind_generator_stiff_method_needs_fewer_right_hand_sides(tmp_path):
    """At equal tolerance and accuracy against a tight run (dopri5 at 1e-10), the stiff default
    (RODAS4, whose dense output comes from its stages) in fewer right-hand sides than the
    explicit one, even counting each directional derivative as one."""
    fmu = our_fmu("WindGenerator", False)
    stop, step = experiment(fmu)
    common = ("--interface", "me", "--stop-time", stop, "--step-size", step)
    reference, _ = spurio_run(fmu, tmp_path / "ref.csv", *common, "--tolerance", "1e-10")
    names = [n for n in reference.dtype.names if n != "time"]
    runs = {}
    for solver in ("dopri5", "stiff"):
        result, said = spurio_run(
            fmu, tmp_path / f"{solver}.csv", *common, "--solver", solver, "--tolerance", "1e-6",
        )
        error = max(agreement(result, reference, names).values())
        runs[solver] = (*right_hand_sides(said), error)
        print(f"\nWindGenerator {solver} at 1e-6: error {error:.1e} of the range; {said.strip()}")
    (explicit, _, explicit_error), (stiff, products, stiff_error) = runs["dopri5"], runs["stiff"]
    assert 2 * stiff < explicit, runs
    assert stiff + products < explicit, runs
    assert stiff_error <= explicit_error, runs
    assert stiff_error < 1e-5, runs
