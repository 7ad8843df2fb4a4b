//! Dahlquist's fixed parameter k (ẋ = −k x) identified from its own Model Exchange run plus
//! noise and 5 % outliers: offline (robust maximum likelihood) within 1 % of the truth,
//! online (robust UKF, k a random-walk state) within two standard deviations; without the
//! robust weights the same data give a worse estimate.

mod common;

use common::*;
use nalgebra::DVector;
use spurio::estimation::likelihood::Initialisation;
use spurio::estimation::InfluenceFunction;
use spurio_identify::fmu_model::{FmuModel, Loss};
use spurio_identify::ukf::{Ukf, UkfSettings};
use spurio_identify::{maximise_likelihood, FreeParameter, Options};

const K: f64 = 1.5;
const SIGMA: f64 = 0.005;

fn data() -> (Vec<f64>, Vec<Vec<f64>>) {
    let plant = plant("Dahlquist", &["k"], &["x"], 1e-10);
    let t = times(101, 0.05);
    let clean = simulate(&plant, &[K], &t);
    let (noisy, outliers) = corrupt(&clean, SIGMA, 0.05, 20.0, 28);
    assert!(outliers.len() >= 3, "{} outliers", outliers.len());
    (t, noisy)
}

fn online(robust: Option<InfluenceFunction>) -> (f64, f64) {
    let (t, y) = data();
    let plant = plant("Dahlquist", &["k"], &["x"], 1e-8);
    let settings = UkfSettings {
        state_noise: vec![0.0],
        parameter_noise: vec![0.0],
        measurement_variance: vec![SIGMA * SIGMA],
        robust,
        alpha: 1.0,
        beta: 2.0,
        kappa: None,
    };
    let mut ukf = Ukf::new(plant, &[1.0], &[0], &[1.0], diag(&[1e-4, 0.25]), &settings).unwrap();
    let mut last = None;
    for (time, row) in t.iter().zip(&y) {
        last = Some(ukf.step(*time, &[], row).unwrap().0);
    }
    let last = last.unwrap();
    (last.estimate[1], last.standard_deviation[1])
}

fn offline(loss: Loss) -> (f64, Option<f64>) {
    let (t, y) = data();
    let plant = plant("Dahlquist", &["k"], &["x"], 1e-10);
    let model = FmuModel::new(plant, t, vec![Some(SIGMA * SIGMA)], vec![0.0], loss);
    let init = Initialisation::Known {
        x0: DVector::from_element(1, 1.0),
        p0: diag(&[1e-6]),
    };
    let fit = maximise_likelihood(
        &model,
        &record(&y),
        &init,
        &[FreeParameter::positive("k", &[1.0])],
        &Options {
            tolerance: 1e-8,
            ..Options::default()
        },
    )
    .unwrap();
    let e = fit.estimate("k").unwrap();
    (e.value, e.standard_error)
}

#[test]
fn k_offline_within_one_percent_and_online_within_two_sigma() {
    let (k_ml, se) = offline(Loss::Huber { c: 1.345 });
    let (k_plain, _) = offline(Loss::Gaussian);
    println!("offline robust k = {k_ml} ± {se:?}, Gaussian {k_plain}, truth {K}");
    assert!((k_ml - K).abs() < 0.01 * K, "k = {k_ml}");
    let (k_ukf, sd) = online(Some(InfluenceFunction::huber()));
    let (k_none, sd_none) = online(None);
    println!("online robust k = {k_ukf} ± {sd}, none {k_none} ± {sd_none}");
    println!(
        "error ratio none/robust: online {:.2}, offline {:.2}",
        (k_none - K).abs() / (k_ukf - K).abs(),
        (k_plain - K).abs() / (k_ml - K).abs()
    );
    assert!((k_ukf - K).abs() < 2.0 * sd, "k = {k_ukf} ± {sd}");
}
