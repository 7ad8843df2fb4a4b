//! The inputs the fuzz target `fmu_state` (scripts/fuzz) found defects with, committed in
//! `tests/fuzz/` as it wrote them (first byte: the model, 3 = DKF-rsKF at the crane's
//! dimensions; then the bytes given to `fmi2DeSerializeFMUstate`).

use spurio_export::harness::Harness;
use spurio_export::types::Status;
use spurio_fmu_kalman::{dims_config, DkfRsKfFmu};

/// A DKF-rsKF state whose step counter reads 1e19 (a whole number, but beyond any count of
/// steps): accepted, it made the next `fmi2DoStep` overflow `steps += 1` (a panic, so
/// `fmi2Fatal`, with overflow checks; a silent wrap to 0 without). It is refused now, with
/// `fmi2Error` naming the counter, and the instance steps on from its own state.
#[test]
fn a_state_whose_step_counter_cannot_be_counted_to_is_refused() {
    let input = include_bytes!("fuzz/dkf_rskf_state_step_counter_1e19.bin");
    assert_eq!(input[0], 3, "the DKF-rsKF");
    let mut h = Harness::<DkfRsKfFmu>::new(&dims_config(4, 1, 2)).unwrap();
    h.initialize(0.0).unwrap();
    assert_eq!(h.restore_state(&input[1..]), Err(Status::Error));
    assert!(
        h.logged(&["step counter", "2^53"]),
        "the refusal names the counter: {:?}",
        h.log()
    );
    assert_eq!(h.do_step(0.0, 0.01), Ok(Status::Ok));
}
