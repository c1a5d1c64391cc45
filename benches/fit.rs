//! Cost of the residual and time-to-solution of enumeration.
//!
//! `cargo bench --bench fit -- --warm-up-time 1 --measurement-time 3`
//!
//! * `residual_k2_80`: one residual evaluation, k = 2, the default 80-node
//!   rule (10 log-graded panels x 8 Gauss points on [0, 300]), Green's
//!   entries gathered per position set (System 3, positions (8, 15)).
//! * `residual_general_k2_80`: the same through the general-k path (baseline).
//! * `floor_k2_80`: the floor the library kernel is measured against, written
//!   here: per node the folded rational form
//!   `X_1 = (N0 + N1 dm1 + N2 dm2 + N12 dm1 dm2) / (1 + D1 dm1 + D2 dm2 + D12 dm1 dm2)`
//!   (`s^2` and `gamma` folded into the 7 coefficients, from the Cramer solution
//!   of the 2 x 2 capacitance system, precomputed once per set), and
//!   `r = sum_q w_q (X_1 - d_q)^2` with 8 independent accumulators.
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
use springmass::detect::misfit::quadrature::GreenTable;
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
    let general = mis.set_general(&[8, 15]);
    let dm = [3.9, 1.1];
    c.bench_function(&format!("{prefix}residual_k2_80"), |b| {
        b.iter(|| set.residual(black_box(&dm)))
    });
    c.bench_function(&format!("{prefix}residual_general_k2_80"), |b| {
        b.iter(|| general.residual(black_box(&dm)))
    });
    let floor = Floor::new(&mis, 8, 15);
    let (rf, rl) = (floor.residual(dm[0], dm[1]), set.residual(&dm));
    assert!((rf - rl).abs() <= 1e-12 * rl, "floor {rf} vs library {rl}");
    c.bench_function(&format!("{prefix}floor_k2_80"), |b| {
        b.iter(|| {
            let dm = black_box(&dm);
            floor.residual(dm[0], dm[1])
        })
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

/// The floor kernel of `residual_k2_80` (module docs): folded coefficients of
/// one pair `(a, b)` (neither the observed mass 1), padded to a multiple of 8
/// nodes with weight 0.
struct Floor {
    /// `[N0, N1, N2, N12, D1, D2, D12, w, d]`, each `np` long.
    c: [Vec<f64>; 9],
}

impl Floor {
    fn new(mis: &Misfit, a: usize, b: usize) -> Floor {
        let chain = mis.chain();
        let nodes = &mis.rule().nodes;
        let g = GreenTable::new(chain, nodes).unwrap();
        let d = mis.data().sample(nodes).unwrap().values;
        let gamma = chain.gamma();
        let np = nodes.len().div_ceil(8) * 8;
        let mut c: [Vec<f64>; 9] = Default::default();
        for v in &mut c {
            v.resize(np, 0.0);
        }
        for (q, &s) in nodes.iter().enumerate() {
            let s2 = s * s;
            let e = |i, j| g.entry(q, i, j);
            let (g11, g1a, g1b) = (e(1, 1), e(1, a), e(1, b));
            let (gaa, gab, gbb) = (e(a, a), e(a, b), e(b, b));
            let det = gaa * gbb - gab * gab;
            c[0][q] = gamma * g11;
            c[1][q] = gamma * s2 * (g11 * gaa - g1a * g1a);
            c[2][q] = gamma * s2 * (g11 * gbb - g1b * g1b);
            c[3][q] = gamma
                * s2
                * s2
                * (g11 * det - g1a * g1a * gbb - g1b * g1b * gaa + 2.0 * g1a * g1b * gab);
            c[4][q] = s2 * gaa;
            c[5][q] = s2 * gbb;
            c[6][q] = s2 * s2 * det;
            c[7][q] = mis.rule().weights[q];
            c[8][q] = d[q];
        }
        Floor { c }
    }

    #[allow(clippy::needless_range_loop)] // lane loops: indexed form vectorises
    fn residual(&self, dm1: f64, dm2: f64) -> f64 {
        let dm12 = dm1 * dm2;
        let [n0, n1, n2, n12, d1, d2, d12, w, d] = &self.c;
        let mut acc = [0.0f64; 8];
        for q0 in (0..n0.len()).step_by(8) {
            let v = |a: &[f64]| -> [f64; 8] { a[q0..q0 + 8].try_into().unwrap() };
            let (n0, n1, n2, n12) = (v(n0), v(n1), v(n2), v(n12));
            let (d1, d2, d12, w, d) = (v(d1), v(d2), v(d12), v(w), v(d));
            for l in 0..8 {
                let num = n0[l] + n1[l] * dm1 + n2[l] * dm2 + n12[l] * dm12;
                let den = 1.0 + d1[l] * dm1 + d2[l] * dm2 + d12[l] * dm12;
                let e = num / den - d[l];
                acc[l] += w[l] * e * e;
            }
        }
        ((acc[0] + acc[1]) + (acc[2] + acc[3])) + ((acc[4] + acc[5]) + (acc[6] + acc[7]))
    }
}

criterion_group!(benches, bench);
criterion_group! {
    name = cpu;
    config = Criterion::default().with_measurement(CpuTime);
    targets = bench_cpu
}
criterion_main!(benches, cpu);
