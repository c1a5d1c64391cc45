//! Laplace transform of a sampled series (30001 samples, dt = 0.01 on [0, 300]).
//!
//! Baseline in the same run: a plain trapezoid sum `Σ w_i x_i e^{-s t_i}`
//! (one complex exponential per sample), the cheapest possible O(N) pass.
//! The Filon transform is reported against it as a ratio; it evaluates two
//! rules (degree 7 and 5) and the weight vector for the noise variance.
//!
//! `cpu/eval_with_covariance/*` (CPU time of this thread): the values and
//! the full data covariance at the 80 Bromwich nodes of `Setup::new()` on
//! the record of the `datafit` bench (n = 20 chain, masses 5 at 8 and 2 at
//! 15, `x_1` on `[0, 300]` with `dt = 0.05`, 6001 samples, noise 1% of
//! `max |x_1|`, seed 1), as `laplace_obs` forms them: `periodic` (the
//! uniform-grid sums) against `general` (the weight vectors and `B B^T`) in
//! the same run; also a single `eval` with a noise level.
//!
//! `cargo bench --bench series -- cpu/`

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use springmass::detect::data::series::TimeData;
use springmass::detect::fit::general::Setup;
use springmass::detect::misfit::MisfitKind;
use springmass::noise::NoiseLevel;
use springmass::time::inverse::{invert, InverseOptions};
use springmass::time::series::{SeriesTransform, TransformOptions};
use springmass::{Chain, Complex64, Defect};
use std::time::Duration;

#[path = "common/cputime.rs"]
mod cputime;
use cputime::CpuTime;

fn x1(n: usize, d: f64, t: f64) -> f64 {
    let np1 = (n + 1) as f64;
    (1..=n)
        .map(|k| {
            let th = k as f64 * std::f64::consts::PI / np1;
            let w = (2.0 - 2.0 * th.cos() - 0.25 * d * d).sqrt();
            2.0 / np1 * th.sin().powi(2) * (-0.5 * d * t).exp() * (w * t).sin() / w
        })
        .sum()
}

fn trapezoid(t: &[f64], x: &[f64], s: Complex64) -> Complex64 {
    let h = t[1] - t[0];
    let mut acc = Complex64::new(0.0, 0.0);
    for (i, (&ti, &xi)) in t.iter().zip(x).enumerate() {
        let w = if i == 0 || i == t.len() - 1 { 0.5 } else { 1.0 };
        acc += (-s * ti).exp() * (w * xi);
    }
    acc * h
}

fn bench(c: &mut Criterion) {
    let t: Vec<f64> = (0..=30000).map(|i| i as f64 * 0.01).collect();
    let x: Vec<f64> = t.iter().map(|&t| x1(20, 0.1, t)).collect();
    let opts = TransformOptions::default();
    let tr = SeriesTransform::new(&t, &x, &opts).unwrap();
    let mut g = c.benchmark_group("series_transform_n30001");
    for (name, s) in [
        ("real_s0.5", Complex64::new(0.5, 0.0)),
        ("bromwich_0.05+2i", Complex64::new(0.05, 2.0)),
        ("real_s300", Complex64::new(300.0, 0.0)),
    ] {
        g.bench_function(format!("baseline_trapezoid/{name}"), |b| {
            b.iter(|| trapezoid(black_box(&t), black_box(&x), black_box(s)))
        });
        g.bench_function(format!("filon_deg7_with_estimate/{name}"), |b| {
            b.iter(|| tr.eval(black_box(s)).unwrap())
        });
    }
    g.bench_function("prepare", |b| {
        b.iter(|| SeriesTransform::new(black_box(&t), black_box(&x), &opts).unwrap())
    });
    // non-uniform grid: Lagrange matrices per panel, moments per panel
    let tn: Vec<f64> = (0..=30000)
        .map(|i| {
            let u = i as f64 / 30000.0;
            300.0 * (u + 0.05 * (std::f64::consts::PI * u).sin().powi(2) * (1.0 - u))
        })
        .collect();
    let xn: Vec<f64> = tn.iter().map(|&t| x1(20, 0.1, t)).collect();
    let trn = SeriesTransform::new(&tn, &xn, &opts).unwrap();
    g.bench_function("filon_nonuniform/bromwich_0.05+2i", |b| {
        b.iter(|| trn.eval(black_box(Complex64::new(0.05, 2.0))).unwrap())
    });
    g.finish();

    let f = |s: Complex64| 1.0 / ((s + 0.05) * (s + 0.05) + 1.0);
    c.bench_function("invert_checked_t10", |b| {
        b.iter(|| invert(&f, black_box(10.0), &InverseOptions::default()).unwrap())
    });
}

fn bench_covariance(c: &mut Criterion<CpuTime>) {
    let truth = Chain::paper(20)
        .unwrap()
        .with_defects([
            Defect::Mass { at: 8, m: 5.0 },
            Defect::Mass { at: 15, m: 2.0 },
        ])
        .unwrap();
    let data = TimeData::simulate(&truth, 300.0, 0.05, NoiseLevel::RelativeMax(1e-2), 1).unwrap();
    let setup = Setup::new().unwrap();
    let (s, _) = MisfitKind::Bromwich
        .laplace_nodes(&setup.real_rule, setup.bromwich_sigma, &setup.bromwich_rule)
        .unwrap();
    let opts = TransformOptions {
        noise_sigma: Some(data.sigma()),
        ..TransformOptions::default()
    };
    let tr = SeriesTransform::new(data.t(), data.y(), &opts).unwrap();
    assert!(tr.has_periodic_sums());
    let general = tr.clone().general_path();
    let mut g = c.benchmark_group(format!(
        "cpu/eval_with_covariance/n{}_q{}",
        data.t().len(),
        s.len()
    ));
    g.sample_size(20).measurement_time(Duration::from_secs(3));
    g.bench_function("periodic", |b| {
        b.iter(|| tr.eval_with_covariance(black_box(&s)).unwrap())
    });
    g.bench_function("general", |b| {
        b.iter(|| general.eval_with_covariance(black_box(&s)).unwrap())
    });
    g.finish();
    let mut g = c.benchmark_group(format!("cpu/eval_noisy/n{}", data.t().len()));
    g.sample_size(20).measurement_time(Duration::from_secs(2));
    let z = s[s.len() / 2];
    g.bench_function("periodic", |b| b.iter(|| tr.eval(black_box(z)).unwrap()));
    g.bench_function("general", |b| {
        b.iter(|| general.eval(black_box(z)).unwrap())
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_group! {
    name = benches_cpu;
    config = Criterion::default().with_measurement(CpuTime);
    targets = bench_covariance
}
criterion_main!(benches, benches_cpu);
