//! Numerical inverse Laplace transform of a general `F(s)`, with a
//! consistency check that refuses what `f64` cannot deliver.
//!
//! Two independent methods:
//!
//! * [`talbot`]: fixed Talbot (Abate & Valkó 2004). `M` evaluations on the
//!   contour `s(θ) = r θ (cot θ + i)`, `r = 2M/(5t)`:
//!   `f(t) ≈ (r/M) [½ F(r) e^{rt} + Σ_{k=1}^{M-1} Re(e^{t s_k} F(s_k) (1 + i σ_k))]`,
//!   `θ_k = kπ/M`, `σ(θ) = θ + (θ cot θ - 1) cot θ`. Very fast for short times,
//!   but the contour crosses the imaginary axis near `±i r π/2`: every pole
//!   with `|Im p| > r π/2 ≈ 0.63 M/t` is left outside and its mode is *silently
//!   missing*. With `f64` the usable `M` is about 20-30 (rounding grows like
//!   `e^{0.4 M}`), so lightly damped oscillations with frequencies up to 2 are
//!   lost from `t ≈ 0.3 M` on (mpmath's default degree 93 fails from `t ≈ 28`
//!   for the same reason). Two Talbot runs can agree on the wrong answer
//!   (when the same poles are outside both contours), so Talbot alone is
//!   never trusted.
//! * [`de_hoog`]: de Hoog, Knight & Stokes (1982). The Bromwich integral on
//!   `Re s = γ` discretised as a Fourier series of period `2T`,
//!   `T = scale · t` (default `scale = 2`), `γ = α - ln(tol)/(2T)`, summed
//!   with the quotient-difference continued fraction and its analytic
//!   remainder; `2M + 1` evaluations of `F` at `γ + i kπ/T`. The Bromwich line
//!   lies to the right of every singularity, so no mode is lost; its errors
//!   (aliasing, truncation of the accelerated series) change when `M` and
//!   `T` change.
//!
//! [`invert`] combines them: two de Hoog runs with different `M`, `T` and
//! `γ` must agree; the result carries an error estimate built from their
//! disagreement and the Talbot value as a cross-check. If the error
//! estimate exceeds `atol + rtol |f|` even at the largest depth it returns
//! [`Error::Numerical`] rather than a value: the typical case is a long
//! time at light damping (with `d = 0.1`, frequencies up to 2: from about
//! `t = 40` on), where rounding in the quotient-difference table grows.
//!
//! ```
//! use springmass::time::inverse::{invert, InverseOptions};
//! use springmass::Complex64;
//! // F(s) = 1/((s + 0.05)^2 + 1)  ->  f(t) = e^{-0.05 t} sin t
//! let f = |s: Complex64| 1.0 / ((s + 0.05) * (s + 0.05) + 1.0);
//! let r = invert(&f, 10.0, &InverseOptions::default())?;
//! let exact = (-0.5f64).exp() * 10f64.sin();
//! assert!((r.value - exact).abs() < 1e-9 && (r.value - exact).abs() <= r.err);
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::error::{Error, Result};
use num_complex::Complex64;
use std::f64::consts::PI;

fn check_t(t: f64) -> Result<()> {
    crate::error::check_f64("t", t, t > 0.0, "> 0 and finite").map(|_| ())
}

fn finite(z: Complex64) -> bool {
    z.re.is_finite() && z.im.is_finite()
}

fn bad_value(method: &str, s: Complex64) -> Error {
    Error::Numerical {
        method: method.into(),
        reason: format!("F(s) is not finite at s = {s} (a singularity on the contour?)"),
    }
}

/// Fixed Talbot inversion with `m` evaluations of `f` (see the module docs
/// for the failure region: this raw function does not check it).
///
/// # Errors
/// `t <= 0`, `m < 4`, `m > 200`, or a non-finite `F` value.
pub fn talbot<F: Fn(Complex64) -> Complex64>(f: &F, t: f64, m: usize) -> Result<f64> {
    check_t(t)?;
    if !(4..=200).contains(&m) {
        return Err(Error::invalid("m", m, "4..=200"));
    }
    let r = 2.0 * m as f64 / (5.0 * t);
    let f0 = f(Complex64::new(r, 0.0));
    if !finite(f0) {
        return Err(bad_value("Talbot", Complex64::new(r, 0.0)));
    }
    let mut acc = 0.5 * f0.re * (r * t).exp();
    for k in 1..m {
        let th = k as f64 * PI / m as f64;
        let cot = th.cos() / th.sin();
        let s = Complex64::new(r * th * cot, r * th);
        let sigma = th + (th * cot - 1.0) * cot;
        let fs = f(s);
        if !finite(fs) {
            return Err(bad_value("Talbot", s));
        }
        acc += ((s * t).exp() * fs * Complex64::new(1.0, sigma)).re;
    }
    Ok(r / m as f64 * acc)
}

/// Parameters of [`de_hoog`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DeHoog {
    /// Continued-fraction depth: `2M + 1` evaluations (default 40).
    pub m: usize,
    /// Abscissa of convergence: every singularity of `F` has `Re s <= alpha` (default 0).
    pub alpha: f64,
    /// Target relative discretisation (aliasing) error (default 1e-12).
    pub tol: f64,
    /// Half period `T = scale · t` (default 2).
    pub scale: f64,
}

impl Default for DeHoog {
    fn default() -> Self {
        DeHoog {
            m: 40,
            alpha: 0.0,
            tol: 1e-12,
            scale: 2.0,
        }
    }
}

/// de Hoog, Knight & Stokes inversion at one time.
///
/// # Errors
/// `t <= 0`; `m` outside `2..=500`; `tol` outside `(0, 1)`; `scale < 1`;
/// `alpha` not finite; a non-finite `F` value or a breakdown of the
/// quotient-difference table ([`Error::Numerical`]).
pub fn de_hoog<F: Fn(Complex64) -> Complex64>(f: &F, t: f64, p: &DeHoog) -> Result<f64> {
    de_hoog_scaled(f, t, p).map(|(v, _)| v)
}

/// [`de_hoog`] and the size `e^{γt}/T Σ_k |F(p_k)|` of the summed terms.
fn de_hoog_scaled<F: Fn(Complex64) -> Complex64>(f: &F, t: f64, p: &DeHoog) -> Result<(f64, f64)> {
    check_t(t)?;
    if !(2..=500).contains(&p.m) {
        return Err(Error::invalid("m", p.m, "2..=500"));
    }
    crate::error::check_f64("tol", p.tol, p.tol > 0.0 && p.tol < 1.0, "in (0, 1)")?;
    crate::error::check_f64("scale", p.scale, p.scale >= 1.0, ">= 1 and finite")?;
    crate::error::check_f64("alpha", p.alpha, true, "finite")?;
    let m = p.m;
    let big_t = p.scale * t;
    let gamma = p.alpha - p.tol.ln() / (2.0 * big_t);
    let np = 2 * m + 1;
    let mut a = Vec::with_capacity(np);
    for k in 0..np {
        let s = Complex64::new(gamma, PI * k as f64 / big_t);
        let v = f(s);
        if !finite(v) {
            return Err(bad_value("de Hoog", s));
        }
        a.push(v);
    }
    a[0] *= 0.5;
    let z = Complex64::from_polar(1.0, PI * t / big_t);
    let fail = |what: &str| Error::Numerical {
        method: "de Hoog".into(),
        reason: format!("quotient-difference breakdown ({what}) at t = {t}, M = {m}"),
    };
    let pre = (gamma * t).exp() / big_t;
    let v = pre * qd_sum(&a, m, z).ok_or_else(|| fail("division by zero"))?.re;
    if !v.is_finite() {
        return Err(fail("non-finite continued fraction"));
    }
    let scale = pre * a.iter().map(|x| x.norm()).sum::<f64>();
    Ok((v, scale))
}

/// The quotient-difference continued fraction of de Hoog et al. for the
/// series `Σ a_k z^k` (with `a_0` already halved), with the analytic remainder.
fn qd_sum(a: &[Complex64], m: usize, z: Complex64) -> Option<Complex64> {
    let np = 2 * m + 1;
    let mut q: Vec<Complex64> = (0..2 * m).map(|i| a[i + 1] / a[i]).collect();
    if q.iter().any(|w| !finite(*w)) {
        return None;
    }
    let mut e = vec![Complex64::new(0.0, 0.0); np];
    let mut d = vec![Complex64::new(0.0, 0.0); np];
    d[0] = a[0];
    for r in 1..=m {
        let mr = 2 * (m - r) + 1;
        let e_new: Vec<Complex64> = (0..mr).map(|i| q[i + 1] - q[i] + e[i + 1]).collect();
        d[2 * r - 1] = -q[0];
        d[2 * r] = -e_new[0];
        if r < m {
            let q_new: Vec<Complex64> = (0..2 * (m - r))
                .map(|i| q[i + 1] * e_new[i + 1] / e_new[i])
                .collect();
            if q_new.iter().any(|w| !finite(*w)) {
                return None;
            }
            q = q_new;
        }
        e = e_new;
    }
    // Continued fraction A_n / B_n, rescaled to avoid overflow.
    let (mut a_prev, mut a_cur) = (Complex64::new(0.0, 0.0), d[0]);
    let (mut b_prev, mut b_cur) = (Complex64::new(1.0, 0.0), Complex64::new(1.0, 0.0));
    for di in d.iter().take(2 * m).skip(1) {
        let a_next = a_cur + di * z * a_prev;
        let b_next = b_cur + di * z * b_prev;
        a_prev = a_cur;
        b_prev = b_cur;
        a_cur = a_next;
        b_cur = b_next;
        let sc = b_cur.norm().max(a_cur.norm());
        if sc > 1e100 || (sc < 1e-100 && sc > 0.0) {
            a_prev /= sc;
            b_prev /= sc;
            a_cur /= sc;
            b_cur /= sc;
        }
    }
    let h = 0.5 * (1.0 + (d[2 * m - 1] - d[2 * m]) * z);
    let rem = -h * (1.0 - (1.0 + d[2 * m] * z / (h * h)).sqrt());
    Some((a_cur + rem * a_prev) / (b_cur + rem * b_prev))
}

/// Absolute aliasing floor of [`invert`]'s error estimate (see there).
pub const ALIAS_FLOOR: f64 = 1e-12;

/// Rounding growth constant of [`invert`]'s error estimate (see there).
pub const ROUND_GROWTH: f64 = 64.0;

/// Options of [`invert`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InverseOptions {
    /// de Hoog depth of the first run (default 40); the second uses `m + m/2`.
    pub m: usize,
    /// Abscissa of convergence (default 0: singularities in `Re s <= 0`).
    pub alpha: f64,
    /// Accepted absolute disagreement (default 1e-9).
    pub atol: f64,
    /// Accepted relative disagreement (default 1e-7).
    pub rtol: f64,
    /// Talbot evaluations for the cross-check (default 24; 0 disables it).
    pub talbot_m: usize,
    /// Largest de Hoog depth tried when the first pair disagrees (default 160;
    /// the depth doubles from `m`).
    pub max_m: usize,
}

impl Default for InverseOptions {
    fn default() -> Self {
        InverseOptions {
            m: 40,
            alpha: 0.0,
            atol: 1e-9,
            rtol: 1e-7,
            talbot_m: 24,
            max_m: 160,
        }
    }
}

/// A checked inverse transform at one time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Inversion {
    /// Time.
    pub t: f64,
    /// `f(t)` (de Hoog run 1).
    pub value: f64,
    /// Error estimate: twice the disagreement of the accepted de Hoog pair,
    /// a rounding term, [`ALIAS_FLOOR`] and `1e-13 |value|` (see [`invert`]).
    pub err: f64,
    /// Number of evaluations of `F` (all de Hoog runs and Talbot).
    pub evaluations: usize,
    /// de Hoog depth of the accepted pair (`m`, `m + m/2`).
    pub m: usize,
    /// The Talbot value, if computed.
    pub talbot: Option<f64>,
    /// Whether Talbot agreed within `err + atol + rtol |value|` (`None` if not run
    /// or if it failed). Disagreement is expected at long times (poles outside
    /// the Talbot contour) and does not invalidate the de Hoog value.
    pub talbot_agrees: Option<bool>,
}

/// `f(t)` from `F(s)`, checked.
///
/// Two de Hoog runs must agree: run 1 (depth `M`, `T = 2t`, aliasing
/// `tol = 1e-12`) gives the value; run 2 (depth `M + M/2`, `T = 2.5 t`,
/// `tol = 1e-10`) changes every source of error at once: truncation of the
/// continued fraction, aliasing, and the rounding amplification `e^{γt}`
/// (`tol^{-1/4}` against `tol^{-1/5}`), so that the rounding error the two
/// runs would share with equal `tol` shows up as disagreement. If they
/// disagree, `M` doubles (up to `max_m`) and the pair is tried again. Talbot
/// is run once as a cross-check; its disagreement is reported, not fatal.
///
/// The error estimate is
/// `err = 4 |v_1 - v_2| + 64 M_2 eps S + 1e-12 + 1e-13 |f|` with
/// `S = e^{γt}/T Σ_k |F(p_k)|` the size of the summed terms (disagreement;
/// a rounding term, [`ROUND_GROWTH`]; the aliasing floor [`ALIAS_FLOOR`],
/// which assumes `f` of order one; a relative floor). The constants are
/// calibrated on the reference controls of `tests/inverse.rs`, where the
/// true error stays below `err` at all 366 reference points (at most 0.21 of
/// it in the printed table). A value is returned only when
/// `err <= atol + rtol |f|`.
///
/// # Errors
/// Invalid options (naming the field); [`Error::Numerical`] when no pair up
/// to `max_m` agrees (the method cannot resolve `f(t)` in `f64`: typically a
/// long time at light damping) or when a run breaks down.
pub fn invert<F: Fn(Complex64) -> Complex64>(
    f: &F,
    t: f64,
    opts: &InverseOptions,
) -> Result<Inversion> {
    check_t(t)?;
    opts.validate()?;
    let mut evaluations = 0;
    let mut m = opts.m;
    let mut last;
    loop {
        let p1 = DeHoog {
            m,
            alpha: opts.alpha,
            ..DeHoog::default()
        };
        let p2 = DeHoog {
            m: m + m / 2,
            scale: 2.5,
            tol: 1e-10,
            ..p1
        };
        let pair = de_hoog_scaled(f, t, &p1).and_then(|v1| Ok((v1, de_hoog_scaled(f, t, &p2)?)));
        evaluations += 2 * p1.m + 1 + 2 * p2.m + 1;
        match pair {
            Ok(((v1, sc1), (v2, sc2))) => {
                let diff = (v1 - v2).abs();
                let tol = opts.atol + opts.rtol * v1.abs();
                let round = ROUND_GROWTH * p2.m as f64 * f64::EPSILON * sc1.max(sc2);
                let err = 4.0 * diff + ALIAS_FLOOR + round + 1e-13 * v1.abs();
                if err <= tol {
                    let (talbot_v, agrees, spent) =
                        talbot_check(f, t, opts.talbot_m, v1, err + tol);
                    evaluations += spent;
                    return Ok(Inversion {
                        t,
                        value: v1,
                        err,
                        evaluations,
                        m,
                        talbot: talbot_v,
                        talbot_agrees: agrees,
                    });
                }
                last = format!(
                    "runs with M = {} and M = {} give {v1:.6e} and {v2:.6e} (error estimate {err:.2e} > tolerance {tol:.2e})",
                    p1.m, p2.m
                );
            }
            Err(e) => last = e.to_string(),
        }
        if m * 2 > opts.max_m {
            break;
        }
        m *= 2;
    }
    Err(Error::Numerical {
        method: "de Hoog".into(),
        reason: format!(
            "not resolved at t = {t} after {evaluations} evaluations: {last}; long times at light \
             damping need higher precision or the exact residue sum"
        ),
    })
}

impl InverseOptions {
    /// Check the tolerances and the orders.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming the field.
    fn validate(&self) -> Result<()> {
        crate::error::check_f64("atol", self.atol, self.atol >= 0.0, ">= 0 and finite")?;
        crate::error::check_f64("rtol", self.rtol, self.rtol >= 0.0, ">= 0 and finite")?;
        crate::error::check_f64("alpha", self.alpha, true, "finite")?;
        if self.m < 4 {
            return Err(Error::invalid("m", self.m, ">= 4"));
        }
        if self.max_m < self.m || self.max_m > 300 {
            return Err(Error::invalid(
                "max_m",
                self.max_m,
                format!("{}..=300 (at least m)", self.m),
            ));
        }
        Ok(())
    }
}

/// The fixed Talbot rule with `talbot_m` nodes as a second method (none when
/// 0): its value, whether it agrees with `v1` within `bound`, and the
/// evaluations spent (none when it failed).
fn talbot_check<F: Fn(Complex64) -> Complex64>(
    f: &F,
    t: f64,
    talbot_m: usize,
    v1: f64,
    bound: f64,
) -> (Option<f64>, Option<bool>, usize) {
    if talbot_m == 0 {
        return (None, None, 0);
    }
    match talbot(f, t, talbot_m) {
        Ok(v) => (Some(v), Some((v - v1).abs() <= bound), talbot_m),
        Err(_) => (None, None, 0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn damped_sine(s: Complex64) -> Complex64 {
        1.0 / ((s + 0.5) * (s + 0.5) + 4.0)
    }
    fn exact(t: f64) -> f64 {
        (-0.5 * t).exp() * (2.0 * t).sin() / 2.0
    }

    #[test]
    fn both_methods_on_a_damped_sine() {
        for &t in &[0.1, 0.5, 1.0, 3.0] {
            let tb = talbot(&damped_sine, t, 24).unwrap();
            assert!(
                (tb - exact(t)).abs() < 1e-9,
                "talbot t={t}: {tb} vs {}",
                exact(t)
            );
        }
        // t = 6: the poles at Im s = ±2 are close to the Talbot contour (r pi/2 = 2.5)
        let tb = talbot(&damped_sine, 6.0, 24).unwrap();
        assert!((tb - exact(6.0)).abs() > 1e-8);
        for &t in &[0.1, 1.0, 5.0, 20.0] {
            let dh = de_hoog(&damped_sine, t, &DeHoog::default()).unwrap();
            // absolute accuracy relative to max |f| ~ 0.4 (aliasing and rounding floors)
            assert!(
                (dh - exact(t)).abs() < 1e-8,
                "de Hoog t={t}: {dh} vs {}",
                exact(t)
            );
            // checked: accurate within its estimate, or refused (never silently wrong)
            match invert(&damped_sine, t, &InverseOptions::default()) {
                Ok(r) => assert!((r.value - exact(t)).abs() <= r.err, "invert t={t}: {r:?}"),
                Err(e) => {
                    assert!(t > 5.0, "t={t}: {e}");
                    assert!(matches!(e, Error::Numerical { .. }));
                }
            }
        }
    }

    #[test]
    fn simple_transforms() {
        // 1/s -> 1, 1/(s+1) -> e^{-t}, 1/s^2 -> t
        type Pair = (fn(Complex64) -> Complex64, fn(f64) -> f64);
        let cases: [Pair; 3] = [
            (|s| 1.0 / s, |_| 1.0),
            (|s| 1.0 / (s + 1.0), |t| (-t).exp()),
            (|s| 1.0 / (s * s), |t| t),
        ];
        for (ff, fe) in cases {
            for &t in &[0.5, 2.0, 10.0] {
                let r = invert(&ff, t, &InverseOptions::default()).unwrap();
                assert!(
                    (r.value - fe(t)).abs() <= r.err.max(1e-9),
                    "t={t}: {} vs {}",
                    r.value,
                    fe(t)
                );
            }
        }
    }

    #[test]
    fn invalid_input() {
        assert!(talbot(&damped_sine, 0.0, 20).is_err());
        assert!(talbot(&damped_sine, 1.0, 2).is_err());
        assert!(de_hoog(&damped_sine, -1.0, &DeHoog::default()).is_err());
        let e = de_hoog(
            &damped_sine,
            1.0,
            &DeHoog {
                tol: 2.0,
                ..Default::default()
            },
        )
        .unwrap_err();
        assert!(e.to_string().contains("tol"));
        let nan = |_s: Complex64| Complex64::new(f64::NAN, 0.0);
        assert!(matches!(
            talbot(&nan, 1.0, 20),
            Err(Error::Numerical { .. })
        ));
        assert!(matches!(
            invert(&nan, 1.0, &InverseOptions::default()),
            Err(Error::Numerical { .. })
        ));
    }
}
