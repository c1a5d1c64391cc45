//! Exhaustive enumeration of position sets, with a local fit of the unknown
//! masses for each set.
//!
//! For every admissible assignment of the unknown positions (a set of
//! distinct positions when the defects are interchangeable, an ordered
//! assignment otherwise; known positions excluded), the unknown masses are
//! fitted in `u = ln m` inside their bounds by the bounded Levenberg-Marquardt
//! driver on the normal equations ([`crate::detect::search::lsq::lm_normal`],
//! with its active set), from the masses of the linearised fit when every
//! mass of the set is free and the set is folded (one or two defects on
//! the real axis: [`SetTable::linearized`](crate::detect::misfit::SetTable::linearized), exact for noiseless data of the
//! set's own model), else from the best point of a small grid of starts
//! (`starts` per unknown mass, log-spaced, default 2). The Jacobian is
//! analytic: `dX_1/dm_l = -gamma s^2 z_l^2` with
//! `z = (I + G_JJ C)^{-1} G_J1` (see [`crate::detect::misfit`]), so one
//! Gauss-Newton step costs one residual evaluation. Sets are fitted in
//! parallel with rayon; the result is sorted by `(residual, positions)` and
//! does not depend on the number of threads.
//!
//! Only the `keep` best sets are reported (the beam search's layers keep
//! `beam`), so the sets are fitted in stages: the Gauss-Newton model at the
//! linearised start (one evaluation), then a fit to a loose tolerance, then
//! the full fit, each set going on only while it could still rank among the
//! kept (estimated from below with a margin; the kept sets' fits are the
//! full fits, the others are dropped).
//!
//! # Cost
//! Exhaustive: `C(a, p)` (interchangeable) or `a!/(a-p)!` set fits, `a` the
//! number of allowed positions, `p` the number of unknown positions; each fit
//! is one linearised solve and one evaluation (folded sets), or
//! `starts^f` grid evaluations plus typically 3 to 10 screening LM
//! evaluations (`f` unknown masses), each evaluation `O(nodes k^3)`; the
//! few sets fitted further take 5 to 30 more each.
//!
//! When the count exceeds `max_sets`, a **beam search** (coarse-to-fine in
//! the number of defects) replaces it: place the unknown-position defects one
//! at a time, fitting all masses placed so far at every allowed position for
//! each of the `beam` best partial hypotheses, and keep the `beam` best. Cost
//! `about beam * p * a` set fits instead of `C(a, p)`, followed by up to
//! `refine_sweeps` sweeps of single-position moves (`p * a` set fits each)
//! from the four best hypotheses (none when the beam's best is below
//! `stop_below`); it is exact when every
//! prefix of the truth ranks within the beam (true when the defects are
//! ordered by their effect on `X_1`, which falls like `s^{-4(j-1)}` with depth
//! `j`), and is not guaranteed otherwise.
//!
//! ```
//! use springmass::{Chain, Defect};
//! use springmass::detect::{data::exact::Data, misfit::{Misfit, MisfitSpec}};
//! use springmass::detect::unknowns::{DefectUnknown, MassUnknowns};
//! use springmass::detect::search::enumerate::{enumerate, EnumerateOptions};
//! let truth = Chain::paper(5)?.with_defects([
//!     Defect::Mass { at: 2, m: 3.0 }, Defect::Mass { at: 4, m: 0.5 }])?;
//! let misfit = Misfit::new(&truth.uniform(), &Data::exact(&truth), &MisfitSpec::default())?;
//! let unknowns = MassUnknowns::new(5, vec![DefectUnknown::free(0.1, 100.0); 2])?;
//! let e = enumerate(&misfit, &unknowns, &EnumerateOptions::default())?;
//! let best = &e.ranked[0];
//! assert_eq!((best.defects[0].0, best.defects[1].0), (2, 4));
//! assert!((best.defects[1].1 - 0.5).abs() < 1e-8);
//! assert_eq!(e.sets, 10);
//! # Ok::<(), springmass::Error>(())
//! ```

mod slots;

pub use slots::{fit_slots, fit_slots_from};
use slots::{fit_slots_inner, quick_slots, SCREEN_RTOL};

use crate::detect::misfit::Misfit;
use crate::detect::search::parallel;
use crate::detect::unknowns::{gen_sets, MassUnknown, MassUnknowns};
use crate::error::{Error, Result};

/// Defects `(position, mass)`.
pub type Defects = Vec<(usize, f64)>;

/// A fitted set: defects, residual, evaluations.
type Fitted = (Defects, f64, usize);

/// Options of [`enumerate`].
#[derive(Clone, Debug, PartialEq)]
pub struct EnumerateOptions {
    /// Hypotheses kept in the ranked list (default 10).
    pub keep: usize,
    /// Log-spaced starting values per unknown mass (default 2: a grid of
    /// `2^f` starts for `f` unknown masses; the best starts the LM fit) of
    /// the sets without a linearised start (three or more defects, the
    /// Bromwich line, a known mass).
    pub starts: usize,
    /// Levenberg-Marquardt iterations per set (default 60).
    pub max_iter: usize,
    /// Largest number of sets enumerated exhaustively (default 200 000);
    /// beyond it the beam search is used.
    pub max_sets: usize,
    /// Beam width of the beam search (default 16).
    pub beam: usize,
    /// Fit sets in parallel (rayon) (default true). The result is the same.
    pub parallel: bool,
    /// Beam search: refinement sweeps (one position moved at a time over all
    /// allowed places, masses refitted) from the 4 best hypotheses (default 4).
    pub refine_sweeps: usize,
    /// Beam search: skip the refinement when the beam's best residual is
    /// at most this (default `None`: always refine). A caller that knows
    /// the data's error floor sets it: no set can beat such an answer by
    /// more than the data's error.
    pub stop_below: Option<f64>,
}

impl Default for EnumerateOptions {
    fn default() -> Self {
        EnumerateOptions {
            keep: 10,
            starts: 2,
            max_iter: 60,
            max_sets: 200_000,
            beam: 16,
            parallel: true,
            refine_sweeps: 4,
            stop_below: None,
        }
    }
}

/// One hypothesis: defects `(position, mass)` in the order of the unknowns
/// (sorted by position when the defects are interchangeable) and its residual.
#[derive(Clone, Debug, PartialEq)]
pub struct Hypothesis {
    /// `(position, mass)` per defect.
    pub defects: Vec<(usize, f64)>,
    /// The residual `r` at the fitted masses.
    pub residual: f64,
}

/// The outcome of [`enumerate`].
#[derive(Clone, Debug, PartialEq)]
pub struct Enumeration {
    /// Best hypotheses, best first (at most `keep`).
    pub ranked: Vec<Hypothesis>,
    /// Number of position sets fitted.
    pub sets: usize,
    /// Residual evaluations.
    pub evaluations: usize,
    /// Whether every set was enumerated (false: beam search).
    pub exhaustive: bool,
}

/// Number of position sets of the exhaustive enumeration, `None` on overflow.
pub fn count_sets(unknowns: &MassUnknowns) -> Option<usize> {
    let a = unknowns.allowed_positions().len();
    let p = unknowns.free_positions().len();
    let mut c: u128 = 1;
    for i in 0..p {
        c = c.checked_mul((a - i) as u128)?;
        if unknowns.interchangeable() {
            c /= (i + 1) as u128;
        }
    }
    usize::try_from(c).ok()
}

/// Enumerate position sets, fit the masses of each, rank by residual.
///
/// # Errors
/// `keep`, `starts`, `beam` or `max_iter` zero (fields `search.*`).
pub fn enumerate(
    misfit: &Misfit,
    unknowns: &MassUnknowns,
    opts: &EnumerateOptions,
) -> Result<Enumeration> {
    for (name, v) in [
        ("search.keep", opts.keep),
        ("search.starts", opts.starts),
        ("search.beam", opts.beam),
        ("search.max_iter", opts.max_iter),
    ] {
        if v == 0 {
            return Err(Error::invalid(name, v, ">= 1"));
        }
    }
    if unknowns.n() != misfit.chain().n() {
        return Err(Error::invalid(
            "unknowns.n",
            unknowns.n(),
            format!("the model chain's n = {}", misfit.chain().n()),
        ));
    }
    match count_sets(unknowns) {
        Some(c) if c <= opts.max_sets => exhaustive(misfit, unknowns, opts),
        _ => beam(misfit, unknowns, opts),
    }
}

fn exhaustive(
    misfit: &Misfit,
    unknowns: &MassUnknowns,
    opts: &EnumerateOptions,
) -> Result<Enumeration> {
    let allowed = unknowns.allowed_positions();
    let p = unknowns.free_positions().len();
    let mut sets: Vec<Vec<usize>> = Vec::new();
    let mut cur = Vec::with_capacity(p);
    gen_sets(
        &allowed,
        p,
        unknowns.interchangeable(),
        0,
        &mut cur,
        &mut sets,
    );
    let fitted = fit_sets_best(
        misfit,
        unknowns,
        &sets,
        unknowns.free_positions().len(),
        opts,
        opts.keep,
    );
    Ok(finish(unknowns, fitted, sets.len(), true, opts.keep))
}

/// The slots `(position, mass)` of the known-position defects and of the
/// first `placed` unknown-position defects, in defect order.
fn slots_for(
    unknowns: &MassUnknowns,
    positions: &[usize],
    placed: usize,
) -> Vec<(usize, MassUnknown)> {
    let free = unknowns.free_positions();
    unknowns
        .defects()
        .iter()
        .enumerate()
        .filter_map(|(i, d)| match d.at {
            Some(at) => Some((at, d.mass)),
            None => {
                let t = free.iter().position(|&f| f == i).expect("free index");
                (t < placed).then(|| (positions[t], d.mass))
            }
        })
        .collect()
}

fn finish(
    unknowns: &MassUnknowns,
    fitted: Vec<Fitted>,
    sets: usize,
    exhaustive: bool,
    keep: usize,
) -> Enumeration {
    let evaluations = fitted.iter().map(|f| f.2).sum();
    let mut ranked: Vec<Hypothesis> = fitted
        .into_iter()
        .map(|(mut defects, residual, _)| {
            if unknowns.interchangeable() && unknowns.free_positions().len() == unknowns.k() {
                defects.sort_by_key(|d| d.0);
            }
            Hypothesis { defects, residual }
        })
        .collect();
    sort_hyps(&mut ranked);
    ranked.truncate(keep);
    Enumeration {
        ranked,
        sets,
        evaluations,
        exhaustive,
    }
}

fn sort_hyps(h: &mut [Hypothesis]) {
    h.sort_by(|a, b| {
        a.residual.total_cmp(&b.residual).then_with(|| {
            let pa: Vec<usize> = a.defects.iter().map(|d| d.0).collect();
            let pb: Vec<usize> = b.defects.iter().map(|d| d.0).collect();
            pa.cmp(&pb)
        })
    });
}

/// A scored position set: the positions in order of placement, the fitted
/// defects and the residual.
type Scored = (Vec<usize>, Defects, f64);

fn beam(misfit: &Misfit, unknowns: &MassUnknowns, opts: &EnumerateOptions) -> Result<Enumeration> {
    let allowed = unknowns.allowed_positions();
    let p = unknowns.free_positions().len();
    let comb = unknowns.interchangeable();
    if p == 0 {
        let (d, r, e) = fit_slots(misfit, &slots_for(unknowns, &[], 0), opts);
        return Ok(finish(unknowns, vec![(d, r, e)], 1, true, opts.keep));
    }
    let mut beam: Vec<Vec<usize>> = vec![Vec::new()];
    let mut sets = 0;
    let mut evaluations = 0;
    let mut last: Vec<Scored> = Vec::new();
    for t in 0..p {
        let cands = beam_candidates(&beam, &allowed, comb);
        let width = opts.beam.max(opts.keep);
        let fitted = fit_sets_best(misfit, unknowns, &cands, t + 1, opts, width);
        sets += cands.len();
        evaluations += fitted.iter().map(|f| f.2).sum::<usize>();
        let mut scored: Vec<Scored> = cands
            .into_iter()
            .zip(fitted)
            .map(|(c, (d, r, _))| (c, d, r))
            .collect();
        scored.sort_by(|a, b| a.2.total_cmp(&b.2).then_with(|| a.0.cmp(&b.0)));
        scored.truncate(width);
        beam = scored.iter().map(|s| s.0.clone()).collect();
        last = scored;
    }
    let mut pool = last;
    let settled = matches!((opts.stop_below, pool.first()), (Some(bar), Some(b)) if b.2 <= bar);
    if !settled {
        let (s, e) = refine(misfit, unknowns, opts, &allowed, &mut pool);
        sets += s;
        evaluations += e;
    }
    pool.sort_by(|a, b| a.2.total_cmp(&b.2).then_with(|| a.0.cmp(&b.0)));
    pool.truncate(opts.keep);
    let fitted = pool.into_iter().map(|(_, d, r)| (d, r, 0)).collect();
    let mut out = finish(unknowns, fitted, sets, false, opts.keep);
    out.evaluations = evaluations;
    Ok(out)
}

/// The beam's next candidates: every set of the beam with one more allowed
/// position (the sets equal up to order once when the defects are
/// interchangeable, `comb`).
fn beam_candidates(beam: &[Vec<usize>], allowed: &[usize], comb: bool) -> Vec<Vec<usize>> {
    let mut cands: Vec<Vec<usize>> = Vec::new();
    for b in beam {
        for &a in allowed {
            if b.contains(&a) {
                continue;
            }
            let mut c = b.clone();
            c.push(a);
            if comb {
                let mut s = c.clone();
                s.sort_unstable();
                if cands.iter().any(|x| {
                    let mut y = x.clone();
                    y.sort_unstable();
                    y == s
                }) {
                    continue;
                }
            }
            cands.push(c);
        }
    }
    cands
}

/// The beam's refinement: from each of the best few hypotheses of `pool`,
/// move one unknown position at a time to every allowed place (masses
/// refitted) while that lowers the residual; this repairs a beam that
/// placed an early defect where a later one would have explained the data
/// better. Every new set goes into `pool`; returns the sets fitted and the
/// evaluations.
fn refine(
    misfit: &Misfit,
    unknowns: &MassUnknowns,
    opts: &EnumerateOptions,
    allowed: &[usize],
    pool: &mut Vec<Scored>,
) -> (usize, usize) {
    let p = unknowns.free_positions().len();
    let comb = unknowns.interchangeable();
    let (mut sets, mut evaluations) = (0, 0);
    let starts: Vec<Vec<usize>> = pool.iter().take(4).map(|s| s.0.clone()).collect();
    for start in starts {
        let mut cur = start;
        let mut cur_r = pool
            .iter()
            .find(|s| s.0 == cur)
            .map_or(f64::INFINITY, |s| s.2);
        for _sweep in 0..opts.refine_sweeps {
            let mut improved = false;
            for t in 0..p {
                let cands: Vec<Vec<usize>> = allowed
                    .iter()
                    .filter(|a| !cur.contains(a))
                    .map(|&a| {
                        let mut c = cur.clone();
                        c[t] = a;
                        c
                    })
                    .collect();
                let fitted = fit_sets(misfit, unknowns, &cands, p, opts);
                sets += cands.len();
                evaluations += fitted.iter().map(|f| f.2).sum::<usize>();
                for (c, (d, r, _)) in cands.into_iter().zip(fitted) {
                    if r < cur_r {
                        cur_r = r;
                        cur = c.clone();
                        improved = true;
                    }
                    let key = canon(&c, comb);
                    if !pool.iter().any(|x| canon(&x.0, comb) == key) {
                        pool.push((c, d, r));
                    }
                }
            }
            if !improved {
                break;
            }
        }
    }
    (sets, evaluations)
}

fn canon(c: &[usize], comb: bool) -> Vec<usize> {
    let mut v = c.to_vec();
    if comb {
        v.sort_unstable();
    }
    v
}

/// [`fit_slots`] for every position set of `sets` (slots from
/// [`slots_for`] with `placed` positions placed), in parallel when
/// `opts.parallel` (same results either way, in the order of `sets`).
fn fit_sets(
    misfit: &Misfit,
    unknowns: &MassUnknowns,
    sets: &[Vec<usize>],
    placed: usize,
    opts: &EnumerateOptions,
) -> Vec<Fitted> {
    let fit_one = |set: &Vec<usize>| fit_slots(misfit, &slots_for(unknowns, set, placed), opts);
    parallel::map(sets, opts.parallel, parallel::MIN_SETS, fit_one)
}

/// How far [`fit_sets_best`] has fitted a set.
#[derive(Clone, Copy, PartialEq)]
enum Stage {
    /// The Gauss-Newton model at the linearised start ([`quick_slots`]).
    Quick,
    /// The fit to the screening tolerance [`SCREEN_RTOL`].
    Screened,
    /// The full fit ([`fit_slots`]).
    Full,
}

/// One set in [`fit_sets_best`]: its fit so far, an upper bound of its
/// full fit's residual (a residual the full fit starts from or passes
/// through) and an estimate from below.
struct Staged {
    fit: Fitted,
    stage: Stage,
    upper: f64,
    lower: f64,
}

/// [`fit_sets`] where only the `need` best sets matter (the rest are
/// ranked after them and dropped): the sets are fitted in stages, and only
/// those that could still be among the `need` best go on to the next:
///
/// 1. a folded set with every mass free: the Gauss-Newton model of its
///    residual at the linearised start ([`quick_slots`]: one evaluation);
///    the residual there bounds the full fit's from above (the fit starts
///    there), and [`QUICK_MARGIN`] times the model's minimum is taken as
///    its bound from below; other sets start at stage 2;
/// 2. the fit to the screening tolerance [`SCREEN_RTOL`] (the full fit's
///    iterations, stopped earlier): its main fit's residual (before the
///    retry of [`fit_slots`]) bounds the full fit's from above, half its
///    residual from below;
/// 3. the full fit, from scratch: the same fit, values and residual as
///    [`fit_sets`] gives the set.
///
/// At each round `t` is the `need`-th smallest upper bound, at least the
/// `need`-th best residual of the full fits, and every set whose bound from
/// below is at most `t` goes one stage on; the rounds end when no set can.
/// The other sets keep the fit of their last stage, whose residual is above
/// `t`. The bounds from below are estimates: over Table 1's systems, exact
/// and noisy (relative noise up to `1e-2`), the full fit's residual was at
/// least 0.35 times the linearised start's model minimum, and within
/// `1e-3` (relative) of the screened residual.
fn fit_sets_best(
    misfit: &Misfit,
    unknowns: &MassUnknowns,
    sets: &[Vec<usize>],
    placed: usize,
    opts: &EnumerateOptions,
    need: usize,
) -> Vec<Fitted> {
    // few sets: staging saves nothing
    if sets.len() <= 4 * need {
        return fit_sets(misfit, unknowns, sets, placed, opts);
    }
    let slots = |i: usize| slots_for(unknowns, &sets[i], placed);
    let screen = |i: usize| {
        let (fit, upper) = fit_slots_inner(misfit, &slots(i), None, opts, SCREEN_RTOL);
        let lower = 0.5 * fit.1;
        Staged {
            fit,
            stage: Stage::Screened,
            upper,
            lower,
        }
    };
    let first = |i: usize| match quick_slots(misfit, &slots(i)) {
        Some((fit, lower)) => Staged {
            upper: fit.1,
            fit,
            stage: Stage::Quick,
            lower,
        },
        None => screen(i),
    };
    let next = |i: usize, old: &Staged| {
        let mut new = match old.stage {
            Stage::Quick => screen(i),
            _ => {
                let fit = fit_slots(misfit, &slots(i), opts);
                Staged {
                    upper: fit.1,
                    lower: fit.1,
                    fit,
                    stage: Stage::Full,
                }
            }
        };
        new.fit.2 += old.fit.2;
        new
    };
    let idx: Vec<usize> = (0..sets.len()).collect();
    let mut staged: Vec<Staged> =
        parallel::map(&idx, opts.parallel, parallel::MIN_SETS, |&i| first(i));
    let mut upper: Vec<f64> = Vec::with_capacity(sets.len());
    loop {
        upper.clear();
        upper.extend(staged.iter().map(|s| s.upper));
        let (_, &mut t, _) = upper.select_nth_unstable_by(need.max(1) - 1, f64::total_cmp);
        let mut go: Vec<usize> = (0..sets.len())
            .filter(|&i| staged[i].stage != Stage::Full && staged[i].lower <= t)
            .collect();
        // the most promising first: their fits lower t for the others
        go.sort_by(|&a, &b| staged[a].lower.total_cmp(&staged[b].lower).then(a.cmp(&b)));
        go.truncate(need.max(1));
        if go.is_empty() {
            break;
        }
        let done: Vec<Staged> = parallel::map(
            &go,
            opts.parallel && sets.len() >= parallel::MIN_SETS,
            2,
            |&i| next(i, &staged[i]),
        );
        for (&i, s) in go.iter().zip(done) {
            staged[i] = s;
        }
    }
    staged.into_iter().map(|s| s.fit).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chain::{Chain, Defect};
    use crate::detect::data::exact::Data;
    use crate::detect::misfit::MisfitSpec;
    use crate::detect::unknowns::DefectUnknown;

    fn setup(n: usize, defs: &[(usize, f64)]) -> Misfit {
        let truth = Chain::paper(n)
            .unwrap()
            .with_defects(defs.iter().map(|&(at, m)| Defect::Mass { at, m }))
            .unwrap();
        Misfit::new(
            &truth.uniform(),
            &Data::exact(&truth),
            &MisfitSpec::default(),
        )
        .unwrap()
    }

    #[test]
    fn counts() {
        let u = MassUnknowns::new(20, vec![DefectUnknown::free(0.1, 10.0); 2]).unwrap();
        assert_eq!(count_sets(&u), Some(190));
        let u = MassUnknowns::new(
            20,
            vec![
                DefectUnknown {
                    at: None,
                    mass: MassUnknown::Known(3.0),
                },
                DefectUnknown {
                    at: None,
                    mass: MassUnknown::Known(7.0),
                },
            ],
        )
        .unwrap();
        assert_eq!(count_sets(&u), Some(380));
        let u = MassUnknowns::new(1000, vec![DefectUnknown::free(0.1, 10.0); 5]).unwrap();
        assert!(count_sets(&u).unwrap() > 1_000_000_000_000);
    }

    #[test]
    fn serial_equals_parallel_and_known_masses_are_ordered() {
        let mis = setup(12, &[(3, 3.0), (9, 7.0)]);
        let u = MassUnknowns::new(
            12,
            vec![
                DefectUnknown {
                    at: None,
                    mass: MassUnknown::Known(7.0),
                },
                DefectUnknown {
                    at: None,
                    mass: MassUnknown::Known(3.0),
                },
            ],
        )
        .unwrap();
        let par = enumerate(&mis, &u, &EnumerateOptions::default()).unwrap();
        let ser = enumerate(
            &mis,
            &u,
            &EnumerateOptions {
                parallel: false,
                ..EnumerateOptions::default()
            },
        )
        .unwrap();
        assert_eq!(par, ser);
        assert_eq!(par.sets, 132);
        assert_eq!(par.ranked[0].defects, vec![(9, 7.0), (3, 3.0)]);
        assert!(par.ranked[0].residual < 1e-28);
        assert!(par.ranked[1].residual > 0.0);
    }

    #[test]
    fn screened_ranking_equals_every_set_fitted_in_full() {
        // Table 1's Systems 2-4 (n = 10, 20), exact and with simulated,
        // noisy data: the kept hypotheses are the full fits' best, the same
        // to the last bit as when every set is fitted in full
        // (the Bromwich line: no linearised start, screened and full fits)
        use crate::detect::misfit::MisfitKind::{Bromwich, RealAxis};
        for (sys, noise, kind) in [
            (3, 0.0, RealAxis),
            (4, 0.0, RealAxis),
            (3, 1e-4, RealAxis),
            (4, 1e-3, RealAxis),
            (2, 1e-2, RealAxis),
            (3, 0.0, Bromwich),
            (4, 1e-4, Bromwich),
        ] {
            let truth = crate::scenes::table1(sys).unwrap();
            let data = if noise > 0.0 {
                Data::simulated(&truth, 200.0, 0.05, noise, 7).unwrap()
            } else {
                Data::exact(&truth)
            };
            let spec = MisfitSpec {
                kind,
                ..MisfitSpec::default()
            };
            let mis = Misfit::new(&truth.uniform(), &data, &spec).unwrap();
            let n = truth.n();
            let u = MassUnknowns::new(n, vec![DefectUnknown::free(0.1, 100.0); 2]).unwrap();
            for keep in [1, 5, 10] {
                let opts = EnumerateOptions {
                    keep,
                    parallel: false,
                    ..EnumerateOptions::default()
                };
                let e = enumerate(&mis, &u, &opts).unwrap();
                let mut sets = Vec::new();
                gen_sets(
                    &u.allowed_positions(),
                    2,
                    true,
                    0,
                    &mut Vec::new(),
                    &mut sets,
                );
                let full = fit_sets(&mis, &u, &sets, 2, &opts);
                let spent: usize = full.iter().map(|f| f.2).sum();
                let reference = finish(&u, full, sets.len(), true, keep);
                assert_eq!(
                    e.ranked, reference.ranked,
                    "S{sys} noise {noise} keep {keep}"
                );
                // exact data: most sets stop at the first stages (noisy
                // data bring every set's residual close to the best's)
                if noise == 0.0 {
                    assert!(
                        e.evaluations < spent,
                        "S{sys}: {} >= {spent}",
                        e.evaluations
                    );
                }
            }
        }
    }

    #[test]
    fn beam_search_finds_a_shallow_pair() {
        let mis = setup(20, &[(4, 5.0), (11, 2.0)]);
        let u = MassUnknowns::new(20, vec![DefectUnknown::free(0.1, 100.0); 2]).unwrap();
        let opts = EnumerateOptions {
            max_sets: 10,
            beam: 4,
            keep: 4,
            ..EnumerateOptions::default()
        };
        let e = enumerate(&mis, &u, &opts).unwrap();
        assert!(!e.exhaustive);
        // beam: 20 + 4 * 19 - 6 (pairs inside the beam counted once), then refinement sweeps
        assert!(e.sets >= 90, "{}", e.sets);
        let best = &e.ranked[0];
        assert_eq!(
            best.defects.iter().map(|d| d.0).collect::<Vec<_>>(),
            vec![4, 11]
        );
        assert!((best.defects[0].1 - 5.0).abs() < 1e-6 && (best.defects[1].1 - 2.0).abs() < 1e-6);
    }

    #[test]
    fn known_position_with_free_mass() {
        let mis = setup(10, &[(2, 4.0), (6, 0.3)]);
        let u = MassUnknowns::new(
            10,
            vec![
                DefectUnknown {
                    at: Some(6),
                    mass: MassUnknown::Free { lo: 0.1, hi: 10.0 },
                },
                DefectUnknown::free(0.1, 10.0),
            ],
        )
        .unwrap();
        let e = enumerate(&mis, &u, &EnumerateOptions::default()).unwrap();
        assert_eq!(e.sets, 9);
        let d = &e.ranked[0].defects;
        assert_eq!((d[0].0, d[1].0), (6, 2));
        assert!((d[0].1 - 0.3).abs() < 1e-8 && (d[1].1 - 4.0).abs() < 1e-8);
    }
}
