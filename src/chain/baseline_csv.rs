//! The CSV reader of a [`super::Baseline`] table: header, units, cells.

use super::Baseline;
use crate::error::{Error, Result};
use crate::series::{parse_number, split_unit};

/// The three columns a baseline table may have.
const COLUMNS: [&str; 3] = ["mass", "spring", "damper"];
/// Label columns, read and ignored.
const LABELS: [&str; 6] = ["storey", "story", "floor", "level", "row", "index"];

/// One data row: its 1-based row number, and the cells read (SI).
struct Row {
    row: usize,
    cells: [Option<f64>; 3],
}

/// A parsed table, not yet checked as a chain.
pub(super) struct Table {
    rows: Vec<Row>,
    has_damper: bool,
}

/// `baseline FILE row R column `C``.
fn at(source: &str, row: usize, col: &str) -> String {
    format!("baseline {source} row {row} column `{col}`")
}

/// The canonical name of a header field, or `None` for a label column.
fn column_of(name: &str, source: &str) -> Result<Option<usize>> {
    let lower = name.trim().to_ascii_lowercase();
    let canon = match lower.as_str() {
        "mass" | "m" => "mass",
        "spring" | "k" | "stiffness" => "spring",
        "damper" | "d" | "c" | "damping" => "damper",
        other => other,
    };
    if let Some(i) = COLUMNS.iter().position(|c| *c == canon) {
        return Ok(Some(i));
    }
    if LABELS.contains(&canon) || canon.is_empty() {
        return Ok(None);
    }
    Err(Error::invalid(
        format!("baseline {source} header"),
        name,
        format!(
            "columns mass, spring and optionally damper (and a label column: {})",
            LABELS.join(", ")
        ),
    ))
}

/// The factor to SI of a unit in the header of column `col` (0: mass,
/// 1: spring, 2: damper).
fn unit_scale(col: usize, unit: Option<&str>, source: &str) -> Result<f64> {
    let Some(u) = unit else { return Ok(1.0) };
    let squashed: String = u
        .chars()
        .filter(|c| !c.is_whitespace() && *c != '*' && *c != '·')
        .collect();
    let f = match (col, squashed.as_str()) {
        (0, "kg") => Some(1.0),
        (0, "g") => Some(1e-3),
        (0, "t") => Some(1e3),
        (1, "N/m") => Some(1.0),
        (1, "kN/m") | (1, "N/mm") => Some(1e3),
        (1, "MN/m") | (1, "kN/mm") => Some(1e6),
        (2, "Ns/m") => Some(1.0),
        (2, "kNs/m") => Some(1e3),
        _ => None,
    };
    let allowed = ["kg, g, t", "N/m, kN/m, MN/m, N/mm, kN/mm", "N s/m, kN s/m"][col];
    f.ok_or_else(|| {
        Error::invalid(
            format!("baseline {source} column `{}`", COLUMNS[col]),
            format!("[{u}]"),
            format!("a unit of {allowed}, or none (SI or dimensionless)"),
        )
    })
}

impl Table {
    /// Read the header and every data row.
    pub(super) fn parse(text: &str, source: &str) -> Result<Table> {
        let (mut rdr, delim) = crate::series::lab_csv_reader(text);
        let mut records = rdr
            .records()
            .filter(|r| !matches!(r, Ok(rec) if rec.iter().all(str::is_empty)));
        let bad_csv = |e: csv::Error| Error::parse(format!("baseline {source}"), "", e.to_string());
        let header = match records.next() {
            Some(r) => r.map_err(bad_csv)?,
            None => {
                return Err(Error::parse(
                    format!("baseline {source}"),
                    "",
                    "empty file; expected a header such as mass,spring",
                ))
            }
        };
        let layout = Layout::of(&header, source)?;
        let mut rows = Vec::new();
        for (r, rec) in records.enumerate() {
            let rec = rec.map_err(bad_csv)?;
            rows.push(layout.row(&rec, r + 1, delim == b';', source)?);
        }
        Ok(Table {
            rows,
            has_damper: layout.cols[2].is_some(),
        })
    }

    /// Check the rows as a chain (see the module docs of
    /// [`super::baseline`]) and build the profile.
    pub(super) fn into_baseline(self, source: &str) -> Result<Baseline> {
        let nrows = self.rows.len();
        let mut mass = Vec::with_capacity(nrows);
        let mut spring = Vec::with_capacity(nrows + 1);
        let mut damper = Vec::with_capacity(nrows + 1);
        for (i, row) in self.rows.iter().enumerate() {
            let [m, k, d] = row.cells;
            let last = i + 1 == nrows;
            match m {
                Some(m) => {
                    if m <= 0.0 {
                        return Err(Error::invalid(
                            at(source, row.row, "mass"),
                            m,
                            "mass > 0 and finite",
                        ));
                    }
                    mass.push(m);
                }
                None if last && i > 0 && k.is_some() => {}
                None => {
                    let why = if last {
                        "a mass > 0 (a last row without a mass holds the right wall's spring and needs it)"
                    } else {
                        "a mass > 0 (only the last row, the right wall's spring, has no mass: one right-wall row at most)"
                    };
                    return Err(Error::invalid(at(source, row.row, "mass"), "empty", why));
                }
            }
            spring.push(check_spring(k, i == 0 || m.is_none(), source, row.row)?);
            damper.push(check_damper(d, source, row.row)?);
        }
        if mass.is_empty() {
            return Err(Error::parse(
                format!("baseline {source}"),
                "",
                "no row with a mass after the header",
            ));
        }
        if spring.len() == mass.len() {
            // no right-wall row: the right end is free
            spring.push(0.0);
            damper.push(0.0);
        }
        let damper = self.has_damper.then_some(damper);
        Baseline::new(mass, spring, damper, source)
    }
}

/// A spring cell: `> 0` between two masses, `> 0` or empty (a free end) at a wall.
fn check_spring(k: Option<f64>, wall: bool, source: &str, row: usize) -> Result<f64> {
    match k {
        None if wall => Ok(0.0),
        None => Err(Error::invalid(
            at(source, row, "spring"),
            "empty",
            "a spring > 0 between two masses (only the first row's spring may be empty: a free left end)",
        )),
        Some(k) if k > 0.0 => Ok(k),
        Some(k) => Err(Error::invalid(
            at(source, row, "spring"),
            k,
            "spring > 0 and finite (leave the first row's cell empty for a free left end)",
        )),
    }
}

fn check_damper(d: Option<f64>, source: &str, row: usize) -> Result<f64> {
    match d {
        None => Ok(0.0),
        Some(d) if d >= 0.0 => Ok(d),
        Some(d) => Err(Error::invalid(
            at(source, row, "damper"),
            d,
            "damper >= 0 and finite (empty: none)",
        )),
    }
}

/// Where each of the three columns sits in the file and its unit factor.
struct Layout {
    cols: [Option<(usize, f64)>; 3],
}

impl Layout {
    fn of(header: &csv::StringRecord, source: &str) -> Result<Layout> {
        let mut cols = [None; 3];
        for (c, field) in header.iter().enumerate() {
            let (name, unit) = split_unit(field);
            let Some(i) = column_of(&name, source)? else {
                continue;
            };
            if cols[i].is_some() {
                return Err(Error::invalid(
                    format!("baseline {source} header"),
                    field,
                    format!("one column `{}`", COLUMNS[i]),
                ));
            }
            cols[i] = Some((c, unit_scale(i, unit.as_deref(), source)?));
        }
        for i in 0..2 {
            if cols[i].is_none() {
                return Err(Error::invalid(
                    format!("baseline {source} header"),
                    header.iter().collect::<Vec<_>>().join(","),
                    format!(
                        "a column `{}` (columns mass, spring and optionally damper)",
                        COLUMNS[i]
                    ),
                ));
            }
        }
        Ok(Layout { cols })
    }

    fn row(&self, rec: &csv::StringRecord, row: usize, comma: bool, source: &str) -> Result<Row> {
        let mut cells = [None; 3];
        for (i, col) in self.cols.iter().enumerate() {
            let Some((c, scale)) = *col else { continue };
            let f = rec.get(c).unwrap_or("");
            if f.is_empty() {
                continue;
            }
            let v = parse_number(f, comma)
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    Error::invalid(at(source, row, COLUMNS[i]), f, "a finite number, or empty")
                })?;
            cells[i] = Some(v * scale);
        }
        Ok(Row { row, cells })
    }
}

#[cfg(test)]
mod tests {
    use super::super::Boundary;
    use super::*;

    fn field_of(text: &str) -> String {
        match Baseline::from_csv_str(text, "b.csv") {
            Err(Error::InvalidParameter { field, .. }) => field,
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn reads_ends_units_and_conventions() {
        let text = "\u{feff}# a frame\r\nstorey;mass [t];spring [kN/m];damper [kN s/m]\r\n1;2,5;;0,1\r\n2;2;30;\r\n3;1;20;\r\n;;40;\r\n";
        let b = Baseline::from_csv_str(text, "b.csv").unwrap();
        assert_eq!(b.masses(), [2500.0, 2000.0, 1000.0]);
        assert_eq!(b.springs(), [0.0, 30e3, 20e3, 40e3]);
        assert_eq!(b.dampers().unwrap(), [100.0, 0.0, 0.0, 0.0]);
        assert_eq!((b.left(), b.right()), (Boundary::Free, Boundary::Fixed));
        assert_eq!(b.source(), "b.csv");
        let b = Baseline::from_csv_str("mass,spring\n1,2\n1,2\n", "x").unwrap();
        assert_eq!(
            (b.left(), b.right(), b.dampers()),
            (Boundary::Fixed, Boundary::Free, None)
        );
    }

    #[test]
    fn errors_name_row_and_column() {
        assert_eq!(
            field_of("mass,spring\n1,1\n-2,1\n,1\n"),
            "baseline b.csv row 2 column `mass`"
        );
        assert_eq!(
            field_of("mass,spring\n1,1\n2,-1\n,1\n"),
            "baseline b.csv row 2 column `spring`"
        );
        assert_eq!(
            field_of("mass,spring\n1,1\n2,\n,1\n"),
            "baseline b.csv row 2 column `spring`"
        );
        // two right-wall rows: the first is not the last row
        assert_eq!(
            field_of("mass,spring\n1,1\n,1\n,1\n"),
            "baseline b.csv row 2 column `mass`"
        );
        assert_eq!(
            field_of("mass,spring\n1,1\n2,x\n"),
            "baseline b.csv row 2 column `spring`"
        );
        assert_eq!(
            field_of("mass,spring [lbf/in]\n1,1\n"),
            "baseline b.csv column `spring`"
        );
        assert_eq!(field_of("mass,sprung\n1,1\n"), "baseline b.csv header");
        assert_eq!(field_of("mass\n1\n"), "baseline b.csv header");
        assert_eq!(
            field_of("mass,spring,damper\n1,1,-0.1\n"),
            "baseline b.csv row 1 column `damper`"
        );
        assert!(Baseline::from_csv_str("mass,spring\n", "b.csv").is_err());
        assert!(Baseline::from_csv_str("", "b.csv").is_err());
    }
}
