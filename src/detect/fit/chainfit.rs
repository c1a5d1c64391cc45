//! Continuous fit of any chain parameters (defect values, uniform `d`, `k`,
//! `mass`, impulse `gamma`) at fixed defect positions, by Levenberg-Marquardt
//! ([`crate::detect::search::lsq`]).
//!
//! The data are any [`MeasurementModel`]; today two:
//!
//! * the time-domain chi-square ([`TimeMisfit`]); Jacobian
//!   exact for defect values, `gamma` and the chain's uniform and damping
//!   parameters ([`TimeMisfit::jacobian`]: the modal sum's derivative), by
//!   central differences of the exact modal sum where it has none (grounded
//!   dampers beside modal ratios, a long chain whose record is simulated);
//! * [`LaplaceObs`]: values `d_q` at Laplace nodes `s_q` (real or complex)
//!   with weights `w_q` (`chi^2 = sum_q w_q |X_1(s_q) - d_q|^2`, for example
//!   quadrature weights over `sigma^2`), or with a whitening matrix `W`
//!   ([`LaplaceObs::whitened`]: `chi^2 = ||W r||^2`, `r` the stacked real
//!   residuals, see [`crate::detect::data::whiten`]); analytic Jacobian by
//!   reciprocity ([`crate::sensitivity::gradient`]).
//!
//! This is the inner step of the unknown-chain-parameter fit: the positions come
//! from a discrete search, and this fit refines every continuous unknown
//! around them; [`ChainFitReport`] carries the Gauss-Newton standard errors.
//!
//! ```
//! use springmass::{Chain, Defect, noise::NoiseLevel, sensitivity::Param};
//! use springmass::detect::{fit::chainfit::fit_chain, data::series::TimeData, misfit::time::TimeMisfit};
//! let truth = Chain::paper(5)?.with_defects([
//!     Defect::Mass { at: 2, m: 3.0 }, Defect::Mass { at: 4, m: 0.5 }])?;
//! let misfit = TimeMisfit::new(TimeData::simulate(&truth, 100.0, 0.5, NoiseLevel::RelativeMax(1e-3), 1)?);
//! // start from wrong masses and damping, positions known
//! let start = Chain::paper(5)?.with_d(0.2)?.with_defects([
//!     Defect::Mass { at: 2, m: 2.0 }, Defect::Mass { at: 4, m: 1.0 }])?;
//! let params = [Param::Defect(0), Param::Defect(1), Param::D];
//! let fit = fit_chain(&start, &params, &misfit, None)?;
//! assert!((fit.chain.d() - 0.1).abs() < 3.0 * fit.std_errors[2] + 1e-6);
//! assert!((fit.chain.defects()[0].value() - 3.0).abs() < 1e-2);
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::chain::Chain;
use crate::detect::model::MeasurementModel;
use crate::detect::search::lsq::{covariance, levenberg_marquardt, LeastSquares, LmFit, LmOptions};
#[cfg(doc)]
use crate::detect::{data::laplace::LaplaceObs, misfit::time::TimeMisfit};
use crate::error::{Error, Result};
use crate::sensitivity::Param;
use nalgebra::DMatrix;

/// The least-squares problem "parameters `params` of `base`".
#[derive(Clone, Debug)]
pub struct ChainProblem<'a> {
    base: Chain,
    params: Vec<Param>,
    obs: &'a dyn MeasurementModel,
}

impl<'a> ChainProblem<'a> {
    /// Problem over `params` (distinct) of `base`.
    ///
    /// # Errors
    /// A repeated parameter or a defect index out of range (field `params`).
    pub fn new(
        base: &Chain,
        params: &[Param],
        obs: &'a dyn MeasurementModel,
    ) -> Result<ChainProblem<'a>> {
        for (i, p) in params.iter().enumerate() {
            p.get(base)?;
            if params[..i].contains(p) {
                return Err(Error::invalid(
                    "params",
                    p.name(base),
                    "distinct parameters",
                ));
            }
        }
        Ok(ChainProblem {
            base: base.clone(),
            params: params.to_vec(),
            obs,
        })
    }

    /// The chain at `theta`.
    ///
    /// # Errors
    /// A value outside its parameter's physical range.
    pub fn chain(&self, theta: &[f64]) -> Result<Chain> {
        let mut c = self.base.clone();
        for (p, v) in self.params.iter().zip(theta) {
            c = p.set(&c, *v)?;
        }
        Ok(c)
    }

    /// The current values of the parameters in `base`.
    pub fn theta0(&self) -> Vec<f64> {
        self.params
            .iter()
            .map(|p| p.get(&self.base).unwrap_or(f64::NAN))
            .collect()
    }
}

impl LeastSquares for ChainProblem<'_> {
    fn residuals(&self, theta: &[f64]) -> Result<Vec<f64>> {
        self.obs.residuals(&self.chain(theta)?)
    }
    fn jacobian(&self, theta: &[f64]) -> Result<DMatrix<f64>> {
        match self.obs.jacobian(&self.chain(theta)?, &self.params)? {
            Some(j) => Ok(j),
            None => crate::detect::search::lsq::central_jacobian(self, theta, 1e-6),
        }
    }
}

/// The result of [`fit_chain`].
#[derive(Clone, Debug)]
pub struct ChainFitReport {
    /// The fitted chain.
    pub chain: Chain,
    /// The parameters, in the order asked for.
    pub params: Vec<Param>,
    /// Their names (`mass@8`, `d`, ...).
    pub names: Vec<String>,
    /// Fitted values.
    pub values: Vec<f64>,
    /// Gauss-Newton standard errors (NaN when the data do not constrain them).
    pub std_errors: Vec<f64>,
    /// The full solver output.
    pub lm: LmFit,
}

impl ChainFitReport {
    /// `chi^2` at the fit.
    pub fn chi2(&self) -> f64 {
        self.lm.chi2
    }
    /// Number of residuals.
    pub fn m(&self) -> usize {
        self.lm.m
    }
}

/// Default bounds of a parameter around its start value: defect values and
/// uniform mass/k in `[v/100, 100 v]`, `d` in `[0, 100 max(d, 0.01)]`, `gamma` in
/// `[-100|g|, 100|g|]`.
pub fn default_bounds(chain: &Chain, params: &[Param]) -> Vec<(f64, f64)> {
    params
        .iter()
        .map(|p| {
            let v = p.get(chain).unwrap_or(1.0);
            if let Some(b) = crate::detect::fit::damping_scales::bounds(chain, *p) {
                return b;
            }
            match p {
                Param::D => (0.0, 100.0 * v.max(0.01)),
                Param::Gamma => (-100.0 * v.abs().max(1e-300), 100.0 * v.abs().max(1e-300)),
                Param::Defect(i) => match chain.defects().get(*i) {
                    Some(d) if d.may_vanish() => (0.0, 100.0 * v.max(0.01)),
                    _ => (v / 100.0, v * 100.0),
                },
                _ => (v / 100.0, v * 100.0),
            }
        })
        .collect()
}

/// Fit `params` of `start` (whose other parameters and defect positions stay
/// fixed) to `obs`, from the values in `start`, within `bounds` (default
/// [`default_bounds`]).
///
/// # Errors
/// As [`ChainProblem::new`] and [`levenberg_marquardt`].
pub fn fit_chain(
    start: &Chain,
    params: &[Param],
    obs: &dyn MeasurementModel,
    bounds: Option<&[(f64, f64)]>,
) -> Result<ChainFitReport> {
    let problem = ChainProblem::new(start, params, obs)?;
    let b = match bounds {
        Some(b) => b.to_vec(),
        None => default_bounds(start, params),
    };
    let lm = levenberg_marquardt(&problem, &problem.theta0(), &b, &LmOptions::default())?;
    let chain = problem.chain(&lm.theta)?;
    let std_errors = match covariance(&lm.jacobian) {
        Ok(c) => c.diagonal().iter().map(|v| v.max(0.0).sqrt()).collect(),
        Err(_) => vec![f64::NAN; params.len()],
    };
    Ok(ChainFitReport {
        names: params.iter().map(|p| p.name(&chain)).collect(),
        values: lm.theta.clone(),
        params: params.to_vec(),
        chain,
        std_errors,
        lm,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::data::laplace::LaplaceObs;

    use num_complex::Complex64;

    #[test]
    fn laplace_fit_recovers_all_chain_parameters_exactly() {
        let truth = crate::scenes::paper_with(8, "mass:2:3.0 spring:5:0.4")
            .unwrap()
            .with_k(1.3)
            .unwrap()
            .with_gamma(0.8)
            .unwrap();
        let s: Vec<Complex64> = (0..60)
            .map(|i| Complex64::new(0.1, 0.05 * i as f64))
            .collect();
        let w = vec![1e6; s.len()];
        let obs = LaplaceObs::exact(&truth, s, w).unwrap();
        let start = crate::scenes::paper_with(8, "mass:2:2.0 spring:5:0.6")
            .unwrap()
            .with_d(0.15)
            .unwrap()
            .with_k(1.1)
            .unwrap()
            .with_gamma(1.0)
            .unwrap();
        let params = Param::all(&start);
        // mass (uniform) is fixed: drop it (it and gamma, k are otherwise near-degenerate)
        let params: Vec<Param> = params.into_iter().filter(|p| *p != Param::Mass).collect();
        let f = fit_chain(&start, &params, &obs, None).unwrap();
        for p in &params {
            let (a, b) = (p.get(&f.chain).unwrap(), p.get(&truth).unwrap());
            assert!(
                (a - b).abs() < 1e-7 * b.abs(),
                "{}: {a} vs {b}",
                p.name(&truth)
            );
        }
        assert!(f.chi2() < 1e-12);
    }

    #[test]
    fn whitened_with_a_scaled_identity_equals_diagonal_weights() {
        let truth = crate::scenes::paper_with(6, "mass:2:3.0 mass:5:0.5").unwrap();
        let s = vec![
            Complex64::new(0.5, 0.0),
            Complex64::new(0.1, 0.7),
            Complex64::new(2.0, 0.0),
            Complex64::new(0.1, 1.3),
        ];
        let data = LaplaceObs::exact(&truth, s.clone(), vec![4.0; 4]).unwrap();
        let diag = LaplaceObs::new(s.clone(), data.values().to_vec(), vec![4.0; 4]).unwrap();
        let w = DMatrix::<f64>::identity(6, 6) * 2.0;
        let wh = LaplaceObs::whitened(s.clone(), data.values().to_vec(), w).unwrap();
        assert_eq!((diag.dof(), wh.dof()), (6, 6));
        let guess = crate::scenes::paper_with(6, "mass:2:2.5 mass:5:0.7").unwrap();
        let (a, b) = (diag.chi2(&guess).unwrap(), wh.chi2(&guess).unwrap());
        assert!((a - b).abs() <= 1e-12 * a, "{a} vs {b}");
        let p = Param::defects(&guess);
        let (ja, jb) = (
            diag.jacobian(&guess, &p).unwrap(),
            wh.jacobian(&guess, &p).unwrap(),
        );
        let (ga, gb) = (ja.transpose() * &ja, jb.transpose() * &jb);
        assert!((ga - &gb).norm() <= 1e-12 * gb.norm());
        // a whitened fit recovers the truth
        let f = fit_chain(&guess, &p, &wh, None).unwrap();
        assert!((f.values[0] - 3.0).abs() < 1e-8 && (f.values[1] - 0.5).abs() < 1e-8);
        assert!(LaplaceObs::whitened(s, data.values().to_vec(), DMatrix::zeros(3, 5)).is_err());
    }

    #[test]
    fn bad_problems() {
        let c = Chain::paper(3).unwrap();
        let obs = LaplaceObs::exact(&c, vec![Complex64::new(1.0, 0.0)], vec![1.0]).unwrap();
        assert!(ChainProblem::new(&c, &[Param::D, Param::D], &obs).is_err());
        assert!(ChainProblem::new(&c, &[Param::Defect(0)], &obs).is_err());
        assert!(LaplaceObs::new(
            vec![Complex64::new(-1.0, 0.0)],
            vec![Complex64::new(0.0, 0.0)],
            vec![1.0]
        )
        .is_err());
        assert!(LaplaceObs::new(vec![], vec![], vec![]).is_err());
    }
}
