//! Tests of the estimator FMU.
