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

use super::case::{range_problems, CaseOutput, KindScene};
use crate::chain::{Chain, Units};
use crate::detect::data::observations::{Observations, Series};
use crate::detect::fit::options::FitSpec;
use crate::detect::fit::{fit, FitReport, Status};
use crate::error::{Error, Result};
use crate::study::realistic::{record, Deviations};
use crate::study::schema::FieldDoc;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// One paragraph for the schema page.
pub const SUMMARY: &str = "Simulates a record of a reference system with a real test's deviation (Rayleigh, between-storey or modal damping, AR(1) noise, offset and drift, a pre-trigger segment or a late clock; physical units with mass and k) by a dense state space independent of the fit's model, fits it with the defaults plus the given options of `springmass fit`, and scores the answer: positions, values within 3 SE, and wrong answers reported as converged or resolved.";

/// The scene fields.
pub const FIELDS: &[FieldDoc] = &[
    FieldDoc::new("system", "string", "required", "S1, S2, S3, S4 (Table 1), C3a, C3b (three defects), k0..k3, or random:N (N masses, one or two mass defects at positions and factors drawn from the case's seed: factors in 0.5..0.8 or 1.25..2)."),
    FieldDoc::new("deviation", "string", "\"none\"", "none, rayleigh, between, modal, modal-modes, ar1-0.9, ar1-0.99, offset-drift, pre-trigger, late-clock, or several joined by + that set different things (rayleigh+ar1-0.9+offset-drift)."),
    FieldDoc::new("level", "float in [0, 1]", "required", "Noise standard deviation relative to the clean record's peak."),
    FieldDoc::new("t_end", "float > 0", "200", "Record length, in units of sqrt(mass / k)."),
    FieldDoc::new("dt", "float > 0", "0.2", "Sampling step, in units of sqrt(mass / k)."),
    FieldDoc::new("mass", "float > 0", "1", "Uniform mass (kg for an SI chain); defect masses scale with it."),
    FieldDoc::new("k", "float > 0", "1", "Uniform stiffness (N/m for an SI chain); the damping scales with sqrt(mass k)."),
    FieldDoc::new("options", "table", "{}", "Options of `springmass fit` as text, by their long names with `_` (e.g. `{ fit = \"d\", defects = \"auto\" }`); n, mass, k and d come from the scene.").opaque(),
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
    (
        "in_interval",
        "fitted values at true positions whose interval (at the fit's level, 0.9 unless options.level) holds the truth",
    ),
    ("interval_level", "the level of the intervals"),
    (
        "answer_p",
        "the probability the fit gives its answer (NaN without a posterior)",
    ),
    (
        "truth_p",
        "the probability the fit gives the true positions (0 when not among its hypotheses)",
    ),
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

serde_defaults! {
    fn default_none() -> String = "none".into();
    fn default_t_end() -> f64 = 200.0;
    fn default_dt() -> f64 = 0.2;
    fn one() -> f64 = 1.0;
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
        self.truth_for(0)
    }

    /// The truth of the case of `seed`: [`Scene::truth`], or for
    /// `random:N` a chain of `N` masses with one or two mass defects drawn
    /// from `seed`.
    ///
    /// # Errors
    /// An unknown system (field `system`).
    pub fn truth_for(&self, seed: u64) -> Result<Chain> {
        let unit = match random_size(&self.system)? {
            Some(n) => random_chain(n, seed)?,
            None => super::noise::truth(&self.system)?,
        };
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
        match random_size(&self.system) {
            Ok(Some(_)) => {}
            Ok(None) => {
                if let Err(e) = super::noise::truth(&self.system) {
                    out.push(e);
                }
            }
            Err(e) => out.push(e),
        }
        if let Err(e) = Deviations::named(&self.deviation, 1.0) {
            out.push(e);
        }
        out.extend(super::noise::record_problems(
            self.level,
            self.t_end,
            self.dt,
            "> 0, at most 1e6 samples",
        ));
        out.extend(range_problems(&[
            ("mass", self.mass, self.mass > 0.0, "> 0"),
            ("k", self.k, self.k > 0.0, "> 0"),
        ]));
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
    let truth = s.truth_for(seed)?;
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
    let flag = |b: bool| f64::from(u8::from(b));
    out.metric("k_true", truth.defects().len() as f64);
    out.metric("k_found", rep.k as f64);
    out.metric("positions_ok", flag(score.positions_ok));
    out.metric("values", score.values as f64);
    out.metric("within_3se", score.within_3se as f64);
    out.metric("converged", flag(converged));
    out.metric("resolved", flag(rep.resolved));
    out.metric("mismatch", flag(rep.status == Status::ModelMismatch));
    out.metric(
        "wrong_confident",
        flag(!score.positions_ok && (converged || rep.resolved)),
    );
    out.metric("fits_data", flag(rep.fits_data));
    out.metric("in_interval", in_interval(&rep, &truth) as f64);
    out.metric("interval_level", rep.level);
    let (answer_p, truth_p) = probabilities(&rep, &truth);
    out.metric("answer_p", answer_p);
    out.metric("truth_p", truth_p);
    out.timing("t_fit", t_fit);
    Ok(out)
}

/// `N` of `random:N` (2..=60), or `None` for a named system.
///
/// # Errors
/// A `random:` without a size in range (field `system`).
fn random_size(system: &str) -> Result<Option<usize>> {
    let Some(n) = system.strip_prefix("random:") else {
        return Ok(None);
    };
    match n.parse::<usize>() {
        Ok(n) if (2..=60).contains(&n) => Ok(Some(n)),
        _ => Err(Error::invalid(
            "system",
            system,
            "random:N with 2 <= N <= 60 masses",
        )),
    }
}

/// The paper's chain of `n` masses with one or two mass defects at
/// positions and factors (0.5..0.8 or 1.25..2) drawn from `seed`.
fn random_chain(n: usize, seed: u64) -> Result<Chain> {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed ^ 0x5EED_CA1B);
    let k = if rng.random_bool(0.5) { 1 } else { 2 };
    let mut at: Vec<usize> = Vec::new();
    while at.len() < k.min(n) {
        let p = rng.random_range(1..=n);
        if !at.contains(&p) {
            at.push(p);
        }
    }
    let defects: Vec<crate::chain::Defect> = at
        .iter()
        .map(|&a| {
            let m = if rng.random_bool(0.5) {
                rng.random_range(0.5..0.8)
            } else {
                rng.random_range(1.25..2.0)
            };
            crate::chain::Defect::Mass { at: a, m }
        })
        .collect();
    Chain::paper(n)?.with_defects(defects)
}

/// Fitted values at true positions whose interval holds the truth.
fn in_interval(rep: &FitReport, truth: &Chain) -> usize {
    rep.defects
        .iter()
        .filter(|d| !d.known)
        .filter(|d| {
            let t = truth
                .defects()
                .iter()
                .find(|t| t.at() == d.at && t.kind() == d.kind);
            match (t, d.interval) {
                (Some(t), Some([lo, hi])) => lo <= t.value() && t.value() <= hi,
                _ => false,
            }
        })
        .count()
}

/// The probability of the fit's answer and of the truth's positions.
fn probabilities(rep: &FitReport, truth: &Chain) -> (f64, f64) {
    let Some(post) = &rep.posterior else {
        return (f64::NAN, f64::NAN);
    };
    let key = |d: &[crate::chain::Defect]| {
        let mut k: Vec<(&str, usize)> = d.iter().map(|d| (d.kind(), d.at())).collect();
        k.sort_unstable();
        k
    };
    let t = key(truth.defects());
    let truth_p = post
        .hypotheses
        .iter()
        .filter(|h| key(&h.defects) == t)
        .map(|h| h.probability)
        .sum();
    (post.answer_probability, truth_p)
}
