//! What the inverse side starts from: observations and their noise model.
//!
//! | module | what |
//! |---|---|
//! | [`measurement`] | what a record measured (displacement, velocity or acceleration of a mass) and what drove it (the impulse or a measured force) |
//! | [`observations`] | the data-first entry: a sampled series (`t`, `x`, optional noise sigma) or Laplace values with errors |
//! | [`series`] | a sampled series with its white-noise level ([`series::TimeData`]) |
//! | [`laplace`] | Laplace-domain values at nodes, weighted or whitened ([`laplace::LaplaceObs`]) |
//! | [`exact`] | values of `X_1` at any node for the mass-only Woodbury kernel ([`exact::Data`]) |
//! | [`whiten`] | whitening of the correlated Laplace-domain noise of a transformed series |

pub mod exact;
pub mod laplace;
pub mod measurement;
pub mod observations;
pub mod series;
pub mod whiten;
