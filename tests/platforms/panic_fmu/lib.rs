//! `PanicTest`: y integrates u; a model error when u < -100, a panic when u = 13. Only for
//! the platform tests: the panic must come back as `fmi2Fatal` through the C ABI on win64,
//! linux64 and aarch64-linux alike.
#![allow(non_snake_case)]

mod model;

spurio_export::export_fmu!(model::PanicTest);
