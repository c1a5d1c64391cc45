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
//! the real axis: [`SetTable::linearized`], exact for noiseless data of the
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
//! from the four best hypotheses; it is exact when every
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

use crate::detect::misfit::{Misfit, SetTable};
use crate::detect::search::lsq::{lm_normal, scratch, LmOptions, NormalEquations};
use crate::detect::unknowns::{gen_sets, MassUnknown, MassUnknowns};
use crate::error::{Error, Result};
use rayon::prelude::*;

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
    let (s, e) = refine(misfit, unknowns, opts, &allowed, &mut pool);
    sets += s;
    evaluations += e;
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
    if opts.parallel {
        sets.par_iter().map(fit_one).collect()
    } else {
        sets.iter().map(fit_one).collect()
    }
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
    let mut staged: Vec<Staged> = if opts.parallel {
        idx.par_iter().map(|&i| first(i)).collect()
    } else {
        idx.iter().map(|&i| first(i)).collect()
    };
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
        let done: Vec<Staged> = if opts.parallel {
            go.par_iter().map(|&i| next(i, &staged[i])).collect()
        } else {
            go.iter().map(|&i| next(i, &staged[i])).collect()
        };
        for (&i, s) in go.iter().zip(done) {
            staged[i] = s;
        }
    }
    staged.into_iter().map(|s| s.fit).collect()
}

/// The bound from below of stage 1 of [`fit_sets_best`]: this fraction of
/// the minimum of the Gauss-Newton model at the linearised start.
const QUICK_MARGIN: f64 = 0.1;

/// The start of a folded set whose every mass is free, in `ln m` (one per
/// slot): the linearised fit's masses ([`SetTable::linearized`]) clamped
/// into their bounds (a mass change that makes the mass negative: the
/// lower bound); `None` for other sets.
fn linear_start(table: &SetTable, slots: &[(usize, MassUnknown)], base: f64) -> Option<[f64; 2]> {
    let x = table.linearized()?;
    let mut u = [0.0; 2];
    for (i, s) in slots.iter().enumerate() {
        let MassUnknown::Free { lo, hi } = s.1 else {
            return None;
        };
        let mass = base + x[i];
        u[i] = if mass > 0.0 {
            mass.ln().clamp(lo.ln(), hi.ln())
        } else {
            lo.ln()
        };
    }
    Some(u)
}

/// Stage 1 of [`fit_sets_best`] for a folded set whose every mass is free:
/// at its linearised start ([`linear_start`], where [`fit_slots`] starts),
/// the defects with their residual `r0` and one evaluation, and the bound
/// from below, [`QUICK_MARGIN`] times the Gauss-Newton model's minimum
/// `r0 - g^T H^-1 g` (`0` when `H` is singular); `None` for other sets.
fn quick_slots(misfit: &Misfit, slots: &[(usize, MassUnknown)]) -> Option<(Fitted, f64)> {
    let k = slots.len();
    if !matches!(k, 1 | 2) {
        return None;
    }
    let mut pos = [0usize; 2];
    for (p, s) in pos.iter_mut().zip(slots) {
        *p = s.0;
    }
    let table = misfit.set(&pos[..k]);
    let base = misfit.chain().mass();
    let u = linear_start(&table, slots, base)?;
    let m = [u[0].exp(), u[1].exp()];
    let dm = [m[0] - base, m[1] - base];
    let (mut g, mut h) = ([0.0; 2], [0.0; 4]);
    let r0 = table.gauss_newton(&dm[..k], &mut g[..k], &mut h[..k * k]);
    // the model's decrease g^T H^-1 g (H positive semidefinite)
    let decrease = if k == 1 {
        g[0] * g[0] / h[0]
    } else {
        let det = h[0] * h[3] - h[1] * h[2];
        (h[3] * g[0] * g[0] - 2.0 * h[1] * g[0] * g[1] + h[0] * g[1] * g[1]) / det
    };
    let lower = if decrease.is_finite() && decrease >= 0.0 {
        QUICK_MARGIN * (r0 - decrease).max(0.0)
    } else {
        0.0
    };
    let defects = pos[..k].iter().copied().zip(m).collect();
    Some(((defects, r0, 1), lower))
}

/// Slots up to which [`fit_slots`] works in stack buffers.
const STACK_K: usize = 8;

/// The relative tolerance of the full mass fits ([`slot_lm_options`]).
const FULL_RTOL: f64 = 1e-9;

/// The relative tolerance of the screening fits of [`fit_sets_best`]
/// (the full fits': `1e-9`, [`slot_lm_options`]).
const SCREEN_RTOL: f64 = 1e-4;

/// Iterations of the probe of [`fit_slots`]'s retry from the uniform mass
/// (a free mass on its lower bound): the retry goes on to convergence only
/// when the probe has gone below the first fit's residual.
const RETRY_PROBE: usize = 4;

/// The normal equations of one set's mass fit in `u = ln m` of the free
/// masses (known masses fixed): `J_u = m J_m`, so `g_u = m g_m` and
/// `(J^T J)_u = m_i m_j (J^T J)_m` (Gauss-Newton, as the driver wants).
struct SlotFit<'a> {
    table: &'a SetTable,
    base: f64,
    /// Slot of each variable.
    free: &'a [usize],
    /// Masses of all slots (the free ones set from `u` at every evaluation).
    m: &'a mut [f64],
    /// Buffers: mass changes, gradient and Gauss-Newton matrix of all slots.
    dm: &'a mut [f64],
    gk: &'a mut [f64],
    hk: &'a mut [f64],
}

impl SlotFit<'_> {
    fn set(&mut self, u: &[f64]) {
        for (&s, &v) in self.free.iter().zip(u) {
            self.m[s] = v.exp();
        }
        for (d, &m) in self.dm.iter_mut().zip(self.m.iter()) {
            *d = m - self.base;
        }
    }
}

impl NormalEquations for SlotFit<'_> {
    fn chi2(&mut self, u: &[f64]) -> Result<f64> {
        self.set(u);
        Ok(self.table.residual(self.dm))
    }

    fn normal(&mut self, u: &[f64], g: &mut [f64], h: &mut [f64]) -> Result<f64> {
        self.set(u);
        let r = self.table.gauss_newton(self.dm, self.gk, self.hk);
        let (k, f) = (self.m.len(), self.free.len());
        for (i, &si) in self.free.iter().enumerate() {
            g[i] = self.m[si] * self.gk[si];
            for (j, &sj) in self.free.iter().enumerate() {
                h[i * f + j] = self.m[si] * self.m[sj] * self.hk[si * k + sj];
            }
        }
        Ok(r)
    }

    fn pieces_are_cheap(&self) -> bool {
        true
    }
}

/// The driver's settings of the full mass fits: `rtol = 1e-9` (on the decrease
/// of the last step or the one predicted for the next,
/// [`LmOptions::predicted_stop`]), steps below `1e-13` in `ln m` stop, `mu`
/// from `1e-3`, times 0.2 or 5, in `[1e-15, 1e12]`.
fn slot_lm_options(max_iter: usize) -> LmOptions {
    LmOptions {
        max_iter,
        rtol: FULL_RTOL,
        xtol: 0.0,
        xtol_abs: 1e-13,
        mu0: 1e-3,
        mu_down: 0.2,
        mu_up: 5.0,
        mu_min: 1e-15,
        mu_max: 1e12,
        predicted_stop: true,
    }
}

/// Fit the unknown masses of the slots (positions fixed). Returns the
/// defects `(position, mass)`, the residual and the evaluations used.
///
/// The linearised fit's masses ([`SetTable::linearized`], when every mass
/// is free and the set folded) or else the best point of a log-spaced grid
/// of starts (`opts.starts` per free mass, at most 729 points) start the
/// bounded Levenberg-Marquardt driver
/// ([`lm_normal`]) in `u = ln m`, on the normal equations of the tabled
/// kernel ([`SetTable::gauss_newton`]: one evaluation per iteration).
pub fn fit_slots(
    misfit: &Misfit,
    slots: &[(usize, MassUnknown)],
    opts: &EnumerateOptions,
) -> Fitted {
    fit_slots_inner(misfit, slots, None, opts, FULL_RTOL).0
}

/// [`fit_slots`] from the given masses `start` (one per slot, the known
/// ones ignored, the free ones clamped into their bounds) instead of the
/// best point of the grid: the kernel's fit from another start, to look for
/// another basin of a set's chi-square.
pub fn fit_slots_from(
    misfit: &Misfit,
    slots: &[(usize, MassUnknown)],
    start: &[f64],
    opts: &EnumerateOptions,
) -> Fitted {
    fit_slots_inner(misfit, slots, Some(start), opts, FULL_RTOL).0
}

/// [`fit_slots`] and [`fit_slots_from`] with the driver's relative
/// tolerance `rtol`; also returns the residual of the main fit (before the
/// retry from the uniform mass), an upper bound of the residual the same
/// fit reaches with a smaller `rtol`.
fn fit_slots_inner(
    misfit: &Misfit,
    slots: &[(usize, MassUnknown)],
    start: Option<&[f64]>,
    opts: &EnumerateOptions,
    rtol: f64,
) -> (Fitted, f64) {
    let k = slots.len();
    let (mut pos_stack, mut pos_heap) = ([0usize; STACK_K], Vec::new());
    let pos = scratch(&mut pos_stack, &mut pos_heap, k, 0);
    for (p, s) in pos.iter_mut().zip(slots) {
        *p = s.0;
    }
    let pos: &[usize] = pos;
    let table = misfit.set(pos);
    // f64 buffers: m, dm, gk, hk, u
    let (mut stack, mut heap) = ([0.0f64; 5 * STACK_K + STACK_K * STACK_K], Vec::new());
    let buf = scratch(&mut stack, &mut heap, 5 * k + k * k, 0.0);
    let (m, buf) = buf.split_at_mut(k);
    let (dm, buf) = buf.split_at_mut(k);
    let (gk, buf) = buf.split_at_mut(k);
    let (hk, u) = buf.split_at_mut(k * k);
    let (mut free_stack, mut free_heap) = ([(0usize, 0.0f64, 0.0f64); STACK_K], Vec::new());
    let free = scratch(&mut free_stack, &mut free_heap, k, (0, 0.0, 0.0));
    let f = first_masses(slots, m, free);
    let free: &[(usize, f64, f64)] = &free[..f];
    let base = misfit.chain().mass();
    if f == 0 {
        set_dm(dm, m, base);
        let r = table.residual(dm);
        return (fitted(pos, m, r, 1), r);
    }
    let (best, mut evals, linear) = first_point(&table, slots, free, start, opts, base, m, dm, u);
    let u = &mut u[..f];
    let (mut bounds_stack, mut bounds_heap) = ([(0.0f64, 0.0f64); STACK_K], Vec::new());
    let bounds = scratch(&mut bounds_stack, &mut bounds_heap, f, (0.0, 0.0));
    let (mut slots_stack, mut slots_heap) = ([0usize; STACK_K], Vec::new());
    let free_slots = scratch(&mut slots_stack, &mut slots_heap, f, 0);
    for ((b, s), &(slot, lo, hi)) in bounds.iter_mut().zip(free_slots.iter_mut()).zip(free) {
        (*b, *s) = ((lo, hi), slot);
    }
    let bounds: &[(f64, f64)] = bounds;
    let mut problem = SlotFit {
        table: &table,
        base,
        free: free_slots,
        m,
        dm,
        gk,
        hk,
    };
    let lm_opts = LmOptions {
        rtol,
        ..slot_lm_options(opts.max_iter)
    };
    let main = main_fit(
        &mut problem,
        u,
        bounds,
        &lm_opts,
        (linear, best),
        &mut evals,
    );
    let wall = misfit.chain().n();
    let r = retry_uniform(
        &mut problem,
        u,
        bounds,
        pos,
        wall,
        &lm_opts,
        main,
        &mut evals,
    );
    problem.set(u);
    (fitted(pos, problem.m, r, evals), main)
}

/// The driver's first point `u` (as `ln m` of the free masses): on a folded
/// set with every mass free, the linearised fit's masses, clamped into the
/// bounds (a mass change that makes the mass negative: its lower bound);
/// else the given start, or the best of a grid of starts (at most 729
/// points). Returns the residual there (infinite when not evaluated), the
/// evaluations and whether the linearised fit gave it.
#[allow(clippy::too_many_arguments)]
#[inline]
fn first_point(
    table: &SetTable,
    slots: &[(usize, MassUnknown)],
    free: &[(usize, f64, f64)],
    start: Option<&[f64]>,
    opts: &EnumerateOptions,
    base: f64,
    m: &mut [f64],
    dm: &mut [f64],
    u: &mut [f64],
) -> (f64, usize, bool) {
    let linear = match start {
        None if free.len() == slots.len() => linear_start(table, slots, base),
        _ => None,
    };
    if let Some(lu) = linear {
        for (v, &(slot, _, _)) in u.iter_mut().zip(free) {
            *v = lu[slot];
        }
        (f64::INFINITY, 0, true)
    } else if let Some(start) = start {
        for (v, &(slot, lo, hi)) in u.iter_mut().zip(free) {
            *v = start
                .get(slot)
                .filter(|m| m.is_finite() && **m > 0.0)
                .map_or(0.5 * (lo + hi), |m| m.ln().clamp(lo, hi));
            m[slot] = v.exp();
        }
        set_dm(dm, m, base);
        (table.residual(dm), 1, false)
    } else {
        let (best, evals) = grid_start(table, free, opts.starts, base, m, dm, u);
        (best, evals, false)
    }
}

/// The slots' first masses into `m`: the known ones, and the geometric
/// middle of the bounds of the free ones, whose `(slot, ln lo, ln hi)` go
/// into `free`. Returns the number of free masses.
#[inline]
fn first_masses(
    slots: &[(usize, MassUnknown)],
    m: &mut [f64],
    free: &mut [(usize, f64, f64)],
) -> usize {
    let mut f = 0;
    for (i, s) in slots.iter().enumerate() {
        m[i] = match s.1 {
            MassUnknown::Known(m) => m,
            MassUnknown::Free { lo, hi } => {
                free[f] = (i, lo.ln(), hi.ln());
                f += 1;
                (lo * hi).sqrt()
            }
        };
    }
    f
}

/// The mass changes `dm = m - base`.
#[inline]
fn set_dm(dm: &mut [f64], m: &[f64], base: f64) {
    for (d, &m) in dm.iter_mut().zip(m) {
        *d = m - base;
    }
}

/// The defects `(position, mass)` of a fit, with its residual and evaluations.
fn fitted(pos: &[usize], m: &[f64], r: f64, evals: usize) -> Fitted {
    (
        pos.iter().copied().zip(m.iter().copied()).collect(),
        r,
        evals,
    )
}

/// The best point of a log-spaced grid of `starts` values per free mass
/// (fewer when that makes more than 729 points) into `u` (as `ln m`);
/// returns its residual and the evaluations.
#[inline]
fn grid_start(
    table: &SetTable,
    free: &[(usize, f64, f64)],
    starts: usize,
    base: f64,
    m: &mut [f64],
    dm: &mut [f64],
    u: &mut [f64],
) -> (f64, usize) {
    let f = free.len();
    let mut g = starts;
    while g > 1 && g.checked_pow(f as u32).is_none_or(|t| t > 729) {
        g -= 1;
    }
    let total = g.pow(f as u32);
    let mut best = f64::INFINITY;
    let mut evals = 0;
    for idx in 0..total {
        let mut rem = idx;
        for &(slot, lo, hi) in free {
            let i = rem % g;
            rem /= g;
            m[slot] = (lo + (hi - lo) * (i as f64 + 0.5) / g as f64).exp();
        }
        set_dm(dm, m, base);
        let r = table.residual(dm);
        evals += 1;
        if r < best {
            best = r;
            for (v, &(slot, _, _)) in u.iter_mut().zip(free) {
                *v = m[slot].ln();
            }
        }
    }
    (best, evals)
}

/// The main fit from `u` (the first point: linearised or not, and its
/// residual `best`); returns its residual. The grid's best is inside the
/// bounds and gives a finite chi^2, so the driver cannot fail; a failure
/// keeps the grid's best.
#[inline]
fn main_fit(
    problem: &mut SlotFit,
    u: &mut [f64],
    bounds: &[(f64, f64)],
    lm_opts: &LmOptions,
    (linear, best): (bool, f64),
    evals: &mut usize,
) -> f64 {
    match lm_normal(problem, u, bounds, lm_opts) {
        Ok(rep) => {
            *evals += rep.evaluations;
            rep.chi2
        }
        Err(_) if linear => {
            *evals += 1;
            problem.chi2(u).unwrap_or(f64::MAX)
        }
        Err(_) => best,
    }
}

/// A free mass on its lower bound after the main fit (residual `r`): retry
/// from the uniform mass and keep the better (into `u`); returns the
/// residual kept. For a defect on the last mass (next to the far wall, at
/// position `wall`) the kernel's landscape in ln m has a second basin at
/// the lower bound, which the grid's best can fall into: that retry runs to
/// convergence. Elsewhere (mostly wrong sets, whose masses end on a bound
/// from every start: 60 of System 3's 190 sets, none improved) it is a
/// probe of `RETRY_PROBE` iterations, continued only when it has gone below
/// the first fit's residual.
#[allow(clippy::too_many_arguments)]
fn retry_uniform(
    problem: &mut SlotFit,
    u: &mut [f64],
    bounds: &[(f64, f64)],
    pos: &[usize],
    wall: usize,
    lm_opts: &LmOptions,
    r: f64,
    evals: &mut usize,
) -> f64 {
    let at_lo = |(v, &(lo, _)): (&f64, &(f64, f64))| (v - lo).abs() < 1e-9;
    let on_bound = u.iter().zip(bounds).any(at_lo);
    if !on_bound {
        return r;
    }
    let at_wall = u
        .iter()
        .zip(bounds)
        .zip(problem.free)
        .any(|(vb, &slot)| at_lo(vb) && pos[slot] == wall);
    let f = u.len();
    let mut u2_stack = [0.0f64; STACK_K];
    let mut u2_heap = Vec::new();
    let u2 = scratch(&mut u2_stack, &mut u2_heap, f, 0.0);
    for (v, &(lo, hi)) in u2.iter_mut().zip(bounds) {
        *v = problem.base.ln().clamp(lo, hi);
    }
    let probe = LmOptions {
        max_iter: if at_wall {
            lm_opts.max_iter
        } else {
            RETRY_PROBE.min(lm_opts.max_iter)
        },
        ..*lm_opts
    };
    let Ok(rep) = lm_normal(problem, u2, bounds, &probe) else {
        return r;
    };
    *evals += rep.evaluations;
    let mut r2 = rep.chi2;
    if r2 < r && !rep.converged {
        if let Ok(rep) = lm_normal(problem, u2, bounds, lm_opts) {
            *evals += rep.evaluations;
            r2 = rep.chi2;
        }
    }
    if r2 < r {
        u.copy_from_slice(u2);
        return r2;
    }
    r
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
