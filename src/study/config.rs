//! The study file: a base scene plus a sweep, as TOML.
//!
//! ```toml
//! [study]
//! name = "scaling"          # required: names the report and the default output folder
//! kind = "forward"          # required: what one case does (see `springmass config schema`)
//! seed = 7                  # default 0: master seed; each case derives its own
//!
//! [scene]                   # the base case, in the schema of `kind`
//! chain = { n = 20 }
//!
//! [[sweep]]                 # one axis per entry; axes are crossed, first slowest
//! path = "chain.n"
//! values = [5, 50, 500]
//!
//! [[sweep]]
//! path = "random_defects.count"
//! range = { from = 1, to = 4, step = 1, integer = true }
//!
//! [[report.plot]]
//! x = "chain.n"
//! y = "max_rel_diff"
//! series = "random_defects.count"
//! ```
//!
//! `[[part]]` adds cases of another kind (own scene and axes) to the same
//! study; `[[report.trace]]` draws the optimizer traces of kind `fit`.
//!
//! Every table refuses unknown fields (`deny_unknown_fields`); the defaults
//! are in [`STUDY_FIELDS`] and, per kind, in the kind's own schema
//! ([`crate::study::kinds::Kind::schema`]). [`check`](crate::study::check::check) reports every problem
//! of a file with its field path and line.

use super::kinds::Kind;
pub use super::schema::{line_of, FieldDoc, Locator, Problem};
use super::schema::{one_line, walk};
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};

/// A parsed study file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StudyFile {
    /// What the study is and does.
    pub study: StudyMeta,
    /// The base case, in the schema of `study.kind` (checked per case).
    #[serde(default)]
    pub scene: toml::Table,
    /// The sweep axes, crossed (the first axis varies slowest). Default: none
    /// (one case per repeat).
    #[serde(default)]
    pub sweep: Vec<Axis>,
    /// Tables and plots of the report.
    #[serde(default)]
    pub report: ReportSpec,
    /// Further parts, each with its own kind, base scene and axes (default
    /// none). With parts, every case has a `part` column: `main` for the
    /// cases of `[scene]` / `[[sweep]]`, the part's name for the others.
    #[serde(default)]
    pub part: Vec<Part>,
}

/// One `[[part]]`: more cases in the same study, of any kind (for example
/// the `locate` cases of a study whose main part fits).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Part {
    /// Name: its label in the `part` column; required, not `main`.
    pub name: String,
    /// Case kind of the part; required.
    pub kind: Kind,
    /// Base scene, in the schema of the part's kind.
    #[serde(default)]
    pub scene: toml::Table,
    /// Axes of the part, crossed like `[[sweep]]`.
    #[serde(default)]
    pub sweep: Vec<Axis>,
}

impl StudyFile {
    /// `(part label, kind)` of the main part and of every `[[part]]`
    /// (the main part's label is `main`).
    pub fn parts(&self) -> Vec<(&str, Kind)> {
        let mut v = vec![(MAIN_PART, self.study.kind)];
        v.extend(self.part.iter().map(|p| (p.name.as_str(), p.kind)));
        v
    }

    /// The kinds of the parts selected by `part` (all parts for `None`).
    pub fn kinds_of(&self, part: Option<&str>) -> Vec<Kind> {
        let mut out: Vec<Kind> = Vec::new();
        for (name, kind) in self.parts() {
            if part.is_none_or(|p| p == name) && !out.contains(&kind) {
                out.push(kind);
            }
        }
        out
    }

    /// Every axis column of the study in order (main axes, then each part's
    /// new ones; `part` first when there are parts).
    pub fn axis_columns(&self) -> Vec<String> {
        let mut cols: Vec<String> = Vec::new();
        if !self.part.is_empty() {
            cols.push(PART_COLUMN.to_string());
        }
        for a in self
            .sweep
            .iter()
            .chain(self.part.iter().flat_map(|p| &p.sweep))
        {
            let c = a.column().to_string();
            if !cols.contains(&c) {
                cols.push(c);
            }
        }
        cols
    }
}

/// Column of the part of a case (studies with `[[part]]` only).
pub const PART_COLUMN: &str = "part";
/// The `part` label of the cases of the main `[scene]` / `[[sweep]]`.
pub const MAIN_PART: &str = "main";

/// The `[study]` table.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StudyMeta {
    /// Name of the study (letters, digits, `-`, `_`, `.`); required.
    pub name: String,
    /// Case kind; required.
    pub kind: Kind,
    /// A paragraph printed at the top of the report (default empty).
    #[serde(default)]
    pub description: String,
    /// Master seed (default 0). Each case's seed is derived from it and the
    /// case's parameters, so it does not depend on the order or the sharding.
    #[serde(default)]
    pub seed: u64,
    /// Replicates of every sweep point, each with its own seed (default 1).
    #[serde(default = "one_usize")]
    pub repeats: usize,
    /// Record measured timings (default true). Timings are the only
    /// non-reproducible numbers; with `false` two runs give identical bytes.
    #[serde(default = "yes")]
    pub timings: bool,
    /// Cases whose scene is invalid (for example `j1 = j2` in a crossed
    /// sweep of two positions): `error` (default: the file is refused) or
    /// `skip` (recorded with status `skipped` and the reason).
    #[serde(default)]
    pub invalid_cases: InvalidCases,
}

/// What to do with cases whose scene fails the kind's checks.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum InvalidCases {
    /// Refuse the study file (every such problem is listed).
    #[default]
    Error,
    /// Run the valid cases; record the others as skipped.
    Skip,
}

/// One sweep axis: a field path and its values (a list or a range).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Axis {
    /// Dotted field path inside `[scene]`, with `[i]` for array elements:
    /// `chain.n`, `chain.defects[1].m`, `noise.level`.
    pub path: String,
    /// Explicit values (any TOML values, tables included). One of `values` / `range`.
    #[serde(default)]
    pub values: Option<Vec<toml::Value>>,
    /// A numeric range. One of `values` / `range`.
    #[serde(default)]
    pub range: Option<Range>,
    /// Names of the values in tables and plots (default: the values themselves).
    #[serde(default)]
    pub labels: Option<Vec<String>>,
    /// Column name of the axis in tables and plots (default: `path`).
    #[serde(default)]
    pub name: Option<String>,
    /// Leave the axis out of the case seeds (default false): every value
    /// of it sees the same records, a paired comparison of settings.
    #[serde(default)]
    pub paired: bool,
}

impl Axis {
    /// The column name: `name` or `path`.
    pub fn column(&self) -> &str {
        self.name.as_deref().unwrap_or(&self.path)
    }
}

/// A numeric range `from ..= to`, given by `count` points or a `step`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Range {
    /// First value.
    pub from: f64,
    /// Last value (included when the step lands on it).
    pub to: f64,
    /// Number of points, `>= 1` (one of `count` / `step`; `count = 1` gives `from`).
    #[serde(default)]
    pub count: Option<usize>,
    /// Step (linear spacing only; one of `count` / `step`).
    #[serde(default)]
    pub step: Option<f64>,
    /// `linear` (default) or `log` (geometric; needs `from, to > 0` and `count`).
    #[serde(default)]
    pub spacing: Spacing,
    /// Round to integers and drop repeats (default false); needed for integer
    /// fields such as `chain.n`.
    #[serde(default)]
    pub integer: bool,
}

/// Spacing of a [`Range`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Spacing {
    /// Equal differences.
    #[default]
    Linear,
    /// Equal ratios.
    Log,
}

/// The `[report]` table.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReportSpec {
    /// Largest number of cases listed one per row in `report.md` (default 200;
    /// `summary.csv` always has them all).
    #[serde(default = "default_case_rows")]
    pub max_case_rows: usize,
    /// Aggregated tables (default: one table over all axes, when there are axes).
    #[serde(default)]
    pub table: Vec<TableSpec>,
    /// SVG plots (default none).
    #[serde(default)]
    pub plot: Vec<PlotSpec>,
    /// SVG heatmaps over two axes (default none).
    #[serde(default)]
    pub heatmap: Vec<HeatmapSpec>,
    /// SVG optimizer-trace plots (kind `fit`; default none).
    #[serde(default)]
    pub trace: Vec<TraceSpec>,
}

impl Default for ReportSpec {
    fn default() -> Self {
        ReportSpec {
            max_case_rows: default_case_rows(),
            table: Vec::new(),
            plot: Vec::new(),
            heatmap: Vec::new(),
            trace: Vec::new(),
        }
    }
}

/// One optimizer-trace plot of the report (kind `fit`, cases run with
/// `search.trace = true`): best residual so far against evaluations, one
/// line per group of cases (the values of the `series` axes), the cases of
/// a group reduced by `aggregate` at every evaluation count.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TraceSpec {
    /// Output file name (default `trace-<series>.svg`, or `trace.svg`).
    #[serde(default)]
    pub file: Option<String>,
    /// Title (default: `best residual against evaluations`).
    #[serde(default)]
    pub title: Option<String>,
    /// Axis columns giving one line per combination of their values
    /// (default: one line per case).
    #[serde(default)]
    pub series: Option<Vec<String>>,
    /// Only the cases whose axis columns have these labels, e.g.
    /// `{ system = "3" }` (default: every case).
    #[serde(default)]
    pub filter: toml::Table,
    /// Reduction over the cases of a line at each evaluation count (default
    /// `median`; `rate` and `count` are not allowed).
    #[serde(default = "median")]
    pub aggregate: Aggregate,
    /// Logarithmic horizontal axis (default false).
    #[serde(default)]
    pub logx: bool,
    /// Logarithmic vertical axis (default true).
    #[serde(default = "yes")]
    pub logy: bool,
    /// Only the cases of this `[[part]]` (`main`: of `[scene]`; default:
    /// every case).
    #[serde(default)]
    pub part: Option<String>,
}

fn median() -> Aggregate {
    Aggregate::Median
}

/// How the cases of one group are reduced to one number.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Aggregate {
    /// Arithmetic mean (default).
    #[default]
    Mean,
    /// Median.
    Median,
    /// Smallest value.
    Min,
    /// Largest value.
    Max,
    /// Share of cases where the metric is true (non-zero).
    Rate,
    /// Number of cases with a value.
    Count,
}

impl Aggregate {
    /// Lower-case name.
    pub fn name(&self) -> &'static str {
        match self {
            Aggregate::Mean => "mean",
            Aggregate::Median => "median",
            Aggregate::Min => "min",
            Aggregate::Max => "max",
            Aggregate::Rate => "rate",
            Aggregate::Count => "count",
        }
    }
}

/// One aggregated table of the report: a row per combination of `rows` values.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TableSpec {
    /// Heading (default: `<aggregate> by <rows>`).
    #[serde(default)]
    pub title: Option<String>,
    /// Axis columns that define the rows (default: every axis).
    #[serde(default)]
    pub rows: Option<Vec<String>>,
    /// Metrics shown (default: every metric of the kind).
    #[serde(default)]
    pub metrics: Option<Vec<String>>,
    /// Reduction over the cases of a row (default `mean`).
    #[serde(default)]
    pub aggregate: Aggregate,
    /// Only the cases of this `[[part]]` (`main`: of `[scene]`; default:
    /// every case).
    #[serde(default)]
    pub part: Option<String>,
}

/// One SVG plot of the report: `aggregate(y)` against axis `x`, one line per
/// value of axis `series`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlotSpec {
    /// Output file name inside the output folder (default `<y>-vs-<x>.svg`).
    #[serde(default)]
    pub file: Option<String>,
    /// Title (default: `<y> against <x>`).
    #[serde(default)]
    pub title: Option<String>,
    /// Axis column on the horizontal axis (numeric values); required.
    pub x: String,
    /// Metric (or timing) on the vertical axis; required.
    pub y: String,
    /// Axis column giving one line per value (default: a single line).
    #[serde(default)]
    pub series: Option<String>,
    /// Reduction over the cases at one point (default `mean`).
    #[serde(default)]
    pub aggregate: Aggregate,
    /// Logarithmic horizontal axis (default false).
    #[serde(default)]
    pub logx: bool,
    /// Logarithmic vertical axis (default false).
    #[serde(default)]
    pub logy: bool,
    /// Only the cases of this `[[part]]` (`main`: of `[scene]`; default:
    /// every case).
    #[serde(default)]
    pub part: Option<String>,
}

/// One SVG heatmap of the report: `aggregate(z)` over the grid of the values
/// of axes `x` and `y` (a residual surface, an accuracy map).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HeatmapSpec {
    /// Output file name (default `<z>-over-<x>-<y>.svg`).
    #[serde(default)]
    pub file: Option<String>,
    /// Title (default: `<aggregate> of <z>`).
    #[serde(default)]
    pub title: Option<String>,
    /// Axis column along the horizontal axis (numeric); required.
    pub x: String,
    /// Axis column along the vertical axis (numeric); required.
    pub y: String,
    /// Metric (or timing) coloured; required.
    pub z: String,
    /// Reduction over the cases of one cell (default `mean`).
    #[serde(default)]
    pub aggregate: Aggregate,
    /// Colour by `log10 z` (default false).
    #[serde(default)]
    pub log_z: bool,
    /// Only the cases of this `[[part]]` (`main`: of `[scene]`; default:
    /// every case).
    #[serde(default)]
    pub part: Option<String>,
}

serde_defaults! {
    fn one_usize() -> usize = 1;
    fn yes() -> bool = true;
    fn default_case_rows() -> usize = 200;
}

/// Every field of a study file outside `[scene]`.
pub const STUDY_FIELDS: &[FieldDoc] = &[
    FieldDoc::new("study", "table", "required", "What the study is and does."),
    FieldDoc::new("study.name", "string", "required", "Name of the study: letters, digits, `-`, `_`, `.`. Titles the report; the default output folder is `out/<name>`."),
    FieldDoc::new("study.kind", "string", "required", "What one case does: `forward`, `suppress`, `fit` or `locate` (see each kind's `scene.*` fields)."),
    FieldDoc::new("study.description", "string", "\"\"", "A paragraph printed at the top of `report.md`."),
    FieldDoc::new("study.seed", "integer >= 0", "0", "Master seed. Each case's seed is derived from it and the case's parameters (not its position), so it is the same whatever the thread count, order or shard."),
    FieldDoc::new("study.repeats", "integer >= 1", "1", "Replicates of every sweep point, each with its own derived seed (a `repeat` column tells them apart)."),
    FieldDoc::new("study.timings", "bool", "true", "Record measured timings (the `t_*` columns). Timings are the only non-reproducible numbers: with `false` two runs of a study give identical bytes."),
    FieldDoc::new("study.invalid_cases", "\"error\" | \"skip\"", "\"error\"", "Cases of the sweep whose scene fails the kind's checks (for example j1 = j2 when two positions are crossed): refuse the file, or record them with status `skipped` and the reason and run the others (counted apart from failed cases). Only failed range checks are skipped: unknown fields and values of the wrong type are always problems of the file."),
    FieldDoc::new("scene", "table", "{}", "The base case, in the schema of `study.kind` (the `scene.*` fields of that kind). Sweeps override fields of it.").opaque(),
    FieldDoc::new("sweep", "array of tables", "[]", "Sweep axes `[[sweep]]`, crossed: every combination of values is one case. The first axis varies slowest. No axes: one case (per repeat)."),
    FieldDoc::new("sweep[].path", "string", "required", "Field path inside `[scene]`: dotted keys, `[i]` for an array element, e.g. `chain.n`, `chain.defects[1].m`. Missing tables are created; the resulting case must satisfy the kind's schema (a misspelled path is an unknown field)."),
    FieldDoc::new("sweep[].values", "array", "none", "Explicit values of the axis (numbers, strings, arrays or tables). Exactly one of `values` and `range`.").opaque(),
    FieldDoc::new("sweep[].range", "table", "none", "A numeric range. Exactly one of `values` and `range`."),
    FieldDoc::new("sweep[].range.from", "float", "required", "First value."),
    FieldDoc::new("sweep[].range.to", "float", "required", "Last value (with `step`: included when a step lands on it, within 1e-9 of the step)."),
    FieldDoc::new("sweep[].range.count", "integer >= 1", "none", "Number of points (exactly one of `count` and `step`)."),
    FieldDoc::new("sweep[].range.step", "float > 0", "none", "Step of a linear range (exactly one of `count` and `step`); the sign follows `to - from`."),
    FieldDoc::new("sweep[].range.spacing", "\"linear\" | \"log\"", "\"linear\"", "Equal differences or equal ratios (`log` needs `from, to > 0` and `count`)."),
    FieldDoc::new("sweep[].range.integer", "bool", "false", "Round every point to the nearest integer and drop repeats; required for integer fields such as `chain.n`."),
    FieldDoc::new("sweep[].labels", "array of strings", "the values", "Names of the values in tables and plots; as many as there are values."),
    FieldDoc::new("sweep[].name", "string", "the path", "Column name of the axis in `summary.csv`, tables and plots."),
    FieldDoc::new("sweep[].paired", "bool", "false", "Leave the axis out of the case seeds: every value of it sees the same records and noise (a paired comparison of methods or settings)."),
    FieldDoc::new("part", "array of tables", "[]", "Further parts `[[part]]` of the study, each with its own kind, base scene and axes, run, resumed, sharded and reported with the main part. With parts, every case has a `part` column (`main` for the cases of `[scene]` and `[[sweep]]`), and tables, plots and heatmaps can be restricted to one part with `part = \"<name>\"`."),
    FieldDoc::new("part[].name", "string", "required", "Name of the part (letters, digits, `-`, `_`, `.`; not `main`; unique): its label in the `part` column."),
    FieldDoc::new("part[].kind", "string", "required", "What one case of the part does (`forward`, `suppress`, `fit`, `locate`)."),
    FieldDoc::new("part[].scene", "table", "{}", "Base scene of the part, in the schema of its kind (checked like `[scene]`).").opaque(),
    FieldDoc::new("part[].sweep", "array of tables", "[]", "Axes of the part `[[part.sweep]]`, crossed like `[[sweep]]` (same fields); `study.repeats` applies."),
    FieldDoc::new("part[].sweep[].path", "string", "required", "As `sweep[].path`, inside the part's scene."),
    FieldDoc::new("part[].sweep[].values", "array", "none", "As `sweep[].values`.").opaque(),
    FieldDoc::new("part[].sweep[].range", "table", "none", "As `sweep[].range`."),
    FieldDoc::new("part[].sweep[].range.from", "float", "required", "As `sweep[].range.from`."),
    FieldDoc::new("part[].sweep[].range.to", "float", "required", "As `sweep[].range.to`."),
    FieldDoc::new("part[].sweep[].range.count", "integer >= 1", "none", "As `sweep[].range.count`."),
    FieldDoc::new("part[].sweep[].range.step", "float > 0", "none", "As `sweep[].range.step`."),
    FieldDoc::new("part[].sweep[].range.spacing", "\"linear\" | \"log\"", "\"linear\"", "As `sweep[].range.spacing`."),
    FieldDoc::new("part[].sweep[].range.integer", "bool", "false", "As `sweep[].range.integer`."),
    FieldDoc::new("part[].sweep[].labels", "array of strings", "the values", "As `sweep[].labels`."),
    FieldDoc::new("part[].sweep[].name", "string", "the path", "As `sweep[].name`; an axis column may be shared by several parts."),
    FieldDoc::new("part[].sweep[].paired", "bool", "false", "As `sweep[].paired`."),
    FieldDoc::new("report", "table", "{}", "What `report.md` shows besides the case list."),
    FieldDoc::new("report.max_case_rows", "integer", "200", "Largest number of cases listed one per row in `report.md` (`summary.csv` always has every case)."),
    FieldDoc::new("report.table", "array of tables", "one table by every axis", "Aggregated tables `[[report.table]]`: one row per combination of the `rows` axes."),
    FieldDoc::new("report.table[].title", "string", "\"<aggregate> by <rows>\"", "Heading of the table."),
    FieldDoc::new("report.table[].rows", "array of strings", "every axis", "Axis columns (axis `name` or `path`, or `repeat`) that define the rows."),
    FieldDoc::new("report.table[].metrics", "array of strings", "every metric", "Metric (or `t_*` timing) columns shown."),
    FieldDoc::new("report.table[].part", "string", "every part", "Only the cases of this part (`main` or a `[[part]]` name; studies with parts)."),
    FieldDoc::new("report.table[].aggregate", "\"mean\" | \"median\" | \"min\" | \"max\" | \"rate\" | \"count\"", "\"mean\"", "Reduction over the cases of a row; `rate` is the share of cases where the metric is true or non-zero. Cases that failed are counted in the `errors` column and left out of the reduction."),
    FieldDoc::new("report.plot", "array of tables", "[]", "SVG plots `[[report.plot]]`: `aggregate(y)` against axis `x`, one line per value of `series`."),
    FieldDoc::new("report.plot[].file", "string", "\"<y>-vs-<x>.svg\"", "Output file name inside the output folder (characters outside `A-Za-z0-9._-` become `_`)."),
    FieldDoc::new("report.plot[].title", "string", "\"<y> against <x>\"", "Plot title."),
    FieldDoc::new("report.plot[].x", "string", "required", "Axis column on the horizontal axis; its values must be numbers."),
    FieldDoc::new("report.plot[].y", "string", "required", "Metric or `t_*` timing on the vertical axis."),
    FieldDoc::new("report.plot[].series", "string", "none", "Axis column giving one line per value (default: one line)."),
    FieldDoc::new("report.plot[].aggregate", "\"mean\" | \"median\" | \"min\" | \"max\" | \"rate\" | \"count\"", "\"mean\"", "Reduction over the cases at one point (repeats and axes not on the plot)."),
    FieldDoc::new("report.plot[].part", "string", "every part", "Only the cases of this part (`main` or a `[[part]]` name; studies with parts)."),
    FieldDoc::new("report.plot[].logx", "bool", "false", "Logarithmic horizontal axis."),
    FieldDoc::new("report.plot[].logy", "bool", "false", "Logarithmic vertical axis (non-positive values are dropped)."),
    FieldDoc::new("report.heatmap", "array of tables", "[]", "SVG heatmaps `[[report.heatmap]]`: `aggregate(z)` over the grid of the values of two axes (residual surfaces, accuracy maps). Cells without a value are grey."),
    FieldDoc::new("report.heatmap[].file", "string", "\"<z>-over-<x>-<y>.svg\"", "Output file name inside the output folder."),
    FieldDoc::new("report.heatmap[].title", "string", "\"<aggregate> of <z>\"", "Heatmap title."),
    FieldDoc::new("report.heatmap[].x", "string", "required", "Axis column along the horizontal axis; its values must be numbers."),
    FieldDoc::new("report.heatmap[].y", "string", "required", "Axis column along the vertical axis; its values must be numbers."),
    FieldDoc::new("report.heatmap[].z", "string", "required", "Metric or `t_*` timing coloured."),
    FieldDoc::new("report.heatmap[].aggregate", "\"mean\" | \"median\" | \"min\" | \"max\" | \"rate\" | \"count\"", "\"mean\"", "Reduction over the cases of one cell."),
    FieldDoc::new("report.heatmap[].part", "string", "every part", "Only the cases of this part (`main` or a `[[part]]` name; studies with parts)."),
    FieldDoc::new("report.heatmap[].log_z", "bool", "false", "Colour by log10 z (non-positive cells grey)."),
    FieldDoc::new("report.trace", "array of tables", "[]", "SVG optimizer-trace plots `[[report.trace]]` (kind `fit`; every case must set `scene.search.trace = true`): best residual so far against residual evaluations, one line per group of cases. The traces are stored in the case records (`results.jsonl`), so resumed, re-threaded and merged runs draw the same plots. Enumeration records no trace."),
    FieldDoc::new("report.trace[].file", "string", "\"trace-<series>.svg\"", "Output file name inside the output folder (`trace.svg` without `series`)."),
    FieldDoc::new("report.trace[].title", "string", "\"best residual against evaluations\"", "Plot title."),
    FieldDoc::new("report.trace[].series", "array of strings", "one line per case", "Axis columns whose values define the lines (e.g. `[\"search\"]`: one line per optimizer and budget)."),
    FieldDoc::new("report.trace[].filter", "table", "{}", "Only the cases whose axis columns have these labels: `{ system = \"3\", data = \"exact\" }` (a label or an array of labels per column).").opaque(),
    FieldDoc::new("report.trace[].aggregate", "\"median\" | \"mean\" | \"min\" | \"max\"", "\"median\"", "Reduction over the cases of a line (repeats, axes not in `series`) of their best residual so far, at every evaluation count where one of them improves."),
    FieldDoc::new("report.trace[].part", "string", "every part", "Only the cases of this part (`main` or a `[[part]]` name; studies with parts)."),
    FieldDoc::new("report.trace[].logx", "bool", "false", "Logarithmic evaluations axis."),
    FieldDoc::new("report.trace[].logy", "bool", "true", "Logarithmic residual axis (non-positive values are dropped)."),
];

/// Parse a study file, failing on the first problem (see [`check`](crate::study::check::check) for all
/// of them). The semantic checks of every case are done by
/// [`crate::study::Study::from_text`].
///
/// # Errors
/// [`Error::Parse`] naming the file, the field and the line.
pub fn parse(text: &str, origin: &str) -> Result<StudyFile> {
    let problems = check_structure(text);
    if let Some(p) = problems.first() {
        return Err(Error::parse("study file", origin, p.to_string()));
    }
    toml::from_str(text).map_err(|e| Error::parse("study file", origin, one_line(&e.to_string())))
}

/// Schema and type problems, before any case is built.
pub fn check_structure(text: &str) -> Vec<Problem> {
    let value: toml::Table = match toml::from_str(text) {
        Ok(v) => v,
        Err(e) => {
            return vec![Problem {
                path: String::new(),
                line: e.span().map(|s| line_of(text, s.start)),
                message: format!("not valid TOML: {}", one_line(e.message())),
            }]
        }
    };
    let locate = Locator::new(text);
    let mut problems = Vec::new();
    walk(
        &toml::Value::Table(value.clone()),
        "",
        "",
        STUDY_FIELDS,
        &locate,
        &mut problems,
    );
    // The scene, against the kind's schema (when the kind is known).
    let kind = value
        .get("study")
        .and_then(|s| s.get("kind"))
        .and_then(|k| k.as_str());
    match kind.map(Kind::from_name) {
        Some(Ok(kind)) => {
            if let Some(scene) = value.get("scene") {
                walk(scene, "scene", "", kind.schema(), &locate, &mut problems);
            }
        }
        Some(Err(e)) => problems.push(Problem {
            path: "study.kind".into(),
            line: locate.line("study.kind"),
            message: e,
        }),
        None => {}
    }
    // The scene of every part, against its kind's schema.
    if let Some(toml::Value::Array(parts)) = value.get("part") {
        for (i, p) in parts.iter().enumerate() {
            let kind = p.get("kind").and_then(|k| k.as_str());
            match kind.map(Kind::from_name) {
                Some(Ok(kind)) => {
                    if let Some(scene) = p.get("scene") {
                        let path = format!("part[{i}].scene");
                        walk(scene, &path, "", kind.schema(), &locate, &mut problems);
                    }
                }
                Some(Err(e)) => {
                    let path = format!("part[{i}].kind");
                    problems.push(Problem {
                        line: locate.line(&path),
                        path,
                        message: e,
                    })
                }
                None => {}
            }
        }
    }
    problems
}

/// The schema as plain text for a terminal (`springmass config --help`):
/// every field with its default, type and meaning.
pub fn schema_text(kinds: &[Kind]) -> String {
    let mut out = String::from("Study file fields (default in brackets):\n");
    let entry = |f: &FieldDoc, prefix: &str| {
        format!(
            "  {prefix}{} [{}]  ({})\n      {}\n",
            f.path,
            f.default,
            f.ty,
            f.doc.replace('`', "")
        )
    };
    for f in STUDY_FIELDS {
        out.push_str(&entry(f, ""));
    }
    for k in kinds {
        out.push_str(&format!(
            "\nKind {}: {}\nScene fields:\n",
            k.name(),
            k.summary()
        ));
        for f in k.schema() {
            out.push_str(&entry(f, "scene."));
        }
        out.push_str("Metrics (columns of summary.csv; t_* are timings):\n");
        for (m, doc) in k.metrics() {
            out.push_str(&format!("  {m}: {}\n", doc.replace('`', "")));
        }
    }
    out
}

/// The schema of `kind` as Markdown: one table of the study fields and one of
/// the kind's scene fields (the text of `springmass config schema`).
pub fn schema_markdown(kinds: &[Kind]) -> String {
    let mut out = String::new();
    let row = |f: &FieldDoc, prefix: &str| {
        format!(
            "| `{prefix}{}` | {} | `{}` | {} |\n",
            f.path,
            f.ty.replace('|', "\\|"),
            f.default,
            f.doc.replace('|', "\\|")
        )
    };
    out.push_str("### Study fields\n\n| field | type | default | meaning |\n|---|---|---|---|\n");
    for f in STUDY_FIELDS {
        out.push_str(&row(f, ""));
    }
    for k in kinds {
        out.push_str(&format!(
            "\n### Kind `{}`: scene fields\n\n{}\n\n| field | type | default | meaning |\n|---|---|---|---|\n",
            k.name(),
            k.summary()
        ));
        for f in k.schema() {
            out.push_str(&row(f, "scene."));
        }
        out.push_str(&format!(
            "\n### Kind `{}`: metrics\n\n| column | meaning |\n|---|---|\n",
            k.name()
        ));
        for (m, doc) in k.metrics() {
            out.push_str(&format!("| `{m}` | {} |\n", doc.replace('|', "\\|")));
        }
    }
    out
}
