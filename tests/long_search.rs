//! Many defects in long chains (issue 14): the greedy search of the
//! data-first fit (`method = greedy`) on exact data, and on a noisy sampled
//! record with a defect that only the record shows, at sizes that run in
//! seconds under `cargo test`; the full-size numbers (n = 60 over 20 draws
//! against enumeration, n = 10^4, the noisy n = 300 record) come from
//! `cargo bench --bench greedy`.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use springmass::detect::data::observations::{LaplaceValues, Observations, Series};
use springmass::detect::data::series::TimeData;
use springmass::detect::fit::{
    fit, DefectCount, FitMethod, FitOptions, FitReport, Model, NoiseSpec,
};
use springmass::detect::misfit::quadrature::Rule;
use springmass::detect::unknowns::KindChoice;
use springmass::forward::Forward;
use springmass::noise::NoiseLevel;
use springmass::{Chain, Complex64, Defect, Error};

/// `k` mass defects at positions in `1..=reach` at least 3 apart, masses
/// log-uniform in `[0.3, 5]` and not within 10% of the uniform mass 1 (the
/// draws of the bench).
fn draw(seed: u64, reach: usize, k: usize) -> Vec<Defect> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    loop {
        let mut p: Vec<usize> = (0..k).map(|_| rng.random_range(1..=reach)).collect();
        p.sort_unstable();
        if p.windows(2).any(|w| w[1] - w[0] < 3) {
            continue;
        }
        return p
            .into_iter()
            .map(|at| loop {
                let m = 0.3 * (5.0f64 / 0.3).powf(rng.random::<f64>());
                if (m - 1.0).abs() >= 0.1 {
                    break Defect::Mass { at, m };
                }
            })
            .collect();
    }
}

/// Exact `X_1` at 80 Gauss-Legendre nodes of `s = sigma_b + i omega`,
/// `omega in [0, 4]`, as Laplace values.
fn exact(truth: &Chain, sigma_b: f64) -> Observations {
    let rule = Rule::gauss_legendre_uniform(0.0, 4.0, 10, 8).unwrap();
    let s: Vec<Complex64> = rule
        .nodes
        .iter()
        .map(|&w| Complex64::new(sigma_b, w))
        .collect();
    let fwd = Forward::new(truth);
    let v = s.iter().map(|z| fwd.eval(*z, 1).unwrap()).collect();
    Observations::Laplace(LaplaceValues::new(s, v, None).unwrap())
}

fn greedy(k: usize, seed: u64) -> FitOptions {
    FitOptions {
        defects: DefectCount::Exactly(k),
        noise: NoiseSpec::Sigma(1e-12),
        kinds: KindChoice::Mass,
        method: FitMethod::Greedy,
        seed,
        ..FitOptions::default()
    }
}

/// Every position exact and every mass within `tol` (relative).
fn assert_recovered(r: &FitReport, truth: &[Defect], tol: f64) {
    let found: Vec<(usize, f64)> = r.defects.iter().map(|d| (d.at, d.value)).collect();
    let want: Vec<(usize, f64)> = truth.iter().map(|d| (d.at(), d.value())).collect();
    assert_eq!(found.len(), want.len(), "found {found:?}, truth {want:?}");
    for (f, w) in found.iter().zip(&want) {
        assert_eq!(f.0, w.0, "found {found:?}, truth {want:?}");
        assert!(
            ((f.1 - w.1) / w.1).abs() < tol,
            "found {found:?}, truth {want:?}"
        );
    }
}

/// Three masses of the seeded draws of a chain of `n` fitted from exact
/// data with `method`: every position right, every mass within 1e-4.
fn recovers_three_masses_on_seeded_draws(n: usize, method: FitMethod) {
    let model = Model::new(n).unwrap();
    for seed in [0, 4, 7, 12, 19] {
        let truth = draw(seed, n, 3);
        let chain = Chain::paper(n)
            .unwrap()
            .with_defects(truth.iter().copied())
            .unwrap();
        let opts = FitOptions {
            method,
            ..greedy(3, seed)
        };
        let r = fit(&exact(&chain, 0.05), &model, &opts).unwrap();
        assert!(r.method.starts_with(method.name()), "{}", r.method);
        // only the enumeration ranks every set
        assert_eq!(r.exhaustive, method == FitMethod::Enumerate);
        assert_recovered(&r, &truth, 1e-4);
    }
}

#[test]
fn greedy_recovers_three_masses_at_n60_on_seeded_draws() {
    recovers_three_masses_on_seeded_draws(60, FitMethod::Greedy);
}

#[test]
fn greedy_does_not_depend_on_threads() {
    let n = 60;
    let truth = draw(8, n, 3);
    let chain = Chain::paper(n)
        .unwrap()
        .with_defects(truth.iter().copied())
        .unwrap();
    let obs = exact(&chain, 0.05);
    let model = Model::new(n).unwrap();
    let par = fit(&obs, &model, &greedy(3, 8)).unwrap();
    let seq = fit(
        &obs,
        &model,
        &FitOptions {
            parallel: false,
            ..greedy(3, 8)
        },
    )
    .unwrap();
    assert_eq!(par.defects, seq.defects);
    assert_eq!(par.chi2.to_bits(), seq.chi2.to_bits());
    assert_eq!(par.evaluations, seq.evaluations);
    assert_recovered(&par, &truth, 1e-4);
}

#[test]
fn greedy_recovers_three_masses_in_a_chain_of_4000() {
    // d = 0.01 and defects within the first 400 masses, as in the bench's
    // long chain (deeper ones leave X_1 unchanged to rounding at this damping).
    // n = 4000 rather than 2000: up to n = 3000 the report's modes (a dense
    // O(n^3) eigen decomposition) take longer than the search itself.
    let n = 4000;
    let truth = draw(1000, 400, 3);
    let chain = Chain::paper(n)
        .and_then(|c| c.with_d(0.01))
        .and_then(|c| c.with_defects(truth.iter().copied()))
        .unwrap();
    let model = Model::new(n).and_then(|m| m.with_d(0.01)).unwrap();
    let r = fit(&exact(&chain, 0.01), &model, &greedy(3, 0)).unwrap();
    assert_recovered(&r, &truth, 1e-4);
}

fn field(e: Error) -> String {
    match e {
        Error::InvalidParameter { field, .. } => field,
        other => panic!("expected an invalid parameter, got {other}"),
    }
}

#[test]
fn greedy_refuses_bad_input_with_typed_errors() {
    let n = 8;
    let chain = Chain::paper(n)
        .unwrap()
        .with_defects([Defect::Mass { at: 3, m: 2.0 }])
        .unwrap();
    let obs = exact(&chain, 0.05);
    let model = Model::new(n).unwrap();
    let refused = |opts: FitOptions| field(fit(&obs, &model, &opts).unwrap_err());
    assert_eq!(refused(greedy(n + 1, 0)), "defects");
    assert_eq!(
        refused(FitOptions {
            defects: DefectCount::Auto { k_max: n + 1 },
            ..greedy(0, 0)
        }),
        "k_max"
    );
    let e = fit(
        &obs,
        &model,
        &FitOptions {
            defects: DefectCount::Auto { k_max: n + 1 },
            ..greedy(0, 0)
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains(&format!("<= n = {n}")), "{e}");
    assert_eq!(
        refused(FitOptions {
            slot_kinds: vec![KindChoice::Mass, KindChoice::Spring],
            ..greedy(2, 0)
        }),
        "kinds"
    );
    // within the range, the same options are accepted
    assert!(fit(&obs, &model, &greedy(2, 0)).is_ok());
}

/// A defect on the last mass (next to the right wall) is found by the
/// enumeration on the Woodbury kernel as by greedy: with two log-spaced
/// starts per mass the kernel's value fit slid to the lower bound there and
/// the enumeration answered the neighbouring mass (found by the greedy
/// bench: 2 of 20 draws at n = 60 missed).
#[test]
fn enumeration_finds_a_defect_on_the_last_mass() {
    for (n, a, b) in [(12usize, 4usize, 12usize), (30, 10, 30)] {
        let truth = [
            Defect::Mass { at: a, m: 2.0 },
            Defect::Mass { at: b, m: 3.0 },
        ];
        let chain = Chain::paper(n).unwrap().with_defects(truth).unwrap();
        let obs = exact(&chain, 0.05);
        for method in [FitMethod::Enumerate, FitMethod::Greedy] {
            let r = fit(
                &obs,
                &Model::new(n).unwrap(),
                &FitOptions {
                    method,
                    ..greedy(2, 0)
                },
            )
            .unwrap();
            assert_recovered(&r, &truth, 1e-6);
        }
    }
}

/// The noisy-record case at a smaller size: `n = 120`, `d = 0.01`,
/// three masses, the deepest at 110, `x_1` on `[0, 320]` every 0.25 with
/// noise `1e-3 max|x_1|`, `sigma` estimated, `k = auto`. Removing the deep
/// defect changes the fit's Bromwich line (`sigma_B = 0.05`) by about
/// `2e-3` of its noise (the bench's `chi_B`) but the record by 365 times
/// its noise (`chi_t`). The greedy search that scored candidates only on the
/// Bromwich line found 14, 70 and 85 here, with `sigma` estimated 8 times
/// too high (14 s); the time-record stage finds all three (under a second).
#[test]
fn greedy_finds_a_defect_only_the_record_shows() {
    let n = 120;
    let truth = [
        Defect::Mass { at: 14, m: 2.2 },
        Defect::Mass { at: 70, m: 0.6 },
        Defect::Mass { at: 110, m: 1.7 },
    ];
    let chain = Chain::paper(n)
        .and_then(|c| c.with_d(0.01))
        .and_then(|c| c.with_defects(truth))
        .unwrap();
    let rec = TimeData::simulate(&chain, 320.0, 0.25, NoiseLevel::RelativeMax(1e-3), 3).unwrap();
    let obs = Observations::Series(Series::new(rec.t().to_vec(), rec.y().to_vec(), None).unwrap());
    let model = Model::new(n).and_then(|m| m.with_d(0.01)).unwrap();
    let opts = FitOptions {
        defects: DefectCount::Auto { k_max: 3 },
        kinds: KindChoice::Mass,
        method: FitMethod::Greedy,
        ..FitOptions::default()
    };
    let r = fit(&obs, &model, &opts).unwrap();
    assert_eq!(r.k, 3, "{:?}", r.k_selection);
    assert_recovered(&r, &truth, 0.05);
    assert!(!r.exhaustive, "the greedy search ranks some sets only");
    assert_ne!(
        r.status,
        springmass::detect::fit::Status::Stalled,
        "the answer's values are refitted to the minimum"
    );
    assert!(
        (r.noise_sigma / rec.sigma() - 1.0).abs() < 0.1,
        "sigma {} against {}",
        r.noise_sigma,
        rec.sigma()
    );
}

/// The greedy search compares hypotheses on a few iterations each; its
/// answer's values are then refitted to the minimum. n = 60, three masses,
/// the deepest (41) barely seen through 1% noise: its value's valley is
/// flat, and the capped refit had stopped short (`stalled`, the mass at
/// 1.95 where the minimum is at 1.79).
#[test]
fn greedy_answer_is_refitted_to_the_minimum() {
    let truth = [
        Defect::Mass { at: 9, m: 2.5 },
        Defect::Mass { at: 23, m: 0.5 },
        Defect::Mass { at: 41, m: 1.8 },
    ];
    let chain = Chain::paper(60)
        .and_then(|c| c.with_defects(truth))
        .unwrap();
    let rec = TimeData::simulate(&chain, 300.0, 0.05, NoiseLevel::RelativeMax(1e-2), 1).unwrap();
    let obs = Observations::Series(Series::new(rec.t().to_vec(), rec.y().to_vec(), None).unwrap());
    let opts = FitOptions {
        defects: DefectCount::Exactly(3),
        kinds: KindChoice::Mass,
        method: FitMethod::Greedy,
        ..FitOptions::default()
    };
    let r = fit(&obs, &Model::new(60).unwrap(), &opts).unwrap();
    let at: Vec<usize> = r.defects.iter().map(|d| d.at).collect();
    assert_eq!(at, [9, 23, 41], "{}", r.message);
    assert_ne!(
        r.status,
        springmass::detect::fit::Status::Stalled,
        "{}",
        r.message
    );
    // the deep mass at the minimum (1.79; the capped refit left 1.95)
    let deep = r.defects[2].value;
    assert!((deep - 1.8).abs() < 0.05, "mass at 41: {deep}");
}

/// `method = relax`: the whole-profile inversion's support (the masses
/// farthest from uniform in standard errors) seeds the discrete fit, which
/// refits it with its neighbours: n = 30, k = 3, exact data on seeded draws
/// (at n = 60 the bench measures it beside the greedy search); a noisy
/// record of System 3 with k chosen by BIC; and a kind the relaxation
/// cannot free is refused by name.
#[test]
fn relax_seeds_the_discrete_fit_from_the_profile() {
    recovers_three_masses_on_seeded_draws(30, FitMethod::Relax);
    let s3 = Chain::paper(20)
        .unwrap()
        .with_defects([
            Defect::Mass { at: 8, m: 5.0 },
            Defect::Mass { at: 15, m: 2.0 },
        ])
        .unwrap();
    let rec = TimeData::simulate(&s3, 300.0, 0.1, NoiseLevel::RelativeMax(1e-3), 3).unwrap();
    let obs = Observations::Series(Series::new(rec.t().to_vec(), rec.y().to_vec(), None).unwrap());
    let opts = FitOptions {
        kinds: KindChoice::Mass,
        method: FitMethod::Relax,
        ..FitOptions::default()
    };
    let r = fit(&obs, &Model::new(20).unwrap(), &opts).unwrap();
    assert_eq!(r.k, 2, "{}", r.summary());
    assert_eq!(
        r.defects.iter().map(|d| d.at).collect::<Vec<_>>(),
        vec![8, 15]
    );
    for (d, m) in r.defects.iter().zip([5.0, 2.0]) {
        assert!((d.value - m).abs() < 4.0 * d.se, "{d:?}");
    }
    for kinds in [KindChoice::Damper, KindChoice::Any] {
        let e = fit(
            &obs,
            &Model::new(20).unwrap(),
            &FitOptions {
                kinds,
                ..opts.clone()
            },
        )
        .unwrap_err();
        assert_eq!(field(e), "kinds");
    }
}

/// The scene path on exact data of a long chain (issue 30): `relax` and
/// `greedy` either return the truth or say the answer does not explain the
/// data; never a wrong set called `converged` or resolved (relax returned
/// masses 1, 2 and 5 as `converged` and resolved on this scene).
#[test]
fn scene_searches_never_call_a_wrong_set_converged() {
    use springmass::detect::fit::{paper, Status};
    use springmass::detect::scene::FitScene;
    let truth = Chain::paper(60)
        .unwrap()
        .with_defects([
            Defect::Mass { at: 10, m: 2.0 },
            Defect::Mass { at: 31, m: 3.0 },
            Defect::Mass { at: 45, m: 0.5 },
        ])
        .unwrap();
    let scene = FitScene::synthetic(&truth);
    let data = scene.data().unwrap();
    for method in [FitMethod::Relax, FitMethod::Greedy] {
        let options = springmass::detect::scene::SceneOptions {
            method,
            ..scene.options()
        };
        let r = paper::fit(&scene, &data, &options).unwrap();
        let at: Vec<usize> = r.defects.iter().map(|d| d.at()).collect();
        let case = format!("{method:?}: {at:?}, {:?}: {}", r.status, r.message);
        if at != [10, 31, 45] {
            assert_eq!(r.status, Status::ModelMismatch, "{case}");
            assert!(!r.resolved && !r.fits_data, "{case}");
        }
    }
}

/// The scene path's default on a long chain (issue 30): from three defects
/// on 40 masses or more, the beam search's answer is kept when its residual
/// is at the data's error floor (no set can do better than 0), and is the
/// exhaustive enumeration's; `search.exhaustive` ranks every set; an answer
/// that does not fit (a spring changed, masses sought) is never certified
/// and every set is ranked.
#[test]
fn the_scene_default_certifies_the_beam_answer_in_a_long_chain() {
    use springmass::detect::fit::{paper, Status};
    use springmass::detect::scene::FitScene;
    let truth = springmass::scenes::paper_with(40, "mass:9:2.5 mass:23:0.5 mass:35:1.8").unwrap();
    let mut scene = FitScene::synthetic(&truth);
    let data = scene.data().unwrap();
    let quick = paper::fit(&scene, &data, &scene.options()).unwrap();
    let at = |r: &paper::SceneReport| r.defects.iter().map(|d| d.at()).collect::<Vec<_>>();
    assert!(quick.certified, "{}", quick.message);
    assert_eq!(at(&quick), [9, 23, 35], "{}", quick.message);
    assert_eq!(quick.status, Status::Converged, "{}", quick.message);
    assert!(quick.message.contains("certified"), "{}", quick.message);
    assert!(quick.sets.unwrap() < 9880 / 4, "{:?} sets", quick.sets);
    scene.search.exhaustive = true;
    let all = paper::fit(&scene, &data, &scene.options()).unwrap();
    assert!(!all.certified && all.exhaustive == Some(true));
    assert_eq!(all.sets, Some(9880));
    assert_eq!(at(&all), at(&quick));
    for (d, e) in quick.defects.iter().zip(&all.defects) {
        assert!((d.value() - e.value()).abs() < 1e-8, "{d:?} {e:?}");
    }
    // a spring changed: no mass set explains the data, nothing is certified
    let spring = springmass::scenes::paper_with(40, "mass:9:2.5 spring:5:0.5 mass:30:0.7").unwrap();
    let scene = FitScene::synthetic(&spring);
    let data = scene.data().unwrap();
    let r = paper::fit(&scene, &data, &scene.options()).unwrap();
    assert!(!r.certified && r.exhaustive == Some(true), "{}", r.message);
    assert!(
        !r.fits_data && r.status == Status::ModelMismatch,
        "{}",
        r.message
    );
}
