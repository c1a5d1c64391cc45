//! The time-record stage of the greedy search: for a sampled record of the
//! paper's measurement, candidates are scored and values refitted on the
//! record itself rather than on the Bromwich line, where defects deep in a
//! long, lightly damped chain fall below the noise while their echoes stand
//! well above it in the record.
//!
//! * **Score.** From the current fit, one simulation gives the residual and
//!   every candidate's sensitivity `g = d x_1 / d value`
//!   ([`Screen`], reciprocity and one FFT convolution per candidate); the
//!   score is the chi-square drop of the best single-value step,
//!   `(r.g)^2 / (g.g)` (its step clamped to the value's bounds).
//! * **Refit.** The `time.refit` best are added in turn and every free value
//!   refitted by the bounded Levenberg-Marquardt ([`lm_normal`]) on the
//!   record, residuals exact (the same simulation) and Jacobian from the
//!   same convolutions (one simulation per iteration, no modal
//!   decomposition); the best is kept.
//! * **Neighbours.** The defect just added is tried one and two positions
//!   away (same kind), each refit started from its fitted value: the
//!   linear score misjudges large defects: a mass of 3 next to the wall
//!   shifts the phase of the whole late record; where it was, its linear
//!   drop was 0.3% of what its refit gave and ranked 33rd, while the search
//!   had placed it two masses away.
//! * **Moves.** Each placed defect is taken out in turn, the candidates
//!   rescored against the rest, and those scoring at least `time.move_ratio`
//!   of where it was (at most `time.refit`) refitted; the best refit
//!   replaces it when it lowers the chi-square. Passes repeat until none
//!   helps (at most `max_passes`).
//! * **One defect at a time.** The fits with `1, 2, ..., k` defects are the
//!   stages of one path (add, then moves), so that the fit of `k` defects
//!   starts from that of `k - 1`. A `k = auto` fit asks for `k = 1, 2, ...`
//!   in turn (and again after re-estimating `sigma`): the stages are kept
//!   in a small process-wide memo keyed by the record, the chain and the
//!   unknowns, so each is computed once. The memo holds unwhitened residual
//!   sums, so a new `sigma` only rescales the chi-squares and standard
//!   errors; the result is the same with or without it.
//!
//! Deterministic: candidates are ranked by `(score, position, kind)`, refits
//! by `(chi-square, sorted pairs)`; parallel work (rayon) only evaluates.

use super::{Counters, Greedy, GreedyFit};
use crate::chain::Chain;
use crate::detect::fit::general::Hypothesis;
use crate::detect::misfit::time::TimeMisfit;
use crate::detect::misfit::time_screen::{Candidate, Screen};
use crate::detect::search::lsq::{lm_normal, LmOptions, NormalEquations};
use crate::detect::unknowns::{DefectKind, KindPositions};
use crate::error::{Error, Result};
use std::sync::Mutex;

/// Options of the time-record stage ([`super::GreedyOptions::time`]).
#[derive(Clone, Debug, PartialEq)]
pub struct TimeStage {
    /// Use it when the fit has a sampled record of the paper's measurement
    /// and no fitted chain parameter (default true).
    pub enabled: bool,
    /// Best-scored candidates refitted at each step (default 3).
    pub refit: usize,
    /// Levenberg-Marquardt iterations per refit (default 12).
    pub max_iter: usize,
    /// A move refits a candidate only if its score is at least this share
    /// of the score of the position it would replace (default 0.7).
    pub move_ratio: f64,
    /// Keep the stages in the process-wide memo (default true; results do
    /// not depend on it).
    pub memo: bool,
}

impl Default for TimeStage {
    fn default() -> Self {
        TimeStage {
            enabled: true,
            refit: 3,
            max_iter: 12,
            move_ratio: 0.7,
            memo: true,
        }
    }
}

/// One refit of the time stage, unwhitened.
#[derive(Clone, Debug)]
struct TFit {
    /// `(kind, position)` of every slot in slot order (fixed slots first,
    /// then the placed ones by position and kind).
    pairs: KindPositions,
    chain: Chain,
    /// Residual sum of squares.
    rss: f64,
    /// Per defect `sqrt((J^T J)^-1)_jj` of the unwhitened Jacobian (times
    /// `sigma`: the standard error); 0 for a known value.
    se_unit: Vec<f64>,
    converged: bool,
}

impl TFit {
    fn key(&self) -> KindPositions {
        let mut k = self.pairs.clone();
        k.sort_unstable_by_key(|&(kind, at)| (at, kind));
        k
    }
}

/// The fits with a given number of placed defects.
#[derive(Clone, Debug)]
struct Stage {
    best: TFit,
    /// Every refit with this many placed defects.
    seen: Vec<TFit>,
    /// Cumulative (refits, simulations, candidates scored, screenings).
    counters: (usize, usize, usize, usize),
}

/// What the memo is keyed by: the record and a description of the problem.
#[derive(Clone, Debug, PartialEq)]
struct Key {
    t: Vec<u64>,
    y: Vec<u64>,
    problem: String,
}

/// Most problems kept in the memo.
const MEMO: usize = 4;

static STAGES: Mutex<Vec<(Key, Vec<Stage>)>> = Mutex::new(Vec::new());

struct Ctx<'a, 'g> {
    g: &'a Greedy<'g>,
    screen: Screen,
    /// Internal whitening of the refits (`max|y| 1e-3`): the LM is scale
    /// invariant, so results do not depend on it.
    scale: f64,
    counters: Counters,
    /// The last candidates scored ([`Ctx::scored`]): the chain, the
    /// defects present, and the scores. The first move of stage 1 takes
    /// its one defect out again, back to the chain stage 1 scored.
    last_scored: Mutex<Option<Scored>>,
}

/// A chain, the defects present on it, and its candidates' scores.
type Scored = (Chain, KindPositions, Vec<(f64, DefectKind, usize, f64)>);

/// The time stage for `g` on `t` (module docs), or `None` where it does not
/// apply (another measurement, fitted chain parameters, no impulse, a
/// record not on a uniform grid from a multiple of its step).
pub(super) fn run(g: &Greedy<'_>, t: &TimeMisfit) -> Result<Option<GreedyFit>> {
    let opts = &g.opts.time;
    let data = t.data();
    if !opts.enabled
        || t.sensors() > 1
        || !data.measurement().is_paper()
        || !g.unknowns.chain().is_empty()
        || g.base.gamma() == 0.0
    {
        return Ok(None);
    }
    let Some(screen) = Screen::new(data.t(), data.y(), &g.base) else {
        return Ok(None);
    };
    let big = data.y().iter().fold(0.0f64, |a, b| a.max(b.abs()));
    let ctx = Ctx {
        g,
        screen,
        scale: if big > 0.0 { 1e-3 * big } else { 1.0 },
        counters: Counters::default(),
        last_scored: Mutex::new(None),
    };
    let key = Key {
        t: data.t().iter().map(|v| v.to_bits()).collect(),
        y: data.y().iter().map(|v| v.to_bits()).collect(),
        problem: ctx.describe(),
    };
    let stages = ctx.stages(key, g.free.len(), opts.memo)?;
    Ok(Some(result(
        &stages[g.free.len()],
        data.sigma_eff(),
        data.len(),
    )))
}

/// The report of the stage with every defect placed: its distinct fits,
/// best first, at the noise level `sigma`.
fn result(stage: &Stage, sigma: f64, residuals: usize) -> GreedyFit {
    let mut seen = stage.seen.clone();
    seen.sort_by(|a, b| a.key().cmp(&b.key()).then_with(|| a.rss.total_cmp(&b.rss)));
    seen.dedup_by(|a, b| a.key() == b.key());
    seen.sort_by(|a, b| a.rss.total_cmp(&b.rss).then_with(|| a.key().cmp(&b.key())));
    let ranked: Vec<Hypothesis> = seen
        .iter()
        .map(|f| {
            let mut h = Hypothesis::from_parts(
                f.chain.defects().to_vec(),
                f.se_unit.iter().map(|s| s * sigma).collect(),
                Vec::new(),
                f.rss / (sigma * sigma),
            );
            h.converged = f.converged;
            h
        })
        .collect();
    let (hypotheses, evaluations, scored, sweeps) = stage.counters;
    GreedyFit {
        paths: vec![stage.best.rss / (sigma * sigma)],
        ranked,
        hypotheses,
        evaluations,
        scored,
        sweeps,
        residuals,
    }
}

impl Ctx<'_, '_> {
    /// Stages `0..=k` (one more defect placed each), from the memo of
    /// earlier fits of the same record and problem when `memo`, the memo
    /// updated with what was added.
    fn stages(&self, key: Key, k: usize, memo: bool) -> Result<Vec<Stage>> {
        let mut stages: Vec<Stage> = if memo {
            let memo = STAGES.lock().unwrap_or_else(|e| e.into_inner());
            memo.iter()
                .find(|(kk, _)| *kk == key)
                .map(|(_, s)| s.clone())
                .unwrap_or_default()
        } else {
            Vec::new()
        };
        if let Some(last) = stages.last() {
            self.counters.set(last.counters);
        }
        let grew = stages.len() <= k;
        while stages.len() <= k {
            let stage = if stages.is_empty() {
                self.start()?
            } else {
                self.next(&stages[stages.len() - 1].best, stages.len())?
            };
            stages.push(stage);
        }
        if memo && grew {
            let mut memo = STAGES.lock().unwrap_or_else(|e| e.into_inner());
            memo.retain(|(kk, _)| *kk != key);
            memo.push((key, stages.clone()));
            if memo.len() > MEMO {
                memo.remove(0);
            }
        }
        Ok(stages)
    }

    fn count(&self, hyps: usize, evals: usize, scored: usize, sweeps: usize) {
        self.counters.add(hyps, evals, scored, sweeps);
    }

    fn counters(&self) -> (usize, usize, usize, usize) {
        self.counters.get()
    }

    /// What the stages depend on besides the record.
    fn describe(&self) -> String {
        let g = self.g;
        let slots = g.unknowns.slots();
        let fixed: Vec<_> = slots.iter().filter(|s| s.at.is_some()).collect();
        let free = g.free.first().map(|&i| slots[i]);
        let o = &g.opts;
        format!(
            "{:?}|{:?}|{:?}|{:?}|{:?}|{:?}|{}|{:?}",
            g.base,
            fixed,
            free,
            g.unknowns.kind_bounds(),
            g.kinds,
            o.time,
            o.max_passes,
            g.free.first().map(|&i| {
                DefectKind::ALL
                    .iter()
                    .map(|&k| g.unknowns.bounds(i, k))
                    .collect::<Vec<_>>()
            })
        )
    }

    /// Stage 0: the fixed slots, their free values fitted.
    fn start(&self) -> Result<Stage> {
        let (pairs, values) = self.g.start_pairs();
        let fit = self.refit(
            &pairs,
            &self.g.slot_of(0),
            &values,
            f64::INFINITY,
            self.g.opts.time.max_iter,
        )?;
        Ok(Stage {
            best: fit.clone(),
            seen: vec![fit],
            counters: self.counters(),
        })
    }

    /// Candidates not in `present`, with the uniform value of their kind.
    fn candidates(&self, chain: &Chain, present: &KindPositions) -> Vec<Candidate> {
        let n = chain.n();
        let (lo, hi) = chain.spring_range();
        let mut c = Vec::new();
        for &kind in &self.g.kinds {
            for at in kind.positions(n) {
                if kind == DefectKind::Spring && (at < lo || at > hi) {
                    continue;
                }
                if !present.contains(&(kind, at)) {
                    c.push((kind, at));
                }
            }
        }
        c
    }

    /// Every candidate against `chain`, best first: `(drop, kind, at,
    /// value)`, the drop in unwhitened squares, the value the step's. The
    /// chain scored last is not scored again (the same scores).
    fn scored(
        &self,
        chain: &Chain,
        present: &KindPositions,
    ) -> Result<Vec<(f64, DefectKind, usize, f64)>> {
        let last = |l: &Scored| l.0 == *chain && l.1 == *present;
        let mut memo = self.last_scored.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(l) = memo.as_ref().filter(|l| last(l)) {
            return Ok(l.2.clone());
        }
        let out = self.score_all(chain, present)?;
        *memo = Some((chain.clone(), present.clone(), out.clone()));
        Ok(out)
    }

    /// [`Ctx::scored`] without its memo.
    fn score_all(
        &self,
        chain: &Chain,
        present: &KindPositions,
    ) -> Result<Vec<(f64, DefectKind, usize, f64)>> {
        let cands = self.candidates(chain, present);
        let (_, s) = self.screen.score(chain, &cands, self.g.opts.parallel)?;
        self.count(0, 1, cands.len(), 1);
        let b = &self.g.score_opts.bounds;
        let mut out: Vec<(f64, DefectKind, usize, f64)> = cands
            .iter()
            .zip(&s)
            .map(|(&(kind, at), &(rg, gg))| {
                let v0 = kind.base_at(chain, at);
                let (lo, hi) = b.of(kind);
                if !(gg > 0.0 && gg.is_finite() && rg.is_finite()) {
                    return (0.0, kind, at, v0);
                }
                let v = (v0 + rg / gg).clamp(lo, hi);
                let d = v - v0;
                ((2.0 * d * rg - d * d * gg).max(0.0), kind, at, v)
            })
            .collect();
        out.sort_by(|a, b| {
            b.0.total_cmp(&a.0)
                .then_with(|| a.2.cmp(&b.2))
                .then_with(|| a.1.cmp(&b.1))
        });
        Ok(out)
    }

    fn best_of(fits: Vec<TFit>) -> Option<TFit> {
        fits.into_iter()
            .min_by(|a, b| a.rss.total_cmp(&b.rss).then_with(|| a.key().cmp(&b.key())))
    }

    /// Refit `cur` plus each candidate (value: the step's), abandoning a
    /// refit that has not gone below `beat` after a few iterations;
    /// hypotheses refitted before in `done` are not refitted again.
    fn extend(
        &self,
        cur: &TFit,
        cands: &[(f64, DefectKind, usize, f64)],
        beat: f64,
        done: &[TFit],
    ) -> Vec<TFit> {
        let n_fixed = self.g.slot_of(0).len();
        let placed = cur.pairs.len() - n_fixed + 1;
        let slot_of = self.g.slot_of(placed);
        let fits = self.g.map(cands, |&(_, kind, at, v)| {
            let mut pairs = cur.pairs.clone();
            pairs.push((kind, at));
            let mut key = pairs.clone();
            key.sort_unstable_by_key(|&(kind, at)| (at, kind));
            if let Some(f) = done.iter().find(|f| f.key() == key) {
                return Some(f.clone());
            }
            let mut values: Vec<f64> = cur.chain.defects().iter().map(|d| d.value()).collect();
            values.push(v);
            self.refit(&pairs, &slot_of, &values, beat, self.g.opts.time.max_iter)
                .ok()
        });
        fits.into_iter().flatten().collect()
    }

    /// Stage `j` from the best of stage `j - 1`: add one defect, then moves.
    fn next(&self, prev: &TFit, j: usize) -> Result<Stage> {
        let opts = &self.g.opts.time;
        let n_fixed = self.g.slot_of(0).len();
        let mut seen = Vec::new();
        let s = self.scored(&prev.chain, &prev.pairs)?;
        if s.is_empty() {
            return Err(Error::invalid(
                "defects",
                self.g.free.len(),
                "at most the number of candidate positions",
            ));
        }
        let cands: Vec<_> = s.into_iter().take(opts.refit).collect();
        let fits = self.extend(prev, &cands, prev.rss, &seen);
        seen.extend(fits.iter().cloned());
        let mut cur = Self::best_of(fits).ok_or_else(|| Error::Numerical {
            method: "greedy (time record)".into(),
            reason: format!("no candidate for defect {j} could be fitted"),
        })?;
        cur = self.neighbours(prev, cur, n_fixed, &mut seen);
        cur = self.moves(cur, n_fixed, &mut seen)?;
        cur = self.polished(cur, n_fixed, &mut seen);
        Ok(Stage {
            best: cur,
            seen,
            counters: self.counters(),
        })
    }

    /// The new defect's neighbours (two positions each side), from its
    /// fitted value: the linear score misjudges a large defect (a heavy mass
    /// by the wall shifts the phase of the whole late record). Returns the
    /// better of `cur` and the best neighbour; every fit is added to `seen`.
    fn neighbours(&self, prev: &TFit, cur: TFit, n_fixed: usize, seen: &mut Vec<TFit>) -> TFit {
        let Some(i) = (n_fixed..cur.pairs.len()).find(|&i| !prev.pairs.contains(&cur.pairs[i]))
        else {
            return cur;
        };
        let (kind, at) = cur.pairs[i];
        let v = cur.chain.defects()[i].value();
        let n = self.g.base.n();
        let (lo, hi) = self.g.base.spring_range();
        let near: Vec<_> = [at.wrapping_sub(2), at.wrapping_sub(1), at + 1, at + 2]
            .into_iter()
            .filter(|&q| kind.positions(n).contains(&q))
            .filter(|&q| kind != DefectKind::Spring || (lo..=hi).contains(&q))
            .filter(|&q| !cur.pairs.contains(&(kind, q)))
            .map(|q| (0.0, kind, q, v))
            .collect();
        let fits = self.extend(prev, &near, cur.rss, seen);
        seen.extend(fits.iter().cloned());
        match Self::best_of(fits) {
            Some(b) if b.rss < cur.rss * (1.0 - 1e-9) => b,
            _ => cur,
        }
    }

    /// Moves: each placed defect in turn taken out and the best candidates
    /// for its place refitted, while that improves (at most `max_passes`
    /// passes); every fit is added to `seen`.
    fn moves(&self, mut cur: TFit, n_fixed: usize, seen: &mut Vec<TFit>) -> Result<TFit> {
        let opts = &self.g.opts.time;
        for _ in 0..self.g.opts.max_passes {
            let mut improved = false;
            for p in n_fixed..cur.pairs.len() {
                let (kind, at) = cur.pairs[p];
                let mut rest = cur.clone();
                rest.pairs.remove(p);
                rest.chain = cur.chain.without_defect(p);
                let s = self.scored(&rest.chain, &rest.pairs)?;
                let here = s
                    .iter()
                    .find(|c| (c.1, c.2) == (kind, at))
                    .map_or(0.0, |c| c.0);
                let cands: Vec<_> = s
                    .into_iter()
                    .filter(|c| (c.1, c.2) != (kind, at) && c.0 >= opts.move_ratio * here)
                    .take(opts.refit)
                    .collect();
                if cands.is_empty() {
                    continue;
                }
                let fits = self.extend(&rest, &cands, cur.rss, seen);
                seen.extend(fits.iter().cloned());
                if let Some(b) = Self::best_of(fits) {
                    if b.rss < cur.rss * (1.0 - 1e-9) {
                        cur = b;
                        improved = true;
                    }
                }
            }
            if !improved {
                break;
            }
        }
        Ok(cur)
    }

    /// The stage's best fit, its values refitted to the minimum when its
    /// capped refit stopped short ([`TimeStage::max_iter`] iterations, or
    /// abandoned): the search compares hypotheses on a few iterations each,
    /// but the answer's values and standard errors must be the minimum's
    /// (a deep defect's flat valley took a dozen iterations and more). At
    /// most [`POLISH_ITER`] iterations; kept (and added to `seen`) when it
    /// is no worse.
    fn polished(&self, cur: TFit, n_fixed: usize, seen: &mut Vec<TFit>) -> TFit {
        if cur.converged {
            return cur;
        }
        let slot_of = self.g.slot_of(cur.pairs.len() - n_fixed);
        let values: Vec<f64> = cur.chain.defects().iter().map(|d| d.value()).collect();
        match self.refit(&cur.pairs, &slot_of, &values, f64::INFINITY, POLISH_ITER) {
            Ok(f) if f.rss <= cur.rss => {
                seen.push(f.clone());
                f
            }
            _ => cur,
        }
    }

    /// Refit the free values of `pairs` (slot order, `slot_of` their slots)
    /// from `values` on the record; the placed defects in canonical order.
    /// A refit whose chi-square is still above `beat` (unwhitened) after
    /// [`ABANDON_AFTER`] evaluations is abandoned: it stops where it is,
    /// marked not converged.
    fn refit(
        &self,
        pairs: &KindPositions,
        slot_of: &[usize],
        values: &[f64],
        beat: f64,
        max_iter: usize,
    ) -> Result<TFit> {
        let g = self.g;
        let slots = g.unknowns.slots();
        let (pairs, values) = g.canonical(pairs, slot_of, values);
        let mut defects = Vec::with_capacity(pairs.len());
        let mut free = Vec::new();
        let mut theta = Vec::new();
        let mut bounds = Vec::new();
        for (j, (&(kind, at), &v)) in pairs.iter().zip(&values).enumerate() {
            match slots[slot_of[j]].known {
                Some(known) => defects.push(kind.defect(at, known)),
                None => {
                    let b = g.unknowns.bounds(slot_of[j], kind);
                    let v = v.clamp(b.0, b.1);
                    defects.push(kind.defect(at, v));
                    free.push(j);
                    theta.push(v);
                    bounds.push(b);
                }
            }
        }
        let chain = g.base.uniform().with_defects(defects)?;
        if free.is_empty() {
            let r = self.screen.residual(&chain)?;
            self.count(1, 1, 0, 0);
            return Ok(TFit {
                se_unit: vec![0.0; pairs.len()],
                pairs,
                chain,
                rss: r.iter().map(|v| v * v).sum(),
                converged: true,
            });
        }
        let mut problem = Values {
            screen: &self.screen,
            chain,
            free: free.clone(),
            cands: free.iter().map(|&j| pairs[j]).collect(),
            scale: 1.0 / self.scale,
            best: None,
            beat: beat / (self.scale * self.scale),
            evaluations: 0,
            abandoned: false,
        };
        let lm_opts = LmOptions {
            max_iter,
            rtol: 1e-7,
            xtol: 1e-7,
            ..LmOptions::default()
        };
        let lm = lm_normal(&mut problem, &mut theta, &bounds, &lm_opts)?;
        self.count(1, problem.evaluations, 0, 0);
        let chain = problem.chain_at(&theta)?;
        let se_unit = problem.unit_errors(&theta, pairs.len());
        Ok(TFit {
            pairs,
            chain,
            rss: lm.chi2 * self.scale * self.scale,
            se_unit,
            converged: lm.converged && !problem.abandoned,
        })
    }
}

impl Values<'_> {
    /// Standard errors at unit noise of the defect values (0 for a held
    /// one; all 0 when the last normal matrix is not at `theta`):
    /// `(J_u^T J_u)^-1 = s^2 (J^T J)^-1` with `J = s J_u`.
    fn unit_errors(&self, theta: &[f64], k: usize) -> Vec<f64> {
        let mut se_unit = vec![0.0; k];
        let p = self.free.len();
        if let Some((_, th, h)) = &self.best {
            if th.as_slice() == theta {
                let m = nalgebra::DMatrix::from_row_slice(p, p, h);
                let inv = m.try_inverse();
                for (c, &j) in self.free.iter().enumerate() {
                    se_unit[j] = inv
                        .as_ref()
                        .map(|i| i[(c, c)])
                        .filter(|v| *v >= 0.0)
                        .map_or(f64::NAN, |v| v.sqrt() * self.scale);
                }
            }
        }
        se_unit
    }
}

/// The free values of one hypothesis as a least-squares problem on the
/// record: residuals `(x_1 - y) s` and Jacobian `g s` from one simulation.
struct Values<'a> {
    screen: &'a Screen,
    /// The hypothesis (free values replaced at each evaluation).
    chain: Chain,
    /// Indices of the free values among the chain's defects.
    free: Vec<usize>,
    cands: Vec<Candidate>,
    /// Whitening `1 / sigma_0`.
    scale: f64,
    /// Lowest `chi^2` evaluated: `(chi2, theta, J^T J)`.
    best: Option<(f64, Vec<f64>, Vec<f64>)>,
    /// Abandon above this `chi^2` after [`ABANDON_AFTER`] evaluations.
    beat: f64,
    evaluations: usize,
    abandoned: bool,
}

/// Levenberg-Marquardt iterations of the refit of a stage's best fit
/// that stopped short ([`Ctx::polished`]).
const POLISH_ITER: usize = 100;

/// Evaluations after which a refit that has not beaten its target is abandoned.
const ABANDON_AFTER: usize = 4;

impl Values<'_> {
    fn chain_at(&self, theta: &[f64]) -> Result<Chain> {
        let mut d = self.chain.defects().to_vec();
        for (&j, &v) in self.free.iter().zip(theta) {
            d[j] = DefectKind::of(&d[j]).defect(d[j].at(), v);
        }
        self.chain.uniform().with_defects(d)
    }
}

impl NormalEquations for Values<'_> {
    fn chi2(&mut self, theta: &[f64]) -> Result<f64> {
        let r = self.screen.residual(&self.chain_at(theta)?)?;
        Ok(r.iter().map(|v| v * v).sum::<f64>() * self.scale * self.scale)
    }

    fn normal(&mut self, theta: &[f64], g: &mut [f64], h: &mut [f64]) -> Result<f64> {
        if !self.abandoned
            && self.evaluations >= ABANDON_AFTER
            && self.best.as_ref().is_some_and(|b| b.0 > self.beat)
        {
            self.abandoned = true;
        }
        if self.abandoned {
            // every further trial is rejected without a simulation
            return Ok(f64::INFINITY);
        }
        self.evaluations += 1;
        let chain = self.chain_at(theta)?;
        let (x1, cols) = self
            .screen
            .each(&chain, &self.cands, false, |_, g| g.to_vec())?;
        let s = self.scale;
        let r: Vec<f64> = x1
            .iter()
            .zip(self.screen.y())
            .map(|(a, b)| (a - b) * s)
            .collect();
        let chi2: f64 = r.iter().map(|v| v * v).sum();
        let p = theta.len();
        for a in 0..p {
            g[a] = s * cols[a].iter().zip(&r).map(|(u, v)| u * v).sum::<f64>();
            for b in 0..=a {
                let v = s
                    * s
                    * cols[a]
                        .iter()
                        .zip(&cols[b])
                        .map(|(u, v)| u * v)
                        .sum::<f64>();
                h[a * p + b] = v;
                h[b * p + a] = v;
            }
        }
        if chi2.is_finite() && self.best.as_ref().is_none_or(|b| chi2 <= b.0) {
            self.best = Some((chi2, theta.to_vec(), h.to_vec()));
        }
        Ok(chi2)
    }

    fn pieces_are_cheap(&self) -> bool {
        true
    }
}
