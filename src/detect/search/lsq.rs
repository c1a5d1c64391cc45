//! Weighted nonlinear least squares: a bounded Levenberg-Marquardt solver and
//! the Gauss-Newton (Fisher) covariance at its solution.
//!
//! A problem gives *whitened* residuals `r_i(theta) = (model_i - data_i) / sigma_i`
//! so that `chi^2 = sum r_i^2` is a chi-square at the truth, and optionally
//! their Jacobian (default: central differences). The solver minimises
//! `chi^2` on the box `lo <= theta <= hi` by damped Gauss-Newton steps
//! `(J^T J + mu diag(J^T J)) delta = -J^T r` (Marquardt's scaling), projected on
//! the box; `mu` shrinks by 3 after an accepted step and grows by 4 after a
//! rejected one. Stops when the relative decrease of `chi^2` falls below
//! `rtol` (default 1e-10) or the step below `xtol` relative (default 1e-10),
//! or after `max_iter` (default 100) Jacobians.
//!
//! ```
//! use springmass::detect::search::lsq::{levenberg_marquardt, LeastSquares, LmOptions};
//! struct Line;  // fit y = a + b x to three points, sigma = 0.1
//! impl LeastSquares for Line {
//!     fn residuals(&self, p: &[f64]) -> springmass::Result<Vec<f64>> {
//!         Ok([(0.0, 1.0), (1.0, 3.1), (2.0, 4.9)].iter()
//!             .map(|(x, y)| (p[0] + p[1] * x - y) / 0.1).collect())
//!     }
//! }
//! let fit = levenberg_marquardt(&Line, &[0.0, 0.0], &[(-10.0, 10.0); 2], &LmOptions::default())?;
//! assert!((fit.theta[1] - 1.95).abs() < 1e-9);
//! assert!((fit.std_errors()?[1] - 0.1 / 2f64.sqrt()).abs() < 1e-9);
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::error::{Error, Result};
use nalgebra::{DMatrix, DVector};

/// A weighted least-squares problem (see the module docs).
pub trait LeastSquares {
    /// Whitened residuals at `theta`.
    ///
    /// # Errors
    /// A `theta` the model rejects.
    fn residuals(&self, theta: &[f64]) -> Result<Vec<f64>>;

    /// Jacobian `d r_i / d theta_j` (rows = residuals). Default: central
    /// differences with step `1e-6 max(|theta_j|, 1e-3)`.
    ///
    /// # Errors
    /// As [`LeastSquares::residuals`].
    fn jacobian(&self, theta: &[f64]) -> Result<DMatrix<f64>> {
        central_jacobian(self, theta, 1e-6)
    }
}

/// Central-difference Jacobian with relative step `rel`.
///
/// # Errors
/// As [`LeastSquares::residuals`].
pub fn central_jacobian<P: LeastSquares + ?Sized>(
    p: &P,
    theta: &[f64],
    rel: f64,
) -> Result<DMatrix<f64>> {
    let mut cols: Vec<Vec<f64>> = Vec::with_capacity(theta.len());
    let mut th = theta.to_vec();
    for j in 0..theta.len() {
        let h = rel * theta[j].abs().max(1e-3);
        th[j] = theta[j] + h;
        let up = p.residuals(&th)?;
        th[j] = theta[j] - h;
        let dn = p.residuals(&th)?;
        th[j] = theta[j];
        cols.push(
            up.iter()
                .zip(&dn)
                .map(|(a, b)| (a - b) / (2.0 * h))
                .collect(),
        );
    }
    let m = cols.first().map_or(0, Vec::len);
    Ok(DMatrix::from_fn(m, theta.len(), |i, j| cols[j][i]))
}

/// Options of [`levenberg_marquardt`].
#[derive(Clone, Debug, PartialEq)]
pub struct LmOptions {
    /// Most Jacobian evaluations [default 100].
    pub max_iter: usize,
    /// Relative decrease of `chi^2` that counts as converged [default 1e-10].
    pub rtol: f64,
    /// Relative step that counts as converged [default 1e-10].
    pub xtol: f64,
    /// Initial damping `mu` [default 1e-3].
    pub mu0: f64,
}

impl Default for LmOptions {
    fn default() -> Self {
        LmOptions {
            max_iter: 100,
            rtol: 1e-10,
            xtol: 1e-10,
            mu0: 1e-3,
        }
    }
}

/// The result of [`levenberg_marquardt`].
#[derive(Clone, Debug)]
pub struct LmFit {
    /// The minimiser.
    pub theta: Vec<f64>,
    /// `chi^2` there.
    pub chi2: f64,
    /// Number of residuals.
    pub m: usize,
    /// The Jacobian at `theta`.
    pub jacobian: DMatrix<f64>,
    /// Jacobian evaluations.
    pub iterations: usize,
    /// Residual evaluations (Jacobians by differences not counted).
    pub evaluations: usize,
    /// Whether a tolerance was met (rather than `max_iter`).
    pub converged: bool,
    /// Indices of parameters that ended on a bound.
    pub at_bound: Vec<usize>,
}

impl LmFit {
    /// Degrees of freedom `m - p`.
    pub fn dof(&self) -> usize {
        self.m.saturating_sub(self.theta.len())
    }

    /// Gauss-Newton covariance `(J^T J)^{-1}` (the inverse Fisher information
    /// for whitened residuals).
    ///
    /// # Errors
    /// [`Error::Unresolvable`] when `J^T J` is singular (a parameter the data do
    /// not constrain).
    pub fn covariance(&self) -> Result<DMatrix<f64>> {
        covariance(&self.jacobian)
    }

    /// Standard errors `sqrt(diag((J^T J)^{-1}))`.
    ///
    /// # Errors
    /// As [`LmFit::covariance`].
    pub fn std_errors(&self) -> Result<Vec<f64>> {
        Ok(self
            .covariance()?
            .diagonal()
            .iter()
            .map(|v| v.max(0.0).sqrt())
            .collect())
    }
}

/// `(J^T J)^{-1}` by an SVD pseudo-inverse with a relative cutoff of `1e-13`.
///
/// # Errors
/// [`Error::Unresolvable`] when a singular value falls below the cutoff.
pub fn covariance(j: &DMatrix<f64>) -> Result<DMatrix<f64>> {
    let p = j.ncols();
    if p == 0 {
        return Ok(DMatrix::zeros(0, 0));
    }
    // column scaling for conditioning
    let scale: Vec<f64> = (0..p)
        .map(|c| {
            let n = j.column(c).norm();
            if n > 0.0 {
                1.0 / n
            } else {
                1.0
            }
        })
        .collect();
    let js = DMatrix::from_fn(j.nrows(), p, |r, c| j[(r, c)] * scale[c]);
    let svd = js.svd(false, true);
    let smax = svd.singular_values.max();
    let smin = svd.singular_values.min();
    if smin.is_nan() || smin <= 1e-13 * smax {
        return Err(Error::Unresolvable {
            reason: format!(
                "the data do not constrain all {p} parameters (singular value ratio {:.1e})",
                if smax > 0.0 { smin / smax } else { 0.0 }
            ),
        });
    }
    let vt = svd.v_t.expect("v_t requested");
    let mut cov: DMatrix<f64> = DMatrix::zeros(p, p);
    for k in 0..p {
        let s2 = svd.singular_values[k] * svd.singular_values[k];
        for a in 0..p {
            for b in 0..p {
                cov[(a, b)] += vt[(k, a)] * vt[(k, b)] / s2;
            }
        }
    }
    Ok(DMatrix::from_fn(p, p, |a, b| {
        cov[(a, b)] * scale[a] * scale[b]
    }))
}

fn chi2_of(r: &[f64]) -> f64 {
    r.iter().map(|v| v * v).sum()
}

/// Bounded Levenberg-Marquardt from `theta0` (clamped into the bounds).
///
/// # Errors
/// `bounds` of the wrong length or with `lo >= hi` (field `bounds`); the first
/// residual evaluation failing; a non-finite `chi^2` at the start.
pub fn levenberg_marquardt<P: LeastSquares + ?Sized>(
    problem: &P,
    theta0: &[f64],
    bounds: &[(f64, f64)],
    opts: &LmOptions,
) -> Result<LmFit> {
    let p = theta0.len();
    if bounds.len() != p {
        return Err(Error::invalid(
            "bounds",
            bounds.len(),
            format!("one (lo, hi) per parameter ({p})"),
        ));
    }
    for (i, &(lo, hi)) in bounds.iter().enumerate() {
        if lo.is_nan() || hi.is_nan() || lo >= hi {
            return Err(Error::invalid(
                format!("bounds[{i}]"),
                format!("({lo}, {hi})"),
                "lo < hi",
            ));
        }
    }
    let clamp = |th: &mut [f64]| {
        for (v, &(lo, hi)) in th.iter_mut().zip(bounds) {
            *v = v.clamp(lo, hi);
        }
    };
    let mut theta = theta0.to_vec();
    clamp(&mut theta);
    let mut r = problem.residuals(&theta)?;
    let mut chi2 = chi2_of(&r);
    let mut evaluations = 1;
    if !chi2.is_finite() {
        return Err(Error::Numerical {
            method: "levenberg-marquardt".into(),
            reason: "chi-square not finite at the starting point".into(),
        });
    }
    let mut mu = opts.mu0;
    let mut iterations = 0;
    let mut converged = false;
    let mut jac = problem.jacobian(&theta)?;
    iterations += 1;
    'outer: while iterations <= opts.max_iter {
        let rv = DVector::from_column_slice(&r);
        let jtj = jac.transpose() * &jac;
        let g = jac.transpose() * rv;
        loop {
            let mut a = jtj.clone();
            for i in 0..p {
                a[(i, i)] += mu * jtj[(i, i)].max(1e-300);
            }
            let step = match a.cholesky() {
                Some(ch) => ch.solve(&(-&g)),
                None => {
                    mu *= 4.0;
                    if mu > 1e20 {
                        converged = true;
                        break 'outer;
                    }
                    continue;
                }
            };
            let mut trial: Vec<f64> = theta.iter().zip(step.iter()).map(|(t, s)| t + s).collect();
            clamp(&mut trial);
            let moved: f64 = trial
                .iter()
                .zip(&theta)
                .map(|(a, b)| ((a - b) / b.abs().max(1e-12)).abs())
                .fold(0.0, f64::max);
            let rt = problem.residuals(&trial);
            evaluations += 1;
            let (rt, c2) = match rt {
                Ok(v) => {
                    let c = chi2_of(&v);
                    (v, c)
                }
                Err(_) => (Vec::new(), f64::INFINITY),
            };
            if c2.is_finite() && c2 <= chi2 {
                let dec = (chi2 - c2) / chi2.max(1e-300);
                theta = trial;
                r = rt;
                chi2 = c2;
                mu = (mu / 3.0).max(1e-12);
                if dec < opts.rtol || moved < opts.xtol {
                    converged = true;
                    break 'outer;
                }
                jac = problem.jacobian(&theta)?;
                iterations += 1;
                break;
            }
            mu *= 4.0;
            if mu > 1e20 || moved < opts.xtol {
                converged = true;
                break 'outer;
            }
        }
    }
    // Jacobian at the final point (it may be the last accepted one already)
    let jacobian = problem.jacobian(&theta)?;
    let at_bound = theta
        .iter()
        .zip(bounds)
        .enumerate()
        .filter(|(_, (v, (lo, hi)))| **v <= *lo || **v >= *hi)
        .map(|(i, _)| i)
        .collect();
    Ok(LmFit {
        theta,
        chi2,
        m: r.len(),
        jacobian,
        iterations,
        evaluations,
        converged,
        at_bound,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Exp {
        t: Vec<f64>,
        y: Vec<f64>,
    }
    impl LeastSquares for Exp {
        fn residuals(&self, p: &[f64]) -> Result<Vec<f64>> {
            Ok(self
                .t
                .iter()
                .zip(&self.y)
                .map(|(t, y)| (p[0] * (-p[1] * t).exp() - y) / 0.01)
                .collect())
        }
    }

    #[test]
    fn recovers_exponential_and_respects_bounds() {
        let t: Vec<f64> = (0..50).map(|i| i as f64 * 0.1).collect();
        let y: Vec<f64> = t.iter().map(|t| 2.0 * (-0.7 * t).exp()).collect();
        let pr = Exp { t, y };
        let f = levenberg_marquardt(
            &pr,
            &[1.0, 0.1],
            &[(0.1, 10.0), (0.0, 5.0)],
            &LmOptions::default(),
        )
        .unwrap();
        assert!(
            (f.theta[0] - 2.0).abs() < 1e-8 && (f.theta[1] - 0.7).abs() < 1e-8,
            "{:?}",
            f.theta
        );
        assert!(f.chi2 < 1e-12);
        let g = levenberg_marquardt(
            &pr,
            &[1.0, 0.1],
            &[(0.1, 1.5), (0.0, 5.0)],
            &LmOptions::default(),
        )
        .unwrap();
        assert_eq!(g.theta[0], 1.5);
        assert_eq!(g.at_bound, vec![0]);
        assert!(levenberg_marquardt(
            &pr,
            &[1.0],
            &[(0.0, 1.0), (0.0, 1.0)],
            &LmOptions::default()
        )
        .is_err());
        assert!(levenberg_marquardt(
            &pr,
            &[1.0, 1.0],
            &[(1.0, 1.0), (0.0, 1.0)],
            &LmOptions::default()
        )
        .is_err());
    }

    #[test]
    fn covariance_detects_unconstrained() {
        let j = DMatrix::from_row_slice(3, 2, &[1.0, 2.0, 2.0, 4.0, 3.0, 6.0]);
        assert!(covariance(&j).is_err());
        let j = DMatrix::from_row_slice(3, 2, &[1.0, 0.0, 0.0, 2.0, 0.0, 0.0]);
        let c = covariance(&j).unwrap();
        assert!((c[(0, 0)] - 1.0).abs() < 1e-14 && (c[(1, 1)] - 0.25).abs() < 1e-14);
    }
}
