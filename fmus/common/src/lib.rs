//! What several spurio FMUs share and that knows the `spurio` models (the FMI-generic
//! plumbing is in `spurio-export`):
//! - [`structured`]: vector and matrix variables (`x_hat[1]`, `A[1,1]`) as blocks;
//! - [`estimator`]: the one generic estimator adapter ([`estimator::EstimatorFmu`]) and its
//!   input checks;
//! - [`kalman`], [`dual`]: the sKF/rsKF and DKF/DKF-rsKF estimators behind their FMUs;
//! - [`controller`]: presets, pole and limit parameters of the two state-feedback FMUs.
//!
//! An FMU binary links only what it uses of this crate.
#![forbid(unsafe_code)]

pub mod controller;
pub mod dual;
pub mod estimator;
pub mod kalman;
pub mod structured;

use spurio_export::{Config, Failure};

/// A parameter error of the `spurio` models as an `fmi2Error` naming the parameter.
pub fn param_failure(e: &spurio::ParameterError) -> Failure {
    Failure::error(e.to_string())
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
    pub use spurio::state::PlainState;
    pub use spurio_export::{ByteReader, ByteWriter, Cause};
}

/// Implements `FmuModel::save_state` and `load_state`, inside `impl FmuModel for …`, as the
/// plain-bytes snapshots ([`spurio::state::PlainState`]) of the listed fields, in order: the
/// FMU state is derived from the model's own types, not written by hand. Fields rebuilt from
/// the configuration (layouts) are left out. A failed load changes nothing.
#[macro_export]
macro_rules! fmu_state {
    ($($field:ident),+ $(,)?) => {
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
            $(self.$field = $field;)+
            Ok(())
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
