//! Observed data `X_1*(s)`: where it comes from, its error, and its values
//! at the quadrature nodes.
//!
//! A [`Data`] object owns the source of the observation and its noise level,
//! so that a misfit can weight by it (SimPEG's split: the noise level belongs
//! to the data, not to the misfit).
//!
//! * [`Source::Exact`]: synthetic data from the closed-form model of a chain
//!   with known (true) defects. Error estimate per node: 4 ulps of `|X_1|`.
//! * [`Source::Series`]: the Laplace transform of a sampled `x_1(t)` (the
//!   paper's pipeline), by [`crate::time::series::SeriesTransform`]: from a
//!   simulation of the true chain ([`Data::simulated`], optionally with seeded
//!   white noise on the samples) or from a measured CSV ([`Data::from_csv`]).
//!   Error estimate per node: the transform's discretisation + truncation +
//!   rounding estimate plus the noise's standard deviation.
//! * Optional seeded relative Gaussian noise in the Laplace domain: `X* (1 + level xi)` on the real
//!   axis, `X* + level |X*| (xi_1 + i xi_2) / sqrt 2` on complex nodes, with
//!   `xi ~ N(0, 1)` drawn from `ChaCha8Rng::seed_from_u64(seed)` in node order;
//!   error estimate `hypot(level |X*|, 4 eps |X*|)`.
//!
//! ```
//! use springmass::{Chain, Defect, detect::data::exact::Data};
//! let truth = Chain::paper(5)?.with_defect(Defect::Mass { at: 2, m: 3.0 })?;
//! let data = Data::exact(&truth);
//! let at = data.sample(&[0.5_f64, 1.0])?;
//! assert_eq!(at.values.len(), 2);
//! assert!((at.values[0] - springmass::forward::response(&truth, 0.5, 1)?).abs() == 0.0);
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::chain::Chain;
use crate::error::{check_f64, Error, Result};
use crate::forward::Forward;
use crate::scalar::Scalar;
use crate::series::TimeSeries;
use crate::time::series::{SeriesTransform, TransformOptions};
use crate::time::simulate::{simulate, SimOptions};
use num_complex::Complex64;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// Where the observation comes from.
#[derive(Clone, Debug)]
#[non_exhaustive]
pub enum Source {
    /// The closed-form model of a chain with its true defects.
    Exact {
        /// The true chain.
        chain: Chain,
    },
    /// Values given at fixed nodes (a user's Laplace data with their
    /// errors); they can be sampled at those nodes only.
    Values {
        /// The nodes.
        s: Vec<Complex64>,
        /// `X_1(s_q)`.
        values: Vec<Complex64>,
        /// Standard error per node (absolute).
        sigma: Vec<f64>,
    },
    /// The Laplace transform of a sampled series.
    Series {
        /// The prepared transform.
        transform: Box<SeriesTransform>,
        /// Where the series came from (for reports).
        origin: String,
        /// The true chain, when the series was simulated.
        truth: Option<Chain>,
    },
}

/// Observed `X_1*(s)` with its noise model.
#[derive(Clone, Debug)]
pub struct Data {
    source: Source,
    forward: Forward,
    noise: f64,
    seed: u64,
}

/// Data values at a set of nodes with their error estimates.
#[derive(Clone, Debug, PartialEq)]
pub struct Samples<T> {
    /// `X_1*(s_q)` (noisy if the data has a noise level).
    pub values: Vec<T>,
    /// Standard error estimate per node (absolute).
    pub sigma: Vec<f64>,
}

/// Relative rounding error assumed for exact values.
const ROUNDING: f64 = 4.0 * f64::EPSILON;

impl Data {
    /// Synthetic data from the exact model of `truth` (observing mass 1).
    pub fn exact(truth: &Chain) -> Data {
        Data {
            source: Source::Exact {
                chain: truth.clone(),
            },
            forward: Forward::new(truth),
            noise: 0.0,
            seed: 0,
        }
    }

    /// Laplace values `X_1(s_q)` at fixed nodes with their standard errors.
    ///
    /// # Errors
    /// Lengths that differ or are zero, a value or node that is not finite,
    /// an error that is not positive (field `values`).
    pub fn at_nodes(s: Vec<Complex64>, values: Vec<Complex64>, sigma: Vec<f64>) -> Result<Data> {
        super::check_lengths(
            "values",
            s.len(),
            values.len(),
            (sigma.len(), "errors"),
            "as many values and errors as nodes, at least one",
        )?;
        let finite = |z: &Complex64| z.re.is_finite() && z.im.is_finite();
        if !(s.iter().all(finite)
            && values.iter().all(finite)
            && sigma.iter().all(|e| e.is_finite() && *e > 0.0))
        {
            return Err(Error::invalid(
                "values",
                "a node, value or error out of range",
                "finite nodes and values, errors > 0",
            ));
        }
        Ok(Data {
            source: Source::Values { s, values, sigma },
            forward: Forward::new(&Chain::paper(1)?),
            noise: 0.0,
            seed: 0,
        })
    }

    /// Data from samples `x_1(t_i)` (uniform or not), with the white-noise
    /// standard deviation of the samples if known.
    ///
    /// # Errors
    /// As [`SeriesTransform::new`].
    pub fn from_samples(
        t: &[f64],
        x: &[f64],
        noise_sigma: Option<f64>,
        origin: impl Into<String>,
    ) -> Result<Data> {
        let opts = TransformOptions {
            noise_sigma,
            ..TransformOptions::default()
        };
        let transform = SeriesTransform::new(t, x, &opts)?;
        Ok(Data::series(transform, origin.into(), None))
    }

    /// Data from a CSV time series (column `column`, for example `x1`).
    ///
    /// # Errors
    /// I/O and parse errors; a missing column; as [`SeriesTransform::new`].
    pub fn from_csv(
        path: impl AsRef<std::path::Path>,
        column: &str,
        noise_sigma: Option<f64>,
    ) -> Result<Data> {
        let ts = TimeSeries::read_csv(path.as_ref())?;
        let x = ts.require(column)?;
        Data::from_samples(ts.t(), x, noise_sigma, path.as_ref().display().to_string())
    }

    /// The paper's pipeline: simulate `x_1(t)` of `truth` on `[0, t_end]` with
    /// output step `dt`, add white noise of standard deviation `noise_sigma`
    /// (seeded, `0` for none) to the samples, and Laplace-transform them.
    ///
    /// # Errors
    /// As [`simulate`]; `noise_sigma` negative or not finite (field `data.noise`).
    pub fn simulated(
        truth: &Chain,
        t_end: f64,
        dt: f64,
        noise_sigma: f64,
        seed: u64,
    ) -> Result<Data> {
        check_f64(
            "data.noise",
            noise_sigma,
            noise_sigma >= 0.0,
            ">= 0 and finite",
        )?;
        let traj = simulate(truth, &SimOptions::new(t_end, dt))?;
        let x = traj.x(1).ok_or_else(|| Error::Numerical {
            method: "simulate".into(),
            reason: "mass 1 not observed".into(),
        })?;
        let x: Vec<f64> = if noise_sigma > 0.0 {
            crate::noise::add_noise(x, crate::noise::NoiseLevel::Absolute(noise_sigma), seed)?.0
        } else {
            x.to_vec()
        };
        let opts = TransformOptions {
            noise_sigma: (noise_sigma > 0.0).then_some(noise_sigma),
            ..TransformOptions::default()
        };
        let transform = SeriesTransform::new(&traj.t, &x, &opts)?;
        Ok(Data::series(
            transform,
            format!("simulated x_1(t), t in [0, {t_end}], dt = {dt}, noise sigma = {noise_sigma}"),
            Some(truth.clone()),
        ))
    }

    fn series(transform: SeriesTransform, origin: String, truth: Option<Chain>) -> Data {
        // the forward model is unused for series data; keep a valid placeholder
        let placeholder = truth
            .clone()
            .unwrap_or_else(|| Chain::new(1).expect("n = 1 is valid"));
        Data {
            source: Source::Series {
                transform: Box::new(transform),
                origin,
                truth,
            },
            forward: Forward::new(&placeholder),
            noise: 0.0,
            seed: 0,
        }
    }

    /// Add relative Gaussian noise of standard deviation `level`, drawn with `seed`.
    ///
    /// # Errors
    /// `level` negative or not finite (field `data.noise`).
    pub fn with_noise(mut self, level: f64, seed: u64) -> Result<Data> {
        self.noise = check_f64("data.noise", level, level >= 0.0, ">= 0 and finite")?;
        self.seed = seed;
        Ok(self)
    }

    /// The source.
    pub fn source(&self) -> &Source {
        &self.source
    }

    /// The noise level (relative standard deviation).
    pub fn noise(&self) -> f64 {
        self.noise
    }

    /// The noise seed.
    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// The true chain, when the data are synthetic.
    pub fn truth(&self) -> Option<&Chain> {
        match &self.source {
            Source::Exact { chain } => Some(chain),
            Source::Series { truth, .. } => truth.as_ref(),
            Source::Values { .. } => None,
        }
    }

    /// Value and error estimate (absolute) at one `s`, noiseless.
    fn value_err<T: Scalar>(&self, s: T) -> Result<(T, f64)> {
        match &self.source {
            Source::Exact { .. } => {
                let x = self.forward.eval(s, 1)?;
                let e = ROUNDING * x.magnitude();
                Ok((x, e))
            }
            Source::Series { transform, .. } => {
                crate::forward::check_s(&s)?;
                let z = s.to_c64();
                let v = transform.eval(z)?;
                let err = v.err + v.noise_var.unwrap_or(0.0).sqrt();
                let x = if z.im == 0.0 {
                    T::from_c64(Complex64::new(v.value.re, 0.0))
                } else {
                    T::from_c64(v.value)
                };
                let x = x.ok_or_else(|| Error::invalid("s", z, "a value of the node type"))?;
                Ok((x, err))
            }
            Source::Values {
                s: nodes,
                values,
                sigma,
            } => {
                let z = s.to_c64();
                let q = nodes.iter().position(|n| *n == z).ok_or_else(|| {
                    Error::invalid("s", z, "one of the nodes the values are given at")
                })?;
                let x = T::from_c64(values[q])
                    .ok_or_else(|| Error::invalid("s", z, "a value of the node type"))?;
                Ok((x, sigma[q]))
            }
        }
    }

    /// The sampled record behind series data (times, values as sampled,
    /// noise included), `None` for exact-model data.
    pub fn samples(&self) -> Option<(&[f64], &[f64])> {
        match &self.source {
            Source::Series { transform, .. } => Some(transform.samples()),
            Source::Exact { .. } | Source::Values { .. } => None,
        }
    }

    /// The noiseless value at one `s` (for the adaptive reference).
    ///
    /// # Errors
    /// As [`Forward::eval`].
    pub fn value<T: Scalar>(&self, s: T) -> Result<T> {
        Ok(self.value_err(s)?.0)
    }

    /// Values (with the data's noise, seeded) and error estimates at `nodes`.
    ///
    /// # Errors
    /// As [`Forward::eval`] for any node.
    pub fn sample<T: Scalar>(&self, nodes: &[T]) -> Result<Samples<T>> {
        let is_real = T::from_c64(Complex64::new(0.0, 1.0)).is_none();
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        let mut values = Vec::with_capacity(nodes.len());
        let mut sigma = Vec::with_capacity(nodes.len());
        for s in nodes {
            let (x, err) = self.value_err(s.clone())?;
            let mag = x.magnitude();
            sigma.push((self.noise * mag).hypot(err));
            if self.noise > 0.0 {
                let a: f64 = StandardNormal.sample(&mut rng);
                if is_real {
                    values.push(x.clone() + x.scale(self.noise * a));
                } else {
                    let b: f64 = StandardNormal.sample(&mut rng);
                    let dz = Complex64::new(a, b) * (self.noise * mag / std::f64::consts::SQRT_2);
                    values.push(x + T::from_c64(dz).expect("complex type"));
                }
            } else {
                values.push(x);
            }
        }
        Ok(Samples { values, sigma })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn s3() -> Chain {
        crate::scenes::table1(3).unwrap()
    }

    #[test]
    fn exact_data_matches_reference_json() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/laplace_S3.json");
        let text = std::fs::read_to_string(path)
            .unwrap_or_else(|e| panic!("reference {path} missing: {e}"));
        let v: serde_json::Value = serde_json::from_str(&text).unwrap();
        let data = Data::exact(&s3());
        for p in v["real_s"].as_array().unwrap() {
            let s = p["s"].as_f64().unwrap();
            let x: f64 = p["X1_str"].as_str().unwrap().parse().unwrap();
            let got = data.value(s).unwrap();
            assert!((got - x).abs() <= 1e-13 * x.abs(), "s {s}: {got} vs {x}");
        }
    }

    #[test]
    fn simulated_series_data_match_the_model() {
        let c = crate::scenes::table1(1).unwrap();
        let d = Data::simulated(&c, 300.0, 0.05, 0.0, 0).unwrap();
        let exact = Data::exact(&c);
        for s in [0.2, 1.0, 5.0] {
            let sm = d.sample(&[s]).unwrap();
            let x = exact.value(s).unwrap();
            assert!(
                (sm.values[0] - x).abs() <= sm.sigma[0].max(1e-12),
                "s {s}: {} vs {x} (+-{})",
                sm.values[0],
                sm.sigma[0]
            );
        }
        let z = Complex64::new(0.1, 1.3);
        let sm = d.sample(&[z]).unwrap();
        assert!((sm.values[0] - exact.value(z).unwrap()).norm() <= sm.sigma[0].max(1e-12));
        assert!(d.truth().is_some());
        assert!(Data::simulated(&c, 300.0, 0.05, -1.0, 0).is_err());
    }

    #[test]
    fn noise_is_seeded_and_sized() {
        let nodes: Vec<f64> = (1..=2000).map(|i| i as f64 * 0.01).collect();
        let a = Data::exact(&s3()).with_noise(1e-3, 7).unwrap();
        let x = a.sample(&nodes).unwrap();
        let y = a.sample(&nodes).unwrap();
        assert_eq!(x, y);
        let clean = Data::exact(&s3()).sample(&nodes).unwrap();
        let rel: Vec<f64> = x
            .values
            .iter()
            .zip(&clean.values)
            .map(|(a, b)| (a - b) / b)
            .collect();
        let rms = (rel.iter().map(|r| r * r).sum::<f64>() / rel.len() as f64).sqrt();
        assert!((rms - 1e-3).abs() < 1e-4, "rms {rms}");
        let other = Data::exact(&s3()).with_noise(1e-3, 8).unwrap();
        assert_ne!(other.sample(&nodes).unwrap().values, x.values);
        assert!((x.sigma[0] / clean.values[0] - 1e-3).abs() < 1e-9);
        assert!(Data::exact(&s3()).with_noise(-1.0, 0).is_err());
        let zc = [Complex64::new(0.1, 1.0)];
        let c = a.sample(&zc).unwrap();
        assert!(c.values[0].im != clean.values[0]);
    }
}
