//! The data-first fit: from a measured series (simulated here, then saved and
//! read back as a user's CSV) with nothing known but n and d.

use springmass::detect::data::observations::{LaplaceValues, Observations, Series};
use springmass::detect::data::series::TimeData;
use springmass::detect::fit::{fit, DefectCount, FitMethod, FitOptions, Model, NoiseSpec, Status};
use springmass::detect::misfit::MisfitKind;
use springmass::detect::unknowns::KindChoice;
use springmass::noise::NoiseLevel;
use springmass::series::TimeSeries;
use springmass::{Chain, Complex64, Defect, Error};

fn record(truth: &Chain, t_end: f64, dt: f64, level: f64, seed: u64) -> Series {
    let d = TimeData::simulate(truth, t_end, dt, NoiseLevel::RelativeMax(level), seed).unwrap();
    Series::new(d.t().to_vec(), d.y().to_vec(), None).unwrap()
}

fn s1() -> Chain {
    Chain::paper(5)
        .unwrap()
        .with_defects([
            Defect::Mass { at: 2, m: 3.0 },
            Defect::Mass { at: 4, m: 0.5 },
        ])
        .unwrap()
}

#[test]
fn csv_round_trip_recovers_system1_with_sigma_and_k_unknown() {
    let truth = s1();
    let rec = record(&truth, 150.0, 0.25, 1e-3, 11);
    let dir = std::env::temp_dir().join(format!("springmass-fit-data-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("x1.csv");
    TimeSeries::new(rec.t().to_vec(), vec![("x1".into(), rec.x().to_vec())])
        .unwrap()
        .write_csv(&path)
        .unwrap();
    let obs = Observations::Series(Series::from_csv(&path, Some("x1"), None).unwrap());
    let opts = FitOptions {
        defects: DefectCount::Auto { k_max: 3 },
        ..FitOptions::default()
    };
    let r = fit(&obs, &Model::new(5).unwrap(), &opts).unwrap();
    eprintln!("{}", r.summary());
    assert_eq!(r.k, 2, "{}", r.summary());
    let at: Vec<usize> = r.defects.iter().map(|d| d.at).collect();
    assert_eq!(at, vec![2, 4]);
    for (d, truth) in r.defects.iter().zip([3.0, 0.5]) {
        assert!((d.value - truth).abs() < 4.0 * d.se, "{d:?}");
        assert!(d.se > 1e-8, "standard errors must reflect the noise: {d:?}");
    }
    assert!(r.noise_estimated);
    let sigma_true = 1e-3 * rec.x().iter().fold(0.0f64, |a, v| a.max(v.abs()));
    assert!(
        (r.noise_sigma / sigma_true - 1.0).abs() < 0.2,
        "{} vs {sigma_true}",
        r.noise_sigma
    );
    // k raised to 3 at most, and not past 2 where one or two more defects
    // cannot win (the answer explains the record)
    let ks: Vec<usize> = r.k_selection.iter().map(|row| row.k).collect();
    assert!(ks == [0, 1, 2] || ks == [0, 1, 2, 3], "{ks:?}");
    assert!(r.fits_data, "{}", r.summary());
    let p = r.predicted.as_ref().unwrap();
    assert_eq!(p.model.len(), rec.x().len());
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn too_few_defects_do_not_fit_the_data_and_noise_is_not_at_rounding_level() {
    let truth = s1();
    let rec = record(&truth, 150.0, 0.25, 1e-3, 5);
    let obs = Observations::Series(rec);
    // one defect where there are two: the residual is not white
    let r = fit(
        &obs,
        &Model::new(5).unwrap(),
        &FitOptions {
            defects: DefectCount::Exactly(1),
            ..FitOptions::default()
        },
    )
    .unwrap();
    assert!(!r.fits_data, "{}", r.summary());
    assert!(!r.resolved || !r.fits_data);
}

#[test]
fn bromwich_and_stochastic_methods_agree_on_system1() {
    let rec = record(&s1(), 150.0, 0.25, 1e-3, 2);
    let obs = Observations::Series(rec);
    for (misfit, method) in [
        (MisfitKind::Bromwich, FitMethod::Enumerate),
        (MisfitKind::Bromwich, FitMethod::Ga),
        (MisfitKind::Time, FitMethod::Pso),
    ] {
        let r = fit(
            &obs,
            &Model::new(5).unwrap(),
            &FitOptions {
                defects: DefectCount::Exactly(2),
                kinds: KindChoice::Mass,
                misfit: Some(misfit),
                method,
                max_evals: 3000,
                ..FitOptions::default()
            },
        )
        .unwrap();
        let at: Vec<usize> = r.defects.iter().map(|d| d.at).collect();
        assert_eq!(at, vec![2, 4], "{misfit:?} {method:?}: {}", r.summary());
    }
}

#[test]
fn laplace_values_without_errors_scale_the_standard_errors() {
    let truth = s1();
    let s: Vec<Complex64> = (1..=60)
        .map(|i| Complex64::new(0.1, 0.05 * i as f64))
        .collect();
    let fwd = springmass::forward::Forward::new(&truth);
    let values: Vec<Complex64> = s.iter().map(|z| fwd.eval(*z, 1).unwrap()).collect();
    let obs = Observations::Laplace(LaplaceValues::new(s, values, None).unwrap());
    let r = fit(
        &obs,
        &Model::new(5).unwrap(),
        &FitOptions {
            defects: DefectCount::Exactly(2),
            ..FitOptions::default()
        },
    )
    .unwrap();
    let at: Vec<usize> = r.defects.iter().map(|d| d.at).collect();
    assert_eq!(at, vec![2, 4], "{}", r.summary());
    assert!((r.defects[0].value - 3.0).abs() < 1e-6);
}

#[test]
fn any_kind_with_fitted_damping() {
    let truth = Chain::paper(5)
        .unwrap()
        .with_defect(Defect::Spring { at: 2, k: 0.5 })
        .unwrap();
    let obs = Observations::Series(record(&truth, 100.0, 0.25, 1e-3, 4));
    let model = Model::new(5)
        .unwrap()
        .with_d(0.12)
        .unwrap()
        .fitting(&springmass::detect::fit::parse_params("d").unwrap())
        .unwrap();
    let r = fit(
        &obs,
        &model,
        &FitOptions {
            defects: DefectCount::Exactly(1),
            kinds: KindChoice::Any,
            ..FitOptions::default()
        },
    )
    .unwrap();
    assert_eq!(
        (r.defects[0].kind, r.defects[0].at),
        ("spring", 2),
        "{}",
        r.summary()
    );
    let d = &r.params[0];
    assert!((d.value - 0.1).abs() < 4.0 * d.se, "{d:?}");
}

#[test]
fn bad_input_is_a_typed_error_naming_the_field() {
    let rec = record(&s1(), 50.0, 0.5, 1e-3, 1);
    let obs = Observations::Series(rec);
    let model = Model::new(5).unwrap();
    let field = |o: FitOptions, m: &Model| match fit(&obs, m, &o).unwrap_err() {
        Error::InvalidParameter { field, .. } => field,
        e => panic!("unexpected {e}"),
    };
    assert_eq!(
        field(
            FitOptions {
                defects: DefectCount::Exactly(6),
                ..FitOptions::default()
            },
            &model
        ),
        "defects"
    );
    assert_eq!(
        field(
            FitOptions {
                defects: DefectCount::Auto { k_max: 6 },
                ..FitOptions::default()
            },
            &model
        ),
        "k_max"
    );
    assert_eq!(
        field(
            FitOptions {
                method: FitMethod::Ga,
                kinds: KindChoice::Spring,
                ..FitOptions::default()
            },
            &model
        ),
        "method"
    );
    assert!(
        NoiseSpec::parse("0").is_err()
            && NoiseSpec::parse("-1").is_err()
            && NoiseSpec::parse("nan").is_err()
    );
    assert!(DefectCount::parse("many").is_err());
    let _ = Status::Converged;
}

#[test]
fn mass_defects_on_laplace_values_take_the_woodbury_kernel() {
    // System 3's X_1 on a Bromwich line with 0.1% noise and its errors: the
    // fit ranks all 190 position sets with the paper's Woodbury kernel and
    // refits the best like the enumeration; its chi-square is the misfit's
    let truth = springmass::scenes::table1(3).unwrap();
    let s: Vec<Complex64> = (0..80)
        .map(|i| Complex64::new(0.05, 0.05 * i as f64))
        .collect();
    let fwd = springmass::forward::Forward::new(&truth);
    let mut state = 7u64;
    let mut gauss = || {
        // Box-Muller on a seeded LCG (test-local, deterministic)
        let mut u = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        let (a, b) = (u(), u());
        (-2.0 * a.ln()).sqrt() * (2.0 * std::f64::consts::PI * b).cos()
    };
    let mut values = Vec::new();
    let mut sigma = Vec::new();
    for z in &s {
        let x = fwd.eval(*z, 1).unwrap();
        let e = 1e-3 * x.norm();
        values.push(x + Complex64::new(gauss(), gauss()) * e);
        sigma.push(e);
    }
    let obs = Observations::Laplace(
        LaplaceValues::new(s.clone(), values.clone(), Some(sigma.clone())).unwrap(),
    );
    let r = fit(
        &obs,
        &Model::new(20).unwrap(),
        &FitOptions {
            defects: DefectCount::Exactly(2),
            // masses: the Woodbury kernel's kind
            kinds: KindChoice::Mass,
            // the errors are absolute (not rescaled by an estimate)
            noise: NoiseSpec::Sigma(1.0),
            ..FitOptions::default()
        },
    )
    .unwrap();
    assert!(r.method.contains("Woodbury"), "{}", r.method);
    assert_eq!(r.sets_fitted, 190);
    let at: Vec<usize> = r.defects.iter().map(|d| d.at).collect();
    assert_eq!(at, vec![8, 15], "{}", r.summary());
    for (d, m) in r.defects.iter().zip([5.0, 2.0]) {
        assert!((d.value - m).abs() < 3.0 * d.se, "{d:?}");
    }
    // the reported chi-square is the data's at the fitted chain
    let fitted = truth.uniform().with_defects(r.found()).unwrap();
    let w: Vec<f64> = sigma.iter().map(|e| 1.0 / (e * e)).collect();
    let direct = springmass::detect::data::laplace::LaplaceObs::new(s, values, w)
        .unwrap()
        .chi2(&fitted)
        .unwrap();
    assert!(
        (r.chi2 - direct).abs() <= 1e-6 * direct,
        "{} vs {direct}",
        r.chi2
    );
    assert!(
        (r.chi2 - 158.0).abs() < 5.0 * (2.0f64 * 158.0).sqrt(),
        "chi2 {} for 160 values and 4 parameters",
        r.chi2
    );
}

/// Two light masses (a mass lost, not added): the coarse pass starts every
/// set from a lighter value too. From the heavy start only, the search told
/// two defects ranked the truth out of reach and returned masses at 1 and
/// 2, `model-mismatch` (found on a random record of n = 10).
#[test]
fn two_light_masses_are_found_from_the_lighter_start() {
    let truth = Chain::paper(10)
        .unwrap()
        .with_d(0.05)
        .unwrap()
        .with_defects([
            Defect::Mass { at: 2, m: 0.44 },
            Defect::Mass { at: 7, m: 0.61 },
        ])
        .unwrap();
    let obs = Observations::Series(record(&truth, 300.0, 0.1, 1e-3, 31));
    let r = fit(
        &obs,
        &Model::new(10).unwrap().with_d(0.05).unwrap(),
        &FitOptions {
            defects: DefectCount::Exactly(2),
            kinds: KindChoice::Mass,
            ..FitOptions::default()
        },
    )
    .unwrap();
    let at: Vec<usize> = r.defects.iter().map(|d| d.at).collect();
    assert_eq!(at, [2, 7], "{}", r.summary());
    assert_eq!(r.status, Status::Converged, "{}", r.summary());
    for (d, m) in r.defects.iter().zip([0.44, 0.61]) {
        assert!((d.value - m).abs() < 4.0 * d.se, "{d:?}");
    }
}
