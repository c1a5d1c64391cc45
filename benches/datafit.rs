//! CPU time of the data-first fit of a noisy record (issue 13): the whole
//! `fit()` and, in the same run, the time-misfit pipeline it runs per `k`
//! on the new path against the earlier one (`Setup::reference`: no screen,
//! time-domain Jacobians by central differences).
//!
//! `cargo bench --bench datafit -- --warm-up-time 1 --measurement-time 5`
//!
//! Records: `x_1` on `[0, 300]`, `dt = 0.05` (6001 samples), noise 1% of
//! `max |x_1|`, seed 1, of
//!
//! * `n20k2`: n = 20, masses 5 at 8 and 2 at 15 (System 3);
//! * `n37k2`: n = 37, masses 3 at 10 and 2 at 25;
//! * `n37k3`: n = 37, masses 3 at 7, 0.5 at 19 and 2 at 30.
//!
//! Benchmarks (this thread's CPU time, `CLOCK_THREAD_CPUTIME_ID`, so
//! everything runs on one thread: `parallel = false`):
//!
//! * `cpu/fit/<case>`: `fit()` with `k` given, sigma unknown, default misfit
//!   (time, shortlist from the Bromwich line);
//! * `cpu/pipeline/<case>/new` and `.../reference`: `fit_noisy_general` with
//!   the time misfit at the record's true sigma, `Setup::new()` against
//!   `Setup::reference()` (the ratio of the two is the speed-up).

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use springmass::detect::data::observations::{Observations, Series};
use springmass::detect::data::series::TimeData;
use springmass::detect::fit::general::{fit_noisy_general, GeneralOptions, Setup};
use springmass::detect::fit::{fit, DefectCount, FitOptions, Model};
use springmass::detect::misfit::MisfitKind;
use springmass::detect::unknowns::{KindChoice, Unknowns};
use springmass::noise::NoiseLevel;
use springmass::{Chain, Defect};
use std::time::Duration;

#[path = "common/cputime.rs"]
mod cputime;
use cputime::CpuTime;

fn case(n: usize, defects: &[(usize, f64)]) -> (Chain, TimeData) {
    let truth = Chain::paper(n)
        .unwrap()
        .with_defects(defects.iter().map(|&(at, m)| Defect::Mass { at, m }))
        .unwrap();
    let data = TimeData::simulate(&truth, 300.0, 0.05, NoiseLevel::RelativeMax(1e-2), 1).unwrap();
    (truth, data)
}

fn bench_cpu(c: &mut Criterion<CpuTime>) {
    let cases = [
        ("n20k2", case(20, &[(8, 5.0), (15, 2.0)])),
        ("n37k2", case(37, &[(10, 3.0), (25, 2.0)])),
        ("n37k3", case(37, &[(7, 3.0), (19, 0.5), (30, 2.0)])),
    ];
    let gopts = GeneralOptions {
        parallel: false,
        ..GeneralOptions::default()
    };
    for (name, (truth, data)) in &cases {
        let k = truth.defects().len();
        let n = truth.n();
        let obs =
            Observations::Series(Series::new(data.t().to_vec(), data.y().to_vec(), None).unwrap());
        let model = Model::new(n).unwrap();
        let opts = FitOptions {
            defects: DefectCount::Exactly(k),
            // masses: the records' defects
            kinds: KindChoice::Mass,
            parallel: false,
            ..FitOptions::default()
        };
        let r = fit(&obs, &model, &opts).unwrap();
        assert_eq!(r.defects.len(), k);
        let mut g = c.benchmark_group(format!("cpu/fit/{name}"));
        g.sample_size(10).measurement_time(Duration::from_secs(5));
        g.bench_function("new", |b| {
            b.iter(|| fit(black_box(&obs), &model, &opts).unwrap())
        });
        g.finish();
        let unknowns = Unknowns::free(n, &vec![KindChoice::Mass; k], &[]).unwrap();
        let base = truth.uniform();
        let mut g = c.benchmark_group(format!("cpu/pipeline/{name}"));
        g.sample_size(10).measurement_time(Duration::from_secs(5));
        for (label, setup) in [
            ("new", Setup::new().unwrap()),
            ("reference", Setup::reference().unwrap()),
        ] {
            g.bench_function(label, |b| {
                b.iter(|| {
                    fit_noisy_general(
                        &base,
                        black_box(data),
                        &unknowns,
                        MisfitKind::Time,
                        &setup,
                        &gopts,
                    )
                    .unwrap()
                })
            });
        }
        g.finish();
    }
}

criterion_group! {
    name = benches_cpu;
    config = Criterion::default().with_measurement(CpuTime);
    targets = bench_cpu
}
criterion_main!(benches_cpu);
