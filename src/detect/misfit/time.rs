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
//! use springmass::detect::{data::series::TimeData, misfit::time::TimeMisfit};
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
use crate::detect::data::series::TimeData;
use crate::error::Result;
use crate::time::modal::ModalResponse;

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

    /// Model of the record for `chain`: `x_1(t_i)` by the exact modal sum
    /// for the paper's measurement, otherwise as the data's
    /// [`Measurement`](crate::detect::data::measurement::Measurement) says
    /// (another observable or mass, a measured force).
    ///
    /// # Errors
    /// As [`ModalResponse::impulse`] and
    /// [`Measurement::time_model`](crate::detect::data::measurement::Measurement::time_model).
    pub fn model(&self, chain: &Chain) -> Result<Vec<f64>> {
        let m = self.data.measurement();
        if m.is_paper() {
            return Ok(ModalResponse::impulse(chain, 1)?.eval_many(self.data.t()));
        }
        m.time_model(chain, self.data.t())
    }

    /// Whitened residuals `(x_1(t_i) - y_i) / sigma`.
    ///
    /// # Errors
    /// As [`TimeMisfit::model`].
    pub fn residuals(&self, chain: &Chain) -> Result<Vec<f64>> {
        let x = self.model(chain)?;
        Ok(x.iter()
            .zip(self.data.y())
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
    use crate::noise::NoiseLevel;
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
