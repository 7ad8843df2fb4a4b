//! Durbin & Koopman's Nile local-level example (docs/estimators.md, "Maximum likelihood"):
//! `cargo run --release -p spurio-identify --example nile` prints the maximum-likelihood
//! variances with their standard errors, the log-likelihood and the runs.

use spurio_identify::{nile, Curvature, Options};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let (years, flows) = nile::flows()?;
    // nile::fit searches with the default options.
    let options = Options::default();
    let fit = nile::fit(&flows)?;
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
    let [epsilon, eta] = nile::DURBIN_KOOPMAN;
    println!("Durbin & Koopman: σ²_ε = {epsilon}, σ²_η = {eta}");
    Ok(())
}
