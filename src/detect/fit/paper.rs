//! `fit(scene, data, options)`: find the defects that best explain the data.
//!
//! Builds the residual of the scene's `[misfit]` (fixed rule, tabled Green's
//! function, data sampled at the same nodes), the unknowns of `[unknowns]`,
//! and runs the chosen method:
//!
//! * `enumerate` (default): every position set, masses fitted per set by
//!   Levenberg-Marquardt ([`crate::detect::search::enumerate`]); the runners-up
//!   are the next position sets in the ranking.
//! * `ga`, `nelder-mead`, `pso`: [`crate::detect::search::minimize`] on
//!   [`MisfitObjective`] (the residual; invalid candidates get a finite
//!   penalty). The defects and residual reported are the optimizer's own best.
//!   The runners-up are probes around it: each unknown position moved by
//!   +-1 and +-2 (to free places), masses refitted by the enumeration's LM;
//!   a negative gap means the optimizer stopped short of a better neighbour.
//!   These methods need interchangeable unknown-position defects (the
//!   optimizers' spaces are unordered).
//!
//! **General path.** When the scene asks for what the mass-only Woodbury
//! path cannot do (spring, damper or `any` defects, chain parameters `d`,
//! `gamma`, `k`, `mass`, or `[misfit] kind = "time"`,
//! [`FitScene::is_general`]), `fit` runs the general noisy fit
//! ([`crate::detect::fit::general::fit_general`]; method `enumerate` only): the
//! residual is then a chi-square (Laplace data weighted by the rule over the
//! data's variance at each node, or the time-domain chi-square of the scene's
//! series), `floor` is the chi-square gap threshold
//! [`crate::detect::fit::identify::DEFAULT_THRESHOLD`], and the report carries
//! the standard errors of the defect values and the fitted chain parameters.
//!
//! The report gives the defects found, the residual, the runners-up with
//! their gaps `r_alt - r_best`, the number of residual evaluations, the wall
//! time, and whether the gap to the first runner-up is above the data's
//! error floor ([`crate::detect::misfit::Misfit::floor`]); below it the data
//! cannot tell the two hypotheses apart. `fits_data` says whether the best
//! residual itself is within the floor (a residual far above it means the
//! model lacks a defect or the search missed the truth).
//!
//! ```
//! use springmass::{Chain, Defect};
//! use springmass::detect::{fit::paper::fit, scene::FitScene};
//! let truth = Chain::paper(10)?.with_defects([
//!     Defect::Mass { at: 3, m: 3.0 }, Defect::Mass { at: 7, m: 2.0 }])?;
//! let scene = FitScene::synthetic(&truth);
//! let report = fit(&scene, &scene.data()?, &scene.options())?;
//! assert_eq!(report.defects, vec![Defect::Mass { at: 3, m: report.defects[0].value() },
//!                                 Defect::Mass { at: 7, m: report.defects[1].value() }]);
//! assert!((report.defects[1].value() - 2.0).abs() < 1e-8);
//! assert!(report.resolved);
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::chain::Defect;
use crate::detect::data::exact::Data;
use crate::detect::data::laplace::LaplaceObs;
use crate::detect::fit::general::{
    fit_general, identify_general, laplace_obs, FittedParam, GeneralOptions, Setup,
};
use crate::detect::misfit::time::TimeMisfit;
use crate::detect::misfit::{Misfit, MisfitKind};
use crate::detect::scene::{DataSourceKind, FitScene};
use crate::detect::search::enumerate::{enumerate, fit_slots, Defects, EnumerateOptions};
use crate::detect::search::{minimize, Candidate, Method, Objective, SearchOptions, Space};
use crate::detect::unknowns::{MassUnknown, Unknowns};
use crate::error::{Error, Result};
use num_complex::Complex64;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// Fitting methods.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FitMethod {
    /// Exhaustive enumeration of position sets with a mass fit per set.
    #[default]
    Enumerate,
    /// Genetic algorithm.
    #[serde(alias = "genetic")]
    Ga,
    /// Nelder-Mead.
    NelderMead,
    /// Particle swarm.
    #[serde(alias = "particle-swarm")]
    Pso,
}

impl FitMethod {
    /// Parse `enumerate`, `ga`, `nelder-mead`, `pso` (aliases `genetic`,
    /// `particle-swarm`, `nm`).
    ///
    /// # Errors
    /// [`Error::Parse`] naming the allowed names.
    pub fn parse(text: &str) -> Result<FitMethod> {
        match text.trim().to_ascii_lowercase().as_str() {
            "enumerate" | "enum" => Ok(FitMethod::Enumerate),
            "ga" | "genetic" => Ok(FitMethod::Ga),
            "nelder-mead" | "nm" => Ok(FitMethod::NelderMead),
            "pso" | "particle-swarm" => Ok(FitMethod::Pso),
            _ => Err(Error::parse(
                "method",
                text,
                "expected enumerate, ga, nelder-mead or pso",
            )),
        }
    }

    /// The canonical name.
    pub fn name(self) -> &'static str {
        match self {
            FitMethod::Enumerate => "enumerate",
            FitMethod::Ga => "ga",
            FitMethod::NelderMead => "nelder-mead",
            FitMethod::Pso => "pso",
        }
    }
}

/// Options of [`fit`] (from a scene's `[search]` with [`FitScene::options`]).
#[derive(Clone, Debug, PartialEq)]
pub struct FitOptions {
    /// The method.
    pub method: FitMethod,
    /// Seed of stochastic methods.
    pub seed: u64,
    /// Evaluation budget of stochastic methods.
    pub max_evals: usize,
    /// Record the optimizer's trace.
    pub trace: bool,
    /// Enumeration options (`keep` also sets the number of hypotheses reported).
    pub enumerate: EnumerateOptions,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitScene::synthetic(&crate::Chain::new(1).expect("n = 1 is valid")).options()
    }
}

/// An alternative hypothesis.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Alternative {
    /// Its defects (masses fitted).
    pub defects: Vec<Defect>,
    /// Its residual.
    pub residual: f64,
    /// `residual - best residual`.
    pub gap: f64,
}

/// What [`fit`] found.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FitReport {
    /// The method used.
    pub method: String,
    /// The defects found (mass defects; any kind on the general path).
    pub defects: Vec<Defect>,
    /// The residual at the defects found.
    pub residual: f64,
    /// The next best hypotheses, best first.
    pub runners_up: Vec<Alternative>,
    /// Residual evaluations of the method.
    pub evaluations: usize,
    /// Residual evaluations spent probing runners-up (stochastic methods).
    pub probe_evaluations: usize,
    /// Position sets fitted (enumeration).
    pub sets: Option<usize>,
    /// Whether the enumeration was exhaustive (false: beam search).
    pub exhaustive: Option<bool>,
    /// Wall time of the search, seconds (the residual's setup excluded).
    pub wall_time_s: f64,
    /// Wall time of the setup (rule, Green's tables, data), seconds.
    pub setup_time_s: f64,
    /// `(evaluations, best residual)` per iteration when traced.
    pub trace: Vec<(usize, f64)>,
    /// The residual: kind and rule.
    pub misfit: String,
    /// Quadrature nodes.
    pub nodes: usize,
    /// The data's error floor on `r`.
    pub floor: f64,
    /// Gap to the first runner-up above the floor (the answer is resolved by the data).
    pub resolved: bool,
    /// The residual is within the data's error (`r <= 4 floor`): the
    /// hypothesis explains the data. False means a defect is missing from the
    /// model, or the search (beam search, stochastic methods) missed the truth.
    /// General path: `chi^2 <= m + 4 sqrt(2 m)` with `m` residuals.
    pub fits_data: bool,
    /// General path: Gauss-Newton standard errors of the defect values, in the
    /// order of `defects` (0 for a known value); empty on the mass-only path.
    pub std_errors: Vec<f64>,
    /// General path: the fitted chain parameters with their standard errors.
    pub chain_params: Vec<FittedParam>,
    /// General path: the identifiability report (chi-square gaps of the
    /// alternatives, the noise level at which the runner-up becomes
    /// indistinguishable, per-defect significance and flags); see
    /// [`crate::detect::fit::identify`].
    pub identifiability: Option<crate::detect::fit::identify::Identifiability>,
}

/// Fit the scene's unknowns to `data`.
///
/// # Errors
/// Invalid chain, unknowns or misfit in the scene (typed, naming the field);
/// a method this build does not provide (`search.method`).
pub fn fit(scene: &FitScene, data: &Data, options: &FitOptions) -> Result<FitReport> {
    if scene.is_general() {
        return fit_general_scene(scene, data, options);
    }
    let t0 = Instant::now();
    let model = scene.truth()?.uniform();
    let unknowns = scene.unknowns()?;
    let misfit = Misfit::new(&model, data, &scene.misfit)?;
    let setup = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    let to_defects = |d: &[(usize, f64)]| -> Vec<Defect> {
        d.iter().map(|&(at, m)| Defect::Mass { at, m }).collect()
    };
    let mut probe_evals = 0;
    let (defects, residual, runners, evaluations, sets, exhaustive, trace) = match options.method {
        FitMethod::Enumerate => {
            let e = enumerate(&misfit, &unknowns, &options.enumerate)?;
            let best = e.ranked.first().ok_or_else(|| Error::Numerical {
                method: "enumerate".into(),
                reason: "no hypothesis".into(),
            })?;
            let runners: Vec<Alternative> = e.ranked[1..]
                .iter()
                .map(|h| Alternative {
                    defects: to_defects(&h.defects),
                    residual: h.residual,
                    gap: h.residual - best.residual,
                })
                .collect();
            (
                to_defects(&best.defects),
                best.residual,
                runners,
                e.evaluations,
                Some(e.sets),
                Some(e.exhaustive),
                Vec::new(),
            )
        }
        m => {
            let method = match m {
                FitMethod::Ga => Method::Genetic,
                FitMethod::NelderMead => Method::NelderMead,
                _ => Method::ParticleSwarm,
            };
            if !unknowns.interchangeable() {
                return Err(Error::invalid(
                    "search.method",
                    m.name(),
                    "enumerate when the defects at unknown positions differ (known, unequal masses or unequal bounds)",
                ));
            }
            let obj = MisfitObjective::new(&misfit, &unknowns);
            let opts = SearchOptions {
                max_evals: options.max_evals,
                seed: options.seed,
                trace: options.trace,
                ..SearchOptions::default()
            };
            let res = minimize(method, &obj, &opts)?;
            let best = unknowns.decode(&res.best).map_err(|_| Error::Numerical {
                method: m.name().into(),
                reason: "the best candidate is outside the space".into(),
            })?;
            let (runners, probes) =
                probe_neighbours(&misfit, &unknowns, &res.best.positions, &options.enumerate);
            probe_evals = probes;
            let mut best = best;
            if unknowns.interchangeable() && unknowns.free_positions().len() == unknowns.k() {
                best.sort_by_key(|d| d.0);
            }
            (
                to_defects(&best),
                res.cost,
                runners
                    .into_iter()
                    .map(|(d, r)| Alternative {
                        defects: to_defects(&d),
                        residual: r,
                        gap: r - res.cost,
                    })
                    .collect(),
                res.evaluations,
                None,
                None,
                res.trace,
            )
        }
    };
    let wall = t1.elapsed().as_secs_f64();
    let floor = misfit.floor();
    let resolved = runners.first().is_none_or(|r| r.gap > floor);
    let fits_data = residual <= 4.0 * floor;
    let kind = match scene.misfit.kind {
        MisfitKind::RealAxis => format!("real-axis [0, {}]", scene.misfit.s_max),
        MisfitKind::Bromwich => format!(
            "bromwich sigma={} omega in [0, {}]",
            scene.misfit.sigma, scene.misfit.omega_max
        ),
        MisfitKind::Time => "time".into(),
    };
    Ok(FitReport {
        method: options.method.name().into(),
        defects,
        residual,
        runners_up: runners,
        evaluations,
        probe_evaluations: probe_evals,
        sets,
        exhaustive,
        wall_time_s: wall,
        setup_time_s: setup,
        trace,
        misfit: format!("{kind}, {}", misfit.rule().name),
        nodes: misfit.nodes(),
        floor,
        resolved,
        fits_data,
        std_errors: Vec::new(),
        chain_params: Vec::new(),
        identifiability: None,
    })
}

/// The general path of [`fit`]: defects of any kind and chain parameters
/// ([`crate::detect::fit::general::fit_general`]); the residual is a chi-square,
/// `floor` the gap threshold [`crate::detect::fit::identify::DEFAULT_THRESHOLD`].
fn fit_general_scene(scene: &FitScene, data: &Data, options: &FitOptions) -> Result<FitReport> {
    let t0 = Instant::now();
    if options.method != FitMethod::Enumerate {
        return Err(Error::invalid(
            "search.method",
            options.method.name(),
            "enumerate for defects of other kinds, chain parameters or the time misfit",
        ));
    }
    let unknowns = scene.general_unknowns()?;
    let base = scene.unknowns.start_chain(&scene.truth()?)?;
    let mut setup = Setup::new()?;
    let (coarse, fine, misfit_name, nodes) = match scene.misfit.kind {
        MisfitKind::Time => {
            let td = scene.time_data()?;
            let coarse = laplace_obs(&td, MisfitKind::Bromwich, &setup)?;
            let name = format!(
                "time-domain chi-square ({} samples, sigma = {:.3e}; shortlist from the Bromwich line sigma = {})",
                td.len(),
                td.sigma(),
                setup.bromwich_sigma
            );
            let n = td.len();
            (coarse, Some(TimeMisfit::new(td)), name, n)
        }
        kind if scene.data.source != DataSourceKind::Exact => {
            // a sampled series: its transform at the scene's nodes, whitened by
            // the transform's noise covariance (a true chi-square)
            let rule = scene.misfit.rule()?;
            let choice = if kind == MisfitKind::RealAxis {
                setup.real_rule = rule.clone();
                MisfitKind::RealAxis
            } else {
                setup.bromwich_rule = rule.clone();
                setup.bromwich_sigma = scene.misfit.sigma;
                MisfitKind::Bromwich
            };
            let td = scene.time_data()?;
            let obs = laplace_obs(&td, choice, &setup)?;
            let name = format!(
                "{} chi-square of the transformed series, {:?} ({} dof of {} nodes), {}",
                choice.name(),
                setup.weighting,
                obs.dof(),
                rule.nodes.len(),
                rule.name
            );
            let n = obs.dof();
            (obs, None, name, n)
        }
        kind => {
            // exact-model data with independent per-node noise: weights 1/sigma_q^2
            let rule = scene.misfit.rule()?;
            let (s, values, sigma): (Vec<Complex64>, Vec<Complex64>, Vec<f64>) =
                if kind == MisfitKind::RealAxis {
                    let sm = data.sample(&rule.nodes)?;
                    (
                        rule.nodes.iter().map(|&x| Complex64::new(x, 0.0)).collect(),
                        sm.values.iter().map(|&x| Complex64::new(x, 0.0)).collect(),
                        sm.sigma,
                    )
                } else {
                    let s: Vec<Complex64> = rule
                        .nodes
                        .iter()
                        .map(|&w| Complex64::new(scene.misfit.sigma, w))
                        .collect();
                    let sm = data.sample(&s)?;
                    (s, sm.values, sm.sigma)
                };
            let weights = sigma.iter().map(|sg| 1.0 / (sg * sg).max(1e-300)).collect();
            let n = s.len();
            let name = format!(
                "{} chi-square on the rule's nodes (independent node noise, weights 1 / sigma_q^2), {}",
                if kind == MisfitKind::RealAxis {
                    "real-axis"
                } else {
                    "bromwich"
                },
                rule.name
            );
            (LaplaceObs::new(s, values, weights)?, None, name, n)
        }
    };
    let noise_level = match scene.data.source {
        DataSourceKind::Exact => data.noise(),
        _ => scene.noise_sigma()?,
    };
    setup.shortlist = setup.shortlist.max(options.enumerate.keep);
    let gopts = GeneralOptions {
        parallel: options.enumerate.parallel,
        max_sets: options.enumerate.max_sets,
        ..GeneralOptions::default()
    };
    let setup_time = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    let g = fit_general(&base, &unknowns, &coarse, fine.as_ref(), &setup, &gopts)?;
    let best = g.ranked.first().ok_or_else(|| Error::Numerical {
        method: "fit_general".into(),
        reason: "no hypothesis".into(),
    })?;
    let runners: Vec<Alternative> = g.ranked[1..]
        .iter()
        .take(options.enumerate.keep.saturating_sub(1))
        .map(|h| Alternative {
            defects: h.defects.clone(),
            residual: h.chi2,
            gap: h.chi2 - best.chi2,
        })
        .collect();
    let floor = crate::detect::fit::identify::DEFAULT_THRESHOLD;
    let m = g.residuals as f64;
    let identifiability = identify_general(&g.ranked, &base, noise_level, None).ok();
    Ok(FitReport {
        method: "enumerate (general noisy fit)".into(),
        defects: best.defects.clone(),
        residual: best.chi2,
        resolved: runners.first().is_none_or(|r| r.gap > floor),
        runners_up: runners,
        evaluations: g.evaluations,
        probe_evaluations: 0,
        sets: Some(g.hypotheses),
        exhaustive: Some(true),
        wall_time_s: t1.elapsed().as_secs_f64(),
        setup_time_s: setup_time,
        trace: Vec::new(),
        misfit: misfit_name,
        nodes,
        floor,
        fits_data: best.chi2 <= m + 4.0 * (2.0 * m).sqrt(),
        std_errors: best.std_errors.clone(),
        chain_params: best.chain.clone(),
        identifiability,
    })
}

/// The residual as an optimizer [`Objective`]: the candidate is decoded by
/// [`Unknowns::decode`] (invalid candidates get its finite penalty, at least
/// [`crate::detect::unknowns::PENALTY`]) and costed by [`Misfit::residual`].
pub struct MisfitObjective<'a> {
    misfit: &'a Misfit,
    unknowns: &'a Unknowns,
}

impl<'a> MisfitObjective<'a> {
    /// Wrap a residual and its unknowns (same `n`).
    pub fn new(misfit: &'a Misfit, unknowns: &'a Unknowns) -> MisfitObjective<'a> {
        MisfitObjective { misfit, unknowns }
    }
}

impl Objective for MisfitObjective<'_> {
    fn space(&self) -> &Space {
        self.unknowns.space()
    }
    fn cost(&self, c: &Candidate) -> f64 {
        match self.unknowns.decode(c) {
            Ok(d) => {
                let r = self.misfit.residual(&d);
                if r.is_nan() {
                    f64::MAX
                } else {
                    r
                }
            }
            Err(p) => p,
        }
    }
}

/// Hypotheses next to `positions` (each unknown position moved by +-1, +-2
/// to a free place; masses refitted), best first, at most `opts.keep - 1`;
/// and the evaluations spent.
fn probe_neighbours(
    misfit: &Misfit,
    unknowns: &Unknowns,
    positions: &[usize],
    opts: &EnumerateOptions,
) -> (Vec<(Defects, f64)>, usize) {
    let allowed = unknowns.allowed_positions();
    let mut seen: Vec<Vec<usize>> = vec![sorted(positions)];
    let mut out = Vec::new();
    let mut evals = 0;
    for t in 0..positions.len() {
        for delta in [-2i64, -1, 1, 2] {
            let p = positions[t] as i64 + delta;
            if p < 1 || !allowed.contains(&(p as usize)) || positions.contains(&(p as usize)) {
                continue;
            }
            let mut cand = positions.to_vec();
            cand[t] = p as usize;
            if seen.contains(&sorted(&cand)) {
                continue;
            }
            seen.push(sorted(&cand));
            let mut pi = cand.iter();
            let slots: Vec<(usize, MassUnknown)> = unknowns
                .defects()
                .iter()
                .map(|d| {
                    (
                        d.at.unwrap_or_else(|| *pi.next().expect("one per position")),
                        d.mass,
                    )
                })
                .collect();
            let (mut d, r, e) = fit_slots(misfit, &slots, opts);
            evals += e;
            if unknowns.interchangeable() && unknowns.free_positions().len() == unknowns.k() {
                d.sort_by_key(|x| x.0);
            }
            out.push((d, r));
        }
    }
    out.sort_by(|a, b| a.1.total_cmp(&b.1));
    out.truncate(opts.keep.saturating_sub(1));
    (out, evals)
}

fn sorted(v: &[usize]) -> Vec<usize> {
    let mut s = v.to_vec();
    s.sort_unstable();
    s
}
