//! Defect detection: fit the positions and masses of defects to observed data.
//!
//! | module | what |
//! |---|---|
//! | [`lsq`] | bounded Levenberg-Marquardt and Gauss-Newton covariance |
//! | [`misfit_time`] | time-domain chi-square against a sampled series |
//! | [`identify`] | standard errors, chi-square gaps, noise level of indistinguishability, flags |
//! | [`select`] | number of defects by AIC, BIC or a chi-square test |
//! | [`chainfit`] | continuous fit of defect values and chain parameters (d, k, mass, gamma) |

pub mod chainfit;
pub mod identify;
pub mod lsq;
pub mod misfit_time;
pub mod select;
