//! Sampled time series: `t` and one or more named columns (for example `x1`,
//! `x20`), with CSV input/output and validation.
//!
//! CSV form: a header line `t,name1,name2,...` then one row per sample. Times
//! must be finite and strictly increasing (uniform or not); values finite.
//! Reading accepts what data loggers and pandas write (see
//! [`TimeSeries::from_csv_str`]). Files are written atomically through
//! [`crate::io::write_atomic`], so a reader never sees half a file and a device
//! or FIFO is never replaced.
//!
//! ```
//! use springmass::series::TimeSeries;
//! let ts = TimeSeries::new(vec![0.0, 0.5, 1.0], vec![("x1".into(), vec![0.0, 0.4, 0.6])])?;
//! assert_eq!(ts.column("x1").unwrap()[1], 0.4);
//! assert_eq!(ts.uniform_step(1e-12), Some(0.5));
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::error::{Error, Result};
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
    units: Vec<Option<String>>,
    time_unit: Option<String>,
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
            units: vec![None; names.len()],
            names,
            columns: cols,
            time_unit: None,
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
    /// A column by name (or by the header's text with its unit, `x1 [m]`).
    pub fn column(&self, name: &str) -> Option<&[f64]> {
        self.position_of(name).map(|i| self.columns[i].as_slice())
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

    /// Parse CSV text.
    ///
    /// Accepted forms (read with the `csv` crate):
    /// * delimiter `,`, `;` or tab, sniffed from the header line (with `;`, a
    ///   decimal comma `0,5` is read as `0.5`);
    /// * quoted fields and headers (`"t","x1"`), a UTF-8 byte-order mark;
    /// * units in headers: `time [s]` or `time (s)` is column `time` with unit
    ///   `s` ([`TimeSeries::unit`], [`TimeSeries::time_unit`]);
    /// * pandas' index column: an unnamed (or `Unnamed: 0`) first column is
    ///   dropped when another column is named `t` or `time`, and is the time
    ///   otherwise (a series indexed by time);
    /// * comment lines starting with `#`, blank lines, trailing empty fields
    ///   (`t,x1,` or a trailing delimiter on every row).
    ///
    /// The time column is the first one named `t` or `time` (any case), else
    /// the first column; every other column is a value column.
    ///
    /// ```
    /// use springmass::series::TimeSeries;
    /// let ts = TimeSeries::from_csv_str(",time [s],x1 [m]\n0,0.0,1.5\n1,0.5,2.5\n")?;
    /// assert_eq!(ts.names(), ["x1"]);
    /// assert_eq!(ts.unit("x1"), Some("m"));
    /// assert_eq!(ts.time_unit(), Some("s"));
    /// let ts = TimeSeries::from_csv_str("t;x1\n0;0,5\n1;1,5\n")?;
    /// assert_eq!(ts.column("x1").unwrap(), [0.5, 1.5]);
    /// # Ok::<(), springmass::Error>(())
    /// ```
    ///
    /// # Errors
    /// [`Error::Parse`] naming the row (1-based data row), the line of the
    /// text and the column (name and 1-based position in the file) for a
    /// missing header, a missing or empty field, a number that does not parse
    /// or is NaN/inf, and unsorted or duplicate times.
    pub fn from_csv_str(text: &str) -> Result<TimeSeries> {
        let (mut rdr, delim) = lab_csv_reader(text);
        let mut records = rdr.records();
        let layout = Layout::from_header(&mut records, delim)?;
        let decimal_comma = delim == b';';
        let mut t: Vec<f64> = Vec::new();
        let mut values: Vec<Vec<f64>> = vec![Vec::new(); layout.cols.len()];
        let mut vals = Vec::with_capacity(layout.used.len());
        let mut row = 0usize;
        for rec in records {
            let rec = rec.map_err(|e| csv_error(&e))?;
            if rec.iter().all(str::is_empty) && rec.len() <= 1 {
                continue;
            }
            row += 1;
            layout.check_fields(&rec, row, delim)?;
            vals.clear();
            for (name, c) in &layout.used {
                let f = rec.get(*c).unwrap_or("");
                let err = |reason: String| {
                    Error::parse(at_cell(&rec, row, name, *c), raw_row(&rec, delim), reason)
                };
                if f.is_empty() {
                    return Err(err("empty field".into()));
                }
                let v = parse_number(f, decimal_comma)
                    .ok_or_else(|| err(format!("{:?} is not a number", clip(f))))?;
                if !v.is_finite() {
                    return Err(err(format!("{v}: values must be finite")));
                }
                vals.push(v);
            }
            if let Some(&prev) = t.last() {
                if vals[0] <= prev {
                    let (name, c) = &layout.used[0];
                    return Err(Error::parse(
                        at_cell(&rec, row, name, *c),
                        raw_row(&rec, delim),
                        format!("time {} is not greater than the previous time {prev}: times must be sorted and distinct", vals[0]),
                    ));
                }
            }
            t.push(vals[0]);
            for (col, v) in values.iter_mut().zip(&vals[1..]) {
                col.push(*v);
            }
        }
        if t.is_empty() {
            return Err(Error::parse(
                "CSV",
                layout.header_text,
                "no data rows after the header",
            ));
        }
        let Layout { cols, time, .. } = layout;
        let units: Vec<Option<String>> = cols.iter().map(|c| c.1.clone()).collect();
        let mut ts = TimeSeries::new(t, cols.into_iter().map(|c| c.0).zip(values).collect())?;
        ts.units = units;
        ts.time_unit = time.1;
        Ok(ts)
    }

    /// Read a CSV file (see [`TimeSeries::from_csv_str`]), at most
    /// [`crate::io::max_input_bytes`] bytes (256 MiB by default).
    ///
    /// # Errors
    /// [`Error::Io`] naming the file (missing, unreadable, a directory, above
    /// the cap); the errors of [`TimeSeries::from_csv_str`] prefixed with the file.
    pub fn read_csv(path: impl AsRef<Path>) -> Result<TimeSeries> {
        let path = path.as_ref();
        crate::io::parse_file(path, TimeSeries::from_csv_str)
    }

    /// The unit of a value column, if its header gave one (`x1 [m]`).
    pub fn unit(&self, name: &str) -> Option<&str> {
        let i = self.names.iter().position(|n| n == name)?;
        self.units.get(i)?.as_deref()
    }

    /// Set the units of the value columns (one per column, in order) and
    /// of the time column ([`crate::units::record_in_si`]).
    pub(crate) fn set_units(&mut self, units: Vec<Option<String>>, time_unit: Option<String>) {
        debug_assert_eq!(units.len(), self.names.len());
        self.units = units;
        self.time_unit = time_unit;
    }

    /// The unit of the time column, if its header gave one (`time [s]`).
    pub fn time_unit(&self) -> Option<&str> {
        self.time_unit.as_deref()
    }

    /// A value column by name (also as the header wrote it with its unit,
    /// `x1 [m]`), or else by its 1-based number among the value columns (`1`
    /// is the first column after the time).
    ///
    /// ```
    /// use springmass::series::TimeSeries;
    /// let ts = TimeSeries::from_csv_str("t,a,b\n0,1,2\n1,3,4\n")?;
    /// assert_eq!(ts.select("b")?.0, "b");
    /// assert_eq!(ts.select("1")?.0, "a");
    /// assert!(ts.select("3").is_err());
    /// # Ok::<(), springmass::Error>(())
    /// ```
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] listing the columns present.
    pub fn select(&self, key: &str) -> Result<(&str, &[f64])> {
        let i = match self.position_of(key) {
            Some(i) => Some(i),
            None => key
                .trim()
                .parse::<usize>()
                .ok()
                .filter(|&k| (1..=self.names.len()).contains(&k))
                .map(|k| k - 1),
        };
        match i {
            Some(i) => Ok((&self.names[i], &self.columns[i])),
            None => Err(Error::invalid(
                "column",
                key,
                format!(
                    "a name (one of: {}) or a number 1..={}",
                    self.names.join(", "),
                    self.names.len()
                ),
            )),
        }
    }

    /// The index of a value column by its name, or by the header's full text
    /// with its unit (`x1 [m]` or `x1 (m)` for column `x1` of unit `m`).
    fn position_of(&self, key: &str) -> Option<usize> {
        if let Some(i) = self.names.iter().position(|n| n == key) {
            return Some(i);
        }
        let (name, unit) = split_unit(key);
        let i = self.names.iter().position(|n| *n == name)?;
        (unit.is_some() && self.units[i] == unit).then_some(i)
    }

    /// CSV text with 17 significant digits (round-trips `f64`).
    pub fn to_csv_string(&self) -> String {
        let mut out = String::with_capacity(self.t.len() * 24 * (1 + self.columns.len()));
        out.push('t');
        if let Some(u) = &self.time_unit {
            out.push_str(&format!(" [{u}]"));
        }
        for (n, u) in self.names.iter().zip(&self.units) {
            out.push(',');
            out.push_str(n);
            if let Some(u) = u {
                out.push_str(&format!(" [{u}]"));
            }
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

/// Write `bytes` to `path` atomically; see [`crate::io::write_atomic`]
/// (kept here for existing callers): refuses directories, devices, FIFOs and
/// sockets, follows symbolic links to their target.
///
/// # Errors
/// As [`crate::io::write_atomic`].
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    crate::io::write_atomic(path, bytes)
}

/// The bytes a [`lab_csv_reader`] reads.
pub(crate) type LabCsv<'a> = std::io::Cursor<std::borrow::Cow<'a, [u8]>>;

/// A CSV reader over `text` as a lab writes it: a byte-order mark dropped,
/// `#` comment lines blanked (line numbers stay), the delimiter sniffed
/// (`,`, `;` or tab), no header handling, ragged rows allowed, fields
/// trimmed. Returns the reader and the delimiter.
pub(crate) fn lab_csv_reader(
    text: &str,
) -> (csv::Reader<std::io::Cursor<std::borrow::Cow<'_, [u8]>>>, u8) {
    use std::borrow::Cow;
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let text = blank_comment_lines(text);
    let delim = sniff_delimiter(&text);
    let bytes: Cow<'_, [u8]> = match text {
        Cow::Borrowed(t) => Cow::Borrowed(t.as_bytes()),
        Cow::Owned(t) => Cow::Owned(t.into_bytes()),
    };
    let rdr = csv::ReaderBuilder::new()
        .delimiter(delim)
        .has_headers(false)
        .flexible(true)
        .trim(csv::Trim::All)
        .from_reader(std::io::Cursor::new(bytes));
    (rdr, delim)
}

/// The delimiter of a CSV text: the most frequent of `,`, `;` and tab (outside
/// quotes) on its first line that is neither blank nor a `#` comment.
fn sniff_delimiter(text: &str) -> u8 {
    let line = text
        .lines()
        .find(|l| !l.trim().is_empty() && !l.trim_start().starts_with('#'))
        .unwrap_or("");
    let mut counts = [0usize; 3];
    let mut quoted = false;
    for ch in line.chars() {
        match ch {
            '"' => quoted = !quoted,
            ',' if !quoted => counts[0] += 1,
            ';' if !quoted => counts[1] += 1,
            '\t' if !quoted => counts[2] += 1,
            _ => {}
        }
    }
    let delims = [b',', b';', b'\t'];
    let mut best = 0;
    for i in 1..3 {
        if counts[i] > counts[best] {
            best = i;
        }
    }
    delims[best]
}

fn delim_str(d: u8) -> &'static str {
    match d {
        b';' => ";",
        b'\t' => "\t",
        _ => ",",
    }
}

/// `time [s]` -> (`time`, `s`); `x1 (m)` -> (`x1`, `m`); `x1` -> (`x1`, none).
pub(crate) fn split_unit(h: &str) -> (String, Option<String>) {
    let h = h.trim();
    for (open, close) in [('[', ']'), ('(', ')')] {
        if let Some(body) = h.strip_suffix(close) {
            if let Some(i) = body.rfind(open) {
                let name = body[..i].trim();
                let unit = body[i + 1..].trim();
                if !name.is_empty() {
                    return (
                        name.to_string(),
                        (!unit.is_empty()).then(|| unit.to_string()),
                    );
                }
            }
        }
    }
    (h.to_string(), None)
}

/// The columns a CSV header declares: the time column, the value columns
/// (name, unit, 0-based file column) and the file columns read.
struct Layout {
    time: (String, Option<String>, usize),
    cols: Vec<(String, Option<String>, usize)>,
    /// (name, file column) of the time and then each value column.
    used: Vec<(String, usize)>,
    /// Fields a row needs (the last column read, plus one).
    ncol_needed: usize,
    /// Named header fields: a non-empty field beyond them is an error.
    named: usize,
    header_text: String,
}

impl Layout {
    /// Read the header record (skipping blank lines) and decide the columns.
    fn from_header(records: &mut csv::StringRecordsIter<LabCsv<'_>>, delim: u8) -> Result<Layout> {
        let header = loop {
            match records.next() {
                None => {
                    return Err(Error::parse(
                        "CSV",
                        "",
                        "empty file; expected a header such as t,x1",
                    ))
                }
                Some(Err(e)) => return Err(csv_error(&e)),
                Some(Ok(r)) if r.iter().all(str::is_empty) && r.len() <= 1 => continue,
                Some(Ok(r)) => break r,
            }
        };
        let hline = header.position().map_or(1, |p| p.line());
        let header_text = clip(&raw_row(&header, delim)).to_string();
        let bad_header = |reason: &str| {
            Error::parse(
                format!("CSV header (line {hline})"),
                header_text.clone(),
                reason.to_string(),
            )
        };
        let mut cols: Vec<(String, Option<String>, usize)> = header
            .iter()
            .enumerate()
            .map(|(i, h)| {
                let (name, unit) = split_unit(h);
                (name, unit, i)
            })
            .collect();
        while cols.last().is_some_and(|c| c.0.is_empty()) {
            cols.pop();
        }
        let named = cols.len();
        if cols.is_empty() {
            return Err(bad_header(
                "the header has no column names; expected e.g. `t,x1`",
            ));
        }
        if header
            .iter()
            .filter(|h| !h.is_empty())
            .all(|h| parse_number(h, delim == b';').is_some())
        {
            return Err(bad_header(
                "the first line holds only numbers: the file has no header; add one such as `t,x1` as its first line",
            ));
        }
        let first_unnamed = cols
            .first()
            .is_some_and(|c| c.0.is_empty() || c.0 == "Unnamed: 0" || c.0 == "index");
        if first_unnamed && cols[1..].iter().any(|c| is_time(&c.0)) {
            cols.remove(0);
        }
        if cols.len() < 2 {
            return Err(bad_header(
                "expected a time column and at least one value column, e.g. `t,x1` (delimiter `,`, `;` or tab)",
            ));
        }
        check_unique_names(&cols).map_err(|r| bad_header(&r))?;
        let ti = cols.iter().position(|c| is_time(&c.0)).unwrap_or(0);
        let time = cols.remove(ti);
        for c in cols.iter_mut() {
            if c.0.is_empty() {
                c.0 = format!("column{}", c.2 + 1);
            }
        }
        let time_name = if time.0.is_empty() {
            "t".to_string()
        } else {
            time.0.clone()
        };
        let used: Vec<(String, usize)> = std::iter::once((time_name, time.2))
            .chain(cols.iter().map(|c| (c.0.clone(), c.2)))
            .collect();
        let ncol_needed = used.iter().map(|u| u.1).max().unwrap_or(0) + 1;
        Ok(Layout {
            time,
            cols,
            used,
            ncol_needed,
            named,
            header_text,
        })
    }

    /// A row must have every column read and no value beyond the header's
    /// named columns (trailing empty fields are fine).
    fn check_fields(&self, rec: &csv::StringRecord, row: usize, delim: u8) -> Result<()> {
        let mut n_fields = rec.len();
        while n_fields > 0 && rec.get(n_fields - 1) == Some("") {
            n_fields -= 1;
        }
        if n_fields > self.named {
            let c = n_fields - 1;
            return Err(Error::parse(
                format!("CSV row {row} (line {}), column {}", line_of(rec), c + 1),
                raw_row(rec, delim),
                format!(
                    "extra field {:?}: the header names {} columns, this row has {n_fields}",
                    clip(rec.get(c).unwrap_or("")),
                    self.named
                ),
            ));
        }
        if n_fields < self.ncol_needed {
            let (name, c) = self
                .used
                .iter()
                .find(|u| u.1 >= n_fields)
                .cloned()
                .unwrap_or_default();
            return Err(Error::parse(
                at_cell(rec, row, &name, c),
                raw_row(rec, delim),
                format!(
                    "missing field: expected {} fields as in the header, found {n_fields}",
                    self.ncol_needed
                ),
            ));
        }
        Ok(())
    }
}

fn is_time(n: &str) -> bool {
    n.eq_ignore_ascii_case("t") || n.eq_ignore_ascii_case("time")
}

/// Column names must be unique, and only one may name the time (`t`, `time`).
fn check_unique_names(cols: &[(String, Option<String>, usize)]) -> std::result::Result<(), String> {
    for (k, b) in cols.iter().enumerate() {
        for a in &cols[..k] {
            let same = !a.0.is_empty() && a.0 == b.0;
            if same || (is_time(&a.0) && is_time(&b.0)) {
                return Err(format!(
                    "columns {} `{}` and {} `{}` have the same name{}: rename one so that the column to read is unambiguous",
                    a.2 + 1,
                    clip(&a.0),
                    b.2 + 1,
                    clip(&b.0),
                    if same { "" } else { " (both name the time)" }
                ));
            }
        }
    }
    Ok(())
}

fn line_of(rec: &csv::StringRecord) -> u64 {
    rec.position().map_or(0, |p| p.line())
}

pub(crate) fn at_cell(rec: &csv::StringRecord, row: usize, name: &str, c: usize) -> String {
    format!(
        "CSV row {row} (line {}), column {} `{}`",
        line_of(rec),
        c + 1,
        clip(name)
    )
}

/// The fields of a record joined again (for an error message).
pub(crate) fn raw_row(rec: &csv::StringRecord, delim: u8) -> String {
    rec.iter().collect::<Vec<_>>().join(delim_str(delim))
}

/// At most 60 characters of a field, for a message.
pub(crate) fn clip(s: &str) -> &str {
    match s.char_indices().nth(60) {
        Some((i, _)) => &s[..i],
        None => s,
    }
}

/// A number, with a decimal comma when the delimiter is `;` (`0,5`).
pub(crate) fn parse_number(f: &str, decimal_comma: bool) -> Option<f64> {
    if decimal_comma && f.contains(',') && !f.contains('.') {
        f.replacen(',', ".", 1).parse::<f64>().ok()
    } else {
        f.parse::<f64>().ok()
    }
}

/// Spreadsheet error values: a cell holding one is data (and not a number),
/// not a comment, although it starts with `#`.
const SPREADSHEET_ERRORS: [&str; 8] = [
    "#N/A", "#VALUE!", "#DIV/0!", "#REF!", "#NAME?", "#NUM!", "#NULL!", "#SPILL!",
];

fn is_comment_line(line: &str) -> bool {
    let l = line.trim_start();
    l.starts_with('#')
        && !SPREADSHEET_ERRORS.iter().any(|e| {
            let code = l
                .get(..e.len())
                .is_some_and(|head| head.eq_ignore_ascii_case(e));
            // the whole cell: followed by a delimiter, a space or the line end
            code && l[e.len()..]
                .chars()
                .next()
                .is_none_or(|c| matches!(c, ',' | ';' | '\t' | ' ' | '\r' | '\n' | '"'))
        })
}

/// `#` comment lines replaced by blank lines (line numbers stay), unless the
/// `#` opens a spreadsheet error value such as `#N/A` (a data row whose time
/// is missing must be reported, not skipped).
fn blank_comment_lines(text: &str) -> std::borrow::Cow<'_, str> {
    if !text.lines().any(is_comment_line) {
        return std::borrow::Cow::Borrowed(text);
    }
    let mut out = String::with_capacity(text.len());
    for line in text.split_inclusive('\n') {
        if is_comment_line(line) {
            out.push('\n');
        } else {
            out.push_str(line);
        }
    }
    std::borrow::Cow::Owned(out)
}

pub(crate) fn csv_error(e: &csv::Error) -> Error {
    let at = e
        .position()
        .map(|p| format!("CSV line {}", p.line()))
        .unwrap_or_else(|| "CSV".to_string());
    Error::parse(at, "", e.to_string())
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

    fn x1(text: &str) -> TimeSeries {
        TimeSeries::from_csv_str(text).unwrap_or_else(|e| panic!("{text:?}: {e}"))
    }

    #[test]
    fn csv_forms_of_loggers_and_pandas() {
        let want_t = [0.0, 0.5];
        let want_x = [1.0, 2.0];
        let forms = [
            ("quoted headers", "\"t\",\"x1\"\n0,1\n0.5,2\n"),
            ("units", "time [s],x1 [m]\n0,1\n0.5,2\n"),
            ("units in parentheses", "Time (s),x1 (m)\n0,1\n0.5,2\n"),
            ("semicolon", "t;x1\n0;1\n0.5;2\n"),
            ("semicolon, decimal comma", "t;x1\n0;1\n0,5;2,0\n"),
            ("tab", "t\tx1\n0\t1\n0.5\t2\n"),
            ("trailing empty fields", "t,x1,\n0,1,\n0.5,2,\n"),
            ("trailing delimiter on rows only", "t,x1\n0,1,\n0.5,2,,\n"),
            ("pandas to_csv()", ",t,x1\n0,0.0,1.0\n1,0.5,2.0\n"),
            (
                "pandas Unnamed: 0",
                "Unnamed: 0,t,x1\n0,0.0,1.0\n1,0.5,2.0\n",
            ),
            ("pandas series indexed by time", ",x1\n0.0,1.0\n0.5,2.0\n"),
            (
                "comments and blank lines",
                "# logger v2\n\nt,x1\n# start\n0,1\n\n0.5,2\n",
            ),
            ("CRLF and BOM", "\u{feff}t,x1\r\n0,1\r\n0.5,2\r\n"),
            (
                "quoted values",
                "\"t\";\"x1\"\n\"0\";\"1\"\n\"0.5\";\"2\"\n",
            ),
            ("time not first", "x1,t\n1,0\n2,0.5\n"),
        ];
        for (what, text) in forms {
            let ts = x1(text);
            assert_eq!(ts.t(), want_t, "{what}");
            assert_eq!(ts.names(), ["x1"], "{what}");
            assert_eq!(ts.column("x1").unwrap(), want_x, "{what}");
        }
        let ts = x1("time [s],x1 [m]\n0,1\n0.5,2\n");
        assert_eq!(ts.time_unit(), Some("s"));
        assert_eq!(ts.unit("x1"), Some("m"));
        // units survive a round trip
        assert_eq!(x1(&ts.to_csv_string()), ts);
        // columns by name or number
        let ts = x1("t,a,b\n0,1,2\n1,3,4\n");
        assert_eq!(ts.select("b").unwrap().1, [2.0, 4.0]);
        assert_eq!(ts.select("2").unwrap().0, "b");
        assert!(ts.select("0").is_err());
        assert!(ts.select("c").unwrap_err().to_string().contains("a, b"));
        // issue 32 item 5: the header's full text, with its unit
        let ts = x1("t [s],x1 [m],x2 (mm)\n0,1,2\n1,3,4\n");
        assert_eq!(ts.select("x1 [m]").unwrap().0, "x1");
        assert_eq!(ts.select("x2 (mm)").unwrap().0, "x2");
        assert!(ts.select("x1 [mm]").is_err());
    }

    #[test]
    fn csv_that_would_change_data_silently_is_refused() {
        // issue 32 item 9: each case names row/line and column
        let cases = [
            ("t,x1\n0,1\n19.25,1,5\n", "row 2 (line 3), column 3"),
            ("t,x1\n0,1\n#N/A,2\n1,3\n", "row 2 (line 3), column 1 `t`"),
            ("t,x1\n0,1\n#VALUE!,2\n", "not a number"),
            ("0,1\n1,2\n2,3\n", "no header"),
            (",\n0,1\n1,2\n", "no column names"),
            ("t,t,x1\n0,1,2\n1,2,3\n", "columns 1 `t` and 2 `t`"),
            ("time,t,x1\n0,1,2\n1,2,3\n", "both name the time"),
            ("t,x1,x1\n0,1,2\n1,2,3\n", "columns 2 `x1` and 3 `x1`"),
        ];
        assert_parse_errors(&cases);
        // comments still work, also right before and after a data row
        let ts = x1("# a, b\nt,x1\n#c\n0,1\n#N/Ao\n#name: v\n1,2\n");
        assert_eq!(ts.t(), [0.0, 1.0]);
    }

    #[test]
    fn a_long_line_is_not_echoed_whole() {
        // issue 32 item 10: a 1 MB field in an error message
        let text = format!("t,x1\n0,{}\n", "9".repeat(1 << 20) + "z");
        let e = TimeSeries::from_csv_str(&text).unwrap_err().to_string();
        assert!(e.len() < 2000, "{} bytes", e.len());
    }

    /// Every text is refused with a parse error whose message holds its needle.
    fn assert_parse_errors(cases: &[(&str, &str)]) {
        for &(text, needle) in cases {
            let e = TimeSeries::from_csv_str(text).unwrap_err();
            assert!(matches!(e, Error::Parse { .. }), "{text:?}: {e}");
            assert!(e.to_string().contains(needle), "{text:?}: {e}");
        }
    }

    #[test]
    fn malformed_csv_names_row_and_column() {
        let cases = [
            ("t,x1\n0,1\n1,\n", "row 2 (line 3), column 2 `x1`"),
            ("t,x1,x2\n0,1,2\n1,2\n", "column 3 `x2`"),
            ("t;x1\n0;1\n1;abc\n", "row 2 (line 3), column 2 `x1`"),
            ("# c\nt,x1\n0,1\n1,inf\n", "row 2 (line 4), column 2 `x1`"),
            ("t,x1\n0,1\n0,2\n", "row 2 (line 3), column 1 `t`"),
            ("t\tx1\n0\t1\n\"1\t2\n", "line"),
            ("t,x1\n", "no data rows"),
            ("# only a comment\n", "empty"),
        ];
        assert_parse_errors(&cases);
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
