//! The spurio FMUs as safe Rust: for each FMU, its variable table and its step function over
//! the plain-Rust models of the `spurio` crate. Each FMU binary (`fmus/<ModelIdentifier>/`)
//! is one line: `spurio_fmi2::export_fmu!(…)` on a type of this crate.
//!
//! [`catalogue`] lists every FMU with its documentation page and its packaged variants: the
//! packager writes `.fmu` archives from it, and the tests check that the committed
//! `modelDescription/*.xml` files equal what it generates.

pub mod estimators;
pub mod gantry_crane;
pub mod structured;

use spurio_fmi2::{Config, FmuModel, ModelInfo};

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
    CatalogueEntry {
        model_identifier,
        documentation,
        images: &[],
        describe,
        variants: vec![(model_identifier.to_string(), Config::new())],
    }
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
        generic(
            "KalmanFilter",
            include_str!("../../../docs/fmus/KalmanFilter.md"),
            KalmanFilterFmu::describe,
            vec![("KalmanFilter", dims_config(1, 0, 1))],
        ),
        generic(
            "RobustKalmanFilter",
            include_str!("../../../docs/fmus/RobustKalmanFilter.md"),
            RobustKalmanFilterFmu::describe,
            vec![("RobustKalmanFilter", dims_config(1, 0, 1))],
        ),
        generic(
            "DualKalmanFilter",
            include_str!("../../../docs/fmus/DualKalmanFilter.md"),
            DualKalmanFilterFmu::describe,
            vec![("DualKalmanFilter", dims_config(4, 1, 2))],
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
