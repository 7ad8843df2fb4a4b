//! `DualKalmanFilter.fmu`: the dual Kalman filter (DKF), dimension-generic (keys `n`, `m`, `p`), as
//! [`spurio_fmu_common::dual::Dual`] over [`spurio::estimation::DualKalmanFilter`].
pub use spurio_fmu_common::{dual::DualKalmanFilterFmu, kalman::dims_config as dims};
spurio_export::export_fmu! { DualKalmanFilterFmu, variants = [("DualKalmanFilter", dims(4, 1, 2)), ("DualKalmanFilterGenerator", dims(8, 2, 2))] }
