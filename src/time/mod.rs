//! Time domain: simulation of the chain ([`simulate`]) and the exact inverse
//! Laplace transform of its responses as finite sums of damped modes ([`modal`]).

pub mod modal;
pub mod simulate;
