//! Output-only (ambient) fits: which storey changed, or every storey's
//! factor, from response channels under an unknown broadband force
//! ([`AmbientMisfit`]: least squares on the Welch cross-spectral matrix,
//! the force level and sensor-noise floors profiled out). The forces are
//! white, or band-limited to [`AmbientOptions::force_band`] (flat inside,
//! none outside).
//!
//! # Method
//!
//! 1. **Checks.** The sampling must resolve the nominal chain's highest
//!    mode (`1.2 w_max <= 0.8 pi / dt`), the record must hold
//!    [`MIN_SEGMENTS`] segments of a length that resolves the first mode by
//!    four bins and the narrowest resonance by two
//!    ([`segment_length`]); otherwise a typed error says which.
//! 2. **Defect search** (`Defects`): for `k = 0..=k_max`, every set of `k`
//!    elements is scored by the chi-square a Gauss-Newton step from the
//!    `k = 0` fit would reach (one differenced Jacobian column per element);
//!    the best [`AmbientOptions::screen`] sets of each `k` are fitted by
//!    bounded Levenberg-Marquardt (factors, and the uniform damper `d` with
//!    `fit_d`); `k` by BIC; the runner-up set and its gap are reported.
//! 3. **Profile** (`Profile`): every element a factor (and `d`), one fit.
//! 4. **Modes.** The fitted chain's first modes (frequency, damping ratio)
//!    with standard errors by the delta method.
//!
//! What output-only data cannot give: the absolute scale. Scaling every
//! mass, spring and damper by one factor leaves the spectra's shape and
//! moves only the (unknown) force level. The masses are therefore the
//! user's known values (`--mass`, a baseline), and a profile of masses and
//! springs together is refused.

use crate::chain::{Chain, Defect};
use crate::detect::data::ambient::{segment_length, welch, AmbientRecord, MIN_SEGMENTS};
use crate::detect::fit::modal_locate::KRow;
use crate::detect::fit::modal_update::{elements, on_bound, FactorEstimate};
use crate::detect::fit::profile::ProfileMode;
use crate::detect::fit::select::chi2_sf;
use crate::detect::misfit::ambient::AmbientMisfit;
use crate::detect::model::MeasurementModel;
use crate::detect::search::lsq::{covariance, levenberg_marquardt, LeastSquares, LmFit, LmOptions};
use crate::error::{Error, Result};
use nalgebra::DMatrix;
use serde::Serialize;

/// What an ambient fit estimates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AmbientTarget {
    /// Between `k_min` and `k_max` changed elements, positions and values.
    Defects {
        /// Fewest defects tried.
        k_min: usize,
        /// Most defects tried.
        k_max: usize,
    },
    /// Every element a factor.
    Profile,
}

/// Options of [`fit_ambient`].
#[derive(Clone, Debug, PartialEq)]
pub struct AmbientOptions {
    /// Masses (1-based) the white forces act on; `None`: every mass.
    pub ambient_on: Option<Vec<usize>>,
    /// The forces' band `[w_a, w_b]` (rad per unit time): a flat spectrum
    /// of the fitted level inside it, none outside; `None` (default):
    /// white over every frequency.
    pub force_band: Option<(f64, f64)>,
    /// Fit the uniform damper `d` too (default true: ambient damping is
    /// rarely known).
    pub fit_d: bool,
    /// The defect search or the profile.
    pub target: AmbientTarget,
    /// Where defects may be: springs (default) or masses.
    pub kinds: ProfileMode,
    /// Factors bounded to `[lo, hi]` (default `[0.05, 20]`).
    pub bounds: (f64, f64),
    /// Segment length (samples); `None`: [`segment_length`].
    pub seg_len: Option<usize>,
    /// Sets of each `k` fitted after the screen (default 8).
    pub screen: usize,
    /// Modes reported (default 5).
    pub modes: usize,
}

impl Default for AmbientOptions {
    fn default() -> AmbientOptions {
        AmbientOptions {
            ambient_on: None,
            force_band: None,
            fit_d: true,
            target: AmbientTarget::Defects { k_min: 0, k_max: 2 },
            kinds: ProfileMode::Springs,
            bounds: (0.05, 20.0),
            seg_len: None,
            screen: 8,
            modes: 5,
        }
    }
}

/// One identified mode with its standard errors (delta method).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct IdentifiedMode {
    /// 1-based, increasing frequency.
    pub mode: usize,
    /// Undamped natural frequency `omega_j` (rad per unit time).
    pub omega: f64,
    /// Its standard error.
    pub omega_se: Option<f64>,
    /// Damping ratio.
    pub zeta: f64,
    /// Its standard error.
    pub zeta_se: Option<f64>,
}

/// The answer of [`fit_ambient`].
#[derive(Clone, Debug, Serialize)]
pub struct AmbientReport {
    /// `converged`, `model-mismatch` or `not-identifiable`.
    pub status: String,
    /// Whether the answer stands.
    pub resolved: bool,
    /// One sentence on the status.
    pub message: String,
    /// `defects` or `profile`.
    pub target: &'static str,
    /// Number of defects chosen (defect search).
    pub k: usize,
    /// The changed elements (defect search) or every element (profile).
    pub factors: Vec<FactorEstimate>,
    /// Covariance of the factors, in their order (Gauss-Newton's; empty
    /// when it could not be formed): what `springmass monitor` compares
    /// records with.
    pub covariance: Vec<Vec<f64>>,
    /// The fitted uniform damper `d` and its standard error.
    pub d: (f64, Option<f64>),
    /// The force level per mass (two-sided density; inside `force_band`
    /// when the forces are band-limited).
    pub force_level: f64,
    /// The forces' band (rad per unit time) when band-limited.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub force_band: Option<(f64, f64)>,
    /// Sensor-noise floor per channel.
    pub noise_floor: Vec<f64>,
    /// Chi-square of the answer.
    pub chi2: f64,
    /// Number of residuals.
    pub dof: usize,
    /// Upper-tail p-value of the chi-square.
    pub p_value: f64,
    /// The best set of every `k` (defect search).
    pub k_selection: Vec<KRow>,
    /// The runner-up set at the chosen `k` and its chi-square gap.
    pub runner_up: Option<(Vec<String>, f64)>,
    /// Position sets fitted by Levenberg-Marquardt.
    pub sets: usize,
    /// Segments averaged `K`, their length `L`, the bins used.
    pub segments: (usize, usize, usize),
    /// The fitted band (rad per unit time).
    pub band: (f64, f64),
    /// The fitted chain's first modes.
    pub modes: Vec<IdentifiedMode>,
    /// The fitted chain.
    pub chain: Chain,
}

/// Element factors (and `d`) on a nominal chain, fitted to the spectrum.
struct Problem<'a> {
    nominal: &'a Chain,
    elements: Vec<Defect>,
    misfit: &'a AmbientMisfit,
    /// `Some(d0)`: the last parameter is `d / d0`.
    d0: Option<f64>,
}

impl Problem<'_> {
    fn chain(&self, theta: &[f64]) -> Result<Chain> {
        let scaled: Vec<Defect> = self
            .elements
            .iter()
            .zip(theta)
            .map(|(d, f)| d.with_value(d.value() * f))
            .collect();
        let keep = self.nominal.defects().iter().copied().filter(|d| {
            !scaled
                .iter()
                .any(|s| s.kind() == d.kind() && s.at() == d.at())
        });
        let mut chain = self
            .nominal
            .uniform()
            .with_defects(keep.chain(scaled.iter().copied()))?;
        if let Some(d0) = self.d0 {
            chain = chain.with_d(d0 * theta[self.elements.len()])?;
        }
        Ok(chain)
    }

    fn len(&self) -> usize {
        self.elements.len() + usize::from(self.d0.is_some())
    }

    fn fit(&self, start: &[f64], bounds: (f64, f64)) -> Result<LmFit> {
        let b: Vec<(f64, f64)> = (0..self.len())
            .map(|i| {
                if i < self.elements.len() {
                    bounds
                } else {
                    (1e-3, 1e3)
                }
            })
            .collect();
        levenberg_marquardt(self, start, &b, &LmOptions::default())
    }
}

impl LeastSquares for Problem<'_> {
    fn residuals(&self, theta: &[f64]) -> Result<Vec<f64>> {
        self.misfit.residuals(&self.chain(theta)?)
    }

    /// Forward differences (`p + 1` evaluations instead of `2 p`; the
    /// truncation error, `~1e-6` relative, is far below the noise).
    fn jacobian(&self, theta: &[f64]) -> Result<DMatrix<f64>> {
        let r0 = self.residuals(theta)?;
        let mut j = DMatrix::zeros(r0.len(), theta.len());
        for c in 0..theta.len() {
            let h = 1e-6 * theta[c].abs().max(1e-3);
            let mut t = theta.to_vec();
            t[c] += h;
            let r = self.residuals(&t)?;
            for (i, (a, b)) in r.iter().zip(&r0).enumerate() {
                j[(i, c)] = (a - b) / h;
            }
        }
        Ok(j)
    }
}

/// The search's answer, every `k`'s best set, the runner-up and its gap,
/// and the number of sets fitted.
type Found = (SetFit, Vec<KRow>, Option<(Vec<String>, f64)>, usize);

/// The misfit, (segments, length, bins) and the band.
type Built = (AmbientMisfit, (usize, usize, usize), (f64, f64));

/// One fitted set: element indices and the fit.
struct SetFit {
    idx: Vec<usize>,
    fit: LmFit,
}

/// Fit `nominal`'s changed elements (or every element) to an ambient
/// record (see the module docs).
///
/// # Errors
/// Observed or excited masses outside the chain (fields `observe`,
/// `ambient_on`); sampling too coarse for the highest mode (field `dt`);
/// a record too short to resolve the first mode (field `samples`); a
/// constant channel ([`AmbientRecord::new`]); a profile of masses and
/// springs together (field `kinds`: the scale is not determined); `k_max`
/// above the number of elements (field `k_max`).
pub fn fit_ambient(
    nominal: &Chain,
    rec: &AmbientRecord,
    opts: &AmbientOptions,
) -> Result<AmbientReport> {
    check(nominal, rec, opts)?;
    let (misfit, segments, band) = build_misfit(nominal, rec, opts)?;
    let els = elements(nominal, opts.kinds);
    let d0 = opts.fit_d.then(|| start_d(nominal));
    let problem = |elements: Vec<Defect>| Problem {
        nominal,
        elements,
        misfit: &misfit,
        d0,
    };
    let (answer, k_selection, runner_up, sets) = match opts.target {
        AmbientTarget::Profile => {
            let p = problem(els.clone());
            let fit = p.fit(&vec![1.0; p.len()], opts.bounds)?;
            let idx = (0..els.len()).collect();
            (SetFit { idx, fit }, Vec::new(), None, 1)
        }
        AmbientTarget::Defects { k_min, k_max } => {
            search(&problem(Vec::new()), &els, k_min, k_max, opts)?
        }
    };
    let chosen: Vec<Defect> = answer.idx.iter().map(|&i| els[i]).collect();
    let (fit, misfit) = reweight(nominal, &chosen, d0, answer.fit, &misfit, opts.bounds);
    let answer = SetFit {
        idx: answer.idx,
        fit,
    };
    let p = Problem {
        nominal,
        elements: chosen,
        misfit: &misfit,
        d0,
    };
    let chain = p.chain(&answer.fit.theta)?;
    let cov = covariance(&answer.fit.jacobian).ok();
    let nuisance = misfit.nuisance(&chain)?;
    let report = AmbientReport {
        status: String::new(),
        resolved: false,
        message: String::new(),
        target: match opts.target {
            AmbientTarget::Profile => "profile",
            AmbientTarget::Defects { .. } => "defects",
        },
        k: answer.idx.len(),
        factors: estimates(&p, &answer.fit, cov.as_ref(), opts.bounds),
        covariance: cov.as_ref().map_or_else(Vec::new, |c| {
            let m = p.elements.len();
            (0..m)
                .map(|i| (0..m).map(|j| c[(i, j)]).collect())
                .collect()
        }),
        d: damper(&p, &answer.fit, cov.as_ref(), nominal),
        force_level: nuisance.force_level,
        force_band: opts.force_band,
        noise_floor: nuisance.noise_floor,
        chi2: answer.fit.chi2,
        dof: misfit.dof(),
        p_value: chi2_sf(
            answer.fit.chi2,
            misfit
                .dof()
                .saturating_sub(p.len() + rec.observe.len() + 1)
                .max(1) as f64,
        ),
        k_selection,
        runner_up,
        sets,
        segments,
        band,
        modes: identified_modes(&p, &answer.fit.theta, cov.as_ref(), opts.modes)?,
        chain,
    };
    Ok(judge(report))
}

/// Refit the chosen elements twice with the weights of the spectrum the
/// fit predicts (Fisher scoring of the Whittle likelihood: the data's own
/// weights are noisy, which widens the estimates' spread beyond their
/// standard errors). Keeps the data-weighted fit if a pass fails.
fn reweight(
    nominal: &Chain,
    chosen: &[Defect],
    d0: Option<f64>,
    mut fit: LmFit,
    misfit: &AmbientMisfit,
    bounds: (f64, f64),
) -> (LmFit, AmbientMisfit) {
    let mut current = misfit.clone();
    for _ in 0..2 {
        let p = Problem {
            nominal,
            elements: chosen.to_vec(),
            misfit: &current,
            d0,
        };
        let Ok(next) = p.chain(&fit.theta).and_then(|c| current.reweighted(&c)) else {
            break;
        };
        let q = Problem {
            misfit: &next,
            elements: chosen.to_vec(),
            ..p
        };
        let refit = if q.len() == 0 {
            base_fit(&q, bounds)
        } else {
            q.fit(&fit.theta, bounds)
        };
        match refit {
            Ok(f) => {
                fit = f;
                current = next;
            }
            Err(_) => break,
        }
    }
    (fit, current)
}

/// The options against the chain and the record.
fn check(nominal: &Chain, rec: &AmbientRecord, opts: &AmbientOptions) -> Result<()> {
    if nominal.damping().is_modal() {
        // the output spectrum is assembled from the tridiagonal K(s)
        return Err(Error::invalid(
            "damping",
            "modal",
            "grounded, between or rayleigh for an output-only fit (its spectrum needs a tridiagonal damping matrix)",
        ));
    }
    let n = nominal.n();
    for &o in &rec.observe {
        nominal.check_observe(o)?;
    }
    if let Some(on) = &opts.ambient_on {
        if on.is_empty() || on.iter().any(|&m| m == 0 || m > n) {
            return Err(Error::invalid(
                "ambient_on",
                format!("{on:?}"),
                format!("a non-empty list of masses in 1..={n}"),
            ));
        }
    }
    if opts.target == AmbientTarget::Profile && opts.kinds == ProfileMode::Both {
        return Err(Error::invalid(
            "kinds",
            "both",
            "springs or masses: output-only data do not fix the scale of masses and springs together (give the masses)",
        ));
    }
    let (lo, hi) = opts.bounds;
    if !(lo > 0.0 && lo < 1.0 && hi > 1.0 && hi.is_finite()) {
        return Err(Error::invalid(
            "bounds",
            format!("{lo}:{hi}"),
            "0 < lo < 1 < hi",
        ));
    }
    let modes = crate::time::modal::undamped_modes(nominal)?;
    let w_max = modes.omega.last().copied().unwrap_or(0.0);
    let nyquist = std::f64::consts::PI / rec.dt;
    if 1.2 * w_max > 0.8 * nyquist {
        return Err(Error::invalid(
            "dt",
            rec.dt,
            format!(
                "<= {:.4e}: sampling too coarse for the chain's highest mode (omega {w_max:.4e}; need 1.2 omega_max <= 0.8 pi / dt)",
                0.8 * std::f64::consts::PI / (1.2 * w_max)
            ),
        ));
    }
    Ok(())
}

/// The spectrum's model over the band, and (segments, length, bins), band.
fn build_misfit(nominal: &Chain, rec: &AmbientRecord, opts: &AmbientOptions) -> Result<Built> {
    let seg = match opts.seg_len {
        Some(s) => s,
        None => segment_length(nominal, rec.dt)?,
    };
    if rec.len() < seg / 2 * (MIN_SEGMENTS + 1) {
        return Err(Error::invalid(
            "samples",
            rec.len(),
            format!(
                ">= {}: too short to resolve the first mode ({MIN_SEGMENTS} segments of {seg} samples, a bin of a quarter of the first natural frequency)",
                seg / 2 * (MIN_SEGMENTS + 1)
            ),
        ));
    }
    let spec = welch(rec, seg)?;
    let w_max = crate::time::modal::undamped_modes(nominal)?
        .omega
        .last()
        .copied()
        .unwrap_or(0.0);
    let band = (0.0, (1.3 * w_max).min(0.8 * std::f64::consts::PI / rec.dt));
    let on = opts
        .ambient_on
        .clone()
        .unwrap_or_else(|| (1..=nominal.n()).collect());
    let mut misfit = AmbientMisfit::new(&spec, rec.observe.clone(), rec.kind, on, band)?;
    if let Some(fb) = opts.force_band {
        misfit = misfit.with_force_band(fb)?;
    }
    let bins = misfit.bins();
    Ok((misfit, (spec.segments, seg, bins), band))
}

/// The damper's starting value: the nominal `d`, or 2% of critical at the
/// first mode when the nominal chain is undamped.
fn start_d(nominal: &Chain) -> f64 {
    if nominal.d() > 0.0 {
        return nominal.d();
    }
    let w1 = crate::time::modal::undamped_modes(nominal)
        .ok()
        .and_then(|m| m.omega.first().copied())
        .unwrap_or(1.0);
    0.04 * w1 * nominal.mass()
}

/// The base fit (no defect: `d` alone with `fit_d`, else the nominal chain).
fn base_fit(base: &Problem, bounds: (f64, f64)) -> Result<LmFit> {
    if base.d0.is_some() {
        return base.fit(&[1.0], bounds);
    }
    let r = base.residuals(&[])?;
    Ok(LmFit {
        theta: Vec::new(),
        chi2: r.iter().map(|v| v * v).sum(),
        m: r.len(),
        jacobian: DMatrix::zeros(r.len(), 0),
        iterations: 0,
        evaluations: 1,
        converged: true,
        at_bound: Vec::new(),
    })
}

/// Differenced Jacobian columns at the base fit: one per element, then `d`.
fn screen_columns(base: &Problem, theta_d: &[f64], els: &[Defect]) -> Result<Vec<Vec<f64>>> {
    const H: f64 = 1e-4;
    let diff = |p: &Problem, lo: Vec<f64>, hi: Vec<f64>, step: f64| -> Result<Vec<f64>> {
        let (a, b) = (p.residuals(&lo)?, p.residuals(&hi)?);
        Ok(a.iter()
            .zip(&b)
            .map(|(a, b)| (b - a) / (2.0 * step))
            .collect())
    };
    let mut cols = Vec::with_capacity(els.len() + 1);
    for e in els {
        crate::cancel::check()?;
        let p = Problem {
            elements: vec![*e],
            ..*base
        };
        let with = |f: f64| [vec![f], theta_d.to_vec()].concat();
        cols.push(diff(&p, with(1.0 - H), with(1.0 + H), H)?);
    }
    if let Some(&td) = theta_d.first() {
        let h = H * td;
        cols.push(diff(base, vec![td - h], vec![td + h], h)?);
    }
    Ok(cols)
}

/// The chi-square a Gauss-Newton step on `set` (and `d`) would reach.
fn screen_score(gram: &DMatrix<f64>, g: &[f64], chi2: f64, set: &[usize], d: Option<usize>) -> f64 {
    let idx: Vec<usize> = set.iter().copied().chain(d).collect();
    let a = DMatrix::from_fn(idx.len(), idx.len(), |r, c| gram[(idx[r], idx[c])]);
    let b = nalgebra::DVector::from_iterator(idx.len(), idx.iter().map(|&i| g[i]));
    match a.cholesky() {
        Some(ch) => chi2 - b.dot(&ch.solve(&b)),
        None => f64::INFINITY,
    }
}

/// The defect search: screen, fit the best sets of each `k`, choose `k` by BIC.
fn search(
    base: &Problem,
    els: &[Defect],
    k_min: usize,
    k_max: usize,
    opts: &AmbientOptions,
) -> Result<Found> {
    if k_min > k_max || k_max > els.len() || k_max > 4 {
        return Err(Error::invalid(
            "k_max",
            k_max,
            format!("k_min <= k_max <= min(4, {})", els.len()),
        ));
    }
    let base_fit = base_fit(base, opts.bounds)?;
    let r0 = base.residuals(&base_fit.theta)?;
    let cols = screen_columns(base, &base_fit.theta, els)?;
    let q = cols.len();
    let gram = DMatrix::from_fn(q, q, |a, b| dot(&cols[a], &cols[b]));
    let g: Vec<f64> = cols.iter().map(|c| -dot(c, &r0)).collect();
    let d_col = base.d0.map(|_| els.len());
    let mut rows: Vec<(SetFit, Option<SetFit>)> = Vec::new();
    let mut sets = 0;
    for k in k_min..=k_max {
        if k == 0 {
            let fit = base_fit.clone();
            rows.push((
                SetFit {
                    idx: Vec::new(),
                    fit,
                },
                None,
            ));
            continue;
        }
        let mut scored: Vec<(f64, Vec<usize>)> = Vec::new();
        let mut idx: Vec<usize> = (0..k).collect();
        loop {
            scored.push((
                screen_score(&gram, &g, base_fit.chi2, &idx, d_col),
                idx.clone(),
            ));
            if !super::modal_locate::next_combination(&mut idx, els.len()) {
                break;
            }
        }
        scored.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut fits = Vec::new();
        for (_, idx) in scored.into_iter().take(opts.screen.max(2)) {
            crate::cancel::check()?;
            let p = Problem {
                elements: idx.iter().map(|&i| els[i]).collect(),
                ..*base
            };
            let start = [vec![1.0; k], base_fit.theta.clone()].concat();
            if let Ok(fit) = p.fit(&start, opts.bounds) {
                fits.push(SetFit { idx, fit });
            }
        }
        sets += fits.len();
        fits.sort_by(|a, b| a.fit.chi2.total_cmp(&b.fit.chi2));
        let mut it = fits.into_iter();
        let first = it.next().ok_or_else(|| Error::Numerical {
            method: "ambient defect search".into(),
            reason: format!("no set of {k} elements could be fitted"),
        })?;
        rows.push((first, it.next()));
    }
    Ok(choose(rows, els, r0.len(), sets))
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// `spring 3`, `mass 2`.
fn label(els: &[Defect], idx: &[usize]) -> Vec<String> {
    idx.iter()
        .map(|&i| format!("{} {}", els[i].kind(), els[i].at()))
        .collect()
}

/// The number of defects by BIC (`chi2 + 2 k ln N`: a position and a value each).
fn choose(
    rows: Vec<(SetFit, Option<SetFit>)>,
    els: &[Defect],
    n_data: usize,
    sets: usize,
) -> Found {
    let ln = (n_data.max(2) as f64).ln();
    let bic = |f: &SetFit| f.fit.chi2 + 2.0 * f.idx.len() as f64 * ln;
    let k_selection: Vec<KRow> = rows
        .iter()
        .map(|(f, _)| KRow {
            k: f.idx.len(),
            chi2: f.fit.chi2,
            bic: bic(f),
            set: label(els, &f.idx),
        })
        .collect();
    let chosen = (0..rows.len())
        .min_by(|&a, &b| bic(&rows[a].0).total_cmp(&bic(&rows[b].0)))
        .expect("at least one k");
    let (answer, second) = rows.into_iter().nth(chosen).expect("in range");
    let runner_up = second.map(|s| (label(els, &s.idx), s.fit.chi2 - answer.fit.chi2));
    (answer, k_selection, runner_up, sets)
}

/// The fitted elements with standard errors.
fn estimates(
    p: &Problem,
    fit: &LmFit,
    cov: Option<&DMatrix<f64>>,
    bounds: (f64, f64),
) -> Vec<FactorEstimate> {
    p.elements
        .iter()
        .enumerate()
        .map(|(c, d)| {
            let f = fit.theta[c];
            let se = cov.map(|m| m[(c, c)].max(0.0).sqrt());
            let at_bound = on_bound(f, bounds);
            let determined = se.is_some_and(|s| s.is_finite() && s < 0.5 * f) && !at_bound;
            FactorEstimate::new(d, f, se, determined, at_bound)
        })
        .collect()
}

/// The fitted `d` and its standard error (the nominal `d` without `fit_d`).
fn damper(
    p: &Problem,
    fit: &LmFit,
    cov: Option<&DMatrix<f64>>,
    nominal: &Chain,
) -> (f64, Option<f64>) {
    match p.d0 {
        Some(d0) => {
            let i = p.elements.len();
            (
                d0 * fit.theta[i],
                cov.map(|m| d0 * m[(i, i)].max(0.0).sqrt()),
            )
        }
        None => (nominal.d(), None),
    }
}

/// The first `count` modes of the fitted chain, standard errors by the
/// delta method (differenced frequencies and damping ratios).
fn identified_modes(
    p: &Problem,
    theta: &[f64],
    cov: Option<&DMatrix<f64>>,
    count: usize,
) -> Result<Vec<IdentifiedMode>> {
    let modes_at = |t: &[f64]| -> Result<Vec<(f64, f64)>> {
        let m = crate::time::modal::natural_modes(&p.chain(t)?)?;
        Ok(m.iter()
            .take(count)
            .map(|m| (m.omega, m.zeta.unwrap_or(0.0)))
            .collect())
    };
    let at = modes_at(theta)?;
    let q = theta.len();
    let mut jw = DMatrix::zeros(at.len(), q);
    let mut jz = DMatrix::zeros(at.len(), q);
    for c in 0..q {
        let h = 1e-5 * theta[c].abs().max(1e-3);
        let (mut lo, mut hi) = (theta.to_vec(), theta.to_vec());
        lo[c] -= h;
        hi[c] += h;
        let (a, b) = (modes_at(&lo)?, modes_at(&hi)?);
        for j in 0..at.len().min(a.len()).min(b.len()) {
            jw[(j, c)] = (b[j].0 - a[j].0) / (2.0 * h);
            jz[(j, c)] = (b[j].1 - a[j].1) / (2.0 * h);
        }
    }
    let se = |j: &DMatrix<f64>, row: usize| {
        cov.map(|c| {
            let r = j.row(row);
            (r * c * r.transpose())[(0, 0)].max(0.0).sqrt()
        })
    };
    Ok(at
        .iter()
        .enumerate()
        .map(|(j, &(omega, zeta))| IdentifiedMode {
            mode: j + 1,
            omega,
            omega_se: se(&jw, j),
            zeta,
            zeta_se: se(&jz, j),
        })
        .collect())
}

/// Status, `resolved` and message.
fn judge(mut r: AmbientReport) -> AmbientReport {
    let margin = (r.dof.max(2) as f64).ln();
    let marginal = r
        .k_selection
        .iter()
        .position(|row| row.k == r.k)
        .filter(|&i| i > 0)
        .map(|i| r.k_selection[i - 1].bic - r.k_selection[i].bic)
        .filter(|gain| *gain < margin);
    let close = r.runner_up.as_ref().filter(|(_, gap)| *gap < margin);
    (r.status, r.resolved, r.message) = if r.p_value < 1e-3 {
        (
            "model-mismatch".into(),
            false,
            format!(
                "the chain does not explain the spectra (chi2 {:.1} on {} residuals): check the nominal chain, the observed masses and kind, the excited set (--ambient-on), or allow more defects",
                r.chi2, r.dof
            ),
        )
    } else if let Some(gain) = marginal {
        (
            "not-identifiable".into(),
            false,
            format!(
                "the spectra barely ask for defect {} (BIC better by only {gain:.2})",
                r.k
            ),
        )
    } else if let Some((set, gap)) = close {
        (
            "not-identifiable".into(),
            false,
            format!(
                "the spectra do not tell this set from {} (chi-square worse by only {gap:.2})",
                set.join(", ")
            ),
        )
    } else if r.factors.iter().any(|f| !f.determined) {
        (
            "not-identifiable".into(),
            false,
            "a factor is not determined (on a bound, or its standard error above half its value)"
                .into(),
        )
    } else {
        let what = match (r.target, r.k) {
            ("defects", 0) => "no element changed",
            ("defects", _) => "every defect identifiable",
            _ => "every factor determined",
        };
        ("converged".into(), true, what.into())
    };
    r
}

impl AmbientReport {
    /// The report as text: status, factors, damping, modes, the evidence.
    pub fn summary(&self) -> String {
        use std::fmt::Write;
        let mut out = format!("status: {} - {}\n", self.status, self.message);
        if self.target == "defects" && self.factors.is_empty() {
            out.push_str("no changed element\n");
        }
        for f in &self.factors {
            let se = f.se.map_or("-".into(), |s| format!("{s:.4}"));
            let _ = writeln!(
                out,
                "{} {}: factor {:.4} +- {se} ({:.5e}, nominal {:.5e})",
                f.kind, f.at, f.factor, f.value, f.nominal
            );
        }
        let dse = self.d.1.map_or("(fixed)".into(), |s| format!("+- {s:.3e}"));
        let _ = writeln!(out, "d = {:.5e} {dse}", self.d.0);
        let floors: Vec<String> = self
            .noise_floor
            .iter()
            .map(|v| format!("{v:.3e}"))
            .collect();
        let band = self.force_band.map_or(String::new(), |(a, b)| {
            format!(" in the force band {a:.4}..{b:.4} rad/time")
        });
        // a floor is a free linear term of the fitted spectrum; below 0 it is
        // no noise level (the model's spectrum exceeds the measured one there)
        let negative = if self.noise_floor.iter().any(|&v| v < 0.0) {
            " (a negative floor is no noise level: the fitted spectrum exceeds the measured one on that channel)"
        } else {
            ""
        };
        let _ = writeln!(
            out,
            "force level {:.4e}{band}, sensor-noise floors [{}]{negative}",
            self.force_level,
            floors.join(", ")
        );
        let (k, l, b) = self.segments;
        let _ = writeln!(
            out,
            "chi2 {:.2} on {} residuals (p = {:.3}); Welch: {k} segments of {l} samples, {b} bins in {:.4}..{:.4} rad/time",
            self.chi2, self.dof, self.p_value, self.band.0, self.band.1
        );
        if let Some((set, gap)) = &self.runner_up {
            let _ = writeln!(
                out,
                "runner-up: {} (chi2 worse by {gap:.2})",
                set.join(", ")
            );
        }
        if !self.k_selection.is_empty() {
            out.push_str("number of defects by BIC (the search, weighted by the data):\n");
        }
        for row in &self.k_selection {
            let mark = if row.k == self.k { "  <- chosen" } else { "" };
            let _ = writeln!(
                out,
                "  k = {}: chi2 {:.2}, bic {:.2} [{}]{mark}",
                row.k,
                row.chi2,
                row.bic,
                row.set.join(", ")
            );
        }
        out.push_str("modes of the fitted chain (omega rad/time, zeta):\n");
        for m in &self.modes {
            let s = |v: Option<f64>| v.map_or("-".into(), |v| format!("{v:.2e}"));
            let _ = writeln!(
                out,
                "  {}: omega {:.5} +- {}, zeta {:.4} +- {}",
                m.mode,
                m.omega,
                s(m.omega_se),
                m.zeta,
                s(m.zeta_se)
            );
        }
        out
    }
}
