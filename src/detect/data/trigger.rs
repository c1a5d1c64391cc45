//! When the blow came: the impulse's time on the record's axis.
//!
//! The fit's model starts the motion at `t = 0`. A real record often does
//! not: a data logger keeps a pre-trigger segment before the blow, or its
//! clock reads 12.5 s when the hammer lands. [`TriggerSpec`] says what is
//! known of that time: `At(t)` (the user knows it; `At(0)` is the paper's
//! convention) or `Auto` (the default: detected here, then refined by the
//! fit, [`crate::detect::fit::trigger`]).
//!
//! **Detection** ([`detect_onset`]), only for a record that shows it does
//! not start with the blow (a quiet lead-in of [`LEAD_IN`] samples or
//! more, an axis that starts before 0, or one that starts more than a step
//! and a half after 0; a record that moves from its first samples on an
//! axis from 0 is taken as the paper's, whatever its chain, unless it is of
//! a displacement that starts more than five noise levels from rest, which
//! the blow's displacement is not): the first sample that leaves the
//! record's starting level by more than five noise levels brackets the blow
//! (for a displacement cut short, the bracket is the comparison window
//! before the first sample);
//! inside that bracket the time `t0` is the minimiser of the chi-square of
//! `b + A u(t - t0)` on the first few periods (`u` the uniform chain's
//! response of the observed quantity, zero before `t0`; the level `b` and
//! the scale `A` solved by least squares for each `t0`, so that neither the
//! sensor's offset nor the impulse's size matters). A record whose blow is at
//! its start (within the noise: a chi-square gain below
//! [`DETECTION_CHI2`], or a shift below [`MIN_SHIFT`] steps) keeps `t0 =
//! 0` (the user's axis), and the fit is exactly the paper's.
//!
//! **Shift** ([`Series::shifted`]): samples before `t0` are dropped and the
//! rest re-timed `t - t0`.
//!
//! ```
//! use springmass::{Chain, Defect};
//! use springmass::detect::data::{observations::Series, trigger::detect_onset};
//! use springmass::time::modal::ModalResponse;
//! // the paper's chain hit at t = 3.3 of a record that starts at 0
//! let chain = Chain::paper(8)?.with_defect(Defect::Mass { at: 5, m: 2.0 })?;
//! let x1 = ModalResponse::impulse(&chain, 1)?;
//! let t: Vec<f64> = (0..400).map(|i| 0.2 * i as f64).collect();
//! let x: Vec<f64> = t.iter().map(|&t| if t < 3.3 { 0.0 } else { x1.eval(t - 3.3) }).collect();
//! let rec = Series::new(t, x, None)?;
//! let t0 = detect_onset(&rec, &chain.uniform())?.expect("a late blow");
//! assert!((t0 - 3.3).abs() < 0.02, "{t0}");
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::chain::Chain;
use crate::detect::data::observations::{Series, MIN_SAMPLES};
use crate::detect::fit::noise::high_frequency_sigma;
use crate::error::{Error, Result};
use crate::time::modal::ModalResponse;

/// Chi-square gain (in units of the noise variance) below which a detected
/// blow is taken to be at the record's start: a 5-sigma threshold for one
/// parameter.
pub const DETECTION_CHI2: f64 = 25.0;
/// Fewest samples at the starting level that make a pre-trigger segment.
pub const LEAD_IN: usize = 3;
/// Smallest detected shift of the blow from the user's `t = 0`, in steps:
/// below it the early-time comparison with the uniform chain cannot tell
/// a late blow from a defect near mass 1, and a record that late fits as
/// one that starts with the blow.
pub const MIN_SHIFT: f64 = 0.05;

/// What is known of the impulse's time on the record's axis.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub enum TriggerSpec {
    /// Unknown: detected from the record and refined by the fit (default).
    #[default]
    Auto,
    /// Known: the blow at this time of the record's axis (`At(0)`: the
    /// paper's convention, the record starting with the blow).
    At(f64),
}

impl TriggerSpec {
    /// Parse `auto` or a time (`0`, `12.5`, `-0.1`).
    ///
    /// # Errors
    /// Anything else (field `trigger`).
    pub fn parse(text: &str) -> Result<TriggerSpec> {
        let s = text.trim();
        if s.eq_ignore_ascii_case("auto") {
            return Ok(TriggerSpec::Auto);
        }
        match s.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(TriggerSpec::At(v)),
            _ => Err(Error::invalid(
                "trigger",
                text,
                "auto, or the time of the blow on the record's axis (a finite number)",
            )),
        }
    }
}

impl std::fmt::Display for TriggerSpec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            TriggerSpec::Auto => f.write_str("auto"),
            TriggerSpec::At(v) => write!(f, "{v}"),
        }
    }
}

impl Series {
    /// The record re-timed so that the blow at `t0` (on this record's time
    /// axis, [`Series::t`]) is `t = 0`: samples before `t0` dropped, the
    /// rest at `t - t0`. Returns the new record and how many samples were
    /// dropped.
    ///
    /// # Errors
    /// `t0` not finite, or leaving fewer than [`MIN_SAMPLES`] samples
    /// (field `trigger`); a measured force (field `trigger`: the force and
    /// the response are re-timed together by the user, not here).
    pub fn shifted(&self, t0: f64) -> Result<(Series, usize)> {
        let t = self.t();
        let first = t.partition_point(|&v| v < t0);
        if !t0.is_finite() || t.len() - first < MIN_SAMPLES {
            return Err(Error::invalid(
                "trigger",
                t0 + self.origin(),
                format!(
                    "a time inside the record ({} .. {}) that leaves at least {MIN_SAMPLES} samples after it",
                    t[0] + self.origin(),
                    t[t.len() - 1] + self.origin()
                ),
            ));
        }
        if self.measurement().force().is_some() {
            return Err(Error::invalid(
                "trigger",
                t0 + self.origin(),
                "the record's own start with a measured force (align the force and the response in the file)",
            ));
        }
        let ts: Vec<f64> = t[first..].iter().map(|v| v - t0).collect();
        let mut out = Series::new(ts, self.x()[first..].to_vec(), self.sigma())?
            .with_measurement(self.measurement().clone())?;
        out.set_origin(self.origin() + t0);
        if !self.others().is_empty() {
            let others = self
                .others()
                .iter()
                .map(|o| Ok(o.shifted(t0)?.0))
                .collect::<Result<Vec<_>>>()?;
            out = if self.separate_records() {
                out.with_records(others)?
            } else {
                out.with_sensors(others)?
            };
        }
        Ok((out, first))
    }
}

/// The blow's time on `rec`'s axis, detected (see the module docs), or
/// `None` when the record starts with it (the paper's convention holds),
/// when it is too short or flat to tell, or when it was driven by a
/// measured force. `uniform` is the chain the record is compared with at
/// early times (the model's uniform chain).
///
/// # Errors
/// The uniform chain's modal errors.
pub fn detect_onset(rec: &Series, uniform: &Chain) -> Result<Option<f64>> {
    Ok(onset_candidates(rec, uniform)?.first().copied())
}

/// The blow's possible times on `rec`'s axis, best first: the first is
/// [`detect_onset`]'s; a displacement cut short after its blow adds the
/// other local minima of the comparison's chi-square before the record
/// (at most [`CUT_CANDIDATES`] in all, each a detection on its own: gain
/// and shift above the thresholds). The comparison is with the uniform
/// chain, so a long cut, whose window a defect's echo has reached, can
/// put its best minimum a period or more away from the blow; the fit tries
/// the others when the first does not explain the record. Empty when
/// [`detect_onset`] is `None`.
///
/// # Errors
/// The uniform chain's modal errors.
pub fn onset_candidates(rec: &Series, uniform: &Chain) -> Result<Vec<f64>> {
    let (t, x) = (rec.t(), rec.x());
    if t.len() < MIN_SAMPLES || rec.measurement().force().is_some() {
        return Ok(Vec::new());
    }
    // a noise-free record is compared to the rounding of its own printed
    // digits at best
    let sigma = high_frequency_sigma(x).max(1e-9 * rec.max_abs());
    let Some(first) = (1..t.len()).find(|&i| (x[i] - x[0]).abs() > 5.0 * sigma) else {
        return Ok(Vec::new());
    };
    let dt = t[1] - t[0];
    // only a record that shows it does not start with the blow is
    // examined: a quiet lead-in of at least LEAD_IN samples, an axis that
    // starts before 0 or more than a step and a half after it, or a
    // displacement that starts away from rest; a record that moves from
    // its first samples on an axis from 0 is the paper's
    let lead_in = first >= LEAD_IN;
    let cut = cut_short(rec, sigma);
    if !(lead_in || cut || rec.origin() < 0.0 || t[0] > 1.5 * dt) {
        return Ok(Vec::new());
    }
    let u = ModalResponse::impulse_observable(
        uniform,
        rec.measurement().sensor().at,
        rec.measurement().sensor().kind,
    )?;
    let window = window(uniform, dt);
    let end = t[first] + window;
    let last = t.partition_point(|&v| v <= end).max(first + 4).min(t.len());
    let w = Window {
        t: &t[..last],
        x: &x[..last],
        u: &u,
    };
    // the blow in the samples' bracket, and for a displacement that starts
    // away from rest also before the record (its quiet start may be the
    // flat top of the first swing, not a lead-in at an offset): the better
    let inside = (lead_in || !cut).then(|| {
        let lo = t[first.saturating_sub(2)] - if first <= 2 { dt } else { 0.0 };
        golden(&w, lo, t[first])
    });
    // first the best of the two brackets' minimisers, then the other
    // minima before a record cut short, best first
    let before = match cut {
        true => minima(&w, t[0] - window, t[0]),
        false => Vec::new(),
    };
    let chi2 = |v: f64| (v, w.chi2(v));
    // (the best itself among them is dropped below as a repeat)
    let mut others: Vec<(f64, f64)> = before.iter().copied().map(chi2).collect();
    others.sort_by(|a, b| a.1.total_cmp(&b.1));
    let best = [inside, before.first().copied()]
        .into_iter()
        .flatten()
        .map(chi2)
        .min_by(|a, b| a.1.total_cmp(&b.1));
    let null = -rec.origin();
    let c_null = w.chi2(null);
    let mut out: Vec<f64> = Vec::new();
    for (v, c) in best.into_iter().chain(others) {
        let detected =
            (c_null - c) / (sigma * sigma) > DETECTION_CHI2 && (v - null).abs() > MIN_SHIFT * dt;
        // the best must be a detection; the others are alternatives to it
        if !detected {
            if out.is_empty() {
                return Ok(out);
            }
            continue;
        }
        if out.len() < CUT_CANDIDATES && out.iter().all(|o| (o - v).abs() > dt) {
            out.push(v);
        }
    }
    Ok(out)
}

/// Most candidate times of a record cut short ([`onset_candidates`]).
pub const CUT_CANDIDATES: usize = 3;

/// Whether `rec` is a displacement record that starts away from rest by
/// more than five noise levels `sigma`: a displacement is 0 at the blow, so
/// such a record was cut short after it (a logger started by a threshold
/// without a pre-trigger segment), or its sensor has an offset (the
/// detection's free level then finds no shift).
fn cut_short(rec: &Series, sigma: f64) -> bool {
    rec.measurement().sensor().kind == crate::forward::Observable::Displacement
        && rec.x()[0].abs() > 5.0 * sigma
}

/// Length of the comparison window after the first moving sample: four
/// periods of the uniform chain's highest mode, at least eight steps (a
/// defect near the sensor biases the time by a few hundredths of a step
/// here; the joint refinement of the fit removes that).
fn window(uniform: &Chain, dt: f64) -> f64 {
    let w_max = uniform.uniform_band();
    (4.0 * std::f64::consts::TAU / w_max).max(8.0 * dt)
}

/// The early samples and the uniform response they are compared with.
struct Window<'a> {
    t: &'a [f64],
    x: &'a [f64],
    u: &'a ModalResponse,
}

impl Window<'_> {
    /// `min over (b, A) of sum (x_i - b - A u(t_i - t0))^2`.
    fn chi2(&self, t0: f64) -> f64 {
        let m = self.u.eval_after(self.t, t0);
        let n = self.t.len() as f64;
        let (sm, sx) = (m.iter().sum::<f64>(), self.x.iter().sum::<f64>());
        let smm: f64 = m.iter().map(|v| v * v).sum();
        let smx: f64 = m.iter().zip(self.x).map(|(a, b)| a * b).sum();
        let det = n * smm - sm * sm;
        let (b, a) = if det.abs() > 1e-300 {
            ((smm * sx - sm * smx) / det, (n * smx - sm * sx) / det)
        } else {
            (sx / n, 0.0)
        };
        m.iter()
            .zip(self.x)
            .map(|(mi, xi)| (xi - b - a * mi).powi(2))
            .sum()
    }
}

/// Points of the grid of [`golden`] and [`minima`].
const GRID: usize = 24;

/// The minimiser of [`Window::chi2`] on `[lo, hi]`: the best of a grid of
/// [`GRID`] + 1 points, then golden-section search
/// ([`crate::linalg::golden`]) in its bracket.
fn golden(w: &Window<'_>, lo: f64, hi: f64) -> f64 {
    let (at, c) = grid(w, lo, hi);
    refine(w, &at, lowest(&c))
}

/// Every local minimum of [`Window::chi2`] on `[lo, hi]`: the grid's
/// (a point no higher than its neighbours), each refined as in [`golden`];
/// the first is [`golden`]'s (the grid's lowest point), the others in the
/// grid's order.
fn minima(w: &Window<'_>, lo: f64, hi: f64) -> Vec<f64> {
    let (at, c) = grid(w, lo, hi);
    let low = lowest(&c);
    std::iter::once(low)
        .chain((0..=GRID).filter(|&i| {
            i != low && (i == 0 || c[i] <= c[i - 1]) && (i == GRID || c[i] <= c[i + 1])
        }))
        .map(|i| refine(w, &at, i))
        .collect()
}

/// The index of the grid's lowest chi-square (the first of equals).
fn lowest(c: &[f64]) -> usize {
    (0..c.len())
        .min_by(|&a, &b| c[a].total_cmp(&c[b]))
        .unwrap_or(0)
}

/// The grid of [`golden`] on `[lo, hi]`: a point's time, and the chi-square
/// at every point.
fn grid(w: &Window<'_>, lo: f64, hi: f64) -> (impl Fn(usize) -> f64, Vec<f64>) {
    let h = (hi - lo) / GRID as f64;
    let at = move |i: usize| lo + h * i as f64;
    let c = (0..=GRID).map(|i| w.chi2(at(i))).collect();
    (at, c)
}

/// The golden-section minimiser of [`Window::chi2`] between the grid's
/// neighbours of point `i`.
fn refine(w: &Window<'_>, at: &impl Fn(usize) -> f64, i: usize) -> f64 {
    let (a, b) = (at(i.saturating_sub(1)), at((i + 1).min(GRID)));
    crate::linalg::golden(|t| w.chi2(t), a, b, 60).0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::noise::NoiseLevel;

    fn late(t0: f64, t_first: f64, noise: f64, seed: u64) -> Series {
        let chain = crate::scenes::paper_with(20, "mass:8:5 mass:15:2").unwrap();
        let x1 = ModalResponse::impulse(&chain, 1).unwrap();
        let t: Vec<f64> = (0..1000).map(|i| t_first + 0.2 * i as f64).collect();
        let clean: Vec<f64> = t
            .iter()
            .map(|&v| if v < t0 { 0.0 } else { x1.eval(v - t0) })
            .collect();
        let x = if noise > 0.0 {
            crate::noise::add_noise(&clean, NoiseLevel::RelativeMax(noise), seed)
                .unwrap()
                .0
        } else {
            clean
        };
        Series::on_axis(t, x, None).unwrap()
    }

    /// A late blow, and a displacement cut short after it (`t0 < 0`).
    #[test]
    fn a_late_blow_or_a_cut_is_found_within_a_small_part_of_a_step() {
        let uniform = Chain::paper(20).unwrap();
        let late_cases = [(10.0, 1e-3), (10.07, 1e-2), (3.31, 0.0)];
        let cut_cases = [(-0.37, 1e-3), (-1.3, 1e-2), (-0.07, 0.0), (-4.1, 1e-3)];
        for (t0, noise) in late_cases.into_iter().chain(cut_cases) {
            let rec = late(t0, 0.0, noise, 3);
            let got = detect_onset(&rec, &uniform).unwrap().expect("found");
            assert!((got - t0).abs() < 0.05, "t0 {t0} noise {noise}: {got}");
        }
    }

    /// A long cut of a chain whose defect's echo reaches the comparison
    /// window: the blow is among the candidates (measured: the best match
    /// is a period away, at -12.1 for a cut of 2.5).
    #[test]
    fn a_long_cuts_blow_is_among_the_candidates() {
        let chain = crate::scenes::paper_with(10, "mass:4:2").unwrap();
        let x1 = ModalResponse::impulse(&chain, 1).unwrap();
        for (cut, seed) in [(2.0, 7), (2.5, 7)] {
            let t: Vec<f64> = (0..1000).map(|i| 0.1 * i as f64).collect();
            let clean: Vec<f64> = t.iter().map(|&v| x1.eval(v + cut)).collect();
            let noise = NoiseLevel::RelativeMax(5e-3);
            let x = crate::noise::add_noise(&clean, noise, seed).unwrap().0;
            let rec = Series::on_axis(t, x, None).unwrap();
            let got = onset_candidates(&rec, &Chain::paper(10).unwrap()).unwrap();
            assert!(got.len() <= CUT_CANDIDATES, "{got:?}");
            assert!(
                got.iter().any(|v| (v + cut).abs() < 0.05),
                "cut {cut}: {got:?}"
            );
        }
    }

    /// Also with a sensor's offset, which is no cut: the detection's free
    /// level takes it.
    #[test]
    fn a_record_that_starts_with_the_blow_is_left_alone() {
        let uniform = Chain::paper(20).unwrap();
        for (seed, offset) in (0..10).flat_map(|s| [(s, 0.0), (s, 0.05)]) {
            for noise in [0.0, 1e-3, 1e-2] {
                let rec = late(0.0, 0.0, noise, seed);
                let x: Vec<f64> = rec.x().iter().map(|v| v + offset).collect();
                let rec = Series::on_axis(rec.t().to_vec(), x, None).unwrap();
                assert_eq!(
                    detect_onset(&rec, &uniform).unwrap(),
                    None,
                    "{seed} {noise} {offset}"
                );
            }
        }
    }

    #[test]
    fn shift_drops_the_pre_trigger_and_keeps_the_user_axis() {
        let rec = late(10.0, 0.0, 1e-3, 1);
        let (s, dropped) = rec.shifted(10.0).unwrap();
        assert_eq!(dropped, 50);
        assert!(s.t()[0].abs() < 1e-12 && (s.origin() - 10.0).abs() < 1e-12);
        assert!(rec.shifted(1e9).is_err());
        assert!(rec.shifted(f64::NAN).is_err());
    }

    #[test]
    fn parse() {
        assert_eq!(TriggerSpec::parse("auto").unwrap(), TriggerSpec::Auto);
        assert_eq!(TriggerSpec::parse(" 12.5").unwrap(), TriggerSpec::At(12.5));
        for bad in ["", "soon", "inf", "nan"] {
            let e = TriggerSpec::parse(bad).unwrap_err().to_string();
            assert!(e.contains("trigger"), "{e}");
        }
    }
}
