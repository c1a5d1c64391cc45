//! Kind `realism`: the data-first fit of a record as it comes off a real
//! test ([`crate::study::realistic`]: damping that is not the paper's,
//! coloured noise, a sensor offset and drift, a blow that is not at the
//! record's start, physical units), generated independently of the fit's
//! model, fitted with the defaults plus what a user would know (`n`, the
//! nominal mass and stiffness, and the `options` of `springmass fit`, such
//! as `fit = "d"` when the damping is unknown), and scored against the
//! truth.
//!
//! The question it answers is the one a user cannot check: is the answer
//! right, and when it is not, does the report say so? Metrics: positions
//! right, values within 3 standard errors, the status, and whether a wrong
//! answer came with `converged` or `resolved` (the worst outcome).
//!
//! ```
//! use springmass::study::kinds::Kind;
//! let scene: toml::Value = toml::from_str("system = \"S1\"\ndeviation = \"pre-trigger\"\nlevel = 1e-3\nt_end = 100.0\ndt = 0.25").unwrap();
//! let out = Kind::Realism.run(&scene, 3)?;
//! assert_eq!(out.metrics["positions_ok"].as_f64(), Some(1.0));
//! assert_eq!(out.metrics["wrong_confident"].as_f64(), Some(0.0));
//! # Ok::<(), springmass::Error>(())
//! ```

use super::case::{CaseOutput, KindScene};
use crate::chain::{Chain, Units};
use crate::detect::data::observations::{Observations, Series};
use crate::detect::fit::options::FitSpec;
use crate::detect::fit::{fit, FitReport, Status};
use crate::error::{check_f64, Error, Result};
use crate::study::realistic::{record, Deviations, NAMES};
use crate::study::schema::FieldDoc;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// One paragraph for the schema page.
pub const SUMMARY: &str = "Simulates a record of a reference system with a real test's deviation (Rayleigh or between-storey damping, AR(1) noise, offset and drift, a pre-trigger segment or a late clock; physical units with mass and k) by a dense state space independent of the fit's model, fits it with the defaults plus the given options of `springmass fit`, and scores the answer: positions, values within 3 SE, and wrong answers reported as converged or resolved.";

/// The scene fields.
pub const FIELDS: &[FieldDoc] = &[
    FieldDoc::new("system", "string", "required", "S1, S2, S3, S4 (Table 1), C3a, C3b (three defects), k0..k3."),
    FieldDoc::new("deviation", "string", "\"none\"", "none, rayleigh, between, ar1-0.9, ar1-0.99, offset-drift, pre-trigger, late-clock."),
    FieldDoc::new("level", "float in [0, 1]", "required", "Noise standard deviation relative to the clean record's peak."),
    FieldDoc::new("t_end", "float > 0", "200", "Record length, in units of sqrt(mass / k)."),
    FieldDoc::new("dt", "float > 0", "0.2", "Sampling step, in units of sqrt(mass / k)."),
    FieldDoc::new("mass", "float > 0", "1", "Uniform mass (kg for an SI chain); defect masses scale with it."),
    FieldDoc::new("k", "float > 0", "1", "Uniform stiffness (N/m for an SI chain); the damping scales with sqrt(mass k)."),
    FieldDoc::opaque("options", "table", "{}", "Options of `springmass fit` as text, by their long names with `_` (e.g. `{ fit = \"d\", defects = \"auto\" }`); n, mass, k and d come from the scene."),
];

/// `(column, meaning)` of the metrics.
pub const METRICS: &[(&str, &str)] = &[
    ("k_true", "number of true defects"),
    ("k_found", "number of defects of the answer"),
    (
        "positions_ok",
        "1 when every position is right and none is extra",
    ),
    ("values", "fitted values at true positions"),
    (
        "within_3se",
        "of those, the truth within 3 reported standard errors",
    ),
    ("converged", "1 when the status is converged"),
    ("resolved", "1 when the fit says resolved"),
    ("mismatch", "1 when the status is model-mismatch"),
    (
        "wrong_confident",
        "1 when the positions are wrong and the status is converged or resolved is true",
    ),
    ("fits_data", "1 when the fit says the residual is noise"),
    ("t_fit", "wall time of the fit, seconds"),
];

/// The scene of a `realism` case.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// Reference system.
    pub system: String,
    /// The deviation ([`Deviations::named`]).
    #[serde(default = "default_none")]
    pub deviation: String,
    /// Relative noise level.
    pub level: f64,
    /// Record length, in units of `sqrt(mass / k)` (default 200).
    #[serde(default = "default_t_end")]
    pub t_end: f64,
    /// Sampling step, same units (default 0.2).
    #[serde(default = "default_dt")]
    pub dt: f64,
    /// Uniform mass (default 1).
    #[serde(default = "one")]
    pub mass: f64,
    /// Uniform stiffness (default 1).
    #[serde(default = "one")]
    pub k: f64,
    /// Options of the fit, as `springmass fit` takes them.
    #[serde(default)]
    pub options: FitSpec,
}

fn default_none() -> String {
    "none".into()
}
fn default_t_end() -> f64 {
    200.0
}
fn default_dt() -> f64 {
    0.2
}
fn one() -> f64 {
    1.0
}

impl Scene {
    /// `sqrt(mass / k)`: the chain's time scale.
    fn time_unit(&self) -> f64 {
        (self.mass / self.k).sqrt()
    }

    /// The reference system scaled to the scene's mass and stiffness (its
    /// damping by `sqrt(mass k)`, so that every damping ratio is kept).
    ///
    /// # Errors
    /// An unknown system (field `system`).
    pub fn truth(&self) -> Result<Chain> {
        let unit = super::noise::truth(&self.system)?;
        let c = (self.mass * self.k).sqrt();
        let gamma = unit.gamma() * c;
        unit.to_si(&Units::new(self.mass, self.k, c)?)?
            .with_gamma(gamma)
    }

    /// What the user tells the fit: the options, with n, mass, k and the
    /// nominal damping of the truth's uniform part.
    fn spec(&self, truth: &Chain) -> FitSpec {
        FitSpec {
            n: truth.n(),
            mass: Some(truth.mass()),
            k: Some(truth.k()),
            d: self.options.d.or(Some(truth.d())),
            gamma: self.options.gamma.or(Some(truth.gamma())),
            ..self.options.clone()
        }
    }
}

impl KindScene for Scene {
    const FIELDS: &'static [FieldDoc] = FIELDS;

    fn problems(&self) -> Vec<Error> {
        let mut out = Vec::new();
        if let Err(e) = super::noise::truth(&self.system) {
            out.push(e);
        }
        if !NAMES.contains(&self.deviation.as_str()) {
            out.push(Error::invalid(
                "deviation",
                &self.deviation,
                NAMES.join(", "),
            ));
        }
        let checks = [
            (
                "level",
                self.level,
                (0.0..=1.0).contains(&self.level),
                "in [0, 1]",
            ),
            (
                "t_end",
                self.t_end,
                self.t_end > 0.0 && self.t_end <= 1e5,
                "in (0, 1e5]",
            ),
            (
                "dt",
                self.dt,
                self.dt > 0.0 && self.t_end / self.dt <= 1e6,
                "> 0, at most 1e6 samples",
            ),
            ("mass", self.mass, self.mass > 0.0, "> 0"),
            ("k", self.k, self.k > 0.0, "> 0"),
        ];
        for (field, v, ok, allowed) in checks {
            if let Err(e) = check_f64(field, v, ok, allowed) {
                out.push(e);
            }
        }
        let spec = FitSpec {
            n: 1,
            ..self.options.clone()
        };
        if let Err(e) = spec.options() {
            out.push(e);
        }
        out
    }
}

/// The record of `s` and the fit of it.
///
/// # Errors
/// As [`record`] and [`fit`].
pub fn fit_case(s: &Scene, seed: u64) -> Result<(Chain, FitReport)> {
    let truth = s.truth()?;
    let unit = s.time_unit();
    let dev = Deviations::named(&s.deviation, unit)?;
    let (t, x) = record(&truth, &dev, s.t_end * unit, s.dt * unit, s.level, seed)?;
    let spec = s.spec(&truth);
    let (model, mut opts) = spec.build()?;
    opts.parallel = false;
    let obs = Observations::Series(
        Series::on_axis(t, x, opts.noise.known())?.with_measurement(spec.measurement(None)?)?,
    );
    let rep = fit(&obs, &model, &opts)?;
    Ok((truth, rep))
}

/// Run one case.
///
/// # Errors
/// As [`fit_case`].
pub fn run(s: &Scene, seed: u64) -> Result<CaseOutput> {
    let t0 = Instant::now();
    let (truth, rep) = fit_case(s, seed)?;
    let t_fit = t0.elapsed().as_secs_f64();
    let score = super::noise::score(&rep, &truth);
    let converged = rep.status == Status::Converged;
    let mut out = CaseOutput::default();
    let mut put = |k: &str, v: f64| {
        out.metrics.insert(k.into(), serde_json::json!(v));
    };
    let flag = |b: bool| f64::from(u8::from(b));
    put("k_true", truth.defects().len() as f64);
    put("k_found", rep.k as f64);
    put("positions_ok", flag(score.positions_ok));
    put("values", score.values as f64);
    put("within_3se", score.within_3se as f64);
    put("converged", flag(converged));
    put("resolved", flag(rep.resolved));
    put("mismatch", flag(rep.status == Status::ModelMismatch));
    put(
        "wrong_confident",
        flag(!score.positions_ok && (converged || rep.resolved)),
    );
    put("fits_data", flag(rep.fits_data));
    out.timings.insert("t_fit".into(), serde_json::json!(t_fit));
    Ok(out)
}
