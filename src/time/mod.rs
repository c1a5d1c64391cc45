//! Time domain: simulation of the chain ([`simulate`]), the exact inverse
//! Laplace transform of its responses as finite sums of damped modes
//! ([`modal`]), numerical inverse Laplace transforms of any `F(s)`
//! ([`inverse`]), and the Laplace transform of sampled data ([`series`]).

pub mod inverse;
pub mod modal;
pub mod series;
pub mod simulate;
