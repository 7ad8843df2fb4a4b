//! `DualKalmanFilter.fmu`: the dual Kalman filter (DKF), dimension-generic (keys `n`, `m`, `p`), as
//! [`spurio_fmu_kalman::dual::DualLayout`] over [`spurio::estimation::DualKalmanFilter`].
pub use spurio_fmu_kalman::{dims_config as dims, DualKalmanFilterFmu};
spurio_export::export_fmu! { DualKalmanFilterFmu, variants = [("DualKalmanFilter", dims(4, 1, 2)), ("DualKalmanFilterGenerator", dims(8, 2, 2))] }
