//! The noise model of a sampled record, in one place: white, or an
//! autoregressive process AR(p), and the linear map that whitens it.
//!
//! For AR(p) noise `n_t = sum_{i=1}^{p} phi_i n_{t-i} + e_t` (innovations
//! `e_t` white, standard deviation `sigma_e`) the **prediction-error filter**
//! `e_t = r_t - sum_i phi_i r_{t-i}` turns a residual `r` into white noise.
//! The filter is conditional on the first `p` samples, which are dropped:
//! the whitened vector has `N - p` entries (the degrees of freedom lose `p`).
//! [`NoiseModel::filter`] applies it to a residual and
//! [`NoiseModel::filter_columns`] to the columns of a Jacobian, the same
//! linear map, so that standard errors from the whitened Jacobian are those
//! of the fitted noise model. The division by `sigma_e` is the caller's
//! (the time misfit's `1 / sigma`).
//!
//! The coefficients are estimated from a residual by Burg's method
//! ([`burg`]: the reflection coefficients are at most 1 in magnitude by
//! construction, so the fitted process is stationary), and the order by the
//! criterion ([`select_order`]: BIC `N ln sigma_e^2(p) + p ln N` over
//! `p = 0..=p_max`).
//!
//! ```
//! use springmass::detect::data::noise_model::{burg, NoiseModel};
//! use rand::SeedableRng;
//! use rand_distr::{Distribution, StandardNormal};
//! let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
//! let mut x = vec![0.0; 4000];
//! for t in 1..x.len() {
//!     let z: f64 = StandardNormal.sample(&mut rng);
//!     x[t] = 0.9 * x[t - 1] + z;
//! }
//! let fit = burg(&x, 1)?;
//! assert!((fit.coefficients[0] - 0.9).abs() < 0.02);
//! let white = NoiseModel::Ar(fit.coefficients).filter(&x);
//! assert_eq!(white.len(), 3999);
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::error::{Error, Result};
use nalgebra::DMatrix;
use serde::Serialize;

/// Highest autoregressive order the criterion tries by default.
pub const P_MAX: usize = 8;

/// The noise of a record: white, or AR(p) with these coefficients
/// (`phi_1..phi_p`, stationary).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub enum NoiseModel {
    /// Independent samples (the paper's model).
    #[default]
    White,
    /// `n_t = sum_i phi_i n_{t-i} + e_t`.
    Ar(Vec<f64>),
}

impl NoiseModel {
    /// An AR model from its coefficients, checked for stationarity (AR(0)
    /// is white).
    ///
    /// # Errors
    /// A non-finite coefficient, or a non-stationary process (a reflection
    /// coefficient of magnitude 1 or more), field `noise_model`.
    pub fn ar(coefficients: Vec<f64>) -> Result<NoiseModel> {
        if coefficients.is_empty() {
            return Ok(NoiseModel::White);
        }
        if coefficients.iter().any(|c| !c.is_finite()) || reflection(&coefficients).is_none() {
            return Err(Error::invalid(
                "noise_model",
                format!("{coefficients:?}"),
                "the coefficients of a stationary AR process (every reflection coefficient of magnitude below 1)",
            ));
        }
        Ok(NoiseModel::Ar(coefficients))
    }

    /// The order `p` (0 for white noise).
    pub fn order(&self) -> usize {
        self.coefficients().len()
    }

    /// `phi_1..phi_p` (empty for white noise).
    pub fn coefficients(&self) -> &[f64] {
        match self {
            NoiseModel::White => &[],
            NoiseModel::Ar(c) => c,
        }
    }

    /// Whether the model is white.
    pub fn is_white(&self) -> bool {
        self.order() == 0
    }

    /// The prediction-error filter of `r`: `e_t = r_t - sum_i phi_i r_{t-i}`
    /// for `t = p..N` (`N - p` values; `r` itself for white noise, empty
    /// when `N <= p`).
    pub fn filter(&self, r: &[f64]) -> Vec<f64> {
        let phi = self.coefficients();
        let p = phi.len();
        (p..r.len())
            .map(|t| {
                phi.iter()
                    .enumerate()
                    .fold(r[t], |e, (i, f)| e - f * r[t - 1 - i])
            })
            .collect()
    }

    /// [`NoiseModel::filter`] of every column of `m` (rows = samples).
    pub fn filter_columns(&self, m: &DMatrix<f64>) -> DMatrix<f64> {
        if self.is_white() {
            return m.clone();
        }
        let rows = m.nrows().saturating_sub(self.order());
        let mut out = DMatrix::zeros(rows, m.ncols());
        for c in 0..m.ncols() {
            let col: Vec<f64> = m.column(c).iter().copied().collect();
            for (o, v) in out.column_mut(c).iter_mut().zip(self.filter(&col)) {
                *o = v;
            }
        }
        out
    }

    /// `h = D^{1/2} L^{-T} a` of a weight vector `a` over the samples, so
    /// that the covariance of two weighted sums of the stationary noise is
    /// `cov(a . n, b . n) = sigma_e^2 h_a . h_b` (`a` itself for white
    /// noise). Here `L` is the exact whitening of the stationary process,
    /// the prediction-error filter of order `min(t, p)` at sample `t` (the
    /// step-down recursion's lower orders for the first `p` samples), and
    /// `D` the variances of those prediction errors over `sigma_e^2` (1
    /// from sample `p` on): the innovations form `Gamma = sigma_e^2 L^{-1}
    /// D L^{-T}` of the noise covariance. `O(N p)`, by back substitution.
    pub fn covariance_root_t(&self, a: &[f64]) -> Vec<f64> {
        let p = self.order();
        if p == 0 {
            return a.to_vec();
        }
        let Some((orders, d)) = innovations(self.coefficients()) else {
            return vec![f64::NAN; a.len()];
        };
        let n = a.len();
        let mut y = a.to_vec();
        for j in (0..n).rev() {
            let mut v = a[j];
            for k in 1..=p {
                let i = j + k;
                if i >= n {
                    break;
                }
                let coeffs = &orders[i.min(p)];
                if k <= coeffs.len() {
                    v += coeffs[k - 1] * y[i];
                }
            }
            y[j] = v;
        }
        for (j, v) in y.iter_mut().enumerate().take(p) {
            *v *= d[j].sqrt();
        }
        y
    }

    /// The process variance over the innovation variance,
    /// `1 / prod_i (1 - kappa_i^2)` with `kappa` the reflection
    /// coefficients (1 for white noise): the marginal standard deviation of
    /// the noise is `sigma_e` times its square root.
    pub fn variance_ratio(&self) -> f64 {
        reflection(self.coefficients())
            .map(|k| 1.0 / k.iter().map(|x| 1.0 - x * x).product::<f64>())
            .unwrap_or(f64::INFINITY)
    }
}

/// The reflection coefficients of the AR coefficients `phi` (the
/// step-down recursion), `None` when the process is not stationary.
fn reflection(phi: &[f64]) -> Option<Vec<f64>> {
    // a_m[i], i = 1..=m, in the convention e_t = x_t - sum a_i x_{t-i}
    let mut a = phi.to_vec();
    let mut kappa = vec![0.0; phi.len()];
    for m in (0..phi.len()).rev() {
        let k = a[m];
        if k.abs() >= 1.0 || !k.is_finite() {
            return None;
        }
        kappa[m] = k;
        let d = 1.0 - k * k;
        a = (0..m).map(|i| (a[i] + k * a[m - 1 - i]) / d).collect();
    }
    Some(kappa)
}

/// The prediction-error filters of orders `0..=p` of the stationary AR
/// process `phi` (by the step-down recursion; order `m` at index `m`), and
/// the variances of the first `p` samples' prediction errors over the
/// innovation variance, `1 / prod_{j > t} (1 - kappa_j^2)`. `None` when the
/// process is not stationary.
fn innovations(phi: &[f64]) -> Option<(Vec<Vec<f64>>, Vec<f64>)> {
    let p = phi.len();
    let kappa = reflection(phi)?;
    let mut orders = vec![Vec::new(); p + 1];
    orders[p] = phi.to_vec();
    for m in (1..=p).rev() {
        let a = &orders[m];
        let k = a[m - 1];
        let den = 1.0 - k * k;
        orders[m - 1] = (0..m - 1)
            .map(|i| (a[i] + k * a[m - 2 - i]) / den)
            .collect();
    }
    let d = (0..p)
        .map(|t| 1.0 / kappa[t..].iter().map(|x| 1.0 - x * x).product::<f64>())
        .collect();
    Some((orders, d))
}

/// An AR fit of a series.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ArFit {
    /// `phi_1..phi_p`.
    pub coefficients: Vec<f64>,
    /// The innovation variance `sigma_e^2` (of the demeaned series).
    pub innovation_var: f64,
}

/// Burg's estimate of AR(`p`) coefficients of `x` (demeaned first).
///
/// # Errors
/// Fewer than `2 p + 2` values or a non-finite value (field `residual`).
pub fn burg(x: &[f64], p: usize) -> Result<ArFit> {
    let n = x.len();
    if n < 2 * p + 2 || x.iter().any(|v| !v.is_finite()) {
        return Err(Error::invalid(
            "residual",
            format!("{n} values"),
            format!("at least {} finite values for AR({p})", 2 * p + 2),
        ));
    }
    let mean = x.iter().sum::<f64>() / n as f64;
    let mut f: Vec<f64> = x.iter().map(|v| v - mean).collect();
    let mut b = f.clone();
    let mut e = f.iter().map(|v| v * v).sum::<f64>() / n as f64;
    // a[i] in the convention e_t = x_t + sum a_i x_{t-i}
    let mut a: Vec<f64> = Vec::with_capacity(p);
    for m in 0..p {
        let (mut num, mut den) = (0.0, 0.0);
        for t in m + 1..n {
            num += f[t] * b[t - 1];
            den += f[t] * f[t] + b[t - 1] * b[t - 1];
        }
        let k = if den > 0.0 { -2.0 * num / den } else { 0.0 };
        for t in (m + 1..n).rev() {
            let (ft, bt) = (f[t], b[t - 1]);
            f[t] = ft + k * bt;
            b[t] = bt + k * ft;
        }
        let prev = a.clone();
        for i in 0..m {
            a[i] = prev[i] + k * prev[m - 1 - i];
        }
        a.push(k);
        e *= 1.0 - k * k;
    }
    Ok(ArFit {
        coefficients: a.iter().map(|v| -v).collect(),
        innovation_var: e,
    })
}

/// The AR order of `x` by BIC over `p = 0..=p_max` (`N ln sigma_e^2(p) + p ln N`,
/// [`burg`] at each order), and its fit; `p_max` is lowered to what the
/// series supports (`N / 10`).
///
/// # Errors
/// As [`burg`].
pub fn select_order(x: &[f64], p_max: usize) -> Result<ArFit> {
    let n = x.len();
    let p_max = p_max.min(n / 10);
    let nf = n as f64;
    let mut best: Option<(f64, ArFit)> = None;
    for p in 0..=p_max {
        let fit = burg(x, p)?;
        let bic = nf * fit.innovation_var.max(f64::MIN_POSITIVE).ln() + p as f64 * nf.ln();
        if best.as_ref().is_none_or(|(b, _)| bic < *b) {
            best = Some((bic, fit));
        }
    }
    best.map(|(_, f)| f).ok_or_else(|| Error::Numerical {
        method: "select_order".into(),
        reason: "no order fitted".into(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};

    fn ar_series(phi: &[f64], n: usize, seed: u64) -> Vec<f64> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let burn = 2000;
        let mut x = vec![0.0; n + burn];
        for t in 0..x.len() {
            let z: f64 = StandardNormal.sample(&mut rng);
            x[t] = z + phi
                .iter()
                .enumerate()
                .filter(|(i, _)| t > *i)
                .map(|(i, f)| f * x[t - 1 - i])
                .sum::<f64>();
        }
        x.split_off(burn)
    }

    #[test]
    fn burg_recovers_the_coefficients() {
        for (phi, tol) in [
            (vec![0.9], 0.02),
            (vec![0.99], 0.01),
            (vec![1.2, -0.5], 0.04),
        ] {
            let x = ar_series(&phi, 5000, 11);
            let fit = burg(&x, phi.len()).unwrap();
            for (a, b) in fit.coefficients.iter().zip(&phi) {
                assert!((a - b).abs() < tol, "{phi:?}: {:?}", fit.coefficients);
            }
            assert!((fit.innovation_var - 1.0).abs() < 0.06, "{fit:?}");
            let sel = select_order(&x, P_MAX).unwrap();
            assert_eq!(sel.coefficients.len(), phi.len(), "{phi:?}: {sel:?}");
        }
        // white noise: order 0
        let w = ar_series(&[], 3000, 5);
        assert_eq!(select_order(&w, P_MAX).unwrap().coefficients.len(), 0);
        assert!(burg(&[1.0, 2.0], 1).is_err());
        assert!(burg(&[1.0, f64::NAN, 0.0, 1.0, 2.0], 1).is_err());
    }

    #[test]
    fn whitening_a_known_ar_series_gives_white_output() {
        use crate::detect::fit::noise::ljung_box;
        for phi in [vec![0.9], vec![0.99], vec![1.2, -0.5]] {
            let x = ar_series(&phi, 4000, 21);
            assert!(ljung_box(&x, 20).1 < 1e-6);
            let m = NoiseModel::ar(phi.clone()).unwrap();
            let e = m.filter(&x);
            assert_eq!(e.len(), x.len() - phi.len());
            assert!(ljung_box(&e, 20).1 > 0.01, "{phi:?}");
            let var = e.iter().map(|v| v * v).sum::<f64>() / e.len() as f64;
            assert!((var - 1.0).abs() < 0.08, "{phi:?}: {var}");
            // the same map on a matrix's columns
            let mat = DMatrix::from_fn(x.len(), 2, |i, j| x[i] * (j + 1) as f64);
            let w = m.filter_columns(&mat);
            assert_eq!(w.nrows(), e.len());
            assert!((w[(5, 1)] - 2.0 * e[5]).abs() < 1e-12);
        }
    }

    #[test]
    fn covariance_root_gives_the_stationary_covariance_of_weighted_sums() {
        // the autocovariance from the MA(infinity) weights, independently
        for phi in [
            vec![0.7],
            vec![-0.95],
            vec![1.2, -0.5],
            vec![0.5, 0.2, -0.3],
        ] {
            let mut psi = vec![1.0f64];
            for j in 1..4000 {
                let v: f64 = (1..=phi.len().min(j))
                    .map(|k| phi[k - 1] * psi[j - k])
                    .sum();
                psi.push(v);
            }
            let gamma = |h: usize| -> f64 { psi.iter().zip(&psi[h..]).map(|(a, b)| a * b).sum() };
            let n = 13;
            let a: Vec<f64> = (0..n).map(|i| ((i * 7 + 3) % 5) as f64 - 1.7).collect();
            let b: Vec<f64> = (0..n).map(|i| (0.3 * i as f64).cos()).collect();
            let mut exact = 0.0;
            for (i, ai) in a.iter().enumerate() {
                for (j, bj) in b.iter().enumerate() {
                    exact += ai * bj * gamma(i.abs_diff(j));
                }
            }
            let m = NoiseModel::ar(phi.clone()).unwrap();
            let (ha, hb) = (m.covariance_root_t(&a), m.covariance_root_t(&b));
            let got: f64 = ha.iter().zip(&hb).map(|(x, y)| x * y).sum();
            assert!(
                (got - exact).abs() < 1e-9 * exact.abs().max(1.0),
                "{phi:?}: {got} vs {exact}"
            );
            // the variance of one sample is the process variance
            let mut e0 = vec![0.0; n];
            e0[4] = 1.0;
            let h = m.covariance_root_t(&e0);
            let var: f64 = h.iter().map(|x| x * x).sum();
            assert!((var - m.variance_ratio()).abs() < 1e-9 * var, "{phi:?}");
        }
        assert_eq!(
            NoiseModel::White.covariance_root_t(&[1.0, 2.0]),
            vec![1.0, 2.0]
        );
    }

    #[test]
    fn stationarity_and_variance_ratio() {
        assert_eq!(NoiseModel::ar(vec![]).unwrap(), NoiseModel::White);
        assert!(NoiseModel::ar(vec![1.0]).is_err());
        assert!(NoiseModel::ar(vec![1.2, 0.3]).is_err());
        assert!(NoiseModel::ar(vec![f64::NAN]).is_err());
        // AR(1): 1 / (1 - rho^2)
        let m = NoiseModel::ar(vec![0.9]).unwrap();
        assert!((m.variance_ratio() - 1.0 / 0.19).abs() < 1e-12);
        // AR(2) against the Yule-Walker variance: gamma0 / sigma_e^2
        let (a, b) = (1.2f64, -0.5f64);
        let rho1 = a / (1.0 - b);
        let rho2 = a * rho1 + b;
        let expect = 1.0 / (1.0 - a * rho1 - b * rho2);
        let r = NoiseModel::ar(vec![a, b]).unwrap().variance_ratio();
        assert!((r - expect).abs() < 1e-10 * expect, "{r} vs {expect}");
        assert_eq!(NoiseModel::White.variance_ratio(), 1.0);
        assert_eq!(NoiseModel::White.filter(&[1.0, 2.0]), vec![1.0, 2.0]);
    }
}
