//! The export layer's FMI 2.0 Co-Simulation front driven through its C entry points
//! (in-process harness) with the shared toy model ([`common::toy`]):
//! state masks, argument checks, panics caught as fmi2Fatal (their text on the logger only),
//! direct feedthrough, refused steps, no non-finite value published, time overflow, and the
//! checks of a serialized FMU state.

mod common;

use common::toy::{Toy, U, Y, Y0, Z};
use spurio_export::harness::Harness;
use spurio_export::types::Status;
use spurio_export::{Config, FmuModel};

/// A toy instance initialized at `start_time`.
fn started(start_time: f64) -> Harness<Toy> {
    let mut h = Harness::<Toy>::new(&Config::new()).unwrap();
    h.initialize(start_time).unwrap();
    h
}

fn errors(h: &Harness<Toy>) -> Vec<String> {
    h.log()
        .into_iter()
        .filter(|(s, _, _)| *s >= Status::Error)
        .map(|(_, _, t)| t)
        .collect()
}

/// The last message logged with status Error or worse ("" when there is none).
fn last_error(h: &Harness<Toy>) -> String {
    errors(h).pop().unwrap_or_default()
}

#[test]
fn stepping_before_initialisation_is_an_illegal_call_sequence() {
    let mut h = Harness::<Toy>::new(&Config::new()).unwrap();
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
    let mut h = Harness::<Toy>::new(&Config::new()).unwrap();
    assert_eq!(h.set_real(&[Y0 as u32], &[11.0]), Err(Status::Error));
    assert!(last_error(&h).contains("`y0` = 11 is above its maximum 10"));
    h.set_real(&[Y0 as u32], &[2.0]).unwrap();
    h.initialize(0.0).unwrap();
    // a batch with one bad value sets none of them
    assert_eq!(h.set_real(&[U as u32, 99], &[3.0, 1.0]), Err(Status::Error));
    assert!(last_error(&h).contains("unknown value reference 99"));
    assert_eq!(h.set_real(&[U as u32], &[f64::NAN]), Err(Status::Error));
    assert!(last_error(&h).contains("`u[1]`") && last_error(&h).contains("NaN"));
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
    let mut h = started(0.0);
    h.set_real(&[U as u32], &[4.0]).unwrap();
    assert_eq!(h.real(Z as u32).unwrap(), 4.0);
    assert_eq!(
        h.real(Y as u32).unwrap(),
        0.0,
        "the state does not advance without a step"
    );
}

#[test]
fn a_panic_is_caught_and_reported_as_fatal() {
    let mut h = started(0.0);
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
    let mut h = started(0.0);
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
    let mut h = started(1.0);
    assert_eq!(h.do_step(0.0, 0.1), Err(Status::Error));
    assert!(last_error(&h).contains("expected currentCommunicationPoint = 1"));
    assert_eq!(h.do_step(1.0, 0.0), Err(Status::Error));
    assert!(last_error(&h).contains("communicationStepSize must be finite and > 0"));
    h.do_step(1.0, 0.1).unwrap();
    h.do_step(1.1, 0.1).unwrap();
}

#[test]
fn a_step_the_model_refuses_changes_nothing() {
    let mut h = started(0.0);
    h.set_real(&[U as u32], &[1.0]).unwrap();
    assert_eq!(h.do_step(0.0, 2000.0), Err(Status::Error));
    assert!(
        last_error(&h).contains("fmi2DoStep: step refused: a step of 2000 s is longer than 1000 s"),
        "{}",
        last_error(&h)
    );
    // still StepComplete at t = 0 with y = 0: the next step is taken from there
    assert_eq!(h.real(Y as u32).unwrap(), 0.0);
    h.do_step(0.0, 3.0).unwrap();
    assert_eq!(h.real(Y as u32).unwrap(), 3.0);
}

#[test]
fn a_non_finite_result_is_an_error_and_is_not_published() {
    let mut h = started(0.0);
    h.set_real(&[U as u32], &[1.0]).unwrap();
    h.do_step(0.0, 1.0).unwrap();
    // 1e308 · 10 overflows: y would be +inf
    h.set_real(&[U as u32], &[1e308]).unwrap();
    assert_eq!(h.do_step(1.0, 10.0), Err(Status::Error));
    let e = last_error(&h);
    assert!(
        e.contains(
            "fmi2DoStep: variable `y[1]` (value reference 2) came out as inf: not published"
        ),
        "{e}"
    );
    // the last published values stay readable (Error state), the time did not advance
    assert_eq!(h.real(Y as u32).unwrap(), 1.0);
    assert_eq!(h.real(Z as u32).unwrap(), 1.0);
    assert_eq!(h.do_step(11.0, 1.0), Err(Status::Error));
    assert!(last_error(&h).contains("not allowed in state Error"));
    // fmi2Reset leads on
    h.reset().unwrap();
    h.initialize(0.0).unwrap();
    assert_eq!(h.real(Y as u32).unwrap(), 0.0);
}

#[test]
fn a_step_whose_end_is_not_a_finite_time_is_rejected() {
    let mut h = started(1e308);
    assert_eq!(h.do_step(1e308, 1e308), Err(Status::Error));
    assert!(
        last_error(&h).contains("= inf, not a finite time"),
        "{}",
        last_error(&h)
    );
    assert_eq!(h.last_successful_time().unwrap(), 1e308);
    // a step below the time resolution at 1e308 would not advance the time
    assert_eq!(h.do_step(1e308, 1.0), Err(Status::Error));
    assert!(last_error(&h).contains("below the time resolution"));
    // the communication point is still checked (time stayed finite)
    assert_eq!(h.do_step(0.0, 1.0), Err(Status::Error));
    assert!(last_error(&h).contains("expected currentCommunicationPoint = 1"));
    // a finite end passes the time checks (and reaches the model's own refusal)
    assert_eq!(h.do_step(1e308, 1e307), Err(Status::Error));
    assert!(last_error(&h).contains("step refused"));
    assert_eq!(h.last_successful_time().unwrap(), 1e308);
}

#[test]
fn an_infinite_stop_time_is_rejected() {
    let mut h = Harness::<Toy>::new(&Config::new()).unwrap();
    assert_eq!(
        h.setup_experiment(0.0, Some(f64::INFINITY)),
        Err(Status::Error)
    );
    assert!(last_error(&h).contains("stopTime = inf must be finite"));
    h.setup_experiment(0.0, Some(1e12)).unwrap();
}

/// Where the fields of a serialized state of [`Toy`] start: the header strings
/// (format, model identifier, GUID), then the state-machine index, time, stop time, the
/// inputs-changed flag, the value count and the values.
struct Layout {
    state_index: usize,
    time: usize,
    stop: usize,
    values: usize,
}

fn layout() -> Layout {
    let guid = Toy::describe(&Config::new()).unwrap().guid;
    let header = [
        8 + "spurio-fmu-state/2".len(),
        8 + "Toy".len(),
        8 + guid.len(),
    ];
    let state_index = header.iter().sum::<usize>();
    let time = state_index + 8;
    let stop = time + 8 + 1;
    let values = stop + 8 + 1 + 8;
    Layout {
        state_index,
        time,
        stop,
        values,
    }
}

/// Where `y0` starts among the serialized values: nine Reals before it (u, y, z, P), the
/// Integer `N` (4 bytes) and the Boolean `positive` (1 byte).
const Y0_OFFSET: usize = 9 * 8 + 4 + 1;

fn put_f64(bytes: &mut [u8], at: usize, x: f64) {
    bytes[at..at + 8].copy_from_slice(&x.to_le_bytes());
}

#[test]
fn a_serialized_state_is_validated_before_it_is_accepted() {
    let mut h = Harness::<Toy>::new(&Config::new()).unwrap();
    h.set_real(&[Y0 as u32], &[1.5]).unwrap();
    h.setup_experiment(0.0, Some(100.0)).unwrap();
    h.enter_initialization_mode().unwrap();
    h.exit_initialization_mode().unwrap();
    h.set_real(&[U as u32], &[2.0]).unwrap();
    h.do_step(0.0, 1.0).unwrap();
    let good = h.serialized_state().unwrap();
    let at = layout();
    assert_eq!(&good[at.values..at.values + 8], &2.0f64.to_le_bytes()); // u
    assert_eq!(&good[at.values + 16..at.values + 24], &3.5f64.to_le_bytes()); // y[1]

    let corrupt = |edit: &dyn Fn(&mut Vec<u8>)| {
        let mut bytes = good.clone();
        edit(&mut bytes);
        bytes
    };
    let mut other_version = good.clone();
    other_version[8 + "spurio-fmu-state/".len()] = b'1';
    let mut other_model = good.clone();
    other_model[16 + "spurio-fmu-state/2".len()] = b'J';
    let mut cases: Vec<(&str, Vec<u8>, &str)> = vec![
        ("version", other_version, "of format spurio-fmu-state/1"),
        ("model", other_model, "by model Joy, this FMU is Toy"),
        (
            "not a state",
            b"hello".to_vec(),
            "not a serialized spurio FMU state",
        ),
        ("truncated", good[..good.len() - 3].to_vec(), "truncated"),
        ("left over", corrupt(&|b| b.push(0)), "1 bytes left over"),
        (
            "NaN time",
            corrupt(&|b| put_f64(b, at.time, f64::NAN)),
            "its time NaN",
        ),
        (
            "inf time",
            corrupt(&|b| put_f64(b, at.time, f64::INFINITY)),
            "its time inf",
        ),
        (
            "stop before time",
            corrupt(&|b| put_f64(b, at.stop, 0.5)),
            "its stop time 0.5",
        ),
        (
            "NaN value",
            corrupt(&|b| put_f64(b, at.values + 16, f64::NAN)),
            "`y[1]` = NaN",
        ),
        (
            "out of bounds",
            corrupt(&|b| put_f64(b, at.values + Y0_OFFSET, 11.0)),
            "`y0` = 11",
        ),
        (
            "model part",
            corrupt(&|b| {
                let n = b.len();
                put_f64(b, n - 8, f64::NEG_INFINITY)
            }),
            "the toy's state -inf is not finite",
        ),
    ];
    // the state machine's StartAndEnd, StepInProgress, Fatal and a code that is no state
    let machine_states = [0u8, 4, 9, 77].map(|code| {
        let reason = format!("state machine state {code}");
        (corrupt(&|b| b[at.state_index] = code), reason)
    });
    for (bytes, reason) in &machine_states {
        cases.push(("machine state", bytes.clone(), reason.as_str()));
    }
    for (case, bytes, reason) in cases {
        assert_eq!(
            h.restore_state(&bytes),
            Err(Status::Error),
            "{case}: {reason}"
        );
        let e = last_error(&h);
        assert!(
            e.contains("fmi2DeSerializeFMUstate") && e.contains(reason),
            "{case}: {e}"
        );
    }
    // every rejection left the instance as it was
    assert_eq!(h.real(Y as u32).unwrap(), 3.5);
    h.do_step(1.0, 1.0).unwrap();
    assert_eq!(h.real(Y as u32).unwrap(), 5.5);
    // and the good bytes restore the saved point
    h.restore_state(&good).unwrap();
    assert_eq!(h.real(Y as u32).unwrap(), 3.5);
    assert_eq!(h.last_successful_time().unwrap(), 1.0);
}

/// Run by [`a_panic_prints_nothing_on_stderr`] in a child process: a panicking step.
#[test]
fn panicking_step_child() {
    if std::env::var_os("SPURIO_PANIC_CHILD").is_none() {
        return;
    }
    let mut h = started(0.0);
    h.set_real(&[U as u32], &[13.0]).unwrap();
    assert_eq!(h.do_step(0.0, 0.1), Err(Status::Fatal));
    let (_, _, text) = h.log().pop().unwrap();
    assert!(
        text.contains("internal error: unlucky input (at "),
        "{text}"
    );
    assert!(text.contains("toy.rs"), "{text}");
    eprintln!("child done");
}

#[test]
fn a_panic_prints_nothing_on_stderr() {
    common::assert_child_prints_only_its_line("panicking_step_child");
}
