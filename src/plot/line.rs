//! Line charts: curves, the chart's options, and its layout (ranges, ticks,
//! panels, styles, legend) decided before anything is drawn.

use super::style::PALETTE;
use super::ticks::{axis_ticks, nice_step};
use super::MAX_SERIES;
use crate::error::{Error, Result};
use crate::series::write_atomic;
use std::path::Path;

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
    pub(super) title: String,
    pub(super) x_label: String,
    pub(super) y_label: String,
    pub(super) lines: Vec<Line>,
    pub(super) log_x: bool,
    pub(super) log_y: bool,
    pub(super) integer_x: bool,
    pub(super) integer_y: bool,
    pub(super) categories: Option<Vec<String>>,
    pub(super) y_range: Option<(f64, f64)>,
    pub(super) size: Option<(u32, u32)>,
    pub(super) own_y: bool,
    pub(super) columns: Option<usize>,
    pub(super) panel_y_labels: Vec<String>,
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
    /// Style index of every line (see [`series_style`](super::series_style)).
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
    pub(super) fn plotted(&self, i: usize) -> Vec<(f64, f64)> {
        self.lines[i]
            .points
            .iter()
            .filter(|p| self.keep(p))
            .map(|&(x, y)| (Self::tf(x, self.log_x), Self::tf(y, self.log_y)))
            .collect()
    }

    /// The kept error bars of line `i`: `(x, lo, hi)` in plotted coordinates.
    pub(super) fn plotted_errors(&self, i: usize) -> Vec<(f64, f64, f64)> {
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
    pub(super) fn plotted_band(&self, i: usize) -> Vec<(f64, f64, f64)> {
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
            super::render::line_plot(self, &layout)
        }
        #[cfg(not(feature = "plot"))]
        {
            let _ = layout;
            Err(super::unavailable())
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

#[cfg(test)]
mod tests {
    use super::*;
    #[cfg(feature = "plot")]
    use crate::plot::tick_label;

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
}
