//! The search at `k` defects narrowed from the answers at `k - 1`, when the
//! number of defects is left to the criterion: from three defects on, the
//! sets themselves ([`nest`]); below, or where nesting does not apply, the
//! kinds tried at each position of a search over several kinds
//! ([`narrow`]). `FitOptions::exhaustive` turns both off, and effort high
//! where every set can be searched ([`super::effort`]).
//!
//! **Sets** (from `k = 3`). The search at `k` takes only the sets made of
//! one of the best 8 answers at `k - 1` (4 at effort low) and one more
//! `(kind, position)` pair, any kind the unknowns allow: about
//! `8 (P - k)` sets for `P` pairs instead of `C(P, k)` (System 3 at
//! `k = 4`: 118 of 4 845; System C3b with every kind sought at `k = 3`:
//! 444 of 35 990). One more defect usually explains what the best `k - 1`
//! left, and the criterion only needs each `k`'s best fit; measured against
//! the exhaustive search on random records (`tests/nested_k.rs`).
//!
//! **Kinds** (`--kinds any` at two defects, at the cost of one kind). With
//! `k` defects each free to be a mass, a spring or a damper, the
//! enumeration has `C(3n + 1, k)` sets against `C(n, k)` for one kind.
//! Before the search at `k = 2` (or any `k` that is not nested), the best
//! answer at `k - 1` (the incumbent) is extended by each `(kind, position)`
//! pair in turn and refitted on the coarse (Laplace) misfit from there,
//! every defect value free and the chain parameters (a fitted damping)
//! held at the incumbent's, as the coarse pass that ranks the sets holds
//! them: the chi-square each pair reaches is its sensitivity. (With the
//! damping free too, each fit's Jacobian took the general gradient at
//! every node instead of the tabulated sweep: System 3's 1% record with
//! `--fit d --damping grounded` spent a fifth of its instructions here.)
//! The search at `k` then draws its sets from
//!
//! * at each position, the kind that reached the lowest chi-square there;
//! * the right wall's spring (position `n`) beside the last mass's best
//!   kind: near the wall a spring and a mass change the record alike;
//! * the [`EXTRA_PAIRS`] pairs of lowest chi-square overall (the other kinds
//!   where the data point, e.g. a mass and its neighbouring spring);
//! * every pair of the best answers at `k - 1` ([`previous_sets`], the
//!   answers a nested search would extend), so an incumbent that holds a
//!   wrong kind can still be replaced.
//!
//! That is about `n + 8` pairs instead of `3n + 1`. Measured against the
//! full product on the test suite's mixed-kind records
//! (`tests/kinds_any.rs`), the answers agree in positions and kinds. The
//! sets at `k >= 3` were first nested within these pairs too; the kinds
//! then followed the incumbent alone, and where it held a wrong kind (a
//! spring for the mass at 2 of System C3a) its sensitivities called the
//! other true masses springs or dampers: with `--kinds any` at 1% noise
//! C3b's three masses were found in 6 of 20 records, and 20 of 20 nested
//! over every kind (`configs/studies/effort.toml`).
//!
//! Either way the search is no longer exhaustive, and the report says so
//! (`exhaustive: false`, the method names the narrowing).

use super::general::{self, Hypothesis};
use crate::chain::Chain;
use crate::detect::model::MeasurementModel;
use crate::detect::unknowns::{by_position, DefectKind, KindPositions, Unknowns};
use crate::error::Result;

/// Narrow only when the full product holds more than this many times the
/// sets of one kind per position.
const NARROW_ABOVE: f64 = 3.0;
/// Pairs kept beyond the best kind of every position: the lowest
/// chi-squares overall.
pub const EXTRA_PAIRS: usize = 2;
/// Levenberg-Marquardt iterations of each sensitivity fit.
const SENSITIVITY_ITER: usize = 40;

/// The search at `k` is nested from this many defects on.
pub const NEST_FROM: usize = 3;
/// Nest only when the full search holds more than this many times the
/// nested one's sets.
const NEST_ABOVE: f64 = 2.0;

/// The answers at `k - 1` a nested search at `k` extends: the
/// `(kind, position)` sets of `ranked` (the answers refitted to the end,
/// best first), then those of `shortlist` (the Laplace ranking's best
/// before the time-domain refits dropped some), each once, at most
/// `count` ([`super::effort::Effort::nest_previous`]: 8 by default).
pub(super) fn previous_sets(
    ranked: &[Hypothesis],
    shortlist: &[KindPositions],
    count: usize,
) -> Vec<KindPositions> {
    let mut out: Vec<KindPositions> = Vec::new();
    let sorted = |mut key: KindPositions| {
        by_position(&mut key);
        key
    };
    let keys = ranked
        .iter()
        .map(Hypothesis::key)
        .chain(shortlist.iter().cloned());
    for key in keys.map(sorted) {
        if out.len() < count && !out.contains(&key) {
            out.push(key);
        }
    }
    out
}

/// The unknowns of the search at `k` nested in the answers at `k - 1`:
/// every set made of one of `previous` ([`previous_sets`]) and one more
/// `(kind, position)` pair of the unknowns' candidates, with the number of
/// these sets and of the full search's. `None` when nesting does not apply:
/// fewer than [`NEST_FROM`] defects, slots of known position or unlike
/// slots, answers at `k - 1` of another size (known defects), or a full
/// search at most [`NEST_ABOVE`] times larger.
///
/// A search so nested finds the best set at `k` whenever it holds one of
/// the best answers at `k - 1`: the usual case, where one more defect
/// explains what the best `k - 1` left. It can miss a set at `k` none of
/// whose subsets ranked among them; the report then says the search was
/// not exhaustive, and the fit at `k - 1` is made no worse than the answer
/// at `k` with a defect dropped (the engine's backward rule).
/// `FitOptions::exhaustive` searches every set.
pub(super) fn nest(
    unknowns: &Unknowns,
    previous: &[KindPositions],
) -> Result<Option<(Unknowns, (usize, usize))>> {
    let k = unknowns.k();
    let first = unknowns.slots()[0];
    if k < NEST_FROM
        || previous.is_empty()
        || unknowns.sets().is_some()
        || unknowns
            .slots()
            .iter()
            .any(|s| s.at.is_some() || *s != first)
        || previous.iter().any(|h| h.len() + 1 != k)
    {
        return Ok(None);
    }
    let n = unknowns.n();
    let pairs: Vec<(DefectKind, usize)> = match unknowns.candidates() {
        Some(c) => c.to_vec(),
        None => every_pair(first.kind.kinds(), n),
    };
    let mut sets: Vec<KindPositions> = Vec::new();
    // answers holding a pair the kinds' narrowing dropped are not extended
    // (the narrowing keeps every pair of the best two)
    for held in previous
        .iter()
        .filter(|h| h.iter().all(|p| pairs.contains(p)))
    {
        for &pair in pairs.iter().filter(|p| !held.contains(p)) {
            let mut set = held.clone();
            set.push(pair);
            by_position(&mut set);
            sets.push(set);
        }
    }
    sets.sort();
    sets.dedup();
    let full = choose(pairs.len(), k);
    if full <= NEST_ABOVE * sets.len() as f64 {
        return Ok(None);
    }
    let count = sets.len();
    Ok(Some((unknowns.within(sets)?, (count, full as usize))))
}

/// The narrowed unknowns and what the narrowing cost.
pub(super) struct Narrowed {
    /// The unknowns restricted to the kept pairs ([`Unknowns::among`]).
    pub unknowns: Unknowns,
    /// Pairs kept, of how many.
    pub kept: (usize, usize),
    /// Model evaluations of the sensitivity fits.
    pub evaluations: usize,
}

/// Every `(kind, position)` pair of `kinds` on a chain of `n` masses, by
/// kind then position.
fn every_pair(kinds: &[DefectKind], n: usize) -> Vec<(DefectKind, usize)> {
    kinds
        .iter()
        .flat_map(|&kind| kind.positions(n).map(move |at| (kind, at)))
        .collect()
}

/// `C(n, k)` as a float.
fn choose(n: usize, k: usize) -> f64 {
    (0..k).fold(1.0, |c, i| {
        c * (n.saturating_sub(i)) as f64 / (i + 1) as f64
    })
}

/// The narrowed unknowns of a search over several kinds (see the module
/// docs), or `None` when narrowing would not pay: fewer than two defects of
/// unknown position, one kind each, or a product small enough.
/// `previous` are the ranked answers at `k - 1` (the best first: the
/// incumbent), `answers` the best answers at `k - 1` ([`previous_sets`],
/// which start with `previous`'s: every pair of theirs is kept), `base` the
/// model's chain (with its known defects and the fitted chain parameters'
/// starting values), `obs` the coarse misfit.
///
/// # Errors
/// As [`Hypothesis::to_chain`].
pub(super) fn narrow(
    base: &Chain,
    unknowns: &Unknowns,
    previous: &[Hypothesis],
    answers: &[KindPositions],
    obs: &dyn MeasurementModel,
) -> Result<Option<Narrowed>> {
    let free: Vec<_> = unknowns.slots().iter().filter(|s| s.at.is_none()).collect();
    let Some(incumbent) = previous.first() else {
        return Ok(None);
    };
    let kinds: Vec<DefectKind> = match free.first() {
        Some(s) if free.iter().all(|t| t.kind == s.kind) => s.kind.kinds().to_vec(),
        _ => return Ok(None),
    };
    let n = unknowns.n();
    let pairs = every_pair(&kinds, n);
    let held = incumbent.key();
    if free.len() < 2
        || held.len() + 1 != unknowns.k()
        || choose(pairs.len(), free.len()) <= NARROW_ABOVE * choose(n, free.len())
    {
        return Ok(None);
    }
    let start = incumbent.to_chain(base)?.uniform();
    let mut evaluations = 0;
    let mut scored: Vec<((DefectKind, usize), f64)> = Vec::with_capacity(pairs.len());
    for &pair in pairs.iter().filter(|p| !held.contains(p)) {
        let (with, values) = incumbent.extended(pair, &start);
        // the chain parameters held (the module docs)
        let fit = general::fit_pairs_from(
            &start,
            unknowns,
            &with,
            &values,
            obs,
            SENSITIVITY_ITER,
            false,
        );
        let chi2 = match fit {
            Ok((h, e)) => {
                evaluations += e;
                h.chi2
            }
            Err(_) => f64::INFINITY,
        };
        scored.push((pair, chi2));
    }
    let kept = kept_pairs(&scored, answers, n);
    let total = pairs.len();
    Ok(Some(Narrowed {
        kept: (kept.len(), total),
        unknowns: unknowns.among(kept),
        evaluations,
    }))
}

/// The pairs kept from the sensitivities `scored` (see the module docs):
/// the best kind at every position (every kind where none could be fitted),
/// the [`EXTRA_PAIRS`] best overall and every pair of the best answers at
/// `k - 1` (`answers`, [`previous_sets`]: an answer keeps its kinds, a mass
/// the incumbent's sensitivities would call a damper); sorted by position
/// then kind, each once.
fn kept_pairs(
    scored: &[((DefectKind, usize), f64)],
    answers: &[KindPositions],
    n: usize,
) -> Vec<(DefectKind, usize)> {
    let mut keep: Vec<(DefectKind, usize)> = Vec::new();
    for at in 0..=n {
        let here: Vec<&((DefectKind, usize), f64)> =
            scored.iter().filter(|(p, _)| p.1 == at).collect();
        match here.iter().min_by(|a, b| a.1.total_cmp(&b.1)) {
            Some(best) if best.1.is_finite() => keep.push(best.0),
            _ => keep.extend(here.iter().map(|s| s.0)),
        }
    }
    // the right wall's spring (the left wall's, position 0, has no other kind)
    if scored.iter().any(|s| s.0 == (DefectKind::Spring, n)) {
        keep.push((DefectKind::Spring, n));
    }
    let mut order: Vec<&((DefectKind, usize), f64)> =
        scored.iter().filter(|s| s.1.is_finite()).collect();
    order.sort_by(|a, b| a.1.total_cmp(&b.1).then_with(|| a.0.cmp(&b.0)));
    keep.extend(order.iter().take(EXTRA_PAIRS).map(|s| s.0));
    keep.extend(answers.iter().flatten());
    by_position(&mut keep);
    keep.dedup();
    keep
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kept_pairs_take_the_best_kind_per_position_and_the_best_overall() {
        use DefectKind::{Damper, Mass, Spring};
        // n = 2: spring 0, and mass/spring/damper at 1 and 2
        let scored = vec![
            ((Mass, 1), 50.0),
            ((Spring, 1), 40.0),
            ((Damper, 1), 60.0),
            ((Mass, 2), 10.0),
            ((Spring, 2), 12.0),
            ((Damper, 2), f64::INFINITY),
            ((Spring, 0), 70.0),
        ];
        let kept = kept_pairs(&scored, &[], 2);
        // per position: spring 0, spring 1, mass 2; overall best two:
        // mass 2, spring 2
        assert_eq!(kept, vec![(Spring, 0), (Spring, 1), (Mass, 2), (Spring, 2)]);
        // a position where nothing could be fitted keeps every kind
        let failed = vec![((Mass, 1), f64::INFINITY), ((Spring, 1), f64::INFINITY)];
        assert_eq!(kept_pairs(&failed, &[], 1), vec![(Mass, 1), (Spring, 1)]);
    }

    #[test]
    fn choose_counts_subsets() {
        assert_eq!(choose(37, 4), 66045.0);
        assert_eq!(choose(12, 4), 495.0);
        assert_eq!(choose(3, 4), 0.0);
    }
}
