//! Defect detection: fitting the defects of a chain (masses, springs,
//! dampers that differ) to a measured record or to Laplace data
//! ([`fit::fit`], see its example), and explicit locators for one defect
//! ([`locate`]).
//!
//! The paper's Table 1 from a scene (exact-model data, the real-axis
//! residual (4.18), the mass-only Woodbury kernel):
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
//! Data flow: [`data`] (observations and their noise) -> [`misfit`] (one
//! misfit kind each: real axis, Bromwich line, time) -> [`unknowns`]
//! (positions, kinds, values, chain parameters) -> [`search`] (enumeration,
//! GA, Nelder-Mead, PSO, bounded Levenberg-Marquardt) -> [`fit`] (the report
//! with standard errors, noise level, number of defects, status). Scenes
//! ([`scene`]) and studies describe synthetic data and call the same fit;
//! the explicit locators ([`locate`]) stand apart.
//!
//! | module | what |
//! |---|---|
//! | [`data`] | observations: a sampled series or Laplace values; [`data::exact`] the exact-model values of synthetic data; whitening |
//! | [`misfit`] | [`misfit::MisfitKind`], the quadrature rules ([`misfit::quadrature`]), the mass-only Woodbury kernel, the time-domain chi-square ([`misfit::time`]) |
//! | [`unknowns`] | the unknowns of a fit |
//! | [`search`] | optimizers and [`search::enumerate`], [`search::lsq`] (bounded Levenberg-Marquardt) |
//! | [`fit`] | [`fit::fit`] from data ([`fit::model`] what is known, [`fit::options`] what to look for, `fit/engine.rs` the machinery); [`fit::paper::fit`] the scene's fit (the paper's Table 1 path); [`fit::general`] the hypothesis fits, [`fit::chainfit`], [`fit::identify`], [`fit::select`] (k), [`fit::noise`] (sigma), [`fit::spectral`] (masses from modes) |
//! | [`scene`] | the TOML fit scene |
//! | [`locate`] | explicit single-defect locators (section 4.1), corrected, any precision |

pub mod data;
pub mod fit;
pub mod locate;
pub mod misfit;
pub mod scene;
pub mod search;
pub mod unknowns;
