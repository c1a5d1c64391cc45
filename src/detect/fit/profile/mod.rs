//! Whole-profile inversion: every mass, every spring, or both, of the chain
//! free, fitted to the data by bounded Levenberg-Marquardt with reciprocity
//! gradients (O(n) per node, [`crate::sensitivity`]), regularised only as
//! much as the noise needs, with standard errors and a visibility report.
//!
//! # Method
//!
//! 1. **Observations**: Laplace values are used as given (chi-square at
//!    their nodes); a sampled series is transformed to a whitened Bromwich
//!    chi-square ([`crate::detect::fit::general::laplace_obs`], the record's
//!    line of [`Setup::for_record`]) with at least two complex nodes per
//!    free value.
//! 2. **Continuation** in the weight `lambda` of a sparsity-promoting
//!    penalty on the relative deviation of every free value from the
//!    model's uniform one, `delta_j = (theta_j - u_j) / u_j`: the penalty
//!    row `sqrt(lambda) delta_j / (delta_j^2 + eps^2)^(1/4)` adds
//!    `lambda |delta_j|` to the chi-square for `|delta_j| >> eps` (a smooth
//!    L1; `eps` = [`ProfileOptions::eps`]). `lambda` starts at the data
//!    chi-square of the uniform chain (at least the number of data: the
//!    first stage stays near it) and drops tenfold per stage, each stage warm-started, until the
//!    data chi-square reaches the discrepancy target
//!    `dof + 2 sqrt(2 dof)` (noise level known or estimated) or `lambda`
//!    reaches [`ProfileOptions::lambda_min`] times its start.
//! 3. **Restarts.** When the data chi-square stays above three times its
//!    target (a wrong basin: the misfit of a strongly varying profile has
//!    many local minima), the continuation is run again from a frequency
//!    continuation ([`BANDS`]: the lowest quarter, half and three quarters
//!    of the band in turn, warm-started), from the data-first defect fit's
//!    answer (a few defects, k by BIC), from a layer-stripping start (the
//!    values nearest the sensor freed first), from the same data weighted
//!    by the transform's own error (a series) or relatively (Laplace
//!    values), and from scaled uniform starts; the lowest chi-square wins.
//! 4. **Visibility**: from the Fisher information `J^T J` of the data at
//!    that profile, the free values are taken in order of distance from the
//!    observed mass; the longest prefix in which every value's standard
//!    error (with the whole prefix free) satisfies `2 SE <= change
//!    max(u_j, theta_j)` is *visible*: the data would show a change of
//!    `change` (default 10%) of the value there (of the uniform value, for a
//!    value below it) at two standard errors. Beyond it the data
//!    cannot see such a change (a deep, light defect's echo is below the
//!    noise); those values are reported as not visible, without a standard
//!    error.
//! 5. **Final fit**: every value free, the hidden ones under a Gaussian
//!    prior of width `change` around the uniform value (they move where the
//!    data ask, and their uncertainty enters the visible values' standard
//!    errors), the visible ones and the chain parameters unpenalised. For a
//!    record whose every value is visible (at most [`TIME_POLISH_MAX`]),
//!    the values are then polished by the time-domain chi-square, the likelihood of the samples
//!    themselves, whose Gauss-Newton covariance gives the standard errors
//!    (measured calibrated: `tests/long_chains.rs`).
//!
//! With a noise level not given, a first pass runs the continuation to its
//! end, the residual of that nearly free fit gives `sigma` (`sqrt(chi^2 /
//! (m - p))`), the fit is repeated at that level, and the standard errors
//! are scaled by the final residual.
//!
//! ```
//! use springmass::{Chain, Defect};
//! use springmass::detect::data::observations::{LaplaceValues, Observations};
//! use springmass::detect::fit::{fit_profile, Model, NoiseSpec};
//! use springmass::detect::fit::profile::{ProfileMode, ProfileOptions};
//! use num_complex::Complex64;
//! // exact Laplace values of a chain whose masses all differ
//! let truth = Chain::paper(8)?.with_defects(
//!     (1..=8).map(|i| Defect::Mass { at: i, m: 1.0 + 0.1 * i as f64 }))?;
//! let s: Vec<Complex64> = (0..60).map(|q| Complex64::new(0.05, 0.05 * q as f64)).collect();
//! let x = s.iter().map(|z| springmass::forward::response(&truth, *z, 1)).collect::<Result<Vec<_>, _>>()?;
//! let obs = Observations::Laplace(LaplaceValues::new(s, x, None)?);
//! let opts = ProfileOptions { noise: NoiseSpec::Sigma(1e-12), ..ProfileOptions::new(ProfileMode::Masses) };
//! let p = fit_profile(&obs, &Model::new(8)?, &opts)?;
//! for (i, e) in p.elements.iter().enumerate() {
//!     assert!((e.value - (1.0 + 0.1 * (i + 1) as f64)).abs() < 1e-8);
//! }
//! assert_eq!(p.visible_count(), 8);
//! # Ok::<(), springmass::Error>(())
//! ```

mod options;
mod path;
mod report;

pub use options::{ProfileMode, ProfileOptions};
use path::{continuation, depth_order, regularised_path, visible_prefix};
use report::{noise_note, verdict, visibility_note};
pub use report::{ElementEstimate, ProfileReport};

use crate::chain::{Chain, Defect};
use crate::detect::data::laplace::LaplaceObs;
use crate::detect::data::observations::{Observations, Series};
use crate::detect::fit::chainfit::fit_chain;
use crate::detect::fit::general::{laplace_obs, Setup};
use crate::detect::fit::goodness::{exact_record, FITS_DATA_P};
use crate::detect::fit::model::Model;
use crate::detect::fit::options::{FitOptions, NoiseSpec};
use crate::detect::fit::record::whiteness_p;
use crate::detect::fit::report::FitReport;
use crate::detect::fit::select::chi2_sf;
use crate::detect::misfit::time::TimeMisfit;
use crate::detect::misfit::MisfitKind;
use crate::detect::search::lsq::{covariance, levenberg_marquardt, LeastSquares, LmOptions};
use crate::error::{Error, Result};
use crate::sensitivity::Param;
use nalgebra::DMatrix;
use std::time::Instant;

/// One free value: its defect form and uniform value.
#[derive(Clone, Copy, Debug)]
struct Elem {
    kind: ElemKind,
    at: usize,
    uniform: f64,
    start: f64,
    depth: f64,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum ElemKind {
    Mass,
    Spring,
}

impl Elem {
    fn defect(&self, value: f64) -> Defect {
        match self.kind {
            ElemKind::Mass => Defect::Mass {
                at: self.at,
                m: value,
            },
            ElemKind::Spring => Defect::Spring {
                at: self.at,
                k: value,
            },
        }
    }
    fn name(&self) -> &'static str {
        match self.kind {
            ElemKind::Mass => "mass",
            ElemKind::Spring => "spring",
        }
    }
}

/// The free values of `mode` on `model`'s chain, and the defects that stay
/// fixed (known defects of other kinds; known values of the profiled kind
/// stay known).
fn elements(model: &Model, mode: ProfileMode, observe: usize) -> Result<(Vec<Elem>, Vec<Defect>)> {
    let chain = model.chain();
    let n = chain.n();
    let known = chain.defects();
    let is_known = |kind: ElemKind, at: usize| {
        known.iter().any(|d| match (kind, d) {
            (ElemKind::Mass, Defect::Mass { at: a, .. }) => *a == at,
            (ElemKind::Spring, Defect::Spring { at: a, .. }) => *a == at,
            _ => false,
        })
    };
    let o = observe as f64;
    let mut elems = Vec::new();
    if matches!(mode, ProfileMode::Masses | ProfileMode::Both) {
        for at in 1..=n {
            if !is_known(ElemKind::Mass, at) {
                elems.push(Elem {
                    kind: ElemKind::Mass,
                    at,
                    uniform: chain.mass(),
                    start: chain.mass(),
                    depth: (at as f64 - o).abs(),
                });
            }
        }
    }
    if matches!(mode, ProfileMode::Springs | ProfileMode::Both) {
        let (lo, hi) = chain.spring_range();
        if lo <= hi && !(n == 1 && chain.is_free_free()) {
            for at in lo..=hi {
                if !is_known(ElemKind::Spring, at) {
                    elems.push(Elem {
                        kind: ElemKind::Spring,
                        at,
                        uniform: chain.k(),
                        start: chain.k(),
                        depth: (at as f64 + 0.5 - o).abs(),
                    });
                }
            }
        }
    }
    if elems.is_empty() {
        return Err(Error::invalid(
            "profile",
            mode.name(),
            "a mode with at least one free value (every value of this kind is known, or the chain has no spring)",
        ));
    }
    Ok((elems, known.to_vec()))
}

/// What is free and what is held: the chain's uniform part, the defects
/// held at their values, the free values and the fitted chain parameters
/// (the parameter vector is the free values, then the chain parameters).
struct Space {
    base: Chain,
    fixed: Vec<Defect>,
    elems: Vec<Elem>,
    params: Vec<Param>,
}

impl Space {
    fn chain(&self, theta: &[f64]) -> Result<Chain> {
        let nf = self.elems.len();
        let mut c = self.base.clone();
        for (p, v) in self.params.iter().zip(&theta[nf..]) {
            c = p.set(&c, *v)?;
        }
        let defects = self
            .fixed
            .iter()
            .copied()
            .chain(self.elems.iter().zip(theta).map(|(e, v)| e.defect(*v)));
        c.with_defects(defects)
    }

    /// The chain parameters of [`Space::chain`] in parameter-vector order.
    fn jac_params(&self) -> Vec<Param> {
        let k0 = self.fixed.len();
        (0..self.elems.len())
            .map(|i| Param::Defect(k0 + i))
            .chain(self.params.iter().copied())
            .collect()
    }

    /// Every free value at `scale` times its start, the chain parameters at
    /// the model's values.
    fn start(&self, scale: f64) -> Vec<f64> {
        self.elems
            .iter()
            .map(|e| e.start * scale)
            .chain(self.params.iter().map(|p| p.get(&self.base).unwrap_or(1.0)))
            .collect()
    }

    /// The problem on `obs` without a penalty.
    fn problem<'a>(&'a self, obs: &'a LaplaceObs) -> Problem<'a> {
        Problem {
            obs,
            space: self,
            lambda: 0.0,
            eps: 0.0,
            penalised: None,
            prior_width: None,
        }
    }
}

/// The least-squares problem: data residuals plus penalty rows.
struct Problem<'a> {
    obs: &'a LaplaceObs,
    space: &'a Space,
    lambda: f64,
    eps: f64,
    /// Which free values carry the penalty (`None`: all).
    penalised: Option<Vec<bool>>,
    /// Instead of the smooth L1: a Gaussian prior of this relative width
    /// around the uniform value, `r = (theta - u) / (width u)`.
    prior_width: Option<f64>,
}

impl Problem<'_> {
    fn chain(&self, theta: &[f64]) -> Result<Chain> {
        self.space.chain(theta)
    }

    /// Penalty rows `(index of the free value, residual, derivative)`.
    fn penalty(&self, theta: &[f64]) -> Vec<(usize, f64, f64)> {
        let sl = self.lambda.sqrt();
        let e2 = self.eps * self.eps;
        self.space
            .elems
            .iter()
            .zip(theta)
            .enumerate()
            .filter(|(i, _)| self.penalised.as_ref().is_none_or(|m| m[*i]))
            .map(|(i, (e, v))| {
                let d = (v - e.uniform) / e.uniform;
                if let Some(w) = self.prior_width {
                    return (i, d / w, 1.0 / (w * e.uniform));
                }
                let q = d * d + e2;
                let r = sl * d / q.powf(0.25);
                let dr = sl / e.uniform * (0.5 * d * d + e2) / q.powf(1.25);
                (i, r, dr)
            })
            .collect()
    }
}

impl LeastSquares for Problem<'_> {
    fn residuals(&self, theta: &[f64]) -> Result<Vec<f64>> {
        let mut r = self.obs.residuals(&self.chain(theta)?)?;
        if self.lambda > 0.0 {
            r.extend(self.penalty(theta).into_iter().map(|(_, v, _)| v));
        }
        Ok(r)
    }
    fn jacobian(&self, theta: &[f64]) -> Result<DMatrix<f64>> {
        let j = self
            .obs
            .jacobian(&self.chain(theta)?, &self.space.jac_params())?;
        if self.lambda <= 0.0 {
            return Ok(j);
        }
        let pen = self.penalty(theta);
        let m = j.nrows();
        let mut out = DMatrix::zeros(m + pen.len(), j.ncols());
        out.rows_mut(0, m).copy_from(&j);
        for (row, (i, _, dr)) in pen.into_iter().enumerate() {
            out[(m + row, i)] = dr;
        }
        Ok(out)
    }
}

impl Problem<'_> {
    /// The data chi-square alone (no penalty rows).
    fn data_chi2(&self, theta: &[f64]) -> Result<f64> {
        Ok(self
            .obs
            .residuals(&self.chain(theta)?)?
            .iter()
            .map(|v| v * v)
            .sum())
    }
}

/// The observations as a Laplace chi-square at noise level `sigma`, and the
/// misfit's description.
fn laplace(
    obs: &Observations,
    model: &Model,
    sigma: f64,
    free: usize,
) -> Result<(LaplaceObs, String)> {
    laplace_band(obs, model, sigma, free, 1.0)
}

/// As [`laplace`], on the lowest fraction `band` of the frequencies: the
/// Bromwich line of a record over `band` times its width, or the given
/// Laplace values with `|Im s|` at most `band` times the largest.
fn laplace_band(
    obs: &Observations,
    model: &Model,
    sigma: f64,
    free: usize,
    band: f64,
) -> Result<(LaplaceObs, String)> {
    match obs {
        Observations::Series(s) => {
            let mut setup = Setup::for_record(s.t().last().copied(), model.chain())?;
            // at least two complex nodes (four real data) per free value
            let nodes = (2 * free).max(80);
            let panels = nodes.div_ceil(8);
            // the band of Setup::for_record: twice the chain's, at least 4
            let chain_band = model.chain().uniform_band();
            setup.bromwich_rule = crate::detect::misfit::quadrature::Rule::gauss_legendre_uniform(
                0.0,
                (2.0 * chain_band).max(4.0) * band,
                panels,
                8,
            )?;
            setup.screen_nodes = 0;
            let td = s.time_data(sigma)?;
            let l = laplace_obs(&td, MisfitKind::Bromwich, &setup)?;
            let name = format!(
                "bromwich (whitened chi-square of the transformed series, sigma_B = {}, {} nodes, {} dof)",
                setup.bromwich_sigma,
                l.nodes().len(),
                l.dof()
            );
            Ok((l, name))
        }
        Observations::Laplace(l) => {
            let w_max = l.s().iter().fold(0.0f64, |a, z| a.max(z.im.abs()));
            let o = l.obs_where(sigma, |q| l.s()[q].im.abs() <= band * w_max)?;
            let name = format!("chi-square at {} given Laplace nodes", o.nodes().len());
            Ok((o, name))
        }
    }
}

/// A start from the data-first defect fit (`detect::fit::fit`,
/// the number of defects by BIC among `0..=4`, kinds those of the profile,
/// enumeration up to 20 masses and the greedy search beyond):
/// its defects' values at their positions, the uniform value elsewhere.
/// `None` when that fit fails.
fn defect_start(
    fit: DefectFitter,
    obs: &Observations,
    model: &Model,
    space: &Space,
    opts: &ProfileOptions,
) -> Option<Vec<f64>> {
    use crate::detect::fit::options::{DefectCount, DEFAULT_K_MAX};
    use crate::detect::unknowns::KindChoice;
    let fopts = FitOptions {
        defects: DefectCount::Auto {
            k_max: DEFAULT_K_MAX.min(model.n()),
        },
        kinds: match opts.mode {
            ProfileMode::Masses => KindChoice::Mass,
            ProfileMode::Springs => KindChoice::Spring,
            ProfileMode::Both => KindChoice::Any,
        },
        noise: opts.noise,
        // enumeration up to C(20, 4) = 4845 sets; the greedy search beyond
        method: if model.n() <= 20 {
            crate::detect::search::FitMethod::Enumerate
        } else {
            crate::detect::search::FitMethod::Greedy
        },
        parallel: false,
        ..FitOptions::default()
    };
    let r = fit(obs, model, &fopts).ok()?;
    let mut theta = space.start(1.0);
    for d in r.found() {
        if let Some(i) = space
            .elems
            .iter()
            .position(|e| e.name() == d.kind() && e.at == d.at())
        {
            theta[i] = d.value();
        }
    }
    let nf = space.elems.len();
    for (j, p) in space.params.iter().enumerate() {
        let name = crate::detect::fit::general::param_name(p);
        if let Some(e) = r.params.iter().find(|e| e.name == name) {
            theta[nf + j] = e.value;
        }
    }
    Some(theta)
}

/// Fractions of the band fitted in turn by the frequency continuation.
pub const BANDS: [f64; 3] = [0.25, 0.5, 0.75];

/// A start grown from the low frequencies (a frequency continuation, the
/// classical remedy for a misfit with many local minima at high
/// frequencies): the continuation on the lowest quarter, half and three
/// quarters of the band in turn, each warm-started from the last (bands
/// with fewer data than free values skipped); the values and iterations.
fn band_start(
    obs: &Observations,
    model: &Model,
    sigma: f64,
    space: &Space,
    opts: &ProfileOptions,
) -> Result<(Vec<f64>, usize)> {
    let mut theta = space.start(1.0);
    let mut iterations = 0;
    let p = space.elems.len() + space.params.len();
    for band in BANDS {
        let (l, _) = laplace_band(obs, model, sigma, space.elems.len(), band)?;
        if l.dof() <= p {
            continue;
        }
        let dof = l.dof() as f64;
        let target = dof + 2.0 * (2.0 * dof).sqrt();
        let path = continuation(&l, space, opts, Some(target), theta)?;
        iterations += path.iterations;
        theta = path.theta;
    }
    Ok((theta, iterations))
}

/// The data-first defect fit handed to [`fit_profile_with`] for its
/// restart from a defect fit (`detect::fit::fit`; passed in, so
/// that the defect fit's own `relax` method can run the profile without an
/// import cycle).
pub type DefectFitter<'a> =
    &'a (dyn Fn(&Observations, &Model, &FitOptions) -> Result<FitReport> + Sync);

/// Fit every value of `opts.mode` (see the module docs), with `defect_fit`
/// for the restart from a defect fit (`None`: that restart is skipped).
/// `detect::fit::fit_profile` passes the data-first fit.
///
/// # Errors
/// Invalid options; a mode with nothing free; fewer data than free values
/// (field `profile`); a numerical failure of the forward model.
pub fn fit_profile_with(
    obs: &Observations,
    model: &Model,
    opts: &ProfileOptions,
    defect_fit: Option<DefectFitter>,
) -> Result<ProfileReport> {
    check_input(obs, model, opts)?;
    let t0 = Instant::now();
    let space = profile_space(obs, model, opts)?;
    let (nf, np) = (space.elems.len(), space.params.len());
    let (sigma, estimated) = start_sigma(obs, opts);
    let (sigma, l, misfit, path) =
        regularised_path(obs, model, opts, defect_fit, &space, sigma, estimated)?;
    let mut iterations = path.iterations;
    // visibility at the regularised profile
    let jac = space.problem(&l).jacobian(&path.theta)?;
    let order = depth_order(&space.elems);
    let visible = visible_prefix(&jac, &space.elems, &path.theta, &order, np, opts.change);
    let visible_set: Vec<bool> = (0..nf).map(|i| order[..visible].contains(&i)).collect();
    let bounds = bounds_of(&space, opts.bound);
    let mut fin = final_fit(&space, &l, &path.theta, &visible_set, &bounds, opts, misfit)?;
    let p = visible + np;
    // a record: the visible values polished by the time-domain chi-square
    // (the likelihood of the samples themselves), the others held
    let polished = match obs {
        Observations::Series(series) if p > 0 && p <= TIME_POLISH_MAX && visible == nf => {
            time_polish(series, sigma, &space, &visible_set, &bounds, &mut fin)?;
            Some(series)
        }
        _ => None,
    };
    iterations += fin.iterations;
    let fit_dof = fin.m.saturating_sub(p).max(1) as f64;
    let (scale, fits_data, fit_p_value) =
        goodness(polished, (sigma, estimated), &space, &fin, fit_dof)?;
    let chi2_out = fin.chi2 / (scale * scale);
    let (elements, params) = estimates(&space, &fin, &visible_set, scale);
    let covariance = element_covariance(&fin, &visible_set, scale);
    let visible_depth = order[..visible]
        .iter()
        .map(|&i| space.elems[i].depth)
        .fold(None, |a: Option<f64>, d| Some(a.map_or(d, |x| x.max(d))));
    let any_bound = elements.iter().any(|e| e.at_bound);
    let (status, mut message) = verdict(fin.converged, any_bound, visible, fits_data);
    let note = visibility_note(&space.elems, &order, visible, opts.change, visible_depth);
    message.push_str(&note);
    message.push_str(&noise_note(fits_data, fit_p_value));
    Ok(ProfileReport {
        mode: opts.mode,
        observe_kind: match obs {
            Observations::Series(series) => Some(series.measurement().sensor().kind),
            _ => None,
        },
        elements,
        params,
        covariance,
        visible_depth,
        change: opts.change,
        noise_sigma: sigma * scale,
        noise_estimated: estimated,
        chi2: chi2_out,
        m: fin.m,
        p,
        lambda: path.lambda,
        stages: path.stages,
        fits_data,
        fit_p_value,
        status,
        message,
        misfit: fin.misfit,
        iterations,
        seconds: t0.elapsed().as_secs_f64(),
        chain: space.chain(&fin.theta)?,
    })
}

/// The options, one sensor, and the memory of the dense `n x n` blocks
/// (issue 32 item 7: refused before allocating).
///
/// # Errors
/// Invalid options; several sensors (field `observe`); a chain above the
/// memory budget.
fn check_input(obs: &Observations, model: &Model, opts: &ProfileOptions) -> Result<()> {
    opts.validate()?;
    if let Observations::Series(s) = obs {
        if !s.others().is_empty() {
            return Err(crate::error::Error::invalid(
                "observe",
                format!("{} sensors", s.sensors().count()),
                "one sensor for the whole-profile fit",
            ));
        }
    }
    crate::io::check_fit_memory(model.chain().n(), true)
}

/// The final fit's goodness of fit: the noise scale (an estimated level
/// is read from this fit's residual: `1` when given), whether the answer
/// explains the data, and the p-value behind that. With a given level the
/// chi-square is tested (`p > 0.01`); the time residual of a record
/// whose final fit is the time-domain chi-square (`polished`) is also
/// tested for whiteness (Ljung-Box, as the defect fit's,
/// [`FITS_DATA_P`]), the only test with an estimated level: the level
/// takes up any misfit, while the residual of a wrong chain (a damping the
/// model lacks, a defect of another kind) stays coloured. (A profile left
/// on the Bromwich line, with values the data do not see, is not so
/// tested: its chain is not the time residual's best.) The p-value is
/// the failed test's, else the chi-square's (given level) or the
/// whiteness test's.
///
/// # Errors
/// The forward model's, at the final chain.
fn goodness(
    polished: Option<&Series>,
    (sigma, estimated): (f64, bool),
    space: &Space,
    fin: &FinalFit,
    fit_dof: f64,
) -> Result<(f64, bool, f64)> {
    let scale = if estimated {
        (fin.chi2 / fit_dof).sqrt()
    } else {
        1.0
    };
    let chi2_p = chi2_sf(fin.chi2 / (scale * scale), fit_dof);
    let (white_p, exact) = match polished {
        Some(s) => {
            let tm = TimeMisfit::new(s.time_data(sigma * scale)?);
            let r = tm.residuals(&space.chain(&fin.theta)?)?;
            // an exact record's residual (in the data's units) is its
            // rounding, which no whiteness test can judge (as the defect fit's)
            let level = sigma * scale;
            let rss = r.iter().map(|v| (v * level).powi(2)).sum::<f64>();
            (whiteness_p(&r), exact_record(rss, r.len(), s.max_abs()))
        }
        None => (f64::NAN, false),
    };
    let white = white_p.is_nan() || white_p >= FITS_DATA_P || exact;
    let chi2_ok = estimated || chi2_p > 0.01;
    let p = match (chi2_ok, white) {
        (_, false) => white_p,
        (false, true) => chi2_p,
        (true, true) if estimated && !white_p.is_nan() => white_p,
        (true, true) => chi2_p,
    };
    Ok((scale, chi2_ok && white, p))
}

/// The space of the profile: the chain's uniform part, the defects held
/// fixed, the profile's elements and the fitted chain parameters.
fn profile_space(obs: &Observations, model: &Model, opts: &ProfileOptions) -> Result<Space> {
    let observe = match obs {
        Observations::Series(s) => s.measurement().sensor().at,
        Observations::Laplace(l) => l.sensor().at,
    };
    model.chain().check_observe(observe)?;
    let (elems, fixed) = elements(model, opts.mode, observe)?;
    Ok(Space {
        // the uniform part: the profile's values replace the uniform one
        base: model.chain().uniform(),
        fixed,
        elems,
        params: model.fitted().to_vec(),
    })
}

/// The noise level the fit starts from, and whether it is estimated (from
/// the record's high frequencies, or 1 for Laplace values without their
/// own sigma) rather than given.
fn start_sigma(obs: &Observations, opts: &ProfileOptions) -> (f64, bool) {
    let given_sigma = match (obs, opts.noise) {
        (_, NoiseSpec::Sigma(s)) => Some(s),
        (Observations::Laplace(l), NoiseSpec::Auto) if l.sigma().is_some() => Some(1.0),
        _ => None,
    };
    let sigma = match (obs, given_sigma) {
        (_, Some(s)) => s,
        (Observations::Series(s), None) => super::first_guess(s),
        (Observations::Laplace(_), None) => 1.0,
    };
    (sigma, given_sigma.is_none())
}

/// The final fit of a profile and what it reports.
struct FinalFit {
    /// Every value, then the chain parameters.
    theta: Vec<f64>,
    /// Their standard errors (NaN where the covariance fails).
    ses: Vec<f64>,
    /// Their covariance (`None` when it fails).
    cov: Option<DMatrix<f64>>,
    /// The data chi-square.
    chi2: f64,
    converged: bool,
    at_bound: Vec<usize>,
    /// Degrees of freedom of the data.
    m: usize,
    /// What the chi-square compares.
    misfit: String,
    iterations: usize,
}

/// The final fit: every value free from `start`; a Gaussian prior of width
/// `change` around the uniform value on the values the data cannot see
/// (they move only where the data ask, and their uncertainty enters the
/// visible values' standard errors); the visible ones and the chain
/// parameters unpenalised.
fn final_fit(
    space: &Space,
    l: &LaplaceObs,
    start: &[f64],
    visible_set: &[bool],
    bounds: &[(f64, f64)],
    opts: &ProfileOptions,
    misfit: String,
) -> Result<FinalFit> {
    let all_visible = visible_set.iter().all(|v| *v);
    let final_prob = Problem {
        lambda: if all_visible { 0.0 } else { 1.0 },
        penalised: Some(visible_set.iter().map(|v| !v).collect()),
        prior_width: Some(opts.change),
        ..space.problem(l)
    };
    let lm_opts = LmOptions {
        max_iter: opts.max_iter,
        ..LmOptions::default()
    };
    let f = levenberg_marquardt(&final_prob, start, bounds, &lm_opts)?;
    let cov = covariance(&f.jacobian).ok();
    let ses: Vec<f64> = match &cov {
        Some(c) => c.diagonal().iter().map(|v| v.max(0.0).sqrt()).collect(),
        None => vec![f64::NAN; f.theta.len()],
    };
    Ok(FinalFit {
        cov,
        chi2: final_prob.data_chi2(&f.theta)?,
        theta: f.theta,
        ses,
        converged: f.converged,
        at_bound: f.at_bound,
        m: l.dof(),
        misfit,
        iterations: f.iterations,
    })
}

/// The visible values and the chain parameters of `fin` polished by the
/// time-domain chi-square of the record (noise `sigma`), the others held.
fn time_polish(
    series: &Series,
    sigma: f64,
    space: &Space,
    visible_set: &[bool],
    bounds: &[(f64, f64)],
    fin: &mut FinalFit,
) -> Result<()> {
    let (nf, np) = (space.elems.len(), space.params.len());
    let tm = TimeMisfit::new(series.time_data(sigma)?);
    let start = space.chain(&fin.theta)?;
    let k0 = space.fixed.len();
    let vis_idx: Vec<usize> = (0..nf).filter(|&i| visible_set[i]).collect();
    let p = vis_idx.len() + np;
    let pvis: Vec<Param> = vis_idx
        .iter()
        .map(|&i| Param::Defect(k0 + i))
        .chain(space.params.iter().copied())
        .collect();
    let b: Vec<(f64, f64)> = vis_idx
        .iter()
        .map(|&i| bounds[i])
        .chain(bounds[nf..].iter().copied())
        .collect();
    let r = fit_chain(&start, &pvis, &tm, Some(&b))?;
    fin.iterations += r.lm.iterations;
    for (k, &i) in vis_idx.iter().enumerate() {
        fin.theta[i] = r.values[k];
        fin.ses[i] = r.std_errors[k];
    }
    for j in 0..np {
        fin.theta[nf + j] = r.values[vis_idx.len() + j];
        fin.ses[nf + j] = r.std_errors[vis_idx.len() + j];
    }
    // the polished block replaces the visible values' covariance
    let idx: Vec<usize> = vis_idx.iter().copied().chain(nf..nf + np).collect();
    fin.cov = match (fin.cov.take(), r.lm.covariance()) {
        (Some(mut c), Ok(block)) => {
            for (a, &i) in idx.iter().enumerate() {
                for (b, &j) in idx.iter().enumerate() {
                    c[(i, j)] = block[(a, b)];
                }
            }
            Some(c)
        }
        _ => None,
    };
    fin.at_bound =
        r.lm.at_bound
            .iter()
            .filter_map(|&k| vis_idx.get(k).copied())
            .collect();
    fin.converged = r.lm.converged;
    fin.chi2 = r.chi2();
    fin.m = r.m();
    fin.misfit = format!(
        "time (chi-square of {} samples) for the {p} visible values, from the profile of the {}",
        fin.m, fin.misfit
    );
    Ok(())
}

/// The estimates of the elements and of the chain parameters, standard
/// errors scaled by `scale` (the hidden elements' NaN).
fn estimates(
    space: &Space,
    fin: &FinalFit,
    visible_set: &[bool],
    scale: f64,
) -> (Vec<ElementEstimate>, Vec<(String, f64, f64)>) {
    let nf = space.elems.len();
    let (theta, ses) = (&fin.theta, &fin.ses);
    let mut out = Vec::with_capacity(nf);
    for (i, e) in space.elems.iter().enumerate() {
        let vis = visible_set[i];
        out.push(ElementEstimate {
            kind: e.name(),
            at: e.at,
            value: theta[i],
            se: if vis { ses[i] * scale } else { f64::NAN },
            uniform: e.uniform,
            visible: vis,
            at_bound: vis && fin.at_bound.contains(&i),
            depth: e.depth,
        });
    }
    let params = space
        .params
        .iter()
        .enumerate()
        .map(|(i, pm)| {
            (
                crate::detect::fit::general::param_name(pm).to_string(),
                theta[nf + i],
                ses.get(nf + i).copied().unwrap_or(f64::NAN) * scale,
            )
        })
        .collect();
    (out, params)
}

/// The covariance of the element values of `fin`, scaled by `scale^2`
/// (the rows and columns of hidden values NaN; all NaN without one).
fn element_covariance(fin: &FinalFit, visible_set: &[bool], scale: f64) -> Vec<Vec<f64>> {
    let nf = visible_set.len();
    (0..nf)
        .map(|i| {
            (0..nf)
                .map(|j| match &fin.cov {
                    Some(c) if visible_set[i] && visible_set[j] => c[(i, j)] * scale * scale,
                    _ => f64::NAN,
                })
                .collect()
        })
        .collect()
}

/// The pre-pass observation of a series: the same transformed data
/// weighted as if the samples were nearly exact (noise `1e-4` of the level:
/// the transform's own error estimate dominates the covariance, which
/// weighs every node about by its relative accuracy). Its continuation
/// answer starts the chi-square fit when the uniform start lands in a wrong
/// basin (measured on a six-storey frame's roof displacement at 1% noise).
/// `None` for Laplace values.
fn pre_pass(
    obs: &Observations,
    model: &Model,
    sigma: f64,
    free: usize,
) -> Result<Option<LaplaceObs>> {
    match obs {
        Observations::Series(_) => Ok(Some(laplace(obs, model, sigma * 1e-4, free)?.0)),
        Observations::Laplace(l) => {
            let w = l
                .values()
                .iter()
                .map(|v| 1.0 / v.norm_sqr().max(f64::MIN_POSITIVE))
                .collect();
            Ok(Some(
                LaplaceObs::new(l.s().to_vec(), l.values().to_vec(), w)?
                    .with_measurement(l.sensor(), None)?,
            ))
        }
    }
}

fn check_counts(l: &LaplaceObs, p: usize) -> Result<()> {
    if l.dof() <= p {
        return Err(Error::invalid(
            "profile",
            format!("{} free values for {} data", p, l.dof()),
            "more data (real residuals) than free values: more nodes or a longer record",
        ));
    }
    Ok(())
}

fn bounds_of(space: &Space, bound: f64) -> Vec<(f64, f64)> {
    space
        .elems
        .iter()
        .map(|e| (e.uniform / bound, e.uniform * bound))
        .chain(crate::detect::fit::chainfit::default_bounds(
            &space.base,
            &space.params,
        ))
        .collect()
}

/// Most free values (visible ones and chain parameters) polished in the
/// time domain (its Jacobian may be by differences: one modal sum per value).
pub const TIME_POLISH_MAX: usize = 40;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::fit::report::Status;

    /// The profile without the restart from a defect fit.
    fn fit_profile(o: &Observations, m: &Model, p: &ProfileOptions) -> Result<ProfileReport> {
        fit_profile_with(o, m, p, None)
    }
    use crate::chain::Boundary;
    use crate::detect::data::observations::LaplaceValues;
    use num_complex::Complex64;

    fn exact(truth: &Chain, q: usize, sigma_b: f64, w: f64) -> Observations {
        let s: Vec<Complex64> = (0..q)
            .map(|i| Complex64::new(sigma_b, w * (i as f64 + 0.5) / q as f64))
            .collect();
        let x = s
            .iter()
            .map(|z| crate::forward::response(truth, *z, 1))
            .collect::<Result<Vec<_>>>()
            .unwrap();
        Observations::Laplace(LaplaceValues::new(s, x, None).unwrap())
    }

    #[test]
    fn modes_parse_and_refuse() {
        assert_eq!(ProfileMode::parse("both").unwrap(), ProfileMode::Both);
        let e = ProfileMode::parse("all").unwrap_err().to_string();
        assert!(e.contains("profile"), "{e}");
    }

    #[test]
    fn bad_options_are_named() {
        let obs = exact(&Chain::paper(3).unwrap(), 20, 0.1, 3.0);
        let model = Model::new(3).unwrap();
        for (opts, field) in [
            (
                ProfileOptions {
                    change: 0.0,
                    ..ProfileOptions::new(ProfileMode::Masses)
                },
                "profile.change",
            ),
            (
                ProfileOptions {
                    lambda: Some(-1.0),
                    ..ProfileOptions::new(ProfileMode::Masses)
                },
                "profile.lambda",
            ),
            (
                ProfileOptions {
                    eps: 0.0,
                    ..ProfileOptions::new(ProfileMode::Masses)
                },
                "profile.eps",
            ),
        ] {
            let e = fit_profile(&obs, &model, &opts).unwrap_err().to_string();
            assert!(e.contains(field), "{e}");
        }
        // nothing free: one mass with both ends free has no spring
        let m1 = Model::new(1)
            .unwrap()
            .with_ends(Boundary::Free, Boundary::Free)
            .unwrap();
        let one = Chain::paper(1)
            .unwrap()
            .with_boundaries(Boundary::Free, Boundary::Fixed)
            .unwrap();
        let e = fit_profile(
            &exact(&one, 10, 0.1, 3.0),
            &m1,
            &ProfileOptions::new(ProfileMode::Springs),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("profile"), "{e}");
        // more free values than data
        let e = fit_profile(
            &exact(&Chain::paper(30).unwrap(), 5, 0.1, 3.0),
            &Model::new(30).unwrap(),
            &ProfileOptions::new(ProfileMode::Masses),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("more data"), "{e}");
    }

    #[test]
    fn springs_of_a_short_chain_exactly() {
        let truth = Chain::paper(5)
            .unwrap()
            .with_defects((0..=5).map(|j| Defect::Spring {
                at: j,
                k: 1.0 + 0.07 * j as f64 - 0.1 * (j % 2) as f64,
            }))
            .unwrap();
        let obs = exact(&truth, 60, 0.05, 3.0);
        let opts = ProfileOptions {
            noise: NoiseSpec::Sigma(1e-12),
            ..ProfileOptions::new(ProfileMode::Springs)
        };
        let p = fit_profile(&obs, &Model::new(5).unwrap(), &opts).unwrap();
        assert_eq!(p.elements.len(), 6);
        for e in &p.elements {
            let k = 1.0 + 0.07 * e.at as f64 - 0.1 * (e.at % 2) as f64;
            assert!((e.value - k).abs() < 1e-7, "{e:?}");
            assert!(e.visible);
        }
        assert_eq!(p.status, Status::Converged, "{}", p.summary());
    }
}
