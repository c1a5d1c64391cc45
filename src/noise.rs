//! Seeded additive white Gaussian noise for synthetic measurements.
//!
//! `y_i = x_i + sigma z_i`, `z_i` independent standard normal, drawn from
//! `ChaCha8Rng::seed_from_u64(seed)`: the same seed gives the same noise on
//! every machine and thread count. The level is given as
//!
//! * [`NoiseLevel::Absolute`]`(sigma)`: the standard deviation itself;
//! * [`NoiseLevel::Snr`]`(db)`: signal-to-noise ratio in decibels with respect
//!   to the RMS of the signal, `sigma = rms(x) 10^{-db/20}`;
//! * [`NoiseLevel::RelativeMax`]`(r)`: `sigma = r max|x_i|`.
//!
//! ```
//! use springmass::noise::{add_noise, NoiseLevel};
//! let x = vec![1.0, -2.0, 0.5, 0.0];
//! let (y, sigma) = add_noise(&x, NoiseLevel::RelativeMax(1e-3), 7)?;
//! assert_eq!(sigma, 2e-3);
//! assert_eq!(y, add_noise(&x, NoiseLevel::RelativeMax(1e-3), 7)?.0); // reproducible
//! assert!(y.iter().zip(&x).all(|(a, b)| (a - b).abs() < 10.0 * sigma));
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::error::{Error, Result};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// SplitMix64 finaliser: spreads a 64-bit value over all bits (the
/// seeds of independent noise streams: studies' cases, a scene's sensors
/// and records).
pub fn splitmix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// How large the noise is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum NoiseLevel {
    /// Standard deviation `sigma >= 0`.
    Absolute(f64),
    /// Signal-to-noise ratio in dB relative to the RMS of the signal (finite).
    Snr(f64),
    /// `sigma = r max|x|`, `r >= 0`.
    RelativeMax(f64),
}

impl NoiseLevel {
    /// Parse `abs:SIGMA`, `snr:DB` or `rel:R` (for example `abs:1e-4`, `snr:40`, `rel:1e-3`).
    ///
    /// # Errors
    /// [`Error::Parse`] naming the expected forms.
    pub fn parse(text: &str) -> Result<NoiseLevel> {
        let bad = |why: &str| {
            Error::parse(
                "noise level",
                text,
                format!("{why}; expected abs:SIGMA, snr:DB or rel:R (for example abs:1e-4, snr:40, rel:1e-3)"),
            )
        };
        let (kind, val) = text.split_once(':').ok_or_else(|| bad("missing `:`"))?;
        let v: f64 = val
            .trim()
            .parse()
            .map_err(|_| bad("the value is not a number"))?;
        let level = match kind.trim() {
            "abs" => NoiseLevel::Absolute(v),
            "snr" => NoiseLevel::Snr(v),
            "rel" => NoiseLevel::RelativeMax(v),
            _ => return Err(bad("unknown kind")),
        };
        level.check()?;
        Ok(level)
    }

    fn check(&self) -> Result<()> {
        match *self {
            NoiseLevel::Absolute(s) => {
                crate::error::check_f64("noise sigma", s, s >= 0.0, ">= 0 and finite")?;
            }
            NoiseLevel::Snr(db) => {
                crate::error::check_f64("noise snr (dB)", db, true, "finite")?;
            }
            NoiseLevel::RelativeMax(r) => {
                crate::error::check_f64("noise relative level", r, r >= 0.0, ">= 0 and finite")?;
            }
        }
        Ok(())
    }

    /// The standard deviation this level means for the signal `x`.
    ///
    /// # Errors
    /// A negative or non-finite level; a non-finite signal value.
    pub fn sigma(&self, x: &[f64]) -> Result<f64> {
        self.check()?;
        if let Some(i) = x.iter().position(|v| !v.is_finite()) {
            return Err(Error::invalid(format!("x[{i}]"), x[i], "finite"));
        }
        Ok(match *self {
            NoiseLevel::Absolute(s) => s,
            NoiseLevel::Snr(db) => {
                let rms = if x.is_empty() {
                    0.0
                } else {
                    (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt()
                };
                rms * 10f64.powf(-db / 20.0)
            }
            NoiseLevel::RelativeMax(r) => r * x.iter().fold(0.0f64, |a, v| a.max(v.abs())),
        })
    }
}

/// `x + sigma z` with `z` standard normal from `ChaCha8Rng::seed_from_u64(seed)`;
/// returns the noisy copy and `sigma`.
///
/// # Errors
/// As [`NoiseLevel::sigma`].
pub fn add_noise(x: &[f64], level: NoiseLevel, seed: u64) -> Result<(Vec<f64>, f64)> {
    let sigma = level.sigma(x)?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let y = x
        .iter()
        .map(|v| {
            let z: f64 = StandardNormal.sample(&mut rng);
            v + sigma * z
        })
        .collect();
    Ok((y, sigma))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_and_statistics() {
        let x: Vec<f64> = (0..20000).map(|i| (i as f64 * 0.01).sin()).collect();
        let (y, sigma) = add_noise(&x, NoiseLevel::Snr(20.0), 3).unwrap();
        let rms = (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt();
        assert!((rms - 0.5f64.sqrt()).abs() < 1e-2);
        assert!((sigma - rms / 10.0).abs() < 1e-12 * sigma);
        let d: Vec<f64> = y.iter().zip(&x).map(|(a, b)| a - b).collect();
        let mean = d.iter().sum::<f64>() / d.len() as f64;
        let var = d.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / d.len() as f64;
        assert!(mean.abs() < 4.0 * sigma / (d.len() as f64).sqrt());
        assert!((var.sqrt() / sigma - 1.0).abs() < 0.03);
        // different seeds differ, same seed repeats
        assert_ne!(y, add_noise(&x, NoiseLevel::Snr(20.0), 4).unwrap().0);
        assert_eq!(y, add_noise(&x, NoiseLevel::Snr(20.0), 3).unwrap().0);
        assert_eq!(add_noise(&x, NoiseLevel::Absolute(0.0), 1).unwrap().0, x);
    }

    #[test]
    fn parse_and_errors() {
        assert_eq!(
            NoiseLevel::parse("abs:1e-4").unwrap(),
            NoiseLevel::Absolute(1e-4)
        );
        assert_eq!(NoiseLevel::parse("snr:40").unwrap(), NoiseLevel::Snr(40.0));
        assert_eq!(
            NoiseLevel::parse("rel:0.01").unwrap(),
            NoiseLevel::RelativeMax(0.01)
        );
        for bad in ["abs", "abs:x", "foo:1", "abs:-1", "rel:nan", "snr:inf"] {
            assert!(NoiseLevel::parse(bad).is_err(), "{bad}");
        }
        let e = add_noise(&[1.0, f64::NAN], NoiseLevel::Absolute(1.0), 0).unwrap_err();
        assert!(e.to_string().contains("x[1]"));
        let e = add_noise(&[1.0], NoiseLevel::Absolute(-1.0), 0).unwrap_err();
        assert!(e.to_string().contains("noise sigma"));
    }
}
