//! Durbin & Koopman's Nile local-level example (docs/estimators.md, "Maximum likelihood"):
//! `cargo run --release -p spurio-identify --example nile` prints the maximum-likelihood
//! variances with their standard errors, the log-likelihood and the runs.

use spurio::estimation::likelihood::{Initialisation, LinearGaussianModel, Record};
use spurio_identify::{maximise_likelihood, nile, Curvature, FreeParameter, Options};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let (years, flows) = nile::flows()?;
    let record = Record::of_output(&flows)?;
    let options = Options::default();
    let fit = maximise_likelihood(
        &LinearGaussianModel::local_level(),
        &record,
        &Initialisation::Diffuse { kappa: None },
        &[
            FreeParameter::positive("sigma2_epsilon", &[1e3, 1e4, 1e5]),
            FreeParameter::positive("sigma2_eta", &[1e2, 1e3, 1e4]),
        ],
        &options,
    )?;
    println!(
        "Nile flows {}–{} ({} samples), local level x⁺ = x + η, y = x + ε, diffuse x₀",
        years[0],
        years[years.len() - 1],
        flows.len()
    );
    println!("parameter       estimate   std. error   start (best run)");
    for estimate in &fit.estimates {
        let se = estimate
            .standard_error
            .map_or_else(|| "n/a".to_string(), |se| format!("{se:.1}"));
        println!(
            "{:<14} {:>9.2} {:>12} {:>10}",
            estimate.name, estimate.value, se, estimate.start
        );
    }
    if let Curvature::NotPositiveDefinite = fit.curvature {
        println!("the Hessian of −ℓ at the optimum is not positive definite: no standard errors");
    }
    let ll = &fit.log_likelihood;
    println!(
        "log-likelihood ℓ = {:.4} ({} terms, {} left out as diffuse, {} missing)",
        ll.value, ll.terms, ll.left_out, ll.missing
    );
    println!(
        "Nelder–Mead (argmin) on ln σ², sd(−ℓ) over the simplex < {:e}: {} starts, best run {}, polish {} iterations",
        options.tolerance,
        fit.runs.len(),
        fit.best_run + 1,
        fit.polish_iterations
    );
    for (i, run) in fit.runs.iter().enumerate() {
        println!(
            "  run {}: start {:?} -> {:?}, ℓ = {:.6}, {} iterations{}",
            i + 1,
            run.start,
            run.estimate
                .iter()
                .map(|v| (v * 100.0).round() / 100.0)
                .collect::<Vec<_>>(),
            run.log_likelihood,
            run.iterations,
            if run.converged {
                ""
            } else {
                " (not converged)"
            }
        );
    }
    println!("Durbin & Koopman: σ²_ε = 15099, σ²_η = 1469.1");
    Ok(())
}
