//! The identity of an FMU and its `modelDescription.xml`, generated from the variable table.
//!
//! The XML is written by hand (no dependency) in the element order of the FMI 2.0 schema.
//! The GUID is a hash of everything in the interface, so a binary and a modelDescription
//! built from different tables (or a variant packaged for other dimensions) never match.
//!
//! The FMI 3.0 view of the same identity is in [`fmi3`] (its description) over [`arrays`]
//! (the table's structured scalars as arrays); the Model Exchange interface a table declares
//! is [`model_exchange`]. This layer stands on the variable table alone: the model trait, the
//! instance and the fronts are above it.

pub mod arrays;
pub mod fmi3;
pub mod model_exchange;
#[cfg(test)]
mod model_exchange_tests;

use crate::variables::{Causality, Value, Variable};
use model_exchange::{DeclarationError, ModelExchangeInfo};
use std::collections::BTreeMap;
use std::fmt::Write;

/// A packaging-time configuration of a dimension-generic FMU: `key = value` lines, read from
/// `resources/variant.cfg` inside the FMU. Static FMUs have an empty one.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Config {
    entries: BTreeMap<String, String>,
}

/// Why a configuration is not acceptable.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ConfigError {
    /// A line that is not `key = value`.
    Syntax { line: usize, text: String },
    /// A dimension that is not a positive integer.
    NotPositive { key: String, value: String },
}

impl std::fmt::Display for ConfigError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Syntax { line, text } => write!(
                f,
                "{CONFIG_FILE} line {line}: expected `key = value`, got `{text}`"
            ),
            Self::NotPositive { key, value } => write!(
                f,
                "{CONFIG_FILE}: `{key}` must be a positive integer, got `{value}`"
            ),
        }
    }
}

impl std::error::Error for ConfigError {}

/// File name of the configuration inside the FMU's `resources/` folder.
pub const CONFIG_FILE: &str = "variant.cfg";

impl Config {
    /// An empty configuration.
    pub fn new() -> Self {
        Self::default()
    }
    /// Parses `key = value` lines; `#` starts a comment.
    pub fn parse(text: &str) -> Result<Self, ConfigError> {
        let mut entries = BTreeMap::new();
        for (n, line) in text.lines().enumerate() {
            let line = line.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            let (key, value) = line.split_once('=').ok_or_else(|| ConfigError::Syntax {
                line: n + 1,
                text: line.to_string(),
            })?;
            entries.insert(key.trim().to_string(), value.trim().to_string());
        }
        Ok(Self { entries })
    }
    /// Sets a key.
    pub fn set(&mut self, key: &str, value: impl ToString) {
        self.entries.insert(key.to_string(), value.to_string());
    }
    /// The raw value of `key`.
    pub fn get(&self, key: &str) -> Option<&str> {
        self.entries.get(key).map(|s| s.as_str())
    }
    /// `key` as a positive integer, or `default` when absent.
    pub fn dimension(&self, key: &str, default: usize) -> Result<usize, ConfigError> {
        match self.get(key) {
            None => Ok(default),
            Some(v) => match v.parse::<usize>() {
                Ok(n) if n > 0 => Ok(n),
                _ => Err(ConfigError::NotPositive {
                    key: key.to_string(),
                    value: v.to_string(),
                }),
            },
        }
    }
    /// Whether the configuration is empty.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }
    /// The file text (sorted keys).
    pub fn to_text(&self) -> String {
        let mut s = String::new();
        for (k, v) in &self.entries {
            let _ = writeln!(s, "{k} = {v}");
        }
        s
    }
}

/// `DefaultExperiment` of the model description.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DefaultExperiment {
    pub start_time: f64,
    pub stop_time: f64,
    pub step_size: f64,
}

/// Everything `modelDescription.xml` says about one FMU (or one variant of a generic FMU).
#[derive(Debug, Clone, PartialEq)]
pub struct ModelInfo {
    /// `modelName` (also the name users see).
    pub model_name: String,
    /// `modelIdentifier`: the binary's file name without extension.
    pub model_identifier: String,
    /// What the FMU is.
    pub description: String,
    /// The variables; value reference = index.
    pub variables: Vec<Variable>,
    /// Suggested experiment.
    pub default_experiment: Option<DefaultExperiment>,
    /// The configuration this interface was built for.
    pub config: Config,
    /// The Model Exchange interface, if the model offers it
    /// ([`ModelInfo::with_model_exchange`]).
    pub model_exchange: Option<ModelExchangeInfo>,
    /// `guid`, derived from all of the above.
    pub guid: String,
}

/// Log categories every spurio FMU declares (`LogCategories`).
pub const LOG_CATEGORIES: [(&str, &str); 6] = [
    (
        "logEvents",
        "Events: rail stops, gain updates, outliers rejected, state restored",
    ),
    ("logStatusWarning", "Calls that return fmi2Warning"),
    ("logStatusDiscard", "Calls that return fmi2Discard"),
    (
        "logStatusError",
        "Calls that return fmi2Error, with the reason",
    ),
    ("logStatusFatal", "Calls that return fmi2Fatal"),
    ("logAll", "Everything"),
];

impl ModelInfo {
    /// A model description for `variables`; computes the GUID.
    pub fn new(
        model_identifier: &str,
        description: &str,
        variables: Vec<Variable>,
        default_experiment: Option<DefaultExperiment>,
        config: Config,
    ) -> Self {
        let mut info = Self {
            model_name: model_identifier.to_string(),
            model_identifier: model_identifier.to_string(),
            description: description.to_string(),
            variables,
            default_experiment,
            config,
            model_exchange: None,
            guid: String::new(),
        };
        info.guid = guid_of(&info.to_xml_with_guid(""));
        info
    }

    /// The same model under the model name `name` (a packaged variant's own name); the GUID
    /// covers it.
    pub fn with_model_name(mut self, name: &str) -> Self {
        self.model_name = name.to_string();
        self.guid = guid_of(&self.to_xml_with_guid(""));
        self
    }

    /// The same model offering Model Exchange too: the states, derivatives and event
    /// indicators come from the table ([`crate::Variable::state`],
    /// [`crate::Variable::derivative_of`], [`crate::Variable::event_indicator`]), checked here
    /// (every state has exactly one derivative, …). The GUID covers it.
    pub fn with_model_exchange(mut self) -> Result<Self, DeclarationError> {
        self.model_exchange = Some(ModelExchangeInfo::from_table(&self.variables)?);
        self.guid = guid_of(&self.to_xml_with_guid(""));
        Ok(self)
    }

    /// Index of the variable called `name`.
    pub fn index_of(&self, name: &str) -> Option<usize> {
        self.variables.iter().position(|v| v.name == name)
    }

    /// The `modelDescription.xml` text.
    pub fn to_xml(&self) -> String {
        self.to_xml_with_guid(&self.guid)
    }

    fn to_xml_with_guid(&self, guid: &str) -> String {
        let mut x = String::new();
        let _ = writeln!(x, r#"<?xml version="1.0" encoding="UTF-8"?>"#);
        let _ = writeln!(
            x,
            r#"<fmiModelDescription fmiVersion="2.0" modelName="{}" guid="{}" description="{}" author="spurio" version="{}" generationTool="spurio {}" variableNamingConvention="structured" numberOfEventIndicators="{}">"#,
            esc(&self.model_name),
            esc(guid),
            esc(&self.description),
            env!("CARGO_PKG_VERSION"),
            env!("CARGO_PKG_VERSION"),
            self.model_exchange
                .as_ref()
                .map_or(0, |m| m.event_indicators.len()),
        );
        let me = self.model_exchange.is_some();
        if me {
            let _ = writeln!(
                x,
                r#"  <ModelExchange modelIdentifier="{}" needsExecutionTool="false" completedIntegratorStepNotNeeded="true" canBeInstantiatedOnlyOncePerProcess="false" canNotUseMemoryManagementFunctions="true" canGetAndSetFMUstate="true" canSerializeFMUstate="true" providesDirectionalDerivative="true"/>"#,
                esc(&self.model_identifier)
            );
        }
        let _ = writeln!(
            x,
            r#"  <CoSimulation modelIdentifier="{}" canHandleVariableCommunicationStepSize="true" canInterpolateInputs="false" maxOutputDerivativeOrder="0" canRunAsynchronuously="false" canBeInstantiatedOnlyOncePerProcess="false" canNotUseMemoryManagementFunctions="true" canGetAndSetFMUstate="true" canSerializeFMUstate="true" providesDirectionalDerivative="{me}"/>"#,
            esc(&self.model_identifier)
        );
        write_units(&mut x, self.units());
        write_log_categories(&mut x, "fmi2");
        write_default_experiment(&mut x, self.default_experiment.as_ref());
        write_variant(
            &mut x,
            &self.config,
            "VendorAnnotations",
            r#"Tool name="spurio""#,
            "Tool",
        );
        let _ = writeln!(x, "  <ModelVariables>");
        for (i, v) in self.variables.iter().enumerate() {
            let _ = writeln!(x, "    <!-- {} -->", i + 1);
            let _ = write!(
                x,
                r#"    <ScalarVariable name="{}" valueReference="{}""#,
                esc(&v.name),
                i
            );
            if !v.description.is_empty() {
                let _ = write!(x, r#" description="{}""#, esc(&v.description));
            }
            write_causality(&mut x, v);
            let _ = writeln!(x, ">");
            let _ = write!(x, "      <{}", v.variable_type());
            if let Some(state) = v.derivative_of.filter(|_| me) {
                let _ = write!(x, r#" derivative="{}""#, state + 1);
            }
            write_unit_and_bounds(&mut x, v);
            if v.has_start() {
                let _ = write!(x, r#" start="{}""#, start_text(&v.start));
            }
            let _ = writeln!(x, "/>");
            let _ = writeln!(x, "    </ScalarVariable>");
        }
        let _ = writeln!(x, "  </ModelVariables>");
        let _ = writeln!(x, "  <ModelStructure>");
        let outputs: Vec<(usize, &Variable)> = self
            .variables
            .iter()
            .enumerate()
            .filter(|(_, v)| v.causality == Causality::Output)
            .collect();
        if !outputs.is_empty() {
            let _ = writeln!(x, "    <Outputs>");
            for (i, v) in &outputs {
                let _ = writeln!(
                    x,
                    r#"      <Unknown index="{}"{}/>"#,
                    i + 1,
                    dependencies(&references(&v.dependencies), me)
                );
            }
            let _ = writeln!(x, "    </Outputs>");
        }
        if let Some(m) = &self.model_exchange {
            let _ = writeln!(x, "    <Derivatives>");
            for &d in &m.derivatives {
                let _ = writeln!(
                    x,
                    r#"      <Unknown index="{}"{}/>"#,
                    d + 1,
                    dependencies(&references(&self.variables[d].dependencies), me)
                );
            }
            let _ = writeln!(x, "    </Derivatives>");
        }
        let initial_unknowns: Vec<usize> = self
            .variables
            .iter()
            .enumerate()
            .filter(|(_, v)| is_initial_unknown(v, me))
            .map(|(i, _)| i)
            .collect();
        if !initial_unknowns.is_empty() {
            let _ = writeln!(x, "    <InitialUnknowns>");
            for i in initial_unknowns {
                let _ = writeln!(x, r#"      <Unknown index="{}"/>"#, i + 1);
            }
            let _ = writeln!(x, "    </InitialUnknowns>");
        }
        let _ = writeln!(x, "  </ModelStructure>");
        let _ = writeln!(x, "</fmiModelDescription>");
        x
    }

    /// The units of the variables, sorted, once each.
    pub(crate) fn units(&self) -> Vec<&str> {
        let mut units: Vec<&str> = self
            .variables
            .iter()
            .filter_map(|v| v.unit.as_deref())
            .collect();
        units.sort_unstable();
        units.dedup();
        units
    }
}

// The parts of `modelDescription.xml` both FMI versions write alike.

/// `<UnitDefinitions>` of `units` (nothing if there are none).
pub(crate) fn write_units(x: &mut String, units: Vec<&str>) {
    if units.is_empty() {
        return;
    }
    let _ = writeln!(x, "  <UnitDefinitions>");
    for unit in units {
        match base_unit(unit) {
            Some(base) => {
                let _ = writeln!(x, r#"    <Unit name="{}">"#, esc(unit));
                let _ = writeln!(x, "      <BaseUnit{base}/>");
                let _ = writeln!(x, "    </Unit>");
            }
            None => {
                let _ = writeln!(x, r#"    <Unit name="{}"/>"#, esc(unit));
            }
        }
    }
    let _ = writeln!(x, "  </UnitDefinitions>");
}

/// `<LogCategories>`, their descriptions naming the functions of the version whose prefix is
/// `fmi` (`"fmi2"`, `"fmi3"`).
pub(crate) fn write_log_categories(x: &mut String, fmi: &str) {
    let _ = writeln!(x, "  <LogCategories>");
    for (name, description) in LOG_CATEGORIES {
        let description = description.replace("fmi2", fmi);
        let _ = writeln!(
            x,
            r#"    <Category name="{name}" description="{}"/>"#,
            esc(&description)
        );
    }
    let _ = writeln!(x, "  </LogCategories>");
}

/// `<DefaultExperiment>`, if there is one.
pub(crate) fn write_default_experiment(x: &mut String, e: Option<&DefaultExperiment>) {
    if let Some(e) = e {
        let _ = writeln!(
            x,
            r#"  <DefaultExperiment startTime="{}" stopTime="{}" stepSize="{}"/>"#,
            e.start_time, e.stop_time, e.step_size
        );
    }
}

/// The variant configuration as `<Variant>` settings in the annotation element of the
/// version (`<$outer><$tool>…</$tool_end></$outer>`); nothing for the default configuration.
pub(crate) fn write_variant(
    x: &mut String,
    config: &Config,
    outer: &str,
    tool: &str,
    tool_end: &str,
) {
    if config.is_empty() {
        return;
    }
    let _ = writeln!(x, "  <{outer}>");
    let _ = writeln!(x, "    <{tool}>");
    let _ = writeln!(x, "      <Variant>");
    for line in config.to_text().lines() {
        if let Some((k, v)) = line.split_once(" = ") {
            let _ = writeln!(
                x,
                r#"        <Setting name="{}" value="{}"/>"#,
                esc(k),
                esc(v)
            );
        }
    }
    let _ = writeln!(x, "      </Variant>");
    let _ = writeln!(x, "    </{tool_end}>");
    let _ = writeln!(x, "  </{outer}>");
}

/// The ` causality=… variability=… initial=…` attributes of a variable.
pub(crate) fn write_causality(x: &mut String, v: &Variable) {
    let _ = write!(
        x,
        r#" causality="{}" variability="{}""#,
        v.causality.as_str(),
        v.variability.as_str()
    );
    if let Some(initial) = v.initial {
        let _ = write!(x, r#" initial="{}""#, initial.as_str());
    }
}

/// The ` unit=… min=… max=…` attributes of a variable's type.
pub(crate) fn write_unit_and_bounds(x: &mut String, v: &Variable) {
    if let Some(unit) = &v.unit {
        let _ = write!(x, r#" unit="{}""#, esc(unit));
    }
    let bound = |b: f64| match v.start {
        // xs:int bounds: an integer literal, not "1.0".
        Value::Integer(_) => format!("{}", b.round() as i64),
        _ => fmt_real(b),
    };
    if let Some(min) = v.min {
        let _ = write!(x, r#" min="{}""#, bound(min));
    }
    if let Some(max) = v.max {
        let _ = write!(x, r#" max="{}""#, bound(max));
    }
    if let Some(nominal) = v.nominal {
        let _ = write!(x, r#" nominal="{}""#, fmt_real(nominal));
    }
}

/// A start value as its XML attribute text.
pub(crate) fn start_text(value: &Value) -> String {
    match value {
        Value::Real(r) => fmt_real(*r),
        Value::Integer(i) => i.to_string(),
        Value::Boolean(b) => b.to_string(),
        Value::String(s) => esc(s),
    }
}

/// FMI 2.0 indices (1-based) of the table indices `deps`, ascending and once each (FMI
/// 2.0.4 §2.2.8 orders a `dependencies` list by magnitude).
fn references(deps: &[usize]) -> Vec<u32> {
    let mut references: Vec<u32> = deps.iter().map(|d| *d as u32 + 1).collect();
    references.sort_unstable();
    references.dedup();
    references
}

/// The ` dependencies="…"` attribute of an output or derivative with the declared
/// dependencies `deps` (the version's references). Co-Simulation only: the declared inputs
/// (none: `""`, no direct feedthrough). With Model Exchange the declared states and inputs,
/// and no attribute (depends on every known) when the model declares none.
pub(crate) fn dependencies(deps: &[u32], model_exchange: bool) -> String {
    if model_exchange && deps.is_empty() {
        return String::new();
    }
    let deps: Vec<String> = deps.iter().map(u32::to_string).collect();
    format!(r#" dependencies="{}""#, deps.join(" "))
}

/// Whether a variable is an initial unknown (outputs with `initial` approx or calculated,
/// calculated parameters, and with Model Exchange the states and derivatives with `initial`
/// approx or calculated: FMI 2.0.4 §2.2.8, FMI 3.0.2 §2.4.8).
pub(crate) fn is_initial_unknown(v: &Variable, model_exchange: bool) -> bool {
    ((v.causality == Causality::Output || model_exchange && (v.state || v.derivative_of.is_some()))
        && matches!(
            v.initial,
            Some(crate::variables::Initial::Approx) | Some(crate::variables::Initial::Calculated)
        ))
        || v.causality == Causality::CalculatedParameter
}

/// Writes a Real so that it reads back to the same `f64` (shortest round-trip form).
pub fn fmt_real(v: f64) -> String {
    if v.is_finite() {
        format!("{v:?}")
    } else if v.is_nan() {
        "NaN".into()
    } else if v > 0.0 {
        "INF".into()
    } else {
        "-INF".into()
    }
}

/// Escapes text for an XML attribute.
pub fn esc(s: &str) -> String {
    let mut o = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => o.push_str("&amp;"),
            '<' => o.push_str("&lt;"),
            '>' => o.push_str("&gt;"),
            '"' => o.push_str("&quot;"),
            '\'' => o.push_str("&apos;"),
            '\n' => o.push_str("&#10;"),
            c => o.push(c),
        }
    }
    o
}

/// The SI base-unit attributes of the units spurio uses (`BaseUnit` element), or `None` for a
/// unit that is written without a base (allowed by the standard).
pub(crate) fn base_unit(unit: &str) -> Option<&'static str> {
    Some(match unit {
        "m" => r#" m="1""#,
        "kg" => r#" kg="1""#,
        "s" => r#" s="1""#,
        "rad" => r#" rad="1""#,
        "m/s" => r#" m="1" s="-1""#,
        "m/s2" => r#" m="1" s="-2""#,
        "rad/s" => r#" s="-1" rad="1""#,
        "N" => r#" kg="1" m="1" s="-2""#,
        "N.s/m" => r#" kg="1" s="-1""#,
        "kg.m2" => r#" kg="1" m="2""#,
        "kg.m2/(rad.s)" => r#" kg="1" m="2" s="-1" rad="-1""#,
        "N.m" => r#" kg="1" m="2" s="-2""#,
        "V" => r#" kg="1" m="2" s="-3" A="-1""#,
        "A" => r#" A="1""#,
        "Ohm" => r#" kg="1" m="2" s="-3" A="-2""#,
        "F" => r#" kg="-1" m="-2" s="4" A="2""#,
        "H" => r#" kg="1" m="2" s="-2" A="-2""#,
        "Hz" => r#" s="-1""#,
        "rpm" => r#" s="-1" rad="1" factor="0.10471975511965977""#,
        "1" => "",
        _ => return None,
    })
}

/// A GUID (`{8-4-4-4-12}` hex) from two FNV-1a 64-bit hashes of `text`.
pub fn guid_of(text: &str) -> String {
    let fnv = |basis: u64| {
        text.bytes().fold(basis, |h, b| {
            (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3)
        })
    };
    let a = fnv(0xcbf2_9ce4_8422_2325);
    let b = fnv(0x84222325_cbf29ce4 ^ 0x5555_5555_5555_5555);
    format!(
        "{{{:08x}-{:04x}-{:04x}-{:04x}-{:012x}}}",
        a >> 32,
        (a >> 16) & 0xffff,
        a & 0xffff,
        b >> 48,
        b & 0xffff_ffff_ffff
    )
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::variables::{Initial, Variable};

    fn info() -> ModelInfo {
        ModelInfo::new(
            "Demo",
            "A <demo> & test",
            vec![
                Variable::parameter("k", 2.0).unit("m").min(0.0),
                Variable::input("u", 0.0).unit("N"),
                Variable::output("y").unit("m").depends_on(&[1]),
            ],
            Some(DefaultExperiment {
                start_time: 0.0,
                stop_time: 1.0,
                step_size: 0.01,
            }),
            Config::new(),
        )
    }

    /// The elements both versions' descriptions have, in the schemas' order.
    pub(crate) const SCHEMA_ORDER: [&str; 6] = [
        "<CoSimulation",
        "<UnitDefinitions>",
        "<LogCategories>",
        "<DefaultExperiment",
        "<ModelVariables>",
        "<ModelStructure>",
    ];

    /// Each of `tags` stands in `xml`, each after the one before.
    pub(crate) fn assert_in_order(xml: &str, tags: &[&str]) {
        let positions: Vec<usize> = tags
            .iter()
            .map(|t| xml.find(t).unwrap_or_else(|| panic!("no {t}")))
            .collect();
        assert!(positions.windows(2).all(|w| w[0] < w[1]), "{positions:?}");
    }

    #[test]
    fn xml_has_the_schema_order_and_escapes() {
        let x = info().to_xml();
        assert_in_order(&x, &SCHEMA_ORDER);
        assert!(x.contains(r#"description="A &lt;demo&gt; &amp; test""#));
        assert!(x.contains(r#"<Unknown index="3" dependencies="2"/>"#));
        assert!(!x.contains(r#"causality="input" variability="continuous" initial"#));
        assert!(x.contains(r#"<Real unit="m" min="0.0" start="2.0"/>"#));
    }

    #[test]
    fn integer_bounds_are_integer_literals() {
        let info = ModelInfo::new(
            "Demo",
            "",
            vec![Variable::integer_parameter("N", 3).min(1.0).max(10.0)],
            None,
            Config::new(),
        );
        assert!(info
            .to_xml()
            .contains(r#"<Integer min="1" max="10" start="3"/>"#));
    }

    #[test]
    fn guid_changes_with_the_interface() {
        let a = info();
        let mut vars = a.variables.clone();
        vars[0].initial = Some(Initial::Approx);
        let b = ModelInfo::new(
            "Demo",
            "A <demo> & test",
            vars,
            a.default_experiment,
            Config::new(),
        );
        assert_ne!(a.guid, b.guid);
        assert_eq!(a.guid, info().guid);
        assert_eq!(a.guid.len(), 38);
    }

    #[test]
    fn config_round_trip_and_errors() {
        let c = Config::parse("# dims\nn = 3\nm=1\n").unwrap();
        assert_eq!(c.dimension("n", 1).unwrap(), 3);
        assert_eq!(c.dimension("p", 2).unwrap(), 2);
        assert_eq!(Config::parse(&c.to_text()).unwrap(), c);
        assert!(Config::parse("n 3").is_err());
        let bad = Config::parse("n = 0").unwrap();
        assert!(bad
            .dimension("n", 1)
            .unwrap_err()
            .to_string()
            .contains("`n`"));
    }

    #[test]
    fn reals_round_trip_through_text() {
        for v in [0.1, 1e-5, 9.3e-6, 0.84385, 17.0, -3.5e300] {
            assert_eq!(fmt_real(v).parse::<f64>().unwrap(), v);
        }
    }
}
