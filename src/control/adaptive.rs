//! Adaptive state feedback: pole placement redone on the identified model (paper 000 §VI,
//! Fig. 6; docs/controllers.md §2.14).
//!
//! Every `N`-th step the dual Kalman filter delivers estimates `Â`, `B̂` and the controller
//! recomputes `L = [0 … 0 1] 𝒞(Â, B̂)⁻¹ φ(Â)` (Ackermann, paper 000 eq. 15) for fixed desired
//! poles; the input is `u_k = sat(−L x̂_k)`.
//!
//! An identified model is not always usable: early in the identification `B̂` may be ≈ 0
//! (not reachable), the estimate may hold NaN, or the placement may return a huge gain from
//! an ill-conditioned `𝒞`. In all those cases the controller keeps the last good gain (or the
//! initial gain given at construction, e.g. the nominal-model design) and reports why
//! through [`GainUpdate::Kept`]. Consecutive rejected updates form an *episode*; only the
//! first rejection of an episode has `first_in_episode = true`, so the FMU layer can log one
//! warning per episode instead of one per step. An accepted update ends the episode.

use crate::control::pole_placement::{
    characteristic_polynomial, check_poles, gain_of, PolePlacementError,
    DEFAULT_MAX_CONDITION_NUMBER,
};
use crate::control::state_feedback::{InputLimits, StateController};
use crate::state::PlainState;
use crate::ParameterError;
use nalgebra::{Complex, DMatrix, DVector, Matrix4, RowVector4, Vector4};
use std::fmt;

/// Default bound on the Euclidean norm of an accepted gain.
pub const DEFAULT_MAX_GAIN_NORM: f64 = 1e6;

/// Why an update did not change the gain.
#[derive(Debug, Clone, PartialEq)]
pub enum GainRejection {
    /// `Â` or `B̂` holds NaN or infinity.
    NonFiniteEstimate,
    /// `Â` is not n × n or `B̂` not n × 1 (n = number of desired poles).
    WrongDimensions {
        /// Number of states n.
        states: usize,
        /// Shape of Â.
        a_shape: (usize, usize),
        /// Shape of B̂.
        b_shape: (usize, usize),
    },
    /// The new gain contains NaN or infinity.
    NonFiniteGain,
    /// `(Â, B̂)` is not reachable.
    NotReachable {
        /// Condition number of the reachability matrix.
        condition_number: f64,
    },
    /// The new gain is larger than the configured bound.
    GainTooLarge {
        /// ‖L‖₂ of the rejected gain.
        norm: f64,
        /// The bound.
        bound: f64,
    },
    /// Any other pole-placement failure.
    PlacementFailed(PolePlacementError),
}

impl fmt::Display for GainRejection {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NonFiniteEstimate => write!(f, "the estimated A or B contains NaN or infinity"),
            Self::WrongDimensions {
                states,
                a_shape,
                b_shape,
            } => write!(
                f,
                "the estimate must be A {states}×{states} and B {states}×1, got A {}×{} and B \
                 {}×{}",
                a_shape.0, a_shape.1, b_shape.0, b_shape.1
            ),
            Self::NotReachable { condition_number } => write!(
                f,
                "the estimated (A, B) is not reachable (reachability matrix condition number \
                 {condition_number:e})"
            ),
            Self::NonFiniteGain => write!(f, "the recomputed gain contains NaN or infinity"),
            Self::GainTooLarge { norm, bound } => {
                write!(f, "the recomputed gain has norm {norm:e} > bound {bound:e}")
            }
            Self::PlacementFailed(e) => write!(f, "pole placement failed: {e}"),
        }
    }
}

/// Outcome of [`AdaptiveStateFeedback::update`].
#[derive(Debug, Clone, PartialEq)]
pub enum GainUpdate {
    /// Not a recompute step (only every `N`-th call recomputes): gain unchanged.
    NotDue,
    /// The gain was recomputed from the estimate and accepted.
    Updated,
    /// The estimate or the new gain was rejected; the last good gain is kept.
    Kept {
        /// Why.
        reason: GainRejection,
        /// `true` for the first rejection after an accepted update (or since the start):
        /// log a warning for this one only.
        first_in_episode: bool,
    },
}

/// Configuration of an [`AdaptiveStateFeedback`].
#[derive(Debug, Clone, PartialEq)]
pub struct AdaptiveStateFeedbackConfig {
    /// Desired discrete closed-loop poles (self-conjugate, inside the unit circle); their
    /// number is the number of states.
    pub poles: Vec<Complex<f64>>,
    /// Actuator limits.
    pub limits: InputLimits,
    /// Recompute the gain every `recompute_period` calls to `update` (≥ 1).
    pub recompute_period: usize,
    /// Gains with a larger Euclidean norm are rejected.
    pub max_gain_norm: f64,
    /// Estimates whose reachability matrix has a larger condition number are rejected.
    pub max_condition_number: f64,
    /// Gain used until the first accepted update (1 × n), e.g. the nominal design. Without
    /// one, the controller outputs the admissible input closest to zero until then.
    pub initial_gain: Option<DMatrix<f64>>,
}

impl AdaptiveStateFeedbackConfig {
    /// A configuration with the defaults: recompute every step, gain norm ≤ 1e6,
    /// condition number ≤ 1e12, no initial gain.
    pub fn new(poles: Vec<Complex<f64>>, limits: InputLimits) -> Self {
        Self {
            poles,
            limits,
            recompute_period: 1,
            max_gain_norm: DEFAULT_MAX_GAIN_NORM,
            max_condition_number: DEFAULT_MAX_CONDITION_NUMBER,
            initial_gain: None,
        }
    }
}

/// The part of an [`AdaptiveStateFeedback`] that evolves with `update` (everything but the
/// configuration): what an FMU state must carry besides the parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct AdaptiveProgress {
    /// The gain in use (1 × n), if any.
    pub gain: Option<DMatrix<f64>>,
    /// Calls to `update` left before the next recompute (`< recompute_period`).
    pub calls_until_due: usize,
    /// Whether the last recompute was rejected.
    pub in_rejection_episode: bool,
    /// Total number of rejected updates.
    pub rejected_updates: u64,
    /// Number of episodes of consecutive rejected updates.
    pub rejection_episodes: u64,
}

/// The adaptive pole-placement controller (see the module doc).
#[derive(Debug, Clone, PartialEq)]
pub struct AdaptiveStateFeedback {
    config: AdaptiveStateFeedbackConfig,
    gain: Option<DMatrix<f64>>,
    /// Calls to `update` left before the next recompute (0: the next call recomputes).
    calls_until_due: usize,
    in_bad_episode: bool,
    rejected_updates: u64,
    episodes: u64,
    /// `[1, φ₁, …, φ_n]` of the desired poles (derived from the configuration once).
    characteristic: Vec<f64>,
}

/// The outcome of a gain recompute from one estimate, before it is committed: `Ok` with the
/// candidate written to the caller's row, or why it is rejected
/// ([`AdaptiveStateFeedback::candidate_gain_into`]).
pub type Candidate = Result<(), GainRejection>;

impl AdaptiveStateFeedback {
    /// Checks the configuration (poles, period, bounds, initial gain) and builds the
    /// controller.
    pub fn new(config: AdaptiveStateFeedbackConfig) -> Result<Self, ParameterError> {
        if config.poles.is_empty() {
            return Err(ParameterError::new("poles", "at least one pole is needed"));
        }
        check_poles(&config.poles, true)
            .map_err(|e| ParameterError::new("poles", e.to_string()))?;
        if config.recompute_period == 0 {
            return Err(ParameterError::new(
                "recompute_period",
                "must be at least 1 (recompute every N-th step)",
            ));
        }
        if config.max_gain_norm.is_nan() || config.max_gain_norm <= 0.0 {
            return Err(ParameterError::new(
                "max_gain_norm",
                format!(
                    "must be a positive number (or +∞), got {}",
                    config.max_gain_norm
                ),
            ));
        }
        crate::require_positive("max_condition_number", config.max_condition_number)?;
        let n = config.poles.len();
        if let Some(gain) = &config.initial_gain {
            if gain.shape() != (1, n) {
                return Err(ParameterError::new(
                    "initial_gain",
                    format!("must be 1×{n}, got {}×{}", gain.nrows(), gain.ncols()),
                ));
            }
            if !gain.iter().all(|v| v.is_finite()) {
                return Err(ParameterError::new("initial_gain", "must be finite"));
            }
        }
        Ok(Self {
            gain: config.initial_gain.clone(),
            characteristic: characteristic_polynomial(&config.poles),
            config,
            calls_until_due: 0,
            in_bad_episode: false,
            rejected_updates: 0,
            episodes: 0,
        })
    }

    /// Number of states n.
    pub fn states(&self) -> usize {
        self.config.poles.len()
    }

    /// The gain in use (1 × n), `None` before the first good one when no initial gain was
    /// given.
    pub fn gain(&self) -> Option<&DMatrix<f64>> {
        self.gain.as_ref()
    }

    /// The configuration.
    pub fn config(&self) -> &AdaptiveStateFeedbackConfig {
        &self.config
    }

    /// Total number of rejected updates.
    pub fn rejected_updates(&self) -> u64 {
        self.rejected_updates
    }

    /// Number of episodes of consecutive rejected updates.
    pub fn rejection_episodes(&self) -> u64 {
        self.episodes
    }

    /// Whether the last recompute was rejected (an episode is under way).
    pub fn in_rejection_episode(&self) -> bool {
        self.in_bad_episode
    }

    /// The evolving state (gain, recompute phase, episode bookkeeping).
    pub fn progress(&self) -> AdaptiveProgress {
        AdaptiveProgress {
            gain: self.gain.clone(),
            calls_until_due: self.calls_until_due,
            in_rejection_episode: self.in_bad_episode,
            rejected_updates: self.rejected_updates,
            rejection_episodes: self.episodes,
        }
    }

    /// Restores what [`AdaptiveStateFeedback::progress`] returned (for a controller with the
    /// same configuration); errors if it does not fit this configuration.
    pub fn restore_progress(&mut self, progress: AdaptiveProgress) -> Result<(), ParameterError> {
        let n = self.states();
        if let Some(gain) = &progress.gain {
            if gain.shape() != (1, n) || !gain.iter().all(|v| v.is_finite()) {
                return Err(ParameterError::new(
                    "gain",
                    format!(
                        "must be a finite 1×{n} row, got {}×{}",
                        gain.nrows(),
                        gain.ncols()
                    ),
                ));
            }
        }
        if progress.calls_until_due >= self.config.recompute_period {
            return Err(ParameterError::new(
                "calls_until_due",
                format!(
                    "must be below recompute_period = {}, got {}",
                    self.config.recompute_period, progress.calls_until_due
                ),
            ));
        }
        self.gain = progress.gain;
        self.calls_until_due = progress.calls_until_due;
        self.in_bad_episode = progress.in_rejection_episode;
        self.rejected_updates = progress.rejected_updates;
        self.episodes = progress.rejection_episodes;
        Ok(())
    }

    /// Feeds the latest model estimate; every `N`-th call recomputes the gain from it.
    pub fn update(&mut self, a_hat: &DMatrix<f64>, b_hat: &DMatrix<f64>) -> GainUpdate {
        let mut row = [0.0; 4];
        let mut long_row = Vec::new();
        let candidate = match self.states() {
            n if n <= row.len() => &mut row[..n],
            n => {
                long_row.resize(n, 0.0);
                &mut long_row[..]
            }
        };
        let outcome = self
            .is_due()
            .then(|| self.candidate_gain_into(a_hat, b_hat, candidate));
        self.commit(outcome, candidate)
    }

    /// Whether the next [`AdaptiveStateFeedback::update`] recomputes the gain.
    pub fn is_due(&self) -> bool {
        self.calls_until_due == 0
    }

    /// What [`AdaptiveStateFeedback::update`] does once the estimate is assessed: `outcome`
    /// is `None` when no recompute was due, else the [`Candidate`] of
    /// [`AdaptiveStateFeedback::candidate_gain_into`] for the row `candidate` it wrote. Lets
    /// a caller assess an estimate once, show the result, and commit it later.
    pub fn commit(&mut self, outcome: Option<Candidate>, candidate: &[f64]) -> GainUpdate {
        let Some(outcome) = outcome else {
            self.calls_until_due = self.calls_until_due.saturating_sub(1);
            return GainUpdate::NotDue;
        };
        self.calls_until_due = self.config.recompute_period - 1;
        let n = self.states();
        match outcome {
            Ok(()) if candidate.len() == n => {
                match &mut self.gain {
                    Some(gain) if gain.len() == n => gain.copy_from_slice(candidate),
                    gain => *gain = Some(DMatrix::from_row_slice(1, n, candidate)),
                }
                self.in_bad_episode = false;
                GainUpdate::Updated
            }
            Ok(()) => self.reject(GainRejection::WrongDimensions {
                states: n,
                a_shape: (n, n),
                b_shape: (candidate.len(), 1),
            }),
            Err(reason) => self.reject(reason),
        }
    }

    fn reject(&mut self, reason: GainRejection) -> GainUpdate {
        let first_in_episode = !self.in_bad_episode;
        self.in_bad_episode = true;
        self.rejected_updates += 1;
        if first_in_episode {
            self.episodes += 1;
        }
        GainUpdate::Kept {
            reason,
            first_in_episode,
        }
    }

    /// The gain recomputed from the estimate `Â`, `B̂` (Ackermann for the configured poles),
    /// written to `candidate` (1 × n, row order) when it is acceptable, or why not. Changes
    /// nothing in the controller. For n = 4 (the crane) the arithmetic runs on fixed-size
    /// matrices, without heap allocation; its results are bit-identical to the general path.
    pub fn candidate_gain_into(
        &self,
        a_hat: &DMatrix<f64>,
        b_hat: &DMatrix<f64>,
        candidate: &mut [f64],
    ) -> Candidate {
        let n = self.states();
        if a_hat.shape() != (n, n) || b_hat.shape() != (n, 1) || candidate.len() != n {
            return Err(GainRejection::WrongDimensions {
                states: n,
                a_shape: a_hat.shape(),
                b_shape: b_hat.shape(),
            });
        }
        if !(a_hat.iter().all(|v| v.is_finite()) && b_hat.iter().all(|v| v.is_finite())) {
            return Err(GainRejection::NonFiniteEstimate);
        }
        let bound = self.config.max_condition_number;
        let gain = if n == 4 {
            let a = Matrix4::from_column_slice(a_hat.as_slice());
            let b = Vector4::from_column_slice(b_hat.as_slice());
            gain_of(&a, &b, &self.characteristic, bound).map(|g: RowVector4<f64>| {
                candidate.copy_from_slice(g.as_slice());
            })
        } else {
            let b = DVector::from_column_slice(b_hat.as_slice());
            gain_of(a_hat, &b, &self.characteristic, bound).map(|g| {
                candidate.copy_from_slice(g.as_slice());
            })
        };
        gain.map_err(|e| match e {
            PolePlacementError::NotReachable {
                condition_number, ..
            } => GainRejection::NotReachable { condition_number },
            PolePlacementError::NonFiniteGain => GainRejection::NonFiniteGain,
            PolePlacementError::NonFinite { .. } => GainRejection::NonFiniteEstimate,
            other => GainRejection::PlacementFailed(other),
        })?;
        let norm = candidate.iter().map(|v| v * v).sum::<f64>().sqrt();
        if !norm.is_finite() {
            return Err(GainRejection::NonFiniteGain);
        }
        if norm > self.config.max_gain_norm {
            return Err(GainRejection::GainTooLarge {
                norm,
                bound: self.config.max_gain_norm,
            });
        }
        Ok(())
    }
}

/// The adaptive law: the gain is the last good one ([`AdaptiveStateFeedback::gain`]).
impl StateController for AdaptiveStateFeedback {
    fn current_gain(&self) -> Option<&DMatrix<f64>> {
        self.gain.as_ref()
    }
    fn input_limits(&self) -> InputLimits {
        self.config.limits
    }
}

// FMU-state snapshots (plain bytes) of the types above: every field, in order.
crate::plain_state!(AdaptiveStateFeedbackConfig {
    poles,
    limits,
    recompute_period,
    max_gain_norm,
    max_condition_number,
    initial_gain
});
// A state read back is checked as `AdaptiveStateFeedback::new` checks its configuration (a
// corrupted state cannot bring unplaceable poles, a zero recompute period or a mis-sized
// gain), and the characteristic polynomial is derived from the poles again.
impl crate::state::PlainState for AdaptiveStateFeedback {
    fn save(&self, out: &mut Vec<u8>) {
        self.config.save(out);
        self.gain.save(out);
        self.calls_until_due.save(out);
        self.in_bad_episode.save(out);
        self.rejected_updates.save(out);
        self.episodes.save(out);
    }
    fn read(input: &mut &[u8]) -> Result<Self, crate::state::StateError> {
        let config = AdaptiveStateFeedbackConfig::read(input)?;
        let period = config.recompute_period;
        let mut controller = Self::new(config).map_err(|_| crate::state::StateError::Invalid {
            what: "adaptive controller configuration",
            value: period as u64,
        })?;
        let progress = AdaptiveProgress {
            gain: PlainState::read(input)?,
            calls_until_due: PlainState::read(input)?,
            in_rejection_episode: PlainState::read(input)?,
            rejected_updates: PlainState::read(input)?,
            rejection_episodes: PlainState::read(input)?,
        };
        let due = progress.calls_until_due;
        controller
            .restore_progress(progress)
            .map_err(|_| crate::state::StateError::Invalid {
                what: "adaptive controller gain or recompute phase",
                value: due as u64,
            })?;
        Ok(controller)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::crane::{crane_reference_design, DiscreteDesign};
    use nalgebra::dvector;

    /// The crane's reference design and a configuration with its poles and |u| ≤ 17 N.
    fn crane_config() -> (DiscreteDesign, AdaptiveStateFeedbackConfig) {
        let design = crane_reference_design().unwrap();
        let config = AdaptiveStateFeedbackConfig::new(
            design.poles.clone(),
            InputLimits::symmetric(17.0).unwrap(),
        );
        (design, config)
    }

    fn crane_controller(initial_gain: Option<DMatrix<f64>>) -> AdaptiveStateFeedback {
        let (_, mut config) = crane_config();
        config.initial_gain = initial_gain;
        AdaptiveStateFeedback::new(config).unwrap()
    }

    #[test]
    fn bad_estimates_keep_the_last_good_gain_and_warn_once_per_episode() {
        let design = crane_reference_design().unwrap();
        let (a, b) = (design.a.clone(), design.b.clone());
        let mut controller = crane_controller(None);
        let x = dvector![0.2, 0.0, 0.0, 0.0];
        // Before any gain: zero input, never NaN.
        assert_eq!(controller.control(&x), 0.0);

        assert_eq!(controller.update(&a, &b), GainUpdate::Updated);
        let good = controller.gain().unwrap().clone();
        assert!((&good - &design.gain).amax() < 1e-12);

        // A slightly different but valid estimate is accepted.
        let b_scaled = &b * 1.1;
        assert_eq!(controller.update(&a, &b_scaled), GainUpdate::Updated);
        let last_good = controller.gain().unwrap().clone();
        assert!((&last_good - &good).amax() > 1e-3);

        // Episode 1: unreachable, then NaN, then a wrong shape.
        let zero_b = DMatrix::zeros(4, 1);
        match controller.update(&a, &zero_b) {
            GainUpdate::Kept {
                reason: GainRejection::NotReachable { condition_number },
                first_in_episode: true,
            } => assert!(condition_number.is_infinite() || condition_number > 1e12),
            other => panic!("expected a first NotReachable rejection, got {other:?}"),
        }
        let mut nan_a = a.clone();
        nan_a[(1, 2)] = f64::NAN;
        assert_eq!(
            controller.update(&nan_a, &b),
            GainUpdate::Kept {
                reason: GainRejection::NonFiniteEstimate,
                first_in_episode: false
            }
        );
        assert!(matches!(
            controller.update(&DMatrix::zeros(3, 3), &b),
            GainUpdate::Kept {
                reason: GainRejection::WrongDimensions { .. },
                first_in_episode: false
            }
        ));
        assert_eq!(controller.gain(), Some(&last_good));
        let u = controller.control(&x);
        assert!(u.is_finite());
        assert!((u - (-(&last_good * &x)[(0, 0)])).abs() < 1e-15);

        // Recovery ends the episode; a new bad estimate opens episode 2.
        assert_eq!(controller.update(&a, &b), GainUpdate::Updated);
        assert!(matches!(
            controller.update(&a, &zero_b),
            GainUpdate::Kept {
                first_in_episode: true,
                ..
            }
        ));
        assert_eq!(controller.rejection_episodes(), 2);
        assert_eq!(controller.rejected_updates(), 4);
        assert!(controller.gain().unwrap().iter().all(|v| v.is_finite()));
    }

    #[test]
    fn a_huge_gain_is_rejected() {
        let (design, mut config) = crane_config();
        config.max_gain_norm = 10.0;
        config.initial_gain = Some(design.gain.clone());
        let mut controller = AdaptiveStateFeedback::new(config).unwrap();
        // A tiny B̂ needs a gain ~ 1/ε.
        let tiny_b = &design.b * 1e-4;
        match controller.update(&design.a, &tiny_b) {
            GainUpdate::Kept {
                reason: GainRejection::GainTooLarge { norm, bound },
                first_in_episode: true,
            } => {
                assert!(norm > bound);
                assert!(GainRejection::GainTooLarge { norm, bound }
                    .to_string()
                    .contains("bound"));
            }
            other => panic!("expected GainTooLarge, got {other:?}"),
        }
        assert_eq!(controller.gain(), Some(&design.gain));
    }

    #[test]
    fn progress_round_trips_and_is_checked() {
        let (design, mut config) = crane_config();
        config.recompute_period = 2;
        let mut controller = AdaptiveStateFeedback::new(config.clone()).unwrap();
        controller.update(&design.a, &design.b);
        controller.update(&design.a, &design.b);
        controller.update(&design.a, &DMatrix::zeros(4, 1));
        let saved = controller.progress();
        let mut other = AdaptiveStateFeedback::new(config).unwrap();
        other.restore_progress(saved.clone()).unwrap();
        assert_eq!(other, controller);
        for _ in 0..3 {
            assert_eq!(
                other.update(&design.a, &design.b),
                controller.update(&design.a, &design.b)
            );
        }
        let mut bad = saved.clone();
        bad.calls_until_due = 2;
        assert!(other.restore_progress(bad).is_err());
        let mut bad = saved;
        bad.gain = Some(DMatrix::zeros(1, 3));
        assert_eq!(other.restore_progress(bad).unwrap_err().parameter, "gain");
    }

    /// The crane's n = 4 runs on fixed-size matrices; on perturbed estimates (and one that is
    /// not reachable) it gives the general path's gain to the bit.
    #[test]
    fn the_fixed_size_gain_is_the_general_one_to_the_bit() {
        use crate::control::pole_placement::{ackermann_with_options, PolePlacementOptions};
        let (design, config) = crane_config();
        let controller = AdaptiveStateFeedback::new(config).unwrap();
        let options = PolePlacementOptions {
            require_stable: true,
            ..PolePlacementOptions::default()
        };
        let mut accepted = 0;
        for k in 0..200 {
            let wobble = |i: usize| 1.0 + 0.05 * ((k * 31 + i * 7) as f64 * 0.618).sin();
            let a = DMatrix::from_fn(4, 4, |i, j| design.a[(i, j)] * wobble(i * 4 + j));
            let scale = if k == 13 { 0.0 } else { 1.0 };
            let b = DMatrix::from_fn(4, 1, |i, _| design.b[(i, 0)] * wobble(20 + i) * scale);
            let mut row = [0.0; 4];
            let fixed = controller.candidate_gain_into(&a, &b, &mut row);
            match ackermann_with_options(&a, &b, &design.poles, &options) {
                Ok(general) => {
                    assert_eq!(fixed, Ok(()), "estimate {k}");
                    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                    assert_eq!(bits(&row), bits(general.as_slice()), "estimate {k}");
                    accepted += 1;
                }
                Err(e) => assert!(
                    matches!(
                        (e, fixed),
                        (
                            PolePlacementError::NotReachable { .. },
                            Err(GainRejection::NotReachable { .. })
                        )
                    ),
                    "estimate {k}"
                ),
            }
        }
        assert_eq!(accepted, 199);
    }

    /// A saved state is read back only if it could have been built: a zero recompute period
    /// (which would make the next commit underflow), poles outside the unit circle or a
    /// mis-sized gain are refused; a good one comes back equal, its polynomial derived again.
    #[test]
    fn a_state_read_back_is_checked_like_a_new_controller() {
        let design = crane_reference_design().unwrap();
        let good = crane_controller(Some(design.gain.clone()));
        let read = |c: &AdaptiveStateFeedback| {
            let mut bytes = Vec::new();
            c.save(&mut bytes);
            AdaptiveStateFeedback::read(&mut bytes.as_slice())
        };
        assert_eq!(read(&good), Ok(good.clone()));
        let mut bad = good.clone();
        bad.config.recompute_period = 0;
        assert!(read(&bad).is_err());
        let mut bad = good.clone();
        bad.config.poles[0] = Complex::new(1.5, 0.0);
        assert!(read(&bad).is_err());
        let mut bad = good;
        bad.gain = Some(DMatrix::zeros(1, 3));
        assert!(read(&bad).is_err());
    }

    #[test]
    fn recomputes_only_every_nth_call() {
        let (design, mut config) = crane_config();
        config.recompute_period = 3;
        let mut controller = AdaptiveStateFeedback::new(config).unwrap();
        let outcomes: Vec<GainUpdate> = (0..6)
            .map(|_| controller.update(&design.a, &design.b))
            .collect();
        let updated: Vec<bool> = outcomes.iter().map(|o| *o == GainUpdate::Updated).collect();
        assert_eq!(updated, vec![true, false, false, true, false, false]);
    }

    #[test]
    fn control_is_saturated_and_survives_nan_state() {
        let design = crane_reference_design().unwrap();
        let controller = crane_controller(Some(design.gain.clone()));
        assert_eq!(controller.control(&dvector![-100.0, 0.0, 0.0, 0.0]), 17.0);
        assert_eq!(controller.control(&dvector![100.0, 0.0, 0.0, 0.0]), -17.0);
        assert_eq!(controller.control(&dvector![f64::NAN, 0.0, 0.0, 0.0]), 0.0);
        let toward = controller
            .control_towards(&dvector![0.1, 0.0, 0.0, 0.0], &dvector![0.1, 0.0, 0.0, 0.0]);
        assert_eq!(toward, 0.0);
    }

    #[test]
    fn invalid_configurations_are_named() {
        let limits = InputLimits::symmetric(1.0).unwrap();
        let half = Complex::new(0.5, 0.0);
        let e = AdaptiveStateFeedback::new(AdaptiveStateFeedbackConfig::new(
            vec![Complex::new(1.5, 0.0)],
            limits,
        ))
        .unwrap_err();
        assert_eq!(e.parameter, "poles");
        assert!(e.reason.contains("unit circle"), "{e}");
        let mut config = AdaptiveStateFeedbackConfig::new(vec![half], limits);
        config.recompute_period = 0;
        assert_eq!(
            AdaptiveStateFeedback::new(config.clone())
                .unwrap_err()
                .parameter,
            "recompute_period"
        );
        config.recompute_period = 1;
        config.initial_gain = Some(DMatrix::zeros(1, 2));
        assert_eq!(
            AdaptiveStateFeedback::new(config).unwrap_err().parameter,
            "initial_gain"
        );
        assert!(
            AdaptiveStateFeedback::new(AdaptiveStateFeedbackConfig::new(vec![], limits)).is_err()
        );
    }
}
