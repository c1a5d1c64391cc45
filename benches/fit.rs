//! Cost of the residual and time-to-solution of enumeration.
//!
//! `cargo bench --bench fit -- --warm-up-time 1 --measurement-time 3`
//!
//! * `residual_k2_80`: one residual evaluation, k = 2, the default 80-node
//!   rule (10 log-graded panels x 8 Gauss points on [0, 300]), Green's
//!   entries gathered per position set (System 3, positions (8, 15)).
//! * `residual_general_k2_80`: the same through the general-k path (baseline).
//! * `gauss_newton_k2_80`: residual plus analytic Jacobian pieces.
//! * `gather_set_80`: gathering one position set's entries from the table.
//! * `enumerate/system{1..4}`: exhaustive enumeration, single-threaded,
//!   exact data, table built beforehand (setup measured in `setup/system3`).
//!
//! The machine is shared: every benchmark runs twice, under wall time
//! (criterion's default) and under this thread's CPU time
//! (`CLOCK_THREAD_CPUTIME_ID`, group names prefixed `cpu/`), which is far
//! less sensitive to other processes.

use criterion::measurement::Measurement;
use criterion::{black_box, criterion_group, criterion_main, Criterion};
use springmass::detect::data::exact::Data;
use springmass::detect::misfit::{Misfit, MisfitSpec};
use springmass::detect::search::enumerate::{enumerate, EnumerateOptions};
use springmass::detect::unknowns::{DefectUnknown, MassUnknowns};
use springmass::scenes;

#[path = "common/cputime.rs"]
mod cputime;
use cputime::CpuTime;

fn bench_cpu(c: &mut Criterion<CpuTime>) {
    bench_generic(c, "cpu/");
}

fn bench(c: &mut Criterion) {
    bench_generic(c, "");
}

fn bench_generic<M: Measurement + 'static>(c: &mut Criterion<M>, prefix: &str) {
    let chain = scenes::table1(3).unwrap();
    let spec = MisfitSpec::default();
    let mis = Misfit::new(&chain.uniform(), &Data::exact(&chain), &spec).unwrap();
    assert_eq!(mis.nodes(), 80);
    let set = mis.set(&[8, 15]);
    let dm = [3.9, 1.1];
    c.bench_function(&format!("{prefix}residual_k2_80"), |b| {
        b.iter(|| set.residual(black_box(&dm)))
    });
    c.bench_function(&format!("{prefix}residual_general_k2_80"), |b| {
        b.iter(|| set.residual_general(black_box(&dm)))
    });
    let (mut g, mut h) = ([0.0; 2], [0.0; 4]);
    c.bench_function(&format!("{prefix}gauss_newton_k2_80"), |b| {
        b.iter(|| set.gauss_newton(black_box(&dm), &mut g, &mut h))
    });
    c.bench_function(&format!("{prefix}gather_set_80"), |b| {
        b.iter(|| mis.set(black_box(&[8, 15])))
    });
    c.bench_function(&format!("{prefix}setup/system3"), |b| {
        b.iter(|| Misfit::new(&chain.uniform(), &Data::exact(&chain), &spec).unwrap())
    });
    let opts = EnumerateOptions {
        parallel: false,
        ..EnumerateOptions::default()
    };
    let mut group = c.benchmark_group(format!("{prefix}enumerate"));
    for sys in 1..=4 {
        let chain = scenes::table1(sys).unwrap();
        let n = chain.n();
        let defs = scenes::truth(&format!("S{sys}")).unwrap();
        let mis = Misfit::new(&chain.uniform(), &Data::exact(&chain), &spec).unwrap();
        let u = MassUnknowns::new(n, vec![DefectUnknown::free(0.1, 100.0); 2]).unwrap();
        let e = enumerate(&mis, &u, &opts).unwrap();
        assert_eq!(e.ranked[0].defects[0].0, defs[0].0);
        assert_eq!(e.ranked[0].defects[1].0, defs[1].0);
        if prefix.is_empty() {
            eprintln!(
                "system {sys}: {} sets, {} evaluations",
                e.sets, e.evaluations
            );
        }
        group.bench_function(format!("system{sys}"), |b| {
            b.iter(|| enumerate(&mis, &u, &opts).unwrap())
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_group! {
    name = cpu;
    config = Criterion::default().with_measurement(CpuTime);
    targets = bench_cpu
}
criterion_main!(benches, cpu);
