//! `DkfRsKf.fmu`: the DKF-rsKF of paper 001 Fig. 2, dimension-generic (keys `n`, `m`, `p`), as
//! [`spurio_fmu_kalman::dual::DualLayout`] over [`spurio::estimation::DkfRsKf`].
pub use spurio_fmu_kalman::{dims_config as dims, DkfRsKfFmu};
spurio_export::export_fmu! { DkfRsKfFmu, variants = [("DkfRsKf", dims(4, 1, 2)), ("DkfRsKfGenerator", dims(8, 2, 2))] }
