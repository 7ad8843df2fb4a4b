//! How `fmi*Set*`/`fmi*Get*` may access each variable, precomputed once per configuration
//! from its declaration: the table the get/set checks read.

use super::state::bits::*;
use crate::variables::{Causality, Initial, Variability, Variable, VariableType};

/// How `fmi*Set*`/`fmi*Get*` may access one variable, precomputed from its declaration
/// (once per configuration, in the interface), so that a call checks a value in a few
/// instructions: its type, the states in which it may be set, and its bounds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Access {
    /// The variable's type.
    pub variable_type: VariableType,
    /// In one word: the states ([`super::state::ModelState::bit`]) in which `fmi*Set*` may set it, its
    /// type's bit ([`Access::type_bit`]) and [`Access::INPUT`], [`Access::PARAMETER`]; a set
    /// is allowed when `bits & need == need` with `need` = state bit | type bit.
    pub bits: u32,
    /// Lower bound (−`f64::MAX` when none, so that `min <= x && x <= max` also says that
    /// `x` is finite: NaN fails both comparisons, ±∞ one).
    pub min: f64,
    /// Upper bound (`f64::MAX` when none).
    pub max: f64,
}

impl Access {
    /// The bit of an input (setting it invalidates the direct-feedthrough outputs).
    pub const INPUT: u32 = 1 << 24;
    /// The bit of a parameter (setting it in Step Mode calls `parameters_changed`).
    pub const PARAMETER: u32 = 1 << 25;
    /// The bit of a Real output or state derivative: an unknown of a directional derivative.
    pub const UNKNOWN: u32 = 1 << 26;
    /// The bit of a Real input or continuous state: a known of a directional derivative.
    pub const KNOWN: u32 = 1 << 27;

    /// The bit of type `t` in [`Access::bits`] (above the state bits).
    #[inline(always)]
    pub const fn type_bit(t: VariableType) -> u32 {
        1 << (16 + t as u32)
    }

    /// Whether value `x` may be set where `need` (state bit | type bit, see [`Access::bits`])
    /// is asked: the state and type allowed, `x` finite and within the bounds.
    #[inline(always)]
    pub fn admits(&self, need: u32, x: f64) -> bool {
        self.bits & need == need && x >= self.min && x <= self.max
    }

    /// Whether the variable may be set in the state with bit `state`.
    pub fn settable_in(&self, state: u32) -> bool {
        self.bits & state != 0
    }

    /// Whether the variable is an input.
    pub fn is_input(&self) -> bool {
        self.bits & Self::INPUT != 0
    }

    /// Whether the variable is a parameter.
    pub fn is_parameter(&self) -> bool {
        self.bits & Self::PARAMETER != 0
    }

    /// The access rules of `v` (FMI 2.0.4 §3.2.3 / FMI 3.0.2 §2.4.7: what may be set when).
    pub fn of(v: &Variable) -> Self {
        let not_constant = v.variability != Variability::Constant;
        let input = v.causality == Causality::Input;
        let mut settable = 0;
        if not_constant && (input || matches!(v.initial, Some(Initial::Exact | Initial::Approx))) {
            settable |= INSTANTIATED;
        }
        if not_constant && (input || v.initial == Some(Initial::Exact)) {
            settable |= INIT_MODE;
        }
        if input || (v.causality == Causality::Parameter && v.variability == Variability::Tunable) {
            settable |= STEP_COMPLETE | EVENT_MODE;
        }
        // Continuous-Time Mode: continuous-time inputs only; a discrete input changes at
        // events alone (FMI 2.0.4 §3.2.3, FMI 3.0.2 §3.2.1).
        if input && v.variability == Variability::Continuous {
            settable |= CONTINUOUS_TIME_MODE;
        }
        let mut bits = settable | Self::type_bit(v.variable_type());
        if input {
            bits |= Self::INPUT;
        }
        if v.causality == Causality::Parameter {
            bits |= Self::PARAMETER;
        }
        if v.variable_type() == VariableType::Real {
            if v.causality == Causality::Output || v.derivative_of.is_some() {
                bits |= Self::UNKNOWN;
            }
            if input || v.state {
                bits |= Self::KNOWN;
            }
        }
        Self {
            variable_type: v.variable_type(),
            bits,
            min: v.min.unwrap_or(-f64::MAX),
            max: v.max.unwrap_or(f64::MAX),
        }
    }
}
