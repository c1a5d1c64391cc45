//! `springmass noise-study`: the shipped noise studies, run by the study
//! engine (`springmass study`) from their embedded files, with the common
//! overrides on the command line. Nothing here fits or scores: the cases
//! are the study kind `noise` (`springmass::study::kinds::noise`) and the
//! `fit` kind for the defect-kind study.

use super::study::RunArgs;
use anyhow::Context;
use clap::{Args as ClapArgs, ValueEnum};
use springmass::detect::misfit::MisfitKind;
use springmass::study::Study;

/// Which shipped study.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Part {
    /// The data-first fit with its defaults (time misfit, noise estimated),
    /// k given: positions right, truth within 2 and 3 SE, wrong answers
    /// flagged, estimated over true noise (S1-S4, C3a, C3b at 1e-4, 1e-3,
    /// 1e-2); parts: k chosen by BIC (k0-k3), damping fitted (S3)
    /// [configs/studies/noise-study.toml].
    DataFirst,
    /// Success against noise per misfit (real axis, Bromwich line, time),
    /// k and noise given, 8 levels [configs/studies/noise-misfits.toml].
    Misfits,
    /// Spring, damper and mass defects sought as each kind and as `any`,
    /// damping fitted [configs/studies/defect-kinds.toml].
    Kinds,
}

impl Part {
    fn text(self) -> &'static str {
        match self {
            Part::DataFirst => springmass::study::NOISE_STUDY,
            Part::Misfits => springmass::study::NOISE_MISFITS,
            Part::Kinds => springmass::study::DEFECT_KINDS,
        }
    }
    fn name(self) -> &'static str {
        match self {
            Part::DataFirst => "data-first",
            Part::Misfits => "misfits",
            Part::Kinds => "kinds",
        }
    }
}

/// Arguments of `springmass noise-study`.
#[derive(ClapArgs, Debug)]
pub struct Args {
    /// Which shipped study.
    #[arg(value_enum, default_value = "data-first")]
    pub part: Part,
    /// Systems of the main sweep (S1,S2,S3,S4,C3a,C3b) [default: the file's].
    #[arg(long, value_delimiter = ',')]
    pub systems: Vec<String>,
    /// Noise levels of the main sweep (relative to max |x_1|, in [0, 1]) [default: the file's].
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    pub levels: Vec<f64>,
    /// Misfits of the main sweep (real-axis, bromwich, time; `misfits` only) [default: all three].
    #[arg(long, value_delimiter = ',')]
    pub misfits: Vec<String>,
    /// Repeats (noise draws) per cell, 1 to 10000 [default: the file's, 20].
    #[arg(long)]
    pub seeds: Option<usize>,
    /// Only the main sweep, not the file's [[part]] sections.
    #[arg(long)]
    pub main_only: bool,
    /// Print the study file that would run, and stop.
    #[arg(long)]
    pub print: bool,
    #[command(flatten)]
    pub run: RunArgs,
}

/// The shipped study file of `a.part` with the overrides of `a` applied.
///
/// # Errors
/// An override the file has no sweep for, or a bad value (naming the option).
pub fn study_text(a: &Args) -> anyhow::Result<String> {
    let mut doc: toml::Table = toml::from_str(a.part.text()).context("the embedded study file")?;
    let mut set_sweep = |path: &str,
                         option: &str,
                         values: Vec<toml::Value>|
     -> anyhow::Result<()> {
        let sweeps = doc
            .get_mut("sweep")
            .and_then(|v| v.as_array_mut())
            .with_context(|| format!("--{option}: the {} study has no sweeps", a.part.name()))?;
        let sweep = sweeps
            .iter_mut()
            .filter_map(|v| v.as_table_mut())
            .find(|t| t.get("path").and_then(|p| p.as_str()) == Some(path))
            .with_context(|| {
                format!(
                    "--{option}: the {} study does not sweep `{path}`",
                    a.part.name()
                )
            })?;
        sweep.insert("values".into(), toml::Value::Array(values));
        Ok(())
    };
    if !a.systems.is_empty() {
        let known = springmass::scenes::NOISE_SYSTEMS;
        for s in &a.systems {
            if !known.contains(&s.as_str()) {
                anyhow::bail!(
                    "invalid --systems value {s:?}: allowed {}",
                    known.join(", ")
                );
            }
        }
        set_sweep(
            "system",
            "systems",
            a.systems.iter().map(|s| s.clone().into()).collect(),
        )?;
    }
    if !a.levels.is_empty() {
        for l in &a.levels {
            if !(l.is_finite() && (0.0..=1.0).contains(l)) {
                anyhow::bail!("invalid --levels value {l}: allowed in [0, 1]");
            }
        }
        set_sweep(
            "level",
            "levels",
            a.levels.iter().map(|&l| l.into()).collect(),
        )?;
    }
    if !a.misfits.is_empty() {
        for m in &a.misfits {
            MisfitKind::parse(m).with_context(|| format!("invalid --misfits value {m:?}"))?;
        }
        set_sweep(
            "misfit",
            "misfits",
            a.misfits.iter().map(|m| m.clone().into()).collect(),
        )?;
    }
    if let Some(n) = a.seeds {
        if !(1..=10_000).contains(&n) {
            anyhow::bail!("invalid --seeds value {n}: allowed 1 to 10000");
        }
        doc.get_mut("study")
            .and_then(|v| v.as_table_mut())
            .context("the embedded study file has no [study]")?
            .insert("repeats".into(), (n as i64).into());
    }
    if a.main_only {
        doc.remove("part");
        // report items of the removed parts
        if let Some(report) = doc.get_mut("report").and_then(|v| v.as_table_mut()) {
            for (_, v) in report.iter_mut() {
                let Some(items) = v.as_array_mut() else {
                    continue;
                };
                items.retain(|it| {
                    it.get("part")
                        .and_then(|p| p.as_str())
                        .is_none_or(|p| p == "main")
                });
            }
        }
    }
    Ok(toml::to_string(&doc)?)
}

pub fn run(a: Args) -> anyhow::Result<()> {
    a.run.checked_shard()?;
    let text = study_text(&a)?;
    if a.print {
        print!("{text}");
        return Ok(());
    }
    let study = Study::from_text(&text, &format!("<noise-study {}>", a.part.name()))?;
    a.run.run(&study)
}
