//! `DualKalmanFilter.fmu` (DKF, docs/estimators.md §2.9; papers 000 §VI, 001 §2, after Haykin,
//! *Kalman Filtering and Neural Networks*, ch. 5) and `DkfRsKf.fmu` (docs/estimators.md §2.10;
//! paper 001 Fig. 2: an rsKF cleans the measured outputs, the DKF identifies from them).
//!
//! Each `fmi2DoStep` with inputs u_k, y_k runs, in sequence,
//!
//! ```text
//! (DkfRsKf only) rsKF random walk per channel, started at C x0: y_clean = x̂_rsKF (weights w_j)
//! state filter with Θ̂_{k−1} = [Â B̂; Ĉ D̂]:  x̂_k, ŷ_k = Ĉ x̂_k + D̂ u_k
//! parameter filter on the previous sample:  Θ_k = Θ_{k−1} + r_k,  Y = Θ Φ + V,
//!     Y = [x̂_k; y_{k−1}], Φ = [x̂_{k−1}; u_{k−1}], Cov r = q_theta·I, Cov V = r_theta·I
//! ```
//!
//! (see [`spurio::estimation::DualKalmanFilter`] for the exact sequence). Every row of Θ
//! shares Φ, so rows with equal settings share one (n+m)×(n+m) covariance.
//!
//! Missing samples (docs/estimators.md, "Missing samples"): `y_valid[j]` = false hands the
//! filter y_j = NaN: the state filter corrects with the present channels, Θ̂ is held while
//! its variances walk; the DkfRsKf's cleaner predicts that channel (w_j = 0) and the DKF gets
//! it as missing.
//!
//! Configuration `n`, `m` (may be 0), `p`. Parameters: the initial model `A`, `B`, `C`, `D`,
//! the state filter's `Q`, `R`, `P0`, `x0`, the parameter filter's scalars `q_theta`
//! (random-walk variance of every entry of Θ), `p0_theta` (initial variance of every entry)
//! and `r_theta` (measurement variance of every row, papers: 0.5), and
//! `fix_output_matrices` (C and D known: their rows of Θ never change; default true, which
//! removes the similarity-transform ambiguity of identifying from outputs).
//!
//! Bounded adaptation (docs/estimators.md §2.9; off by default, the papers' filter):
//! `excitation_min` > 0 freezes Θ̂ and its covariance while the windowed excitation
//! ε = λ_min(M), M_k = λ M_{k−1} + (1 − λ) Φ Φᵀ, λ = 1 − 1/`excitation_window`, is below it;
//! `pmax_theta` > 0 bounds the variances the random walk can raise. Outputs `excitation` (ε)
//! and `adapting`.
//!
//! Identifying A and B (docs/estimators.md §2.9; off by default): `known_rows` = k fixes rows
//! 1..k of [A B] at their initial values (zero Q_θ and Σ₀ there); `output_error` = true makes
//! the parameter filter a dual EKF on the free entries ϑ of [A B]: S⁻ = Â S + ∂(Â x̂ + B̂ u)/∂ϑ,
//! H = Ĉ S⁻, ϑ ← ϑ + G e_k with the state filter's innovation e_k, S = (I − K Ĉ) S⁻.

use crate::filtered::{FilterFamily, Filtered, SignalBlocks, Signals};
use crate::model::{
    add_estimates, add_influence, add_inputs, model_info, read_influence, Defaults, Dimensions,
    ModelBlocks,
};
use nalgebra::DVector;
use spurio::estimation::{
    AdaptationBounds, DkfRsKf, DualKalmanConfig, DualKalmanFilter, ParameterMeasurement,
    RobustKalmanFilter, StateEstimator,
};
use spurio_export::{Cause, Config, Context, Failure, ModelInfo, Values, Variable, VariableTable};
use spurio_fmu_common::estimator::{
    add_tuning, add_validity, copy_inputs, count, error, read_inputs, EstimatorFmu,
};
use spurio_fmu_common::structured::{add_matrix, add_vector, Block};

/// Value references of the cleaner's parameters (DkfRsKf).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CleanerBlocks {
    pub w: Block,
    pub y_clean: Block,
    pub q_clean: usize,
    pub r_clean: usize,
    pub p0_clean: usize,
    pub psi: (usize, usize),
    /// The input-driven cleaner (configuration key `cleaner_input` = 1): its inputs `v[j]`
    /// and per-channel parameters `a_clean[j]`, `b_clean[j]`.
    pub driven: Option<DrivenCleanerBlocks>,
}

/// Value references of the input-driven cleaner's inputs and parameters (docs/estimators.md
/// §2.10): x_j(k) = a_clean[j] x_j(k−1) + b_clean[j] v_j(k−1), y_j = x_j.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DrivenCleanerBlocks {
    pub v: Block,
    pub a_clean: Block,
    pub b_clean: Block,
}

/// Value references of a `DualKalmanFilter` / `DkfRsKf` variant.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DualLayout {
    pub signals: SignalBlocks,
    pub a_hat: Block,
    pub b_hat: Block,
    pub c_hat: Block,
    pub d_hat: Block,
    pub model: ModelBlocks,
    pub q_theta: usize,
    pub p0_theta: usize,
    pub r_theta: usize,
    pub fix_output_matrices: usize,
    pub cleaner: Option<CleanerBlocks>,
    pub bounds: BoundBlocks,
}

impl Signals for DualLayout {
    fn signals(&self) -> &SignalBlocks {
        &self.signals
    }
}

/// Value references of the bounded adaptation's parameters and outputs (docs/estimators.md
/// §2.9, "Bounded adaptation").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BoundBlocks {
    pub excitation_window: usize,
    pub excitation_min: usize,
    pub pmax_theta: usize,
    pub excitation: usize,
    pub adapting: usize,
    /// Structural knowledge (docs/estimators.md §2.9, "Identifying A and B").
    pub known_rows: usize,
    pub output_error: usize,
}

fn add_bounds(t: &mut VariableTable, n: usize) -> BoundBlocks {
    let excitation_window = t.add(
        Variable::parameter("excitation_window", 200.0)
            .min(1.0)
            .max(1e9)
            .describe("Bounded adaptation: effective window N_w (samples) of the excitation measure ε = λ_min(M), M = λM + (1−λ)ΦΦᵀ, λ = 1 − 1/N_w"),
    );
    let excitation_min = add_tuning(t, "excitation_min", 0.0, "Bounded adaptation: the parameter filter runs only while ε >= excitation_min (regressor units²); below it Θ and its covariance are frozen. 0 = always (papers)");
    let pmax_theta = add_tuning(t, "pmax_theta", 0.0, "Bounded adaptation: the random walk raises a variance of Θ at most to pmax_theta. 0 = no bound (papers)");
    let excitation =
        t.add(Variable::discrete_output("excitation").describe(
            "Excitation measure ε = λ_min(M) of the last step (0 while excitation_min = 0)",
        ));
    let adapting =
        t.add(Variable::boolean_output("adapting").describe(
            "Whether the last step updated Θ (false while frozen by the excitation gate)",
        ));
    let known_rows = t.add(
        Variable::integer_parameter("known_rows", 0)
            .min(0.0)
            .max(n as f64)
            .describe("Structural knowledge: rows 1..known_rows of [A B] are known (their initial values) and never change; 2 for the crane's kinematic rows with C = [I 0] makes A and B unique. 0 = none (papers)"),
    );
    let output_error = t.add(
        Variable::boolean_parameter("output_error", false)
            .describe("Parameter filter measurement: false = Y = [x̂_k; y_{k−1}] row by row (papers); true = the state filter's innovation against its recurrent sensitivity to the free entries of [A B] (dual EKF); needs fix_output_matrices"),
    );
    BoundBlocks {
        excitation_window,
        excitation_min,
        pmax_theta,
        excitation,
        adapting,
        known_rows,
        output_error,
    }
}

fn interface(config: &Config, cleaned: bool) -> Result<(DualLayout, ModelInfo), Cause> {
    let dims = Dimensions::from_config(config, 4, 1, 2)?;
    let Dimensions { n, m, p } = dims;
    let cleaner_input = if cleaned {
        count(config, "cleaner_input", 0, 0)?
    } else {
        0
    };
    let driven = cleaner_input > 0;
    if cleaner_input > 1 {
        return Err(
            "variant.cfg: `cleaner_input` must be 0 (random walk) or 1 (driven by v[j])".into(),
        );
    }
    let mut t = VariableTable::new();
    let (u, y) = add_inputs(
        &mut t,
        dims,
        if cleaned {
            "Measured output y_k, possibly with outliers (cleaned by the rsKF first)"
        } else {
            "Measured output y_k (sampled at the start of the step)"
        },
    );
    let v = driven.then(|| {
        add_vector(&mut t, "v", p, |name, _| {
            Variable::input(name, 0.0).describe("Input v_j of the rsKF cleaner of channel j: x_j(k) = a_clean[j] x_j(k−1) + b_clean[j] v_j(k−1) (sampled at the start of the step)")
        })
    });
    let (x_hat, y_hat) = add_estimates(&mut t, dims);
    let hat = |t: &mut VariableTable, name: &str, rows: usize, cols: usize, what: &str| {
        add_matrix(t, name, rows, cols, |element, _, _| {
            Variable::discrete_output(element).describe(what)
        })
    };
    let a_hat = hat(&mut t, "A_hat", n, n, "Estimated state matrix Â");
    let b_hat = hat(&mut t, "B_hat", n, m, "Estimated input matrix B̂");
    let c_hat = hat(&mut t, "C_hat", p, n, "Estimated output matrix Ĉ");
    let d_hat = hat(&mut t, "D_hat", p, m, "Estimated feedthrough matrix D̂");
    let cleaner_outputs = cleaned.then(|| {
        let w = add_vector(&mut t, "w", p, |name, _| {
            Variable::discrete_output(name).describe(
                "rsKF weight of channel j in the last sample (1 = trusted, → 0 = outlier)",
            )
        });
        let y_clean = add_vector(&mut t, "y_clean", p, |name, _| {
            Variable::discrete_output(name)
                .describe("Cleaned output (rsKF estimate) fed to the DKF")
        });
        (w, y_clean)
    });
    let model = ModelBlocks::add(
        &mut t,
        dims,
        Defaults {
            q: 1e-4,
            r: 1e-2,
            p0: 1.0,
        },
        "Initial ",
    );
    let q_theta = add_tuning(
        &mut t,
        "q_theta",
        1e-6,
        "Parameter filter: random-walk variance Q_θ of every entry of Θ = [A B; C D]",
    );
    let p0_theta = add_tuning(
        &mut t,
        "p0_theta",
        1.0,
        "Parameter filter: initial variance of every entry of Θ",
    );
    let r_theta = add_tuning(
        &mut t,
        "r_theta",
        0.5,
        "Parameter filter: measurement variance R_θ of every row of Y = [x⁺; y] (papers: 0.5)",
    );
    let fix_output_matrices = t.add(
        Variable::boolean_parameter("fix_output_matrices", true)
            .describe("C and D are known: Ĉ = C, D̂ = D forever (removes the similarity ambiguity)"),
    );
    let cleaner = match cleaner_outputs {
        Some((w, y_clean)) => {
            let q_clean = add_tuning(
                &mut t,
                "q_clean",
                1e-3,
                "rsKF cleaner (random walk per channel): process variance",
            );
            let r_clean = add_tuning(
                &mut t,
                "r_clean",
                1e-2,
                "rsKF cleaner: measurement noise variance of each channel",
            );
            let p0_clean = add_tuning(&mut t, "p0_clean", 1.0, "rsKF cleaner: initial variance (its estimate starts at C·x0, the DKF's initial output)");
            let driven = v.map(|v| DrivenCleanerBlocks {
                v,
                a_clean: add_vector(&mut t, "a_clean", p, |name, _| {
                    Variable::parameter(name, 1.0).describe("rsKF cleaner of channel j: a_j of x_j(k) = a_j x_j(k−1) + b_j v_j(k−1) (1 with b_j = 0: the random walk)")
                }),
                b_clean: add_vector(&mut t, "b_clean", p, |name, _| {
                    Variable::parameter(name, 0.0).describe("rsKF cleaner of channel j: b_j of x_j(k) = a_j x_j(k−1) + b_j v_j(k−1) (0: v_j unused)")
                }),
            });
            let psi = add_influence(&mut t);
            Some(CleanerBlocks {
                w,
                y_clean,
                q_clean,
                r_clean,
                p0_clean,
                psi,
                driven,
            })
        }
        None => None,
    };
    let bounds = add_bounds(&mut t, n);
    let (id, description) = if cleaned {
        (
            "DkfRsKf",
            "DKF-rsKF (paper 001 Fig. 2): robust Kalman filter cleaning the outputs, then a dual Kalman filter estimating states and [A B; C D]",
        )
    } else {
        (
            "DualKalmanFilter",
            "Dual Kalman filter (DKF, Haykin ch. 5): states and the model matrices [A B; C D], papers 000/001",
        )
    };
    let y_valid = add_validity(&mut t, "y", p);
    let info = model_info(config, (id, description), t, 10.0, 0.05);
    Ok((
        DualLayout {
            signals: SignalBlocks {
                dims,
                u,
                y,
                y_valid,
                x_hat,
                y_hat,
            },
            a_hat,
            b_hat,
            c_hat,
            d_hat,
            model,
            q_theta,
            p0_theta,
            r_theta,
            fix_output_matrices,
            cleaner,
            bounds,
        },
        info,
    ))
}

fn scalar(values: &Values, index: usize, name: &str, positive: bool) -> Result<f64, Failure> {
    let v = values.real(index);
    let ok = v.is_finite() && if positive { v > 0.0 } else { v >= 0.0 };
    if ok {
        Ok(v)
    } else {
        Err(Failure::error(format!(
            "parameter `{name}`: a variance must be finite and {}, got {v}",
            if positive { "> 0" } else { ">= 0" }
        )))
    }
}

/// The library names the initial matrices A0…D0; the FMU calls them A…D.
fn dual_error(e: spurio::estimation::EstimationError) -> Failure {
    let mut text = e.to_string();
    for name in ["A", "B", "C", "D"] {
        text = text.replace(
            &format!("parameter `{name}0`"),
            &format!("parameter `{name}` (initial {name})"),
        );
    }
    Failure::error(text)
}

fn build_dual(layout: &DualLayout, values: &Values) -> Result<DualKalmanFilter, Failure> {
    let q_theta = scalar(values, layout.q_theta, "q_theta", false)?;
    let p0_theta = scalar(values, layout.p0_theta, "p0_theta", false)?;
    let r_theta = scalar(values, layout.r_theta, "r_theta", true)?;
    let mut config = DualKalmanConfig::new(layout.model.read(values));
    config.parameter_q.fill(q_theta);
    config.parameter_p0.fill(p0_theta);
    config.parameter_r.fill(r_theta);
    if values.boolean(layout.fix_output_matrices) {
        config = config.fix_output_matrices();
    }
    let b = &layout.bounds;
    let known_rows = values.integer(b.known_rows);
    let n = layout.signals.dims.n;
    let known = usize::try_from(known_rows)
        .ok()
        .filter(|k| *k <= n)
        .ok_or_else(|| {
            Failure::error(format!(
                "parameter `known_rows`: must be between 0 and n = {n}, got {known_rows}"
            ))
        })?;
    config = config.fix_state_rows(&(0..known).collect::<Vec<_>>());
    if values.boolean(b.output_error) {
        config.measurement = ParameterMeasurement::OutputError;
    }
    let pmax_theta = scalar(values, b.pmax_theta, "pmax_theta", false)?;
    config.bounds = AdaptationBounds {
        excitation_window: values.real(b.excitation_window),
        excitation_min: values.real(b.excitation_min),
        max_variance: if pmax_theta == 0.0 {
            f64::INFINITY
        } else {
            pmax_theta
        },
    };
    DualKalmanFilter::new(config).map_err(dual_error)
}

/// Writes the `block.rows × block.cols` block of Θ̂ (stored by columns, `ld` rows) starting at
/// row `row0`, column `col0` into `out`, the block's row-major variables in the values. The
/// blocks of the packaged variants (n = 8, m = p = 2 and n = 4, m = 1, p = 2) take a copy of
/// fixed size.
fn write_theta_block(
    out: &mut [f64],
    block: &Block,
    theta: &[f64],
    ld: usize,
    (row0, col0): (usize, usize),
) {
    let start = row0 + col0 * ld;
    let shape = (block.rows, block.cols);
    match shape {
        (8, 8) => transpose::<8, 8>(out, shape, theta, ld, start),
        (8, 2) => transpose::<8, 2>(out, shape, theta, ld, start),
        (2, 8) => transpose::<2, 8>(out, shape, theta, ld, start),
        (2, 2) => transpose::<2, 2>(out, shape, theta, ld, start),
        (4, 4) => transpose::<4, 4>(out, shape, theta, ld, start),
        (4, 1) => transpose::<4, 1>(out, shape, theta, ld, start),
        (2, 4) => transpose::<2, 4>(out, shape, theta, ld, start),
        (2, 1) => transpose::<2, 1>(out, shape, theta, ld, start),
        _ => transpose::<0, 0>(out, shape, theta, ld, start),
    }
}

/// Copies the `rows × cols` matrix stored by columns (`ld` apart) from `theta[start]` into
/// `out` by rows; `R`, `C` > 0 are `rows`, `cols` known at compile time (0: at run time).
fn transpose<const R: usize, const C: usize>(
    out: &mut [f64],
    (rows, cols): (usize, usize),
    theta: &[f64],
    ld: usize,
    start: usize,
) {
    let (rows, cols) = if R == 0 { (rows, cols) } else { (R, C) };
    let Some(out) = out.get_mut(..rows * cols) else {
        return;
    };
    for j in 0..cols {
        let first = start + j * ld;
        let Some(column) = theta.get(first..first + rows) else {
            return;
        };
        for (i, &v) in column.iter().enumerate() {
            if let Some(slot) = out.get_mut(i * cols + j) {
                *slot = v;
            }
        }
    }
}

fn write_dual_outputs(l: &DualLayout, values: &mut Values, dual: &DualKalmanFilter) {
    let n = l.signals.dims.n;
    let theta = dual.theta();
    let (ld, data) = (theta.nrows(), theta.as_slice());
    let blocks = [
        (&l.a_hat, (0, 0)),
        (&l.b_hat, (0, n)),
        (&l.c_hat, (n, 0)),
        (&l.d_hat, (n, n)),
    ];
    // Â, B̂, Ĉ, D̂ follow one another in the variables: one slice of the values holds them.
    let span = l.a_hat.first..l.d_hat.indices().end;
    let first = span.start;
    match values.reals_mut(span) {
        Some(out) => {
            for (block, at) in blocks {
                let start = block.first.checked_sub(first).unwrap_or(usize::MAX);
                let slots = out.get_mut(start..start.saturating_add(block.rows * block.cols));
                if let Some(slots) = slots {
                    write_theta_block(slots, block, data, ld, at);
                }
            }
        }
        None => {
            for (block, at) in blocks {
                if let Some(slots) = values.reals_mut(block.indices()) {
                    write_theta_block(slots, block, data, ld, at);
                }
            }
        }
    }
    l.signals.x_hat.write_vector(values, dual.state());
    values.set_real(l.bounds.excitation, dual.excitation());
    values.set_boolean(l.bounds.adapting, dual.adapting());
}

fn write_initial_dual(l: &DualLayout, ctx: &mut Context, dual: &DualKalmanFilter) {
    write_dual_outputs(l, ctx.values, dual);
    let u = l.signals.u.vector(ctx.values);
    let y_hat = dual.c() * dual.state() + dual.d() * u;
    l.signals.y_hat.write_vector(ctx.values, &y_hat);
}

/// A dual filter behind a `DualKalmanFilter`-style FMU.
pub trait DualFilter: StateEstimator + Clone + std::fmt::Debug + 'static {
    /// Whether an rsKF cleans the outputs first: parameters `q_clean`…, outputs `w[j]`,
    /// `y_clean[j]`.
    const CLEANED: bool;
    /// Reads and checks the parameters, builds the filter.
    fn build(layout: &DualLayout, values: &Values) -> Result<Self, Failure>;
    /// The DKF (estimates of the state and of Θ).
    fn dual(&self) -> &DualKalmanFilter;
    /// Reads the cleaner's own inputs `v[j]` (input-driven cleaner) before a step.
    fn read_cleaner_input(
        &mut self,
        cleaner: &CleanerBlocks,
        values: &Values,
    ) -> Result<(), Failure> {
        let _ = (cleaner, values);
        Ok(())
    }
    /// Writes the cleaner's outputs, before the first step (`initial`) or after a step.
    fn write_cleaner(&self, cleaner: &CleanerBlocks, values: &mut Values, initial: bool) {
        let _ = (cleaner, values, initial);
    }
}

impl DualFilter for DualKalmanFilter {
    const CLEANED: bool = false;
    fn build(layout: &DualLayout, values: &Values) -> Result<Self, Failure> {
        build_dual(layout, values)
    }
    fn dual(&self) -> &DualKalmanFilter {
        self
    }
}

impl DualFilter for DkfRsKf {
    const CLEANED: bool = true;
    fn build(layout: &DualLayout, values: &Values) -> Result<Self, Failure> {
        let c = layout
            .cleaner
            .ok_or_else(|| Failure::error("DkfRsKf: the layout has no cleaner"))?;
        let q = scalar(values, c.q_clean, "q_clean", false)?;
        let r = scalar(values, c.r_clean, "r_clean", true)?;
        let p0 = scalar(values, c.p0_clean, "p0_clean", false)?;
        let psi = read_influence(values, c.psi)?;
        let dual = build_dual(layout, values)?;
        // The cleaner starts at the DKF's initial output ŷ₀ = C x̂₀ (0 with the default x0):
        // a robust filter started far from the signal trusts its first samples whatever
        // they are, so a known initial state must reach the cleaner too.
        let start = dual.c() * dual.state();
        // The random walk (a = 1, b = 0) unless the variant's cleaner is input-driven.
        let p = start.len();
        let (a, b) = match c.driven {
            Some(d) => (d.a_clean.vector(values), d.b_clean.vector(values)),
            None => (DVector::from_element(p, 1.0), DVector::zeros(p)),
        };
        // a, b hold one finite entry per channel (the layout's vectors; values set are
        // finite), so the library's checks of them cannot fail here
        let cleaner =
            RobustKalmanFilter::first_order_from(start, (&a, &b), q, r, p0, psi).map_err(error)?;
        if c.driven.is_some() {
            DkfRsKf::with_cleaner_input(cleaner, dual).map_err(error)
        } else {
            DkfRsKf::new(cleaner, dual).map_err(error)
        }
    }
    fn read_cleaner_input(&mut self, c: &CleanerBlocks, values: &Values) -> Result<(), Failure> {
        let (Some(driven), Some(v)) = (c.driven, self.cleaner_input_mut()) else {
            return Ok(());
        };
        // Every b_j = 0: the cleaner has no input and v is not read.
        if v.is_empty() {
            return Ok(());
        }
        if !copy_inputs(values, &driven.v, v) {
            read_inputs(values, &driven.v, "v", v)?;
        }
        Ok(())
    }
    fn dual(&self) -> &DualKalmanFilter {
        DkfRsKf::dual(self)
    }
    fn write_cleaner(&self, c: &CleanerBlocks, values: &mut Values, initial: bool) {
        if initial {
            for k in c.w.indices() {
                values.set_real(k, 1.0);
            }
            c.y_clean.write_vector(values, self.cleaner().state());
        } else {
            c.w.write_vector(values, self.cleaner().weights());
            c.y_clean.write_vector(values, self.cleaned_output());
        }
    }
}

/// The family of the dual filters (DKF, DKF-rsKF) behind the one [`Filtered`] adapter.
impl<F: DualFilter> FilterFamily<F> for DualLayout {
    fn interface(config: &Config) -> Result<(Self, ModelInfo), Cause> {
        interface(config, F::CLEANED)
    }

    fn build(&self, values: &Values) -> Result<F, Failure> {
        F::build(self, values)
    }

    fn read_inputs(&self, filter: &mut F, values: &Values) -> Result<(), Failure> {
        match &self.cleaner {
            Some(c) => filter.read_cleaner_input(c, values),
            None => Ok(()),
        }
    }

    fn write_initial(&self, filter: &F, ctx: &mut Context) {
        write_initial_dual(self, ctx, filter.dual());
        if let Some(c) = &self.cleaner {
            filter.write_cleaner(c, ctx.values, true);
        }
    }

    fn write_outputs(&self, filter: &F, values: &mut Values) {
        write_dual_outputs(self, values, filter.dual());
        self.signals.y_hat.write_vector(values, filter.output());
        if let Some(c) = &self.cleaner {
            filter.write_cleaner(c, values, false);
        }
    }
}

/// `DualKalmanFilter.fmu`.
pub type DualKalmanFilterFmu = EstimatorFmu<Filtered<DualLayout, DualKalmanFilter>>;
/// `DkfRsKf.fmu`.
pub type DkfRsKfFmu = EstimatorFmu<Filtered<DualLayout, DkfRsKf>>;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::dims_config;
    use spurio_export::harness::Harness;
    use spurio_export::FmuModel;

    /// The FMU `M` for `n` states, `m` inputs and `p` outputs, and its value references by
    /// variable name.
    fn harness<M: FmuModel>(n: usize, m: usize, p: usize) -> (Harness<M>, impl Fn(&str) -> u32) {
        let config = dims_config(n, m, p);
        let info = M::describe(&config).unwrap();
        let h = Harness::<M>::new(&config).unwrap();
        (h, move |name: &str| info.index_of(name).unwrap() as u32)
    }

    #[test]
    fn generator_variant_steps_and_reports_the_model() {
        let (mut h, vr) = harness::<DkfRsKfFmu>(8, 2, 2);
        h.initialize(0.0).unwrap();
        let mut out = [0.0; 3];
        for k in 0..100 {
            let t = k as f64 * 0.1;
            h.set_real(
                &[vr("u[1]"), vr("y[1]"), vr("y[2]")],
                &[t.sin(), t.cos(), 0.5],
            )
            .unwrap();
            h.do_step(t, 0.1).unwrap();
        }
        h.get_real(&[vr("A_hat[1,1]"), vr("C_hat[1,1]"), vr("w[1]")], &mut out)
            .unwrap();
        assert!(out.iter().all(|v| v.is_finite()));
        assert_eq!(out[1], 1.0, "C is fixed by default");
    }

    #[test]
    fn the_cleaner_starts_at_the_initial_output_and_rejects_a_first_outlier() {
        let (mut h, vr) = harness::<DkfRsKfFmu>(4, 1, 2);
        h.set_real(
            &[vr("x0[1]"), vr("q_clean"), vr("r_clean"), vr("p0_clean")],
            &[0.2, 1e-5, 1e-5, 1e-5],
        )
        .unwrap();
        h.initialize(0.0).unwrap();
        let mut out = [0.0; 3];
        h.get_real(&[vr("y_clean[1]"), vr("y_clean[2]"), vr("w[1]")], &mut out)
            .unwrap();
        assert_eq!(out, [0.2, 0.0, 1.0], "y_clean starts at C x0");
        // The first sample carries a +0.28 outlier on the position.
        h.set_real(&[vr("u[1]"), vr("y[1]"), vr("y[2]")], &[0.0, 0.48, 0.0])
            .unwrap();
        h.do_step(0.0, 0.05).unwrap();
        h.get_real(&[vr("y_clean[1]"), vr("y_clean[2]"), vr("w[1]")], &mut out)
            .unwrap();
        assert!(
            (out[0] - 0.2).abs() < 0.015,
            "cleaned {} (outlier 0.28)",
            out[0]
        );
        assert!(out[2] < 0.05, "weight {}", out[2]);
    }

    /// The real outputs of a DkfRsKf variant after 300 steps on a signal with outliers (`v`:
    /// the cleaner's inputs, if it has them, and the parameters to set before initialising).
    fn dkf_rskf_outputs(
        config: &Config,
        parameters: &[(&str, f64)],
        with_v: bool,
    ) -> Vec<(String, f64)> {
        let info = DkfRsKfFmu::describe(config).unwrap();
        let vr = |name: &str| info.index_of(name).unwrap() as u32;
        let mut h = Harness::<DkfRsKfFmu>::new(config).unwrap();
        for (name, value) in parameters {
            h.set_real(&[vr(name)], &[*value]).unwrap();
        }
        h.set_real(&[vr("q_clean"), vr("r_clean")], &[0.05, 0.01])
            .unwrap();
        h.initialize(0.0).unwrap();
        for k in 0..300 {
            let t = k as f64 * 0.05;
            let spike = if k % 23 == 7 { 2.0 } else { 0.0 };
            let u = (0.7 * t).sin().signum();
            h.set_real(
                &[vr("u[1]"), vr("y[1]"), vr("y[2]")],
                &[u, (0.5 * t).sin() + spike, 0.3 * (0.9 * t).cos()],
            )
            .unwrap();
            if with_v {
                h.set_real(&[vr("v[1]"), vr("v[2]")], &[u, -u]).unwrap();
            }
            h.do_step(t, 0.05).unwrap();
        }
        info.variables
            .iter()
            .filter(|v| v.causality == spurio_export::Causality::Output)
            .filter(|v| matches!(v.start, spurio_export::Value::Real(_)))
            .map(|v| {
                let mut out = [0.0];
                h.get_real(&[vr(&v.name)], &mut out).unwrap();
                (v.name.clone(), out[0])
            })
            .collect()
    }

    /// `cleaner_input` = 1 with a_clean = 1, b_clean = 0 (the defaults) is the DkfRsKf's
    /// random-walk cleaner bit for bit, whatever v; a_clean, b_clean ≠ defaults drive it by v.
    #[test]
    fn the_driven_cleaner_with_default_parameters_is_the_random_walk() {
        let mut driven = dims_config(4, 1, 2);
        driven.set("cleaner_input", 1);
        let walk = dkf_rskf_outputs(&dims_config(4, 1, 2), &[], false);
        let by_default = dkf_rskf_outputs(&driven, &[], true);
        assert_eq!(walk.len(), by_default.len());
        for ((name, a), (other, b)) in walk.iter().zip(&by_default) {
            assert_eq!(name, other);
            assert_eq!(a.to_bits(), b.to_bits(), "{name}: {a} against {b}");
        }
        let moved = dkf_rskf_outputs(
            &driven,
            &[
                ("a_clean[1]", 0.9),
                ("b_clean[1]", 0.1),
                ("b_clean[2]", 0.05),
            ],
            true,
        );
        let differs = |name: &str| {
            let find = |set: &[(String, f64)]| set.iter().find(|(n, _)| n == name).unwrap().1;
            find(&walk) != find(&moved)
        };
        assert!(differs("y_clean[1]") && differs("y_clean[2]"));
        let mut bad = dims_config(4, 1, 2);
        bad.set("cleaner_input", 2);
        assert!(DkfRsKfFmu::describe(&bad).is_err());
    }

    /// Near rest (u, y a tiny wobble around 0) the papers' filter lets Σ grow and Θ̂ move;
    /// with `excitation_min` above the rest excitation Θ̂ is frozen.
    #[test]
    fn the_excitation_gate_freezes_the_model_at_rest() {
        let run = |excitation_min: f64| {
            let (mut h, vr) = harness::<DualKalmanFilterFmu>(4, 1, 2);
            h.set_real(
                &[vr("excitation_min"), vr("excitation_window")],
                &[excitation_min, 50.0],
            )
            .unwrap();
            h.initialize(0.0).unwrap();
            for k in 0..2000 {
                let wobble = 1e-3 * ((k * 7919) % 13) as f64 / 13.0;
                h.set_real(
                    &[vr("u[1]"), vr("y[1]"), vr("y[2]")],
                    &[wobble * wobble, wobble, -wobble],
                )
                .unwrap();
                h.do_step(k as f64 * 0.05, 0.05).unwrap();
            }
            let mut out = [0.0; 3];
            h.get_real(
                &[vr("A_hat[1,1]"), vr("A_hat[2,2]"), vr("excitation")],
                &mut out,
            )
            .unwrap();
            out
        };
        let free = run(0.0);
        assert_eq!(free[2], 0.0, "ε is not computed without the gate");
        assert!((free[0] - 1.0).abs() > 1e-6, "Â[1,1] = {}", free[0]);
        assert!((free[1] - 1.0).abs() > 1e-6, "Â[2,2] = {}", free[1]);
        let gated = run(1e-3);
        // x̂₃, x̂₄ never move (A = I, C = [I 0]): the regressor spans 3 of 5 directions.
        assert_eq!(gated[2], 0.0, "ε = {}", gated[2]);
        assert_eq!(gated[0], 1.0, "Â[1,1] frozen at A");
        assert_eq!(gated[1], 1.0, "Â[2,2] frozen at A");
    }

    /// `known_rows` = 2 keeps rows 1–2 of [Â B̂] at A, B bit for bit while the output-error
    /// filter moves rows 3–4 (default A = I except Â[1,3] = 0.05, B = 0, C = [I 0]); `known_rows` > n and `output_error` with free C are refused.
    #[test]
    fn known_rows_stay_and_the_output_error_filter_moves_the_rest() {
        let (mut h, vr) = harness::<DualKalmanFilterFmu>(4, 1, 2);
        h.set_integer(&[vr("known_rows")], &[2]).unwrap();
        h.set_boolean(&[vr("output_error")], &[true]).unwrap();
        h.set_real(&[vr("A[1,3]"), vr("p0_theta")], &[0.05, 1e-2])
            .unwrap();
        h.initialize(0.0).unwrap();
        for k in 0..200 {
            let t = k as f64 * 0.05;
            let u = if (k / 10) % 2 == 0 { 1.0 } else { -1.0 };
            h.set_real(
                &[vr("u[1]"), vr("y[1]"), vr("y[2]")],
                &[u, 0.1 * t.sin(), 0.05 * (2.0 * t).cos()],
            )
            .unwrap();
            h.do_step(t, 0.05).unwrap();
        }
        let mut out = [0.0; 5];
        h.get_real(
            &[
                vr("A_hat[1,1]"),
                vr("A_hat[1,3]"),
                vr("B_hat[2,1]"),
                vr("A_hat[3,3]"),
                vr("B_hat[3,1]"),
            ],
            &mut out,
        )
        .unwrap();
        assert_eq!(&out[..3], &[1.0, 0.05, 0.0], "rows 1–2 known");
        assert!((out[3] - 1.0).abs() > 1e-6, "Â[3,3] = {}", out[3]);
        // x₃ reaches y₁ through Â[1,3] = 0.05: B̂[3,1] is learnt from the output error.
        assert!(out[4].abs() > 1e-3, "B̂[3,1] = {}", out[4]);

        let (mut h, vr) = harness::<DualKalmanFilterFmu>(4, 1, 2);
        // Refused when set (above the declared max) or at initialisation.
        let refused =
            h.set_integer(&[vr("known_rows")], &[5]).is_err() || h.initialize(0.0).is_err();
        assert!(refused && h.logged(&["known_rows"]), "{:?}", h.log());
        let (mut h, vr) = harness::<DualKalmanFilterFmu>(4, 1, 2);
        h.set_boolean(
            &[vr("output_error"), vr("fix_output_matrices")],
            &[true, false],
        )
        .unwrap();
        assert!(h.initialize(0.0).is_err());
        assert!(h.logged(&["C and D known"]), "{:?}", h.log());
    }

    /// Every block shape with a fixed-size copy, and one without, lands row-major in its
    /// variables: A_hat[i,j] = Θ̂[i, j] and so on.
    #[test]
    fn theta_blocks_are_written_row_major() {
        for (n, m, p) in [(8, 2, 2), (4, 1, 2), (3, 1, 2), (2, 0, 1)] {
            let (rows, cols) = (n + p, n + m);
            let theta = nalgebra::DMatrix::from_fn(rows, cols, |i, j| (100 * i + j) as f64);
            let mut t = VariableTable::new();
            let mut block = |name: &str, r: usize, c: usize| {
                add_matrix(&mut t, name, r, c, |e, _, _| Variable::discrete_output(e))
            };
            let blocks = [
                (block("A_hat", n, n), (0, 0)),
                (block("B_hat", n, m), (0, n)),
                (block("C_hat", p, n), (n, 0)),
                (block("D_hat", p, m), (n, n)),
            ];
            let mut values = Values::from_start(&t.into_variables());
            for (b, at) in &blocks {
                let slots = values.reals_mut(b.indices()).unwrap();
                write_theta_block(slots, b, theta.as_slice(), rows, *at);
            }
            for (b, (row0, col0)) in &blocks {
                for i in 0..b.rows {
                    for j in 0..b.cols {
                        let want = theta[(row0 + i, col0 + j)];
                        assert_eq!(values.real(b.index(i, j)), want, "n = {n}: ({i}, {j})");
                    }
                }
            }
        }
    }

    /// The outputs of a stepped DKF (n = 8, m = p = 2: one slice of the values for the four
    /// blocks) are its Θ̂ and x̂.
    #[test]
    fn the_outputs_are_the_filters_estimates() {
        let config = dims_config(8, 2, 2);
        let (layout, info) = interface(&config, false).unwrap();
        let mut values = Values::from_start(&info.variables);
        let mut dkf = build_dual(&layout, &values).unwrap();
        for k in 0..50 {
            let t = k as f64 * 0.1;
            let u = nalgebra::DVector::from_vec(vec![t.sin(), (2.0 * t).cos()]);
            let y = nalgebra::DVector::from_vec(vec![(0.5 * t).sin(), 0.1 * t]);
            dkf.step(&u, &y).unwrap();
        }
        write_dual_outputs(&layout, &mut values, &dkf);
        let n = layout.signals.dims.n;
        let theta = dkf.theta();
        let moved = theta.iter().filter(|v| **v != 0.0 && **v != 1.0).count();
        assert!(moved >= 8, "{moved} entries of Θ̂ moved");
        for (block, (row0, col0)) in [
            (layout.a_hat, (0, 0)),
            (layout.b_hat, (0, n)),
            (layout.c_hat, (n, 0)),
            (layout.d_hat, (n, n)),
        ] {
            for i in 0..block.rows {
                for j in 0..block.cols {
                    assert_eq!(values.real(block.index(i, j)), theta[(row0 + i, col0 + j)]);
                }
            }
        }
        assert_eq!(layout.signals.x_hat.vector(&values), *dkf.state());
    }

    #[test]
    fn bad_covariances_are_errors_naming_the_parameter() {
        let (mut h, vr) = harness::<DualKalmanFilterFmu>(2, 0, 1);
        h.set_real(&[vr("Q[1,2]")], &[0.5]).unwrap();
        assert!(h.initialize(0.0).is_err());
        assert!(h.logged(&["parameter `Q`", "symmetric"]), "{:?}", h.log());
    }
}
