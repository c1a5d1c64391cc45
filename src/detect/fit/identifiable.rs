//! What a fit's data determine when they do not determine every parameter:
//! the combinations of parameters seen by the data's Fisher information.
//!
//! With `J` the whitened Jacobian of the data residuals `r` at `theta`, the
//! eigenvectors `v_i` of `J^T J` with eigenvalue `lambda_i` are the
//! combinations `v_i . theta` the data measure with standard error
//! `1 / sqrt(lambda_i)`. Each is reported as a weighted mean (weights whose
//! magnitudes sum to 1), so that its standard error reads as that of an
//! average factor. A combination counts as determined when that error is
//! below `max_se`; its estimate is the data's own (one Gauss-Newton step
//! from `theta` along `v_i`: `v_i . theta - v_i . J^T r / lambda_i`), so a
//! prior that held the fit near a nominal value does not bias it.
//!
//! ```
//! use nalgebra::DMatrix;
//! use springmass::detect::fit::identifiable::determined_combinations;
//! // two parameters, the data see only their sum (with error 0.01)
//! let j = DMatrix::from_row_slice(1, 2, &[100.0, 100.0]);
//! let c = determined_combinations(&j, &[0.0], &[0.4, 0.6], 1.0, 0.05);
//! assert_eq!(c.len(), 1);
//! assert!((c[0].weights[0] - 0.5).abs() < 1e-12 && (c[0].weights[1] - 0.5).abs() < 1e-12);
//! assert!((c[0].estimate - 0.5).abs() < 1e-12);           // the mean of 0.4 and 0.6
//! assert!((c[0].se - 0.005).abs() < 1e-12);               // 0.01 on the sum
//! ```

use nalgebra::DMatrix;
use serde::Serialize;

/// One combination `weights . theta` of the parameters.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Combination {
    /// Weights, one per parameter, their magnitudes summing to 1 (largest
    /// entry positive).
    pub weights: Vec<f64>,
    /// The data's estimate of `weights . theta`.
    pub estimate: f64,
    /// Its standard error.
    pub se: f64,
}

/// The combinations the data determine to `max_se` (see the module docs),
/// most precise first; `scale` multiplies every standard error (the
/// residual's scale when the noise level was estimated).
pub fn determined_combinations(
    j: &DMatrix<f64>,
    r: &[f64],
    theta: &[f64],
    scale: f64,
    max_se: f64,
) -> Vec<Combination> {
    let p = theta.len();
    if j.ncols() != p || j.nrows() != r.len() || p == 0 {
        return Vec::new();
    }
    let f = j.transpose() * j;
    let g = j.transpose() * nalgebra::DVector::from_column_slice(r);
    let eig = nalgebra::SymmetricEigen::new(f);
    let mut out: Vec<Combination> = (0..p)
        .filter_map(|i| {
            let lambda = eig.eigenvalues[i];
            let mut v: Vec<f64> = eig.eigenvectors.column(i).iter().copied().collect();
            let l1: f64 = v.iter().map(|x| x.abs()).sum();
            let se = scale / lambda.max(0.0).sqrt() / l1;
            if se.is_nan() || se >= max_se {
                return None;
            }
            let top = v
                .iter()
                .copied()
                .fold(0.0, |a: f64, b| if b.abs() > a.abs() { b } else { a });
            if top < 0.0 {
                v.iter_mut().for_each(|x| *x = -*x);
            }
            let vt: f64 = v.iter().zip(theta).map(|(a, b)| a * b).sum();
            let vg: f64 = v.iter().zip(g.iter()).map(|(a, b)| a * b).sum();
            Some(Combination {
                weights: v.iter().map(|x| x / l1).collect(),
                estimate: (vt - vg / lambda) / l1,
                se,
            })
        })
        .collect();
    out.sort_by(|a, b| a.se.total_cmp(&b.se));
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_data_estimate_ignores_where_a_prior_held_the_fit() {
        // linear data y = theta_1 + theta_2 = 3 seen exactly; theta held at (1, 1)
        let j = DMatrix::from_row_slice(1, 2, &[10.0, 10.0]);
        let r = [10.0 * (2.0 - 3.0)];
        let c = determined_combinations(&j, &r, &[1.0, 1.0], 1.0, 1.0);
        assert_eq!(c.len(), 1);
        assert!((c[0].estimate - 1.5).abs() < 1e-12);
        assert!(determined_combinations(&j, &r, &[1.0, 1.0], 1.0, 0.01).is_empty());
    }
}
