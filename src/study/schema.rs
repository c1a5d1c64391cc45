//! The bottom of the study module: field documentation ([`FieldDoc`]),
//! problems ([`Problem`]) with their lines, and the unknown-field walk with
//! its "did you mean" suggestion. Imports nothing of the study module but
//! [`super::paths`].

use super::paths::{get_path, parse_path, Segment};
use crate::error::Error;
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

    /// The field with its contents free-form:
    /// `FieldDoc::new(..).opaque()`.
    pub const fn opaque(self) -> FieldDoc {
        FieldDoc {
            opaque: true,
            ..self
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
                        let message = match closest(key, &siblings) {
                            Some(s) => format!("unknown field '{key}' (did you mean '{s}'?)"),
                            None if siblings.is_empty() => {
                                format!("unknown field '{key}'; no fields here")
                            }
                            None => format!(
                                "unknown field '{key}'; fields here: {}",
                                siblings.join(", ")
                            ),
                        };
                        out.push(Problem {
                            line: locate.line(&full),
                            path: full,
                            message,
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

/// The [`FieldDoc`] of a concrete path (`chain.defects[1].m` is documented
/// as `chain.defects[].m`).
pub fn doc_of<'a>(schema: &'a [FieldDoc], path: &str) -> Option<&'a FieldDoc> {
    let mut generic = String::with_capacity(path.len());
    let mut in_index = false;
    for c in path.chars() {
        match c {
            '[' => {
                in_index = true;
                generic.push('[');
            }
            ']' => {
                in_index = false;
                generic.push(']');
            }
            _ if in_index => {}
            _ => generic.push(c),
        }
    }
    schema.iter().find(|f| f.path == generic)
}

/// The field path an error names and a plain one-line message for it:
/// `unknown field 'nn' (did you mean 'n'?)`, `n must be an integer >= 1,
/// got -3` (a value of the wrong type, described by the field's type in
/// `schema` and the value found in `root`), `m = 0 is not allowed: m > 0 and
/// finite` (a failed range check). Paths are relative to `root`.
pub fn plain_message(
    e: &Error,
    root: Option<&toml::Value>,
    schema: &[FieldDoc],
) -> (String, String) {
    match e {
        Error::InvalidParameter {
            field,
            value,
            allowed,
        } => {
            let key = field
                .rsplit('.')
                .next()
                .unwrap_or(field)
                .split('[')
                .next()
                .unwrap_or(field);
            let message = if value == "present" {
                // an unknown field: the walk's message
                allowed.clone()
            } else if value == "?" {
                // serde: a wrong type, a bad enum value, a missing field
                let found = root.and_then(|r| get_path(r, field));
                match (
                    allowed.starts_with("missing field"),
                    doc_of(schema, field),
                    found,
                ) {
                    (true, _, _) => allowed.replace('`', "'"),
                    (false, Some(doc), Some(v)) => format!(
                        "{key} must be {}{}, got {}",
                        article(doc.ty),
                        doc.ty.replace('`', ""),
                        show(v)
                    ),
                    _ => format!("{key}: {}", allowed.replace('`', "'")),
                }
            } else {
                format!("{key} = {value} is not allowed: {allowed}")
            };
            (field.clone(), message)
        }
        Error::Parse { input, reason, .. } => (input.clone(), reason.clone()),
        other => (String::new(), other.to_string()),
    }
}

/// `a ` or `an ` before a type in words (nothing before a list of values).
fn article(ty: &str) -> &'static str {
    match ty.chars().next() {
        Some(c) if "aeiou".contains(c) => "an ",
        Some(c) if c.is_ascii_alphabetic() => "a ",
        _ => "",
    }
}

/// A TOML value as written in a file (short).
fn show(v: &toml::Value) -> String {
    let s = match v {
        toml::Value::String(s) => format!("{s:?}"),
        toml::Value::Table(_) => "a table".to_string(),
        toml::Value::Array(_) => "an array".to_string(),
        other => other.to_string(),
    };
    if s.chars().count() > 40 {
        format!("{}...", s.chars().take(40).collect::<String>())
    } else {
        s
    }
}
