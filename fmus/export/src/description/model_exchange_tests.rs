//! The Model Exchange interface in both model descriptions, and the declaration errors.

use super::model_exchange::DeclarationError;
use super::{Config, ModelInfo};
use crate::variables::Variable;

/// x (output, state), v (local state), u (input), der(x) = v, der(v) = u − x, z = x
/// (der(v)'s dependencies declared out of order and twice: the descriptions sort them).
fn table() -> Vec<Variable> {
    vec![
        Variable::output("x").state().nominal(0.5).depends_on(&[0]),
        Variable::derivative("v", 0).state().describe("velocity"),
        Variable::input("u", 0.0),
        Variable::derivative("der(v)", 1).depends_on(&[2, 0, 2]),
        Variable::event_indicator("z"),
    ]
}

fn info(variables: Vec<Variable>) -> Result<ModelInfo, DeclarationError> {
    ModelInfo::new("Osc", "", variables, None, Config::new()).with_model_exchange()
}

#[test]
fn the_interface_comes_from_the_table() {
    let info = info(table()).unwrap();
    let me = info.model_exchange.as_ref().unwrap();
    assert_eq!(
        (me.states.clone(), me.derivatives.clone()),
        (vec![0, 1], vec![1, 3])
    );
    assert_eq!(me.event_indicators, [4]);
    assert_eq!(me.nominals(&info.variables).collect::<Vec<_>>(), [0.5, 1.0]);
    // the GUID covers the interface
    let cs = ModelInfo::new("Osc", "", table(), None, Config::new());
    assert_ne!(cs.guid, info.guid);
}

#[test]
fn both_descriptions_declare_it() {
    let info = info(table()).unwrap();
    let x = info.to_xml();
    super::tests::assert_in_order(
        &x,
        &[
            "numberOfEventIndicators=\"1\"",
            "<ModelExchange modelIdentifier=\"Osc\"",
            "<CoSimulation",
        ],
    );
    assert!(x.contains(r#"providesDirectionalDerivative="true"/>"#));
    assert!(x.contains(r#"<Real nominal="0.5"/>"#));
    assert!(x.contains(r#"name="v" valueReference="1" description="velocity" causality="local" variability="continuous" initial="calculated">"#));
    assert!(x.contains(r#"<Real derivative="1"/>"#));
    assert!(x.contains(r#"<Real derivative="2"/>"#));
    let structure = &x[x.find("<ModelStructure>").unwrap()..];
    super::tests::assert_in_order(
        structure,
        &[
            "<Outputs>",
            r#"<Unknown index="1" dependencies="1"/>"#,
            "<Derivatives>",
            r#"<Unknown index="2"/>"#,
            r#"<Unknown index="4" dependencies="1 3"/>"#,
            "<InitialUnknowns>",
        ],
    );
    let initial = &structure[structure.find("<InitialUnknowns>").unwrap()..];
    super::tests::assert_in_order(
        initial,
        &[
            r#"<Unknown index="1"/>"#,
            r#"<Unknown index="2"/>"#,
            r#"<Unknown index="4"/>"#,
            "</InitialUnknowns>",
        ],
    );
    assert!(
        !initial.contains(r#"index="5""#),
        "an event indicator is no initial unknown"
    );
    let x3 = super::fmi3::model_description(&info);
    super::tests::assert_in_order(
        &x3,
        &[
            r#"<ModelExchange modelIdentifier="Osc""#,
            r#"providesDirectionalDerivatives="true" providesAdjointDerivatives="true""#,
            "<CoSimulation",
            r#"name="x" valueReference="1""#,
            r#"name="v" valueReference="2""#,
            r#"derivative="1""#,
            r#"name="der(v)" valueReference="4""#,
            r#"derivative="2""#,
            r#"<Output valueReference="1" dependencies="1"/>"#,
            r#"<ContinuousStateDerivative valueReference="2"/>"#,
            r#"<ContinuousStateDerivative valueReference="4" dependencies="1 3"/>"#,
            r#"<InitialUnknown valueReference="1"/>"#,
            r#"<EventIndicator valueReference="5"/>"#,
        ],
    );
}

#[test]
fn inconsistent_declarations_are_errors() {
    use crate::variables::Causality;
    type Edit = fn(&mut Vec<Variable>);
    let cases: [(Edit, &str); 8] = [
        (|t| t[3].derivative_of = None, "state `v` has no derivative"),
        (
            |t| t[4].derivative_of = Some(1),
            "state `v` has two derivatives",
        ),
        (
            |t| t[3].derivative_of = Some(2),
            "state `v` has no derivative: declare `der(v)` with derivative_of",
        ),
        (
            |t| t[2].state = true,
            "state `u` must be a continuous Real output or local variable",
        ),
        (
            |t| t.push(Variable::parameter("k", 1.0).derivative_of(0)),
            "state `x` has two derivatives, `v` and `k`",
        ),
        (
            |t| t.push(Variable::output("w").derivative_of(2)),
            "derivative `w` is declared of index 2",
        ),
        (
            |t| t[4].causality = Causality::Output,
            "event indicator `z` must be a continuous Real local",
        ),
        (
            |t| t.retain(|v| !v.state && v.derivative_of.is_none()),
            "at least one state",
        ),
    ];
    for (edit, message) in cases {
        let mut t = table();
        edit(&mut t);
        let e = info(t).unwrap_err().to_string();
        assert!(e.contains(message), "{e}");
    }
}
