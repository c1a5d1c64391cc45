//! Weighted nonlinear least squares: one bounded Levenberg-Marquardt driver
//! and the Gauss-Newton (Fisher) covariance at its solution.
//!
//! The driver, [`lm_normal`], works on a problem given by its **normal
//! equations** ([`NormalEquations`]): `chi^2`, `g = J^T r` and `J^T J` at a
//! point, for whitened residuals `r_i(theta) = (model_i - data_i) / sigma_i`
//! (so that `chi^2 = sum r_i^2` is a chi-square at the truth). A problem that
//! gives the residual vector and its Jacobian ([`LeastSquares`], default
//! Jacobian by central differences) is solved by [`levenberg_marquardt`],
//! which adapts it to the normal equations and adds the Jacobian and the
//! covariance of the solution; the mass fits of the enumeration
//! ([`crate::detect::search::enumerate::fit_slots`]) give the normal
//! equations directly (the tabled Woodbury kernel accumulates them without
//! forming `J`, in log masses).
//!
//! The driver minimises `chi^2` on the box `lo <= theta <= hi` by damped
//! Gauss-Newton steps `(J^T J + mu diag(J^T J)) delta = -J^T r` (Marquardt's
//! scaling) on the **active set**: a variable at a bound whose descent
//! direction leaves the box is frozen for the step (plain clamping of the
//! full step would stall the others), the rest of the step is clamped into
//! the box. `mu` shrinks by `mu_down` (default 1/3) after an accepted step and
//! grows by `mu_up` (default 4) after a rejected one or a failed solve. Stops
//! when `chi^2` is zero, the relative decrease of `chi^2` falls below `rtol`
//! (default 1e-10) (with [`LmOptions::predicted_stop`], also when the
//! decrease the Gauss-Newton model predicts for the next step does), the
//! step below `xtol` relative (default 1e-10) or below
//! `xtol_abs` absolute (default 0: off), `mu` passes `mu_max`, or after
//! `max_iter` (default 100) normal-equation evaluations. It allocates no
//! memory per iteration (none at all for up to 8 parameters).
//!
//! ```
//! use springmass::detect::search::lsq::{levenberg_marquardt, LeastSquares, LmOptions};
//! struct Line;  // fit y = a + b x to three points, sigma = 0.1
//! impl LeastSquares for Line {
//!     fn residuals(&self, p: &[f64]) -> springmass::Result<Vec<f64>> {
//!         Ok([(0.0, 1.0), (1.0, 3.1), (2.0, 4.9)].iter()
//!             .map(|(x, y)| (p[0] + p[1] * x - y) / 0.1).collect())
//!     }
//! }
//! let fit = levenberg_marquardt(&Line, &[0.0, 0.0], &[(-10.0, 10.0); 2], &LmOptions::default())?;
//! assert!((fit.theta[1] - 1.95).abs() < 1e-9);
//! assert!((fit.std_errors()?[1] - 0.1 / 2f64.sqrt()).abs() < 1e-9);
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::error::{Error, Result};
use nalgebra::DMatrix;

/// A weighted least-squares problem (see the module docs).
pub trait LeastSquares {
    /// Whitened residuals at `theta`.
    ///
    /// # Errors
    /// A `theta` the model rejects.
    fn residuals(&self, theta: &[f64]) -> Result<Vec<f64>>;

    /// Jacobian `d r_i / d theta_j` (rows = residuals). Default: central
    /// differences with step `1e-6 max(|theta_j|, 1e-3)`.
    ///
    /// # Errors
    /// As [`LeastSquares::residuals`].
    fn jacobian(&self, theta: &[f64]) -> Result<DMatrix<f64>> {
        central_jacobian(self, theta, 1e-6)
    }
}

/// Central-difference Jacobian with relative step `rel`.
///
/// # Errors
/// As [`LeastSquares::residuals`].
pub fn central_jacobian<P: LeastSquares + ?Sized>(
    p: &P,
    theta: &[f64],
    rel: f64,
) -> Result<DMatrix<f64>> {
    let mut cols: Vec<Vec<f64>> = Vec::with_capacity(theta.len());
    let mut th = theta.to_vec();
    for (j, v) in theta.iter().enumerate() {
        let h = rel * v.abs().max(1e-3);
        cols.push(difference_column(p, &mut th, j, h)?);
    }
    let m = cols.first().map_or(0, Vec::len);
    Ok(DMatrix::from_fn(m, theta.len(), |i, j| cols[j][i]))
}

/// Column `j` of [`central_jacobian`] at `th` with step `h`: the central
/// difference; when one side leaves the model's domain (a value on or near
/// a bound such as `d >= 0` or `m > 0`, where `th[j] - h` is invalid), the
/// one-sided difference on the other side, so that the step never reaches
/// the caller as an error about a value the user did not give.
fn difference_column<P: LeastSquares + ?Sized>(
    p: &P,
    th: &mut [f64],
    j: usize,
    h: f64,
) -> Result<Vec<f64>> {
    let v = th[j];
    th[j] = v + h;
    let up = p.residuals(th);
    th[j] = v - h;
    let dn = p.residuals(th);
    th[j] = v;
    difference_within(up, dn, || p.residuals(th), h)
}

/// The central difference `(up - dn) / 2h` of residuals evaluated a step
/// `h` either side of a value; when one side failed (it left the model's
/// domain: a value on a bound such as `d >= 0`), the one-sided difference
/// of the other side against `center`, the residuals at the value itself.
///
/// # Errors
/// Both sides' failure (the first side's error), or `center`'s.
pub(crate) fn difference_within(
    up: Result<Vec<f64>>,
    dn: Result<Vec<f64>>,
    center: impl FnOnce() -> Result<Vec<f64>>,
    h: f64,
) -> Result<Vec<f64>> {
    let diff = |a: &[f64], b: &[f64], w: f64| -> Vec<f64> {
        a.iter().zip(b).map(|(a, b)| (a - b) / w).collect()
    };
    match (up, dn) {
        (Ok(up), Ok(dn)) => Ok(diff(&up, &dn, 2.0 * h)),
        (Ok(up), Err(_)) => Ok(diff(&up, &center()?, h)),
        (Err(_), Ok(dn)) => Ok(diff(&center()?, &dn, h)),
        (Err(e), Err(_)) => Err(e),
    }
}

/// Options of [`lm_normal`] and [`levenberg_marquardt`].
#[derive(Clone, Debug, PartialEq)]
pub struct LmOptions {
    /// Most normal-equation (Jacobian) evaluations [default 100].
    pub max_iter: usize,
    /// Relative decrease of `chi^2` that counts as converged [default 1e-10].
    pub rtol: f64,
    /// Relative step that counts as converged [default 1e-10].
    pub xtol: f64,
    /// Absolute step (largest component) that counts as converged, tested
    /// before the trial point is evaluated [default 0: off].
    pub xtol_abs: f64,
    /// Initial damping `mu` [default 1e-3].
    pub mu0: f64,
    /// Factor of `mu` after an accepted step [default 1/3].
    pub mu_down: f64,
    /// Factor of `mu` after a rejected step or a failed solve [default 4].
    pub mu_up: f64,
    /// Smallest `mu` [default 1e-12].
    pub mu_min: f64,
    /// Largest `mu`: beyond it the fit stops (converged) [default 1e20].
    pub mu_max: f64,
    /// Also stop (converged) when the decrease of `chi^2` the Gauss-Newton
    /// model predicts for the next step is below `rtol` (relative), while
    /// `mu <= mu0`: one evaluation fewer per fit, the point kept being that
    /// step short of the minimum (`chi^2` within about `rtol` relative of
    /// it) [default false].
    pub predicted_stop: bool,
}

impl Default for LmOptions {
    fn default() -> Self {
        LmOptions {
            max_iter: 100,
            rtol: 1e-10,
            xtol: 1e-10,
            xtol_abs: 0.0,
            mu0: 1e-3,
            mu_down: 1.0 / 3.0,
            mu_up: 4.0,
            mu_min: 1e-12,
            mu_max: 1e20,
            predicted_stop: false,
        }
    }
}

/// A least-squares problem given by its normal equations (see the module
/// docs): the interface of [`lm_normal`].
pub trait NormalEquations {
    /// `chi^2` at `theta`.
    ///
    /// # Errors
    /// A `theta` the model rejects (the driver treats it as an infinite
    /// `chi^2` at a trial point).
    fn chi2(&mut self, theta: &[f64]) -> Result<f64>;

    /// `chi^2` at `theta`, and the normal equations there: `g = J^T r`
    /// (half the gradient of `chi^2`) and `h = J^T J` (row-major `p x p`).
    /// The driver calls it at its starting point and at accepted points
    /// (after [`NormalEquations::chi2`] at the same point, unless
    /// [`NormalEquations::pieces_are_cheap`]).
    ///
    /// # Errors
    /// As [`NormalEquations::chi2`].
    fn normal(&mut self, theta: &[f64], g: &mut [f64], h: &mut [f64]) -> Result<f64>;

    /// Whether [`NormalEquations::normal`] costs about as little as
    /// [`NormalEquations::chi2`]: the driver then evaluates every trial point
    /// with its normal equations (one evaluation per iteration) instead of
    /// `chi^2` first and the normal equations after acceptance. Default false.
    fn pieces_are_cheap(&self) -> bool {
        false
    }
}

/// What [`lm_normal`] reports (the minimiser is left in its `theta`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LmReport {
    /// `chi^2` at the minimiser.
    pub chi2: f64,
    /// Normal-equation evaluations.
    pub iterations: usize,
    /// Points evaluated: the start and every trial point.
    pub evaluations: usize,
    /// Whether a tolerance was met (rather than `max_iter`).
    pub converged: bool,
}

/// Parameters up to which [`lm_normal`] works in stack buffers.
const STACK_P: usize = 8;

/// The first `n` places of `stack` when they are enough, else `heap`
/// resized to `n` (filled with `fill`): scratch space without an
/// allocation in the common case.
#[inline]
pub(crate) fn scratch<'a, T: Copy>(
    stack: &'a mut [T],
    heap: &'a mut Vec<T>,
    n: usize,
    fill: T,
) -> &'a mut [T] {
    if n <= stack.len() {
        &mut stack[..n]
    } else {
        heap.resize(n, fill);
        heap
    }
}

/// Bounded Levenberg-Marquardt on the normal equations from `theta`
/// (clamped into the bounds), which holds the minimiser on return.
///
/// # Errors
/// `bounds` of the wrong length or with `lo >= hi` (field `bounds`); the
/// first evaluation failing or its `chi^2` not finite; a failing
/// [`NormalEquations::normal`] at an accepted point.
pub fn lm_normal<P: NormalEquations + ?Sized>(
    problem: &mut P,
    theta: &mut [f64],
    bounds: &[(f64, f64)],
    opts: &LmOptions,
) -> Result<LmReport> {
    let p = theta.len();
    check_bounds(bounds, p)?;
    for (v, &(lo, hi)) in theta.iter_mut().zip(bounds) {
        *v = v.clamp(lo, hi);
    }
    // workspace: g, h, trial g, trial h, the reduced system a, b, the trial
    // point, and the active indices
    let mut stack = [0.0f64; 3 * STACK_P * STACK_P + 5 * STACK_P];
    let mut heap = Vec::new();
    let ws = scratch(&mut stack, &mut heap, 3 * p * p + 5 * p, 0.0);
    let (g, ws) = ws.split_at_mut(p);
    let (h, ws) = ws.split_at_mut(p * p);
    let (g_t, ws) = ws.split_at_mut(p);
    let (h_t, ws) = ws.split_at_mut(p * p);
    let (a, ws) = ws.split_at_mut(p * p);
    let (b, ws) = ws.split_at_mut(p);
    let (trial, further) = ws.split_at_mut(p);
    let mut act_stack = [0usize; STACK_P];
    let mut act_heap = Vec::new();
    let act = scratch(&mut act_stack, &mut act_heap, p, 0);
    let chi2 = problem.normal(theta, g, h)?;
    if !chi2.is_finite() {
        return Err(Error::Numerical {
            method: "levenberg-marquardt".into(),
            reason: "chi-square not finite at the starting point".into(),
        });
    }
    let mut w = Work {
        g,
        h,
        g_t,
        h_t,
        a,
        b,
        trial,
        further,
        act,
    };
    iterate(problem, theta, bounds, opts, &mut w, chi2)
}

/// The workspace of [`lm_normal`]: `g` and `h` at the current point and at
/// the trial point, the reduced system `a`, `b` of the active set `act`,
/// the trial point and a point further along its step ([`further`]).
struct Work<'w> {
    g: &'w mut [f64],
    h: &'w mut [f64],
    g_t: &'w mut [f64],
    h_t: &'w mut [f64],
    a: &'w mut [f64],
    b: &'w mut [f64],
    trial: &'w mut [f64],
    further: &'w mut [f64],
    act: &'w mut [usize],
}

/// The iterations of [`lm_normal`] from `theta`, where `chi^2 = chi2` and
/// the normal equations are in `w.g`, `w.h`.
fn iterate<P: NormalEquations + ?Sized>(
    problem: &mut P,
    theta: &mut [f64],
    bounds: &[(f64, f64)],
    opts: &LmOptions,
    w: &mut Work,
    mut chi2: f64,
) -> Result<LmReport> {
    let cheap = problem.pieces_are_cheap();
    let (mut iterations, mut evaluations) = (1, 1);
    let (mut mu, mut converged) = (opts.mu0, false);
    while iterations <= opts.max_iter {
        crate::cancel::check()?;
        if chi2 == 0.0 {
            converged = true;
            break;
        }
        let fa = active_set(theta, bounds, w.g, w.act);
        if fa == 0 {
            converged = true;
            break;
        }
        let act = &w.act[..fa];
        let (a, b) = (&mut w.a[..fa * fa], &mut w.b[..fa]);
        damped_system(act, w.g, w.h, mu, a, b);
        if !cholesky_solve(a, b, fa) {
            mu *= opts.mu_up;
            if mu > opts.mu_max {
                converged = true;
                break;
            }
            continue;
        }
        if predicted_stop(opts, (mu, chi2), act, w.g, w.h, b) {
            converged = true;
            break;
        }
        let (moved_abs, moved) = trial_point(theta, bounds, act, b, w.trial);
        if moved_abs < opts.xtol_abs {
            converged = true;
            break;
        }
        let c2 = if cheap {
            iterations += 1;
            problem.normal(w.trial, w.g_t, w.h_t)
        } else {
            problem.chi2(w.trial)
        };
        evaluations += 1;
        let mut c2 = c2.unwrap_or(f64::INFINITY);
        if c2.is_finite() && c2 <= chi2 {
            if !cheap && mu <= CRAWL_MU {
                let (tried, f) = further(problem, (theta, bounds), w, (chi2, c2));
                evaluations += usize::from(tried);
                c2 = f.unwrap_or(c2);
            }
            let dec = (chi2 - c2) / chi2.max(1e-300);
            theta.copy_from_slice(w.trial);
            chi2 = c2;
            mu = (mu * opts.mu_down).max(opts.mu_min);
            if dec < opts.rtol || moved < opts.xtol {
                converged = true;
                break;
            }
            if cheap {
                w.g.copy_from_slice(w.g_t);
                w.h.copy_from_slice(w.h_t);
            } else {
                chi2 = problem.normal(theta, w.g, w.h)?;
                iterations += 1;
            }
        } else {
            mu *= opts.mu_up;
            if mu > opts.mu_max || moved < opts.xtol {
                converged = true;
                break;
            }
        }
    }
    Ok(LmReport {
        chi2,
        iterations,
        evaluations,
        converged,
    })
}

/// The damping `mu` at and below which an accepted step is a Gauss-Newton
/// step (the damping's share of the system under a millionth), where
/// [`further`] looks along it.
const CRAWL_MU: f64 = 1e-6;

/// The multiples of an accepted Gauss-Newton step [`further`] tries: at
/// least `FURTHER.0` (a shorter one is the step itself, near enough), at
/// most `FURTHER.1`.
const FURTHER: (f64, f64) = (2.0, 16.0);

/// The chi-square at a point further along the accepted Gauss-Newton step
/// `d = trial - theta` (chi-square `f0` at `theta`, `f1` at the trial),
/// moved into `w.trial`, when it is lower than `f1`; `None` otherwise
/// (`w.trial` kept); first whether a point was evaluated. One evaluation,
/// at the minimum of the parabola through `f0`, the slope `2 g.d` and
/// `f1`, made only where that minimum is at least [`FURTHER`]`.0` steps
/// out. A point tried and not kept costs one residual more: the adapter
/// keeps the residuals of the last point only, and the normal equations
/// at the trial evaluate them again.
///
/// Why: where the model cannot explain the data (a large residual) the
/// Gauss-Newton matrix `J^T J` can overstate the chi-square's curvature
/// many times, and its steps are then too short by as much: each step
/// along the same direction, the chi-square falling by a near constant
/// fraction (measured: a between-storey damping model fitted to a record
/// damped to the ground fell by 2 in 64 000 per step and stopped at the
/// 100-step limit, 35 short of its minimum). Near a minimum that explains
/// the data the parabola's minimum is the step itself (within a few per
/// cent) and no point is tried.
fn further<P: NormalEquations + ?Sized>(
    problem: &mut P,
    (theta, bounds): (&[f64], &[(f64, f64)]),
    w: &mut Work,
    (f0, f1): (f64, f64),
) -> (bool, Option<f64>) {
    let slope: f64 = (0..theta.len())
        .map(|i| 2.0 * w.g[i] * (w.trial[i] - theta[i]))
        .sum();
    // a slope that is not a descent (or not a number): nothing to extend
    if slope.is_nan() || slope >= 0.0 {
        return (false, None);
    }
    // f(t) = f0 + slope t + c t^2 through f(1) = f1
    let c = f1 - f0 - slope;
    let t = if c > 0.0 {
        -slope / (2.0 * c)
    } else {
        FURTHER.1
    };
    if t.is_nan() || t < FURTHER.0 {
        return (false, None);
    }
    let t = t.min(FURTHER.1);
    for (i, (&v, &(lo, hi))) in theta.iter().zip(bounds).enumerate() {
        w.further[i] = (v + t * (w.trial[i] - v)).clamp(lo, hi);
    }
    match problem.chi2(w.further) {
        Ok(f) if f < f1 => {
            w.trial.copy_from_slice(w.further);
            (true, Some(f))
        }
        _ => (true, None),
    }
}

/// Whether the step `delta` would end the fit anyway (with
/// [`LmOptions::predicted_stop`]): the decrease the Gauss-Newton model
/// predicts for it below `rtol chi^2` (undamped beyond the start, so that
/// the step is not merely shortened); the fit then stops before evaluating
/// it.
#[inline]
fn predicted_stop(
    opts: &LmOptions,
    (mu, chi2): (f64, f64),
    act: &[usize],
    g: &[f64],
    h: &[f64],
    delta: &[f64],
) -> bool {
    if !(opts.predicted_stop && mu <= opts.mu0) {
        return false;
    }
    let pred = predicted_decrease(act, g, h, delta);
    pred.is_finite() && pred >= 0.0 && pred < opts.rtol * chi2
}

/// The active set into `act`: the free variables, and those at a bound
/// whose descent direction (`-g`) points into the box. Returns its size.
#[inline]
fn active_set(theta: &[f64], bounds: &[(f64, f64)], g: &[f64], act: &mut [usize]) -> usize {
    let mut fa = 0;
    for (i, (&v, &(lo, hi))) in theta.iter().zip(bounds).enumerate() {
        if !((v <= lo && g[i] > 0.0) || (v >= hi && g[i] < 0.0)) {
            act[fa] = i;
            fa += 1;
        }
    }
    fa
}

/// The damped system of the active variables `act`: `a = H_aa + mu
/// diag(H_aa)` (row-major) and `b = -g_a`, for the full `g` and `h`.
#[inline]
fn damped_system(act: &[usize], g: &[f64], h: &[f64], mu: f64, a: &mut [f64], b: &mut [f64]) {
    let (p, fa) = (g.len(), act.len());
    for (r, &i) in act.iter().enumerate() {
        b[r] = -g[i];
        for (c, &j) in act.iter().enumerate() {
            a[r * fa + c] = h[i * p + j];
        }
        a[r * fa + r] += mu * h[i * p + i].max(1e-300);
    }
}

/// The decrease of `chi^2` the Gauss-Newton model predicts for the step
/// `delta` of the active variables: `-(2 g.delta + delta^T H delta)`.
#[inline]
fn predicted_decrease(act: &[usize], g: &[f64], h: &[f64], delta: &[f64]) -> f64 {
    let p = g.len();
    let mut pred = 0.0;
    for (r, &i) in act.iter().enumerate() {
        let mut hd = 0.0;
        for (c, &j) in act.iter().enumerate() {
            hd += h[i * p + j] * delta[c];
        }
        pred -= delta[r] * (2.0 * g[i] + hd);
    }
    pred
}

/// The trial point `theta + delta` on the active variables, clamped into
/// the box, into `trial`; returns the largest absolute and relative moves.
#[inline]
fn trial_point(
    theta: &[f64],
    bounds: &[(f64, f64)],
    act: &[usize],
    delta: &[f64],
    trial: &mut [f64],
) -> (f64, f64) {
    trial.copy_from_slice(theta);
    let (mut moved_abs, mut moved) = (0.0f64, 0.0f64);
    for (r, &i) in act.iter().enumerate() {
        let (lo, hi) = bounds[i];
        trial[i] = (theta[i] + delta[r]).clamp(lo, hi);
        let d = (trial[i] - theta[i]).abs();
        moved_abs = moved_abs.max(d);
        moved = moved.max(d / theta[i].abs().max(1e-12));
    }
    (moved_abs, moved)
}

fn check_bounds(bounds: &[(f64, f64)], p: usize) -> Result<()> {
    if bounds.len() != p {
        return Err(Error::invalid(
            "bounds",
            bounds.len(),
            format!("one (lo, hi) per parameter ({p})"),
        ));
    }
    for (i, &(lo, hi)) in bounds.iter().enumerate() {
        if lo.is_nan() || hi.is_nan() || lo >= hi {
            return Err(Error::invalid(
                format!("bounds[{i}]"),
                format!("({lo}, {hi})"),
                "lo < hi",
            ));
        }
    }
    Ok(())
}

/// Solve the symmetric positive definite `n x n` system `a x = b` in place
/// (Cholesky; `x` in `b`, `a` overwritten). False when a pivot is not
/// positive or a value not finite.
fn cholesky_solve(a: &mut [f64], b: &mut [f64], n: usize) -> bool {
    for j in 0..n {
        let mut d = a[j * n + j];
        for k in 0..j {
            d -= a[j * n + k] * a[j * n + k];
        }
        if !(d > 0.0 && d.is_finite()) {
            return false;
        }
        let d = d.sqrt();
        a[j * n + j] = d;
        for i in j + 1..n {
            let mut v = a[i * n + j];
            for k in 0..j {
                v -= a[i * n + k] * a[j * n + k];
            }
            a[i * n + j] = v / d;
        }
    }
    for i in 0..n {
        let mut v = b[i];
        for k in 0..i {
            v -= a[i * n + k] * b[k];
        }
        b[i] = v / a[i * n + i];
    }
    for i in (0..n).rev() {
        let mut v = b[i];
        for k in i + 1..n {
            v -= a[k * n + i] * b[k];
        }
        b[i] = v / a[i * n + i];
    }
    b.iter().all(|x| x.is_finite())
}

/// A [`LeastSquares`] problem as normal equations: keeps the residuals of the
/// last evaluated point, so that the normal equations at an accepted point
/// cost only the Jacobian.
struct Adapter<'a, P: ?Sized> {
    problem: &'a P,
    /// The last point evaluated and its residuals.
    last: Vec<f64>,
    r: Vec<f64>,
    /// The last Jacobian formed and its point (the driver's last accepted
    /// point, where the fit often ends).
    jac: Option<(Vec<f64>, DMatrix<f64>)>,
}

impl<P: LeastSquares + ?Sized> Adapter<'_, P> {
    fn residuals_at(&mut self, theta: &[f64]) -> Result<&[f64]> {
        if self.last != theta || self.r.is_empty() {
            self.r = self.problem.residuals(theta)?;
            self.last.clear();
            self.last.extend_from_slice(theta);
        }
        Ok(&self.r)
    }
}

impl<P: LeastSquares + ?Sized> NormalEquations for Adapter<'_, P> {
    fn chi2(&mut self, theta: &[f64]) -> Result<f64> {
        Ok(chi2_of(self.residuals_at(theta)?))
    }

    fn normal(&mut self, theta: &[f64], g: &mut [f64], h: &mut [f64]) -> Result<f64> {
        let chi2 = chi2_of(self.residuals_at(theta)?);
        if !chi2.is_finite() {
            // the driver stops on it; no Jacobian of a point it rejects
            return Ok(chi2);
        }
        let j = self.problem.jacobian(theta)?;
        let p = theta.len();
        let m = self.r.len();
        if j.nrows() != m || j.ncols() != p {
            return Err(Error::Numerical {
                method: "levenberg-marquardt".into(),
                reason: format!(
                    "a {}x{} Jacobian for {m} residuals and {p} parameters",
                    j.nrows(),
                    j.ncols()
                ),
            });
        }
        // J^T r and J^T J from the columns of J (column-major), no temporaries
        let col = |a: usize| &j.as_slice()[a * m..(a + 1) * m];
        for a in 0..p {
            g[a] = dot(col(a), &self.r);
            for b in 0..=a {
                let v = dot(col(a), col(b));
                h[a * p + b] = v;
                h[b * p + a] = v;
            }
        }
        self.jac = Some((theta.to_vec(), j));
        Ok(chi2)
    }
}

/// The result of [`levenberg_marquardt`].
#[derive(Clone, Debug)]
pub struct LmFit {
    /// The minimiser.
    pub theta: Vec<f64>,
    /// `chi^2` there.
    pub chi2: f64,
    /// Number of residuals.
    pub m: usize,
    /// The Jacobian at `theta`.
    pub jacobian: DMatrix<f64>,
    /// Jacobian evaluations.
    pub iterations: usize,
    /// Residual evaluations (Jacobians by differences not counted).
    pub evaluations: usize,
    /// Whether a tolerance was met (rather than `max_iter`).
    pub converged: bool,
    /// Indices of parameters that ended on a bound.
    pub at_bound: Vec<usize>,
}

impl LmFit {
    /// Degrees of freedom `m - p`.
    pub fn dof(&self) -> usize {
        self.m.saturating_sub(self.theta.len())
    }

    /// Gauss-Newton covariance `(J^T J)^{-1}` (the inverse Fisher information
    /// for whitened residuals).
    ///
    /// # Errors
    /// [`Error::Unresolvable`] when `J^T J` is singular (a parameter the data do
    /// not constrain).
    pub fn covariance(&self) -> Result<DMatrix<f64>> {
        covariance(&self.jacobian)
    }

    /// Standard errors `sqrt(diag((J^T J)^{-1}))`.
    ///
    /// # Errors
    /// As [`LmFit::covariance`].
    pub fn std_errors(&self) -> Result<Vec<f64>> {
        Ok(self
            .covariance()?
            .diagonal()
            .iter()
            .map(|v| v.max(0.0).sqrt())
            .collect())
    }
}

/// `(J^T J)^{-1}` by an SVD pseudo-inverse with a relative cutoff of `1e-13`.
///
/// # Errors
/// [`Error::Unresolvable`] when a singular value falls below the cutoff.
pub fn covariance(j: &DMatrix<f64>) -> Result<DMatrix<f64>> {
    let p = j.ncols();
    if p == 0 {
        return Ok(DMatrix::zeros(0, 0));
    }
    if j.nrows() < p {
        // fewer residuals than parameters: `J^T J` has rank <= rows < p
        return Err(Error::Unresolvable {
            reason: format!(
                "the data do not constrain all {p} parameters: only {} residual rows (need at least {p}; use a longer or denser record, or fewer unknowns)",
                j.nrows()
            ),
        });
    }
    // column scaling for conditioning
    let scale: Vec<f64> = (0..p)
        .map(|c| {
            let n = j.column(c).norm();
            if n > 0.0 {
                1.0 / n
            } else {
                1.0
            }
        })
        .collect();
    let js = DMatrix::from_fn(j.nrows(), p, |r, c| j[(r, c)] * scale[c]);
    // not finite (or no SVD): the data constrain nothing measurable, as a NaN
    // singular value said before the SVD was checked
    let svd = crate::linalg::svd_checked(js, false, true).ok_or_else(|| Error::Unresolvable {
        reason: format!("the Jacobian of the {p} parameters is not finite"),
    })?;
    let smax = svd.singular_values.max();
    let smin = svd.singular_values.min();
    if smin.is_nan() || smin <= 1e-13 * smax {
        return Err(Error::Unresolvable {
            reason: format!(
                "the data do not constrain all {p} parameters (singular value ratio {:.1e})",
                if smax > 0.0 { smin / smax } else { 0.0 }
            ),
        });
    }
    let vt = svd.v_t.expect("v_t requested");
    let mut cov: DMatrix<f64> = DMatrix::zeros(p, p);
    for k in 0..p {
        let s2 = svd.singular_values[k] * svd.singular_values[k];
        for a in 0..p {
            for b in 0..p {
                cov[(a, b)] += vt[(k, a)] * vt[(k, b)] / s2;
            }
        }
    }
    Ok(DMatrix::from_fn(p, p, |a, b| {
        cov[(a, b)] * scale[a] * scale[b]
    }))
}

/// `sum_i a_i b_i`, four interleaved partial sums.
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut acc = [0.0f64; 4];
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for ((s, x), y) in acc.iter_mut().zip(x).zip(y) {
            *s += x * y;
        }
    }
    let tail: f64 = ra.iter().zip(rb).map(|(x, y)| x * y).sum();
    ((acc[0] + acc[1]) + (acc[2] + acc[3])) + tail
}

fn chi2_of(r: &[f64]) -> f64 {
    r.iter().map(|v| v * v).sum()
}

/// Bounded Levenberg-Marquardt from `theta0` (clamped into the bounds):
/// [`lm_normal`] on the normal equations of `problem`, with the Jacobian at
/// the minimiser for its covariance.
///
/// # Errors
/// `bounds` of the wrong length or with `lo >= hi` (field `bounds`); the first
/// residual evaluation failing; a non-finite `chi^2` at the start.
pub fn levenberg_marquardt<P: LeastSquares + ?Sized>(
    problem: &P,
    theta0: &[f64],
    bounds: &[(f64, f64)],
    opts: &LmOptions,
) -> Result<LmFit> {
    check_bounds(bounds, theta0.len())?;
    let mut adapter = Adapter {
        problem,
        last: Vec::new(),
        r: Vec::new(),
        jac: None,
    };
    let mut theta = theta0.to_vec();
    let report = lm_normal(&mut adapter, &mut theta, bounds, opts)?;
    // Jacobian at the final point (formed there already when the fit ended
    // at an accepted point without a further step)
    let jacobian = match adapter.jac.take() {
        Some((at, j)) if at == theta => j,
        _ => problem.jacobian(&theta)?,
    };
    let m = adapter.residuals_at(&theta)?.len();
    let at_bound = theta
        .iter()
        .zip(bounds)
        .enumerate()
        .filter(|(_, (v, (lo, hi)))| **v <= *lo || **v >= *hi)
        .map(|(i, _)| i)
        .collect();
    Ok(LmFit {
        theta,
        chi2: report.chi2,
        m,
        jacobian,
        iterations: report.iterations,
        evaluations: report.evaluations,
        converged: report.converged,
        at_bound,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Exp {
        t: Vec<f64>,
        y: Vec<f64>,
    }

    impl Exp {
        /// The fit from `(1, 0.1)` with the amplitude in `[0.1, a_max]`, the
        /// rate in `[0, 5]`.
        fn fit(&self, a_max: f64) -> LmFit {
            levenberg_marquardt(
                self,
                &[1.0, 0.1],
                &[(0.1, a_max), (0.0, 5.0)],
                &LmOptions::default(),
            )
            .unwrap()
        }
    }
    impl LeastSquares for Exp {
        fn residuals(&self, p: &[f64]) -> Result<Vec<f64>> {
            Ok(self
                .t
                .iter()
                .zip(&self.y)
                .map(|(t, y)| (p[0] * (-p[1] * t).exp() - y) / 0.01)
                .collect())
        }
    }

    /// `(theta - 2, 1 - e (theta - 2)^2)`: a residual that stays 1 at the
    /// minimum `theta = 2`, where `J^T J = 1` overstates the chi-square's
    /// curvature `1 - 2 e` so that Gauss-Newton steps shrink the distance
    /// to it only by the factor `2 e` each.
    struct Crawl(f64);
    impl LeastSquares for Crawl {
        fn residuals(&self, p: &[f64]) -> Result<Vec<f64>> {
            let x = p[0] - 2.0;
            Ok(vec![x, 1.0 - self.0 * x * x])
        }
    }

    #[test]
    fn a_crawl_of_gauss_newton_steps_is_cut_short_along_the_step() {
        // factor 0.9 a step: 30 Gauss-Newton steps leave 0.9^30 = 0.04
        let opts = LmOptions {
            max_iter: 30,
            ..LmOptions::default()
        };
        let f = levenberg_marquardt(&Crawl(0.45), &[3.0], &[(0.0, 10.0)], &opts).unwrap();
        assert!(f.converged, "{f:?}");
        assert!((f.theta[0] - 2.0).abs() < 1e-4, "{:?}", f.theta);
        assert!((f.chi2 - 1.0).abs() < 1e-8, "{}", f.chi2);
    }

    #[test]
    fn a_point_past_the_step_only_where_the_parabola_puts_its_minimum() {
        // a linear residual (chi^2 = (theta - 2)^2 + 1): from theta = 3,
        // g = 1, h = 1
        let mut ad = Adapter {
            problem: &Crawl(0.0),
            last: Vec::new(),
            r: Vec::new(),
            jac: None,
        };
        let (mut g, mut h, mut gt, mut ht) = ([0.0], [0.0], [0.0], [0.0]);
        let (mut a, mut b, mut trial, mut past, mut act) = ([0.0], [0.0], [0.0], [0.0], [0]);
        let f0 = ad.normal(&[3.0], &mut g, &mut h).unwrap();
        // (a differenced Jacobian)
        assert_eq!(f0, 2.0);
        assert!((g[0] - 1.0).abs() < 1e-9 && (h[0] - 1.0).abs() < 1e-9);
        let mut w = Work {
            g: &mut g,
            h: &mut h,
            g_t: &mut gt,
            h_t: &mut ht,
            a: &mut a,
            b: &mut b,
            trial: &mut trial,
            further: &mut past,
            act: &mut act,
        };
        let bounds = [(0.0, 10.0)];
        // the Gauss-Newton step, exact here: no point tried
        w.trial[0] = 2.0;
        let out = further(&mut ad, (&[3.0], &bounds), &mut w, (f0, 1.0));
        assert_eq!(out, (false, None));
        assert_eq!(w.trial[0], 2.0);
        // a step a tenth as long: the parabola's minimum 10 steps out,
        // at the minimum, taken
        w.trial[0] = 2.9;
        let out = further(&mut ad, (&[3.0], &bounds), &mut w, (f0, 1.81));
        assert!(out.0);
        assert!((out.1.unwrap() - 1.0).abs() < 1e-12, "{out:?}");
        assert!((w.trial[0] - 2.0).abs() < 1e-9);
        // a bound before it: the point clamped, still lower
        w.trial[0] = 2.9;
        let out = further(&mut ad, (&[3.0], &[(2.5, 10.0)]), &mut w, (f0, 1.81));
        assert!(out.0);
        assert_eq!(w.trial[0], 2.5);
    }

    #[test]
    fn fewer_residuals_than_parameters_is_an_error_not_a_panic() {
        // one datum, two parameters: J is 1 x 2, J^T J singular
        let pr = Exp {
            t: vec![0.5],
            y: vec![1.0],
        };
        let f = pr.fit(10.0);
        assert_eq!((f.jacobian.nrows(), f.jacobian.ncols()), (1, 2));
        assert_eq!(f.dof(), 0);
        for e in [f.covariance().unwrap_err(), f.std_errors().unwrap_err()] {
            match e {
                Error::Unresolvable { reason } => {
                    assert!(reason.contains("only 1 residual rows"), "{reason}");
                    assert!(reason.contains("all 2 parameters"), "{reason}");
                }
                e => panic!("{e:?}"),
            }
        }
        assert!(covariance(&DMatrix::zeros(2, 3)).is_err());
        assert!(covariance(&DMatrix::identity(3, 3)).is_ok());
    }

    #[test]
    fn recovers_exponential_and_respects_bounds() {
        let t: Vec<f64> = (0..50).map(|i| i as f64 * 0.1).collect();
        let y: Vec<f64> = t.iter().map(|t| 2.0 * (-0.7 * t).exp()).collect();
        let pr = Exp { t, y };
        let f = pr.fit(10.0);
        assert!(
            (f.theta[0] - 2.0).abs() < 1e-8 && (f.theta[1] - 0.7).abs() < 1e-8,
            "{:?}",
            f.theta
        );
        assert!(f.chi2 < 1e-12);
        let g = pr.fit(1.5);
        assert_eq!(g.theta[0], 1.5);
        assert_eq!(g.at_bound, vec![0]);
        assert!(levenberg_marquardt(
            &pr,
            &[1.0],
            &[(0.0, 1.0), (0.0, 1.0)],
            &LmOptions::default()
        )
        .is_err());
        assert!(levenberg_marquardt(
            &pr,
            &[1.0, 1.0],
            &[(1.0, 1.0), (0.0, 1.0)],
            &LmOptions::default()
        )
        .is_err());
    }

    /// `y = a t` with `a >= 0` required by the model (as `d >= 0`): a
    /// negative `a` is an error, as a chain with a negative damping is.
    struct NonNegative {
        t: Vec<f64>,
        y: Vec<f64>,
    }
    impl LeastSquares for NonNegative {
        fn residuals(&self, p: &[f64]) -> Result<Vec<f64>> {
            if p[0] < 0.0 {
                return Err(Error::invalid("a", p[0], "a >= 0"));
            }
            Ok(self
                .t
                .iter()
                .zip(&self.y)
                .map(|(t, y)| p[0] * t - y)
                .collect())
        }
    }

    #[test]
    fn the_difference_step_never_leaves_the_domain_at_a_bound() {
        let t: Vec<f64> = (0..20).map(f64::from).collect();
        // the data want a < 0: the fit ends on the bound a = 0, where the
        // central difference would evaluate a = -1e-9
        let y: Vec<f64> = t.iter().map(|t| -0.5 * t).collect();
        let pr = NonNegative { t: t.clone(), y };
        let j = central_jacobian(&pr, &[0.0], 1e-6).unwrap();
        for (i, &ti) in t.iter().enumerate() {
            assert!(
                (j[(i, 0)] - ti).abs() <= 1e-6 * ti.max(1.0),
                "{}",
                j[(i, 0)]
            );
        }
        let f = levenberg_marquardt(&pr, &[0.0], &[(0.0, 10.0)], &LmOptions::default()).unwrap();
        assert_eq!(f.theta, vec![0.0]);
        // inside the domain the central difference is unchanged
        let y: Vec<f64> = t.iter().map(|t| 2.0 * t).collect();
        let pr = NonNegative { t, y };
        let f = levenberg_marquardt(&pr, &[1.0], &[(0.0, 10.0)], &LmOptions::default()).unwrap();
        assert!((f.theta[0] - 2.0).abs() < 1e-10, "{:?}", f.theta);
    }

    /// Rosenbrock as least squares, `r = (10 (y - x^2), 1 - x)`, given by
    /// its normal equations; counts the evaluations of each kind.
    struct Rosen {
        cheap: bool,
        chi2_calls: usize,
        normal_calls: usize,
    }
    impl Rosen {
        fn new(cheap: bool) -> Rosen {
            Rosen {
                cheap,
                chi2_calls: 0,
                normal_calls: 0,
            }
        }
        fn r(t: &[f64]) -> [f64; 2] {
            [10.0 * (t[1] - t[0] * t[0]), 1.0 - t[0]]
        }
    }
    impl NormalEquations for Rosen {
        fn chi2(&mut self, t: &[f64]) -> Result<f64> {
            self.chi2_calls += 1;
            Ok(chi2_of(&Rosen::r(t)))
        }
        fn normal(&mut self, t: &[f64], g: &mut [f64], h: &mut [f64]) -> Result<f64> {
            self.normal_calls += 1;
            let r = Rosen::r(t);
            let j = [[-20.0 * t[0], 10.0], [-1.0, 0.0]];
            for a in 0..2 {
                g[a] = j[0][a] * r[0] + j[1][a] * r[1];
                for b in 0..2 {
                    h[a * 2 + b] = j[0][a] * j[0][b] + j[1][a] * j[1][b];
                }
            }
            Ok(chi2_of(&r))
        }
        fn pieces_are_cheap(&self) -> bool {
            self.cheap
        }
    }
    impl LeastSquares for Rosen {
        fn residuals(&self, t: &[f64]) -> Result<Vec<f64>> {
            Ok(Rosen::r(t).to_vec())
        }
    }

    #[test]
    fn normal_equations_driver_both_modes() {
        let opts = LmOptions::default();
        let bounds = [(-5.0, 5.0); 2];
        for cheap in [false, true] {
            let mut pr = Rosen::new(cheap);
            let mut t = [-1.2, 1.0];
            let rep = lm_normal(&mut pr, &mut t, &bounds, &opts).unwrap();
            assert!(rep.converged && rep.chi2 < 1e-20, "{cheap}: {rep:?}");
            assert!((t[0] - 1.0).abs() < 1e-9 && (t[1] - 1.0).abs() < 1e-9);
            assert_eq!(rep.iterations, pr.normal_calls);
            // one evaluation per trial, of chi^2 or of the normal equations
            assert_eq!(
                rep.evaluations,
                pr.chi2_calls + pr.normal_calls - {
                    if cheap {
                        0
                    } else {
                        pr.normal_calls - 1
                    }
                }
            );
            if cheap {
                assert_eq!(pr.chi2_calls, 0);
            }
        }
        // the residual form reaches the same point through the adapter
        let fit = levenberg_marquardt(&Rosen::new(false), &[-1.2, 1.0], &bounds, &opts).unwrap();
        assert!((fit.theta[0] - 1.0).abs() < 1e-9 && fit.chi2 < 1e-20);
        assert_eq!(fit.m, 2);
    }

    #[test]
    fn active_set_frees_the_other_variable() {
        // x <= 0.5 cuts off the minimum (1, 1): the constrained minimum is
        // x = 0.5 on the bound, y = x^2 = 0.25 exactly (the frozen x does not
        // stall y)
        for cheap in [false, true] {
            let mut pr = Rosen::new(cheap);
            let mut t = [-1.2, 1.0];
            let bounds = [(-5.0, 0.5), (-5.0, 5.0)];
            let rep = lm_normal(&mut pr, &mut t, &bounds, &LmOptions::default()).unwrap();
            assert!(rep.converged);
            assert_eq!(t[0], 0.5);
            assert!((t[1] - 0.25).abs() < 1e-9, "{t:?}");
            assert!((rep.chi2 - 0.25).abs() < 1e-12);
        }
        // a start outside the box is clamped; an exact fit stops at once
        let mut pr = Rosen::new(true);
        let mut t = [1.0, 1.0];
        let rep = lm_normal(&mut pr, &mut t, &[(-5.0, 5.0); 2], &LmOptions::default()).unwrap();
        assert_eq!((rep.chi2, rep.iterations, rep.evaluations), (0.0, 1, 1));
        let mut t = [9.0, 1.0];
        lm_normal(&mut pr, &mut t, &[(-5.0, 5.0); 2], &LmOptions::default()).unwrap();
        assert!((t[0] - 1.0).abs() < 1e-9);
        assert!(lm_normal(&mut pr, &mut t, &[(-5.0, 5.0)], &LmOptions::default()).is_err());
    }

    #[test]
    fn cholesky_solves_and_refuses() {
        let mut a = [4.0, 2.0, 2.0, 3.0];
        let mut b = [2.0, 1.0];
        assert!(cholesky_solve(&mut a, &mut b, 2));
        assert!((b[0] - 0.5).abs() < 1e-15 && b[1].abs() < 1e-15);
        let mut a = [1.0, 2.0, 2.0, 1.0];
        assert!(!cholesky_solve(&mut a, &mut [1.0, 1.0], 2));
        let mut a = [f64::NAN];
        assert!(!cholesky_solve(&mut a, &mut [1.0], 1));
    }

    #[test]
    fn covariance_detects_unconstrained() {
        let j = DMatrix::from_row_slice(3, 2, &[1.0, 2.0, 2.0, 4.0, 3.0, 6.0]);
        assert!(covariance(&j).is_err());
        let j = DMatrix::from_row_slice(3, 2, &[1.0, 0.0, 0.0, 2.0, 0.0, 0.0]);
        let c = covariance(&j).unwrap();
        assert!((c[(0, 0)] - 1.0).abs() < 1e-14 && (c[(1, 1)] - 0.25).abs() < 1e-14);
    }
}
