//! O(n) reference solver: the full tridiagonal system `K(s) X = gamma e_1` for
//! any mass, spring and damper profile, by Gaussian elimination with partial
//! pivoting (the LAPACK `gtsv` scheme, which stays stable for complex `s`,
//! where `K(s)` is complex symmetric but not diagonally dominant).
//!
//! It knows nothing of Green's functions or defects, which makes it the
//! independent check of the closed form and the Woodbury updates, and the
//! fallback for chains whose "defects" are not few.
//!
//! For real `s` the elimination is written in *excess-stiffness* form,
//! `E_i = m_i s^2 + d_i s + kappa_i E_{i+1} / (E_{i+1} + kappa_i)`, `X_1 = gamma / (E_1 + kappa_0)`,
//! `X_{i+1} = kappa_i X_i / (E_{i+1} + kappa_i)`: every term is positive, and the
//! small part `m s^2 + d s` is never added to `2k` (which at `s = 1e-6` would
//! round away eight digits of it). `K(s)` is symmetric positive definite there,
//! so no pivoting is needed. Complex `s` uses the pivoted `gtsv` scheme.

use crate::chain::Chain;
use crate::error::{Error, Result};
use crate::scalar::Scalar;

/// Displacements `X_1..X_n` (0-based vector) of `chain` at `s`, all masses at once.
///
/// Cost O(n) time and memory.
///
/// # Errors
/// `s` not finite or `Re s < 0`; [`Error::Singular`] when `K(s)` is singular.
///
/// ```
/// use springmass::{Chain, forward::tridiag::solve_all};
/// let x = solve_all(&Chain::paper(20)?, 0.5_f64)?;
/// assert_eq!(x.len(), 20);
/// # Ok::<(), springmass::Error>(())
/// ```
pub fn solve_all<T: Scalar>(chain: &Chain, s: T) -> Result<Vec<T>> {
    super::check_s(&s)?;
    if s.to_c64().im == 0.0 {
        return solve_all_real(chain, s);
    }
    let n = chain.n();
    let c = chain.coefficients();
    let (m, d, kd) = (&c.m, c.d_diag(), c.k_diag());
    let s2 = s.clone() * s.clone();
    // diagonal, super/sub diagonal (symmetric: dl = du = -kappa_i, i = 1..n-1)
    let diag: Vec<T> = (0..n)
        .map(|i| s2.scale(m[i]) + s.scale(d[i]) + T::from_f64(kd[i]))
        .collect();
    let dl: Vec<T> = (0..n.saturating_sub(1))
        .map(|i| {
            // -k_i exactly as before the spring-parallel dampers (no -0 imaginary part)
            if c.c[i + 1] == 0.0 {
                T::from_f64(-c.k[i + 1])
            } else {
                -kappa(&c, i + 1, &s)
            }
        })
        .collect();
    let mut b: Vec<T> = vec![T::zero(); n];
    b[0] = T::from_f64(chain.gamma());
    solve_general(diag, dl, b).ok_or_else(|| Error::Singular {
        s: format!("{}", s.to_c64()),
    })
}

/// Solve the symmetric tridiagonal system with diagonal `diag` and
/// off-diagonal `off` (`n - 1`) for the right side `b`, by Gaussian
/// elimination with partial pivoting (LAPACK `gtsv`); `None` when it is
/// singular or a value is not finite.
pub fn solve_general<T: Scalar>(mut diag: Vec<T>, off: Vec<T>, mut b: Vec<T>) -> Option<Vec<T>> {
    let n = diag.len();
    let mut dl = off;
    let mut du = dl.clone();
    let mut du2: Vec<T> = vec![T::zero(); n.saturating_sub(2)];
    for i in 0..n.saturating_sub(1) {
        if diag[i].magnitude() >= dl[i].magnitude() {
            // no interchange
            if diag[i].is_zero() {
                return None;
            }
            let fact = dl[i].clone() / diag[i].clone();
            diag[i + 1] = diag[i + 1].clone() - fact.clone() * du[i].clone();
            b[i + 1] = b[i + 1].clone() - fact * b[i].clone();
            dl[i] = T::zero();
        } else {
            // interchange rows i and i+1
            let fact = diag[i].clone() / dl[i].clone();
            diag[i] = dl[i].clone();
            let temp = diag[i + 1].clone();
            diag[i + 1] = du[i].clone() - fact.clone() * temp.clone();
            if i + 2 < n {
                dl[i] = du[i + 1].clone();
                du[i + 1] = -(fact.clone() * dl[i].clone());
            } else {
                dl[i] = T::zero();
            }
            du[i] = temp;
            let bi = b[i].clone();
            b[i] = b[i + 1].clone();
            b[i + 1] = bi - fact * b[i + 1].clone();
        }
        if i + 2 < n {
            du2[i] = dl[i].clone();
        }
    }
    if diag[n - 1].is_zero() {
        return None;
    }
    // back substitution: U has diag, du, du2
    let mut x = vec![T::zero(); n];
    x[n - 1] = b[n - 1].clone() / diag[n - 1].clone();
    if n >= 2 {
        x[n - 2] = (b[n - 2].clone() - du[n - 2].clone() * x[n - 1].clone()) / diag[n - 2].clone();
    }
    for i in (0..n.saturating_sub(2)).rev() {
        x[i] =
            (b[i].clone() - du[i].clone() * x[i + 1].clone() - du2[i].clone() * x[i + 2].clone())
                / diag[i].clone();
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// Real `s`: excess-stiffness elimination (see the module docs).
fn solve_all_real<T: Scalar>(chain: &Chain, s: T) -> Result<Vec<T>> {
    let n = chain.n();
    let c = chain.coefficients();
    let (m, k, d, g) = (&c.m, &c.k, &c.d, &c.g);
    let s2 = s.clone() * s.clone();
    // e[i] = E_{i+1} (0-based), dd[i] = D_{i+1} = E + kappa_{i}
    let mut e = vec![T::zero(); n];
    let mut tail = kappa(&c, n, &s); // kappa_n * (E_{n+1}/D_{n+1}) with the wall ratio 1
    for i in (0..n).rev() {
        e[i] = s2.scale(m[i]) + s.scale(d[i]) + T::from_f64(g[i]) + tail;
        // spring (and its damper) to the left of mass i+1
        tail = if c.c[i] == 0.0 {
            let kap = k[i];
            e[i].clone().scale(kap) / (e[i].clone() + T::from_f64(kap))
        } else {
            let kap = kappa(&c, i, &s);
            e[i].clone() * kap.clone() / (e[i].clone() + kap)
        };
    }
    let mut x = Vec::with_capacity(n);
    let mut xi = T::from_f64(chain.gamma()) / (e[0].clone() + kappa(&c, 0, &s));
    x.push(xi.clone());
    for i in 1..n {
        xi = if c.c[i] == 0.0 {
            xi.scale(k[i]) / (e[i].clone() + T::from_f64(k[i]))
        } else {
            let kap = kappa(&c, i, &s);
            xi * kap.clone() / (e[i].clone() + kap)
        };
        x.push(xi.clone());
    }
    if x.iter().any(|v| !v.is_finite()) {
        return Err(Error::Singular {
            s: format!("{}", s.to_c64()),
        });
    }
    Ok(x)
}

/// `kappa_i(s) = k_i + c_i s`, spring `i` and the damper beside it.
fn kappa<T: Scalar>(c: &crate::chain::Coefficients, i: usize, s: &T) -> T {
    if c.c[i] == 0.0 {
        T::from_f64(c.k[i])
    } else {
        T::from_f64(c.k[i]) + s.scale(c.c[i])
    }
}

/// `X_observe(s)` by the O(n) solver (1-based `observe`).
pub fn solve<T: Scalar>(chain: &Chain, s: T, observe: usize) -> Result<T> {
    chain.check_observe(observe)?;
    Ok(solve_all(chain, s)?.swap_remove(observe - 1))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenes;
    use num_complex::Complex64;

    fn dense(chain: &Chain, s: Complex64) -> Vec<Complex64> {
        let n = chain.n();
        let c = chain.coefficients();
        let (m, k, d, g) = (&c.m, &c.k, &c.d, &c.g);
        let mut a = nalgebra::DMatrix::<Complex64>::zeros(n, n);
        for i in 0..n {
            a[(i, i)] = s * s * m[i] + s * d[i] + g[i] + k[i] + k[i + 1];
            if i + 1 < n {
                a[(i, i + 1)] = (-k[i + 1]).into();
                a[(i + 1, i)] = (-k[i + 1]).into();
            }
        }
        let mut b = nalgebra::DVector::<Complex64>::zeros(n);
        b[0] = chain.gamma().into();
        a.lu().solve(&b).unwrap().iter().copied().collect()
    }

    #[test]
    fn matches_dense_lu() {
        let chain = scenes::paper_with(
            12,
            "mass:1:1e3 spring:0:0.3 spring:12:7 damper:5:2 mass:12:1e-3",
        )
        .unwrap();
        for s in [
            Complex64::new(0.3, 0.0),
            Complex64::new(0.0, 1.3),
            Complex64::new(0.2, 40.0),
            Complex64::new(5.0, -2.0),
        ] {
            let x = solve_all(&chain, s).unwrap();
            let r = dense(&chain, s);
            let scale = r.iter().map(|z| z.norm()).fold(0.0, f64::max);
            for i in 0..12 {
                assert!((x[i] - r[i]).norm() <= 1e-12 * scale, "s={s} i={i}");
            }
        }
    }

    #[test]
    fn n_one() {
        let c = Chain::paper(1).unwrap();
        let x = solve(&c, 2.0, 1).unwrap();
        assert!((x - 1.0 / (4.0 + 0.2 + 2.0)).abs() < 1e-15);
    }

    #[test]
    fn singular_undamped_resonance_is_an_error() {
        // n = 1, k = 1, m = 1, d = 0: pole at s = i sqrt(2)
        let c = Chain::new(1).unwrap();
        let r = solve(&c, Complex64::new(0.0, 2f64.sqrt()), 1);
        assert!(r.is_err() || r.unwrap().norm() > 1e14);
    }
}

#[cfg(test)]
mod damping_tests {
    use super::*;
    use crate::chain::dense_ref;
    use num_complex::Complex64;

    #[test]
    fn every_damping_model_matches_the_dense_solve() {
        for chain in dense_ref::model_chains() {
            for s in [
                Complex64::new(0.3, 0.0),
                Complex64::new(2.5, 0.0),
                Complex64::new(0.2, 1.3),
                Complex64::new(0.05, 4.0),
            ] {
                let x = solve_all(&chain, s).unwrap();
                let scale = x.iter().map(|z| z.norm()).fold(0.0, f64::max);
                for (i, xi) in x.iter().enumerate() {
                    let want = dense_ref::solve(&chain, s, i + 1);
                    assert!(
                        (xi - want).norm() <= 1e-12 * scale,
                        "{} s={s} i={i}",
                        chain.damping()
                    );
                }
                if s.im == 0.0 {
                    let xr = solve_all(&chain, s.re).unwrap();
                    for (a, b) in xr.iter().zip(&x) {
                        assert!((a - b.re).abs() <= 1e-12 * scale);
                    }
                }
            }
        }
    }
}
