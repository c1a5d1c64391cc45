//! Kind `fit`: defect detection by fitting ([`crate::detect::fit::paper::fit`], the
//! data-first fit's pipeline on the scene's data) on a
//! [`FitScene`]: synthetic data of the scene's true chain (exact, or
//! simulated and Laplace-transformed, with optional noise), the unknowns, the
//! residual (quadrature rule and nodes) and the search (method, budget).
//!
//! The case's seed becomes the data's noise seed and the search's seed
//! unless the scene sets `data.seed` / `search.seed` itself. Metrics: whether
//! the positions found equal the true ones, the position and mass errors,
//! the residual and its gap to the best other hypothesis against the data's
//! error floor, and the evaluations; timings: setup and search.
//!
//! ```
//! use springmass::study::kinds::Kind;
//! let scene: toml::Value = toml::from_str(r#"
//!     chain = { n = 5, defects = [ { kind = "mass", at = 2, m = 3.0 }, { kind = "mass", at = 4, m = 0.5 } ] }
//! "#).unwrap();
//! let out = Kind::Fit.run(&scene, 0)?;
//! assert_eq!(out.metrics["success"], true);
//! # Ok::<(), springmass::Error>(())
//! ```

use super::case::{chain_problems, num, CaseOutput, KindScene};
use crate::chain::Defect;
use crate::detect::fit::fit_scene;
use crate::detect::fit::paper::SceneReport;

use crate::detect::scene::{DataSourceKind, FitScene};
use crate::error::{check_f64, Error, Result};
use crate::study::paths::set_path;
use crate::study::schema::FieldDoc;
use crate::study::seeds::splitmix64;

/// One paragraph for the schema page.
pub const SUMMARY: &str = "Fits the unknown defects of a chain to synthetic data of its true defects (detect::fit with a FitScene) and records whether the positions were recovered, the errors, the residual gap against the data's floor, and the cost.";

/// Every scene field of kind `fit` (the [`FitScene`] schema).
pub const FIELDS: &[FieldDoc] = &[
    FieldDoc::new("chain", "table", "required", "The chain; its defects are the truth used for synthetic data (the model is its uniform part)."),
    FieldDoc::new("chain.n", "integer >= 1", "required", "Number of masses."),
    FieldDoc::new("chain.k", "float > 0", "1", "Uniform spring constant."),
    FieldDoc::new("chain.d", "float >= 0", "0.1", "Uniform damping."),
    FieldDoc::new("chain.gamma", "float", "1", "Impulse on mass 1."),
    FieldDoc::new("chain.mass", "float > 0", "1", "Uniform mass."),
    FieldDoc::new("chain.left", "\"fixed\" | \"free\"", "\"fixed\"", "Mass 1's end: a wall spring or free (a shear frame's roof); free ends are fitted by the general path."),
    FieldDoc::new("chain.right", "\"fixed\" | \"free\"", "\"fixed\"", "Mass n's end."),
    FieldDoc::new("chain.defects", "array of tables", "[]", "The true defects, e.g. `{ kind = \"mass\", at = 8, m = 5.0 }`."),
    FieldDoc::new("chain.defects[].kind", "\"mass\" | \"spring\" | \"damper\"", "required", "What differs (the fit looks for mass defects)."),
    FieldDoc::new("chain.defects[].at", "integer", "required", "Position."),
    FieldDoc::new("chain.defects[].m", "float > 0", "required for mass", "The mass."),
    FieldDoc::new("chain.defects[].k", "float > 0", "required for spring", "The stiffness."),
    FieldDoc::new("chain.defects[].d", "float >= 0", "required for damper", "The damping."),
    FieldDoc::new("data", "table", "{}", "The data."),
    FieldDoc::new("data.source", "\"exact\" | \"simulated\" | \"series\" | \"modes\"", "\"exact\"", "Closed-form model of the chain; a simulation Laplace-transformed (the paper's pipeline); a measured CSV series; or measured modes (a modes CSV, or the chain's lowest undamped modes with noise), fitted by the modal defect search."),
    FieldDoc::new("data.path", "string or array of strings", "none", "CSV series (source `series`; a list: several records of the same chain, fitted jointly); the modes CSV (source `modes`)."),
    FieldDoc::new("data.column", "string or array of strings", "\"x1\" (several sensors: \"x{mass}\")", "Column of the CSV series; a list: one per `observe` mass."),
    FieldDoc::new("data.noise", "float >= 0", "0", "`exact`: relative Laplace-domain noise; `simulated`: absolute noise on the samples; `series`: the samples' known noise."),
    FieldDoc::new("data.seed", "integer", "the case's seed", "Noise seed (in a study: derived from the case unless given)."),
    FieldDoc::new("data.relative", "bool", "false", "`simulated`/`series`: `noise` is relative to the largest |x_1|."),
    FieldDoc::new("data.t_end", "float", "300", "`simulated`: end of the record."),
    FieldDoc::new("data.dt", "float", "0.05", "`simulated`: sampling step."),
    FieldDoc::new("data.observe", "integer in 1..=n, or an array of them", "1", "`simulated`/`series`: the observed mass; a list: several sensors of one test, one joint fit (each sensor with its own noise stream and level)."),
    FieldDoc::new("data.observe_kind", "string or array of strings", "\"displacement\"", "`simulated`/`series`: \"displacement\", \"velocity\" or \"acceleration\"; a list: one per `observe` mass."),
    FieldDoc::new("data.records", "integer in 1..=1000", "1", "`simulated`: records of the same chain (hammer hits, each with its own noise stream), one joint fit; not with several sensors."),
    FieldDoc::new("data.modes", "integer in 1..=n", "3", "`modes` (simulated): the number of lowest undamped modes measured."),
    FieldDoc::new("data.floors", "array of integers in 1..=n", "every mass", "`modes` (simulated): the masses whose mode-shape components are measured."),
    FieldDoc::new("data.frequency_noise", "float >= 0", "0", "`modes` (simulated): relative noise of the frequencies (and their stated standard error)."),
    FieldDoc::new("data.shape_noise", "float >= 0", "0", "`modes` (simulated): noise of the shape components, relative to the mode's largest measured component (and their stated standard error)."),
    FieldDoc::new("data.modal_residual", "\"property\" | \"dynamic\"", "\"property\"", "`modes`: the measurement model, the modal-property difference or the modal dynamic residual."),
    FieldDoc::new("data.hammer_width", "float > 0", "none", "`simulated`: a half-sine hammer blow of this width (unit impulse times gamma) on mass 1 instead of the ideal impulse; the fit uses its samples."),
    FieldDoc::new("data.force_column", "string", "none", "`series`: the CSV column of the measured force on mass 1 (a hammer test)."),
    FieldDoc::new("unknowns", "table", "{}", "The unknowns."),
    FieldDoc::new("unknowns.k", "integer", "number of true mass defects", "Number of defects sought."),
    FieldDoc::new("unknowns.mass_bounds", "[float, float]", "[0.1, 100]", "Bounds of unknown masses."),
    FieldDoc::new("unknowns.kind", "\"mass\" | \"spring\" | \"damper\" | \"ground\" | \"any\"", "\"mass\"", "Kind of the sought defects; anything but mass (or `chain`, or `misfit.kind = \"time\"`) selects the general noisy fit."),
    FieldDoc::new("unknowns.chain", "array of \"d\" | \"gamma\" | \"k\" | \"mass\"", "[]", "Uniform chain parameters fitted alongside the defects (not all four: they scale out)."),
    FieldDoc::new("unknowns.chain_start", "table", "the [chain] values", "Starting values of fitted chain parameters, e.g. `{ d = 0.2 }`.").opaque(),
    FieldDoc::new("unknowns.spring_bounds", "[float, float]", "[0.01, 100]", "Bounds of unknown springs (lo > 0)."),
    FieldDoc::new("unknowns.damper_bounds", "[float, float]", "[0, 100]", "Bounds of unknown dampers (lo >= 0)."),
    FieldDoc::new("unknowns.defects", "array of tables", "[]", "Per-defect knowledge (known position and/or mass, bounds)."),
    FieldDoc::new("unknowns.defects[].at", "integer", "unknown", "Known position."),
    FieldDoc::new("unknowns.defects[].m", "float", "unknown", "Known mass."),
    FieldDoc::new("unknowns.defects[].bounds", "[float, float]", "mass_bounds", "Bounds of this unknown value (mass, spring or damper bounds by kind)."),
    FieldDoc::new("unknowns.defects[].kind", "\"mass\" | \"spring\" | \"damper\" | \"ground\" | \"any\"", "unknowns.kind", "Kind of this defect."),
    FieldDoc::new("misfit", "table", "{}", "The residual."),
    FieldDoc::new("misfit.kind", "\"real-axis\" | \"bromwich\" | \"time\"", "\"real-axis\"", "L2 residual on [0, s_max] of the real axis, on the line s = sigma + i omega, or the time-domain chi-square on the sampled series (needs simulated or series data; general fit)."),
    FieldDoc::new("misfit.rule", "\"gl-log\" | \"gl-uniform\"", "by kind", "Quadrature rule: Gauss-Legendre on log-graded or uniform panels."),
    FieldDoc::new("misfit.panels", "integer", "10 (real axis), 40 (Bromwich)", "Number of panels."),
    FieldDoc::new("misfit.per_panel", "integer", "8", "Gauss points per panel."),
    FieldDoc::new("misfit.first", "float", "0.05", "End of the first log-graded panel."),
    FieldDoc::new("misfit.s_max", "float", "300", "Upper limit of the real-axis integral."),
    FieldDoc::new("misfit.sigma", "float", "0.1", "Abscissa of the Bromwich line."),
    FieldDoc::new("misfit.omega_max", "float", "4", "Upper limit of omega on the Bromwich line."),
    FieldDoc::new("search", "table", "{}", "The search."),
    FieldDoc::new("search.method", crate::detect::search::registry::METHOD_TYPE, "\"enumerate\"", "A search of the registry (`springmass fit --help`): exhaustive enumeration of position sets, greedy, relax, or a stochastic optimizer."),
    FieldDoc::new("search.seed", "integer", "the case's seed", "Seed of stochastic methods (in a study: derived from the case unless given)."),
    FieldDoc::new("search.max_evals", "integer", "20000", "Evaluation budget of stochastic methods."),
    FieldDoc::new("search.keep", "integer", "5", "Hypotheses reported (best and runners-up)."),
    FieldDoc::new("search.starts", "integer", "2", "Enumeration: starting values per unknown mass."),
    FieldDoc::new("search.max_sets", "integer", "200000", "Enumeration: largest exhaustive set count before the beam search."),
    FieldDoc::new("search.beam", "integer", "16", "Enumeration: beam width."),
    FieldDoc::new("search.exhaustive", "bool", "false", "Enumeration: rank every position set (false: from 3 defects on chains of 40 masses or more the beam search runs first, and its answer is kept when certified: its residual at the data's error floor, which no set can beat)."),
    FieldDoc::new("search.parallel", "bool", "true", "Parallel residual evaluations (on the study's thread pool)."),
    FieldDoc::new("search.trace", "bool", "false", "Record the optimizer's trace."),
    FieldDoc::new("profile.mode", "\"none\" | \"masses\" | \"springs\" | \"both\"", "\"none\"", "`springmass fit --scene`: fit every mass (spring, both) of the chain instead of the defects (the whole-profile inversion). Studies profile through the `noise` kind's `profile` field; a `fit` study refuses it."),
    FieldDoc::new("profile.change", "float", "0.1", "The relative change the profile's visibility is stated for (> 0)."),
    FieldDoc::new("profile.penalty", "float", "(continuation)", "A fixed penalty weight instead of the continuation to the noise level (> 0)."),
];

/// Every metric and timing of kind `fit`.
pub const METRICS: &[(&str, &str)] = &[
    (
        "success",
        "the defects found equal the true ones in kind and position (as sets)",
    ),
    (
        "found",
        "positions found, e.g. 8;15 (other kinds prefixed: spring:4;damper:7)",
    ),
    ("truth", "true positions, e.g. 8;15"),
    (
        "position_error",
        "sum of |found - true| over positions (both sorted)",
    ),
    (
        "mass_max_rel_err",
        "largest relative error of the fitted defect values (masses; springs and dampers too in a general fit), when the positions are right",
    ),
    ("residual", "residual at the answer"),
    (
        "gap",
        "residual of the best other hypothesis minus the answer's",
    ),
    ("floor", "the data's error floor on the residual"),
    (
        "resolved",
        "gap above the floor and the residual within 4 floors: the data decide the answer",
    ),
    (
        "fits_data",
        "the answer's residual is within the data's floor",
    ),
    ("evaluations", "residual evaluations"),
    (
        "value_max_se",
        "general fit: largest |value - truth| / standard error over the defects, when the positions are right",
    ),
    ("fit_d", "general fit: the fitted uniform damping d"),
    ("fit_d_se", "general fit: its standard error"),
    ("fit_gamma", "general fit: the fitted impulse scale gamma"),
    ("fit_gamma_se", "general fit: its standard error"),
    ("fit_k", "general fit: the fitted uniform spring constant k"),
    ("fit_k_se", "general fit: its standard error"),
    ("fit_mass", "general fit: the fitted uniform mass"),
    ("fit_mass_se", "general fit: its standard error"),
    ("nodes", "quadrature nodes of the residual"),
    (
        "t_setup",
        "measured seconds of the setup (rule, tables, data)",
    ),
    ("t_search", "measured seconds of the search"),
];

/// `(label, value)` of every defect, sorted: the label is the position for a
/// mass (`8`) and `kind:position` otherwise (`spring:4`).
fn positions(d: &[Defect]) -> Vec<(String, f64)> {
    let mut v: Vec<(usize, String, f64)> = d
        .iter()
        .map(|d| {
            let label = match d {
                Defect::Mass { at, .. } => at.to_string(),
                other => format!("{}:{}", other.kind(), other.at()),
            };
            (d.at(), label, d.value())
        })
        .collect();
    v.sort_by(|a, b| (a.0, &a.1).cmp(&(b.0, &b.1)));
    v.into_iter().map(|(_, l, x)| (l, x)).collect()
}

fn position_of(label: &str) -> usize {
    label
        .rsplit(':')
        .next()
        .and_then(|p| p.parse().ok())
        .unwrap_or(0)
}

/// The trace reduced to its improvements: `[evaluations, best residual so
/// far]` where the best residual drops, plus the last point (the curve of
/// best residual against evaluations is the same step function).
pub fn best_so_far(trace: &[(usize, f64)]) -> Vec<[f64; 2]> {
    let mut out: Vec<[f64; 2]> = Vec::new();
    let mut best = f64::INFINITY;
    for &(e, r) in trace {
        if r.is_finite() && r < best {
            best = r;
            out.push([e as f64, r]);
        }
    }
    if let (Some(&(e, _)), Some(last)) = (trace.last(), out.last()) {
        if (e as f64) > last[0] {
            out.push([e as f64, best]);
        }
    }
    out
}

/// Put the case seed into `data.seed` and `search.seed` unless given.
pub fn seeded(value: &toml::Value, seed: u64) -> toml::Value {
    let mut v = value.clone();
    let has = |v: &toml::Value, t: &str| v.get(t).and_then(|x| x.get("seed")).is_some();
    if !has(&v, "data") {
        let _ = set_path(
            &mut v,
            "data.seed",
            toml::Value::Integer((seed >> 1) as i64),
        );
    }
    if !has(&v, "search") {
        let s2 = splitmix64(seed);
        let _ = set_path(
            &mut v,
            "search.seed",
            toml::Value::Integer((s2 >> 1) as i64),
        );
    }
    v
}

/// The problems of `[unknowns]` against the chain's n and defects, and of
/// the search method and data source they allow.
fn unknowns_problems(scene: &FitScene, out: &mut Vec<Error>) {
    if scene.data.source == DataSourceKind::Modes {
        let modal = scene
            .unknowns()
            .and_then(|_| crate::detect::fit::modal_scene::modal_kinds(scene))
            .and_then(|_| crate::detect::fit::modal_scene::check_method(scene))
            .and_then(|_| crate::detect::fit::modal_scene::formulation(scene).map(|_| ()));
        if let Err(e) = modal {
            out.push(e);
        }
        return;
    }
    if scene.is_general() {
        if let Err(e) = scene.unknowns() {
            out.push(e);
        }
        if !scene.search.method.search().general_scene {
            out.push(method_problem(
                scene,
                "for the general fit (non-mass kinds, chain parameters or the time misfit)",
            ));
        }
        if scene.misfit.kind == crate::detect::misfit::MisfitKind::Time
            && scene.data.source == crate::detect::scene::DataSourceKind::Exact
        {
            out.push(Error::invalid(
                "data.source",
                "exact",
                "simulated or series for misfit.kind = \"time\"",
            ));
        }
    } else {
        match scene.unknowns().and_then(|u| u.to_mass()) {
            Err(e) => out.push(e),
            Ok(u) => {
                if !scene.search.method.search().general_scene && !u.interchangeable() {
                    out.push(method_problem(
                        scene,
                        "when the defects at unknown positions differ (known, unequal masses or unequal bounds)",
                    ));
                }
            }
        }
    }
}

/// `search.method` refused: the searches the general fit takes are allowed
/// `when`.
fn method_problem(scene: &FitScene, when: &str) -> Error {
    Error::invalid(
        "search.method",
        scene.search.method.name(),
        format!(
            "{} {when}",
            crate::detect::search::registry::names(|s| s.general_scene, "or")
        ),
    )
}

/// The problems of `[data]`.
fn data_problems(d: &crate::detect::scene::DataSpec, out: &mut Vec<Error>) {
    if let Err(e) = check_f64("data.noise", d.noise, d.noise >= 0.0, ">= 0 and finite") {
        out.push(e);
    }
    let t_end = d.t_end.unwrap_or(300.0);
    if let Err(e) = check_f64("data.t_end", t_end, t_end > 0.0, "> 0 and finite") {
        out.push(e);
    }
    if let Some(dt) = d.dt {
        if let Err(e) = check_f64(
            "data.dt",
            dt,
            dt > 0.0 && dt <= t_end.abs() && t_end / dt <= 2e7,
            "0 < dt <= t_end, at most 2e7 steps",
        ) {
            out.push(e);
        }
    }
    if d.source == DataSourceKind::Series && d.path.is_none() {
        out.push(Error::invalid(
            "data.path",
            "(none)",
            "a CSV file for source = \"series\"",
        ));
    }
    if let Err(e) = d
        .sensors()
        .and_then(|_| d.columns())
        .and_then(|_| d.record_count())
    {
        out.push(e);
    }
}

/// The fit scene's checks, sub-table by sub-table, so that
/// `springmass config check` lists every problem of a scene (with
/// [`KindScene::all_problems`]: every unknown field and every type error
/// first), not the first one.
impl KindScene for FitScene {
    const FIELDS: &'static [FieldDoc] = FIELDS;

    /// `[truth]`, the fit scene's other name of `[chain]` (as
    /// `springmass fit --scene` reads it), is `chain`.
    fn canonical(value: &toml::Value) -> toml::Value {
        let mut v = value.clone();
        if let Some(t) = v.as_table_mut() {
            if !t.contains_key("chain") {
                if let Some(truth) = t.remove("truth") {
                    t.insert("chain".into(), truth);
                }
            }
        }
        v
    }

    fn problems(&self) -> Vec<Error> {
        let mut out = chain_problems(&self.chain);
        // the unknowns need only n (and the number of mass defects)
        let chain_ok = crate::chain::Chain::new(self.chain.n).is_ok();
        data_problems(&self.data, &mut out);
        if chain_ok {
            unknowns_problems(self, &mut out);
        }
        // [misfit]
        if self.misfit.kind != crate::detect::misfit::MisfitKind::Time {
            if let Err(e) = self.misfit.rule() {
                out.push(e);
            }
        }
        // [search]
        if self.search.method.is_stochastic() && self.search.max_evals == 0 {
            out.push(Error::invalid(
                "search.max_evals",
                0,
                ">= 1 for a stochastic method",
            ));
        }
        // [profile]
        if let Err(e) = self.profile.check() {
            out.push(e);
        }
        if let Some(mode) = self.profile.mode.as_deref() {
            if mode.trim() != "none" {
                if let Err(e) = crate::detect::fit::profile::ProfileMode::parse(mode) {
                    out.push(Error::invalid(
                        "profile.mode",
                        mode,
                        format!("none, masses, springs or both ({e})"),
                    ));
                }
            }
        }
        out
    }
}

/// Deserialize and check a scene (the first of its problems, see
/// [`KindScene::all_problems`] for all of them).
///
/// # Errors
/// [`crate::Error::InvalidParameter`] naming the field.
pub fn scene(value: &toml::Value) -> Result<FitScene> {
    <FitScene as KindScene>::from_value(value)
}

/// The metrics of the fit's answer `r` against the `truth` (labels and
/// values): success, found, truth, position_error, mass_max_rel_err and
/// (with standard errors) value_max_se.
fn outcome_metrics(
    truth: &[(String, f64)],
    r: &SceneReport,
    m: &mut serde_json::Map<String, serde_json::Value>,
) {
    let found = positions(&r.defects);
    let list = |p: &[(String, f64)]| p.iter().map(|x| x.0.clone()).collect::<Vec<_>>().join(";");
    let same = truth.len() == found.len() && truth.iter().zip(&found).all(|(a, b)| a.0 == b.0);
    let pos_err: usize = if truth.len() == found.len() {
        truth
            .iter()
            .zip(&found)
            .map(|(a, b)| position_of(&a.0).abs_diff(position_of(&b.0)))
            .sum()
    } else {
        usize::MAX
    };
    m.insert("success".into(), same.into());
    m.insert("found".into(), list(&found).into());
    m.insert("truth".into(), list(truth).into());
    m.insert(
        "position_error".into(),
        if pos_err == usize::MAX {
            serde_json::Value::Null
        } else {
            pos_err.into()
        },
    );
    let mrel = if same {
        truth
            .iter()
            .zip(&found)
            .map(|(a, b)| ((b.1 - a.1) / a.1).abs())
            .fold(0.0, f64::max)
    } else {
        f64::NAN
    };
    m.insert("mass_max_rel_err".into(), num(mrel));
    if !r.std_errors.is_empty() {
        let mut by_label: Vec<(String, f64, f64)> = r
            .defects
            .iter()
            .zip(&r.std_errors)
            .map(|(d, &se)| {
                (
                    positions(std::slice::from_ref(d))[0].0.clone(),
                    d.value(),
                    se,
                )
            })
            .collect();
        by_label.sort_by(|a, b| a.0.cmp(&b.0));
        let zmax = if same {
            truth
                .iter()
                .map(|(l, t)| {
                    by_label
                        .iter()
                        .find(|x| &x.0 == l)
                        .map_or(f64::NAN, |x| (x.1 - t).abs() / x.2)
                })
                .fold(0.0, f64::max)
        } else {
            f64::NAN
        };
        m.insert("value_max_se".into(), num(zmax));
    }
}

/// Run one `fit` case.
///
/// # Errors
/// An invalid scene; the fit's own errors.
pub fn run(value: &toml::Value, seed: u64) -> Result<CaseOutput> {
    let s = scene(&seeded(value, seed))?;
    if let Some(mode) = s.profile.requested() {
        return Err(Error::invalid(
            "profile.mode",
            mode,
            "\"none\" in a `fit` study (profile studies use the `noise` kind's `profile` field)",
        ));
    }
    let r = fit_scene(&s)?;
    let truth = positions(s.truth()?.defects());
    let mut out = CaseOutput::default();
    outcome_metrics(&truth, &r, &mut out.metrics);
    let m = &mut out.metrics;
    for p in &r.chain_params {
        m.insert(format!("fit_{}", p.name), num(p.value));
        m.insert(format!("fit_{}_se", p.name), num(p.std_error));
    }
    m.insert("residual".into(), num(r.residual));
    m.insert(
        "gap".into(),
        r.runners_up
            .first()
            .map_or(serde_json::Value::Null, |a| num(a.gap)),
    );
    m.insert("floor".into(), num(r.floor));
    m.insert("resolved".into(), r.resolved.into());
    m.insert("fits_data".into(), r.fits_data.into());
    m.insert("evaluations".into(), r.evaluations.into());
    m.insert("nodes".into(), r.nodes.into());
    out.trace = best_so_far(&r.trace);
    out.timing("t_setup", r.setup_time_s);
    out.timing("t_search", r.wall_time_s);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::study::kinds::Kind;

    #[test]
    fn best_so_far_keeps_improvements_and_the_end() {
        let t = [(10, 5.0), (20, 6.0), (30, 2.0), (40, 2.0), (50, f64::NAN)];
        assert_eq!(best_so_far(&t), vec![[10.0, 5.0], [30.0, 2.0], [50.0, 2.0]]);
        assert!(best_so_far(&[]).is_empty());
    }

    #[test]
    fn every_problem_of_a_scene_is_listed() {
        let v: toml::Value = toml::from_str(
            r#"
            chain = { n = 5, mass = 0.0, defects = [ { kind = "mass", at = 2, m = 3.0 }, { kind = "mass", at = 7, m = -1.0 } ] }
            data = { noise = -1.0, dt = "x" }
            unknowns = { k = 9 }
            misfit = { s_max = 0.0 }
            search = { methd = "ga" }
            "#,
        )
        .unwrap();
        let errs = Kind::Fit.validate_all(&v);
        let fields: Vec<String> = errs
            .iter()
            .map(|e| match e {
                crate::Error::InvalidParameter { field, .. } => field.clone(),
                other => other.to_string(),
            })
            .collect();
        assert_eq!(
            fields,
            vec![
                "search.methd",
                "data.dt",
                "chain.mass",
                "chain.defects[1].at",
                "chain.defects[1].m",
                "data.noise",
                "unknowns.k",
                "misfit.s_max",
            ],
            "{errs:?}"
        );
        // the first problem is what a run reports
        assert!(Kind::Fit.validate(&v).is_err());
    }

    #[test]
    fn traced_runs_record_the_trace() {
        let v: toml::Value = toml::from_str(
            r#"
            chain = { n = 5, defects = [ { kind = "mass", at = 2, m = 3.0 }, { kind = "mass", at = 4, m = 0.5 } ] }
            search = { method = "ga", max_evals = 600, parallel = false, trace = true }
            "#,
        )
        .unwrap();
        let a = Kind::Fit.run(&v, 1).unwrap();
        assert!(a.trace.len() >= 2, "{:?}", a.trace);
        assert!(a
            .trace
            .windows(2)
            .all(|w| w[0][0] < w[1][0] && w[0][1] >= w[1][1]));
        assert_eq!(a.trace, Kind::Fit.run(&v, 1).unwrap().trace);
    }

    #[test]
    fn general_scenes_run_and_are_checked() {
        let v: toml::Value = toml::from_str(
            r#"
            chain = { n = 6, defects = [ { kind = "spring", at = 3, k = 0.5 }, { kind = "damper", at = 5, d = 0.6 } ] }
            unknowns = { defects = [ { kind = "spring" }, { kind = "damper" } ] }
            search = { parallel = false }
            "#,
        )
        .unwrap();
        assert!(FitScene::all_problems(&v).is_empty());
        let out = Kind::Fit.run(&v, 0).unwrap();
        assert_eq!(out.metrics["success"], true, "{:?}", out.metrics);
        assert_eq!(out.metrics["found"], "spring:3;damper:5");
        assert!(out.metrics["mass_max_rel_err"].as_f64().unwrap() < 1e-6);
        // the time misfit needs sampled data; the general fit only enumerates
        let bad: toml::Value = toml::from_str(
            r#"
            chain = { n = 6, defects = [ { kind = "spring", at = 3, k = 0.5 } ] }
            unknowns = { kind = "spring", chain = ["d"] }
            misfit = { kind = "time" }
            search = { method = "ga" }
            "#,
        )
        .unwrap();
        let text: Vec<String> = FitScene::all_problems(&bad)
            .iter()
            .map(|e| e.to_string())
            .collect();
        assert!(text.iter().any(|t| t.contains("data.source")), "{text:?}");
        assert!(text.iter().any(|t| t.contains("search.method")), "{text:?}");
    }
}
