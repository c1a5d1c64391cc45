//! Heatmaps of a value over a grid, with a colour bar.

use crate::error::{Error, Result};
use crate::series::write_atomic;
use std::path::Path;

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
            super::render::heatmap(self)
        }
        #[cfg(not(feature = "plot"))]
        {
            Err(super::unavailable())
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plot::ticks::grid_ticks;

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
