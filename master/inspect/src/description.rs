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

/// The FMI version of a model description.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Version {
    Fmi2,
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
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
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

/// An element as written: its attributes (in file order) and its line.
#[derive(Debug, Clone)]
pub struct Element {
    pub line: u32,
    pub attributes: Vec<(String, String)>,
}

impl Element {
    /// The attributes of `node` (no namespace) and its line.
    fn of(doc: &Document, node: Node) -> Self {
        Self {
            line: doc.text_pos_at(node.range().start).row,
            attributes: node
                .attributes()
                .filter(|a| a.namespace().is_none())
                .map(|a| (a.name().to_string(), a.value().to_string()))
                .collect(),
        }
    }

    /// The attribute `name`, if written.
    pub fn get(&self, name: &str) -> Option<&str> {
        self.attributes
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_str())
    }

    /// The attribute `name` as an owned string.
    pub fn text(&self, name: &str) -> Option<String> {
        self.get(name).map(str::to_string)
    }

    /// The attribute `name` split at whitespace; `None` when it is absent.
    pub fn words(&self, name: &str) -> Option<Vec<&str>> {
        self.get(name).map(|v| v.split_whitespace().collect())
    }
}

/// A type definition: FMI 2.0 `<SimpleType name>` with its type element, FMI 3.0
/// `<Float64Type name …>` and the like.
#[derive(Debug, Clone)]
pub struct TypeDefinition {
    /// `Real`, `Float64`, `Enumeration`, …
    pub type_name: String,
    /// The attributes of the definition (`name`) and of its type (`unit`, `displayUnit`, …).
    pub element: Element,
}

/// A `<Unit>` of `UnitDefinitions` and the names of its display units.
#[derive(Debug, Clone)]
pub struct Unit {
    pub element: Element,
    pub display_units: Vec<String>,
}

/// One variable of `ModelVariables`: its `type_name` (FMI 2.0: `Real`, `Integer`, `Boolean`,
/// `String`, `Enumeration`, empty when it has no type element; FMI 3.0: the element,
/// `Float64`, `Int32`, `Binary`, `Clock`, …); in `element` the attributes of the variable and,
/// in FMI 2.0, of its type element (`start`, `unit`, `min`, … live there; the two never share
/// a name), as written, where the `start` of an FMI 3.0 String or Binary variable is its
/// `<Start value>` children joined by spaces; FMI 3.0's `<Dimension>`s (a fixed extent
/// `start`, or the `valueReference` of the structural parameter that holds it) and
/// `<Alias>`es (`name`, `description`, `displayUnit`).
#[derive(Debug, Clone)]
pub struct Variable {
    pub type_name: String,
    pub element: Element,
    pub dimensions: Vec<Element>,
    pub aliases: Vec<Element>,
}

/// The lists of `ModelStructure`, in both versions' terms.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
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

/// An entry of `ModelStructure`: FMI 2.0 `<Unknown index>`, FMI 3.0 `<Output
/// valueReference>` and the like, with its `dependencies` and `dependenciesKind`.
#[derive(Debug, Clone)]
pub struct Unknown {
    pub list: StructureList,
    pub element: Element,
}

impl Unknown {
    /// The variable it is: FMI 2.0 `index` (1-based position), FMI 3.0 `valueReference`.
    pub fn reference(&self) -> Option<&str> {
        self.element
            .get("index")
            .or_else(|| self.element.get("valueReference"))
    }
}

/// A model description of FMI 2.0 or 3.0.
#[derive(Debug, Clone)]
pub struct ModelDescription {
    pub version: Version,
    /// `<fmiModelDescription>`: `fmiVersion`, `modelName`, `guid` (FMI 3.0:
    /// `instantiationToken`), `generationTool`, `variableNamingConvention`, …
    pub root: Element,
    pub interfaces: Vec<(InterfaceKind, Element)>,
    pub default_experiment: Option<Element>,
    pub units: Vec<Unit>,
    pub types: Vec<TypeDefinition>,
    pub variables: Vec<Variable>,
    pub structure: Vec<Unknown>,
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
        let fmi_version = root.attribute("fmiVersion").unwrap_or_default();
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
        .map(|(kind, n)| (kind, Element::of(&doc, n)))
        .collect();
        let units = children(root, "UnitDefinitions")
            .flat_map(|d| children(d, "Unit"))
            .map(|u| Unit {
                element: Element::of(&doc, u),
                display_units: children(u, "DisplayUnit")
                    .filter_map(|d| d.attribute("name").map(str::to_string))
                    .collect(),
            })
            .collect();
        let types = children(root, "TypeDefinitions")
            .flat_map(|d| d.children().filter(|c| c.is_element()))
            .map(|t| type_definition(&doc, t, version))
            .collect();
        let variables = children(root, "ModelVariables")
            .flat_map(|m| m.children().filter(|c| c.is_element()))
            .map(|v| variable(&doc, v, version))
            .collect();
        let structure = children(root, "ModelStructure")
            .flat_map(|m| structure(&doc, m, version))
            .collect();
        let default_experiment = children(root, "DefaultExperiment")
            .next()
            .map(|n| Element::of(&doc, n));
        Ok(Self {
            version,
            root: Element::of(&doc, root),
            interfaces,
            default_experiment,
            units,
            types,
            variables,
            structure,
        })
    }

    /// The GUID (FMI 2.0) or instantiation token (FMI 3.0).
    pub fn token(&self) -> Option<&str> {
        match self.version {
            Version::Fmi2 => self.root.get("guid"),
            Version::Fmi3 => self.root.get("instantiationToken"),
        }
    }

    /// The type definition called `name`.
    pub fn type_definition(&self, name: &str) -> Option<&TypeDefinition> {
        self.types
            .iter()
            .find(|t| t.element.get("name") == Some(name))
    }

    /// A variable's unit: its own, else its declared type's.
    pub fn unit_of<'a>(&'a self, v: &'a Variable) -> Option<&'a str> {
        v.element.get("unit").or_else(|| {
            v.element
                .get("declaredType")
                .and_then(|t| self.type_definition(t))
                .and_then(|t| t.element.get("unit"))
        })
    }

    /// The variability in force: as written, else the standard's default (FMI 2.0:
    /// `continuous`; FMI 3.0: `fixed` for parameters, `continuous` for floats, `discrete`
    /// otherwise).
    pub fn variability(&self, v: &Variable) -> String {
        if let Some(written) = v.element.get("variability") {
            return written.to_string();
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
        if let Some(written) = v.element.get("initial") {
            return Some(written.to_string());
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
        self.element.get("causality").unwrap_or("local")
    }

    /// Its line.
    pub fn line(&self) -> u32 {
        self.element.line
    }

    /// Its name.
    pub fn name(&self) -> &str {
        self.element.get("name").unwrap_or_default()
    }

    /// Its start value, if it has one.
    pub fn start(&self) -> Option<&str> {
        self.element.get("start")
    }

    /// Whether it is a floating-point variable (FMI 2.0 `Real`, FMI 3.0 `Float32`/`Float64`).
    pub fn is_float(&self) -> bool {
        matches!(self.type_name.as_str(), "Real" | "Float32" | "Float64")
    }
}

/// A type definition of `version`.
fn type_definition(doc: &Document, t: Node, version: Version) -> TypeDefinition {
    let mut element = Element::of(doc, t);
    let type_name = match version {
        // <SimpleType name><Real unit/></SimpleType>: the type element's attributes join the name.
        Version::Fmi2 => match t.first_element_child() {
            Some(inner) => {
                element
                    .attributes
                    .extend(Element::of(doc, inner).attributes);
                inner.tag_name().name().to_string()
            }
            None => String::new(),
        },
        // <Float64Type name unit/>
        Version::Fmi3 => {
            let tag = t.tag_name().name();
            tag.strip_suffix("Type").unwrap_or(tag).to_string()
        }
    };
    TypeDefinition { type_name, element }
}

fn variable(doc: &Document, v: Node, version: Version) -> Variable {
    let mut element = Element::of(doc, v);
    let mut type_name = v.tag_name().name().to_string();
    if version == Version::Fmi2 {
        // The type element's attributes (`start`, `unit`, …) join the variable's.
        let typed = v
            .children()
            .find(|c| c.is_element() && FMI2_TYPES.contains(&c.tag_name().name()));
        type_name = typed
            .map(|t| t.tag_name().name().to_string())
            .unwrap_or_default();
        if let Some(t) = typed {
            element.attributes.extend(Element::of(doc, t).attributes);
        }
    }
    let values: Vec<&str> = children(v, "Start")
        .filter_map(|s| s.attribute("value"))
        .collect();
    if element.get("start").is_none() && !values.is_empty() {
        element.attributes.push(("start".into(), values.join(" ")));
    }
    Variable {
        type_name,
        element,
        dimensions: children(v, "Dimension")
            .map(|d| Element::of(doc, d))
            .collect(),
        aliases: children(v, "Alias").map(|a| Element::of(doc, a)).collect(),
    }
}

fn structure(doc: &Document, m: Node, version: Version) -> Vec<Unknown> {
    let unknown = |list, u| Unknown {
        list,
        element: Element::of(doc, u),
    };
    let mut out = Vec::new();
    match version {
        Version::Fmi2 => {
            for (element, list) in [
                ("Outputs", StructureList::Outputs),
                ("Derivatives", StructureList::Derivatives),
                ("InitialUnknowns", StructureList::InitialUnknowns),
            ] {
                for l in children(m, element) {
                    out.extend(children(l, "Unknown").map(|u| unknown(list, u)));
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
                out.push(unknown(list, u));
            }
        }
    }
    out
}
