//! Reading an FMI 3.0 model description into the master's variables (docs/ cite: FMI 3.0
//! §2.4.7 model variables, §2.4.8 model structure).
//!
//! FMI 3.0 variables are elements named by their type (`<Float64>`, `<Int32>`, …) and may be
//! arrays (`<Dimension start="3"/>` or `<Dimension valueReference="…"/>`, a structural
//! parameter whose start value is taken: the master does not use configuration mode). Every
//! array is laid out as its elements, named as our FMI 2.0 FMUs name their structured
//! scalars: `x[i,j]`, 1-based, row-major (the order of FMI 3.0's serialisation), so a system
//! addresses an element of an FMI 3.0 array as it does the scalar of an FMI 2.0 FMU. The
//! whole array keeps its own name ([`super::ArrayInfo`]). The rules checked here: a name
//! (of a variable, an alias or an array element) is unique; a value reference is unique; a
//! dimension's structural parameter exists and has a start value; every `ModelStructure`
//! entry refers to a known variable, an `<Output>` to an output listed once.

use super::xml::Inherited;
use super::{ArrayInfo, Causality, VarType, VariableHead, VariableInfo};
use crate::xml::{attribute, tags, Tag};
use std::collections::HashMap;

/// What the master takes from an FMI 3.0 model description.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Description {
    pub version: String,
    pub model_name: String,
    pub instantiation_token: String,
    /// `modelIdentifier` of `<CoSimulation>` (None: no Co-Simulation interface).
    pub co_simulation: Option<String>,
    /// `<CoSimulation hasEventMode="true">`: the FMU can be run with Event Mode (FMI 3.0
    /// §4.2, `eventModeUsed`).
    pub co_simulation_event_mode: bool,
    /// `modelIdentifier` of `<ModelExchange>` (None: no Model Exchange interface).
    pub model_exchange: Option<String>,
    /// The other interfaces declared, to say what the FMU is when it is not Co-Simulation.
    pub other_interfaces: Vec<&'static str>,
    pub variables: Vec<VariableInfo>,
    pub arrays: Vec<ArrayInfo>,
    /// Extra names (`<Alias>`) of variables: (alias, variable index).
    pub aliases: Vec<(String, usize)>,
}

/// A dimension as written.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Dim {
    Fixed(u64),
    Structural(u32),
}

/// One variable element as written.
#[derive(Debug, Clone, PartialEq)]
struct Raw {
    name: String,
    vr: u32,
    var_type: VarType,
    causality: Causality,
    variability: String,
    start: Option<String>,
    /// Its own `unit`, `min` and `max`.
    own: Inherited,
    declared_type: Option<String>,
    description: Option<String>,
    dims: Vec<Dim>,
    aliases: Vec<String>,
}

fn var_type(element: &str) -> Option<VarType> {
    Some(match element {
        "Float64" => VarType::Real,
        "Float32" => VarType::Float32,
        "Int8" => VarType::Int8,
        "UInt8" => VarType::UInt8,
        "Int16" => VarType::Int16,
        "UInt16" => VarType::UInt16,
        "Int32" => VarType::Integer,
        "UInt32" => VarType::UInt32,
        "Int64" => VarType::Int64,
        "UInt64" => VarType::UInt64,
        "Boolean" => VarType::Boolean,
        "String" => VarType::String,
        "Binary" => VarType::Binary,
        "Enumeration" => VarType::Enumeration,
        "Clock" => VarType::Clock,
        _ => return None,
    })
}

fn number<T: std::str::FromStr>(text: &str, what: &str) -> Result<T, String> {
    text.trim()
        .parse()
        .map_err(|_| format!("{what} `{text}` is not a valid number"))
}

/// One `<Output>`/… of `ModelStructure`: (list, value reference, dependencies).
type Unknown = (&'static str, u32, Option<Vec<u32>>);

/// Reads `xml` (an FMI 3.0 model description).
pub(super) fn read(xml: &str) -> Result<Description, String> {
    let mut d = Description {
        version: String::new(),
        model_name: String::new(),
        instantiation_token: String::new(),
        co_simulation: None,
        co_simulation_event_mode: false,
        model_exchange: None,
        other_interfaces: Vec::new(),
        variables: Vec::new(),
        arrays: Vec::new(),
        aliases: Vec::new(),
    };
    let mut raw: Vec<Raw> = Vec::new();
    let mut types: HashMap<String, Inherited> = HashMap::new();
    let mut in_variables = false;
    let mut in_structure = false;
    // Whether the last variable element is still open (its Dimension/Alias children follow).
    let mut open = false;
    let mut unknowns: Vec<Unknown> = Vec::new();
    for tag in tags(xml) {
        match tag? {
            Tag::End(e) => match e.name().as_ref() {
                "ModelVariables" => in_variables = false,
                "ModelStructure" => in_structure = false,
                name if in_variables && var_type(name).is_some() => open = false,
                _ => {}
            },
            Tag::Start { element: e, empty } => {
                let name = e.name().as_ref().to_string();
                match name.as_str() {
                    "fmiModelDescription" => {
                        d.version = attribute(&e, "fmiVersion").unwrap_or_default();
                        d.model_name = attribute(&e, "modelName").unwrap_or_default();
                        d.instantiation_token =
                            attribute(&e, "instantiationToken").unwrap_or_default();
                    }
                    "CoSimulation" => {
                        d.co_simulation = Some(model_identifier(&e, "CoSimulation")?);
                        d.co_simulation_event_mode =
                            attribute(&e, "hasEventMode").is_some_and(|v| v.trim() == "true");
                    }
                    "ModelExchange" => {
                        d.model_exchange = Some(model_identifier(&e, "ModelExchange")?);
                        d.other_interfaces.push("Model Exchange");
                    }
                    "ScheduledExecution" => d.other_interfaces.push("Scheduled Execution"),
                    "ModelVariables" => in_variables = !empty,
                    // FMI 2.0's variable element: the description is FMI 2.0 whatever it says.
                    "ScalarVariable" => {
                        return Err(format!(
                            "fmiVersion is `{}`, but the description is FMI 2.0: it declares \
                             its variables as <ScalarVariable> (FMI 3.0 declares <Float64>, \
                             <Int32>, … directly); correct fmiVersion to 2.0",
                            d.version
                        ))
                    }
                    "ModelStructure" => in_structure = !empty,
                    "Dimension" if in_variables && open => {
                        let dim = match (attribute(&e, "start"), attribute(&e, "valueReference")) {
                            (Some(s), _) => Dim::Fixed(number(&s, "Dimension start")?),
                            (None, Some(vr)) => {
                                Dim::Structural(number(&vr, "Dimension valueReference")?)
                            }
                            (None, None) => {
                                return Err(format!(
                                "variable `{}`: a <Dimension> has neither start nor valueReference",
                                raw.last().map(|r| r.name.as_str()).unwrap_or("?")
                            ))
                            }
                        };
                        if let Some(r) = raw.last_mut() {
                            r.dims.push(dim);
                        }
                    }
                    "Alias" if in_variables && open => {
                        if let (Some(r), Some(alias)) = (raw.last_mut(), attribute(&e, "name")) {
                            r.aliases.push(alias);
                        }
                    }
                    element if in_variables => {
                        if let Some(t) = var_type(element) {
                            raw.push(variable(&e, t)?);
                            open = !empty;
                        }
                    }
                    element if in_structure => {
                        let list = match element {
                            "Output" => "Output",
                            "ContinuousStateDerivative" => "ContinuousStateDerivative",
                            "ClockedState" => "ClockedState",
                            "InitialUnknown" => "InitialUnknown",
                            "EventIndicator" => "EventIndicator",
                            _ => continue,
                        };
                        let vr = attribute(&e, "valueReference").ok_or_else(|| {
                            format!("ModelStructure: an <{list}> has no valueReference")
                        })?;
                        let vr = number(&vr, &format!("ModelStructure/{list} valueReference"))?;
                        let deps = attribute(&e, "dependencies")
                            .map(|text| {
                                text.split_whitespace()
                                    .map(|t| {
                                        number(t, &format!("ModelStructure/{list} dependency"))
                                    })
                                    .collect::<Result<Vec<u32>, String>>()
                            })
                            .transpose()?;
                        unknowns.push((list, vr, deps));
                    }
                    element if element.ends_with("Type") && !in_variables => {
                        // <Float64Type name="Length" unit="m" min="0"/> in TypeDefinitions.
                        if let Some(n) = attribute(&e, "name") {
                            types.insert(n, Inherited::of(&e));
                        }
                    }
                    _ => {}
                }
            }
        }
    }
    lay_out(&mut d, raw, &types)?;
    dependencies(&mut d, &unknowns)?;
    Ok(d)
}

/// The `modelIdentifier` of the interface element `element` (`<CoSimulation>`, …), which
/// FMI 3.0 requires.
fn model_identifier(e: &quick_xml::events::BytesStart, element: &str) -> Result<String, String> {
    attribute(e, "modelIdentifier")
        .ok_or_else(|| format!("<{element}> has no modelIdentifier, which FMI 3.0 requires"))
}

fn variable(e: &quick_xml::events::BytesStart, var_type: VarType) -> Result<Raw, String> {
    let name = attribute(e, "name").ok_or("a variable has no name")?;
    let vr = attribute(e, "valueReference")
        .ok_or_else(|| format!("variable `{name}` has no valueReference"))?;
    let vr = number(&vr, &format!("valueReference of `{name}`"))?;
    let causality = match attribute(e, "causality").as_deref() {
        Some("parameter") => Causality::Parameter,
        Some("calculatedParameter") => Causality::CalculatedParameter,
        Some("structuralParameter") => Causality::StructuralParameter,
        Some("input") => Causality::Input,
        Some("output") => Causality::Output,
        Some("independent") => Causality::Independent,
        Some("local") | None => Causality::Local,
        Some(other) => {
            return Err(format!(
                "variable `{name}`: causality `{other}` is none of FMI 3.0's (parameter, \
                 calculatedParameter, structuralParameter, input, output, local, independent)"
            ))
        }
    };
    Ok(Raw {
        name,
        vr,
        var_type,
        causality,
        variability: attribute(e, "variability").unwrap_or_default(),
        start: attribute(e, "start"),
        own: Inherited::of(e),
        declared_type: attribute(e, "declaredType"),
        description: attribute(e, "description"),
        dims: Vec::new(),
        aliases: Vec::new(),
    })
}

/// One start value as f64 (None: none, or not a number the master moves).
fn start_value(var_type: VarType, text: &str) -> Option<f64> {
    match var_type {
        VarType::Boolean => match text {
            "true" | "1" => Some(1.0),
            "false" | "0" => Some(0.0),
            _ => None,
        },
        VarType::String | VarType::Binary | VarType::Clock => None,
        _ => text.parse().ok(),
    }
}

/// The element names of an array of dimensions `dims`: `x[1,1]`, `x[1,2]`, … (row-major).
pub(super) fn element_names(name: &str, dims: &[usize]) -> Vec<String> {
    let count: usize = dims.iter().product();
    (0..count)
        .map(|k| {
            let mut rest = k;
            let mut index = vec![0; dims.len()];
            for (slot, d) in index.iter_mut().zip(dims).rev() {
                *slot = rest % d + 1;
                rest /= d;
            }
            let index: Vec<String> = index.iter().map(usize::to_string).collect();
            format!("{name}[{}]", index.join(","))
        })
        .collect()
}

/// Turns the variables as written into scalars and array elements, checking names and
/// value references.
fn lay_out(
    d: &mut Description,
    raw: Vec<Raw>,
    types: &HashMap<String, Inherited>,
) -> Result<(), String> {
    let mut by_vr: HashMap<u32, usize> = HashMap::new();
    for (i, r) in raw.iter().enumerate() {
        if let Some(first) = by_vr.insert(r.vr, i) {
            return Err(format!(
                "variables `{}` and `{}` share value reference {}; in FMI 3.0 a value reference \
                 names one variable (aliases are <Alias> elements)",
                raw[first].name, r.name, r.vr
            ));
        }
    }
    let mut names: HashMap<String, String> = HashMap::new();
    let mut claim = |name: &str, owner: &str| -> Result<(), String> {
        match names.insert(name.to_string(), owner.to_string()) {
            Some(first) if first == owner => Err(format!(
                "the name `{name}` is given twice (to `{first}`); names must be unique"
            )),
            Some(first) => Err(format!(
                "the name `{name}` is ambiguous: it names `{first}` and `{owner}`"
            )),
            None => Ok(()),
        }
    };
    for r in &raw {
        let dims = r
            .dims
            .iter()
            .map(|dim| match *dim {
                Dim::Fixed(n) => usize::try_from(n).map_err(|_| format!("dimension {n} is too large")),
                Dim::Structural(vr) => {
                    let Some(&p) = by_vr.get(&vr) else {
                        return Err(format!(
                            "variable `{}`: its dimension refers to value reference {vr}, which no variable has",
                            r.name
                        ));
                    };
                    let p = &raw[p];
                    p.start
                        .as_deref()
                        .and_then(|s| s.trim().parse::<u64>().ok())
                        .and_then(|n| usize::try_from(n).ok())
                        .ok_or_else(|| {
                            format!(
                                "variable `{}`: its dimension is `{}`, which has no non-negative integer start value",
                                r.name, p.name
                            )
                        })
                }
            })
            .collect::<Result<Vec<usize>, String>>()?;
        let starts: Vec<&str> = r
            .start
            .as_deref()
            .map(|s| s.split_whitespace().collect())
            .unwrap_or_default();
        let Inherited { unit, range } = r
            .own
            .clone()
            .or(r.declared_type.as_ref().and_then(|t| types.get(t)));
        let fixed = matches!(r.variability.as_str(), "fixed" | "constant");
        let head = |name: String| VariableHead {
            name,
            value_reference: r.vr,
            var_type: r.var_type,
            causality: r.causality,
        };
        let info =
            |name: String, start: Option<&str>, element: Option<(usize, usize)>| VariableInfo {
                head: head(name),
                fixed,
                start: start.and_then(|s| start_value(r.var_type, s)),
                unit: unit.clone(),
                range,
                description: r.description.clone(),
                dependencies: None,
                element,
            };
        if r.dims.is_empty() {
            claim(&r.name, &r.name)?;
            let index = d.variables.len();
            d.variables
                .push(info(r.name.clone(), starts.first().copied(), None));
            for a in &r.aliases {
                claim(a, &r.name)?;
                d.aliases.push((a.clone(), index));
            }
            continue;
        }
        claim(&r.name, &r.name)?;
        let array = d.arrays.len();
        let count: usize = dims.iter().product();
        let mut elements = Vec::with_capacity(count);
        for (k, element) in element_names(&r.name, &dims).into_iter().enumerate() {
            claim(&element, &r.name)?;
            // One start value stands for every element.
            let start = if starts.len() == 1 {
                starts.first()
            } else {
                starts.get(k)
            };
            elements.push(d.variables.len());
            d.variables
                .push(info(element, start.copied(), Some((array, k))));
        }
        d.arrays.push(ArrayInfo {
            head: head(r.name.clone()),
            dimensions: dims,
            elements,
        });
    }
    Ok(())
}

/// Checks `ModelStructure` and gives each output element its dependencies (every element
/// of every variable it lists).
fn dependencies(d: &mut Description, unknowns: &[Unknown]) -> Result<(), String> {
    // Value reference -> the variable indices that carry it (one, or an array's elements).
    let mut by_vr: HashMap<u32, Vec<usize>> = HashMap::new();
    for (i, v) in d.variables.iter().enumerate() {
        by_vr.entry(v.head.value_reference).or_default().push(i);
    }
    let array_vrs: Vec<(u32, &ArrayInfo)> = d
        .arrays
        .iter()
        .map(|a| (a.head.value_reference, a))
        .collect();
    let known = |vr: u32| by_vr.contains_key(&vr) || array_vrs.iter().any(|(v, _)| *v == vr);
    let mut listed: Vec<u32> = Vec::new();
    let mut given: Vec<(Vec<usize>, Option<Vec<usize>>)> = Vec::new();
    for (list, vr, deps) in unknowns {
        if !known(*vr) {
            return Err(format!(
                "ModelStructure/{list}: value reference {vr} is no variable's"
            ));
        }
        let mut resolved = None;
        if let Some(deps) = deps {
            let mut all = Vec::new();
            for dep in deps {
                if !known(*dep) {
                    return Err(format!(
                        "ModelStructure/{list}: dependency {dep} of value reference {vr} is no variable's"
                    ));
                }
                all.extend(by_vr.get(dep).cloned().unwrap_or_default());
            }
            resolved = Some(all);
        }
        if *list != "Output" {
            continue;
        }
        let targets = by_vr.get(vr).cloned().unwrap_or_default();
        if let Some(&first) = targets.first() {
            let v = &d.variables[first];
            if v.head.causality != Causality::Output {
                return Err(format!(
                    "ModelStructure/Output: value reference {vr} is `{}`, whose causality is {}, not output",
                    v.head.name,
                    v.head.causality.name()
                ));
            }
        }
        if listed.contains(vr) {
            return Err(format!(
                "ModelStructure/Output: value reference {vr} is listed twice"
            ));
        }
        listed.push(*vr);
        given.push((targets, resolved));
    }
    for (targets, deps) in given {
        for t in targets {
            d.variables[t].dependencies = deps.clone();
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn elements_are_named_one_based_row_major() {
        assert_eq!(
            element_names("x", &[2, 3]),
            ["x[1,1]", "x[1,2]", "x[1,3]", "x[2,1]", "x[2,2]", "x[2,3]"]
        );
        assert_eq!(element_names("u", &[2]), ["u[1]", "u[2]"]);
        assert!(element_names("e", &[0, 4]).is_empty());
    }

    const HEAD: &str = r#"<fmiModelDescription fmiVersion="3.0" modelName="M" instantiationToken="{t}">
        <CoSimulation modelIdentifier="M"/><ModelVariables>"#;

    fn md(variables: &str, structure: &str) -> String {
        format!("{HEAD}{variables}</ModelVariables><ModelStructure>{structure}</ModelStructure></fmiModelDescription>")
    }

    #[test]
    fn arrays_take_their_structural_dimensions_and_starts() {
        let xml = md(
            r#"<UInt64 name="n" valueReference="1" causality="structuralParameter" variability="fixed" start="2"/>
               <Float64 name="A" valueReference="2" causality="parameter" variability="tunable" start="1 2 3 4 5 6">
                 <Dimension valueReference="1"/><Dimension start="3"/></Float64>
               <Float64 name="u" valueReference="3" causality="input" start="7"><Dimension start="2"/></Float64>
               <Float64 name="y" valueReference="4" causality="output" unit="m" min="-1"><Dimension valueReference="1"/></Float64>"#,
            r#"<Output valueReference="4" dependencies="3"/>"#,
        );
        let d = read(&xml).unwrap();
        assert_eq!(d.co_simulation.as_deref(), Some("M"));
        assert_eq!(d.instantiation_token, "{t}");
        let names: Vec<&str> = d.variables.iter().map(|v| v.head.name.as_str()).collect();
        assert_eq!(
            names,
            [
                "n", "A[1,1]", "A[1,2]", "A[1,3]", "A[2,1]", "A[2,2]", "A[2,3]", "u[1]", "u[2]",
                "y[1]", "y[2]"
            ]
        );
        assert_eq!(d.variables[6].start, Some(6.0));
        assert_eq!(d.variables[6].element, Some((0, 5)));
        assert_eq!(
            (d.variables[7].start, d.variables[8].start),
            (Some(7.0), Some(7.0))
        );
        assert_eq!(d.arrays[0].dimensions, [2, 3]);
        assert_eq!(d.arrays[2].elements, [9, 10]);
        assert_eq!(d.variables[10].dependencies, Some(vec![7, 8]));
        assert_eq!(d.variables[10].unit.as_deref(), Some("m"));
        assert_eq!(d.variables[10].range.min, Some(-1.0));
        assert_eq!(d.variables[1].range, crate::fmu::Range::default());
        assert_eq!(
            d.variables[0].head.causality,
            Causality::StructuralParameter
        );
    }

    #[test]
    fn units_and_ranges_come_from_the_variable_or_its_declared_type() {
        let xml = r#"<fmiModelDescription fmiVersion="3.0" modelName="M" instantiationToken="{t}">
            <ModelExchange modelIdentifier="M"/>
            <TypeDefinitions><Float64Type name="Mass" unit="kg" min="0" max="1e4"/></TypeDefinitions>
            <ModelVariables>
              <Float64 name="M" valueReference="1" causality="parameter" variability="fixed" start="1" declaredType="Mass"/>
              <Float64 name="m" valueReference="2" causality="parameter" variability="fixed" start="1" declaredType="Mass" max="2.5" unit="g"/>
              <Int32 name="n" valueReference="3" causality="parameter" variability="fixed" start="1" min="-3"/>
            </ModelVariables><ModelStructure/></fmiModelDescription>"#;
        let d = read(xml).unwrap();
        let seen: Vec<_> = d
            .variables
            .iter()
            .map(|v| (v.unit.as_deref(), v.range.min, v.range.max))
            .collect();
        assert_eq!(
            seen,
            [
                (Some("kg"), Some(0.0), Some(1e4)),
                (Some("g"), Some(0.0), Some(2.5)),
                (None, Some(-3.0), None)
            ]
        );
    }

    #[test]
    fn ambiguous_names_and_references_are_refused() {
        // (variables, model structure, what the refusal says)
        let cases = [
            (
                r#"<Float64 name="x" valueReference="1" causality="output"><Dimension start="2"/></Float64>
               <Float64 name="x[2]" valueReference="2" causality="output"/>"#,
                "",
                "`x[2]` is ambiguous: it names `x` and `x[2]`",
            ),
            (
                r#"<Float64 name="a" valueReference="1"/><Int32 name="b" valueReference="1"/>"#,
                "",
                "`a` and `b` share value reference 1",
            ),
            (
                r#"<Float64 name="y" valueReference="1" causality="output"><Dimension valueReference="9"/></Float64>"#,
                "",
                "refers to value reference 9, which no variable has",
            ),
            (
                r#"<Float64 name="u" valueReference="1" causality="input"/>"#,
                r#"<Output valueReference="1"/>"#,
                "`u`, whose causality is input, not output",
            ),
        ];
        for (variables, structure, says) in cases {
            let e = read(&md(variables, structure)).unwrap_err();
            assert!(e.contains(says), "{e}");
        }
    }
}
