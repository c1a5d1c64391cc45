//! `springmass spectral`: the mass profile from modal data of mass 1 (an
//! inverse eigenvalue problem; `springmass::detect::fit::spectral`).

use anyhow::Context;
use clap::Args as ClapArgs;
use springmass::chain::Boundary;
use springmass::detect::fit::spectral::{masses_from_spectrum, Spectrum};
use springmass::Chain;
use std::path::PathBuf;

/// Arguments of `springmass spectral`.
#[derive(ClapArgs, Debug)]
#[command(after_help = "\
The modes file is a CSV with a header holding the columns `omega` (natural
frequencies in rad/s) and `residue` (the driving-point modal constants of
mass 1 per unit impulse: X_1(s) / gamma = sum_j residue_j / (s^2 + omega_j^2), as an
experimental modal analysis of the impulse response of mass 1 gives them),
one row per mode, every mode of the chain. Springs are uniform (--k) with
the given ends. Prints every mass, and the consistency of the rebuilt
matrix: about the relative error of the masses; above 1e-6 the data (or
f64) could not resolve part of the chain.

Example: springmass spectral --modes modes.csv --n 8 --k 1")]
pub struct Args {
    /// CSV of the modes (columns omega, residue).
    #[arg(long)]
    pub modes: PathBuf,
    /// Number of masses (as many modes are needed).
    #[arg(long)]
    pub n: usize,
    /// Uniform spring constant.
    #[arg(long, default_value_t = 1.0)]
    pub k: f64,
    /// Left end (mass 1's side): fixed or free.
    #[arg(long, default_value = "fixed")]
    pub left: Boundary,
    /// Right end: fixed or free.
    #[arg(long, default_value = "fixed")]
    pub right: Boundary,
    /// Print JSON: {"masses": [...], "consistency": c, "resolved": bool}.
    #[arg(long)]
    pub json: bool,
}

/// The columns `omega` and `residue` of a CSV file.
fn read_modes(path: &std::path::Path) -> anyhow::Result<(Vec<f64>, Vec<f64>)> {
    let text = springmass::io::read_to_string_capped(path)?;
    let mut rd = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .comment(Some(b'#'))
        .from_reader(text.as_bytes());
    let headers = rd.headers()?.clone();
    let col = |name: &str| {
        headers
            .iter()
            .position(|h| h.eq_ignore_ascii_case(name))
            .with_context(|| {
                format!(
                    "invalid modes: {}: no column `{name}` (header: {})",
                    path.display(),
                    headers.iter().collect::<Vec<_>>().join(",")
                )
            })
    };
    let (io, ir) = (col("omega")?, col("residue")?);
    let (mut om, mut re) = (Vec::new(), Vec::new());
    for (i, rec) in rd.records().enumerate() {
        let rec = rec?;
        let num = |j: usize, name: &str| -> anyhow::Result<f64> {
            rec.get(j)
                .and_then(|v| v.parse::<f64>().ok())
                .with_context(|| {
                    format!(
                        "invalid modes: {} row {}: `{name}` is not a number",
                        path.display(),
                        i + 1
                    )
                })
        };
        om.push(num(io, "omega")?);
        re.push(num(ir, "residue")?);
    }
    Ok((om, re))
}

/// The modes must be as many as the masses (so that `--n` is bounded by the
/// file, which the input cap bounds), each frequency finite and `>= 0` (a
/// negative omega is not a frequency; its square would pass for a positive
/// eigenvalue), and the chain's memory within the budget.
fn check_modes(a: &Args, omega: &[f64]) -> anyhow::Result<()> {
    if a.n != omega.len() {
        return Err(springmass::Error::invalid(
            "n",
            a.n,
            format!(
                "the number of modes of the spectrum in {} ({}): one mode per mass",
                a.modes.display(),
                omega.len()
            ),
        )
        .into());
    }
    if let Some(i) = omega.iter().position(|w| !(w.is_finite() && *w >= 0.0)) {
        return Err(springmass::Error::invalid(
            format!("{} row {}: omega", a.modes.display(), i + 1),
            omega[i],
            "a natural frequency >= 0 rad/s, finite",
        )
        .into());
    }
    // the chain, the spectrum and the rebuilt tridiagonal matrix: about 16
    // vectors of n values
    springmass::io::check_alloc(&format!("spectral (n = {})", a.n), 16.0 * 8.0 * a.n as f64)?;
    Ok(())
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let (omega, residue) = read_modes(&a.modes)?;
    check_modes(&a, &omega)?;
    let chain = Chain::paper(a.n)?
        .with_k(a.k)?
        .with_boundaries(a.left, a.right)?;
    let spec = Spectrum {
        lambda: omega.iter().map(|w| w * w).collect(),
        residue,
    };
    let s = masses_from_spectrum(&chain.springs(), &spec)?;
    let resolved = s.consistency < 1e-6;
    if a.json {
        let v = serde_json::json!({
            "masses": s.masses,
            "consistency": s.consistency,
            "resolved": resolved,
        });
        println!("{}", serde_json::to_string_pretty(&v)?);
        return Ok(());
    }
    println!(
        "masses from {} modes of mass 1 ({} springs k = {}, ends {}-{}):",
        a.n,
        a.n + 1,
        a.k,
        chain.left(),
        chain.right()
    );
    for (i, m) in s.masses.iter().enumerate() {
        println!("  m_{} = {m:.12e}", i + 1);
    }
    println!(
        "consistency {:.1e}: {}",
        s.consistency,
        if resolved {
            "about the relative error of the masses"
        } else {
            "NOT resolved: part of the chain is beyond what these data (or f64) resolve; fit the record instead (springmass fit --data)"
        }
    );
    Ok(())
}
