//! The blow's time as a fitted nuisance: the record re-timed to the
//! detected blow ([`crate::detect::data::trigger`]), fitted, the time refined
//! with the fitted chain and the record refitted when it moved, and its
//! standard error from the joint Jacobian of the time and the fitted values.
//!
//! * **Plan** ([`plan`]): with `trigger = At(t)` the record is re-timed to
//!   `t`; with `auto` (the default) to the detected blow, or to the user's
//!   `t = 0` when none is detected. A record that starts at the blow on an
//!   axis starting at 0 is not re-timed at all: the fit is the paper's, to
//!   the last digit.
//! * **Refinement** (`auto` only): the chi-square of the fitted chain
//!   against the record, as a function of the blow's time, minimised within
//!   half a step of the detected time (golden section, the samples fixed);
//!   the record is refitted once at the refined time when it moved by more
//!   than 5% of a step.
//! * **Standard error**: `sigma^2 (J^T J)^{-1}` of the time and every fitted
//!   defect value and chain parameter, `J` by central differences, so that
//!   the time's correlation with the impulse and the first masses is in it.
//!
//! Chains of [`MAX_N_REFINE`] masses or more keep the detected time (their
//! modal decompositions are too costly to repeat): no refinement, no
//! standard error (reported as NaN).

use crate::chain::Chain;
use crate::detect::data::observations::{Observations, Series};
use crate::detect::data::trigger::{detect_onset, TriggerSpec};
use crate::detect::fit::{FitReport, Model};
use crate::error::Result;
use crate::sensitivity::Param;
use crate::time::modal::ModalResponse;
use nalgebra::DMatrix;
use serde::Serialize;

/// Largest chain whose blow time is refined and given a standard error.
pub const MAX_N_REFINE: usize = 100;

/// The blow's time as the report gives it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct TriggerEstimate {
    /// The blow's time on the record's own axis.
    pub time: f64,
    /// Its standard error (NaN where not computed, see the module docs).
    pub se: f64,
    /// Samples before the blow, left out of the fit.
    pub dropped: usize,
    /// Detected from the record (`false`: given by the user).
    pub detected: bool,
    /// Refits at a refined time (0 or 1).
    pub refits: usize,
}

/// The time (on `obs`'s own re-based axis, [`Series::t`]) to re-time the
/// record to, or `None` for the paper's record that starts with the blow.
///
/// # Errors
/// The detection's modal errors.
pub(super) fn plan(obs: &Observations, model: &Model, spec: TriggerSpec) -> Result<Option<f64>> {
    let Observations::Series(s) = obs else {
        return Ok(None);
    };
    let t0 = match spec {
        TriggerSpec::At(v) => v - s.origin(),
        TriggerSpec::Auto => detect_onset(s, &model.chain().uniform())?.unwrap_or(-s.origin()),
    };
    Ok((t0 != 0.0).then_some(t0))
}

/// Fit the record re-timed to `t0` by `run`, refine the time (when
/// `refine`), and put the time and its standard error in the report; the
/// predicted series is given on the record's own axis.
///
/// # Errors
/// As [`Series::shifted`] and `run`.
pub(super) fn fit_retimed(
    rec: &Series,
    model: &Model,
    t0: f64,
    refine: bool,
    run: impl Fn(&Observations) -> Result<FitReport>,
) -> Result<FitReport> {
    let (shifted, mut dropped) = rec.shifted(t0)?;
    let mut report = run(&Observations::Series(shifted))?;
    let (mut time, mut refits) = (t0, 0);
    let small = model.n() < MAX_N_REFINE;
    if refine && small {
        let chain = fitted_chain(&report, model)?;
        let step = step_near(rec.t(), t0);
        let better = refined(rec, &chain, t0, step, report.noise_sigma)?;
        if (better - t0).abs() > 0.05 * step {
            let (again, d) = rec.shifted(better)?;
            report = run(&Observations::Series(again))?;
            (time, dropped, refits) = (better, d, 1);
        }
    }
    let se = if small {
        standard_error(rec, &report, model, time)?
    } else {
        f64::NAN
    };
    if let Some(p) = report.predicted.as_mut() {
        p.t.iter_mut().for_each(|v| *v += time + rec.origin());
    }
    report.trigger = Some(TriggerEstimate {
        time: time + rec.origin(),
        se,
        dropped,
        detected: refine,
        refits,
    });
    Ok(report)
}

/// The fitted chain of `report`: the model's chain (its known defects
/// first), the defects found, the fitted chain parameters.
fn fitted_chain(report: &FitReport, model: &Model) -> Result<Chain> {
    let mut chain = model.chain().clone().with_defects(report.found())?;
    for (p, e) in model.fitted().iter().zip(&report.params) {
        chain = p.set(&chain, e.value)?;
    }
    Ok(chain)
}

/// The sampling step at `t0`.
fn step_near(t: &[f64], t0: f64) -> f64 {
    let i = t.partition_point(|&v| v < t0).clamp(1, t.len() - 1);
    t[i] - t[i - 1]
}

/// The record's samples after `from` compared with `chain`'s response to a
/// blow at a variable time.
struct Record<'a> {
    t: &'a [f64],
    y: &'a [f64],
    inv_sigma: f64,
    rec: &'a Series,
}

impl<'a> Record<'a> {
    fn after(rec: &'a Series, from: f64, sigma: f64) -> Record<'a> {
        let first = rec.t().partition_point(|&v| v < from);
        Record {
            t: &rec.t()[first..],
            y: &rec.x()[first..],
            inv_sigma: 1.0 / sigma.max(f64::MIN_POSITIVE),
            rec,
        }
    }

    /// `chain`'s response at the sensor.
    fn response(&self, chain: &Chain) -> Result<ModalResponse> {
        let sensor = self.rec.measurement().sensor();
        ModalResponse::impulse_observable(chain, sensor.at, sensor.kind)
    }

    /// Whitened residuals of the response `u` to a blow at `time` (zero
    /// before it).
    fn residuals(&self, u: &ModalResponse, time: f64) -> Vec<f64> {
        self.t
            .iter()
            .zip(self.y)
            .map(|(&t, &y)| {
                let m = if t > time { u.eval(t - time) } else { 0.0 };
                (m - y) * self.inv_sigma
            })
            .collect()
    }

    fn chi2(&self, u: &ModalResponse, time: f64) -> f64 {
        self.residuals(u, time).iter().map(|r| r * r).sum()
    }
}

/// The blow's time within half a `step` of `t0` that fits `chain` best
/// (golden section on the samples after `t0 + step / 2`).
fn refined(rec: &Series, chain: &Chain, t0: f64, step: f64, sigma: f64) -> Result<f64> {
    let r = Record::after(rec, t0 + 0.5 * step, sigma);
    let u = r.response(chain)?;
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let (mut a, mut b) = (t0 - 0.5 * step, t0 + 0.5 * step);
    let (mut c, mut d) = (b - g * (b - a), a + g * (b - a));
    let (mut fc, mut fd) = (r.chi2(&u, c), r.chi2(&u, d));
    while b - a > 1e-6 * step {
        crate::cancel::check()?;
        if fc < fd {
            (b, d, fd) = (d, c, fc);
            c = b - g * (b - a);
            fc = r.chi2(&u, c);
        } else {
            (a, c, fc) = (c, d, fd);
            d = a + g * (b - a);
            fd = r.chi2(&u, d);
        }
    }
    let best = 0.5 * (a + b);
    // never worse than where it started
    Ok(if r.chi2(&u, best) <= r.chi2(&u, t0) {
        best
    } else {
        t0
    })
}

/// Standard error of the blow's time jointly with the fitted values (see
/// the module docs); NaN when the information matrix is singular.
fn standard_error(rec: &Series, report: &FitReport, model: &Model, time: f64) -> Result<f64> {
    let chain = fitted_chain(report, model)?;
    let known = model.chain().defects().len();
    let mut params: Vec<Param> = (known..chain.defects().len()).map(Param::Defect).collect();
    params.extend_from_slice(model.fitted());
    let r = Record::after(rec, time, report.noise_sigma);
    let h_t = 1e-4 * step_near(rec.t(), time);
    let mut cols: Vec<Vec<f64>> = Vec::with_capacity(params.len() + 1);
    let u = r.response(&chain)?;
    let (plus, minus) = (r.residuals(&u, time + h_t), r.residuals(&u, time - h_t));
    cols.push(difference(&plus, &minus, h_t));
    for p in &params {
        let v = p.get(&chain)?;
        let h = 1e-6 * v.abs().max(1e-6);
        let up = r.residuals(&r.response(&p.set(&chain, v + h)?)?, time);
        let down = r.residuals(&r.response(&p.set(&chain, v - h)?)?, time);
        cols.push(difference(&up, &down, h));
    }
    let j = DMatrix::from_fn(r.t.len(), cols.len(), |i, c| cols[c][i]);
    Ok((j.transpose() * &j)
        .try_inverse()
        .map_or(f64::NAN, |inv| inv[(0, 0)].max(0.0).sqrt()))
}

fn difference(up: &[f64], down: &[f64], h: f64) -> Vec<f64> {
    up.iter()
        .zip(down)
        .map(|(a, b)| (a - b) / (2.0 * h))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::fit::{fit, FitOptions};
    use crate::noise::NoiseLevel;

    /// `chain` hit at `blow` of a record sampled every 0.2 from `start`,
    /// simulated by a second method (the sparse stepping of the simulator,
    /// not the modal sum the fit uses).
    fn record(chain: &Chain, start: f64, blow: f64, noise: f64, seed: u64) -> Series {
        use crate::time::simulate::{simulate, Method, SimOptions};
        // the simulator's step divides both the blow's offset from the
        // first sample and the sampling step: the samples are its own points
        let fine = 0.01;
        let opts = SimOptions::new(220.0, fine).with_method(Method::Expm);
        let x1 = simulate(chain, &opts).unwrap().x(1).unwrap().to_vec();
        let t: Vec<f64> = (0..1000).map(|i| start + 0.2 * i as f64).collect();
        let clean: Vec<f64> = t
            .iter()
            .map(|&v| {
                let i = ((v - blow) / fine).round();
                if i < 0.0 {
                    0.0
                } else {
                    x1[i as usize]
                }
            })
            .collect();
        let (x, _) = crate::noise::add_noise(&clean, NoiseLevel::RelativeMax(noise), seed).unwrap();
        Series::on_axis(t, x, None).unwrap()
    }

    #[test]
    fn a_late_blow_is_fitted_with_its_standard_error() {
        let truth = crate::scenes::paper_with(20, "mass:8:5 mass:15:2").unwrap();
        let rec = record(&truth, 0.0, 10.13, 1e-3, 5);
        let r = fit(
            &Observations::Series(rec),
            &Model::new(20).unwrap(),
            &FitOptions::default(),
        )
        .unwrap();
        let pos: Vec<usize> = r.defects.iter().map(|d| d.at).collect();
        assert_eq!(pos, vec![8, 15], "{}", r.summary());
        let tr = r.trigger.expect("re-timed");
        assert!(tr.detected && tr.se > 0.0 && tr.se < 0.05, "{tr:?}");
        assert!((tr.time - 10.13).abs() < 4.0 * tr.se.max(1e-3), "{tr:?}");
    }
}
