//! `springmass response`: print X_i(s) for a list of s.

use super::ChainArgs;
use clap::Args as ClapArgs;
use springmass::chain::{Boundary, Units};
use springmass::forward::{Forward, Observable};
use springmass::scalar::parse_complex;
use springmass::time::modal::{natural_modes, NaturalMode};
use springmass::{Chain, Complex64};

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
    #[command(flatten)]
    pub setup: SetupArgs,
    /// What is observed: displacement (X), velocity (s X) or acceleration
    /// (s^2 X - x'(0+): the impulse's delta excluded).
    #[arg(long, default_value = "displacement")]
    pub observe_kind: String,
    /// Excitation: `impulse` (gamma delta on mass 1) or `force` (print the
    /// transfer function H(s) per unit force on mass 1; multiply by F(s)).
    #[arg(long, default_value = "impulse")]
    pub excitation: String,
    /// Also print the natural frequencies and damping ratios of the chain.
    #[arg(long)]
    pub modes: bool,
}

/// Ends and physical units of the chain, shared by `response` and `simulate`.
#[derive(ClapArgs, Debug, Clone, Default)]
pub struct SetupArgs {
    /// Left end (mass 1's side): fixed or free [default: the scene's, else fixed].
    #[arg(long)]
    pub left: Option<String>,
    /// Right end (mass n's side): fixed or free [default: the scene's, else fixed].
    #[arg(long)]
    pub right: Option<String>,
    /// kg per unit of mass (the chain's masses are multiplied by it; with
    /// the other scales the chain is in SI units: t in s, omega in rad/s).
    #[arg(long)]
    pub mass_scale: Option<f64>,
    /// N/m per unit of stiffness.
    #[arg(long)]
    pub stiffness_scale: Option<f64>,
    /// N s/m per unit of damping.
    #[arg(long)]
    pub damping_scale: Option<f64>,
}

impl SetupArgs {
    /// Apply the ends and the unit scales to `chain`.
    pub fn apply(&self, chain: Chain) -> anyhow::Result<Chain> {
        let left = match &self.left {
            Some(t) => t.parse::<Boundary>()?,
            None => chain.left(),
        };
        let right = match &self.right {
            Some(t) => t.parse::<Boundary>()?,
            None => chain.right(),
        };
        let chain = chain.with_boundaries(left, right)?;
        let units = Units::new(
            self.mass_scale.unwrap_or(1.0),
            self.stiffness_scale.unwrap_or(1.0),
            self.damping_scale.unwrap_or(1.0),
        )?;
        Ok(chain.to_si(&units)?)
    }

    /// Any unit scale given.
    pub fn has_units(&self) -> bool {
        self.mass_scale.is_some() || self.stiffness_scale.is_some() || self.damping_scale.is_some()
    }
}

/// The natural modes as text lines (`# mode j: omega, f, zeta`).
pub fn modes_text(chain: &Chain, si: bool) -> anyhow::Result<Vec<String>> {
    let (w, f) = if si {
        ("rad/s", "Hz")
    } else {
        ("rad/time", "1/time")
    };
    Ok(natural_modes(chain)?
        .iter()
        .enumerate()
        .map(|(j, m)| {
            let z = m
                .zeta
                .map_or("rigid-body mode".to_string(), |z| format!("zeta = {z:.6e}"));
            format!(
                "# mode {}: omega = {:.10e} {w}, f = {:.10e} {f}, {z}",
                j + 1,
                m.omega,
                m.frequency
            )
        })
        .collect())
}

/// The observable of mass `observe` at `s` (impulse response, or the
/// transfer function of a unit force with `force`), real arithmetic on the
/// real axis.
fn eval(
    fwd: &Forward,
    s: Complex64,
    observe: usize,
    kind: Observable,
    force: bool,
) -> springmass::Result<Complex64> {
    Ok(match (s.im == 0.0, force) {
        (true, false) => fwd.observe(s.re, observe, kind)?.into(),
        (false, false) => fwd.observe(s, observe, kind)?,
        (true, true) => fwd.transfer_function(s.re, observe, kind)?.into(),
        (false, true) => fwd.transfer_function(s, observe, kind)?,
    })
}

/// [`eval`], and where it meets a singular value with `gamma != 1`: a pole,
/// or `X = gamma * G` overflowing f64, told apart with `gamma = 1`.
fn eval_explained(
    chain: &Chain,
    fwd: &Forward,
    s: Complex64,
    observe: usize,
    kind: Observable,
    force: bool,
) -> anyhow::Result<Complex64> {
    Ok(match eval(fwd, s, observe, kind, force) {
        Err(springmass::Error::Singular { s: at }) if chain.gamma() != 1.0 => {
            // a pole, or X = gamma * G overflowing f64: decide with gamma = 1
            let unit = chain.clone().with_gamma(1.0)?;
            match eval(&Forward::new(&unit), s, observe, kind, force) {
                Ok(g) => {
                    return Err(springmass::Error::Unresolvable {
                        reason: format!(
                            "X_{}({at}) = gamma * ({} {:+}i) with gamma = {} overflows f64",
                            observe,
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
    })
}

/// The values as JSON: `{"points": [{"s", "x"}, ...]}`, with the observable
/// and excitation when not the default, the ends when not both fixed, and the
/// modes when asked for.
fn print_json(
    chain: &Chain,
    rows: &[(Complex64, Complex64)],
    kind: Observable,
    force: bool,
    modes: Option<&[NaturalMode]>,
) {
    let points: Vec<serde_json::Value> = rows
        .iter()
        .map(|(s, x)| serde_json::json!({"s": [s.re, s.im], "x": [x.re, x.im]}))
        .collect();
    let mut out = serde_json::json!({ "points": points });
    if kind != Observable::Displacement || force {
        out["observe_kind"] = kind.name().into();
        out["excitation"] = if force { "force" } else { "impulse" }.into();
    }
    if !chain.is_fixed_fixed() {
        out["left"] = chain.left().name().into();
        out["right"] = chain.right().name().into();
    }
    if let Some(m) = modes {
        out["modes"] = m
            .iter()
            .map(
                |m| serde_json::json!({"omega": m.omega, "frequency": m.frequency, "zeta": m.zeta}),
            )
            .collect::<Vec<_>>()
            .into();
    }
    println!("{out}");
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let chain = a.setup.apply(a.chain.chain()?)?;
    let kind: Observable = a.observe_kind.parse()?;
    let force = match a.excitation.trim().to_ascii_lowercase().as_str() {
        "impulse" => false,
        "force" => true,
        other => anyhow::bail!("invalid --excitation {other:?}: allowed impulse or force"),
    };
    let fwd = Forward::new(&chain);
    let mut rows = Vec::with_capacity(a.s.len());
    let s_values =
        a.s.iter()
            .map(|t| parse_complex(t))
            .collect::<Result<Vec<_>, _>>()?;
    for s in s_values {
        let x = eval_explained(&chain, &fwd, s, a.observe, kind, force)?;
        rows.push((s, x));
    }
    let modes = if a.modes {
        Some(natural_modes(&chain)?)
    } else {
        None
    };
    if a.json {
        print_json(&chain, &rows, kind, force, modes.as_deref());
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
        if !chain.is_fixed_fixed() {
            println!("# ends: left {}, right {}", chain.left(), chain.right());
        }
        if !chain.damping().is_grounded() {
            println!("# damping: {}", chain.damping());
        }
        if let Some(b) = chain.baseline() {
            println!(
                "# baseline: {} (masses and springs from it; k and mass above are its means)",
                b.source()
            );
        }
        if a.modes {
            for line in modes_text(&chain, a.setup.has_units())? {
                println!("{line}");
            }
        }
        let sym = kind.prefix().to_ascii_uppercase();
        if force {
            println!(
                "# H_{}(s): {} of mass {} per unit force on mass 1",
                a.observe, kind, a.observe
            );
        } else if kind == Observable::Displacement {
            println!("# X_{}(s)", a.observe);
        } else {
            println!("# {sym}_{}(s): {} of mass {}", a.observe, kind, a.observe);
        }
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
