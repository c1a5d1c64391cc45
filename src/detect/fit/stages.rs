//! The fit's stages over record models ([`super::record`]): the white fit,
//! then, when its residual is not white (or a record model is asked for),
//! the refits with the criterion's noise model and nuisances until the AR
//! coefficients stop moving. The last stage only (the white fit's, when no
//! record model follows it) is refitted at its settled noise level and,
//! when a narrowed search's answer does not explain the record, searched
//! over every set.

use super::assemble::fits_data;
use super::engine::{Engine, Given, KFit};
use super::general::Hypothesis;
use super::record::{self, RecordModel, MAX_REFITS};
use super::report::KRow;
use super::{choose_k, estimated_level, first_sigma, fit_every_k, misfit_of, settle_sigma, Model};
use super::{FitOptions, NoiseSpec};
use crate::chain::Chain;
use crate::detect::data::nuisance::Nuisance;
use crate::detect::data::observations::{Observations, Series};
use crate::detect::misfit::MisfitKind;
use crate::detect::unknowns::{by_position, DefectKind};
use crate::error::Result;

/// One stage: the engine it ran on, its fits of every k, the final noise
/// level, the evaluations, and the criterion's choice of k.
pub(super) struct Stage<'a> {
    pub(super) engine: Engine<'a>,
    pub(super) fits: Vec<KFit>,
    pub(super) sigma: f64,
    pub(super) estimated: bool,
    pub(super) evaluations: usize,
    pub(super) chosen: usize,
    pub(super) rows: Vec<KRow>,
    pub(super) criterion: String,
    /// The searches may be narrowed from the fits at one defect fewer: no
    /// narrowed search has failed to explain the record (after one has,
    /// the later stages search every set at once).
    pub(super) narrow: bool,
    /// Why the answer is doubtful when the criterion's choice was stepped
    /// down past a null defect to an answer that is not the rest of it
    /// ([`without_null_defects`]).
    pub(super) doubt: Option<String>,
    /// The noise level the stage's fits started from.
    start: f64,
    /// Whether the criterion's choice (before any step down past null
    /// defects) explains the record.
    explained: bool,
    /// Whether an estimated noise level has been settled (the fits refitted
    /// at the largest model's estimate when it differs by more than a
    /// factor 2, [`super::settle_sigma`]).
    settled: bool,
}

impl Stage<'_> {
    /// The chosen fit.
    pub(super) fn best(&self) -> &KFit {
        &self.fits[self.chosen]
    }

    /// The chosen fit's residual `x - model` (nuisances removed).
    fn residual(&self) -> Option<&[f64]> {
        self.best().predicted.as_ref().map(|(_, r)| r.as_slice())
    }

    /// Whether its noise level is settled and its answer explains the
    /// record: a screening fit is then the fit a full one would be.
    pub(super) fn settled_and_explained(&self) -> bool {
        self.settled && self.explained
    }

    /// The chosen fit's best chain.
    fn chain(&self) -> Result<Chain> {
        self.best().ranked[0].to_chain(self.engine.model.chain())
    }
}

/// Fit with the record model `record` from noise level `sigma`; with
/// `narrow`, the searches narrowed from the fits at one defect fewer first,
/// and with `last`, the noise level settled and every set searched when
/// their choice does not explain the record ([`settled`], [`widened`]; a
/// stage that a record model may follow leaves both until it is known to
/// be the last).
#[allow(clippy::too_many_arguments)]
fn run<'a>(
    obs: &'a Observations,
    model: &'a Model,
    opts: &'a FitOptions,
    given: Option<Given>,
    record: RecordModel,
    sigma: f64,
    estimated: bool,
    narrow: bool,
    last: bool,
) -> Result<Stage<'a>> {
    let engine = Engine {
        obs,
        model,
        opts,
        misfit: misfit_of(obs, opts),
        prepared: std::sync::Mutex::new(None),
        given,
        support: std::sync::Mutex::new(None),
        record,
    };
    // a screening fit is compared by its residual's criterion, which the
    // noise level does not enter: its level is settled only when it
    // explains the record (it may then be the answer, [`settled`])
    let settle = last && !opts.screen;
    let (fits, first, evaluations) = fit_every_k(&engine, sigma, estimated, narrow, settle)?;
    let mut stage = finish(engine, fits, [sigma, first], estimated, evaluations, narrow)?;
    // a known level needs no settling
    stage.settled = settle || (last && !estimated);
    match last {
        true => self::last(stage),
        false => Ok(stage),
    }
}

/// The last stage: [`settled`], then [`widened`].
///
/// # Errors
/// As [`settle_sigma`] and [`widened`].
fn last(stage: Stage<'_>) -> Result<Stage<'_>> {
    widened(settled(stage)?)
}

/// `stage` with its estimated noise level settled, if it was not: a
/// screening fit's only when it explains the record, so that it is then
/// the fit a full one would be (the same fits at the same levels; a full
/// one searches every set only where its answer does not explain the
/// record, [`widened`]).
///
/// # Errors
/// As [`settle_sigma`].
fn settled(stage: Stage<'_>) -> Result<Stage<'_>> {
    let screened = stage.engine.opts.screen && !stage.explained;
    if stage.settled || !stage.estimated || screened {
        return Ok(stage);
    }
    let Stage {
        engine,
        fits,
        start,
        narrow,
        evaluations,
        ..
    } = stage;
    let (fits, spent) = settle_sigma(&engine, fits, start, narrow)?;
    let level = estimated_level(&fits);
    finish(
        engine,
        fits,
        [start, level],
        true,
        evaluations + spent,
        narrow,
    )
}

/// The stage of `fits` made from noise level `start` to `level`: the
/// criterion's choice of `k`, stepped down past null defects.
///
/// # Errors
/// As [`choose_k`].
fn finish<'a>(
    engine: Engine<'a>,
    fits: Vec<KFit>,
    [start, level]: [f64; 2],
    estimated: bool,
    evaluations: usize,
    narrow: bool,
) -> Result<Stage<'a>> {
    let (chosen, rows, criterion) = choose_k(&fits, level, estimated, engine.opts.criterion)?;
    let explained = fits_data(&fits[chosen], level, estimated);
    let best: Vec<KBest<'_>> = fits
        .iter()
        .map(|f| (f.k, &f.ranked[0], f.chi2_at(level, estimated)))
        .collect();
    let (chosen, doubt) = without_null_defects(&best, chosen, engine.model.chain());
    let sigma = reported_sigma(engine.obs, &fits[chosen], level, estimated);
    Ok(Stage {
        engine,
        fits,
        sigma,
        estimated,
        evaluations,
        chosen,
        rows,
        criterion,
        narrow,
        doubt,
        start,
        explained,
        settled: true,
    })
}

/// `stage` again with every set searched when a narrowed search's answer
/// does not explain the record (the narrowed fits kept when that fails).
///
/// # Errors
/// Only [`crate::Error::Cancelled`].
fn widened(stage: Stage<'_>) -> Result<Stage<'_>> {
    let narrowed = stage.fits.iter().any(|f| f.searched.is_some());
    if !narrowed
        || stage.explained
        || stage.engine.opts.screen
        || !every_set_fits(&stage.engine, &stage.fits)?
    {
        return Ok(stage);
    }
    let (start, estimated) = (stage.start, stage.estimated);
    match fit_every_k(&stage.engine, start, estimated, false, true) {
        Ok((every, level, spent)) => {
            let evaluations = stage.evaluations + spent;
            finish(
                stage.engine,
                every,
                [start, level],
                estimated,
                evaluations,
                false,
            )
        }
        Err(e @ crate::Error::Cancelled) => Err(e),
        Err(_) => Ok(stage),
    }
}

/// The noise level of the report: for a record with an estimated level,
/// the chosen fit's own residual estimate (the same as with its `k` given,
/// whatever the largest `k` fitted), else `sigma` (given, or for Laplace
/// values the largest model's estimate, which their chi-square test of the
/// chosen model is measured against).
fn reported_sigma(obs: &Observations, chosen: &KFit, sigma: f64, estimated: bool) -> f64 {
    match obs {
        Observations::Series(_) if estimated => chosen.sigma_hat.max(f64::MIN_POSITIVE),
        _ => sigma,
    }
}

/// A number of defects' best answer and its chi-square at the stage's
/// level ([`without_null_defects`]).
type KBest<'h> = (usize, &'h Hypothesis, f64);

/// The largest rise of the chi-square, per defect dropped, of a step down
/// past defects null within their standard errors ([`without_null_defects`]):
/// two standard errors' worth (a null defect's removal moves it by at most
/// about one).
const NULL_RISE: f64 = 4.0;

/// The criterion's choice, stepped down while the chosen fit holds a free
/// defect whose value equals the uniform value within its standard error
/// or `1e-9` relative (on an exact record the chi-square keeps falling with
/// rounding, and such a "defect" is none). With the doubt to report when
/// the larger fit without its null defects is not the smaller answer (a
/// weak defect more, and the null one fitted where it is not: a nested
/// search of a record with a deep fourth mass gave masses 3, 4, 6 and 9
/// with 6 null, and then the three-defect answer 3, 4, 6 as `converged`,
/// where the truth was 3, 4, 9 and 18). Every null defect is dropped at
/// once: the rest is compared with the fit of its own size. A defect null
/// within its standard error only (not to rounding) whose fit without it
/// has a chi-square (at the stage's level) more than
/// [`NULL_RISE`] higher per dropped defect is no null: its standard error,
/// a linear measure, misjudged it (n = 40, a mass at 3 of 2 under 10%
/// noise, every kind sought: a spring at 3 within its error of 1, whose
/// fit without it rose by 117 and did not explain the record).
fn without_null_defects(
    fits: &[KBest<'_>],
    mut chosen: usize,
    base: &Chain,
) -> (usize, Option<String>) {
    let known = base.defects().len();
    // each null defect, and whether it is null to rounding
    let nulls = |h: &Hypothesis| -> Vec<((DefectKind, usize), bool)> {
        h.defects
            .iter()
            .zip(&h.std_errors)
            .filter_map(|(d, se)| {
                let u = d.base_value(base);
                let free = !base.defects().contains(d);
                let gap = (d.value() - u).abs();
                let rounding = gap <= 1e-9 * u.abs();
                (free && (rounding || gap <= *se)).then_some((DefectKind::key_of(d), rounding))
            })
            .collect()
    };
    let (mut doubt, first) = (None, chosen);
    while fits[chosen].0 > 0 && fits[chosen].1.defects.len() > known {
        let found = nulls(fits[chosen].1);
        if found.is_empty() {
            break;
        }
        let null: Vec<(DefectKind, usize)> = found.iter().map(|(p, _)| *p).collect();
        // the fit without every null defect, else with one fewer
        let k = fits[chosen].0;
        let Some(i) = (fits.iter().position(|f| f.0 + null.len() == k))
            .or_else(|| fits.iter().position(|f| f.0 + 1 == k))
        else {
            break;
        };
        let rise = fits[i].2 - fits[chosen].2;
        let dropped = (k - fits[i].0) as f64;
        if !found.iter().all(|(_, rounding)| *rounding) && rise > NULL_RISE * dropped {
            break;
        }
        // the rest of the larger answer should be the smaller one
        let mut rest: Vec<_> = fits[chosen]
            .1
            .key()
            .into_iter()
            .filter(|p| !null.contains(p))
            .collect();
        let mut smaller = fits[i].1.key();
        by_position(&mut rest);
        by_position(&mut smaller);
        if chosen == first && rest != smaller {
            let names = |v: &[(DefectKind, usize)]| {
                v.iter()
                    .map(|(kind, at)| format!("{}@{at}", kind.name()))
                    .collect::<Vec<_>>()
                    .join(", ")
            };
            doubt = Some(format!(
                "the criterion's best fit has {} defects, with {} at the uniform value within its standard error; the rest of it ({}) is not this answer: the data cannot tell these hypotheses apart",
                fits[chosen].0,
                names(&null),
                names(&rest)
            ));
        }
        chosen = i;
    }
    (chosen, doubt)
}

/// Whether searching every set at each `k` of `fits` stays within the
/// options' `max_sets` (the narrowed searches are kept otherwise).
///
/// # Errors
/// As the unknowns' construction.
fn every_set_fits(engine: &Engine<'_>, fits: &[KFit]) -> Result<bool> {
    let max = engine.opts.max_sets as f64;
    for f in fits {
        if engine.space_size(f.k)? > max {
            return Ok(false);
        }
    }
    Ok(true)
}

/// Every stage of a fit (see the module docs); the last is the answer, its
/// evaluations those of all stages.
///
/// # Errors
/// As [`fit_every_k`], [`record::select_record`] and the record model's misfit.
pub(super) fn fit_stages<'a>(
    obs: &'a Observations,
    model: &'a Model,
    opts: &'a FitOptions,
    given: Option<Given>,
) -> Result<Stage<'a>> {
    let (sigma0, estimated) = first_sigma(obs, opts);
    let scene = given.is_some();
    let first = RecordModel {
        scales: sensor_scales(obs, opts),
        ..RecordModel::default()
    };
    // a known sigma is of white noise: AR only when asked for
    let noise_choice = match (opts.noise, opts.noise_model) {
        (NoiseSpec::Sigma(_), record::NoiseModelChoice::Auto) => record::NoiseModelChoice::White,
        (_, c) => c,
    };
    // a record model may follow the white fit: refitting at the settled
    // noise level, and searching every set when the white answer does not
    // explain the record, are then left to the last stage (coloured noise
    // or a sensor's drift, not a missed set, is the usual cause; and
    // coloured noise's level is off the first estimate from the finest
    // scales, so each stage would be fitted twice)
    let record_may_follow = matches!(obs, Observations::Series(s) if s.others().is_empty())
        && !scene
        && misfit_of(obs, opts) == MisfitKind::Time
        && record::open(noise_choice, opts.nuisance);
    let mut stage = run(
        obs,
        model,
        opts,
        given,
        first,
        sigma0,
        estimated,
        true,
        !record_may_follow,
    )?;
    stage.engine.record.converged = true;
    let Observations::Series(series) = obs else {
        return Ok(stage);
    };
    if !series.others().is_empty() {
        return rescaled(stage, sigma0, estimated);
    }
    if !record_may_follow {
        return Ok(stage);
    }
    let forced = record::forced(noise_choice, opts.nuisance);
    if !forced && fits_data(stage.best(), stage.sigma, estimated) {
        return last(stage);
    }
    let Some(r) = stage.residual() else {
        return last(stage);
    };
    let choice = record::select_record(r, series.t(), noise_choice, opts.nuisance)?;
    let mut rec = RecordModel {
        noise: choice.noise,
        nuisance: choice.nuisance,
        ..RecordModel::default()
    };
    if rec.is_plain() {
        return last(stage);
    }
    let mut sigma = if estimated {
        choice.innovation_var.sqrt().max(f64::MIN_POSITIVE)
    } else {
        sigma0
    };
    let stage = refine(series, stage, &mut rec, &mut sigma, estimated, noise_choice)?;
    last(stage)
}

/// Refits after the first fit of a record of several sensors with an
/// estimated noise level, while a sensor's level relative to the first's
/// (from the residuals at the answer) differs from the one fitted with by
/// more than [`SCALE_TOLERANCE`] (at most [`MAX_REFITS`]). The sensors'
/// records are taken as white (no noise model, no nuisance).
///
/// # Errors
/// As [`fit_every_k`].
fn rescaled(mut stage: Stage<'_>, sigma0: f64, estimated: bool) -> Result<Stage<'_>> {
    let (obs, model, opts) = (stage.engine.obs, stage.engine.model, stage.engine.opts);
    let mut refits = 0;
    while estimated && refits < MAX_REFITS {
        let levels = stage.best().sensor_levels();
        let scales: Vec<f64> = levels.iter().skip(1).map(|s| s / levels[0]).collect();
        let old = &stage.engine.record.scales;
        let moved = scales
            .iter()
            .zip(old)
            .any(|(a, b)| !(a / b).ln().is_finite() || (a / b).ln().abs() > SCALE_TOLERANCE.ln());
        if !moved {
            break;
        }
        let rec = RecordModel {
            scales,
            ..RecordModel::default()
        };
        refits += 1;
        let evaluations = stage.evaluations;
        stage = run(
            obs,
            model,
            opts,
            None,
            rec,
            sigma0,
            estimated,
            stage.narrow,
            true,
        )?;
        stage.evaluations += evaluations;
        stage.engine.record.converged = true;
    }
    Ok(stage)
}

/// The largest ratio between a sensor's relative noise level estimated
/// from the residuals and the one a fit used before it is refitted.
pub const SCALE_TOLERANCE: f64 = 1.25;

/// The further sensors' noise levels relative to the first's to start
/// from: 1 (a given level holds for every sensor), or the ratios of the
/// levels of their finest scales ([`super::first_guess`]).
fn sensor_scales(obs: &Observations, opts: &FitOptions) -> Vec<f64> {
    let (Observations::Series(s), NoiseSpec::Auto) = (obs, opts.noise) else {
        return Vec::new();
    };
    let first = super::first_guess(s);
    s.others()
        .iter()
        .map(|o| super::first_guess(o) / first)
        .collect()
}

/// The refits with the record model `rec` until the criterion's AR order
/// and coefficients from the latest residual stop changing (at most
/// [`MAX_REFITS`]); a re-chosen white model without nuisances keeps the
/// latest fit.
fn refine<'a>(
    series: &Series,
    mut stage: Stage<'a>,
    rec: &mut RecordModel,
    sigma: &mut f64,
    estimated: bool,
    choice: record::NoiseModelChoice,
) -> Result<Stage<'a>> {
    let (obs, model, opts) = (stage.engine.obs, stage.engine.model, stage.engine.opts);
    let mut evaluations = stage.evaluations;
    loop {
        rec.screen = screen_estimate(series, rec, &stage.chain()?, *sigma)?;
        rec.iterations += 1;
        stage = run(
            obs,
            model,
            opts,
            None,
            rec.clone(),
            *sigma,
            estimated,
            stage.narrow,
            false,
        )?;
        evaluations += stage.evaluations;
        let mut done = rec.noise.is_white();
        if !done {
            if let Some(r) = stage.residual() {
                let (noise, var, still) = record::reestimate(r, series.t(), &rec.noise, choice)?;
                let white = !still && noise.is_white() && rec.nuisance == Nuisance::None;
                if white {
                    // the coloured model's answer leaves white noise: the
                    // colour may have been the first fit's misfit, so the
                    // white fit from this residual's level is the answer
                    // when it explains the record
                    let level = if estimated { var.sqrt() } else { *sigma };
                    let plain = last(plain(obs, model, opts, level, estimated, stage.narrow)?)?;
                    evaluations += plain.evaluations;
                    if plain.explained {
                        let mut plain = plain;
                        plain.evaluations = evaluations;
                        return Ok(plain);
                    }
                }
                done = still || white;
                if !done {
                    rec.noise = noise;
                    if estimated {
                        *sigma = var.sqrt().max(f64::MIN_POSITIVE);
                    }
                }
            }
        }
        if done || rec.iterations >= MAX_REFITS {
            stage.engine.record.iterations = rec.iterations;
            stage.engine.record.converged = done;
            stage.evaluations = evaluations;
            return Ok(stage);
        }
    }
}

/// The white fit without nuisances from noise level `sigma` ([`refine`]),
/// to be settled and widened by [`last`].
///
/// # Errors
/// As [`fit_every_k`].
fn plain<'a>(
    obs: &'a Observations,
    model: &'a Model,
    opts: &'a FitOptions,
    sigma: f64,
    estimated: bool,
    narrow: bool,
) -> Result<Stage<'a>> {
    let sigma = sigma.max(f64::MIN_POSITIVE);
    let mut stage = run(
        obs,
        model,
        opts,
        None,
        RecordModel::default(),
        sigma,
        estimated,
        narrow,
        false,
    )?;
    stage.engine.record.converged = true;
    Ok(stage)
}

/// The nuisances at `chain` under `rec` (empty without nuisances): what the
/// Laplace screen's record is corrected by.
fn screen_estimate(
    series: &Series,
    rec: &RecordModel,
    chain: &Chain,
    sigma: f64,
) -> Result<Vec<f64>> {
    rec.misfit(rec.time_data(series, sigma)?)?
        .nuisance_values(chain)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chain::Defect;

    fn answer(defects: &[(usize, f64, f64)]) -> Hypothesis {
        Hypothesis::from_parts(
            defects
                .iter()
                .map(|&(at, m, _)| Defect::Mass { at, m })
                .collect(),
            defects.iter().map(|&(_, _, se)| se).collect(),
            vec![],
            0.0,
        )
    }

    /// A defect at the uniform value within its error is dropped: to the
    /// smaller answer when it is the rest, with a doubt when it is not;
    /// not when the smaller answer's chi-square rises by more than
    /// `NULL_RISE` per defect dropped (the error misjudged it), unless the
    /// defect is null to rounding.
    #[test]
    fn a_null_defect_is_dropped_unless_its_removal_costs_more_than_its_error_says() {
        let base = Chain::paper(10).unwrap();
        let k1 = answer(&[(3, 2.0, 0.01)]);
        let other = answer(&[(5, 2.0, 0.01)]);
        let null_at_7 = answer(&[(3, 2.0, 0.01), (7, 1.02, 0.05)]);
        let rounding = answer(&[(3, 2.0, 0.01), (7, 1.0 + 1e-12, 0.0)]);
        let fits = |one: &'static str, two: &Hypothesis, rise: f64| -> (usize, Option<String>) {
            let h1 = if one == "rest" { &k1 } else { &other };
            let best: Vec<KBest<'_>> = vec![(1, h1, 100.0 + rise), (2, two, 100.0)];
            without_null_defects(&best, 1, &base)
        };
        assert_eq!(fits("rest", &null_at_7, 0.5), (0, None));
        let (i, doubt) = fits("other", &null_at_7, 0.5);
        assert_eq!(i, 0);
        assert!(doubt.unwrap().contains("mass@7 at the uniform value"));
        // a rise of 30: mass 7's removal costs far more than its error says
        assert_eq!(fits("rest", &null_at_7, 30.0), (1, None));
        assert_eq!(fits("rest", &null_at_7, NULL_RISE + 0.1), (1, None));
        assert_eq!(fits("rest", &null_at_7, NULL_RISE - 0.1), (0, None));
        // null to rounding: dropped whatever the rise (an exact record)
        assert_eq!(fits("rest", &rounding, 1e6), (0, None));
        // no null defect: kept
        let real = answer(&[(3, 2.0, 0.01), (7, 1.5, 0.05)]);
        assert_eq!(fits("rest", &real, 0.5), (1, None));
    }
}
