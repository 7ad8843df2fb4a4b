//! `terminalsAndIcons/terminalsAndIcons.xml` (FMI 3.0.2 §2.4.9, schema
//! `fmi3TerminalsAndIcons.xsd`): the FMU's icon and the terminals that group its signals.
//!
//! The terminals are the natural buses of the variable table, per causality (inputs first):
//!
//! - a signal's *family* is its base name: the name up to the first `[` or `.` (`x_hat[2]` and
//!   `u.valid` belong to `x_hat` and `u`), and a Boolean `<b>_valid` belongs to `<b>` (an
//!   estimator's `y` and `y_valid` travel together);
//! - a family that is an array (`x_hat`, `A_hat`) or holds more than one variable (the
//!   scalars `x_hat[1]` … `x_hat[4]` of a controller; `y` with `y_valid`; a table's `u`,
//!   `u.valid`, `u.held`) is a terminal of its own, named after it;
//! - the other scalars of a causality form one terminal, `inputs` or `outputs` (the crane's
//!   `x`, `theta`, `v`, `omega`, `U_applied`; the generator's references `u_drive`,
//!   `u_field`).
//!
//! Member names follow the standard's suggested scheme: the variable name without its
//! `<terminal>.` prefix (`u.valid` is member `valid` of `u`), else the variable name. Every
//! member is a `signal` (§2.4.9.2.2: inputs and outputs). The matching rule is `plug` for a
//! terminal of one variable or of one naming-convention array (all of it must connect),
//! `bus` otherwise (a sensor's `y` may connect to an estimator's `y`, leaving `y_valid`).
//!
//! With the images (`terminalsAndIcons/icon.png`, and `icon.svg` beside it), the
//! `<GraphicalRepresentation>` places the icon over the default coordinate system (−100 … 100,
//! 0.1 mm per unit: 20 mm square; the icon files are fixed paths, §2.4.9.1.3, the element has
//! no file attribute), and each terminal's `<TerminalGraphicalRepresentation>` draws it beside
//! the icon, inputs down the left edge and outputs down the right ([`terminal_extent`]).

use super::{escape, Direction, Signal};
use std::fmt::Write;

/// One terminal: its name, its members (variable, member name) and a description.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Terminal {
    pub name: String,
    pub direction: Direction,
    pub matching_rule: &'static str,
    pub members: Vec<(String, String)>,
    pub description: String,
}

/// The family a signal belongs to (see the module documentation).
fn family(signal: &Signal, all: &[Signal]) -> String {
    let base = signal
        .name
        .split(['[', '.'])
        .next()
        .unwrap_or(&signal.name)
        .to_string();
    if signal.type_name == "Boolean" {
        if let Some(value) = base.strip_suffix("_valid") {
            let has_value = all.iter().any(|s| {
                s.direction == signal.direction
                    && s.type_name != "Boolean"
                    && s.name.split(['[', '.']).next() == Some(value)
            });
            if has_value {
                return value.to_string();
            }
        }
    }
    base
}

/// The terminals of a model's signals, inputs first, each in declaration order.
pub fn terminals(signals: &[Signal]) -> Vec<Terminal> {
    let mut terminals: Vec<Terminal> = Vec::new();
    for direction in [Direction::Input, Direction::Output] {
        let ours: Vec<&Signal> = signals
            .iter()
            .filter(|s| s.direction == direction)
            .collect();
        let mut families: Vec<(String, Vec<&Signal>)> = Vec::new();
        for signal in &ours {
            let name = family(signal, signals);
            match families.iter_mut().find(|(f, _)| *f == name) {
                Some((_, members)) => members.push(signal),
                None => families.push((name, vec![signal])),
            }
        }
        let mut loose: Vec<&Signal> = Vec::new();
        for (name, members) in families {
            if members.len() == 1 && members[0].dimensions.is_empty() {
                loose.push(members[0]);
                continue;
            }
            let one_array = members.len() == 1
                || members
                    .iter()
                    .all(|m| m.name.starts_with(&format!("{name}[")));
            let description = describe(&members, one_array);
            terminals.push(Terminal {
                members: members
                    .iter()
                    .map(|m| (m.name.clone(), member_name(&m.name, &name)))
                    .collect(),
                name,
                direction,
                matching_rule: if one_array { "plug" } else { "bus" },
                description,
            });
        }
        if !loose.is_empty() {
            let name = format!("{}s", direction.causality());
            terminals.push(Terminal {
                description: format!(
                    "The scalar {}s: {}",
                    direction.causality(),
                    loose
                        .iter()
                        .map(|m| m.name.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
                members: loose
                    .iter()
                    .map(|m| (m.name.clone(), member_name(&m.name, &name)))
                    .collect(),
                matching_rule: if loose.len() == 1 { "plug" } else { "bus" },
                name,
                direction,
            });
        }
    }
    unique_names(&mut terminals);
    terminals
}

/// A terminal's description: its variable's, for one; for the scalars of a naming-convention
/// array, the first and last and what their descriptions share up to a `:`
/// (`x_hat[1] … x_hat[4]: Estimated state`); else the variables and the first one's.
fn describe(members: &[&Signal], one_array: bool) -> String {
    let first = members[0].description.clone().unwrap_or_default();
    let (Some(head), Some(last)) = (members.first(), members.last()) else {
        return first;
    };
    if members.len() == 1 {
        return first;
    }
    if !one_array {
        let listed: Vec<&str> = members.iter().map(|m| m.name.as_str()).collect();
        return format!("{}: {first}", listed.join(", "));
    }
    let mut shared = first.as_str();
    for m in members {
        let d = m.description.as_deref().unwrap_or("");
        let common = shared
            .char_indices()
            .zip(d.chars())
            .find(|((_, a), b)| a != b)
            .map_or(shared.len().min(d.len()), |((i, _), _)| i);
        shared = &shared[..common];
    }
    let shared = shared
        .rsplit_once(':')
        .map_or("", |(before, _)| before.trim());
    let span = format!("{} … {}", head.name, last.name);
    if shared.is_empty() {
        span
    } else {
        format!("{span}: {shared}")
    }
}

/// The member name of `variable` in the terminal `terminal`: without the `<terminal>.`
/// prefix where it has one.
fn member_name(variable: &str, terminal: &str) -> String {
    variable
        .strip_prefix(terminal)
        .and_then(|rest| rest.strip_prefix('.'))
        .filter(|rest| !rest.is_empty())
        .unwrap_or(variable)
        .to_string()
}

/// Terminal names are unique among siblings (§2.4.9.2.1): a name given to an input and an
/// output terminal gets `_in` and `_out`; any clash left (within a causality) gets a number.
fn unique_names(terminals: &mut [Terminal]) {
    let named: Vec<(String, Direction)> = terminals
        .iter()
        .map(|t| (t.name.clone(), t.direction))
        .collect();
    for t in terminals.iter_mut() {
        if named.iter().any(|(n, d)| *n == t.name && *d != t.direction) {
            let suffix = match t.direction {
                Direction::Input => "_in",
                Direction::Output => "_out",
            };
            t.name.push_str(suffix);
        }
    }
    for k in 0..terminals.len() {
        let mut n = 2;
        let base = terminals[k].name.clone();
        while terminals[..k].iter().any(|t| t.name == terminals[k].name) {
            terminals[k].name = format!("{base}_{n}");
            n += 1;
        }
    }
}

/// The base names of the terminal icons (`terminalsAndIcons/<name>.png` and `.svg`): an input
/// terminal is drawn as a filled triangle on the icon's left edge, an output terminal as an
/// open one on its right edge, both pointing in the direction of the signal.
pub const TERMINAL_ICONS: [&str; 2] = ["input", "output"];

/// Where terminal `k` of `n` on one edge sits: `(x1, y1, x2, y2)` in the coordinate system
/// (−100 … 100): outside the icon, 20 units wide, the edge divided evenly from the top, each
/// at most 20 units high (rounded to hundredths).
pub fn terminal_extent(direction: Direction, k: usize, n: usize) -> (f64, f64, f64, f64) {
    let pitch = 200.0 / n.max(1) as f64;
    let centre = 100.0 - pitch * (k as f64 + 0.5);
    let half = (pitch / 2.0).min(10.0);
    let (x1, x2) = match direction {
        Direction::Input => (-120.0, -100.0),
        Direction::Output => (100.0, 120.0),
    };
    let hundredths = |v: f64| (v * 100.0).round() / 100.0;
    (x1, hundredths(centre - half), x2, hundredths(centre + half))
}

/// The `terminalsAndIcons.xml` text: with `graphics`, the icon's placement and each
/// terminal's ([`terminal_extent`], [`TERMINAL_ICONS`]); then the terminals.
pub fn terminals_and_icons(signals: &[Signal], graphics: bool) -> String {
    let mut x = String::new();
    let _ = writeln!(x, r#"<?xml version="1.0" encoding="UTF-8"?>"#);
    let _ = writeln!(x, r#"<fmiTerminalsAndIcons fmiVersion="3.0">"#);
    if graphics {
        let _ = writeln!(x, "  <GraphicalRepresentation>");
        let _ = writeln!(
            x,
            r#"    <CoordinateSystem x1="-100" y1="-100" x2="100" y2="100" suggestedScalingFactorTo_mm="0.1"/>"#
        );
        let _ = writeln!(x, r#"    <Icon x1="-100" y1="-100" x2="100" y2="100"/>"#);
        let _ = writeln!(x, "  </GraphicalRepresentation>");
    }
    let terminals = terminals(signals);
    if !terminals.is_empty() {
        let _ = writeln!(x, "  <Terminals>");
        for t in &terminals {
            let _ = writeln!(
                x,
                r#"    <Terminal name="{}" matchingRule="{}" description="{}">"#,
                escape(&t.name),
                t.matching_rule,
                escape(&t.description)
            );
            for (variable, member) in &t.members {
                let _ = writeln!(
                    x,
                    r#"      <TerminalMemberVariable variableName="{}" memberName="{}" variableKind="signal"/>"#,
                    escape(variable),
                    escape(member)
                );
            }
            if graphics {
                let side: Vec<&Terminal> = terminals
                    .iter()
                    .filter(|o| o.direction == t.direction)
                    .collect();
                let k = side.iter().position(|o| o.name == t.name).unwrap_or(0);
                let (x1, y1, x2, y2) = terminal_extent(t.direction, k, side.len());
                let _ = writeln!(
                    x,
                    r#"      <TerminalGraphicalRepresentation x1="{x1}" y1="{y1}" x2="{x2}" y2="{y2}" iconBaseName="{}"/>"#,
                    t.direction.causality()
                );
            }
            let _ = writeln!(x, "    </Terminal>");
        }
        let _ = writeln!(x, "  </Terminals>");
    }
    let _ = writeln!(x, "</fmiTerminalsAndIcons>");
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    fn signal(name: &str, direction: Direction, type_name: &str, dims: &[usize]) -> Signal {
        Signal {
            name: name.into(),
            direction,
            type_name: type_name.into(),
            dimensions: dims.to_vec(),
            description: Some(format!("about {name}")),
        }
    }

    fn summary(ts: &[Terminal]) -> Vec<String> {
        ts.iter()
            .map(|t| {
                let members: Vec<String> = t
                    .members
                    .iter()
                    .map(|(v, m)| {
                        if v == m {
                            v.clone()
                        } else {
                            format!("{v}={m}")
                        }
                    })
                    .collect();
                format!("{} {} [{}]", t.name, t.matching_rule, members.join(" "))
            })
            .collect()
    }

    #[test]
    fn the_crane_has_its_input_and_its_outputs_as_two_terminals() {
        use Direction::*;
        let crane: Vec<Signal> = [("U", Input), ("x", Output), ("theta", Output)]
            .iter()
            .map(|(n, d)| signal(n, *d, "Float64", &[]))
            .collect();
        assert_eq!(
            summary(&terminals(&crane)),
            ["inputs plug [U]", "outputs bus [x theta]"]
        );
    }

    #[test]
    fn an_estimator_groups_its_vectors_and_validity_flags() {
        use Direction::*;
        let kf = vec![
            signal("u", Input, "Float64", &[1]),
            signal("y", Input, "Float64", &[2]),
            signal("x_hat", Output, "Float64", &[4]),
            signal("y_hat", Output, "Float64", &[2]),
            signal("A_hat", Output, "Float64", &[4, 4]),
            signal("excitation", Output, "Float64", &[]),
            signal("adapting", Output, "Boolean", &[]),
            signal("y_valid", Input, "Boolean", &[2]),
        ];
        assert_eq!(
            summary(&terminals(&kf)),
            [
                "u plug [u]",
                "y bus [y y_valid]",
                "x_hat plug [x_hat]",
                "y_hat plug [y_hat]",
                "A_hat plug [A_hat]",
                "outputs bus [excitation adapting]",
            ]
        );
        let xml = terminals_and_icons(&kf, false);
        assert!(!xml.contains("GraphicalRepresentation"));
        assert!(xml.contains(
            r#"<TerminalMemberVariable variableName="y_valid" memberName="y_valid" variableKind="signal"/>"#
        ));
        assert!(xml
            .contains(r#"<Terminal name="x_hat" matchingRule="plug" description="about x_hat">"#));
    }

    #[test]
    fn structured_scalars_and_table_columns_form_families() {
        use Direction::*;
        let controller: Vec<Signal> = (1..=2)
            .map(|i| signal(&format!("x_hat[{i}]"), Input, "Float64", &[]))
            .chain([signal("u", Output, "Float64", &[1])])
            .collect();
        assert_eq!(
            summary(&terminals(&controller)),
            ["x_hat plug [x_hat[1] x_hat[2]]", "u plug [u]"]
        );
        let mut described = controller.clone();
        described[0].description = Some("Estimated state: cart position x".into());
        described[1].description = Some("Estimated state: load angle θ".into());
        assert_eq!(
            terminals(&described)[0].description,
            "x_hat[1] … x_hat[2]: Estimated state"
        );
        assert_eq!(terminals(&controller)[0].description, "x_hat[1] … x_hat[2]");
        let table = vec![
            signal("u", Output, "Float64", &[]),
            signal("u.valid", Output, "Boolean", &[]),
            signal("u.held", Output, "Float64", &[]),
            signal("time_of_day", Output, "Float64", &[]),
        ];
        assert_eq!(
            summary(&terminals(&table)),
            [
                "u bus [u u.valid=valid u.held=held]",
                "outputs plug [time_of_day]"
            ]
        );
    }

    #[test]
    fn names_shared_by_an_input_and_an_output_terminal_are_made_unique() {
        let vector = |name, direction| signal(name, direction, "Float64", &[2]);
        let mut s = vec![
            vector("u", Direction::Input),
            vector("u", Direction::Output),
        ];
        s.push(vector("inputs", Direction::Input));
        s.push(signal("w", Direction::Input, "Float64", &[]));
        let names: Vec<String> = terminals(&s).into_iter().map(|t| t.name).collect();
        assert_eq!(names, ["u_in", "inputs", "inputs_2", "u_out"]);
        let xml = terminals_and_icons(&s, true);
        assert!(xml.contains(r#"<Icon x1="-100" y1="-100" x2="100" y2="100"/>"#));
        // Three input terminals down the left edge, one output in the middle of the right.
        assert!(xml.contains(
            r#"<TerminalGraphicalRepresentation x1="-120" y1="56.67" x2="-100" y2="76.67" iconBaseName="input"/>"#
        ), "{xml}");
        assert!(xml.contains(
            r#"<TerminalGraphicalRepresentation x1="100" y1="-10" x2="120" y2="10" iconBaseName="output"/>"#
        ));
        assert_eq!(
            terminal_extent(Direction::Input, 0, 20),
            (-120.0, 90.0, -100.0, 100.0)
        );
    }
}
