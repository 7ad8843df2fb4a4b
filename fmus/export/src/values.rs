//! The values an instance holds for its variable table, flat (one number per variable), and
//! the finiteness scans and computed runs of the check after every model call.

use crate::bytes::{ByteReader, ByteWriter, StateFormatError};
use crate::variables::{Causality, Value, Variable, VariableType};

/// The current values of an instance, one per variable, indexed like the table.
///
/// Stored flat for memory speed: one `f64` per variable (a Real as it is, an Integer exactly,
/// a Boolean as 0 or 1, a String as 0 with its text kept apart), so that an instance's values
/// take 9 bytes per variable, a get or set is one load or store, and the roll-back copy
/// before a model call is a `memcpy`.
#[derive(Debug, Default, PartialEq)]
pub struct Values {
    numbers: Vec<f64>,
    types: Vec<VariableType>,
    /// The String variables' texts, by index (ascending).
    strings: Vec<(usize, String)>,
}

/// Written out because the derived `clone_from` clones afresh: this one reuses the buffers
/// (and each String's), so the per-call snapshot of the values allocates nothing after
/// the first.
impl Clone for Values {
    fn clone(&self) -> Self {
        Self {
            numbers: self.numbers.clone(),
            types: self.types.clone(),
            strings: self.strings.clone(),
        }
    }
    fn clone_from(&mut self, source: &Self) {
        self.numbers.clone_from(&source.numbers);
        self.types.clone_from(&source.types);
        if self.strings.len() != source.strings.len() {
            self.strings.clone_from(&source.strings);
        } else {
            for (to, from) in self.strings.iter_mut().zip(&source.strings) {
                to.0 = from.0;
                to.1.clone_from(&from.1);
            }
        }
    }
}

/// A number of the flat storage as its value of type `t`.
fn typed(t: VariableType, x: f64) -> Value {
    match t {
        VariableType::Real => Value::Real(x),
        VariableType::Integer => Value::Integer(x as i32),
        VariableType::Boolean => Value::Boolean(x != 0.0),
        VariableType::String => Value::String(String::new()),
    }
}

impl Values {
    /// The start values of `variables`.
    pub fn from_start(variables: &[Variable]) -> Self {
        let mut values = Self::default();
        values.reset_to_start(variables);
        values
    }
    /// Back to the start values of `variables` in place: the buffers (and each String's) are
    /// reused, so a reset of an instance with the same table allocates nothing (`fmi2Reset`
    /// of a plant that an estimator resets once per sigma point and step).
    pub fn reset_to_start(&mut self, variables: &[Variable]) {
        self.numbers.clear();
        self.numbers.resize(variables.len(), 0.0);
        self.types.clear();
        self.types
            .extend(variables.iter().map(Variable::variable_type));
        let mut texts = 0;
        for (i, v) in variables.iter().enumerate() {
            if let Value::String(text) = &v.start {
                match self.strings.get_mut(texts) {
                    Some(slot) => {
                        slot.0 = i;
                        slot.1.clone_from(text);
                    }
                    None => self.strings.push((i, text.clone())),
                }
                texts += 1;
            } else {
                self.set(i, v.start.clone());
            }
        }
        self.strings.truncate(texts);
    }
    /// The number of values.
    pub fn len(&self) -> usize {
        self.numbers.len()
    }
    /// Whether there is no value.
    pub fn is_empty(&self) -> bool {
        self.numbers.is_empty()
    }
    /// The value at `index` (a String's text is copied).
    pub fn get(&self, index: usize) -> Option<Value> {
        let t = *self.types.get(index)?;
        Some(match t {
            VariableType::String => Value::String(self.string(index).to_string()),
            _ => typed(t, self.numbers[index]),
        })
    }
    /// Every value as a number (see [`Values::number`]; a String is 0 here), by index: what
    /// the typed getters read once the type is checked.
    #[inline]
    pub fn numbers(&self) -> &[f64] {
        &self.numbers
    }
    /// The numbers, to set in place values whose types were checked (an Integer exactly, a
    /// Boolean as 0 or 1: see [`Values::numbers`]).
    #[inline]
    pub(crate) fn numbers_mut(&mut self) -> &mut [f64] {
        &mut self.numbers
    }
    /// The type of the value at `index`.
    pub fn variable_type(&self, index: usize) -> Option<VariableType> {
        self.types.get(index).copied()
    }
    /// The value at `index` as a number: a Real as it is, an Integer exactly, a Boolean as 0
    /// or 1, a String (or an unknown index) as NaN.
    #[inline]
    pub fn number(&self, index: usize) -> f64 {
        match self.types.get(index) {
            Some(VariableType::String) | None => f64::NAN,
            Some(_) => self.numbers[index],
        }
    }
    /// Replaces the value at `index` when it has the variable's type (checked by the caller).
    pub fn set(&mut self, index: usize, value: Value) {
        match (self.types.get(index), value) {
            (Some(VariableType::Real), Value::Real(x)) => self.numbers[index] = x,
            (Some(VariableType::Integer), Value::Integer(i)) => self.numbers[index] = f64::from(i),
            (Some(VariableType::Boolean), Value::Boolean(b)) => {
                self.numbers[index] = f64::from(u8::from(b))
            }
            (Some(VariableType::String), Value::String(text)) => {
                if let Some(slot) = self.text_mut(index) {
                    *slot = text;
                }
            }
            _ => {}
        }
    }
    fn text_mut(&mut self, index: usize) -> Option<&mut String> {
        let at = self
            .strings
            .binary_search_by_key(&index, |(i, _)| *i)
            .ok()?;
        Some(&mut self.strings[at].1)
    }
    /// The Real at `index`; NaN if the index is not a Real (a table bug caught by tests).
    #[inline]
    pub fn real(&self, index: usize) -> f64 {
        match self.types.get(index) {
            Some(VariableType::Real) => self.numbers[index],
            _ => f64::NAN,
        }
    }
    /// Sets the Real at `index`.
    #[inline]
    pub fn set_real(&mut self, index: usize, value: f64) {
        if self.types.get(index) == Some(&VariableType::Real) {
            self.numbers[index] = value;
        }
    }
    /// Sets the Reals at `first`, `first + 1`, … to `values` (nothing when one of them is
    /// not a Real): a model's outputs declared one after the other, written at once.
    #[inline]
    pub fn set_reals<const N: usize>(&mut self, first: usize, values: [f64; N]) {
        let types = self.types.get(first..).and_then(|t| t.first_chunk::<N>());
        // every type compared (no early exit): unrolled for the N of the call
        if types.is_some_and(|types| {
            types
                .iter()
                .fold(true, |all, t| all & (*t == VariableType::Real))
        }) {
            self.put_reals(first, values);
        }
    }
    /// Whether the `n` values from `first` on are all Reals (a model that checks a run once,
    /// when it is built, then writes it with [`Values::put_reals`]).
    pub fn are_reals(&self, first: usize, n: usize) -> bool {
        self.types
            .get(first..first.saturating_add(n))
            .is_some_and(|t| t.iter().all(|t| *t == VariableType::Real))
    }
    /// Sets the values at `first`, `first + 1`, … to `values` without looking at their types
    /// (nothing when the run passes the end): for a run [`Values::are_reals`] accepted when the
    /// model was built; [`Values::set_reals`] otherwise.
    #[inline(always)]
    pub fn put_reals<const N: usize>(&mut self, first: usize, values: [f64; N]) {
        if let Some(slots) = self
            .numbers
            .get_mut(first..)
            .and_then(|n| n.first_chunk_mut::<N>())
        {
            *slots = values;
        }
    }
    /// The Integer at `index` (0 if it is not an Integer).
    pub fn integer(&self, index: usize) -> i32 {
        match self.types.get(index) {
            Some(VariableType::Integer) => self.numbers[index] as i32,
            _ => 0,
        }
    }
    /// Sets the Integer at `index`.
    pub fn set_integer(&mut self, index: usize, value: i32) {
        self.set(index, Value::Integer(value));
    }
    /// The Boolean at `index` (false if it is not a Boolean).
    pub fn boolean(&self, index: usize) -> bool {
        self.types.get(index) == Some(&VariableType::Boolean) && self.numbers[index] != 0.0
    }
    /// Sets the Boolean at `index`.
    pub fn set_boolean(&mut self, index: usize, value: bool) {
        self.set(index, Value::Boolean(value));
    }
    /// The String at `index` ("" if it is not a String).
    pub fn string(&self, index: usize) -> &str {
        match self.strings.binary_search_by_key(&index, |(i, _)| *i) {
            Ok(at) => &self.strings[at].1,
            Err(_) => "",
        }
    }
    /// The first Real that is NaN or infinite: (index, value). (Integers and Booleans are
    /// always finite, Strings are stored as 0: one scan of the numbers.)
    pub fn first_non_finite(&self) -> Option<(usize, f64)> {
        first_non_finite(&self.numbers)
    }
    /// The String variables' texts, by index (ascending), for the roll-back copy of a model
    /// call whose computed variables include a String.
    pub(crate) fn texts(&self) -> &Vec<(usize, String)> {
        &self.strings
    }
    /// The String variables' texts, to restore them.
    pub(crate) fn texts_mut(&mut self) -> &mut Vec<(usize, String)> {
        &mut self.strings
    }
    /// Writes every value in order (for an FMU state).
    pub fn save(&self, out: &mut ByteWriter) {
        for (i, (t, x)) in self.types.iter().zip(&self.numbers).enumerate() {
            match t {
                VariableType::Real => out.put_f64(*x),
                VariableType::Integer => out.put_i32(*x as i32),
                VariableType::Boolean => out.put_bool(*x != 0.0),
                VariableType::String => out.put_str(self.string(i)),
            }
        }
    }
    /// Reads back in place what [`Values::save`] wrote of values of the same types.
    pub fn load(&mut self, input: &mut ByteReader) -> Result<(), StateFormatError> {
        for i in 0..self.numbers.len() {
            match self.types[i] {
                VariableType::Real => self.numbers[i] = input.f64()?,
                VariableType::Integer => self.numbers[i] = f64::from(input.i32()?),
                VariableType::Boolean => self.numbers[i] = f64::from(u8::from(input.bool()?)),
                VariableType::String => {
                    let text = input.string()?;
                    if let Some(slot) = self.text_mut(i) {
                        *slot = text;
                    }
                }
            }
        }
        Ok(())
    }
    /// The values at `range` as one slice to write in place, when every one of them is a Real
    /// (None otherwise): a model writes a block of outputs at memory speed.
    pub fn reals_mut(&mut self, range: std::ops::Range<usize>) -> Option<&mut [f64]> {
        let types = self.types.get(range.clone())?;
        // Every type compared (no early exit), so the check runs a vector of types at a time.
        if types
            .iter()
            .fold(true, |real, t| real & (*t == VariableType::Real))
        {
            self.numbers.get_mut(range)
        } else {
            None
        }
    }
    /// Reals at consecutive `indices`, collected.
    pub fn reals(&self, indices: &[usize]) -> Vec<f64> {
        indices.iter().map(|&i| self.real(i)).collect()
    }
}

/// Whether every number of `xs` is finite, branch-free: `x · 0` is ±0 for a finite `x` and
/// NaN for NaN or ±∞, and a sum stays ±0 until a NaN enters it. Eight independent lanes
/// (no reassociation of one sum: each lane is its own sum), so the compiler turns the loop
/// into packed multiplies and adds, ≈ 2 instructions a value with SSE2; the fewer than eight
/// values before them are summed apart (a short range costs no lane set-up). The cost of the
/// check after every model call ([`crate::instance`]).
#[inline]
pub fn all_finite(xs: &[f64]) -> bool {
    const LANES: usize = 8;
    let (head, body) = xs.split_at(xs.len() % LANES);
    let mut sum = 0.0f64;
    for x in head {
        sum += x * 0.0;
    }
    if !body.is_empty() {
        let mut acc = [0.0f64; LANES];
        for chunk in body.chunks_exact(LANES) {
            for (a, x) in acc.iter_mut().zip(chunk) {
                *a += x * 0.0;
            }
        }
        // lane k with lane k + 4, then k with k + 2: the adds of whole registers, so that
        // the loop keeps the lanes in their registers (no shuffles)
        let half = [
            acc[0] + acc[4],
            acc[1] + acc[5],
            acc[2] + acc[6],
            acc[3] + acc[7],
        ];
        sum += (half[0] + half[2]) + (half[1] + half[3]);
    }
    !sum.is_nan()
}

/// The first number of `xs` that is NaN or infinite: (position, value). The cold path after
/// [`all_finite`] said there is one, to name its variable.
#[cold]
pub fn first_non_finite(xs: &[f64]) -> Option<(usize, f64)> {
    xs.iter().position(|x| !x.is_finite()).map(|i| (i, xs[i]))
}

/// The variables a model call may write (outputs, locals, calculated parameters: everything
/// but parameters and inputs, which only the master sets), as runs of consecutive indices:
/// what the export layer copies before a model call and checks for non-finite values after
/// it. Two runs apart by at most [`RUN_GAP`] other variables are one run (copying and
/// scanning a few parameters costs less than another run; a model does not change them).
pub fn computed_runs(variables: &[Variable]) -> Vec<std::ops::Range<usize>> {
    let mut runs: Vec<std::ops::Range<usize>> = Vec::new();
    for (i, v) in variables.iter().enumerate() {
        if matches!(v.causality, Causality::Parameter | Causality::Input) {
            continue;
        }
        match runs.last_mut() {
            Some(run) if i - run.end <= RUN_GAP => run.end = i + 1,
            _ => runs.push(i..i + 1),
        }
    }
    runs
}

/// The most parameters or inputs between two computed runs that [`computed_runs`] joins.
pub const RUN_GAP: usize = 4;

#[cfg(test)]
mod tests {
    use super::*;

    /// A Real, an Integer, a String and a Boolean parameter: x = 1.5, n = 3, s = "abc",
    /// b = true.
    fn one_of_each_type() -> [Variable; 4] {
        [
            Variable::parameter("x", 1.5),
            Variable::integer_parameter("n", 3),
            Variable::string_parameter("s", "abc"),
            Variable::boolean_parameter("b", true),
        ]
    }

    /// Sets x = −2.25, n = 7, s = `text`, b = false.
    fn change_every_value(values: &mut Values, text: &str) {
        values.set_real(0, -2.25);
        values.set_integer(1, 7);
        values.set(2, Value::String(text.to_string()));
        values.set_boolean(3, false);
    }

    #[test]
    fn clone_from_reuses_the_buffers_and_copies_every_value() {
        let table = one_of_each_type();
        let mut current = Values::from_start(&table);
        assert_eq!(current.get(0), Some(Value::Real(1.5)));
        assert_eq!(current.get(1), Some(Value::Integer(3)));
        assert_eq!(current.get(2), Some(Value::String("abc".into())));
        assert_eq!(current.get(3), Some(Value::Boolean(true)));
        let mut before = current.clone();
        let buffer = before.numbers.as_ptr();
        let string = before.string(2).as_ptr();
        change_every_value(&mut current, "xy");
        before.clone_from(&current);
        assert_eq!(before, current);
        assert_eq!(before.real(0), -2.25);
        assert_eq!(before.integer(1), 7);
        assert_eq!(before.string(2), "xy");
        assert!(!before.boolean(3));
        assert_eq!(before.numbers.as_ptr(), buffer);
        assert_eq!(before.string(2).as_ptr(), string);
    }

    #[test]
    fn reset_to_start_restores_every_start_value_in_the_same_buffers() {
        let table = one_of_each_type();
        let mut values = Values::from_start(&table);
        let numbers = values.numbers.as_ptr();
        let text = values.string(2).as_ptr();
        change_every_value(&mut values, "wxyz");
        let text_changed = values.string(2).as_ptr();
        values.reset_to_start(&table);
        assert_eq!(values, Values::from_start(&table));
        assert_eq!(
            (values.real(0), values.integer(1), values.string(2)),
            (1.5, 3, "abc")
        );
        assert!(values.boolean(3));
        assert_eq!(values.numbers.as_ptr(), numbers);
        // The set moved in a new String (4 bytes); the reset copies "abc" into its buffer.
        assert_ne!(text_changed, text);
        assert_eq!(values.string(2).as_ptr(), text_changed);
        // A table with fewer Strings drops the extra texts.
        let shorter = [Variable::parameter("x", 0.5)];
        values.reset_to_start(&shorter);
        assert_eq!(values, Values::from_start(&shorter));
    }

    #[test]
    fn a_value_of_another_type_is_not_stored_and_reads_as_its_default() {
        let table = [
            Variable::parameter("x", 1.5),
            Variable::integer_parameter("n", 3),
        ];
        let mut values = Values::from_start(&table);
        values.set(0, Value::Integer(9));
        values.set_real(1, 4.5);
        assert_eq!((values.real(0), values.integer(1)), (1.5, 3));
        assert!(values.real(1).is_nan());
        assert_eq!(
            (values.integer(0), values.number(1), values.len()),
            (0, 3.0, 2)
        );
        values.set_real(0, f64::INFINITY);
        assert_eq!(values.first_non_finite(), Some((0, f64::INFINITY)));
    }
}
