//! Many defects in long chains: the greedy search against enumeration and
//! the stochastic optimizers, through the data-first fit
//! (`springmass::detect::fit::fit`).
//!
//! `cargo bench --bench greedy [-- --draws 20 --enumerate 5 --methods greedy,enumerate,ga,nelder-mead,pso
//!  --n 60 --k 3 --long --long-n 10000 --long-draws 3 --threads 1 --verbose
//!  --noisy --noisy-draws 1 --noisy-first 0 --no-fit]`
//!
//! **Short chains** (default `n = 60`, `k = 3`): each draw places `k` mass
//! defects at random positions at least 3 apart, masses log-uniform in
//! `[0.3, 5]` (redrawn within 10% of the uniform mass 1), on the paper's
//! chain (`k = 1`, `d = 0.1`, mass 1, fixed ends); seeded (`ChaCha8`, seed =
//! draw index). Data: exact `X_1` at 80 Gauss-Legendre nodes of the Bromwich
//! line `s = 0.05 + i omega`, `omega in [0, 4]` (10 panels of 8), handed to
//! the fit as Laplace values with a stated error of 1e-12. Every method is
//! told `k`. Success: every position right and every mass within 1e-4
//! (relative). Per method: success rate, median and worst wall time per
//! draw, median misfit evaluations (Levenberg-Marquardt residuals, plus the
//! rank-one candidate evaluations for greedy; the stochastic optimizers'
//! objective calls), and the ratio of the median times against enumeration
//! measured in the same run. Enumeration (`C(60, 3) = 34 220` sets) runs on
//! the first `--enumerate` draws only (default 5; `--enumerate 20` for all).
//!
//! **Long chain** (`--long`): `n = 10^4` (`--long-n`), `k = 3` masses in
//! `[0.3, 5]` at positions at least 3 apart within the first 400 masses
//! (deeper defects leave `X_1` unchanged to rounding at this damping: the
//! identifiability limit, not the search's), `d = 0.01`, exact data at 80
//! nodes of `s = 0.01 + i omega`, `omega in [0, 4]`; greedy only: time per
//! draw, success, and the process's peak resident memory (`VmHWM`). The time
//! is the whole fit, report included: up to `n = 3000` the report's modes of
//! the fitted chain (a dense eigen decomposition, `O(n^3)`) dominate it
//! (`--long-n 3000`: about 40 s, against 1 s at `--long-n 3001`, where the
//! modes are skipped).
//!
//! **Noisy record** (`--noisy`, seconds per draw): the issue's
//! `n = 300`, `k = 4` case. One mass defect in each quarter of the chain
//! (masses log-uniform in `[0.5, 3]`, not within 10% of 1), `d = 0.01`, `x_1`
//! sampled on `0, 0.25, ..., 800` with white noise `1e-3 max|x_1|` (seed =
//! draw index), `sigma` estimated, `k = auto` (`k_max` 4), greedy;
//! `--noisy-draws` (default 1) draws from `--noisy-first` (default 0). Before the fit each defect's visibility is
//! printed: `chi_t`, the root of the chi-square its removal adds to the time
//! record (noise-free difference over `sigma`), and `chi_B`, the same on the
//! fit's Bromwich line (`sigma_B = max(10 / t_end, 0.05)`, 80 nodes up to
//! `omega = 4`, the noise of each node taken as `sigma sqrt(dt / (2 sigma_B))`
//! and the nodes treated as independent, an upper bound), and on the lowest
//! line the record allows, `sigma_B = 10 / t_end`. `--no-fit`: the
//! visibilities only. Per draw: the positions found, the wall time of the
//! whole fit (report included), and `sigma` estimated against the true one;
//! at the end the count of draws with every position right, the median and
//! worst time and the worst `sigma` ratio. The greedy search scores and
//! refits these candidates on the record itself (its time-record stage,
//! `springmass::detect::fit::greedy`), where every defect is visible.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use springmass::detect::data::observations::{LaplaceValues, Observations, Series};
use springmass::detect::data::series::TimeData;
use springmass::detect::fit::{fit, DefectCount, FitMethod, FitOptions, Model, NoiseSpec};
use springmass::detect::misfit::quadrature::Rule;
use springmass::detect::unknowns::KindChoice;
use springmass::noise::NoiseLevel;
use springmass::{Chain, Complex64, Defect};
use std::time::Instant;

/// `k` mass defects, positions in `1..=reach` at least `gap` apart, masses
/// log-uniform in `[lo, hi]` and not within 10% of 1.
fn draw(seed: u64, reach: usize, k: usize, gap: usize, lo: f64, hi: f64) -> Vec<Defect> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    loop {
        let mut p: Vec<usize> = (0..k).map(|_| rng.random_range(1..=reach)).collect();
        p.sort_unstable();
        if p.windows(2).any(|w| w[1] - w[0] < gap) {
            continue;
        }
        return p
            .into_iter()
            .map(|at| loop {
                let m = lo * (hi / lo).powf(rng.random::<f64>());
                if (m - 1.0).abs() >= 0.1 {
                    break Defect::Mass { at, m };
                }
            })
            .collect();
    }
}

fn data(truth: &Chain, sigma_b: f64) -> Observations {
    let rule = Rule::gauss_legendre_uniform(0.0, 4.0, 10, 8).expect("rule");
    let s: Vec<Complex64> = rule
        .nodes
        .iter()
        .map(|&w| Complex64::new(sigma_b, w))
        .collect();
    let fwd = springmass::forward::Forward::new(truth);
    let v = s.iter().map(|z| fwd.eval(*z, 1).expect("X_1")).collect();
    Observations::Laplace(LaplaceValues::new(s, v, None).expect("values"))
}

fn recovered(r: &springmass::detect::fit::FitReport, truth: &[Defect]) -> bool {
    r.defects.len() == truth.len()
        && r.defects
            .iter()
            .zip(truth)
            .all(|(d, t)| d.at == t.at() && ((d.value - t.value()) / t.value()).abs() < 1e-4)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    if v.is_empty() {
        return f64::NAN;
    }
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

fn peak_rss_mb() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1)?.parse::<f64>().ok())
        })
        .map_or(f64::NAN, |kb| kb / 1024.0)
}

struct Row {
    ok: usize,
    runs: usize,
    ms: Vec<f64>,
    evals: Vec<f64>,
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let get = |flag: &str| {
        args.iter()
            .position(|a| a == flag)
            .and_then(|i| args.get(i + 1).cloned())
    };
    let verbose = args.iter().any(|a| a == "--verbose");
    if let Some(t) = get("--threads").and_then(|s| s.parse().ok()) {
        rayon::ThreadPoolBuilder::new()
            .num_threads(t)
            .build_global()
            .expect("thread pool");
    }
    let draws: u64 = get("--draws").and_then(|s| s.parse().ok()).unwrap_or(20);
    let n_enum: u64 = get("--enumerate").and_then(|s| s.parse().ok()).unwrap_or(5);
    let n: usize = get("--n").and_then(|s| s.parse().ok()).unwrap_or(60);
    let k: usize = get("--k").and_then(|s| s.parse().ok()).unwrap_or(3);
    let methods: Vec<FitMethod> = get("--methods")
        .unwrap_or_else(|| "greedy,enumerate".into())
        .split(',')
        .map(|m| FitMethod::parse(m).expect("method"))
        .collect();
    if draws > 0 {
        println!(
            "short chains: n = {n}, k = {k} masses in [0.3, 5], positions >= 3 apart; exact X_1 at 80 Bromwich nodes (sigma_B = 0.05); {draws} draws (enumeration: the first {n_enum}); {} threads",
            rayon::current_num_threads()
        );
    }
    let mut rows: Vec<(FitMethod, Row)> = methods
        .iter()
        .map(|&m| {
            (
                m,
                Row {
                    ok: 0,
                    runs: 0,
                    ms: vec![],
                    evals: vec![],
                },
            )
        })
        .collect();
    let mut paired: Vec<(f64, f64)> = Vec::new();
    for seed in 0..draws {
        let defects = draw(seed, n, k, 3, 0.3, 5.0);
        let truth = Chain::paper(n)
            .expect("chain")
            .with_defects(defects.iter().copied())
            .expect("truth");
        let obs = data(&truth, 0.05);
        let mut times = (f64::NAN, f64::NAN);
        for (m, row) in rows.iter_mut() {
            if *m == FitMethod::Enumerate && seed >= n_enum {
                continue;
            }
            let opts = FitOptions {
                defects: DefectCount::Exactly(k),
                noise: NoiseSpec::Sigma(1e-12),
                method: *m,
                seed,
                kinds: KindChoice::Mass,
                ..FitOptions::default()
            };
            let t0 = Instant::now();
            let r = fit(&obs, &Model::new(n).expect("model"), &opts).expect("fit");
            let ms = t0.elapsed().as_secs_f64() * 1e3;
            let ok = recovered(&r, &defects);
            row.ok += ok as usize;
            row.runs += 1;
            row.ms.push(ms);
            row.evals.push(r.evaluations as f64);
            match m {
                FitMethod::Greedy => times.0 = ms,
                FitMethod::Enumerate => times.1 = ms,
                _ => {}
            }
            if verbose || !ok {
                println!(
                    "  draw {seed:>2} {:<11} {} truth {:?} found {:?} ({:.1} ms, {} evaluations)",
                    m.name(),
                    if ok { "ok  " } else { "MISS" },
                    defects
                        .iter()
                        .map(|d| (d.at(), (d.value() * 1e3).round() / 1e3))
                        .collect::<Vec<_>>(),
                    r.defects
                        .iter()
                        .map(|d| (d.at, (d.value * 1e3).round() / 1e3))
                        .collect::<Vec<_>>(),
                    ms,
                    r.evaluations
                );
            }
        }
        if times.0.is_finite() && times.1.is_finite() {
            paired.push(times);
        }
    }
    if draws > 0 {
        println!(
            "  {:<12} {:>8} {:>12} {:>12} {:>14}",
            "method", "success", "median ms", "worst ms", "median evals"
        );
        for (m, row) in rows.iter().filter(|(_, row)| row.runs > 0) {
            println!(
                "  {:<12} {:>4}/{:<3} {:>12.1} {:>12.1} {:>14.0}",
                m.name(),
                row.ok,
                row.runs,
                median(row.ms.clone()),
                row.ms.iter().copied().fold(0.0, f64::max),
                median(row.evals.clone())
            );
        }
        if !paired.is_empty() {
            let ratio = median(paired.iter().map(|(g, e)| e / g).collect());
            println!(
                "  enumeration / greedy wall time, median over the {} paired draws: {ratio:.0}x",
                paired.len()
            );
        }
    }
    if args.iter().any(|a| a == "--long") {
        let n: usize = get("--long-n")
            .and_then(|s| s.parse().ok())
            .unwrap_or(10_000);
        let long_draws: u64 = get("--long-draws")
            .and_then(|s| s.parse().ok())
            .unwrap_or(3);
        println!(
            "\nlong chain: n = {n}, k = {k} masses in [0.3, 5] within the first 400, d = 0.01; exact X_1 at 80 nodes of s = 0.01 + i omega; {long_draws} draws, greedy"
        );
        for seed in 0..long_draws {
            let defects = draw(1000 + seed, 400, k, 3, 0.3, 5.0);
            let truth = Chain::paper(n)
                .and_then(|c| c.with_d(0.01))
                .and_then(|c| c.with_defects(defects.iter().copied()))
                .expect("truth");
            let obs = data(&truth, 0.01);
            let opts = FitOptions {
                defects: DefectCount::Exactly(k),
                noise: NoiseSpec::Sigma(1e-12),
                method: FitMethod::Greedy,
                kinds: KindChoice::Mass,
                ..FitOptions::default()
            };
            let model = Model::new(n).and_then(|m| m.with_d(0.01)).expect("model");
            let t0 = Instant::now();
            let r = fit(&obs, &model, &opts).expect("fit");
            let s = t0.elapsed().as_secs_f64();
            println!(
                "  draw {seed}: {} truth {:?} found {:?}; {s:.2} s, {} evaluations, peak memory so far {:.0} MB",
                if recovered(&r, &defects) { "ok  " } else { "MISS" },
                defects
                    .iter()
                    .map(|d| (d.at(), (d.value() * 1e3).round() / 1e3))
                    .collect::<Vec<_>>(),
                r.defects
                    .iter()
                    .map(|d| (d.at, (d.value * 1e3).round() / 1e3))
                    .collect::<Vec<_>>(),
                r.evaluations,
                peak_rss_mb()
            );
        }
    }
    if args.iter().any(|a| a == "--noisy") {
        let draws: u64 = get("--noisy-draws")
            .and_then(|s| s.parse().ok())
            .unwrap_or(1);
        let first: u64 = get("--noisy-first")
            .and_then(|s| s.parse().ok())
            .unwrap_or(0);
        noisy(first, draws, verbose, args.iter().any(|a| a == "--no-fit"));
    }
}

/// The noisy record case (module docs).
fn noisy(first: u64, draws: u64, verbose: bool, no_fit: bool) {
    let (n, k, d, t_end, dt, level) = (300, 4, 0.01, 800.0, 0.25, 1e-3);
    println!(
        "\nnoisy record: n = {n}, k = {k} masses in [0.5, 3] (one per quarter), d = {d}; x_1 on [0, {t_end}] every {dt}, noise {level} max|x_1|, sigma estimated, k = auto; {draws} draws, greedy"
    );
    let mut ok = 0;
    let mut secs_all = Vec::new();
    let mut sigma_ratio = 1.0f64;
    for seed in first..first + draws {
        let mut rng = ChaCha8Rng::seed_from_u64(2000 + seed);
        let q = n / k;
        let defects: Vec<Defect> = (0..k)
            .map(|j| {
                let at = rng.random_range(j * q + 1..=(j + 1) * q);
                let m = loop {
                    let m = 0.5 * 6f64.powf(rng.random::<f64>());
                    if (m - 1.0).abs() >= 0.1 {
                        break m;
                    }
                };
                Defect::Mass { at, m }
            })
            .collect();
        let chain_with = |ds: &[Defect]| {
            Chain::paper(n)
                .and_then(|c| c.with_d(d))
                .and_then(|c| c.with_defects(ds.iter().copied()))
                .expect("chain")
        };
        let truth = chain_with(&defects);
        let rec = TimeData::simulate(&truth, t_end, dt, NoiseLevel::RelativeMax(level), seed)
            .expect("record");
        let sigma = rec.sigma();
        // visibility of each defect: what its removal changes, over the noise
        let clean = |c: &Chain| {
            TimeData::simulate(c, t_end, dt, NoiseLevel::Absolute(0.0), 0)
                .expect("clean")
                .y()
                .to_vec()
        };
        let x_true = clean(&truth);
        let rule = Rule::gauss_legendre_uniform(0.0, 4.0, 10, 8).expect("rule");
        // the fit's line, and the lowest the record allows (10 / t_end)
        let lines = [(10.0f64 / t_end).max(0.05), 10.0 / t_end];
        let lap = |c: &Chain, sigma_b: f64| {
            let f = springmass::forward::Forward::new(c);
            rule.nodes
                .iter()
                .map(|&w| f.eval(Complex64::new(sigma_b, w), 1).expect("X_1"))
                .collect::<Vec<_>>()
        };
        let mut vis = Vec::new();
        for j in 0..k {
            let rest: Vec<Defect> = (0..k).filter(|&i| i != j).map(|i| defects[i]).collect();
            let c = chain_with(&rest);
            let chi_t = x_true
                .iter()
                .zip(clean(&c))
                .map(|(a, b)| ((a - b) / sigma).powi(2))
                .sum::<f64>()
                .sqrt();
            let chi_b: Vec<f64> = lines
                .iter()
                .map(|&sigma_b| {
                    let sigma_l = sigma * (dt / (2.0 * sigma_b)).sqrt();
                    lap(&truth, sigma_b)
                        .iter()
                        .zip(lap(&c, sigma_b))
                        .map(|(a, b)| ((a - b).norm() / sigma_l).powi(2))
                        .sum::<f64>()
                        .sqrt()
                })
                .collect();
            vis.push(format!(
                "({}, {:.3}): chi_t {chi_t:.1}, chi_B {:.2e} (sigma_B {}), {:.2e} (sigma_B {})",
                defects[j].at(),
                defects[j].value(),
                chi_b[0],
                lines[0],
                chi_b[1],
                lines[1]
            ));
        }
        println!("  draw {seed}: sigma = {sigma:.2e}; {}", vis.join("; "));
        if no_fit {
            continue;
        }
        let obs = Observations::Series(
            Series::new(rec.t().to_vec(), rec.y().to_vec(), None).expect("series"),
        );
        let opts = FitOptions {
            defects: DefectCount::Auto { k_max: k },
            method: FitMethod::Greedy,
            seed,
            kinds: KindChoice::Mass,
            ..FitOptions::default()
        };
        let model = Model::new(n).and_then(|m| m.with_d(d)).expect("model");
        let t0 = Instant::now();
        let r = fit(&obs, &model, &opts).expect("fit");
        let secs = t0.elapsed().as_secs_f64();
        let right =
            r.defects.len() == k && r.defects.iter().zip(&defects).all(|(e, t)| e.at == t.at());
        ok += right as usize;
        secs_all.push(secs);
        let ratio = r.noise_sigma / sigma;
        if (ratio - 1.0).abs() > (sigma_ratio - 1.0).abs() {
            sigma_ratio = ratio;
        }
        println!(
            "  draw {seed}: {} k = {} found {:?}; {secs:.1} s, {} evaluations, sigma estimated {:.2e} (true {sigma:.2e})",
            if right { "ok  " } else { "MISS" },
            r.k,
            r.defects
                .iter()
                .map(|e| (e.at, (e.value * 1e3).round() / 1e3))
                .collect::<Vec<_>>(),
            r.evaluations,
            r.noise_sigma
        );
        for row in &r.k_selection {
            println!(
                "    k = {}: chi2 {:.4e}, criterion {:.1}, positions {:?}",
                row.k, row.chi2, row.criterion, row.positions
            );
        }
        if verbose {
            println!("{}", r.summary());
        }
    }
    if !no_fit {
        println!(
            "  positions right: {ok}/{draws}; wall time per draw median {:.1} s, worst {:.1} s; sigma estimated / true, farthest from 1: {sigma_ratio:.3}",
            median(secs_all.clone()),
            secs_all.iter().copied().fold(0.0, f64::max)
        );
    }
}
