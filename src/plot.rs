//! SVG plots: line charts (one panel or small multiples) and heatmaps,
//! written atomically.
//!
//! Text is laid out with the DejaVu Sans font bundled in `assets/` (its
//! licence is `assets/DejaVuSans-LICENSE.txt`), registered once with plotters'
//! `ab_glyph` backend, so plots render the same on any machine without system
//! fonts. Rendering needs the `plot` feature (on by default); without it the
//! chart types still exist and [`LinePlot::to_svg_string`] and
//! [`Heatmap::to_svg_string`] return an [`Error::InvalidParameter`] naming
//! `plot`.
//!
//! What the charts do for the reader:
//!
//! - ticks are chosen here, not by the backend: "nice" steps (1, 2, 2.5, 5
//!   times a power of ten) computed as integer multiples of the step, so zero
//!   is exactly `0` (never `-2.776e-17` or `-0`) ([`linear_ticks`]);
//!   integer quantities (positions, counts) get integer ticks only
//!   ([`integer_ticks`]); log axes get labelled decades, or 1-2-5 or plain
//!   ticks when they span a decade or less ([`log_ticks`]);
//! - categorical axes ([`LinePlot::categories`]) put ticks at the categories
//!   only and draw points side by side, never joined by lines;
//! - rates sit on `[0, 1]` ([`LinePlot::rate`]);
//! - series beyond the 8 colours differ in dash pattern and marker too
//!   ([`series_style`]), and the legend sits outside the data, to the right;
//! - a chart with more than [`MAX_SERIES`] series becomes small multiples:
//!   one panel per series, or one panel per [`Line::panel`] name, with shared
//!   axes.
//!
//! ```no_run
//! use springmass::plot::{LinePlot, Line};
//! let pts: Vec<(f64, f64)> = (0..100).map(|i| (i as f64 * 0.1, (i as f64 * 0.1).sin())).collect();
//! LinePlot::new("x_1(t)", "t (time units)", "x_1 (displacement)")
//!     .line(Line::new("x_1", pts))
//!     .write_svg("out/x1.svg")?;
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::error::{Error, Result};
use crate::series::write_atomic;
use std::path::Path;

/// Most series one panel carries; a chart with more becomes small multiples.
pub const MAX_SERIES: usize = 6;

/// Qualitative colour cycle (colour-blind friendly, Okabe-Ito), as RGB.
const PALETTE: [(u8, u8, u8); 8] = [
    (0, 114, 178),
    (213, 94, 0),
    (0, 158, 115),
    (204, 121, 167),
    (230, 159, 0),
    (86, 180, 233),
    (0, 0, 0),
    (240, 228, 66),
];

// ---------------------------------------------------------------- ticks

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
fn nearest_label(v: f64, ticks: &[f64], labels: &[String]) -> String {
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

// ---------------------------------------------------------------- styles

/// Dash pattern of a series.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dash {
    /// A solid line.
    Solid,
    /// Long dashes.
    Dashed,
    /// Short dots.
    Dotted,
}

/// Marker shape of a series.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Marker {
    /// Filled circle.
    Circle,
    /// Filled square.
    Square,
    /// Filled triangle.
    Triangle,
    /// Cross.
    Cross,
}

/// How series `i` of a chart is drawn: the colour cycles through 8, the dash
/// pattern changes every 8 series (solid, dashed, dotted) and the marker with
/// every series, so series `i` and `i + 8` never look alike.
pub fn series_style(i: usize) -> ((u8, u8, u8), Dash, Marker) {
    const DASHES: [Dash; 3] = [Dash::Solid, Dash::Dashed, Dash::Dotted];
    const MARKERS: [Marker; 4] = [
        Marker::Circle,
        Marker::Square,
        Marker::Triangle,
        Marker::Cross,
    ];
    (
        PALETTE[i % 8],
        DASHES[(i / 8) % 3],
        MARKERS[(i + i / 8) % 4],
    )
}

// ---------------------------------------------------------------- charts

/// One curve of a [`LinePlot`].
#[derive(Clone, Debug)]
pub struct Line {
    /// Legend label (empty: no legend entry).
    pub label: String,
    /// Points `(x, y)`; non-finite points are skipped. On a categorical axis
    /// `x` is the index of the category.
    pub points: Vec<(f64, f64)>,
    /// Draw markers instead of a line.
    pub markers: bool,
    /// Dashed line.
    pub dashed: bool,
    /// The panel (small multiple) this curve belongs to; `None`: the chart
    /// decides.
    pub panel: Option<String>,
    /// Error bars, `(lo, hi)` for each point (empty: none).
    pub errors: Vec<(f64, f64)>,
    /// A shaded band `(x, lo, hi)` in the curve's colour (empty: none), for
    /// example the noise band around zero of a residual.
    pub band: Vec<(f64, f64, f64)>,
}

impl Line {
    /// A solid line.
    pub fn new(label: impl Into<String>, points: Vec<(f64, f64)>) -> Line {
        Line {
            label: label.into(),
            points,
            markers: false,
            dashed: false,
            panel: None,
            errors: Vec::new(),
            band: Vec::new(),
        }
    }
    /// Markers only.
    pub fn markers(mut self) -> Line {
        self.markers = true;
        self
    }
    /// Dashed.
    pub fn dashed(mut self) -> Line {
        self.dashed = true;
        self
    }
    /// Put the curve in the panel `name` (one panel per distinct name, in
    /// order of appearance; a label keeps its style in every panel).
    pub fn panel(mut self, name: impl Into<String>) -> Line {
        self.panel = Some(name.into());
        self
    }
    /// Vertical error bars, `(lo, hi)` for each point, in data units.
    pub fn errors(mut self, bars: Vec<(f64, f64)>) -> Line {
        self.errors = bars;
        self
    }
    /// A shaded band `(x, lo, hi)` drawn under the curve.
    pub fn band(mut self, band: Vec<(f64, f64, f64)>) -> Line {
        self.band = band;
        self
    }
}

#[cfg_attr(not(feature = "plot"), allow(dead_code))]
/// A line chart with optional logarithmic, integer or categorical axes;
/// with more than [`MAX_SERIES`] curves, or with [`Line::panel`] names, a
/// grid of small multiples sharing their axes (or each with its own y axis,
/// [`LinePlot::own_y`]).
#[derive(Clone, Debug)]
pub struct LinePlot {
    title: String,
    x_label: String,
    y_label: String,
    lines: Vec<Line>,
    log_x: bool,
    log_y: bool,
    integer_x: bool,
    integer_y: bool,
    categories: Option<Vec<String>>,
    y_range: Option<(f64, f64)>,
    size: Option<(u32, u32)>,
    own_y: bool,
    columns: Option<usize>,
    panel_y_labels: Vec<String>,
}

/// One panel of a laid-out chart.
#[derive(Clone, Debug, PartialEq)]
pub struct Panel {
    /// Panel title (empty for a single-panel chart).
    pub title: String,
    /// Indices of its lines in the chart.
    pub lines: Vec<usize>,
    /// Its plotted y range (the chart's unless [`LinePlot::own_y`]).
    pub y_range: (f64, f64),
    /// Its y ticks (plotted coordinates).
    pub y_ticks: Vec<f64>,
}

/// Where everything of a [`LinePlot`] goes, in plotted coordinates
/// (`log10` of the value on a log axis).
#[derive(Clone, Debug)]
pub struct Layout {
    /// Plotted x range.
    pub x_range: (f64, f64),
    /// Plotted y range (of the whole chart).
    pub y_range: (f64, f64),
    /// x ticks (plotted coordinates).
    pub x_ticks: Vec<f64>,
    /// y ticks (plotted coordinates).
    pub y_ticks: Vec<f64>,
    /// Panels, in reading order.
    pub panels: Vec<Panel>,
    /// Style index of every line (see [`series_style`]).
    pub style: Vec<usize>,
    /// Legend entries `(label, style index, markers drawn)`, no repeats.
    pub legend: Vec<(String, usize, bool)>,
}

/// The extent `(x0, x1, y0, y1)` of some points (plotted coordinates).
type Extent = (f64, f64, f64, f64);

fn extent_of(pts: &[(f64, f64)]) -> Option<Extent> {
    if pts.is_empty() {
        return None;
    }
    Some(pts.iter().fold(
        (f64::MAX, f64::MIN, f64::MAX, f64::MIN),
        |(a, b, c, d), &(x, y)| (a.min(x), b.max(x), c.min(y), d.max(y)),
    ))
}

/// Ticks over `[lo, hi]` (plotted coordinates) on a log, integer or linear
/// axis; a degenerate range is widened first.
fn axis_ticks(lo: f64, hi: f64, log: bool, integer: bool) -> Vec<f64> {
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

/// `[lo, hi]` widened to hold the ticks `t`, plus a 4% margin.
fn pad(lo: f64, hi: f64, t: &[f64]) -> (f64, f64) {
    let lo = t.iter().copied().fold(lo, f64::min);
    let hi = t.iter().copied().fold(hi, f64::max);
    let m = if hi > lo { 0.04 * (hi - lo) } else { 0.5 };
    (lo - m, hi + m)
}

/// Refuse a range f64 cannot subdivide into ticks (it would loop).
fn check_extent((x0, x1, y0, y1): Extent) -> Result<()> {
    for (name, lo, hi) in [("plot.x", x0, x1), ("plot.y", y0, y1)] {
        if lo.abs() > 1e300 || hi.abs() > 1e300 || !(hi - lo).is_finite() {
            return Err(Error::invalid(
                name,
                format!("[{lo:e}, {hi:e}]"),
                "a data range within +-1e300",
            ));
        }
    }
    Ok(())
}

/// Panels, line styles and legend entries of a chart.
struct Grouping {
    panels: Vec<(String, Vec<usize>)>,
    style: Vec<usize>,
    legend: Vec<(String, usize, bool)>,
}

impl LinePlot {
    /// A new, empty chart.
    pub fn new(
        title: impl Into<String>,
        x_label: impl Into<String>,
        y_label: impl Into<String>,
    ) -> LinePlot {
        LinePlot {
            title: title.into(),
            x_label: x_label.into(),
            y_label: y_label.into(),
            lines: Vec::new(),
            log_x: false,
            log_y: false,
            integer_x: false,
            integer_y: false,
            categories: None,
            y_range: None,
            size: None,
            own_y: false,
            columns: None,
            panel_y_labels: Vec::new(),
        }
    }
    /// Add a curve.
    pub fn line(mut self, line: Line) -> LinePlot {
        self.lines.push(line);
        self
    }
    /// Logarithmic x axis (non-positive x are skipped).
    pub fn log_x(mut self, on: bool) -> LinePlot {
        self.log_x = on;
        self
    }
    /// Logarithmic y axis (non-positive y are skipped).
    pub fn log_y(mut self, on: bool) -> LinePlot {
        self.log_y = on;
        self
    }
    /// The x values are integers (positions, counts): integer ticks only.
    pub fn integer_x(mut self, on: bool) -> LinePlot {
        self.integer_x = on;
        self
    }
    /// The y values are integers: integer ticks only.
    pub fn integer_y(mut self, on: bool) -> LinePlot {
        self.integer_y = on;
        self
    }
    /// A categorical x axis: the x of a point is the index of its category
    /// in `names`; ticks at the categories only, points side by side, no
    /// joining lines.
    pub fn categories(mut self, names: Vec<String>) -> LinePlot {
        self.categories = Some(names);
        self
    }
    /// A fixed y range (data units), ticks inside it.
    pub fn y_range(mut self, lo: f64, hi: f64) -> LinePlot {
        self.y_range = Some((lo, hi));
        self
    }
    /// A rate or fraction: the y axis is `[0, 1]`.
    pub fn rate(self) -> LinePlot {
        self.y_range(0.0, 1.0)
    }
    /// Picture size in pixels (default: 900 x 560 for one panel, 330 x 250
    /// per panel for small multiples, plus the legend).
    pub fn size(mut self, w: u32, h: u32) -> LinePlot {
        self.size = Some((w, h));
        self
    }
    /// Every panel gets its own y range and ticks (the x axis stays shared),
    /// for panels of different quantities, such as a fit and its residual.
    pub fn own_y(mut self, on: bool) -> LinePlot {
        self.own_y = on;
        self
    }
    /// Panels per row (default: by the number of panels).
    pub fn columns(mut self, c: usize) -> LinePlot {
        self.columns = Some(c.max(1));
        self
    }
    /// The y-axis label of each panel in order (default: the chart's).
    pub fn panel_y_labels(mut self, labels: Vec<String>) -> LinePlot {
        self.panel_y_labels = labels;
        self
    }

    fn keep(&self, &(x, y): &(f64, f64)) -> bool {
        x.is_finite() && y.is_finite() && (!self.log_x || x > 0.0) && (!self.log_y || y > 0.0)
    }

    fn tf(v: f64, log: bool) -> f64 {
        if log {
            v.log10()
        } else {
            v
        }
    }

    /// The kept points of line `i`, in plotted coordinates.
    fn plotted(&self, i: usize) -> Vec<(f64, f64)> {
        self.lines[i]
            .points
            .iter()
            .filter(|p| self.keep(p))
            .map(|&(x, y)| (Self::tf(x, self.log_x), Self::tf(y, self.log_y)))
            .collect()
    }

    /// The kept error bars of line `i`: `(x, lo, hi)` in plotted coordinates.
    fn plotted_errors(&self, i: usize) -> Vec<(f64, f64, f64)> {
        let l = &self.lines[i];
        l.points
            .iter()
            .zip(&l.errors)
            .filter(|(p, &(lo, hi))| self.keep(p) && self.keep(&(p.0, lo)) && self.keep(&(p.0, hi)))
            .map(|(&(x, _), &(lo, hi))| {
                let ty = |v| Self::tf(v, self.log_y);
                (Self::tf(x, self.log_x), ty(lo), ty(hi))
            })
            .collect()
    }

    /// The kept band of line `i`: `(x, lo, hi)` in plotted coordinates.
    fn plotted_band(&self, i: usize) -> Vec<(f64, f64, f64)> {
        self.lines[i]
            .band
            .iter()
            .filter(|&&(x, lo, hi)| self.keep(&(x, lo)) && self.keep(&(x, hi)))
            .map(|&(x, lo, hi)| {
                let ty = |v| Self::tf(v, self.log_y);
                (Self::tf(x, self.log_x), ty(lo), ty(hi))
            })
            .collect()
    }

    /// Everything of lines `ids` that takes room: points, bars, bands.
    fn extent(&self, ids: &[usize]) -> Option<Extent> {
        let mut pts: Vec<(f64, f64)> = Vec::new();
        for &i in ids {
            pts.extend(self.plotted(i));
            for (x, lo, hi) in self
                .plotted_errors(i)
                .into_iter()
                .chain(self.plotted_band(i))
            {
                pts.extend([(x, lo), (x, hi)]);
            }
        }
        extent_of(&pts)
    }

    /// The plotted x range and its ticks.
    fn x_axis(&self, x0: f64, x1: f64) -> ((f64, f64), Vec<f64>) {
        let (range, ticks) = match &self.categories {
            Some(names) => {
                let n = names.len().max(1) as f64;
                (
                    ((-0.5f64).min(x0 - 0.5), (n - 0.5).max(x1 + 0.5)),
                    (0..names.len()).map(|i| i as f64).collect(),
                )
            }
            None => {
                let t = axis_ticks(x0, x1, self.log_x, self.integer_x);
                // ticks within the data only: the axis ends at the data
                let t: Vec<f64> = if self.log_x || x1 <= x0 {
                    t
                } else {
                    let tol = 1e-9 * (x1 - x0);
                    t.into_iter()
                        .filter(|&v| v >= x0 - tol && v <= x1 + tol)
                        .collect()
                };
                (pad(x0, x1, &[]), t)
            }
        };
        let ticks = ticks
            .into_iter()
            .filter(|v| *v >= range.0 && *v <= range.1)
            .collect();
        (range, ticks)
    }

    /// The plotted y range over the data `[y0, y1]` and its ticks.
    fn y_axis(&self, y0: f64, y1: f64) -> ((f64, f64), Vec<f64>) {
        if let Some((lo, hi)) = self.y_range {
            let (lo, hi) = (Self::tf(lo, self.log_y), Self::tf(hi, self.log_y));
            let t = axis_ticks(lo, hi, self.log_y, self.integer_y);
            return (pad(lo.min(y0), hi.max(y1), &[]), t);
        }
        // loose ticks: the axis reaches the next tick beyond the data
        let (a, b) = if self.log_y || y1 <= y0 {
            (y0, y1)
        } else {
            let step = nice_step(y1 - y0, 6);
            let step = if self.integer_y { step.max(1.0) } else { step };
            (
                (y0 / step - 1e-9).floor() * step,
                (y1 / step + 1e-9).ceil() * step,
            )
        };
        let w = if y1 > y0 { y1 - y0 } else { 1.0 };
        let t: Vec<f64> = axis_ticks(a, b, self.log_y, self.integer_y)
            .into_iter()
            .filter(|&v| v >= y0 - 0.3 * w && v <= y1 + 0.3 * w)
            .collect();
        (pad(y0, y1, &t), t)
    }

    /// Whether line `i` is drawn with markers.
    fn draws_markers(&self, i: usize) -> bool {
        let l = &self.lines[i];
        l.markers || self.categories.is_some() || l.points.len() <= 25
    }

    /// Panels by [`Line::panel`] name; a label keeps its style everywhere.
    fn group_named(&self) -> Grouping {
        let mut g = Grouping {
            panels: Vec::new(),
            style: vec![0; self.lines.len()],
            legend: Vec::new(),
        };
        let mut labels: Vec<String> = Vec::new();
        for (i, l) in self.lines.iter().enumerate() {
            let name = l.panel.clone().unwrap_or_default();
            match g.panels.iter_mut().find(|p| p.0 == name) {
                Some(p) => p.1.push(i),
                None => g.panels.push((name, vec![i])),
            }
            let s = labels
                .iter()
                .position(|x| *x == l.label)
                .unwrap_or_else(|| {
                    labels.push(l.label.clone());
                    labels.len() - 1
                });
            g.style[i] = s;
            if !l.label.is_empty() && !g.legend.iter().any(|e| e.0 == l.label) {
                g.legend.push((l.label.clone(), s, self.draws_markers(i)));
            }
        }
        g
    }

    /// Panels and styles: by name, one per curve beyond [`MAX_SERIES`]
    /// (colours only, always solid, no legend), or one panel with a legend.
    fn grouping(&self) -> Grouping {
        if self.lines.iter().any(|l| l.panel.is_some()) {
            return self.group_named();
        }
        let n = self.lines.len();
        if n > MAX_SERIES {
            let panels = self
                .lines
                .iter()
                .enumerate()
                .map(|(i, l)| match l.label.as_str() {
                    "" => (format!("series {}", i + 1), vec![i]),
                    s => (s.to_string(), vec![i]),
                })
                .collect();
            let style = (0..n).map(|i| i % PALETTE.len()).collect();
            return Grouping {
                panels,
                style,
                legend: Vec::new(),
            };
        }
        let legend = (0..n)
            .filter(|&i| !self.lines[i].label.is_empty())
            .map(|i| (self.lines[i].label.clone(), i, self.draws_markers(i)))
            .collect();
        Grouping {
            panels: vec![(String::new(), (0..n).collect())],
            style: (0..n).collect(),
            legend,
        }
    }

    /// Ranges, ticks, panels and styles of the chart (what
    /// [`LinePlot::to_svg_string`] draws).
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] when no curve has a plottable point.
    pub fn layout(&self) -> Result<Layout> {
        let all: Vec<usize> = (0..self.lines.len()).collect();
        let has_points = all.iter().any(|&i| !self.plotted(i).is_empty());
        let ext = self.extent(&all).filter(|_| has_points).ok_or_else(|| {
            Error::invalid(
                "plot.points",
                "none",
                "at least one finite point (positive on log axes)",
            )
        })?;
        check_extent(ext)?;
        let (x0, x1, y0, y1) = ext;
        let (x_range, x_ticks) = self.x_axis(x0, x1);
        let (y_range, y_ticks) = self.y_axis(y0, y1);
        let g = self.grouping();
        let panels = g
            .panels
            .into_iter()
            .map(|(title, lines)| {
                let (yr, yt) = match self.extent(&lines) {
                    Some((_, _, a, b)) if self.own_y => self.y_axis(a, b),
                    _ => (y_range, y_ticks.clone()),
                };
                Panel {
                    title,
                    lines,
                    y_range: yr,
                    y_ticks: yt,
                }
            })
            .collect();
        Ok(Layout {
            x_range,
            y_range,
            x_ticks,
            y_ticks,
            panels,
            style: g.style,
            legend: g.legend,
        })
    }

    /// Render to an SVG string.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] when no curve has a plottable point, or
    /// (field `plot`) when the crate is built without the `plot` feature.
    pub fn to_svg_string(&self) -> Result<String> {
        let layout = self.layout()?;
        #[cfg(feature = "plot")]
        {
            render::line_plot(self, &layout)
        }
        #[cfg(not(feature = "plot"))]
        {
            let _ = layout;
            Err(unavailable())
        }
    }

    /// Write the SVG file atomically.
    ///
    /// # Errors
    /// As [`LinePlot::to_svg_string`]; [`Error::Io`] when the file cannot be
    /// written.
    pub fn write_svg(&self, path: impl AsRef<Path>) -> Result<()> {
        write_atomic(path.as_ref(), self.to_svg_string()?.as_bytes())
    }
}

/// A heatmap of `z[iy][ix]` over the grid `x[ix]`, `y[iy]` (cell centres),
/// with a colour bar; `log_z` colours by `log10 z` (non-positive cells grey).
/// An axis whose centres are all integers (positions) gets integer ticks.
#[derive(Clone, Debug)]
pub struct Heatmap {
    /// Title.
    pub title: String,
    /// x-axis label.
    pub x_label: String,
    /// y-axis label.
    pub y_label: String,
    /// Cell centres along x (increasing).
    pub x: Vec<f64>,
    /// Cell centres along y (increasing).
    pub y: Vec<f64>,
    /// Values, `z[iy][ix]`; non-finite cells are grey.
    pub z: Vec<Vec<f64>>,
    /// Colour by `log10 z`.
    pub log_z: bool,
    /// Optional marker (for example the truth or the minimum).
    pub mark: Option<(f64, f64)>,
}

impl Heatmap {
    /// Render to an SVG string.
    ///
    /// # Errors
    /// Empty grid or `z` shape not `y.len() x x.len()`; (field `plot`) a
    /// build without the `plot` feature.
    pub fn to_svg_string(&self) -> Result<String> {
        let (nx, ny) = (self.x.len(), self.y.len());
        if nx == 0 || ny == 0 || self.z.len() != ny || self.z.iter().any(|r| r.len() != nx) {
            return Err(Error::invalid(
                "heatmap.z",
                format!("{} rows", self.z.len()),
                format!("{ny} rows of {nx} values"),
            ));
        }
        #[cfg(feature = "plot")]
        {
            render::heatmap(self)
        }
        #[cfg(not(feature = "plot"))]
        {
            Err(unavailable())
        }
    }

    /// Write the SVG file atomically.
    ///
    /// # Errors
    /// As [`Heatmap::to_svg_string`]; [`Error::Io`] when the file cannot be
    /// written.
    pub fn write_svg(&self, path: impl AsRef<Path>) -> Result<()> {
        write_atomic(path.as_ref(), self.to_svg_string()?.as_bytes())
    }
}

/// Ticks for an axis of cell centres: integers when every centre is one.
#[cfg_attr(not(feature = "plot"), allow(dead_code))]
fn grid_ticks(c: &[f64], lo: f64, hi: f64) -> Vec<f64> {
    let t = if c.iter().all(|v| v.fract() == 0.0) {
        integer_ticks(lo, hi, 8)
    } else {
        linear_ticks(lo, hi, 6)
    };
    t.into_iter().filter(|v| *v >= lo && *v <= hi).collect()
}

#[cfg(not(feature = "plot"))]
fn unavailable() -> Error {
    Error::invalid(
        "plot",
        "svg",
        "a build with the `plot` feature (plots are not compiled in)",
    )
}

/// A five-stop approximation of the viridis colour map, `u` in [0, 1].
#[cfg_attr(not(feature = "plot"), allow(dead_code))]
fn viridis(u: f64) -> (u8, u8, u8) {
    const STOPS: [(f64, f64, f64); 5] = [
        (68.0, 1.0, 84.0),
        (59.0, 82.0, 139.0),
        (33.0, 145.0, 140.0),
        (94.0, 201.0, 98.0),
        (253.0, 231.0, 37.0),
    ];
    let u = if u.is_finite() {
        u.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let x = u * 4.0;
    let i = (x.floor() as usize).min(3);
    let f = x - i as f64;
    let (a, b) = (STOPS[i], STOPS[i + 1]);
    let m = |p: f64, q: f64| (p + (q - p) * f).round() as u8;
    (m(a.0, b.0), m(a.1, b.1), m(a.2, b.2))
}

#[cfg(feature = "plot")]
mod render {
    //! The plotters side: only drawing, every decision is in [`super::Layout`].

    use super::*;
    use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint};
    use plotters::element::DashedPathElement;
    use plotters::prelude::*;
    use std::sync::Once;

    static FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");
    static REGISTER: Once = Once::new();

    fn ensure_font() {
        REGISTER.call_once(|| {
            // The bundled font is valid; a failure here would only lose text.
            let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT);
        });
    }

    fn rgb((r, g, b): (u8, u8, u8)) -> RGBColor {
        RGBColor(r, g, b)
    }

    fn plot_err<E: std::fmt::Debug>(e: E) -> Error {
        Error::Numerical {
            method: "plot".into(),
            reason: format!("{e:?}"),
        }
    }

    /// A linear axis over `[lo, hi]` whose ticks are exactly `ticks` (bold
    /// grid lines and labels there, no light lines).
    #[derive(Clone, Debug)]
    struct Axis {
        lo: f64,
        hi: f64,
        ticks: Vec<f64>,
    }

    impl Axis {
        fn new(lo: f64, hi: f64, ticks: Vec<f64>) -> Axis {
            Axis { lo, hi, ticks }
        }
    }

    impl Ranged for Axis {
        type FormatOption = DefaultFormatting;
        type ValueType = f64;
        fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
            let u = (value - self.lo) / (self.hi - self.lo);
            let px = limit.0 as f64 + u * (limit.1 - limit.0) as f64;
            px.round().clamp(-1e7, 1e7) as i32
        }
        fn key_points<Hint: KeyPointHint>(&self, hint: Hint) -> Vec<f64> {
            if hint.weight().allow_light_points() {
                Vec::new()
            } else {
                self.ticks.clone()
            }
        }
        fn range(&self) -> std::ops::Range<f64> {
            self.lo..self.hi
        }
    }

    type Chart<'a, 'b> = ChartContext<'a, SVGBackend<'b>, Cartesian2d<Axis, Axis>>;

    fn draw_markers(
        chart: &mut Chart<'_, '_>,
        pts: &[(f64, f64)],
        marker: Marker,
        color: RGBColor,
    ) -> Result<()> {
        let s = color.filled();
        match marker {
            Marker::Circle => chart
                .draw_series(pts.iter().map(|&p| Circle::new(p, 4, s)))
                .map(|_| ()),
            Marker::Square => chart
                .draw_series(
                    pts.iter()
                        .map(|&p| EmptyElement::at(p) + Rectangle::new([(-3, -3), (4, 4)], s)),
                )
                .map(|_| ()),
            Marker::Triangle => chart
                .draw_series(pts.iter().map(|&p| TriangleMarker::new(p, 5, s)))
                .map(|_| ()),
            Marker::Cross => chart
                .draw_series(pts.iter().map(|&p| Cross::new(p, 4, color.stroke_width(2))))
                .map(|_| ()),
        }
        .map_err(plot_err)
    }

    fn draw_path(
        chart: &mut Chart<'_, '_>,
        pts: Vec<(f64, f64)>,
        dash: Dash,
        color: RGBColor,
    ) -> Result<()> {
        let style = color.stroke_width(2);
        match dash {
            Dash::Solid => chart.draw_series(LineSeries::new(pts, style)).map(|_| ()),
            Dash::Dashed => chart
                .draw_series(DashedLineSeries::new(pts, 8, 5, style))
                .map(|_| ()),
            Dash::Dotted => chart
                .draw_series(DashedLineSeries::new(pts, 2, 4, style))
                .map(|_| ()),
        }
        .map_err(plot_err)
    }

    /// Panels per row and rows for `n` panels (or `columns` per row).
    fn grid_shape(n: usize, columns: Option<usize>) -> (usize, usize) {
        let cols = columns.unwrap_or(match n {
            0 | 1 => 1,
            2 | 3 => n,
            4 => 2,
            5 | 6 | 9 => 3,
            _ => 4,
        });
        let cols = cols.clamp(1, n.max(1));
        (cols, n.max(1).div_ceil(cols))
    }

    const LEGEND_FONT: (&str, u32) = ("sans-serif", 13);

    /// Width of the legend column from the text extents (0 without one).
    fn legend_width(l: &Layout) -> u32 {
        if l.legend.is_empty() {
            return 0;
        }
        let mut scratch = String::new();
        let probe = SVGBackend::with_string(&mut scratch, (10, 10)).into_drawing_area();
        let style = LEGEND_FONT.into_text_style(&probe);
        let text_w = l
            .legend
            .iter()
            .map(|e| {
                probe
                    .estimate_text_size(&e.0, &style)
                    .map(|s| s.0)
                    .unwrap_or(8 * e.0.len() as u32)
            })
            .max()
            .unwrap_or(0);
        (text_w + 62).clamp(110, 360)
    }

    /// Tick labels of an axis: category names, log labels or plain numbers.
    struct Labels<'a> {
        ticks: &'a [f64],
        log: Vec<String>,
        is_log: bool,
        categories: Option<&'a [String]>,
    }

    impl<'a> Labels<'a> {
        fn new(ticks: &'a [f64], is_log: bool, categories: Option<&'a [String]>) -> Labels<'a> {
            let log = log_tick_labels(&ticks.iter().map(|v| 10f64.powf(*v)).collect::<Vec<_>>());
            Labels {
                ticks,
                log,
                is_log,
                categories,
            }
        }
        fn at(&self, v: f64) -> String {
            if let Some(names) = self.categories {
                let i = v.round();
                let hit = (v - i).abs() < 1e-6 && i >= 0.0 && (i as usize) < names.len();
                return if hit {
                    names[i as usize].clone()
                } else {
                    String::new()
                };
            }
            if self.is_log {
                nearest_label(v, self.ticks, &self.log)
            } else {
                tick_label_step(v, step_of(self.ticks))
            }
        }
        /// Room for the longest label, in pixels.
        fn width(&self) -> u32 {
            let longest = self
                .ticks
                .iter()
                .map(|&v| self.at(v).chars().count() as u32);
            longest.max().unwrap_or(1) * 8 + 14
        }
    }

    pub(super) fn line_plot(p: &LinePlot, l: &Layout) -> Result<String> {
        ensure_font();
        let n = l.panels.len();
        let (cols, rows) = grid_shape(n, p.columns);
        let legend_w = legend_width(l);
        let (w, h) = p.size.unwrap_or(if n <= 1 {
            (900 + legend_w.saturating_sub(150), 560)
        } else {
            (cols as u32 * 330 + legend_w, rows as u32 * 250 + 50)
        });
        let mut buf = String::new();
        {
            let root = SVGBackend::with_string(&mut buf, (w, h)).into_drawing_area();
            root.fill(&WHITE).map_err(plot_err)?;
            let body = root
                .titled(&p.title, ("sans-serif", 20))
                .map_err(plot_err)?;
            let (bw, _) = body.dim_in_pixel();
            let (plots, legend) = body.split_horizontally(bw.saturating_sub(legend_w));
            let cells = plots.split_evenly((rows, cols));
            let x_labels = Labels::new(&l.x_ticks, p.log_x, p.categories.as_deref());
            let y_label_w = l
                .panels
                .iter()
                .map(|pn| Labels::new(&pn.y_ticks, p.log_y, None).width())
                .max()
                .unwrap_or(22);
            for (pi, panel) in l.panels.iter().enumerate() {
                let at = PanelAt {
                    bottom: pi + cols >= n,
                    left: pi % cols == 0 || p.own_y,
                    y_label_w,
                };
                let y_desc = p.panel_y_labels.get(pi).unwrap_or(&p.y_label);
                draw_panel(&cells[pi], p, l, panel, &x_labels, y_desc, at)?;
            }
            draw_legend(&legend, p, l)?;
            root.present().map_err(plot_err)?;
        }
        Ok(buf)
    }

    /// Where a panel sits in the grid: which axis descriptions it carries.
    #[derive(Clone, Copy)]
    struct PanelAt {
        bottom: bool,
        left: bool,
        y_label_w: u32,
    }

    fn draw_panel(
        area: &DrawingArea<SVGBackend<'_>, plotters::coord::Shift>,
        p: &LinePlot,
        l: &Layout,
        panel: &Panel,
        x_labels: &Labels<'_>,
        y_desc: &str,
        at: PanelAt,
    ) -> Result<()> {
        let mut b = ChartBuilder::on(area);
        b.margin(10)
            .margin_right(18)
            .x_label_area_size(if at.bottom { 46 } else { 26 })
            .y_label_area_size(at.y_label_w + if at.left { 22 } else { 0 });
        if !panel.title.is_empty() {
            b.caption(&panel.title, ("sans-serif", 15));
        }
        let mut chart: Chart<'_, '_> = b
            .build_cartesian_2d(
                Axis::new(l.x_range.0, l.x_range.1, l.x_ticks.clone()),
                Axis::new(panel.y_range.0, panel.y_range.1, panel.y_ticks.clone()),
            )
            .map_err(plot_err)?;
        let y_labels = Labels::new(&panel.y_ticks, p.log_y, None);
        let fxr = |v: &f64| x_labels.at(*v);
        let fyr = |v: &f64| y_labels.at(*v);
        let mut mesh = chart.configure_mesh();
        mesh.label_style(("sans-serif", 13))
            .x_label_formatter(&fxr)
            .y_label_formatter(&fyr)
            .bold_line_style(RGBColor(225, 225, 225))
            .light_line_style(TRANSPARENT)
            .axis_desc_style(("sans-serif", 14));
        if at.bottom {
            mesh.x_desc(p.x_label.as_str());
        }
        if at.left {
            mesh.y_desc(y_desc);
        }
        mesh.draw().map_err(plot_err)?;
        for (k, &i) in panel.lines.iter().enumerate() {
            draw_line(&mut chart, p, l, i, (k, panel.lines.len()))?;
        }
        Ok(())
    }

    /// Line `i`, the `k`-th of `m` in its panel: band, path, markers, bars.
    fn draw_line(
        chart: &mut Chart<'_, '_>,
        p: &LinePlot,
        l: &Layout,
        i: usize,
        (k, m): (usize, usize),
    ) -> Result<()> {
        let line = &p.lines[i];
        let (c, dash, marker) = series_style(l.style[i]);
        let color = rgb(c);
        let band = p.plotted_band(i);
        if !band.is_empty() {
            let mut poly: Vec<(f64, f64)> = band.iter().map(|&(x, lo, _)| (x, lo)).collect();
            poly.extend(band.iter().rev().map(|&(x, _, hi)| (x, hi)));
            chart
                .draw_series(std::iter::once(Polygon::new(
                    poly,
                    color.mix(0.18).filled(),
                )))
                .map_err(plot_err)?;
        }
        // side by side within a category, never joined
        let off = if p.categories.is_some() {
            let w = (0.6 / m as f64).min(0.12);
            (k as f64 - (m as f64 - 1.0) / 2.0) * w
        } else {
            0.0
        };
        let pts: Vec<(f64, f64)> = p.plotted(i).into_iter().map(|q| (q.0 + off, q.1)).collect();
        let bars: Vec<(f64, f64, f64)> = p
            .plotted_errors(i)
            .into_iter()
            .map(|(x, lo, hi)| (x + off, lo, hi))
            .collect();
        if !bars.is_empty() {
            chart
                .draw_series(bars.iter().map(|&(x, lo, hi)| {
                    PathElement::new(vec![(x, lo), (x, hi)], color.stroke_width(2))
                }))
                .map_err(plot_err)?;
        }
        if p.categories.is_none() && !line.markers {
            let dash = if line.dashed && dash == Dash::Solid {
                Dash::Dashed
            } else {
                dash
            };
            draw_path(chart, pts.clone(), dash, color)?;
        }
        if p.categories.is_some() || line.markers || line.points.len() <= 25 {
            draw_markers(chart, &pts, marker, color)?;
        }
        Ok(())
    }

    /// The legend, outside the data: a column on the right.
    fn draw_legend(
        area: &DrawingArea<SVGBackend<'_>, plotters::coord::Shift>,
        p: &LinePlot,
        l: &Layout,
    ) -> Result<()> {
        for (k, (label, s, markers)) in l.legend.iter().enumerate() {
            let (c, dash, marker) = series_style(*s);
            let line = p.lines.iter().find(|x| x.label == *label);
            let only_markers = line.is_some_and(|x| x.markers) || p.categories.is_some();
            let dash = if line.is_some_and(|x| x.dashed) && dash == Dash::Solid {
                Dash::Dashed
            } else {
                dash
            };
            let color = rgb(c);
            let y = 40 + 24 * k as i32;
            let (x0, x1) = (10, 42);
            if !only_markers {
                draw_legend_path(area, (x0, x1, y), dash, color)?;
            }
            if *markers {
                draw_legend_marker(area, ((x0 + x1) / 2, y), marker, color)?;
            }
            area.draw(&Text::new(
                label.clone(),
                (x1 + 10, y - 6),
                LEGEND_FONT.into_font(),
            ))
            .map_err(plot_err)?;
        }
        Ok(())
    }

    fn draw_legend_path(
        area: &DrawingArea<SVGBackend<'_>, plotters::coord::Shift>,
        (x0, x1, y): (i32, i32, i32),
        dash: Dash,
        color: RGBColor,
    ) -> Result<()> {
        let style = color.stroke_width(2);
        let path = vec![(x0, y), (x1, y)];
        match dash {
            Dash::Solid => area.draw(&PathElement::new(path, style)),
            Dash::Dashed => area.draw(&DashedPathElement::new(path, 8, 5, style)),
            Dash::Dotted => area.draw(&DashedPathElement::new(path, 2, 4, style)),
        }
        .map_err(plot_err)
    }

    fn draw_legend_marker(
        area: &DrawingArea<SVGBackend<'_>, plotters::coord::Shift>,
        m: (i32, i32),
        marker: Marker,
        color: RGBColor,
    ) -> Result<()> {
        let s = color.filled();
        match marker {
            Marker::Circle => area.draw(&Circle::new(m, 4, s)),
            Marker::Square => {
                area.draw(&Rectangle::new([(m.0 - 3, m.1 - 3), (m.0 + 4, m.1 + 4)], s))
            }
            Marker::Triangle => area.draw(&TriangleMarker::new(m, 5, s)),
            Marker::Cross => area.draw(&Cross::new(m, 4, color.stroke_width(2))),
        }
        .map_err(plot_err)
    }

    /// The spacing of evenly spaced ticks (1 for fewer than two).
    fn step_of(t: &[f64]) -> f64 {
        if t.len() >= 2 {
            (t[1] - t[0]).abs()
        } else {
            1.0
        }
    }

    /// The colour scale of a heatmap: `z` in plotted units (`log10 z` on a
    /// log scale; `None` for a grey cell) and its range.
    fn heat_scale(h: &Heatmap) -> (impl Fn(f64) -> Option<f64> + '_, f64, f64) {
        let tf = move |v: f64| -> Option<f64> {
            if !v.is_finite() || (h.log_z && v <= 0.0) {
                None
            } else if h.log_z {
                Some(v.log10())
            } else {
                Some(v)
            }
        };
        let vals: Vec<f64> = h.z.iter().flatten().filter_map(|&v| tf(v)).collect();
        let (lo, hi) = vals
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), &v| (a.min(v), b.max(v)));
        let (lo, hi) = if vals.is_empty() {
            (0.0, 1.0)
        } else if hi > lo {
            (lo, hi)
        } else {
            (lo - 0.5, hi + 0.5)
        };
        (tf, lo, hi)
    }

    /// Cell edges around the centres `c`.
    fn cell_edges(c: &[f64]) -> Vec<f64> {
        let n = c.len();
        if n == 1 {
            return vec![c[0] - 0.5, c[0] + 0.5];
        }
        let mut e = Vec::with_capacity(n + 1);
        e.push(c[0] - 0.5 * (c[1] - c[0]));
        for i in 0..n - 1 {
            e.push(0.5 * (c[i] + c[i + 1]));
        }
        e.push(c[n - 1] + 0.5 * (c[n - 1] - c[n - 2]));
        e
    }

    /// Ticks of the colour bar over `[lo, hi]` (plotted units).
    fn bar_ticks(h: &Heatmap, lo: f64, hi: f64) -> Vec<f64> {
        if h.log_z {
            log_ticks(10f64.powf(lo), 10f64.powf(hi))
                .into_iter()
                .map(f64::log10)
                .collect()
        } else {
            linear_ticks(lo, hi, 6)
        }
    }

    pub(super) fn heatmap(h: &Heatmap) -> Result<String> {
        ensure_font();
        let (nx, ny) = (h.x.len(), h.y.len());
        let (tf, lo, hi) = heat_scale(h);
        let (ex, ey) = (cell_edges(&h.x), cell_edges(&h.y));
        let xt = grid_ticks(&h.x, ex[0], ex[nx]);
        let yt = grid_ticks(&h.y, ey[0], ey[ny]);
        let (sx, sy) = (step_of(&xt), step_of(&yt));
        let mut buf = String::new();
        {
            let root = SVGBackend::with_string(&mut buf, (900, 640)).into_drawing_area();
            root.fill(&WHITE).map_err(plot_err)?;
            let (main, bar) = root.split_horizontally(790);
            let mut chart = ChartBuilder::on(&main)
                .caption(&h.title, ("sans-serif", 20))
                .margin(12)
                .x_label_area_size(45)
                .y_label_area_size(70)
                .build_cartesian_2d(Axis::new(ex[0], ex[nx], xt), Axis::new(ey[0], ey[ny], yt))
                .map_err(plot_err)?;
            chart
                .configure_mesh()
                .disable_mesh()
                .x_desc(h.x_label.as_str())
                .y_desc(h.y_label.as_str())
                .label_style(("sans-serif", 13))
                .x_label_formatter(&|v: &f64| tick_label_step(*v, sx))
                .y_label_formatter(&|v: &f64| tick_label_step(*v, sy))
                .draw()
                .map_err(plot_err)?;
            let cells = (0..ny).flat_map(|iy| (0..nx).map(move |ix| (ix, iy)));
            chart
                .draw_series(cells.map(|(ix, iy)| {
                    let color = match tf(h.z[iy][ix]) {
                        Some(v) => rgb(viridis((v - lo) / (hi - lo))),
                        None => RGBColor(190, 190, 190),
                    };
                    Rectangle::new([(ex[ix], ey[iy]), (ex[ix + 1], ey[iy + 1])], color.filled())
                }))
                .map_err(plot_err)?;
            if let Some(m) = h.mark {
                chart
                    .draw_series(std::iter::once(Cross::new(m, 8, RED.stroke_width(3))))
                    .map_err(plot_err)?;
            }
            colour_bar(&bar, h, lo, hi)?;
            root.present().map_err(plot_err)?;
        }
        Ok(buf)
    }

    /// The colour bar of a heatmap over `[lo, hi]`, labelled in data units.
    fn colour_bar(
        area: &DrawingArea<SVGBackend<'_>, plotters::coord::Shift>,
        h: &Heatmap,
        lo: f64,
        hi: f64,
    ) -> Result<()> {
        let zt = bar_ticks(h, lo, hi);
        let sz = step_of(&zt);
        let zl = log_tick_labels(&zt.iter().map(|v| 10f64.powf(*v)).collect::<Vec<_>>());
        let mut cb = ChartBuilder::on(area)
            .margin_top(50)
            .margin_bottom(57)
            .margin_right(8)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..1.0, Axis::new(lo, hi, zt.clone()))
            .map_err(plot_err)?;
        cb.configure_mesh()
            .disable_mesh()
            .disable_x_axis()
            .label_style(("sans-serif", 12))
            .y_label_formatter(&|v: &f64| {
                if h.log_z {
                    nearest_label(*v, &zt, &zl)
                } else {
                    tick_label_step(*v, sz)
                }
            })
            .draw()
            .map_err(plot_err)?;
        let steps = 100;
        cb.draw_series((0..steps).map(|i| {
            let a = lo + (hi - lo) * i as f64 / steps as f64;
            let b = lo + (hi - lo) * (i + 1) as f64 / steps as f64;
            Rectangle::new(
                [(0.0, a), (1.0, b)],
                rgb(viridis((i as f64 + 0.5) / steps as f64)).filled(),
            )
        }))
        .map_err(plot_err)?;
        Ok(())
    }
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

    #[test]
    fn styles_repeat_no_combination_within_24_series() {
        let mut seen = std::collections::HashSet::new();
        for i in 0..24 {
            let (c, d, m) = series_style(i);
            assert!(seen.insert((c, d as u8, m as u8)), "series {i}");
        }
        // series 0 and 8 share a colour but neither dash nor marker
        let (a, b) = (series_style(0), series_style(8));
        assert_eq!(a.0, b.0);
        assert!(a.1 != b.1 && a.2 != b.2);
    }

    #[test]
    fn layout_panels_rates_and_categories() {
        let line = |i: usize| Line::new(format!("s{i}"), vec![(1.0, i as f64), (2.0, 1.0)]);
        // up to 6 series: one panel with a legend
        let mut p = LinePlot::new("t", "x", "y");
        for i in 0..6 {
            p = p.line(line(i));
        }
        let l = p.clone().layout().unwrap();
        assert_eq!(l.panels.len(), 1);
        assert_eq!(l.legend.len(), 6);
        // 7 series: small multiples, one per series, no legend
        let l = p.line(line(6)).layout().unwrap();
        assert_eq!(l.panels.len(), 7);
        assert!(l.legend.is_empty());
        // named panels: a label keeps its style across panels
        let l = LinePlot::new("t", "x", "y")
            .line(Line::new("a", vec![(1.0, 0.5)]).panel("S1"))
            .line(Line::new("b", vec![(1.0, 0.5)]).panel("S1"))
            .line(Line::new("a", vec![(1.0, 0.5)]).panel("S2"))
            .rate()
            .layout()
            .unwrap();
        assert_eq!(l.panels.len(), 2);
        assert_eq!(l.style, vec![0, 1, 0]);
        assert_eq!(l.legend.len(), 2);
        // a rate axis is [0, 1] with both ends labelled
        assert_eq!(l.y_ticks.first(), Some(&0.0));
        assert_eq!(l.y_ticks.last(), Some(&1.0));
        assert!(l.y_range.0 < 0.0 && l.y_range.1 > 1.0);
        // categories: ticks at the categories only
        let l = LinePlot::new("t", "system", "y")
            .categories(vec!["1".into(), "2".into(), "3".into()])
            .line(Line::new("m", vec![(0.0, 1.0), (1.0, 2.0), (2.0, 3.0)]))
            .layout()
            .unwrap();
        assert_eq!(l.x_ticks, vec![0.0, 1.0, 2.0]);
        // integer x: integer ticks
        let l = LinePlot::new("t", "j", "r")
            .integer_x(true)
            .line(Line::new("", vec![(1.0, 1.0), (3.0, 2.0)]))
            .layout()
            .unwrap();
        assert!(
            l.x_ticks.iter().all(|v| v.fract() == 0.0),
            "{:?}",
            l.x_ticks
        );
        assert!(LinePlot::new("empty", "x", "y").layout().is_err());
    }

    #[cfg(feature = "plot")]
    #[test]
    fn line_plot_renders_text_and_paths() {
        let pts: Vec<(f64, f64)> = (1..200)
            .map(|i| (i as f64 * 0.05, (i as f64 * 0.05).sin()))
            .collect();
        let svg = LinePlot::new("sine", "t", "x")
            .line(Line::new("sin", pts.clone()))
            .line(Line::new("dashed", pts.iter().map(|&(x, y)| (x, 0.5 * y)).collect()).dashed())
            .to_svg_string()
            .unwrap();
        assert!(svg.contains("<svg") && svg.contains("sine") && svg.contains("polyline"));
        assert!(!svg.contains("-0<") && !svg.contains("e-17"));
        assert_eq!(tick_label(1.0000000000004e-6), "1e-6");
        assert_eq!(tick_label(2.5e7), "2.5e7");
        assert_eq!(tick_label(0.25), "0.25");
        assert_eq!(tick_label(300.0), "300");
        assert_eq!(tick_label(-0.001), "-0.001");
        assert_eq!(tick_label(0.0), "0");
        let log = LinePlot::new("log", "s", "r")
            .log_x(true)
            .log_y(true)
            .line(Line::new("", vec![(0.0, 1.0), (1e-3, 1e-9), (10.0, 1e3)]).markers())
            .to_svg_string()
            .unwrap();
        assert!(log.contains("<svg"));
        assert!(LinePlot::new("empty", "x", "y").to_svg_string().is_err());
        // small multiples carry each series' name as a panel caption
        let mut many = LinePlot::new("many", "x", "y");
        for i in 0..9 {
            many = many.line(Line::new(
                format!("series-{i}"),
                vec![(0.0, 0.0), (1.0, i as f64)],
            ));
        }
        let svg = many.to_svg_string().unwrap();
        assert!((0..9).all(|i| svg.contains(&format!("series-{i}"))));
    }

    #[cfg(not(feature = "plot"))]
    #[test]
    fn without_the_feature_plots_are_a_typed_error() {
        let e = LinePlot::new("t", "x", "y")
            .line(Line::new("", vec![(0.0, 1.0)]))
            .to_svg_string()
            .unwrap_err();
        assert!(matches!(e, Error::InvalidParameter { ref field, .. } if field == "plot"));
    }

    #[test]
    fn heatmap_checks_shape_and_renders() {
        let h = Heatmap {
            title: "r(j, m)".into(),
            x_label: "j".into(),
            y_label: "m".into(),
            x: vec![1.0, 2.0, 3.0],
            y: vec![0.5, 1.0],
            z: vec![vec![1e-3, 1e-1, 0.0], vec![1.0, f64::NAN, 10.0]],
            log_z: true,
            mark: Some((2.0, 1.0)),
        };
        #[cfg(feature = "plot")]
        assert!(h.to_svg_string().unwrap().contains("<svg"));
        assert_eq!(grid_ticks(&h.x, 0.5, 3.5), vec![1.0, 2.0, 3.0]);
        let bad = Heatmap {
            z: vec![vec![1.0]],
            ..h
        };
        assert!(bad.to_svg_string().is_err());
    }
}
