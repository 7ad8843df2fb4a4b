//! The C ABI both fronts ([`crate::fmi2`], [`crate::fmi3`]) stand on: what an FMI entry point
//! does besides mapping its C signature, written once for both versions.
//!
//! - [`slot`]: the instance handle and the guarded call on it (NULL check, panic guard,
//!   allowed-state mask);
//! - [`instantiate`]: the one instantiation routine (name, variant configuration, GUID,
//!   interface);
//! - [`kinds`]: the value kinds of the typed get/set functions;
//! - [`fmu_state`]: the FMU-state functions over the handle;
//! - [`model_exchange`]: the Model Exchange entry points both versions have alike;
//! - [`pointers`]: pointer arguments as slices and strings.
//!
//! Below it: [`crate::instance`] and [`crate::guard`]; nothing here knows a front.

pub mod fmu_state;
pub mod instantiate;
pub mod kinds;
pub mod model_exchange;
pub mod pointers;
pub mod slot;
