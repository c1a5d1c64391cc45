//! Kind `noise`: the data-first fit ([`crate::detect::fit::fit`]) of a
//! noisy record of a reference system, told only the chain's `n` and `d`
//! (and the number of defects when `defects = "given"`), scored against the
//! system's truth.
//!
//! The record is `x_1(t)` on `[0, t_end]` every `dt` with white noise of
//! standard deviation `level max|x_1|` drawn with the case's seed (derived
//! from the case's parameters and repeat, not its position in a list, so a
//! subset of a sweep reproduces the full sweep's cells). Metrics: whether
//! every position is right, the number of defects found, how many fitted
//! values lie within 3 reported standard errors of the truth, whether a
//! wrong answer was flagged resolved or a wrong position identifiable, and
//! the estimated over the true noise level. The noise study
//! (`configs/studies/noise-study.toml`) is a sweep of this kind.
//!
//! ```
//! use springmass::study::kinds::Kind;
//! let scene: toml::Value = toml::from_str("system = \"S1\"\nlevel = 1e-3\nt_end = 100.0\ndt = 0.25").unwrap();
//! let out = Kind::Noise.run(&scene, 3)?;
//! assert_eq!(out.metrics["positions_ok"].as_f64(), Some(1.0));
//! # Ok::<(), springmass::Error>(())
//! ```

use super::case::{CaseOutput, KindScene};
use crate::chain::Chain;
use crate::detect::misfit::MisfitKind;
use crate::detect::noise_study::{fit_record, noisy_data, selection_truths, systems, StudyConfig};
use crate::error::{check_f64, Error, Result};
use crate::study::schema::FieldDoc;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// One paragraph for the schema page.
pub const SUMMARY: &str = "Simulates a noisy record of a reference system (S1-S4, C3a, C3b, or k0-k3 with 0 to 3 defects), fits it with the data-first fit told only n and d (and k when defects = \"given\"), noise level estimated, and scores the answer against the truth.";

/// The scene fields.
pub const FIELDS: &[FieldDoc] = &[
    FieldDoc::new("system", "string", "required", "S1, S2, S3, S4 (Table 1), C3a, C3b (three defects), or k0, k1, k2, k3 (n = 10 with 0 to 3 defects, for the choice of k)."),
    FieldDoc::new("level", "float in [0, 1]", "required", "Noise standard deviation relative to max |x_1|."),
    FieldDoc::new("t_end", "float > 0", "200", "Record length."),
    FieldDoc::new("dt", "float > 0", "0.2", "Sampling step."),
    FieldDoc::new("defects", "\"given\" | \"auto\"", "\"given\"", "Tell the fit the true number of defects, or let it choose among 0..=4 by BIC."),
    FieldDoc::new("misfit", "\"time\" | \"bromwich\" | \"real-axis\" | \"default\"", "\"default\"", "The fit's misfit (default: the fit's default for a series, time)."),
    FieldDoc::new("noise", "\"auto\" | \"given\"", "\"auto\"", "Estimate the noise level (auto) or tell the fit the true one."),
];

/// `(column, meaning)` of the metrics.
pub const METRICS: &[(&str, &str)] = &[
    ("k_true", "number of true defects"),
    ("k_found", "number of defects of the answer"),
    ("k_ok", "1 when k_found = k_true"),
    (
        "positions_ok",
        "1 when every position is right and none is extra",
    ),
    ("values", "fitted values at true positions"),
    (
        "within_3se",
        "of those, the truth within 3 reported standard errors",
    ),
    (
        "wrong_flagged",
        "1 when a wrong answer is flagged resolved or a wrong position identifiable",
    ),
    ("resolved", "1 when the fit says resolved"),
    ("fits_data", "1 when the fit says the residual is noise"),
    ("sigma_ratio", "estimated over true noise level"),
    ("t_fit", "wall time of the fit, seconds"),
];

/// The scene of a `noise` case.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// Reference system.
    pub system: String,
    /// Relative noise level.
    pub level: f64,
    /// Record length (default 200).
    #[serde(default = "default_t_end")]
    pub t_end: f64,
    /// Sampling step (default 0.2).
    #[serde(default = "default_dt")]
    pub dt: f64,
    /// `given` (default) or `auto`.
    #[serde(default = "default_given")]
    pub defects: String,
    /// `default`, `time`, `bromwich`, `real-axis`.
    #[serde(default = "default_misfit")]
    pub misfit: String,
    /// `auto` (default) or `given`.
    #[serde(default = "default_auto")]
    pub noise: String,
}

fn default_t_end() -> f64 {
    200.0
}
fn default_dt() -> f64 {
    0.2
}
fn default_given() -> String {
    "given".into()
}
fn default_misfit() -> String {
    "default".into()
}
fn default_auto() -> String {
    "auto".into()
}

/// The truth of a reference system by name.
///
/// # Errors
/// An unknown name (field `system`).
pub fn truth(name: &str) -> Result<Chain> {
    if let Some(s) = systems().into_iter().find(|s| s.name == name) {
        return Ok(s.truth);
    }
    let k: Option<usize> = name.strip_prefix('k').and_then(|k| k.parse().ok());
    match k {
        Some(k) if k <= 3 => Ok(selection_truths()[k].clone()),
        _ => Err(Error::invalid(
            "system",
            name,
            "S1, S2, S3, S4, C3a, C3b, k0, k1, k2 or k3",
        )),
    }
}

impl KindScene for Scene {
    const FIELDS: &'static [FieldDoc] = FIELDS;

    fn problems(&self) -> Vec<Error> {
        let mut out = Vec::new();
        if let Err(e) = truth(&self.system) {
            out.push(e);
        }
        let mut push = |r: Result<f64>| {
            if let Err(e) = r {
                out.push(e);
            }
        };
        push(check_f64(
            "level",
            self.level,
            (0.0..=1.0).contains(&self.level),
            "in [0, 1]",
        ));
        push(check_f64(
            "t_end",
            self.t_end,
            self.t_end > 0.0 && self.t_end <= 1e5,
            "in (0, 1e5]",
        ));
        push(check_f64(
            "dt",
            self.dt,
            self.dt > 0.0 && self.t_end / self.dt <= 1e6,
            "> 0 with at most 1e6 samples",
        ));
        if !matches!(self.defects.as_str(), "given" | "auto") {
            out.push(Error::invalid(
                "defects",
                &self.defects,
                "\"given\" or \"auto\"",
            ));
        }
        if self.misfit != "default" {
            if let Err(e) = MisfitKind::parse(&self.misfit) {
                out.push(Error::invalid(
                    "misfit",
                    &self.misfit,
                    format!("default, time, bromwich or real-axis ({e})"),
                ));
            }
        }
        if !matches!(self.noise.as_str(), "given" | "auto") {
            out.push(Error::invalid(
                "noise",
                &self.noise,
                "\"auto\" or \"given\"",
            ));
        }
        out
    }
}

/// Run one case.
///
/// # Errors
/// As the simulation and the fit.
pub fn run(s: &Scene, seed: u64) -> Result<CaseOutput> {
    let truth = truth(&s.system)?;
    let cfg = StudyConfig {
        t_end: s.t_end,
        dt: s.dt,
        ..StudyConfig::default()
    };
    let data = noisy_data(&truth, &cfg, s.level, seed)?;
    let k_true = truth.defects().len();
    let misfit = if s.misfit == "default" {
        None
    } else {
        Some(MisfitKind::parse(&s.misfit)?)
    };
    let t0 = Instant::now();
    let rep = fit_record(
        &truth,
        &data,
        s.defects == "given",
        misfit,
        s.noise == "given",
    )?;
    let t_fit = t0.elapsed().as_secs_f64();
    let score = crate::detect::noise_study::score(&rep, &truth);
    let mut out = CaseOutput::default();
    let mut put = |k: &str, v: f64| {
        out.metrics.insert(k.into(), serde_json::json!(v));
    };
    put("k_true", k_true as f64);
    put("k_found", rep.k as f64);
    put("k_ok", (rep.k == k_true) as u8 as f64);
    put("positions_ok", score.positions_ok as u8 as f64);
    put("values", score.values as f64);
    put("within_3se", score.within_3se as f64);
    put("wrong_flagged", score.wrong_flagged as u8 as f64);
    put("resolved", rep.resolved as u8 as f64);
    put("fits_data", rep.fits_data as u8 as f64);
    put(
        "sigma_ratio",
        if data.sigma() > 0.0 {
            rep.noise_sigma / data.sigma()
        } else {
            f64::NAN
        },
    );
    out.timings.insert("t_fit".into(), serde_json::json!(t_fit));
    Ok(out)
}
