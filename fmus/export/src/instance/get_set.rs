//! Values and their access: `fmi*Get*`/`fmi*Set*` on an instance. Every value reference is
//! checked against the variable table, every value against the variable's type, causality,
//! variability, bounds and finiteness ([`Access`]) before anything is changed, so a rejected
//! call loses nothing; a read first lets the model compute what is stale (outputs in
//! Initialization Mode, direct feedthrough after inputs were set, a Model Exchange
//! evaluation).

use super::access::Access;
use super::common::Instance;
use super::state::{reference, state_name, Function, ModelState};
use crate::model::FmuModel;
use crate::types::Status;
use crate::values::Values;
use crate::variables::{Causality, Value, Variability, VariableType};

/// The value references [`Instance::set_spans`] keeps on the stack for a call of scalars:
/// the master's calls (the inputs of one instance) name at most this many.
const SCALARS: usize = 16;

impl<M: FmuModel> Instance<M> {
    /// value's position in the call, the values and its index to `out`, in order.
    pub fn get_values(
        &mut self,
        f: &Function,
        vrs: &[u32],
        expected: VariableType,
        mut out: impl FnMut(usize, &Values, usize),
    ) -> Status {
        if let Some(&vr) = vrs.iter().find(|vr| !self.is_of_type(**vr, expected)) {
            return self.reject(f, &self.type_error(vr, expected));
        }
        let status = self.refresh_for(f, vrs.iter().map(|&vr| vr as usize));
        if status > Status::Warning {
            return status;
        }
        let values = &self.core.values;
        for (i, vr) in vrs.iter().enumerate() {
            out(i, values, *vr as usize);
        }
        status
    }

    /// `fmi2Get{Real,Integer,Boolean}` into the C array `out` (as long as `vrs`), each
    /// number ([`Values::numbers`]) turned into the C type by `to_c`. The path of a master's
    /// every step: one tight pass (bounds and type of the reference, one load, one store a
    /// value); the references are checked first only when the model computes before the
    /// read; on an error the values already written are undefined, as FMI 2.0.4 §2.1.3
    /// allows.
    #[inline(always)]
    pub fn get_array<C>(
        &mut self,
        f: &Function,
        expected: VariableType,
        vrs: &[u32],
        out: &mut [C],
        to_c: impl Fn(f64) -> C,
    ) -> Status {
        let mut status = Status::Ok;
        if self.needs_refresh() || self.reads_pending_indicator(vrs, false) {
            status = self.refresh_before_get(f, vrs, expected);
            if status > Status::Warning {
                return status;
            }
        }
        let access: &[Access] = &self.interface.access;
        let Some(numbers) = self.core.values.numbers().get(..access.len()) else {
            return self.reject(f, "internal: the values do not match the variable table");
        };
        for (o, &vr) in out.iter_mut().zip(vrs) {
            match access.get(vr as usize) {
                Some(a) if a.variable_type == expected => *o = to_c(numbers[vr as usize]),
                _ => return self.reject(f, &self.type_error(vr, expected)),
            }
        }
        status
    }

    /// Before a get of `vrs` that needs values computed first: the references checked (so
    /// that a rejected read computes nothing), then [`Instance::refresh_outputs`].
    #[inline(never)]
    pub(crate) fn refresh_before_get(
        &mut self,
        f: &Function,
        vrs: &[u32],
        expected: VariableType,
    ) -> Status {
        if let Some(&vr) = vrs.iter().find(|vr| !self.is_of_type(**vr, expected)) {
            return self.reject(f, &self.type_error(vr, expected));
        }
        self.refresh_for(f, vrs.iter().map(|&vr| vr as usize))
    }

    /// Before values are read by `f`: in Initialization Mode the model computes the outputs
    /// and calculated parameters from the current parameters; in Step Mode, after inputs
    /// were set, it recomputes the direct-feedthrough outputs; a Model Exchange instance
    /// evaluates its derivatives and outputs when states, inputs or time changed. Otherwise
    /// nothing to do.
    pub fn refresh_outputs(&mut self, f: &Function) -> Status {
        if self.model_exchange {
            // Outputs and derivatives from the current states, inputs and time.
            return self.evaluate(f);
        }
        if !self.needs_refresh() {
            return Status::Ok;
        }
        if self.core.state == ModelState::InitializationMode {
            self.run_model(f, |m, ctx| m.initialize(ctx))
        } else if self.core.inputs_changed && self.core.state == ModelState::StepComplete {
            let status = self.run_model(f, |m, ctx| m.update_outputs(ctx));
            if status <= Status::Warning {
                self.core.inputs_changed = false;
            }
            status
        } else {
            Status::Ok
        }
    }

    /// Before `f` reads the variables at table indices `read`: [`Instance::refresh_outputs`],
    /// then the event indicators when one of them is read ([`Instance::indicators_for`]).
    pub(crate) fn refresh_for(
        &mut self,
        f: &Function,
        read: impl Iterator<Item = usize>,
    ) -> Status {
        let status = self.refresh_outputs(f);
        if status > Status::Warning {
            return status;
        }
        status.max(self.indicators_for(f, read))
    }

    /// Whether values must be computed before they are read ([`Instance::refresh_outputs`]).
    /// The event indicators are not among them: a read computes them only when it names one
    /// ([`Instance::reads_pending_indicator`]).
    #[inline]
    pub(crate) fn needs_refresh(&self) -> bool {
        let state = self.core.state;
        state == ModelState::InitializationMode
            || (self.core.inputs_changed
                && (state == ModelState::StepComplete || (self.model_exchange && state.computes())))
    }

    /// Whether value reference `vr` names a variable of type `expected`.
    #[inline]
    pub fn is_of_type(&self, vr: u32, expected: VariableType) -> bool {
        self.interface
            .access
            .get(vr as usize)
            .is_some_and(|a| a.variable_type == expected)
    }

    /// Why FMI 2.0 value reference `vr` names no variable.
    pub(crate) fn unknown_reference(&self, vr: usize) -> String {
        let info = &self.interface.info;
        format!(
            "unknown value reference {vr} ({} has value references 0 to {})",
            info.model_identifier,
            info.variables.len().saturating_sub(1)
        )
    }

    /// Why `vr` is not a variable of type `expected` (unknown, or of another type).
    fn type_error(&self, vr: u32, expected: VariableType) -> String {
        let info = &self.interface.info;
        match info.variables.get(vr as usize) {
            None => self.unknown_reference(vr as usize),
            Some(v) => format!(
                "variable `{}` (value reference {vr}) is of type {}, not {expected}",
                v.name,
                v.variable_type()
            ),
        }
    }

    /// Why the variable at `vr` cannot be set by `f` in the current state.
    fn not_settable(&self, f: &Function, vr: u32) -> String {
        let v = &self.interface.info.variables[vr as usize];
        let what = match (v.causality, v.variability) {
            (Causality::Parameter, Variability::Fixed) if f.name.starts_with("fmi3") => {
                "a fixed parameter: it can be set only before fmi3ExitInitializationMode"
            }
            (Causality::Parameter, Variability::Fixed) => {
                "a fixed parameter: it can be set only before fmi2ExitInitializationMode"
            }
            (Causality::Output, _) => "an output: the FMU computes it",
            (Causality::CalculatedParameter, _) => "a calculated parameter: the FMU computes it",
            _ => "not settable now",
        };
        format!(
            "variable `{}`{} is {what} (state {})",
            v.name,
            reference(f, vr),
            state_name(f, self.core.state)
        )
    }

    /// Checks that `f` may set the variable at `vr` to a value of type `actual` (`number`: its
    /// value as a number, for the finiteness and bounds checks) in the current state (its
    /// bit `bit`); its access rules, or the rejection's status.
    #[inline(always)]
    fn check_set(
        &self,
        f: &Function,
        bit: u32,
        vr: u32,
        actual: VariableType,
        number: Option<f64>,
    ) -> Result<&Access, Status> {
        let need = bit | Access::type_bit(actual);
        match self.interface.access.get(vr as usize) {
            Some(a) if number.map_or(a.bits & need == need, |x| a.admits(need, x)) => Ok(a),
            _ => Err(self.reject_set(f, vr, actual, number)),
        }
    }

    /// The rejection of a value [`Instance::check_set`] refuses.
    #[cold]
    #[inline(never)]
    pub(crate) fn reject_set(
        &self,
        f: &Function,
        vr: u32,
        actual: VariableType,
        x: Option<f64>,
    ) -> Status {
        let bit = self.core.state.bit();
        let message = match self.interface.access.get(vr as usize) {
            Some(a) if a.variable_type == actual && !a.settable_in(bit) => self.not_settable(f, vr),
            Some(a) if a.variable_type == actual => {
                self.out_of_range(f, vr, x.unwrap_or(f64::NAN), a)
            }
            _ => self.type_error(vr, actual),
        };
        self.reject(f, &message)
    }

    /// Why `x` is not a value the variable at `vr` accepts: not finite or out of its bounds.
    fn out_of_range(&self, f: &Function, vr: u32, x: f64, a: &Access) -> String {
        let name = &self.interface.info.variables[vr as usize].name;
        if !x.is_finite() {
            format!(
                "variable `{name}`{}: {x} rejected, values must be finite",
                reference(f, vr)
            )
        } else if x < a.min {
            format!("variable `{name}` = {x} is below its minimum {}", a.min)
        } else {
            format!("variable `{name}` = {x} is above its maximum {}", a.max)
        }
    }

    /// After values were set (`flags`: the [`Access::bits`] of the variables set, or-ed):
    /// inputs changed (the direct-feedthrough outputs are stale), parameters changed in Step
    /// Mode (the model is told).
    #[inline(always)]
    pub(crate) fn values_set(&mut self, f: &Function, flags: u32) -> Status {
        self.jacobian.forget();
        let parameters = flags & Access::PARAMETER != 0;
        // Model Exchange: a tunable parameter set in Event Mode changes the derivatives and
        // outputs read next, as an input does.
        self.core.inputs_changed |= flags & Access::INPUT != 0 || parameters && self.model_exchange;
        if parameters {
            return self.parameters_set(f);
        }
        Status::Ok
    }

    /// After parameters were set: in Step Mode (Event Mode), the model is told.
    #[inline(never)]
    fn parameters_set(&mut self, f: &Function) -> Status {
        if matches!(
            self.core.state,
            ModelState::StepComplete | ModelState::EventMode
        ) {
            return self.run_model(f, |m, ctx| m.parameters_changed(ctx));
        }
        Status::Ok
    }

    /// `fmi2Set{Real,Integer,Boolean,String}`: the `(value reference, value)` pairs of
    /// `targets`. Checks every value first (reference, type, whether it may be set in this
    /// state, finiteness, bounds: from the precomputed [`Access`] table), then sets them all,
    /// so a rejected call changes nothing. `targets` is walked twice (hence `Clone`): no
    /// buffer.
    pub fn set_values<I>(&mut self, f: &Function, targets: I) -> Status
    where
        I: Iterator<Item = (u32, Value)> + Clone,
    {
        let bit = self.core.state.bit();
        let mut flags = 0;
        for (vr, value) in targets.clone() {
            let number = match value {
                Value::Real(x) => Some(x),
                Value::Integer(i) => Some(f64::from(i)),
                _ => None,
            };
            match self.check_set(f, bit, vr, value.variable_type(), number) {
                Ok(a) => flags |= a.bits,
                Err(status) => return status,
            }
        }
        for (vr, value) in targets {
            self.core.values.set(vr as usize, value);
        }
        self.values_set(f, flags)
    }

    /// `fmi2Set{Real,Integer,Boolean}`: as [`Instance::set_values`] for values of type
    /// `actual` given as numbers ([`Values::numbers`]), the path of a master's every step:
    /// no value enum, stored in place.
    pub fn set_numbers<I>(&mut self, f: &Function, actual: VariableType, targets: I) -> Status
    where
        I: Iterator<Item = (u32, f64)> + Clone,
    {
        let bit = self.core.state.bit();
        let mut flags = 0;
        for (vr, x) in targets.clone() {
            match self.check_set(f, bit, vr, actual, Some(x)) {
                Ok(a) => flags |= a.bits,
                Err(status) => return status,
            }
        }
        let numbers = self.core.values.numbers_mut();
        for (vr, x) in targets {
            if let Some(slot) = numbers.get_mut(vr as usize) {
                *slot = x;
            }
        }
        self.values_set(f, flags)
    }

    /// `fmi2Set{Real,Integer,Boolean}` from the C arrays: value references `vrs`, values
    /// `values` (of the same length) of a C type that `to_number` turns into stored numbers.
    /// As [`Instance::set_numbers`], in two tight passes over the arrays: the first checks
    /// each value with one load of its [`Access`] (`bits & need == need` for type and state,
    /// `min <= x <= max` for bounds and finiteness), the second stores (one value: checked,
    /// then stored, no loop); any failure goes to the cold path that names the variable and
    /// the reason.
    #[inline(always)]
    pub fn set_array<C: Copy>(
        &mut self,
        f: &Function,
        actual: VariableType,
        (vrs, values): (&[u32], &[C]),
        to_number: impl Fn(C) -> f64,
    ) -> Status {
        let need = self.core.state.bit() | Access::type_bit(actual);
        let access: &[Access] = &self.interface.access;
        if let ([vr], [v]) = (vrs, values) {
            // one value (a master's common call): checked and stored in one go, no loops
            let (vr, x) = (*vr, to_number(*v));
            return match (access.get(vr as usize), self.core.values.numbers_mut()) {
                (Some(a), numbers) if a.admits(need, x) => {
                    let flags = a.bits;
                    if let Some(slot) = numbers.get_mut(vr as usize) {
                        *slot = x;
                    }
                    self.values_set(f, flags)
                }
                _ => self.reject_set(f, vr, actual, Some(x)),
            };
        }
        let mut flags = 0;
        for (&vr, &v) in vrs.iter().zip(values) {
            let x = to_number(v);
            match access.get(vr as usize) {
                Some(a) if a.admits(need, x) => flags |= a.bits,
                _ => return self.reject_set(f, vr, actual, Some(x)),
            }
        }
        let numbers = self.core.values.numbers_mut();
        for (&vr, &v) in vrs.iter().zip(values) {
            if let Some(slot) = numbers.get_mut(vr as usize) {
                *slot = to_number(v);
            }
        }
        self.values_set(f, flags)
    }

    /// `fmi3Set{Float64,Int32,Boolean}`'s fast path: the values `values` (arrays row-major)
    /// for the FMI 3.0 value references `vrs` ([`super::interface::Span`]s), each checked with
    /// its [`Access`] as in [`Instance::set_array`], then stored; `None` when a reference is
    /// unknown or `time`, the count is not `values.len()` or a value is refused: nothing is
    /// changed then, and the full path checks again and says why.
    ///
    /// The master's call, every reference a scalar (`values.len() = vrs.len()`, at most
    /// [`SCALARS`] references), looks each reference up once: its table index is kept on the
    /// stack between the check and the store. A call naming an array is checked, then
    /// stored, span by span.
    #[inline(always)]
    pub(crate) fn set_spans<C: Copy>(
        &mut self,
        f: &Function,
        actual: VariableType,
        vrs: &[u32],
        values: &[C],
        to_number: impl Fn(C) -> f64,
    ) -> Option<Status> {
        let need = self.core.state.bit() | Access::type_bit(actual);
        let (access, spans) = (&self.interface.access, &self.interface.spans);
        let mut flags = 0;
        if vrs.len() == values.len() && vrs.len() <= SCALARS {
            let mut at = [0u32; SCALARS];
            let mut scalars = true;
            for ((index, &vr), &v) in at.iter_mut().zip(vrs).zip(values) {
                let span = spans.get(vr as usize)?;
                if span.len != 1 {
                    scalars = false;
                    break;
                }
                let (a, x) = (access.get(span.first as usize)?, to_number(v));
                if !a.admits(need, x) {
                    return None;
                }
                flags |= a.bits;
                *index = span.first;
            }
            if scalars {
                let numbers = self.core.values.numbers_mut();
                for (&index, &v) in at.iter().zip(values) {
                    if let Some(slot) = numbers.get_mut(index as usize) {
                        *slot = to_number(v);
                    }
                }
                return Some(self.values_set(f, flags));
            }
            flags = 0;
        }
        let mut k = 0;
        for &vr in vrs {
            let span = spans.get(vr as usize).filter(|span| span.len > 0)?;
            let (first, len) = (span.first as usize, span.len as usize);
            if len == 1 {
                let (a, x) = (access.get(first)?, to_number(*values.get(k)?));
                if !a.admits(need, x) {
                    return None;
                }
                flags |= a.bits;
                k += 1;
                continue;
            }
            let xs = values.get(k..k + len)?;
            for (a, &v) in access.get(first..first + len)?.iter().zip(xs) {
                let x = to_number(v);
                if !a.admits(need, x) {
                    return None;
                }
                flags |= a.bits;
            }
            k += len;
        }
        if k != values.len() {
            return None;
        }
        let numbers = self.core.values.numbers_mut();
        let mut k = 0;
        for &vr in vrs {
            if let Some(span) = spans.get(vr as usize) {
                let (first, len) = (span.first as usize, span.len as usize);
                if len == 1 {
                    if let (Some(slot), Some(&v)) = (numbers.get_mut(first), values.get(k)) {
                        *slot = to_number(v);
                    }
                    k += 1;
                    continue;
                }
                if let (Some(to), Some(xs)) =
                    (numbers.get_mut(first..first + len), values.get(k..k + len))
                {
                    for (slot, &v) in to.iter_mut().zip(xs) {
                        *slot = to_number(v);
                    }
                }
                k += len;
            }
        }
        Some(self.values_set(f, flags))
    }
}
