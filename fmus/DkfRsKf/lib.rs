//! The `DkfRsKf` FMU binary: the FMI 2.0 CS symbols for [`spurio_fmus::estimators::dual`].
#![allow(non_snake_case)]

spurio_fmi2::export_fmu!(spurio_fmus::estimators::dual::DkfRsKfFmu);
