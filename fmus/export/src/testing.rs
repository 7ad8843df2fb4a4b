//! Checks every FMU crate runs on itself (the [`export_fmu!`](crate::export_fmu) macro
//! generates a test calling [`check_bundled_variants`]).

use crate::model::FmuModel;
use crate::query::Variant;
use std::path::Path;

/// Each bundled variant describes itself, has unique variable names, and its generated
/// `modelDescription.xml` equals the committed `<repo>/modelDescription/<stem>.xml` (FMI 2.0)
/// and `<repo>/modelDescription/fmi3/<stem>.xml` (FMI 3.0); the
/// FMU's page (`<crate>/README.md`) starts with `# <modelIdentifier>`. A library that bundles
/// none (an FMU only a packager writes, for a configuration it is given) must refuse the
/// empty configuration, so that no tool mistakes it for a variant.
pub fn check_bundled_variants<M: FmuModel>(variants: &[Variant], crate_dir: &Path) {
    if variants.is_empty() {
        let refused = M::describe(&crate::description::Config::new()).is_err();
        assert!(
            refused,
            "no bundled variant, yet the empty configuration describes one"
        );
    }
    let repo = crate_dir.join("../..");
    for (stem, config) in variants {
        let info = M::describe(config).unwrap_or_else(|e| panic!("{stem}: {e}"));
        let mut names: Vec<&str> = info.variables.iter().map(|v| v.name.as_str()).collect();
        names.sort_unstable();
        let n = names.len();
        names.dedup();
        assert_eq!(n, names.len(), "{stem}: duplicate variable names");
        let path = repo.join("modelDescription").join(format!("{stem}.xml"));
        let committed =
            std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        assert!(
            committed == info.to_xml(),
            "{} differs from the variable table of {}: run `spurio model-descriptions --write`",
            path.display(),
            info.model_identifier
        );
        let path = repo
            .join("modelDescription/fmi3")
            .join(format!("{stem}.xml"));
        let committed =
            std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        assert!(
            committed == crate::description::fmi3::model_description(&info),
            "{} differs from the variable table of {}: run `spurio model-descriptions --write`",
            path.display(),
            info.model_identifier
        );
        let page = std::fs::read_to_string(crate_dir.join("README.md"))
            .unwrap_or_else(|e| panic!("{}: README.md: {e}", crate_dir.display()));
        assert!(page.starts_with(&format!("# {}", info.model_identifier)));
    }
}

/// Each bundled variant declares Model Exchange in its description
/// ([`crate::ModelInfo::with_model_exchange`]) exactly when the FMU is exported with it
/// (`export_fmu!(Model, model_exchange)`, `exported`).
pub fn check_interfaces<M: FmuModel>(variants: &[Variant], exported: bool) {
    for (stem, config) in variants {
        let info = M::describe(config).unwrap_or_else(|e| panic!("{stem}: {e}"));
        assert_eq!(
            info.model_exchange.is_some(),
            exported,
            "{stem}: the description declares Model Exchange: {}, export_fmu! exports it: {exported}",
            info.model_exchange.is_some()
        );
    }
}
