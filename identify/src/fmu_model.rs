//! An FMU as a [`PredictionErrorModel`] (docs/estimators.md, "Maximum likelihood on an FMU"):
//! at fixed θ (the FMU's free parameters, then the variances of the measured variables when
//! they are estimated) the online filter of [`crate::filter`] (unscented or extended, by its
//! settings) over the FMU's states gives
//! the prediction errors v_t and their covariances F_t = S_t of the innovations likelihood,
//! so that [`crate::maximise_likelihood`] fits the FMU's parameters.
//!
//! **Robust loss.** With [`Loss::Huber`] each channel's term ½ v²/F becomes ρ(v/√F), ρ(r) = r²/2 for |r| ≤ c and c|r| − c²/2 beyond
//! (Huber's loss): the predictor reports the pseudo-residual ṽ = sgn(v) √(2ρ(v/√F)) √F, for
//! which ½ ṽ²/F = ρ, and a diagonal F (the channels taken apart). The curvature at the
//! optimum is then that of the Huber loss (standard errors from it are those of the
//! M-estimator's Hessian, without the sandwich correction). The filter itself corrects
//! without robust weights: with weights, a model far from the truth (a wrong coefficient of
//! restitution, whose first bounce misses the data) would have every later innovation taken
//! for an outlier, the filter would stop following the data and the loss would go flat in
//! θ; corrected fully, the filter follows the data and an outlier moves the state for a
//! sample or two, while the loss bounds each prediction error's influence.

use crate::filter::{Filter, FilterSettings};
use crate::plant::FmuPlant;
use nalgebra::{DMatrix, DVector};
use spurio::estimation::likelihood::{
    LikelihoodError, OneStepPredictor, PredictionError, PredictionErrorModel,
};
use spurio::estimation::EstimationError;
use std::cell::RefCell;
use std::rc::Rc;

/// The loss of the prediction errors.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Loss {
    /// The Gaussian innovations likelihood.
    Gaussian,
    /// Huber's loss with threshold c (module documentation).
    Huber { c: f64 },
}

/// The FMU model over a record sampled at `times` (module documentation).
#[derive(Debug)]
pub struct FmuModel {
    plant: Rc<RefCell<FmuPlant>>,
    times: Rc<Vec<f64>>,
    names: Vec<String>,
    /// The filter: its Q_x and linearisation, and R when the variances are not in θ.
    filter: FilterSettings,
    /// Whether the variances of the measured variables are in θ (after the parameters).
    variances_free: bool,
    loss: Loss,
}

/// The name of the variance of measured variable `output` as a free parameter.
pub fn variance_name(output: &str) -> String {
    format!("var({output})")
}

impl FmuModel {
    /// The model of `plant` sampled at `times`, filtered by `filter` (its robust weights
    /// left out: module documentation); the variances of the measured variables estimated
    /// (named [`variance_name`], after the FMU's parameters in θ) when `variances_free`, else
    /// the filter's R.
    pub fn new(
        plant: Rc<RefCell<FmuPlant>>,
        times: Vec<f64>,
        filter: FilterSettings,
        variances_free: bool,
        loss: Loss,
    ) -> Self {
        let names = {
            let pl = plant.borrow();
            let mut names: Vec<String> = pl.parameters().iter().map(|p| p.name.clone()).collect();
            if variances_free {
                names.extend(pl.output_names().iter().map(|name| variance_name(name)));
            }
            names
        };
        Self {
            plant,
            times: Rc::new(times),
            names,
            filter: FilterSettings {
                robust: None,
                ..filter
            },
            variances_free,
            loss,
        }
    }
}

/// The filter at fixed θ over the samples, one per step.
#[derive(Debug)]
pub struct FmuPredictor {
    filter: Filter,
    /// The trajectory column the filter writes (not kept).
    column: Vec<f64>,
    times: Rc<Vec<f64>>,
    sample: usize,
    loss: Loss,
}

/// A sample's vector (inputs, outputs).
type Vector = DVector<f64>;

impl OneStepPredictor for FmuPredictor {
    fn step(
        &mut self,
        u: &Vector,
        y: &Vector,
        error: &mut PredictionError,
    ) -> Result<(), EstimationError> {
        let time = *self
            .times
            .get(self.sample)
            .ok_or(EstimationError::Dimension {
                what: "samples (more than the record's times)",
                expected: self.times.len(),
                got: self.sample + 1,
            })?;
        let errors = self
            .filter
            .step(time, u.as_slice(), y.as_slice(), &mut self.column)
            .map_err(|e| EstimationError::Design {
                what: "the FMU's filter",
                reason: e.to_string(),
            })?;
        let (v, f) = (errors.v, errors.f);
        self.sample += 1;
        match self.loss {
            Loss::Gaussian => {
                error.v = v;
                error.f = f;
            }
            Loss::Huber { c } => {
                let k = v.len();
                let mut pseudo = DVector::zeros(k);
                let mut diagonal = DMatrix::zeros(k, k);
                for a in 0..k {
                    let sd = f[(a, a)].sqrt();
                    let r = v[a] / sd;
                    let rho = if r.abs() <= c {
                        0.5 * r * r
                    } else {
                        c * r.abs() - 0.5 * c * c
                    };
                    pseudo[a] = r.signum() * (2.0 * rho).sqrt() * sd;
                    diagonal[(a, a)] = f[(a, a)];
                }
                error.v = pseudo;
                error.f = diagonal;
            }
        }
        Ok(())
    }
}

impl PredictionErrorModel for FmuModel {
    type Predictor = FmuPredictor;

    fn outputs(&self) -> usize {
        self.filter.noise.measurement.len()
    }

    fn inputs(&self) -> usize {
        self.plant.borrow().input_names().len()
    }

    fn states(&self) -> usize {
        self.plant.borrow().states()
    }

    fn parameter_names(&self) -> &[String] {
        &self.names
    }

    fn predictor(
        &self,
        theta: &[f64],
        x0: DVector<f64>,
        p0: DMatrix<f64>,
    ) -> Result<FmuPredictor, LikelihoodError> {
        let free = self.plant.borrow().parameters().len();
        if theta.len() != self.names.len() {
            return Err(LikelihoodError::Initialisation(format!(
                "{} values for the {} free parameters {}",
                theta.len(),
                self.names.len(),
                self.names.join(", ")
            )));
        }
        let mut settings = self.filter.clone();
        if self.variances_free {
            settings.noise.measurement = theta[free..].to_vec();
        }
        self.plant.borrow_mut().start_afresh();
        let filter = Filter::new(
            self.plant.clone(),
            &theta[..free],
            &[],
            x0.as_slice(),
            p0,
            &settings,
        )
        .map_err(|e| LikelihoodError::Initialisation(e.to_string()))?;
        let column = vec![0.0; 2 * filter.filter_states() + 3 * settings.noise.measurement.len()];
        Ok(FmuPredictor {
            filter,
            column,
            times: self.times.clone(),
            sample: 0,
            loss: self.loss,
        })
    }
}
