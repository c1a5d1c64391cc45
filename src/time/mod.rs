//! Time domain: simulation of the chain ([`simulate`]), the exact inverse
//! Laplace transform of its responses as finite sums of damped modes
//! ([`modal`]), the numerical inverse Laplace transform of a general `F(s)`
//! ([`inverse`]), the Laplace transform of sampled data ([`series`]) and
//! the modes a modal survey measures, damped or not ([`survey_modes`]).

pub mod inverse;
pub mod modal;
pub(crate) mod qep_roots;
pub mod series;
pub mod simulate;
pub mod survey_modes;
