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

use criterion::measurement::{Measurement, ValueFormatter};
use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};
use springmass::detect::data::Data;
use springmass::detect::misfit::{Misfit, MisfitSpec};
use springmass::detect::search::enumerate::{enumerate, EnumerateOptions};
use springmass::detect::space::{DefectUnknown, Unknowns};
use springmass::{Chain, Defect};

const TABLE1: [(usize, [(usize, f64); 2]); 4] = [
    (5, [(2, 3.0), (4, 0.5)]),
    (10, [(3, 3.0), (7, 2.0)]),
    (20, [(8, 5.0), (15, 2.0)]),
    (20, [(8, 5.0), (15, 15.0)]),
];

fn truth(n: usize, defs: &[(usize, f64)]) -> Chain {
    Chain::paper(n)
        .unwrap()
        .with_defects(defs.iter().map(|&(at, m)| Defect::Mass { at, m }))
        .unwrap()
}

/// Thread CPU time (Linux `clock_gettime(CLOCK_THREAD_CPUTIME_ID)`).
struct CpuTime;

#[repr(C)]
struct Timespec {
    tv_sec: i64,
    tv_nsec: i64,
}

extern "C" {
    fn clock_gettime(clk: i32, tp: *mut Timespec) -> i32;
}

fn thread_cpu_ns() -> u64 {
    let mut t = Timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes one timespec; 3 = CLOCK_THREAD_CPUTIME_ID on Linux.
    let rc = unsafe { clock_gettime(3, &mut t) };
    assert_eq!(rc, 0, "clock_gettime(CLOCK_THREAD_CPUTIME_ID) failed");
    t.tv_sec as u64 * 1_000_000_000 + t.tv_nsec as u64
}

struct NsFormatter;

impl ValueFormatter for NsFormatter {
    fn scale_values(&self, typical: f64, values: &mut [f64]) -> &'static str {
        let (f, unit) = if typical < 1e3 {
            (1.0, "ns")
        } else if typical < 1e6 {
            (1e-3, "us")
        } else if typical < 1e9 {
            (1e-6, "ms")
        } else {
            (1e-9, "s")
        };
        values.iter_mut().for_each(|v| *v *= f);
        unit
    }
    fn scale_throughputs(&self, _: f64, _: &Throughput, values: &mut [f64]) -> &'static str {
        values.iter_mut().for_each(|v| *v = 0.0);
        "n/a"
    }
    fn scale_for_machines(&self, _: &mut [f64]) -> &'static str {
        "ns"
    }
}

impl Measurement for CpuTime {
    type Intermediate = u64;
    type Value = u64;
    fn start(&self) -> u64 {
        thread_cpu_ns()
    }
    fn end(&self, i: u64) -> u64 {
        thread_cpu_ns() - i
    }
    fn add(&self, a: &u64, b: &u64) -> u64 {
        a + b
    }
    fn zero(&self) -> u64 {
        0
    }
    fn to_f64(&self, v: &u64) -> f64 {
        *v as f64
    }
    fn formatter(&self) -> &dyn ValueFormatter {
        &NsFormatter
    }
}

fn bench_cpu(c: &mut Criterion<CpuTime>) {
    bench_generic(c, "cpu/");
}

fn bench(c: &mut Criterion) {
    bench_generic(c, "");
}

fn bench_generic<M: Measurement + 'static>(c: &mut Criterion<M>, prefix: &str) {
    let (n, defs) = TABLE1[2];
    let chain = truth(n, &defs);
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
    for (i, &(n, defs)) in TABLE1.iter().enumerate() {
        let chain = truth(n, &defs);
        let mis = Misfit::new(&chain.uniform(), &Data::exact(&chain), &spec).unwrap();
        let u = Unknowns::new(n, vec![DefectUnknown::free(0.1, 100.0); 2]).unwrap();
        let e = enumerate(&mis, &u, &opts).unwrap();
        assert_eq!(e.ranked[0].defects[0].0, defs[0].0);
        assert_eq!(e.ranked[0].defects[1].0, defs[1].0);
        if prefix.is_empty() {
            eprintln!(
                "system {}: {} sets, {} evaluations",
                i + 1,
                e.sets,
                e.evaluations
            );
        }
        group.bench_function(format!("system{}", i + 1), |b| {
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
