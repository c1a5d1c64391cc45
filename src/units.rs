//! Units in a record's header (`t [ms]`, `x1 [mm]`, `a1 [m/s^2]`, `a1 [g]`):
//! recognised, converted to SI (seconds, metres), and checked against what
//! the column is said to measure.
//!
//! A record whose header gives units is converted to SI before the fit, so
//! the same test written in millimetres and milliseconds gives the same
//! chain as in metres and seconds; the chain's `--mass`, `--k`, `--d` and
//! `--gamma` are then in SI (kg, N/m, N s/m, N s). A unit that is not
//! recognised (`V`, `counts`) leaves the values as they are, and the
//! conversion says so; a unit of another quantity than the column measures
//! (`x1 [m/s^2]` read as a displacement) is an error.
//!
//! ```
//! use springmass::units::{parse_unit, Quantity};
//! let mm = parse_unit("mm").unwrap();
//! assert_eq!((mm.quantity, mm.to_si), (Quantity::Displacement, 1e-3));
//! let g = parse_unit("g").unwrap();
//! assert_eq!(g.quantity, Quantity::Acceleration);
//! assert!((g.to_si - 9.80665).abs() < 1e-12);
//! assert_eq!(parse_unit("m/s²").unwrap().quantity, Quantity::Acceleration);
//! assert!(parse_unit("V").is_none());
//! ```

use crate::error::{Error, Result};
use crate::forward::Observable;
use crate::series::TimeSeries;

/// What a unit measures.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Quantity {
    /// Seconds and multiples.
    Time,
    /// Metres and multiples, inches, feet.
    Displacement,
    /// A length per time.
    Velocity,
    /// A length per time squared, or `g`.
    Acceleration,
}

impl Quantity {
    /// `time`, `displacement`, `velocity`, `acceleration`.
    pub fn name(self) -> &'static str {
        match self {
            Quantity::Time => "time",
            Quantity::Displacement => "displacement",
            Quantity::Velocity => "velocity",
            Quantity::Acceleration => "acceleration",
        }
    }

    /// The SI unit's symbol.
    pub fn si(self) -> &'static str {
        match self {
            Quantity::Time => "s",
            Quantity::Displacement => "m",
            Quantity::Velocity => "m/s",
            Quantity::Acceleration => "m/s^2",
        }
    }

    /// The quantity of an observable.
    pub fn of(kind: Observable) -> Quantity {
        match kind {
            Observable::Displacement => Quantity::Displacement,
            Observable::Velocity => Quantity::Velocity,
            Observable::Acceleration => Quantity::Acceleration,
        }
    }
}

/// A recognised unit: its quantity and the factor to SI.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Unit {
    /// What it measures.
    pub quantity: Quantity,
    /// Multiply a value by this to get SI.
    pub to_si: f64,
}

/// Standard gravity, m/s^2.
pub const STANDARD_GRAVITY: f64 = 9.806_65;

fn length(text: &str) -> Option<f64> {
    Some(match text {
        "m" => 1.0,
        "cm" => 1e-2,
        "mm" => 1e-3,
        "um" | "µm" | "μm" | "micron" => 1e-6,
        "nm" => 1e-9,
        "km" => 1e3,
        "in" | "inch" => 0.0254,
        "ft" => 0.3048,
        _ => return None,
    })
}

fn time(text: &str) -> Option<f64> {
    Some(match text {
        "s" | "sec" => 1.0,
        "ms" => 1e-3,
        "us" | "µs" | "μs" => 1e-6,
        "ns" => 1e-9,
        "min" => 60.0,
        "h" => 3600.0,
        _ => return None,
    })
}

/// Recognise a unit (case-sensitive, as SI symbols are: `ms` is not `Ms`).
/// Forms: a length (`m`, `mm`, `um`, `in`, ...), a time (`s`, `ms`, ...),
/// `L/T` (velocity), `L/T^2`, `L/T2`, `L/T²`, `L/s/s` (acceleration), `g`.
/// `None` for anything else.
pub fn parse_unit(text: &str) -> Option<Unit> {
    let u = text.trim();
    let unit = |quantity, to_si| Some(Unit { quantity, to_si });
    if u == "g" || u == "G" {
        return unit(Quantity::Acceleration, STANDARD_GRAVITY);
    }
    if let Some(f) = time(u) {
        return unit(Quantity::Time, f);
    }
    if let Some(f) = length(u) {
        return unit(Quantity::Displacement, f);
    }
    let (num, den) = u.split_once('/')?;
    let l = length(num.trim())?;
    let den = den.trim();
    for suffix in ["^2", "2", "²", "**2"] {
        if let Some(tu) = den.strip_suffix(suffix).and_then(time) {
            return unit(Quantity::Acceleration, l / (tu * tu));
        }
    }
    if let Some((a, b)) = den.split_once('/') {
        let (ta, tb) = (time(a.trim())?, time(b.trim())?);
        return unit(Quantity::Acceleration, l / (ta * tb));
    }
    unit(Quantity::Velocity, l / time(den)?)
}

/// The factor that takes a column with header unit `unit` to SI, checked
/// against the quantity `expected`: `Ok(None)` for no unit or one not
/// recognised (the values are used as they are).
///
/// # Errors
/// A recognised unit of another quantity (field `field`, naming the unit,
/// its quantity and the expected one).
pub fn si_factor(field: &str, unit: Option<&str>, expected: Quantity) -> Result<Option<f64>> {
    let Some(text) = unit else {
        return Ok(None);
    };
    let Some(u) = parse_unit(text) else {
        return Ok(None);
    };
    if u.quantity != expected {
        return Err(Error::invalid(
            field,
            format!("[{text}], a unit of {}", u.quantity.name()),
            format!(
                "a unit of {} (the column is read as {}: check --observe-kind or the column)",
                expected.name(),
                expected.name()
            ),
        ));
    }
    Ok(Some(u.to_si))
}

/// `table` with its time column and value column `column` converted to SI
/// by their headers' units (`column` read as `kind`), and one note per
/// column on what was done (`t [ms] -> s`, `unit [V] not recognised`).
/// The other columns (a force) are left as they are.
///
/// # Errors
/// A unit that contradicts the column's quantity ([`si_factor`]); a
/// column that does not exist (field `column`).
pub fn record_in_si(
    table: &TimeSeries,
    column: &str,
    kind: Observable,
) -> Result<(TimeSeries, Vec<String>)> {
    let mut notes = Vec::new();
    let t_unit = table.time_unit();
    let ft = si_factor("t", t_unit, Quantity::Time)?;
    let x_unit = table.unit(column);
    let fx = si_factor(column, x_unit, Quantity::of(kind))?;
    for (name, unit, f, q) in [
        ("t", t_unit, ft, Quantity::Time),
        (column, x_unit, fx, Quantity::of(kind)),
    ] {
        match (unit, f) {
            (Some(u), Some(f)) if f != 1.0 => {
                notes.push(format!("{name} [{u}] converted to {}", q.si()))
            }
            (Some(u), None) => notes.push(format!(
                "{name} [{u}]: unit not recognised, values used as they are"
            )),
            _ => {}
        }
    }
    if ft.is_none_or(|f| f == 1.0) && fx.is_none_or(|f| f == 1.0) {
        return Ok((table.clone(), notes));
    }
    let scale = |v: &[f64], f: Option<f64>| -> Vec<f64> {
        let f = f.unwrap_or(1.0);
        v.iter().map(|x| x * f).collect()
    };
    let t = scale(table.t(), ft);
    let cols = table
        .names()
        .iter()
        .map(|n| {
            let v = table.require(n)?;
            Ok((
                n.clone(),
                if n == column {
                    scale(v, fx)
                } else {
                    v.to_vec()
                },
            ))
        })
        .collect::<Result<Vec<_>>>()?;
    let mut out = TimeSeries::new(t, cols)?;
    let units = table
        .names()
        .iter()
        .map(|n| match (n == column, fx) {
            (true, Some(_)) => Some(Quantity::of(kind).si().to_string()),
            _ => table.unit(n).map(str::to_string),
        })
        .collect();
    let t_si = match ft {
        Some(_) => Some("s".to_string()),
        None => t_unit.map(str::to_string),
    };
    out.set_units(units, t_si);
    Ok((out, notes))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn units_and_their_factors() {
        let cases = [
            ("s", Quantity::Time, 1.0),
            ("ms", Quantity::Time, 1e-3),
            ("mm", Quantity::Displacement, 1e-3),
            ("in", Quantity::Displacement, 0.0254),
            ("mm/s", Quantity::Velocity, 1e-3),
            ("m/s^2", Quantity::Acceleration, 1.0),
            ("mm/s2", Quantity::Acceleration, 1e-3),
            ("m/ms^2", Quantity::Acceleration, 1e6),
            ("m/s/s", Quantity::Acceleration, 1.0),
            ("g", Quantity::Acceleration, STANDARD_GRAVITY),
        ];
        for (text, q, f) in cases {
            let u = parse_unit(text).unwrap_or_else(|| panic!("{text}"));
            assert_eq!(u.quantity, q, "{text}");
            assert!((u.to_si / f - 1.0).abs() < 1e-12, "{text}: {}", u.to_si);
        }
        for text in ["V", "counts", "", "m/V", "kg", "Ms"] {
            assert!(parse_unit(text).is_none(), "{text}");
        }
    }

    #[test]
    fn a_record_in_millimetres_and_milliseconds_is_the_same_in_si() {
        let mm =
            TimeSeries::from_csv_str("t [ms],x1 [mm],f [N]\n0,0,1\n500,2,0\n1000,3,0\n").unwrap();
        let (si, notes) = record_in_si(&mm, "x1", Observable::Displacement).unwrap();
        assert_eq!(si.t(), [0.0, 0.5, 1.0]);
        assert_eq!(si.column("x1").unwrap(), [0.0, 0.002, 0.003]);
        assert_eq!(si.column("f").unwrap(), [1.0, 0.0, 0.0]);
        assert_eq!((si.unit("x1"), si.time_unit()), (Some("m"), Some("s")));
        assert_eq!(notes.len(), 2, "{notes:?}");
        let e = record_in_si(&mm, "x1", Observable::Acceleration)
            .unwrap_err()
            .to_string();
        assert!(e.contains("x1") && e.contains("displacement"), "{e}");
    }

    #[test]
    fn a_contradicting_unit_is_refused_naming_the_field() {
        let e = si_factor("x1", Some("m/s^2"), Quantity::Displacement)
            .unwrap_err()
            .to_string();
        assert!(e.contains("x1") && e.contains("acceleration"), "{e}");
        assert_eq!(
            si_factor("x1", Some("V"), Quantity::Displacement).unwrap(),
            None
        );
        assert_eq!(
            si_factor("a1", Some("g"), Quantity::Acceleration).unwrap(),
            Some(STANDARD_GRAVITY)
        );
        assert_eq!(si_factor("t", None, Quantity::Time).unwrap(), None);
    }
}
