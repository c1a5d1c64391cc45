//! The plotters side: only drawing, every decision is in [`super::Layout`].
//! Here the pieces both chart kinds use: the bundled font, the axis type,
//! the error of a drawing call.

mod heat;
mod lines;

pub(super) use heat::heatmap;
pub(super) use lines::line_plot;

use crate::error::Error;
use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint};
use plotters::prelude::*;
use std::sync::Once;

static FONT: &[u8] = include_bytes!("../../../assets/DejaVuSans.ttf");
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

/// The spacing of evenly spaced ticks (1 for fewer than two).
fn step_of(t: &[f64]) -> f64 {
    if t.len() >= 2 {
        (t[1] - t[0]).abs()
    } else {
        1.0
    }
}
