//! An FMU's XML files checked against the standard's XML schemas with libxml2's XML Schema
//! validator: the model description (FMI 2.0 `fmi2ModelDescription.xsd`, FMI 3.0
//! `fmi3ModelDescription.xsd`) and FMI 3.0's other files where an FMU has them,
//! `terminalsAndIcons/terminalsAndIcons.xml` (`fmi3TerminalsAndIcons.xsd`) and
//! `sources/buildDescription.xml` (`fmi3BuildDescription.xsd`), and the manifest of the
//! layered standard fmi-ls-ref, `extra/org.fmi-standard.fmi-ls-ref/fmi-ls-manifest.xml`
//! (`fmi3LayeredStandardReferenceManifest.xsd`, which imports the FMI 3.0 manifest
//! attributes from `../fmi3/`). The schema files are the standard's own, committed under
//! `master/inspect/schema/` (BSD licence; `schema/README.md` says where they come from) and
//! built into the library; they are written to a temporary folder for libxml2, which
//! resolves their `xs:include`s beside them.

use crate::{InspectError, Problem, Rule};
use libxml::parser::{Parser, ParserOptions};
use libxml::schemas::{SchemaParserContext, SchemaValidationContext};
use std::sync::Mutex;

/// The schema files of each folder, `schema/<folder>/*.xsd`: (file name, text), listed by the
/// build script (`build.rs`).
const FOLDERS: [(&str, &[(&str, &str)]); 3] = [
    ("fmi2", include!(concat!(env!("OUT_DIR"), "/fmi2.rs"))),
    ("fmi3", include!(concat!(env!("OUT_DIR"), "/fmi3.rs"))),
    (
        "fmi-ls-ref",
        include!(concat!(env!("OUT_DIR"), "/fmi-ls-ref.rs")),
    ),
];

/// A schema of the standard: the kind of file it describes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Schema {
    Fmi2ModelDescription,
    Fmi3ModelDescription,
    Fmi3TerminalsAndIcons,
    Fmi3BuildDescription,
    /// The manifest of fmi-ls-ref, version 1.0.0-rc.1 ([`LS_REF_VERSION`]).
    LsRefManifest,
}

/// The version of fmi-ls-ref whose manifest schema is built in.
pub const LS_REF_VERSION: &str = "1.0.0-rc.1";

impl Schema {
    /// Its entry point, `<folder>/<file>`.
    fn entry(self) -> &'static str {
        match self {
            Self::Fmi2ModelDescription => "fmi2/fmi2ModelDescription.xsd",
            Self::Fmi3ModelDescription => "fmi3/fmi3ModelDescription.xsd",
            Self::Fmi3TerminalsAndIcons => "fmi3/fmi3TerminalsAndIcons.xsd",
            Self::Fmi3BuildDescription => "fmi3/fmi3BuildDescription.xsd",
            Self::LsRefManifest => "fmi-ls-ref/fmi3LayeredStandardReferenceManifest.xsd",
        }
    }
}

/// libxml2's schema code is used by one thread at a time (its wrapper is not documented as
/// safe to share between threads).
static LIBXML: Mutex<()> = Mutex::new(());

/// The complaints of `schema` about `xml` (the well-formed text of the archive entry
/// `place`), each with its line.
pub fn validate(xml: &str, schema: Schema, place: &str) -> Result<Vec<Problem>, InspectError> {
    let folder = tempfile::Builder::new()
        .prefix("spurio-xsd-")
        .tempdir()
        .map_err(|e| InspectError::Schema(format!("cannot create a temporary folder: {e}")))?;
    for (sub, files) in FOLDERS {
        let sub = folder.path().join(sub);
        std::fs::create_dir(&sub)
            .map_err(|e| InspectError::Schema(format!("cannot create {}: {e}", sub.display())))?;
        for (name, text) in files {
            std::fs::write(sub.join(name), text)
                .map_err(|e| InspectError::Schema(format!("cannot write {name}: {e}")))?;
        }
    }
    let entry = folder.path().join(schema.entry());
    let entry = entry
        .to_str()
        .ok_or_else(|| InspectError::Schema(format!("{} is not UTF-8", entry.display())))?
        .to_string();
    let _one_at_a_time = LIBXML
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner());
    // The wrapper panics where libxml2 returns a null context (out of memory): that is
    // answered as an error, not a crash.
    std::panic::catch_unwind(|| run(&entry, xml, place)).unwrap_or_else(|_| {
        Err(InspectError::Schema(
            "libxml2 failed to set up the validation".into(),
        ))
    })
}

fn run(schema: &str, xml: &str, place: &str) -> Result<Vec<Problem>, InspectError> {
    let mut parser = SchemaParserContext::from_file(schema);
    let mut context = SchemaValidationContext::from_parser(&mut parser).map_err(|errors| {
        let first = errors
            .first()
            .and_then(|e| e.message.clone())
            .unwrap_or_default();
        InspectError::Schema(format!(
            "the built-in schema {schema} does not parse: {first}"
        ))
    })?;
    let options = ParserOptions {
        recover: false,
        no_net: true,
        ..Default::default()
    };
    let document = Parser::default()
        .parse_string_with_options(xml, options)
        .map_err(|e| InspectError::IllFormed {
            file: place.to_string(),
            reason: format!("libxml2: {e:?}"),
        })?;
    let problems = match context.validate_document(&document) {
        Ok(()) => Vec::new(),
        Err(errors) => errors
            .into_iter()
            .map(|e| Problem {
                rule: Rule::Schema,
                severity: crate::Severity::Error,
                place: place.to_string(),
                line: e
                    .line
                    .and_then(|l| u32::try_from(l).ok())
                    .filter(|l| *l > 0),
                message: e
                    .message
                    .unwrap_or_else(|| "the schema refuses it".into())
                    .trim()
                    .to_string(),
            })
            .collect(),
    };
    Ok(problems)
}
