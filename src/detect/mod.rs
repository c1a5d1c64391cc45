//! Defect detection: fitting the defects of a chain (masses, springs,
//! dampers that differ) to a measured record or to Laplace data
//! ([`fit::fit`], see its example), and explicit locators for one defect
//! ([`locate`]).
//!
//! The paper's Table 1 from a scene (exact-model data, the real-axis
//! residual (4.18), the mass-only Woodbury kernel), through the same
//! pipeline as [`fit::fit`]:
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
//! Data flow, one direction: [`data`] (observations and their noise) ->
//! [`model`] (the measurement-model interface every continuous fit takes:
//! residuals, Jacobian, degrees of freedom) ->
//! [`misfit`] (one misfit kind each: real axis, Bromwich line, time; the
//! fast kernels for one position set) ->
//! [`unknowns`] (positions, kinds, values, chain parameters) -> [`search`]
//! (enumeration, GA, Nelder-Mead, PSO, bounded Levenberg-Marquardt) ->
//! [`scene`] (a TOML description: truth for synthetic data, unknowns,
//! misfit, search options) -> [`fit`] (the report with standard errors,
//! noise level, number of defects, status; [`fit::paper`] runs a scene
//! through it). Each module imports only the ones before it: the search
//! builds its space from the unknowns ([`search::Space::for_masses`]), the
//! scene owns its options and knows nothing of the fit, and the scene path
//! ([`fit::paper::fit`]) turns a scene into observations, a model and
//! options, runs the one pipeline, then compares with the scene's truth.
//! The explicit locators ([`locate`]) stand apart.
//!
//! | module | what |
//! |---|---|
//! | [`data`] | observations: a sampled series or Laplace values; [`data::exact`] the exact-model values of synthetic data; whitening |
//! | [`model`] | [`model::MeasurementModel`]: one interface for every way of comparing a chain with data (see `docs/architecture.md` for how to add one) |
//! | [`misfit`] | [`misfit::MisfitKind`], the quadrature rules ([`misfit::quadrature`]), the mass-only Woodbury kernel, the time-domain chi-square ([`misfit::time`]) |
//! | [`unknowns`] | the unknowns of a fit |
//! | [`search`] | optimizers ([`search::minimize`], [`search::MisfitObjective`] on the Woodbury kernel), [`search::enumerate`], [`search::lsq`] (bounded Levenberg-Marquardt), [`search::rankone`] (the greedy search's scoring kernel) |
//! | [`scene`] | the TOML fit scene and its options |
//! | [`fit`] | [`fit::fit`] from data ([`fit::model`] what is known, [`fit::options`] what to look for, `fit/engine.rs` the machinery); [`fit::paper::fit`] a scene through the same engine (the paper's Table 1 path); [`fit::general`] the hypothesis fits, [`fit::greedy`] the greedy search with moves, [`fit::chainfit`], [`fit::identify`], [`fit::select`] (k), [`fit::noise`] (sigma), [`fit::spectral`] (masses from modes), [`fit::profile`] (every mass or spring free), [`fit::visibility`] (how deep the data see) |
//! | [`locate`] | explicit single-defect locators (section 4.1), corrected, any precision |
//!
//! ## The cost of a new defect kind
//!
//! Every kernel reads a defect through its [`Site`](crate::chain::Site):
//! the probe `u` (a point `e_j` or a strain `e_i - e_{i+1}`) and the power
//! of `s` in `c(s) = (value - uniform) s^power` (2 a mass, 1 a damper, 0 a
//! stiffness). The matrices are assembled in one place
//! ([`Chain::coefficients`](crate::Chain::coefficients): `M`, `D`, and `K`
//! as a ground-stiffness diagonal plus the springs' Laplacian), and the
//! Woodbury forward model, the transfer sweep, the tridiagonal and modal
//! solvers, both simulators, the sensitivities, both Jacobians, the greedy
//! search's rank-one scores and its candidate sensitivities on a sampled
//! record ([`misfit::time_screen`]) are written for any site.
//!
//! Measured by adding one: the ground spring (`Defect::Ground`, a spring
//! from mass `j` to the ground; commit "Ground spring: a fourth defect
//! kind"). Its code is in **two source files**:
//!
//! | file | what the kind needs there |
//! |---|---|
//! | `src/chain.rs` | the `Defect` variant: its name, position, value, site (`e_j`, power 0), uniform value (0), value range |
//! | `src/detect/unknowns/mod.rs` | `DefectKind` and `KindChoice` entries (name, starting values, bounds) |
//!
//! and its name in three help or schema texts (`src/cmd/fit.rs`,
//! `src/detect/fit/mod.rs`, `src/study/kinds/fit.rs`), the README and the
//! Python docstrings. Everything else, the CLI, the scene and study files,
//! the Python package, every fit method, reads it from these two; the
//! tests in `tests/ground.rs` check each path against references written
//! out by hand. A kind whose site is not a point or a stiffness between
//! neighbours (a dashpot between two masses: a strain probe with power 1)
//! would also need the assembly and the transfer sweep to carry an
//! off-diagonal damping, which no kind needs today.

pub mod data;
pub mod fit;
pub mod locate;
pub mod misfit;
pub mod model;
pub mod monitor;
pub mod scene;
pub mod search;
pub mod unknowns;
