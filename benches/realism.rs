//! The cost of a real test's deviations (issue 27): the defaults on a
//! record with one deviation against the same fit of the same chain's
//! record without it, as ratios measured in one run.
//!
//! `cargo bench --bench realism -- --warm-up-time 1 --measurement-time 5`
//!
//! Records: the realism study's generator (`springmass::study::realistic`,
//! a dense state space independent of the fit's model), `x_1` on
//! `[0, 200]` at `dt = 0.2`, 1% noise of the clean peak, told what the
//! study tells the fit (n and the uniform chain). One record's cost
//! depends on its noise draw (measured 2026-11-29: System 3's AR(0.9)
//! record of seed 1 took 4.0 times its white twin, the five of seeds 1 to
//! 5 together 2.7 times theirs), so each `S3` benchmark fits the records of
//! seeds 1 to 5 one after the other; `S1-fit-d` fits seed 1's.
//!
//! * `realism/S3/<deviation>`: System 3 (n = 20, masses 5 at 8 and 2
//!   at 15) with the defaults, for `none`, `ar1-0.9`, `ar1-0.99`,
//!   `offset-drift`, `pre-trigger` and `late-clock`;
//! * `realism/S1-fit-d/<deviation>`: System 1 (n = 5, masses 3 at 2 and
//!   0.5 at 4) with the damping unknown (`--fit d`: the damping models
//!   screened, the criterion's kept), for `none` (the paper's grounded
//!   damping), `rayleigh`, `between` and `modal`.
//!
//! The `S3` group runs every fit on this thread (`parallel = false`) and
//! takes this thread's CPU time; the `S1-fit-d` group takes wall time (the
//! damping models may be screened side by side on other threads). After each
//! group, the ratio of each deviation to `none` (mean wall time of 2 fits)
//! is printed.

use criterion::measurement::Measurement;
use criterion::{black_box, criterion_group, criterion_main, Criterion};
use springmass::detect::data::observations::{Observations, Series};
use springmass::detect::fit::options::FitSpec;
use springmass::detect::fit::{fit, FitOptions, Model};
use springmass::study::realistic::{record, Deviations};
use std::time::{Duration, Instant};

#[path = "common/cputime.rs"]
mod cputime;
use cputime::CpuTime;

/// The record of `system` with `deviation`, and the model and options the
/// study's user gives (`fit_d`: the damping unknown).
fn case(
    system: &str,
    deviation: &str,
    fit_d: bool,
    seed: u64,
) -> (Observations, Model, FitOptions) {
    let truth = springmass::scenes::by_name(system).unwrap();
    let dev = Deviations::named(deviation, 1.0).unwrap();
    let (t, x) = record(&truth, &dev, 200.0, 0.2, 1e-2, seed).unwrap();
    let obs = Observations::Series(Series::new(t, x, None).unwrap());
    let spec = FitSpec {
        fit: fit_d.then(|| "d".to_string()),
        d: Some(truth.d()),
        // masses: the records' defects
        kinds: Some("mass".into()),
        ..FitSpec::new(truth.n())
    };
    let (model, mut opts) = spec.build().unwrap();
    opts.parallel = false;
    (obs, model, opts)
}

/// Mean wall time of `runs` fits.
fn mean_s(runs: usize, f: impl Fn()) -> f64 {
    let t = Instant::now();
    for _ in 0..runs {
        f();
    }
    t.elapsed().as_secs_f64() / runs as f64
}

fn group<M: Measurement>(
    c: &mut Criterion<M>,
    name: &str,
    system: &str,
    fit_d: bool,
    deviations: &[&str],
    seeds: &[u64],
) {
    let cases: Vec<_> = deviations
        .iter()
        .map(|d| {
            let records: Vec<_> = seeds.iter().map(|&s| case(system, d, fit_d, s)).collect();
            (*d, records)
        })
        .collect();
    let fit_all = |records: &[(Observations, Model, FitOptions)]| {
        for (obs, model, opts) in records {
            black_box(fit(black_box(obs), model, opts).unwrap());
        }
    };
    let mut g = c.benchmark_group(format!("realism/{name}"));
    g.sample_size(10).measurement_time(Duration::from_secs(5));
    for (dev, records) in &cases {
        g.bench_function(*dev, |b| b.iter(|| fit_all(records)));
    }
    g.finish();
    let times: Vec<f64> = cases
        .iter()
        .map(|(_, records)| mean_s(2, || fit_all(records)))
        .collect();
    for ((dev, _), t) in cases.iter().zip(&times) {
        println!(
            "{name}/{dev}: {t:.3} s for {} records, {:.2}x the records without a deviation (wall, mean of 2)",
            seeds.len(),
            t / times[0]
        );
    }
}

fn records(c: &mut Criterion<CpuTime>) {
    let deviations = [
        "none",
        "ar1-0.9",
        "ar1-0.99",
        "offset-drift",
        "pre-trigger",
        "late-clock",
    ];
    group(c, "S3", "S3", false, &deviations, &[1, 2, 3, 4, 5]);
}

fn damping(c: &mut Criterion) {
    let deviations = ["none", "rayleigh", "between", "modal"];
    group(c, "S1-fit-d", "S1", true, &deviations, &[1]);
}

criterion_group! {
    name = cpu;
    config = Criterion::default().with_measurement(CpuTime);
    targets = records
}
criterion_group!(wall, damping);
criterion_main!(cpu, wall);
