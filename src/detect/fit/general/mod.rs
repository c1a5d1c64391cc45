//! Fitting defects to a noisy sampled series `y_i = x_1(t_i) + sigma z_i`, with
//! one of three misfits, and the pieces of the noise study.
//!
//! * [`MisfitKind::RealAxis`]: the paper's residual on `[0, 300]` (80-node
//!   `gl-log` rule of [`crate::detect::misfit::quadrature`]), the data being the
//!   Laplace transform of the series ([`crate::time::series`]) at the nodes;
//! * [`MisfitKind::Bromwich`]: the same on the line `s = sigma_B + i omega`,
//!   `omega in [0, W]` (default `sigma_B = 0.05`, a few over the record length
//!   `T = 200` so that the unrecorded tail weighs `e^{-sigma_B T}`; `W = 4`, above
//!   the chain's band `2 sqrt(k/mass)`), 80 nodes (`gl-uniform` 10x8);
//! * [`MisfitKind::Time`]: the time-domain chi-square ([`TimeMisfit`]).
//!
//! **Weighting**: the noise level belongs to the data; a Laplace misfit is
//! a true chi-square by default (see [`crate::detect::fit::setup`]).
//!
//! **Search.** Laplace misfits: every position set is first *screened*: 4
//! Levenberg-Marquardt iterations over its masses from `m = 2` on 20 of the
//! 80 whitened nodes ([`LaplaceObs::screen`]: their marginal covariance,
//! whitened on its own, so still a true chi-square), and the best
//! `max(screen_keep = 40, C(n, k) / 20)` sets go on to the coarse pass proper
//! ([`Setup::coarse_iter`] iterations on every node, analytic Jacobian). Both
//! fit each set on the rational form of its Laplace model
//! ([`crate::detect::misfit::laplace_sets`]: per node a ratio of two multilinear
//! polynomials in the defect values, their coefficients formed once per set
//! from Green's data shared by every set), where it applies, instead of a
//! transfer sweep per node and evaluation; the best `shortlist` sets are then
//! fitted to convergence from
//! that point and from `m = 0.5` (ahead of a time-domain refit only where
//! the first does not explain the values to their noise), and ranked. The time misfit costs a modal
//! decomposition per evaluation (about 1.5 ms for `n = 20`), so it refines
//! the Bromwich shortlist: its best two position sets, and any other within
//! a Bromwich chi-square of 25 of the best ([`Setup::time_slack`]), are
//! refitted in the time domain (exact Jacobian, [`TimeMisfit::jacobian`])
//! and re-ranked by their time-domain chi-square. The Bromwich values are a
//! linear projection of the record, so a set's Bromwich chi-square is the
//! part of its time chi-square that the projection sees: on the datafit
//! benchmark's records the shortlist's time gaps were 1.0 to 1.9 times
//! their Bromwich gaps, and a set 25 behind on the line cannot win. Cost: `C(n, k)` screens on 20
//! nodes, `screen_keep` short fits, `shortlist` full fits. On the noise
//! study's systems (S1-S4, C3a, C3b) at 1e-3 and 1e-2 noise the earlier
//! path's winner ranks at most 12th on the screen (test
//! `screen_and_slack_keep_the_reference_winner`); [`Setup::reference`] keeps that
//! path (every set through the coarse pass, time Jacobians by differences).
//!
//! **General fit** ([`fit_general`], [`fit_noisy_general`]): defects of kind
//! mass, spring, damper or any of them ([`Unknowns`]) at unknown (or
//! known) positions, and uniform chain parameters (`d`, `gamma`, `k`, `mass`)
//! fitted alongside. Coarse pass over every `(kind, position)` hypothesis on
//! Laplace data (defect values only, chain parameters at their starting
//! values; rayon, result independent of the thread count: ranked by
//! `(chi2, hypothesis)`), then the shortlist with the chain parameters, in
//! the time domain for the time misfit. Every [`Hypothesis`] carries its
//! defects, fitted chain parameters, chi-square and standard errors.
//!
//! ```
//! use springmass::{Chain, Defect, noise::NoiseLevel, sensitivity::Param};
//! use springmass::detect::data::series::TimeData;
//! use springmass::detect::fit::general::{fit_noisy_general, GeneralOptions, Setup};
//! use springmass::detect::misfit::MisfitKind;
//! use springmass::detect::unknowns::{Unknowns, KindChoice};
//! let truth = Chain::paper(5)?.with_defect(Defect::Spring { at: 2, k: 0.5 })?;
//! let data = TimeData::simulate(&truth, 100.0, 0.5, NoiseLevel::RelativeMax(1e-3), 1)?;
//! let unknowns = Unknowns::free(5, &[KindChoice::Any], &[Param::D])?;
//! let fit = fit_noisy_general(&truth.uniform().with_d(0.12)?, &data, &unknowns,
//!     MisfitKind::Time, &Setup::new()?, &GeneralOptions::default())?;
//! let best = &fit.ranked[0];
//! assert_eq!(best.key()[0].1, 2);
//! assert_eq!(best.defects[0].kind(), "spring");
//! let d = best.param("d").unwrap();
//! assert!((d.value - 0.1).abs() < 4.0 * d.std_error);
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::chain::{Chain, Defect};
use crate::detect::data::laplace::LaplaceObs;
use crate::detect::data::series::TimeData;
use crate::detect::fit::identify::{identify, Alternative, FittedDefect, Identifiability};
use crate::detect::misfit::laplace_sets::SetTables;
use crate::detect::misfit::time::TimeMisfit;
use crate::detect::misfit::MisfitKind;
use crate::detect::search::parallel;
use crate::detect::unknowns::{KindPositions, Unknowns};
use crate::error::{Error, Result};
use serde::Serialize;
use std::collections::HashMap;

mod hypothesis;
mod sets;

pub use super::setup::{laplace_obs, laplace_obs_under, Setup};
use hypothesis::rank;
pub use hypothesis::{param_name, FittedParam, Hypothesis};
use sets::{better, fit_pairs, fit_pairs_coarse, fit_pairs_fast, starts, Fitted, Tol};
pub(crate) use sets::{fit_pairs_from, fit_placed_from};

/// Which of the shortlist's Laplace fits `fits` (in shortlist order) are
/// refitted in the time domain: the best and the runner-up by the Laplace
/// chi-square, and every other set within `slack` of the best.
///
/// Why the others can be left out: the whitened Bromwich values are a linear
/// projection of the record, so a set's Bromwich chi-square is (up to the
/// model-error variance, which only lowers it) the part of its time-domain
/// chi-square that the projection sees, `chi2_T = chi2_B + C` with `C` the
/// chi-square of the residual's other components. `C` is the same noise for
/// every set plus what the projection misses of the set's misfit, minus a
/// cross term of about one standard normal variable squared at worst; so a
/// set whose Bromwich gap to the best exceeds `slack = 25` (five standard
/// deviations) cannot win in the time domain. Measured on the datafit
/// benchmark's records: the time gaps of the shortlist were 1.0 to 1.9
/// times their Bromwich gaps (`C` never below the best set's).
fn time_refits(fits: &[Result<Fitted>], slack: f64) -> Vec<bool> {
    let mut order: Vec<usize> = (0..fits.len()).filter(|&i| fits[i].is_ok()).collect();
    let chi2 = |i: usize| fits[i].as_ref().map_or(f64::INFINITY, |f| f.hyp.chi2);
    order.sort_by(|&a, &b| chi2(a).total_cmp(&chi2(b)).then(a.cmp(&b)));
    let mut go = vec![false; fits.len()];
    if let Some(&best) = order.first() {
        let floor = chi2(best);
        for (rank, &i) in order.iter().enumerate() {
            go[i] = rank < 2 || chi2(i) - floor <= slack;
        }
    }
    go
}

/// `f` over `items`, in parallel (rayon, [`parallel::map`]: never nested)
/// or not; the output keeps the order of `items`.
fn map_maybe_par<T: Sync, U: Send>(
    items: &[T],
    parallel: bool,
    f: impl Fn(&T) -> U + Sync + Send,
) -> Vec<U> {
    parallel::map(items, parallel, 2, f)
}

/// Options of [`fit_general`].
#[derive(Clone, Debug, PartialEq)]
pub struct GeneralOptions {
    /// Fit hypotheses in parallel (rayon); the result does not depend on it
    /// (default true).
    pub parallel: bool,
    /// Largest number of hypotheses (default 200 000).
    pub max_sets: usize,
    /// Rounds when chain parameters are fitted: after each, the coarse pass
    /// is repeated with the chain parameters at the best fit's values
    /// (default 2).
    pub rounds: usize,
    /// The chain-parameter values the first round starts from (a chain of
    /// the same `n`, whose uniform part is taken); `None`: the base
    /// chain's (default). The fit at `k` defects starts from the answer
    /// at `k - 1`; the bounds of the chain parameters are the base's.
    pub start: Option<Chain>,
}

impl Default for GeneralOptions {
    fn default() -> Self {
        GeneralOptions {
            parallel: true,
            max_sets: 200_000,
            rounds: 2,
            start: None,
        }
    }
}

/// A round whose best fit left every chain parameter within this many
/// standard errors of the values the round started from is the last: the
/// next would rank the sets at practically the same values.
const SETTLED_SE: f64 = 0.5;

/// The result of [`fit_general`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct GeneralFit {
    /// The shortlist, refitted (defect values and chain parameters), best first.
    pub ranked: Vec<Hypothesis>,
    /// Hypotheses of the coarse pass (per round).
    pub hypotheses: usize,
    /// The coarse pass's best sets (the fine pass's shortlist, last round),
    /// best first: the ranking before the time-domain refits dropped some.
    pub shortlist: Vec<KindPositions>,
    /// Residual evaluations, all passes.
    pub evaluations: usize,
    /// Number of residuals of the final misfit (chi-square degrees of freedom
    /// plus the number of fitted values).
    pub residuals: usize,
}

/// The general noisy fit: defects of `unknowns` (mass, spring, damper or any,
/// at unknown or known positions) and its chain parameters, on `base` (its
/// uniform part and chain-parameter starting values).
///
/// * **coarse pass** (parallel, deterministic): every hypothesis
///   ([`Unknowns::hypotheses`]) fitted on `coarse` by
///   `setup.coarse_iter` Levenberg-Marquardt iterations over its defect values
///   only (chain parameters at their current values), ranked by
///   `(chi2, hypothesis)`;
/// * **fine pass** on the best `setup.shortlist`: defect values and chain
///   parameters together on `coarse` to convergence, from the coarse values
///   and from a second start (the better kept); then, with `fine`, the best
///   two and every set within `setup.time_slack` of the best on `coarse`
///   are refitted on the time-domain chi-square from there and ranked by it
///   (the others are dropped: a set whose Laplace chi-square exceeds the
///   best's by more than the slack cannot win in the time domain, see
///   `time_refits` in the source).
/// * with chain parameters, up to `opts.rounds` rounds: the chain
///   parameters of the best fit become the starting values of the next
///   coarse pass (none when they are within half a standard error of this
///   round's: [`GeneralOptions::start`] warm-starts the first); the
///   next fine pass and time refits take the earlier rounds' fits of the
///   sets they have fitted already (those fits free the chain parameters)
///   and fit only the sets new to the shortlist.
///
/// # Errors
/// `unknowns.n` differing from the chain's (field `unknowns.n`); too many
/// hypotheses (`search.max_sets`); a shortlist of zero (`shortlist`); no
/// hypothesis could be fitted.
pub fn fit_general(
    base: &Chain,
    unknowns: &Unknowns,
    coarse: &LaplaceObs,
    fine: Option<&TimeMisfit>,
    setup: &Setup,
    opts: &GeneralOptions,
) -> Result<GeneralFit> {
    if unknowns.n() != base.n() {
        return Err(Error::invalid(
            "unknowns.n",
            unknowns.n(),
            format!("the chain's n = {}", base.n()),
        ));
    }
    if setup.shortlist == 0 {
        return Err(Error::invalid("shortlist", 0, ">= 1"));
    }
    let hyps = unknowns.hypotheses(opts.max_sets)?;
    let differenced = match fine {
        Some(t) if !setup.exact_time_jacobian => Some(t.clone().with_analytic_jacobian(false)),
        _ => None,
    };
    let passes = Passes {
        unknowns,
        coarse,
        fine: differenced.as_ref().or(fine),
        setup,
        parallel: opts.parallel,
        chain_bounds: crate::detect::fit::chainfit::default_bounds(base, unknowns.chain()),
    };
    let rounds = if unknowns.chain().is_empty() {
        1
    } else {
        opts.rounds.max(1)
    };
    let mut current = match &opts.start {
        Some(c) if c.n() == base.n() => c.uniform(),
        _ => base.uniform(),
    };
    let mut evaluations = 0;
    let mut last: Option<(Vec<Hypothesis>, usize, Vec<KindPositions>)> = None;
    let mut memo = Memo::default();
    for _ in 0..rounds {
        let (ranked, m, spent, shortlist) = passes.round(&current, &hyps, &mut memo)?;
        evaluations += spent;
        let moved = ranked[0].chain_moved_from(&current, SETTLED_SE)?;
        current = ranked[0].to_chain(&current)?.uniform();
        last = Some((ranked, m, shortlist));
        if !moved {
            break;
        }
    }
    let (ranked, residuals, shortlist) = last.expect("at least one round");
    Ok(GeneralFit {
        ranked,
        hypotheses: hyps.len(),
        shortlist,
        evaluations,
        residuals,
    })
}

/// The fine and time-domain fits of the sets a round has fitted, by set:
/// these fits free the chain parameters, so a later round, whose coarse
/// pass ranks every set again at the chain parameters the earlier one
/// found, takes them as they are for the sets its shortlist shares with
/// the earlier one's (each fit's start differs between rounds only in the
/// chain parameters, which the fit itself adjusts) and fits only the sets
/// new to its shortlist. Profiling the chain parameters per shortlist in
/// this way leaves a round with unchanged chain parameters nothing to
/// refit (issue 30 item 3).
#[derive(Default)]
struct Memo {
    laplace: HashMap<KindPositions, Fitted>,
    time: HashMap<KindPositions, Fitted>,
}

impl Memo {
    /// The fit of `pairs` in `fits`, if any, with no evaluations spent.
    fn reused(fits: &HashMap<KindPositions, Fitted>, pairs: &KindPositions) -> Option<Fitted> {
        fits.get(pairs).map(|f| Fitted {
            evaluations: 0,
            ..f.clone()
        })
    }

    /// Keep the fits that succeeded, by set.
    fn keep<'p>(
        fits: &mut HashMap<KindPositions, Fitted>,
        done: impl Iterator<Item = (&'p KindPositions, &'p Result<Fitted>)>,
    ) {
        for (pairs, f) in done {
            if let Ok(f) = f {
                fits.entry(pairs.clone()).or_insert_with(|| f.clone());
            }
        }
    }
}

/// What every round of [`fit_general`] shares: the unknowns, the two
/// misfits (`coarse` Laplace values, optional `fine` time-domain refit),
/// the setup and the chain parameters' bounds.
struct Passes<'a> {
    unknowns: &'a Unknowns,
    coarse: &'a LaplaceObs,
    fine: Option<&'a TimeMisfit>,
    setup: &'a Setup,
    parallel: bool,
    chain_bounds: Vec<(f64, f64)>,
}

impl Passes<'_> {
    /// One round from the chain-parameter values of `current`: screen,
    /// coarse pass, fine pass, then the time-domain refits. Returns the
    /// fitted hypotheses ranked, the residual count of the final misfit,
    /// the evaluations spent and the coarse pass's shortlist.
    fn round(
        &self,
        current: &Chain,
        hyps: &[KindPositions],
        memo: &mut Memo,
    ) -> Result<(Vec<Hypothesis>, usize, usize, Vec<KindPositions>)> {
        // the passes below evaluate at `current`'s chain parameters
        self.coarse.retable(current);
        let (pool, screened) = self.screen(current, hyps);
        let (ranked, spent) = coarse_pass(
            current,
            self.unknowns,
            &pool,
            &self.chain_bounds,
            self.coarse,
            self.setup.coarse_iter,
            true,
            self.parallel,
            self.setup.rational_sets,
        );
        let mut ranked: Vec<(Hypothesis, KindPositions)> =
            ranked.into_iter().map(|(h, p)| (h, p.clone())).collect();
        ranked.truncate(self.setup.shortlist);
        let shortlist = ranked.iter().map(|(_, p)| p.clone()).collect();
        let laplace_fits = self.laplace_fits(current, &ranked, memo);
        let (fine_fits, skipped) = match self.fine {
            None => (laplace_fits, 0),
            Some(t) => self.time_fits(current, t, &ranked, laplace_fits, memo),
        };
        let (fitted, m, fine_spent) = collect_fits(fine_fits)?;
        Ok((
            rank(fitted),
            m,
            screened + spent + skipped + fine_spent,
            shortlist,
        ))
    }

    /// Every hypothesis on the screening nodes, the best `screen_keep` (at
    /// least a twentieth) kept for the coarse pass proper; all of them when
    /// there is no screen. Returns the pool and the evaluations spent.
    fn screen<'h>(
        &self,
        current: &Chain,
        hyps: &'h [KindPositions],
    ) -> (Vec<&'h KindPositions>, usize) {
        let keep = self.setup.screen_keep;
        let all: Vec<&KindPositions> = hyps.iter().collect();
        let screen = self
            .coarse
            .screen()
            .filter(|_| keep > 0 && hyps.len() > keep);
        let Some(sc) = screen else {
            return (all, 0);
        };
        let (ranked, spent) = coarse_pass(
            current,
            self.unknowns,
            &all,
            &self.chain_bounds,
            sc,
            self.setup.screen_iter,
            self.setup.screen_retry,
            self.parallel,
            self.setup.rational_sets,
        );
        let pool = ranked
            .into_iter()
            .take(keep.max(hyps.len() / 20))
            .map(|(_, h)| h)
            .collect();
        (pool, spent)
    }

    /// Whether the fine pass on the Laplace values holds the chain
    /// parameters at the round's values: ahead of a time-domain refit
    /// (which frees them), when they are damping parameters and every
    /// defect sought is a mass. A mass changes the response's frequencies,
    /// the damping its decay: the fits of mass sets at the damping of the
    /// answer at one defect fewer ([`GeneralOptions::start`]) rank the
    /// sets as their fits with the damping free do, and run on the
    /// tabulated sweep, built once per damping value (with `d` free every
    /// step sweeps every mass). A spring or a damper defect trades off
    /// with the damping: holding it lost the truth (a spring and a damper
    /// with `d` fitted: a damper at mass 1 instead of 7, reported
    /// `model-mismatch`), so those fits free it.
    fn holds_damping(&self) -> bool {
        self.fine.is_some()
            && self
                .unknowns
                .slots()
                .iter()
                .all(|s| s.kind == crate::detect::unknowns::KindChoice::Mass)
            && self.unknowns.chain().iter().all(|p| p.is_damping())
    }

    /// The fine pass on the Laplace values: values and chain parameters
    /// (held where [`Passes::holds_damping`]) from the coarse values and
    /// from a second start, the better kept (ahead of a time-domain refit
    /// these fits only choose its start, and the second is fitted only
    /// where the first does not explain the values, [`explained_chi2`]).
    fn laplace_fits(
        &self,
        current: &Chain,
        ranked: &[(Hypothesis, KindPositions)],
        memo: &mut Memo,
    ) -> Vec<Result<Fitted>> {
        let tol = if self.fine.is_some() {
            Tol::Seed
        } else {
            Tol::Full
        };
        // ahead of a time-domain refit the Laplace values are the record's,
        // whitened at its noise level: their chi-square is calibrated
        let explained = match (self.fine, self.setup.every_second_start) {
            (Some(_), false) => explained_chi2(self.coarse),
            _ => None,
        };
        let holds_damping = self.holds_damping();
        let done = &memo.laplace;
        let fits = map_maybe_par(ranked, self.parallel, |(h, pairs)| {
            if let Some(f) = Memo::reused(done, pairs) {
                return Ok(f);
            }
            let fit = |values: &[f64]| {
                fit_pairs(
                    current,
                    self.unknowns,
                    pairs,
                    values,
                    &self.chain_bounds,
                    !holds_damping,
                    self.coarse,
                    100,
                    tol,
                )
            };
            let alt: Vec<f64> = pairs.iter().map(|&(k, _)| starts(k, current)[1]).collect();
            let first = fit(&h.masses());
            if first
                .as_ref()
                .is_ok_and(|f| explained.is_some_and(|(lo, hi)| (lo..=hi).contains(&f.hyp.chi2)))
            {
                return first;
            }
            better(first, fit(&alt))
        });
        Memo::keep(&mut memo.laplace, ranked.iter().map(|(_, p)| p).zip(&fits));
        fits
    }

    /// The time-domain refits of the Laplace fits within the slack
    /// ([`time_refits`]), from the Laplace fits' values; the others are
    /// dropped (their evaluations returned as the second value), failed
    /// Laplace fits kept as errors.
    fn time_fits(
        &self,
        current: &Chain,
        t: &TimeMisfit,
        ranked: &[(Hypothesis, KindPositions)],
        laplace_fits: Vec<Result<Fitted>>,
        memo: &mut Memo,
    ) -> (Vec<Result<Fitted>>, usize) {
        let refit = time_refits(&laplace_fits, self.setup.time_slack);
        let mut skipped = 0;
        let mut failed = Vec::new();
        let chosen: Vec<(Fitted, &KindPositions)> = laplace_fits
            .into_iter()
            .zip(ranked)
            .zip(refit)
            .filter_map(|((f, (_, pairs)), go)| match f {
                Ok(f) if go => Some((f, pairs)),
                Ok(f) => {
                    skipped += f.evaluations;
                    None
                }
                Err(e) => {
                    failed.push(Err(e));
                    None
                }
            })
            .collect();
        let done = &memo.time;
        let fits = map_maybe_par(&chosen, self.parallel, |(best, pairs)| {
            if let Some(f) = Memo::reused(done, pairs) {
                return Ok(f);
            }
            let start = best.hyp.to_chain(current)?.uniform();
            let mut out = fit_pairs(
                &start,
                self.unknowns,
                pairs,
                &best.hyp.masses(),
                &self.chain_bounds,
                true,
                t,
                100,
                Tol::Seed,
            )?;
            out.evaluations += best.evaluations;
            Ok(out)
        });
        Memo::keep(&mut memo.time, chosen.iter().map(|(_, p)| *p).zip(&fits));
        (fits.into_iter().chain(failed).collect(), skipped)
    }
}

/// The whitened Laplace chi-squares with which a fine fit ahead of a
/// time-domain refit explains the record's Laplace values to their noise:
/// at most `K + 3 sqrt(2 K)` with `K` the chi-square's degrees of freedom,
/// and at least `K / 4` (lower, the noise level the values were whitened
/// at is too high, by twice or more, and the bound means nothing). `None`
/// without whitening: diagonal weights give no chi-square, and every second
/// start is then fitted; Laplace values given as data, whose fits are the
/// answer and whose level may be a placeholder, always fit both starts.
/// The second start of the fine pass looks for a minimum that the coarse
/// values' basin missed; a minimum can beat a fit that already explains
/// the values only by about the noise. Measured on 1806 fine fits (28
/// records of `springmass simulate --method expm`: Table 1's S1 to S4,
/// three masses on n = 20, two light masses on n = 10, a mass and a
/// spring on n = 12 with `--kinds any`; 0.1% and 1% noise, two seeds; the
/// defaults and `--fit d`): the second start was better in 126 fits, every
/// one of them with a first fit more than 300 standard deviations
/// (`sqrt(2 K)`) above `K`; of the 716 first fits within these bounds it
/// was better in none, and those 716 second starts took 19 493 of the
/// 63 830 evaluations of the fine pass. No first fit was below `K / 4`
/// (the least, 143 for `K = 160`).
fn explained_chi2(obs: &LaplaceObs) -> Option<(f64, f64)> {
    obs.whitening().map(|_| {
        let k = obs.dof() as f64;
        (k / 4.0, k + 3.0 * (2.0 * k).sqrt())
    })
}

/// The hypotheses of the fits that succeeded, the residual count of the
/// last, and their evaluations; the first error when none succeeded.
fn collect_fits(fits: Vec<Result<Fitted>>) -> Result<(Vec<Hypothesis>, usize, usize)> {
    let mut fitted = Vec::with_capacity(fits.len());
    let mut m = 0;
    let mut evaluations = 0;
    let mut first_err = None;
    for f in fits {
        match f {
            Ok(f) => {
                evaluations += f.evaluations;
                m = f.m;
                fitted.push(f.hyp);
            }
            Err(e) => {
                first_err.get_or_insert(e);
            }
        }
    }
    if fitted.is_empty() {
        return Err(first_err.unwrap_or_else(|| Error::Numerical {
            method: "fit_general".into(),
            reason: "no hypothesis could be fitted".into(),
        }));
    }
    Ok((fitted, m, evaluations))
}

/// The coarse pass over `hyps` on `obs` (defect values only, chain
/// parameters at `current`'s values; with `retry`, [`fit_pairs_coarse`]'s
/// heavier retry on a bound; with `rational`, on the sets' rational form,
/// [`fit_pairs_fast`], where it applies): the fitted hypotheses ranked by
/// `(chi2, hypothesis)`, and the evaluations spent.
#[allow(clippy::too_many_arguments)]
fn coarse_pass<'h>(
    current: &Chain,
    unknowns: &Unknowns,
    hyps: &[&'h KindPositions],
    chain_bounds: &[(f64, f64)],
    obs: &LaplaceObs,
    max_iter: usize,
    retry: bool,
    parallel: bool,
    rational: bool,
) -> (Vec<(Hypothesis, &'h KindPositions)>, usize) {
    // the rational form of each set's model, when it applies (chain
    // parameters are held here): per-node Green's data shared by every set
    let probes = hyps
        .iter()
        .flat_map(|h| h.iter().map(|&(kind, at)| kind.site_in(current, at).probe));
    let pair_uses = hyps
        .iter()
        .map(|h| h.len() * h.len().saturating_sub(1) / 2)
        .sum();
    let tables = if rational {
        SetTables::new(obs, current, probes, pair_uses)
    } else {
        None
    };
    let fits: Vec<Option<Fitted>> = map_maybe_par(hyps, parallel, |h| {
        let fit = |v: &[f64]| -> Result<Fitted> {
            let fast = tables
                .as_ref()
                .and_then(|t| fit_pairs_fast(t, current, unknowns, h, v, max_iter, Tol::Seed));
            match fast {
                Some(f) => f,
                None => fit_pairs(
                    current,
                    unknowns,
                    h,
                    v,
                    chain_bounds,
                    false,
                    obs,
                    max_iter,
                    Tol::Seed,
                ),
            }
        };
        let from = |which: usize| {
            let v: Vec<f64> = h.iter().map(|&(k, _)| starts(k, current)[which]).collect();
            if retry {
                fit_pairs_coarse(unknowns, h, &v, fit)
            } else {
                fit(&v)
            }
        };
        // a weakening is as likely as a stiffening, a mass lost as one
        // added: the coarse pass starts from both sides of the uniform
        // values. (From the heavy side only, two light masses were out of
        // reach: masses of 0.44 at 2 and 0.61 at 7 of n = 10, 0.1% noise,
        // k = 2 given, returned masses at 1 and 2, `model-mismatch`.)
        better(from(0), from(1)).ok()
    });
    let mut evaluations = 0;
    let mut ranked = Vec::with_capacity(hyps.len());
    for (f, h) in fits.into_iter().zip(hyps) {
        if let Some(f) = f {
            evaluations += f.evaluations;
            ranked.push((f.hyp, *h));
        }
    }
    ranked.sort_by(|a, b| a.0.chi2.total_cmp(&b.0.chi2).then_with(|| a.1.cmp(b.1)));
    (ranked, evaluations)
}

/// [`fit_general`] on a noisy series with the chosen misfit: real axis or
/// Bromwich (coarse and fine passes on its Laplace data, [`laplace_obs`]), or
/// time (coarse pass on the Bromwich data, fine pass in the time domain).
///
/// # Errors
/// As [`laplace_obs`] and [`fit_general`].
pub fn fit_noisy_general(
    base: &Chain,
    data: &TimeData,
    unknowns: &Unknowns,
    choice: MisfitKind,
    setup: &Setup,
    opts: &GeneralOptions,
) -> Result<GeneralFit> {
    match choice {
        MisfitKind::Time => {
            let obs = laplace_obs(data, MisfitKind::Bromwich, setup)?;
            let t = TimeMisfit::new(data.clone());
            fit_general(base, unknowns, &obs, Some(&t), setup, opts)
        }
        laplace => {
            let obs = laplace_obs(data, laplace, setup)?;
            fit_general(base, unknowns, &obs, None, setup, opts)
        }
    }
}

/// The identifiability report ([`crate::detect::fit::identify`]) of the
/// best of `ranked` against its alternatives at noise level `sigma`, each
/// defect compared with the uniform value of its kind in `base` (`mass`,
/// `k` or `d`).
///
/// # Errors
/// No hypothesis (field `ranked`); as [`identify`].
pub fn identify_general(
    ranked: &[Hypothesis],
    base: &Chain,
    sigma: f64,
    threshold: Option<f64>,
) -> Result<Identifiability> {
    let mut r = identify_with(ranked, |d| d.base_value(base), sigma, threshold)?;
    if base.baseline().is_some() {
        // "no defect" is the baseline's value there, not a uniform one
        for d in &mut r.defects {
            d.reason = d
                .reason
                .replace("errors of the uniform", "errors of the baseline");
        }
    }
    Ok(r)
}

fn identify_with(
    ranked: &[Hypothesis],
    uniform: impl Fn(&Defect) -> f64,
    sigma: f64,
    threshold: Option<f64>,
) -> Result<Identifiability> {
    let best = ranked
        .first()
        .ok_or_else(|| Error::invalid("ranked", 0, "at least one hypothesis"))?;
    let defects: Vec<FittedDefect> = best
        .defects
        .iter()
        .zip(&best.std_errors)
        .map(|(d, &std_error)| FittedDefect {
            at: d.at(),
            value: d.value(),
            std_error,
            uniform: uniform(d),
        })
        .collect();
    let alts: Vec<Alternative> = ranked[1..]
        .iter()
        .map(|h| Alternative {
            positions: h.positions(),
            chi2: h.chi2,
        })
        .collect();
    identify(&defects, best.chi2, &alts, sigma, threshold)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::unknowns::KindChoice;
    use crate::noise::NoiseLevel;

    #[test]
    fn shared_subsets_count_and_order() {
        let c = |n: usize, k| crate::detect::unknowns::subsets(&(1..=n).collect::<Vec<_>>(), k);
        assert_eq!(c(5, 2).len(), 10);
        assert_eq!(c(20, 3).len(), 1140);
        assert_eq!(c(3, 3), vec![vec![1, 2, 3]]);
        assert_eq!(c(3, 0), vec![Vec::<usize>::new()]);
        assert!(c(2, 3).is_empty());
        assert!(c(6, 3).windows(2).all(|w| w[0] < w[1]));
    }

    #[test]
    fn system1_with_noise_every_misfit() {
        let truth = crate::scenes::paper_with(5, "mass:2:3.0 mass:4:0.5").unwrap();
        let data =
            TimeData::simulate(&truth, 200.0, 0.2, NoiseLevel::RelativeMax(1e-3), 3).unwrap();
        let setup = Setup::new().unwrap();
        let u = Unknowns::free(5, &[KindChoice::Mass; 2], &[]).unwrap();
        let opts = GeneralOptions::default();
        for choice in [MisfitKind::Bromwich, MisfitKind::Time] {
            let g = fit_noisy_general(&truth.uniform(), &data, &u, choice, &setup, &opts).unwrap();
            let r = &g.ranked;
            assert!(r[0].matches(&truth, 0.05), "{choice:?}: {:?}", r[0]);
        }
        // the real axis cannot see the light mass at 4 through 1e-3 noise
        // (docs/paper-notes.md): its best set has a chi-square no worse than the truth's
        let obs = laplace_obs(&data, MisfitKind::RealAxis, &setup).unwrap();
        let r = fit_general(&truth.uniform(), &u, &obs, None, &setup, &opts)
            .unwrap()
            .ranked;
        let t: f64 = obs.residuals(&truth).unwrap().iter().map(|v| v * v).sum();
        eprintln!("real axis: best {:?}, truth chi2 {t}", r[0]);
        assert!(r[0].chi2 <= t * (1.0 + 1e-9));
    }

    /// Ahead of the time-domain refits, the fine pass leaves out the second
    /// starts of the fits that explain the record's Laplace values: fewer
    /// evaluations for the same answer as with every second start fitted;
    /// at a noise level ten times too high (every chi-square far below its
    /// degrees of freedom) it leaves out none.
    #[test]
    fn second_starts_only_where_the_first_fit_does_not_explain_the_values() {
        let truth = crate::scenes::paper_with(5, "mass:2:3.0 mass:4:0.5").unwrap();
        let data =
            TimeData::simulate(&truth, 200.0, 0.2, NoiseLevel::RelativeMax(1e-3), 1).unwrap();
        let u = Unknowns::free(5, &[KindChoice::Mass; 2], &[]).unwrap();
        let opts = GeneralOptions {
            parallel: false,
            ..GeneralOptions::default()
        };
        let every = Setup {
            every_second_start: true,
            ..Setup::new().unwrap()
        };
        let fit = |data: &TimeData, setup: &Setup| {
            fit_noisy_general(&truth.uniform(), data, &u, MisfitKind::Time, setup, &opts).unwrap()
        };
        let (rule, all) = (fit(&data, &Setup::new().unwrap()), fit(&data, &every));
        assert!(rule.ranked[0].matches(&truth, 0.05), "{:?}", rule.ranked[0]);
        assert_eq!(rule.ranked[0].key(), all.ranked[0].key());
        let (a, b) = (&rule.ranked[0], &all.ranked[0]);
        assert!((a.chi2 - b.chi2).abs() <= 1e-6 * b.chi2, "{a:?} vs {b:?}");
        assert!(
            rule.evaluations < all.evaluations,
            "{} vs {}",
            rule.evaluations,
            all.evaluations
        );
        let high = data.clone().with_sigma(10.0 * data.sigma()).unwrap();
        let (rule, all) = (fit(&high, &Setup::new().unwrap()), fit(&high, &every));
        assert_eq!(rule.evaluations, all.evaluations);
        assert_eq!(rule.ranked, all.ranked);
    }

    /// Two masses of n = 6 at `d = 0.12` (0.1% noise), sought with `d`
    /// free from `d = 0.1`: the truth, setup, unknowns, base chain, the
    /// record's Bromwich values and its time misfit.
    fn damped_pair() -> (Chain, Setup, Unknowns, Chain, LaplaceObs, TimeMisfit) {
        let truth = crate::scenes::paper_with(6, "mass:2:3.0 mass:5:0.5")
            .unwrap()
            .with_d(0.12)
            .unwrap();
        let data =
            TimeData::simulate(&truth, 150.0, 0.25, NoiseLevel::RelativeMax(1e-3), 2).unwrap();
        let setup = Setup::new().unwrap();
        let u = Unknowns::free(6, &[KindChoice::Mass; 2], &[crate::sensitivity::Param::D]).unwrap();
        let base = truth.uniform().with_d(0.1).unwrap();
        let bromwich = laplace_obs(&data, MisfitKind::Bromwich, &setup).unwrap();
        (truth, setup, u, base, bromwich, TimeMisfit::new(data))
    }

    /// With a chain parameter free, a round takes the fits of the sets an
    /// earlier round fitted ([`Memo`]): past the chain parameters' fixed
    /// point, a further round (when it runs) changes nothing, bit for bit,
    /// and spends only its coarse pass; and every fit it took is still a
    /// minimum at the final chain parameters (refitted from where it
    /// stands, it gains nothing), for the time misfit and for Bromwich
    /// values alone.
    #[test]
    fn later_rounds_take_the_fits_of_the_sets_already_fitted() {
        let (truth, setup, u, base, bromwich, time) = damped_pair();
        let rounds = |r: usize| GeneralOptions {
            rounds: r,
            parallel: false,
            ..GeneralOptions::default()
        };
        for fine in [Some(&time), None] {
            let fit = |r| fit_general(&base, &u, &bromwich, fine, &setup, &rounds(r)).unwrap();
            let (one, two, three) = (fit(1), fit(2), fit(3));
            assert!(two.ranked[0].matches(&truth, 0.05), "{:?}", two.ranked[0]);
            let d = |f: &GeneralFit| f.ranked[0].param("d").unwrap().value;
            assert!((d(&one) - 0.1).abs() > 1e-3, "the first round moves d");
            assert_eq!(two.ranked, three.ranked, "fine {}", fine.is_some());
            // the third round: its screen and coarse pass only
            let third = three.evaluations - two.evaluations;
            let second = two.evaluations - one.evaluations;
            assert!(third <= second, "{third} > {second}");
            assert!(
                third < one.evaluations / 2,
                "{third} vs {}",
                one.evaluations
            );
            let obs: &dyn crate::detect::model::MeasurementModel = match fine {
                Some(t) => t,
                None => &bromwich,
            };
            for h in &three.ranked {
                let start = h.to_chain(&base).unwrap().uniform();
                let (again, _) =
                    fit_pairs_from(&start, &u, &h.key(), &h.masses(), obs, 100, true).unwrap();
                assert!(
                    again.chi2 >= h.chi2 * (1.0 - 1e-6),
                    "{:?}: {} refitted to {}",
                    h.positions(),
                    h.chi2,
                    again.chi2
                );
            }
        }
    }

    /// A round whose best fit leaves the damping within half a standard
    /// error of where the round started is the last; from the answer at
    /// one defect fewer (the warm start) the record's damping is found in
    /// one round, and the answer is the one of two rounds from afar.
    #[test]
    fn a_round_that_leaves_the_damping_where_it_started_is_the_last() {
        let (truth, setup, u, base, bromwich, time) = damped_pair();
        let fit = |rounds: usize, start: Option<Chain>| {
            let opts = GeneralOptions {
                rounds,
                parallel: false,
                start,
                ..GeneralOptions::default()
            };
            fit_general(&base, &u, &bromwich, Some(&time), &setup, &opts).unwrap()
        };
        let far = fit(2, None);
        assert!(
            far.evaluations > fit(1, None).evaluations,
            "d moved: two rounds"
        );
        let best = &far.ranked[0];
        assert!(best.matches(&truth, 0.05), "{best:?}");
        let warm = best.to_chain(&base).unwrap();
        let (one, two) = (fit(1, Some(warm.clone())), fit(2, Some(warm)));
        assert_eq!(one.evaluations, two.evaluations, "settled: one round");
        assert_eq!(one.ranked, two.ranked);
        let d = |f: &GeneralFit| f.ranked[0].param("d").unwrap().clone();
        assert_eq!(two.ranked[0].key(), best.key());
        assert!((d(&two).value - d(&far).value).abs() <= 0.1 * d(&far).std_error);
    }
}

#[cfg(test)]
mod screen_tests {
    use super::*;
    use crate::detect::unknowns::KindChoice;
    use crate::noise::NoiseLevel;
    use rayon::prelude::*;

    /// Screen then refine against the earlier path on the noise study's
    /// systems (S1-S4, C3a, C3b; its record: [0, 200], dt = 0.2) at 1e-3 and
    /// 1e-2 noise, two seeds each: the reference winner ranks within the
    /// screen's keep on the screen, and the new path's winner is the same
    /// position set with the same time-domain chi-square (to 1e-6).
    #[test]
    fn screen_and_slack_keep_the_reference_winner() {
        let mut cases = Vec::new();
        for name in crate::scenes::NOISE_SYSTEMS {
            let truth = crate::scenes::by_name(name).unwrap();
            for level in [1e-3, 1e-2] {
                for seed in 0..2u64 {
                    cases.push((name, truth.clone(), level, seed));
                }
            }
        }
        let setup = Setup::new().unwrap();
        let reference = Setup::reference().unwrap();
        let serial = GeneralOptions {
            parallel: false,
            ..GeneralOptions::default()
        };
        let out: Vec<String> = cases
            .par_iter()
            .map(|(name, truth, level, seed)| {
                let data = TimeData::simulate(
                    truth,
                    200.0,
                    0.2,
                    NoiseLevel::RelativeMax(*level),
                    13 + *seed,
                )
                .unwrap();
                let k = truth.defects().len();
                let base = truth.uniform();
                let unknowns = Unknowns::free(base.n(), &vec![KindChoice::Mass; k], &[]).unwrap();
                let old = fit_noisy_general(
                    &base,
                    &data,
                    &unknowns,
                    MisfitKind::Time,
                    &reference,
                    &serial,
                )
                .unwrap();
                let new =
                    fit_noisy_general(&base, &data, &unknowns, MisfitKind::Time, &setup, &serial)
                        .unwrap();
                let winner = old.ranked[0].key();
                // the winner's rank on the screen
                let obs = laplace_obs(&data, MisfitKind::Bromwich, &setup).unwrap();
                let hyps = unknowns.hypotheses(200_000).unwrap();
                let all: Vec<&KindPositions> = hyps.iter().collect();
                let (screened, _) = coarse_pass(
                    &base,
                    &unknowns,
                    &all,
                    &[],
                    obs.screen().expect("a screen by default"),
                    setup.screen_iter,
                    setup.screen_retry,
                    false,
                    setup.rational_sets,
                );
                let rank = screened.iter().position(|(_, h)| **h == winner);
                let keep = setup.screen_keep.max(hyps.len() / 20);
                assert!(
                    rank.is_some_and(|r| r < keep),
                    "{} {level:e} seed {seed}: winner {:?} ranks {rank:?} on the screen",
                    name,
                    old.ranked[0].positions()
                );
                let (a, b) = (&old.ranked[0], &new.ranked[0]);
                assert_eq!(a.key(), b.key(), "{} {level:e} seed {seed}", name);
                // the time refits left out by the slack change neither the
                // winner nor a runner-up within the slack (beyond it another
                // set left out may be closer: S4 at 1e-2, seed 0: 291
                // against the 304 reported)
                let gap = |f: &GeneralFit| f.ranked[1].chi2 - f.ranked[0].chi2;
                if gap(&old) <= setup.time_slack {
                    assert_eq!(
                        old.ranked[1].key(),
                        new.ranked[1].key(),
                        "{} {level:e} seed {seed}: runner-up",
                        name
                    );
                } else {
                    assert!(gap(&new) >= gap(&old) - 1e-9 * old.ranked[0].chi2);
                }
                assert!(
                    (a.chi2 - b.chi2).abs() <= 1e-6 * a.chi2,
                    "{} {level:e} seed {seed}: chi2 {} vs {}",
                    name,
                    a.chi2,
                    b.chi2
                );
                format!(
                    "{} {level:e} seed {seed}: winner {:?} (truth: {}), screen rank {} of {}",
                    name,
                    a.positions(),
                    a.positions_match(truth),
                    rank.unwrap_or(usize::MAX),
                    hyps.len()
                )
            })
            .collect();
        for line in out {
            eprintln!("{line}");
        }
    }
}
