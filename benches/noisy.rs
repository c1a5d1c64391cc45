//! Cost of one Levenberg-Marquardt step's model work (residuals and
//! Jacobian) for each misfit of a noisy series, positions known.
//!
//! `cargo bench --bench noisy -- --warm-up-time 1 --measurement-time 3`
//!
//! System 3 of Table 1 (n = 20, masses 5 at 8 and 2 at 15, d = 0.1), its
//! series x_1(t) on [0, 200] at dt = 0.2 with 0.1% noise, two unknown masses.
//! Per misfit, `residuals` and `residuals+jacobian` at the truth:
//!
//! * `real/diagonal`, `bromwich/diagonal`: 80 nodes weighted `w_q / v_q`
//!   (the baseline: one O(k) forward solve per node);
//! * `real/whitened`, `bromwich/whitened`: the same residuals multiplied by
//!   the whitening matrix (a true chi-square; 30 x 80 and 160 x 160);
//! * `time`: the time-domain chi-square (exact modal sum at 1001 samples,
//!   Jacobian by central differences).
//!
//! Every benchmark runs under thread CPU time (group `cpu/`): the machine is
//! shared; report ratios against the diagonal baseline of the same run.

use criterion::measurement::Measurement;
use criterion::{black_box, criterion_group, criterion_main, Criterion};
use springmass::detect::data::whiten::Weighting;
use springmass::detect::fit::chainfit::ChainProblem;
use springmass::detect::fit::general::{laplace_obs, Setup};
use springmass::detect::misfit::MisfitKind;
use springmass::detect::search::lsq::LeastSquares;
use springmass::detect::{data::series::TimeData, misfit::time::TimeMisfit};
use springmass::noise::NoiseLevel;
use springmass::scenes;
use springmass::sensitivity::Param;

#[path = "common/cputime.rs"]
mod cputime;
use cputime::CpuTime;

fn bench_generic<M: Measurement + 'static>(c: &mut Criterion<M>) {
    let truth = scenes::table1(3).unwrap();
    let data = TimeData::simulate(&truth, 200.0, 0.2, NoiseLevel::RelativeMax(1e-3), 1).unwrap();
    let params = Param::defects(&truth);
    let theta: Vec<f64> = truth.defects().iter().map(|d| d.value()).collect();
    let mut group = c.benchmark_group("cpu/noisy");
    for choice in [MisfitKind::RealAxis, MisfitKind::Bromwich] {
        for weighting in [Weighting::Diagonal, Weighting::Whitened] {
            let setup = Setup {
                weighting,
                ..Setup::new().unwrap()
            };
            let obs = laplace_obs(&data, choice, &setup).unwrap();
            let problem = ChainProblem::new(&truth, &params, &obs).unwrap();
            let name = format!(
                "{}/{}",
                choice.name(),
                format!("{weighting:?}").to_lowercase()
            );
            eprintln!(
                "{name}: {} residuals",
                problem.residuals(&theta).unwrap().len()
            );
            group.bench_function(format!("{name}/residuals"), |b| {
                b.iter(|| problem.residuals(black_box(&theta)).unwrap())
            });
            group.bench_function(format!("{name}/residuals+jacobian"), |b| {
                b.iter(|| {
                    (
                        problem.residuals(black_box(&theta)).unwrap(),
                        problem.jacobian(black_box(&theta)).unwrap(),
                    )
                })
            });
        }
    }
    let misfit = TimeMisfit::new(data.clone());
    let problem = ChainProblem::new(&truth, &params, &misfit).unwrap();
    group.bench_function("time/residuals", |b| {
        b.iter(|| problem.residuals(black_box(&theta)).unwrap())
    });
    group.bench_function("time/residuals+jacobian", |b| {
        b.iter(|| {
            (
                problem.residuals(black_box(&theta)).unwrap(),
                problem.jacobian(black_box(&theta)).unwrap(),
            )
        })
    });
    group.finish();
}

criterion_group! {
    name = cpu;
    config = Criterion::default().with_measurement(CpuTime);
    targets = bench_generic
}
criterion_main!(cpu);
