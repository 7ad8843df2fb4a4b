//! Durbin & Koopman's Nile example (docs/estimators.md, "Maximum likelihood"): the local-level
//! model x⁺ = x + η, y = x + ε fitted to the Nile flows 1871–1970 by maximum likelihood with a
//! diffuse initial state gives σ²_ε = 15099, σ²_η = 1469.1 (D&K §2.10, diffuse likelihood §7.2.2; an
//! independent numpy filter gives 15098.5, 1469.18 and ℓ = −632.55, the first term left out).

use sha2::{Digest, Sha256};
use spurio::estimation::likelihood::{log_likelihood, Initialisation, LinearGaussianModel, Record};
use spurio_identify::{nile, Curvature};

fn nile_fit() -> spurio_identify::Fit {
    let (_, flows) = nile::flows().unwrap();
    nile::fit(&flows).unwrap()
}

#[test]
fn the_committed_record_is_the_published_one() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../data/nile/nile.csv");
    let bytes = std::fs::read(path).unwrap();
    let digest: String = Sha256::digest(&bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    assert_eq!(
        digest,
        "88e97bea7249e5832a85e41aec6ce4b8f7b1b14aae930c8363da7f193286b598"
    );
    let (years, flows) = nile::flows().unwrap();
    assert_eq!((years.len(), years[0], years[99]), (100, 1871.0, 1970.0));
    assert_eq!((flows[0], flows[99]), (1120.0, 740.0));
}

/// Relative difference.
fn relative(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

#[test]
fn nile_local_level_reproduces_durbin_and_koopman() {
    let fit = nile_fit();
    let epsilon = fit.estimate("sigma2_epsilon").unwrap();
    let eta = fit.estimate("sigma2_eta").unwrap();
    println!(
        "σ²_ε = {} ± {:?}, σ²_η = {} ± {:?}, ℓ = {}",
        epsilon.value,
        epsilon.standard_error,
        eta.value,
        eta.standard_error,
        fit.log_likelihood.value
    );
    // Durbin & Koopman to 3 significant digits, and the numpy check much closer.
    assert_eq!(format!("{:.3e}", epsilon.value), format!("{:.3e}", 15099.0));
    assert_eq!(format!("{:.3e}", eta.value), format!("{:.3e}", 1469.1));
    assert!(relative(epsilon.value, 15098.5) < 1e-4, "{}", epsilon.value);
    assert!(relative(eta.value, 1469.18) < 1e-3, "{}", eta.value);
    assert!((fit.log_likelihood.value - -632.5456).abs() < 0.01);
    assert_eq!(
        (fit.log_likelihood.terms, fit.log_likelihood.left_out),
        (99, 1)
    );
    // Every one of the nine starts reaches the same optimum.
    assert_eq!(fit.runs.len(), 9);
    for run in &fit.runs {
        assert!(run.converged, "{run:?}");
        assert!(
            (run.log_likelihood - fit.log_likelihood.value).abs() < 1e-6,
            "{run:?}"
        );
    }
    // Standard errors: the numpy check's Hessian in θ gives 3145.5 and 1280.4.
    assert!(relative(epsilon.standard_error.unwrap(), 3145.5) < 0.01);
    assert!(relative(eta.standard_error.unwrap(), 1280.4) < 0.01);
    assert!(matches!(fit.curvature, Curvature::PositiveDefinite { .. }));
}

/// The covariance from the log-scale Hessian and the delta method equals the inverse of a
/// Hessian taken in the natural parameters directly (the gradient vanishes at the optimum).
#[test]
fn delta_method_equals_the_natural_hessian() {
    let fit = nile_fit();
    let (_, flows) = nile::flows().unwrap();
    let record = Record::of_output(&flows).unwrap();
    let model = LinearGaussianModel::local_level();
    let diffuse = Initialisation::Diffuse { kappa: None };
    let theta: Vec<f64> = fit.estimates.iter().map(|e| e.value).collect();
    let f = |t: &[f64]| -log_likelihood(&model, t, &record, &diffuse).unwrap().value;
    let h: Vec<f64> = theta.iter().map(|t| 1e-3 * t).collect();
    let mut hessian = nalgebra::DMatrix::zeros(2, 2);
    for i in 0..2 {
        for j in 0..2 {
            let at = |si: f64, sj: f64| {
                let mut t = theta.clone();
                t[i] += si * h[i];
                t[j] += sj * h[j];
                f(&t)
            };
            hessian[(i, j)] = (at(1.0, 1.0) - at(1.0, -1.0) - at(-1.0, 1.0) + at(-1.0, -1.0))
                / (4.0 * h[i] * h[j]);
        }
    }
    for i in 0..2 {
        for j in 0..2 {
            assert!(
                (fit.hessian[(i, j)] - hessian[(i, j)]).abs() < 1e-3 * hessian[(i, i)].abs(),
                "{} against {}",
                fit.hessian,
                hessian
            );
        }
    }
    let Curvature::PositiveDefinite { covariance } = &fit.curvature else {
        panic!("not positive definite");
    };
    let inverse = hessian.try_inverse().unwrap();
    for i in 0..2 {
        assert!(relative(covariance[(i, i)], inverse[(i, i)]) < 2e-3);
    }
}
