//! The report of a finished study: `summary.csv` (one row per case),
//! `report.md` (aggregated tables, plots, failures, the case list) and the
//! SVG plots chosen by `[[report.plot]]`.
//!
//! Everything is computed from the records sorted by case id, so the files
//! depend only on the records, never on the order in which cases finished,
//! the thread count or the sharding. Nothing time-dependent (dates, run
//! durations) is written.

use super::config::{Aggregate, HeatmapSpec, PlotSpec, TableSpec, TraceSpec};
use super::records::{Counts, Record};
use super::sweep::{format_float, MAIN_PART, PART_COLUMN};
use super::Study;
use crate::error::{Error, Result};
use crate::plot::{Heatmap, Line, LinePlot};
use crate::series::write_atomic;
use std::path::Path;

/// File name of the Markdown report.
pub const REPORT: &str = "report.md";
/// File name of the per-case table.
pub const SUMMARY: &str = "summary.csv";

/// The columns of a study's tables: axis columns, then metric columns.
struct Columns {
    axes: Vec<String>,
    metrics: Vec<String>,
}

/// Columns of `summary.csv` before the axes and between axes and metrics.
const FIXED_COLUMNS: &[&str] = &["id", "repeat", "seed", "status", "error"];

impl Columns {
    /// The header of metric `m`: its name, or `metric_<name>` when an axis
    /// (or a fixed column) has that name already (the forward kind's metric
    /// `n` beside an axis named `n`), so that no column appears twice.
    fn metric_header(&self, m: &str) -> String {
        if self.axes.iter().any(|a| a == m) || FIXED_COLUMNS.contains(&m) {
            format!("metric_{m}")
        } else {
            m.to_string()
        }
    }
}

fn columns(study: &Study) -> Columns {
    columns_of(study, None)
}

/// The columns of the cases of `part` (every part for `None`): the axes
/// of those parts and the metrics of their kinds.
fn columns_of(study: &Study, part: Option<&str>) -> Columns {
    let f = &study.file;
    let timings = f.study.timings;
    let axes: Vec<String> = match part {
        None => f.axis_columns(),
        Some(p) => {
            let sweep = if p == MAIN_PART {
                Some(&f.sweep)
            } else {
                f.part.iter().find(|x| x.name == p).map(|x| &x.sweep)
            };
            sweep
                .into_iter()
                .flatten()
                .map(|a| a.column().to_string())
                .collect()
        }
    };
    let mut metrics: Vec<String> = Vec::new();
    for k in f.kinds_of(part) {
        for m in k.metrics() {
            if (timings || !m.0.starts_with("t_")) && !metrics.iter().any(|x| x == m.0) {
                metrics.push(m.0.to_string());
            }
        }
    }
    Columns { axes, metrics }
}

/// The records of `part` (all of them for `None`), in order.
fn of_part(records: &[Record], part: Option<&str>) -> Vec<Record> {
    records
        .iter()
        .filter(|r| in_part(r, part))
        .cloned()
        .collect()
}

/// Is the record one of part `part` (any part for `None`)?
fn in_part(r: &Record, part: Option<&str>) -> bool {
    let Some(p) = part else {
        return true;
    };
    match r.params.first() {
        Some(x) if x.column == PART_COLUMN => x.label == p,
        _ => p == MAIN_PART,
    }
}

/// The value of a metric (or timing) of a record as a number (`true` = 1).
pub fn metric(r: &Record, name: &str) -> Option<f64> {
    let v = r.metrics.get(name).or_else(|| r.timings.get(name))?;
    match v {
        serde_json::Value::Number(n) => n.as_f64(),
        serde_json::Value::Bool(b) => Some(if *b { 1.0 } else { 0.0 }),
        _ => None,
    }
}

fn metric_text(r: &Record, name: &str) -> String {
    match r.metrics.get(name).or_else(|| r.timings.get(name)) {
        None | Some(serde_json::Value::Null) => String::new(),
        Some(serde_json::Value::String(s)) => s.clone(),
        Some(v) => v.to_string(),
    }
}

/// The label of an axis column (`repeat` included) in a record.
fn axis_label(r: &Record, column: &str) -> String {
    if column == "repeat" {
        return r.repeat.to_string();
    }
    r.params
        .iter()
        .find(|p| p.column == column)
        .map(|p| p.label.clone())
        .unwrap_or_default()
}

fn axis_number(r: &Record, column: &str) -> Option<f64> {
    if column == "repeat" {
        return Some(r.repeat as f64);
    }
    let p = r.params.iter().find(|p| p.column == column)?;
    p.value.as_f64().or_else(|| p.label.parse().ok())
}

/// Reduce `values` with `agg` (`None` when there is nothing to reduce).
pub fn aggregate(agg: Aggregate, values: &[f64]) -> Option<f64> {
    let v: Vec<f64> = values.iter().copied().filter(|x| !x.is_nan()).collect();
    if agg == Aggregate::Count {
        return Some(v.len() as f64);
    }
    if v.is_empty() {
        return None;
    }
    Some(match agg {
        Aggregate::Mean => v.iter().sum::<f64>() / v.len() as f64,
        Aggregate::Min => v.iter().copied().fold(f64::INFINITY, f64::min),
        Aggregate::Max => v.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        Aggregate::Rate => v.iter().filter(|&&x| x != 0.0).count() as f64 / v.len() as f64,
        Aggregate::Median => {
            let mut s = v.clone();
            s.sort_by(f64::total_cmp);
            let m = s.len() / 2;
            if s.len() % 2 == 1 {
                s[m]
            } else {
                0.5 * (s[m - 1] + s[m])
            }
        }
        Aggregate::Count => unreachable!(),
    })
}

/// A number for a Markdown table: integers as integers, four significant
/// digits otherwise.
pub fn fmt_num(x: f64) -> String {
    if x.is_nan() {
        return "NaN".into();
    }
    if x.is_infinite() {
        return if x > 0.0 { "inf" } else { "-inf" }.into();
    }
    if x == x.trunc() && x.abs() < 1e9 {
        return format_float(x);
    }
    let a = x.abs();
    if (1e-3..1e5).contains(&a) {
        let decimals = (3 - a.log10().floor() as i32).clamp(0, 6) as usize;
        format!("{x:.decimals$}")
    } else {
        format!("{x:.3e}")
    }
}

/// The `summary.csv` text: one row per record (sorted by id).
///
/// # Errors
/// None in practice (writing CSV to memory).
pub fn summary_csv(study: &Study, records: &[Record]) -> Result<String> {
    let cols = columns(study);
    let mut w = csv::Writer::from_writer(Vec::new());
    let mut header: Vec<String> = vec!["id".into(), "repeat".into(), "seed".into()];
    header.extend(cols.axes.iter().cloned());
    header.extend(["status".to_string(), "error".to_string()]);
    header.extend(cols.metrics.iter().map(|m| cols.metric_header(m)));
    let csv_err = |e: csv::Error| Error::invalid("summary.csv", "?", e.to_string());
    w.write_record(&header).map_err(csv_err)?;
    for r in records {
        let mut row: Vec<String> = vec![r.id.clone(), r.repeat.to_string(), r.seed.to_string()];
        row.extend(cols.axes.iter().map(|a| axis_label(r, a)));
        row.push(r.status.clone());
        row.push(r.error.clone().unwrap_or_default());
        row.extend(cols.metrics.iter().map(|m| metric_text(r, m)));
        w.write_record(&row).map_err(csv_err)?;
    }
    let bytes = w
        .into_inner()
        .map_err(|e| Error::invalid("summary.csv", "?", e.to_string()))?;
    Ok(String::from_utf8_lossy(&bytes).into_owned())
}

/// Group records by the labels of `rows` columns, in order of first appearance.
fn group<'a>(records: &'a [Record], rows: &[String]) -> Vec<(Vec<String>, Vec<&'a Record>)> {
    let mut out: Vec<(Vec<String>, Vec<&Record>)> = Vec::new();
    for r in records {
        let key: Vec<String> = rows.iter().map(|c| axis_label(r, c)).collect();
        match out.iter_mut().find(|(k, _)| *k == key) {
            Some((_, v)) => v.push(r),
            None => out.push((key, vec![r])),
        }
    }
    out
}

fn md_escape(s: &str) -> String {
    s.replace('|', "\\|").replace('\n', " ")
}

fn table_md(study: &Study, records: &[Record], spec: &TableSpec) -> String {
    let cols = columns_of(study, spec.part.as_deref());
    let records = &of_part(records, spec.part.as_deref())[..];
    let rows = spec.rows.clone().unwrap_or_else(|| cols.axes.clone());
    let metrics = spec.metrics.clone().unwrap_or_else(|| cols.metrics.clone());
    let title = spec.title.clone().unwrap_or_else(|| {
        if rows.is_empty() {
            format!("{} over all cases", spec.aggregate.name())
        } else {
            format!("{} by {}", spec.aggregate.name(), rows.join(", "))
        }
    });
    let mut s = format!("## {}\n\n", md_escape(&title));
    let mut header: Vec<String> = rows.iter().map(|r| format!("`{r}`")).collect();
    header.push("cases".into());
    header.push("errors".into());
    header.extend(
        metrics
            .iter()
            .map(|m| format!("{} `{m}`", spec.aggregate.name())),
    );
    s.push_str(&format!("| {} |\n", header.join(" | ")));
    s.push_str(&format!("|{}\n", "---|".repeat(header.len())));
    for (key, recs) in group(records, &rows) {
        let mut cells: Vec<String> = key.iter().map(|k| md_escape(k)).collect();
        cells.push(recs.len().to_string());
        cells.push(recs.iter().filter(|r| !r.ok()).count().to_string());
        for m in &metrics {
            let vals: Vec<f64> = recs
                .iter()
                .filter(|r| r.ok())
                .filter_map(|r| metric(r, m))
                .collect();
            cells.push(aggregate(spec.aggregate, &vals).map_or("–".into(), fmt_num));
        }
        s.push_str(&format!("| {} |\n", cells.join(" | ")));
    }
    s.push('\n');
    s
}

/// File name of a plot (sanitised).
pub fn plot_file(spec: &PlotSpec) -> String {
    sanitize(
        spec.file
            .clone()
            .unwrap_or_else(|| format!("{}-vs-{}.svg", spec.y, spec.x)),
    )
}

/// Characters outside `A-Za-z0-9._-` become `_`; no leading dot; `.svg` appended if missing.
fn sanitize(raw: String) -> String {
    let mut f: String = raw
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || "._-".contains(c) {
                c
            } else {
                '_'
            }
        })
        .collect();
    if f.starts_with('.') {
        f.insert(0, '_');
    }
    if !f.ends_with(".svg") {
        f.push_str(".svg");
    }
    f
}

/// The unit of a column or metric, for axis labels: seconds for timings
/// (`t_*`, except the ratio `t_speedup`), bits for a precision in bits; `None` for dimensionless
/// quantities (the model's masses, springs and times are in units of the
/// chain's own `m = k = 1`).
fn unit_of(name: &str) -> Option<&'static str> {
    if name.starts_with("t_") && !name.contains("speedup") && !name.contains("ratio") {
        Some("s")
    } else if name == "bits" {
        Some("bits")
    } else {
        None
    }
}

/// `name (unit)` or `name`.
fn with_unit(text: String, name: &str) -> String {
    match unit_of(name) {
        Some(u) => format!("{text} ({u})"),
        None => text,
    }
}

/// The categories of a categorical axis column, in case order: `Some` when
/// a value of the column is not a number (a table such as a `chain` swept
/// as `system`, a string, a boolean), `None` for a numeric axis.
fn categories(records: &[Record], column: &str) -> Option<Vec<String>> {
    if column == "repeat" {
        return None;
    }
    let categorical = records.iter().any(|r| {
        r.params
            .iter()
            .any(|p| p.column == column && p.value.as_f64().is_none())
    });
    if !categorical {
        return None;
    }
    let mut names: Vec<String> = Vec::new();
    for r in records {
        let l = axis_label(r, column);
        if !names.contains(&l) {
            names.push(l);
        }
    }
    Some(names)
}

/// The 95% Wilson score interval of a rate: `k` successes in `n` runs
/// (`[0, 1]` for no runs). Unlike `p +- 1.96 sqrt(p (1 - p) / n)` it stays
/// inside `[0, 1]` and is not empty at a rate of 0 or 1.
pub fn wilson_interval(k: f64, n: f64) -> (f64, f64) {
    if n <= 0.0 {
        return (0.0, 1.0);
    }
    let z = 1.959_963_984_540_054;
    let p = (k / n).clamp(0.0, 1.0);
    let z2n = z * z / n;
    let centre = (p + z2n / 2.0) / (1.0 + z2n);
    let half = z * (p * (1.0 - p) / n + z2n / (4.0 * n)).sqrt() / (1.0 + z2n);
    ((centre - half).max(0.0), (centre + half).min(1.0))
}

/// Build the chart of one plot spec: a categorical x axis (points side by
/// side, no joining lines) when the x column is not numeric, integer ticks
/// when every x is an integer, `[0, 1]` for a rate, small multiples beyond
/// six series (see [`crate::plot`]).
///
/// # Errors
/// [`Error::InvalidParameter`] when a numeric x axis has a value that is
/// not a number.
pub fn plot_chart(records: &[Record], spec: &PlotSpec) -> Result<LinePlot> {
    let records = &of_part(records, spec.part.as_deref())[..];
    let rate = spec.aggregate == Aggregate::Rate;
    let mut title = spec
        .title
        .clone()
        .unwrap_or_else(|| format!("{} of {} against {}", spec.aggregate.name(), spec.y, spec.x));
    if rate {
        // in the title, not the y label: a label longer than a panel's
        // height runs into the next row's
        title.push_str(" (bars: 95% Wilson interval)");
    }
    let cats = categories(records, &spec.x);
    let y_label = if rate {
        // a reader's label, not the metric's name: `rate positions_ok` was
        // read as a number of positions
        format!("fraction with {}", spec.y.replace('_', " "))
    } else {
        format!("{} {}", spec.aggregate.name(), spec.y)
    };
    let mut chart = LinePlot::new(
        title,
        with_unit(spec.x.clone(), &spec.x),
        with_unit(y_label, &spec.y),
    )
    .log_x(spec.logx && cats.is_none())
    .log_y(spec.logy);
    if spec.aggregate == Aggregate::Rate {
        chart = chart.rate();
    }
    let mut all_integer = true;
    let series: Vec<String> = spec.series.iter().cloned().collect();
    let groups = group(records, &series);
    let m = groups.len();
    for (gi, (key, recs)) in groups.into_iter().enumerate() {
        let mut xs: Vec<(f64, Vec<f64>)> = Vec::new();
        for r in recs.iter().filter(|r| r.ok()) {
            let number = match &cats {
                Some(names) => {
                    let l = axis_label(r, &spec.x);
                    names.iter().position(|n| *n == l).map(|i| i as f64)
                }
                None => axis_number(r, &spec.x),
            };
            let x = number.ok_or_else(|| {
                Error::invalid(
                    format!("report.plot x = {:?}", spec.x),
                    axis_label(r, &spec.x),
                    "numeric axis values",
                )
            })?;
            let Some(y) = metric(r, &spec.y) else {
                continue;
            };
            match xs.iter_mut().find(|(xx, _)| *xx == x) {
                Some((_, v)) => v.push(y),
                None => xs.push((x, vec![y])),
            }
        }
        let mut rows: Vec<(f64, f64, (f64, f64))> = xs
            .into_iter()
            .filter_map(|(x, v)| {
                let y = aggregate(spec.aggregate, &v)?;
                let runs = v.iter().filter(|x| !x.is_nan()).count() as f64;
                Some((x, y, wilson_interval(y * runs, runs)))
            })
            .collect();
        rows.sort_by(|a, b| a.0.total_cmp(&b.0));
        all_integer &= rows.iter().all(|p| p.0.fract() == 0.0);
        // rates of several series on a log axis, side by side (lines at 1
        // would hide each other): 0.02 decades apart
        let shift = if rate && m > 1 && spec.logx && cats.is_none() {
            10f64.powf(0.02 * (gi as f64 - (m as f64 - 1.0) / 2.0))
        } else {
            1.0
        };
        let pts: Vec<(f64, f64)> = rows.iter().map(|r| (r.0 * shift, r.1)).collect();
        let label = match &spec.series {
            Some(s) => format!("{s} = {}", key.join(", ")),
            None => String::new(),
        };
        let mut line = Line::new(label, pts.clone());
        if rate {
            line = line.errors(rows.iter().map(|r| r.2).collect());
        }
        chart = chart.line(if pts.len() == 1 { line.markers() } else { line });
    }
    Ok(match cats {
        Some(names) => chart.categories(names),
        None => chart.integer_x(all_integer && !spec.logx),
    })
}

/// File name of a heatmap (sanitised).
pub fn heatmap_file(spec: &HeatmapSpec) -> String {
    sanitize(
        spec.file
            .clone()
            .unwrap_or_else(|| format!("{}-over-{}-{}.svg", spec.z, spec.x, spec.y)),
    )
}

/// Build the heatmap of one spec.
///
/// # Errors
/// [`Error::InvalidParameter`] when an axis has non-numeric values.
pub fn heatmap_chart(records: &[Record], spec: &HeatmapSpec) -> Result<Heatmap> {
    let records = &of_part(records, spec.part.as_deref())[..];
    let number = |r: &Record, col: &str| {
        axis_number(r, col).ok_or_else(|| {
            Error::invalid(
                format!("report.heatmap axis {col:?}"),
                axis_label(r, col),
                "numeric axis values",
            )
        })
    };
    let mut xs: Vec<f64> = Vec::new();
    let mut ys: Vec<f64> = Vec::new();
    for r in records {
        let (x, y) = (number(r, &spec.x)?, number(r, &spec.y)?);
        if !xs.contains(&x) {
            xs.push(x);
        }
        if !ys.contains(&y) {
            ys.push(y);
        }
    }
    xs.sort_by(f64::total_cmp);
    ys.sort_by(f64::total_cmp);
    let mut cells: Vec<Vec<Vec<f64>>> = vec![vec![Vec::new(); xs.len()]; ys.len()];
    for r in records.iter().filter(|r| r.ok()) {
        let (x, y) = (number(r, &spec.x)?, number(r, &spec.y)?);
        let ix = xs.iter().position(|&v| v == x).unwrap_or(0);
        let iy = ys.iter().position(|&v| v == y).unwrap_or(0);
        if let Some(z) = metric(r, &spec.z) {
            cells[iy][ix].push(z);
        }
    }
    let z: Vec<Vec<f64>> = cells
        .iter()
        .map(|row| {
            row.iter()
                .map(|c| aggregate(spec.aggregate, c).unwrap_or(f64::NAN))
                .collect()
        })
        .collect();
    Ok(Heatmap {
        title: spec
            .title
            .clone()
            .unwrap_or_else(|| format!("{} of {}", spec.aggregate.name(), spec.z)),
        x_label: with_unit(spec.x.clone(), &spec.x),
        y_label: with_unit(spec.y.clone(), &spec.y),
        x: xs,
        y: ys,
        z,
        log_z: spec.log_z,
        mark: None,
    })
}

/// File name of a trace plot (sanitised).
pub fn trace_file(spec: &TraceSpec) -> String {
    sanitize(spec.file.clone().unwrap_or_else(|| match &spec.series {
        Some(s) if !s.is_empty() => format!("trace-{}.svg", s.join("-")),
        _ => "trace.svg".into(),
    }))
}

/// Does a record pass a trace spec's `filter`?
fn passes(r: &Record, filter: &toml::Table) -> bool {
    filter.iter().all(|(col, want)| {
        let label = axis_label(r, col);
        match want {
            toml::Value::String(s) => *s == label,
            toml::Value::Array(a) => a.iter().any(|v| v.as_str() == Some(label.as_str())),
            _ => false,
        }
    })
}

/// Build the chart of one trace spec: best residual so far against
/// evaluations, one line per group of ok cases with a trace. The cases of a
/// group are step functions; at every evaluation count where one of them
/// improves, the line is `aggregate` over the cases that have started.
///
/// # Errors
/// [`Error::InvalidParameter`] when no selected case recorded a trace.
pub fn trace_chart(records: &[Record], spec: &TraceSpec) -> Result<LinePlot> {
    let records = &of_part(records, spec.part.as_deref())[..];
    let title = spec
        .title
        .clone()
        .unwrap_or_else(|| "best residual against evaluations".into());
    let mut chart = LinePlot::new(
        title,
        "residual evaluations",
        format!("{} best residual so far", spec.aggregate.name()),
    )
    .log_x(spec.logx)
    .log_y(spec.logy)
    .integer_x(!spec.logx);
    let selected: Vec<Record> = records
        .iter()
        .filter(|r| r.ok() && !r.trace.is_empty() && passes(r, &spec.filter))
        .cloned()
        .collect();
    if selected.is_empty() {
        return Err(Error::invalid(
            "report.trace",
            "no trace",
            "cases with a recorded trace (search.trace = true, a stochastic search.method; enumeration records none)",
        ));
    }
    let per_case = spec.series.is_none();
    let series: Vec<String> = spec.series.clone().unwrap_or_default();
    let groups: Vec<(String, Vec<&Record>)> = if per_case {
        selected
            .iter()
            .map(|r| {
                let params: Vec<String> = r.params.iter().map(|p| p.label.clone()).collect();
                (format!("{} {}", r.id, params.join(", ")), vec![r])
            })
            .collect()
    } else {
        group(&selected, &series)
            .into_iter()
            .map(|(key, recs)| {
                let label = series
                    .iter()
                    .zip(&key)
                    .map(|(c, v)| format!("{c} = {v}"))
                    .collect::<Vec<_>>()
                    .join(", ");
                (label, recs)
            })
            .collect()
    };
    for (label, recs) in groups {
        let mut xs: Vec<f64> = recs
            .iter()
            .flat_map(|r| r.trace.iter().map(|p| p[0]))
            .collect();
        xs.sort_by(f64::total_cmp);
        xs.dedup();
        let pts: Vec<(f64, f64)> = xs
            .iter()
            .filter_map(|&x| {
                // each case's best residual at x: its last point at or before x
                let vals: Vec<f64> = recs
                    .iter()
                    .filter_map(|r| r.trace.iter().rev().find(|p| p[0] <= x).map(|p| p[1]))
                    .collect();
                aggregate(spec.aggregate, &vals).map(|y| (x, y))
            })
            .collect();
        let n = recs.len();
        let label = if per_case || n == 1 {
            label
        } else {
            format!("{label} ({n} cases)")
        };
        let line = Line::new(label, pts.clone());
        chart = chart.line(if pts.len() == 1 { line.markers() } else { line });
    }
    Ok(chart)
}

/// The `report.md` text; also returns the plots to write `(file, svg)`.
fn report_md(study: &Study, records: &[Record]) -> (String, Vec<(String, String)>) {
    let mut s = header_md(study, records);
    for t in &report_tables(study) {
        s.push_str(&table_md(study, records, t));
    }
    let plots = plots_md(study, records, &mut s);
    failed_md(records, &mut s);
    case_plots_md(records, &mut s);
    cases_md(study, records, &mut s);
    (s, plots)
}

/// The title, the description and the table of the study's facts (kind,
/// cases, seed, repeats, axes, parts, hash), with the note on the files.
fn header_md(study: &Study, records: &[Record]) -> String {
    let f = &study.file;
    let counts = Counts::of(records);
    let mut s = format!("# Study `{}`\n\n", f.study.name);
    if !f.study.description.trim().is_empty() {
        s.push_str(f.study.description.trim());
        s.push_str("\n\n");
    }
    s.push_str("| | |\n|---|---|\n");
    s.push_str(&format!("| kind | `{}` |\n", f.study.kind.name()));
    // (the kinds of the parts are listed with their axes below)
    s.push_str(&format!(
        "| cases | {} ({} ok, {} failed, {} skipped) |\n",
        records.len(),
        counts.ok,
        counts.failed,
        counts.skipped
    ));
    s.push_str(&format!(
        "| seed | {} |\n| repeats | {} |\n",
        f.study.seed, f.study.repeats
    ));
    for a in &f.sweep {
        let labels = axis_labels(a);
        let shown = if labels.len() <= 8 {
            labels.join(", ")
        } else {
            format!(
                "{}, {}, ..., {} ({} values)",
                labels[0],
                labels[1],
                labels[labels.len() - 1],
                labels.len()
            )
        };
        s.push_str(&format!(
            "| axis `{}` | `{}` = {} |\n",
            md_escape(a.column()),
            md_escape(&a.path),
            md_escape(&shown)
        ));
    }
    for p in &f.part {
        s.push_str(&format!(
            "| part `{}` | kind `{}` |\n",
            md_escape(&p.name),
            p.kind.name()
        ));
        for a in &p.sweep {
            s.push_str(&format!(
                "| axis `{}` (part `{}`) | `{}` = {} |\n",
                md_escape(a.column()),
                md_escape(&p.name),
                md_escape(&a.path),
                md_escape(&axis_labels(a).join(", "))
            ));
        }
    }
    s.push_str(&format!("| study hash | `{}` |\n\n", study.hash));
    s.push_str("The study file is `study.toml` beside this report; every case is a line of `results.jsonl` and a row of `summary.csv`.");
    if f.study.timings {
        s.push_str(" Columns `t_*` are wall-clock measurements on the machine that ran the case (with the other cases running beside it): reported, not reproducible.");
    }
    s.push_str("\n\n");
    s
}

/// The labels of an axis's values (none when the axis is invalid).
fn axis_labels(a: &super::config::Axis) -> Vec<String> {
    let vals = super::sweep::axis_values(a).unwrap_or_default();
    vals.into_iter().map(|v| v.1).collect()
}

/// The report's tables: those of `[[report.table]]`, or by default one mean
/// table by every axis per part (one table when there are no parts; none
/// without axes).
fn report_tables(study: &Study) -> Vec<TableSpec> {
    let f = &study.file;
    let mut tables = f.report.table.clone();
    if tables.is_empty() && !columns(study).axes.is_empty() {
        let parts: Vec<Option<String>> = if f.part.is_empty() {
            vec![None]
        } else {
            f.parts().iter().map(|p| Some(p.0.to_string())).collect()
        };
        for part in parts {
            tables.push(TableSpec {
                title: part
                    .as_ref()
                    .map(|p| format!("mean by every axis, part {p}")),
                rows: None,
                metrics: None,
                aggregate: Aggregate::Mean,
                part,
            });
        }
    }
    tables
}

/// The `## Plots` section (plots, heatmaps, traces) into `s`; returns the
/// plots to write `(file, svg)`.
fn plots_md(study: &Study, records: &[Record], s: &mut String) -> Vec<(String, String)> {
    let r = &study.file.report;
    let mut plots = Vec::new();
    if r.plot.is_empty() && r.heatmap.is_empty() && r.trace.is_empty() {
        return plots;
    }
    s.push_str("## Plots\n\n");
    for p in &r.plot {
        let svg = plot_chart(records, p).and_then(|c| c.to_svg_string());
        one_plot_md("Plot", plot_file(p), svg, s, &mut plots);
    }
    for h in &r.heatmap {
        let svg = heatmap_chart(records, h).and_then(|c| c.to_svg_string());
        one_plot_md("Heatmap", heatmap_file(h), svg, s, &mut plots);
    }
    for t in &r.trace {
        let svg = trace_chart(records, t).and_then(|c| c.to_svg_string());
        one_plot_md("Trace plot", trace_file(t), svg, s, &mut plots);
    }
    plots
}

/// One plot's link into `s` and its svg into `plots`, or why it was not
/// drawn (`what` names the plot's sort).
fn one_plot_md(
    what: &str,
    file: String,
    svg: Result<String>,
    s: &mut String,
    plots: &mut Vec<(String, String)>,
) {
    match svg {
        Ok(svg) => {
            s.push_str(&format!("![{}]({file})\n\n", md_escape(&file)));
            plots.push((file, svg));
        }
        Err(e) => s.push_str(&format!(
            "{what} `{file}` not drawn: {}\n\n",
            md_escape(&e.to_string())
        )),
    }
}

/// A record's parameters, `column = label, ...`, escaped for markdown.
fn params_md(r: &Record) -> String {
    let params: Vec<String> = r
        .params
        .iter()
        .map(|p| format!("{} = {}", p.column, p.label))
        .collect();
    md_escape(&params.join(", "))
}

/// The table of the failed and skipped cases, when there are some.
fn failed_md(records: &[Record], s: &mut String) {
    let failed: Vec<&Record> = records.iter().filter(|r| !r.ok()).collect();
    if failed.is_empty() {
        return;
    }
    s.push_str(
        "## Failed and skipped cases\n\n| id | parameters | status | reason |\n|---|---|---|---|\n",
    );
    for r in failed {
        s.push_str(&format!(
            "| {} | {} | {} | {} |\n",
            r.id,
            params_md(r),
            r.status,
            md_escape(r.error.as_deref().unwrap_or(""))
        ));
    }
    s.push('\n');
}

/// The links to the cases' own plots, when there are some.
fn case_plots_md(records: &[Record], s: &mut String) {
    let with_files: Vec<&Record> = records.iter().filter(|r| !r.files.is_empty()).collect();
    if with_files.is_empty() {
        return;
    }
    s.push_str("## Case plots\n\n");
    for r in with_files {
        let links: Vec<String> = r
            .files
            .iter()
            .map(|f| {
                let name = f
                    .rsplit('/')
                    .next()
                    .unwrap_or(f)
                    .trim_start_matches(r.id.as_str())
                    .trim_start_matches('-')
                    .trim_end_matches(".svg");
                format!("[{name}]({f})")
            })
            .collect();
        s.push_str(&format!(
            "- {} ({}): {}\n",
            r.id,
            params_md(r),
            links.join(", ")
        ));
    }
    s.push('\n');
}

/// The `## Cases` section: one row per case, or a pointer to `summary.csv`
/// beyond `report.max_case_rows`.
fn cases_md(study: &Study, records: &[Record], s: &mut String) {
    let f = &study.file;
    s.push_str("## Cases\n\n");
    if records.len() > f.report.max_case_rows {
        s.push_str(&format!(
            "{} cases: more than `report.max_case_rows` = {}; see `summary.csv`.\n",
            records.len(),
            f.report.max_case_rows
        ));
        return;
    }
    let cols = columns(study);
    let mut header: Vec<String> = vec!["id".into()];
    if f.study.repeats > 1 {
        header.push("repeat".into());
    }
    header.extend(cols.axes.iter().map(|a| format!("`{a}`")));
    header.push("status".into());
    header.extend(
        cols.metrics
            .iter()
            .map(|m| format!("`{}`", cols.metric_header(m))),
    );
    s.push_str(&format!(
        "| {} |\n|{}\n",
        header.join(" | "),
        "---|".repeat(header.len())
    ));
    for r in records {
        let mut cells = vec![r.id.clone()];
        if f.study.repeats > 1 {
            cells.push(r.repeat.to_string());
        }
        cells.extend(cols.axes.iter().map(|a| md_escape(&axis_label(r, a))));
        cells.push(r.status.clone());
        cells.extend(cols.metrics.iter().map(|m| match metric(r, m) {
            Some(x) => fmt_num(x),
            None => md_escape(&metric_text(r, m)),
        }));
        s.push_str(&format!("| {} |\n", cells.join(" | ")));
    }
}

/// Write `summary.csv`, `report.md` and the plots into `out`, atomically.
/// `records` must be sorted by id (as [`super::run`] and
/// [`super::shard::merge`] give them).
///
/// # Errors
/// [`Error::Io`].
pub fn write(study: &Study, records: &[Record], out: &Path) -> Result<()> {
    write_atomic(&out.join(SUMMARY), summary_csv(study, records)?.as_bytes())?;
    let (md, plots) = report_md(study, records);
    for (file, svg) in &plots {
        write_atomic(&out.join(file), svg.as_bytes())?;
    }
    write_atomic(&out.join(REPORT), md.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wilson_intervals_hold_the_rate_and_stay_in_the_unit_interval() {
        // 20 of 20: the lower end is 0.839 (textbook value), the upper 1
        let (lo, hi) = wilson_interval(20.0, 20.0);
        assert!((lo - 0.8389).abs() < 1e-4 && hi == 1.0, "{lo} {hi}");
        let (lo, hi) = wilson_interval(0.0, 20.0);
        assert!(lo == 0.0 && (hi - 0.1611).abs() < 1e-4, "{lo} {hi}");
        // 10 of 20: symmetric around 1/2
        let (lo, hi) = wilson_interval(10.0, 20.0);
        assert!((lo + hi - 1.0).abs() < 1e-12 && (lo - 0.2993).abs() < 1e-4);
        assert_eq!(wilson_interval(0.0, 0.0), (0.0, 1.0));
    }

    #[test]
    fn aggregates() {
        let v = [1.0, 0.0, 3.0, f64::NAN];
        assert_eq!(aggregate(Aggregate::Mean, &v), Some(4.0 / 3.0));
        assert_eq!(aggregate(Aggregate::Median, &v), Some(1.0));
        assert_eq!(aggregate(Aggregate::Median, &[1.0, 2.0]), Some(1.5));
        assert_eq!(aggregate(Aggregate::Min, &v), Some(0.0));
        assert_eq!(aggregate(Aggregate::Max, &v), Some(3.0));
        assert_eq!(aggregate(Aggregate::Rate, &v), Some(2.0 / 3.0));
        assert_eq!(aggregate(Aggregate::Count, &v), Some(3.0));
        assert_eq!(aggregate(Aggregate::Mean, &[]), None);
    }

    #[test]
    fn number_format() {
        assert_eq!(fmt_num(3.0), "3");
        assert_eq!(fmt_num(0.123456), "0.1235");
        assert_eq!(fmt_num(12.3456), "12.35");
        assert_eq!(fmt_num(1.5e-12), "1.500e-12");
        assert_eq!(fmt_num(f64::INFINITY), "inf");
    }

    #[test]
    fn plot_names_are_sanitised() {
        let p: PlotSpec = toml::from_str("x = \"chain.n\"\ny = \"a/b\"").unwrap();
        assert_eq!(plot_file(&p), "a_b-vs-chain.n.svg");
        let p: PlotSpec = toml::from_str("x = \"a\"\ny = \"b\"\nfile = \"../x\"").unwrap();
        assert_eq!(plot_file(&p), "_.._x.svg");
    }
}
