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
//! the estimated over the true noise level; with `fit = ["d"]` the fitted
//! damping and its standard error. The noise study
//! (`configs/studies/noise-study.toml`, the data-first defaults, and
//! `configs/studies/noise-misfits.toml`, every misfit over eight noise
//! levels) is a sweep of this kind; `springmass noise-study` runs them.
//!
//! ```
//! use springmass::study::kinds::Kind;
//! let scene: toml::Value = toml::from_str("system = \"S1\"\nlevel = 1e-3\nt_end = 100.0\ndt = 0.25").unwrap();
//! let out = Kind::Noise.run(&scene, 3)?;
//! assert_eq!(out.metrics["positions_ok"].as_f64(), Some(1.0));
//! # Ok::<(), springmass::Error>(())
//! ```

use super::case::{range_problems, CaseOutput, KindScene};
use crate::chain::Chain;
use crate::detect::data::observations::{Observations, Series};
use crate::detect::data::series::TimeData;
use crate::detect::fit::{parse_params, FitReport, Model};
use crate::detect::misfit::MisfitKind;
use crate::error::{check_f64, Error, Result};
use crate::noise::NoiseLevel;
use crate::study::schema::FieldDoc;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// One paragraph for the schema page.
pub const SUMMARY: &str = "Simulates a noisy record of a reference system (S1-S4, C3a, C3b, or k0-k3 with 0 to 3 defects), fits it with the data-first fit told only n and d (and k when defects = \"given\"; d fitted too with fit = [\"d\"]), noise level estimated or given, and scores the answer against the truth.";

/// The scene fields.
pub const FIELDS: &[FieldDoc] = &[
    FieldDoc::new("system", "string", "required", "S1, S2, S3, S4 (Table 1), C3a, C3b (three defects), or k0, k1, k2, k3 (n = 10 with 0 to 3 defects, for the choice of k)."),
    FieldDoc::new("level", "float in [0, 1]", "required", "Noise standard deviation relative to max |x_1|."),
    FieldDoc::new("t_end", "float > 0", "200", "Record length."),
    FieldDoc::new("dt", "float > 0", "0.2", "Sampling step."),
    FieldDoc::new("defects", "\"given\" | \"auto\"", "\"given\"", "Tell the fit the true number of defects, or let it choose among 0..=4 by BIC."),
    FieldDoc::new("misfit", "\"time\" | \"bromwich\" | \"real-axis\" | \"default\"", "\"default\"", "The fit's misfit (default: the fit's default for a series, time)."),
    FieldDoc::new("noise", "\"auto\" | \"given\"", "\"auto\"", "Estimate the noise level (auto) or tell the fit the true one."),
    FieldDoc::new("fit", "array of \"d\", \"gamma\", \"k\", \"mass\"", "[]", "Uniform chain parameters fitted with the defects (at most three)."),
    FieldDoc::new("d_start", "float >= 0", "the truth's d", "The damping the fit is told, or starts from when d is fitted."),
    FieldDoc::new("profile", "\"none\" | \"masses\" | \"springs\" | \"both\"", "\"none\"", "Fit every mass (spring, both) instead of a few defects (the whole-profile inversion); scored on the visible values."),
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
    (
        "within_2se",
        "fitted values at true positions with the truth within 2 reported standard errors",
    ),
    ("d_fit", "fitted damping (NaN when d is not fitted)"),
    ("d_se", "its standard error"),
    (
        "d_within_3se",
        "1 when the true d is within 3 standard errors of d_fit",
    ),
    ("t_fit", "wall time of the fit, seconds"),
    (
        "visible",
        "profile: values the data resolve (NaN for a defect fit)",
    ),
    (
        "depth",
        "profile: distance from the sensor up to which every value is visible",
    ),
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
    /// Chain parameters fitted with the defects (default none).
    #[serde(default)]
    pub fit: Vec<String>,
    /// The damping the fit is told or starts from (default the truth's).
    #[serde(default)]
    pub d_start: Option<f64>,
    /// `none` (default: the defect fit), or the whole profile fitted:
    /// `masses`, `springs`, `both`.
    #[serde(default = "default_none")]
    pub profile: String,
}

serde_defaults! {
    fn default_none() -> String = "none".into();
    fn default_t_end() -> f64 = 200.0;
    fn default_dt() -> f64 = 0.2;
    fn default_given() -> String = "given".into();
    fn default_misfit() -> String = "default".into();
    fn default_auto() -> String = "auto".into();
}

/// The truth of a reference system by name ([`crate::scenes::NOISE_SYSTEMS`]
/// and [`crate::scenes::SELECTION`]).
///
/// # Errors
/// An unknown name (field `system`).
pub fn truth(name: &str) -> Result<Chain> {
    let known = crate::scenes::NOISE_SYSTEMS
        .iter()
        .chain(&crate::scenes::SELECTION);
    match known.clone().find(|s| **s == name) {
        Some(s) => crate::scenes::by_name(s),
        None => Err(Error::invalid(
            "system",
            name,
            known.copied().collect::<Vec<_>>().join(", "),
        )),
    }
}

/// A noisy record of `truth`: `x_1(t)` on `0, dt, ..., t_end` from the
/// simulation, plus white noise of standard deviation `level max|x_1|`
/// drawn with `seed`.
///
/// # Errors
/// As [`TimeData::simulate`].
pub fn noisy_record(truth: &Chain, t_end: f64, dt: f64, level: f64, seed: u64) -> Result<TimeData> {
    TimeData::simulate(truth, t_end, dt, NoiseLevel::RelativeMax(level), seed)
}

/// How a data-first answer compares with the truth.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Score {
    /// Every true position found, none extra.
    pub positions_ok: bool,
    /// Fitted values at true positions.
    pub values: usize,
    /// Of which the truth lies within 2 reported standard errors.
    pub within_2se: usize,
    /// Of which the truth lies within 3 reported standard errors.
    pub within_3se: usize,
    /// A wrong answer flagged resolved, or a wrong position flagged identifiable.
    pub wrong_flagged: bool,
}

/// Score `rep` against `truth` (positions of every kind, values within 2
/// and 3 SE).
pub fn score(rep: &FitReport, truth: &Chain) -> Score {
    let t: Vec<(usize, f64)> = truth
        .defects()
        .iter()
        .map(|d| (d.at(), d.value()))
        .collect();
    let mut tp: Vec<usize> = t.iter().map(|x| x.0).collect();
    tp.sort_unstable();
    let mut fp: Vec<usize> = rep.found().iter().map(|d| d.at()).collect();
    fp.sort_unstable();
    let positions_ok = tp == fp;
    let (mut values, mut within_2se, mut within_3se) = (0, 0, 0);
    let mut wrong_flagged = !positions_ok && rep.resolved;
    for d in rep.defects.iter().filter(|d| !d.known) {
        match t.iter().find(|x| x.0 == d.at) {
            Some(&(_, v)) => {
                values += 1;
                within_2se += usize::from((d.value - v).abs() <= 2.0 * d.se);
                within_3se += usize::from((d.value - v).abs() <= 3.0 * d.se);
            }
            None => wrong_flagged |= d.identifiable,
        }
    }
    Score {
        positions_ok,
        values,
        within_2se,
        within_3se,
        wrong_flagged,
    }
}

/// The data-first fit of a noisy record of `truth` as a case of this kind
/// runs it: told only the truth's uniform part (n, and d = `s.d_start` or
/// the truth's), the number of defects when `s.defects = "given"`
/// (otherwise chosen by BIC among `0..=min(4, n)`), the misfit, the true
/// noise level when `s.noise = "given"`, and the chain parameters `s.fit`
/// to fit. The defects are sought as masses (the records' defects are
/// masses; the study compares noise handling, not kinds). Sequential
/// (studies run cases in parallel).
///
/// # Errors
/// As [`crate::detect::fit::fit`]; a bad `fit` or `d_start`.
pub fn fit_record(s: &Scene, truth: &Chain, data: &TimeData) -> Result<FitReport> {
    use crate::detect::fit::{fit, DefectCount, FitOptions, NoiseSpec, DEFAULT_K_MAX};
    let (obs, sigma) = observations(s, data)?;
    let misfit = match s.misfit.as_str() {
        "default" => None,
        m => Some(MisfitKind::parse(m)?),
    };
    let opts = FitOptions {
        defects: if s.defects == "given" {
            DefectCount::Exactly(truth.defects().len())
        } else {
            DefectCount::Auto {
                k_max: DEFAULT_K_MAX.min(truth.n()),
            }
        },
        kinds: crate::detect::unknowns::KindChoice::Mass,
        noise: sigma.map_or(NoiseSpec::Auto, NoiseSpec::Sigma),
        misfit,
        parallel: false,
        ..FitOptions::default()
    };
    fit(&obs, &told_model(s, truth)?, &opts)
}

/// The record as the fit's observations, and the noise level the fit is
/// told: the true one when `s.noise = "given"` (and the record is noisy).
///
/// # Errors
/// As [`Series::new`].
fn observations(s: &Scene, data: &TimeData) -> Result<(Observations, Option<f64>)> {
    let sigma = (s.noise == "given" && data.sigma() > 0.0).then_some(data.sigma());
    let obs = Observations::Series(Series::new(data.t().to_vec(), data.y().to_vec(), sigma)?);
    Ok((obs, sigma))
}

/// The model the fit is told: the truth's uniform part, with d =
/// `s.d_start` when given, fitting the chain parameters `s.fit`.
///
/// # Errors
/// A bad `d_start` or `fit`.
fn told_model(s: &Scene, truth: &Chain) -> Result<Model> {
    let mut model = Model::from_chain(&truth.uniform());
    if let Some(d) = s.d_start {
        model = model.with_d(d)?;
    }
    model.fitting(&parse_params(&s.fit.join(","))?)
}

/// The failed range checks of a record's `level`, `t_end` and `dt` (of
/// this kind and of kind `realism`); `dt_allowed` words dt's check.
pub(super) fn record_problems(level: f64, t_end: f64, dt: f64, dt_allowed: &str) -> Vec<Error> {
    range_problems(&[
        ("level", level, (0.0..=1.0).contains(&level), "in [0, 1]"),
        ("t_end", t_end, t_end > 0.0 && t_end <= 1e5, "in (0, 1e5]"),
        ("dt", dt, dt > 0.0 && t_end / dt <= 1e6, dt_allowed),
    ])
}

impl KindScene for Scene {
    const FIELDS: &'static [FieldDoc] = FIELDS;

    fn problems(&self) -> Vec<Error> {
        let mut out = Vec::new();
        if let Err(e) = truth(&self.system) {
            out.push(e);
        }
        out.extend(record_problems(
            self.level,
            self.t_end,
            self.dt,
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
        if let Err(e) = parse_params(&self.fit.join(","))
            .and_then(|p| crate::detect::fit::Model::new(1)?.fitting(&p))
        {
            out.push(e);
        }
        if let Some(d) = self.d_start {
            if let Err(e) = check_f64("d_start", d, d >= 0.0, ">= 0") {
                out.push(e);
            }
        }
        if self.profile != "none" {
            if let Err(e) = crate::detect::fit::profile::ProfileMode::parse(&self.profile) {
                out.push(Error::invalid(
                    "profile",
                    &self.profile,
                    format!("none, masses, springs or both ({e})"),
                ));
            }
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
    let data = noisy_record(&truth, s.t_end, s.dt, s.level, seed)?;
    if s.profile != "none" {
        return run_profile(s, &truth, &data);
    }
    let k_true = truth.defects().len();
    let t0 = Instant::now();
    let rep = fit_record(s, &truth, &data)?;
    let t_fit = t0.elapsed().as_secs_f64();
    let score = score(&rep, &truth);
    let mut out = CaseOutput::default();
    out.metric("k_true", k_true as f64);
    out.metric("k_found", rep.k as f64);
    out.metric("k_ok", (rep.k == k_true) as u8 as f64);
    out.metric("positions_ok", score.positions_ok as u8 as f64);
    out.metric("values", score.values as f64);
    out.metric("within_2se", score.within_2se as f64);
    out.metric("within_3se", score.within_3se as f64);
    out.metric("wrong_flagged", score.wrong_flagged as u8 as f64);
    out.metric("resolved", rep.resolved as u8 as f64);
    out.metric("fits_data", rep.fits_data as u8 as f64);
    out.metric("visible", f64::NAN);
    out.metric(
        "depth",
        rep.visibility
            .as_ref()
            .and_then(|v| v.depth)
            .map_or(f64::NAN, |d| d as f64),
    );
    out.metric("sigma_ratio", sigma_ratio(rep.noise_sigma, &data));
    let d = rep.params.iter().find(|p| p.name == "d");
    out.metric("d_fit", d.map_or(f64::NAN, |p| p.value));
    out.metric("d_se", d.map_or(f64::NAN, |p| p.se));
    out.metric(
        "d_within_3se",
        d.map_or(f64::NAN, |p| {
            f64::from(u8::from((p.value - truth.d()).abs() <= 3.0 * p.se))
        }),
    );
    out.timing("t_fit", t_fit);
    Ok(out)
}

/// The estimated over the true noise level (NaN for a noise-free record).
fn sigma_ratio(estimated: f64, data: &TimeData) -> f64 {
    if data.sigma() > 0.0 {
        estimated / data.sigma()
    } else {
        f64::NAN
    }
}

/// A `profile` case: the whole-profile inversion of the record, told the
/// truth's uniform part (n, d = `s.d_start` or the truth's); scored on the
/// visible values (`values`, `within_2se`, `within_3se`), and
/// `positions_ok` when the values more than 3 SE from uniform are exactly
/// the true defects' (of the profiled kind).
fn run_profile(s: &Scene, truth: &Chain, data: &TimeData) -> Result<CaseOutput> {
    use crate::detect::fit::fit_profile;
    use crate::detect::fit::profile::{ProfileMode, ProfileOptions};
    use crate::detect::fit::NoiseSpec;
    let (obs, sigma) = observations(s, data)?;
    let model = told_model(s, truth)?;
    let mut opts = ProfileOptions::new(ProfileMode::parse(&s.profile)?);
    opts.noise = sigma.map_or(NoiseSpec::Auto, NoiseSpec::Sigma);
    let t0 = Instant::now();
    let rep = fit_profile(&obs, &model, &opts)?;
    let t_fit = t0.elapsed().as_secs_f64();
    let true_value = |kind: &str, at: usize| {
        truth
            .defects()
            .iter()
            .find(|d| d.kind() == kind && d.at() == at)
            .map(|d| d.value())
    };
    let (mut values, mut w2, mut w3) = (0usize, 0usize, 0usize);
    let mut positions_ok = true;
    for e in rep.elements.iter().filter(|e| e.visible) {
        let v = true_value(e.kind, e.at).unwrap_or(e.uniform);
        values += 1;
        w2 += usize::from((e.value - v).abs() <= 2.0 * e.se);
        w3 += usize::from((e.value - v).abs() <= 3.0 * e.se);
        let flagged = e.significance() > 3.0;
        positions_ok &= flagged == true_value(e.kind, e.at).is_some();
    }
    let profiled = |kind: &str| rep.elements.iter().any(|e| e.kind == kind);
    // a true defect of the profiled kind that is not visible is missed
    positions_ok &= truth.defects().iter().all(|d| {
        !profiled(d.kind())
            || rep
                .elements
                .iter()
                .any(|e| e.kind == d.kind() && e.at == d.at() && e.visible)
    });
    let mut out = CaseOutput::default();
    let k_true = truth.defects().len() as f64;
    out.metric("k_true", k_true);
    out.metric("k_found", f64::NAN);
    out.metric("k_ok", f64::NAN);
    out.metric("positions_ok", f64::from(u8::from(positions_ok)));
    out.metric("values", values as f64);
    out.metric("within_2se", w2 as f64);
    out.metric("within_3se", w3 as f64);
    out.metric("wrong_flagged", f64::NAN);
    out.metric("resolved", f64::NAN);
    out.metric("fits_data", f64::from(u8::from(rep.fits_data)));
    out.metric("sigma_ratio", sigma_ratio(rep.noise_sigma, data));
    out.metric("d_fit", f64::NAN);
    out.metric("d_se", f64::NAN);
    out.metric("d_within_3se", f64::NAN);
    out.metric("visible", rep.visible_count() as f64);
    out.metric("depth", rep.visible_depth.unwrap_or(f64::NAN));
    out.timing("t_fit", t_fit);
    Ok(out)
}
