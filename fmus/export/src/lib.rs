//! The export layer shared by every spurio FMU: the FMI 2.0 and FMI 3.0 fronts, Co-Simulation
//! and (for the models that offer it) Model Exchange.
//!
//! One implementation of the FMI plumbing for all FMUs, with no dependencies, in layers whose
//! imports point one way (a module uses only those listed after it):
//!
//! - [`export_fmu!`]: emits the `fmi2*`, `fmi3*` and query symbols of one FMU binary for a
//!   model type, with its bundled variants; [`harness`] and [`testing`]: the in-process driver
//!   and the checks every FMU crate runs on itself; [`query`]: the non-FMI questions a
//!   packager asks a built library (bundled variants, model description of a configuration);
//! - the fronts [`fmi2`] and [`fmi3`], of the same shape: the C entry points and their
//!   argument checks, each with its own C types and messages;
//! - [`abi`]: what both fronts share below their C signatures: the instance handle and the
//!   guarded call on it, the one instantiation routine (variant, GUID, resources), the value
//!   kinds, the FMU-state and the common Model Exchange entry points;
//! - [`guard`]: `catch_unwind` around every call, the panic hook and the call marker;
//! - [`instance`]: one instance, split by concern: the state machine with both versions'
//!   masks, values and access checks, stepping and roll-back, FMU states, logging, Model
//!   Exchange;
//! - [`model`]: the safe trait a model implements (`describe`, `create`, `initialize`,
//!   `do_step`, state save/load; [`ModelExchange`]);
//! - [`description`]: the model identity and `modelDescription.xml` of both versions,
//!   generated from the table (so the XML and the binary cannot disagree), with a GUID hashed
//!   from the interface; the FMI 3.0 arrays over the table; the Model Exchange interface;
//! - [`values`], [`variables`]: the values of an instance and the variable table
//!   (value reference = index);
//! - [`types`], [`bytes`], [`uri`]: the C types of the standard headers, the byte format of
//!   FMU states, resource URIs.
//!
//! One piece of process-wide state: the interfaces ([`instance::interface()`]: the model
//! description, the access table of the get/set checks, the FMI 3.0 arrays), built once per
//! model and configuration and shared read-only by their instances; everything else an
//! instance owns, so any number of instances of any number of FMUs live in one process.
//! Once initialised, an instance's set/step/get calls allocate nothing in this layer
//! (`tests/allocations.rs`; every FMU: `tests/allocations/run`).

pub mod abi;
pub mod bytes;
pub mod description;
pub mod fmi2;
pub mod fmi3;
pub mod guard;
pub mod harness;
pub mod instance;
pub mod model;
pub mod query;
pub mod testing;
pub mod types;
pub mod uri;
pub mod values;
pub mod variables;

pub use bytes::{ByteReader, ByteWriter};
pub use description::model_exchange::ModelExchangeInfo;
pub use description::{Config, DefaultExperiment, ModelInfo};
pub use model::{Cause, Context, EventUpdate, Failure, FmuModel, ModelExchange};
pub use values::Values;
pub use variables::{
    rows, Causality, Initial, Value, Variability, Variable, VariableTable, VariableType,
};

/// Emits, in the crate that builds an FMU's `cdylib`, the FMI 2.0 Co-Simulation C API
/// (`fmi2GetTypesPlatform` … `fmi2GetStringStatus`, see [`fmi2`]) and the FMI 3.0 one
/// (`fmi3GetVersion` …, see [`fmi3`]) for the model type `$model`, the query
/// symbols of [`query`] and `pub fn bundled_variants()`, and a test that the committed model
/// descriptions of those variants are up to date.
///
/// The variants are `(file stem, configuration)` pairs; without any, the FMU has one: its
/// default configuration, named by its model identifier.
///
/// ```ignore
/// spurio_export::export_fmu!(GantryCraneFmu);
/// spurio_export::export_fmu!(SensorFmu, variants = [("Sensor", Config::new()), ("Sensor2", two)]);
/// // Model Exchange too (the model implements `ModelExchange` and its description says
/// // `.with_model_exchange()`):
/// spurio_export::export_fmu!(GantryCraneFmu, model_exchange);
/// spurio_export::export_fmu!(LinearSystemFmu, model_exchange, variants = [("LinearSystem", c)]);
/// ```
#[macro_export]
macro_rules! export_fmu {
    (@with $model:ty, $me:expr, variants = [$(($stem:expr, $config:expr)),* $(,)?]) => {
        /// The Model Exchange functions of this FMU's model, if it offers the interface.
        #[doc(hidden)]
        pub fn spurio_model_exchange() -> ::std::option::Option<$crate::model::Hooks<$model>> {
            $me
        }

        /// The variants of this FMU that are bundled and whose model descriptions are
        /// committed: (file stem, configuration).
        pub fn bundled_variants() -> Vec<$crate::query::Variant> {
            let declared: Vec<$crate::query::Variant> =
                vec![$((::std::string::ToString::to_string(&$stem), $config)),*];
            if declared.is_empty() {
                $crate::query::default_variants::<$model>()
            } else {
                declared
            }
        }

        #[cfg(test)]
        mod bundled_variants_tests {
            #[allow(unused_imports)]
            use super::*;
            #[test]
            fn committed_model_descriptions_match_the_declaration() {
                $crate::testing::check_bundled_variants::<$model>(
                    &super::bundled_variants(),
                    ::std::path::Path::new(env!("CARGO_MANIFEST_DIR")),
                );
            }
            #[test]
            fn model_exchange_is_declared_where_it_is_exported() {
                $crate::testing::check_interfaces::<$model>(
                    &super::bundled_variants(),
                    super::spurio_model_exchange().is_some(),
                );
            }
        }

        mod query_exports {
            #![allow(unsafe_code, clippy::missing_safety_doc)]
            #[allow(unused_imports)]
            use super::*;

            #[no_mangle]
            pub unsafe extern "C" fn spurio_variants(out: *mut u8, capacity: usize) -> usize {
                unsafe { $crate::query::query_variants(super::bundled_variants, out, capacity) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn spurio_describe(
                config: *const ::std::os::raw::c_char,
                out: *mut u8,
                capacity: usize,
            ) -> isize {
                unsafe { $crate::query::query_describe::<$model>(config, out, capacity) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn spurio_describe3(
                config: *const ::std::os::raw::c_char,
                out: *mut u8,
                capacity: usize,
            ) -> isize {
                unsafe {
                    $crate::query::query_describe_with(
                        $crate::query::describe3::<$model>,
                        config,
                        out,
                        capacity,
                    )
                }
            }
        }

        $crate::front_exports!(fmi2_exports, $model, {
            use $crate::fmi2::{ffi, functions, model_exchange as me};
            use $crate::types::*;
        }, fmi2_life_cycle_entries, fmi2_value_entries, fmi2_model_exchange_entries);
        $crate::front_exports!(fmi3_exports, $model, {
            use $crate::abi::kinds::Fmi3;
            use $crate::fmi3::{ffi, functions, model_exchange as me, types::*};
        }, fmi3_life_cycle_entries, fmi3_value_entries, fmi3_model_exchange_entries);
    };
    ($model:ty) => {
        $crate::export_fmu!(@with $model, None, variants = []);
    };
    ($model:ty, model_exchange) => {
        $crate::export_fmu!(@with $model, Some($crate::model::hooks::<$model>()), variants = []);
    };
    ($model:ty, variants = [$($variants:tt)*]) => {
        $crate::export_fmu!(@with $model, None, variants = [$($variants)*]);
    };
    ($model:ty, model_exchange, variants = [$($variants:tt)*]) => {
        $crate::export_fmu!(
            @with $model,
            Some($crate::model::hooks::<$model>()),
            variants = [$($variants)*]
        );
    };
}

/// Emits, inside [`export_fmu!`], the module that holds one front's symbols for the model type
/// `$model`: the front's imports, `M`, then the entries macro of each of the front's files
/// (`fmi2_life_cycle_entries` in [`fmi2::ffi`], …).
#[doc(hidden)]
#[macro_export]
macro_rules! front_exports {
    ($module:ident, $model:ty, { $($import:item)* }, $($entries:ident),+) => {
        mod $module {
            #![allow(unsafe_code, non_snake_case, clippy::missing_safety_doc)]
            #[allow(unused_imports)]
            use super::*;
            $($import)*
            type M = $model;
            $($crate::$entries!();)+
        }
    };
}
