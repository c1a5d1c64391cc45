//! Damping models in a data-first fit ([`crate::chain::Damping`]): the
//! choice among the models by the criterion. The starting values and
//! bounds of their parameters, scaled from the chain's natural frequencies
//! (never a bound made for unit masses), are in
//! [`damping_scales`](super::damping_scales); the report's `damping` entry
//! ([`DampingEstimate`]) is in [`report`](super::report).
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

pub use super::damping_scales::{bounds, omega_range, start};
pub use super::report::{DampingCandidate, DampingEstimate};
use crate::chain::Damping;
use crate::detect::data::nuisance::Nuisance;
use crate::detect::fit::model::Model;
use crate::detect::fit::options::FitOptions;
use crate::detect::fit::record::{NoiseModelChoice, NuisanceChoice};
use crate::detect::fit::report::FitReport;
use crate::error::{Error, Result};
use rayon::prelude::*;

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

/// The options a candidate is screened with: [`screen_options`] as a
/// screening fit (no search of every set after a narrowed answer that does
/// not explain the record, [`FitOptions::screen`]) without uncertainty: the
/// choice compares criteria only, and the chosen model is fitted again
/// with [`screen_options`]. On the wrong models, whose answers never
/// explain the record, the search of every set was most of the choice's
/// cost.
pub fn candidate_options(opts: &FitOptions) -> FitOptions {
    FitOptions {
        screen: true,
        uncertainty: false,
        ..screen_options(opts)
    }
}

/// A candidate damping model and its fit.
type Candidate = (Model, Result<FitReport>);

/// Fit every damping model with `fit_one` (screening fits,
/// [`candidate_options`]) and return the report of the one with the
/// smallest [`criterion`], fitted again with `chosen` ([`screen_options`])
/// and then with `refit` when given and that fit does not fit the data
/// (the options asked for), its `damping` entry listing every candidate as
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
    chosen: impl Fn(&Model) -> Result<FitReport>,
    refit: Option<impl Fn(&Model) -> Result<FitReport>>,
) -> Result<FitReport> {
    let mut best: Option<(f64, Model)> = None;
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
            best = Some((c, m));
        }
    }
    let Some((_, m)) = best else {
        return Err(first_err
            .unwrap_or_else(|| Error::invalid("damping", "none", "a damping model that fits")));
    };
    // the chosen model fitted in full (the candidates were screening fits)
    let mut report = chosen(&m)?;
    evaluations += report.evaluations;
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
