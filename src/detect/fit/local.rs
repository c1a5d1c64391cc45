//! One fitted hypothesis seen up close: its chain, its free parameters (the
//! defect values of unknown position and the fitted chain parameters), their
//! bounds, and the residuals and Jacobian of the measurement model the fit
//! ranked it on. The posterior over hypotheses
//! ([`super::posterior`]) and the intervals ([`super::intervals`]) are
//! computed from it.

use super::chainfit::{default_bounds, ChainProblem};
use super::general::Hypothesis;
use super::Model;
use crate::chain::Chain;
use crate::detect::model::MeasurementModel;
use crate::detect::search::lsq::{central_jacobian, LeastSquares};
use crate::detect::unknowns::{DefectKind, KindBounds};
use crate::error::Result;
use crate::sensitivity::Param;
use nalgebra::DMatrix;

/// A hypothesis at its optimum, with the data's local information.
#[derive(Clone, Debug)]
pub(super) struct Local {
    /// The chain the hypothesis describes.
    pub(super) chain: Chain,
    /// Its free parameters: defect values first (in the chain's defect
    /// order), then the fitted chain parameters.
    pub(super) params: Vec<Param>,
    /// Their values.
    pub(super) theta: Vec<f64>,
    /// Their search ranges.
    pub(super) bounds: Vec<(f64, f64)>,
    /// `chi^2` on the measurement model (at the noise level it whitens by).
    pub(super) chi2: f64,
    /// The Jacobian of the whitened residuals.
    pub(super) jacobian: DMatrix<f64>,
}

impl Local {
    /// `h` on `data` (the measurement model its fit ranked it on), with the
    /// defects of `model`'s chain known (not free).
    ///
    /// # Errors
    /// The measurement model's errors at this chain.
    pub(super) fn of(h: &Hypothesis, model: &Model, data: &dyn MeasurementModel) -> Result<Local> {
        let base = model.chain();
        let chain = h.to_chain(base)?;
        let kb = KindBounds::for_chain(base);
        let known = known_keys(base);
        let mut params = Vec::new();
        let mut bounds = Vec::new();
        for (i, d) in chain.defects().iter().enumerate() {
            let kind = DefectKind::of(d);
            if !known.contains(&(kind, d.at())) {
                params.push(Param::Defect(i));
                bounds.push(kb.of(kind));
            }
        }
        let fitted = model.fitted();
        params.extend_from_slice(fitted);
        bounds.extend(default_bounds(base, fitted));
        let problem = ChainProblem::new(&chain, &params, data)?;
        let theta = problem.theta0();
        let r = data.residuals(&chain)?;
        let jacobian = match data.jacobian(&chain, &params)? {
            Some(j) => j,
            None => central_jacobian(&problem, &theta, 1e-6)?,
        };
        Ok(Local {
            chi2: r.iter().map(|v| v * v).sum(),
            chain,
            params,
            theta,
            bounds,
            jacobian,
        })
    }

    /// The free defects' kinds, in the order of [`Local::params`].
    pub(super) fn free_defects(&self) -> Vec<crate::chain::Defect> {
        self.params
            .iter()
            .filter_map(|p| match p {
                Param::Defect(i) => self.chain.defects().get(*i).copied(),
                _ => None,
            })
            .collect()
    }

    /// The Fisher information `J^T J`.
    pub(super) fn information(&self) -> DMatrix<f64> {
        self.jacobian.transpose() * &self.jacobian
    }
}

/// `(kind, position)` of the defects `base` knows (not fitted).
pub(super) fn known_keys(base: &Chain) -> Vec<(DefectKind, usize)> {
    base.defects().iter().map(DefectKind::key_of).collect()
}

/// The defects of `defects` that `base` does not know.
pub(super) fn free_of(defects: &[crate::chain::Defect], base: &Chain) -> Vec<crate::chain::Defect> {
    let known = known_keys(base);
    defects
        .iter()
        .filter(|d| !known.contains(&DefectKind::key_of(d)))
        .copied()
        .collect()
}

/// The profile of `chi^2` in parameter `i` of `local`: the others refitted
/// with it held at `value`, from `start` (their values, in
/// [`Local::params`] order without `i`).
///
/// # Errors
/// The measurement model's and the least-squares fit's errors.
pub(super) fn profile_chi2(
    local: &Local,
    data: &dyn MeasurementModel,
    i: usize,
    value: f64,
    start: &[f64],
) -> Result<f64> {
    let held = local.params[i].set(&local.chain, value)?;
    let others: Vec<Param> = (0..local.params.len())
        .filter(|&j| j != i)
        .map(|j| local.params[j])
        .collect();
    if others.is_empty() {
        return data.chi2(&held);
    }
    let bounds: Vec<(f64, f64)> = (0..local.bounds.len())
        .filter(|&j| j != i)
        .map(|j| local.bounds[j])
        .collect();
    let theta0: Vec<f64> = start
        .iter()
        .zip(&bounds)
        .map(|(v, (lo, hi))| v.clamp(*lo, *hi))
        .collect();
    let problem = ChainProblem::new(&held, &others, data)?;
    let opts = crate::detect::search::lsq::LmOptions {
        max_iter: 30,
        rtol: 1e-8,
        ..Default::default()
    };
    let fit = crate::detect::search::lsq::levenberg_marquardt(&problem, &theta0, &bounds, &opts)?;
    // the held chain's own residual is a valid upper bound when the refit
    // went astray
    Ok(fit.chi2.min(
        problem
            .residuals(&theta0)
            .map_or(f64::INFINITY, |r| r.iter().map(|v| v * v).sum()),
    ))
}
