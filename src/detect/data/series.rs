//! A sampled series `y_i ~ x_1(t_i)` with its white-noise level: the
//! observation the time-domain misfit ([`crate::detect::misfit::time`]) and
//! the series transform work on.

use crate::chain::Chain;
use crate::error::{check_f64, Error, Result};
use crate::noise::{add_noise, NoiseLevel};
use crate::series::TimeSeries;
use crate::time::simulate::{simulate, SimOptions};

/// A sampled, noisy observation of `x_1(t)` with its white-noise level.
#[derive(Clone, Debug, PartialEq)]
pub struct TimeData {
    t: Vec<f64>,
    y: Vec<f64>,
    sigma: f64,
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
        Ok(TimeData { t, y, sigma })
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
    /// The same samples with another stated noise level.
    pub fn with_sigma(mut self, sigma: f64) -> Result<TimeData> {
        self.sigma = check_f64("sigma", sigma, sigma >= 0.0, ">= 0 and finite")?;
        Ok(self)
    }
}
