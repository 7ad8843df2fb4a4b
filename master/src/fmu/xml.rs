//! What the model description says that rust-fmi's schema does not keep: the entries of
//! `ModelStructure` as written (so indices can be checked and an absent `dependencies` told
//! from an empty one), each variable's unit and whether it declares a start value.

use super::Range;
use crate::xml::{attribute, tags, Tag};
use quick_xml::events::BytesStart;
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
    /// `min` and `max`: each the variable's own, else its `declaredType`'s.
    pub ranges: Vec<Range>,
    /// Whether its type element has a `start`.
    pub has_start: Vec<bool>,
}

/// The attributes a variable takes from its type definition when it does not declare them
/// itself: `unit`, `min`, `max`.
#[derive(Debug, Clone, Default, PartialEq)]
pub(super) struct Inherited {
    pub unit: Option<String>,
    pub range: Range,
}

impl Inherited {
    /// The `unit`, `min` and `max` of a numeric type element; a bound that is not a number is
    /// no bound.
    pub fn of(element: &BytesStart) -> Self {
        let bound = |key| attribute(element, key).and_then(|t| t.trim().parse::<f64>().ok());
        Self {
            unit: attribute(element, "unit"),
            range: Range {
                min: bound("min"),
                max: bound("max"),
            },
        }
    }

    /// These attributes, each absent one taken from `declared` (a type definition's).
    pub fn or(self, declared: Option<&Inherited>) -> Self {
        let Some(d) = declared else { return self };
        Self {
            unit: self.unit.or_else(|| d.unit.clone()),
            range: Range {
                min: self.range.min.or(d.range.min),
                max: self.range.max.or(d.range.max),
            },
        }
    }
}

/// The units, ranges and start flags of every `ScalarVariable`, in one walk.
pub(super) fn variable_extras(xml: &str) -> Result<VariableExtras, String> {
    let mut types: HashMap<String, Inherited> = HashMap::new();
    let mut simple_type: Option<String> = None;
    let mut in_variable = false;
    // (own attributes, declared type) per variable.
    let mut declared: Vec<(Inherited, Option<String>)> = Vec::new();
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
                    declared.push((Inherited::default(), None));
                    has_start.push(false);
                    in_variable = !empty;
                }
                kind @ ("Real" | "Integer" | "Boolean" | "String" | "Enumeration") => {
                    let numeric = matches!(kind, "Real" | "Integer" | "Enumeration");
                    if let Some(name) = &simple_type {
                        if numeric {
                            types.insert(name.clone(), Inherited::of(&e));
                        }
                    } else if in_variable {
                        if let Some(last) = declared.last_mut().filter(|_| numeric) {
                            *last = (Inherited::of(&e), attribute(&e, "declaredType"));
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
    let (units, ranges) = declared
        .into_iter()
        .map(|(own, declared_type)| {
            let all = own.or(declared_type.and_then(|t| types.get(&t)));
            (all.unit, all.range)
        })
        .unzip();
    Ok(VariableExtras {
        units,
        ranges,
        has_start,
    })
}

/// The FMI 2.0 elements whose rust-fmi schema type is not named as the element:
/// `(schema type, element)`. rust-fmi's errors name an element by its Rust type.
const FMI2_TYPE_NAMES: &[(&str, &str)] = &[
    ("Fmi2ModelDescription", "fmiModelDescription"),
    ("Fmi2Unit", "Unit"),
    ("Fmi2VariableDependency", "Unknown"),
];

/// What each FMI 2.0 element that rust-fmi's schema reads strictly allows:
/// `(element, what it allows)`.
const FMI2_ALLOWED: &[(&str, &str)] = &[
    (
        "Unit",
        "the attribute name and the elements <BaseUnit> (at most one) and <DisplayUnit>",
    ),
    (
        "BaseUnit",
        "the attributes kg, m, s, A, K, mol, cd, rad, factor and offset",
    ),
    (
        "DisplayUnit",
        "the attributes name, factor, offset and inverse",
    ),
    ("UnitDefinitions", "the elements <Unit>"),
    ("TypeDefinitions", "the elements <SimpleType>"),
    ("LogCategories", "the elements <Category>"),
    ("ModelVariables", "the elements <ScalarVariable>"),
    (
        "ModelStructure",
        "the elements <Outputs>, <Derivatives> and <InitialUnknowns>",
    ),
    ("fmiModelDescription", "the attributes of FMI 2.0"),
];

/// The FMI 2.0 element rust-fmi's schema type `schema_type` reads.
fn fmi2_element(schema_type: &str) -> &str {
    FMI2_TYPE_NAMES
        .iter()
        .find(|(t, _)| *t == schema_type)
        .map_or(schema_type, |(_, element)| element)
}

/// The attribute the schema's Rust field `field` reads: its name in camel case
/// (`value_reference` → `valueReference`), as every required attribute of FMI 2.0 is.
fn fmi2_attribute(field: &str) -> String {
    let mut parts = field.split('_');
    let mut name = parts.next().unwrap_or_default().to_string();
    for part in parts {
        let mut chars = part.chars();
        if let Some(first) = chars.next() {
            name.extend(first.to_uppercase());
            name.push_str(chars.as_str());
        }
    }
    name
}

/// The message of rust-fmi's FMI 2.0 schema refusing a model description, in the standard's
/// terms: an element is named as FMI 2.0 names it (`<Unit>`, not the schema's `Fmi2Unit`)
/// and an attribute too (`valueReference`, not the field `value_reference`). An unknown
/// attribute or child says what the element allows; a missing one that it is required.
/// Other messages (a value that does not parse) are kept as they are.
pub(super) fn schema_error(error: &fmi::schema::Error) -> String {
    use hard_xml::XmlError;
    let fmi::schema::Error::XmlParse(xml_error) = error else {
        return error.to_string();
    };
    match xml_error {
        XmlError::UnknownField { name, field } => {
            let element = fmi2_element(name);
            match FMI2_ALLOWED.iter().find(|(e, _)| *e == element) {
                Some((_, allowed)) => format!(
                    "<{element}> has `{field}`, which FMI 2.0 does not allow there (allowed: {allowed})"
                ),
                None => format!("<{element}> has `{field}`, which FMI 2.0 does not allow there"),
            }
        }
        // The variable's type element is the schema's field `elem`.
        XmlError::MissingField { name, field } if name == "ScalarVariable" && field == "elem" => {
            "a <ScalarVariable> has none of <Real>, <Integer>, <Boolean>, <String> and \
             <Enumeration>, one of which FMI 2.0 requires"
                .to_string()
        }
        XmlError::MissingField { name, field } => format!(
            "<{}> has no `{}`, which FMI 2.0 requires there",
            fmi2_element(name),
            fmi2_attribute(field)
        ),
        other => other.to_string(),
    }
}

/// Why `xml`, which says fmiVersion 2.0 and which FMI 2.0's schema refuses, is an FMI 3.0
/// description, if it is shaped as one: its root has FMI 3.0's `instantiationToken`, or
/// its variables are FMI 3.0's typed elements (`<Float64>`, …) instead of `<ScalarVariable>`.
pub(super) fn fmi3_shape(xml: &str) -> Option<&'static str> {
    let mut in_variables = false;
    for tag in tags(xml) {
        let Ok(Tag::Start { element, empty }) = tag else {
            continue;
        };
        match element.name().as_ref() {
            "fmiModelDescription" if attribute(&element, "instantiationToken").is_some() => {
                return Some("its <fmiModelDescription> has an instantiationToken (FMI 2.0: guid)")
            }
            "ModelVariables" => in_variables = !empty,
            "Float64" | "Float32" | "Int8" | "UInt8" | "Int16" | "UInt16" | "Int32" | "UInt32"
            | "Int64" | "UInt64" | "Binary" | "Clock"
                if in_variables =>
            {
                return Some(
                    "it declares its variables as <Float64>, <Int32>, … (FMI 2.0 declares \
                     <ScalarVariable>)",
                )
            }
            _ => {}
        }
    }
    None
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

    #[test]
    fn ranges_come_from_the_variable_or_its_declared_type_bound_by_bound() {
        let xml = r#"<fmiModelDescription>
            <TypeDefinitions>
              <SimpleType name="Mass"><Real unit="kg" min="0" max="1e4"/></SimpleType>
            </TypeDefinitions>
            <ModelVariables>
              <ScalarVariable name="M" valueReference="0"><Real declaredType="Mass"/></ScalarVariable>
              <ScalarVariable name="m" valueReference="1"><Real declaredType="Mass" max="2.5"/></ScalarVariable>
              <ScalarVariable name="n" valueReference="2"><Integer min="-3"/></ScalarVariable>
              <ScalarVariable name="b" valueReference="3"><Boolean/></ScalarVariable>
              <ScalarVariable name="e" valueReference="4"><Real min="0.5" max="oops"/></ScalarVariable>
            </ModelVariables></fmiModelDescription>"#;
        let range = |min, max| Range { min, max };
        assert_eq!(
            variable_extras(xml).unwrap().ranges,
            vec![
                range(Some(0.0), Some(1e4)),
                range(Some(0.0), Some(2.5)),
                range(Some(-3.0), None),
                range(None, None),
                range(Some(0.5), None),
            ]
        );
        let r = range(Some(0.0), Some(2.5));
        assert_eq!((r.clamp(-1.0), r.clamp(1.0), r.clamp(3.0)), (0.0, 1.0, 2.5));
        assert_eq!(Range::default().clamp(-7.0), -7.0);
    }
}
