//! `springmass` command-line interface: a thin layer over the library.
//! Every subcommand lives in its own file under `src/cmd/`.

mod cmd;

use clap::{Parser, Subcommand};

/// Vibration suppression and defect detection in 1D spring-mass chains.
#[derive(Parser)]
#[command(name = "springmass", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Laplace-domain response X_i(s) of a chain (closed form + Woodbury).
    Response(cmd::response::Args),
    /// Run a study file (sweep of cases) in parallel into tables and plots; `study merge` combines shards.
    Study(cmd::study::Args),
    /// Check a study file, print the schema of every field with its default.
    Config(cmd::config::Args),
    /// Locate one mass defect from X_1(s) (section 4.1 locators, corrected).
    Locate(cmd::locate::Args),
    /// Time-domain simulation x_i(t): impulse on mass 1, optional forces, CSV/SVG out.
    Simulate(cmd::simulate::Args),
    /// Vibration suppression controls (Theorem 3.1, Corollary 3.2), verified by simulation.
    Suppress(cmd::suppress::Args),
    /// Laplace transform X(s) of a sampled series (CSV), with error estimates.
    Laplace(cmd::laplace::Args),
    /// Fit defects to a measured series (--data; noise and number of defects estimated) or a scene (--scene).
    Fit(cmd::fit::Args),
    /// Residual surfaces r(j, m) and r(j1, j2) (the paper's Figures 16 and 17), CSV + SVG.
    Surface(cmd::surface::Args),
    /// Noise study: success vs noise per misfit, calibration, damping, number of defects.
    NoiseStudy(cmd::noise::Args),
}

fn run() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::Response(a) => cmd::response::run(a),
        Command::Study(a) => cmd::study::run(a),
        Command::Config(a) => cmd::config::run(a),
        Command::Locate(a) => cmd::locate::run(a),
        Command::Simulate(a) => cmd::simulate::run(a),
        Command::Suppress(a) => cmd::suppress::run(a),
        Command::Laplace(a) => cmd::laplace::run(a),
        Command::Fit(a) => cmd::fit::run(a),
        Command::Surface(a) => cmd::surface::run(a),
        Command::NoiseStudy(a) => cmd::noise::run(a),
    }
}

fn main() {
    if let Err(e) = run() {
        // one line: the error and its causes joined by ": "
        eprintln!("error: {e:#}");
        std::process::exit(2);
    }
}
