//! Data for the FMU identification tests: the Reference FMUs of the repository's third-party
//! folder, run and corrupted by `spurio_identify::synthetic`.
#![allow(dead_code)]

use spurio_identify::plant::FmuPlant;
use spurio_identify::synthetic::{self, parameter_at_end, Case};
use std::cell::RefCell;
use std::path::PathBuf;
use std::rc::Rc;

#[allow(unused_imports)] // ekf_linear uses them, the other tests not
pub use synthetic::{corrupt, diag, times};

/// The FMI 2.0 Reference FMU `model` of the repository's third-party folder.
pub fn reference(model: &str) -> PathBuf {
    let fmu = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../tests/third_party/reference-fmus/fmi2")
        .join(format!("{model}.fmu"));
    assert!(fmu.is_file(), "{} is missing", fmu.display());
    fmu
}

/// The Reference FMU `model` with `free` estimated and `outputs` measured, no inputs.
pub fn plant(
    model: &str,
    free: &[&str],
    outputs: &[&str],
    tolerance: f64,
) -> Rc<RefCell<FmuPlant>> {
    synthetic::plant(&reference(model), free, outputs, tolerance).expect("the plant opens")
}

/// The measured variables at `times` from the FMU's own initial states at `theta`.
pub fn simulate(plant: &Rc<RefCell<FmuPlant>>, theta: &[f64], times: &[f64]) -> Vec<Vec<f64>> {
    synthetic::simulate(plant, theta, times).expect("simulated")
}

/// Runs the five fits of `case`, prints them and asserts the done-when figures: offline
/// (robust) within 1 % of the truth with a standard error below 1 %, online (robust UKF and
/// EKF) within two standard deviations, at least three outliers in the data. The error
/// ratios without/with the robust weights (online, offline) are returned.
pub fn check(case: &Case) -> (f64, f64) {
    let fits = case.identify(&reference(case.model)).expect("the fits");
    let truth = case.truth;
    let (ml, se) = (
        fits.offline_robust.value,
        fits.offline_robust.standard_error,
    );
    let (ml_plain, se_plain) = (fits.offline_plain.value, fits.offline_plain.standard_error);
    let (ukf, sd) = parameter_at_end(&fits.ukf_robust);
    let (ukf_plain, sd_plain) = parameter_at_end(&fits.ukf_plain);
    let (ekf, ekf_sd) = parameter_at_end(&fits.ekf_robust);
    let ratios = (
        case.error_ratio(ukf_plain, ukf),
        case.error_ratio(ml_plain, ml),
    );
    println!(
        "{} {} (truth {truth}, start {}): offline Huber {ml:.6} ± {se:?}, Gaussian {ml_plain:.6} ± {se_plain:?}; online robust UKF {ukf:.6} ± {sd:.6}, plain {ukf_plain:.6} ± {sd_plain:.6}, robust EKF {ekf:.6} ± {ekf_sd:.6}; error ratio none/robust online {:.2}, offline {:.2}; {:.2} s",
        case.model,
        case.parameter,
        case.start,
        ratios.0,
        ratios.1,
        fits.seconds
    );
    assert!(
        fits.data.outliers.len() >= 3,
        "{} outliers",
        fits.data.outliers.len()
    );
    assert!((ml - truth).abs() < 0.01 * truth.abs(), "offline {ml}");
    assert!(
        se.is_some_and(|se| se > 0.0 && se < 0.01 * truth.abs()),
        "se {se:?}"
    );
    assert!((ukf - truth).abs() < 2.0 * sd, "online {ukf} ± {sd}");
    assert!(
        (ekf - truth).abs() < 2.0 * ekf_sd,
        "online EKF {ekf} ± {ekf_sd}"
    );
    ratios
}
