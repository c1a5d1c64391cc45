//! Greedy search with moves: many defects in long chains without
//! enumerating position sets.
//!
//! Enumeration fits `C(n, k)` position sets (34 220 for `n = 60`, `k = 3`);
//! this search fits `O(k (k + passes) refit)` of them and scores the rest by
//! a rank-one formula, so that `n = 10^4` is a matter of seconds.
//!
//! # Algorithm
//!
//! 1. **Add.** From the current fit (at first the chain with its known
//!    defects and any defect of known position), every candidate `(kind,
//!    position)` is scored by the exact rank-one update of `X_1`
//!    ([`crate::detect::search::rankone`]): its own value fitted (grid, then
//!    Gauss-Newton), the other values held. The `refit` best candidates are
//!    added in turn and *all* values (and the fitted chain parameters) refitted
//!    by the bounded Levenberg-Marquardt ([`crate::detect::search::lsq`],
//!    analytic Jacobian by reciprocity); the best refit is kept. Repeat until
//!    `k` defects are placed.
//! 2. **Move.** For each placed defect in turn, take it out (the others keep
//!    their values), score every candidate against the rest, and refit the
//!    `refit` best (other than where it was); accept the best refit if it
//!    lowers the chi-square. A move can change the kind as well as the
//!    position (so it covers swaps of kind). Passes repeat until none helps
//!    (at most `max_passes`).
//! 3. **Restart.** The same from each of the `restarts` runners-up of the
//!    first step (candidates at least two positions from the earlier starts);
//!    the best result wins.
//!
//! Every fit on the way is kept: the ranked list holds the answer and its
//! one-move neighbours (the sets a final pass tried), which is what the
//! report's runner-up gap and identifiability need.
//!
//! **Sampled records.** With a time-domain misfit on a record of the
//! paper's measurement (impulse on mass 1, displacement of mass 1, uniform
//! sampling) and no fitted chain parameter, the same add-and-move search
//! runs on the record itself instead ([`TimeStage`], module `time`):
//! candidates are scored by their linearised chi-square drop from one
//! simulation of the current fit (sensitivities by reciprocity,
//! [`crate::detect::misfit::time_screen`]) and values refitted on the
//! record. Deep defects of a long, lightly damped chain fall below the
//! noise on the Bromwich line while their echoes stand well above it in the
//! record (the `--noisy` case of `cargo bench --bench greedy`: all four
//! positions right in 20 of 20 draws at `n = 300`, a few seconds each).
//! Otherwise (another measurement, fitted chain parameters, a non-uniform
//! record) the Bromwich-line search runs and its `setup.shortlist` best are
//! refitted in the time domain and re-ranked, as
//! [`fit_general`](crate::detect::fit::general::fit_general) does.
//!
//! # Cost and determinism
//!
//! Scoring is `O(n Q)` (the sweep) plus `O(n_candidates Q (grid + iterations))`,
//! `Q` the Laplace nodes; memory `O(n Q)`, never an `n x n` matrix. Scoring
//! and refits run in parallel (rayon); candidates are ranked by
//! `(chi2, position, kind)` and refits by `(chi2, hypothesis)`, so the result
//! does not depend on the thread count.
//!
//! ```
//! use springmass::{Chain, Complex64, Defect};
//! use springmass::detect::data::laplace::LaplaceObs;
//! use springmass::detect::fit::general::Setup;
//! use springmass::detect::fit::greedy::{fit_greedy, GreedyOptions};
//! use springmass::detect::unknowns::{Unknowns, KindChoice};
//! let truth = Chain::paper(40)?.with_defects([
//!     Defect::Mass { at: 6, m: 3.0 }, Defect::Mass { at: 19, m: 0.5 }, Defect::Mass { at: 31, m: 2.0 }])?;
//! let s: Vec<Complex64> = (0..80).map(|q| Complex64::new(0.05, 0.05 * q as f64)).collect();
//! let obs = LaplaceObs::exact(&truth, s, vec![1.0; 80])?;
//! let unknowns = Unknowns::free(40, &[KindChoice::Mass; 3], &[])?;
//! let fit = fit_greedy(&truth.uniform(), &unknowns, &obs, None, &Setup::new()?, &GreedyOptions::default())?;
//! assert_eq!(fit.ranked[0].positions(), vec![6, 19, 31]);
//! assert!(fit.ranked[0].matches(&truth, 1e-6));
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::chain::{Chain, Defect};
use crate::detect::data::laplace::LaplaceObs;
use crate::detect::fit::chainfit::{default_bounds, ChainProblem};
use crate::detect::fit::general::{param_name, Hypothesis, Setup};
use crate::detect::misfit::time::TimeMisfit;
use crate::detect::model::MeasurementModel;
use crate::detect::search::lsq::{levenberg_marquardt, LmFit, LmOptions};
use crate::detect::search::rankone::{
    score, ScoreOptions, Scored, SetDefect, SetProblem, Sweep, Target,
};
use crate::detect::unknowns::{DefectKind, KindChoice, KindPositions, Unknowns};
use crate::error::{Error, Result};
use crate::sensitivity::Param;

mod time;
pub use time::TimeStage;

/// The work of a search, counted across its threads: hypotheses refitted,
/// misfit evaluations, candidates scored, sweeps.
#[derive(Debug, Default)]
struct Counters(std::sync::Mutex<(usize, usize, usize, usize)>);

impl Counters {
    fn add(&self, hyps: usize, evals: usize, scored: usize, sweeps: usize) {
        let mut c = self.0.lock().unwrap_or_else(|e| e.into_inner());
        c.0 += hyps;
        c.1 += evals;
        c.2 += scored;
        c.3 += sweeps;
    }

    fn get(&self) -> (usize, usize, usize, usize) {
        *self.0.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn set(&self, to: (usize, usize, usize, usize)) {
        *self.0.lock().unwrap_or_else(|e| e.into_inner()) = to;
    }
}

/// Options of [`fit_greedy`].
#[derive(Clone, Debug, PartialEq)]
pub struct GreedyOptions {
    /// Best-scored candidates refitted (all values) at each step and move (default 3).
    pub refit: usize,
    /// Restarts from the first step's runners-up (default 2).
    pub restarts: usize,
    /// Most passes of moves per path (default 20).
    pub max_passes: usize,
    /// Levenberg-Marquardt iterations per refit (default 100).
    pub max_iter: usize,
    /// Candidate scoring: value grid and Gauss-Newton polish (bounds are the slots').
    pub score: ScoreOptions,
    /// Score and refit in parallel (rayon); the result does not depend on it (default true).
    pub parallel: bool,
    /// The time-record stage, used instead of the Bromwich line's when the
    /// fit has a sampled record ([module docs](self)).
    pub time: TimeStage,
}

impl Default for GreedyOptions {
    fn default() -> Self {
        GreedyOptions {
            refit: 3,
            restarts: 2,
            max_passes: 20,
            max_iter: 100,
            score: ScoreOptions::default(),
            parallel: true,
            time: TimeStage::default(),
        }
    }
}

impl GreedyOptions {
    /// Check the options.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming `greedy.refit` (0), `greedy.max_iter`
    /// (0), `greedy.grid` (below 2).
    pub fn validate(&self) -> Result<()> {
        if self.refit == 0 {
            return Err(Error::invalid("greedy.refit", 0, ">= 1"));
        }
        if self.max_iter == 0 {
            return Err(Error::invalid("greedy.max_iter", 0, ">= 1"));
        }
        if self.score.grid < 2 {
            return Err(Error::invalid("greedy.grid", self.score.grid, ">= 2"));
        }
        if self.time.refit == 0 {
            return Err(Error::invalid("greedy.time.refit", 0, ">= 1"));
        }
        if self.time.max_iter == 0 {
            return Err(Error::invalid("greedy.time.max_iter", 0, ">= 1"));
        }
        if !(self.time.move_ratio >= 0.0 && self.time.move_ratio.is_finite()) {
            return Err(Error::invalid(
                "greedy.time.move_ratio",
                self.time.move_ratio,
                ">= 0 and finite",
            ));
        }
        Ok(())
    }
}

/// The result of [`fit_greedy`].
#[derive(Clone, Debug, PartialEq)]
pub struct GreedyFit {
    /// Every hypothesis refitted on the way (distinct), best first: the answer
    /// and its one-move neighbours.
    pub ranked: Vec<Hypothesis>,
    /// Position sets refitted by Levenberg-Marquardt.
    pub hypotheses: usize,
    /// Residual evaluations of the full model (Levenberg-Marquardt).
    pub evaluations: usize,
    /// Rank-one candidate evaluations (each O(Q)).
    pub scored: usize,
    /// Candidate sweeps (each O(n Q)).
    pub sweeps: usize,
    /// Number of residuals of the final misfit.
    pub residuals: usize,
    /// Chi-square at the end of each path (the first from the best first
    /// candidate, then the restarts).
    pub paths: Vec<f64>,
}

/// One refitted hypothesis.
#[derive(Clone, Debug)]
struct Fit {
    /// `(kind, position)` of every slot, in slot order.
    pairs: KindPositions,
    /// The fitted chain (defects in slot order).
    chain: Chain,
    hyp: Hypothesis,
    m: usize,
}

impl Fit {
    fn key(&self) -> KindPositions {
        let mut k = self.pairs.clone();
        k.sort_unstable_by_key(|&(kind, at)| (at, kind));
        k
    }
}

struct Greedy<'a> {
    base: Chain,
    unknowns: &'a Unknowns,
    obs: &'a LaplaceObs,
    target: Target,
    opts: &'a GreedyOptions,
    /// Indices of the slots placed by the search.
    free: Vec<usize>,
    kinds: Vec<DefectKind>,
    score_opts: ScoreOptions,
    chain_bounds: Vec<(f64, f64)>,
    counters: Counters,
}

/// Greedy search with moves and restarts (module docs) for the defects of
/// `unknowns` on `base` (its uniform part; the slots' known defects are
/// added), fitted to `coarse`; with `fine`, the `setup.shortlist` best are
/// refitted in the time domain and re-ranked.
///
/// Slots with a known position are always present (their values fitted);
/// the slots of unknown position must share one kind choice (they are
/// placed one at a time, interchangeably).
///
/// # Errors
/// `unknowns.n` differing from the chain's; slots of unknown position with
/// different kinds or bounds (field `kinds`); bad options
/// ([`GreedyOptions::validate`]); fewer candidate positions than defects
/// (field `defects`); no hypothesis could be fitted.
pub fn fit_greedy(
    base: &Chain,
    unknowns: &Unknowns,
    coarse: &LaplaceObs,
    fine: Option<&TimeMisfit>,
    setup: &Setup,
    opts: &GreedyOptions,
) -> Result<GreedyFit> {
    opts.validate()?;
    if unknowns.n() != base.n() {
        return Err(Error::invalid(
            "unknowns.n",
            unknowns.n(),
            format!("the chain's n = {}", base.n()),
        ));
    }
    let slots = unknowns.slots();
    let free: Vec<usize> = (0..slots.len())
        .filter(|&i| slots[i].at.is_none())
        .collect();
    let choice = free.first().map(|&i| slots[i].kind);
    if free
        .iter()
        .any(|&i| Some(slots[i].kind) != choice || slots[i].bounds != slots[free[0]].bounds)
    {
        return Err(Error::invalid(
            "kinds",
            "different kinds or bounds per defect",
            "one kind choice and one range for every defect of unknown position (greedy places them interchangeably)",
        ));
    }
    let kinds: Vec<DefectKind> = choice.unwrap_or(KindChoice::Mass).kinds().to_vec();
    let mut kb = *unknowns.kind_bounds();
    if let Some(&i) = free.first() {
        for kind in DefectKind::ALL {
            kb.set(kind, unknowns.bounds(i, kind));
        }
    }
    let g = Greedy {
        base: base.uniform(),
        unknowns,
        obs: coarse,
        target: Target::new(coarse),
        opts,
        free,
        kinds,
        score_opts: ScoreOptions {
            bounds: kb,
            ..opts.score.clone()
        },
        chain_bounds: default_bounds(base, unknowns.chain()),
        counters: Counters::default(),
    };
    g.run(fine, setup)
}

impl Greedy<'_> {
    fn count(&self, hyps: usize, evals: usize, scored: usize, sweeps: usize) {
        self.counters.add(hyps, evals, scored, sweeps);
    }

    fn map<T: Sync, U: Send>(&self, items: &[T], f: impl Fn(&T) -> U + Sync + Send) -> Vec<U> {
        crate::detect::search::parallel::map(items, self.opts.parallel, 2, f)
    }

    /// The starting value of a defect of `kind` (the coarse start of the
    /// enumeration: twice the uniform mass or spring, a heavier damper).
    fn start_value(&self, kind: DefectKind, chain: &Chain) -> f64 {
        kind.start(chain)
    }

    /// Refit the values of the hypothesis `pairs` (slot order: the known and
    /// fixed-position slots, then as many free slots as placed, `slot_of`
    /// their slot indices) from `values`, chain parameters from `start`, on
    /// `obs`. The placed defects are put in canonical order (position, kind).
    /// Without chain parameters, given the `kernel` of the Laplace values
    /// `obs` holds, the values are fitted on that gathered Woodbury kernel
    /// ([`SetProblem`], O(Q) per evaluation whatever `n`), otherwise on the chain's own residuals ([`ChainProblem`]).
    fn refit(
        &self,
        pairs: &KindPositions,
        slot_of: &[usize],
        values: &[f64],
        start: &Chain,
        obs: &dyn MeasurementModel,
        kernel: Option<&Target>,
    ) -> Result<Fit> {
        let (pairs, values) = self.canonical(pairs, slot_of, values);
        let p = self.values_problem(&pairs, slot_of, &values, start)?;
        let chain = start.uniform().with_defects(p.defects)?;
        if p.params.is_empty() {
            let r = obs.residuals(&chain)?;
            self.count(1, 1, 0, 0);
            let m = r.len();
            return Ok(Fit {
                pairs,
                hyp: Hypothesis::from_parts(
                    chain.defects().to_vec(),
                    vec![0.0; values.len()],
                    Vec::new(),
                    r.iter().map(|v| v * v).sum(),
                ),
                chain,
                m,
            });
        }
        let lm_opts = LmOptions {
            max_iter: self.opts.max_iter,
            ..LmOptions::default()
        };
        // the gathered Woodbury kernel of the Laplace values `kernel` was built from
        let fast = kernel.filter(|_| self.unknowns.chain().is_empty());
        let (lm, fitted) = if let Some(target) = fast {
            let problem = SetProblem::new(&chain, &p.set, target)?;
            let lm = levenberg_marquardt(&problem, &p.theta0, &p.bounds, &lm_opts)?;
            let mut d = chain.defects().to_vec();
            for (param, &v) in p.params.iter().zip(&lm.theta) {
                if let Param::Defect(i) = param {
                    d[*i] = pairs[*i].0.defect(pairs[*i].1, v);
                }
            }
            let fitted = chain.uniform().with_defects(d)?;
            (lm, fitted)
        } else {
            let problem = ChainProblem::new(&chain, &p.params, obs)?;
            let lm = levenberg_marquardt(&problem, &p.theta0, &p.bounds, &lm_opts)?;
            let fitted = problem.chain(&lm.theta)?;
            (lm, fitted)
        };
        self.count(1, lm.evaluations, 0, 0);
        Ok(fit_of(pairs, &p.params, &lm, fitted))
    }

    /// The values problem of the canonical hypothesis `pairs` with `values`
    /// (clamped into their bounds; known slots held), chain parameters from
    /// `start`.
    fn values_problem(
        &self,
        pairs: &KindPositions,
        slot_of: &[usize],
        values: &[f64],
        start: &Chain,
    ) -> Result<ValuesProblem> {
        let slots = self.unknowns.slots();
        let mut p = ValuesProblem {
            defects: Vec::with_capacity(pairs.len()),
            set: Vec::with_capacity(pairs.len()),
            params: Vec::new(),
            theta0: Vec::new(),
            bounds: Vec::new(),
        };
        for (j, (&(kind, at), &v)) in pairs.iter().zip(values).enumerate() {
            let slot = &slots[slot_of[j]];
            match slot.known {
                Some(known) => {
                    p.defects.push(kind.defect(at, known));
                    p.set.push(SetDefect::Fixed(kind, at, known));
                }
                None => {
                    let b = self.unknowns.bounds(slot_of[j], kind);
                    let v = v.clamp(b.0, b.1);
                    p.defects.push(kind.defect(at, v));
                    p.set.push(SetDefect::Free(kind, at, p.theta0.len()));
                    p.params.push(Param::Defect(j));
                    p.theta0.push(v);
                    p.bounds.push(b);
                }
            }
        }
        for (param, b) in self.unknowns.chain().iter().zip(&self.chain_bounds) {
            p.params.push(*param);
            p.theta0.push(param.get(start)?.clamp(b.0, b.1));
            p.bounds.push(*b);
        }
        Ok(p)
    }

    /// Slot indices of a hypothesis with the fixed slots and `placed` free ones.
    fn slot_of(&self, placed: usize) -> Vec<usize> {
        let slots = self.unknowns.slots();
        let mut v: Vec<usize> = (0..slots.len())
            .filter(|&i| slots[i].at.is_some())
            .collect();
        v.extend(self.free.iter().take(placed));
        v
    }

    /// The placed defects of `pairs` (after the fixed slots of `slot_of`)
    /// in canonical order (position, kind), `values` along.
    fn canonical(
        &self,
        pairs: &KindPositions,
        slot_of: &[usize],
        values: &[f64],
    ) -> (KindPositions, Vec<f64>) {
        let slots = self.unknowns.slots();
        let n_fixed = slot_of.iter().filter(|&&i| slots[i].at.is_some()).count();
        let mut order: Vec<(DefectKind, usize, f64)> = pairs[n_fixed..]
            .iter()
            .zip(&values[n_fixed..])
            .map(|(&(k, a), &v)| (k, a, v))
            .collect();
        order.sort_by_key(|&(k, a, _)| (a, k));
        let pairs: KindPositions = pairs[..n_fixed]
            .iter()
            .copied()
            .chain(order.iter().map(|&(k, a, _)| (k, a)))
            .collect();
        let values: Vec<f64> = values[..n_fixed]
            .iter()
            .copied()
            .chain(order.iter().map(|o| o.2))
            .collect();
        (pairs, values)
    }

    /// The known and fixed-position slots: their pairs and starting values.
    fn start_pairs(&self) -> (KindPositions, Vec<f64>) {
        let slots = self.unknowns.slots();
        let mut pairs = Vec::new();
        let mut values = Vec::new();
        for i in self.slot_of(0) {
            let at = slots[i].at.expect("fixed slots have a position");
            let kind = *slots[i]
                .kind
                .kinds()
                .iter()
                .find(|k| k.positions(self.base.n()).contains(&at))
                .unwrap_or(&slots[i].kind.kinds()[0]);
            pairs.push((kind, at));
            values.push(slots[i].known.unwrap_or(self.start_value(kind, &self.base)));
        }
        (pairs, values)
    }

    /// The start: known and fixed-position slots, fitted (with the chain parameters).
    fn start(&self) -> Result<Fit> {
        let (pairs, values) = self.start_pairs();
        self.refit(
            &pairs,
            &self.slot_of(0),
            &values,
            &self.base,
            self.obs,
            Some(&self.target),
        )
    }

    /// Score every candidate against `chain`, excluding the pairs present.
    fn scored(&self, chain: &Chain, present: &KindPositions) -> Result<Vec<Scored>> {
        let sweep = Sweep::new(chain, self.target.nodes(), &self.kinds)?;
        let s = score(
            &sweep,
            &self.target,
            present,
            &self.score_opts,
            self.opts.parallel,
        );
        self.count(0, 0, s.iter().map(|c| c.evaluations).sum(), 1);
        Ok(s)
    }

    /// Refit `cur` plus each candidate (values: `cur`'s, then the candidate's).
    fn extend(&self, cur: &Fit, cands: &[Scored]) -> Vec<Fit> {
        let placed = cur.pairs.len() - self.slot_of(0).len() + 1;
        let slot_of = self.slot_of(placed);
        let fits = self.map(cands, |c| {
            let mut pairs = cur.pairs.clone();
            pairs.push((c.kind, c.at));
            let mut values: Vec<f64> = cur.chain.defects().iter().map(|d| d.value()).collect();
            values.push(c.value);
            self.refit(
                &pairs,
                &slot_of,
                &values,
                &cur.chain,
                self.obs,
                Some(&self.target),
            )
            .ok()
        });
        fits.into_iter().flatten().collect()
    }

    fn best_of(fits: Vec<Fit>) -> Option<Fit> {
        fits.into_iter().min_by(|a, b| {
            a.hyp
                .chi2
                .total_cmp(&b.hyp.chi2)
                .then_with(|| a.key().cmp(&b.key()))
        })
    }

    /// One path: add to `k` defects (the first forced to `first` if given),
    /// then moves. Every refit is pushed to `seen`.
    fn path(
        &self,
        start: &Fit,
        first: Option<&Scored>,
        step0: &[Scored],
        seen: &mut Vec<Fit>,
    ) -> Result<Fit> {
        let n_fixed = start.pairs.len();
        let mut cur = start.clone();
        for step in 0..self.free.len() {
            let cands: Vec<Scored> = match (step, first) {
                (0, Some(f)) => vec![*f],
                (0, None) => step0.iter().take(self.opts.refit).copied().collect(),
                _ => {
                    let s = self.scored(&cur.chain, &cur.pairs)?;
                    s.into_iter().take(self.opts.refit).collect()
                }
            };
            if cands.is_empty() {
                return Err(Error::invalid(
                    "defects",
                    self.free.len(),
                    "at most the number of candidate positions",
                ));
            }
            let fits = self.extend(&cur, &cands);
            seen.extend(fits.iter().cloned());
            cur = Self::best_of(fits).ok_or_else(|| Error::Numerical {
                method: "greedy".into(),
                reason: format!("no candidate for defect {} could be fitted", step + 1),
            })?;
        }
        // moves
        for _ in 0..self.opts.max_passes {
            let mut improved = false;
            for p in n_fixed..cur.pairs.len() {
                let (kind, at) = cur.pairs[p];
                // the rest, at their fitted values
                let mut rest = cur.clone();
                rest.pairs.remove(p);
                rest.chain = cur.chain.without_defect(p);
                let s = self.scored(&rest.chain, &rest.pairs)?;
                let cands: Vec<Scored> = s
                    .into_iter()
                    .filter(|c| (c.kind, c.at) != (kind, at))
                    .take(self.opts.refit)
                    .collect();
                let fits = self.extend(&rest, &cands);
                seen.extend(fits.iter().cloned());
                if let Some(b) = Self::best_of(fits) {
                    if b.hyp.chi2 < cur.hyp.chi2 * (1.0 - 1e-9) {
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

    fn run(&self, fine: Option<&TimeMisfit>, setup: &Setup) -> Result<GreedyFit> {
        if let Some(t) = fine {
            if let Some(f) = time::run(self, t)? {
                return Ok(f);
            }
        }
        let start = self.start()?;
        let mut seen: Vec<Fit> = vec![start.clone()];
        let paths = self.explore(&start, &mut seen)?;
        // distinct hypotheses, best first, the full set only
        let k_total = start.pairs.len() + self.free.len();
        seen.retain(|f| f.pairs.len() == k_total);
        seen.sort_by(|a, b| {
            a.key()
                .cmp(&b.key())
                .then_with(|| a.hyp.chi2.total_cmp(&b.hyp.chi2))
        });
        seen.dedup_by(|a, b| a.key() == b.key());
        sort_ranked(&mut seen);
        if seen.is_empty() {
            return Err(Error::Numerical {
                method: "greedy".into(),
                reason: "no hypothesis could be fitted".into(),
            });
        }
        if let Some(t) = fine {
            seen = self.time_refits(&seen, t, setup)?;
        }
        let residuals = seen[0].m;
        let (hypotheses, evaluations, scored, sweeps) = self.counters.get();
        Ok(GreedyFit {
            ranked: seen.into_iter().map(|f| f.hyp).collect(),
            hypotheses,
            evaluations,
            scored,
            sweeps,
            residuals,
            paths,
        })
    }

    /// The greedy path from `start`, then restarts from the runners-up of
    /// its first step (away from earlier starts); every fit seen is added
    /// to `seen`. Returns each path's best chi-square.
    fn explore(&self, start: &Fit, seen: &mut Vec<Fit>) -> Result<Vec<f64>> {
        let mut paths = Vec::new();
        if self.free.is_empty() {
            return Ok(paths);
        }
        let step0 = self.scored(&start.chain, &start.pairs)?;
        let best = self.path(start, None, &step0, seen)?;
        paths.push(best.hyp.chi2);
        let mut starts: Vec<(DefectKind, usize)> = vec![best.pairs[start.pairs.len()]];
        for c in &step0 {
            if starts.len() > self.opts.restarts {
                break;
            }
            if starts
                .iter()
                .any(|&(k, a)| k == c.kind && a.abs_diff(c.at) < 2)
            {
                continue;
            }
            starts.push((c.kind, c.at));
            let f = self.path(start, Some(c), &step0, seen)?;
            paths.push(f.hyp.chi2);
        }
        Ok(paths)
    }

    /// The best `setup.shortlist` of `seen` refitted on the time-domain
    /// chi-square from their values, ranked by it.
    fn time_refits(&self, seen: &[Fit], t: &TimeMisfit, setup: &Setup) -> Result<Vec<Fit>> {
        let short: Vec<Fit> = seen.iter().take(setup.shortlist.max(1)).cloned().collect();
        let slot_of = self.slot_of(self.free.len());
        let refits: Vec<Option<Fit>> = self.map(&short, |f| {
            let values: Vec<f64> = f.chain.defects().iter().map(|d| d.value()).collect();
            self.refit(&f.pairs, &slot_of, &values, &f.chain, t, None)
                .ok()
        });
        let mut timed: Vec<Fit> = refits.into_iter().flatten().collect();
        if timed.is_empty() {
            return Err(Error::Numerical {
                method: "greedy".into(),
                reason: "no hypothesis could be refitted in the time domain".into(),
            });
        }
        sort_ranked(&mut timed);
        Ok(timed)
    }
}

/// Best chi-square first, ties broken by the hypothesis.
fn sort_ranked(fits: &mut [Fit]) {
    fits.sort_by(|a, b| {
        a.hyp
            .chi2
            .total_cmp(&b.hyp.chi2)
            .then_with(|| a.key().cmp(&b.key()))
    });
}

/// The least-squares problem of one greedy hypothesis: its defects at their
/// starting values, the rank-one set description, and the free parameters
/// (defect values, then chain parameters) with starts and bounds.
struct ValuesProblem {
    defects: Vec<Defect>,
    set: Vec<SetDefect>,
    params: Vec<Param>,
    theta0: Vec<f64>,
    bounds: Vec<(f64, f64)>,
}

/// The [`Fit`] of `pairs` from a converged values problem over `params`.
fn fit_of(pairs: KindPositions, params: &[Param], lm: &LmFit, fitted: Chain) -> Fit {
    let hyp = Hypothesis::from_fit(params, lm, &fitted, pairs.len(), |p| {
        param_name(p).to_string()
    });
    Fit {
        pairs,
        hyp: Hypothesis {
            converged: true,
            ..hyp
        },
        chain: fitted,
        m: lm.m,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::detect::unknowns::Slot;
    use num_complex::Complex64;

    fn nodes(q: usize, sigma: f64, w: f64) -> Vec<Complex64> {
        (0..q)
            .map(|i| Complex64::new(sigma, w * (i as f64 + 0.5) / q as f64))
            .collect()
    }

    #[test]
    fn recovers_three_masses_thread_independent() {
        let truth = crate::scenes::paper_with(30, "mass:4:0.4 mass:13:3.0 mass:25:1.8").unwrap();
        let s = nodes(60, 0.05, 4.0);
        let obs = LaplaceObs::exact(&truth, s, vec![1.0; 60]).unwrap();
        let u = Unknowns::free(30, &[KindChoice::Mass; 3], &[]).unwrap();
        let setup = Setup::new().unwrap();
        let a = fit_greedy(
            &truth.uniform(),
            &u,
            &obs,
            None,
            &setup,
            &GreedyOptions::default(),
        )
        .unwrap();
        let b = fit_greedy(
            &truth.uniform(),
            &u,
            &obs,
            None,
            &setup,
            &GreedyOptions {
                parallel: false,
                ..GreedyOptions::default()
            },
        )
        .unwrap();
        assert_eq!(a, b);
        assert!(a.ranked[0].matches(&truth, 1e-6), "{:?}", a.ranked[0]);
        assert!(a.ranked.len() > 3 && a.ranked[1].chi2 > 1e6 * a.ranked[0].chi2.max(1e-30));
        assert!(a.hypotheses < 200, "{}", a.hypotheses);
    }

    #[test]
    fn any_kind_with_a_known_defect_and_fitted_damping() {
        let truth = crate::scenes::three_kinds(15, [2, 6, 11])
            .unwrap()
            .with_d(0.12)
            .unwrap();
        let s = nodes(60, 0.05, 4.0);
        let obs = LaplaceObs::exact(&truth, s, vec![1.0; 60]).unwrap();
        let u = Unknowns::new(
            15,
            vec![
                Slot {
                    kind: KindChoice::Mass,
                    at: Some(2),
                    known: Some(2.0),
                    bounds: None,
                },
                Slot::free(KindChoice::Any),
                Slot::free(KindChoice::Any),
            ],
            vec![Param::D],
            crate::detect::unknowns::KindBounds::default(),
        )
        .unwrap();
        let start = Chain::paper(15).unwrap().with_d(0.1).unwrap();
        let f = fit_greedy(
            &start,
            &u,
            &obs,
            None,
            &Setup::new().unwrap(),
            &GreedyOptions::default(),
        )
        .unwrap();
        let best = &f.ranked[0];
        assert!(best.positions_match(&truth), "{best:?}");
        assert!(best.matches(&truth, 1e-5), "{best:?}");
        assert!((best.param("d").unwrap().value - 0.12).abs() < 1e-6);
        assert_eq!(best.std_errors[0], 0.0);
    }

    /// A sampled record: `(coarse, fine)` for `fit_greedy` (the coarse
    /// Laplace values are not used by the time stage).
    fn record(truth: &Chain, t_end: f64, seed: u64) -> (LaplaceObs, TimeMisfit) {
        use crate::detect::data::series::TimeData;
        use crate::noise::NoiseLevel;
        let data =
            TimeData::simulate(truth, t_end, 0.25, NoiseLevel::RelativeMax(1e-3), seed).unwrap();
        let s = nodes(20, 0.05, 4.0);
        let coarse = LaplaceObs::exact(truth, s, vec![1.0; 20]).unwrap();
        (coarse, TimeMisfit::new(data))
    }

    #[test]
    fn time_stage_finds_masses_alike_with_threads_and_memo() {
        let truth = crate::scenes::paper_with(40, "mass:7:2.5 mass:31:0.6")
            .unwrap()
            .with_d(0.02)
            .unwrap();
        let (coarse, fine) = record(&truth, 120.0, 1);
        let u = Unknowns::free(40, &[KindChoice::Mass; 2], &[]).unwrap();
        let setup = Setup::new().unwrap();
        let run = |parallel: bool, memo: bool| {
            fit_greedy(
                &truth.uniform(),
                &u,
                &coarse,
                Some(&fine),
                &setup,
                &GreedyOptions {
                    parallel,
                    time: TimeStage {
                        memo,
                        ..TimeStage::default()
                    },
                    ..GreedyOptions::default()
                },
            )
            .unwrap()
        };
        let a = run(true, false);
        assert_eq!(a.ranked[0].positions(), vec![7, 31], "{:?}", a.ranked[0]);
        for (d, t) in a.ranked[0].defects.iter().zip(truth.defects()) {
            assert!((d.value() / t.value() - 1.0).abs() < 0.01, "{d:?}");
        }
        assert_eq!(a.residuals, fine.data().len());
        assert!(a.ranked.len() > 1 && a.ranked[1].chi2 > a.ranked[0].chi2);
        // at the truth the chi-square is about the number of samples
        let n = fine.data().len() as f64;
        assert!(a.ranked[0].chi2 < 1.2 * n, "{}", a.ranked[0].chi2);
        assert!(a.ranked[0].std_errors.iter().all(|s| *s > 0.0 && *s < 0.01));
        assert_eq!(a, run(false, false));
        // the memo: k = 1 first, then k = 2 from its stages
        let one = Unknowns::free(40, &[KindChoice::Mass], &[]).unwrap();
        let opts = GreedyOptions::default();
        let f1 = fit_greedy(&truth.uniform(), &one, &coarse, Some(&fine), &setup, &opts).unwrap();
        assert_eq!(f1.ranked[0].positions(), vec![7]);
        assert_eq!(a, run(true, true));
        assert_eq!(a, run(false, true));
    }

    #[test]
    fn time_stage_any_kind_with_a_known_defect() {
        let truth = crate::scenes::three_kinds(24, [3, 9, 17])
            .unwrap()
            .with_d(0.02)
            .unwrap();
        let (coarse, fine) = record(&truth, 100.0, 2);
        let u = Unknowns::new(
            24,
            vec![
                Slot {
                    kind: KindChoice::Mass,
                    at: Some(3),
                    known: None,
                    bounds: None,
                },
                Slot::free(KindChoice::Any),
                Slot::free(KindChoice::Any),
            ],
            vec![],
            crate::detect::unknowns::KindBounds::default(),
        )
        .unwrap();
        let f = fit_greedy(
            &truth.uniform(),
            &u,
            &coarse,
            Some(&fine),
            &Setup::new().unwrap(),
            &GreedyOptions::default(),
        )
        .unwrap();
        let best = &f.ranked[0];
        assert!(best.positions_match(&truth), "{best:?}");
        assert!(best.matches(&truth, 0.05), "{best:?}");
    }

    #[test]
    fn typed_errors() {
        let c = Chain::paper(6).unwrap();
        let s = nodes(10, 0.1, 2.0);
        let obs = LaplaceObs::exact(&c, s, vec![1.0; 10]).unwrap();
        let setup = Setup::new().unwrap();
        let mixed = Unknowns::free(6, &[KindChoice::Mass, KindChoice::Spring], &[]).unwrap();
        let e = fit_greedy(&c, &mixed, &obs, None, &setup, &GreedyOptions::default()).unwrap_err();
        assert!(e.to_string().contains("kinds"), "{e}");
        let u = Unknowns::free(6, &[KindChoice::Mass], &[]).unwrap();
        let e = fit_greedy(
            &c,
            &u,
            &obs,
            None,
            &setup,
            &GreedyOptions {
                refit: 0,
                ..GreedyOptions::default()
            },
        )
        .unwrap_err();
        assert!(e.to_string().contains("greedy.refit"), "{e}");
        let e = fit_greedy(
            &Chain::paper(7).unwrap(),
            &u,
            &obs,
            None,
            &setup,
            &GreedyOptions::default(),
        )
        .unwrap_err();
        assert!(e.to_string().contains("unknowns.n"), "{e}");
    }
}
