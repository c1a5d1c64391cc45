//! What a study writes and reads back: the [`Record`] of one case (a line
//! of `results.jsonl`), the [`Manifest`] of an output folder, and the file
//! names. Below [`super::run`], [`super::report`] and [`super::shard`], which
//! all read and write them.

use super::sweep::Param;
use crate::error::{Error, Result};
use crate::series::write_atomic;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// File names inside an output folder.
pub const RESULTS: &str = "results.jsonl";
/// The copy of the study file.
pub const STUDY_COPY: &str = "study.toml";
/// The manifest.
pub const MANIFEST: &str = "manifest.json";
/// The lock file of a study folder: one run at a time per `--out`.
pub const LOCK: &str = ".lock";

/// The record of one finished case: one line of `results.jsonl`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Record {
    /// Case id (`c0042`).
    pub id: String,
    /// Case content key (see [`super::sweep::Case::key`]).
    pub key: String,
    /// The case's seed.
    pub seed: u64,
    /// Replicate number.
    pub repeat: usize,
    /// Axis values.
    pub params: Vec<Param>,
    /// `ok`, `error` or `skipped` (an invalid scene with `study.invalid_cases = "skip"`).
    pub status: String,
    /// The error message of a failed case.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
    /// Reproducible results.
    pub metrics: serde_json::Map<String, serde_json::Value>,
    /// Measured timings (empty when `study.timings = false`).
    #[serde(default, skip_serializing_if = "serde_json::Map::is_empty")]
    pub timings: serde_json::Map<String, serde_json::Value>,
    /// Pictures of this case, relative to the output folder
    /// (`cases/<id>-<name>.svg`), written before the record.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub files: Vec<String>,
    /// The optimizer's trace, `[evaluations, best residual so far]` at each
    /// improvement (kind `fit` with `search.trace = true`; empty otherwise).
    /// Kept in the record so that a resumed or merged run draws the same
    /// `[[report.trace]]` plots.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub trace: Vec<[f64; 2]>,
}

impl Record {
    /// Did the case succeed?
    pub fn ok(&self) -> bool {
        self.status == "ok"
    }

    /// Was the case skipped (an invalid scene with
    /// `study.invalid_cases = "skip"`)? A skipped case is not a failed one.
    pub fn skipped(&self) -> bool {
        self.status == "skipped"
    }
}

/// How many records succeeded, failed (status `error`) and were skipped:
/// counted the same way on the console, in `report.md` and by `study merge`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counts {
    /// Records with status `ok`.
    pub ok: usize,
    /// Records with status `error` (the case ran and failed, or panicked).
    pub failed: usize,
    /// Records with status `skipped`.
    pub skipped: usize,
}

impl Counts {
    /// The counts of `records`.
    pub fn of<'a>(records: impl IntoIterator<Item = &'a Record>) -> Counts {
        let mut c = Counts::default();
        for r in records {
            if r.ok() {
                c.ok += 1;
            } else if r.skipped() {
                c.skipped += 1;
            } else {
                c.failed += 1;
            }
        }
        c
    }
}

/// What identifies the study an output folder belongs to.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    /// Study name.
    pub study: String,
    /// Content hash of the study file text (16 hex digits).
    pub hash: String,
    /// Number of cases of the whole study.
    pub cases: usize,
    /// The shard (`I/N`), if this folder holds one.
    pub shard: Option<String>,
}

/// Folder of the per-case pictures inside an output folder.
pub const CASES: &str = "cases";

/// Parse a `results.jsonl`: the records of its complete, valid lines, and
/// whether anything (a partial last line, a damaged line) was dropped.
///
/// # Errors
/// [`Error::Io`] other than a missing file.
pub fn load_records(path: &Path) -> Result<(Vec<Record>, bool)> {
    let bytes = match std::fs::read(path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok((vec![], false)),
        Err(e) => return Err(Error::io(path, e)),
    };
    let mut dirty = false;
    let mut out = Vec::new();
    let complete_len = bytes.iter().rposition(|&b| b == b'\n').map_or(0, |p| p + 1);
    if complete_len < bytes.len() {
        dirty = true; // a partial last line: the case is run again
    }
    for line in bytes[..complete_len].split(|&b| b == b'\n') {
        if line.is_empty() {
            continue;
        }
        match std::str::from_utf8(line)
            .ok()
            .and_then(|l| serde_json::from_str::<Record>(l).ok())
        {
            Some(r) => out.push(r),
            None => dirty = true,
        }
    }
    Ok((out, dirty))
}

/// Write `records` as `results.jsonl` atomically, in the order given.
pub fn write_records(out: &Path, records: &[Record]) -> Result<()> {
    let mut text = String::new();
    for r in records {
        text.push_str(
            &serde_json::to_string(r)
                .map_err(|e| Error::invalid("record", &r.id, e.to_string()))?,
        );
        text.push('\n');
    }
    write_atomic(&out.join(RESULTS), text.as_bytes())
}

/// May a run (or a merge) write into `out`? Yes when it does not exist, is
/// an empty folder, or holds the [`MANIFEST`] of a study (the caller then
/// compares the manifest with its own). Never over results this tool did
/// not write: a non-empty folder without a manifest is refused, and so is a
/// path that is not a folder.
///
/// # Errors
/// [`Error::InvalidParameter`] naming the path, what is in it and what to
/// do; [`Error::Io`] when the folder cannot be read.
pub fn check_out_folder(out: &Path) -> Result<()> {
    let meta = match std::fs::metadata(out) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(Error::io(out, e)),
    };
    if !meta.is_dir() {
        return Err(Error::invalid(
            "out",
            out.display(),
            "a folder (new, empty, or written by `springmass study`); this path is not a folder",
        ));
    }
    if out.join(MANIFEST).is_file() {
        return Ok(());
    }
    let mut names: Vec<String> = Vec::new();
    for e in std::fs::read_dir(out).map_err(|e| Error::io(out, e))? {
        let e = e.map_err(|e| Error::io(out, e))?;
        let name = e.file_name().to_string_lossy().into_owned();
        // the lock of a run that has not written its manifest yet
        if name != LOCK {
            names.push(name);
        }
    }
    if names.is_empty() {
        return Ok(());
    }
    names.sort();
    let shown: Vec<&str> = names.iter().take(3).map(|s| s.as_str()).collect();
    Err(Error::invalid(
        "out",
        out.display(),
        format!(
            "a new or empty folder, or one written by `springmass study` (with {MANIFEST}); this folder holds {} file(s) it did not write ({}{}): choose another --out, or move those files away",
            names.len(),
            shown.join(", "),
            if names.len() > shown.len() { ", ..." } else { "" }
        ),
    ))
}
