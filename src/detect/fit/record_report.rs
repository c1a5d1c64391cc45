//! The report's lines on the record model ([`super::record`]): the noise
//! model, the whiteness of the whitened residual, the fitted nuisances with
//! their standard errors, and what a model mismatch suggests.

use super::engine::{Engine, KFit};
use super::general::Hypothesis;
use super::record::{self, NoiseModelReport, NuisanceEstimate};
use super::report::KRow;
use crate::detect::data::nuisance::Nuisance;
use crate::detect::data::observations::Observations;
use crate::detect::misfit::MisfitKind;
use crate::error::Result;
use crate::sensitivity::Param;
use nalgebra::DMatrix;

/// The criterion margin below which, under a coloured noise model, a
/// neighbouring number of defects is as good as the chosen one (6: "strong"
/// evidence on Kass and Raftery's scale of `2 ln B`).
pub const K_MARGIN: f64 = 6.0;

/// A chi-square (2 dof) of a trend in the residual above which a mismatch
/// message suggests an offset and drift (p about 4e-6).
const TREND_CHI2: f64 = 25.0;

impl Engine<'_> {
    /// The noise model of a series fitted by the time misfit (`None`
    /// otherwise), at innovation sd `sigma`.
    pub(super) fn noise_model_report(&self, sigma: f64) -> Option<NoiseModelReport> {
        let time = matches!(self.obs, Observations::Series(_)) && self.misfit == MisfitKind::Time;
        time.then(|| {
            NoiseModelReport::new(
                &self.record.noise,
                sigma,
                self.record.iterations,
                self.record.converged,
            )
        })
    }

    /// The Ljung-Box p-value of the whitened residual (series data).
    pub(super) fn whiteness_p(&self, f: &KFit) -> Option<f64> {
        let (_, r) = f.predicted.as_ref()?;
        Some(record::whiteness_p(f.whitened.as_deref().unwrap_or(r)))
    }

    /// The fitted nuisances with standard errors from the full Jacobian
    /// `[W J, W B] / sigma` (the defects' and chain parameters' correlation
    /// included; the nuisance block alone where the Jacobian is not
    /// analytic); empty without nuisances.
    ///
    /// # Errors
    /// As the time misfit's model and Jacobian.
    pub(super) fn nuisance_estimates(
        &self,
        best: &Hypothesis,
        sigma: f64,
    ) -> Result<Vec<NuisanceEstimate>> {
        let Observations::Series(s) = self.obs else {
            return Ok(Vec::new());
        };
        if self.record.nuisance == Nuisance::None {
            return Ok(Vec::new());
        }
        let tm = self.record.misfit(self.record.time_data(s, sigma)?)?;
        let chain = best.to_chain(self.model.chain())?;
        let values = tm.nuisance_values(&chain)?;
        let known = self.model.chain().defects();
        let mut params: Vec<Param> = chain
            .defects()
            .iter()
            .enumerate()
            .filter(|(_, d)| !known.contains(d))
            .map(|(i, _)| Param::Defect(i))
            .collect();
        params.extend_from_slice(self.model.fitted());
        let b = tm.nuisance_jacobian();
        let full = match tm.unprojected_jacobian(&chain, &params)? {
            Some(j) if j.nrows() == b.nrows() => {
                let mut a = DMatrix::zeros(b.nrows(), j.ncols() + b.ncols());
                a.columns_mut(0, j.ncols()).copy_from(&j);
                a.columns_mut(j.ncols(), b.ncols()).copy_from(&b);
                a
            }
            _ => b.clone(),
        };
        let offset = full.ncols() - b.ncols();
        let cov = (full.transpose() * &full).try_inverse();
        Ok(self
            .record
            .nuisance
            .params()
            .iter()
            .zip(values)
            .enumerate()
            .map(|(i, (name, value))| NuisanceEstimate {
                name,
                value,
                se: cov
                    .as_ref()
                    .map_or(f64::NAN, |c| c[(offset + i, offset + i)].max(0.0).sqrt()),
            })
            .collect())
    }

    /// Under a coloured noise model, why the number of defects is not
    /// resolved: a fit with one defect more or less within [`K_MARGIN`] of
    /// the chosen one by the criterion (strongly coloured noise can leave a
    /// deep defect at the edge of what the data show). `None` with white
    /// noise (where each defect's identifiability decides, as before), a
    /// given number of defects, or a clear margin.
    pub(super) fn k_margin(&self, rows: &[KRow], k: usize, criterion: &str) -> Option<String> {
        if self.record.noise.is_white() || !matches!(criterion, "bic" | "aic") {
            return None;
        }
        let chosen = rows.iter().find(|r| r.k == k)?.criterion;
        let near = rows
            .iter()
            .filter(|r| r.k + 1 == k || r.k == k + 1)
            .find(|r| (r.criterion - chosen).abs() < K_MARGIN)?;
        Some(format!(
            "the number of defects is not resolved under the coloured noise: k = {} is within a {criterion} margin of {:.2} < {K_MARGIN} of k = {k}",
            near.k,
            (near.criterion - chosen).abs()
        ))
    }

    /// Whether the search tried one defect kind only where the user left
    /// the kinds to the defaults or named one (`kinds` not `any`, no
    /// per-defect kinds, no scene's unknowns, some defect searched for).
    pub(super) fn searched_one_kind(&self) -> bool {
        let searched = !matches!(self.opts.defects, super::options::DefectCount::Exactly(0));
        searched
            && self.given.is_none()
            && self.opts.slot_kinds.is_empty()
            && self.opts.kinds != crate::detect::unknowns::KindChoice::Any
    }

    /// What a residual that is not noise suggests: a trend (offset, drift),
    /// colour (an AR noise model), a misfit at early times (a late trigger
    /// or another impulse). `None` when nothing specific shows.
    pub(super) fn mismatch_hint(&self, f: &KFit) -> Option<String> {
        let (Observations::Series(s), Some((_, r))) = (self.obs, &f.predicted) else {
            return None;
        };
        let mut hints = Vec::new();
        if self.record.nuisance != Nuisance::OffsetDrift && trend_chi2(r, s.t()) > TREND_CHI2 {
            hints.push("a trend (a sensor offset or drift): try --nuisance offset+drift");
        }
        let p = record::whiteness_p(f.whitened.as_deref().unwrap_or(r));
        if p < super::goodness::FITS_DATA_P {
            hints.push(if self.record.noise.is_white() {
                "colour (correlated noise): try --noise-model ar"
            } else {
                "colour that the fitted AR noise model does not whiten (a missing defect, another damping model, or noise beyond AR(8))"
            });
        }
        if early_misfit(r) {
            hints.push("a misfit at early times (a late trigger, another impulse or force)");
        }
        (!hints.is_empty()).then(|| hints.join("; "))
    }
}

/// The chi-square (2 dof) of an offset and drift fitted to `r`, against
/// the rest of `r` as noise.
fn trend_chi2(r: &[f64], t: &[f64]) -> f64 {
    let rest = record::detrend(r, t, Nuisance::OffsetDrift);
    let rss: f64 = r.iter().map(|v| v * v).sum();
    let rest_ss: f64 = rest.iter().map(|v| v * v).sum();
    let var = rest_ss / (r.len().saturating_sub(2).max(1)) as f64;
    if var <= 0.0 {
        return 0.0;
    }
    (rss - rest_ss) / var
}

/// Whether the first tenth of the residual is more than three times the
/// rest's rms.
fn early_misfit(r: &[f64]) -> bool {
    let cut = r.len() / 10;
    if cut < 4 {
        return false;
    }
    let rms = |x: &[f64]| (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt();
    rms(&r[..cut]) > 3.0 * rms(&r[cut..])
}
