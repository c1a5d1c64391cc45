//! Drawing a line chart from its [`Layout`]: panels, curves, bands, error
//! bars and the legend.

use super::{ensure_font, plot_err, rgb, step_of, Axis};
use crate::error::Result;
use crate::plot::ticks::{log_tick_labels, nearest_label, tick_label_step};
use crate::plot::{series_style, Dash, Layout, LinePlot, Marker, Panel};
use plotters::element::DashedPathElement;
use plotters::prelude::*;

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

pub(in crate::plot) fn line_plot(p: &LinePlot, l: &Layout) -> Result<String> {
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
        if line.is_some_and(|x| x.points.is_empty() && !x.band.is_empty()) {
            // a band alone: its swatch, as shaded in the panel
            area.draw(&Rectangle::new(
                [(x0, y - 6), (x1, y + 6)],
                color.mix(0.18).filled(),
            ))
            .map_err(plot_err)?;
        } else {
            if !only_markers {
                draw_legend_path(area, (x0, x1, y), dash, color)?;
            }
            if *markers {
                draw_legend_marker(area, ((x0 + x1) / 2, y), marker, color)?;
            }
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
        Marker::Square => area.draw(&Rectangle::new([(m.0 - 3, m.1 - 3), (m.0 + 4, m.1 + 4)], s)),
        Marker::Triangle => area.draw(&TriangleMarker::new(m, 5, s)),
        Marker::Cross => area.draw(&Cross::new(m, 4, color.stroke_width(2))),
    }
    .map_err(plot_err)
}
