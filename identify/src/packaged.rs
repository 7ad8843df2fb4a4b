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
use crate::plant::PlantSpec;
pub use spurio_table::declaration::DeclarationError;
use spurio_table::declaration::{invalid, Entries};

/// A variable of the plant by name, with its unit.
#[derive(Debug, Clone, PartialEq)]
pub struct Named {
    pub name: String,
    pub unit: Option<String>,
}

/// A measured variable y_j of the plant, with the variance R_jj of its noise.
#[derive(Debug, Clone, PartialEq)]
pub struct Measured {
    pub variable: Named,
    pub noise: f64,
}

/// A free parameter θ_i of the plant, with its start value θ₀,i.
#[derive(Debug, Clone, PartialEq)]
pub struct Free {
    pub parameter: Named,
    pub start: f64,
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
    pub outputs: Vec<Measured>,
    pub states: Vec<Named>,
    pub free: Vec<Free>,
}

/// Writes `v` so that parsing gives it back exactly (Rust's shortest round trip).
fn number_text(v: f64) -> String {
    format!("{v:?}")
}

/// Whether a name or unit cannot be carried by the configuration (`#`, a line break,
/// surrounding spaces, empty).
fn uncarriable_text(s: &str) -> bool {
    s.trim().is_empty() || s.trim() != s || s.contains(['#', '\n', '\r'])
}

/// The first of `items` whose name or unit cannot be carried, as (`what`, text).
fn first_uncarriable<'a>(
    what: &'static str,
    items: impl IntoIterator<Item = &'a Named>,
) -> Option<(&'static str, String)> {
    items.into_iter().find_map(|n| {
        let unit = n.unit.as_ref().filter(|u| uncarriable_text(u));
        if uncarriable_text(&n.name) {
            Some((what, n.name.clone()))
        } else {
            unit.map(|u| (what, u.clone()))
        }
    })
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
        // Each list: its items with their numbers (`noise`, `start`, `value`), if any.
        type Item<'a> = (&'a Named, Option<(&'static str, f64)>);
        fn plain(items: &[Named]) -> Vec<Item<'_>> {
            items.iter().map(|n| (n, None)).collect()
        }
        let outputs: Vec<Item> = (self.outputs.iter())
            .map(|m| (&m.variable, Some(("noise", m.noise))))
            .collect();
        let free: Vec<Item> = (self.free.iter())
            .map(|f| (&f.parameter, Some(("start", f.start))))
            .collect();
        let set_names: Vec<Named> = (self.set.iter())
            .map(|(name, _)| Named {
                name: name.clone(),
                unit: None,
            })
            .collect();
        let set: Vec<Item> = (set_names.iter().zip(&self.set))
            .map(|(n, (_, v))| (n, Some(("value", *v))))
            .collect();
        let lists = [
            ("inputs", "input", plain(&self.inputs)),
            ("outputs", "output", outputs),
            ("states", "state", plain(&self.states)),
            ("free", "free", free),
            ("set", "set", set),
        ];
        // Each list's count under `group`, then each item's name, unit and number.
        for (group, key, items) in lists {
            entries.push((group.to_string(), items.len().to_string()));
            for (i, (item, number)) in items.into_iter().enumerate() {
                let at = format!("{key}.{}", i + 1);
                entries.push((at.clone(), item.name.clone()));
                if let Some(unit) = &item.unit {
                    entries.push((format!("{at}.unit"), unit.clone()));
                }
                if let Some((field, value)) = number {
                    entries.push((format!("{at}.{field}"), number_text(value)));
                }
            }
        }
        entries
    }

    /// The first name or unit the configuration cannot carry (`#`, a line break, empty), as
    /// (what, text).
    pub fn uncarriable(&self) -> Option<(&'static str, String)> {
        if uncarriable_text(&self.name) {
            return Some(("the model name", self.name.clone()));
        }
        first_uncarriable("an input", &self.inputs)
            .or_else(|| {
                first_uncarriable(
                    "a measured variable",
                    self.outputs.iter().map(|m| &m.variable),
                )
            })
            .or_else(|| first_uncarriable("a state", &self.states))
            .or_else(|| {
                first_uncarriable("a free parameter", self.free.iter().map(|f| &f.parameter))
            })
            .or_else(|| {
                self.set
                    .iter()
                    .find(|(n, _)| uncarriable_text(n))
                    .map(|(n, _)| ("a set parameter", n.clone()))
            })
    }

    /// R's diagonal: the measured variables' noise variances, in the order of y.
    pub fn noise(&self) -> Vec<f64> {
        self.outputs.iter().map(|m| m.noise).collect()
    }

    /// θ₀: the free parameters' starts, in the order of θ.
    pub fn starts(&self) -> Vec<f64> {
        self.free.iter().map(|f| f.start).collect()
    }

    /// What the filter takes from the plant, by name: the free parameters, the inputs and
    /// the measured variables.
    pub fn plant_spec(&self) -> PlantSpec {
        let names =
            |items: &mut dyn Iterator<Item = &Named>| items.map(|n| n.name.clone()).collect();
        PlantSpec {
            free: names(&mut self.free.iter().map(|f| &f.parameter)),
            inputs: names(&mut self.inputs.iter()),
            outputs: names(&mut self.outputs.iter().map(|m| &m.variable)),
        }
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
        let outputs = (outputs.into_iter().zip(noise))
            .map(|(variable, noise)| Measured { variable, noise })
            .collect();
        let free = list("free", "free")?;
        let starts = numbers("free", free.len(), "start")?;
        let free = (free.into_iter().zip(starts))
            .map(|(parameter, start)| Free { parameter, start })
            .collect();
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
            inputs: vec![named("U", Some("N"))],
            outputs: vec![
                Measured {
                    variable: named("x", Some("m")),
                    noise: 1e-6,
                },
                Measured {
                    variable: named("theta", Some("rad")),
                    noise: 0.1 + 0.2,
                },
            ],
            states: vec![named("x", Some("m")), named("A[1,2]", None)],
            free: vec![Free {
                parameter: named("M", Some("kg")),
                start: 1.01262,
            }],
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
        assert_eq!(entries["free.1.start"], "1.01262");
        assert_eq!(declared.noise(), [1e-6, 0.30000000000000004]);
        assert_eq!(declared.starts(), [1.01262]);
        let spec = declared.plant_spec();
        assert_eq!(
            (spec.free, spec.inputs, spec.outputs),
            (
                vec!["M".to_string()],
                vec!["U".to_string()],
                vec!["x".to_string(), "theta".to_string()]
            )
        );
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
        named.free[0].parameter.name = "a#b".into();
        assert_eq!(
            named.uncarriable(),
            Some(("a free parameter", "a#b".into()))
        );
    }
}
