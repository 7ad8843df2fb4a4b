//! Model Exchange event indicators are computed when they are read, not at every evaluation:
//! the ramp model (`common/ramp.rs`: one state, twelve indicators, counting its calls) driven
//! through the FMI 2.0 C entry points (in-process harness). An integration loop that reads
//! derivatives alone makes one model call per evaluation; `fmi2GetEventIndicators` and a
//! getter of an indicator's variable see indicators consistent with the states last set; a
//! restored FMU state and a non-finite indicator behave as before. (That none of it
//! allocates: `allocations.rs`.)
#![allow(unsafe_code)]

#[path = "common/ramp.rs"]
mod ramp;

use ramp::{calls, expected, Me, Ramp, DER_X, N, U, X, Z0};
use spurio_export::abi::model_exchange as me;
use spurio_export::fmi2::functions;
use spurio_export::types::*;

#[test]
fn an_integration_loop_reading_derivatives_makes_one_model_call_an_evaluation() {
    let m = Me::new();
    for k in 0..1000 {
        m.set(k as f64 * 1e-3, k as f64);
        assert_eq!(m.derivative(), 1.0);
    }
    assert_eq!(calls(), (1000, 0));
    // the indicators, when asked for: computed once for the states last set
    let mut z = [f64::NAN; N];
    assert_eq!(m.indicators(&mut z), fmi2OK);
    assert_eq!(z, expected(999.0));
    assert_eq!(m.indicators(&mut z), fmi2OK);
    assert_eq!(calls(), (0, 1));
    // a new state: evaluated and computed again when read
    m.set(1.0, 3.0);
    assert_eq!(m.indicators(&mut z), fmi2OK);
    assert_eq!(z, expected(3.0));
    assert_eq!(calls(), (1, 1));
}

#[test]
fn a_getter_of_an_indicator_variable_computes_them_and_one_of_other_variables_does_not() {
    let mut m = Me::new();
    m.set(0.0, 4.0);
    assert_eq!(m.0.real(DER_X as u32), Ok(1.0));
    assert_eq!(m.0.real(X as u32), Ok(4.0));
    assert_eq!(calls(), (1, 0));
    assert_eq!(m.0.real((Z0 + 3) as u32), Ok(1.0));
    assert_eq!(m.0.real((Z0 + 11) as u32), Ok(-7.0));
    assert_eq!(calls(), (0, 1));
    // an input changes the derivative; the indicators are stale until read
    m.0.set_real(&[U as u32], &[2.0]).unwrap();
    assert_eq!(m.derivative(), 2.0);
    m.set(0.5, 5.0);
    let mut out = [0.0; 3];
    m.0.get_real(&[X as u32, (Z0 + 1) as u32, DER_X as u32], &mut out)
        .unwrap();
    assert_eq!(out, [5.0, 4.0, 2.0]);
    assert_eq!(calls(), (2, 1));
}

#[test]
fn a_restored_state_reads_its_own_indicators() {
    let mut m = Me::new();
    m.set(0.0, 2.0);
    assert_eq!(m.derivative(), 1.0);
    // saved with the indicators stale (never read at x = 2)
    let saved = m.0.serialized_state().unwrap();
    m.set(0.1, 9.0);
    let mut z = [0.0; N];
    assert_eq!(m.indicators(&mut z), fmi2OK);
    assert_eq!(z, expected(9.0));
    assert_eq!(m.0.restore_state(&saved), Ok(Status::Ok));
    assert_eq!(m.indicators(&mut z), fmi2OK);
    assert_eq!(z, expected(2.0));
    assert_eq!(m.0.real((Z0 + 1) as u32), Ok(1.0));
}

#[test]
fn a_non_finite_indicator_is_an_error_naming_it_when_read() {
    let m = Me::new();
    m.set(0.0, 7.5);
    // the derivatives do not need the indicators
    assert_eq!(m.derivative(), 1.0);
    let mut z = [-1.0; N];
    assert_eq!(m.indicators(&mut z), fmi2Error);
    assert_eq!(z, [-1.0; N], "nothing published");
    assert!(m.0.logged(&[
        "fmi2GetEventIndicators",
        "event indicator 8 came out as NaN: not published"
    ]));
    // the instance is in state Error
    let f = &functions::SET_TIME;
    assert_eq!(
        unsafe { me::set_time::<Ramp, ()>(m.0.component(), f, 1.0) },
        fmi2Error
    );
}
