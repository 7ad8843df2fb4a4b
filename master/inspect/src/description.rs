//! A model description of FMI 2.0 or FMI 3.0 read into one shape for both versions, every
//! element with its line, and nothing judged yet: what is absent stays `None`, what is
//! written stays text (the rules in [`crate::rules`] say what is wrong with it).
//!
//! FMI 2.0 writes a variable as `<ScalarVariable>` with one type element inside (`<Real
//! start="1"/>`) and addresses `ModelStructure` by 1-based position in `ModelVariables`;
//! FMI 3.0 writes the type as the element (`<Float64 start="1"/>`), an array's extent as
//! `<Dimension>` children, aliases as `<Alias>` children, and addresses `ModelStructure` by
//! value reference (FMI 2.0 section 2.2, FMI 3.0 section 2.4).

use crate::InspectError;
use roxmltree::{Document, Node};
use serde::Serialize;

/// The FMI version of a model description.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum Version {
    #[serde(rename = "2.0")]
    Fmi2,
    #[serde(rename = "3.0")]
    Fmi3,
}

impl Version {
    /// `2.0` or `3.0`.
    pub fn number(self) -> &'static str {
        match self {
            Self::Fmi2 => "2.0",
            Self::Fmi3 => "3.0",
        }
    }
}

/// An interface the FMU declares.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum InterfaceKind {
    ModelExchange,
    CoSimulation,
    ScheduledExecution,
}

impl InterfaceKind {
    /// The element that declares it.
    pub fn element(self) -> &'static str {
        match self {
            Self::ModelExchange => "ModelExchange",
            Self::CoSimulation => "CoSimulation",
            Self::ScheduledExecution => "ScheduledExecution",
        }
    }

    /// Its short name (`ME`, `CS`, `SE`).
    pub fn short(self) -> &'static str {
        match self {
            Self::ModelExchange => "ME",
            Self::CoSimulation => "CS",
            Self::ScheduledExecution => "SE",
        }
    }
}

/// `<ModelExchange>`, `<CoSimulation>` or `<ScheduledExecution>`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Interface {
    pub kind: InterfaceKind,
    pub model_identifier: Option<String>,
    pub line: u32,
}

/// `<DefaultExperiment>`, its attributes as written.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DefaultExperiment {
    pub start_time: Option<String>,
    pub stop_time: Option<String>,
    pub tolerance: Option<String>,
    pub step_size: Option<String>,
    pub line: u32,
}

/// A `<Unit>` of `UnitDefinitions` and the names of its display units.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Unit {
    pub name: String,
    pub display_units: Vec<String>,
    pub line: u32,
}

/// A type definition (FMI 2.0 `<SimpleType>`, FMI 3.0 `<Float64Type>` …).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TypeDefinition {
    pub name: String,
    /// `Real`, `Float64`, `Enumeration`, …
    pub type_name: String,
    pub unit: Option<String>,
    pub display_unit: Option<String>,
    pub line: u32,
}

/// An FMI 3.0 `<Dimension>`: a fixed extent (`start`) or the value reference of the
/// structural parameter that holds it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Dimension {
    pub start: Option<String>,
    pub value_reference: Option<String>,
    pub line: u32,
}

/// An FMI 3.0 `<Alias>`: another name of its variable.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Alias {
    pub name: String,
    pub description: Option<String>,
    pub display_unit: Option<String>,
    pub line: u32,
}

/// One variable of `ModelVariables`, its attributes as written.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Variable {
    pub name: String,
    pub value_reference: Option<String>,
    /// FMI 2.0: `Real`, `Integer`, `Boolean`, `String`, `Enumeration`; FMI 3.0: the element
    /// (`Float64`, `Int32`, `Binary`, `Clock`, …). Empty when an FMI 2.0 variable has no type
    /// element.
    pub type_name: String,
    pub description: Option<String>,
    /// As written; absent is `local`.
    pub causality: Option<String>,
    pub variability: Option<String>,
    pub initial: Option<String>,
    pub declared_type: Option<String>,
    pub unit: Option<String>,
    pub display_unit: Option<String>,
    /// The start value: the attribute, or FMI 3.0's `<Start value>` children of a String or
    /// Binary variable joined by spaces.
    pub start: Option<String>,
    pub min: Option<String>,
    pub max: Option<String>,
    pub nominal: Option<String>,
    /// FMI 2.0: the 1-based index of the state; FMI 3.0: its value reference.
    pub derivative: Option<String>,
    pub clocks: Option<String>,
    pub dimensions: Vec<Dimension>,
    pub aliases: Vec<Alias>,
    pub line: u32,
}

/// The lists of `ModelStructure`, in both versions' terms.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
pub enum StructureList {
    /// FMI 2.0 `<Outputs>`, FMI 3.0 `<Output>`.
    Outputs,
    /// FMI 2.0 `<Derivatives>`, FMI 3.0 `<ContinuousStateDerivative>`.
    Derivatives,
    /// FMI 2.0 `<InitialUnknowns>`, FMI 3.0 `<InitialUnknown>`.
    InitialUnknowns,
    /// FMI 3.0 `<ClockedState>`.
    ClockedStates,
    /// FMI 3.0 `<EventIndicator>`.
    EventIndicators,
}

impl StructureList {
    /// Where an entry of the list is, in `version`'s terms.
    pub fn place(self, version: Version) -> &'static str {
        match (version, self) {
            (Version::Fmi2, Self::Outputs) => "ModelStructure/Outputs",
            (Version::Fmi2, Self::Derivatives) => "ModelStructure/Derivatives",
            (Version::Fmi2, Self::InitialUnknowns) => "ModelStructure/InitialUnknowns",
            (Version::Fmi3, Self::Outputs) => "ModelStructure/Output",
            (Version::Fmi3, Self::Derivatives) => "ModelStructure/ContinuousStateDerivative",
            (Version::Fmi3, Self::InitialUnknowns) => "ModelStructure/InitialUnknown",
            (_, Self::ClockedStates) => "ModelStructure/ClockedState",
            (_, Self::EventIndicators) => "ModelStructure/EventIndicator",
        }
    }
}

/// An entry of `ModelStructure`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Unknown {
    pub list: StructureList,
    /// FMI 2.0: `index` (1-based position); FMI 3.0: `valueReference`.
    pub reference: Option<String>,
    /// Split at whitespace; `None` when the attribute is absent.
    pub dependencies: Option<Vec<String>>,
    pub dependencies_kind: Option<Vec<String>>,
    pub line: u32,
}

/// A model description of FMI 2.0 or 3.0.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ModelDescription {
    /// `fmiVersion` as written.
    pub fmi_version: String,
    pub version: Version,
    pub model_name: Option<String>,
    /// FMI 2.0 `guid`, FMI 3.0 `instantiationToken`.
    pub token: Option<String>,
    pub description: Option<String>,
    pub generation_tool: Option<String>,
    pub generation_date_and_time: Option<String>,
    /// `flat` (the default) or `structured`.
    pub variable_naming_convention: Option<String>,
    pub interfaces: Vec<Interface>,
    pub default_experiment: Option<DefaultExperiment>,
    pub units: Vec<Unit>,
    pub types: Vec<TypeDefinition>,
    pub variables: Vec<Variable>,
    pub structure: Vec<Unknown>,
}

/// The 1-based line of `node`.
fn line(doc: &Document, node: Node) -> u32 {
    doc.text_pos_at(node.range().start).row
}

fn text(node: Node, name: &str) -> Option<String> {
    node.attribute(name).map(str::to_string)
}

fn words(node: Node, name: &str) -> Option<Vec<String>> {
    node.attribute(name)
        .map(|v| v.split_whitespace().map(str::to_string).collect())
}

fn children<'a, 'input>(
    node: Node<'a, 'input>,
    name: &'a str,
) -> impl Iterator<Item = Node<'a, 'input>> + 'a {
    node.children()
        .filter(move |c| c.is_element() && c.tag_name().name() == name)
}

/// The FMI 2.0 type elements of a `<ScalarVariable>`.
const FMI2_TYPES: [&str; 5] = ["Real", "Integer", "Boolean", "String", "Enumeration"];

/// The FMI 3.0 variable elements.
pub const FMI3_TYPES: [&str; 15] = [
    "Float32",
    "Float64",
    "Int8",
    "UInt8",
    "Int16",
    "UInt16",
    "Int32",
    "UInt32",
    "Int64",
    "UInt64",
    "Boolean",
    "String",
    "Binary",
    "Enumeration",
    "Clock",
];

impl ModelDescription {
    /// Reads the text of a `modelDescription.xml`; fails only when it is not well-formed XML
    /// or its `fmiVersion` is neither 2.0 nor 3.x.
    pub fn parse(xml: &str) -> Result<Self, InspectError> {
        let options = roxmltree::ParsingOptions {
            allow_dtd: false,
            ..Default::default()
        };
        let doc =
            Document::parse_with_options(xml, options).map_err(|e| InspectError::IllFormed {
                file: "modelDescription.xml".into(),
                reason: e.to_string(),
            })?;
        let root = doc.root_element();
        if root.tag_name().name() != "fmiModelDescription" {
            return Err(InspectError::NotModelDescription(format!(
                "its root element is <{}>, not <fmiModelDescription>",
                root.tag_name().name()
            )));
        }
        let fmi_version = root.attribute("fmiVersion").unwrap_or_default().to_string();
        let version = if fmi_version == "2.0" {
            Version::Fmi2
        } else if fmi_version.starts_with("3.") {
            Version::Fmi3
        } else {
            return Err(InspectError::NotModelDescription(format!(
                "fmiVersion is `{fmi_version}`; FMI 2.0 and FMI 3.0 model descriptions are read"
            )));
        };
        let interfaces = [
            InterfaceKind::ModelExchange,
            InterfaceKind::CoSimulation,
            InterfaceKind::ScheduledExecution,
        ]
        .iter()
        .flat_map(|&kind| children(root, kind.element()).map(move |n| (kind, n)))
        .map(|(kind, n)| Interface {
            kind,
            model_identifier: text(n, "modelIdentifier"),
            line: line(&doc, n),
        })
        .collect();
        let default_experiment =
            children(root, "DefaultExperiment")
                .next()
                .map(|n| DefaultExperiment {
                    start_time: text(n, "startTime"),
                    stop_time: text(n, "stopTime"),
                    tolerance: text(n, "tolerance"),
                    step_size: text(n, "stepSize"),
                    line: line(&doc, n),
                });
        let units = children(root, "UnitDefinitions")
            .flat_map(|d| children(d, "Unit"))
            .map(|u| Unit {
                name: u.attribute("name").unwrap_or_default().to_string(),
                display_units: children(u, "DisplayUnit")
                    .filter_map(|d| text(d, "name"))
                    .collect(),
                line: line(&doc, u),
            })
            .collect();
        let types = children(root, "TypeDefinitions")
            .flat_map(|d| d.children().filter(|c| c.is_element()))
            .map(|t| {
                // FMI 2.0: <SimpleType name><Real unit/></SimpleType>; FMI 3.0: <Float64Type name unit/>.
                let (named, typed, type_name) = match version {
                    Version::Fmi2 => {
                        let inner = t.first_element_child().unwrap_or(t);
                        (t, inner, inner.tag_name().name().to_string())
                    }
                    Version::Fmi3 => {
                        let tag = t.tag_name().name();
                        (t, t, tag.strip_suffix("Type").unwrap_or(tag).to_string())
                    }
                };
                TypeDefinition {
                    name: named.attribute("name").unwrap_or_default().to_string(),
                    type_name,
                    unit: text(typed, "unit"),
                    display_unit: text(typed, "displayUnit"),
                    line: line(&doc, t),
                }
            })
            .collect();
        let variables = children(root, "ModelVariables")
            .flat_map(|m| m.children().filter(|c| c.is_element()))
            .map(|v| variable(&doc, v, version))
            .collect();
        let structure = children(root, "ModelStructure")
            .flat_map(|m| structure(&doc, m, version))
            .collect();
        Ok(Self {
            fmi_version,
            version,
            model_name: text(root, "modelName"),
            token: match version {
                Version::Fmi2 => text(root, "guid"),
                Version::Fmi3 => text(root, "instantiationToken"),
            },
            description: text(root, "description"),
            generation_tool: text(root, "generationTool"),
            generation_date_and_time: text(root, "generationDateAndTime"),
            variable_naming_convention: text(root, "variableNamingConvention"),
            interfaces,
            default_experiment,
            units,
            types,
            variables,
            structure,
        })
    }

    /// The type definition called `name`.
    pub fn type_definition(&self, name: &str) -> Option<&TypeDefinition> {
        self.types.iter().find(|t| t.name == name)
    }

    /// A variable's unit: its own, else its declared type's.
    pub fn unit_of(&self, v: &Variable) -> Option<String> {
        v.unit.clone().or_else(|| {
            v.declared_type
                .as_deref()
                .and_then(|t| self.type_definition(t))
                .and_then(|t| t.unit.clone())
        })
    }

    /// The variability in force: as written, else the standard's default (FMI 2.0:
    /// `continuous`; FMI 3.0: `fixed` for parameters, `continuous` for floats, `discrete`
    /// otherwise).
    pub fn variability(&self, v: &Variable) -> String {
        if let Some(written) = &v.variability {
            return written.clone();
        }
        let default = match self.version {
            Version::Fmi2 => "continuous",
            Version::Fmi3 => match v.causality() {
                "parameter" | "calculatedParameter" | "structuralParameter" => "fixed",
                _ if v.is_float() => "continuous",
                _ => "discrete",
            },
        };
        default.to_string()
    }

    /// The `initial` in force: as written, else the standard's default for the causality
    /// and variability (FMI 2.0 table in section 2.2.7, FMI 3.0 section 2.4.7.4); `None` for
    /// `independent` and for a combination that has no default (an illegal one).
    pub fn initial(&self, v: &Variable) -> Option<String> {
        if let Some(written) = &v.initial {
            return Some(written.clone());
        }
        let default = match (self.variability(v).as_str(), v.causality()) {
            ("constant", "output" | "local") => "exact",
            ("fixed" | "tunable", "parameter" | "structuralParameter") => "exact",
            ("fixed" | "tunable", "calculatedParameter" | "local") => "calculated",
            ("discrete" | "continuous", "input") => "exact",
            ("discrete" | "continuous", "output" | "local") => "calculated",
            _ => return None,
        };
        Some(default.to_string())
    }
}

impl Variable {
    /// The causality in force (absent is `local`).
    pub fn causality(&self) -> &str {
        self.causality.as_deref().unwrap_or("local")
    }

    /// Whether it is a floating-point variable (FMI 2.0 `Real`, FMI 3.0 `Float32`/`Float64`).
    pub fn is_float(&self) -> bool {
        matches!(self.type_name.as_str(), "Real" | "Float32" | "Float64")
    }
}

fn variable(doc: &Document, v: Node, version: Version) -> Variable {
    // Where the type's attributes are: FMI 2.0's inner element, FMI 3.0's variable itself.
    let (typed, type_name) = match version {
        Version::Fmi2 => match v
            .children()
            .find(|c| c.is_element() && FMI2_TYPES.contains(&c.tag_name().name()))
        {
            Some(t) => (t, t.tag_name().name().to_string()),
            None => (v, String::new()),
        },
        Version::Fmi3 => (v, v.tag_name().name().to_string()),
    };
    let start = text(typed, "start").or_else(|| {
        let values: Vec<&str> = children(v, "Start")
            .filter_map(|s| s.attribute("value"))
            .collect();
        (!values.is_empty()).then(|| values.join(" "))
    });
    Variable {
        name: v.attribute("name").unwrap_or_default().to_string(),
        value_reference: text(v, "valueReference"),
        type_name,
        description: text(v, "description"),
        causality: text(v, "causality"),
        variability: text(v, "variability"),
        initial: text(v, "initial"),
        declared_type: text(typed, "declaredType"),
        unit: text(typed, "unit"),
        display_unit: text(typed, "displayUnit"),
        start,
        min: text(typed, "min"),
        max: text(typed, "max"),
        nominal: text(typed, "nominal"),
        derivative: text(typed, "derivative"),
        clocks: text(v, "clocks"),
        dimensions: children(v, "Dimension")
            .map(|d| Dimension {
                start: text(d, "start"),
                value_reference: text(d, "valueReference"),
                line: line(doc, d),
            })
            .collect(),
        aliases: children(v, "Alias")
            .map(|a| Alias {
                name: a.attribute("name").unwrap_or_default().to_string(),
                description: text(a, "description"),
                display_unit: text(a, "displayUnit"),
                line: line(doc, a),
            })
            .collect(),
        line: line(doc, v),
    }
}

fn unknown(doc: &Document, u: Node, list: StructureList, reference: &str) -> Unknown {
    Unknown {
        list,
        reference: text(u, reference),
        dependencies: words(u, "dependencies"),
        dependencies_kind: words(u, "dependenciesKind"),
        line: line(doc, u),
    }
}

fn structure(doc: &Document, m: Node, version: Version) -> Vec<Unknown> {
    let mut out = Vec::new();
    match version {
        Version::Fmi2 => {
            for (element, list) in [
                ("Outputs", StructureList::Outputs),
                ("Derivatives", StructureList::Derivatives),
                ("InitialUnknowns", StructureList::InitialUnknowns),
            ] {
                for l in children(m, element) {
                    out.extend(children(l, "Unknown").map(|u| unknown(doc, u, list, "index")));
                }
            }
        }
        Version::Fmi3 => {
            for u in m.children().filter(|c| c.is_element()) {
                let list = match u.tag_name().name() {
                    "Output" => StructureList::Outputs,
                    "ContinuousStateDerivative" => StructureList::Derivatives,
                    "InitialUnknown" => StructureList::InitialUnknowns,
                    "ClockedState" => StructureList::ClockedStates,
                    "EventIndicator" => StructureList::EventIndicators,
                    _ => continue,
                };
                out.push(unknown(doc, u, list, "valueReference"));
            }
        }
    }
    out
}
