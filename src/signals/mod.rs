//! The signal chain of the FMUs (docs/models.md §2.5–§2.6): a portable seeded random generator,
//! the signal sources (step, random steps, PRBS, sine/cosine) and the sensor model (Gaussian
//! noise, ε-contaminated outliers, ADC quantisation).

pub mod rng;
pub mod sensor;
pub mod source;
