//! What every sample-driven state estimator of spurio does, as one trait, so that one generic
//! FMU adapter drives the sKF, the rsKF, the DKF and the DKF-rsKF.

use super::{DkfRsKf, DualKalmanFilter, EstimationError, KalmanFilter, RobustKalmanFilter};
use nalgebra::DVector;

/// A discrete-time estimator of the state of
///
/// ```text
/// x_{k+1} = A x_k + B u_k + w_k,      y_k = C x_k + D u_k + v_k
/// ```
///
/// that processes one sample per call: [`StateEstimator::step`]`(u_k, y_k)` predicts
/// x̂_{k|k−1} = A x̂_{k−1|k−1} + B u_{k−1}, forms the innovation
/// e_k = y_k − C x̂_{k|k−1} − D u_k, corrects x̂_{k|k} = x̂_{k|k−1} + K_k ψ(e_k) (ψ the identity
/// for the sKF and the DKF, an influence function for the rsKF) and leaves the estimate
/// x̂_{k|k} and the fitted output ŷ_k = C x̂_{k|k} + D u_k. The DKF estimates
/// Θ = [A B; C D] alongside the state; the DKF-rsKF first cleans y_k with an rsKF.
pub trait StateEstimator {
    /// Processes the sample (u_k, y_k); on an error the estimate is unchanged.
    fn step(&mut self, u: &DVector<f64>, y: &DVector<f64>) -> Result<(), EstimationError>;
    /// The state estimate x̂_{k|k}.
    fn state(&self) -> &DVector<f64>;
    /// The fitted output ŷ_k = C x̂_{k|k} + D u_k.
    fn output(&self) -> &DVector<f64>;
    /// The innovation e_k of the last step.
    fn innovation(&self) -> &DVector<f64>;
    /// Everything that evolves from step to step (estimate, covariances, counters).
    fn dynamic_state(&self) -> Vec<f64>;
    /// Restores [`StateEstimator::dynamic_state`] into an estimator built from the same
    /// parameters, which then continues bit for bit.
    fn set_dynamic_state(&mut self, state: &[f64]) -> Result<(), EstimationError>;
}

macro_rules! forward {
    ($($t:ty),*) => {$(
        impl StateEstimator for $t {
            fn step(&mut self, u: &DVector<f64>, y: &DVector<f64>) -> Result<(), EstimationError> {
                <$t>::step(self, u, y)
            }
            fn state(&self) -> &DVector<f64> {
                <$t>::state(self)
            }
            fn output(&self) -> &DVector<f64> {
                <$t>::output(self)
            }
            fn innovation(&self) -> &DVector<f64> {
                <$t>::innovation(self)
            }
            fn dynamic_state(&self) -> Vec<f64> {
                <$t>::dynamic_state(self)
            }
            fn set_dynamic_state(&mut self, state: &[f64]) -> Result<(), EstimationError> {
                <$t>::set_dynamic_state(self, state)
            }
        }
    )*};
}
forward!(KalmanFilter, RobustKalmanFilter, DualKalmanFilter);

/// The DKF-rsKF: the state and fitted output are the DKF's (driven by the cleaned outputs).
impl StateEstimator for DkfRsKf {
    fn step(&mut self, u: &DVector<f64>, y: &DVector<f64>) -> Result<(), EstimationError> {
        DkfRsKf::step(self, u, y)
    }
    fn state(&self) -> &DVector<f64> {
        self.dual().state()
    }
    fn output(&self) -> &DVector<f64> {
        self.dual().output()
    }
    fn innovation(&self) -> &DVector<f64> {
        self.dual().innovation()
    }
    fn dynamic_state(&self) -> Vec<f64> {
        DkfRsKf::dynamic_state(self)
    }
    fn set_dynamic_state(&mut self, state: &[f64]) -> Result<(), EstimationError> {
        DkfRsKf::set_dynamic_state(self, state)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimation::GaussianModel;
    use crate::state_space::StateSpace;
    use nalgebra::{dmatrix, dvector};

    /// Drives any estimator through the trait: the generic path must equal the direct one.
    fn run<E: StateEstimator>(e: &mut E, samples: &[(f64, f64)]) -> Vec<f64> {
        for (u, y) in samples {
            e.step(&dvector![*u], &dvector![*y]).unwrap();
        }
        e.state().iter().chain(e.output().iter()).copied().collect()
    }

    #[test]
    fn the_trait_drives_the_skf_like_its_own_methods() {
        let make = || {
            KalmanFilter::new(GaussianModel {
                system: StateSpace {
                    a: dmatrix![0.9],
                    b: dmatrix![1.0],
                    c: dmatrix![1.0],
                    d: dmatrix![0.0],
                    q: dmatrix![0.01],
                    r: dmatrix![0.1],
                },
                x0: dvector![0.0],
                p0: dmatrix![1.0],
            })
            .unwrap()
        };
        let samples = [(1.0, 0.5), (0.0, 1.2), (-1.0, 0.7)];
        let mut direct = make();
        for (u, y) in samples {
            direct.step(&dvector![u], &dvector![y]).unwrap();
        }
        let mut generic = make();
        let through_trait = run(&mut generic, &samples);
        assert_eq!(through_trait, vec![direct.state()[0], direct.output()[0]]);
        // The state moved towards the measurements and stays finite.
        assert!(through_trait[0] > 0.0 && through_trait[0] < 1.2);
        let saved = StateEstimator::dynamic_state(&generic);
        let mut restored = make();
        StateEstimator::set_dynamic_state(&mut restored, &saved).unwrap();
        assert_eq!(
            run(&mut restored, &[(0.3, 0.4)]),
            run(&mut generic, &[(0.3, 0.4)])
        );
    }
}
