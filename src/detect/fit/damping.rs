//! Damping models in a data-first fit ([`crate::chain::Damping`]): the
//! starting values and bounds of their parameters, scaled from the chain's
//! natural frequencies (never a bound made for unit masses), the choice
//! among the models by the criterion, and the report's `damping` entry.
//!
//! # Scales
//!
//! With `omega_min`, `omega_max` the uniform chain's lowest and highest
//! natural frequencies and `omega_ref = sqrt(omega_min omega_max)`, the
//! damping ratio of mode `omega` is `d / (2 mass omega)` (grounded),
//! `c omega / (2 k)` (between), `a / (2 omega) + b omega / 2` (Rayleigh)
//! and `zeta` itself (modal).
//!
//! * **Starting values**: the damping of the chain's `d` (the user's, or the
//!   paper's 0.1) at `omega_ref`, i.e. `c = d k / (mass omega_ref^2)`,
//!   `a = d / (2 mass)`, `b = d / (2 mass omega_ref^2)`,
//!   `zeta = d / (2 mass omega_ref)` (a ratio of 2% at `omega_ref` when `d`
//!   is 0).
//! * **Bounds**: from 0 to a damping ratio of 1 at `omega_min` for each
//!   parameter alone: `c <= 2 k / omega_min`, `a <= 2 omega_min`,
//!   `b <= 2 / omega_min`.
//!
//! # Choosing the model
//!
//! With `--fit d` and no `--damping`, every model is fitted (its parameters
//! in place of `d`; with white noise and no nuisance unless one was given,
//! [`screen_options`]: the screening fit) and the one with the smallest
//! `BIC = N ln(RSS / N) + p ln N` is chosen (`RSS` the residual sum of
//! squares of the `N` samples, `p` the free parameters: defect values and
//! positions as the number-of-defects criterion counts them, plus the
//! chain parameters), with every candidate's value in `damping.candidates`.
//! When the chosen model's screening residual is not noise, it is fitted
//! again with the options asked for (the default noise model `auto` takes a
//! coloured-noise model then); otherwise its screening fit is the report,
//! as `auto` would keep it.

use crate::chain::{Chain, Damping};
use crate::detect::data::nuisance::Nuisance;
use crate::detect::fit::model::Model;
use crate::detect::fit::options::FitOptions;
use crate::detect::fit::record::{NoiseModelChoice, NuisanceChoice};
use crate::detect::fit::report::FitReport;
use crate::error::{Error, Result};
use crate::sensitivity::Param;
use rayon::prelude::*;
use serde::Serialize;
use std::collections::BTreeMap;

/// Damping ratio of the starting value when the chain's `d` is 0.
const START_RATIO: f64 = 0.02;

/// The lowest positive and the highest natural frequency of `chain`'s
/// uniform part (closed form).
///
/// # Errors
/// As [`crate::time::modal::natural_modes`].
pub fn omega_range(chain: &Chain) -> Result<(f64, f64)> {
    let modes = crate::time::modal::natural_modes(&chain.uniform().with_d(0.0)?)?;
    let lo = modes
        .iter()
        .map(|m| m.omega)
        .filter(|&w| w > 0.0)
        .fold(f64::INFINITY, f64::min);
    let hi = modes.iter().map(|m| m.omega).fold(0.0, f64::max);
    if !(lo.is_finite() && hi > 0.0) {
        return Err(Error::invalid(
            "chain",
            "no vibrating mode",
            "a chain with a positive natural frequency",
        ));
    }
    Ok((lo, hi))
}

/// The model `name` with starting values scaled from `chain` (module docs).
///
/// # Errors
/// An unknown name (field `damping`); as [`omega_range`].
pub fn start(chain: &Chain, name: &str) -> Result<Damping> {
    let model: Damping = name.parse()?;
    if model.is_grounded() {
        return Ok(model);
    }
    let (lo, hi) = omega_range(chain)?;
    let w2 = lo * hi;
    let (m, k) = (chain.mass(), chain.k());
    let d = if chain.d() > 0.0 {
        chain.d()
    } else {
        2.0 * m * w2.sqrt() * START_RATIO
    };
    let out = match model {
        Damping::Between { .. } => Damping::Between {
            c: d * k / (m * w2),
        },
        Damping::Modal { .. } => Damping::modal(d / (2.0 * m * w2.sqrt())),
        _ => Damping::Rayleigh {
            a: d / (2.0 * m),
            b: d / (2.0 * m * w2),
        },
    };
    // inside the bounds
    let values: Vec<f64> = out
        .params()
        .iter()
        .zip(params_of(&out))
        .map(|((_, v), p)| bounds(chain, p).map_or(*v, |(lo, hi)| v.clamp(lo, 0.5 * hi)))
        .collect();
    Ok(out.with_params(&values))
}

/// The fitted parameters of a model, in the order of [`Damping::params`].
fn params_of(d: &Damping) -> Vec<Param> {
    match d {
        Damping::Grounded => vec![],
        Damping::Between { .. } => vec![Param::C],
        Damping::Rayleigh { .. } => vec![Param::A, Param::B],
        Damping::Modal { zeta } => (0..zeta.len())
            .map(|index| Param::Zeta {
                index,
                of: zeta.len(),
            })
            .collect(),
    }
}

/// The bounds of a damping model's parameter `p` for `chain` (module
/// docs); `None` for any other parameter or when the chain has no
/// vibrating mode.
pub fn bounds(chain: &Chain, p: Param) -> Option<(f64, f64)> {
    if matches!(p, Param::Zeta { .. }) {
        return Some((0.0, 1.0));
    }
    if !matches!(p, Param::C | Param::A | Param::B) {
        return None;
    }
    let (lo, _) = omega_range(chain).ok()?;
    match p {
        Param::C => Some((0.0, 2.0 * chain.k() / lo)),
        Param::A => Some((0.0, 2.0 * lo)),
        Param::B => Some((0.0, 2.0 / lo)),
        _ => None,
    }
}

/// One candidate model of a fit that chose the damping model, as its
/// screening fit ([`screen_options`]) left it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DampingCandidate {
    /// `grounded`, `between` or `rayleigh`.
    pub model: String,
    /// Its criterion value (smaller is better; `NaN` when its fit failed).
    pub criterion: f64,
    /// Its number of defects.
    pub k: usize,
    /// Its positions.
    pub positions: Vec<usize>,
}

/// The damping model of a fit and its parameters with standard errors:
/// JSON `{"model": "rayleigh", "a": .., "b": .., "se": {"a": .., "b": ..},
/// "fitted": true, "candidates": [..]}`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DampingEstimate {
    /// `grounded`, `between` or `rayleigh`.
    pub model: String,
    /// Its parameters (`d` for grounded; `c`; `a`, `b`).
    #[serde(flatten)]
    pub values: BTreeMap<String, f64>,
    /// Their standard errors (0 for a parameter not fitted).
    pub se: BTreeMap<String, f64>,
    /// Whether they were fitted.
    pub fitted: bool,
    /// Every model fitted when the fit chose the model (empty otherwise).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub candidates: Vec<DampingCandidate>,
}

impl DampingEstimate {
    /// The entry of a report fitted with `model`'s damping model.
    pub fn of(report: &FitReport, model: &Model) -> DampingEstimate {
        let chain = model.chain();
        let damping = chain.damping();
        let mut names: Vec<(String, f64)> = damping.params();
        if damping.is_grounded() {
            names = vec![("d".into(), chain.d())];
        }
        let mut values = BTreeMap::new();
        let mut se = BTreeMap::new();
        let mut fitted = false;
        for (name, v) in names {
            match report.params.iter().find(|p| p.name == name) {
                Some(p) => {
                    values.insert(name.to_string(), p.value);
                    se.insert(name.to_string(), p.se);
                    fitted = true;
                }
                None => {
                    values.insert(name.to_string(), v);
                    se.insert(name.to_string(), 0.0);
                }
            }
        }
        DampingEstimate {
            model: damping.name().to_string(),
            values,
            se,
            fitted,
            candidates: Vec::new(),
        }
    }

    /// One line for the text report.
    pub fn line(&self) -> String {
        let vals: Vec<String> = self
            .values
            .iter()
            .map(|(k, v)| format!("{k} = {v:.4e} +- {:.2e}", self.se.get(k).unwrap_or(&0.0)))
            .collect();
        let mut out = format!("damping model: {} ({})", self.model, vals.join(", "));
        if !self.candidates.is_empty() {
            let c: Vec<String> = self
                .candidates
                .iter()
                .map(|c| format!("{} {:.1}", c.model, c.criterion))
                .collect();
            out.push_str(&format!("; chosen by BIC among {}", c.join(", ")));
        }
        out
    }
}

/// `N ln(RSS / N) + p ln N` of a report (module docs); `NaN` without a
/// predicted series.
pub fn criterion(report: &FitReport) -> f64 {
    let p = report
        .k_selection
        .iter()
        .find(|r| r.k == report.k)
        .map_or(report.params.len(), |r| r.params) as f64;
    let (rss, n) = match &report.predicted {
        Some(pr) => (
            pr.residual.iter().map(|r| r * r).sum::<f64>(),
            pr.residual.len() as f64,
        ),
        None => (
            report.chi2 * report.noise_sigma * report.noise_sigma,
            report.dof as f64 + p,
        ),
    };
    if n <= 0.0 || rss <= 0.0 {
        return f64::NAN;
    }
    n * (rss / n).ln() + p * n.ln()
}

/// The options the candidates of a damping choice are fitted with: white
/// noise, and no nuisance unless one was given. The [`criterion`] is the
/// raw residual's, which a white fit minimises; a coloured noise model
/// (chosen when the white residual fails the whiteness test) refits every
/// shortlisted set under it, and on the wrong models, whose residual is
/// never white, that was most of the choice's cost.
pub fn screen_options(opts: &FitOptions) -> FitOptions {
    let mut o = opts.clone();
    o.noise_model = NoiseModelChoice::White;
    if o.nuisance == NuisanceChoice::Auto {
        o.nuisance = NuisanceChoice::Fixed(Nuisance::None);
    }
    o
}

/// A candidate damping model and its fit.
type Candidate = (Model, Result<FitReport>);

/// Fit every damping model with `fit_one` and return the report of the one
/// with the smallest [`criterion`] (refitted with `refit` when given and
/// its screening fit does not fit the data: the options asked for, where
/// the candidates were fitted with [`screen_options`]), its `damping` entry listing every candidate as
/// `fit_one` fitted it; evaluations are the sum over the fits, the wall
/// time that of the whole choice (a candidate's own clock may include work
/// shared with the others, so their sum would overstate it).
///
/// # Errors
/// The first candidate's error when every candidate fails; the refit's
/// error; a cancellation.
pub fn fit_choosing(
    model: &Model,
    fit_one: impl Fn(&Model) -> Result<FitReport> + Sync,
    refit: Option<impl Fn(&Model) -> Result<FitReport>>,
) -> Result<FitReport> {
    let mut best: Option<(f64, FitReport, Model)> = None;
    let mut candidates = Vec::new();
    let mut first_err = None;
    let started = std::time::Instant::now();
    let mut evaluations = 0;
    // the candidates are independent fits of a second or more each: fitted
    // side by side, taken in the models' order (the same choice whatever
    // the thread count)
    let fitted: Vec<(&str, Result<Candidate>)> = Damping::MODELS
        .par_iter()
        .map(|&name| {
            (
                name,
                model.candidate(name).map(|m| {
                    let r = fit_one(&m);
                    (m, r)
                }),
            )
        })
        .collect();
    for (name, fit) in fitted {
        let (m, r) = fit?;
        let r = match r {
            Ok(r) => r,
            Err(Error::Cancelled) => return Err(Error::Cancelled),
            Err(e) => {
                candidates.push(DampingCandidate {
                    model: name.to_string(),
                    criterion: f64::NAN,
                    k: 0,
                    positions: vec![],
                });
                first_err.get_or_insert(e);
                continue;
            }
        };
        evaluations += r.evaluations;
        let c = criterion(&r);
        candidates.push(DampingCandidate {
            model: name.to_string(),
            criterion: c,
            k: r.k,
            positions: r.found().iter().map(|d| d.at()).collect(),
        });
        if best.as_ref().is_none_or(|(b, ..)| c < *b) {
            best = Some((c, r, m));
        }
    }
    let Some((_, mut report, m)) = best else {
        return Err(first_err
            .unwrap_or_else(|| Error::invalid("damping", "none", "a damping model that fits")));
    };
    // a white residual: the options asked for (`auto`) would keep the
    // white fit, so the screening fit is the answer
    if let Some(refit) = refit.filter(|_| !report.fits_data) {
        report = refit(&m)?;
        evaluations += report.evaluations;
    }
    let mut est = DampingEstimate::of(&report, &m);
    est.candidates = candidates;
    report.damping = Some(est);
    report.evaluations = evaluations;
    report.wall_time_s = started.elapsed().as_secs_f64();
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn starts_and_bounds_scale_with_the_chain() {
        let c = Chain::paper(20).unwrap();
        let (lo, hi) = omega_range(&c).unwrap();
        assert!((lo - 2.0 * (std::f64::consts::PI / 42.0).sin()).abs() < 1e-14);
        let Damping::Rayleigh { a, b } = start(&c, "rayleigh").unwrap() else {
            panic!()
        };
        // the same damping ratio as d = 0.1 at omega_ref
        let w = (lo * hi).sqrt();
        assert!((a / (2.0 * w) + b * w / 2.0 - 0.1 / (2.0 * w)).abs() < 1e-14);
        // SI: masses 1000 kg, springs 1e6 N/m: frequencies 31.6 times higher
        let si = c
            .to_si(&crate::chain::Units::new(1000.0, 1e6, 1000.0).unwrap())
            .unwrap();
        let (lo_si, _) = omega_range(&si).unwrap();
        assert!((lo_si / lo - 1e3_f64.sqrt()).abs() < 1e-9);
        let (_, c_hi) = bounds(&si, Param::C).unwrap();
        assert!((c_hi - 2.0 * 1e6 / lo_si).abs() < 1e-6 * c_hi);
        let Damping::Between { c: c0 } = start(&si, "between").unwrap() else {
            panic!()
        };
        assert!(c0 > 0.0 && c0 < c_hi);
        assert!(start(&c, "viscous").is_err());
    }
}
