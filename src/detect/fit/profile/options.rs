//! What a whole-profile inversion frees and how it is run: [`ProfileMode`] and
//! [`ProfileOptions`] (the `profile.*` settings), validated in one place.

use crate::detect::fit::options::NoiseSpec;
use crate::error::{check_f64, Error, Result};
use serde::Serialize;

/// What is free in a whole-profile inversion.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ProfileMode {
    /// Every mass.
    Masses,
    /// Every spring that exists (a free end has no wall spring).
    Springs,
    /// Every mass and every spring (one end response often cannot separate
    /// them: the visibility report says so).
    Both,
}

impl ProfileMode {
    /// `masses`, `springs` or `both`.
    pub fn name(self) -> &'static str {
        match self {
            ProfileMode::Masses => "masses",
            ProfileMode::Springs => "springs",
            ProfileMode::Both => "both",
        }
    }

    /// Parse `masses`, `springs` or `both`.
    ///
    /// # Errors
    /// Any other text (field `profile`).
    pub fn parse(text: &str) -> Result<ProfileMode> {
        match text.trim() {
            "masses" | "mass" => Ok(ProfileMode::Masses),
            "springs" | "spring" => Ok(ProfileMode::Springs),
            "both" => Ok(ProfileMode::Both),
            other => Err(Error::invalid("profile", other, "masses, springs or both")),
        }
    }
}

/// Options of `detect::fit::fit_profile`.
#[derive(Clone, Debug, PartialEq)]
pub struct ProfileOptions {
    /// What is free.
    pub mode: ProfileMode,
    /// The noise level: given (of the samples, or the scale of the Laplace
    /// values' errors when they carry none) or estimated [default: auto].
    pub noise: NoiseSpec,
    /// The relative change the visibility report is stated for (`> 0`)
    /// [default: 0.1].
    pub change: f64,
    /// Fixed penalty weight (`> 0`) instead of the continuation; `None`: the
    /// continuation with the discrepancy target (the default).
    pub lambda: Option<f64>,
    /// Smallest weight of the continuation relative to its start (in `(0,
    /// 1)`) [default: 1e-10].
    pub lambda_min: f64,
    /// Width of the smooth L1 (`> 0`, relative deviation) [default: 1e-3].
    pub eps: f64,
    /// Free values bounded to `[u / bound, bound u]` (`> 1`) [default: 100].
    pub bound: f64,
    /// Most Levenberg-Marquardt iterations per stage [default: 200].
    pub max_iter: usize,
}

impl ProfileOptions {
    /// The defaults for `mode`.
    pub fn new(mode: ProfileMode) -> ProfileOptions {
        ProfileOptions {
            mode,
            noise: NoiseSpec::Auto,
            change: 0.1,
            lambda: None,
            lambda_min: 1e-10,
            eps: 1e-3,
            bound: 100.0,
            max_iter: 200,
        }
    }

    /// Check every option.
    ///
    /// # Errors
    /// The first option out of range, named.
    pub fn validate(&self) -> Result<()> {
        check_f64(
            "profile.change",
            self.change,
            self.change > 0.0,
            "> 0 and finite",
        )?;
        if let Some(l) = self.lambda {
            check_f64("profile.lambda", l, l > 0.0, "> 0 and finite")?;
        }
        check_f64(
            "profile.lambda_min",
            self.lambda_min,
            self.lambda_min > 0.0 && self.lambda_min < 1.0,
            "0 < lambda_min < 1",
        )?;
        check_f64("profile.eps", self.eps, self.eps > 0.0, "> 0 and finite")?;
        check_f64(
            "profile.bound",
            self.bound,
            self.bound > 1.0,
            "> 1 and finite",
        )?;
        if self.max_iter == 0 {
            return Err(Error::invalid("profile.max_iter", 0, ">= 1"));
        }
        if let NoiseSpec::Sigma(s) = self.noise {
            check_f64("noise", s, s > 0.0, "> 0 and finite")?;
        }
        Ok(())
    }
}
