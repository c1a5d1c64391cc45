//! Fits of real measurement setups through the data-first pipeline
//! (`detect::fit::fit`): a shear frame struck at its free roof and recorded
//! by an accelerometer, and a hammer test whose measured force replaces the
//! ideal impulse. The records are simulated by the time stepper
//! (`TimeData::simulate_measured`), independently of the fit's own models
//! (the modal sum and the exponential integrator through the force samples).

use springmass::chain::Boundary;
use springmass::detect::data::measurement::{Measurement, Sensor};
use springmass::detect::data::observations::{Observations, Series};
use springmass::detect::data::series::TimeData;
use springmass::detect::fit::{fit, DefectCount, FitOptions, Model, NoiseSpec};
use springmass::detect::misfit::MisfitKind;
use springmass::detect::unknowns::KindChoice;
use springmass::forward::Observable;
use springmass::noise::NoiseLevel;
use springmass::time::simulate::Force;
use springmass::{Chain, Defect};

const DT_HAMMER: f64 = 0.005;

fn series_of(rec: &TimeData) -> Series {
    Series::new(rec.t().to_vec(), rec.y().to_vec(), None)
        .unwrap()
        .with_measurement(rec.measurement().clone())
        .unwrap()
}

/// A 5-storey shear frame seen from its roof: mass 1 is the roof (left end
/// free), the ground is the right wall; storey j (counted from the roof) is
/// spring j, joining masses j and j + 1 (spring 5 joins the lowest floor to
/// the ground; spring 0, a left wall spring, does not exist here). Each
/// storey in turn is weakened by 20-40%;
/// the roof's acceleration at 1% noise, sigma unknown, kind unknown.
#[test]
fn shear_frame_storey_weakening_found_from_the_roof_accelerometer() {
    let weakening = [0.2, 0.3, 0.4, 0.25, 0.35];
    for (storey, &w) in (1..=5usize).zip(&weakening) {
        let spring = storey;
        let truth = Chain::paper(5)
            .unwrap()
            .with_d(0.02)
            .unwrap()
            .with_boundaries(Boundary::Free, Boundary::Fixed)
            .unwrap()
            .with_defect(Defect::Spring {
                at: spring,
                k: 1.0 - w,
            })
            .unwrap();
        let sensor = Sensor {
            at: 1,
            kind: Observable::Acceleration,
        };
        let rec = TimeData::simulate_measured(
            &truth,
            120.0,
            0.1,
            sensor,
            None,
            NoiseLevel::RelativeMax(1e-2),
            storey as u64,
        )
        .unwrap();
        let obs = Observations::Series(series_of(&rec));
        let model = Model::new(5)
            .unwrap()
            .with_d(0.02)
            .unwrap()
            .with_ends(Boundary::Free, Boundary::Fixed)
            .unwrap();
        let opts = FitOptions {
            defects: DefectCount::Exactly(1),
            kinds: KindChoice::Any,
            noise: NoiseSpec::Auto,
            ..FitOptions::default()
        };
        let r = fit(&obs, &model, &opts).unwrap();
        let d = &r.defects[0];
        assert_eq!(
            (d.kind, d.at),
            ("spring", spring),
            "storey {storey}: found {} at {} ({})",
            d.kind,
            d.at,
            r.message
        );
        let z = (d.value - (1.0 - w)) / d.se;
        assert!(
            z.abs() < 3.0,
            "storey {storey}: k = {} +- {} vs {}",
            d.value,
            d.se,
            1.0 - w
        );
        assert!(r.noise_estimated);
        assert!(r.setup.contains("acceleration") && r.setup.contains("free-fixed"));
    }
}

/// A hammer test: a half-sine force of width 0.05 on mass 1 instead of the
/// delta, recorded with the response (1% noise, sigma unknown); the defects
/// are recovered from (force, response) as from an ideal impulse, and for
/// the accelerometer, which sees `f(t)/m_1` directly, the fit that ignores
/// the measured force (the impulse model) does much worse.
///
/// The fit's force is the cubic through the samples (10 per pulse here): its
/// error at the pulse's kinks biases the mass at 3 by about 6e-4 relative
/// (measured at 1e-3 noise, where that is 12 standard errors; 4 times more at
/// 5 samples per pulse: it scales as dt^2), below the standard error at 1%
/// noise.
#[test]
fn hammer_test_recovers_the_defects_like_an_ideal_impulse() {
    let truth = Chain::paper(8)
        .unwrap()
        .with_defects([
            Defect::Mass { at: 3, m: 2.5 },
            Defect::Mass { at: 6, m: 0.5 },
        ])
        .unwrap();
    let width = 0.05;
    let peak = std::f64::consts::PI / (2.0 * width); // unit impulse
    let hammer = Force::func(move |t| {
        if (0.0..=width).contains(&t) {
            peak * (std::f64::consts::PI * t / width).sin()
        } else {
            0.0
        }
    });
    let sensor = Sensor {
        at: 1,
        kind: Observable::Displacement,
    };
    let opts = FitOptions {
        defects: DefectCount::Exactly(2),
        ..FitOptions::default()
    };
    let model = Model::new(8).unwrap();
    let check = |r: &springmass::detect::fit::FitReport, what: &str| {
        let mut got: Vec<(usize, f64, f64)> =
            r.defects.iter().map(|d| (d.at, d.value, d.se)).collect();
        got.sort_by_key(|g| g.0);
        assert_eq!(
            got.iter().map(|g| g.0).collect::<Vec<_>>(),
            vec![3, 6],
            "{what}: {got:?}"
        );
        for ((_, v, se), want) in got.iter().zip([2.5, 0.5]) {
            assert!((v - want).abs() < 3.0 * se, "{what}: {v} +- {se} vs {want}");
            assert!((v - want).abs() < 0.05 * want, "{what}: {v} vs {want}");
        }
    };
    for (kind, seed) in [(Observable::Displacement, 1), (Observable::Acceleration, 2)] {
        let sensor = Sensor { kind, ..sensor };
        // 1% of the free vibration's amplitude (the acceleration's spike
        // during the blow, f/m_1, is 30 times larger)
        let clean = TimeData::simulate_measured(
            &truth,
            60.0,
            DT_HAMMER,
            sensor,
            Some(hammer.clone()),
            NoiseLevel::Absolute(0.0),
            seed,
        )
        .unwrap();
        let amplitude = clean
            .t()
            .iter()
            .zip(clean.y())
            .filter(|(t, _)| **t > 2.0 * width)
            .fold(0.0f64, |a, (_, y)| a.max(y.abs()));
        let rec = TimeData::simulate_measured(
            &truth,
            60.0,
            DT_HAMMER,
            sensor,
            Some(hammer.clone()),
            NoiseLevel::Absolute(1e-2 * amplitude),
            seed,
        )
        .unwrap();
        assert!(rec.measurement().force().is_some());
        let forced = fit(&Observations::Series(series_of(&rec)), &model, &opts).unwrap();
        check(&forced, &format!("hammer, {kind}"));
        assert!(forced.setup.contains("measured force"));
        if kind != Observable::Acceleration {
            continue;
        }
        // the same record read as if the impulse were ideal: the model misses
        // the force's shape, which the acceleration sees directly
        let as_impulse = Series::new(rec.t().to_vec(), rec.y().to_vec(), None)
            .unwrap()
            .with_measurement(Measurement::new(1, kind))
            .unwrap();
        let naive = fit(&Observations::Series(as_impulse), &model, &opts).unwrap();
        assert!(
            naive.noise_sigma > 1.5 * forced.noise_sigma,
            "{kind}: impulse model sigma {} vs force model {}",
            naive.noise_sigma,
            forced.noise_sigma
        );
    }
    // the ideal impulse on the same chain, same noise: the reference
    let rec = TimeData::simulate_measured(
        &truth,
        60.0,
        0.05,
        sensor,
        None,
        NoiseLevel::RelativeMax(1e-2),
        3,
    )
    .unwrap();
    let ideal = fit(&Observations::Series(series_of(&rec)), &model, &opts).unwrap();
    check(&ideal, "ideal impulse");
}

/// The Bromwich chi-square alone (no time refinement) with a measured force:
/// the transform of the force multiplies the model.
#[test]
fn bromwich_misfit_with_a_measured_force() {
    let truth = Chain::paper(6)
        .unwrap()
        .with_defect(Defect::Mass { at: 4, m: 3.0 })
        .unwrap();
    let hammer = Force::func(|t| {
        if (0.0..=0.1).contains(&t) {
            (std::f64::consts::PI * t / 0.1).sin()
        } else {
            0.0
        }
    });
    let sensor = Sensor {
        at: 1,
        kind: Observable::Velocity,
    };
    let rec = TimeData::simulate_measured(
        &truth,
        80.0,
        0.02,
        sensor,
        Some(hammer),
        NoiseLevel::RelativeMax(1e-3),
        4,
    )
    .unwrap();
    let opts = FitOptions {
        defects: DefectCount::Exactly(1),
        misfit: Some(MisfitKind::Bromwich),
        ..FitOptions::default()
    };
    let r = fit(
        &Observations::Series(series_of(&rec)),
        &Model::new(6).unwrap(),
        &opts,
    )
    .unwrap();
    assert_eq!(r.defects[0].at, 4, "{}", r.message);
    assert!((r.defects[0].value - 3.0).abs() < 0.1, "{:?}", r.defects[0]);
}

#[test]
fn bad_setups_are_typed_errors() {
    let rec = TimeData::simulate(
        &Chain::paper(4).unwrap(),
        10.0,
        0.1,
        NoiseLevel::Absolute(0.0),
        0,
    )
    .unwrap();
    // a sensor beyond the chain
    let s = series_of(&rec)
        .with_measurement(Measurement::new(9, Observable::Velocity))
        .unwrap();
    let e = fit(
        &Observations::Series(s),
        &Model::new(4).unwrap(),
        &FitOptions::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("observe"), "{e}");
    // a force of the wrong length
    let e = series_of(&rec)
        .with_measurement(Measurement::paper().with_force(vec![1.0, 0.0]).unwrap())
        .unwrap_err()
        .to_string();
    assert!(e.contains("force"), "{e}");
    // a spring at the missing wall of a free end
    let e = Model::new(4)
        .unwrap()
        .with_ends(Boundary::Free, Boundary::Fixed)
        .unwrap()
        .with_known(Defect::Spring { at: 0, k: 0.5 })
        .unwrap_err()
        .to_string();
    assert!(e.contains("spring") || e.contains("at"), "{e}");
}

/// A chain in SI units (a 4-storey frame: 1000 kg floors, 2e6 N/m storeys,
/// 500 N s/m dampers), one floor 1.5 t heavier, its roof displacement
/// sampled at 200 Hz for 10 s: the fit in the data's units, with the
/// natural frequencies of the fitted chain in rad/s.
#[test]
fn fit_in_physical_units() {
    let si = |c: Chain| {
        c.with_mass(1000.0)
            .unwrap()
            .with_k(2e6)
            .unwrap()
            .with_d(500.0)
            .unwrap()
            .with_gamma(100.0)
            .unwrap()
    };
    let truth = si(Chain::paper(4).unwrap())
        .with_defect(Defect::Mass { at: 3, m: 2500.0 })
        .unwrap();
    let rec = TimeData::simulate_measured(
        &truth,
        10.0,
        0.005,
        Sensor::PAPER,
        None,
        NoiseLevel::RelativeMax(1e-2),
        5,
    )
    .unwrap();
    let model = Model::from_chain(&si(Chain::paper(4).unwrap()));
    let opts = FitOptions {
        defects: DefectCount::Exactly(1),
        ..FitOptions::default()
    };
    let r = fit(&Observations::Series(series_of(&rec)), &model, &opts).unwrap();
    let d = &r.defects[0];
    assert_eq!(d.at, 3, "{}", r.message);
    assert!(
        (d.value - 2500.0).abs() < 3.0 * d.se,
        "{} +- {}",
        d.value,
        d.se
    );
    // the fitted chain's modes against the truth's (rad/s)
    let want = springmass::time::modal::natural_modes(&truth).unwrap();
    assert_eq!(r.modes.len(), 4);
    for (m, w) in r.modes.iter().zip(&want) {
        assert!(
            (m.omega - w.omega).abs() < 1e-2 * w.omega,
            "{} vs {}",
            m.omega,
            w.omega
        );
    }
    assert!(r.modes[0].omega > 10.0 && r.modes[0].omega < 50.0);
}
