//! The export layer driven through its C entry points (in-process harness) with a toy model:
//! state masks, argument checks, panics caught as fmi2Fatal, direct feedthrough.

use spurio_export::harness::Harness;
use spurio_export::types::Status;
use spurio_export::{
    ByteReader, ByteWriter, Cause, Config, Context, Failure, FmuModel, ModelInfo, Variable,
};

/// y = integral of u (Euler per step); z = 2 u (direct feedthrough); panics when u = 13.
#[derive(Clone, Debug, Default)]
struct Integrator {
    state: f64,
}

const U: usize = 0;
const Y: usize = 1;
const Z: usize = 2;
const Y0: usize = 3;

impl FmuModel for Integrator {
    fn describe(_config: &Config) -> Result<ModelInfo, Cause> {
        Ok(ModelInfo::new(
            "Integrator",
            "test model",
            vec![
                Variable::input("u", 0.0),
                Variable::output("y"),
                Variable::output("z").depends_on(&[U]),
                Variable::parameter("y0", 0.0).min(-10.0).max(10.0),
            ],
            None,
            Config::new(),
        ))
    }
    fn create(_info: &ModelInfo) -> Result<Self, Cause> {
        Ok(Self::default())
    }
    fn initialize(&mut self, ctx: &mut Context) -> Result<(), Failure> {
        self.state = ctx.values.real(Y0);
        ctx.values.set_real(Y, self.state);
        self.update_outputs(ctx)
    }
    fn do_step(&mut self, ctx: &mut Context, _time: f64, step: f64) -> Result<(), Failure> {
        let u = ctx.values.real(U);
        if u == 13.0 {
            panic!("unlucky input");
        }
        if u < -100.0 {
            return Err(Failure::error("u below -100 is not integrable"));
        }
        self.state += step * u;
        ctx.values.set_real(Y, self.state);
        self.update_outputs(ctx)
    }
    fn update_outputs(&mut self, ctx: &mut Context) -> Result<(), Failure> {
        let u = ctx.values.real(U);
        ctx.values.set_real(Z, 2.0 * u);
        Ok(())
    }
    fn save_state(&self, out: &mut ByteWriter) {
        out.put_f64(self.state);
    }
    fn load_state(&mut self, input: &mut ByteReader) -> Result<(), Cause> {
        self.state = input.f64()?;
        Ok(())
    }
}

fn errors(h: &Harness<Integrator>) -> Vec<String> {
    h.log()
        .into_iter()
        .filter(|(s, _, _)| *s >= Status::Error)
        .map(|(_, _, t)| t)
        .collect()
}

/// The last message logged with status Error or worse ("" when there is none).
fn last_error(h: &Harness<Integrator>) -> String {
    errors(h).pop().unwrap_or_default()
}

#[test]
fn stepping_before_initialisation_is_an_illegal_call_sequence() {
    let mut h = Harness::<Integrator>::new(&Config::new()).unwrap();
    assert_eq!(h.do_step(0.0, 0.1), Err(Status::Error));
    let e = errors(&h);
    assert!(
        e[0].contains("fmi2DoStep: illegal call sequence") && e[0].contains("Instantiated"),
        "{e:?}"
    );
    // nothing was lost: the normal sequence still works
    h.initialize(0.0).unwrap();
    h.set_real(&[U as u32], &[1.0]).unwrap();
    h.do_step(0.0, 0.5).unwrap();
    assert_eq!(h.real(Y as u32).unwrap(), 0.5);
}

#[test]
fn rejected_sets_change_nothing_and_say_why() {
    let mut h = Harness::<Integrator>::new(&Config::new()).unwrap();
    assert_eq!(h.set_real(&[Y0 as u32], &[11.0]), Err(Status::Error));
    assert!(last_error(&h).contains("`y0` = 11 is above its maximum 10"));
    h.set_real(&[Y0 as u32], &[2.0]).unwrap();
    h.initialize(0.0).unwrap();
    // a batch with one bad value sets none of them
    assert_eq!(h.set_real(&[U as u32, 99], &[3.0, 1.0]), Err(Status::Error));
    assert!(last_error(&h).contains("unknown value reference 99"));
    assert_eq!(h.set_real(&[U as u32], &[f64::NAN]), Err(Status::Error));
    assert!(last_error(&h).contains("`u`") && last_error(&h).contains("NaN"));
    assert_eq!(h.set_real(&[Y0 as u32], &[1.0]), Err(Status::Error));
    assert!(last_error(&h).contains("fixed parameter"));
    assert_eq!(h.set_real(&[Y as u32], &[1.0]), Err(Status::Error));
    assert!(last_error(&h).contains("an output"));
    let mut v = [0.0; 2];
    h.get_real(&[U as u32, Y as u32], &mut v).unwrap();
    assert_eq!(v, [0.0, 2.0]);
}

#[test]
fn direct_feedthrough_outputs_follow_their_inputs_between_steps() {
    let mut h = Harness::<Integrator>::new(&Config::new()).unwrap();
    h.initialize(0.0).unwrap();
    h.set_real(&[U as u32], &[4.0]).unwrap();
    assert_eq!(h.real(Z as u32).unwrap(), 8.0);
    assert_eq!(
        h.real(Y as u32).unwrap(),
        0.0,
        "the state does not advance without a step"
    );
}

#[test]
fn a_panic_is_caught_and_reported_as_fatal() {
    let mut h = Harness::<Integrator>::new(&Config::new()).unwrap();
    h.initialize(0.0).unwrap();
    h.set_real(&[U as u32], &[13.0]).unwrap();
    assert_eq!(h.do_step(0.0, 0.1), Err(Status::Fatal));
    let log = h.log();
    let (status, category, text) = log.last().unwrap();
    assert_eq!(*status, Status::Fatal);
    assert_eq!(category, "logStatusFatal");
    assert!(
        text.contains("fmi2DoStep: internal error: unlucky input"),
        "{text}"
    );
    // a fatal instance refuses further steps
    assert_eq!(h.do_step(0.1, 0.1), Err(Status::Error));
}

#[test]
fn a_model_error_moves_the_instance_to_the_error_state() {
    let mut h = Harness::<Integrator>::new(&Config::new()).unwrap();
    h.initialize(0.0).unwrap();
    h.set_real(&[U as u32], &[-200.0]).unwrap();
    assert_eq!(h.do_step(0.0, 0.1), Err(Status::Error));
    assert!(last_error(&h).contains("fmi2DoStep: u below -100 is not integrable"));
    assert_eq!(h.do_step(0.0, 0.1), Err(Status::Error));
    assert!(last_error(&h).contains("illegal call sequence") && last_error(&h).contains("Error"));
    // outputs can still be read in the Error state
    assert_eq!(h.real(Y as u32).unwrap(), 0.0);
}

#[test]
fn communication_point_and_step_size_are_checked() {
    let mut h = Harness::<Integrator>::new(&Config::new()).unwrap();
    h.initialize(1.0).unwrap();
    assert_eq!(h.do_step(0.0, 0.1), Err(Status::Error));
    assert!(last_error(&h).contains("expected currentCommunicationPoint = 1"));
    assert_eq!(h.do_step(1.0, 0.0), Err(Status::Error));
    assert!(last_error(&h).contains("communicationStepSize must be finite and > 0"));
    h.do_step(1.0, 0.1).unwrap();
    h.do_step(1.1, 0.1).unwrap();
}
