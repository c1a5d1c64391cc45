//! The defaults (k unknown, chosen by BIC; sigma estimated) against the
//! same fit told k, as a ratio measured in one run (issue 30: the defaults
//! should cost at most twice the k-given fit).
//!
//! `cargo bench --bench kauto -- --warm-up-time 1 --measurement-time 5`
//!
//! Records: `x_1` on `[0, 300]`, `dt = 0.05` (6001 samples), noise 1% of
//! `max |x_1|`, seed 1, of
//!
//! * `s3`: Table 1 System 3 (n = 20, masses 5 at 8 and 2 at 15);
//! * `n37`: the paper-sized n = 37 scene (masses 3 at 10 and 2 at 25).
//!
//! Benchmarks (this thread's CPU time, `parallel = false`):
//! `cpu/kauto/<case>/given` (`--defects 2`), `.../auto` (the defaults) and
//! `.../auto-low` (the defaults at `--effort low`, issue 30 item 5). The
//! ratios `auto / given` and `auto-low / given` of each case are printed
//! after its group.
//! The Python peer (`benches/scipy_peer.py`) compares the command line
//! with scipy's least_squares and differential evolution.
//!
//! Defect kind unknown (`cpu/kinds/<case>/mass` against `.../any`, the
//! defaults with `kinds` mass or any; issue 30 item 2b, at most 3x): n = 12
//! on `[0, 200]`, `dt = 0.05`, 1% noise, seed 1, with a mass (2 at 4) and a
//! spring (0.5 at 8) (`mixed`), or three masses (2 at 2, 0.6 at 6, 1.8 at
//! 9) (`masses`); and the records `s3` and `n37` above. The ratio
//! `any / mass` is printed after each group.
//!
//! The damping fitted (`cpu/fit-d/<case>/fit-d`: `--fit d --damping
//! grounded`) against the defaults told `d` (`.../given`), on `s3` and
//! `n37` (issue 30: at most 2x); the ratio is printed after each group.
//! On `s3` also the fit that chooses the damping model too
//! (`cpu/fit-d/s3/choice`: `--fit d` alone; with `parallel` false its
//! candidates are fitted on the calling thread, so its thread CPU time is
//! all of its work).
//!
//! The hidden-defect check that the defaults add to a fit
//! (`cpu/unseen/<case>/stepped`: each probe's record resumed from the saved
//! states of one simulation and stopped once it shows the change) against
//! the same check with every probe summed over its modes
//! (`.../summed`, the measurement model's default `near`), at the truth of
//! `s3` and of `n60` (n = 60, masses 2.5 at 9 and 0.5 at 23); the ratio is
//! printed after each group.

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use springmass::detect::data::observations::{Observations, Series};
use springmass::detect::data::series::TimeData;
use springmass::detect::fit::effort::Effort;
use springmass::detect::fit::general::Hypothesis;
use springmass::detect::fit::options::FitSpec;
use springmass::detect::fit::unseen::unseen;
use springmass::detect::fit::{fit, DefectCount, FitOptions, Model};
use springmass::detect::misfit::time::TimeMisfit;
use springmass::detect::model::MeasurementModel;
use springmass::detect::unknowns::DefectKind;
use springmass::detect::unknowns::KindChoice;
use springmass::noise::NoiseLevel;
use springmass::sensitivity::Param;
use springmass::{Chain, Defect};
use std::time::{Duration, Instant};

#[path = "common/cputime.rs"]
mod cputime;
use cputime::CpuTime;

fn record(n: usize, defects: &[(usize, f64)]) -> Observations {
    let truth = Chain::paper(n)
        .unwrap()
        .with_defects(defects.iter().map(|&(at, m)| Defect::Mass { at, m }))
        .unwrap();
    let d = TimeData::simulate(&truth, 300.0, 0.05, NoiseLevel::RelativeMax(1e-2), 1).unwrap();
    Observations::Series(Series::new(d.t().to_vec(), d.y().to_vec(), None).unwrap())
}

/// The records' defects are masses, sought as masses (every kind, the
/// default: `cpu/kinds`).
fn options(defects: DefectCount) -> FitOptions {
    FitOptions {
        defects,
        kinds: KindChoice::Mass,
        parallel: false,
        ..FitOptions::default()
    }
}

/// Mean wall time of `runs` fits (the ratio line beside criterion's).
fn mean_s(runs: usize, f: impl Fn()) -> f64 {
    let t = Instant::now();
    for _ in 0..runs {
        f();
    }
    t.elapsed().as_secs_f64() / runs as f64
}

/// Criterion's group `group` of the fits of `obs` by each `(label, model,
/// options)`, then the mean wall time of three fits of each, in order (for
/// the ratio line printed after the group).
fn timed(
    c: &mut Criterion<CpuTime>,
    group: &str,
    obs: &Observations,
    fits: &[(&str, &Model, &FitOptions)],
) -> Vec<f64> {
    let mut grp = c.benchmark_group(group);
    grp.sample_size(10).measurement_time(Duration::from_secs(5));
    for &(label, model, opts) in fits {
        grp.bench_function(label, |b| {
            b.iter(|| fit(black_box(obs), model, opts).unwrap())
        });
    }
    grp.finish();
    fits.iter()
        .map(|&(_, model, opts)| {
            mean_s(3, || {
                fit(obs, model, opts).unwrap();
            })
        })
        .collect()
}

fn bench_kauto(c: &mut Criterion<CpuTime>) {
    let cases = [
        ("s3", 20, record(20, &[(8, 5.0), (15, 2.0)])),
        ("n37", 37, record(37, &[(10, 3.0), (25, 2.0)])),
    ];
    for (name, n, obs) in &cases {
        let model = Model::new(*n).unwrap();
        let given = options(DefectCount::Exactly(2));
        let auto = options(FitOptions::default().defects);
        let low = FitOptions {
            effort: Effort::Low,
            ..auto.clone()
        };
        let a = fit(obs, &model, &auto).unwrap();
        let g = fit(obs, &model, &given).unwrap();
        let at = |r: &springmass::detect::fit::FitReport| -> Vec<usize> {
            r.defects.iter().map(|d| d.at).collect()
        };
        assert_eq!(at(&a), at(&g), "{name}: the defaults choose k = 2");
        let l = fit(obs, &model, &low).unwrap();
        assert_eq!(at(&l), at(&g), "{name}: effort low chooses k = 2");
        let t = timed(
            c,
            &format!("cpu/kauto/{name}"),
            obs,
            &[
                ("given", &model, &given),
                ("auto", &model, &auto),
                ("auto-low", &model, &low),
            ],
        );
        let (tg, ta, tl) = (t[0], t[1], t[2]);
        println!(
            "{name}: defaults {ta:.3} s, effort low {tl:.3} s, k given {tg:.3} s, ratios {:.1}x and {:.1}x (wall, one thread, mean of 3)",
            ta / tg,
            tl / tg
        );
    }
}

fn bench_kinds(c: &mut Criterion<CpuTime>) {
    let twelve = |defects: Vec<Defect>| {
        let truth = Chain::paper(12).unwrap().with_defects(defects).unwrap();
        let d = TimeData::simulate(&truth, 200.0, 0.05, NoiseLevel::RelativeMax(1e-2), 1).unwrap();
        Observations::Series(Series::new(d.t().to_vec(), d.y().to_vec(), None).unwrap())
    };
    let cases = [
        (
            "mixed",
            12,
            twelve(vec![
                Defect::Mass { at: 4, m: 2.0 },
                Defect::Spring { at: 8, k: 0.5 },
            ]),
        ),
        (
            "masses",
            12,
            twelve(vec![
                Defect::Mass { at: 2, m: 2.0 },
                Defect::Mass { at: 6, m: 0.6 },
                Defect::Mass { at: 9, m: 1.8 },
            ]),
        ),
        ("s3", 20, record(20, &[(8, 5.0), (15, 2.0)])),
        ("n37", 37, record(37, &[(10, 3.0), (25, 2.0)])),
    ];
    for (name, n, obs) in &cases {
        let model = Model::new(*n).unwrap();
        let with = |kinds| FitOptions {
            kinds,
            parallel: false,
            ..FitOptions::default()
        };
        let (mass, any) = (with(KindChoice::Mass), with(KindChoice::Any));
        let t = timed(
            c,
            &format!("cpu/kinds/{name}"),
            obs,
            &[("mass", &model, &mass), ("any", &model, &any)],
        );
        let (tm, ta) = (t[0], t[1]);
        println!(
            "{name}: kinds any {ta:.3} s, kinds mass {tm:.3} s, ratio {:.1}x (wall, one thread, mean of 3)",
            ta / tm
        );
    }
}

/// `--fit d` (the damping fitted, the grounded model given) against the
/// defaults told `d` (issue 30: at most 2x), on the records `s3` and
/// `n37`; the damping model's choice (`--fit d` alone) is timed on `s3`
/// too (`cpu/fit-d/s3/choice`).
fn bench_fit_d(c: &mut Criterion<CpuTime>) {
    let cases = [
        ("s3", 20, record(20, &[(8, 5.0), (15, 2.0)])),
        ("n37", 37, record(37, &[(10, 3.0), (25, 2.0)])),
    ];
    for (name, n, obs) in &cases {
        let spec = |fit_d: bool, damping: Option<&str>| FitSpec {
            fit: fit_d.then(|| "d".to_string()),
            damping: damping.map(str::to_string),
            kinds: Some("mass".into()),
            ..FitSpec::new(*n)
        };
        let build = |s: FitSpec| {
            let (model, opts) = s.build().unwrap();
            let opts = FitOptions {
                parallel: false,
                ..opts
            };
            (model, opts)
        };
        let (model, given) = build(spec(false, None));
        let (model_d, fit_d) = build(spec(true, Some("grounded")));
        let at = |r: &springmass::detect::fit::FitReport| -> Vec<usize> {
            r.defects.iter().map(|d| d.at).collect()
        };
        let g = fit(obs, &model, &given).unwrap();
        let d = fit(obs, &model_d, &fit_d).unwrap();
        assert_eq!(at(&g), at(&d), "{name}: --fit d finds the same masses");
        assert!(d.params.iter().any(|p| p.name == "d"), "{name}: d fitted");
        let (model_c, choose) = build(spec(true, None));
        let mut runs = vec![("given", &model, &given), ("fit-d", &model_d, &fit_d)];
        if *name == "s3" {
            runs.push(("choice", &model_c, &choose));
        }
        let t = timed(c, &format!("cpu/fit-d/{name}"), obs, &runs);
        let (tg, td) = (t[0], t[1]);
        let choice = match t.get(2) {
            Some(tc) => format!(", the damping model chosen too {tc:.3} s ({:.1}x)", tc / tg),
            None => String::new(),
        };
        println!(
            "{name}: --fit d {td:.3} s, d given {tg:.3} s, ratio {:.1}x{choice} (wall, one thread, mean of 3)",
            td / tg
        );
    }
}

/// The time misfit with the measurement model's default `near`: every
/// probe of the hidden-defect check summed over its modes.
#[derive(Debug)]
struct Summed<'a>(&'a TimeMisfit);

impl MeasurementModel for Summed<'_> {
    fn name(&self) -> &'static str {
        "time, summed"
    }
    fn dof(&self) -> usize {
        MeasurementModel::dof(self.0)
    }
    fn residuals(&self, chain: &Chain) -> springmass::Result<Vec<f64>> {
        self.0.residuals(chain)
    }
    fn jacobian(
        &self,
        chain: &Chain,
        params: &[Param],
    ) -> springmass::Result<Option<nalgebra::DMatrix<f64>>> {
        MeasurementModel::jacobian(self.0, chain, params)
    }
}

fn bench_unseen(c: &mut Criterion<CpuTime>) {
    for (name, n, defects) in [
        ("s3", 20, vec![(8, 5.0), (15, 2.0)]),
        ("n60", 60, vec![(9, 2.5), (23, 0.5)]),
    ] {
        let truth = Chain::paper(n)
            .unwrap()
            .with_defects(defects.iter().map(|&(at, m)| Defect::Mass { at, m }))
            .unwrap();
        let data =
            TimeData::simulate(&truth, 300.0, 0.05, NoiseLevel::RelativeMax(1e-2), 1).unwrap();
        let misfit = TimeMisfit::new(data);
        let summed = Summed(&misfit);
        let model = Model::new(n).unwrap();
        let h = Hypothesis::from_parts(truth.defects().to_vec(), vec![0.0; 2], vec![], 0.0);
        let kinds = [DefectKind::Mass, DefectKind::Spring];
        let check = |m: &dyn MeasurementModel| unseen(&h, &model, m, &kinds, 1.0, false).unwrap();
        assert_eq!(check(&misfit), check(&summed), "{name}: the same elements");
        let mut grp = c.benchmark_group(format!("cpu/unseen/{name}"));
        grp.sample_size(10).measurement_time(Duration::from_secs(5));
        grp.bench_function("stepped", |b| b.iter(|| check(black_box(&misfit))));
        grp.bench_function("summed", |b| b.iter(|| check(black_box(&summed))));
        grp.finish();
        let ts = mean_s(3, || {
            check(&misfit);
        });
        let tm = mean_s(3, || {
            check(&summed);
        });
        println!(
            "{name}: the hidden-defect check stepped {ts:.3} s, summed over modes {tm:.3} s, ratio {:.2}x (wall, one thread, mean of 3)",
            ts / tm
        );
    }
}

criterion_group! {
    name = benches_kauto;
    config = Criterion::default().with_measurement(CpuTime);
    targets = bench_kauto, bench_kinds, bench_fit_d, bench_unseen
}
criterion_main!(benches_kauto);
