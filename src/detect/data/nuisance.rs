//! Linear sensor nuisances: a constant offset `c0` and a linear drift
//! `c1 t` of the sensor, `y_i = x(t_i) + c0 + c1 t_i + noise`.
//!
//! They enter the record linearly, so they are profiled out exactly
//! (variable projection): with `W` the noise model's whitening and `B` the
//! nuisance columns `[1, t]`, the residual of a chain is `P W (x - y)` and
//! its Jacobian `P W J`, where `P = I - Q Q^T` projects off the whitened
//! columns (`W B = Q R`). The minimum over the nuisances is reached for every
//! chain at once; the degrees of freedom lose one per nuisance. The
//! nuisances at a chain are `c = -(W B)^+ W (x - y)` ([`Projector::coefficients`]).
//!
//! ```
//! use springmass::detect::data::{noise_model::NoiseModel, nuisance::{Nuisance, Projector}};
//! let t: Vec<f64> = (0..50).map(|i| 0.1 * i as f64).collect();
//! let p = Projector::new(Nuisance::OffsetDrift, &t, &NoiseModel::White).unwrap().expect("two columns");
//! // a residual that is a pure offset and drift is projected to zero
//! let r: Vec<f64> = t.iter().map(|t| 2.0 - 0.5 * t).collect();
//! assert!(p.project(&r).iter().all(|v| v.abs() < 1e-12));
//! let c = p.coefficients(&r);
//! assert!((c[0] + 2.0).abs() < 1e-12 && (c[1] - 0.5).abs() < 1e-12);
//! ```

use super::noise_model::NoiseModel;
use crate::error::{Error, Result};
use nalgebra::DMatrix;
use serde::Serialize;

/// Which nuisances the sensor adds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub enum Nuisance {
    /// None (the paper's model).
    #[default]
    None,
    /// A constant offset `c0`.
    Offset,
    /// An offset and a linear drift `c0 + c1 t`.
    OffsetDrift,
}

impl Nuisance {
    /// Number of nuisance parameters.
    pub fn count(self) -> usize {
        match self {
            Nuisance::None => 0,
            Nuisance::Offset => 1,
            Nuisance::OffsetDrift => 2,
        }
    }

    /// `none`, `offset`, `offset+drift`.
    pub fn name(self) -> &'static str {
        match self {
            Nuisance::None => "none",
            Nuisance::Offset => "offset",
            Nuisance::OffsetDrift => "offset+drift",
        }
    }

    /// The names of the parameters (`offset`, `drift`).
    pub fn params(self) -> &'static [&'static str] {
        &["offset", "drift"][..self.count()]
    }

    /// Every choice, fewest parameters first.
    pub const ALL: [Nuisance; 3] = [Nuisance::None, Nuisance::Offset, Nuisance::OffsetDrift];

    /// The nuisance columns at times `t` (rows = samples).
    pub fn columns(self, t: &[f64]) -> DMatrix<f64> {
        DMatrix::from_fn(
            t.len(),
            self.count(),
            |i, j| if j == 0 { 1.0 } else { t[i] },
        )
    }
}

/// The projector off the whitened nuisance columns (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct Projector {
    /// Orthonormal basis of `W B` (rows = whitened samples).
    q: DMatrix<f64>,
    /// `R^-1 Q^T`, the nuisances of a whitened residual (up to the sign).
    pinv: DMatrix<f64>,
}

impl Projector {
    /// The projector of `nuisance` at times `t` under `noise`; `None` for
    /// no nuisance.
    ///
    /// # Errors
    /// Fewer whitened samples than nuisances plus one, or columns that are
    /// not independent (a record of one time), field `nuisance`.
    pub fn new(nuisance: Nuisance, t: &[f64], noise: &NoiseModel) -> Result<Option<Projector>> {
        if nuisance == Nuisance::None {
            return Ok(None);
        }
        let wb = noise.filter_columns(&nuisance.columns(t));
        let bad = || {
            Error::invalid(
                "nuisance",
                nuisance.name(),
                "a record long enough to separate an offset and a drift from the response",
            )
        };
        if wb.nrows() <= wb.ncols() {
            return Err(bad());
        }
        let qr = wb.qr();
        let (q, r) = (qr.q(), qr.r());
        let scale = r.diagonal().amax();
        if r.diagonal().iter().any(|d| d.abs() <= 1e-12 * scale) {
            return Err(bad());
        }
        let rinv = r.try_inverse().ok_or_else(bad)?;
        let pinv = &rinv * q.transpose();
        Ok(Some(Projector { q, pinv }))
    }

    /// `P r` of a whitened vector.
    pub fn project(&self, r: &[f64]) -> Vec<f64> {
        let v = nalgebra::DVector::from_column_slice(r);
        let p = &v - &self.q * (self.q.transpose() * &v);
        p.iter().copied().collect()
    }

    /// `P J` of whitened columns.
    pub fn project_columns(&self, j: &DMatrix<f64>) -> DMatrix<f64> {
        j - &self.q * (self.q.transpose() * j)
    }

    /// The nuisances `c` that minimise `|r + W B c|` for a whitened
    /// residual `r = W (x - y)`: `-(W B)^+ r`.
    pub fn coefficients(&self, r: &[f64]) -> Vec<f64> {
        let v = nalgebra::DVector::from_column_slice(r);
        (-(&self.pinv * v)).iter().copied().collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn projection_under_an_ar_model() {
        let t: Vec<f64> = (0..200).map(|i| 0.5 * i as f64).collect();
        let noise = NoiseModel::ar(vec![0.8]).unwrap();
        let p = Projector::new(Nuisance::OffsetDrift, &t, &noise)
            .unwrap()
            .unwrap();
        // residual = offset + drift + something else: the nuisances come
        // back exactly when the something else is orthogonal after whitening
        let raw: Vec<f64> = t.iter().map(|t| 0.3 + 0.01 * t).collect();
        let w = noise.filter(&raw);
        let c = p.coefficients(&w);
        assert!(
            (c[0] + 0.3).abs() < 1e-12 && (c[1] + 0.01).abs() < 1e-12,
            "{c:?}"
        );
        assert!(p.project(&w).iter().all(|v| v.abs() < 1e-12));
        // idempotent
        let z: Vec<f64> = (0..199).map(|i| ((i * 37) % 11) as f64).collect();
        let once = p.project(&z);
        let twice = p.project(&once);
        assert!(once.iter().zip(&twice).all(|(a, b)| (a - b).abs() < 1e-10));
        assert!(Projector::new(Nuisance::None, &t, &noise)
            .unwrap()
            .is_none());
        assert!(
            Projector::new(Nuisance::OffsetDrift, &[0.0, 0.0, 0.0], &NoiseModel::White).is_err()
        );
        assert_eq!(Nuisance::OffsetDrift.params(), &["offset", "drift"]);
    }
}
