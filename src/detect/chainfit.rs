//! Continuous fit of any chain parameters (defect values, uniform `d`, `k`,
//! `mass`, impulse `gamma`) at fixed defect positions, by Levenberg-Marquardt
//! ([`crate::detect::lsq`]).
//!
//! Two kinds of observation:
//!
//! * [`Obs::Time`]: the time-domain chi-square ([`TimeMisfit`]); Jacobian by
//!   central differences of the exact modal sum;
//! * [`Obs::Laplace`]: values `d_q` at Laplace nodes `s_q` (real or complex)
//!   with weights `w_q` (`chi^2 = sum_q w_q |X_1(s_q) - d_q|^2`, for example
//!   quadrature weights over `sigma^2`), or with a whitening matrix `W`
//!   ([`LaplaceObs::whitened`]: `chi^2 = ||W r||^2`, `r` the stacked real
//!   residuals, see [`crate::detect::whiten`]); analytic Jacobian by
//!   reciprocity ([`crate::sensitivity::gradient`]).
//!
//! This is the inner step of the unknown-chain-parameter fit: the positions come
//! from a discrete search, and this fit refines every continuous unknown
//! around them; [`ChainFitReport`] carries the Gauss-Newton standard errors.
//!
//! ```
//! use springmass::{Chain, Defect, noise::NoiseLevel, sensitivity::Param};
//! use springmass::detect::{chainfit::{fit_chain, Obs}, misfit_time::{TimeData, TimeMisfit}};
//! let truth = Chain::paper(5)?.with_defects([
//!     Defect::Mass { at: 2, m: 3.0 }, Defect::Mass { at: 4, m: 0.5 }])?;
//! let misfit = TimeMisfit::new(TimeData::simulate(&truth, 100.0, 0.5, NoiseLevel::RelativeMax(1e-3), 1)?);
//! // start from wrong masses and damping, positions known
//! let start = Chain::paper(5)?.with_d(0.2)?.with_defects([
//!     Defect::Mass { at: 2, m: 2.0 }, Defect::Mass { at: 4, m: 1.0 }])?;
//! let params = [Param::Defect(0), Param::Defect(1), Param::D];
//! let fit = fit_chain(&start, &params, &Obs::Time(&misfit), None)?;
//! assert!((fit.chain.d() - 0.1).abs() < 3.0 * fit.std_errors[2] + 1e-6);
//! assert!((fit.chain.defects()[0].value() - 3.0).abs() < 1e-2);
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::chain::Chain;
use crate::detect::lsq::{covariance, levenberg_marquardt, LeastSquares, LmFit, LmOptions};
use crate::detect::misfit_time::TimeMisfit;
use crate::error::{check_f64, Error, Result};
use crate::forward::Forward;
use crate::sensitivity::{defect_gradient_with, gradient, Param};
use nalgebra::DMatrix;
use num_complex::Complex64;

/// Laplace-domain observations: `chi^2 = sum_q w_q |X_1(s_q) - d_q|^2`
/// (diagonal weights, [`LaplaceObs::new`]) or `chi^2 = ||W r||^2` with `r`
/// the stacked real residuals `[Re r_1..r_Q; Im r_q for complex s_q]`
/// ([`crate::time::series::stack_re_im`]) and a whitening matrix `W`
/// ([`LaplaceObs::whitened`]).
#[derive(Clone, Debug, PartialEq)]
pub struct LaplaceObs {
    s: Vec<Complex64>,
    values: Vec<Complex64>,
    weights: Vec<f64>,
    whitening: Option<DMatrix<f64>>,
}

impl LaplaceObs {
    /// Nodes, data and weights.
    ///
    /// # Errors
    /// Lengths differ or are zero; a node with `Re s < 0` or non-finite; a
    /// weight negative or non-finite.
    pub fn new(s: Vec<Complex64>, values: Vec<Complex64>, weights: Vec<f64>) -> Result<LaplaceObs> {
        if s.is_empty() || s.len() != values.len() || s.len() != weights.len() {
            return Err(Error::invalid(
                "s",
                format!(
                    "{} nodes, {} values, {} weights",
                    s.len(),
                    values.len(),
                    weights.len()
                ),
                "equal lengths, at least one node",
            ));
        }
        for (i, z) in s.iter().enumerate() {
            crate::forward::check_s(z)
                .map_err(|_| Error::invalid(format!("s[{i}]"), z, "finite, Re s >= 0"))?;
        }
        for (i, w) in weights.iter().enumerate() {
            check_f64(&format!("weights[{i}]"), *w, *w >= 0.0, ">= 0 and finite")?;
        }
        for (i, v) in values.iter().enumerate() {
            if !(v.re.is_finite() && v.im.is_finite()) {
                return Err(Error::invalid(format!("values[{i}]"), v, "finite"));
            }
        }
        Ok(LaplaceObs {
            s,
            values,
            weights,
            whitening: None,
        })
    }

    /// Nodes, data and a whitening matrix `W` (`K` rows, one column per row of
    /// the stacked real residual vector: `Q` plus the number of complex
    /// nodes), typically [`crate::detect::whiten::Whitening::matrix`] of the
    /// data covariance; `chi^2 = ||W r||^2` has `K` degrees of freedom at the
    /// true chain.
    ///
    /// # Errors
    /// As [`LaplaceObs::new`]; `W` with the wrong number of columns, no rows,
    /// or a non-finite entry (field `whitening`).
    pub fn whitened(
        s: Vec<Complex64>,
        values: Vec<Complex64>,
        whitening: DMatrix<f64>,
    ) -> Result<LaplaceObs> {
        let q = s.len();
        let mut obs = LaplaceObs::new(s, values, vec![1.0; q])?;
        let m = crate::time::series::stacked_rows(&obs.s).len();
        if whitening.ncols() != m || whitening.nrows() == 0 {
            return Err(Error::invalid(
                "whitening",
                format!("{}x{}", whitening.nrows(), whitening.ncols()),
                format!("at least one row and {m} columns (stacked residuals)"),
            ));
        }
        if whitening.iter().any(|v| !v.is_finite()) {
            return Err(Error::invalid("whitening", "non-finite entry", "finite"));
        }
        obs.whitening = Some(whitening);
        Ok(obs)
    }

    /// Degrees of freedom of the chi-square at a fixed chain: the rows of `W`
    /// when whitened, otherwise the number of real residuals (one per real
    /// node, two per complex node; with diagonal weights this is only a
    /// count, the misfit is not a chi-square).
    pub fn dof(&self) -> usize {
        match &self.whitening {
            Some(w) => w.nrows(),
            None => crate::time::series::stacked_rows(&self.s).len(),
        }
    }

    /// The whitening matrix, if any.
    pub fn whitening(&self) -> Option<&DMatrix<f64>> {
        self.whitening.as_ref()
    }

    /// The data values.
    pub fn values(&self) -> &[Complex64] {
        &self.values
    }

    /// `chi^2` of `chain` (the sum of squared [`LaplaceObs::residuals`]).
    ///
    /// # Errors
    /// As [`LaplaceObs::residuals`].
    pub fn chi2(&self, chain: &Chain) -> Result<f64> {
        Ok(self.residuals(chain)?.iter().map(|v| v * v).sum())
    }

    /// Exact data of `truth` at the nodes (for tests and studies).
    ///
    /// # Errors
    /// As [`Forward::eval`] and [`LaplaceObs::new`].
    pub fn exact(truth: &Chain, s: Vec<Complex64>, weights: Vec<f64>) -> Result<LaplaceObs> {
        let fwd = Forward::new(truth);
        let values = s
            .iter()
            .map(|z| fwd.eval(*z, 1))
            .collect::<Result<Vec<_>>>()?;
        LaplaceObs::new(s, values, weights)
    }

    /// The nodes.
    pub fn nodes(&self) -> &[Complex64] {
        &self.s
    }

    /// Whitened residuals of `chain` (real and imaginary parts, imaginary parts
    /// only for complex nodes).
    ///
    /// # Errors
    /// As [`Forward::eval`].
    pub fn residuals(&self, chain: &Chain) -> Result<Vec<f64>> {
        let fwd = Forward::new(chain);
        if let Some(w) = &self.whitening {
            let diff = self
                .s
                .iter()
                .zip(&self.values)
                .map(|(z, d)| Ok(fwd.eval(*z, 1)? - d))
                .collect::<Result<Vec<Complex64>>>()?;
            let r = nalgebra::DVector::from_vec(crate::time::series::stack_re_im(&self.s, &diff));
            return Ok((w * r).iter().copied().collect());
        }
        let mut r = Vec::with_capacity(2 * self.s.len());
        for q in 0..self.s.len() {
            let x = fwd.eval(self.s[q], 1)?;
            let sw = self.weights[q].sqrt();
            let e = (x - self.values[q]) * sw;
            r.push(e.re);
            if self.s[q].im != 0.0 {
                r.push(e.im);
            }
        }
        Ok(r)
    }

    fn jacobian(&self, chain: &Chain, params: &[Param]) -> Result<DMatrix<f64>> {
        let mut rows: Vec<Vec<f64>> = Vec::with_capacity(2 * self.s.len());
        // defect parameters only: O(k) per site by the transfer sweep
        let defect_idx: Option<Vec<usize>> = params
            .iter()
            .map(|p| match p {
                Param::Defect(i) => Some(*i),
                _ => None,
            })
            .collect();
        let fwd = Forward::new(chain);
        let mut grads: Vec<Vec<Complex64>> = Vec::with_capacity(self.s.len());
        for q in 0..self.s.len() {
            let g = match &defect_idx {
                Some(idx) => {
                    let all = defect_gradient_with(&fwd, self.s[q])?;
                    crate::sensitivity::Gradient {
                        value: all.value,
                        grad: idx.iter().map(|&i| all.grad[i]).collect(),
                    }
                }
                None => gradient(chain, self.s[q], 1, params)?,
            };
            if self.whitening.is_some() {
                grads.push(g.grad);
                continue;
            }
            let sw = self.weights[q].sqrt();
            rows.push(g.grad.iter().map(|v| v.re * sw).collect());
            if self.s[q].im != 0.0 {
                rows.push(g.grad.iter().map(|v| v.im * sw).collect());
            }
        }
        if let Some(w) = &self.whitening {
            // stacked rows: Re of every node, then Im of the complex nodes
            let layout = crate::time::series::stacked_rows(&self.s);
            let j = DMatrix::from_fn(layout.len(), params.len(), |r, c| {
                let (q, im) = layout[r];
                if im {
                    grads[q][c].im
                } else {
                    grads[q][c].re
                }
            });
            return Ok(w * j);
        }
        Ok(DMatrix::from_fn(rows.len(), params.len(), |i, j| {
            rows[i][j]
        }))
    }
}

/// What a chain is fitted to.
#[derive(Clone, Copy, Debug)]
pub enum Obs<'a> {
    /// Time-domain chi-square.
    Time(&'a TimeMisfit),
    /// Laplace-domain weighted values.
    Laplace(&'a LaplaceObs),
}

/// The least-squares problem "parameters `params` of `base`".
#[derive(Clone, Debug)]
pub struct ChainProblem<'a> {
    base: Chain,
    params: Vec<Param>,
    obs: Obs<'a>,
}

impl<'a> ChainProblem<'a> {
    /// Problem over `params` (distinct) of `base`.
    ///
    /// # Errors
    /// A repeated parameter or a defect index out of range (field `params`).
    pub fn new(base: &Chain, params: &[Param], obs: Obs<'a>) -> Result<ChainProblem<'a>> {
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
        let c = self.chain(theta)?;
        match self.obs {
            Obs::Time(m) => m.residuals(&c),
            Obs::Laplace(l) => l.residuals(&c),
        }
    }
    fn jacobian(&self, theta: &[f64]) -> Result<DMatrix<f64>> {
        match self.obs {
            Obs::Time(_) => crate::detect::lsq::central_jacobian(self, theta, 1e-6),
            Obs::Laplace(l) => l.jacobian(&self.chain(theta)?, &self.params),
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
            match p {
                Param::D => (0.0, 100.0 * v.max(0.01)),
                Param::Gamma => (-100.0 * v.abs().max(1e-300), 100.0 * v.abs().max(1e-300)),
                Param::Defect(i) => match chain.defects().get(*i) {
                    Some(crate::Defect::Damper { .. }) => (0.0, 100.0 * v.max(0.01)),
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
    obs: &Obs<'_>,
    bounds: Option<&[(f64, f64)]>,
) -> Result<ChainFitReport> {
    let problem = ChainProblem::new(start, params, *obs)?;
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
    use crate::Defect;

    #[test]
    fn laplace_fit_recovers_all_chain_parameters_exactly() {
        let truth = Chain::paper(8)
            .unwrap()
            .with_k(1.3)
            .unwrap()
            .with_gamma(0.8)
            .unwrap()
            .with_defects([
                Defect::Mass { at: 2, m: 3.0 },
                Defect::Spring { at: 5, k: 0.4 },
            ])
            .unwrap();
        let s: Vec<Complex64> = (0..60)
            .map(|i| Complex64::new(0.1, 0.05 * i as f64))
            .collect();
        let w = vec![1e6; s.len()];
        let obs = LaplaceObs::exact(&truth, s, w).unwrap();
        let start = Chain::paper(8)
            .unwrap()
            .with_d(0.15)
            .unwrap()
            .with_k(1.1)
            .unwrap()
            .with_gamma(1.0)
            .unwrap()
            .with_defects([
                Defect::Mass { at: 2, m: 2.0 },
                Defect::Spring { at: 5, k: 0.6 },
            ])
            .unwrap();
        let params = Param::all(&start);
        // mass (uniform) is fixed: drop it (it and gamma, k are otherwise near-degenerate)
        let params: Vec<Param> = params.into_iter().filter(|p| *p != Param::Mass).collect();
        let f = fit_chain(&start, &params, &Obs::Laplace(&obs), None).unwrap();
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
        let truth = Chain::paper(6)
            .unwrap()
            .with_defects([
                Defect::Mass { at: 2, m: 3.0 },
                Defect::Mass { at: 5, m: 0.5 },
            ])
            .unwrap();
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
        let guess = Chain::paper(6)
            .unwrap()
            .with_defects([
                Defect::Mass { at: 2, m: 2.5 },
                Defect::Mass { at: 5, m: 0.7 },
            ])
            .unwrap();
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
        let f = fit_chain(&guess, &p, &Obs::Laplace(&wh), None).unwrap();
        assert!((f.values[0] - 3.0).abs() < 1e-8 && (f.values[1] - 0.5).abs() < 1e-8);
        assert!(LaplaceObs::whitened(s, data.values().to_vec(), DMatrix::zeros(3, 5)).is_err());
    }

    #[test]
    fn bad_problems() {
        let c = Chain::paper(3).unwrap();
        let obs = LaplaceObs::exact(&c, vec![Complex64::new(1.0, 0.0)], vec![1.0]).unwrap();
        assert!(ChainProblem::new(&c, &[Param::D, Param::D], Obs::Laplace(&obs)).is_err());
        assert!(ChainProblem::new(&c, &[Param::Defect(0)], Obs::Laplace(&obs)).is_err());
        assert!(LaplaceObs::new(
            vec![Complex64::new(-1.0, 0.0)],
            vec![Complex64::new(0.0, 0.0)],
            vec![1.0]
        )
        .is_err());
        assert!(LaplaceObs::new(vec![], vec![], vec![]).is_err());
    }
}
