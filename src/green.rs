//! Closed-form Green's function of the uniform chain (Theorem 2.1, any `k`),
//! for each end fixed or free ([`Boundary`]).
//!
//! The uniform chain's dynamic stiffness is `K(s) = tridiag(-k, mass s^2 + d s + 2k, -k)`
//! and its Green's function is `G(s) = K(s)^{-1}`. With
//! `cosh(lambda) = 1 + (mass s^2 + d s) / (2k)`, for `i <= j`
//!
//! `G_ij = sinh(i lambda) sinh((n+1-j) lambda) / (k sinh(lambda) sinh((n+1) lambda))`.
//!
//! (The paper's `R = A^{-1}` with `A = tridiag(1, h, 1) = -K` when `k = 1`, so `R = -G`.)
//!
//! # Numerical form
//!
//! Every `sinh(p lambda)` is written as `e^{p lambda} (1 - q^{2p}) / 2` with
//! `q = e^{-lambda}`, `|q| <= 1` for `Re s >= 0`; the growing exponentials
//! cancel analytically and what is left is
//!
//! `G_ij = q^{j-i+1} (1 - q^{2i}) (1 - q^{2(n+1-j)}) / (k (1 - q^2) (1 - q^{2(n+1)}))`,
//!
//! each `1 - q^{2p}` taken as `-expm1(-2 p lambda)`. No term exceeds 1 in size, so
//! nothing overflows for any `n`; values below the range underflow to 0. `lambda`
//! itself is `2 asinh( sqrt(s) sqrt((mass s + d)/k) / 2 )`, which has no
//! cancellation at small `|s|` and no overflow at large `|s|`. At `lambda = 0`
//! (`s = 0`) the static limit `G_ij = i (n+1-j) / (k (n+1))` is used.
//!
//! Spring defects need the strain probe `e_i - e_{i+1}`; its entries are
//! formed from the closed-form differences
//! `sinh((i+1) lambda) - sinh(i lambda) = 2 cosh((i + 1/2) lambda) sinh(lambda/2)`,
//! so they do not cancel either. Every entry costs O(1) whatever `n`.
//!
//! # Free ends (derivation)
//!
//! Away from the ends every column of `G` solves the interior recurrence
//! `-k x_{i-1} + (mass s^2 + d s + 2k) x_i - k x_{i+1} = 0`, whose solutions
//! are `e^{+-i lambda}`. Let `L_i` solve it with the left end condition and
//! `R_j` with the right one; then for `i <= j`
//!
//! `G_ij = L_i R_j / (k C)`,  `C = L_1 R_0 - L_0 R_1` (the Casoratian, constant in `i`),
//!
//! because row `j` of `K G e_j` is `R_j (a L_j - k L_{j-1}) - k L_j R_{j+1} = k (L_{j+1} R_j - L_j R_{j+1}) = k C`
//! and every other row vanishes. A fixed end is `x_0 = 0` (`x_{n+1} = 0`);
//! a free end has no wall spring, so row 1 reads `(a - k) x_1 - k x_2 = 0`,
//! which is the interior row with the ghost value `x_0 = x_1` (and
//! `x_{n+1} = x_n` on the right). Hence
//!
//! | end | `L_i` (left) | `R_j` (right) |
//! |---|---|---|
//! | fixed | `sinh(i lambda)` | `sinh((n+1-j) lambda)` |
//! | free | `cosh((i - 1/2) lambda)` | `cosh((n + 1/2 - j) lambda)` |
//!
//! and `C` is `sinh(lambda) sinh((n+1) lambda)` (fixed-fixed),
//! `sinh(lambda) cosh((n + 1/2) lambda)` (one end free, either one), and
//! `sinh(lambda) sinh(n lambda)` (free-free). The poles are the zeros of `C`:
//! with `lambda = i theta`, `cosh(lambda) = 1 - mass omega^2/(2k)` gives
//! `omega = 2 sqrt(k/mass) sin(theta/2)` with `theta = j pi/(n+1)` (fixed-fixed),
//! `theta = (2j-1) pi/(2n+1)` (one end free) and `theta = (j-1) pi / n`
//! (free-free, `j = 1` the rigid-body mode at `s = 0`). Differences for the
//! strain probes stay products: at a free end
//! `L_i - L_{i+1} = -2 sinh(i lambda) sinh(lambda/2)` and
//! `R_j - R_{j+1} = 2 sinh((n-j) lambda) sinh(lambda/2)`.
//!
//! In `q` form the half-integer multiples of `lambda` appear, so every factor
//! is kept as `e^{h lambda / 2} * mantissa` with an integer `h`; e.g.
//! `cosh((i - 1/2) lambda) = e^{(2i-1) lambda/2} (1 + q^{2i-1}) / 2`. No
//! mantissa exceeds 1 in size and no difference of nearly equal terms is
//! formed, exactly as in the fixed-fixed case. Static limits (`lambda -> 0`):
//! `G_ij = (n+1-j)/k` (left free), `i/k` (right free); with both ends free
//! `s = 0` is the rigid-body pole ([`Green::is_singular`]).
//!
//! ```
//! use springmass::green::{Green, Probe};
//! let g = Green::new(20, 1.0, 1.0, 0.1, 0.5_f64);
//! // X_1 of the uniform chain is gamma G_11 = sinh(n lambda) / (k sinh((n+1) lambda))
//! let lam = g.lambda();
//! let expect = (20.0 * lam).sinh() / (21.0 * lam).sinh();
//! assert!((g.entry(1, 1) - expect).abs() < 1e-14 * expect);
//! assert_eq!(g.bilinear(Probe::Point(3), Probe::Point(7)), g.entry(3, 7));
//! ```

use crate::chain::{Boundary, Chain};
use crate::scalar::Scalar;
use std::sync::Arc;

mod profile;

pub use crate::chain::Probe;

/// A factor `e^{h lambda / 2} * mantissa` (the exponent is kept as an integer
/// number of half-`lambda`s and cancelled analytically against the denominator).
#[derive(Clone, Debug)]
struct Factor<T> {
    half_exp: usize,
    mant: T,
    /// A binary exponent: `0` in the closed form; a nonuniform chain's
    /// factors are `mant * 2^exp2` ([`profile`]).
    exp2: i32,
}

impl<T> Factor<T> {
    /// A factor of the closed form: `e^{half_exp lambda / 2} * mant`.
    fn closed(half_exp: usize, mant: T) -> Factor<T> {
        Factor {
            half_exp,
            mant,
            exp2: 0,
        }
    }
}

impl<T> From<profile::Scaled<T>> for Factor<T> {
    fn from(v: profile::Scaled<T>) -> Factor<T> {
        Factor {
            half_exp: 0,
            mant: v.mant,
            exp2: v.exp2,
        }
    }
}

/// The left and right factors of one probe at one `s`, computed once and
/// reused for every entry that involves the probe (see [`Green::pair`]).
#[derive(Clone, Debug)]
pub struct ProbeFactors<T> {
    probe: Probe,
    left: Factor<T>,
    right: Factor<T>,
}

impl<T> ProbeFactors<T> {
    /// The probe these factors belong to.
    pub fn probe(&self) -> Probe {
        self.probe
    }
}

/// The Green's function of a uniform chain at one value of `s`.
///
/// Construction costs a few transcendental functions; every entry after that
/// costs three. What depends only on `(n, k, mass, d, s)` and the ends lives
/// here, so a caller that evaluates many defect hypotheses at one `s` builds
/// it once.
#[derive(Clone, Debug)]
pub struct Green<T: Scalar> {
    n: usize,
    lambda: T,
    left: Boundary,
    right: Boundary,
    /// `lambda == 0`: use the static limit.
    stat: bool,
    /// `1 - q`
    one_m_q: T,
    /// mantissa of `k C` (see the module docs), or its static limit
    den: T,
    /// `k C = e^{den_half lambda / 2} den`
    den_half: usize,
    /// A nonuniform chain's sweeps ([`Green::of_chain`] on a chain with a
    /// [`crate::chain::Baseline`]); `None` for the closed form.
    profile: Option<Arc<profile::ProfileGreen<T>>>,
}

impl<T: Scalar> Green<T> {
    /// Green's function of the uniform chain `(n, k, mass, d)` with both ends
    /// fixed, at `s`.
    ///
    /// The parameters are assumed validated (see [`crate::Chain`]); `s` must have
    /// `Re s >= 0`. Use [`crate::forward`] for the checked entry point.
    pub fn new(n: usize, k: f64, mass: f64, d: f64, s: T) -> Green<T> {
        Self::with_ends(n, k, mass, d, s, Boundary::Fixed, Boundary::Fixed)
    }

    /// Green's function of the uniform chain `(n, k, mass, d)` with the given
    /// ends, at `s` (unchecked, as [`Green::new`]).
    pub fn with_ends(
        n: usize,
        k: f64,
        mass: f64,
        d: f64,
        s: T,
        left: Boundary,
        right: Boundary,
    ) -> Green<T> {
        Self::from_lambda_ends(n, k, lambda_of(k, mass, d, &s), left, right)
    }

    /// Green's function of the uniform part of `chain` (its `n`, `k`, `mass`,
    /// `d` and ends; defects ignored) at `s` (unchecked, as [`Green::new`]).
    ///
    /// ```
    /// use springmass::{Chain, chain::Boundary, green::Green};
    /// let c = Chain::new(1)?.with_boundaries(Boundary::Free, Boundary::Fixed)?;
    /// // one mass on one spring: 1 / (s^2 + 1)
    /// let g = Green::of_chain(&c, 2.0_f64);
    /// assert!((g.entry(1, 1) - 0.2).abs() < 1e-15);
    /// # Ok::<(), springmass::Error>(())
    /// ```
    pub fn of_chain(chain: &Chain, s: T) -> Green<T> {
        if chain.baseline().is_some() {
            return Self::of_profile(chain, s);
        }
        let (d_u, c_u) = chain.uniform_damping();
        if c_u != 0.0 {
            return Self::with_spring_dampers(
                chain.n(),
                chain.k(),
                chain.mass(),
                (d_u, c_u),
                s,
                chain.left(),
                chain.right(),
            );
        }
        Self::with_ends(
            chain.n(),
            chain.k(),
            chain.mass(),
            d_u,
            s,
            chain.left(),
            chain.right(),
        )
    }

    /// Green's function of the uniform chain whose every spring `k` has a
    /// damper `c` beside it and every mass a damper `d` to the ground,
    /// `(dc.0, dc.1) = (d, c)`: the dynamic stiffness is
    /// `(mass s^2 + d s) I + (k + c s) Lap`, so `G` is the `k = 1` Green's
    /// function at `cosh(lambda) = 1 + (mass s^2 + d s) / (2 (k + c s))`
    /// divided by `k + c s` (the Rayleigh chain's uniform part has the same
    /// form, [`Chain::uniform_damping`]). `lambda` is taken with
    /// `Re lambda >= 0` (`G` is even in `lambda`). Unchecked, as [`Green::new`].
    pub fn with_spring_dampers(
        n: usize,
        k: f64,
        mass: f64,
        dc: (f64, f64),
        s: T,
        left: Boundary,
        right: Boundary,
    ) -> Green<T> {
        let kappa = T::from_f64(k) + s.scale(dc.1);
        let inner = (s.scale(mass) + T::from_f64(dc.0)) / kappa.clone();
        let mut lambda = (s.sqrt() * inner.sqrt()).scale(0.5).asinh().scale(2.0);
        if lambda.re_f64() < 0.0 {
            lambda = -lambda;
        }
        let mut g = Self::from_lambda_ends(n, 1.0, lambda, left, right);
        g.den = g.den * kappa;
        g
    }

    /// Green's function of `chain` without its defects, from the two
    /// recurrence sweeps of its coefficients (module `green::profile`): O(n) per `s`,
    /// O(1) per entry. [`Green::of_chain`] takes this form for a chain on
    /// a [`crate::chain::Baseline`]; [`Green::lambda`] is zero then (a
    /// nonuniform chain has no single `lambda`).
    pub fn of_profile(chain: &Chain, s: T) -> Green<T> {
        let p = profile::ProfileGreen::of_chain(chain, &s);
        let mut g = Self::from_lambda_ends(chain.n(), 1.0, T::one(), chain.left(), chain.right());
        g.lambda = T::zero();
        g.den = if p.is_singular() { T::zero() } else { T::one() };
        g.profile = Some(Arc::new(p));
        g
    }

    /// Green's function for a given `lambda` (`Re lambda >= 0`), both ends fixed.
    pub fn from_lambda(n: usize, k: f64, lambda: T) -> Green<T> {
        Self::from_lambda_ends(n, k, lambda, Boundary::Fixed, Boundary::Fixed)
    }

    /// Green's function for a given `lambda` (`Re lambda >= 0`) and ends.
    pub fn from_lambda_ends(
        n: usize,
        k: f64,
        lambda: T,
        left: Boundary,
        right: Boundary,
    ) -> Green<T> {
        let stat = lambda.is_zero();
        let nf = n as f64;
        let (one_m_q, den, den_half) = if stat {
            let den = match (left, right) {
                (Boundary::Fixed, Boundary::Fixed) => k * (nf + 1.0),
                (Boundary::Free, Boundary::Free) => 0.0,
                _ => k,
            };
            (T::zero(), T::from_f64(den), 0)
        } else {
            let one_m_q = -(-lambda.clone()).expm1();
            let one_m_q2 = -(lambda.scale(-2.0)).expm1();
            let (second, half) = match (left, right) {
                (Boundary::Fixed, Boundary::Fixed) => {
                    (-(lambda.scale(-2.0 * (nf + 1.0))).expm1(), 2 * n + 4)
                }
                (Boundary::Free, Boundary::Free) => (-(lambda.scale(-2.0 * nf)).expm1(), 2 * n + 2),
                _ => (T::one() + lambda.scale(-(2.0 * nf + 1.0)).exp(), 2 * n + 3),
            };
            (one_m_q, (one_m_q2 * second).scale(0.25 * k), half)
        };
        Green {
            n,
            lambda,
            left,
            right,
            stat,
            one_m_q,
            den,
            den_half,
            profile: None,
        }
    }

    /// Number of masses.
    pub fn n(&self) -> usize {
        self.n
    }

    /// The ends `(left, right)`.
    pub fn ends(&self) -> (Boundary, Boundary) {
        (self.left, self.right)
    }

    /// `lambda(s)`, with `cosh(lambda) = 1 + (mass s^2 + d s)/(2k)` and `Re lambda >= 0`.
    pub fn lambda(&self) -> T {
        self.lambda.clone()
    }

    /// `true` at the rigid-body pole (`s = 0` with both ends free): every
    /// entry is infinite there.
    pub fn is_singular(&self) -> bool {
        self.den.is_zero()
    }

    /// `exp(-h lambda / 2)`.
    #[inline]
    fn qhalf(&self, h: usize) -> T {
        if h == 0 {
            T::one()
        } else {
            self.lambda.scale(-0.5 * h as f64).exp()
        }
    }

    /// `(1 - q^{2p}) / 2`.
    #[inline]
    fn half_one_minus_q2p(&self, p: usize) -> T {
        if p == 0 {
            T::zero()
        } else {
            (self.lambda.scale(-2.0 * p as f64)).expm1().scale(-0.5)
        }
    }

    /// `(1 + q^{h}) / 2`.
    #[inline]
    fn half_one_plus_q(&self, h: usize) -> T {
        (T::one() + self.lambda.scale(-(h as f64)).exp()).scale(0.5)
    }

    /// The factor of an end `p` masses in: `sinh(p lambda)` at a fixed end,
    /// `cosh((p - 1/2) lambda)` at a free one.
    #[inline]
    fn end_point(&self, end: Boundary, p: usize) -> Factor<T> {
        debug_assert!(self.profile.is_none());
        match (end, self.stat) {
            (Boundary::Fixed, true) => Factor::closed(0, T::from_f64(p as f64)),
            (Boundary::Fixed, false) => Factor::closed(2 * p, self.half_one_minus_q2p(p)),
            (Boundary::Free, true) => Factor::closed(0, T::one()),
            (Boundary::Free, false) => Factor::closed(2 * p - 1, self.half_one_plus_q(2 * p - 1)),
        }
    }

    /// `L_a`: `sinh(a lambda)` (fixed) or `cosh((a - 1/2) lambda)` (free).
    #[inline]
    fn left_point(&self, a: usize) -> Factor<T> {
        if let Some(p) = &self.profile {
            return p.left_point(a).into();
        }
        self.end_point(self.left, a)
    }

    /// `R_b`: `sinh(p lambda)` (fixed) or `cosh((p - 1/2) lambda)` (free), `p = n + 1 - b`.
    #[inline]
    fn right_point(&self, b: usize) -> Factor<T> {
        if let Some(p) = &self.profile {
            return p.right_point(b).into();
        }
        self.end_point(self.right, self.n + 1 - b)
    }

    /// `L_i - L_{i+1}`: fixed `-e^{(i+1) lambda} (1 + q^{2i+1}) (1 - q) / 2`,
    /// free `-2 sinh(i lambda) sinh(lambda/2) = -e^{(i+1/2) lambda} (1 - q^{2i}) (1 - q) / 2`.
    fn left_diff(&self, i: usize) -> Factor<T> {
        if let Some(p) = &self.profile {
            return p.left_diff(i).into();
        }
        self.end_diff(self.left, i + 1, -1.0)
    }

    /// `R_j - R_{j+1}` with `p = n + 1 - j`: fixed
    /// `e^{p lambda} (1 + q^{2p-1}) (1 - q) / 2`, free
    /// `2 sinh((p-1) lambda) sinh(lambda/2) = e^{(p - 1/2) lambda} (1 - q^{2(p-1)}) (1 - q) / 2`.
    fn right_diff(&self, j: usize) -> Factor<T> {
        if let Some(p) = &self.profile {
            return p.right_diff(j).into();
        }
        self.end_diff(self.right, self.n + 1 - j, 1.0)
    }

    /// The closed form's difference of two neighbouring end factors, `p`
    /// and `p - 1` masses from an end held `end`, times `sign` (`-1` on the
    /// left, `1` on the right): fixed `e^{p lambda} (1 + q^{2p-1}) (1 - q) / 2`,
    /// free `e^{(p-1/2) lambda} (1 - q^{2(p-1)}) (1 - q) / 2`; at a static
    /// `s`, `1` fixed and `0` free.
    fn end_diff(&self, end: Boundary, p: usize, sign: f64) -> Factor<T> {
        debug_assert!(self.profile.is_none());
        match (end, self.stat) {
            (Boundary::Fixed, true) => Factor::closed(0, T::from_f64(sign)),
            (Boundary::Fixed, false) => {
                let m = (T::one() + self.qhalf(2 * (2 * p - 1))) * self.one_m_q.clone();
                Factor::closed(2 * p, m.scale(0.5 * sign))
            }
            (Boundary::Free, true) => Factor::closed(0, T::zero()),
            (Boundary::Free, false) => {
                let m = self.half_one_minus_q2p(p - 1) * self.one_m_q.clone();
                Factor::closed(2 * p - 1, if sign < 0.0 { -m } else { m })
            }
        }
    }

    fn left(&self, p: Probe) -> Factor<T> {
        match p {
            Probe::Point(a) => self.left_point(a),
            Probe::Diff(i) => self.left_diff(i),
        }
    }

    fn right(&self, p: Probe) -> Factor<T> {
        match p {
            Probe::Point(b) => self.right_point(b),
            Probe::Diff(j) => self.right_diff(j),
        }
    }

    /// `L R / (k C)` with the exponentials cancelled.
    #[inline]
    fn combine(&self, l: Factor<T>, r: Factor<T>) -> T {
        self.combine_ref(&l, &r)
    }

    #[inline]
    fn combine_ref(&self, l: &Factor<T>, r: &Factor<T>) -> T {
        if let Some(p) = &self.profile {
            return p.combine(&l.mant, l.exp2, &r.mant, r.exp2);
        }
        let num = l.mant.clone() * r.mant.clone();
        if self.stat {
            return num / self.den.clone();
        }
        // exponent of the quotient: l + r - den <= 0 (see the module docs)
        debug_assert!(l.half_exp + r.half_exp <= self.den_half);
        let p = self.den_half - l.half_exp - r.half_exp;
        self.qhalf(p) * num / self.den.clone()
    }

    /// `G_ij` (1-based, `1 <= i, j <= n`), symmetric.
    pub fn entry(&self, i: usize, j: usize) -> T {
        let (a, b) = if i <= j { (i, j) } else { (j, i) };
        self.combine(self.left_point(a), self.right_point(b))
    }

    /// The factors of one probe, for repeated use with [`Green::pair`].
    pub fn factors(&self, p: Probe) -> ProbeFactors<T> {
        ProbeFactors {
            probe: p,
            left: self.left(p),
            right: self.right(p),
        }
    }

    /// `u^T G v` from precomputed factors: one exponential per entry.
    pub fn pair(&self, u: &ProbeFactors<T>, v: &ProbeFactors<T>) -> T {
        let (ulo, uhi) = u.probe.span();
        let (vlo, vhi) = v.probe.span();
        if uhi <= vlo {
            self.combine_ref(&u.left, &v.right)
        } else if vhi <= ulo {
            self.combine_ref(&v.left, &u.right)
        } else {
            self.bilinear(u.probe, v.probe)
        }
    }

    /// `u^T G v` for two probes.
    pub fn bilinear(&self, u: Probe, v: Probe) -> T {
        let (ulo, uhi) = u.span();
        let (vlo, vhi) = v.span();
        if uhi <= vlo {
            self.combine(self.left(u), self.right(v))
        } else if vhi <= ulo {
            self.combine(self.left(v), self.right(u))
        } else {
            // Only Diff(i) with itself overlaps:
            // G_ii - 2 G_{i,i+1} + G_{i+1,i+1} = [L_i dR_i - R_{i+1} dL_i] / (k C),
            // both terms positive for real s.
            let i = match (u, v) {
                (Probe::Diff(i), Probe::Diff(_)) => i,
                _ => unreachable!("point probes never overlap other probes"),
            };
            // L_0 = 0 at a fixed left end, R_{n+1} = 0 at a fixed right end
            // (spring 0 / n exist only there)
            let t1 = if i == 0 {
                T::zero()
            } else {
                self.combine(self.left_point(i), self.right_diff(i))
            };
            let t2 = if i == self.n {
                T::zero()
            } else {
                let mut ld = self.left_diff(i);
                ld.mant = -ld.mant;
                self.combine(ld, self.right_point(i + 1))
            };
            t1 + t2
        }
    }
}

/// `lambda = 2 asinh( sqrt(s) sqrt((mass s + d)/k) / 2 )`: no cancellation at
/// small `|s|`, no overflow at large `|s|`.
pub fn lambda_of<T: Scalar>(k: f64, mass: f64, d: f64, s: &T) -> T {
    let inner = (s.scale(mass) + T::from_f64(d)).scale(1.0 / k);
    let root = s.sqrt() * inner.sqrt();
    root.scale(0.5).asinh().scale(2.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use num_complex::Complex64;

    fn rel(a: Complex64, b: Complex64) -> f64 {
        (a - b).norm() / b.norm().max(1e-300)
    }

    #[test]
    fn matches_dense_inverse_complex_and_real() {
        let ss = [
            Complex64::new(1e-3, 0.0),
            Complex64::new(0.5, 0.0),
            Complex64::new(3.0, 0.0),
            Complex64::new(0.5, 2.0),
            Complex64::new(0.1, 0.7),
            Complex64::new(1.0, -5.0),
            Complex64::new(0.0, 0.37),
        ];
        for &n in &[1usize, 2, 3, 7, 20] {
            for &(k, mass, d) in &[(1.0, 1.0, 0.1), (2.5, 0.3, 0.0), (0.7, 4.0, 3.0)] {
                for &s in &ss {
                    let inv = dense_matrix(n, k, mass, d, s).lu().try_inverse().unwrap();
                    let g = Green::new(n, k, mass, d, s);
                    let gr = (s.im == 0.0).then(|| Green::new(n, k, mass, d, s.re));
                    for i in 1..=n {
                        for j in 1..=n {
                            let e = g.entry(i, j);
                            assert!(
                                rel(e, inv[(i - 1, j - 1)]) < 1e-11,
                                "n={n} s={s} ({i},{j}) {e} vs {}",
                                inv[(i - 1, j - 1)]
                            );
                            if let Some(gr) = &gr {
                                assert!(
                                    rel(Complex64::new(gr.entry(i, j), 0.0), inv[(i - 1, j - 1)])
                                        < 1e-11
                                );
                            }
                        }
                    }
                    // strain probes against the dense inverse
                    let vec_of = |p: Probe| {
                        let mut v = nalgebra::DVector::<Complex64>::zeros(n);
                        match p {
                            Probe::Point(j) => v[j - 1] = 1.0.into(),
                            Probe::Diff(i) => {
                                if i >= 1 {
                                    v[i - 1] += Complex64::from(1.0);
                                }
                                if i < n {
                                    v[i] -= Complex64::from(1.0);
                                }
                            }
                        }
                        v
                    };
                    let probes: Vec<Probe> = (0..=n)
                        .map(Probe::Diff)
                        .chain((1..=n).map(Probe::Point))
                        .collect();
                    for &u in &probes {
                        for &v in &probes {
                            let expect = (vec_of(u).transpose() * &inv * vec_of(v))[(0, 0)];
                            let got = g.bilinear(u, v);
                            let scale = inv.iter().map(|z| z.norm()).fold(0.0, f64::max);
                            assert!(
                                (got - expect).norm() <= 1e-11 * scale.max(expect.norm()),
                                "n={n} s={s} {u:?} {v:?}: {got} vs {expect}"
                            );
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn free_ends_match_dense_inverse() {
        use Boundary::*;
        for (left, right) in [(Free, Fixed), (Fixed, Free), (Free, Free)] {
            for &n in &[1usize, 2, 3, 8] {
                for &s in &[
                    Complex64::new(0.3, 0.0),
                    Complex64::new(2e-3, 0.0),
                    Complex64::new(0.2, 1.3),
                    Complex64::new(5.0, -40.0),
                ] {
                    let (k, mass, d) = (1.7, 0.6, 0.2);
                    let mut m = dense_matrix(n, k, mass, d, s);
                    if left == Free {
                        m[(0, 0)] -= k;
                    }
                    if right == Free {
                        m[(n - 1, n - 1)] -= k;
                    }
                    let inv = m.lu().try_inverse().unwrap();
                    let g = Green::with_ends(n, k, mass, d, s, left, right);
                    let scale = inv.iter().map(|z| z.norm()).fold(0.0, f64::max);
                    for i in 1..=n {
                        for j in 1..=n {
                            let e = g.entry(i, j);
                            assert!(
                                (e - inv[(i - 1, j - 1)]).norm() < 1e-12 * scale,
                                "{left:?}-{right:?} n={n} s={s} ({i},{j}) {e} vs {}",
                                inv[(i - 1, j - 1)]
                            );
                        }
                    }
                    let lo = usize::from(left == Free);
                    let hi = if right == Free { n - 1 } else { n };
                    for i in lo..=hi {
                        if lo > hi || (n == 1 && left == Free && right == Free) {
                            break;
                        }
                        let mut u = nalgebra::DVector::<Complex64>::zeros(n);
                        if i >= 1 {
                            u[i - 1] += Complex64::from(1.0);
                        }
                        if i < n {
                            u[i] -= Complex64::from(1.0);
                        }
                        let want = (u.transpose() * &inv * &u)[(0, 0)];
                        let got = g.bilinear(Probe::Diff(i), Probe::Diff(i));
                        assert!((got - want).norm() < 1e-12 * scale, "diff {i}");
                        let want1 = (u.transpose() * inv.column(0))[(0, 0)];
                        let got1 = g.bilinear(Probe::Diff(i), Probe::Point(1));
                        assert!((got1 - want1).norm() < 1e-12 * scale, "diff {i} x 1");
                    }
                }
            }
        }
        // static limits
        let g = Green::with_ends(4, 2.0, 1.0, 0.1, 0.0_f64, Free, Fixed);
        assert!((g.entry(1, 3) - 1.0).abs() < 1e-15);
        let g = Green::with_ends(4, 2.0, 1.0, 0.1, 0.0_f64, Fixed, Free);
        assert!((g.entry(2, 3) - 1.0).abs() < 1e-15);
        let g = Green::with_ends(4, 2.0, 1.0, 0.1, 0.0_f64, Free, Free);
        assert!(g.is_singular() && !g.entry(1, 1).is_finite());
    }

    /// The dynamic stiffness matrix of the uniform chain (fixed ends), dense.
    fn dense_matrix(
        n: usize,
        k: f64,
        mass: f64,
        d: f64,
        s: Complex64,
    ) -> nalgebra::DMatrix<Complex64> {
        let diag = s * s * mass + s * d + 2.0 * k;
        let mut m = nalgebra::DMatrix::<Complex64>::zeros(n, n);
        for i in 0..n {
            m[(i, i)] = diag;
            if i + 1 < n {
                m[(i, i + 1)] = Complex64::new(-k, 0.0);
                m[(i + 1, i)] = Complex64::new(-k, 0.0);
            }
        }
        m
    }

    #[test]
    fn static_limit_and_tiny_s() {
        let n = 9;
        let g0 = Green::new(n, 2.0, 1.0, 0.0, 0.0_f64);
        let gt = Green::new(n, 2.0, 1.0, 0.0, 1e-9_f64);
        for i in 1..=n {
            for j in i..=n {
                let exact = (i * (n + 1 - j)) as f64 / (2.0 * (n + 1) as f64);
                assert!((g0.entry(i, j) - exact).abs() < 1e-15 * exact);
                assert!((gt.entry(i, j) - exact).abs() < 1e-12 * exact);
            }
        }
        assert!((g0.bilinear(Probe::Diff(0), Probe::Diff(0)) - 9.0 / 20.0).abs() < 1e-15);
    }

    #[test]
    fn never_overflows() {
        for &n in &[1usize, 1000, 1_000_000, 1_000_000_000] {
            for &s in &[1e-6, 1e-3, 1.0, 1e4, 1e8] {
                let g = Green::new(n, 1.0, 1e6, 10.0, s);
                for &(i, j) in &[(1, 1), (1, n), (n / 2 + 1, n), (n, n)] {
                    let e = g.entry(i, j);
                    assert!(e.is_finite() && e >= 0.0, "n={n} s={s} ({i},{j}) {e}");
                }
                let gc = Green::new(n, 1.0, 1e-3, 0.0, Complex64::new(s, 100.0));
                assert!(Scalar::is_finite(&gc.entry(1, n)));
            }
        }
    }
}

#[cfg(test)]
mod damping_tests {
    use super::*;
    use crate::chain::dense_ref;
    use num_complex::Complex64;

    #[test]
    fn spring_dampers_match_the_dense_inverse() {
        for chain in dense_ref::model_chains() {
            if chain.damping().is_grounded() {
                continue;
            }
            let u = chain.uniform();
            let d = dense_ref::assemble(&u);
            let n = u.n();
            for s in [
                Complex64::new(0.4, 0.0),
                Complex64::new(0.1, 2.0),
                Complex64::new(3.0, 30.0),
            ] {
                let a = nalgebra::DMatrix::from_fn(n, n, |i, j| {
                    s * s * d.m[(i, j)] + s * d.c[(i, j)] + Complex64::new(d.k[(i, j)], 0.0)
                });
                let inv = a.try_inverse().unwrap();
                let g = Green::of_chain(&u, s);
                let scale = inv.iter().map(|z| z.norm()).fold(0.0, f64::max);
                for i in 1..=n {
                    for j in 1..=n {
                        let e = (g.entry(i, j) - inv[(i - 1, j - 1)]).norm();
                        assert!(e <= 1e-12 * scale, "{} s={s} ({i},{j})", chain.damping());
                    }
                }
                let sp = (g.bilinear(Probe::Diff(3), Probe::Diff(3))
                    - (inv[(2, 2)] - inv[(2, 3)] - inv[(3, 2)] + inv[(3, 3)]))
                    .norm();
                assert!(sp <= 1e-12 * scale);
            }
        }
    }
}
