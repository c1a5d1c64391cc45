//! The data-first entry of the inverse side: what a user measured, with no
//! truth attached.
//!
//! * [`Series`]: a sampled record `x(t_i)` of the observed mass (times `t`,
//!   values `x`, and the white-noise standard deviation `sigma` when known;
//!   `None` asks the fit to estimate it);
//! * [`LaplaceValues`]: values `X(s_q)` at real or complex nodes with their
//!   standard errors when known.
//!
//! ```
//! use springmass::detect::data::observations::{Observations, Series};
//! let t: Vec<f64> = (0..200).map(|i| 0.1 * i as f64).collect();
//! let x: Vec<f64> = t.iter().map(|t| (-0.05 * t).exp() * t.sin()).collect();
//! let obs = Observations::Series(Series::new(t, x, None)?);
//! assert_eq!(obs.len(), 200);
//! assert!(Series::new(vec![0.0, 1.0], vec![0.0, 1.0], None).is_err()); // too short
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::detect::data::laplace::LaplaceObs;
use crate::detect::data::measurement::{Measurement, Sensor};
use crate::detect::data::series::TimeData;
use crate::error::{check_f64, Error, Result};
use crate::series::TimeSeries;
use num_complex::Complex64;
use std::path::Path;

/// Fewest samples of a series the fit accepts.
pub const MIN_SAMPLES: usize = 16;

/// A sampled record of the observed mass.
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    t: Vec<f64>,
    x: Vec<f64>,
    sigma: Option<f64>,
    measurement: Measurement,
    /// Where `t = 0` of [`Series::t`] lies on the user's time axis (0 unless
    /// the record was re-based, [`Series::on_axis`], or re-timed to its
    /// blow, [`Series::shifted`]).
    origin: f64,
    /// Further sensors' records at the same times ([`Series::with_sensors`];
    /// empty: one sensor), or further records of the same chain
    /// ([`Series::with_records`]).
    others: Vec<Series>,
    /// `others` are separate records (tests of their own), not sensors of
    /// this one.
    separate: bool,
}

/// Largest accepted magnitude of a recorded value: the misfit squares and
/// sums the values, which overflows f64 (about 1.8e308) beyond this.
pub const MAX_RECORD_VALUE: f64 = 1e150;
/// Smallest accepted time step: the Laplace nodes scale with its inverse,
/// which overflows f64 for steps below this.
pub const MIN_TIME_STEP: f64 = 1e-200;

/// What in a record makes the fit's arithmetic fail, said up front: an
/// all-zero record when the noise is estimated from it (a zero noise level:
/// the chi-square is not finite), values whose squares overflow, time steps
/// whose inverse overflows.
fn check_scales(t: &[f64], x: &[f64], noise_from_data: bool) -> Result<()> {
    if noise_from_data && x.iter().all(|v| *v == 0.0) {
        return Err(Error::invalid(
            "x",
            format!("{} samples, every one 0", x.len()),
            "a record with a response (not all zero; the noise level estimated from it would be 0): check the column and the sensor",
        ));
    }
    if let Some(i) = x.iter().position(|v| v.abs() > MAX_RECORD_VALUE) {
        return Err(Error::invalid(
            format!("x[{i}]"),
            x[i],
            format!("a magnitude <= {MAX_RECORD_VALUE:e} (squares overflow f64 beyond): rescale the data, e.g. to other units"),
        ));
    }
    if let Some(i) = (1..t.len()).find(|&i| t[i] - t[i - 1] < MIN_TIME_STEP) {
        return Err(Error::invalid(
            format!("t[{i}] - t[{}]", i - 1),
            t[i] - t[i - 1],
            format!("a time step >= {MIN_TIME_STEP:e} (the Laplace nodes scale with 1/step and overflow f64 beyond): rescale the times"),
        ));
    }
    Ok(())
}

impl Series {
    /// Times `t` (finite, `>= 0`, strictly increasing), values `x` (finite),
    /// and the noise standard deviation of the samples if known (`> 0`).
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming the field: `x` (length differs from
    /// `t`, or fewer than [`MIN_SAMPLES`] samples), `t[i]`, `x[i]` (NaN or
    /// infinite), `noise` (`sigma <= 0` or not finite).
    pub fn new(t: Vec<f64>, x: Vec<f64>, sigma: Option<f64>) -> Result<Series> {
        if t.len() != x.len() {
            return Err(Error::invalid(
                "x",
                format!("{} values for {} times", x.len(), t.len()),
                "one value per time",
            ));
        }
        if t.len() < MIN_SAMPLES {
            return Err(Error::invalid(
                "x",
                format!("{} samples", t.len()),
                format!("at least {MIN_SAMPLES} samples"),
            ));
        }
        crate::series::check_times(&t)?;
        if t[0] < 0.0 {
            return Err(Error::invalid(
                "t[0]",
                t[0],
                ">= 0 (time since the impulse; a record with a pre-trigger segment at negative times is read by Series::on_axis, and the fit finds the blow with trigger auto)",
            ));
        }
        for (i, v) in x.iter().enumerate() {
            check_f64(&format!("x[{i}]"), *v, true, "finite (no NaN or inf)")?;
        }
        if let Some(s) = sigma {
            check_f64("noise", s, s > 0.0, "> 0 and finite (or auto)")?;
        }
        check_scales(&t, &x, sigma.is_none())?;
        Ok(Series {
            t,
            x,
            sigma,
            measurement: Measurement::paper(),
            origin: 0.0,
            others: Vec::new(),
            separate: false,
        })
    }

    /// A record on the user's own time axis, which may start before `0` (a
    /// pre-trigger segment at negative times): re-based to start at `0`,
    /// the offset kept as [`Series::origin`]. Otherwise as [`Series::new`].
    ///
    /// ```
    /// use springmass::detect::data::observations::Series;
    /// let t: Vec<f64> = (0..20).map(|i| -1.0 + 0.1 * i as f64).collect();
    /// let s = Series::on_axis(t, (0..20).map(|i| i as f64).collect(), None)?;
    /// assert_eq!((s.t()[0], s.origin()), (0.0, -1.0));
    /// # Ok::<(), springmass::Error>(())
    /// ```
    ///
    /// # Errors
    /// As [`Series::new`].
    pub fn on_axis(t: Vec<f64>, x: Vec<f64>, sigma: Option<f64>) -> Result<Series> {
        let first = t.first().copied().unwrap_or(0.0);
        if first >= 0.0 || first.is_nan() {
            return Series::new(t, x, sigma);
        }
        let rebased = t.iter().map(|v| v - first).collect();
        let mut s = Series::new(rebased, x, sigma)?;
        s.origin = first;
        Ok(s)
    }

    /// Where `t = 0` of this record lies on the user's time axis: a time on
    /// the user's axis is `t + origin`.
    pub fn origin(&self) -> f64 {
        self.origin
    }

    pub(crate) fn set_origin(&mut self, origin: f64) {
        self.origin = origin;
    }

    /// Column `column` of a CSV file (time column `t`); `column = None` takes
    /// the first column after the time.
    ///
    /// # Errors
    /// I/O and parse errors of [`TimeSeries::read_csv`]; a column that does
    /// not exist (field `column`, naming the columns there are); as
    /// [`Series::new`].
    pub fn from_csv(
        path: impl AsRef<Path>,
        column: Option<&str>,
        sigma: Option<f64>,
    ) -> Result<Series> {
        let ts = TimeSeries::read_csv(path.as_ref())?;
        Series::from_table(&ts, column, sigma)
    }

    /// Column `column` of a table (`None`: the first column).
    ///
    /// # Errors
    /// As [`Series::from_csv`].
    pub fn from_table(ts: &TimeSeries, column: Option<&str>, sigma: Option<f64>) -> Result<Series> {
        let x = match column {
            Some(c) => ts.column(c).ok_or_else(|| {
                Error::invalid(
                    "column",
                    c,
                    format!("one of the file's columns: {}", ts.names().join(", ")),
                )
            })?,
            None => ts.column_at(0).ok_or_else(|| {
                Error::invalid("column", "(none)", "a file with at least one value column")
            })?,
        };
        Series::on_axis(ts.t().to_vec(), x.to_vec(), sigma)
    }

    /// One record of several sensors from a table: `columns` (one per
    /// measurement, in order; `None`: the table's value columns in order,
    /// `skip` left out, as many as measurements), each column with its
    /// measurement, the first joined by the others ([`Series::with_sensors`]).
    ///
    /// # Errors
    /// A column that does not exist (field `column`), columns and sensors
    /// of different counts (field `column`); as [`Series::from_table`],
    /// [`Series::with_measurement`] and [`Series::with_sensors`].
    pub fn from_table_sensors(
        ts: &TimeSeries,
        columns: Option<&[String]>,
        skip: Option<&str>,
        measurements: Vec<Measurement>,
        sigma: Option<f64>,
    ) -> Result<Series> {
        let names: Vec<String> = match columns {
            Some(c) => c.to_vec(),
            None => ts
                .names()
                .iter()
                .filter(|c| Some(c.as_str()) != skip)
                .take(measurements.len())
                .cloned()
                .collect(),
        };
        if measurements.is_empty() {
            return Err(Error::invalid("observe", "(none)", "at least one sensor"));
        }
        if names.len() != measurements.len() {
            return Err(Error::invalid(
                "column",
                format!("{} columns ({})", names.len(), names.join(", ")),
                format!(
                    "one value column per sensor: {} sensors",
                    measurements.len()
                ),
            ));
        }
        let mut all = names
            .iter()
            .zip(measurements)
            .map(|(c, m)| Series::from_table(ts, Some(c), sigma)?.with_measurement(m));
        let first = all.next().expect("at least one sensor")?;
        first.with_sensors(all.collect::<Result<_>>()?)
    }

    /// The times.
    pub fn t(&self) -> &[f64] {
        &self.t
    }

    /// The values.
    pub fn x(&self) -> &[f64] {
        &self.x
    }

    /// The stated noise standard deviation, if any.
    pub fn sigma(&self) -> Option<f64> {
        self.sigma
    }

    /// The same record as another measurement: the velocity or acceleration
    /// of a mass, or driven by a measured force on mass 1 (see
    /// [`Measurement`]; default: the displacement of mass 1 after the
    /// impulse).
    ///
    /// # Errors
    /// As [`Measurement::check_times`].
    pub fn with_measurement(mut self, measurement: Measurement) -> Result<Series> {
        measurement.check_times(&self.t)?;
        self.measurement = measurement;
        Ok(self)
    }

    /// What the record measured.
    pub fn measurement(&self) -> &Measurement {
        &self.measurement
    }

    /// The same record joined by further sensors' records of the same
    /// test (one joint fit: [`crate::detect::fit::fit`] stacks the
    /// residuals of every sensor, each at its own noise level).
    ///
    /// ```
    /// use springmass::{detect::data::{measurement::Measurement, observations::Series}, forward::Observable};
    /// let t: Vec<f64> = (0..40).map(|i| 0.5 * i as f64).collect();
    /// let x: Vec<f64> = t.iter().map(|t| t.sin()).collect();
    /// let far = Series::new(t.clone(), x.clone(), None)?.with_measurement(Measurement::new(5, Observable::Displacement))?;
    /// let joint = Series::new(t.clone(), x.clone(), None)?.with_sensors(vec![far.clone()])?;
    /// assert_eq!(joint.sensors().count(), 2);
    /// // the same mass twice is refused
    /// assert!(Series::new(t, x, None)?.with_sensors(vec![far.clone(), far]).is_err());
    /// # Ok::<(), springmass::Error>(())
    /// ```
    ///
    /// # Errors
    /// [`Error::InvalidParameter`]: a record at other times or with
    /// further sensors of its own (field `sensors`), a mass observed twice
    /// (field `observe`).
    pub fn with_sensors(mut self, others: Vec<Series>) -> Result<Series> {
        crate::detect::data::series::check_joint(
            &self.t,
            others.iter().map(|o| (o.t.as_slice(), o.others.is_empty())),
        )?;
        let mut seen = vec![self.measurement.sensor().at];
        for o in &others {
            let at = o.measurement.sensor().at;
            if seen.contains(&at) {
                return Err(Error::invalid(
                    "observe",
                    at,
                    "each mass observed once (one column per sensor)",
                ));
            }
            seen.push(at);
        }
        self.others = others;
        Ok(self)
    }

    /// The same record joined by the records of further tests of the same
    /// chain (several hammer hits, a record per excitation): each with its
    /// own times, sensor, impulse or measured force and noise level. One
    /// joint fit ([`crate::detect::fit::fit`] stacks every record's
    /// residual at its own noise level, as for several sensors); the report
    /// lists each record with its level and whether the joint answer
    /// explains it ([`crate::detect::fit::report::SensorEstimate`]).
    ///
    /// ```
    /// use springmass::detect::data::observations::Series;
    /// let t: Vec<f64> = (0..40).map(|i| 0.5 * i as f64).collect();
    /// let x: Vec<f64> = t.iter().map(|t| t.sin()).collect();
    /// let t2: Vec<f64> = (0..30).map(|i| 0.25 * i as f64).collect();
    /// let x2: Vec<f64> = t2.iter().map(|t| 0.5 * t.sin()).collect();
    /// let second = Series::new(t2, x2, None)?;
    /// let joint = Series::new(t, x, None)?.with_records(vec![second.clone()])?;
    /// assert_eq!(joint.sensors().count(), 2);
    /// assert!(joint.separate_records());
    /// // a record that holds records of its own is refused
    /// assert!(second.clone().with_records(vec![joint]).is_err());
    /// # Ok::<(), springmass::Error>(())
    /// ```
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming `records`: this record or a
    /// further one holding further sensors or records of its own.
    pub fn with_records(mut self, others: Vec<Series>) -> Result<Series> {
        let count = others.len() + 1;
        let nested = std::iter::once(&self)
            .chain(&others)
            .position(|o| !o.others.is_empty());
        if let Some(j) = nested {
            return Err(Error::invalid(
                "records",
                format!("record {} of {count}", j + 1),
                "records of one sensor each (several sensors and several records are not fitted together)",
            ));
        }
        self.others = others;
        self.separate = !self.others.is_empty();
        Ok(self)
    }

    /// Whether the further series are separate records
    /// ([`Series::with_records`]) rather than sensors of one test.
    pub fn separate_records(&self) -> bool {
        self.separate
    }

    /// Every sensor's record, this one first.
    pub fn sensors(&self) -> impl Iterator<Item = &Series> {
        std::iter::once(self).chain(&self.others)
    }

    /// The further sensors' records (empty: one sensor).
    pub fn others(&self) -> &[Series] {
        &self.others
    }

    /// The same record with noise level `sigma` as [`TimeData`] (the form
    /// the misfits use).
    ///
    /// # Errors
    /// `sigma` negative or not finite.
    pub fn time_data(&self, sigma: f64) -> Result<TimeData> {
        self.time_data_scaled(sigma, &[])
    }

    /// As [`Series::time_data`], the further sensors at noise levels
    /// `sigma * scales[j]` (1 where `scales` has no entry).
    ///
    /// # Errors
    /// As [`Series::time_data`].
    pub fn time_data_scaled(&self, sigma: f64, scales: &[f64]) -> Result<TimeData> {
        let one = |s: &Series, sigma: f64| {
            TimeData::new(s.t.clone(), s.x.clone(), sigma)?.with_measurement(s.measurement.clone())
        };
        let td = one(self, sigma)?;
        if self.others.is_empty() {
            return Ok(td);
        }
        let others = self
            .others
            .iter()
            .enumerate()
            .map(|(j, o)| one(o, sigma * scales.get(j).copied().unwrap_or(1.0)))
            .collect::<Result<Vec<_>>>()?;
        if self.separate {
            Ok(td.with_records(others))
        } else {
            td.with_others(others)
        }
    }

    /// Largest `|x|`.
    pub fn max_abs(&self) -> f64 {
        self.x.iter().fold(0.0f64, |a, v| a.max(v.abs()))
    }
}

/// Values of the transfer function at Laplace nodes.
#[derive(Clone, Debug, PartialEq)]
pub struct LaplaceValues {
    s: Vec<Complex64>,
    values: Vec<Complex64>,
    sigma: Option<Vec<f64>>,
    sensor: Sensor,
}

impl LaplaceValues {
    /// Nodes `s` (finite, `Re s >= 0`), values, and the standard error of each
    /// value if known (`> 0`; of the real and of the imaginary part each, so
    /// that a complex node adds two terms to the chi-square).
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming `values` (length), `s[i]`,
    /// `values[i]`, `sigma[i]`.
    pub fn new(
        s: Vec<Complex64>,
        values: Vec<Complex64>,
        sigma: Option<Vec<f64>>,
    ) -> Result<LaplaceValues> {
        if s.is_empty() || s.len() != values.len() {
            return Err(Error::invalid(
                "values",
                format!("{} values at {} nodes", values.len(), s.len()),
                "one value per node, at least one node",
            ));
        }
        for (i, z) in s.iter().enumerate() {
            crate::forward::check_s(z)
                .map_err(|_| Error::invalid(format!("s[{i}]"), z, "finite, Re s >= 0"))?;
        }
        for (i, v) in values.iter().enumerate() {
            if !(v.re.is_finite() && v.im.is_finite()) {
                return Err(Error::invalid(format!("values[{i}]"), v, "finite"));
            }
        }
        if let Some(sg) = &sigma {
            if sg.len() != s.len() {
                return Err(Error::invalid(
                    "sigma",
                    format!("{} errors for {} nodes", sg.len(), s.len()),
                    "one error per node",
                ));
            }
            for (i, v) in sg.iter().enumerate() {
                check_f64(&format!("sigma[{i}]"), *v, *v > 0.0, "> 0 and finite")?;
            }
        }
        Ok(LaplaceValues {
            s,
            values,
            sigma,
            sensor: Sensor::PAPER,
        })
    }

    /// The same values as the transform of another observable (velocity
    /// `s X`, acceleration `s^2 X - x'(0+)`) or of another mass (default: `X_1`).
    pub fn with_sensor(mut self, sensor: Sensor) -> LaplaceValues {
        self.sensor = sensor;
        self
    }

    /// The sensor.
    pub fn sensor(&self) -> Sensor {
        self.sensor
    }

    /// The nodes.
    pub fn s(&self) -> &[Complex64] {
        &self.s
    }

    /// The values.
    pub fn values(&self) -> &[Complex64] {
        &self.values
    }

    /// The standard errors, if known.
    pub fn sigma(&self) -> Option<&[f64]> {
        self.sigma.as_deref()
    }

    /// The chi-square observation of these values: node `q` weighted by
    /// `1 / sigma_q^2`, or by `1 / sigma^2` when they carry no errors.
    ///
    /// # Errors
    /// `sigma` not positive and finite when needed (as [`LaplaceObs::new`]).
    pub fn obs(&self, sigma: f64) -> Result<LaplaceObs> {
        self.obs_where(sigma, |_| true)
    }

    /// As [`LaplaceValues::obs`], on the nodes `q` with `keep(q)`.
    ///
    /// # Errors
    /// As [`LaplaceValues::obs`]; no node kept (field `s`).
    pub fn obs_where(&self, sigma: f64, keep: impl Fn(usize) -> bool) -> Result<LaplaceObs> {
        let q: Vec<usize> = (0..self.s.len()).filter(|&q| keep(q)).collect();
        let w = q
            .iter()
            .map(|&i| match &self.sigma {
                Some(sg) => 1.0 / (sg[i] * sg[i]),
                None => 1.0 / (sigma * sigma),
            })
            .collect();
        LaplaceObs::new(
            q.iter().map(|&i| self.s[i]).collect(),
            q.iter().map(|&i| self.values[i]).collect(),
            w,
        )?
        .with_measurement(self.sensor, None)
    }
}

/// What a fit starts from.
#[derive(Clone, Debug, PartialEq)]
pub enum Observations {
    /// A sampled record of the observed mass.
    Series(Series),
    /// Laplace-domain values.
    Laplace(LaplaceValues),
}

impl Observations {
    /// Number of samples (of every sensor) or nodes.
    pub fn len(&self) -> usize {
        match self {
            Observations::Series(s) => s.t.len() * s.sensors().count(),
            Observations::Laplace(l) => l.s.len(),
        }
    }

    /// Never true for validated observations.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(n: usize) -> Vec<f64> {
        (0..n).map(|i| 0.1 * i as f64).collect()
    }

    #[test]
    fn series_refuses_bad_input_naming_the_field() {
        let field = |e: Error| match e {
            Error::InvalidParameter { field, .. } => field,
            e => panic!("unexpected {e}"),
        };
        assert_eq!(
            field(Series::new(grid(10), vec![0.0; 10], None).unwrap_err()),
            "x"
        );
        assert_eq!(
            field(Series::new(grid(20), vec![0.0; 19], None).unwrap_err()),
            "x"
        );
        let mut x = vec![0.0; 20];
        x[3] = f64::NAN;
        assert_eq!(
            field(Series::new(grid(20), x.clone(), None).unwrap_err()),
            "x[3]"
        );
        x[3] = f64::INFINITY;
        assert_eq!(field(Series::new(grid(20), x, None).unwrap_err()), "x[3]");
        let mut t = grid(20);
        t[5] = t[4];
        assert_eq!(
            field(Series::new(t, vec![0.0; 20], None).unwrap_err()),
            "t[5]"
        );
        assert_eq!(
            field(Series::new(grid(20), vec![0.0; 20], Some(0.0)).unwrap_err()),
            "noise"
        );
        assert_eq!(
            field(Series::new(grid(20), vec![0.0; 20], Some(-1.0)).unwrap_err()),
            "noise"
        );
        let t: Vec<f64> = grid(20).iter().map(|v| v - 1.0).collect();
        assert_eq!(
            field(Series::new(t, vec![0.0; 20], None).unwrap_err()),
            "t[0]"
        );
        assert!(Series::new(grid(16), vec![0.0; 16], Some(1e-3)).is_ok());
    }

    #[test]
    fn missing_column_is_named() {
        // a record with a response (an all-zero one is refused with auto noise)
        let ts = TimeSeries::new(grid(20), vec![("x1".into(), grid(20))]).unwrap();
        let e = Series::from_table(&ts, Some("x7"), None).unwrap_err();
        assert!(
            e.to_string().contains("column") && e.to_string().contains("x1"),
            "{e}"
        );
        assert_eq!(Series::from_table(&ts, None, None).unwrap().x().len(), 20);
    }

    #[test]
    fn laplace_values_checked() {
        let s = vec![Complex64::new(1.0, 0.0)];
        assert!(LaplaceValues::new(s.clone(), vec![], None).is_err());
        assert!(LaplaceValues::new(s.clone(), vec![Complex64::new(f64::NAN, 0.0)], None).is_err());
        assert!(
            LaplaceValues::new(s.clone(), vec![Complex64::new(1.0, 0.0)], Some(vec![0.0])).is_err()
        );
        assert!(LaplaceValues::new(
            vec![Complex64::new(-1.0, 0.0)],
            vec![Complex64::new(1.0, 0.0)],
            None
        )
        .is_err());
        assert!(LaplaceValues::new(s, vec![Complex64::new(1.0, 0.0)], Some(vec![0.1])).is_ok());
    }
}
