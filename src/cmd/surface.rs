//! `springmass surface`: residual surfaces, the paper's Figures 16 and 17.
//!
//! * `--kind jm`: one defect, `r(j, m)` over `j = 1..=n` and `m` on a log grid
//!   (Figure 16);
//! * `--kind pair`: two defects of known masses, `r(j1, j2)` over distinct
//!   positions (Figure 17; the masses come from `--masses` or the scene's true
//!   defects).
//!
//! Writes `<out>.csv` and `<out>.svg` (heatmap of `log10 r`, the minimum marked).

use anyhow::Context;
use clap::{Args as ClapArgs, ValueEnum};
use springmass::detect::misfit::Misfit;
use springmass::detect::scene::FitScene;
use springmass::io::{check_alloc, check_magnitude, check_outputs, write_atomic};
use springmass::plot::Heatmap;
use springmass::{Chain, Error};
use std::path::PathBuf;

/// Which surface.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum Kind {
    /// r over (j, m), one defect (Figure 16).
    Jm,
    /// r over (j1, j2), two defects of known masses (Figure 17).
    Pair,
}

/// Arguments of `springmass surface`.
#[derive(ClapArgs, Debug)]
pub struct Args {
    /// The scene ([chain] with the true defects, [data], [misfit]).
    #[arg(long)]
    pub scene: PathBuf,
    /// jm (Figure 16) or pair (Figure 17).
    #[arg(long, value_enum)]
    pub kind: Kind,
    /// Output prefix: writes PREFIX.csv and PREFIX.svg.
    #[arg(long, default_value = "surface")]
    pub out: PathBuf,
    /// jm: mass range, 1e-300 <= LO < HI <= 1e300 [default: the scene's mass_bounds].
    #[arg(long, num_args = 2, value_names = ["LO", "HI"], allow_hyphen_values = true)]
    pub m_range: Option<Vec<f64>>,
    /// jm: number of masses on the log grid (2..=100000).
    #[arg(long, default_value_t = 60)]
    pub m_steps: usize,
    /// pair: the two known masses, comma separated [default: the scene's true masses].
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub masses: Vec<f64>,
}

/// Largest `--m-steps`.
pub const MAX_M_STEPS: usize = 100_000;

/// Bytes per grid cell: the f64 in the heatmap, a CSV line (about 40 bytes)
/// and its share of the SVG (about 200 bytes per drawn cell).
const BYTES_PER_CELL: f64 = 8.0 + 40.0 + 200.0;

pub fn run(a: Args) -> anyhow::Result<()> {
    springmass::io::check_prefix(&a.out)?;
    let csv_path = a.out.with_extension("csv");
    let svg_path = a.out.with_extension("svg");
    check_outputs([csv_path.as_path(), svg_path.as_path()])?;
    if let Some(v) = &a.m_range {
        check_range(v[0], v[1])?;
    }
    if !(2..=MAX_M_STEPS).contains(&a.m_steps) {
        return Err(Error::invalid("--m-steps", a.m_steps, format!("2..={MAX_M_STEPS}")).into());
    }
    for (i, m) in a.masses.iter().enumerate() {
        check_magnitude(&format!("--masses[{i}]"), *m)?;
    }
    // read with the input cap (FitScene::load reads without one)
    let text = springmass::io::read_to_string_capped(&a.scene)?;
    let scene = FitScene::from_toml(&text).with_context(|| format!("{}", a.scene.display()))?;
    let truth = scene.truth()?;
    let data = scene.data().context("in [data]")?;
    let misfit = Misfit::new(&truth.uniform(), &data, &scene.misfit)?;
    let n = truth.n();
    let mut csv = String::new();
    let heat = match a.kind {
        Kind::Jm => jm_surface(&a, &scene, &misfit, n, &mut csv)?,
        Kind::Pair => pair_surface(&a, &truth, &misfit, &mut csv)?,
    };
    write_atomic(&csv_path, csv.as_bytes())?;
    heat.write_svg(&svg_path)?;
    println!("wrote {} and {}", csv_path.display(), svg_path.display());
    Ok(())
}

/// `r(j, m)` over every position and a log grid of masses (Figure 16): the
/// CSV rows into `csv`, the heatmap returned.
fn jm_surface(
    a: &Args,
    scene: &FitScene,
    misfit: &Misfit,
    n: usize,
    csv: &mut String,
) -> anyhow::Result<Heatmap> {
    let [lo, hi] = match &a.m_range {
        Some(v) => [v[0], v[1]],
        None => scene.unknowns.mass_bounds,
    };
    check_range(lo, hi)?;
    check_alloc(
        &format!("surface --kind jm (n = {n}, {} masses)", a.m_steps),
        BYTES_PER_CELL * n as f64 * a.m_steps as f64,
    )?;
    let ms: Vec<f64> = (0..a.m_steps)
        .map(|i| lo * (hi / lo).powf(i as f64 / (a.m_steps - 1) as f64))
        .collect();
    csv.push_str("j,m,r\n");
    let mut z = vec![vec![0.0; n]; ms.len()];
    let mut best = (f64::INFINITY, 0.0, 0.0);
    for (iy, &m) in ms.iter().enumerate() {
        for j in 1..=n {
            let r = misfit.residual(&[(j, m)]);
            z[iy][j - 1] = r;
            csv.push_str(&format!("{j},{m:.10e},{r:.10e}\n"));
            if r < best.0 {
                best = (r, j as f64, m.log10());
            }
        }
    }
    Ok(Heatmap {
        title: format!(
            "r(j, m), n = {n}: log10 r (min at j = {}, m = {:.4})",
            best.1,
            10f64.powf(best.2)
        ),
        x_label: "j".into(),
        y_label: "log10 m".into(),
        x: (1..=n).map(|j| j as f64).collect(),
        y: ms.iter().map(|m| m.log10()).collect(),
        z,
        log_z: true,
        mark: Some((best.1, best.2)),
    })
}

/// `r(j1, j2)` over distinct positions of two known masses (Figure 17): the
/// CSV rows into `csv`, the heatmap returned.
fn pair_surface(
    a: &Args,
    truth: &Chain,
    misfit: &Misfit,
    csv: &mut String,
) -> anyhow::Result<Heatmap> {
    let n = truth.n();
    let masses: Vec<f64> = if a.masses.is_empty() {
        truth.defects().iter().map(|d| d.value()).collect()
    } else {
        a.masses.clone()
    };
    if masses.len() != 2 || masses.iter().any(|m| !(m.is_finite() && *m > 0.0)) {
        return Err(Error::invalid(
            "--masses",
            format!("{masses:?}"),
            "two masses > 0 (or a scene with two true defects)",
        )
        .into());
    }
    check_alloc(
        &format!("surface --kind pair (n = {n})"),
        BYTES_PER_CELL * n as f64 * n as f64,
    )?;
    csv.push_str("j1,j2,r\n");
    let mut z = vec![vec![f64::NAN; n]; n];
    let mut best = (f64::INFINITY, 0.0, 0.0);
    for j2 in 1..=n {
        for j1 in 1..=n {
            if j1 == j2 {
                continue;
            }
            let r = misfit.residual(&[(j1, masses[0]), (j2, masses[1])]);
            z[j2 - 1][j1 - 1] = r;
            csv.push_str(&format!("{j1},{j2},{r:.10e}\n"));
            if r < best.0 {
                best = (r, j1 as f64, j2 as f64);
            }
        }
    }
    Ok(Heatmap {
        title: format!(
            "r(j1, j2), m1 = {}, m2 = {}: log10 r (min at ({}, {}))",
            masses[0], masses[1], best.1, best.2
        ),
        x_label: "j1".into(),
        y_label: "j2".into(),
        x: (1..=n).map(|j| j as f64).collect(),
        y: (1..=n).map(|j| j as f64).collect(),
        z,
        log_z: true,
        mark: Some((best.1, best.2)),
    })
}

/// A log-grid mass range: 0 < LO < HI, both within 1e-300..=1e300 (beyond,
/// the grid holds subnormal or overflowing masses and the residuals hang).
fn check_range(lo: f64, hi: f64) -> springmass::Result<()> {
    check_magnitude("--m-range LO", lo)?;
    check_magnitude("--m-range HI", hi)?;
    if !(lo > 0.0 && hi > lo) {
        return Err(Error::invalid(
            "--m-range",
            format!("[{lo}, {hi}]"),
            "0 < LO < HI, within 1e-300..=1e300",
        ));
    }
    Ok(())
}
