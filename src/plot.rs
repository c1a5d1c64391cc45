//! SVG plots: line charts and heatmaps, written atomically.
//!
//! Text is laid out with the DejaVu Sans font bundled in `assets/` (registered
//! once with plotters' `ab_glyph` backend), so plots render the same on any
//! machine without system fonts.
//!
//! ```no_run
//! use springmass::plot::{LinePlot, Line};
//! let pts: Vec<(f64, f64)> = (0..100).map(|i| (i as f64 * 0.1, (i as f64 * 0.1).sin())).collect();
//! LinePlot::new("x_1(t)", "t", "x_1")
//!     .line(Line::new("x_1", pts))
//!     .write_svg("x1.svg")?;
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::error::{Error, Result};
use crate::series::write_atomic;
use plotters::prelude::*;
use std::path::Path;
use std::sync::Once;

static FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");
static REGISTER: Once = Once::new();

fn ensure_font() {
    REGISTER.call_once(|| {
        // The bundled font is valid; a failure here would only lose text.
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT);
    });
}

/// Qualitative colour cycle (colour-blind friendly, Okabe-Ito).
const PALETTE: [RGBColor; 8] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
    RGBColor(0, 0, 0),
    RGBColor(240, 228, 66),
];

/// One curve of a [`LinePlot`].
#[derive(Clone, Debug)]
pub struct Line {
    /// Legend label (empty: no legend entry).
    pub label: String,
    /// Points `(x, y)`; non-finite points are skipped.
    pub points: Vec<(f64, f64)>,
    /// Draw markers instead of a line.
    pub markers: bool,
    /// Dashed line.
    pub dashed: bool,
}

impl Line {
    /// A solid line.
    pub fn new(label: impl Into<String>, points: Vec<(f64, f64)>) -> Line {
        Line {
            label: label.into(),
            points,
            markers: false,
            dashed: false,
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
}

/// A short tick label: plain decimals with at most 4 significant digits for
/// `1e-3 <= |v| < 1e5`, otherwise `1e-6`, `2.5e7` (rounding noise such as
/// `1.0000000000004e-6` is removed).
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
    if (1e-3..1e5).contains(&a) {
        let decimals = (3 - a.log10().floor() as i32).clamp(0, 6) as usize;
        trim(format!("{v:.decimals$}"))
    } else {
        let t = format!("{v:.3e}");
        let (mant, exp) = t.split_once('e').unwrap_or((&t, "0"));
        format!("{}e{exp}", trim(mant.to_string()))
    }
}

/// A line chart with optional logarithmic axes.
#[derive(Clone, Debug)]
pub struct LinePlot {
    title: String,
    x_label: String,
    y_label: String,
    lines: Vec<Line>,
    log_x: bool,
    log_y: bool,
    size: (u32, u32),
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
            size: (900, 560),
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
    /// Picture size in pixels.
    pub fn size(mut self, w: u32, h: u32) -> LinePlot {
        self.size = (w, h);
        self
    }

    fn keep(&self, &(x, y): &(f64, f64)) -> bool {
        x.is_finite() && y.is_finite() && (!self.log_x || x > 0.0) && (!self.log_y || y > 0.0)
    }

    /// Render to an SVG string.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] when no curve has a plottable point.
    pub fn to_svg_string(&self) -> Result<String> {
        ensure_font();
        let pts: Vec<(f64, f64)> = self
            .lines
            .iter()
            .flat_map(|l| l.points.iter().copied())
            .filter(|p| self.keep(p))
            .collect();
        if pts.is_empty() {
            return Err(Error::invalid(
                "plot.points",
                "none",
                "at least one finite point (positive on log axes)",
            ));
        }
        let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for &(x, y) in &pts {
            x0 = x0.min(x);
            x1 = x1.max(x);
            y0 = y0.min(y);
            y1 = y1.max(y);
        }
        let pad = |lo: f64, hi: f64, log: bool| -> (f64, f64) {
            if log {
                if hi <= lo {
                    (lo / 2.0, hi * 2.0)
                } else {
                    (lo, hi)
                }
            } else if hi <= lo {
                (lo - 0.5 - lo.abs() * 0.1, hi + 0.5 + hi.abs() * 0.1)
            } else {
                let m = 0.04 * (hi - lo);
                (lo - m, hi + m)
            }
        };
        let (x0, x1) = pad(x0, x1, self.log_x);
        let (y0, y1) = pad(y0, y1, self.log_y);
        let mut buf = String::new();
        {
            let root = SVGBackend::with_string(&mut buf, self.size).into_drawing_area();
            root.fill(&WHITE).map_err(plot_err)?;
            let mut builder = ChartBuilder::on(&root);
            builder
                .caption(&self.title, ("sans-serif", 20))
                .margin(12)
                .x_label_area_size(45)
                .y_label_area_size(80);
            macro_rules! draw {
                ($chart:expr) => {{
                    let mut chart = $chart;
                    chart
                        .configure_mesh()
                        .x_desc(self.x_label.as_str())
                        .y_desc(self.y_label.as_str())
                        .label_style(("sans-serif", 13))
                        .x_label_formatter(&|v: &f64| tick_label(*v))
                        .y_label_formatter(&|v: &f64| tick_label(*v))
                        .light_line_style(RGBColor(235, 235, 235))
                        .draw()
                        .map_err(plot_err)?;
                    let mut any_label = false;
                    for (i, l) in self.lines.iter().enumerate() {
                        let color = PALETTE[i % PALETTE.len()];
                        let data: Vec<(f64, f64)> =
                            l.points.iter().copied().filter(|p| self.keep(p)).collect();
                        let style = color.stroke_width(2);
                        let anno = if l.markers {
                            chart
                                .draw_series(
                                    data.iter().map(|&p| Circle::new(p, 3, color.filled())),
                                )
                                .map_err(plot_err)?
                        } else if l.dashed {
                            chart
                                .draw_series(DashedLineSeries::new(data.clone(), 6, 4, style))
                                .map_err(plot_err)?
                        } else {
                            chart
                                .draw_series(LineSeries::new(data.clone(), style))
                                .map_err(plot_err)?
                        };
                        if !l.label.is_empty() {
                            any_label = true;
                            anno.label(l.label.as_str()).legend(move |(x, y)| {
                                PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
                            });
                        }
                    }
                    if any_label {
                        chart
                            .configure_series_labels()
                            .background_style(WHITE.mix(0.85))
                            .border_style(BLACK)
                            .label_font(("sans-serif", 13))
                            .position(SeriesLabelPosition::UpperRight)
                            .draw()
                            .map_err(plot_err)?;
                    }
                }};
            }
            match (self.log_x, self.log_y) {
                (false, false) => draw!(builder
                    .build_cartesian_2d(x0..x1, y0..y1)
                    .map_err(plot_err)?),
                (true, false) => draw!(builder
                    .build_cartesian_2d((x0..x1).log_scale(), y0..y1)
                    .map_err(plot_err)?),
                (false, true) => draw!(builder
                    .build_cartesian_2d(x0..x1, (y0..y1).log_scale())
                    .map_err(plot_err)?),
                (true, true) => {
                    draw!(builder
                        .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
                        .map_err(plot_err)?)
                }
            }
            root.present().map_err(plot_err)?;
        }
        Ok(buf)
    }

    /// Write the SVG file atomically.
    pub fn write_svg(&self, path: impl AsRef<Path>) -> Result<()> {
        write_atomic(path.as_ref(), self.to_svg_string()?.as_bytes())
    }
}

/// A heatmap of `z[iy][ix]` over the grid `x[ix]`, `y[iy]` (cell centres),
/// with a colour bar; `log_z` colours by `log10 z` (non-positive cells grey).
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
    /// Empty grid or `z` shape not `y.len() x x.len()`.
    pub fn to_svg_string(&self) -> Result<String> {
        ensure_font();
        let (nx, ny) = (self.x.len(), self.y.len());
        if nx == 0 || ny == 0 || self.z.len() != ny || self.z.iter().any(|r| r.len() != nx) {
            return Err(Error::invalid(
                "heatmap.z",
                format!("{} rows", self.z.len()),
                format!("{ny} rows of {nx} values"),
            ));
        }
        let tf = |v: f64| -> Option<f64> {
            if !v.is_finite() || (self.log_z && v <= 0.0) {
                None
            } else if self.log_z {
                Some(v.log10())
            } else {
                Some(v)
            }
        };
        let vals: Vec<f64> = self.z.iter().flatten().filter_map(|&v| tf(v)).collect();
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
        let edges = |c: &[f64]| -> Vec<f64> {
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
        };
        let (ex, ey) = (edges(&self.x), edges(&self.y));
        let mut buf = String::new();
        {
            let root = SVGBackend::with_string(&mut buf, (900, 640)).into_drawing_area();
            root.fill(&WHITE).map_err(plot_err)?;
            let (main, bar) = root.split_horizontally(790);
            let mut chart = ChartBuilder::on(&main)
                .caption(&self.title, ("sans-serif", 20))
                .margin(12)
                .x_label_area_size(45)
                .y_label_area_size(70)
                .build_cartesian_2d(ex[0]..ex[nx], ey[0]..ey[ny])
                .map_err(plot_err)?;
            chart
                .configure_mesh()
                .disable_mesh()
                .x_desc(self.x_label.as_str())
                .y_desc(self.y_label.as_str())
                .label_style(("sans-serif", 13))
                .draw()
                .map_err(plot_err)?;
            let cells = (0..ny).flat_map(|iy| (0..nx).map(move |ix| (ix, iy)));
            chart
                .draw_series(cells.map(|(ix, iy)| {
                    let color = match tf(self.z[iy][ix]) {
                        Some(v) => viridis((v - lo) / (hi - lo)),
                        None => RGBColor(190, 190, 190),
                    };
                    Rectangle::new([(ex[ix], ey[iy]), (ex[ix + 1], ey[iy + 1])], color.filled())
                }))
                .map_err(plot_err)?;
            if let Some(m) = self.mark {
                chart
                    .draw_series(std::iter::once(Cross::new(m, 8, RED.stroke_width(3))))
                    .map_err(plot_err)?;
            }
            // colour bar
            let mut cb = ChartBuilder::on(&bar)
                .margin_top(50)
                .margin_bottom(57)
                .margin_right(8)
                .y_label_area_size(60)
                .build_cartesian_2d(0.0..1.0, lo..hi)
                .map_err(plot_err)?;
            cb.configure_mesh()
                .disable_mesh()
                .disable_x_axis()
                .y_desc(if self.log_z { "log10" } else { "" })
                .label_style(("sans-serif", 12))
                .draw()
                .map_err(plot_err)?;
            let steps = 100;
            cb.draw_series((0..steps).map(|i| {
                let a = lo + (hi - lo) * i as f64 / steps as f64;
                let b = lo + (hi - lo) * (i + 1) as f64 / steps as f64;
                Rectangle::new(
                    [(0.0, a), (1.0, b)],
                    viridis((i as f64 + 0.5) / steps as f64).filled(),
                )
            }))
            .map_err(plot_err)?;
            root.present().map_err(plot_err)?;
        }
        Ok(buf)
    }

    /// Write the SVG file atomically.
    pub fn write_svg(&self, path: impl AsRef<Path>) -> Result<()> {
        write_atomic(path.as_ref(), self.to_svg_string()?.as_bytes())
    }
}

/// A five-stop approximation of the viridis colour map, `u` in [0, 1].
fn viridis(u: f64) -> RGBColor {
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
    RGBColor(m(a.0, b.0), m(a.1, b.1), m(a.2, b.2))
}

fn plot_err<E: std::fmt::Debug>(e: E) -> Error {
    Error::Numerical {
        method: "plot".into(),
        reason: format!("{e:?}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
        assert!(h.to_svg_string().unwrap().contains("<svg"));
        let bad = Heatmap {
            z: vec![vec![1.0]],
            ..h
        };
        assert!(bad.to_svg_string().is_err());
    }
}
