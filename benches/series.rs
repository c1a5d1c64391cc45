//! Laplace transform of a sampled series (30001 samples, dt = 0.01 on [0, 300]).
//!
//! Baseline in the same run: a plain trapezoid sum `Σ w_i x_i e^{-s t_i}`
//! (one complex exponential per sample), the cheapest possible O(N) pass.
//! The Filon transform is reported against it as a ratio; it evaluates two
//! rules (degree 7 and 5) and the weight vector for the noise variance.

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use springmass::time::inverse::{invert, InverseOptions};
use springmass::time::series::{SeriesTransform, TransformOptions};
use springmass::Complex64;

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

criterion_group!(benches, bench);
criterion_main!(benches);
