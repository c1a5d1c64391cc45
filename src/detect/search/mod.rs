//! Optimizers over mixed integer/real spaces behind one interface.
//!
//! TEMPORARY COPY of the interface types owned by the `optim` branch (which
//! implements genetic, Nelder-Mead and particle-swarm `minimize`). Only the
//! type definitions live here until that branch is on `main`; the
//! exhaustive enumeration ([`enumerate`]) is independent of them.

pub mod enumerate;

/// The search space: `n_positions` distinct integer positions in `1..=n`
/// (none in `excluded`) and `bounds.len()` real values.
#[derive(Clone, Debug, PartialEq)]
pub struct Space {
    /// Positions range over `1..=n`.
    pub n: usize,
    /// Number of integer positions.
    pub n_positions: usize,
    /// Positions that may not be used (known defects).
    pub excluded: Vec<usize>,
    /// Bounds of the real values.
    pub bounds: Vec<(f64, f64)>,
    /// Whether a value is searched on a log scale.
    pub log_scale: Vec<bool>,
    /// `pairing[v] = Some(p)`: value `v` belongs to position `p`.
    pub pairing: Vec<Option<usize>>,
}

/// A point of a [`Space`].
#[derive(Clone, Debug, PartialEq)]
pub struct Candidate {
    /// Integer positions.
    pub positions: Vec<usize>,
    /// Real values.
    pub values: Vec<f64>,
}

/// What an optimizer minimizes.
pub trait Objective: Sync {
    /// The space.
    fn space(&self) -> &Space;
    /// The cost; a finite penalty for invalid candidates, never NaN.
    fn cost(&self, c: &Candidate) -> f64;
}

/// The stochastic optimizers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// Genetic algorithm.
    Genetic,
    /// Nelder-Mead.
    NelderMead,
    /// Particle swarm.
    ParticleSwarm,
}

/// Options shared by the optimizers.
#[derive(Clone, Debug, PartialEq)]
pub struct SearchOptions {
    /// Budget of cost evaluations.
    pub max_evals: usize,
    /// Seed.
    pub seed: u64,
    /// Record the best cost after each iteration.
    pub trace: bool,
}

impl Default for SearchOptions {
    fn default() -> Self {
        SearchOptions {
            max_evals: 20_000,
            seed: 0,
            trace: false,
        }
    }
}

/// Outcome of a search.
#[derive(Clone, Debug, PartialEq)]
pub struct SearchResult {
    /// Best candidate.
    pub best: Candidate,
    /// Its cost.
    pub cost: f64,
    /// Cost evaluations used.
    pub evaluations: usize,
    /// `(evaluations, best cost)` per iteration when traced.
    pub trace: Vec<(usize, f64)>,
}
