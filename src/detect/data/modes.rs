//! Measured modes: what an experimental modal analysis gives (natural
//! frequencies, damping ratios, mode shapes at the masses where sensors
//! were), read from a CSV table.
//!
//! One row per mode; columns (any order, names case-insensitive):
//!
//! | column | meaning | required |
//! |---|---|---|
//! | `frequency` | natural frequency, Hz (`frequency [Hz]`; `[rad/s]` is converted) | yes |
//! | `frequency_se` | its standard error, same unit | no |
//! | `damping` | modal damping ratio `-Re p / abs(p)` of the mode's pole `p`; fitted when the nominal chain is damped, reported otherwise | no |
//! | `damping_se` | its standard error | no |
//! | `phi_J` | mode-shape component at mass `J` (1-based), any scaling; an empty cell = not measured | no |
//! | `phi_J_se` | its standard error, in the row's scaling | no |
//!
//! ```
//! use springmass::detect::data::modes::MeasuredModes;
//! let m = MeasuredModes::from_csv_str("frequency,phi_1,phi_3\n2.5,1.0,-0.4\n0.9,0.3,1.0\n")?;
//! assert_eq!(m.len(), 2);
//! assert_eq!(m.modes()[0].frequency, 0.9);               // sorted by frequency
//! assert_eq!(m.modes()[0].shape[1].mass, 3);
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::error::{Error, Result};
use crate::series::{at_cell, csv_error, parse_number, raw_row, split_unit};
use serde::Serialize;
use std::path::Path;

/// One measured mode-shape component.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ShapeEntry {
    /// The mass (1-based).
    pub mass: usize,
    /// The component, in the mode's own scaling.
    pub value: f64,
    /// Its standard error, when given.
    pub se: Option<f64>,
}

/// One measured mode.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MeasuredMode {
    /// Natural frequency (Hz).
    pub frequency: f64,
    /// Its standard error (Hz), when given.
    pub frequency_se: Option<f64>,
    /// Damping ratio, when given.
    pub damping: Option<f64>,
    /// Its standard error, when given.
    pub damping_se: Option<f64>,
    /// Mode-shape components at the measured masses, by mass.
    pub shape: Vec<ShapeEntry>,
}

/// Measured modes, in increasing frequency.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MeasuredModes {
    modes: Vec<MeasuredMode>,
}

impl MeasuredModes {
    /// Modes from their values, sorted by frequency.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming the field (`modes[i].frequency`,
    /// `..frequency_se`, `..damping`, `..phi_J`, `..phi_J_se`) and its
    /// range: no mode; a frequency not positive and finite; two modes of
    /// the same frequency (not sortable); a standard error not positive; a
    /// damping ratio outside `[0, 1)`; a shape component not finite or at
    /// mass 0; a mass listed twice in one mode.
    pub fn new(mut modes: Vec<MeasuredMode>) -> Result<MeasuredModes> {
        if modes.is_empty() {
            return Err(Error::invalid(
                "modes",
                "none",
                "at least one measured mode",
            ));
        }
        for (i, m) in modes.iter().enumerate() {
            check_mode(i, m)?;
        }
        modes.sort_by(|a, b| a.frequency.total_cmp(&b.frequency));
        if let Some(w) = modes.windows(2).find(|w| w[0].frequency == w[1].frequency) {
            return Err(Error::invalid(
                "modes.frequency",
                w[0].frequency,
                "distinct frequencies (two modes of the same frequency cannot be sorted or paired)",
            ));
        }
        Ok(MeasuredModes { modes })
    }

    /// The modes, in increasing frequency.
    pub fn modes(&self) -> &[MeasuredMode] {
        &self.modes
    }

    /// Number of modes.
    pub fn len(&self) -> usize {
        self.modes.len()
    }

    /// Whether there is no mode (never, once built).
    pub fn is_empty(&self) -> bool {
        self.modes.is_empty()
    }

    /// The largest mass any shape names (0 without shapes).
    pub fn max_mass(&self) -> usize {
        let masses = self
            .modes
            .iter()
            .flat_map(|m| m.shape.iter().map(|e| e.mass));
        masses.max().unwrap_or(0)
    }

    /// Check that every shape component names a mass of an `n`-mass chain.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] on `modes.phi_J` with `1 <= J <= n`.
    pub fn check_chain(&self, n: usize) -> Result<()> {
        let j = self.max_mass();
        if j > n {
            return Err(Error::invalid(
                format!("modes.phi_{j}"),
                format!("mass {j}"),
                format!("a mass of the chain, 1 <= J <= n = {n}"),
            ));
        }
        Ok(())
    }

    /// The modes whose 1-based numbers (in increasing frequency) are in
    /// `keep`, and the others.
    ///
    /// # Errors
    /// A number outside `1..=len` (field `hold_out`); nothing left to fit.
    pub fn split(&self, hold_out: &[usize]) -> Result<(MeasuredModes, Vec<MeasuredMode>)> {
        if let Some(&j) = hold_out.iter().find(|&&j| j == 0 || j > self.len()) {
            return Err(Error::invalid(
                "hold_out",
                j,
                format!("mode numbers 1..={} (in increasing frequency)", self.len()),
            ));
        }
        let (mut kept, mut held) = (Vec::new(), Vec::new());
        for (i, m) in self.modes.iter().enumerate() {
            if hold_out.contains(&(i + 1)) {
                held.push(m.clone());
            } else {
                kept.push(m.clone());
            }
        }
        if kept.is_empty() {
            return Err(Error::invalid(
                "hold_out",
                format!("{hold_out:?}"),
                "at least one mode left to fit",
            ));
        }
        Ok((MeasuredModes { modes: kept }, held))
    }

    /// Read the table of the module docs from CSV text (`,`, `;` with a
    /// decimal comma, or tab; `#` comment lines; a byte-order mark).
    ///
    /// # Errors
    /// [`Error::Parse`] naming the row and column for a cell that is not a
    /// number, an unknown column or a missing `frequency` column;
    /// the errors of [`MeasuredModes::new`].
    pub fn from_csv_str(text: &str) -> Result<MeasuredModes> {
        let (mut rdr, delim) = crate::series::lab_csv_reader(text);
        let mut records = rdr.records();
        let header = loop {
            match records.next() {
                None => return Err(Error::parse("modes CSV", "", "no header line")),
                Some(r) => {
                    let r = r.map_err(|e| csv_error(&e))?;
                    if !r.iter().all(str::is_empty) {
                        break r;
                    }
                }
            }
        };
        let cols = header
            .iter()
            .enumerate()
            .map(|(c, h)| Column::parse(h, c, &header, delim))
            .collect::<Result<Vec<_>>>()?;
        if !cols.iter().any(|c| matches!(c.role, Role::Frequency)) {
            return Err(Error::parse(
                "modes CSV header (line 1)",
                raw_row(&header, delim),
                "no `frequency` column (Hz): one row per mode, columns frequency, phi_1, phi_2, ...",
            ));
        }
        let mut modes = Vec::new();
        for rec in records {
            let rec = rec.map_err(|e| csv_error(&e))?;
            if rec.iter().all(str::is_empty) {
                continue;
            }
            modes.push(read_row(&rec, modes.len() + 1, &cols, delim)?);
        }
        MeasuredModes::new(modes)
    }

    /// Read a modes file (see [`MeasuredModes::from_csv_str`]).
    ///
    /// # Errors
    /// [`Error::Io`] naming the file; the parse errors prefixed with it.
    pub fn read_csv(path: impl AsRef<Path>) -> Result<MeasuredModes> {
        let path = path.as_ref();
        crate::io::parse_file(path, MeasuredModes::from_csv_str)
    }
}

/// What a column holds.
#[derive(Clone, Copy, Debug)]
enum Role {
    Frequency,
    FrequencySe,
    Damping,
    DampingSe,
    Shape(usize),
    ShapeSe(usize),
}

/// One header cell: its role and the factor to Hz (frequency columns).
#[derive(Clone, Debug)]
struct Column {
    role: Role,
    name: String,
    index: usize,
    to_hz: f64,
}

impl Column {
    fn parse(h: &str, index: usize, header: &csv::StringRecord, delim: u8) -> Result<Column> {
        let (name, unit) = split_unit(h);
        let lower = name.to_ascii_lowercase();
        let bad = |reason: String| {
            Error::parse(
                format!("modes CSV header (line 1), column {} `{name}`", index + 1),
                raw_row(header, delim),
                reason,
            )
        };
        let mass = |s: &str| s.parse::<usize>().ok().filter(|&j| j >= 1);
        let role = match lower.as_str() {
            "frequency" | "f" => Role::Frequency,
            "frequency_se" | "f_se" => Role::FrequencySe,
            "damping" | "zeta" => Role::Damping,
            "damping_se" | "zeta_se" => Role::DampingSe,
            _ => match lower.strip_prefix("phi_") {
                Some(rest) => match rest.strip_suffix("_se") {
                    Some(j) => Role::ShapeSe(mass(j).ok_or_else(|| bad(shape_help()))?),
                    None => Role::Shape(mass(rest).ok_or_else(|| bad(shape_help()))?),
                },
                None => return Err(bad(format!("unknown column; {}", shape_help()))),
            },
        };
        let to_hz = match (role, unit.as_deref()) {
            (Role::Frequency | Role::FrequencySe, Some(u)) => {
                frequency_unit(u).ok_or_else(|| {
                    bad(format!(
                        "unit [{u}]: a frequency column takes [Hz] or [rad/s]"
                    ))
                })?
            }
            _ => 1.0,
        };
        Ok(Column {
            role,
            name,
            index,
            to_hz,
        })
    }
}

fn shape_help() -> String {
    "columns are frequency, frequency_se, damping, damping_se, phi_J and phi_J_se with J a mass number >= 1"
        .to_string()
}

/// The factor from a frequency unit to Hz.
fn frequency_unit(u: &str) -> Option<f64> {
    match u {
        "Hz" | "hz" | "1/s" => Some(1.0),
        "rad/s" => Some(1.0 / std::f64::consts::TAU),
        _ => None,
    }
}

/// One data row as a mode (`row` 1-based).
fn read_row(
    rec: &csv::StringRecord,
    row: usize,
    cols: &[Column],
    delim: u8,
) -> Result<MeasuredMode> {
    let mut mode = MeasuredMode {
        frequency: f64::NAN,
        frequency_se: None,
        damping: None,
        damping_se: None,
        shape: Vec::new(),
    };
    let mut ses: Vec<(usize, f64)> = Vec::new();
    if rec.len() > cols.len() {
        return Err(Error::parse(
            format!("modes CSV row {row}"),
            raw_row(rec, delim),
            format!("{} fields for {} columns", rec.len(), cols.len()),
        ));
    }
    for c in cols {
        let f = rec.get(c.index).unwrap_or("");
        if f.is_empty() {
            continue;
        }
        let v = parse_number(f, delim == b';')
            .filter(|v| v.is_finite())
            .ok_or_else(|| {
                Error::parse(
                    format!("modes {}", at_cell(rec, row, &c.name, c.index)),
                    raw_row(rec, delim),
                    format!("{f:?} is not a finite number"),
                )
            })?;
        match c.role {
            Role::Frequency => mode.frequency = v * c.to_hz,
            Role::FrequencySe => mode.frequency_se = Some(v * c.to_hz),
            Role::Damping => mode.damping = Some(v),
            Role::DampingSe => mode.damping_se = Some(v),
            Role::Shape(j) => mode.shape.push(ShapeEntry {
                mass: j,
                value: v,
                se: None,
            }),
            Role::ShapeSe(j) => ses.push((j, v)),
        }
    }
    for (j, se) in ses {
        match mode.shape.iter_mut().find(|e| e.mass == j) {
            Some(e) => e.se = Some(se),
            None => {
                return Err(Error::invalid(
                    format!("modes[{row}].phi_{j}_se"),
                    se,
                    format!("a standard error only where phi_{j} is given"),
                ))
            }
        }
    }
    if mode.frequency.is_nan() {
        return Err(Error::invalid(
            format!("modes[{row}].frequency"),
            "empty",
            "every mode's frequency (Hz)",
        ));
    }
    mode.shape.sort_by_key(|e| e.mass);
    Ok(mode)
}

/// The ranges of one mode's values (`i` 0-based).
fn check_mode(i: usize, m: &MeasuredMode) -> Result<()> {
    let field = |f: &str| format!("modes[{}].{f}", i + 1);
    let positive = |name: &str, v: f64| {
        if v > 0.0 && v.is_finite() {
            Ok(())
        } else {
            Err(Error::invalid(field(name), v, "> 0 and finite"))
        }
    };
    positive("frequency", m.frequency)?;
    if let Some(se) = m.frequency_se {
        positive("frequency_se", se)?;
    }
    if let Some(se) = m.damping_se {
        if m.damping.is_none() {
            return Err(Error::invalid(
                field("damping_se"),
                se,
                "a standard error only where the damping ratio is given",
            ));
        }
        positive("damping_se", se)?;
    }
    if let Some(z) = m.damping {
        if !(0.0..1.0).contains(&z) {
            return Err(Error::invalid(
                field("damping"),
                z,
                "a damping ratio in [0, 1)",
            ));
        }
    }
    for (a, e) in m.shape.iter().enumerate() {
        let name = format!("phi_{}", e.mass);
        if e.mass == 0 {
            return Err(Error::invalid(field("phi_0"), e.value, "masses J >= 1"));
        }
        if !e.value.is_finite() {
            return Err(Error::invalid(field(&name), e.value, "finite"));
        }
        if let Some(se) = e.se {
            positive(&format!("{name}_se"), se)?;
        }
        if m.shape[..a].iter().any(|b| b.mass == e.mass) {
            return Err(Error::invalid(
                field(&name),
                e.mass,
                "each mass once per mode",
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_units_se_and_empty_cells() {
        let m = MeasuredModes::from_csv_str(
            "\u{feff}# modes\nfrequency [rad/s];phi_2;phi_2_se;phi_1\n6,2832;0,5;0,01;\n",
        )
        .unwrap();
        let mode = &m.modes()[0];
        assert!((mode.frequency - 1.0).abs() < 1e-4);
        assert_eq!(mode.shape.len(), 1);
        assert_eq!(mode.shape[0].se, Some(0.01));
    }

    #[test]
    fn bad_tables_name_the_field() {
        let cases = [
            ("frequency,phi_1\n-1,0.5\n", "frequency"),
            ("frequency,phi_1\n1,0.5\n1,0.3\n", "distinct"),
            ("frequency,phi_x\n1,0.5\n", "phi_J"),
            ("frequency,mode\n1,0.5\n", "unknown column"),
            ("phi_1\n0.5\n", "no `frequency`"),
            ("frequency,phi_1\n1,abc\n", "not a finite number"),
            ("frequency,phi_1\n1,0.5,3\n", "fields"),
            ("frequency [kHz],phi_1\n1,0.5\n", "[Hz] or [rad/s]"),
            ("frequency,phi_1_se\n1,0.5\n", "only where"),
            ("frequency,damping\n1,1.5\n", "damping"),
            ("frequency\n", "at least one"),
        ];
        for (text, want) in cases {
            let e = MeasuredModes::from_csv_str(text).unwrap_err().to_string();
            assert!(e.contains(want), "{text:?}: {e}");
        }
    }

    #[test]
    fn chain_check_and_hold_out() {
        let m = MeasuredModes::from_csv_str("frequency,phi_5\n1,1\n2,1\n").unwrap();
        assert!(m.check_chain(4).unwrap_err().to_string().contains("phi_5"));
        m.check_chain(5).unwrap();
        let (fit, held) = m.split(&[2]).unwrap();
        assert_eq!((fit.len(), held.len(), held[0].frequency), (1, 1, 2.0));
        assert!(m.split(&[3]).is_err() && m.split(&[1, 2]).is_err());
    }
}
