//! The extended filter on a linear FMU is the Kalman filter of the sampled system: Dahlquist
//! (ẋ = −k x, y = x) sampled every h is x_{k+1} = e^{−kh} x_k, whose scalar Kalman filter is
//! written out here; the EKF on the FMU (its transition matrix by differences of the
//! integrator, its measurement Jacobian by differences of the outputs) must give the same
//! estimates and standard deviations to the integrator's tolerance.

mod common;

use spurio_identify::filter::{Filter, FilterSettings, Linearisation, Noise};

#[test]
fn ekf_on_dahlquist_equals_the_scalar_kalman_filter() {
    let (k, h, q, r) = (1.5, 0.05, 1e-4, 0.01f64.powi(2));
    let plant = common::plant("Dahlquist", &["k"], &["x"], 1e-12);
    let t = common::times(60, h);
    let clean = common::simulate(&plant, &[k], &t);
    let (y, _) = common::corrupt(&clean, 0.01, 0.0, 0.0, 7);
    let x0 = plant.borrow_mut().initial_states(&[k]).expect("x0");
    let p0 = 0.04;
    let settings = FilterSettings {
        noise: Noise::new(q, 1, 0.0, 0, &[r]),
        robust: None,
        linearisation: Linearisation::Extended,
    };
    let mut ekf = Filter::new(plant, &[k], &[], &x0, common::diag(&[p0]), &settings).unwrap();
    let trajectory = ekf.run(&t, &vec![Vec::new(); t.len()], &y).unwrap();
    // The scalar Kalman filter: the first sample corrects the prior, the later ones predict
    // x⁻ = a x̂, P⁻ = a² P + q first.
    let a = (-k * h).exp();
    let (mut x, mut p) = (x0[0], p0);
    let mut worst = 0.0f64;
    for (i, row) in y.iter().enumerate() {
        if i > 0 {
            x *= a;
            p = a * a * p + q;
        }
        let gain = p / (p + r);
        let innovation = row[0] - x;
        x += gain * innovation;
        p *= 1.0 - gain;
        assert!(
            (trajectory.innovation(i, 0) - innovation).abs() < 1e-8,
            "{i}"
        );
        let errors = [
            (trajectory.estimate(i, 0) - x).abs(),
            (trajectory.standard_deviation(i, 0) - p.sqrt()).abs() / p.sqrt(),
            trajectory.weight(i, 0) - 1.0,
        ];
        worst = errors.iter().fold(worst, |w, e| w.max(e.abs()));
    }
    println!("EKF vs Kalman filter: largest difference {worst:e}");
    assert!(worst < 1e-8, "{worst:e}");
}

#[test]
fn directional_derivatives_give_the_analytic_jacobian_and_none_where_not_provided() {
    use spurio_identify::plant::Start;
    // VanDerPol: ẋ₀ = x₁, ẋ₁ = μ (1 − x₀²) x₁ − x₀, so at x = (2, 0.5), μ = 1.3:
    // A = [[0, 1], [−2 μ x₀ x₁ − 1, μ (1 − x₀²)]] = [[0, 1], [−3.6, −3.9]].
    let plant = common::plant("VanDerPol", &["mu"], &["x0"], 1e-10);
    plant.borrow_mut().initial_states(&[1.3]).expect("x0");
    let start = Start {
        time: 0.0,
        states: &[2.0, 0.5],
        parameters: &[1.3],
        inputs: &[],
        reference: None,
    };
    let a = plant
        .borrow_mut()
        .state_jacobian(&start)
        .unwrap()
        .expect("A");
    let expected = [0.0, -3.6, 1.0, -3.9]; // column-major
    for (got, want) in a.iter().zip(expected) {
        assert!((got - want).abs() < 1e-12, "{a:?}");
    }
    let dahlquist = common::plant("Dahlquist", &["k"], &["x"], 1e-10);
    dahlquist.borrow_mut().initial_states(&[1.0]).expect("x0");
    let start = Start {
        states: &[1.0],
        parameters: &[1.0],
        ..start
    };
    assert!(dahlquist
        .borrow_mut()
        .state_jacobian(&start)
        .unwrap()
        .is_none());
}

#[test]
fn an_outlier_is_weighted_down_and_a_missing_sample_only_predicts() {
    let (k, h, r) = (1.5, 0.05, 0.01f64.powi(2));
    let plant = common::plant("Dahlquist", &["k"], &["x"], 1e-12);
    let t = common::times(40, h);
    let mut y = common::simulate(&plant, &[k], &t);
    y[20][0] += 0.5; // 50 σ
    y[30][0] = f64::NAN;
    let x0 = plant.borrow_mut().initial_states(&[k]).expect("x0");
    let settings = FilterSettings {
        noise: Noise::new(1e-8, 1, 0.0, 0, &[r]),
        robust: Some(spurio::estimation::InfluenceFunction::huber()),
        linearisation: Linearisation::Extended,
    };
    let mut ekf = Filter::new(plant, &[k], &[], &x0, common::diag(&[1e-4]), &settings).unwrap();
    let tr = ekf.run(&t, &vec![Vec::new(); t.len()], &y).unwrap();
    // Huber's weight c/|r| at a 50 σ innovation (r ≈ 50): about 1.645/50.
    let w = tr.weight(20, 0);
    assert!(w > 0.0 && w < 0.05, "{w}");
    assert!(
        (tr.estimate(20, 0) - y[19][0] * (-k * h).exp()).abs() < 0.02,
        "{}",
        tr.estimate(20, 0)
    );
    assert!(tr.weight(30, 0).is_nan() && tr.innovation(30, 0).is_nan());
    let predicted = tr.estimate(29, 0) * (-k * h).exp();
    assert!((tr.estimate(30, 0) - predicted).abs() < 1e-9);
    // P⁻ = a² P + Q, uncorrected.
    let a2 = (-2.0 * k * h).exp();
    let p_prior = a2 * tr.standard_deviation(29, 0).powi(2) + 1e-8;
    assert!((tr.standard_deviation(30, 0).powi(2) - p_prior).abs() < 1e-12 * p_prior.max(1.0));
    assert!(tr.weight(10, 0) == 1.0);
}
