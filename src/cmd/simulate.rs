//! `springmass simulate`: x_i(t) of a chain (impulse on mass 1, optional
//! forces from a CSV), written as CSV and/or plotted as SVG.
//!
//! Noise: additive white Gaussian noise of standard deviation `--noise`,
//! seeded (`ChaCha8Rng::seed_from_u64(seed)`, stream = column index), so the
//! same seed gives the same data. (Implemented here until the shared noise
//! module lands on main; the lead may switch this to it.)

use super::ChainArgs;
use anyhow::Context;
use clap::Args as ClapArgs;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use springmass::plot::{Line, LinePlot};
use springmass::series::TimeSeries;
use springmass::time::simulate::{simulate_forced, Forcing, Method, SimOptions};
use springmass::Error;
use std::path::PathBuf;

/// Arguments of `springmass simulate`.
#[derive(ClapArgs, Debug)]
pub struct Args {
    #[command(flatten)]
    pub chain: ChainArgs,
    /// Last time.
    #[arg(long, default_value_t = 200.0, allow_hyphen_values = true)]
    pub t_end: f64,
    /// Output time step.
    #[arg(long, default_value_t = 0.05, allow_hyphen_values = true)]
    pub dt: f64,
    /// Observed masses (1-based), comma separated.
    #[arg(long, value_delimiter = ',', default_value = "1")]
    pub observe: Vec<usize>,
    /// Standard deviation of additive white Gaussian noise (0: none).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub noise: f64,
    /// Seed of the noise.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Method: auto, expm, modal or rk.
    #[arg(long, default_value = "auto")]
    pub method: String,
    /// External forces: a CSV `t,f<j>,...` (column f<j> acts on mass j; zero
    /// outside the sampled window).
    #[arg(long, value_name = "FILE.csv")]
    pub force: Option<PathBuf>,
    /// Interpolation order of the sampled forces (1 = linear, 3 = cubic).
    #[arg(long, default_value_t = 3)]
    pub force_order: usize,
    /// Write the series as CSV (`t,x<i>,...`); without --out and --plot the CSV goes to stdout.
    #[arg(long, value_name = "FILE.csv")]
    pub out: Option<PathBuf>,
    /// Plot the series as SVG.
    #[arg(long, value_name = "FILE.svg")]
    pub plot: Option<PathBuf>,
}

/// Add seeded white Gaussian noise of standard deviation `level` to every column.
fn add_noise(ts: &TimeSeries, level: f64, seed: u64) -> anyhow::Result<TimeSeries> {
    if !(level.is_finite() && level >= 0.0) {
        return Err(Error::invalid("noise", level, "noise >= 0 and finite").into());
    }
    if level == 0.0 {
        return Ok(ts.clone());
    }
    let normal =
        Normal::new(0.0, level).map_err(|e| Error::invalid("noise", level, e.to_string()))?;
    let cols = ts
        .names()
        .iter()
        .enumerate()
        .map(|(c, name)| {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            rng.set_stream(c as u64);
            let col = ts.column_at(c).unwrap_or_default();
            (
                name.clone(),
                col.iter().map(|x| x + normal.sample(&mut rng)).collect(),
            )
        })
        .collect();
    Ok(TimeSeries::new(ts.t().to_vec(), cols)?)
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let chain = a.chain.chain()?;
    let method: Method = a.method.parse()?;
    let forcing = match &a.force {
        Some(path) => {
            let ts = TimeSeries::read_csv(path)?;
            Forcing::from_series(&ts, a.force_order)
                .with_context(|| format!("forces from {}", path.display()))?
        }
        None => Forcing::new(),
    };
    let opts = SimOptions::new(a.t_end, a.dt)
        .with_observe(a.observe.clone())
        .with_method(method);
    let traj = simulate_forced(&chain, &opts, &forcing)?;
    let series = add_noise(&traj.to_series()?, a.noise, a.seed)?;
    if let Some(path) = &a.out {
        series.write_csv(path)?;
    }
    if let Some(path) = &a.plot {
        let defects = chain
            .defects()
            .iter()
            .map(|d| d.to_string())
            .collect::<Vec<_>>()
            .join(", ");
        let mut title = format!("n = {}, d = {}", chain.n(), chain.d());
        if !defects.is_empty() {
            title.push_str(&format!(", defects: {defects}"));
        }
        if !forcing.is_empty() {
            title.push_str(", forced");
        }
        if a.noise > 0.0 {
            title.push_str(&format!(", noise {}", a.noise));
        }
        let mut plot = LinePlot::new(title, "t", "displacement");
        for name in series.names() {
            let col = series.column(name).unwrap_or_default();
            let pts = series
                .t()
                .iter()
                .copied()
                .zip(col.iter().copied())
                .collect();
            plot = plot.line(Line::new(name.replacen('x', "x_", 1), pts));
        }
        plot.write_svg(path)?;
    }
    if a.out.is_none() && a.plot.is_none() {
        print!("{}", series.to_csv_string());
    }
    eprintln!(
        "simulated n = {}, {} samples, method {} ({} internal steps per output step)",
        chain.n(),
        traj.t.len(),
        traj.method,
        traj.substeps
    );
    Ok(())
}
