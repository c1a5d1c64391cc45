//! Wall time of the damping model's choice (issue 27's cost): on a record
//! of a Rayleigh-damped chain, the defaults with `--fit d` (the damping
//! models screened cheapest first until one explains the record, the
//! others fitted at its set) against the same fit
//! told the model (`--damping rayleigh --fit d`), and against the defaults
//! on a record of the paper's grounded damping of the same chain (the
//! white-noise fit the issue measures the cost against). One run, so the
//! ratios hold on a shared machine.
//!
//! `cargo bench --bench damping -- --warm-up-time 1 --measurement-time 10`
//!
//! Records: n = 5, masses 3 at 2 and 0.5 at 4, `x_1` on `[0, 120]` at
//! `dt = 0.5`, 1% noise of `max |x_1|`, seed 2; Rayleigh damping
//! `a = 0.05`, `b = 0.02` (and `d = 0`), or grounded `d = 0.1`.
//!
//! Benchmarks (wall time: the choice uses every core):
//!
//! * `damping/choice`: the Rayleigh record, `fit = d`, no model given;
//! * `damping/given`: the same record, `damping = rayleigh`, `fit = d`;
//! * `damping/grounded`: the grounded record with the defaults.

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use springmass::chain::Damping;
use springmass::detect::data::observations::{Observations, Series};
use springmass::detect::data::series::TimeData;
use springmass::detect::fit::fit;
use springmass::detect::fit::options::FitSpec;
use springmass::noise::NoiseLevel;
use springmass::{Chain, Defect};
use std::time::Duration;

fn record(damping: Option<Damping>) -> Observations {
    let chain = Chain::paper(5)
        .unwrap()
        .with_defects([
            Defect::Mass { at: 2, m: 3.0 },
            Defect::Mass { at: 4, m: 0.5 },
        ])
        .unwrap();
    let chain = match damping {
        Some(d) => chain.with_d(0.0).unwrap().with_damping(d).unwrap(),
        None => chain,
    };
    let data = TimeData::simulate(&chain, 120.0, 0.5, NoiseLevel::RelativeMax(1e-2), 2).unwrap();
    Observations::Series(Series::new(data.t().to_vec(), data.y().to_vec(), None).unwrap())
}

fn bench(c: &mut Criterion) {
    let rayleigh = record(Some(Damping::Rayleigh { a: 0.05, b: 0.02 }));
    let grounded = record(None);
    let spec = |fit_d: bool, damping: Option<&str>, d: f64| FitSpec {
        fit: fit_d.then(|| "d".to_string()),
        damping: damping.map(str::to_string),
        d: Some(d),
        // masses: the record's defects (every kind: `cpu/kinds` in kauto)
        kinds: Some("mass".into()),
        ..FitSpec::new(5)
    };
    let cases = [
        ("choice", &rayleigh, spec(true, None, 0.0)),
        ("given", &rayleigh, spec(true, Some("rayleigh"), 0.0)),
        ("grounded", &grounded, spec(false, None, 0.1)),
    ];
    let mut g = c.benchmark_group("damping");
    g.sample_size(10).measurement_time(Duration::from_secs(10));
    for (name, obs, spec) in &cases {
        let (model, opts) = spec.build().unwrap();
        let r = fit(obs, &model, &opts).unwrap();
        assert_eq!(r.found().len(), 2, "{name}: {}", r.summary());
        g.bench_function(*name, |b| {
            b.iter(|| fit(black_box(*obs), &model, &opts).unwrap())
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
