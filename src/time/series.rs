//! Laplace transform of a sampled series, `X(s) = ∫_{t_0}^∞ x(t) e^{-s t} dt`,
//! at real or complex `s`, with a per-`s` error estimate.
//!
//! # Method
//!
//! * **Filon-type quadrature.** The samples `x(t_0..t_N)` (uniform or not) are
//!   cut into panels of `p` consecutive intervals; on each panel `x` is replaced
//!   by its degree-`p` Lagrange interpolant and the product with `e^{-s t}` is
//!   integrated *exactly* (moments `∫ v^k e^{-w(1+v)} dv` on `[-1, 1]`, by a
//!   series for `|w| < 3` and by the stable forward recurrence otherwise). The
//!   rule is therefore exact for piecewise polynomials of degree `p` whatever
//!   `s` is: large real `s` (the kernel decays within one step) and large
//!   `Im s` (the kernel oscillates within one step) cost no accuracy. When
//!   `N` is not a multiple of `p` the last intervals are integrated with the
//!   interpolant through the last `p + 1` samples.
//!   The value is a weighted sum `X ≈ Σ w_i(s) x_i`.
//! * **Discretisation error estimate**: the same rule with degree `p - 2`
//!   (default `p = 7` against `5`); `|Q_p - Q_{p-2}|` estimates the error of
//!   the lower-order rule and so bounds that of the returned `Q_p` whenever
//!   the data are resolved.
//! * **Rounding floor**: `eps (32 + |s| t_max) Σ |w_i x_i|` (summation and the
//!   phase `s t` of the kernel).
//! * **Truncation (tail beyond `t_N`)**, [`Tail`]:
//!   - [`Tail::Envelope`] (default): an exponential envelope
//!     `|x(t)| <= A e^{-a (t - t_N)}` is fitted to block maxima of the last
//!     quarter of the record (the rate halved for safety, and taken as 0
//!     unless the envelope falls by at least a factor 2 across the window; `A`
//!     the largest block maximum carried forward to `t_N`), and the tail bound
//!     `A |e^{-s t_N}| / (a + Re s)` is added to the error estimate. No value
//!     correction: for oscillating many-mode responses an extrapolation of
//!     the last samples by one exponential is more often wrong than the
//!     truncation itself. The bound is honest but pessimistic (about 100x
//!     the true truncation error for a 20-mass chain at `s = 0.001`).
//!   - [`Tail::Modes`]: the end of the record is fitted to a sum of decaying
//!     modes ([`ModeFit`], matrix pencil) on two windows; the analytic
//!     transform of the fitted tail is *added* to the value and the
//!     disagreement of the two windows (plus the fit residual) is the
//!     truncation estimate. Accepted only if the model reproduces every
//!     sample of the window; otherwise the envelope bound is used. For
//!     few-mode records this removes the truncation error (n = 4 chain on
//!     [0, 300]: error 3e-15 at `s = 0.001` instead of 4e-9).
//!   - [`Tail::Zero`]: the signal is zero after `t_N` (no bound).
//! * **Noise**: with a noise level `sigma` (white, per sample) the variance
//!   of the transformed value is `sigma^2 Σ |w_i|^2`. The transformed noise is
//!   strongly correlated between nodes: [`SeriesTransform::noise_covariance`]
//!   gives the full covariance of the stacked real and imaginary parts
//!   ([`stack_re_im`]) and [`SeriesTransform::data_covariance`] adds the error
//!   estimate as model-error variance (whitened in [`crate::detect::data::whiten`]).
//! * **Uniform grids** (`|t_i - (t_0 + i dt)|` within a few units in the last
//!   place of the largest time): the weight of sample `i` is, away from the
//!   first `p` samples and the last panels, `e^{-s t_i}` times a function of
//!   `i mod p`, so every sum over samples of products of weights (noise
//!   variance, covariance blocks, the noise part of `Q_p - Q_{p-2}`) is one
//!   period of that pattern times a geometric series plus the exact weights
//!   of the two ends: `O(p)` per pair of nodes instead of `O(N)`, no weight
//!   vector formed. The panels' factors `e^{-s alpha_k}` of the rules' sums
//!   follow from one another by the ratio `e^{-s p dt}` (recomputed every 16
//!   panels). Both agree with the general path (weight vectors, one
//!   exponential per panel) to rounding: values within a small fraction of
//!   the rounding floor `err_round`, covariances to about `1e-14` of their
//!   largest entry.
//!
//! # Velocity and acceleration records
//!
//! The transform of a sampled velocity or acceleration series is the
//! transform of that series, compared with the model's
//! [`crate::forward::observe`]: `s X(s)` for a velocity, and for an
//! acceleration `s^2 X(s) - x'(0+)`. The impulse `gamma delta(t)` on mass 1
//! puts a delta into the true acceleration of mass 1 that no sample
//! carries (and a jump `0 -> gamma/m_1` into its velocity at `t = 0`, which the
//! quadrature over `[t_0, t_N]` with `t_0 = 0` integrates correctly as long as
//! the first sample is the `0+` value, as [`crate::time::simulate`] writes it).
//! The model's `s^2 X_1 - gamma/m_1` is the transform of the acceleration for
//! `t > 0`, so the two compare directly. A measured force has no delta: the
//! acceleration's transform is `s^2 H(s) F(s)` ([`crate::forward::transfer_function`]).
//!
//! ```
//! use springmass::time::series::{SeriesTransform, TransformOptions};
//! use springmass::Complex64;
//! // x(t) = e^{-t} sampled on [0, 40]: X(s) = 1/(s + 1).
//! let t: Vec<f64> = (0..=4000).map(|i| i as f64 * 0.01).collect();
//! let x: Vec<f64> = t.iter().map(|t| (-t).exp()).collect();
//! let tr = SeriesTransform::new(&t, &x, &TransformOptions::default())?;
//! let v = tr.eval(Complex64::new(2.0, 3.0))?;
//! let exact = Complex64::new(1.0, 0.0) / Complex64::new(3.0, 3.0);
//! assert!((v.value - exact).norm() < 1e-12);
//! assert!((v.value - exact).norm() <= v.err);
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::error::{Error, Result};
use crate::series::TimeSeries;
use nalgebra::DMatrix;
use num_complex::Complex64;

/// Default degree of the local interpolant.
pub const DEFAULT_DEGREE: usize = 7;

/// What is assumed about the signal after the last sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Tail {
    /// Fit an exponential envelope to the end of the record and add the tail
    /// bound to the error estimate (the default).
    #[default]
    Envelope,
    /// The signal is zero after the last sample (no truncation error).
    Zero,
    /// Fit the end of the record to a sum of decaying modes (matrix pencil)
    /// and add the analytic transform of the fitted tail as a correction;
    /// its error is the disagreement of fits on two windows plus the fit
    /// residual. Falls back to [`Tail::Envelope`] when no acceptable fit is
    /// found (see [`ModeFit`]).
    Modes,
}

/// Options of [`SeriesTransform`].
#[derive(Clone, Debug, PartialEq)]
pub struct TransformOptions {
    /// Degree `p` of the local interpolant, `3..=9` (default 7); the error
    /// estimate uses degree `p - 2`. Reduced automatically for short series.
    pub degree: usize,
    /// White noise standard deviation per sample, if known: enables
    /// [`LaplaceValue::noise_var`].
    pub noise_sigma: Option<f64>,
    /// The tail model.
    pub tail: Tail,
}

impl Default for TransformOptions {
    fn default() -> Self {
        TransformOptions {
            degree: DEFAULT_DEGREE,
            noise_sigma: None,
            tail: Tail::Envelope,
        }
    }
}

/// `X(s)` of a series with its error budget.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LaplaceValue {
    /// The Laplace variable.
    pub s: Complex64,
    /// The transform: quadrature of the record plus [`LaplaceValue::tail`].
    pub value: Complex64,
    /// The tail correction included in `value` (zero unless [`Tail::Modes`]).
    pub tail: Complex64,
    /// Total error estimate: `err_disc + err_trunc + err_round`.
    pub err: f64,
    /// Discretisation estimate `|Q_p - Q_{p-2}|`.
    pub err_disc: f64,
    /// Truncation (tail) bound.
    pub err_trunc: f64,
    /// Rounding floor.
    pub err_round: f64,
    /// `sigma^2 Σ |w_i|^2` when a noise level was given.
    pub noise_var: Option<f64>,
}

impl LaplaceValue {
    /// Whether the value and every error estimate are finite (representable
    /// in f64).
    pub fn is_finite(&self) -> bool {
        [
            self.value.re,
            self.value.im,
            self.err,
            self.err_disc,
            self.err_trunc,
        ]
        .iter()
        .chain(self.noise_var.as_ref())
        .all(|x| x.is_finite())
    }
}

/// Exponential envelope of the end of the record: `|x(t)| <= amp e^{-rate (t - t_end)}`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Envelope {
    /// The last sample time.
    pub t_end: f64,
    /// Envelope amplitude at `t_end`.
    pub amp: f64,
    /// Decay rate used for the bound (half the fitted rate, at least 0).
    pub rate: f64,
}

#[derive(Clone, Debug)]
struct Panel {
    first: usize,
    alpha: f64,
    h2: f64,
    mat: usize,
}

#[derive(Clone, Debug)]
struct Rule {
    p: usize,
    /// The panels: `full` panels of `p` intervals from sample 0, then (when
    /// `p` does not divide `N`) the panel of the last `p` intervals that
    /// integrates only the remainder.
    panels: Vec<Panel>,
    full: usize,
    /// Lagrange monomial coefficients, `(p+1) x (p+1)` row-major per matrix:
    /// `L_j(v) = Σ_k mats[m][j (p+1) + k] v^k`.
    mats: Vec<Vec<f64>>,
}

/// A prepared transform of one sampled series, ready for many `s`.
#[derive(Clone, Debug)]
pub struct SeriesTransform {
    t: Vec<f64>,
    x: Vec<f64>,
    hi: Rule,
    lo: Rule,
    envelope: Option<Envelope>,
    modes: Option<(ModeFit, ModeFit)>,
    opts: TransformOptions,
    /// The spacing `dt` when the grid is uniform ([`uniform_spacing`]): the
    /// sums over samples of products of weights are then formed as periodic
    /// sums ([`Periodic`]); `None` forms the weight vectors.
    uniform_dt: Option<f64>,
}

impl SeriesTransform {
    /// The samples the transform was built from: times and values.
    pub fn samples(&self) -> (&[f64], &[f64]) {
        (&self.t, &self.x)
    }

    /// Prepare the transform of samples `x[i] = x(t[i])`.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] for fewer than 4 samples, lengths that
    /// differ, non-finite or non-increasing times (naming the index), a
    /// non-finite value (naming the index), a degree outside `3..=9`, a noise
    /// level that is negative or not finite.
    pub fn new(t: &[f64], x: &[f64], opts: &TransformOptions) -> Result<SeriesTransform> {
        if t.len() != x.len() {
            return Err(Error::invalid(
                "x.len",
                x.len(),
                format!("equal to the number of times ({})", t.len()),
            ));
        }
        if t.len() < 4 {
            return Err(Error::invalid(
                "series length",
                t.len(),
                "at least 4 samples",
            ));
        }
        crate::series::check_times(t)?;
        if let Some(i) = x.iter().position(|v| !v.is_finite()) {
            return Err(Error::invalid(format!("x[{i}]"), x[i], "finite"));
        }
        if !(3..=9).contains(&opts.degree) {
            return Err(Error::invalid("degree", opts.degree, "3..=9"));
        }
        if let Some(sig) = opts.noise_sigma {
            if !(sig.is_finite() && sig >= 0.0) {
                return Err(Error::invalid("noise_sigma", sig, ">= 0 and finite"));
            }
        }
        let p = opts.degree.min(t.len() - 1);
        let hi = Rule::new(t, p);
        let lo = Rule::new(t, p - 2);
        let (envelope, modes) = match opts.tail {
            Tail::Envelope => (Some(fit_envelope(t, x)), None),
            Tail::Zero => (None, None),
            Tail::Modes => match (ModeFit::fit(t, x, 1.0 / 3.0), ModeFit::fit(t, x, 0.25)) {
                (Some(a), Some(b)) => (None, Some((a, b))),
                _ => (Some(fit_envelope(t, x)), None),
            },
        };
        let uniform_dt = uniform_spacing(t);
        Ok(SeriesTransform {
            t: t.to_vec(),
            x: x.to_vec(),
            hi,
            lo,
            envelope,
            modes,
            opts: opts.clone(),
            uniform_dt,
        })
    }

    /// Uniform samples `x[i] = x(t0 + i dt)`.
    ///
    /// # Errors
    /// `dt <= 0` or not finite, `t0` not finite, and everything [`SeriesTransform::new`] checks.
    pub fn uniform(t0: f64, dt: f64, x: &[f64], opts: &TransformOptions) -> Result<Self> {
        crate::error::check_f64("dt", dt, dt > 0.0, "> 0 and finite")?;
        crate::error::check_f64("t0", t0, true, "finite")?;
        let t: Vec<f64> = (0..x.len()).map(|i| t0 + i as f64 * dt).collect();
        SeriesTransform::new(&t, x, opts)
    }

    /// The column `column` of a validated [`TimeSeries`].
    ///
    /// # Errors
    /// A missing column (naming the columns present), and everything
    /// [`SeriesTransform::new`] checks.
    pub fn from_series(ts: &TimeSeries, column: &str, opts: &TransformOptions) -> Result<Self> {
        let x = ts.require(column)?;
        SeriesTransform::new(ts.t(), x, opts)
    }

    /// Degree of the interpolant actually used.
    pub fn degree(&self) -> usize {
        self.hi.p
    }

    /// The fitted tail envelope (`None` with [`Tail::Zero`], or with
    /// [`Tail::Modes`] when the mode fit was accepted).
    pub fn envelope(&self) -> Option<Envelope> {
        self.envelope
    }

    /// The accepted mode fit of the tail (only with [`Tail::Modes`]).
    pub fn mode_fit(&self) -> Option<&ModeFit> {
        self.modes.as_ref().map(|m| &m.0)
    }

    /// Quadrature weights `w_i(s)` of the degree-`p` rule: `X(s) ≈ Σ w_i x_i`.
    pub fn weights(&self, s: Complex64) -> Vec<Complex64> {
        self.hi.weights(&self.t, s)
    }

    /// The same transform with the sums of products of weights always
    /// formed from the weight vectors, also on a uniform grid (where they
    /// are otherwise periodic sums): the reference for tests and
    /// benchmarks. The results agree to rounding.
    #[doc(hidden)]
    pub fn general_path(mut self) -> SeriesTransform {
        self.uniform_dt = None;
        self
    }

    /// Whether the uniform-grid (periodic) sums are used.
    #[doc(hidden)]
    pub fn has_periodic_sums(&self) -> bool {
        self.uniform_dt.is_some()
    }

    /// The degree-`p` weights at the node of `hi` (the local weights of
    /// that rule there) as a [`Periodic`] of period `p`.
    fn periodic_hi(&self, dt: f64, hi: &mut LocalWeights) -> Periodic {
        let lay = Layout::new(self.t.len(), &[&self.hi], self.hi.p, dt);
        let (head, tail) = lay.windows(&self.hi, hi);
        Periodic::new(hi.s, &lay, head, tail)
    }

    /// The difference of the two rules' weights at the node of `hi` and
    /// `lo`, `w_p - w_{p-2}`, as a [`Periodic`] of period `lcm(p, p - 2)`.
    fn periodic_diff(&self, dt: f64, hi: &mut LocalWeights, lo: &mut LocalWeights) -> Periodic {
        let period = lcm(self.hi.p, self.lo.p);
        let lay = Layout::new(self.t.len(), &[&self.hi, &self.lo], period, dt);
        let (mut head, mut tail) = lay.windows(&self.hi, hi);
        let (head_lo, tail_lo) = lay.windows(&self.lo, lo);
        for (a, b) in head.iter_mut().zip(&head_lo) {
            *a -= b;
        }
        for (a, b) in tail.iter_mut().zip(&tail_lo) {
            *a -= b;
        }
        Periodic::new(hi.s, &lay, head, tail)
    }

    /// `X(s)` with its error estimate.
    ///
    /// # Errors
    /// `s` not finite; [`Error::Unresolvable`] when the tail cannot be
    /// bounded (the record does not decay and `Re s <= 0`, or decays more
    /// slowly than `e^{-Re(s) t}` grows) or the sum overflows.
    pub fn eval(&self, s: Complex64) -> Result<LaplaceValue> {
        check_node(s)?;
        let mut hi = LocalWeights::new(&self.hi, s);
        let mut lo = LocalWeights::new(&self.lo, s);
        let (q_lo, _) = self.lo.apply(&self.x, self.uniform_dt, &mut lo);
        if self.opts.noise_sigma.is_some() {
            if let Some(dt) = self.uniform_dt {
                let (q_hi, sum_abs) = self.hi.apply(&self.x, Some(dt), &mut hi);
                let sum_w2 = self.periodic_hi(dt, &mut hi).sum_sq();
                return self.value_of(s, q_hi, sum_abs, q_lo, sum_w2);
            }
            let (q_hi, sum_abs, w_hi) = self.hi.apply_and_weights(&self.t, &self.x, s);
            self.value_of(s, q_hi, sum_abs, q_lo, sum_sq(&w_hi))
        } else {
            let (q_hi, sum_abs) = self.hi.apply(&self.x, self.uniform_dt, &mut hi);
            self.value_of(s, q_hi, sum_abs, q_lo, 0.0)
        }
    }

    /// The value at `s` from the two rules' sums: `q_hi` (with the l1 bound
    /// `sum_abs` of its terms), `q_lo`, and `sum_w2 = Σ |w_i|^2` of the
    /// degree-`p` weights (used only with a noise level).
    fn value_of(
        &self,
        s: Complex64,
        q_hi: Complex64,
        sum_abs: f64,
        q_lo: Complex64,
        sum_w2: f64,
    ) -> Result<LaplaceValue> {
        if !(q_hi.re.is_finite() && q_hi.im.is_finite() && q_lo.norm().is_finite()) {
            return Err(Error::Unresolvable {
                reason: format!(
                    "the transform overflows at s = {s} (Re s too negative for this record)"
                ),
            });
        }
        let t_max = self.t[0].abs().max(self.t[self.t.len() - 1].abs());
        let err_round = f64::EPSILON * (32.0 + s.norm() * t_max) * sum_abs;
        let err_disc = (q_hi - q_lo).norm();
        let mut tail = Complex64::new(0.0, 0.0);
        let err_trunc = match (self.envelope, &self.modes) {
            (None, Some((a, b))) => {
                let slowest = a.max_re_pole().max(b.max_re_pole());
                if s.re <= slowest {
                    return Err(Error::Unresolvable {
                        reason: format!(
                            "fitted tail after t = {} decays at rate {:.3e}: its transform needs Re s > {:.3e}, got s = {s}",
                            a.t_end, -slowest, slowest
                        ),
                    });
                }
                tail = a.tail(s);
                2.0 * (tail - b.tail(s)).norm() + 10.0 * a.residual.max(b.residual) * a.tail_abs(s)
            }
            (None, None) => 0.0,
            (Some(env), _) => {
                let decay = env.rate + s.re;
                if env.amp == 0.0 {
                    0.0
                } else if decay <= 0.0 {
                    return Err(Error::Unresolvable {
                        reason: format!(
                            "tail after t = {} not bounded at s = {s}: the record decays at rate {:.3e}, \
                             which needs Re s > {:.3e}",
                            env.t_end, env.rate, -env.rate
                        ),
                    });
                } else {
                    env.amp * (-s.re * env.t_end).exp() / decay
                }
            }
        };
        Ok(LaplaceValue {
            s,
            value: q_hi + tail,
            tail,
            err: err_disc + err_trunc + err_round,
            err_disc,
            err_trunc,
            err_round,
            noise_var: self.opts.noise_sigma.map(|sig| sig * sig * sum_w2),
        })
    }

    /// [`SeriesTransform::eval`] at each `s`.
    ///
    /// # Errors
    /// The first failing `s`.
    pub fn eval_many(&self, s: &[Complex64]) -> Result<Vec<LaplaceValue>> {
        s.iter().map(|&z| self.eval(z)).collect()
    }

    /// Noise covariance of the transformed values at the nodes `s`, for white
    /// noise of standard deviation `sigma` on every sample.
    ///
    /// `X(s_q) = Σ_i a_i(s_q) x_i` ([`SeriesTransform::weights`]) is linear in
    /// the samples, so with `A_qi = a_i(s_q)` the stacked real vector
    /// `[Re X(s_1..s_Q); Im X(s_q) for complex s_q]` ([`stack_re_im`]) has covariance
    /// `sigma^2 B B^T`, `B = [Re A; Im A]`, that is the blocks
    /// `sigma^2/2 Re(A A^H ± A A^T)` (`Re-Re`: `+`, `Im-Im`: `-`) and
    /// `sigma^2/2 Im(A A^T ∓ A A^H)` between them. The `Im` row of a real node is
    /// identically zero and is left out. The transformed noise of nearby nodes
    /// is strongly correlated (the kernels `e^{-s t}` are smooth in `s`): the
    /// matrix is far from diagonal and usually numerically rank-deficient.
    /// The tail correction of [`Tail::Modes`] (which depends on the data
    /// nonlinearly) is not included. On a uniform grid the blocks are formed
    /// from the periodic structure of the weights (module docs), equal to
    /// `B B^T` to rounding.
    ///
    /// # Errors
    /// `sigma` negative or not finite; a node not finite.
    pub fn noise_covariance(&self, s: &[Complex64], sigma: f64) -> Result<DMatrix<f64>> {
        crate::error::check_f64("sigma", sigma, sigma >= 0.0, ">= 0 and finite")?;
        if let Some(z) = s.iter().find(|z| !(z.re.is_finite() && z.im.is_finite())) {
            return Err(Error::invalid("s", z, "finite"));
        }
        if let Some(dt) = self.uniform_dt {
            let w: Vec<Periodic> = s
                .iter()
                .map(|&z| self.periodic_hi(dt, &mut LocalWeights::new(&self.hi, z)))
                .collect();
            return Ok(periodic_covariance(s, &w, sigma));
        }
        let mut b = WeightRows::new(s, self.t.len());
        for (q, z) in s.iter().enumerate() {
            b.set(q, &self.weights(*z));
        }
        Ok(b.covariance(sigma))
    }

    /// The error estimate of `v` (a value of this transform) that is not
    /// caused by white noise of level `sigma` on the samples:
    /// `err_trunc + err_round + max(0, err_disc - 3 sigma ||w_p - w_{p-2}||)`,
    /// where `sigma ||w_p - w_{p-2}||` is the standard deviation of the noise's
    /// contribution to `Q_p - Q_{p-2}` (the discretisation estimate). Equal to
    /// `v.err` when `sigma = 0`.
    pub fn model_error(&self, v: &LaplaceValue, sigma: f64) -> f64 {
        let mut hi = LocalWeights::new(&self.hi, v.s);
        let mut lo = LocalWeights::new(&self.lo, v.s);
        self.model_error_at(v, sigma, &mut hi, &mut lo)
    }

    /// [`SeriesTransform::model_error`] with the local weights `hi`, `lo` of
    /// the two rules at the node of `v`.
    fn model_error_at(
        &self,
        v: &LaplaceValue,
        sigma: f64,
        hi: &mut LocalWeights,
        lo: &mut LocalWeights,
    ) -> f64 {
        if sigma > 0.0 {
            let disc = match self.uniform_dt {
                Some(dt) => self.periodic_diff(dt, hi, lo).sum_sq(),
                None => {
                    let hi = self.hi.weights(&self.t, v.s);
                    let lo = self.lo.weights(&self.t, v.s);
                    diff_sum_sq(&hi, &lo)
                }
            };
            model_error_with(v, sigma, disc)
        } else {
            model_error_with(v, 0.0, 0.0)
        }
    }

    /// The full data covariance of `values` (from [`SeriesTransform::eval_many`]
    /// on this transform): the noise covariance at their nodes
    /// ([`SeriesTransform::noise_covariance`], with the transform's noise level,
    /// zero if none was given) plus the transform's own error estimate as an
    /// independent model-error variance on the diagonal: `e_q^2` on the `Re`
    /// row of a real node, `e_q^2 / 2` on each of the `Re` and `Im` rows of a
    /// complex node (so that `E|e_q|^2 = e_q^2` as for the diagonal weighting).
    ///
    /// `e_q` is [`SeriesTransform::model_error`]: the error estimate without
    /// the part of the discretisation estimate that the noise itself causes
    /// (on a noisy record `|Q_p - Q_{p-2}|` is mostly noise, 0.3 to 1 noise
    /// standard deviation for the 20-mass chain at 1e-3 noise, already
    /// counted in the noise covariance; counting it again as independent
    /// variance deflates the chi-square by a factor of 3).
    ///
    /// # Errors
    /// As [`SeriesTransform::noise_covariance`].
    pub fn data_covariance(&self, values: &[LaplaceValue]) -> Result<DMatrix<f64>> {
        let s: Vec<Complex64> = values.iter().map(|v| v.s).collect();
        let sigma = self.opts.noise_sigma.unwrap_or(0.0);
        let mut c = self.noise_covariance(&s, sigma)?;
        let rows = stacked_rows(&s);
        let model: Vec<f64> = values.iter().map(|v| self.model_error(v, sigma)).collect();
        add_model_error(&mut c, &s, &rows, &model);
        Ok(c)
    }

    /// [`SeriesTransform::eval_many`] and [`SeriesTransform::data_covariance`]
    /// of its values in one pass. The results are those of the two calls
    /// (the same operations in the same order).
    ///
    /// On a uniform grid (the usual case; see [`SeriesTransform::uniform`])
    /// no weight vector is formed: the values are the rules' sums
    /// `Σ w_i x_i` and every sum over samples of products of weights (the
    /// noise variance `Σ |w_i|^2`, the noise part `Σ |w_{p,i} - w_{p-2,i}|^2`
    /// of the discretisation estimate, the blocks `Σ w_i(a) w_i(b)` and
    /// `Σ w_i(a) conj(w_i(b))` of the covariance) is, away from the first
    /// and the last few samples, a geometric series times a sum over one
    /// period of the weights' periodic pattern (the weight of sample `i` is
    /// `e^{-s t_i}` times a function of `i mod p`): `O(p)` work per pair of
    /// nodes plus the exact weights of the two ends, instead of `O(N)`. On
    /// other grids the weights of each node are formed once (together with
    /// the rules' sums) and serve the value, its noise variance, the
    /// noise-free part of its error estimate
    /// ([`SeriesTransform::model_error`]) and its rows of the noise
    /// covariance `sigma^2 B B^T`. The two ways agree to rounding.
    ///
    /// # Errors
    /// As [`SeriesTransform::eval_many`] (the first failing `s`).
    pub fn eval_with_covariance(
        &self,
        s: &[Complex64],
    ) -> Result<(Vec<LaplaceValue>, DMatrix<f64>)> {
        let sigma = self.opts.noise_sigma.unwrap_or(0.0);
        if let Some(dt) = self.uniform_dt {
            let mut values = Vec::with_capacity(s.len());
            let mut model = Vec::with_capacity(s.len());
            let mut w = Vec::with_capacity(s.len());
            for &z in s {
                check_node(z)?;
                let mut hi = LocalWeights::new(&self.hi, z);
                let mut lo = LocalWeights::new(&self.lo, z);
                let (q_lo, _) = self.lo.apply(&self.x, Some(dt), &mut lo);
                let (q_hi, sum_abs) = self.hi.apply(&self.x, Some(dt), &mut hi);
                let wz = self.periodic_hi(dt, &mut hi);
                let sum_w2 = if self.opts.noise_sigma.is_some() {
                    wz.sum_sq()
                } else {
                    0.0
                };
                let v = self.value_of(z, q_hi, sum_abs, q_lo, sum_w2)?;
                model.push(self.model_error_at(&v, sigma, &mut hi, &mut lo));
                values.push(v);
                w.push(wz);
            }
            let mut c = periodic_covariance(s, &w, sigma);
            add_model_error(&mut c, s, &stacked_rows(s), &model);
            return Ok((values, c));
        }
        self.weighted_with_covariance(s, None)
    }

    /// [`SeriesTransform::eval_with_covariance`] for coloured noise: the
    /// noise covariance is `sigma^2 R R^T` (`sigma` the options'
    /// `noise_sigma`), given `root_t(a) = R^T a` of a real weight vector
    /// over the samples (for AR noise, `NoiseModel::covariance_root_t` of
    /// the fit's noise models).
    /// Every node's weights are formed (the periodic sums assume white
    /// noise); the noise variance of each value and the noise part of its
    /// discretisation estimate use the mapped weights too.
    ///
    /// # Errors
    /// As [`SeriesTransform::eval_many`] (the first failing `s`).
    pub fn eval_with_coloured_covariance(
        &self,
        s: &[Complex64],
        root_t: &RootT<'_>,
    ) -> Result<(Vec<LaplaceValue>, DMatrix<f64>)> {
        self.weighted_with_covariance(s, Some(root_t))
    }

    /// The values and covariance from every node's weight vector, mapped
    /// by `root_t` (white noise when `None`).
    fn weighted_with_covariance(
        &self,
        s: &[Complex64],
        root_t: Option<&RootT<'_>>,
    ) -> Result<(Vec<LaplaceValue>, DMatrix<f64>)> {
        let sigma = self.opts.noise_sigma.unwrap_or(0.0);
        let map = |w: Vec<Complex64>| -> Vec<Complex64> {
            match root_t {
                None => w,
                Some(f) => {
                    let re = f(&w.iter().map(|z| z.re).collect::<Vec<_>>());
                    let im = f(&w.iter().map(|z| z.im).collect::<Vec<_>>());
                    re.into_iter()
                        .zip(im)
                        .map(|(a, b)| Complex64::new(a, b))
                        .collect()
                }
            }
        };
        let mut b = WeightRows::new(s, self.t.len());
        let mut values = Vec::with_capacity(s.len());
        let mut model = Vec::with_capacity(s.len());
        for (q, &z) in s.iter().enumerate() {
            check_node(z)?;
            let (q_hi, sum_abs, w_hi) = self.hi.apply_and_weights(&self.t, &self.x, z);
            let w_hi = map(w_hi);
            let sum_w2 = if self.opts.noise_sigma.is_some() {
                sum_sq(&w_hi)
            } else {
                0.0
            };
            let v = if sigma > 0.0 {
                let (q_lo, _, w_lo) = self.lo.apply_and_weights(&self.t, &self.x, z);
                let v = self.value_of(z, q_hi, sum_abs, q_lo, sum_w2)?;
                model.push(model_error_with(&v, sigma, diff_sum_sq(&w_hi, &map(w_lo))));
                v
            } else {
                let (q_lo, _) = self
                    .lo
                    .apply(&self.x, None, &mut LocalWeights::new(&self.lo, z));
                let v = self.value_of(z, q_hi, sum_abs, q_lo, sum_w2)?;
                model.push(model_error_with(&v, 0.0, 0.0));
                v
            };
            b.set(q, &w_hi);
            values.push(v);
        }
        let mut c = b.covariance(sigma);
        add_model_error(&mut c, s, &stacked_rows(s), &model);
        Ok((values, c))
    }
}

/// `a -> R^T a` of a real weight vector, `sigma^2 R R^T` the noise
/// covariance ([`SeriesTransform::eval_with_coloured_covariance`]).
pub type RootT<'a> = dyn Fn(&[f64]) -> Vec<f64> + 'a;

/// `s` finite (every evaluation checks it first).
fn check_node(s: Complex64) -> Result<()> {
    if !(s.re.is_finite() && s.im.is_finite()) {
        return Err(Error::invalid("s", s, "finite"));
    }
    Ok(())
}

/// `Σ |w_i|^2`.
fn sum_sq(w: &[Complex64]) -> f64 {
    w.iter().map(|w| w.norm_sqr()).sum()
}

/// `Σ |a_i - b_i|^2`.
fn diff_sum_sq(a: &[Complex64], b: &[Complex64]) -> f64 {
    a.iter().zip(b).map(|(a, b)| (a - b).norm_sqr()).sum()
}

/// [`SeriesTransform::model_error`] of `v` given `disc_sq = Σ |w_{p,i} -
/// w_{p-2,i}|^2` of the two rules' weights at its node (unused when
/// `sigma = 0`).
fn model_error_with(v: &LaplaceValue, sigma: f64, disc_sq: f64) -> f64 {
    let noise_disc = if sigma > 0.0 {
        sigma * disc_sq.sqrt()
    } else {
        0.0
    };
    v.err_trunc + v.err_round + (v.err_disc - 3.0 * noise_disc).max(0.0)
}

/// The model-error variances on the diagonal of a stacked covariance:
/// `e_q^2` on the `Re` row of a real node, `e_q^2 / 2` on each row of a
/// complex one.
fn add_model_error(c: &mut DMatrix<f64>, s: &[Complex64], rows: &[(usize, bool)], model: &[f64]) {
    for (r, &(q, _)) in rows.iter().enumerate() {
        let e2 = model[q] * model[q];
        c[(r, r)] += if s[q].im != 0.0 { 0.5 * e2 } else { e2 };
    }
}

/// The stacked real weight matrix `B = [Re A; Im A]` of
/// [`SeriesTransform::noise_covariance`], filled node by node: `Re` rows
/// first (every node), then `Im` rows (complex nodes), as [`stack_re_im`].
/// Held as `B^T` (one contiguous column per row of `B`: filled in order).
struct WeightRows {
    bt: DMatrix<f64>,
    /// The `Im` row of each node (`None` for a real node).
    im_row: Vec<Option<usize>>,
}

/// The `Im` row of each node in the stacked layout ([`stacked_rows`]),
/// `None` for a real node, and the number of rows.
fn im_rows(s: &[Complex64]) -> (Vec<Option<usize>>, usize) {
    let mut next = s.len();
    let im_row = s
        .iter()
        .map(|z| {
            (z.im != 0.0).then(|| {
                next += 1;
                next - 1
            })
        })
        .collect();
    (im_row, next)
}

impl WeightRows {
    fn new(s: &[Complex64], samples: usize) -> WeightRows {
        let (im_row, rows) = im_rows(s);
        WeightRows {
            bt: DMatrix::zeros(samples, rows),
            im_row,
        }
    }

    /// The rows of node `q` from its weights `a`.
    fn set(&mut self, q: usize, a: &[Complex64]) {
        for (o, w) in self.bt.column_mut(q).iter_mut().zip(a) {
            *o = w.re;
        }
        if let Some(r) = self.im_row[q] {
            for (o, w) in self.bt.column_mut(r).iter_mut().zip(a) {
                *o = w.im;
            }
        }
    }

    /// `sigma^2 B B^T` (`B` by a blocked transpose of `B^T`).
    fn covariance(&self, sigma: f64) -> DMatrix<f64> {
        let (n, m) = self.bt.shape();
        let mut b = DMatrix::<f64>::zeros(m, n);
        const BLOCK: usize = 64;
        let src = self.bt.as_slice();
        let dst = b.as_mut_slice();
        for j0 in (0..m).step_by(BLOCK) {
            for i0 in (0..n).step_by(BLOCK) {
                for j in j0..(j0 + BLOCK).min(m) {
                    for i in i0..(i0 + BLOCK).min(n) {
                        // b[(j, i)] = bt[(i, j)], column-major
                        dst[i * m + j] = src[j * n + i];
                    }
                }
            }
        }
        let mut c = &b * &self.bt;
        c *= sigma * sigma;
        c
    }
}

/// The spacing `dt = (t_N - t_0) / N` of a uniform grid:
/// `|t_i - (t_0 + i dt)| <= 16 eps max(|t_0|, |t_N|)` for every sample, a
/// few units in the last place of the largest time (grids made as
/// `t_0 + i dt` or `i dt`, or read from decimal text, pass; a spacing that
/// drifts does not). Then the weights of the full panels differ from a
/// periodic pattern times `e^{-s t_i}` only by rounding (the phase error
/// `|s| |t_i - (t_0 + i dt)|` is at the level of the rounding of `s t_i`).
fn uniform_spacing(t: &[f64]) -> Option<f64> {
    let n = t.len();
    let (t0, tn) = (t[0], t[n - 1]);
    let dt = (tn - t0) / (n - 1) as f64;
    let tol = 16.0 * f64::EPSILON * t0.abs().max(tn.abs());
    t.iter()
        .enumerate()
        .all(|(i, &ti)| (ti - (t0 + i as f64 * dt)).abs() <= tol)
        .then_some(dt)
}

fn lcm(a: usize, b: usize) -> usize {
    fn gcd(a: usize, b: usize) -> usize {
        if b == 0 {
            a
        } else {
            gcd(b, a % b)
        }
    }
    a / gcd(a, b) * b
}

/// Where the weights of one or two rules are periodic on a uniform grid of
/// spacing `dt`: taken exactly on the samples `0..l` and `r..n`, and on
/// `l..r` as `w_{l + k P + j} = w_{l + j} e^{-s P dt k}` (`k < m`, `j < P`)
/// for a period `P` that is a multiple of the rules' degrees. Sample `i` of
/// a full panel `k` (`i = k p + j`) has the weight
/// `h2 e^{-s t_{kp}} (W_j + [j = 0] e^{s p dt} W_p)`, the second term from the
/// panel before, so the pattern holds from sample `p` on until the remainder
/// panel (or the last sample) ([`Rule::bulk_end`]).
struct Layout {
    n: usize,
    l: usize,
    period: usize,
    m: usize,
    r: usize,
    /// `P dt`.
    pdt: f64,
}

impl Layout {
    fn new(n: usize, rules: &[&Rule], period: usize, dt: f64) -> Layout {
        let end = rules.iter().map(|r| r.bulk_end(n)).min().unwrap_or(0);
        let l = period.min(n);
        let m = if end > l { (end - l) / period } else { 0 };
        Layout {
            n,
            l,
            period,
            m,
            r: l + m * period,
            pdt: period as f64 * dt,
        }
    }

    /// The exact weights of `rule` at the node of `cache` on `0..l` followed by the
    /// reference period `l..l + P` (when `m > 0`), and on `r..n`.
    fn windows(&self, rule: &Rule, cache: &mut LocalWeights) -> (Vec<Complex64>, Vec<Complex64>) {
        let head_end = if self.m > 0 {
            self.l + self.period
        } else {
            self.l
        };
        (
            rule.window(0, head_end, cache),
            rule.window(self.r, self.n, cache),
        )
    }
}

/// Weights at a node `s` in the form of a [`Layout`]: the two ends, one
/// period and the number of periods.
struct Periodic {
    s: Complex64,
    head: Vec<Complex64>,
    reference: Vec<Complex64>,
    tail: Vec<Complex64>,
    m: usize,
    pdt: f64,
    /// `e^{-s P dt}` and `e^{-s P dt m}`.
    rho: Complex64,
    rho_m: Complex64,
}

impl Periodic {
    /// From [`Layout::windows`].
    fn new(s: Complex64, lay: &Layout, mut head: Vec<Complex64>, tail: Vec<Complex64>) -> Self {
        let reference = head.split_off(lay.l);
        Periodic {
            s,
            head,
            reference,
            tail,
            m: lay.m,
            pdt: lay.pdt,
            rho: (-s * lay.pdt).exp(),
            rho_m: (-s * (lay.pdt * lay.m as f64)).exp(),
        }
    }

    /// `Σ_{k<m} (e^{-(s_a + s_b) P dt})^k` (`conj`: `s_b` conjugated) for
    /// `a` = self: [`geometric`], or where the reduced exponent `z` has
    /// `|z| >= 1/2` (no cancellation in `1 - e^{-z}`) the plain
    /// `(1 - r^m) / (1 - r)` from the two nodes' `e^{-s P dt}` and
    /// `e^{-s P dt m}` (no exponential per pair).
    fn series(&self, b: &Periodic, conj: bool) -> Complex64 {
        let (sb, rb, rbm) = if conj {
            (b.s.conj(), b.rho.conj(), b.rho_m.conj())
        } else {
            (b.s, b.rho, b.rho_m)
        };
        let z = (self.s + sb) * self.pdt;
        if reduce_phase(z).norm_sqr() >= 0.25 {
            let one = Complex64::new(1.0, 0.0);
            (one - self.rho_m * rbm) / (one - self.rho * rb)
        } else {
            geometric(z, self.m)
        }
    }

    /// `Σ |w_i|^2`.
    fn sum_sq(&self) -> f64 {
        let ends = sum_sq(&self.head) + sum_sq(&self.tail);
        if self.m == 0 {
            return ends;
        }
        let g = geometric(Complex64::new(2.0 * self.s.re * self.pdt, 0.0), self.m);
        ends + sum_sq(&self.reference) * g.re
    }

    /// `[Σ Re a_i Re b_i, Σ Im a_i Im b_i, Σ Re a_i Im b_i, Σ Im a_i Re b_i]`
    /// for the weights `a` (self) and `b` (same layout): on the periodic part
    /// from `T = Σ a_i b_i` and `H = Σ a_i conj(b_i)` (one period times the
    /// geometric series in `e^{-(s_a + s_b) P dt}`, resp.
    /// `e^{-(s_a + conj s_b) P dt}`) as `Re(H ± T) / 2`, `Im(T ∓ H) / 2`.
    fn products(&self, b: &Periodic) -> [f64; 4] {
        let mut p = [0.0; 4];
        let ends = self.head.iter().zip(&b.head);
        for (u, v) in ends.chain(self.tail.iter().zip(&b.tail)) {
            p[0] += u.re * v.re;
            p[1] += u.im * v.im;
            p[2] += u.re * v.im;
            p[3] += u.im * v.re;
        }
        if self.m > 0 {
            let mut t = Complex64::new(0.0, 0.0);
            let mut h = Complex64::new(0.0, 0.0);
            for (u, v) in self.reference.iter().zip(&b.reference) {
                t += u * v;
                h += u * v.conj();
            }
            let t = t * self.series(b, false);
            let h = h * self.series(b, true);
            p[0] += 0.5 * (h.re + t.re);
            p[1] += 0.5 * (h.re - t.re);
            p[2] += 0.5 * (t.im - h.im);
            p[3] += 0.5 * (t.im + h.im);
        }
        p
    }
}

/// `sigma^2 B B^T` of [`SeriesTransform::noise_covariance`] from the
/// [`Periodic`] weights `w` of the nodes `s` (one layout).
fn periodic_covariance(s: &[Complex64], w: &[Periodic], sigma: f64) -> DMatrix<f64> {
    let (im_row, rows) = im_rows(s);
    let mut c = DMatrix::<f64>::zeros(rows, rows);
    let s2 = sigma * sigma;
    for a in 0..s.len() {
        for b in a..s.len() {
            let [xx, yy, xy, yx] = w[a].products(&w[b]);
            c[(a, b)] = s2 * xx;
            c[(b, a)] = s2 * xx;
            if let Some(ib) = im_row[b] {
                c[(a, ib)] = s2 * xy;
                c[(ib, a)] = s2 * xy;
            }
            if let Some(ia) = im_row[a] {
                c[(ia, b)] = s2 * yx;
                c[(b, ia)] = s2 * yx;
                if let Some(ib) = im_row[b] {
                    c[(ia, ib)] = s2 * yy;
                    c[(ib, ia)] = s2 * yy;
                }
            }
        }
    }
    c
}

/// `Σ_{k<m} e^{-z k}` as `expm1(-m z) / expm1(-z)` ([`Scalar::expm1`](crate::scalar::Scalar::expm1): no cancellation when
/// `e^{-z}` is near 1), with `Im z` first reduced to `[-π, π]` (the terms
/// are `2πi`-periodic in `z`); `m` when the reduced `z` is 0.
fn geometric(z: Complex64, m: usize) -> Complex64 {
    use crate::scalar::Scalar;
    if m == 0 {
        return Complex64::new(0.0, 0.0);
    }
    let z = reduce_phase(z);
    if z.re == 0.0 && z.im == 0.0 {
        return Complex64::new(m as f64, 0.0);
    }
    (-z * m as f64).expm1() / (-z).expm1()
}

/// `z - 2πi k` with the imaginary part in `[-π, π]`.
fn reduce_phase(z: Complex64) -> Complex64 {
    let tau = std::f64::consts::TAU;
    Complex64::new(z.re, z.im - tau * (z.im / tau).round())
}

/// Which part of which node each row of the stacked real vector holds:
/// `(q, false)` for `Re X(s_q)` (every node, in order), then `(q, true)` for
/// `Im X(s_q)` (complex nodes only, in order).
pub fn stacked_rows(s: &[Complex64]) -> Vec<(usize, bool)> {
    let mut rows: Vec<(usize, bool)> = (0..s.len()).map(|q| (q, false)).collect();
    rows.extend(
        s.iter()
            .enumerate()
            .filter(|(_, z)| z.im != 0.0)
            .map(|(q, _)| (q, true)),
    );
    rows
}

/// The stacked real vector `[Re z_1..z_Q; Im z_q for complex s_q]` of values
/// `z` at nodes `s`: the layout of [`SeriesTransform::noise_covariance`].
pub fn stack_re_im(s: &[Complex64], z: &[Complex64]) -> Vec<f64> {
    stacked_rows(s)
        .into_iter()
        .map(|(q, im)| if im { z[q].im } else { z[q].re })
        .collect()
}

impl Rule {
    fn new(t: &[f64], p: usize) -> Rule {
        let n = t.len();
        let mut panels = Vec::new();
        let mut mats: Vec<Vec<f64>> = Vec::new();
        let mut last_nodes: Vec<f64> = Vec::new();
        let mut push = |first: usize, alpha: f64, beta: f64| {
            let h2 = 0.5 * (beta - alpha);
            let c = 0.5 * (alpha + beta);
            let nodes: Vec<f64> = (0..=p).map(|j| (t[first + j] - c) / h2).collect();
            let same = !mats.is_empty()
                && nodes
                    .iter()
                    .zip(&last_nodes)
                    .all(|(a, b)| (a - b).abs() <= 1e-12);
            if !same {
                mats.push(lagrange_monomial(&nodes));
                last_nodes = nodes;
            }
            panels.push(Panel {
                first,
                alpha,
                h2,
                mat: mats.len() - 1,
            });
        };
        let full = (n - 1) / p;
        for k in 0..full {
            push(k * p, t[k * p], t[k * p + p]);
        }
        let r = (n - 1) % p;
        if r > 0 {
            push(n - 1 - p, t[n - 1 - r], t[n - 1]);
        }
        Rule {
            p,
            panels,
            full,
            mats,
        }
    }

    /// The end of the periodic part of the weights on a uniform grid: from
    /// sample `p` on, the weights follow the pattern of the full panels up
    /// to (excluding) the first sample of the remainder panel, or the last
    /// sample (which has one panel only) when there is none.
    fn bulk_end(&self, n: usize) -> usize {
        if self.panels.len() > self.full {
            n - 1 - self.p
        } else {
            n - 1
        }
    }

    /// The weights `w_i(s)` for `i` in `lo..hi`, from the panels that touch
    /// these samples only (the same sums, in the same order, as
    /// [`Rule::weights`]).
    fn window(&self, lo: usize, hi: usize, cache: &mut LocalWeights) -> Vec<Complex64> {
        let mut out = vec![Complex64::new(0.0, 0.0); hi - lo];
        let p = self.p;
        // the panels' first samples increase (the remainder panel is last)
        let start = self.panels.partition_point(|q| q.first + p < lo);
        let end = self.panels.partition_point(|q| q.first < hi);
        let run = &self.panels[start..end.max(start)];
        self.visit_panels(run, None, cache, |first, scale, w, _| {
            for (j, wj) in w.iter().enumerate() {
                let i = first + j;
                if (lo..hi).contains(&i) {
                    out[i - lo] += scale * wj;
                }
            }
        });
        out
    }

    /// Visit every panel with its first sample index, the factor
    /// `h2 e^{-s alpha}` and its local weights `W_j` (and their l1 norms
    /// `|Re W_j| + |Im W_j|`).
    fn for_each_panel(
        &self,
        s: Complex64,
        visit: impl FnMut(usize, Complex64, &[Complex64], &[f64]),
    ) {
        let mut cache = LocalWeights::new(self, s);
        self.visit_panels(&self.panels, None, &mut cache, visit);
    }

    /// [`Rule::for_each_panel`] on `panels` (a run of this rule's panels),
    /// with the local weights of `cache` (of this rule at `s`).
    ///
    /// With `step = Some(e^{-s p dt})` (all the panels, of a uniform grid of
    /// spacing `dt`) the factor `e^{-s alpha}` of a full panel is that of the
    /// panel before times `step`, and is computed afresh every
    /// [`REANCHOR`] panels and for the remainder panel: one complex
    /// exponential per 16 panels instead of one per panel, at the cost of a
    /// relative change of the factors of at most about `16 eps` plus the
    /// phase `|s| |alpha_k - (alpha_0 + k p dt)|` (the rounding of the
    /// times; [`uniform_spacing`]), below the rounding of the phase `s alpha`
    /// itself.
    fn visit_panels(
        &self,
        panels: &[Panel],
        step: Option<Complex64>,
        cache: &mut LocalWeights,
        mut visit: impl FnMut(usize, Complex64, &[Complex64], &[f64]),
    ) {
        let s = cache.s;
        let mut last: (usize, u64) = (usize::MAX, 0);
        let mut slot = 0;
        let mut e = Complex64::new(0.0, 0.0);
        for (k, pan) in panels.iter().enumerate() {
            let key = (pan.mat, pan.h2.to_bits());
            if key != last {
                slot = cache.slot(self, pan);
                last = key;
            }
            e = match step {
                Some(step) if k % REANCHOR != 0 && k < self.full => e * step,
                _ => (-s * pan.alpha).exp(),
            };
            let scale = e * pan.h2;
            let (w, wabs) = &cache.entries[slot];
            visit(pan.first, scale, w, wabs);
        }
    }

    fn weights(&self, t: &[f64], s: Complex64) -> Vec<Complex64> {
        let mut out = vec![Complex64::new(0.0, 0.0); t.len()];
        self.for_each_panel(s, |first, scale, w, _| {
            for (j, wj) in w.iter().enumerate() {
                out[first + j] += scale * wj;
            }
        });
        out
    }

    /// [`Rule::apply`] and [`Rule::weights`] from one visit of the panels
    /// (the same sums as the two calls).
    fn apply_and_weights(
        &self,
        t: &[f64],
        x: &[f64],
        s: Complex64,
    ) -> (Complex64, f64, Vec<Complex64>) {
        let mut out = vec![Complex64::new(0.0, 0.0); t.len()];
        let mut acc = Complex64::new(0.0, 0.0);
        let mut abs = 0.0;
        self.for_each_panel(s, |first, scale, w, wabs| {
            let mut loc = Complex64::new(0.0, 0.0);
            let mut la = 0.0;
            for (j, ((wj, aj), xj)) in w.iter().zip(wabs).zip(&x[first..]).enumerate() {
                loc += wj * xj;
                la += aj * xj.abs();
                out[first + j] += scale * wj;
            }
            acc += scale * loc;
            abs += (scale.re.abs() + scale.im.abs()) * la;
        });
        (acc, abs, out)
    }

    /// `(Σ w_i x_i, Σ_panels Σ_j |scale W_j| |x_j|)` without forming the weights
    /// (the second is an upper bound of `Σ |w_i x_i|`, in the l1 norm of the
    /// complex weights), with the local weights of `cache` (of this rule at
    /// the node). With `dt` (a uniform grid) the panels' factors
    /// `e^{-s alpha}` by the recurrence of [`Rule::visit_panels`].
    fn apply(&self, x: &[f64], dt: Option<f64>, cache: &mut LocalWeights) -> (Complex64, f64) {
        let mut acc = Complex64::new(0.0, 0.0);
        let mut abs = 0.0;
        let step = dt.map(|dt| (-cache.s * (self.p as f64 * dt)).exp());
        self.visit_panels(&self.panels, step, cache, |first, scale, w, wabs| {
            let mut loc = Complex64::new(0.0, 0.0);
            let mut la = 0.0;
            for ((wj, aj), xj) in w.iter().zip(wabs).zip(&x[first..]) {
                loc += wj * xj;
                la += aj * xj.abs();
            }
            acc += scale * loc;
            abs += (scale.re.abs() + scale.im.abs()) * la;
        });
        (acc, abs)
    }
}

/// The local weights `W_j` of the panels of one rule at one node `s`, with
/// their l1 norms, by (Lagrange matrix, exact `h2`): a uniform grid has a
/// handful of distinct `h2` values (rounding of `t_i`), so this small exact
/// cache makes the rule cost one exponential per panel, and serves all the
/// visits of the rule's panels at the node.
struct LocalWeights {
    s: Complex64,
    mu: Vec<Complex64>,
    /// The slot in `entries` of each key.
    map: std::collections::HashMap<(usize, u64), usize, std::hash::BuildHasherDefault<KeyHasher>>,
    /// `(W_j, |Re W_j| + |Im W_j|)`; slot 0 holds the last weights computed
    /// once the cache is full (256 keys).
    entries: Vec<(Vec<Complex64>, Vec<f64>)>,
}

impl LocalWeights {
    fn new(rule: &Rule, s: Complex64) -> LocalWeights {
        let zero = (
            vec![Complex64::new(0.0, 0.0); rule.p + 1],
            vec![0.0; rule.p + 1],
        );
        LocalWeights {
            s,
            mu: vec![Complex64::new(0.0, 0.0); rule.p + 1],
            map: Default::default(),
            entries: vec![zero],
        }
    }

    /// The slot of the local weights of panel `pan` of `rule` (the rule of
    /// this cache), computed if new.
    fn slot(&mut self, rule: &Rule, pan: &Panel) -> usize {
        let key = (pan.mat, pan.h2.to_bits());
        if let Some(&slot) = self.map.get(&key) {
            return slot;
        }
        let p = rule.p;
        moments(self.s * pan.h2, &mut self.mu);
        let l = &rule.mats[pan.mat];
        let (mut w, mut wabs) = (vec![Complex64::new(0.0, 0.0); p + 1], vec![0.0; p + 1]);
        for (j, (wj, aj)) in w.iter_mut().zip(wabs.iter_mut()).enumerate() {
            let row = &l[j * (p + 1)..(j + 1) * (p + 1)];
            *wj = row.iter().zip(&self.mu).map(|(c, m)| m * c).sum();
            *aj = wj.re.abs() + wj.im.abs();
        }
        if self.map.len() < 256 {
            self.map.insert(key, self.entries.len());
            self.entries.push((w, wabs));
            self.entries.len() - 1
        } else {
            self.entries[0] = (w, wabs);
            0
        }
    }
}

/// How often [`Rule::visit_panels`] recomputes the exponential of a panel on a
/// uniform grid.
const REANCHOR: usize = 16;

/// A multiplicative (Fx-style) hash of the `(matrix, h2 bits)` keys of the
/// local-weight cache of [`Rule::visit_panels`]: the default SipHash cost as
/// much as the lookup saved. Only speed depends on it.
#[derive(Default)]
struct KeyHasher(u64);

impl std::hash::Hasher for KeyHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(u64::from(b));
        }
    }
    fn write_u64(&mut self, v: u64) {
        self.0 = (self.0.rotate_left(5) ^ v).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
    fn write_usize(&mut self, v: usize) {
        self.write_u64(v as u64);
    }
}

/// Monomial coefficients of the Lagrange basis on `nodes`, row-major `(p+1)^2`.
fn lagrange_monomial(nodes: &[f64]) -> Vec<f64> {
    let m = nodes.len();
    let mut out = vec![0.0; m * m];
    for j in 0..m {
        let mut poly = vec![0.0; m];
        poly[0] = 1.0;
        let mut deg = 0;
        let mut denom = 1.0;
        for (k, &v) in nodes.iter().enumerate() {
            if k == j {
                continue;
            }
            // poly *= (x - v)
            for i in (0..=deg).rev() {
                poly[i + 1] += poly[i];
                poly[i] *= -v;
            }
            deg += 1;
            denom *= nodes[j] - v;
        }
        for k in 0..m {
            out[j * m + k] = poly[k] / denom;
        }
    }
    out
}

/// `mu_k(w) = ∫_{-1}^{1} v^k e^{-w (1 + v)} dv`, `k = 0..out.len()`.
///
/// `|w| < 3`: `e^{-w} Σ_j (-w)^j / j! · ∫ v^{k+j}` (terms at most `3^j/j!`);
/// otherwise the forward recurrence
/// `mu_k = ((-1)^k - e^{-2w} + k mu_{k-1}) / w`, whose error growth factor
/// `k / |w|` stays below one for the degrees used here.
pub(crate) fn moments(w: Complex64, out: &mut [Complex64]) {
    let p = out.len() - 1;
    if w.norm() < 3.0 {
        for o in out.iter_mut() {
            *o = Complex64::new(0.0, 0.0);
        }
        let mut term = Complex64::new(1.0, 0.0);
        for j in 0..80 {
            for (k, o) in out.iter_mut().enumerate() {
                if (k + j) % 2 == 0 {
                    *o += term * (2.0 / (k + j + 1) as f64);
                }
            }
            term *= -w / (j + 1) as f64;
            if term.norm() < 1e-22 {
                break;
            }
        }
        let e = (-w).exp();
        for o in out.iter_mut() {
            *o *= e;
        }
    } else {
        let e2 = (-2.0 * w).exp();
        out[0] = (1.0 - e2) / w;
        for k in 1..=p {
            let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
            out[k] = (sign - e2 + out[k - 1] * k as f64) / w;
        }
    }
}

/// A decaying-mode model of the end of a record, `x(t) ≈ Σ C_i e^{p_i (t - t_end)}`,
/// fitted by the matrix pencil method (Hua & Sarkar) and used by
/// [`Tail::Modes`] to continue the record analytically:
/// `∫_{t_end}^∞ x e^{-st} dt = e^{-s t_end} Σ C_i / (s - p_i)`.
///
/// Fit: the last `frac` of the record (uniform spacing required), decimated
/// to at most 300 points; Hankel pencil with parameter `L/3`; model order
/// from the singular values above `1e-11 σ_max`; amplitudes by complex least
/// squares. The fit is accepted only if every pole decays and the model
/// reproduces *every* sample of the window (not only the decimated ones,
/// which would hide aliasing) to a relative RMS residual below `1e-4`.
/// Records with many modes of very different amplitudes (for example a
/// 20-mass chain) are usually rejected: their weak modes sit below the
/// rank threshold, and [`Tail::Modes`] then falls back to the envelope bound.
#[derive(Clone, Debug, PartialEq)]
pub struct ModeFit {
    /// End of the record.
    pub t_end: f64,
    /// Poles `p_i` (continuous time).
    pub poles: Vec<Complex64>,
    /// Amplitudes `C_i` at `t_end`.
    pub amps: Vec<Complex64>,
    /// Relative RMS residual of the fit over the window.
    pub residual: f64,
}

impl ModeFit {
    /// Fit the last `frac` of the record; `None` if no acceptable fit.
    pub fn fit(t: &[f64], x: &[f64], frac: f64) -> Option<ModeFit> {
        use nalgebra::DMatrix;
        let n = t.len();
        let t_end = t[n - 1];
        let start = t.partition_point(|&v| v < t_end - frac * (t_end - t[0]));
        let nw = n - start;
        if nw < 30 {
            return None;
        }
        let h = (t_end - t[start]) / (nw - 1) as f64;
        if t[start..]
            .windows(2)
            .any(|w| ((w[1] - w[0]) - h).abs() > 1e-6 * h)
        {
            return None;
        }
        let q = nw.div_ceil(300).max(1);
        let idx: Vec<usize> = (start..n).step_by(q).collect();
        let y: Vec<f64> = idx.iter().map(|&i| x[i]).collect();
        let l = y.len();
        let big_h = q as f64 * h;
        let norm_y = (y.iter().map(|v| v * v).sum::<f64>() / l as f64).sqrt();
        if l < 30 || norm_y == 0.0 {
            return None;
        }
        let pp = l / 3;
        let hank = DMatrix::from_fn(l - pp, pp + 1, |i, j| y[i + j]);
        let svd = crate::linalg::svd_checked(hank, false, true)?;
        let sv = &svd.singular_values;
        let smax = sv.iter().cloned().fold(0.0, f64::max);
        let r = sv.iter().filter(|&&v| v > 1e-11 * smax).count().min(pp - 1);
        if r == 0 {
            return None;
        }
        let vt = svd.v_t?; // rows: right singular vectors
        let vr = vt.rows(0, r).transpose(); // (pp+1) x r
        let v1 = vr.rows(0, pp).into_owned();
        let v2 = vr.rows(1, pp).into_owned();
        let a = v1.pseudo_inverse(1e-14).ok()? * v2;
        let z = a.complex_eigenvalues();
        if z.iter()
            .any(|zi| zi.norm().is_nan() || zi.norm() >= 1.0 || zi.norm() == 0.0)
        {
            return None;
        }
        // amplitudes: y_k = Σ c_i z_i^k
        let vand = DMatrix::from_fn(l, r, |k, i| z[i].powu(k as u32));
        let yc = nalgebra::DVector::from_iterator(l, y.iter().map(|&v| Complex64::new(v, 0.0)));
        let c = crate::linalg::svd_checked(vand, true, true)?
            .solve(&yc, 0.0)
            .ok()?;
        let poles: Vec<Complex64> = z.iter().map(|zi| zi.ln() / big_h).collect();
        let t0 = t[idx[0]];
        // residual on every sample of the window
        let mut res2 = 0.0;
        let mut sum2 = 0.0;
        for i in start..n {
            let model: f64 = poles
                .iter()
                .zip(c.iter())
                .map(|(p, ci)| (ci * (p * (t[i] - t0)).exp()).re)
                .sum();
            res2 += (model - x[i]).powi(2);
            sum2 += x[i] * x[i];
        }
        let residual = (res2 / sum2.max(f64::MIN_POSITIVE)).sqrt();
        if residual.is_nan() || residual >= 1e-4 {
            return None;
        }
        let amps = poles
            .iter()
            .zip(c.iter())
            .map(|(p, ci)| ci * (p * (t_end - t0)).exp())
            .collect();
        Some(ModeFit {
            t_end,
            poles,
            amps,
            residual,
        })
    }

    /// `∫_{t_end}^∞ model(t) e^{-st} dt` (real part of the complex model, so
    /// that conjugate pairs combine: for real `x` the model is real).
    pub fn tail(&self, s: Complex64) -> Complex64 {
        // Re(model) = (model + conj(model))/2, transform of conj term uses conj(p), conj(C).
        let e = (-s * self.t_end).exp();
        let sum: Complex64 = self
            .poles
            .iter()
            .zip(&self.amps)
            .map(|(p, c)| 0.5 * (c / (s - p) + c.conj() / (s - p.conj())))
            .sum();
        e * sum
    }

    /// `|e^{-s t_end}| Σ |C_i| / |s - p_i|`: the scale of the tail transform.
    pub fn tail_abs(&self, s: Complex64) -> f64 {
        (-s.re * self.t_end).exp()
            * self
                .poles
                .iter()
                .zip(&self.amps)
                .map(|(p, c)| c.norm() / (s - p).norm().min((s - p.conj()).norm()))
                .sum::<f64>()
    }

    /// The largest real part of the poles (the slowest decay, negated).
    pub fn max_re_pole(&self) -> f64 {
        self.poles
            .iter()
            .map(|p| p.re)
            .fold(f64::NEG_INFINITY, f64::max)
    }
}

/// Envelope of the last quarter of the record (at least 16 samples): 8
/// blocks by time, `ln max|x|` fitted linearly; see the module docs.
fn fit_envelope(t: &[f64], x: &[f64]) -> Envelope {
    let n = t.len();
    let t_end = t[n - 1];
    let span = t_end - t[0];
    let mut start = t.partition_point(|&v| v < t_end - 0.25 * span);
    start = start.min(n.saturating_sub(16));
    let t0 = t[start];
    let nb = 8usize;
    let width = (t_end - t0) / nb as f64;
    let mut blocks: Vec<(f64, f64)> = Vec::new(); // (block start time, max |x|)
    if width > 0.0 {
        let mut cur = 0usize;
        let mut mx = 0.0f64;
        let mut have = false;
        for i in start..n {
            let b = (((t[i] - t0) / width) as usize).min(nb - 1);
            if b != cur && have {
                blocks.push((t0 + cur as f64 * width, mx));
                mx = 0.0;
            }
            cur = b;
            have = true;
            mx = mx.max(x[i].abs());
        }
        if have {
            blocks.push((t0 + cur as f64 * width, mx));
        }
    }
    let floor = blocks.iter().fold(0.0f64, |a, b| a.max(b.1)) * 1e-300;
    let mut rate = 0.0;
    if blocks.len() >= 3 && floor > 0.0 {
        let pts: Vec<(f64, f64)> = blocks
            .iter()
            .map(|&(tb, m)| (tb + 0.5 * width, (m + floor).ln()))
            .collect();
        let k = pts.len() as f64;
        let mt = pts.iter().map(|p| p.0).sum::<f64>() / k;
        let my = pts.iter().map(|p| p.1).sum::<f64>() / k;
        let sxy: f64 = pts.iter().map(|p| (p.0 - mt) * (p.1 - my)).sum();
        let sxx: f64 = pts.iter().map(|p| (p.0 - mt) * (p.0 - mt)).sum();
        if sxx > 0.0 {
            let fitted = -sxy / sxx;
            // A decay is only believed if the envelope falls by at least a
            // factor of 2 across the window; otherwise the record is treated
            // as not decaying (rate 0).
            if fitted * (t_end - t0) >= std::f64::consts::LN_2 {
                rate = 0.5 * fitted;
            }
        }
    }
    let amp = blocks
        .iter()
        .map(|&(tb, m)| m * (-rate * (t_end - tb)).exp())
        .fold(0.0f64, f64::max);
    Envelope { t_end, amp, rate }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn c(re: f64, im: f64) -> Complex64 {
        Complex64::new(re, im)
    }

    #[test]
    fn moments_series_and_recurrence_agree_near_the_switch() {
        for &w in &[c(2.99, 0.0), c(0.0, 2.99), c(2.1, 2.1), c(0.05, 2.99)] {
            let mut a = vec![c(0.0, 0.0); 10];
            moments(w, &mut a);
            let w2 = w * (3.01 / 2.99);
            let mut b = vec![c(0.0, 0.0); 10];
            moments(w2, &mut b);
            // compare the recurrence at w2 with the series at w2 forced via a tiny shift check:
            // derivative bound |d mu/dw| <= 2, so |a - b| <= 2 |w - w2|.
            for k in 0..10 {
                assert!(
                    (a[k] - b[k]).norm() <= 2.0 * (w - w2).norm() + 1e-14,
                    "{w} {k}"
                );
            }
        }
    }

    #[test]
    fn moments_match_quadrature() {
        for &w in &[
            c(0.3, 0.0),
            c(5.0, 0.0),
            c(0.01, 7.0),
            c(40.0, -3.0),
            c(1.0, 1.0),
        ] {
            let mut mu = vec![c(0.0, 0.0); 8];
            moments(w, &mut mu);
            for (k, m) in mu.iter().enumerate() {
                // composite Simpson with many points
                let n = 20000;
                let h = 2.0 / n as f64;
                let f = |v: f64| (-w * (1.0 + v)).exp() * v.powi(k as i32);
                let mut acc = f(-1.0) + f(1.0);
                for i in 1..n {
                    let v = -1.0 + i as f64 * h;
                    acc += f(v) * if i % 2 == 1 { 4.0 } else { 2.0 };
                }
                acc *= h / 3.0;
                assert!((acc - m).norm() < 1e-10, "w={w} k={k}: {acc} vs {m}");
            }
        }
    }

    #[test]
    fn exact_for_polynomials_on_nonuniform_grids() {
        // cubic x(t) on [0, 2] with jittered times: exact up to the tail, which is zero.
        let t: Vec<f64> = (0..=41)
            .map(|i| {
                2.0 * i as f64 / 41.0
                    + if i % 41 == 0 {
                        0.0
                    } else {
                        0.01 * ((i * 7) % 5) as f64 / 5.0
                    }
            })
            .collect();
        let x: Vec<f64> = t.iter().map(|t| 1.0 - 2.0 * t + 0.5 * t * t * t).collect();
        let opts = TransformOptions {
            tail: Tail::Zero,
            ..Default::default()
        };
        let tr = SeriesTransform::new(&t, &x, &opts).unwrap();
        for &s in &[c(0.0, 0.0), c(1.0, 0.0), c(0.1, 50.0), c(200.0, 0.0)] {
            let v = tr.eval(s).unwrap();
            // exact: ∫_0^2 (1 - 2t + t^3/2) e^{-st} dt, by a fine Simpson rule
            let n = 200000;
            let h = 2.0 / n as f64;
            let f = |u: f64| (-s * u).exp() * (1.0 - 2.0 * u + 0.5 * u * u * u);
            let mut acc = f(0.0) + f(2.0);
            for i in 1..n {
                acc += f(i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
            }
            acc *= h / 3.0;
            assert!(
                (v.value - acc).norm() < 1e-9 * (1.0 + acc.norm()),
                "{s}: {} vs {acc}",
                v.value
            );
            assert!(v.err_disc < 1e-9, "{s}: {}", v.err_disc);
        }
    }

    #[test]
    fn errors_name_the_field() {
        let o = TransformOptions::default();
        let e = SeriesTransform::new(&[0.0, 1.0, 1.0, 2.0], &[0.0; 4], &o).unwrap_err();
        assert!(e.to_string().contains("t[2]"), "{e}");
        let e = SeriesTransform::new(&[0.0, 1.0, 2.0, 3.0], &[0.0, f64::NAN, 0.0, 0.0], &o)
            .unwrap_err();
        assert!(e.to_string().contains("x[1]"), "{e}");
        let e = SeriesTransform::uniform(0.0, 0.0, &[0.0; 8], &o).unwrap_err();
        assert!(e.to_string().contains("dt"), "{e}");
        let e = SeriesTransform::uniform(0.0, -0.1, &[0.0; 8], &o).unwrap_err();
        assert!(e.to_string().contains("dt"), "{e}");
        let e = SeriesTransform::new(&[0.0, 1.0, 2.0], &[0.0; 3], &o).unwrap_err();
        assert!(e.to_string().contains("at least 4"), "{e}");
    }

    #[test]
    fn noise_covariance_matches_monte_carlo() {
        // 401 samples on [0, 40], white noise sigma = 0.3; 3 real and 3 complex nodes
        let n = 401;
        let sigma = 0.3;
        let t: Vec<f64> = (0..n).map(|i| i as f64 * 0.1).collect();
        let s = [
            c(0.05, 0.0),
            c(0.3, 0.0),
            c(2.0, 0.0),
            c(0.05, 0.5),
            c(0.05, 0.6),
            c(0.2, 3.0),
        ];
        let opts = TransformOptions {
            tail: Tail::Zero,
            ..Default::default()
        };
        let tr = SeriesTransform::new(&t, &vec![0.0; n], &opts).unwrap();
        let cov = tr.noise_covariance(&s, sigma).unwrap();
        let m = stacked_rows(&s).len();
        assert_eq!((cov.nrows(), cov.ncols()), (m, m));
        assert_eq!(m, 9);
        // the diagonal agrees with the per-node variance of eval
        let trn = SeriesTransform::new(
            &t,
            &vec![0.0; n],
            &TransformOptions {
                noise_sigma: Some(sigma),
                ..opts.clone()
            },
        )
        .unwrap();
        for (q, z) in s.iter().enumerate() {
            let v = trn.eval(*z).unwrap().noise_var.unwrap();
            let mut d = cov[(q, q)];
            if let Some(r) = stacked_rows(&s).iter().position(|&(p, im)| p == q && im) {
                d += cov[(r, r)];
            }
            assert!((d - v).abs() <= 1e-12 * v, "{z}: {d} vs {v}");
        }
        // Monte Carlo: 400 seeded draws
        let draws = 400;
        let mut acc = DMatrix::<f64>::zeros(m, m);
        for seed in 0..draws {
            let (e, _) = crate::noise::add_noise(
                &vec![0.0; n],
                crate::noise::NoiseLevel::Absolute(sigma),
                1000 + seed,
            )
            .unwrap();
            let tr = SeriesTransform::new(&t, &e, &opts).unwrap();
            let vals: Vec<Complex64> = s.iter().map(|z| tr.eval(*z).unwrap().value).collect();
            let r = nalgebra::DVector::from_vec(stack_re_im(&s, &vals));
            acc += &r * r.transpose();
        }
        acc /= draws as f64;
        // each entry within 4.5 standard errors of the sample second moment
        // (Var = (C_jj C_kk + C_jk^2) / draws for Gaussian data)
        for j in 0..m {
            for k in 0..m {
                let se = ((cov[(j, j)] * cov[(k, k)] + cov[(j, k)].powi(2)) / draws as f64).sqrt();
                assert!(
                    (acc[(j, k)] - cov[(j, k)]).abs() <= 4.5 * se,
                    "({j},{k}): MC {} vs {} (se {se})",
                    acc[(j, k)],
                    cov[(j, k)]
                );
            }
        }
        // strongly correlated neighbours: the two close Bromwich nodes
        let corr = cov[(3, 4)] / (cov[(3, 3)] * cov[(4, 4)]).sqrt();
        assert!(corr > 0.5, "{corr}");
    }

    #[test]
    fn data_covariance_adds_the_error_estimate() {
        let t: Vec<f64> = (0..=400).map(|i| i as f64 * 0.1).collect();
        let x: Vec<f64> = t.iter().map(|t| (-0.2 * t).exp() * t.sin()).collect();
        let tr = SeriesTransform::new(
            &t,
            &x,
            &TransformOptions {
                noise_sigma: Some(1e-3),
                ..Default::default()
            },
        )
        .unwrap();
        let s = [c(0.5, 0.0), c(0.1, 1.0)];
        let vals = tr.eval_many(&s).unwrap();
        let full = tr.data_covariance(&vals).unwrap();
        let noise = tr.noise_covariance(&s, 1e-3).unwrap();
        let d = &full - &noise;
        // the difference is tiny next to the noise: compare on the noise scale
        let tol = |r: usize| 4.0 * f64::EPSILON * full[(r, r)];
        let e: Vec<f64> = vals.iter().map(|v| tr.model_error(v, 1e-3)).collect();
        assert!((d[(0, 0)] - e[0].powi(2)).abs() <= tol(0));
        assert!((d[(1, 1)] - 0.5 * e[1].powi(2)).abs() <= tol(1));
        assert!((d[(2, 2)] - 0.5 * e[1].powi(2)).abs() <= tol(2));
        // without noise the model error is the whole estimate; with noise at most that
        for v in &vals {
            assert!((tr.model_error(v, 0.0) - v.err).abs() <= 1e-15 * v.err);
            assert!(tr.model_error(v, 1e-3) <= v.err);
        }
        assert_eq!(d[(0, 1)], 0.0);
        assert_eq!(
            stack_re_im(&s, &[c(1.0, 2.0), c(3.0, 4.0)]),
            vec![1.0, 3.0, 4.0]
        );
    }

    #[test]
    fn one_pass_matches_the_per_call_values_and_covariance() {
        // jittered times (several Lagrange matrices), noise level given or
        // not, real and complex nodes
        let t: Vec<f64> = (0..=1203)
            .map(|i| 0.05 * i as f64 + if i % 5 == 2 { 0.004 } else { 0.0 })
            .collect();
        let x: Vec<f64> = t
            .iter()
            .enumerate()
            .map(|(i, t)| (-0.05 * t).exp() * (1.3 * t).sin() + 1e-3 * ((i * 37) % 11) as f64)
            .collect();
        let s = [
            c(0.2, 0.0),
            c(0.05, 0.0),
            c(0.05, 0.3),
            c(0.05, 0.31),
            c(0.1, 2.5),
            c(3.0, 0.0),
        ];
        for sigma in [Some(1e-3), Some(0.0), None] {
            let tr = SeriesTransform::new(
                &t,
                &x,
                &TransformOptions {
                    noise_sigma: sigma,
                    ..Default::default()
                },
            )
            .unwrap();
            let vals = tr.eval_many(&s).unwrap();
            let cov = tr.data_covariance(&vals).unwrap();
            let (v1, c1) = tr.eval_with_covariance(&s).unwrap();
            let close = |a: f64, b: f64, scale: f64| (a - b).abs() <= 1e-12 * scale;
            for (a, b) in vals.iter().zip(&v1) {
                assert_eq!(a.s, b.s);
                assert!(close(a.value.re, b.value.re, a.value.norm()));
                assert!(close(a.value.im, b.value.im, a.value.norm()));
                assert!(close(a.err, b.err, a.err));
                assert!(close(a.err_disc, b.err_disc, a.err_disc));
                assert_eq!(a.noise_var.is_some(), b.noise_var.is_some());
                if let (Some(p), Some(q)) = (a.noise_var, b.noise_var) {
                    assert!(close(p, q, p));
                }
                // each node's eval agrees too
                let e = tr.eval(a.s).unwrap();
                assert!(close(e.value.re, a.value.re, a.value.norm()));
                assert!(close(e.err, a.err, a.err));
            }
            assert_eq!((c1.nrows(), c1.ncols()), (cov.nrows(), cov.ncols()));
            for j in 0..cov.nrows() {
                for k in 0..cov.ncols() {
                    let scale = (cov[(j, j)] * cov[(k, k)]).sqrt();
                    assert!(close(cov[(j, k)], c1[(j, k)], scale), "({j},{k})");
                }
            }
        }
        assert!(SeriesTransform::new(&t, &x, &TransformOptions::default())
            .unwrap()
            .eval_with_covariance(&[c(f64::NAN, 0.0)])
            .is_err());
    }

    #[test]
    fn non_decaying_record_refuses_small_s() {
        let t: Vec<f64> = (0..=1000).map(|i| i as f64 * 0.1).collect();
        let x: Vec<f64> = t.iter().map(|t| t.sin()).collect();
        let tr = SeriesTransform::new(&t, &x, &TransformOptions::default()).unwrap();
        assert!(matches!(
            tr.eval(c(0.0, 1.0)),
            Err(Error::Unresolvable { .. })
        ));
        let v = tr.eval(c(0.5, 0.0)).unwrap();
        let exact = 1.0 / (0.25 + 1.0);
        assert!((v.value.re - exact).abs() <= v.err);
    }
}

#[cfg(test)]
mod periodic_tests {
    use super::*;

    fn c(re: f64, im: f64) -> Complex64 {
        Complex64::new(re, im)
    }

    fn max_abs(m: &DMatrix<f64>) -> f64 {
        m.iter().fold(0.0f64, |a, v| a.max(v.abs()))
    }

    /// `sigma^2 B B^T` written out from the weight vectors.
    fn explicit_cov(tr: &SeriesTransform, s: &[Complex64], sigma: f64) -> DMatrix<f64> {
        let rows = stacked_rows(s);
        let w: Vec<Vec<Complex64>> = s.iter().map(|&z| tr.weights(z)).collect();
        let part = |(q, im): (usize, bool), i: usize| if im { w[q][i].im } else { w[q][i].re };
        DMatrix::from_fn(rows.len(), rows.len(), |a, b| {
            sigma
                * sigma
                * (0..tr.t.len())
                    .map(|i| part(rows[a], i) * part(rows[b], i))
                    .sum::<f64>()
        })
    }

    fn nodes() -> Vec<Complex64> {
        let mut s = vec![
            c(1e-4, 0.0),
            c(0.01, 0.0),
            c(0.3, 0.0),
            c(2.0, 0.0),
            c(50.0, 0.0),
        ];
        s.extend((0..12).map(|k| c(0.05, 0.01 + 8.0 * k as f64 / 11.0)));
        s.extend([c(0.05, 0.31), c(1e-4, 3.0), c(1.0, 1.0)]);
        s
    }

    fn record(t: &[f64]) -> Vec<f64> {
        t.iter()
            .map(|t| (-0.1 * t).exp() * (1.3 * t).sin() + 0.3 * (-0.02 * t).exp() * (0.7 * t).cos())
            .collect()
    }

    /// Uniform grids: `N` a multiple of 7 and 35 or not, a few panels only,
    /// `t_0 != 0`, `dt = 0.01` and `0.05`, 6001 and 30001 samples.
    const GRIDS: [(f64, f64, usize); 11] = [
        (0.0, 0.05, 6001),
        (0.0, 0.01, 6001),
        (0.0, 0.01, 30001),
        (3.7, 0.05, 6001),
        (3.7, 0.05, 283),
        (0.0, 0.05, 281),
        (0.0, 0.05, 351),
        (-2.0, 0.01, 500),
        (0.0, 0.1, 8),
        (0.0, 0.1, 15),
        (0.5, 0.1, 30),
    ];

    #[test]
    fn periodic_sums_match_the_weight_vectors_on_uniform_grids() {
        let s = nodes();
        for &(t0, dt, n) in &GRIDS {
            let t: Vec<f64> = (0..n).map(|i| t0 + i as f64 * dt).collect();
            let x = record(&t);
            for sigma in [Some(1e-2), None] {
                let opts = TransformOptions {
                    noise_sigma: sigma,
                    tail: Tail::Zero,
                    ..Default::default()
                };
                let tr = SeriesTransform::new(&t, &x, &opts).unwrap();
                assert!(tr.has_periodic_sums(), "{t0} {dt} {n}");
                let g = tr.clone().general_path();
                assert!(!g.has_periodic_sums());
                let what = format!("t0 {t0} dt {dt} n {n} sigma {sigma:?}");
                // the noise covariance: periodic sums against B B^T
                let fast = tr.noise_covariance(&s, 0.3).unwrap();
                let old = g.noise_covariance(&s, 0.3).unwrap();
                let scale = max_abs(&old);
                assert!(max_abs(&(&fast - &old)) <= 1e-12 * scale, "{what}");
                if n <= 6001 {
                    let ex = explicit_cov(&tr, &s, 0.3);
                    assert!(max_abs(&(&fast - &ex)) <= 1e-12 * scale, "{what}");
                }
                // values, error estimates, noise variances and the data covariance
                let (v1, c1) = tr.eval_with_covariance(&s).unwrap();
                let (v0, c0) = g.eval_with_covariance(&s).unwrap();
                if sigma.is_some() {
                    assert!(max_abs(&(&c1 - &c0)) <= 1e-12 * max_abs(&c0), "{what}");
                } else {
                    // no noise: the model-error variances e_q^2 alone, and
                    // e_q (the error estimate) moves with the values
                    for (r, (q, _)) in stacked_rows(&s).into_iter().enumerate() {
                        let tol = 0.5 * v0[q].err * v0[q].err_round + 1e-12 * c0[(r, r)];
                        assert!((c1[(r, r)] - c0[(r, r)]).abs() <= tol, "{what} {r}");
                    }
                    let off = &c1 - DMatrix::from_diagonal(&c1.diagonal());
                    assert_eq!(max_abs(&off), 0.0);
                }
                for (a, b) in v1.iter().zip(&v0) {
                    let z = a.s;
                    // the values differ only by the panels' factors
                    // e^{-s alpha} (recurrence), far below the rounding floor
                    assert!(
                        (a.value - b.value).norm() <= 0.1 * b.err_round,
                        "{what} {z}"
                    );
                    assert!((a.err - b.err).abs() <= 0.2 * b.err_round, "{what} {z}");
                    assert_eq!(a.err_trunc, b.err_trunc);
                    match (a.noise_var, b.noise_var) {
                        (Some(p), Some(q)) => assert!((p - q).abs() <= 1e-12 * q, "{what} {z}"),
                        (None, None) => {}
                        _ => panic!("{what} {z}: noise_var given on one path only"),
                    }
                    let (ma, mb) = (tr.model_error(b, 1e-2), g.model_error(b, 1e-2));
                    assert!((ma - mb).abs() <= 1e-12 * mb, "{what} {z}: {ma} {mb}");
                }
            }
        }
    }

    #[test]
    fn eval_with_covariance_is_eval_many_and_data_covariance_on_uniform_grids() {
        let s = nodes();
        for &(t0, dt, n) in &GRIDS[..8] {
            let t: Vec<f64> = (0..n).map(|i| t0 + i as f64 * dt).collect();
            let opts = TransformOptions {
                noise_sigma: Some(1e-2),
                tail: Tail::Zero,
                ..Default::default()
            };
            let tr = SeriesTransform::new(&t, &record(&t), &opts).unwrap();
            assert!(tr.has_periodic_sums());
            let vals = tr.eval_many(&s).unwrap();
            let (v1, c1) = tr.eval_with_covariance(&s).unwrap();
            assert_eq!(vals, v1);
            assert_eq!(tr.data_covariance(&vals).unwrap(), c1);
        }
    }

    #[test]
    fn non_uniform_grids_take_the_weight_vectors() {
        let s = nodes();
        // jittered, drifting spacing, one time off by 1e-9 dt
        let grids: Vec<Vec<f64>> = vec![
            (0..=1203)
                .map(|i| 0.05 * i as f64 + if i % 5 == 2 { 0.004 } else { 0.0 })
                .collect(),
            (0..=2000)
                .map(|i| 0.05 * i as f64 * (1.0 + 1e-9 * i as f64))
                .collect(),
            (0..=2000)
                .map(|i| 0.05 * i as f64 + if i == 1000 { 5e-11 } else { 0.0 })
                .collect(),
        ];
        for t in &grids {
            let x = record(t);
            let opts = TransformOptions {
                noise_sigma: Some(1e-2),
                tail: Tail::Zero,
                ..Default::default()
            };
            let tr = SeriesTransform::new(t, &x, &opts).unwrap();
            assert!(!tr.has_periodic_sums());
            let g = tr.clone().general_path();
            let (v1, c1) = tr.eval_with_covariance(&s).unwrap();
            assert_eq!(
                (v1.clone(), c1.clone()),
                g.eval_with_covariance(&s).unwrap()
            );
            let ex = explicit_cov(&tr, &s, 0.3);
            let cov = tr.noise_covariance(&s, 0.3).unwrap();
            assert!(max_abs(&(&cov - &ex)) <= 1e-13 * max_abs(&ex));
            // with a noise level, eval forms the weights: as before, the
            // value is that of the rule's plain sum
            for v in &v1 {
                assert_eq!(v.value, tr.eval(v.s).unwrap().value);
                let w = tr.weights(v.s);
                let plain: Complex64 = w.iter().zip(&x).map(|(w, x)| w * x).sum();
                assert!((plain - v.value).norm() <= v.err_round);
            }
        }
    }

    #[test]
    fn uniform_spacing_accepts_rounded_grids_only() {
        let t: Vec<f64> = (0..=6000).map(|i| i as f64 * 0.05).collect();
        assert_eq!(uniform_spacing(&t), Some(0.05));
        // times read back from 2-decimal text
        let parsed: Vec<f64> = t
            .iter()
            .map(|v| format!("{v:.2}").parse().unwrap())
            .collect();
        assert!(uniform_spacing(&parsed).is_some());
        let shifted: Vec<f64> = (0..=6000).map(|i| 7.3 + i as f64 * 0.05).collect();
        assert!(uniform_spacing(&shifted).is_some());
        let mut off = t.clone();
        off[3000] += 1e-10;
        assert_eq!(uniform_spacing(&off), None);
        let drift: Vec<f64> = (0..=6000)
            .map(|i| i as f64 * 0.05 * (1.0 + 1e-12 * i as f64))
            .collect();
        assert_eq!(uniform_spacing(&drift), None);
    }

    #[test]
    fn geometric_series_against_the_plain_sum() {
        let tau = std::f64::consts::TAU;
        for &z in &[
            c(7e-5, 0.0),
            c(1e-12, 0.0),
            c(0.0, 1e-9),
            c(0.035, 0.1),
            c(0.035, -2.0),
            c(1e-6, tau + 1e-7),
            c(0.0, 3.0 * tau),
            c(3.0, 1.0),
            c(-0.01, 0.2),
            c(0.0, 0.0),
        ] {
            for m in [1usize, 2, 7, 50] {
                let mut plain = Complex64::new(0.0, 0.0);
                for k in (0..m).rev() {
                    plain += (-z * k as f64).exp();
                }
                let bound: f64 = (0..m).map(|k| (-z.re * k as f64).exp()).sum();
                let g = geometric(z, m);
                assert!((g - plain).norm() <= 1e-13 * bound, "{z} {m}: {g} {plain}");
            }
            assert_eq!(geometric(z, 0), Complex64::new(0.0, 0.0));
        }
    }

    #[test]
    fn negative_real_parts_agree_too() {
        let t: Vec<f64> = (0..=700).map(|i| i as f64 * 0.05).collect();
        let opts = TransformOptions {
            noise_sigma: Some(1e-2),
            tail: Tail::Zero,
            ..Default::default()
        };
        let tr = SeriesTransform::new(&t, &record(&t), &opts).unwrap();
        let s = [c(-0.05, 0.0), c(-0.02, 1.0), c(0.1, 0.5)];
        let (_, c1) = tr.eval_with_covariance(&s).unwrap();
        let (_, c0) = tr.clone().general_path().eval_with_covariance(&s).unwrap();
        assert!(max_abs(&(&c1 - &c0)) <= 1e-12 * max_abs(&c0));
    }
}
