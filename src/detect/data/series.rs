//! A sampled series `y_i ~ x_1(t_i)` (or another [`Measurement`]) with its white-noise level: the
//! observation the time-domain misfit ([`crate::detect::misfit::time`]) and
//! the series transform work on.

use crate::chain::Chain;
use crate::detect::data::measurement::{Measurement, Sensor};
use crate::error::{check_f64, Error, Result};
use crate::noise::{add_noise, NoiseLevel};
use crate::series::TimeSeries;
use crate::time::simulate::{simulate, simulate_forced, Force, Forcing, SimOptions};

/// A sampled, noisy observation of `x_1(t)` with its white-noise level.
#[derive(Clone, Debug, PartialEq)]
pub struct TimeData {
    t: Vec<f64>,
    y: Vec<f64>,
    sigma: f64,
    measurement: Measurement,
    /// Further sensors' records at the same times, each with its own noise
    /// level and measurement (empty: one sensor), or further records of
    /// the same chain at times of their own ([`TimeData::with_records`]).
    others: Vec<TimeData>,
}

impl TimeData {
    /// Samples `y` at times `t` with noise standard deviation `sigma` (absolute).
    ///
    /// # Errors
    /// Lengths differ or are zero (field `t`), non-finite values, `sigma < 0`.
    pub fn new(t: Vec<f64>, y: Vec<f64>, sigma: f64) -> Result<TimeData> {
        if t.is_empty() || t.len() != y.len() {
            return Err(Error::invalid(
                "t",
                format!("{} times, {} values", t.len(), y.len()),
                "as many times as values, at least one",
            ));
        }
        for (i, (a, b)) in t.iter().zip(&y).enumerate() {
            check_f64(&format!("t[{i}]"), *a, *a >= 0.0, ">= 0 and finite")?;
            check_f64(&format!("y[{i}]"), *b, true, "finite")?;
        }
        check_f64("sigma", sigma, sigma >= 0.0, ">= 0 and finite")?;
        Ok(TimeData {
            t,
            y,
            sigma,
            measurement: Measurement::paper(),
            others: Vec::new(),
        })
    }

    /// Column `column` of a series (time column `t`), noise level `sigma`.
    ///
    /// # Errors
    /// Missing column; as [`TimeData::new`].
    pub fn from_series(series: &TimeSeries, column: &str, sigma: f64) -> Result<TimeData> {
        TimeData::new(series.t().to_vec(), series.require(column)?.to_vec(), sigma)
    }

    /// Simulate `x_1(t)` of `truth` on `0, dt, ..., t_end` with the time
    /// stepper ([`crate::time::simulate`], method `Auto`) and add seeded white noise
    /// of the given level (`NoiseLevel::RelativeMax(r)`: `sigma = r max|x_1|`).
    ///
    /// # Errors
    /// As [`simulate`] and [`add_noise`].
    pub fn simulate(
        truth: &Chain,
        t_end: f64,
        dt: f64,
        level: NoiseLevel,
        seed: u64,
    ) -> Result<TimeData> {
        let traj = simulate(truth, &SimOptions::new(t_end, dt))?;
        let x = traj
            .x(1)
            .ok_or_else(|| Error::invalid("observe", 1, "mass 1 simulated"))?;
        let (y, sigma) = add_noise(x, level, seed)?;
        TimeData::new(traj.t.clone(), y, sigma)
    }

    /// Simulate the record `sensor` takes of `truth` on `0, dt, ..., t_end`,
    /// driven by the impulse `gamma delta` (`force = None`) or by `force` on
    /// mass 1 (then `gamma` is not applied and the record keeps the force's
    /// samples, as a data logger does: [`Measurement::with_force`]), with
    /// seeded white noise on the response (`NoiseLevel::RelativeMax(r)`:
    /// `sigma = r max|y|`).
    ///
    /// ```
    /// use springmass::{Chain, forward::Observable, noise::NoiseLevel};
    /// use springmass::detect::data::{measurement::Sensor, series::TimeData};
    /// use springmass::time::simulate::Force;
    /// let c = Chain::paper(5)?;
    /// let hammer = Force::func(|t| if t < 0.05 { (std::f64::consts::PI * t / 0.05).sin() } else { 0.0 });
    /// let sensor = Sensor { at: 1, kind: Observable::Acceleration };
    /// let rec = TimeData::simulate_measured(&c, 20.0, 0.01, sensor, Some(hammer), NoiseLevel::Absolute(0.0), 0)?;
    /// assert!(rec.measurement().force().is_some());
    /// # Ok::<(), springmass::Error>(())
    /// ```
    ///
    /// # Errors
    /// As [`simulate_forced`], [`add_noise`] and [`Measurement::with_force`].
    pub fn simulate_measured(
        truth: &Chain,
        t_end: f64,
        dt: f64,
        sensor: Sensor,
        force: Option<Force>,
        level: NoiseLevel,
        seed: u64,
    ) -> Result<TimeData> {
        sensor.check(truth.n())?;
        let opts = SimOptions::new(t_end, dt)
            .with_observe(vec![sensor.at])
            .with_observe_kind(sensor.kind);
        let (traj, measurement) = match force {
            None => (
                simulate(truth, &opts)?,
                Measurement::paper().with_sensor(sensor),
            ),
            Some(f) => {
                let quiet = truth.clone().with_gamma(0.0)?;
                let traj = simulate_forced(&quiet, &opts, &Forcing::new().with(1, f.clone()))?;
                let samples: Vec<f64> = traj.t.iter().map(|&t| f.eval(t)).collect();
                let m = Measurement::paper()
                    .with_sensor(sensor)
                    .with_force(samples)?;
                (traj, m)
            }
        };
        let y = traj
            .x(sensor.at)
            .ok_or_else(|| Error::invalid("observe", sensor.at, "the simulated mass"))?;
        let (y, sigma) = add_noise(y, level, seed)?;
        TimeData::new(traj.t.clone(), y, sigma)?.with_measurement(measurement)
    }

    /// The sample times.
    pub fn t(&self) -> &[f64] {
        &self.t
    }
    /// The samples.
    pub fn y(&self) -> &[f64] {
        &self.y
    }
    /// The stated noise level.
    pub fn sigma(&self) -> f64 {
        self.sigma
    }
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.y.len()
    }
    /// Whether there are no samples (never, by construction).
    pub fn is_empty(&self) -> bool {
        self.y.is_empty()
    }
    /// The weight used: `max(sigma, 8 eps max|y|, 1e-300)`.
    pub fn sigma_eff(&self) -> f64 {
        let ymax = self.y.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        self.sigma.max(8.0 * f64::EPSILON * ymax).max(1e-300)
    }
    /// What the samples measured and what drove the chain (default: the
    /// displacement of mass 1 after the impulse).
    pub fn measurement(&self) -> &Measurement {
        &self.measurement
    }
    /// The same samples as another measurement (sensor, measured force).
    ///
    /// # Errors
    /// As [`Measurement::check_times`].
    pub fn with_measurement(mut self, measurement: Measurement) -> Result<TimeData> {
        measurement.check_times(&self.t)?;
        self.measurement = measurement;
        Ok(self)
    }
    /// The same record with further sensors' records at the same times
    /// (each with its own noise level and measurement; none of them with
    /// further sensors of its own): one joint record of several sensors.
    ///
    /// # Errors
    /// A record at other times (field `sensors`), or one that holds further
    /// sensors itself (field `sensors`).
    pub fn with_others(mut self, others: Vec<TimeData>) -> Result<TimeData> {
        check_joint(
            &self.t,
            others.iter().map(|o| (o.t.as_slice(), o.others.is_empty())),
        )?;
        self.others = others;
        Ok(self)
    }
    /// The same record with further records of the same chain, each at
    /// its own times with its own noise level and measurement (checked by
    /// [`crate::detect::data::observations::Series::with_records`], which
    /// builds them).
    pub(crate) fn with_records(mut self, others: Vec<TimeData>) -> TimeData {
        self.others = others;
        self
    }
    /// The further sensors' records (empty: one sensor).
    pub fn others(&self) -> &[TimeData] {
        &self.others
    }
    /// The same samples with another stated noise level.
    pub fn with_sigma(mut self, sigma: f64) -> Result<TimeData> {
        self.sigma = check_f64("sigma", sigma, sigma >= 0.0, ">= 0 and finite")?;
        Ok(self)
    }
}

/// The check of a joint record of several sensors: every further sensor's
/// record (its times, and whether it holds no further sensors of its own)
/// at the first sensor's times `t`, with no further sensors of its own.
///
/// # Errors
/// [`Error::InvalidParameter`] naming `sensors` and the sensor's place.
pub(crate) fn check_joint<'a>(
    t: &[f64],
    others: impl ExactSizeIterator<Item = (&'a [f64], bool)>,
) -> Result<()> {
    let count = others.len() + 1;
    for (j, (ot, single)) in others.enumerate() {
        if ot != t || !single {
            return Err(Error::invalid(
                "sensors",
                format!("sensor {} of {count}", j + 2),
                "records at the first sensor's times, with no further sensors of their own",
            ));
        }
    }
    Ok(())
}
