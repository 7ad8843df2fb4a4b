//! `KalmanFilter.fmu`: the standard Kalman filter (sKF) as an FMI 2.0 CS FMU, dimension-generic (keys `n`, `m`, `p`
//! of the packaging configuration). The adapter is the generic
//! [`spurio_fmu_common::estimator::EstimatorFmu`] over [`spurio_fmu_common::kalman`].
#![deny(unsafe_code)]
#![allow(non_snake_case)] // the crate is named by the FMU's model identifier

use spurio_fmu_common::kalman::dims_config;
pub use spurio_fmu_common::kalman::KalmanFilterFmu;

spurio_export::export_fmu!(
    KalmanFilterFmu,
    variants = [
        ("KalmanFilter", dims_config(1, 0, 1)),
        ("DistributedObserverCentralKalman", dims_config(3, 0, 2)),
    ]
);
