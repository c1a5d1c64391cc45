//! Simulator cost: the paper's horizon at n = 20 (t in [0, 300], dt = 0.1) by
//! the three methods, unforced and forced; and a fixed horizon (t in [0, 10],
//! dt = 0.5) with the sparse Rk method at n = 20, 1000 and 10^4. Report ratios
//! against the baseline measured in the same run: one O(n) tridiagonal solve
//! `forward::tridiag::solve_all` at the same n (the machine is shared).

use criterion::{black_box, criterion_group, criterion_main, BenchmarkId, Criterion};
use springmass::forward::tridiag;
use springmass::time::modal::ModalResponse;
use springmass::time::simulate::{simulate, simulate_forced, Forcing, Method, SimOptions};
use springmass::{Chain, Defect};

fn chain(n: usize) -> Chain {
    Chain::paper(n)
        .unwrap()
        .with_defect(Defect::Mass {
            at: 3.min(n),
            m: 5.0,
        })
        .unwrap()
}

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("simulate");
    for &n in &[20usize, 1000, 10_000] {
        let ch = chain(n);
        g.bench_with_input(BenchmarkId::new("baseline_tridiag_solve", n), &n, |b, _| {
            b.iter(|| black_box(tridiag::solve_all(&ch, black_box(0.7_f64)).unwrap()))
        });
        let opts = SimOptions::new(10.0, 0.5).with_method(Method::Rk);
        g.bench_with_input(BenchmarkId::new("rk_t10_dt0.5", n), &n, |b, _| {
            b.iter(|| black_box(simulate(&ch, &opts).unwrap()))
        });
    }
    let ch = chain(20);
    let long = SimOptions::new(300.0, 0.1);
    for m in [Method::Expm, Method::Rk, Method::Modal] {
        let o = long.clone().with_method(m);
        g.bench_function(BenchmarkId::new("n20_t300_dt0.1", m.to_string()), |b| {
            b.iter(|| black_box(simulate(&ch, &o).unwrap()))
        });
    }
    let forcing = Forcing::new().on(20, |t| 0.1 * (0.7 * t).sin());
    for m in [Method::Expm, Method::Rk] {
        let o = long.clone().with_method(m);
        g.bench_function(
            BenchmarkId::new("n20_t300_dt0.1_forced", m.to_string()),
            |b| b.iter(|| black_box(simulate_forced(&ch, &o, &forcing).unwrap())),
        );
    }
    g.bench_function("modal_setup_n20", |b| {
        b.iter(|| black_box(ModalResponse::impulse(&ch, 1).unwrap()))
    });
    g.finish();
    // The time misfit's model: x_1 at 6001 uniform samples (t in [0, 300],
    // dt = 0.05) from the modal sum. Baseline in the same run: the same sum
    // evaluated term by term (exp, sin, cos per sample and term); the
    // uniform-grid recurrence of `eval_many` is the tested path.
    let mut g = c.benchmark_group("modal_series");
    let r = ModalResponse::impulse(&ch, 1).unwrap();
    let ts: Vec<f64> = (0..6001).map(|i| i as f64 * 0.05).collect();
    g.bench_function("baseline_term_by_term_n20_6001", |b| {
        b.iter(|| black_box(ts.iter().map(|&t| r.eval(t)).collect::<Vec<f64>>()))
    });
    g.bench_function("eval_many_uniform_n20_6001", |b| {
        b.iter(|| black_box(r.eval_many(black_box(&ts))))
    });
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = bench
}
criterion_main!(benches);
