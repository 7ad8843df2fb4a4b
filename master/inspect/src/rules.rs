//! The rules of the FMI standard on a model description that its XML schema cannot express,
//! the ones fmpy's `validate_fmu` and the Reference FMUs' `fmusim` check, in both versions:
//!
//! - names: unique (FMI 3.0 aliases included), and of the grammar of the naming convention
//!   (`flat`: no CR, LF or TAB; `structured`: FMI 2.0 section 2.2.9, e.g. `a.b[1,2]`,
//!   `der(x)`, `'quoted name'`);
//! - value references: FMI 3.0: one variable each; FMI 2.0: variables of one base type
//!   (Real; Integer and Enumeration; Boolean; String) that share one are aliases, of which
//!   at most one non-constant variable may carry a start value;
//! - causality, variability and initial: only the combinations the standard's table allows
//!   (FMI 2.0 section 2.2.7, FMI 3.0 section 2.4.7.4), `continuous` only for floats, one
//!   independent variable (FMI 3.0: exactly one);
//! - start values: required where `initial` is `exact` or `approx` and for inputs, refused
//!   where `initial` is `calculated` and for the independent variable; numbers within
//!   `min` ≤ `max`;
//! - units and types: a variable's unit and display unit, and its declared type, are defined;
//! - `derivative=`: names an existing variable, itself a float;
//! - FMI 3.0 arrays: each `<Dimension>` a fixed extent or the value reference of a structural
//!   parameter or constant of an integer type;
//! - `ModelStructure`: every reference and dependency names a variable; `dependenciesKind`
//!   has one entry per dependency; the outputs are exactly the variables of causality
//!   output; each listed derivative has `derivative=`; the initial unknowns are exactly the
//!   outputs and states/derivatives with `initial` `approx` or `calculated` and the
//!   calculated parameters (FMI 2.0 section 2.2.8);
//! - interfaces: at least one; each `modelIdentifier` a C identifier with, for every platform
//!   folder under `binaries/`, its library there (`<id>.so`, `.dll`, `.dylib`); an FMU with
//!   neither binaries nor sources runs nowhere;
//! - `DefaultExperiment`: numbers, a stop time after the start time, positive step size and
//!   tolerance.

use crate::archive::Archive;
use crate::description::{ModelDescription, StructureList, Unknown, Variable, Version};
use crate::{Problem, Rule, Severity};
use std::collections::{BTreeSet, HashMap};

/// Every rule's problems with `md` (read from `archive`), in the order of the rules above.
pub fn check(md: &ModelDescription, archive: &Archive) -> Vec<Problem> {
    let mut c = Checker {
        md,
        problems: Vec::new(),
    };
    c.names();
    c.value_references();
    c.combinations();
    c.start_values();
    c.units_and_types();
    c.dimensions();
    c.derivative_attributes();
    c.model_structure();
    c.interfaces(archive);
    c.default_experiment();
    c.problems
}

struct Checker<'a> {
    md: &'a ModelDescription,
    problems: Vec<Problem>,
}

/// `variable `name``, the place of a problem with a variable.
fn place(v: &Variable) -> String {
    format!("variable `{}`", v.name())
}

impl Checker<'_> {
    fn error(&mut self, rule: Rule, place: String, line: u32, message: String) {
        self.problems.push(Problem {
            rule,
            severity: Severity::Error,
            place,
            line: Some(line),
            message,
        });
    }

    fn names(&mut self) {
        let md = self.md;
        let mut seen: HashMap<&str, u32> = HashMap::new();
        let names = md.variables.iter().flat_map(|v| {
            std::iter::once((v.name(), v.line())).chain(
                v.aliases
                    .iter()
                    .map(|a| (a.get("name").unwrap_or_default(), a.line)),
            )
        });
        for (name, line) in names {
            if let Some(first) = seen.insert(name, line) {
                self.error(
                    Rule::UniqueName,
                    format!("variable `{name}`"),
                    line,
                    format!("the name is taken already by the variable on line {first}; names must be unique"),
                );
            }
        }
        let structured = md.root.get("variableNamingConvention") == Some("structured");
        for v in &md.variables {
            let names = std::iter::once((v.name(), v.line())).chain(
                v.aliases
                    .iter()
                    .map(|a| (a.get("name").unwrap_or_default(), a.line)),
            );
            for (name, line) in names {
                let fault = if structured {
                    structured_name(name).err()
                } else {
                    name.chars()
                        .find(|c| matches!(c, '\r' | '\n' | '\t'))
                        .map(|c| format!("a flat name may not contain {c:?}"))
                };
                if let Some(fault) = fault {
                    let convention = if structured { "structured" } else { "flat" };
                    self.error(
                        Rule::VariableName,
                        format!("variable `{name}`"),
                        line,
                        format!("not a legal name for variableNamingConvention=\"{convention}\": {fault}"),
                    );
                }
            }
        }
    }

    fn value_references(&mut self) {
        let md = self.md;
        match md.version {
            Version::Fmi3 => {
                let mut seen: HashMap<&str, &Variable> = HashMap::new();
                for v in &md.variables {
                    let Some(vr) = v.element.get("valueReference") else {
                        continue;
                    };
                    if let Some(first) = seen.insert(vr, v) {
                        let message = format!(
                            "value reference {vr} is that of `{}` (line {}) too; in FMI 3.0 each variable has its own (another name is an <Alias>)",
                            first.name(), first.line()
                        );
                        self.error(Rule::ValueReference, place(v), v.line(), message);
                    }
                }
            }
            Version::Fmi2 => {
                // The alias set's variable that carries a start value, per (base type, vr).
                let mut start_holder: HashMap<(&str, &str), &Variable> = HashMap::new();
                for v in &md.variables {
                    let Some(vr) = v.element.get("valueReference") else {
                        continue;
                    };
                    if v.start().is_none() || md.variability(v) == "constant" {
                        continue;
                    }
                    let base = match v.type_name.as_str() {
                        "Enumeration" => "Integer",
                        other => other,
                    };
                    if let Some(first) = start_holder.insert((base, vr), v) {
                        let message = format!(
                            "shares value reference {vr} ({base}) with `{}` (line {}) and both have a start value; \
                             of a set of aliases at most one non-constant variable may have one",
                            first.name(), first.line()
                        );
                        self.error(Rule::ValueReference, place(v), v.line(), message);
                    }
                }
            }
        }
    }

    fn combinations(&mut self) {
        let md = self.md;
        let independent: Vec<&Variable> = md
            .variables
            .iter()
            .filter(|v| v.causality() == "independent")
            .collect();
        match (md.version, independent.len()) {
            (Version::Fmi3, 0) => self.error(
                Rule::Causality,
                "ModelVariables".into(),
                1,
                "FMI 3.0 asks for exactly one variable of causality=\"independent\" (the time); there is none".into(),
            ),
            (_, n) if n > 1 => {
                let names: Vec<String> = independent.iter().map(|v| format!("`{}`", v.name())).collect();
                self.error(
                    Rule::Causality,
                    place(independent[1]),
                    independent[1].line(),
                    format!("{n} variables are independent ({}); there may be only one", names.join(", ")),
                );
            }
            _ => {}
        }
        for v in &md.variables {
            let variability = md.variability(v);
            let initial = md.initial(v);
            if variability == "continuous" && !v.is_float() && !v.type_name.is_empty() {
                self.error(
                    Rule::Causality,
                    place(v),
                    v.line(),
                    format!(
                        "a {} variable cannot have variability=\"continuous\" (only floats can)",
                        v.type_name
                    ),
                );
            }
            if !legal(md.version, v.causality(), &variability, initial.as_deref()) {
                let initial = match (v.element.get("initial"), &initial) {
                    (Some(i), _) => format!(" and initial=\"{i}\""),
                    (None, Some(i)) => format!(" (initial=\"{i}\" by default)"),
                    (None, None) => String::new(),
                };
                self.error(
                    Rule::Causality,
                    place(v),
                    v.line(),
                    format!(
                        "causality=\"{}\" with variability=\"{variability}\"{initial} is not a combination FMI {} allows",
                        v.causality(),
                        md.version.number()
                    ),
                );
            }
        }
    }

    fn start_values(&mut self) {
        let md = self.md;
        for v in &md.variables {
            let initial = md.initial(v);
            let needs =
                matches!(initial.as_deref(), Some("exact" | "approx")) || v.causality() == "input";
            if needs && v.start().is_none() && v.type_name != "Clock" {
                let why = match initial.as_deref() {
                    _ if v.causality() == "input" => "an input".to_string(),
                    Some(i) => format!("initial=\"{i}\""),
                    None => String::new(),
                };
                self.error(
                    Rule::StartValue,
                    place(v),
                    v.line(),
                    format!("has no start value, which {why} requires"),
                );
            }
            if v.start().is_some() && initial.as_deref() == Some("calculated") {
                self.error(
                    Rule::StartValue,
                    place(v),
                    v.line(),
                    "has a start value but initial=\"calculated\" (the FMU calculates it; a start value is not allowed)".into(),
                );
            }
            if v.start().is_some() && v.causality() == "independent" {
                self.error(
                    Rule::StartValue,
                    place(v),
                    v.line(),
                    "is the independent variable and may not have a start value".into(),
                );
            }
            self.bounds(v);
        }
    }

    /// `min` ≤ `max`, and each start value within them.
    fn bounds(&mut self, v: &Variable) {
        if matches!(
            v.type_name.as_str(),
            "Boolean" | "String" | "Binary" | "Clock" | ""
        ) {
            return;
        }
        let number = |name| {
            v.element
                .get(name)
                .and_then(|s| s.trim().parse::<f64>().ok())
        };
        let (min, max) = (number("min"), number("max"));
        if let (Some(lo), Some(hi)) = (min, max) {
            if lo > hi {
                self.error(
                    Rule::Bounds,
                    place(v),
                    v.line(),
                    format!("min = {lo} is above max = {hi}"),
                );
                return;
            }
        }
        let starts = v.start().unwrap_or_default().split_whitespace();
        for start in starts.filter_map(|s| s.parse::<f64>().ok()) {
            let below = min
                .filter(|lo| start < *lo)
                .map(|lo| format!("below min = {lo}"));
            let above = max
                .filter(|hi| start > *hi)
                .map(|hi| format!("above max = {hi}"));
            if let Some(outside) = below.or(above) {
                self.error(
                    Rule::Bounds,
                    place(v),
                    v.line(),
                    format!("the start value {start} is {outside}"),
                );
                return;
            }
        }
    }

    fn units_and_types(&mut self) {
        let md = self.md;
        for v in &md.variables {
            let declared = v
                .element
                .get("declaredType")
                .map(|t| (t, md.type_definition(t)));
            match declared {
                Some((name, None)) => self.error(
                    Rule::UnitsAndTypes,
                    place(v),
                    v.line(),
                    format!("declaredType=\"{name}\" is not defined in TypeDefinitions"),
                ),
                Some((name, Some(t))) if t.type_name != v.type_name => self.error(
                    Rule::UnitsAndTypes,
                    place(v),
                    v.line(),
                    format!(
                        "a {} variable cannot have declaredType=\"{name}\", a {} type (line {})",
                        v.type_name, t.type_name, t.element.line
                    ),
                ),
                _ => {}
            }
            let unit = md.unit_of(v);
            let defined = unit.map(|u| {
                (
                    u,
                    md.units.iter().find(|d| d.element.get("name") == Some(u)),
                )
            });
            if let Some((u, None)) = defined {
                self.error(
                    Rule::UnitsAndTypes,
                    place(v),
                    v.line(),
                    format!("its unit \"{u}\" is not defined in UnitDefinitions"),
                );
                continue;
            }
            let display_units = std::iter::once((v.element.get("displayUnit"), v.line(), v.name()))
                .chain(v.aliases.iter().map(|a| {
                    let name = a.get("name").unwrap_or_default();
                    (a.get("displayUnit"), a.line, name)
                }));
            for (display, line, name) in display_units {
                let Some(display) = display else { continue };
                let known = defined
                    .and_then(|(_, d)| d)
                    .is_some_and(|d| d.display_units.iter().any(|n| n == display));
                if !known {
                    let of = unit.map_or("it has no unit".to_string(), |u| format!("unit \"{u}\""));
                    self.error(
                        Rule::UnitsAndTypes,
                        format!("variable `{name}`"),
                        line,
                        format!("its displayUnit \"{display}\" is not a display unit of its {of}"),
                    );
                }
            }
        }
    }

    /// The variable a reference of `ModelStructure` or `derivative=` names: FMI 2.0 a
    /// 1-based position in `ModelVariables`, FMI 3.0 a value reference.
    fn resolve(&self, reference: &str) -> Result<usize, String> {
        let md = self.md;
        match md.version {
            Version::Fmi2 => match reference.parse::<usize>() {
                Ok(i) if (1..=md.variables.len()).contains(&i) => Ok(i - 1),
                Ok(i) => Err(format!(
                    "index {i} is out of range (ModelVariables has {} variables, numbered from 1)",
                    md.variables.len()
                )),
                Err(_) => Err(format!("`{reference}` is not a variable index")),
            },
            Version::Fmi3 => md
                .variables
                .iter()
                .position(|v| v.element.get("valueReference") == Some(reference))
                .ok_or_else(|| format!("no variable has value reference {reference}")),
        }
    }

    /// FMI 3.0 arrays: a `<Dimension>` has a fixed extent (`start`) or names, by value
    /// reference, the structural parameter or constant of an integer type that holds it.
    fn dimensions(&mut self) {
        let md = self.md;
        for v in &md.variables {
            for d in &v.dimensions {
                let problem = match (d.get("start"), d.get("valueReference")) {
                    (Some(_), None) => continue,
                    (None, None) => "has neither start nor valueReference".to_string(),
                    (Some(_), Some(_)) => "has both start and valueReference".to_string(),
                    (None, Some(vr)) => match self.resolve(vr.trim()) {
                        Err(why) => format!("valueReference=\"{vr}\" names no variable: {why}"),
                        Ok(i) => {
                            let holder = &md.variables[i];
                            let integer = holder.type_name.contains("Int");
                            let fixed = holder.causality() == "structuralParameter"
                                || md.variability(holder) == "constant";
                            if integer && fixed {
                                continue;
                            }
                            format!(
                                "valueReference=\"{vr}\" names `{}`, which is not a structural parameter or constant of an integer type",
                                holder.name()
                            )
                        }
                    },
                };
                self.error(
                    Rule::Dimension,
                    place(v),
                    d.line,
                    format!("its <Dimension> {problem}"),
                );
            }
        }
    }

    fn derivative_attributes(&mut self) {
        let md = self.md;
        for v in &md.variables {
            let Some(reference) = v.element.get("derivative") else {
                continue;
            };
            match self.resolve(reference.trim()) {
                Err(why) => self.error(
                    Rule::Derivative,
                    place(v),
                    v.line(),
                    format!("derivative=\"{reference}\" names no variable: {why}"),
                ),
                Ok(i) if !md.variables[i].is_float() => {
                    let state = &md.variables[i];
                    self.error(
                        Rule::Derivative,
                        place(v),
                        v.line(),
                        format!("derivative=\"{reference}\" names `{}`, a {} variable; a state must be a float", state.name(), state.type_name),
                    )
                }
                Ok(_) => {}
            }
        }
    }

    fn model_structure(&mut self) {
        let md = self.md;
        let mut listed: HashMap<StructureList, Vec<usize>> = HashMap::new();
        // The line of each state derivative's entry.
        let mut lines: HashMap<usize, u32> = HashMap::new();
        for u in &md.structure {
            let list = u.list.place(md.version);
            let Some(reference) = u.reference() else {
                continue; // the schema names the missing attribute
            };
            let entry = match self.resolve(reference.trim()) {
                Ok(i) => i,
                Err(why) => {
                    self.error(Rule::ModelStructure, list.into(), u.element.line, why);
                    continue;
                }
            };
            self.dependencies(u, &md.variables[entry]);
            listed.entry(u.list).or_default().push(entry);
            if u.list == StructureList::Derivatives {
                lines.insert(entry, u.element.line);
            }
        }
        let names = |set: &BTreeSet<usize>| -> String {
            let names: Vec<String> = set
                .iter()
                .map(|&i| format!("`{}`", md.variables[i].name()))
                .collect();
            if names.is_empty() {
                "none".into()
            } else {
                names.join(", ")
            }
        };
        let line_of = |list: StructureList| {
            md.structure
                .iter()
                .find(|u| u.list == list)
                .map_or(1, |u| u.element.line)
        };

        // Outputs: each output once, nothing else.
        let outputs = listed.remove(&StructureList::Outputs).unwrap_or_default();
        let place = StructureList::Outputs.place(md.version);
        let mut once = BTreeSet::new();
        for &i in &outputs {
            if !once.insert(i) {
                let line = line_of(StructureList::Outputs);
                self.error(
                    Rule::ModelStructure,
                    place.into(),
                    line,
                    format!("`{}` is listed twice", md.variables[i].name()),
                );
            }
        }
        let expected: BTreeSet<usize> = (0..md.variables.len())
            .filter(|&i| md.variables[i].causality() == "output")
            .collect();
        self.same_set(
            place,
            line_of(StructureList::Outputs),
            &expected,
            &once,
            "the variables of causality=\"output\"",
            &names,
        );

        // Derivatives: each has derivative=.
        let derivatives = listed
            .remove(&StructureList::Derivatives)
            .unwrap_or_default();
        let place = StructureList::Derivatives.place(md.version);
        let mut states = BTreeSet::new();
        for &i in &derivatives {
            let d = &md.variables[i];
            match d.element.get("derivative").map(|r| self.resolve(r.trim())) {
                Some(Ok(state)) => {
                    states.insert(state);
                }
                Some(Err(_)) => {} // said by derivative_attributes
                None => {
                    let line = lines.get(&i).copied().unwrap_or(d.line());
                    self.error(
                        Rule::ModelStructure,
                        place.into(),
                        line,
                        format!(
                            "`{}` is listed as a state derivative but has no derivative= attribute",
                            d.name()
                        ),
                    )
                }
            }
        }

        // InitialUnknowns: exactly the standard's set.
        let initial_unknowns: BTreeSet<usize> = listed
            .remove(&StructureList::InitialUnknowns)
            .unwrap_or_default()
            .into_iter()
            .collect();
        let approximate = |i: &usize| {
            matches!(
                md.initial(&md.variables[*i]).as_deref(),
                Some("approx" | "calculated")
            )
        };
        let mut expected: BTreeSet<usize> = (0..md.variables.len())
            .filter(|&i| {
                let v = &md.variables[i];
                (v.causality() == "output" && v.element.get("clocks").is_none() && approximate(&i))
                    || v.causality() == "calculatedParameter"
            })
            .collect();
        expected.extend(
            derivatives
                .iter()
                .chain(states.iter())
                .filter(|i| approximate(i)),
        );
        self.same_set(
            StructureList::InitialUnknowns.place(md.version),
            line_of(StructureList::InitialUnknowns),
            &expected,
            &initial_unknowns,
            "the outputs and continuous states and derivatives with initial=\"approx\" or \"calculated\", and the calculated parameters",
            &names,
        );
    }

    /// A problem when `listed` is not `expected`, naming what is missing and what is extra.
    fn same_set(
        &mut self,
        place: &str,
        line: u32,
        expected: &BTreeSet<usize>,
        listed: &BTreeSet<usize>,
        what: &str,
        names: &dyn Fn(&BTreeSet<usize>) -> String,
    ) {
        if expected == listed {
            return;
        }
        let missing: BTreeSet<usize> = expected.difference(listed).copied().collect();
        let extra: BTreeSet<usize> = listed.difference(expected).copied().collect();
        let mut parts = Vec::new();
        if !missing.is_empty() {
            parts.push(format!("missing {}", names(&missing)));
        }
        if !extra.is_empty() {
            parts.push(format!("not to be listed {}", names(&extra)));
        }
        self.error(
            Rule::ModelStructure,
            place.into(),
            line,
            format!("must list exactly {what}: {}", parts.join("; ")),
        );
    }

    fn dependencies(&mut self, u: &Unknown, of: &Variable) {
        let list = u.list.place(self.md.version);
        let line = u.element.line;
        let dependencies = u.element.words("dependencies");
        for d in dependencies.iter().flatten() {
            if let Err(why) = self.resolve(d) {
                let message = format!("a dependency of `{}`: {why}", of.name());
                self.error(Rule::Dependencies, list.into(), line, message);
            }
        }
        let message = match (dependencies, u.element.words("dependenciesKind")) {
            (None, Some(_)) => format!(
                "the entry of `{}` has dependenciesKind but no dependencies",
                of.name()
            ),
            (Some(d), Some(k)) if d.len() != k.len() => format!(
                "the entry of `{}` has {} dependencies but {} dependenciesKind",
                of.name(),
                d.len(),
                k.len()
            ),
            _ => return,
        };
        self.error(Rule::Dependencies, list.into(), line, message);
    }

    fn interfaces(&mut self, archive: &Archive) {
        let md = self.md;
        if md.interfaces.is_empty() {
            self.error(
                Rule::Interface,
                "fmiModelDescription".into(),
                1,
                "declares no interface (<ModelExchange>, <CoSimulation> or <ScheduledExecution>)"
                    .into(),
            );
        }
        let platforms = archive.platforms();
        if platforms.is_empty() && !archive.has_sources() {
            self.error(
                Rule::Binaries,
                "binaries/".into(),
                1,
                "the FMU has neither binaries (binaries/<platform>/) nor sources (sources/): it runs nowhere".into(),
            );
        }
        let mut identifiers: Vec<(&str, u32)> = Vec::new();
        for (kind, element) in &md.interfaces {
            let Some(id) = element.get("modelIdentifier") else {
                continue; // the schema names the missing attribute
            };
            if !is_c_identifier(id) {
                self.error(
                    Rule::Interface,
                    format!("<{}>", kind.element()),
                    element.line,
                    format!("modelIdentifier \"{id}\" is not a valid C identifier (letters, digits and `_`, not starting with a digit): it prefixes the library's function names and names its file"),
                );
                continue;
            }
            if !identifiers.iter().any(|(known, _)| *known == id) {
                identifiers.push((id, element.line));
            }
        }
        for platform in &platforms {
            for (id, line) in &identifiers {
                let candidates = library_names(platform, id);
                if !candidates.iter().any(|c| archive.has(c)) {
                    self.error(
                        Rule::Binaries,
                        format!("binaries/{platform}/"),
                        *line,
                        format!(
                            "has no library for modelIdentifier \"{id}\" (expected {})",
                            candidates.join(" or ")
                        ),
                    );
                }
            }
        }
    }

    fn default_experiment(&mut self) {
        let Some(e) = &self.md.default_experiment else {
            return;
        };
        let mut number = |name: &str| -> Option<f64> {
            let text = e.get(name)?;
            match text.trim().parse::<f64>() {
                Ok(x) if x.is_finite() => Some(x),
                _ => {
                    self.error(
                        Rule::DefaultExperiment,
                        "DefaultExperiment".into(),
                        e.line,
                        format!("{name}=\"{text}\" is not a finite number"),
                    );
                    None
                }
            }
        };
        let start = number("startTime");
        let stop = number("stopTime");
        let step = number("stepSize");
        let tolerance = number("tolerance");
        if let (Some(start), Some(stop)) = (start, stop) {
            if stop < start {
                self.error(
                    Rule::DefaultExperiment,
                    "DefaultExperiment".into(),
                    e.line,
                    format!("stopTime = {stop} is before startTime = {start}"),
                );
            }
        }
        for (name, value) in [("stepSize", step), ("tolerance", tolerance)] {
            if let Some(x) = value.filter(|x| *x <= 0.0) {
                self.error(
                    Rule::DefaultExperiment,
                    "DefaultExperiment".into(),
                    e.line,
                    format!("{name} = {x} is not positive"),
                );
            }
        }
    }
}

/// Whether `(causality, variability, initial)` is in the standard's table (FMI 2.0 section
/// 2.2.7; FMI 3.0 adds the structural parameter).
fn legal(version: Version, causality: &str, variability: &str, initial: Option<&str>) -> bool {
    let Some(initial) = initial else {
        return causality == "independent" && variability == "continuous";
    };
    match (causality, variability) {
        ("structuralParameter", "fixed" | "tunable") => {
            version == Version::Fmi3 && initial == "exact"
        }
        ("parameter", "fixed" | "tunable") => initial == "exact",
        ("calculatedParameter", "fixed" | "tunable") => matches!(initial, "calculated" | "approx"),
        ("input", "discrete" | "continuous") => initial == "exact",
        ("output", "constant") | ("local", "constant") => initial == "exact",
        ("output", "discrete" | "continuous") | ("local", "discrete" | "continuous") => {
            matches!(initial, "calculated" | "exact" | "approx")
        }
        ("local", "fixed" | "tunable") => matches!(initial, "calculated" | "approx"),
        _ => false,
    }
}

/// Whether `s` is a C identifier.
fn is_c_identifier(s: &str) -> bool {
    let mut chars = s.chars();
    chars
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_')
}

/// The file names the library of `id` may have in `binaries/<platform>/`: by the platform's
/// operating system (FMI 2.0 `win64`, `linux64`, `darwin64`; FMI 3.0 tuples such as
/// `x86_64-windows`), any of the three for a platform of another name.
fn library_names(platform: &str, id: &str) -> Vec<String> {
    let extensions: &[&str] = if platform.starts_with("win") || platform.ends_with("-windows") {
        &["dll"]
    } else if platform.starts_with("darwin") || platform.ends_with("-darwin") {
        &["dylib"]
    } else if platform.starts_with("linux") || platform.ends_with("-linux") {
        &["so"]
    } else {
        &["so", "dll", "dylib"]
    };
    extensions
        .iter()
        .map(|ext| format!("binaries/{platform}/{id}.{ext}"))
        .collect()
}

/// Checks a name against the grammar of `variableNamingConvention="structured"` (FMI 2.0
/// section 2.2.9, FMI 3.0 section 2.4.7.5):
///
/// ```text
/// name       = identifier | "der(" identifier ["," unsignedInteger] ")"
/// identifier = bname [arrayIndices] {"." bname [arrayIndices]}
/// bname      = nondigit {digit | nondigit} | "'" qchar {qchar} "'"
/// arrayIndices = "[" unsignedInteger {"," unsignedInteger} "]"
/// ```
pub fn structured_name(name: &str) -> Result<(), String> {
    let chars: Vec<char> = name.chars().collect();
    let mut at = 0;
    if name.starts_with("der(") {
        at = 4;
        identifier(&chars, &mut at)?;
        if chars.get(at) == Some(&',') {
            at += 1;
            unsigned(&chars, &mut at)?;
        }
        expect(&chars, &mut at, ')')?;
    } else {
        identifier(&chars, &mut at)?;
    }
    if at < chars.len() {
        return Err(format!(
            "unexpected {:?} at character {}",
            chars[at],
            at + 1
        ));
    }
    Ok(())
}

fn expect(chars: &[char], at: &mut usize, c: char) -> Result<(), String> {
    match chars.get(*at) {
        Some(&found) if found == c => {
            *at += 1;
            Ok(())
        }
        Some(found) => Err(format!(
            "expected {c:?} at character {}, found {found:?}",
            *at + 1
        )),
        None => Err(format!("expected {c:?} at the end")),
    }
}

fn unsigned(chars: &[char], at: &mut usize) -> Result<(), String> {
    let start = *at;
    while chars.get(*at).is_some_and(char::is_ascii_digit) {
        *at += 1;
    }
    if *at == start {
        return Err(format!(
            "expected an unsigned integer at character {}",
            start + 1
        ));
    }
    Ok(())
}

fn identifier(chars: &[char], at: &mut usize) -> Result<(), String> {
    loop {
        bname(chars, at)?;
        if chars.get(*at) == Some(&'[') {
            *at += 1;
            unsigned(chars, at)?;
            while chars.get(*at) == Some(&',') {
                *at += 1;
                unsigned(chars, at)?;
            }
            expect(chars, at, ']')?;
        }
        if chars.get(*at) != Some(&'.') {
            return Ok(());
        }
        *at += 1;
    }
}

fn bname(chars: &[char], at: &mut usize) -> Result<(), String> {
    let nondigit = |c: &char| c.is_ascii_alphabetic() || *c == '_';
    match chars.get(*at) {
        Some('\'') => {
            *at += 1;
            let start = *at;
            loop {
                match chars.get(*at) {
                    None => return Err("a quoted name is not closed with '".into()),
                    Some('\'') if *at > start => {
                        *at += 1;
                        return Ok(());
                    }
                    Some('\'') => return Err("a quoted name is empty".into()),
                    Some('\\') => *at += 2,
                    Some(c) if c.is_ascii_graphic() || *c == ' ' => *at += 1,
                    Some(c) => return Err(format!("{c:?} may not appear in a quoted name")),
                }
            }
        }
        Some(c) if nondigit(c) => {
            *at += 1;
            while chars
                .get(*at)
                .is_some_and(|c| nondigit(c) || c.is_ascii_digit())
            {
                *at += 1;
            }
            Ok(())
        }
        Some(c) => Err(format!(
            "a name part cannot start with {c:?} (character {})",
            *at + 1
        )),
        None => Err("a name part is missing at the end".into()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn structured_names_follow_the_grammar() {
        for good in [
            "x",
            "a.b[1,2].c",
            "der(x)",
            "der(a.b[3],2)",
            "'quoted name'",
            "_u1",
            "y[10]",
        ] {
            assert_eq!(structured_name(good), Ok(()), "{good}");
        }
        let bad = |name: &str| structured_name(name).unwrap_err();
        assert!(bad("1x").contains("cannot start with '1'"));
        assert!(bad("a[1").contains("expected ']' at the end"));
        assert!(bad("a b").contains("unexpected ' ' at character 2"));
        assert!(bad("a[]").contains("expected an unsigned integer at character 3"));
        assert!(bad("der(x").contains("expected ')' at the end"));
        assert!(bad("a.").contains("missing at the end"));
        assert!(bad("''").contains("empty"));
    }

    #[test]
    fn the_combination_table_is_the_standards() {
        use Version::*;
        assert!(legal(Fmi2, "parameter", "fixed", Some("exact")));
        assert!(!legal(Fmi2, "parameter", "fixed", Some("calculated")));
        assert!(!legal(Fmi2, "parameter", "continuous", Some("exact")));
        assert!(!legal(Fmi2, "structuralParameter", "fixed", Some("exact")));
        assert!(legal(Fmi3, "structuralParameter", "tunable", Some("exact")));
        assert!(legal(Fmi2, "output", "continuous", Some("approx")));
        assert!(!legal(Fmi2, "input", "continuous", Some("approx")));
        assert!(!legal(Fmi2, "input", "constant", Some("exact")));
        assert!(legal(Fmi2, "independent", "continuous", None));
        assert!(!legal(Fmi2, "independent", "discrete", None));
    }

    #[test]
    fn libraries_are_named_by_the_platforms_system() {
        assert_eq!(library_names("win64", "M"), ["binaries/win64/M.dll"]);
        assert_eq!(
            library_names("x86_64-linux", "M"),
            ["binaries/x86_64-linux/M.so"]
        );
        assert_eq!(
            library_names("aarch64-darwin", "M"),
            ["binaries/aarch64-darwin/M.dylib"]
        );
        assert_eq!(library_names("linux64", "M"), ["binaries/linux64/M.so"]);
        assert_eq!(library_names("odd", "M").len(), 3);
        assert!(
            is_c_identifier("_Crane2") && !is_c_identifier("2Crane") && !is_c_identifier("a-b")
        );
    }
}
