//! One-dimensional root finding in any [`RealScalar`]: a scan for sign
//! changes, then the Illinois variant of regula falsi (superlinear, never
//! leaves its bracket).

use crate::precision::RealScalar;

/// Refine a bracket `[a, b]` with `g(a) g(b) < 0` until `|b - a| <= tol`.
pub fn refine<T: RealScalar>(g: &impl Fn(&T) -> T, a: T, ga: T, b: T, gb: T, tol: f64) -> T {
    let (mut a, mut ga, mut b, mut gb) = (a, ga, b, gb);
    let mut side = 0i8;
    for _ in 0..400 {
        if (b.clone() - a.clone()).abs().to_f64() <= tol {
            break;
        }
        let denom = gb.clone() - ga.clone();
        let mut c = b.clone() - gb.clone() * (b.clone() - a.clone()) / denom;
        // keep c strictly inside (a, b); fall back to bisection
        let (lo, hi) = if a < b { (&a, &b) } else { (&b, &a) };
        if !(c.is_finite() && c > *lo && c < *hi) {
            c = (a.clone() + b.clone()).scale(0.5);
        }
        let gc = g(&c);
        if !gc.is_finite() {
            // step into the half that keeps a finite bracket
            c = (a.clone() + b.clone()).scale(0.5);
            let gm = g(&c);
            if !gm.is_finite() {
                break;
            }
            if (gm.clone() > T::zero()) == (ga.clone() > T::zero()) {
                a = c;
                ga = gm;
            } else {
                b = c;
                gb = gm;
            }
            continue;
        }
        if gc.is_zero() {
            return c;
        }
        if (gc.clone() > T::zero()) == (gb.clone() > T::zero()) {
            // c replaces b; a stays: halve ga if a stayed twice (Illinois)
            b = c;
            gb = gc;
            if side == -1 {
                ga = ga.scale(0.5);
            }
            side = -1;
        } else {
            a = c;
            ga = gc;
            if side == 1 {
                gb = gb.scale(0.5);
            }
            side = 1;
        }
    }
    let ma = ga.abs();
    let mb = gb.abs();
    if ma < mb {
        a
    } else {
        b
    }
}

/// All roots of `g` on `[lo, hi]` found by scanning `k + 1` equally spaced
/// points for sign changes (non-finite values are skipped) and refining each.
pub fn roots<T: RealScalar>(g: &impl Fn(&T) -> T, lo: f64, hi: f64, k: usize, tol: f64) -> Vec<T> {
    let k = k.max(2);
    let mut out = Vec::new();
    let mut prev: Option<(T, T)> = None;
    for i in 0..=k {
        let x = T::from_f64(lo + (hi - lo) * i as f64 / k as f64);
        let gx = g(&x);
        if !gx.is_finite() {
            prev = None;
            continue;
        }
        if gx.is_zero() {
            out.push(x.clone());
            prev = None;
            continue;
        }
        if let Some((px, pg)) = prev.take() {
            if (pg.clone() > T::zero()) != (gx.clone() > T::zero()) {
                out.push(refine(g, px, pg, x.clone(), gx.clone(), tol));
            }
        }
        prev = Some((x, gx));
    }
    out
}

/// A root near `guess` in `[lo, hi]`: brackets of growing width around the
/// guess, then a full scan of `k` points if none is found.
pub fn near<T: RealScalar>(
    g: &impl Fn(&T) -> T,
    guess: f64,
    lo: f64,
    hi: f64,
    k: usize,
    tol: f64,
) -> Option<T> {
    let mut w = 0.05;
    while w < (hi - lo) {
        let a = (guess - w).max(lo);
        let b = (guess + w).min(hi);
        let (ta, tb) = (T::from_f64(a), T::from_f64(b));
        let (ga, gb) = (g(&ta), g(&tb));
        if ga.is_finite() && gb.is_finite() && (ga.clone() > T::zero()) != (gb.clone() > T::zero())
        {
            return Some(refine(g, ta, ga, tb, gb, tol));
        }
        if a <= lo && b >= hi {
            break;
        }
        w *= 4.0;
    }
    roots(g, lo, hi, k, tol).into_iter().next()
}

pub use crate::linalg::golden;

#[cfg(all(test, feature = "bigfloat"))]
mod tests {
    use super::*;
    use crate::precision::{with_precision, BigReal};
    use crate::scalar::Scalar;

    #[test]
    fn finds_roots_in_f64_and_big() {
        let g = |x: &f64| x * x - 2.0;
        let r = roots(&g, 0.0, 3.0, 7, 1e-14);
        assert_eq!(r.len(), 1);
        assert!((r[0] - 2f64.sqrt()).abs() < 1e-14);
        let r2 = roots(&|x: &f64| (x - 1.0) * (x - 2.5), 0.0, 3.0, 12, 1e-14);
        assert_eq!(r2.len(), 2);
        assert!((near(&g, 1.3, 0.0, 3.0, 8, 1e-14).unwrap() - 2f64.sqrt()).abs() < 1e-14);
        with_precision(256, || {
            let gb = |x: &BigReal| x.clone() * x.clone() - BigReal::from_f64(2.0);
            let tol = 1e-70;
            let r = near(&gb, 1.3, 0.0, 3.0, 8, tol).unwrap();
            let err = (r.clone() * r - BigReal::from_f64(2.0)).abs().to_f64();
            assert!(err < 1e-69, "{err}");
        });
        let (x, fx) = golden(|x| (x - 0.3).powi(2), -1.0, 2.0, 80);
        assert!((x - 0.3).abs() < 1e-7 && fx < 1e-14);
    }
}
