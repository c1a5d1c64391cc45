//! Config-driven studies: a TOML file describing a base scene and a sweep,
//! run in parallel into tables and plots.
//!
//! ```text
//! study.toml ──► config (schema, checks) ──► sweep (cases, ids, seeds) ──► run (rayon, results.jsonl)
//!                                                                           │  shard: a slice per machine
//!                                                                           ▼
//!                                                     report (summary.csv, report.md, SVG plots)
//! ```
//!
//! | module | what |
//! |---|---|
//! | [`schema`], [`paths`], [`seeds`] | the bottom: field docs and problems, field paths, hashes |
//! | [`config`] | the study file: types and schema with defaults |
//! | [`check`] | `config check`: every problem in one pass; study file or fit scene |
//! | [`sweep`] | crossing the axes into cases with stable ids and derived seeds |
//! | [`kinds`] | what one case does (`forward`, ...) |
//! | [`realistic`] | records as they come off a real test (damping models, coloured noise, offset, drift, a late blow), generated independently of the fit's model |
//! | [`records`] | `results.jsonl` records, the manifest, safe output folders |
//! | [`run`] | the parallel, resumable runner |
//! | [`report`] | `summary.csv`, `report.md`, SVG plots |
//! | [`shard`] | `--shard I/N` and `study merge` |
//!
//! ```no_run
//! use springmass::study::{Study, run::{run, RunOptions}};
//! let study = Study::default_study()?;
//! let summary = run(&study, &RunOptions::new("out/default"))?;
//! assert!(summary.complete);
//! # Ok::<(), springmass::Error>(())
//! ```

/// Functions for serde's `#[serde(default = "...")]` of the study's
/// tables, one line each: `fn name() -> Type = value;`.
macro_rules! serde_defaults {
    ($(fn $name:ident() -> $t:ty = $v:expr;)*) => {
        $(
            fn $name() -> $t {
                $v
            }
        )*
    };
}

pub mod check;
pub mod config;
pub mod kinds;
pub mod paths;
#[cfg(not(feature = "cli"))]
mod progress;
pub mod realistic;
pub mod records;
pub mod report;
pub mod run;
pub mod schema;
pub mod seeds;
pub mod shard;
pub mod sweep;

use crate::error::{Error, Result};
use config::StudyFile;
use std::collections::HashMap;
use sweep::Case;

/// The embedded default study (`springmass study` with no file).
pub const DEFAULT_STUDY: &str = include_str!("../../configs/studies/default.toml");

/// The shipped noise study: the data-first fit with its defaults on noisy
/// records (`springmass noise-study data-first`).
pub const NOISE_STUDY: &str = include_str!("../../configs/studies/noise-study.toml");

/// The shipped success-against-noise table per misfit
/// (`springmass noise-study misfits`).
pub const NOISE_MISFITS: &str = include_str!("../../configs/studies/noise-misfits.toml");

/// The shipped defect-kind study (`springmass noise-study kinds`).
pub const DEFECT_KINDS: &str = include_str!("../../configs/studies/defect-kinds.toml");

/// A parsed, expanded and checked study.
#[derive(Clone, Debug)]
pub struct Study {
    /// The parsed file.
    pub file: StudyFile,
    /// The file's text (copied into the output folder).
    pub text: String,
    /// FNV-1a hash of the text, 16 hex digits.
    pub hash: String,
    /// Every case, in expansion order.
    pub cases: Vec<Case>,
    by_id: HashMap<String, usize>,
}

impl Study {
    /// Parse, expand and check every case of a study file's text.
    ///
    /// # Errors
    /// [`Error::Parse`] with every problem of the file (as
    /// [`check::check`] lists them), one per line.
    pub fn from_text(text: &str, origin: &str) -> Result<Study> {
        let problems = check::check(text);
        if !problems.is_empty() {
            let all: Vec<String> = problems.iter().map(|p| p.to_string()).collect();
            return Err(Error::parse(
                "study file",
                origin,
                format!("{} problem(s):\n  {}", problems.len(), all.join("\n  ")),
            ));
        }
        let file = config::parse(text, origin)?;
        let cases = sweep::expand(&file)?;
        let by_id = cases
            .iter()
            .enumerate()
            .map(|(i, c)| (c.id.clone(), i))
            .collect();
        Ok(Study {
            file,
            text: text.to_string(),
            hash: format!("{:016x}", sweep::fnv1a(text.as_bytes())),
            cases,
            by_id,
        })
    }

    /// Read and check a study file.
    ///
    /// # Errors
    /// [`Error::Io`], or as [`Study::from_text`].
    pub fn from_file(path: impl AsRef<std::path::Path>) -> Result<Study> {
        let p = path.as_ref();
        let text = crate::io::read_to_string_capped(p)?;
        Study::from_text(&text, &p.display().to_string())
    }

    /// The embedded default study ([`DEFAULT_STUDY`]).
    ///
    /// # Errors
    /// None in practice (the embedded file is tested).
    pub fn default_study() -> Result<Study> {
        Study::from_text(DEFAULT_STUDY, "<default study>")
    }

    /// The case with this id.
    pub fn case(&self, id: &str) -> Option<&Case> {
        self.by_id.get(id).map(|&i| &self.cases[i])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_study_is_valid_and_small() {
        let s = Study::default_study().unwrap();
        assert!(!s.cases.is_empty() && s.cases.len() <= 64);
        assert_eq!(s.case(&s.cases[3].id).unwrap().index, 3);
    }

    #[test]
    fn shipped_configs_check() {
        let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/configs/studies");
        let mut n = 0;
        for e in std::fs::read_dir(dir).unwrap() {
            let p = e.unwrap().path();
            if p.extension().is_some_and(|x| x == "toml") {
                let text = std::fs::read_to_string(&p).unwrap();
                // configs/studies/ holds study files only (scenes: configs/scenes/)
                if !text.lines().any(|l| l.trim() == "[study]") {
                    continue;
                }
                assert_eq!(check::check(&text), vec![], "{}", p.display());
                n += 1;
            }
        }
        assert!(n >= 7, "{n} study files");
    }
}
