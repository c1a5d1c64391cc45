//! Exact time-domain signals: every [`URatio`] is a finite sum of damped modes.
//!
//! # Formula
//!
//! `U_b` has the simple zeros `c_j = cos(theta_j)`, `theta_j = j pi/(b+1)`,
//! `j = 1..b`, and `a < b`, so in `c` the partial fractions are exact:
//! `U_a(c)/U_b(c) = sum_j U_a(c_j) / (U_b'(c_j) (c - c_j))`, with
//! `U_a(c_j)/U_b'(c_j) = (-1)^{j+1} sin((a+1) theta_j) sin(theta_j) / (b+1)`.
//! Since `c - c_j = (m/(2k)) (s^2 + 2 alpha s + omega_j^2)` with
//! `alpha = d/(2m)` and `omega_j^2 = 2k (1 - c_j)/m = 4 (k/m) sin^2(theta_j/2)`,
//!
//! `coef U_a/U_b = sum_j A_j / (s^2 + 2 alpha s + omega_j^2)`,
//! `A_j = coef (2k/m) U_a(c_j)/U_b'(c_j)`, and therefore
//!
//! `x(t) = sum_j A_j e^{-alpha t} sinh(beta_j t) / beta_j`, `beta_j^2 = alpha^2 - omega_j^2`.
//!
//! One formula covers every damping regime: `beta_j` imaginary (under-damped,
//! `sin(nu t)/nu`, including `d = 0`), zero (critically damped, `t e^{-alpha t}`,
//! the double pole), real (over-damped, written as
//! `e^{-(alpha - beta) t} (1 - e^{-2 beta t}) / (2 beta)` with
//! `alpha - beta = omega^2/(alpha + beta)` so that neither overflow nor
//! cancellation occurs). Near the critical coincidence the two residues
//! `+-A/(2 beta)` blow up, but the pair is never split, so nothing cancels.
//! This is the `residue` recipe of the reference file
//! (`r = sign U_a(c_k)/(U_b'(c_k)(2 s_k + d)/2)` summed over both roots),
//! generalised to `k`, `m`.
//!
//! # Convolution
//!
//! Each mode is the impulse response of `y'' + 2 alpha y' + omega^2 y = u`,
//! so the response to a disturbance `u` (piecewise linear between samples)
//! is propagated exactly, step by step, with the Taylor series of the mode's
//! transition functions ([`Convolution`]).
//!
//! ```
//! use springmass::control::{Suppression, Signal, exact::Modes};
//! let sup = Suppression::paper(4)?;
//! let f = Modes::new(&sup, Signal::F);
//! assert_eq!(f.len(), 5);                 // U_5 has 5 zeros
//! assert_eq!(f.eval(0.0), 0.0);
//! assert!(f.eval(10.0).abs() < 0.5);
//! # Ok::<(), springmass::Error>(())
//! ```

use super::{Signal, Suppression, URatio};
use crate::error::{Error, Result};
use num_complex::Complex64;
use std::f64::consts::PI;

/// One mode `A e^{-alpha t} sinh(beta t)/beta` (`alpha` shared).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mode {
    /// Amplitude `A_j`.
    pub amp: f64,
    /// `omega_j^2 = 2k(1 - c_j)/m > 0`.
    pub omega_sq: f64,
    /// `beta_j^2 = alpha^2 - omega_j^2` (computed as a product, no cancellation).
    pub beta_sq: f64,
}

/// A pole of the Laplace transform with its residue (and multiplicity).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pole {
    /// Location.
    pub s: Complex64,
    /// Residue (for a double pole: the coefficient of `t e^{s t}`).
    pub residue: Complex64,
    /// 1 (simple) or 2 (critically damped mode).
    pub order: u8,
}

/// The exact time-domain form of a [`URatio`].
#[derive(Clone, Debug, PartialEq)]
pub struct Modes {
    alpha: f64,
    modes: Vec<Mode>,
}

/// `e^{-alpha t} sinh(beta t)/beta` for `beta^2 = beta_sq`, stable in every regime.
#[inline]
fn mode_kernel(alpha: f64, omega_sq: f64, beta_sq: f64, t: f64) -> f64 {
    if beta_sq < 0.0 {
        let nu = (-beta_sq).sqrt();
        (-alpha * t).exp() * (nu * t).sin() / nu
    } else if beta_sq == 0.0 {
        t * (-alpha * t).exp()
    } else {
        let beta = beta_sq.sqrt();
        let slow = omega_sq / (alpha + beta); // alpha - beta, no cancellation
        let x = 2.0 * beta * t;
        let shape = if x == 0.0 {
            t
        } else {
            -(-x).exp_m1() / (2.0 * beta)
        };
        (-slow * t).exp() * shape
    }
}

impl Modes {
    /// The modes of `signal` for the problem `sup`.
    pub fn new(sup: &Suppression, signal: Signal) -> Modes {
        Self::of_ratio(&sup.ratio(signal), sup.k(), sup.mass(), sup.d())
    }

    /// The modes of any proper ratio (`a < b`) for `k`, `mass`, `d`.
    pub fn of_ratio(r: &URatio, k: f64, mass: f64, d: f64) -> Modes {
        let alpha = d / (2.0 * mass);
        let b1 = (r.b + 1) as f64;
        let modes = (1..=r.b)
            .map(|j| {
                let th = j as f64 * PI / b1;
                let sign = if j % 2 == 1 { 1.0 } else { -1.0 };
                let ratio = sign * ((r.a + 1) as f64 * th).sin() * th.sin() / b1;
                let amp = r.coef * 2.0 * k / mass * ratio;
                let half = (0.5 * th).sin();
                let omega_sq = 4.0 * k / mass * half * half;
                let omega = omega_sq.sqrt();
                let beta_sq = (alpha - omega) * (alpha + omega);
                Mode {
                    amp,
                    omega_sq,
                    beta_sq,
                }
            })
            .collect();
        Modes { alpha, modes }
    }

    /// Number of modes (`b`).
    pub fn len(&self) -> usize {
        self.modes.len()
    }
    /// No modes (never for a valid ratio).
    pub fn is_empty(&self) -> bool {
        self.modes.is_empty()
    }
    /// The shared decay rate `alpha = d/(2m)`.
    pub fn alpha(&self) -> f64 {
        self.alpha
    }
    /// The modes.
    pub fn modes(&self) -> &[Mode] {
        &self.modes
    }

    /// `x(t)`; 0 for `t <= 0` (the signals are causal and start at 0).
    pub fn eval(&self, t: f64) -> f64 {
        if t <= 0.0 {
            return 0.0;
        }
        self.modes
            .iter()
            .map(|m| m.amp * mode_kernel(self.alpha, m.omega_sq, m.beta_sq, t))
            .sum()
    }

    /// `x(t)` at many times.
    pub fn eval_many(&self, t: &[f64]) -> Vec<f64> {
        t.iter().map(|&t| self.eval(t)).collect()
    }

    /// The partial-fraction sum in the Laplace domain,
    /// `sum_j A_j / (s^2 + 2 alpha s + omega_j^2)` (a check of the expansion).
    pub fn laplace(&self, s: Complex64) -> Complex64 {
        self.modes
            .iter()
            .map(|m| m.amp / (s * s + 2.0 * self.alpha * s + m.omega_sq))
            .sum()
    }

    /// Poles and residues (both roots of every mode).
    pub fn poles(&self) -> Vec<Pole> {
        let mut out = Vec::with_capacity(2 * self.modes.len());
        let a = Complex64::new(-self.alpha, 0.0);
        for m in &self.modes {
            if m.beta_sq == 0.0 {
                out.push(Pole {
                    s: a,
                    residue: m.amp.into(),
                    order: 2,
                });
                continue;
            }
            let beta = Complex64::new(m.beta_sq, 0.0).sqrt();
            for sg in [1.0, -1.0] {
                out.push(Pole {
                    s: a + sg * beta,
                    residue: sg * m.amp / (2.0 * beta),
                    order: 1,
                });
            }
        }
        out
    }

    /// The slowest decay rate `min_j Re(-s_j)` (0 for an undamped chain).
    pub fn slowest_decay(&self) -> f64 {
        self.poles()
            .iter()
            .map(|p| -p.s.re)
            .fold(f64::INFINITY, f64::min)
    }

    /// Prepare the exact convolution with a disturbance sampled at step `h`
    /// from `t = 0` (`u[i] = u(i h)`, linear in between, zero after the last
    /// sample), available for `0 <= t <= max(t_end, last sample)`.
    ///
    /// # Errors
    /// `h` not finite and positive; fewer than 2 samples; a non-finite sample;
    /// `t_end` not finite.
    pub fn convolve(&self, u: &[f64], h: f64, t_end: f64) -> Result<Convolution> {
        Convolution::new(self, u, h, t_end)
    }
}

/// Taylor coefficients (scaled by `1/k!`) of the two transition functions of
/// one mode: `h` (`h(0) = 0, h'(0) = 1`) and `p` (`p(0) = 1, p'(0) = 0`) of
/// `y'' + 2 alpha y' + omega^2 y = 0`.
#[derive(Clone, Debug)]
struct Series {
    h: Vec<f64>,
    p: Vec<f64>,
}

const TERMS: usize = 32;

impl Series {
    fn new(alpha: f64, omega_sq: f64) -> Series {
        let rec = |c0: f64, c1: f64| {
            let mut c = vec![0.0; TERMS];
            c[0] = c0;
            c[1] = c1;
            for k in 0..TERMS - 2 {
                let kf = k as f64;
                c[k + 2] = (-2.0 * alpha * (kf + 1.0) * c[k + 1] - omega_sq * c[k])
                    / ((kf + 1.0) * (kf + 2.0));
            }
            c
        };
        Series {
            h: rec(0.0, 1.0),
            p: rec(1.0, 0.0),
        }
    }

    /// `(h, h', I0 = int_0^tau h, I1 = int_0^tau h(w)(tau - w) dw, p, p')` at `tau`.
    #[inline]
    fn at(&self, tau: f64) -> [f64; 6] {
        let (mut h, mut hd, mut i0, mut i1, mut p, mut pd) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        // Horner from the top: sum_k c_k tau^k etc.
        for k in (0..TERMS).rev() {
            let kf = k as f64;
            h = h * tau + self.h[k];
            p = p * tau + self.p[k];
            i0 = i0 * tau + self.h[k] / (kf + 1.0);
            i1 = i1 * tau + self.h[k] / ((kf + 1.0) * (kf + 2.0));
            if k >= 1 {
                hd = hd * tau + self.h[k] * kf;
                pd = pd * tau + self.p[k] * kf;
            }
        }
        [h, hd, i0 * tau, i1 * tau * tau, p, pd]
    }
}

/// The exact response of a [`Modes`] kernel to a piecewise-linear input:
/// `y(t) = int_0^t x(t - tau) u(tau) dtau`, available at every `t >= 0`
/// (`u` is zero after its last sample, as for a sampled force in
/// [`crate::time::simulate`]).
#[derive(Clone, Debug)]
pub struct Convolution {
    /// Internal step (the sample step divided so that `rate * step <= 1`).
    step: f64,
    /// Number of internal steps per sample.
    sub: usize,
    u: Vec<f64>,
    h: f64,
    amps: Vec<f64>,
    series: Vec<Series>,
    /// States `(y, y')` of every mode at every internal grid point, mode-major.
    states: Vec<Vec<[f64; 2]>>,
}

impl Convolution {
    fn new(modes: &Modes, u: &[f64], h: f64, t_end: f64) -> Result<Convolution> {
        if !t_end.is_finite() {
            return Err(Error::invalid("t_end", t_end, "finite"));
        }
        if !(h.is_finite() && h > 0.0) {
            return Err(Error::invalid("dt", h, "finite and > 0"));
        }
        if u.len() < 2 {
            return Err(Error::invalid(
                "disturbance.len",
                u.len(),
                "at least 2 samples",
            ));
        }
        if let Some(i) = u.iter().position(|v| !v.is_finite()) {
            return Err(Error::invalid(format!("disturbance[{i}]"), u[i], "finite"));
        }
        let rate = modes
            .modes
            .iter()
            .map(|m| 2.0 * modes.alpha + m.omega_sq.sqrt())
            .fold(0.0, f64::max);
        let sub = ((rate * h).ceil() as usize).max(1);
        let step = h / sub as f64;
        let mut conv = Convolution {
            step,
            sub,
            u: u.to_vec(),
            h,
            amps: modes.modes.iter().map(|m| m.amp).collect(),
            series: modes
                .modes
                .iter()
                .map(|m| Series::new(modes.alpha, m.omega_sq))
                .collect(),
            states: Vec::new(),
        };
        let samples = (u.len() - 1).max((t_end / h).ceil().max(0.0) as usize);
        let total = samples * sub;
        let full: Vec<[f64; 6]> = conv.series.iter().map(|s| s.at(step)).collect();
        conv.states = conv
            .series
            .iter()
            .enumerate()
            .map(|(j, _)| {
                let f = full[j];
                let mut st = Vec::with_capacity(total + 1);
                let (mut y, mut v) = (0.0, 0.0);
                st.push([y, v]);
                for g in 0..total {
                    let (u0, slope) = conv.input(g);
                    let ny = f[4] * y + f[0] * v + u0 * f[2] + slope * f[3];
                    let nv = f[5] * y + f[1] * v + u0 * f[0] + slope * f[2];
                    y = ny;
                    v = nv;
                    st.push([y, v]);
                }
                st
            })
            .collect();
        Ok(conv)
    }

    /// Input value at internal grid point `g` and its slope on `[g, g+1]`.
    #[inline]
    fn input(&self, g: usize) -> (f64, f64) {
        let i = g / self.sub;
        let r = (g % self.sub) as f64 / self.sub as f64;
        if i + 1 >= self.u.len() {
            return (0.0, 0.0);
        }
        let slope = (self.u[i + 1] - self.u[i]) / self.h;
        (self.u[i] + slope * r * self.h, slope)
    }

    /// `y(t)`; 0 for `t <= 0`, NaN beyond the prepared horizon.
    pub fn eval(&self, t: f64) -> f64 {
        if t <= 0.0 {
            return 0.0;
        }
        let last = self.states[0].len() - 1;
        let pos = t / self.step;
        if pos.is_nan() || pos > last as f64 * (1.0 + 1e-12) {
            return f64::NAN;
        }
        let g = (pos.floor() as usize).min(last);
        let tau = t - g as f64 * self.step;
        let (u0, slope) = self.input(g);
        let mut sum = 0.0;
        for (j, s) in self.series.iter().enumerate() {
            let [y, v] = self.states[j][g];
            let f = if tau == 0.0 {
                [0.0, 1.0, 0.0, 0.0, 1.0, 0.0]
            } else {
                s.at(tau)
            };
            sum += self.amps[j] * (f[4] * y + f[0] * v + u0 * f[2] + slope * f[3]);
        }
        sum
    }

    /// `y` at the sample times `i h` up to the horizon.
    pub fn on_grid(&self) -> Vec<f64> {
        (0..=(self.states[0].len() - 1) / self.sub)
            .map(|i| {
                let g = i * self.sub;
                self.states
                    .iter()
                    .zip(&self.amps)
                    .map(|(st, a)| a * st[g][0])
                    .sum()
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn partial_fractions_match_closed_form() {
        for &(n, k, m, d) in &[
            (4usize, 1.0, 1.0, 0.1),
            (19, 1.0, 1.0, 0.0),
            (7, 2.0, 0.5, 5.0),
            (30, 0.3, 2.0, 1.0),
        ] {
            let sup = Suppression::new(n, k, d, m, 1.3).unwrap();
            for sig in [
                Signal::F,
                Signal::G,
                Signal::F1,
                Signal::Y1,
                Signal::YEnd,
                Signal::X1Single,
            ] {
                let modes = Modes::new(&sup, sig);
                for s in [
                    Complex64::new(0.3, 0.0),
                    Complex64::new(0.5, 2.0),
                    Complex64::new(0.05, 0.9),
                    Complex64::new(2.0, -1.0),
                ] {
                    let exact: Complex64 = sup.ratio(sig).eval(&sup, s).unwrap();
                    let pf = modes.laplace(s);
                    assert!(
                        (exact - pf).norm() <= 1e-12 * exact.norm().max(1e-3),
                        "n={n} {sig:?} s={s}: {exact} vs {pf}"
                    );
                }
            }
        }
    }

    #[test]
    fn kernel_continuous_through_critical_damping() {
        let (alpha, om2) = (0.5, 0.25);
        for &t in &[0.1, 1.0, 7.0, 40.0] {
            let c = mode_kernel(alpha, om2, 0.0, t);
            // |beta| t <= 1e-6: the exact kernels differ by (beta t)^2/6 < 1e-12
            let over = mode_kernel(alpha, om2, alpha * alpha * 1e-16, t);
            let under = mode_kernel(alpha, om2, -alpha * alpha * 1e-16, t);
            assert!((c - over).abs() <= 1e-12 * c.abs() && (c - under).abs() <= 1e-12 * c.abs());
        }
    }

    /// An exactly critically damped mode: k = m = 1, d = 2 sqrt(2(1 - c_j)).
    #[test]
    fn critical_mode_matches_laplace_and_residues() {
        let n = 4; // b = 5 for F: c_j = cos(j pi/6)
        let cj = (2.0 * PI / 6.0).cos(); // j = 2: 1 - c = 1/2 exactly-ish
        let d = (8.0 * (1.0 - cj)).sqrt();
        let sup = Suppression::new(n, 1.0, d, 1.0, 1.0).unwrap();
        let f = Modes::new(&sup, Signal::F);
        let near = f.modes().iter().filter(|m| m.beta_sq.abs() < 1e-12).count();
        assert_eq!(near, 1);
        let s = Complex64::new(0.4, 0.3);
        let e: Complex64 = sup.ratio(Signal::F).eval(&sup, s).unwrap();
        assert!((e - f.laplace(s)).norm() < 1e-12);
        // numerical Laplace transform of f(t) at real s by Gauss-Legendre on [0, 80]
        let sr = 0.6;
        let (mut acc, nodes) = (0.0, 40_000);
        let hh = 80.0 / nodes as f64;
        for i in 0..nodes {
            // midpoint is enough for a smooth decaying integrand at this step
            let t = (i as f64 + 0.5) * hh;
            acc += f.eval(t) * (-sr * t).exp() * hh;
        }
        let lap: f64 = sup.ratio(Signal::F).eval(&sup, sr).unwrap();
        assert!((acc - lap).abs() < 1e-7, "{acc} vs {lap}");
    }

    #[test]
    fn convolution_with_linear_ramp_is_exact() {
        // u = t (ramp): y = int_0^t x(t-w) w dw; for a single under-damped mode
        // check against fine quadrature; for the full kernel check linearity.
        let sup = Suppression::paper(4).unwrap();
        let f = Modes::new(&sup, Signal::F);
        let h = 0.05;
        let u: Vec<f64> = (0..=400).map(|i| (i as f64 * h * 0.7).sin()).collect();
        let conv = f.convolve(&u, h, 20.0).unwrap();
        assert!(conv.eval(20.5).is_nan());
        let grid = conv.on_grid();
        for &i in &[20usize, 150, 400] {
            let t = i as f64 * h;
            // Simpson on a fine grid with the piecewise-linear u
            let m = 20_000;
            let dw = t / m as f64;
            let uu = |w: f64| {
                let k = ((w / h).floor() as usize).min(u.len() - 2);
                let r = w / h - k as f64;
                u[k] * (1.0 - r) + u[k + 1] * r
            };
            let mut acc = 0.0;
            for q in 0..=m {
                let w = q as f64 * dw;
                let wt = if q == 0 || q == m {
                    1.0
                } else if q % 2 == 1 {
                    4.0
                } else {
                    2.0
                };
                acc += wt * f.eval(t - w) * uu(w);
            }
            acc *= dw / 3.0;
            assert!((grid[i] - acc).abs() < 1e-9, "t={t}: {} vs {acc}", grid[i]);
            assert!((conv.eval(t) - grid[i]).abs() < 1e-14);
            let tm = t - 0.3 * h;
            assert!((conv.eval(tm) - grid[i]).abs() < 0.1);
        }
        assert!(f.convolve(&[1.0, f64::NAN], 0.1, 1.0).is_err());
        assert!(f.convolve(&[1.0, 2.0], -0.1, 1.0).is_err());
    }
}
