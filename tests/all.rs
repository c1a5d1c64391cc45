//! Every integration test in one binary (`cargo test --test all`): one link
//! of the library instead of one per file. Each file of `tests/` stays a
//! module of its own name, so `cargo test --test all fit_data::` runs one
//! file's tests. Tests that need a feature are compiled only with it (the
//! binary itself needs `cli`: many tests run the built `springmass`).
//!
//! The command-line fuzz run (`tests/fuzz_cli.rs`, 10 000 cases) is a
//! target of its own that `cargo test` leaves out: run it with
//! `cargo test --test fuzz_cli` (CI does, in its own step).

// forward.rs, locate.rs and suppress.rs each declare `mod common;` (as they
// did as binaries of their own): three copies of the small helper module
#![allow(clippy::duplicate_mod)]

#[path = "ambient.rs"]
mod ambient;
#[path = "baseline.rs"]
mod baseline;
#[path = "boundaries.rs"]
mod boundaries;
#[path = "chi2.rs"]
mod chi2;
#[path = "cli.rs"]
mod cli;
#[path = "cli_fit.rs"]
mod cli_fit;
#[path = "cli_hardening.rs"]
mod cli_hardening;
#[path = "damping_models.rs"]
mod damping_models;
/// The tests' own dense state-space generator of records.
#[path = "common/dense.rs"]
mod dense;
#[path = "first_use.rs"]
mod first_use;
#[path = "fit.rs"]
mod fit;
#[path = "fit_data.rs"]
mod fit_data;
#[path = "forward.rs"]
mod forward;
#[path = "ground.rs"]
mod ground;
#[path = "hardening_fuzz.rs"]
mod hardening_fuzz;
#[path = "inverse.rs"]
mod inverse;
#[path = "k_auto.rs"]
mod k_auto;
#[path = "kinds_any.rs"]
mod kinds_any;
#[cfg(feature = "bigfloat")]
#[path = "locate.rs"]
mod locate;
#[path = "long_chains.rs"]
mod long_chains;
#[path = "long_search.rs"]
mod long_search;
#[path = "mismatch.rs"]
mod mismatch;
#[path = "modal_update.rs"]
mod modal_update;
#[path = "monitor.rs"]
mod monitor;
#[path = "nested_k.rs"]
mod nested_k;
#[path = "noise.rs"]
mod noise;
#[path = "observables.rs"]
mod observables;
#[path = "real_setups.rs"]
mod real_setups;
#[path = "realistic_noise.rs"]
mod realistic_noise;
#[path = "records.rs"]
mod records;
#[path = "room_for_more.rs"]
mod room_for_more;
#[path = "scene_data.rs"]
mod scene_data;
#[path = "search.rs"]
mod search;
#[path = "sensors.rs"]
mod sensors;
#[path = "simulate.rs"]
mod simulate;
#[path = "spectral.rs"]
mod spectral;
#[path = "study.rs"]
mod study;
#[path = "study_safety.rs"]
mod study_safety;
#[path = "suppress.rs"]
mod suppress;
#[path = "threads.rs"]
mod threads;
#[path = "time_series.rs"]
mod time_series;
#[path = "trigger.rs"]
mod trigger;
#[path = "uncertainty.rs"]
mod uncertainty;
