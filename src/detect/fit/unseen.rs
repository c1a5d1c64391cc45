//! Where a further defect could hide: the check that an answer found with
//! the number of defects left to the criterion is the *whole* answer.
//!
//! A criterion (BIC, AIC) picks the fewest defects that explain the data.
//! When the data barely see part of the chain (far from the sensor, behind
//! a heavy mass, or under coloured noise whose power sits where the chain's
//! modes are), a real defect there changes `chi^2` by less than the
//! criterion's penalty, and the answer without it is reported with a high
//! probability although the data never ruled it out. This check asks, for
//! every mass and spring of the kinds searched that the answer leaves
//! unchanged: if that element were halved, or doubled, would the record
//! change by more than [`Z`] standard errors, beyond what the answer's own
//! values and fitted chain parameters can absorb? The change is computed
//! exactly (the measurement model's whitened residuals of the changed
//! chain, noise model and nuisances included), and the part the answer's
//! parameters can absorb is removed to first order (projection off the
//! columns of their Jacobian): `dchi^2 = |P (r(changed) - r(answer))|^2`.
//! Each probe's residuals come from the model's
//! [`MeasurementModel::near`]: the time misfit of a grounded chain simulates
//! the answer once, keeping its states, and resumes each probe's
//! simulation where the impulse's front first reaches the changed element
//! (`time_screen::Saved`; the same record to rounding, and deep probes of
//! a short record cost nothing: n = 1000, 120 probes, the fit 10.1 s wall
//! against 12.5 s before, the same report), and stops it once the first
//! samples show the change: the part of the change the answer cannot
//! absorb over first rows is a lower bound of the whole (fewer rows can
//! only be fitted better), so a probe is settled as soon as that bound
//! passes the bar. Without nuisances (projected over the whole record)
//! the first residuals are those of the first samples (the noise filter is
//! causal). n = 300, an 800-unit record: the check 6.6 s of 11.3 s before,
//! 2.0 s of 6.9 s after (one thread), the same report. At every chain
//! length (from n = 5 on measured) the stepped probes cost less than
//! their modal sums; where the chain is stiff or heavily damped for the
//! record's step (more than four Taylor sub-steps per sample), each probe
//! is summed over its modes.
//! The exact change matters: behind a heavy mass or over a long record a
//! linearized error is optimistic by a factor of several (System 3 under
//! AR(0.9) noise: mass 15 doubled moves `chi^2` by about 6, its linearized
//! standard error promises 30).
//!
//! The report then says `not-identifiable`, names the elements and keeps
//! the answer: it is the best fit, not one the data prove complete.

use super::chainfit::ChainProblem;
use super::engine::{Engine, KFit};
use super::general::Hypothesis;
use super::options::DefectCount;
pub use super::report::unseen::{Unseen, UnseenElement, Z};
use super::Model;
use crate::chain::Chain;
use crate::detect::model::MeasurementModel;
use crate::detect::search::lsq::LeastSquares;
use crate::detect::unknowns::DefectKind;
use crate::error::Result;
use crate::sensitivity::Param;
use nalgebra::{DMatrix, DVector};
use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};

/// The relative change the check is stated for: the element halved, and
/// doubled (the smaller of the two moves counts).
pub const CHANGE: f64 = 0.5;

/// Most elements probed (two residual evaluations each); a longer chain is
/// probed at this many evenly spaced elements.
pub const MAX_PROBES: usize = 120;

impl Engine<'_> {
    /// [`unseen`] for the answer `best` of `f` (`scale`: the final noise
    /// level over `f`'s) when the number of defects was left to the
    /// criterion, for the kinds of `--kinds`; `None` otherwise, or when the
    /// check cannot be made (it never costs the fit its answer).
    pub(super) fn unseen_of(&self, f: &KFit, best: &Hypothesis, scale: f64) -> Option<Unseen> {
        let auto = matches!(self.opts.defects, DefectCount::Auto { .. });
        if !auto || self.given.is_some() || !self.opts.slot_kinds.is_empty() {
            return None;
        }
        let data = self.measurement_at(f.sigma_fit).ok()?;
        unseen(
            best,
            self.model,
            data.as_ref(),
            self.opts.kinds.kinds(),
            scale,
            self.opts.parallel,
        )
        .ok()
        .flatten()
    }
}

/// The elements of `kinds` (masses and springs; other kinds have no
/// neutral value to halve) that `h` leaves unchanged and whose halving or
/// doubling `data` would not show at [`Z`] standard errors (see the module
/// doc); `scale` multiplies every standard error (the final noise level
/// over the one `data` whitens at). At most [`MAX_PROBES`] elements are
/// probed, evenly spaced, on the thread pool when `parallel` (the result
/// does not depend on it). `Ok(None)` when no element of `kinds` is left.
///
/// # Errors
/// The measurement model's errors at a probed chain; cancelled
/// ([`crate::cancel`]).
pub fn unseen(
    h: &Hypothesis,
    model: &Model,
    data: &dyn MeasurementModel,
    kinds: &[DefectKind],
    scale: f64,
    parallel: bool,
) -> Result<Option<Unseen>> {
    let answer = h.to_chain(model.chain())?;
    let all = probes(&answer, kinds);
    let of = all.len();
    let probes = spaced(all, MAX_PROBES);
    if probes.is_empty() {
        return Ok(None);
    }
    let mut params: Vec<Param> = (0..answer.defects().len()).map(Param::Defect).collect();
    params.extend_from_slice(model.fitted());
    let own = match data.jacobian(&answer, &params)? {
        Some(j) => j,
        None => {
            let problem = ChainProblem::new(&answer, &params, data)?;
            LeastSquares::jacobian(&problem, &problem.theta0())?
        }
    };
    let r0 = DVector::from_vec(data.residuals(&answer)?);
    let bounds = Bounds::new(own);
    // each probe differs from the answer in one element: the model's
    // residuals of nearby chains (a long record resumed where it differs,
    // and stopped once its first rows show the change)
    let near = data.near(&answer)?;
    let bar = Z * Z * scale * scale;
    let shown = |c: &Chain| -> Result<f64> {
        let mut enough = |first: &[f64]| bounds.shown(first, &r0) >= bar;
        let r = near(c, &mut enough)?;
        Ok(bounds.shown(&r, &r0) / (scale * scale))
    };
    let least = crate::detect::search::parallel::map(&probes, parallel, 8, |&(kind, at, value)| {
        crate::cancel::check()?;
        let mut least = f64::INFINITY;
        for factor in [1.0 - CHANGE, 1.0 / (1.0 - CHANGE)] {
            let c = answer
                .clone()
                .with_defect(kind.defect(at, factor * value))?;
            least = least.min(shown(&c)?);
            if least.is_nan() || least < Z * Z {
                // not shown, whatever the other change does
                break;
            }
        }
        Ok(least)
    });
    let mut elements = Vec::new();
    for (&(kind, at, _), least) in probes.iter().zip(least) {
        // NaN (a change the model cannot evaluate) counts as not shown
        let least = least?;
        if least.is_nan() || least < Z * Z {
            elements.push(UnseenElement {
                kind: kind.name(),
                at,
            });
        }
    }
    Ok(Some(Unseen {
        elements,
        checked: probes.len(),
        of,
    }))
}

/// The part of a change of the residuals that the answer's own parameters
/// cannot absorb, `min_b |d - J b|^2`, over the first rows of the residuals
/// or all of them: over first rows it is a lower bound of the whole (fewer
/// rows to fit can only fit better), so a probe whose first rows already
/// show the change need not be computed further.
struct Bounds {
    own: DMatrix<f64>,
    /// The orthonormal columns of the first rows of `own`, by row count.
    q: Mutex<BTreeMap<usize, Option<Arc<DMatrix<f64>>>>>,
}

impl Bounds {
    fn new(own: DMatrix<f64>) -> Bounds {
        Bounds {
            own,
            q: Mutex::new(BTreeMap::new()),
        }
    }

    /// `min_b |(r - r0) - J b|^2` over the rows of `r` (the first rows of
    /// a residual vector like `r0`).
    fn shown(&self, r: &[f64], r0: &DVector<f64>) -> f64 {
        let m = r.len().min(r0.len());
        let d = DVector::from_iterator(m, r.iter().zip(r0.iter()).map(|(a, b)| a - b));
        if self.own.ncols() == 0 {
            // nothing of the answer's to absorb the change (an empty
            // Jacobian may have no rows either)
            return d.norm_squared();
        }
        if self.own.nrows() < m {
            // a Jacobian shorter than the residuals: the absorbed part is
            // unknown, so the change counts as not shown
            return 0.0;
        }
        let q = {
            let mut cache = self
                .q
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner);
            cache
                .entry(m)
                .or_insert_with(|| {
                    let j = self.own.rows(0, m).into_owned();
                    (j.ncols() > 0 && m >= j.ncols()).then(|| Arc::new(j.qr().q()))
                })
                .clone()
        };
        match q {
            Some(q) => {
                // d - Q Q^T d, without a copy of Q's transpose
                let along = q.tr_mul(&d);
                let mut off = d;
                off.gemv(-1.0, &*q, &along, 1.0);
                off.norm_squared()
            }
            None if m < self.own.ncols() => 0.0,
            None => d.norm_squared(),
        }
    }
}

/// `(kind, position, value)` of every mass and spring of `kinds` that
/// `answer` leaves unchanged (its own value there).
fn probes(answer: &Chain, kinds: &[DefectKind]) -> Vec<(DefectKind, usize, f64)> {
    let taken: Vec<(DefectKind, usize)> = answer.defects().iter().map(DefectKind::key_of).collect();
    let springs = answer.springs();
    let (lo, hi) = answer.spring_range();
    let mut out = Vec::new();
    for &kind in kinds {
        let sites: Vec<(usize, f64)> = match kind {
            DefectKind::Mass => (1..=answer.n()).map(|j| (j, answer.mass_at(j))).collect(),
            DefectKind::Spring => (lo..=hi).map(|j| (j, springs[j])).collect(),
            DefectKind::Damper | DefectKind::Ground => continue,
        };
        out.extend(
            sites
                .into_iter()
                .filter(|&(at, value)| value > 0.0 && !taken.contains(&(kind, at)))
                .map(|(at, value)| (kind, at, value)),
        );
    }
    out
}

/// At most `max` of `v`, evenly spaced, first and last kept.
fn spaced<T: Copy>(v: Vec<T>, max: usize) -> Vec<T> {
    if v.len() <= max || max < 2 {
        return v;
    }
    let last = v.len() - 1;
    (0..max).map(|i| v[i * last / (max - 1)]).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Over first rows the unabsorbed change never exceeds the whole
    /// one's and grows with the rows; over all rows it is the projection
    /// off the Jacobian's columns.
    #[test]
    fn bounds_over_first_rows_grow_to_the_whole_projection() {
        let m = 200;
        let j = DMatrix::from_fn(m, 3, |r, c| ((r * (c + 2)) as f64 * 0.37).sin() + c as f64);
        let r0 = DVector::from_fn(m, |r, _| (r as f64 * 0.11).cos());
        let r: Vec<f64> = (0..m)
            .map(|i| r0[i] + 0.01 * (i as f64 * 0.05).sin() * (i as f64).sqrt())
            .collect();
        let b = Bounds::new(j.clone());
        let whole = b.shown(&r, &r0);
        let d = DVector::from_iterator(m, r.iter().zip(r0.iter()).map(|(a, b)| a - b));
        let q = j.qr().q();
        let direct = (&d - &q * (q.transpose() * &d)).norm_squared();
        assert!((whole - direct).abs() <= 1e-12 * direct, "{whole} {direct}");
        assert!(whole > 0.0);
        let mut last = 0.0;
        for rows in (0..=m).step_by(7) {
            let v = b.shown(&r[..rows], &r0);
            assert!(
                v >= last - 1e-12 * whole && v <= whole * (1.0 + 1e-12),
                "{rows}: {v}"
            );
            last = v;
        }
        // fewer rows than parameters are fitted exactly
        assert_eq!(b.shown(&r[..2], &r0), 0.0);
        // no parameters (an empty Jacobian, perhaps without rows): all of it
        for empty in [DMatrix::zeros(0, 0), DMatrix::zeros(m, 0)] {
            let none = Bounds::new(empty);
            assert_eq!(none.shown(&r, &r0), d.norm_squared());
            assert_eq!(none.shown(&r[..50], &r0), d.rows(0, 50).norm_squared());
        }
    }

    #[test]
    fn spacing_keeps_the_ends_and_the_count() {
        let v: Vec<usize> = (1..=1000).collect();
        let s = spaced(v.clone(), 120);
        assert_eq!((s.len(), s[0], s[119]), (120, 1, 1000));
        assert!(s.windows(2).all(|w| w[1] > w[0]));
        assert_eq!(spaced(v[..5].to_vec(), 120), v[..5].to_vec());
    }

    #[test]
    fn probes_skip_the_answers_elements_and_free_ends() {
        let c = crate::scenes::paper_with(5, "mass:2:3").unwrap();
        let p = probes(
            &c,
            &[DefectKind::Mass, DefectKind::Spring, DefectKind::Damper],
        );
        let masses: Vec<usize> = p
            .iter()
            .filter(|q| q.0 == DefectKind::Mass)
            .map(|q| q.1)
            .collect();
        assert_eq!(masses, vec![1, 3, 4, 5]);
        assert_eq!(p.iter().filter(|q| q.0 == DefectKind::Spring).count(), 6);
        assert!(p.iter().all(|q| q.2 == 1.0));
        let free = c
            .with_boundaries(crate::chain::Boundary::Fixed, crate::chain::Boundary::Free)
            .unwrap();
        assert_eq!(probes(&free, &[DefectKind::Spring]).len(), 5);
    }
}
