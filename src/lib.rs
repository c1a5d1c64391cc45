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
//! ## Where each piece lives
//!
//! | module | what |
//! |---|---|
//! | [`chain`] | the chain and its defects, validated |
//! | [`scalar`] | the number types the model is generic over (`f64`, `Complex64`, extended precision) |
//! | [`green`] | closed-form Green's function, overflow-free for every `n` and `s` |
//! | [`forward`] | Woodbury response; [`forward::tridiag`] the O(n) reference |
//! | [`control`] | vibration suppression (Theorem 3.1, Corollary 3.2): Laplace, exact time domain, verification |
//! | [`linalg`] | the small pivoted solve behind Woodbury |
//! | [`sensitivity`] | derivatives of X_o(s) with respect to every parameter (reciprocity) |
//! | [`precision`] | arbitrary-precision reals ([`precision::BigReal`]) and real-only operations |
//! | [`scenes`] | the paper's reference scenes (P1-P4, Table 1's S1-S4), shared by tests, benches and configs |
//! | [`series`] | sampled time series, CSV in and out, atomic writes |
//! | [`io`] | safe atomic writes (never a device, FIFO or directory), size-capped reads, memory budget and limits |
//! | [`plot`] | SVG line plots and heatmaps (bundled font) |
//! | [`study`] | config-driven studies: sweeps, parallel resumable runs, reports |
//! | [`detect::locate`] | explicit single-defect locators (section 4.1), error floors, any precision |
//! | [`time`] | simulation ([`time::simulate`]), exact ([`time::modal`]) and numerical ([`time::inverse`]) inverse Laplace transforms, transform of sampled series ([`time::series`]) |
//! | [`noise`] | seeded additive white Gaussian noise |
//! | [`error`] | one error type; every variant names the field and its range |
//! | [`detect`] | defect fitting: data, quadrature, residuals, unknowns, [`detect::search`] (enumeration, GA, Nelder-Mead, particle swarm), `fit` |

pub mod chain;
pub mod control;
pub mod detect;
pub mod error;
pub mod forward;
pub mod green;
pub mod io;
pub mod linalg;
pub mod noise;
pub mod plot;
pub mod precision;
pub mod scalar;
pub mod scenes;
pub mod sensitivity;
pub mod series;
pub mod study;
pub mod time;

pub use chain::{Chain, ChainSpec, Defect};
pub use error::{Error, Result};
pub use num_complex::Complex64;
