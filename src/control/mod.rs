//! Controllers of the papers (docs/controllers.md §2.13–§2.14): pole placement and adaptive state
//! feedback (paper 000 §IV–VI, eqs 8–15, Fig. 6).
//!
//! * [`pole_placement`]: reachability matrix `𝒞 = [B  A B  …  A^{n−1}B]` (eq. 14) and
//!   Ackermann's formula `L = [0 … 0 1] 𝒞⁻¹ φ(A)` (eq. 15), single-input, with typed errors;
//!   continuous-to-discrete pole mapping `z = e^{s Ts}`.
//! * [`state_feedback`]: the saturated law `u = sat(−L x̂)` (eq. 11) and the actuator limits.
//! * [`adaptive`]: the gain recomputed from the DKF's `Â`, `B̂` every N steps, keeping the last
//!   good gain when the estimate is unusable (paper 000 Fig. 6).
//! * [`crane`]: the documented crane design (poles −1 ± 0.5j, −1.5 ± 5.2j at Ts = 0.05 s).

pub mod adaptive;
pub mod crane;
pub mod pole_placement;
pub mod state_feedback;

pub use adaptive::{
    AdaptiveProgress, AdaptiveStateFeedback, AdaptiveStateFeedbackConfig, GainRejection, GainUpdate,
};
pub use crane::{
    crane_design, crane_reference_design, crane_zoh, DiscreteDesign, CRANE_CONTINUOUS_POLES,
    CRANE_SAMPLE_TIME,
};
pub use pole_placement::{
    ackermann, ackermann_with_options, characteristic_polynomial, poles_from_continuous,
    reachability_matrix, PolePlacementError, PolePlacementOptions,
};
pub use state_feedback::{InputLimits, StateController, StateFeedback};
