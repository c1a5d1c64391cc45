//! Structural model updating from measured modes: every storey spring
//! (and/or mass) of a nominal chain as a factor, fitted to measured
//! frequencies and mode shapes ([`ModalMisfit`]).
//!
//! # Method
//!
//! 1. **Starts.** Bounded Levenberg-Marquardt on the factors from the
//!    nominal chain (all factors 1) and from [`ModalUpdateOptions::starts`]
//!    seeded log-uniform starts in `[1/2, 2]` (the misfit of a modal
//!    comparison has several basins: mode pairings change along the way);
//!    the lowest chi-square wins.
//! 2. **Identifiability.** With at least as many data as factors and a
//!    Jacobian of full rank, every factor gets a Gauss-Newton standard error.
//!    Otherwise (fewer data, or combinations the data do not see) a Gaussian
//!    prior of width `w` around the nominal value is added, `w` chosen by
//!    the discrepancy principle (the narrowest width of a ladder whose data
//!    chi-square reaches the number of data); a factor whose standard error
//!    the data do not shrink below half the prior's is reported as **not
//!    determined** rather than pinned anywhere.
//! 3. **Prediction.** Every mode of the updated chain is listed (frequency,
//!    damping ratio where the chain is damped, MAC against every measured
//!    mode, held-out ones included), so modes kept out of the fit check it.
//!
//! Without standard errors in the table, the weights are assumed
//! ([`ModalWeights`]) and the standard errors are scaled by the residual
//! (`sqrt(chi^2 / (m - p))`, as `scipy.optimize.curve_fit` does by default).

use crate::chain::{Chain, Defect};
use crate::detect::data::modes::{MeasuredMode, MeasuredModes};
use crate::detect::fit::identifiable::{determined_combinations, Combination};
use crate::detect::fit::profile::ProfileMode;
use crate::detect::fit::select::chi2_sf;
use crate::detect::misfit::modal::{mac, ModalMisfit, ModalWeights};
use crate::detect::misfit::modal_dynamic::ModalDynamicResidual;
use crate::detect::model::MeasurementModel;
use crate::detect::search::lsq::{covariance, levenberg_marquardt, LeastSquares, LmFit, LmOptions};
use crate::error::{Error, Result};
use crate::time::survey_modes::SurveyModes;
use nalgebra::DMatrix;
use rand::{Rng, SeedableRng};
use serde::Serialize;

/// Prior widths tried (relative), narrowest first.
const PRIOR_LADDER: [f64; 9] = [0.01, 0.02, 0.05, 0.1, 0.2, 0.3, 0.5, 1.0, 2.0];

/// Options of [`update_from_modes`].
#[derive(Clone, Debug, PartialEq)]
pub struct ModalUpdateOptions {
    /// What is free: springs (default), masses or both.
    pub mode: ProfileMode,
    /// Random starts beside the nominal one (default 20).
    pub starts: usize,
    /// Seed of the starts (default 1).
    pub seed: u64,
    /// Factors bounded to `[lo, hi]` (default `[0.05, 20]`).
    pub bounds: (f64, f64),
    /// Standard errors assumed where the table gives none.
    pub weights: ModalWeights,
    /// Modes (1-based, increasing frequency) kept out of the fit and only
    /// predicted.
    pub hold_out: Vec<usize>,
    /// The measurement model: the modal-property difference (default) or
    /// the modal dynamic residual.
    pub formulation: ModalFormulation,
}

/// How the chain is compared with the measured modes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum ModalFormulation {
    /// Frequencies and MAC-paired shapes of the chain's eigen-solve against
    /// the measured ones ([`ModalMisfit`]).
    #[default]
    PropertyDifference,
    /// The equations of motion at the measured frequencies, the unmeasured
    /// shape components profiled out
    /// ([`crate::detect::misfit::modal_dynamic::ModalDynamicResidual`]).
    DynamicResidual,
}

impl ModalFormulation {
    /// `property` (or `property-difference`, `mpd`) or `dynamic` (or
    /// `dynamic-residual`, `mdr`).
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming `modal_residual`.
    pub fn parse(text: &str) -> Result<ModalFormulation> {
        match text.trim().to_ascii_lowercase().as_str() {
            "property" | "property-difference" | "mpd" => Ok(ModalFormulation::PropertyDifference),
            "dynamic" | "dynamic-residual" | "mdr" => Ok(ModalFormulation::DynamicResidual),
            other => Err(Error::invalid(
                "modal_residual",
                other,
                "property (the modal-property difference) or dynamic (the modal dynamic residual)",
            )),
        }
    }

    /// `property-difference` or `dynamic-residual`.
    pub fn name(self) -> &'static str {
        match self {
            ModalFormulation::PropertyDifference => "property-difference",
            ModalFormulation::DynamicResidual => "dynamic-residual",
        }
    }
}

impl Default for ModalUpdateOptions {
    fn default() -> ModalUpdateOptions {
        ModalUpdateOptions {
            mode: ProfileMode::Springs,
            starts: 20,
            seed: 1,
            bounds: (0.05, 20.0),
            weights: ModalWeights::default(),
            hold_out: Vec::new(),
            formulation: ModalFormulation::default(),
        }
    }
}

impl ModalUpdateOptions {
    /// # Errors
    /// `starts > 10000`, bounds not `0 < lo < 1 < hi` (field `bounds`), bad
    /// weights.
    pub fn check(&self) -> Result<()> {
        if self.starts > 10_000 {
            return Err(Error::invalid("starts", self.starts, "0..=10000"));
        }
        let (lo, hi) = self.bounds;
        if !(lo > 0.0 && lo < 1.0 && hi > 1.0 && hi.is_finite()) {
            return Err(Error::invalid(
                "bounds",
                format!("{lo}:{hi}"),
                "0 < lo < 1 < hi, finite",
            ));
        }
        self.weights.check()
    }
}

/// The measurement model of `formulation` for `modes` against chains like
/// `nominal` (the property difference compares the measured damping
/// ratios too when `nominal` is damped; the dynamic residual is the
/// undamped eigen-equation's and leaves them out).
///
/// # Errors
/// As [`ModalMisfit::new`] and [`ModalDynamicResidual::new`].
pub fn modal_model(
    modes: MeasuredModes,
    nominal: &Chain,
    weights: ModalWeights,
    formulation: ModalFormulation,
) -> Result<Box<dyn MeasurementModel>> {
    let n = nominal.n();
    Ok(match formulation {
        ModalFormulation::PropertyDifference => {
            Box::new(ModalMisfit::new(modes, n, weights)?.with_damping_of(nominal))
        }
        ModalFormulation::DynamicResidual => {
            Box::new(ModalDynamicResidual::new(modes, n, weights)?)
        }
    })
}

/// One fitted element.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FactorEstimate {
    /// `spring`, `mass` or `damper`.
    pub kind: &'static str,
    /// Spring index (`0..=n`, spring `j` joins masses `j` and `j + 1`) or
    /// mass (1-based).
    pub at: usize,
    /// The nominal value.
    pub nominal: f64,
    /// The updated value.
    pub value: f64,
    /// `value / nominal`.
    pub factor: f64,
    /// Standard error of the factor (`None` when not determined).
    pub se: Option<f64>,
    /// Whether the data determine it.
    pub determined: bool,
    /// Whether it stopped on a bound.
    pub at_bound: bool,
}

impl FactorEstimate {
    /// Element `d` (its nominal value) at factor `factor`, with the factor's
    /// standard error `se`, whether the data determine it and whether it
    /// stopped on a bound.
    pub fn new(
        d: &Defect,
        factor: f64,
        se: Option<f64>,
        determined: bool,
        at_bound: bool,
    ) -> FactorEstimate {
        FactorEstimate {
            kind: d.kind(),
            at: d.at(),
            nominal: d.value(),
            value: d.value() * factor,
            factor,
            se,
            determined,
            at_bound,
        }
    }
}

/// One mode of the updated chain.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PredictedMode {
    /// Frequency (Hz for a chain in SI units: `omega / (2 pi)`).
    pub frequency: f64,
    /// Damping ratio, where the chain is damped.
    pub damping: Option<f64>,
    /// MAC against every measured mode (fitted, then held out), over the
    /// masses each was measured at.
    pub mac: Vec<f64>,
    /// The measured mode (0-based, same order as `mac`) paired with it.
    pub paired: Option<usize>,
    /// Whether that measured mode was held out of the fit.
    pub held_out: bool,
    /// The measured frequency it is paired with.
    pub measured_frequency: Option<f64>,
}

/// The answer of [`update_from_modes`].
#[derive(Clone, Debug, Serialize)]
pub struct ModalUpdateReport {
    /// `converged`, `model-mismatch` or `not-determined`.
    pub status: String,
    /// Whether every factor is determined and the fit explains the data.
    pub resolved: bool,
    /// One sentence on the status.
    pub message: String,
    /// The factors.
    pub factors: Vec<FactorEstimate>,
    /// Data chi-square at the answer.
    pub chi2: f64,
    /// Number of data (frequencies and shape components less one scale per shape).
    pub dof: usize,
    /// Upper-tail p-value of `chi2` on `dof - parameters`.
    pub p_value: Option<f64>,
    /// The number of factors the data fit: every factor without a prior;
    /// under the prior the trace of the data's hat matrix
    /// `J (J^T J + I / w^2)^-1 J^T` (a factor the prior holds counts for
    /// less than one), so that the goodness-of-fit test and the residual
    /// scale do not count as fitted what the prior fixed.
    pub parameters: f64,
    /// Whether the standard errors came from the table.
    pub errors_given: bool,
    /// The standard errors assumed where the table gives none (`1%
    /// frequency, 5% shape`); `None` when it gives every one.
    pub assumed_weights: Option<String>,
    /// The measurement model fitted.
    pub formulation: ModalFormulation,
    /// Width of the prior on the factors, when one was needed.
    pub prior_width: Option<f64>,
    /// The combinations of factors the modes determine (a 10% change at
    /// two standard errors), when they do not determine every factor: the
    /// weights follow the order of `factors`.
    pub combinations: Vec<Combination>,
    /// Every mode of the updated chain.
    pub modes: Vec<PredictedMode>,
    /// Starts run.
    pub starts: usize,
    /// Misfit evaluations.
    pub evaluations: usize,
    /// The updated chain.
    pub chain: Chain,
}

impl ModalUpdateReport {
    /// The report as text: status, the factors, every mode of the updated
    /// chain against the measured ones.
    pub fn summary(&self) -> String {
        use std::fmt::Write;
        let mut out = format!("status: {} - {}\n", self.status, self.message);
        let p = self
            .p_value
            .map_or(String::new(), |p| format!(", p = {p:.3}"));
        let _ = writeln!(
            out,
            "chi2 {:.4} on {} data{p} ({})",
            self.chi2,
            self.dof,
            self.formulation.name()
        );
        if let Some(w) = self.prior_width {
            let _ = writeln!(
                out,
                "prior on the factors: width {:.0}% around 1 (the discrepancy principle)",
                100.0 * w
            );
        }
        let _ = writeln!(
            out,
            "element      nominal        updated     factor   +- SE"
        );
        for f in &self.factors {
            let se =
                f.se.map_or("not determined".to_string(), |s| format!("{s:.4}"));
            let bound = if f.at_bound { " (on its bound)" } else { "" };
            let _ = writeln!(
                out,
                "{:<6} {:>4} {:>12.5e} {:>12.5e} {:>9.4}   {se}{bound}",
                f.kind, f.at, f.nominal, f.value, f.factor
            );
        }
        if !self.combinations.is_empty() {
            let _ = writeln!(
                out,
                "combinations of factors the modes determine (weights . factors):"
            );
        }
        for c in &self.combinations {
            let _ = writeln!(
                out,
                "  {:.4} +- {:.4}: {}",
                c.estimate,
                c.se,
                self.terms(&c.weights)
            );
        }
        let _ = writeln!(
            out,
            "modes of the updated chain (Hz when the chain is in SI units):"
        );
        for (j, m) in self.modes.iter().enumerate() {
            let _ = write!(out, "  {:>3}: {:.5}", j + 1, m.frequency);
            if let Some(z) = m.damping {
                let _ = write!(out, " (zeta {z:.4})");
            }
            if let (Some(t), Some(f)) = (m.paired, m.measured_frequency) {
                let tag = if m.held_out { "held out" } else { "fitted" };
                let mac = m.mac.get(t).copied().unwrap_or(f64::NAN);
                let _ = write!(
                    out,
                    "  measured {f:.5} ({tag}, error {:+.2}%, MAC {mac:.3})",
                    100.0 * (m.frequency / f - 1.0)
                );
            }
            out.push('\n');
        }
        out
    }
}

impl ModalUpdateReport {
    /// The largest weights of a combination as `+0.62 spring 3 ...`.
    fn terms(&self, weights: &[f64]) -> String {
        let mut idx: Vec<usize> = (0..weights.len())
            .filter(|&i| weights[i].abs() >= 0.1)
            .collect();
        idx.sort_by(|&a, &b| weights[b].abs().total_cmp(&weights[a].abs()));
        let shown: Vec<String> = idx
            .iter()
            .take(6)
            .map(|&i| {
                format!(
                    "{:+.2} {} {}",
                    weights[i], self.factors[i].kind, self.factors[i].at
                )
            })
            .collect();
        let more = if idx.len() > 6 { " ..." } else { "" };
        format!("{}{more}", shown.join(" "))
    }
}

/// The factors' problem: misfit rows plus optional prior rows.
pub(crate) struct FactorProblem<'a> {
    pub(crate) nominal: &'a Chain,
    pub(crate) elements: &'a [Defect],
    pub(crate) misfit: &'a dyn MeasurementModel,
    pub(crate) prior: Option<f64>,
}

impl FactorProblem<'_> {
    /// The nominal chain with the elements scaled by `theta`.
    pub(crate) fn chain(&self, theta: &[f64]) -> Result<Chain> {
        let defects = self
            .elements
            .iter()
            .zip(theta)
            .map(|(d, f)| d.with_value(d.value() * f));
        self.nominal.uniform().with_defects(defects)
    }
}

impl LeastSquares for FactorProblem<'_> {
    fn residuals(&self, theta: &[f64]) -> Result<Vec<f64>> {
        let mut r = self.misfit.residuals(&self.chain(theta)?)?;
        if let Some(w) = self.prior {
            r.extend(theta.iter().map(|f| (f - 1.0) / w));
        }
        Ok(r)
    }
}

/// The elements freed by `mode`, each as a defect at its nominal value.
pub(crate) fn elements(nominal: &Chain, mode: ProfileMode) -> Vec<Defect> {
    let mut out = Vec::new();
    if mode != ProfileMode::Springs {
        out.extend((1..=nominal.n()).map(|at| Defect::Mass {
            at,
            m: nominal.mass_at(at),
        }));
    }
    if mode != ProfileMode::Masses {
        let (lo, hi) = nominal.spring_range();
        let k = nominal.springs();
        out.extend((lo..=hi).map(|at| Defect::Spring { at, k: k[at] }));
    }
    out
}

/// Update `nominal` (its masses and springs, defects included, are the
/// nominal values; its ends are kept) to the measured `modes`.
///
/// # Errors
/// Bad options; the data's errors ([`ModalMisfit::new`]); a nominal chain
/// the eigen solver cannot take.
///
/// ```
/// use springmass::{Chain, Defect, chain::Boundary, time::modal::undamped_modes};
/// use springmass::detect::data::modes::{MeasuredMode, MeasuredModes, ShapeEntry};
/// use springmass::detect::fit::modal_update::{update_from_modes, ModalUpdateOptions};
/// // a 3-storey shear frame whose middle storey lost 30% of its stiffness
/// let nominal = Chain::new(3)?.with_boundaries(Boundary::Fixed, Boundary::Free)?;
/// let truth = nominal.clone().with_defect(Defect::Spring { at: 1, k: 0.7 })?;
/// let m = undamped_modes(&truth)?;
/// let modes = (0..2).map(|j| MeasuredMode {
///     frequency: m.omega[j] / std::f64::consts::TAU, frequency_se: None, damping: None, damping_se: None,
///     shape: (0..3).map(|i| ShapeEntry { mass: i + 1, value: m.shapes[(i, j)], se: None }).collect(),
/// }).collect();
/// let r = update_from_modes(&nominal, MeasuredModes::new(modes)?, &ModalUpdateOptions::default())?;
/// assert!((r.factors[1].factor - 0.7).abs() < 1e-6);
/// # Ok::<(), springmass::Error>(())
/// ```
pub fn update_from_modes(
    nominal: &Chain,
    modes: MeasuredModes,
    opts: &ModalUpdateOptions,
) -> Result<ModalUpdateReport> {
    opts.check()?;
    let (fitted, held) = modes.split(&opts.hold_out)?;
    // the property difference pairs and predicts the modes in the report
    // whichever model is fitted
    let pairing =
        ModalMisfit::new(fitted.clone(), nominal.n(), opts.weights)?.with_damping_of(nominal);
    let model = modal_model(fitted.clone(), nominal, opts.weights, opts.formulation)?;
    let misfit = model.as_ref();
    let els = elements(nominal, opts.mode);
    let mut problem = FactorProblem {
        nominal,
        elements: &els,
        misfit,
        prior: None,
    };
    let (mut best, mut evaluations) = best_of_starts(&problem, opts)?;
    if !every_factor_seen(&best, misfit.dof(), opts) {
        let (fit, w, ev) = regularised(&mut problem, &best, misfit.dof() as f64, opts)?;
        evaluations += ev;
        best = fit;
        problem.prior = Some(w);
    }
    let chain = problem.chain(&best.theta)?;
    let chi2 = misfit.chi2(&chain)?;
    let parameters = effective_parameters(&best, misfit.dof());
    let factors = estimates(
        &els,
        &best,
        &problem,
        (chi2, misfit.dof() as f64 - parameters),
        pairing.errors_given(),
        opts,
    );
    let combinations = match problem.prior {
        Some(_) => combinations(&best, misfit, &chain, chi2, pairing.errors_given())?,
        None => Vec::new(),
    };
    let predicted = predict(&chain, &pairing, &fitted, &held)?;
    Ok(judge(ModalUpdateReport {
        status: String::new(),
        resolved: false,
        message: String::new(),
        factors,
        chi2,
        dof: misfit.dof(),
        p_value: None,
        parameters,
        errors_given: pairing.errors_given(),
        assumed_weights: pairing.assumed().map(|(w, _)| w),
        formulation: opts.formulation,
        prior_width: problem.prior,
        combinations,
        modes: predicted,
        starts: opts.starts + 1,
        evaluations,
        chain,
    }))
}

/// Whether the fit without a prior pins every factor: at least as many
/// data as factors, and every factor's standard error below half its value
/// and off its bounds.
fn every_factor_seen(fit: &LmFit, dof: usize, opts: &ModalUpdateOptions) -> bool {
    let p = fit.theta.len();
    let Ok(cov) = covariance(&fit.jacobian) else {
        return false;
    };
    dof >= p
        && fit.theta.iter().enumerate().all(|(i, &f)| {
            let se = cov[(i, i)].max(0.0).sqrt();
            se.is_finite() && se < 0.5 * f && !on_bound(f, opts.bounds)
        })
}

/// Whether a factor stopped on a bound.
pub(crate) fn on_bound(f: f64, bounds: (f64, f64)) -> bool {
    f <= bounds.0 * (1.0 + 1e-9) || f >= bounds.1 * (1.0 - 1e-9)
}

/// The lowest chi-square over the nominal start and the seeded ones.
fn best_of_starts(problem: &FactorProblem, opts: &ModalUpdateOptions) -> Result<(LmFit, usize)> {
    let p = problem.elements.len();
    let bounds = vec![opts.bounds; p];
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(opts.seed);
    let mut best: Option<LmFit> = None;
    let mut evaluations = 0;
    for s in 0..=opts.starts {
        crate::cancel::check()?;
        let start: Vec<f64> = if s == 0 {
            vec![1.0; p]
        } else {
            (0..p)
                .map(|_| 2f64.powf(rng.random_range(-1.0..=1.0)))
                .collect()
        };
        let fit = match levenberg_marquardt(problem, &start, &bounds, &LmOptions::default()) {
            Ok(f) => f,
            Err(Error::Cancelled) => return Err(Error::Cancelled),
            Err(_) => continue,
        };
        evaluations += fit.evaluations;
        if best.as_ref().is_none_or(|b| fit.chi2 < b.chi2) {
            best = Some(fit);
        }
    }
    let best = best.ok_or_else(|| Error::Numerical {
        method: "modal update".into(),
        reason: "no start converged (check the nominal chain's units against the frequencies)"
            .into(),
    })?;
    Ok((best, evaluations))
}

/// The fit under the narrowest prior whose data chi-square reaches
/// `target` (the discrepancy principle), warm-started from `start`.
fn regularised(
    problem: &mut FactorProblem,
    start: &LmFit,
    target: f64,
    opts: &ModalUpdateOptions,
) -> Result<(LmFit, f64, usize)> {
    let bounds = vec![opts.bounds; problem.elements.len()];
    let mut evaluations = 0;
    let mut last = None;
    for &w in &PRIOR_LADDER {
        problem.prior = Some(w);
        let fit = levenberg_marquardt(&*problem, &start.theta, &bounds, &LmOptions::default())?;
        evaluations += fit.evaluations;
        let data = problem.misfit.chi2(&problem.chain(&fit.theta)?)?;
        let done = data <= target.max(1.0);
        last = Some((fit, w));
        if done {
            break;
        }
    }
    let (fit, w) = last.expect("a non-empty ladder");
    Ok((fit, w, evaluations))
}

/// Standard error below which a combination counts as determined: a 10%
/// change shows at two standard errors (the profile's visibility rule).
const COMBINATION_SE: f64 = 0.05;

/// The combinations of factors the data alone determine (the data rows of
/// the fit's Jacobian, without the prior's).
fn combinations(
    fit: &LmFit,
    misfit: &dyn MeasurementModel,
    chain: &Chain,
    chi2: f64,
    given: bool,
) -> Result<Vec<Combination>> {
    let r = misfit.residuals(chain)?;
    let j = fit.jacobian.rows(0, r.len()).into_owned();
    let p = fit.theta.len();
    let dof = misfit.dof();
    let scale = if given || dof <= p {
        1.0
    } else {
        (chi2 / (dof - p) as f64).sqrt()
    };
    Ok(determined_combinations(
        &j,
        &r,
        &fit.theta,
        scale,
        COMBINATION_SE,
    ))
}

/// The trace of the data rows' hat matrix of `fit` (its first `m` rows
/// are the data, any further ones the prior's): the number of factors the
/// data fit (see [`ModalUpdateReport::parameters`]); the factor count when
/// the normal matrix is singular.
fn effective_parameters(fit: &LmFit, m: usize) -> f64 {
    let j = &fit.jacobian;
    let p = j.ncols();
    let m = m.min(j.nrows());
    let Some(inv) = (j.transpose() * j).try_inverse() else {
        return p as f64;
    };
    let data = j.rows(0, m);
    let trace = (&inv * (data.transpose() * data)).trace();
    if trace.is_finite() {
        trace.clamp(0.0, p as f64)
    } else {
        p as f64
    }
}

/// Factor estimates with standard errors and the determined flags;
/// `(chi2, free)` the data chi-square and its degrees of freedom.
fn estimates(
    els: &[Defect],
    fit: &LmFit,
    problem: &FactorProblem,
    (chi2, free): (f64, f64),
    given: bool,
    opts: &ModalUpdateOptions,
) -> Vec<FactorEstimate> {
    let scale = if given || free <= 0.0 {
        1.0
    } else {
        (chi2 / free).sqrt().max(f64::MIN_POSITIVE)
    };
    let cov: Option<DMatrix<f64>> = covariance(&fit.jacobian).ok();
    els.iter()
        .enumerate()
        .map(|(i, d)| {
            let f = fit.theta[i];
            let se = cov.as_ref().map(|c| c[(i, i)].max(0.0).sqrt() * scale);
            let at_bound = on_bound(f, opts.bounds);
            let determined = match (se, problem.prior) {
                (Some(s), Some(w)) => s.is_finite() && s < 0.5 * w && !at_bound,
                (Some(s), None) => s.is_finite() && s < 0.5 * f && !at_bound,
                (None, _) => false,
            };
            FactorEstimate::new(d, f, se.filter(|_| determined), determined, at_bound)
        })
        .collect()
}

/// Every mode of `chain` against the fitted and held-out measured modes.
fn predict(
    chain: &Chain,
    misfit: &ModalMisfit,
    fitted: &MeasuredModes,
    held: &[MeasuredMode],
) -> Result<Vec<PredictedMode>> {
    let modes = misfit.modes_of(chain)?;
    let damped = crate::time::survey_modes::is_damped(chain);
    let zetas: Vec<Option<f64>> = modes.zeta.iter().map(|&z| damped.then_some(z)).collect();
    let all: Vec<&MeasuredMode> = fitted.modes().iter().chain(held).collect();
    let mut paired: Vec<Option<usize>> = vec![None; modes.omega.len()];
    for (t, j) in misfit.pairing(&modes).into_iter().enumerate() {
        paired[j] = Some(t);
    }
    // held-out modes: the best MAC among modes not paired yet
    for (h, m) in held.iter().enumerate() {
        let free = (0..modes.omega.len()).filter(|&j| paired[j].is_none());
        let score = |j: usize| shape_mac(&modes, j, m).unwrap_or(0.0) - frequency_gap(&modes, j, m);
        if let Some(j) = free.max_by(|&a, &b| score(a).total_cmp(&score(b))) {
            paired[j] = Some(fitted.len() + h);
        }
    }
    Ok((0..modes.omega.len())
        .map(|j| PredictedMode {
            frequency: modes.omega[j] / std::f64::consts::TAU,
            damping: zetas[j],
            mac: all
                .iter()
                .map(|m| shape_mac(&modes, j, m).unwrap_or(f64::NAN))
                .collect(),
            paired: paired[j],
            held_out: paired[j].is_some_and(|t| t >= fitted.len()),
            measured_frequency: paired[j].map(|t| all[t].frequency),
        })
        .collect())
}

/// MAC of model mode `j` and `m` over `m`'s masses (`None` below two).
fn shape_mac(modes: &SurveyModes, j: usize, m: &MeasuredMode) -> Option<f64> {
    (m.shape.len() >= 2).then(|| {
        let a: Vec<f64> = m
            .shape
            .iter()
            .map(|e| modes.shapes[(e.mass - 1, j)])
            .collect();
        let b: Vec<f64> = m.shape.iter().map(|e| e.value).collect();
        mac(&a, &b)
    })
}

/// Relative frequency distance of model mode `j` from `m`.
fn frequency_gap(modes: &SurveyModes, j: usize, m: &MeasuredMode) -> f64 {
    (modes.omega[j] / std::f64::consts::TAU / m.frequency - 1.0).abs()
}

/// Said when a chi-square test ran on assumed weights
/// ([`ModalMisfit::assumed`]); empty when the table gave every one.
pub(crate) fn assumed_note(assumed: Option<&str>) -> String {
    assumed.map_or(String::new(), |w| {
        format!(" (under the assumed weights, {w}: if the modes are less precise, give their standard errors)")
    })
}

/// Status, `resolved` and message.
fn judge(mut r: ModalUpdateReport) -> ModalUpdateReport {
    let free = r.dof as f64 - r.parameters;
    if free > 0.5 {
        r.p_value = Some(chi2_sf(r.chi2, free));
    }
    let undetermined: Vec<String> = r
        .factors
        .iter()
        .filter(|f| !f.determined)
        .map(|f| format!("{} {}", f.kind, f.at))
        .collect();
    let mismatch = r.p_value.is_some_and(|p| p < 0.01);
    (r.status, r.resolved, r.message) = if mismatch {
        (
            "model-mismatch".into(),
            false,
            format!(
                "the updated chain does not explain the modes (chi2 {:.3} on {free:.1} dof, p = {:.2e}): check the pairing (MAC), the ends, or free the masses too{}",
                r.chi2,
                r.p_value.unwrap_or(0.0),
                assumed_note(r.assumed_weights.as_deref())
            ),
        )
    } else if !undetermined.is_empty() {
        (
            "not-determined".into(),
            false,
            format!(
                "the modes do not determine {} (held at the nominal value by a prior of width {}); measure more modes or more masses",
                undetermined.join(", "),
                r.prior_width.map_or("-".into(), |w| format!("{:.0}%", 100.0 * w))
            ),
        )
    } else {
        let how = match (r.errors_given, free > 0.0) {
            (true, _) => "standard errors from the table",
            (false, true) => "standard errors from the assumed weights, scaled by the residual",
            (false, false) => {
                "standard errors from the assumed weights only (as many data as factors: no residual to scale them by)"
            }
        };
        (
            "converged".into(),
            true,
            format!("every factor determined by the modes; {how}"),
        )
    };
    r
}
