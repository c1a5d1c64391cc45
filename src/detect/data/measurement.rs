//! What a record measured and what drove the chain: the sensor (the
//! displacement, velocity or acceleration of one mass) and the excitation
//! (the ideal impulse `gamma delta(t)` on mass 1, or a measured force on
//! mass 1 sampled at the record's own times, as in a hammer test).
//!
//! The misfits turn a candidate chain into the model of the record through
//! [`Measurement`]:
//!
//! | excitation | Laplace model at `s` | time model at `t_i` |
//! |---|---|---|
//! | impulse | [`Forward::observe`]: `X`, `s X`, `s^2 X - [at = 1] gamma/m_1` | exact modal sum, differentiated `p` times |
//! | force `f` | `s^p X(s) F(s)` with `X` the response to the impulse `gamma` (so `gamma` scales the force) and `F` the transform of the sampled force | the exponential integrator, exact for the piecewise-cubic force through the samples ([`simulate_forced`], [`FORCE_ORDER`]) |
//!
//! `p` is 0, 1, 2 for displacement, velocity, acceleration. With a force the
//! record's times must be `0, dt, 2 dt, ...` (a data logger's channels share
//! one clock), so that the integrator steps between the force's samples and
//! is exact for its piecewise-cubic interpolant.
//!
//! ```
//! use springmass::{Chain, forward::Observable};
//! use springmass::detect::data::measurement::Measurement;
//! let m = Measurement::new(1, Observable::Acceleration);
//! let c = Chain::paper(4)?;
//! let t: Vec<f64> = (0..5).map(|i| i as f64 * 0.5).collect();
//! let a = m.time_model(&c, &t)?;
//! // the acceleration of mass 1 at t = 0+ is -d gamma / m_1^2
//! assert!((a[0] + 0.1).abs() < 1e-12);
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::chain::Chain;
use crate::error::{check_f64, Error, Result};
use crate::forward::{Forward, Observable};
use crate::sensitivity::{gradient, observe_gradient, Gradient, Param};
use crate::time::modal::ModalResponse;
use crate::time::simulate::{simulate_forced, Force, Forcing, Method, SimOptions, MAX_N_EXPM};
use num_complex::Complex64;
use serde::Serialize;

/// Degree of the piecewise polynomial through the force samples (cubic:
/// a hammer's half-sine of width `w` sampled every `w / 5` is reproduced to
/// about `1e-3` of its peak, where piecewise-linear is off by 5%).
pub const FORCE_ORDER: usize = 3;

/// The sensor: which observable of which mass.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Sensor {
    /// Observed mass (1-based).
    pub at: usize,
    /// Displacement, velocity or acceleration.
    pub kind: Observable,
}

impl Sensor {
    /// The paper's sensor: the displacement of mass 1.
    pub const PAPER: Sensor = Sensor {
        at: 1,
        kind: Observable::Displacement,
    };

    /// Check the observed mass against a chain of `n` masses.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming `observe` when `at` is not in `1..=n`.
    pub fn check(&self, n: usize) -> Result<()> {
        if self.at == 0 || self.at > n {
            return Err(Error::invalid(
                "observe",
                self.at,
                format!("a mass of the chain, 1..={n}"),
            ));
        }
        Ok(())
    }

    /// The observable's transform for the impulse excitation.
    ///
    /// # Errors
    /// As [`Forward::observe`].
    pub fn laplace<T: crate::scalar::Scalar>(&self, fwd: &Forward, s: T) -> Result<T> {
        if self.kind == Observable::Displacement {
            fwd.eval(s, self.at)
        } else {
            fwd.observe(s, self.at, self.kind)
        }
    }
}

/// Sensor and excitation of a sampled record (see the module docs).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Measurement {
    sensor: Sensor,
    /// Force on mass 1 at the record's times; `None`: the impulse.
    force: Option<Vec<f64>>,
    /// The time range the force was windowed to, if it was.
    window: Option<(f64, f64)>,
}

impl Measurement {
    /// `kind` of mass `at` after the impulse on mass 1.
    pub fn new(at: usize, kind: Observable) -> Measurement {
        Measurement {
            sensor: Sensor { at, kind },
            force: None,
            window: None,
        }
    }

    /// The paper's measurement: the displacement of mass 1 after the impulse.
    pub fn paper() -> Measurement {
        Measurement::default().with_sensor(Sensor::PAPER)
    }

    /// Another sensor.
    pub fn with_sensor(mut self, sensor: Sensor) -> Measurement {
        self.sensor = sensor;
        self
    }

    /// Driven by the measured force `f` on mass 1 (samples at the record's
    /// times, checked when the measurement is attached to a record).
    ///
    /// # Errors
    /// A non-finite sample (field `force[i]`), fewer than 2 samples, or an
    /// all-zero force (field `force`).
    pub fn with_force(mut self, f: Vec<f64>) -> Result<Measurement> {
        for (i, v) in f.iter().enumerate() {
            check_f64(&format!("force[{i}]"), *v, true, "finite")?;
        }
        if f.len() < 2 {
            return Err(Error::invalid(
                "force",
                format!("{} samples", f.len()),
                "at least 2 samples",
            ));
        }
        if f.iter().all(|v| *v == 0.0) {
            return Err(Error::invalid(
                "force",
                "all zero",
                "a force that is not zero everywhere (the chain would not move)",
            ));
        }
        self.force = Some(f);
        Ok(self)
    }

    /// Note the time range the force was windowed to
    /// ([`crate::detect::data::force_window`]; shown by [`Measurement::describe`]).
    pub fn with_force_window(mut self, window: Option<(f64, f64)>) -> Measurement {
        self.window = window;
        self
    }

    /// The time range the force was windowed to, if it was.
    pub fn force_window(&self) -> Option<(f64, f64)> {
        self.window
    }

    /// The sensor.
    pub fn sensor(&self) -> Sensor {
        self.sensor
    }

    /// The force samples, if driven by a measured force.
    pub fn force(&self) -> Option<&[f64]> {
        self.force.as_deref()
    }

    /// Whether this is the paper's measurement (displacement of mass 1, impulse).
    pub fn is_paper(&self) -> bool {
        self.sensor == Sensor::PAPER && self.force.is_none()
    }

    /// A short description: `acceleration of mass 1, measured force`.
    pub fn describe(&self) -> String {
        format!(
            "{} of mass {}, {}",
            self.sensor.kind.name(),
            self.sensor.at,
            match (&self.force, self.window) {
                (Some(_), Some((a, b))) =>
                    format!("measured force on mass 1, windowed to {a}..{b}"),
                (Some(_), None) => "measured force on mass 1".to_string(),
                (None, _) => "impulse on mass 1".to_string(),
            }
        )
    }

    /// Check the measurement against the record's times `t`.
    ///
    /// # Errors
    /// A force of another length than `t` (field `force`), or, with a force,
    /// times that are not `0, dt, 2 dt, ...` to a relative `1e-9` (field `t`).
    pub fn check_times(&self, t: &[f64]) -> Result<()> {
        let Some(f) = &self.force else {
            return Ok(());
        };
        if f.len() != t.len() {
            return Err(Error::invalid(
                "force",
                format!("{} samples for {} times", f.len(), t.len()),
                "one force sample per sample of the record",
            ));
        }
        if t.len() < 2 || t[0] != 0.0 {
            return Err(Error::invalid(
                "t",
                t.first().copied().unwrap_or(f64::NAN),
                "with a measured force, times 0, dt, 2 dt, ... starting at 0",
            ));
        }
        let dt = t[1] - t[0];
        for (i, &ti) in t.iter().enumerate() {
            if (ti - i as f64 * dt).abs() > 1e-9 * (i as f64 * dt).max(dt) {
                return Err(Error::invalid(
                    format!("t[{i}]"),
                    ti,
                    format!("with a measured force, uniform times i dt (dt = {dt})"),
                ));
            }
        }
        Ok(())
    }

    /// The model of the record at times `t` for `chain` (see the module docs).
    ///
    /// # Errors
    /// The observed mass out of range; as [`ModalResponse::impulse_observable`]
    /// or [`simulate_forced`]; with a force, times that fail
    /// [`Measurement::check_times`].
    pub fn time_model(&self, chain: &Chain, t: &[f64]) -> Result<Vec<f64>> {
        self.sensor.check(chain.n())?;
        let Some(f) = &self.force else {
            return Ok(
                ModalResponse::impulse_observable(chain, self.sensor.at, self.sensor.kind)?
                    .eval_many(t),
            );
        };
        self.check_times(t)?;
        let dt = t[1];
        let t_end = t[t.len() - 1];
        let method = if chain.n() <= MAX_N_EXPM {
            Method::Expm
        } else {
            Method::Rk
        };
        let opts = SimOptions::new(t_end + 0.25 * dt, dt)
            .with_observe(vec![self.sensor.at])
            .with_observe_kind(self.sensor.kind)
            .with_method(method)
            .with_force_nodes(FORCE_ORDER + 1);
        let gamma = chain.gamma();
        let scaled: Vec<f64> = f.iter().map(|v| v * gamma).collect();
        let forcing = Forcing::new().with(1, Force::sampled(t.to_vec(), scaled, FORCE_ORDER)?);
        let quiet = chain.clone().with_gamma(0.0)?;
        let traj = simulate_forced(&quiet, &opts, &forcing)?;
        let x = traj.x(self.sensor.at).ok_or_else(|| Error::Numerical {
            method: "simulate".into(),
            reason: "the observed mass was not simulated".into(),
        })?;
        if x.len() < t.len() {
            return Err(Error::Numerical {
                method: "simulate".into(),
                reason: format!("{} samples simulated for {} times", x.len(), t.len()),
            });
        }
        Ok(x[..t.len()].to_vec())
    }
}

/// A hammer's blow on mass 1: the half-sine `f(t) = A sin(pi t / w)` on
/// `[0, w]`, zero after, with `A = pi J / (2 w)` so that its impulse is `J`.
///
/// # Errors
/// `width` or `impulse` not finite and `> 0` (fields `hammer_width`, `impulse`).
///
/// ```
/// let f = springmass::detect::data::measurement::hammer(0.05, 1.0)?;
/// assert!((f.eval(0.025) - std::f64::consts::PI / 0.1).abs() < 1e-12);
/// assert_eq!(f.eval(0.06), 0.0);
/// # Ok::<(), springmass::Error>(())
/// ```
pub fn hammer(width: f64, impulse: f64) -> Result<Force> {
    check_f64("hammer_width", width, width > 0.0, "> 0 and finite")?;
    check_f64("impulse", impulse, impulse > 0.0, "> 0 and finite")?;
    let peak = std::f64::consts::PI * impulse / (2.0 * width);
    Ok(Force::func(move |t| {
        if (0.0..=width).contains(&t) {
            peak * (std::f64::consts::PI * t / width).sin()
        } else {
            0.0
        }
    }))
}

/// The observable's Laplace model at `s` and, for a force, the force's
/// transform `F(s)` there (see the module docs).
///
/// # Errors
/// As [`Forward::eval`] and [`Forward::observe`].
pub fn laplace_model(
    sensor: Sensor,
    fwd: &Forward,
    s: Complex64,
    force_hat: Option<Complex64>,
) -> Result<Complex64> {
    match force_hat {
        None => sensor.laplace(fwd, s),
        Some(f) => Ok(s.powu(sensor.kind.power()) * f * fwd.eval(s, sensor.at)?),
    }
}

/// The observable's Laplace model and its derivatives with respect to
/// `params` (reciprocity, O(n) per `s`; see the module docs).
///
/// # Errors
/// As [`gradient`] and [`observe_gradient`].
pub fn laplace_gradient(
    sensor: Sensor,
    chain: &Chain,
    s: Complex64,
    force_hat: Option<Complex64>,
    params: &[Param],
) -> Result<Gradient<Complex64>> {
    match force_hat {
        None => observe_gradient(chain, s, sensor.at, sensor.kind, params),
        Some(f) => {
            let g = gradient(chain, s, sensor.at, params)?;
            Ok(scale_gradient(g, s.powu(sensor.kind.power()) * f))
        }
    }
}

/// `g` times the factor `c` (value and every derivative).
pub fn scale_gradient(g: Gradient<Complex64>, c: Complex64) -> Gradient<Complex64> {
    Gradient {
        value: g.value * c,
        grad: g.grad.into_iter().map(|v| v * c).collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chain::Boundary;
    use crate::time::simulate::simulate;

    fn chain() -> Chain {
        crate::scenes::paper_with(5, "mass:2:2.0 spring:4:0.6").unwrap()
    }

    #[test]
    fn impulse_time_model_matches_the_simulation_for_every_observable() {
        for (left, right) in [
            (Boundary::Fixed, Boundary::Fixed),
            (Boundary::Free, Boundary::Fixed),
        ] {
            let c = chain().with_boundaries(left, right).unwrap();
            for kind in [
                Observable::Displacement,
                Observable::Velocity,
                Observable::Acceleration,
            ] {
                for at in [1, 3] {
                    let opts = SimOptions::new(20.0, 0.1)
                        .with_observe(vec![at])
                        .with_observe_kind(kind)
                        .with_method(Method::Expm);
                    let sim = simulate(&c, &opts).unwrap();
                    let m = Measurement::new(at, kind);
                    let model = m.time_model(&c, &sim.t).unwrap();
                    let x = sim.x(at).unwrap();
                    let scale = x.iter().fold(0.0f64, |a, v| a.max(v.abs()));
                    for (a, b) in model.iter().zip(x) {
                        assert!(
                            (a - b).abs() < 1e-9 * scale,
                            "{left}-{right} {kind} at {at}: {a} vs {b}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn forced_laplace_model_is_the_transform_of_the_forced_time_model() {
        // a smooth force with a known transform: f = t e^{-2t}, F = 1/(s+2)^2
        let c = chain().with_gamma(1.5).unwrap();
        let dt = 0.002;
        let t: Vec<f64> = (0..=20_000).map(|i| i as f64 * dt).collect();
        let f: Vec<f64> = t.iter().map(|&x| x * (-2.0 * x).exp()).collect();
        let fwd = Forward::new(&c);
        for kind in [Observable::Displacement, Observable::Acceleration] {
            let m = Measurement::new(1, kind).with_force(f.clone()).unwrap();
            let y = m.time_model(&c, &t).unwrap();
            let s = Complex64::new(0.4, 0.7);
            // trapezoid transform of the model (smooth integrand, e^{-0.4 * 40} tail)
            let mut num = Complex64::new(0.0, 0.0);
            for (i, (&ti, &yi)) in t.iter().zip(&y).enumerate() {
                let w = if i == 0 || i + 1 == t.len() { 0.5 } else { 1.0 };
                num += w * dt * yi * (-s * ti).exp();
            }
            let fh = 1.0 / ((s + 2.0) * (s + 2.0));
            let want = laplace_model(m.sensor(), &fwd, s, Some(fh)).unwrap();
            assert!(
                (num - want).norm() < 1e-5 * want.norm(),
                "{kind}: {num} vs {want}"
            );
        }
    }

    #[test]
    fn gradients_match_differences() {
        let c = chain();
        let params = [Param::Defect(0), Param::Defect(1), Param::Gamma, Param::D];
        let s = Complex64::new(0.3, 1.1);
        for force in [None, Some(Complex64::new(0.5, -0.2))] {
            for kind in [Observable::Velocity, Observable::Acceleration] {
                let sensor = Sensor { at: 1, kind };
                let g = laplace_gradient(sensor, &c, s, force, &params).unwrap();
                for (j, p) in params.iter().enumerate() {
                    let v = p.get(&c).unwrap();
                    let h = 1e-6 * v.abs().max(1.0);
                    let val = |x: f64| {
                        let cc = p.set(&c, x).unwrap();
                        laplace_model(sensor, &Forward::new(&cc), s, force).unwrap()
                    };
                    let fd = (val(v + h) - val(v - h)) / (2.0 * h);
                    assert!(
                        (fd - g.grad[j]).norm() < 1e-6 * (1.0 + fd.norm()),
                        "{kind} {force:?} {p:?}: {fd} vs {}",
                        g.grad[j]
                    );
                }
            }
        }
    }

    #[test]
    fn bad_measurements_are_typed_errors() {
        assert!(Measurement::paper().with_force(vec![0.0, 0.0]).is_err());
        assert!(Measurement::paper().with_force(vec![1.0]).is_err());
        assert!(Measurement::paper()
            .with_force(vec![1.0, f64::NAN])
            .is_err());
        let m = Measurement::paper()
            .with_force(vec![1.0, 0.0, 0.0])
            .unwrap();
        let e = m.check_times(&[0.0, 0.1]).unwrap_err().to_string();
        assert!(e.contains("force"), "{e}");
        let e = m.check_times(&[0.0, 0.1, 0.3]).unwrap_err().to_string();
        assert!(e.contains("t[2]"), "{e}");
        let e = Measurement::new(7, Observable::Velocity)
            .time_model(&Chain::paper(5).unwrap(), &[0.0, 1.0])
            .unwrap_err()
            .to_string();
        assert!(e.contains("observe"), "{e}");
    }
}
