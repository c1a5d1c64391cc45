//! Which storeys changed, from measured modes: the defect search (positions
//! and values) on modal data.
//!
//! For `k = 0..=k_max`, every set of `k` elements (springs, masses or both)
//! of the nominal chain is fitted to the modes ([`ModalMisfit`]) by bounded
//! Levenberg-Marquardt on their factors (from the nominal values and from a
//! softer and a stiffer start); `k` is chosen by BIC on the chi-square under
//! the stated weights, and the runner-up set is reported with its gap. The
//! search is exhaustive (at most [`MAX_SETS`] sets per `k`), so the answer
//! is the best set, not a heuristic's guess.
//!
//! The chi-square is only as meaningful as the weights: with standard
//! errors in the table it is a goodness-of-fit test (a failed one gives
//! `model-mismatch`); with assumed weights (1% frequency, 5% shape) the
//! report says so.
//!
//! ```
//! use springmass::{Chain, Defect, chain::Boundary, time::modal::undamped_modes};
//! use springmass::detect::data::modes::{MeasuredMode, MeasuredModes, ShapeEntry};
//! use springmass::detect::fit::modal_locate::{locate_from_modes, ModalLocateOptions};
//! let nominal = Chain::new(6)?.with_boundaries(Boundary::Fixed, Boundary::Free)?;
//! let truth = nominal.clone().with_defect(Defect::Spring { at: 2, k: 0.7 })?;
//! let m = undamped_modes(&truth)?;
//! let modes = (0..3).map(|j| MeasuredMode {
//!     frequency: m.omega[j] / std::f64::consts::TAU, frequency_se: None, damping: None, damping_se: None,
//!     shape: [1, 3, 6].iter().map(|&i| ShapeEntry { mass: i, value: m.shapes[(i - 1, j)], se: None }).collect(),
//! }).collect();
//! let r = locate_from_modes(&nominal, MeasuredModes::new(modes)?, &ModalLocateOptions::default())?;
//! assert_eq!((r.k, r.defects[0].at), (1, 2));
//! assert!((r.defects[0].factor - 0.7).abs() < 1e-6);
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::chain::{Chain, Damping, Defect};
use crate::detect::data::modes::MeasuredModes;
use crate::detect::fit::modal_update::{
    assumed_note, elements, on_bound, FactorEstimate, FactorProblem,
};
use crate::detect::fit::modal_update::{modal_model, ModalFormulation};
use crate::detect::fit::profile::ProfileMode;
use crate::detect::fit::report::Status;
use crate::detect::fit::select::chi2_sf;
use crate::detect::misfit::modal::{ModalMisfit, ModalWeights};
use crate::detect::model::MeasurementModel;
use crate::detect::search::lsq::{covariance, levenberg_marquardt, LmFit, LmOptions};
use crate::error::{Error, Result};
use serde::Serialize;

/// Most position sets fitted for one `k`.
pub const MAX_SETS: usize = 20_000;

/// Options of [`locate_from_modes`].
#[derive(Clone, Debug, PartialEq)]
pub struct ModalLocateOptions {
    /// Where defects may be: springs (default), masses or both; `None`
    /// for dampers alone.
    pub kinds: Option<ProfileMode>,
    /// Dampers too (default false): needs measured damping ratios and a
    /// damped nominal chain (grounded or between-storey damping).
    pub dampers: bool,
    /// Smallest number of defects tried (default 0).
    pub k_min: usize,
    /// Largest number of defects tried exhaustively (default 2).
    pub k_max: usize,
    /// `--defects auto`: while the largest number tried wins, try one more
    /// in the best [`NESTED_FROM`] answers at one fewer (default false;
    /// the report's `nested_above` says from where).
    pub extend: bool,
    /// Factors bounded to `[lo, hi]` (default `[0.05, 20]`).
    pub bounds: (f64, f64),
    /// Standard errors assumed where the table gives none.
    pub weights: ModalWeights,
    /// The measurement model: the modal-property difference (default) or
    /// the modal dynamic residual.
    pub formulation: ModalFormulation,
}

impl Default for ModalLocateOptions {
    fn default() -> ModalLocateOptions {
        ModalLocateOptions {
            kinds: Some(ProfileMode::Springs),
            dampers: false,
            k_min: 0,
            k_max: 2,
            extend: false,
            bounds: (0.05, 20.0),
            weights: ModalWeights::default(),
            formulation: ModalFormulation::default(),
        }
    }
}

/// The best set for one `k`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct KRow {
    /// Number of defects.
    pub k: usize,
    /// Its best chi-square.
    pub chi2: f64,
    /// `chi2 + 2 k ln N`.
    pub bic: f64,
    /// The best set's elements, as `spring 3`, `mass 2`.
    pub set: Vec<String>,
}

/// The answer of [`locate_from_modes`].
#[derive(Clone, Debug, Serialize)]
pub struct ModalLocateReport {
    /// `converged`, `model-mismatch` or `not-identifiable`.
    pub status: Status,
    /// Whether the answer stands (fits, and no other set within the margin).
    pub resolved: bool,
    /// One sentence on the status.
    pub message: String,
    /// Number of defects chosen.
    pub k: usize,
    /// The defects: element, nominal and fitted value, factor, SE.
    pub defects: Vec<FactorEstimate>,
    /// Chi-square of the answer.
    pub chi2: f64,
    /// Number of data.
    pub dof: usize,
    /// Upper-tail p-value of the answer's chi-square (with given errors).
    pub p_value: Option<f64>,
    /// Whether the standard errors came from the table.
    pub errors_given: bool,
    /// The standard errors assumed where the table gives none and the
    /// columns that would give them; `None` when it gives every one.
    pub assumed_weights: Option<(String, String)>,
    /// The table's damping ratios: `fitted` (a damped nominal chain),
    /// `not used` (an undamped one), `absent` (not in the table, the
    /// nominal damped: no damper can be searched) or `none` (neither).
    pub damping_ratios: &'static str,
    /// The best set of every `k` tried.
    pub k_selection: Vec<KRow>,
    /// The runner-up set at the chosen `k` and its chi-square gap.
    pub runner_up: Option<(Vec<String>, f64)>,
    /// The runner-up set's fitted defects (the scene report's alternative).
    #[serde(skip)]
    pub runner_up_defects: Vec<Defect>,
    /// Whether dampers were among the elements searched.
    pub dampers_searched: bool,
    /// With `extend`: the number of defects above which the sets were
    /// searched nested in the best ones at one fewer (not exhaustively).
    pub nested_above: Option<usize>,
    /// Position sets fitted.
    pub sets: usize,
    /// The chain with the defects.
    pub chain: Chain,
}

impl ModalLocateReport {
    /// The report as text: status, defects, the evidence for every `k`.
    pub fn summary(&self) -> String {
        use std::fmt::Write;
        let mut out = format!("status: {} - {}\n", self.status.name(), self.message);
        if self.defects.is_empty() {
            out.push_str("no changed element\n");
        }
        for d in &self.defects {
            let se = d.se.map_or("-".to_string(), |s| format!("{s:.4}"));
            let _ = writeln!(
                out,
                "{} at {}: factor {:.4} +- {se} ({:.5e}, nominal {:.5e})",
                d.kind, d.at, d.factor, d.value, d.nominal
            );
        }
        let p = self
            .p_value
            .map_or(String::new(), |p| format!(", p = {p:.3}"));
        let _ = writeln!(out, "chi2 {:.4} on {} data{p}", self.chi2, self.dof);
        if let Some((set, gap)) = &self.runner_up {
            let _ = writeln!(
                out,
                "runner-up: {} (chi2 worse by {gap:.4})",
                set.join(", ")
            );
        }
        out.push_str("number of defects by bic:\n");
        for row in &self.k_selection {
            let mark = if row.k == self.k { "  <- chosen" } else { "" };
            let _ = writeln!(
                out,
                "  k = {}: chi2 {:.4e}, bic {:.4e} [{}]{mark}",
                row.k,
                row.chi2,
                row.bic,
                row.set.join(", ")
            );
        }
        if let Some(k) = self.nested_above {
            let _ = writeln!(
                out,
                "more than {k} defects: each set one element more than the best {NESTED_FROM} at one fewer (nested, not every set)"
            );
        }
        let _ = writeln!(out, "{} position sets fitted", self.sets);
        out
    }
}

/// One fitted set.
#[derive(Clone)]
struct SetFit {
    idx: Vec<usize>,
    fit: LmFit,
}

/// Find the changed elements of `nominal` from measured `modes`.
///
/// # Errors
/// `k_max` above the number of elements, or more than [`MAX_SETS`] sets
/// for one `k` (field `k_max`); the data's errors ([`ModalMisfit::new`]).
pub fn locate_from_modes(
    nominal: &Chain,
    modes: MeasuredModes,
    opts: &ModalLocateOptions,
) -> Result<ModalLocateReport> {
    let property =
        ModalMisfit::new(modes.clone(), nominal.n(), opts.weights)?.with_damping_of(nominal);
    let errors_given = property.errors_given();
    let damping_ratios = damping_ratios(&property, nominal);
    let model = modal_model(modes, nominal, opts.weights, opts.formulation)?;
    let misfit = model.as_ref();
    let mut els = opts.kinds.map_or_else(Vec::new, |k| elements(nominal, k));
    if opts.dampers {
        els.extend(damper_elements(nominal, &property)?);
    }
    check_size(els.len(), opts.k_max)?;
    if opts.k_min > opts.k_max {
        return Err(Error::invalid(
            "defects",
            opts.k_min,
            format!("<= k_max = {}", opts.k_max),
        ));
    }
    let search = search_by_k(nominal, &els, misfit, opts)?;
    let (best, chosen) = (&search.best, search.chosen);
    let bic = |f: &SetFit| bic(f, misfit.dof());
    let label = |idx: &[usize]| idx.iter().map(|&i| name(&els[i])).collect::<Vec<_>>();
    let k_selection = best
        .iter()
        .map(|(f, _)| KRow {
            k: f.idx.len(),
            chi2: f.fit.chi2,
            bic: bic(f),
            set: label(&f.idx),
        })
        .collect();
    let (answer, second) = &best[chosen];
    let problem = FactorProblem {
        nominal,
        elements: &answer.idx.iter().map(|&i| els[i]).collect::<Vec<_>>(),
        misfit,
        prior: None,
    };
    let chain = problem.chain(&answer.fit.theta)?;
    let runner_up_defects = match second {
        Some(s) => fitted_defects(&problem, &els, s)?,
        None => Vec::new(),
    };
    let report = ModalLocateReport {
        status: Status::Converged,
        resolved: false,
        message: String::new(),
        k: best[chosen].0.idx.len(),
        defects: defect_estimates(&els, answer, opts),
        chi2: answer.fit.chi2,
        dof: misfit.dof(),
        p_value: None,
        errors_given,
        assumed_weights: property.assumed(),
        damping_ratios,
        k_selection,
        runner_up: second
            .as_ref()
            .map(|s| (label(&s.idx), s.fit.chi2 - answer.fit.chi2)),
        runner_up_defects,
        nested_above: search.nested_above,
        dampers_searched: opts.dampers,
        sets: search.sets,
        chain,
    };
    Ok(judge(report))
}

/// What the table's damping ratios are to the misfit (see
/// [`ModalLocateReport::damping_ratios`]).
fn damping_ratios(property: &ModalMisfit, nominal: &Chain) -> &'static str {
    if property.uses_damping() {
        "fitted"
    } else if property.ignores_damping() {
        "not used"
    } else if crate::time::survey_modes::is_damped(nominal) {
        "absent"
    } else {
        "none"
    }
}

/// `chi2 + 2 k ln N` of a set on `n_data` data.
fn bic(f: &SetFit, n_data: usize) -> f64 {
    f.fit.chi2 + 2.0 * f.idx.len() as f64 * (n_data as f64).max(1.0).ln()
}

/// The best and second-best set of every number of defects tried, the
/// one BIC chooses, from where the search was nested, and the sets fitted.
struct ByK {
    best: Vec<(SetFit, Option<SetFit>)>,
    chosen: usize,
    nested_above: Option<usize>,
    sets: usize,
}

/// Every set of `k_min..=k_max` elements of `els`; with `extend`, while the
/// largest number tried wins, one more defect in the best answers at one
/// fewer (nested), as long as it wins.
fn search_by_k(
    nominal: &Chain,
    els: &[Defect],
    misfit: &dyn MeasurementModel,
    opts: &ModalLocateOptions,
) -> Result<ByK> {
    let n_data = misfit.dof();
    let choose = |best: &[(SetFit, Option<SetFit>)]| {
        (0..best.len())
            .min_by(|&a, &b| bic(&best[a].0, n_data).total_cmp(&bic(&best[b].0, n_data)))
            .expect("k = 0 at least")
    };
    let mut out = ByK {
        best: Vec::new(),
        chosen: 0,
        nested_above: None,
        sets: 0,
    };
    let mut top = Vec::new();
    for k in opts.k_min..=opts.k_max {
        let (mut fits, count) = best_sets(nominal, els, misfit, k, opts)?;
        out.sets += count;
        let second = (fits.len() > 1).then(|| fits.remove(1));
        top = fits;
        out.best.push((top[0].clone(), second));
    }
    out.chosen = choose(&out.best);
    while opts.extend && out.chosen + 1 == out.best.len() && top[0].idx.len() < els.len() {
        let (mut fits, count) = nested_sets(nominal, els, misfit, &top, opts)?;
        out.sets += count;
        if fits.is_empty() {
            break;
        }
        out.nested_above.get_or_insert(top[0].idx.len());
        let second = (fits.len() > 1).then(|| fits.remove(1));
        top = fits;
        out.best.push((top[0].clone(), second));
        out.chosen = choose(&out.best);
    }
    Ok(out)
}

/// The defects of the set `fit` of `els`, fitted (the chain of `problem`
/// with that set's elements scaled by its factors).
fn fitted_defects(problem: &FactorProblem, els: &[Defect], fit: &SetFit) -> Result<Vec<Defect>> {
    let elements: Vec<Defect> = fit.idx.iter().map(|&i| els[i]).collect();
    let chain = FactorProblem {
        elements: &elements,
        ..*problem
    }
    .chain(&fit.fit.theta)?;
    Ok(chain
        .defects()
        .iter()
        .filter(|d| elements.iter().any(|e| e.site() == d.site()))
        .copied()
        .collect())
}

/// Refuse a search too large to be exhaustive.
fn check_size(elements: usize, k_max: usize) -> Result<()> {
    if k_max > elements {
        return Err(Error::invalid(
            "k_max",
            k_max,
            format!("<= {elements}, the number of elements"),
        ));
    }
    let count = binomial(elements, k_max);
    if count > MAX_SETS as f64 {
        return Err(Error::invalid(
            "k_max",
            k_max,
            format!("at most {MAX_SETS} position sets per k ({count:.0} for {elements} elements): lower --defects"),
        ));
    }
    Ok(())
}

fn binomial(n: usize, k: usize) -> f64 {
    (0..k).fold(1.0, |acc, i| acc * (n - i) as f64 / (i + 1) as f64)
}

/// `spring 3`, `mass 2`, `damper 2`.
fn name(d: &Defect) -> String {
    format!("{} {}", d.kind(), d.at())
}

/// `--defects` of a modal or output-only search: `auto` (0 to 2), `auto:K`
/// (0 to K) or `K` (exactly K), as `(k_min, k_max)`.
///
/// # Errors
/// Another text (field `defects`).
///
/// ```
/// use springmass::detect::fit::modal_locate::parse_defect_count;
/// assert_eq!(parse_defect_count("auto")?, (0, 2));
/// assert_eq!(parse_defect_count("auto:3")?, (0, 3));
/// assert_eq!(parse_defect_count("1")?, (1, 1));
/// assert!(parse_defect_count("two").is_err());
/// # Ok::<(), springmass::Error>(())
/// ```
pub fn parse_defect_count(text: &str) -> Result<(usize, usize)> {
    let bad = || Error::invalid("defects", text, "auto, auto:K or K (a number of defects)");
    match text.split_once(':') {
        None if text == "auto" => Ok((0, 2)),
        Some(("auto", k)) => Ok((0, k.parse().map_err(|_| bad())?)),
        None => {
            let k = text.parse().map_err(|_| bad())?;
            Ok((k, k))
        }
        Some(_) => Err(bad()),
    }
}

/// `--kinds` of a modal search: `spring`, `mass`, `damper` or a comma
/// list of them, `any` (springs and masses, and dampers when the modes
/// can show them: measured damping ratios and a damped `nominal`), or
/// `default` (the command line's and Python's default: springs, and
/// dampers when the modes can show them).
///
/// # Errors
/// Another word (field `kinds`).
///
/// ```
/// use springmass::Chain;
/// use springmass::detect::data::modes::MeasuredModes;
/// use springmass::detect::fit::modal_locate::parse_kinds;
/// use springmass::detect::fit::profile::ProfileMode;
/// let modes = MeasuredModes::from_csv_str("frequency,damping,phi_1\n0.1,0.02,1\n")?;
/// let damped = Chain::new(4)?.with_d(0.05)?;
/// assert_eq!(parse_kinds("any", &damped, &modes)?, (Some(ProfileMode::Both), true));
/// assert_eq!(parse_kinds("any", &Chain::new(4)?, &modes)?, (Some(ProfileMode::Both), false));
/// assert_eq!(parse_kinds("damper", &damped, &modes)?, (None, true));
/// assert_eq!(parse_kinds("default", &damped, &modes)?, (Some(ProfileMode::Springs), true));
/// assert_eq!(parse_kinds("default", &Chain::new(4)?, &modes)?, (Some(ProfileMode::Springs), false));
/// assert!(parse_kinds("beam", &damped, &modes).is_err());
/// # Ok::<(), springmass::Error>(())
/// ```
pub fn parse_kinds(
    text: &str,
    nominal: &Chain,
    modes: &MeasuredModes,
) -> Result<(Option<ProfileMode>, bool)> {
    let (mut springs, mut masses, mut dampers) = (false, false, false);
    // dampers show in the modes through measured ratios of a damped chain
    let measurable = crate::time::survey_modes::is_damped(nominal)
        && modes.modes().iter().any(|m| m.damping.is_some());
    for word in text.split(',').map(str::trim) {
        match word {
            "spring" | "springs" => springs = true,
            "mass" | "masses" => masses = true,
            "damper" | "dampers" => dampers = true,
            "any" | "both" | "all" => {
                springs = true;
                masses = true;
                dampers |= measurable;
            }
            "default" => {
                springs = true;
                dampers |= measurable;
            }
            other => {
                return Err(Error::invalid(
                    "kinds",
                    other,
                    "spring, mass, damper (a comma list of them), any or default, with --modes",
                ))
            }
        }
    }
    let kinds = match (springs, masses) {
        (true, true) => Some(ProfileMode::Both),
        (true, false) => Some(ProfileMode::Springs),
        (false, true) => Some(ProfileMode::Masses),
        (false, false) => None,
    };
    Ok((kinds, dampers))
}

/// The dampers of `nominal` as elements: one per storey (between-storey
/// damping) or per mass (grounded), each at its nominal value (a damper
/// of value 0 has no factor and is left out).
///
/// # Errors
/// Damping ratios the misfit does not compare (field `kinds`: an undamped
/// nominal chain or a table without them); another damping model.
fn damper_elements(nominal: &Chain, misfit: &ModalMisfit) -> Result<Vec<Defect>> {
    if !misfit.uses_damping() {
        return Err(Error::invalid(
            "kinds",
            "damper",
            "damping ratios in the table (column damping) and a damped nominal chain (--d, --damping) to search dampers",
        ));
    }
    let (values, sites): (Vec<f64>, Vec<usize>) = match nominal.damping() {
        Damping::Between { .. } => {
            let (lo, hi) = nominal.spring_range();
            (nominal.spring_dampers(), (lo..=hi).collect())
        }
        Damping::Grounded => {
            let d = nominal.dampers();
            (
                std::iter::once(0.0).chain(d).collect(),
                (1..=nominal.n()).collect(),
            )
        }
        other => {
            return Err(Error::invalid(
                "kinds",
                "damper",
                format!(
                    "the grounded or between damping model for damper defects (not {})",
                    other.name()
                ),
            ))
        }
    };
    Ok(sites
        .into_iter()
        .filter(|&at| values[at] > 0.0)
        .map(|at| Defect::Damper { at, d: values[at] })
        .collect())
}

/// The best sets of `k` elements (at most [`NESTED_FROM`], best first),
/// and the sets fitted.
fn best_sets(
    nominal: &Chain,
    els: &[Defect],
    misfit: &dyn MeasurementModel,
    k: usize,
    opts: &ModalLocateOptions,
) -> Result<(Vec<SetFit>, usize)> {
    let mut fits: Vec<SetFit> = Vec::new();
    let mut idx: Vec<usize> = (0..k).collect();
    loop {
        crate::cancel::check()?;
        if let Some(fit) = fit_set(nominal, els, misfit, &idx, opts)? {
            fits.push(SetFit {
                idx: idx.clone(),
                fit,
            });
        }
        if !next_combination(&mut idx, els.len()) {
            break;
        }
    }
    let count = fits.len();
    Ok((best_of(fits, k)?, count))
}

/// The best [`NESTED_FROM`] of `fits` (of `k` elements), best first.
///
/// # Errors
/// No fit at all.
fn best_of(mut fits: Vec<SetFit>, k: usize) -> Result<Vec<SetFit>> {
    if fits.is_empty() {
        return Err(Error::Numerical {
            method: "modal defect search".into(),
            reason: format!("no set of {k} elements could be fitted"),
        });
    }
    fits.sort_by(|a, b| a.fit.chi2.total_cmp(&b.fit.chi2).then(a.idx.cmp(&b.idx)));
    fits.truncate(NESTED_FROM);
    Ok(fits)
}

/// How many of the best sets at one defect fewer the nested search of
/// `--defects auto` grows by one element.
pub const NESTED_FROM: usize = 8;

/// The sets of one element more than the sets of `top` (each grown by
/// every element it does not hold, each set once), fitted: their best
/// [`NESTED_FROM`] (empty when none could be fitted) and the sets fitted.
fn nested_sets(
    nominal: &Chain,
    els: &[Defect],
    misfit: &dyn MeasurementModel,
    top: &[SetFit],
    opts: &ModalLocateOptions,
) -> Result<(Vec<SetFit>, usize)> {
    let mut seen = std::collections::BTreeSet::new();
    for t in top {
        for e in (0..els.len()).filter(|e| !t.idx.contains(e)) {
            let mut idx = t.idx.clone();
            idx.push(e);
            idx.sort_unstable();
            seen.insert(idx);
        }
    }
    let mut fits = Vec::new();
    for idx in seen {
        crate::cancel::check()?;
        if let Some(fit) = fit_set(nominal, els, misfit, &idx, opts)? {
            fits.push(SetFit { idx, fit });
        }
    }
    let count = fits.len();
    let k = top.first().map_or(0, |t| t.idx.len() + 1);
    Ok((best_of(fits, k).unwrap_or_default(), count))
}

/// The next k-subset of `0..n` in lexicographic order; false after the
/// last (the exhaustive searches on modes and on an output spectrum).
pub(super) fn next_combination(idx: &mut [usize], n: usize) -> bool {
    let k = idx.len();
    for i in (0..k).rev() {
        if idx[i] < n - k + i {
            idx[i] += 1;
            for j in i + 1..k {
                idx[j] = idx[j - 1] + 1;
            }
            return true;
        }
    }
    false
}

/// The best fit of one set from three starts (nominal, softer, stiffer).
fn fit_set(
    nominal: &Chain,
    els: &[Defect],
    misfit: &dyn MeasurementModel,
    idx: &[usize],
    opts: &ModalLocateOptions,
) -> Result<Option<LmFit>> {
    let chosen: Vec<Defect> = idx.iter().map(|&i| els[i]).collect();
    let problem = FactorProblem {
        nominal,
        elements: &chosen,
        misfit,
        prior: None,
    };
    if idx.is_empty() {
        let chi2 = misfit.chi2(nominal)?;
        return Ok(Some(LmFit {
            theta: Vec::new(),
            chi2,
            m: misfit.dof(),
            jacobian: nalgebra::DMatrix::zeros(misfit.dof(), 0),
            iterations: 0,
            evaluations: 1,
            converged: true,
            at_bound: Vec::new(),
        }));
    }
    let bounds = vec![opts.bounds; idx.len()];
    let mut best: Option<LmFit> = None;
    for start in [1.0, 0.6, 1.6] {
        match levenberg_marquardt(
            &problem,
            &vec![start; idx.len()],
            &bounds,
            &LmOptions::default(),
        ) {
            Ok(f) if best.as_ref().is_none_or(|b| f.chi2 < b.chi2) => best = Some(f),
            Ok(_) => {}
            Err(Error::Cancelled) => return Err(Error::Cancelled),
            Err(_) => {}
        }
    }
    Ok(best)
}

/// The chosen set's defects with standard errors.
fn defect_estimates(els: &[Defect], s: &SetFit, opts: &ModalLocateOptions) -> Vec<FactorEstimate> {
    let cov = covariance(&s.fit.jacobian).ok();
    s.idx
        .iter()
        .enumerate()
        .map(|(c, &i)| {
            let d = &els[i];
            let f = s.fit.theta[c];
            let se = cov.as_ref().map(|m| m[(c, c)].max(0.0).sqrt());
            let at_bound = on_bound(f, opts.bounds);
            FactorEstimate::new(
                d,
                f,
                se,
                se.is_some_and(f64::is_finite) && !at_bound,
                at_bound,
            )
        })
        .collect()
}

/// Status, `resolved` and message.
fn judge(mut r: ModalLocateReport) -> ModalLocateReport {
    let p = 2 * r.k;
    let free = r.dof.saturating_sub(p);
    if free > 0 {
        r.p_value = Some(chi2_sf(r.chi2, free as f64));
    }
    let margin = (r.dof.max(1) as f64).ln();
    let close = r.runner_up.as_ref().filter(|(_, gap)| *gap < margin);
    // the last defect added must win by the margin too
    let pos = r.k_selection.iter().position(|row| row.k == r.k);
    let marginal = pos
        .filter(|&i| i > 0)
        .map(|i| r.k_selection[i - 1].bic - r.k_selection[i].bic)
        .filter(|gain| *gain < margin);
    let weights = match &r.assumed_weights {
        None => "standard errors from the table".to_string(),
        Some((what, cols)) => {
            format!("chi-square under assumed weights ({what}): give {cols} for a test")
        }
    };
    (r.status, r.resolved, r.message) = if r.p_value.is_some_and(|p| p < 0.01) {
        let msg = format!(
            "no set of up to {} changed elements explains the modes (chi2 {:.3} on {free} dof): check the pairing (MAC) and the nominal chain, {}or update every element (--profile){}",
            r.k_selection.last().map_or(0, |row| row.k),
            r.chi2,
            if r.damping_ratios == "fitted" && !r.dampers_searched {
                "search the dampers too (--kinds spring,damper or any), "
            } else {
                ""
            },
            assumed_note(r.assumed_weights.as_ref().map(|(w, _)| w.as_str()))
        );
        (Status::ModelMismatch, false, msg)
    } else if let Some(gain) = marginal {
        let msg = format!(
            "the modes barely ask for defect {} (BIC better by only {gain:.3} than with {}): it may be noise; {weights}",
            r.k,
            r.k - 1
        );
        (Status::NotIdentifiable, false, msg)
    } else if let Some((set, gap)) = close {
        let msg = format!(
            "the modes do not tell this set from {} (chi-square worse by only {gap:.3}); {weights}",
            set.join(", ")
        );
        (Status::NotIdentifiable, false, msg)
    } else if r.defects.iter().any(|d| !d.determined) {
        (
            Status::NotIdentifiable,
            false,
            format!(
                "a defect's value is not determined (on a bound or no standard error); {weights}"
            ),
        )
    } else {
        let what = if r.k == 0 {
            "no element changed"
        } else {
            "every defect identifiable"
        };
        (Status::Converged, true, format!("{what}; {weights}"))
    };
    if r.damping_ratios == "not used" {
        r.message.push_str(
            "; the table's damping ratios were not used (an undamped nominal chain): a changed damper can pass for a changed spring here, give the nominal damping (--damping, --d) to fit them and --kinds any to search the dampers",
        );
    }
    r
}
