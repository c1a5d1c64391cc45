//! The fits at neighbouring numbers of defects made consistent with each
//! other: the fit at `k + 1` is never worse than the fit at `k` (it is
//! extended from it when its search missed, [`Engine::monotone`]), and the
//! fit at `k` is never worse than the best answer at `k + 1` with one defect
//! dropped ([`Engine::backward`]: a search that did not rank every set,
//! such as the kinds narrowed per position of `detect::fit::narrow`, can
//! miss at `k` what it finds at `k + 1`).

use super::{Engine, Found, KFit};
use crate::chain::Chain;
use crate::detect::fit::general::{self, Hypothesis};
use crate::detect::model::MeasurementModel;
use crate::detect::unknowns::{DefectKind, KindPositions};
use crate::error::Result;

impl Engine<'_> {
    /// The fit of `next.k = prev.k + 1` defects made no worse than `prev`'s:
    /// when its best residual exceeds `prev`'s (a search that missed what
    /// `prev` found), `prev`'s best answer is extended by one defect of
    /// vanishing size at each new `(kind, position)` of `next`'s best
    /// [`EXTENSIONS`] answers and refitted from there, every value and
    /// chain parameter free ([`general::fit_pairs_from`]: its residual
    /// cannot exceed the start's, which is `prev`'s); the best of them
    /// joins `next`'s ranking. A fit that is not worse is returned as it is,
    /// so the chi-square is non-increasing in `k` and the noise estimate
    /// does not depend on how far `k` was raised.
    ///
    /// # Errors
    /// As the observations' preparation and [`Self::measured`].
    pub(in crate::detect::fit) fn monotone(
        &self,
        prev: &KFit,
        next: KFit,
        sigma: f64,
    ) -> Result<KFit> {
        if next.k != prev.k + 1 || next.rss <= prev.rss || self.given.is_some() {
            return Ok(next);
        }
        let Some(base) = prev.ranked.first() else {
            return Ok(next);
        };
        let start = base.to_chain(self.model.chain())?.uniform();
        let starts = extensions(base, &next.ranked)
            .into_iter()
            .map(|pair| base.extended(pair, &start));
        let exhaustive = next.exhaustive;
        Ok(
            match self.joined(&next, &start, starts.collect(), exhaustive, sigma)? {
                Some(f) if f.rss < next.rss => f,
                _ => next,
            },
        )
    }

    /// The fit of `prev.k = next.k - 1` defects made no worse than `next`'s
    /// best answer with one defect of unknown position dropped: each such
    /// subset is refitted from `next`'s values (every value and chain
    /// parameter free, [`general::fit_pairs_from`]) and the best joins
    /// `prev`'s ranking when it beats `prev`'s best. Only where `prev`'s
    /// search did not rank every set (`exhaustive` false), and only the
    /// subsets it did not rank (an exhaustive search has already fitted
    /// every subset), of those only the ones within the slack of
    /// [`Self::within_slack`]. With chain parameters fitted (`--fit d`, a
    /// damping model's parameters, `k`, ...), every subset but `prev`'s
    /// best is refitted, ranked or not: the search fits each set from the
    /// chain's starting parameters, and from a start far from the record's
    /// (the Rayleigh model's, scaled from the chain) its fit of the true
    /// set can stop in another basin, while `next`'s values start it in
    /// the right one (a
    /// Rayleigh-damped System 1 record: the true two masses at chi-square
    /// 1.3e5 from the start, about 1000 from the three-defect answer's
    /// values, which had added a spurious spring). Returns `None` when
    /// `prev` stands.
    ///
    /// # Errors
    /// As the observations' preparation and [`Self::measured`].
    pub(in crate::detect::fit) fn backward(
        &self,
        prev: &KFit,
        next: &KFit,
        sigma: f64,
    ) -> Result<Option<KFit>> {
        let chain_fitted = !self.model.fitted().is_empty();
        let Some(top) = next.ranked.first() else {
            return Ok(None);
        };
        let base = self.model.chain();
        let known = base.defects().len();
        // a defect of `next` within [`NULL_SE`] standard errors of its
        // chain value: the set without it may fit as well, wherever
        // `prev`'s search left that set (its start may have led it to
        // another basin: a wall spring 3.5 times stiffer, found at three
        // defects with a null damper beside it, had stopped at 28 times
        // the chi-square at two); it is refitted from `next`'s values
        let null = |i: usize| {
            let d = &top.defects[i];
            i >= known
                && top
                    .std_errors
                    .get(i)
                    .is_some_and(|se| (d.value() - d.base_value(base)).abs() <= NULL_SE * se)
        };
        let every = prev.exhaustive && !chain_fitted && !(0..top.defects.len()).any(null);
        if every || next.k != prev.k + 1 || prev.k == 0 || self.given.is_some() {
            return Ok(None);
        }
        let (pairs, values) = (top.key(), top.masses());
        if pairs.len() != known + next.k {
            return Ok(None);
        }
        let start = top.to_chain(base)?.uniform();
        let starts: Vec<_> = (known..pairs.len())
            .filter_map(|drop| {
                let (mut p, mut v) = (pairs.clone(), values.clone());
                p.remove(drop);
                v.remove(drop);
                let ranked = match chain_fitted {
                    // with chain parameters fitted, a ranked set but the
                    // best may have stopped in another basin (the best is
                    // where its start led, and the drop of `next`'s extra
                    // defect leads there too)
                    true => prev.ranked.first().is_some_and(|h| h.key() == p),
                    false => prev.ranked.iter().any(|h| h.key() == p),
                };
                // a set the narrowed search ranked lost on its screen already
                let screened = !chain_fitted
                    && prev
                        .searched
                        .as_ref()
                        .is_some_and(|u| u.admits(&p[known..]));
                (null(drop) || !(ranked || screened)).then_some((p, v))
            })
            .collect();
        let starts = self.within_slack(prev, &start, starts, sigma)?;
        if starts.is_empty() {
            return Ok(None);
        }
        Ok(self
            .joined(prev, &start, starts, prev.exhaustive, sigma)?
            .filter(|f| f.rss < prev.rss))
    }

    /// The `starts` of [`Self::backward`] that could beat `prev`'s best:
    /// with a time misfit (whose fits cost a modal decomposition per
    /// evaluation), each is first fitted from the chain parameters `start`
    /// (`next`'s) on the coarse Laplace misfit
    /// ([`SLACK_ITER`] iterations) and kept only when its chi-square there
    /// is within the search's slack ([`general::Setup::time_slack`]) of
    /// `prev`'s best answer's: the rule by which the search itself refits
    /// its sets in the time domain. Every start is kept without a time
    /// misfit.
    ///
    /// # Errors
    /// As the observations' preparation.
    fn within_slack(
        &self,
        prev: &KFit,
        start: &Chain,
        starts: Vec<(KindPositions, Vec<f64>)>,
        sigma: f64,
    ) -> Result<Vec<(KindPositions, Vec<f64>)>> {
        let (coarse, fine, _, setup) = self.prepared(sigma)?;
        let (Some(_), Some(best), Some(unknowns)) =
            (fine, prev.ranked.first(), self.unknowns(prev.k)?)
        else {
            return Ok(starts);
        };
        let base = self.model.chain();
        let chain = best.to_chain(base)?;
        let floor = coarse.chi2(&chain)?;
        Ok(starts
            .into_iter()
            .filter(|(pairs, values)| {
                general::fit_pairs_from(start, &unknowns, pairs, values, &coarse, SLACK_ITER, true)
                    .is_ok_and(|(h, _)| h.chi2 <= floor + setup.time_slack)
            })
            .collect())
    }

    /// The best of `starts` (each a `(kind, position)` set of `into.k`
    /// defects with its starting values) refitted from `start`'s chain
    /// parameters ([`general::fit_pairs_from`]: every value and chain
    /// parameter free, never worse than the start), joined to `into`'s
    /// ranking and measured against the data; `None` when none could be
    /// fitted or the best does not beat `into`'s best.
    ///
    /// # Errors
    /// As the observations' preparation and [`Self::measured`].
    fn joined(
        &self,
        into: &KFit,
        start: &Chain,
        starts: Vec<(KindPositions, Vec<f64>)>,
        exhaustive: bool,
        sigma: f64,
    ) -> Result<Option<KFit>> {
        let Some(unknowns) = self.unknowns(into.k)? else {
            return Ok(None);
        };
        let (coarse, fine, misfit_name, _) = self.prepared(sigma)?;
        let obs: &dyn MeasurementModel = match fine.as_ref() {
            Some(t) => t,
            None => &coarse,
        };
        let (mut best, mut spent): (Option<Hypothesis>, usize) = (None, 0);
        for (pairs, values) in &starts {
            if let Ok((h, e)) =
                general::fit_pairs_from(start, &unknowns, pairs, values, obs, 100, true)
            {
                spent += e;
                if best.as_ref().is_none_or(|b| h.chi2 < b.chi2) {
                    best = Some(h);
                }
            }
        }
        let Some(h) = best else {
            return Ok(None);
        };
        if into.ranked.first().is_some_and(|b| b.chi2 <= h.chi2) {
            return Ok(None);
        }
        // a set ranked before, from another start, gives way to its refit
        let mut ranked = into.ranked.clone();
        ranked.retain(|r| r.key() != h.key());
        ranked.push(h);
        let (ranked, _) = self.ranked(ranked, 0)?;
        let found = Found {
            ranked,
            evaluations: into.evaluations + spent,
            hypotheses: into.hypotheses + starts.len(),
            method_name: into.method_name.clone(),
            exhaustive,
            searched: into.searched.clone(),
            shortlist: into.shortlist.clone(),
            budget_exhausted: into.budget_exhausted,
            trace: into.trace.clone(),
        };
        let f = self.measured(into.k, sigma, found, &coarse, fine.as_ref(), misfit_name)?;
        Ok(Some(f))
    }
}

/// Standard errors within which a defect of [`Engine::backward`]'s larger
/// fit counts as at its chain value (the set without it is refitted).
const NULL_SE: f64 = 3.0;

/// Levenberg-Marquardt iterations of [`Engine::within_slack`]'s coarse fits.
const SLACK_ITER: usize = 40;

/// How many of the next fit's best answers propose the new defect of
/// [`Engine::monotone`]'s extensions.
const EXTENSIONS: usize = 3;

/// The `(kind, position)` pairs of the best [`EXTENSIONS`] hypotheses of
/// `next` at positions that `base` does not hold, in order, each once.
fn extensions(base: &Hypothesis, next: &[Hypothesis]) -> Vec<(DefectKind, usize)> {
    let held = base.positions();
    let mut out: Vec<(DefectKind, usize)> = Vec::new();
    for h in next.iter().take(EXTENSIONS) {
        for pair in h.key() {
            if !held.contains(&pair.1) && !out.contains(&pair) {
                out.push(pair);
            }
        }
    }
    out
}
