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
//! ([`crate::study::kinds::Kind::schema`]). [`check`] reports every problem
//! of a file with its field path and line.

use super::kinds::Kind;
use super::sweep;
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
        let mut v = vec![(sweep::MAIN_PART, self.study.kind)];
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
            cols.push(sweep::PART_COLUMN.to_string());
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

fn one_usize() -> usize {
    1
}
fn yes() -> bool {
    true
}
fn default_case_rows() -> usize {
    200
}

/// Documentation of one field: its path, type, default and meaning.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FieldDoc {
    /// Dotted path; `[]` stands for any array index.
    pub path: &'static str,
    /// Type in words.
    pub ty: &'static str,
    /// Default in TOML syntax, or `required`.
    pub default: &'static str,
    /// What the field does.
    pub doc: &'static str,
    /// The field holds free-form data (values of any shape): its contents are
    /// not checked against the schema.
    pub opaque: bool,
}

impl FieldDoc {
    /// A documented field.
    pub const fn new(
        path: &'static str,
        ty: &'static str,
        default: &'static str,
        doc: &'static str,
    ) -> FieldDoc {
        FieldDoc {
            path,
            ty,
            default,
            doc,
            opaque: false,
        }
    }

    /// A field whose contents are free-form.
    pub const fn opaque(
        path: &'static str,
        ty: &'static str,
        default: &'static str,
        doc: &'static str,
    ) -> FieldDoc {
        FieldDoc {
            path,
            ty,
            default,
            doc,
            opaque: true,
        }
    }
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
    FieldDoc::new("study.invalid_cases", "\"error\" | \"skip\"", "\"error\"", "Cases of the sweep whose scene fails the kind's checks (for example j1 = j2 when two positions are crossed): refuse the file, or record them with status `skipped` and the reason and run the others."),
    FieldDoc::opaque("scene", "table", "{}", "The base case, in the schema of `study.kind` (the `scene.*` fields of that kind). Sweeps override fields of it."),
    FieldDoc::new("sweep", "array of tables", "[]", "Sweep axes `[[sweep]]`, crossed: every combination of values is one case. The first axis varies slowest. No axes: one case (per repeat)."),
    FieldDoc::new("sweep[].path", "string", "required", "Field path inside `[scene]`: dotted keys, `[i]` for an array element, e.g. `chain.n`, `chain.defects[1].m`. Missing tables are created; the resulting case must satisfy the kind's schema (a misspelled path is an unknown field)."),
    FieldDoc::opaque("sweep[].values", "array", "none", "Explicit values of the axis (numbers, strings, arrays or tables). Exactly one of `values` and `range`."),
    FieldDoc::new("sweep[].range", "table", "none", "A numeric range. Exactly one of `values` and `range`."),
    FieldDoc::new("sweep[].range.from", "float", "required", "First value."),
    FieldDoc::new("sweep[].range.to", "float", "required", "Last value (with `step`: included when a step lands on it, within 1e-9 of the step)."),
    FieldDoc::new("sweep[].range.count", "integer >= 1", "none", "Number of points (exactly one of `count` and `step`)."),
    FieldDoc::new("sweep[].range.step", "float > 0", "none", "Step of a linear range (exactly one of `count` and `step`); the sign follows `to - from`."),
    FieldDoc::new("sweep[].range.spacing", "\"linear\" | \"log\"", "\"linear\"", "Equal differences or equal ratios (`log` needs `from, to > 0` and `count`)."),
    FieldDoc::new("sweep[].range.integer", "bool", "false", "Round every point to the nearest integer and drop repeats; required for integer fields such as `chain.n`."),
    FieldDoc::new("sweep[].labels", "array of strings", "the values", "Names of the values in tables and plots; as many as there are values."),
    FieldDoc::new("sweep[].name", "string", "the path", "Column name of the axis in `summary.csv`, tables and plots."),
    FieldDoc::new("part", "array of tables", "[]", "Further parts `[[part]]` of the study, each with its own kind, base scene and axes, run, resumed, sharded and reported with the main part. With parts, every case has a `part` column (`main` for the cases of `[scene]` and `[[sweep]]`), and tables, plots and heatmaps can be restricted to one part with `part = \"<name>\"`."),
    FieldDoc::new("part[].name", "string", "required", "Name of the part (letters, digits, `-`, `_`, `.`; not `main`; unique): its label in the `part` column."),
    FieldDoc::new("part[].kind", "string", "required", "What one case of the part does (`forward`, `suppress`, `fit`, `locate`)."),
    FieldDoc::opaque("part[].scene", "table", "{}", "Base scene of the part, in the schema of its kind (checked like `[scene]`)."),
    FieldDoc::new("part[].sweep", "array of tables", "[]", "Axes of the part `[[part.sweep]]`, crossed like `[[sweep]]` (same fields); `study.repeats` applies."),
    FieldDoc::new("part[].sweep[].path", "string", "required", "As `sweep[].path`, inside the part's scene."),
    FieldDoc::opaque("part[].sweep[].values", "array", "none", "As `sweep[].values`."),
    FieldDoc::new("part[].sweep[].range", "table", "none", "As `sweep[].range`."),
    FieldDoc::new("part[].sweep[].range.from", "float", "required", "As `sweep[].range.from`."),
    FieldDoc::new("part[].sweep[].range.to", "float", "required", "As `sweep[].range.to`."),
    FieldDoc::new("part[].sweep[].range.count", "integer >= 1", "none", "As `sweep[].range.count`."),
    FieldDoc::new("part[].sweep[].range.step", "float > 0", "none", "As `sweep[].range.step`."),
    FieldDoc::new("part[].sweep[].range.spacing", "\"linear\" | \"log\"", "\"linear\"", "As `sweep[].range.spacing`."),
    FieldDoc::new("part[].sweep[].range.integer", "bool", "false", "As `sweep[].range.integer`."),
    FieldDoc::new("part[].sweep[].labels", "array of strings", "the values", "As `sweep[].labels`."),
    FieldDoc::new("part[].sweep[].name", "string", "the path", "As `sweep[].name`; an axis column may be shared by several parts."),
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
    FieldDoc::opaque("report.trace[].filter", "table", "{}", "Only the cases whose axis columns have these labels: `{ system = \"3\", data = \"exact\" }` (a label or an array of labels per column)."),
    FieldDoc::new("report.trace[].aggregate", "\"median\" | \"mean\" | \"min\" | \"max\"", "\"median\"", "Reduction over the cases of a line (repeats, axes not in `series`) of their best residual so far, at every evaluation count where one of them improves."),
    FieldDoc::new("report.trace[].part", "string", "every part", "Only the cases of this part (`main` or a `[[part]]` name; studies with parts)."),
    FieldDoc::new("report.trace[].logx", "bool", "false", "Logarithmic evaluations axis."),
    FieldDoc::new("report.trace[].logy", "bool", "true", "Logarithmic residual axis (non-positive values are dropped)."),
];

/// One problem found in a study file.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Problem {
    /// Field path (`scene.chain.n`, `sweep[1].range.count`), or empty for
    /// the file as a whole.
    pub path: String,
    /// 1-based line of the field in the file, when known.
    pub line: Option<usize>,
    /// What is wrong and what is allowed.
    pub message: String,
}

impl std::fmt::Display for Problem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match (self.line, self.path.is_empty()) {
            (Some(l), false) => write!(f, "line {l}: {}: {}", self.path, self.message),
            (Some(l), true) => write!(f, "line {l}: {}", self.message),
            (None, false) => write!(f, "{}: {}", self.path, self.message),
            (None, true) => write!(f, "{}", self.message),
        }
    }
}

/// Parse a study file, failing on the first problem (see [`check`] for all
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

/// Every problem of a study file: syntax, unknown or misspelled fields
/// (anywhere, the scene included), types, sweep axes, report references, and
/// the checks of every case of the sweep. Empty when the file is good.
///
/// Never panics, whatever the input.
///
/// ```
/// use springmass::study::config::check;
/// let problems = check("[study]\nname = \"x\"\nkind = \"forward\"\nseeed = 3\n[scene]\nchain = { n = 5 }\n");
/// assert_eq!(problems.len(), 1);
/// assert_eq!(problems[0].path, "study.seeed");
/// assert_eq!(problems[0].line, Some(4));
/// assert!(problems[0].message.contains("did you mean `seed`"));
/// ```
pub fn check(text: &str) -> Vec<Problem> {
    let mut problems = check_structure(text);
    if !problems.is_empty() {
        return problems;
    }
    let file: StudyFile = match toml::from_str(text) {
        Ok(f) => f,
        Err(e) => {
            return vec![Problem {
                path: String::new(),
                line: e.span().map(|s| line_of(text, s.start)),
                message: one_line(e.message()),
            }]
        }
    };
    let locate = Locator::new(text);
    problems.extend(check_semantics(&file, &locate));
    problems
}

/// Schema and type problems, before any case is built.
fn check_structure(text: &str) -> Vec<Problem> {
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
    if problems.is_empty() {
        // types, required fields: serde, which gives the first problem only
        // (with its line)
        if let Err(e) = toml::from_str::<StudyFile>(text) {
            problems.push(Problem {
                path: String::new(),
                line: e.span().map(|s| line_of(text, s.start)),
                message: one_line(e.message()),
            });
        }
    }
    problems
}

/// Checks that need the whole study: axes, report references, every case.
fn check_semantics(file: &StudyFile, locate: &Locator) -> Vec<Problem> {
    let problems = std::cell::RefCell::new(Vec::new());
    let push = |path: String, message: String| {
        let line = locate.line(&path);
        problems.borrow_mut().push(Problem {
            path,
            line,
            message,
        })
    };
    let name = &file.study.name;
    if name.is_empty()
        || !name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "-_.".contains(c))
        || name.starts_with('.')
    {
        push(
            "study.name".into(),
            format!("{name:?} is not allowed: use letters, digits, '-', '_', '.', not starting with '.'"),
        );
    }
    if file.study.repeats == 0 {
        push(
            "study.repeats".into(),
            "0 is not allowed: repeats >= 1".into(),
        );
    }
    let mut columns: Vec<String> = vec!["repeat".into()];
    if !file.part.is_empty() {
        columns.push(sweep::PART_COLUMN.into());
    }
    let mut names: Vec<&str> = vec![sweep::MAIN_PART];
    for (i, p) in file.part.iter().enumerate() {
        let n = p.name.as_str();
        if n.is_empty()
            || !n
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || "-_.".contains(c))
        {
            push(
                format!("part[{i}].name"),
                format!("{n:?} is not allowed: use letters, digits, '-', '_', '.'"),
            );
        } else if names.contains(&n) {
            push(
                format!("part[{i}].name"),
                format!("{n:?} is used twice (`main` is the part of [scene] and [[sweep]])"),
            );
        }
        names.push(n);
    }
    let part_axes = std::iter::once((String::new(), &file.sweep)).chain(
        file.part
            .iter()
            .enumerate()
            .map(|(i, p)| (format!("part[{i}]."), &p.sweep)),
    );
    for (prefix, axes) in part_axes {
        let mut own: Vec<String> = Vec::new();
        for (i, axis) in axes.iter().enumerate() {
            if let Err(e) = sweep::axis_values(axis) {
                push(format!("{prefix}sweep[{i}]"), e);
            }
            if let Err(e) = sweep::parse_path(&axis.path) {
                push(format!("{prefix}sweep[{i}].path"), e);
            }
            let col = axis.column().to_string();
            if own.contains(&col) || col == "repeat" || col == sweep::PART_COLUMN {
                push(
                    format!("{prefix}sweep[{i}].name"),
                    format!("axis column {col:?} is used twice (give the axes distinct `name`s)"),
                );
            }
            own.push(col.clone());
            if !columns.contains(&col) {
                columns.push(col);
            }
        }
    }
    // a report item's `part` must name a part; its metrics are those of the
    // kinds of the parts it covers
    let check_part = |path: String, part: &Option<String>| {
        if let Some(p) = part {
            if !names.contains(&p.as_str()) {
                push(
                    path,
                    format!("{p:?} is not a part; parts: {}", names.join(", ")),
                );
            }
        }
    };
    // an unknown part is reported once (check_part); its metrics are then
    // checked against every kind
    let known_part = |part: &Option<String>| -> Option<String> {
        part.clone().filter(|p| names.contains(&p.as_str()))
    };
    let kinds_label = |part: &Option<String>| {
        file.kinds_of(known_part(part).as_deref())
            .iter()
            .map(|k| k.name())
            .collect::<Vec<_>>()
            .join(" or ")
    };
    let known_metric = |m: &str, part: &Option<String>| {
        file.kinds_of(known_part(part).as_deref())
            .iter()
            .any(|k| k.metrics().iter().any(|x| x.0 == m))
    };
    let metric_list = |part: &Option<String>| {
        let mut v: Vec<&str> = Vec::new();
        for k in file.kinds_of(known_part(part).as_deref()) {
            for m in k.metrics() {
                if !v.contains(&m.0) {
                    v.push(m.0);
                }
            }
        }
        v.join(", ")
    };
    for (i, t) in file.report.table.iter().enumerate() {
        for (j, r) in t.rows.iter().flatten().enumerate() {
            if !columns.contains(r) {
                push(
                    format!("report.table[{i}].rows[{j}]"),
                    format!("{r:?} is not an axis column; axes: {}", columns.join(", ")),
                );
            }
        }
        check_part(format!("report.table[{i}].part"), &t.part);
        for (j, m) in t.metrics.iter().flatten().enumerate() {
            if !known_metric(m, &t.part) {
                push(
                    format!("report.table[{i}].metrics[{j}]"),
                    format!(
                        "{m:?} is not a metric of kind {}; metrics: {}",
                        kinds_label(&t.part),
                        metric_list(&t.part)
                    ),
                );
            }
        }
    }
    for (i, p) in file.report.plot.iter().enumerate() {
        if !columns.contains(&p.x) {
            push(
                format!("report.plot[{i}].x"),
                format!(
                    "{:?} is not an axis column; axes: {}",
                    p.x,
                    columns.join(", ")
                ),
            );
        }
        if let Some(s) = &p.series {
            if !columns.contains(s) {
                push(
                    format!("report.plot[{i}].series"),
                    format!("{s:?} is not an axis column; axes: {}", columns.join(", ")),
                );
            }
        }
        check_part(format!("report.plot[{i}].part"), &p.part);
        if !known_metric(&p.y, &p.part) {
            push(
                format!("report.plot[{i}].y"),
                format!(
                    "{:?} is not a metric of kind {}; metrics: {}",
                    p.y,
                    kinds_label(&p.part),
                    metric_list(&p.part)
                ),
            );
        }
    }
    for (i, h) in file.report.heatmap.iter().enumerate() {
        for (field, col) in [("x", &h.x), ("y", &h.y)] {
            if !columns.contains(col) {
                push(
                    format!("report.heatmap[{i}].{field}"),
                    format!(
                        "{col:?} is not an axis column; axes: {}",
                        columns.join(", ")
                    ),
                );
            }
        }
        check_part(format!("report.heatmap[{i}].part"), &h.part);
        if !known_metric(&h.z, &h.part) {
            push(
                format!("report.heatmap[{i}].z"),
                format!(
                    "{:?} is not a metric of kind {}; metrics: {}",
                    h.z,
                    kinds_label(&h.part),
                    metric_list(&h.part)
                ),
            );
        }
    }
    for (i, t) in file.report.trace.iter().enumerate() {
        check_part(format!("report.trace[{i}].part"), &t.part);
        if !file
            .kinds_of(known_part(&t.part).as_deref())
            .contains(&Kind::Fit)
        {
            push(
                format!("report.trace[{i}]"),
                format!(
                    "optimizer traces are recorded by kind fit only, not {}",
                    kinds_label(&t.part)
                ),
            );
        }
        for (j, c) in t.series.iter().flatten().enumerate() {
            if !columns.contains(c) {
                push(
                    format!("report.trace[{i}].series[{j}]"),
                    format!("{c:?} is not an axis column; axes: {}", columns.join(", ")),
                );
            }
        }
        for (c, v) in &t.filter {
            if !columns.contains(c) {
                push(
                    format!("report.trace[{i}].filter.{c}"),
                    format!("{c:?} is not an axis column; axes: {}", columns.join(", ")),
                );
            }
            let ok = match v {
                toml::Value::String(_) => true,
                toml::Value::Array(a) => a.iter().all(|x| x.is_str()),
                _ => false,
            };
            if !ok {
                push(
                    format!("report.trace[{i}].filter.{c}"),
                    "a label (string) or an array of labels".into(),
                );
            }
        }
        if matches!(t.aggregate, Aggregate::Rate | Aggregate::Count) {
            push(
                format!("report.trace[{i}].aggregate"),
                format!(
                    "{:?} is not allowed here: median, mean, min or max",
                    t.aggregate.name()
                ),
            );
        }
    }
    let axes_ok = file
        .sweep
        .iter()
        .chain(file.part.iter().flat_map(|p| &p.sweep))
        .all(|a| sweep::axis_values(a).is_ok() && sweep::parse_path(&a.path).is_ok());
    if !axes_ok || file.study.repeats == 0 {
        return problems.into_inner();
    }
    let skip = file.study.invalid_cases == InvalidCases::Skip;
    // Every case: the kind's deserialisation and semantic checks. One problem
    // per distinct message (a bad base field fails every case alike).
    match sweep::expand(file) {
        Err(e) => push(String::new(), e.to_string()),
        Ok(cases) => {
            // (path, message) -> (first failing case, number of failing cases),
            // in order of first appearance
            let mut found: Vec<((String, String), (usize, usize))> = Vec::new();
            for (ci, case) in cases.iter().enumerate() {
                let errs = case.kind.validate_all(&case.scene);
                // with `skip`, unknown fields still are errors (a misspelling
                // would otherwise skip every case)
                let errs: Vec<Error> = errs
                    .into_iter()
                    .filter(|e| !skip || e.to_string().contains("unknown field"))
                    .collect();
                for e in errs {
                    let (path, message) = split_field(&e);
                    // the scene of the case's part
                    let scene = match case.params.first() {
                        Some(p)
                            if p.column == sweep::PART_COLUMN && p.label != sweep::MAIN_PART =>
                        {
                            let i = file
                                .part
                                .iter()
                                .position(|x| x.name == p.label)
                                .unwrap_or(0);
                            format!("part[{i}].scene")
                        }
                        _ => "scene".to_string(),
                    };
                    let path = if path.is_empty() {
                        scene
                    } else {
                        format!("{scene}.{path}")
                    };
                    let key = (path, message);
                    match found.iter_mut().find(|(k, _)| *k == key) {
                        Some((_, (_, count))) => *count += 1,
                        None => found.push((key, (ci, 1))),
                    }
                }
            }
            for t in &file.report.trace {
                let untraced: Vec<usize> =
                    (0..cases.len())
                        .filter(|&i| {
                            cases[i].kind == Kind::Fit
                                && t.part.as_deref().is_none_or(|p| {
                                    cases[i].params.first().is_some_and(|x| {
                                        x.column == sweep::PART_COLUMN && x.label == p
                                    }) || (p == sweep::MAIN_PART && file.part.is_empty())
                                })
                                && cases[i]
                                    .scene
                                    .get("search")
                                    .and_then(|s| s.get("trace"))
                                    .and_then(|t| t.as_bool())
                                    != Some(true)
                        })
                        .collect();
                let key = (
                    "scene.search.trace".to_string(),
                    "report.trace needs the optimizer trace of every case: set search.trace = true (in every value of a swept `search` table too)".to_string(),
                );
                if let Some(&first) = untraced
                    .first()
                    .filter(|_| !found.iter().any(|f| f.0 == key))
                {
                    found.push((
                        (
                            "scene.search.trace".to_string(),
                            "report.trace needs the optimizer trace of every case: set search.trace = true (in every value of a swept `search` table too)".to_string(),
                        ),
                        (first, untraced.len()),
                    ));
                }
            }
            for ((path, message), (first, count)) in found {
                let case = &cases[first];
                let where_ = if count == cases.len() || case.params.is_empty() {
                    String::new()
                } else {
                    format!(
                        " ({count} of {} cases, first {}: {})",
                        cases.len(),
                        case.id,
                        case.describe()
                    )
                };
                push(path, format!("{message}{where_}"));
            }
        }
    }
    problems.into_inner()
}

/// The field named by an error, and the message.
fn split_field(e: &Error) -> (String, String) {
    match e {
        Error::InvalidParameter { field, .. } => (field.clone(), e.to_string()),
        Error::Parse { input, reason, .. } => (input.clone(), reason.clone()),
        _ => (String::new(), e.to_string()),
    }
}

/// Check `value` (at `path`, schema-relative `rel`) against `schema`: every
/// key must be documented. Reports unknown keys with a suggestion.
fn walk(
    value: &toml::Value,
    path: &str,
    rel: &str,
    schema: &[FieldDoc],
    locate: &Locator,
    out: &mut Vec<Problem>,
) {
    match value {
        toml::Value::Table(t) => {
            for (key, v) in t {
                let rel_key = if rel.is_empty() {
                    key.clone()
                } else {
                    format!("{rel}.{key}")
                };
                let full = if path.is_empty() {
                    key.clone()
                } else {
                    format!("{path}.{key}")
                };
                match schema.iter().find(|f| f.path == rel_key) {
                    Some(f) if f.opaque => {}
                    Some(_) => walk(v, &full, &rel_key, schema, locate, out),
                    None => {
                        // a key that only has children (an undocumented parent)
                        let prefix = format!("{rel_key}.");
                        let prefix_arr = format!("{rel_key}[]");
                        if schema
                            .iter()
                            .any(|f| f.path.starts_with(&prefix) || f.path.starts_with(&prefix_arr))
                        {
                            walk(v, &full, &rel_key, schema, locate, out);
                            continue;
                        }
                        let siblings: Vec<&str> = schema
                            .iter()
                            .filter_map(|f| {
                                let rest = if rel.is_empty() {
                                    Some(f.path)
                                } else {
                                    f.path.strip_prefix(rel).and_then(|r| r.strip_prefix('.'))
                                }?;
                                (!rest.contains('.') && !rest.contains('[')).then_some(rest)
                            })
                            .collect();
                        let hint = match closest(key, &siblings) {
                            Some(s) => format!("; did you mean `{s}`?"),
                            None => String::new(),
                        };
                        let allowed = if siblings.is_empty() {
                            "no fields here".to_string()
                        } else {
                            format!("expected one of {}", siblings.join(", "))
                        };
                        out.push(Problem {
                            line: locate.line(&full),
                            path: full,
                            message: format!("unknown field `{key}`, {allowed}{hint}"),
                        });
                    }
                }
            }
        }
        toml::Value::Array(a) => {
            let rel_arr = format!("{rel}[]");
            if schema
                .iter()
                .any(|f| f.path.starts_with(&format!("{rel_arr}.")))
            {
                for (i, v) in a.iter().enumerate() {
                    walk(v, &format!("{path}[{i}]"), &rel_arr, schema, locate, out);
                }
            }
        }
        _ => {}
    }
}

/// Unknown fields of a scene `value` against a kind's `schema`, with paths
/// `scene.<field>` (no lines: the value may come from a sweep).
pub fn unknown_fields(value: &toml::Value, schema: &[FieldDoc]) -> Vec<Problem> {
    let mut out = Vec::new();
    let none = Locator {
        text: String::new(),
        doc: None,
    };
    walk(value, "scene", "", schema, &none, &mut out);
    out
}

/// The candidate closest to `key` by edit distance, if close enough.
fn closest<'a>(key: &str, candidates: &[&'a str]) -> Option<&'a str> {
    let mut best: Option<(usize, &str)> = None;
    for c in candidates {
        let d = edit_distance(&key.to_ascii_lowercase(), &c.to_ascii_lowercase());
        if best.is_none_or(|(bd, _)| d < bd) {
            best = Some((d, c));
        }
    }
    best.filter(|(d, c)| *d <= 2.max(c.len() / 3))
        .map(|(_, c)| c)
}

fn edit_distance(a: &str, b: &str) -> usize {
    let a: Vec<char> = a.chars().collect();
    let b: Vec<char> = b.chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    for i in 1..=a.len() {
        let mut cur = vec![i; b.len() + 1];
        for j in 1..=b.len() {
            let sub = prev[j - 1] + usize::from(a[i - 1] != b[j - 1]);
            cur[j] = sub.min(prev[j] + 1).min(cur[j - 1] + 1);
        }
        prev = cur;
    }
    prev[b.len()]
}

/// Finds the line of a field path in the source text (via `toml_edit` spans).
pub struct Locator {
    text: String,
    doc: Option<toml_edit::ImDocument<String>>,
}

impl Locator {
    /// Parse `text` once (a text that does not parse locates nothing).
    pub fn new(text: &str) -> Locator {
        Locator {
            text: text.to_string(),
            doc: toml_edit::ImDocument::parse(text.to_string()).ok(),
        }
    }

    /// The 1-based line of `path` (`a.b[2].c`), or of its nearest located
    /// parent; `None` when nothing can be located.
    pub fn line(&self, path: &str) -> Option<usize> {
        let doc = self.doc.as_ref()?;
        let segments = sweep::parse_path(path).ok()?;
        let mut item: toml_edit::Item = doc.as_item().clone();
        let mut best: Option<usize> = None;
        for seg in segments {
            let next = match seg {
                sweep::Segment::Key(k) => {
                    let Some((key, v)) = item.as_table_like().and_then(|t| t.get_key_value(&k))
                    else {
                        return best;
                    };
                    if let Some(span) = key.span().or_else(|| v.span()) {
                        best = Some(line_of(&self.text, span.start));
                    }
                    v.clone()
                }
                sweep::Segment::Index(i) => {
                    if let Some(aot) = item.as_array_of_tables() {
                        let Some(t) = aot.get(i) else {
                            return best;
                        };
                        if let Some(span) = t.span() {
                            best = Some(line_of(&self.text, span.start));
                        }
                        toml_edit::Item::Table(t.clone())
                    } else {
                        let Some(v) = item.as_array().and_then(|a| a.get(i)) else {
                            return best;
                        };
                        if let Some(span) = v.span() {
                            best = Some(line_of(&self.text, span.start));
                        }
                        toml_edit::Item::Value(v.clone())
                    }
                }
            };
            item = next;
        }
        best
    }
}

/// 1-based line of byte offset `at`.
pub fn line_of(text: &str, at: usize) -> usize {
    text.as_bytes()[..at.min(text.len())]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
        + 1
}

fn one_line(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
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

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"
[study]
name = "t"
kind = "forward"

[scene]
chain = { n = 10, defects = [ { kind = "mass", at = 3, m = 2.0 } ] }

[[sweep]]
path = "chain.n"
values = [5, 10]
"#;

    #[test]
    fn good_file_has_no_problems() {
        assert_eq!(check(GOOD), vec![]);
        assert!(parse(GOOD, "GOOD").is_ok());
    }

    #[test]
    fn misspelled_fields_are_named_with_lines() {
        let bad = GOOD.replace("path = \"chain.n\"", "pth = \"chain.n\"");
        let p = check(&bad);
        assert!(
            p.iter().any(|p| p.path == "sweep[0].pth"
                && p.line == Some(10)
                && p.message.contains("did you mean `path`")),
            "{p:?}"
        );
        let bad = GOOD.replace("kind = \"mass\"", "kind = \"mass\", mm = 3");
        let p = check(&bad);
        assert!(
            p.iter()
                .any(|p| p.path == "scene.chain.defects[0].mm" && p.line == Some(7)),
            "{p:?}"
        );
    }

    #[test]
    fn every_problem_is_reported() {
        let bad = GOOD
            .replace("name = \"t\"", "name = \"t\"\nseeed = 1")
            .replace("[scene]", "[scene]\nobserv = 2\n[report]\nplots = 1");
        let p = check(&bad);
        let paths: Vec<&str> = p.iter().map(|p| p.path.as_str()).collect();
        assert!(paths.contains(&"study.seeed"), "{p:?}");
        assert!(paths.contains(&"scene.observ"), "{p:?}");
        assert!(paths.contains(&"report.plots"), "{p:?}");
    }

    #[test]
    fn case_level_problems_name_the_case() {
        // n = 2 makes the defect at 3 out of range, in one case only
        let bad = GOOD.replace("values = [5, 10]", "values = [2, 10]");
        let p = check(&bad);
        assert_eq!(p.len(), 1, "{p:?}");
        assert_eq!(p[0].path, "scene.chain.defects[0].at");
        assert!(
            p[0].message
                .contains("1 of 2 cases, first c0000: chain.n = 2"),
            "{p:?}"
        );
        // a misspelled sweep path is an unknown field of the case
        let bad = GOOD.replace("path = \"chain.n\"", "path = \"chain.nn\"");
        let p = check(&bad);
        assert!(p[0].message.contains("nn"), "{p:?}");
    }

    #[test]
    fn syntax_errors_have_lines() {
        let p = check("[study]\nname = \n");
        assert_eq!(p.len(), 1);
        assert_eq!(p[0].line, Some(2));
    }

    #[test]
    fn report_references_are_checked() {
        let bad = format!("{GOOD}\n[[report.plot]]\nx = \"chain.m\"\ny = \"max_rel\"\n");
        let p = check(&bad);
        let paths: Vec<&str> = p.iter().map(|p| p.path.as_str()).collect();
        assert_eq!(paths, vec!["report.plot[0].x", "report.plot[0].y"], "{p:?}");
    }
}
