//! `springmass suppress`: the controls of Theorem 3.1 / Corollary 3.2, their
//! verification by simulation, robustness curves, CSV + SVG + summary.json.

use anyhow::Context;
use clap::Args as ClapArgs;
use serde_json::json;
use springmass::control::exact::Modes;
use springmass::control::verify::{
    robustness, Baseline, Input, Perturbation, RobustPoint, Robustness, Run, Target, VerifyOptions,
};
use springmass::control::{Scheme, Signal, Suppression};
use springmass::plot::{Line, LinePlot};
use springmass::series::{write_atomic, TimeSeries};
use std::path::{Path, PathBuf};

/// Arguments of `springmass suppress`.
#[derive(ClapArgs, Debug)]
pub struct Args {
    /// Control position n: f acts on mass n, g on mass n-1; the chain has n+1 masses (n >= 2).
    #[arg(long)]
    pub n: usize,
    /// Spring constant.
    #[arg(long, default_value_t = 1.0, allow_hyphen_values = true)]
    pub k: f64,
    /// Damping per mass.
    #[arg(long, default_value_t = 0.1, allow_hyphen_values = true)]
    pub d: f64,
    /// Mass of every body.
    #[arg(long, default_value_t = 1.0, allow_hyphen_values = true)]
    pub mass: f64,
    /// Impulse on mass 1 (ignored with --disturbance).
    #[arg(long, default_value_t = 1.0, allow_hyphen_values = true)]
    pub gamma: f64,
    /// Only the single control f1 of Corollary 3.2 (default: Theorem 3.1's f and g,
    /// plus f1 for the comparison figure).
    #[arg(long)]
    pub single: bool,
    /// Simulated horizon.
    #[arg(long, default_value_t = 60.0, allow_hyphen_values = true)]
    pub t_end: f64,
    /// Output step of the simulation (a divisor of the disturbance step).
    #[arg(long, default_value_t = 0.01, allow_hyphen_values = true)]
    pub dt: f64,
    /// Disturbance on mass 1 instead of the impulse: CSV `t,u` with uniform t from 0.
    #[arg(long)]
    pub disturbance: Option<PathBuf>,
    /// Delay of the applied controls.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub delay: f64,
    /// Relative gain error of the applied controls (|eps| <= 1).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub gain_error: f64,
    /// Delays of the robustness curves (each within 0..=t_end).
    #[arg(
        long,
        value_delimiter = ',',
        allow_hyphen_values = true,
        default_value = "0,0.001,0.003,0.01,0.03,0.1,0.3,1"
    )]
    pub robust_delays: Vec<f64>,
    /// Gain errors of the robustness curves.
    #[arg(
        long,
        value_delimiter = ',',
        allow_hyphen_values = true,
        default_value = "0,0.0001,0.001,0.01,0.03,0.1,0.3"
    )]
    pub robust_gains: Vec<f64>,
    /// Output folder.
    #[arg(long)]
    pub out_dir: PathBuf,
}

fn pts(t: &[f64], v: &[f64]) -> Vec<(f64, f64)> {
    t.iter().copied().zip(v.iter().copied()).collect()
}

/// A curve of [`plot_xy`]: label, values, dashed.
type Curve<'a> = (&'a str, &'a [f64], bool);

fn plot_xy(
    path: &Path,
    title: &str,
    ylabel: &str,
    t: &[f64],
    lines: &[Curve],
) -> anyhow::Result<()> {
    let mut p = LinePlot::new(title, "t", ylabel);
    for (label, v, dashed) in lines {
        let l = Line::new(*label, pts(t, v));
        p = p.line(if *dashed { l.dashed() } else { l });
    }
    p.write_svg(path)?;
    Ok(())
}

fn robust_plot(
    path: &Path,
    title: &str,
    xlabel: &str,
    curves: &[(&str, &[RobustPoint])],
) -> anyhow::Result<()> {
    let mut p = LinePlot::new(title, xlabel, "relative max")
        .log_x(true)
        .log_y(true);
    for (label, c) in curves {
        p = p.line(
            Line::new(
                format!("x_end/y_end, {label}"),
                c.iter()
                    .map(|r| (r.value, r.rel_x_end_vs_uncontrolled))
                    .collect(),
            )
            .markers(),
        );
        p = p.line(
            Line::new(
                format!("|x1-y1|/y1, {label}"),
                c.iter().map(|r| (r.value, r.rel_x1_minus_y1)).collect(),
            )
            .dashed(),
        );
    }
    p.write_svg(path)?;
    Ok(())
}

fn robust_csv(path: &Path, r: &Robustness) -> anyhow::Result<()> {
    let mut out =
        String::from("kind,target,value,rel_x_end,rel_x_end_vs_uncontrolled,rel_x1_minus_y1\n");
    for (kind, target, c) in [
        ("delay", "all", &r.delay_all),
        ("delay", "first", &r.delay_first),
        ("gain_error", "all", &r.gain_all),
        ("gain_error", "first", &r.gain_first),
    ] {
        for p in c {
            out.push_str(&format!(
                "{kind},{target},{:e},{:e},{:e},{:e}\n",
                p.value, p.rel_x_end, p.rel_x_end_vs_uncontrolled, p.rel_x1_minus_y1
            ));
        }
    }
    write_atomic(path, out.as_bytes())?;
    Ok(())
}

/// Delays within the horizon (a delay beyond `t_end` never acts, and a huge
/// one made the delayed stepping hang), an existing `--out-dir` that is a
/// folder, and the memory of the simulated series: about 12 stored series of
/// `t_end / dt + 1` samples, each run on a chain of n + 1 masses (dense
/// (2n x 2n) matrices when n <= 2000).
fn check_limits(a: &Args) -> anyhow::Result<()> {
    for (field, tau) in std::iter::once(("--delay", a.delay))
        .chain(a.robust_delays.iter().map(|&t| ("--robust-delays", t)))
    {
        if !(tau.is_finite() && (0.0..=a.t_end).contains(&tau)) {
            return Err(springmass::Error::invalid(
                field,
                tau,
                format!("0 <= delay <= t_end = {} (the simulated horizon)", a.t_end),
            )
            .into());
        }
    }
    springmass::io::check_output_dir(&a.out_dir).context("--out-dir")?;
    let samples = a.t_end / a.dt + 1.0;
    let m = a.n as f64 + 1.0;
    let runs = (a.robust_delays.len() + a.robust_gains.len() + 4) as f64;
    let dense = if m <= springmass::time::simulate::MAX_N_EXPM as f64 {
        64.0 * (2.0 * m) * (2.0 * m)
    } else {
        0.0
    };
    let bytes =
        8.0 * 12.0 * samples * runs.min(4.0) + 8.0 * 32.0 * m + dense + 40.0 * samples * 8.0;
    springmass::io::check_alloc(
        &format!("suppress (n = {}, {samples:.0} samples)", a.n),
        bytes,
    )?;
    Ok(())
}

/// The runs `suppress` reports: the exact controls, the perturbed ones (if a
/// delay or gain error was given), the single control f1 alone and
/// Theorem 3.1's f without g (for the cloak's comparison figures).
struct Runs {
    scheme: Scheme,
    exact_main: Run,
    applied_main: Option<Run>,
    single: Option<Run>,
    f_without_g: Option<Run>,
}

impl Runs {
    /// What the series and figures show: the perturbed run if any.
    fn shown(&self) -> &Run {
        self.applied_main.as_ref().unwrap_or(&self.exact_main)
    }
}

/// Parse and check everything before any work: the chain, the perturbations,
/// the input, the horizon, the limits and the output folder.
fn prepare(a: &Args) -> anyhow::Result<(Suppression, Perturbation, Input, VerifyOptions)> {
    let sup = Suppression::new(a.n, a.k, a.d, a.mass, a.gamma)?;
    let perturbation = Perturbation::new(a.delay, a.gain_error, Target::All)?;
    for &tau in &a.robust_delays {
        Perturbation::new(tau, 0.0, Target::All).context("--robust-delays")?;
    }
    for &eps in &a.robust_gains {
        Perturbation::new(0.0, eps, Target::All).context("--robust-gains")?;
    }
    let input = match &a.disturbance {
        None => Input::Impulse,
        Some(p) => {
            let ts = TimeSeries::read_csv(p)
                .with_context(|| format!("reading disturbance {}", p.display()))?;
            Input::from_series(&ts).with_context(|| format!("disturbance {}", p.display()))?
        }
    };
    let opts = VerifyOptions::new(a.t_end, a.dt)?;
    check_limits(a)?;
    Ok((sup, perturbation, input, opts))
}

/// Simulate the main scheme (exact and perturbed) and the comparison runs.
fn simulate_runs(
    a: &Args,
    sup: &Suppression,
    perturbation: &Perturbation,
    input: &Input,
    opts: &VerifyOptions,
) -> anyhow::Result<Runs> {
    let n = sup.n();
    let scheme = if a.single {
        Scheme::Single
    } else {
        Scheme::Cloak
    };
    let base = Baseline::new(sup, input, opts)?;
    let exact_main = springmass::control::verify::verify(sup, scheme, input, opts)?;
    let applied_main = if perturbation.delay == 0.0 && perturbation.gain_error == 0.0 {
        None
    } else {
        Some(base.run(&sup.controls(scheme), perturbation)?)
    };
    // comparison runs for the cloak: f1 alone (Corollary 3.2, Figures 4/7) and
    // Theorem 3.1's f without g (a diagnostic: it does not keep mass n+1 still).
    let single = if a.single {
        None
    } else {
        Some(springmass::control::verify::verify(
            sup,
            Scheme::Single,
            input,
            opts,
        )?)
    };
    let f_without_g = if a.single {
        None
    } else {
        Some(base.run(&[(n, Signal::F)], &Perturbation::NONE)?)
    };
    Ok(Runs {
        scheme,
        exact_main,
        applied_main,
        single,
        f_without_g,
    })
}

/// `timeseries.csv`: input, controls, displacements of the shown run and of f1 alone.
fn write_timeseries(out: &Path, n: usize, runs: &Runs) -> anyhow::Result<()> {
    let shown = runs.shown();
    let mut cols: Vec<(String, Vec<f64>)> = Vec::new();
    if !shown.input.is_empty() {
        cols.push(("u".into(), shown.input.clone()));
    }
    for c in &shown.controls {
        cols.push((format!("{}_on_{}", c.signal.name(), c.at), c.values.clone()));
    }
    cols.push(("y1".into(), shown.y1.clone()));
    cols.push(("x1".into(), shown.x1.clone()));
    cols.push((
        "x1_minus_y1".into(),
        shown.x1.iter().zip(&shown.y1).map(|(x, y)| x - y).collect(),
    ));
    cols.push((format!("x{n}"), shown.x_n.clone()));
    cols.push((format!("x{}", n + 1), shown.x_end.clone()));
    cols.push((format!("y{}", n + 1), shown.y_end.clone()));
    if let Some(s) = &runs.single {
        cols.push(("f1_on_n".into(), s.controls[0].values.clone()));
        cols.push(("x1_f1_alone".into(), s.x1.clone()));
        cols.push((format!("x{}_f1_alone", n + 1), s.x_end.clone()));
    }
    TimeSeries::new(shown.t.clone(), cols)?.write_csv(out.join("timeseries.csv"))?;
    Ok(())
}

/// The paper's Figures 3-8 for the cloak, Figure 9 for the single control;
/// returns the file names written.
fn write_figures(out: &Path, n: usize, runs: &Runs) -> anyhow::Result<Vec<String>> {
    let shown = runs.shown();
    let t = &shown.t;
    let tag = if shown.input.is_empty() {
        "impulse"
    } else {
        "disturbance"
    };
    let mut figures = vec![];
    let mut fig = |name: &str| {
        figures.push(name.to_string());
        out.join(name)
    };
    match runs.scheme {
        Scheme::Cloak => {
            let (f, g) = (&shown.controls[0], &shown.controls[1]);
            let s = runs
                .single
                .as_ref()
                .expect("cloak runs the single control too");
            let x_end = format!("x_{}", n + 1);
            // (file, title, y label, the two curves)
            let plots: [(&str, String, &str, [Curve; 2]); 4] = [
                (
                    "fig_controls.svg",
                    format!("Controls (n = {n}): f on mass {n}, g on mass {}", n - 1),
                    "force",
                    [("f", &f.values, false), ("g", &g.values, false)],
                ),
                (
                    "fig_x1_f_alone.svg",
                    format!("x_1 without controls and with f1 alone (n = {n}, {tag})"),
                    "x_1",
                    [("no control", &shown.y1, false), ("f1 alone", &s.x1, true)],
                ),
                (
                    "fig_x1_cloak.svg",
                    format!("x_1 without controls and with f and g (n = {n}, {tag})"),
                    "x_1",
                    [
                        ("no control", &shown.y1, false),
                        ("f and g", &shown.x1, true),
                    ],
                ),
                (
                    "fig_x_end.svg",
                    format!("x_{} without and with f and g", n + 1),
                    &x_end,
                    [
                        ("no control", &shown.y_end, false),
                        ("f and g", &shown.x_end, false),
                    ],
                ),
            ];
            for (file, title, ylabel, lines) in &plots {
                plot_xy(&fig(file), title, ylabel, t, lines)?;
            }
        }
        Scheme::Single => {
            let f1 = &shown.controls[0];
            plot_xy(
                &fig("fig_single.svg"),
                &format!("Single control f1 on mass {n} (n = {n}, {tag})"),
                "",
                t,
                &[
                    ("f1", &f1.values, false),
                    ("x_1 with f1", &shown.x1, false),
                    ("x_1 no control", &shown.y1, true),
                    (&format!("x_{} with f1", n + 1), &shown.x_end, false),
                    (&format!("x_{} no control", n + 1), &shown.y_end, true),
                ],
            )?;
        }
    }
    Ok(figures)
}

/// The robustness curves: `robustness.csv` and two figures (their names are
/// appended to `figures`).
fn write_robustness(
    a: &Args,
    out: &Path,
    (sup, input, opts): (&Suppression, &Input, &VerifyOptions),
    scheme: Scheme,
    figures: &mut Vec<String>,
) -> anyhow::Result<Robustness> {
    let n = sup.n();
    let rob = robustness(sup, scheme, input, opts, &a.robust_delays, &a.robust_gains)?;
    robust_csv(&out.join("robustness.csv"), &rob)?;
    let plots = [
        (
            "robust_delay.svg",
            "Delayed controls",
            "delay tau",
            [&rob.delay_all, &rob.delay_first],
        ),
        (
            "robust_gain.svg",
            "Gain error",
            "relative gain error eps",
            [&rob.gain_all, &rob.gain_first],
        ),
    ];
    for (file, what, x_label, [all, first]) in plots {
        figures.push(file.into());
        robust_plot(
            &out.join(file),
            &format!(
                "{what} (n = {n}): residual at mass {} and visibility at mass 1",
                n + 1
            ),
            x_label,
            &[("all", all), ("f only", first)],
        )?;
    }
    Ok(rob)
}

/// `summary.json`: the chain, the controls' modes, every run's metrics, the files.
fn write_summary(
    a: &Args,
    sup: &Suppression,
    runs: &Runs,
    rob: &Robustness,
    figures: &[String],
) -> anyhow::Result<()> {
    let poles: Vec<_> = sup
        .controls(runs.scheme)
        .iter()
        .map(|&(at, sig)| {
            let m = Modes::new(sup, sig);
            json!({"signal": sig.name(), "on_mass": at, "modes": m.len(),
                   "slowest_decay_rate": m.slowest_decay()})
        })
        .collect();
    let shown = runs.shown();
    let summary = json!({
        "scheme": match runs.scheme { Scheme::Cloak => "theorem_3_1_cloak", Scheme::Single => "corollary_3_2_single" },
        "chain": {"n": sup.n(), "masses": sup.n() + 1, "k": sup.k(), "d": sup.d(), "mass": sup.mass(), "gamma": sup.gamma()},
        "input": if shown.input.is_empty() { json!("impulse") } else { json!({"disturbance": a.disturbance.as_ref().map(|p| p.display().to_string())}) },
        "t_end": a.t_end, "dt": a.dt,
        "controls": poles,
        "exact_controls": runs.exact_main.metrics,
        "applied_controls": runs.applied_main.as_ref().map(|r| json!({"delay": a.delay, "gain_error": a.gain_error, "metrics": r.metrics})),
        "single_control_f1_alone": runs.single.as_ref().map(|r| r.metrics.clone()),
        "theorem_f_without_g": runs.f_without_g.as_ref().map(|r| r.metrics.clone()),
        "robustness": rob,
        "files": {"timeseries": "timeseries.csv", "robustness": "robustness.csv", "figures": figures},
    });
    write_atomic(
        &a.out_dir.join("summary.json"),
        serde_json::to_string_pretty(&summary)?.as_bytes(),
    )?;
    Ok(())
}

/// The one-line results on stdout.
fn print_results(n: usize, runs: &Runs, out: &Path) {
    let m = &runs.exact_main.metrics;
    println!(
        "n = {n} ({} masses), {}: max|x_{}|/max|y_1| = {:.3e}, max|x_1 - y_1|/max|y_1| = {:.3e}, max|x_{}|/max|y_{}| = {:.3e}",
        n + 1,
        match runs.scheme { Scheme::Cloak => "f and g", Scheme::Single => "f1 alone" },
        n + 1,
        m.rel_x_end,
        m.rel_x1_minus_y1,
        n + 1,
        n + 1,
        m.rel_x_end_vs_uncontrolled
    );
    if let Some(s) = &runs.single {
        println!(
            "f1 alone: max|x_{}|/max|y_1| = {:.3e}, visible at mass 1: max|x_1 - y_1|/max|y_1| = {:.3e}",
            n + 1,
            s.metrics.rel_x_end,
            s.metrics.rel_x1_minus_y1
        );
    }
    println!("wrote {}", out.display());
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let (sup, perturbation, input, opts) = prepare(&a)?;
    let out = &a.out_dir;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let n = sup.n();
    let runs = simulate_runs(&a, &sup, &perturbation, &input, &opts)?;
    write_timeseries(out, n, &runs)?;
    let mut figures = write_figures(out, n, &runs)?;
    let rob = write_robustness(&a, out, (&sup, &input, &opts), runs.scheme, &mut figures)?;
    write_summary(&a, &sup, &runs, &rob, &figures)?;
    print_results(n, &runs, out);
    Ok(())
}
