//! Drawing a heatmap: the coloured cells, the mark and the colour bar.

use super::{ensure_font, plot_err, rgb, step_of, Axis};
use crate::error::Result;
use crate::plot::style::viridis;
use crate::plot::ticks::{
    grid_ticks, linear_ticks, log_tick_labels, log_ticks, nearest_label, tick_label_step,
};
use crate::plot::Heatmap;
use plotters::prelude::*;

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

pub(in crate::plot) fn heatmap(h: &Heatmap) -> Result<String> {
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
