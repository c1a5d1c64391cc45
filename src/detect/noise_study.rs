//! The noise study: how defect recovery degrades with measurement noise, per
//! misfit; calibration of the standard errors; fitting the damping; choosing
//! the number of defects.
//!
//! Data are always noisy *simulated time series*: `x_1(t)` of the true chain on
//! `0, dt, ..., t_end` (default `t_end = 200`, `dt = 0.2`, 1001 samples) from
//! the time stepper, plus seeded white noise of standard deviation
//! `level max|x_1|`. Every task derives its own seed from
//! `(study seed, system, level, repeat)`, so results do not depend on the
//! thread count.
//!
//! ```no_run
//! use springmass::detect::noise_study::{success_table, systems, StudyConfig};
//! use springmass::detect::fit::general::{Setup};
//! use springmass::detect::misfit::MisfitKind;
//! let cfg = StudyConfig { levels: vec![1e-3], seeds: 2, ..StudyConfig::default() };
//! let cells = success_table(&systems()[..1], &cfg, &MisfitKind::ALL, &Setup::new()?)?;
//! assert_eq!(cells.len(), 3);
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::chain::{Chain, Defect};
use crate::detect::data::series::TimeData;
use crate::detect::fit::chainfit::ChainFitReport;
use crate::detect::fit::general::{
    fit_damping, fit_noisy, fit_noisy_general, time_from_bromwich, GeneralOptions, Hypothesis,
    Setup,
};
use crate::detect::fit::select::{select, Criterion, ModelFit, Selection};
use crate::detect::misfit::MisfitKind;
use crate::detect::unknowns::{KindChoice, Unknowns};
use crate::error::Result;
use crate::noise::NoiseLevel;
use crate::sensitivity::Param;
use rayon::prelude::*;
use serde::Serialize;

/// A named true chain.
#[derive(Clone, Debug)]
pub struct System {
    /// Name (`S1`..`S4`, `C3a`, `C3b`).
    pub name: String,
    /// The true chain.
    pub truth: Chain,
}

fn sys(name: &str, n: usize, defects: &[(usize, f64)]) -> System {
    System {
        name: name.into(),
        truth: Chain::paper(n)
            .and_then(|c| c.with_defects(defects.iter().map(|&(at, m)| Defect::Mass { at, m })))
            .expect("valid built-in system"),
    }
}

/// The paper's Table 1 systems S1-S4 and two chains with three defects:
/// `C3a` (n = 10: (2, 2), (5, 4), (8, 0.5)) and `C3b` (n = 20: (4, 3), (10, 0.5), (16, 2)).
pub fn systems() -> Vec<System> {
    vec![
        sys("S1", 5, &[(2, 3.0), (4, 0.5)]),
        sys("S2", 10, &[(3, 3.0), (7, 2.0)]),
        sys("S3", 20, &[(8, 5.0), (15, 2.0)]),
        sys("S4", 20, &[(8, 5.0), (15, 15.0)]),
        sys("C3a", 10, &[(2, 2.0), (5, 4.0), (8, 0.5)]),
        sys("C3b", 20, &[(4, 3.0), (10, 0.5), (16, 2.0)]),
    ]
}

/// Settings of the success-vs-noise study.
#[derive(Clone, Debug)]
pub struct StudyConfig {
    /// Noise levels (relative to `max |x_1|`).
    pub levels: Vec<f64>,
    /// Seeds per (system, level).
    pub seeds: usize,
    /// Record length.
    pub t_end: f64,
    /// Sampling step.
    pub dt: f64,
    /// Relative mass tolerance of a success.
    pub mass_tol: f64,
    /// Study seed.
    pub seed: u64,
}

impl Default for StudyConfig {
    /// Levels `1e-8, 1e-7, ..., 1e-1`, 20 seeds, `t_end = 200`, `dt = 0.2`,
    /// masses within 5%, seed 1.
    fn default() -> Self {
        StudyConfig {
            levels: (0..8).map(|e| 10f64.powi(e - 8)).collect(),
            seeds: 20,
            t_end: 200.0,
            dt: 0.2,
            mass_tol: 0.05,
            seed: 1,
        }
    }
}

/// A task seed from its coordinates (splitmix64 mixing).
pub fn task_seed(parts: &[u64]) -> u64 {
    let mut h: u64 = 0x9E37_79B9_7F4A_7C15;
    for &p in parts {
        h ^= p
            .wrapping_add(0x9E37_79B9_7F4A_7C15)
            .wrapping_add(h << 6)
            .wrapping_add(h >> 2);
        let mut z = h;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        h = z ^ (z >> 31);
    }
    h
}

/// One cell of the success table.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Cell {
    /// System name.
    pub system: String,
    /// Misfit name.
    pub misfit: &'static str,
    /// Noise level.
    pub level: f64,
    /// Runs.
    pub runs: usize,
    /// Positions exact and masses within the tolerance.
    pub successes: usize,
    /// Positions exact.
    pub positions_ok: usize,
}

impl Cell {
    /// Success rate.
    pub fn rate(&self) -> f64 {
        self.successes as f64 / self.runs.max(1) as f64
    }
}

/// Noisy data of `truth` for one task.
///
/// # Errors
/// As [`TimeData::simulate`].
pub fn noisy_data(truth: &Chain, cfg: &StudyConfig, level: f64, seed: u64) -> Result<TimeData> {
    TimeData::simulate(
        truth,
        cfg.t_end,
        cfg.dt,
        NoiseLevel::RelativeMax(level),
        seed,
    )
}

/// Success of every misfit on every (system, level), over `cfg.seeds` seeds.
/// Parallel over tasks (rayon), deterministic.
///
/// # Errors
/// The first failing fit.
pub fn success_table(
    systems: &[System],
    cfg: &StudyConfig,
    misfits: &[MisfitKind],
    setup: &Setup,
) -> Result<Vec<Cell>> {
    let mut tasks = Vec::new();
    for (si, _) in systems.iter().enumerate() {
        for (li, _) in cfg.levels.iter().enumerate() {
            for r in 0..cfg.seeds {
                tasks.push((si, li, r));
            }
        }
    }
    let results: Vec<Result<Vec<(bool, bool)>>> = tasks
        .par_iter()
        .map(|&(si, li, r)| {
            let s = &systems[si];
            let seed = task_seed(&[cfg.seed, si as u64, li as u64, r as u64]);
            let data = noisy_data(&s.truth, cfg, cfg.levels[li], seed)?;
            let k = s.truth.defects().len();
            let base = s.truth.uniform();
            let mut bromwich: Option<Vec<Hypothesis>> = None;
            let mut out = Vec::with_capacity(misfits.len());
            for &m in misfits {
                let h = match m {
                    MisfitKind::Bromwich | MisfitKind::Time => {
                        if bromwich.is_none() {
                            bromwich =
                                Some(fit_noisy(&base, &data, k, MisfitKind::Bromwich, setup)?);
                        }
                        let b = bromwich.as_ref().expect("set above");
                        if m == MisfitKind::Time {
                            time_from_bromwich(&base, &data, b, setup)?
                        } else {
                            b.clone()
                        }
                    }
                    other => fit_noisy(&base, &data, k, other, setup)?,
                };
                out.push((
                    h[0].matches(&s.truth, cfg.mass_tol),
                    h[0].positions_match(&s.truth),
                ));
            }
            Ok(out)
        })
        .collect();
    let mut cells = Vec::new();
    for (si, s) in systems.iter().enumerate() {
        for (mi, m) in misfits.iter().enumerate() {
            for (li, &level) in cfg.levels.iter().enumerate() {
                let mut cell = Cell {
                    system: s.name.clone(),
                    misfit: m.name(),
                    level,
                    runs: 0,
                    successes: 0,
                    positions_ok: 0,
                };
                for (t, res) in tasks.iter().zip(&results) {
                    if t.0 == si && t.1 == li {
                        let v = res.as_ref().map_err(Clone::clone)?;
                        cell.runs += 1;
                        cell.successes += v[mi].0 as usize;
                        cell.positions_ok += v[mi].1 as usize;
                    }
                }
                cells.push(cell);
            }
        }
    }
    Ok(cells)
}

/// Calibration of the standard errors: fraction of repeats with the true mass
/// within two standard errors.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Calibration {
    /// Repeats.
    pub repeats: usize,
    /// Per defect: fraction of repeats with `|m_hat - m| <= 2 se`.
    pub within_2se: Vec<f64>,
    /// Over all defects.
    pub overall: f64,
    /// Per defect: mean standard error.
    pub mean_se: Vec<f64>,
    /// Per defect: empirical standard deviation of `m_hat`.
    pub sd_estimate: Vec<f64>,
    /// Mean chi-square per degree of freedom at the fits.
    pub mean_reduced_chi2: f64,
}

/// Fit the masses of `truth`'s defects at their (known) positions in the time
/// domain, `repeats` times with fresh noise, and check the standard errors.
///
/// # Errors
/// As the fits.
pub fn calibration(
    truth: &Chain,
    cfg: &StudyConfig,
    level: f64,
    repeats: usize,
) -> Result<Calibration> {
    let k = truth.defects().len();
    type Run = Result<(Vec<f64>, Vec<f64>, f64)>;
    let runs: Vec<Run> = (0..repeats)
        .into_par_iter()
        .map(|r| {
            let data = noisy_data(truth, cfg, level, task_seed(&[cfg.seed, 77, r as u64]))?;
            let misfit = crate::detect::misfit::time::TimeMisfit::new(data);
            // start 10% off the truth
            let start = truth
                .uniform()
                .with_defects(truth.defects().iter().map(|d| match *d {
                    Defect::Mass { at, m } => Defect::Mass { at, m: m * 1.1 },
                    other => other,
                }))?;
            let params = crate::sensitivity::Param::defects(&start);
            let f = crate::detect::fit::chainfit::fit_chain(
                &start,
                &params,
                &crate::detect::fit::chainfit::Obs::Time(&misfit),
                None,
            )?;
            Ok((
                f.values.clone(),
                f.std_errors.clone(),
                f.chi2() / f.lm.dof() as f64,
            ))
        })
        .collect();
    let mut within = vec![0usize; k];
    let mut se_sum = vec![0.0; k];
    let mut vals: Vec<Vec<f64>> = vec![Vec::new(); k];
    let mut red = 0.0;
    for r in runs {
        let (v, se, rc) = r?;
        red += rc;
        for i in 0..k {
            let m = truth.defects()[i].value();
            if (v[i] - m).abs() <= 2.0 * se[i] {
                within[i] += 1;
            }
            se_sum[i] += se[i];
            vals[i].push(v[i]);
        }
    }
    let n = repeats.max(1) as f64;
    let sd = vals
        .iter()
        .map(|v| {
            let mean = v.iter().sum::<f64>() / n;
            (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0)).sqrt()
        })
        .collect();
    Ok(Calibration {
        repeats,
        within_2se: within.iter().map(|&w| w as f64 / n).collect(),
        overall: within.iter().sum::<usize>() as f64 / (n * k.max(1) as f64),
        mean_se: se_sum.iter().map(|s| s / n).collect(),
        sd_estimate: sd,
        mean_reduced_chi2: red / n,
    })
}

/// One damping fit.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DampingFit {
    /// Seed.
    pub seed: u64,
    /// Positions found.
    pub positions: Vec<usize>,
    /// Fitted `d`.
    pub d: f64,
    /// Its standard error.
    pub se: f64,
    /// Relative error `|d - d_true| / d_true`.
    pub rel_err: f64,
}

/// Unknown damping: positions and masses by the time-domain fit at a wrong
/// damping guess `d0`, then masses and `d` together by Levenberg-Marquardt,
/// then the positions again at the fitted `d`, then the final joint fit
/// (alternation around the enumeration, `rounds` times).
///
/// # Errors
/// As the fits.
pub fn fit_unknown_damping(
    guess: &Chain,
    data: &TimeData,
    k: usize,
    setup: &Setup,
    rounds: usize,
) -> Result<(Hypothesis, ChainFitReport)> {
    let mut base = guess.uniform();
    let mut last = None;
    for _ in 0..rounds.max(1) {
        let h = fit_noisy(&base, data, k, MisfitKind::Time, setup)?;
        let best = h[0].clone();
        let rep = fit_damping(&base, data, &best)?;
        base = base.with_d(rep.chain.d())?;
        last = Some((best, rep));
    }
    Ok(last.expect("at least one round"))
}

/// The damping study: `seeds` noisy series of `truth`, damping unknown (start
/// `d0`).
///
/// # Errors
/// As the fits.
pub fn damping_study(
    truth: &Chain,
    cfg: &StudyConfig,
    level: f64,
    seeds: usize,
    d0: f64,
    setup: &Setup,
) -> Result<Vec<DampingFit>> {
    let k = truth.defects().len();
    (0..seeds)
        .into_par_iter()
        .map(|r| {
            let seed = task_seed(&[cfg.seed, 99, r as u64]);
            let data = noisy_data(truth, cfg, level, seed)?;
            let guess = truth.uniform().with_d(d0)?;
            let (h, rep) = fit_unknown_damping(&guess, &data, k, setup, 2)?;
            let d = rep.chain.d();
            Ok(DampingFit {
                seed,
                positions: h.positions(),
                d,
                se: *rep.std_errors.last().unwrap_or(&f64::NAN),
                rel_err: (d - truth.d()).abs() / truth.d(),
            })
        })
        .collect()
}

/// Choose the number of defects for one noisy series: the time-domain fit for
/// each `k = 0..=kmax` (2 parameters per defect), then [`select`].
///
/// # Errors
/// As the fits.
pub fn choose_k(
    base: &Chain,
    data: &TimeData,
    kmax: usize,
    criterion: Criterion,
    setup: &Setup,
) -> Result<Selection> {
    let mut fits = Vec::new();
    for k in 0..=kmax {
        let h = fit_noisy(base, data, k, MisfitKind::Time, setup)?;
        fits.push(ModelFit::new(k, h[0].chi2, 2 * k));
    }
    select(&fits, data.len(), criterion)
}

/// Confusion table `table[true k][chosen k]` over `seeds` series per truth.
///
/// # Errors
/// As the fits.
pub fn confusion(
    truths: &[Chain],
    cfg: &StudyConfig,
    level: f64,
    seeds: usize,
    criterion: Criterion,
    setup: &Setup,
) -> Result<Vec<Vec<usize>>> {
    let kmax = truths.len() - 1;
    let tasks: Vec<(usize, usize)> = (0..truths.len())
        .flat_map(|t| (0..seeds).map(move |r| (t, r)))
        .collect();
    let chosen: Vec<Result<usize>> = tasks
        .par_iter()
        .map(|&(t, r)| {
            let data = noisy_data(
                &truths[t],
                cfg,
                level,
                task_seed(&[cfg.seed, 55, t as u64, r as u64]),
            )?;
            Ok(choose_k(&truths[t].uniform(), &data, kmax, criterion, setup)?.chosen)
        })
        .collect();
    let mut table = vec![vec![0usize; kmax + 1]; truths.len()];
    for (&(t, _), c) in tasks.iter().zip(chosen) {
        let c = c?;
        table[t][c.min(kmax)] += 1;
    }
    Ok(table)
}

/// Truth chains with 0..=3 defects on `n = 10` for the confusion table:
/// none; (4, 2); (3, 3), (7, 2); (2, 2), (5, 4), (8, 0.5).
pub fn selection_truths() -> Vec<Chain> {
    let s = systems();
    vec![
        Chain::paper(10).expect("valid"),
        sys("k1", 10, &[(4, 2.0)]).truth,
        s[1].truth.clone(),
        s[4].truth.clone(),
    ]
}

/// A case of the defect-kind study: a true chain with spring, damper or mass
/// defects, what the fit is told about the kinds, and the chain parameters it
/// fits alongside.
#[derive(Clone, Debug)]
pub struct KindCase {
    /// Name.
    pub name: String,
    /// The true chain.
    pub truth: Chain,
    /// The kind of each sought defect (positions always unknown).
    pub kinds: Vec<KindChoice>,
    /// Chain parameters fitted with the defects.
    pub params: Vec<Param>,
    /// Starting damping (the truth's `d` is 0.1).
    pub d_start: f64,
}

/// The shipped cases of the defect-kind study (paper chains, `d = 0.1`):
/// a spring defect; a damper defect; a spring and a damper with `d` unknown
/// (start 0.15); a mass and a spring with the kinds unknown ("any"); a spring
/// and a damper deep in a 20-mass chain with `d` unknown.
pub fn kind_cases() -> Vec<KindCase> {
    let case =
        |name: &str, n: usize, defects: Vec<Defect>, kinds: Vec<KindChoice>, d: bool| KindCase {
            name: name.into(),
            truth: Chain::paper(n)
                .and_then(|c| c.with_defects(defects))
                .expect("valid built-in case"),
            kinds,
            params: if d { vec![Param::D] } else { vec![] },
            d_start: if d { 0.15 } else { 0.1 },
        };
    vec![
        case(
            "spring 6:0.5 (n=10)",
            10,
            vec![Defect::Spring { at: 6, k: 0.5 }],
            vec![KindChoice::Spring],
            false,
        ),
        case(
            "damper 6:0.6 (n=10)",
            10,
            vec![Defect::Damper { at: 6, d: 0.6 }],
            vec![KindChoice::Damper],
            false,
        ),
        case(
            "spring 4:0.5 + damper 7:0.6, d unknown (n=10)",
            10,
            vec![
                Defect::Spring { at: 4, k: 0.5 },
                Defect::Damper { at: 7, d: 0.6 },
            ],
            vec![KindChoice::Spring, KindChoice::Damper],
            true,
        ),
        case(
            "mass 3:2 + spring 6:0.4, kinds unknown (n=8)",
            8,
            vec![
                Defect::Mass { at: 3, m: 2.0 },
                Defect::Spring { at: 6, k: 0.4 },
            ],
            vec![KindChoice::Any, KindChoice::Any],
            false,
        ),
        case(
            "spring 12:0.5 + damper 16:0.6, d unknown (n=20)",
            20,
            vec![
                Defect::Spring { at: 12, k: 0.5 },
                Defect::Damper { at: 16, d: 0.6 },
            ],
            vec![KindChoice::Spring, KindChoice::Damper],
            true,
        ),
    ]
}

/// One row of the defect-kind study.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct KindRow {
    /// Case name.
    pub case: String,
    /// Noise level.
    pub level: f64,
    /// Runs.
    pub runs: usize,
    /// Kinds and positions exact.
    pub found: usize,
    /// Found, and every true value within 3 standard errors of its estimate.
    pub values_within_3se: usize,
    /// Found, and every value within 5% (relative).
    pub values_within_5pct: usize,
    /// Runs with the fitted `d` within 3 standard errors of the truth
    /// (`None` when `d` is not fitted).
    pub d_within_3se: Option<usize>,
}

/// The defect-kind study: each case on `seeds` noisy series at `level`, fitted
/// with the time misfit by [`fit_noisy_general`] (kinds, positions, values and
/// chain parameters). Parallel over (case, seed); deterministic.
///
/// # Errors
/// As the fits.
pub fn kinds_study(
    cases: &[KindCase],
    cfg: &StudyConfig,
    level: f64,
    seeds: usize,
    setup: &Setup,
) -> Result<Vec<KindRow>> {
    let tasks: Vec<(usize, usize)> = (0..cases.len())
        .flat_map(|c| (0..seeds).map(move |r| (c, r)))
        .collect();
    let opts = GeneralOptions {
        parallel: false,
        ..GeneralOptions::default()
    };
    type Outcome = (bool, bool, bool, Option<bool>);
    let out: Vec<Result<Outcome>> = tasks
        .par_iter()
        .map(|&(c, r)| {
            let case = &cases[c];
            let truth = &case.truth;
            let data = noisy_data(
                truth,
                cfg,
                level,
                task_seed(&[cfg.seed, 33, c as u64, r as u64]),
            )?;
            let unknowns = Unknowns::free(truth.n(), &case.kinds, &case.params)?;
            let start = truth.uniform().with_d(case.d_start)?;
            let fit = fit_noisy_general(&start, &data, &unknowns, MisfitKind::Time, setup, &opts)?;
            let best = &fit.ranked[0];
            let found = best.positions_match(truth);
            let value_ok = |rel: Option<f64>| {
                found
                    && truth.defects().iter().all(|t| {
                        best.defects.iter().zip(&best.std_errors).any(|(d, se)| {
                            d.kind() == t.kind()
                                && d.at() == t.at()
                                && match rel {
                                    Some(rel) => (d.value() - t.value()).abs() <= rel * t.value(),
                                    None => (d.value() - t.value()).abs() <= 3.0 * se,
                                }
                        })
                    })
            };
            let d_ok = best
                .param("d")
                .map(|p| (p.value - truth.d()).abs() <= 3.0 * p.std_error);
            Ok((found, value_ok(None), value_ok(Some(0.05)), d_ok))
        })
        .collect();
    let mut rows: Vec<KindRow> = cases
        .iter()
        .map(|c| KindRow {
            case: c.name.clone(),
            level,
            runs: 0,
            found: 0,
            values_within_3se: 0,
            values_within_5pct: 0,
            d_within_3se: (!c.params.is_empty()).then_some(0),
        })
        .collect();
    for (&(c, _), o) in tasks.iter().zip(out) {
        let (found, se3, pct5, d) = o?;
        let row = &mut rows[c];
        row.runs += 1;
        row.found += found as usize;
        row.values_within_3se += se3 as usize;
        row.values_within_5pct += pct5 as usize;
        if let (Some(n), Some(true)) = (row.d_within_3se.as_mut(), d) {
            *n += 1;
        }
    }
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seeds_are_distinct_and_stable() {
        let a = task_seed(&[1, 0, 0, 0]);
        assert_eq!(a, task_seed(&[1, 0, 0, 0]));
        assert_ne!(a, task_seed(&[1, 0, 0, 1]));
        assert_ne!(task_seed(&[1, 0, 1, 0]), task_seed(&[1, 1, 0, 0]));
    }

    #[test]
    fn kinds_study_finds_a_spring_and_a_damper_at_one_percent() {
        let cases = kind_cases();
        let cfg = StudyConfig::default();
        let rows = kinds_study(&cases[..2], &cfg, 1e-2, 1, &Setup::new().unwrap()).unwrap();
        assert_eq!(rows.len(), 2);
        for r in &rows {
            assert_eq!((r.runs, r.found, r.values_within_3se), (1, 1, 1), "{r:?}");
            assert_eq!(r.d_within_3se, None);
        }
    }
}

/// One case of the data-first study: the default fit of a noisy record,
/// told only `n` (and `k` when `k_given`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DataFirstRow {
    /// System name.
    pub system: String,
    /// Noise level (relative to `max |x_1|`).
    pub level: f64,
    /// Repeat.
    pub repeat: usize,
    /// True number of defects.
    pub k_true: usize,
    /// Number of defects of the answer.
    pub k_found: usize,
    /// Every position right (and no extra one).
    pub positions_ok: bool,
    /// Values of the right positions.
    pub values: usize,
    /// Of which the truth lies within 3 reported standard errors.
    pub within_3se: usize,
    /// A wrong answer flagged resolved, or a wrong position flagged identifiable.
    pub wrong_flagged: bool,
    /// Estimated over true noise level.
    pub sigma_ratio: f64,
    /// Status of the fit.
    pub status: String,
    /// Wall time of the fit.
    pub seconds: f64,
}

/// How a data-first answer compares with the truth.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Score {
    /// Every true position found, none extra.
    pub positions_ok: bool,
    /// Fitted values at true positions.
    pub values: usize,
    /// Of which the truth lies within 3 reported standard errors.
    pub within_3se: usize,
    /// A wrong answer flagged resolved, or a wrong position flagged identifiable.
    pub wrong_flagged: bool,
}

/// Score `rep` against `truth` (positions of every kind, values within 3 SE).
pub fn score(rep: &crate::detect::fit::FitReport, truth: &Chain) -> Score {
    let t: Vec<(usize, f64)> = truth
        .defects()
        .iter()
        .map(|d| (d.at(), d.value()))
        .collect();
    let mut tp: Vec<usize> = t.iter().map(|x| x.0).collect();
    tp.sort_unstable();
    let mut fp: Vec<usize> = rep.found().iter().map(|d| d.at()).collect();
    fp.sort_unstable();
    let positions_ok = tp == fp;
    let mut values = 0;
    let mut within_3se = 0;
    let mut wrong_flagged = !positions_ok && rep.resolved;
    for d in rep.defects.iter().filter(|d| !d.known) {
        match t.iter().find(|x| x.0 == d.at) {
            Some(&(_, v)) => {
                values += 1;
                if (d.value - v).abs() <= 3.0 * d.se {
                    within_3se += 1;
                }
            }
            None => wrong_flagged |= d.identifiable,
        }
    }
    Score {
        positions_ok,
        values,
        within_3se,
        wrong_flagged,
    }
}

/// The data-first fit of a noisy record of `truth`, told only its uniform
/// part (n, d, ...), the number of defects when `k_given` (otherwise chosen
/// by BIC among `0..=min(4, n)`), the misfit (`None`: the fit's default)
/// and the true noise level when `noise_given` (otherwise estimated).
/// Sequential (the studies run cases in parallel).
///
/// # Errors
/// As [`crate::detect::fit::fit`].
pub fn fit_record(
    truth: &Chain,
    data: &TimeData,
    k_given: bool,
    misfit: Option<MisfitKind>,
    noise_given: bool,
) -> Result<crate::detect::fit::FitReport> {
    use crate::detect::data::observations::{Observations, Series};
    use crate::detect::fit::{fit, DefectCount, FitOptions, Model, NoiseSpec, DEFAULT_K_MAX};
    let sigma = (noise_given && data.sigma() > 0.0).then_some(data.sigma());
    let obs = Observations::Series(Series::new(data.t().to_vec(), data.y().to_vec(), sigma)?);
    let opts = FitOptions {
        defects: if k_given {
            DefectCount::Exactly(truth.defects().len())
        } else {
            DefectCount::Auto {
                k_max: DEFAULT_K_MAX.min(truth.n()),
            }
        },
        noise: sigma.map_or(NoiseSpec::Auto, NoiseSpec::Sigma),
        misfit,
        parallel: false,
        ..FitOptions::default()
    };
    fit(&obs, &Model::from_chain(&truth.uniform()), &opts)
}

/// A seed from values (not list positions): a subset of systems, levels or
/// repeats reproduces the full table's cells.
pub fn value_seed(system: &str, level: f64, repeat: usize, study_seed: u64) -> u64 {
    let name = system.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
        (h ^ b as u64).wrapping_mul(0x100_0000_01b3)
    });
    task_seed(&[study_seed, name, level.to_bits(), repeat as u64])
}

/// The data-first study: for every (system, level, repeat) a noisy record
/// (seed [`value_seed`]), fitted by [`crate::detect::fit::fit`] with its
/// default settings (time misfit, noise estimated), `k` given (`k_given`)
/// or chosen by BIC among `0..=4`. Cases in parallel (rayon), each fit
/// sequential: the result does not depend on the thread count.
///
/// # Errors
/// The first failing fit.
pub fn data_first(
    systems: &[System],
    cfg: &StudyConfig,
    k_given: bool,
) -> Result<Vec<DataFirstRow>> {
    let mut tasks = Vec::new();
    for s in systems {
        for &level in &cfg.levels {
            for r in 0..cfg.seeds {
                tasks.push((s, level, r));
            }
        }
    }
    tasks
        .par_iter()
        .map(|&(s, level, r)| {
            let data = noisy_data(
                &s.truth,
                cfg,
                level,
                value_seed(&s.name, level, r, cfg.seed),
            )?;
            let k_true = s.truth.defects().len();
            let t0 = std::time::Instant::now();
            let rep = fit_record(&s.truth, &data, k_given, None, false)?;
            let sc = score(&rep, &s.truth);
            Ok(DataFirstRow {
                system: s.name.clone(),
                level,
                repeat: r,
                k_true,
                k_found: rep.k,
                positions_ok: sc.positions_ok,
                values: sc.values,
                within_3se: sc.within_3se,
                wrong_flagged: sc.wrong_flagged,
                sigma_ratio: rep.noise_sigma / data.sigma(),
                status: rep.status.name().to_string(),
                seconds: t0.elapsed().as_secs_f64(),
            })
        })
        .collect()
}
