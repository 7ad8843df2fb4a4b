//! The rules of FMI 2.0 on model variables and `ModelStructure` that a master relies on to
//! address variables unambiguously:
//! - a variable's name is unique;
//! - a value reference identifies one value per base type (Real, Integer/Enumeration,
//!   Boolean, String); variables sharing it within a base type are aliases of one value,
//!   and of an alias set at most one variable whose variability is not `constant` may carry
//!   a `start` value (so at most one parameter or input, which must have one);
//! - every `index` and `dependencies` entry of `ModelStructure` is the 1-based position of a
//!   variable in `ModelVariables`; an entry of `Outputs` is a variable of causality output,
//!   listed once; an entry of `Derivatives` is a Real.

use super::xml::Unknown;
use super::{Causality, VarType, VariableInfo};
use std::collections::HashMap;

/// Checks names and alias sets. `has_start[i]` and `constant[i]` describe variable `i`.
pub(super) fn variables(
    vars: &[VariableInfo],
    has_start: &[bool],
    constant: &[bool],
) -> Result<(), String> {
    let mut by_name: HashMap<&str, usize> = HashMap::with_capacity(vars.len());
    for (i, v) in vars.iter().enumerate() {
        if let Some(first) = by_name.insert(&v.head.name, i) {
            return Err(format!(
                "two variables are called `{}` (variables {} and {} of ModelVariables); names must be unique",
                v.head.name,
                first + 1,
                i + 1
            ));
        }
    }
    // The variable of each alias set that carries a start value (variability not constant).
    let mut start_holder: HashMap<(VarType, u32), usize> = HashMap::new();
    for (i, v) in vars.iter().enumerate() {
        let starts = has_start.get(i).copied().unwrap_or(false);
        let is_constant = constant.get(i).copied().unwrap_or(false);
        if !starts || is_constant {
            continue;
        }
        let key = (v.head.var_type.base(), v.head.value_reference);
        if let Some(&first) = start_holder.get(&key) {
            let a = &vars[first];
            return Err(format!(
                "variables `{}` ({}) and `{}` ({}) share value reference {} ({}) and both have a start value; \
                 FMI 2.0 allows at most one start value in a set of aliases, so the value would be ambiguous",
                a.head.name,
                a.head.causality.name(),
                v.head.name,
                v.head.causality.name(),
                v.head.value_reference,
                match key.0 {
                    VarType::Integer => "Integer/Enumeration",
                    base => base.name(),
                }
            ));
        }
        start_holder.insert(key, i);
    }
    Ok(())
}

/// Checks `ModelStructure` against the variables and returns, for each output's 0-based
/// index, its 0-based dependencies (`None` when the attribute is absent).
pub(super) fn model_structure(
    vars: &[VariableInfo],
    unknowns: &[Unknown],
) -> Result<HashMap<usize, Option<Vec<usize>>>, String> {
    let n = vars.len();
    let position = |what: &str, list: &str, text: &str| -> Result<usize, String> {
        match text.parse::<usize>() {
            Ok(i) if (1..=n).contains(&i) => Ok(i - 1),
            Ok(i) => Err(format!(
                "ModelStructure/{list}: {what} {i} is out of range (ModelVariables has {n} variables, numbered from 1)"
            )),
            Err(_) => Err(format!(
                "ModelStructure/{list}: {what} `{text}` is not a variable number"
            )),
        }
    };
    let mut outputs = HashMap::new();
    for u in unknowns {
        let Some(index) = &u.index else {
            return Err(format!(
                "ModelStructure/{}: an <Unknown> has no index",
                u.list
            ));
        };
        let i = position("index", u.list, index)?;
        let mut deps = None;
        if let Some(list) = &u.dependencies {
            let mut d = Vec::with_capacity(list.len());
            for text in list {
                let j = position(
                    &format!("a dependency of `{}`", vars[i].head.name),
                    u.list,
                    text,
                )?;
                d.push(j);
            }
            deps = Some(d);
        }
        match u.list {
            "Outputs" => {
                if vars[i].head.causality != Causality::Output {
                    return Err(format!(
                        "ModelStructure/Outputs: index {} is `{}`, whose causality is {}, not output",
                        i + 1,
                        vars[i].head.name,
                        vars[i].head.causality.name()
                    ));
                }
                if outputs.insert(i, deps).is_some() {
                    return Err(format!(
                        "ModelStructure/Outputs: `{}` (index {}) is listed twice",
                        vars[i].head.name,
                        i + 1
                    ));
                }
            }
            "Derivatives" if vars[i].head.var_type != VarType::Real => {
                return Err(format!(
                    "ModelStructure/Derivatives: index {} is `{}`, which is not a Real",
                    i + 1,
                    vars[i].head.name
                ));
            }
            _ => {}
        }
    }
    Ok(outputs)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fmu::{Range, VariableHead};

    fn var(name: &str, vr: u32, t: VarType, c: Causality) -> VariableInfo {
        VariableInfo {
            head: VariableHead {
                name: name.into(),
                value_reference: vr,
                var_type: t,
                causality: c,
            },
            fixed: false,
            start: None,
            unit: None,
            range: Range::default(),
            description: None,
            dependencies: None,
            element: None,
        }
    }

    #[test]
    fn aliases_follow_the_base_type_rule() {
        use Causality::*;
        use VarType::*;
        // Same vr, different base types: allowed.
        let v = [
            var("a", 1, Real, Parameter),
            var("b", 1, Integer, Parameter),
        ];
        assert_eq!(variables(&v, &[true, true], &[false, false]), Ok(()));
        // Same vr and base type, one start: an alias, allowed.
        let v = [var("a", 1, Real, Input), var("b", 1, Real, Output)];
        assert_eq!(variables(&v, &[true, false], &[false, false]), Ok(()));
        // Integer and Enumeration share a base type: two starts are refused.
        let v = [
            var("k", 2, Integer, Parameter),
            var("e", 2, Enumeration, Parameter),
        ];
        let e = variables(&v, &[true, true], &[false, false]).unwrap_err();
        assert!(
            e.contains(
                "`k` (parameter) and `e` (parameter) share value reference 2 (Integer/Enumeration)"
            ),
            "{e}"
        );
        // Constants may each have their start.
        let v = [var("c", 3, Real, Local), var("d", 3, Real, Local)];
        assert_eq!(variables(&v, &[true, true], &[true, true]), Ok(()));
    }

    #[test]
    fn indices_are_checked_and_converted() {
        use Causality::*;
        use VarType::*;
        let v = [var("u", 0, Real, Input), var("y", 1, Real, Output)];
        let u = |list, index: &str, deps: Option<&[&str]>| Unknown {
            list,
            index: Some(index.into()),
            dependencies: deps.map(|d| d.iter().map(|s| s.to_string()).collect()),
        };
        let ok = model_structure(&v, &[u("Outputs", "2", Some(&["1"]))]).unwrap();
        assert_eq!(ok[&1], Some(vec![0]));
        let e = model_structure(&v, &[u("Outputs", "3", None)]).unwrap_err();
        assert!(
            e.contains("index 3 is out of range (ModelVariables has 2"),
            "{e}"
        );
        let e = model_structure(&v, &[u("Outputs", "2", Some(&["0"]))]).unwrap_err();
        assert!(e.contains("a dependency of `y` 0 is out of range"), "{e}");
        let e = model_structure(&v, &[u("Outputs", "1", None)]).unwrap_err();
        assert!(e.contains("`u`, whose causality is input"), "{e}");
    }
}
