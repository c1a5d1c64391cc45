//! # springmass
//!
//! Vibration suppression and defect detection in one-dimensional spring-mass
//! chains, after Egarguin, Meklachi, Onofrei and Harari-Arnold (2019).
//!
//! ## The model in one paragraph
//!
//! `n` masses in series between two walls, springs `k` between neighbours and
//! to the walls, a damper `d` on every mass, an impulse `gamma delta(t)` on mass 1.
//! In the Laplace domain the displacements solve the tridiagonal system
//! `K(s) X = gamma e_1`, `K(s) = M s^2 + D s + K_spring`. The uniform chain has a
//! closed-form inverse (Theorem 2.1, [`green`]); a defect (a mass, a spring or a
//! damper that differs) is a rank-1 update, so a chain with `k` defects costs
//! one `k x k` solve per `s` whatever its length ([`forward`]).
//!
//! ## A first evaluation
//!
//! ```
//! use springmass::{Chain, Defect, forward::response};
//! // The paper's System 3: n = 20, defects (8, 5) and (15, 2), d = 0.1.
//! let chain = Chain::paper(20)?
//!     .with_defect(Defect::Mass { at: 8, m: 5.0 })?
//!     .with_defect(Defect::Mass { at: 15, m: 2.0 })?;
//! let x1 = response(&chain, 0.5_f64, 1)?;            // real s
//! let x1c = response(&chain, num_complex::Complex64::new(0.5, 2.0), 1)?; // complex s
//! assert!(x1 > 0.0 && x1c.norm() > 0.0);
//! # Ok::<(), springmass::Error>(())
//! ```
//!
//! ## A fit from data, in five lines
//!
//! A user's record of mass 1 (here a CSV this example writes first), the
//! number of masses, nothing else: the number of defects, their positions,
//! values, standard errors and the noise level all come from the data.
//!
//! ```
//! # use springmass::{Chain, Defect, noise::NoiseLevel, series::TimeSeries};
//! # let truth = Chain::paper(6)?.with_defect(Defect::Mass { at: 4, m: 2.5 })?;
//! # let rec = springmass::detect::data::series::TimeData::simulate(&truth, 120.0, 0.25, NoiseLevel::RelativeMax(1e-3), 7)?;
//! # let path = std::env::temp_dir().join(format!("springmass-lib-doc-{}.csv", std::process::id()));
//! # TimeSeries::new(rec.t().to_vec(), vec![("x1".into(), rec.y().to_vec())])?.write_csv(&path)?;
//! use springmass::detect::{data::observations::{Observations, Series}, fit};
//! let obs = Observations::Series(Series::from_csv(&path, Some("x1"), None)?);
//! let report = fit::fit(&obs, &fit::Model::new(6)?, &fit::FitOptions::default())?;
//! println!("{}", report.summary());           // the answer with error bars first
//! assert_eq!((report.k, report.defects[0].at), (1, 4));
//! # std::fs::remove_file(&path).ok();
//! # Ok::<(), springmass::Error>(())
//! ```
//!
//! ## Cargo features
//!
//! `cli` (the `springmass` binary: clap, anyhow, indicatif), `plot` (SVG plots
//! with the bundled DejaVu Sans font) and `bigfloat` (extended precision,
//! astro-float) are on by default. With `default-features = false` the library
//! needs only its numerical dependencies; a plot then returns an
//! [`Error::InvalidParameter`] naming `plot`, and a precision other than `f64`
//! one naming `precision`.
//!
//! ## Where each piece lives, in data-flow order
//!
//! | module | what |
//! |---|---|
//! | [`chain`] | the model: a chain and its defects, validated |
//! | [`scenes`] | the reference scenes (the paper's P1-P4 and Table 1's S1-S4, the noise study's C3a, C3b, k0-k3), shared by tests, benches and configs |
//! | [`scalar`], [`precision`], [`linalg`] | number types (`f64`, `Complex64`, extended precision) and the small pivoted solve |
//! | [`green`] | closed-form Green's function, overflow-free for every `n` and `s` |
//! | [`observable`] | what a sensor measures at a mass: displacement, velocity or acceleration |
//! | [`forward`] | Woodbury response; [`forward::tridiag`] the O(n) reference |
//! | [`sensitivity`] | derivatives of X_o(s) with respect to every parameter (reciprocity) |
//! | [`time`] | simulation ([`time::simulate`]), exact ([`time::modal`]) and numerical ([`time::inverse`]) inverse Laplace transforms, transform of sampled series ([`time::series`]) |
//! | [`noise`] | seeded additive white Gaussian noise (synthetic data) |
//! | [`series`] | sampled time series, CSV in (pandas, loggers) and out |
//! | [`units`] | units in a record's header (`t [ms]`, `x1 [mm]`, `a1 [g]`) converted to SI and checked against the observable |
//! | [`io`] | safe atomic writes (never a device, FIFO or directory), size-capped reads, memory budget and limits |
//! | [`control`] | vibration suppression (Theorem 3.1, Corollary 3.2): Laplace, exact time domain, verification |
//! | [`detect::data`] | the inverse side starts here: observations (a series or Laplace values), their noise model, whitening |
//! | [`detect::model`] | one measurement-model interface, [`detect::model::MeasurementModel`] (residuals, Jacobian, degrees of freedom), implemented by the time-domain misfit and the Laplace values |
//! | [`detect::misfit`] | one [`detect::misfit::MisfitKind`] (real axis, Bromwich, time), quadrature rules, the mass-only Woodbury kernel |
//! | [`detect::unknowns`] | what is unknown: positions, kinds, values, chain parameters |
//! | [`detect::search`] | enumeration, genetic algorithm, Nelder-Mead, particle swarm, bounded Levenberg-Marquardt |
//! | [`detect::fit`] | `fit(observations, model, options) -> FitReport`: noise and number of defects estimated, standard errors, status, how deep the data see; [`detect::fit::fit_profile`] every mass or spring free (whole-profile inversion) |
//! | [`detect::scene`] | TOML fit scenes (truth for synthetic data + unknowns + misfit + search) |
//! | [`detect::locate`] | explicit single-defect locators (section 4.1), error floors, any precision |
//! | [`study`] | config-driven studies: sweeps, parallel resumable runs, reports; the noise studies are its kind [`study::kinds::noise`] |
//! | [`plot`] | SVG line plots and heatmaps (bundled font) |
//! | [`error`] | one error type; every variant names the field and its range |

pub mod cancel;
pub mod chain;
pub mod control;
pub mod detect;
pub mod error;
pub mod forward;
pub mod green;
pub mod io;
pub mod linalg;
pub mod noise;
pub mod observable;
pub mod plot;
pub mod precision;
pub mod scalar;
pub mod scenes;
pub mod sensitivity;
pub mod series;
pub mod study;
pub mod time;
pub mod units;

pub use chain::{Chain, ChainSpec, Defect};
pub use error::{Error, Result};
pub use num_complex::Complex64;
