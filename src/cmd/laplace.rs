//! `springmass laplace`: the Laplace transform X(s) of a sampled series (CSV)
//! with a per-point error estimate.

use anyhow::Context;
use clap::Args as ClapArgs;
use springmass::scalar::parse_complex;
use springmass::series::TimeSeries;
use springmass::time::series::{
    LaplaceValue, SeriesTransform, Tail, TransformOptions, DEFAULT_DEGREE,
};
use springmass::Error;
use std::path::PathBuf;

/// The tail model on the command line.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum TailArg {
    Envelope,
    Modes,
    Zero,
}

/// Arguments of `springmass laplace`.
#[derive(ClapArgs, Debug)]
pub struct Args {
    /// CSV time series with a header `t,<name>,...` (uniform or not; times
    /// >= 0; `,` `;` or tab; units, pandas index and `#` comments accepted).
    #[arg(long)]
    pub series: PathBuf,
    /// Column to transform, by name or number (1 = the first column after the
    /// time) [default: 1].
    #[arg(long)]
    pub column: Option<String>,
    /// Values of s, comma separated or repeated: 0.5,1+5i,0.05+2i.
    #[arg(
        long,
        value_delimiter = ',',
        required = true,
        allow_hyphen_values = true
    )]
    pub s: Vec<String>,
    /// Degree of the local interpolant (3..=9); the error estimate compares with degree - 2.
    #[arg(long, default_value_t = DEFAULT_DEGREE)]
    pub degree: usize,
    /// Known white-noise standard deviation of the samples: adds the noise
    /// standard deviation of each X(s).
    #[arg(long, allow_hyphen_values = true)]
    pub noise_sigma: Option<f64>,
    /// After the last sample: `envelope` (bound the tail by a fitted
    /// exponential envelope), `modes` (fit decaying modes and add their
    /// transform as a correction; falls back to `envelope`), `zero` (the
    /// signal is zero there).
    #[arg(long, value_enum, default_value_t = TailArg::Envelope)]
    pub tail: TailArg,
    /// Print JSON: {"points": [{"s": [re, im], "x": [re, im], "err": e}, ...]}
    /// (plus "noise_std" per point with --noise-sigma).
    #[arg(long)]
    pub json: bool,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let s_values =
        a.s.iter()
            .map(|text| parse_complex(text))
            .collect::<Result<Vec<_>, _>>()?;
    let ts = TimeSeries::read_csv(&a.series)?;
    if ts.t()[0] < 0.0 {
        return Err(Error::invalid(
            format!("{}: t[0]", a.series.display()),
            ts.t()[0],
            "t >= 0: the Laplace transform integrates from t = 0 (shift the times)",
        )
        .into());
    }
    let column = match &a.column {
        Some(c) => ts.select(c)?.0.to_string(),
        None => ts.names()[0].clone(),
    };
    let opts = TransformOptions {
        degree: a.degree,
        noise_sigma: a.noise_sigma,
        tail: match a.tail {
            TailArg::Envelope => Tail::Envelope,
            TailArg::Modes => Tail::Modes,
            TailArg::Zero => Tail::Zero,
        },
    };
    let tr = SeriesTransform::from_series(&ts, &column, &opts)
        .with_context(|| format!("{}: column {column}", a.series.display()))?;
    let mut rows = Vec::with_capacity(a.s.len());
    for (text, &s) in a.s.iter().zip(&s_values) {
        let v = tr.eval(s).with_context(|| format!("at s = {text}"))?;
        if !v.is_finite() {
            return Err(Error::Unresolvable {
                reason: format!(
                    "X({text}) or its error estimate is not representable in f64 (got {} {:+}i, err {})",
                    v.value.re, v.value.im, v.err
                ),
            }
            .into());
        }
        rows.push(v);
    }
    if a.json {
        print_json(&rows);
    } else {
        print_text(&a, &ts, &column, &tr, rows);
    }
    Ok(())
}

/// The values as JSON: `{"points": [{"s", "x", "err"[, "noise_std"]}, ...]}`.
fn print_json(rows: &[LaplaceValue]) {
    let points: Vec<serde_json::Value> = rows
        .iter()
        .map(|v| {
            let mut p = serde_json::json!({
                "s": [v.s.re, v.s.im],
                "x": [v.value.re, v.value.im],
                "err": v.err,
            });
            if let Some(var) = v.noise_var {
                p["noise_std"] = serde_json::json!(var.sqrt());
            }
            p
        })
        .collect();
    println!("{}", serde_json::json!({ "points": points }));
}

/// The values as a table under `#` lines on the series, the interpolant and
/// the tail.
fn print_text(
    a: &Args,
    ts: &TimeSeries,
    column: &str,
    tr: &SeriesTransform,
    rows: Vec<LaplaceValue>,
) {
    let t = ts.t();
    println!(
        "# {}: column {column}, {} samples on [{}, {}], degree {}",
        a.series.display(),
        t.len(),
        t[0],
        t[t.len() - 1],
        tr.degree()
    );
    if let Some(fit) = tr.mode_fit() {
        println!(
            "# tail after t = {}: {} decaying modes fitted (relative residual {:.1e}), transform added",
            fit.t_end,
            fit.poles.len(),
            fit.residual
        );
    }
    if let Some(env) = tr.envelope() {
        println!(
            "# tail after t = {}: |x| <= {:.3e} exp(-{:.3e} (t - {}))  (bound, no correction)",
            env.t_end, env.amp, env.rate, env.t_end
        );
    }
    println!(
        "{:>24} {:>24} {:>24} {:>24} {:>10} {:>10} {:>10}{}",
        "Re s",
        "Im s",
        "Re X",
        "Im X",
        "err",
        "disc",
        "trunc",
        if a.noise_sigma.is_some() {
            format!(" {:>10}", "noise_std")
        } else {
            String::new()
        }
    );
    for v in rows {
        println!(
            "{:>24.16e} {:>24.16e} {:>24.16e} {:>24.16e} {:>10.3e} {:>10.3e} {:>10.3e}{}",
            v.s.re,
            v.s.im,
            v.value.re,
            v.value.im,
            v.err,
            v.err_disc,
            v.err_trunc,
            v.noise_var
                .map(|var| format!(" {:>10.3e}", var.sqrt()))
                .unwrap_or_default()
        );
    }
}
