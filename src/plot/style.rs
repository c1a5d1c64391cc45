//! How series look: colours, dash patterns and markers, and the colour map
//! of heatmaps.

/// Qualitative colour cycle (colour-blind friendly, Okabe-Ito), as RGB.
pub(super) const PALETTE: [(u8, u8, u8); 8] = [
    (0, 114, 178),
    (213, 94, 0),
    (0, 158, 115),
    (204, 121, 167),
    (230, 159, 0),
    (86, 180, 233),
    (0, 0, 0),
    (240, 228, 66),
];

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

/// A five-stop approximation of the viridis colour map, `u` in [0, 1].
#[cfg_attr(not(feature = "plot"), allow(dead_code))]
pub(super) fn viridis(u: f64) -> (u8, u8, u8) {
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

#[cfg(test)]
mod tests {
    use super::*;

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
}
