//! `DkfRsKf.fmu`: the rsKF cleaning the outputs + DKF (paper 001 Fig. 2) as an FMI 2.0 CS FMU, dimension-generic (keys `n`, `m`, `p`
//! of the packaging configuration). The adapter is the generic
//! [`spurio_fmu_common::estimator::EstimatorFmu`] over [`spurio_fmu_common::dual`].
#![deny(unsafe_code)]
#![allow(non_snake_case)] // the crate is named by the FMU's model identifier

pub use spurio_fmu_common::dual::DkfRsKfFmu;
use spurio_fmu_common::kalman::dims_config;

spurio_export::export_fmu!(
    DkfRsKfFmu,
    variants = [
        ("DkfRsKf", dims_config(4, 1, 2)),
        ("DkfRsKfGenerator", dims_config(8, 2, 2)),
    ]
);
