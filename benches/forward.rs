//! Time per s of the forward model: X_1 by Woodbury (0, 1, 2, 5 defects) and by
//! the transfer sweep, at n = 20 and n = 10^6, against the O(n) solver at
//! n = 20 and 1000. Report ratios against the uniform-chain baseline measured
//! in the same run (the machine is shared).
//!
//! Group `ends_per_s`: the same Woodbury and transfer evaluations (2 defects,
//! n = 20 and 10^6) for each pair of ends, and the acceleration of mass 1
//! ([`Forward::observe`]); compare each with the fixed-fixed case of the same
//! run.

use criterion::{black_box, criterion_group, criterion_main, BenchmarkId, Criterion};
use springmass::chain::Boundary::{self, Fixed, Free};
use springmass::forward::{tridiag, woodbury, Forward, Observable};
use springmass::{Chain, Defect};

fn chain_with(n: usize, k: usize) -> Chain {
    let all = [
        Defect::Mass {
            at: 8.min(n),
            m: 5.0,
        },
        Defect::Mass {
            at: 15.min(n - 1),
            m: 2.0,
        },
        Defect::Spring { at: 3, k: 0.5 },
        Defect::Damper { at: 4, d: 0.3 },
        Defect::Mass { at: n, m: 7.0 },
    ];
    Chain::paper(n)
        .unwrap()
        .with_defects(all.into_iter().take(k))
        .unwrap()
}

const S: [f64; 8] = [0.01, 0.1, 0.5, 1.0, 2.0, 5.0, 30.0, 300.0];

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("x1_per_s");
    for &n in &[20usize, 1_000_000] {
        for &k in &[0usize, 1, 2, 5] {
            let chain = chain_with(n, k);
            let fwd = Forward::new(&chain);
            let ups = fwd.updates().to_vec();
            g.bench_with_input(
                BenchmarkId::new(format!("woodbury/n={n}"), k),
                &k,
                |b, _| {
                    b.iter(|| {
                        let mut acc = 0.0;
                        for &s in &S {
                            let gr = fwd.green(s);
                            acc += woodbury(&gr, &s, &ups, 1.0, 1);
                        }
                        black_box(acc)
                    })
                },
            );
            g.bench_with_input(
                BenchmarkId::new(format!("transfer/n={n}"), k),
                &k,
                |b, _| {
                    b.iter(|| {
                        let mut acc = 0.0;
                        for &s in &S {
                            acc += fwd.eval(s, 1).unwrap();
                        }
                        black_box(acc)
                    })
                },
            );
        }
    }
    for &n in &[20usize, 1000] {
        let chain = chain_with(n, 2);
        g.bench_with_input(BenchmarkId::new("tridiag", n), &n, |b, _| {
            b.iter(|| {
                let mut acc = 0.0;
                for &s in &S {
                    acc += tridiag::solve(&chain, s, 1).unwrap();
                }
                black_box(acc)
            })
        });
    }
    g.finish();
}

fn bench_ends(c: &mut Criterion) {
    let ends: [(Boundary, Boundary); 4] =
        [(Fixed, Fixed), (Free, Fixed), (Fixed, Free), (Free, Free)];
    let mut g = c.benchmark_group("ends_per_s");
    for &n in &[20usize, 1_000_000] {
        for (l, r) in ends {
            let chain = chain_with(n, 2).with_boundaries(l, r).unwrap();
            let fwd = Forward::new(&chain);
            let ups = fwd.updates().to_vec();
            let name = format!("{}-{}", l.name(), r.name());
            g.bench_with_input(
                BenchmarkId::new(format!("woodbury/n={n}"), &name),
                &n,
                |b, _| {
                    b.iter(|| {
                        let mut acc = 0.0;
                        for &s in &S {
                            let gr = fwd.green(s);
                            acc += woodbury(&gr, &s, &ups, 1.0, 1);
                        }
                        black_box(acc)
                    })
                },
            );
            g.bench_with_input(
                BenchmarkId::new(format!("transfer/n={n}"), &name),
                &n,
                |b, _| {
                    b.iter(|| {
                        let mut acc = 0.0;
                        for &s in &S {
                            acc += fwd.eval(s, 1).unwrap();
                        }
                        black_box(acc)
                    })
                },
            );
            g.bench_with_input(
                BenchmarkId::new(format!("acceleration/n={n}"), &name),
                &n,
                |b, _| {
                    b.iter(|| {
                        let mut acc = 0.0;
                        for &s in &S {
                            acc += fwd.observe(s, 1, Observable::Acceleration).unwrap();
                        }
                        black_box(acc)
                    })
                },
            );
        }
    }
    g.finish();
}

criterion_group!(benches, bench, bench_ends);
criterion_main!(benches);
