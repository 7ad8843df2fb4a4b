//! The variable table of an FMU and the values an instance holds for it.
//!
//! A model declares its interface as a list of [`Variable`]s; the value reference of a
//! variable is its position in the list, so dispatch is an index, not a search. The same table
//! produces `modelDescription.xml` ([`crate::description`]) and drives the checks of every
//! `fmi2Get*` / `fmi2Set*` call ([`crate::instance`]).

use crate::bytes::{ByteReader, ByteWriter, StateFormatError};
use std::fmt;

/// `causality` of a variable.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Causality {
    Parameter,
    CalculatedParameter,
    Input,
    Output,
    Local,
}

/// `variability` of a variable.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Variability {
    Constant,
    Fixed,
    Tunable,
    Discrete,
    Continuous,
}

/// `initial` of a variable.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Initial {
    Exact,
    Approx,
    Calculated,
}

/// The FMI type of a variable.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VariableType {
    Real,
    Integer,
    Boolean,
    String,
}

impl fmt::Display for VariableType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            VariableType::Real => "Real",
            VariableType::Integer => "Integer",
            VariableType::Boolean => "Boolean",
            VariableType::String => "String",
        })
    }
}

impl Causality {
    /// The attribute value in `modelDescription.xml`.
    pub fn as_str(self) -> &'static str {
        match self {
            Causality::Parameter => "parameter",
            Causality::CalculatedParameter => "calculatedParameter",
            Causality::Input => "input",
            Causality::Output => "output",
            Causality::Local => "local",
        }
    }
}

impl Variability {
    /// The attribute value in `modelDescription.xml`.
    pub fn as_str(self) -> &'static str {
        match self {
            Variability::Constant => "constant",
            Variability::Fixed => "fixed",
            Variability::Tunable => "tunable",
            Variability::Discrete => "discrete",
            Variability::Continuous => "continuous",
        }
    }
}

impl Initial {
    /// The attribute value in `modelDescription.xml`.
    pub fn as_str(self) -> &'static str {
        match self {
            Initial::Exact => "exact",
            Initial::Approx => "approx",
            Initial::Calculated => "calculated",
        }
    }
}

/// A value of one variable.
#[derive(Debug, PartialEq)]
pub enum Value {
    Real(f64),
    Integer(i32),
    Boolean(bool),
    String(String),
}

/// Written out so that `clone_from` reuses a String's buffer (see [`Values`]).
impl Clone for Value {
    fn clone(&self) -> Self {
        match self {
            Self::Real(v) => Self::Real(*v),
            Self::Integer(v) => Self::Integer(*v),
            Self::Boolean(v) => Self::Boolean(*v),
            Self::String(v) => Self::String(v.clone()),
        }
    }
    fn clone_from(&mut self, source: &Self) {
        match (self, source) {
            (Self::String(to), Self::String(from)) => to.clone_from(from),
            (to, from) => *to = from.clone(),
        }
    }
}

impl Value {
    /// The type of this value.
    pub fn variable_type(&self) -> VariableType {
        match self {
            Value::Real(_) => VariableType::Real,
            Value::Integer(_) => VariableType::Integer,
            Value::Boolean(_) => VariableType::Boolean,
            Value::String(_) => VariableType::String,
        }
    }
}

/// One scalar variable of the interface.
#[derive(Debug, Clone, PartialEq)]
pub struct Variable {
    /// Name (structured naming: `x`, `A[1,2]`, `x_hat[3]`).
    pub name: String,
    /// Human-readable description.
    pub description: String,
    pub causality: Causality,
    pub variability: Variability,
    /// `None` for inputs (FMI 2.0 forbids the attribute there).
    pub initial: Option<Initial>,
    /// The type and, for variables that have one, the start value. Outputs with
    /// `initial="calculated"` carry a placeholder value that is not written to the XML.
    pub start: Value,
    /// Unit of a Real variable (declared in `UnitDefinitions`).
    pub unit: Option<String>,
    /// Lower bound, checked on `fmi2Set*`.
    pub min: Option<f64>,
    /// Upper bound, checked on `fmi2Set*`.
    pub max: Option<f64>,
    /// For outputs: the indices of the inputs this output depends on directly (direct
    /// feedthrough). Empty: the output depends on no input within a step. For a Model
    /// Exchange FMU, outputs and derivatives list the states and inputs they depend on.
    pub dependencies: Vec<usize>,
    /// A continuous state of the Model Exchange interface ([`Variable::state`]).
    pub state: bool,
    /// For a state derivative `der(x)`: the index of its state `x`
    /// ([`Variable::derivative_of`]).
    pub derivative_of: Option<usize>,
    /// The nominal value of a Real (`nominal="…"`; a state's for the solver's error control).
    pub nominal: Option<f64>,
    /// An event indicator of the Model Exchange interface ([`Variable::event_indicator`]).
    pub event_indicator: bool,
}

impl Variable {
    fn new(name: &str, causality: Causality, variability: Variability, start: Value) -> Self {
        let initial = match causality {
            Causality::Input => None,
            Causality::Output | Causality::CalculatedParameter => Some(Initial::Calculated),
            _ => Some(Initial::Exact),
        };
        Self {
            name: name.to_string(),
            description: String::new(),
            causality,
            variability,
            initial,
            start,
            unit: None,
            min: None,
            max: None,
            dependencies: Vec::new(),
            state: false,
            derivative_of: None,
            nominal: None,
            event_indicator: false,
        }
    }

    /// A Real parameter (`fixed`, `initial="exact"`).
    pub fn parameter(name: &str, start: f64) -> Self {
        Self::new(
            name,
            Causality::Parameter,
            Variability::Fixed,
            Value::Real(start),
        )
    }
    /// An Integer parameter (`fixed`).
    pub fn integer_parameter(name: &str, start: i32) -> Self {
        Self::new(
            name,
            Causality::Parameter,
            Variability::Fixed,
            Value::Integer(start),
        )
    }
    /// A Boolean parameter (`fixed`).
    pub fn boolean_parameter(name: &str, start: bool) -> Self {
        Self::new(
            name,
            Causality::Parameter,
            Variability::Fixed,
            Value::Boolean(start),
        )
    }
    /// A String parameter (`fixed`).
    pub fn string_parameter(name: &str, start: &str) -> Self {
        Self::new(
            name,
            Causality::Parameter,
            Variability::Fixed,
            Value::String(start.to_string()),
        )
    }
    /// A continuous Real input.
    pub fn input(name: &str, start: f64) -> Self {
        Self::new(
            name,
            Causality::Input,
            Variability::Continuous,
            Value::Real(start),
        )
    }
    /// A continuous Real output, calculated by the model.
    pub fn output(name: &str) -> Self {
        Self::new(
            name,
            Causality::Output,
            Variability::Continuous,
            Value::Real(0.0),
        )
    }
    /// A discrete Real output (changes only at communication points).
    pub fn discrete_output(name: &str) -> Self {
        Self::new(
            name,
            Causality::Output,
            Variability::Discrete,
            Value::Real(0.0),
        )
    }
    /// A discrete Boolean output.
    pub fn boolean_output(name: &str) -> Self {
        Self::new(
            name,
            Causality::Output,
            Variability::Discrete,
            Value::Boolean(false),
        )
    }
    /// Sets the unit.
    pub fn unit(mut self, unit: &str) -> Self {
        self.unit = Some(unit.to_string());
        self
    }
    /// Sets the description.
    pub fn describe(mut self, description: &str) -> Self {
        self.description = description.to_string();
        self
    }
    /// Sets the lower bound.
    pub fn min(mut self, min: f64) -> Self {
        self.min = Some(min);
        self
    }
    /// Sets the upper bound.
    pub fn max(mut self, max: f64) -> Self {
        self.max = Some(max);
        self
    }
    /// Makes a parameter tunable (settable between steps).
    pub fn tunable(mut self) -> Self {
        self.variability = Variability::Tunable;
        self
    }
    /// Declares direct feedthrough from the inputs at these indices.
    pub fn depends_on(mut self, inputs: &[usize]) -> Self {
        self.dependencies = inputs.to_vec();
        self
    }
    /// Marks a continuous Real (an output or a local) as a continuous state of the Model
    /// Exchange interface; its derivative is declared by [`Variable::derivative_of`]. States
    /// are ordered by value reference.
    pub fn state(mut self) -> Self {
        self.state = true;
        self
    }
    /// A local Real `der(x)`: the time derivative of the state at index `state`
    /// (`derivative="…"` in the model description), calculated by the model.
    pub fn derivative(name: &str, state: usize) -> Self {
        Self::calculated_local(name).derivative_of(state)
    }
    /// A continuous Real local the model calculates (`initial="calculated"`).
    fn calculated_local(name: &str) -> Self {
        Self {
            initial: Some(Initial::Calculated),
            ..Self::new(
                name,
                Causality::Local,
                Variability::Continuous,
                Value::Real(0.0),
            )
        }
    }
    /// Declares this Real the time derivative of the state at index `state`.
    pub fn derivative_of(mut self, state: usize) -> Self {
        self.derivative_of = Some(state);
        self
    }
    /// A local Real that is an event indicator of the Model Exchange interface: the layer
    /// writes into it what [`crate::ModelExchange::event_indicators`] returns (in table order),
    /// so it can be read like any variable; a sign change is a state event. FMI 3.0 lists it
    /// as `<EventIndicator>`, FMI 2.0 counts it in `numberOfEventIndicators`.
    pub fn event_indicator(name: &str) -> Self {
        Self {
            event_indicator: true,
            ..Self::calculated_local(name)
        }
    }
    /// Sets the nominal value (`nominal="…"`, a state's scale for the solver; default 1).
    pub fn nominal(mut self, nominal: f64) -> Self {
        self.nominal = Some(nominal);
        self
    }
    /// The FMI type of the variable.
    pub fn variable_type(&self) -> VariableType {
        self.start.variable_type()
    }
    /// Whether the variable's start value is written to `modelDescription.xml`.
    pub fn has_start(&self) -> bool {
        self.causality == Causality::Input
            || matches!(self.initial, Some(Initial::Exact) | Some(Initial::Approx))
    }
}

/// One-line rows for the variable tables of physical models: name, (start,) unit and
/// description in one call, so a `declare_variables!` table reads as a table. Further
/// attributes chain on as usual (`parameter("m", 1.0, "kg", "Load mass").min(0.0)`).
pub mod rows {
    use super::Variable;

    /// A Real parameter ([`Variable::parameter`]) with its unit and description.
    pub fn parameter(name: &str, start: f64, unit: &str, description: &str) -> Variable {
        Variable::parameter(name, start)
            .unit(unit)
            .describe(description)
    }
    /// A continuous Real input ([`Variable::input`]) with its unit and description.
    pub fn input(name: &str, start: f64, unit: &str, description: &str) -> Variable {
        Variable::input(name, start)
            .unit(unit)
            .describe(description)
    }
    /// A continuous Real output ([`Variable::output`]) with its unit and description.
    pub fn output(name: &str, unit: &str, description: &str) -> Variable {
        Variable::output(name).unit(unit).describe(description)
    }
    /// A state derivative `der(x)` ([`Variable::derivative`]) of the state at index `state`,
    /// with its unit and description.
    pub fn derivative(name: &str, state: usize, unit: &str, description: &str) -> Variable {
        Variable::derivative(name, state)
            .unit(unit)
            .describe(description)
    }
    /// An event indicator ([`Variable::event_indicator`]) with its unit and description.
    pub fn event_indicator(name: &str, unit: &str, description: &str) -> Variable {
        Variable::event_indicator(name)
            .unit(unit)
            .describe(description)
    }
    /// A discrete Real output ([`Variable::discrete_output`]) with its unit and description.
    pub fn discrete_output(name: &str, unit: &str, description: &str) -> Variable {
        Variable::discrete_output(name)
            .unit(unit)
            .describe(description)
    }
}

/// Builds a variable table, handing back each variable's index (= value reference).
#[derive(Debug, Clone, Default)]
pub struct VariableTable {
    variables: Vec<Variable>,
}

impl VariableTable {
    /// An empty table.
    pub fn new() -> Self {
        Self::default()
    }
    /// Adds a variable; returns its index, which is also its value reference.
    pub fn add(&mut self, variable: Variable) -> usize {
        self.variables.push(variable);
        self.variables.len() - 1
    }
    /// The variables, in value-reference order.
    pub fn into_variables(self) -> Vec<Variable> {
        self.variables
    }
    /// The variables added so far.
    pub fn variables(&self) -> &[Variable] {
        &self.variables
    }
}

/// The current values of an instance, one per variable, indexed like the table.
#[derive(Debug, PartialEq)]
pub struct Values {
    values: Vec<Value>,
}

/// Written out because the derived `clone_from` clones afresh: this one reuses the buffer
/// (and each String's), so the per-call snapshot of the values allocates nothing after
/// the first.
impl Clone for Values {
    fn clone(&self) -> Self {
        Self {
            values: self.values.clone(),
        }
    }
    fn clone_from(&mut self, source: &Self) {
        self.values.clone_from(&source.values);
    }
}

impl Values {
    /// The start values of `variables`.
    pub fn from_start(variables: &[Variable]) -> Self {
        Self {
            values: variables.iter().map(|v| v.start.clone()).collect(),
        }
    }
    /// All values.
    pub fn all(&self) -> &[Value] {
        &self.values
    }
    /// Replaces the value at `index` (the type is checked by the caller).
    pub fn set(&mut self, index: usize, value: Value) {
        if let Some(slot) = self.values.get_mut(index) {
            *slot = value;
        }
    }
    /// The Real at `index`; NaN if the index is not a Real (a table bug caught by tests).
    pub fn real(&self, index: usize) -> f64 {
        match self.values.get(index) {
            Some(Value::Real(v)) => *v,
            _ => f64::NAN,
        }
    }
    /// Sets the Real at `index`.
    pub fn set_real(&mut self, index: usize, value: f64) {
        if let Some(Value::Real(slot)) = self.values.get_mut(index) {
            *slot = value;
        }
    }
    /// The Integer at `index` (0 if it is not an Integer).
    pub fn integer(&self, index: usize) -> i32 {
        match self.values.get(index) {
            Some(Value::Integer(v)) => *v,
            _ => 0,
        }
    }
    /// Sets the Integer at `index`.
    pub fn set_integer(&mut self, index: usize, value: i32) {
        if let Some(Value::Integer(slot)) = self.values.get_mut(index) {
            *slot = value;
        }
    }
    /// The Boolean at `index` (false if it is not a Boolean).
    pub fn boolean(&self, index: usize) -> bool {
        matches!(self.values.get(index), Some(Value::Boolean(true)))
    }
    /// Sets the Boolean at `index`.
    pub fn set_boolean(&mut self, index: usize, value: bool) {
        if let Some(Value::Boolean(slot)) = self.values.get_mut(index) {
            *slot = value;
        }
    }
    /// The String at `index` ("" if it is not a String).
    pub fn string(&self, index: usize) -> &str {
        match self.values.get(index) {
            Some(Value::String(v)) => v,
            _ => "",
        }
    }
    /// Writes every value in order (for an FMU state).
    pub fn save(&self, out: &mut ByteWriter) {
        for value in &self.values {
            match value {
                Value::Real(v) => out.put_f64(*v),
                Value::Integer(v) => out.put_i32(*v),
                Value::Boolean(v) => out.put_bool(*v),
                Value::String(v) => out.put_str(v),
            }
        }
    }
    /// Reads back in place what [`Values::save`] wrote of values of the same types.
    pub fn load(&mut self, input: &mut ByteReader) -> Result<(), StateFormatError> {
        for value in &mut self.values {
            *value = match value {
                Value::Real(_) => Value::Real(input.f64()?),
                Value::Integer(_) => Value::Integer(input.i32()?),
                Value::Boolean(_) => Value::Boolean(input.bool()?),
                Value::String(_) => Value::String(input.string()?),
            };
        }
        Ok(())
    }
    /// Reals at consecutive `indices`, collected.
    pub fn reals(&self, indices: &[usize]) -> Vec<f64> {
        indices.iter().map(|&i| self.real(i)).collect()
    }
}

/// Declares an FMU's variable table once and generates from it both the table function and
/// the value-reference constants (`vr::NAME` = position in the table), so the two cannot
/// disagree. An entry is `NAME = <Variable>`, or `NAME[count] = <iterator of Variables>` for a
/// block (then `vr::NAME` is its first position). `let` bindings before `table:` are visible
/// to every entry.
///
/// ```
/// spurio_export::declare_variables! {
///     /// The variable table.
///     pub fn variables() {
///         let gain = 2.0;
///         table: [
///             U = spurio_export::Variable::input("u", 0.0),
///             Y = spurio_export::Variable::output("y").depends_on(&[vr::U]),
///             K[2] = ["k1", "k2"].map(|n| spurio_export::Variable::parameter(n, gain)),
///             H = spurio_export::Variable::parameter("h", 1e-3),
///         ]
///     }
/// }
/// assert_eq!((vr::U, vr::Y, vr::K, vr::H), (0, 1, 2, 4));
/// assert_eq!(variables()[vr::H].name, "h");
/// ```
#[macro_export]
macro_rules! declare_variables {
    (
        $(#[$meta:meta])*
        $vis:vis fn $name:ident() {
            $(let $binding:ident = $value:expr;)*
            table: [ $($id:ident $([$count:expr])? = $variable:expr),+ $(,)? ]
        }
    ) => {
        /// Value references (= positions in the variable table), generated from its declaration.
        pub mod vr {
            $crate::declare_variables!(@vr 0usize; $($id $([$count])?,)+);
        }
        $(#[$meta])*
        $vis fn $name() -> ::std::vec::Vec<$crate::Variable> {
            $(let $binding = $value;)*
            let mut table = ::std::vec::Vec::new();
            $($crate::declare_variables!(@push table; $variable $(; $count)?);)+
            table
        }
    };
    (@vr $position:expr;) => {};
    (@vr $position:expr; $id:ident, $($rest:tt)*) => {
        pub const $id: usize = $position;
        $crate::declare_variables!(@vr $id + 1; $($rest)*);
    };
    (@vr $position:expr; $id:ident [$count:expr], $($rest:tt)*) => {
        pub const $id: usize = $position;
        $crate::declare_variables!(@vr $id + $count; $($rest)*);
    };
    (@push $table:ident; $variable:expr) => {
        $table.push($variable)
    };
    (@push $table:ident; $block:expr; $count:expr) => {{
        let first = $table.len();
        $table.extend($block);
        debug_assert_eq!($table.len() - first, $count, "block size");
    }};
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clone_from_reuses_the_buffers_and_copies_every_value() {
        let table = [
            Variable::parameter("x", 1.5),
            Variable::integer_parameter("n", 3),
            Variable::string_parameter("s", "abc"),
        ];
        let mut current = Values::from_start(&table);
        let mut before = current.clone();
        let buffer = before.all().as_ptr();
        let string = match &before.all()[2] {
            Value::String(s) => s.as_ptr(),
            other => panic!("{other:?}"),
        };
        current.set_real(0, -2.25);
        current.set_integer(1, 7);
        current.set(2, Value::String("xy".to_string()));
        before.clone_from(&current);
        assert_eq!(before, current);
        assert_eq!(before.real(0), -2.25);
        assert_eq!(before.integer(1), 7);
        assert_eq!(before.string(2), "xy");
        assert_eq!(before.all().as_ptr(), buffer);
        match &before.all()[2] {
            Value::String(s) => assert_eq!(s.as_ptr(), string),
            other => panic!("{other:?}"),
        }
    }
}
