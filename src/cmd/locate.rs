//! `springmass locate`: find one mass defect from `X_1(s)` with the explicit
//! locators of section 4.1 (corrected), in `f64` or extended precision.
//!
//! Data: synthetic `X_1(s)` of the chain given by `--scene`/`--defect` (its
//! defect is the truth the locator does not see), exact (closed form) or
//! through a simulated time series (`--simulate`, dt = 0.01, T = 300 by
//! default); a measured time series `--series x1.csv` (Laplace-transformed
//! with its error estimate); or measured Laplace data `--laplace FILE.csv`
//! (columns `s`, `x` and optionally `err`; numbers are read as decimals at
//! the working precision).
//!
//! Exit status: 0 located, 4 not resolvable (the reason is printed), 2 bad
//! input, 3 I/O (see `springmass --help`).

use super::ChainArgs;
use anyhow::{bail, Context};
use clap::Args as ClapArgs;
use springmass::detect::locate::{
    curve, default_grid, locate, Estimate, LaplaceData, Location, Method, Model, Point, SChoice,
};
use springmass::plot::{Line, LinePlot};
use springmass::precision::RealScalar;
#[cfg(feature = "bigfloat")]
use springmass::precision::{check_bits, with_precision, BigReal};
use springmass::series::TimeSeries;
use springmass::time::series::{SeriesTransform, TransformOptions};
use springmass::Error;
use std::path::PathBuf;

/// Arguments of `springmass locate`.
#[derive(ClapArgs, Debug)]
pub struct Args {
    #[command(flatten)]
    pub chain: ChainArgs,
    /// Known mass of the defect (selects the exact known-mass locator, (4.7)).
    /// (`--mass` is the chain's uniform mass.)
    #[arg(long = "m", value_name = "M", conflicts_with = "large")]
    pub defect_mass: Option<f64>,
    /// Heavy defect of unknown mass: (4.17), rewritten and extrapolated in s.
    #[arg(long)]
    pub large: bool,
    /// Locator: exact | asymptotic (need --m), large | large-paper, unknown-mass.
    /// Default: exact with --m, large with --large, unknown-mass otherwise.
    #[arg(long)]
    pub method: Option<String>,
    /// Measured Laplace data: CSV with columns s, x [, err] (absolute error).
    #[arg(long, value_name = "FILE.csv", conflicts_with_all = ["series", "simulate"])]
    pub laplace: Option<PathBuf>,
    /// Measured time series x_1(t): CSV with a header `t,<name>,...`; it is
    /// Laplace-transformed with a per-s error estimate.
    #[arg(long, value_name = "FILE.csv", conflicts_with = "simulate")]
    pub series: Option<PathBuf>,
    /// Column of --series to use, by name or number (1 = the first column
    /// after the time) [default: 1].
    #[arg(long, requires = "series")]
    pub column: Option<String>,
    /// White-noise standard deviation of the --series samples (adds the
    /// transformed noise to each value's error).
    #[arg(long, requires = "series")]
    pub noise_sigma: Option<f64>,
    /// Synthetic data through a simulated time series (instead of the closed form).
    #[arg(long)]
    pub simulate: bool,
    /// Output step of --simulate.
    #[arg(long, default_value_t = 0.01, requires = "simulate")]
    pub dt: f64,
    /// Duration of --simulate.
    #[arg(long, default_value_t = 300.0, requires = "simulate")]
    pub t_end: f64,
    /// Where to evaluate: `auto` (default), one value, or a comma-separated list
    /// (synthetic data are generated there; `auto` uses 61 values from 1e-3 to 100).
    /// For the large-defect locators one value S also uses S/2 and S/sqrt(2).
    #[arg(long, default_value = "auto")]
    pub s: String,
    /// Working precision in bits (64..=4096, a run of seconds; 16384 took
    /// minutes); default: f64.
    #[arg(long, value_name = "BITS")]
    pub precision: Option<usize>,
    /// j(s) curve at STEPS values of s from S0 to S1 (the paper's Figures 11, 13, 15).
    #[arg(long, value_name = "S0:S1:STEPS")]
    pub curve: Option<String>,
    /// Write the curve as an SVG plot.
    #[arg(long, value_name = "FILE.svg", requires = "curve")]
    pub plot: Option<PathBuf>,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
}

/// Largest `--precision` (bits): the same cap as a study's locate case, so
/// that a run ends in seconds.
#[cfg(feature = "bigfloat")]
pub const MAX_CLI_BITS: usize = 4096;

enum Outcome {
    Located,
    Unresolvable,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    if let Some(p) = &a.plot {
        springmass::io::resolve_output(p)?;
    }
    let outcome = match a.precision {
        None => run_in::<f64>(&a)?,
        #[cfg(feature = "bigfloat")]
        Some(bits) => {
            let bits = check_bits(bits)?;
            if bits > MAX_CLI_BITS {
                return Err(springmass::Error::invalid(
                    "precision",
                    bits,
                    format!("64..={MAX_CLI_BITS} bits (the cost grows faster than the square of the bits: 16384 took minutes, 65536 did not finish in 300 s)"),
                )
                .into());
            }
            with_precision(bits, || run_in::<BigReal>(&a))?
        }
        #[cfg(not(feature = "bigfloat"))]
        Some(bits) => return Err(springmass::precision::unavailable(bits).into()),
    };
    if let Outcome::Unresolvable = outcome {
        use std::io::Write;
        std::io::stdout()
            .flush()
            .map_err(|e| Error::io("stdout", e))?;
        std::process::exit(springmass::error::exit::UNRESOLVABLE);
    }
    Ok(())
}

fn method(a: &Args) -> anyhow::Result<Method> {
    let name = match (&a.method, a.defect_mass, a.large) {
        (Some(m), _, _) => m.as_str(),
        (None, Some(_), _) => "exact",
        (None, None, true) => "large",
        (None, None, false) => "unknown-mass",
    };
    let defect_mass = a.defect_mass;
    Ok(Method::from_name(name, || {
        defect_mass.ok_or_else(|| {
            springmass::Error::invalid(
                "--m",
                "missing",
                format!("the defect mass for --method {name}"),
            )
        })
    })?)
}

/// `(the s values to generate synthetic data at, the choice for the locator)`.
fn s_plan(text: &str, method: Method) -> anyhow::Result<(Vec<f64>, SChoice)> {
    let t = text.trim();
    if t == "auto" {
        return Ok((default_grid(), SChoice::Auto));
    }
    let mut vals = Vec::new();
    for part in t.split(',') {
        let v: f64 = part.trim().parse().map_err(|_| {
            Error::parse(
                "s",
                part,
                "expected auto, a positive number or a comma-separated list",
            )
        })?;
        if !(v.is_finite() && v > 0.0) {
            return Err(Error::invalid("s", v, "s > 0 and finite").into());
        }
        vals.push(v);
    }
    let large = matches!(method, Method::Large | Method::LargePaper);
    match (vals.len(), large, method) {
        (1, true, _) => {
            let s = vals[0];
            Ok((vec![s / 2.0, s / 2f64.sqrt(), s], SChoice::At(s)))
        }
        (1, false, Method::UnknownMass) => Err(Error::invalid(
            "s",
            t,
            "auto or two or more values for the unknown-mass locator",
        )
        .into()),
        (1, false, _) => Ok((vals.clone(), SChoice::At(vals[0]))),
        _ => Ok((vals, SChoice::Auto)),
    }
}

fn parse_curve(text: &str) -> anyhow::Result<Vec<f64>> {
    let bad = || {
        Error::parse(
            "curve",
            text,
            "expected S0:S1:STEPS with 0 < S0 < S1, STEPS >= 2",
        )
    };
    let parts: Vec<&str> = text.split(':').collect();
    if parts.len() != 3 {
        return Err(bad().into());
    }
    let s0: f64 = parts[0].trim().parse().map_err(|_| bad())?;
    let s1: f64 = parts[1].trim().parse().map_err(|_| bad())?;
    let steps: usize = parts[2].trim().parse().map_err(|_| bad())?;
    if !(s0.is_finite() && s1.is_finite() && s0 > 0.0 && s1 > s0 && (2..=100_000).contains(&steps))
    {
        return Err(bad().into());
    }
    Ok((0..steps)
        .map(|i| s0 + (s1 - s0) * i as f64 / (steps - 1) as f64)
        .collect())
}

fn read_laplace<T: RealScalar>(path: &std::path::Path) -> anyhow::Result<LaplaceData<T>> {
    let bytes = springmass::io::read_capped(path)?;
    let mut rdr = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .comment(Some(b'#'))
        .from_reader(bytes.as_slice());
    let headers = rdr
        .headers()
        .map_err(|e| Error::parse(path.display().to_string(), "", e.to_string()))?
        .clone();
    let col = |names: &[&str]| headers.iter().position(|h| names.contains(&h));
    let (Some(is), Some(ix)) = (col(&["s"]), col(&["x", "x1", "X1"])) else {
        bail!(
            "{}: need columns s and x (or x1); found {:?}",
            path.display(),
            headers.iter().collect::<Vec<_>>()
        );
    };
    let ie = col(&["err", "error"]);
    let mut points = Vec::new();
    for (line, rec) in rdr.records().enumerate() {
        let rec = rec.map_err(|e| Error::parse(path.display().to_string(), "", e.to_string()))?;
        let what = format!("{} line {}", path.display(), line + 2);
        let field = |i: usize| -> anyhow::Result<T> {
            let t = rec.get(i).unwrap_or("");
            T::parse_decimal(t)
                .ok_or_else(|| Error::parse(what.clone(), t, "expected a finite number").into())
        };
        let err = match ie {
            Some(i) => field(i)?.to_f64(),
            None => 0.0,
        };
        points.push(Point {
            s: field(is)?,
            x: field(ix)?,
            err,
        });
    }
    Ok(LaplaceData::new(format!("{}", path.display()), points)?)
}

fn read_series(a: &Args, path: &PathBuf) -> anyhow::Result<SeriesTransform> {
    let ts = TimeSeries::read_csv(path)?;
    let column = match &a.column {
        Some(c) => ts.select(c)?.0.to_string(),
        None => ts
            .names()
            .first()
            .cloned()
            .with_context(|| format!("{}: no value column", path.display()))?,
    };
    let opts = TransformOptions {
        noise_sigma: a.noise_sigma,
        ..Default::default()
    };
    SeriesTransform::from_series(&ts, &column, &opts)
        .with_context(|| format!("{}: column {column}", path.display()))
}

fn run_in<T: RealScalar>(a: &Args) -> anyhow::Result<Outcome> {
    let method = method(a)?;
    let (s_values, choice) = s_plan(&a.s, method)?;
    let measured = a.laplace.is_some() || a.series.is_some();
    let model_chain = || -> anyhow::Result<springmass::Chain> {
        if a.chain.n.is_some() || a.chain.scene.is_some() {
            a.chain.chain()
        } else {
            bail!("measured data need the chain (--n, or --scene) for the locator's model")
        }
    };
    let synthetic = |svals: &[f64]| -> anyhow::Result<LaplaceData<T>> {
        let chain = a.chain.chain()?;
        if chain.defects().is_empty() {
            bail!("synthetic data need the true defect: give --defect mass:J:M or a --scene with a defect (or use --series / --laplace)");
        }
        Ok(if a.simulate {
            LaplaceData::from_simulation(&chain, a.t_end, a.dt, svals)?
        } else {
            LaplaceData::from_chain(&chain, svals)?
        })
    };
    let transform = match &a.series {
        Some(path) => Some(read_series(a, path)?),
        None => None,
    };
    let source = |svals: &[f64]| -> anyhow::Result<LaplaceData<T>> {
        if let Some(path) = &a.laplace {
            read_laplace(path)
        } else if let (Some(tr), Some(path)) = (&transform, &a.series) {
            Ok(LaplaceData::from_transform(
                format!("{} (Laplace-transformed)", path.display()),
                tr,
                svals,
            )?)
        } else {
            synthetic(svals)
        }
    };
    let model_of = if measured {
        model_chain()?
    } else {
        a.chain.chain()?
    };
    model_of.require_fixed_ends("the explicit locators of section 4.1")?;
    model_of.require_uniform("the explicit locators of section 4.1")?;
    let model: Model<T> = Model::from_chain(&model_of);
    let data = source(&s_values)?;
    let precision = match a.precision {
        Some(b) => format!("{b} bits"),
        None => "f64".into(),
    };
    if let Some(spec) = &a.curve {
        let svals = parse_curve(spec)?;
        let cdata: LaplaceData<T> = if a.laplace.is_some() {
            // a curve over tabulated Laplace data uses the data's own s in the range
            let (lo, hi) = (svals[0], svals[svals.len() - 1]);
            let pts: Vec<Point<T>> = data
                .points()
                .iter()
                .filter(|p| {
                    let s = p.s.to_f64();
                    s >= lo && s <= hi
                })
                .cloned()
                .collect();
            LaplaceData::new(data.label(), pts)?
        } else {
            source(&svals)?
        };
        let est = curve(&model, &cdata, method)?;
        print_curve(a, method, &precision, &est)?;
        return Ok(Outcome::Located);
    }
    match locate(&model, &data, method, choice) {
        Ok(loc) => {
            print_location(a, &precision, data.label(), &loc);
            Ok(Outcome::Located)
        }
        Err(Error::Unresolvable { reason }) => {
            if a.json {
                println!(
                    "{}",
                    serde_json::json!({
                        "resolved": false,
                        "method": method.name(),
                        "precision": precision,
                        "reason": reason,
                    })
                );
            } else {
                println!("not resolvable: {reason}");
            }
            Ok(Outcome::Unresolvable)
        }
        Err(e) => Err(e.into()),
    }
}

/// Decimal digits worth printing for an uncertainty `sigma`.
fn digits_for(sigma: f64, j: f64) -> usize {
    let rel = sigma / j.abs().max(1.0);
    if rel > 0.0 && rel.is_finite() {
        ((-rel.log10()).ceil() as usize + 2).clamp(3, 120)
    } else {
        17
    }
}

fn print_location<T: RealScalar>(a: &Args, precision: &str, label: &str, loc: &Location<T>) {
    let jf = loc.j.to_f64();
    let jtext = loc.j.to_decimal(digits_for(loc.sigma + loc.bias, jf));
    let raw = loc
        .raw_j
        .as_ref()
        .map(|r| r.to_decimal(digits_for(loc.sigma, jf)));
    if a.json {
        println!(
            "{}",
            serde_json::json!({
                "resolved": true,
                "method": loc.method.name(),
                "precision": precision,
                "data": label,
                "position": loc.position,
                "j": jtext,
                "j_f64": jf,
                "sigma": loc.sigma,
                "model_error": loc.bias,
                "s": loc.s,
                "used_s": loc.used,
                "mass": loc.mass,
                "raw_j": raw,
            })
        );
    } else {
        println!(
            "# locate: method {}, precision {precision}, data: {label}",
            loc.method.name()
        );
        println!("position     {}", loc.position);
        println!("j            {jtext}");
        println!("sigma        {:.3e}", loc.sigma);
        println!("model error  {:.3e}", loc.bias);
        println!("s            {}", loc.s);
        if let Some(r) = raw {
            println!("j(s) raw     {r}   (before extrapolation in 1/lambda)");
        }
        if let Some(m) = loc.mass {
            println!("mass (est.)  {m:.6}");
        }
    }
}

fn print_curve<T: RealScalar>(
    a: &Args,
    method: Method,
    precision: &str,
    est: &[Estimate<T>],
) -> anyhow::Result<()> {
    if a.json {
        let pts: Vec<serde_json::Value> = est
            .iter()
            .map(|e| {
                serde_json::json!({
                    "s": e.s,
                    "j": e.j.as_ref().map(|j| j.to_decimal(digits_for(e.sigma, j.to_f64()))),
                    "sigma": e.sigma,
                    "model_error": e.bias,
                    "signal": e.signal,
                    "floor": e.floor,
                    "status": e.status.name(),
                })
            })
            .collect();
        println!(
            "{}",
            serde_json::json!({"method": method.name(), "precision": precision, "curve": pts})
        );
    } else {
        println!("# j(s), method {}, precision {precision}", method.name());
        println!(
            "{:>12} {:>24} {:>10} {:>10} {:>10} {:>10}  status",
            "s", "j", "sigma", "model_err", "signal", "floor"
        );
        for e in est {
            let j =
                e.j.as_ref()
                    .map(|j| j.to_decimal(digits_for(e.sigma, j.to_f64()).min(20)))
                    .unwrap_or_else(|| "-".into());
            println!(
                "{:>12.6} {:>24} {:>10.2e} {:>10.2e} {:>10.2e} {:>10.2e}  {}",
                e.s,
                j,
                e.sigma,
                e.bias,
                e.signal,
                e.floor,
                e.status.name()
            );
        }
    }
    if let Some(path) = &a.plot {
        let pts: Vec<(f64, f64)> = est
            .iter()
            .filter(|e| e.status == springmass::detect::locate::Status::Ok)
            .map(|e| (e.s, e.j_f64()))
            .collect();
        if pts.is_empty() {
            bail!("no s in the curve gives a usable estimate: nothing to plot");
        }
        LinePlot::new(
            format!("j(s), {} locator ({precision})", method.name()),
            "s",
            "j(s)",
        )
        .line(Line::new(method.name(), pts))
        .write_svg(path)?;
        if !a.json {
            println!("# plot written to {}", path.display());
        }
    }
    Ok(())
}
