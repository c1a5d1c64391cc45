//! Many defects in long chains: the greedy search against enumeration and
//! the stochastic optimizers, through the data-first fit
//! (`springmass::detect::fit::fit`).
//!
//! `cargo bench --bench greedy [-- --draws 20 --enumerate 5 --methods greedy,enumerate,ga,nelder-mead,pso
//!  --n 60 --k 3 --long --long-n 10000 --long-draws 3 --threads 1 --verbose]`
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
//! draw, success, and the process's peak resident memory (`VmHWM`).

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use springmass::detect::data::observations::{LaplaceValues, Observations};
use springmass::detect::fit::{fit, DefectCount, FitMethod, FitOptions, Model, NoiseSpec};
use springmass::detect::misfit::quadrature::Rule;
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
    println!(
        "short chains: n = {n}, k = {k} masses in [0.3, 5], positions >= 3 apart; exact X_1 at 80 Bromwich nodes (sigma_B = 0.05); {draws} draws (enumeration: the first {n_enum}); {} threads",
        rayon::current_num_threads()
    );
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
}
