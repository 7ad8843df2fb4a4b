//! The spurio FMUs as safe Rust: for each FMU, its variable table and its step function over
//! the plain-Rust models of the `spurio` crate. Each FMU binary (`fmus/<ModelIdentifier>/`)
//! is one line: `spurio_fmi2::export_fmu!(…)` on a type of this crate.
//!
//! [`catalogue`] lists every FMU with its documentation page and its packaged variants: the
//! packager writes `.fmu` archives from it, and the tests check that the committed
//! `modelDescription/*.xml` files equal what it generates.

pub mod adaptive_state_feedback;
pub mod estimators;
pub mod gantry_crane;
pub mod linear_system;
pub mod opamp_filter;
pub mod sensor;
pub mod signal_source;
pub mod state_feedback;
pub mod structured;
pub mod wind_generator;

use spurio_fmi2::{Config, Failure, FmuModel, ModelInfo};

/// A parameter error of the `spurio` models as an `fmi2Error` naming the parameter.
pub(crate) fn param_failure(e: &spurio::ParameterError) -> Failure {
    Failure::Error(e.to_string())
}

/// One FMU of the product.
pub struct CatalogueEntry {
    /// `modelIdentifier` (also the name of the binary crate's library).
    pub model_identifier: &'static str,
    /// The FMU's documentation page (Markdown), packaged as `documentation/index.html`.
    pub documentation: &'static str,
    /// Pictures the page shows, packaged beside it as `documentation/<file name>` (the page
    /// refers to them as `img/<file name>`, relative to `docs/fmus/`).
    pub images: &'static [(&'static str, &'static [u8])],
    /// Builds the interface for a configuration.
    pub describe: fn(&Config) -> Result<ModelInfo, String>,
    /// The variants committed under `modelDescription/` and bundled: (file stem, config).
    pub variants: Vec<(String, Config)>,
}

fn fixed(
    model_identifier: &'static str,
    documentation: &'static str,
    describe: fn(&Config) -> Result<ModelInfo, String>,
) -> CatalogueEntry {
    generic(
        model_identifier,
        documentation,
        describe,
        vec![(model_identifier, Config::new())],
    )
}

/// The bundled variant of the controllers: the crane (n = 4, `preset = crane`).
pub(crate) fn crane_controller_config() -> Config {
    let mut config = Config::new();
    config.set(state_feedback::CONFIG_STATES, 4);
    config.set(state_feedback::CONFIG_PRESET, "crane");
    config
}

fn generic(
    model_identifier: &'static str,
    documentation: &'static str,
    describe: fn(&Config) -> Result<ModelInfo, String>,
    variants: Vec<(&str, Config)>,
) -> CatalogueEntry {
    CatalogueEntry {
        model_identifier,
        documentation,
        images: &[],
        describe,
        variants: variants
            .into_iter()
            .map(|(stem, config)| (stem.to_string(), config))
            .collect(),
    }
}

/// Every FMU of the product.
pub fn catalogue() -> Vec<CatalogueEntry> {
    let config = |pairs: &[(&str, &str)]| {
        let mut c = Config::new();
        for (k, v) in pairs {
            c.set(k, v);
        }
        c
    };
    use estimators::distributed::{agent_config, DistributedObserverFmu};
    use estimators::dual::{DkfRsKfFmu, DualKalmanFilterFmu};
    use estimators::kalman::{dims_config, KalmanFilterFmu, RobustKalmanFilterFmu};
    use estimators::rls::{arx_config, RecursiveLeastSquaresFmu};
    vec![
        fixed(
            "GantryCrane",
            include_str!("../../../docs/fmus/GantryCrane.md"),
            gantry_crane::GantryCraneFmu::describe,
        ),
        CatalogueEntry {
            model_identifier: "StateFeedback",
            documentation: include_str!("../../../docs/fmus/StateFeedback.md"),
            images: &[],
            describe: state_feedback::StateFeedbackFmu::describe,
            variants: vec![("StateFeedback".to_string(), crane_controller_config())],
        },
        CatalogueEntry {
            model_identifier: "AdaptiveStateFeedback",
            documentation: include_str!("../../../docs/fmus/AdaptiveStateFeedback.md"),
            images: &[],
            describe: adaptive_state_feedback::AdaptiveStateFeedbackFmu::describe,
            variants: vec![(
                "AdaptiveStateFeedback".to_string(),
                crane_controller_config(),
            )],
        },
        CatalogueEntry {
            images: &[(
                "wind_generator_steps.png",
                include_bytes!("../../../docs/fmus/img/wind_generator_steps.png"),
            )],
            ..fixed(
                "WindGenerator",
                include_str!("../../../docs/fmus/WindGenerator.md"),
                wind_generator::WindGeneratorFmu::describe,
            )
        },
        fixed(
            "OpAmpFilter",
            include_str!("../../../docs/fmus/OpAmpFilter.md"),
            opamp_filter::OpAmpFilterFmu::describe,
        ),
        CatalogueEntry {
            variants: vec![
                ("LinearSystem".to_string(), Config::new()),
                (
                    "DistributedObserverPlant".to_string(),
                    config(&[("n", "3"), ("m", "0"), ("p", "2"), ("preset", "paper004")]),
                ),
                (
                    "LinearSystem2".to_string(),
                    config(&[("n", "2"), ("m", "2"), ("p", "2")]),
                ),
            ],
            ..fixed(
                "LinearSystem",
                include_str!("../../../docs/fmus/LinearSystem.md"),
                linear_system::LinearSystemFmu::describe,
            )
        },
        fixed(
            "SignalSource",
            include_str!("../../../docs/fmus/SignalSource.md"),
            signal_source::SignalSourceFmu::describe,
        ),
        CatalogueEntry {
            variants: vec![
                ("Sensor".to_string(), Config::new()),
                ("Sensor2".to_string(), config(&[("channels", "2")])),
            ],
            ..fixed(
                "Sensor",
                include_str!("../../../docs/fmus/Sensor.md"),
                sensor::SensorFmu::describe,
            )
        },
        generic(
            "KalmanFilter",
            include_str!("../../../docs/fmus/KalmanFilter.md"),
            KalmanFilterFmu::describe,
            vec![
                ("KalmanFilter", dims_config(1, 0, 1)),
                ("DistributedObserverCentralKalman", dims_config(3, 0, 2)),
            ],
        ),
        generic(
            "RobustKalmanFilter",
            include_str!("../../../docs/fmus/RobustKalmanFilter.md"),
            RobustKalmanFilterFmu::describe,
            vec![
                ("RobustKalmanFilter", dims_config(1, 0, 1)),
                ("RobustKalmanFilter2", dims_config(2, 0, 2)),
            ],
        ),
        generic(
            "DualKalmanFilter",
            include_str!("../../../docs/fmus/DualKalmanFilter.md"),
            DualKalmanFilterFmu::describe,
            vec![
                ("DualKalmanFilter", dims_config(4, 1, 2)),
                ("DualKalmanFilterGenerator", dims_config(8, 2, 2)),
            ],
        ),
        generic(
            "DkfRsKf",
            include_str!("../../../docs/fmus/DkfRsKf.md"),
            DkfRsKfFmu::describe,
            vec![
                ("DkfRsKf", dims_config(4, 1, 2)),
                ("DkfRsKfGenerator", dims_config(8, 2, 2)),
            ],
        ),
        generic(
            "RecursiveLeastSquares",
            include_str!("../../../docs/fmus/RecursiveLeastSquares.md"),
            RecursiveLeastSquaresFmu::describe,
            vec![("RecursiveLeastSquares", arx_config(2, 2))],
        ),
        generic(
            "DistributedObserver",
            include_str!("../../../docs/fmus/DistributedObserver.md"),
            DistributedObserverFmu::describe,
            vec![
                ("DistributedObserverAgent1", agent_config(1)),
                ("DistributedObserverAgent2", agent_config(2)),
            ],
        ),
    ]
}

/// Test helper: the variable table has exactly these value references, with these names.
#[cfg(test)]
pub(crate) fn assert_value_references(
    variables: &[spurio_fmi2::Variable],
    expect: &[(usize, &str)],
) {
    for (i, name) in expect {
        assert_eq!(variables[*i].name, *name, "value reference {i}");
    }
}
