//! Whether one or two more defects could win: a linear bound that lets the
//! `auto` loop stop at a fit that explains the record without fitting the
//! larger numbers of defects the criterion would reject (issue 30 item 1).
//!
//! At the answer of a fit with `k` defects, its whitened residual `r` is
//! orthogonal to the columns `J` of its own parameters (its defects' values
//! and the fitted chain parameters). Adding a defect at an element `e`
//! (a mass, spring or damper the answer leaves at its chain value) moves
//! the residual, to first order, along the column `c_e` of that element's
//! value; refitting the answer's own parameters alongside leaves the part
//! `c_e' = (I - J J^+) c_e`. The best a small defect there can take off the
//! chi-square is then `(c_e' . r)^2 / |c_e'|^2`, and the best two such
//! defects together `b^T G^-1 b` over the pair (`b = C'^T r`, `G = C'^T
//! C'`). When both stay below half the criterion's price of one and of two
//! defects, the fits at `k + 1` and `k + 2` are not made.
//!
//! The bound is linear: a large defect may explain more than its first
//! derivative says. It is therefore used only where the fit at `k` already
//! explains the record (its residual is white, or its chi-square is that of
//! the noise): a large change the answer left out would leave a residual
//! that the test sees. With a margin of a factor two on the price,
//! `tests/room_for_more.rs` checks on its records that the fits left out
//! would have lost, and on 120 records drawn at random (the guide's "No
//! room for more") the answers were those of the loop without the bound.

use super::{Engine, KFit};
use crate::chain::Chain;
use crate::detect::fit::assemble::fits_data;
use crate::detect::fit::options::DefectCount;
use crate::detect::fit::select::Criterion;
use crate::detect::fit::NoiseSpec;
use crate::detect::model::MeasurementModel;
use crate::detect::unknowns::DefectKind;
use crate::error::Result;
use crate::sensitivity::Param;
use nalgebra::{DMatrix, DVector};

/// The share of the criterion's price of one (two) more defects that the
/// linear bound must stay below.
pub(super) const MARGIN: f64 = 0.5;

/// Most elements the bound is formed for (a Jacobian column each, and a
/// Gram matrix of their square); a search over more (a long chain, or
/// every kind on a chain of 67 masses or more) goes on by the loop's own
/// rule ([`super::stop_early`]).
pub(super) const MAX_ELEMENTS: usize = 200;

/// The linear bound at a fit's answer: the most one more defect, and two
/// more together, could take off its chi-square (at the fit's own noise
/// level).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Room {
    pub(super) one: f64,
    pub(super) two: f64,
}

impl Engine<'_> {
    /// Whether the `auto` loop may stop at the last of `fits`: it explains
    /// the record and [`Probe::bound`] leaves one and two more defects
    /// below [`MARGIN`] of the criterion's price (BIC only; never at effort
    /// high, with a scene's unknowns, positions or per-slot kinds given).
    pub(in crate::detect::fit) fn no_room_for_more(&self, fits: &[KFit]) -> bool {
        let Some(f) = fits.last() else {
            return false;
        };
        let usable = self.opts.effort.stop_after().is_some()
            && matches!(self.opts.defects, DefectCount::Auto { k_max } if k_max > f.k)
            && self.opts.criterion == Criterion::Bic
            && self.given.is_none()
            && self.opts.slot_kinds.is_empty()
            && self.opts.set.is_empty();
        if !usable {
            return false;
        }
        let estimated = self.opts.noise == NoiseSpec::Auto;
        let level = if estimated { f.sigma_hat } else { f.sigma_fit };
        if !fits_data(f, level, estimated) {
            return false;
        }
        let scale = (level / f.sigma_fit).powi(2);
        // BIC's price of a defect of unknown position: two parameters
        let price = 2.0 * (f.n_data.max(2) as f64).ln();
        let no_room = |room: Option<Room>| {
            room.is_some_and(|r| {
                r.one / scale < MARGIN * price && r.two / scale < MARGIN * 2.0 * price
            })
        };
        let Ok(Some(probe)) = self.probe(f) else {
            return false;
        };
        let Ok(data) = self.measurement_at(f.sigma_fit) else {
            return false;
        };
        no_room(probe.bound(data.as_ref()).ok().flatten())
    }

    /// The [`Probe`] of the answer of `f`: `None` where an element of the
    /// search has no value to differentiate at, or the search has more than
    /// [`MAX_ELEMENTS`].
    ///
    /// # Errors
    /// As the unknowns' construction and the answer's chain.
    fn probe(&self, f: &KFit) -> Result<Option<Probe>> {
        let Some(best) = f.ranked.first() else {
            return Ok(None);
        };
        let Some(unknowns) = self.unknowns(1)? else {
            return Ok(None);
        };
        let answer = best.to_chain(self.model.chain())?;
        let taken: Vec<(DefectKind, usize)> =
            answer.defects().iter().map(DefectKind::key_of).collect();
        let mut elements: Vec<(DefectKind, usize)> = Vec::new();
        for set in unknowns.hypotheses(self.opts.max_sets)? {
            for e in set {
                if !taken.contains(&e) && !elements.contains(&e) {
                    elements.push(e);
                }
            }
        }
        if elements.is_empty() || elements.len() > MAX_ELEMENTS {
            return Ok(None);
        }
        let Some(chain) = neutral(&answer, &elements)? else {
            return Ok(None);
        };
        let own = answer.defects().len();
        let mut params: Vec<Param> = (0..own).map(Param::Defect).collect();
        params.extend_from_slice(self.model.fitted());
        let fitted = params.len();
        params.extend((0..elements.len()).map(|i| Param::Defect(own + i)));
        Ok(Some(Probe {
            answer,
            chain,
            params,
            fitted,
        }))
    }
}

/// An answer and every element the search may add to it, each a defect at
/// its chain value ([`neutral`]).
struct Probe {
    answer: Chain,
    /// The answer with the elements' neutral defects after its own.
    chain: Chain,
    /// The answer's own parameters (its defects' values, the fitted chain
    /// parameters), then one per element.
    params: Vec<Param>,
    /// How many of `params` are the answer's own.
    fitted: usize,
}

impl Probe {
    /// [`Room`] at the answer on `data`, in the chi-square of its whitened
    /// residuals; `None` where `data` has no analytic Jacobian.
    ///
    /// # Errors
    /// The measurement model's errors at the answer.
    fn bound(&self, data: &dyn MeasurementModel) -> Result<Option<Room>> {
        let Some(j) = data.jacobian(&self.chain, &self.params)? else {
            return Ok(None);
        };
        let r = DVector::from_vec(data.residuals(&self.answer)?);
        Ok(Some(bound(&j, self.fitted, &r)))
    }
}

/// `answer` with every element of `elements` a defect at the value the
/// answer gives it (the same chain; each value now a parameter), or `None`
/// where an element's value is not one a defect of its kind there takes
/// (a spring at a free end; a damper under Rayleigh or modal damping).
fn neutral(answer: &Chain, elements: &[(DefectKind, usize)]) -> Result<Option<Chain>> {
    use crate::chain::Damping;
    let springs = answer.springs();
    let (dampers, parallel) = (answer.dampers(), answer.spring_dampers());
    let grounds = answer.grounds();
    let mut defects = Vec::with_capacity(elements.len());
    for &(kind, at) in elements {
        let value = match kind {
            DefectKind::Mass => answer.mass_at(at),
            DefectKind::Spring => springs[at],
            DefectKind::Ground => grounds[at - 1],
            DefectKind::Damper => match answer.damping() {
                Damping::Grounded => dampers[at - 1],
                Damping::Between { .. } => parallel[at],
                _ => return Ok(None),
            },
        };
        if !(value.is_finite() && (value > 0.0 || kind != DefectKind::Spring)) {
            return Ok(None);
        }
        defects.push(kind.defect(at, value));
    }
    Ok(Some(answer.clone().with_defects(defects)?))
}

/// [`Room`] from the Jacobian `j` (the first `fitted` columns the answer's
/// own parameters, then one column per element) and the residual `r`.
fn bound(j: &DMatrix<f64>, fitted: usize, r: &DVector<f64>) -> Room {
    let m = j.ncols() - fitted;
    let mut c = j.columns(fitted, m).into_owned();
    if fitted > 0 {
        let q = j.columns(0, fitted).into_owned().qr().q();
        c.gemm(-1.0, &q, &q.tr_mul(&c), 1.0);
    }
    let b = c.tr_mul(r);
    // (a transposed copy: the blocked product is faster than dot products)
    let g = c.transpose() * &c;
    // a column the answer's parameters absorb entirely shows nothing
    let tiny = 1e-12 * g.diagonal().max().max(f64::MIN_POSITIVE);
    let single = |i: usize| {
        if g[(i, i)] > tiny {
            b[i] * b[i] / g[(i, i)]
        } else {
            0.0
        }
    };
    let mut room = Room { one: 0.0, two: 0.0 };
    for i in 0..m {
        let si = single(i);
        room.one = room.one.max(si);
        room.two = room.two.max(si);
        for k in i + 1..m {
            let det = g[(i, i)] * g[(k, k)] - g[(i, k)] * g[(i, k)];
            let pair = if det > 1e-9 * g[(i, i)] * g[(k, k)] && det > 0.0 {
                (g[(k, k)] * b[i] * b[i] - 2.0 * g[(i, k)] * b[i] * b[k] + g[(i, i)] * b[k] * b[k])
                    / det
            } else {
                si.max(single(k))
            };
            room.two = room.two.max(pair);
        }
    }
    room
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bound against a least-squares fit of the columns themselves: a
    /// linear model's best one and two added columns.
    #[test]
    fn the_bound_is_the_linear_least_squares_reduction() {
        let rows = 40;
        let col = |seed: usize| -> Vec<f64> {
            (0..rows)
                .map(|i| {
                    (((i * 7 + seed * 13) % 17) as f64 - 8.0) / 5.0
                        + (seed as f64 * 0.3 + i as f64).sin()
                })
                .collect()
        };
        let cols: Vec<Vec<f64>> = (0..5).map(col).collect();
        let j = DMatrix::from_fn(rows, 5, |i, k| cols[k][i]);
        // r orthogonal to the first column (the answer's own)
        let raw = DVector::from_fn(rows, |i, _| ((i * 3) % 11) as f64 - 5.0);
        let q = j.columns(0, 1).into_owned().qr().q();
        let r = &raw - &q * (q.transpose() * &raw);
        let room = bound(&j, 1, &r);
        let reduction = |ks: &[usize]| -> f64 {
            let mut idx = vec![0];
            idx.extend_from_slice(ks);
            let a = DMatrix::from_fn(rows, idx.len(), |i, k| j[(i, idx[k])]);
            let x = a.clone().svd(true, true).solve(&r, 1e-14).unwrap();
            r.norm_squared() - (&r - &a * x).norm_squared()
        };
        let one = (1..5).map(|k| reduction(&[k])).fold(0.0, f64::max);
        let mut two = 0.0f64;
        for a in 1..5 {
            for b in a + 1..5 {
                two = two.max(reduction(&[a, b]));
            }
        }
        assert!(
            (room.one - one).abs() < 1e-9 * one.max(1.0),
            "{room:?} {one}"
        );
        assert!(
            (room.two - two).abs() < 1e-9 * two.max(1.0),
            "{room:?} {two}"
        );
    }
}
