//! The scene path: `fit(scene, data, options)` finds the defects that best
//! explain a [`FitScene`]'s data, through the same pipeline as the
//! data-first [`crate::detect::fit::fit`], then judges the answer against the
//! data's error floor and reports it in the scene's terms ([`SceneReport`]).
//!
//! The scene becomes the data-first fit's three inputs:
//!
//! * **observations**: the scene's data (exact-model, simulated and
//!   Laplace-transformed, or a measured series) as [`LaplaceValues`] at the
//!   nodes of the scene's `[misfit]` rule (real axis, or the Bromwich line
//!   `s = sigma + i omega`), each with the "error" `1 / sqrt(w_q)` of its
//!   quadrature weight: the fit's chi-square `sum_q w_q |X_1(s_q) - d_q|^2`
//!   is then the paper's residual (4.18) (its Bromwich-line analogue), and
//!   the mass-only Woodbury kernel ranks the position sets on it
//!   ([`crate::detect::misfit::Misfit::at_nodes`]);
//! * **model**: the uniform part of the scene's chain ([`Model::from_chain`]);
//! * **options**: its `[search]` ([`FitOptions`]: method, seed, max_evals,
//!   the number of hypotheses kept, parallelism, max_sets), the known noise
//!   scale 1 (the weights are the errors), and its `[unknowns]` as they are
//!   (known positions with free masses, per-defect bounds) with the
//!   enumeration's starts and beam and the trace flag, which a [`Model`] and
//!   [`FitOptions`] do not describe.
//!
//! The search is the data-first fit's: `enumerate` ranks every position set
//! with the Woodbury kernel, retries the best `keep` sets' kernel fits from
//! the general fit's starts, and refits the answer and the runner-up by
//! bounded Levenberg-Marquardt on the shared chi-square from the kernel's
//! values (a few evaluations each; the other runners-up are the kernel's
//! fits); `ga`, `nelder-mead` and `pso` run
//! [`crate::detect::search::minimize`] on the same residual
//! ([`MisfitObjective`]; they need interchangeable unknown-position
//! defects: the optimizers' spaces are unordered), and the best set and its
//! neighbours (each position moved by one or two) are refitted; their per-iteration
//! trace is the report's `trace` when `[search] trace = true`.
//!
//! After the fit, the scene layer compares: the data's error floor is
//! `sum_q w_q sigma_q^2` with `sigma_q` the data's own error at each node
//! (rounding for exact data, the noise or the transform's error otherwise);
//! `resolved` when the gap to the first runner-up is above it; `fits_data`
//! when the residual is within `4 floor` (a residual far above it means the
//! model lacks a defect or the search missed the truth).
//!
//! **General path.** When the scene asks for what the mass-only kernel does
//! not cover (spring, damper or `any` defects, chain parameters `d`,
//! `gamma`, `k`, `mass`, `[misfit] kind = "time"`, another sensor, free
//! ends: [`FitScene::is_general`]), the observations are the sampled record
//! behind `data` (simulated or read from a file) or `data`'s values at the
//! rule's nodes weighted by their own errors, and the residual is the
//! chi-square of the data-first fit: `floor` is then the chi-square gap
//! threshold [`crate::detect::fit::identify::DEFAULT_THRESHOLD`], and the
//! report carries the standard errors of the defect values and the fitted
//! chain parameters.
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

use super::engine::Given;
use super::judge::{evidence_of, judge, Bar, Evidence};
use super::{fit_with, Alternative, DefectCount, FitOptions, Model, NoiseSpec, Status};
use crate::chain::Defect;
use crate::detect::data::exact::Data;
use crate::detect::data::observations::{LaplaceValues, Observations};
use crate::detect::fit::general::FittedParam;
use crate::detect::misfit::MisfitKind;
use crate::detect::scene::{DataSourceKind, FitScene, SceneOptions};
use crate::detect::search::{registry, FitMethod};
use crate::error::{Error, Result};
use num_complex::Complex64;
use serde::Serialize;
use std::time::Instant;

/// The paper's residual as an optimizer objective (defined with the
/// optimizers, [`crate::detect::search::MisfitObjective`]; named here too
/// for the callers of the scene path).
pub use crate::detect::search::MisfitObjective;

/// What [`fit`] found, in the scene's terms: the shared [`FitReport`](super::FitReport)'s
/// answer, judged against the scene data's error floor.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SceneReport {
    /// The method used.
    pub method: String,
    /// The defects found (mass defects; any kind on the general path).
    pub defects: Vec<Defect>,
    /// The residual at the defects found (the paper's (4.18) on the mass
    /// path; the chi-square on the general path).
    pub residual: f64,
    /// Approximate standard errors of the defects' values (mass path): the
    /// fit's Gauss-Newton errors scaled by `sqrt(floor / terms)`, the data's
    /// mean error per residual term (exact when every term's weighted error
    /// `w_q sigma_q^2` is the same). The general path's are `std_errors`.
    pub error_bars: Vec<f64>,
    /// The next best hypotheses, best first (the data path's
    /// [`Alternative`]; each also under its JSON name `residual`, the
    /// scene's name of its chi-square).
    #[serde(serialize_with = "runners_up_json")]
    pub runners_up: Vec<Alternative>,
    /// Residual evaluations of the search and the refits.
    pub evaluations: usize,
    /// Position sets ranked (enumeration) or refitted (stochastic methods).
    pub sets: Option<usize>,
    /// Whether the enumeration was exhaustive (false: beam search).
    pub exhaustive: Option<bool>,
    /// Wall time of the fit, seconds (the Woodbury tables included).
    pub wall_time_s: f64,
    /// Wall time of the setup (the rule, the data at its nodes), seconds.
    pub setup_time_s: f64,
    /// `(evaluations, best residual)` per iteration when traced.
    pub trace: Vec<(usize, f64)>,
    /// The residual: kind and rule.
    pub misfit: String,
    /// Quadrature nodes (general path: the chi-square's degrees of freedom).
    pub nodes: usize,
    /// The data's error floor on `r`.
    pub floor: f64,
    /// How the fit ended ([`crate::detect::fit::judge`], against the floor
    /// on the mass path; the data-first fit's on the general path).
    pub status: Status,
    /// One line on the status.
    pub message: String,
    /// Gap to the first runner-up above the floor (the answer is resolved by
    /// the data); the general path: the data-first fit's `resolved`.
    pub resolved: bool,
    /// The residual is within the data's error (`r <= 4 floor`): the
    /// hypothesis explains the data. False means a defect is missing from the
    /// model, or the search (beam search, stochastic methods) missed the truth.
    /// General path: the data-first fit's goodness of fit.
    pub fits_data: bool,
    /// The answer is the beam search's, kept without ranking every set
    /// because its residual is at the data's error floor, which no set can
    /// beat by more than the data's error (mass path, from three defects on
    /// chains of 40 masses or more, unless `search.exhaustive`; see the
    /// message). False: the search's own answer (an exhaustive enumeration
    /// says so in `exhaustive`).
    pub certified: bool,
    /// General path: Gauss-Newton standard errors of the defect values, in the
    /// order of `defects` (0 for a known value); empty on the mass path.
    pub std_errors: Vec<f64>,
    /// General path: the fitted chain parameters with their standard errors.
    pub chain_params: Vec<FittedParam>,
    /// General path: the identifiability report (chi-square gaps of the
    /// alternatives, the noise level at which the runner-up becomes
    /// indistinguishable, per-defect significance and flags); see
    /// [`crate::detect::fit::identify`].
    pub identifiability: Option<crate::detect::fit::identify::Identifiability>,
}

impl SceneReport {
    /// The report as text: status and message, the defects with their
    /// standard errors, the residual and the runners-up.
    pub fn summary(&self) -> String {
        use std::fmt::Write;
        let mut out = format!("status: {} - {}\n", self.status.name(), self.message);
        if self.defects.is_empty() {
            out.push_str("no defect\n");
        }
        for (i, d) in self.defects.iter().enumerate() {
            let se = self
                .std_errors
                .get(i)
                .or(self.error_bars.get(i))
                .map_or("-".into(), |s| format!("{s:.4e}"));
            let _ = writeln!(out, "{} at {}: {:.6} +- {se}", d.kind(), d.at(), d.value());
        }
        let _ = writeln!(
            out,
            "residual {:.6e} ({}, {} terms)",
            self.residual, self.misfit, self.nodes
        );
        for alt in &self.runners_up {
            let set: Vec<String> = alt
                .defects
                .iter()
                .map(|d| format!("{} {}", d.kind(), d.at()))
                .collect();
            let _ = writeln!(
                out,
                "runner-up: {} (worse by {:.4e})",
                set.join(", "),
                alt.gap
            );
        }
        out
    }
}

/// Fit the scene's unknowns to `data` (a record or Laplace values; a
/// `modes` scene is fitted by [`crate::detect::fit::fit_scene`]).
///
/// # Errors
/// Invalid chain, unknowns or misfit in the scene (typed, naming the field);
/// a stochastic method for unknowns that are not interchangeable, or on the
/// general path (`search.method`).
pub fn fit(scene: &FitScene, data: &Data, options: &SceneOptions) -> Result<SceneReport> {
    if scene.data.source == DataSourceKind::Modes {
        return Err(Error::invalid(
            "data.source",
            "modes",
            "a record source here (a modes scene is fitted by detect::fit::fit_scene)",
        ));
    }
    if scene.is_general() || options.method == FitMethod::Greedy {
        // the greedy search runs on the general hypothesis fits
        return fit_general_scene(scene, data, options);
    }
    fit_mass_scene(scene, data, options)
}

/// The mass path of [`fit`]: the paper's residual on the rule's nodes with
/// the mass-only kernel, judged against the data's floor.
fn fit_mass_scene(scene: &FitScene, data: &Data, options: &SceneOptions) -> Result<SceneReport> {
    let t0 = Instant::now();
    scene
        .truth()?
        .require_grounded("the scene path's locator model (fit a simulated record with --data)")?;
    scene
        .truth()?
        .require_uniform("the scene path's locator model (fit a simulated record with --data)")?;
    let model = Model::from_chain(&scene.truth()?.uniform());
    let unknowns = scene.unknowns()?;
    let mass = unknowns.to_mass()?;
    let rule = scene.misfit.rule()?;
    if options.method.is_stochastic() && !mass.interchangeable() {
        return Err(Error::invalid(
            "search.method",
            options.method.name(),
            format!(
                "{} when the defects at unknown positions differ (known, unequal masses or unequal bounds)",
                registry::names(|s| !s.stochastic(), "or")
            ),
        ));
    }
    let (obs, floor) = residual_observations(scene, data, &rule)?;
    let opts = mass_options(scene, unknowns.k(), options);
    let given = Given {
        unknowns,
        enumerate: options.enumerate.clone(),
        trace: options.trace,
    };
    let setup = t0.elapsed().as_secs_f64();
    let certify = !options.exhaustive && floor > 0.0;
    let (r, certified) = search_mass_scene(
        &obs,
        &model,
        &opts,
        given,
        certify.then_some(floor),
        scene.chain.n,
    )?;
    // the scene's judgment: gaps and residual against the data's floor
    let residual = r.chi2;
    let fits_data = residual <= FLOOR_FACTOR * floor;
    let evidence = Evidence {
        fits_data,
        ..evidence_of(&r, options.max_evals)
    };
    let verdict = judge(&evidence, Bar::Floor(floor));
    let terms = if scene.misfit.kind == MisfitKind::Bromwich {
        2 * rule.len()
    } else {
        rule.len()
    };
    let scale = (floor / terms.max(1) as f64).sqrt();
    let (method, message) = certified_lines(&r.method, verdict.message, certified, residual, floor);
    Ok(SceneReport {
        method,
        defects: r.defects.iter().map(|d| d.defect()).collect(),
        residual,
        error_bars: r.defects.iter().map(|d| d.se * scale).collect(),
        runners_up: r.alternatives.clone(),
        evaluations: r.evaluations,
        sets: Some(r.sets_fitted),
        exhaustive: Some(r.exhaustive),
        wall_time_s: r.wall_time_s,
        setup_time_s: setup,
        trace: r.trace.clone().unwrap_or_default(),
        misfit: format!("{}, {}", misfit_kind(scene), rule.name),
        nodes: rule.len(),
        floor,
        status: verdict.status,
        message,
        resolved: verdict.resolved,
        fits_data,
        certified: certified.is_some(),
        std_errors: Vec::new(),
        chain_params: Vec::new(),
        identifiability: None,
    })
}

/// The scene's data at the rule's nodes as Laplace observations whose
/// chi-square is the paper's residual (the quadrature weights as inverse
/// variances), and the data's error floor on that residual.
///
/// # Errors
/// As [`at_nodes`] and [`LaplaceValues::new`].
fn residual_observations(
    scene: &FitScene,
    data: &Data,
    rule: &crate::detect::misfit::quadrature::Rule,
) -> Result<(Observations, f64)> {
    let (s, values, errors) = at_nodes(scene, data, &rule.nodes)?;
    let pseudo: Vec<f64> = rule.weights.iter().map(|w| 1.0 / w.sqrt()).collect();
    let floor: f64 = rule
        .weights
        .iter()
        .zip(&errors)
        .map(|(w, e)| w * e * e)
        .sum();
    let obs = Observations::Laplace(LaplaceValues::new(s, values, Some(pseudo))?);
    Ok((obs, floor))
}

/// The mass path's method and message, saying so when the answer was
/// certified against the bar `certified` ([`search_mass_scene`]).
fn certified_lines(
    method: &str,
    message: String,
    certified: Option<f64>,
    residual: f64,
    floor: f64,
) -> (String, String) {
    match certified {
        Some(bar) => (
            format!("{method}, beam search certified"),
            format!(
                "{message}; certified without ranking every set: the residual {residual:.3e} is at most {bar:.3e}, {FLOOR_FACTOR} times the data's error floor {floor:.3e}, and no position set's residual is below 0, so no set fits better by more than the data's error (--exhaustive ranks them all)"
            ),
        ),
        None => (method.to_string(), message),
    }
}

/// The mass path's residual explains the data when it is at most this
/// many times the data's error floor (`fits_data`).
const FLOOR_FACTOR: f64 = 4.0;

/// The scene's default enumeration first tries the beam search from
/// this many defects ...
const CERTIFY_FROM_K: usize = 3;
/// ... on chains of at least this many masses (issue 30: `C(60, 3) = 34 220`
/// sets take seconds; the beam search a tenth of one).
const CERTIFY_FROM_N: usize = 40;
/// The beam's first try keeps this many partial sets (and does not refine);
/// the second keeps the scene's `search.beam` and refines; the third also
/// starts every mass from [`BEAM_RETRY_STARTS`] values (a set's mass fit
/// can end in a local minimum: deep defects of unequal masses). On 22
/// random exact scenes (n = 45 and 60, three masses) the three tries
/// certified 20 (the guide's "certified, not exhaustive").
const NARROW_BEAM: usize = 8;
/// Starting masses per unknown mass of the beam's third try.
const BEAM_RETRY_STARTS: usize = 4;

/// The mass path's search: the options' enumeration, except that from
/// [`CERTIFY_FROM_K`] defects on chains of [`CERTIFY_FROM_N`] masses or more
/// the beam search ([`crate::detect::search::enumerate`]: the defects placed
/// one at a time, the best partial sets kept; tried three times, wider
/// each time: [`NARROW_BEAM`]) runs first, and its answer
/// is kept when it is *certified*: its residual is within [`FLOOR_FACTOR`]
/// times the data's error floor. The residual is a sum of squares, so no
/// position set does better than 0 and none can beat that answer by more
/// than the data's own error (enumerating every set could at most find
/// another that fits as well within that error).
/// Otherwise (the beam missed the truth, or no set explains the data)
/// every set is enumerated as before; always so with `floor` `None`
/// (`search.exhaustive`). Returns the fit and, when the beam's answer is
/// kept, the bar it met.
///
/// # Errors
/// As [`fit_with`].
fn search_mass_scene(
    obs: &Observations,
    model: &Model,
    opts: &FitOptions,
    given: Given,
    floor: Option<f64>,
    n: usize,
) -> Result<(crate::detect::fit::FitReport, Option<f64>)> {
    let k = given.unknowns.k();
    let Some(floor) = floor else {
        return fit_with(obs, model, opts, Some(given)).map(|r| (r, None));
    };
    if opts.method == FitMethod::Enumerate && k >= CERTIFY_FROM_K && n >= CERTIFY_FROM_N {
        let bar = FLOOR_FACTOR * floor;
        let beamed = FitOptions {
            max_sets: 1,
            ..opts.clone()
        };
        let e = &given.enumerate;
        for (beam, sweeps, starts) in [
            (e.beam.min(NARROW_BEAM), 0, e.starts),
            (e.beam, e.refine_sweeps, e.starts),
            (e.beam, e.refine_sweeps, e.starts.max(BEAM_RETRY_STARTS)),
        ] {
            let mut quick = given.clone();
            quick.enumerate.stop_below = Some(bar);
            quick.enumerate.beam = beam;
            quick.enumerate.refine_sweeps = sweeps;
            quick.enumerate.starts = starts;
            // a beam that fails is no answer: the enumeration decides
            if let Ok(b) = fit_with(obs, model, &beamed, Some(quick)) {
                if b.chi2 <= bar {
                    return Ok((b, Some(bar)));
                }
            }
        }
    }
    fit_with(obs, model, opts, Some(given)).map(|r| (r, None))
}

/// The general path's model: the uniform part of `start` with the wholly
/// known defects in it and the unknowns' chain parameters fitted, and the
/// kinds of the free slots.
///
/// # Errors
/// A slot known in only one of position and value (field
/// `unknowns.defects`); as [`Model::with_known`] and [`Model::fitting`].
fn general_model(
    start: &crate::chain::Chain,
    unknowns: &crate::detect::unknowns::Unknowns,
) -> Result<(Model, Vec<crate::detect::unknowns::KindChoice>)> {
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
    Ok((model.fitting(unknowns.chain())?, kinds))
}

/// The data-first fit's options on the mass path: `k` defects, the
/// residual's unit weights, the scene's misfit and search.
fn mass_options(scene: &FitScene, k: usize, options: &SceneOptions) -> FitOptions {
    FitOptions {
        defects: DefectCount::Exactly(k),
        kinds: crate::detect::unknowns::KindChoice::Mass,
        noise: NoiseSpec::Sigma(1.0),
        misfit: Some(scene.misfit.kind),
        method: options.method,
        seed: options.seed,
        max_evals: options.max_evals,
        alternatives: options.enumerate.keep.saturating_sub(1),
        parallel: options.enumerate.parallel,
        max_sets: options.enumerate.max_sets,
        ..FitOptions::default()
    }
}

/// The scene's data at the rule's nodes: the Laplace variables, the values
/// and the data's own errors (sampled in real arithmetic on the real axis,
/// as the paper's residual always was).
#[allow(clippy::type_complexity)]
fn at_nodes(
    scene: &FitScene,
    data: &Data,
    nodes: &[f64],
) -> Result<(Vec<Complex64>, Vec<Complex64>, Vec<f64>)> {
    Ok(match scene.misfit.kind {
        MisfitKind::Bromwich => {
            let s = scene.laplace_nodes(nodes);
            let sm = data.sample(&s)?;
            (s, sm.values, sm.sigma)
        }
        _ => {
            let sm = data.sample(nodes)?;
            (
                scene.laplace_nodes(nodes),
                sm.values.iter().map(|&v| Complex64::new(v, 0.0)).collect(),
                sm.sigma,
            )
        }
    })
}

/// The residual's kind with its range, for the report.
fn misfit_kind(scene: &FitScene) -> String {
    match scene.misfit.kind {
        MisfitKind::RealAxis => format!("real-axis [0, {}]", scene.misfit.s_max),
        MisfitKind::Bromwich => format!(
            "bromwich sigma={} omega in [0, {}]",
            scene.misfit.sigma, scene.misfit.omega_max
        ),
        other => other.name().into(),
    }
}

/// The scene JSON's runners-up: each alternative's fields, and its
/// chi-square under the scene's name `residual` too.
fn runners_up_json<S: serde::Serializer>(
    alts: &[Alternative],
    s: S,
) -> std::result::Result<S::Ok, S::Error> {
    use serde::ser::SerializeSeq;
    #[derive(Serialize)]
    struct Entry<'a> {
        #[serde(flatten)]
        alt: &'a Alternative,
        residual: f64,
    }
    let mut seq = s.serialize_seq(Some(alts.len()))?;
    for alt in alts {
        seq.serialize_element(&Entry {
            alt,
            residual: alt.chi2,
        })?;
    }
    seq.end()
}

/// The general path of [`fit`]: defects of any kind and chain parameters,
/// fitted by the data-first pipeline ([`crate::detect::fit::fit`]) on the
/// data it is given: the sampled record behind `data` (simulated or read
/// from a file), or `data`'s values at the nodes of the scene's rule
/// (exact-model data, weighted by their errors). The residual is then a
/// chi-square and `floor` the gap threshold
/// [`crate::detect::fit::identify::DEFAULT_THRESHOLD`].
fn fit_general_scene(scene: &FitScene, data: &Data, options: &SceneOptions) -> Result<SceneReport> {
    let t0 = Instant::now();
    if !options.method.search().general_scene {
        return Err(Error::invalid(
            "search.method",
            options.method.name(),
            format!(
                "{} for defects of other kinds, chain parameters or the time misfit",
                registry::names(|s| s.general_scene, "or")
            ),
        ));
    }
    let unknowns = scene.unknowns()?;
    let start = scene.unknowns.start_chain(&scene.truth()?)?;
    start
        .require_grounded("the scene path's locator model (fit a simulated record with --data)")?;
    scene
        .truth()?
        .require_uniform("the scene path's locator model (fit a simulated record with --data)")?;
    let (model, kinds) = general_model(&start, &unknowns)?;
    // the data given, as the pipeline's observations (the samples' known
    // noise, or the Laplace values' own errors; else estimated)
    let (obs, sigma) = scene.observations_of(data)?;
    let noise = sigma.map_or(NoiseSpec::Auto, NoiseSpec::Sigma);
    // several sensors or records are one joint time-domain fit: the
    // default real-axis residual means the time misfit there
    let misfit = match scene.misfit.kind {
        MisfitKind::RealAxis if scene.data.is_joint() => MisfitKind::Time,
        kind => kind,
    };
    let opts = FitOptions {
        defects: DefectCount::Exactly(kinds.len()),
        slot_kinds: kinds,
        noise,
        misfit: Some(misfit),
        method: options.method,
        alternatives: options.enumerate.keep.saturating_sub(1).max(1),
        parallel: options.enumerate.parallel,
        max_sets: options.enumerate.max_sets,
        ..FitOptions::default()
    };
    let setup_time = t0.elapsed().as_secs_f64();
    let r = crate::detect::fit::fit(&obs, &model, &opts)?;
    let floor = crate::detect::fit::identify::DEFAULT_THRESHOLD;
    Ok(SceneReport {
        method: format!("{} (general noisy fit)", options.method.name()),
        defects: r.defects.iter().map(|d| d.defect()).collect(),
        residual: r.chi2,
        error_bars: r.defects.iter().map(|d| d.se).collect(),
        status: r.status,
        message: r.message.clone(),
        resolved: r.resolved,
        runners_up: r.alternatives.clone(),
        evaluations: r.evaluations,
        sets: Some(r.sets_fitted),
        exhaustive: Some(r.exhaustive),
        wall_time_s: r.wall_time_s,
        setup_time_s: setup_time,
        trace: Vec::new(),
        misfit: r.misfit.clone(),
        nodes: r.dof,
        floor,
        fits_data: r.fits_data,
        certified: false,
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
