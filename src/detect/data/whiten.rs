//! Whitening of correlated Gaussian data: a true chi-square for Laplace-domain
//! observations of a noisy sampled series.
//!
//! The Laplace transform of a noisy series at nodes `s_1..s_Q` carries noise
//! that is strongly correlated between nodes (the kernels `e^{-s t}` are
//! smooth in `s`), with covariance `C` ([`crate::time::series::SeriesTransform::data_covariance`]).
//! A diagonal weighting `Σ_q w_q |r_q|^2 / v_q` then has no chi-square
//! distribution. With the eigendecomposition `C = V diag(λ) V^T`,
//!
//! ```text
//! W = diag(λ_k^{-1/2}) V_k^T D^{-1}   over the kept components  λ_k > cutoff · λ_max,
//! chi^2 = ||W r||^2  ~  chi-square with K = #kept degrees of freedom,
//! ```
//!
//! where the eigendecomposition is that of the *equilibrated* (correlation)
//! matrix `D^{-1} C D^{-1} = V diag(λ) V^T`, `D = diag(sqrt(C_ii))`: the
//! diagonal of `C` spans many orders of magnitude (the real-axis noise
//! variance falls from `1e-5` at `s = 0` to `1e-11` at `s = 256`, and a node
//! whose tail bound is large has a variance of order 1), and a cutoff
//! relative to the largest eigenvalue of `C` itself would then be set by the
//! worst-known datum rather than by f64 resolution. Equilibrated, the result
//! does not depend on the units of each datum and `λ_max <= m`.
//!
//! for `r` the stacked real residual vector
//! ([`crate::time::series::stack_re_im`]). `K` is the effective number of
//! independent data the Laplace observation really has.
//!
//! **Cutoff** ([`DEFAULT_CUTOFF`] `= 1e-12`, relative to `λ_max` of the
//! correlation matrix): a symmetric
//! eigensolver in f64 returns every eigenvalue with an absolute error of a few
//! `eps · λ_max ≈ 1e-16 λ_max`, and the eigenvector of an eigenvalue `λ` is
//! only determined to about `eps λ_max / gap`. Below `1e-12 λ_max` the
//! computed directions and variances are dominated by rounding (in the
//! covariance itself, formed from weights accurate to `eps`, and in the data,
//! whose transform carries an error of `eps` relative to its largest
//! component): weighting them by `λ^{-1/2}` would amplify rounding by more
//! than `1e6`, and such directions carry no resolvable information anyway.
//! A 4-order margin above the rounding floor keeps the kept variances
//! accurate to about `1e-4`.
//!
//! **Measured** (S3 of the paper, `x_1` on `[0, 200]`, `dt = 0.2`, 1e-3 noise;
//! `tests/chi2.rs`):
//!
//! | nodes | data | kept components (dof) | mean chi2/dof at the truth, 200 seeds |
//! |---|---|---|---|
//! | real axis `[0, 300]`, 80 | 80 | 24 (noise only), 30 (with the model error) | 0.99 (noise only), 0.66 (with it) |
//! | Bromwich `0.05 + i[0, 4]`, 80 | 160 | 160 | 0.95 |
//!
//! The real-axis transform of a record has only about 24 independent data
//! however many nodes are used (the kernels `e^{-s t}` for real `s` are
//! nearly linearly dependent), while the Bromwich line keeps all 160 (its
//! kernels oscillate: cond ~ 1e7). With the model-error variance the
//! chi-square falls below its dof because the error estimate is a bound,
//! not a standard deviation: components dominated by it (the real-axis
//! nodes near `s = 0`, where the tail bound of a noisy record is large)
//! contribute far less than 1 each. The diagonal weighting gives
//! `Σ w_q |r_q|^2 / v_q` of mean 0.017 (Bromwich, per real datum) and 3.3
//! with a heavy tail (real axis): not a chi-square.
//!
//! ```
//! use springmass::detect::data::whiten::Whitening;
//! use nalgebra::DMatrix;
//! // two perfectly correlated unit-variance data and one independent datum
//! let c = DMatrix::from_row_slice(3, 3, &[1.0, 1.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 4.0]);
//! let w = Whitening::new(&c, 1e-12)?;
//! assert_eq!(w.dof(), 2);
//! // (1, 1) is one unit-variance datum seen twice, 2 is one standard deviation
//! assert!((w.chi2(&[1.0, 1.0, 2.0]) - 2.0).abs() < 1e-12);
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::error::{check_f64, Error, Result};
use nalgebra::{DMatrix, DVector, SymmetricEigen};

/// Default relative eigenvalue cutoff (see the module docs).
pub const DEFAULT_CUTOFF: f64 = 1e-12;

/// How Laplace-domain residuals are weighted.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Weighting {
    /// Node `q` weighted by `w_q / v_q` (quadrature weight over the node's
    /// variance): a quadrature of the paper's L2 residual, not a chi-square.
    Diagonal,
    /// Full covariance, whitened ([`Whitening`]): a chi-square with
    /// [`Whitening::dof`] degrees of freedom.
    #[default]
    Whitened,
}

impl Weighting {
    /// `diagonal` or `whitened`.
    pub fn name(self) -> &'static str {
        match self {
            Weighting::Diagonal => "diagonal",
            Weighting::Whitened => "whitened",
        }
    }

    /// Parse a name.
    ///
    /// # Errors
    /// [`Error::Parse`].
    pub fn parse(text: &str) -> Result<Weighting> {
        match text.trim() {
            "diagonal" => Ok(Weighting::Diagonal),
            "whitened" => Ok(Weighting::Whitened),
            _ => Err(Error::parse(
                "weighting",
                text,
                "expected diagonal or whitened",
            )),
        }
    }
}

/// The whitening transform of a covariance matrix.
#[derive(Clone, Debug, PartialEq)]
pub struct Whitening {
    matrix: DMatrix<f64>,
    eigenvalues: Vec<f64>,
    cutoff: f64,
}

impl Whitening {
    /// Whitening of the symmetric positive semi-definite `cov` keeping the
    /// eigenvalues above `rel_cutoff · λ_max`.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] for a non-square, empty or non-finite
    /// matrix or a cutoff outside `(0, 1)`; [`Error::Unresolvable`] when
    /// `λ_max <= 0` (no noise at all).
    pub fn new(cov: &DMatrix<f64>, rel_cutoff: f64) -> Result<Whitening> {
        check_f64(
            "rel_cutoff",
            rel_cutoff,
            rel_cutoff > 0.0 && rel_cutoff < 1.0,
            "in (0, 1)",
        )?;
        if cov.nrows() != cov.ncols() || cov.nrows() == 0 {
            return Err(Error::invalid(
                "cov",
                format!("{}x{}", cov.nrows(), cov.ncols()),
                "square, at least 1x1",
            ));
        }
        if cov.iter().any(|v| !v.is_finite()) {
            return Err(Error::invalid("cov", "non-finite entry", "finite"));
        }
        // symmetrise against rounding of the product that formed it, and
        // equilibrate: the correlation matrix D^-1 C D^-1, D = diag(sqrt(C_ii))
        let m = cov.nrows();
        let d: Vec<f64> = (0..m)
            .map(|i| {
                let v = cov[(i, i)];
                if v > 0.0 {
                    v.sqrt()
                } else {
                    1.0
                }
            })
            .collect();
        let sym = DMatrix::from_fn(m, m, |i, j| {
            0.5 * (cov[(i, j)] + cov[(j, i)]) / (d[i] * d[j])
        });
        let eig = SymmetricEigen::new(sym);
        let mut order: Vec<usize> = (0..eig.eigenvalues.len()).collect();
        order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
        let lmax = eig.eigenvalues[order[0]];
        if lmax <= 0.0 {
            return Err(Error::Unresolvable {
                reason: "the covariance is zero: no noise to weight by".into(),
            });
        }
        let kept: Vec<usize> = order
            .iter()
            .copied()
            .filter(|&k| eig.eigenvalues[k] > rel_cutoff * lmax)
            .collect();
        let mut w = DMatrix::<f64>::zeros(kept.len(), m);
        for (row, &k) in kept.iter().enumerate() {
            let f = eig.eigenvalues[k].sqrt().recip();
            for j in 0..m {
                w[(row, j)] = eig.eigenvectors[(j, k)] * f / d[j];
            }
        }
        Ok(Whitening {
            matrix: w,
            eigenvalues: order.iter().map(|&k| eig.eigenvalues[k]).collect(),
            cutoff: rel_cutoff,
        })
    }

    /// `W` (`dof x m`).
    pub fn matrix(&self) -> &DMatrix<f64> {
        &self.matrix
    }

    /// Number of kept components: the degrees of freedom of [`Whitening::chi2`].
    pub fn dof(&self) -> usize {
        self.matrix.nrows()
    }

    /// Every eigenvalue of the correlation matrix `D^{-1} C D^{-1}`, largest
    /// first (kept or not).
    pub fn eigenvalues(&self) -> &[f64] {
        &self.eigenvalues
    }

    /// The relative cutoff used.
    pub fn cutoff(&self) -> f64 {
        self.cutoff
    }

    /// `W r`.
    ///
    /// # Panics
    /// When `r.len()` differs from the covariance size.
    pub fn apply(&self, r: &[f64]) -> Vec<f64> {
        assert_eq!(r.len(), self.matrix.ncols(), "residual length");
        (&self.matrix * DVector::from_column_slice(r))
            .iter()
            .copied()
            .collect()
    }

    /// `||W r||^2`.
    ///
    /// # Panics
    /// As [`Whitening::apply`].
    pub fn chi2(&self, r: &[f64]) -> f64 {
        self.apply(r).iter().map(|v| v * v).sum()
    }
}

/// Quantile of the chi-square distribution with `k` degrees of freedom at
/// probability `p` (statrs; `k` at least 1).
pub fn chi2_quantile(k: usize, p: f64) -> f64 {
    use statrs::distribution::{ChiSquared, ContinuousCDF};
    ChiSquared::new(k.max(1) as f64)
        .map(|d| d.inverse_cdf(p))
        .unwrap_or(f64::NAN)
}

/// Standard normal quantile (statrs).
pub fn normal_quantile(p: f64) -> f64 {
    use statrs::distribution::{ContinuousCDF, Normal};
    Normal::new(0.0, 1.0)
        .map(|d| d.inverse_cdf(p))
        .unwrap_or(f64::NAN)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn whitening_inverts_the_covariance_on_its_range() {
        // random-ish SPD 5x5 of rank 3 plus a tiny diagonal below the cutoff
        let b = DMatrix::from_fn(5, 3, |i, j| {
            ((i * 3 + j * 7) % 5) as f64 - 1.7 + 0.1 * j as f64
        });
        let mut c = &b * b.transpose();
        for i in 0..5 {
            c[(i, i)] += 1e-20;
        }
        let w = Whitening::new(&c, DEFAULT_CUTOFF).unwrap();
        assert_eq!(w.dof(), 3);
        // W C W^T = I
        let i3 = w.matrix() * &c * w.matrix().transpose();
        assert!((i3 - DMatrix::<f64>::identity(3, 3)).norm() < 1e-10);
        assert!(w.eigenvalues().windows(2).all(|e| e[0] >= e[1]));
    }

    #[test]
    fn quantiles() {
        assert!((normal_quantile(0.95) - 1.644_853_626_951_472_2).abs() < 1e-8);
        assert!((normal_quantile(0.01) + 2.326_347_874_040_841).abs() < 1e-8);
        // chi2(10) 95% = 18.307, chi2(100) 95% = 124.342
        assert!((chi2_quantile(10, 0.95) / 18.307 - 1.0).abs() < 2e-3);
        assert!((chi2_quantile(100, 0.95) / 124.342 - 1.0).abs() < 1e-4);
    }

    #[test]
    fn bad_input() {
        assert!(Whitening::new(&DMatrix::zeros(2, 3), 1e-12).is_err());
        assert!(Whitening::new(&DMatrix::zeros(2, 2), 1e-12).is_err());
        assert!(Whitening::new(&DMatrix::identity(2, 2), 0.0).is_err());
        assert_eq!(Weighting::parse("whitened").unwrap(), Weighting::Whitened);
        assert!(Weighting::parse("full").is_err());
    }
}
