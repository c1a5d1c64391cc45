//! CPU time of the whole-profile inversion (issue 14,
//! `springmass::detect::fit::profile`), with the defect fit of the same
//! record (`fit()`, k given) measured in the same run as the baseline.
//!
//! `cargo bench --bench profile -- --warm-up-time 1 --measurement-time 5`
//!
//! * `cpu/n30/profile`: every mass of a 30-mass chain (masses 1.5 at 4,
//!   0.7 at 9, 1.3 at 20; d = 0.1) from `x_1` on `[0, 300]`, `dt = 0.2`,
//!   noise 1e-3 of `max |x_1|`, sigma unknown; `cpu/n30/defects-k3`: the
//!   defect fit of the same record told `k = 3`;
//! * `cpu/frame6/profile`: every storey stiffness of a six-storey shear
//!   frame seen from its free roof by an accelerometer (the test scene of
//!   `tests/long_chains.rs`), 1% noise, sigma unknown;
//! * `cpu/n100/profile`: every mass of a 100-mass chain (all different,
//!   0.75 to 1.3, d = 0.1) from 300 Laplace values with 1e-3 errors.
//!
//! Before timing, each case's answer is checked (the masses or stiffnesses
//! within 5 standard errors where visible), so a bench that runs measures a
//! fit that works.

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use springmass::chain::Boundary;
use springmass::detect::data::measurement::Sensor;
use springmass::detect::data::observations::{LaplaceValues, Observations, Series};
use springmass::detect::data::series::TimeData;
use springmass::detect::fit::fit_profile;
use springmass::detect::fit::profile::{ProfileMode, ProfileOptions, ProfileReport};
use springmass::detect::fit::{fit, DefectCount, FitOptions, Model};
use springmass::detect::unknowns::KindChoice;
use springmass::forward::Observable;
use springmass::noise::{add_noise, NoiseLevel};
use springmass::{scenes, Chain, Complex64, Defect};
use std::time::Duration;

#[path = "common/cputime.rs"]
mod cputime;
use cputime::CpuTime;

fn series(rec: &TimeData) -> Observations {
    Observations::Series(
        Series::new(rec.t().to_vec(), rec.y().to_vec(), None)
            .unwrap()
            .with_measurement(rec.measurement().clone())
            .unwrap(),
    )
}

fn check(r: &ProfileReport, truth: &dyn Fn(usize) -> f64) {
    for e in r.elements.iter().filter(|e| e.visible) {
        let want = truth(e.at);
        assert!(
            (e.value - want).abs() < 5.0 * e.se,
            "{} {}: {} +- {} vs {want}",
            e.kind,
            e.at,
            e.value,
            e.se
        );
    }
}

fn bench_cpu(c: &mut Criterion<CpuTime>) {
    // n = 30 record: the profile against the defect fit
    let defects = [(4, 1.5), (9, 0.7), (20, 1.3)];
    let truth = Chain::paper(30)
        .unwrap()
        .with_defects(defects.iter().map(|&(at, m)| Defect::Mass { at, m }))
        .unwrap();
    let rec = TimeData::simulate(&truth, 300.0, 0.2, NoiseLevel::RelativeMax(1e-3), 5).unwrap();
    let obs = series(&rec);
    let model = Model::new(30).unwrap();
    let popts = ProfileOptions::new(ProfileMode::Masses);
    let mass = |at: usize| defects.iter().find(|d| d.0 == at).map_or(1.0, |d| d.1);
    check(&fit_profile(&obs, &model, &popts).unwrap(), &mass);
    let fopts = FitOptions {
        defects: DefectCount::Exactly(3),
        kinds: KindChoice::Mass,
        parallel: false,
        ..FitOptions::default()
    };
    let mut g = c.benchmark_group("cpu/n30");
    g.sample_size(10).measurement_time(Duration::from_secs(5));
    g.bench_function("profile", |b| {
        b.iter(|| fit_profile(black_box(&obs), &model, &popts).unwrap())
    });
    g.bench_function("defects-k3", |b| {
        b.iter(|| fit(black_box(&obs), &model, &fopts).unwrap())
    });
    g.finish();

    // six-storey frame, springs from the roof accelerometer
    let change = scenes::FRAME6_CHANGE;
    let frame = scenes::frame6().unwrap();
    let sensor = Sensor {
        at: 1,
        kind: Observable::Acceleration,
    };
    let rec = TimeData::simulate_measured(
        &frame,
        200.0,
        0.1,
        sensor,
        None,
        NoiseLevel::RelativeMax(1e-2),
        1,
    )
    .unwrap();
    let obs = series(&rec);
    let model = Model::new(6)
        .unwrap()
        .with_d(0.02)
        .unwrap()
        .with_ends(Boundary::Free, Boundary::Fixed)
        .unwrap();
    let sopts = ProfileOptions::new(ProfileMode::Springs);
    check(&fit_profile(&obs, &model, &sopts).unwrap(), &|j| {
        1.0 + change[j - 1]
    });
    let mut g = c.benchmark_group("cpu/frame6");
    g.sample_size(10).measurement_time(Duration::from_secs(5));
    g.bench_function("profile", |b| {
        b.iter(|| fit_profile(black_box(&obs), &model, &sopts).unwrap())
    });
    g.finish();

    // n = 100 masses from noisy Laplace values
    let m = scenes::mass_profile(100);
    let long = scenes::profile_chain(100, 0.1).unwrap();
    let s: Vec<Complex64> = (0..300)
        .map(|i| Complex64::new(0.02, 3.0 * (i as f64 + 0.5) / 300.0))
        .collect();
    let x: Vec<Complex64> = s
        .iter()
        .map(|z| springmass::forward::response(&long, *z, 1).unwrap())
        .collect();
    let sigma = 1e-3 * x.iter().fold(0.0f64, |a, v| a.max(v.norm()));
    let flat: Vec<f64> = x.iter().flat_map(|v| [v.re, v.im]).collect();
    let (y, _) = add_noise(&flat, NoiseLevel::Absolute(sigma), 0).unwrap();
    let noisy: Vec<Complex64> = y.chunks(2).map(|c| Complex64::new(c[0], c[1])).collect();
    let obs = Observations::Laplace(
        LaplaceValues::new(s.clone(), noisy, Some(vec![sigma; s.len()])).unwrap(),
    );
    let model = Model::new(100).unwrap();
    check(&fit_profile(&obs, &model, &popts).unwrap(), &|i| m[i - 1]);
    let mut g = c.benchmark_group("cpu/n100");
    g.sample_size(10).measurement_time(Duration::from_secs(5));
    g.bench_function("profile", |b| {
        b.iter(|| fit_profile(black_box(&obs), &model, &popts).unwrap())
    });
    g.finish();
}

criterion_group! {
    name = benches_cpu;
    config = Criterion::default().with_measurement(CpuTime);
    targets = bench_cpu
}
criterion_main!(benches_cpu);
