//! What the intervals and the probabilities over hypotheses cost: the fit
//! with them (the default) against the same fit without
//! (`FitOptions::uncertainty = false`, `--no-uncertainty`), as a ratio
//! measured in one run (issue: they should add at most 50%).
//!
//! `cargo bench --bench uncertainty -- --warm-up-time 1 --measurement-time 5`
//!
//! Records: `x_1` on `[0, 300]`, `dt = 0.05` (6001 samples), noise 1% of
//! `max |x_1|`, seed 1, of Table 1 System 1 (n = 5) and System 3 (n = 20),
//! fitted with k given (2) and with the defaults (k chosen by BIC).
//!
//! Benchmarks (this thread's CPU time, `parallel = false`):
//! `cpu/uncertainty/<case>/<k>/without` and `.../with`; the ratio
//! `with / without` of each is printed after its group.

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use springmass::detect::data::observations::{Observations, Series};
use springmass::detect::data::series::TimeData;
use springmass::detect::fit::{fit, DefectCount, FitOptions, Model};
use springmass::detect::unknowns::KindChoice;
use springmass::noise::NoiseLevel;
use springmass::{Chain, Defect};
use std::time::{Duration, Instant};

#[path = "common/cputime.rs"]
mod cputime;
use cputime::CpuTime;

fn record(n: usize, defects: &[(usize, f64)]) -> Observations {
    let truth = Chain::paper(n)
        .unwrap()
        .with_defects(defects.iter().map(|&(at, m)| Defect::Mass { at, m }))
        .unwrap();
    let d = TimeData::simulate(&truth, 300.0, 0.05, NoiseLevel::RelativeMax(1e-2), 1).unwrap();
    Observations::Series(Series::new(d.t().to_vec(), d.y().to_vec(), None).unwrap())
}

/// Mean wall time of `runs` fits (the ratio line beside criterion's).
fn mean_s(runs: usize, f: impl Fn()) -> f64 {
    let t = Instant::now();
    for _ in 0..runs {
        f();
    }
    t.elapsed().as_secs_f64() / runs as f64
}

fn bench_uncertainty(c: &mut Criterion<CpuTime>) {
    let cases = [
        ("s1", 5, record(5, &[(2, 3.0), (4, 0.5)])),
        ("s3", 20, record(20, &[(8, 5.0), (15, 2.0)])),
    ];
    for (name, n, obs) in &cases {
        let model = Model::new(*n).unwrap();
        for (k, defects) in [
            ("given", DefectCount::Exactly(2)),
            ("auto", FitOptions::default().defects),
        ] {
            let with = FitOptions {
                defects,
                // masses: the records' defects
                kinds: KindChoice::Mass,
                parallel: false,
                ..FitOptions::default()
            };
            let without = FitOptions {
                uncertainty: false,
                ..with.clone()
            };
            let r = fit(obs, &model, &with).unwrap();
            assert!(r.posterior.is_some(), "{name}: a posterior");
            let mut grp = c.benchmark_group(format!("cpu/uncertainty/{name}/{k}"));
            grp.sample_size(10).measurement_time(Duration::from_secs(5));
            grp.bench_function("without", |b| {
                b.iter(|| fit(black_box(obs), &model, &without).unwrap())
            });
            grp.bench_function("with", |b| {
                b.iter(|| fit(black_box(obs), &model, &with).unwrap())
            });
            grp.finish();
            let t0 = mean_s(3, || {
                fit(obs, &model, &without).unwrap();
            });
            let t1 = mean_s(3, || {
                fit(obs, &model, &with).unwrap();
            });
            println!(
                "{name}/{k}: with {:.3} s, without {:.3} s, ratio {:.2}x (wall, one thread, mean of 3)",
                t1,
                t0,
                t1 / t0
            );
        }
    }
}

criterion_group! {
    name = benches_uncertainty;
    config = Criterion::default().with_measurement(CpuTime);
    targets = bench_uncertainty
}
criterion_main!(benches_uncertainty);
