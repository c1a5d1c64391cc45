//! Field paths of a scene: `a.b[2].c` parsed into segments, set and removed.
//! The bottom of the study module (imports nothing of it).

/// One segment of a field path.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Segment {
    /// A table key.
    Key(String),
    /// An array index.
    Index(usize),
}

/// Parse `a.b[2].c` into segments.
///
/// # Errors
/// A message naming the bad part (empty key, bad index, characters outside
/// `A-Za-z0-9_-`).
pub fn parse_path(path: &str) -> std::result::Result<Vec<Segment>, String> {
    let mut out = Vec::new();
    if path.is_empty() {
        return Err("empty field path".into());
    }
    for part in path.split('.') {
        let (key, mut rest) = match part.find('[') {
            Some(i) => (&part[..i], &part[i..]),
            None => (part, ""),
        };
        if key.is_empty()
            || !key
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
        {
            return Err(format!(
                "bad key {key:?} in field path {path:?}: keys are letters, digits, '_', '-'"
            ));
        }
        out.push(Segment::Key(key.to_string()));
        while !rest.is_empty() {
            let close = rest
                .find(']')
                .ok_or_else(|| format!("unclosed '[' in field path {path:?}"))?;
            let idx: usize = rest[1..close]
                .parse()
                .map_err(|_| format!("bad index {:?} in field path {path:?}", &rest[1..close]))?;
            out.push(Segment::Index(idx));
            rest = &rest[close + 1..];
            if !rest.is_empty() && !rest.starts_with('[') {
                return Err(format!("unexpected {rest:?} in field path {path:?}"));
            }
        }
    }
    Ok(out)
}

/// Set the field at `path` of `root` to `value`, creating missing tables.
///
/// # Errors
/// A message naming the path: an index past the end of an array, or a
/// non-table on the way.
pub fn set_path(
    root: &mut toml::Value,
    path: &str,
    value: toml::Value,
) -> std::result::Result<(), String> {
    let segs = parse_path(path)?;
    let mut cur = root;
    let last = segs.len() - 1;
    for (i, seg) in segs.iter().enumerate() {
        match seg {
            Segment::Key(k) => {
                let t = cur.as_table_mut().ok_or_else(|| {
                    format!("cannot set {path:?}: the part before {k:?} is not a table")
                })?;
                if i == last {
                    t.insert(k.clone(), value);
                    return Ok(());
                }
                let next_is_index = matches!(segs[i + 1], Segment::Index(_));
                cur = t.entry(k.clone()).or_insert_with(|| {
                    if next_is_index {
                        toml::Value::Array(vec![])
                    } else {
                        toml::Value::Table(toml::Table::new())
                    }
                });
            }
            Segment::Index(idx) => {
                let a = cur.as_array_mut().ok_or_else(|| {
                    format!("cannot set {path:?}: [{idx}] applied to a non-array")
                })?;
                let len = a.len();
                let slot = a.get_mut(*idx).ok_or_else(|| {
                    format!("cannot set {path:?}: index {idx} past the end (the array has {len} elements)")
                })?;
                if i == last {
                    *slot = value;
                    return Ok(());
                }
                cur = slot;
            }
        }
    }
    Ok(())
}

/// Remove the field at `path` (`a.b[2].c`) from `value`; false when there
/// is no such field.
pub fn remove_path(value: &mut toml::Value, path: &str) -> bool {
    let Ok(segments) = parse_path(path) else {
        return false;
    };
    let Some((last, parents)) = segments.split_last() else {
        return false;
    };
    let mut cur = value;
    for seg in parents {
        let next = match (seg, cur) {
            (Segment::Key(k), toml::Value::Table(t)) => t.get_mut(k),
            (Segment::Index(i), toml::Value::Array(a)) => a.get_mut(*i),
            _ => None,
        };
        match next {
            Some(v) => cur = v,
            None => return false,
        }
    }
    match (last, cur) {
        (Segment::Key(k), toml::Value::Table(t)) => t.remove(k).is_some(),
        (Segment::Index(i), toml::Value::Array(a)) if *i < a.len() => {
            a.remove(*i);
            true
        }
        _ => false,
    }
}

/// The value at `path` (`a.b[2].c`) of `root`, if there is one.
pub fn get_path<'a>(root: &'a toml::Value, path: &str) -> Option<&'a toml::Value> {
    let mut cur = root;
    for seg in parse_path(path).ok()? {
        cur = match (seg, cur) {
            (Segment::Key(k), toml::Value::Table(t)) => t.get(&k)?,
            (Segment::Index(i), toml::Value::Array(a)) => a.get(i)?,
            _ => return None,
        };
    }
    Some(cur)
}
