//! Known-mass locators: the exact relation (4.7) and the paper's asymptotic
//! relation (4.10), both solved for a real position `j` at one `s`.

use super::data::Point;
use super::model::{AtS, Model};
use super::solve::{refine, roots};
use super::{root_tol, scan_points, Estimate, Status};
use crate::precision::RealScalar;

/// The defect signal `D = G_11 - X_1/gamma` and its error floor
/// `err/|gamma| + 8 eps (G_11 + |X_1/gamma|)`.
pub(crate) fn signal<T: RealScalar>(model: &Model<T>, at: &AtS<T>, p: &Point<T>) -> (T, f64) {
    let xg = p.x.clone() / model.gamma().clone();
    let d = at.g11.clone() - xg.clone();
    let floor = p.err / model.gamma().abs().to_f64()
        + 8.0 * T::epsilon() * (at.g11.to_f64() + xg.abs().to_f64());
    (d, floor)
}

/// Solve `ln|f(j)| = ln|D|` on `[1/2, n + 1/2]` and attach
/// `sigma = (floor/|D|) / |d ln f / dj|`.
///
/// Only `D` needs the working precision (it is a difference of nearly equal
/// numbers); `ln f(j) - ln|D|` is well conditioned. So the roots are isolated
/// and solved in `f64` (`ln_f64`, with `ln|D|` rounded to `f64`, which keeps
/// `D`'s relative accuracy), and only then, for a wider type, polished in `T`
/// from a tight bracket: a few evaluations in `T` instead of a full scan.
pub(crate) fn solve_at<T: RealScalar>(
    n: usize,
    at: &AtS<T>,
    d: &T,
    floor: f64,
    ln_f: impl Fn(&T) -> T,
    ln_f64: impl Fn(&f64) -> f64,
) -> Estimate<T> {
    let mut e = Estimate::empty(at);
    let g11_ln = at.g11.ln_abs_f64();
    e.signal = (d.ln_abs_f64() - g11_ln).exp();
    e.floor = floor / at.g11.to_f64();
    let dabs = d.abs();
    if dabs.to_f64() <= 2.0 * floor || d.is_zero() {
        e.status = Status::BelowFloor;
        return e;
    }
    let ln_d64 = d.ln_abs_f64();
    let g64 = |j: &f64| ln_f64(j) - ln_d64;
    let hi = n as f64 + 0.5;
    let found = roots(&g64, 0.5, hi, scan_points(n), root_tol::<f64>(n));
    let Some(&j64) = found.first() else {
        e.status = Status::OutOfRange;
        return e;
    };
    let h = 1e-4;
    let slope = ((ln_f64(&(j64 + h)) - ln_f64(&(j64 - h))) / (2.0 * h)).abs();
    let rel = floor / dabs.to_f64().max(f64::MIN_POSITIVE);
    e.sigma = if slope > 0.0 {
        rel / slope
    } else {
        f64::INFINITY
    };
    let j = if T::epsilon() < 0.5 * f64::EPSILON {
        polish(&|j: &T| ln_f(j) - dabs.ln(), j64, 0.5, hi, n)
    } else {
        T::from_f64(j64)
    };
    if found.len() > 1 {
        let last = found.last().copied().unwrap_or(j64);
        e.sigma = e.sigma.max((last - j64).abs());
        e.status = Status::Ambiguous;
    } else {
        e.status = Status::Ok;
    }
    e.j = Some(j);
    e
}

/// Refine an `f64` root `j0` of `g` in `T`: bracket `j0 -+ w` with `w` from
/// `1e-10` growing by 100 until `g` changes sign, then Illinois to the
/// type's tolerance. Falls back to `j0` if no bracket is found.
fn polish<T: RealScalar>(g: &impl Fn(&T) -> T, j0: f64, lo: f64, hi: f64, n: usize) -> T {
    let mut w = 1e-10 * j0.abs().max(1.0);
    while w < hi - lo {
        let a = T::from_f64((j0 - w).max(lo));
        let b = T::from_f64((j0 + w).min(hi));
        let (ga, gb) = (g(&a), g(&b));
        if ga.is_finite() && gb.is_finite() && (ga.clone() > T::zero()) != (gb.clone() > T::zero())
        {
            return refine(g, a, ga, b, gb, root_tol::<T>(n));
        }
        w *= 100.0;
    }
    T::from_f64(j0)
}

/// The exact locator at one point: `D = c G_1j^2 / (1 + c G_jj)` with `c = (m - mass) s^2`.
pub(crate) fn exact_point<T: RealScalar>(model: &Model<T>, p: &Point<T>, m: &T) -> Estimate<T> {
    let at = model.at(&p.s);
    let (d, floor) = signal(model, &at, p);
    let c = at.c(m);
    if !d.is_zero() && (d > T::zero()) != (c > T::zero()) && d.abs().to_f64() > 2.0 * floor {
        let mut e = Estimate::empty(&at);
        e.signal = (d.ln_abs_f64() - at.g11.ln_abs_f64()).exp();
        e.floor = floor / at.g11.to_f64();
        e.status = Status::WrongSign;
        return e;
    }
    let m64 = m.to_f64();
    let at64 = model.to_f64().at(&p.s.to_f64());
    let c64 = at64.c(&m64);
    solve_at(
        model.n(),
        &at,
        &d,
        floor,
        |j| at.ln_f_exact(j, &c),
        |j| at64.ln_f_exact(j, &c64),
    )
}

/// The asymptotic locator (4.10): `D = ((m - mass)/m) G_1j^2 / G_jj`. Its
/// model error is estimated as the distance to the exact locator on the same
/// datum and reported as `bias`.
pub(crate) fn asymptotic_point<T: RealScalar>(
    model: &Model<T>,
    p: &Point<T>,
    m: &T,
) -> Estimate<T> {
    let at = model.at(&p.s);
    let (d, floor) = signal(model, &at, p);
    let ratio = (m.clone() - model.mass().clone()) / m.clone();
    if !d.is_zero() && (d > T::zero()) != (ratio > T::zero()) && d.abs().to_f64() > 2.0 * floor {
        let mut e = Estimate::empty(&at);
        e.status = Status::WrongSign;
        return e;
    }
    let at64 = model.to_f64().at(&p.s.to_f64());
    let r64 = ratio.to_f64();
    let mut e = solve_at(
        model.n(),
        &at,
        &d,
        floor,
        |j| at.ln_f_asymptotic(j, &ratio),
        |j| at64.ln_f_asymptotic(j, &r64),
    );
    if let Some(j) = &e.j {
        let exact = exact_point(model, p, m);
        e.bias = match (&exact.j, exact.status) {
            (Some(je), Status::Ok) => (j.clone() - je.clone()).abs().to_f64(),
            _ => f64::INFINITY,
        };
    }
    e
}
