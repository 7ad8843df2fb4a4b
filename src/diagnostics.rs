//! Outlier diagnostics (SPEC §3).
