//! One simulation of every mass's response to the blow, for the screen
//! ([`super::Screen`]) and the time misfit's saved states: the record's
//! grid ([`TimeGrid`]), sparse Taylor stepping of the grounded chain
//! ([`simulate`], exact to rounding as [`crate::time::simulate`]'s `Rk`)
//! and the states saved along it to restart from ([`Saved`]).

use super::kernel::{self, max_abs};
use crate::chain::Chain;
use crate::error::{Error, Result};
/// Largest number of stored samples (masses x internal steps) of one
/// simulation; more candidates are screened in chunks.
pub(super) const MAX_STORED: usize = 1 << 23;

/// Most internal steps per record step of a [`TimeGrid`].
pub(crate) const MAX_SUB: usize = 256;

/// The uniform grid behind a record: internal steps of `dt`, the record's
/// samples every `sub` steps from step `first`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TimeGrid {
    /// Internal step.
    pub dt: f64,
    /// Internal steps per record step.
    pub sub: usize,
    /// Internal index of the first sample.
    pub first: usize,
    /// Number of record samples.
    pub samples: usize,
}

impl TimeGrid {
    /// The grid of the record times `t` for `chain`: `None` unless `t` is
    /// uniform (to `1e-9` of its step) and starts at a multiple of the step
    /// at or after 0. The internal step divides the record's so that
    /// `dt omega_max <= 1` (`omega_max` Gershgorin's bound on `chain`'s
    /// frequencies); `None` too where that takes more than `MAX_SUB` (256)
    /// internal steps per record step (a record far too coarse for the
    /// chain, which its modal sum serves at any step).
    pub fn new(t: &[f64], chain: &Chain) -> Option<TimeGrid> {
        let n = t.len();
        if n < 3 {
            return None;
        }
        let step = (t[n - 1] - t[0]) / (n - 1) as f64;
        if !(step > 0.0 && step.is_finite()) {
            return None;
        }
        if t.iter()
            .enumerate()
            .any(|(i, &ti)| (ti - (t[0] + i as f64 * step)).abs() > 1e-9 * step)
        {
            return None;
        }
        let w = omega_max(chain);
        let sub = (step * w).ceil().max(1.0);
        if sub > MAX_SUB as f64 {
            return None;
        }
        let sub = sub as usize;
        let dt = step / sub as f64;
        let f = t[0] / dt;
        if f < -1e-9 || (f - f.round()).abs() > 1e-6 || f > 1e9 {
            return None;
        }
        Some(TimeGrid {
            dt,
            sub,
            first: f.round().max(0.0) as usize,
            samples: n,
        })
    }

    /// Internal steps from `t = 0` to the last sample, inclusive.
    pub fn steps(&self) -> usize {
        self.first + (self.samples - 1) * self.sub + 1
    }

    /// Whether internal step `j` is a record sample.
    pub fn is_sample(&self, j: usize) -> bool {
        j >= self.first && (j - self.first).is_multiple_of(self.sub)
    }

    /// Internal index of sample `i`.
    pub fn index(&self, i: usize) -> usize {
        self.first + i * self.sub
    }
}

/// Gershgorin's bound on the chain's undamped frequencies.
fn omega_max(chain: &Chain) -> f64 {
    let m = chain.masses();
    let k = chain.springs();
    let g = chain.grounds();
    (0..chain.n())
        .map(|i| (2.0 * (k[i] + k[i + 1]) + g[i]) / m[i])
        .fold(0.0, f64::max)
        .sqrt()
}

/// A simulation of the impulse response on a [`TimeGrid`]: `x_1` at the
/// samples, and `x` and `v` of chosen masses at every internal step.
#[derive(Clone, Debug)]
pub struct Run {
    /// `x_1(t_i)` at the record's samples.
    pub x1: Vec<f64>,
    /// Displacements of the masses asked for (`xs[c * steps + j]`).
    xs: Vec<f64>,
    /// Velocities of the masses asked for (`vs[c * steps + j]`).
    vs: Vec<f64>,
    /// `slot[p - 1]`: the row of mass `p` in `xs` and `vs`, if stored.
    slot: Vec<Option<usize>>,
    /// The internal steps stored per mass.
    pub(super) steps: usize,
    /// The largest mass the stepping ever reached: beyond it every
    /// displacement and velocity is exactly 0 at every step.
    pub(super) touched: usize,
}

impl Run {
    /// Mass `p`'s displacement at every internal step, if stored.
    pub(super) fn x(&self, p: usize) -> Option<&[f64]> {
        let c = (*self.slot.get(p.wrapping_sub(1))?)?;
        self.xs.get(c * self.steps..(c + 1) * self.steps)
    }
    /// Mass `p`'s velocity at every internal step, if stored.
    pub(super) fn v(&self, p: usize) -> Option<&[f64]> {
        let c = (*self.slot.get(p.wrapping_sub(1))?)?;
        self.vs.get(c * self.steps..(c + 1) * self.steps)
    }
}

/// Sub-steps of the Taylor stepping satisfy `h ||A||_E <= THETA`.
const THETA: f64 = 1.5;

/// A Taylor step spans as many internal steps as keep `h ||A||_E` at most
/// this (the terms then grow to at most `e^3 / sqrt(6 pi) = 4.6` times the
/// state before they fall): the state in between is summed from the same
/// terms, for `x_1` and the tracked masses only. At a record step of
/// `||A|| dt = 0.65` (four internal steps per Taylor step) this halves the
/// tridiagonal products per unit time (28 terms per step of 2.6 against 16
/// per step of 0.65).
const BLOCK_THETA: f64 = 3.0;

/// Simulate `chain`'s impulse response on `grid` (sparse Taylor stepping
/// in the energy norm, where `A` is skew up to the damping, `||A|| <=
/// omega_max + max d_i / m_i`: steps of several internal steps with `h ||A||
/// <= 3`, the state in between summed from the same terms, or sub-steps
/// with `h ||A|| <= 1.5` when one internal step is longer; terms until
/// they fall below `2^-53` of the state), recording `x_1` at the samples
/// and `x`, `v` of `masses` (1-based, increasing) at every internal step.
///
/// # Errors
/// A mass out of range (field `masses`); a non-finite state (field `chain`);
/// a damping model other than grounded (field `damping`: the stepping and
/// the sensitivities above assume diagonal `D`).
pub fn simulate(chain: &Chain, grid: &TimeGrid, masses: &[usize]) -> Result<Run> {
    require_grounded(chain)?;
    let n = chain.n();
    let steps = grid.steps();
    let mut slot = vec![None; n];
    for (c, &p) in masses.iter().enumerate() {
        if p == 0 || p > n {
            return Err(Error::invalid("masses", p, format!("1..={n}")));
        }
        slot[p - 1] = Some(c);
    }
    let mut st = Stepper::new(chain);
    let mut xs = vec![0.0; masses.len() * steps];
    let mut vs = vec![0.0; masses.len() * steps];
    let mut x1 = Vec::with_capacity(grid.samples);
    advance(&mut st, chain, grid, 0, masses, |j, at| {
        for c in 0..masses.len() {
            xs[c * steps + j] = at.x[c];
            vs[c * steps + j] = at.v[c];
        }
        if grid.is_sample(j) {
            x1.push(at.x1);
        }
        true
    });
    finite(x1.iter().chain(&xs).chain(&vs))?;
    Ok(Run {
        x1,
        xs,
        vs,
        slot,
        steps,
        touched: st.touched,
    })
}

/// The internal steps per Taylor step of [`advance`] (internal steps of
/// `theta = dt ||A||`) that cost least, from one to as many as keep `h ||A||
/// <= BLOCK_THETA`: per internal step, a Taylor step's terms (tridiagonal
/// products over up to `n` rows, about 6 operations a row) shared by its
/// internal steps, and the same terms summed at each internal step inside
/// for `x_1` and `tracked` masses' `x` and `v` (one operation each).
fn block_size(theta: f64, n: usize, tracked: usize) -> usize {
    let most = ((BLOCK_THETA / theta).floor() as usize).clamp(1, SPREAD);
    let per_term = |b: usize| 6.0 * n as f64 / b as f64 + (1 + 2 * tracked) as f64;
    (1..=most)
        .min_by(|&a, &b| {
            let ca = taylor_terms(a as f64 * theta) as f64 * per_term(a);
            let cb = taylor_terms(b as f64 * theta) as f64 * per_term(b);
            ca.total_cmp(&cb)
        })
        .unwrap_or(1)
}

/// Terms of the exponential's Taylor series at `theta` until one falls
/// below `1.1e-16` (at most [`SPREAD`]).
fn taylor_terms(theta: f64) -> usize {
    let (mut m, mut t) = (0, 1.0f64);
    while t > 1.1e-16 && m < SPREAD {
        m += 1;
        t *= theta / m as f64;
    }
    m
}

/// `||A||` in the energy norm: `A` is skew (norm `omega_max`) plus the
/// damping.
fn norm(chain: &Chain) -> f64 {
    let (m, d) = (chain.masses(), chain.dampers());
    omega_max(chain) + (0..chain.n()).map(|i| d[i] / m[i]).fold(0.0, f64::max)
}

/// Taylor sub-steps per internal step of `grid` when [`simulate`] steps
/// `chain` (`h ||A|| <= THETA`): 1 unless heavy damping or a stiff chain
/// asks for more.
pub fn sub_steps(chain: &Chain, grid: &TimeGrid) -> usize {
    ((grid.dt * norm(chain) / THETA).ceil() as usize).max(1)
}

/// What [`advance`] knows at an internal step: `x_1`, `x` and `v` of the
/// tracked masses (in their order), and the whole state where a Taylor
/// step ends (and at the start).
struct At<'a> {
    x1: f64,
    x: &'a [f64],
    v: &'a [f64],
    whole: Option<&'a Stepper>,
}

/// Step `st` (the state of `chain` at internal step `from` of `grid`) to
/// the grid's last step; `each(j, at)` at every internal step `j >= from`,
/// `from` included, until it returns `false`, with `x`, `v` of the masses
/// `tracked` (1-based). Taylor steps span several internal steps up to
/// `h ||A|| <= BLOCK_THETA`, or divide one into sub-steps with
/// `h ||A|| <= THETA` when it is longer.
fn advance(
    st: &mut Stepper,
    chain: &Chain,
    grid: &TimeGrid,
    from: usize,
    tracked: &[usize],
    mut each: impl FnMut(usize, &At) -> bool,
) {
    let theta = grid.dt * norm(chain);
    let inner = sub_steps(chain, grid);
    let block = if inner > 1 || theta.is_nan() || theta <= 0.0 {
        1
    } else {
        block_size(theta, chain.n(), tracked.len())
    };
    let h = grid.dt / inner as f64;
    let last = grid.steps() - 1;
    let nt = tracked.len();
    let (mut tx, mut tv) = (vec![0.0; nt], vec![0.0; nt]);
    let mut between = Vec::new();
    let mut j = from;
    loop {
        for (c, &p) in tracked.iter().enumerate() {
            tx[c] = st.x[p];
            tv[c] = st.v[p];
        }
        let at = At {
            x1: st.x[1],
            x: &tx,
            v: &tv,
            whole: Some(st),
        };
        if !each(j, &at) || j >= last {
            return;
        }
        let b = block.min(last - j);
        if b == 1 {
            for _ in 0..inner {
                st.sub_step(h);
            }
        } else {
            st.block_step(grid.dt, b, tracked, &mut between);
            let w = 1 + 2 * nt;
            for (i, row) in between.chunks(w).enumerate() {
                let at = At {
                    x1: row[0],
                    x: &row[1..=nt],
                    v: &row[1 + nt..],
                    whole: None,
                };
                if !each(j + 1 + i, &at) {
                    return;
                }
            }
        }
        j += b;
    }
}

/// A non-finite value (an unstable simulation) as an error (field `chain`).
fn finite<'a>(mut values: impl Iterator<Item = &'a f64>) -> Result<()> {
    if values.any(|a| !a.is_finite()) {
        return Err(Error::invalid(
            "chain",
            "an unstable simulation",
            "a finite response",
        ));
    }
    Ok(())
}

/// A simulation of `x_1` that keeps its state at every
/// [`SAVED_EVERY`]-th part of the record, so that a chain differing from
/// it only deep in the chain is simulated from the last saved state the
/// difference could not yet have reached ([`Saved::resume`]): before the
/// impulse's front (the masses whose state is above 1e-30 of the largest,
/// plus the stepping's spread) reaches a changed mass, the two chains'
/// states are the same, so the resumed record equals a whole simulation to
/// rounding. The hidden-defect check's probes of a long chain use it
/// ([`crate::detect::fit::unseen`]): a deep probe is stepped only from the
/// time the front reaches it.
#[derive(Clone, Debug)]
pub struct Saved {
    /// The simulated chain's stepping rows and initial velocity.
    rows: Stepper,
    /// `x_1` at the record's samples.
    pub x1: Vec<f64>,
    marks: Vec<Mark>,
    /// The grid the states were saved on (their steps are its own).
    grid: TimeGrid,
}

/// One saved state of [`Saved`].
#[derive(Clone, Debug)]
struct Mark {
    /// The internal step it was saved at.
    step: usize,
    /// The record samples up to that step (included).
    samples: usize,
    /// The state up to the last row used (beyond it exactly 0).
    x: Vec<f64>,
    v: Vec<f64>,
    reach: usize,
    /// The largest stepping row used up to this sample.
    touched: usize,
}

/// Saved states per record (at most; one per sample of a shorter record).
pub const SAVED_EVERY: usize = 64;

impl Saved {
    /// Simulate `chain` on `grid` as [`simulate`] does (`x_1` only),
    /// keeping the states.
    ///
    /// # Errors
    /// As [`simulate`].
    pub fn new(chain: &Chain, grid: &TimeGrid) -> Result<Saved> {
        require_grounded(chain)?;
        let mut st = Stepper::new(chain);
        let rows = st.clone();
        let every = grid.samples.div_ceil(SAVED_EVERY).max(1);
        let mut x1 = Vec::with_capacity(grid.samples);
        let mut marks = Vec::new();
        let mut next = 0;
        advance(&mut st, chain, grid, 0, &[], |j, at| {
            if grid.is_sample(j) {
                x1.push(at.x1);
            }
            // a mark where a Taylor step ends, every `every` samples or so
            if let Some(st) = at.whole.filter(|st| x1.len() >= next && st.touched < st.n) {
                marks.push(Mark {
                    step: j,
                    samples: x1.len(),
                    // beyond the rows used the state is exactly 0
                    x: st.x[..=st.touched + 1].to_vec(),
                    v: st.v[..=st.touched + 1].to_vec(),
                    reach: st.reach,
                    touched: st.touched,
                });
                next = x1.len() + every;
            }
            true
        });
        finite(x1.iter())?;
        Ok(Saved {
            rows,
            x1,
            marks,
            grid: *grid,
        })
    }

    /// `x_1` of `changed` on `grid` (its own grid: [`TimeGrid::new`] of
    /// the record's times for `changed`), from the last saved state
    /// before the front reached the first stepping row in which `changed`
    /// differs from the saved chain (from rest when there is none, or
    /// when `grid` is not the grid the states were saved on). At the
    /// sample counts of `asked_at` `enough` is asked with the samples
    /// so far; when it answers `true` these first samples are returned.
    ///
    /// # Errors
    /// As [`simulate`].
    pub fn resume(
        &self,
        changed: &Chain,
        grid: &TimeGrid,
        mut enough: impl FnMut(&[f64]) -> bool,
    ) -> Result<Vec<f64>> {
        require_grounded(changed)?;
        let mut st = Stepper::new(changed);
        let Some(first) = self.rows.first_difference(&st) else {
            return Ok(self.x1.clone());
        };
        // a chain whose own grid is another (a lighter mass: a finer step)
        // is stepped from rest: the saved steps are of the saved grid
        let same_grid = *grid == self.grid;
        let mark = self
            .marks
            .iter()
            .rev()
            .find(|m| same_grid && m.touched < first);
        let (mut x1, from, fresh) = match mark {
            Some(mark) => {
                st.x[..mark.x.len()].copy_from_slice(&mark.x);
                st.v[..mark.v.len()].copy_from_slice(&mark.v);
                st.reach = mark.reach;
                st.touched = mark.touched;
                (self.x1[..mark.samples].to_vec(), mark.step, false)
            }
            None => (Vec::with_capacity(grid.samples), 0, true),
        };
        let every = grid.samples.div_ceil(ENOUGH_EVERY).max(1);
        advance(&mut st, changed, grid, from, &[], |j, at| {
            if (j > from || fresh) && grid.is_sample(j) {
                x1.push(at.x1);
                let done = x1.len() == grid.samples;
                return done || !asked_at(x1.len(), every) || !enough(&x1);
            }
            true
        });
        finite(x1.iter())?;
        Ok(x1)
    }
}

/// How often (parts of the record) [`Saved::resume`] may ask whether the
/// samples so far are enough (`asked_at`).
pub const ENOUGH_EVERY: usize = 64;

/// Whether [`Saved::resume`] asks at `samples` samples (`every`: the
/// record's [`ENOUGH_EVERY`]-th part): at its first eight multiples, then
/// at multiples about a quarter apart (10, 12, 15, 18, 22, ...). Each
/// question costs the residuals of the samples so far, so asking at every
/// multiple costs the square of the record (a probe that ran to the end
/// of a 6,001-sample record had been asked 64 times, about a third of the
/// hidden-defect check); the answer is found at most a quarter later.
pub fn asked_at(samples: usize, every: usize) -> bool {
    if every == 0 || !samples.is_multiple_of(every) {
        return false;
    }
    let j = samples / every;
    let mut at = 1;
    while at < j {
        at = (at + 1).max(at * 5 / 4);
    }
    at == j
}

/// Each Taylor term spreads the state by one mass; a sub-step works on the
/// masses the impulse has reached plus this many, and sums at most this
/// many terms.
const SPREAD: usize = 48;

/// The state of [`simulate`]'s sparse Taylor stepping, padded with a zero
/// at each end (index `i + 1` for mass `i + 1`), and the rows of
/// `M^-1 (-K x - D v)`.
#[derive(Clone, Debug)]
struct Stepper {
    n: usize,
    lo: Vec<f64>,
    dg: Vec<f64>,
    up: Vec<f64>,
    dd: Vec<f64>,
    x: Vec<f64>,
    v: Vec<f64>,
    tx: Vec<f64>,
    tv: Vec<f64>,
    nx: Vec<f64>,
    nv: Vec<f64>,
    /// The masses the impulse has reached: beyond `reach` the state is
    /// below 1e-30 of its largest value (exactly 0 at first).
    reach: usize,
    /// The largest row a sub-step has used so far (its coefficients and
    /// state; beyond it every state is exactly 0).
    touched: usize,
}

impl Stepper {
    /// At rest but for the impulse's velocity `gamma / m_1` of mass 1.
    fn new(chain: &Chain) -> Stepper {
        let n = chain.n();
        let m = chain.masses();
        let k = chain.springs();
        let d = chain.dampers();
        let g = chain.grounds();
        let mut st = Stepper {
            n,
            lo: vec![0.0; n + 2],
            dg: vec![0.0; n + 2],
            up: vec![0.0; n + 2],
            dd: vec![0.0; n + 2],
            x: vec![0.0; n + 2],
            v: vec![0.0; n + 2],
            tx: vec![0.0; n + 2],
            tv: vec![0.0; n + 2],
            nx: vec![0.0; n + 2],
            nv: vec![0.0; n + 2],
            reach: 1,
            touched: 1,
        };
        for i in 0..n {
            st.lo[i + 1] = k[i] / m[i];
            st.dg[i + 1] = -(k[i] + k[i + 1] + g[i]) / m[i];
            st.up[i + 1] = k[i + 1] / m[i];
            st.dd[i + 1] = -d[i] / m[i];
        }
        st.v[1] = chain.gamma() / m[0];
        st
    }

    /// One sub-step `y <- sum_k (h A)^k y / k!` over the reached masses,
    /// terms until they fall below `2^-53` of the state, then the reach
    /// updated.
    #[inline]
    fn sub_step(&mut self, h: f64) {
        let (hi, scale) = self.begin();
        self.series(h, hi, scale, |_| {});
    }

    /// The rows a Taylor step works on (the reach plus [`SPREAD`]), the
    /// state copied as the first term, and the state's largest entry.
    #[inline]
    fn begin(&mut self) -> (usize, f64) {
        let hi = (self.reach + SPREAD).min(self.n);
        self.touched = self.touched.max(hi);
        self.tx[..=hi + 1].copy_from_slice(&self.x[..=hi + 1]);
        self.tv[..=hi + 1].copy_from_slice(&self.v[..=hi + 1]);
        let scale = max_abs(&self.x[1..=hi], &self.v[1..=hi]).max(f64::MIN_POSITIVE);
        (hi, scale)
    }

    /// The Taylor terms of a step `h` on rows `1..=hi` until they fall
    /// below `2^-53` of `scale`, `each(self)` after each (the new term in
    /// `nx`, `nv`), then the reach updated.
    #[inline]
    fn series(&mut self, h: f64, hi: usize, scale: f64, mut each: impl FnMut(&Stepper)) {
        for term in 1..=SPREAD {
            let big = self.term(h / term as f64, hi);
            each(self);
            std::mem::swap(&mut self.tx, &mut self.nx);
            std::mem::swap(&mut self.tv, &mut self.nv);
            if big <= 1.1e-16 * scale {
                break;
            }
        }
        if self.reach < self.n {
            self.trim(hi, scale);
        }
    }

    /// One Taylor step over `b` internal steps of `dt` (as
    /// [`Stepper::sub_step`] with `h = b dt`), and into `between` the state
    /// at the `b - 1` internal steps inside it, summed from the same terms:
    /// per step `x_1` then `x` and `v` of the masses `tracked`.
    fn block_step(&mut self, dt: f64, b: usize, tracked: &[usize], between: &mut Vec<f64>) {
        let (hi, scale) = self.begin();
        // the masses tracked within reach (the state beyond stays 0)
        let live: Vec<(usize, usize)> = tracked
            .iter()
            .enumerate()
            .filter(|&(_, &p)| p <= hi)
            .map(|(c, &p)| (c, p))
            .collect();
        let nt = tracked.len();
        let w = 1 + 2 * nt;
        between.clear();
        between.resize((b - 1) * w, 0.0);
        for row in between.chunks_mut(w) {
            row[0] = self.x[1];
            for &(c, p) in &live {
                row[1 + c] = self.x[p];
                row[1 + nt + c] = self.v[p];
            }
        }
        // (i / b)^term for the step i inside, and the term's entries that
        // are summed there
        let mut pw = vec![1.0; b - 1];
        let ratio: Vec<f64> = (1..b).map(|i| i as f64 / b as f64).collect();
        let mut entries = vec![0.0; w];
        self.series(b as f64 * dt, hi, scale, |st| {
            entries[0] = st.nx[1];
            for &(c, p) in &live {
                entries[1 + c] = st.nx[p];
                entries[1 + nt + c] = st.nv[p];
            }
            kernel::accumulate(between, &mut pw, &ratio, &entries);
        });
    }

    /// The next Taylor term `alpha A t` into `n*`, added to the state;
    /// returns its largest entry ([`kernel::term`]).
    #[inline]
    fn term(&mut self, alpha: f64, hi: usize) -> f64 {
        kernel::term(
            alpha,
            kernel::Term {
                lo: &self.lo[1..=hi],
                dg: &self.dg[1..=hi],
                up: &self.up[1..=hi],
                dd: &self.dd[1..=hi],
                tx: &self.tx[..hi + 2],
                tv: &self.tv[..hi + 2],
                nx: &mut self.nx[1..=hi],
                nv: &mut self.nv[1..=hi],
                x: &mut self.x[1..=hi],
                v: &mut self.v[1..=hi],
            },
        )
    }

    /// The first row (1-based) in which `other`'s stepping differs from
    /// this one's (its coefficients or its initial velocity); `None` for
    /// the same chain, `Some(0)` for chains of other sizes.
    fn first_difference(&self, other: &Stepper) -> Option<usize> {
        if self.n != other.n {
            return Some(0);
        }
        if self.v[1] != other.v[1] {
            return Some(1);
        }
        (1..=self.n).find(|&i| {
            self.lo[i] != other.lo[i]
                || self.dg[i] != other.dg[i]
                || self.up[i] != other.up[i]
                || self.dd[i] != other.dd[i]
        })
    }

    /// The new reach after a sub-step on `1..=hi`; what lies beyond is
    /// dropped (below 1e-30 of the state).
    fn trim(&mut self, hi: usize, scale: f64) {
        let tiny = 1e-30 * scale;
        let (x, v) = (&mut self.x, &mut self.v);
        self.reach = (1..=hi)
            .rev()
            .find(|&i| x[i].abs() > tiny || v[i].abs() > tiny)
            .unwrap_or(1);
        for i in self.reach + 1..=hi {
            x[i] = 0.0;
            v[i] = 0.0;
        }
        if self.reach + SPREAD >= self.n {
            self.reach = self.n;
        }
    }
}

/// The screen's kernels take the grounded model only.
///
/// # Errors
/// [`Error::InvalidParameter`] naming `damping`.
fn require_grounded(chain: &Chain) -> Result<()> {
    if chain.damping().is_grounded() {
        return Ok(());
    }
    Err(Error::invalid(
        "damping",
        chain.damping().name(),
        "grounded for the sparse time stepping and candidate screen (the modal path takes every model)",
    ))
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;

    use crate::time::modal::Modes;

    /// Asked at the first eight multiples of the step, then at most a
    /// quarter apart (never more than the next multiple), 18 times over
    /// a whole record rather than 64; never between multiples.
    #[test]
    fn enough_is_asked_ever_more_rarely_but_at_most_a_quarter_late() {
        let every = 10;
        let asked: Vec<usize> = (0..=ENOUGH_EVERY * every)
            .filter(|&s| asked_at(s, every))
            .map(|s| s / every)
            .collect();
        assert_eq!(&asked[..10], &[1, 2, 3, 4, 5, 6, 7, 8, 10, 12]);
        assert_eq!(asked.len(), 18, "{asked:?}");
        for w in asked.windows(2) {
            assert!(w[1] <= (w[0] + 1).max(w[0] * 5 / 4), "{asked:?}");
        }
        assert!(!asked_at(15, every) && !asked_at(0, every) && !asked_at(5, 0));
    }

    /// The largest `|v|`.
    fn peak(v: &[f64]) -> f64 {
        v.iter().fold(0.0f64, |a, b| a.max(b.abs()))
    }

    /// The largest `|a_i - b_i|`.
    fn max_diff(a: &[f64], b: &[f64]) -> f64 {
        a.iter()
            .zip(b)
            .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
    }

    /// The paper's chain of `n` masses with `defects` and damping `d`, and
    /// `samples` record times `0, 0.25, ...`.
    pub(in crate::detect::misfit::time_screen) fn chain_and_times(
        n: usize,
        defects: &str,
        d: f64,
        samples: usize,
    ) -> (Chain, Vec<f64>) {
        let c = crate::scenes::paper_with(n, defects)
            .unwrap()
            .with_d(d)
            .unwrap();
        (c, (0..samples).map(|i| 0.25 * i as f64).collect())
    }

    #[test]
    fn simulation_matches_the_modal_sum() {
        let (c, t) = chain_and_times(15, "mass:4:2.5 spring:9:0.4", 0.03, 801);
        let g = TimeGrid::new(&t, &c).unwrap();
        let run = simulate(&c, &g, &[]).unwrap();
        let exact = Modes::new(&c)
            .unwrap()
            .response(1, 1, 1.0)
            .unwrap()
            .eval_many(&t);
        let err = max_diff(&run.x1, &exact);
        assert!(err < 1e-12 * peak(&exact), "{err:e}");
    }

    /// The lanes' maximum is the plain running maximum, whatever the
    /// lengths (remainders of the four lanes), signs and NaNs.
    #[test]
    fn lanes_find_the_running_maximum() {
        let plain = |a: &[f64], b: &[f64]| {
            a.iter()
                .chain(b)
                .fold(0.0f64, |m, &v| if v.abs() > m { v.abs() } else { m })
        };
        for n in 0..12 {
            for at in 0..n.max(1) {
                let mut a: Vec<f64> = (0..n).map(|i| ((i * 7 % 5) as f64 - 2.0) * 0.1).collect();
                let b: Vec<f64> = (0..n / 2).map(|i| -(i as f64) * 0.05).collect();
                if n > 0 {
                    a[at] = -3.0 - at as f64;
                }
                assert_eq!(max_abs(&a, &b), plain(&a, &b), "{n} {at}");
                if n > 1 {
                    a[(at + 1) % n] = f64::NAN;
                    assert_eq!(max_abs(&a, &b), plain(&a, &b), "{n} {at} NaN");
                }
            }
        }
        assert_eq!(max_abs(&[], &[]), 0.0);
        assert_eq!(max_abs(&[], &[1.0, -7.0, 2.0, 3.0, 4.0]), 7.0);
    }

    /// Taylor steps over several internal steps (short steps), one
    /// (`dt ||A||` near 1) and sub-steps (heavy damping) give `x_1` and the
    /// tracked masses' `x` between and at their ends as the modal sum does,
    /// from one mass to 120, masses from 1e-3 to 1e6, without damping too.
    #[test]
    fn simulation_matches_the_modal_sum_over_wide_grids() {
        let cases: [(usize, &str, f64, f64, usize); 8] = [
            (1, "", 0.1, 0.05, 2001),
            (2, "mass:2:1e-3", 0.0, 0.01, 3001),
            (7, "mass:3:1e6", 0.02, 0.5, 801),
            (7, "mass:3:1e6", 0.02, 0.01, 4001),
            (15, "mass:4:2.5 spring:9:0.4", 0.0, 0.02, 4001),
            (15, "mass:4:2.5 spring:9:0.4", 8.0, 0.25, 401),
            (40, "mass:30:0.3", 0.01, 0.25, 1601),
            (120, "mass:5:3 mass:90:0.5", 0.01, 0.1, 2001),
        ];
        for (n, defects, d, dt, samples) in cases {
            let c = crate::scenes::paper_with(n, defects)
                .unwrap()
                .with_d(d)
                .unwrap();
            let t: Vec<f64> = (0..samples).map(|i| dt * i as f64).collect();
            let g = TimeGrid::new(&t, &c).unwrap();
            let mut tracked = vec![1, n.div_ceil(2), n];
            tracked.dedup();
            let run = simulate(&c, &g, &tracked).unwrap();
            let modes = Modes::new(&c).unwrap();
            let x1 = modes.response(1, 1, 1.0).unwrap().eval_many(&t);
            let top = peak(&x1);
            let err = max_diff(&run.x1, &x1);
            assert!(
                err < 1e-11 * top,
                "n = {n} dt = {dt}: x_1 {err:e} of {top:e}"
            );
            let ti: Vec<f64> = (0..g.steps()).map(|j| g.dt * j as f64).collect();
            for &p in &tracked {
                let xp = modes.response(p, 1, 1.0).unwrap().eval_many(&ti);
                // rounding is relative to the whole state (a mass behind
                // one of 1e6 moves 1e-6 as much)
                let big = top.max(peak(&xp));
                let err = max_diff(run.x(p).unwrap(), &xp);
                assert!(
                    err < 1e-11 * big,
                    "n = {n} dt = {dt}: mass {p} {err:e} of {big:e}"
                );
            }
        }
    }

    /// A chain that differs from the saved one deep inside is resumed
    /// where the front reaches it: the same record as a whole simulation
    /// to rounding, and before that the saved chain's samples themselves;
    /// a change at mass 1 or of another size is simulated whole.
    #[test]
    fn resumed_records_match_whole_simulations() {
        let (base, t) = chain_and_times(160, "mass:3:2", 0.02, 1201);
        let g = TimeGrid::new(&t, &base).unwrap();
        let saved = Saved::new(&base, &g).unwrap();
        assert_eq!(saved.x1, simulate(&base, &g, &[]).unwrap().x1);
        let scale = peak(&saved.x1);
        for (change, resumed) in [
            ("mass:120:0.5", true),
            ("mass:60:2", true),
            ("spring:90:0.5", true),
            ("mass:1:2", false),
        ] {
            let c = base
                .clone()
                .with_defect(crate::chain::Defect::parse(change).unwrap())
                .unwrap();
            let gc = TimeGrid::new(&t, &c).unwrap();
            let whole = simulate(&c, &gc, &[]).unwrap().x1;
            let r = saved.resume(&c, &gc, |_| false).unwrap();
            assert_eq!(r.len(), whole.len(), "{change}");
            let err = max_diff(&r, &whole);
            assert!(err <= 1e-13 * scale, "{change}: {err:e}");
            // the samples before the front reached the change are the
            // saved chain's own (bit for bit) when it was resumed
            let same = r.iter().zip(&saved.x1).take_while(|(p, q)| p == q).count();
            assert_eq!(same > 100, resumed, "{change}: {same}");
        }
        let other = Chain::paper(150).unwrap();
        let go = TimeGrid::new(&t, &other).unwrap();
        assert_eq!(
            saved.resume(&other, &go, |_| false).unwrap(),
            simulate(&other, &go, &[]).unwrap().x1
        );
    }

    #[test]
    fn grids() {
        let c = Chain::paper(5).unwrap();
        let t: Vec<f64> = (0..10).map(|i| 1.0 + 0.5 * i as f64).collect();
        let g = TimeGrid::new(&t, &c).unwrap();
        assert_eq!((g.sub, g.first, g.samples), (1, 2, 10));
        // coarse record: the internal grid is refined
        let t: Vec<f64> = (0..10).map(|i| 2.0 * i as f64).collect();
        let g = TimeGrid::new(&t, &c).unwrap();
        assert_eq!(g.sub, 4);
        assert_eq!(g.index(1), 4);
        // not uniform, or not from a multiple of the step
        assert!(TimeGrid::new(&[0.0, 1.0, 3.0], &c).is_none());
        assert!(TimeGrid::new(&[0.3, 0.8, 1.3], &c).is_none());
        // a record far too coarse for the chain (more than MAX_SUB internal
        // steps per sample), and one whose step overflows any grid: none
        let t: Vec<f64> = (0..10).map(|i| 200.0 * i as f64).collect();
        assert!(TimeGrid::new(&t, &c).is_none());
        let t: Vec<f64> = (0..10).map(|i| 5e199 * i as f64).collect();
        assert!(TimeGrid::new(&t, &c).is_none());
    }
}
