//! The fit scene: a TOML file describing the chain, the data, the unknowns,
//! the residual and the search.
//!
//! ```toml
//! [truth]            # or [chain]: the chain (crate::ChainSpec); defects = the TRUE defects
//! n = 20             #   used to synthesise data (ignored by the model, which
//! d = 0.1            #   is the uniform part n, k, d, gamma, mass)
//! defects = [ { kind = "mass", at = 8, m = 5.0 }, { kind = "mass", at = 15, m = 2.0 } ]
//!
//! [data]             # optional
//! source = "exact"   # "exact": the closed-form model of [chain];
//!                    # "simulated": x_1(t) of [chain] on [0, t_end] step dt, transformed;
//!                    # "series": a CSV (path, column = "x1"), transformed
//! noise = 0.0        # exact: relative Laplace-domain noise; simulated: absolute
//!                    # noise on the samples; series: the samples' known noise
//! seed = 0           # noise seed, default 0
//! # t_end = 300.0    # simulated
//! # dt = 0.05        # simulated
//!
//! # relative = false # simulated/series: noise relative to max |x_1|
//! # observe = 1                   # simulated/series: the observed mass
//! # observe_kind = "acceleration" # displacement (default) | velocity | acceleration
//! # hammer_width = 0.05           # simulated: a half-sine blow instead of the delta
//! # force_column = "f"            # series: the measured force on mass 1
//! # observe = [1, 30, 60]         # several sensors, one joint fit (series: column = [..])
//! # records = 3                   # simulated: several records (series: path = [..])
//! # source = "modes"              # measured modes: path = "modes.csv", or simulated
//! #                               #   modes = 3, floors = [2, 4], frequency_noise, shape_noise
//!
//! [unknowns]         # optional; see crate::detect::unknowns::UnknownsSpec
//! k = 2              # default: number of defects in [chain]
//! mass_bounds = [0.1, 100]
//! # kind = "mass"    # "mass" | "spring" | "damper" | "ground" | "any" (per defect:
//! #                  #   [[unknowns.defects]] kind = ...)
//! # chain = []       # chain parameters fitted too: "d", "gamma", "k", "mass"
//! # chain_start = { d = 0.2 }     # their starting values
//! # spring_bounds = [0.01, 100]   # damper_bounds = [0, 100]
//!
//! [misfit]           # optional; see crate::detect::misfit::MisfitSpec
//! kind = "real-axis" # or "bromwich", or "time" (simulated or series data)
//! panels = 10
//! per_panel = 8
//! s_max = 300
//!
//! [search]           # optional; see SearchSpec
//! method = "enumerate"   # a name of detect::search::SEARCHES (ga, nelder-mead, pso, ...)
//! seed = 0
//!
//! [profile]          # optional; see ProfileSpec: fit every mass or spring
//! mode = "masses"    #   "none" (default: the defect fit) | "masses" | "springs" | "both"
//! # change = 0.1     #   the relative change the visibility is stated for
//! # penalty = 1e-3   #   a fixed penalty weight (default: continuation to the noise)
//! ```
//!
//! Every table rejects unknown fields.
//!
//! A scene is a description, not a fitter: it imports nothing of the fit.
//! The scene path of the fit (`detect::fit::paper::fit`, one layer up)
//! turns it into the data-first fit's observations, model and options, and
//! compares the answer with the scene's truth. A scene with another defect
//! kind, chain parameters or the time misfit ([`FitScene::is_general`]) is
//! fitted on the chi-square of its data (unknowns from
//! [`FitScene::unknowns`], series from [`FitScene::time_data`]); see
//! `configs/scenes/fit-spring.toml` and `configs/scenes/fit-any.toml`.
//!
//! ```
//! use springmass::detect::scene::FitScene;
//! let scene = FitScene::from_toml("[chain]\nn = 5\ndefects = [{ kind = \"mass\", at = 2, m = 3.0 }]\n")?;
//! assert_eq!(scene.unknowns()?.k(), 1);
//! assert!(FitScene::from_toml("[chain]\nn = 5\n[search]\nmethd = 1\n").is_err());
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::chain::{Chain, ChainSpec};
use crate::detect::data::exact::Data;
use crate::detect::data::measurement::{hammer, Measurement, Sensor};
use crate::detect::data::observations::{LaplaceValues, Observations, Series};
use crate::detect::data::series::TimeData;
use crate::detect::misfit::{MisfitKind, MisfitSpec};
use crate::detect::search::enumerate::EnumerateOptions;
use crate::detect::search::FitMethod;
use crate::detect::unknowns::{DefectKind, Unknowns, UnknownsSpec};
use crate::error::{Error, Result};
use num_complex::Complex64;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

mod data;
mod modes;

pub use data::{DataSourceKind, DataSpec, OneOrMany, MAX_RECORDS};

/// The `[search]` table.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SearchSpec {
    /// A search of [`crate::detect::search::SEARCHES`] (default `enumerate`).
    #[serde(default)]
    pub method: FitMethod,
    /// Seed of stochastic methods (default 0).
    #[serde(default)]
    pub seed: u64,
    /// Evaluation budget of stochastic methods (default 20 000).
    #[serde(default = "default_max_evals")]
    pub max_evals: usize,
    /// Hypotheses reported (best and runners-up) (default 5).
    #[serde(default = "default_keep")]
    pub keep: usize,
    /// Enumeration: starting values per unknown mass (default 2).
    #[serde(default = "default_starts")]
    pub starts: usize,
    /// Enumeration: largest exhaustive set count before the beam search (default 200 000).
    #[serde(default = "default_max_sets")]
    pub max_sets: usize,
    /// Enumeration: beam width (default 16).
    #[serde(default = "default_beam")]
    pub beam: usize,
    /// Use all cores (default true).
    #[serde(default = "default_true")]
    pub parallel: bool,
    /// Enumeration: rank every position set (default false: from three
    /// defects on chains of 40 masses or more, the greedy search runs first
    /// and its answer is kept when its residual is at the data's error
    /// floor, which no set can beat; `SceneReport::certified`).
    #[serde(default)]
    pub exhaustive: bool,
    /// Record the optimizer's trace (default false).
    #[serde(default)]
    pub trace: bool,
}

fn default_max_evals() -> usize {
    20_000
}
fn default_keep() -> usize {
    5
}
fn default_starts() -> usize {
    2
}
fn default_max_sets() -> usize {
    200_000
}
fn default_beam() -> usize {
    16
}
fn default_true() -> bool {
    true
}

impl Default for SearchSpec {
    fn default() -> Self {
        SearchSpec {
            method: FitMethod::Enumerate,
            seed: 0,
            max_evals: default_max_evals(),
            keep: default_keep(),
            starts: default_starts(),
            max_sets: default_max_sets(),
            beam: default_beam(),
            parallel: true,
            exhaustive: false,
            trace: false,
        }
    }
}

/// Options of the scene's fit (`detect::fit::paper::fit`), from its
/// `[search]` with [`FitScene::options`]; owned by the scene.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneOptions {
    /// The method.
    pub method: FitMethod,
    /// Seed of stochastic methods.
    pub seed: u64,
    /// Evaluation budget of stochastic methods.
    pub max_evals: usize,
    /// Record the optimizer's trace.
    pub trace: bool,
    /// Enumeration options (`keep` also sets the number of hypotheses reported).
    pub enumerate: EnumerateOptions,
    /// Rank every position set, with no certified greedy search first
    /// (`search.exhaustive`).
    pub exhaustive: bool,
}

impl Default for SceneOptions {
    fn default() -> Self {
        FitScene::synthetic(&crate::Chain::new(1).expect("n = 1 is valid")).options()
    }
}

/// A fit scene (see the module documentation for the format).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FitScene {
    /// The chain; its defects are the truth used for synthetic data and for
    /// scoring (written `[truth]` or, as before, `[chain]`).
    #[serde(alias = "truth")]
    pub chain: ChainSpec,
    /// The data.
    #[serde(default)]
    pub data: DataSpec,
    /// The unknowns.
    #[serde(default)]
    pub unknowns: UnknownsSpec,
    /// The residual.
    #[serde(default)]
    pub misfit: MisfitSpec,
    /// The search.
    #[serde(default)]
    pub search: SearchSpec,
    /// The whole-profile inversion instead of the defect fit.
    #[serde(default)]
    pub profile: ProfileSpec,
}

/// The `[profile]` table: every mass (spring, both) of the chain fitted
/// instead of a few defects (`detect::fit::profile`), on the scene's data.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ProfileSpec {
    /// `none` (default), `masses`, `springs` or `both`.
    pub mode: Option<String>,
    /// The relative change the visibility is stated for (default 0.1).
    pub change: Option<f64>,
    /// A fixed penalty weight instead of the continuation (default none).
    pub penalty: Option<f64>,
}

impl ProfileSpec {
    /// The mode's name when a profile is asked for (`None` for `none` or
    /// no table).
    pub fn requested(&self) -> Option<&str> {
        self.mode.as_deref().filter(|m| m.trim() != "none")
    }

    /// Check `change` and `penalty` (the mode's name is checked where it
    /// is parsed).
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming `profile.change` or `profile.penalty`.
    pub fn check(&self) -> Result<()> {
        for (field, v) in [
            ("profile.change", self.change),
            ("profile.penalty", self.penalty),
        ] {
            if let Some(v) = v {
                crate::error::check_f64(field, v, v > 0.0, "> 0 and finite")?;
            }
        }
        Ok(())
    }
}

impl FitScene {
    /// Parse a scene.
    ///
    /// # Errors
    /// [`Error::Parse`] with the TOML message (unknown fields included).
    pub fn from_toml(text: &str) -> Result<FitScene> {
        toml::from_str(text).map_err(|e| Error::parse("fit scene", "", e.to_string().trim()))
    }

    /// Read and parse a scene file.
    ///
    /// # Errors
    /// [`Error::Io`]; [`Error::Parse`].
    pub fn load(path: impl AsRef<Path>) -> Result<FitScene> {
        let text = crate::io::read_to_string_capped(path.as_ref())?;
        toml::from_str(&text).map_err(|e| {
            Error::parse(
                "fit scene",
                path.as_ref().display().to_string(),
                e.to_string().trim(),
            )
        })
    }

    /// A scene for synthetic data of `truth` with the defaults elsewhere.
    pub fn synthetic(truth: &Chain) -> FitScene {
        FitScene {
            chain: ChainSpec::from(truth),
            data: DataSpec::default(),
            unknowns: UnknownsSpec::default(),
            misfit: MisfitSpec::default(),
            search: SearchSpec::default(),
            profile: ProfileSpec::default(),
        }
    }

    /// The true chain (validated).
    ///
    /// # Errors
    /// As [`ChainSpec::build`].
    pub fn truth(&self) -> Result<Chain> {
        self.chain.build()
    }

    /// The data described by `[data]`.
    ///
    /// # Errors
    /// Invalid chain or noise; `series` (not available yet).
    pub fn data(&self) -> Result<Data> {
        if self.data.source == DataSourceKind::Modes {
            return Err(Error::invalid(
                "data.source",
                "modes",
                "a record source (modal data are read by FitScene::measured_modes)",
            ));
        }
        if !self.data.is_paper() {
            // another observable, a force, several sensors or records: the
            // general path fits the (first) record, the others join it in
            // FitScene::observations_of
            let rec = self.measured_record()?;
            let sigma = rec.sigma();
            return Data::from_samples(
                rec.t(),
                rec.y(),
                (sigma > 0.0).then_some(sigma),
                rec.measurement().describe(),
            );
        }
        match self.data.source {
            DataSourceKind::Exact => {
                Data::exact(&self.truth()?).with_noise(self.data.noise, self.data.seed)
            }
            DataSourceKind::Simulated => Data::simulated(
                &self.truth()?,
                self.data.t_end.unwrap_or(300.0),
                self.data.dt.unwrap_or(0.05),
                self.noise_sigma()?,
                self.data.seed,
            ),
            DataSourceKind::Modes => unreachable!("refused above"),
            DataSourceKind::Series => {
                let path = self.series_path(0)?;
                crate::error::check_f64(
                    "data.noise",
                    self.data.noise,
                    self.data.noise >= 0.0,
                    ">= 0 and finite",
                )?;
                let sigma = self.noise_sigma()?;
                Data::from_csv(
                    path,
                    &self.data.columns()?[0],
                    (sigma > 0.0).then_some(sigma),
                )
            }
        }
    }

    /// The scene's data as the pipeline's observations, and the samples'
    /// known noise level (`None`: to be estimated): the sampled record
    /// (simulated or read) with its sensor, or for `exact` data the values
    /// at the misfit's nodes (the Bromwich line for `bromwich`, the real
    /// axis otherwise) with their errors.
    ///
    /// # Errors
    /// As [`FitScene::data`], [`FitScene::measurement`] and the misfit's
    /// rule; `data.source` for exact data with the time misfit.
    pub fn observations(&self) -> Result<(Observations, Option<f64>)> {
        self.observations_of(&self.data()?)
    }

    /// [`FitScene::observations`] of the data `data` (the scene's
    /// [`FitScene::data`] or data given in its place).
    ///
    /// # Errors
    /// As [`FitScene::observations`].
    pub fn observations_of(&self, data: &Data) -> Result<(Observations, Option<f64>)> {
        if let Some((t, x)) = data.samples() {
            let joint = self.data.is_joint();
            let sigma = self.noise_sigma()?;
            // several sensors or records with noise relative to each one's
            // own peak: each has its own level, estimated by the fit
            let sg = (sigma > 0.0 && !(joint && self.data.relative)).then_some(sigma);
            let series =
                Series::new(t.to_vec(), x.to_vec(), sg)?.with_measurement(self.measurement(t)?)?;
            let series = if joint {
                self.joined(series, sg)?
            } else {
                series
            };
            return Ok((Observations::Series(series), sg));
        }
        if self.misfit.kind == MisfitKind::Time {
            return Err(Error::invalid(
                "data.source",
                "exact",
                "\"simulated\" or \"series\" (the time misfit needs a sampled series)",
            ));
        }
        let s = self.laplace_nodes(&self.misfit.rule()?.nodes);
        let sm = data.sample(&s)?;
        let sigma = sm.sigma.iter().map(|v| v.max(1e-300)).collect();
        Ok((
            Observations::Laplace(LaplaceValues::new(s, sm.values, Some(sigma))?),
            Some(1.0),
        ))
    }

    /// `first` (the first sensor's record) joined by the scene's further
    /// sensors ([`Series::with_sensors`]) or further records
    /// ([`Series::with_records`]), each at the noise level `sigma` (`None`:
    /// estimated per sensor or record).
    fn joined(&self, first: Series, sigma: Option<f64>) -> Result<Series> {
        let one = |sensor: usize, record: usize| -> Result<Series> {
            let rec = self.record_of(sensor, record)?;
            Series::new(rec.t().to_vec(), rec.y().to_vec(), sigma)?
                .with_measurement(rec.measurement().clone())
        };
        let sensors = self.data.sensors()?.len();
        if sensors > 1 {
            let others = (1..sensors)
                .map(|j| one(j, 0))
                .collect::<Result<Vec<_>>>()?;
            first.with_sensors(others)
        } else {
            let others = (1..self.data.record_count()?)
                .map(|r| one(0, r))
                .collect::<Result<Vec<_>>>()?;
            first.with_records(others)
        }
    }

    /// The Laplace nodes of the misfit's rule: `sigma + i w` on the
    /// Bromwich line for `bromwich`, the real nodes otherwise.
    pub fn laplace_nodes(&self, rule_nodes: &[f64]) -> Vec<Complex64> {
        match self.misfit.kind {
            MisfitKind::Bromwich => rule_nodes
                .iter()
                .map(|&w| Complex64::new(self.misfit.sigma, w))
                .collect(),
            _ => rule_nodes.iter().map(|&x| Complex64::new(x, 0.0)).collect(),
        }
    }

    /// The absolute noise level of the samples (`simulated`, `series`):
    /// `noise`, times the largest `|x_1|` of the (noise-free simulated, or
    /// measured) record when `relative`. `exact`: `noise` (relative,
    /// Laplace domain).
    ///
    /// # Errors
    /// `data.noise` negative or not finite; as the simulation or the CSV.
    pub fn noise_sigma(&self) -> Result<f64> {
        let d = &self.data;
        crate::error::check_f64("data.noise", d.noise, d.noise >= 0.0, ">= 0 and finite")?;
        if !d.relative || d.noise == 0.0 {
            return Ok(d.noise);
        }
        let level = crate::noise::NoiseLevel::RelativeMax(d.noise);
        match d.source {
            DataSourceKind::Exact | DataSourceKind::Modes => Ok(d.noise),
            DataSourceKind::Simulated if !d.is_paper() => Ok(self.measured_record()?.sigma()),
            DataSourceKind::Simulated => Ok(TimeData::simulate(
                &self.truth()?,
                d.t_end.unwrap_or(300.0),
                d.dt.unwrap_or(0.05),
                level,
                d.seed,
            )?
            .sigma()),
            DataSourceKind::Series => {
                let ts = self.series_of(0)?;
                level.sigma(ts.require(&self.data.columns()?[0])?)
            }
        }
    }

    /// The (first) record of a non-paper `[data]`: simulated as its sensor
    /// sees the truth (hammer or impulse), or read from the CSV, with its
    /// measurement.
    fn measured_record(&self) -> Result<TimeData> {
        self.record_of(0, 0)
    }

    /// The record of sensor `sensor` in record `record` of `[data]`:
    /// simulated (each sensor and record with its own noise stream, the
    /// first with `seed` itself; `relative` noise of its own peak), or read
    /// from the record's CSV, with its measurement.
    ///
    /// # Errors
    /// As [`FitScene::data`]; `data.observe`, `data.observe_kind`,
    /// `data.column`, `data.records` or `data.path` as
    /// [`DataSpec::sensors`], [`DataSpec::columns`],
    /// [`DataSpec::record_count`].
    pub fn record_of(&self, sensor: usize, record: usize) -> Result<TimeData> {
        let d = &self.data;
        crate::error::check_f64("data.noise", d.noise, d.noise >= 0.0, ">= 0 and finite")?;
        d.record_count()?;
        let s = self.sensor_of(sensor)?;
        match d.source {
            DataSourceKind::Exact | DataSourceKind::Modes => Err(Error::invalid(
                "data.source",
                if d.source == DataSourceKind::Exact { "exact" } else { "modes" },
                "\"simulated\" or \"series\" for another observable, a force, several sensors or records",
            )),
            DataSourceKind::Simulated => {
                let truth = self.truth()?;
                let force = match d.hammer_width {
                    Some(w) => Some(hammer(w, 1.0)?),
                    None => None,
                };
                let level = if d.relative {
                    crate::noise::NoiseLevel::RelativeMax(d.noise)
                } else {
                    crate::noise::NoiseLevel::Absolute(d.noise)
                };
                let seed = if sensor == 0 && record == 0 {
                    d.seed
                } else {
                    crate::noise::splitmix64(
                        d.seed ^ crate::noise::splitmix64(((record as u64) << 32) | sensor as u64),
                    )
                };
                let rec = TimeData::simulate_measured(
                    &truth,
                    d.t_end.unwrap_or(300.0),
                    d.dt.unwrap_or(0.05),
                    s,
                    force,
                    level,
                    seed,
                )?;
                let m = self.measurement_of(rec.t(), sensor, record)?;
                rec.with_measurement(m)
            }
            DataSourceKind::Series => {
                let table = self.series_of(record)?;
                let column = &d.columns()?[sensor];
                if table.column(column).is_none() {
                    return Err(Error::invalid(
                        "data.column",
                        column,
                        format!("one of the file's columns: {}", table.names().join(", ")),
                    ));
                }
                let sigma = if d.relative && d.noise > 0.0 {
                    crate::noise::NoiseLevel::RelativeMax(d.noise).sigma(table.require(column)?)?
                } else {
                    d.noise
                };
                let rec = TimeData::from_series(&table, column, sigma)?;
                let m = self.measurement_of(rec.t(), sensor, record)?;
                rec.with_measurement(m)
            }
        }
    }

    /// Sensor `sensor` of `[data]`, checked against the chain.
    ///
    /// # Errors
    /// As [`DataSpec::sensors`]; `data.observe` naming a mass outside the chain.
    fn sensor_of(&self, sensor: usize) -> Result<Sensor> {
        let s = self.data.sensors()?[sensor];
        s.check(self.chain.n).map_err(|_| {
            Error::invalid(
                "data.observe",
                s.at,
                format!("a mass of the chain, 1..={}", self.chain.n),
            )
        })?;
        Ok(s)
    }

    /// The path of record `record`'s CSV.
    fn series_path(&self, record: usize) -> Result<PathBuf> {
        self.data.paths().get(record).cloned().ok_or_else(|| {
            Error::invalid("data.path", "(none)", "a CSV file for source = \"series\"")
        })
    }

    /// The table of record `record`'s CSV.
    fn series_of(&self, record: usize) -> Result<crate::series::TimeSeries> {
        crate::series::TimeSeries::read_csv(self.series_path(record)?)
    }

    /// The sampled series of `[data]` with its noise level, for the
    /// time-domain misfit: `simulated` (the same samples as [`FitScene::data`])
    /// or `series`.
    ///
    /// # Errors
    /// `data.source` is `exact` (no series); as [`FitScene::noise_sigma`].
    pub fn time_data(&self) -> Result<TimeData> {
        if !self.data.is_paper() {
            return self.measured_record();
        }
        let sigma = self.noise_sigma()?;
        match self.data.source {
            DataSourceKind::Exact | DataSourceKind::Modes => Err(Error::invalid(
                "data.source",
                if self.data.source == DataSourceKind::Exact {
                    "exact"
                } else {
                    "modes"
                },
                "\"simulated\" or \"series\" (the time misfit needs a sampled series)",
            )),
            DataSourceKind::Simulated => TimeData::simulate(
                &self.truth()?,
                self.data.t_end.unwrap_or(300.0),
                self.data.dt.unwrap_or(0.05),
                crate::noise::NoiseLevel::Absolute(sigma),
                self.data.seed,
            ),
            DataSourceKind::Series => {
                TimeData::from_series(&self.series_of(0)?, &self.data.columns()?[0], sigma)
            }
        }
    }

    /// Whether the scene needs the general noisy fit (the chi-square of its
    /// data rather than the paper's residual with the mass-only kernel):
    /// non-mass defects, chain parameters, the time misfit, another sensor
    /// than the paper's or a free end.
    pub fn is_general(&self) -> bool {
        self.unknowns.is_general()
            || self.misfit.kind == crate::detect::misfit::MisfitKind::Time
            || !self.data.is_paper()
            || self.chain.left.is_free()
            || self.chain.right.is_free()
    }

    /// What the record of `[data]` at times `t` measured: its sensor, and
    /// the hammer's force samples (`hammer_width`) or the CSV's force column
    /// (`force_column`).
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming `data.hammer_width` (not
    /// `simulated`, or not a width > 0), `data.force_column` (not `series`,
    /// a missing column, other times than the record's), `data.observe`
    /// (not a mass of the chain).
    pub fn measurement(&self, t: &[f64]) -> Result<Measurement> {
        self.measurement_of(t, 0, 0)
    }

    /// [`FitScene::measurement`] of sensor `sensor` in record `record`
    /// (the force column of that record's file).
    ///
    /// # Errors
    /// As [`FitScene::measurement`]; as [`DataSpec::sensors`].
    pub fn measurement_of(&self, t: &[f64], sensor: usize, record: usize) -> Result<Measurement> {
        let d = &self.data;
        let s = self.sensor_of(sensor)?;
        let m = Measurement::paper().with_sensor(s);
        match (&d.hammer_width, &d.force_column) {
            (Some(_), Some(_)) => Err(Error::invalid(
                "data.force_column",
                "with hammer_width",
                "one force: hammer_width (simulated) or force_column (series)",
            )),
            (Some(w), None) => {
                if d.source != DataSourceKind::Simulated {
                    return Err(Error::invalid(
                        "data.hammer_width",
                        w,
                        "source = \"simulated\" only (a measured force is a force_column)",
                    ));
                }
                let f = hammer(*w, 1.0)?;
                m.with_force(t.iter().map(|&x| f.eval(x)).collect())
            }
            (None, Some(c)) => {
                if d.source != DataSourceKind::Series {
                    return Err(Error::invalid(
                        "data.force_column",
                        c,
                        "source = \"series\" only (a simulated blow is hammer_width)",
                    ));
                }
                let ts = self.series_of(record)?;
                let f = ts.column(c).ok_or_else(|| {
                    Error::invalid(
                        "data.force_column",
                        c,
                        format!("one of the file's columns: {}", ts.names().join(", ")),
                    )
                })?;
                if ts.t() != t {
                    return Err(Error::invalid(
                        "data.force_column",
                        c,
                        "a column of the record's own file and times",
                    ));
                }
                m.with_force(f.to_vec())
            }
            (None, None) => Ok(m),
        }
    }

    /// The unknowns (validated against `chain.n`; `k` defaults to the
    /// number of `[chain]` defects of the table's kind, all of them for `any`).
    ///
    /// # Errors
    /// As [`UnknownsSpec::build`].
    pub fn unknowns(&self) -> Result<Unknowns> {
        let kinds = self.unknowns.kind.kinds();
        let k = self
            .chain
            .defects
            .iter()
            .filter(|d| kinds.contains(&DefectKind::of(d)))
            .count();
        self.unknowns.build(self.chain.n, k)
    }

    /// The fit options described by `[search]`.
    pub fn options(&self) -> SceneOptions {
        let s = &self.search;
        SceneOptions {
            method: s.method,
            seed: s.seed,
            max_evals: s.max_evals,
            trace: s.trace,
            enumerate: EnumerateOptions {
                keep: s.keep,
                starts: s.starts,
                max_sets: s.max_sets,
                beam: s.beam,
                parallel: s.parallel,
                ..EnumerateOptions::default()
            },
            exhaustive: s.exhaustive,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn example_config_parses() {
        let text = include_str!("../../../configs/scenes/table1-system3.toml");
        let s = FitScene::from_toml(text).unwrap();
        assert_eq!(s.chain.n, 20);
        assert_eq!(s.unknowns().unwrap().k(), 2);
        s.data().unwrap();
        for text in [
            include_str!("../../../configs/scenes/table1-system3-series.toml"),
            include_str!("../../../configs/scenes/figure16.toml"),
            include_str!("../../../configs/scenes/figure17.toml"),
        ] {
            let s = FitScene::from_toml(text).unwrap();
            s.unknowns().unwrap();
        }
    }

    #[test]
    fn errors_name_fields() {
        let bad = |text: &str, field: &str| {
            let s = FitScene::from_toml(text).unwrap();
            match s.unknowns().and_then(|_| s.data()) {
                Err(Error::InvalidParameter { field: f, .. }) => assert_eq!(f, field, "{text}"),
                other => panic!("{text}: {other:?}"),
            }
        };
        bad("[chain]\nn = 3\n[unknowns]\nk = 4\n", "unknowns.k");
        bad(
            "[chain]\nn = 3\n[unknowns]\nk = 1\nmass_bounds = [5, 5]\n",
            "unknowns.mass_bounds",
        );
        bad(
            "[chain]\nn = 3\n[unknowns]\nk = 2\n[[unknowns.defects]]\nat = 9\n",
            "unknowns.defects[0].at",
        );
        bad(
            "[chain]\nn = 3\n[unknowns]\nk = 2\n[[unknowns.defects]]\nat = 2\n[[unknowns.defects]]\nat = 2\n",
            "unknowns.defects[1].at",
        );
        bad(
            "[chain]\nn = 3\n[unknowns]\nk = 1\n[[unknowns.defects]]\nbounds = [3, 1]\n",
            "unknowns.defects[0].bounds",
        );
        bad(
            "[chain]\nn = 3\n[unknowns]\nk = 1\n[data]\nnoise = -1\n",
            "data.noise",
        );
        bad(
            "[chain]\nn = 3\n[unknowns]\nk = 1\n[data]\nsource = \"series\"\n",
            "data.path",
        );
        assert!(matches!(
            FitScene::from_toml("[chain]\nn = 3\n[misfit]\nkind = \"imaginary\"\n"),
            Err(Error::Parse { .. })
        ));
    }

    #[test]
    fn general_scenes_parse_and_errors_name_fields() {
        for text in [
            include_str!("../../../configs/scenes/fit-spring.toml"),
            include_str!("../../../configs/scenes/fit-any.toml"),
        ] {
            let s = FitScene::from_toml(text).unwrap();
            assert!(s.is_general());
            let u = s.unknowns().unwrap();
            assert_eq!(u.slots().len(), 2);
            assert!(u.to_mass().is_err(), "the mass-only kernel refuses");
        }
        let s =
            FitScene::from_toml(include_str!("../../../configs/scenes/fit-spring.toml")).unwrap();
        assert_eq!(s.unknowns().unwrap().hypotheses(1000).unwrap().len(), 110);
        assert_eq!(
            s.unknowns.start_chain(&s.truth().unwrap()).unwrap().d(),
            0.15
        );
        // 1% of max |x_1|, the same samples as the Laplace data
        let td = s.time_data().unwrap();
        let ymax = td.y().iter().fold(0.0f64, |a, v| a.max(v.abs()));
        assert!((td.sigma() / ymax - 0.01).abs() < 0.002, "{}", td.sigma());
        let field = |text: &str| -> String {
            let s = FitScene::from_toml(text).unwrap();
            match s
                .unknowns()
                .and_then(|_| s.unknowns.start_chain(&s.truth()?))
                .and_then(|_| s.time_data())
            {
                Err(Error::InvalidParameter { field, .. }) => field,
                other => panic!("{text}: {other:?}"),
            }
        };
        let sim = "[data]\nsource = \"simulated\"\nt_end = 10\ndt = 0.5\n";
        let cases = [
            (
                "[unknowns]\nkind = \"spring\"\nchain = [\"q\"]\n",
                "unknowns.chain",
            ),
            (
                "[unknowns]\nkind = \"any\"\nchain = [\"d\", \"k\", \"gamma\", \"mass\"]\n",
                "unknowns.chain",
            ),
            (
                "[unknowns]\nkind = \"spring\"\nchain = [\"d\", \"d\"]\n",
                "unknowns.chain",
            ),
            (
                "[unknowns]\nkind = \"spring\"\nspring_bounds = [0, 1]\n",
                "unknowns.spring_bounds",
            ),
            (
                "[unknowns]\nkind = \"damper\"\ndamper_bounds = [-1, 1]\n",
                "unknowns.damper_bounds",
            ),
            (
                "[unknowns]\nk = 1\n[[unknowns.defects]]\nkind = \"spring\"\nm = 2.0\n",
                "unknowns.defects[0].m",
            ),
            (
                "[unknowns]\nk = 1\n[[unknowns.defects]]\nkind = \"damper\"\nat = 0\n",
                "unknowns.defects[0].at",
            ),
            (
                "[unknowns]\nkind = \"spring\"\nchain = [\"d\"]\nchain_start = { k = 2.0 }\n",
                "unknowns.chain_start.k",
            ),
            (
                "[unknowns]\nkind = \"spring\"\nchain = [\"d\"]\nchain_start = { d = -1.0 }\n",
                "unknowns.chain_start.d",
            ),
            ("[unknowns]\nkind = \"spring\"\nk = 9\n", "unknowns.k"),
            (
                "[unknowns]\nkind = \"spring\"\n[misfit]\nkind = \"time\"\n",
                "data.source",
            ),
        ];
        for (tail, want) in cases {
            let tail = if want == "unknowns.k" || tail.contains("k = 1") {
                tail.to_string()
            } else {
                tail.replacen("[unknowns]\n", "[unknowns]\nk = 1\n", 1)
            };
            let text = format!("[chain]\nn = 3\n{tail}{sim}");
            let text = if want == "data.source" {
                text.replace("simulated", "exact")
            } else {
                text
            };
            assert_eq!(field(&text), want, "{text}");
        }
        assert!(FitScene::from_toml("[chain]\nn = 3\n[unknowns]\nkind = \"rod\"\n").is_err());
        assert!(FitScene::from_toml("[chain]\nn = 3\n[unknowns]\nchains = []\n").is_err());
    }
}
