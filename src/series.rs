//! Sampled time series: `t` and one or more named columns (for example `x1`,
//! `x20`), with CSV input/output and validation.
//!
//! CSV form: a header line `t,name1,name2,...` then one row per sample. Times
//! must be finite and strictly increasing (uniform or not); values finite.
//! Files are written atomically (to a temporary file, then renamed), so a
//! reader never sees half a file.
//!
//! ```
//! use springmass::series::TimeSeries;
//! let ts = TimeSeries::new(vec![0.0, 0.5, 1.0], vec![("x1".into(), vec![0.0, 0.4, 0.6])])?;
//! assert_eq!(ts.column("x1").unwrap()[1], 0.4);
//! assert_eq!(ts.uniform_step(1e-12), Some(0.5));
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::error::{Error, Result};
use std::io::Write;
use std::path::Path;

/// Check a time grid: every `t[i]` finite and strictly greater than `t[i-1]`
/// (uniform or not). Shared by [`TimeSeries::new`] and
/// [`crate::time::series::SeriesTransform::new`].
///
/// ```
/// use springmass::series::check_times;
/// assert!(check_times(&[0.0, 0.5, 2.0]).is_ok());
/// assert!(check_times(&[0.0, 0.5, 0.5]).is_err());
/// ```
///
/// # Errors
/// [`Error::InvalidParameter`] naming the first bad sample (`t[i]`).
pub fn check_times(t: &[f64]) -> Result<()> {
    for (i, w) in t.iter().enumerate() {
        if !w.is_finite() {
            return Err(Error::invalid(format!("t[{i}]"), w, "finite"));
        }
        if i > 0 && *w <= t[i - 1] {
            return Err(Error::invalid(
                format!("t[{i}]"),
                w,
                format!(
                    "strictly greater than t[{}] = {} (sorted, no duplicates)",
                    i - 1,
                    t[i - 1]
                ),
            ));
        }
    }
    Ok(())
}

/// A validated time series.
#[derive(Clone, Debug, PartialEq)]
pub struct TimeSeries {
    t: Vec<f64>,
    names: Vec<String>,
    columns: Vec<Vec<f64>>,
}

impl TimeSeries {
    /// Build and validate.
    ///
    /// # Errors
    /// Empty series, no column, non-finite or non-increasing times (naming the
    /// sample index), column length mismatch, non-finite values, duplicate or
    /// empty column names.
    pub fn new(t: Vec<f64>, columns: Vec<(String, Vec<f64>)>) -> Result<TimeSeries> {
        if t.is_empty() {
            return Err(Error::invalid("t", "[]", "at least one sample"));
        }
        if columns.is_empty() {
            return Err(Error::invalid("columns", "[]", "at least one value column"));
        }
        check_times(&t)?;
        let mut names = Vec::with_capacity(columns.len());
        let mut cols = Vec::with_capacity(columns.len());
        for (name, v) in columns {
            if name.is_empty() || names.contains(&name) {
                return Err(Error::invalid("column name", &name, "non-empty and unique"));
            }
            if v.len() != t.len() {
                return Err(Error::invalid(
                    format!("{name}.len"),
                    v.len(),
                    format!("equal to the number of times ({})", t.len()),
                ));
            }
            if let Some(i) = v.iter().position(|x| !x.is_finite()) {
                return Err(Error::invalid(format!("{name}[{i}]"), v[i], "finite"));
            }
            names.push(name);
            cols.push(v);
        }
        Ok(TimeSeries {
            t,
            names,
            columns: cols,
        })
    }

    /// Sample times.
    pub fn t(&self) -> &[f64] {
        &self.t
    }
    /// Column names, in order.
    pub fn names(&self) -> &[String] {
        &self.names
    }
    /// A column by name.
    pub fn column(&self, name: &str) -> Option<&[f64]> {
        self.names
            .iter()
            .position(|n| n == name)
            .map(|i| self.columns[i].as_slice())
    }
    /// A column by position (0-based, excluding `t`).
    pub fn column_at(&self, i: usize) -> Option<&[f64]> {
        self.columns.get(i).map(|c| c.as_slice())
    }
    /// A column by name, or an error naming it and the columns present.
    pub fn require(&self, name: &str) -> Result<&[f64]> {
        self.column(name).ok_or_else(|| {
            Error::invalid("column", name, format!("one of: {}", self.names.join(", ")))
        })
    }
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }
    /// Never true for a validated series (kept for API symmetry).
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }
    /// The step if the times are uniform to relative tolerance `rel_tol`.
    pub fn uniform_step(&self, rel_tol: f64) -> Option<f64> {
        if self.t.len() < 2 {
            return None;
        }
        let h = (self.t[self.t.len() - 1] - self.t[0]) / (self.t.len() - 1) as f64;
        let ok = self
            .t
            .windows(2)
            .all(|w| ((w[1] - w[0]) - h).abs() <= rel_tol.max(1e-12) * h.abs());
        ok.then_some(h)
    }

    /// Parse CSV text (header `t,<names>`).
    ///
    /// # Errors
    /// [`Error::Parse`] naming the line (1-based) for a missing header, a
    /// missing or extra field, or a number that does not parse or is NaN/inf;
    /// unsorted or duplicate times name the line too.
    pub fn from_csv_str(text: &str) -> Result<TimeSeries> {
        let mut lines = text
            .lines()
            .enumerate()
            .filter(|(_, l)| !l.trim().is_empty() && !l.trim_start().starts_with('#'));
        let (hline, header) = lines
            .next()
            .ok_or_else(|| Error::parse("CSV", "", "empty file; expected a header t,x1,..."))?;
        let names: Vec<String> = header.split(',').map(|h| h.trim().to_string()).collect();
        if names.len() < 2 || !matches!(names[0].as_str(), "t" | "time") {
            return Err(Error::parse(
                format!("CSV header (line {})", hline + 1),
                header,
                "expected `t,<name>[,<name>...]` with at least one value column",
            ));
        }
        let ncol = names.len();
        let mut t = Vec::new();
        let mut cols: Vec<Vec<f64>> = vec![Vec::new(); ncol - 1];
        for (ln, line) in lines {
            let fields: Vec<&str> = line.split(',').map(str::trim).collect();
            let where_ = format!("CSV line {}", ln + 1);
            if fields.len() != ncol {
                return Err(Error::parse(
                    where_,
                    line,
                    format!(
                        "expected {ncol} fields ({}), found {}",
                        names.join(","),
                        fields.len()
                    ),
                ));
            }
            let mut vals = Vec::with_capacity(ncol);
            for (f, name) in fields.iter().zip(&names) {
                let v: f64 = f.parse().map_err(|_| {
                    Error::parse(
                        where_.clone(),
                        line,
                        format!("field `{name}` = {f:?} is not a number"),
                    )
                })?;
                if !v.is_finite() {
                    return Err(Error::parse(
                        where_.clone(),
                        line,
                        format!("field `{name}` is {v}; values must be finite"),
                    ));
                }
                vals.push(v);
            }
            if let Some(&prev) = t.last() {
                if vals[0] <= prev {
                    return Err(Error::parse(
                        where_,
                        line,
                        format!("time {} is not greater than the previous time {prev}: times must be sorted and distinct", vals[0]),
                    ));
                }
            }
            t.push(vals[0]);
            for (c, v) in cols.iter_mut().zip(&vals[1..]) {
                c.push(*v);
            }
        }
        if t.is_empty() {
            return Err(Error::parse("CSV", header, "no data rows after the header"));
        }
        TimeSeries::new(t, names[1..].iter().cloned().zip(cols).collect())
    }

    /// Read a CSV file (see [`TimeSeries::from_csv_str`]).
    pub fn read_csv(path: impl AsRef<Path>) -> Result<TimeSeries> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        TimeSeries::from_csv_str(&text).map_err(|e| match e {
            Error::Parse {
                what,
                input,
                reason,
            } => Error::Parse {
                what: format!("{}: {what}", path.display()),
                input,
                reason,
            },
            other => other,
        })
    }

    /// CSV text with 17 significant digits (round-trips `f64`).
    pub fn to_csv_string(&self) -> String {
        let mut out = String::with_capacity(self.t.len() * 24 * (1 + self.columns.len()));
        out.push('t');
        for n in &self.names {
            out.push(',');
            out.push_str(n);
        }
        out.push('\n');
        for i in 0..self.t.len() {
            out.push_str(&format!("{:e}", self.t[i]));
            for c in &self.columns {
                out.push_str(&format!(",{:e}", c[i]));
            }
            out.push('\n');
        }
        out
    }

    /// Write CSV atomically (temporary file in the same folder, then rename).
    pub fn write_csv(&self, path: impl AsRef<Path>) -> Result<()> {
        write_atomic(path.as_ref(), self.to_csv_string().as_bytes())
    }
}

/// Write `bytes` to `path` atomically: a temporary sibling file, `fsync`, rename.
/// Creates parent folders.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    }
    let file_name = path
        .file_name()
        .map(|f| f.to_string_lossy().to_string())
        .unwrap_or_default();
    let tmp = path.with_file_name(format!(".{file_name}.tmp{}", std::process::id()));
    {
        let mut f = std::fs::File::create(&tmp).map_err(|e| Error::io(&tmp, e))?;
        f.write_all(bytes).map_err(|e| Error::io(&tmp, e))?;
        f.sync_all().map_err(|e| Error::io(&tmp, e))?;
    }
    std::fs::rename(&tmp, path).map_err(|e| Error::io(path, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_roundtrip_is_exact() {
        let t: Vec<f64> = (0..50).map(|i| i as f64 * 0.1).collect();
        let x: Vec<f64> = t.iter().map(|v| (v * 1.3).sin() / 3.0).collect();
        let ts = TimeSeries::new(t, vec![("x1".into(), x)]).unwrap();
        let back = TimeSeries::from_csv_str(&ts.to_csv_string()).unwrap();
        assert_eq!(ts, back);
    }

    #[test]
    fn csv_errors_name_the_line() {
        let cases = [
            ("t,x1\n0,1\n1\n", "line 3"),
            ("t,x1\n0,1\n1,nan\n", "line 3"),
            ("t,x1\n0,1\n0,2\n", "line 3"),
            ("t,x1\n1,1\n0.5,2\n", "line 3"),
            ("t,x1\n0,abc\n", "line 2"),
            ("x1\n0\n", "header"),
            ("", "empty"),
        ];
        for (text, needle) in cases {
            let e = TimeSeries::from_csv_str(text).unwrap_err().to_string();
            assert!(e.contains(needle), "{text:?}: {e}");
        }
    }

    #[test]
    fn validation() {
        assert!(TimeSeries::new(vec![0.0, 0.0], vec![("x".into(), vec![1.0, 2.0])]).is_err());
        assert!(TimeSeries::new(vec![0.0, 1.0], vec![("x".into(), vec![1.0])]).is_err());
        assert!(TimeSeries::new(vec![0.0, 1.0], vec![("x".into(), vec![1.0, f64::NAN])]).is_err());
        let ts =
            TimeSeries::new(vec![0.0, 1.0, 3.0], vec![("x".into(), vec![1.0, 2.0, 3.0])]).unwrap();
        assert_eq!(ts.uniform_step(1e-9), None);
        assert!(ts
            .require("y")
            .unwrap_err()
            .to_string()
            .contains("one of: x"));
    }
}
