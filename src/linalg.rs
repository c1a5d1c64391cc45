//! Small dense linear algebra over any [`Scalar`] (the Woodbury capacitance
//! systems are `k x k` with `k` the number of defects, so a plain Gaussian
//! elimination with partial pivoting is the right tool; nalgebra's LU needs
//! `ComplexField`, which the arbitrary-precision type does not implement).

use crate::scalar::Scalar;

/// Partial pivoting of column `col` of the row-major `k x k` system
/// `(a, b)`: the row at or below `col` whose entry has the largest
/// `magnitude` is swapped into row `col`. `false` when that magnitude is
/// zero or not finite (the elimination stops).
#[inline(always)]
pub(crate) fn pivot<T>(
    a: &mut [T],
    b: &mut [T],
    k: usize,
    col: usize,
    magnitude: impl Fn(&T) -> f64,
) -> bool {
    let mut piv = col;
    let mut best = magnitude(&a[col * k + col]);
    for r in col + 1..k {
        let m = magnitude(&a[r * k + col]);
        if m > best {
            best = m;
            piv = r;
        }
    }
    if best == 0.0 || !best.is_finite() {
        return false;
    }
    if piv != col {
        for c in 0..k {
            a.swap(col * k + c, piv * k + c);
        }
        b.swap(col, piv);
    }
    true
}

/// Solve `A x = b` in place for a row-major `k x k` matrix `a`; on return `b`
/// holds `x`. Partial pivoting by modulus.
///
/// Returns `false` (and leaves `b` unspecified) when a pivot is exactly zero
/// or not finite.
///
/// ```
/// use springmass::linalg::solve_in_place;
/// let mut a = vec![2.0, 1.0, 1.0, 3.0];
/// let mut b = vec![3.0, 5.0];
/// assert!(solve_in_place(&mut a, &mut b, 2));
/// assert!((b[0] - 0.8).abs() < 1e-15 && (b[1] - 1.4).abs() < 1e-15);
/// ```
pub fn solve_in_place<T: Scalar>(a: &mut [T], b: &mut [T], k: usize) -> bool {
    debug_assert_eq!(a.len(), k * k);
    debug_assert_eq!(b.len(), k);
    for col in 0..k {
        if !pivot(a, b, k, col, T::magnitude) {
            return false;
        }
        let p = a[col * k + col].clone();
        for r in col + 1..k {
            let f = a[r * k + col].clone() / p.clone();
            if f.is_zero() {
                continue;
            }
            for c in col + 1..k {
                let v = a[col * k + c].clone();
                a[r * k + c] = a[r * k + c].clone() - f.clone() * v;
            }
            let bc = b[col].clone();
            b[r] = b[r].clone() - f * bc;
            a[r * k + col] = T::zero();
        }
    }
    for row in (0..k).rev() {
        let mut acc = b[row].clone();
        for c in row + 1..k {
            acc = acc - a[row * k + c].clone() * b[c].clone();
        }
        b[row] = acc / a[row * k + row].clone();
    }
    true
}

/// Iterations allowed to an SVD (a few per singular value suffice).
pub const SVD_MAX_ITERATIONS: usize = 10_000;

/// The SVD of `m` (nalgebra's `svd`, at its tolerance), or `None` when an
/// entry is not finite or it has not converged within
/// [`SVD_MAX_ITERATIONS`]: nalgebra's `svd` iterates without a cap and never
/// ends on non-finite entries.
///
/// ```
/// use nalgebra::DMatrix;
/// use springmass::linalg::svd_checked;
/// let svd = svd_checked(DMatrix::from_row_slice(2, 2, &[3.0, 0.0, 0.0, 2.0]), false, false).unwrap();
/// assert_eq!(svd.singular_values.as_slice(), &[3.0, 2.0]);
/// assert!(svd_checked(DMatrix::from_row_slice(1, 1, &[f64::NAN]), true, true).is_none());
/// ```
pub fn svd_checked<T>(
    m: nalgebra::DMatrix<T>,
    compute_u: bool,
    compute_v: bool,
) -> Option<nalgebra::linalg::SVD<T, nalgebra::Dyn, nalgebra::Dyn>>
where
    T: nalgebra::ComplexField<RealField = f64>,
{
    if !m.iter().all(|v| v.is_finite()) {
        return None;
    }
    // nalgebra's own tolerance (`svd` uses 5 machine epsilons): the same
    // answer as `svd` wherever that ends
    nalgebra::linalg::SVD::try_new(
        m,
        compute_u,
        compute_v,
        5.0 * f64::EPSILON,
        SVD_MAX_ITERATIONS,
    )
}

/// Minimise a unimodal `f` on `[a, b]` by golden-section search; returns `(x, f(x))`.
pub fn golden(mut f: impl FnMut(f64) -> f64, a: f64, b: f64, iters: usize) -> (f64, f64) {
    let r = (5f64.sqrt() - 1.0) / 2.0;
    let (mut a, mut b) = (a, b);
    let mut c = b - r * (b - a);
    let mut d = a + r * (b - a);
    let mut fc = f(c);
    let mut fd = f(d);
    for _ in 0..iters {
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - r * (b - a);
            fc = f(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + r * (b - a);
            fd = f(d);
        }
    }
    if fc < fd {
        (c, fc)
    } else {
        (d, fd)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use num_complex::Complex64;

    #[test]
    fn needs_pivoting() {
        let mut a = vec![0.0, 1.0, 1.0, 0.0];
        let mut b = vec![2.0, 3.0];
        assert!(solve_in_place(&mut a, &mut b, 2));
        assert_eq!(b, vec![3.0, 2.0]);
        let mut s = vec![1.0, 2.0, 2.0, 4.0];
        let mut b = vec![1.0, 1.0];
        assert!(!solve_in_place(&mut s, &mut b, 2));
    }

    #[test]
    fn complex_random_against_nalgebra() {
        let k = 5;
        let mut a: Vec<Complex64> = (0..k * k)
            .map(|i| {
                Complex64::new(
                    ((i * 7 + 3) % 11) as f64 - 5.0,
                    ((i * 5 + 1) % 7) as f64 - 3.0,
                )
            })
            .collect();
        let b: Vec<Complex64> = (0..k).map(|i| Complex64::new(i as f64, 1.0)).collect();
        let m = nalgebra::DMatrix::from_row_slice(k, k, &a);
        let x_ref = m
            .lu()
            .solve(&nalgebra::DVector::from_vec(b.clone()))
            .unwrap();
        let mut x = b;
        assert!(solve_in_place(&mut a, &mut x, k));
        for i in 0..k {
            assert!((x[i] - x_ref[i]).norm() < 1e-12);
        }
    }
}
