//! FMU adapters.
