//! Saturated state feedback `u = sat(−L (x̂ − x_ref))` (paper 000 eq. 11; docs/controllers.md §2.13).
//!
//! The gain comes from [`crate::control::ackermann`] (or from anywhere else: an LQ design, a
//! user parameter). The actuator limits `[u_min, u_max]` are applied here, and the output is
//! never NaN: a non-finite product (NaN estimate, dimension mismatch) gives the admissible
//! input closest to zero.

use crate::control::pole_placement::{
    ackermann_with_options, PolePlacementError, PolePlacementOptions,
};
use crate::ParameterError;
use nalgebra::{Complex, DMatrix};

/// Actuator limits `u_min < u_max` (either may be infinite).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InputLimits {
    min: f64,
    max: f64,
}

impl InputLimits {
    /// Limits `[min, max]`; errors when either is NaN or `min ≥ max`.
    pub fn new(min: f64, max: f64) -> Result<Self, ParameterError> {
        if min.is_nan() {
            return Err(ParameterError::new("u_min", "must not be NaN"));
        }
        if max.is_nan() {
            return Err(ParameterError::new("u_max", "must not be NaN"));
        }
        if min >= max {
            return Err(ParameterError::new(
                "u_max",
                format!("must be greater than u_min = {min}, got {max}"),
            ));
        }
        Ok(Self { min, max })
    }

    /// Symmetric limits `[−bound, bound]` (e.g. ±17 N for the crane).
    pub fn symmetric(bound: f64) -> Result<Self, ParameterError> {
        if bound.is_nan() || bound <= 0.0 {
            return Err(ParameterError::new(
                "u_max",
                format!("must be a positive number (or +∞), got {bound}"),
            ));
        }
        Self::new(-bound, bound)
    }

    /// No limits.
    pub fn unlimited() -> Self {
        Self {
            min: f64::NEG_INFINITY,
            max: f64::INFINITY,
        }
    }

    /// Lower limit.
    pub fn min(&self) -> f64 {
        self.min
    }

    /// Upper limit.
    pub fn max(&self) -> f64 {
        self.max
    }

    /// `u` clipped to the limits; NaN becomes the admissible value closest to zero. (Written
    /// with `max`/`min`, which never panic, rather than `clamp`.)
    pub fn saturate(&self, u: f64) -> f64 {
        let value = if u.is_nan() { 0.0 } else { u };
        value.max(self.min).min(self.max)
    }
}

/// `−L (x − x_ref)` for a gain row `L` (n entries), or `None` when lengths differ or the
/// result is not finite.
pub fn feedback_term(gain: &[f64], state: &[f64], reference: Option<&[f64]>) -> Option<f64> {
    if gain.is_empty() || gain.len() != state.len() {
        return None;
    }
    if reference.is_some_and(|r| r.len() != state.len()) {
        return None;
    }
    let u: f64 = -(0..state.len())
        .map(|i| gain[i] * (state[i] - reference.map_or(0.0, |r| r[i])))
        .sum::<f64>();
    u.is_finite().then_some(u)
}

/// A fixed, saturated state-feedback controller.
#[derive(Debug, Clone, PartialEq)]
pub struct StateFeedback {
    gain: DMatrix<f64>,
    limits: InputLimits,
}

impl StateFeedback {
    /// A controller with a given 1 × n gain; errors if the gain is not one finite row.
    pub fn from_gain(gain: DMatrix<f64>, limits: InputLimits) -> Result<Self, ParameterError> {
        if gain.nrows() != 1 || gain.ncols() == 0 {
            return Err(ParameterError::new(
                "L",
                format!("must be a 1×n row, got {}×{}", gain.nrows(), gain.ncols()),
            ));
        }
        if !gain.iter().all(|v| v.is_finite()) {
            return Err(ParameterError::new("L", "must be finite"));
        }
        Ok(Self { gain, limits })
    }

    /// A controller placing the (discrete, stable, self-conjugate) `poles` of `A − B L` by
    /// Ackermann's formula.
    pub fn place(
        a: &DMatrix<f64>,
        b: &DMatrix<f64>,
        poles: &[Complex<f64>],
        limits: InputLimits,
    ) -> Result<Self, PolePlacementError> {
        let options = PolePlacementOptions {
            require_stable: true,
            ..PolePlacementOptions::default()
        };
        let gain = ackermann_with_options(a, b, poles, &options)?;
        Ok(Self { gain, limits })
    }

    /// The gain `L` (1 × n).
    pub fn gain(&self) -> &DMatrix<f64> {
        &self.gain
    }

    /// The actuator limits.
    pub fn limits(&self) -> InputLimits {
        self.limits
    }
}

/// A discrete state-feedback law (paper 000 §IV eq. 15; Fig. 6 for the adaptive one)
///
/// ```text
/// u_k = sat_[u_min, u_max]( −L_k (x̂_k − x_ref) )
/// ```
///
/// with a fixed gain `L` ([`StateFeedback`]) or one recomputed from the estimated model
/// ([`crate::control::AdaptiveStateFeedback`]). The law itself is shared: it never returns
/// NaN — without a gain, or for a NaN or mis-sized estimate, it gives the admissible input
/// closest to zero.
pub trait StateController {
    /// The gain `L_k` (1 × n) in use; `None` while there is none.
    fn current_gain(&self) -> Option<&DMatrix<f64>>;
    /// The actuator limits.
    fn input_limits(&self) -> InputLimits;
    /// The gain in use as a row of n entries (empty while there is none, or if it is not
    /// one row).
    fn gain_row(&self) -> &[f64] {
        self.current_gain()
            .filter(|gain| gain.nrows() == 1)
            .map_or(&[], |gain| gain.as_slice())
    }
    /// `u = sat(−L x̂)` (regulation to the origin).
    fn control(&self, x_hat: &(impl AsRef<[f64]> + ?Sized)) -> f64 {
        let u = feedback_term(self.gain_row(), x_hat.as_ref(), None);
        self.input_limits().saturate(u.unwrap_or(0.0))
    }
    /// `u = sat(−L x̂ + v)`: regulation with an exogenous input `v` added before the
    /// saturation (e.g. a small dither that makes a closed loop identifiable,
    /// docs/controllers.md §2.14). `v = 0` gives [`StateController::control`].
    fn control_plus(&self, x_hat: &(impl AsRef<[f64]> + ?Sized), v: f64) -> f64 {
        let u = feedback_term(self.gain_row(), x_hat.as_ref(), None);
        self.input_limits().saturate(u.unwrap_or(0.0) + v)
    }
    /// `u = sat(−L (x̂ − x_ref))`: regulation to a reference state `x_ref`, which must be an
    /// equilibrium with zero input (e.g. any cart position of the crane, at rest).
    fn control_towards(
        &self,
        x_hat: &(impl AsRef<[f64]> + ?Sized),
        x_ref: &(impl AsRef<[f64]> + ?Sized),
    ) -> f64 {
        let u = feedback_term(self.gain_row(), x_hat.as_ref(), Some(x_ref.as_ref()));
        self.input_limits().saturate(u.unwrap_or(0.0))
    }
}

impl StateController for StateFeedback {
    fn current_gain(&self) -> Option<&DMatrix<f64>> {
        Some(&self.gain)
    }
    fn input_limits(&self) -> InputLimits {
        self.limits
    }
}

// FMU-state snapshots (plain bytes) of the types above: every field, in order.
// Limits read back from a saved state are checked as `InputLimits::new` checks them, so a
// corrupted FMU state cannot bring NaN limits (or min ≥ max) into the controller.
impl crate::state::PlainState for InputLimits {
    fn save(&self, out: &mut Vec<u8>) {
        self.min.save(out);
        self.max.save(out);
    }
    fn read(input: &mut &[u8]) -> Result<Self, crate::state::StateError> {
        let (min, max) = (f64::read(input)?, f64::read(input)?);
        Self::new(min, max).map_err(|_| crate::state::StateError::Invalid {
            what: "input limits (NaN, or min >= max)",
            value: min.to_bits(),
        })
    }
}
crate::plain_state!(StateFeedback { gain, limits });

#[cfg(test)]
mod limit_state_tests {
    use super::*;
    use crate::state::PlainState;

    #[test]
    fn saved_limits_are_checked_when_read() {
        let limits = InputLimits::symmetric(17.0).unwrap();
        let mut bytes = Vec::new();
        limits.save(&mut bytes);
        assert_eq!(InputLimits::read(&mut bytes.as_slice()), Ok(limits));
        // a NaN lower limit (the misuse suite's corrupted state, which made saturate panic)
        bytes[..8].copy_from_slice(&f64::NAN.to_le_bytes());
        assert!(InputLimits::read(&mut bytes.as_slice()).is_err());
        let mut swapped = Vec::new();
        17.0f64.save(&mut swapped);
        (-17.0f64).save(&mut swapped);
        assert!(InputLimits::read(&mut swapped.as_slice()).is_err());
        assert_eq!(limits.saturate(f64::NAN), 0.0);
        assert_eq!(limits.saturate(1e308), 17.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{dmatrix, dvector};

    #[test]
    fn output_is_saturated_and_never_nan() {
        let limits = InputLimits::new(-1.0, 2.0).unwrap();
        let controller = StateFeedback::from_gain(dmatrix![1.0, 10.0], limits).unwrap();
        assert_eq!(controller.control(&dvector![0.1, 0.0]), -0.1);
        assert_eq!(controller.control(&dvector![0.0, 1.0]), -1.0);
        assert_eq!(controller.control(&dvector![0.0, -1.0]), 2.0);
        assert_eq!(controller.control(&dvector![f64::NAN, 0.0]), 0.0);
        assert_eq!(controller.control(&dvector![1.0]), 0.0);
        assert_eq!(
            controller.control_towards(&dvector![1.0, 0.0], &dvector![1.5, 0.0]),
            0.5
        );
        let positive =
            StateFeedback::from_gain(dmatrix![1.0], InputLimits::new(0.5, 1.0).unwrap()).unwrap();
        assert_eq!(positive.control(&dvector![f64::NAN]), 0.5);
    }

    #[test]
    fn bad_limits_and_gains_are_named() {
        assert_eq!(InputLimits::new(1.0, 1.0).unwrap_err().parameter, "u_max");
        assert_eq!(
            InputLimits::new(f64::NAN, 1.0).unwrap_err().parameter,
            "u_min"
        );
        assert!(InputLimits::symmetric(-3.0).is_err());
        assert!(InputLimits::symmetric(f64::INFINITY).is_ok());
        let limits = InputLimits::unlimited();
        assert_eq!(
            StateFeedback::from_gain(dmatrix![1.0; 2.0], limits)
                .unwrap_err()
                .parameter,
            "L"
        );
        assert!(StateFeedback::from_gain(dmatrix![f64::NAN], limits).is_err());
    }
}
