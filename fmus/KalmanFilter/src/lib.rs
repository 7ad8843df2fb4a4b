//! `KalmanFilter.fmu`: the standard Kalman filter (sKF), dimension-generic (keys `n`, `m`, `p`), as
//! [`spurio_fmu_common::kalman::Linear`] over [`spurio::estimation::KalmanFilter`].
pub use spurio_fmu_common::{kalman::dims_config as dims, kalman::KalmanFilterFmu};
spurio_export::export_fmu! { KalmanFilterFmu, variants = [("KalmanFilter", dims(1, 0, 1)), ("DistributedObserverCentralKalman", dims(3, 0, 2))] }
