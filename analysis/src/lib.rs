//! spurio-analysis: what is read off a run's results, shared by the command line (`spurio
//! diagnose`, `spurio run --plot`), the papers' experiments and the benchmarks: the outlier
//! [`diagnostics`] (two-sided Grubbs test, excess kurtosis, skewness, E_res) and the command
//! that applies them to a results CSV ([`diagnose`]), summary [`stats`] of Monte-Carlo runs,
//! and the [`plot`]s (time series, histograms, heat maps).
//!
//! Its modules import one way: `diagnose` → `plot`, `diagnostics`; `stats` stands alone.

#![forbid(unsafe_code)]

pub mod diagnose;
pub mod diagnostics;
pub mod plot;
pub mod stats;

pub use stats::median;
