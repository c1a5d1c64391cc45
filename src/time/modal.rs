//! Exact inverse Laplace transform of the chain's responses: `x_i(t)` as a
//! finite sum of damped modes.
//!
//! `X_i(s) = amp [K(s)^{-1}]_{ij}` with `K(s) = M s^2 + D s + K` (impulse `amp`
//! on mass `j`) is rational in `s` with the `2n` roots of `det K(s)` as poles,
//! so `x_i(t)` is a finite sum of damped exponentials. Two paths, chosen per
//! chain by [`Modes::new`]:
//!
//! * **Proportional damping** (`d_i / m_i = alpha` for all `i`, which includes
//!   `d = 0`, uniform chains and spring defects): the real symmetric
//!   eigenproblem `M^{-1/2} K M^{-1/2} q_k = omega_k^2 q_k` (closed form
//!   `omega_k^2 = (4k/m) sin^2(k pi / (2(n+1)))`, `q_ik ∝ sin(i k pi/(n+1))` for a
//!   uniform chain, [`ModalPath::ClosedForm`]; dense symmetric eigen otherwise,
//!   [`ModalPath::Proportional`]). Every mode is one second-order term
//!   ```text
//!   c_k / (s^2 + alpha s + omega_k^2)  <->  c_k e^{-alpha t/2} sin(b_k t) / b_k,
//!   b_k^2 = omega_k^2 - alpha^2/4,  c_k = amp q_ik q_jk / sqrt(m_i m_j)
//!   ```
//!   evaluated with `sin(b t)/b` as an entire function of `b^2` (power series
//!   near 0), so under-, critically (`b = 0`, the `t e^{-alpha t/2}` term) and
//!   over-damped modes are one formula without cancellation.
//! * **General damping** (for example a mass defect with uniform `d`, the
//!   paper's case, or damper defects): the quadratic eigenproblem
//!   `(M s^2 + D s + K) v = 0`, linearised in the symmetric scaling
//!   (`2n x 2n` real Schur form for starting values), each pole then refined by
//!   Rayleigh-quotient iteration on the tridiagonal `K(s)` (O(n) per step),
//!   residues `amp v_i v_j / (v^T (2 p M + D) v)` ([`ModalPath::Quadratic`]).
//!   Two poles closer than 5% (near-critical modes of a non-proportional
//!   chain) become one second-order term `(e (s + a) + c) / ((s + a)^2 + w2)`:
//!   its centre from the Schur form, `w2` from `det K(-a)` divided by the
//!   other poles, `e` and `c` fitted to the exact `X(s)` on `Re s = 1/2`; this
//!   stays accurate through critical damping, where separate residues blow up.
//!   [`ModalResponse::error_bound`] estimates the remaining error (rounding
//!   and pole conditioning).
//!
//! **Boundaries.** A free end is a wall spring of 0; the uniform chain keeps
//! closed-form modes for every pair of ends, `omega_j = 2 sqrt(k/m) sin(theta_j/2)`
//! with `theta_j = j pi/(n+1)` and shapes `sin(i theta)` (fixed-fixed),
//! `theta_j = (2j-1) pi/(2n+1)` with `cos((i-1/2) theta)` (left free) or
//! `sin(i theta)` (right free), `theta_j = (j-1) pi/n` with `cos((i-1/2) theta)`
//! (free-free; `j = 1` is the rigid-body mode, `omega = 0`, whose term
//! `c (1 - e^{-alpha t})/alpha` tends to the drift `c/alpha`, or grows like `c t`
//! without damping). See [`crate::green`] for the derivation.
//!
//! **Observables.** [`ModalResponse::derivative`] differentiates every term
//! (velocity, then acceleration for `t > 0`, the impulse's delta excluded).
//! [`natural_modes`] reports natural frequencies and damping ratios.
//!
//! ```
//! use springmass::{Chain, Defect, forward::response, Complex64};
//! use springmass::time::modal::ModalResponse;
//! let chain = Chain::paper(20)?.with_defect(Defect::Mass { at: 15, m: 1.01 })?;
//! let x1 = ModalResponse::impulse(&chain, 1)?;
//! assert!(x1.eval(0.0).abs() < 1e-14);                  // x(0) = 0
//! let s = Complex64::new(0.5, 2.0);                      // its transform is X_1(s)
//! assert!((x1.laplace(s) - response(&chain, s, 1)?).norm() < 1e-12);
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::chain::{closed_theta, Boundary, Chain, Damping, Site};
use crate::error::{Error, Result};
use crate::observable::Observable;
use nalgebra::DMatrix;
use num_complex::Complex64;

/// Largest chain for the dense symmetric eigen path.
pub const MAX_N_SYMMETRIC: usize = 3000;
/// Largest chain for the quadratic (general damping) path: its Schur form is
/// `O((2n)^3)`.
pub const MAX_N_QUADRATIC: usize = 1000;

/// How a [`Modes`] decomposition was computed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModalPath {
    /// Uniform chain: closed-form (Chebyshev) modes.
    ClosedForm,
    /// Proportional damping: dense real symmetric eigenproblem.
    Proportional,
    /// General damping: quadratic eigenproblem.
    Quadratic,
}

/// One term of a modal sum.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Term {
    /// `e^{-a t} (e cos(b t) + c sin(b t)/b)` with `b^2 = w2` (any sign:
    /// `cosh`/`sinh` for `w2 < 0`, `e + c t` for `w2 = 0`); transform
    /// `(e (s + a) + c) / (s^2 + 2 a s + a^2 + w2)`. Proportional modes have
    /// `e = 0`; a near-double pole pair of the general path is one such term.
    Osc {
        /// Coefficient of `sin(b t)/b`.
        c: f64,
        /// Coefficient of `cos(b t)`.
        e: f64,
        /// Decay rate.
        a: f64,
        /// Squared damped frequency.
        w2: f64,
    },
    /// A complex-conjugate pole pair: `2 Re(r e^{p t})`, `Im p > 0`.
    Pair {
        /// Pole (upper half plane).
        p: Complex64,
        /// Residue at `p`.
        r: Complex64,
    },
    /// A real pole: `r e^{p t}`.
    Real {
        /// Pole.
        p: f64,
        /// Residue.
        r: f64,
    },
}

/// A pole of `X(s)` with its principal-part coefficient: the term is
/// `residue / (s - pole)^order`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoleResidue {
    /// The pole.
    pub pole: Complex64,
    /// The coefficient of `1 / (s - pole)^order`.
    pub residue: Complex64,
    /// 1, or 2 for an exactly critically damped mode.
    pub order: u8,
}

/// `cos(sqrt(w2) t)` as an entire function of `w2` (`cosh` for `w2 < 0`).
fn cos_t(w2: f64, t: f64) -> f64 {
    let z = w2 * t * t;
    if z.abs() < 0.1 {
        let mut term = 1.0;
        let mut sum = 1.0;
        for k in 1..12 {
            term *= -z / ((2 * k - 1) as f64 * (2 * k) as f64);
            sum += term;
        }
        sum
    } else if w2 > 0.0 {
        (w2.sqrt() * t).cos()
    } else {
        ((-w2).sqrt() * t).cosh()
    }
}

/// `sin(sqrt(w2) t) / sqrt(w2)` as an entire function of `w2` (so `t` at `w2 = 0`,
/// `sinh` for `w2 < 0`).
fn sinc_t(w2: f64, t: f64) -> f64 {
    let z = w2 * t * t;
    if z.abs() < 0.1 {
        // t * sum_k (-z)^k / (2k+1)!
        let mut term = 1.0;
        let mut sum = 1.0;
        for k in 1..12 {
            term *= -z / ((2 * k) as f64 * (2 * k + 1) as f64);
            sum += term;
        }
        t * sum
    } else if w2 > 0.0 {
        let b = w2.sqrt();
        (b * t).sin() / b
    } else {
        let b = (-w2).sqrt();
        (b * t).sinh() / b
    }
}

impl Term {
    /// The term as `scale Re(r e^{p t})`, `(p, r, scale)`: scale 2 for a
    /// pole pair and an oscillating [`Term::Osc`], 1 for a real pole; `None`
    /// for an `Osc` with `w2 <= 0`, which has no such form.
    #[inline]
    fn exponential(&self) -> Option<(Complex64, Complex64, f64)> {
        match *self {
            Term::Pair { p, r } => Some((p, r, 2.0)),
            Term::Osc { c, e, a, w2 } if w2 > 0.0 => {
                let b = w2.sqrt();
                Some((
                    Complex64::new(-a, b),
                    Complex64::new(0.5 * e, -0.5 * c / b),
                    2.0,
                ))
            }
            Term::Real { p, r } => Some((Complex64::new(p, 0.0), Complex64::new(r, 0.0), 1.0)),
            Term::Osc { .. } => None,
        }
    }
    /// Value at `t >= 0`.
    pub fn eval(&self, t: f64) -> f64 {
        match *self {
            Term::Osc { c, e, a, w2 } => {
                if w2 < 0.0 && w2 * t * t < -1.0 {
                    // overdamped, large t: avoid overflow of sinh * exp
                    let b = (-w2).sqrt();
                    let (up, down) = (((b - a) * t).exp(), (-(a + b) * t).exp());
                    c * (up - down) / (2.0 * b) + e * 0.5 * (up + down)
                } else if e == 0.0 {
                    c * (-a * t).exp() * sinc_t(w2, t)
                } else {
                    (-a * t).exp() * (c * sinc_t(w2, t) + e * cos_t(w2, t))
                }
            }
            Term::Pair { p, r } => {
                let (sn, cs) = (p.im * t).sin_cos();
                2.0 * (p.re * t).exp() * (r.re * cs - r.im * sn)
            }
            Term::Real { p, r } => r * (p * t).exp(),
        }
    }
    /// Laplace transform at `s`.
    pub fn laplace(&self, s: Complex64) -> Complex64 {
        match *self {
            Term::Osc { c, e, a, w2 } => ((s + a) * e + c) / (s * s + s * (2.0 * a) + (a * a + w2)),
            Term::Pair { p, r } => r / (s - p) + r.conj() / (s - p.conj()),
            Term::Real { p, r } => r / (s - p),
        }
    }
    /// The time derivative for `t > 0` (the jump `term(0+)` at `t = 0` dropped):
    /// `Osc {c, e}` becomes `Osc {c: -(a c + e w2), e: c - a e}`, a pole term
    /// `r e^{p t}` becomes `r p e^{p t}`.
    pub fn derivative(&self) -> Term {
        match *self {
            Term::Osc { c, e, a, w2 } => Term::Osc {
                c: -(a * c + e * w2),
                e: c - a * e,
                a,
                w2,
            },
            Term::Pair { p, r } => Term::Pair { p, r: r * p },
            Term::Real { p, r } => Term::Real { p, r: r * p },
        }
    }
    /// The largest pole modulus of the term.
    fn pole_norm(&self) -> f64 {
        match *self {
            Term::Osc { a, w2, .. } => a.abs() + w2.abs().sqrt(),
            Term::Pair { p, .. } => p.norm(),
            Term::Real { p, .. } => p.abs(),
        }
    }
    /// A bound on `|term(t)|` over `t >= 0` (for rounding estimates).
    fn amplitude(&self) -> f64 {
        match *self {
            Term::Osc { c, e, a, w2 } => {
                // max over t of e^{-at} |sin(bt)/b| (sinh for w2 < 0)
                let crit = 1.0 / (a * std::f64::consts::E);
                let b = w2.abs().sqrt();
                let env = if w2 >= 0.0 {
                    (1.0 / b).min(crit)
                } else if b <= a {
                    // b = a: a rigid-body mode, (1 - e^{-2at})/(2a) <= 1/(2a)
                    (0.5 / b).min(1.0 / ((a - b) * std::f64::consts::E))
                } else {
                    f64::INFINITY
                };
                let env = if env.is_nan() { f64::INFINITY } else { env };
                c.abs() * env + e.abs()
            }
            Term::Pair { r, .. } => 2.0 * r.norm(),
            Term::Real { r, .. } => r.abs(),
        }
    }
}

/// `out[i] += scale_l Re(r_l e^{p_l t_i})` for the terms `l` in order, each
/// stepped by `e^{p_l dt}` and re-anchored every [`ANCHOR`] samples
/// ([`ModalResponse::eval_many`]); samples at `t < 0` are skipped.
fn step_terms(
    out: &mut [f64],
    ts: &[f64],
    dt: f64,
    p: &[Complex64],
    r: &[Complex64],
    scale: &[f64],
) {
    const L: usize = 4;
    let n = p.len();
    debug_assert!(n <= L);
    let zero = Complex64::new(0.0, 0.0);
    let mut z = [zero; L];
    for (zl, pl) in z.iter_mut().zip(p) {
        *zl = (pl * dt).exp();
    }
    let mut w = [zero; L];
    for (i, (o, &t)) in out.iter_mut().zip(ts).enumerate() {
        if t < 0.0 {
            continue;
        }
        if i % ANCHOR == 0 || t - dt < 0.0 {
            for l in 0..n {
                w[l] = r[l] * (p[l] * t).exp();
            }
        } else {
            for l in 0..n {
                w[l] *= z[l];
            }
        }
        for l in 0..n {
            *o += scale[l] * w[l].re;
        }
    }
}

/// Samples between exact re-anchorings of the recurrence in
/// [`ModalResponse::eval_many`].
pub const ANCHOR: usize = 64;

/// Samples between exact re-anchorings of the recurrence in
/// [`DoublePoleSum::eval_many`] (derivatives for a Jacobian).
pub const DERIVATIVE_ANCHOR: usize = 256;

/// From this many sums on, [`DoublePoleSum::eval_many_columns`] forms them
/// as one matrix product (fewer: the loop over the samples, whose sums a
/// chain fit's few columns keep to the bit).
pub const GEMM_COLUMNS: usize = 8;

/// Steps the poles `p` along the uniform grid `ts` (step `dt`): for each
/// sample `i` at `t >= 0`, calls `f(i, t, w)` with `w[l] = e^{p[l] t}`,
/// taken exactly every [`DERIVATIVE_ANCHOR`] samples and at the first
/// sample from `t = 0` on, and otherwise one complex multiplication by
/// `e^{p[l] dt}` from the sample before (the pole sums' shared recurrence).
fn step_poles<const L: usize>(
    p: &[Complex64; L],
    ts: &[f64],
    dt: f64,
    mut f: impl FnMut(usize, f64, &[Complex64; L]),
) {
    let z: [Complex64; L] = std::array::from_fn(|l| (p[l] * dt).exp());
    let mut w = [Complex64::new(0.0, 0.0); L];
    for (i, &t) in ts.iter().enumerate() {
        if t < 0.0 {
            continue;
        }
        if i % DERIVATIVE_ANCHOR == 0 || t - dt < 0.0 {
            for l in 0..L {
                w[l] = (p[l] * t).exp();
            }
        } else {
            for l in 0..L {
                w[l] *= z[l];
            }
        }
        f(i, t, &w);
    }
}

/// The step `dt` when `ts` is uniform to rounding: every
/// `|t_i - (t_0 + i dt)| <= 8 eps max(|t_0|, |t_last|, dt)` with
/// `dt = (t_last - t_0) / (N - 1) > 0`; `None` otherwise or for fewer than
/// 3 times. The rounding is that of the grid's largest time: a record's
/// axis shifted to its blow (`t_i - t_blow`) keeps the rounding of `t_i`
/// in its samples near zero.
fn uniform_step(ts: &[f64]) -> Option<f64> {
    let n = ts.len();
    if n < 3 {
        return None;
    }
    let (t0, t1) = (ts[0], ts[n - 1]);
    let dt = (t1 - t0) / (n - 1) as f64;
    if !(dt > 0.0 && dt.is_finite()) {
        return None;
    }
    let tol = 8.0 * f64::EPSILON * t0.abs().max(t1.abs()).max(dt);
    ts.iter()
        .enumerate()
        .all(|(i, &t)| (t - (t0 + i as f64 * dt)).abs() <= tol)
        .then_some(dt)
}

/// `x(t)` as an exact finite sum of damped modes (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct ModalResponse {
    terms: Vec<Term>,
    path: ModalPath,
    /// error from the conditioning of the poles (general path)
    pole_err: f64,
}

impl ModalResponse {
    /// `x_observe(t)` of `chain` for its impulse `gamma` on mass 1.
    ///
    /// # Errors
    /// `observe` out of range; see [`Modes::new`].
    pub fn impulse(chain: &Chain, observe: usize) -> Result<ModalResponse> {
        Modes::new(chain)?.response(observe, 1, chain.gamma())
    }
    /// The observable `obs` of mass `observe` after the impulse on mass 1:
    /// the displacement's modal sum differentiated `obs.power()` times
    /// ([`ModalResponse::derivative`]; the acceleration excludes the delta).
    ///
    /// # Errors
    /// As [`ModalResponse::impulse`].
    ///
    /// ```
    /// use springmass::{Chain, forward::{observe, Observable}, Complex64};
    /// use springmass::time::modal::ModalResponse;
    /// let c = Chain::paper(6)?;
    /// let a = ModalResponse::impulse_observable(&c, 1, Observable::Acceleration)?;
    /// let s = Complex64::new(0.3, 1.0);
    /// let want = observe(&c, s, 1, Observable::Acceleration)?;
    /// assert!((a.laplace(s) - want).norm() < 1e-12);
    /// # Ok::<(), springmass::Error>(())
    /// ```
    pub fn impulse_observable(
        chain: &Chain,
        observe: usize,
        obs: Observable,
    ) -> Result<ModalResponse> {
        let mut r = ModalResponse::impulse(chain, observe)?;
        for _ in 0..obs.power() {
            r = r.derivative();
        }
        Ok(r)
    }

    /// The time derivative for `t > 0` (term by term, see
    /// [`Term::derivative`]); its transform is `s X(s) - x(0+)`.
    pub fn derivative(&self) -> ModalResponse {
        let pmax = self.terms.iter().map(Term::pole_norm).fold(0.0, f64::max);
        ModalResponse {
            terms: self.terms.iter().map(Term::derivative).collect(),
            path: self.path,
            pole_err: self.pole_err * pmax,
        }
    }

    /// Build from terms (for example to combine responses).
    pub fn from_terms(terms: Vec<Term>, path: ModalPath) -> ModalResponse {
        ModalResponse {
            terms,
            path,
            pole_err: 0.0,
        }
    }
    /// The terms.
    pub fn terms(&self) -> &[Term] {
        &self.terms
    }
    /// The decomposition path used.
    pub fn path(&self) -> ModalPath {
        self.path
    }
    /// All poles (conjugates included) with their residues.
    pub fn poles(&self) -> Vec<PoleResidue> {
        let mut out = Vec::with_capacity(2 * self.terms.len());
        let pr = |pole, residue, order| PoleResidue {
            pole,
            residue,
            order,
        };
        for t in &self.terms {
            match *t {
                Term::Osc { c, e, a, w2 } => {
                    if w2 > 0.0 {
                        let b = w2.sqrt();
                        let r = Complex64::new(0.5 * e, -c / (2.0 * b));
                        out.push(pr(Complex64::new(-a, b), r, 1));
                        out.push(pr(Complex64::new(-a, -b), r.conj(), 1));
                    } else if w2 < 0.0 {
                        let b = (-w2).sqrt();
                        let (r1, r2) = (0.5 * e + c / (2.0 * b), 0.5 * e - c / (2.0 * b));
                        out.push(pr(Complex64::new(-a + b, 0.0), r1.into(), 1));
                        out.push(pr(Complex64::new(-a - b, 0.0), r2.into(), 1));
                    } else {
                        if e != 0.0 {
                            out.push(pr(Complex64::new(-a, 0.0), e.into(), 1));
                        }
                        out.push(pr(Complex64::new(-a, 0.0), c.into(), 2));
                    }
                }
                Term::Pair { p, r } => {
                    out.push(pr(p, r, 1));
                    out.push(pr(p.conj(), r.conj(), 1));
                }
                Term::Real { p, r } => out.push(pr(p.into(), r.into(), 1)),
            }
        }
        out
    }
    /// `x(t)`; zero for `t < 0`.
    pub fn eval(&self, t: f64) -> f64 {
        if t < 0.0 {
            return 0.0;
        }
        self.terms.iter().map(|m| m.eval(t)).sum()
    }
    /// The response to a blow at `time` at the times `ts` (ascending): zero
    /// up to `time`, `x(t - time)` after it, by [`ModalResponse::eval_many`]
    /// (the shifted times of a uniform grid are one).
    pub fn eval_after(&self, ts: &[f64], time: f64) -> Vec<f64> {
        let first = ts.partition_point(|&t| t <= time);
        let shifted: Vec<f64> = ts[first..].iter().map(|&t| t - time).collect();
        let mut out = vec![0.0; first];
        out.extend(self.eval_many(&shifted));
        out
    }
    /// `x(t)` at many times. On a uniform grid `t_i = t_0 + i dt` (to
    /// rounding, as a sampled record's times are) each oscillating or
    /// decaying term is stepped by one complex multiplication per sample,
    /// `w_{i+1} = w_i e^{p dt}`, re-anchored at the exact `r e^{p t_i}`
    /// every [`ANCHOR`] samples so that the recurrence's rounding stays
    /// below `ANCHOR` ulps: about 10 times faster than a sine, cosine and
    /// exponential per sample and term. Other grids, and overdamped or
    /// critically damped `Osc` terms, are evaluated term by term.
    pub fn eval_many(&self, ts: &[f64]) -> Vec<f64> {
        let Some(dt) = uniform_step(ts) else {
            return ts.iter().map(|&t| self.eval(t)).collect();
        };
        let mut out = vec![0.0; ts.len()];
        // up to L consecutive stepped terms share one pass over the samples
        // (independent recurrences side by side); each sample still
        // receives the terms in their order, as term by term would
        const L: usize = 4;
        let zero = Complex64::new(0.0, 0.0);
        let (mut p, mut r, mut scale) = ([zero; L], [zero; L], [0.0; L]);
        let mut len = 0;
        let mut terms = self.terms.iter().peekable();
        while let Some(term) = terms.next() {
            // the term as 2 Re(r e^{p t}) (pair) or r e^{p t} (real)
            let stepped = term.exponential();
            match stepped {
                Some((pl, rl, sl)) => {
                    p[len] = pl;
                    r[len] = rl;
                    scale[len] = sl;
                    len += 1;
                }
                None => {
                    for (o, &t) in out.iter_mut().zip(ts) {
                        if t >= 0.0 {
                            *o += term.eval(t);
                        }
                    }
                    continue;
                }
            }
            // flush when full, at the end, or before a term evaluated directly
            let next_direct = matches!(terms.peek(), Some(Term::Osc { w2, .. }) if *w2 <= 0.0);
            if len == L || terms.peek().is_none() || next_direct {
                step_terms(&mut out, ts, dt, &p[..len], &r[..len], &scale[..len]);
                len = 0;
            }
        }
        out
    }
    /// The Laplace transform `X(s) = sum_k term_k(s)` (for checks against
    /// [`crate::forward::response`]).
    pub fn laplace(&self, s: Complex64) -> Complex64 {
        self.terms.iter().map(|m| m.laplace(s)).sum()
    }
    /// An error estimate for [`ModalResponse::eval`]: rounding
    /// `8 eps sum_k max_t |term_k(t)|`, plus, on the general path, the pole
    /// conditioning `eps sum_k max_t |term_k| (|p_k| / sep_k)^2` (`sep_k` the
    /// distance to the nearest other pole). Large when close poles carry large
    /// cancelling residues. An estimate, not a rigorous bound.
    pub fn error_bound(&self) -> f64 {
        8.0 * f64::EPSILON * self.terms.iter().map(Term::amplitude).sum::<f64>() + self.pole_err
    }
}

#[derive(Clone, Debug)]
enum Inner {
    /// alpha = d_i / m_i (beside beta g_i), beta = c_j / k_j (mode k's
    /// damping alpha + beta omega_k^2); q: None for the closed form, else
    /// column k = mode k
    Prop {
        alpha: f64,
        beta: f64,
        /// the modal model's ratios, one per entry of `omega2` (empty for
        /// another model): mode k's damping adds 2 zeta_k omega_k
        zeta: Vec<f64>,
        omega2: Vec<f64>,
        q: Option<DMatrix<f64>>,
    },
    Quad {
        poles: Vec<Complex64>,
        vecs: Vec<Vec<Complex64>>,
        norms: Vec<Complex64>,
        /// |p| / distance to the nearest other pole
        conds: Vec<f64>,
        /// near-double pole pairs `(a, w2)`: `(s + a)^2 + w2`
        clusters: Vec<(f64, f64)>,
        k: Vec<f64>,
        d: Vec<f64>,
        g: Vec<f64>,
        /// spring-parallel dampers
        c: Vec<f64>,
    },
}

/// The modal decomposition of a chain, shared by the responses of all
/// `(observed, excited)` pairs.
#[derive(Clone, Debug)]
pub struct Modes {
    n: usize,
    ends: (Boundary, Boundary),
    masses: Vec<f64>,
    path: ModalPath,
    inner: Inner,
}

impl Modes {
    /// The best path for this chain: closed form for a uniform chain,
    /// symmetric eigen for proportional damping, quadratic eigen otherwise.
    ///
    /// # Errors
    /// A chain too large for the path it needs ([`MAX_N_SYMMETRIC`],
    /// [`MAX_N_QUADRATIC`]), or an eigenvalue solver that does not converge.
    pub fn new(chain: &Chain) -> Result<Modes> {
        if matches!(chain.damping(), Damping::Modal { .. }) || proportional_damping(chain).is_some()
        {
            Modes::proportional(chain)
        } else {
            Modes::quadratic(chain)
        }
    }

    /// The proportional-damping path; also the `modal` damping model's
    /// (every undamped mode damped with its ratio `zeta_j`, plus grounded
    /// dampers proportional to the masses, if any).
    ///
    /// # Errors
    /// Damping not proportional to mass; `n >` [`MAX_N_SYMMETRIC`] for a
    /// non-uniform chain.
    pub fn proportional(chain: &Chain) -> Result<Modes> {
        let n = chain.n();
        let (alpha, beta) = proportional_coefficients(chain)?;
        // the modal model's ratio of each mode (none for another model)
        let ratios = |omega2: &[f64]| {
            if chain.damping().is_modal() {
                chain.damping().modal_ratios_of(omega2)
            } else {
                Vec::new()
            }
        };
        let masses = chain.masses();
        let springs = chain.springs();
        let grounds = chain.grounds();
        let ends = (chain.left(), chain.right());
        let uniform_m = masses.iter().all(|&m| m == masses[0]) && grounds.iter().all(|&g| g == 0.0);
        let (lo, hi) = chain.spring_range();
        let uniform_k = (lo..=hi).all(|j| springs[j] == chain.k());
        if uniform_m && uniform_k {
            let (k, m) = (chain.k(), masses[0]);
            let omega2: Vec<f64> = (1..=n)
                .map(|j| {
                    let s = (0.5 * closed_theta(ends, n, j)).sin();
                    4.0 * k / m * s * s
                })
                .collect();
            let zeta = ratios(&omega2);
            return Ok(Modes {
                n,
                ends,
                masses,
                path: ModalPath::ClosedForm,
                inner: Inner::Prop {
                    alpha,
                    beta,
                    zeta,
                    omega2,
                    q: None,
                },
            });
        }
        let eig = symmetric_eigen(
            &masses,
            &springs,
            &grounds,
            "a modal decomposition of a non-uniform chain",
        )?;
        Ok(Modes {
            n,
            ends,
            masses,
            path: ModalPath::Proportional,
            inner: Inner::Prop {
                alpha,
                beta,
                zeta: ratios(eig.eigenvalues.as_slice()),
                omega2: eig.eigenvalues.iter().copied().collect(),
                q: Some(eig.eigenvectors),
            },
        })
    }

    /// The general (quadratic eigenproblem) path; works for every chain.
    ///
    /// # Errors
    /// `n >` [`MAX_N_QUADRATIC`]; the Schur iteration does not converge or
    /// the pole count is not `2n`.
    pub fn quadratic(chain: &Chain) -> Result<Modes> {
        let n = chain.n();
        if n > MAX_N_QUADRATIC {
            return Err(Error::invalid(
                "n",
                n,
                format!(
                    "n <= {MAX_N_QUADRATIC} for the quadratic eigenproblem (non-proportional damping)"
                ),
            ));
        }
        let m = chain.masses();
        let k = chain.springs();
        let d = chain.dampers();
        let g = chain.grounds();
        let c = chain.spring_dampers();
        let qep = Qep {
            m: &m,
            k: &k,
            d: &d,
            g: &g,
            c: &c,
        };
        let ev = poles(chain, &qep)?;
        // near-double pole pairs: one second-order term each, fitted per
        // response (see `Modes::response`)
        let (used, mut clusters) = near_double_pairs(&ev);
        let (poles, vecs, norms, conds) = simple_modes(chain, &qep, &ev, &used);
        // the pair's product (w2) from the determinant: the Schur 2x2 blocks
        // split a near-double pair with cancellation, its centre is reliable
        let schur_clusters = clusters.clone();
        for (ci, cl) in clusters.iter_mut().enumerate() {
            let others: Vec<(f64, f64)> = schur_clusters
                .iter()
                .enumerate()
                .filter(|(j, _)| *j != ci)
                .map(|(_, c)| *c)
                .collect();
            if let Some(w2) = qep.cluster_w2(cl.0, &poles, &others) {
                cl.1 = w2;
            }
        }
        Ok(Modes {
            n,
            ends: (chain.left(), chain.right()),
            masses: m,
            path: ModalPath::Quadratic,
            inner: Inner::Quad {
                poles,
                vecs,
                norms,
                conds,
                clusters,
                k,
                d,
                g,
                c,
            },
        })
    }

    /// `i` (field `observe`) and `j` (field `excite`) in `1..=n`.
    fn check_masses(&self, i: usize, j: usize) -> Result<()> {
        for (field, v) in [("observe", i), ("excite", j)] {
            if v < 1 || v > self.n {
                return Err(Error::invalid(
                    field,
                    v,
                    format!("1 <= {field} <= {}", self.n),
                ));
            }
        }
        Ok(())
    }

    /// Entry `x` (0-based) of the proportional path's mass-normalised mode
    /// `m` (0-based) before the `M^{-1/2}` scaling: column `m` of `q`, or
    /// the closed form's shape.
    fn prop_entry(&self, q: Option<&DMatrix<f64>>, m: usize, x: usize) -> f64 {
        match q {
            Some(q) => q[(x, m)],
            None => closed_shape(self.ends, self.n, m + 1, x + 1),
        }
    }

    /// The simple poles of the quadratic path in the upper half-plane and
    /// real (near-double pairs apart), with their vectors (physical
    /// coordinates, any scale and phase); `None` on another path.
    pub fn quadratic_poles(&self) -> Option<(&[Complex64], &[Vec<Complex64>])> {
        match &self.inner {
            Inner::Quad { poles, vecs, .. } => Some((poles, vecs)),
            Inner::Prop { .. } => None,
        }
    }

    /// The path used.
    pub fn path(&self) -> ModalPath {
        self.path
    }

    /// Response of mass `i` to an impulse `amp delta(t)` on mass `j` (1-based).
    ///
    /// # Errors
    /// `i` or `j` outside `1..=n`.
    pub fn response(&self, i: usize, j: usize, amp: f64) -> Result<ModalResponse> {
        self.check_masses(i, j)?;
        let (i0, j0) = (i - 1, j - 1);
        let mut terms = Vec::new();
        let mut pole_err = 0.0;
        match &self.inner {
            Inner::Prop {
                alpha,
                beta,
                zeta,
                omega2,
                q,
            } => {
                let scale = amp / (self.masses[i0] * self.masses[j0]).sqrt();
                for (kk, &w) in omega2.iter().enumerate() {
                    let mut a = prop_rate(*alpha, *beta, w);
                    if let Some(z) = zeta.get(kk).filter(|z| **z != 0.0) {
                        a += z * w.max(0.0).sqrt();
                    }
                    let (qi, qj) = (
                        self.prop_entry(q.as_ref(), kk, i0),
                        self.prop_entry(q.as_ref(), kk, j0),
                    );
                    let c = scale * qi * qj;
                    if c != 0.0 {
                        terms.push(Term::Osc {
                            c,
                            e: 0.0,
                            a,
                            w2: w - a * a,
                        });
                    }
                }
            }
            Inner::Quad {
                poles,
                vecs,
                norms,
                conds,
                clusters,
                k,
                d,
                g,
                c,
            } => {
                for (((p, v), nu), cond) in poles.iter().zip(vecs).zip(norms).zip(conds) {
                    let r = v[i0] * v[j0] * amp / nu;
                    let term = if p.im == 0.0 {
                        Term::Real { p: p.re, r: r.re }
                    } else {
                        Term::Pair { p: *p, r }
                    };
                    pole_err += f64::EPSILON * term.amplitude() * cond * cond;
                    terms.push(term);
                }
                if !clusters.is_empty() {
                    let qep = Qep {
                        m: &self.masses,
                        k,
                        d,
                        g,
                        c,
                    };
                    terms.extend(fit_clusters(&qep, clusters, &terms, i0, j0, amp)?);
                }
            }
        }
        Ok(ModalResponse {
            terms,
            path: self.path,
            pole_err,
        })
    }
}

impl Modes {
    /// The derivative of the response of mass `i` to an impulse `amp delta(t)`
    /// on mass `j` with respect to one value `theta` of the chain whose
    /// dynamic stiffness changes as `dK(s)/dtheta = s^power u u^T`
    /// (`u = e_at` with power 2 for the mass at `at`, power 1 for its damper;
    /// `u = e_at - e_{at+1}` with power 0 for spring `at`), as an exact sum
    /// over the poles (see [`DoublePoleSum`]):
    ///
    /// ```text
    /// dX_ij/dtheta = -amp s^power (e_i^T K^-1 u)(u^T K^-1 e_j)
    ///              = sum_k A_k / (s - p_k)^2 + B_k / (s - p_k),
    /// A_k = -amp p_k^power a_k b_k,
    /// B_k = -amp (power p_k^(power-1) a_k b_k + p_k^power (a_k hb_k + b_k ha_k)),
    /// ```
    ///
    /// with `a_k = v_ik (u.v_k) / nu_k`, `b_k = (u.v_k) v_jk / nu_k` the residues of
    /// the two factors at `p_k` and `ha_k = sum_{l != k} a_l / (p_k - p_l)` (and
    /// `hb_k`) the rest of each factor there: its inverse transform is
    /// `sum_k (A_k t + B_k) e^{p_k t}` (reciprocity: the double poles are the
    /// `t e^{p t}` terms of a moving pole). `u` is given as `(mass, coefficient)`
    /// pairs (1-based masses; a wall side of a spring is left out).
    ///
    /// `Ok(None)` when the decomposition has no simple-pole form: the
    /// proportional paths, and near-double pole pairs of the quadratic path
    /// (use differences there).
    ///
    /// # Errors
    /// `i`, `j` or a mass of `u` outside `1..=n` (fields `observe`, `excite`,
    /// `u`); `power > 2` (field `power`).
    ///
    /// ```
    /// use springmass::{Chain, Defect};
    /// use springmass::time::modal::Modes;
    /// let c = Chain::paper(6)?.with_defect(Defect::Mass { at: 3, m: 2.0 })?;
    /// let d = Modes::new(&c)?.value_derivative(1, 1, 1.0, &[(3, 1.0)], 2)?.unwrap();
    /// let h = 1e-6;
    /// let x = |m: f64| -> springmass::Result<f64> {
    ///     let c = Chain::paper(6)?.with_defect(Defect::Mass { at: 3, m })?;
    ///     Ok(springmass::time::modal::ModalResponse::impulse(&c, 1)?.eval(7.0))
    /// };
    /// let fd = (x(2.0 + h)? - x(2.0 - h)?) / (2.0 * h);
    /// assert!((d.eval(7.0) - fd).abs() < 1e-7);
    /// # Ok::<(), springmass::Error>(())
    /// ```
    pub fn value_derivative(
        &self,
        i: usize,
        j: usize,
        amp: f64,
        u: &[(usize, f64)],
        power: u32,
    ) -> Result<Option<DoublePoleSum>> {
        if power > 2 {
            return Err(Error::invalid("power", power, "0, 1 or 2"));
        }
        let mut poly = [0.0; 3];
        poly[power as usize] = 1.0;
        self.value_derivative_poly(i, j, amp, u, poly)
    }

    /// [`Modes::value_derivative`] for `dK(s)/dtheta = p(s) u u^T` with the
    /// polynomial `p(s) = poly[0] + poly[1] s + poly[2] s^2` (a defect's
    /// [`crate::chain::Site`] in a damping model that adds terms).
    ///
    /// # Errors
    /// As [`Modes::value_derivative`].
    pub fn value_derivative_poly(
        &self,
        i: usize,
        j: usize,
        amp: f64,
        u: &[(usize, f64)],
        poly: [f64; 3],
    ) -> Result<Option<DoublePoleSum>> {
        self.check_masses(i, j)?;
        if let Some(&(at, _)) = u.iter().find(|(at, _)| *at < 1 || *at > self.n) {
            return Err(Error::invalid("u", at, format!("masses in 1..={}", self.n)));
        }
        let Inner::Quad {
            poles,
            vecs,
            norms,
            clusters,
            ..
        } = &self.inner
        else {
            return Ok(None);
        };
        if !clusters.is_empty() {
            return Ok(None);
        }
        let (i0, j0) = (i - 1, j - 1);
        // every pole (conjugates included) with the residues of both factors
        let mut all: Vec<(Complex64, Complex64, Complex64)> = Vec::with_capacity(2 * poles.len());
        for ((p, v), nu) in poles.iter().zip(vecs).zip(norms) {
            let uv: Complex64 = u.iter().map(|&(at, c)| v[at - 1] * c).sum();
            let a = v[i0] * uv / nu;
            let b = uv * v[j0] / nu;
            all.push((*p, a, b));
            if p.im != 0.0 {
                all.push((p.conj(), a.conj(), b.conj()));
            }
        }
        let mut terms = Vec::with_capacity(poles.len());
        for (k, &(p, a, b)) in all.iter().enumerate() {
            if p.im < 0.0 {
                continue;
            }
            let (mut ha, mut hb) = (Complex64::new(0.0, 0.0), Complex64::new(0.0, 0.0));
            for (l, &(q, al, bl)) in all.iter().enumerate() {
                if l != k {
                    let inv = (p - q).inv();
                    ha += al * inv;
                    hb += bl * inv;
                }
            }
            let f = p * p * poly[2] + p * poly[1] + poly[0];
            let df = p * (2.0 * poly[2]) + poly[1];
            let ab = a * b;
            terms.push(DoubleTerm {
                p,
                a: -f * ab * amp,
                b: -(df * ab + f * (a * hb + b * ha)) * amp,
                twice: p.im != 0.0,
            });
        }
        Ok(Some(DoublePoleSum { terms }))
    }
}

/// One simple pole of a decomposition with its mode vector and norm:
/// `X_ij(s) = sum_k v_k[i] v_k[j] / (nu_k (s - p_k))` over every pole,
/// conjugates included ([`Modes::simple_poles`]).
struct SimplePole<'a> {
    p: Complex64,
    /// The vector, read conjugated with `conj` (a conjugate pole of the
    /// quadratic path borrows its partner's).
    v: std::borrow::Cow<'a, [Complex64]>,
    conj: bool,
    nu: Complex64,
}

impl SimplePole<'_> {
    /// Entry `x` (0-based) of the vector.
    fn at(&self, x: usize) -> Complex64 {
        if self.conj {
            self.v[x].conj()
        } else {
            self.v[x]
        }
    }
}

/// The poles of a proportional mode `s^2 + 2 a s + w` (`w` its squared
/// frequency) and their difference: `(p, p', p - p')` with `p = -a + i
/// sqrt(w - a^2)` and `p'` its conjugate when underdamped, `p, p' = -a +-
/// sqrt(a^2 - w)` when overdamped; `None` at or within `1e-8` of critical
/// damping.
fn prop_pole_pair(a: f64, w: f64) -> Option<(Complex64, Complex64, Complex64)> {
    let w2 = w - a * a;
    if w2.abs() <= 1e-8 * w.abs().max(a * a) {
        return None;
    }
    let r = w2.abs().sqrt();
    Some(if w2 > 0.0 {
        let p = Complex64::new(-a, r);
        (p, p.conj(), Complex64::new(0.0, 2.0 * r))
    } else {
        (
            Complex64::new(-a + r, 0.0),
            Complex64::new(-a - r, 0.0),
            Complex64::new(2.0 * r, 0.0),
        )
    })
}

/// The damping rate `a` of a proportional mode of squared frequency `w`
/// (`s^2 + 2 a s + w`): `(alpha + beta w) / 2`.
fn prop_rate(alpha: f64, beta: f64, w: f64) -> f64 {
    if beta == 0.0 {
        0.5 * alpha
    } else {
        0.5 * (alpha + beta * w.max(0.0))
    }
}

impl Modes {
    /// Every pole with its vector and norm, conjugates included; `None`
    /// where the decomposition has no simple-pole form: near-double pole
    /// pairs of the quadratic path; a proportional mode at (or within
    /// `1e-8` of) critical damping or of zero frequency; the `modal`
    /// damping model (whose damping matrix is not the chain's
    /// tridiagonal one, so no stiffness change of it is a sum of sites).
    ///
    /// A proportional mode `q_m` (mass-normalised) of `s^2 + 2 a s + w^2`
    /// gives the two poles `p, p' = -a +- sqrt(a^2 - w^2)` with the vector
    /// `M^{-1/2} q_m` and the norms `p - p'` and `p' - p` (the partial
    /// fractions of `1 / ((s - p)(s - p'))`).
    fn simple_poles(&self) -> Option<Vec<SimplePole<'_>>> {
        let n = self.n;
        let mut out = Vec::with_capacity(2 * n);
        match &self.inner {
            Inner::Quad {
                poles,
                vecs,
                norms,
                clusters,
                ..
            } => {
                if !clusters.is_empty() {
                    return None;
                }
                for ((p, v), nu) in poles.iter().zip(vecs).zip(norms) {
                    let v = std::borrow::Cow::Borrowed(v.as_slice());
                    out.push(SimplePole {
                        p: *p,
                        v: v.clone(),
                        conj: false,
                        nu: *nu,
                    });
                    if p.im != 0.0 {
                        out.push(SimplePole {
                            p: p.conj(),
                            v,
                            conj: true,
                            nu: nu.conj(),
                        });
                    }
                }
            }
            Inner::Prop {
                alpha,
                beta,
                zeta,
                omega2,
                q,
            } => {
                if !zeta.is_empty() {
                    return None;
                }
                for (kk, &w) in omega2.iter().enumerate() {
                    let (p, q2, nu) = prop_pole_pair(prop_rate(*alpha, *beta, w), w)?;
                    let v: std::borrow::Cow<'_, [Complex64]> = (0..n)
                        .map(|i0| {
                            let qi = self.prop_entry(q.as_ref(), kk, i0);
                            Complex64::new(qi / self.masses[i0].sqrt(), 0.0)
                        })
                        .collect();
                    out.push(SimplePole {
                        p: q2,
                        v: v.clone(),
                        conj: false,
                        nu: -nu,
                    });
                    out.push(SimplePole {
                        p,
                        v,
                        conj: false,
                        nu,
                    });
                }
            }
        }
        Some(out)
    }

    /// The derivative of the response of mass `i` to an impulse `amp delta(t)`
    /// on mass `j` with respect to a value `theta` whose dynamic stiffness
    /// changes as a weighted sum of sites,
    /// `dK(s)/dtheta = sum_r w_r p_r(s) u_r u_r^T` (`terms` as
    /// `(site, w_r)`: a uniform chain parameter, see
    /// [`crate::sensitivity::stiffness_terms`]), as an exact sum over the
    /// poles. With `X_ij(s) = sum_k alpha_k beta_l ...` in the simple-pole
    /// form (`alpha_k = v_k[i] / nu_k`, `beta_k = v_k[j] / nu_k`) and the
    /// couplings `F_kl(s) = sum_r w_r p_r(s) (u_r.v_k)(u_r.v_l)`:
    ///
    /// ```text
    /// dX_ij/dtheta = -amp sum_{k,l} alpha_k F_kl(s) beta_l / ((s - p_k)(s - p_l))
    ///              = sum_k A_k / (s - p_k)^2 + B_k / (s - p_k),
    /// A_k = -amp alpha_k beta_k F_kk(p_k),
    /// B_k = -amp (alpha_k beta_k F'_kk(p_k)
    ///             + sum_{l != k} (alpha_k beta_l + alpha_l beta_k) F_kl(p_k) / (p_k - p_l)),
    /// ```
    ///
    /// [`Modes::value_derivative_poly`] for one site, and for the
    /// proportional paths too. `O(R P^2)` for `R` sites and `P = 2n` poles.
    ///
    /// `Ok(None)` where the decomposition has no simple-pole form (see
    /// `simple_poles` in the source) or two poles coincide.
    ///
    /// # Errors
    /// `i` or `j` outside `1..=n` (fields `observe`, `excite`). A site's
    /// entries outside `1..=n` are walls ([`crate::chain::Probe::entries`]).
    pub fn sites_derivative(
        &self,
        i: usize,
        j: usize,
        amp: f64,
        terms: &[(Site, f64)],
    ) -> Result<Option<DoublePoleSum>> {
        let n = self.n;
        self.check_masses(i, j)?;
        let probes: Vec<Vec<(usize, f64)>> = terms
            .iter()
            .map(|(s, _)| s.probe.entries(n).collect())
            .collect();
        let Some(poles) = self.simple_poles() else {
            return Ok(None);
        };
        let (i0, j0) = (i - 1, j - 1);
        // (u_r . v_k) per pole, every site's in a row
        let uv: Vec<Vec<Complex64>> = poles
            .iter()
            .map(|pk| {
                probes
                    .iter()
                    .map(|u| u.iter().map(|&(at, c)| pk.at(at - 1) * c).sum())
                    .collect()
            })
            .collect();
        let alpha: Vec<Complex64> = poles.iter().map(|pk| pk.at(i0) / pk.nu).collect();
        let beta: Vec<Complex64> = poles.iter().map(|pk| pk.at(j0) / pk.nu).collect();
        let mut out = Vec::with_capacity(n);
        let mut g = vec![Complex64::new(0.0, 0.0); terms.len()];
        for (k, pk) in poles.iter().enumerate() {
            let p = pk.p;
            if p.im < 0.0 {
                continue;
            }
            // g_r = w_r p_r(p_k) (u_r.v_k); F_kk and F'_kk
            let (mut fkk, mut dfkk) = (Complex64::new(0.0, 0.0), Complex64::new(0.0, 0.0));
            for ((gr, (site, w)), u) in g.iter_mut().zip(terms).zip(&uv[k]) {
                let c = site.poly;
                let f = p * p * c[2] + p * c[1] + c[0];
                let df = p * (2.0 * c[2]) + c[1];
                *gr = f * *w * u;
                fkk += *gr * u;
                dfkk += df * *w * u * u;
            }
            let mut cross = Complex64::new(0.0, 0.0);
            for (l, pl) in poles.iter().enumerate() {
                if l == k {
                    continue;
                }
                let gap = p - pl.p;
                if gap == Complex64::new(0.0, 0.0) {
                    return Ok(None);
                }
                let fkl: Complex64 = g.iter().zip(&uv[l]).map(|(a, b)| a * b).sum();
                cross += (alpha[k] * beta[l] + alpha[l] * beta[k]) * fkl / gap;
            }
            let ab = alpha[k] * beta[k];
            out.push(DoubleTerm {
                p,
                a: -ab * fkk * amp,
                b: -(ab * dfkk + cross) * amp,
                twice: p.im != 0.0,
            });
        }
        Ok(Some(DoublePoleSum { terms: out }))
    }
}

/// What changes in a [`Modes::modal_derivative`]: the chain's masses and
/// springs by weighted sites (`(site, w_r)`, each of `p_r(s) = c_0 + c_1 s
/// + c_2 s^2` read as `c_0 + c_2 s^2`: a stiffness or a mass, no damper;
/// `c_1` is the model's tridiagonal stand-in's), or one ratio of the `modal`
/// damping model (index `index` of its `of` ratios: the modes whose rank
/// by frequency reads it, [`Damping::modal_ratio`]).
#[derive(Clone, Copy, Debug)]
pub enum ModalChange<'a> {
    /// `dK/dtheta = sum_r w_r c_0r u_r u_r^T`, `dM/dtheta = sum_r w_r c_2r u_r u_r^T`.
    Sites(&'a [(Site, f64)]),
    /// The ratio `zeta[index]` of a model of `of` ratios.
    Ratio {
        /// 0-based.
        index: usize,
        /// How many ratios the model has (the last one is every higher mode's).
        of: usize,
    },
}

impl Modes {
    /// The derivative of the response of mass `i` to an impulse `amp
    /// delta(t)` on mass `j` under the `modal` damping model (every
    /// undamped mode `phi_m` (`phi^T M phi = 1`) of `s^2 + 2 a_m s +
    /// w_m^2`, `a_m = zeta_m w_m`), as an exact sum over its poles: with
    /// `D_m(s) = s^2 + 2 a_m s + w_m^2`,
    ///
    /// ```text
    /// dX_ij = amp sum_m d(phi_mi phi_mj) / D_m(s) - phi_mi phi_mj (2 da_m s + d(w_m^2)) / D_m(s)^2,
    /// d(w_m^2) = phi_m^T (dK - w_m^2 dM) phi_m,          da_m = zeta_m dw_m + dzeta_m w_m,
    /// dphi_m  = sum_{l != m} phi_l phi_l^T (dK - w_m^2 dM) phi_m / (w_m^2 - w_l^2) - phi_m (phi_m^T dM phi_m) / 2,
    /// ```
    ///
    /// (the eigenvalue and eigenvector derivatives of `K phi = w^2 M phi`);
    /// each `D_m` is `(s - p)(s - p')`, so the second term has double poles
    /// (`A = N(p) / nu^2`, `B = N'(p) / nu^2 - 2 N(p) / nu^3` with `nu = p - p'`).
    ///
    /// `Ok(None)` for another damping model (see
    /// [`Modes::sites_derivative`]), grounded dampers beside the ratios, a
    /// damper's site, two modes of one frequency, a mode at zero
    /// frequency or within `1e-8` of critical damping.
    ///
    /// # Errors
    /// `i` or `j` outside `1..=n` (fields `observe`, `excite`).
    pub fn modal_derivative(
        &self,
        i: usize,
        j: usize,
        amp: f64,
        change: ModalChange<'_>,
    ) -> Result<Option<DoublePoleSum>> {
        let n = self.n;
        self.check_masses(i, j)?;
        let Inner::Prop {
            alpha,
            beta,
            zeta,
            omega2,
            q,
        } = &self.inner
        else {
            return Ok(None);
        };
        if zeta.is_empty() || *alpha != 0.0 || *beta != 0.0 || omega2.iter().any(|w| *w <= 0.0) {
            return Ok(None);
        }
        let (i0, j0) = (i - 1, j - 1);
        // mass-normalised shapes, mode by mode
        let phi: Vec<Vec<f64>> = (0..n)
            .map(|m| {
                (0..n)
                    .map(|x| self.prop_entry(q.as_ref(), m, x) / self.masses[x].sqrt())
                    .collect()
            })
            .collect();
        let Some(ModeChanges { dw2, dzeta, dphi }) = mode_changes(change, omega2, &phi, i0, j0)
        else {
            return Ok(None);
        };
        let mut out = Vec::with_capacity(2 * n);
        for m in 0..n {
            let w = omega2[m].sqrt();
            let a = zeta[m] * w;
            let Some((p, partner, nu)) = prop_pole_pair(a, omega2[m]) else {
                return Ok(None);
            };
            let da = zeta[m] * dw2[m] / (2.0 * w) + dzeta[m] * w;
            let pp = phi[m][i0] * phi[m][j0];
            let dpp = dphi[m].0 * phi[m][j0] + phi[m][i0] * dphi[m].1;
            // N(s) = -pp (2 da s + dw2), at p with nu = p - partner
            let term = |p: Complex64, nu: Complex64, twice: bool| {
                let np = -pp * (p * (2.0 * da) + dw2[m]);
                let dn = -pp * 2.0 * da;
                DoubleTerm {
                    p,
                    a: np / (nu * nu) * amp,
                    b: ((dn - 2.0 * np / nu) / (nu * nu) + dpp / nu) * amp,
                    twice,
                }
            };
            if p.im != 0.0 {
                // its conjugate term implied
                out.push(term(p, nu, true));
            } else {
                out.push(term(p, nu, false));
                out.push(term(partner, -nu, false));
            }
        }
        Ok(Some(DoublePoleSum { terms: out }))
    }
}

/// The change of each undamped mode in a [`Modes::modal_derivative`]:
/// `d(w_m^2)`, `d(zeta_m)` and `d(phi_m)` at the observed and excited
/// masses.
struct ModeChanges {
    dw2: Vec<f64>,
    dzeta: Vec<f64>,
    dphi: Vec<(f64, f64)>,
}

/// [`ModeChanges`] of `change` for the modes `phi` (mass-normalised, mode
/// by mode) of squared frequencies `omega2`, at masses `i0` and `j0`
/// (0-based); `None` for a damper's site or two modes of one frequency.
fn mode_changes(
    change: ModalChange<'_>,
    omega2: &[f64],
    phi: &[Vec<f64>],
    i0: usize,
    j0: usize,
) -> Option<ModeChanges> {
    let n = omega2.len();
    let mut out = ModeChanges {
        dw2: vec![0.0; n],
        dzeta: vec![0.0; n],
        dphi: vec![(0.0, 0.0); n],
    };
    let terms = match change {
        ModalChange::Ratio { index, of } => {
            let mut order: Vec<usize> = (0..n).collect();
            order.sort_by(|&a, &b| omega2[a].total_cmp(&omega2[b]));
            for (rank, &m) in order.iter().enumerate() {
                if rank.min(of.max(1) - 1) == index {
                    out.dzeta[m] = 1.0;
                }
            }
            return Some(out);
        }
        ModalChange::Sites(terms) => terms,
    };
    // a site's damping term under this model is its tridiagonal stand-in's
    // (the Laplace side's, [`Chain::site`]): here the modes carry the
    // damping, so only a damper is refused
    if terms.iter().any(|(s, _)| s.power == 1) {
        return None;
    }
    // u_r . phi_m
    let uphi: Vec<Vec<f64>> = terms
        .iter()
        .map(|(s, _)| {
            let u: Vec<(usize, f64)> = s.probe.entries(n).collect();
            phi.iter()
                .map(|f| u.iter().map(|&(at, c)| f[at - 1] * c).sum())
                .collect()
        })
        .collect();
    // phi_l^T (dK - w_m^2 dM) phi_m
    let coupling = |l: usize, m: usize| -> f64 {
        terms
            .iter()
            .zip(&uphi)
            .map(|((s, w), u)| w * (s.poly[0] - omega2[m] * s.poly[2]) * u[l] * u[m])
            .sum()
    };
    for m in 0..n {
        out.dw2[m] = coupling(m, m);
        let mass: f64 = terms
            .iter()
            .zip(&uphi)
            .map(|((s, w), u)| w * s.poly[2] * u[m] * u[m])
            .sum();
        let (mut di, mut dj) = (-0.5 * mass * phi[m][i0], -0.5 * mass * phi[m][j0]);
        for l in (0..n).filter(|&l| l != m) {
            let gap = omega2[m] - omega2[l];
            if gap == 0.0 {
                return None;
            }
            let c = coupling(l, m) / gap;
            di += c * phi[l][i0];
            dj += c * phi[l][j0];
        }
        out.dphi[m] = (di, dj);
    }
    Some(out)
}

/// One term `(a t + b) e^{p t}` of a [`DoublePoleSum`] (twice its real part
/// for a pole of the upper half plane, whose conjugate term is implied).
#[derive(Clone, Copy, Debug, PartialEq)]
struct DoubleTerm {
    p: Complex64,
    a: Complex64,
    b: Complex64,
    twice: bool,
}

/// A real function `sum_k (a_k t + b_k) e^{p_k t}` (transform
/// `sum_k a_k / (s - p_k)^2 + b_k / (s - p_k)`, conjugate poles implied): the
/// derivative of a modal response with respect to a chain value
/// ([`Modes::value_derivative`]).
#[derive(Clone, Debug, PartialEq)]
pub struct DoublePoleSum {
    terms: Vec<DoubleTerm>,
}

impl DoublePoleSum {
    /// Value at `t >= 0` (zero for `t < 0`).
    pub fn eval(&self, t: f64) -> f64 {
        if t < 0.0 {
            return 0.0;
        }
        self.terms
            .iter()
            .map(|d| {
                let v = (d.a * t + d.b) * (d.p * t).exp();
                if d.twice {
                    2.0 * v.re
                } else {
                    v.re
                }
            })
            .sum()
    }

    /// Values at many times: on a uniform grid by the recurrence of
    /// [`ModalResponse::eval_many`] (`(a t + b) e^{p t} = t u + v` with
    /// `u = a e^{p t}`, `v = b e^{p t}` both stepped by one complex
    /// multiplication per sample, four terms at a time so that the steps do
    /// not wait on each other), re-anchored at the exact values every
    /// [`DERIVATIVE_ANCHOR`] samples (a derivative needs less than a value:
    /// the recurrence's rounding stays below `1e-13` relative); otherwise
    /// term by term.
    pub fn eval_many(&self, ts: &[f64]) -> Vec<f64> {
        let Some(dt) = uniform_step(ts) else {
            return ts.iter().map(|&t| self.eval(t)).collect();
        };
        let zero = Complex64::new(0.0, 0.0);
        let mut out = vec![0.0; ts.len()];
        const L: usize = 4;
        for chunk in self.terms.chunks(L) {
            // padded with zero terms
            let mut p = [zero; L];
            let mut a = [zero; L];
            let mut b = [zero; L];
            for (l, d) in chunk.iter().enumerate() {
                let scale = if d.twice { 2.0 } else { 1.0 };
                p[l] = d.p;
                a[l] = d.a * scale;
                b[l] = d.b * scale;
            }
            let z: [Complex64; L] = std::array::from_fn(|l| (p[l] * dt).exp());
            let (mut u, mut v) = ([zero; L], [zero; L]);
            for (i, (o, &t)) in out.iter_mut().zip(ts).enumerate() {
                if t < 0.0 {
                    continue;
                }
                if i % DERIVATIVE_ANCHOR == 0 || t - dt < 0.0 {
                    for l in 0..L {
                        let w = (p[l] * t).exp();
                        u[l] = a[l] * w;
                        v[l] = b[l] * w;
                    }
                } else {
                    for l in 0..L {
                        u[l] *= z[l];
                        v[l] *= z[l];
                    }
                }
                let mut acc = 0.0;
                for l in 0..L {
                    acc += t * u[l].re + v[l].re;
                }
                *o += acc;
            }
        }
        out
    }

    /// Several sums at many times in one pass over the samples, when they
    /// share their poles (the columns of one Jacobian: each a chain
    /// parameter's derivative over the same modes): each pole's `e^{p t}`
    /// is stepped once for all of them (one complex multiplication per
    /// sample and pole, against two per sum in [`Self::eval_many`]) and
    /// re-anchored at its exact value every [`DERIVATIVE_ANCHOR`] samples,
    /// and each sum adds `Re((a t + b) e^{p t})`. From [`GEMM_COLUMNS`]
    /// sums on, that last step is one matrix product: the samples' `t
    /// e^{p t}` and `e^{p t}` (real and imaginary parts) times the sums'
    /// coefficients (the same values to rounding; the elements' columns
    /// of the linear bound on more defects at n = 37, 6,001 samples: 133
    /// million instructions in the loop, 20 in the product). Sums over
    /// other poles, a single sum and a grid that is not uniform are
    /// evaluated one by one.
    pub fn eval_many_columns(sums: &[&DoublePoleSum], ts: &[f64]) -> Vec<Vec<f64>> {
        let shared = sums.split_first().is_some_and(|(first, rest)| {
            rest.iter().all(|s| {
                s.terms.len() == first.terms.len()
                    && s.terms.iter().zip(&first.terms).all(|(a, b)| a.p == b.p)
            })
        });
        let Some(dt) = uniform_step(ts).filter(|_| shared && sums.len() > 1) else {
            return sums.iter().map(|s| s.eval_many(ts)).collect();
        };
        if sums.len() >= GEMM_COLUMNS {
            return Self::eval_columns_product(sums, ts, dt);
        }
        const L: usize = 4;
        let zero = Complex64::new(0.0, 0.0);
        let mut out = vec![vec![0.0; ts.len()]; sums.len()];
        for (j, chunk) in sums[0].terms.chunks(L).enumerate() {
            // padded with zero terms
            let mut p = [zero; L];
            for (l, d) in chunk.iter().enumerate() {
                p[l] = d.p;
            }
            let coef: Vec<[(Complex64, Complex64); L]> = sums
                .iter()
                .map(|s| {
                    std::array::from_fn(|l| {
                        match s.terms.get(j * L + l).filter(|_| l < chunk.len()) {
                            Some(d) => {
                                let scale = if d.twice { 2.0 } else { 1.0 };
                                (d.a * scale, d.b * scale)
                            }
                            None => (zero, zero),
                        }
                    })
                })
                .collect();
            step_poles(&p, ts, dt, |i, t, w| {
                for (o, c) in out.iter_mut().zip(&coef) {
                    let mut acc = 0.0;
                    for l in 0..L {
                        let (a, b) = c[l];
                        acc += (a.re * t + b.re) * w[l].re - (a.im * t + b.im) * w[l].im;
                    }
                    o[i] += acc;
                }
            });
        }
        out
    }

    /// [`Self::eval_many_columns`] of sums over the same poles on the
    /// uniform grid `ts` (step `dt`) as one matrix product: row `i` of the
    /// basis holds `t Re w`, `t Im w`, `Re w`, `Im w` for each pole's `w =
    /// e^{p t_i}` (stepped and re-anchored as there), and the
    /// coefficients `Re a`, `-Im a`, `Re b`, `-Im b` of each sum's term
    /// make its column: `Re((a t + b) w)`.
    fn eval_columns_product(sums: &[&DoublePoleSum], ts: &[f64], dt: f64) -> Vec<Vec<f64>> {
        let terms = &sums[0].terms;
        let mut basis = DMatrix::zeros(ts.len(), 4 * terms.len());
        for (j, d) in terms.iter().enumerate() {
            step_poles(&[d.p], ts, dt, |i, t, [w]| {
                basis[(i, 4 * j)] = t * w.re;
                basis[(i, 4 * j + 1)] = t * w.im;
                basis[(i, 4 * j + 2)] = w.re;
                basis[(i, 4 * j + 3)] = w.im;
            });
        }
        let coef = DMatrix::from_fn(4 * terms.len(), sums.len(), |row, c| {
            let d = &sums[c].terms[row / 4];
            let scale = if d.twice { 2.0 } else { 1.0 };
            scale
                * match row % 4 {
                    0 => d.a.re,
                    1 => -d.a.im,
                    2 => d.b.re,
                    _ => -d.b.im,
                }
        });
        let out = basis * coef;
        out.column_iter()
            .map(|c| c.iter().copied().collect())
            .collect()
    }

    /// The Laplace transform at `s`.
    pub fn laplace(&self, s: Complex64) -> Complex64 {
        self.terms
            .iter()
            .map(|d| {
                let f = |p: Complex64, a: Complex64, b: Complex64| {
                    let r = (s - p).inv();
                    a * r * r + b * r
                };
                let v = f(d.p, d.a, d.b);
                if d.twice {
                    v + f(d.p.conj(), d.a.conj(), d.b.conj())
                } else {
                    v
                }
            })
            .sum()
    }
}

/// The `2n` poles of the chain: by the Aberth iteration from the undamped
/// modes ([`super::qep_roots`], `O(n^2)`) when it is sure of them and they
/// hold no near-double pair, otherwise (and for a free-free chain's
/// rigid-body pole) by the Schur form ([`schur_poles`]).
fn poles(chain: &Chain, qep: &Qep) -> Result<Vec<Complex64>> {
    if !chain.is_free_free() {
        let tri = super::qep_roots::Tridiagonal {
            m: qep.m,
            k: qep.k,
            d: qep.d,
            g: qep.g,
            c: qep.c,
        };
        if let Some(ev) = super::qep_roots::aberth_poles(&tri) {
            if near_double_pairs(&ev).1.is_empty() {
                return Ok(ev);
            }
        }
    }
    schur_poles(chain, qep)
}

/// The `2n` poles of the chain: the eigenvalues of the symmetrised
/// first-order companion matrix, by a complex Schur form (the rigid-body
/// pole of a free-free chain snapped to exactly 0).
///
/// # Errors
/// The Schur iteration does not converge, or the poles are not `2n` in
/// conjugate pairs.
fn schur_poles(chain: &Chain, qep: &Qep) -> Result<Vec<Complex64>> {
    let (m, k, d, g, cd) = (qep.m, qep.k, qep.d, qep.g, qep.c);
    let n = m.len();
    let n2 = 2 * n;
    let mut l = DMatrix::zeros(n2, n2);
    for i in 0..n {
        l[(i, n + i)] = 1.0;
        l[(n + i, i)] = -(g[i] + k[i] + k[i + 1]) / m[i];
        l[(n + i, n + i)] = -(d[i] + cd[i] + cd[i + 1]) / m[i];
        if i + 1 < n {
            let root = (m[i] * m[i + 1]).sqrt();
            let c = k[i + 1] / root;
            l[(n + i, i + 1)] = c;
            l[(n + i + 1, i)] = c;
            l[(n + i, n + i + 1)] = cd[i + 1] / root;
            l[(n + i + 1, n + i)] = cd[i + 1] / root;
        }
    }
    let fail = |reason: String| Error::Numerical {
        method: "quadratic eigenproblem".into(),
        reason,
    };
    let schur = nalgebra::Schur::try_new(l, f64::EPSILON, 1000 * n2)
        .ok_or_else(|| fail("the Schur iteration did not converge".into()))?;
    let mut ev: Vec<Complex64> = schur.complex_eigenvalues().iter().copied().collect();
    if chain.is_free_free() {
        // the rigid-body pole is exactly 0 (K 1 = 0): snap the Schur value
        if let Some(i0) = (0..ev.len()).min_by(|&a, &b| ev[a].norm().total_cmp(&ev[b].norm())) {
            ev[i0] = Complex64::new(0.0, 0.0);
        }
    }
    let npos = ev.iter().filter(|z| z.im > 0.0).count();
    let nneg = ev.iter().filter(|z| z.im < 0.0).count();
    if npos != nneg || ev.len() != n2 {
        return Err(fail(format!(
            "{npos} poles above and {nneg} below the real axis (expected conjugate pairs)"
        )));
    }
    Ok(ev)
}

/// The near-double pole pairs (relative distance below [`CLUSTER`]): the
/// poles they use, and each pair's `(a, w2)` (centre `-a`, product `w2`).
fn near_double_pairs(ev: &[Complex64]) -> (Vec<bool>, Vec<(f64, f64)>) {
    let mut used = vec![false; ev.len()];
    let mut clusters = Vec::new();
    for (idx, p0) in ev.iter().enumerate() {
        if p0.im > 0.0 && 2.0 * p0.im <= CLUSTER * p0.norm() {
            used[idx] = true;
            clusters.push((-p0.re, p0.im * p0.im));
        }
    }
    let mut reals: Vec<(usize, f64)> = ev
        .iter()
        .enumerate()
        .filter(|(_, z)| z.im == 0.0)
        .map(|(i, z)| (i, z.re))
        .collect();
    reals.sort_by(|a, b| a.1.total_cmp(&b.1));
    let mut r = 0;
    while r + 1 < reals.len() {
        let ((i1, p1), (i2, p2)) = (reals[r], reals[r + 1]);
        if (p1 - p2).abs() <= CLUSTER * p1.abs().max(p2.abs()) {
            used[i1] = true;
            used[i2] = true;
            let h = 0.5 * (p1 - p2);
            clusters.push((-0.5 * (p1 + p2), -h * h));
            r += 2;
        } else {
            r += 1;
        }
    }
    (used, clusters)
}

/// The simple poles (upper half-plane and real, not `used` by a pair):
/// poles refined on the quadratic eigenproblem, their vectors, the vectors'
/// norms and the poles' condition numbers.
type SimpleModes = (
    Vec<Complex64>,
    Vec<Vec<Complex64>>,
    Vec<Complex64>,
    Vec<f64>,
);

/// [`SimpleModes`] of the poles `ev`.
fn simple_modes(chain: &Chain, qep: &Qep, ev: &[Complex64], used: &[bool]) -> SimpleModes {
    let (m, d) = (qep.m, qep.d);
    let n = m.len();
    let mut poles = Vec::new();
    let mut vecs = Vec::new();
    let mut norms = Vec::new();
    let mut conds = Vec::new();
    for (idx, &p0) in ev.iter().enumerate() {
        if p0.im < 0.0 || used[idx] {
            continue;
        }
        let sep = ev
            .iter()
            .enumerate()
            .filter(|(j, _)| *j != idx)
            .map(|(_, z)| (z - p0).norm())
            .fold(f64::INFINITY, f64::min);
        let real = p0.im == 0.0;
        if p0 == Complex64::new(0.0, 0.0) && chain.is_free_free() {
            // rigid-body mode: v = 1, residue amp / sum d
            let v = vec![Complex64::new(1.0, 0.0); n];
            let nu: Complex64 = d.iter().sum::<f64>().into();
            poles.push(p0);
            vecs.push(v);
            norms.push(nu);
            conds.push(0.0);
            continue;
        }
        let (mut p, mut v) = qep.refine(p0, real);
        if (p - p0).norm() > 0.5 * sep {
            // converged to a neighbour: keep the Schur value
            p = p0;
            v = qep.null_vector(p0);
        }
        let nu: Complex64 = (0..n)
            .map(|i| (p * (2.0 * m[i]) + d[i]) * v[i] * v[i])
            .sum::<Complex64>()
            + qep.spring_form(&v, qep.c);
        poles.push(p);
        vecs.push(v);
        norms.push(nu);
        conds.push(p.norm() / sep);
    }
    (poles, vecs, norms, conds)
}

/// The eigen-decomposition of the mass-symmetrised stiffness matrix
/// `M^{-1/2} K M^{-1/2}` (tridiagonal; grounds on the diagonal), for `what`.
///
/// # Errors
/// `n >` [`MAX_N_SYMMETRIC`] (field `n`); the iteration does not converge.
fn symmetric_eigen(
    masses: &[f64],
    springs: &[f64],
    grounds: &[f64],
    what: &str,
) -> Result<nalgebra::SymmetricEigen<f64, nalgebra::Dyn>> {
    let n = masses.len();
    if n > MAX_N_SYMMETRIC {
        return Err(Error::invalid(
            "n",
            n,
            format!("n <= {MAX_N_SYMMETRIC} for {what}"),
        ));
    }
    let kt = DMatrix::from_fn(n, n, |i, j| {
        if i == j {
            (grounds[i] + springs[i] + springs[i + 1]) / masses[i]
        } else if j == i + 1 || i == j + 1 {
            -springs[i.max(j)] / (masses[i] * masses[j]).sqrt()
        } else {
            0.0
        }
    });
    nalgebra::SymmetricEigen::try_new(kt, f64::EPSILON, 100 * n).ok_or_else(|| Error::Numerical {
        method: "symmetric eigen".into(),
        reason: "did not converge".into(),
    })
}

/// Relative distance below which two poles are treated as one near-double
/// pair. Generous on purpose: the pair's term is exact for any separation,
/// while separate residues lose about `eps / sep^2`, and the Schur form can
/// misplace the two poles of a near-double pair by `sqrt(eps)` or more
/// (seen: 1e-3 at the edge of critical damping).
const CLUSTER: f64 = 0.05;

/// Two points per near-double pair on a circle around its centre `-a`
/// (radius half the distance to the nearest other pole, at least twice the
/// pair's half-width), where the pair dominates: the points of
/// [`fit_clusters`].
fn cluster_points(clusters: &[(f64, f64)], others: &[Term]) -> Vec<Complex64> {
    let mut other_poles: Vec<Complex64> = Vec::new();
    for t in others {
        match *t {
            Term::Pair { p, .. } => {
                other_poles.push(p);
                other_poles.push(p.conj());
            }
            Term::Real { p, .. } => other_poles.push(p.into()),
            Term::Osc { .. } => {}
        }
    }
    let mut pts = Vec::with_capacity(2 * clusters.len());
    for (ci, &(a, w2)) in clusters.iter().enumerate() {
        let centre = Complex64::new(-a, 0.0);
        let half_width = w2.abs().sqrt();
        let dist = other_poles
            .iter()
            .map(|p| (p - centre).norm())
            .chain(
                clusters
                    .iter()
                    .enumerate()
                    .filter(|(j, _)| *j != ci)
                    .map(|(_, c)| (c.0 - a).abs()),
            )
            .fold(f64::INFINITY, f64::min);
        let rho = if dist.is_finite() {
            0.5 * dist
        } else {
            1.0 + a.abs()
        }
        .max(2.0 * half_width)
        .max(1e-6 * (1.0 + a.abs()));
        for angle in [0.5 * std::f64::consts::PI, 0.3 * std::f64::consts::PI] {
            pts.push(centre + Complex64::from_polar(rho, angle));
        }
    }
    pts
}

/// The second-order terms `(e (s + a) + c) / ((s + a)^2 + w2)` of the
/// near-double pole pairs, fitted (jointly, least squares) so that the modal
/// sum equals the exact `amp [K(s)^-1]_{ij}` (an O(n) tridiagonal solve) at
/// two points per pair on a circle around the pair's centre `-a` (radius half
/// the distance to the nearest other pole, at least twice the pair's
/// half-width), where the pair dominates. `a`, `w2` (the pair's sum and
/// product) are well conditioned even where the two poles are not.
fn fit_clusters(
    qep: &Qep,
    clusters: &[(f64, f64)],
    others: &[Term],
    i0: usize,
    j0: usize,
    amp: f64,
) -> Result<Vec<Term>> {
    let nc = clusters.len();
    let pts = cluster_points(clusters, others);
    let mut mat = DMatrix::zeros(2 * pts.len(), 2 * nc);
    let mut rhs = nalgebra::DVector::zeros(2 * pts.len());
    for (row, &s) in pts.iter().enumerate() {
        let mut e = vec![Complex64::new(0.0, 0.0); qep.n()];
        e[j0] = Complex64::new(1.0, 0.0);
        let x = qep.solve(s, &e)[i0] * amp;
        let r = x - others.iter().map(|t| t.laplace(s)).sum::<Complex64>();
        rhs[2 * row] = r.re;
        rhs[2 * row + 1] = r.im;
        for (c, &(a, w2)) in clusters.iter().enumerate() {
            let den = (s + a) * (s + a) + w2;
            let fe = (s + a) / den;
            let fc = Complex64::new(1.0, 0.0) / den;
            mat[(2 * row, 2 * c)] = fe.re;
            mat[(2 * row + 1, 2 * c)] = fe.im;
            mat[(2 * row, 2 * c + 1)] = fc.re;
            mat[(2 * row + 1, 2 * c + 1)] = fc.im;
        }
    }
    let numerical = |reason: String| Error::Numerical {
        method: "near-double poles".into(),
        reason,
    };
    let beyond = || {
        numerical(
            "the response at the poles' points is beyond f64 (a damping or stiffness \
             too large for the time step's scale?)"
                .into(),
        )
    };
    if !rhs.iter().all(|v| v.is_finite()) {
        return Err(beyond());
    }
    let sol = crate::linalg::svd_checked(mat, true, true)
        .ok_or_else(beyond)?
        .solve(&rhs, 1e-15)
        .map_err(|e| numerical(e.to_string()))?;
    Ok(clusters
        .iter()
        .enumerate()
        .map(|(c, &(a, w2))| Term::Osc {
            c: sol[2 * c + 1],
            e: sol[2 * c],
            a,
            w2,
        })
        .collect())
}

/// Normalised shape of mode `j` at mass `i` (both 1-based) of the uniform
/// chain with the given ends.
fn closed_shape(ends: (Boundary, Boundary), n: usize, j: usize, i: usize) -> f64 {
    let th = closed_theta(ends, n, j);
    let (nf, x) = (n as f64, i as f64);
    match ends {
        (Boundary::Fixed, Boundary::Fixed) => (2.0 / (nf + 1.0)).sqrt() * (x * th).sin(),
        (Boundary::Free, Boundary::Fixed) => 2.0 / (2.0 * nf + 1.0).sqrt() * ((x - 0.5) * th).cos(),
        (Boundary::Fixed, Boundary::Free) => 2.0 / (2.0 * nf + 1.0).sqrt() * (x * th).sin(),
        (Boundary::Free, Boundary::Free) => {
            if j == 1 {
                1.0 / nf.sqrt()
            } else {
                (2.0 / nf).sqrt() * ((x - 0.5) * th).cos()
            }
        }
    }
}

/// One natural mode of a chain: undamped natural frequency and damping ratio.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NaturalMode {
    /// Undamped natural frequency `omega_j` (rad per unit of time; rad/s for a
    /// chain in SI units, see [`crate::chain::Units`]). 0 for a rigid-body mode.
    pub omega: f64,
    /// `omega_j / (2 pi)` (Hz for a chain in SI units).
    pub frequency: f64,
    /// Modal damping ratio `zeta_j = phi_j^T D phi_j / (2 omega_j phi_j^T M phi_j)`;
    /// exact for proportional damping (`d_i/m_i = alpha`: `zeta_j = alpha/(2 omega_j)`),
    /// the classical diagonal approximation otherwise (the exact damped poles
    /// are those of [`ModalResponse::poles`]). `None` for a rigid-body mode.
    pub zeta: Option<f64>,
}

/// The undamped modes of a chain: `K phi_j = omega_j^2 M phi_j`, in
/// increasing frequency, each shape scaled to `phi_j^T M phi_j = 1`
/// ([`undamped_modes`]).
#[derive(Clone, Debug, PartialEq)]
pub struct UndampedModes {
    /// `omega_j` (rad per unit of time), increasing; 0 for a rigid-body mode.
    pub omega: Vec<f64>,
    /// Column `j` is `phi_j`, row `i` mass `i + 1`.
    pub shapes: DMatrix<f64>,
}

/// Natural frequencies and mass-normalised mode shapes of `chain` (the
/// dense symmetric eigenproblem of `M^{-1/2} K M^{-1/2}`, any masses, springs
/// and ends; damping is not part of it).
///
/// # Errors
/// `n >` [`MAX_N_SYMMETRIC`]; a failed eigen solver.
///
/// ```
/// use springmass::{Chain, time::modal::undamped_modes};
/// let m = undamped_modes(&Chain::new(4)?)?;
/// let w1 = 2.0 * (std::f64::consts::PI / 10.0).sin();   // 2 sin(pi / (2 (n+1)))
/// assert!((m.omega[0] - w1).abs() < 1e-14);
/// let phi = m.shapes.column(0);
/// assert!((phi.dot(&phi) - 1.0).abs() < 1e-14);         // unit masses
/// # Ok::<(), springmass::Error>(())
/// ```
pub fn undamped_modes(chain: &Chain) -> Result<UndampedModes> {
    let masses = chain.masses();
    let eig = symmetric_eigen(
        &masses,
        &chain.springs(),
        &chain.grounds(),
        "the mode shapes of a chain",
    )?;
    let n = masses.len();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
    let omega = order
        .iter()
        .map(|&c| eig.eigenvalues[c].max(0.0).sqrt())
        .collect();
    let shapes = DMatrix::from_fn(n, n, |i, j| {
        eig.eigenvectors[(i, order[j])] / masses[i].sqrt()
    });
    Ok(UndampedModes { omega, shapes })
}

/// Natural frequencies and damping ratios of `chain`, in increasing
/// frequency: the undamped eigenproblem `K phi = omega^2 M phi` (closed form
/// for a uniform chain with any ends, [`MAX_N_SYMMETRIC`] masses otherwise).
///
/// # Errors
/// A non-uniform chain with `n >` [`MAX_N_SYMMETRIC`]; a failed eigen solver.
///
/// ```
/// use springmass::{Chain, chain::Boundary, time::modal::natural_modes};
/// // cantilever-like chain, mass 1 at the free end: omega_1 = 2 sin(pi / (2 (2n+1)))
/// let c = Chain::new(5)?.with_boundaries(Boundary::Free, Boundary::Fixed)?;
/// let m = natural_modes(&c)?;
/// let w1 = 2.0 * (std::f64::consts::PI / 22.0).sin();
/// assert!((m[0].omega - w1).abs() < 1e-15 && m[0].zeta == Some(0.0));
/// # Ok::<(), springmass::Error>(())
/// ```
pub fn natural_modes(chain: &Chain) -> Result<Vec<NaturalMode>> {
    if chain.damping().is_modal() {
        return modal_natural_modes(chain);
    }
    let n = chain.n();
    let masses = chain.masses();
    let dampers = chain.dampers();
    let springs = chain.springs();
    let grounds = chain.grounds();
    let cdamp = chain.spring_dampers();
    let ends = (chain.left(), chain.right());
    let (lo, hi) = chain.spring_range();
    let (d_u, c_u) = chain.uniform_damping();
    let uniform = masses.iter().all(|&m| m == chain.mass())
        && grounds.iter().all(|&g| g == 0.0)
        && (lo..=hi).all(|j| springs[j] == chain.k() && cdamp[j] == c_u)
        && dampers.iter().all(|&d| d == d_u);
    // (omega^2, sum_i (d_i/m_i) q_i^2 + the spring dampers' form)
    let mut raw: Vec<(f64, f64)> = if uniform {
        let (k, m, alpha) = (chain.k(), chain.mass(), d_u / chain.mass());
        (1..=n)
            .map(|j| {
                let s = (0.5 * closed_theta(ends, n, j)).sin();
                let w2 = 4.0 * k / m * s * s;
                let damp = if c_u == 0.0 {
                    alpha
                } else {
                    alpha + c_u / k * w2
                };
                (w2, damp)
            })
            .collect()
    } else {
        let eig = symmetric_eigen(
            &masses,
            &springs,
            &grounds,
            "the natural modes of a non-uniform chain",
        )?;
        (0..n)
            .map(|c| {
                let q = eig.eigenvectors.column(c);
                let damp: f64 = (0..n).map(|i| dampers[i] / masses[i] * q[i] * q[i]).sum();
                // sum_j c_j (x_j - x_{j+1})^2 with x = M^{-1/2} q
                let x = |i: usize| {
                    if i == 0 || i > n {
                        0.0
                    } else {
                        q[i - 1] / masses[i - 1].sqrt()
                    }
                };
                let between: f64 = (0..=n)
                    .filter(|&j| cdamp[j] != 0.0)
                    .map(|j| cdamp[j] * (x(j) - x(j + 1)).powi(2))
                    .sum();
                (eig.eigenvalues[c], damp + between)
            })
            .collect()
    };
    raw.sort_by(|a, b| a.0.total_cmp(&b.0));
    let top = raw.last().map_or(0.0, |r| r.0.abs());
    Ok(raw
        .into_iter()
        .map(|(w2, damp)| {
            let rigid = w2 <= 64.0 * f64::EPSILON * top;
            let omega = if rigid { 0.0 } else { w2.sqrt() };
            NaturalMode {
                omega,
                frequency: omega / (2.0 * std::f64::consts::PI),
                zeta: (!rigid).then(|| damp / (2.0 * omega)),
            }
        })
        .collect())
}

/// [`natural_modes`] of a chain with modal damping: every mode's ratio is
/// its `zeta_j`, beside the grounded dampers' own.
fn modal_natural_modes(chain: &Chain) -> Result<Vec<NaturalMode>> {
    let grounded = chain.clone().with_damping(Damping::Grounded)?;
    Ok(natural_modes(&grounded)?
        .into_iter()
        .enumerate()
        .map(|(j, m)| NaturalMode {
            zeta: m.zeta.map(|z| z + chain.damping().modal_ratio(j)),
            ..m
        })
        .collect())
}

/// `(alpha, beta)` of [`Modes::proportional`]: of `C = alpha M + beta K`,
/// or for the modal model the grounded dampers' `alpha` (the modes' own
/// damping apart).
///
/// # Errors
/// Damping not proportional (field `chain`); grounded dampers beside the
/// modal model not proportional to the masses (field `d`).
fn proportional_coefficients(chain: &Chain) -> Result<(f64, f64)> {
    if chain.damping().is_modal() {
        let grounded = chain.clone().with_damping(Damping::Grounded)?;
        let alpha = proportional_alpha(&grounded).ok_or_else(|| {
            Error::invalid(
                "d",
                chain.d(),
                "0 (or dampers proportional to the masses) beside the modal damping model",
            )
        })?;
        return Ok((alpha, 0.0));
    }
    proportional_damping(chain).ok_or_else(|| {
        Error::invalid(
            "chain",
            "damping not proportional",
            "C = alpha M + beta K (use the quadratic path)",
        )
    })
}

/// `Some((alpha, beta))` when `C = alpha M + beta K`: `beta = c_j / k_j`
/// for every spring that exists and `d_i = alpha m_i + beta g_i` for every
/// mass (to 4 ulps); `beta = 0` without spring-parallel dampers (then as
/// [`proportional_alpha`]).
pub fn proportional_damping(chain: &Chain) -> Option<(f64, f64)> {
    let c = chain.coefficients();
    if !c.has_spring_dampers() {
        return proportional_alpha(chain).map(|a| (a, 0.0));
    }
    let (lo, hi) = chain.spring_range();
    let beta = c.c[lo] / c.k[lo];
    let close = |x: f64, y: f64| (x - y).abs() <= 8.0 * f64::EPSILON * x.abs().max(y.abs());
    if !(lo..=hi).all(|j| close(c.c[j], beta * c.k[j])) {
        return None;
    }
    let alpha = (c.d[0] - beta * c.g[0]) / c.m[0];
    (0..c.m.len())
        .all(|i| {
            let r = c.d[i] - beta * c.g[i] - alpha * c.m[i];
            r.abs() <= 8.0 * f64::EPSILON * c.d[i].abs().max(alpha * c.m[i])
        })
        .then_some((alpha, beta))
}

/// `Some(alpha)` when `d_i / m_i = alpha` for every mass (to 4 ulps).
pub fn proportional_alpha(chain: &Chain) -> Option<f64> {
    let m = chain.masses();
    let d = chain.dampers();
    let a0 = d[0] / m[0];
    d.iter()
        .zip(&m)
        .all(|(d, m)| (d / m - a0).abs() <= 4.0 * f64::EPSILON * a0)
        .then_some(a0)
}

/// `|re| + |im|`.
fn l1(z: Complex64) -> f64 {
    z.re.abs() + z.im.abs()
}

/// The tridiagonal quadratic eigenproblem `(M s^2 + D s + K) v = 0`.
struct Qep<'a> {
    m: &'a [f64],
    k: &'a [f64],
    d: &'a [f64],
    /// Ground stiffness per mass.
    g: &'a [f64],
    /// Dampers parallel to the springs (`n + 1`, beside `k`).
    c: &'a [f64],
}

impl Qep<'_> {
    fn n(&self) -> usize {
        self.m.len()
    }

    /// `v^T Lap(w) v = sum_j w_j (v_j - v_{j+1})^2` (`v_0 = v_{n+1} = 0`;
    /// unconjugated), for spring-parallel coefficients `w` (`n + 1`).
    fn spring_form(&self, v: &[Complex64], w: &[f64]) -> Complex64 {
        let n = self.n();
        let at = |i: usize| {
            if i == 0 || i > n {
                Complex64::new(0.0, 0.0)
            } else {
                v[i - 1]
            }
        };
        (0..=n)
            .filter(|&j| w[j] != 0.0)
            .map(|j| (at(j) - at(j + 1)) * (at(j) - at(j + 1)) * w[j])
            .sum()
    }

    /// Solve `K(p) w = b` (pivoted; zero pivots are nudged, as inverse
    /// iteration wants a large solution there).
    fn solve(&self, p: Complex64, b: &[Complex64]) -> Vec<Complex64> {
        let n = self.n();
        let cd = self.c;
        let mut dg: Vec<Complex64> = (0..n)
            .map(|i| {
                p * p * self.m[i]
                    + p * (self.d[i] + cd[i] + cd[i + 1])
                    + (self.g[i] + self.k[i] + self.k[i + 1])
            })
            .collect();
        let mut dl: Vec<Complex64> = (0..n.saturating_sub(1))
            .map(|i| -(p * cd[i + 1]) - self.k[i + 1])
            .collect();
        let mut du = dl.clone();
        let mut x = b.to_vec();
        let tiny = f64::EPSILON * (p.norm_sqr() * self.m.iter().cloned().fold(0.0, f64::max) + 4.0);
        let nz = |z: Complex64| {
            if z.re == 0.0 && z.im == 0.0 {
                Complex64::new(tiny, 0.0)
            } else {
                z
            }
        };
        if n == 1 {
            return vec![x[0] / nz(dg[0])];
        }
        for i in 0..n - 1 {
            // partial pivoting by the l1 modulus (no hypot per row)
            if l1(dg[i]) >= l1(dl[i]) {
                let piv = nz(dg[i]);
                dg[i] = piv;
                let fact = dl[i] / piv;
                dg[i + 1] -= fact * du[i];
                x[i + 1] = x[i + 1] - fact * x[i];
                dl[i] = Complex64::new(0.0, 0.0);
            } else {
                let fact = dg[i] / dl[i];
                dg[i] = dl[i];
                let temp = dg[i + 1];
                dg[i + 1] = du[i] - fact * temp;
                if i + 2 < n {
                    dl[i] = du[i + 1];
                    du[i + 1] = -fact * dl[i];
                } else {
                    dl[i] = Complex64::new(0.0, 0.0);
                }
                du[i] = temp;
                let tb = x[i];
                x[i] = x[i + 1];
                x[i + 1] = tb - fact * x[i + 1];
            }
        }
        x[n - 1] /= nz(dg[n - 1]);
        x[n - 2] = (x[n - 2] - du[n - 2] * x[n - 1]) / nz(dg[n - 2]);
        for i in (0..n.saturating_sub(2)).rev() {
            x[i] = (x[i] - du[i] * x[i + 1] - dl[i] * x[i + 2]) / nz(dg[i]);
        }
        x
    }

    /// `w2` of a near-double pair centred at `-a`: `det K(-a) / (det M
    /// prod_other (-a - p))`, with `det K` from the `LDL^T` pivots (log scale).
    fn cluster_w2(&self, a: f64, poles: &[Complex64], clusters: &[(f64, f64)]) -> Option<f64> {
        let s = -a;
        let n = self.n();
        let (mut log, mut sign) = (0.0_f64, 1.0_f64);
        let mut prev = 0.0_f64;
        for i in 0..n {
            let cd = self.c;
            let mut r = self.m[i] * s * s
                + (self.d[i] + cd[i] + cd[i + 1]) * s
                + self.g[i]
                + self.k[i]
                + self.k[i + 1];
            if i > 0 {
                let kap = self.k[i] + cd[i] * s;
                r -= kap * kap / prev;
            }
            if r == 0.0 {
                r = f64::EPSILON * (self.k[i] + self.k[i + 1]);
            }
            prev = r;
            let q = r / self.m[i];
            log += q.abs().ln();
            sign *= q.signum();
        }
        for p in poles {
            if p.im == 0.0 {
                let f = s - p.re;
                log -= f.abs().ln();
                sign *= f.signum();
            } else {
                log -= (Complex64::new(s, 0.0) - p).norm_sqr().ln();
            }
        }
        for &(ao, w2o) in clusters {
            let f = (s + ao) * (s + ao) + w2o;
            log -= f.abs().ln();
            sign *= f.signum();
        }
        // (s + a)^2 + w2 at s = -a is w2
        let w2 = sign * log.exp();
        w2.is_finite().then_some(w2)
    }

    /// `v` over its largest component's max-modulus `max(|re|, |im|)`
    /// (a scale: every use of a mode shape is invariant to it).
    fn normalise(v: &mut [Complex64]) {
        let s = v
            .iter()
            .map(|z| z.re.abs().max(z.im.abs()))
            .fold(0.0, f64::max);
        if s > 0.0 && s.is_finite() {
            for z in v.iter_mut() {
                *z /= s;
            }
        }
    }

    fn start(&self) -> Vec<Complex64> {
        // deterministic, generic (not orthogonal to symmetric or antisymmetric modes)
        (0..self.n())
            .map(|i| {
                Complex64::new(
                    1.0 + 0.5 * ((i as f64 * 0.618_033_988_75).fract() - 0.5),
                    0.0,
                )
            })
            .collect()
    }

    /// Two steps of inverse iteration at `p`.
    fn null_vector(&self, p: Complex64) -> Vec<Complex64> {
        let mut v = self.start();
        for _ in 0..2 {
            v = self.solve(p, &v);
            Qep::normalise(&mut v);
        }
        v
    }

    /// Rayleigh-quotient iteration from `p0`: `p` solves `v^T K(p) v = 0`.
    fn refine(&self, p0: Complex64, real: bool) -> (Complex64, Vec<Complex64>) {
        let n = self.n();
        let mut p = p0;
        let mut v = self.start();
        for _ in 0..12 {
            v = self.solve(p, &v);
            Qep::normalise(&mut v);
            if !v.iter().all(|z| z.re.is_finite() && z.im.is_finite()) {
                return (p0, self.null_vector(p0));
            }
            let mut a = Complex64::new(0.0, 0.0);
            let mut b = a;
            let mut c = a;
            for i in 0..n {
                let v2 = v[i] * v[i];
                a += v2 * self.m[i];
                b += v2 * self.d[i];
                c += v2 * (self.g[i] + self.k[i] + self.k[i + 1]);
                if i + 1 < n {
                    c -= v[i] * v[i + 1] * (2.0 * self.k[i + 1]);
                }
            }
            if self.c.iter().any(|&x| x != 0.0) {
                b += self.spring_form(&v, self.c);
            }
            let disc = (b * b - a * c * 4.0).sqrt();
            let qq = if (b.conj() * disc).re >= 0.0 {
                -(b + disc) * 0.5
            } else {
                -(b - disc) * 0.5
            };
            let r1 = qq / a;
            let r2 = if qq.norm() > 0.0 { c / qq } else { r1 };
            let mut pn = if (r1 - p).norm() <= (r2 - p).norm() {
                r1
            } else {
                r2
            };
            if real {
                pn = Complex64::new(pn.re, 0.0);
            }
            let done = (pn - p).norm() <= 4.0 * f64::EPSILON * pn.norm().max(1e-300);
            p = pn;
            if done {
                break;
            }
        }
        // final vector at the converged pole
        v = self.solve(p, &v);
        Qep::normalise(&mut v);
        if !v.iter().all(|z| z.re.is_finite() && z.im.is_finite()) {
            v = self.null_vector(p);
        }
        (p, v)
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn uniform_grid_recurrence_matches_term_by_term_evaluation() {
        use crate::chain::Boundary;
        let chains = [
            Chain::paper(20).unwrap(),
            crate::scenes::paper_with(8, "mass:3:5 damper:6:3").unwrap(),
            Chain::paper(6)
                .unwrap()
                .with_d(0.0)
                .unwrap()
                .with_boundaries(Boundary::Free, Boundary::Free)
                .unwrap(),
            Chain::paper(5).unwrap().with_d(4.0).unwrap(), // overdamped modes
        ];
        for c in &chains {
            for dt in [0.05, 0.2] {
                let ts: Vec<f64> = (0..6001).map(|i| i as f64 * dt).collect();
                for r in [
                    ModalResponse::impulse(c, 1).unwrap(),
                    ModalResponse::impulse(c, c.n()).unwrap().derivative(),
                ] {
                    let fast = r.eval_many(&ts);
                    for (i, &t) in ts.iter().enumerate() {
                        let slow = r.eval(t);
                        // relative to the terms' own sizes at t (they may cancel)
                        let envelope = |m: &Term| match *m {
                            Term::Pair { p, r } => 2.0 * r.norm() * (p.re * t).exp(),
                            Term::Real { p, r } => (r * (p * t).exp()).abs(),
                            Term::Osc { c, e, a, w2 } if w2 > 0.0 => {
                                (-a * t).exp() * (e.abs() + c.abs() / w2.sqrt())
                            }
                            Term::Osc { .. } => m.eval(t).abs(),
                        };
                        let amp: f64 = r.terms().iter().map(envelope).sum();
                        // both round the argument p t: error ~ eps (|p| t + ANCHOR)
                        let pmax = r.terms().iter().map(Term::pole_norm).fold(0.0, f64::max);
                        let tol = 4.0 * f64::EPSILON * (ANCHOR as f64 + pmax * t) * amp + 1e-300;
                        assert!(
                            (fast[i] - slow).abs() <= tol,
                            "t = {t}: {} vs {slow} (tol {tol})",
                            fast[i]
                        );
                    }
                }
            }
        }
        // a non-uniform grid takes the term-by-term path
        assert!(uniform_step(&[0.0, 0.1, 0.3]).is_none());
        assert_eq!(uniform_step(&[0.0, 0.5, 1.0]), Some(0.5));
    }

    use super::*;

    /// The chunked pass of `ModalResponse::eval_many` gives the values of
    /// the earlier one-term-at-a-time pass (each term stepped over every
    /// sample in turn), to the last bit.
    #[test]
    fn chunked_terms_match_one_term_at_a_time() {
        use crate::Defect;
        let chains = [
            Chain::paper(20)
                .unwrap()
                .with_defects([
                    Defect::Mass { at: 8, m: 5.0 },
                    Defect::Mass { at: 15, m: 2.0 },
                ])
                .unwrap(),
            Chain::paper(7).unwrap(),
            Chain::paper(5).unwrap().with_d(4.0).unwrap(), // overdamped modes
            Chain::paper(6)
                .unwrap()
                .with_defects([Defect::Damper { at: 2, d: 6.0 }])
                .unwrap(),
        ];
        for c in &chains {
            let ts: Vec<f64> = (0..3001).map(|i| -0.3 + i as f64 * 0.05).collect();
            let dt = uniform_step(&ts).unwrap();
            for r in [
                ModalResponse::impulse(c, 1).unwrap(),
                ModalResponse::impulse(c, c.n()).unwrap().derivative(),
            ] {
                let mut slow = vec![0.0; ts.len()];
                for term in r.terms() {
                    let one = term.exponential();
                    match one {
                        Some((p, rr, sc)) => step_terms(&mut slow, &ts, dt, &[p], &[rr], &[sc]),
                        None => {
                            for (o, &t) in slow.iter_mut().zip(&ts) {
                                if t >= 0.0 {
                                    *o += term.eval(t);
                                }
                            }
                        }
                    }
                }
                let fast = r.eval_many(&ts);
                for (a, b) in fast.iter().zip(&slow) {
                    let scale = slow.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                    assert!((a - b).abs() <= 1e-12 * scale, "{a} vs {b}");
                    assert_eq!(a.to_bits(), b.to_bits());
                }
            }
        }
    }

    #[test]
    fn value_derivative_is_the_derivative_of_the_response() {
        use crate::chain::Defect;
        use crate::forward::response;
        // mass, damper and spring values of a quadratic-path chain
        let base = |m: f64, d: f64, k: f64| {
            Chain::paper(8)
                .unwrap()
                .with_defects([
                    Defect::Mass { at: 3, m },
                    Defect::Damper { at: 5, d },
                    Defect::Spring { at: 6, k },
                ])
                .unwrap()
        };
        let (m, d, k) = (2.5, 0.3, 0.7);
        let modes = Modes::new(&base(m, d, k)).unwrap();
        assert_eq!(modes.path(), ModalPath::Quadratic);
        let h = 1e-6;
        type Case = (Vec<(usize, f64)>, u32, Chain, Chain);
        let cases: [Case; 3] = [
            (vec![(3, 1.0)], 2, base(m + h, d, k), base(m - h, d, k)),
            (vec![(5, 1.0)], 1, base(m, d + h, k), base(m, d - h, k)),
            (
                vec![(6, 1.0), (7, -1.0)],
                0,
                base(m, d, k + h),
                base(m, d, k - h),
            ),
        ];
        let ts: Vec<f64> = (0..2000).map(|i| i as f64 * 0.05).collect();
        for (u, power, up, dn) in cases {
            let ds = modes
                .value_derivative(1, 1, 1.0, &u, power)
                .unwrap()
                .unwrap();
            for s in [Complex64::new(0.3, 0.0), Complex64::new(0.05, 1.1)] {
                let fd = (response(&up, s, 1).unwrap() - response(&dn, s, 1).unwrap()) / (2.0 * h);
                let ex = ds.laplace(s);
                assert!(
                    (ex - fd).norm() <= 1e-7 * fd.norm(),
                    "{u:?} at {s}: {ex} vs {fd}"
                );
            }
            // the recurrence against term-by-term values
            let fast = ds.eval_many(&ts);
            let scale = fast.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            for (i, &t) in ts.iter().enumerate() {
                assert!((fast[i] - ds.eval(t)).abs() <= 1e-11 * scale, "t = {t}");
            }
        }
        // the wrong kind of decomposition, or bad input
        let uniform = Modes::new(&Chain::paper(8).unwrap()).unwrap();
        assert!(uniform
            .value_derivative(1, 1, 1.0, &[(3, 1.0)], 2)
            .unwrap()
            .is_none());
        assert!(modes.value_derivative(0, 1, 1.0, &[(3, 1.0)], 2).is_err());
        assert!(modes.value_derivative(1, 1, 1.0, &[(9, 1.0)], 2).is_err());
        assert!(modes.value_derivative(1, 1, 1.0, &[(3, 1.0)], 3).is_err());
    }
    use crate::chain::Defect;
    use crate::forward::response;

    fn check_laplace(chain: &Chain, i: usize, tol: f64) {
        let r = ModalResponse::impulse(chain, i).unwrap();
        for s in [
            Complex64::new(0.05, 0.0),
            Complex64::new(0.5, 0.0),
            Complex64::new(2.0, 0.0),
            Complex64::new(0.1, 0.7),
            Complex64::new(0.5, 2.0),
            Complex64::new(1.0, 5.0),
        ] {
            let want = response(chain, s, i).unwrap();
            let got = r.laplace(s);
            assert!(
                (got - want).norm() <= tol * want.norm().max(1e-3),
                "{:?} i={i} s={s}: {got} vs {want}",
                r.path()
            );
        }
        assert!(r.eval(0.0).abs() < 1e-13, "x(0) = {}", r.eval(0.0));
    }

    #[test]
    fn paths_are_chosen_per_chain() {
        let u = Chain::paper(10).unwrap();
        assert_eq!(Modes::new(&u).unwrap().path(), ModalPath::ClosedForm);
        let s = u
            .clone()
            .with_defect(Defect::Spring { at: 3, k: 2.0 })
            .unwrap();
        assert_eq!(Modes::new(&s).unwrap().path(), ModalPath::Proportional);
        let m = u.with_defect(Defect::Mass { at: 3, m: 2.0 }).unwrap();
        assert_eq!(Modes::new(&m).unwrap().path(), ModalPath::Quadratic);
        let m0 = Chain::new(10)
            .unwrap()
            .with_defect(Defect::Mass { at: 3, m: 2.0 })
            .unwrap();
        assert_eq!(Modes::new(&m0).unwrap().path(), ModalPath::Proportional);
    }

    #[test]
    fn laplace_matches_forward_model() {
        let chains = [
            Chain::paper(20).unwrap(),
            Chain::paper(20)
                .unwrap()
                .with_defect(Defect::Mass { at: 15, m: 1.01 })
                .unwrap(),
            Chain::paper(5)
                .unwrap()
                .with_defect(Defect::Mass { at: 3, m: 4.0 })
                .unwrap(),
            crate::scenes::paper_with(12, "spring:0:3 damper:7:2.5 mass:4:0.3").unwrap(),
            Chain::new(8)
                .unwrap()
                .with_defect(Defect::Spring { at: 4, k: 0.2 })
                .unwrap(),
        ];
        for c in &chains {
            for i in [1, c.n() / 2, c.n()] {
                check_laplace(c, i, 1e-11);
            }
        }
    }

    #[test]
    fn a_grid_shifted_to_its_blow_is_still_uniform_and_eval_after_matches_eval() {
        // a pre-trigger record's axis, shifted to the blow: samples near
        // zero carry the rounding of the original times
        let ts: Vec<f64> = (0..1000).map(|i| -10.0 + 0.2 * i as f64).collect();
        let blow = 10.13;
        let shifted: Vec<f64> = ts.iter().map(|t| t - blow).collect();
        assert_eq!(
            uniform_step(&shifted).map(|d| (d - 0.2).abs() < 1e-12),
            Some(true)
        );
        assert!(uniform_step(&[0.0, 0.2, 0.41, 0.6]).is_none());
        let c = crate::scenes::paper_with(20, "mass:8:5 mass:15:2").unwrap();
        let x1 = ModalResponse::impulse(&c, 1).unwrap();
        let got = x1.eval_after(&ts, blow);
        let peak = got.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        for (&t, g) in ts.iter().zip(&got) {
            let want = if t > blow { x1.eval(t - blow) } else { 0.0 };
            assert!((g - want).abs() <= 1e-12 * peak, "t = {t}: {g} vs {want}");
        }
    }

    #[test]
    fn quadratic_and_symmetric_paths_agree() {
        let c = Chain::new(9)
            .unwrap()
            .with_d(0.3)
            .unwrap()
            .with_defect(Defect::Spring { at: 5, k: 2.0 })
            .unwrap();
        let a = Modes::proportional(&c)
            .unwrap()
            .response(1, 1, 1.0)
            .unwrap();
        let b = Modes::quadratic(&c).unwrap().response(1, 1, 1.0).unwrap();
        for t in [0.5, 3.0, 17.0, 90.0] {
            assert!((a.eval(t) - b.eval(t)).abs() < 1e-13, "t={t}");
        }
    }

    #[test]
    fn critically_and_over_damped_modes() {
        // uniform n = 1, m = k = 1: s^2 + d s + 2; critical at d = 2 sqrt 2
        let dc = 2.0 * 2f64.sqrt();
        for (d, exact) in [
            (
                dc,
                Box::new(move |t: f64| t * (-dc * t / 2.0).exp()) as Box<dyn Fn(f64) -> f64>,
            ),
            (
                4.0,
                Box::new(|t: f64| {
                    let b = (4.0f64 - 2.0).sqrt();
                    (-2.0 * t).exp() * (b * t).sinh() / b
                }),
            ),
            (
                0.0,
                Box::new(|t: f64| (2f64.sqrt() * t).sin() / 2f64.sqrt()),
            ),
        ] {
            let c = Chain::new(1).unwrap().with_d(d).unwrap();
            let r = ModalResponse::impulse(&c, 1).unwrap();
            for t in [0.0, 0.01, 1.0, 5.0, 40.0, 400.0] {
                let e = exact(t);
                assert!((r.eval(t) - e).abs() <= 1e-15 * (10.0 + t), "d={d} t={t}");
            }
        }
        // a critically damped mode inside a longer uniform chain: exact double pole
        let n = 6;
        let w1 = 4.0
            * (std::f64::consts::PI / (2.0 * (n as f64 + 1.0)))
                .sin()
                .powi(2);
        let c = Chain::new(n).unwrap().with_d(2.0 * w1.sqrt()).unwrap();
        let r = ModalResponse::impulse(&c, 1).unwrap();
        assert!(r.poles().iter().any(|p| p.order == 2));
        check_laplace(&c, 1, 1e-12);
        check_laplace(&c, n, 1e-12);
    }

    #[test]
    fn bad_indices_are_errors() {
        let m = Modes::new(&Chain::paper(4).unwrap()).unwrap();
        assert!(m.response(5, 1, 1.0).is_err());
        assert!(m.response(1, 0, 1.0).is_err());
    }
}

#[cfg(test)]
mod scan_near_critical {
    use super::*;
    use crate::chain::Defect;
    use crate::time::simulate::{simulate, Method, SimOptions};

    /// Non-proportional chains swept through critical damping of their modes:
    /// the residue sum keeps matching the matrix-exponential simulation
    /// within its own reported rounding bound.
    #[test]
    fn sweep_through_critical_damping() {
        let mut worst: f64 = 0.0;
        for n in [2usize, 3] {
            for step in 0..300 {
                let d = 0.2 + step as f64 * 0.01;
                let chain = Chain::new(n)
                    .unwrap()
                    .with_d(d)
                    .unwrap()
                    .with_defect(Defect::Mass { at: n, m: 2.0 })
                    .unwrap();
                let r = ModalResponse::impulse(&chain, 1).unwrap();
                let o = SimOptions::new(30.0, 0.5).with_method(Method::Expm);
                let tr = simulate(&chain, &o).unwrap();
                let e =
                    tr.t.iter()
                        .zip(tr.x(1).unwrap())
                        .map(|(&t, x)| (r.eval(t) - x).abs())
                        .fold(0.0, f64::max);
                worst = worst.max(e / (1e-14 + r.error_bound()));
                assert!(
                    e <= 1e-13 + 10.0 * r.error_bound(),
                    "n={n} d={d}: {e:e}, bound {:e}",
                    r.error_bound()
                );
            }
        }
        println!("worst error / (1e-14 + bound) = {worst:.2}");
    }

    fn chain2(d: f64) -> Chain {
        Chain::new(2)
            .unwrap()
            .with_d(d)
            .unwrap()
            .with_defect(Defect::Mass { at: 2, m: 2.0 })
            .unwrap()
    }

    /// Real-pole terms (0 when the pair is one term or complex).
    fn real_count(d: f64) -> usize {
        let r = ModalResponse::impulse(&chain2(d), 1).unwrap();
        r.terms()
            .iter()
            .filter(|t| matches!(t, Term::Real { .. }))
            .count()
    }

    /// Is the near-double pair (one term) overdamped (`w2 < 0`)?
    fn pair_overdamped(d: f64) -> bool {
        let r = ModalResponse::impulse(&chain2(d), 1).unwrap();
        r.terms()
            .iter()
            .any(|t| matches!(t, Term::Osc { w2, e, .. } if *e != 0.0 && *w2 < 0.0))
    }

    fn bisect(mut lo: f64, mut hi: f64, left: impl Fn(f64) -> bool) -> (f64, f64) {
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if left(mid) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        (lo, hi)
    }

    /// At the physical edge of critical damping (the pair's `w2` changes
    /// sign) and at the edge where the pair stops being one term, no pole is
    /// lost and the residue sum matches the matrix-exponential simulation.
    #[test]
    fn at_the_merging_edge_no_pole_is_lost() {
        let mut d = 0.5;
        while !pair_overdamped(d) && real_count(d) == 0 {
            d += 0.01;
        }
        let (plo, phi) = bisect(d - 0.01, d, |x| !pair_overdamped(x) && real_count(x) == 0);
        let mut d2 = d;
        while real_count(d2) == 0 {
            d2 += 0.01;
        }
        let (clo, chi) = bisect(d2 - 0.01, d2, |x| real_count(x) == 0);
        let mut ds = vec![];
        for (lo, hi) in [(plo, phi), (clo, chi)] {
            ds.extend([
                lo,
                hi,
                hi * (1.0 + 1e-12),
                lo * (1.0 - 1e-12),
                hi * (1.0 + 1e-8),
            ]);
        }
        for d in ds {
            let chain = chain2(d);
            let r = ModalResponse::impulse(&chain, 1).unwrap();
            let npoles: usize = r.poles().iter().filter(|p| p.order == 1).count();
            assert_eq!(npoles, 4, "d = {d}: {:?}", r.terms());
            let tr = simulate(
                &chain,
                &SimOptions::new(30.0, 0.5).with_method(Method::Expm),
            )
            .unwrap();
            let e =
                tr.t.iter()
                    .zip(tr.x(1).unwrap())
                    .map(|(&t, x)| (r.eval(t) - x).abs())
                    .fold(0.0, f64::max);
            println!(
                "d = {d:.17}: real-pole terms {}, |modal - expm| {e:.2e}, bound {:.2e}",
                real_count(d),
                r.error_bound()
            );
            assert!(
                e <= 1e-11 && e <= 1e-14 + 10.0 * r.error_bound(),
                "d = {d}: {e:e} {:?}",
                r.terms()
            );
        }
    }
}

#[cfg(test)]
mod damping_tests {
    use super::*;
    use crate::chain::{dense_ref, Damping};

    fn check(chain: &Chain) {
        let (dt, samples) = (0.25, 400);
        let ts: Vec<f64> = (0..samples).map(|i| i as f64 * dt).collect();
        for o in [1, chain.n()] {
            let want = dense_ref::impulse(chain, o, dt, samples);
            let got = ModalResponse::impulse(chain, o).unwrap().eval_many(&ts);
            let scale = want.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            for (i, (g, w)) in got.iter().zip(&want).enumerate() {
                assert!(
                    (g - w).abs() <= 1e-10 * scale,
                    "{} o={o} t={}: {g} vs {w}",
                    chain.damping(),
                    ts[i]
                );
            }
        }
    }

    #[test]
    fn every_damping_model_matches_the_matrix_exponential() {
        for chain in dense_ref::model_chains() {
            check(&chain);
        }
        // Rayleigh without damper defects is proportional: the symmetric path
        let r = crate::scenes::paper_with(9, "mass:3:2 spring:6:0.5 ground:2:0.3")
            .unwrap()
            .with_d(0.0)
            .unwrap()
            .with_damping(Damping::Rayleigh { a: 0.02, b: 0.04 })
            .unwrap();
        assert_eq!(Modes::new(&r).unwrap().path(), ModalPath::Proportional);
        check(&r);
        let u = Chain::paper(7)
            .unwrap()
            .with_d(0.0)
            .unwrap()
            .with_damping(Damping::Between { c: 0.1 })
            .unwrap();
        assert_eq!(Modes::new(&u).unwrap().path(), ModalPath::ClosedForm);
        check(&u);
        // a spring defect under between-storey damping is not proportional
        let q = u
            .with_defect(crate::Defect::Spring { at: 3, k: 2.0 })
            .unwrap();
        assert_eq!(Modes::new(&q).unwrap().path(), ModalPath::Quadratic);
        check(&q);
    }

    #[test]
    fn modal_damping_matches_the_matrix_exponential_and_the_dense_solve() {
        for chain in dense_ref::modal_chains() {
            check(&chain);
            // the Laplace transform: the exact modal sum, not the stand-in
            for s in [
                num_complex::Complex64::new(0.05, 0.0),
                num_complex::Complex64::new(0.3, 1.2),
                num_complex::Complex64::new(2.0, -0.7),
            ] {
                for o in [1, 4] {
                    let want = dense_ref::solve(&chain, s, o);
                    let got = crate::forward::response(&chain, s, o).unwrap();
                    assert!((got - want).norm() <= 1e-12 * want.norm(), "{s} {o}");
                    let h = crate::forward::transfer_function(
                        &chain,
                        s,
                        o,
                        crate::forward::Observable::Velocity,
                    )
                    .unwrap();
                    let v = s * want / chain.gamma();
                    assert!((h - v).norm() <= 1e-12 * v.norm(), "{s} {o}");
                }
            }
            // every mode's ratio is its zeta_j (plus d's alpha / (2 omega))
            let Damping::Modal { zeta } = chain.damping() else {
                unreachable!()
            };
            for (j, m) in natural_modes(&chain).unwrap().iter().enumerate() {
                let extra = chain.d() / (2.0 * m.omega);
                let want = zeta[j.min(zeta.len() - 1)];
                assert!((m.zeta.unwrap() - want - extra).abs() < 1e-12, "{m:?}");
            }
        }
        // grounded dampers not proportional to the masses: refused, typed
        let bad = crate::scenes::paper_with(6, "mass:2:3")
            .unwrap()
            .with_damping(Damping::modal(0.02))
            .unwrap();
        match Modes::new(&bad) {
            Err(Error::InvalidParameter { field, .. }) => assert_eq!(field, "d"),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn value_derivative_poly_matches_a_difference() {
        for chain in dense_ref::model_chains().into_iter().skip(1).take(2) {
            let modes = Modes::new(&chain).unwrap();
            let n = chain.n();
            for (i, d) in chain.defects().iter().enumerate() {
                let site = chain.site(d);
                let u: Vec<(usize, f64)> = site.probe.entries(n).collect();
                let Some(der) = modes
                    .value_derivative_poly(1, 1, 1.0, &u, site.poly)
                    .unwrap()
                else {
                    continue;
                };
                let p = crate::sensitivity::Param::Defect(i);
                let v = d.value();
                let h = 1e-6 * v.max(0.1);
                let x = |v: f64| {
                    ModalResponse::impulse(&p.set(&chain, v).unwrap(), 1)
                        .unwrap()
                        .eval(6.0)
                };
                let fd = (x(v + h) - x(v - h)) / (2.0 * h);
                assert!((der.eval(6.0) - fd).abs() < 1e-6, "{} {d}", chain.damping());
            }
        }
    }

    #[test]
    fn natural_modes_damping_ratios_of_rayleigh() {
        let (a, b) = (0.02, 0.04);
        let r = Chain::paper(6)
            .unwrap()
            .with_d(0.0)
            .unwrap()
            .with_damping(Damping::Rayleigh { a, b })
            .unwrap();
        for m in natural_modes(&r).unwrap() {
            let want = a / (2.0 * m.omega) + b * m.omega / 2.0;
            assert!((m.zeta.unwrap() - want).abs() < 1e-12);
        }
        let s = r
            .with_defect(crate::Defect::Mass { at: 2, m: 3.0 })
            .unwrap();
        for m in natural_modes(&s).unwrap() {
            let want = a / (2.0 * m.omega) + b * m.omega / 2.0;
            assert!((m.zeta.unwrap() - want).abs() < 1e-12);
        }
    }

    /// One site's sum is [`Modes::value_derivative_poly`] on the quadratic
    /// path (every kind, a Rayleigh site's polynomial, observed and excited
    /// masses apart); masses outside the chain are typed errors.
    #[test]
    fn sites_derivative_of_one_site_is_the_value_derivative() {
        let chains = [
            crate::scenes::mixed(7).unwrap(),
            crate::scenes::paper_with(6, "mass:2:1e3 spring:4:0.3")
                .unwrap()
                .with_damping(Damping::Rayleigh { a: 0.02, b: 0.01 })
                .unwrap(),
        ];
        let t: Vec<f64> = (0..400).map(|i| 0.1 * i as f64).collect();
        for c in &chains {
            let m = Modes::quadratic(c).unwrap();
            for d in c.defects() {
                let site = c.site(d);
                let u: Vec<(usize, f64)> = site.probe.entries(c.n()).collect();
                for (i, j) in [(1, 1), (3, 2)] {
                    let one = m
                        .value_derivative_poly(i, j, 1.3, &u, site.poly)
                        .unwrap()
                        .unwrap();
                    let sum = m
                        .sites_derivative(i, j, 1.3, &[(site, 1.0)])
                        .unwrap()
                        .unwrap();
                    let (a, b) = (one.eval_many(&t), sum.eval_many(&t));
                    let peak = a.iter().fold(0.0f64, |p, v| p.max(v.abs()));
                    let err = a
                        .iter()
                        .zip(&b)
                        .fold(0.0f64, |e, (x, y)| e.max((x - y).abs()));
                    assert!(
                        err <= 1e-12 * peak,
                        "{d:?} ({i}, {j}): {err:.2e} of {peak:.2e}"
                    );
                }
            }
            let site = c.site(&c.defects()[0]);
            assert!(m.sites_derivative(0, 1, 1.0, &[(site, 1.0)]).is_err());
            assert!(m
                .sites_derivative(1, c.n() + 1, 1.0, &[(site, 1.0)])
                .is_err());
        }
    }

    /// The columns of a Jacobian evaluated together (their poles stepped
    /// once for all) equal each column alone to 1e-12 of its peak: long
    /// records (many re-anchorings), light and heavy damping (real poles),
    /// a grid that is not uniform, and a single column.
    #[test]
    fn columns_evaluated_together_match_each_alone() {
        let chains = [
            crate::scenes::mixed(7).unwrap(),
            crate::scenes::paper_with(20, "mass:3:5 mass:9:0.2 spring:15:2").unwrap(),
            crate::scenes::paper_with(6, "mass:2:3 mass:5:0.5")
                .unwrap()
                .with_d(1.2)
                .unwrap(),
        ];
        let long: Vec<f64> = (0..6001).map(|i| 0.05 * i as f64).collect();
        let uneven: Vec<f64> = (0..300).map(|i| 0.01 * (i * i) as f64 / 30.0).collect();
        for c in &chains {
            let m = Modes::quadratic(c).unwrap();
            // each defect's value, and the chain's uniform d (its sites)
            let mut sums: Vec<DoublePoleSum> = c
                .defects()
                .iter()
                .map(|d| m.sites_derivative(1, 1, 1.0, &[(c.site(d), 1.0)]).unwrap())
                .collect::<Option<_>>()
                .unwrap();
            let terms = crate::sensitivity::stiffness_terms(c, &crate::sensitivity::Param::D)
                .unwrap()
                .unwrap();
            sums.push(m.sites_derivative(1, 1, 1.0, &terms).unwrap().unwrap());
            let refs: Vec<&DoublePoleSum> = sums.iter().collect();
            // a group of GEMM_COLUMNS or more sums: the matrix product
            let many: Vec<&DoublePoleSum> = refs
                .iter()
                .cycle()
                .take(GEMM_COLUMNS + 2)
                .copied()
                .collect();
            for t in [&long, &uneven] {
                for group in [&refs[..], &refs[..1], &many[..]] {
                    let together = DoublePoleSum::eval_many_columns(group, t);
                    for (s, col) in group.iter().zip(&together) {
                        let alone = s.eval_many(t);
                        let peak = alone.iter().fold(0.0f64, |p, v| p.max(v.abs()));
                        let err = alone
                            .iter()
                            .zip(col)
                            .fold(0.0f64, |e, (x, y)| e.max((x - y).abs()));
                        assert!(peak > 0.0 && err <= 1e-12 * peak, "{err:.2e} of {peak:.2e}");
                    }
                }
            }
        }
    }
}
