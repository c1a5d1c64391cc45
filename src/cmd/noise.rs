//! `springmass noise-study`: success vs noise per misfit, calibration of the
//! standard errors, unknown damping, and the number-of-defects confusion table.

use anyhow::Context;
use clap::{Args as ClapArgs, ValueEnum};
use springmass::detect::fit::general::Setup;
use springmass::detect::fit::select::Criterion;
use springmass::detect::misfit::MisfitKind;
use springmass::detect::noise_study::{
    calibration, confusion, damping_study, kind_cases, kinds_study, selection_truths,
    success_table, systems, StudyConfig,
};
use springmass::plot::{Line, LinePlot};
use springmass::series::write_atomic;
use std::fmt::Write as _;
use std::path::PathBuf;

/// Which part of the study.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Part {
    /// Success rate vs noise level, per system and misfit (table, CSV, SVG).
    Table,
    /// Standard errors over noisy repeats (S3, positions known).
    Calibration,
    /// Damping fitted with the defects (S3, d unknown).
    Damping,
    /// Number of defects chosen for 0..3 true defects (confusion table).
    Selection,
    /// Identifiability report of one time-domain fit (S3, 1% noise).
    Identify,
    /// Spring, damper and any-kind defects at unknown positions, with the
    /// damping fitted alongside (time misfit, 1% noise, `--part-seeds` seeds).
    Kinds,
    /// The data-first fit with its defaults (time misfit, noise estimated)
    /// and k given: positions right, truth within 3 standard errors, wrong
    /// answers flagged (S1-S4, C3a, C3b; `--levels`, default 1e-4,1e-3,1e-2).
    DataFirst,
    /// The same with the number of defects chosen by BIC (0..=4) on the
    /// selection truths (0 to 3 defects, n = 10).
    DataFirstK,
    /// All of the above but the data-first parts.
    All,
}

/// Arguments of `springmass noise-study`.
#[derive(ClapArgs, Debug)]
pub struct Args {
    /// What to run.
    #[arg(value_enum, default_value = "all")]
    pub part: Part,
    /// Seeds per (system, level) for the table.
    #[arg(long, default_value_t = 20)]
    pub seeds: usize,
    /// Noise levels (relative to max |x_1|), comma separated [default: 1e-8,1e-7,...,1e-1].
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    pub levels: Vec<f64>,
    /// Systems for the table (S1,S2,S3,S4,C3a,C3b) [default: all].
    #[arg(long, value_delimiter = ',')]
    pub systems: Vec<String>,
    /// Misfits for the table (real,bromwich,time) [default: all].
    #[arg(long, value_delimiter = ',')]
    pub misfits: Vec<String>,
    /// Record length.
    #[arg(long, default_value_t = 200.0)]
    pub t_end: f64,
    /// Sampling step.
    #[arg(long, default_value_t = 0.2)]
    pub dt: f64,
    /// Study seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Repeats for the calibration.
    #[arg(long, default_value_t = 100)]
    pub repeats: usize,
    /// Seeds per truth for the damping and selection studies.
    #[arg(long, default_value_t = 10)]
    pub part_seeds: usize,
    /// Criterion for the number of defects: aic, bic, chi2[:ALPHA].
    #[arg(long, default_value = "bic")]
    pub criterion: String,
    /// Weighting of the Laplace misfits: diagonal or whitened.
    #[arg(long, default_value = "whitened")]
    pub weighting: String,
    /// Output folder for CSV and SVG files.
    #[arg(long, default_value = "noise-study")]
    pub out: PathBuf,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let mut cfg = StudyConfig {
        seeds: a.seeds,
        t_end: a.t_end,
        dt: a.dt,
        seed: a.seed,
        ..StudyConfig::default()
    };
    if !a.levels.is_empty() {
        for l in &a.levels {
            if !(l.is_finite() && *l >= 0.0) {
                anyhow::bail!("invalid --levels value {l}: allowed >= 0 and finite");
            }
        }
        cfg.levels = a.levels.clone();
    }
    let setup = Setup {
        weighting: springmass::detect::data::whiten::Weighting::parse(&a.weighting)?,
        ..Setup::new()?
    };
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let mut md = String::new();
    if matches!(a.part, Part::DataFirst | Part::DataFirstK) {
        return data_first(&a, &cfg);
    }
    if matches!(a.part, Part::Table | Part::All) {
        table(&a, &cfg, &setup, &mut md)?;
    }
    if matches!(a.part, Part::Identify | Part::All) {
        let s3 = &systems()[2];
        let data = springmass::detect::noise_study::noisy_data(&s3.truth, &cfg, 1e-2, a.seed)?;
        let ranked = springmass::detect::fit::general::fit_noisy(
            &s3.truth.uniform(),
            &data,
            2,
            MisfitKind::Time,
            &setup,
        )?;
        let r =
            springmass::detect::fit::general::identify_ranked(&ranked, 1.0, data.sigma(), None)?;
        writeln!(
            md,
            "\n## Identifiability (S3, time misfit, 1% noise, seed {})\n",
            a.seed
        )?;
        writeln!(md, "best chi2 {:.2} on {} samples; runner-up gap {:?}; runner-up indistinguishable at noise {:?} (sigma = {:.3e})\n", r.chi2_best, data.len(), r.runner_up_gap, r.sigma_indistinguishable, r.sigma)?;
        writeln!(
            md,
            "| at | mass | SE | sigmas from 1 | position gap | rival | identifiable | reason |"
        )?;
        writeln!(md, "|---|---|---|---|---|---|---|---|")?;
        for d in &r.defects {
            writeln!(
                md,
                "| {} | {:.4} | {:.4} | {:.1} | {:?} | {:?} | {} | {} |",
                d.at,
                d.value,
                d.std_error,
                d.significance,
                d.position_gap,
                d.nearest_rival,
                d.identifiable,
                d.reason
            )?;
        }
        writeln!(
            md,
            "\nalternatives (positions, chi2 gap): {:?}",
            r.alternatives
        )?;
    }
    if matches!(a.part, Part::Calibration | Part::All) {
        let s3 = &systems()[2];
        let c = calibration(&s3.truth, &cfg, 1e-2, a.repeats)?;
        writeln!(
            md,
            "\n## Calibration of standard errors (S3, positions known, 1% noise, {} repeats)\n",
            c.repeats
        )?;
        writeln!(
            md,
            "| defect | true m | mean SE | SD of estimates | within 2 SE |"
        )?;
        writeln!(md, "|---|---|---|---|---|")?;
        for (i, d) in s3.truth.defects().iter().enumerate() {
            writeln!(
                md,
                "| {} | {} | {:.4} | {:.4} | {:.2} |",
                d.at(),
                d.value(),
                c.mean_se[i],
                c.sd_estimate[i],
                c.within_2se[i]
            )?;
        }
        writeln!(
            md,
            "\noverall within 2 SE: {:.3}; mean reduced chi2 {:.3}",
            c.overall, c.mean_reduced_chi2
        )?;
    }
    if matches!(a.part, Part::Damping | Part::All) {
        let s3 = &systems()[2];
        let fits = damping_study(&s3.truth, &cfg, 1e-2, a.part_seeds, 0.2, &setup)?;
        writeln!(
            md,
            "\n## Unknown damping (S3, true d = 0.1, start d = 0.2, 1% noise)\n"
        )?;
        writeln!(md, "| seed | positions | d | SE | rel. error |")?;
        writeln!(md, "|---|---|---|---|---|")?;
        for f in &fits {
            writeln!(
                md,
                "| {} | {:?} | {:.5} | {:.5} | {:.4} |",
                f.seed, f.positions, f.d, f.se, f.rel_err
            )?;
        }
        let within = fits.iter().filter(|f| f.rel_err <= 0.01).count();
        let mut errs: Vec<f64> = fits.iter().map(|f| f.rel_err).collect();
        errs.sort_by(f64::total_cmp);
        writeln!(
            md,
            "\nd within 1%: {within}/{}; median rel. error {:.4}; max {:.4}",
            fits.len(),
            errs.get(errs.len() / 2).copied().unwrap_or(f64::NAN),
            errs.last().copied().unwrap_or(f64::NAN)
        )?;
    }
    if matches!(a.part, Part::Kinds | Part::All) {
        let rows = kinds_study(&kind_cases(), &cfg, 1e-2, a.part_seeds, &setup)?;
        writeln!(
            md,
            "\n## Spring, damper and any-kind defects at unknown positions (time misfit, 1% noise, {} seeds per case)\n",
            a.part_seeds
        )?;
        writeln!(
            md,
            "| case | kinds and positions exact | values within 3 SE | values within 5% | d within 3 SE |"
        )?;
        writeln!(md, "|---|---|---|---|---|")?;
        for r in &rows {
            writeln!(
                md,
                "| {} | {}/{} | {}/{} | {}/{} | {} |",
                r.case,
                r.found,
                r.runs,
                r.values_within_3se,
                r.runs,
                r.values_within_5pct,
                r.runs,
                r.d_within_3se
                    .map_or("-".to_string(), |d| format!("{d}/{}", r.runs))
            )?;
        }
    }
    if matches!(a.part, Part::Selection | Part::All) {
        let criterion = Criterion::parse(&a.criterion)?;
        let truths = selection_truths();
        let t = confusion(&truths, &cfg, 1e-3, a.part_seeds, criterion, &setup)?;
        writeln!(
            md,
            "\n## Number of defects (n = 10, 0.1% noise, {:?}, {} seeds per row)\n",
            criterion, a.part_seeds
        )?;
        writeln!(md, "| true k \\ chosen | 0 | 1 | 2 | 3 |")?;
        writeln!(md, "|---|---|---|---|---|")?;
        for (k, row) in t.iter().enumerate() {
            writeln!(
                md,
                "| {k} | {} |",
                row.iter()
                    .map(|v| v.to_string())
                    .collect::<Vec<_>>()
                    .join(" | ")
            )?;
        }
        let correct: usize = (0..t.len()).map(|k| t[k][k]).sum();
        let total: usize = t.iter().flatten().sum();
        writeln!(md, "\ncorrect: {correct}/{total}")?;
    }
    print!("{md}");
    write_atomic(&a.out.join("noise-study.md"), md.as_bytes())?;
    Ok(())
}

fn table(a: &Args, cfg: &StudyConfig, setup: &Setup, md: &mut String) -> anyhow::Result<()> {
    let all = systems();
    let chosen: Vec<_> = if a.systems.is_empty() {
        all
    } else {
        let mut v = Vec::new();
        for name in &a.systems {
            let s = all
                .iter()
                .find(|s| s.name.eq_ignore_ascii_case(name))
                .with_context(|| {
                    format!("unknown system {name}: allowed S1, S2, S3, S4, C3a, C3b")
                })?;
            v.push(s.clone());
        }
        v
    };
    let misfits: Vec<MisfitKind> = if a.misfits.is_empty() {
        MisfitKind::ALL.to_vec()
    } else {
        a.misfits
            .iter()
            .map(|m| MisfitKind::parse(m))
            .collect::<springmass::Result<_>>()?
    };
    let start = std::time::Instant::now();
    let cells = success_table(&chosen, cfg, &misfits, setup)?;
    writeln!(
        md,
        "## Success rate vs noise (positions exact and masses within {:.0}%; {} seeds; t_end = {}, dt = {}; {:.0} s)\n",
        cfg.mass_tol * 100.0,
        cfg.seeds,
        cfg.t_end,
        cfg.dt,
        start.elapsed().as_secs_f64()
    )?;
    write!(md, "| system | misfit |")?;
    for l in &cfg.levels {
        write!(md, " {l:.0e} |")?;
    }
    writeln!(md)?;
    writeln!(md, "|---|---|{}", "---|".repeat(cfg.levels.len()))?;
    let mut csv = String::from("system,misfit,level,runs,successes,positions_ok\n");
    let mut plot = LinePlot::new(
        "Defect recovery vs noise, one panel per system",
        "noise level (relative to max |x_1|)",
        "success rate",
    )
    .log_x(true)
    .rate();
    for s in &chosen {
        for m in &misfits {
            write!(md, "| {} | {} |", s.name, m.name())?;
            let mut pts = Vec::new();
            for c in cells
                .iter()
                .filter(|c| c.system == s.name && c.misfit == m.name())
            {
                write!(md, " {:.2} |", c.rate())?;
                writeln!(
                    csv,
                    "{},{},{:e},{},{},{}",
                    c.system, c.misfit, c.level, c.runs, c.successes, c.positions_ok
                )?;
                pts.push((c.level, c.rate()));
            }
            writeln!(md)?;
            plot = plot.line(Line::new(m.name(), pts).panel(s.name.clone()));
        }
    }
    write_atomic(&a.out.join("success.csv"), csv.as_bytes())?;
    plot.write_svg(a.out.join("success.svg"))?;
    Ok(())
}

/// `noise-study data-first` and `data-first-k`.
fn data_first(a: &Args, cfg: &StudyConfig) -> anyhow::Result<()> {
    use springmass::detect::noise_study::{data_first, System};
    let mut cfg = cfg.clone();
    if a.levels.is_empty() {
        cfg.levels = vec![1e-4, 1e-3, 1e-2];
    }
    let k_given = a.part == Part::DataFirst;
    let systems: Vec<System> = if k_given {
        let all = systems();
        if a.systems.is_empty() {
            all
        } else {
            let mut v = Vec::new();
            for name in &a.systems {
                v.push(
                    all.iter()
                        .find(|s| &s.name == name)
                        .cloned()
                        .ok_or_else(|| {
                            springmass::Error::invalid(
                                "systems",
                                name,
                                "S1, S2, S3, S4, C3a or C3b",
                            )
                        })?,
                );
            }
            v
        }
    } else {
        selection_truths()
            .into_iter()
            .enumerate()
            .map(|(i, truth)| System {
                name: format!("k{i}"),
                truth,
            })
            .collect()
    };
    let rows = data_first(&systems, &cfg, k_given)?;
    let mut csv = String::from("system,level,repeat,k_true,k_found,positions_ok,values,within_3se,wrong_flagged,sigma_ratio,status,seconds\n");
    for r in &rows {
        let _ = writeln!(
            csv,
            "{},{:e},{},{},{},{},{},{},{},{:.4},{},{:.3}",
            r.system,
            r.level,
            r.repeat,
            r.k_true,
            r.k_found,
            r.positions_ok,
            r.values,
            r.within_3se,
            r.wrong_flagged,
            r.sigma_ratio,
            r.status,
            r.seconds
        );
    }
    let name = if k_given {
        "data-first.csv"
    } else {
        "data-first-k.csv"
    };
    write_atomic(&a.out.join(name), csv.as_bytes())?;
    println!("| system | level | positions right | k right | truth within 3 SE | wrong flagged | median sigma ratio | mean s |");
    println!("|---|---|---|---|---|---|---|---|");
    for s in &systems {
        for &level in &cfg.levels {
            let cell: Vec<_> = rows
                .iter()
                .filter(|r| r.system == s.name && r.level == level)
                .collect();
            let pos = cell.iter().filter(|r| r.positions_ok).count();
            let k_ok = cell.iter().filter(|r| r.k_found == r.k_true).count();
            let vals: usize = cell.iter().map(|r| r.values).sum();
            let within: usize = cell.iter().map(|r| r.within_3se).sum();
            let wrong = cell.iter().filter(|r| r.wrong_flagged).count();
            let mut ratios: Vec<f64> = cell.iter().map(|r| r.sigma_ratio).collect();
            ratios.sort_by(f64::total_cmp);
            let med = ratios.get(ratios.len() / 2).copied().unwrap_or(f64::NAN);
            let secs: f64 = cell.iter().map(|r| r.seconds).sum::<f64>() / cell.len().max(1) as f64;
            println!(
                "| {} | {:e} | {}/{} | {}/{} | {}/{} | {} | {:.3} | {:.2} |",
                s.name,
                level,
                pos,
                cell.len(),
                k_ok,
                cell.len(),
                within,
                vals,
                wrong,
                med,
                secs
            );
        }
    }
    println!("(rows in {})", a.out.join(name).display());
    Ok(())
}
