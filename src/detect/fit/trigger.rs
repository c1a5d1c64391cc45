//! The blow's time as a fitted nuisance: the record re-timed to the
//! detected blow ([`crate::detect::data::trigger`]), fitted, the time refined
//! with the fitted chain and the record refitted when it moved, and its
//! standard error from the joint Jacobian of the time and the fitted values.
//!
//! * **Plan**: with `trigger = At(t)` the record is re-timed to
//!   `t`; with `auto` (the default) to the detected blow, or to the user's
//!   `t = 0` when none is detected. A record that starts at the blow on an
//!   axis starting at 0 is not re-timed at all: the fit is the paper's, to
//!   the last digit.
//! * **Refinement** (`auto` only): the blow's time and the fitted values
//!   (defects and chain parameters) fitted jointly by bounded
//!   Levenberg-Marquardt from the fit at the detected time (with the white
//!   noise model and no sensor nuisance: a record model would only fit the
//!   misfit of a time off by a fraction of a sample), the time within
//!   a step of it (a defect near the sensor can stand in for a time error:
//!   fitting both lets the data choose), an offset and a drift profiled
//!   out of the residual as far as the options allow them; the record is
//!   then refitted with the full options (the number and places of the
//!   defects chosen again) at the refined time when it moved by more than
//!   its standard error (or 5% of a step), or at the detected time when
//!   that fit did not explain the record. The time is then refined again
//!   with the answer's chain and nuisances, and the record refitted while
//!   it moves (at most [`MAX_REFITS`] refits in all): the white fit's chain
//!   can be far from the answer's (a record with a sensor offset), and a
//!   time a few standard errors off is a misfit a defect near the sensor
//!   takes up (measured: Rayleigh damping, an offset and drift and a late
//!   clock on System 3 at 0.1% noise gave a spurious mass at 1, 0.2% off,
//!   called converged).
//! * **Standard error**: `sigma^2 (J^T J)^{-1}` of the time and every fitted
//!   defect value and chain parameter, `J` by central differences, so that
//!   the time's correlation with the impulse and the first masses is in it.
//!
//! Chains of [`MAX_N_REFINE`] masses or more keep the detected time (their
//! modal decompositions are too costly to repeat): no refinement, no
//! standard error (reported as NaN).

use crate::chain::Chain;
use crate::detect::data::noise_model::NoiseModel;
use crate::detect::data::nuisance::{Nuisance, Projector};
use crate::detect::data::observations::{Observations, Series};
use crate::detect::data::trigger::{detect_onset, onset_candidates, TriggerSpec};
pub use crate::detect::fit::report::trigger::TriggerEstimate;
use crate::detect::fit::{FitReport, Model};
use crate::detect::search::lsq::difference_within;
use crate::error::{Error, Result};
use crate::sensitivity::Param;
use crate::time::modal::ModalResponse;
use nalgebra::DMatrix;

/// A fit of a record (re-timed observations to a report).
pub(super) type FitRun<'a> = dyn Fn(&Observations) -> Result<FitReport> + 'a;

/// Largest chain whose blow time is refined and given a standard error.
pub const MAX_N_REFINE: usize = 100;

/// Most refits at a refined time.
pub const MAX_REFITS: usize = 3;

/// The times (on `obs`'s own re-based axis, [`Series::t`]) to re-time the
/// record to, best first ([`onset_candidates`]: more than one only for a
/// displacement cut short after its blow), or none for the paper's record
/// that starts with the blow.
///
/// # Errors
/// The detection's modal errors.
pub(super) fn plan(obs: &Observations, model: &Model, spec: TriggerSpec) -> Result<Vec<f64>> {
    let Observations::Series(s) = obs else {
        return Ok(Vec::new());
    };
    if s.separate_records() {
        // one blow time re-times one test: several records must each
        // start with their own blow
        for (j, r) in s.sensors().enumerate() {
            let t0 = match spec {
                TriggerSpec::At(v) => v - r.origin(),
                TriggerSpec::Auto => detect_onset(r, &model.chain().uniform())?.unwrap_or(0.0),
            };
            if t0 != 0.0 {
                return Err(Error::invalid(
                    "trigger",
                    format!("record {} of {}", j + 1, s.sensors().count()),
                    "several records that each start with their blow (cut each record at its blow; the blow time is fitted for one record only)",
                ));
            }
        }
        return Ok(Vec::new());
    }
    let times = match spec {
        TriggerSpec::At(v) => vec![v - s.origin()],
        TriggerSpec::Auto => match onset_candidates(s, &model.chain().uniform())? {
            found if found.is_empty() => vec![-s.origin()],
            found => found,
        },
    };
    Ok(match times[..] {
        [0.0] => Vec::new(),
        _ => times,
    })
}

/// Fit the record re-timed to `t0` by `run`, refine the time (when
/// `refine`), and put the time and its standard error in the report; the
/// predicted series is given on the record's own axis.
///
/// The chain the time is refined with comes from `first` when given (a
/// white fit: at a detected time that is off by a fraction of a sample
/// the residual of a quiet record is not noise, and the full defaults
/// would fit a record model to that misfit before the refined time
/// removes it); the answer is `run`'s, or `first`'s when the time stays,
/// `first`'s answer explains the record (`fits_data`) and its flag says
/// the full options would keep the white model there (no record model
/// asked for).
///
/// The refinement profiles `nuisance` out of the residual (the most the
/// options allow): a sensor offset that it left in would move the time,
/// and the full fit at that time would take the misfit up with a defect
/// near the sensor.
///
/// # Errors
/// As [`Series::shifted`], `first` and `run`.
pub(super) fn fit_retimed(
    rec: &Series,
    model: &Model,
    t0: f64,
    (refine, nuisance): (bool, Nuisance),
    first: Option<(&FitRun<'_>, bool)>,
    run: impl Fn(&Observations) -> Result<FitReport>,
) -> Result<FitReport> {
    let (shifted, mut dropped) = rec.shifted(t0)?;
    let small = model.n() < MAX_N_REFINE;
    let (mut time, mut refits) = (t0, 0);
    let shifted = Observations::Series(shifted);
    let (mut report, mut final_fit, keeps) = match first {
        Some((f, keeps)) if refine && small => (f(&shifted)?, false, keeps),
        _ => (run(&shifted)?, true, false),
    };
    let step = step_near(rec.t(), t0);
    if refine && small {
        let chain = fitted_chain(&report, model)?;
        let (better, se) = refined(rec, &chain, model, (t0, step), report.noise_sigma, nuisance)?;
        if (better - t0).abs() > se.min(0.05 * step) {
            let (again, d) = rec.shifted(better)?;
            report = run(&Observations::Series(again))?;
            (time, dropped, refits, final_fit) = (better, d, 1, true);
        }
    }
    // the white fit at an unmoved time is the answer when it explains the
    // record (the defaults would keep the white model); otherwise the full
    // defaults at that time
    let done = final_fit || (keeps && report.fits_data);
    if !done {
        report = run(&shifted)?;
    }
    // the time again with the answer's chain and nuisances: the chain it
    // was refined with may be far from the answer's (a white fit of a
    // record with an offset), and a time off by a few of its standard
    // errors is a misfit that a defect near the sensor takes up
    while refine && small && refits < MAX_REFITS {
        let chain = fitted_chain(&report, model)?;
        let own = Nuisance::ALL[report.nuisance.len().min(2)];
        let (better, se) = refined(rec, &chain, model, (time, step), report.noise_sigma, own)?;
        if (better - time).abs() <= se.min(0.05 * step) {
            break;
        }
        let (again, d) = rec.shifted(better)?;
        report = run(&Observations::Series(again))?;
        (time, dropped, refits) = (better, d, refits + 1);
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
/// blow at a variable time, the sensor's nuisances (an offset, a drift)
/// profiled out of the residual.
struct Record<'a> {
    t: &'a [f64],
    y: &'a [f64],
    inv_sigma: f64,
    rec: &'a Series,
    nuisance: Option<Projector>,
}

impl<'a> Record<'a> {
    fn after(rec: &'a Series, from: f64, sigma: f64, nuisance: Nuisance) -> Result<Record<'a>> {
        let first = rec.t().partition_point(|&v| v < from);
        let t = &rec.t()[first..];
        Ok(Record {
            t,
            y: &rec.x()[first..],
            inv_sigma: 1.0 / sigma.max(f64::MIN_POSITIVE),
            rec,
            nuisance: Projector::new(nuisance, t, &NoiseModel::White)?,
        })
    }

    /// `chain`'s response at the sensor.
    fn response(&self, chain: &Chain) -> Result<ModalResponse> {
        let sensor = self.rec.measurement().sensor();
        ModalResponse::impulse_observable(chain, sensor.at, sensor.kind)
    }

    /// Whitened residuals of the response `u` to a blow at `time` (zero
    /// before it), the nuisances projected off.
    fn residuals(&self, u: &ModalResponse, time: f64) -> Vec<f64> {
        let r: Vec<f64> = u
            .eval_after(self.t, time)
            .iter()
            .zip(self.y)
            .map(|(m, &y)| (m - y) * self.inv_sigma)
            .collect();
        match &self.nuisance {
            Some(p) => p.project(&r),
            None => r,
        }
    }
}

/// The fitted values and the blow's time as one least-squares problem on
/// the samples after `from` (those before the blow model 0).
struct Joint<'a> {
    record: Record<'a>,
    chain: &'a Chain,
    params: &'a [Param],
}

impl crate::detect::search::lsq::LeastSquares for Joint<'_> {
    fn residuals(&self, theta: &[f64]) -> Result<Vec<f64>> {
        crate::cancel::check()?;
        let mut c = self.chain.clone();
        for (p, v) in self.params.iter().zip(&theta[1..]) {
            c = p.set(&c, *v)?;
        }
        Ok(self.record.residuals(&self.record.response(&c)?, theta[0]))
    }
}

/// The parameters fitted with the blow's time: the defects found and the
/// fitted chain parameters of `chain` (the model's known defects first).
fn fitted_params(chain: &Chain, model: &Model) -> Vec<Param> {
    let known = model.chain().defects().len();
    let mut params: Vec<Param> = (known..chain.defects().len()).map(Param::Defect).collect();
    params.extend_from_slice(model.fitted());
    params
}

/// The blow's time within a `step` of `t0`, fitted jointly with `chain`'s
/// fitted values by bounded Levenberg-Marquardt (the values within a
/// factor 100 of the fit's; the samples from a step and a half before `t0`,
/// so that the set does not change with the time). Returns the time and
/// its standard error.
fn refined(
    rec: &Series,
    chain: &Chain,
    model: &Model,
    (t0, step): (f64, f64),
    sigma: f64,
    nuisance: Nuisance,
) -> Result<(f64, f64)> {
    use crate::detect::search::lsq::{levenberg_marquardt, LmOptions};
    let params = fitted_params(chain, model);
    let joint = Joint {
        record: Record::after(rec, t0 - 1.5 * step, sigma, nuisance)?,
        chain,
        params: &params,
    };
    let mut theta = vec![t0];
    let mut bounds = vec![(t0 - step, t0 + step)];
    for p in &params {
        let v = p.get(chain)?;
        theta.push(v);
        bounds.push(if v > 0.0 {
            (v / 100.0, v * 100.0)
        } else {
            (0.0, 1.0)
        });
    }
    let opts = LmOptions {
        max_iter: 30,
        rtol: 1e-8,
        ..LmOptions::default()
    };
    let fit = levenberg_marquardt(&joint, &theta, &bounds, &opts)?;
    let se = fit.std_errors().map_or(f64::INFINITY, |e| e[0]);
    Ok((fit.theta[0], se))
}

/// Standard error of the blow's time jointly with the fitted values (see
/// the module docs); NaN when the information matrix is singular.
fn standard_error(rec: &Series, report: &FitReport, model: &Model, time: f64) -> Result<f64> {
    let chain = fitted_chain(report, model)?;
    let params = fitted_params(&chain, model);
    let nuisance = Nuisance::ALL[report.nuisance.len().min(2)];
    time_error(rec, (&chain, &params), (report.noise_sigma, nuisance), time)
}

/// [`standard_error`] of `chain` with its fitted `params`, the record's
/// noise level and nuisances as given.
fn time_error(
    rec: &Series,
    (chain, params): (&Chain, &[Param]),
    (sigma, nuisance): (f64, Nuisance),
    time: f64,
) -> Result<f64> {
    let r = Record::after(rec, time, sigma, nuisance)?;
    let h_t = 1e-4 * step_near(rec.t(), time);
    let mut cols: Vec<Vec<f64>> = Vec::with_capacity(params.len() + 1);
    let u = r.response(chain)?;
    let (plus, minus) = (r.residuals(&u, time + h_t), r.residuals(&u, time - h_t));
    cols.push(difference(&plus, &minus, h_t));
    for p in params {
        let v = p.get(chain)?;
        let h = 1e-6 * v.abs().max(1e-6);
        // a value on its bound (a damper fitted at 0): the one-sided
        // difference
        let at =
            |v: f64| -> Result<Vec<f64>> { Ok(r.residuals(&r.response(&p.set(chain, v)?)?, time)) };
        cols.push(difference_within(at(v + h), at(v - h), || at(v), h)?);
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

    /// A fitted damper on its bound 0: its one-sided difference (the
    /// central one left the domain `d >= 0`, and the whole fit failed with
    /// an error about a value the user never gave).
    #[test]
    fn a_damper_fitted_at_zero_still_gives_the_time_its_error() {
        let truth = crate::scenes::paper_with(10, "damper:8:0").unwrap();
        let rec = record(&truth, 0.0, 3.3, 1e-3, 2);
        let params = [Param::Defect(0)];
        let se = time_error(&rec, (&truth, &params), (1e-3, Nuisance::None), 3.3).unwrap();
        assert!(se.is_finite() && se > 0.0 && se < 0.01, "{se}");
    }
}
