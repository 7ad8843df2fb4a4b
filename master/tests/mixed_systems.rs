//! Model Exchange instances inside co-simulation systems (issue 26, "Mixed systems"): two
//! continuous LinearSystems in a chain, integrated by the master as one ODE, against the
//! closed-form solution of the combined linear ODE; the same chain as Co-Simulation
//! instances (the second one's input held over each step) for the difference; and the
//! errors of a system file's Model Exchange keys.

mod common;

use spurio_master::fmu::Interface;
use spurio_master::ssp::SspVersion;
use spurio_master::{RunOptions, System, SystemDescription, SystemError};

/// `exp(M t)` of a square matrix (row-major, `n × n`) by scaling and squaring a Taylor
/// series: `exp(M t) = (Σₖ (M t / 2ˢ)ᵏ / k!)^(2ˢ)` with `‖M t‖ / 2ˢ < 1/2`, 30 terms (far below
/// round-off there).
fn expm(m: &[f64], n: usize, t: f64) -> Vec<f64> {
    let norm: f64 = m.iter().map(|v| (v * t).abs()).sum();
    let squarings = (norm / 0.5).log2().ceil().max(0.0) as i32;
    let scale = t / 2f64.powi(squarings);
    let product = |a: &[f64], b: &[f64]| {
        let mut c = vec![0.0; n * n];
        for i in 0..n {
            for k in 0..n {
                for j in 0..n {
                    c[i * n + j] += a[i * n + k] * b[k * n + j];
                }
            }
        }
        c
    };
    let a: Vec<f64> = m.iter().map(|v| v * scale).collect();
    let mut sum = vec![0.0; n * n];
    let mut term = vec![0.0; n * n];
    for i in 0..n {
        sum[i * n + i] = 1.0;
        term[i * n + i] = 1.0;
    }
    for k in 1..30 {
        term = product(&term, &a).iter().map(|v| v / k as f64).collect();
        for (s, t) in sum.iter_mut().zip(&term) {
            *s += t;
        }
    }
    for _ in 0..squarings {
        sum = product(&sum, &sum);
    }
    sum
}

/// Plant `a`: ẋₐ = A₁ xₐ + B₁ u₁, yₐ = C₁ xₐ + D₁ u₁ (a damped oscillator driven by the
/// constant u₁ = 1, with feedthrough D₁ = 0.5); plant `b`: ẋ_b = A₂ x_b + B₂ yₐ. The
/// parameters of each as a system file writes them.
const PLANT_A: &str = r#""A[1,1]" = 0.0, "A[1,2]" = 1.0, "A[2,1]" = -4.0, "A[2,2]" = -0.4, "B[1,1]" = 0.0, "B[2,1]" = 1.0, "C[1,1]" = 1.0, "C[1,2]" = 0.0, "D[1,1]" = 0.5, "x0[1]" = 1.0, "x0[2]" = 0.0, "u[1]" = 1.0, "Q[1,1]" = 0.0, "Q[2,2]" = 0.0, "R[1,1]" = 0.0, continuous = true"#;
const PLANT_B: &str = r#""A[1,1]" = -1.0, "A[1,2]" = 0.0, "A[2,1]" = 1.0, "A[2,2]" = -2.0, "B[1,1]" = 1.0, "B[2,1]" = 0.0, "C[1,1]" = 0.0, "C[1,2]" = 1.0, "D[1,1]" = 0.0, "x0[1]" = 0.0, "x0[2]" = 0.0, "Q[1,1]" = 0.0, "Q[2,2]" = 0.0, "R[1,1]" = 0.0, continuous = true"#;

/// The combined ODE ż = M z of z = (xₐ, x_b, 1) (the constant input as a fifth state):
/// its solution `exp(M t) z₀` at `t`.
fn chain_solution(t: f64) -> [f64; 4] {
    #[rustfmt::skip]
    let m = [
        0.0, 1.0, 0.0, 0.0, 0.0,
        -4.0, -0.4, 0.0, 0.0, 1.0,
        1.0, 0.0, -1.0, 0.0, 0.5,
        0.0, 0.0, 1.0, -2.0, 0.0,
        0.0, 0.0, 0.0, 0.0, 0.0,
    ];
    let z0 = [1.0, 0.0, 0.0, 0.0, 1.0];
    let e = expm(&m, 5, t);
    let mut z = [0.0; 4];
    for (i, zi) in z.iter_mut().enumerate() {
        *zi = (0..5).map(|j| e[i * 5 + j] * z0[j]).sum();
    }
    z
}

/// The chain `a.y[1] -> b.u[1]` run with the interface `interface` (and `extra` keys on
/// each instance) with communication step `step` until 5 s: the largest deviation of
/// `b.x[1]`, `b.x[2]` and `a.x[1]` from the closed-form solution over the recorded points.
fn chain_error(interface: &str, extra: &str, step: f64) -> f64 {
    deviation(&chain(interface, extra, step))
}

/// The chain system of [`chain_error`].
fn chain(interface: &str, extra: &str, step: f64) -> System {
    let instances: String = [("a", PLANT_A), ("b", PLANT_B)]
        .iter()
        .map(|(name, parameters)| {
            format!(
                "[[instance]]\nname = \"{name}\"\nfmu = \"LinearSystem.fmu\"\ninterface = \"{interface}\"\n{extra}\nparameters = {{ {parameters} }}\n"
            )
        })
        .collect();
    let text = format!(
        "stop_time = 5.0\nstep_size = {step:?}\nconnections = [\"a.y[1] -> b.u[1]\"]\nrecord = [\"a.x[1]\", \"b.x[1]\", \"b.x[2]\"]\n{instances}"
    );
    common::resolve(&text).unwrap()
}

/// The largest deviation of the chain's records from the closed-form solution.
fn deviation(system: &System) -> f64 {
    let (series, _) = common::run(system, &RunOptions::default());
    assert!((series.time.last().unwrap() - 5.0).abs() < 1e-12);
    let mut worst: f64 = 0.0;
    for (t, row) in series.time.iter().zip(&series.rows) {
        let z = chain_solution(*t);
        for (value, exact) in row.iter().zip([z[0], z[2], z[3]]) {
            worst = worst.max((value - exact).abs());
        }
    }
    worst
}

#[test]
fn a_chain_of_model_exchange_fmus_is_one_ode_and_matches_the_closed_form_solution() {
    // As one ODE: only the solver's error (tolerance 1e-9), whatever the communication step.
    let coupled = chain_error("me", "tolerance = 1e-9", 0.1);
    let coupled_coarse = chain_error("me", "tolerance = 1e-9", 0.5);
    // As Co-Simulation: each plant exact over a step, but b's input held at yₐ(t_k).
    let delayed = chain_error("cs", "", 0.1);
    println!(
        "largest deviation from exp(M t) z0 over 0–5 s: Model Exchange as one ODE {coupled:.2e} (step 0.1 s), {coupled_coarse:.2e} (step 0.5 s); Co-Simulation, input held over 0.1 s steps {delayed:.2e}"
    );
    assert!(coupled < 1e-7, "{coupled}");
    assert!(coupled_coarse < 1e-7, "{coupled_coarse}");
    assert!(delayed > 1e-3, "{delayed}");
    assert!(delayed > 1e4 * coupled);
}

#[test]
fn the_stiff_solvers_integrate_the_chain_too() {
    for solver in ["rodas3", "shampine4"] {
        let error = chain_error(
            "me",
            &format!("solver = \"{solver}\"\ntolerance = 1e-8"),
            0.1,
        );
        println!("{solver}: largest deviation {error:.2e}");
        assert!(error < 1e-5, "{solver}: {error}");
    }
}

#[test]
fn an_algebraic_loop_between_model_exchange_fmus_is_refused_naming_them() {
    // y depends on u in both (D ≠ 0): a.y → b.u → b.y → a.u is an algebraic loop.
    for algorithm in ["gauss-seidel", "jacobi"] {
        let text = format!(
            r#"
            stop_time = 1.0
            step_size = 0.1
            algorithm = "{algorithm}"
            connections = ["a.y[1] -> b.u[1]", "b.y[1] -> a.u[1]"]
            [[instance]]
            name = "a"
            fmu = "LinearSystem.fmu"
            interface = "me"
            [[instance]]
            name = "b"
            fmu = "LinearSystem.fmu"
            interface = "me"
            "#
        );
        let e = common::resolve(&text).unwrap_err();
        assert!(matches!(e, SystemError::ModelExchangeLoop { .. }), "{e}");
        common::assert_names(
            &e.to_string(),
            &[
                "algebraic loop",
                "Model Exchange",
                "`a`",
                "`b`",
                "a.u[1]",
                "b.u[1]",
            ],
        );
    }
}

#[test]
fn bad_model_exchange_keys_are_errors_naming_the_line_and_the_instance() {
    let parse = |keys: &str| {
        let text = format!(
            "stop_time = 1.0\nstep_size = 0.1\n[[instance]]\nname = \"a\"\nfmu = \"LinearSystem.fmu\"\n{keys}\n"
        );
        toml::from_str::<SystemDescription>(&text)
            .unwrap_err()
            .to_string()
    };
    common::assert_names(
        &parse("solver = \"euler\""),
        &["line 6", "unknown solver `euler`", "dopri5", "rodas3"],
    );
    common::assert_names(
        &parse("tolerance = -1e-6"),
        &["line 6", "expected a positive number"],
    );
    common::assert_names(&parse("max_step = 0"), &["line 6", "positive"]);
    common::assert_names(&parse("interface = \"fmi\""), &["line 6", "me", "cs"]);
    // A Co-Simulation instance takes no solver.
    let e = common::resolve(
        "stop_time = 1.0\nstep_size = 0.1\n[[instance]]\nname = \"a\"\nfmu = \"LinearSystem.fmu\"\nsolver = \"rodas3\"\n",
    )
    .unwrap_err();
    common::assert_names(
        &e.to_string(),
        &[
            "instance `a`",
            "LinearSystem.fmu",
            "Co-Simulation",
            "interface = \"me\"",
        ],
    );
}

#[test]
fn an_ssp_marks_the_model_exchange_components_and_runs_them_so() {
    let system = chain("me", "", 0.1);
    let dir = tempfile::tempdir().unwrap();
    let ssp = dir.path().join("chain.ssp");
    system.export_ssp(&ssp, SspVersion::V1_0).unwrap();
    let ssd = {
        use std::io::Read;
        let mut archive = zip::ZipArchive::new(std::fs::File::open(&ssp).unwrap()).unwrap();
        let mut text = String::new();
        let mut entry = archive.by_name("SystemStructure.ssd").unwrap();
        entry.read_to_string(&mut text).unwrap();
        text
    };
    assert_eq!(
        ssd.matches(r#"implementation="ModelExchange""#).count(),
        2,
        "{ssd}"
    );
    let imported = System::from_file(&ssp).unwrap();
    for instance in imported.instances() {
        assert_eq!(
            instance.fmu.interface,
            Interface::ModelExchange,
            "{}",
            instance.name
        );
    }
    // The imported chain is the same ODE (at the default tolerance 1e-6).
    let error = deviation(&imported);
    assert!(error < 1e-5, "{error}");
    assert_eq!(error, deviation(&system));
}

/// A system (keys `head`) of one instance `name` of the FMU `fmu` run as Model Exchange
/// (with the instance keys `keys`).
fn reference_system(fmu: &std::path::Path, head: &str, name: &str, keys: &str) -> System {
    let text = format!(
        "{head}\n[[instance]]\nname = \"{name}\"\nfmu = {:?}\ninterface = \"me\"\n{keys}\n",
        fmu.display().to_string()
    );
    common::resolve(&text).unwrap()
}

#[test]
fn state_events_inside_a_communication_step_are_handled_as_in_a_single_fmu_run() {
    // BouncingBall (FMI 2.0 and 3.0) as a system instance: its bounces fall inside the
    // 0.01 s steps; the heights at the communication points are those of `simulate` on the
    // same grid, to the solvers' accuracy (the system restarts the solver at every point).
    for version in ["fmi2", "fmi3"] {
        let fmu = common::reference(version, "BouncingBall");
        let system = reference_system(
            &fmu,
            "stop_time = 3.0\nstep_size = 0.01\nrecord = [\"ball.h\"]",
            "ball",
            "tolerance = 1e-9",
        );
        let (series, _) = common::run(&system, &RunOptions::default());
        let file = spurio_master::fmu::FmuFile::open_for(
            &fmu,
            &Default::default(),
            Interface::ModelExchange,
        )
        .unwrap();
        let mut instance = file.instantiate_model_exchange("ball", false).unwrap();
        let mut layout = instance.layout(&file, &[]).unwrap();
        layout.recorded.retain(|r| r.0 == "h");
        let options = spurio_master::model_exchange::Options {
            tolerance: 1e-9,
            ..spurio_master::model_exchange::Options::new(0.0, 3.0, 0.01)
        };
        let mut alone = spurio_master::TimeSeries::default();
        let summary = spurio_master::model_exchange::simulate(
            &mut instance,
            &layout,
            &options,
            &mut alone,
            &mut |_| {},
        )
        .unwrap();
        assert!(summary.state_events >= 8, "{summary:?}");
        assert_eq!(series.time.len(), alone.time.len());
        let (h, h_alone) = (series.column("ball.h").unwrap(), alone.column("h").unwrap());
        let worst = h
            .iter()
            .zip(&h_alone)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        println!("{version} BouncingBall in a system against alone: max |Δh| = {worst:.2e} m");
        assert!(worst < 1e-9, "{version}: {worst}");
    }
}

#[test]
fn a_model_exchange_fmu_that_ends_the_simulation_ends_the_run_where_it_asked() {
    // Stair counts the seconds with time events and asks to end at t = 9 (FMI 2.0 and 3.0).
    for version in ["fmi2", "fmi3"] {
        let fmu = common::reference(version, "Stair");
        let system = reference_system(&fmu, "stop_time = 10.0\nstep_size = 0.2", "stair", "");
        let (series, end) = common::run(&system, &RunOptions::default());
        let spurio_master::RunEnd::Terminated {
            instance,
            time,
            interface,
            ..
        } = &end
        else {
            panic!("{version}: {end:?}")
        };
        assert_eq!(
            (instance.as_str(), *interface),
            ("stair", Interface::ModelExchange)
        );
        assert!((time - 9.0).abs() < 1e-12, "{version}: {time}");
        assert_eq!(series.time.last(), Some(time));
        assert_eq!(series.column("stair.counter").unwrap().last(), Some(&10.0));
        common::assert_names(&end.to_string(), &["`stair`", "t = 9", "Model Exchange"]);
    }
}

#[test]
fn an_fmu_with_model_exchange_only_is_integrated_without_being_asked() {
    // LinearSystem without its <CoSimulation> element: no `interface` key needed.
    let dir = tempfile::tempdir().unwrap();
    let only_me = dir.path().join("LinearSystemME.fmu");
    let bytes = common::rewrite(
        &common::fmus().join("LinearSystem.fmu"),
        |name, data| {
            if name != "modelDescription.xml" {
                return Some(data);
            }
            let text = String::from_utf8(data).unwrap();
            let start = text.find("<CoSimulation").unwrap();
            let end = start + text[start..].find("/>").unwrap() + 2;
            Some(format!("{}{}", &text[..start], &text[end..]).into_bytes())
        },
        &[],
    );
    std::fs::write(&only_me, bytes).unwrap();
    let text = format!(
        "stop_time = 1.0\nstep_size = 0.1\nrecord = [\"p.x[1]\"]\n[[instance]]\nname = \"p\"\nfmu = {:?}\nparameters = {{ continuous = true, \"A[1,1]\" = -1.0, \"A[1,2]\" = 0.0, \"A[2,1]\" = 0.0, \"A[2,2]\" = -1.0, \"x0[1]\" = 1.0 }}\n",
        only_me.display().to_string()
    );
    let system = common::resolve(&text).unwrap();
    assert_eq!(
        system.instance("p").unwrap().fmu.interface,
        Interface::ModelExchange
    );
    // ẋ = −x from 1 (B u with u = 0): e^{−t}.
    let (series, _) = common::run(&system, &RunOptions::default());
    let x = series.column("p.x[1]").unwrap();
    for (t, x) in series.time.iter().zip(&x) {
        assert!((x - (-t).exp()).abs() < 1e-5, "t = {t}: {x}");
    }
    // Asking for Co-Simulation is refused, naming the interface.
    let e =
        common::resolve(&text.replace("parameters", "interface = \"cs\"\nparameters")).unwrap_err();
    common::assert_names(&e.to_string(), &["LinearSystemME.fmu", "Co-Simulation"]);
}
