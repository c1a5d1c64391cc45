//! The ground spring (`Defect::Ground`: a spring from one mass to the
//! ground), the kind added to show what a new defect kind costs: its
//! physics is one `Site` in `src/chain.rs` and its fitting table one entry of
//! `DefectKind` in `src/detect/unknowns/mod.rs`. Here every path that reads it
//! is checked against references written out in this file: a dense solve of
//! `(M s^2 + D s + K) x = gamma e_1` assembled by hand, the identity with a
//! wall spring at mass 1, finite differences of the response, the modal sum
//! against the simulator, and fits from data.

use springmass::detect::data::observations::{LaplaceValues, Observations, Series};
use springmass::detect::data::series::TimeData;
use springmass::detect::fit::{fit, DefectCount, FitMethod, FitOptions, Model, NoiseSpec};
use springmass::detect::unknowns::{DefectKind, KindChoice};
use springmass::forward::{response, Forward};
use springmass::noise::NoiseLevel;
use springmass::sensitivity::{gradient, Param};
use springmass::time::modal::ModalResponse;
use springmass::time::simulate::{simulate, Method, SimOptions};
use springmass::{Chain, Complex64, Defect, Error};

/// `X` at every mass by a dense LU of the matrix assembled here from the
/// defect list (not from the library's assembly).
fn dense(chain: &Chain, s: Complex64) -> Vec<Complex64> {
    let n = chain.n();
    let mut m = vec![chain.mass(); n];
    let mut d = vec![chain.d(); n];
    let mut g = vec![0.0; n];
    let mut k = vec![chain.k(); n + 1];
    for def in chain.defects() {
        match *def {
            Defect::Mass { at, m: v } => m[at - 1] = v,
            Defect::Damper { at, d: v } => d[at - 1] = v,
            Defect::Ground { at, g: v } => g[at - 1] = v,
            Defect::Spring { at, k: v } => k[at] = v,
        }
    }
    let mut a = nalgebra::DMatrix::<Complex64>::zeros(n, n);
    for i in 0..n {
        a[(i, i)] = s * s * m[i] + s * d[i] + g[i] + k[i] + k[i + 1];
        if i + 1 < n {
            a[(i, i + 1)] = (-k[i + 1]).into();
            a[(i + 1, i)] = (-k[i + 1]).into();
        }
    }
    let mut b = nalgebra::DVector::<Complex64>::zeros(n);
    b[0] = chain.gamma().into();
    a.lu().solve(&b).unwrap().iter().copied().collect()
}

fn chains() -> Vec<Chain> {
    let c = |n: usize, defs: Vec<Defect>| Chain::paper(n).unwrap().with_defects(defs).unwrap();
    vec![
        c(1, vec![Defect::Ground { at: 1, g: 0.7 }]),
        c(6, vec![Defect::Ground { at: 3, g: 2.0 }]),
        c(
            12,
            vec![
                Defect::Ground { at: 12, g: 0.05 },
                Defect::Mass { at: 12, m: 3.0 },
                Defect::Spring { at: 5, k: 0.4 },
                Defect::Ground { at: 5, g: 30.0 },
                Defect::Damper { at: 5, d: 0.0 },
            ],
        ),
        Chain::paper(40)
            .unwrap()
            .with_d(0.0)
            .unwrap()
            .with_defects([
                Defect::Ground { at: 17, g: 1e-3 },
                Defect::Ground { at: 2, g: 1e3 },
            ])
            .unwrap(),
    ]
}

#[test]
fn every_forward_path_matches_a_dense_solve() {
    let nodes = [
        Complex64::new(1e-6, 0.0),
        Complex64::new(0.3, 0.0),
        Complex64::new(2.0, 0.0),
        Complex64::new(1e4, 0.0),
        Complex64::new(0.05, 1.3),
        Complex64::new(1.0, -7.0),
    ];
    for chain in chains() {
        let n = chain.n();
        let fwd = Forward::new(&chain);
        for &s in &nodes {
            let want = dense(&chain, s);
            for o in [1, n] {
                let w = want[o - 1];
                let tol = 1e-10 * w.norm() + 1e-300;
                let closed = fwd.eval(s, o).unwrap();
                assert!(
                    (closed - w).norm() <= tol,
                    "{chain:?} s={s} X_{o}: {closed} vs {w}"
                );
                let tri = springmass::forward::tridiag::solve(&chain, s, o).unwrap();
                assert!(
                    (tri - w).norm() <= tol,
                    "tridiagonal {chain:?} s={s}: {tri} vs {w}"
                );
                if s.im == 0.0 {
                    let real = response(&chain, s.re, o).unwrap();
                    assert!(
                        (real - w.re).abs() <= tol,
                        "real {chain:?} s={s}: {real} vs {w}"
                    );
                }
            }
        }
    }
}

#[test]
fn a_ground_spring_at_mass_one_is_a_stiffer_wall_spring() {
    let base = Chain::paper(9).unwrap();
    let ground = base
        .clone()
        .with_defect(Defect::Ground { at: 1, g: 0.6 })
        .unwrap();
    let wall = base.with_defect(Defect::Spring { at: 0, k: 1.6 }).unwrap();
    for s in [Complex64::new(0.2, 0.0), Complex64::new(0.05, 0.9)] {
        for o in [1, 5, 9] {
            let (a, b) = (
                Forward::new(&ground).eval(s, o).unwrap(),
                Forward::new(&wall).eval(s, o).unwrap(),
            );
            assert!((a - b).norm() <= 1e-13 * b.norm(), "{s} X_{o}: {a} vs {b}");
        }
    }
    let (a, b) = (
        ModalResponse::impulse(&ground, 1).unwrap(),
        ModalResponse::impulse(&wall, 1).unwrap(),
    );
    for t in [0.5, 7.0, 40.0] {
        assert!((a.eval(t) - b.eval(t)).abs() <= 1e-12, "t = {t}");
    }
}

#[test]
fn the_derivative_by_reciprocity_matches_finite_differences() {
    let chain = Chain::paper(8)
        .unwrap()
        .with_defects([
            Defect::Ground { at: 4, g: 0.5 },
            Defect::Mass { at: 6, m: 2.0 },
        ])
        .unwrap();
    let p = Param::Defect(0);
    for s in [Complex64::new(0.4, 0.0), Complex64::new(0.1, 1.1)] {
        let got = gradient(&chain, s, 1, &[p]).unwrap().grad[0];
        let h = 1e-6;
        let up = Forward::new(&p.set(&chain, 0.5 + h).unwrap())
            .eval(s, 1)
            .unwrap();
        let dn = Forward::new(&p.set(&chain, 0.5 - h).unwrap())
            .eval(s, 1)
            .unwrap();
        let fd = (up - dn) / (2.0 * h);
        assert!((got - fd).norm() <= 1e-7 * fd.norm(), "{s}: {got} vs {fd}");
    }
}

#[test]
fn modal_sum_and_simulator_agree_with_ground_springs() {
    for chain in chains().into_iter().take(3) {
        let n = chain.n();
        let modal = ModalResponse::impulse(&chain, n).unwrap();
        let s = Complex64::new(0.3, 0.9);
        let want = dense(&chain, s)[n - 1];
        let got = modal.laplace(s);
        assert!(
            (got - want).norm() <= 1e-9 * want.norm(),
            "{chain:?}: {got} vs {want}"
        );
        let opts = SimOptions::new(30.0, 0.5).with_observe(vec![n]);
        let ex: Vec<f64> = (0..=60).map(|i| modal.eval(i as f64 * 0.5)).collect();
        for m in [Method::Expm, Method::Rk] {
            let tr = simulate(&chain, &opts.clone().with_method(m)).unwrap();
            let e = tr
                .x(n)
                .unwrap()
                .iter()
                .zip(&ex)
                .fold(0.0f64, |a, (x, y)| a.max((x - y).abs()));
            assert!(e <= 1e-11, "{chain:?} {m}: {e:e}");
        }
    }
}

fn ground_truth() -> Chain {
    Chain::paper(12)
        .unwrap()
        .with_defect(Defect::Ground { at: 7, g: 0.3 })
        .unwrap()
}

/// Exact `X_1` of `truth` at 60 nodes of the Bromwich line `0.05 + i w`.
fn exact_values(truth: &Chain) -> Observations {
    let s: Vec<Complex64> = (0..60)
        .map(|q| Complex64::new(0.05, 0.05 * q as f64))
        .collect();
    let fwd = Forward::new(truth);
    let values: Vec<Complex64> = s.iter().map(|&z| fwd.eval(z, 1).unwrap()).collect();
    Observations::Laplace(LaplaceValues::new(s, values, None).unwrap())
}

#[test]
fn a_ground_spring_is_found_from_exact_laplace_values() {
    let truth = ground_truth();
    let obs = exact_values(&truth);
    for method in [FitMethod::Enumerate, FitMethod::Greedy] {
        let opts = FitOptions {
            defects: DefectCount::Exactly(1),
            kinds: KindChoice::Ground,
            method,
            ..FitOptions::default()
        };
        let r = fit(&obs, &Model::new(12).unwrap(), &opts).unwrap();
        let d = &r.defects[0];
        assert_eq!((d.kind, d.at), ("ground", 7), "{method:?}: {}", r.summary());
        assert!((d.value - 0.3).abs() < 1e-6, "{method:?}: {d:?}");
    }
}

#[test]
fn a_ground_spring_is_found_from_a_noisy_record_with_sigma_unknown() {
    let truth = ground_truth();
    let rec = TimeData::simulate(&truth, 200.0, 0.25, NoiseLevel::RelativeMax(1e-3), 3).unwrap();
    let obs = Observations::Series(Series::new(rec.t().to_vec(), rec.y().to_vec(), None).unwrap());
    let opts = FitOptions {
        defects: DefectCount::Exactly(1),
        kinds: KindChoice::Ground,
        noise: NoiseSpec::Auto,
        ..FitOptions::default()
    };
    let r = fit(&obs, &Model::new(12).unwrap(), &opts).unwrap();
    let d = &r.defects[0];
    assert_eq!((d.kind, d.at), ("ground", 7), "{}", r.summary());
    assert!(d.se > 1e-8 && (d.value - 0.3).abs() < 4.0 * d.se, "{d:?}");
    assert!(r.noise_estimated && r.fits_data, "{}", r.summary());
}

#[test]
fn names_ranges_and_bad_values() {
    assert_eq!(
        Defect::parse("ground:3:0.5").unwrap(),
        Defect::Ground { at: 3, g: 0.5 }
    );
    assert_eq!(DefectKind::from_name("ground"), Some(DefectKind::Ground));
    assert_eq!(
        springmass::detect::fit::options::parse_kinds("ground").unwrap(),
        KindChoice::Ground
    );
    // `any` keeps to the chain's own elements (a ground spring at mass 1 is a wall spring)
    assert!(!KindChoice::Any.kinds().contains(&DefectKind::Ground));
    let c = Chain::paper(4).unwrap();
    for (bad, field) in [
        (Defect::Ground { at: 0, g: 1.0 }, "defects[0].at"),
        (Defect::Ground { at: 5, g: 1.0 }, "defects[0].at"),
        (Defect::Ground { at: 2, g: -1.0 }, "defects[0].g"),
        (Defect::Ground { at: 2, g: f64::NAN }, "defects[0].g"),
    ] {
        match c.clone().with_defect(bad) {
            Err(Error::InvalidParameter { field: f, .. }) => assert_eq!(f, field, "{bad:?}"),
            other => panic!("{bad:?}: {other:?}"),
        }
    }
    // zero is allowed (no support), and a ground spring may share a mass with a mass defect
    assert!(c
        .with_defects([
            Defect::Ground { at: 2, g: 0.0 },
            Defect::Mass { at: 2, m: 2.0 }
        ])
        .is_ok());
}

#[test]
fn a_known_ground_spring_in_the_model_is_kept_while_a_mass_is_fitted() {
    let truth = Chain::paper(10)
        .unwrap()
        .with_defects([
            Defect::Ground { at: 3, g: 0.8 },
            Defect::Mass { at: 8, m: 2.5 },
        ])
        .unwrap();
    let obs = exact_values(&truth);
    let model = Model::new(10)
        .unwrap()
        .with_known(Defect::Ground { at: 3, g: 0.8 })
        .unwrap();
    let opts = FitOptions {
        defects: DefectCount::Exactly(1),
        ..FitOptions::default()
    };
    let r = fit(&obs, &model, &opts).unwrap();
    let d = r.defects.iter().find(|d| !d.known).unwrap();
    assert_eq!((d.kind, d.at), ("mass", 8), "{}", r.summary());
    assert!((d.value - 2.5).abs() < 1e-6, "{d:?}");
}

/// The record's search path (`detect::misfit::time_screen`, and the time
/// misfit's fast simulation for chains of 100 masses or more): a ground
/// spring's sensitivity against the modal derivative, and the simulated
/// model of a long chain with ground springs against the modal sum.
#[test]
fn record_scores_and_the_long_chain_time_model_read_ground_springs() {
    use springmass::detect::misfit::time::TimeMisfit;
    use springmass::detect::misfit::time_screen::Screen;
    use springmass::time::modal::Modes;
    let n = 12;
    let c = Chain::paper(n)
        .unwrap()
        .with_defects([
            Defect::Ground { at: 6, g: 0.4 },
            Defect::Mass { at: 3, m: 2.0 },
        ])
        .unwrap();
    let t: Vec<f64> = (0..1201).map(|i| 0.1 * i as f64).collect();
    let screen = Screen::new(&t, &vec![0.0; t.len()], &c).unwrap();
    let modes = Modes::new(&c).unwrap();
    let cands = vec![(DefectKind::Ground, 6), (DefectKind::Ground, 9)];
    let (_, gs) = screen.each(&c, &cands, false, |_, g| g.to_vec()).unwrap();
    for (&(_, p), g) in cands.iter().zip(&gs) {
        let exact = modes
            .value_derivative(1, 1, c.gamma(), &[(p, 1.0)], 0)
            .unwrap()
            .unwrap()
            .eval_many(&t);
        let norm = exact.iter().map(|v| v * v).sum::<f64>().sqrt();
        let err = g
            .iter()
            .zip(&exact)
            .map(|(a, b)| (a - b) * (a - b))
            .sum::<f64>()
            .sqrt()
            / norm;
        assert!(err < 1e-9, "ground at {p}: relative error {err:e}");
    }
    // n = 120: the time misfit's model is the fast simulation
    let long = Chain::paper(120)
        .unwrap()
        .with_d(0.05)
        .unwrap()
        .with_defects([
            Defect::Ground { at: 4, g: 0.5 },
            Defect::Ground { at: 30, g: 2.0 },
        ])
        .unwrap();
    let data = TimeData::simulate(&long, 100.0, 0.25, NoiseLevel::RelativeMax(0.0), 1).unwrap();
    let model = TimeMisfit::new(data.clone()).model(&long).unwrap();
    let exact = ModalResponse::impulse(&long, 1)
        .unwrap()
        .eval_many(data.t());
    let scale = exact.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let e = model
        .iter()
        .zip(&exact)
        .fold(0.0f64, |a, (x, y)| a.max((x - y).abs()));
    assert!(e <= 1e-10 * scale, "max error {e:e} of {scale:e}");
}
