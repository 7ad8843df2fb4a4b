//! What the model description says that rust-fmi's schema does not keep: the entries of
//! `ModelStructure` as written (so indices can be checked and an absent `dependencies` told
//! from an empty one), each variable's unit and whether it declares a start value.

use crate::xml::{attribute, tags, Tag};
use std::collections::HashMap;

/// One `<Unknown>` of `ModelStructure`, as written.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) struct Unknown {
    /// `Outputs`, `Derivatives` or `InitialUnknowns`.
    pub list: &'static str,
    /// The `index` attribute, unparsed (`None` when absent).
    pub index: Option<String>,
    /// The `dependencies` attribute split at whitespace, unparsed (`None` when absent).
    pub dependencies: Option<Vec<String>>,
}

/// Every `<Unknown>` of `ModelStructure`, in file order.
pub(super) fn model_structure(xml: &str) -> Result<Vec<Unknown>, String> {
    let mut list: Option<&'static str> = None;
    let mut out = Vec::new();
    for tag in tags(xml) {
        match tag? {
            // A self-closing list (`<Outputs/>`) holds nothing and has no end tag.
            Tag::Start { element: e, empty } => match e.name().as_ref() {
                "Outputs" if !empty => list = Some("Outputs"),
                "Derivatives" if !empty => list = Some("Derivatives"),
                "InitialUnknowns" if !empty => list = Some("InitialUnknowns"),
                "Unknown" => out.extend(unknown(list, &e)),
                _ => {}
            },
            Tag::End(e)
                if matches!(
                    e.name().as_ref(),
                    "Outputs" | "Derivatives" | "InitialUnknowns"
                ) =>
            {
                list = None
            }
            Tag::End(_) => {}
        }
    }
    Ok(out)
}

fn unknown(list: Option<&'static str>, e: &quick_xml::events::BytesStart) -> Option<Unknown> {
    let list = list?;
    let mut index = None;
    let mut dependencies = None;
    for a in e.attributes().flatten() {
        let value = a.value.to_string();
        match a.key.as_ref() {
            "index" => index = Some(value.trim().to_string()),
            "dependencies" => {
                dependencies = Some(value.split_whitespace().map(str::to_string).collect())
            }
            _ => {}
        }
    }
    Some(Unknown {
        list,
        index,
        dependencies,
    })
}

/// What rust-fmi's schema does not keep of the `ScalarVariable`s, each list in file order.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct VariableExtras {
    /// The unit: the variable's own `unit` attribute, else that of its `declaredType`.
    pub units: Vec<Option<String>>,
    /// Whether its type element has a `start`.
    pub has_start: Vec<bool>,
}

/// The units and start flags of every `ScalarVariable`, in one walk.
pub(super) fn variable_extras(xml: &str) -> Result<VariableExtras, String> {
    let mut type_units: HashMap<String, String> = HashMap::new();
    let mut simple_type: Option<String> = None;
    let mut in_variable = false;
    // (own unit, declared type) per variable.
    let mut declared: Vec<(Option<String>, Option<String>)> = Vec::new();
    let mut has_start = Vec::new();
    for tag in tags(xml) {
        match tag? {
            Tag::End(e) => match e.name().as_ref() {
                "SimpleType" => simple_type = None,
                "ScalarVariable" => in_variable = false,
                _ => {}
            },
            Tag::Start { element: e, empty } => match e.name().as_ref() {
                "SimpleType" if !empty => simple_type = attribute(&e, "name"),
                "ScalarVariable" => {
                    declared.push((None, None));
                    has_start.push(false);
                    in_variable = !empty;
                }
                kind @ ("Real" | "Integer" | "Boolean" | "String" | "Enumeration") => {
                    let has_unit = matches!(kind, "Real" | "Integer" | "Enumeration");
                    if let Some(name) = &simple_type {
                        if let Some(unit) = attribute(&e, "unit").filter(|_| has_unit) {
                            type_units.insert(name.clone(), unit);
                        }
                    } else if in_variable {
                        if let Some(last) = declared.last_mut().filter(|_| has_unit) {
                            *last = (attribute(&e, "unit"), attribute(&e, "declaredType"));
                        }
                        if let Some(last) = has_start.last_mut() {
                            *last |= e.attributes().flatten().any(|a| a.key.as_ref() == "start");
                        }
                    }
                }
                _ => {}
            },
        }
    }
    let units = declared
        .into_iter()
        .map(|(unit, declared_type)| {
            unit.or_else(|| declared_type.and_then(|t| type_units.get(&t).cloned()))
        })
        .collect();
    Ok(VariableExtras { units, has_start })
}

/// What each FMI 2.0 element that rust-fmi's schema reads strictly allows, by the schema's
/// name for it: `(schema type, element, what it allows)`. The schema names an element by
/// its Rust type, which differs from the element for `<Unit>` and `<fmiModelDescription>`.
const FMI2_ELEMENTS: &[(&str, &str, &str)] = &[
    (
        "Fmi2Unit",
        "Unit",
        "the attribute name and the elements <BaseUnit> (at most one) and <DisplayUnit>",
    ),
    (
        "BaseUnit",
        "BaseUnit",
        "the attributes kg, m, s, A, K, mol, cd, rad, factor and offset",
    ),
    (
        "DisplayUnit",
        "DisplayUnit",
        "the attributes name, factor, offset and inverse",
    ),
    ("UnitDefinitions", "UnitDefinitions", "the elements <Unit>"),
    (
        "TypeDefinitions",
        "TypeDefinitions",
        "the elements <SimpleType>",
    ),
    ("LogCategories", "LogCategories", "the elements <Category>"),
    (
        "ModelVariables",
        "ModelVariables",
        "the elements <ScalarVariable>",
    ),
    (
        "ModelStructure",
        "ModelStructure",
        "the elements <Outputs>, <Derivatives> and <InitialUnknowns>",
    ),
    (
        "Fmi2ModelDescription",
        "fmiModelDescription",
        "the attributes of FMI 2.0",
    ),
];

/// The message of rust-fmi's FMI 2.0 schema refusing a model description, in the standard's
/// terms: hard_xml's `unknown field "X" in element "T"` (`T` the schema's Rust type) becomes
/// `<Element> has `X`, which FMI 2.0 does not allow there (allowed: …)`. Other messages are
/// kept as they are.
pub(super) fn schema_error(error: &dyn std::fmt::Display) -> String {
    let text = error.to_string();
    let unknown = text
        .strip_prefix("unknown field \"")
        .and_then(|rest| rest.split_once("\" in element \""))
        .and_then(|(field, rest)| Some((field, rest.strip_suffix('"')?)));
    let Some((field, schema_type)) = unknown else {
        return text;
    };
    match FMI2_ELEMENTS.iter().find(|(t, _, _)| *t == schema_type) {
        Some((_, element, allowed)) => format!(
            "<{element}> has `{field}`, which FMI 2.0 does not allow there (allowed: {allowed})"
        ),
        None => format!(
            "<{}> has `{field}`, which FMI 2.0 does not allow there",
            schema_type.strip_prefix("Fmi2").unwrap_or(schema_type)
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn model_structure_tells_absent_from_empty_dependencies() {
        let xml = r#"<a><ModelStructure><Outputs>
            <Unknown index="2" dependencies=""/>
            <Unknown index="3" dependencies="1 4"/>
            <Unknown index="5"/>
        </Outputs><InitialUnknowns><Unknown index="7"></Unknown></InitialUnknowns>
        </ModelStructure></a>"#;
        let d = model_structure(xml).unwrap();
        let deps: Vec<_> = d
            .iter()
            .map(|u| (u.list, u.index.as_deref(), u.dependencies.clone()))
            .collect();
        assert_eq!(
            deps,
            vec![
                ("Outputs", Some("2"), Some(vec![])),
                (
                    "Outputs",
                    Some("3"),
                    Some(vec!["1".to_string(), "4".to_string()])
                ),
                ("Outputs", Some("5"), None),
                ("InitialUnknowns", Some("7"), None),
            ]
        );
    }

    #[test]
    fn start_values_are_seen_on_every_type() {
        let xml = r#"<m><ModelVariables>
            <ScalarVariable name="a" valueReference="0"><Real start="1"/></ScalarVariable>
            <ScalarVariable name="b" valueReference="0"><Real/></ScalarVariable>
            <ScalarVariable name="c" valueReference="0"><String start="x"/></ScalarVariable>
            <ScalarVariable name="d" valueReference="0"><Enumeration declaredType="E"/></ScalarVariable>
        </ModelVariables></m>"#;
        assert_eq!(
            variable_extras(xml).unwrap().has_start,
            vec![true, false, true, false]
        );
    }

    #[test]
    fn units_come_from_the_variable_or_its_declared_type() {
        let xml = r#"<fmiModelDescription>
            <TypeDefinitions>
              <SimpleType name="Length"><Real quantity="Length" unit="m"/></SimpleType>
            </TypeDefinitions>
            <ModelVariables>
              <ScalarVariable name="x" valueReference="0"><Real declaredType="Length"/></ScalarVariable>
              <ScalarVariable name="F" valueReference="1"><Real unit="N" declaredType="Length"/></ScalarVariable>
              <ScalarVariable name="n" valueReference="2"><Integer/></ScalarVariable>
              <ScalarVariable name="v" valueReference="3"><Real unit="m/s"/></ScalarVariable>
            </ModelVariables></fmiModelDescription>"#;
        assert_eq!(
            variable_extras(xml).unwrap().units,
            vec![Some("m".into()), Some("N".into()), None, Some("m/s".into())]
        );
    }
}
