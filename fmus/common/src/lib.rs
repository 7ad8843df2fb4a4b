//! What several spurio FMUs share and that knows the `spurio` models (the FMI-generic
//! plumbing is in `spurio-export`):
//! - [`structured`]: vector and matrix variables (`x_hat[1]`, `A[1,1]`) as blocks;
//! - [`clock`]: the one sample clock of the discrete-time FMUs (`sample_period`);
//! - [`estimator`]: the one generic estimator adapter ([`estimator::EstimatorFmu`]) and its
//!   input checks;
//! - [`controller`]: the sampled-controller skeleton of the two state-feedback FMUs
//!   ([`controller::SampledController`] over a control law), their presets, pole and limit
//!   parameters.
//!
//! The Kalman family's own code (KalmanFilter, RobustKalmanFilter, DualKalmanFilter, DkfRsKf)
//! is in `spurio-fmu-kalman` (`fmus/kalman/`). An FMU binary links only what it uses of this
//! crate.
#![forbid(unsafe_code)]

pub mod clock;
pub mod controller;
pub mod estimator;
pub mod structured;

use spurio_export::{Config, Failure};

/// A parameter error of the `spurio` models as an `fmi2Error` naming the parameter.
pub fn param_failure(e: &spurio::ParameterError) -> Failure {
    Failure::error(e.to_string())
}

/// `h_max · |λ|max` above which RK4 substeps are refused (RK4's real-axis stability limit is
/// 2.785).
pub const RK4_STABILITY_MARGIN: f64 = 2.5;

/// The RK4 substep bound `h_max` (> 0) of a model whose fastest mode is `fastest` [1/s]:
/// refused, naming `h_max`, when RK4 would be unstable on that mode (`mode` describes it in
/// the message).
pub fn rk4_substep(h_max: f64, fastest: f64, mode: &str) -> Result<f64, Failure> {
    let h_max = spurio::require_positive("h_max", h_max).map_err(Failure::error)?;
    let product = h_max * fastest;
    if product.is_nan() || product > RK4_STABILITY_MARGIN {
        return Err(Failure::error(format!(
            "parameter `h_max`: {h_max} s would make RK4 unstable on {mode}; use at most {:.3e} s",
            RK4_STABILITY_MARGIN / fastest
        )));
    }
    Ok(h_max)
}

/// The bundled variant of the controllers: the crane (n = 4, `preset = crane`).
pub fn crane_controller_config() -> Config {
    let mut config = Config::new();
    config.set(controller::CONFIG_STATES, 4);
    config.set(controller::CONFIG_PRESET, "crane");
    config
}

/// What [`fmu_state!`] expands to refers to.
#[doc(hidden)]
pub mod reexport {
    pub use spurio::ode::check_substeps;
    pub use spurio::state::PlainState;
    pub use spurio_export::{ByteReader, ByteWriter, Cause, Context};
}

/// Implements `FmuModel::check_step`, inside `impl FmuModel for …`, for a plant integrated in
/// RK4 substeps of at most `self.<h_max>`: a communication step that would need more substeps
/// than one call may take ([`spurio::ode::check_substeps`]) is refused before anything moves.
#[macro_export]
macro_rules! rk4_check_step {
    ($h_max:ident) => {
        fn check_step(
            &self,
            _ctx: &$crate::reexport::Context,
            _time: f64,
            step: f64,
        ) -> ::std::result::Result<(), $crate::reexport::Cause> {
            $crate::reexport::check_substeps(step, self.$h_max)?;
            ::std::result::Result::Ok(())
        }
    };
}

/// The check every RK4 plant FMU passes, on a harness `h` initialised with `h_max` = 1 ns: a
/// step of `long_step` and one of 1e308 s, each needing more substeps than one call may take,
/// are refused at once (in well under 0.1 s) with `fmi2Error`, and the log names the step, `h_max`
/// and the bound. What went otherwise is the error. The caller checks that the FMU stayed where
/// it was.
pub fn refuses_too_many_substeps<M: spurio_export::FmuModel>(
    h: &mut spurio_export::harness::Harness<M>,
    long_step: f64,
) -> Result<(), String> {
    for step in [long_step, 1e308] {
        let words = [
            "fmi2DoStep: step refused",
            "h_max = 0.000000001",
            "more than the 100000",
        ];
        h.refuses_at_once(0.1, &words, |h| h.do_step(0.0, step))
            .map_err(|e| format!("a step of {step} s: {e}"))?;
    }
    Ok(())
}

/// One communication step of a plant, taken on a copy by `advance`: the copy replaces `plant`
/// only if `finite` holds for it; otherwise the step fails with the message `non_finite()` and
/// `plant` is left as it was.
pub fn advance_finite<P: Clone>(
    plant: &mut P,
    advance: impl FnOnce(&mut P),
    finite: impl FnOnce(&P) -> bool,
    non_finite: impl FnOnce() -> String,
) -> Result<(), Failure> {
    let mut next = plant.clone();
    advance(&mut next);
    if !finite(&next) {
        return Err(Failure::error(non_finite()));
    }
    *plant = next;
    Ok(())
}

/// Implements `FmuModel::save_state` and `load_state`, inside `impl FmuModel for …`, as the
/// plain-bytes snapshots ([`spurio::state::PlainState`]) of the listed fields, in order: the
/// FMU state is derived from the model's own types, not written by hand. Fields rebuilt from
/// the configuration (layouts) are left out. A failed load changes nothing.
///
/// With `; check = f` (`f: fn(&Self) -> Result<(), Cause>`), the loaded model is validated by
/// `f` before it is accepted (parameters in range, finite state…): bytes that decode but
/// describe a model that could not exist are refused, and the model is left as it was.
#[macro_export]
macro_rules! fmu_state {
    ($($field:ident),+ $(,)?) => {
        $crate::fmu_state!($($field),+; check = |_: &Self| ::std::result::Result::Ok(()));
    };
    ($($field:ident),+; check = $check:expr) => {
        fn save_state(&self, out: &mut $crate::reexport::ByteWriter) {
            let mut bytes = ::std::vec::Vec::new();
            $($crate::reexport::PlainState::save(&self.$field, &mut bytes);)+
            out.put_bytes(&bytes);
        }

        fn load_state(
            &mut self,
            input: &mut $crate::reexport::ByteReader,
        ) -> ::std::result::Result<(), $crate::reexport::Cause> {
            let bytes = input.byte_vec()?;
            let mut rest = bytes.as_slice();
            $(let $field = $crate::reexport::PlainState::read(&mut rest)
                .map_err(|e| format!("{}: {e}", stringify!($field)))?;)+
            // Swap the loaded fields in (the locals then hold the previous ones).
            $(let $field = ::std::mem::replace(&mut self.$field, $field);)+
            let check: fn(&Self) -> ::std::result::Result<(), $crate::reexport::Cause> = $check;
            if let ::std::result::Result::Err(e) = check(&*self) {
                $(self.$field = $field;)+
                return ::std::result::Result::Err(e);
            }
            ::std::result::Result::Ok(())
        }
    };
}

/// A configuration from `(key, value)` pairs.
pub fn config(pairs: &[(&str, &str)]) -> Config {
    let mut c = Config::new();
    for (k, v) in pairs {
        c.set(k, v);
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rk4_substep_is_refused_beyond_the_stability_margin() {
        assert_eq!(rk4_substep(0.25, 10.0, "the mode").unwrap(), 0.25);
        let Err(Failure::Error(message)) = rk4_substep(0.3, 10.0, "the test mode (10 1/s)") else {
            panic!("h_max · |λ| = 3 > 2.5 must be refused");
        };
        assert_eq!(
            message.to_string(),
            "parameter `h_max`: 0.3 s would make RK4 unstable on the test mode (10 1/s); use at most 2.500e-1 s"
        );
        assert!(rk4_substep(0.0, 10.0, "the mode").is_err());
        assert!(rk4_substep(0.1, f64::NAN, "the mode").is_err());
    }
}
