//! The bottom of the study module: field documentation ([`FieldDoc`]),
//! problems ([`Problem`]) with their lines, and the unknown-field walk with
//! its "did you mean" suggestion. Imports nothing of the study module but
//! [`super::paths`].

use super::paths::{parse_path, Segment};
use serde::Serialize;

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

/// Check `value` (at `path`, schema-relative `rel`) against `schema`: every
/// key must be documented. Reports unknown keys with a suggestion.
pub(crate) fn walk(
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
        let segments = parse_path(path).ok()?;
        let mut item: toml_edit::Item = doc.as_item().clone();
        let mut best: Option<usize> = None;
        for seg in segments {
            let next = match seg {
                Segment::Key(k) => {
                    let Some((key, v)) = item.as_table_like().and_then(|t| t.get_key_value(&k))
                    else {
                        return best;
                    };
                    if let Some(span) = key.span().or_else(|| v.span()) {
                        best = Some(line_of(&self.text, span.start));
                    }
                    v.clone()
                }
                Segment::Index(i) => {
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

pub(crate) fn one_line(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}
