//! Whole-profile inversion (`detect::fit::profile`): every mass or every
//! spring of a chain from one end's response, with standard errors and the
//! visibility report. The data are independent of the fit's model: exact
//! Laplace values by the tridiagonal solve (`forward::tridiag`), records by
//! the time stepper (`TimeData::simulate_measured`).

use num_complex::Complex64;
use springmass::chain::Boundary;
use springmass::detect::data::measurement::Sensor;
use springmass::detect::data::observations::{LaplaceValues, Observations, Series};
use springmass::detect::data::series::TimeData;
use springmass::detect::fit::fit_profile;
use springmass::detect::fit::profile::{ProfileMode, ProfileOptions};
use springmass::detect::fit::{Model, NoiseSpec};
use springmass::forward::Observable;
use springmass::noise::{add_noise, NoiseLevel};
use springmass::{scenes, Chain, Defect};

/// Laplace values of `truth` on the line `sigma_b + i omega`, `q` nodes
/// over `omega in (0, w)`, by the O(n) tridiagonal solve.
fn laplace_values(
    truth: &Chain,
    q: usize,
    sigma_b: f64,
    w: f64,
) -> (Vec<Complex64>, Vec<Complex64>) {
    let s: Vec<Complex64> = (0..q)
        .map(|i| Complex64::new(sigma_b, w * (i as f64 + 0.5) / q as f64))
        .collect();
    let x = s
        .iter()
        .map(|z| springmass::forward::tridiag::solve(truth, *z, 1).unwrap())
        .collect();
    (s, x)
}

/// n = 100, noise-free: every mass within 1e-6 relative.
#[test]
#[ignore = "heavy (long chains): run by .ci/run; cargo test --test all -- --ignored heavy"]
fn heavy_profile_of_100_masses_from_exact_values() {
    let n = 100;
    let m = scenes::mass_profile(n);
    let truth = scenes::profile_chain(n, 0.01).unwrap();
    let (s, x) = laplace_values(&truth, 300, 0.01, 3.0);
    let obs = Observations::Laplace(LaplaceValues::new(s, x, None).unwrap());
    let model = Model::new(n).unwrap().with_d(0.01).unwrap();
    let opts = ProfileOptions {
        noise: NoiseSpec::Sigma(1e-13),
        ..ProfileOptions::new(ProfileMode::Masses)
    };
    let p = fit_profile(&obs, &model, &opts).unwrap();
    let worst = p
        .elements
        .iter()
        .map(|e| ((e.value - m[e.at - 1]) / m[e.at - 1]).abs())
        .fold(0.0f64, f64::max);
    assert!(
        worst < 1e-6,
        "worst relative error {worst:e}\n{}",
        p.summary()
    );
    assert_eq!(p.visible_count(), n, "{}", p.summary());
}

/// n = 100 at 1e-3 noise: the standard errors are calibrated (the truth
/// within 2 SE for at least 90% of the visible masses over ten draws:
/// neighbouring estimates are strongly correlated, so fewer draws say
/// little; measured 92.5% of 385 over twelve),
/// and the deep masses the damping hides are reported as not visible.
#[test]
#[ignore = "heavy (long chains): run by .ci/run; cargo test --test all -- --ignored heavy"]
fn heavy_profile_of_100_masses_at_1e_3_noise_has_calibrated_errors() {
    let n = 100;
    let m = scenes::mass_profile(n);
    let truth = scenes::profile_chain(n, 0.1).unwrap();
    let (s, x) = laplace_values(&truth, 300, 0.02, 3.0);
    let scale = x.iter().fold(0.0f64, |a, v| a.max(v.norm()));
    let sigma = 1e-3 * scale;
    let (mut within, mut visible) = (0usize, 0usize);
    for seed in 0..10u64 {
        let flat: Vec<f64> = x.iter().flat_map(|v| [v.re, v.im]).collect();
        let (y, _) = add_noise(&flat, NoiseLevel::Absolute(sigma), seed).unwrap();
        let noisy: Vec<Complex64> = y.chunks(2).map(|c| Complex64::new(c[0], c[1])).collect();
        let obs = Observations::Laplace(
            LaplaceValues::new(s.clone(), noisy, Some(vec![sigma; s.len()])).unwrap(),
        );
        let model = Model::new(n).unwrap();
        let p = fit_profile(&obs, &model, &ProfileOptions::new(ProfileMode::Masses)).unwrap();
        for e in p.elements.iter().filter(|e| e.visible) {
            visible += 1;
            if (e.value - m[e.at - 1]).abs() <= 2.0 * e.se {
                within += 1;
            }
        }
        assert!(p.visible_count() >= 5, "{}", p.summary());
        assert!(
            p.visible_count() < n,
            "deep masses cannot be visible at d = 0.1\n{}",
            p.summary()
        );
        // visible values form the prefix nearest the sensor
        let depth = p.visible_depth.unwrap();
        assert!(p.elements.iter().all(|e| e.visible == (e.depth <= depth)));
        assert!(p.message.contains("cannot see"), "{}", p.message);
    }
    let frac = within as f64 / visible as f64;
    assert!(
        frac >= 0.9,
        "{within} of {visible} visible masses within 2 SE"
    );
}

/// A six-storey shear frame seen from its roof (left end free, roof
/// accelerometer, ideal hammer impulse), every storey stiffness changed by
/// -25% to +5%, 1% noise, noise level unknown: all six storey stiffnesses
/// within 1% in each of six records, with calibrated standard errors.
#[test]
fn six_storey_frame_every_storey_stiffness_from_the_roof() {
    let change = scenes::FRAME6_CHANGE;
    let truth = scenes::frame6().unwrap();
    let sensor = Sensor {
        at: 1,
        kind: Observable::Acceleration,
    };
    let mut z = Vec::new();
    for seed in 1..=6u64 {
        let rec = TimeData::simulate_measured(
            &truth,
            200.0,
            0.1,
            sensor,
            None,
            NoiseLevel::RelativeMax(1e-2),
            seed,
        )
        .unwrap();
        let series = Series::new(rec.t().to_vec(), rec.y().to_vec(), None)
            .unwrap()
            .with_measurement(rec.measurement().clone())
            .unwrap();
        let model = Model::new(6)
            .unwrap()
            .with_d(0.02)
            .unwrap()
            .with_ends(Boundary::Free, Boundary::Fixed)
            .unwrap();
        let p = fit_profile(
            &Observations::Series(series),
            &model,
            &ProfileOptions::new(ProfileMode::Springs),
        )
        .unwrap();
        assert_eq!(p.elements.len(), 6, "{}", p.summary());
        assert!(p.noise_estimated);
        assert!(p.misfit.starts_with("time"), "{}", p.misfit);
        for e in &p.elements {
            let k = 1.0 + change[e.at - 1];
            assert!(e.visible, "{}", p.summary());
            assert!(
                ((e.value - k) / k).abs() < 0.01,
                "seed {seed}: storey {} k = {} vs {k}\n{}",
                e.at,
                e.value,
                p.summary()
            );
            z.push((e.value - k) / e.se);
        }
    }
    // calibrated: the rms of (estimate - truth) / SE near 1 over 36 values
    // (measured 1.14 over 72 with the noise level given), none far out
    let rms = (z.iter().map(|v| v * v).sum::<f64>() / z.len() as f64).sqrt();
    assert!((0.6..=1.5).contains(&rms), "rms z = {rms}: {z:?}");
    assert!(z.iter().all(|v| v.abs() < 4.5), "{z:?}");
}

/// The defect fit's report says how deep the data see: a 100-mass chain
/// (d = 0.1, 1e-3 noise, t = 0..300) sees a 10% mass change only a few
/// dozen masses deep, and a fitted defect beyond that depth is named.
#[test]
fn defect_fit_reports_how_deep_the_data_see() {
    use springmass::detect::fit::{fit, DefectCount, FitOptions};
    let truth = Chain::paper(100)
        .unwrap()
        .with_defects([
            Defect::Mass { at: 10, m: 2.0 },
            Defect::Mass { at: 70, m: 2.0 },
        ])
        .unwrap();
    let rec = TimeData::simulate(&truth, 300.0, 0.2, NoiseLevel::RelativeMax(1e-3), 5).unwrap();
    let series = Series::new(rec.t().to_vec(), rec.y().to_vec(), None).unwrap();
    let opts = FitOptions {
        defects: DefectCount::Exactly(2),
        ..FitOptions::default()
    };
    let r = fit(
        &Observations::Series(series),
        &Model::new(100).unwrap(),
        &opts,
    )
    .unwrap();
    let v = r.visibility.as_ref().expect("a visibility report");
    let depth = v.depth.expect("the first masses are seen");
    assert!((10..60).contains(&depth), "{}", v.line());
    assert_eq!(v.se.len(), 100);
    // standard errors grow with depth (the echo decays)
    assert!(v.se[80] > 10.0 * v.se[5], "{:?}", &v.se[..10]);
    for d in r.found() {
        assert_eq!(
            v.hidden.contains(&d.at()),
            d.at() > depth + 1,
            "{}",
            v.line()
        );
    }
    assert!(r.summary().contains("visibility: "));
}

/// `--profile both`: with the chain's known damping to the ground, one end's
/// record separates every mass from every spring (an 8-mass chain, a
/// heavier and a lighter mass and a softer spring, 1e-3 noise, four
/// records): every value visible, within 2.5% and calibrated. Undamped, the
/// record has one direction too few (n poles and n residues for 2n + 1
/// values): the report then names a value it cannot see.
#[test]
fn profile_both_separates_masses_from_springs_when_damped() {
    let truth = Chain::paper(8)
        .unwrap()
        .with_defects([
            Defect::Mass { at: 2, m: 1.3 },
            Defect::Spring { at: 4, k: 0.8 },
            Defect::Mass { at: 6, m: 0.8 },
        ])
        .unwrap();
    let (masses, springs) = (truth.masses(), truth.springs());
    let mut z = Vec::new();
    for seed in 1..=4u64 {
        let rec =
            TimeData::simulate(&truth, 300.0, 0.1, NoiseLevel::RelativeMax(1e-3), seed).unwrap();
        let series = Series::new(rec.t().to_vec(), rec.y().to_vec(), None).unwrap();
        let p = fit_profile(
            &Observations::Series(series),
            &Model::new(8).unwrap(),
            &ProfileOptions::new(ProfileMode::Both),
        )
        .unwrap();
        assert_eq!(p.elements.len(), 17, "{}", p.summary());
        for e in &p.elements {
            let t = if e.kind == "mass" {
                masses[e.at - 1]
            } else {
                springs[e.at]
            };
            assert!(e.visible, "seed {seed}\n{}", p.summary());
            assert!(
                ((e.value - t) / t).abs() < 0.025,
                "seed {seed}: {} {}\n{}",
                e.kind,
                e.at,
                p.summary()
            );
            z.push((e.value - t) / e.se);
        }
    }
    let within = z.iter().filter(|v| v.abs() <= 2.0).count();
    assert!(
        within * 10 >= z.len() * 9,
        "{within} of {} within 2 SE: {z:?}",
        z.len()
    );
    // undamped: one value is reported as not visible
    let undamped = truth.clone().with_d(0.0).unwrap();
    let rec = TimeData::simulate(&undamped, 300.0, 0.1, NoiseLevel::RelativeMax(1e-6), 2).unwrap();
    let p = fit_profile(
        &Observations::Series(Series::new(rec.t().to_vec(), rec.y().to_vec(), None).unwrap()),
        &Model::new(8).unwrap().with_d(0.0).unwrap(),
        &ProfileOptions::new(ProfileMode::Both),
    )
    .unwrap();
    assert!(p.elements.iter().any(|e| !e.visible), "{}", p.summary());
}
