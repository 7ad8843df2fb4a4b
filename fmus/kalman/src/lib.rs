//! The Kalman family's FMU code, one crate for the four FMUs that share it
//! (docs/estimators.md §2.7–§2.10); each FMU's folder names its bundled variants and exports it:
//!
//! | FMU (folder) | filter | here |
//! |---|---|---|
//! | `KalmanFilter` (`fmus/KalmanFilter/`) | sKF | [`linear`]: [`KalmanFilterFmu`] |
//! | `RobustKalmanFilter` (`fmus/RobustKalmanFilter/`) | rsKF (Cipra & Romera 1997) | [`linear`]: [`RobustKalmanFilterFmu`] |
//! | `DualKalmanFilter` (`fmus/DualKalmanFilter/`) | DKF (Haykin ch. 5) | [`dual`]: [`DualKalmanFilterFmu`] |
//! | `DkfRsKf` (`fmus/DkfRsKf/`) | rsKF cleaning → DKF (paper 001 Fig. 2) | [`dual`]: [`DkfRsKfFmu`] |
//!
//! Layers, imports pointing down: [`linear`] and [`dual`] (each family's variables, how its
//! filter is built and what it writes) → [`filtered`] (the one adapter that reads the inputs
//! and steps a family's filter) and [`model`] (the linear-Gaussian model blocks, dimensions,
//! inputs and estimates all four declare) → `spurio-fmu-common` (the estimator FMU, its sample
//! clock, structured variables) and `spurio-export`. The filters themselves are
//! [`spurio::estimation`]'s.
//!
//! Why a crate of its own rather than the KalmanFilter folder with the others depending on it:
//! an FMU crate exports the `fmi2*`/`fmi3*` symbols (`export_fmu!`), so a second FMU linking it
//! would define them twice.
#![forbid(unsafe_code)]

pub mod dual;
pub mod filtered;
pub mod linear;
pub mod model;

pub use dual::{DkfRsKfFmu, DualKalmanFilterFmu};
pub use linear::{KalmanFilterFmu, RobustKalmanFilterFmu};
pub use model::dims_config;
