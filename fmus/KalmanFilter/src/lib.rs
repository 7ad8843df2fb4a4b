//! `KalmanFilter.fmu`: the standard Kalman filter (sKF), dimension-generic (keys `n`, `m`, `p`), as
//! [`spurio_fmu_kalman::linear::LinearLayout`] over [`spurio::estimation::KalmanFilter`].
pub use spurio_fmu_kalman::{dims_config as dims, KalmanFilterFmu};
spurio_export::export_fmu! { KalmanFilterFmu, variants = [("KalmanFilter", dims(1, 0, 1)), ("DistributedObserverCentralKalman", dims(3, 0, 2))] }
