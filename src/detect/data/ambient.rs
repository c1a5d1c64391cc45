//! Output-only (ambient) records: several response channels of a chain
//! shaken by an unknown broadband force, and their Welch cross-spectral
//! matrix.
//!
//! A record is a CSV with a time column and one value column per observed
//! mass, in the order of `observe` (read by the project's lab CSV reader,
//! [`TimeSeries::read_csv`]). The sampling must be uniform.
//!
//! The spectrum ([`welch`]) is the averaged cross-periodogram of `K`
//! Hann-windowed segments of `L` samples with 50% overlap:
//! `G_ab(w_j) = dt / (K U) sum_s X_a,s(w_j) conj(X_b,s(w_j))` with
//! `U = sum w_n^2`, one-sided bins `w_j = 2 pi j / (L dt)`. The segment
//! length is chosen from the nominal chain ([`segment_length`]) so that the
//! first mode and the narrowest resonance are resolved by several bins.
//!
//! ```
//! use springmass::detect::data::ambient::{AmbientRecord, welch};
//! use springmass::forward::Observable;
//! let y: Vec<f64> = (0..4096).map(|i| ((i * 7919) % 101) as f64 / 101.0 - 0.5).collect();
//! let rec = AmbientRecord::new(0.5, vec![1], Observable::Displacement, vec![y])?;
//! let g = welch(&rec, 256)?;
//! assert_eq!(g.segments, 31);
//! assert_eq!(g.omega.len(), 129);
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::chain::Chain;
use crate::error::{Error, Result};
use crate::forward::Observable;
use crate::series::TimeSeries;
use nalgebra::DMatrix;
use num_complex::Complex64;
use std::f64::consts::TAU;
use std::path::Path;

/// Fewest segments averaged: fewer leave the spectral matrix too noisy
/// (and, below the number of channels, singular).
pub const MIN_SEGMENTS: usize = 8;

/// An output-only record: a uniform step and one channel per observed mass.
#[derive(Clone, Debug, PartialEq)]
pub struct AmbientRecord {
    /// Sampling step.
    pub dt: f64,
    /// Observed masses (1-based), one per channel, in column order.
    pub observe: Vec<usize>,
    /// What every channel measured.
    pub kind: Observable,
    /// The channels, each `len` samples.
    pub channels: Vec<Vec<f64>>,
}

impl AmbientRecord {
    /// Build and validate.
    ///
    /// # Errors
    /// `dt` not positive and finite; `observe` empty, with a repeated or
    /// zero mass, or not one per channel; channels of unequal length,
    /// non-finite, or constant (field `channel J (mass I)`: a dead sensor).
    pub fn new(
        dt: f64,
        observe: Vec<usize>,
        kind: Observable,
        channels: Vec<Vec<f64>>,
    ) -> Result<AmbientRecord> {
        if !(dt > 0.0 && dt.is_finite()) {
            return Err(Error::invalid("dt", dt, "> 0 and finite"));
        }
        check_observe(&observe, channels.len())?;
        let len = channels[0].len();
        for (j, c) in channels.iter().enumerate() {
            let field = format!("channel {} (mass {})", j + 1, observe[j]);
            if c.len() != len {
                return Err(Error::invalid(field, c.len(), format!("{len} samples")));
            }
            if let Some(i) = c.iter().position(|v| !v.is_finite()) {
                return Err(Error::invalid(format!("{field}[{i}]"), c[i], "finite"));
            }
            if is_constant(c) {
                return Err(Error::invalid(
                    field,
                    "constant",
                    "a varying signal (a constant channel carries no spectrum: a dead or clipped sensor?)",
                ));
            }
        }
        Ok(AmbientRecord {
            dt,
            observe,
            kind,
            channels,
        })
    }

    /// The channels of a series, in column order, one per `observe` entry.
    ///
    /// # Errors
    /// Non-uniform times (field `t`); a column count other than
    /// `observe.len()` (field `observe`); as [`AmbientRecord::new`].
    pub fn from_series(
        ts: &TimeSeries,
        observe: Vec<usize>,
        kind: Observable,
    ) -> Result<AmbientRecord> {
        let dt = uniform_step(ts)?;
        let p = ts.names().len();
        if p != observe.len() {
            return Err(Error::invalid(
                "observe",
                format!("{observe:?}"),
                format!("one mass per value column of the record ({p} columns; --column a,b picks some)"),
            ));
        }
        let channels = (0..p)
            .map(|i| ts.column_at(i).expect("counted").to_vec())
            .collect();
        AmbientRecord::new(dt, observe, kind, channels)
    }

    /// The record of the value columns `columns` of `ts` (names or 1-based
    /// numbers, one per observed mass, in order); every value column when
    /// `columns` is empty ([`AmbientRecord::from_series`]).
    ///
    /// # Errors
    /// A column not in the record, or not one per observed mass (field
    /// `column`); as [`AmbientRecord::new`].
    ///
    /// ```
    /// use springmass::series::TimeSeries;
    /// use springmass::{detect::data::ambient::AmbientRecord, forward::Observable};
    /// let ts = TimeSeries::from_csv_str("t,x1,x5,x9\n0,1,2,3\n1,2,1,0\n2,0,3,1\n")?;
    /// let r = AmbientRecord::from_series_columns(&ts, &["x9", "x1"], vec![9, 1], Observable::Displacement)?;
    /// assert_eq!(r.channels[0], vec![3.0, 0.0, 1.0]);
    /// assert!(AmbientRecord::from_series_columns(&ts, &["x1"], vec![1, 9], Observable::Displacement).is_err());
    /// # Ok::<(), springmass::Error>(())
    /// ```
    pub fn from_series_columns(
        ts: &TimeSeries,
        columns: &[&str],
        observe: Vec<usize>,
        kind: Observable,
    ) -> Result<AmbientRecord> {
        if columns.is_empty() {
            return AmbientRecord::from_series(ts, observe, kind);
        }
        if columns.len() != observe.len() {
            return Err(Error::invalid(
                "column",
                columns.join(","),
                format!(
                    "one column per observed mass ({} masses in --observe)",
                    observe.len()
                ),
            ));
        }
        let dt = uniform_step(ts)?;
        let channels = columns
            .iter()
            .map(|c| ts.select(c).map(|(_, v)| v.to_vec()))
            .collect::<Result<Vec<_>>>()?;
        AmbientRecord::new(dt, observe, kind, channels)
    }

    /// Read a CSV record (see the module docs).
    ///
    /// # Errors
    /// As [`TimeSeries::read_csv`] and [`AmbientRecord::from_series`].
    pub fn read_csv(
        path: impl AsRef<Path>,
        observe: Vec<usize>,
        kind: Observable,
    ) -> Result<AmbientRecord> {
        AmbientRecord::from_series(&TimeSeries::read_csv(path)?, observe, kind)
    }

    /// Samples per channel.
    pub fn len(&self) -> usize {
        self.channels[0].len()
    }

    /// Never true for a validated record.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// The record's sampling step.
///
/// # Errors
/// A non-uniform one (field `t`).
fn uniform_step(ts: &TimeSeries) -> Result<f64> {
    ts.uniform_step(1e-6).ok_or_else(|| {
        Error::invalid(
            "t",
            "non-uniform",
            "a uniform sampling step (resample the record first)",
        )
    })
}

fn check_observe(observe: &[usize], channels: usize) -> Result<()> {
    if observe.is_empty() || observe.len() != channels {
        return Err(Error::invalid(
            "observe",
            format!("{observe:?}"),
            format!("one observed mass per channel ({channels} channels)"),
        ));
    }
    for (i, &m) in observe.iter().enumerate() {
        if m == 0 || observe[..i].contains(&m) {
            return Err(Error::invalid(
                "observe",
                format!("{observe:?}"),
                "distinct masses, 1-based",
            ));
        }
    }
    Ok(())
}

fn is_constant(c: &[f64]) -> bool {
    let mean = c.iter().sum::<f64>() / c.len() as f64;
    let scale = c.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
    let var = c.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / c.len() as f64;
    var.sqrt() <= 1e-12 * scale || scale == 0.0
}

/// A Welch cross-spectral matrix.
#[derive(Clone, Debug, PartialEq)]
pub struct CrossSpectrum {
    /// Bin frequencies `2 pi j / (L dt)`, `j = 0..=L/2` (rad per unit time).
    pub omega: Vec<f64>,
    /// The `p x p` Hermitian matrix at every bin.
    pub g: Vec<DMatrix<Complex64>>,
    /// Number of segments averaged, `K`.
    pub segments: usize,
    /// Segment length `L` (samples).
    pub seg_len: usize,
    /// Sampling step.
    pub dt: f64,
}

impl CrossSpectrum {
    /// Bin width `2 pi / (L dt)`.
    pub fn bin(&self) -> f64 {
        TAU / (self.seg_len as f64 * self.dt)
    }

    /// The equivalent number of independent segments: `K / (1 + 2 rho^2)`
    /// with `rho = 1/6`, the Hann window's correlation at 50% overlap.
    pub fn effective_segments(&self) -> f64 {
        self.segments as f64 / (1.0 + 2.0 / 36.0)
    }
}

/// The periodic Hann window of `len` samples.
pub fn hann(len: usize) -> Vec<f64> {
    (0..len)
        .map(|n| 0.5 - 0.5 * (TAU * n as f64 / len as f64).cos())
        .collect()
}

/// The Welch cross-spectral matrix of `rec` with segments of `seg_len`
/// samples (see the module docs).
///
/// # Errors
/// `seg_len` below 16 or odd (field `seg_len`); fewer than
/// [`MIN_SEGMENTS`] segments (field `samples`: the record is too short).
pub fn welch(rec: &AmbientRecord, seg_len: usize) -> Result<CrossSpectrum> {
    if seg_len < 16 || !seg_len.is_multiple_of(2) {
        return Err(Error::invalid("seg_len", seg_len, "even and >= 16"));
    }
    let hop = seg_len / 2;
    let k = if rec.len() >= seg_len {
        (rec.len() - seg_len) / hop + 1
    } else {
        0
    };
    if k < MIN_SEGMENTS {
        return Err(Error::invalid(
            "samples",
            rec.len(),
            format!(
                ">= {} to average {MIN_SEGMENTS} segments of {seg_len} samples (the record is too short to resolve the chain's first mode)",
                hop * (MIN_SEGMENTS + 1)
            ),
        ));
    }
    let w = hann(seg_len);
    let u: f64 = w.iter().map(|v| v * v).sum();
    let p = rec.channels.len();
    let bins = seg_len / 2 + 1;
    let mut g = vec![DMatrix::<Complex64>::zeros(p, p); bins];
    let fft = rustfft::FftPlanner::new().plan_fft_forward(seg_len);
    for s in 0..k {
        let spectra: Vec<Vec<Complex64>> = rec
            .channels
            .iter()
            .map(|c| dft(&c[s * hop..s * hop + seg_len], &w, fft.as_ref()))
            .collect();
        for (j, gj) in g.iter_mut().enumerate() {
            for a in 0..p {
                for b in 0..p {
                    gj[(a, b)] += spectra[a][j] * spectra[b][j].conj();
                }
            }
        }
    }
    let scale = rec.dt / (k as f64 * u);
    for gj in &mut g {
        *gj *= Complex64::new(scale, 0.0);
    }
    let omega = (0..bins)
        .map(|j| TAU * j as f64 / (seg_len as f64 * rec.dt))
        .collect();
    Ok(CrossSpectrum {
        omega,
        g,
        segments: k,
        seg_len,
        dt: rec.dt,
    })
}

/// Windowed, de-meaned DFT of one segment at bins `0..=L/2` (`sum_n y_n
/// e^{-2 pi i j n / L}`, by the FFT `fft` of length `L`).
fn dft(x: &[f64], w: &[f64], fft: &dyn rustfft::Fft<f64>) -> Vec<Complex64> {
    let len = x.len();
    let mean = x.iter().sum::<f64>() / len as f64;
    let mut y: Vec<Complex64> = x
        .iter()
        .zip(w)
        .map(|(v, w)| Complex64::new((v - mean) * w, 0.0))
        .collect();
    fft.process(&mut y);
    y.truncate(len / 2 + 1);
    y
}

/// The segment length for `nominal`: the smallest power of two whose bin
/// is at most a quarter of the first natural frequency and at most half
/// the narrowest half-power bandwidth `2 zeta_j omega_j`.
///
/// # Errors
/// A chain with a rigid-body mode (field `ends`); the eigen solver's.
pub fn segment_length(nominal: &Chain, dt: f64) -> Result<usize> {
    let modes = crate::time::modal::natural_modes(nominal)?;
    let w1 = modes.first().map_or(0.0, |m| m.omega);
    if w1 <= 0.0 {
        return Err(Error::invalid(
            "ends",
            "free-free",
            "a chain held to the ground (a rigid-body mode has no resonance to fit)",
        ));
    }
    let mut target = w1 / 4.0;
    for m in &modes {
        if let Some(z) = m.zeta.filter(|z| *z > 0.0) {
            target = target.min(z * m.omega);
        }
    }
    let mut len = 16usize;
    while TAU / (len as f64 * dt) > target && len < (1 << 24) {
        len *= 2;
    }
    Ok(len)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn white_noise_has_a_flat_spectrum_of_its_variance_times_dt() {
        // a deterministic pseudo-random sequence of variance ~1/12
        let mut state = 12345u64;
        let y: Vec<f64> = (0..20_000)
            .map(|_| {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            })
            .collect();
        let rec = AmbientRecord::new(0.5, vec![3], Observable::Velocity, vec![y]).unwrap();
        let g = welch(&rec, 256).unwrap();
        let mean: f64 = g.g[10..120].iter().map(|m| m[(0, 0)].re).sum::<f64>() / 110.0;
        assert!((mean / (0.5 / 12.0) - 1.0).abs() < 0.05, "{mean}");
    }

    #[test]
    fn bad_records_are_refused_naming_the_field() {
        let e = AmbientRecord::new(
            0.1,
            vec![1, 2],
            Observable::Displacement,
            vec![vec![1.0; 50]],
        )
        .unwrap_err();
        assert!(e.to_string().contains("observe"), "{e}");
        let y: Vec<f64> = (0..50).map(|i| i as f64).collect();
        let e = AmbientRecord::new(
            0.1,
            vec![1, 2],
            Observable::Displacement,
            vec![y.clone(), vec![2.0; 50]],
        )
        .unwrap_err();
        assert!(e.to_string().contains("channel 2 (mass 2)"), "{e}");
        let rec = AmbientRecord::new(0.1, vec![1], Observable::Displacement, vec![y]).unwrap();
        let e = welch(&rec, 32).unwrap_err();
        assert!(e.to_string().contains("samples"), "{e}");
    }
}
