//! `DualKalmanFilter.fmu`: the dual Kalman filter (DKF) as an FMI 2.0 CS FMU, dimension-generic (keys `n`, `m`, `p`
//! of the packaging configuration). The adapter is the generic
//! [`spurio_fmu_common::estimator::EstimatorFmu`] over [`spurio_fmu_common::dual`].
#![deny(unsafe_code)]
#![allow(non_snake_case)] // the crate is named by the FMU's model identifier

pub use spurio_fmu_common::dual::DualKalmanFilterFmu;
use spurio_fmu_common::kalman::dims_config;

spurio_export::export_fmu!(
    DualKalmanFilterFmu,
    variants = [
        ("DualKalmanFilter", dims_config(4, 1, 2)),
        ("DualKalmanFilterGenerator", dims_config(8, 2, 2)),
    ]
);
