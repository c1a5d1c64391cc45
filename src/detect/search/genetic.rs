//! Our genetic algorithm for mixed integer/real genomes, as an argmin [`Solver`].
//!
//! Genome: a [`Candidate`] (distinct positions, values in bounds), kept
//! canonical (positions ascending, each with its paired values). One
//! generation:
//!
//! 1. **elitism**: the `elites` best individuals pass unchanged;
//! 2. **selection**: tournaments of `tournament` individuals;
//! 3. **crossover** (rate `crossover_rate`), defect by defect: slot `p` of the
//!    child takes the defect (position *and* its paired values) of one parent
//!    at random; if that position is already used in the child, the other
//!    parent's, else a random free position with the chosen values. When both
//!    parents put slot `p` at the same position, its values are blended
//!    (BLX-0.25 in unit coordinates). Values tied to no position are blended
//!    the same way;
//! 4. **mutation**: each defect moves with probability `position_mutation`,
//!    by a random jump to a free position (fraction `jump_probability`) or to
//!    the next free neighbour left or right (its values move with it); each
//!    value moves with probability `value_mutation` by a Gaussian step in unit
//!    coordinates (log-aware) whose scale is drawn log-uniformly in
//!    `sigma_range` (multi-scale: coarse exploration and fine refinement in one
//!    operator), reflected into `[0, 1]`;
//! 5. optional **Lamarckian polish** (`polish`, on by default): the best
//!    `polish_top` distinct position sets of the generation that were never
//!    polished get their values fitted by Nelder-Mead
//!    ([`super::nelder_mead::polish`], at most `polish_evals` each) and
//!    replace their individual. The residual is a smooth function of the
//!    values for each position set, and the gap between the best and the
//!    second-best position set can be 1e-13 of its scale: random value
//!    mutation alone rarely resolves it.
//!
//! **Restarts**: when for `stall_generations` the best individual kept its
//! position set and its cost did not fall by a relative `stall_rel` (with
//! exact data the cost of the true position set keeps falling by orders of
//! magnitude towards the rounding floor; such refinements say nothing about
//! the positions, hence a large threshold), the population is re-drawn at random (an independent
//! restart; the best so far is kept by the tracker). The run stops when `patience` restarts in a row
//! brought no better position set, when the budget is spent or when the
//! target cost is reached.
//! Children are evaluated in one batch per generation, in parallel when
//! `parallel` (results recorded in order: same seed, same answer, whatever the
//! thread count). Parallel evaluation only pays when one cost takes more
//! than a few microseconds, hence off by default.

use super::nelder_mead::{polish, step_position, NelderMeadOptions};
use super::{argmin_err, Candidate, SearchOptions, Space, Tracked};
use crate::error::{Error, Result};
use argmin::core::{
    CostFunction, Executor, PopulationState, Problem, Solver, TerminationReason, TerminationStatus,
    KV,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use std::collections::HashSet;

/// Genetic-algorithm knobs.
///
/// Defaults: `population = 30`, `tournament = 3`, `crossover_rate = 0.9`,
/// `position_mutation = 0.3`, `jump_probability = 0.3`,
/// `value_mutation = 0.5`, `sigma_range = (1e-7, 0.3)`, `elites = 2`,
/// `stall_generations = 20`, `stall_rel = 0.99`, `patience = 2`, `polish = true`, `polish_top = 3`,
/// `polish_evals = 300`, `parallel = false`.
#[derive(Clone, Debug, PartialEq)]
pub struct GeneticOptions {
    /// Population size (>= 4).
    pub population: usize,
    /// Tournament size (>= 1; 1 = random selection).
    pub tournament: usize,
    /// Probability of crossover, in `[0, 1]`.
    pub crossover_rate: f64,
    /// Per-defect probability of a position move, in `[0, 1]`.
    pub position_mutation: f64,
    /// Fraction of position moves that are random jumps, in `[0, 1]`.
    pub jump_probability: f64,
    /// Per-value probability of a Gaussian step, in `[0, 1]`.
    pub value_mutation: f64,
    /// Range of the step's scale in unit coordinates, `0 < lo <= hi`.
    pub sigma_range: (f64, f64),
    /// Individuals copied unchanged (< population).
    pub elites: usize,
    /// Generations without improvement before a restart (>= 1).
    pub stall_generations: usize,
    /// Relative improvement of the best cost that resets the stall count (as a
    /// change of the best position set does), in `[0, 1)`.
    pub stall_rel: f64,
    /// Restarts in a row without a better position set before stopping (>= 1).
    pub patience: usize,
    /// Lamarckian Nelder-Mead polish of the best new position sets.
    pub polish: bool,
    /// Distinct position sets polished per generation.
    pub polish_top: usize,
    /// Evaluation cap of one polish.
    pub polish_evals: usize,
    /// Evaluate each generation with rayon.
    pub parallel: bool,
}

impl Default for GeneticOptions {
    fn default() -> Self {
        GeneticOptions {
            population: 30,
            tournament: 3,
            crossover_rate: 0.9,
            position_mutation: 0.3,
            jump_probability: 0.3,
            value_mutation: 0.5,
            sigma_range: (1e-7, 0.3),
            elites: 2,
            stall_generations: 20,
            stall_rel: 0.99,
            patience: 2,
            polish: true,
            polish_top: 3,
            polish_evals: 300,
            parallel: false,
        }
    }
}

impl GeneticOptions {
    /// # Errors
    /// [`Error::InvalidParameter`] naming the field.
    pub fn validate(&self) -> Result<()> {
        if self.population < 4 {
            return Err(Error::invalid(
                "genetic.population",
                self.population,
                ">= 4",
            ));
        }
        if self.tournament == 0 {
            return Err(Error::invalid("genetic.tournament", 0, ">= 1"));
        }
        for (f, v) in [
            ("genetic.crossover_rate", self.crossover_rate),
            ("genetic.position_mutation", self.position_mutation),
            ("genetic.jump_probability", self.jump_probability),
            ("genetic.value_mutation", self.value_mutation),
        ] {
            if !(0.0..=1.0).contains(&v) {
                return Err(Error::invalid(f, v, "in [0, 1]"));
            }
        }
        let (a, b) = self.sigma_range;
        if !(a > 0.0 && a <= b && b.is_finite()) {
            return Err(Error::invalid(
                "genetic.sigma_range",
                format!("({a}, {b})"),
                "0 < lo <= hi, finite",
            ));
        }
        if self.elites >= self.population {
            return Err(Error::invalid(
                "genetic.elites",
                self.elites,
                format!("< population = {}", self.population),
            ));
        }
        if self.stall_generations == 0 {
            return Err(Error::invalid("genetic.stall_generations", 0, ">= 1"));
        }
        if !(0.0..1.0).contains(&self.stall_rel) {
            return Err(Error::invalid(
                "genetic.stall_rel",
                self.stall_rel,
                "in [0, 1)",
            ));
        }
        if self.patience == 0 {
            return Err(Error::invalid("genetic.patience", 0, ">= 1"));
        }
        if self.polish && self.polish_evals == 0 {
            return Err(Error::invalid(
                "genetic.polish_evals",
                0,
                ">= 1 when polish",
            ));
        }
        Ok(())
    }
}

/// One member of the population.
#[derive(Clone, Debug, PartialEq)]
pub struct Individual {
    /// The genome (canonical).
    pub candidate: Candidate,
    /// Its cost.
    pub cost: f64,
}

/// The argmin problem of the GA: the tracked objective.
pub struct GaProblem<'t, 'a> {
    tracked: &'t Tracked<'a>,
}

impl CostFunction for GaProblem<'_, '_> {
    type Param = Candidate;
    type Output = f64;
    fn cost(&self, c: &Candidate) -> std::result::Result<f64, argmin::core::Error> {
        Ok(self.tracked.cost(c))
    }
}

/// The genetic algorithm as an argmin solver (see the module doc).
pub struct Genetic {
    opts: GeneticOptions,
    nm: NelderMeadOptions,
    space: Space,
    rng: ChaCha8Rng,
    polished: HashSet<Vec<usize>>,
    best: f64,
    best_positions: Option<Vec<usize>>,
    stalled: usize,
    incumbent: Option<(Vec<usize>, f64)>,
    idle_restarts: usize,
    finished: bool,
}

impl Genetic {
    /// A GA over `space`, seeded. Validate `opts` and `space` first
    /// ([`GeneticOptions::validate`], [`Space::validate`]).
    pub fn new(space: Space, opts: GeneticOptions, nm: NelderMeadOptions, seed: u64) -> Genetic {
        Genetic {
            opts,
            nm,
            space,
            rng: ChaCha8Rng::seed_from_u64(seed),
            polished: HashSet::new(),
            best: f64::INFINITY,
            best_positions: None,
            stalled: 0,
            incumbent: None,
            idle_restarts: 0,
            finished: false,
        }
    }

    fn tournament<'p>(&mut self, pop: &'p [Individual]) -> &'p Individual {
        let mut best = &pop[self.rng.random_range(0..pop.len())];
        for _ in 1..self.opts.tournament {
            let c = &pop[self.rng.random_range(0..pop.len())];
            if c.cost < best.cost {
                best = c;
            }
        }
        best
    }

    fn blend(&mut self, i: usize, a: f64, b: f64) -> f64 {
        let (ua, ub) = (self.space.to_unit(i, a), self.space.to_unit(i, b));
        let beta = -0.25 + 1.5 * self.rng.random::<f64>();
        self.space.from_unit(i, ua + beta * (ub - ua))
    }

    fn free_position(&mut self, taken: &[usize]) -> usize {
        let free: Vec<usize> = self
            .space
            .available()
            .into_iter()
            .filter(|j| !taken.contains(j))
            .collect();
        free[self.rng.random_range(0..free.len())]
    }

    fn crossover(&mut self, a: &Candidate, b: &Candidate) -> Candidate {
        let groups = self.space.groups();
        let mut child = a.clone();
        let mut taken: Vec<usize> = Vec::with_capacity(a.positions.len());
        for (p, g) in groups.iter().enumerate() {
            let from_b = self.rng.random_bool(0.5);
            let (src, alt) = if from_b { (b, a) } else { (a, b) };
            let pos = if !taken.contains(&src.positions[p]) {
                src.positions[p]
            } else if !taken.contains(&alt.positions[p]) {
                alt.positions[p]
            } else {
                self.free_position(&taken)
            };
            let donor = if pos == alt.positions[p] && pos != src.positions[p] {
                alt
            } else {
                src
            };
            for &i in g {
                child.values[i] = if a.positions[p] == b.positions[p] {
                    self.blend(i, a.values[i], b.values[i])
                } else {
                    donor.values[i]
                };
            }
            child.positions[p] = pos;
            taken.push(pos);
        }
        for i in self.space.free_values() {
            child.values[i] = self.blend(i, a.values[i], b.values[i]);
        }
        child
    }

    fn mutate(&mut self, c: &mut Candidate, force: bool) {
        let k = c.positions.len();
        let nv = c.values.len();
        let mut changed = false;
        for p in 0..k {
            if self.rng.random::<f64>() < self.opts.position_mutation {
                let new = if self.rng.random::<f64>() < self.opts.jump_probability {
                    Some(self.free_position(&c.positions))
                } else {
                    let dir = if self.rng.random_bool(0.5) { 1 } else { -1 };
                    step_position(&self.space, &c.positions, p, dir, 1)
                        .or_else(|| step_position(&self.space, &c.positions, p, -dir, 1))
                };
                if let Some(j) = new {
                    changed |= j != c.positions[p];
                    c.positions[p] = j;
                }
            }
        }
        for i in 0..nv {
            if self.rng.random::<f64>() < self.opts.value_mutation
                || (force && !changed && i + 1 == nv)
            {
                self.step_value(c, i);
                changed = true;
            }
        }
        if force && !changed && k > 0 {
            let p = self.rng.random_range(0..k);
            c.positions[p] = self.free_position(&c.positions);
        }
    }

    fn step_value(&mut self, c: &mut Candidate, i: usize) {
        let (lo, hi) = self.sigma_range_log();
        let sigma = 10f64.powf(lo + (hi - lo) * self.rng.random::<f64>());
        let z: f64 = StandardNormal.sample(&mut self.rng);
        let mut u = self.space.to_unit(i, c.values[i]) + sigma * z;
        if u < 0.0 {
            u = -u;
        }
        if u > 1.0 {
            u = 2.0 - u;
        }
        c.values[i] = self.space.from_unit(i, u);
    }

    fn sigma_range_log(&self) -> (f64, f64) {
        (
            self.opts.sigma_range.0.log10(),
            self.opts.sigma_range.1.log10(),
        )
    }

    fn evaluate(
        &self,
        problem: &mut Problem<GaProblem<'_, '_>>,
        cs: Vec<Candidate>,
    ) -> Result<Vec<Individual>> {
        let parallel = self.opts.parallel;
        let costs = problem
            .bulk_problem("cost_count", cs.len(), |o| {
                Ok(o.tracked.cost_batch(&cs, parallel))
            })
            .map_err(|e| argmin_err("genetic", e))?;
        Ok(cs
            .into_iter()
            .zip(costs)
            .map(|(candidate, cost)| Individual { candidate, cost })
            .collect())
    }

    /// Polish the best never-polished distinct position sets in `pop` (sorted).
    fn polish_top(
        &mut self,
        problem: &mut Problem<GaProblem<'_, '_>>,
        pop: &mut [Individual],
    ) -> Result<()> {
        if !self.opts.polish {
            return Ok(());
        }
        let mut seen: Vec<Vec<usize>> = Vec::new();
        for ind in pop.iter_mut() {
            if seen.len() >= self.opts.polish_top {
                break;
            }
            if seen.contains(&ind.candidate.positions) {
                continue;
            }
            seen.push(ind.candidate.positions.clone());
            if self.polished.contains(&ind.candidate.positions) {
                continue;
            }
            let nm = self.nm.clone();
            let cap = self.opts.polish_evals;
            let start = ind.candidate.clone();
            let out = problem
                .problem("polish_count", |o| {
                    let t = o.tracked;
                    if t.done() {
                        return Ok(None);
                    }
                    polish(t, &start, cap.min(t.remaining()), &nm)
                        .map(Some)
                        .map_err(to_argmin)
                })
                .map_err(|e| argmin_err("genetic", e))?;
            let Some((c, v)) = out else {
                return Ok(());
            };
            self.polished.insert(ind.candidate.positions.clone());
            if v < ind.cost {
                ind.candidate = c;
                ind.cost = v;
            }
        }
        Ok(())
    }
}

fn sort(pop: &mut [Individual]) {
    pop.sort_by(|a, b| a.cost.total_cmp(&b.cost));
}

type GaState = PopulationState<Individual, f64>;

impl<'t, 'a> Solver<GaProblem<'t, 'a>, GaState> for Genetic {
    fn name(&self) -> &str {
        "Genetic algorithm (mixed integer/real)"
    }

    fn init(
        &mut self,
        problem: &mut Problem<GaProblem<'t, 'a>>,
        state: GaState,
    ) -> std::result::Result<(GaState, Option<KV>), argmin::core::Error> {
        let cs: Vec<Candidate> = (0..self.opts.population)
            .map(|_| self.space.random_candidate(&mut self.rng))
            .collect();
        let mut pop = self.evaluate(problem, cs).map_err(to_argmin)?;
        sort(&mut pop);
        self.polish_top(problem, &mut pop).map_err(to_argmin)?;
        sort(&mut pop);
        self.best = pop[0].cost;
        let best = pop[0].clone();
        Ok((
            state
                .individual(best.clone())
                .cost(best.cost)
                .population(pop),
            None,
        ))
    }

    fn next_iter(
        &mut self,
        problem: &mut Problem<GaProblem<'t, 'a>>,
        mut state: GaState,
    ) -> std::result::Result<(GaState, Option<KV>), argmin::core::Error> {
        let pop = state.take_population().ok_or_else(|| {
            argmin::core::Error::msg("genetic: no population in state (potential bug)")
        })?;
        let n_children = self.opts.population - self.opts.elites;
        let mut children = Vec::with_capacity(n_children);
        while children.len() < n_children {
            let a = self.tournament(&pop).candidate.clone();
            let b = self.tournament(&pop).candidate.clone();
            let mut c = if self.rng.random::<f64>() < self.opts.crossover_rate {
                self.crossover(&a, &b)
            } else {
                a.clone()
            };
            let mut c2 = c.clone();
            self.mutate(&mut c2, false);
            c2 = self.space.canonicalize(&c2);
            if c2 == a || c2 == b {
                self.mutate(&mut c, true);
                c2 = self.space.canonicalize(&c);
            }
            children.push(c2);
        }
        let mut next: Vec<Individual> = pop[..self.opts.elites].to_vec();
        next.extend(self.evaluate(problem, children).map_err(to_argmin)?);
        sort(&mut next);
        self.polish_top(problem, &mut next).map_err(to_argmin)?;
        sort(&mut next);
        let moved = self.best_positions.as_ref() != Some(&next[0].candidate.positions);
        if moved || next[0].cost < self.best - self.opts.stall_rel * self.best.abs() {
            self.stalled = 0;
            self.best = next[0].cost;
            self.best_positions = Some(next[0].candidate.positions.clone());
        } else {
            self.stalled += 1;
        }
        if self.stalled >= self.opts.stall_generations {
            let b = &next[0];
            let better = match &self.incumbent {
                None => true,
                Some((pos, cost)) => b.candidate.positions != *pos && b.cost < *cost,
            };
            if better {
                self.incumbent = Some((b.candidate.positions.clone(), b.cost));
                self.idle_restarts = 0;
            } else {
                self.idle_restarts += 1;
            }
            if self.idle_restarts >= self.opts.patience {
                self.finished = true;
            } else {
                // independent restart: a fresh population (the incumbent is
                // kept by the tracker; elites would pull the new population
                // back into the old basin)
                let fresh: Vec<Candidate> = (0..self.opts.population)
                    .map(|_| self.space.random_candidate(&mut self.rng))
                    .collect();
                next = self.evaluate(problem, fresh).map_err(to_argmin)?;
                sort(&mut next);
                self.polish_top(problem, &mut next).map_err(to_argmin)?;
                sort(&mut next);
                self.best = next[0].cost;
                self.best_positions = Some(next[0].candidate.positions.clone());
                self.stalled = 0;
            }
        }
        let best = next[0].clone();
        let kv = argmin::kv!("stalled" => self.stalled as u64; "best_cost" => best.cost;);
        Ok((
            state
                .individual(best.clone())
                .cost(best.cost)
                .population(next),
            Some(kv),
        ))
    }

    fn terminate(&mut self, _state: &GaState) -> TerminationStatus {
        if self.finished {
            return TerminationStatus::Terminated(TerminationReason::SolverConverged);
        }
        TerminationStatus::NotTerminated
    }
}

fn to_argmin(e: Error) -> argmin::core::Error {
    argmin::core::Error::msg(e.to_string())
}

pub(crate) fn run(tracked: &Tracked<'_>, opts: &SearchOptions) -> Result<()> {
    let ga = Genetic::new(
        tracked.space().clone(),
        opts.genetic.clone(),
        opts.nelder_mead.clone(),
        opts.seed,
    );
    let stop_at = opts.max_evals;
    Executor::new(
        GaProblem { tracked },
        super::nelder_mead::Budgeted::new(ga, tracked, stop_at, None),
    )
    .configure(|s| s.max_iters(u64::MAX))
    .ctrlc(false)
    .run()
    .map_err(|e| argmin_err("genetic", e))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn space() -> Space {
        use crate::detect::search::TestValue::*;
        crate::detect::search::test_space(12, 6, &[Mass(0), Mass(1), Global])
    }

    /// A GA of default options on [`space`] with seed `seed`.
    fn genetic(seed: u64) -> Genetic {
        Genetic::new(
            space(),
            GeneticOptions::default(),
            NelderMeadOptions::default(),
            seed,
        )
    }

    #[test]
    fn crossover_keeps_each_value_with_its_position() {
        let s = space();
        let mut ga = genetic(5);
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        for _ in 0..500 {
            let a = s.random_candidate(&mut rng);
            let b = s.random_candidate(&mut rng);
            if a.positions.iter().any(|p| b.positions.contains(p)) {
                continue;
            }
            let c = s.canonicalize(&ga.crossover(&a, &b));
            assert!(s.contains(&c), "{c:?}");
            for (q, &pos) in c.positions.iter().enumerate() {
                let from = [&a, &b].into_iter().find_map(|par| {
                    par.positions
                        .iter()
                        .position(|&x| x == pos)
                        .map(|p| par.values[p])
                });
                assert_eq!(from, Some(c.values[q]), "{a:?} x {b:?} -> {c:?}");
            }
        }
    }

    #[test]
    fn mutation_and_crossover_stay_in_space() {
        let s = space();
        let mut ga = genetic(1);
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let mut moved = 0;
        for _ in 0..2000 {
            let a = s.random_candidate(&mut rng);
            let b = s.random_candidate(&mut rng);
            let mut c = ga.crossover(&a, &b);
            let before = c.clone();
            ga.mutate(&mut c, true);
            assert!(s.contains(&c), "{c:?}");
            assert_ne!(c, before, "forced mutation changed nothing");
            moved += (c.positions != before.positions) as usize;
        }
        assert!(moved > 200, "positions moved only {moved} times");
    }

    #[test]
    fn options_validate() {
        GeneticOptions::default().validate().unwrap();
        let bad = crate::detect::search::spoiled::<GeneticOptions>(&[
            |o| o.population = 3,
            |o| o.elites = 40,
            |o| o.crossover_rate = 1.5,
            |o| o.sigma_range = (0.0, 0.1),
            |o| o.patience = 0,
            |o| o.stall_rel = 1.0,
        ]);
        for o in bad {
            assert!(
                matches!(o.validate(), Err(Error::InvalidParameter { .. })),
                "{o:?}"
            );
        }
    }
}
