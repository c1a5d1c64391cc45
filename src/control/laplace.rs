//! Laplace-domain closed forms of the suppression scheme, evaluated without
//! overflow for any `n` and any `s`.
//!
//! Every signal is `coef U_a(c) / U_b(c) = coef sinh((a+1) lambda) / sinh((b+1) lambda)`
//! with `c = cosh(lambda) = 1 + (m s^2 + d s)/(2k)` ([`URatio`]). With
//! `q = exp(-lambda)`, `Re lambda >= 0`:
//!
//! `sinh((a+1) l) / sinh((b+1) l) = q^{b-a} expm1(-2(a+1) l) / expm1(-2(b+1) l)`,
//!
//! every factor at most 1 in size (for `|q| <= 1`), so nothing overflows
//! (for `n = 10^4` at `s = 300` the value underflows to 0, which is its
//! correctly rounded value). At `lambda = 0` (`s = 0`, or `s = -d/m`) the
//! limit `(a+1)/(b+1)` is used.
//!
//! ```
//! use springmass::control::{Suppression, Signal};
//! use springmass::Complex64;
//! let sup = Suppression::new(19, 2.0, 0.1, 1.5, 1.0)?;
//! let f = sup.ratio(Signal::F).eval(&sup, Complex64::new(0.3, 1.2))?;
//! assert!(f.norm().is_finite());
//! let big = Suppression::paper(10_000)?;
//! assert_eq!(big.ratio(Signal::F).eval(&big, 300.0_f64)?, 0.0); // underflow, no overflow
//! # Ok::<(), springmass::Error>(())
//! ```

use super::Suppression;
use crate::error::{Error, Result};
use crate::scalar::Scalar;
use num_complex::Complex64;

/// `coef * U_a(c) / U_b(c)` with `c = cosh(lambda)`, `a < b`: a proper
/// rational function of `s` (numerator degree `2a`, denominator `2b`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct URatio {
    /// Degree of the numerator Chebyshev polynomial.
    pub a: usize,
    /// Degree of the denominator Chebyshev polynomial (`b > a`).
    pub b: usize,
    /// Constant factor (carries `gamma`, the sign and `1/k` for displacements).
    pub coef: f64,
}

/// `lambda(s)` with `cosh(lambda) = 1 + (mass s^2 + d s)/(2k)`, computed as
/// `2 asinh( sqrt(s) sqrt((mass s + d)/k) / 2 )` (no cancellation at small
/// `|s|`); `Re lambda >= 0` for `Re s >= 0`.
pub fn lambda<T: Scalar>(k: f64, mass: f64, d: f64, s: T) -> T {
    let inner = (s.scale(mass) + T::from_f64(d)).scale(1.0 / k);
    let root = s.sqrt() * inner.sqrt();
    root.scale(0.5).asinh().scale(2.0)
}

impl URatio {
    /// Value at `s` for the problem's `k`, `m`, `d`.
    ///
    /// # Errors
    /// See [`URatio::eval_with`].
    pub fn eval<T: Scalar>(&self, sup: &Suppression, s: T) -> Result<T> {
        self.eval_with(sup.k(), sup.mass(), sup.d(), s)
    }

    /// Value at `s` (real or complex, any half plane) for given `k`, `mass`, `d`.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] for a non-finite `s`; [`Error::Singular`]
    /// at a pole (`U_b(c(s)) = 0`, on the imaginary axis when `d = 0`).
    pub fn eval_with<T: Scalar>(&self, k: f64, mass: f64, d: f64, s: T) -> Result<T> {
        if !s.is_finite() {
            return Err(Error::invalid("s", format!("{:?}", s.to_c64()), "finite"));
        }
        let singular = || Error::Singular {
            s: format!("{}", s.to_c64()),
        };
        if s.re_f64() >= 0.0 {
            let lam = lambda(k, mass, d, s.clone());
            let v = self.of_lambda(lam).ok_or_else(singular)?;
            return if v.is_finite() {
                Ok(v)
            } else {
                Err(singular())
            };
        }
        // Left half plane: complex lambda, branch with Re lambda >= 0.
        let sc = s.to_c64();
        let mut lam = lambda(k, mass, d, sc);
        if lam.re < 0.0 {
            lam = -lam;
        }
        let v = self.of_lambda(lam).ok_or_else(singular)?;
        if !Scalar::is_finite(&v) {
            return Err(singular());
        }
        // A real type at real s < 0: the value is real (up to rounding).
        Ok(T::from_c64(v).unwrap_or_else(|| T::from_f64(v.re)))
    }

    /// `coef sinh((a+1) l)/sinh((b+1) l)` for `Re l >= 0`; `None` at a pole.
    pub fn of_lambda<T: Scalar>(&self, lam: T) -> Option<T> {
        let (a1, b1) = ((self.a + 1) as f64, (self.b + 1) as f64);
        if lam.is_zero() {
            return Some(T::from_f64(self.coef * a1 / b1));
        }
        let den = lam.scale(-2.0 * b1).expm1();
        if den.is_zero() {
            return None;
        }
        let num = lam.scale(-2.0 * a1).expm1();
        let q = lam.scale(-((self.b - self.a) as f64)).exp();
        Some((q * num / den).scale(self.coef))
    }

    /// Reference evaluation by the Chebyshev three-term recurrence in `c`
    /// (fine for small `b` and moderate `|c|`; overflows for large `b |lambda|`).
    pub fn eval_recurrence(&self, k: f64, mass: f64, d: f64, s: Complex64) -> Complex64 {
        let c = 1.0 + (s * s * mass + s * d) / (2.0 * k);
        let (mut u0, mut u1) = (Complex64::new(1.0, 0.0), 2.0 * c);
        let mut ua = u0;
        let mut ub = u0;
        for p in 0..=self.b {
            let up = if p == 0 { u0 } else { u1 };
            if p == self.a {
                ua = up;
            }
            if p == self.b {
                ub = up;
            }
            if p >= 1 {
                let u2 = 2.0 * c * u1 - u0;
                u0 = u1;
                u1 = u2;
            }
        }
        self.coef * ua / ub
    }
}

#[cfg(test)]
mod tests {
    use super::super::{Scheme, Signal, Suppression};
    use super::*;
    use nalgebra::{DMatrix, DVector};

    /// Dense solve of the `(n+1)`-mass uniform chain with point loads.
    fn dense(sup: &Suppression, s: Complex64, loads: &[(usize, Complex64)]) -> DVector<Complex64> {
        let n1 = sup.n() + 1;
        let (k, m, d) = (sup.k(), sup.mass(), sup.d());
        let mut a = DMatrix::<Complex64>::zeros(n1, n1);
        for i in 0..n1 {
            a[(i, i)] = s * s * m + s * d + 2.0 * k;
            if i + 1 < n1 {
                a[(i, i + 1)] = (-k).into();
                a[(i + 1, i)] = (-k).into();
            }
        }
        let mut b = DVector::<Complex64>::zeros(n1);
        for &(at, v) in loads {
            b[at - 1] += v;
        }
        a.lu().solve(&b).unwrap()
    }

    fn ss() -> Vec<Complex64> {
        vec![
            Complex64::new(0.05, 0.0),
            Complex64::new(0.7, 0.0),
            Complex64::new(3.0, 0.0),
            Complex64::new(0.5, 2.0),
            Complex64::new(0.1, 0.7),
            Complex64::new(1.0, -5.0),
            Complex64::new(0.02, 1.3),
            Complex64::new(-0.01, 0.9),
        ]
    }

    #[test]
    fn general_k_m_theorem_and_corollary_against_dense_solve() {
        for &n in &[2usize, 3, 4, 7, 19, 40] {
            for &(k, m, d, gamma) in &[
                (1.0, 1.0, 0.1, 1.0),
                (2.5, 0.3, 0.0, 1.0),
                (0.7, 4.0, 3.0, -2.0),
                (10.0, 1.0, 5.0, 0.5),
            ] {
                let sup = Suppression::new(n, k, d, m, gamma).unwrap();
                for s in ss() {
                    let ev = |sig| sup.ratio(sig).eval(&sup, s).unwrap();
                    let (f, g, f1) = (ev(Signal::F), ev(Signal::G), ev(Signal::F1));
                    let y = dense(&sup, s, &[(1, gamma.into())]);
                    let scale = y.iter().map(|z| z.norm()).fold(0.0, f64::max);
                    // Theorem 3.1
                    let x = dense(&sup, s, &[(1, gamma.into()), (n, f), (n - 1, g)]);
                    assert!(
                        x[n].norm() <= 1e-12 * scale,
                        "n={n} k={k} s={s}: X_n+1 = {}",
                        x[n]
                    );
                    assert!((x[0] - y[0]).norm() <= 1e-12 * scale, "n={n} s={s}: X1");
                    // Corollary 3.2
                    let x1 = dense(&sup, s, &[(1, gamma.into()), (n, f1)]);
                    assert!(x1[n].norm() <= 1e-12 * scale && x1[n - 1].norm() <= 1e-12 * scale);
                    assert!((x1[0] - ev(Signal::X1Single)).norm() <= 1e-12 * scale);
                    // displacement closed forms carry 1/k
                    assert!((y[0] - ev(Signal::Y1)).norm() <= 1e-12 * scale);
                    assert!((y[n] - ev(Signal::YEnd)).norm() <= 1e-12 * scale);
                    // the recurrence form
                    for sig in [Signal::F, Signal::G, Signal::F1, Signal::Y1] {
                        let r = sup.ratio(sig).eval_recurrence(k, m, d, s);
                        assert!((r - ev(sig)).norm() <= 1e-10 * r.norm().max(1e-300));
                    }
                }
            }
        }
        assert_eq!(
            Suppression::paper(4).unwrap().controls(Scheme::Cloak).len(),
            2
        );
    }

    #[test]
    fn real_matches_complex_and_no_overflow() {
        let sup = Suppression::paper(19).unwrap();
        for &s in &[0.0, 1e-8, 1e-3, 0.5, 10.0, 300.0, 1e6, -0.02] {
            for sig in [Signal::F, Signal::G, Signal::F1, Signal::Y1, Signal::YEnd] {
                let r = sup.ratio(sig);
                let vr: f64 = r.eval(&sup, s).unwrap();
                let vc: Complex64 = r.eval(&sup, Complex64::new(s, 0.0)).unwrap();
                assert!(
                    (vr - vc.re).abs() <= 1e-13 * vr.abs().max(1e-300),
                    "{s} {sig:?}"
                );
            }
        }
        // static limit: F(0) = -gamma 3/(n+2)
        let f0: f64 = sup.ratio(Signal::F).eval(&sup, 0.0).unwrap();
        assert!((f0 + 3.0 / 21.0).abs() < 1e-15);
        for &n in &[10_000usize, 1_000_000] {
            let big = Suppression::paper(n).unwrap();
            for &s in &[300.0, 1e-6, 1e-3] {
                let v: f64 = big.ratio(Signal::G).eval(&big, s).unwrap();
                assert!(v.is_finite() && v >= 0.0);
                let c: Complex64 = big
                    .ratio(Signal::F)
                    .eval(&big, Complex64::new(s, 50.0))
                    .unwrap();
                assert!(Scalar::is_finite(&c));
            }
        }
    }

    #[test]
    fn poles_of_undamped_chain_are_singular() {
        let sup = Suppression::new(4, 1.0, 0.0, 1.0, 1.0).unwrap();
        // U_5(c) = 0 at c = cos(pi/6): s = i sqrt(2 (1 - c))
        let w = (2.0 * (1.0 - (std::f64::consts::PI / 6.0).cos())).sqrt();
        let r = sup.ratio(Signal::F).eval(&sup, Complex64::new(0.0, w));
        match r {
            Err(Error::Singular { .. }) => {}
            Ok(v) => assert!(v.norm() > 1e12, "{v}"),
            Err(e) => panic!("{e}"),
        }
        assert!(sup
            .ratio(Signal::F)
            .eval(&sup, Complex64::new(f64::NAN, 0.0))
            .is_err());
    }
}
