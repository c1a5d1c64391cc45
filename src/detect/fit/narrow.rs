//! A search over every defect kind (`--kinds any`) at the cost of one kind:
//! the kinds tried at each position are chosen from the data's sensitivity
//! at the previous number of defects, not taken as a product over every set.
//!
//! With `k` defects each free to be a mass, a spring or a damper, the
//! enumeration has `C(3n + 1, k)` sets against `C(n, k)` for one kind: for
//! `n = 12`, `k = 4`, 66 045 against 495 (9.8 s against 0.4 s). Before the
//! search at `k` (`k >= 2`), the best answer at `k - 1` (the incumbent) is
//! extended by each `(kind, position)` pair in turn and refitted on the
//! coarse (Laplace) misfit from there, every value free: the chi-square each
//! pair reaches is its sensitivity. The search at `k` then draws its sets
//! from
//!
//! * at each position, the kind that reached the lowest chi-square there;
//! * the right wall's spring (position `n`) beside the last mass's best
//!   kind: near the wall a spring and a mass change the record alike;
//! * the [`EXTRA_PAIRS`] pairs of lowest chi-square overall (the other kinds
//!   where the data point, e.g. a mass and its neighbouring spring);
//! * every pair of the [`KEEP_PREVIOUS`] best answers at `k - 1` (so an
//!   incumbent that holds a wrong kind can still be replaced).
//!
//! That is about `n + 8` pairs instead of `3n + 1`. The search is then no
//! longer exhaustive, and the report says so (`exhaustive: false`, the
//! method names the narrowing). Measured against the full product on the
//! test suite's mixed-kind records (`tests/kinds_any.rs`), the answers agree
//! in positions and kinds.

use super::general::{self, Hypothesis};
use crate::chain::Chain;
use crate::detect::model::MeasurementModel;
use crate::detect::unknowns::{DefectKind, Unknowns};
use crate::error::Result;

/// Narrow only when the full product holds more than this many times the
/// sets of one kind per position.
const NARROW_ABOVE: f64 = 3.0;
/// Pairs kept beyond the best kind of every position: the lowest
/// chi-squares overall.
pub const EXTRA_PAIRS: usize = 2;
/// The best answers at `k - 1` whose every pair is kept.
pub const KEEP_PREVIOUS: usize = 2;
/// Levenberg-Marquardt iterations of each sensitivity fit.
const SENSITIVITY_ITER: usize = 40;

/// The narrowed unknowns and what the narrowing cost.
pub(super) struct Narrowed {
    /// The unknowns restricted to the kept pairs ([`Unknowns::among`]).
    pub unknowns: Unknowns,
    /// Pairs kept, of how many.
    pub kept: (usize, usize),
    /// Model evaluations of the sensitivity fits.
    pub evaluations: usize,
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
/// `previous` are the ranked answers at `k - 1` (the best first), `base`
/// the model's chain (with its known defects and the fitted chain
/// parameters' starting values), `obs` the coarse misfit.
///
/// # Errors
/// As [`Hypothesis::to_chain`].
pub(super) fn narrow(
    base: &Chain,
    unknowns: &Unknowns,
    previous: &[Hypothesis],
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
    let pairs: Vec<(DefectKind, usize)> = kinds
        .iter()
        .flat_map(|&kind| kind.positions(n).map(move |at| (kind, at)))
        .collect();
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
        let chi2 = match general::fit_pairs_from(
            &start,
            unknowns,
            &with,
            &values,
            obs,
            SENSITIVITY_ITER,
        ) {
            Ok((h, e)) => {
                evaluations += e;
                h.chi2
            }
            Err(_) => f64::INFINITY,
        };
        scored.push((pair, chi2));
    }
    let kept = kept_pairs(&scored, previous, n);
    let total = pairs.len();
    Ok(Some(Narrowed {
        kept: (kept.len(), total),
        unknowns: unknowns.among(kept),
        evaluations,
    }))
}

/// The pairs kept from the sensitivities `scored` (see the module docs):
/// the best kind at every position (every kind where none could be fitted),
/// the [`EXTRA_PAIRS`] best overall and the pairs of the best
/// [`KEEP_PREVIOUS`] answers in `previous`; in the order of the full list,
/// each once.
fn kept_pairs(
    scored: &[((DefectKind, usize), f64)],
    previous: &[Hypothesis],
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
    for h in previous.iter().take(KEEP_PREVIOUS) {
        keep.extend(h.key());
    }
    keep.sort_by_key(|&(kind, at)| (at, kind));
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
