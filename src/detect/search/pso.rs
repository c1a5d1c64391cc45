//! argmin's particle swarm with relax-and-round positions.
//!
//! ## Treatment of the positions: relax and round
//!
//! A particle is `[x_1..x_k, u_1..u_m]`: relaxed positions in
//! `[0.5, n + 0.5]` and values in unit coordinates `[0, 1]` (log-scaled
//! values are uniform in `ln v`). Each evaluation rounds the positions to
//! distinct free integers ([`Space::round_positions`](super::Space::round_positions): nearest integer,
//! collisions and excluded positions moved to the nearest free one).
//!
//! Why this and not positions fixed per run: a swarm is a global, population
//! method whose strength is sampling many position sets at once; fixing
//! positions per run would turn it into an expensive inner value fit. The
//! rounding makes the cost piecewise constant in `x`, which a swarm tolerates
//! (its moves are stochastic, not gradient-like), unlike Nelder-Mead.
//!
//! ## Finish (default [`Finish::LocalSearch`])
//!
//! A swarm converges on the values slowly once the positions settle (its
//! steps shrink only as fast as the velocities damp), so the run ends, if
//! asked, with Nelder-Mead on the values at the best positions
//! ([`Finish::Polish`]) or with the discrete neighbour search of
//! [`super::nelder_mead::local_search`] ([`Finish::LocalSearch`]).
//!
//! ## Episodes
//!
//! A swarm stops after `stall_iters` sweeps without improvement (or at
//! `swarm_share` of the budget); its finish follows; then a new swarm, seeded
//! from `(seed, episode)`, starts. The run stops when `patience` episodes in a
//! row brought no better position set, or the budget is spent.
//!
//! Seeding: `ParticleSwarm::with_rng_generator(ChaCha8Rng::seed_from_u64(seed))`
//! (argmin's default seeds itself from the OS, which would not be reproducible).

use super::nelder_mead::{local_search_memo, polish, Budgeted, FitMemo};
use super::{argmin_err, finite_cost, Candidate, SearchOptions, Tracked};
use crate::error::{Error, Result};
use argmin::core::State;
use argmin::core::{CostFunction, Executor};
use argmin::solver::particleswarm::ParticleSwarm;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// What runs after the swarm.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Finish {
    /// Nothing: the swarm's best is the answer.
    None,
    /// Nelder-Mead on the values at the swarm's best positions.
    Polish,
    /// Nelder-Mead value fits plus the discrete neighbour search on positions.
    LocalSearch,
}

/// Particle-swarm knobs.
///
/// Defaults: `particles = 40`; argmin's factors (inertia `1/(2 ln 2)`,
/// cognitive and social `0.5 + ln 2`); `stall_iters = 30` (stop the swarm
/// after that many sweeps without a relative improvement of 1e-12);
/// `finish = LocalSearch`; `swarm_share = 0.7`; `patience = 2`; `parallel = false`.
#[derive(Clone, Debug, PartialEq)]
pub struct PsoOptions {
    /// Swarm size (>= 2).
    pub particles: usize,
    /// Inertia factor (>= 0).
    pub inertia: f64,
    /// Cognitive factor (>= 0).
    pub cognitive: f64,
    /// Social factor (>= 0).
    pub social: f64,
    /// Sweeps without improvement before the swarm stops.
    pub stall_iters: usize,
    /// What runs after the swarm.
    pub finish: Finish,
    /// Cap on one swarm's evaluations, as a fraction of the budget, in `(0, 1]`
    /// (1 when `finish = None`).
    pub swarm_share: f64,
    /// Episodes in a row without a better position set before stopping (>= 1).
    pub patience: usize,
    /// Evaluate each sweep with rayon (deterministic; pays only for costly objectives).
    pub parallel: bool,
}

impl Default for PsoOptions {
    fn default() -> Self {
        PsoOptions {
            particles: 40,
            inertia: 1.0 / (2.0 * 2f64.ln()),
            cognitive: 0.5 + 2f64.ln(),
            social: 0.5 + 2f64.ln(),
            stall_iters: 30,
            finish: Finish::LocalSearch,
            swarm_share: 0.7,
            patience: 2,
            parallel: false,
        }
    }
}

impl PsoOptions {
    /// # Errors
    /// [`Error::InvalidParameter`] naming the field.
    pub fn validate(&self) -> Result<()> {
        if self.particles < 2 {
            return Err(Error::invalid("pso.particles", self.particles, ">= 2"));
        }
        for (f, v) in [
            ("pso.inertia", self.inertia),
            ("pso.cognitive", self.cognitive),
            ("pso.social", self.social),
        ] {
            if !(v >= 0.0 && v.is_finite()) {
                return Err(Error::invalid(f, v, ">= 0 and finite"));
            }
        }
        super::nelder_mead::at_least_one(&[
            ("pso.stall_iters", self.stall_iters),
            ("pso.patience", self.patience),
        ])?;
        if !(self.swarm_share > 0.0 && self.swarm_share <= 1.0) {
            return Err(Error::invalid(
                "pso.swarm_share",
                self.swarm_share,
                "in (0, 1]",
            ));
        }
        Ok(())
    }
}

/// Relaxed particle -> rounded candidate.
struct Swarmed<'t, 'a> {
    tracked: &'t Tracked<'a>,
    parallel: bool,
}

impl Swarmed<'_, '_> {
    fn candidate(&self, z: &[f64]) -> Candidate {
        let space = self.tracked.space();
        let k = space.n_positions;
        Candidate {
            positions: space.round_positions(&z[..k]),
            values: z[k..]
                .iter()
                .enumerate()
                .map(|(i, &u)| space.from_unit(i, u))
                .collect(),
        }
    }
}

impl CostFunction for Swarmed<'_, '_> {
    type Param = Vec<f64>;
    type Output = f64;
    fn cost(&self, z: &Vec<f64>) -> std::result::Result<f64, argmin::core::Error> {
        Ok(finite_cost(self.tracked.cost(&self.candidate(z))))
    }

    /// One swarm sweep as one batch: evaluated in parallel when asked,
    /// recorded in particle order (deterministic whatever the thread count,
    /// and whether or not argmin's own `rayon` feature is enabled).
    fn bulk_cost<P>(&self, params: &[P]) -> std::result::Result<Vec<f64>, argmin::core::Error>
    where
        P: std::borrow::Borrow<Vec<f64>> + argmin::core::SyncAlias,
        f64: argmin::core::SendAlias,
        Self: argmin::core::SyncAlias,
    {
        let cands: Vec<Candidate> = params.iter().map(|p| self.candidate(p.borrow())).collect();
        Ok(self.tracked.cost_batch(&cands, self.parallel))
    }
}

pub(crate) fn run(tracked: &Tracked<'_>, opts: &SearchOptions) -> Result<()> {
    let o = &opts.pso;
    let space = tracked.space().clone();
    let k = space.n_positions;
    let dim = k + space.n_values();
    if dim == 0 {
        tracked.cost(&Candidate {
            positions: vec![],
            values: vec![],
        });
        return Ok(());
    }
    let mut lo = vec![0.5; k];
    let mut hi = vec![space.n as f64 + 0.5 - 1e-9; k];
    lo.extend(std::iter::repeat_n(0.0, space.n_values()));
    hi.extend(std::iter::repeat_n(1.0, space.n_values()));
    let share = if o.finish == Finish::None {
        1.0
    } else {
        o.swarm_share
    };
    let swarm_cap = (((opts.max_evals as f64) * share).ceil() as usize).max(1);
    let mut incumbent: Option<(Vec<usize>, f64)> = None;
    let mut idle = 0;
    let mut episode: u64 = 0;
    let mut memo = FitMemo::new();
    while !tracked.done() && idle < o.patience {
        let stop_at = tracked.evaluations() + swarm_cap.min(tracked.remaining());
        let Some((best, cost)) = swarm_episode(tracked, opts, (&lo, &hi), stop_at, episode)? else {
            break;
        };
        let mut out = (best.clone(), cost);
        if !tracked.done() {
            match o.finish {
                Finish::None => {}
                Finish::Polish => {
                    out = polish(tracked, &best, tracked.remaining(), &opts.nelder_mead)?;
                }
                Finish::LocalSearch => {
                    out = local_search_memo(tracked, &best, &opts.nelder_mead, &mut memo)?;
                }
            }
        }
        let better = match &incumbent {
            None => true,
            Some((pos, c)) => out.0.positions != *pos && out.1 < *c,
        };
        if better {
            incumbent = Some((out.0.positions.clone(), out.1));
            idle = 0;
        } else {
            idle += 1;
        }
        episode += 1;
    }
    Ok(())
}

/// One swarm episode (seeded by `episode`) in the box `(lo, hi)` until
/// `stop_at` evaluations: its best candidate (canonical) and cost, `None`
/// when it has none.
fn swarm_episode(
    tracked: &Tracked<'_>,
    opts: &SearchOptions,
    (lo, hi): (&[f64], &[f64]),
    stop_at: usize,
    episode: u64,
) -> Result<Option<(Candidate, f64)>> {
    let o = &opts.pso;
    let rng = ChaCha8Rng::seed_from_u64(episode_seed(opts.seed, episode));
    let pso = ParticleSwarm::new((lo.to_vec(), hi.to_vec()), o.particles)
        .with_inertia_factor(o.inertia)
        .and_then(|p| p.with_cognitive_factor(o.cognitive))
        .and_then(|p| p.with_social_factor(o.social))
        .map_err(|e| argmin_err("particle-swarm", e))?
        .with_rng_generator(rng);
    let res = Executor::new(
        Swarmed {
            tracked,
            parallel: o.parallel,
        },
        Budgeted::new(pso, tracked, stop_at, Some((o.stall_iters, 1e-12))),
    )
    .configure(|s| s.max_iters(u64::MAX))
    .ctrlc(false)
    .run()
    .map_err(|e| argmin_err("particle-swarm", e))?;
    let st = res.state();
    let Some(best) = st.get_best_param() else {
        return Ok(None);
    };
    let best = tracked.space().canonicalize(
        &Swarmed {
            tracked,
            parallel: false,
        }
        .candidate(&best.position),
    );
    Ok(Some((best, st.get_best_cost())))
}

/// Seed of swarm episode `e`: a SplitMix64 step of `seed` and `e`.
fn episode_seed(seed: u64, e: u64) -> u64 {
    let mut z = seed ^ e.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::search::{minimize, FitMethod, Objective, Space};

    struct Valley(Space);
    impl Objective for Valley {
        fn space(&self) -> &Space {
            &self.0
        }
        fn cost(&self, c: &Candidate) -> f64 {
            (c.positions[0] as f64 - 13.0).powi(2) + (c.values[0] - 0.7).powi(2)
        }
    }

    #[test]
    fn swarm_alone_is_seeded_and_finds_a_one_defect_optimum() {
        let mut s = Space::masses(30, 1, (0.0, 1.0));
        s.log_scale = vec![false];
        let v = Valley(s);
        let mut opts = SearchOptions {
            max_evals: 5000,
            seed: 11,
            ..Default::default()
        };
        opts.pso.finish = Finish::None;
        let a = minimize(FitMethod::Pso, &v, &opts).unwrap();
        let b = minimize(FitMethod::Pso, &v, &opts).unwrap();
        assert_eq!(a, b);
        assert_eq!(a.best.positions, vec![13]);
        assert!((a.best.values[0] - 0.7).abs() < 1e-3);
    }

    #[test]
    fn episode_seeds_differ() {
        let s: std::collections::HashSet<u64> = (0..100).map(|e| episode_seed(7, e)).collect();
        assert_eq!(s.len(), 100);
        assert_ne!(episode_seed(1, 0), episode_seed(2, 0));
    }

    #[test]
    fn options_validate() {
        PsoOptions::default().validate().unwrap();
        for o in crate::detect::search::spoiled::<PsoOptions>(&[
            |o| o.particles = 1,
            |o| o.inertia = -1.0,
            |o| o.swarm_share = 0.0,
            |o| o.patience = 0,
        ]) {
            assert!(o.validate().is_err(), "{o:?}");
        }
    }
}
