//! `config check`: every problem of a study file in one pass.

use super::config::{
    check_structure, Aggregate, Axis, InvalidCases, StudyFile, MAIN_PART, PART_COLUMN, STUDY_FIELDS,
};
use super::kinds::{typed_scene, Kind};
use super::paths::remove_path;
use super::schema::{line_of, one_line, plain_message, Locator, Problem};
use super::sweep;
use crate::error::Error;

/// Every problem of a study file: syntax, unknown or misspelled fields
/// (anywhere, the scene included), types, sweep axes, report references, and
/// the checks of every case of the sweep. Empty when the file is good.
///
/// Never panics, whatever the input.
///
/// ```
/// use springmass::study::check::check;
/// let problems = check("[study]\nname = \"x\"\nkind = \"forward\"\nseeed = 3\n[scene]\nchain = { n = 5 }\n");
/// assert_eq!(problems.len(), 1);
/// assert_eq!(problems[0].path, "study.seeed");
/// assert_eq!(problems[0].line, Some(4));
/// assert!(problems[0].message.contains("did you mean 'seed'"));
/// ```
pub fn check(text: &str) -> Vec<Problem> {
    let value = match parse_table(text) {
        Ok(v) => v,
        Err(p) => return p,
    };
    let locate = Locator::new(text);
    // unknown fields everywhere (the scenes against their kinds' schemas)
    let mut problems = check_structure(text);
    // types of the fields outside the scenes: every wrong field is reported
    // and left out (its default stands in), so that the checks below still
    // see the rest of the file
    let root = toml::Value::Table(value);
    let mut clean = root.clone();
    for p in &problems {
        remove_path(&mut clean, &p.path);
    }
    let (typed, file) = typed_scene::<StudyFile>(clean);
    for e in typed {
        let (path, message) = plain_message(&e, Some(&root), STUDY_FIELDS);
        let path = if path == "scene" { String::new() } else { path };
        problems.push(Problem {
            line: locate.line(&path),
            path,
            message,
        });
    }
    if let Some(file) = file {
        problems.extend(check_semantics(&file, &locate));
    }
    let mut seen = Vec::new();
    problems.retain(|p| {
        let new = !seen.contains(p);
        seen.push(p.clone());
        new
    });
    // in file order (problems without a line last)
    problems.sort_by_key(|p| p.line.unwrap_or(usize::MAX));
    problems
}

/// `text` as a TOML table, or the one problem of its syntax.
fn parse_table(text: &str) -> Result<toml::Table, Vec<Problem>> {
    toml::from_str(text).map_err(|e: toml::de::Error| {
        vec![Problem {
            path: String::new(),
            line: e.span().map(|s| line_of(text, s.start)),
            message: format!("not valid TOML: {}", one_line(e.message())),
        }]
    })
}

/// `((path, message), (first failing case, failing cases, line at the axis))`.
type Found = ((String, String), (usize, usize, Option<usize>));

/// Checks that need the whole study: axes, report references, every case.
fn check_semantics(file: &StudyFile, locate: &Locator) -> Vec<Problem> {
    let mut c = Semantics {
        file,
        locate,
        problems: Vec::new(),
        names: vec![MAIN_PART],
        columns: vec!["repeat".into()],
    };
    c.study_block();
    c.part_names();
    c.sweep_axes();
    c.report_tables();
    c.report_plots();
    c.report_heatmaps();
    c.report_traces();
    let axes_ok = file
        .sweep
        .iter()
        .chain(file.part.iter().flat_map(|p| &p.sweep))
        .all(|a| sweep::axis_values(a).is_ok() && sweep::parse_path(&a.path).is_ok());
    if axes_ok && file.study.repeats > 0 {
        c.cases();
    }
    c.problems
}

/// The state of [`check_semantics`]: the problems found so far, the part
/// names and the axis columns (the names report items may refer to).
struct Semantics<'a> {
    file: &'a StudyFile,
    locate: &'a Locator,
    problems: Vec<Problem>,
    /// `main` and the names of the `[[part]]`s, in file order.
    names: Vec<&'a str>,
    /// `repeat`, the part column when there are parts, then every axis column.
    columns: Vec<String>,
}

/// Whether `name` is made of letters, digits, '-', '_' and '.' only (and is not empty).
fn plain_name(name: &str) -> bool {
    !name.is_empty()
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "-_.".contains(c))
}

impl<'a> Semantics<'a> {
    /// A problem at `path`, on the line of `path` in the file.
    fn push(&mut self, path: String, message: String) {
        let line = self.locate.line(&path);
        self.problems.push(Problem {
            path,
            line,
            message,
        })
    }

    /// `[study]`: the name (a file name) and the number of repeats.
    fn study_block(&mut self) {
        let name = &self.file.study.name;
        if !plain_name(name) || name.starts_with('.') {
            self.push(
                "study.name".into(),
                format!("{name:?} is not allowed: use letters, digits, '-', '_', '.', not starting with '.'"),
            );
        }
        if self.file.study.repeats == 0 {
            self.push(
                "study.repeats".into(),
                "0 is not allowed: repeats >= 1".into(),
            );
        }
    }

    /// `[[part]]`: every name plain and distinct (`main` included).
    fn part_names(&mut self) {
        let file = self.file;
        if !file.part.is_empty() {
            self.columns.push(PART_COLUMN.into());
        }
        for (i, p) in file.part.iter().enumerate() {
            let n = p.name.as_str();
            if !plain_name(n) {
                self.push(
                    format!("part[{i}].name"),
                    format!("{n:?} is not allowed: use letters, digits, '-', '_', '.'"),
                );
            } else if self.names.contains(&n) {
                self.push(
                    format!("part[{i}].name"),
                    format!("{n:?} is used twice (`main` is the part of [scene] and [[sweep]])"),
                );
            }
            self.names.push(n);
        }
    }

    /// `[[sweep]]` of the main part and of every part: values, paths and
    /// distinct columns; collects the columns.
    fn sweep_axes(&mut self) {
        let file = self.file;
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
                    self.push(format!("{prefix}sweep[{i}]"), e);
                }
                if let Err(e) = sweep::parse_path(&axis.path) {
                    self.push(format!("{prefix}sweep[{i}].path"), e);
                }
                let col = axis.column().to_string();
                if own.contains(&col) || col == "repeat" || col == PART_COLUMN {
                    self.push(
                        format!("{prefix}sweep[{i}].name"),
                        format!(
                            "axis column {col:?} is used twice (give the axes distinct `name`s)"
                        ),
                    );
                }
                own.push(col.clone());
                if !self.columns.contains(&col) {
                    self.columns.push(col);
                }
            }
        }
    }

    /// A report reference to an axis column.
    fn column(&mut self, path: String, col: &str) {
        if !self.columns.iter().any(|c| c == col) {
            let message = format!(
                "{col:?} is not an axis column; axes: {}",
                self.columns.join(", ")
            );
            self.push(path, message);
        }
    }

    /// A report item's `part` must name a part.
    fn part(&mut self, path: String, part: &Option<String>) {
        if let Some(p) = part {
            if !self.names.contains(&p.as_str()) {
                let message = format!("{p:?} is not a part; parts: {}", self.names.join(", "));
                self.push(path, message);
            }
        }
    }

    /// The kinds of the parts a report item covers: of its part when that is
    /// known, of every part otherwise (an unknown part is reported once, by
    /// [`Self::part`]; its metrics are then checked against every kind).
    fn kinds(&self, part: &Option<String>) -> Vec<Kind> {
        let known = part.as_deref().filter(|p| self.names.contains(p));
        self.file.kinds_of(known)
    }

    /// A report reference to a metric of the kinds of `part`.
    fn metric(&mut self, path: String, m: &str, part: &Option<String>) {
        let kinds = self.kinds(part);
        if kinds.iter().any(|k| k.metrics().iter().any(|x| x.0 == m)) {
            return;
        }
        let mut list: Vec<&str> = Vec::new();
        for k in &kinds {
            for x in k.metrics() {
                if !list.contains(&x.0) {
                    list.push(x.0);
                }
            }
        }
        let message = format!(
            "{m:?} is not a metric of kind {}; metrics: {}",
            kinds_label(&kinds),
            list.join(", ")
        );
        self.push(path, message);
    }

    /// `[[report.table]]`: rows, part, metrics.
    fn report_tables(&mut self) {
        for (i, t) in self.file.report.table.iter().enumerate() {
            for (j, r) in t.rows.iter().flatten().enumerate() {
                self.column(format!("report.table[{i}].rows[{j}]"), r);
            }
            self.part(format!("report.table[{i}].part"), &t.part);
            for (j, m) in t.metrics.iter().flatten().enumerate() {
                self.metric(format!("report.table[{i}].metrics[{j}]"), m, &t.part);
            }
        }
    }

    /// `[[report.plot]]`: x, series, part, y.
    fn report_plots(&mut self) {
        for (i, p) in self.file.report.plot.iter().enumerate() {
            self.column(format!("report.plot[{i}].x"), &p.x);
            if let Some(s) = &p.series {
                self.column(format!("report.plot[{i}].series"), s);
            }
            self.part(format!("report.plot[{i}].part"), &p.part);
            self.metric(format!("report.plot[{i}].y"), &p.y, &p.part);
        }
    }

    /// `[[report.heatmap]]`: x, y, part, z.
    fn report_heatmaps(&mut self) {
        for (i, h) in self.file.report.heatmap.iter().enumerate() {
            for (field, col) in [("x", &h.x), ("y", &h.y)] {
                self.column(format!("report.heatmap[{i}].{field}"), col);
            }
            self.part(format!("report.heatmap[{i}].part"), &h.part);
            self.metric(format!("report.heatmap[{i}].z"), &h.z, &h.part);
        }
    }

    /// `[[report.trace]]`: part (of kind fit), series, filter, aggregate.
    fn report_traces(&mut self) {
        for (i, t) in self.file.report.trace.iter().enumerate() {
            self.part(format!("report.trace[{i}].part"), &t.part);
            let kinds = self.kinds(&t.part);
            if !kinds.contains(&Kind::Fit) {
                self.push(
                    format!("report.trace[{i}]"),
                    format!(
                        "optimizer traces are recorded by kind fit only, not {}",
                        kinds_label(&kinds)
                    ),
                );
            }
            for (j, c) in t.series.iter().flatten().enumerate() {
                self.column(format!("report.trace[{i}].series[{j}]"), c);
            }
            for (c, v) in &t.filter {
                self.column(format!("report.trace[{i}].filter.{c}"), c);
                let ok = match v {
                    toml::Value::String(_) => true,
                    toml::Value::Array(a) => a.iter().all(|x| x.is_str()),
                    _ => false,
                };
                if !ok {
                    self.push(
                        format!("report.trace[{i}].filter.{c}"),
                        "a label (string) or an array of labels".into(),
                    );
                }
            }
            if matches!(t.aggregate, Aggregate::Rate | Aggregate::Count) {
                self.push(
                    format!("report.trace[{i}].aggregate"),
                    format!(
                        "{:?} is not allowed here: median, mean, min or max",
                        t.aggregate.name()
                    ),
                );
            }
        }
    }

    /// Every case: the kind's deserialisation and semantic checks. One
    /// problem per distinct message (a bad base field fails every case
    /// alike), naming the failing cases unless all fail.
    fn cases(&mut self) {
        let cases = match sweep::expand(self.file) {
            Err(e) => return self.push(String::new(), e.to_string()),
            Ok(cases) => cases,
        };
        let mut found = self.case_errors(&cases);
        self.untraced(&cases, &mut found);
        for ((path, message), (first, count, line)) in found {
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
            let message = format!("{message}{where_}");
            match line {
                Some(l) => self.problems.push(Problem {
                    path,
                    line: Some(l),
                    message,
                }),
                None => self.push(path, message),
            }
        }
    }

    /// The errors of every case, `(path, message) -> (first failing case,
    /// number of failing cases, line of the axis that sets the field)`, in
    /// order of first appearance.
    fn case_errors(&self, cases: &[sweep::Case]) -> Vec<Found> {
        let skip = self.file.study.invalid_cases == InvalidCases::Skip;
        let mut found: Vec<Found> = Vec::new();
        for (ci, case) in cases.iter().enumerate() {
            let errs = case.kind.validate_all(&case.scene);
            // with `skip`, unknown fields and values of the wrong type
            // still are errors (a misspelling or a type error would
            // otherwise skip every case): only failed range checks skip
            let errs = errs.into_iter().filter(|e| {
                !skip
                    || matches!(e, Error::InvalidParameter { value, .. } if value == "present" || value == "?")
            });
            let (scene, prefix, axes) = self.case_part(case);
            for e in errs {
                let (path, message) = plain_message(&e, Some(&case.scene), case.kind.schema());
                let line = self.axis_line(&path, &message, &prefix, axes);
                let path = if path.is_empty() || path == "scene" {
                    scene.clone()
                } else {
                    format!("{scene}.{path}")
                };
                let key = (path, message);
                match found.iter_mut().find(|(k, _)| *k == key) {
                    Some((_, (_, count, _))) => *count += 1,
                    None => found.push((key, (ci, 1, line))),
                }
            }
        }
        found
    }

    /// The scene path, the axis prefix and the axes of the case's part.
    fn case_part(&self, case: &sweep::Case) -> (String, String, &'a [Axis]) {
        let file = self.file;
        match case.params.first() {
            Some(p) if p.column == PART_COLUMN && p.label != MAIN_PART => {
                let i = file
                    .part
                    .iter()
                    .position(|x| x.name == p.label)
                    .unwrap_or(0);
                (
                    format!("part[{i}].scene"),
                    format!("part[{i}]."),
                    file.part.get(i).map(|p| &p.sweep[..]).unwrap_or(&[]),
                )
            }
            _ => ("scene".to_string(), String::new(), &file.sweep[..]),
        }
    }

    /// A field set by an axis is reported at the axis: the line of its
    /// `path` (an unknown field), `values` or `range`.
    fn axis_line(&self, path: &str, message: &str, prefix: &str, axes: &[Axis]) -> Option<usize> {
        let i = axes.iter().position(|a| {
            path == a.path
                || path.starts_with(&format!("{}.", a.path))
                || path.starts_with(&format!("{}[", a.path))
        })?;
        let field = if message.starts_with("unknown field") {
            "path"
        } else if axes[i].values.is_some() {
            "values"
        } else {
            "range"
        };
        self.locate
            .line(&format!("{prefix}sweep[{i}].{field}"))
            .or_else(|| self.locate.line(&format!("{prefix}sweep[{i}]")))
    }

    /// `report.trace` needs the optimizer trace of every fit case it covers.
    fn untraced(&self, cases: &[sweep::Case], found: &mut Vec<Found>) {
        let file = self.file;
        for t in &file.report.trace {
            let untraced: Vec<usize> = (0..cases.len())
                .filter(|&i| {
                    cases[i].kind == Kind::Fit
                        && t.part.as_deref().is_none_or(|p| {
                            cases[i]
                                .params
                                .first()
                                .is_some_and(|x| x.column == PART_COLUMN && x.label == p)
                                || (p == MAIN_PART && file.part.is_empty())
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
            if let Some(&first) = untraced.first() {
                if !found.iter().any(|f| f.0 == key) {
                    found.push((key, (first, untraced.len(), None)));
                }
            }
        }
    }
}

/// The kinds' names, joined by "or".
fn kinds_label(kinds: &[Kind]) -> String {
    kinds
        .iter()
        .map(|k| k.name())
        .collect::<Vec<_>>()
        .join(" or ")
}

/// What a TOML file is, for `config check`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FileKind {
    /// A study file (`[study]`, `[scene]`, `[[sweep]]`, ...): `springmass study FILE`.
    Study,
    /// A fit scene (`[chain]` at the top level, the format of
    /// [`crate::detect::scene::FitScene`]): `springmass fit --scene FILE`.
    FitScene,
}

impl FileKind {
    /// What the file is and how to run it, in one line.
    pub fn describe(&self) -> &'static str {
        match self {
            FileKind::Study => "this is a study file; run `springmass study FILE`",
            FileKind::FitScene => "this is a fit scene; run `springmass fit --scene FILE`",
        }
    }
}

/// What `text` is: a fit scene when it has a top-level `[chain]` (or
/// `[truth]`) table and no `[study]` table, a study file otherwise (also
/// when it does not parse).
pub fn file_kind(text: &str) -> FileKind {
    match toml::from_str::<toml::Table>(text) {
        Ok(t)
            if (t.contains_key("chain") || t.contains_key("truth")) && !t.contains_key("study") =>
        {
            FileKind::FitScene
        }
        _ => FileKind::Study,
    }
}

/// What the file is and every problem of it: [`check`] for a study file,
/// [`check_fit_scene`] for a fit scene.
///
/// ```
/// use springmass::study::check::{check_file, FileKind};
/// let (kind, problems) = check_file("[chain]\nn = 5\nnn = 3\n");
/// assert_eq!(kind, FileKind::FitScene);
/// assert_eq!(problems[0].path, "chain.nn");
/// assert_eq!(problems[0].line, Some(3));
/// assert!(problems[0].message.contains("did you mean 'n'"));
/// ```
pub fn check_file(text: &str) -> (FileKind, Vec<Problem>) {
    match file_kind(text) {
        FileKind::Study => (FileKind::Study, check(text)),
        FileKind::FitScene => (FileKind::FitScene, check_fit_scene(text)),
    }
}

/// Every problem of a fit scene (the file of `springmass fit --scene`):
/// every unknown field, every value of the wrong type and every failed
/// check of the scene (the checks of kind `fit`), each with its field path
/// and line; then parsing it with
/// [`crate::detect::scene::FitScene::from_toml`] and building its truth and
/// unknowns, in case those refuse what the checks let through.
pub fn check_fit_scene(text: &str) -> Vec<Problem> {
    let (value, truth) = match parse_table(text) {
        // `[truth]` is the other name of `[chain]`: checked as `chain`,
        // reported under the file's name
        Ok(mut v) => {
            let truth = !v.contains_key("chain") && v.contains_key("truth");
            if truth {
                let t = v.remove("truth").expect("checked above");
                v.insert("chain".into(), t);
            }
            (toml::Value::Table(v), truth)
        }
        Err(p) => return p,
    };
    let locate = Locator::new(text);
    let mut errors = Kind::Fit.validate_all(&value);
    if errors.is_empty() {
        let scene = crate::detect::scene::FitScene::from_toml(text);
        let err = match scene {
            Err(e) => Some(e),
            Ok(s) => s.truth().err().or_else(|| s.unknowns().err()),
        };
        errors.extend(err);
    }
    errors
        .iter()
        .map(|e| {
            let (mut path, message) = plain_message(e, Some(&value), Kind::Fit.schema());
            if truth && (path == "chain" || path.starts_with("chain.")) {
                path = format!("truth{}", &path["chain".len()..]);
            }
            Problem {
                line: locate.line(&path),
                path,
                message,
            }
        })
        .collect()
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
        assert!(crate::study::config::parse(GOOD, "GOOD").is_ok());
    }

    #[test]
    fn misspelled_fields_are_named_with_lines() {
        let bad = GOOD.replace("path = \"chain.n\"", "pth = \"chain.n\"");
        let p = check(&bad);
        assert!(
            p.iter().any(|p| p.path == "sweep[0].pth"
                && p.line == Some(10)
                && p.message.contains("did you mean 'path'")),
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

    #[test]
    fn plain_messages_name_the_field_and_the_value() {
        let bad = GOOD
            .replace("name = \"t\"", "name = \"t\"\nrepeats = \"two\"")
            .replace("m = 2.0", "m = \"heavy\"");
        let p = check(&bad);
        let find = |path: &str| p.iter().find(|x| x.path == path).cloned();
        let r = find("study.repeats").unwrap_or_else(|| panic!("{p:?}"));
        assert_eq!(r.message, "repeats must be an integer >= 1, got \"two\"");
        assert_eq!(r.line, Some(4));
        // the [scene] problem is found although [study] has one
        // a defect is one value to serde: its type error names the defect,
        // the line and the offending value
        let m = find("scene.chain.defects[0]").unwrap_or_else(|| panic!("{p:?}"));
        assert!(m.message.contains("\"heavy\""), "{m:?}");
        assert_eq!(m.line, Some(8));
    }

    #[test]
    fn fit_scenes_are_recognised() {
        assert_eq!(file_kind("[chain]\nn = 3\n"), FileKind::FitScene);
        assert_eq!(file_kind(GOOD), FileKind::Study);
        assert_eq!(file_kind("not toml ["), FileKind::Study);
        let (k, p) = check_file("[chain]\nn = 0\n");
        assert_eq!(k, FileKind::FitScene);
        assert_eq!(p.len(), 1, "{p:?}");
        assert_eq!(p[0].path, "chain.n");
        assert_eq!(p[0].line, Some(2));
        // `[truth]`, the other name of `[chain]`, is reported by its name
        let (k, p) = check_file("[truth]\nn = 0\n");
        assert_eq!(k, FileKind::FitScene);
        assert_eq!(p.len(), 1, "{p:?}");
        assert_eq!(p[0].path, "truth.n");
        assert_eq!(p[0].line, Some(2));
    }
}
