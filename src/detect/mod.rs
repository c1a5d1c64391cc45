//! Defect detection: fit the positions and masses of defects to observed
//! `X_1` data by minimising an L2 residual.
//!
//! | module | what |
//! |---|---|
//! | [`data`] | observed data `X_1*(s)`: source, noise, values at nodes |
//! | [`quadrature`] | fixed rules with tabled Green's functions; adaptive reference |
//! | [`misfit`] | the residuals (real axis, Bromwich line) and per-position-set tables |
//! | [`space`] | the unknowns and the search space |
//! | [`search`] | optimizers: exhaustive enumeration (+ GA, Nelder-Mead, PSO) |
//! | [`scene`] | the TOML fit scene |
//! | [`fit`] | `fit(scene, data, options) -> FitReport` |

pub mod data;
pub mod fit;
pub mod misfit;
pub mod quadrature;
pub mod scene;
pub mod search;
pub mod space;
