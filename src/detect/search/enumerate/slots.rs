//! The fit of the unknown masses of one position set (its slots): in
//! `u = ln m` inside their bounds by the bounded Levenberg-Marquardt driver on
//! the normal equations, from the linearised start of a folded set or the best
//! point of a small grid, in stages (a quick Gauss-Newton estimate, a loose
//! fit, the full fit) with a retry from the uniform masses.

use super::{EnumerateOptions, Fitted};
use crate::detect::misfit::{Misfit, SetTable};
use crate::detect::search::lsq::{lm_normal, scratch, LmOptions, NormalEquations};
use crate::detect::unknowns::MassUnknown;
use crate::error::Result;

/// The bound from below of stage 1 of [`fit_sets_best`](super::fit_sets_best): this fraction of
/// the minimum of the Gauss-Newton model at the linearised start.
pub(super) const QUICK_MARGIN: f64 = 0.1;

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

/// Stage 1 of [`fit_sets_best`](super::fit_sets_best) for a folded set whose every mass is free:
/// at its linearised start ([`linear_start`], where [`fit_slots`] starts),
/// the defects with their residual `r0` and one evaluation, and the bound
/// from below, [`QUICK_MARGIN`] times the Gauss-Newton model's minimum
/// `r0 - g^T H^-1 g` (`0` when `H` is singular); `None` for other sets.
pub(super) fn quick_slots(
    misfit: &Misfit,
    slots: &[(usize, MassUnknown)],
) -> Option<(Fitted, f64)> {
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

/// The relative tolerance of the screening fits of [`fit_sets_best`](super::fit_sets_best)
/// (the full fits': `1e-9`, [`slot_lm_options`]).
pub(super) const SCREEN_RTOL: f64 = 1e-4;

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
pub(super) fn fit_slots_inner(
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
pub(super) fn fitted(pos: &[usize], m: &[f64], r: f64, evals: usize) -> Fitted {
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
