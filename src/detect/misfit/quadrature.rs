//! Quadrature for the residual integrals: fixed rules with precomputed
//! nodes, weights and Green's-function tables, and an adaptive reference.
//!
//! The paper's residual (4.18) is `r = int_0^300 |X_1(s; unknowns) - X_1*(s)|^2 ds`.
//! A fixed rule replaces it by `r = sum_q w_q |X_1(s_q) - X_1*(s_q)|^2`. What
//! depends only on the uniform chain and the node (the Green's function) is
//! computed once per study in a [`GreenTable`]; what depends on the unknowns is
//! the small Woodbury solve per node (see [`crate::detect::misfit`]).
//!
//! * [`Rule::gauss_legendre_log`]: composite Gauss-Legendre on log-graded panels
//!   `[0, first], [first, first r], ..., [.., b]` (the residual's integrand
//!   lives at small `s` and decays like a power of `s`); the default real-axis
//!   rule is 10 panels of 8 points (80 nodes) with `first = 0.05` on `[0, 300]`.
//! * [`Rule::gauss_legendre_uniform`]: composite Gauss-Legendre on equal panels
//!   (used for the Bromwich line, whose integrand has resonance peaks spread
//!   over `omega in [0, 2 sqrt(k/mass)]`).
//! * [`Adaptive`]: the reference, the `quadrature` crate's double-exponential
//!   rule on log-graded panels with recursive bisection until the error
//!   estimate is below `max(rel_tol |r|, abs_tol)`. The default tolerances
//!   (`rel_tol = 1e-12`, `abs_tol = 1e-28`) resolve residual gaps of `1e-13`:
//!   a default absolute tolerance such as `1e-10` would not (docs/paper-notes.md).
//!
//! ```
//! use springmass::detect::misfit::quadrature::{Adaptive, Rule};
//! let rule = Rule::gauss_legendre_log(0.0, 300.0, 10, 8, 0.05)?;
//! assert_eq!(rule.len(), 80);
//! let f = |s: f64| (-s).exp() / (1.0 + s);
//! let fixed = rule.integrate(f);
//! let adaptive = Adaptive::default().integrate(f, 0.0, 300.0)?;
//! assert!((fixed - adaptive.value).abs() < 1e-9);
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::chain::Chain;
use crate::error::{Error, Result};
use crate::green::Green;
use crate::scalar::Scalar;

/// Gauss-Legendre nodes and weights on `[-1, 1]` (Newton iteration on the
/// Legendre recurrence; nodes accurate to a few ulps for `npts <= 200`).
///
/// ```
/// let (x, w) = springmass::detect::misfit::quadrature::gauss_legendre(5);
/// let exact = 2.0 / 9.0; // int x^8 dx over [-1, 1], degree 8 <= 2*5-1
/// let got: f64 = x.iter().zip(&w).map(|(x, w)| w * x.powi(8)).sum();
/// assert!((got - exact).abs() < 1e-15);
/// ```
pub fn gauss_legendre(npts: usize) -> (Vec<f64>, Vec<f64>) {
    let mut x = vec![0.0; npts];
    let mut w = vec![0.0; npts];
    let nf = npts as f64;
    for i in 0..npts.div_ceil(2) {
        // Tricomi's initial guess
        let mut z = (std::f64::consts::PI * (i as f64 + 0.75) / (nf + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            let (mut p0, mut p1) = (1.0, z);
            if npts == 0 {
                break;
            }
            for k in 2..=npts {
                let kf = k as f64;
                let p2 = ((2.0 * kf - 1.0) * z * p1 - (kf - 1.0) * p0) / kf;
                p0 = p1;
                p1 = p2;
            }
            let pn = if npts == 1 { z } else { p1 };
            let pm = if npts == 1 { 1.0 } else { p0 };
            dp = nf * (z * pn - pm) / (z * z - 1.0);
            let dz = pn / dp;
            z -= dz;
            if dz.abs() < 1e-16 {
                break;
            }
        }
        let wi = 2.0 / ((1.0 - z * z) * dp * dp);
        x[i] = -z;
        x[npts - 1 - i] = z;
        w[i] = wi;
        w[npts - 1 - i] = wi;
    }
    if npts % 2 == 1 {
        x[npts / 2] = 0.0;
    }
    (x, w)
}

/// A fixed quadrature rule on an interval of a real parameter `t`
/// (`t = s` on the real axis, `t = omega` on a Bromwich line).
#[derive(Clone, Debug, PartialEq)]
pub struct Rule {
    /// A short description, for reports (`gl-log 10x8 first=0.05 on [0, 300]`).
    pub name: String,
    /// Nodes, increasing.
    pub nodes: Vec<f64>,
    /// Weights (all positive).
    pub weights: Vec<f64>,
    /// The interval.
    pub a: f64,
    /// The interval.
    pub b: f64,
}

impl Rule {
    /// Composite Gauss-Legendre with `per_panel` points on each of the panels
    /// between the given increasing `breaks`.
    ///
    /// # Errors
    /// Fewer than two breaks, breaks not finite and strictly increasing, or
    /// `per_panel` outside `1..=64`.
    pub fn composite(name: impl Into<String>, breaks: &[f64], per_panel: usize) -> Result<Rule> {
        if breaks.len() < 2 {
            return Err(Error::invalid(
                "misfit.panels",
                breaks.len().saturating_sub(1),
                ">= 1",
            ));
        }
        if breaks.iter().any(|b| !b.is_finite()) || breaks.windows(2).any(|p| p[1] <= p[0]) {
            return Err(Error::invalid(
                "misfit.breaks",
                format!("{breaks:?}"),
                "finite and strictly increasing",
            ));
        }
        if !(1..=64).contains(&per_panel) {
            return Err(Error::invalid("misfit.per_panel", per_panel, "1..=64"));
        }
        let (x, w) = gauss_legendre(per_panel);
        let mut nodes = Vec::with_capacity((breaks.len() - 1) * per_panel);
        let mut weights = Vec::with_capacity(nodes.capacity());
        for p in breaks.windows(2) {
            let (c, h) = (0.5 * (p[0] + p[1]), 0.5 * (p[1] - p[0]));
            for (xi, wi) in x.iter().zip(&w) {
                nodes.push(c + h * xi);
                weights.push(h * wi);
            }
        }
        Ok(Rule {
            name: name.into(),
            nodes,
            weights,
            a: breaks[0],
            b: *breaks.last().unwrap(),
        })
    }

    /// Composite Gauss-Legendre on log-graded panels of `[a, b]`: the first
    /// panel is `[a, first]`, the others grow geometrically from `first` to `b`.
    ///
    /// # Errors
    /// Need `0 <= a < first < b`, all finite, `panels >= 2`, `per_panel` in `1..=64`.
    pub fn gauss_legendre_log(
        a: f64,
        b: f64,
        panels: usize,
        per_panel: usize,
        first: f64,
    ) -> Result<Rule> {
        if !(a.is_finite() && a >= 0.0) {
            return Err(Error::invalid("misfit.s_min", a, "finite and >= 0"));
        }
        if !(first.is_finite() && first > a && first < b) {
            return Err(Error::invalid(
                "misfit.first",
                first,
                format!("{a} < first < s_max = {b}"),
            ));
        }
        if !b.is_finite() {
            return Err(Error::invalid("misfit.s_max", b, "finite"));
        }
        if panels < 2 {
            return Err(Error::invalid("misfit.panels", panels, ">= 2 for gl-log"));
        }
        let ratio = (b / first).powf(1.0 / (panels - 1) as f64);
        let mut breaks = vec![a, first];
        for i in 1..panels - 1 {
            breaks.push(first * ratio.powi(i as i32));
        }
        breaks.push(b);
        Rule::composite(
            format!("gl-log {panels}x{per_panel} first={first} on [{a}, {b}]"),
            &breaks,
            per_panel,
        )
    }

    /// Composite Gauss-Legendre on `panels` equal panels of `[a, b]`.
    ///
    /// # Errors
    /// `a < b` finite, `panels >= 1`, `per_panel` in `1..=64`.
    pub fn gauss_legendre_uniform(a: f64, b: f64, panels: usize, per_panel: usize) -> Result<Rule> {
        if !(a.is_finite() && b.is_finite() && a < b) {
            return Err(Error::invalid(
                "misfit.interval",
                format!("[{a}, {b}]"),
                "finite with a < b",
            ));
        }
        if panels == 0 {
            return Err(Error::invalid("misfit.panels", panels, ">= 1"));
        }
        let h = (b - a) / panels as f64;
        let breaks: Vec<f64> = (0..=panels)
            .map(|i| if i == panels { b } else { a + h * i as f64 })
            .collect();
        Rule::composite(
            format!("gl-uniform {panels}x{per_panel} on [{a}, {b}]"),
            &breaks,
            per_panel,
        )
    }

    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    /// No nodes (never true for a rule built by the constructors).
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// `sum_q w_q f(t_q)`.
    pub fn integrate(&self, f: impl Fn(f64) -> f64) -> f64 {
        self.nodes
            .iter()
            .zip(&self.weights)
            .map(|(&t, &w)| w * f(t))
            .sum()
    }
}

/// Result of an adaptive integration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AdaptiveOutput {
    /// The integral.
    pub value: f64,
    /// Sum of the panels' error estimates (the double-exponential estimate
    /// can be slightly optimistic).
    pub error: f64,
    /// Integrand evaluations.
    pub evaluations: usize,
    /// The absolute tolerance aimed at, `max(rel_tol |I|, abs_tol)`.
    pub tolerance: f64,
}

/// The adaptive reference: double-exponential quadrature (`quadrature`
/// crate) on log-graded panels, each bisected (geometrically when it does not
/// touch 0) until its error estimate is below its share of
/// `max(rel_tol |I|, abs_tol)`.
#[derive(Clone, Debug, PartialEq)]
pub struct Adaptive {
    /// Relative tolerance (default `1e-12`).
    pub rel_tol: f64,
    /// Absolute tolerance (default `1e-28`).
    pub abs_tol: f64,
    /// Largest bisection depth per initial panel (default 12).
    pub max_depth: usize,
    /// Initial breakpoints strictly inside `(a, b)` are taken from this list
    /// (default `1e-3, 1e-2, 0.1, 0.3, 1, 2, 4, 8, 16, 40, 100`).
    pub breaks: Vec<f64>,
}

impl Default for Adaptive {
    fn default() -> Self {
        Adaptive {
            rel_tol: 1e-12,
            abs_tol: 1e-28,
            max_depth: 12,
            breaks: vec![1e-3, 1e-2, 0.1, 0.3, 1.0, 2.0, 4.0, 8.0, 16.0, 40.0, 100.0],
        }
    }
}

impl Adaptive {
    /// An adaptive rule with the given tolerances and the default panels.
    pub fn with_tol(rel_tol: f64, abs_tol: f64) -> Adaptive {
        Adaptive {
            rel_tol,
            abs_tol,
            ..Adaptive::default()
        }
    }

    /// `int_a^b f`.
    ///
    /// # Errors
    /// Bad interval or tolerances; [`Error::Numerical`] when some panel
    /// does not reach its tolerance at the largest depth (the value is then
    /// not trustworthy at the requested level).
    pub fn integrate(&self, f: impl Fn(f64) -> f64, a: f64, b: f64) -> Result<AdaptiveOutput> {
        if !(a.is_finite() && b.is_finite() && a < b) {
            return Err(Error::invalid(
                "interval",
                format!("[{a}, {b}]"),
                "finite with a < b",
            ));
        }
        if !(self.rel_tol >= 0.0 && self.abs_tol >= 0.0 && self.rel_tol + self.abs_tol > 0.0) {
            return Err(Error::invalid(
                "tolerance",
                format!("rel {} abs {}", self.rel_tol, self.abs_tol),
                "non-negative, not both zero",
            ));
        }
        let mut breaks = vec![a];
        breaks.extend(self.breaks.iter().copied().filter(|&t| t > a && t < b));
        breaks.push(b);
        // a first pass gives the scale for the relative tolerance
        let rough: f64 = breaks
            .windows(2)
            .map(|p| quadrature::double_exponential::integrate(&f, p[0], p[1], 1e-6).integral)
            .sum::<f64>()
            .abs();
        let target = (self.rel_tol * rough).max(self.abs_tol);
        let mut out = AdaptiveOutput {
            value: 0.0,
            error: 0.0,
            evaluations: 0,
            tolerance: target,
        };
        let mut failed = None;
        let total = b - a;
        for p in breaks.windows(2) {
            self.panel(&f, p[0], p[1], target, total, 0, &mut out, &mut failed);
        }
        if let Some((lo, hi, err)) = failed {
            return Err(Error::Numerical {
                method: "adaptive double-exponential".into(),
                reason: format!(
                    "panel [{lo:e}, {hi:e}] error estimate {err:e} above its tolerance after depth {}; total error {:e}, target {target:e}",
                    self.max_depth, out.error
                ),
            });
        }
        Ok(out)
    }

    #[allow(clippy::too_many_arguments)]
    fn panel(
        &self,
        f: &impl Fn(f64) -> f64,
        lo: f64,
        hi: f64,
        target: f64,
        total: f64,
        depth: usize,
        out: &mut AdaptiveOutput,
        failed: &mut Option<(f64, f64, f64)>,
    ) {
        // this panel's share of the tolerance, in proportion to its log-width
        // would starve wide panels; share by length with a floor instead
        let share = (target * ((hi - lo) / total)).max(target * 1e-3);
        let o = quadrature::double_exponential::integrate(f, lo, hi, share);
        out.evaluations += o.num_function_evaluations as usize;
        if o.error_estimate <= share || depth >= self.max_depth {
            if o.error_estimate > share && failed.is_none() {
                *failed = Some((lo, hi, o.error_estimate));
            }
            out.value += o.integral;
            out.error += o.error_estimate;
            return;
        }
        let mid = if lo > 0.0 && hi / lo > 4.0 {
            (lo * hi).sqrt()
        } else {
            0.5 * (lo + hi)
        };
        self.panel(f, lo, mid, target, total, depth + 1, out, failed);
        self.panel(f, mid, hi, target, total, depth + 1, out, failed);
    }
}

/// The Green's function of a uniform chain tabled at the nodes of a rule.
///
/// Per node `s_q` it stores `p_q[p] = exp(-p lambda)` and
/// `o_q[p] = 1 - exp(-2 p lambda)` for `p = 0..=n+1` and
/// `1 / (k o_q[1] o_q[n+1])`, so that every entry is three products:
///
/// `G_ij(s_q) = p_q[j-i+1] o_q[i] o_q[n+1-j] / (k o_q[1] o_q[n+1])`, `i <= j`
///
/// (the formula of [`crate::green`]). Memory `2 (n+2)` scalars per node;
/// building costs `2 (n+2)` exponentials per node, once per study.
#[derive(Clone, Debug)]
pub struct GreenTable<T: Scalar> {
    n: usize,
    stride: usize,
    s: Vec<T>,
    pw: Vec<T>,
    om: Vec<T>,
    inv_den: Vec<T>,
}

/// Largest `(n + 2) * nodes` accepted by [`GreenTable::new`].
pub const MAX_TABLE: usize = 50_000_000;

impl<T: Scalar> GreenTable<T> {
    /// Table the uniform part of `chain` (its `n, k, mass, d`; defects are
    /// ignored) at the Laplace variables `s` (`Re s > 0`).
    ///
    /// # Errors
    /// A node with `Re s < 0` or not finite; a table larger than [`MAX_TABLE`].
    pub fn new(chain: &Chain, s: &[T]) -> Result<GreenTable<T>> {
        chain.require_uniform("the tabled Green's function of the uniform chain")?;
        let n = chain.n();
        let stride = n + 2;
        if stride.saturating_mul(s.len()) > MAX_TABLE {
            return Err(Error::invalid(
                "chain.n",
                n,
                format!(
                    "(n + 2) * nodes <= {MAX_TABLE} for a tabled residual ({} nodes)",
                    s.len()
                ),
            ));
        }
        let mut pw = Vec::with_capacity(stride * s.len());
        let mut om = Vec::with_capacity(stride * s.len());
        let mut inv_den = Vec::with_capacity(s.len());
        for sq in s {
            crate::forward::check_s(sq)?;
            let lam = Green::new(n, chain.k(), chain.mass(), chain.d(), sq.clone()).lambda();
            if lam.is_zero() {
                for p in 0..stride {
                    pw.push(T::one());
                    om.push(T::from_f64(p as f64));
                }
            } else {
                for p in 0..stride {
                    pw.push(lam.scale(-(p as f64)).exp());
                    om.push(-lam.scale(-2.0 * p as f64).expm1());
                }
            }
            let base = om.len() - stride;
            let den = (om[base + 1].clone() * om[base + n + 1].clone()).scale(chain.k());
            inv_den.push(T::one() / den);
        }
        Ok(GreenTable {
            n,
            stride,
            s: s.to_vec(),
            pw,
            om,
            inv_den,
        })
    }

    /// Number of masses.
    pub fn n(&self) -> usize {
        self.n
    }

    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.s.len()
    }

    /// No nodes.
    pub fn is_empty(&self) -> bool {
        self.s.is_empty()
    }

    /// The Laplace variables.
    pub fn s(&self) -> &[T] {
        &self.s
    }

    /// `G_ij(s_q)`, 1-based `i, j` in `1..=n` (unchecked beyond debug asserts).
    #[inline]
    pub fn entry(&self, q: usize, i: usize, j: usize) -> T {
        debug_assert!(i >= 1 && j >= 1 && i <= self.n && j <= self.n);
        let (a, b) = if i <= j { (i, j) } else { (j, i) };
        let base = q * self.stride;
        self.pw[base + b - a + 1].clone()
            * self.om[base + a].clone()
            * self.om[base + self.n + 1 - b].clone()
            * self.inv_den[q].clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use num_complex::Complex64;

    #[test]
    fn gauss_legendre_exact_for_polynomials() {
        for npts in 1..=40 {
            let (x, w) = gauss_legendre(npts);
            assert!(x.windows(2).all(|p| p[0] < p[1]));
            for deg in 0..2 * npts {
                let got: f64 = x.iter().zip(&w).map(|(x, w)| w * x.powi(deg as i32)).sum();
                let exact = if deg % 2 == 1 {
                    0.0
                } else {
                    2.0 / (deg as f64 + 1.0)
                };
                assert!((got - exact).abs() < 2e-14, "npts {npts} deg {deg}");
            }
        }
    }

    #[test]
    fn composite_rules_integrate_smooth_functions() {
        let f = |s: f64| 1.0 / (1.0 + s * s);
        let exact = 300f64.atan();
        let r = Rule::gauss_legendre_log(0.0, 300.0, 16, 10, 0.05).unwrap();
        assert_eq!(r.len(), 160);
        assert!((r.integrate(f) - exact).abs() < 1e-12);
        let u = Rule::gauss_legendre_uniform(0.0, 3.0, 3, 10).unwrap();
        let g = |s: f64| (-s).exp() * s.cos();
        let exact_g = 0.5 * (1.0 + (-3f64).exp() * (3f64.sin() - 3f64.cos()));
        assert!((u.integrate(g) - exact_g).abs() < 1e-14);
        assert!(r.weights.iter().all(|&w| w > 0.0));
        assert!((r.weights.iter().sum::<f64>() - 300.0).abs() < 1e-11);
    }

    #[test]
    fn adaptive_reaches_tight_tolerance() {
        let f = |s: f64| (-3.0 * s).exp() * s * s;
        let exact = 2.0 / 27.0; // to 300: exp(-900) negligible
        let o = Adaptive::default().integrate(f, 0.0, 300.0).unwrap();
        assert!((o.value - exact).abs() < 1e-13 * exact, "{o:?}");
        // tiny integrands are resolved in absolute terms
        let g = |s: f64| 1e-14 * (-s).exp();
        let o = Adaptive::default().integrate(g, 0.0, 300.0).unwrap();
        assert!((o.value - 1e-14).abs() < 1e-26, "{o:?}");
    }

    #[test]
    fn bad_rules_are_typed_errors() {
        let field = |r: Result<Rule>| match r {
            Err(Error::InvalidParameter { field, .. }) => field,
            other => panic!("{other:?}"),
        };
        assert_eq!(
            field(Rule::gauss_legendre_log(0.0, 300.0, 10, 8, 400.0)),
            "misfit.first"
        );
        assert_eq!(
            field(Rule::gauss_legendre_log(0.0, 300.0, 1, 8, 1.0)),
            "misfit.panels"
        );
        assert_eq!(
            field(Rule::gauss_legendre_uniform(0.0, 3.0, 4, 0)),
            "misfit.per_panel"
        );
        assert_eq!(
            field(Rule::gauss_legendre_uniform(3.0, 3.0, 4, 4)),
            "misfit.interval"
        );
    }

    #[test]
    fn table_matches_green() {
        for &(n, k, mass, d) in &[
            (1usize, 1.0, 1.0, 0.1),
            (20, 1.0, 1.0, 0.1),
            (37, 2.5, 0.7, 0.0),
        ] {
            let chain = Chain::new(n)
                .unwrap()
                .with_k(k)
                .unwrap()
                .with_mass(mass)
                .unwrap()
                .with_d(d)
                .unwrap();
            let s = [1e-4, 0.05, 0.7, 3.0, 50.0, 300.0];
            let t = GreenTable::new(&chain, &s).unwrap();
            let sc: Vec<Complex64> = s.iter().map(|&x| Complex64::new(0.1, x)).collect();
            let tc = GreenTable::new(&chain, &sc).unwrap();
            for (q, &sq) in s.iter().enumerate() {
                let g = Green::new(n, k, mass, d, sq);
                let gc = Green::new(n, k, mass, d, sc[q]);
                for i in 1..=n {
                    for j in 1..=n {
                        let (e, x) = (t.entry(q, i, j), g.entry(i, j));
                        assert!(
                            (e - x).abs() <= 1e-13 * x.abs() + 1e-300,
                            "{n} {sq} {i} {j}"
                        );
                        let (e, x) = (tc.entry(q, i, j), gc.entry(i, j));
                        assert!((e - x).norm() <= 1e-13 * x.norm() + 1e-300);
                    }
                }
            }
        }
        let c = Chain::paper(3).unwrap();
        assert!(GreenTable::new(&c, &[-1.0]).is_err());
    }
}
