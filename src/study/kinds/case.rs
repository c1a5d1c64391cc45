//! What every kind shares: the [`CaseOutput`] of a case, and the
//! [`KindScene`] trait that reads and checks a scene against its field
//! schema (every unknown field, every type error, every range check).
//! Below the kinds' own files and [`super`].

use crate::error::{check_f64, Error, Result};
use crate::study::paths::remove_path;
use crate::study::schema::{line_of, unknown_fields as schema_unknown_fields, FieldDoc, Problem};
use serde::de::DeserializeOwned;

/// The numbers (and pictures) one case produces.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CaseOutput {
    /// Reproducible results (a function of the scene and the seed only).
    pub metrics: serde_json::Map<String, serde_json::Value>,
    /// Measured wall-clock numbers (keys start with `t_`); not reproducible.
    pub timings: serde_json::Map<String, serde_json::Value>,
    /// Pictures of this case (written as `cases/<id>-<name>.svg`).
    pub plots: Vec<CasePlot>,
    /// The optimizer's trace, `[evaluations, best residual so far]` at each
    /// improvement (kind `fit` with `search.trace = true`); reproducible.
    pub trace: Vec<[f64; 2]>,
}

impl CaseOutput {
    /// Record the metric `key`: `v` as a JSON number (`null` when
    /// not finite).
    pub fn metric(&mut self, key: &str, v: f64) {
        self.metrics.insert(key.into(), num(v));
    }

    /// Record the timing `key` (measured seconds), as [`CaseOutput::metric`].
    pub fn timing(&mut self, key: &str, seconds: f64) {
        self.timings.insert(key.into(), num(seconds));
    }
}

/// One picture of one case.
#[derive(Clone, Debug, PartialEq)]
pub struct CasePlot {
    /// Short name (letters, digits, `_`), part of the file name.
    pub name: String,
    /// The SVG text.
    pub svg: String,
}

impl CasePlot {
    /// The picture `name` of the line plot `plot`.
    ///
    /// # Errors
    /// As [`crate::plot::LinePlot::to_svg_string`].
    pub fn of_lines(name: &str, plot: &crate::plot::LinePlot) -> Result<CasePlot> {
        Ok(CasePlot {
            name: name.into(),
            svg: plot.to_svg_string()?,
        })
    }
}

/// Unknown fields of `value` against `schema` (paths relative to the scene).
pub fn unknown_fields(value: &toml::Value, schema: &[FieldDoc]) -> Vec<Problem> {
    schema_unknown_fields(value, schema)
}

/// A kind's scene: deserialized against its field schema, then range-checked.
/// A kind implements [`KindScene::problems`]; reading and checking come free.
pub trait KindScene: DeserializeOwned {
    /// The documented fields of the scene (unknown fields are errors).
    const FIELDS: &'static [FieldDoc];

    /// Every failed range check, each naming its field.
    fn problems(&self) -> Vec<Error>;

    /// The scene with its aliases resolved to the schema's names (the
    /// scene as written by default).
    fn canonical(value: &toml::Value) -> toml::Value {
        value.clone()
    }

    /// The first of [`KindScene::problems`].
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming the field.
    fn check(&self) -> Result<()> {
        match self.problems().into_iter().next() {
            Some(e) => Err(e),
            None => Ok(()),
        }
    }

    /// Deserialize ([`from_scene`]) and check a resolved scene.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming the field.
    fn from_value(value: &toml::Value) -> Result<Self> {
        let scene: Self = from_scene(&Self::canonical(value), Self::FIELDS)?;
        scene.check()?;
        Ok(scene)
    }

    /// Every problem of a resolved scene, each naming its field: every
    /// unknown field; every field of the wrong type (found one at a time:
    /// each is reported and removed, so that the next one shows, its default
    /// standing in); then [`KindScene::problems`] of what remains. Empty
    /// exactly when [`KindScene::from_value`] succeeds.
    fn all_problems(value: &toml::Value) -> Vec<Error> {
        let (mut out, clean) = unknown_errors(&Self::canonical(value), Self::FIELDS);
        let (typed, scene) = typed_scene::<Self>(clean);
        out.extend(typed);
        if let Some(scene) = scene {
            out.extend(scene.problems());
        }
        out
    }
}

/// The unknown fields of `value` as errors (paths relative to the scene),
/// and `value` without them.
pub fn unknown_errors(value: &toml::Value, schema: &[FieldDoc]) -> (Vec<Error>, toml::Value) {
    let mut clean = value.clone();
    let mut out = Vec::new();
    for (path, e) in unknown_field_errors(value, schema) {
        remove_path(&mut clean, &path);
        out.push(e);
    }
    (out, clean)
}

/// Each unknown field of `value` against `schema`: its path relative to
/// the scene, and the error naming it.
fn unknown_field_errors(
    value: &toml::Value,
    schema: &[FieldDoc],
) -> impl Iterator<Item = (String, Error)> {
    unknown_fields(value, schema).into_iter().map(|p| {
        let path = p.path.strip_prefix("scene.").unwrap_or(&p.path).to_string();
        (path.clone(), Error::invalid(path, "present", p.message))
    })
}

/// Deserialize `value` as a `T`, collecting type errors: each failing field
/// is reported and removed (its default stands in) and deserialisation is
/// tried again. A missing required field ends the search (`None`).
pub fn typed_scene<T: DeserializeOwned>(mut value: toml::Value) -> (Vec<Error>, Option<T>) {
    let mut out: Vec<Error> = Vec::new();
    // fields removed for their type: their absence is no second problem
    let mut removed: Vec<String> = Vec::new();
    // at most one pass per field of the scene, and a hard bound
    for _ in 0..64 {
        match from_text::<T>(&value) {
            Ok(t) => return (out, Some(t)),
            Err(e) => {
                let field = match &e {
                    Error::InvalidParameter { field, .. } => field.clone(),
                    _ => String::new(),
                };
                let text = e.to_string();
                let missing = text.contains("missing field");
                let repeated = out.iter().any(|x| x.to_string() == text);
                let was_removed = missing
                    && removed.iter().any(|r| {
                        let name = r.rsplit('.').next().unwrap_or(r);
                        text.contains(&format!("missing field `{name}`"))
                    });
                if !repeated && !was_removed {
                    out.push(e);
                }
                if missing || repeated || field == "scene" || !remove_path(&mut value, &field) {
                    return (out, None);
                }
                removed.push(field);
            }
        }
    }
    (out, None)
}

/// The failed range checks among `checks`, in order: each is
/// `(field, value, ok, allowed)` as [`check_f64`] takes it.
pub fn range_problems(checks: &[(&str, f64, bool, &str)]) -> Vec<Error> {
    checks
        .iter()
        .filter_map(|&(field, v, ok, allowed)| check_f64(field, v, ok, allowed).err())
        .collect()
}

/// `e` with its field put under `prefix` (e.g. `perturbation.`): errors of
/// a sub-table checked on its own, named by their path in the scene.
pub fn prefix_field(e: Error, prefix: &str) -> Error {
    match e {
        Error::InvalidParameter {
            field,
            value,
            allowed,
        } => Error::InvalidParameter {
            field: format!("{prefix}{field}"),
            value,
            allowed,
        },
        other => other,
    }
}

/// `e` with its field put under `chain.`.
pub fn prefix_chain(e: Error) -> Error {
    prefix_field(e, "chain.")
}

/// Every problem of a chain spec, each naming its field (`chain.n`,
/// `chain.defects[1].m`): the uniform parameters one by one, each defect
/// on its own, then the defects together (duplicates).
pub fn chain_problems(spec: &crate::chain::ChainSpec) -> Vec<Error> {
    use crate::chain::Chain;
    let prefix = prefix_chain;
    let base = match Chain::new(spec.n) {
        Ok(c) => c,
        Err(e) => return vec![prefix(e)],
    };
    let mut out: Vec<Error> = [
        base.clone().with_k(spec.k).err(),
        base.clone().with_d(spec.d).err(),
        base.clone().with_gamma(spec.gamma).err(),
        base.clone().with_mass(spec.mass).err(),
    ]
    .into_iter()
    .flatten()
    .map(prefix)
    .collect();
    let mut each_ok = true;
    for (i, d) in spec.defects.iter().enumerate() {
        // a bad position hides a bad value: check the value at position 1 too
        let at_one = d.with_at(1);
        let errs: Vec<Error> = match base.clone().with_defect(*d) {
            Ok(_) => Vec::new(),
            Err(e) => {
                let bad_at =
                    matches!(&e, Error::InvalidParameter { field, .. } if field.ends_with(".at"));
                let mut v = vec![e];
                if bad_at {
                    v.extend(base.clone().with_defect(at_one).err());
                }
                v
            }
        };
        for e in errs {
            each_ok = false;
            // with_defect names the defect by its index in the chain (0 here)
            out.push(match prefix(e) {
                Error::InvalidParameter {
                    field,
                    value,
                    allowed,
                } => Error::InvalidParameter {
                    field: field.replacen("defects[0]", &format!("defects[{i}]"), 1),
                    value,
                    allowed: allowed.replacen("defects[0]", &format!("defects[{i}]"), 1),
                },
                other => other,
            });
        }
    }
    if out.is_empty() && each_ok {
        if let Err(e) = spec.build() {
            out.push(prefix(e));
        }
    }
    out
}

/// Deserialize a scene: first unknown fields (named with their path), then
/// serde (types and required fields).
///
/// # Errors
/// [`Error::InvalidParameter`] naming the field.
pub fn from_scene<T: DeserializeOwned>(value: &toml::Value, schema: &[FieldDoc]) -> Result<T> {
    if let Some((_, e)) = unknown_field_errors(value, schema).next() {
        return Err(e);
    }
    from_text(value)
}

/// Deserialize through text, so that serde's message carries a line we can
/// map back to the field path.
fn from_text<T: DeserializeOwned>(value: &toml::Value) -> Result<T> {
    let text = toml::to_string(value).map_err(|e| Error::invalid("scene", "?", e.to_string()))?;
    toml::from_str(&text).map_err(|e| {
        let field = e
            .span()
            .and_then(|s| field_at(&text, s.start))
            .unwrap_or_else(|| "scene".to_string());
        let msg = e.message().split_whitespace().collect::<Vec<_>>().join(" ");
        Error::invalid(field, "?", msg)
    })
}

/// The dotted path of the key whose value starts at byte `at` of a
/// `toml::to_string` output (best effort; `None` if not found).
fn field_at(text: &str, at: usize) -> Option<String> {
    let line_no = line_of(text, at);
    let mut table = String::new();
    // occurrences of each `[[array.of.tables]]` header so far
    let mut seen: std::collections::HashMap<String, usize> = std::collections::HashMap::new();
    for (i, line) in text.lines().enumerate() {
        let l = line.trim();
        if l.starts_with('[') {
            let name = l
                .trim_start_matches('[')
                .trim_end_matches(']')
                .trim_end_matches(']')
                .trim()
                .to_string();
            table = if l.starts_with("[[") {
                let c = seen.entry(name.clone()).or_insert(0);
                *c += 1;
                format!("{name}[{}]", *c - 1)
            } else {
                name
            };
        }
        if i + 1 == line_no {
            if l.starts_with('[') {
                return Some(table);
            }
            let key = l.split('=').next()?.trim().trim_matches('"');
            return Some(if table.is_empty() {
                key.to_string()
            } else {
                format!("{table}.{key}")
            });
        }
    }
    None
}

/// A metric's number: JSON `null` for a value that is not finite.
pub(crate) fn num(x: f64) -> serde_json::Value {
    serde_json::Number::from_f64(x)
        .map(serde_json::Value::Number)
        .unwrap_or(serde_json::Value::Null)
}
