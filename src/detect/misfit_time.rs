//! Time-domain misfit: the chi-square between a sampled series `y_i ~ x_1(t_i)`
//! and the model's exact `x_1(t)` (finite modal sum, [`crate::time::modal`]).
//!
//! `chi^2 = sum_i (x_1(t_i; chain) - y_i)^2 / sigma^2`
//!
//! with `sigma` the data's white-noise level, which belongs to the data object
//! ([`TimeData`]); at the truth `chi^2` is a chi-square variable with as many
//! degrees of freedom as samples. With noise-free data `sigma` is replaced by
//! an effective floor `8 eps max|y|` (see [`TimeData::sigma_eff`]).
//!
//! Unlike the real-axis residual, this misfit keeps the conditioning of the
//! measurement: moving a deep defect by one position changes `x_1(t)` by per
//! cents, not by `1e-13` (docs/paper-notes.md, "Why deep defects are hard on the real s axis").
//!
//! ```
//! use springmass::{Chain, Defect, noise::NoiseLevel};
//! use springmass::detect::misfit_time::{TimeData, TimeMisfit};
//! let truth = Chain::paper(20)?.with_defects([
//!     Defect::Mass { at: 8, m: 5.0 }, Defect::Mass { at: 15, m: 2.0 }])?;
//! let data = TimeData::simulate(&truth, 200.0, 0.5, NoiseLevel::RelativeMax(1e-3), 7)?;
//! let misfit = TimeMisfit::new(data);
//! let right = misfit.chi2(&truth)?;
//! let wrong = misfit.chi2(&Chain::paper(20)?.with_defects([
//!     Defect::Mass { at: 8, m: 5.0 }, Defect::Mass { at: 16, m: 2.0 }])?)?;
//! assert!(right < 2.0 * 401.0 && wrong > right + 1000.0);  // 401 samples
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::chain::Chain;
use crate::error::{check_f64, Error, Result};
use crate::noise::{add_noise, NoiseLevel};
use crate::series::TimeSeries;
use crate::time::modal::ModalResponse;
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

/// The time-domain chi-square of a candidate chain against [`TimeData`].
#[derive(Clone, Debug)]
pub struct TimeMisfit {
    data: TimeData,
    inv_sigma: f64,
}

impl TimeMisfit {
    /// Misfit against `data`.
    pub fn new(data: TimeData) -> TimeMisfit {
        let inv_sigma = 1.0 / data.sigma_eff();
        TimeMisfit { data, inv_sigma }
    }

    /// The data.
    pub fn data(&self) -> &TimeData {
        &self.data
    }

    /// Model `x_1(t_i)` of `chain` (exact modal sum).
    ///
    /// # Errors
    /// As [`ModalResponse::impulse`].
    pub fn model(&self, chain: &Chain) -> Result<Vec<f64>> {
        Ok(ModalResponse::impulse(chain, 1)?.eval_many(&self.data.t))
    }

    /// Whitened residuals `(x_1(t_i) - y_i) / sigma`.
    ///
    /// # Errors
    /// As [`TimeMisfit::model`].
    pub fn residuals(&self, chain: &Chain) -> Result<Vec<f64>> {
        let x = self.model(chain)?;
        Ok(x.iter()
            .zip(&self.data.y)
            .map(|(a, b)| (a - b) * self.inv_sigma)
            .collect())
    }

    /// `chi^2 = sum (x_1(t_i) - y_i)^2 / sigma^2`.
    ///
    /// # Errors
    /// As [`TimeMisfit::model`].
    pub fn chi2(&self, chain: &Chain) -> Result<f64> {
        Ok(self.residuals(chain)?.iter().map(|r| r * r).sum())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Defect;

    #[test]
    fn chi2_is_a_chi_square_at_the_truth() {
        let truth = Chain::paper(10)
            .unwrap()
            .with_defects([
                Defect::Mass { at: 3, m: 3.0 },
                Defect::Mass { at: 7, m: 2.0 },
            ])
            .unwrap();
        let mut sum = 0.0;
        let reps = 20;
        for seed in 0..reps {
            let data = TimeData::simulate(&truth, 100.0, 0.5, NoiseLevel::RelativeMax(1e-3), seed)
                .unwrap();
            sum += TimeMisfit::new(data).chi2(&truth).unwrap();
        }
        let mean = sum / reps as f64;
        // 201 degrees of freedom, sd of the mean sqrt(2*201/20) = 4.5
        assert!((mean - 201.0).abs() < 20.0, "mean chi2 {mean}");
    }

    #[test]
    fn bad_input() {
        assert!(TimeData::new(vec![], vec![], 0.1).is_err());
        assert!(TimeData::new(vec![0.0], vec![1.0, 2.0], 0.1).is_err());
        assert!(TimeData::new(vec![0.0], vec![f64::NAN], 0.1).is_err());
        assert!(TimeData::new(vec![0.0], vec![1.0], -0.1).is_err());
        let d = TimeData::new(vec![0.0, 1.0], vec![0.0, 0.0], 0.0).unwrap();
        assert!(d.sigma_eff() > 0.0);
    }
}
