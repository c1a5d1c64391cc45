//! Defect detection: explicit locators for one defect ([`locate`]), and
//! fitting the positions and masses of defects to observed `X_1` data by
//! minimising an L2 residual.
//!
//! ```
//! use springmass::{Chain, Defect};
//! use springmass::detect::{fit::paper::fit, scene::FitScene};
//! // the paper's Table 1, System 1: synthetic data, both positions and masses unknown
//! let truth = Chain::paper(5)?.with_defects([
//!     Defect::Mass { at: 2, m: 3.0 }, Defect::Mass { at: 4, m: 0.5 }])?;
//! let scene = FitScene::synthetic(&truth);          // or FitScene::load("scene.toml")
//! let report = fit(&scene, &scene.data()?, &scene.options())?;
//! assert_eq!(report.defects.iter().map(|d| d.at()).collect::<Vec<_>>(), vec![2, 4]);
//! assert!(report.runners_up[0].gap > 1e-9);          // next best: (2, 3), r = 1.9e-9 higher
//! # Ok::<(), springmass::Error>(())
//! ```
//!
//! | module | what |
//! |---|---|
//! | [`data`] | observed data `X_1*(s)`: source, noise, values at nodes |
//! | [`quadrature`] | fixed rules with tabled Green's functions; adaptive reference |
//! | [`misfit`] | the residuals (real axis, Bromwich line) and per-position-set tables |
//! | [`space`] | the unknowns and the search space |
//! | [`search`] | optimizers: exhaustive enumeration ([`search::enumerate`]), GA, Nelder-Mead, PSO |
//! | [`scene`] | the TOML fit scene |
//! | [`fit`] | `fit(scene, data, options) -> FitReport` |
//! | [`lsq`] | bounded Levenberg-Marquardt and Gauss-Newton covariance |
//! | [`misfit_time`] | time-domain chi-square against a sampled series |
//! | [`identify`] | standard errors, chi-square gaps, noise level of indistinguishability, flags |
//! | [`select`] | number of defects by AIC, BIC or a chi-square test |
//! | [`noisefit`] | fits to noisy sampled series with each misfit (noise study) |
//! | [`noise_study`] | success vs noise, calibration, unknown damping, number of defects |
//! | [`whiten`] | whitening of the correlated Laplace-domain noise: a true chi-square and its degrees of freedom |
//! | [`chainfit`] | continuous fit of defect values and chain parameters (d, k, mass, gamma) |
//! | [`locate`] | explicit single-defect locators (section 4.1), corrected, any precision |

pub mod data;
pub mod fit;
pub mod locate;
pub mod misfit;
pub mod noise_study;
pub mod scene;
pub mod search;
pub mod unknowns;
