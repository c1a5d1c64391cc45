//! How probable each defect hypothesis is: the evidence of every hypothesis
//! the search refitted (its number of defects, kinds and positions), by the
//! Laplace approximation at its optimum, normalised over them, with a bound
//! on the hypotheses the search pruned.
//!
//! For a hypothesis `h` with `p` free values `theta` (its defect values and
//! the fitted chain parameters), Gaussian noise at the report's level and a
//! prior `pi`:
//!
//! ```text
//! ln Z_h = -chi2_h / 2 + (p/2) ln(2 pi) + (1/2) ln det C_h - sum ln(width_j) + ln P(positions, k)
//! ```
//!
//! where `C_h = (J^T J)^-1` is the covariance at the optimum, each defect
//! value's prior is uniform over its search range (`width_j`, or the range
//! of [`Prior::range`]), and a direction the data do not constrain counts
//! its prior width instead of `sqrt(2 pi / lambda)`. The chain parameters'
//! prior is the same for every hypothesis and cancels. The prior over
//! positions is uniform among the position (and kind) sets of each `k`,
//! and over `k` uniform among the counts searched (or, with
//! [`KPrior::Site`], every site defective with probability `P`
//! independently).
//!
//! Probabilities are normalised over the hypotheses refitted; the ones the
//! screen dropped (a worse fit on the Laplace screen than every one kept)
//! are bounded by the worst kept one's weight each: `pruned_bound` is the
//! largest share of probability they could hold.

use super::local::{free_of, Local};
pub use super::prior::{KPrior, Prior};
pub use super::report::posterior::{
    HypothesisProbability, KProbability, PositionProbability, Posterior, TOP,
};
use super::stages::Stage;
use crate::chain::Defect;
use crate::detect::model::MeasurementModel;
use crate::detect::unknowns::DefectKind;
use crate::error::Result;
use std::collections::BTreeMap;

/// One refitted hypothesis with its weight.
struct Weighted {
    defects: Vec<Defect>,
    k: usize,
    chi2: f64,
    log_z: f64,
}

/// The posterior of `stage`'s fits at its noise level, under `prior`; the
/// reported answer is `stage`'s chosen fit's best hypothesis.
///
/// # Errors
/// The measurement model's errors at a refitted hypothesis.
pub(super) fn posterior(
    stage: &Stage<'_>,
    prior: &Prior,
    data: (f64, &dyn MeasurementModel),
    answer: Option<&Local>,
) -> Result<Posterior> {
    let engine = &stage.engine;
    let model = engine.model;
    let base = model.chain();
    let sigma = stage.sigma;
    let k_count = stage.fits.len() as f64;
    let sites = engine.space_size(1)?.max(1.0);
    let best_chi2 = stage
        .fits
        .iter()
        .filter_map(|f| {
            f.ranked
                .first()
                .map(|h| h.chi2 * (f.sigma_fit / sigma).powi(2))
        })
        .fold(f64::INFINITY, f64::min);
    let mut all: Vec<Weighted> = Vec::new();
    let mut floor: Vec<(usize, f64, f64)> = Vec::new(); // (k, pruned count, worst log z)
    for f in &stage.fits {
        // the model the answer's fit ranked on serves every fit at its level
        let own = match f.sigma_fit == data.0 {
            true => None,
            false => Some(engine.measurement_at(f.sigma_fit)?),
        };
        let on: &dyn MeasurementModel = own.as_deref().unwrap_or(data.1);
        let scale2 = (f.sigma_fit / sigma).powi(2);
        let space = engine.space_size(f.k)?;
        let ln_pos = match prior.k {
            KPrior::Uniform => -k_count.ln() - space.max(1.0).ln(),
            KPrior::Site(p) => f.k as f64 * p.ln() + (sites - f.k as f64).max(0.0) * (-p).ln_1p(),
        };
        let mut seen: Vec<Vec<(DefectKind, usize)>> = Vec::new();
        let mut worst = f64::INFINITY;
        for h in &f.ranked {
            let key = h.key();
            if seen.contains(&key) {
                continue;
            }
            seen.push(key);
            let chi2 = h.chi2 * scale2;
            // far from the best (weight below e^-100 of it, more than any
            // Occam factor makes up): its evidence from its own standard
            // errors, without a Jacobian
            let (log_z, defects, chi2) = if chi2 - best_chi2 > FAR {
                let lz = rough_log_evidence(h, chi2, sigma / f.sigma_fit, base, prior);
                (lz, free_of(&h.defects, base), chi2)
            } else {
                let reused = answer.filter(|_| std::ptr::eq(h, &stage.best().ranked[0]));
                let fresh = match reused {
                    Some(_) => None,
                    None => Some(Local::of(h, model, on)?),
                };
                let local = reused.or(fresh.as_ref()).expect("one of the two");
                let lz = log_evidence(local, scale2, sigma / f.sigma_fit, prior, base);
                (lz, local.free_defects(), local.chi2 * scale2)
            };
            let log_z = log_z + ln_pos;
            worst = worst.min(log_z);
            all.push(Weighted {
                defects,
                k: f.k,
                chi2,
                log_z,
            });
        }
        floor.push((f.k, (space - seen.len() as f64).max(0.0), worst));
    }
    Ok(normalise(all, &floor, prior, stage))
}

/// The hypotheses' probabilities, the marginals and the pruned bound.
fn normalise(
    mut all: Vec<Weighted>,
    floor: &[(usize, f64, f64)],
    prior: &Prior,
    stage: &Stage<'_>,
) -> Posterior {
    all.sort_by(|a, b| b.log_z.total_cmp(&a.log_z));
    let top = all.first().map_or(0.0, |w| w.log_z);
    let weight = |lz: f64| (lz - top).exp();
    let total: f64 = all.iter().map(|w| weight(w.log_z)).sum();
    let pruned_w: f64 = floor
        .iter()
        .filter(|(_, n, lz)| *n > 0.0 && lz.is_finite())
        .map(|(_, n, lz)| n * weight(*lz))
        .sum();
    let p = |w: &Weighted| weight(w.log_z) / total;
    let mut k_probability: Vec<KProbability> = floor
        .iter()
        .map(|(k, ..)| KProbability {
            k: *k,
            probability: all.iter().filter(|w| w.k == *k).map(p).sum(),
        })
        .collect();
    k_probability.sort_by_key(|k| k.k);
    let mut sites: BTreeMap<(&'static str, usize), f64> = BTreeMap::new();
    for w in &all {
        for d in &w.defects {
            *sites.entry((d.kind(), d.at())).or_insert(0.0) += p(w);
        }
    }
    let answer = stage
        .best()
        .ranked
        .first()
        .map(|h| free_key(&h.key(), stage));
    let answer_probability = all
        .iter()
        .find(|w| Some(sorted_key(&w.defects)) == answer)
        .map_or(0.0, p);
    Posterior {
        prior: prior.describe(),
        hypotheses: all
            .iter()
            .take(TOP)
            .map(|w| HypothesisProbability {
                defects: w.defects.clone(),
                k: w.k,
                chi2: w.chi2,
                log_evidence: w.log_z,
                probability: p(w),
            })
            .collect(),
        k_probability,
        position_probability: sites
            .into_iter()
            .map(|((kind, at), probability)| PositionProbability {
                kind,
                at,
                probability,
            })
            .collect(),
        answer_probability,
        refitted: all.len(),
        pruned: floor.iter().map(|(_, n, _)| n).sum(),
        pruned_bound: pruned_w / (total + pruned_w),
    }
}

/// `(kind, position)` of `defects`, sorted.
fn sorted_key(defects: &[Defect]) -> Vec<(DefectKind, usize)> {
    let mut k: Vec<(DefectKind, usize)> = defects.iter().map(DefectKind::key_of).collect();
    k.sort();
    k
}

/// The answer's key without the model's known defects, sorted.
fn free_key(key: &[(DefectKind, usize)], stage: &Stage<'_>) -> Vec<(DefectKind, usize)> {
    let known = super::local::known_keys(stage.engine.model.chain());
    let mut k: Vec<(DefectKind, usize)> =
        key.iter().filter(|k| !known.contains(k)).copied().collect();
    k.sort();
    k
}

/// Chi-square above the best one's beyond which a hypothesis's evidence is
/// taken from its own standard errors (its weight is below `e^-100` of the
/// best's either way).
const FAR: f64 = 200.0;

/// [`log_evidence`] from the hypothesis's standard errors (correlations
/// left out) and the search ranges, for a hypothesis far from the best.
fn rough_log_evidence(
    h: &super::general::Hypothesis,
    chi2: f64,
    ratio: f64,
    base: &crate::chain::Chain,
    prior: &Prior,
) -> f64 {
    let kb = crate::detect::unknowns::KindBounds::for_chain(base);
    let free = free_of(&h.defects, base);
    let mut occam = 0.0;
    for (d, se) in h.defects.iter().zip(&h.std_errors) {
        if !free.contains(d) {
            continue;
        }
        let (lo, hi) = kb.of(DefectKind::of(d));
        let width = match prior.range {
            Some((a, b)) => (b - a) * d.base_value(base).abs(),
            None => hi - lo,
        };
        let w = (2.0 * std::f64::consts::PI).sqrt() * se * ratio;
        occam += w.min(width).max(1e-300).ln() - width.max(1e-300).ln();
    }
    -0.5 * chi2 + occam
}

/// The Laplace log-evidence of `local` (fitted at a noise level `ratio`
/// times smaller than the report's; its chi-square scaled by `scale2`),
/// without the position prior.
fn log_evidence(
    local: &Local,
    scale2: f64,
    ratio: f64,
    prior: &Prior,
    base: &crate::chain::Chain,
) -> f64 {
    let widths: Vec<f64> = local
        .params
        .iter()
        .zip(&local.bounds)
        .map(|(p, (lo, hi))| match (p, prior.range) {
            (crate::sensitivity::Param::Defect(i), Some((a, b))) => {
                let u = local.chain.defects()[*i].base_value(base).abs();
                (b - a) * u
            }
            _ => hi - lo,
        })
        .collect();
    let n_def = local
        .params
        .iter()
        .filter(|p| matches!(p, crate::sensitivity::Param::Defect(_)))
        .count();
    // the information at the report's noise level
    let info = local.information() * (1.0 / (ratio * ratio));
    let mean_width = if widths.is_empty() {
        1.0
    } else {
        (widths.iter().map(|w| w.max(1e-300).ln()).sum::<f64>() / widths.len() as f64).exp()
    };
    let eig = if info.nrows() == 0 {
        nalgebra::DVector::zeros(0)
    } else {
        nalgebra::SymmetricEigen::new(info).eigenvalues
    };
    // each direction: the posterior's width sqrt(2 pi / lambda), at most the prior's
    let occam: f64 = eig
        .iter()
        .map(|&l| {
            let w = (2.0 * std::f64::consts::PI / l.max(1e-300)).sqrt();
            w.min(mean_width).ln()
        })
        .sum();
    let prior_values: f64 = widths[..n_def].iter().map(|w| w.max(1e-300).ln()).sum();
    -0.5 * local.chi2 * scale2 + occam - prior_values
}
