//! Records with what a real sensor adds (issue 27, items 2, 3 and 6):
//! coloured noise (AR(1), rho 0.9 and 0.99) and a sensor offset with a slow
//! drift, fitted with the defaults. The generator is independent of the
//! fitted model's code path: the chain's equations of motion
//! `M x'' + D x' + K x = 0`, `x'(0) = gamma / m_1 e_1`, assembled here from
//! `chain.coefficients()` and stepped exactly by the dense state-space
//! matrix exponential (nalgebra's `exp`), not by the modal sum the fit uses;
//! the noise comes from its own seeded ChaCha8 generator.
//!
//! The checks: positions right, every value within 3 standard errors, and
//! never `converged` (nor `resolved`) with wrong positions. The grid over
//! more seeds is `#[ignore]`d (`cargo test --release --test all
//! realistic_noise -- --ignored`).

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use springmass::detect::data::observations::{Observations, Series};
use springmass::detect::fit::{fit, FitOptions, FitReport, Model, Status};
use springmass::{scenes, Chain};

/// `x_1(t_i)` of `truth` after the impulse on `0, dt, ..., t_end`, by the
/// dense state-space matrix exponential.
fn clean_record(truth: &Chain, t_end: f64, dt: f64) -> (Vec<f64>, Vec<f64>) {
    let (t, mut x) = crate::dense::records(truth, &[1], t_end, dt);
    (t, x.remove(0))
}

/// What the sensor adds.
#[derive(Clone, Copy, Debug)]
enum Deviation {
    /// AR(1) noise with this coefficient, stationary from the first sample.
    Ar(f64),
    /// White noise, an offset of 2% of the peak and a drift of 2% of the
    /// peak over the record.
    OffsetDrift,
}

/// The record of `truth` with noise of `level` times its peak (the
/// process's marginal standard deviation) and the deviation.
fn record(truth: &Chain, level: f64, dev: Deviation, seed: u64) -> Observations {
    let (t, x) = clean_record(truth, 200.0, 0.2);
    let peak = x.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let sd = level * peak;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let rho = match dev {
        Deviation::Ar(rho) => rho,
        Deviation::OffsetDrift => 0.0,
    };
    let innov = Normal::new(0.0, sd * (1.0 - rho * rho).sqrt()).unwrap();
    let mut e = Normal::new(0.0, sd).unwrap().sample(&mut rng);
    let t_end = t[t.len() - 1];
    let y: Vec<f64> = t
        .iter()
        .zip(&x)
        .map(|(&ti, xi)| {
            let v = xi + e;
            e = rho * e + innov.sample(&mut rng);
            match dev {
                Deviation::Ar(_) => v,
                Deviation::OffsetDrift => v + 0.02 * peak * (1.0 + ti / t_end),
            }
        })
        .collect();
    Observations::Series(Series::new(t, y, None).unwrap())
}

/// Table 1's System 3 style chain: n = 20, masses 5 at 8 and 2 at 15.
fn system3() -> Chain {
    scenes::paper_with(20, "mass:8:5 mass:15:2").unwrap()
}

fn defaults(obs: &Observations, n: usize, kinds: Option<&str>) -> FitReport {
    let spec = springmass::detect::fit::options::FitSpec {
        kinds: kinds.map(str::to_string),
        ..springmass::detect::fit::options::FitSpec::new(n)
    };
    let (model, opts): (Model, FitOptions) = spec.build().unwrap();
    fit(obs, &model, &opts).unwrap()
}

/// Whether the report's positions and kinds are the truth's, and every
/// value within 3 standard errors of it.
fn right(r: &FitReport, truth: &Chain) -> (bool, bool) {
    let mut want: Vec<(String, usize, f64)> = truth
        .defects()
        .iter()
        .map(|d| (d.kind().to_string(), d.at(), d.value()))
        .collect();
    want.sort_by_key(|w| w.1);
    let mut got: Vec<_> = r.defects.iter().collect();
    got.sort_by_key(|d| d.at);
    let positions = got.len() == want.len()
        && got
            .iter()
            .zip(&want)
            .all(|(g, w)| g.kind == w.0 && g.at == w.1);
    let values = positions
        && got
            .iter()
            .zip(&want)
            .all(|(g, w)| (g.value - w.2).abs() <= 3.0 * g.se);
    (positions, values)
}

/// One case: positions right, values within 3 SE, and the status honest.
fn check(truth: &Chain, level: f64, dev: Deviation, seed: u64, kinds: Option<&str>) {
    let r = defaults(&record(truth, level, dev, seed), truth.n(), kinds);
    let (positions, values) = right(&r, truth);
    let case = format!("{dev:?} at {level}, seed {seed}:\n{}", r.summary());
    assert!(positions, "positions: {case}");
    assert!(values, "values: {case}");
    assert!(r.whiteness_p.is_some(), "{case}");
}

/// Never `converged` or `resolved` with wrong positions.
fn honest(truth: &Chain, r: &FitReport) -> bool {
    right(r, truth).0 || (r.status != Status::Converged && !r.resolved)
}

#[test]
fn ar_noise_rho_0_9_at_one_percent() {
    check(&system3(), 1e-2, Deviation::Ar(0.9), 1, None);
}

#[test]
fn ar_noise_rho_0_99_at_one_percent() {
    check(&system3(), 1e-2, Deviation::Ar(0.99), 2, None);
}

#[test]
fn offset_and_drift_at_one_percent() {
    let truth = system3();
    let r = defaults(&record(&truth, 1e-2, Deviation::OffsetDrift, 3), 20, None);
    assert!(right(&r, &truth).1, "{}", r.summary());
    let names: Vec<&str> = r.nuisance.iter().map(|n| n.name).collect();
    assert_eq!(names, vec!["offset", "drift"], "{}", r.summary());
    // the offset at t = 0 is 2% of the peak (0.0246 for System 3's chain)
    let peak = clean_record(&truth, 200.0, 0.2)
        .1
        .iter()
        .fold(0.0f64, |a, v| a.max(v.abs()));
    let off = &r.nuisance[0];
    assert!(
        (off.value - 0.02 * peak).abs() < 4.0 * off.se,
        "{}",
        r.summary()
    );
}

/// The right damping model given (`--damping grounded --fit d`) on a
/// record of genuinely coloured noise: the fit needs an AR model, so it is
/// checked against the other damping models fitted with white noise; none
/// explains the record, so the answer stands (right, not a mismatch), and
/// the report lists the models checked.
#[test]
fn the_right_damping_model_given_survives_the_check_under_coloured_noise() {
    let truth = system3();
    let obs = record(&truth, 1e-3, Deviation::Ar(0.9), 1);
    let spec = springmass::detect::fit::options::FitSpec {
        fit: Some("d".into()),
        damping: Some("grounded".into()),
        ..springmass::detect::fit::options::FitSpec::new(20)
    };
    let (model, opts) = spec.build().unwrap();
    let r = fit(&obs, &model, &opts).unwrap();
    let case = r.summary();
    assert!(right(&r, &truth).1, "{case}");
    assert_ne!(r.status, Status::ModelMismatch, "{case}");
    let d = r
        .damping
        .as_ref()
        .expect("the damping entry of a checked fit");
    assert!(d.checked, "{case}");
    let mut checked: Vec<&str> = d.candidates.iter().map(|c| c.model.as_str()).collect();
    checked.sort_unstable();
    assert_eq!(checked, ["between", "modal", "rayleigh"], "{case}");
    assert!(case.contains("given, and checked against"), "{case}");
}

#[test]
fn spring_defect_under_ar_noise() {
    let truth = scenes::paper_with(10, "spring:4:0.5").unwrap();
    check(&truth, 1e-3, Deviation::Ar(0.9), 4, Some("spring"));
}

/// An honest report that says a further defect could hide.
fn hidden_named(truth: &Chain, r: &FitReport) {
    assert!(honest(truth, r), "{}", r.summary());
    assert_eq!(r.status, Status::NotIdentifiable, "{}", r.summary());
    let said = r.message.contains("would not show a further defect");
    assert!(said, "{}", r.summary());
}

/// System 3 under AR(0.9) noise at 1% (a record of the study generator,
/// `springmass::study::realistic`, whose seed made the fit report one
/// defect as `converged`): the noise hides the far half of the chain, so
/// the answer, right or wrong, is not called complete, and the report names
/// the masses a further defect could hide at.
#[test]
fn a_defect_the_coloured_noise_hides_is_not_called_converged() {
    use springmass::study::realistic::{record, Deviations};
    let truth = system3();
    let dev = Deviations::named("ar1-0.9", 1.0).unwrap();
    let (t, x) = record(&truth, &dev, 200.0, 0.2, 1e-2, 1_163_048_740_634_525_917).unwrap();
    let obs = Observations::Series(Series::on_axis(t, x, None).unwrap());
    let r = defaults(&obs, 20, None);
    hidden_named(&truth, &r);
    assert!(r.message.contains("mass 13"), "{}", r.summary());
    let u = r.unseen.as_ref().expect("the check ran");
    assert!(
        u.elements.iter().any(|e| e.kind == "mass" && e.at == 13),
        "{u:?}"
    );
    // every mass and spring the answer leaves unchanged (every kind sought)
    assert_eq!((u.checked, u.of), (40, 40), "{u:?}");
}

/// With little noise every mass of a short chain shows: the check leaves
/// a right answer `converged`; with much noise on a longer chain the far
/// masses do not show, and the report says which.
#[test]
fn the_check_for_hidden_defects_follows_the_noise() {
    let truth = scenes::paper_with(8, "mass:3:2").unwrap();
    let r = defaults(&record(&truth, 1e-4, Deviation::Ar(0.0), 6), 8, None);
    assert!(right(&r, &truth).1, "{}", r.summary());
    assert_eq!(r.status, Status::Converged, "{}", r.summary());
    let truth = scenes::paper_with(40, "mass:3:2").unwrap();
    let obs = record(&truth, 1e-1, Deviation::Ar(0.0), 6);
    let r = defaults(&obs, 40, Some("mass"));
    hidden_named(&truth, &r);
    assert!(r.message.contains("-40"), "{}", r.summary());
    // every kind sought (the default): the mass at 3 barely shows at 10%
    // noise, and this record's answer is a spring there (14.8 +- 14.3, the
    // mass at 3 within a chi-square of 3.7): not sure either way
    let r = defaults(&obs, 40, None);
    assert!(
        r.status != Status::Converged && !r.resolved,
        "{}",
        r.summary()
    );
}

/// A white-noise record keeps the white model, no nuisance, and the
/// answer of the paper's record model.
#[test]
fn white_noise_record_keeps_the_white_answer() {
    use springmass::detect::data::nuisance::Nuisance;
    use springmass::detect::fit::record::{NoiseModelChoice, NuisanceChoice};
    let truth = scenes::paper_with(10, "mass:3:3 mass:7:2").unwrap();
    let obs = record(&truth, 1e-2, Deviation::Ar(0.0), 5);
    let r = defaults(&obs, 10, None);
    assert_eq!(r.noise_model.as_ref().map(|m| m.kind), Some("white"));
    assert!(r.nuisance.is_empty() && r.fits_data, "{}", r.summary());
    assert!(right(&r, &truth).1, "{}", r.summary());
    let (model, opts) = springmass::detect::fit::options::FitSpec::new(10)
        .build()
        .unwrap();
    let paper = FitOptions {
        noise_model: NoiseModelChoice::White,
        nuisance: NuisanceChoice::Fixed(Nuisance::None),
        ..opts
    };
    let p = fit(&obs, &model, &paper).unwrap();
    assert_eq!(p.found().len(), r.found().len());
    for (a, b) in p.defects.iter().zip(&r.defects) {
        assert_eq!(a.at, b.at);
        assert!((a.value - b.value).abs() <= 1e-12 * b.value.abs());
        assert!((a.se - b.se).abs() <= 1e-12 * b.se.abs());
    }
    assert!((p.chi2 - r.chi2).abs() <= 1e-12 * r.chi2);
    assert_eq!(p.status, r.status);
}

/// The grid: 0.1% and 1% noise, AR(0.9), AR(0.99) and offset+drift, seeds
/// 0..N; prints the counts and fails on any dishonest status.
#[test]
#[ignore]
fn grid_over_seeds() {
    let seeds: u64 = std::env::var("SEEDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(5);
    let truth = system3();
    let mut dishonest = Vec::new();
    for dev in [
        Deviation::Ar(0.9),
        Deviation::Ar(0.99),
        Deviation::OffsetDrift,
    ] {
        for level in [1e-3, 1e-2] {
            let (mut pos, mut val) = (0, 0);
            for seed in 0..seeds {
                let r = defaults(&record(&truth, level, dev, seed), 20, None);
                let (p, v) = right(&r, &truth);
                pos += p as usize;
                val += v as usize;
                if !honest(&truth, &r) {
                    dishonest.push(format!("{dev:?} {level} {seed}:\n{}", r.summary()));
                }
            }
            println!("{dev:?} at {level}: positions {pos}/{seeds}, values {val}/{seeds}");
        }
    }
    assert!(dishonest.is_empty(), "{}", dishonest.join("\n"));
}

/// White noise, the stiffness unknown and far from its start (`--fit k`
/// on a chain of `k = 2`, fitted from 1): the first white fit, started at
/// the wrong stiffness, misses and leaves a coloured residual, so an AR
/// model is fitted; its answer is right and leaves white noise. The answer
/// is then the white fit's (from that level), not the AR fit's: the AR
/// model over a white residual colours it, and the right answer was called
/// a `model-mismatch` with every standard error about 27 times too large.
#[test]
fn a_colour_that_was_the_first_fits_misfit_gives_way_to_white_noise() {
    let truth = scenes::paper_with(10, "mass:4:2")
        .unwrap()
        .with_k(2.0)
        .unwrap();
    for seed in [1, 2] {
        let obs = record(&truth, 5e-3, Deviation::Ar(0.0), seed);
        let spec = springmass::detect::fit::options::FitSpec {
            fit: Some("k".into()),
            ..springmass::detect::fit::options::FitSpec::new(10)
        };
        let (model, opts) = spec.build().unwrap();
        let r = fit(&obs, &model, &opts).unwrap();
        let case = format!("seed {seed}:\n{}", r.summary());
        assert!(right(&r, &truth).1, "{case}");
        assert_eq!(r.status, Status::Converged, "{case}");
        let white = r.noise_model.as_ref().is_none_or(|m| m.p == 0);
        assert!(white, "{case}");
        let k = r.params.iter().find(|p| p.name == "k").expect("k fitted");
        assert!((k.value - 2.0).abs() < 3.0 * k.se, "{case}");
    }
}
