//! Damping models in a data-first fit ([`crate::chain::Damping`]): the
//! choice among the models by the criterion. The starting values and
//! bounds of their parameters, scaled from the chain's natural frequencies
//! (never a bound made for unit masses), are in
//! [`damping_scales`](super::damping_scales); the report's `damping` entry
//! ([`DampingEstimate`]) is in [`report`](super::report).
//!
//! # Choosing the model
//!
//! With `--fit d` and no `--damping`, the models are fitted (their
//! parameters in place of `d`; with white noise and no nuisance unless one
//! was given, [`screen_options`]: the screening fit) and compared by
//! `BIC = N ln(RSS / N) + p ln N` (`RSS` the residual sum of squares of the
//! `N` samples, `p` the free parameters: defect values and positions as the
//! number-of-defects criterion counts them, plus the chain parameters),
//! every candidate's value in `damping.candidates`. The models' positions
//! are searched one after the other, first the cheapest ([`ORDER`]);
//! after each search the models not yet searched are fitted at the best
//! set so far alone, and as soon as the best so far explains the record
//! (its residual is noise) and none does better at its set, it is chosen;
//! otherwise a model that did better there, or explains the record there,
//! is searched next ([`fit_choosing`]; `--effort high` searches every
//! model).
//! The chosen model's screening fit is its answer when it explains the
//! record (a screening fit is then finished as a full one). When the
//! chosen model's screening residual is not noise, it is fitted
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
use crate::detect::fit::report::{FitReport, Status};
use crate::detect::search::parallel;
use crate::detect::unknowns::{DefectKind, KindChoice};
use crate::error::{Error, Result};

/// `N ln(RSS / N) + p ln N` of a report (module docs); `NaN` without a
/// predicted series. With several sensors or records, each its own noise
/// level estimated from its own residual, `sum_j N_j ln(RSS_j / N_j) + p
/// ln N` (`N` every sensor's samples): the log-likelihood with each
/// sensor's variance profiled out, from the levels the report gives
/// (`sigma_j^2 = RSS_j / (N_j (1 - p / N))`).
pub fn criterion(report: &FitReport) -> f64 {
    let p = report
        .k_selection
        .iter()
        .find(|r| r.k == report.k)
        .map_or(report.params.len(), |r| r.params) as f64;
    if !report.sensors.is_empty() && report.noise_estimated {
        let n: f64 = report.sensors.iter().map(|s| s.samples as f64).sum();
        let keep = 1.0 - p / n;
        let positive = |v: f64| v > 0.0;
        if !positive(keep) || !report.sensors.iter().all(|s| positive(s.sigma)) {
            return f64::NAN;
        }
        let log_lik: f64 = report
            .sensors
            .iter()
            .map(|s| s.samples as f64 * (s.sigma * s.sigma * keep).ln())
            .sum();
        return log_lik + p * n.ln();
    }
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
/// screening fit ([`FitOptions::screen`]: no search of every set after a
/// narrowed answer that does not explain the record; such an answer's
/// noise level is not settled, and it has no intervals). On the wrong
/// models, whose answers never explain the record, the search of every set
/// was most of the choice's cost. A candidate that explains the record is
/// the fit [`screen_options`] gives, and is the answer when chosen.
pub fn candidate_options(opts: &FitOptions) -> FitOptions {
    FitOptions {
        screen: true,
        ..screen_options(opts)
    }
}

/// A candidate damping model's name, the model and its fit.
type Candidate<'n> = (&'n str, Model, Result<FitReport>);

/// A defect set: each defect's kind and position.
pub type Set = [(DefectKind, usize)];

/// The models by the cost of their search, the cheapest first, the order
/// in which [`fit_choosing`] searches them but for a model its fit at the
/// best set so far puts forward. Measured on System 3's 1% record
/// (grounded damping, CPU seconds of each screening fit on one thread):
/// grounded 0.27, rayleigh 0.84, modal 1.25, between 2.31 (its damping is
/// not proportional: complex modes).
pub const ORDER: [&str; 4] = ["grounded", "rayleigh", "modal", "between"];

/// A fit of one candidate model.
pub type FitOne<'a> = &'a dyn Fn(&Model) -> Result<FitReport>;

/// The fits a damping choice makes ([`fit_choosing`]), each of one
/// candidate model.
pub struct ChoiceFits<'a> {
    /// A candidate's screening fit ([`candidate_options`]).
    pub candidate: &'a (dyn Fn(&Model) -> Result<FitReport> + Sync),
    /// A candidate's screening fit of one set only, its values free
    /// ([`FitOptions::set`](super::options::FitOptions::set)).
    pub at: &'a (dyn Fn(&Model, &Set) -> Result<FitReport> + Sync),
    /// The chosen model's fit ([`screen_options`]), where its screening
    /// fit is not the answer and no [`Self::refit`] is given.
    pub chosen: FitOne<'a>,
    /// The fit with the options asked for, where they differ from
    /// [`screen_options`]: made when the chosen model's screening fit does
    /// not explain the record.
    pub refit: Option<FitOne<'a>>,
    /// Search every model (`--effort high`), even when one explains the
    /// record.
    pub every: bool,
    /// Fit the models side by side where they are fitted together (every
    /// model searched, or fitted at a set), by the thread policy
    /// ([`parallel::map`]; the choice does not depend on it).
    pub parallel: bool,
}

/// Choose the damping model (module docs) and return the chosen model's
/// report, its `damping` entry listing every candidate in the order of
/// [`Damping::MODELS`]; evaluations are the sum over the fits, the wall
/// time that of the whole choice.
///
/// The models' positions are searched ([`ChoiceFits::candidate`]) one
/// after the other, [`ORDER`]'s first model first. After each search the
/// models not yet searched are fitted at the best set so far (the set of
/// the searched model with the smallest [`criterion`]) alone (values and
/// damping parameters free, [`ChoiceFits::at`]; each model at a set once;
/// the modal model without the set's damper defects, a kind it does not
/// take, with which the grounded model makes up for modal damping):
/// when that best model explains the record (its residual is noise) and
/// none does better at its set, it is chosen and the others are listed as
/// fitted at its set ([`DampingCandidate::searched`] false); otherwise the
/// models that did better at that set than a best that explains the
/// record, or explain the record there, are searched next, the smallest
/// criterion first, and the others after them in [`ORDER`] (on a record
/// damped between storeys the grounded search fails and the
/// between-storey model explains the record at its set: it is searched
/// next, not Rayleigh and modal damping). When no model is chosen so, and
/// with [`ChoiceFits::every`] (every model searched side by side), the
/// smallest criterion chooses. The chosen model's screening fit is the
/// answer when it explains the record (it is then the fit
/// [`ChoiceFits::chosen`] gives, [`FitReport::screened`]); otherwise the
/// model is fitted again as asked ([`ChoiceFits::refit`]), or, where the
/// options asked for are the screening ones, with [`ChoiceFits::chosen`].
///
/// Why a model that explains the record is not searched against: its
/// residual is already noise, so a model with more free parameters beats it
/// only by a chance fall of the residual's chi-square of more than `ln N`
/// per extra parameter (8.7 for 6001 samples; a chance of 0.3% for one).
/// A model with as many (or fewer) that does better must fit the record at
/// some set better than this model at its own: the check at this model's
/// set finds it when the two sets are the same, the usual case (the
/// defects are the record's, whatever the damping); two explanations at
/// different sets are the case it can miss, which `--effort high` rules
/// out. Measured in the guide ("The damping model chosen where one
/// explains the record"): on 120 records the same model, positions and
/// status as searching every model.
///
/// # Errors
/// The first candidate's error when every candidate fails; the refit's
/// error; a cancellation.
pub fn fit_choosing(model: &Model, fits: &ChoiceFits<'_>) -> Result<FitReport> {
    let started = std::time::Instant::now();
    if fits.every {
        let all = search(model, &Damping::MODELS, fits)?;
        return chosen(best_of(all)?, started, fits);
    }
    let mut searched: Vec<Candidate<'_>> = Vec::new();
    let mut pending: Vec<&str> = ORDER.to_vec();
    let mut at = AtSets::default();
    while !pending.is_empty() {
        let name = pending.remove(0);
        searched.extend(search(model, &[name], fits)?);
        // the best so far against the models not searched yet at its set
        let best = searched
            .iter()
            .filter_map(|(_, _, r)| r.as_ref().ok().map(|r| (criterion(r), r)))
            .filter(|b| b.0.is_finite())
            .min_by(|a, b| a.0.total_cmp(&b.0));
        let Some((bar, r)) = best else {
            continue;
        };
        // one model left needs no order; a best that does not explain the
        // record cannot be chosen by a check at its set
        if pending.len() < 2 && !r.fits_data {
            continue;
        }
        let set: Vec<(DefectKind, usize)> = r.found().iter().map(DefectKind::key_of).collect();
        let others = at.fit(model, &set, &pending, fits)?;
        let holds = |c: &Option<AtSet>| c.as_ref().is_some_and(|c| c.0.criterion >= bar);
        if r.fits_data && others.iter().all(holds) {
            let mut best = best_of(searched)?;
            best.candidates
                .extend(others.into_iter().flatten().map(|c| c.0));
            best.candidates.sort_by_key(|c| model_rank(&c.model));
            best.evaluations += at.spent;
            return chosen(best, started, fits);
        }
        // the models that did better at the best set than a best that
        // explains the record, or explain the record there, are searched
        // next, the smallest criterion first; the others after them, in
        // ORDER (a fit at a set of a model that does not explain the
        // record, with defects it took to make up for its damping, is no
        // ranking: on modally damped records the between-storey model did
        // better there than the modal one)
        let promising = |c: &Option<AtSet>| {
            c.as_ref()
                .filter(|c| c.1 || (r.fits_data && c.0.criterion < bar))
                .map(|c| c.0.criterion)
                .filter(|v| !v.is_nan())
                .unwrap_or(f64::INFINITY)
        };
        let mut order: Vec<(&str, f64)> = pending
            .iter()
            .copied()
            .zip(others.iter().map(promising))
            .collect();
        order.sort_by(|a, b| a.1.total_cmp(&b.1));
        pending = order.into_iter().map(|(n, _)| n).collect();
    }
    let mut best = best_of(searched)?;
    best.evaluations += at.spent;
    chosen(best, started, fits)
}

/// A model's fit at a set: its entry and whether it explains the record.
type AtSet = (DampingCandidate, bool);

/// A model, a set and the model's fit there (`None`: the fit failed).
type Done = (String, Vec<(DefectKind, usize)>, Option<AtSet>);

/// The fits of models at a set ([`ChoiceFits::at`]), each made once: a
/// model is fitted at a set again when a later best has the same set.
#[derive(Default)]
struct AtSets {
    /// `(model, set)` and its fit (`None`: the fit failed).
    done: Vec<Done>,
    /// The evaluations of every fit made.
    spent: usize,
}

impl AtSets {
    /// The entries of the models `names` fitted at `set` (side by side
    /// where not fitted before, taken in their order), `None` where a fit
    /// failed.
    ///
    /// # Errors
    /// A cancellation.
    fn fit(
        &mut self,
        model: &Model,
        set: &Set,
        names: &[&str],
        fits: &ChoiceFits<'_>,
    ) -> Result<Vec<Option<AtSet>>> {
        let find = |done: &[Done], name: &str| {
            done.iter().position(|(n, s, _)| n == name && s[..] == *set)
        };
        let new: Vec<&str> = names
            .iter()
            .copied()
            .filter(|n| find(&self.done, n).is_none())
            .collect();
        let fitted = parallel::map(&new, fits.parallel, 2, |&name| {
            let fit = |m: Model| {
                // a kind of `any` the model's searches do not take (no
                // damper under modal damping, `KindChoice::under`) left
                // out of the set; a kind asked for by name (ground) kept
                let takes = KindChoice::Any.under(m.chain().damping()).kinds();
                let kept: Vec<_> = set
                    .iter()
                    .copied()
                    .filter(|(kind, _)| takes.contains(kind) || !DefectKind::ANY.contains(kind))
                    .collect();
                (fits.at)(&m, &kept)
            };
            (name, model.candidate(name).and_then(fit))
        });
        for (name, r) in fitted {
            let entry = match r {
                Ok(r) => {
                    self.spent += r.evaluations;
                    Some((candidate_of(name, &r, false), r.fits_data))
                }
                Err(Error::Cancelled) => return Err(Error::Cancelled),
                Err(_) => None,
            };
            self.done.push((name.to_string(), set.to_vec(), entry));
        }
        Ok(names
            .iter()
            .map(|n| find(&self.done, n).and_then(|i| self.done[i].2.clone()))
            .collect())
    }
}

/// The screening fits of the models `names` side by side, in their order.
///
/// # Errors
/// A model that cannot be made; a cancellation.
fn search<'n>(
    model: &Model,
    names: &[&'n str],
    fits: &ChoiceFits<'_>,
) -> Result<Vec<Candidate<'n>>> {
    let fitted = parallel::map(names, fits.parallel, 2, |&name| {
        let m = model.candidate(name)?;
        let r = (fits.candidate)(&m);
        Ok((name, m, r))
    });
    let fitted: Vec<Candidate<'n>> = fitted.into_iter().collect::<Result<_>>()?;
    match fitted.iter().any(|c| matches!(c.2, Err(Error::Cancelled))) {
        true => Err(Error::Cancelled),
        false => Ok(fitted),
    }
}

/// The chosen model: the searched candidate with the smallest criterion
/// ([`best_of`]).
struct Best {
    /// The model.
    model: Model,
    /// Its screening fit.
    report: FitReport,
    /// Every candidate's entry.
    candidates: Vec<DampingCandidate>,
    /// The evaluations of every fit so far.
    evaluations: usize,
}

/// The report of the chosen model: its screening fit where that is the
/// fit [`ChoiceFits::chosen`] would give (it explains the record,
/// [`FitReport::screened`] false); else, where the options asked for
/// differ from the screening ones, fitted as asked ([`ChoiceFits::refit`]),
/// and otherwise with [`ChoiceFits::chosen`]. Its
/// `damping` entry lists the candidates; its evaluations are every fit's
/// and its wall time that of the choice from `started`.
fn chosen(best: Best, started: std::time::Instant, fits: &ChoiceFits<'_>) -> Result<FitReport> {
    let Best {
        model: m,
        report,
        candidates,
        mut evaluations,
    } = best;
    // a screening fit that does not explain the record goes straight to the
    // fit as asked when the options asked for differ from the screening
    // ones: that fit searches every set itself where its narrowed answer
    // does not explain the record, and the full fit with the screening
    // options, which searched every set with a residual that could not
    // explain it either (a sensor offset, coloured noise), was most of the
    // choice's cost (76.8 of 89 s on a 12-mass record with damping between
    // storeys and a sensor offset). A white residual: the options asked
    // for (`auto`) would keep the white fit, so the screening fit is the
    // answer.
    let refit_now = report.screened || !report.fits_data;
    let (mut report, spent) = match fits.refit {
        Some(refit) if refit_now => (refit(&m)?, true),
        None if report.screened => ((fits.chosen)(&m)?, true),
        _ => (report, false),
    };
    if spent {
        evaluations += report.evaluations;
    }
    let mut est = DampingEstimate::of(&report, &m);
    est.candidates = candidates;
    report.damping = Some(est);
    report.evaluations = evaluations;
    report.wall_time_s = started.elapsed().as_secs_f64();
    Ok(report)
}

/// A damping model's place in [`Damping::MODELS`], the order of the
/// report's candidates.
fn model_rank(name: &str) -> Option<usize> {
    Damping::MODELS.iter().position(|n| *n == name)
}

/// The candidate entry of a fit.
fn candidate_of(name: &str, r: &FitReport, searched: bool) -> DampingCandidate {
    DampingCandidate {
        model: name.to_string(),
        criterion: criterion(r),
        k: r.k,
        positions: r.found().iter().map(|d| d.at()).collect(),
        searched,
    }
}

/// The searched candidates' entries in the order of [`Damping::MODELS`],
/// the one with the smallest [`criterion`] (the first in that order on a
/// tie) and the evaluations of their fits.
///
/// # Errors
/// The first candidate's error (in that order) when every candidate
/// failed; a cancellation.
fn best_of(mut searched: Vec<Candidate<'_>>) -> Result<Best> {
    searched.sort_by_key(|c| model_rank(c.0));
    let mut best: Option<(f64, Model, FitReport)> = None;
    let mut candidates = Vec::new();
    let mut first_err = None;
    let mut evaluations = 0;
    for (name, m, r) in searched {
        let r = match r {
            Ok(r) => r,
            Err(Error::Cancelled) => return Err(Error::Cancelled),
            Err(e) => {
                candidates.push(DampingCandidate {
                    model: name.to_string(),
                    criterion: f64::NAN,
                    k: 0,
                    positions: vec![],
                    searched: true,
                });
                first_err.get_or_insert(e);
                continue;
            }
        };
        evaluations += r.evaluations;
        let c = candidate_of(name, &r, true);
        if best.as_ref().is_none_or(|(b, ..)| c.criterion < *b) {
            best = Some((c.criterion, m, r));
        }
        candidates.push(c);
    }
    let Some((_, model, report)) = best else {
        return Err(first_err
            .unwrap_or_else(|| Error::invalid("damping", "none", "a damping model that fits")));
    };
    Ok(Best {
        model,
        report,
        candidates,
        evaluations,
    })
}

/// Whether a fit with its damping model given is checked against the other
/// models ([`check_given`]): the damping parameters fitted (`--fit d`) and
/// the model given (not chosen), the noise model left to the fit (`auto`)
/// and taken coloured, and the answer not already a mismatch.
pub fn checks_given(model: &Model, opts: &FitOptions, report: &FitReport) -> bool {
    model.fits_damping()
        && !model.chooses_damping()
        && opts.noise_model == NoiseModelChoice::Auto
        && report.noise_model.as_ref().is_some_and(|n| n.p > 0)
        && report.status != Status::ModelMismatch
}

/// The options the other models are fitted with by [`check_given`]:
/// [`candidate_options`] (white noise, a screening fit) at the number of
/// defects of the given model's answer (`report.k`: the criterion's choice
/// among `0..=4` cost three to five times the fit's own on the coloured
/// records the check runs on; from three defects on, the criterion's
/// choice up to `report.k`, whose nested searches cost less than ranking
/// every set of `report.k`), and without intervals (only the criterion
/// and the whiteness are read).
pub fn check_options(opts: &FitOptions, report: &FitReport) -> FitOptions {
    use crate::detect::fit::options::DefectCount;
    let defects = match report.k {
        k @ 0..=2 => DefectCount::Exactly(k),
        k => DefectCount::Auto { k_max: k },
    };
    FitOptions {
        defects,
        uncertainty: false,
        ..candidate_options(opts)
    }
}

/// A damping model given, whose fit explains the record only with a
/// coloured noise model, checked against the other models: each is fitted
/// with white noise at the answer's number of defects ([`check_options`],
/// by `fit`, in [`ORDER`]), and
/// the first that explains the record with a smaller [`criterion`] makes
/// the answer a `model-mismatch`, its message naming that model and its
/// defects. The colour was then the wrong damping model's misfit, not
/// noise: an AR model whitens a misfit made of the chain's own damped
/// modes, and a defect of another kind (a damper beside a mass) takes up
/// the rest, so the given model's answer can look sure at wrong positions
/// (a Rayleigh record fitted as between-storey damping with every kind
/// sought: a damper at 8 and a mass at 9, for masses at 8 and 15). The
/// models checked are listed in the report's `damping.candidates`, not
/// searched as a choice would, and their evaluations are added.
///
/// Genuinely coloured noise is left alone: no white fit of any model
/// explains it.
///
/// # Errors
/// A cancellation.
pub fn check_given(model: &Model, report: &mut FitReport, fit: FitOne<'_>) -> Result<()> {
    let given = model.chain().damping().name();
    let bar = criterion(report);
    let started = std::time::Instant::now();
    let mut checked = Vec::new();
    let mut better = None;
    for name in ORDER.into_iter().filter(|n| *n != given) {
        let r = match model.candidate(name).and_then(|m| fit(&m)) {
            Ok(r) => r,
            Err(Error::Cancelled) => return Err(Error::Cancelled),
            Err(_) => continue,
        };
        report.evaluations += r.evaluations;
        let c = candidate_of(name, &r, true);
        // NaN (no residual to compare) does not stop the explanation
        let smaller = c.criterion.partial_cmp(&bar).is_none_or(|o| o.is_lt());
        let explains = r.fits_data && r.status != Status::ModelMismatch && smaller;
        checked.push(c);
        if explains {
            better = Some(r);
            break;
        }
    }
    report.wall_time_s += started.elapsed().as_secs_f64();
    let mut est = report
        .damping
        .take()
        .unwrap_or_else(|| DampingEstimate::of(report, model));
    est.candidates = checked;
    est.checked = true;
    report.damping = Some(est);
    let Some(r) = better else {
        return Ok(());
    };
    let other = r.damping.as_ref().map_or("grounded", |d| d.model.as_str());
    let set = crate::Defect::places(&r.found());
    let noise = report.noise_model.as_ref().map_or(0, |n| n.p);
    report.status = Status::ModelMismatch;
    report.resolved = false;
    report.fits_data = false;
    report.message = format!(
        "the damping model given ({given}) explains the record only with an AR({noise}) noise model, and {other} damping explains it with white noise ({set}; criterion {:.4e} against {:.4e}): the colour is the misfit of a wrong damping model, not noise, and this answer may be wrong; fit without --damping to choose the model",
        criterion(&r),
        bar
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::data::observations::{Observations, Series};
    use crate::detect::data::series::TimeData;
    use crate::detect::fit::options::{DefectCount, FitSpec};
    use crate::noise::NoiseLevel;
    use std::sync::Mutex;

    /// What a stub candidate gives: its residual sum of squares as a
    /// multiple of the real fit's, and whether it explains the record.
    type Outcome = (f64, bool);

    /// A real report of a small fit, and the model that chooses damping.
    fn base() -> (FitReport, Model) {
        let truth = crate::scenes::paper_with(5, "mass:2:3.0").unwrap();
        let rec = TimeData::simulate(&truth, 60.0, 0.5, NoiseLevel::RelativeMax(1e-3), 1).unwrap();
        let obs =
            Observations::Series(Series::new(rec.t().to_vec(), rec.y().to_vec(), None).unwrap());
        let (model, opts) = FitSpec {
            fit: Some("d".into()),
            ..FitSpec::new(5)
        }
        .build()
        .unwrap();
        assert!(model.chooses_damping());
        let opts = FitOptions {
            defects: DefectCount::Exactly(1),
            uncertainty: false,
            ..opts
        };
        let r = crate::detect::fit::fit(&obs, &model.candidate("grounded").unwrap(), &opts);
        (r.unwrap(), model)
    }

    /// `base` with its residual scaled to `rss` times its sum of squares.
    fn stub(base: &FitReport, (rss, fits): Outcome) -> FitReport {
        let mut r = base.clone();
        r.fits_data = fits;
        r.screened = !fits;
        r.damping = None;
        for v in &mut r.predicted.as_mut().unwrap().residual {
            *v *= rss.sqrt();
        }
        r
    }

    /// The choice over stub candidates (`searched[i]` and `at[i]` the
    /// outcomes of [`Damping::MODELS`]`[i]`'s search and fit at a set):
    /// the chosen model, the models searched and fitted at a set (sorted by
    /// name) and the candidates' `searched` flags.
    fn choose(
        searched: [Outcome; 4],
        at: [Outcome; 4],
        every: bool,
    ) -> (String, Vec<String>, Vec<String>, Vec<bool>) {
        let (base, model) = base();
        let index = |m: &Model| {
            let name = m.chain().damping().name();
            Damping::MODELS.iter().position(|n| *n == name).unwrap()
        };
        let calls = Mutex::new((Vec::new(), Vec::new()));
        let candidate = |m: &Model| {
            calls
                .lock()
                .unwrap()
                .0
                .push(Damping::MODELS[index(m)].to_string());
            Ok(stub(&base, searched[index(m)]))
        };
        let at_set = |m: &Model, set: &Set| {
            assert_eq!(set.len(), base.found().len());
            calls
                .lock()
                .unwrap()
                .1
                .push(Damping::MODELS[index(m)].to_string());
            Ok(stub(&base, at[index(m)]))
        };
        let chosen = |m: &Model| Ok(stub(&base, searched[index(m)]));
        let r = fit_choosing(
            &model,
            &ChoiceFits {
                candidate: &candidate,
                at: &at_set,
                chosen: &chosen,
                refit: None,
                every,
                parallel: true,
            },
        )
        .unwrap();
        let est = r.damping.unwrap();
        let names: Vec<&str> = est.candidates.iter().map(|c| c.model.as_str()).collect();
        assert_eq!(names, Damping::MODELS);
        let flags = est.candidates.iter().map(|c| c.searched).collect();
        // the fits side by side are called in any order
        let (mut s, mut a) = calls.into_inner().unwrap();
        s.sort();
        a.sort();
        (est.model, s, a, flags)
    }

    /// No model explains the record: the chosen one is fitted as asked when
    /// the options asked for differ from the screening ones (never with the
    /// screening options in full first), and with the screening options
    /// otherwise.
    #[test]
    fn a_choice_that_explains_nothing_goes_straight_to_the_fit_as_asked() {
        let (base, model) = base();
        // between fits best; none explains the record
        let rss = |m: &Model| match m.chain().damping().name() {
            "between" => 0.5,
            _ => 1.0,
        };
        let calls = Mutex::new(Vec::new());
        let log = |what: &str, m: &Model| {
            let name = m.chain().damping().name().to_string();
            calls.lock().unwrap().push(format!("{what} {name}"));
        };
        let candidate = |m: &Model| Ok(stub(&base, (rss(m), false)));
        let at_set = |m: &Model, _: &Set| Ok(stub(&base, (rss(m), false)));
        let chosen = |m: &Model| {
            log("chosen", m);
            Ok(stub(&base, (rss(m), false)))
        };
        let asked = |m: &Model| {
            log("asked", m);
            Ok(stub(&base, (rss(m), true)))
        };
        for refit in [true, false] {
            calls.lock().unwrap().clear();
            let r = fit_choosing(
                &model,
                &ChoiceFits {
                    candidate: &candidate,
                    at: &at_set,
                    chosen: &chosen,
                    refit: refit.then_some(&asked as FitOne<'_>),
                    every: false,
                    parallel: false,
                },
            )
            .unwrap();
            assert_eq!(r.damping.unwrap().model, "between");
            let want = match refit {
                true => "asked between",
                false => "chosen between",
            };
            assert_eq!(*calls.lock().unwrap(), [want]);
            assert_eq!(r.fits_data, refit);
        }
    }

    /// With several sensors the criterion is every sensor's log-likelihood
    /// at its own level: a sensor fitted twice as badly (its level doubled)
    /// raises it by `N_j ln 4`, and every sensor's samples count.
    #[test]
    fn the_criterion_of_several_sensors_counts_each_at_its_level() {
        use crate::detect::fit::report::SensorEstimate;
        let (mut r, _) = base();
        let sensor = |samples, sigma| SensorEstimate {
            record: 0,
            at: 1,
            kind: "displacement".into(),
            samples,
            sigma,
            whiteness_p: 0.5,
            fits_data: true,
        };
        r.noise_estimated = true;
        r.sensors = vec![sensor(400, 1e-3), sensor(600, 2e-3)];
        let p = r.k_selection.iter().find(|k| k.k == r.k).unwrap().params as f64;
        let keep = 1.0 - p / 1000.0;
        let want = 400.0 * (1e-6 * keep).ln() + 600.0 * (4e-6 * keep).ln() + p * 1000f64.ln();
        let c = criterion(&r);
        assert!((c - want).abs() < 1e-9 * want.abs(), "{c} {want}");
        r.sensors[0].sigma = 2e-3;
        assert!((criterion(&r) - c - 400.0 * 4f64.ln()).abs() < 1e-6);
        r.sensors[1].sigma = 0.0;
        assert!(criterion(&r).is_nan());
    }

    #[test]
    fn the_first_model_that_explains_the_record_is_checked_at_its_set() {
        let (no, yes) = (false, true);
        let every = ["between", "grounded", "modal", "rayleigh"];
        // (searched, at a set, every, chosen, searched (sorted), fitted at
        // a set (sorted), the candidates' flags in the order of MODELS:
        // grounded, between, rayleigh, modal)
        type Case<'a> = (
            [Outcome; 4],
            [Outcome; 4],
            bool,
            &'a str,
            &'a [&'a str],
            &'a [&'a str],
            [bool; 4],
        );
        let cases: [Case<'_>; 6] = [
            // grounded explains; the others do no better at its set: they
            // are fitted there only
            (
                [(1.0, yes), (0.5, yes), (0.5, yes), (0.5, yes)],
                [(9.0, no), (1.0, yes), (2.0, no), (3.0, no)],
                false,
                "grounded",
                &["grounded"],
                &["between", "modal", "rayleigh"],
                [true, false, false, false],
            ),
            // rayleigh does better at grounded's set: it is searched,
            // explains the record, and modal and between do no better at
            // its set
            (
                [(1.0, yes), (0.5, yes), (0.9, yes), (0.5, yes)],
                [(9.0, no), (2.0, no), (0.95, yes), (0.99, yes)],
                false,
                "rayleigh",
                &["grounded", "rayleigh"],
                // each model fitted at the set once
                &["between", "modal", "rayleigh"],
                [true, false, true, false],
            ),
            // grounded does not explain the record: the others are fitted
            // at its set and searched in that order; modal, the best there,
            // explains the record, and between and rayleigh do no better at
            // its set (rayleigh, next in ORDER, is never searched)
            (
                [(1.0, no), (0.65, yes), (0.9, no), (0.6, yes)],
                [(1.0, no), (0.7, no), (1.0, no), (0.6, yes)],
                false,
                "modal",
                &["grounded", "modal"],
                &["between", "modal", "rayleigh"],
                [true, false, false, true],
            ),
            // nothing explains the record: every model searched (in the
            // order of their fits at the best set), the smallest criterion
            // chosen
            (
                [(1.0, no), (0.8, no), (0.9, no), (0.7, no)],
                [(1.0, yes); 4],
                false,
                "modal",
                &every,
                &["between", "modal", "rayleigh"],
                [true; 4],
            ),
            // a model that explains the record but is beaten by one
            // searched before it does not stop the search
            (
                [(0.5, no), (0.8, no), (0.9, yes), (0.7, no)],
                [(1.0, yes); 4],
                false,
                "grounded",
                &every,
                &["between", "modal", "rayleigh"],
                [true; 4],
            ),
            // every model searched when asked, none at a set
            (
                [(1.0, yes), (0.5, yes), (0.9, yes), (0.6, yes)],
                [(0.1, yes); 4],
                true,
                "between",
                &every,
                &[],
                [true; 4],
            ),
        ];
        for (i, (searched, at, all, model, s, a, flags)) in cases.into_iter().enumerate() {
            let got = choose(searched, at, all);
            assert_eq!(
                got,
                (
                    model.to_string(),
                    s.iter().map(|n| n.to_string()).collect(),
                    a.iter().map(|n| n.to_string()).collect(),
                    flags.to_vec()
                ),
                "case {i}"
            );
        }
    }

    /// A damper defect of the best set is left out of the set the modal
    /// model is fitted at (it damps each mode; its searches take no
    /// damper), and kept for the others.
    #[test]
    fn a_damper_is_left_out_of_the_modal_models_set() {
        let (mut base, model) = base();
        let mut damper = base.defects[0].clone();
        damper.kind = "damper";
        damper.at = 4;
        damper.value = 0.3;
        base.defects.push(damper);
        let sets = Mutex::new(Vec::new());
        let candidate = |_: &Model| Ok(stub(&base, (1.0, false)));
        let at_set = |m: &Model, set: &Set| {
            let name = m.chain().damping().name().to_string();
            sets.lock().unwrap().push((name, set.to_vec()));
            Ok(stub(&base, (1.0, false)))
        };
        fit_choosing(
            &model,
            &ChoiceFits {
                candidate: &candidate,
                at: &at_set,
                chosen: &candidate,
                refit: None,
                every: false,
                parallel: false,
            },
        )
        .unwrap();
        let mut sets = sets.into_inner().unwrap();
        sets.sort();
        let full: Vec<(DefectKind, usize)> = base.found().iter().map(DefectKind::key_of).collect();
        assert_eq!(full.len(), 2);
        assert!(full.contains(&(DefectKind::Damper, 4)));
        let without: Vec<_> = full
            .iter()
            .copied()
            .filter(|p| p.0 != DefectKind::Damper)
            .collect();
        // fitted once each at grounded's set (the best never changes)
        let want = [
            ("between".to_string(), full.clone()),
            ("modal".to_string(), without),
            ("rayleigh".to_string(), full),
        ];
        assert_eq!(sets, want);
    }

    #[test]
    fn a_given_model_is_checked_only_when_its_fit_took_coloured_noise() {
        use crate::detect::data::noise_model::NoiseModel;
        use crate::detect::fit::record::NoiseModelReport;
        let (white, choosing) = base();
        let given = choosing.candidate("rayleigh").unwrap();
        let opts = FitOptions::default();
        let mut coloured = white.clone();
        coloured.noise_model = Some(NoiseModelReport::new(
            &NoiseModel::ar(vec![0.9]).unwrap(),
            1e-3,
            1,
            true,
        ));
        // a model given, d fitted, auto noise that took AR(1)
        assert!(checks_given(&given, &opts, &coloured));
        // white noise; the model chosen; noise asked for; already a mismatch
        assert!(!checks_given(&given, &opts, &white));
        assert!(!checks_given(&choosing, &opts, &coloured));
        let ar = FitOptions {
            noise_model: NoiseModelChoice::Ar(None),
            ..opts.clone()
        };
        assert!(!checks_given(&given, &ar, &coloured));
        let mut mismatch = coloured.clone();
        mismatch.status = Status::ModelMismatch;
        assert!(!checks_given(&given, &opts, &mismatch));
        // the other models are fitted at the answer's number of defects,
        // with the criterion's choice from three on
        assert_eq!(
            check_options(&opts, &white).defects,
            DefectCount::Exactly(white.k)
        );
        let mut three = white.clone();
        three.k = 3;
        assert_eq!(
            check_options(&opts, &three).defects,
            DefectCount::Auto { k_max: 3 }
        );
        assert_eq!(
            check_options(&opts, &three).noise_model,
            NoiseModelChoice::White
        );
    }
}
