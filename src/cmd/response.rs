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

/// `X_observe(s)`, real arithmetic on the real axis.
fn eval(fwd: &Forward, s: Complex64, observe: usize) -> springmass::Result<Complex64> {
    if s.im == 0.0 {
        Ok(fwd.eval(s.re, observe)?.into())
    } else {
        fwd.eval(s, observe)
    }
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let chain = a.chain.chain()?;
    let fwd = Forward::new(&chain);
    let mut rows = Vec::with_capacity(a.s.len());
    let s_values =
        a.s.iter()
            .map(|t| parse_complex(t))
            .collect::<Result<Vec<_>, _>>()?;
    for s in s_values {
        let x = match eval(&fwd, s, a.observe) {
            Err(springmass::Error::Singular { s: at }) if chain.gamma() != 1.0 => {
                // a pole, or X = gamma * G overflowing f64: decide with gamma = 1
                let unit = chain.clone().with_gamma(1.0)?;
                match eval(&Forward::new(&unit), s, a.observe) {
                    Ok(g) => {
                        return Err(springmass::Error::Unresolvable {
                            reason: format!(
                                "X_{}({at}) = gamma * ({} {:+}i) with gamma = {} overflows f64",
                                a.observe,
                                g.re,
                                g.im,
                                chain.gamma()
                            ),
                        }
                        .into())
                    }
                    Err(_) => return Err(springmass::Error::Singular { s: at }.into()),
                }
            }
            other => other?,
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
