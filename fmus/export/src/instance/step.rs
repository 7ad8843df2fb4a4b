//! Stepping and roll-back: every model call (initialisation, a step, direct feedthrough,
//! tunable parameters, a Model Exchange evaluation) runs through `Instance::run_model`.
//!
//! **No non-finite value is ever published.** After every model call that computes values,
//! every value the call may write (outputs, locals, calculated parameters:
//! [`super::Interface::computed`]; a model never writes its parameters or inputs, checked in debug
//! builds) is checked by a branch-free scan; a NaN or ±∞ is `fmi2Error` naming the variable,
//! the values go back to those before the call (so `fmi2GetReal` in the `Error` state reads
//! the last finite values, never the NaN), the time does not advance, and the instance moves
//! to the `Error` state (the model's internal state may have advanced: as after any model
//! error, `fmi2SetFMUstate` or `fmi2Reset` lead on).
//!
//! A step whose end `t + h` is not finite, that does not start at the current communication
//! point or that the model refuses in [`FmuModel::check_step`] is `fmi2Error` and leaves the
//! instance as it was; a model that fails inside a step moves the instance to `Error`.

use super::common::Instance;
use super::interface::WINDOW;
use super::state::{fmi2 as functions, Function, ModelState};
use crate::model::{Context, Failure, FmuModel, LogMessage};
use crate::types::Status;
use crate::values::{all_finite, first_non_finite};

impl<M: FmuModel> Instance<M> {
    /// Runs one model call (initialisation, a step, direct feedthrough, parameters changed,
    /// a Model Exchange evaluation) on the values, then checks what it computed: the values
    /// a call may write ([`super::Interface::computed`]: outputs, locals, calculated parameters) are
    /// copied before it and scanned after it ([`crate::variables::all_finite`]); a non-finite
    /// one puts them back and is `Error` naming the variable. The model's messages are
    /// logged, its failure is the call's status.
    #[inline]
    pub(crate) fn run_model(
        &mut self,
        f: &Function,
        call: impl FnOnce(&mut M, &mut Context) -> Result<(), Failure>,
    ) -> Status {
        // the call may change the values or the model: a Jacobian kept is stale
        self.jacobian.forget();
        self.save_computed();
        let mut ctx = Context::at(&mut self.core.values, self.core.time);
        ctx.log_events = self.logger.events;
        let result = call(&mut self.core.model, &mut ctx);
        let status = if ctx.messages.is_empty() {
            Status::Ok
        } else {
            let messages = ctx.take_messages();
            self.deliver(&messages)
        };
        if self.audit.is_some() {
            if let Some(index) = self.changed_uncomputed() {
                return self.meddled(f, index);
            }
        }
        match result {
            Ok(()) if self.computed_finite() => status,
            Ok(()) => self.unpublish(f),
            Err(failure) => self.model_failed(f, failure),
        }
    }

    /// Copies the values a model call may change into the roll-back buffer.
    #[inline(always)]
    fn save_computed(&mut self) {
        let numbers = self.core.values.numbers();
        let mut to = self.before.as_mut_slice();
        if let Some(window) = &self.interface.window {
            // a fixed block (two vector moves), whatever the run's length
            if let Some(from) = numbers.get(window.start..window.start + WINDOW) {
                self.before_window.copy_from_slice(from);
            }
        } else {
            match &self.interface.computed[..] {
                // the common table: outputs in one block (no loop, one copy)
                [run] => {
                    if let Some(from) = numbers.get(run.clone()) {
                        if from.len() == to.len() && !copy_short(to, from) {
                            to.copy_from_slice(from);
                        }
                    }
                }
                runs => {
                    for run in runs {
                        let (Some(from), Some((head, tail))) =
                            (numbers.get(run.clone()), to.split_at_mut_checked(run.len()))
                        else {
                            break;
                        };
                        head.copy_from_slice(from);
                        to = tail;
                    }
                }
            }
        }
        if self.interface.computed_texts {
            self.before_texts.clone_from(self.core.values.texts());
        }
        if let Some(all) = &mut self.audit {
            (**all).clone_from(&self.core.values);
        }
    }

    /// Puts back the values [`Instance::save_computed`] copied.
    fn restore_computed(&mut self) {
        let numbers = self.core.values.numbers_mut();
        let mut from = self.before.as_slice();
        if let Some(window) = &self.interface.window {
            if let Some(to) = numbers.get_mut(window.start..window.start + WINDOW) {
                for ((to, from), lane) in to.iter_mut().zip(self.before_window).zip(window.lanes) {
                    if lane {
                        *to = from;
                    }
                }
            }
        } else {
            for run in &self.interface.computed {
                let (Some(to), Some((head, tail))) = (
                    numbers.get_mut(run.clone()),
                    from.split_at_checked(run.len()),
                ) else {
                    break;
                };
                to.copy_from_slice(head);
                from = tail;
            }
        }
        if self.interface.computed_texts {
            self.core.values.texts_mut().clone_from(&self.before_texts);
        }
    }

    /// Whether every value a model call may change is finite (branch-free scan).
    #[inline(always)]
    fn computed_finite(&self) -> bool {
        let numbers = self.core.values.numbers();
        if let Some(window) = &self.interface.window {
            // Branch-free, a few vector instructions: a lane of the run times 0 is ±0 when it
            // is finite and NaN when not; the other lanes are masked to +0 first.
            let Some(xs) = numbers
                .get(window.start..)
                .and_then(|n| n.first_chunk::<WINDOW>())
            else {
                return true;
            };
            let z: [f64; WINDOW] =
                std::array::from_fn(|k| f64::from_bits(xs[k].to_bits() & window.keep[k]) * 0.0);
            // (lanes 0 + 2 and 1 + 3: two vector halves added as they are, no shuffle)
            return (z[0] + z[2]) + (z[1] + z[3]) == 0.0;
        }
        match &self.interface.computed[..] {
            [run] => numbers.get(run.clone()).is_none_or(|xs| match xs.len() {
                // a short run (a scalar filter's outputs) value by value, no lanes to set up
                0..=SHORT_RUN => xs.iter().all(|x| x.is_finite()),
                _ => all_finite(xs),
            }),
            runs => runs
                .iter()
                .all(|run| numbers.get(run.clone()).is_none_or(all_finite)),
        }
    }

    /// Checks, from now on, after every model call that the model wrote only the values it
    /// computes — the contract `Instance::run_model` relies on (parameters and inputs are
    /// the master's) — at the cost of a copy of every value per call: for tests (the
    /// [`crate::harness::Harness`] turns it on; debug builds always do).
    pub fn audit_model_writes(&mut self) {
        self.audit = Some(Box::new(self.core.values.clone()));
    }

    /// Under the audit: the first value outside [`super::Interface::computed`] the last model call
    /// changed.
    #[cold]
    #[inline(never)]
    fn changed_uncomputed(&self) -> Option<usize> {
        let before = self.audit.as_deref()?;
        let (now, was) = (self.core.values.numbers(), before.numbers());
        (0..now.len()).find(|&i| {
            now[i].to_bits() != was[i].to_bits()
                && !self.interface.computed.iter().any(|run| run.contains(&i))
        })
    }

    /// A model call that changed the parameter or input at `index`: every value back to
    /// before the call, `Error` naming the variable (a bug of the model).
    #[cold]
    #[inline(never)]
    fn meddled(&mut self, f: &Function, index: usize) -> Status {
        if let Some(before) = &self.audit {
            self.core.values.clone_from(&**before);
        }
        self.core.state = ModelState::Error;
        let name = self
            .interface
            .info
            .variables
            .get(index)
            .map_or("?", |v| v.name.as_str());
        self.logger.error(&format!(
            "{}: internal error: the model changed variable `{name}` (value reference {index}), a parameter or input that only the master sets",
            f.name
        ));
        Status::Error
    }

    /// Logs the model's messages; the worst status among them.
    #[cold]
    #[inline(never)]
    fn deliver(&self, messages: &[LogMessage]) -> Status {
        let mut status = Status::Ok;
        for m in messages {
            self.logger.log(m.status, m.category, &m.text);
            status = status.max(m.status);
        }
        status
    }

    /// After a model call produced a non-finite value: the values back, `Error` naming the
    /// first such variable.
    #[cold]
    #[inline(never)]
    fn unpublish(&mut self, f: &Function) -> Status {
        let numbers = self.core.values.numbers();
        let found = self.interface.computed.iter().find_map(|run| {
            let (k, x) = first_non_finite(numbers.get(run.clone())?)?;
            Some((run.start + k, x))
        });
        self.restore_computed();
        self.core.state = ModelState::Error;
        let (index, value) = found.unwrap_or((usize::MAX, f64::NAN));
        self.logger.error(&format!(
            "{}: variable `{}` (value reference {index}) came out as {value}: not published (the variables keep their values from before the call; fmi2Reset or fmi2SetFMUstate lead on)",
            f.name,
            self.interface.info.variables.get(index).map_or("?", |v| v.name.as_str())
        ));
        Status::Error
    }

    /// A model call that failed: `Discard` (the instance intact) or `Error` (the instance
    /// in the `Error` state), the cause logged.
    #[cold]
    #[inline(never)]
    fn model_failed(&mut self, f: &Function, failure: Failure) -> Status {
        match failure {
            Failure::Discard(message) => {
                self.logger.log(
                    Status::Discard,
                    Status::Discard.category(),
                    &format!("{}: {message}", f.name),
                );
                Status::Discard
            }
            Failure::Error(message) => {
                self.logger.error(&format!("{}: {message}", f.name));
                self.core.state = ModelState::Error;
                Status::Error
            }
        }
    }

    /// `fmi2DoStep`.
    pub fn do_step(&mut self, current_time: f64, step: f64) -> Status {
        self.do_step_as(&functions::DO_STEP, current_time, step)
    }

    /// `fmi2DoStep` or its FMI 3.0 twin `f`: the arguments checked (a step that is finite,
    /// positive and moves the time, from the current communication point, not past the stop
    /// time), the model's [`FmuModel::check_step`], then the step.
    #[inline]
    pub fn do_step_as(&mut self, f: &Function, current_time: f64, step: f64) -> Status {
        let time = self.core.time;
        let end = current_time + step;
        // `end > current_time` also refuses a NaN, `end < ∞` the rest of a non-finite end
        // (−∞ cannot pass the first)
        let valid = step > 0.0
            && (current_time - time).abs() <= 1e-9 * time.abs().max(1.0)
            && end > current_time
            && end < f64::INFINITY
            && self
                .core
                .stop_time
                .is_none_or(|stop| end <= stop + 1e-9 * stop.abs().max(1.0));
        if !valid {
            return self.reject_step(f, current_time, step);
        }
        let refusal = {
            let ctx = Context::at(&mut self.core.values, current_time);
            self.core.model.check_step(&ctx, current_time, step)
        };
        if let Err(cause) = refusal {
            return self.reject(f, &format!("step refused: {cause}"));
        }
        let status = self.run_model(f, |m, ctx| m.do_step(ctx, current_time, step));
        if status <= Status::Warning {
            self.core.time = end;
            self.core.inputs_changed = false;
        }
        status
    }

    /// The rejection of the arguments of a step [`Instance::do_step_as`] refuses, with the
    /// first reason.
    #[cold]
    #[inline(never)]
    fn reject_step(&self, f: &Function, current_time: f64, step: f64) -> Status {
        let time = self.core.time;
        let end = current_time + step;
        let message = if !step.is_finite() || step <= 0.0 {
            format!("communicationStepSize must be finite and > 0, got {step:.16}")
        } else if !current_time.is_finite()
            || (current_time - time).abs() > 1e-9 * time.abs().max(1.0)
        {
            format!("expected currentCommunicationPoint = {time:.16} but was {current_time:.16}")
        } else if !end.is_finite() {
            format!(
                "the step ends at currentCommunicationPoint + communicationStepSize = {current_time:.16} + {step:.16} = {end}, not a finite time"
            )
        } else if end <= current_time {
            format!(
                "communicationStepSize = {step:.16} is below the time resolution at currentCommunicationPoint = {current_time:.16}: the time would not advance"
            )
        } else {
            let stop = self.core.stop_time.unwrap_or(f64::NAN);
            format!("the step to {end:.16} would pass stopTime = {stop:.16}")
        };
        self.reject(f, &message)
    }
}

/// The longest run of computed values [`Instance`] copies and scans value by value (no call of
/// the library copy, no lanes of [`all_finite`] to set up): a scalar filter's outputs.
const SHORT_RUN: usize = 4;

/// Copies `from` into `to` when both hold the same number of values, at most [`SHORT_RUN`],
/// entry by entry; `false` (nothing copied) otherwise.
#[inline(always)]
fn copy_short(to: &mut [f64], from: &[f64]) -> bool {
    match (to, from) {
        ([a], [x]) => *a = *x,
        ([a, b], [x, y]) => (*a, *b) = (*x, *y),
        ([a, b, c], [x, y, z]) => (*a, *b, *c) = (*x, *y, *z),
        ([a, b, c, d], [x, y, z, w]) => (*a, *b, *c, *d) = (*x, *y, *z, *w),
        _ => return false,
    }
    true
}

#[cfg(test)]
mod short_run_tests {
    use super::*;

    #[test]
    fn short_runs_are_copied_entry_by_entry_and_longer_ones_refused() {
        let from = [1.5, -2.0, f64::NAN, 4.0, 5.0];
        for n in 1..=SHORT_RUN {
            let mut to = [0.0; 5];
            assert!(copy_short(&mut to[..n], &from[..n]), "{n}");
            for (k, (t, f)) in to.iter().zip(from).enumerate() {
                let expected = if k < n { f.to_bits() } else { 0 };
                assert_eq!(t.to_bits(), expected, "{n} {k}");
            }
        }
        let mut to = [0.0; 5];
        assert!(!copy_short(&mut to, &from));
        assert!(!copy_short(&mut to[..2], &from[..3]));
        assert!(!copy_short(&mut to[..0], &from[..0]));
        assert_eq!(to, [0.0; 5]);
    }
}
