//! The driver on a model written here (no FMU): `ẋ = −1` from `x = 1`, one event indicator
//! `z = x − 0.5` (a state event at t = 0.5), and the misbehaviours an FMU can show: failing or
//! NaN derivatives, an indicator that chatters, an event iteration that never settles. Each
//! ends in an error naming the FMU, the call and the time; nothing hangs.

use super::*;
use crate::record::TimeSeries;

#[derive(Debug, Clone, Copy, PartialEq)]
enum Misbehaviour {
    None,
    NanAfter(f64),
    ErrorAfter(f64),
    /// Every event puts the state back just above the indicator's zero.
    Chatter,
    /// Every event iteration after the first asks for another one.
    NeverSettles,
    /// Every event puts the state back 10 ns of time above the indicator's zero: events
    /// 10 ns apart, time moving on, the end 5·10⁷ events away.
    Creeps,
}

struct Model {
    t: f64,
    x: f64,
    misbehaviour: Misbehaviour,
    events: usize,
}

impl Model {
    fn new(misbehaviour: Misbehaviour) -> Self {
        Self {
            t: 0.0,
            x: 1.0,
            misbehaviour,
            events: 0,
        }
    }
}

impl ModelExchangeCalls for Model {
    fn name(&self) -> String {
        "Model.fmu (instance `m`)".into()
    }
    fn is_fmi3(&self) -> bool {
        false
    }
    fn setup_experiment(&mut self, _: Experiment) -> Result<(), CallError> {
        Ok(())
    }
    fn set(&mut self, _: VarType, _: &[u32], _: &[f64]) -> Result<(), CallError> {
        Ok(())
    }
    fn get(&mut self, _: VarType, _: &[u32], out: &mut [f64]) -> Result<(), CallError> {
        out.fill(self.x);
        Ok(())
    }
    fn enter_initialization_mode(&mut self, _: Experiment) -> Result<(), CallError> {
        Ok(())
    }
    fn exit_initialization_mode(&mut self) -> Result<(), CallError> {
        Ok(())
    }
    fn enter_event_mode(&mut self) -> Result<(), CallError> {
        Ok(())
    }
    fn update_discrete_states(&mut self) -> Result<EventUpdate, CallError> {
        self.events += 1;
        if self.misbehaviour == Misbehaviour::Chatter && self.t > 0.0 {
            self.x = 0.5 + 1e-15;
        }
        if self.misbehaviour == Misbehaviour::Creeps && self.t > 0.0 {
            self.x = 0.5 + 1e-8;
        }
        Ok(EventUpdate {
            discrete_states_need_update: self.misbehaviour == Misbehaviour::NeverSettles
                && self.t > 0.0,
            values_changed: matches!(
                self.misbehaviour,
                Misbehaviour::Chatter | Misbehaviour::Creeps
            ),
            ..EventUpdate::default()
        })
    }
    fn enter_continuous_time_mode(&mut self) -> Result<(), CallError> {
        Ok(())
    }
    fn completed_integrator_step(&mut self) -> Result<(bool, bool), CallError> {
        Ok((false, false))
    }
    fn set_time(&mut self, time: f64) -> Result<(), CallError> {
        self.t = time;
        Ok(())
    }
    fn set_continuous_states(&mut self, x: &[f64]) -> Result<(), CallError> {
        self.x = x[0];
        Ok(())
    }
    fn get_continuous_states(&mut self, x: &mut [f64]) -> Result<(), CallError> {
        x[0] = self.x;
        Ok(())
    }
    fn get_nominals(&mut self, nominals: &mut [f64]) -> Result<(), CallError> {
        nominals.fill(1.0);
        Ok(())
    }
    fn get_derivatives(&mut self, dx: &mut [f64]) -> Result<(), CallError> {
        dx[0] = match self.misbehaviour {
            Misbehaviour::NanAfter(t) if self.t > t => f64::NAN,
            Misbehaviour::ErrorAfter(t) if self.t > t => return Err(CallError("fmi2Error".into())),
            _ => -1.0,
        };
        Ok(())
    }
    fn get_event_indicators(&mut self, z: &mut [f64]) -> Result<(), CallError> {
        z[0] = self.x - 0.5;
        Ok(())
    }
    fn directional_derivative(&mut self, _: &[f64], _: &mut [f64]) -> Result<bool, CallError> {
        Ok(false)
    }
    fn terminate(&mut self) -> Result<(), CallError> {
        Ok(())
    }
}

fn layout() -> Layout {
    Layout {
        states: 1,
        event_indicators: 1,
        recorded: vec![("x".into(), VarType::Real, 0)],
        start_values: Vec::new(),
    }
}

fn run(misbehaviour: Misbehaviour, method: Method) -> (Result<Summary, MeError>, Vec<Event>) {
    let mut model = Model::new(misbehaviour);
    let mut events = Vec::new();
    let options = Options {
        method,
        ..Options::new(0.0, 1.0, 0.1)
    };
    let result = simulate(
        &mut model,
        &layout(),
        &options,
        &mut TimeSeries::default(),
        &mut |e| events.push(*e),
    );
    (result, events)
}

#[test]
fn a_state_event_is_located_to_the_stated_tolerance() {
    for method in [Method::Dopri5, Method::Rodas3] {
        let (result, events) = run(Misbehaviour::None, method);
        let summary = result.unwrap();
        assert_eq!(summary.state_events, 1);
        let t = events[0].time;
        // located to the bracket, at its right end: the indicator has changed sign there
        assert!(
            t >= 0.5 && t - 0.5 <= event_time_tolerance(0.5),
            "{method}: {t:e}"
        );
        assert_eq!(summary.end_time, 1.0);
    }
}

#[test]
fn failing_or_nan_derivatives_are_errors_naming_the_call_and_the_time() {
    let (result, _) = run(Misbehaviour::ErrorAfter(0.3), Method::Dopri5);
    let e = result.unwrap_err();
    let MeError::Call { call, time, .. } = &e else {
        panic!("{e}")
    };
    assert_eq!(*call, "fmi2GetDerivatives");
    assert!(*time > 0.3 && *time < 0.6, "{e}");
    assert!(e.to_string().contains("Model.fmu"), "{e}");
    for method in [Method::Dopri5, Method::Rodas3] {
        let (result, _) = run(Misbehaviour::NanAfter(0.3), method);
        let e = result.unwrap_err();
        let MeError::NotFinite { call, time, .. } = &e else {
            panic!("{e}")
        };
        assert_eq!(*call, "fmi2GetDerivatives");
        assert!((*time - 0.3).abs() < 1e-6, "{e}");
        eprintln!("{e}");
    }
}

#[test]
fn chattering_and_an_unsettled_event_iteration_are_errors_and_nothing_hangs() {
    let start = std::time::Instant::now();
    let (result, events) = run(Misbehaviour::Chatter, Method::Dopri5);
    let e = result.unwrap_err();
    eprintln!("{e}");
    let MeError::Chattering {
        time, events: n, ..
    } = &e
    else {
        panic!("{e}")
    };
    assert!((*time - 0.5).abs() < 1e-9, "{e}");
    assert_eq!(*n, 101);
    assert_eq!(events.len(), 100, "the one beyond the bound is not handled");
    assert!(e.to_string().contains("fmi2GetEventIndicators"), "{e}");
    assert!(e.to_string().contains("Model.fmu"), "{e}");
    let (result, _) = run(Misbehaviour::NeverSettles, Method::Dopri5);
    let e = result.unwrap_err();
    eprintln!("{e}");
    let MeError::EventIteration { call, time, .. } = &e else {
        panic!("{e}")
    };
    assert_eq!(*call, "fmi2NewDiscreteStates");
    assert!((*time - 0.5).abs() < 1e-9, "{e}");
    assert!(start.elapsed().as_secs_f64() < 5.0);
}

#[test]
fn events_in_a_row_closer_than_a_microsecond_are_chattering_and_end_at_once() {
    let start = std::time::Instant::now();
    let (result, events) = run(Misbehaviour::Creeps, Method::Dopri5);
    let e = result.unwrap_err();
    // (first event, last event, how many) of the run stopped.
    let (from, time, n) = match &e {
        MeError::CloseEvents {
            from, time, events, ..
        } => (from, time, events),
        other => panic!("not CloseEvents: {other}"),
    };
    assert_eq!(*n, 10_001);
    assert_eq!(
        events.len(),
        10_000,
        "the one beyond the bound is not handled"
    );
    // 10⁴ events 10 ns apart from the first at 0.5.
    assert!(
        (*from - 0.5).abs() < 1e-9 && (*time - 0.5 - 1e-4).abs() < 1e-7,
        "{e}"
    );
    assert!(e.to_string().contains("Model.fmu"), "{e}");
    assert!(start.elapsed().as_secs_f64() < 5.0);
}
