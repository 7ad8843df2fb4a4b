//! `RecursiveLeastSquares.fmu`: ARX(na, nb) recursive least squares with forgetting, docs/estimators.md
//! §2.11; paper 002 §3.
//!
//! ```text
//! y(t) = −a₁ y(t−1) − … − a_na y(t−na) + b₁ u(t−1) + … + b_nb u(t−nb) + e(t) = φᵀθ + e
//! ε = y − φᵀθ(t−1),  L = Pφ/(λ + φᵀPφ),  θ(t) = θ(t−1) + L ε,  P = (P − Pφφᵀ P/(λ + φᵀPφ))/λ
//! ```
//!
//! Outputs θ = [a₁ … a_na, b₁ … b_nb] (`theta[i]`), the one-step prediction `y_hat` = φᵀθ(t−1)
//! and, for na = 2, nb ∈ {1, 2}, the continuous-time equivalent K ω_n²/(s² + 2ζω_n s + ω_n²)
//! of the current estimate: `wn`, `zeta`, `dc_gain`, `overshoot` [%] and the 2 %
//! `settling_time` [s] (see [`spurio::estimation::ContinuousSecondOrder`]). When the model is
//! not second order or the estimate has no continuous equivalent (a pole on the negative real
//! axis or outside the unit circle, e.g. at the start when θ = 0) those outputs are 0 and an
//! event is logged once.
//!
//! With `prefilter` = true, u and y pass through 1/Â(q) (Steiglitz–McBride) refreshed every
//! `refresh` samples, which removes the bias of least squares under white output noise
//! (docs/experiments.md §4, paper 002's error in ζ). Â starts at `prefilter_a` (default 0: no filtering);
//! `refresh` = 0 keeps it fixed, so that a master can run Steiglitz–McBride iterations: the
//! same record again with `prefilter_a` set to the previous run's final a₁ … a_na.
//!
//! Missing samples (docs/estimators.md, "Missing samples"): the Boolean input `y_valid` = false
//! makes the step a prediction ([`RecursiveLeastSquares::step_missing`]): θ and P kept, `y_hat`
//! the prediction, which also stands for y(t) in the following regressors; `y` is ignored. The
//! na steps whose regressors hold that prediction give `y_hat` but do not update θ and P
//! either: the equations batch least squares drops when it drops those touching a missing
//! sample.

use spurio::estimation::{EstimationError, RecursiveLeastSquares};
use spurio_export::{
    Cause, Config, Context, DefaultExperiment, Failure, ModelInfo, Values, Variable, VariableTable,
};
use spurio_fmu_common::estimator::{
    add_tuning, add_validity, count, error, DynamicState, Estimator,
};
use spurio_fmu_common::structured::{add_vector, Block};

/// The continuous second-order readout of the estimate (written together by
/// [`write_readout`]): name, unit (none for the DC gain), description.
const READOUT: [(&str, Option<&str>, &str); 5] = [
    (
        "wn",
        Some("rad/s"),
        "Natural frequency ω_n of the continuous equivalent (0 when unavailable)",
    ),
    (
        "zeta",
        Some("1"),
        "Damping ratio ζ of the continuous equivalent (0 when unavailable)",
    ),
    ("dc_gain", None, "DC gain Σb/(1 + Σa) (0 when unavailable)"),
    (
        "overshoot",
        Some("%"),
        "Step-response overshoot of the continuous equivalent (0 when unavailable)",
    ),
    (
        "settling_time",
        Some("s"),
        "2 % settling time of the continuous equivalent (0 when unavailable)",
    ),
];

/// Value references of a `RecursiveLeastSquares` variant.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RlsLayout {
    pub na: usize,
    pub nb: usize,
    pub u: usize,
    pub y: usize,
    /// The Boolean input `y_valid` (last in the table).
    pub y_valid: usize,
    pub theta: Block,
    pub y_hat: usize,
    /// The readout outputs, in the order of [`READOUT`].
    pub readout: [usize; 5],
    pub lambda: usize,
    pub p0_scale: usize,
    pub ts: usize,
    pub prefilter: usize,
    pub refresh: usize,
    pub prefilter_a: Block,
}

/// The RLS estimator and whether the readout failure was logged.
#[derive(Debug, Clone)]
pub struct Rls {
    rls: RecursiveLeastSquares,
    /// Sampling period of the readout (0: the sample period of the clock).
    ts: f64,
    readout_logged: bool,
}

fn interface(config: &Config) -> Result<(RlsLayout, ModelInfo), Cause> {
    let na = count(config, "na", 2, 0)?;
    let nb = count(config, "nb", 2, 0)?;
    if na + nb == 0 {
        return Err("variant.cfg: na + nb must be at least 1".into());
    }
    let mut t = VariableTable::new();
    let u = t.add(Variable::input("u", 0.0).describe("Input sample u(t)"));
    let y = t.add(Variable::input("y", 0.0).describe("Output sample y(t)"));
    let theta = add_vector(&mut t, "theta", na + nb, |name, i| {
        let what = if i < na {
            format!(
                "ARX coefficient a{} (y(t) = −Σ a_i y(t−i) + Σ b_j u(t−j))",
                i + 1
            )
        } else {
            format!("ARX coefficient b{}", i - na + 1)
        };
        Variable::discrete_output(name).describe(&what)
    });
    let y_hat =
        t.add(Variable::discrete_output("y_hat").describe("One-step prediction φᵀθ(t−1) of y(t)"));
    let readout = READOUT.map(|(name, unit, what)| {
        let output = Variable::discrete_output(name).describe(what);
        t.add(match unit {
            Some(unit) => output.unit(unit),
            None => output,
        })
    });
    let lambda = t.add(
        Variable::parameter("lambda", 1.0)
            .min(0.0)
            .max(1.0)
            .describe(
            "Forgetting factor λ in (0, 1] (paper 002: 0.98; 1 keeps a single step's transient)",
        ),
    );
    let p0_scale = add_tuning(
        &mut t,
        "p0_scale",
        1e4,
        "Initial covariance P₀ = p0_scale·I (large: no prior knowledge); θ₀ = 0",
    );
    let ts =
        t.add(Variable::parameter("Ts", 0.0).unit("s").min(0.0).describe(
            "Sampling period for the continuous readout; 0 = the sample period (sample_period, or the first step's size)",
        ));
    let prefilter = t.add(Variable::boolean_parameter("prefilter", false).describe(
        "Steiglitz–McBride prefilter: u, y filtered through 1/Â(q) (removes the noise bias)",
    ));
    let refresh = t.add(
        Variable::integer_parameter("refresh", 10)
            .min(0.0)
            .describe("Prefilter: samples between refreshes of Â(q) from θ; 0 = keep Â fixed"),
    );
    let prefilter_a = add_vector(&mut t, "prefilter_a", na, |name, i| {
        Variable::parameter(name, 0.0).describe(&format!(
            "Prefilter: initial â{} of Â(q) = 1 + â₁q⁻¹ + … (Steiglitz–McBride: the previous pass's a{})",
            i + 1,
            i + 1
        ))
    });
    let y_valid = add_validity(&mut t, "y", 0).first;
    let info = ModelInfo::new(
        "RecursiveLeastSquares",
        "Recursive least squares on an ARX(na, nb) model with forgetting, continuous second-order readout (paper 002)",
        t.into_variables(),
        Some(DefaultExperiment {
            start_time: 0.0,
            stop_time: 10.0,
            step_size: 0.01,
        }),
        config.clone(),
    );
    Ok((
        RlsLayout {
            na,
            nb,
            u,
            y,
            y_valid,
            theta,
            y_hat,
            readout,
            lambda,
            p0_scale,
            ts,
            prefilter,
            refresh,
            prefilter_a,
        },
        info,
    ))
}

fn write_readout(l: &RlsLayout, values: &mut Values, figures: [f64; 5]) {
    for (index, value) in l.readout.into_iter().zip(figures) {
        values.set_real(index, value);
    }
}

impl Estimator for Rls {
    type Layout = RlsLayout;

    fn interface(config: &Config) -> Result<(RlsLayout, ModelInfo), Cause> {
        interface(config)
    }

    fn build(l: &RlsLayout, values: &Values) -> Result<Self, Failure> {
        let lambda = values.real(l.lambda);
        let p0 = values.real(l.p0_scale);
        let rls = if values.boolean(l.prefilter) {
            let refresh = values.integer(l.refresh);
            if refresh < 0 {
                return Err(Failure::error(format!(
                    "parameter `refresh`: must be >= 0 samples (0 = fixed prefilter), got {refresh}"
                )));
            }
            RecursiveLeastSquares::with_prefilter(l.na, l.nb, lambda, p0, refresh as u64).and_then(
                |mut rls| {
                    let denominator: Vec<f64> =
                        l.prefilter_a.indices().map(|k| values.real(k)).collect();
                    rls.set_prefilter_denominator(&denominator)?;
                    Ok(rls)
                },
            )
        } else {
            RecursiveLeastSquares::new(l.na, l.nb, lambda, p0)
        }
        .map_err(|e| {
            Failure::error(
                e.to_string()
                    .replace("parameter `P0`", "parameter `p0_scale`"),
            )
        })?;
        let ts = values.real(l.ts);
        if !(ts.is_finite() && ts >= 0.0) {
            return Err(Failure::error(format!(
                "parameter `Ts`: the sampling period must be finite and >= 0 (0 = the sample period), got {ts}"
            )));
        }
        Ok(Self {
            rls,
            ts,
            readout_logged: false,
        })
    }

    fn write_initial(&self, l: &RlsLayout, ctx: &mut Context) {
        l.theta.indices().for_each(|k| ctx.values.set_real(k, 0.0));
        ctx.values.set_real(l.y_hat, 0.0);
        write_readout(l, ctx.values, [0.0; 5]);
    }

    fn step(
        &mut self,
        l: &RlsLayout,
        ctx: &mut Context,
        time: f64,
        step: f64,
    ) -> Result<(), Failure> {
        let u = ctx.values.real(l.u);
        let y = ctx.values.real(l.y);
        for (name, v) in [("u", u), ("y", y)] {
            if !v.is_finite() {
                return Err(Failure::error(format!(
                    "input `{name}` = {v} is not finite: the estimator cannot use it (the step was not taken)"
                )));
            }
        }
        // `y_valid` false: a missing sample, the prediction only.
        let y_hat = if !ctx.values.boolean(l.y_valid) {
            self.rls.step_missing(u).map_err(error)?
        } else {
            y - self.rls.step(u, y).map_err(error)?
        };
        for (k, index) in l.theta.indices().enumerate() {
            ctx.values
                .set_real(index, self.rls.parameters().get(k).copied().unwrap_or(0.0));
        }
        ctx.values.set_real(l.y_hat, y_hat);
        let ts = if self.ts > 0.0 { self.ts } else { step };
        match self.rls.readout(ts) {
            Ok(c)
                if [
                    c.natural_frequency,
                    c.damping,
                    c.dc_gain,
                    c.overshoot_percent,
                    c.settling_time,
                ]
                .iter()
                .all(|v| v.is_finite()) =>
            {
                write_readout(
                    l,
                    ctx.values,
                    [
                        c.natural_frequency,
                        c.damping,
                        c.dc_gain,
                        c.overshoot_percent,
                        c.settling_time,
                    ],
                );
            }
            result => {
                write_readout(l, ctx.values, [0.0; 5]);
                if !self.readout_logged {
                    self.readout_logged = true;
                    // the message is built only when it will be shown: no allocation in a
                    // step otherwise
                    if ctx.logs_events() {
                        let reason = match result {
                            Err(why) => EstimationError::from(why).to_string(),
                            Ok(_) => "a figure of the continuous equivalent is not finite".into(),
                        };
                        ctx.log_event(|| format!(
                            "t = {time}: no continuous second-order readout ({reason}); wn, zeta, dc_gain, overshoot and settling_time are 0 while it is unavailable (logged once)"
                        ));
                    }
                }
            }
        }
        Ok(())
    }
}

/// The RLS and whether the readout problem was logged (once per episode).
impl DynamicState for Rls {
    fn dynamic_state(&self) -> Vec<f64> {
        let mut state = self.rls.dynamic_state();
        state.push(if self.readout_logged { 1.0 } else { 0.0 });
        state
    }
    fn set_dynamic_state(&mut self, state: &[f64]) -> Result<(), EstimationError> {
        let (flag, rest) = state.split_last().ok_or(EstimationError::Dimension {
            what: "saved RecursiveLeastSquares state",
            expected: 1,
            got: 0,
        })?;
        self.rls.set_dynamic_state(rest)?;
        self.readout_logged = *flag != 0.0;
        Ok(())
    }
}

/// `RecursiveLeastSquares.fmu`.
pub type RecursiveLeastSquaresFmu = spurio_fmu_common::estimator::EstimatorFmu<Rls>;

/// The configuration of a variant with na, nb.
pub fn arx_config(na: usize, nb: usize) -> Config {
    let mut c = Config::new();
    c.set("na", na);
    c.set("nb", nb);
    c
}

spurio_export::export_fmu!(
    RecursiveLeastSquaresFmu,
    variants = [("RecursiveLeastSquares", arx_config(2, 2))]
);

#[cfg(test)]
mod tests {
    use super::*;
    use spurio_export::harness::Harness;
    use spurio_export::FmuModel;

    /// `y_valid` = false: the prediction only. θ held through a gap of 50 samples (the `y`
    /// given meanwhile, 1e6, ignored) and the 2 samples after it, `y_hat` the model's free-run prediction (the true
    /// output, once θ is identified), and the same θ at the end as without the gap (the
    /// system is noise-free: any 4 independent samples determine it).
    #[test]
    fn a_missing_sample_is_predicted_and_leaves_theta() {
        let config = arx_config(2, 2);
        let info = RecursiveLeastSquaresFmu::describe(&config).unwrap();
        let vr = |n: &str| info.index_of(n).unwrap() as u32;
        let theta: Vec<u32> = (1..=4).map(|i| vr(&format!("theta[{i}]"))).collect();
        let mut runs = Vec::new();
        for gap in [false, true] {
            let mut h = Harness::<RecursiveLeastSquaresFmu>::new(&config).unwrap();
            h.initialize(0.0).unwrap();
            let (mut y1, mut y2, mut u1, mut u2) = (0.0, 0.0, 0.0, 0.0);
            let (mut held, mut now) = ([0.0; 4], [0.0; 4]);
            for k in 0..400 {
                let u = if (k / 17) % 2 == 0 { 1.0 } else { -1.0 };
                let y = 1.5 * y1 - 0.7 * y2 + u1 + 0.5 * u2;
                let missing = gap && (200..250).contains(&k);
                let given = if missing { 1e6 } else { y };
                h.set_real(&[vr("u"), vr("y")], &[u, given]).unwrap();
                h.set_boolean(&[vr("y_valid")], &[!missing]).unwrap();
                h.do_step(k as f64 * 0.01, 0.01).unwrap();
                h.get_real(&theta, &mut now).unwrap();
                // The gap and the na = 2 steps whose regressors hold its predictions.
                if gap && (200..252).contains(&k) {
                    assert_eq!(now, held, "θ held at step {k}");
                    let y_hat = h.real(vr("y_hat")).unwrap();
                    assert!((y_hat - y).abs() < 1e-5, "prediction {y_hat} against {y}");
                }
                held = now;
                (y2, y1, u2, u1) = (y1, y, u1, u);
            }
            runs.push(now);
        }
        for (with_gap, without) in runs[1].iter().zip(&runs[0]) {
            assert!((with_gap - without).abs() < 1e-5, "{runs:?}");
        }
        let expected = [-1.5, 0.7, 1.0, 0.5];
        for (t, e) in runs[1].iter().zip(expected) {
            assert!((t - e).abs() < 1e-5, "{runs:?}");
        }
    }

    #[test]
    fn identifies_the_op_amp_filter_and_rejects_lambda_above_one() {
        // docs/reference-values.md §6: H(s) = 27/(s² + 5.19 s + 27) with ZOH at Ts = 0.01 s; these rounded
        // coefficients have ω_n = 5.196607, ζ = 0.499362 (computed independently).
        let (a1, a2, b1, b2) = (-1.946793, 0.949424, 1.32665e-3, 1.30389e-3);
        let config = arx_config(2, 2);
        let info = RecursiveLeastSquaresFmu::describe(&config).unwrap();
        let vr = |n: &str| info.index_of(n).unwrap() as u32;
        let mut h = Harness::<RecursiveLeastSquaresFmu>::new(&config).unwrap();
        // A weak prior: the ARX regressors are nearly collinear at this sampling rate.
        h.set_real(&[vr("p0_scale")], &[1e10]).unwrap();
        h.initialize(0.0).unwrap();
        let (mut y1, mut y2, mut u1, mut u2) = (0.0, 0.0, 0.0, 0.0);
        for k in 0..2000 {
            let u = if (k / 37) % 3 == 0 { 1.0 } else { -1.0 };
            let y = -a1 * y1 - a2 * y2 + b1 * u1 + b2 * u2;
            h.set_real(&[vr("u"), vr("y")], &[u, y]).unwrap();
            h.do_step(k as f64 * 0.01, 0.01).unwrap();
            (y2, y1, u2, u1) = (y1, y, u1, u);
        }
        let mut out = [0.0; 2];
        h.get_real(&[vr("wn"), vr("zeta")], &mut out).unwrap();
        assert!((out[0] - 5.196607).abs() < 1e-3, "{out:?}");
        assert!((out[1] - 0.499362).abs() < 1e-3, "{out:?}");
        assert!(h.logged(&["logged once"]), "{:?}", h.log());

        let mut bad = Harness::<RecursiveLeastSquaresFmu>::new(&config).unwrap();
        assert!(bad.set_real(&[vr("lambda")], &[1.5]).is_err());
        assert!(bad.logged(&["`lambda` = 1.5"]));
        let mut unstable = Harness::<RecursiveLeastSquaresFmu>::new(&config).unwrap();
        unstable.set_boolean(&[vr("prefilter")], &[true]).unwrap();
        unstable
            .set_real(&[vr("prefilter_a[1]"), vr("prefilter_a[2]")], &[-2.1, 1.1])
            .unwrap();
        assert!(unstable.initialize(0.0).is_err());
        assert!(
            unstable.logged(&["parameter `prefilter_a`"]),
            "{:?}",
            unstable.log()
        );

        bad.set_real(&[vr("lambda")], &[0.0]).unwrap();
        assert!(bad.initialize(0.0).is_err());
        assert!(bad.logged(&["parameter `lambda`"]), "{:?}", bad.log());
    }
}
