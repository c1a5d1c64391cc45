//! Intervals for every fitted value of the reported answer, at a level
//! (default 0.9): the Wald interval `value +- z se` where the profile
//! likelihood agrees with it, else the profile-likelihood interval.
//!
//! The profile of parameter `i` is `chi2_p(t) = min chi2` with `theta_i = t`
//! and every other free value refitted (from the linearised path
//! `theta + C[:, i] / C[i, i] (t - theta_i)`). At the Wald ends the profile
//! is compared with `z^2` (`z` the normal quantile of the level), first on
//! the linearised path itself (no refit; exact for a linear model, an upper
//! bound of the profile otherwise): when `sqrt(chi2 - chi2_min)` there is
//! within [`AGREE`] of `z` on both sides and the ends lie inside the search
//! range, the Wald interval is reported (`wald`); otherwise each end is the root of `chi2_p(t) - chi2_min = z^2`
//! (`profile`), or the end of the search range when the profile stays
//! below it there (`profile-bounded`). A value the data do not constrain
//! gets its whole search range (`unconstrained`).

use super::local::{profile_chi2, Local};
use crate::detect::model::MeasurementModel;
use crate::detect::search::lsq::covariance;
use crate::error::{Error, Result};
use nalgebra::DMatrix;
use serde::Serialize;

/// Relative difference between `sqrt(Delta chi2)` at a Wald end and `z`
/// below which the Wald interval stands.
pub const AGREE: f64 = 0.1;

/// The default level of the intervals.
pub const DEFAULT_LEVEL: f64 = 0.9;

/// An interval for one fitted value.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Interval {
    /// Lower end.
    pub lo: f64,
    /// Upper end.
    pub hi: f64,
    /// `wald`, `profile`, `profile-bounded`, `unconstrained` or `known`.
    pub method: &'static str,
}

/// Check a level: `0 < level < 1`.
///
/// # Errors
/// [`Error::InvalidParameter`] naming `level`.
pub fn check_level(level: f64) -> Result<f64> {
    if level > 0.0 && level < 1.0 {
        Ok(level)
    } else {
        Err(Error::invalid(
            "level",
            level,
            "0 < level < 1 (the intervals' coverage, e.g. 0.9)",
        ))
    }
}

/// The two-sided normal quantile of `level`.
fn z_of(level: f64) -> f64 {
    use statrs::distribution::{ContinuousCDF, Normal};
    Normal::new(0.0, 1.0)
        .map(|n| n.inverse_cdf(0.5 + level / 2.0))
        .unwrap_or(1.6448536269514722)
}

/// The intervals of `local`'s free values (in [`Local::params`] order) on
/// `data`, the report's noise level being `ratio` times the one `data`
/// whitens by.
///
/// # Errors
/// The measurement model's errors along a profile.
pub(super) fn intervals(
    local: &Local,
    data: &dyn MeasurementModel,
    ratio: f64,
    level: f64,
) -> Result<Vec<Interval>> {
    let z = z_of(level);
    let Ok(cov) = covariance(&local.jacobian) else {
        return Ok(local
            .bounds
            .iter()
            .map(|&(lo, hi)| Interval {
                lo,
                hi,
                method: "unconstrained",
            })
            .collect());
    };
    (0..local.params.len())
        .map(|i| one(local, data, &cov, i, z, ratio))
        .collect()
}

/// The interval of parameter `i`.
fn one(
    local: &Local,
    data: &dyn MeasurementModel,
    cov: &DMatrix<f64>,
    i: usize,
    z: f64,
    ratio: f64,
) -> Result<Interval> {
    let (lo_b, hi_b) = local.bounds[i];
    let theta = local.theta[i];
    let se = cov[(i, i)].max(0.0).sqrt() * ratio;
    if !(se.is_finite() && se > 0.0) {
        return Ok(Interval {
            lo: lo_b,
            hi: hi_b,
            method: "unconstrained",
        });
    }
    let p = Profile {
        local,
        data,
        cov,
        i,
        ratio,
    };
    let ends = [theta - z * se, theta + z * se];
    let inside = ends.iter().all(|e| *e > lo_b && *e < hi_b);
    if inside {
        let agree = ends
            .iter()
            .map(|&e| p.along_path(e).map(|d| (d.sqrt() - z).abs() <= AGREE * z))
            .collect::<Result<Vec<bool>>>()?;
        if agree.iter().all(|a| *a) {
            return Ok(Interval {
                lo: ends[0],
                hi: ends[1],
                method: "wald",
            });
        }
    }
    let (lo, lo_bounded) = p.end(-1.0, se, z)?;
    let (hi, hi_bounded) = p.end(1.0, se, z)?;
    Ok(Interval {
        lo,
        hi,
        method: if lo_bounded || hi_bounded {
            "profile-bounded"
        } else {
            "profile"
        },
    })
}

/// The profile of one parameter.
struct Profile<'a> {
    local: &'a Local,
    data: &'a dyn MeasurementModel,
    cov: &'a DMatrix<f64>,
    i: usize,
    ratio: f64,
}

impl Profile<'_> {
    /// The other parameters on the linearised profile path at `t`, in
    /// [`Local::params`] order without `i`.
    fn path(&self, t: f64) -> Vec<f64> {
        let (l, i) = (self.local, self.i);
        let step = t - l.theta[i];
        (0..l.theta.len())
            .filter(|&j| j != i)
            .map(|j| {
                let (lo, hi) = l.bounds[j];
                (l.theta[j] + self.cov[(j, i)] / self.cov[(i, i)] * step).clamp(lo, hi)
            })
            .collect()
    }

    /// `chi2 - chi2_min` on the linearised path at `t` (no refit: an upper
    /// bound of the profile's, equal to it for a linear model), at the
    /// report's noise level.
    fn along_path(&self, t: f64) -> Result<f64> {
        let (l, i) = (self.local, self.i);
        let mut chain = l.params[i].set(&l.chain, t)?;
        let others = (0..l.params.len()).filter(|&j| j != i);
        for (j, v) in others.zip(self.path(t)) {
            chain = l.params[j].set(&chain, v)?;
        }
        let c = self.data.chi2(&chain)?;
        Ok(((c - l.chi2) / (self.ratio * self.ratio)).max(0.0))
    }

    /// `chi2_p(t) - chi2_min` at the report's noise level (at least 0).
    fn excess(&self, t: f64) -> Result<f64> {
        let (l, i) = (self.local, self.i);
        let start = self.path(t);
        let c = profile_chi2(l, self.data, i, t, &start)?;
        Ok(((c - l.chi2) / (self.ratio * self.ratio)).max(0.0))
    }

    /// The end on side `dir` (-1 or +1): the root of `sqrt(excess) = z`,
    /// bracketed by doubling from the Wald end, then regula falsi
    /// (Illinois); `true` when the search range's end is reached first.
    fn end(&self, dir: f64, se: f64, z: f64) -> Result<(f64, bool)> {
        let l = self.local;
        let theta = l.theta[self.i];
        let (lo_b, hi_b) = l.bounds[self.i];
        let bound = if dir < 0.0 { lo_b } else { hi_b };
        let clip = |t: f64| t.clamp(lo_b, hi_b);
        let g = |t: f64| -> Result<f64> { Ok(self.excess(t)?.sqrt() - z) };
        let (mut a, mut ga) = (theta, -z);
        let mut b = clip(theta + dir * z * se);
        let mut gb = g(b)?;
        let mut width = z * se;
        while gb < 0.0 {
            if b == bound {
                return Ok((bound, true));
            }
            (a, ga) = (b, gb);
            width *= 2.0;
            b = clip(theta + dir * width);
            gb = g(b)?;
        }
        // Illinois regula falsi on [a, b], g(a) < 0 <= g(b)
        let tol = 1e-4 * se;
        let mut side = 0i8;
        for _ in 0..30 {
            if (b - a).abs() <= tol {
                break;
            }
            let c = b - gb * (b - a) / (gb - ga);
            let gc = g(c)?;
            if gc >= 0.0 {
                (b, gb) = (c, gc);
                if side == 1 {
                    ga /= 2.0;
                }
                side = 1;
            } else {
                (a, ga) = (c, gc);
                if side == -1 {
                    gb /= 2.0;
                }
                side = -1;
            }
        }
        Ok((if gb.abs() < ga.abs() { b } else { a }, false))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn level_and_quantile() {
        assert!(check_level(0.0).is_err());
        assert!(check_level(1.0).is_err());
        assert!(check_level(f64::NAN).is_err());
        assert!((z_of(0.9) - 1.6448536269514722).abs() < 1e-9);
        assert!((z_of(0.5) - 0.6744897501960817).abs() < 1e-9);
    }
}
