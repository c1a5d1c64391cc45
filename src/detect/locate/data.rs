//! Laplace-domain data for the locators: `X_1` at a set of real `s`, each with
//! an absolute error estimate.
//!
//! The error level is part of the data (as in SimPEG), not of the locator: a
//! point from the exact model carries `err = 0` (the locators then use the
//! rounding floor of the number type), a point from a transformed time series
//! carries the transform's error estimate, and a measured series its noise.

use crate::chain::Chain;
use crate::error::{Error, Result};
use crate::forward::Forward;
use crate::precision::RealScalar;
use crate::time::series::SeriesTransform;
use crate::time::simulate::{simulate, SimOptions};
use num_complex::Complex64;

/// One datum: `X_1(s)` with an absolute error estimate `err >= 0`.
#[derive(Clone, Debug, PartialEq)]
pub struct Point<T> {
    /// Real `s > 0`.
    pub s: T,
    /// Observed `X_1(s)`.
    pub x: T,
    /// Absolute error of `x` (0: exact up to rounding in `T`).
    pub err: f64,
}

/// `X_1` at increasing real `s`, with error estimates and a label naming the source.
#[derive(Clone, Debug)]
pub struct LaplaceData<T> {
    label: String,
    points: Vec<Point<T>>,
}

/// The default grid for `--s auto` on model data: 61 values `10^(-3 + i/12)`,
/// `s = 0.001 ... 100`, twelve per decade.
pub fn default_grid() -> Vec<f64> {
    (0..=60)
        .map(|i| 10f64.powf(-3.0 + i as f64 / 12.0))
        .collect()
}

impl<T: RealScalar> LaplaceData<T> {
    /// Validated data, sorted by `s`.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] for no points, `s <= 0` or not finite, a repeated
    /// `s`, a non-finite `x`, or `err` negative or not finite.
    pub fn new(label: impl Into<String>, mut points: Vec<Point<T>>) -> Result<LaplaceData<T>> {
        if points.is_empty() {
            return Err(Error::invalid(
                "data",
                "no points",
                "at least one value of s",
            ));
        }
        for (i, p) in points.iter().enumerate() {
            if !(p.s.is_finite() && p.s > T::zero()) {
                return Err(Error::invalid(
                    format!("data[{i}].s"),
                    p.s.to_f64(),
                    "s > 0 and finite",
                ));
            }
            if !p.x.is_finite() {
                return Err(Error::invalid(
                    format!("data[{i}].x"),
                    p.x.to_f64(),
                    "finite",
                ));
            }
            if !(p.err.is_finite() && p.err >= 0.0) {
                return Err(Error::invalid(
                    format!("data[{i}].err"),
                    p.err,
                    "err >= 0 and finite",
                ));
            }
        }
        points.sort_by(|a, b| a.s.partial_cmp(&b.s).unwrap_or(std::cmp::Ordering::Equal));
        for w in points.windows(2) {
            if w[0].s == w[1].s {
                return Err(Error::invalid(
                    "data.s",
                    w[0].s.to_f64(),
                    "distinct values of s",
                ));
            }
        }
        Ok(LaplaceData {
            label: label.into(),
            points,
        })
    }

    /// Data from `f64` columns.
    ///
    /// # Errors
    /// Columns of different lengths, and everything [`LaplaceData::new`] rejects.
    pub fn from_f64(
        label: impl Into<String>,
        s: &[f64],
        x: &[f64],
        err: &[f64],
    ) -> Result<LaplaceData<T>> {
        if s.len() != x.len() || s.len() != err.len() {
            return Err(Error::invalid(
                "data",
                format!("{} s, {} x, {} err", s.len(), x.len(), err.len()),
                "columns of equal length",
            ));
        }
        let points = s
            .iter()
            .zip(x)
            .zip(err)
            .map(|((&s, &x), &err)| Point {
                s: T::from_f64(s),
                x: T::from_f64(x),
                err,
            })
            .collect();
        Self::new(label, points)
    }

    /// Exact synthetic data: `X_1(s)` of `chain` (any defects) by the closed-form
    /// Woodbury model evaluated in `T`, with `err = 0`.
    ///
    /// # Errors
    /// Invalid `s` (see [`LaplaceData::new`]).
    pub fn from_chain(chain: &Chain, s: &[f64]) -> Result<LaplaceData<T>> {
        let fwd = Forward::new(chain);
        let mut points = Vec::with_capacity(s.len());
        for &si in s {
            if !(si.is_finite() && si > 0.0) {
                return Err(Error::invalid("s", si, "s > 0 and finite"));
            }
            let st = T::from_f64(si);
            let x = fwd.eval(st.clone(), 1)?;
            points.push(Point { s: st, x, err: 0.0 });
        }
        Self::new("exact model", points)
    }

    /// Data from a sampled series `x_1(t)`: its Laplace transform at real `s`
    /// ([`crate::time::series`]), each value with the transform's error budget
    /// (discretisation + truncation + rounding) plus, when the transform was
    /// given a noise level, one standard deviation of the transformed noise.
    ///
    /// # Errors
    /// Invalid `s` and the transform's own errors.
    pub fn from_transform(
        label: impl Into<String>,
        tr: &SeriesTransform,
        s: &[f64],
    ) -> Result<LaplaceData<T>> {
        let mut points = Vec::with_capacity(s.len());
        for &si in s {
            if !(si.is_finite() && si > 0.0) {
                return Err(Error::invalid("s", si, "s > 0 and finite"));
            }
            let v = tr.eval(Complex64::new(si, 0.0))?;
            let err = v.err + v.noise_var.map(f64::sqrt).unwrap_or(0.0);
            points.push(Point {
                s: T::from_f64(si),
                x: T::from_f64(v.value.re),
                err,
            });
        }
        Self::new(label, points)
    }

    /// Simulated data: `x_1(t)` of `chain` simulated on `[0, t_end]` with output
    /// step `dt` ([`crate::time::simulate`]), then transformed as in
    /// [`LaplaceData::from_transform`] (the paper's "simulated data").
    ///
    /// # Errors
    /// Invalid simulation options or `s`.
    pub fn from_simulation(
        chain: &Chain,
        t_end: f64,
        dt: f64,
        s: &[f64],
    ) -> Result<LaplaceData<T>> {
        let traj = simulate(chain, &SimOptions::new(t_end, dt))?;
        let x = traj
            .x(1)
            .ok_or_else(|| Error::invalid("observe", 1, "mass 1 observed"))?;
        let tr = SeriesTransform::uniform(0.0, dt, x, &Default::default())?;
        Self::from_transform(format!("simulated x_1(t), dt = {dt}, T = {t_end}"), &tr, s)
    }

    /// The points, by increasing `s`.
    pub fn points(&self) -> &[Point<T>] {
        &self.points
    }

    /// Where the data come from.
    pub fn label(&self) -> &str {
        &self.label
    }

    /// Index of the point whose `s` is within relative `1e-9` of `s`.
    pub fn find(&self, s: f64) -> Option<usize> {
        self.points
            .iter()
            .position(|p| (p.s.to_f64() - s).abs() <= 1e-9 * s.abs())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn validation_and_sorting() {
        let d = LaplaceData::<f64>::from_f64("t", &[2.0, 1.0], &[0.1, 0.2], &[0.0, 1e-9]).unwrap();
        assert_eq!(d.points()[0].s, 1.0);
        assert_eq!(d.find(2.0), Some(1));
        assert!(d.find(3.0).is_none());
        assert!(LaplaceData::<f64>::from_f64("t", &[1.0], &[0.1, 0.2], &[0.0]).is_err());
        assert!(LaplaceData::<f64>::from_f64("t", &[0.0], &[0.1], &[0.0]).is_err());
        assert!(LaplaceData::<f64>::from_f64("t", &[1.0, 1.0], &[0.1, 0.1], &[0.0, 0.0]).is_err());
        assert!(LaplaceData::<f64>::from_f64("t", &[1.0], &[f64::NAN], &[0.0]).is_err());
        assert!(LaplaceData::<f64>::from_f64("t", &[1.0], &[0.1], &[-1.0]).is_err());
        assert!(LaplaceData::<f64>::from_f64("t", &[], &[], &[]).is_err());
        let g = default_grid();
        assert_eq!(g.len(), 61);
        assert!((g[0] - 1e-3).abs() < 1e-18 && (g[60] - 100.0).abs() < 1e-12);
    }
}
