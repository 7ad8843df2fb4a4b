//! The extended filter's parameter column at a bound of the parameter's declared range:
//! BouncingBall's coefficient of restitution e ∈ [0.5, 1]. Dropped from h₀ = 1 m at rest, the
//! ball reaches the floor at t_b = √(2h₀/g) with speed v_b = g t_b and leaves it with e v_b,
//! so after the bounce h = e v_b τ − g τ²/2 and v = e v_b − g τ (τ = t − t_b): ∂h/∂e = v_b τ,
//! ∂v/∂e = v_b, whatever e. With P₀ = diag(0, 0, σ²) and a measurement too noisy to correct,
//! P⁻ = Φ P₀ Φᵀ gives the column Φ_xe = P[x, e] / P[e, e] after the first interval. At e = 1 a
//! central difference would evaluate the plant at Π(1 + δ) = 1 and give half of it
//! (docs/estimators.md, "Parameters within their declared range").

mod common;

use spurio_identify::filter::{Filter, FilterSettings, Linearisation, Noise};

const G: f64 = 9.81;
const T1: f64 = 0.6;

/// Φ_he and Φ_ve over [0, T1] of the EKF on BouncingBall at e.
fn parameter_column(e: f64) -> (f64, f64) {
    let plant = common::plant("BouncingBall", &["e"], &["h"], 1e-10);
    let x0 = plant.borrow_mut().initial_states(&[e]).expect("x0");
    assert_eq!(x0, [1.0, 0.0]);
    let settings = FilterSettings {
        noise: Noise::new(0.0, 2, 0.0, 1, &[1e6]),
        robust: None,
        linearisation: Linearisation::Extended,
    };
    let p0 = common::diag(&[1e-30, 1e-30, 0.01]);
    let mut ekf = Filter::new(plant, &[e], &[0], &x0, p0, &settings).expect("the filter");
    let mut column = vec![0.0; 2 * 3 + 3];
    ekf.step(0.0, &[], &[1.0], &mut column).expect("t = 0");
    let t_b = (2.0 / G).sqrt();
    let h = e * G * t_b * (T1 - t_b) - 0.5 * G * (T1 - t_b).powi(2);
    ekf.step(T1, &[], &[h], &mut column).expect("t = 0.6");
    let p = ekf.covariance();
    (p[(0, 2)] / p[(2, 2)], p[(1, 2)] / p[(2, 2)])
}

#[test]
fn the_parameter_column_at_a_bound_is_the_one_sided_slope_not_half_of_it() {
    let t_b = (2.0 / G).sqrt();
    let v_b = G * t_b;
    let expected = (v_b * (T1 - t_b), v_b);
    for e in [0.8, 1.0, 0.5] {
        let (dh, dv) = parameter_column(e);
        println!(
            "e = {e}: ∂h/∂e {dh:.9} (analytic {:.9}), ∂v/∂e {dv:.9} (analytic {:.9})",
            expected.0, expected.1
        );
        assert!(
            (dh - expected.0).abs() < 1e-5 * expected.0,
            "e = {e}: ∂h/∂e {dh}"
        );
        assert!(
            (dv - expected.1).abs() < 1e-5 * expected.1,
            "e = {e}: ∂v/∂e {dv}"
        );
    }
}
