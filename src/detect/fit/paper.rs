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
use crate::detect::fit::general::FittedParam;
use crate::detect::misfit::{Misfit, MisfitKind};
use crate::detect::scene::{FitScene, SceneOptions};
use crate::detect::search::enumerate::{enumerate, fit_slots, Defects, EnumerateOptions};
use crate::detect::search::FitMethod;
use crate::detect::search::{minimize, Candidate, Objective, SearchOptions, Space};
use crate::detect::unknowns::{MassUnknown, MassUnknowns};
use crate::error::{Error, Result};
use num_complex::Complex64;
use serde::Serialize;
use std::time::Instant;

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
pub fn fit(scene: &FitScene, data: &Data, options: &SceneOptions) -> Result<FitReport> {
    if scene.is_general() || options.method == FitMethod::Greedy {
        // the greedy search runs in the data-first pipeline
        return fit_general_scene(scene, data, options);
    }
    let t0 = Instant::now();
    let model = scene.truth()?.uniform();
    let unknowns = scene.unknowns()?.to_mass()?;
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
            let method = m.stochastic().ok_or_else(|| Error::Numerical {
                method: m.name().into(),
                reason: "enumeration is handled above".into(),
            })?;
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
        other => other.name().into(),
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

/// The general path of [`fit`]: defects of any kind and chain parameters,
/// fitted by the data-first pipeline ([`crate::detect::fit::fit`]) on the
/// data it is given: the sampled record behind `data` (simulated or read
/// from a file), or `data`'s values at the nodes of the scene's rule
/// (exact-model data, weighted by their errors). The residual is then a
/// chi-square and `floor` the gap threshold
/// [`crate::detect::fit::identify::DEFAULT_THRESHOLD`].
fn fit_general_scene(scene: &FitScene, data: &Data, options: &SceneOptions) -> Result<FitReport> {
    use crate::detect::data::observations::{LaplaceValues, Observations, Series};
    use crate::detect::fit::{DefectCount, FitOptions, Model, NoiseSpec};
    let t0 = Instant::now();
    if !matches!(options.method, FitMethod::Enumerate | FitMethod::Greedy) {
        return Err(Error::invalid(
            "search.method",
            options.method.name(),
            "enumerate or greedy for defects of other kinds, chain parameters or the time misfit",
        ));
    }
    let unknowns = scene.unknowns()?;
    let start = scene.unknowns.start_chain(&scene.truth()?)?;
    let mut model = Model::from_chain(&start.uniform());
    let mut kinds = Vec::new();
    for slot in unknowns.slots() {
        match (slot.at, slot.known) {
            (Some(at), Some(v)) => {
                let kind = slot.kind.kinds()[0];
                model = model.with_known(kind.defect(at, v))?;
            }
            (None, None) => kinds.push(slot.kind),
            _ => {
                return Err(Error::invalid(
                    "unknowns.defects",
                    "a known position with a free value, or a known value at a free position",
                    "the general fit takes defects that are either wholly known or wholly free",
                ))
            }
        }
    }
    model = model.fitting(unknowns.chain())?;
    let (obs, noise) = match data.samples() {
        Some((t, x)) => {
            let sigma = scene.noise_sigma()?;
            let noise = if sigma > 0.0 {
                NoiseSpec::Sigma(sigma)
            } else {
                NoiseSpec::Auto
            };
            let sg = (sigma > 0.0).then_some(sigma);
            let series =
                Series::new(t.to_vec(), x.to_vec(), sg)?.with_measurement(scene.measurement(t)?)?;
            (Observations::Series(series), noise)
        }
        None => {
            if scene.misfit.kind == MisfitKind::Time {
                return Err(Error::invalid(
                    "data.source",
                    "exact",
                    "\"simulated\" or \"series\" (the time misfit needs a sampled series)",
                ));
            }
            let rule = scene.misfit.rule()?;
            let s: Vec<Complex64> = match scene.misfit.kind {
                MisfitKind::Bromwich => rule
                    .nodes
                    .iter()
                    .map(|&w| Complex64::new(scene.misfit.sigma, w))
                    .collect(),
                _ => rule.nodes.iter().map(|&x| Complex64::new(x, 0.0)).collect(),
            };
            let sm = data.sample(&s)?;
            let sigma = sm.sigma.iter().map(|v| v.max(1e-300)).collect();
            (
                Observations::Laplace(LaplaceValues::new(s, sm.values, Some(sigma))?),
                NoiseSpec::Sigma(1.0),
            )
        }
    };
    let opts = FitOptions {
        defects: DefectCount::Exactly(kinds.len()),
        slot_kinds: kinds,
        noise,
        misfit: Some(scene.misfit.kind),
        method: options.method,
        alternatives: options.enumerate.keep.saturating_sub(1).max(1),
        parallel: options.enumerate.parallel,
        max_sets: options.enumerate.max_sets,
        ..FitOptions::default()
    };
    let setup_time = t0.elapsed().as_secs_f64();
    let r = crate::detect::fit::fit(&obs, &model, &opts)?;
    let floor = crate::detect::fit::identify::DEFAULT_THRESHOLD;
    Ok(FitReport {
        method: format!("{} (general noisy fit)", options.method.name()),
        defects: r.defects.iter().map(|d| d.defect()).collect(),
        residual: r.chi2,
        resolved: r.resolved,
        runners_up: r
            .alternatives
            .iter()
            .map(|a| Alternative {
                defects: a.defects.clone(),
                residual: a.chi2,
                gap: a.gap,
            })
            .collect(),
        evaluations: r.evaluations,
        probe_evaluations: 0,
        sets: Some(r.hypotheses),
        exhaustive: Some(true),
        wall_time_s: r.wall_time_s,
        setup_time_s: setup_time,
        trace: Vec::new(),
        misfit: r.misfit.clone(),
        nodes: r.dof,
        floor,
        fits_data: r.fits_data,
        std_errors: r.defects.iter().map(|d| d.se).collect(),
        chain_params: r
            .params
            .iter()
            .map(|p| FittedParam {
                name: p.name.clone(),
                value: p.value,
                std_error: p.se,
            })
            .collect(),
        identifiability: r.identifiability,
    })
}

/// The residual as an optimizer [`Objective`]: the candidate is decoded by
/// [`MassUnknowns::decode`] (invalid candidates get its finite penalty, at least
/// [`crate::detect::unknowns::PENALTY`]) and costed by [`Misfit::residual`].
pub struct MisfitObjective<'a> {
    misfit: &'a Misfit,
    unknowns: &'a MassUnknowns,
}

impl<'a> MisfitObjective<'a> {
    /// Wrap a residual and its unknowns (same `n`).
    pub fn new(misfit: &'a Misfit, unknowns: &'a MassUnknowns) -> MisfitObjective<'a> {
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
    unknowns: &MassUnknowns,
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
