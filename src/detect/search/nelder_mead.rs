//! argmin's Nelder-Mead on the real values, with the integer positions
//! handled outside the simplex.
//!
//! ## Treatment of the positions (default: [`Positions::LocalSearch`])
//!
//! Nelder-Mead is a local method for continuous functions; a rounded position
//! makes the cost piecewise constant along that axis, which stalls the simplex
//! (its moves shrink inside one plateau). So by default the positions are
//! **fixed per run** and searched by an outer discrete loop:
//!
//! 1. draw distinct random positions and random values (seeded);
//! 2. fit the values with Nelder-Mead at those positions ([`polish`]);
//! 3. descent over positions: try the moves of one defect to the next free
//!    position up to `neighbourhood` steps left or right, refit the values
//!    from the current ones (warm start), take the first move that lowers the
//!    cost (or the best move, `first_improvement = false`); repeat until no
//!    move helps;
//! 4. restart from 1 until `patience` consecutive restarts end at an already
//!    known or worse position set, or the budget is spent.
//!
//! Fitted position sets are memoised for the whole run ([`FitMemo`]): a
//! restart that walks into known territory costs almost nothing, which is
//! what makes the restarts (and so the robustness) cheap.
//!
//! This follows the structure of the residual (a smooth function of the
//! masses for every position set) and needs no rounding heuristics; its
//! weakness is the same as the data's: when two position sets differ by less
//! than the value fits' accuracy, the descent can stop at the wrong one.
//!
//! [`Positions::RelaxRound`] is the textbook alternative, kept for
//! comparison: the simplex moves over relaxed positions `x in [0.5, n + 0.5]`
//! and unit values together, the cost is evaluated at the rounded, repaired
//! positions ([`Space::round_positions`]), restarted from random points until
//! the budget is spent.
//!
//! Values move in unit coordinates; a vertex outside `[0, 1]` is evaluated at
//! its projection plus the squared distance (so the simplex is pushed back
//! and no value ever leaves its bounds).

use super::{argmin_err, finite_cost, Candidate, SearchOptions, Space, Tracked};
use crate::error::{Error, Result};
use argmin::core::{
    CostFunction, Executor, Problem, Solver, State, TerminationReason, TerminationStatus, KV,
};
use argmin::solver::neldermead::NelderMead;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::collections::HashMap;

/// How Nelder-Mead treats the integer positions (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Positions {
    /// Positions fixed per run, discrete descent over them, restarts.
    LocalSearch,
    /// Relaxed positions in the simplex, rounded for each evaluation; restarts.
    RelaxRound,
}

/// Nelder-Mead knobs.
///
/// Defaults: `positions = LocalSearch`, `step = 0.15` (initial simplex edge
/// in unit coordinates), `sd_rel = 1e-3`, `sd_tolerance = 1e-30`,
/// `min_progress = 1e-4`, `rounds = 40`, `max_iters_per_fit = 400`,
/// `neighbourhood = 1`, `patience = 3`, `first_improvement = true`.
///
/// One value fit ([`polish`]) is a sequence of Nelder-Mead *rounds*: each
/// round stops when the standard deviation of the vertex costs falls below
/// `max(sd_rel * c, sd_tolerance)`, with `c` the best cost at the round's
/// start; the next round restarts the simplex at the best vertex with an edge
/// of twice the last round's move. The fit stops when a round lowers the cost
/// by less than a relative `min_progress`. The tolerance is therefore
/// relative (scale-free): a fit at a wrong position set stops on its plateau
/// after a few rounds, a fit at the true one keeps converging towards the
/// rounding floor, which is what separates position sets whose residuals
/// differ by 1e-13. Restarting also cures Nelder-Mead's degenerate simplices.
#[derive(Clone, Debug, PartialEq)]
pub struct NelderMeadOptions {
    /// Treatment of the positions.
    pub positions: Positions,
    /// Initial simplex edge in unit coordinates, in `(0, 1]`.
    pub step: f64,
    /// Stop one fit when the vertex costs' standard deviation is below this.
    pub sd_tolerance: f64,
    /// A round stops when the vertex costs' standard deviation is below `sd_rel` times its start cost.
    pub sd_rel: f64,
    /// A fit stops when a round improves the cost by less than this (relative).
    pub min_progress: f64,
    /// Cap on rounds per fit.
    pub rounds: usize,
    /// Cap on Nelder-Mead iterations per fit.
    pub max_iters_per_fit: usize,
    /// Largest position move (in free positions) tried by the local search.
    pub neighbourhood: usize,
    /// Restarts in a row without a better position set before stopping.
    pub patience: usize,
    /// Take the first improving position move instead of the best one.
    pub first_improvement: bool,
}

impl Default for NelderMeadOptions {
    fn default() -> Self {
        NelderMeadOptions {
            positions: Positions::LocalSearch,
            step: 0.15,
            sd_tolerance: 1e-30,
            sd_rel: 1e-3,
            min_progress: 1e-4,
            rounds: 40,
            max_iters_per_fit: 400,
            neighbourhood: 1,
            patience: 3,
            first_improvement: true,
        }
    }
}

impl NelderMeadOptions {
    /// # Errors
    /// [`Error::InvalidParameter`] naming the field.
    pub fn validate(&self) -> Result<()> {
        if !(self.step > 0.0 && self.step <= 1.0) {
            return Err(Error::invalid("nelder_mead.step", self.step, "in (0, 1]"));
        }
        for (f, v) in [
            ("nelder_mead.sd_tolerance", self.sd_tolerance),
            ("nelder_mead.sd_rel", self.sd_rel),
        ] {
            if !(v >= 0.0 && v.is_finite()) {
                return Err(Error::invalid(f, v, ">= 0 and finite"));
            }
        }
        if !(self.min_progress >= 0.0 && self.min_progress < 1.0) {
            return Err(Error::invalid(
                "nelder_mead.min_progress",
                self.min_progress,
                "in [0, 1)",
            ));
        }
        at_least_one(&[
            ("nelder_mead.rounds", self.rounds),
            ("nelder_mead.max_iters_per_fit", self.max_iters_per_fit),
            ("nelder_mead.neighbourhood", self.neighbourhood),
            ("nelder_mead.patience", self.patience),
        ])
    }
}

/// The first of the `(field, count)` that is 0, as an error (`>= 1`).
///
/// # Errors
/// [`Error::InvalidParameter`] naming that field.
pub(crate) fn at_least_one(counts: &[(&str, usize)]) -> Result<()> {
    match counts.iter().find(|c| c.1 == 0) {
        Some(&(field, _)) => Err(Error::invalid(field, 0, ">= 1")),
        None => Ok(()),
    }
}

/// Wraps an argmin solver with our budget (and an optional stall test on the
/// best cost), so every method stops on the shared evaluation count.
pub(crate) struct Budgeted<'t, 'a, S> {
    pub inner: S,
    pub tracked: &'t Tracked<'a>,
    /// Stop when the tracked evaluation count reaches this.
    pub stop_at: usize,
    /// Stop after `stall.0` iterations without a relative improvement of `stall.1`.
    pub stall: Option<(usize, f64)>,
    last_best: f64,
    stalled: usize,
}

impl<'t, 'a, S> Budgeted<'t, 'a, S> {
    pub fn new(
        inner: S,
        tracked: &'t Tracked<'a>,
        stop_at: usize,
        stall: Option<(usize, f64)>,
    ) -> Self {
        Budgeted {
            inner,
            tracked,
            stop_at,
            stall,
            last_best: f64::INFINITY,
            stalled: 0,
        }
    }
}

impl<O, I: State<Float = f64>, S: Solver<O, I>> Solver<O, I> for Budgeted<'_, '_, S> {
    fn name(&self) -> &str {
        self.inner.name()
    }
    fn init(
        &mut self,
        problem: &mut Problem<O>,
        state: I,
    ) -> std::result::Result<(I, Option<KV>), argmin::core::Error> {
        self.inner.init(problem, state)
    }
    fn next_iter(
        &mut self,
        problem: &mut Problem<O>,
        state: I,
    ) -> std::result::Result<(I, Option<KV>), argmin::core::Error> {
        self.inner.next_iter(problem, state)
    }
    fn terminate(&mut self, state: &I) -> TerminationStatus {
        let s = self.inner.terminate(state);
        if s.terminated() {
            return s;
        }
        if self.tracked.evaluations() >= self.stop_at || self.tracked.done() {
            return TerminationStatus::Terminated(TerminationReason::SolverExit(
                "evaluation budget spent".into(),
            ));
        }
        if let Some((limit, rel)) = self.stall {
            let b = state.get_best_cost();
            if b < self.last_best - rel * self.last_best.abs() {
                self.last_best = b;
                self.stalled = 0;
            } else {
                self.stalled += 1;
                if self.stalled >= limit {
                    return TerminationStatus::Terminated(TerminationReason::SolverConverged);
                }
            }
        }
        TerminationStatus::NotTerminated
    }
}

/// Values of `space` at unit coordinates `u`, each projected onto `[0, 1]`;
/// adds the squared distance of each projection to `out` (in order).
fn unit_values(space: &Space, u: &[f64], out: &mut f64) -> Vec<f64> {
    u.iter()
        .enumerate()
        .map(|(i, &ui)| {
            let p = ui.clamp(0.0, 1.0);
            *out += (ui - p).powi(2);
            space.from_unit(i, p)
        })
        .collect()
}

/// Cost of unit values at fixed positions (projection + squared distance).
struct ValueFit<'t, 'a> {
    tracked: &'t Tracked<'a>,
    positions: Vec<usize>,
}

impl ValueFit<'_, '_> {
    fn candidate(&self, u: &[f64]) -> (Candidate, f64) {
        let space = self.tracked.space();
        let mut out = 0.0;
        let values = unit_values(space, u, &mut out);
        (
            Candidate {
                positions: self.positions.clone(),
                values,
            },
            out,
        )
    }
}

impl CostFunction for ValueFit<'_, '_> {
    type Param = Vec<f64>;
    type Output = f64;
    fn cost(&self, u: &Vec<f64>) -> std::result::Result<f64, argmin::core::Error> {
        let (c, out) = self.candidate(u);
        Ok(finite_cost(self.tracked.cost(&c) + out))
    }
}

/// Initial simplex around `x0` (unit coordinates): `x0` and `x0 +- step e_i`,
/// the sign chosen to stay inside `[0, 1]`.
fn simplex(x0: &[f64], step: f64) -> Vec<Vec<f64>> {
    let mut s = vec![x0.to_vec()];
    for i in 0..x0.len() {
        let mut v = x0.to_vec();
        v[i] = if x0[i] + step <= 1.0 {
            x0[i] + step
        } else {
            x0[i] - step
        };
        s.push(v);
    }
    s
}

/// Fit the values of `start` with Nelder-Mead, positions fixed; at most about
/// `max_evals` evaluations (checked per iteration) and
/// `opts.max_iters_per_fit` iterations. Returns the best candidate of the fit
/// and its cost (never worse than `start`'s, which is evaluated first).
///
/// A space without values costs one evaluation.
///
/// # Errors
/// [`Error::Numerical`] if argmin fails.
pub fn polish(
    tracked: &Tracked<'_>,
    start: &Candidate,
    max_evals: usize,
    opts: &NelderMeadOptions,
) -> Result<(Candidate, f64)> {
    let space = tracked.space();
    let nv = space.n_values();
    let c0 = tracked.cost(start);
    if nv == 0 {
        return Ok((start.clone(), c0));
    }
    let x0: Vec<f64> = (0..nv)
        .map(|i| space.to_unit(i, start.values[i]).clamp(0.0, 1.0))
        .collect();
    let stop_at = tracked.evaluations() + max_evals;
    let (mut x, mut cost) = (x0, c0);
    let mut step = opts.step;
    for _ in 0..opts.rounds {
        if tracked.evaluations() >= stop_at || tracked.done() {
            break;
        }
        let problem = ValueFit {
            tracked,
            positions: start.positions.clone(),
        };
        let tol = (opts.sd_rel * cost).max(opts.sd_tolerance);
        let nm = NelderMead::new(simplex(&x, step))
            .with_sd_tolerance(tol)
            .map_err(|e| argmin_err("nelder-mead", e))?;
        let res = Executor::new(problem, Budgeted::new(nm, tracked, stop_at, None))
            .configure(|s| s.max_iters(opts.max_iters_per_fit as u64))
            .ctrlc(false)
            .run()
            .map_err(|e| argmin_err("nelder-mead", e))?;
        let st = res.state();
        let (Some(u), c) = (st.get_best_param(), st.get_best_cost()) else {
            break;
        };
        if c >= cost {
            break;
        }
        let moved = u
            .iter()
            .zip(&x)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        let progress = (cost - c) / cost.abs().max(f64::MIN_POSITIVE);
        x = u.clone();
        cost = c;
        step = (2.0 * moved).clamp(1e-9, opts.step);
        if progress < opts.min_progress {
            break;
        }
    }
    let fit = ValueFit {
        tracked,
        positions: start.positions.clone(),
    };
    if cost < c0 {
        Ok((fit.candidate(&x).0, cost))
    } else {
        Ok((start.clone(), c0))
    }
}

/// The free position reached from `positions[p]` by `steps` moves in
/// direction `dir` (skipping excluded and taken positions), if any.
pub fn step_position(
    space: &Space,
    positions: &[usize],
    p: usize,
    dir: isize,
    steps: usize,
) -> Option<usize> {
    let mut j = positions[p] as isize;
    let mut moved = 0;
    loop {
        j += dir;
        if j < 1 || j > space.n as isize {
            return None;
        }
        let ju = j as usize;
        if space.excluded.contains(&ju) || positions.contains(&ju) {
            continue;
        }
        moved += 1;
        if moved == steps {
            return Some(ju);
        }
    }
}

/// Fitted position sets of one run: positions -> (fitted candidate, cost).
/// The objective is deterministic, so a set fitted once need not be refitted
/// when a later descent (or restart) comes back to it.
pub type FitMemo = HashMap<Vec<usize>, (Candidate, f64)>;

/// Discrete descent over positions from `start`, refitting the
/// values at every trial (see the module doc). Returns the local optimum.
///
/// # Errors
/// [`Error::Numerical`] if argmin fails.
pub fn local_search(
    tracked: &Tracked<'_>,
    start: &Candidate,
    opts: &NelderMeadOptions,
) -> Result<(Candidate, f64)> {
    local_search_memo(tracked, start, opts, &mut FitMemo::new())
}

/// [`local_search`] sharing the fits of earlier descents through `memo`.
///
/// # Errors
/// [`Error::Numerical`] if argmin fails.
pub fn local_search_memo(
    tracked: &Tracked<'_>,
    start: &Candidate,
    opts: &NelderMeadOptions,
    memo: &mut FitMemo,
) -> Result<(Candidate, f64)> {
    let space = tracked.space().clone();
    let mut fit = |c: &Candidate| -> Result<(Candidate, f64)> {
        if let Some(hit) = memo.get(&c.positions) {
            return Ok(hit.clone());
        }
        let out = polish(tracked, c, tracked.remaining().max(1), opts)?;
        memo.insert(c.positions.clone(), out.clone());
        Ok(out)
    };
    let (mut cur, mut cur_cost) = fit(&space.canonicalize(start))?;
    while !tracked.done() {
        let mut best: Option<(Candidate, f64)> = None;
        'moves: for p in 0..space.n_positions {
            for dir in [-1isize, 1] {
                for steps in 1..=opts.neighbourhood {
                    let Some(j) = step_position(&space, &cur.positions, p, dir, steps) else {
                        break;
                    };
                    let mut trial = cur.clone();
                    trial.positions[p] = j;
                    let trial = space.canonicalize(&trial);
                    let (c, v) = fit(&trial)?;
                    if best.as_ref().is_none_or(|(_, b)| v < *b) {
                        best = Some((c, v));
                    }
                    if tracked.done() || (opts.first_improvement && v < cur_cost) {
                        break 'moves;
                    }
                }
            }
        }
        match best {
            Some((c, v)) if v < cur_cost => {
                cur = c;
                cur_cost = v;
            }
            _ => break,
        }
    }
    Ok((cur, cur_cost))
}

/// Relaxed problem: `[x_1..x_k, u_1..u_m]` -> rounded candidate.
struct Relaxed<'t, 'a> {
    tracked: &'t Tracked<'a>,
}

impl Relaxed<'_, '_> {
    fn candidate(&self, z: &[f64]) -> (Candidate, f64) {
        let space = self.tracked.space();
        let k = space.n_positions;
        let positions = space.round_positions(&z[..k]);
        let mut out = 0.0;
        for &x in &z[..k] {
            let p = x.clamp(0.5, space.n as f64 + 0.5);
            out += ((x - p) / space.n as f64).powi(2);
        }
        let values = unit_values(space, &z[k..], &mut out);
        (Candidate { positions, values }, out)
    }
}

impl CostFunction for Relaxed<'_, '_> {
    type Param = Vec<f64>;
    type Output = f64;
    fn cost(&self, z: &Vec<f64>) -> std::result::Result<f64, argmin::core::Error> {
        let (c, out) = self.candidate(z);
        Ok(finite_cost(self.tracked.cost(&c) + out))
    }
}

/// A random relaxed point: positions uniform in `[0.5, n + 0.5]`, values in `[0, 1]`.
pub(crate) fn random_relaxed(space: &Space, rng: &mut ChaCha8Rng) -> Vec<f64> {
    use rand::Rng;
    let mut z: Vec<f64> = (0..space.n_positions)
        .map(|_| 0.5 + rng.random::<f64>() * space.n as f64)
        .collect();
    z.extend((0..space.n_values()).map(|_| rng.random::<f64>()));
    z
}

pub(crate) fn run(tracked: &Tracked<'_>, opts: &SearchOptions) -> Result<()> {
    let o = &opts.nelder_mead;
    let space = tracked.space().clone();
    let mut rng = ChaCha8Rng::seed_from_u64(opts.seed);
    match o.positions {
        Positions::LocalSearch => {
            let mut incumbent: Option<(Vec<usize>, f64)> = None;
            let mut idle = 0;
            let mut memo = FitMemo::new();
            while !tracked.done() && idle < o.patience {
                let start = space.random_candidate(&mut rng);
                let (c, v) = local_search_memo(tracked, &start, o, &mut memo)?;
                let better = match &incumbent {
                    None => true,
                    Some((pos, best)) => c.positions != *pos && v < *best,
                };
                if better {
                    incumbent = Some((c.positions.clone(), v));
                    idle = 0;
                } else {
                    if let Some((pos, best)) = incumbent.as_mut() {
                        if c.positions == *pos && v < *best {
                            *best = v;
                        }
                    }
                    idle += 1;
                }
            }
        }
        Positions::RelaxRound => {
            let scale: Vec<f64> = (0..space.n_positions)
                .map(|_| space.n as f64)
                .chain((0..space.n_values()).map(|_| 1.0))
                .collect();
            while !tracked.done() {
                let z0 = random_relaxed(&space, &mut rng);
                let mut s = vec![z0.clone()];
                for i in 0..z0.len() {
                    let mut v = z0.clone();
                    let st = o.step * scale[i];
                    v[i] = if z0[i] + st
                        <= if i < space.n_positions {
                            space.n as f64 + 0.5
                        } else {
                            1.0
                        } {
                        z0[i] + st
                    } else {
                        z0[i] - st
                    };
                    s.push(v);
                }
                let nm = NelderMead::new(s)
                    .with_sd_tolerance(o.sd_tolerance)
                    .map_err(|e| argmin_err("nelder-mead", e))?;
                let stop_at = tracked.evaluations() + tracked.remaining();
                Executor::new(
                    Relaxed { tracked },
                    Budgeted::new(nm, tracked, stop_at, None),
                )
                .configure(|s| s.max_iters(10 * o.max_iters_per_fit as u64))
                .ctrlc(false)
                .run()
                .map_err(|e| argmin_err("nelder-mead", e))?;
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::search::Objective;

    struct Bowl(Space);
    impl Objective for Bowl {
        fn space(&self) -> &Space {
            &self.0
        }
        fn cost(&self, c: &Candidate) -> f64 {
            // minimum 0 at positions {4, 9}, values (3, 0.2)
            let p = (c.positions[0] as f64 - 4.0).abs() + (c.positions[1] as f64 - 9.0).abs();
            p + (c.values[0] / 3.0).ln().powi(2) + 10.0 * (c.values[1] / 0.2).ln().powi(2)
        }
    }

    #[test]
    fn polish_converges_far_below_the_start_at_fixed_positions() {
        let bowl = Bowl(Space::masses(12, 2, (0.1, 20.0)));
        let t = Tracked::new(&bowl, &SearchOptions::default());
        let start = Candidate {
            positions: vec![4, 9],
            values: vec![10.0, 10.0],
        };
        let (c, v) = polish(&t, &start, 5000, &NelderMeadOptions::default()).unwrap();
        assert_eq!(c.positions, vec![4, 9]);
        assert!(v < 1e-20, "{v:e} at {c:?}");
        assert!((c.values[0] - 3.0).abs() < 1e-8 && (c.values[1] - 0.2).abs() < 1e-9);
        // at a wrong position set, the fit stops on the plateau (cost 1) quickly
        let before = t.evaluations();
        let start = Candidate {
            positions: vec![5, 9],
            values: vec![10.0, 10.0],
        };
        let (_, v) = polish(&t, &start, 5000, &NelderMeadOptions::default()).unwrap();
        assert!((v - 1.0).abs() < 1e-3);
        assert!(
            t.evaluations() - before < 1000,
            "{}",
            t.evaluations() - before
        );
    }

    #[test]
    fn local_search_walks_to_the_optimum() {
        let bowl = Bowl(Space::masses(12, 2, (0.1, 20.0)));
        let t = Tracked::new(
            &bowl,
            &SearchOptions {
                max_evals: 100_000,
                ..Default::default()
            },
        );
        let start = Candidate {
            positions: vec![1, 12],
            values: vec![1.0, 1.0],
        };
        let (c, v) = local_search(&t, &start, &NelderMeadOptions::default()).unwrap();
        assert_eq!(c.positions, vec![4, 9]);
        assert!(v < 1e-12);
    }

    #[test]
    fn step_position_skips_taken_and_excluded() {
        let mut s = Space::masses(8, 2, (0.1, 20.0));
        s.excluded = vec![4];
        assert_eq!(step_position(&s, &[3, 5], 0, 1, 1), Some(6));
        assert_eq!(step_position(&s, &[3, 5], 0, 1, 2), Some(7));
        assert_eq!(step_position(&s, &[3, 5], 0, -1, 1), Some(2));
        assert_eq!(step_position(&s, &[1, 5], 0, -1, 1), None);
        assert_eq!(step_position(&s, &[3, 8], 1, 1, 1), None);
    }
}
