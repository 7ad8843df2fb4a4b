//! The noisy cosine with outliers of paper 000 (§VII-A, Tables 2–3, Figs 3–5) and paper 001
//! (§5, Figs 3–4): SignalSource (cosine) → Sensor (noise variance 0.01, ε-contaminated
//! outliers uniform in ±[0, 4.8]) → the scalar sKF and rsKF side by side (A = C = 1,
//! Q = R = 1e-4, x̂₀ = 0, P₀ = 0), 1000 samples, 100 seeds.
//!
//! Scores (docs/diagnostics.md §3): `E_res = (1/N) Σ_k (y_clean,k − x̂_{k|k})²` over the N = 1000 samples —
//! the estimators process the sample of t_k in `fmi2DoStep(t_k)`, so x̂_{k|k} is the row of
//! t_{k+1}; the excess kurtosis and skewness of paper 001 (eqs 18–19); the Grubbs test of
//! paper 000 (eqs 35–36) on the measured signal; its histogram with the ±2σ band.
//!
//! Paper 001's "mean ± std" of E_res, kurtosis and skewness are reproduced by the spread over
//! 50-sample segments of one run (its sKF E_res of 0.1728 ± 0.1945 cannot be a spread over
//! runs: most runs' E_res lies within 0.03 of the mean); we report both that and the spread
//! over seeds. Paper 001's rsKF figure, 0.0087 ± 0.0023, also shows its filter had no
//! start-up transient (see the report's notes): started at x̂₀ = 0 under the cosine's
//! y₀ = 1, the rsKF's first 100 samples alone give E_res ≈ 0.067. We start the filters at a
//! robust estimate of the initial level (the median of the first five measurements) for that
//! comparison, and report the literal start beside it.

use super::{ExperimentContext, Report, Row};
use crate::diagnostics::{
    excess_kurtosis, grubbs_critical_value, grubbs_iterative, histogram, mean, residual_error,
    skewness, std_dev, two_sigma_band,
};
use crate::plot::RGBColor;
use crate::plot::{measured_lines, panels_png, Line, Panel};
use crate::runner::{column, edited, mean_std, mean_std_of, median, pm, simulate, write_csv, Edit};
use anyhow::{ensure, Result};
use spurio_master::System;
use spurio_master::TimeSeries;

/// Samples per run (paper 000/001: 1000).
const SAMPLES: usize = 1000;
/// Segment length of the within-run spreads (paper 001's "±").
const SEGMENT: usize = 50;
/// Measurements whose median starts the filters in the robust-start runs.
const START_WINDOW: usize = 5;
/// Grubbs significance level (paper 000: 5 %).
const ALPHA: f64 = 0.05;
/// Prior variance P₀ of the causal alternative start: the mean square of a unit cosine.
const PRIOR_VARIANCE: f64 = 0.5;
/// The seed of the CSVs and plots.
const SHOWN_SEED: u32 = 1;

/// One run's signals, aligned sample by sample (length [`SAMPLES`]).
struct Signals {
    clean: Vec<f64>,
    measured: Vec<f64>,
    outlier: Vec<bool>,
    skf: Vec<f64>,
    rskf: Vec<f64>,
}

impl Signals {
    fn from_series(series: &TimeSeries) -> Result<Self> {
        let rows = series.time.len();
        ensure!(
            rows > SAMPLES,
            "the run recorded {rows} points, {} needed",
            SAMPLES + 1
        );
        let first =
            |name: &str| -> Result<Vec<f64>> { Ok(column(series, name)?[..SAMPLES].to_vec()) };
        // x̂_{k|k} of the sample taken at t_k is published at t_{k+1}.
        let estimate =
            |name: &str| -> Result<Vec<f64>> { Ok(column(series, name)?[1..=SAMPLES].to_vec()) };
        Ok(Self {
            clean: first("sensor.y_clean[1]")?,
            measured: first("sensor.y[1]")?,
            outlier: first("sensor.outlier[1]")?
                .iter()
                .map(|f| *f != 0.0)
                .collect(),
            skf: estimate("skf.y_hat[1]")?,
            rskf: estimate("rskf.y_hat[1]")?,
        })
    }

    fn run(system: &System, edits: &[Edit<'_>]) -> Result<(Self, TimeSeries)> {
        let series = simulate(&edited(system, edits)?)?;
        Ok((Self::from_series(&series)?, series))
    }
}

/// Mean and sample std of `statistic` over consecutive [`SEGMENT`]-sample segments.
fn segment_spread(
    len: usize,
    statistic: impl Fn(std::ops::Range<usize>) -> Result<f64>,
) -> Result<(f64, f64)> {
    let values = (0..len / SEGMENT)
        .map(|s| statistic(s * SEGMENT..(s + 1) * SEGMENT))
        .collect::<Result<Vec<f64>>>()?;
    Ok(mean_std(&values))
}

fn e_res(clean: &[f64], estimate: &[f64]) -> Result<f64> {
    Ok(residual_error(clean, estimate)?)
}

/// Whole-run value and (mean, std) over segments of a moment statistic.
fn moment(
    data: &[f64],
    f: fn(&[f64]) -> Result<f64, crate::diagnostics::DiagnosticsError>,
) -> Result<[f64; 3]> {
    let whole = f(data)?;
    let (m, s) = segment_spread(data.len(), |r| Ok(f(&data[r])?))?;
    Ok([whole, m, s])
}

/// What one seed gives in one scenario.
#[derive(Debug, Clone, Default)]
struct SeedFigures {
    outliers: f64,
    /// Literal start x̂₀ = 0, P₀ = 0.
    e_skf: f64,
    e_rskf: f64,
    /// rsKF error over the first 100 samples' share of E_res (literal start).
    e_rskf_first_100: f64,
    /// Filters started at the median of the first measurements.
    e_skf_robust: f64,
    e_rskf_robust: f64,
    /// rsKF with x̂₀ = 0, P₀ = 0.5.
    e_rskf_prior: f64,
    /// rsKF on the same noise without outliers (literal start).
    e_rskf_no_outliers: f64,
    /// (mean, std) over segments: sKF, rsKF (both started at the median).
    seg_e_skf: (f64, f64),
    seg_e_rskf: (f64, f64),
    /// (mean, std) over segments of the rsKF started at x̂₀ = 0.
    seg_e_rskf_literal: (f64, f64),
    /// [whole, segment mean, segment std] of kurtosis / skewness: noisy cosine without
    /// outliers, rsKF, sKF (robust start), measured.
    kurtosis: [[f64; 3]; 4],
    skewness: [[f64; 3]; 4],
    /// Grubbs on the measured signal.
    grubbs_mean: f64,
    grubbs_std: f64,
    grubbs_critical: f64,
    /// Samples with |y − ȳ|/s > G_crit with one mean and s (paper 000 eq. 36 on every sample).
    grubbs_single_pass: f64,
    /// Iterated test: rejected samples, and how many of them are true outliers.
    grubbs_iterative: f64,
    grubbs_iterative_true: f64,
}

fn seed_figures(system: &System, seed: u32) -> Result<SeedFigures> {
    let seed_value = seed.into();
    let (literal, _) = Signals::run(system, &[("sensor.seed", seed_value)])?;
    let mut start: Vec<f64> = literal.measured[..START_WINDOW].to_vec();
    start.sort_by(f64::total_cmp);
    let x0 = start[START_WINDOW / 2];
    let (robust, _) = Signals::run(
        system,
        &[
            ("sensor.seed", seed_value),
            ("skf.x0[1]", x0.into()),
            ("rskf.x0[1]", x0.into()),
        ],
    )?;
    let (prior, _) = Signals::run(
        system,
        &[
            ("sensor.seed", seed_value),
            ("rskf.P0[1,1]", PRIOR_VARIANCE.into()),
        ],
    )?;
    // Same noise stream, no outliers: the Sensor draws noise and outliers from separate
    // streams, so ε = 0 leaves the noise sample for sample the same.
    let (no_outliers, _) = Signals::run(
        system,
        &[
            ("sensor.seed", seed_value),
            ("sensor.epsilon[1]", 0.0.into()),
        ],
    )?;
    let noisy_clean = &no_outliers.measured;

    let first_100 = e_res(&literal.clean[..100], &literal.rskf[..100])? * 100.0 / SAMPLES as f64;
    let seg_e = |s: &Signals, estimate: &[f64]| {
        segment_spread(SAMPLES, |r| e_res(&s.clean[r.clone()], &estimate[r]))
    };
    let moments = |f| -> Result<[[f64; 3]; 4]> {
        Ok([
            moment(noisy_clean, f)?,
            moment(&robust.rskf, f)?,
            moment(&robust.skf, f)?,
            moment(&literal.measured, f)?,
        ])
    };

    let y = &literal.measured;
    let grubbs_mean = mean(y)?;
    let grubbs_std = std_dev(y)?;
    let grubbs_critical = grubbs_critical_value(y.len(), ALPHA)?;
    let single = y
        .iter()
        .filter(|v| (*v - grubbs_mean).abs() / grubbs_std > grubbs_critical)
        .count();
    let rejected = grubbs_iterative(y, ALPHA)?;
    let rejected_true = rejected.iter().filter(|i| literal.outlier[**i]).count();

    Ok(SeedFigures {
        outliers: literal.outlier.iter().filter(|o| **o).count() as f64,
        e_skf: e_res(&literal.clean, &literal.skf)?,
        e_rskf: e_res(&literal.clean, &literal.rskf)?,
        e_rskf_first_100: first_100,
        e_skf_robust: e_res(&robust.clean, &robust.skf)?,
        e_rskf_robust: e_res(&robust.clean, &robust.rskf)?,
        e_rskf_prior: e_res(&prior.clean, &prior.rskf)?,
        e_rskf_no_outliers: e_res(&no_outliers.clean, &no_outliers.rskf)?,
        seg_e_skf: seg_e(&robust, &robust.skf)?,
        seg_e_rskf: seg_e(&robust, &robust.rskf)?,
        seg_e_rskf_literal: seg_e(&literal, &literal.rskf)?,
        kurtosis: moments(excess_kurtosis)?,
        skewness: moments(skewness)?,
        grubbs_mean,
        grubbs_std,
        grubbs_critical,
        grubbs_single_pass: single as f64,
        grubbs_iterative: rejected.len() as f64,
        grubbs_iterative_true: rejected_true as f64,
    })
}

/// Mean ± std over seeds of one figure.
fn over_seeds(results: &[SeedFigures], f: impl Fn(&SeedFigures) -> f64) -> (f64, f64) {
    mean_std_of(results, f)
}

/// A figure whose "±" is a within-run spread: the seeds' mean of the segment mean and of the
/// segment std.
fn segments(results: &[SeedFigures], f: impl Fn(&SeedFigures) -> (f64, f64)) -> (f64, f64) {
    (
        mean_std_of(results, |r| f(r).0).0,
        mean_std_of(results, |r| f(r).1).0,
    )
}

/// Measured samples (grey, outliers red), the clean cosine and both filters' estimates
/// (papers 000 Figs 3 and 5, 001 Figs 3–4).
fn signals_png(ctx: &ExperimentContext, file: &str, title: &str, s: &Signals) -> Result<()> {
    let k: Vec<f64> = (0..SAMPLES).map(|k| k as f64).collect();
    let [measured, outliers] = measured_lines("measured", &k, &s.measured, |i| s.outlier[i]);
    let panel = Panel {
        label: "y (noisy cosine)".into(),
        lines: vec![
            measured,
            outliers,
            Line::new("clean cosine", k.clone(), s.clean.clone()).colour(RGBColor(0, 0, 0)),
            Line::new("sKF", k.clone(), s.skf.clone()).colour(RGBColor(230, 120, 0)),
            Line::new("rsKF", k.clone(), s.rskf.clone()).colour(RGBColor(30, 80, 200)),
        ],
    };
    panels_png(
        &ctx.out_dir.join(file),
        title,
        "sample k (Tₛ = 0.1 s)",
        &[panel],
    )
}

/// Both scenarios: the shown seed's CSV and plots, and the Monte-Carlo figures.
struct Scenario {
    results: Vec<SeedFigures>,
    shown: Signals,
}

fn scenario(ctx: &ExperimentContext, file: &str, label: &str) -> Result<Scenario> {
    let system = ctx.system("cosine_outliers", file)?;
    let results = ctx.for_each_seed(&ctx.seed_list(), |seed| seed_figures(&system, seed))?;
    let (shown, series) = Signals::run(&system, &[("sensor.seed", SHOWN_SEED.into())])?;
    write_csv(
        &series,
        &ctx.out_dir.join(format!("{label}_seed{SHOWN_SEED}.csv")),
    )?;
    Ok(Scenario { results, shown })
}

/// The figures [`run`] writes, with their captions.
const FIGURES: [(&str, &str); 3] = [
    ("paper000_signals.png", "Paper 000 scenario: measurements (outliers red), clean cosine, sKF and rsKF (paper 000 Figs 3 and 5)"),
    ("paper000_histogram.png", "Histogram of the measured signal with the mean ± 2σ band (paper 000 Fig. 4)"),
    ("paper001_signals.png", "Paper 001 scenario: outliers in the first 500 samples only (paper 001 Figs 3–4)"),
];

/// Runs `examples/cosine_outliers/paper000.toml` and `paper001.toml`.
pub fn run(ctx: &ExperimentContext) -> Result<Report> {
    let p0 = scenario(ctx, "paper000.toml", "paper000")?;
    let p1 = scenario(ctx, "paper001.toml", "paper001")?;
    let histogram = figures(ctx, &p0, &p1)?;
    let (r0, r1) = (&p0.results, &p1.results);
    let mut rows = paper000_rows(r0)?;
    rows.extend(paper001_rows(r1));
    rows.extend(moment_rows(r1));
    let notes = notes(r0, r1, &histogram);
    Ok(Report {
        title: "Cosine with outliers: sKF vs rsKF (paper 000 §VII-A, paper 001 §5)".into(),
        setup: "SignalSource (cosine, period 250 samples) → Sensor (noise variance 0.01, ε-contaminated outliers U(−4.8, 4.8)) → KalmanFilter and RobustKalmanFilter FMUs side by side (scalar, A = C = 1, Q = R = 1e-4, Huber c = 1.645), 1000 samples at 0.1 s, run by the master. E_res = (1/N)‖y_clean − x̂ₖ|ₖ‖² over all 1000 samples. Systems: examples/cosine_outliers/paper000.toml (outliers anywhere, ε = 0.05) and paper001.toml (outliers only in the first 500 samples, ε = 0.10 there).".into(),
        rows,
        figures: FIGURES
            .iter()
            .map(|(file, caption)| (file.to_string(), caption.to_string()))
            .collect(),
        notes,
        figures_of_merit: vec![
            ("e_res_skf_000".into(), over_seeds(r0, |r| r.e_skf).0),
            ("e_res_rskf_000".into(), over_seeds(r0, |r| r.e_rskf).0),
            ("e_res_rskf_000_std".into(), over_seeds(r0, |r| r.e_rskf).1),
            ("e_res_skf_001".into(), over_seeds(r1, |r| r.e_skf).0),
            ("e_res_rskf_001_literal".into(), over_seeds(r1, |r| r.e_rskf).0),
            ("e_res_rskf_001".into(), over_seeds(r1, |r| r.e_rskf_robust).0),
            ("e_res_rskf_001_no_outliers".into(), over_seeds(r1, |r| r.e_rskf_no_outliers).0),
            ("grubbs_critical".into(), r0.first().map_or(f64::NAN, |r| r.grubbs_critical)),
            ("grubbs_single_pass".into(), over_seeds(r0, |r| r.grubbs_single_pass).0),
            ("outliers_000".into(), over_seeds(r0, |r| r.outliers).0),
            ("outliers_001".into(), over_seeds(r1, |r| r.outliers).0),
            ("kurtosis_skf_001_segments".into(), segments(r1, |r| (r.kurtosis[2][1], r.kurtosis[2][2])).0),
            ("kurtosis_rskf_001_segments".into(), segments(r1, |r| (r.kurtosis[1][1], r.kurtosis[1][2])).0),
        ],
    })
}

/// The histogram of the shown run: its mean ± 2σ band and how many samples lie outside.
struct HistogramFacts {
    band: (f64, f64),
    outside: usize,
}

/// The signal plots of both scenarios and the histogram of paper 000's shown run.
fn figures(ctx: &ExperimentContext, p0: &Scenario, p1: &Scenario) -> Result<HistogramFacts> {
    signals_png(
        ctx,
        "paper000_signals.png",
        &format!(
            "Paper 000 scenario, seed {SHOWN_SEED}: measurements, sKF and rsKF (both started at 0)"
        ),
        &p0.shown,
    )?;
    signals_png(
        ctx,
        "paper001_signals.png",
        &format!("Paper 001 scenario (outliers in the first 500 samples), seed {SHOWN_SEED}"),
        &p1.shown,
    )?;
    let measured = &p0.shown.measured;
    let (edges, counts) = histogram(measured, 60)?;
    let band = two_sigma_band(measured)?;
    crate::plot::histogram_png(
        &ctx.out_dir.join("paper000_histogram.png"),
        &format!("Measured noisy cosine with outliers, seed {SHOWN_SEED}: histogram and mean ± 2σ"),
        "measured y",
        (&edges, &counts),
        band,
    )?;
    let outside = measured
        .iter()
        .filter(|v| **v < band.0 || **v > band.1)
        .count();
    Ok(HistogramFacts { band, outside })
}

/// Paper 000's scenario: outliers, E_res of both filters, Grubbs.
fn paper000_rows(r0: &[SeedFigures]) -> Result<Vec<Row>> {
    let e_skf0 = over_seeds(r0, |r| r.e_skf);
    let e_rskf0 = over_seeds(r0, |r| r.e_rskf);
    let e_rskf0_robust = over_seeds(r0, |r| r.e_rskf_robust);
    let critical = r0.first().map(|r| r.grubbs_critical).unwrap_or(f64::NAN);
    let critical_exact = grubbs_critical_value(SAMPLES, ALPHA)?;
    let single = over_seeds(r0, |r| r.grubbs_single_pass);
    let shown_grubbs = r0.first().cloned().unwrap_or_default();
    let mean_of = |f: fn(&SeedFigures) -> f64, digits| pm(over_seeds(r0, f), digits);
    Ok(vec![
        Row::info(
            "**Paper 000 scenario** (5 % outliers anywhere): outliers per run",
            "50",
            pm(over_seeds(r0, |r| r.outliers), 1),
        ),
        Row::goal(
            "E_res sKF",
            "0.1782 ± 0.0284",
            pm(e_skf0, 4),
            "0.15 … 0.21 (reference 0.179 ± 0.023)",
            (0.15..=0.21).contains(&e_skf0.0),
        ),
        Row::goal(
            "E_res rsKF (x̂₀ = 0, P₀ = 0, as the paper)",
            "0.0124 ± 4.88e-4",
            format!("{:.5} ± {:.2e}", e_rskf0.0, e_rskf0.1),
            "≤ 0.0124",
            e_rskf0.0 <= 0.0124,
        ),
        Row::info(
            "E_res rsKF started at the median of y₀…y₄",
            "—",
            format!("{:.5} ± {:.2e}", e_rskf0_robust.0, e_rskf0_robust.1),
        ),
        Row::goal(
            "Grubbs critical value, N = 1000, α = 0.05",
            "4.04",
            format!("{critical:.4}"),
            "4.0400",
            (critical_exact - 4.04).abs() < 5e-5 && critical == critical_exact,
        ),
        Row::info(
            "Grubbs: mean, std of the measured signal",
            "−0.0945, 1.388",
            [mean_of(|r| r.grubbs_mean, 4), mean_of(|r| r.grubbs_std, 3)].join(", "),
        ),
        Row::info(
            "Grubbs: samples rejected (one pass, eq. 36 on every sample) / outliers",
            "10 / 50",
            format!(
                "{} / {} (seed {SHOWN_SEED}: {} / {})",
                pm(single, 1),
                pm(over_seeds(r0, |r| r.outliers), 1),
                shown_grubbs.grubbs_single_pass,
                shown_grubbs.outliers
            ),
        ),
        Row::info(
            "Grubbs iterated (remove, retest): rejected, of which true outliers",
            "—",
            [
                mean_of(|r| r.grubbs_iterative, 1),
                mean_of(|r| r.grubbs_iterative_true, 1),
            ]
            .join(", "),
        ),
    ])
}

/// Paper 001's scenario: E_res over seeds and over segments, the start-up transient.
fn paper001_rows(r1: &[SeedFigures]) -> Vec<Row> {
    let e_skf1 = over_seeds(r1, |r| r.e_skf);
    let e_rskf1 = over_seeds(r1, |r| r.e_rskf);
    let e_rskf1_robust = over_seeds(r1, |r| r.e_rskf_robust);
    vec![
        Row::info(
            "**Paper 001 scenario** (50 outliers on average, all in the first 500 samples): outliers per run",
            "50",
            pm(over_seeds(r1, |r| r.outliers), 1),
        ),
        Row::info(
            "E_res sKF (spread over seeds)",
            "0.1728 ± 0.1945",
            pm(e_skf1, 4),
        ),
        Row::info(
            &format!("E_res sKF (spread over {SEGMENT}-sample segments)"),
            "0.1728 ± 0.1945",
            pm(segments(r1, |r| r.seg_e_skf), 4),
        ),
        Row::info(
            "E_res sKF started at the median of y₀…y₄",
            "—",
            pm(over_seeds(r1, |r| r.e_skf_robust), 4),
        ),
        Row::info(
            "E_res rsKF, x̂₀ = 0, P₀ = 0 (start-up transient)",
            "0.0087 ± 0.0023",
            format!(
                "{} (first 100 samples contribute {:.4})",
                pm(e_rskf1, 4),
                over_seeds(r1, |r| r.e_rskf_first_100).0
            ),
        ),
        Row::goal(
            "E_res rsKF started at the median of y₀…y₄ (spread over seeds)",
            "0.0087 ± 0.0023",
            pm(e_rskf1_robust, 4),
            "≤ 0.0087",
            e_rskf1_robust.0 <= 0.0087,
        ),
        Row::info(
            &format!("E_res rsKF, same start (spread over {SEGMENT}-sample segments)"),
            "0.0087 ± 0.0023",
            pm(segments(r1, |r| r.seg_e_rskf), 4),
        ),
        Row::info(
            "E_res rsKF, x̂₀ = 0, P₀ = 0.5 (causal: prior variance of a unit cosine)",
            "—",
            format!(
                "{} (median {:.4})",
                pm(over_seeds(r1, |r| r.e_rskf_prior), 4),
                median(&r1.iter().map(|r| r.e_rskf_prior).collect::<Vec<_>>())
            ),
        ),
        Row::info(
            "E_res rsKF, x̂₀ = 0, same noise without any outlier",
            "—",
            pm(over_seeds(r1, |r| r.e_rskf_no_outliers), 4),
        ),
    ]
}

/// Kurtosis and skewness (paper 001 eqs 18–19) of the clean signal, both filters and the
/// measurements, over segments and whole runs.
fn moment_rows(r1: &[SeedFigures]) -> Vec<Row> {
    let mut rows = Vec::new();
    let names = ["clean (noise, no outliers)", "rsKF", "sKF", "measured"];
    let paper_kurtosis = [
        "−0.7765 ± 0.5423",
        "−0.8586 ± 0.5318",
        "5.5647 ± 12.0013",
        "—",
    ];
    let paper_skewness = ["−0.007 ± 0.46", "−0.0048 ± 0.5722", "0.0199 ± 1.5275", "—"];
    for (what, paper, pick) in [
        ("kurtosis", paper_kurtosis, 0usize),
        ("skewness", paper_skewness, 1usize),
    ] {
        for (i, name) in names.iter().enumerate() {
            let get = |r: &SeedFigures| {
                if pick == 0 {
                    r.kurtosis[i]
                } else {
                    r.skewness[i]
                }
            };
            rows.push(Row::info(
                &format!("{what}, {name}"),
                paper[i],
                format!(
                    "{} ({SEGMENT}-sample segments); whole run {}",
                    pm(segments(r1, |r| (get(r)[1], get(r)[2])), 3),
                    pm(over_seeds(r1, |r| get(r)[0]), 3)
                ),
            ));
        }
    }

    rows
}

/// The notes: the outlier generator, the start-up transient, segments, Grubbs, histogram.
fn notes(r0: &[SeedFigures], r1: &[SeedFigures], histogram: &HistogramFacts) -> Vec<String> {
    let n_seeds = r0.len();
    let e_rskf1 = over_seeds(r1, |r| r.e_rskf);
    let single = over_seeds(r0, |r| r.grubbs_single_pass);
    let (band, outside) = (histogram.band, histogram.outside);
    vec![
        format!("{n_seeds} seeds (Sensor `seed` 1…{n_seeds}) per scenario; mean ± sample std over seeds unless a row says segments. Run time is in the experiments log line."),
        "Generator: the Sensor FMU's ε-contamination — each sample independently carries an outlier with probability ε, of magnitude U[0, 4.8] and random sign, i.e. U(−4.8, 4.8). docs/experiments.md §4's generator places exactly 50 outliers at distinct indices; here the count is Binomial(1000, 0.05), 50 ± 6.9, which widens the spread of the sKF's E_res but leaves the means where they were (an independent numpy run with exactly 50: sKF 0.179 ± 0.023, rsKF 0.0121 ± 0.0006). Paper 001: \"5 % of all the data, placed in the first 500\" — ε = 0.10 inside the Sensor's window t < 50 s; with ε = 0.05 there (25 outliers) the sKF's E_res halves to ≈ 0.09, far from the paper's 0.1728.".into(),
        format!("Paper 001's rsKF figure 0.0087 is not reachable with the literal start: its E_res is dominated by the start-up, not by outliers. With x̂₀ = 0, P₀ = 0 under y₀ ≈ 1 the rsKF sees the true signal as an outlier (R = 1e-4 while the noise variance is 0.01, so Huber weights are below 1 almost everywhere and the gain is small) and needs ≈ 100 samples to reach the cosine: those samples alone contribute {:.4} of the {:.4}; without any outlier at all the rsKF still scores {:.4}. Paper 001's ± 0.0023 is a spread over segments, like its sKF figure; with that transient the rsKF's spread over {SEGMENT}-sample segments is {:.4} ± {:.4}, so the paper's run had none. We therefore start both filters at a robust estimate of the initial level, the median of the first {START_WINDOW} measurements (0.4 s; the cosine moves by 0.5 % over them; the median ignores up to two outliers among them), keeping P₀ = 0, Q, R and the scoring of all 1000 samples unchanged. A causal alternative, the prior x̂₀ = 0 with variance P₀ = 0.5 (the mean square of a unit cosine), is shown too: it follows y₀ and so fails when y₀ itself is an outlier (10 % of runs in this scenario), hence its larger spread.", over_seeds(r1, |r| r.e_rskf_first_100).0, e_rskf1.0, over_seeds(r1, |r| r.e_rskf_no_outliers).0, segments(r1, |r| r.seg_e_rskf_literal).0, segments(r1, |r| r.seg_e_rskf_literal).1),
        format!("Paper 001's spreads of E_res, kurtosis and skewness are read as spreads over segments of one run (docs/experiments.md §4); {SEGMENT}-sample segments reproduce its clean and rsKF kurtosis (100-sample ones give ≈ −0.89 ± 0.36 for the clean signal). \"Clean\" is the noisy cosine without outliers (the same seed with ε = 0: the Sensor draws noise and outliers from separate streams), as paper 001's \"datos limpios\". Moments of the filters are those of the median-started runs; the noise-free cosine has kurtosis −1.5 over whole periods."),
        format!("Grubbs (paper 000 Table 2) runs on the measured signal: applying eq. 36 with one mean and std to every sample rejects {:.1} ± {:.1} samples of ≈ 50 outliers, the paper's 10 of 50. Our mean and std of that signal ({:.4}, {:.3}) differ from the paper's (−0.0945, 1.388): with the paper's std the threshold 4.04·1.388 = 5.6 would exceed almost every |y| ≤ 5.8 and reject none, so its table's std is not the one its test used. Critical value: ((N−1)/√N)·√(t²/(N−2+t²)), t the Student-t quantile at α/(2N), N − 2 dof (the paper prints N/√N). The iterated test (remove the suspect, recompute, retest) finds most outliers.", single.0, single.1, over_seeds(r0, |r| r.grubbs_mean).0, over_seeds(r0, |r| r.grubbs_std).0),
        format!("Histogram (paper 000 Fig. 4), seed {SHOWN_SEED}: {outside} samples lie outside mean ± 2σ = [{:.3}, {:.3}]: the outliers and the cosine's extremes.", band.0, band.1),
        format!("CSV of the shown runs: paper000_seed{SHOWN_SEED}.csv, paper001_seed{SHOWN_SEED}.csv (time, measured, clean, outlier flag, sKF and rsKF estimates, rsKF weight; the estimates lag one row, see the module doc)."),
    ]
}
