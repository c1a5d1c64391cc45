//! `springmass fit`: fit defect positions and masses to data described by a
//! TOML scene (see `springmass::detect::scene`).

use anyhow::Context;
use clap::Args as ClapArgs;
use springmass::detect::fit::paper::{fit, FitMethod, FitReport};
use springmass::detect::scene::FitScene;
use std::path::PathBuf;

/// Arguments of `springmass fit`.
#[derive(ClapArgs, Debug)]
pub struct Args {
    /// The fit scene (TOML with [chain], [data], [unknowns], [misfit], [search]).
    #[arg(long)]
    pub scene: PathBuf,
    /// enumerate | ga | nelder-mead | pso (overrides [search].method).
    #[arg(long)]
    pub method: Option<String>,
    /// Seed of stochastic methods (overrides [search].seed).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Noise level of synthetic data (overrides [data].noise; relative or
    /// absolute as [data].relative says).
    #[arg(long)]
    pub noise: Option<f64>,
    /// Record and print the optimizer's trace.
    #[arg(long)]
    pub trace: bool,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let mut scene = FitScene::load(&a.scene)?;
    if let Some(m) = &a.method {
        scene.search.method = FitMethod::parse(m)?;
    }
    if let Some(s) = a.seed {
        scene.search.seed = s;
    }
    if let Some(x) = a.noise {
        scene.data.noise = x;
    }
    if a.trace {
        scene.search.trace = true;
    }
    let data = scene.data().context("in [data]")?;
    let report = fit(&scene, &data, &scene.options())?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print_text(&scene, &report);
    }
    Ok(())
}

/// `(at, value)` for masses; `(kind at, value)` for other kinds or when
/// `kinds` (the general fit).
fn fmt_defects(d: &[springmass::Defect], kinds: bool) -> String {
    d.iter()
        .map(|d| match d {
            springmass::Defect::Mass { .. } if !kinds => format!("({}, {:.6})", d.at(), d.value()),
            _ => format!("({} {}, {:.6})", d.kind(), d.at(), d.value()),
        })
        .collect::<Vec<_>>()
        .join(", ")
}

fn print_text(scene: &FitScene, r: &FitReport) {
    println!("# method   {}", r.method);
    println!("# misfit   {} ({} nodes)", r.misfit, r.nodes);
    let general = !r.std_errors.is_empty();
    let truth: Vec<springmass::Defect> = scene.chain.defects.clone();
    if !truth.is_empty() {
        println!("truth      {}", fmt_defects(&truth, general));
    }
    println!("found      {}", fmt_defects(&r.defects, general));
    if !r.std_errors.is_empty() {
        for (d, se) in r.defects.iter().zip(&r.std_errors) {
            println!(
                "  {:<6} at {:>3}  {:.6} +- {:.2e}",
                d.kind(),
                d.at(),
                d.value(),
                se
            );
        }
    }
    for p in &r.chain_params {
        println!(
            "  chain {:<6} {:.6} +- {:.2e}",
            p.name, p.value, p.std_error
        );
    }
    println!(
        "{}   {:.6e}",
        if general { "chi2    " } else { "residual" },
        r.residual
    );
    println!(
        "{} {:.3e}  ({})",
        if general { "gap thr. " } else { "data floor" },
        r.floor,
        if r.resolved {
            "resolved: the first runner-up is above the floor"
        } else {
            "NOT resolved: the first runner-up is within the data's error"
        }
    );
    if !r.fits_data {
        println!(
            "WARNING    the residual is far above the data floor: the hypothesis does not explain the data (a defect missing from [unknowns], or the search missed the truth)"
        );
    }
    if !r.runners_up.is_empty() {
        println!("runners-up");
        for alt in &r.runners_up {
            println!(
                "  {:<48} r = {:.6e}  gap = {:.3e}",
                fmt_defects(&alt.defects, general),
                alt.residual,
                alt.gap
            );
        }
    }
    if let Some(id) = &r.identifiability {
        println!(
            "identifiability (noise level {:.3e}; gap threshold {})",
            id.sigma, id.threshold
        );
        if let (Some(g), Some(s)) = (id.runner_up_gap, id.sigma_indistinguishable) {
            println!(
                "  runner-up chi2 gap {g:.4e}: indistinguishable from the answer at noise {s:.3e} ({:.1}x the data's)",
                if id.sigma > 0.0 { s / id.sigma } else { f64::INFINITY }
            );
        }
        for d in &id.defects {
            println!(
                "  at {:>3}: {:.1} SE from the uniform value; {}{}",
                d.at,
                d.significance,
                match (d.nearest_rival, d.position_gap) {
                    (Some(p), Some(g)) => format!("nearest rival position {p} (chi2 gap {g:.3e})"),
                    _ => "no listed alternative moves it".to_string(),
                },
                if d.identifiable {
                    String::from("  identifiable")
                } else {
                    format!("  NOT identifiable: {}", d.reason)
                }
            );
        }
    }
    let sets = r
        .sets
        .map(|s| format!(", {s} position sets"))
        .unwrap_or_default();
    let beam = match r.exhaustive {
        Some(false) => " (beam search)",
        _ => "",
    };
    println!("evaluations {}{sets}{beam}", r.evaluations);
    println!(
        "wall time  {:.3} ms (setup {:.3} ms)",
        r.wall_time_s * 1e3,
        r.setup_time_s * 1e3
    );
    if !r.trace.is_empty() {
        println!("trace (evaluations, best residual)");
        for (e, c) in &r.trace {
            println!("  {e:>8} {c:.6e}");
        }
    }
}
