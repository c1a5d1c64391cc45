//! The large-defect locator (4.17): no mass needed, valid for `m >> mass`.
//!
//! As `m -> inf` the defect pins mass `j`, and mass 1 sees a uniform chain of
//! `j - 1` masses: `k X_1 / gamma = q E(j-1) / E(j)`. Hence
//!
//! `delta := q - k X_1 / gamma = q^{2j-1} E(1) / E(j)`, and exactly
//! `j = ln(1 + 2 sinh(lambda) / delta) / (2 lambda)`,
//!
//! which is the paper's (4.17) `j = acosh((cosh l - x) / sqrt(x^2 - 2 x cosh l + 1)) / l`
//! (`k = 1`) after the identity `x^2 - 2 x cosh l + 1 = (e^l - x) delta`. The
//! rewritten form takes one subtraction (`delta`), the printed form two
//! cancelling sums of order 1 (`cosh l - x` is harmless, the square root's
//! argument is not). Both need `delta`, whose relative size is
//! `~ q^{2(j-1)} ~ s^{-4(j-1)}`: with `X_1` rounded to 16 digits, `delta` keeps
//! only `16 - 4 (j-1) log10 s` of them, and no rewriting can restore the rest.
//! The locator therefore estimates `delta`'s error, returns `BelowFloor`
//! instead of NaN/inf, and needs extended-precision data for the paper's
//! 7-digit values at `s = 50`.
//!
//! For a finite heavy mass the estimate is biased: `j(s) ~ j + L / (2 lambda)`,
//! `L = ln(m / (m - mass))` (0.0184 for `m = 4` at `s = 50`: the paper's
//! 3.018423). Auto mode removes it by extrapolating in `1/lambda` from two
//! values of `s` and checks the extrapolation against a third.

use super::data::Point;
use super::model::Model;
use super::{Estimate, Status};
use crate::precision::RealScalar;

/// `k X_1 / gamma` and its absolute error floor.
fn scaled<T: RealScalar>(model: &Model<T>, p: &Point<T>, q: &T) -> (T, f64) {
    let kx = model.k().clone() * p.x.clone() / model.gamma().clone();
    let floor = model.k().to_f64() * p.err / model.gamma().abs().to_f64()
        + 8.0 * T::epsilon() * (q.to_f64() + kx.abs().to_f64());
    (kx, floor)
}

/// The rewritten (4.17) at one point.
pub(crate) fn stable_point<T: RealScalar>(model: &Model<T>, p: &Point<T>) -> Estimate<T> {
    let at = model.at(&p.s);
    let mut e = Estimate::empty(&at);
    let (kx, floor) = scaled(model, p, &at.q);
    let delta = at.q.clone() - kx;
    e.signal = (delta.ln_abs_f64() - at.q.ln_abs_f64()).exp();
    e.floor = floor / at.q.to_f64();
    let df = delta.to_f64();
    if delta.abs().to_f64() <= 2.0 * floor || delta.is_zero() {
        e.status = Status::BelowFloor;
        return e;
    }
    if df < 0.0 {
        e.status = Status::WrongSign;
        return e;
    }
    let r = at.two_sinh() / delta.clone();
    let two_l = at.lambda.clone().scale(2.0);
    let j = r.ln_1p() / two_l.clone();
    let rf = r.to_f64();
    let frac = if rf.is_finite() { rf / (1.0 + rf) } else { 1.0 };
    e.sigma = (floor / df) / two_l.to_f64() * frac;
    let jf = j.to_f64();
    e.status = if jf.is_finite() && jf >= 0.5 && jf <= model.n() as f64 + 0.5 {
        Status::Ok
    } else {
        Status::OutOfRange
    };
    e.j = Some(j);
    e
}

/// (4.17) exactly as printed (with `x = k X_1 / gamma` for general `k`), for
/// comparison: non-finite results are reported as [`Status::NonFinite`].
pub(crate) fn paper_point<T: RealScalar>(model: &Model<T>, p: &Point<T>) -> Estimate<T> {
    let at = model.at(&p.s);
    let mut e = Estimate::empty(&at);
    let (x, floor) = scaled(model, p, &at.q);
    let c = at.cosh.clone();
    let a = c.clone() - x.clone();
    let b = x.clone() * x.clone() - (x.clone() * c.clone()).scale(2.0) + T::one();
    let bf = b.to_f64();
    // error of b: from the data and from rounding its three O(1) terms
    let db = 2.0 * (x.clone() - c.clone()).abs().to_f64() * floor
        + 8.0
            * T::epsilon()
            * (x.clone() * x.clone() + (x.abs() * c.clone()).scale(2.0) + T::one()).to_f64();
    e.signal = bf.abs();
    e.floor = db;
    let y = a / b.sqrt();
    let j = y.acosh() / at.lambda.clone();
    let jf = j.to_f64();
    if !(jf.is_finite() && bf > 0.0) {
        e.status = Status::NonFinite;
        return e;
    }
    e.sigma = 0.5 * (db / bf) / at.lambda.to_f64();
    e.status = if bf <= 2.0 * db {
        Status::BelowFloor
    } else if jf >= 0.5 && jf <= model.n() as f64 + 0.5 {
        Status::Ok
    } else {
        Status::OutOfRange
    };
    e.j = Some(j);
    e
}

#[cfg(all(test, feature = "bigfloat"))]
mod tests {
    use super::*;
    use crate::chain::{Chain, Defect};
    use crate::detect::locate::LaplaceData;
    use crate::precision::{with_precision, BigReal};

    #[test]
    fn pinned_mass_gives_j_exactly_and_forms_agree() {
        // m -> infinity pins mass j: the rewritten (4.17) is then exact
        with_precision(256, || {
            for &(n, j) in &[(5usize, 3usize), (20, 2), (3, 1)] {
                let c = Chain::paper(n)
                    .unwrap()
                    .with_defect(Defect::Mass { at: j, m: 1e30 })
                    .unwrap();
                let model: Model<BigReal> = Model::from_chain(&c);
                let data = LaplaceData::<BigReal>::from_chain(&c, &[2.0, 10.0]).unwrap();
                for p in data.points() {
                    let e = stable_point(&model, p);
                    let q = paper_point(&model, p);
                    assert_eq!(e.status, Status::Ok);
                    let jv = e.j.unwrap();
                    // 1/m = 1e-30 residual: j exact to ~1e-30 / (2 lambda)
                    assert!((jv.to_f64() - j as f64).abs() < 1e-25, "{n} {j}: {jv:?}");
                    assert!((jv - q.j.unwrap()).abs().to_f64() < 1e-60);
                }
            }
        });
    }

    #[test]
    fn light_defect_is_wrong_sign_not_nan() {
        let c = Chain::paper(5)
            .unwrap()
            .with_defect(Defect::Mass { at: 2, m: 0.5 })
            .unwrap();
        let model: Model<f64> = Model::from_chain(&c);
        let data = LaplaceData::<f64>::from_chain(&c, &[3.0]).unwrap();
        let e = stable_point(&model, &data.points()[0]);
        assert_eq!(e.status, Status::WrongSign);
        assert!(e.j.is_none());
    }
}
