//! Time per locator call, f64 against extended precision (128, 256, 512 bits).
//!
//! `cargo bench --bench locate -- --warm-up-time 1 --measurement-time 3`
//!
//! - `point/<method>/<precision>`: one estimate at one s (n = 20, j = 3, m = 5, s = 5),
//!   the unit cost of every curve point;
//! - `auto/<method>/f64`: `locate` with `--s auto` over the 61-point default grid.

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use springmass::detect::locate::{
    default_grid, estimate, locate, LaplaceData, Method, Model, SChoice,
};
use springmass::precision::{with_precision, BigReal, RealScalar};
use springmass::{Chain, Defect};

fn chain() -> Chain {
    Chain::paper(20)
        .unwrap()
        .with_defect(Defect::Mass { at: 3, m: 5.0 })
        .unwrap()
}

fn point_bench<T: RealScalar>(c: &mut Criterion, label: &str) {
    let ch = chain();
    let data = LaplaceData::<T>::from_chain(&ch, &[5.0]).unwrap();
    let model: Model<T> = Model::from_chain(&ch);
    let p = data.points()[0].clone();
    for (name, method) in [
        ("exact", Method::Exact { m: 5.0 }),
        ("asymptotic", Method::Asymptotic { m: 5.0 }),
        ("large", Method::Large),
        ("large-paper", Method::LargePaper),
    ] {
        c.bench_function(&format!("point/{name}/{label}"), |b| {
            b.iter(|| estimate(black_box(&model), black_box(&p), method).unwrap())
        });
    }
}

fn points(c: &mut Criterion) {
    point_bench::<f64>(c, "f64");
    for bits in [128usize, 256, 512] {
        with_precision(bits, || point_bench::<BigReal>(c, &format!("{bits}bits")));
    }
}

fn auto(c: &mut Criterion) {
    let ch = chain();
    let data = LaplaceData::<f64>::from_chain(&ch, &default_grid()).unwrap();
    let model: Model<f64> = Model::from_chain(&ch);
    for (name, method) in [
        ("exact", Method::Exact { m: 5.0 }),
        ("large", Method::Large),
        ("unknown-mass", Method::UnknownMass),
    ] {
        c.bench_function(&format!("auto/{name}/f64"), |b| {
            b.iter(|| locate(black_box(&model), black_box(&data), method, SChoice::Auto).unwrap())
        });
    }
}

criterion_group!(benches, points, auto);
criterion_main!(benches);
