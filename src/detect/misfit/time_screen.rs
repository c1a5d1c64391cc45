//! Screening defect candidates on a sampled record: the linearised effect of
//! every candidate value on `x_1(t)` from **one** simulation of the current
//! chain, and the chi-square drop of its best single-value step.
//!
//! # Sensitivities by reciprocity
//!
//! For the paper's measurement (impulse `gamma delta(t)` on mass 1,
//! displacement of mass 1) `X_1(s) = gamma G_11(s)`, `G = K(s)^-1`,
//! `K(s) = M s^2 + D s + K`. A value `theta` whose dynamic stiffness changes
//! as `dK/dtheta = s^power u u^T` moves it by
//!
//! ```text
//! dX_1/dtheta = -gamma s^power (e_1^T G u)(u^T G e_1) = -s^power (u^T X)^2 / gamma
//! ```
//!
//! (`G` symmetric, `X = gamma G e_1` the responses of every mass to the same
//! impulse). With `x_p(0) = 0` for every mass, `s X_p` is the transform of
//! the velocity `v_p`, so in the time domain
//!
//! | value | `u` | power | `d x_1 / d theta` |
//! |---|---|---|---|
//! | mass `m_p` | `e_p` | 2 | `-(v_p * v_p)(t) / gamma` |
//! | damper `d_p` (to ground) | `e_p` | 1 | `-(v_p * x_p)(t) / gamma` |
//! | spring `k_p` (masses `p`, `p+1`) | `e_p - e_{p+1}` | 0 | `-(w_p * w_p)(t) / gamma`, `w_p = x_p - x_{p+1}` |
//!
//! (`*` the causal convolution `int_0^t a(tau) b(t - tau) dtau`; a wall side
//! of a spring is a zero displacement). One simulation that records `x` and
//! `v` at every mass therefore gives every candidate's sensitivity by one
//! convolution each: `O(n T)` for the simulation (sparse Taylor stepping,
//! exact to rounding as [`crate::time::simulate`]'s `Rk`) and
//! `O(n T log T)` for the convolutions (FFT, two real convolutions per
//! complex transform), instead of one modal derivative per candidate.
//!
//! # Accuracy
//!
//! The responses are exact to rounding at the samples; the convolution
//! integral is the trapezoid rule on the record's grid (refined by an
//! integer factor when the record is coarse for the chain: `dt omega_max <=
//! 1`). The integrand is band-limited (the chain's frequencies, below the
//! grid's Nyquist frequency), so the rule is spectrally accurate except for
//! the end corrections where the integrand's derivatives jump at `tau = 0`:
//! only on mass 1, whose velocity starts at `gamma / m_1`, and its
//! neighbours. Measured against the exact modal derivative
//! ([`crate::time::modal::Modes::value_derivative`], test below): relative
//! error `2e-14` from mass 4 on, `2e-10` at mass 3, `5e-7` at mass 2 and
//! `8e-4` for the values touching mass 1 (`n = 12`, `dt = 0.1`):
//! exact enough to rank candidates and to serve as the Jacobian of a
//! Gauss-Newton refit whose residuals are exact.
//!
//! # Score
//!
//! With the residual `r_i = y_i - x_1(t_i)` and a candidate's sensitivity
//! `g_i`, the best single-value step is `delta = (r.g) / (g.g)` (clamped to
//! the value's bounds) and lowers `sum r_i^2` by `2 delta (r.g) - delta^2
//! (g.g)` (`(r.g)^2 / (g.g)` unclamped); over `sigma^2` that is the
//! chi-square drop.

use crate::chain::{Chain, Probe};
use crate::detect::unknowns::DefectKind;
use crate::error::{Error, Result};
use num_complex::Complex64;

/// Largest number of stored samples (masses x internal steps) of one
/// simulation; more candidates are screened in chunks.
const MAX_STORED: usize = 1 << 23;

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
    /// frequencies).
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
        let sub = ((step * w).ceil() as usize).max(1);
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
    steps: usize,
    /// The largest mass the stepping ever reached: beyond it every
    /// displacement and velocity is exactly 0 at every step.
    touched: usize,
}

impl Run {
    fn x(&self, p: usize) -> Option<&[f64]> {
        let c = (*self.slot.get(p.wrapping_sub(1))?)?;
        self.xs.get(c * self.steps..(c + 1) * self.steps)
    }
    fn v(&self, p: usize) -> Option<&[f64]> {
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
    // in the energy norm A is skew (norm omega_max) plus the damping
    let (m, d) = (chain.masses(), chain.dampers());
    let norm = omega_max(chain) + (0..chain.n()).map(|i| d[i] / m[i]).fold(0.0, f64::max);
    let theta = grid.dt * norm;
    let inner = ((theta / THETA).ceil() as usize).max(1);
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
        Ok(Saved { rows, x1, marks })
    }

    /// `x_1` of `changed` on `grid` (its own grid: [`TimeGrid::new`] of
    /// the record's times for `changed`), from the last saved state
    /// before the front reached the first stepping row in which `changed`
    /// differs from the saved chain (from rest when there is none). Every
    /// [`ENOUGH_EVERY`]-th part of the record `enough` is asked with the
    /// samples so far; when it answers `true` these first samples are
    /// returned.
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
        let (mut x1, from, fresh) = match self.marks.iter().rev().find(|m| m.touched < first) {
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
                return done || !x1.len().is_multiple_of(every) || !enough(&x1);
            }
            true
        });
        finite(x1.iter())?;
        Ok(x1)
    }
}

/// How often (parts of the record) [`Saved::resume`] asks whether the
/// samples so far are enough.
pub const ENOUGH_EVERY: usize = 64;

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
        let mut entries = vec![0.0; w];
        self.series(b as f64 * dt, hi, scale, |st| {
            entries[0] = st.nx[1];
            for &(c, p) in &live {
                entries[1 + c] = st.nx[p];
                entries[1 + nt + c] = st.nv[p];
            }
            for (i, (row, f)) in between.chunks_mut(w).zip(pw.iter_mut()).enumerate() {
                *f *= (i + 1) as f64 / b as f64;
                for (r, e) in row.iter_mut().zip(&entries) {
                    *r += *f * e;
                }
            }
        });
    }

    /// The next Taylor term `alpha A t` into `n*`, added to the state;
    /// returns its largest entry.
    #[inline]
    fn term(&mut self, alpha: f64, hi: usize) -> f64 {
        let w = hi + 2;
        let (txw, tvw) = (&self.tx[..w], &self.tv[..w]);
        let (nxw, nvw) = (&mut self.nx[1..=hi], &mut self.nv[1..=hi]);
        let (xw, vw) = (&mut self.x[1..=hi], &mut self.v[1..=hi]);
        let (low, dgw, upw, ddw) = (
            &self.lo[1..=hi],
            &self.dg[1..=hi],
            &self.up[1..=hi],
            &self.dd[1..=hi],
        );
        for i in 0..hi {
            let a = alpha
                * (low[i] * txw[i]
                    + dgw[i] * txw[i + 1]
                    + upw[i] * txw[i + 2]
                    + ddw[i] * tvw[i + 1]);
            let b = alpha * tvw[i + 1];
            nvw[i] = a;
            nxw[i] = b;
            vw[i] += a;
            xw[i] += b;
        }
        max_abs(nvw, nxw)
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

/// The largest `|v|` of `a` and `b` (NaN ignored, 0 for none), in four
/// independent lanes: a single running maximum waits on each comparison
/// (half the stepping's time when it did), the lanes do not; the result is
/// the same.
#[inline]
fn max_abs(a: &[f64], b: &[f64]) -> f64 {
    let mut m = [0.0f64; 4];
    for s in [a, b] {
        let mut it = s.chunks_exact(4);
        for c in &mut it {
            for (l, &v) in m.iter_mut().zip(c) {
                let v = v.abs();
                if v > *l {
                    *l = v;
                }
            }
        }
        for &v in it.remainder() {
            let v = v.abs();
            if v > m[0] {
                m[0] = v;
            }
        }
    }
    m.into_iter().fold(0.0, |a, v| if v > a { v } else { a })
}

/// Radix-2 complex FFT of one size.
#[derive(Clone, Debug)]
struct Fft {
    n: usize,
    tw: Vec<Complex64>,
}

impl Fft {
    fn new(n: usize) -> Fft {
        debug_assert!(n.is_power_of_two());
        let tw = (0..n / 2)
            .map(|k| Complex64::from_polar(1.0, -2.0 * std::f64::consts::PI * k as f64 / n as f64))
            .collect();
        Fft { n, tw }
    }

    /// In place, forward (`e^{-2 pi i jk/n}`); `inverse` conjugates and scales by `1/n`.
    fn run(&self, a: &mut [Complex64], inverse: bool) {
        let n = self.n;
        let bits = n.trailing_zeros();
        for i in 0..n {
            let j = i.reverse_bits() >> (usize::BITS - bits);
            if j > i {
                a.swap(i, j);
            }
        }
        if inverse {
            a.iter_mut().for_each(|z| *z = z.conj());
        }
        let mut len = 2;
        while len <= n {
            let stride = n / len;
            for chunk in a.chunks_exact_mut(len) {
                let (lo, hi) = chunk.split_at_mut(len / 2);
                for (k, (u, w)) in lo.iter_mut().zip(hi.iter_mut()).enumerate() {
                    let t = *w * self.tw[k * stride];
                    *w = *u - t;
                    *u += t;
                }
            }
            len <<= 1;
        }
        if inverse {
            let s = 1.0 / n as f64;
            a.iter_mut().for_each(|z| *z = z.conj() * s);
        }
    }
}

/// A candidate whose sensitivity [`Screen`] computes.
pub type Candidate = (DefectKind, usize);

/// The residual `y - x_1` and, per candidate, `(r.g, g.g)`.
pub type Scores = (Vec<f64>, Vec<(f64, f64)>);

/// Screening of candidates against one record (see the module docs).
#[derive(Clone, Debug)]
pub struct Screen {
    grid: TimeGrid,
    y: Vec<f64>,
    fft: Fft,
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

impl Screen {
    /// The screen of the record `(t, y)` for chains like `chain` (its
    /// frequencies set the internal grid); `None` when the record's times
    /// are not a uniform grid from a multiple of its step ([`TimeGrid::new`])
    /// or the chain's damping model is not grounded.
    pub fn new(t: &[f64], y: &[f64], chain: &Chain) -> Option<Screen> {
        if t.len() != y.len() || !chain.damping().is_grounded() {
            return None;
        }
        let grid = TimeGrid::new(t, chain)?;
        let size = (2 * grid.steps()).next_power_of_two();
        Some(Screen {
            grid,
            y: y.to_vec(),
            fft: Fft::new(size),
        })
    }

    /// The grid.
    pub fn grid(&self) -> &TimeGrid {
        &self.grid
    }

    /// The residual `y_i - x_1(t_i)` of `chain` (unwhitened).
    ///
    /// # Errors
    /// As [`simulate`].
    pub fn residual(&self, chain: &Chain) -> Result<Vec<f64>> {
        let run = simulate(chain, &self.grid, &[])?;
        Ok(self.y.iter().zip(&run.x1).map(|(a, b)| a - b).collect())
    }

    /// The masses whose responses the sensitivity of `c` needs.
    fn needs(c: Candidate, n: usize, out: &mut Vec<usize>) {
        let (kind, p) = c;
        out.extend(kind.site(p).probe.entries(n).map(|(i, _)| i));
    }

    /// Whether every mass `c` reads lies beyond `touched`, the reach of
    /// the chain's simulation: its sensitivity is 0 (the convolution of
    /// zero records), given without a convolution (n = 1000, T = 300: more
    /// than half the candidates, and the second chunk's simulation).
    fn dead(c: Candidate, n: usize, touched: usize) -> bool {
        let (kind, p) = c;
        kind.site(p).probe.entries(n).all(|(i, _)| i > touched)
    }

    /// `(a, b)` of the sensitivity `-(a * b) / gamma` of `c` on `run`: with
    /// `u = probe^T x` the probe's displacement and `u'` its velocity,
    /// `(u', u')` for a site of power 2 (a mass), `(u', u)` for power 1 (a
    /// damper), `(u, u)` for power 0 (a spring); a strain probe's `u`, `u'`
    /// are written into `buf`.
    fn factors<'r>(
        run: &'r Run,
        c: Candidate,
        n: usize,
        buf: &'r mut (Vec<f64>, Vec<f64>),
    ) -> Result<(&'r [f64], &'r [f64])> {
        let missing = || Error::invalid("candidate", format!("{c:?}"), "a simulated position");
        let (kind, p) = c;
        let site = kind.site(p);
        let (x, v): (&[f64], &[f64]) = match site.probe {
            Probe::Point(q) => (run.x(q).ok_or_else(missing)?, run.v(q).ok_or_else(missing)?),
            Probe::Diff(_) => {
                // u = probe^T x (and u' = probe^T v when the power needs it)
                let combine = |out: &mut Vec<f64>, of: fn(&Run, usize) -> Option<&[f64]>| {
                    out.clear();
                    out.resize(run.steps, 0.0);
                    for (i, w) in site.probe.entries(n) {
                        for (o, a) in out.iter_mut().zip(of(run, i).ok_or_else(missing)?) {
                            *o += w * a;
                        }
                    }
                    Ok::<(), Error>(())
                };
                let (bx, bv) = (&mut buf.0, &mut buf.1);
                combine(bx, Run::x)?;
                if site.power > 0 {
                    combine(bv, Run::v)?;
                }
                (&bx[..], &bv[..])
            }
        };
        Ok(match site.power {
            0 => (x, x),
            1 => (v, x),
            _ => (v, v),
        })
    }

    /// The sensitivities `d x_1(t_i) / d value` of the candidates `cands`
    /// on `chain` (module docs), handed to `f(index, g)` in turn, and the
    /// model `x_1(t_i)`. Candidates are taken two per transform; with
    /// `parallel` the pairs run on rayon's pool (the results do not depend
    /// on it).
    ///
    /// # Errors
    /// A candidate position out of range (field `candidate`); as [`simulate`];
    /// `gamma = 0` (field `gamma`).
    pub fn each<T: Send>(
        &self,
        chain: &Chain,
        cands: &[Candidate],
        parallel: bool,
        f: impl Fn(usize, &[f64]) -> T + Sync + Send,
    ) -> Result<(Vec<f64>, Vec<T>)> {
        self.each_with_residual(chain, cands, parallel, |i, _, g| f(i, g))
    }

    /// [`Screen::each`] with the residual `y - x_1` handed along:
    /// `f(index, r, g)`.
    ///
    /// # Errors
    /// As [`Screen::each`].
    pub fn each_with_residual<T: Send>(
        &self,
        chain: &Chain,
        cands: &[Candidate],
        parallel: bool,
        f: impl Fn(usize, &[f64], &[f64]) -> T + Sync + Send,
    ) -> Result<(Vec<f64>, Vec<T>)> {
        let n = chain.n();
        let gamma = chain.gamma();
        if gamma == 0.0 {
            return Err(Error::invalid("gamma", 0.0, "a nonzero impulse"));
        }
        for &(kind, p) in cands {
            if !kind.positions(n).contains(&p) {
                return Err(Error::invalid(
                    "candidate",
                    format!("{kind:?} {p}"),
                    "a position of the chain",
                ));
            }
        }
        let steps = self.grid.steps();
        // chunks of candidates whose masses fit in MAX_STORED
        let per_chunk = (MAX_STORED / (2 * steps)).max(2);
        let mut x1: Vec<f64> = Vec::new();
        let mut r: Vec<f64> = Vec::new();
        let mut out: Vec<T> = Vec::with_capacity(cands.len());
        let mut start = 0;
        let mut touched = n;
        while start < cands.len() || x1.is_empty() {
            let mut masses = Vec::new();
            let mut end = start;
            while end < cands.len() {
                let mut m = masses.clone();
                Self::needs(cands[end], n, &mut m);
                m.sort_unstable();
                m.dedup();
                if m.len() > per_chunk && end > start {
                    break;
                }
                masses = m;
                end += 1;
            }
            // a later chunk whose candidates all lie beyond the reach of the
            // first simulation (the same chain) needs none
            if !x1.is_empty() && (start..end).all(|i| Self::dead(cands[i], n, touched)) {
                let zero = vec![0.0; x1.len()];
                out.extend((start..end).map(|i| f(i, &r, &zero)));
                start = end;
                continue;
            }
            let run = simulate(chain, &self.grid, &masses)?;
            if x1.is_empty() {
                x1 = run.x1.clone();
                r = self.y.iter().zip(&x1).map(|(a, b)| a - b).collect();
                touched = run.touched;
            }
            let idx: Vec<usize> = (start..end).collect();
            let pairs: Vec<&[usize]> = idx.chunks(2).collect();
            let zero = vec![0.0; x1.len()];
            let work = |pair: &&[usize]| -> Result<Vec<T>> {
                if pair.iter().all(|&i| Self::dead(cands[i], n, run.touched)) {
                    return Ok(pair.iter().map(|&i| f(i, &r, &zero)).collect());
                }
                let gs = self.convolve(&run, cands, pair, n, gamma)?;
                Ok(pair.iter().zip(gs).map(|(&i, g)| f(i, &r, &g)).collect())
            };
            let res: Vec<Result<Vec<T>>> =
                crate::detect::search::parallel::map(&pairs, parallel, 2, work);
            for part in res {
                out.extend(part?);
            }
            start = end;
            if cands.is_empty() {
                break;
            }
        }
        Ok((x1, out))
    }

    /// The sensitivities of one or two candidates at the samples.
    fn convolve(
        &self,
        run: &Run,
        cands: &[Candidate],
        pair: &[usize],
        n: usize,
        gamma: f64,
    ) -> Result<Vec<Vec<f64>>> {
        let size = self.fft.n;
        let steps = run.steps;
        let (mut b0, mut b1) = ((Vec::new(), Vec::new()), (Vec::new(), Vec::new()));
        let (a0, c0) = Self::factors(run, cands[pair[0]], n, &mut b0)?;
        let (a1, c1) = match pair.get(1) {
            Some(&i) => Self::factors(run, cands[i], n, &mut b1)?,
            None => (&[][..], &[][..]),
        };
        let pack = |re: &[f64], im: &[f64]| {
            let mut z = vec![Complex64::new(0.0, 0.0); size];
            for (o, v) in z.iter_mut().zip(re) {
                o.re = *v;
            }
            for (o, v) in z.iter_mut().zip(im) {
                o.im = *v;
            }
            z
        };
        let same = std::ptr::eq(a0.as_ptr(), c0.as_ptr())
            && (a1.is_empty() || std::ptr::eq(a1.as_ptr(), c1.as_ptr()));
        let mut za = pack(a0, a1);
        self.fft.run(&mut za, false);
        let zb = if same {
            None
        } else {
            let mut z = pack(c0, c1);
            self.fft.run(&mut z, false);
            Some(z)
        };
        // split the two real transforms, multiply, and pack the products
        let half = Complex64::new(0.5, 0.0);
        let mi = Complex64::new(0.0, -0.5);
        let mut prod = vec![Complex64::new(0.0, 0.0); size];
        for k in 0..size {
            let kc = (size - k) % size;
            let (pa, qa) = (za[k], za[kc].conj());
            let (ar, ai) = ((pa + qa) * half, (pa - qa) * mi);
            let (br, bi) = match &zb {
                None => (ar, ai),
                Some(zb) => {
                    let (pb, qb) = (zb[k], zb[kc].conj());
                    ((pb + qb) * half, (pb - qb) * mi)
                }
            };
            prod[k] = ar * br + Complex64::new(0.0, 1.0) * (ai * bi);
        }
        self.fft.run(&mut prod, true);
        // trapezoid: dt (sum - a(0) b(j) / 2 - a(j) b(0) / 2), sampled
        let scale = -self.grid.dt / gamma;
        let sample = |a: &[f64], b: &[f64], re: bool| -> Vec<f64> {
            (0..self.grid.samples)
                .map(|i| {
                    let j = self.grid.index(i);
                    let c = if re { prod[j].re } else { prod[j].im };
                    let end = if j < steps {
                        0.5 * (a[0] * b[j] + a[j] * b[0])
                    } else {
                        0.0
                    };
                    scale * (c - end)
                })
                .collect()
        };
        let mut gs = vec![sample(a0, c0, true)];
        if pair.len() > 1 {
            gs.push(sample(a1, c1, false));
        }
        Ok(gs)
    }

    /// The residual `y - x_1` of `chain` and, per candidate, `(r.g, g.g)`.
    ///
    /// # Errors
    /// As [`Screen::each`].
    pub fn score(&self, chain: &Chain, cands: &[Candidate], parallel: bool) -> Result<Scores> {
        let (x1, s) = self.each_with_residual(chain, cands, parallel, |_, r, g| {
            let rg: f64 = r.iter().zip(g).map(|(a, b)| a * b).sum();
            let gg: f64 = g.iter().map(|b| b * b).sum();
            (rg, gg)
        })?;
        Ok((self.y.iter().zip(&x1).map(|(a, b)| a - b).collect(), s))
    }

    /// The record's values.
    pub fn y(&self) -> &[f64] {
        &self.y
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::time::modal::Modes;

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
    fn chain_and_times(n: usize, defects: &str, d: f64, samples: usize) -> (Chain, Vec<f64>) {
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

    #[test]
    fn sensitivities_match_the_modal_derivative() {
        // every kind, a wall spring, a known defect of each kind on the chain
        let n = 12;
        let c = crate::scenes::three_kinds(n, [5, 8, 10])
            .unwrap()
            .with_d(0.05)
            .unwrap()
            .with_gamma(1.7)
            .unwrap();
        let t: Vec<f64> = (0..1201).map(|i| 0.1 * i as f64).collect();
        let y = vec![0.0; t.len()];
        let screen = Screen::new(&t, &y, &c).unwrap();
        let modes = Modes::new(&c).unwrap();
        let cands: Vec<Candidate> = [
            (DefectKind::Mass, &[1, 2, 3, 5, 12][..]),
            (DefectKind::Damper, &[1, 7, 10]),
            (DefectKind::Spring, &[0, 1, 4, 8, 12]),
        ]
        .into_iter()
        .flat_map(|(kind, at)| at.iter().map(move |&p| (kind, p)))
        .collect();
        for parallel in [false, true] {
            let (x1, gs) = screen
                .each(&c, &cands, parallel, |_, g| g.to_vec())
                .unwrap();
            assert_eq!(x1.len(), t.len());
            for (&(kind, p), g) in cands.iter().zip(&gs) {
                let site = kind.site(p);
                let (u, power): (Vec<(usize, f64)>, u32) =
                    (site.probe.entries(n).collect(), site.power);
                let exact = modes
                    .value_derivative(1, 1, c.gamma(), &u, power)
                    .unwrap()
                    .unwrap()
                    .eval_many(&t);
                let norm = exact.iter().map(|v| v * v).sum::<f64>().sqrt();
                let err = g
                    .iter()
                    .zip(&exact)
                    .map(|(a, b)| (a - b) * (a - b))
                    .sum::<f64>()
                    .sqrt()
                    / norm;
                // the trapezoid's end correction: mass 1's velocity jumps at
                // t = 0 (measured: 8e-4 next to mass 1, 5e-7 at mass 2, 2e-10
                // at mass 3, 2e-14 beyond)
                let nearest = if kind == DefectKind::Spring {
                    p.max(1)
                } else {
                    p
                };
                let tol = match nearest {
                    1 => 2e-3,
                    2 => 1e-5,
                    3 => 1e-8,
                    _ => 1e-12,
                };
                assert!(err < tol, "{kind:?} {p}: relative error {err:.2e}");
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

    /// Candidates beyond the front of a short record's simulation score
    /// exactly zero without a convolution, and the others score as when
    /// they are screened alone.
    #[test]
    fn candidates_beyond_the_front_score_zero() {
        use crate::detect::unknowns::DefectKind;
        let (c, t) = chain_and_times(200, "mass:3:2", 0.05, 161);
        let y: Vec<f64> = t.iter().map(|&x| 1e-3 * (0.3 * x).sin()).collect();
        let screen = Screen::new(&t, &y, &c).unwrap();
        let cands: Vec<Candidate> = (1..=200).map(|p| (DefectKind::Mass, p)).collect();
        let (r, all) = screen.score(&c, &cands, false).unwrap();
        let touched = simulate(&c, &screen.grid, &[]).unwrap().touched;
        assert!(touched > 20 && touched < 150, "{touched}");
        let live = touched.min(199);
        for (p, s) in (1..=200).zip(&all) {
            if p > touched {
                assert_eq!((s.0.abs(), s.1), (0.0, 0.0), "mass {p}");
            } else if p < touched - 60 {
                assert!(s.1 > 0.0, "mass {p}");
            }
        }
        let (r1, alone) = screen.score(&c, &cands[..live], false).unwrap();
        assert_eq!(r, r1);
        for (a, b) in alone.iter().zip(&all) {
            assert!(
                (a.0 - b.0).abs() <= 1e-12 * a.0.abs().max(1e-300),
                "{a:?} {b:?}"
            );
            assert!(
                (a.1 - b.1).abs() <= 1e-12 * a.1.abs().max(1e-300),
                "{a:?} {b:?}"
            );
        }
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
    }
}
