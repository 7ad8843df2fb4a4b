//! The variable table of an FMU: its variables, their types and attributes, and the macro that
//! declares a table with its value-reference constants.
//!
//! A model declares its interface as a list of [`Variable`]s; the value reference of a
//! variable is its position in the list, so dispatch is an index, not a search. The same table
//! produces `modelDescription.xml` ([`crate::description`]) and drives the checks of every
//! `fmi2Get*` / `fmi2Set*` call ([`crate::instance`]); the values an instance holds for it are
//! [`crate::values::Values`].

use std::fmt;

/// `attribute! { Name { Variant = "text", … } }`: an enumeration whose values are written to
/// `modelDescription.xml` as the texts given, with `as_str` giving the text.
macro_rules! attribute {
    ($(#[$m:meta])* $name:ident { $($variant:ident = $text:literal),* $(,)? }) => {
        $(#[$m])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq)]
        pub enum $name { $($variant),* }
        impl $name {
            /// The value's text in `modelDescription.xml`.
            pub fn as_str(self) -> &'static str {
                match self { $($name::$variant => $text),* }
            }
        }
    };
}

attribute! {
    /// `causality` of a variable.
    Causality {
        Parameter = "parameter", CalculatedParameter = "calculatedParameter", Input = "input",
        Output = "output", Local = "local",
    }
}
attribute! {
    /// `variability` of a variable.
    Variability {
        Constant = "constant", Fixed = "fixed", Tunable = "tunable", Discrete = "discrete",
        Continuous = "continuous",
    }
}
attribute! {
    /// `initial` of a variable.
    Initial { Exact = "exact", Approx = "approx", Calculated = "calculated" }
}
attribute! {
    /// The FMI type of a variable (its element name in an FMI 2.0 `ScalarVariable`).
    VariableType { Real = "Real", Integer = "Integer", Boolean = "Boolean", String = "String" }
}

impl fmt::Display for VariableType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
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

/// Written out so that `clone_from` reuses a String's buffer (see [`crate::values::Values`]).
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
