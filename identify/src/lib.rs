//! Identification of a plant FMU's states and chosen parameters from measurements
//! (docs/estimators.md): online, the robust unscented and extended Kalman filters of
//! [`filter`] on a Model Exchange FMU ([`plant`]); offline (feature `offline`, on by default),
//! maximum likelihood of the innovations over named free parameters ([`maximise_likelihood`],
//! argmin's Nelder–Mead), the `spurio identify` session ([`session`]) and identification
//! from an FMU's own run plus noise and outliers ([`synthetic`]).
//!
//! The online part links the FMU importer, its Model Exchange stepper and the solvers only: it
//! is what an estimator FMU carries (fmus/PlantEstimator builds this crate without default
//! features, so neither the optimiser nor the session's readers enter it).

pub mod ekf;
pub mod estimator;
pub mod filter;
#[cfg(feature = "offline")]
pub mod fmu_model;
#[cfg(feature = "offline")]
mod maximum_likelihood;
pub mod online;
pub mod packaged;
pub mod plant;
mod prediction;
#[cfg(feature = "offline")]
pub mod session;
#[cfg(feature = "offline")]
pub mod synthetic;
pub mod ukf;

#[cfg(feature = "offline")]
pub use maximum_likelihood::{
    maximise_likelihood, nile, Curvature, Estimate, Fit, FreeParameter, IdentifyError, Options,
    Run, Scale,
};
