//! The `[data]` table of a fit scene: where the data come from (exact,
//! simulated, a CSV series, measured modes), its sensors (one or several),
//! its records (one or several) and their noise.

use crate::detect::data::measurement::Sensor;
use crate::error::{Error, Result};
use crate::forward::Observable;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// Where the data of a scene come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum DataSourceKind {
    /// The closed-form model of the `[chain]` (with its true defects).
    #[default]
    Exact,
    /// A simulation of `[chain]` (`t_end`, `dt`), optional white noise of
    /// standard deviation `noise` on the samples, Laplace-transformed (the
    /// paper's pipeline).
    Simulated,
    /// A measured CSV series (`path`, `column`), Laplace-transformed; `noise`
    /// is the samples' known standard deviation (error estimate only).
    Series,
    /// Measured modes: a modes CSV (`path`, see
    /// [`crate::detect::data::modes`]) or the lowest `modes` undamped modes
    /// of `[chain]` seen at `floors`, with `frequency_noise` and
    /// `shape_noise`; fitted by the modal defect search
    /// ([`crate::detect::fit::modal_locate`]).
    Modes,
}

/// One value or a list of them: `observe = 1` or `observe = [1, 30, 60]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum OneOrMany<T> {
    /// One value.
    One(T),
    /// A list.
    Many(Vec<T>),
}

impl<T: Clone> OneOrMany<T> {
    /// The values as a list.
    pub fn to_vec(&self) -> Vec<T> {
        match self {
            OneOrMany::One(v) => vec![v.clone()],
            OneOrMany::Many(v) => v.clone(),
        }
    }
}

impl<T> From<T> for OneOrMany<T> {
    fn from(v: T) -> Self {
        OneOrMany::One(v)
    }
}

/// Most records a scene simulates or reads.
pub const MAX_RECORDS: usize = 1000;

/// The `[data]` table.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Default)]
#[serde(default, deny_unknown_fields)]
pub struct DataSpec {
    /// `exact` (default), `simulated` or `series`.
    pub source: DataSourceKind,
    /// Path of the CSV series (for `series`; a list: several records of
    /// the same chain, fitted jointly), or of the modes CSV (for `modes`).
    pub path: Option<OneOrMany<PathBuf>>,
    /// Column of the CSV series (default `x1`); a list with several
    /// `observe` masses, one per mass (default `x{mass}`).
    pub column: Option<OneOrMany<String>>,
    /// `exact`: relative Laplace-domain noise; `simulated`: absolute noise
    /// on the samples; `series`: the samples' known noise (default 0).
    pub noise: f64,
    /// Noise seed (default 0).
    pub seed: u64,
    /// `simulated`: end of the record (default 300).
    pub t_end: Option<f64>,
    /// `simulated`: sampling step (default 0.05).
    pub dt: Option<f64>,
    /// `simulated` and `series`: `noise` is relative to the largest `|x_1|` of
    /// the record (default false: absolute).
    pub relative: bool,
    /// `simulated` and `series`: the observed mass (default 1); a list:
    /// several sensors of one test, fitted jointly (each with its own
    /// noise stream when simulated, and its own noise level).
    pub observe: Option<OneOrMany<usize>>,
    /// `simulated` and `series`: `displacement` (default), `velocity` or
    /// `acceleration`; a list: one per `observe` mass.
    pub observe_kind: Option<OneOrMany<Observable>>,
    /// `simulated`: the number of records of the same chain (hammer hits,
    /// each with its own noise stream), fitted jointly (default 1).
    pub records: Option<usize>,
    /// `modes` (simulated): the number of lowest modes measured (default 3).
    pub modes: Option<usize>,
    /// `modes` (simulated): the masses whose mode-shape components are
    /// measured (default every mass).
    pub floors: Option<Vec<usize>>,
    /// `modes` (simulated): the frequencies' relative noise (default 0).
    pub frequency_noise: Option<f64>,
    /// `modes` (simulated): the shapes' noise, relative to each mode's
    /// largest measured component (default 0).
    pub shape_noise: Option<f64>,
    /// `modes`: the measurement model, `property` (the modal-property
    /// difference, default) or `dynamic` (the modal dynamic residual).
    pub modal_residual: Option<String>,
    /// `simulated`: a hammer's half-sine blow of this width (unit impulse,
    /// times `gamma`) on mass 1 instead of the ideal impulse; the record
    /// keeps the force's samples and the fit uses them.
    pub hammer_width: Option<f64>,
    /// `series`: the CSV column of the measured force on mass 1 (a hammer
    /// test); the fit uses it instead of the ideal impulse.
    pub force_column: Option<String>,
}

impl DataSpec {
    /// The (first) sensor of `[data]` (default: the displacement of mass 1).
    pub fn sensor(&self) -> Sensor {
        let at = self
            .observe
            .as_ref()
            .and_then(|o| o.to_vec().first().copied())
            .unwrap_or(1);
        let kind = self
            .observe_kind
            .as_ref()
            .and_then(|k| k.to_vec().first().copied())
            .unwrap_or_default();
        Sensor { at, kind }
    }

    /// Every sensor of `[data]`: the `observe` masses, each with its
    /// `observe_kind` (one kind for all, or one per mass).
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming `data.observe` (an empty list) or
    /// `data.observe_kind` (a list of another length).
    pub fn sensors(&self) -> Result<Vec<Sensor>> {
        let at = self.observe.as_ref().map_or(vec![1], OneOrMany::to_vec);
        if at.is_empty() {
            return Err(Error::invalid(
                "data.observe",
                "[]",
                "a mass or a list of masses",
            ));
        }
        let kinds = self
            .observe_kind
            .as_ref()
            .map_or(vec![Observable::default()], OneOrMany::to_vec);
        if kinds.len() != 1 && kinds.len() != at.len() {
            return Err(Error::invalid(
                "data.observe_kind",
                format!("{} kinds", kinds.len()),
                format!("one kind, or one per observe mass ({})", at.len()),
            ));
        }
        Ok(at
            .iter()
            .enumerate()
            .map(|(i, &at)| Sensor {
                at,
                kind: kinds[i.min(kinds.len() - 1)],
            })
            .collect())
    }

    /// The CSV files of `[data]` (`series`: one per record; `modes`: one).
    pub fn paths(&self) -> Vec<PathBuf> {
        self.path.as_ref().map_or(Vec::new(), OneOrMany::to_vec)
    }

    /// The CSV column of each sensor (`series`): `column` (one per sensor),
    /// by default `x1` for one sensor and `x{mass}` for several.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming `data.column`: a list of another
    /// length than `observe`.
    pub fn columns(&self) -> Result<Vec<String>> {
        let sensors = self.sensors()?;
        match &self.column {
            None if sensors.len() == 1 => Ok(vec!["x1".into()]),
            None => Ok(sensors.iter().map(|s| format!("x{}", s.at)).collect()),
            Some(c) => {
                let c = c.to_vec();
                if c.len() != sensors.len() {
                    return Err(Error::invalid(
                        "data.column",
                        format!("{} columns", c.len()),
                        format!("one column per observe mass ({})", sensors.len()),
                    ));
                }
                Ok(c)
            }
        }
    }

    /// The number of records: the `series` files, or `records` simulated
    /// ones (default 1).
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming `data.records` (0, more than
    /// [`MAX_RECORDS`], given for a `series` or `exact` source, or with
    /// several sensors: several sensors and several records are not fitted
    /// together) or `data.path` (more files than [`MAX_RECORDS`]).
    pub fn record_count(&self) -> Result<usize> {
        let several_sensors = self.observe.as_ref().is_some_and(|o| o.to_vec().len() > 1);
        let count = match (self.source, self.records) {
            (DataSourceKind::Series, Some(r)) => {
                return Err(Error::invalid(
                    "data.records",
                    r,
                    "`simulated` only (a `series` scene lists one path per record)",
                ))
            }
            (DataSourceKind::Series, None) => self.paths().len().max(1),
            (DataSourceKind::Simulated, r) => r.unwrap_or(1),
            (_, Some(r)) if r != 1 => {
                return Err(Error::invalid(
                    "data.records",
                    r,
                    "`simulated` only (several records are sampled series)",
                ))
            }
            _ => 1,
        };
        // the field that set the count
        let field = if self.records.is_some() {
            "data.records"
        } else {
            "data.path"
        };
        if count == 0 || count > MAX_RECORDS {
            return Err(Error::invalid(
                field,
                count,
                format!("1..={MAX_RECORDS} records"),
            ));
        }
        if count > 1 && several_sensors {
            return Err(Error::invalid(
                field,
                count,
                "1 with several observe masses (several sensors and several records are not fitted together)",
            ));
        }
        Ok(count)
    }

    /// Whether `[data]` holds several sensors or several records.
    pub fn is_joint(&self) -> bool {
        self.observe.as_ref().is_some_and(|o| o.to_vec().len() > 1)
            || self.records.is_some_and(|r| r > 1)
            || self.paths().len() > 1
    }

    /// Whether `[data]` is the paper's measurement: the displacement of
    /// mass 1 after the ideal impulse, one record.
    pub fn is_paper(&self) -> bool {
        matches!(self.sensors().as_deref(), Ok([s]) if *s == Sensor::PAPER)
            && self.hammer_width.is_none()
            && self.force_column.is_none()
            && !self.is_joint()
            && self.source != DataSourceKind::Modes
    }
}
