//! The noise level when the user does not know it, and a check that the
//! residual of a fit looks like noise.
//!
//! * [`high_frequency_sigma`]: a first guess from the series alone. The
//!   `p`-th finite difference of white noise of standard deviation `sigma`
//!   has standard deviation `sigma sqrt(C(2p, p))`, while a smooth signal's
//!   shrinks like `(omega dt)^p`; the median absolute difference (robust to
//!   the impulse's kink and to outliers) scaled by `1.4826 / sqrt(C(2p, p))`
//!   is an estimate of `sigma` plus the signal's share, so the smallest over
//!   `p = 2..=6` is kept. It can only overestimate a finely sampled smooth
//!   record's noise; the fit then replaces it by the residual estimate.
//! * [`residual_sigma`]: `sqrt(RSS / (N - p))` of the best fit's time-domain
//!   residual, as `scipy.optimize.curve_fit` does with `absolute_sigma=False`.
//! * [`ljung_box`]: the portmanteau statistic of the residual's
//!   autocorrelations at lags `1..=L`, and its upper-tail p-value on `L`
//!   degrees of freedom: a model that misses a defect leaves a structured,
//!   correlated residual; noise leaves a white one. This is how "fits the
//!   data" is judged when `sigma` was estimated (a chi-square test is then
//!   void: the estimate absorbs any misfit).
//!
//! ```
//! use springmass::detect::fit::noise::{high_frequency_sigma, ljung_box};
//! use rand::SeedableRng;
//! use rand_distr::{Distribution, StandardNormal};
//! let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
//! let noise: Vec<f64> = (0..4000).map(|_| { let z: f64 = StandardNormal.sample(&mut rng); 1e-3 * z }).collect();
//! let x: Vec<f64> = (0..4000).map(|i| (0.05 * i as f64).sin()).zip(&noise).map(|(a, b)| a + b).collect();
//! let s = high_frequency_sigma(&x);
//! assert!((s / 1e-3 - 1.0).abs() < 0.1, "{s}");
//! assert!(ljung_box(&noise, 20).1 > 0.01);        // white
//! assert!(ljung_box(&x, 20).1 < 1e-6);            // a sine is not
//! ```

use crate::detect::fit::select::chi2_sf;

/// Highest difference order tried by [`high_frequency_sigma`].
const MAX_ORDER: usize = 6;

/// First estimate of the white-noise standard deviation of `x` from its
/// finest scales (see the module docs); 0 for fewer than 8 samples or a
/// constant series.
pub fn high_frequency_sigma(x: &[f64]) -> f64 {
    let mut best = f64::INFINITY;
    let mut d: Vec<f64> = x.to_vec();
    for p in 1..=MAX_ORDER {
        d = d.windows(2).map(|w| w[1] - w[0]).collect();
        if d.len() < 8 {
            break;
        }
        if p < 2 {
            continue;
        }
        let mut a: Vec<f64> = d.iter().map(|v| v.abs()).collect();
        let mid = a.len() / 2;
        a.select_nth_unstable_by(mid, f64::total_cmp);
        let mad = a[mid];
        let scale = binomial(2 * p, p).sqrt();
        best = best.min(1.482_6 * mad / scale);
    }
    if best.is_finite() {
        best
    } else {
        0.0
    }
}

fn binomial(n: usize, k: usize) -> f64 {
    (0..k).fold(1.0, |acc, i| acc * (n - i) as f64 / (i + 1) as f64)
}

/// `sqrt(RSS / (N - p))` of residuals `r` with `p` fitted parameters
/// (`N - p` at least 1).
pub fn residual_sigma(r: &[f64], p: usize) -> f64 {
    let rss: f64 = r.iter().map(|v| v * v).sum();
    let dof = r.len().saturating_sub(p).max(1);
    (rss / dof as f64).sqrt()
}

/// Ljung-Box statistic `Q = N (N + 2) sum_{h=1}^{L} rho_h^2 / (N - h)` of
/// `r` and its p-value on `L` degrees of freedom (`L` clamped to `N / 4`);
/// `(0, 1)` for fewer than 8 values or a zero residual.
pub fn ljung_box(r: &[f64], lags: usize) -> (f64, f64) {
    let n = r.len();
    let lags = lags.min(n / 4);
    if n < 8 || lags == 0 {
        return (0.0, 1.0);
    }
    let mean = r.iter().sum::<f64>() / n as f64;
    let c0: f64 = r.iter().map(|v| (v - mean) * (v - mean)).sum();
    if c0 <= 0.0 || !c0.is_finite() {
        return (0.0, 1.0);
    }
    let nf = n as f64;
    let mut q = 0.0;
    for h in 1..=lags {
        let ch: f64 = (h..n).map(|i| (r[i] - mean) * (r[i - h] - mean)).sum();
        let rho = ch / c0;
        q += rho * rho / (nf - h as f64);
    }
    q *= nf * (nf + 2.0);
    (q, chi2_sf(q, lags as f64))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};

    fn noise(n: usize, sigma: f64, seed: u64) -> Vec<f64> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        (0..n)
            .map(|_| {
                let z: f64 = StandardNormal.sample(&mut rng);
                sigma * z
            })
            .collect()
    }

    #[test]
    fn high_frequency_estimate_is_unbiased_on_white_noise_and_bounded_on_signals() {
        for sigma in [1e-6, 1e-3, 1.0] {
            let e = high_frequency_sigma(&noise(6001, sigma, 3));
            assert!((e / sigma - 1.0).abs() < 0.08, "{sigma}: {e}");
        }
        // a smooth record with noise: never far below the noise
        let t: Vec<f64> = (0..6001).map(|i| 0.05 * i as f64).collect();
        let n = noise(6001, 1e-4, 9);
        let x: Vec<f64> = t
            .iter()
            .zip(&n)
            .map(|(t, e)| (-0.02 * t).exp() * (1.3 * t).sin() + e)
            .collect();
        let e = high_frequency_sigma(&x);
        assert!(e > 0.9e-4 && e < 3e-4, "{e}");
        assert_eq!(high_frequency_sigma(&[1.0; 20]), 0.0);
        assert_eq!(high_frequency_sigma(&[1.0, 2.0]), 0.0);
    }

    #[test]
    fn residual_sigma_divides_by_the_dof() {
        assert!((residual_sigma(&[1.0, -1.0, 1.0, -1.0], 2) - 2f64.sqrt()).abs() < 1e-15);
        assert_eq!(residual_sigma(&[1.0], 5), 1.0);
    }

    #[test]
    fn ljung_box_is_calibrated_on_white_noise() {
        let mut rejected = 0;
        for seed in 0..200 {
            if ljung_box(&noise(1000, 1.0, seed), 20).1 < 0.05 {
                rejected += 1;
            }
        }
        // 5% expected: 10 of 200, sd about 3
        assert!((2..=22).contains(&rejected), "{rejected}");
        assert_eq!(ljung_box(&[0.0; 100], 10), (0.0, 1.0));
    }
}
