//! Case kinds: what one case of a study does.
//!
//! Each kind lives in its own file and provides a scene schema (a serde type
//! with `deny_unknown_fields` plus its [`FieldDoc`] list), the list of the
//! metrics it records, and `run(scene, seed) -> CaseOutput`. A case never
//! prints; it returns numbers. Adding a kind is one new file and one arm in
//! each `match` below.

pub mod fit;
pub mod forward;
pub mod locate;
pub mod suppress;

use super::config::{FieldDoc, Problem};
use crate::error::{Error, Result};
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

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

/// One picture of one case.
#[derive(Clone, Debug, PartialEq)]
pub struct CasePlot {
    /// Short name (letters, digits, `_`), part of the file name.
    pub name: String,
    /// The SVG text.
    pub svg: String,
}

/// The case kinds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Kind {
    /// Forward-model accuracy and speed: Woodbury closed form against the
    /// O(n) tridiagonal reference on an s grid.
    Forward,
    /// Active suppression (Theorem 3.1, Corollary 3.2) verified by simulation.
    Suppress,
    /// Defect detection by fitting (`detect::fit` on a `FitScene`).
    Fit,
    /// Explicit single-defect locators (section 4.1).
    Locate,
}

/// Every kind, in documentation order.
pub const ALL: &[Kind] = &[Kind::Forward, Kind::Suppress, Kind::Fit, Kind::Locate];

impl Kind {
    /// The name used in `study.kind`.
    pub fn name(&self) -> &'static str {
        match self {
            Kind::Forward => "forward",
            Kind::Suppress => "suppress",
            Kind::Fit => "fit",
            Kind::Locate => "locate",
        }
    }

    /// Parse a kind name.
    ///
    /// # Errors
    /// A message listing the kinds.
    pub fn from_name(name: &str) -> std::result::Result<Kind, String> {
        ALL.iter()
            .copied()
            .find(|k| k.name() == name)
            .ok_or_else(|| {
                format!(
                    "unknown kind {name:?}; kinds: {}",
                    ALL.iter().map(|k| k.name()).collect::<Vec<_>>().join(", ")
                )
            })
    }

    /// One paragraph on what a case of this kind does.
    pub fn summary(&self) -> &'static str {
        match self {
            Kind::Forward => forward::SUMMARY,
            Kind::Suppress => suppress::SUMMARY,
            Kind::Fit => fit::SUMMARY,
            Kind::Locate => locate::SUMMARY,
        }
    }

    /// The scene fields (paths relative to `[scene]`).
    pub fn schema(&self) -> &'static [FieldDoc] {
        match self {
            Kind::Forward => forward::FIELDS,
            Kind::Suppress => suppress::FIELDS,
            Kind::Fit => fit::FIELDS,
            Kind::Locate => locate::FIELDS,
        }
    }

    /// `(column, meaning)` of every metric and timing the kind records.
    pub fn metrics(&self) -> &'static [(&'static str, &'static str)] {
        match self {
            Kind::Forward => forward::METRICS,
            Kind::Suppress => suppress::METRICS,
            Kind::Fit => fit::METRICS,
            Kind::Locate => locate::METRICS,
        }
    }

    /// Check a resolved scene without running it: unknown fields, types,
    /// ranges.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming the field (relative to `[scene]`).
    pub fn validate(&self, scene: &toml::Value) -> Result<()> {
        match self {
            Kind::Forward => forward::Scene::from_value(scene).map(|_| ()),
            Kind::Suppress => suppress::Scene::from_value(scene).map(|_| ()),
            Kind::Fit => fit::scene(scene).map(|_| ()),
            Kind::Locate => locate::Scene::from_value(scene).map(|_| ()),
        }
    }

    /// Every problem of a resolved scene: every unknown field, every type
    /// error, and every failed range check of the fields that have the right
    /// type ([`KindScene::all_problems`]).
    pub fn validate_all(&self, scene: &toml::Value) -> Vec<Error> {
        match self {
            Kind::Forward => forward::Scene::all_problems(scene),
            Kind::Suppress => suppress::Scene::all_problems(scene),
            Kind::Fit => crate::detect::scene::FitScene::all_problems(scene),
            Kind::Locate => locate::Scene::all_problems(scene),
        }
    }

    /// Run one case.
    ///
    /// # Errors
    /// Whatever the case's computation reports; the runner records it as a
    /// failed case.
    pub fn run(&self, scene: &toml::Value, seed: u64) -> Result<CaseOutput> {
        match self {
            Kind::Forward => forward::run(&forward::Scene::from_value(scene)?, seed),
            Kind::Suppress => suppress::run(&suppress::Scene::from_value(scene)?, seed),
            Kind::Fit => fit::run(scene, seed),
            Kind::Locate => locate::run(&locate::Scene::from_value(scene)?, seed),
        }
    }
}

/// Unknown fields of `value` against `schema` (paths relative to the scene).
pub fn unknown_fields(value: &toml::Value, schema: &[FieldDoc]) -> Vec<Problem> {
    super::config::unknown_fields(value, schema)
}

/// A kind's scene: deserialized against its field schema, then range-checked.
/// A kind implements [`KindScene::problems`]; reading and checking come free.
pub trait KindScene: DeserializeOwned {
    /// The documented fields of the scene (unknown fields are errors).
    const FIELDS: &'static [FieldDoc];

    /// Every failed range check, each naming its field.
    fn problems(&self) -> Vec<Error>;

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
        let scene: Self = from_scene(value, Self::FIELDS)?;
        scene.check()?;
        Ok(scene)
    }

    /// Every problem of a resolved scene, each naming its field: every
    /// unknown field; every field of the wrong type (found one at a time:
    /// each is reported and removed, so that the next one shows, its default
    /// standing in); then [`KindScene::problems`] of what remains. Empty
    /// exactly when [`KindScene::from_value`] succeeds.
    fn all_problems(value: &toml::Value) -> Vec<Error> {
        let (mut out, clean) = unknown_errors(value, Self::FIELDS);
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
    for p in unknown_fields(value, schema) {
        let path = p.path.strip_prefix("scene.").unwrap_or(&p.path).to_string();
        remove_path(&mut clean, &path);
        out.push(Error::invalid(path, "present", p.message));
    }
    (out, clean)
}

/// Deserialize `value` as a `T`, collecting type errors: each failing field
/// is reported and removed (its default stands in) and deserialisation is
/// tried again. A missing required field ends the search (`None`).
pub fn typed_scene<T: DeserializeOwned>(mut value: toml::Value) -> (Vec<Error>, Option<T>) {
    let mut out: Vec<Error> = Vec::new();
    // at most one pass per field of the scene, and a hard bound
    for _ in 0..64 {
        match from_text::<T>(&value) {
            Ok(t) => return (out, Some(t)),
            Err(e) => {
                let field = match &e {
                    Error::InvalidParameter { field, .. } => field.clone(),
                    _ => String::new(),
                };
                let missing = e.to_string().contains("missing field");
                let repeated = out.iter().any(|x| x.to_string() == e.to_string());
                if !repeated {
                    out.push(e);
                }
                if missing || repeated || field == "scene" || !remove_path(&mut value, &field) {
                    return (out, None);
                }
            }
        }
    }
    (out, None)
}

/// Remove the field at `path` (`a.b[2].c`) from `value`; false when there
/// is no such field.
fn remove_path(value: &mut toml::Value, path: &str) -> bool {
    let Ok(segments) = super::sweep::parse_path(path) else {
        return false;
    };
    let Some((last, parents)) = segments.split_last() else {
        return false;
    };
    let mut cur = value;
    for seg in parents {
        let next = match (seg, cur) {
            (super::sweep::Segment::Key(k), toml::Value::Table(t)) => t.get_mut(k),
            (super::sweep::Segment::Index(i), toml::Value::Array(a)) => a.get_mut(*i),
            _ => None,
        };
        match next {
            Some(v) => cur = v,
            None => return false,
        }
    }
    match (last, cur) {
        (super::sweep::Segment::Key(k), toml::Value::Table(t)) => t.remove(k).is_some(),
        (super::sweep::Segment::Index(i), toml::Value::Array(a)) if *i < a.len() => {
            a.remove(*i);
            true
        }
        _ => false,
    }
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
    use crate::chain::{Chain, Defect};
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
        let at_one = match *d {
            Defect::Mass { m, .. } => Defect::Mass { at: 1, m },
            Defect::Spring { k, .. } => Defect::Spring { at: 1, k },
            Defect::Damper { d, .. } => Defect::Damper { at: 1, d },
        };
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
    if let Some(p) = unknown_fields(value, schema).into_iter().next() {
        let path = p.path.strip_prefix("scene.").unwrap_or(&p.path).to_string();
        return Err(Error::invalid(path, "present", p.message));
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
    let line_no = super::config::line_of(text, at);
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kinds_roundtrip_names() {
        for k in ALL {
            assert_eq!(Kind::from_name(k.name()), Ok(*k));
            assert!(!k.schema().is_empty());
            assert!(!k.metrics().is_empty());
        }
        assert!(Kind::from_name("fwd").unwrap_err().contains("forward"));
    }

    #[test]
    fn type_errors_name_the_field() {
        let v: toml::Value = toml::from_str("chain = { n = 5.5 }").unwrap();
        let e = Kind::Forward.validate(&v).unwrap_err();
        match e {
            Error::InvalidParameter { field, .. } => assert_eq!(field, "chain.n"),
            other => panic!("{other:?}"),
        }
        let v: toml::Value = toml::from_str("chain = { n = 5 }\ns = { count = \"x\" }").unwrap();
        match Kind::Forward.validate(&v).unwrap_err() {
            Error::InvalidParameter { field, .. } => assert_eq!(field, "s.count"),
            other => panic!("{other:?}"),
        }
    }
}
