//! Subcommands. Shared argument groups live here.

pub mod config;
pub mod fit;
pub mod fit_ambient;
pub mod fit_args;
pub mod fit_modes;
pub mod laplace;
pub mod locate;
pub mod monitor;
pub mod noise;
pub mod response;
pub mod simulate;
pub mod spectral;
pub mod study;
pub mod suppress;
pub mod surface;

use anyhow::Context;
use clap::Args as ClapArgs;
use springmass::{Chain, ChainSpec, Defect};
use std::path::PathBuf;

/// How a chain is given on the command line: flags, or the `[chain]` table of
/// a TOML scene file (flags given explicitly override the file).
#[derive(ClapArgs, Debug, Clone)]
pub struct ChainArgs {
    /// Number of masses.
    #[arg(long)]
    pub n: Option<usize>,
    /// Uniform spring constant [default: 1].
    #[arg(long, allow_hyphen_values = true)]
    pub k: Option<f64>,
    /// Uniform damping [default: 0.1].
    #[arg(long, allow_hyphen_values = true)]
    pub d: Option<f64>,
    /// Impulse on mass 1 [default: 1].
    #[arg(long, allow_hyphen_values = true)]
    pub gamma: Option<f64>,
    /// Uniform mass [default: 1].
    #[arg(long, allow_hyphen_values = true)]
    pub mass: Option<f64>,
    /// A defect `kind:at:value` (repeatable): mass:8:5, spring:3:0.5, damper:4:0.3.
    #[arg(long = "defect", value_name = "KIND:AT:VALUE")]
    pub defects: Vec<String>,
    /// TOML scene file with a `[chain]` table (n, k, d, gamma, mass, defects).
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// Damping model: grounded (the paper's: d on every mass), between:C
    /// (a damper C parallel to every spring), rayleigh:A:B (C = A M + B K),
    /// modal:ZETA (every mode damped with the ratio ZETA) or modal:Z1,Z2,..
    /// (a ratio per mode in the order of frequency, the last for every higher mode).
    /// With another model than grounded, --d is an extra grounded damping [default 0].
    #[arg(long, value_name = "MODEL[:P1[:P2]]")]
    pub damping: Option<String>,
    /// A measured profile instead of the uniform chain: a CSV with one row
    /// per mass, columns mass, spring (to the mass before; empty for a free
    /// left end) and optionally damper, and a last row with only the right
    /// wall's spring when that end is fixed. Gives n and the ends; defects
    /// apply on top of it.
    #[arg(long, value_name = "FILE")]
    pub baseline: Option<PathBuf>,
}

impl ChainArgs {
    /// Build and validate the chain.
    pub fn chain(&self) -> anyhow::Result<Chain> {
        let baseline = self
            .baseline
            .as_ref()
            .map(springmass::chain::Baseline::read_csv)
            .transpose()?;
        let mut spec = match &self.scene {
            Some(path) => read_chain_spec(path)?,
            None => ChainSpec {
                n: match &baseline {
                    Some(b) => b.n(),
                    None => self
                        .n
                        .context("--n is required (or give --scene FILE or --baseline FILE)")?,
                },
                k: 1.0,
                d: 0.1,
                gamma: 1.0,
                mass: 1.0,
                defects: vec![],
                left: Default::default(),
                right: Default::default(),
                damping: Default::default(),
                baseline: None,
            },
        };
        if let Some(b) = baseline {
            b.check_agrees(self.n.or(Some(spec.n)), None, None)?;
            spec.n = b.n();
            spec.baseline = Some(springmass::chain::BaselineSpec::Table(b));
        }
        if let Some(n) = self.n {
            spec.n = n;
        }
        if let Some(k) = self.k {
            spec.k = k;
        }
        if let Some(d) = self.d {
            spec.d = d;
        }
        if let Some(g) = self.gamma {
            spec.gamma = g;
        }
        if let Some(m) = self.mass {
            spec.mass = m;
        }
        for t in &self.defects {
            spec.defects.push(Defect::parse(t)?);
        }
        if let Some(text) = &self.damping {
            spec.damping = springmass::chain::Damping::parse_complete(text)?;
            if !spec.damping.is_grounded() && self.d.is_none() {
                spec.d = 0.0;
            }
        }
        Ok(spec.build()?)
    }
}

/// Read the `[chain]` table of a scene file (other tables are ignored here).
pub fn read_chain_spec(path: &std::path::Path) -> anyhow::Result<ChainSpec> {
    let text = springmass::io::read_to_string_capped(path)?;
    let value: toml::Table =
        toml::from_str(&text).with_context(|| format!("parsing {}", path.display()))?;
    let chain = value
        .get("chain")
        .with_context(|| format!("{}: no [chain] table", path.display()))?
        .clone();
    let mut spec: ChainSpec = chain
        .try_into()
        .with_context(|| format!("{}: in [chain]", path.display()))?;
    // a baseline's path is the scene file's neighbour
    let dir = path.parent().unwrap_or(std::path::Path::new("."));
    spec.baseline = spec.baseline.map(|b| b.relative_to(dir));
    Ok(spec)
}

/// Print a report: pretty JSON with `--json` (`json`), otherwise its text
/// `summary`.
pub fn print_report<R: serde::Serialize>(
    json: bool,
    report: &R,
    summary: impl FnOnce(&R) -> String,
) -> anyhow::Result<()> {
    if json {
        println!("{}", serde_json::to_string_pretty(report)?);
    } else {
        print!("{}", summary(report));
    }
    Ok(())
}
