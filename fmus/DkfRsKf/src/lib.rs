//! `DkfRsKf.fmu`: the DKF-rsKF of paper 001 Fig. 2, dimension-generic (keys `n`, `m`, `p`), as
//! [`spurio_fmu_kalman::dual::DualLayout`] over [`spurio::estimation::DkfRsKf`]; the key
//! `cleaner_input` = 1 gives the cleaner of each channel an input `v[j]` of its own
//! (`DkfRsKfInput`: x_j(k) = a_clean[j] x_j(k−1) + b_clean[j] v_j(k−1)).
pub use spurio_fmu_kalman::{dims_config as dims, DkfRsKfFmu};

/// The dimensions `n`, `m`, `p` with the input-driven cleaner (`cleaner_input` = 1).
pub fn driven_cleaner(n: usize, m: usize, p: usize) -> spurio_export::Config {
    let mut config = dims(n, m, p);
    config.set("cleaner_input", 1);
    config
}

spurio_export::export_fmu! { DkfRsKfFmu, variants = [("DkfRsKf", dims(4, 1, 2)), ("DkfRsKfGenerator", dims(8, 2, 2)), ("DkfRsKfInput", driven_cleaner(4, 1, 2))] }
