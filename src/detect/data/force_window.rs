//! The force window of experimental modal analysis: a measured hammer
//! force is zeroed outside its pulse.
//!
//! A force sensor carries noise over the whole record; convolved through
//! the chain, that noise becomes a response the model attributes to the
//! structure, and it can bias a fit or move a defect. A lab applies a force
//! window: the force is kept on the pulse and set to zero elsewhere. Here
//! the pulse is found as the samples around the largest `|f|` that stay
//! above [`PULSE_LEVEL`] times the force's noise level (the median absolute
//! deviation of the samples, scaled to a standard deviation), widened by
//! [`MARGIN`] samples on each side; or the window is given as a time range,
//! or switched off.
//!
//! ```
//! use springmass::detect::data::force_window::{apply, ForceWindow};
//! let t: Vec<f64> = (0..200).map(|i| 0.01 * i as f64).collect();
//! // a half-sine blow on [0.1, 0.15] and a noisy sensor elsewhere
//! let f: Vec<f64> = t.iter().enumerate().map(|(i, &t)| {
//!     let pulse = if (0.1..=0.15).contains(&t) { (std::f64::consts::PI * (t - 0.1) / 0.05).sin() * 100.0 } else { 0.0 };
//!     pulse + if i % 2 == 0 { 0.3 } else { -0.3 }
//! }).collect();
//! let (g, window) = apply(&t, &f, ForceWindow::Auto)?;
//! let (t0, t1) = window.expect("a pulse");
//! assert!(t0 <= 0.1 && t1 >= 0.15 && t1 - t0 < 0.12);
//! assert_eq!(g[150], 0.0);                 // noise outside the pulse removed
//! assert_eq!(g[12], f[12]);                // the pulse kept
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::error::{Error, Result};

/// A windowed force and the time range it was windowed to (`None`: the
/// whole record kept).
pub type Windowed = (Vec<f64>, Option<(f64, f64)>);

/// Samples above this many noise levels belong to the pulse.
pub const PULSE_LEVEL: f64 = 5.0;
/// Samples kept on each side of the detected pulse.
pub const MARGIN: usize = 2;

/// Which part of a measured force is kept.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub enum ForceWindow {
    /// The detected pulse (default).
    #[default]
    Auto,
    /// The whole record (no window).
    Off,
    /// The samples with `t0 <= t <= t1`.
    Range(f64, f64),
}

impl ForceWindow {
    /// Parse `auto`, `none`, or `T0:T1` (times on the record's axis).
    ///
    /// # Errors
    /// Anything else, or `T0 >= T1` (field `force_window`).
    pub fn parse(text: &str) -> Result<ForceWindow> {
        let s = text.trim();
        let bad = || {
            Error::invalid(
                "force_window",
                text,
                "auto, none, or T0:T1 with finite T0 < T1 (times on the record's axis)",
            )
        };
        match s {
            "auto" => Ok(ForceWindow::Auto),
            "none" | "off" => Ok(ForceWindow::Off),
            _ => {
                let (a, b) = s.split_once(':').ok_or_else(bad)?;
                let (a, b): (f64, f64) = (
                    a.trim().parse().map_err(|_| bad())?,
                    b.trim().parse().map_err(|_| bad())?,
                );
                if a.is_finite() && b.is_finite() && a < b {
                    Ok(ForceWindow::Range(a, b))
                } else {
                    Err(bad())
                }
            }
        }
    }
}

/// The force `f` at times `t` windowed as `spec` says, and the window's
/// time range (`None` when the whole record is kept).
///
/// # Errors
/// `t` and `f` of different lengths (field `force`); a given range that
/// holds no sample (field `force_window`).
pub fn apply(t: &[f64], f: &[f64], spec: ForceWindow) -> Result<Windowed> {
    if t.len() != f.len() || f.is_empty() {
        return Err(Error::invalid(
            "force",
            format!("{} samples for {} times", f.len(), t.len()),
            "one force sample per time",
        ));
    }
    let (lo, hi) = match spec {
        ForceWindow::Off => return Ok((f.to_vec(), None)),
        ForceWindow::Range(a, b) => {
            let lo = t.partition_point(|&v| v < a);
            let hi = t.partition_point(|&v| v <= b);
            if lo >= hi {
                return Err(Error::invalid(
                    "force_window",
                    format!("{a}:{b}"),
                    format!(
                        "a range that holds samples of the record ({} .. {})",
                        t[0],
                        t[t.len() - 1]
                    ),
                ));
            }
            (lo, hi)
        }
        ForceWindow::Auto => match pulse(f) {
            Some(r) => r,
            None => return Ok((f.to_vec(), None)),
        },
    };
    let g = f
        .iter()
        .enumerate()
        .map(|(i, &v)| if (lo..hi).contains(&i) { v } else { 0.0 })
        .collect();
    Ok((g, Some((t[lo], t[hi - 1]))))
}

/// The pulse's sample range `[lo, hi)` around the largest `|f|` (see the
/// module docs), or `None` when the force has no noise to stand out from
/// (a clean force: nothing to window) or no clear pulse.
fn pulse(f: &[f64]) -> Option<(usize, usize)> {
    let mut dev: Vec<f64> = f.iter().map(|v| v.abs()).collect();
    let mid = dev.len() / 2;
    dev.select_nth_unstable_by(mid, f64::total_cmp);
    let noise = 1.4826 * dev[mid];
    if noise <= 0.0 {
        return None;
    }
    let peak = (0..f.len()).max_by(|&a, &b| f[a].abs().total_cmp(&f[b].abs()))?;
    if f[peak].abs() < 4.0 * PULSE_LEVEL * noise {
        return None;
    }
    let above = |i: usize| f[i].abs() > PULSE_LEVEL * noise;
    let mut lo = peak;
    while lo > 0 && above(lo - 1) {
        lo -= 1;
    }
    let mut hi = peak + 1;
    while hi < f.len() && above(hi) {
        hi += 1;
    }
    Some((lo.saturating_sub(MARGIN), (hi + MARGIN).min(f.len())))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parse_and_bad_input() {
        assert_eq!(ForceWindow::parse("auto").unwrap(), ForceWindow::Auto);
        assert_eq!(ForceWindow::parse("none").unwrap(), ForceWindow::Off);
        assert_eq!(
            ForceWindow::parse("0:0.2").unwrap(),
            ForceWindow::Range(0.0, 0.2)
        );
        for bad in ["", "0.2:0", "a:b", "1", "nan:1"] {
            let e = ForceWindow::parse(bad).unwrap_err().to_string();
            assert!(e.contains("force_window"), "{e}");
        }
        let t = [0.0, 1.0, 2.0];
        assert!(apply(&t, &[1.0, 2.0], ForceWindow::Auto).is_err());
        assert!(apply(&t, &[1.0, 2.0, 3.0], ForceWindow::Range(5.0, 6.0)).is_err());
    }

    #[test]
    fn a_clean_force_is_left_alone_and_a_range_is_kept() {
        let t: Vec<f64> = (0..50).map(|i| i as f64).collect();
        let mut f = vec![0.0; 50];
        f[3] = 1.0;
        f[4] = 2.0;
        let (g, w) = apply(&t, &f, ForceWindow::Auto).unwrap();
        assert_eq!((g, w), (f.clone(), None));
        let noisy: Vec<f64> = f
            .iter()
            .enumerate()
            .map(|(i, v)| v + 0.01 * (i as f64).sin())
            .collect();
        let (g, w) = apply(&t, &noisy, ForceWindow::Range(2.0, 6.0)).unwrap();
        assert_eq!(w, Some((2.0, 6.0)));
        assert!(g[..2].iter().chain(&g[7..]).all(|v| *v == 0.0));
        assert_eq!(&g[2..7], &noisy[2..7]);
    }
}
