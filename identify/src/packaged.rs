//! An estimator FMU's declaration (fmus/PlantEstimator): the `key = value` entries that
//! `spurio package-estimator` writes into the FMU's `resources/variant.cfg` beside the plant
//! FMU it unpacks into `resources/plant/`, from which the FMU's binary builds its variables
//! and sets up the same filter as `spurio identify --method ukf|ekf` (docs/estimators.md,
//! "An estimator FMU for any plant FMU"):
//!
//! ```text
//! name = GantryCraneEstimator   the model name
//! plant = GantryCrane           the plant's model name (for messages and the page)
//! method = ukf                  ukf | ekf
//! robust = huber                huber | tukey | none
//! tolerance = 1e-8              relative tolerance of the plant's integration
//! inputs = 1                    the plant inputs u, in order, with their units
//! input.1 = U
//! input.1.unit = N
//! outputs = 2                   the measured variables y, their units and variances R
//! output.1 = x
//! output.1.unit = m
//! output.1.noise = 1e-6
//! states = 4                    the plant's continuous states x (names, units)
//! state.1 = x
//! free = 3                      the free parameters θ, their units and start values θ₀
//! free.1 = M
//! free.1.start = 1.01262
//! set = 1                       parameters set for the experiment, not estimated
//! set.1 = x0
//! set.1.value = 0.2
//! ```
//!
//! Names are kept whole (a name may hold `,` or `[ ]`); a name or unit holding `#` or a line
//! break cannot be carried and is refused when declared.

use crate::online::{Method, Robust};
pub use spurio_table::declaration::DeclarationError;
use spurio_table::declaration::{invalid, Entries};

/// A variable of the plant by name, with its unit.
#[derive(Debug, Clone, PartialEq)]
pub struct Named {
    pub name: String,
    pub unit: Option<String>,
}

/// One estimator FMU's declaration (module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct EstimatorDeclaration {
    pub name: String,
    pub plant: String,
    pub method: Method,
    pub robust: Robust,
    pub tolerance: f64,
    pub inputs: Vec<Named>,
    /// Parameters of the plant set for the experiment (not estimated): (name, value).
    pub set: Vec<(String, f64)>,
    pub outputs: Vec<Named>,
    /// R: one variance per measured variable.
    pub noise: Vec<f64>,
    pub states: Vec<Named>,
    pub free: Vec<Named>,
    /// θ₀: one start per free parameter.
    pub starts: Vec<f64>,
}

/// Writes `v` so that parsing gives it back exactly (Rust's shortest round trip).
fn number_text(v: f64) -> String {
    format!("{v:?}")
}

impl EstimatorDeclaration {
    /// The `key = value` entries (module documentation).
    pub fn entries(&self) -> Vec<(String, String)> {
        let mut entries = vec![
            ("name".to_string(), self.name.clone()),
            ("plant".to_string(), self.plant.clone()),
            ("method".to_string(), self.method.name().to_string()),
            ("robust".to_string(), self.robust.name().to_string()),
            ("tolerance".to_string(), number_text(self.tolerance)),
        ];
        let mut list =
            |group: &str,
             key: &str,
             items: &[Named],
             extra: &dyn Fn(usize) -> Option<(&'static str, String)>| {
                entries.push((group.to_string(), items.len().to_string()));
                for (i, item) in items.iter().enumerate() {
                    let at = format!("{key}.{}", i + 1);
                    entries.push((at.clone(), item.name.clone()));
                    if let Some(unit) = &item.unit {
                        entries.push((format!("{at}.unit"), unit.clone()));
                    }
                    if let Some((field, value)) = extra(i) {
                        entries.push((format!("{at}.{field}"), value));
                    }
                }
            };
        list("inputs", "input", &self.inputs, &|_| None);
        list("outputs", "output", &self.outputs, &|j| {
            self.noise.get(j).map(|v| ("noise", number_text(*v)))
        });
        list("states", "state", &self.states, &|_| None);
        list("free", "free", &self.free, &|i| {
            self.starts.get(i).map(|v| ("start", number_text(*v)))
        });
        let set: Vec<Named> = self
            .set
            .iter()
            .map(|(name, _)| Named {
                name: name.clone(),
                unit: None,
            })
            .collect();
        list("set", "set", &set, &|i| {
            self.set.get(i).map(|(_, v)| ("value", number_text(*v)))
        });
        entries
    }

    /// The first name or unit the configuration cannot carry (`#`, a line break, empty), as
    /// (what, text).
    pub fn uncarriable(&self) -> Option<(&'static str, String)> {
        let bad = |s: &str| s.trim().is_empty() || s.trim() != s || s.contains(['#', '\n', '\r']);
        let named = |what: &'static str, items: &[Named]| {
            items.iter().find_map(|n| {
                if bad(&n.name) {
                    Some((what, n.name.clone()))
                } else {
                    n.unit
                        .as_ref()
                        .filter(|u| bad(u))
                        .map(|u| (what, u.clone()))
                }
            })
        };
        if bad(&self.name) {
            return Some(("the model name", self.name.clone()));
        }
        named("an input", &self.inputs)
            .or_else(|| named("a measured variable", &self.outputs))
            .or_else(|| named("a state", &self.states))
            .or_else(|| named("a free parameter", &self.free))
            .or_else(|| {
                self.set
                    .iter()
                    .find(|(n, _)| bad(n))
                    .map(|(n, _)| ("a set parameter", n.clone()))
            })
    }

    /// The declaration whose entries `get` gives (`None` for a key that is absent).
    pub fn from_entries<'a>(
        get: impl Fn(&str) -> Option<&'a str>,
    ) -> Result<Self, DeclarationError> {
        let e = Entries::new(get);
        let list = |group: &str, key: &str| -> Result<Vec<Named>, DeclarationError> {
            let count = e.count(group, 0)?;
            if count > MAX_ITEMS {
                return Err(invalid(group, &count.to_string(), "more than 1000"));
            }
            (1..=count)
                .map(|i| {
                    let at = format!("{key}.{i}");
                    let unit = e.optional(&format!("{at}.unit")).map(str::to_string);
                    Ok(Named {
                        name: e.required(&at)?.to_string(),
                        unit,
                    })
                })
                .collect()
        };
        // The numbers `{key}.{i}.{field}` of the `count` items of a list.
        let numbers =
            |key: &str, count: usize, field: &str| -> Result<Vec<f64>, DeclarationError> {
                (1..=count)
                    .map(|i| e.number(&format!("{key}.{i}.{field}")))
                    .collect()
            };
        let method_name = e.required("method")?;
        let method = Method::named(method_name)
            .filter(|m| *m != Method::MaximumLikelihood)
            .ok_or_else(|| invalid("method", method_name, "not `ukf` or `ekf`"))?;
        let robust_name = e.required("robust")?;
        let robust = Robust::named(robust_name)
            .ok_or_else(|| invalid("robust", robust_name, "not `huber`, `tukey` or `none`"))?;
        let tolerance = e.number("tolerance")?;
        if tolerance <= 0.0 {
            return Err(invalid("tolerance", &tolerance.to_string(), "not > 0"));
        }
        let outputs = list("outputs", "output")?;
        if outputs.is_empty() {
            let reason = "an estimator measures at least one variable";
            return Err(invalid("outputs", "0", reason));
        }
        let noise = numbers("output", outputs.len(), "noise")?;
        if let Some(j) = noise.iter().position(|v| *v <= 0.0) {
            let key = format!("output.{}.noise", j + 1);
            return Err(invalid(
                &key,
                &noise[j].to_string(),
                "a variance must be > 0",
            ));
        }
        let free = list("free", "free")?;
        let starts = numbers("free", free.len(), "start")?;
        let set_names = list("set", "set")?;
        let set_values = numbers("set", set_names.len(), "value")?;
        let set = set_names
            .into_iter()
            .map(|n| n.name)
            .zip(set_values)
            .collect();
        Ok(Self {
            name: e.required("name")?.to_string(),
            plant: e.required("plant")?.to_string(),
            method,
            robust,
            tolerance,
            noise,
            starts,
            inputs: list("inputs", "input")?,
            outputs,
            states: list("states", "state")?,
            free,
            set,
        })
    }
}

/// The most names of one kind a declaration holds.
pub const MAX_ITEMS: usize = 1000;

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeMap;

    fn crane() -> EstimatorDeclaration {
        let named = |name: &str, unit: Option<&str>| Named {
            name: name.into(),
            unit: unit.map(str::to_string),
        };
        EstimatorDeclaration {
            name: "GantryCraneEstimator".into(),
            plant: "GantryCrane".into(),
            method: Method::Ukf,
            robust: Robust::Huber,
            tolerance: 1e-8,
            noise: vec![1e-6, 0.1 + 0.2],
            starts: vec![1.01262],
            inputs: vec![named("U", Some("N"))],
            outputs: vec![named("x", Some("m")), named("theta", Some("rad"))],
            states: vec![named("x", Some("m")), named("A[1,2]", None)],
            free: vec![named("M", Some("kg"))],
            set: vec![("x0".into(), 0.2)],
        }
    }

    #[test]
    fn a_declaration_survives_its_entries_exactly() {
        let declared = crane();
        let entries: BTreeMap<String, String> = declared.entries().into_iter().collect();
        let back = EstimatorDeclaration::from_entries(|k| entries.get(k).map(String::as_str));
        assert_eq!(back.unwrap(), declared);
        assert_eq!(entries["output.2.noise"], "0.30000000000000004");
        assert_eq!(entries["state.2"], "A[1,2]");
        assert_eq!(declared.uncarriable(), None);
    }

    #[test]
    fn a_bad_entry_is_named() {
        let mut entries: BTreeMap<String, String> = crane().entries().into_iter().collect();
        entries.insert("method".into(), "ml".into());
        let e = EstimatorDeclaration::from_entries(|k| entries.get(k).map(String::as_str));
        assert_eq!(
            e.unwrap_err().to_string(),
            "`method = ml`: not `ukf` or `ekf`"
        );
        entries.insert("method".into(), "ekf".into());
        entries.insert("output.1.noise".into(), "0".into());
        let e = EstimatorDeclaration::from_entries(|k| entries.get(k).map(String::as_str));
        assert_eq!(
            e.unwrap_err().to_string(),
            "`output.1.noise = 0`: a variance must be > 0"
        );
        entries.remove("free.1.start");
        let e = EstimatorDeclaration::from_entries(|k| entries.get(k).map(String::as_str));
        assert!(e.unwrap_err().to_string().contains("output.1.noise"));
        let mut named = crane();
        named.free[0].name = "a#b".into();
        assert_eq!(
            named.uncarriable(),
            Some(("a free parameter", "a#b".into()))
        );
    }
}
