//! Known-mass locators: the exact relation (4.7) and the paper's asymptotic
//! relation (4.10), both solved for a real position `j` at one `s`.

use super::data::Point;
use super::model::{AtS, Model};
use super::solve::roots;
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

/// Solve `ln|f(j)| = ln|D|` on `[1/2, n + 1/2]` and attach `sigma = (floor/|D|) / |d ln f / dj|`.
pub(crate) fn solve_at<T: RealScalar>(
    n: usize,
    at: &AtS<T>,
    d: &T,
    floor: f64,
    ln_f: impl Fn(&T) -> T,
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
    let ln_d = dabs.ln();
    let g = |j: &T| ln_f(j) - ln_d.clone();
    let hi = n as f64 + 0.5;
    let found = roots(&g, 0.5, hi, scan_points(n), root_tol::<T>(n));
    let Some(j) = found.first().cloned() else {
        e.status = Status::OutOfRange;
        return e;
    };
    let h = 1e-4;
    let jf = j.to_f64();
    let slope =
        ((ln_f(&T::from_f64(jf + h)) - ln_f(&T::from_f64(jf - h))).to_f64() / (2.0 * h)).abs();
    let rel = floor / dabs.to_f64().max(f64::MIN_POSITIVE);
    e.sigma = if slope > 0.0 {
        rel / slope
    } else {
        f64::INFINITY
    };
    if found.len() > 1 {
        let last = found.last().map(|r| r.to_f64()).unwrap_or(jf);
        e.sigma = e.sigma.max((last - jf).abs());
        e.status = Status::Ambiguous;
    } else {
        e.status = Status::Ok;
    }
    e.j = Some(j);
    e
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
    solve_at(model.n(), &at, &d, floor, |j| at.ln_f_exact(j, &c))
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
    let mut e = solve_at(model.n(), &at, &d, floor, |j| at.ln_f_asymptotic(j, &ratio));
    if let Some(j) = &e.j {
        let exact = exact_point(model, p, m);
        e.bias = match (&exact.j, exact.status) {
            (Some(je), Status::Ok) => (j.clone() - je.clone()).abs().to_f64(),
            _ => f64::INFINITY,
        };
    }
    e
}
