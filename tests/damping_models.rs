//! Damping models end to end: records of between-storey, Rayleigh and
//! modally damped chains from a generator of their own (the matrices assembled densely
//! from the models' definitions, the impulse response by the matrix
//! exponential of the state-space form: no code of the library's forward
//! or time paths), fitted with the defaults and `--fit d` (every damping
//! model fitted, the criterion choosing). Right positions, values within
//! 3 standard errors, the right model chosen.

use nalgebra::{DMatrix, DVector};
use springmass::detect::data::observations::{Observations, Series};
use springmass::detect::fit::fit;
use springmass::detect::fit::options::FitSpec;
use springmass::detect::fit::report::{FitReport, Status};
use springmass::noise::{add_noise, NoiseLevel};

/// The generator's damping models.
#[derive(Clone, Copy, Debug)]
enum Model {
    /// `C = d I` (a damper `d` from every mass to the ground: the paper's).
    Grounded(f64),
    /// `C = c Lap` (a damper `c` beside every spring, the walls' included).
    Between(f64),
    /// `C = a M + b K`.
    Rayleigh(f64, f64),
    /// Every undamped mode damped with one ratio:
    /// `C = M Phi diag(2 zeta omega) Phi^T M` (mass-normalised shapes).
    Modal(f64),
    /// A ratio per mode: modes 1, 2 and the rest.
    ModalPerMode([f64; 3]),
}

/// `M`, `C`, `K` of a fixed-fixed chain of unit masses and springs with
/// the mass defects `masses` (`(at, m)`, 1-based).
fn matrices(n: usize, masses: &[(usize, f64)], model: Model) -> [DMatrix<f64>; 3] {
    let mut m = DMatrix::identity(n, n);
    for &(at, v) in masses {
        m[(at - 1, at - 1)] = v;
    }
    // the Laplacian of n + 1 unit links between two walls
    let lap = DMatrix::from_fn(n, n, |i, j| match i.abs_diff(j) {
        0 => 2.0,
        1 => -1.0,
        _ => 0.0,
    });
    let c = match model {
        Model::Grounded(d) => DMatrix::identity(n, n) * d,
        Model::Between(c) => &lap * c,
        Model::Rayleigh(a, b) => &m * a + &lap * b,
        Model::Modal(zeta) => modal_c(&m, &lap, [zeta; 3]),
        Model::ModalPerMode(zeta) => modal_c(&m, &lap, zeta),
    };
    [m, c, lap]
}

/// `M Phi diag(2 zeta_j omega_j) Phi^T M` with `zeta` the ratios of
/// modes 1, 2 and the rest (in the order of the frequencies).
fn modal_c(m: &DMatrix<f64>, k: &DMatrix<f64>, zeta: [f64; 3]) -> DMatrix<f64> {
    // M^-1/2 K M^-1/2 = Q diag(omega^2) Q^T, Phi = M^-1/2 Q
    let mh = DMatrix::from_diagonal(&m.diagonal().map(|v| 1.0 / v.sqrt()));
    let eig = (&mh * k * &mh).symmetric_eigen();
    let phi = &mh * &eig.eigenvectors;
    let mut rank: Vec<usize> = (0..eig.eigenvalues.len()).collect();
    rank.sort_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]));
    let mut w = eig.eigenvalues.clone();
    for (r, &i) in rank.iter().enumerate() {
        w[i] = 2.0 * zeta[r.min(2)] * eig.eigenvalues[i].sqrt();
    }
    m * &phi * DMatrix::from_diagonal(&w) * phi.transpose() * m
}

/// `x_1(i dt)`, `i < samples`, after a unit impulse on mass 1, plus white
/// noise of `level` times the largest `|x_1|`.
fn record(
    n: usize,
    masses: &[(usize, f64)],
    model: Model,
    (dt, samples): (f64, usize),
    level: f64,
    seed: u64,
) -> Observations {
    let [m, c, k] = matrices(n, masses, model);
    let minv = m.try_inverse().unwrap();
    let mut a = DMatrix::zeros(2 * n, 2 * n);
    a.view_mut((0, n), (n, n)).fill_with_identity();
    a.view_mut((n, 0), (n, n)).copy_from(&(-(&minv * k)));
    a.view_mut((n, n), (n, n)).copy_from(&(-(&minv * c)));
    let e = (a * dt).exp();
    let mut y = DVector::zeros(2 * n);
    y[n] = minv[(0, 0)];
    let mut x = Vec::with_capacity(samples);
    for _ in 0..samples {
        x.push(y[0]);
        y = &e * y;
    }
    let (x, _) = add_noise(&x, NoiseLevel::RelativeMax(level), seed).unwrap();
    let t = (0..samples).map(|i| i as f64 * dt).collect();
    Observations::Series(Series::new(t, x, None).unwrap())
}

/// Fit with the defaults and `fit = d` (model chosen) or `damping` given.
fn check(
    n: usize,
    masses: &[(usize, f64)],
    model: Model,
    level: f64,
    seed: u64,
    damping: Option<&str>,
) -> FitReport {
    let grid = if n > 10 { (0.5, 401) } else { (0.5, 241) };
    let obs = record(n, masses, model, grid, level, seed);
    let spec = FitSpec {
        fit: Some("d".into()),
        damping: damping.map(str::to_string),
        ..FitSpec::new(n)
    };
    let (m, opts) = spec.build().unwrap();
    let r = fit(&obs, &m, &opts).unwrap();
    let what = format!("{model:?} at {level}, seed {seed}:\n{}", r.summary());
    let at: Vec<usize> = r.found().iter().map(|d| d.at()).collect();
    let want: Vec<usize> = masses.iter().map(|p| p.0).collect();
    assert_eq!(at, want, "{what}");
    for (d, &(_, v)) in r.defects.iter().zip(masses) {
        assert!((d.value - v).abs() < 3.0 * d.se, "{d:?}: {what}");
    }
    let est = r.damping.as_ref().expect("a damping entry");
    let truth: Vec<(&str, f64)> = match model {
        Model::Grounded(d) => vec![("d", d)],
        Model::Between(c) => vec![("c", c)],
        Model::Rayleigh(a, b) => vec![("a", a), ("b", b)],
        Model::Modal(zeta) => vec![("zeta", zeta)],
        Model::ModalPerMode(z) => vec![("zeta_1", z[0]), ("zeta_2", z[1]), ("zeta_3", z[2])],
    };
    let name = match model {
        Model::Grounded(_) => "grounded",
        Model::Between(_) => "between",
        Model::Rayleigh(..) => "rayleigh",
        Model::Modal(_) | Model::ModalPerMode(_) => "modal",
    };
    assert_eq!(est.model, name, "{what}");
    assert!(est.fitted);
    for (p, v) in truth {
        let (got, se) = (est.values[p], est.se[p]);
        assert!(
            se > 0.0 && (got - v).abs() < 3.0 * se,
            "{p} = {got} +- {se}: {what}"
        );
    }
    if damping.is_none() {
        chosen_as_every_model_searched(&obs, &r, &at, n, &what);
    }
    r
}

/// The damping choice of `r` (`fit = d`): every model listed; a model
/// fitted only at the chosen set (not searched) is fitted at the answer's
/// positions and does no better there; and searching every model
/// (`--effort high`) chooses the same model and set. The answer `at`.
fn chosen_as_every_model_searched(
    obs: &Observations,
    r: &FitReport,
    at: &[usize],
    n: usize,
    what: &str,
) {
    let est = r.damping.as_ref().unwrap();
    assert_eq!(est.candidates.len(), 4, "{what}");
    let chosen = est
        .candidates
        .iter()
        .find(|c| c.model == est.model)
        .unwrap();
    assert!(chosen.searched, "{what}");
    for c in est.candidates.iter().filter(|c| !c.searched) {
        assert_eq!(c.positions, at, "{c:?}: {what}");
        assert!(c.criterion >= chosen.criterion, "{c:?}: {what}");
    }
    let spec = FitSpec {
        fit: Some("d".into()),
        effort: Some("high".into()),
        ..FitSpec::new(n)
    };
    let (m, opts) = spec.build().unwrap();
    let every = fit(obs, &m, &opts).unwrap();
    let e = every.damping.as_ref().unwrap();
    assert!(e.candidates.iter().all(|c| c.searched), "{what}");
    assert_eq!(e.model, est.model, "{what}\n{}", every.summary());
    let at_every: Vec<usize> = every.found().iter().map(|d| d.at()).collect();
    assert_eq!(at_every, at, "{what}\n{}", every.summary());
}

const SYSTEM: [(usize, f64); 2] = [(2, 3.0), (4, 0.5)];

#[test]
fn grounded_records_are_fitted_and_the_others_only_at_their_set() {
    for (level, seed) in [(1e-3, 13), (1e-2, 15)] {
        let r = check(5, &SYSTEM, Model::Grounded(0.1), level, seed, None);
        // the first model searched explains the record: the others are
        // fitted at its set only
        let searched: Vec<bool> = r
            .damping
            .unwrap()
            .candidates
            .iter()
            .map(|c| c.searched)
            .collect();
        assert_eq!(searched, [true, false, false, false]);
    }
}

#[test]
fn rayleigh_records_are_fitted_and_the_model_chosen() {
    for (level, seed) in [(1e-3, 1), (1e-2, 2)] {
        check(5, &SYSTEM, Model::Rayleigh(0.05, 0.02), level, seed, None);
    }
}

#[test]
fn between_storey_records_are_fitted_and_the_model_chosen() {
    for (level, seed) in [(1e-3, 3), (1e-2, 4)] {
        check(5, &SYSTEM, Model::Between(0.05), level, seed, None);
    }
}

#[test]
fn modally_damped_records_are_fitted_and_the_model_chosen() {
    for (level, seed) in [(1e-3, 7), (1e-2, 8)] {
        check(5, &SYSTEM, Model::Modal(0.03), level, seed, None);
    }
}

#[test]
fn a_given_model_with_its_parameters_fitted() {
    check(
        5,
        &SYSTEM,
        Model::Rayleigh(0.05, 0.02),
        1e-2,
        5,
        Some("rayleigh"),
    );
    check(5, &SYSTEM, Model::Between(0.05), 1e-2, 6, Some("between"));
    check(5, &SYSTEM, Model::Modal(0.02), 1e-2, 9, Some("modal"));
}

/// The Rayleigh model given with its parameters fitted from the start
/// scaled from the chain (`--d 0`: no grounded damping to scale from), on
/// a heavily damped System 1 record (a = b = 0.05) at 0.1% noise: from
/// that start the search's fit of the true two masses stopped at a
/// chi-square of 1.3e5, and the criterion took three defects (a damper or
/// a spring beside the masses); the fit at two defects is now made no
/// worse than the three-defect answer with one dropped, refitted from its
/// values.
#[test]
fn a_given_model_fitted_from_a_start_far_from_the_record() {
    let obs = record(
        5,
        &SYSTEM,
        Model::Rayleigh(0.05, 0.05),
        (0.2, 1001),
        1e-3,
        1,
    );
    let spec = FitSpec {
        fit: Some("d".into()),
        damping: Some("rayleigh".into()),
        d: Some(0.0),
        ..FitSpec::new(5)
    };
    let (m, opts) = spec.build().unwrap();
    let r = fit(&obs, &m, &opts).unwrap();
    let what = r.summary();
    let found: Vec<String> = r.found().iter().map(springmass::Defect::place).collect();
    assert_eq!(found, ["mass@2", "mass@4"], "{what}");
    assert_eq!(r.status, Status::Converged, "{what}");
    for (d, &(_, v)) in r.defects.iter().zip(&SYSTEM) {
        assert!((d.value - v).abs() < 3.0 * d.se, "{d:?}: {what}");
    }
}

#[test]
fn a_ratio_per_mode_is_fitted_from_its_starting_values() {
    // modes 1, 2 and 3..5 with their own ratios, fitted from 2% each
    for (level, seed) in [(1e-3, 11), (1e-2, 12)] {
        check(
            5,
            &SYSTEM,
            Model::ModalPerMode([0.01, 0.04, 0.02]),
            level,
            seed,
            Some("modal:0.02,0.02,0.02"),
        );
    }
}

#[test]
fn a_model_that_needs_a_parameter_neither_given_nor_fitted_is_refused() {
    let spec = FitSpec {
        damping: Some("rayleigh:0.01".into()),
        ..FitSpec::new(5)
    };
    match spec.build() {
        Err(springmass::Error::InvalidParameter { field, allowed, .. }) => {
            assert_eq!(field, "damping");
            assert!(
                allowed.contains('b') && allowed.contains("--fit d"),
                "{allowed}"
            );
        }
        other => panic!("{other:?}"),
    }
    let spec = FitSpec {
        damping: Some("between:-0.1".into()),
        ..FitSpec::new(5)
    };
    match spec.build() {
        Err(springmass::Error::InvalidParameter { field, allowed, .. }) => {
            assert_eq!(field, "damping.c");
            assert!(allowed.contains(">= 0"), "{allowed}");
        }
        other => panic!("{other:?}"),
    }
}

/// The larger grid: n = 20 with the paper's defects, 0.1% and 1% noise,
/// ten seeds per model (minutes).
#[test]
#[ignore]
fn larger_grid_of_seeds() {
    let paper = [(8, 5.0), (15, 2.0)];
    for seed in 0..10 {
        for level in [1e-3, 1e-2] {
            check(20, &paper, Model::Rayleigh(0.05, 0.01), level, seed, None);
            check(20, &paper, Model::Between(0.05), level, 100 + seed, None);
            check(20, &paper, Model::Modal(0.02), level, 200 + seed, None);
        }
    }
}

/// A Rayleigh-damped record fitted with the between-storey model given:
/// the residual of the wrong model took the largest AR noise model, whose
/// coefficients never settled, and the report said `converged` at wrong
/// positions (8 and 13). It must not be called converged or resolved:
/// two masses sought (a mismatch, the AR model unsettled), two defects of
/// any kind (a mismatch: the model given is checked against the others
/// with white noise, and Rayleigh explains the record), or the defaults
/// (every kind, their number by the criterion).
#[test]
fn a_wrong_damping_model_given_is_not_called_converged() {
    let paper = [(8, 5.0), (15, 2.0)];
    for seed in [1, 2] {
        let obs = record(
            20,
            &paper,
            Model::Rayleigh(0.05, 0.01),
            (0.5, 401),
            1e-2,
            seed,
        );
        for (kinds, defects) in [("mass", Some("2")), ("any", Some("2")), ("any", None)] {
            let spec = FitSpec {
                fit: Some("d".into()),
                damping: Some("between".into()),
                defects: defects.map(str::to_string),
                kinds: Some(kinds.into()),
                ..FitSpec::new(20)
            };
            let (m, opts) = spec.build().unwrap();
            let r = fit(&obs, &m, &opts).unwrap();
            let at: Vec<usize> = r.found().iter().map(|d| d.at()).collect();
            let what = format!("seed {seed}, kinds {kinds}: {at:?}\n{}", r.summary());
            assert!(!r.resolved, "{what}");
            assert_ne!(r.status, Status::Converged, "{what}");
            if kinds == "mass" {
                assert_eq!(r.status, Status::ModelMismatch, "{what}");
                assert!(r.message.contains("did not settle"), "{what}");
            }
            // every kind sought with two defects: a damper beside a mass
            // and an AR(4) noise model took up the wrong damping's misfit
            // (a damper at 8 and a mass at 9, `converged`, for seed 2);
            // the Rayleigh model explains the record with white noise
            if kinds == "any" && defects.is_some() {
                assert_eq!(r.status, Status::ModelMismatch, "{what}");
                assert!(
                    r.message
                        .contains("rayleigh damping explains it with white noise (mass@8, mass@15"),
                    "{what}"
                );
                let d = r.damping.as_ref().expect("the damping entry");
                assert!(d.checked && d.model == "between", "{what}");
                assert!(d.candidates.iter().any(|c| c.model == "rayleigh"), "{what}");
            }
        }
    }
}
