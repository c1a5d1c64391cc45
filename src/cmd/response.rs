//! `springmass response`: print X_i(s) for a list of s.

use super::ChainArgs;
use clap::Args as ClapArgs;
use springmass::forward::Forward;
use springmass::scalar::parse_complex;
use springmass::Complex64;

/// Arguments of `springmass response`.
#[derive(ClapArgs, Debug)]
pub struct Args {
    #[command(flatten)]
    pub chain: ChainArgs,
    /// Values of s, comma separated or repeated: 0.5,1+5i,2-0.5i.
    #[arg(
        long,
        value_delimiter = ',',
        required = true,
        allow_hyphen_values = true
    )]
    pub s: Vec<String>,
    /// The observed mass (1-based).
    #[arg(long, default_value_t = 1)]
    pub observe: usize,
    /// Print JSON: {"points": [{"s": [re, im], "x": [re, im]}, ...]}.
    #[arg(long)]
    pub json: bool,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let chain = a.chain.chain()?;
    let fwd = Forward::new(&chain);
    let mut rows = Vec::with_capacity(a.s.len());
    for t in &a.s {
        let s = parse_complex(t)?;
        let x: Complex64 = if s.im == 0.0 {
            fwd.eval(s.re, a.observe)?.into()
        } else {
            fwd.eval(s, a.observe)?
        };
        rows.push((s, x));
    }
    if a.json {
        let points: Vec<serde_json::Value> = rows
            .iter()
            .map(|(s, x)| serde_json::json!({"s": [s.re, s.im], "x": [x.re, x.im]}))
            .collect();
        println!("{}", serde_json::json!({ "points": points }));
    } else {
        println!(
            "# chain: n = {}, k = {}, d = {}, gamma = {}, mass = {}, defects = [{}]",
            chain.n(),
            chain.k(),
            chain.d(),
            chain.gamma(),
            chain.mass(),
            chain
                .defects()
                .iter()
                .map(|d| d.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        );
        println!("# X_{}(s)", a.observe);
        println!(
            "{:>24} {:>24} {:>24} {:>24}",
            "Re s", "Im s", "Re X", "Im X"
        );
        for (s, x) in rows {
            println!(
                "{:>24.16e} {:>24.16e} {:>24.16e} {:>24.16e}",
                s.re, s.im, x.re, x.im
            );
        }
    }
    Ok(())
}
