//! What the sensor adds to a record, chosen and iterated: the noise model
//! (white or AR(p)) and the nuisances (offset, drift), for the time misfit
//! of a sampled series.
//!
//! The choices ([`NoiseModelChoice`], [`NuisanceChoice`], `auto` by
//! default) and [`select_record`], the criterion's choice from a fit's
//! residual: for every allowed nuisance set and AR order `p`, the residual
//! with the nuisance columns regressed out is fitted by Burg's method and
//! scored by `BIC = N ln sigma_e^2 + (p + nuisances) ln N`; the lowest wins.
//! The fit ([`super::fit`]) first fits with white noise and no nuisance; with
//! both choices `auto` it keeps that fit when its residual passes the
//! whiteness test (Ljung-Box, [`super::noise::ljung_box`]), so a white
//! record costs what it did. Otherwise it refits with the chosen record
//! model, re-chooses the AR order and coefficients from the new best fit's
//! residual and refits until the order stays and no coefficient moves by more than
//! [`PHI_TOL`] (at most [`MAX_REFITS`] refits; the report says how many).

use super::noise::ljung_box;
use crate::chain::Chain;
use crate::detect::data::noise_model::{burg, ArFit, NoiseModel, P_MAX};
use crate::detect::data::nuisance::Nuisance;
use crate::detect::data::observations::Series;
use crate::detect::data::series::TimeData;
use crate::detect::misfit::time::TimeMisfit;
use crate::error::{Error, Result};
use serde::Serialize;

/// Refits with a record model at most (after the white fit).
pub const MAX_REFITS: usize = 3;

/// The AR coefficients have converged when none moves by more than this.
pub const PHI_TOL: f64 = 0.01;

/// Ljung-Box lags of the whiteness tests.
pub const LB_LAGS: usize = 20;

/// Which noise models the fit may use.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub enum NoiseModelChoice {
    /// White, unless the white fit's residual fails the whiteness test and
    /// AR(p), p <= 8, wins by the criterion.
    #[default]
    Auto,
    /// White noise (the paper's model).
    White,
    /// AR(p), `p` in `1..=8` by the criterion, or exactly `p`.
    Ar(Option<usize>),
}

impl NoiseModelChoice {
    /// `auto`, `white`, `ar` or `ar:P` (`P` in `0..=8`; `ar:0` is white).
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming `noise_model`.
    pub fn parse(text: &str) -> Result<NoiseModelChoice> {
        let bad = || {
            Error::invalid(
                "noise_model",
                text,
                format!("auto, white, ar or ar:P with P in 0..={P_MAX}"),
            )
        };
        match text.trim() {
            "auto" => Ok(NoiseModelChoice::Auto),
            "white" => Ok(NoiseModelChoice::White),
            "ar" => Ok(NoiseModelChoice::Ar(None)),
            t => {
                let p: usize = t
                    .strip_prefix("ar:")
                    .and_then(|p| p.trim().parse().ok())
                    .ok_or_else(bad)?;
                match p {
                    0 => Ok(NoiseModelChoice::White),
                    p if p <= P_MAX => Ok(NoiseModelChoice::Ar(Some(p))),
                    _ => Err(bad()),
                }
            }
        }
    }

    /// The AR orders allowed.
    fn orders(self) -> std::ops::RangeInclusive<usize> {
        match self {
            NoiseModelChoice::Auto => 0..=P_MAX,
            NoiseModelChoice::White => 0..=0,
            NoiseModelChoice::Ar(None) => 1..=P_MAX,
            NoiseModelChoice::Ar(Some(p)) => p..=p,
        }
    }
}

/// Which sensor nuisances the fit may use.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub enum NuisanceChoice {
    /// None, unless the white fit's residual fails the whiteness test and
    /// an offset (and drift) wins by the criterion.
    #[default]
    Auto,
    /// Exactly these.
    Fixed(Nuisance),
}

impl NuisanceChoice {
    /// The most nuisances the choice allows: `offset+drift` for `auto`.
    pub fn widest(self) -> Nuisance {
        match self {
            NuisanceChoice::Auto => Nuisance::OffsetDrift,
            NuisanceChoice::Fixed(n) => n,
        }
    }

    /// `auto`, `none`, `offset` or `offset+drift`.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming `nuisance`.
    pub fn parse(text: &str) -> Result<NuisanceChoice> {
        match text.trim() {
            "auto" => Ok(NuisanceChoice::Auto),
            "none" => Ok(NuisanceChoice::Fixed(Nuisance::None)),
            "offset" => Ok(NuisanceChoice::Fixed(Nuisance::Offset)),
            "offset+drift" | "drift" => Ok(NuisanceChoice::Fixed(Nuisance::OffsetDrift)),
            t => Err(Error::invalid(
                "nuisance",
                t,
                "none, offset, offset+drift or auto",
            )),
        }
    }

    /// The nuisance sets allowed.
    fn sets(self) -> Vec<Nuisance> {
        match self {
            NuisanceChoice::Auto => Nuisance::ALL.to_vec(),
            NuisanceChoice::Fixed(n) => vec![n],
        }
    }
}

/// Whether the choices ask for a record model whatever the white fit's
/// residual (an AR model or a nuisance given); otherwise the white fit stands
/// when its residual is white.
pub fn forced(noise: NoiseModelChoice, nuisance: NuisanceChoice) -> bool {
    matches!(noise, NoiseModelChoice::Ar(_))
        || matches!(
            nuisance,
            NuisanceChoice::Fixed(Nuisance::Offset | Nuisance::OffsetDrift)
        )
}

/// Whether the choices allow anything but white noise without nuisances.
pub fn open(noise: NoiseModelChoice, nuisance: NuisanceChoice) -> bool {
    noise != NoiseModelChoice::White || nuisance != NuisanceChoice::Fixed(Nuisance::None)
}

/// The model of a record at a chain (nuisances included), the residual
/// `x - model`, and the whitened residual (`None` for the plain record).
pub type Measured = (Vec<f64>, Vec<f64>, Option<Vec<f64>>);

/// The record model a fit runs with: the noise model, the nuisances, and
/// the first estimate of the nuisances that the Laplace screen's record is
/// corrected by (the screen has no nuisance columns).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RecordModel {
    /// The noise model.
    pub noise: NoiseModel,
    /// The nuisances profiled out of the time misfit.
    pub nuisance: Nuisance,
    /// `offset` (and `drift`) subtracted from the record before the screen.
    pub screen: Vec<f64>,
    /// Refits with this model after the white fit.
    pub iterations: usize,
    /// The AR coefficients stopped moving.
    pub converged: bool,
    /// The further sensors' noise levels relative to the first sensor's
    /// (empty: one sensor, or every sensor at the same level).
    pub scales: Vec<f64>,
}

impl RecordModel {
    /// White noise and no nuisance: the paper's record.
    pub fn is_plain(&self) -> bool {
        self.noise.is_white() && self.nuisance == Nuisance::None
    }

    /// Why the coloured noise model is not noise: its AR coefficients were
    /// still moving after the last of [`MAX_REFITS`] refits, which genuine
    /// coloured noise does not do (an AR(1) of rho 0.9 or 0.99 settles in
    /// one or two) and the residual of a model that misses the record's
    /// structure does (a wrong damping model took AR(8) and never settled,
    /// and was reported `converged` at wrong positions). `None` for white
    /// noise or settled coefficients.
    pub fn unsettled(&self) -> Option<String> {
        (!self.noise.is_white() && !self.converged).then(|| {
            format!(
                "colour that the AR({}) noise model did not settle on (its coefficients still moved after {} refits): structure that the chain, damping or record model misses rather than noise (another damping model: try --fit d)",
                self.noise.order(),
                self.iterations
            )
        })
    }

    /// Samples the whitened residual loses: the AR order plus the nuisances.
    pub fn lost(&self) -> usize {
        self.noise.order() + self.nuisance.count()
    }

    /// The record `s` as the time misfit's data at noise level `sigma` (the
    /// further sensors' at `sigma` times their [`RecordModel::scales`]).
    ///
    /// # Errors
    /// As [`Series::time_data_scaled`].
    pub fn time_data(&self, s: &Series, sigma: f64) -> Result<TimeData> {
        s.time_data_scaled(sigma, &self.scales)
    }

    /// The time misfit of `td` under this model.
    ///
    /// # Errors
    /// As [`TimeMisfit::with_record_model`].
    pub fn misfit(&self, td: TimeData) -> Result<TimeMisfit> {
        if self.is_plain() {
            return Ok(TimeMisfit::new(td));
        }
        TimeMisfit::new(td).with_record_model(self.noise.clone(), self.nuisance)
    }

    /// The record the Laplace screen sees: the first nuisance estimate
    /// subtracted, at the innovation level (its transform's covariance is
    /// that of [`RecordModel::noise`]: [`super::setup::laplace_obs_under`]);
    /// `None` for the plain record.
    ///
    /// # Errors
    /// As [`TimeData::new`].
    pub fn screen_data(&self, td: &TimeData) -> Result<Option<TimeData>> {
        if self.is_plain() {
            return Ok(None);
        }
        let trend = |t: f64| {
            self.screen
                .iter()
                .enumerate()
                .map(|(i, c)| c * t.powi(i as i32))
                .sum::<f64>()
        };
        let y = td
            .t()
            .iter()
            .zip(td.y())
            .map(|(&t, y)| y - trend(t))
            .collect();
        Ok(Some(
            TimeData::new(td.t().to_vec(), y, td.sigma())?
                .with_measurement(td.measurement().clone())?,
        ))
    }

    /// The misfit line's note on the record model (empty when plain).
    pub fn describe(&self) -> String {
        if self.is_plain() {
            return String::new();
        }
        let mut out = String::new();
        if !self.noise.is_white() {
            out.push_str(&format!(", whitened by AR({})", self.noise.order()));
        }
        if self.nuisance != Nuisance::None {
            out.push_str(&format!(", {} profiled out", self.nuisance.name()));
        }
        out
    }

    /// The model of the record at `chain` (with the fitted nuisances), the
    /// residual `x - model`, and the whitened residual (`None` when plain).
    ///
    /// # Errors
    /// As [`TimeMisfit::model`].
    pub fn measured(&self, tm: &TimeMisfit, chain: &Chain, x: &[f64]) -> Result<Measured> {
        let mut model = tm.model(chain)?;
        let mut r: Vec<f64> = x.iter().zip(&model).map(|(a, b)| a - b).collect();
        if self.is_plain() {
            return Ok((model, r, None));
        }
        let whitened = tm.whiten(&r);
        let c = tm.nuisance_values(chain)?;
        for ((m, r), t) in model.iter_mut().zip(r.iter_mut()).zip(tm.data().t()) {
            let trend: f64 = c
                .iter()
                .enumerate()
                .map(|(i, c)| c * t.powi(i as i32))
                .sum();
            *m += trend;
            *r -= trend;
        }
        Ok((model, r, Some(whitened)))
    }
}

/// The record model the criterion chooses from a residual.
#[derive(Clone, Debug, PartialEq)]
pub struct RecordChoice {
    /// The noise model.
    pub noise: NoiseModel,
    /// The nuisances.
    pub nuisance: Nuisance,
    /// The innovation variance of the residual under it.
    pub innovation_var: f64,
}

/// The criterion's record model for residual `r` at times `t` (see the
/// module docs).
///
/// # Errors
/// As [`burg`] (a residual too short for the orders asked).
pub fn select_record(
    r: &[f64],
    t: &[f64],
    noise: NoiseModelChoice,
    nuisance: NuisanceChoice,
) -> Result<RecordChoice> {
    let n = r.len() as f64;
    let mut best: Option<(f64, RecordChoice)> = None;
    for set in nuisance.sets() {
        let detrended = detrend(r, t, set);
        // orders the record supports (a tenth of its samples), the white
        // model always
        let supported = noise.orders().filter(|&p| p == 0 || 10 * p <= r.len());
        for p in supported {
            let fit = burg(&detrended, p)?;
            let var = fit.innovation_var.max(f64::MIN_POSITIVE);
            let bic = n * var.ln() + (p + set.count()) as f64 * n.ln();
            if best.as_ref().is_none_or(|(b, _)| bic < *b) {
                best = Some((bic, choice(fit, set)?));
            }
        }
    }
    best.map(|(_, c)| c).ok_or_else(|| {
        Error::invalid(
            "noise_model",
            format!("{noise:?}"),
            format!("an AR order of at most a tenth of the {} samples", r.len()),
        )
    })
}

fn choice(fit: ArFit, nuisance: Nuisance) -> Result<RecordChoice> {
    Ok(RecordChoice {
        noise: NoiseModel::ar(fit.coefficients)?,
        nuisance,
        innovation_var: fit.innovation_var,
    })
}

/// `r` with its least-squares fit by the nuisance columns removed (`r`
/// itself for none).
pub fn detrend(r: &[f64], t: &[f64], nuisance: Nuisance) -> Vec<f64> {
    match crate::detect::data::nuisance::Projector::new(nuisance, t, &NoiseModel::White) {
        Ok(Some(p)) => p.project(r),
        _ => r.to_vec(),
    }
}

/// The criterion's noise model for residual `r` at times `t` (nuisances
/// already removed), its innovation variance, and whether it is `current`
/// again: the same order, no coefficient moved by more than [`PHI_TOL`].
///
/// # Errors
/// As [`select_record`].
pub fn reestimate(
    r: &[f64],
    t: &[f64],
    current: &NoiseModel,
    choice: NoiseModelChoice,
) -> Result<(NoiseModel, f64, bool)> {
    let c = select_record(r, t, choice, NuisanceChoice::Fixed(Nuisance::None))?;
    let moved = c
        .noise
        .coefficients()
        .iter()
        .zip(current.coefficients())
        .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    let same = c.noise.order() == current.order() && moved < PHI_TOL;
    Ok((c.noise, c.innovation_var, same))
}

/// The Ljung-Box p-value of a whitened residual.
pub fn whiteness_p(whitened: &[f64]) -> f64 {
    ljung_box(whitened, LB_LAGS).1
}

/// The noise model as the report gives it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct NoiseModelReport {
    /// `white` or `ar`.
    pub kind: &'static str,
    /// The AR order (0 for white).
    pub p: usize,
    /// `phi_1..phi_p`.
    pub coefficients: Vec<f64>,
    /// The innovation standard deviation (the noise sigma for white noise).
    pub innovation_sigma: f64,
    /// Refits with this model after the white fit (0: the white fit itself).
    pub iterations: usize,
    /// Whether the coefficients stopped moving within the refits.
    pub converged: bool,
}

impl NoiseModelReport {
    /// The report of `model` at innovation sd `sigma`.
    pub fn new(model: &NoiseModel, sigma: f64, iterations: usize, converged: bool) -> Self {
        NoiseModelReport {
            kind: if model.is_white() { "white" } else { "ar" },
            p: model.order(),
            coefficients: model.coefficients().to_vec(),
            innovation_sigma: sigma,
            iterations,
            converged,
        }
    }

    /// One line of text.
    pub fn line(&self) -> String {
        if self.p == 0 {
            return "white".to_string();
        }
        let c: Vec<String> = self
            .coefficients
            .iter()
            .map(|c| format!("{c:.4}"))
            .collect();
        format!(
            "AR({}) [{}], innovation sigma {:.4e}, {} refit{}{}",
            self.p,
            c.join(", "),
            self.innovation_sigma,
            self.iterations,
            if self.iterations == 1 { "" } else { "s" },
            if self.converged {
                ""
            } else {
                " (coefficients still moving)"
            }
        )
    }
}

/// One fitted nuisance in the report.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct NuisanceEstimate {
    /// `offset` or `drift`.
    pub name: &'static str,
    /// Its value (record units; per unit time for the drift).
    pub value: f64,
    /// Its standard error, from the full Jacobian `[J, B]`.
    pub se: f64,
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};

    #[test]
    fn parsing() {
        assert_eq!(
            NoiseModelChoice::parse("auto").unwrap(),
            NoiseModelChoice::Auto
        );
        assert_eq!(
            NoiseModelChoice::parse("ar:0").unwrap(),
            NoiseModelChoice::White
        );
        assert_eq!(
            NoiseModelChoice::parse("ar:2").unwrap(),
            NoiseModelChoice::Ar(Some(2))
        );
        assert!(NoiseModelChoice::parse("ar:9").is_err());
        assert!(NoiseModelChoice::parse("pink").is_err());
        assert_eq!(
            NuisanceChoice::parse("offset+drift").unwrap(),
            NuisanceChoice::Fixed(Nuisance::OffsetDrift)
        );
        assert!(NuisanceChoice::parse("tilt").is_err());
        assert!(!forced(NoiseModelChoice::Auto, NuisanceChoice::Auto));
        assert!(!forced(NoiseModelChoice::White, NuisanceChoice::Auto));
        assert!(forced(NoiseModelChoice::Ar(None), NuisanceChoice::Auto));
        assert!(forced(
            NoiseModelChoice::Auto,
            NuisanceChoice::Fixed(Nuisance::Offset)
        ));
    }

    #[test]
    fn the_criterion_finds_an_offset_and_ar_noise() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
        let t: Vec<f64> = (0..2000).map(|i| 0.1 * i as f64).collect();
        let mut n = vec![0.0; t.len()];
        for i in 1..n.len() {
            let z: f64 = StandardNormal.sample(&mut rng);
            n[i] = 0.9 * n[i - 1] + z;
        }
        let r: Vec<f64> = n.iter().zip(&t).map(|(e, t)| e + 3.0 + 0.05 * t).collect();
        let c = select_record(&r, &t, NoiseModelChoice::Auto, NuisanceChoice::Auto).unwrap();
        assert_eq!(c.nuisance, Nuisance::OffsetDrift);
        assert_eq!(c.noise.order(), 1);
        assert!((c.noise.coefficients()[0] - 0.9).abs() < 0.03, "{c:?}");
        // white noise: white, none
        let w: Vec<f64> = (0..2000).map(|_| StandardNormal.sample(&mut rng)).collect();
        let c = select_record(&w, &t, NoiseModelChoice::Auto, NuisanceChoice::Auto).unwrap();
        assert_eq!((c.noise.order(), c.nuisance), (0, Nuisance::None));
        // forced AR: at least order 1
        let c = select_record(&w, &t, NoiseModelChoice::Ar(None), NuisanceChoice::Auto).unwrap();
        assert_eq!(c.noise.order(), 1);
        // a short record: only the orders it supports (16 samples: AR(1))
        let c = select_record(
            &w[..16],
            &t[..16],
            NoiseModelChoice::Ar(None),
            NuisanceChoice::Auto,
        )
        .unwrap();
        assert!(c.noise.order() <= 1);
        let e = select_record(
            &w[..16],
            &t[..16],
            NoiseModelChoice::Ar(Some(5)),
            NuisanceChoice::Auto,
        );
        assert!(
            matches!(e, Err(Error::InvalidParameter { ref field, .. }) if field == "noise_model")
        );
    }
}
