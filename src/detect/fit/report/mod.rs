//! What a data-first fit ([`crate::detect::fit::fit`]) returns: the answer
//! with error bars first, then how it was reached and how far to trust it,
//! in the spirit of scipy's `OptimizeResult` and argmin's termination reason.

use crate::chain::Defect;
use crate::detect::fit::identify::Identifiability;
use crate::detect::unknowns::DefectKind;
use serde::Serialize;

pub mod damping;
pub mod posterior;
pub mod trigger;
pub mod unseen;

pub use damping::{DampingCandidate, DampingEstimate};
pub use posterior::Posterior;
pub use trigger::TriggerEstimate;
pub use unseen::{Unseen, UnseenElement};

/// How the fit ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Status {
    /// Converged, every defect identifiable, the runner-up clearly worse.
    Converged,
    /// A stochastic search used its whole evaluation budget.
    BudgetExhausted,
    /// The value fit stopped without converging.
    Stalled,
    /// A fitted value ended on a bound of its range (a wrong basin, or a
    /// defect outside the range searched).
    ValueAtBound,
    /// The data cannot tell the answer from an alternative, or a defect from
    /// no defect, at this noise level.
    NotIdentifiable,
    /// The best answer does not explain the data: its residual is not noise
    /// (`fits_data` false). The chain, damping or noise model (or the
    /// record: an offset, a drift, a late trigger) differs from the data's;
    /// the positions and values are the best of a wrong model.
    ModelMismatch,
}

impl Status {
    /// `converged`, `budget-exhausted`, ...
    pub fn name(self) -> &'static str {
        match self {
            Status::Converged => "converged",
            Status::BudgetExhausted => "budget-exhausted",
            Status::Stalled => "stalled",
            Status::ValueAtBound => "value-at-bound",
            Status::NotIdentifiable => "not-identifiable",
            Status::ModelMismatch => "model-mismatch",
        }
    }
}

/// One defect found.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DefectEstimate {
    /// `mass`, `spring` or `damper`.
    pub kind: &'static str,
    /// Position (masses and dampers `1..=n`, springs `0..=n`).
    pub at: usize,
    /// Fitted value.
    pub value: f64,
    /// Its standard error (NaN when the data do not constrain it; 0 for a
    /// known defect).
    pub se: f64,
    /// The value ended on a bound of its range.
    pub at_bound: bool,
    /// Given by the model, not fitted.
    pub known: bool,
    /// Standard errors from "no defect" (`|value - uniform| / se`; on a
    /// baseline, `|value - baseline| / se`).
    pub significance: f64,
    /// The baseline's value at this site (what "no defect" means there);
    /// absent on the uniform chain, whose value is the uniform one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub baseline: Option<f64>,
    /// Whether the data single it out (position and value), see
    /// [`crate::detect::fit::identify`].
    pub identifiable: bool,
    /// The interval at the report's level ([`FitReport::level`]):
    /// `[lo, hi]` ([`crate::detect::fit::intervals`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub interval: Option<[f64; 2]>,
    /// How the interval was found: `wald`, `profile`, `profile-bounded`,
    /// `unconstrained` or `known`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub interval_method: Option<&'static str>,
}

impl DefectEstimate {
    /// As a chain defect.
    pub fn defect(&self) -> Defect {
        DefectKind::from_name(self.kind)
            .unwrap_or(DefectKind::Mass)
            .defect(self.at, self.value)
    }
}

/// A fitted chain parameter (`d`, `gamma`, `k`, `mass`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ParamEstimate {
    /// Its name.
    pub name: String,
    /// Fitted value.
    pub value: f64,
    /// Standard error.
    pub se: f64,
    /// The value ended on a bound of its range.
    pub at_bound: bool,
    /// The interval at the report's level, as for a defect.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub interval: Option<[f64; 2]>,
    /// How the interval was found.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub interval_method: Option<&'static str>,
}

/// An alternative answer and how much worse it fits: the one alternative
/// type of the data path ([`FitReport::alternatives`]) and the scene path
/// ([`crate::detect::fit::paper::SceneReport::runners_up`]).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Alternative {
    /// Its defects (values fitted).
    pub defects: Vec<Defect>,
    /// Its chi-square (on the scene's mass path: the paper's residual, the
    /// chi-square with the quadrature weights as inverse variances).
    pub chi2: f64,
    /// `chi2 - best chi2` (above 9: three standard deviations worse).
    pub gap: f64,
}

impl Alternative {
    /// An alternative of chi-square `chi2` next to a best of `best_chi2`.
    pub fn new(defects: Vec<Defect>, chi2: f64, best_chi2: f64) -> Alternative {
        Alternative {
            defects,
            chi2,
            gap: chi2 - best_chi2,
        }
    }

    /// Its positions, in the order of its defects.
    pub fn positions(&self) -> Vec<usize> {
        self.defects.iter().map(Defect::at).collect()
    }
}

/// The evidence for one number of defects.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct KRow {
    /// Number of defects.
    pub k: usize,
    /// Best chi-square with `k` defects (at the final noise level).
    pub chi2: f64,
    /// Free parameters.
    pub params: usize,
    /// The criterion's value (smaller is better).
    pub criterion: f64,
    /// Its positions.
    pub positions: Vec<usize>,
}

/// The predicted series next to the observed one.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Predicted {
    /// Times.
    pub t: Vec<f64>,
    /// Observed values.
    pub observed: Vec<f64>,
    /// The best fit's model.
    pub model: Vec<f64>,
    /// `observed - model`.
    pub residual: Vec<f64>,
}

/// One sensor of a record of several: what it measured and its noise level.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SensorEstimate {
    /// With several records (`--data` repeated), the record's place
    /// (1-based, in the order given); 0 for a sensor of one record.
    pub record: usize,
    /// The observed mass.
    pub at: usize,
    /// `displacement`, `velocity` or `acceleration`.
    pub kind: String,
    /// Its samples.
    pub samples: usize,
    /// Its noise standard deviation: estimated from its own residual at the
    /// answer (`noise_estimated`), or the given level.
    pub sigma: f64,
    /// The Ljung-Box p-value of its own residual at the joint answer.
    pub whiteness_p: f64,
    /// Whether the joint answer explains it (`whiteness_p >= 0.001`): a
    /// sensor or record whose residual is not noise disagrees with the
    /// others (another chain, a fault of that test), and the fit's status
    /// is then `model-mismatch`, naming it.
    pub fits_data: bool,
}

/// The answer of a data-first fit.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FitReport {
    /// The defects found (known ones included, flagged), with standard errors.
    pub defects: Vec<DefectEstimate>,
    /// Number of defects fitted (known ones excluded).
    pub k: usize,
    /// The fitted chain parameters.
    pub params: Vec<ParamEstimate>,
    /// Noise standard deviation used for the final fit (of the samples, or
    /// the scale of the Laplace values' errors).
    pub noise_sigma: f64,
    /// Whether it was estimated from the data.
    pub noise_estimated: bool,
    /// Every sensor of a record of several, with its own noise level
    /// estimated from its own residual (`noise_sigma` is then the first
    /// sensor's level as the joint residual estimates it, every sensor's
    /// residual scaled to it); empty for one sensor.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub sensors: Vec<SensorEstimate>,
    /// Final chi-square.
    pub chi2: f64,
    /// Its degrees of freedom.
    pub dof: usize,
    /// How the fit ended.
    pub status: Status,
    /// One line on the status.
    pub message: String,
    /// The fit converged, the runner-up's chi-square gap is above the
    /// threshold, every defect is identifiable, and the residual is
    /// consistent with noise (`fits_data`): an answer whose residual is not
    /// noise (a missing defect, a wrong basin) is never called resolved.
    pub resolved: bool,
    /// The residual is consistent with noise (chi-square test with a known
    /// sigma; Ljung-Box whiteness test of the time residual when sigma was
    /// estimated).
    pub fits_data: bool,
    /// p-value behind `fits_data`.
    pub fit_p_value: f64,
    /// The next best answers, best first.
    pub alternatives: Vec<Alternative>,
    /// The evidence for each number of defects tried (one row when `k` was given).
    pub k_selection: Vec<KRow>,
    /// `bic`, `aic`, `chi2` (with `defects = auto`), or `given`.
    pub criterion: String,
    /// The misfit used (`real-axis`, `bromwich`, `time`) with its details.
    pub misfit: String,
    /// What the data measured and the chain's ends, for example
    /// `acceleration of mass 1, measured force on mass 1; ends free-fixed`.
    pub setup: String,
    /// The search method.
    pub method: String,
    /// Misfit evaluations spent.
    pub evaluations: usize,
    /// Position (and kind) sets fitted for the chosen number of defects.
    pub sets_fitted: usize,
    /// Whether every position set was ranked (false: a search that does
    /// not enumerate, greedy, relax or stochastic; the Woodbury kernel's
    /// beam search, for more sets than `max_sets`; or a search over every
    /// kind whose kinds per position were narrowed, `detect::fit::narrow`,
    /// which `method` then names).
    pub exhaustive: bool,
    /// `(evaluations, best cost)` per iteration of a stochastic search, when
    /// traced (`Given::trace`, the scene's `[search] trace`); the cost is the
    /// misfit the search ran on.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub trace: Option<Vec<(usize, f64)>>,
    /// Wall time, seconds.
    pub wall_time_s: f64,
    /// A screening fit's answer that does not explain the record
    /// ([`FitOptions::screen`](super::FitOptions::screen)): its noise level
    /// not settled and no intervals, so not the fit a full one would be
    /// (not written).
    #[serde(skip)]
    pub screened: bool,
    /// The predicted series (series data only).
    pub predicted: Option<Predicted>,
    /// The identifiability report of the best answer.
    pub identifiability: Option<Identifiability>,
    /// How deep the data see a 10% mass change (mass defects on a record or
    /// Laplace values; `None` for the scene path and other kinds): the
    /// defects the data cannot see are named there.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub visibility: Option<crate::detect::fit::visibility::Visibility>,
    /// With the number of defects left to the criterion: the masses and
    /// springs whose halving or doubling the data would not show (a
    /// further defect could hide there; see [`crate::detect::fit::unseen`]);
    /// `None` when the check was not made.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unseen: Option<Unseen>,
    /// Natural frequencies and damping ratios of the fitted chain (its
    /// units: rad/s and Hz when the data and the chain are in SI units);
    /// empty for a non-uniform chain of more than 400 masses (the dense
    /// eigen solver is O(n^3)).
    pub modes: Vec<ModeEstimate>,
    /// The blow's time on the record's axis, when the record was re-timed
    /// to it ([`crate::detect::fit::trigger`]; absent for a record that
    /// starts with the blow, and for Laplace values).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub trigger: Option<TriggerEstimate>,
    /// The record's noise model (a series fitted by the time misfit):
    /// `white`, or `ar` with its order, coefficients, innovation sigma and
    /// refits ([`crate::detect::fit::record`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub noise_model: Option<crate::detect::fit::record::NoiseModelReport>,
    /// Ljung-Box p-value of the residual whitened by the noise model
    /// (series data).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub whiteness_p: Option<f64>,
    /// The sensor's fitted offset and drift with standard errors (empty:
    /// none fitted).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub nuisance: Vec<crate::detect::fit::record::NuisanceEstimate>,
    /// The damping model with its parameters and standard errors (absent
    /// for the grounded model chosen by the user, the paper's).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub damping: Option<DampingEstimate>,
    /// The measured profile the defects are relative to (its file, or
    /// `inline`); absent for the uniform chain.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub baseline: Option<String>,
    /// The level of the intervals of the defects and parameters.
    pub level: f64,
    /// How probable each hypothesis is (JSON: `prior`, `hypotheses`,
    /// `k_probability`, `position_probability`, `answer_probability`,
    /// `pruned_bound`, ...; [`crate::detect::fit::posterior`]); absent
    /// when it could not be computed.
    #[serde(flatten, skip_serializing_if = "Option::is_none")]
    pub posterior: Option<Posterior>,
}

/// One natural mode of the fitted chain
/// ([`crate::time::modal::natural_modes`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ModeEstimate {
    /// Undamped natural frequency, rad per unit of time (0: rigid-body mode).
    pub omega: f64,
    /// `omega / (2 pi)`.
    pub frequency: f64,
    /// Damping ratio (NaN for a rigid-body mode).
    pub zeta: f64,
}

impl FitReport {
    /// The defects found, as chain defects.
    pub fn found(&self) -> Vec<Defect> {
        self.defects
            .iter()
            .filter(|d| !d.known)
            .map(DefectEstimate::defect)
            .collect()
    }

    /// The evidence for each number of defects and the best alternatives.
    fn evidence_lines(&self, out: &mut String) {
        if self.k_selection.len() > 1 {
            out.push_str(&format!("number of defects by {}:\n", self.criterion));
            for r in &self.k_selection {
                out.push_str(&format!(
                    "  k = {}: chi2 {}, {} {}{}\n",
                    r.k,
                    fmt_g(r.chi2),
                    self.criterion,
                    fmt_g(r.criterion),
                    if r.k == self.k { "  <- chosen" } else { "" }
                ));
            }
        }
        for (i, a) in self.alternatives.iter().take(3).enumerate() {
            let d: Vec<String> = a.defects.iter().map(Defect::place).collect();
            out.push_str(&format!(
                "alternative {}: {} (chi2 gap {})\n",
                i + 1,
                d.join(", "),
                fmt_g(a.gap)
            ));
        }
    }

    /// Human summary: the answer and its error bars first.
    pub fn summary(&self) -> String {
        let mut out = String::new();
        if self.k == 0 {
            out.push_str("no defect found\n");
        }
        if let Some(b) = &self.baseline {
            out.push_str(&format!("baseline: {b} (values relative to its profile)\n"));
        }
        self.answer_lines(&mut out);
        out.push_str(&format!(
            "status: {} - {}\nnoise sigma {} ({}), chi2 {} on {} dof, fits the data: {} (p = {})\n",
            self.status.name(),
            self.message,
            fmt_g(self.noise_sigma),
            if self.noise_estimated {
                "estimated"
            } else {
                "given"
            },
            fmt_g(self.chi2),
            self.dof,
            match (
                self.fits_data,
                self.fit_p_value < crate::detect::fit::goodness::FITS_DATA_P
            ) {
                (false, _) => "NO",
                // fitted to the rounding of its digits: no test can judge that
                (true, true) => "yes, an exact record",
                (true, false) => "yes",
            },
            fmt_p(self.fit_p_value)
        ));
        self.sensor_lines(&mut out);
        if let Some(t) = &self.trigger {
            out.push_str(&format!("{}\n", t.line()));
        }
        if let Some(v) = &self.visibility {
            out.push_str(&format!("visibility: {}\n", v.line()));
        }
        self.record_lines(&mut out);
        if let Some(d) = &self.damping {
            out.push_str(&format!("{}\n", d.line()));
        }
        self.evidence_lines(&mut out);
        if let Some(p) = &self.posterior {
            out.push_str(&p.lines());
        }
        self.modes_line(&mut out);
        let ranked = match self.exhaustive {
            true => "",
            false => " (not every set ranked)",
        };
        out.push_str(&format!(
            "{}\nmisfit {}, method {}{ranked}, {} evaluations, {:.2} s\n",
            self.setup, self.misfit, self.method, self.evaluations, self.wall_time_s
        ));
        out
    }

    /// The defects and the fitted chain parameters, a line each.
    fn answer_lines(&self, out: &mut String) {
        for d in &self.defects {
            out.push_str(&format!(
                "{} at {}: {} +- {}{}{}{}{}{}\n",
                d.kind,
                d.at,
                fmt_g(d.value),
                fmt_g(d.se),
                interval_text(d.interval, d.interval_method, self.level),
                d.baseline
                    .map_or(String::new(), |b| format!(" (baseline {})", fmt_g(b))),
                if d.known { " (known)" } else { "" },
                if d.at_bound { " (AT BOUND)" } else { "" },
                if !d.known && !d.identifiable {
                    " (not identifiable)"
                } else {
                    ""
                },
            ));
        }
        for p in &self.params {
            let line = value_line(&p.name, " =", p.value, p.se);
            out.push_str(&format!(
                "{}{}\n",
                line.trim_end(),
                interval_text(p.interval, p.interval_method, self.level)
            ));
        }
    }

    /// The noise level of each sensor (or record) of several, one line.
    fn sensor_lines(&self, out: &mut String) {
        if !self.sensors.is_empty() {
            let records = self.sensors[0].record > 0;
            let s: Vec<String> = self
                .sensors
                .iter()
                .map(|s| {
                    format!(
                        "{}{} of mass {}: sigma {}{}",
                        if records {
                            format!("record {}: ", s.record)
                        } else {
                            String::new()
                        },
                        s.kind,
                        s.at,
                        fmt_g(s.sigma),
                        if s.fits_data {
                            String::new()
                        } else {
                            format!(" (NOT explained, whiteness p = {:.1e})", s.whiteness_p)
                        }
                    )
                })
                .collect();
            let label = if records { "records" } else { "sensors" };
            out.push_str(&format!("{label}: {}\n", s.join("; ")));
        }
    }

    /// The fitted chain's lowest natural frequencies, one line.
    fn modes_line(&self, out: &mut String) {
        if !self.modes.is_empty() {
            let shown: Vec<String> = self
                .modes
                .iter()
                .take(6)
                .map(|m| format!("{} (zeta {})", fmt_g(m.omega), fmt_g(m.zeta)))
                .collect();
            out.push_str(&format!(
                "natural frequencies of the fitted chain (rad per unit time): {}{}\n",
                shown.join(", "),
                if self.modes.len() > 6 { ", ..." } else { "" }
            ));
        }
    }
}

impl FitReport {
    /// The noise model, the whitened residual's whiteness and the
    /// nuisances (when not the paper's white record).
    fn record_lines(&self, out: &mut String) {
        if let Some(m) = self.noise_model.as_ref().filter(|m| m.p > 0) {
            out.push_str(&format!(
                "noise model: {}; whitened residual Ljung-Box p = {:.3}\n",
                m.line(),
                self.whiteness_p.unwrap_or(f64::NAN)
            ));
        }
        for n in &self.nuisance {
            out.push_str(&value_line(
                &format!("sensor {}", n.name),
                ":",
                n.value,
                n.se,
            ));
        }
    }
}

/// Four significant digits.
pub(crate) fn fmt_g(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let a = v.abs();
    if (1e-3..1e5).contains(&a) {
        let digits = (3 - a.log10().floor() as i32).max(0) as usize;
        format!("{v:.digits$}")
    } else {
        format!("{v:.3e}")
    }
}

/// `, 90% in [lo, hi] (profile)`, or nothing without an interval.
fn interval_text(i: Option<[f64; 2]>, method: Option<&str>, level: f64) -> String {
    match (i, method) {
        (_, Some("known")) | (None, _) => String::new(),
        (Some([lo, hi]), m) => format!(
            ", {}% in [{}, {}]{}",
            100.0 * level,
            fmt_g(lo),
            fmt_g(hi),
            match m {
                Some("wald") | None => String::new(),
                Some(m) => format!(" ({m})"),
            }
        ),
    }
}

/// `name`, `sep`, ` value +- se` and a newline (`d = 0.1 +- 0.002`).
fn value_line(name: &str, sep: &str, value: f64, se: f64) -> String {
    format!("{name}{sep} {} +- {}\n", fmt_g(value), fmt_g(se))
}

/// A p-value to three decimals, or in exponent form below 0.001 (where
/// three decimals print 0.000).
pub(crate) fn fmt_p(p: f64) -> String {
    if p >= 1e-3 || p == 0.0 || p.is_nan() {
        format!("{p:.3}")
    } else {
        format!("{p:.1e}")
    }
}
