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

use super::records::{self as run, load_records, Counts, Manifest, Record, MANIFEST, STUDY_COPY};
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

/// The environment variables of a Slurm job array that [`Shard::from_slurm`]
/// reads: the task's id, the number of tasks, and (optional) the smallest id
/// and the step of `--array=MIN-MAX:STEP`.
pub const SLURM_VARS: [&str; 4] = [
    "SLURM_ARRAY_TASK_ID",
    "SLURM_ARRAY_TASK_COUNT",
    "SLURM_ARRAY_TASK_MIN",
    "SLURM_ARRAY_TASK_STEP",
];

impl Shard {
    /// The shard of this task of a Slurm job array (`sbatch --array=0-N`):
    /// `I = (SLURM_ARRAY_TASK_ID - MIN) / STEP + 1` of
    /// `N = SLURM_ARRAY_TASK_COUNT`, where `MIN` is `SLURM_ARRAY_TASK_MIN`
    /// (0 when unset) and `STEP` is `SLURM_ARRAY_TASK_STEP` (1 when unset).
    /// `--array=0-7` and `--array=1-8` both give shards 1/8 ... 8/8.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming the variable: missing (not inside
    /// a job array), not a number, or inconsistent (an id outside
    /// `MIN ..= MIN + STEP (N - 1)` or off the step, `N = 0`).
    pub fn from_slurm() -> Result<Shard> {
        Shard::from_vars(|name| std::env::var(name).ok())
    }

    /// As [`Shard::from_slurm`], reading the variables through `get`.
    ///
    /// ```
    /// use springmass::study::shard::Shard;
    /// let env = |id: &'static str, count: &'static str| {
    ///     move |name: &str| match name {
    ///         "SLURM_ARRAY_TASK_ID" => Some(id.to_string()),
    ///         "SLURM_ARRAY_TASK_COUNT" => Some(count.to_string()),
    ///         _ => None,
    ///     }
    /// };
    /// assert_eq!(Shard::from_vars(env("0", "4"))?, Shard::new(1, 4)?);
    /// assert_eq!(Shard::from_vars(env("3", "4"))?, Shard::new(4, 4)?);
    /// assert!(Shard::from_vars(env("4", "4")).is_err());
    /// # Ok::<(), springmass::Error>(())
    /// ```
    ///
    /// # Errors
    /// As [`Shard::from_slurm`].
    pub fn from_vars(get: impl Fn(&str) -> Option<String>) -> Result<Shard> {
        let num = |name: &str, default: Option<u64>| -> Result<u64> {
            match get(name) {
                Some(v) => v.trim().parse::<u64>().map_err(|_| {
                    Error::invalid(name, &v, "a whole number >= 0 (as Slurm sets it)")
                }),
                None => default.ok_or_else(|| {
                    Error::invalid(
                        name,
                        "(not set)",
                        "set by Slurm inside a job array (`sbatch --array=0-N`); outside Slurm use --shard I/N",
                    )
                }),
            }
        };
        let id = num(SLURM_VARS[0], None)?;
        let count = num(SLURM_VARS[1], None)?;
        let min = num(SLURM_VARS[2], Some(0))?;
        let step = num(SLURM_VARS[3], Some(1))?;
        if count == 0 || count > 1_000_000 {
            return Err(Error::invalid(SLURM_VARS[1], count, "1 ..= 1000000 tasks"));
        }
        if step == 0 {
            return Err(Error::invalid(SLURM_VARS[3], step, ">= 1"));
        }
        let last = min.saturating_add(step.saturating_mul(count - 1));
        if id < min || id > last || (id - min) % step != 0 {
            return Err(Error::invalid(
                SLURM_VARS[0],
                id,
                format!(
                    "one of the array's {count} task ids {min}, {}, ..., {last} (SLURM_ARRAY_TASK_MIN = {min}, SLURM_ARRAY_TASK_STEP = {step}): the variables are inconsistent",
                    min + step
                ),
            ));
        }
        Shard::new(((id - min) / step + 1) as usize, count as usize)
    }
}

/// The `--shard` option: a fixed slice `I/N`, or `auto` (the task of a
/// Slurm job array, [`Shard::from_slurm`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShardSpec {
    /// `--shard I/N`.
    Fixed(Shard),
    /// `--shard auto`.
    Auto,
}

impl ShardSpec {
    /// The shard: `Fixed` as given, `Auto` from the Slurm variables.
    ///
    /// # Errors
    /// As [`Shard::from_slurm`].
    pub fn resolve(&self) -> Result<Shard> {
        match self {
            ShardSpec::Fixed(s) => Ok(*s),
            ShardSpec::Auto => Shard::from_slurm(),
        }
    }
}

impl std::str::FromStr for ShardSpec {
    type Err = Error;
    fn from_str(s: &str) -> Result<ShardSpec> {
        if s.trim() == "auto" {
            return Ok(ShardSpec::Auto);
        }
        s.parse::<Shard>().map(ShardSpec::Fixed).map_err(|_| {
            Error::parse(
                "shard",
                s,
                "expected I/N with 1 <= I <= N (e.g. 3/8), or auto (a Slurm job array task)",
            )
        })
    }
}

/// What [`merge`] did.
#[derive(Clone, Debug, PartialEq)]
pub struct MergeSummary {
    /// Cases of the study.
    pub total: usize,
    /// Records read (before removing duplicates).
    pub read: usize,
    /// Failed cases (status `error`).
    pub failed: usize,
    /// Skipped cases (status `skipped`), not counted in `failed`.
    pub skipped: usize,
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
        check_folder(d, first, &text, &study)?;
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
    check_complete(&study, &all)?;
    let manifest = Manifest {
        study: study.file.study.name.clone(),
        hash: study.hash.clone(),
        cases: study.cases.len(),
        shard: None,
    };
    check_merge_out(out, &manifest)?;
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let mtext = serde_json::to_string_pretty(&manifest).unwrap_or_default() + "\n";
    crate::series::write_atomic(&out.join(MANIFEST), mtext.as_bytes())?;
    crate::series::write_atomic(&out.join(STUDY_COPY), text.as_bytes())?;
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
        failed: Counts::of(&records).failed,
        skipped: Counts::of(&records).skipped,
        report: out.join(super::report::REPORT),
    })
}

/// Refuse a folder of another study: its `study.toml` differs from the first
/// folder's `text`, or its manifest's hash from the study's.
fn check_folder(d: &Path, first: &Path, text: &str, study: &Study) -> Result<()> {
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
    Ok(())
}

/// Refuse a merge that misses cases, naming how many and the first few.
fn check_complete(study: &Study, all: &BTreeMap<String, Record>) -> Result<()> {
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
    Ok(())
}

/// Never over results of another study (or of a shard, or not ours): `out`
/// is new, empty, or holds this `manifest`.
fn check_merge_out(out: &Path, manifest: &Manifest) -> Result<()> {
    run::check_out_folder(out)?;
    let mpath = out.join(MANIFEST);
    if mpath.is_file() {
        let old: Option<Manifest> = std::fs::read_to_string(&mpath)
            .ok()
            .and_then(|t| serde_json::from_str(&t).ok());
        if old.as_ref() != Some(manifest) {
            return Err(Error::invalid(
                "out",
                out.display(),
                "a new or empty folder, or the merged folder of this same study: this one holds another study's or a shard's results; choose another --out",
            ));
        }
    }
    Ok(())
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

    #[test]
    fn slurm_variables_give_the_shard() {
        let vars = |pairs: &[(&str, &str)]| {
            let owned: Vec<(String, String)> = pairs
                .iter()
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .collect();
            move |name: &str| {
                owned
                    .iter()
                    .find(|(k, _)| k == name)
                    .map(|(_, v)| v.clone())
            }
        };
        let id = "SLURM_ARRAY_TASK_ID";
        let count = "SLURM_ARRAY_TASK_COUNT";
        let min = "SLURM_ARRAY_TASK_MIN";
        let step = "SLURM_ARRAY_TASK_STEP";
        // --array=0-7 and --array=1-8 give the same shards
        let a = Shard::from_vars(vars(&[(id, "0"), (count, "8"), (min, "0")])).unwrap();
        let b = Shard::from_vars(vars(&[(id, "1"), (count, "8"), (min, "1")])).unwrap();
        assert_eq!(
            (a, b),
            (Shard::new(1, 8).unwrap(), Shard::new(1, 8).unwrap())
        );
        // --array=10-40:10
        let c = Shard::from_vars(vars(&[(id, "30"), (count, "4"), (min, "10"), (step, "10")]));
        assert_eq!(c.unwrap(), Shard::new(3, 4).unwrap());
        // missing, not a number, inconsistent: each names its variable
        for (v, want) in [
            (vars(&[]), id),
            (vars(&[(id, "1")]), count),
            (vars(&[(id, "one"), (count, "2")]), id),
            (vars(&[(id, "2"), (count, "2")]), id),
            (vars(&[(id, "0"), (count, "0")]), count),
            (vars(&[(id, "0"), (count, "2"), (min, "1")]), id),
            (
                vars(&[(id, "15"), (count, "4"), (min, "10"), (step, "10")]),
                id,
            ),
        ] {
            match Shard::from_vars(v) {
                Err(Error::InvalidParameter { field, .. }) => assert_eq!(field, want),
                other => panic!("{want}: {other:?}"),
            }
        }
        assert_eq!("auto".parse::<ShardSpec>().unwrap(), ShardSpec::Auto);
        assert_eq!(
            "2/3".parse::<ShardSpec>().unwrap(),
            ShardSpec::Fixed(Shard::new(2, 3).unwrap())
        );
        assert!("auto/2".parse::<ShardSpec>().is_err());
    }
}
