//! The committed `modelDescription/*.xml` files are the interface users see; they must be
//! exactly what the Rust variable tables generate (regenerate with
//! `spurio model-descriptions --write`).

use std::path::PathBuf;

#[test]
fn committed_model_descriptions_match_the_variable_tables() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../modelDescription");
    let mut checked = 0;
    for entry in spurio_fmus::catalogue() {
        for (stem, config) in &entry.variants {
            let generated = (entry.describe)(config).expect("describe").to_xml();
            let path = dir.join(format!("{stem}.xml"));
            let committed = std::fs::read_to_string(&path)
                .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            assert!(
                committed == generated,
                "{} differs from the variable table of {}: run `spurio model-descriptions --write`",
                path.display(),
                entry.model_identifier
            );
            checked += 1;
        }
    }
    assert!(checked >= 1);
}

#[test]
fn every_fmu_has_a_documentation_page_and_unique_names() {
    for entry in spurio_fmus::catalogue() {
        assert!(entry
            .documentation
            .starts_with(&format!("# {}", entry.model_identifier)));
        for (_, config) in &entry.variants {
            let info = (entry.describe)(config).expect("describe");
            let mut names: Vec<&str> = info.variables.iter().map(|v| v.name.as_str()).collect();
            names.sort_unstable();
            let n = names.len();
            names.dedup();
            assert_eq!(
                n,
                names.len(),
                "{}: duplicate variable names",
                entry.model_identifier
            );
        }
    }
}
