//! The Model Exchange instances of a running co-simulation, integrated by the master between
//! communication points (issue 26, "Mixed systems"; docs/engine.md).
//!
//! The instances connected to each other form one group ([`crate::plan::CoupledPlan`]),
//! integrated as **one ODE** over their concatenated states `x = (x₁, …, x_N)` by one
//! [`Stepper`] (OMSimulator's strongly coupled system):
//!
//! ```text
//! ẋᵢ = fᵢ(t, xᵢ, uᵢ),   uᵢ = (outputs of the other members it is connected to at (t, x),
//!                             inputs from outside the group, held from the communication point)
//! ```
//!
//! At every evaluation of the right-hand side the time and the states are set on every
//! member, the outputs that feed other members are read and the connected inputs set in
//! dependency order (an algebraic loop between members is refused when the system is
//! compiled), then the derivatives are read; the event indicators likewise. So a chain of
//! members is not delayed by a communication step. An event of any member is an event of
//! the group: every member enters event mode and iterates until none asks for another
//! iteration; the earliest announced time event of any member is the group's.
//!
//! A group with one member is an ME instance alone. Inputs from outside the group (from
//! Co-Simulation or data instances, or from another group) are set at the communication
//! point and held over the interval; the solver then starts again from the states there
//! ([`Stepper::inputs_changed`]; a group that no outside connection drives goes on without
//! a restart), and the outputs are read at the interval's end like those of a
//! Co-Simulation instance.

use crate::batch::{Batch, Unit};
use crate::coupling::ResolvedInstance;
use crate::fmu::me::MeInstance;
use crate::fmu::{CallError, Experiment, FmuFile, VarType};
use crate::model_exchange::{Advance, EventUpdate, Layout, ModelExchangeCalls, Options, Stepper};
use crate::plan::{CoupledPlan, Op};
use crate::record::NoRecording;

/// Where a group finds its members' instances among the running ones.
pub(crate) trait Members {
    /// The instance at `position` and the values last given to each array of its FMU.
    fn unit(&mut self, position: usize) -> (&mut Unit, &mut [Vec<f64>]);
    /// The instance's name.
    fn name(&self, position: usize) -> &str;
}

/// How a group's members are laid out and connected.
struct Wiring {
    /// The members' positions among the running instances.
    positions: Vec<usize>,
    /// Per member: (first, count) of its states in `x`, of its indicators in `z`.
    states: Vec<(usize, usize)>,
    indicators: Vec<(usize, usize)>,
    /// The outputs read first, then the sets (true) and re-reads (false) in order.
    reads: Vec<Batch>,
    propagation: Vec<(bool, Batch)>,
    name: String,
    fmi3: bool,
}

/// One group of Model Exchange instances with its stepper.
pub(crate) struct Coupled {
    wiring: Wiring,
    stepper: Stepper,
    /// Its step multiple.
    pub(crate) multiple: u64,
    /// Where a member asked to end the run (`terminateSimulation`), if one did.
    terminated: Option<f64>,
    /// Whether inputs are set from outside the group at the communication points.
    driven_from_outside: bool,
    /// Who an event is told of (`--verbose`).
    speakers: Speakers,
}

/// Whom a group's events are told of: a state event by the member whose indicator changed
/// sign (its own indicator number), a time or step event by the group.
struct Speakers {
    group: String,
    /// Per member: its instance name and the range of its indicators in the group's.
    members: Vec<(String, std::ops::Range<usize>)>,
}

impl Speakers {
    /// Tells `event` to the log (shown with `--verbose`): `instance `name`: t = …: state
    /// event (indicator i)`, the time to 17 digits as a single-FMU run prints it.
    fn tell(&self, event: &crate::model_exchange::Event) {
        use crate::model_exchange::EventKind;
        if let EventKind::State { indicator } = event.kind {
            if let Some((name, range)) = self.members.iter().find(|(_, r)| r.contains(&indicator)) {
                let own = EventKind::State {
                    indicator: indicator - range.start,
                };
                log::info!("instance `{name}`: t = {:.17}: {own}", event.time);
                return;
            }
        }
        log::info!("{}: t = {:.17}: {}", self.group, event.time, event.kind);
    }
}

/// The error of member `k` of a group, naming it.
fn of_member(name: &str, e: CallError) -> CallError {
    CallError(format!("instance `{name}`: {}", e.0))
}

impl Coupled {
    /// The group of `plan` over the running instances `members` (`position[i]`: where
    /// instance i of `instances` runs), integrated over [`start`, `stop`].
    pub(crate) fn new<M: Members + ?Sized>(
        plan: &CoupledPlan,
        instances: &[ResolvedInstance],
        position: &[usize],
        members: &mut M,
        (start, stop): (f64, f64),
    ) -> Result<Self, CallError> {
        let mut wiring = Wiring {
            positions: plan.members.iter().map(|&i| position[i]).collect(),
            states: Vec::new(),
            indicators: Vec::new(),
            reads: Vec::new(),
            propagation: Vec::new(),
            name: match plan.members.as_slice() {
                [one] => format!(
                    "instance `{}` ({})",
                    instances[*one].name,
                    instances[*one].fmu.path.display()
                ),
                many => format!(
                    "the Model Exchange instances {} (integrated as one ODE)",
                    many.iter()
                        .map(|&i| format!("`{}`", instances[i].name))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            },
            fmi3: false,
        };
        let (mut n, mut m) = (0, 0);
        for &p in &wiring.positions {
            let name = members.name(p).to_string();
            let me = me_of(members.unit(p).0, &name)?;
            let d = me.description();
            wiring.states.push((n, d.states));
            wiring.indicators.push((m, d.event_indicators));
            n += d.states;
            m += d.event_indicators;
            wiring.fmi3 |= me.is_fmi3();
        }
        let batch = |t: &crate::plan::Transfer, fmu: &FmuFile| {
            let mut b = Batch::new(t, fmu);
            b.member = position[t.member];
            b
        };
        wiring.reads = plan
            .reads
            .iter()
            .map(|t| batch(t, &instances[t.member].fmu))
            .collect();
        wiring.propagation = plan
            .propagation
            .iter()
            .map(|op| match op {
                Op::Set(t) => (true, batch(t, &instances[t.member].fmu)),
                Op::Get(t) => (false, batch(t, &instances[t.member].fmu)),
            })
            .collect();
        let first = &instances[plan.members[0]];
        // One solver for the group: the members' settings agree on the method (the plan
        // checked it); the tightest tolerance and maximum step.
        let tolerance = plan
            .members
            .iter()
            .map(|&i| instances[i].integration.tolerance)
            .fold(f64::INFINITY, f64::min);
        let max_step = plan
            .members
            .iter()
            .filter_map(|&i| instances[i].integration.max_step)
            .reduce(f64::min);
        let options = Options {
            method: first.integration.method,
            tolerance,
            max_step,
            ..Options::new(start, stop, stop - start)
        };
        let layout = Layout {
            states: n,
            event_indicators: m,
            ..Layout::default()
        };
        let stepper = Stepper::new(wiring.name.clone(), wiring.fmi3, &layout, &options);
        let speakers = Speakers {
            group: wiring.name.clone(),
            members: wiring
                .positions
                .iter()
                .zip(&wiring.indicators)
                .map(|(&p, &(first, count))| (members.name(p).to_string(), first..first + count))
                .collect(),
        };
        Ok(Self {
            speakers,
            wiring,
            stepper,
            multiple: u64::from(plan.step_multiple),
            terminated: None,
            driven_from_outside: plan.driven_from_outside,
        })
    }

    /// The first member's position (for the call monitor).
    pub(crate) fn first_position(&self) -> usize {
        self.wiring.positions[0]
    }

    /// After every member left initialisation mode at `t`: the first event iteration and
    /// continuous-time mode.
    pub(crate) fn initialise<M: Members + ?Sized>(
        &mut self,
        members: &mut M,
        buffer: &mut [f64],
        t: f64,
    ) -> Result<(), crate::model_exchange::MeError> {
        let mut view = View {
            members,
            wiring: &mut self.wiring,
            buffer,
        };
        if let Advance::Terminated(end) = self.stepper.initialise(&mut view, t)? {
            self.terminated = Some(end);
        }
        Ok(())
    }

    /// Integrates the group from its time to `t_end` with the inputs as they are set; the
    /// time at which a member asked to end the run, if one did (before or on the way).
    pub(crate) fn advance_to<M: Members + ?Sized>(
        &mut self,
        members: &mut M,
        buffer: &mut [f64],
        t_end: f64,
    ) -> Result<Option<f64>, crate::model_exchange::MeError> {
        if self.terminated.is_some() {
            return Ok(self.terminated);
        }
        let mut view = View {
            members,
            wiring: &mut self.wiring,
            buffer,
        };
        let speakers = &self.speakers;
        let mut tell = |event: &crate::model_exchange::Event| speakers.tell(event);
        let start = if self.driven_from_outside {
            self.stepper.inputs_changed(&mut view, &mut tell)?
        } else {
            Advance::Reached(self.stepper.time())
        };
        let outcome = match start {
            Advance::Reached(_) => {
                self.stepper
                    .advance_to(&mut view, t_end, &mut NoRecording, &mut tell)?
            }
            terminated => terminated,
        };
        if let Advance::Terminated(end) = outcome {
            self.terminated = Some(end);
        }
        Ok(self.terminated)
    }
}

/// The Model Exchange instance of a unit (a group holds no other).
fn me_of<'a>(unit: &'a mut Unit, name: &str) -> Result<&'a mut MeInstance, CallError> {
    match unit {
        Unit::Me(me) => Ok(me),
        Unit::Cs(_) => Err(CallError(format!(
            "instance `{name}` runs as Co-Simulation, not in a Model Exchange group"
        ))),
    }
}

/// A group as one FMU for the stepper: its calls go to every member, the states and
/// indicators concatenated.
struct View<'a, M: Members + ?Sized> {
    members: &'a mut M,
    wiring: &'a mut Wiring,
    /// The exchange's value buffer (the connections' sources have their slots there).
    buffer: &'a mut [f64],
}

/// Calls `f` on every member at `positions` of `members` (with its index in the group),
/// naming a failing one.
fn each<M: Members + ?Sized>(
    members: &mut M,
    positions: &[usize],
    mut f: impl FnMut(usize, &mut MeInstance) -> Result<(), CallError>,
) -> Result<(), CallError> {
    for (k, &p) in positions.iter().enumerate() {
        let result = match members.unit(p).0 {
            Unit::Me(me) => f(k, me),
            Unit::Cs(_) => Err(CallError("runs as Co-Simulation".into())),
        };
        if let Err(e) = result {
            return Err(of_member(members.name(p), e));
        }
    }
    Ok(())
}

impl<M: Members + ?Sized> View<'_, M> {
    /// Calls `f` on every member (with its index in the group), naming a failing one.
    fn each(
        &mut self,
        f: impl FnMut(usize, &mut MeInstance) -> Result<(), CallError>,
    ) -> Result<(), CallError> {
        each(self.members, &self.wiring.positions, f)
    }

    /// Calls `f` on every member with its part of `values`: laid out as the states
    /// (`states`) or as the event indicators.
    fn each_part(
        &mut self,
        states: bool,
        values: &mut [f64],
        mut f: impl FnMut(&mut MeInstance, &mut [f64]) -> Result<(), CallError>,
    ) -> Result<(), CallError> {
        let Wiring {
            positions,
            states: state_parts,
            indicators,
            ..
        } = &*self.wiring;
        let parts = if states { state_parts } else { indicators };
        each(self.members, positions, |k, me| {
            f(me, part(values, parts, k))
        })
    }

    /// The outputs feeding other members read, the connected inputs set in order.
    fn propagate(&mut self) -> Result<(), CallError> {
        let Self {
            members,
            wiring,
            buffer,
        } = self;
        for batch in &mut wiring.reads {
            let (unit, _) = members.unit(batch.member);
            if let Err(e) = batch.get(unit, buffer) {
                return Err(of_member(members.name(batch.member), e));
            }
        }
        for (set, batch) in &mut wiring.propagation {
            let (unit, held) = members.unit(batch.member);
            let result = if *set {
                batch.set(unit, buffer, held)
            } else {
                batch.get(unit, buffer)
            };
            if let Err(e) = result {
                return Err(of_member(members.name(batch.member), e));
            }
        }
        Ok(())
    }
}

/// `parts[k]`'s slice of `all`.
fn part<'a, T>(all: &'a mut [T], parts: &[(usize, usize)], k: usize) -> &'a mut [T] {
    let (first, count) = parts[k];
    &mut all[first..first + count]
}

impl<M: Members + ?Sized> ModelExchangeCalls for View<'_, M> {
    fn name(&self) -> String {
        self.wiring.name.clone()
    }

    fn is_fmi3(&self) -> bool {
        self.wiring.fmi3
    }

    // The exchange sets up, initialises and reads the members one by one.
    fn setup_experiment(&mut self, _: Experiment) -> Result<(), CallError> {
        Ok(())
    }

    fn set(&mut self, _: VarType, _: &[u32], _: &[f64]) -> Result<(), CallError> {
        Err(CallError(
            "a group's values are set member by member".into(),
        ))
    }

    fn get(&mut self, _: VarType, _: &[u32], _: &mut [f64]) -> Result<(), CallError> {
        Err(CallError(
            "a group's values are read member by member".into(),
        ))
    }

    fn enter_initialization_mode(&mut self, _: Experiment) -> Result<(), CallError> {
        Ok(())
    }

    fn exit_initialization_mode(&mut self) -> Result<(), CallError> {
        Ok(())
    }

    fn enter_event_mode(&mut self) -> Result<(), CallError> {
        self.each(|_, me| me.enter_event_mode())
    }

    /// One round of the event iteration: the values propagated between the members, then
    /// every member's update; another round when any asks for one.
    fn update_discrete_states(&mut self) -> Result<EventUpdate, CallError> {
        self.propagate()?;
        let mut all = EventUpdate::default();
        self.each(|_, me| {
            let u = me.update_discrete_states()?;
            all.discrete_states_need_update |= u.discrete_states_need_update;
            all.terminate_simulation |= u.terminate_simulation;
            all.nominals_changed |= u.nominals_changed;
            all.values_changed |= u.values_changed;
            all.next_event_time = match (all.next_event_time, u.next_event_time) {
                (Some(a), Some(b)) => Some(a.min(b)),
                (a, b) => a.or(b),
            };
            Ok(())
        })?;
        Ok(all)
    }

    fn enter_continuous_time_mode(&mut self) -> Result<(), CallError> {
        self.each(|_, me| me.enter_continuous_time_mode())
    }

    fn completed_integrator_step(&mut self) -> Result<(bool, bool), CallError> {
        let (mut enter, mut terminate) = (false, false);
        self.each(|_, me| {
            let (e, t) = me.completed_integrator_step()?;
            enter |= e;
            terminate |= t;
            Ok(())
        })?;
        Ok((enter, terminate))
    }

    fn set_time(&mut self, time: f64) -> Result<(), CallError> {
        self.each(|_, me| me.set_time(time))
    }

    fn set_continuous_states(&mut self, x: &[f64]) -> Result<(), CallError> {
        let Wiring {
            positions, states, ..
        } = &*self.wiring;
        each(self.members, positions, |k, me| {
            let (first, count) = states[k];
            me.set_continuous_states(&x[first..first + count])
        })
    }

    fn get_continuous_states(&mut self, x: &mut [f64]) -> Result<(), CallError> {
        self.each_part(true, x, |me, x| me.get_continuous_states(x))
    }

    fn get_nominals(&mut self, nominals: &mut [f64]) -> Result<(), CallError> {
        self.each_part(true, nominals, |me, n| me.get_nominals(n))
    }

    /// The derivatives of every member, its connected inputs set from the others' outputs
    /// at the time and states set.
    fn get_derivatives(&mut self, dx: &mut [f64]) -> Result<(), CallError> {
        self.propagate()?;
        self.each_part(true, dx, |me, dx| me.get_derivatives(dx))
    }

    fn get_event_indicators(&mut self, z: &mut [f64]) -> Result<(), CallError> {
        self.propagate()?;
        self.each_part(false, z, |me, z| me.get_event_indicators(z))
    }

    /// A group's Jacobian has the blocks of its connections, which no member gives: the
    /// solver differentiates by differences; a member alone gives its own.
    fn directional_derivative(&mut self, seed: &[f64], out: &mut [f64]) -> Result<bool, CallError> {
        if self.wiring.positions.len() != 1 {
            return Ok(false);
        }
        let mut given = false;
        self.each(|_, me| {
            given = me.directional_derivative(seed, out)?;
            Ok(())
        })?;
        Ok(given)
    }

    fn terminate(&mut self) -> Result<(), CallError> {
        self.each(|_, me| me.terminate())
    }
}
