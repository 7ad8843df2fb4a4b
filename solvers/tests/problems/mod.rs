//! What the solvers' integration tests share: the model error and Robertson's problem.

use spurio_solvers::OdeSystem;

#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct ModelError(pub String);

/// Robertson's chemical kinetics (Hairer & Wanner, *Solving ODEs II*, §IV.1, (1.4)):
/// rate constants 0.04, 10⁴, 3·10⁷; stiff.
pub struct Robertson;

impl OdeSystem for Robertson {
    type Error = ModelError;
    fn rhs(&mut self, _t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), ModelError> {
        dy[0] = -0.04 * y[0] + 1e4 * y[1] * y[2];
        dy[2] = 3e7 * y[1] * y[1];
        dy[1] = -dy[0] - dy[2];
        Ok(())
    }
}
