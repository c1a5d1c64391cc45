//! `springmass study`: run a study file (or the embedded default) into a
//! report; `springmass study merge`: combine shard outputs.

use anyhow::Context;
use clap::{Args as ClapArgs, Subcommand};
use springmass::study::run::check_threads;
use springmass::study::run::{run as run_study, RunOptions};
use springmass::study::shard::{merge, ShardSpec};
use springmass::study::Study;
use std::path::PathBuf;

/// Arguments of `springmass study`.
#[derive(ClapArgs, Debug)]
#[command(args_conflicts_with_subcommands = true)]
pub struct Args {
    #[command(subcommand)]
    pub merge: Option<MergeCommand>,
    /// The study file (TOML). Without it (or with --default), the embedded
    /// default study runs.
    pub file: Option<PathBuf>,
    /// Run the embedded default study (`springmass config show-default` prints it).
    #[arg(long, conflicts_with = "file")]
    pub default: bool,
    #[command(flatten)]
    pub run: RunArgs,
}

/// How a study runs: shared by `springmass study` and `springmass noise-study`.
#[derive(ClapArgs, Debug)]
pub struct RunArgs {
    /// Output folder [default: out/<study name>]. Running again with the same
    /// folder resumes: finished cases are not recomputed.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Worker threads, 1 to 1024 [default: number of cores]. Results do not depend on it.
    #[arg(long)]
    pub threads: Option<usize>,
    /// Run only shard I of N (1-based): cases whose index is I-1 modulo N.
    /// `auto`: the task of a Slurm job array (SLURM_ARRAY_TASK_ID,
    /// SLURM_ARRAY_TASK_COUNT). Combine the shard folders with
    /// `springmass study merge`.
    #[arg(long, value_name = "I/N|auto")]
    pub shard: Option<ShardSpec>,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

impl RunArgs {
    /// Check the options, then run `study` with them.
    pub fn run(&self, study: &Study) -> anyhow::Result<()> {
        let shard = self.checked_shard()?;
        run_into(study, self.out.clone(), self.threads, shard, self.quiet)
    }

    /// The thread count and shard, checked before any work.
    pub fn checked_shard(&self) -> anyhow::Result<Option<springmass::study::shard::Shard>> {
        if let Some(n) = self.threads {
            check_threads(n)?;
        }
        Ok(self.shard.map(|s| s.resolve()).transpose()?)
    }
}

/// `springmass study merge DIR... --out DIR`.
#[derive(Subcommand, Debug)]
pub enum MergeCommand {
    /// Combine the output folders of shards (or partial runs) of one study into
    /// the report a single run gives.
    Merge {
        /// Shard output folders.
        #[arg(required = true)]
        dirs: Vec<PathBuf>,
        /// Output folder of the combined report.
        #[arg(long)]
        out: PathBuf,
    },
}

pub fn run(a: Args) -> anyhow::Result<()> {
    if let Some(MergeCommand::Merge { dirs, out }) = a.merge {
        let m = merge(&dirs, &out)?;
        println!(
            "merged {} records from {} folder(s): {} cases, {} failed, {} skipped",
            m.read,
            dirs.len(),
            m.total,
            m.failed,
            m.skipped
        );
        println!("report: {}", m.report.display());
        return Ok(());
    }
    // every option before any work
    a.run.checked_shard()?;
    let study = match (&a.file, a.default) {
        (Some(f), false) => Study::from_file(f)?,
        _ => Study::default_study()?,
    };
    a.run.run(&study)
}

/// Run `study` into `out` (default `out/<study name>`), resuming what is
/// there; shared with `springmass noise-study`. The options are checked.
fn run_into(
    study: &Study,
    out: Option<PathBuf>,
    threads: Option<usize>,
    shard: Option<springmass::study::shard::Shard>,
    quiet: bool,
) -> anyhow::Result<()> {
    let out = out.unwrap_or_else(|| PathBuf::from("out").join(&study.file.study.name));
    let mut opts = RunOptions::new(&out);
    opts.threads = threads;
    opts.shard = shard;
    opts.progress = !quiet;
    eprintln!(
        "study {}: {} cases{}, output in {}",
        study.file.study.name,
        study.cases.len(),
        shard.map(|s| format!(" (shard {s})")).unwrap_or_default(),
        out.display()
    );
    let start = std::time::Instant::now();
    let s = run_study(study, &opts).with_context(|| format!("running into {}", out.display()))?;
    eprintln!(
        "{} run now, {} resumed, {} failed, {} skipped, in {:.1} s",
        s.ran,
        s.resumed,
        s.failed,
        s.skipped,
        start.elapsed().as_secs_f64()
    );
    match (&s.report, shard) {
        (Some(r), _) => println!("report: {}", r.display()),
        (None, Some(sh)) => println!(
            "shard {sh} done: {} cases in {}; combine the shard folders with `springmass study merge DIR... --out DIR`",
            s.selected,
            out.display()
        ),
        (None, None) => println!("incomplete: run the same command again to resume"),
    }
    Ok(())
}
