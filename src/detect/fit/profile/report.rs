//! The answer of a whole-profile inversion ([`ProfileReport`], one
//! [`ElementEstimate`] per free value) and the judgement of it: the status and
//! the notes on noise and visibility.

use super::{Elem, ProfileMode};
use crate::chain::Chain;
use crate::detect::fit::report::Status;
use serde::Serialize;

/// One value of the fitted profile.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ElementEstimate {
    /// `mass` or `spring`.
    pub kind: &'static str,
    /// Mass index `1..=n`, or spring index (spring `j` joins masses `j` and
    /// `j + 1`).
    pub at: usize,
    /// Fitted value.
    pub value: f64,
    /// Standard error (NaN when not visible).
    pub se: f64,
    /// The model's uniform value here.
    pub uniform: f64,
    /// The data resolve a change of [`ProfileOptions::change`](super::ProfileOptions::change) here at two
    /// standard errors.
    pub visible: bool,
    /// The value ended on a bound.
    pub at_bound: bool,
    /// Distance from the observed mass, in masses (springs half-way).
    pub depth: f64,
}

impl ElementEstimate {
    /// Standard errors from the uniform value (`|value - uniform| / se`).
    pub fn significance(&self) -> f64 {
        (self.value - self.uniform).abs() / self.se
    }
}

/// The answer of `detect::fit::fit_profile`.
#[derive(Clone, Debug, Serialize)]
pub struct ProfileReport {
    /// What was free.
    pub mode: ProfileMode,
    /// What the record's sensor measured (`None` for exact data): kept so
    /// that `springmass monitor` fits later records of that sensor alike.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub observe_kind: Option<crate::forward::Observable>,
    /// Every free value, in order of position (masses, then springs).
    pub elements: Vec<ElementEstimate>,
    /// Fitted chain parameters (`d`, `gamma`, `k`, `mass`), as the model
    /// asked, with standard errors.
    pub params: Vec<(String, f64, f64)>,
    /// Covariance of the element values, in the order of `elements` (its
    /// diagonal is `se^2`; rows and columns of the values that are not
    /// visible are NaN, and every entry is NaN when the covariance fails).
    /// Monitoring (`detect::monitor`) tests a later record's change with it.
    pub covariance: Vec<Vec<f64>>,
    /// Deepest distance (in masses from the observed one) up to which every
    /// value is visible; `None` when none is.
    pub visible_depth: Option<f64>,
    /// The relative change visibility is stated for.
    pub change: f64,
    /// Noise standard deviation used.
    pub noise_sigma: f64,
    /// Whether it was estimated.
    pub noise_estimated: bool,
    /// Data chi-square of the final fit (at `noise_sigma`).
    pub chi2: f64,
    /// Number of data (real residuals).
    pub m: usize,
    /// Free values in the final fit.
    pub p: usize,
    /// Penalty weight at the end of the continuation (0 when none was needed).
    pub lambda: f64,
    /// Continuation stages run.
    pub stages: usize,
    /// The residual is consistent with noise: the chi-square test at the
    /// 1% level with a given noise level, and for a record the Ljung-Box
    /// whiteness test of its time residual (the defect fit's level), the
    /// only test with an estimated level. Otherwise the status is
    /// `model-mismatch`.
    pub fits_data: bool,
    /// Its p-value: the failed test's, else the chi-square's (given level)
    /// or the whiteness test's (estimated).
    pub fit_p_value: f64,
    /// How the fit ended.
    pub status: Status,
    /// One line on it.
    pub message: String,
    /// The misfit.
    pub misfit: String,
    /// Levenberg-Marquardt iterations over every stage.
    pub iterations: usize,
    /// Wall time, seconds.
    pub seconds: f64,
    /// The fitted chain.
    #[serde(skip)]
    pub chain: Chain,
}

impl ProfileReport {
    /// Number of visible values.
    pub fn visible_count(&self) -> usize {
        self.elements.iter().filter(|e| e.visible).count()
    }

    /// A human summary: the answer first (values with error bars), then the
    /// visibility and the fit's statistics.
    pub fn summary(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        let vis = self.visible_count();
        let _ = writeln!(
            s,
            "profile of {} ({} values, {} visible): {}",
            self.mode.name(),
            self.elements.len(),
            vis,
            self.status.name()
        );
        let _ = writeln!(s, "  {}", self.message);
        let _ = writeln!(s, "  kind    at      value          se   uniform  visible");
        for e in &self.elements {
            let se = if e.se.is_finite() {
                format!("{:11.4e}", e.se)
            } else {
                format!("{:>11}", "-")
            };
            let _ = writeln!(
                s,
                "  {:<6} {:>3} {:>11.6} {} {:>9.4} {:>8}{}",
                e.kind,
                e.at,
                e.value,
                se,
                e.uniform,
                if e.visible { "yes" } else { "no" },
                if e.at_bound { "  (at bound)" } else { "" }
            );
        }
        for (name, v, se) in &self.params {
            let _ = writeln!(s, "  {name} = {v:.6} +- {se:.2e}");
        }
        let _ = writeln!(
            s,
            "  noise sigma {:.3e} ({}); chi2 {:.1} for {} data, {} free; p = {}",
            self.noise_sigma,
            if self.noise_estimated {
                "estimated"
            } else {
                "given"
            },
            self.chi2,
            self.m,
            self.p,
            crate::detect::fit::report::fmt_p(self.fit_p_value)
        );
        let _ = writeln!(
            s,
            "  misfit: {}; {} continuation stages (final lambda {:.2e}), {} iterations, {:.2} s",
            self.misfit, self.stages, self.lambda, self.iterations, self.seconds
        );
        s
    }
}

/// The profile's status and the first words of its message.
pub(super) fn verdict(
    converged: bool,
    any_bound: bool,
    visible: usize,
    fits_data: bool,
) -> (Status, String) {
    if !converged {
        (
            Status::Stalled,
            "the final fit stopped at its iteration limit".to_string(),
        )
    } else if any_bound {
        (
            Status::ValueAtBound,
            "a value ended on its bound (a wrong basin, or a value outside the range)".to_string(),
        )
    } else if !fits_data {
        (
            Status::ModelMismatch,
            "model-mismatch: the profile does not explain the data (the chain, damping or noise model differs from the data's)".to_string(),
        )
    } else if visible == 0 {
        (
            Status::NotIdentifiable,
            "no value is visible: the data cannot resolve a change of this size anywhere"
                .to_string(),
        )
    } else {
        (Status::Converged, "converged".to_string())
    }
}

/// The note of a residual that is not noise (none when `fits_data`).
pub(super) fn noise_note(fits_data: bool, fit_p_value: f64) -> String {
    if fits_data {
        String::new()
    } else {
        format!("; the residual is not noise (p = {fit_p_value:.2e})")
    }
}

/// How many of the values are visible (the first `visible` in `order`), to
/// which depth, and the first hidden one, for the message.
pub(super) fn visibility_note(
    elems: &[Elem],
    order: &[usize],
    visible: usize,
    change: f64,
    visible_depth: Option<f64>,
) -> String {
    let nf = elems.len();
    match order.get(visible).map(|&i| &elems[i]) {
        Some(e) if visible < nf => format!(
            "; {} of {} values visible (a {}% change at 2 SE), up to depth {}; from {} {} on the data cannot see such a change",
            visible,
            nf,
            change * 100.0,
            visible_depth.map_or("-".to_string(), |d| format!("{d}")),
            e.name(),
            e.at
        ),
        _ => format!(
            "; every value visible (a {}% change at 2 SE)",
            change * 100.0
        ),
    }
}
