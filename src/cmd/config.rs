//! `springmass config`: check a study file, print the schema.

use clap::{Args as ClapArgs, Subcommand};
use springmass::study::check::{check_file, FileKind};
use springmass::study::config::{schema_markdown, schema_text};
use springmass::study::kinds::ALL;
use springmass::study::{Study, DEFAULT_STUDY};
use std::path::PathBuf;

/// Arguments of `springmass config`.
#[derive(ClapArgs, Debug)]
#[command(after_long_help = format!("{LONG_HELP}\n\n{}", schema_text(ALL)))]
pub struct Args {
    #[command(subcommand)]
    pub command: ConfigCommand,
}

const LONG_HELP: &str = "\
A study file is TOML with four tables:
  [study]     name, kind, description, seed (0), repeats (1), timings (true)
  [scene]     the base case, in the schema of the kind
  [[sweep]]   path = \"field.path\" and values = [...] or range = { from, to, count | step, spacing, integer }
  [report]    max_case_rows (200), [[report.table]], [[report.plot]]
Unknown fields are errors. Every field follows; `springmass config schema` prints
the same as Markdown tables, and docs/config.md is the reference page.";

/// The subcommands.
#[derive(Subcommand, Debug)]
pub enum ConfigCommand {
    /// Check a study file or a fit scene (says which): report every problem
    /// with its field path and line; exit 1 if any.
    Check {
        /// The study file or fit scene (a TOML with `[chain]` at the top level).
        file: PathBuf,
    },
    /// Print every field of a study file (and of each kind's scene) with its type and default (Markdown).
    Schema,
    /// Print the embedded default study file.
    ShowDefault,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    match a.command {
        ConfigCommand::Check { file } => {
            let text = springmass::io::read_to_string_capped(&file)?;
            let (kind, problems) = check_file(&text);
            let what = kind.describe().replace("FILE", &file.display().to_string());
            if problems.is_empty() && kind == FileKind::FitScene {
                println!("{}: ok ({what})", file.display());
                Ok(())
            } else if problems.is_empty() {
                let s = Study::from_text(&text, &file.display().to_string())?;
                let count = |k: springmass::study::kinds::Kind| {
                    s.cases.iter().filter(|c| c.kind == k).count()
                };
                let mut kinds = vec![s.file.study.kind];
                kinds.extend(s.file.part.iter().map(|p| p.kind));
                kinds.dedup();
                let mut seen = Vec::new();
                let by_kind: Vec<String> = kinds
                    .into_iter()
                    .filter(|k| {
                        let new = !seen.contains(k);
                        seen.push(*k);
                        new
                    })
                    .map(|k| format!("{} {}", count(k), k.name()))
                    .collect();
                println!(
                    "{}: ok (study {:?}, {} cases: {}{})",
                    file.display(),
                    s.file.study.name,
                    s.cases.len(),
                    by_kind.join(", "),
                    if s.file.part.is_empty() {
                        String::new()
                    } else {
                        format!("; {} part(s) besides main", s.file.part.len())
                    }
                );
                Ok(())
            } else {
                for p in &problems {
                    println!("{}: {p}", file.display());
                }
                eprintln!("{}: {} problem(s) ({what})", file.display(), problems.len());
                // invalid input: the documented exit status 2
                std::process::exit(2);
            }
        }
        ConfigCommand::Schema => {
            print!("{}", schema_markdown(ALL));
            Ok(())
        }
        ConfigCommand::ShowDefault => {
            print!("{DEFAULT_STUDY}");
            Ok(())
        }
    }
}
