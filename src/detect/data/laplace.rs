//! Laplace-domain observations `d_q ~ X_1(s_q)` at real or complex nodes,
//! weighted per node or whitened by their covariance, with the residuals and
//! Jacobian a least-squares fit needs.

use crate::chain::Chain;
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
    /// nodes), typically [`crate::detect::data::whiten::Whitening::matrix`] of the
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

    /// The per-node weights (all 1 when whitened).
    pub fn weights(&self) -> &[f64] {
        &self.weights
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

    pub(crate) fn jacobian(&self, chain: &Chain, params: &[Param]) -> Result<DMatrix<f64>> {
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
