//! SVG plots: line charts (one panel or small multiples) and heatmaps,
//! written atomically.
//!
//! Text is laid out with the DejaVu Sans font bundled in `assets/` (its
//! licence is `assets/DejaVuSans-LICENSE.txt`), registered once with plotters'
//! `ab_glyph` backend, so plots render the same on any machine without system
//! fonts. Rendering needs the `plot` feature (on by default); without it the
//! chart types still exist and [`LinePlot::to_svg_string`] and
//! [`Heatmap::to_svg_string`] return an
//! [`Error::InvalidParameter`](crate::Error::InvalidParameter) naming `plot`.
//!
//! One job a file: `ticks.rs` (tick positions and labels), `style.rs`
//! (colours, dashes, markers, the heatmap colour map), `line.rs` (line charts
//! and their [`Layout`]), `heatmap.rs` (heatmaps), and `render/` (the
//! plotters drawing of both, behind the `plot` feature).
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

mod heatmap;
mod line;
#[cfg(feature = "plot")]
mod render;
mod style;
mod ticks;

pub use heatmap::Heatmap;
pub use line::{Layout, Line, LinePlot, Panel};
pub use style::{series_style, Dash, Marker};
pub use ticks::{
    integer_ticks, linear_ticks, log_tick_labels, log_ticks, nice_step, tick_label, tick_label_step,
};

#[cfg(not(feature = "plot"))]
use crate::error::Error;

/// Most series one panel carries; a chart with more becomes small multiples.
pub const MAX_SERIES: usize = 6;

#[cfg(not(feature = "plot"))]
pub(crate) fn unavailable() -> Error {
    Error::invalid(
        "plot",
        "svg",
        "a build with the `plot` feature (plots are not compiled in)",
    )
}
