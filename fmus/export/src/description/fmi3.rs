//! The FMI 3.0 `modelDescription.xml`, generated from the same [`ModelInfo`] as the FMI 2.0
//! one (element order of `fmi3ModelDescription.xsd`): Co-Simulation (no event mode) and, where
//! the model declares it, Model Exchange;
//! `time` as the independent variable, arrays from [`Layout`], `Float64`/`Int32`/`Boolean`/
//! `String` elements with units, descriptions, bounds and start values (arrays: start lists),
//! `ModelStructure` with `Output` dependencies and `InitialUnknown`s.
//!
//! The instantiation token is the GUID of the FMI 2.0 description: one binary, one identity,
//! whichever version a master loads.

use super::arrays::Layout;
use crate::description::{
    dependencies, esc, is_initial_unknown, start_text, write_causality, write_default_experiment,
    write_log_categories, write_unit_and_bounds, write_units, write_variant, ModelInfo,
};
use crate::variables::{Causality, VariableType};
use std::fmt::Write;

/// The FMI 3.0 element name of a type.
pub fn type_name(t: VariableType) -> &'static str {
    match t {
        VariableType::Real => "Float64",
        VariableType::Integer => "Int32",
        VariableType::Boolean => "Boolean",
        VariableType::String => "String",
    }
}

/// The FMI 3.0 `modelDescription.xml` of `info`.
pub fn model_description(info: &ModelInfo) -> String {
    let layout = Layout::of(&info.variables);
    let mut x = String::new();
    let _ = writeln!(x, r#"<?xml version="1.0" encoding="UTF-8"?>"#);
    let _ = writeln!(
        x,
        r#"<fmiModelDescription fmiVersion="3.0" modelName="{}" instantiationToken="{}" description="{}" author="spurio" version="{}" generationTool="spurio {}" variableNamingConvention="structured">"#,
        esc(&info.model_name),
        esc(&info.guid),
        esc(&info.description),
        env!("CARGO_PKG_VERSION"),
        env!("CARGO_PKG_VERSION"),
    );
    let me = info.model_exchange.is_some();
    if me {
        let _ = writeln!(
            x,
            r#"  <ModelExchange modelIdentifier="{}" needsExecutionTool="false" canBeInstantiatedOnlyOncePerProcess="false" canGetAndSetFMUState="true" canSerializeFMUState="true" providesDirectionalDerivatives="true" providesAdjointDerivatives="true" providesPerElementDependencies="false" needsCompletedIntegratorStep="false" providesEvaluateDiscreteStates="false"/>"#,
            esc(&info.model_identifier)
        );
    }
    let _ = writeln!(
        x,
        r#"  <CoSimulation modelIdentifier="{}" needsExecutionTool="false" canBeInstantiatedOnlyOncePerProcess="false" canGetAndSetFMUState="true" canSerializeFMUState="true" providesDirectionalDerivatives="{me}" providesAdjointDerivatives="{me}" providesPerElementDependencies="false" canHandleVariableCommunicationStepSize="true" maxOutputDerivativeOrder="0" providesIntermediateUpdate="false" mightReturnEarlyFromDoStep="false" canReturnEarlyAfterIntermediateUpdate="false" hasEventMode="false" providesEvaluateDiscreteStates="false"/>"#,
        esc(&info.model_identifier)
    );
    // "s": the unit of `time`.
    let mut units: Vec<&str> = info
        .variables
        .iter()
        .filter_map(|v| v.unit.as_deref())
        .chain(["s"])
        .collect();
    units.sort_unstable();
    units.dedup();
    write_units(&mut x, units);
    write_log_categories(&mut x, "fmi3");
    write_default_experiment(&mut x, info.default_experiment.as_ref());
    let _ = writeln!(x, "  <ModelVariables>");
    let _ = writeln!(
        x,
        r#"    <Float64 name="time" valueReference="0" causality="independent" variability="continuous" description="Simulation time" unit="s"/>"#
    );
    for (k, group) in layout.variables().iter().enumerate() {
        let v = &info.variables[group.first];
        let element = type_name(v.variable_type());
        let _ = write!(
            x,
            r#"    <{element} name="{}" valueReference="{}""#,
            esc(&group.name),
            k + 1
        );
        let description = group.description(&info.variables);
        if !description.is_empty() {
            let _ = write!(x, r#" description="{}""#, esc(&description));
        }
        write_causality(&mut x, v);
        if let Some(state) = v.derivative_of.filter(|_| me) {
            if let Some(vr) = layout.value_reference_of(state) {
                let _ = write!(x, r#" derivative="{vr}""#);
            }
        }
        write_unit_and_bounds(&mut x, v);
        let string = v.variable_type() == VariableType::String;
        if v.has_start() && !string {
            let starts: Vec<String> = group
                .indices()
                .map(|i| start_text(&info.variables[i].start))
                .collect();
            let _ = write!(x, r#" start="{}""#, starts.join(" "));
        }
        if group.dims.is_empty() && !(string && v.has_start()) {
            let _ = writeln!(x, "/>");
            continue;
        }
        let _ = writeln!(x, ">");
        if string && v.has_start() {
            for i in group.indices() {
                let _ = writeln!(
                    x,
                    r#"      <Start value="{}"/>"#,
                    start_text(&info.variables[i].start)
                );
            }
        }
        for d in &group.dims {
            let _ = writeln!(x, r#"      <Dimension start="{d}"/>"#);
        }
        let _ = writeln!(x, "    </{element}>");
    }
    let _ = writeln!(x, "  </ModelVariables>");
    let _ = writeln!(x, "  <ModelStructure>");
    let dependencies_of = |group: &super::arrays::Fmi3Variable| {
        let mut deps: Vec<u32> = group
            .indices()
            .flat_map(|i| info.variables[i].dependencies.iter())
            .filter_map(|d| layout.value_reference_of(*d))
            .collect();
        deps.sort_unstable();
        deps.dedup();
        dependencies(&deps, me)
    };
    let groups = || {
        layout
            .variables()
            .iter()
            .enumerate()
            .map(|(k, g)| (k + 1, g))
    };
    for (vr, group) in groups() {
        if info.variables[group.first].causality == Causality::Output {
            let deps = dependencies_of(group);
            let _ = writeln!(x, r#"    <Output valueReference="{vr}"{deps}/>"#);
        }
    }
    if let Some(m) = &info.model_exchange {
        // In state order (the derivatives of an array state form an array).
        let mut written = Vec::new();
        for &d in &m.derivatives {
            let Some(vr) = layout.value_reference_of(d) else {
                continue;
            };
            if written.contains(&vr) {
                continue;
            }
            written.push(vr);
            if let Some((_, group)) = groups().find(|(k, _)| *k as u32 == vr) {
                let deps = dependencies_of(group);
                let _ = writeln!(
                    x,
                    r#"    <ContinuousStateDerivative valueReference="{vr}"{deps}/>"#
                );
            }
        }
    }
    for (vr, group) in groups() {
        if is_initial_unknown(&info.variables[group.first], me) {
            let _ = writeln!(x, r#"    <InitialUnknown valueReference="{vr}"/>"#);
        }
    }
    for (vr, group) in groups() {
        if me && info.variables[group.first].event_indicator {
            let _ = writeln!(x, r#"    <EventIndicator valueReference="{vr}"/>"#);
        }
    }
    let _ = writeln!(x, "  </ModelStructure>");
    write_variant(
        &mut x,
        &info.config,
        "Annotations",
        r#"Annotation type="spurio""#,
        "Annotation",
    );
    let _ = writeln!(x, "</fmiModelDescription>");
    x
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::description::tests::{assert_in_order, SCHEMA_ORDER};
    use crate::description::{Config, DefaultExperiment};
    use crate::variables::Variable;

    fn info() -> ModelInfo {
        let mut config = Config::new();
        config.set("n", 2);
        ModelInfo::new(
            "Demo",
            "A <demo>",
            vec![
                Variable::parameter("A[1,1]", 1.0).unit("m"),
                Variable::parameter("A[1,2]", 0.5).unit("m"),
                Variable::input("u[1]", 0.0).unit("N"),
                Variable::input("u[2]", 0.0).unit("N"),
                Variable::output("y[1]").depends_on(&[3]),
                Variable::output("y[2]"),
                Variable::integer_parameter("N", 3).min(1.0),
                Variable::boolean_output("flag"),
            ],
            Some(DefaultExperiment {
                start_time: 0.0,
                stop_time: 1.0,
                step_size: 0.01,
            }),
            config,
        )
    }

    #[test]
    fn arrays_dimensions_and_structure() {
        let info = info();
        let x = model_description(&info);
        assert!(x.contains(&format!(r#"instantiationToken="{}""#, info.guid)));
        assert!(x.contains(
            r#"<Float64 name="A" valueReference="1" causality="parameter" variability="fixed" initial="exact" unit="m" start="1.0 0.5">"#
        ));
        assert!(x.contains(
            "      <Dimension start=\"1\"/>\n      <Dimension start=\"2\"/>\n    </Float64>"
        ));
        assert!(x.contains(r#"<Float64 name="u" valueReference="2" causality="input" variability="continuous" unit="N" start="0.0 0.0">"#));
        assert!(x.contains(r#"<Int32 name="N" valueReference="4" causality="parameter" variability="fixed" initial="exact" min="1" start="3"/>"#));
        assert!(x.contains(r#"<Boolean name="flag" valueReference="5" causality="output" variability="discrete" initial="calculated"/>"#));
        assert!(x.contains(r#"<Output valueReference="3" dependencies="2"/>"#));
        assert!(x.contains(r#"<Output valueReference="5" dependencies=""/>"#));
        assert!(x.contains(r#"<InitialUnknown valueReference="3"/>"#));
        assert!(x.contains(r#"<Setting name="n" value="2"/>"#));
        let order: Vec<&str> = SCHEMA_ORDER.into_iter().chain(["<Annotations>"]).collect();
        assert_in_order(&x, &order);
    }
}
