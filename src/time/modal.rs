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
//!   Nearly double poles (near-critical modes of a non-proportional chain)
//!   give large residues of opposite signs: [`ModalResponse::error_bound`]
//!   reports the resulting rounding bound.
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

use crate::chain::Chain;
use crate::error::{Error, Result};
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
    /// `c e^{-a t} sin(b t)/b` with `b^2 = w2` (any sign; `w2 = 0` is
    /// `c t e^{-a t}`); transform `c / (s^2 + 2 a s + a^2 + w2)`.
    Osc {
        /// Coefficient.
        c: f64,
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
    /// Value at `t >= 0`.
    pub fn eval(&self, t: f64) -> f64 {
        match *self {
            Term::Osc { c, a, w2 } => {
                if w2 < 0.0 && w2 * t * t < -1.0 {
                    // overdamped, large t: avoid overflow of sinh * exp
                    let b = (-w2).sqrt();
                    c * (((b - a) * t).exp() - (-(a + b) * t).exp()) / (2.0 * b)
                } else {
                    c * (-a * t).exp() * sinc_t(w2, t)
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
            Term::Osc { c, a, w2 } => c / (s * s + s * (2.0 * a) + (a * a + w2)),
            Term::Pair { p, r } => r / (s - p) + r.conj() / (s - p.conj()),
            Term::Real { p, r } => r / (s - p),
        }
    }
    /// A bound on `|term(t)|` over `t >= 0` (for rounding estimates).
    fn amplitude(&self) -> f64 {
        match *self {
            Term::Osc { c, a, w2 } => {
                let env = if w2 > 0.0 {
                    1.0 / w2.sqrt()
                } else if w2 == 0.0 {
                    1.0 / (a * std::f64::consts::E)
                } else {
                    1.0 / (2.0 * (-w2).sqrt())
                };
                c.abs() * env
            }
            Term::Pair { r, .. } => 2.0 * r.norm(),
            Term::Real { r, .. } => r.abs(),
        }
    }
}

/// `x(t)` as an exact finite sum of damped modes (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct ModalResponse {
    terms: Vec<Term>,
    path: ModalPath,
}

impl ModalResponse {
    /// `x_observe(t)` of `chain` for its impulse `gamma` on mass 1.
    ///
    /// # Errors
    /// `observe` out of range; see [`Modes::new`].
    pub fn impulse(chain: &Chain, observe: usize) -> Result<ModalResponse> {
        Modes::new(chain)?.response(observe, 1, chain.gamma())
    }
    /// Build from terms (for example to combine responses).
    pub fn from_terms(terms: Vec<Term>, path: ModalPath) -> ModalResponse {
        ModalResponse { terms, path }
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
                Term::Osc { c, a, w2 } => {
                    if w2 > 0.0 {
                        let b = w2.sqrt();
                        let r = Complex64::new(0.0, -c / (2.0 * b));
                        out.push(pr(Complex64::new(-a, b), r, 1));
                        out.push(pr(Complex64::new(-a, -b), r.conj(), 1));
                    } else if w2 < 0.0 {
                        let b = (-w2).sqrt();
                        out.push(pr(Complex64::new(-a + b, 0.0), (c / (2.0 * b)).into(), 1));
                        out.push(pr(Complex64::new(-a - b, 0.0), (-c / (2.0 * b)).into(), 1));
                    } else {
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
    /// `x(t)` at many times.
    pub fn eval_many(&self, ts: &[f64]) -> Vec<f64> {
        ts.iter().map(|&t| self.eval(t)).collect()
    }
    /// The Laplace transform `X(s) = sum_k term_k(s)` (for checks against
    /// [`crate::forward::response`]).
    pub fn laplace(&self, s: Complex64) -> Complex64 {
        self.terms.iter().map(|m| m.laplace(s)).sum()
    }
    /// A rounding bound for [`ModalResponse::eval`]: `8 eps sum_k max_t |term_k(t)|`
    /// (large when nearly double poles carry large cancelling residues).
    pub fn error_bound(&self) -> f64 {
        8.0 * f64::EPSILON * self.terms.iter().map(Term::amplitude).sum::<f64>()
    }
}

#[derive(Clone, Debug)]
enum Inner {
    /// alpha = d_i / m_i; q: None for the closed form, else column k = mode k
    Prop {
        alpha: f64,
        omega2: Vec<f64>,
        q: Option<DMatrix<f64>>,
    },
    Quad {
        poles: Vec<Complex64>,
        vecs: Vec<Vec<Complex64>>,
        norms: Vec<Complex64>,
    },
}

/// The modal decomposition of a chain, shared by the responses of all
/// `(observed, excited)` pairs.
#[derive(Clone, Debug)]
pub struct Modes {
    n: usize,
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
        if proportional_alpha(chain).is_some() {
            Modes::proportional(chain)
        } else {
            Modes::quadratic(chain)
        }
    }

    /// The proportional-damping path.
    ///
    /// # Errors
    /// Damping not proportional to mass; `n >` [`MAX_N_SYMMETRIC`] for a
    /// non-uniform chain.
    pub fn proportional(chain: &Chain) -> Result<Modes> {
        let n = chain.n();
        let alpha = proportional_alpha(chain).ok_or_else(|| {
            Error::invalid(
                "chain",
                "damping not proportional to mass",
                "d_i / m_i equal for all masses (use the quadratic path)",
            )
        })?;
        let masses = chain.masses();
        let springs = chain.springs();
        let uniform_m = masses.iter().all(|&m| m == masses[0]);
        let uniform_k = springs.iter().all(|&k| k == springs[0]);
        if uniform_m && uniform_k {
            let (k, m) = (springs[0], masses[0]);
            let omega2 = (1..=n)
                .map(|j| {
                    let s = (j as f64 * std::f64::consts::PI / (2 * (n + 1)) as f64).sin();
                    4.0 * k / m * s * s
                })
                .collect();
            return Ok(Modes {
                n,
                masses,
                path: ModalPath::ClosedForm,
                inner: Inner::Prop {
                    alpha,
                    omega2,
                    q: None,
                },
            });
        }
        if n > MAX_N_SYMMETRIC {
            return Err(Error::invalid(
                "n",
                n,
                format!("n <= {MAX_N_SYMMETRIC} for a modal decomposition of a non-uniform chain"),
            ));
        }
        let kt = DMatrix::from_fn(n, n, |i, j| {
            if i == j {
                (springs[i] + springs[i + 1]) / masses[i]
            } else if j == i + 1 {
                -springs[j] / (masses[i] * masses[j]).sqrt()
            } else if i == j + 1 {
                -springs[i] / (masses[i] * masses[j]).sqrt()
            } else {
                0.0
            }
        });
        let eig =
            nalgebra::SymmetricEigen::try_new(kt, f64::EPSILON, 100 * n).ok_or_else(|| {
                Error::Numerical {
                    method: "symmetric eigen".into(),
                    reason: "did not converge".into(),
                }
            })?;
        Ok(Modes {
            n,
            masses,
            path: ModalPath::Proportional,
            inner: Inner::Prop {
                alpha,
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
        let n2 = 2 * n;
        let mut l = DMatrix::zeros(n2, n2);
        for i in 0..n {
            l[(i, n + i)] = 1.0;
            l[(n + i, i)] = -(k[i] + k[i + 1]) / m[i];
            l[(n + i, n + i)] = -d[i] / m[i];
            if i + 1 < n {
                let c = k[i + 1] / (m[i] * m[i + 1]).sqrt();
                l[(n + i, i + 1)] = c;
                l[(n + i + 1, i)] = c;
            }
        }
        let fail = |reason: String| Error::Numerical {
            method: "quadratic eigenproblem".into(),
            reason,
        };
        let schur = nalgebra::Schur::try_new(l, f64::EPSILON, 1000 * n2)
            .ok_or_else(|| fail("the Schur iteration did not converge".into()))?;
        let ev: Vec<Complex64> = schur.complex_eigenvalues().iter().copied().collect();
        let npos = ev.iter().filter(|z| z.im > 0.0).count();
        let nneg = ev.iter().filter(|z| z.im < 0.0).count();
        if npos != nneg || ev.len() != n2 {
            return Err(fail(format!(
                "{npos} poles above and {nneg} below the real axis (expected conjugate pairs)"
            )));
        }
        let qep = Qep {
            m: &m,
            k: &k,
            d: &d,
        };
        let mut poles = Vec::new();
        let mut vecs = Vec::new();
        let mut norms = Vec::new();
        for (idx, &p0) in ev.iter().enumerate() {
            if p0.im < 0.0 {
                continue;
            }
            let sep = ev
                .iter()
                .enumerate()
                .filter(|(j, _)| *j != idx)
                .map(|(_, z)| (z - p0).norm())
                .fold(f64::INFINITY, f64::min);
            let real = p0.im == 0.0;
            let (mut p, mut v) = qep.refine(p0, real);
            if (p - p0).norm() > 0.5 * sep {
                // converged to a neighbour: keep the Schur value
                p = p0;
                v = qep.null_vector(p0);
            }
            let nu: Complex64 = (0..n)
                .map(|i| (p * (2.0 * m[i]) + d[i]) * v[i] * v[i])
                .sum();
            poles.push(p);
            vecs.push(v);
            norms.push(nu);
        }
        Ok(Modes {
            n,
            masses: m,
            path: ModalPath::Quadratic,
            inner: Inner::Quad { poles, vecs, norms },
        })
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
        for (field, v) in [("observe", i), ("excite", j)] {
            if v < 1 || v > self.n {
                return Err(Error::invalid(
                    field,
                    v,
                    format!("1 <= {field} <= {}", self.n),
                ));
            }
        }
        let (i0, j0) = (i - 1, j - 1);
        let mut terms = Vec::new();
        match &self.inner {
            Inner::Prop { alpha, omega2, q } => {
                let n = self.n;
                let scale = amp / (self.masses[i0] * self.masses[j0]).sqrt();
                let a = 0.5 * alpha;
                for (kk, &w) in omega2.iter().enumerate() {
                    let (qi, qj) = match q {
                        Some(q) => (q[(i0, kk)], q[(j0, kk)]),
                        None => {
                            let th = (kk + 1) as f64 * std::f64::consts::PI / (n + 1) as f64;
                            let c = (2.0 / (n + 1) as f64).sqrt();
                            (c * (i as f64 * th).sin(), c * (j as f64 * th).sin())
                        }
                    };
                    let c = scale * qi * qj;
                    if c != 0.0 {
                        terms.push(Term::Osc {
                            c,
                            a,
                            w2: w - a * a,
                        });
                    }
                }
            }
            Inner::Quad { poles, vecs, norms } => {
                for ((p, v), nu) in poles.iter().zip(vecs).zip(norms) {
                    let r = v[i0] * v[j0] * amp / nu;
                    if p.im == 0.0 {
                        terms.push(Term::Real { p: p.re, r: r.re });
                    } else {
                        terms.push(Term::Pair { p: *p, r });
                    }
                }
            }
        }
        Ok(ModalResponse {
            terms,
            path: self.path,
        })
    }
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

/// The tridiagonal quadratic eigenproblem `(M s^2 + D s + K) v = 0`.
struct Qep<'a> {
    m: &'a [f64],
    k: &'a [f64],
    d: &'a [f64],
}

impl Qep<'_> {
    fn n(&self) -> usize {
        self.m.len()
    }

    /// Solve `K(p) w = b` (pivoted; zero pivots are nudged, as inverse
    /// iteration wants a large solution there).
    fn solve(&self, p: Complex64, b: &[Complex64]) -> Vec<Complex64> {
        let n = self.n();
        let mut dg: Vec<Complex64> = (0..n)
            .map(|i| p * p * self.m[i] + p * self.d[i] + (self.k[i] + self.k[i + 1]))
            .collect();
        let mut dl: Vec<Complex64> = (0..n.saturating_sub(1))
            .map(|i| Complex64::new(-self.k[i + 1], 0.0))
            .collect();
        let mut du = dl.clone();
        let mut x = b.to_vec();
        let tiny = f64::EPSILON * (p.norm_sqr() * self.m.iter().cloned().fold(0.0, f64::max) + 4.0);
        let nz = |z: Complex64| {
            if z.norm() == 0.0 {
                Complex64::new(tiny, 0.0)
            } else {
                z
            }
        };
        if n == 1 {
            return vec![x[0] / nz(dg[0])];
        }
        for i in 0..n - 1 {
            if dg[i].norm() >= dl[i].norm() {
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

    fn normalise(v: &mut [Complex64]) {
        let s = v.iter().map(|z| z.norm()).fold(0.0, f64::max);
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
                c += v2 * (self.k[i] + self.k[i + 1]);
                if i + 1 < n {
                    c -= v[i] * v[i + 1] * (2.0 * self.k[i + 1]);
                }
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
    use super::*;
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
            Chain::paper(12)
                .unwrap()
                .with_defects([
                    Defect::Spring { at: 0, k: 3.0 },
                    Defect::Damper { at: 7, d: 2.5 },
                    Defect::Mass { at: 4, m: 0.3 },
                ])
                .unwrap(),
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
