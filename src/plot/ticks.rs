//! Axis ticks and their labels: "nice" linear steps, integer ticks, log
//! decades, and the ticks of a line chart's axes and of a heatmap's grid.

/// Snap a tick computed as `k * step` to exactly 0 when it is rounding
/// noise (`|v| < 1e-9 step`), and turn `-0.0` into `0.0`.
fn snap(v: f64, step: f64) -> f64 {
    if v.abs() < step.abs() * 1e-9 {
        0.0
    } else {
        v + 0.0
    }
}

/// The "nice" step (1, 2, 2.5 or 5 times a power of ten) that cuts `span`
/// into about `target` intervals.
pub fn nice_step(span: f64, target: usize) -> f64 {
    let raw = span.abs() / target.max(1) as f64;
    if !(raw.is_finite() && raw > 0.0) {
        return 1.0;
    }
    let p = 10f64.powf(raw.log10().floor());
    let f = raw / p;
    let m = if f <= 1.0 {
        1.0
    } else if f <= 2.0 {
        2.0
    } else if f <= 2.5 {
        2.5
    } else if f <= 5.0 {
        5.0
    } else {
        10.0
    };
    m * p
}

/// Ticks `k * step` inside `[lo, hi]` with a nice step (about `target`
/// intervals). Every tick is an integer multiple of the step, so a range
/// that contains zero has the tick exactly `0.0`.
///
/// ```
/// let t = springmass::plot::linear_ticks(-2.776e-17, 1.0, 5);
/// assert_eq!(t, vec![0.0, 0.2, 0.4, 0.6000000000000001, 0.8, 1.0]);
/// assert!(t[0].is_sign_positive());
/// ```
pub fn linear_ticks(lo: f64, hi: f64, target: usize) -> Vec<f64> {
    if !(lo.is_finite() && hi.is_finite()) {
        return Vec::new();
    }
    if hi <= lo {
        return vec![snap(lo, lo.abs().max(1e-300))];
    }
    let step = nice_step(hi - lo, target);
    let k0 = (lo / step - 1e-9).ceil();
    let k1 = (hi / step + 1e-9).floor();
    if !(k0.is_finite() && k1.is_finite()) || k1 - k0 > 1000.0 {
        return vec![lo, hi];
    }
    (k0 as i64..=k1 as i64)
        .map(|k| snap(k as f64 * step, step))
        .collect()
}

/// Integer ticks inside `[lo, hi]`: step 1, 2, 5, 10, 20, ... (about
/// `target` intervals), never a fraction.
///
/// ```
/// assert_eq!(springmass::plot::integer_ticks(0.6, 5.4, 6), vec![1.0, 2.0, 3.0, 4.0, 5.0]);
/// ```
pub fn integer_ticks(lo: f64, hi: f64, target: usize) -> Vec<f64> {
    if !(lo.is_finite() && hi.is_finite()) {
        return Vec::new();
    }
    let step = nice_step(hi - lo, target);
    let step = if step <= 1.0 {
        1.0
    } else if step.fract() != 0.0 {
        // 2.5 * 10^k (k = 0): step 2
        let p = 10f64.powf(step.log10().floor());
        (step / p).floor().max(1.0) * p
    } else {
        step
    };
    let k0 = (lo / step - 1e-9).ceil();
    let k1 = (hi / step + 1e-9).floor();
    if !(k0.is_finite() && k1.is_finite()) || k1 < k0 || k1 - k0 > 1000.0 {
        return Vec::new();
    }
    (k0 as i64..=k1 as i64)
        .map(|k| snap(k as f64 * step, step))
        .collect()
}

/// Ticks of a logarithmic axis over `[lo, hi]` (both positive), in data
/// units: the powers of ten when the range holds three or more (thinned to
/// at most 8), else 1-2-5 ticks, else 1..9 times powers of ten, else (a range
/// narrower than a factor of about 3) plain linear ticks, so that an axis
/// spanning less than a decade still has at least two labelled ticks.
///
/// ```
/// use springmass::plot::log_ticks;
/// assert_eq!(log_ticks(1e-8, 0.1), vec![1e-8, 1e-7, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1]);
/// assert_eq!(log_ticks(0.3, 2.5), vec![0.5, 1.0, 2.0]);
/// assert!(log_ticks(2.1, 2.9).len() >= 2);
/// ```
pub fn log_ticks(lo: f64, hi: f64) -> Vec<f64> {
    if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && hi >= lo) {
        return Vec::new();
    }
    let (a, b) = (lo.log10(), hi.log10());
    let inside = |v: f64| v >= lo * (1.0 - 1e-9) && v <= hi * (1.0 + 1e-9);
    let (e0, e1) = ((a - 1e-9).ceil() as i32, (b + 1e-9).floor() as i32);
    if e1 - e0 >= 2 {
        let n = (e1 - e0 + 1) as usize;
        let every = match n.div_ceil(8) {
            0 | 1 => 1,
            2 => 2,
            3..=5 => 5,
            k => 10 * k.div_ceil(10),
        };
        // multiples of `every` in the exponent: 1e-30, 1e-25, ... not 1e-31, 1e-27
        return (e0..=e1)
            .filter(|e| e.rem_euclid(every as i32) == 0)
            .map(pow10)
            .collect();
    }
    let multiples = |ms: &[f64]| -> Vec<f64> {
        let mut v = Vec::new();
        for e in (a.floor() as i32 - 1)..=(b.ceil() as i32) {
            for &m in ms {
                let t = m * pow10(e);
                if inside(t) {
                    v.push(t);
                }
            }
        }
        v
    };
    let t = multiples(&[1.0, 2.0, 5.0]);
    if t.len() >= 3 {
        return t;
    }
    let t = multiples(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]);
    if t.len() >= 3 {
        return t;
    }
    linear_ticks(lo, hi, 4)
}

/// Labels of log-axis ticks given in data units: [`tick_label`] each, or,
/// when ticks lie closer than its 4 significant digits tell apart (a log
/// axis spanning a tiny factor), [`tick_label_step`] with the smallest
/// spacing.
pub fn log_tick_labels(ticks: &[f64]) -> Vec<String> {
    // decades over a wide range: one notation for all (1e-8 ... 1e-1)
    let exps: Vec<Option<i32>> = ticks
        .iter()
        .map(|v| {
            let e = v.log10().round();
            (e.is_finite() && (v / pow10(e as i32) - 1.0).abs() < 1e-9).then_some(e as i32)
        })
        .collect();
    if ticks.len() >= 2
        && exps.iter().all(Option::is_some)
        && exps.iter().flatten().any(|e| e.abs() >= 4)
    {
        return exps
            .iter()
            .flatten()
            .map(|e| {
                if *e == 0 {
                    "1".into()
                } else {
                    format!("1e{e}")
                }
            })
            .collect();
    }
    let plain: Vec<String> = ticks.iter().map(|v| tick_label(*v)).collect();
    if plain.windows(2).all(|w| w[0] != w[1]) {
        return plain;
    }
    let step = ticks
        .windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .fold(f64::INFINITY, f64::min);
    ticks.iter().map(|v| tick_label_step(*v, step)).collect()
}

/// The label of the tick nearest `v` (plotted coordinates `ticks`, labels
/// `labels` of the same length); empty when there is none.
#[cfg_attr(not(feature = "plot"), allow(dead_code))]
pub(super) fn nearest_label(v: f64, ticks: &[f64], labels: &[String]) -> String {
    ticks
        .iter()
        .zip(labels)
        .min_by(|a, b| (a.0 - v).abs().total_cmp(&(b.0 - v).abs()))
        .map(|(_, l)| l.clone())
        .unwrap_or_default()
}

/// `10^e` without the rounding of `powi` for negative `e` (`1e-7`, not
/// `9.999999999999999e-8`).
fn pow10(e: i32) -> f64 {
    format!("1e{e}").parse().unwrap_or(f64::NAN)
}

/// A short tick label: plain decimals with at most 4 significant digits for
/// `1e-3 <= |v| < 1e5`, otherwise `1e-6`, `2.5e7` (rounding noise such as
/// `1.0000000000004e-6` is removed); `0` for both zeros.
pub fn tick_label(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return if v == 0.0 { "0".into() } else { format!("{v}") };
    }
    let a = v.abs();
    let trim = |t: String| -> String {
        if t.contains('.') {
            t.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            t
        }
    };
    let s = if (1e-3..1e5).contains(&a) {
        let decimals = (3 - a.log10().floor() as i32).clamp(0, 6) as usize;
        trim(format!("{v:.decimals$}"))
    } else {
        let t = format!("{v:.3e}");
        let (mant, exp) = t.split_once('e').unwrap_or((&t, "0"));
        format!("{}e{exp}", trim(mant.to_string()))
    };
    if s == "-0" {
        "0".into()
    } else {
        s
    }
}

/// A tick label on a linear axis with tick spacing `step`: enough decimals
/// to tell neighbouring ticks apart (`1000.2`, `1000.4`), else
/// [`tick_label`].
pub fn tick_label_step(v: f64, step: f64) -> String {
    let v = snap(v, step);
    let a = v.abs().max(step.abs());
    if !(step.is_finite() && step > 0.0 && (1e-3..1e5).contains(&a)) {
        return tick_label(v);
    }
    let decimals = (-(step.log10().floor()) as i32 + 1).clamp(0, 8) as usize;
    let t = format!("{v:.decimals$}");
    let t = if t.contains('.') {
        t.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        t
    };
    if t == "-0" {
        "0".into()
    } else {
        t
    }
}

/// Ticks over `[lo, hi]` (plotted coordinates) on a log, integer or linear
/// axis; a degenerate range is widened first.
pub(super) fn axis_ticks(lo: f64, hi: f64, log: bool, integer: bool) -> Vec<f64> {
    if log {
        let (a, b) = if hi > lo {
            (lo, hi)
        } else {
            (lo - 0.5, hi + 0.5)
        };
        log_ticks(10f64.powf(a), 10f64.powf(b))
            .into_iter()
            .map(f64::log10)
            .collect()
    } else if integer {
        let (a, b) = if hi > lo {
            (lo, hi)
        } else {
            (lo - 1.0, hi + 1.0)
        };
        integer_ticks(a, b, 6)
    } else {
        let (a, b) = if hi > lo {
            (lo, hi)
        } else {
            let w = 0.5 + lo.abs() * 0.1;
            (lo - w, hi + w)
        };
        linear_ticks(a, b, 6)
    }
}

/// Ticks for an axis of cell centres: integers when every centre is one.
#[cfg_attr(not(feature = "plot"), allow(dead_code))]
pub(super) fn grid_ticks(c: &[f64], lo: f64, hi: f64) -> Vec<f64> {
    let t = if c.iter().all(|v| v.fract() == 0.0) {
        integer_ticks(lo, hi, 8)
    } else {
        linear_ticks(lo, hi, 6)
    };
    t.into_iter().filter(|v| *v >= lo && *v <= hi).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_snap_to_zero_and_never_print_minus_zero() {
        // a range whose low end is rounding noise around 0
        let t = linear_ticks(-2.776e-17, 1.0, 5);
        assert_eq!(t[0].to_bits(), 0.0f64.to_bits(), "{t:?}");
        assert_eq!(tick_label(t[0]), "0");
        // a range crossing 0 at an awkward step: 0 is exact
        let t = linear_ticks(-0.3, 0.7, 6);
        assert!(t.iter().any(|v| v.to_bits() == 0.0f64.to_bits()), "{t:?}");
        for v in &t {
            let s = tick_label_step(*v, 0.2);
            assert!(!s.contains("e-1") && s != "-0", "{v} -> {s}");
        }
        assert_eq!(tick_label(-0.0), "0");
        assert_eq!(tick_label_step(-1e-18, 0.1), "0");
        assert_eq!(tick_label_step(-0.0, 0.5), "0");
        // neighbouring ticks stay apart
        assert_eq!(tick_label_step(1000.2, 0.2), "1000.2");
        assert_eq!(tick_label_step(0.30000000000000004, 0.1), "0.3");
    }

    #[test]
    fn integer_quantities_get_integer_ticks() {
        assert_eq!(integer_ticks(0.6, 5.4, 6), vec![1.0, 2.0, 3.0, 4.0, 5.0]);
        // a short range: still step 1, never 0.5
        assert_eq!(integer_ticks(1.8, 4.2, 8), vec![2.0, 3.0, 4.0]);
        for (lo, hi) in [(1.0, 19.0), (0.0, 1000.0), (5.0, 100_000.0), (-3.0, 3.0)] {
            let t = integer_ticks(lo, hi, 6);
            assert!(t.len() >= 2, "{lo}..{hi}: {t:?}");
            assert!(t.iter().all(|v| v.fract() == 0.0), "{lo}..{hi}: {t:?}");
        }
        // a 2.5 step becomes an integer one
        let t = integer_ticks(0.0, 15.0, 6);
        assert!(t.iter().all(|v| v.fract() == 0.0), "{t:?}");
    }

    #[test]
    fn log_ticks_label_sub_decade_ranges() {
        assert_eq!(log_ticks(1e-8, 0.1).len(), 8);
        assert_eq!(log_ticks(1.0, 1e3), vec![1.0, 10.0, 100.0, 1000.0]);
        // many decades: thinned to at most 8
        assert!(log_ticks(1e-300, 1e300).len() <= 8);
        assert_eq!(
            log_tick_labels(&log_ticks(1e-31, 1e-3)),
            ["1e-30", "1e-25", "1e-20", "1e-15", "1e-10", "1e-5"]
        );
        // about one decade: 1-2-5
        assert_eq!(log_ticks(0.3, 2.5), vec![0.5, 1.0, 2.0]);
        assert_eq!(log_ticks(64.0, 512.0), vec![100.0, 200.0, 500.0]);
        // less than a factor 2.5: 1..9 multiples or plain ticks, at least 2
        for (lo, hi) in [(2.1, 2.9), (128.0, 256.0), (0.9995, 1.0005), (3e-7, 5e-7)] {
            let t = log_ticks(lo, hi);
            assert!(t.len() >= 2, "{lo}..{hi}: {t:?}");
            assert!(
                t.iter().all(|v| *v >= lo * 0.999 && *v <= hi * 1.001),
                "{t:?}"
            );
            let labels = log_tick_labels(&t);
            let mut d = labels.clone();
            d.dedup();
            assert_eq!(d, labels, "distinct labels");
        }
        assert!(log_ticks(0.0, 1.0).is_empty());
        // decades over a wide range share one notation
        assert_eq!(
            log_tick_labels(&log_ticks(1e-8, 0.1)),
            ["1e-8", "1e-7", "1e-6", "1e-5", "1e-4", "1e-3", "1e-2", "1e-1"]
        );
        assert_eq!(log_tick_labels(&[1.0, 10.0, 100.0]), ["1", "10", "100"]);
        assert_eq!(tick_label(1e-7), "1e-7");
    }
}
