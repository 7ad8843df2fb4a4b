//! What an FMI 3.0 archive carries beside its model description and binaries, derived from
//! that description (which the FMU library generates from its variable table, so a new FMU
//! gets them with no list to edit):
//!
//! - [`terminals`]: `terminalsAndIcons/terminalsAndIcons.xml` (FMI 3.0.2 §2.4.9), the
//!   terminals that group the FMU's natural signal buses, and its icon;
//! - [`reference`]: the reference results of the layered standard `fmi-ls-ref`
//!   (`extra/org.fmi-standard.fmi-ls-ref/`), the FMU's cross-check scenario written with the
//!   FMI 3.0 variables, as the Reference FMUs carry theirs.
//!
//! Both read the description's variables through [`signals`].

pub mod reference;
pub mod terminals;

use spurio_master::xml::{attribute, tags, Tag};

/// Why the extras of an archive could not be written.
#[derive(Debug, thiserror::Error)]
pub enum ExtrasError {
    #[error("{model}: the FMI 3.0 model description: {reason}")]
    Description { model: String, reason: String },
    #[error("{model}: {file}: {reason}")]
    CrossCheck {
        model: String,
        file: String,
        reason: String,
    },
}

/// The causality of a signal: what a terminal groups.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    Input,
    Output,
}

impl Direction {
    /// The `causality` attribute value.
    pub fn causality(self) -> &'static str {
        match self {
            Direction::Input => "input",
            Direction::Output => "output",
        }
    }
}

/// An input or output of an FMI 3.0 model description.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Signal {
    pub name: String,
    /// The `<Dimension start>` of an array, in order (empty for a scalar).
    pub dimensions: Vec<usize>,
    pub direction: Direction,
    /// The element type (`Float64`, `Int32`, `Boolean`, …).
    pub type_name: String,
    pub description: Option<String>,
}

impl Signal {
    /// The names of its elements as the FMI 2.0 twin's structured scalars name them (and the
    /// cross-check files' columns): `x[i,j]`, 1-based, row-major; the name itself for a scalar.
    pub fn element_names(&self) -> Vec<String> {
        if self.dimensions.is_empty() {
            return vec![self.name.clone()];
        }
        let mut indices: Vec<Vec<usize>> = vec![Vec::new()];
        for &d in &self.dimensions {
            indices = indices
                .into_iter()
                .flat_map(|prefix| {
                    (1..=d).map(move |i| {
                        let mut next = prefix.clone();
                        next.push(i);
                        next
                    })
                })
                .collect();
        }
        indices
            .iter()
            .map(|index| {
                let index: Vec<String> = index.iter().map(|i| i.to_string()).collect();
                format!("{}[{}]", self.name, index.join(","))
            })
            .collect()
    }
}

/// The model name and the inputs and outputs (in declaration order) of an FMI 3.0
/// description.
pub fn signals(description: &str) -> Result<(String, Vec<Signal>), String> {
    let mut model_name = None;
    let mut signals = Vec::new();
    // Depth below `<ModelVariables>` (None: outside it), and whether the variable open at
    // depth 1 is a signal (its `<Dimension>` children then belong to the last signal).
    let mut depth: Option<usize> = None;
    let mut open_is_signal = false;
    for tag in tags(description) {
        match tag? {
            Tag::Start { element, empty } => {
                let name = element.name().as_ref().to_string();
                match depth {
                    None if name == "fmiModelDescription" => {
                        model_name = attribute(&element, "modelName");
                    }
                    None if name == "ModelVariables" && !empty => depth = Some(0),
                    None => {}
                    Some(0) => {
                        let direction = match attribute(&element, "causality").as_deref() {
                            Some("input") => Some(Direction::Input),
                            Some("output") => Some(Direction::Output),
                            _ => None,
                        };
                        open_is_signal = direction.is_some();
                        if let Some(direction) = direction {
                            let variable = attribute(&element, "name")
                                .ok_or_else(|| format!("a <{name}> has no name"))?;
                            signals.push(Signal {
                                name: variable,
                                direction,
                                type_name: name.clone(),
                                dimensions: Vec::new(),
                                description: attribute(&element, "description"),
                            });
                        }
                        if !empty {
                            depth = Some(1);
                        }
                    }
                    Some(d) => {
                        if d == 1 && name == "Dimension" && open_is_signal {
                            let signal = signals
                                .last_mut()
                                .ok_or("a <Dimension> before its variable")?;
                            let size = attribute(&element, "start")
                                .and_then(|s| s.trim().parse::<usize>().ok())
                                .ok_or_else(|| {
                                    format!(
                                        "`{}`: a <Dimension> without a start (a structural parameter), which the packager does not resolve",
                                        signal.name
                                    )
                                })?;
                            signal.dimensions.push(size);
                        }
                        if !empty {
                            depth = Some(d + 1);
                        }
                    }
                }
            }
            Tag::End(_) => {
                depth = match depth {
                    Some(0) | None => None,
                    Some(d) => Some(d - 1),
                };
            }
        }
    }
    let model_name = model_name.ok_or("no <fmiModelDescription modelName>")?;
    Ok((model_name, signals))
}

/// XML text with `&`, `<`, `>` and `"` escaped.
pub fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

#[cfg(test)]
mod tests {
    use super::*;

    const DESCRIPTION: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" modelName="Demo &amp; co" instantiationToken="x">
  <ModelVariables>
    <Float64 name="time" valueReference="0" causality="independent" variability="continuous"/>
    <Float64 name="A" valueReference="1" causality="parameter" variability="fixed" start="1 2 3 4">
      <Dimension start="2"/>
      <Dimension start="2"/>
    </Float64>
    <Float64 name="y" valueReference="2" causality="input" description="Measured y" start="0 0">
      <Dimension start="2"/>
    </Float64>
    <Boolean name="y_valid" valueReference="3" causality="input" start="true true">
      <Dimension start="2"/>
    </Boolean>
    <Float64 name="L" valueReference="4" causality="output">
      <Dimension start="1"/>
      <Dimension start="3"/>
    </Float64>
    <Int32 name="count" valueReference="5" causality="output"/>
  </ModelVariables>
  <ModelStructure>
    <Output valueReference="4"/>
  </ModelStructure>
</fmiModelDescription>"#;

    #[test]
    fn signals_are_the_inputs_and_outputs_with_their_dimensions() {
        let (model, signals) = signals(DESCRIPTION).unwrap();
        assert_eq!(model, "Demo & co");
        let names: Vec<&str> = signals.iter().map(|s| s.name.as_str()).collect();
        assert_eq!(names, ["y", "y_valid", "L", "count"]);
        assert_eq!(signals[0].direction, Direction::Input);
        assert_eq!(signals[0].description.as_deref(), Some("Measured y"));
        assert_eq!(signals[1].type_name, "Boolean");
        assert_eq!(signals[2].dimensions, [1, 3]);
        assert_eq!(signals[2].element_names(), ["L[1,1]", "L[1,2]", "L[1,3]"]);
        assert_eq!(signals[3].element_names(), ["count"]);
        assert_eq!(signals[3].direction, Direction::Output);
    }

    #[test]
    fn a_structural_dimension_and_ill_formed_text_are_named() {
        let by_reference = DESCRIPTION.replace(
            r#"<Dimension start="1"/>"#,
            r#"<Dimension valueReference="1"/>"#,
        );
        let err = signals(&by_reference).unwrap_err();
        assert!(
            err.contains("`L`") && err.contains("structural parameter"),
            "{err}"
        );
        let err = signals("<fmiModelDescription><ModelVariables>").unwrap_err();
        assert!(err.contains("ill-formed XML"), "{err}");
    }
}
