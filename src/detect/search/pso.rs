//! argmin's particle swarm with relax-and-round positions.
//!
//! ## Treatment of the positions: relax and round
//!
//! A particle is `[x_1..x_k, u_1..u_m]`: relaxed positions in
//! `[0.5, n + 0.5]` and values in unit coordinates `[0, 1]` (log-scaled
//! values are uniform in `ln v`). Each evaluation rounds the positions to
//! distinct free integers ([`Space::round_positions`]: nearest integer,
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
//! [`super::nelder_mead::local_search`] ([`Finish::LocalSearch`]). The swarm
//! gets `swarm_share` of the budget, the finish the rest.
//!
//! Seeding: `ParticleSwarm::with_rng_generator(ChaCha8Rng::seed_from_u64(seed))`
//! (argmin's default seeds itself from the OS, which would not be reproducible).

use super::nelder_mead::{local_search, polish, Budgeted};
use super::{argmin_err, finite_cost, Candidate, SearchOptions, Tracked};
use crate::error::{Error, Result};
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
/// cognitive and social `0.5 + ln 2`); `stall_iters = 150` (stop the swarm
/// after that many sweeps without a relative improvement of 1e-12);
/// `finish = LocalSearch`; `swarm_share = 0.7`.
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
    /// Fraction of the budget for the swarm when a finish follows, in `(0, 1]`.
    pub swarm_share: f64,
}

impl Default for PsoOptions {
    fn default() -> Self {
        PsoOptions {
            particles: 40,
            inertia: 1.0 / (2.0 * 2f64.ln()),
            cognitive: 0.5 + 2f64.ln(),
            social: 0.5 + 2f64.ln(),
            stall_iters: 150,
            finish: Finish::LocalSearch,
            swarm_share: 0.7,
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
        if self.stall_iters == 0 {
            return Err(Error::invalid("pso.stall_iters", 0, ">= 1"));
        }
        if !(self.swarm_share > 0.0 && self.swarm_share <= 1.0) {
            return Err(Error::invalid("pso.swarm_share", self.swarm_share, "in (0, 1]"));
        }
        Ok(())
    }
}

/// Relaxed particle -> rounded candidate.
struct Swarmed<'t, 'a> {
    tracked: &'t Tracked<'a>,
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
    let share = if o.finish == Finish::None { 1.0 } else { o.swarm_share };
    let stop_at = ((opts.max_evals as f64) * share).ceil() as usize;
    let pso = ParticleSwarm::new((lo, hi), o.particles)
        .with_inertia_factor(o.inertia)
        .and_then(|p| p.with_cognitive_factor(o.cognitive))
        .and_then(|p| p.with_social_factor(o.social))
        .map_err(|e| argmin_err("particle-swarm", e))?
        .with_rng_generator(ChaCha8Rng::seed_from_u64(opts.seed));
    Executor::new(
        Swarmed { tracked },
        Budgeted::new(pso, tracked, stop_at, Some(o.stall_iters)),
    )
    .configure(|s| s.max_iters(u64::MAX))
    .ctrlc(false)
    .run()
    .map_err(|e| argmin_err("particle-swarm", e))?;
    let Some((best, _)) = tracked.best() else {
        return Ok(());
    };
    let best = space.canonicalize(&best);
    match o.finish {
        Finish::None => {}
        Finish::Polish => {
            if !tracked.done() {
                polish(tracked, &best, tracked.remaining(), &opts.nelder_mead)?;
            }
        }
        Finish::LocalSearch => {
            if !tracked.done() {
                local_search(tracked, &best, &opts.nelder_mead)?;
            }
        }
    }
    Ok(())
}
