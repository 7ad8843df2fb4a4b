//! spurio-inspect: what any FMI 2.0 or FMI 3.0 FMU says about itself (`spurio info`) and
//! whether it says it by the standard (`spurio validate`), ours or a third party's, Model
//! Exchange, Co-Simulation or Scheduled Execution, without loading its binary.
//!
//! [`Fmu::open`] reads the archive ([`archive`]: entry names and `modelDescription.xml`,
//! bounded) and the model description into one shape for both versions
//! ([`ModelDescription`], every element with its line). [`Fmu::validate`] checks it against
//! the standard's XML schema ([`schema`], libxml2) and the rules the schema cannot express
//! ([`rules`]); each [`Problem`] names its rule, its place and its line.

pub mod archive;
pub mod description;
pub mod rules;
pub mod schema;

pub use description::{InterfaceKind, ModelDescription, Variable, Version};

use std::path::{Path, PathBuf};

/// Why an FMU cannot be inspected at all (a problem of its content is a [`Problem`]).
#[derive(Debug, thiserror::Error)]
pub enum InspectError {
    #[error("cannot read the file: {0}")]
    Open(String),
    #[error("not an FMU archive (an FMU is a zip file): {0}")]
    NotZip(String),
    #[error("the archive has no modelDescription.xml")]
    NoModelDescription,
    #[error("{0} is larger than {1} bytes")]
    TooLarge(String, u64),
    #[error("{file} is not well-formed XML: {reason}")]
    IllFormed { file: String, reason: String },
    #[error("modelDescription.xml: {0}")]
    NotModelDescription(String),
    #[error("the schema validation could not run: {0}")]
    Schema(String),
}

/// An [`InspectError`] with the FMU it concerns (its message quotes the error, which is
/// therefore not its source: the message is said once).
#[derive(Debug, thiserror::Error)]
#[error("{}: {error}", file.display())]
pub struct FmuError {
    pub file: PathBuf,
    pub error: InspectError,
}

/// The rule a problem breaks (see [`rules`] for what each checks).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Rule {
    /// The standard's XML schema.
    Schema,
    UniqueName,
    VariableName,
    ValueReference,
    /// Causality, variability and initial.
    Causality,
    StartValue,
    Bounds,
    UnitsAndTypes,
    Derivative,
    /// FMI 3.0 array dimensions.
    Dimension,
    ModelStructure,
    Dependencies,
    /// Interfaces and model identifiers.
    Interface,
    Binaries,
    DefaultExperiment,
    /// `terminalsAndIcons.xml`'s terminals name variables of the model description.
    Terminals,
    /// A layered standard's manifest (`extra/<name>/fmi-ls-manifest.xml`).
    LayeredStandard,
}

impl Rule {
    /// The rule's name in a report.
    pub fn name(self) -> &'static str {
        match self {
            Self::Schema => "schema",
            Self::UniqueName => "unique-name",
            Self::VariableName => "variable-name",
            Self::ValueReference => "value-reference",
            Self::Causality => "causality",
            Self::StartValue => "start-value",
            Self::Bounds => "bounds",
            Self::UnitsAndTypes => "units-and-types",
            Self::Derivative => "derivative",
            Self::Dimension => "dimension",
            Self::ModelStructure => "model-structure",
            Self::Dependencies => "dependencies",
            Self::Interface => "interface",
            Self::Binaries => "binaries",
            Self::DefaultExperiment => "default-experiment",
            Self::LayeredStandard => "layered-standard",
            Self::Terminals => "terminals",
        }
    }
}

/// How bad a problem is: an error breaks the standard; a warning is a problem that tools
/// accept (explained in its message).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Severity {
    Error,
    Warning,
}

/// One problem of an FMU: its rule, where it is and what is wrong.
#[derive(Debug, Clone, PartialEq)]
pub struct Problem {
    pub rule: Rule,
    pub severity: Severity,
    /// The element, variable or archive entry (`variable `x``, `ModelStructure/Outputs`).
    pub place: String,
    /// The line in `modelDescription.xml`, where there is one.
    pub line: Option<u32>,
    pub message: String,
}

impl std::fmt::Display for Problem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let severity = match self.severity {
            Severity::Error => "error",
            Severity::Warning => "warning",
        };
        match self.line {
            Some(line) => write!(
                f,
                "{severity}: line {line}: {}: {}",
                self.place, self.message
            )?,
            None => write!(f, "{severity}: {}: {}", self.place, self.message)?,
        }
        write!(f, " [{}]", self.rule.name())
    }
}

/// An FMU read for inspection.
pub struct Fmu {
    pub archive: archive::Archive,
    pub model_description: ModelDescription,
}

impl Fmu {
    /// Reads the FMU archive at `path` and its model description.
    pub fn open(path: &Path) -> Result<Self, FmuError> {
        let with_file = |error| FmuError {
            file: path.to_path_buf(),
            error,
        };
        let archive = archive::Archive::read(path).map_err(with_file)?;
        let model_description =
            ModelDescription::parse(&archive.model_description).map_err(with_file)?;
        Ok(Self {
            archive,
            model_description,
        })
    }

    /// Every problem: the schema's first, then the rules', then those of the other XML
    /// files of the standard the archive has.
    pub fn validate(&self) -> Result<Vec<Problem>, InspectError> {
        let md = &self.model_description;
        let model_schema = match md.version {
            Version::Fmi2 => schema::Schema::Fmi2ModelDescription,
            Version::Fmi3 => schema::Schema::Fmi3ModelDescription,
        };
        let mut problems = schema::validate(
            &self.archive.model_description,
            model_schema,
            "modelDescription.xml",
        )?;
        problems.extend(rules::check(md, &self.archive));
        for (name, text) in &self.archive.documents {
            problems.extend(document_problems(name, text, md)?);
        }
        Ok(problems)
    }

    /// The platform folders under `binaries/`.
    pub fn platforms(&self) -> Vec<String> {
        self.archive.platforms()
    }
}

/// The problems of one of the standard's XML files besides the model description `md`: not
/// well-formed; against its schema (`terminalsAndIcons.xml`, `buildDescription.xml`); a
/// terminal member that names no variable of `md`; a layered standard's manifest without
/// its name and version (`fmi-ls:fmi-ls-name`, `fmi-ls:fmi-ls-version`) or with a name that
/// is not its folder's (`extra/<name>/`).
fn document_problems(
    name: &str,
    text: &str,
    md: &ModelDescription,
) -> Result<Vec<Problem>, InspectError> {
    let problem = |line: Option<u32>, message: String| Problem {
        rule: Rule::Schema,
        severity: Severity::Error,
        place: name.to_string(),
        line,
        message,
    };
    let options = roxmltree::ParsingOptions {
        allow_dtd: false,
        ..Default::default()
    };
    let doc = match roxmltree::Document::parse_with_options(text, options) {
        Ok(doc) => doc,
        Err(e) => {
            let line = Some(e.pos().row);
            return Ok(vec![problem(line, format!("not well-formed XML: {e}"))]);
        }
    };
    let schema = match name {
        "terminalsAndIcons/terminalsAndIcons.xml" => schema::Schema::Fmi3TerminalsAndIcons,
        "sources/buildDescription.xml" => schema::Schema::Fmi3BuildDescription,
        "extra/org.fmi-standard.fmi-ls-ref/fmi-ls-manifest.xml" => {
            let mut problems = manifest_problems(&doc, name);
            problems.extend(ls_ref_problems(&doc, text, name)?);
            return Ok(problems);
        }
        _ => {
            return Ok(manifest_problems(&doc, name));
        }
    };
    let mut problems = schema::validate(text, schema, name)?;
    if schema == schema::Schema::Fmi3TerminalsAndIcons {
        let known = |n: &str| {
            md.variables
                .iter()
                .any(|v| v.name() == n || v.aliases.iter().any(|a| a.get("name") == Some(n)))
        };
        let members = doc
            .descendants()
            .filter(|n| n.has_tag_name("TerminalMemberVariable"));
        for member in members {
            let Some(variable) = member.attribute("variableName") else {
                continue; // the schema names the missing attribute
            };
            if !known(variable) {
                problems.push(Problem {
                    rule: Rule::Terminals,
                    severity: Severity::Error,
                    place: name.to_string(),
                    line: Some(doc.text_pos_at(member.range().start).row),
                    message: format!(
                        "the terminal member variableName=\"{variable}\" names no variable of modelDescription.xml"
                    ),
                });
            }
        }
    }
    Ok(problems)
}

/// The problems of the layered standard's manifest `name` (`extra/<layer>/fmi-ls-manifest.xml`,
/// FMI 3.0 section 2.5): its root element must carry `fmi-ls:fmi-ls-name` and
/// `fmi-ls:fmi-ls-version`. A name other than the folder's, or an empty version, is a
/// warning: the standard names the folder after the layered standard (reverse domain
/// notation, `org.fmi-standard.fmi-ls-ref`) and asks for its version, but an importer of the
/// FMU itself does not read the manifest.
fn manifest_problems(doc: &roxmltree::Document, name: &str) -> Vec<Problem> {
    const MANIFEST: &str = "http://fmi-standard.org/fmi-ls-manifest";
    let root = doc.root_element();
    let layer = name
        .strip_prefix("extra/")
        .and_then(|rest| rest.strip_suffix("/fmi-ls-manifest.xml"))
        .unwrap_or_default();
    let line = Some(doc.text_pos_at(root.range().start).row);
    let element = root.tag_name().name();
    let problem = |severity, message| Problem {
        rule: Rule::LayeredStandard,
        severity,
        place: name.to_string(),
        line,
        message,
    };
    let mut problems = Vec::new();
    match root.attribute((MANIFEST, "fmi-ls-name")) {
        None => problems.push(problem(
            Severity::Error,
            format!("the root element <{element}> has no fmi-ls:fmi-ls-name (namespace {MANIFEST})"),
        )),
        Some(n) if n != layer => problems.push(problem(
            Severity::Warning,
            format!(
                "fmi-ls:fmi-ls-name is \"{n}\" but the manifest's folder is extra/{layer}/: FMI 3.0 (section 2.5) \
                 names the folder after the layered standard, in reverse domain notation, so a tool that looks the \
                 layer up by one will not find it by the other (importers that only run the FMU ignore the manifest)"
            ),
        )),
        Some(_) => {}
    }
    match root.attribute((MANIFEST, "fmi-ls-version")) {
        None => problems.push(problem(
            Severity::Error,
            format!("the root element <{element}> has no fmi-ls:fmi-ls-version"),
        )),
        Some(v) if v.trim().is_empty() => problems.push(problem(
            Severity::Warning,
            "fmi-ls:fmi-ls-version is empty: a tool cannot tell which version of the layered standard \
             the files follow (importers that only run the FMU ignore the manifest)"
                .into(),
        )),
        Some(_) => {}
    }
    problems
}

/// The problems of fmi-ls-ref's manifest against the schema of version
/// [`schema::LS_REF_VERSION`]. A manifest that declares another version (the Reference FMUs
/// v0.0.41 write the draft 1.0.0-alpha.1, `<Related>` elements only) cannot be held to it:
/// its problems are warnings that say so.
fn ls_ref_problems(
    doc: &roxmltree::Document,
    text: &str,
    name: &str,
) -> Result<Vec<Problem>, InspectError> {
    const MANIFEST: &str = "http://fmi-standard.org/fmi-ls-manifest";
    let declared = doc
        .root_element()
        .attribute((MANIFEST, "fmi-ls-version"))
        .unwrap_or_default();
    let mut problems = schema::validate(text, schema::Schema::LsRefManifest, name)?;
    if declared != schema::LS_REF_VERSION {
        for p in &mut problems {
            p.severity = Severity::Warning;
            p.message = format!(
                "{} (the manifest declares fmi-ls-ref version \"{declared}\"; the schema is of version {}, \
                 so this is a warning: the draft it follows may allow it)",
                p.message,
                schema::LS_REF_VERSION
            );
        }
    }
    Ok(problems)
}
