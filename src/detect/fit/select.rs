//! Model selection for the number of defects: given the best fit for each
//! candidate count `k = 0..K` (its chi-square on `N` data), choose `k` by an
//! information criterion or a chi-square goodness-of-fit test, and report the
//! evidence for every `k`.
//!
//! With `p_k` free parameters (each defect counts its position and its value,
//! plus any fitted chain parameters):
//!
//! * `AIC_k = chi^2_k + 2 p_k`, Akaike weights `w_k ∝ exp(-(AIC_k - AIC_min)/2)`;
//! * `BIC_k = chi^2_k + p_k ln N`, Schwarz weights likewise (approximate
//!   posterior probabilities under equal priors);
//! * chi-square test: the smallest `k` whose `chi^2_k` is consistent with a
//!   chi-square on `N - p_k` degrees of freedom (upper-tail p-value at least
//!   `alpha`, default 0.01).
//!
//! `chi^2` must be a true chi-square (whitened residuals of independent
//! data, such as the time-domain misfit [`crate::detect::misfit::time`]).
//!
//! ```
//! use springmass::detect::fit::select::{select, Criterion, ModelFit};
//! // 400 data; the 2-defect model fits to noise, the 1-defect model does not
//! let fits = [ModelFit::new(0, 9000.0, 0), ModelFit::new(1, 1500.0, 2),
//!             ModelFit::new(2, 395.0, 4), ModelFit::new(3, 390.0, 6)];
//! let s = select(&fits, 400, Criterion::Bic)?;
//! assert_eq!(s.chosen, 2);
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::error::{Error, Result};
use serde::Serialize;

/// The best fit of one candidate number of defects.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ModelFit {
    /// Number of defects.
    pub k: usize,
    /// Its best chi-square.
    pub chi2: f64,
    /// Number of free parameters.
    pub params: usize,
}

impl ModelFit {
    /// A fit of `k` defects with `chi2` and `params` free parameters.
    pub fn new(k: usize, chi2: f64, params: usize) -> ModelFit {
        ModelFit { k, chi2, params }
    }
}

/// How to choose.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub enum Criterion {
    /// Akaike information criterion.
    Aic,
    /// Bayesian (Schwarz) information criterion.
    Bic,
    /// Smallest `k` passing the chi-square goodness-of-fit test at level `alpha`.
    ChiSquare {
        /// Significance level, in `(0, 1)`.
        alpha: f64,
    },
}

impl Criterion {
    /// Parse `aic`, `bic` or `chi2` / `chi2:ALPHA`.
    ///
    /// # Errors
    /// [`Error::Parse`] naming the forms.
    pub fn parse(text: &str) -> Result<Criterion> {
        let bad = || Error::parse("criterion", text, "expected aic, bic, chi2 or chi2:ALPHA");
        match text.trim() {
            "aic" => Ok(Criterion::Aic),
            "bic" => Ok(Criterion::Bic),
            "chi2" => Ok(Criterion::ChiSquare { alpha: 0.01 }),
            t => {
                let a = t.strip_prefix("chi2:").ok_or_else(bad)?;
                let alpha: f64 = a.parse().map_err(|_| bad())?;
                if !(alpha > 0.0 && alpha < 1.0) {
                    return Err(Error::invalid("alpha", alpha, "0 < alpha < 1"));
                }
                Ok(Criterion::ChiSquare { alpha })
            }
        }
    }
}

/// The evidence for one `k`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Evidence {
    /// Number of defects.
    pub k: usize,
    /// Best chi-square.
    pub chi2: f64,
    /// Free parameters.
    pub params: usize,
    /// `chi^2 / (N - p)`.
    pub reduced_chi2: f64,
    /// Upper-tail p-value of `chi^2` on `N - p` degrees of freedom.
    pub p_value: f64,
    /// AIC.
    pub aic: f64,
    /// BIC.
    pub bic: f64,
    /// Akaike weight.
    pub aic_weight: f64,
    /// Schwarz weight.
    pub bic_weight: f64,
}

/// The choice and the evidence behind it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Selection {
    /// The chosen number of defects.
    pub chosen: usize,
    /// The criterion used.
    pub criterion: Criterion,
    /// Evidence per candidate, in increasing `k`.
    pub evidence: Vec<Evidence>,
}

/// Choose among `fits` (one per `k`, any order) on `n_data` data.
///
/// With [`Criterion::ChiSquare`], when no `k` passes, the `k` of smallest
/// reduced chi-square is chosen.
///
/// # Errors
/// No fits, a repeated `k`, a non-finite or negative chi-square, `p >= n_data`.
pub fn select(fits: &[ModelFit], n_data: usize, criterion: Criterion) -> Result<Selection> {
    if fits.is_empty() {
        return Err(Error::invalid("fits", 0, "at least one candidate"));
    }
    let mut fits = fits.to_vec();
    fits.sort_by_key(|f| f.k);
    for w in fits.windows(2) {
        if w[0].k == w[1].k {
            return Err(Error::invalid(
                "fits",
                format!("k = {} twice", w[0].k),
                "one fit per k",
            ));
        }
    }
    for f in &fits {
        crate::error::check_f64(
            &format!("fits[k={}].chi2", f.k),
            f.chi2,
            f.chi2 >= 0.0,
            ">= 0 and finite",
        )?;
        if f.params >= n_data {
            return Err(Error::invalid(
                format!("fits[k={}].params", f.k),
                f.params,
                format!("< number of data ({n_data})"),
            ));
        }
    }
    let ln_n = (n_data as f64).ln();
    let mut ev: Vec<Evidence> = fits
        .iter()
        .map(|f| {
            let dof = (n_data - f.params) as f64;
            Evidence {
                k: f.k,
                chi2: f.chi2,
                params: f.params,
                reduced_chi2: f.chi2 / dof,
                p_value: chi2_sf(f.chi2, dof),
                aic: f.chi2 + 2.0 * f.params as f64,
                bic: f.chi2 + ln_n * f.params as f64,
                aic_weight: 0.0,
                bic_weight: 0.0,
            }
        })
        .collect();
    let weights = |vals: Vec<f64>| -> Vec<f64> {
        let m = vals.iter().cloned().fold(f64::INFINITY, f64::min);
        let e: Vec<f64> = vals.iter().map(|v| (-(v - m) / 2.0).exp()).collect();
        let s: f64 = e.iter().sum();
        e.iter().map(|v| v / s).collect()
    };
    let wa = weights(ev.iter().map(|e| e.aic).collect());
    let wb = weights(ev.iter().map(|e| e.bic).collect());
    for (i, e) in ev.iter_mut().enumerate() {
        e.aic_weight = wa[i];
        e.bic_weight = wb[i];
    }
    let argmin = |f: &dyn Fn(&Evidence) -> f64| -> usize {
        ev.iter()
            .min_by(|a, b| f(a).total_cmp(&f(b)))
            .map(|e| e.k)
            .unwrap_or(0)
    };
    let chosen = match criterion {
        Criterion::Aic => argmin(&|e| e.aic),
        Criterion::Bic => argmin(&|e| e.bic),
        Criterion::ChiSquare { alpha } => match ev.iter().find(|e| e.p_value >= alpha) {
            Some(e) => e.k,
            None => argmin(&|e| e.reduced_chi2),
        },
    };
    Ok(Selection {
        chosen,
        criterion,
        evidence: ev,
    })
}

/// Upper tail `P(X > x)` of a chi-square variable with `dof` degrees of
/// freedom (statrs' regularised incomplete gamma); 1 for `x <= 0`, NaN for
/// `dof <= 0`.
pub fn chi2_sf(x: f64, dof: f64) -> f64 {
    use statrs::distribution::{ChiSquared, ContinuousCDF};
    if x <= 0.0 {
        return 1.0;
    }
    match ChiSquared::new(dof) {
        Ok(d) => d.sf(x),
        Err(_) => f64::NAN,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chi2_tail_known_values() {
        // mpmath gammainc(k/2, x/2, inf, regularized=True)
        let cases = [
            (3.841458820694124, 1.0, 0.05),
            (1.0, 2.0, (-0.5f64).exp()),
            (400.0, 400.0, 0.490596581992764),
            (15.5073130558655, 8.0, 0.0499999999999992),
            (500.0, 400.0, 0.000482212759593434),
        ];
        for (x, k, p) in cases {
            let v = chi2_sf(x, k);
            assert!(
                (v - p).abs() < 2e-3 * p.max(1e-3),
                "x={x} k={k}: {v} vs {p}"
            );
        }
        assert_eq!(chi2_sf(0.0, 3.0), 1.0);
        assert!(chi2_sf(1e5, 10.0) < 1e-300);
    }

    #[test]
    fn criteria() {
        let fits = [
            ModelFit::new(1, 410.0, 2),
            ModelFit::new(0, 5000.0, 0),
            ModelFit::new(2, 404.0, 4),
        ];
        // 2 defects improve chi2 by 6 for 2 extra params: AIC takes it, BIC does not
        let s = select(&fits, 400, Criterion::Aic).unwrap();
        assert_eq!(s.chosen, 2);
        assert_eq!(
            s.evidence.iter().map(|e| e.k).collect::<Vec<_>>(),
            vec![0, 1, 2]
        );
        assert_eq!(select(&fits, 400, Criterion::Bic).unwrap().chosen, 1);
        assert_eq!(
            select(&fits, 400, Criterion::ChiSquare { alpha: 0.01 })
                .unwrap()
                .chosen,
            1
        );
        let w: f64 = s.evidence.iter().map(|e| e.bic_weight).sum();
        assert!((w - 1.0).abs() < 1e-12);
        assert!(select(&[], 10, Criterion::Aic).is_err());
        assert!(select(
            &[ModelFit::new(1, 1.0, 2), ModelFit::new(1, 2.0, 2)],
            10,
            Criterion::Aic
        )
        .is_err());
        assert!(select(&[ModelFit::new(1, f64::NAN, 2)], 10, Criterion::Aic).is_err());
        assert!(select(&[ModelFit::new(1, 1.0, 10)], 10, Criterion::Aic).is_err());
        assert_eq!(
            Criterion::parse("chi2:0.05").unwrap(),
            Criterion::ChiSquare { alpha: 0.05 }
        );
        assert!(Criterion::parse("chi2:2").is_err());
        assert!(Criterion::parse("foo").is_err());
    }
}
