//! Spreading a study over machines: `--shard I/N` and `study merge`.
//!
//! Shard `I` of `N` (1-based, `1 <= I <= N`) holds the cases whose index is
//! `I - 1` modulo `N`: a round-robin slice, so that shards get a fair mix of
//! cheap and expensive cases when the cost grows along an axis. Seeds do not
//! depend on the shard (see [`super::sweep`]), so the union of the shards'
//! records is exactly the set of records of a single run, and [`merge`]
//! writes exactly the files a single run writes.
//!
//! ```
//! use springmass::study::shard::Shard;
//! let s: Shard = "2/3".parse()?;
//! assert!(s.contains(1) && s.contains(4) && !s.contains(2));
//! assert!("0/3".parse::<Shard>().is_err());
//! # Ok::<(), springmass::Error>(())
//! ```

use super::records::{self as run, load_records, Manifest, Record, MANIFEST, STUDY_COPY};
use super::Study;
use crate::error::{Error, Result};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// A slice `I/N` of a study's cases.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// 1-based shard number `I`.
    pub index: usize,
    /// Number of shards `N`.
    pub count: usize,
}

impl Shard {
    /// Shard `index` of `count`.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] unless `1 <= index <= count`.
    pub fn new(index: usize, count: usize) -> Result<Shard> {
        if count == 0 || index == 0 || index > count {
            return Err(Error::invalid(
                "shard",
                format!("{index}/{count}"),
                "I/N with 1 <= I <= N",
            ));
        }
        Ok(Shard { index, count })
    }

    /// Does case number `case_index` (0-based) belong to this shard?
    pub fn contains(&self, case_index: usize) -> bool {
        case_index % self.count == self.index - 1
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl std::str::FromStr for Shard {
    type Err = Error;
    fn from_str(s: &str) -> Result<Shard> {
        let bad = || Error::parse("shard", s, "expected I/N with 1 <= I <= N, e.g. 3/8");
        let (i, n) = s.split_once('/').ok_or_else(bad)?;
        let i: usize = i.trim().parse().map_err(|_| bad())?;
        let n: usize = n.trim().parse().map_err(|_| bad())?;
        Shard::new(i, n).map_err(|_| bad())
    }
}

/// What [`merge`] did.
#[derive(Clone, Debug, PartialEq)]
pub struct MergeSummary {
    /// Cases of the study.
    pub total: usize,
    /// Records read (before removing duplicates).
    pub read: usize,
    /// Failed cases.
    pub failed: usize,
    /// The report written.
    pub report: PathBuf,
}

/// Combine the output folders of shards (or of partial runs) of one study
/// into `out`: the same `results.jsonl`, `summary.csv`, `report.md` and plots
/// as a single run. A case found in several folders is taken from the first.
///
/// # Errors
/// [`Error::InvalidParameter`] when the folders belong to different studies
/// (their `study.toml` differ), or when cases are missing (naming how many
/// and the first few); [`Error::Io`].
pub fn merge(dirs: &[PathBuf], out: &Path) -> Result<MergeSummary> {
    let first = dirs
        .first()
        .ok_or_else(|| Error::invalid("merge", "no folders", "at least one folder"))?;
    let text = read(&first.join(STUDY_COPY))?;
    let study = Study::from_text(&text, &first.join(STUDY_COPY).display().to_string())?;
    let mut all: BTreeMap<String, Record> = BTreeMap::new();
    let mut sources: BTreeMap<String, PathBuf> = BTreeMap::new();
    let mut read_count = 0;
    for d in dirs {
        let other = read(&d.join(STUDY_COPY))?;
        if other != text {
            return Err(Error::invalid(
                d.display().to_string(),
                "a folder of another study",
                format!(
                    "folders of one study (its study.toml differs from {})",
                    first.display()
                ),
            ));
        }
        let mtext = read(&d.join(MANIFEST))?;
        let m: Manifest = serde_json::from_str(&mtext)
            .map_err(|e| Error::parse(d.join(MANIFEST).display().to_string(), "", e.to_string()))?;
        if m.hash != study.hash {
            return Err(Error::invalid(
                d.join(MANIFEST).display().to_string(),
                &m.hash,
                format!("hash {} of its study.toml", study.hash),
            ));
        }
        let (records, _) = load_records(&d.join(run::RESULTS))?;
        for r in records {
            if !all.contains_key(&r.id) {
                for f in &r.files {
                    sources.insert(f.clone(), d.join(f));
                }
            }
            match study.case(&r.id) {
                Some(c) if c.key == r.key => {}
                _ => {
                    return Err(Error::invalid(
                        d.join(run::RESULTS).display().to_string(),
                        &r.id,
                        "a record of one of this study's cases",
                    ))
                }
            }
            read_count += 1;
            all.entry(r.id.clone()).or_insert(r);
        }
    }
    let missing: Vec<&str> = study
        .cases
        .iter()
        .filter(|c| !all.contains_key(&c.id))
        .map(|c| c.id.as_str())
        .collect();
    if !missing.is_empty() {
        let shown: Vec<&str> = missing.iter().take(8).copied().collect();
        return Err(Error::invalid(
            "merge",
            format!(
                "{} of {} cases missing ({}{})",
                missing.len(),
                study.cases.len(),
                shown.join(", "),
                if missing.len() > shown.len() {
                    ", ..."
                } else {
                    ""
                }
            ),
            "every case finished: run the missing shards (or resume them) first",
        ));
    }
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let manifest = Manifest {
        study: study.file.study.name.clone(),
        hash: study.hash.clone(),
        cases: study.cases.len(),
        shard: None,
    };
    crate::series::write_atomic(&out.join(STUDY_COPY), text.as_bytes())?;
    let mtext = serde_json::to_string_pretty(&manifest).unwrap_or_default() + "\n";
    crate::series::write_atomic(&out.join(MANIFEST), mtext.as_bytes())?;
    for (f, src) in &sources {
        let bytes = std::fs::read(src).map_err(|e| Error::io(src, e))?;
        crate::series::write_atomic(&out.join(f), &bytes)?;
    }
    let records: Vec<Record> = all.into_values().collect();
    run::write_records(out, &records)?;
    super::report::write(&study, &records, out)?;
    Ok(MergeSummary {
        total: study.cases.len(),
        read: read_count,
        failed: records.iter().filter(|r| !r.ok()).count(),
        report: out.join(super::report::REPORT),
    })
}

fn read(p: &Path) -> Result<String> {
    std::fs::read_to_string(p).map_err(|e| Error::io(p, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_partition_the_cases() {
        for n in 1..6 {
            let shards: Vec<Shard> = (1..=n).map(|i| Shard::new(i, n).unwrap()).collect();
            for c in 0..40 {
                assert_eq!(shards.iter().filter(|s| s.contains(c)).count(), 1);
            }
        }
        for bad in ["", "1", "0/2", "3/2", "a/b", "1/0", "-1/2"] {
            assert!(bad.parse::<Shard>().is_err(), "{bad}");
        }
        assert_eq!("2/5".parse::<Shard>().unwrap().to_string(), "2/5");
    }
}
