//! `RobustKalmanFilter.fmu`: the robust-statistics Kalman filter (rsKF, Cipra & Romera), dimension-generic (keys `n`, `m`, `p`), as
//! [`spurio_fmu_kalman::linear::LinearLayout`] over [`spurio::estimation::RobustKalmanFilter`].
pub use spurio_fmu_kalman::{dims_config as dims, RobustKalmanFilterFmu};
spurio_export::export_fmu! { RobustKalmanFilterFmu, variants = [("RobustKalmanFilter", dims(1, 0, 1)), ("RobustKalmanFilter2", dims(2, 0, 2)), ("RobustKalmanFilterInput", dims(1, 1, 1))] }
