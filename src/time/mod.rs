//! Time domain: simulation, exact and numerical inverse Laplace transforms,
//! and the Laplace transform of sampled data.

pub mod inverse;
pub mod series;
