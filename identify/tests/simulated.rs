//! Maximum likelihood on records simulated by spurio's `LinearSystem` plant with known
//! parameters (docs/estimators.md, "Maximum likelihood"): the estimates lie within a few
//! standard errors of the truth; a parameter the data do not determine gives a Hessian that
//! is not positive definite; bad declarations are named.

use nalgebra::{dmatrix, DMatrix, DVector};
use spurio::estimation::likelihood::{Initialisation, LinearGaussianModel, ModelMatrix, Record};
use spurio::plants::linear_system::{LinearSystem, LinearSystemParameters, TimeDomain};
use spurio::state_space::StateSpace;
use spurio_identify::{maximise_likelihood, Curvature, FreeParameter, IdentifyError, Options};

/// The two-state model x⁺ = [[a, 0.3], [0, 0.6]] x + [0; b] u + w, y = [1 0] x + v,
/// Cov w = q I, Var v = r.
fn system(a: f64, b: f64, q: f64, r: f64) -> StateSpace {
    StateSpace {
        a: dmatrix![a, 0.3; 0.0, 0.6],
        b: dmatrix![0.0; b],
        c: dmatrix![1.0, 0.0],
        d: dmatrix![0.0],
        q: DMatrix::identity(2, 2) * q,
        r: dmatrix![r],
    }
}

/// `samples` samples of `system` driven by a square wave plus a sine, every 20th output
/// missing (NaN).
fn simulate(system: StateSpace, samples: usize, seed: u64) -> Record {
    let mut plant = LinearSystem::new(LinearSystemParameters {
        system,
        time_domain: TimeDomain::Discrete,
        initial_state: DVector::zeros(2),
        seed,
    })
    .unwrap();
    let (mut inputs, mut outputs) = (Vec::new(), Vec::new());
    for k in 0..samples {
        let t = k as f64;
        let square = if (k / 25) % 2 == 0 { 1.0 } else { -1.0 };
        let u = [square + 0.5 * (2.0 * std::f64::consts::PI * t / 13.0).sin()];
        let input = plant.input(&u).unwrap();
        let mut y = plant.output(input);
        if k % 20 == 19 {
            y[0] = f64::NAN;
        }
        inputs.push(DVector::from_column_slice(&u));
        outputs.push(y);
        plant.advance(input, 1.0).unwrap();
    }
    Record::new(inputs, outputs).unwrap()
}

fn two_state_model() -> LinearGaussianModel {
    LinearGaussianModel::new(system(0.0, 0.0, 1.0, 1.0))
        .unwrap()
        .free("a", ModelMatrix::A, &[(0, 0)])
        .unwrap()
        .free("b", ModelMatrix::B, &[(1, 0)])
        .unwrap()
        .free("q", ModelMatrix::Q, &[(0, 0), (1, 1)])
        .unwrap()
        .free("r", ModelMatrix::R, &[(0, 0)])
        .unwrap()
}

#[test]
fn a_simulated_two_state_model_is_identified_within_its_standard_errors() {
    let truth = [("a", 0.8), ("b", 0.5), ("q", 0.01), ("r", 0.04)];
    let record = simulate(system(0.8, 0.5, 0.01, 0.04), 3000, 3);
    let fit = maximise_likelihood(
        &two_state_model(),
        &record,
        &Initialisation::Diffuse { kappa: None },
        &[
            FreeParameter::real("a", &[0.3, 0.95]),
            FreeParameter::real("b", &[1.0]),
            FreeParameter::positive("q", &[0.1]),
            FreeParameter::positive("r", &[0.1]),
        ],
        &Options::default(),
    )
    .unwrap();
    assert_eq!(fit.log_likelihood.missing, 150);
    assert_eq!(
        fit.log_likelihood.left_out, 2,
        "two states: two samples diffuse"
    );
    for (name, true_value) in truth {
        let estimate = fit.estimate(name).unwrap();
        let se = estimate.standard_error.unwrap();
        println!("{name}: {} ± {se} (truth {true_value})", estimate.value);
        assert!(
            (estimate.value - true_value).abs() < 3.0 * se,
            "{name}: {} ± {se}, truth {true_value}",
            estimate.value
        );
        assert!(se < 0.3 * true_value, "{name}: se {se} is not small");
    }
    // Both starts of `a` reach the same optimum.
    assert_eq!(fit.runs.len(), 2);
    for run in &fit.runs {
        assert!(
            (run.log_likelihood - fit.log_likelihood.value).abs() < 1e-4,
            "{run:?}"
        );
    }
}

/// The local level with a free input gain b and a record whose input is zero: ℓ does not
/// depend on b, the Hessian has a zero row and is reported as not positive definite, with no
/// standard error.
#[test]
fn a_parameter_the_data_do_not_determine_gives_no_standard_error() {
    let one = || dmatrix![1.0];
    let mut with_input = StateSpace::without_input(one(), one(), one(), one());
    (with_input.b, with_input.d) = (dmatrix![0.0], dmatrix![0.0]);
    let model = LinearGaussianModel::new(with_input)
        .unwrap()
        .free("b", ModelMatrix::B, &[(0, 0)])
        .unwrap()
        .free("r", ModelMatrix::R, &[(0, 0)])
        .unwrap();
    let y: Vec<f64> = (0..60).map(|k| ((k * 7919) % 13) as f64 - 6.0).collect();
    let record = Record::new(
        vec![DVector::zeros(1); y.len()],
        y.iter().map(|&v| DVector::from_element(1, v)).collect(),
    )
    .unwrap();
    let fit = maximise_likelihood(
        &model,
        &record,
        &Initialisation::Diffuse { kappa: None },
        &[
            FreeParameter::real("b", &[0.5]),
            FreeParameter::positive("r", &[1.0]),
        ],
        &Options::default(),
    )
    .unwrap();
    assert_eq!(fit.curvature, Curvature::NotPositiveDefinite);
    assert!(fit.estimates.iter().all(|e| e.standard_error.is_none()));
    assert_eq!(fit.hessian[(0, 0)], 0.0);
}

#[test]
fn parameters_are_checked_by_name_before_anything_runs() {
    let model = LinearGaussianModel::local_level();
    let record = Record::of_output(&[1.0, 2.0, 3.0]).unwrap();
    let diffuse = Initialisation::Diffuse { kappa: None };
    let fit = |parameters: &[FreeParameter]| {
        maximise_likelihood(&model, &record, &diffuse, parameters, &Options::default()).unwrap_err()
    };
    let epsilon = FreeParameter::positive("sigma2_epsilon", &[1.0]);
    let error = fit(&[
        epsilon.clone(),
        FreeParameter::positive("sigma2_nu", &[1.0]),
    ]);
    assert_eq!(
        error.to_string(),
        "`sigma2_nu` is not a free parameter of the model; its free parameters are sigma2_epsilon, sigma2_eta"
    );
    assert!(matches!(
        fit(std::slice::from_ref(&epsilon)),
        IdentifyError::MissingParameter { name } if name == "sigma2_eta"
    ));
    let error = fit(&[
        epsilon.clone(),
        FreeParameter::positive("sigma2_eta", &[-1.0]),
    ]);
    assert!(error.to_string().contains("must be positive"), "{error}");
    let error = fit(&[epsilon.clone(), epsilon.clone()]);
    assert!(
        matches!(error, IdentifyError::DuplicateParameter { .. }),
        "{error}"
    );
    let fixed = LinearGaussianModel::new(system(0.8, 0.5, 0.01, 0.04)).unwrap();
    let error = maximise_likelihood(&fixed, &record, &diffuse, &[], &Options::default());
    assert_eq!(error.unwrap_err(), IdentifyError::NoFreeParameter);
}
