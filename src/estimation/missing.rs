//! Missing samples (docs/estimators.md, "Missing samples"): a NaN measurement y_j is a
//! missing sample, not an error, for every estimator of spurio. A recorded table marks a
//! lost sample with an empty cell, which every CSV reader (fmpy, pandas, the master) reads
//! as NaN, and a NaN is never a measurement, so the NaN itself is the flag: no separate `y_valid` input that could
//! contradict it or be left unconnected. A y_j = ±∞, a non-finite input u or neighbour
//! estimate stays an error.
//!
//! What each estimator does with a missing sample (Cipra & Romera 1997: the update with the
//! present channels only):
//!
//! | estimator | missing y_j |
//! |---|---|
//! | sKF, rsKF | prediction x⁻, P⁻ = A P Aᵀ + Q; the update with the present channels (rows of C, rows and columns of R selected, [`MissingMask`]); e_j = 0; the rsKF's w_j = 0 |
//! | DKF | the state filter as the sKF; the parameter filter's random walk only (Θ̂ kept, Σ += diag(q̃)) when a channel of y_k or y_{k−1} is missing |
//! | DKF-rsKF | the rsKF as above; the DKF gets the missing channels as missing |
//! | RLS | no update (θ, P kept); y(t) replaced in the regressors by its prediction φᵀθ; ε = 0; the na steps whose regressors hold that prediction do not update either |
//! | distributed observer | no output injection from channel j (e_j = 0): prediction and consensus |
//!
//! Each is allocation-free and bounded: a few passes over the model's matrices in buffers
//! allocated with the estimator.

use crate::linalg::dense::View;
use nalgebra::{DMatrix, DVector};

/// Which channels of a sample are missing, as the matrices of the update with the present
/// ones (docs/estimators.md, "Missing samples"). A NaN measurement y_j is a missing
/// sample. Cipra & Romera's update with the present channels only selects the rows of C and
/// the rows and columns of R with a selection matrix W (q×p, q present channels):
/// C_W = W C, R_W = W R Wᵀ. The mask keeps the sizes and writes instead
///
/// ```text
/// C_M = C with the rows of the missing channels zero,
/// R_M = R with their rows and columns zero and 1 on their diagonal,
/// ```
///
/// i.e. C_M, R_M are C_W, R_W and a block that does not couple, after a permutation. Then
/// G = C_M P⁻ has zero rows j, S = C_M P⁻ C_Mᵀ + R_M is W S_W Wᵀ plus 1 on the missing
/// diagonal, its Cholesky factor is that of S_W and 1 there (every term that couples a
/// missing channel is an exact zero), and the gain of a missing channel is exactly 0: the
/// update (x̂, P) is the one with C_W, R_W, bit for bit up to the sign of zeros, with the same
/// kernels, no allocation, and S still solved by Cholesky. The buffers are allocated with the
/// filter.
#[derive(Debug, Clone)]
pub(crate) struct MissingMask {
    /// C_M (p×n).
    pub(crate) c: DMatrix<f64>,
    /// R_M (p×p).
    pub(crate) r: DMatrix<f64>,
}

impl MissingMask {
    pub(crate) fn new(outputs: usize, states: usize) -> Self {
        Self {
            c: DMatrix::zeros(outputs, states),
            r: DMatrix::zeros(outputs, outputs),
        }
    }

    /// Whether some channel of `y` is missing (NaN).
    #[inline]
    pub(crate) fn any(y: &DVector<f64>) -> bool {
        y.iter().any(|v| v.is_nan())
    }

    /// Writes C_M and R_M for the sample `y` from the model's `c` and `r`; gives the number
    /// of missing channels.
    pub(crate) fn select(&mut self, c: View<'_>, r: &DMatrix<f64>, y: &DVector<f64>) -> usize {
        let p = y.len();
        let missing = |j: usize| y.get(j).is_some_and(|v| v.is_nan());
        let (rows, cols) = self.c.shape();
        for j in 0..cols {
            for i in 0..rows {
                self.c[(i, j)] = if missing(i) { 0.0 } else { c.at(i, j) };
            }
        }
        let (r_source, r_masked) = (r.as_slice(), self.r.as_mut_slice());
        for (index, (target, source)) in r_masked.iter_mut().zip(r_source).enumerate() {
            let (i, j) = (index % p, index / p);
            *target = match (missing(i) || missing(j), i == j) {
                (false, _) => *source,
                (true, true) => 1.0,
                (true, false) => 0.0,
            };
        }
        (0..p).filter(|&j| missing(j)).count()
    }
}

#[cfg(test)]
mod tests {
    use super::super::{
        DistributedObserver, DistributedObserverConfig, DkfRsKf, DualKalmanConfig,
        DualKalmanFilter, GaussianModel, InfluenceFunction, KalmanFilter, RecursiveLeastSquares,
        RobustKalmanFilter, StateEstimator,
    };
    use crate::state_space::StateSpace;
    use nalgebra::{dmatrix, dvector, DMatrix, DVector};

    const NAN: f64 = f64::NAN;

    /// A damped oscillator with an input, measured by two sensors with correlated noise
    /// (n = 2, m = 1, p = 2: one of the packaged kernel sizes), or, with `states` = 3, a third
    /// state driven by the first (the general kernels).
    fn model(states: usize, c: DMatrix<f64>, r: DMatrix<f64>) -> GaussianModel {
        let (a, b) = match states {
            2 => (dmatrix![0.95, 0.1; -0.1, 0.9], dmatrix![0.0; 0.1]),
            _ => (
                dmatrix![0.95, 0.1, 0.0; -0.1, 0.9, 0.0; 0.05, 0.0, 0.8],
                dmatrix![0.0; 0.1; 0.02],
            ),
        };
        let p = c.nrows();
        GaussianModel {
            system: StateSpace {
                a,
                b,
                c,
                d: DMatrix::zeros(p, 1),
                q: DMatrix::identity(states, states) * 1e-3,
                r,
            },
            x0: DVector::zeros(states),
            p0: DMatrix::identity(states, states) * 0.5,
        }
    }

    fn two_sensors(states: usize) -> GaussianModel {
        let mut c = DMatrix::zeros(2, states);
        c[(0, 0)] = 1.0;
        c[(1, 0)] = 0.5;
        c[(1, 1)] = 1.0;
        model(states, c, dmatrix![0.04, 0.01; 0.01, 0.09])
    }

    /// u_k and a measurement of the oscillator's trajectory (a deterministic record).
    fn sample(k: usize) -> (DVector<f64>, DVector<f64>) {
        let t = k as f64;
        let u = (0.05 * t).sin();
        (
            dvector![u],
            dvector![
                (0.1 * t).sin() + 0.05 * (1.3 * t).cos(),
                0.4 * (0.1 * t).cos()
            ],
        )
    }

    fn assert_symmetric_positive_definite(p: &DMatrix<f64>) {
        assert_eq!(p, &p.transpose(), "P exactly symmetric");
        assert!(p.clone().cholesky().is_some(), "P positive definite: {p}");
    }

    /// With every channel missing, a step of the sKF is the prediction: P grows by exactly
    /// A P Aᵀ + Q (to rounding) each step, x̂ = A x̂ + B u, the outputs stay finite, e = 0.
    #[test]
    fn skf_with_every_channel_missing_predicts_and_its_covariance_grows_by_a_p_at_plus_q() {
        for states in [2, 3] {
            let m = two_sensors(states);
            let (a, b, q) = (m.system.a.clone(), m.system.b.clone(), m.system.q.clone());
            let mut filter = KalmanFilter::new(m).unwrap();
            for k in 0..50 {
                let (u, y) = sample(k);
                filter.step(&u, &y).unwrap();
            }
            let mut u_prev = sample(49).0;
            for k in 50..80 {
                let (p_before, x_before) = (filter.covariance().clone(), filter.state().clone());
                let u = sample(k).0;
                filter.step(&u, &dvector![NAN, NAN]).unwrap();
                let expected = &a * &p_before * a.transpose() + &q;
                let error = (filter.covariance() - &expected).abs().max();
                assert!(
                    error <= 1e-15 * expected.abs().max(),
                    "{states} states, step {k}"
                );
                let x_expected = &a * &x_before + &b * &u_prev;
                assert!((filter.state() - x_expected).abs().max() <= 1e-15);
                assert!(
                    filter.covariance().trace() > p_before.trace(),
                    "variance grows"
                );
                assert_eq!(filter.innovation(), &dvector![0.0, 0.0]);
                assert!(filter.output().iter().all(|v| v.is_finite()));
                assert!(filter.gain().iter().all(|&k| k == 0.0));
                assert_symmetric_positive_definite(filter.covariance());
                u_prev = u;
            }
            // The first sample after the gap corrects with a larger gain than before it.
            let (u, y) = sample(80);
            filter.step(&u, &y).unwrap();
            let trace_after = filter.covariance().trace();
            assert!(trace_after.is_finite() && filter.gain().iter().all(|k| k.is_finite()));
        }
    }

    /// The reduced model of the present channel `keep` of [`two_sensors`]: C and R with the
    /// other channel's rows (and column of R) removed, as Cipra & Romera select them.
    fn reduced(states: usize, keep: usize) -> GaussianModel {
        let full = two_sensors(states);
        let c = full.system.c.rows(keep, 1).into_owned();
        let r = DMatrix::from_element(1, 1, full.system.r[(keep, keep)]);
        model(states, c, r)
    }

    /// Steps `full` with channel `missing` of each sample NaN and `selected` (the filter of
    /// the other channel alone, [`reduced`]) with that channel, over 40 samples (with an
    /// outlier of 3 on the present channel every 7th when `outliers`); `check(full,
    /// selected)` after each step. Gives `full` at the end.
    fn with_one_channel_missing<F: StateEstimator>(
        (mut full, mut selected): (F, F),
        missing: usize,
        outliers: bool,
        mut check: impl FnMut(&F, &F),
    ) -> F {
        let keep = 1 - missing;
        for k in 0..40 {
            let (u, mut y) = sample(k);
            if outliers && k % 7 == 3 {
                y[keep] += 3.0;
            }
            let mut y_full = y.clone();
            y_full[missing] = NAN;
            full.step(&u, &y_full).unwrap();
            selected.step(&u, &dvector![y[keep]]).unwrap();
            assert_eq!(full.state(), selected.state(), "step {k}");
            assert_eq!(full.innovation()[missing], 0.0);
            assert_eq!(full.innovation()[keep], selected.innovation()[0]);
            check(&full, &selected);
        }
        full
    }

    /// With one of two channels missing, the update is the one of the filter whose C and R
    /// hold the present channel only, bit for bit (the kernels of the packaged size 2×2 and
    /// the general ones), and the missing channel's gain is 0.
    #[test]
    fn skf_with_one_channel_missing_is_the_filter_of_the_present_channel() {
        for states in [2, 3] {
            for missing in [0, 1] {
                let keep = 1 - missing;
                let filters = (
                    KalmanFilter::new(two_sensors(states)).unwrap(),
                    KalmanFilter::new(reduced(states, keep)).unwrap(),
                );
                with_one_channel_missing(filters, missing, false, |full, selected| {
                    assert_eq!(full.covariance(), selected.covariance());
                    let gain = full.gain();
                    assert!(gain.column(missing).iter().all(|&k| k == 0.0));
                    assert_eq!(gain.column(keep), selected.gain().column(0));
                    assert_symmetric_positive_definite(full.covariance());
                });
            }
        }
    }

    /// The scalar filter (one state, one output) on a missing sample: P grows by a² P + q.
    #[test]
    fn scalar_skf_and_rskf_predict_over_a_gap() {
        let scalar = || GaussianModel {
            system: StateSpace {
                a: dmatrix![0.9],
                b: DMatrix::zeros(1, 0),
                c: dmatrix![1.0],
                d: DMatrix::zeros(1, 0),
                q: dmatrix![0.01],
                r: dmatrix![0.1],
            },
            x0: dvector![1.0],
            p0: dmatrix![0.2],
        };
        let mut skf = KalmanFilter::new(scalar()).unwrap().to_scalar().unwrap();
        let mut rskf = RobustKalmanFilter::new(scalar(), InfluenceFunction::huber())
            .unwrap()
            .to_scalar()
            .unwrap();
        for k in 0..30 {
            let y = 0.9_f64.powi(k);
            skf.step(0.0, y).unwrap();
            rskf.step(0.0, y).unwrap();
        }
        let gain_before = skf.gain();
        for _ in 0..10 {
            let (p, x) = (skf.covariance(), skf.state());
            skf.step(0.0, NAN).unwrap();
            rskf.step(0.0, NAN).unwrap();
            assert_eq!(skf.covariance(), 0.9 * (p * 0.9) + 0.01);
            assert_eq!(skf.state(), 0.9 * x);
            assert_eq!((skf.innovation(), skf.gain()), (0.0, 0.0));
            assert_eq!(rskf.weight(), 0.0, "a missing sample has weight 0");
            assert_eq!(rskf.filter().covariance(), skf.covariance());
        }
        skf.step(0.0, 0.5).unwrap();
        rskf.step(0.0, 0.5).unwrap();
        assert!(rskf.weight() > 0.0);
        assert!(
            skf.gain() > 1.5 * gain_before,
            "gain after the gap {} against {gain_before} before it",
            skf.gain()
        );
    }

    /// The rsKF with correlated R and one channel missing is the rsKF of the present channel
    /// (standardised with R_W^{1/2}), bit for bit; the missing channel reports w = 0; an
    /// outlier on the present channel is still down-weighted.
    #[test]
    fn rskf_with_one_channel_missing_is_the_rskf_of_the_present_channel() {
        for states in [2, 3] {
            for missing in [0, 1] {
                let keep = 1 - missing;
                let psi = InfluenceFunction::huber();
                let filters = (
                    RobustKalmanFilter::new(two_sensors(states), psi).unwrap(),
                    RobustKalmanFilter::new(reduced(states, keep), psi).unwrap(),
                );
                let mut down_weighted = 0;
                let check = |f: &RobustKalmanFilter, selected: &RobustKalmanFilter| {
                    assert_eq!(f.covariance(), selected.covariance());
                    assert_eq!(f.weights()[missing], 0.0);
                    assert_eq!(f.weights()[keep], selected.weights()[0]);
                    down_weighted += usize::from(f.weights()[keep] < 1.0);
                    assert_symmetric_positive_definite(f.covariance());
                };
                let mut full = with_one_channel_missing(filters, missing, true, check);
                assert!(
                    down_weighted >= 5,
                    "outliers down-weighted: {down_weighted}"
                );
                full.step(&dvector![0.0], &dvector![NAN, NAN]).unwrap();
                assert_eq!(full.weights(), &dvector![0.0, 0.0]);
            }
        }
    }

    /// A run with every pattern of missing channels (none, one, both) keeps the sKF's and the
    /// rsKF's covariances symmetric positive definite and every output finite; ±∞ and a
    /// non-finite input stay errors.
    #[test]
    fn mixed_patterns_keep_the_covariance_spd_and_other_non_finite_values_are_errors() {
        let mut skf = KalmanFilter::new(two_sensors(3)).unwrap();
        let mut rskf = RobustKalmanFilter::new(two_sensors(3), InfluenceFunction::tukey()).unwrap();
        for k in 0..200 {
            let (u, mut y) = sample(k);
            match k % 5 {
                1 => y[0] = NAN,
                2 => y[1] = NAN,
                3 => y = dvector![NAN, NAN],
                _ => {}
            }
            skf.step(&u, &y).unwrap();
            rskf.step(&u, &y).unwrap();
            for p in [skf.covariance(), rskf.covariance()] {
                assert_symmetric_positive_definite(p);
            }
            for v in [
                skf.output(),
                rskf.output(),
                skf.innovation(),
                rskf.innovation(),
            ] {
                assert!(v.iter().all(|v| v.is_finite()), "step {k}");
            }
        }
        assert!(skf
            .step(&dvector![0.0], &dvector![f64::INFINITY, NAN])
            .is_err());
        let mut skf = KalmanFilter::new(two_sensors(2)).unwrap();
        assert!(skf.step(&dvector![NAN], &dvector![NAN, NAN]).is_err());
        assert!(rskf
            .step(&dvector![0.0], &dvector![1.0, f64::NEG_INFINITY])
            .is_err());
    }

    fn dual_config() -> DualKalmanConfig {
        DualKalmanConfig::new(two_sensors(2)).fix_output_matrices()
    }

    /// The DKF over a gap: the state covariance grows, Θ̂ stays and every parameter variance
    /// grows by exactly q_θ per missing step (the random walk); the predicted output is
    /// finite. Then it resumes learning.
    #[test]
    fn dkf_over_a_gap_predicts_the_state_and_lets_theta_walk() {
        let mut dkf = DualKalmanFilter::new(dual_config()).unwrap();
        for k in 0..60 {
            let (u, y) = sample(k);
            dkf.step(&u, &y).unwrap();
        }
        let variance = |dkf: &DualKalmanFilter| dkf.parameter_covariance(0).unwrap()[(0, 0)];
        let theta = dkf.theta().clone();
        let (mut v, mut trace) = (variance(&dkf), dkf.covariance().trace());
        for k in 60..80 {
            let u = sample(k).0;
            dkf.step(&u, &dvector![NAN, NAN]).unwrap();
            assert_eq!(dkf.theta(), &theta, "Θ̂ kept over the gap");
            assert_eq!(variance(&dkf), v + 1e-6, "Σ grows by q_θ");
            assert!(dkf.covariance().trace() > trace);
            assert!(dkf.predicted_output().iter().all(|v| v.is_finite()));
            assert!(dkf.output().iter().all(|v| v.is_finite()));
            assert_eq!(dkf.innovation(), &dvector![0.0, 0.0]);
            (v, trace) = (variance(&dkf), dkf.covariance().trace());
        }
        // One channel missing: the state filter uses the other, Θ still only walks; the
        // sample after a gap (y_{k−1} missing) does not update Θ either.
        let (u, mut y) = sample(80);
        y[0] = NAN;
        dkf.step(&u, &y).unwrap();
        assert_eq!(dkf.theta(), &theta);
        let (u, y) = sample(81);
        dkf.step(&u, &y).unwrap();
        assert_eq!(dkf.theta(), &theta);
        let (u, y) = sample(82);
        dkf.step(&u, &y).unwrap();
        assert_ne!(
            dkf.theta(),
            &theta,
            "learning resumes with two present samples"
        );
        assert!(variance(&dkf) < v + 3e-6);
    }

    /// The DKF-rsKF over a gap: the DKF gets the missing channels as missing (Θ̂ kept) while
    /// the cleaner's output there is its prediction, finite; its weights are 0.
    #[test]
    fn dkf_rskf_passes_a_missing_sample_on_as_missing() {
        let cleaner =
            RobustKalmanFilter::random_walk(2, 1e-3, 1e-2, 1.0, InfluenceFunction::huber())
                .unwrap();
        let dual = DualKalmanFilter::new(dual_config()).unwrap();
        let mut filter = DkfRsKf::new(cleaner, dual).unwrap();
        for k in 0..30 {
            let (u, y) = sample(k);
            filter.step(&u, &y).unwrap();
        }
        let theta = filter.dual().theta().clone();
        for k in 30..40 {
            filter.step(&sample(k).0, &dvector![NAN, NAN]).unwrap();
            assert_eq!(filter.dual().theta(), &theta);
            assert_eq!(filter.cleaner().weights(), &dvector![0.0, 0.0]);
            assert!(filter.cleaned_output().iter().all(|v| v.is_finite()));
            assert!(filter.dual().state().iter().all(|v| v.is_finite()));
        }
    }

    /// RLS: a missing y leaves θ and P as they are (no update, no forgetting), returns ε = 0,
    /// and the next regressor holds the prediction φᵀθ in place of y; the na = 2 steps whose
    /// regressors hold it give their prediction error but leave θ and P too; with or without
    /// the prefilter. A y = ±∞ or a NaN u stays an error.
    #[test]
    fn rls_skips_its_update_on_a_missing_sample() {
        // A square wave of period 20 samples into y(t) = 1.5 y(t−1) − 0.7 y(t−2) + 0.5 u(t−1).
        let input = |k: usize| {
            if (k / 10).is_multiple_of(2) {
                1.0
            } else {
                -1.0
            }
        };
        for prefilter in [false, true] {
            let mut rls = if prefilter {
                RecursiveLeastSquares::with_prefilter(2, 2, 0.99, 1e4, 0).unwrap()
            } else {
                RecursiveLeastSquares::new(2, 2, 0.99, 1e4).unwrap()
            };
            let (mut y1, mut y2, mut u_prev) = (0.0, 0.0, 0.0);
            for k in 0..200 {
                let u = input(k);
                let y = 1.5 * y1 - 0.7 * y2 + 0.5 * u_prev;
                let (theta, p) = (rls.parameters().to_vec(), rls.covariance().to_vec());
                if (100..110).contains(&k) {
                    assert_eq!(rls.step(u, NAN).unwrap(), 0.0);
                    assert_eq!(rls.parameters(), theta.as_slice());
                    assert_eq!(rls.covariance(), p.as_slice());
                    assert_eq!(rls.last_error(), 0.0);
                } else if (110..112).contains(&k) {
                    let error = rls.step(u, y).unwrap();
                    assert!(
                        error.is_finite() && error == rls.last_error(),
                        "ε = {error}"
                    );
                    assert_eq!(rls.parameters(), theta.as_slice(), "θ held at {k}");
                    assert_eq!(rls.covariance(), p.as_slice(), "P held at {k}");
                } else if k == 112 {
                    rls.step(u, y).unwrap();
                    assert_ne!(rls.covariance(), p.as_slice(), "updating again at {k}");
                } else {
                    rls.step(u, y).unwrap();
                }
                (y2, y1, u_prev) = (y1, y, u);
            }
            let theta = rls.parameters();
            let expected = [-1.5, 0.7, 0.5, 0.0];
            for (t, e) in theta.iter().zip(expected) {
                assert!((t - e).abs() < 1e-3, "prefilter {prefilter}: θ = {theta:?}");
            }
            assert!(rls.step(0.0, f64::INFINITY).is_err());
            assert!(rls.step(NAN, NAN).is_err());
        }
    }

    /// The distributed observer: a missing own measurement gives no output injection
    /// (innovation 0): the step is A x̂ plus the consensus term.
    #[test]
    fn distributed_observer_drops_the_injection_of_a_missing_channel() {
        let a = dmatrix![0.9, 0.1, 0.0; 0.0, 0.95, 0.1; 0.0, 0.0, 0.9];
        let config = |own: DMatrix<f64>, other: DMatrix<f64>| {
            DistributedObserverConfig::new(
                a.clone(),
                own,
                other,
                DMatrix::identity(3, 3) * 0.2,
                dmatrix![0.1],
            )
        };
        let (c1, c2) = (dmatrix![1.0, 0.0, 0.0], dmatrix![0.0, 1.0, 0.0]);
        let mut agent = DistributedObserver::new(config(c1.clone(), c2.clone())).unwrap();
        let neighbour = dvector![0.3, -0.2, 0.1];
        agent.step(&dvector![1.0], &neighbour).unwrap();
        let x = agent.estimate().clone();
        let mut reference = agent.clone();
        agent.step(&dvector![NAN], &neighbour).unwrap();
        // The reference, given its own prediction C x̂ as the measurement, has e = 0 too.
        reference.step(&(&c1 * &x), &neighbour).unwrap();
        assert_eq!(agent.estimate(), reference.estimate());
        assert!(agent.step(&dvector![f64::INFINITY], &neighbour).is_err());
    }
}
