//! Identifiability report of a fit: how well the data pin down each defect.
//!
//! From the best hypothesis (its chi-square and Gauss-Newton covariance) and
//! the ranked alternative position sets (each refitted, with its chi-square):
//!
//! * **standard errors** of every fitted continuous parameter,
//!   `sqrt(diag((J^T J)^{-1}))` with `J` the Jacobian of the whitened residuals
//!   (the inverse Fisher information; calibrated when the stated noise level
//!   is right and the model is);
//! * **chi-square gaps** `Delta chi^2 = chi^2_alt - chi^2_best` per alternative;
//! * **the noise level at which the runner-up becomes indistinguishable**: the
//!   noise-free part of a gap scales as `1/sigma^2` (the model difference is
//!   fixed, the weights are `1/sigma^2`), so the gap falls to the threshold
//!   `T` at `sigma* = sigma sqrt(Delta chi^2 / T)`;
//! * **flags**: a defect is *not identifiable* at the data's noise level when an
//!   alternative that moves it is within `T` of the best, or when its value is
//!   within two standard errors of the uniform chain's value (the data cannot
//!   tell it from no defect).
//!
//! The default threshold `T = 9` is a likelihood ratio of `e^{4.5}` (about 90:1)
//! between two hypotheses with the same number of parameters.
//!
//! ```
//! use springmass::detect::fit::identify::{identify, Alternative, FittedDefect};
//! let best = vec![FittedDefect { at: 8, value: 5.0, std_error: 0.02, uniform: 1.0 },
//!                 FittedDefect { at: 15, value: 2.0, std_error: 0.3, uniform: 1.0 }];
//! let alts = [Alternative { positions: vec![8, 16], chi2: 402.0 },
//!             Alternative { positions: vec![7, 15], chi2: 900.0 }];
//! let r = identify(&best, 400.0, &alts, 1e-2, None)?;
//! assert!(r.defects[0].identifiable && !r.defects[1].identifiable);
//! assert!((r.sigma_indistinguishable.unwrap() - 1e-2 * (2.0f64 / 9.0).sqrt()).abs() < 1e-12);
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::error::{check_f64, Result};
use serde::Serialize;

/// Default chi-square gap below which two hypotheses are indistinguishable.
pub const DEFAULT_THRESHOLD: f64 = 9.0;

/// One defect of the best fit.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FittedDefect {
    /// Position.
    pub at: usize,
    /// Fitted value (mass, spring or damper).
    pub value: f64,
    /// Its standard error (NaN when unconstrained).
    pub std_error: f64,
    /// The uniform chain's value of that kind (no defect).
    pub uniform: f64,
}

/// An alternative position set and its (refitted) chi-square.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Alternative {
    /// Positions, in any order.
    pub positions: Vec<usize>,
    /// Best chi-square with these positions.
    pub chi2: f64,
}

/// The identifiability of one defect.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DefectReport {
    /// Position.
    pub at: usize,
    /// Value and standard error.
    pub value: f64,
    /// Standard error of the value.
    pub std_error: f64,
    /// `|value - uniform| / std_error`: how many standard errors from "no defect".
    pub significance: f64,
    /// The smallest chi-square gap of an alternative without this position.
    pub position_gap: Option<f64>,
    /// The position of that alternative that replaces it.
    pub nearest_rival: Option<usize>,
    /// Whether the defect is identifiable at the data's noise level.
    pub identifiable: bool,
    /// Why not, in words (empty when identifiable).
    pub reason: String,
}

/// The report.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Identifiability {
    /// Best chi-square.
    pub chi2_best: f64,
    /// Noise level of the data.
    pub sigma: f64,
    /// Threshold `T` on the gaps.
    pub threshold: f64,
    /// Alternatives, ranked by chi-square, with their gaps.
    pub alternatives: Vec<(Vec<usize>, f64)>,
    /// Gap of the runner-up.
    pub runner_up_gap: Option<f64>,
    /// Noise level at which the runner-up's gap falls to `T`.
    pub sigma_indistinguishable: Option<f64>,
    /// Per defect.
    pub defects: Vec<DefectReport>,
}

impl Identifiability {
    /// Whether every defect is identifiable.
    pub fn all_identifiable(&self) -> bool {
        self.defects.iter().all(|d| d.identifiable)
    }
}

/// Build the report (see the module docs). `alternatives` need not be sorted
/// and may include the best set itself (it is skipped).
///
/// # Errors
/// A non-finite or negative chi-square or noise level; a threshold `<= 0`.
pub fn identify(
    best: &[FittedDefect],
    chi2_best: f64,
    alternatives: &[Alternative],
    sigma: f64,
    threshold: Option<f64>,
) -> Result<Identifiability> {
    check_f64("chi2_best", chi2_best, chi2_best >= 0.0, ">= 0 and finite")?;
    check_f64("sigma", sigma, sigma >= 0.0, ">= 0 and finite")?;
    let t = threshold.unwrap_or(DEFAULT_THRESHOLD);
    check_f64("threshold", t, t > 0.0, "> 0 and finite")?;
    let mut best_set: Vec<usize> = best.iter().map(|d| d.at).collect();
    best_set.sort_unstable();
    let mut alts: Vec<(Vec<usize>, f64)> = Vec::new();
    for (i, a) in alternatives.iter().enumerate() {
        check_f64(
            &format!("alternatives[{i}].chi2"),
            a.chi2,
            a.chi2 >= 0.0,
            ">= 0 and finite",
        )?;
        let mut p = a.positions.clone();
        p.sort_unstable();
        if p == best_set {
            continue;
        }
        alts.push((p, a.chi2 - chi2_best));
    }
    alts.sort_by(|a, b| a.1.total_cmp(&b.1));
    let runner_up_gap = alts.first().map(|a| a.1);
    let sigma_indistinguishable = runner_up_gap.map(|g| sigma * (g.max(0.0) / t).sqrt());
    let defects = best
        .iter()
        .map(|d| {
            let rival = alts.iter().find(|(p, _)| !p.contains(&d.at));
            let position_gap = rival.map(|r| r.1);
            let nearest_rival = rival.and_then(|(p, _)| {
                p.iter()
                    .filter(|q| !best_set.contains(q))
                    .min_by_key(|q| q.abs_diff(d.at))
                    .copied()
            });
            let significance = (d.value - d.uniform).abs() / d.std_error;
            let mut reasons = Vec::new();
            if let Some(g) = position_gap {
                if g < t {
                    // a rival with no position of its own has the same
                    // positions but this one (another kind at one of them)
                    let of = nearest_rival
                        .map_or("an answer without it".into(), |q| format!("position {q}"));
                    reasons.push(format!(
                        "position {} is within chi2 gap {g:.3} < {t} of {of}",
                        d.at
                    ));
                }
            }
            if significance.is_nan() || significance < 2.0 {
                reasons.push(format!(
                    "value {:.4} is within {significance:.2} standard errors of the uniform {}",
                    d.value, d.uniform
                ));
            }
            DefectReport {
                at: d.at,
                value: d.value,
                std_error: d.std_error,
                significance,
                position_gap,
                nearest_rival,
                identifiable: reasons.is_empty(),
                reason: reasons.join("; "),
            }
        })
        .collect();
    Ok(Identifiability {
        chi2_best,
        sigma,
        threshold: t,
        alternatives: alts,
        runner_up_gap,
        sigma_indistinguishable,
        defects,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gaps_flags_and_scaling() {
        let best = vec![
            FittedDefect {
                at: 3,
                value: 3.0,
                std_error: 0.01,
                uniform: 1.0,
            },
            FittedDefect {
                at: 7,
                value: 1.01,
                std_error: 0.01,
                uniform: 1.0,
            },
        ];
        let alts = [
            Alternative {
                positions: vec![7, 3],
                chi2: 100.0,
            }, // the best itself, skipped
            Alternative {
                positions: vec![3, 8],
                chi2: 500.0,
            },
            Alternative {
                positions: vec![2, 7],
                chi2: 150.0,
            },
        ];
        let r = identify(&best, 100.0, &alts, 1e-3, None).unwrap();
        assert_eq!(r.alternatives.len(), 2);
        assert_eq!(r.runner_up_gap, Some(50.0));
        assert!((r.sigma_indistinguishable.unwrap() - 1e-3 * (50.0f64 / 9.0).sqrt()).abs() < 1e-15);
        assert_eq!(r.defects[0].position_gap, Some(50.0));
        assert_eq!(r.defects[0].nearest_rival, Some(2));
        assert!(r.defects[0].identifiable);
        // second: position well determined (gap 400) but value within 1 se of uniform
        assert_eq!(r.defects[1].position_gap, Some(400.0));
        assert!(!r.defects[1].identifiable);
        assert!(r.defects[1].reason.contains("standard errors"));
        assert!(!r.all_identifiable());
        assert!(identify(&best, f64::NAN, &alts, 1e-3, None).is_err());
        assert!(identify(&best, 1.0, &alts, 1e-3, Some(0.0)).is_err());
        // no alternatives: only the value test
        let r = identify(&best[..1], 1.0, &[], 1e-3, None).unwrap();
        assert!(r.runner_up_gap.is_none() && r.all_identifiable());
        // a rival close by without a position of its own (another kind at
        // a position of the answer): named as such, not as a position
        let close = [Alternative {
            positions: vec![3],
            chi2: 102.0,
        }];
        let r = identify(&best, 100.0, &close, 1e-3, None).unwrap();
        assert_eq!(r.defects[1].nearest_rival, None);
        assert!(
            r.defects[1]
                .reason
                .starts_with("position 7 is within chi2 gap 2.000 < 9 of an answer without it"),
            "{}",
            r.defects[1].reason
        );
        let near = [Alternative {
            positions: vec![3, 8],
            chi2: 102.0,
        }];
        let r = identify(&best, 100.0, &near, 1e-3, None).unwrap();
        assert!(
            r.defects[1].reason.contains("of position 8"),
            "{}",
            r.defects[1].reason
        );
    }
}
