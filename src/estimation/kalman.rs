//! Standard Kalman filter (sKF), docs/estimators.md §2.7; papers 000 §IV (eqs 16–24) and 001 §2.
//!
//! Model: x_{k+1} = A x_k + B u_k + w_k, y_k = C x_k + D u_k + v_k, w ~ N(0, Q), v ~ N(0, R).
//! One call `step(u_k, y_k)`:
//!
//! ```text
//! x⁻ = A x̂_{k−1} + B u_{k−1}                 P⁻ = A P_{k−1} Aᵀ + Q
//! e  = y_k − C x⁻ − D u_k                      (innovation)
//! S  = C P⁻ Cᵀ + R                             K = P⁻ Cᵀ S⁻¹   (Cholesky solve S Kᵀ = C P⁻)
//! x̂_k = x⁻ + K e
//! P_k = (I − K C) P⁻ (I − K C)ᵀ + K R Kᵀ       (Joseph form, on one triangle, mirrored)
//! ŷ_k = C x̂_k + D u_k                          (filtered output)
//! ```
//!
//! Paper 000 prints P⁻ = P + Q: the special case A = I. The Joseph form equals
//! P = (I − K C) P⁻ for the optimal gain and keeps P symmetric positive (semi)definite in
//! floating point; it is evaluated in O(n²p) as P⁻ − K G + (K S − Gᵀ) Kᵀ with G = C P⁻, the
//! same matrix for any K (see `FilterCore`). `u_{k−1}` is zero before the first call; x̂₀, P₀
//! are the estimate one sample before the first measurement.

use super::missing::MissingMask;
use super::{
    require_input_length, require_length, require_psd, require_spd, EstimationError, Saved,
    StateReader,
};
use crate::linalg::dense::{self, View};
use crate::state_space::StateSpace;
use nalgebra::{DMatrix, DVector};

/// The accessors of a filter built on a [`FilterCore`] (field `core`) and a [`StateSpace`]
/// (field `model`): the sKF and the rsKF.
macro_rules! core_accessors {
    () => {
        /// Filtered state x̂_{k|k}.
        pub fn state(&self) -> &DVector<f64> {
            &self.core.x
        }
        /// Covariance P_{k|k} of the filtered state.
        pub fn covariance(&self) -> &DMatrix<f64> {
            &self.core.p
        }
        /// Predicted state x⁻ = x̂_{k|k−1} of the last step.
        pub fn predicted_state(&self) -> &DVector<f64> {
            &self.core.x_prior
        }
        /// Filtered output ŷ = C x̂_{k|k} + D u_k (for the rsKF: the cleaned output).
        pub fn output(&self) -> &DVector<f64> {
            &self.core.output
        }
        /// Innovation e = y_k − C x⁻ − D u_k of the last step.
        pub fn innovation(&self) -> &DVector<f64> {
            &self.core.innovation
        }
        /// Gain K (n×p) of the last step.
        pub fn gain(&self) -> DMatrix<f64> {
            self.core.gain_t.transpose()
        }
        /// Number of steps processed.
        pub fn steps(&self) -> u64 {
            self.core.steps
        }
        /// Number of states n.
        pub fn states(&self) -> usize {
            self.model.states()
        }
        /// Number of inputs m.
        pub fn inputs(&self) -> usize {
            self.model.inputs()
        }
        /// Number of outputs p.
        pub fn outputs(&self) -> usize {
            self.model.outputs()
        }
    };
}
pub(crate) use core_accessors;

/// The prediction / correction machinery shared by the sKF, the rsKF and the DKF's state
/// filter. It owns the estimate, the covariance and every work buffer; the model matrices are
/// passed in (the DKF changes them every step, the rsKF changes the measurement covariance).
///
/// The covariances are computed on their lower triangle and mirrored (exactly symmetric):
/// the prediction as W = P Aᵀ, then P⁻ = A W + Q on one triangle; the correction in
/// O(n²p) instead of the O(n³) of the Joseph form's products, with G = C P⁻ (p×n) and
/// S = G Cᵀ + R:
///
/// ```text
/// P = (I − K C) P⁻ (I − K C)ᵀ + K R Kᵀ = P⁻ − K G − Gᵀ Kᵀ + K S Kᵀ = P⁻ − K G + H Kᵀ,
/// H = K S − Gᵀ   (n×p; zero in exact arithmetic for the optimal gain)
/// ```
///
/// an identity for any K (expand (I − K C) P⁻ (I − K C)ᵀ with P⁻ = P⁻ᵀ), so the update keeps
/// the Joseph form's tolerance of a gain that is not exactly optimal (the rsKF's, or one
/// rounded). A one-state, one-output filter evaluates the Joseph form as written, which is
/// as cheap there: (1 − k c)·(P⁻ (1 − k c)) + k (r k).
#[derive(Debug, Clone)]
pub(crate) struct FilterCore {
    pub(crate) x: DVector<f64>,
    pub(crate) p: DMatrix<f64>,
    pub(crate) x_prior: DVector<f64>,
    pub(crate) p_prior: DMatrix<f64>,
    pub(crate) u_prev: DVector<f64>,
    pub(crate) innovation: DVector<f64>,
    pub(crate) output: DVector<f64>,
    /// Kᵀ (p×n).
    pub(crate) gain_t: DMatrix<f64>,
    /// K (n×p), the transpose of `gain_t`.
    pub(crate) gain: DMatrix<f64>,
    /// P Aᵀ, n×n.
    work_nn: DMatrix<f64>,
    /// G = C P⁻, p×n.
    work_g: DMatrix<f64>,
    /// H = K S − Gᵀ, n×p.
    work_h: DMatrix<f64>,
    /// n scratch.
    work_n: DVector<f64>,
    /// S = C P⁻ Cᵀ + R, p×p.
    work_s: DMatrix<f64>,
    /// The Cholesky factor of S, p×p.
    work_l: DMatrix<f64>,
    pub(crate) steps: u64,
    /// Tests only: run the general kernels at every size (to hold the fixed ones and the
    /// scalar step to them).
    #[cfg(test)]
    pub(crate) general_only: bool,
}

impl FilterCore {
    pub(crate) fn new(x0: DVector<f64>, p0: DMatrix<f64>, inputs: usize, outputs: usize) -> Self {
        let n = x0.len();
        Self {
            x_prior: x0.clone(),
            p_prior: p0.clone(),
            x: x0,
            p: p0,
            u_prev: DVector::zeros(inputs),
            innovation: DVector::zeros(outputs),
            output: DVector::zeros(outputs),
            gain_t: DMatrix::zeros(outputs, n),
            gain: DMatrix::zeros(n, outputs),
            work_nn: DMatrix::zeros(n, n),
            work_g: DMatrix::zeros(outputs, n),
            work_h: DMatrix::zeros(n, outputs),
            work_n: DVector::zeros(n),
            work_s: DMatrix::zeros(outputs, outputs),
            work_l: DMatrix::zeros(outputs, outputs),
            steps: 0,
            #[cfg(test)]
            general_only: false,
        }
    }

    /// x⁻ = A x̂ + B u_{k−1}, P⁻ = A P Aᵀ + Q.
    pub(crate) fn predict(&mut self, a: View<'_>, b: View<'_>, q: &DMatrix<f64>) {
        self.steps += 1;
        let x_prior = self.x_prior.as_mut_slice();
        dense::gemv_inline(x_prior, 1.0, a, self.x.as_slice(), 0.0);
        dense::gemv_inline(x_prior, 1.0, b, self.u_prev.as_slice(), 1.0);
        // The packaged sizes run kernels of their own (same arithmetic, unrolled).
        let fixed = match self.x.len() {
            #[cfg(test)]
            _ if self.general_only => false,
            2 => fixed::predict::<2>(self, a, q),
            3 => fixed::predict::<3>(self, a, q),
            8 => fixed::predict::<8>(self, a, q),
            _ => false,
        };
        if !fixed {
            self.predict_covariance(a, q, self.x.len());
        }
    }

    /// P⁻ = A P Aᵀ + Q: W = P Aᵀ, then P⁻ = A W + Q on the lower triangle, mirrored.
    fn predict_covariance(&mut self, a: View<'_>, q: &DMatrix<f64>, n: usize) {
        if let ([p], [q], [w], [p_prior]) = (
            self.p.as_slice(),
            q.as_slice(),
            self.work_nn.as_mut_slice(),
            self.p_prior.as_mut_slice(),
        ) {
            // One state: a (P a) + q, the order of the kernels.
            let a = a.at(0, 0);
            *w = p * a;
            *p_prior = a * *w + q;
            return;
        }
        let w = self.work_nn.as_mut_slice();
        dense::gemm(w, 1.0, View::of(&self.p), a.t(), 0.0);
        let p_prior = self.p_prior.as_mut_slice();
        dense::gemm_lower(p_prior, a, View::of(&self.work_nn), q.as_slice());
        dense::mirror_lower(p_prior, n);
    }

    /// e = y − C x⁻ − D u; e_j = 0 for a missing sample y_j = NaN (see [`MissingMask`]).
    /// Errors when a present channel's e_j is not finite (y_j = ±∞, or u not finite).
    pub(crate) fn compute_innovation(
        &mut self,
        c: View<'_>,
        d: View<'_>,
        u: &DVector<f64>,
        y: &DVector<f64>,
    ) -> Result<bool, EstimationError> {
        let e = self.innovation.as_mut_slice();
        for (e, y) in e.iter_mut().zip(y.as_slice()) {
            *e = *y;
        }
        dense::gemv_inline(e, -1.0, c, self.x_prior.as_slice(), 1.0);
        dense::gemv_inline(e, -1.0, d, u.as_slice(), 1.0);
        // Every e_j finite: every sample present (a missing y_j = NaN makes e_j NaN), decided
        // by the one check the step needs anyway; the rest is out of line.
        if dense::all_finite(e) {
            return Ok(false);
        }
        self.innovation_of_missing(y)
    }

    /// The rest of [`FilterCore::compute_innovation`] when some e_j is not finite: a missing
    /// sample (NaN) of channel j has no prediction error to correct with, e_j = 0; what is
    /// then still not finite is an error (a non-finite u, or a y_j = ±∞). Gives whether a
    /// channel is missing.
    #[cold]
    #[inline(never)]
    fn innovation_of_missing(&mut self, y: &DVector<f64>) -> Result<bool, EstimationError> {
        let e = self.innovation.as_mut_slice();
        for (e, y) in e.iter_mut().zip(y.as_slice()) {
            if y.is_nan() {
                *e = 0.0;
            }
        }
        if !dense::all_finite(e) {
            return Err(EstimationError::NonFinite {
                what: "innovation y − C x⁻ − D u (check y and u)",
                step: self.steps,
            });
        }
        Ok(MissingMask::any(y))
    }

    /// The opening of a step on the model's own matrices, the same for the sKF and the rsKF:
    /// checks the lengths of (u_k, y_k), predicts x⁻ = A x̂ + B u_{k−1}, P⁻ = A P Aᵀ + Q
    /// ([`FilterCore::predict`]) and computes e = y − C x⁻ − D u
    /// ([`FilterCore::compute_innovation`]). Gives whether the sample has a missing channel
    /// (a y_j = NaN): the correction then uses the present ones only.
    pub(crate) fn predict_and_innovate(
        &mut self,
        model: &StateSpace,
        u: &DVector<f64>,
        y: &DVector<f64>,
    ) -> Result<bool, EstimationError> {
        let [a, b, c, d] = sample_views(model, u, y)?;
        self.predict(a, b, &model.q);
        self.compute_innovation(c, d, u, y)
    }

    /// Gain from S = C P⁻ Cᵀ + R_eff, state update and covariance update with R_eff (see
    /// the type's documentation).
    pub(crate) fn correct(
        &mut self,
        c: View<'_>,
        r_eff: &DMatrix<f64>,
    ) -> Result<(), EstimationError> {
        // The packaged sizes run kernels of their own (same arithmetic, unrolled).
        let fixed = match (self.x.len(), self.innovation.len()) {
            (1, 1) => Some(self.correct_scalar(c, r_eff)),
            #[cfg(test)]
            _ if self.general_only => None,
            (2, 1) => fixed::correct::<2, 1>(self, c, r_eff),
            (2, 2) => fixed::correct::<2, 2>(self, c, r_eff),
            (3, 2) => fixed::correct::<3, 2>(self, c, r_eff),
            (8, 2) => fixed::correct::<8, 2>(self, c, r_eff),
            _ => None,
        };
        match fixed {
            Some(result) => result?,
            None => self.correct_sized(c, r_eff, self.x.len(), self.innovation.len())?,
        }
        if !(dense::all_finite(self.x.as_slice()) && dense::all_finite(self.p.as_slice())) {
            return Err(EstimationError::NonFinite {
                what: "state estimate or its covariance",
                step: self.steps,
            });
        }
        Ok(())
    }

    /// [`FilterCore::correct`] for n = p = 1: [`joseph_scalar`].
    #[inline(always)]
    fn correct_scalar(&mut self, c: View<'_>, r: &DMatrix<f64>) -> Result<(), EstimationError> {
        let (Some(r), Some(x_prior), Some(p_prior), Some(e)) = (
            one(r.as_slice()),
            one(self.x_prior.as_slice()),
            one(self.p_prior.as_slice()),
            one(self.innovation.as_slice()),
        ) else {
            return Ok(());
        };
        let (k, x, p) = joseph_scalar(c.at(0, 0), r, x_prior, p_prior, e, self.steps)?;
        for (target, value) in [
            (self.gain_t.as_mut_slice(), k),
            (self.gain.as_mut_slice(), k),
            (self.x.as_mut_slice(), x),
            (self.p.as_mut_slice(), p),
        ] {
            if let [v] = target {
                *v = value;
            }
        }
        Ok(())
    }

    /// A whole step of a filter with one state, one output and at most one input, in the
    /// order of the general path (bit-identical to it) without its matrix machinery:
    /// [`ScalarEstimate::step`] on the one entry of each buffer, `r_eff(e)` giving the
    /// measurement covariance of the correction (the rsKF's R̃; the sKF's R). `None` (nothing
    /// done) when the filter or the sample has other sizes: the caller takes the general path.
    #[inline(always)]
    pub(crate) fn step_scalar(
        &mut self,
        model: &StateSpace,
        u: &DVector<f64>,
        y: &DVector<f64>,
        r_eff: impl ScalarCovariance,
    ) -> Option<Result<(), EstimationError>> {
        #[cfg(test)]
        if self.general_only {
            return None;
        }
        let y = one(y.as_slice())?;
        let (scalar, u) = match (ScalarModel::of(model)?, u.as_slice()) {
            (m @ ScalarModel { input: None, .. }, []) => (m, 0.0),
            (m @ ScalarModel { input: Some(_), .. }, [u]) => (m, *u),
            _ => return None,
        };
        let mut estimate = self.scalar_estimate(scalar.input.is_some())?;
        let result = estimate.step(&scalar, u, y, r_eff);
        // Stored whatever the result: a failed step leaves what it produced, as the general
        // path does.
        self.store_scalar(&estimate);
        Some(result)
    }

    /// The estimate of a filter with one state and one output (and one input when
    /// `input`), or `None` for other sizes.
    #[inline(always)]
    pub(crate) fn scalar_estimate(&self, input: bool) -> Option<ScalarEstimate> {
        let u_prev = match (self.u_prev.as_slice(), input) {
            ([], false) => 0.0,
            ([u], true) => *u,
            _ => return None,
        };
        Some(ScalarEstimate {
            x: one(self.x.as_slice())?,
            p: one(self.p.as_slice())?,
            x_prior: one(self.x_prior.as_slice())?,
            p_prior: one(self.p_prior.as_slice())?,
            u_prev,
            innovation: one(self.innovation.as_slice())?,
            output: one(self.output.as_slice())?,
            gain: one(self.gain_t.as_slice())?,
            steps: self.steps,
        })
    }

    /// Writes back what [`FilterCore::scalar_estimate`] gave (the sizes it checked).
    #[inline(always)]
    fn store_scalar(&mut self, s: &ScalarEstimate) {
        for (target, value) in [
            (self.x.as_mut_slice(), s.x),
            (self.p.as_mut_slice(), s.p),
            (self.x_prior.as_mut_slice(), s.x_prior),
            (self.p_prior.as_mut_slice(), s.p_prior),
            (self.u_prev.as_mut_slice(), s.u_prev),
            (self.innovation.as_mut_slice(), s.innovation),
            (self.output.as_mut_slice(), s.output),
            (self.gain_t.as_mut_slice(), s.gain),
            (self.gain.as_mut_slice(), s.gain),
        ] {
            if let [v] = target {
                *v = value;
            }
        }
        self.steps = s.steps;
    }

    /// [`FilterCore::correct`] for n states and p outputs, any sizes.
    fn correct_sized(
        &mut self,
        c: View<'_>,
        r_eff: &DMatrix<f64>,
        n: usize,
        p: usize,
    ) -> Result<(), EstimationError> {
        // G = C P⁻, S = R + G Cᵀ, Kᵀ = S⁻¹ G (Cholesky, S symmetric).
        let g = self.work_g.as_mut_slice();
        dense::gemm(g, 1.0, c, View::of(&self.p_prior), 0.0);
        self.work_s.copy_from(r_eff);
        let s = self.work_s.as_mut_slice();
        dense::gemm(s, 1.0, View::of(&self.work_g), c.t(), 1.0);
        self.work_l.copy_from(&self.work_s);
        let l = self.work_l.as_mut_slice();
        if l.iter().any(|v| !v.is_finite()) {
            return Err(EstimationError::NonFinite {
                what: INNOVATION_COVARIANCE,
                step: self.steps,
            });
        }
        if !dense::cholesky(l, p) {
            return Err(EstimationError::Factorisation {
                what: INNOVATION_COVARIANCE,
                step: self.steps,
            });
        }
        self.gain_t.copy_from(&self.work_g);
        dense::cholesky_solve(l, p, self.gain_t.as_mut_slice());
        self.gain.tr_copy_from(&self.gain_t);
        // x̂ = x⁻ + K e.
        let ke = self.work_n.as_mut_slice();
        dense::gemv(
            ke,
            1.0,
            View::of(&self.gain),
            self.innovation.as_slice(),
            0.0,
        );
        for ((x, prior), ke) in self.x.iter_mut().zip(self.x_prior.iter()).zip(ke.iter()) {
            *x = prior + ke;
        }
        // H = K S − Gᵀ, then P = P⁻ − K G + H Kᵀ on the lower triangle, mirrored.
        let (k, g, s) = (
            self.gain.as_slice(),
            self.work_g.as_slice(),
            self.work_s.as_slice(),
        );
        let h = self.work_h.as_mut_slice();
        if k.len() < n * p || g.len() < n * p || s.len() < p * p || h.len() < n * p {
            return Ok(());
        }
        for l in 0..p {
            for i in 0..n {
                let mut v = -g[l + i * p];
                for j in 0..p {
                    v += k[i + j * n] * s[j + l * p];
                }
                h[i + l * n] = v;
            }
        }
        let (p_prior, p_new) = (self.p_prior.as_slice(), self.p.as_mut_slice());
        if p_prior.len() < n * n || p_new.len() < n * n {
            return Ok(());
        }
        for j in 0..n {
            for i in j..n {
                let mut v = p_prior[i + j * n];
                for l in 0..p {
                    v += h[i + l * n] * k[j + l * n] - k[i + l * n] * g[l + j * p];
                }
                p_new[i + j * n] = v;
            }
        }
        dense::mirror_lower(p_new, n);
        Ok(())
    }

    /// The correction of a sample with missing channels (Cipra & Romera 1997: the update
    /// with the present channels only; docs/estimators.md, "Missing samples"). With
    /// every channel missing there is nothing to correct with: x̂ = x⁻, P = P⁻ = A P Aᵀ + Q,
    /// K = 0. Otherwise the correction of [`FilterCore::correct`] with the [`MissingMask`]'s
    /// C and R (the rows of C and R of the present channels selected), which is exactly the
    /// update of the present channels: their gain, x̂ and P as with C and R reduced to
    /// them, and K = 0 for the missing ones. `c` and `r` are the model's C and measurement
    /// covariance of the step (the rsKF passes its R̃, already masked).
    pub(crate) fn correct_present(
        &mut self,
        mask: &mut MissingMask,
        c: View<'_>,
        r: &DMatrix<f64>,
        y: &DVector<f64>,
    ) -> Result<(), EstimationError> {
        if mask.select(c, r, y) == y.len() {
            return self.predict_only();
        }
        self.correct(View::of(&mask.c), &mask.r)
    }

    /// x̂ = x⁻, P = P⁻, K = 0: the step of a sample with every channel missing.
    pub(crate) fn predict_only(&mut self) -> Result<(), EstimationError> {
        self.x.copy_from(&self.x_prior);
        self.p.copy_from(&self.p_prior);
        self.gain.fill(0.0);
        self.gain_t.fill(0.0);
        if !(dense::all_finite(self.x.as_slice()) && dense::all_finite(self.p.as_slice())) {
            return Err(non_finite("state estimate or its covariance", self.steps));
        }
        Ok(())
    }

    /// Errors when the fitted output ŷ is not finite: with missing channels the innovation
    /// no longer sees every entry of u, so a non-finite u is caught here.
    pub(crate) fn check_output(&self) -> Result<(), EstimationError> {
        if !dense::all_finite(self.output.as_slice()) {
            return Err(non_finite("fitted output C x̂ + D u (check u)", self.steps));
        }
        Ok(())
    }

    /// ŷ = C x̂ + D u, and remembers u for the next prediction.
    pub(crate) fn finish(&mut self, c: View<'_>, d: View<'_>, u: &DVector<f64>) {
        let y = self.output.as_mut_slice();
        dense::gemv_inline(y, 1.0, c, self.x.as_slice(), 0.0);
        dense::gemv_inline(y, 1.0, d, u.as_slice(), 1.0);
        for (u_prev, u) in self.u_prev.as_mut_slice().iter_mut().zip(u.as_slice()) {
            *u_prev = *u;
        }
    }
}

/// The filter core's kernels for N states and P outputs known at compile time: the operands
/// copied into arrays of columns, loops the compiler unrolls, the same arithmetic in the same
/// order as [`FilterCore::predict_covariance`] and [`FilterCore::correct_sized`]
/// (bit-identical to them). Each gives up (`false`, `None`) when a buffer does not have the
/// size it is built for, and the caller takes the general path.
mod fixed {
    use super::{EstimationError, FilterCore, INNOVATION_COVARIANCE};
    use crate::linalg::dense::{self, View};
    use nalgebra::DMatrix;

    /// The C columns of R entries each of a view.
    #[inline(always)]
    fn load<const R: usize, const C: usize>(v: View<'_>) -> [[f64; R]; C] {
        let mut out = [[0.0; R]; C];
        for (j, column) in out.iter_mut().enumerate() {
            match v.column(j).and_then(|c| <&[f64; R]>::try_from(c).ok()) {
                Some(c) => *column = *c,
                None => {
                    for (i, value) in column.iter_mut().enumerate() {
                        *value = v.at(i, j);
                    }
                }
            }
        }
        out
    }

    /// A column-major R×C matrix stored in `s` as its columns.
    #[inline(always)]
    fn columns<const R: usize, const C: usize>(s: &[f64]) -> Option<&[[f64; R]; C]> {
        <&[[f64; R]; C]>::try_from(s.as_chunks::<R>().0).ok()
    }

    #[inline(always)]
    fn columns_mut<const R: usize, const C: usize>(s: &mut [f64]) -> Option<&mut [[f64; R]; C]> {
        <&mut [[f64; R]; C]>::try_from(s.as_chunks_mut::<R>().0).ok()
    }

    /// `start + Σₖ columns[k] · weight(k)` (start 0 when `None`), summed term by term from
    /// the first column: the order of the general kernels' products.
    #[inline(always)]
    fn combination<const R: usize, const K: usize>(
        columns: &[[f64; R]; K],
        weight: impl Fn(usize) -> f64,
        start: Option<&[f64; R]>,
    ) -> [f64; R] {
        let mut sum = [0.0; R];
        for (k, column) in columns.iter().enumerate() {
            let s = weight(k);
            for (r, (sum, x)) in sum.iter_mut().zip(column).enumerate() {
                *sum = match (k, start) {
                    (0, None) => x * s,
                    (0, Some(start)) => start[r] + x * s,
                    _ => *sum + x * s,
                };
            }
        }
        sum
    }

    /// P⁻ = A P Aᵀ + Q: W = P Aᵀ, then P⁻ = A W + Q on the lower triangle, mirrored.
    #[inline(always)]
    pub(super) fn predict<const N: usize>(
        core: &mut FilterCore,
        a: View<'_>,
        q: &DMatrix<f64>,
    ) -> bool {
        let (Some(p), Some(q)) = (
            columns::<N, N>(core.p.as_slice()),
            columns::<N, N>(q.as_slice()),
        ) else {
            return false;
        };
        let Some(p_prior) = columns_mut::<N, N>(core.p_prior.as_mut_slice()) else {
            return false;
        };
        // a[k][i] = A(i, k).
        let a = load::<N, N>(a);
        // Column j of W: Σₖ P(:, k) A(j, k).
        let mut w = [[0.0; N]; N];
        for (j, w) in w.iter_mut().enumerate() {
            *w = combination(p, |k| a[k][j], None);
        }
        // Column j of P⁻: A(i, 0) W(0, j) + Q(i, j) + Σₖ A(i, k) W(k, j), kept on rows j..
        // (whole columns vectorise better than their lower parts; the upper part is the
        // mirror of the lower one).
        for j in 0..N {
            let column = combination(&a, |k| w[j][k], Some(&q[j]));
            for i in j..N {
                p_prior[j][i] = column[i];
                p_prior[i][j] = column[i];
            }
        }
        true
    }

    /// The correction of [`FilterCore::correct`] (without its final finiteness check).
    #[inline(always)]
    pub(super) fn correct<const N: usize, const P: usize>(
        core: &mut FilterCore,
        c: View<'_>,
        r: &DMatrix<f64>,
    ) -> Option<Result<(), EstimationError>> {
        let p_prior = columns::<N, N>(core.p_prior.as_slice())?;
        let r = columns::<P, P>(r.as_slice())?;
        let e = <&[f64; P]>::try_from(core.innovation.as_slice()).ok()?;
        // c[k][l] = C(l, k).
        let c = load::<P, N>(c);
        // G = C P⁻: column j is Σₖ C(:, k) P⁻(k, j).
        let mut g = [[0.0; P]; N];
        for (j, g) in g.iter_mut().enumerate() {
            *g = combination(&c, |k| p_prior[j][k], None);
        }
        // S = R + G Cᵀ: column l is G(:, 0) C(l, 0) + R(:, l) + Σₖ G(:, k) C(l, k).
        let mut s = [[0.0; P]; P];
        for (l, column) in s.iter_mut().enumerate() {
            *column = combination(&g, |k| c[k][l], Some(&r[l]));
        }
        let mut factor = s;
        let steps = core.steps;
        let failed = |error: fn(&'static str, u64) -> EstimationError| {
            Some(Err(error(INNOVATION_COVARIANCE, steps)))
        };
        if factor.as_flattened().iter().any(|v| !v.is_finite()) {
            return failed(|what, step| EstimationError::NonFinite { what, step });
        }
        if !dense::cholesky(factor.as_flattened_mut(), P) {
            return failed(|what, step| EstimationError::Factorisation { what, step });
        }
        // Kᵀ = S⁻¹ G, K its transpose.
        let mut gain_t = g;
        dense::cholesky_solve(factor.as_flattened(), P, gain_t.as_flattened_mut());
        let mut gain = [[0.0; N]; P];
        for (i, row) in gain_t.iter().enumerate() {
            for (l, k) in row.iter().enumerate() {
                gain[l][i] = *k;
            }
        }
        // x̂ = x⁻ + K e.
        let mut ke = [0.0; N];
        for (ke, k) in ke.iter_mut().zip(&gain[0]) {
            *ke = k * e[0];
        }
        for l in 1..P {
            for (ke, k) in ke.iter_mut().zip(&gain[l]) {
                *ke += k * e[l];
            }
        }
        for ((x, prior), ke) in core.x.iter_mut().zip(core.x_prior.iter()).zip(&ke) {
            *x = prior + ke;
        }
        // H = K S − Gᵀ, then P = P⁻ − K G + H Kᵀ on the lower triangle, mirrored.
        let mut h = [[0.0; N]; P];
        for (l, h) in h.iter_mut().enumerate() {
            for (i, h) in h.iter_mut().enumerate() {
                let mut v = -g[i][l];
                for j in 0..P {
                    v += gain[j][i] * s[l][j];
                }
                *h = v;
            }
        }
        let p_new = columns_mut::<N, N>(core.p.as_mut_slice())?;
        for j in 0..N {
            for i in j..N {
                let mut v = p_prior[j][i];
                for l in 0..P {
                    v += h[l][i] * gain[l][j] - gain[l][i] * g[j][l];
                }
                p_new[j][i] = v;
                p_new[i][j] = v;
            }
        }
        // Whole arrays assigned: moves of a known size, no call to memcpy.
        *columns_mut::<P, N>(core.work_g.as_mut_slice())? = g;
        *columns_mut::<P, P>(core.work_s.as_mut_slice())? = s;
        *columns_mut::<P, P>(core.work_l.as_mut_slice())? = factor;
        *columns_mut::<P, N>(core.gain_t.as_mut_slice())? = gain_t;
        *columns_mut::<N, P>(core.gain.as_mut_slice())? = gain;
        *columns_mut::<N, P>(core.work_h.as_mut_slice())? = h;
        Some(Ok(()))
    }
}

/// The model of a filter with one state, one output and at most one input, as numbers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ScalarModel {
    pub(crate) a: f64,
    pub(crate) c: f64,
    pub(crate) q: f64,
    /// (b, d) when the model has its one input.
    pub(crate) input: Option<(f64, f64)>,
}

impl ScalarModel {
    /// The model of `system` when it has one state, one output and at most one input.
    #[inline(always)]
    fn of(system: &StateSpace) -> Option<Self> {
        let input = match (system.b.as_slice(), system.d.as_slice()) {
            ([], []) => None,
            ([b], [d]) => Some((*b, *d)),
            _ => return None,
        };
        Some(Self {
            a: one(system.a.as_slice())?,
            c: one(system.c.as_slice())?,
            q: one(system.q.as_slice())?,
            input,
        })
    }
}

/// What evolves in a filter with one state and one output: the entries of the
/// [`FilterCore`]'s buffers (`u_prev` 0 and unused without input).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ScalarEstimate {
    pub(crate) x: f64,
    pub(crate) p: f64,
    pub(crate) x_prior: f64,
    pub(crate) p_prior: f64,
    pub(crate) u_prev: f64,
    pub(crate) innovation: f64,
    pub(crate) output: f64,
    pub(crate) gain: f64,
    pub(crate) steps: u64,
}

impl ScalarEstimate {
    /// One sample (u_k, y_k) of model `m` (u_k unused without input), in the order of the
    /// general path (bit-identical to it): x⁻ = a x̂ + b u_{k−1}, P⁻ = a (P a) + q,
    /// e = (y − c x⁻) − d u, then `r_eff(e)` gives the measurement covariance of the
    /// correction ([`joseph_scalar`]), ŷ = c x̂ + d u. On error the estimate is left as the
    /// failed step produced it.
    #[inline(always)]
    pub(crate) fn step(
        &mut self,
        m: &ScalarModel,
        u: f64,
        y: f64,
        r_eff: impl ScalarCovariance,
    ) -> Result<(), EstimationError> {
        self.steps += 1;
        let step = self.steps;
        self.x_prior = m.a * self.x;
        if let Some((b, _)) = m.input {
            self.x_prior += b * self.u_prev;
        }
        // (P a in a register: the general path's work matrix, the same rounding.)
        let w = self.p * m.a;
        self.p_prior = m.a * w + m.q;
        self.innovation = m.c * -self.x_prior + y;
        if let Some((_, d)) = m.input {
            self.innovation += d * -u;
        }
        // A missing sample y = NaN makes e NaN: the one check of e decides "present" and
        // the missing sample is handled out of line.
        let e = self.innovation;
        if !e.is_finite() {
            if !y.is_nan() {
                return Err(non_finite(
                    "innovation y − C x⁻ − D u (check y and u)",
                    step,
                ));
            }
            // `r_eff` told here, not passed to the out-of-line rest: the hot path then never
            // lays the covariance's arguments out in memory.
            r_eff.missing();
            return self.predict_only(m, u);
        }
        let (k, x, p) = joseph_scalar(m.c, r_eff.at(e), self.x_prior, self.p_prior, e, step)?;
        (self.gain, self.x, self.p) = (k, x, p);
        // one compare for both: v·0 is ±0 for a finite v and NaN otherwise
        if x * 0.0 + p * 0.0 != 0.0 {
            return Err(non_finite("state estimate or its covariance", step));
        }
        self.output = m.c * x;
        if let Some((_, d)) = m.input {
            self.output += d * u;
            self.u_prev = u;
        }
        Ok(())
    }

    /// The rest of [`ScalarEstimate::step`] for a missing sample y = NaN (the prediction
    /// x⁻, P⁻ already made): e = 0, k = 0, x̂ = x⁻, P = P⁻, ŷ = c x̂ + d u, as the general
    /// path's [`FilterCore::predict_only`]. Errors when x̂, P or ŷ is not finite (a
    /// non-finite u).
    #[cold]
    #[inline(never)]
    fn predict_only(&mut self, m: &ScalarModel, u: f64) -> Result<(), EstimationError> {
        (self.innovation, self.gain, self.x, self.p) = (0.0, 0.0, self.x_prior, self.p_prior);
        self.output = m.c * self.x;
        if let Some((_, d)) = m.input {
            self.output += d * u;
        }
        if m.input.is_some() {
            self.u_prev = u;
        }
        if self.x * 0.0 + self.p * 0.0 + self.output * 0.0 != 0.0 {
            return Err(non_finite(
                "state estimate, its covariance or the fitted output (check u)",
                self.steps,
            ));
        }
        Ok(())
    }

    /// Appends the numbers of [`FilterCore`]'s [`Saved::save`] for these sizes.
    fn save(&self, input: bool, out: &mut Vec<f64>) {
        out.extend_from_slice(&[self.x, self.p, self.x_prior, self.p_prior]);
        if input {
            out.push(self.u_prev);
        }
        out.extend_from_slice(&[self.innovation, self.output, self.gain]);
        out.push(self.steps as f64);
    }

    /// Reads back what [`ScalarEstimate::save`] wrote.
    fn restore(&mut self, input: bool, r: &mut StateReader<'_>) -> Result<(), EstimationError> {
        let mut s = *self;
        for v in [&mut s.x, &mut s.p, &mut s.x_prior, &mut s.p_prior] {
            r.fill(std::slice::from_mut(v))?;
        }
        if input {
            r.fill(std::slice::from_mut(&mut s.u_prev))?;
        }
        for v in [&mut s.innovation, &mut s.output, &mut s.gain] {
            r.fill(std::slice::from_mut(v))?;
        }
        s.steps = r.counter()?;
        *self = s;
        Ok(())
    }
}

/// The [`KalmanFilter`] of a model with one state, one output and at most one input, on
/// plain numbers ([`KalmanFilter::to_scalar`]): the same equations in the same order, so the
/// same results bit for bit, without a buffer or a length to check. Its
/// [`ScalarKalmanFilter::dynamic_state`] is the [`KalmanFilter`]'s.
#[derive(Debug, Clone, PartialEq)]
pub struct ScalarKalmanFilter {
    pub(crate) model: ScalarModel,
    /// R.
    pub(crate) r: f64,
    pub(crate) estimate: ScalarEstimate,
}

impl ScalarKalmanFilter {
    /// Processes one sample (see [`KalmanFilter::step`]); `u` is the input u_k (unused
    /// when the model has none).
    #[inline]
    pub fn step(&mut self, u: f64, y: f64) -> Result<(), EstimationError> {
        self.estimate.step(&self.model, u, y, self.r)
    }
    /// Whether the model has its one input.
    pub fn has_input(&self) -> bool {
        self.model.input.is_some()
    }
    /// Filtered state x̂_{k|k}.
    pub fn state(&self) -> f64 {
        self.estimate.x
    }
    /// Its variance P_{k|k}.
    pub fn covariance(&self) -> f64 {
        self.estimate.p
    }
    /// Filtered output ŷ = c x̂_{k|k} + d u_k.
    pub fn output(&self) -> f64 {
        self.estimate.output
    }
    /// Innovation e = y_k − c x⁻ − d u_k of the last step.
    pub fn innovation(&self) -> f64 {
        self.estimate.innovation
    }
    /// Gain k of the last step.
    pub fn gain(&self) -> f64 {
        self.estimate.gain
    }
    /// Number of steps processed.
    pub fn steps(&self) -> u64 {
        self.estimate.steps
    }
    /// What [`KalmanFilter::dynamic_state`] gives for the same filter.
    pub fn dynamic_state(&self) -> Vec<f64> {
        self.saved()
    }
    /// Restores what [`ScalarKalmanFilter::dynamic_state`] returned.
    pub fn set_dynamic_state(&mut self, state: &[f64]) -> Result<(), EstimationError> {
        self.restore_saved(state)
    }
}

impl Saved for ScalarKalmanFilter {
    fn save(&self, out: &mut Vec<f64>) {
        self.estimate.save(self.has_input(), out);
    }
    fn restore(&mut self, input: &mut StateReader<'_>) -> Result<(), EstimationError> {
        self.estimate.restore(self.has_input(), input)
    }
}

/// The measurement covariance of a scalar correction as a function of the innovation e
/// ([`FilterCore::step_scalar`]): the sKF's constant R, the rsKF's R̃(e). A trait rather than a
/// closure so that it is always inlined into the step.
pub(crate) trait ScalarCovariance {
    /// The covariance for the innovation `e`.
    fn at(self, e: f64) -> f64;
    /// Called instead of [`ScalarCovariance::at`] for a missing sample (no correction).
    fn missing(self);
}

impl ScalarCovariance for f64 {
    #[inline(always)]
    fn at(self, _: f64) -> f64 {
        self
    }
    #[inline(always)]
    fn missing(self) {}
}

/// The entry of a buffer of one entry (a 1×1 matrix, a vector of length 1).
#[inline(always)]
fn one(v: &[f64]) -> Option<f64> {
    match v {
        [v] => Some(*v),
        _ => None,
    }
}

/// The correction of a filter with one state and one output, the Joseph form as written (as
/// cheap as any other there), in the order of the former matrix kernels (bit-identical):
/// g = c P⁻, s = g c + r, k = g/√s/√s, x̂ = x⁻ + k e, P = m (P⁻ m) + k (r k) with
/// m = k (−c) + 1. Gives (k, x̂, P), or the error of [`FilterCore::correct`] when s is not
/// finite and positive.
#[inline(always)]
fn joseph_scalar(
    c: f64,
    r: f64,
    x_prior: f64,
    p_prior: f64,
    e: f64,
    step: u64,
) -> Result<(f64, f64, f64), EstimationError> {
    let g = c * p_prior;
    let s = g * c + r;
    if !s.is_finite() {
        return Err(non_finite(INNOVATION_COVARIANCE, step));
    }
    if s <= 0.0 {
        return Err(not_positive(INNOVATION_COVARIANCE, step));
    }
    let l = s.sqrt();
    let k = g / l / l;
    let m = k * -c + 1.0;
    Ok((k, x_prior + k * e, m * (p_prior * m) + k * (r * k)))
}

/// [`EstimationError::Factorisation`] of `what` at `step` (out of line, as [`non_finite`]).
#[cold]
#[inline(never)]
fn not_positive(what: &'static str, step: u64) -> EstimationError {
    EstimationError::Factorisation { what, step }
}

/// [`EstimationError::NonFinite`] of `what` at `step` (out of line: the hot paths only
/// branch to it).
#[cold]
#[inline(never)]
fn non_finite(what: &'static str, step: u64) -> EstimationError {
    EstimationError::NonFinite { what, step }
}

/// The name of S in the errors of [`FilterCore::correct`].
const INNOVATION_COVARIANCE: &str = "innovation covariance C P⁻ Cᵀ + R";

impl Saved for FilterCore {
    /// Appends every evolving quantity (estimates, covariances, last input, last innovation and
    /// output, gain, step count) to `out`.
    fn save(&self, out: &mut Vec<f64>) {
        for block in [
            self.x.as_slice(),
            self.p.as_slice(),
            self.x_prior.as_slice(),
            self.p_prior.as_slice(),
            self.u_prev.as_slice(),
            self.innovation.as_slice(),
            self.output.as_slice(),
            self.gain_t.as_slice(),
        ] {
            out.extend_from_slice(block);
        }
        out.push(self.steps as f64);
    }

    /// Reads back what [`Saved::save`] wrote (same dimensions).
    fn restore(&mut self, input: &mut StateReader<'_>) -> Result<(), EstimationError> {
        input.fill(self.x.as_mut_slice())?;
        input.fill(self.p.as_mut_slice())?;
        input.fill(self.x_prior.as_mut_slice())?;
        input.fill(self.p_prior.as_mut_slice())?;
        input.fill(self.u_prev.as_mut_slice())?;
        input.fill(self.innovation.as_mut_slice())?;
        input.fill(self.output.as_mut_slice())?;
        input.fill(self.gain_t.as_mut_slice())?;
        self.steps = input.counter()?;
        Ok(())
    }
}

/// A linear Gaussian state-space model and the start of its estimate: the model's matrices
/// ([`StateSpace`]: Cov(w) = Q symmetric PSD, Cov(v) = R SPD; a system without input takes
/// `B` n×0 and `D` p×0), the initial estimate `x0` and its covariance `P0` (symmetric PSD).
#[derive(Debug, Clone, PartialEq)]
pub struct GaussianModel {
    pub system: StateSpace,
    pub x0: DVector<f64>,
    pub p0: DMatrix<f64>,
}

impl GaussianModel {
    /// Validates the dimensions and covariances (parameter names "A", "B", "C", "D", "Q", "R",
    /// "P0", "x0"); gives the model and a filter core started at x0 with covariance P0.
    pub(crate) fn into_filter(self) -> Result<(StateSpace, FilterCore), EstimationError> {
        let Self { system, x0, p0 } = self;
        system.check_dimensions()?;
        let (n, m, p) = (system.states(), system.inputs(), system.outputs());
        require_psd("Q", &system.q, n)?;
        require_spd("R", &system.r, p)?;
        require_length("x0", &x0, n, "one entry per state")?;
        require_psd("P0", &p0, n)?;
        Ok((system, FilterCore::new(x0, p0, m, p)))
    }
}

/// Checks the lengths of a sample (u_k, y_k), naming `u` or `y`, and gives the views of
/// A, B, C, D the filter core's updates take.
pub(crate) fn sample_views<'a>(
    model: &'a StateSpace,
    u: &DVector<f64>,
    y: &DVector<f64>,
) -> Result<[View<'a>; 4], EstimationError> {
    require_input_length("u", u, model.inputs())?;
    require_input_length("y", y, model.outputs())?;
    Ok([&model.a, &model.b, &model.c, &model.d].map(View::of))
}

/// Standard Kalman filter (sKF). See the module documentation for the equations.
#[derive(Debug, Clone)]
pub struct KalmanFilter {
    model: StateSpace,
    core: FilterCore,
    missing: MissingMask,
}

impl KalmanFilter {
    /// Builds a filter for the model (errors name the matrix: "A", "B", "C", "D", "Q", "R",
    /// "P0", "x0", and say why).
    pub fn new(model: GaussianModel) -> Result<Self, EstimationError> {
        let (model, core) = model.into_filter()?;
        let missing = MissingMask::new(model.outputs(), model.states());
        Ok(Self {
            model,
            core,
            missing,
        })
    }

    /// Processes one sample: predicts with the previous input, corrects with `y` (input `u`
    /// enters through D). A NaN y_j is a missing sample: the update uses the present
    /// channels only ([`MissingMask`]), e_j = 0, and with every channel missing the step is
    /// the prediction x̂ = x⁻, P = A P Aᵀ + Q. A y_j = ±∞ or a non-finite u is an error. On
    /// error the estimate is left as the failed step produced it; the caller should stop or
    /// rebuild the filter.
    pub fn step(&mut self, u: &DVector<f64>, y: &DVector<f64>) -> Result<(), EstimationError> {
        let m = &self.model;
        if let [r] = *m.r.as_slice() {
            if let Some(result) = self.core.step_scalar(m, u, y, r) {
                return result;
            }
        }
        let missing = self.core.predict_and_innovate(m, u, y)?;
        let (c, d) = (View::of(&m.c), View::of(&m.d));
        if missing {
            self.core.correct_present(&mut self.missing, c, &m.r, y)?;
            self.core.finish(c, d, u);
            return self.core.check_output();
        }
        self.core.correct(c, &m.r)?;
        self.core.finish(c, d, u);
        Ok(())
    }

    /// Everything that evolves from step to step, as a flat list of numbers (for FMU state
    /// serialization): restoring it with [`KalmanFilter::set_dynamic_state`] into a filter
    /// built with the same parameters continues bit for bit.
    pub fn dynamic_state(&self) -> Vec<f64> {
        self.core.saved()
    }

    /// Restores what [`KalmanFilter::dynamic_state`] returned. Errors (naming "state") when
    /// the length does not fit this filter's dimensions.
    pub fn set_dynamic_state(&mut self, state: &[f64]) -> Result<(), EstimationError> {
        self.core.restore_saved(state)
    }

    /// The same filter on plain numbers when the model has one state, one output and at
    /// most one input ([`ScalarKalmanFilter`]); `None` otherwise.
    pub fn to_scalar(&self) -> Option<ScalarKalmanFilter> {
        Self::scalar_parts(&self.model, &self.core)
    }

    /// The [`ScalarKalmanFilter`] of a model and a filter core of those sizes.
    pub(crate) fn scalar_parts(
        model: &StateSpace,
        core: &FilterCore,
    ) -> Option<ScalarKalmanFilter> {
        let scalar = ScalarModel::of(model)?;
        Some(ScalarKalmanFilter {
            model: scalar,
            r: one(model.r.as_slice())?,
            estimate: core.scalar_estimate(scalar.input.is_some())?,
        })
    }

    core_accessors!();
    /// Predicted covariance P⁻ = P_{k|k−1} of the last step.
    pub fn predicted_covariance(&self) -> &DMatrix<f64> {
        &self.core.p_prior
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::estimation::robust::test_rng::TestRng;
    use crate::linalg::kalman_gain_steady;

    fn scalar(v: f64) -> DMatrix<f64> {
        DMatrix::from_element(1, 1, v)
    }

    /// The scalar filter of x⁺ = a x + w, y = x + v without input: Cov w = q, Cov v = r,
    /// x̂₀ = 0, P₀ = p0.
    pub(crate) fn scalar_filter(a: f64, q: f64, r: f64, p0: f64) -> KalmanFilter {
        KalmanFilter::new(GaussianModel {
            system: StateSpace {
                a: scalar(a),
                b: DMatrix::zeros(1, 0),
                c: scalar(1.0),
                d: DMatrix::zeros(1, 0),
                q: scalar(q),
                r: scalar(r),
            },
            x0: DVector::zeros(1),
            p0: scalar(p0),
        })
        .unwrap()
    }

    #[test]
    fn scalar_steady_state_gain_is_golden_ratio_conjugate() {
        let mut filter = scalar_filter(1.0, 1.0, 1.0, 10.0);
        let u = DVector::zeros(0);
        for k in 0..200 {
            filter
                .step(&u, &DVector::from_element(1, (k as f64).sin()))
                .unwrap();
        }
        let expected = (5.0_f64.sqrt() - 1.0) / 2.0;
        assert!((filter.gain()[(0, 0)] - expected).abs() < 1e-12);
        let (k_dare, _) =
            kalman_gain_steady(&scalar(1.0), &scalar(1.0), &scalar(1.0), &scalar(1.0)).unwrap();
        assert!((k_dare[(0, 0)] - expected).abs() < 1e-9, "{k_dare}");
    }

    #[test]
    fn multivariable_steady_state_gain_matches_dare() {
        let a = DMatrix::from_row_slice(3, 3, &[0.9, 0.1, 0.0, -0.2, 0.8, 0.3, 0.0, 0.05, 0.95]);
        let b = DMatrix::from_row_slice(3, 1, &[0.0, 0.1, 1.0]);
        let c = DMatrix::from_row_slice(2, 3, &[1.0, 0.0, 0.0, 0.0, 1.0, 1.0]);
        let d = DMatrix::zeros(2, 1);
        let q = DMatrix::from_diagonal(&DVector::from_vec(vec![0.1, 0.2, 0.05]));
        let r = DMatrix::from_row_slice(2, 2, &[0.5, 0.1, 0.1, 0.3]);
        let mut filter = KalmanFilter::new(GaussianModel {
            system: StateSpace {
                a: a.clone(),
                b,
                c: c.clone(),
                d,
                q: q.clone(),
                r: r.clone(),
            },
            x0: DVector::zeros(3),
            p0: DMatrix::identity(3, 3),
        })
        .unwrap();
        for k in 0..500 {
            let u = DVector::from_element(1, (0.1 * k as f64).cos());
            let y = DVector::from_vec(vec![(k as f64).sin(), 0.5]);
            filter.step(&u, &y).unwrap();
        }
        let (k_dare, p_pred) = kalman_gain_steady(&a, &c, &q, &r).unwrap();
        let k = filter.gain();
        assert!((&k - &k_dare).amax() < 1e-9, "K = {k}, DARE K = {k_dare}");
        assert!((filter.predicted_covariance() - &p_pred).amax() < 1e-9);
    }

    #[test]
    fn covariance_stays_symmetric_positive_definite() {
        let a = DMatrix::from_row_slice(2, 2, &[1.0, 0.05, 0.0, 1.0]);
        let mut filter = KalmanFilter::new(GaussianModel {
            system: StateSpace {
                a,
                b: DMatrix::zeros(2, 0),
                c: DMatrix::from_row_slice(1, 2, &[1.0, 0.0]),
                d: DMatrix::zeros(1, 0),
                q: DMatrix::from_diagonal(&DVector::from_vec(vec![1e-12, 1e-10])),
                r: scalar(1e-8),
            },
            x0: DVector::zeros(2),
            p0: DMatrix::identity(2, 2) * 1e6,
        })
        .unwrap();
        for k in 0..10_000 {
            filter
                .step(
                    &DVector::zeros(0),
                    &DVector::from_element(1, k as f64 * 0.01),
                )
                .unwrap();
            let p = filter.covariance();
            assert_eq!(p[(0, 1)], p[(1, 0)]);
        }
        assert!(nalgebra::Cholesky::new(filter.covariance().clone()).is_some());
    }

    /// A random n×n symmetric positive definite matrix M Mᵀ + δ I (entries of M uniform in
    /// ±1, times `scale`).
    pub(crate) fn random_spd(rng: &mut TestRng, n: usize, scale: f64, delta: f64) -> DMatrix<f64> {
        let m = DMatrix::from_fn(n, n, |_, _| 2.0 * rng.uniform() - 1.0);
        (&m * m.transpose() + DMatrix::identity(n, n) * delta) * scale
    }

    /// The former step (the one the equivalence test holds the filter core to): P⁻ =
    /// A P Aᵀ + Q and P = (I − K C) P⁻ (I − K C)ᵀ + K R Kᵀ as full products, each symmetrised,
    /// K from a Cholesky solve of S = C P⁻ Cᵀ + R. Gives (x̂, P, K).
    fn former_step(
        (a, c, q, r): (&DMatrix<f64>, &DMatrix<f64>, &DMatrix<f64>, &DMatrix<f64>),
        (x, p): (&DVector<f64>, &DMatrix<f64>),
        y: &DVector<f64>,
    ) -> (DVector<f64>, DMatrix<f64>, DMatrix<f64>) {
        let n = x.len();
        let mut p_prior = a * p * a.transpose() + q;
        crate::linalg::symmetrize(&mut p_prior);
        let x_prior = a * x;
        let s = c * &p_prior * c.transpose() + r;
        let k_t = nalgebra::Cholesky::new(s).unwrap().solve(&(c * &p_prior));
        let k = k_t.transpose();
        let x_new = &x_prior + &k * (y - c * &x_prior);
        let m = DMatrix::identity(n, n) - &k * c;
        let mut p_new = &m * &p_prior * m.transpose() + &k * r * k.transpose();
        crate::linalg::symmetrize(&mut p_new);
        (x_new, p_new, k)
    }

    fn relative(new: &DMatrix<f64>, former: &DMatrix<f64>) -> f64 {
        (new - former).amax() / former.amax().max(f64::MIN_POSITIVE)
    }

    #[test]
    fn covariance_update_equals_the_former_joseph_products_within_1e_12() {
        let mut rng = TestRng::new(17);
        let mut worst: f64 = 0.0;
        let mut steps = 0;
        for trial in 0..600 {
            let (n, p) = [
                (1, 1),
                (2, 1),
                (2, 2),
                (3, 2),
                (5, 3),
                (8, 2),
                (8, 1),
                (4, 4),
            ][trial % 8];
            let a = DMatrix::from_fn(n, n, |_, _| (2.0 * rng.uniform() - 1.0) / (n as f64).sqrt());
            let c = DMatrix::from_fn(p, n, |_, _| 2.0 * rng.uniform() - 1.0);
            let scale = 10f64.powf(4.0 * rng.uniform() - 2.0);
            let q = random_spd(&mut rng, n, 0.1 * scale, 0.0);
            let r = random_spd(&mut rng, p, scale, 0.2);
            let p0 = random_spd(&mut rng, n, scale, 0.1);
            let mut filter = KalmanFilter::new(GaussianModel {
                system: StateSpace {
                    a: a.clone(),
                    b: DMatrix::zeros(n, 0),
                    c: c.clone(),
                    d: DMatrix::zeros(p, 0),
                    q: q.clone(),
                    r: r.clone(),
                },
                x0: DVector::from_fn(n, |_, _| rng.normal()),
                p0,
            })
            .unwrap();
            for _ in 0..8 {
                let y = DVector::from_fn(p, |_, _| scale.sqrt() * rng.normal());
                let before = (filter.state().clone(), filter.covariance().clone());
                let former = former_step((&a, &c, &q, &r), (&before.0, &before.1), &y);
                filter.step(&DVector::zeros(0), &y).unwrap();
                let x_scale = former.0.amax().max(filter.predicted_state().amax());
                let dx = (filter.state() - &former.0).amax() / x_scale.max(f64::MIN_POSITIVE);
                let errors = [
                    dx,
                    relative(filter.covariance(), &former.1),
                    relative(&filter.gain(), &former.2),
                ];
                worst = errors.into_iter().fold(worst, f64::max);
                assert!(
                    errors.iter().all(|e| *e <= 1e-12),
                    "n = {n}, p = {p}: {errors:?}"
                );
                let covariance = filter.covariance();
                assert_eq!(covariance, &covariance.transpose());
                assert!(nalgebra::Cholesky::new(covariance.clone()).is_some());
                if n == 1 && p == 1 {
                    // The scalar filter evaluates the Joseph form as written: bit-identical
                    // to the former kernels' order m (P⁻ m) + k (r k).
                    let (k, p_prior) = (filter.gain()[0], filter.predicted_covariance()[0]);
                    let m = k * -c[0] + 1.0;
                    assert_eq!(covariance[0], m * (p_prior * m) + k * (r[0] * k));
                }
                steps += 1;
            }
        }
        assert_eq!(steps, 4800);
        println!("worst relative difference over {steps} steps: {worst:e}");
    }

    #[test]
    fn the_kernels_of_the_packaged_sizes_equal_the_general_ones_bit_for_bit() {
        let mut rng = TestRng::new(23);
        for (n, m, p) in [
            (1, 0, 1),
            (1, 1, 1),
            (2, 0, 1),
            (2, 1, 2),
            (3, 0, 2),
            (8, 2, 2),
            (8, 0, 2),
        ] {
            let system = StateSpace {
                a: DMatrix::from_fn(n, n, |_, _| (2.0 * rng.uniform() - 1.0) / n as f64),
                b: DMatrix::from_fn(n, m, |_, _| rng.normal()),
                c: DMatrix::from_fn(p, n, |_, _| rng.normal()),
                d: DMatrix::from_fn(p, m, |_, _| rng.normal()),
                q: random_spd(&mut rng, n, 0.01, 0.0),
                r: random_spd(&mut rng, p, 0.1, 0.1),
            };
            let mut fixed = KalmanFilter::new(GaussianModel {
                system,
                x0: DVector::zeros(n),
                p0: random_spd(&mut rng, n, 1.0, 0.1),
            })
            .unwrap();
            let mut general = fixed.clone();
            general.core.general_only = true;
            for _ in 0..500 {
                let u = DVector::from_fn(m, |_, _| rng.normal());
                let y = DVector::from_fn(p, |_, _| rng.normal());
                fixed.step(&u, &y).unwrap();
                general.step(&u, &y).unwrap();
                assert_eq!(
                    fixed.dynamic_state(),
                    general.dynamic_state(),
                    "n = {n}, p = {p}"
                );
            }
        }
    }

    /// A random stable model with one state, one output and `m` (0 or 1) inputs.
    pub(crate) fn random_scalar_model(rng: &mut TestRng, m: usize) -> GaussianModel {
        GaussianModel {
            system: StateSpace {
                a: scalar(2.0 * rng.uniform() - 1.0),
                b: DMatrix::from_fn(1, m, |_, _| rng.normal()),
                c: scalar(rng.normal()),
                d: DMatrix::from_fn(1, m, |_, _| rng.normal()),
                q: scalar(0.01 * rng.uniform()),
                r: scalar(0.1 + rng.uniform()),
            },
            x0: DVector::from_element(1, rng.normal()),
            p0: scalar(rng.uniform()),
        }
    }

    /// Steps a general filter (u a vector of `m` entries, 0 or 1) and its form on plain
    /// numbers, `fast` (`fast_step` its step), with the sample (u, y), and asserts that they
    /// leave the same dynamic state bit for bit (`case` names the case in the message).
    pub(crate) fn step_both_bit_for_bit<F: Saved>(
        general: &mut impl crate::estimation::StateEstimator,
        fast: &mut F,
        fast_step: fn(&mut F, f64, f64) -> Result<(), EstimationError>,
        (m, u, y): (usize, f64, f64),
        case: std::fmt::Arguments<'_>,
    ) {
        let bits = |v: Vec<f64>| v.into_iter().map(f64::to_bits).collect::<Vec<_>>();
        general
            .step(&DVector::from_element(m, u), &DVector::from_element(1, y))
            .unwrap();
        fast_step(fast, u, y).unwrap();
        assert_eq!(bits(fast.saved()), bits(general.dynamic_state()), "{case}");
    }

    #[test]
    fn the_scalar_filter_on_numbers_equals_the_general_path_bit_for_bit() {
        let bits = |v: Vec<f64>| v.into_iter().map(f64::to_bits).collect::<Vec<_>>();
        let mut rng = TestRng::new(41);
        for (m, run) in [(0, 0), (1, 0), (0, 1), (1, 1), (0, 2), (1, 2)] {
            let mut general = KalmanFilter::new(random_scalar_model(&mut rng, m)).unwrap();
            general.core.general_only = true;
            let mut fast = general.to_scalar().unwrap();
            assert_eq!(fast.has_input(), m == 1);
            assert_eq!(fast.dynamic_state(), general.dynamic_state());
            for k in 0..5000 {
                let u = rng.normal();
                let y = 10.0 * rng.normal();
                step_both_bit_for_bit(
                    &mut general,
                    &mut fast,
                    ScalarKalmanFilter::step,
                    (m, u, y),
                    format_args!("m = {m}, run {run}, step {k}"),
                );
                assert_eq!(fast.state().to_bits(), general.state()[0].to_bits());
                assert_eq!(fast.output().to_bits(), general.output()[0].to_bits());
                assert_eq!(fast.innovation(), general.innovation()[0]);
                assert_eq!(fast.gain(), general.gain()[(0, 0)]);
                assert!(fast.covariance() > 0.0);
            }
            // A state restored into another filter continues bit for bit; a wrong length is
            // refused and changes nothing.
            let mut restored = fast.clone();
            restored.step(1.0, 2.0).unwrap();
            assert!(restored.set_dynamic_state(&[1.0; 3]).is_err());
            restored.set_dynamic_state(&fast.dynamic_state()).unwrap();
            assert_eq!(restored, fast);
            // A missing sample (NaN) is the same prediction on both, bit for bit.
            for _ in 0..3 {
                fast.step(0.5, f64::NAN).unwrap();
                general
                    .step(
                        &DVector::from_element(m, 0.5),
                        &DVector::from_element(1, f64::NAN),
                    )
                    .unwrap();
                assert_eq!(
                    bits(fast.dynamic_state()),
                    bits(general.dynamic_state()),
                    "m = {m}, run {run}, missing"
                );
            }
            // A non-finite measurement is the same error on both.
            let error = fast.step(0.0, f64::INFINITY).unwrap_err();
            let former = general
                .step(&DVector::zeros(m), &DVector::from_element(1, f64::INFINITY))
                .unwrap_err();
            assert_eq!(error.to_string(), former.to_string());
        }
        // Other sizes have no scalar form.
        assert!(scalar_filter(1.0, 1.0, 1.0, 1.0).to_scalar().is_some());
        let two = KalmanFilter::new(GaussianModel {
            system: StateSpace {
                a: DMatrix::identity(2, 2),
                b: DMatrix::zeros(2, 0),
                c: DMatrix::from_row_slice(1, 2, &[1.0, 0.0]),
                d: DMatrix::zeros(1, 0),
                q: DMatrix::identity(2, 2),
                r: scalar(1.0),
            },
            x0: DVector::zeros(2),
            p0: DMatrix::identity(2, 2),
        })
        .unwrap();
        assert!(two.to_scalar().is_none());
    }

    #[test]
    fn covariance_stays_symmetric_positive_definite_over_random_runs() {
        let mut rng = TestRng::new(5);
        for (n, p) in [(8, 2), (3, 1), (2, 2)] {
            // A marginally stable A (spectral radius near 1) and very different scales of
            // Q, R and P₀, as in the DKF's state filter.
            let a = DMatrix::from_fn(n, n, |i, j| {
                if i == j {
                    0.99
                } else {
                    0.05 * (2.0 * rng.uniform() - 1.0)
                }
            });
            let c = DMatrix::from_fn(p, n, |_, _| 2.0 * rng.uniform() - 1.0);
            let mut filter = KalmanFilter::new(GaussianModel {
                system: StateSpace {
                    a,
                    b: DMatrix::zeros(n, 0),
                    c,
                    d: DMatrix::zeros(p, 0),
                    q: random_spd(&mut rng, n, 1e-8, 1e-3),
                    r: random_spd(&mut rng, p, 1e-4, 0.1),
                },
                x0: DVector::zeros(n),
                p0: random_spd(&mut rng, n, 1e4, 0.1),
            })
            .unwrap();
            for _ in 0..5000 {
                let y = DVector::from_fn(p, |_, _| rng.normal());
                filter.step(&DVector::zeros(0), &y).unwrap();
                let covariance = filter.covariance();
                assert_eq!(covariance, &covariance.transpose());
                let predicted = filter.predicted_covariance();
                assert_eq!(predicted, &predicted.transpose());
            }
            let eigen = nalgebra::SymmetricEigen::new(filter.covariance().clone());
            assert!(
                eigen.eigenvalues.min() > 0.0,
                "n = {n}: {}",
                eigen.eigenvalues
            );
        }
    }

    #[test]
    fn constructor_names_the_bad_matrix() {
        let ok = GaussianModel {
            system: StateSpace {
                a: DMatrix::identity(2, 2),
                b: DMatrix::zeros(2, 1),
                c: DMatrix::from_row_slice(1, 2, &[1.0, 0.0]),
                d: DMatrix::zeros(1, 1),
                q: DMatrix::identity(2, 2),
                r: scalar(1.0),
            },
            x0: DVector::zeros(2),
            p0: DMatrix::identity(2, 2),
        };
        assert!(KalmanFilter::new(ok.clone()).is_ok());
        let cases = [
            (
                GaussianModel {
                    system: StateSpace {
                        a: DMatrix::zeros(2, 3),
                        ..ok.system.clone()
                    },
                    ..ok.clone()
                },
                "A",
                "square",
            ),
            (
                GaussianModel {
                    system: StateSpace {
                        b: DMatrix::zeros(3, 1),
                        ..ok.system.clone()
                    },
                    ..ok.clone()
                },
                "B",
                "rows",
            ),
            (
                GaussianModel {
                    system: StateSpace {
                        c: DMatrix::zeros(1, 3),
                        ..ok.system.clone()
                    },
                    ..ok.clone()
                },
                "C",
                "columns",
            ),
            (
                GaussianModel {
                    system: StateSpace {
                        d: DMatrix::zeros(2, 1),
                        ..ok.system.clone()
                    },
                    ..ok.clone()
                },
                "D",
                "rows",
            ),
            (
                GaussianModel {
                    system: StateSpace {
                        q: DMatrix::from_row_slice(2, 2, &[1.0, 0.0, 0.0, -1.0]),
                        ..ok.system.clone()
                    },
                    ..ok.clone()
                },
                "Q",
                "semidefinite",
            ),
            (
                GaussianModel {
                    system: StateSpace {
                        r: scalar(0.0),
                        ..ok.system.clone()
                    },
                    ..ok.clone()
                },
                "R",
                "positive definite",
            ),
            (
                GaussianModel {
                    x0: DVector::zeros(3),
                    ..ok.clone()
                },
                "x0",
                "entry",
            ),
            (
                GaussianModel {
                    p0: DMatrix::from_row_slice(2, 2, &[1.0, 0.5, 0.0, 1.0]),
                    ..ok
                },
                "P0",
                "symmetric",
            ),
        ];
        for (model, name, why) in cases {
            match KalmanFilter::new(model) {
                Err(EstimationError::Parameter(e)) => {
                    assert_eq!(e.parameter, name);
                    assert!(e.to_string().contains(why), "{e}");
                }
                other => panic!("expected an error naming {name}, got {other:?}"),
            }
        }
    }

    #[test]
    fn step_rejects_wrong_lengths_and_non_finite_measurements() {
        let mut filter = KalmanFilter::new(GaussianModel {
            system: StateSpace {
                a: scalar(1.0),
                b: scalar(1.0),
                c: scalar(1.0),
                d: scalar(0.0),
                q: scalar(1.0),
                r: scalar(1.0),
            },
            x0: DVector::zeros(1),
            p0: scalar(1.0),
        })
        .unwrap();
        let e = filter
            .step(&DVector::zeros(2), &DVector::zeros(1))
            .unwrap_err();
        assert!(matches!(e, EstimationError::Dimension { what: "u", .. }));
        let e = filter
            .step(&DVector::zeros(1), &DVector::from_element(1, f64::INFINITY))
            .unwrap_err();
        assert!(matches!(e, EstimationError::NonFinite { .. }), "{e}");
        // A missing measurement is not an error; a non-finite input still is.
        filter
            .step(&DVector::zeros(1), &DVector::from_element(1, f64::NAN))
            .unwrap();
        let e = filter
            .step(
                &DVector::from_element(1, f64::NAN),
                &DVector::from_element(1, f64::NAN),
            )
            .unwrap_err();
        assert!(matches!(e, EstimationError::NonFinite { .. }), "{e}");
    }

    #[test]
    fn overflowing_covariance_is_an_error_not_nan() {
        let mut filter = scalar_filter(1e200, 1.0, 1.0, 1e200);
        let e = filter
            .step(&DVector::zeros(0), &DVector::from_element(1, 1.0))
            .unwrap_err();
        println!("{e}");
        assert!(
            matches!(e, EstimationError::NonFinite { step: 1, .. }),
            "{e}"
        );
    }
}
