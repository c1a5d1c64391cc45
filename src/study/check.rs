//! `config check`: every problem of a study file in one pass.

use super::config::{
    check_structure, Aggregate, InvalidCases, StudyFile, MAIN_PART, PART_COLUMN, STUDY_FIELDS,
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

/// `((path, message), (first failing case, failing cases, line at the axis))`.
type Found = ((String, String), (usize, usize, Option<usize>));

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
        columns.push(PART_COLUMN.into());
    }
    let mut names: Vec<&str> = vec![MAIN_PART];
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
            if own.contains(&col) || col == "repeat" || col == PART_COLUMN {
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
            let mut found: Vec<Found> = Vec::new();
            for (ci, case) in cases.iter().enumerate() {
                let errs = case.kind.validate_all(&case.scene);
                // with `skip`, unknown fields and values of the wrong type
                // still are errors (a misspelling or a type error would
                // otherwise skip every case): only failed range checks skip
                let errs: Vec<Error> = errs
                    .into_iter()
                    .filter(|e| {
                        !skip
                            || matches!(e, Error::InvalidParameter { value, .. } if value == "present" || value == "?")
                    })
                    .collect();
                // the scene and the axes of the case's part
                let (scene, prefix, axes) = match case.params.first() {
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
                };
                for e in errs {
                    let (path, message) = plain_message(&e, Some(&case.scene), case.kind.schema());
                    // a field set by an axis is reported at the axis
                    let line = axes
                        .iter()
                        .position(|a| {
                            path == a.path
                                || path.starts_with(&format!("{}.", a.path))
                                || path.starts_with(&format!("{}[", a.path))
                        })
                        .and_then(|i| {
                            let field = if message.starts_with("unknown field") {
                                "path"
                            } else if axes[i].values.is_some() {
                                "values"
                            } else {
                                "range"
                            };
                            locate
                                .line(&format!("{prefix}sweep[{i}].{field}"))
                                .or_else(|| locate.line(&format!("{prefix}sweep[{i}]")))
                        });
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
                if let Some(&first) = untraced
                    .first()
                    .filter(|_| !found.iter().any(|f| f.0 == key))
                {
                    found.push((
                        (
                            "scene.search.trace".to_string(),
                            "report.trace needs the optimizer trace of every case: set search.trace = true (in every value of a swept `search` table too)".to_string(),
                        ),
                        (first, untraced.len(), None),
                    ));
                }
            }
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
                    Some(l) => problems.borrow_mut().push(Problem {
                        path,
                        line: Some(l),
                        message,
                    }),
                    None => push(path, message),
                }
            }
        }
    }
    problems.into_inner()
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

/// What `text` is: a fit scene when it has a top-level `[chain]` table and
/// no `[study]` table, a study file otherwise (also when it does not parse).
pub fn file_kind(text: &str) -> FileKind {
    match toml::from_str::<toml::Table>(text) {
        Ok(t) if t.contains_key("chain") && !t.contains_key("study") => FileKind::FitScene,
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
    let value: toml::Value = match toml::from_str::<toml::Table>(text) {
        Ok(v) => toml::Value::Table(v),
        Err(e) => {
            return vec![Problem {
                path: String::new(),
                line: e.span().map(|s| line_of(text, s.start)),
                message: format!("not valid TOML: {}", one_line(e.message())),
            }]
        }
    };
    let locate = Locator::new(text);
    let mut problems: Vec<Problem> = Vec::new();
    for e in Kind::Fit.validate_all(&value) {
        let (path, message) = plain_message(&e, Some(&value), Kind::Fit.schema());
        problems.push(Problem {
            line: locate.line(&path),
            path,
            message,
        });
    }
    if problems.is_empty() {
        let scene = crate::detect::scene::FitScene::from_toml(text);
        let err = match scene {
            Err(e) => Some(e),
            Ok(s) => s.truth().err().or_else(|| s.unknowns().err()),
        };
        if let Some(e) = err {
            let (path, message) = plain_message(&e, Some(&value), Kind::Fit.schema());
            problems.push(Problem {
                line: locate.line(&path),
                path,
                message,
            });
        }
    }
    problems
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
    }
}
