//! `springmass simulate`: x_i(t) of a chain (impulse on mass 1, optional
//! forces from a CSV), written as CSV and/or plotted as SVG.
//!
//! Noise: additive white Gaussian noise ([`springmass::noise`]): `--noise
//! SIGMA` (absolute) or `abs:SIGMA`, `snr:DB`, `rel:R`; column `c` (0-based)
//! of the output uses the seed `seed + c`, so the same seed gives the same data.

use super::ChainArgs;
use anyhow::Context;
use clap::Args as ClapArgs;
use springmass::forward::Observable;
use springmass::noise::{add_noise, NoiseLevel};
use springmass::plot::{Line, LinePlot};
use springmass::series::TimeSeries;
use springmass::time::simulate::{simulate_forced, Forcing, Method, SimOptions};
use springmass::Chain;
use std::path::{Path, PathBuf};

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
    /// Additive white Gaussian noise: SIGMA (absolute), abs:SIGMA, snr:DB or rel:R.
    #[arg(long, allow_hyphen_values = true)]
    pub noise: Option<String>,
    /// Seed of the noise (every random choice is seeded).
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
    #[command(flatten)]
    pub setup: super::response::SetupArgs,
    /// What is recorded: displacement (columns x<i>), velocity (v<i>) or
    /// acceleration (a<i>, for t > 0: the impulse's delta is not a sample).
    #[arg(long, default_value = "displacement")]
    pub observe_kind: String,
}

/// Parse `--noise`: a bare number is an absolute standard deviation.
fn noise_level(text: &str) -> anyhow::Result<NoiseLevel> {
    let level = match text.trim().parse::<f64>() {
        Ok(v) => NoiseLevel::Absolute(v),
        Err(_) => NoiseLevel::parse(text)?,
    };
    level.sigma(&[])?; // validates the level (sign, finiteness)
    Ok(level)
}

/// Add seeded noise to every column (column `c` uses `seed + c`).
fn noisy(ts: &TimeSeries, level: NoiseLevel, seed: u64) -> anyhow::Result<TimeSeries> {
    let mut cols = Vec::with_capacity(ts.names().len());
    for (c, name) in ts.names().iter().enumerate() {
        let col = ts.column_at(c).unwrap_or_default();
        let (y, _) = add_noise(col, level, seed.wrapping_add(c as u64))?;
        cols.push((name.clone(), y));
    }
    Ok(TimeSeries::new(ts.t().to_vec(), cols)?)
}

/// Estimated peak memory of a simulation (bytes): the stored series (time,
/// observed columns, noisy copy and CSV text: about 40 bytes per value), the
/// state vectors (2n values, about 16 work vectors for the Runge-Kutta
/// stages) and, for `expm` / `modal` (or `auto` with n <= 2000), dense
/// (2n x 2n) matrices (about 8 of them).
pub fn memory_estimate(n: usize, samples: f64, observed: usize, method: Method) -> f64 {
    let n = n as f64;
    let series = 40.0 * samples * (observed as f64 + 1.0);
    let state = 8.0 * 16.0 * 2.0 * n;
    let dense_possible = match method {
        Method::Rk => false,
        Method::Auto => n <= springmass::time::simulate::MAX_N_EXPM as f64,
        _ => true,
    };
    let dense = if dense_possible {
        8.0 * 8.0 * (2.0 * n) * (2.0 * n)
    } else {
        0.0
    };
    series + state + dense
}

fn check_memory(n: usize, a: &Args, method: Method) -> anyhow::Result<()> {
    if !(a.dt > 0.0 && a.dt.is_finite() && a.t_end.is_finite()) {
        return Ok(()); // the simulation's own validation names the field
    }
    let samples = (a.t_end / a.dt).abs() + 1.0;
    let bytes = memory_estimate(n, samples, a.observe.len(), method);
    springmass::io::check_alloc(
        &format!(
            "simulate (n = {n}, {samples:.0} samples of {} masses, method {})",
            a.observe.len(),
            a.method
        ),
        bytes,
    )?;
    Ok(())
}

/// Refuse a noise level `text` that put samples beyond 1e300 in magnitude
/// (meaningless, and they hang the plot's axes).
fn check_noisy(series: &TimeSeries, text: &str) -> springmass::Result<()> {
    for (c, name) in series.names().iter().enumerate() {
        let col = series.column_at(c).unwrap_or_default();
        if let Some(i) = col
            .iter()
            .position(|v| v.abs() > springmass::io::MAX_MAGNITUDE)
        {
            return Err(springmass::Error::invalid(
                "--noise",
                text,
                format!(
                    "a level that keeps the samples within 1e300 in magnitude ({name}[{i}] = {:e})",
                    col[i]
                ),
            ));
        }
    }
    Ok(())
}

/// Draw every column of `series` against t, titled with the chain, its
/// defects, the forcing, the noise and free ends.
fn plot_series(
    chain: &Chain,
    series: &TimeSeries,
    forcing: &Forcing,
    a: &Args,
    kind: Observable,
    path: &Path,
) -> springmass::Result<()> {
    let defects = chain
        .defects()
        .iter()
        .map(|d| d.to_string())
        .collect::<Vec<_>>()
        .join(", ");
    let mut title = format!("n = {}, d = {}", chain.n(), chain.d());
    if !chain.damping().is_grounded() {
        title.push_str(&format!(", damping {}", chain.damping()));
    }
    if !defects.is_empty() {
        title.push_str(&format!(", defects: {defects}"));
    }
    if !forcing.is_empty() {
        title.push_str(", forced");
    }
    if let Some(text) = &a.noise {
        title.push_str(&format!(", noise {text}"));
    }
    if !chain.is_fixed_fixed() {
        title.push_str(&format!(", ends {}-{}", chain.left(), chain.right()));
    }
    let mut plot = LinePlot::new(title, "t", kind.name());
    for name in series.names() {
        let col = series.column(name).unwrap_or_default();
        let pts = series
            .t()
            .iter()
            .copied()
            .zip(col.iter().copied())
            .collect();
        plot = plot.line(Line::new(
            name.replacen(kind.prefix(), &format!("{}_", kind.prefix()), 1),
            pts,
        ));
    }
    plot.write_svg(path)?;
    Ok(())
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let chain = a.setup.apply(a.chain.chain()?)?;
    let kind: Observable = a.observe_kind.parse()?;
    let method: Method = a.method.parse()?;
    let level = a.noise.as_deref().map(noise_level).transpose()?;
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
        .with_method(method)
        .with_observe_kind(kind);
    opts.samples(&chain)?; // the simulation's own checks first (dt, t_end, stored values)
    check_memory(chain.n(), &a, method)?;
    let outs = [&a.out, &a.plot];
    springmass::io::check_outputs(outs.iter().filter_map(|p| p.as_deref()))?;
    let traj = simulate_forced(&chain, &opts, &forcing)?;
    let series = match level {
        Some(l) => noisy(&traj.to_series()?, l, a.seed)?,
        None => traj.to_series()?,
    };
    if let Some(text) = &a.noise {
        check_noisy(&series, text)?;
    }
    if let Some(path) = &a.out {
        series.write_csv(path)?;
    }
    if let Some(path) = &a.plot {
        plot_series(&chain, &series, &forcing, &a, kind, path)?;
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
