//! Expanding a study into cases, deterministically.
//!
//! The axes are crossed in file order, the first axis varying slowest (like
//! nested loops), with `study.repeats` replicates innermost. Case `i` of the
//! expansion has
//!
//! - the id `c0000i` (zero-padded to at least 4 digits, so that ids sort like
//!   their positions: the report is ordered by id),
//! - a content key: the FNV-1a hash of the canonical JSON of its parameters
//!   (the axis values and the repeat), and
//! - the seed `splitmix64(study.seed ^ key)`: a function of what the case *is*,
//!   not of when or where it runs, so it is the same for any thread count,
//!   completion order or shard. An axis marked `paired = true` is left out
//!   of the seed (not of the key): its values see the same records, for a
//!   paired comparison of settings.
//!
//! ```
//! use springmass::study::{config::parse, sweep::expand};
//! let file = parse(r#"
//!     [study]
//!     name = "demo"
//!     kind = "forward"
//!     repeats = 2
//!     [scene]
//!     chain = { n = 5 }
//!     [[sweep]]
//!     path = "chain.n"
//!     range = { from = 5, to = 500, count = 3, spacing = "log", integer = true }
//! "#, "demo")?;
//! let cases = expand(&file)?;
//! assert_eq!(cases.len(), 6);
//! assert_eq!(cases[2].id, "c0002");
//! assert_eq!(cases[2].scene["chain"]["n"].as_integer(), Some(50));
//! assert_ne!(cases[2].seed, cases[3].seed); // the two repeats differ
//! # Ok::<(), springmass::Error>(())
//! ```

use super::config::{Axis, Spacing, StudyFile};
pub use super::config::{MAIN_PART, PART_COLUMN};
use super::kinds::Kind;
pub use super::paths::{parse_path, set_path, Segment};
pub use super::seeds::{fnv1a, splitmix64};
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};

/// One case of a study.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Case {
    /// Position in the expansion (0-based).
    pub index: usize,
    /// Stable id, `c` and the zero-padded index; ids sort like indices.
    pub id: String,
    /// Content hash of the parameters (16 hex digits).
    pub key: String,
    /// The case's seed, derived from the study seed and `key`.
    pub seed: u64,
    /// Replicate number, `0..repeats`.
    pub repeat: usize,
    /// `(column, value, label)` of every axis, in axis order.
    pub params: Vec<Param>,
    /// The resolved scene: the base scene with the axis values set.
    pub scene: toml::Value,
    /// What the case does: `study.kind`, or the kind of its `[[part]]`.
    pub kind: Kind,
}

/// The value of one axis in one case.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Param {
    /// The axis column (its `name` or `path`).
    pub column: String,
    /// The value, as JSON.
    pub value: serde_json::Value,
    /// The label (the axis `labels` entry, or the value as text).
    pub label: String,
    /// The axis is left out of the seed (`sweep[].paired`).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub paired: bool,
}

impl Case {
    /// `column = label, ...` for messages.
    pub fn describe(&self) -> String {
        self.params
            .iter()
            .map(|p| format!("{} = {}", p.column, p.label))
            .collect::<Vec<_>>()
            .join(", ")
    }
}

/// The values of one axis, with their labels.
///
/// # Errors
/// A message: neither or both of `values` / `range`, a bad range, labels
/// of the wrong length, no values.
pub fn axis_values(axis: &Axis) -> std::result::Result<Vec<(toml::Value, String)>, String> {
    let values: Vec<toml::Value> = match (&axis.values, &axis.range) {
        (Some(_), Some(_)) => return Err("give `values` or `range`, not both".into()),
        (None, None) => return Err("give `values` or `range`".into()),
        (Some(v), None) => v.clone(),
        (None, Some(r)) => range_values(r)?,
    };
    if values.is_empty() {
        return Err("the axis has no values".into());
    }
    if values.len() > MAX_AXIS {
        return Err(format!(
            "the axis has {} values; at most {MAX_AXIS}",
            values.len()
        ));
    }
    let labels: Vec<String> = match &axis.labels {
        Some(l) if l.len() != values.len() => {
            return Err(format!(
                "`labels` has {} entries for {} values",
                l.len(),
                values.len()
            ))
        }
        Some(l) => l.clone(),
        None => values.iter().map(label_of).collect(),
    };
    Ok(values.into_iter().zip(labels).collect())
}

/// Most values on one axis, and most cases in one study.
pub const MAX_AXIS: usize = 100_000;
/// Most cases in one study.
pub const MAX_CASES: usize = 200_000;

fn range_values(r: &super::config::Range) -> std::result::Result<Vec<toml::Value>, String> {
    if !r.from.is_finite() || !r.to.is_finite() {
        return Err("range: `from` and `to` must be finite".into());
    }
    let pts: Vec<f64> = match (r.count, r.step) {
        (Some(_), Some(_)) => return Err("range: give `count` or `step`, not both".into()),
        (None, None) => return Err("range: give `count` or `step`".into()),
        (Some(0), None) => return Err("range: `count` must be >= 1".into()),
        (Some(c), None) if c > MAX_AXIS => {
            return Err(format!("range: `count` = {c}; at most {MAX_AXIS}"))
        }
        (Some(c), None) => match r.spacing {
            Spacing::Linear => (0..c)
                .map(|i| {
                    if c == 1 {
                        r.from
                    } else if i == c - 1 {
                        r.to
                    } else {
                        r.from + (r.to - r.from) * i as f64 / (c - 1) as f64
                    }
                })
                .collect(),
            Spacing::Log => {
                if r.from <= 0.0 || r.to <= 0.0 {
                    return Err("range: log spacing needs `from` > 0 and `to` > 0".into());
                }
                let (a, b) = (r.from.ln(), r.to.ln());
                (0..c)
                    .map(|i| {
                        if c == 1 {
                            r.from
                        } else if i == c - 1 {
                            r.to
                        } else if i == 0 {
                            r.from
                        } else {
                            (a + (b - a) * i as f64 / (c - 1) as f64).exp()
                        }
                    })
                    .collect()
            }
        },
        (None, Some(step)) => {
            if r.spacing == Spacing::Log {
                return Err("range: `step` needs linear spacing; use `count` with log".into());
            }
            if !(step.is_finite() && step > 0.0) {
                return Err("range: `step` must be > 0 and finite".into());
            }
            let span = (r.to - r.from).abs();
            let n = (span / step + 1e-9).floor();
            if n + 1.0 > MAX_AXIS as f64 {
                return Err(format!("range: more than {MAX_AXIS} points"));
            }
            let sign = if r.to >= r.from { 1.0 } else { -1.0 };
            (0..=n as usize)
                .map(|i| r.from + sign * step * i as f64)
                .collect()
        }
    };
    if r.integer {
        let mut out: Vec<i64> = Vec::with_capacity(pts.len());
        for p in pts {
            let v = p.round();
            if v.abs() > 9.0e15 {
                return Err(format!("range: {p} is too large for an integer"));
            }
            let v = v as i64;
            if !out.contains(&v) {
                out.push(v);
            }
        }
        Ok(out.into_iter().map(toml::Value::Integer).collect())
    } else {
        Ok(pts.into_iter().map(toml::Value::Float).collect())
    }
}

/// A short label for a value: numbers and strings as written, others as
/// compact JSON.
pub fn label_of(v: &toml::Value) -> String {
    match v {
        toml::Value::String(s) => s.clone(),
        toml::Value::Integer(i) => i.to_string(),
        toml::Value::Float(f) => format_float(*f),
        toml::Value::Boolean(b) => b.to_string(),
        other => serde_json::to_string(&to_json(other)).unwrap_or_default(),
    }
}

/// Shortest round-trip text of a float (`1e-5`, `0.25`, `3`).
pub fn format_float(f: f64) -> String {
    if f.is_finite() && f == f.trunc() && f.abs() < 1e15 {
        format!("{f:.0}")
    } else {
        format!("{f}")
    }
}

/// TOML value to JSON (datetimes become strings).
pub fn to_json(v: &toml::Value) -> serde_json::Value {
    match v {
        toml::Value::String(s) => serde_json::Value::String(s.clone()),
        toml::Value::Integer(i) => serde_json::Value::from(*i),
        toml::Value::Float(f) => serde_json::Number::from_f64(*f)
            .map(serde_json::Value::Number)
            .unwrap_or(serde_json::Value::Null),
        toml::Value::Boolean(b) => serde_json::Value::Bool(*b),
        toml::Value::Datetime(d) => serde_json::Value::String(d.to_string()),
        toml::Value::Array(a) => serde_json::Value::Array(a.iter().map(to_json).collect()),
        toml::Value::Table(t) => {
            serde_json::Value::Object(t.iter().map(|(k, v)| (k.clone(), to_json(v))).collect())
        }
    }
}

/// Expand a study into its cases (axes crossed, first slowest; repeats innermost).
///
/// # Errors
/// [`Error::InvalidParameter`] naming the axis (`sweep[i]`) for a bad axis or
/// path, or when the study has more than [`MAX_CASES`] cases.
pub fn expand(file: &StudyFile) -> Result<Vec<Case>> {
    let repeats = file.study.repeats;
    if repeats == 0 {
        return Err(Error::invalid("study.repeats", 0, "repeats >= 1"));
    }
    // (kind, part label, base scene, axes, field prefix of the axes)
    let mut parts: Vec<PartRef> = vec![(
        file.study.kind,
        None,
        &file.scene,
        &file.sweep,
        String::new(),
    )];
    if !file.part.is_empty() {
        parts[0].1 = Some(MAIN_PART);
        for (i, p) in file.part.iter().enumerate() {
            parts.push((
                p.kind,
                Some(p.name.as_str()),
                &p.scene,
                &p.sweep,
                format!("part[{i}]."),
            ));
        }
    }
    let mut all: Vec<(Kind, Vec<Param>, usize, toml::Value)> = Vec::new();
    for (kind, label, scene, sweep, prefix) in parts {
        let head = label.map(|l| Param {
            column: PART_COLUMN.to_string(),
            value: serde_json::Value::String(l.to_string()),
            label: l.to_string(),
            paired: false,
        });
        for (params, repeat, scene) in expand_part(scene, sweep, repeats, &prefix, head)? {
            all.push((kind, params, repeat, scene));
            if all.len() > MAX_CASES {
                return Err(Error::invalid(
                    "sweep",
                    "too many cases",
                    format!("at most {MAX_CASES} cases"),
                ));
            }
        }
    }
    let width = (all.len().saturating_sub(1)).to_string().len().max(4);
    Ok(all
        .into_iter()
        .enumerate()
        .map(|(index, (kind, params, repeat, scene))| {
            let hash = |all: bool| {
                let content = serde_json::json!({
                    "params": params
                        .iter()
                        .filter(|p| all || !p.paired)
                        .map(|p| (p.column.clone(), p.value.clone()))
                        .collect::<Vec<_>>(),
                    "repeat": repeat,
                });
                fnv1a(content.to_string().as_bytes())
            };
            // the key names the case; the seed leaves paired axes out
            let (key, seeded) = (hash(true), hash(false));
            Case {
                index,
                id: format!("c{index:0width$}"),
                key: format!("{key:016x}"),
                seed: splitmix64(file.study.seed ^ seeded),
                repeat,
                params,
                scene,
                kind,
            }
        })
        .collect())
}

/// (kind, part label, base scene, axes, field prefix of the axes) of one part.
type PartRef<'a> = (Kind, Option<&'a str>, &'a toml::Table, &'a [Axis], String);

/// The `(params, repeat, scene)` of one part: its axes crossed, the first
/// slowest, repeats innermost; `head` (the part column) first in `params`.
fn expand_part(
    base: &toml::Table,
    sweep: &[Axis],
    repeats: usize,
    prefix: &str,
    head: Option<Param>,
) -> Result<Vec<(Vec<Param>, usize, toml::Value)>> {
    let mut axes: Vec<Vec<(toml::Value, String)>> = Vec::new();
    for (i, a) in sweep.iter().enumerate() {
        let vals = axis_values(a)
            .map_err(|e| Error::invalid(format!("{prefix}sweep[{i}]"), &a.path, e))?;
        parse_path(&a.path)
            .map_err(|e| Error::invalid(format!("{prefix}sweep[{i}].path"), &a.path, e))?;
        axes.push(vals);
    }
    let mut total: usize = repeats;
    for a in &axes {
        total = total
            .checked_mul(a.len())
            .filter(|&t| t <= MAX_CASES)
            .ok_or_else(|| {
                Error::invalid(
                    "sweep",
                    "too many cases",
                    format!("at most {MAX_CASES} cases"),
                )
            })?;
    }
    let base = toml::Value::Table(base.clone());
    let mut cases = Vec::with_capacity(total);
    let mut idx = vec![0usize; axes.len()];
    for index in 0..total {
        // mixed-radix digits: repeats innermost, then the last axis, ...
        let mut rest = index / repeats;
        let repeat = index % repeats;
        for k in (0..axes.len()).rev() {
            idx[k] = rest % axes[k].len();
            rest /= axes[k].len();
        }
        let mut scene = base.clone();
        let mut params: Vec<Param> = head.iter().cloned().collect();
        for (k, axis) in sweep.iter().enumerate() {
            let (v, label) = &axes[k][idx[k]];
            set_path(&mut scene, &axis.path, v.clone())
                .map_err(|e| Error::invalid(format!("{prefix}sweep[{k}].path"), &axis.path, e))?;
            params.push(Param {
                column: axis.column().to_string(),
                value: to_json(v),
                label: label.clone(),
                paired: axis.paired,
            });
        }
        cases.push((params, repeat, scene));
    }
    Ok(cases)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::study::config::{parse, Range};

    fn range(from: f64, to: f64, count: Option<usize>, step: Option<f64>) -> Range {
        Range {
            from,
            to,
            count,
            step,
            spacing: Spacing::Linear,
            integer: false,
        }
    }

    #[test]
    fn ranges() {
        let v = range_values(&range(0.0, 1.0, Some(5), None)).unwrap();
        assert_eq!(v.last().unwrap().as_float(), Some(1.0));
        assert_eq!(v[1].as_float(), Some(0.25));
        let v = range_values(&range(1.0, 2.0, None, Some(0.1))).unwrap();
        assert_eq!(v.len(), 11); // 2.0 included despite rounding
        let v = range_values(&range(3.0, 1.0, None, Some(1.0))).unwrap();
        assert_eq!(v.len(), 3);
        let mut r = range(5.0, 100000.0, Some(9), None);
        r.spacing = Spacing::Log;
        r.integer = true;
        let v = range_values(&r).unwrap();
        assert_eq!(v.first().unwrap().as_integer(), Some(5));
        assert_eq!(v.last().unwrap().as_integer(), Some(100000));
        assert!(range_values(&range(0.0, 1.0, Some(0), None)).is_err());
        assert!(range_values(&range(0.0, 1.0, None, Some(-1.0))).is_err());
        assert!(range_values(&range(0.0, 1.0, Some(2), Some(1.0))).is_err());
        assert!(range_values(&range(0.0, 1e300, None, Some(1e-300))).is_err());
        let mut r = range(0.0, 1.0, Some(3), None);
        r.spacing = Spacing::Log;
        assert!(range_values(&r).is_err());
    }

    #[test]
    fn paths() {
        assert_eq!(
            parse_path("a.b[2][0].c").unwrap(),
            vec![
                Segment::Key("a".into()),
                Segment::Key("b".into()),
                Segment::Index(2),
                Segment::Index(0),
                Segment::Key("c".into())
            ]
        );
        for bad in ["", "a..b", "a[", "a[x]", "a[1]b", ".a", "a b"] {
            assert!(parse_path(bad).is_err(), "{bad}");
        }
        let mut v: toml::Value = toml::from_str("x = { y = [ { z = 1 } ] }").unwrap();
        set_path(&mut v, "x.y[0].z", toml::Value::Integer(5)).unwrap();
        set_path(&mut v, "p.q", toml::Value::Integer(6)).unwrap();
        assert_eq!(v["x"]["y"][0]["z"].as_integer(), Some(5));
        assert_eq!(v["p"]["q"].as_integer(), Some(6));
        assert!(set_path(&mut v, "x.y[3].z", toml::Value::Integer(1)).is_err());
        assert!(set_path(&mut v, "p.q.r", toml::Value::Integer(1)).is_err());
    }

    #[test]
    fn expansion_is_crossed_first_slowest_and_seeds_follow_content() {
        let text = r#"
            [study]
            name = "t"
            kind = "forward"
            seed = 11
            [scene]
            chain = { n = 5 }
            [[sweep]]
            path = "chain.n"
            values = [5, 6]
            [[sweep]]
            path = "chain.d"
            values = [0.1, 0.2, 0.3]
        "#;
        let f = parse(text, "t").unwrap();
        let c = expand(&f).unwrap();
        assert_eq!(c.len(), 6);
        let pairs: Vec<(i64, f64)> = c
            .iter()
            .map(|c| {
                (
                    c.scene["chain"]["n"].as_integer().unwrap(),
                    c.scene["chain"]["d"].as_float().unwrap(),
                )
            })
            .collect();
        assert_eq!(pairs[0], (5, 0.1));
        assert_eq!(pairs[2], (5, 0.3));
        assert_eq!(pairs[3], (6, 0.1));
        // adding a value to an axis keeps the seeds of the existing points
        let f2 = parse(&text.replace("[5, 6]", "[5, 6, 7]"), "t").unwrap();
        let c2 = expand(&f2).unwrap();
        assert_eq!(c2[4].seed, c[4].seed);
        assert_eq!(c2[4].key, c[4].key);
        // another master seed changes every seed
        let f3 = parse(&text.replace("seed = 11", "seed = 12"), "t").unwrap();
        assert!(expand(&f3)
            .unwrap()
            .iter()
            .zip(&c)
            .all(|(a, b)| a.seed != b.seed));
        let mut seeds: Vec<u64> = c.iter().map(|c| c.seed).collect();
        seeds.dedup();
        assert_eq!(seeds.len(), 6);
    }

    #[test]
    fn a_paired_axis_shares_the_seeds_of_its_values_not_their_keys() {
        let text = r#"
            [study]
            name = "t"
            kind = "forward"
            seed = 11
            repeats = 2
            [scene]
            chain = { n = 5 }
            [[sweep]]
            path = "chain.n"
            values = [5, 6]
            [[sweep]]
            path = "chain.d"
            values = [0.1, 0.2]
            paired = true
        "#;
        let c = expand(&parse(text, "t").unwrap()).unwrap();
        // order: n slowest, then d, repeats innermost
        assert_eq!(c[0].seed, c[2].seed); // n = 5, repeat 0, d = 0.1 and 0.2
        assert_eq!(c[1].seed, c[3].seed);
        assert_ne!(c[0].seed, c[1].seed); // repeats differ
        assert_ne!(c[0].seed, c[4].seed); // n differs
        assert_ne!(c[0].key, c[2].key); // the cases stay distinct
                                        // without `paired`, the seeds are those of any axis
        let plain = expand(&parse(&text.replace("paired = true", ""), "t").unwrap()).unwrap();
        assert_ne!(plain[0].seed, plain[2].seed);
        assert_eq!(plain[0].key, c[0].key);
    }
}
