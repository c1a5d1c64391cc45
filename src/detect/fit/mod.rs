//! Fitting defects to a user's observations: `fit(&Observations, &Model,
//! &FitOptions) -> FitReport`.
//!
//! The data come first ([`crate::detect::data::observations`]): a sampled
//! record of the observed mass, or Laplace values; nothing here knows a
//! truth. The [`Model`] says what is known of the chain (n, k, d, gamma,
//! uniform mass, known defects) and which chain parameters to fit; the
//! [`FitOptions`] say what to look for and how:
//!
//! * **misfit** ([`MisfitKind`]): for a sampled series the default is the
//!   time-domain chi-square (`time`), the likelihood of the samples
//!   themselves (white noise, no transform in between). In the noise
//!   studies (`docs/noise-study.md`) it and the whitened Bromwich line find
//!   every position of the six reference systems in 20 of 20 records up to
//!   1% noise, where the real axis fails on deep defects from 1e-3 on; its
//!   standard errors are the best calibrated (the truth within 3 SE for
//!   99.7% of the values), and with masses judged within 5% it led at 1%
//!   noise (S3: 0.70 against 0.45 for the Bromwich line). Its shortlist
//!   comes from the whitened Bromwich chi-square, and only the sets that
//!   could win there are refitted in the time domain
//!   ([`general::Setup::time_slack`]). `bromwich` and `real-axis` are the whitened
//!   Laplace chi-squares of the transformed series ([`general::laplace_obs`]).
//!   For Laplace values the misfit is the chi-square at the given nodes.
//! * **noise** ([`NoiseSpec`]): given, or estimated (`auto`): a first guess
//!   from the record's finest scales ([`noise::high_frequency_sigma`]), then
//!   the best fit's residual `sqrt(RSS / (N - p))` ([`noise::residual_sigma`]),
//!   refitting when the two differ by more than a factor 2. Standard errors
//!   are then those of the estimated sigma.
//! * **number of defects** ([`DefectCount`]): given, or `auto`: every `k` in
//!   `0..=k_max` is fitted and the criterion ([`Criterion`], BIC by default)
//!   chooses; the table is in the report.
//! * **kinds** ([`KindChoice`](crate::detect::unknowns::KindChoice)): mass, spring, damper, ground (a spring from a mass to the ground) or any (mass, spring or damper).
//! * **method** ([`FitMethod`]): `enumerate` (every position set, values by
//!   bounded Levenberg-Marquardt) works for every kind; `greedy`
//!   ([`greedy`]: one defect at a time, candidates
//!   scored by rank-one updates, then moves, restarts) too, for long chains
//!   and many defects; `ga`, `nelder-mead` and `pso` search mass defects
//!   (and refuse other kinds with a typed error); their best position set is
//!   then refitted like enumeration's. For mass defects on Laplace values
//!   of the paper's setup (fixed ends, displacement of mass 1, impulse, no
//!   known defect or chain parameter) the enumeration ranks the position
//!   sets with the paper's Woodbury kernel
//!   ([`crate::detect::misfit::Misfit::at_nodes`], the same chi-square) and
//!   refits the best: chosen by the unknowns, not asked for.
//! * **visibility**: for mass defects on a user's data the report says how
//!   deep the data see a 10% mass change ([`visibility::Visibility`]) and names
//!   fitted defects beyond that depth;
//! * **hidden defects**: with the number of defects left to the criterion,
//!   every mass and spring the answer leaves unchanged is halved and doubled
//!   in turn; one the data would not show makes the status
//!   `not-identifiable` ([`unseen`]);
//! * **every value free** instead of a few defects: [`fit_profile`]
//!   (`springmass fit --profile masses|springs|both`).
//!
//! ```
//! use springmass::{Chain, Defect, noise::NoiseLevel};
//! use springmass::detect::data::observations::{Observations, Series};
//! use springmass::detect::fit::{fit, DefectCount, FitOptions, Model};
//! // a "measured" record (here simulated with 0.1% noise; the fit is not told)
//! let truth = Chain::paper(6)?.with_defect(Defect::Mass { at: 3, m: 3.0 })?;
//! let rec = springmass::detect::data::series::TimeData::simulate(&truth, 100.0, 0.25, NoiseLevel::RelativeMax(1e-3), 1)?;
//! let obs = Observations::Series(Series::new(rec.t().to_vec(), rec.y().to_vec(), None)?);
//! let report = fit(&obs, &Model::new(6)?, &FitOptions { defects: DefectCount::Exactly(1), ..FitOptions::default() })?;
//! assert_eq!(report.defects[0].at, 3);
//! assert!((report.defects[0].value - 3.0).abs() < 4.0 * report.defects[0].se);
//! assert!(report.noise_estimated);
//! # Ok::<(), springmass::Error>(())
//! ```

pub mod ambient;
mod assemble;
pub mod chainfit;
pub mod damping;
pub mod damping_scales;
pub mod effort;
mod engine;
pub mod general;
mod goodness;
pub mod greedy;
pub mod identifiable;
pub mod identify;
pub mod intervals;
pub mod judge;
mod local;
pub mod modal_locate;
pub mod modal_scene;
pub mod modal_update;
pub mod model;
mod narrow;
pub mod noise;
pub mod options;
pub mod paper;
pub mod posterior;
pub mod prior;
pub mod profile;
pub mod record;
mod record_report;
pub mod report;
pub mod scene_fit;
pub mod select;
pub mod setup;
pub mod spectral;
mod stages;
pub mod trigger;
pub mod unseen;
pub mod visibility;

pub use crate::detect::search::FitMethod;
pub use model::{parse_params, Model};
pub use options::{DefectCount, FitOptions, NoiseSpec, TriggerSpec, DEFAULT_K_MAX};
pub use report::{
    Alternative, DefectEstimate, FitReport, KRow, ModeEstimate, ParamEstimate, Predicted,
    SensorEstimate, Status,
};
pub use scene_fit::fit_scene;
pub use select::Criterion;

use crate::detect::data::observations::{Observations, Series};
use crate::detect::misfit::MisfitKind;
use crate::error::Result;
use engine::{krow, stop_early, Engine, KFit};
use std::time::Instant;

/// Fit defects to `obs` (see the module docs).
///
/// # Errors
/// Invalid options ([`FitOptions::validate`]); too many hypotheses
/// (`max_sets`); a numerical failure of every hypothesis.
pub fn fit(obs: &Observations, model: &Model, opts: &FitOptions) -> Result<FitReport> {
    fit_with(obs, model, opts, None)
}

/// Fit every mass (spring, both) of the chain instead of a few defects: the
/// whole-profile inversion ([`profile`]), with [`fit`] for its restart from
/// a defect fit.
///
/// # Errors
/// As [`profile::fit_profile_with`].
pub fn fit_profile(
    obs: &Observations,
    model: &Model,
    opts: &profile::ProfileOptions,
) -> Result<profile::ProfileReport> {
    crate::cancel::checked(profile::fit_profile_with(obs, model, opts, Some(&fit)))
}

/// [`fit`] with unknowns and search details given by the caller (the scene
/// path, [`paper::fit`]); the same pipeline.
fn fit_with(
    obs: &Observations,
    model: &Model,
    opts: &FitOptions,
    given: Option<engine::Given>,
) -> Result<FitReport> {
    // the damping model: chosen among every model, or reported when not
    // the paper's ([`damping`])
    if model.chooses_damping() && given.is_none() {
        // the candidates screened with white noise (the criterion is the
        // raw residual's), the chosen one fitted as asked
        let screen = damping::screen_options(opts);
        let candidate = damping::candidate_options(opts);
        let refit = screen.noise_model != opts.noise_model || screen.nuisance != opts.nuisance;
        let at = |m: &Model, set: &damping::Set| {
            // one set: nothing to search, and compared by its criterion only
            let o = FitOptions {
                defects: DefectCount::Exactly(set.len()),
                set: set.to_vec(),
                method: FitMethod::Enumerate,
                uncertainty: false,
                ..candidate.clone()
            };
            fit_with(obs, m, &o, None)
        };
        let asked = |m: &Model| fit_with(obs, m, opts, None);
        return damping::fit_choosing(
            model,
            &damping::ChoiceFits {
                candidate: &|m| fit_with(obs, m, &candidate, None),
                at: &at,
                chosen: &|m| fit_with(obs, m, &screen, None),
                refit: refit.then_some(&asked as damping::FitOne<'_>),
                every: opts.effort == effort::Effort::High,
                parallel: opts.parallel,
            },
        );
    }
    let scene = given.is_some();
    let mut r = fit_with_model(obs, model, opts, given)?;
    if !model.chain().damping().is_grounded() {
        r.damping = Some(damping::DampingEstimate::of(&r, model));
    }
    // a damping model given whose fit needed coloured noise: checked
    // against the others with white noise
    if !scene && damping::checks_given(model, opts, &r) {
        let other = damping::check_options(opts, &r);
        damping::check_given(model, &mut r, &|m| fit_with(obs, m, &other, None))?;
    }
    Ok(r)
}

/// [`fit_with`] for the model's damping model.
fn fit_with_model(
    obs: &Observations,
    model: &Model,
    opts: &FitOptions,
    given: Option<engine::Given>,
) -> Result<FitReport> {
    opts.validate(obs, model)?;
    // the scene path's records are the model's own, started by the blow
    let retime = match given {
        None => trigger::plan(obs, model, opts.trigger)?,
        Some(_) => Vec::new(),
    };
    match (&retime[..], obs) {
        ([t0, others @ ..], Observations::Series(rec)) => {
            let auto = opts.trigger == options::TriggerSpec::Auto;
            // the time is refined with the white fit's chain (the record
            // model left to the fit at the refined time); that white fit is
            // the answer when the time stays and it explains the record,
            // unless a record model was asked for. It is a screening fit
            // (`damping::candidate_options`): one that does not explain the
            // record only gives the time its chain, and the search of every
            // set that a full fit adds then was most of a late blow's cost
            // (13.2 of 25 s on a Rayleigh-damped System 3 record with a
            // sensor offset, `--fit d`)
            let white = damping::candidate_options(opts);
            let first = |o: &Observations| fit_record(o, model, &white, None);
            let keeps = !record::forced(opts.noise_model, opts.nuisance);
            let first: Option<(&trigger::FitRun<'_>, bool)> =
                (damping::screen_options(opts) != *opts).then_some((&first, keeps));
            let refine = (auto, opts.nuisance.widest());
            let at = |t0: f64| {
                trigger::fit_retimed(rec, model, t0, refine, first, |o| {
                    fit_record(o, model, opts, None)
                })
            };
            let mut report = at(*t0)?;
            // a record cut short: the blow's other possible times, when the
            // first does not explain the record (the first that does; a
            // time whose fit fails is passed over, the first report kept)
            for &t in others {
                if report.fits_data {
                    break;
                }
                match at(t) {
                    Ok(other) if other.fits_data => report = other,
                    Err(crate::Error::Cancelled) => return Err(crate::Error::Cancelled),
                    _ => {}
                }
            }
            doubt_coloured_lead_in(&mut report);
            Ok(report)
        }
        _ => fit_record(obs, model, opts, given),
    }
}

/// [`fit_with`] on a record that starts with the blow (or Laplace values).
fn fit_record(
    obs: &Observations,
    model: &Model,
    opts: &FitOptions,
    given: Option<engine::Given>,
) -> Result<FitReport> {
    let scene = given.is_some();
    let t0 = Instant::now();
    let stage = stages::fit_stages(obs, model, opts, given)?;
    let (engine, sigma, estimated) = (&stage.engine, stage.sigma, stage.estimated);
    let mut report = engine.report(
        stage.best(),
        sigma,
        estimated,
        stage.rows.clone(),
        stage.criterion.clone(),
        stage.evaluations,
        t0,
    )?;
    note_narrowed(&mut report, &stage.fits);
    if let Some(why) = &stage.doubt {
        doubt_converged(&mut report, why.clone());
    }
    if opts.effort != effort::Effort::Normal {
        report.method = format!("{} [effort {}]", report.method, opts.effort.name());
    }
    // how deep the data see (mass defects of a user's data; not the
    // scene path, whose data are the model's own)
    let one_sensor = match obs {
        Observations::Series(s) => s.others().is_empty(),
        Observations::Laplace(_) => true,
    };
    if !scene && one_sensor && report.defects.iter().all(|d| d.kind == "mass") {
        add_visibility(&mut report, engine, sigma)?;
    }
    // a screening fit is finished as a full one where it explains the
    // record (settled, [`stages`]): it may then be the answer
    report.screened = opts.screen && !stage.settled_and_explained();
    if opts.uncertainty && !report.screened {
        add_uncertainty(&mut report, &stage)?;
    }
    Ok(report)
}

/// The report's search is exhaustive only when every `k`'s was: where the
/// answer's own search ranked every set but another `k`'s was narrowed
/// from one defect fewer ([`narrow`]), the method says which.
fn note_narrowed(report: &mut FitReport, fits: &[KFit]) {
    let narrowed: Vec<String> = fits
        .iter()
        .filter(|f| f.searched.is_some())
        .map(|f| f.k.to_string())
        .collect();
    if narrowed.is_empty() || !report.exhaustive {
        return;
    }
    report.exhaustive = false;
    report.method = format!(
        "{} (the searches at k = {} narrowed from the answers at one defect fewer)",
        report.method,
        narrowed.join(", ")
    );
}

/// The misfit: the options' (time by default) for a series; for Laplace
/// values the real axis when every node is real, else the Bromwich line.
fn misfit_of(obs: &Observations, opts: &FitOptions) -> MisfitKind {
    match obs {
        Observations::Series(_) => opts.misfit.unwrap_or(MisfitKind::Time),
        Observations::Laplace(l) => {
            if l.s().iter().all(|z| z.im == 0.0) {
                MisfitKind::RealAxis
            } else {
                MisfitKind::Bromwich
            }
        }
    }
}

/// The smallest noise level a record's estimate may take, relative to its
/// largest `|x|`: the precision of the fitted model's own response (modal
/// sums and the generators it is checked against agree to about this). On
/// a record noise-free to that precision the residuals at every `k` are
/// rounding, whose differences would otherwise read as overwhelming
/// evidence for more defects (an exact System 2 record had its answer's
/// probability below 0.001 and a "defect" more at the uniform value).
pub(super) const SIGMA_FLOOR: f64 = 1e-12;

/// A series' first noise level: the level of its finest scales
/// ([`noise::high_frequency_sigma`]), at least [`SIGMA_FLOOR`] times its
/// largest `|x|`.
fn first_guess(s: &Series) -> f64 {
    noise::high_frequency_sigma(s.x())
        .max(SIGMA_FLOOR * s.max_abs())
        .max(1e-300)
}

/// The noise level to start from, and whether it is estimated: given, or a
/// first guess from the record's finest scales (1 for Laplace values).
fn first_sigma(obs: &Observations, opts: &FitOptions) -> (f64, bool) {
    match (obs, opts.noise) {
        (_, NoiseSpec::Sigma(s)) => (s, false),
        (Observations::Series(s), NoiseSpec::Auto) => (first_guess(s), true),
        (Observations::Laplace(_), NoiseSpec::Auto) => (1.0, true),
    }
}

/// Every number of defects asked for, fitted at `sigma` (stopping early
/// when `auto`); with an estimated noise level and `settle`, refitted at
/// the largest model's estimate when it differs by more than a factor 2
/// ([`settle_sigma`]), and the final level read from the largest model
/// fitted (it holds every defect the others hold). With `narrowed`, each
/// search may be narrowed from the fit at one defect fewer ([`narrow`]);
/// without, every set is searched. Returns the fits, the final level and
/// the evaluations.
fn fit_every_k(
    engine: &Engine,
    sigma: f64,
    estimated: bool,
    narrowed: bool,
    settle: bool,
) -> Result<(Vec<KFit>, f64, usize)> {
    let ks: Vec<usize> = match engine.opts.defects {
        DefectCount::Exactly(k) => vec![k],
        DefectCount::Auto { k_max } => (0..=k_max).collect(),
    };
    let auto = matches!(engine.opts.defects, DefectCount::Auto { .. });
    let (mut fits, mut evaluations) = fit_ks(engine, &ks, sigma, narrowed, auto)?;
    if !estimated {
        return Ok((fits, sigma, evaluations));
    }
    if settle {
        let (settled, spent) = settle_sigma(engine, fits, sigma, narrowed)?;
        (fits, evaluations) = (settled, evaluations + spent);
    }
    let level = estimated_level(&fits);
    Ok((fits, level, evaluations))
}

/// The noise level estimated from `fits`: the largest model's (it holds
/// every defect the others hold).
fn estimated_level(fits: &[KFit]) -> f64 {
    let last = fits.last().expect("at least one k");
    last.sigma_hat.max(f64::MIN_POSITIVE)
}

/// `fits` made at the noise level `sigma`, refitted (the same numbers of
/// defects) at the largest model's estimate when it differs from `sigma` by
/// more than a factor 2. Returns the fits and the evaluations spent.
///
/// # Errors
/// As [`Engine::fit_k`].
fn settle_sigma(
    engine: &Engine,
    fits: Vec<KFit>,
    sigma: f64,
    narrowed: bool,
) -> Result<(Vec<KFit>, usize)> {
    let s_hat = fits.last().expect("at least one k").sigma_hat;
    let moved = s_hat > 0.0 && !(0.5..=2.0).contains(&(s_hat / sigma));
    if !moved {
        return Ok((fits, 0));
    }
    let ks: Vec<usize> = fits.iter().map(|f| f.k).collect();
    fit_ks(engine, &ks, s_hat, narrowed, false)
}

/// The fits with each number of defects of `ks` at noise level `sigma`,
/// each at least as good as the one before ([`Engine::monotone`]; with
/// `narrowed`, searched from it), then the backward pass; with `stop`, the
/// loop ends early where more defects do not help ([`stop_early`]) or
/// cannot win ([`Engine::no_room_for_more`]).
/// Returns the fits and the evaluations spent.
///
/// # Errors
/// As [`Engine::fit_k`].
fn fit_ks(
    engine: &Engine,
    ks: &[usize],
    sigma: f64,
    narrowed: bool,
    stop: bool,
) -> Result<(Vec<KFit>, usize)> {
    let mut evaluations = 0;
    let mut fits: Vec<KFit> = Vec::with_capacity(ks.len());
    for &k in ks {
        let f = crate::cancel::checked(engine.fit_k_after(k, sigma, fits.last(), narrowed))?;
        let f = match fits.last() {
            Some(prev) => engine.monotone(prev, f, sigma)?,
            None => f,
        };
        evaluations += f.evaluations;
        fits.push(f);
        if stop
            && (stop_early(&fits, engine.obs.len(), engine.opts.effort)
                || engine.no_room_for_more(&fits))
        {
            break;
        }
    }
    evaluations += backward_pass(engine, &mut fits, sigma)?;
    Ok((fits, evaluations))
}

/// Every fit made no worse than the next one's best answer with a defect
/// dropped ([`Engine::backward`]), from the largest `k` down. Returns the
/// evaluations spent.
fn backward_pass(engine: &Engine, fits: &mut Vec<KFit>, sigma: f64) -> Result<usize> {
    let mut spent = 0;
    for i in (1..fits.len()).rev() {
        if let Some(f) = engine.backward(&fits[i - 1], &fits[i], sigma)? {
            spent += f.evaluations.saturating_sub(fits[i - 1].evaluations);
            fits[i - 1] = f;
            spent += searched_again(engine, fits, i, sigma)?;
        }
    }
    Ok(spent)
}

/// After the backward rule has bettered `fits[i - 1]`: a search at
/// `fits[i]` narrowed from the answers at one defect fewer drew its sets
/// from the answers just beaten, so it is searched again from the better
/// one and kept where it is better (and the fit after it made no worse
/// than it, [`Engine::monotone`]). Returns the evaluations spent. (n = 23,
/// masses at 3, 4, 9 and 18, 1% noise: the nested search at four defects,
/// drawn from 3, 4 and 6, missed the truth; once the backward rule had
/// found 3, 4 and 9, the answer was those three, `converged`, where the
/// truth has a chi-square 31 lower.)
///
/// # Errors
/// As [`Engine::fit_k`].
fn searched_again(engine: &Engine, fits: &mut Vec<KFit>, i: usize, sigma: f64) -> Result<usize> {
    if fits[i].searched.is_none() {
        return Ok(0);
    }
    let again = crate::cancel::checked(engine.fit_k(fits[i].k, sigma, Some(&fits[i - 1])))?;
    let again = engine.monotone(&fits[i - 1], again, sigma)?;
    let spent = again.evaluations;
    if again.rss >= fits[i].rss {
        return Ok(spent);
    }
    fits[i] = again;
    if i + 1 < fits.len() {
        let next = fits.remove(i + 1);
        let next = engine.monotone(&fits[i], next, sigma)?;
        fits.insert(i + 1, next);
    }
    Ok(spent)
}

/// The number of defects: the only fit, or the criterion's choice. Returns
/// the chosen fit's index, the evidence table and the criterion's name.
fn choose_k(
    fits: &[KFit],
    sigma: f64,
    estimated: bool,
    criterion: Criterion,
) -> Result<(usize, Vec<KRow>, String)> {
    if fits.len() == 1 {
        let rows = vec![krow(&fits[0], sigma, estimated, f64::NAN)];
        return Ok((0, rows, "given".to_string()));
    }
    let mf: Vec<select::ModelFit> = fits
        .iter()
        .map(|f| select::ModelFit::new(f.k, f.chi2_at(sigma, estimated), f.params))
        .collect();
    let sel = select::select(&mf, fits[0].n_data, criterion)?;
    let value = |e: &select::Evidence| match criterion {
        Criterion::Aic => e.aic,
        Criterion::Bic => e.bic,
        Criterion::ChiSquare { .. } => e.p_value,
    };
    let rows = fits
        .iter()
        .zip(&sel.evidence)
        .map(|(f, e)| krow(f, sigma, estimated, value(e)))
        .collect();
    let i = fits
        .iter()
        .position(|f| f.k == sel.chosen)
        .expect("chosen among the fits");
    let name = match criterion {
        Criterion::Aic => "aic",
        Criterion::Bic => "bic",
        Criterion::ChiSquare { .. } => "chi2 p-value",
    };
    Ok((i, rows, name.to_string()))
}

/// The report's visibility: how deep the data see a
/// [`VISIBILITY_CHANGE`] of mass, from the last prepared Laplace data.
fn add_visibility(report: &mut FitReport, engine: &Engine, sigma: f64) -> Result<()> {
    let chain = engine.model.chain().clone().with_defects(report.found())?;
    if chain.baseline().is_some() && chain.n() > VISIBILITY_BASELINE_MAX_N {
        // every Jacobian column rebuilds the nonuniform chain's Green's
        // function (O(n) per node): O(n^2) per node, left out of long chains
        return Ok(());
    }
    let observe = match engine.obs {
        Observations::Series(s) => s.measurement().sensor().at,
        Observations::Laplace(l) => l.sensor().at,
    };
    let positions: Vec<usize> = report.found().iter().map(|d| d.at()).collect();
    if let Some((at_sigma, (l, ..))) = engine.last_prepared() {
        report.visibility = visibility::visibility(
            &l,
            &chain,
            observe,
            VISIBILITY_CHANGE,
            &positions,
            sigma / at_sigma,
        )
        .ok();
    }
    Ok(())
}

/// The report's intervals ([`intervals`]) and the probabilities over the
/// hypotheses ([`posterior`]).
///
/// # Errors
/// Cancelled ([`crate::cancel`]); a failure of either computation
/// leaves its part of the report out rather than losing the fit.
fn add_uncertainty(report: &mut FitReport, stage: &stages::Stage<'_>) -> Result<()> {
    let f = stage.best();
    let engine = &stage.engine;
    let Ok(data) = engine.measurement_at(f.sigma_fit) else {
        return Ok(());
    };
    let ratio = stage.sigma / f.sigma_fit;
    let best = f
        .ranked
        .first()
        .and_then(|h| local::Local::of(h, engine.model, data.as_ref()).ok());
    if let Some(local) = &best {
        let found = crate::cancel::checked(intervals::intervals(
            local,
            data.as_ref(),
            ratio,
            engine.opts.level,
        ));
        if let Ok(ivs) = found {
            place_intervals(report, local, &ivs);
        } else if let Err(e @ crate::Error::Cancelled) = found {
            return Err(e);
        }
    }
    report.posterior = crate::cancel::checked(posterior::posterior(
        stage,
        &engine.opts.prior,
        (f.sigma_fit, data.as_ref()),
        best.as_ref(),
    ))
    .ok();
    crate::cancel::check()?;
    doubt_improbable_answer(report);
    Ok(())
}

/// Below this probability the answer is not called resolved: another
/// hypothesis (or several together) is more probable.
pub const ANSWER_PROBABILITY_MIN: f64 = 0.5;

/// A converged answer the posterior gives less than
/// [`ANSWER_PROBABILITY_MIN`] becomes `not-identifiable`, naming the most
/// probable hypothesis.
fn doubt_improbable_answer(report: &mut FitReport) {
    let Some(post) = &report.posterior else {
        return;
    };
    if post.answer_probability >= ANSWER_PROBABILITY_MIN {
        return;
    }
    let top = post
        .hypotheses
        .first()
        .map_or("another".to_string(), |h| crate::Defect::places(&h.defects));
    let why = format!(
        "the answer has probability {:.2} only (most probable: {top}); the data cannot tell these hypotheses apart",
        post.answer_probability
    );
    doubt_converged(report, why);
}

/// A blow detected after a quiet lead-in of a record whose noise the fit
/// found coloured: the detector's level is the finest scales', which a
/// coloured lead-in wanders past before the blow (measured: AR(0.9) noise
/// and a 10-unit lead-in placed the blow early on every one of 20 records),
/// so a `converged` answer is doubted and the message asks for the time.
fn doubt_coloured_lead_in(report: &mut FitReport) {
    let lead_in = report
        .trigger
        .as_ref()
        .is_some_and(|t| t.detected && t.dropped >= crate::detect::data::trigger::LEAD_IN);
    let coloured = report.noise_model.as_ref().is_some_and(|m| m.p > 0);
    if lead_in && coloured {
        doubt_converged(
            report,
            "the blow's time was detected after a lead-in whose noise is coloured (AR), where the detector can place it early: give the time with --trigger T to be sure".into(),
        );
    }
}

/// A `converged` answer becomes `not-identifiable`, not resolved, for the
/// reason `why`; any other status already says the answer is not sure, and
/// its message gains the reason.
fn doubt_converged(report: &mut FitReport, why: String) {
    if report.status == Status::Converged {
        report.status = Status::NotIdentifiable;
        report.resolved = false;
        report.message = why;
    } else if !report.message.contains(&why) {
        report.message = format!("{}; {why}", report.message);
    }
}

/// Each interval on its defect (by kind and position) or chain parameter
/// (by name).
fn place_intervals(report: &mut FitReport, local: &local::Local, ivs: &[intervals::Interval]) {
    for (p, iv) in local.params.iter().zip(ivs) {
        match p {
            crate::sensitivity::Param::Defect(i) => {
                let Some(d) = local.chain.defects().get(*i) else {
                    continue;
                };
                if let Some(e) = report
                    .defects
                    .iter_mut()
                    .find(|e| e.at == d.at() && e.kind == d.kind() && !e.known)
                {
                    e.interval = Some([iv.lo, iv.hi]);
                    e.interval_method = Some(iv.method);
                }
            }
            q => {
                let name = general::param_name(q);
                if let Some(e) = report.params.iter_mut().find(|e| e.name == name) {
                    e.interval = Some([iv.lo, iv.hi]);
                    e.interval_method = Some(iv.method);
                }
            }
        }
    }
}

/// The longest chain on a baseline whose report states its visibility.
pub const VISIBILITY_BASELINE_MAX_N: usize = 60;

/// The relative mass change the report's visibility is stated for.
pub const VISIBILITY_CHANGE: f64 = 0.1;
