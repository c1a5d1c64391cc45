//! One measurement-model interface: every way of comparing a candidate
//! chain with data implements [`MeasurementModel`].
//!
//! A measurement model owns its data and their noise (whitening or weights
//! live with the data, never in the caller), and answers three questions
//! about a candidate chain:
//!
//! * its **residuals** `r(chain)`, whitened so that `chi^2 = |r|^2` is a
//!   chi-square at the truth (unit noise per entry);
//! * their **Jacobian** with respect to any chain parameters
//!   ([`Param`]: defect values, `d`, `k`, `gamma`, `mass`), or `None` where
//!   the model has no analytic one (the caller then differences the
//!   residuals, [`crate::detect::search::lsq::central_jacobian`]);
//! * its **degrees of freedom** (the number of independent residual entries).
//!
//! Implementations, one file each:
//!
//! | model | file | residuals |
//! |---|---|---|
//! | time domain | [`crate::detect::misfit::time`] ([`TimeMisfit`](crate::detect::misfit::time::TimeMisfit)) | `(x_1(t_i) - y_i) / sigma` from the exact modal sum |
//! | Laplace values, real axis or Bromwich line | [`crate::detect::data::laplace`] ([`LaplaceObs`](crate::detect::data::laplace::LaplaceObs)) | `W (X_1(s_q) - d_q)` stacked real and imaginary parts, or `sqrt(w_q)` weights |
//! | output spectrum (ambient records) | [`crate::detect::misfit::ambient`] ([`AmbientMisfit`](crate::detect::misfit::ambient::AmbientMisfit)) | `sqrt(K) L^-1 (G^ - G) L^-H` of the Welch cross-spectral matrix, force level and noise floors profiled out |
//! | measured modes (frequencies, shapes) | [`crate::detect::misfit::modal`] ([`ModalMisfit`](crate::detect::misfit::modal::ModalMisfit)) | `(f_j - f) / se_f` and `(c phi_j - phi) / se` over the measured masses, MAC-paired |
//!
//! The continuous fit ([`crate::detect::fit::chainfit::fit_chain`]), the
//! hypothesis fits of the general path, the greedy search and the
//! whole-profile inversion take a `&dyn MeasurementModel`, so a new kind of
//! data (modal data, several sensors, an output spectrum) is one new file
//! implementing this trait. The fast kernels for one position set (the
//! mass-only Woodbury kernel [`crate::detect::misfit::Misfit`], the
//! rational set model [`crate::detect::misfit::laplace_sets`], the rank-one
//! set problem of the greedy search) are built from Laplace values and
//! reproduce [`MeasurementModel::residuals`] of those values to rounding.
//!
//! ```
//! use springmass::{Chain, Defect, noise::NoiseLevel, sensitivity::Param};
//! use springmass::detect::{data::series::TimeData, misfit::time::TimeMisfit, model::MeasurementModel};
//! let truth = Chain::paper(5)?.with_defect(Defect::Mass { at: 2, m: 3.0 })?;
//! let data = TimeData::simulate(&truth, 50.0, 0.5, NoiseLevel::RelativeMax(1e-3), 1)?;
//! let model: &dyn MeasurementModel = &TimeMisfit::new(data);
//! assert_eq!(model.residuals(&truth)?.len(), model.dof());
//! assert!(model.chi2(&truth)? < 2.0 * model.dof() as f64);
//! let j = model.jacobian(&truth, &[Param::Defect(0)])?.expect("analytic");
//! assert_eq!((j.nrows(), j.ncols()), (model.dof(), 1));
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::chain::Chain;
use crate::error::Result;
use crate::sensitivity::Param;
use nalgebra::DMatrix;

/// The residual function of [`MeasurementModel::near`]: the residuals of a
/// chain, or only their first rows once `enough` (asked with first rows
/// from time to time, perhaps never) answered `true`.
pub type Near<'a> = Box<dyn Fn(&Chain, Enough<'_>) -> Result<Vec<f64>> + Sync + 'a>;

/// Asked by a [`Near`] function with the first rows of a chain's residuals
/// (exactly the first rows of the whole vector): `true` when these are
/// enough and the rest need not be computed.
pub type Enough<'e> = &'e mut dyn FnMut(&[f64]) -> bool;

/// A way of comparing a candidate chain with data (see the module docs).
pub trait MeasurementModel: Sync + std::fmt::Debug {
    /// A short name for reports (`time`, `laplace`).
    fn name(&self) -> &'static str;

    /// Degrees of freedom of `chi^2` at a fixed chain: the number of
    /// independent residual entries.
    fn dof(&self) -> usize;

    /// Whitened residuals of `chain` (`chi^2` is their sum of squares).
    ///
    /// # Errors
    /// The forward model's errors for this chain.
    fn residuals(&self, chain: &Chain) -> Result<Vec<f64>>;

    /// The Jacobian of [`MeasurementModel::residuals`] with respect to
    /// `params` of `chain` (one column per parameter), or `Ok(None)` where
    /// the model has no analytic Jacobian for these parameters.
    ///
    /// # Errors
    /// A parameter that `chain` does not have (field `params`); the forward
    /// model's errors.
    fn jacobian(&self, chain: &Chain, params: &[Param]) -> Result<Option<DMatrix<f64>>>;

    /// The residuals of chains that differ from `base` in a few elements
    /// (the hidden-defect check's probes): [`MeasurementModel::residuals`]
    /// to rounding, perhaps cheaper after work done once for `base` (the
    /// time misfit of a grounded chain resumes each chain's simulation where it
    /// first differs from `base`'s, and stops where the caller has seen
    /// enough, see [`Enough`]). The default calls `residuals`.
    ///
    /// # Errors
    /// The forward model's errors for `base`.
    fn near<'a>(&'a self, base: &Chain) -> Result<Near<'a>> {
        let _ = base;
        Ok(Box::new(move |c: &Chain, _: Enough<'_>| self.residuals(c)))
    }

    /// `chi^2 = |r|^2`.
    ///
    /// # Errors
    /// As [`MeasurementModel::residuals`].
    fn chi2(&self, chain: &Chain) -> Result<f64> {
        Ok(self.residuals(chain)?.iter().map(|r| r * r).sum())
    }
}
