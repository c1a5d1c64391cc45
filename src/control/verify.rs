//! Verification of the suppression scheme by time-domain simulation, for the
//! paper's impulse and for any sampled disturbance, with optional delay and
//! gain error in the applied controls.
//!
//! The `(n+1)`-mass chain is simulated twice with
//! [`crate::time::simulate::simulate_forced`] (exponential integrator, forces
//! integrated with order 8 per step): without controls (`y`) and with the
//! exact controls of [`super::exact`] applied as external forces (`x`). The
//! report ([`Metrics`]) holds `max_t |x_{n+1}|` and `max_t |x_1 - y_1|`, both
//! relative to `max_t |y_1|`, and `max_t |x_{n+1}| / max_t |y_{n+1}|`.
//!
//! # Disturbances
//!
//! For a disturbance `u(t)` on mass 1 instead of the impulse, the controls
//! are `f_u = f_1 * u` (convolution with the impulse-response controls for
//! `gamma = 1`), computed exactly for `u` piecewise linear between its
//! samples ([`super::exact::Convolution`]); the simulator receives `u` as the
//! same piecewise-linear force.
//!
//! # Imperfect controls
//!
//! Applied controls are `(1 + eps) f(t - tau)` ([`Perturbation`]), on all
//! controls or on the control on mass `n` only. By linearity and time
//! invariance, a delay or gain error common to `f` and `g` leaves mass 1
//! exactly unaware (the pair still cancels its own echo at mass 1); only the
//! suppression at mass `n+1` degrades, by `y_{n+1}(t) - y_{n+1}(t - tau)`
//! (delay) or `-eps y_{n+1}` (gain). An error in `f` alone makes the
//! intervention visible at mass 1.
//!
//! ```
//! use springmass::control::{Suppression, Scheme};
//! use springmass::control::verify::{verify, Input, VerifyOptions};
//! let sup = Suppression::paper(4)?;
//! let run = verify(&sup, Scheme::Cloak, &Input::Impulse, &VerifyOptions::new(20.0, 0.05)?)?;
//! assert!(run.metrics.rel_x_end < 1e-8 && run.metrics.rel_x1_minus_y1 < 1e-8);
//! # Ok::<(), springmass::Error>(())
//! ```

use super::exact::{Convolution, Modes};
use super::{Scheme, Signal, Suppression};
use crate::error::{check_f64, Error, Result};
use crate::series::TimeSeries;
use crate::time::simulate::{simulate_forced, Force, Forcing, Method, SimOptions, Trajectory};
use serde::Serialize;
use std::sync::Arc;

/// Largest number of (time step x mode) states kept by the exact convolutions
/// of a disturbance (each state is 16 bytes, per signal).
pub const MAX_CONV_STATES: usize = 20_000_000;

/// Which controls a [`Perturbation`] acts on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum Target {
    /// Every control (a common latency / gain error of the controller).
    All,
    /// Only the control on mass `n` (`f` or `f1`).
    First,
}

/// Delay and relative gain error of the applied controls:
/// `(1 + gain_error) f(t - delay)`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Perturbation {
    /// `tau >= 0`.
    pub delay: f64,
    /// `eps`, `|eps| <= 1`.
    pub gain_error: f64,
    /// Which controls are affected.
    pub target: Target,
}

impl Perturbation {
    /// Exact controls.
    pub const NONE: Perturbation = Perturbation {
        delay: 0.0,
        gain_error: 0.0,
        target: Target::All,
    };

    /// Validated perturbation.
    ///
    /// # Errors
    /// `delay` negative or not finite; `gain_error` outside `[-1, 1]`.
    pub fn new(delay: f64, gain_error: f64, target: Target) -> Result<Perturbation> {
        check_f64("delay", delay, delay >= 0.0, "delay >= 0 and finite")?;
        check_f64(
            "gain_error",
            gain_error,
            gain_error.abs() <= 1.0,
            "-1 <= gain_error <= 1 (relative error of the control amplitude)",
        )?;
        Ok(Perturbation {
            delay,
            gain_error,
            target,
        })
    }

    fn is_none(&self) -> bool {
        self.delay == 0.0 && self.gain_error == 0.0
    }
}

/// Simulation horizon, step, method and perturbation.
#[derive(Clone, Debug, PartialEq)]
pub struct VerifyOptions {
    /// Horizon `t_end > 0`.
    pub t_end: f64,
    /// Output step `0 < dt <= t_end`.
    pub dt: f64,
    /// Simulator method [default `Auto`: matrix exponential up to 300 masses].
    pub method: Method,
    /// Applied-control errors [default none].
    pub perturbation: Perturbation,
}

impl VerifyOptions {
    /// Horizon and step, exact controls.
    ///
    /// # Errors
    /// `t_end <= 0`, `dt <= 0`, `dt > t_end`, non-finite values.
    pub fn new(t_end: f64, dt: f64) -> Result<VerifyOptions> {
        check_f64("t_end", t_end, t_end > 0.0, "t_end > 0 and finite")?;
        check_f64(
            "dt",
            dt,
            dt > 0.0 && dt <= t_end,
            &format!("0 < dt <= t_end = {t_end}"),
        )?;
        Ok(VerifyOptions {
            t_end,
            dt,
            method: Method::Auto,
            perturbation: Perturbation::NONE,
        })
    }
    /// With a perturbation.
    pub fn with_perturbation(mut self, p: Perturbation) -> VerifyOptions {
        self.perturbation = p;
        self
    }
    /// With a simulator method.
    pub fn with_method(mut self, m: Method) -> VerifyOptions {
        self.method = m;
        self
    }
}

/// What hits mass 1.
#[derive(Clone, Debug, PartialEq)]
pub enum Input {
    /// The paper's impulse `gamma delta(t)`.
    Impulse,
    /// A force `u(t)` sampled at `t = i h` from `t = 0`, linear between
    /// samples, zero after the last one.
    Sampled {
        /// Sample step.
        h: f64,
        /// Samples `u(i h)`.
        u: Vec<f64>,
    },
}

impl Input {
    /// A disturbance from a time series: the column `u` (or the only column),
    /// uniform times starting at `t = 0`.
    ///
    /// # Errors
    /// Times not starting at 0 or not uniform; no column `u` among several.
    /// (Non-finite values are refused when the series is built or read.)
    pub fn from_series(ts: &TimeSeries) -> Result<Input> {
        let col = match ts.column("u") {
            Some(c) => c,
            None if ts.names().len() == 1 => ts.column_at(0).unwrap_or_default(),
            None => {
                return Err(Error::invalid(
                    "disturbance column",
                    ts.names().join(","),
                    "a column named u (or a single value column)",
                ))
            }
        };
        if ts.t()[0] != 0.0 {
            return Err(Error::invalid(
                "disturbance t[0]",
                ts.t()[0],
                "0 (the chain is at rest until t = 0)",
            ));
        }
        let h = ts.uniform_step(1e-9).ok_or_else(|| {
            Error::invalid(
                "disturbance t",
                format!("{} samples", ts.len()),
                "at least 2 uniformly spaced samples",
            )
        })?;
        if let Some(i) = col.iter().position(|v| !v.is_finite()) {
            return Err(Error::invalid(
                format!("disturbance[{i}]"),
                col[i],
                "finite",
            ));
        }
        Ok(Input::Sampled { h, u: col.to_vec() })
    }
}

/// Verification maxima over the simulated window.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Metrics {
    /// `max |y_1|` (uncontrolled).
    pub max_abs_y1: f64,
    /// `max |y_{n+1}|` (uncontrolled).
    pub max_abs_y_end: f64,
    /// `max |x_{n+1}|` (controlled).
    pub max_abs_x_end: f64,
    /// `max |x_n|` (controlled).
    pub max_abs_x_n: f64,
    /// `max |x_1 - y_1|`.
    pub max_abs_x1_minus_y1: f64,
    /// `max |x_{n+1}| / max |y_1|`.
    pub rel_x_end: f64,
    /// `max |x_1 - y_1| / max |y_1|` (visibility of the intervention at mass 1).
    pub rel_x1_minus_y1: f64,
    /// `max |x_{n+1}| / max |y_{n+1}|` (residual vibration at the target).
    pub rel_x_end_vs_uncontrolled: f64,
    /// Simulator check: `max |y_1(sim) - y_1(exact)| / max |y_1|`.
    pub sim_vs_exact_y1: f64,
    /// Simulator check with controls: `max |x_1(sim) - x_1(exact)| / max |y_1|`,
    /// when the exact `x_1` is known (exact controls of a scheme).
    pub sim_vs_exact_x1: Option<f64>,
}

/// One applied control, sampled on the output grid.
#[derive(Clone, Debug, PartialEq)]
pub struct AppliedControl {
    /// Mass it acts on.
    pub at: usize,
    /// Which law.
    pub signal: Signal,
    /// Applied values (after delay and gain error) at the output times.
    pub values: Vec<f64>,
}

/// A verification run.
#[derive(Clone, Debug, PartialEq)]
pub struct Run {
    /// Output times.
    pub t: Vec<f64>,
    /// The applied controls.
    pub controls: Vec<AppliedControl>,
    /// The disturbance on mass 1 at the output times (empty for the impulse).
    pub input: Vec<f64>,
    /// `x_1` with controls.
    pub x1: Vec<f64>,
    /// `x_n` with controls.
    pub x_n: Vec<f64>,
    /// `x_{n+1}` with controls.
    pub x_end: Vec<f64>,
    /// `y_1` without controls.
    pub y1: Vec<f64>,
    /// `y_{n+1}` without controls.
    pub y_end: Vec<f64>,
    /// The maxima.
    pub metrics: Metrics,
}

/// A time function shared with the simulator.
type Shared = Arc<dyn Fn(f64) -> f64 + Send + Sync>;

/// The exact kernel of one signal for the input: the impulse response, or
/// its convolution with the disturbance.
fn signal_fn(sup: &Suppression, sig: Signal, input: &Input, t_end: f64) -> Result<Shared> {
    Ok(match input {
        Input::Impulse => {
            let m = Modes::new(sup, sig);
            Arc::new(move |t| m.eval(t))
        }
        Input::Sampled { h, u } => {
            let m = Modes::new(&sup.with_gamma(1.0)?, sig);
            let c: Convolution = m.convolve(u, *h, t_end)?;
            Arc::new(move |t| c.eval(t))
        }
    })
}

fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(0.0, |a, x| a.max(x.abs()))
}

fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).fold(0.0, |m, (x, y)| m.max((x - y).abs()))
}

/// The uncontrolled run, shared by every controlled run of a study.
#[derive(Clone, Debug)]
pub struct Baseline {
    sup: Suppression,
    input: Input,
    opts: SimOptions,
    t: Vec<f64>,
    u: Vec<f64>,
    y1: Vec<f64>,
    y_end: Vec<f64>,
    y1_exact: Vec<f64>,
}

impl Baseline {
    /// Simulate the chain without controls.
    ///
    /// # Errors
    /// Invalid options; a disturbance whose step is not a multiple of `dt`;
    /// simulator failures.
    pub fn new(sup: &Suppression, input: &Input, opts: &VerifyOptions) -> Result<Baseline> {
        let n = sup.n();
        if *input == Input::Impulse && sup.gamma() == 0.0 {
            return Err(Error::invalid(
                "gamma",
                0,
                "non-zero for the impulse input (nothing to suppress)",
            ));
        }
        if let Input::Sampled { h, u } = input {
            if u.iter().all(|v| *v == 0.0) {
                return Err(Error::invalid(
                    "disturbance",
                    "all zero",
                    "at least one non-zero sample (nothing to suppress)",
                ));
            }
            // memory of the exact convolutions: modes x internal steps
            let steps = (opts.t_end.max(h * (u.len() - 1) as f64) / h).ceil();
            let states = steps * (n + 2) as f64;
            if states > MAX_CONV_STATES as f64 {
                return Err(Error::invalid(
                    "disturbance samples x modes",
                    format!("{steps} x {}", n + 2),
                    format!(
                        "at most {MAX_CONV_STATES}: use a coarser disturbance step, a shorter horizon or a smaller n"
                    ),
                ));
            }
        }
        let sim = SimOptions::new(opts.t_end, opts.dt)
            .with_observe(vec![1, n - 1, n, n + 1])
            .with_method(opts.method);
        let forcing = Self::input_forcing(input, opts)?;
        let chain = match input {
            Input::Impulse => sup.chain().clone(),
            Input::Sampled { .. } => sup.chain().clone().with_gamma(0.0)?,
        };
        let traj = simulate_forced(&chain, &sim, &forcing)?;
        let y1_fn = signal_fn(sup, Signal::Y1, input, opts.t_end)?;
        let y1_exact: Vec<f64> = traj.t.iter().map(|&t| y1_fn(t)).collect();
        let u = match input {
            Input::Impulse => vec![],
            Input::Sampled { .. } => traj.t.iter().map(|&t| forcing.value(1, t)).collect(),
        };
        Ok(Baseline {
            sup: sup.clone(),
            input: input.clone(),
            opts: sim,
            y1: obs(&traj, 1)?,
            y_end: obs(&traj, n + 1)?,
            t: traj.t,
            u,
            y1_exact,
        })
    }

    fn input_forcing(input: &Input, opts: &VerifyOptions) -> Result<Forcing> {
        Ok(match input {
            Input::Impulse => Forcing::new(),
            Input::Sampled { h, u } => {
                let ratio = h / opts.dt;
                if (ratio - ratio.round()).abs() > 1e-9 * ratio.max(1.0) || ratio.round() < 1.0 {
                    return Err(Error::invalid(
                        "dt",
                        opts.dt,
                        format!("a divisor of the disturbance step {h} (dt = h / integer)"),
                    ));
                }
                let t: Vec<f64> = (0..u.len()).map(|i| i as f64 * h).collect();
                Forcing::new().with(1, Force::sampled(t, u.clone(), 1)?)
            }
        })
    }

    /// Output times.
    pub fn t(&self) -> &[f64] {
        &self.t
    }
    /// Uncontrolled `x_1`.
    pub fn y1(&self) -> &[f64] {
        &self.y1
    }
    /// Uncontrolled `x_{n+1}`.
    pub fn y_end(&self) -> &[f64] {
        &self.y_end
    }

    /// Simulate with the given controls `(mass, law)` and perturbation.
    ///
    /// # Errors
    /// A control on a mass outside `1..=n+1`; simulator failures.
    pub fn run(&self, controls: &[(usize, Signal)], p: &Perturbation) -> Result<Run> {
        self.run_expect(controls, p, None)
    }

    fn run_expect(
        &self,
        controls: &[(usize, Signal)],
        p: &Perturbation,
        expect_x1: Option<Signal>,
    ) -> Result<Run> {
        let n = self.sup.n();
        let t_end = self.opts.t_end;
        let mut forcing =
            Self::input_forcing(&self.input, &VerifyOptions::new(t_end, self.opts.dt)?)?;
        let mut applied = Vec::with_capacity(controls.len());
        for (i, &(at, sig)) in controls.iter().enumerate() {
            let hit = p.target == Target::All || i == 0;
            let (tau, gain) = if hit {
                (p.delay, 1.0 + p.gain_error)
            } else {
                (0.0, 1.0)
            };
            let base = signal_fn(&self.sup, sig, &self.input, t_end)?;
            let f: Shared = Arc::new(move |t| gain * base(t - tau));
            applied.push(AppliedControl {
                at,
                signal: sig,
                values: self.t.iter().map(|&t| f(t)).collect(),
            });
            let g = f.clone();
            forcing = forcing.with(at, Force::func(move |t| g(t)));
        }
        let chain = match self.input {
            Input::Impulse => self.sup.chain().clone(),
            Input::Sampled { .. } => self.sup.chain().clone().with_gamma(0.0)?,
        };
        let traj = simulate_forced(&chain, &self.opts, &forcing)?;
        let x1 = obs(&traj, 1)?;
        let x_n = obs(&traj, n)?;
        let x_end = obs(&traj, n + 1)?;
        let max_y1 = max_abs(&self.y1);
        let max_y_end = max_abs(&self.y_end);
        let sim_vs_exact_x1 = match expect_x1 {
            Some(sig) => {
                let e = signal_fn(&self.sup, sig, &self.input, t_end)?;
                let ex: Vec<f64> = self.t.iter().map(|&t| e(t)).collect();
                Some(max_abs_diff(&x1, &ex) / max_y1)
            }
            None => None,
        };
        let metrics = Metrics {
            max_abs_y1: max_y1,
            max_abs_y_end: max_y_end,
            max_abs_x_end: max_abs(&x_end),
            max_abs_x_n: max_abs(&x_n),
            max_abs_x1_minus_y1: max_abs_diff(&x1, &self.y1),
            rel_x_end: max_abs(&x_end) / max_y1,
            rel_x1_minus_y1: max_abs_diff(&x1, &self.y1) / max_y1,
            rel_x_end_vs_uncontrolled: max_abs(&x_end) / max_y_end,
            sim_vs_exact_y1: max_abs_diff(&self.y1, &self.y1_exact) / max_y1,
            sim_vs_exact_x1,
        };
        Ok(Run {
            t: self.t.clone(),
            controls: applied,
            input: self.u.clone(),
            x1,
            x_n,
            x_end,
            y1: self.y1.clone(),
            y_end: self.y_end.clone(),
            metrics,
        })
    }
}

fn obs(traj: &Trajectory, i: usize) -> Result<Vec<f64>> {
    traj.x(i)
        .map(|x| x.to_vec())
        .ok_or_else(|| Error::Numerical {
            method: "simulate".into(),
            reason: format!("mass {i} was not observed"),
        })
}

/// Simulate a scheme (uncontrolled and controlled) and measure it.
///
/// For exact controls the simulated `x_1` is also compared with its exact
/// form (`y_1` for the cloak, the `(n-1)`-chain response for the single control).
///
/// # Errors
/// As [`Baseline::new`] and [`Baseline::run`].
pub fn verify(
    sup: &Suppression,
    scheme: Scheme,
    input: &Input,
    opts: &VerifyOptions,
) -> Result<Run> {
    let base = Baseline::new(sup, input, opts)?;
    let expect = opts.perturbation.is_none().then_some(match scheme {
        Scheme::Cloak => Signal::Y1,
        Scheme::Single => Signal::X1Single,
    });
    base.run_expect(&sup.controls(scheme), &opts.perturbation, expect)
}

/// One point of a robustness curve.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct RobustPoint {
    /// The delay `tau` or the gain error `eps`.
    pub value: f64,
    /// `max |x_{n+1}| / max |y_1|`.
    pub rel_x_end: f64,
    /// `max |x_{n+1}| / max |y_{n+1}|`.
    pub rel_x_end_vs_uncontrolled: f64,
    /// `max |x_1 - y_1| / max |y_1|`.
    pub rel_x1_minus_y1: f64,
}

/// Robustness curves of a scheme over delays and gain errors.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Robustness {
    /// Delay on every control.
    pub delay_all: Vec<RobustPoint>,
    /// Delay on the control on mass `n` only.
    pub delay_first: Vec<RobustPoint>,
    /// Gain error on every control.
    pub gain_all: Vec<RobustPoint>,
    /// Gain error on the control on mass `n` only.
    pub gain_first: Vec<RobustPoint>,
}

/// Simulate the scheme over the grids of delays and gain errors (one
/// simulation per point; the uncontrolled run is shared).
///
/// # Errors
/// A negative or non-finite delay, a gain error outside `[-1, 1]`, and the
/// errors of [`Baseline`].
pub fn robustness(
    sup: &Suppression,
    scheme: Scheme,
    input: &Input,
    opts: &VerifyOptions,
    delays: &[f64],
    gains: &[f64],
) -> Result<Robustness> {
    let base = Baseline::new(sup, input, opts)?;
    let controls = sup.controls(scheme);
    let curve =
        |vals: &[f64], make: &dyn Fn(f64) -> Result<Perturbation>| -> Result<Vec<RobustPoint>> {
            vals.iter()
                .map(|&v| {
                    let m = base.run(&controls, &make(v)?)?.metrics;
                    Ok(RobustPoint {
                        value: v,
                        rel_x_end: m.rel_x_end,
                        rel_x_end_vs_uncontrolled: m.rel_x_end_vs_uncontrolled,
                        rel_x1_minus_y1: m.rel_x1_minus_y1,
                    })
                })
                .collect()
        };
    let single = controls.len() == 1;
    let delay_all = curve(delays, &|v| Perturbation::new(v, 0.0, Target::All))?;
    let gain_all = curve(gains, &|v| Perturbation::new(0.0, v, Target::All))?;
    // with one control, "first only" is the same experiment
    let (delay_first, gain_first) = if single {
        (delay_all.clone(), gain_all.clone())
    } else {
        (
            curve(delays, &|v| Perturbation::new(v, 0.0, Target::First))?,
            curve(gains, &|v| Perturbation::new(0.0, v, Target::First))?,
        )
    };
    Ok(Robustness {
        delay_all,
        delay_first,
        gain_all,
        gain_first,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn options_and_perturbations_are_validated() {
        assert!(VerifyOptions::new(0.0, 0.1).is_err());
        assert!(VerifyOptions::new(10.0, 20.0).is_err());
        assert!(Perturbation::new(-0.1, 0.0, Target::All).is_err());
        assert!(Perturbation::new(f64::NAN, 0.0, Target::All).is_err());
        assert!(Perturbation::new(0.1, 1.5, Target::All).is_err());
        let ts = TimeSeries::new(vec![0.1, 0.2], vec![("u".into(), vec![1.0, 2.0])]).unwrap();
        assert!(Input::from_series(&ts).is_err());
        let ts =
            TimeSeries::new(vec![0.0, 0.1, 0.3], vec![("u".into(), vec![1.0, 2.0, 3.0])]).unwrap();
        assert!(Input::from_series(&ts).is_err());
        let sup = Suppression::new(4, 1.0, 0.1, 1.0, 0.0).unwrap();
        let opts = VerifyOptions::new(10.0, 0.1).unwrap();
        assert!(Baseline::new(&sup, &Input::Impulse, &opts).is_err());
        let zero = Input::Sampled {
            h: 0.1,
            u: vec![0.0; 5],
        };
        assert!(Baseline::new(&sup, &zero, &opts).is_err());
        let big = Input::Sampled {
            h: 1e-4,
            u: vec![1.0; 10],
        };
        let sup = Suppression::paper(4000).unwrap();
        let opts = VerifyOptions::new(1000.0, 1e-4).unwrap();
        assert!(Baseline::new(&sup, &big, &opts).is_err());
    }

    #[test]
    fn common_mode_errors_stay_invisible_at_mass_1() {
        let sup = Suppression::paper(4).unwrap();
        let opts = VerifyOptions::new(30.0, 0.05).unwrap();
        let base = Baseline::new(&sup, &Input::Impulse, &opts).unwrap();
        let c = sup.controls(Scheme::Cloak);
        let eps = 0.1;
        let g = base
            .run(&c, &Perturbation::new(0.0, eps, Target::All).unwrap())
            .unwrap()
            .metrics;
        assert!(g.rel_x1_minus_y1 < 1e-9);
        // x_{n+1} = -eps y_{n+1}
        assert!((g.rel_x_end_vs_uncontrolled - eps).abs() < 1e-8);
        let d = base
            .run(&c, &Perturbation::new(0.5, 0.0, Target::All).unwrap())
            .unwrap()
            .metrics;
        assert!(d.rel_x1_minus_y1 < 1e-9 && d.rel_x_end > 1e-3);
        // x_{n+1}(t) = y_{n+1}(t) - y_{n+1}(t - tau), from the exact modal form
        let ye = Modes::new(&sup, Signal::YEnd);
        let want = base
            .t()
            .iter()
            .map(|&t| (ye.eval(t) - ye.eval(t - 0.5)).abs())
            .fold(0.0, f64::max);
        assert!(
            (d.max_abs_x_end - want).abs() < 1e-10 * want,
            "{} vs {want}",
            d.max_abs_x_end
        );
        let f = base
            .run(&c, &Perturbation::new(0.0, eps, Target::First).unwrap())
            .unwrap()
            .metrics;
        assert!(f.rel_x1_minus_y1 > 1e-3);
    }
}
