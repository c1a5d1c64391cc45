//! Records that do not start at the blow (issue: real records, item 3), from
//! the dense state-space generator `springmass::study::realistic` (not the
//! fit's modal sums): a pre-trigger segment, a late clock, an axis that
//! starts before 0, a record in millimetres and milliseconds. The defaults
//! find the blow, its standard error covers the truth, the positions are
//! right; a record that starts with its blow is fitted as before.

use springmass::detect::data::observations::{Observations, Series};
use springmass::detect::fit::{fit, FitOptions, Model, Status, TriggerSpec};
use springmass::study::realistic::{record, Deviations};

fn s3() -> springmass::Chain {
    springmass::scenes::by_name("S3").unwrap()
}

fn fitted(dev: &Deviations, level: f64, seed: u64) -> springmass::detect::fit::FitReport {
    let (t, x) = record(&s3(), dev, 200.0, 0.2, level, seed).unwrap();
    let obs = Observations::Series(Series::on_axis(t, x, None).unwrap());
    fit(&obs, &Model::new(20).unwrap(), &FitOptions::default()).unwrap()
}

#[test]
fn a_late_blow_is_found_and_the_defects_with_it() {
    let cases = [("pre-trigger", 10.07, 1e-3), ("late-clock", 12.53, 1e-2)];
    for (name, blow, level) in cases {
        for seed in [1, 2] {
            let r = fitted(&Deviations::named(name, 1.0).unwrap(), level, seed);
            let pos: Vec<usize> = r.defects.iter().map(|d| d.at).collect();
            assert_eq!(pos, [8, 15], "{name} {seed}: {}", r.summary());
            assert_eq!(
                r.status,
                Status::Converged,
                "{name} {seed}: {}",
                r.summary()
            );
            let tr = r.trigger.expect("re-timed");
            assert!(tr.detected, "{tr:?}");
            assert!(
                (tr.time - blow).abs() < 4.0 * tr.se,
                "{name} {seed}: {tr:?}"
            );
            for (d, truth) in r.defects.iter().zip([5.0, 2.0]) {
                assert!((d.value - truth).abs() < 4.0 * d.se, "{name} {seed}: {d:?}");
            }
        }
    }
}

#[test]
fn a_late_blow_with_a_sensor_offset_is_refined_with_the_answers_chain() {
    // Rayleigh damping, a sensor offset and drift and a late clock on
    // System 3 at 0.1% (the Rayleigh model given, its parameters fitted):
    // the white fit the time was first refined with took one defect and
    // no offset, its time was 8 of the answer's standard errors late, and
    // the answer at that time was `converged` with a spurious mass at 1
    // (1.002, chi-square 1036 at the true set against 992 at the true
    // time). The time is now refined again with the answer's chain.
    use springmass::detect::fit::options::FitSpec;
    let dev = Deviations::named("rayleigh+offset-drift+late-clock", 1.0).unwrap();
    let (t, x) = record(&s3(), &dev, 200.0, 0.2, 1e-3, 5_881_965_878_838_249_759).unwrap();
    let obs = Observations::Series(Series::on_axis(t, x, None).unwrap());
    let spec = FitSpec {
        fit: Some("d".into()),
        damping: Some("rayleigh".into()),
        d: Some(0.0),
        ..FitSpec::new(20)
    };
    let (model, opts) = spec.build().unwrap();
    let r = fit(&obs, &model, &opts).unwrap();
    let what = r.summary();
    let found: Vec<String> = r.found().iter().map(springmass::Defect::place).collect();
    assert_eq!(found, ["mass@8", "mass@15"], "{what}");
    assert_eq!(r.status, Status::Converged, "{what}");
    let tr = r.trigger.expect("re-timed");
    assert!(tr.detected && tr.refits >= 1, "{tr:?}");
    assert!((tr.time - 12.53).abs() < 4.0 * tr.se, "{tr:?}");
    assert_eq!(r.nuisance.len(), 2, "{what}");
}

#[test]
fn a_blow_detected_after_a_coloured_lead_in_is_not_a_sure_answer() {
    // a 10-unit lead-in with AR(0.9) noise: the detector's finest-scale
    // level is passed by the wandering lead-in before the blow, or the
    // blow is not found; whatever it finds, the answer must not be
    // `converged` (a known limit of the detector: the message asks for the
    // time when the blow was detected under coloured noise)
    use springmass::study::realistic::Colour;
    let dev = Deviations {
        colour: Colour::Ar1(0.9),
        ..Deviations::named("pre-trigger", 1.0).unwrap()
    };
    let truth = springmass::scenes::by_name("S1").unwrap();
    for seed in [31_676, 7_919] {
        let (t, x) = record(&truth, &dev, 200.0, 0.2, 1e-3, seed).unwrap();
        let obs = Observations::Series(Series::on_axis(t, x, None).unwrap());
        let r = fit(&obs, &Model::new(5).unwrap(), &FitOptions::default()).unwrap();
        // detected early, or not at all (the lead-in then fitted as motion)
        assert_ne!(r.status, Status::Converged, "{seed}: {}", r.summary());
        assert!(!r.resolved, "{seed}: {}", r.summary());
        if seed == 31_676 {
            // this record's fit was `converged` with a wrong second defect
            // before the detection was doubted
            let tr = r.trigger.as_ref().expect("detected");
            assert!(tr.detected && tr.time < 9.0, "{tr:?}");
            assert!(r.message.contains("--trigger"), "{}", r.message);
        }
    }
}

#[test]
fn a_pre_trigger_segment_at_negative_times_and_a_given_time() {
    // the logger's axis runs from -5 (the blow at 0 of that axis)
    let dev = Deviations {
        blow: 0.0,
        start: -5.0,
        ..Deviations::default()
    };
    let (t, x) = record(&s3(), &dev, 205.0, 0.2, 1e-3, 4).unwrap();
    let rec = Series::on_axis(t, x, None).unwrap();
    assert_eq!(rec.origin(), -5.0);
    let obs = Observations::Series(rec);
    let model = Model::new(20).unwrap();
    let auto = fit(&obs, &model, &FitOptions::default()).unwrap();
    let given = fit(
        &obs,
        &model,
        &FitOptions {
            trigger: TriggerSpec::At(0.0),
            ..FitOptions::default()
        },
    )
    .unwrap();
    for r in [&auto, &given] {
        let pos: Vec<usize> = r.defects.iter().map(|d| d.at).collect();
        assert_eq!(pos, [8, 15], "{}", r.summary());
        let tr = r.trigger.expect("re-timed");
        assert!(tr.time.abs() < 4.0 * tr.se.max(1e-6), "{tr:?}");
    }
    assert!(!given.trigger.unwrap().detected);
    // a time outside the record: a clear error naming the field
    let e = fit(
        &obs,
        &model,
        &FitOptions {
            trigger: TriggerSpec::At(1e6),
            ..FitOptions::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("trigger"), "{e}");
}

/// A displacement record cut short after the blow on an axis from 0 (a
/// logger started by a threshold, no pre-trigger segment): its first
/// sample is far from rest, which a displacement at the blow is not, so
/// the blow is sought before the record. Every fourth sample of a record
/// at `dt = 0.05` from the fifth on: the blow at -0.25.
#[test]
fn a_displacement_record_cut_short_after_the_blow_is_re_timed() {
    for seed in [1, 2] {
        let (t, x) = record(&s3(), &Deviations::default(), 200.0, 0.05, 1e-3, seed).unwrap();
        let t: Vec<f64> = t.iter().skip(5).step_by(4).map(|v| v - 0.25).collect();
        let x: Vec<f64> = x.into_iter().skip(5).step_by(4).collect();
        let obs = Observations::Series(Series::on_axis(t, x, None).unwrap());
        let r = fit(&obs, &Model::new(20).unwrap(), &FitOptions::default()).unwrap();
        let what = format!("seed {seed}: {}", r.summary());
        let pos: Vec<usize> = r.defects.iter().map(|d| d.at).collect();
        assert_eq!(pos, [8, 15], "{what}");
        assert_eq!(r.status, Status::Converged, "{what}");
        let tr = r.trigger.expect("re-timed");
        assert!(tr.detected, "{tr:?}");
        assert!((tr.time + 0.25).abs() < 4.0 * tr.se, "{what}");
    }
}

/// A record of System 3 that starts `cut` after its blow, on an axis from 0.
fn cut_short(cut: f64, level: f64, seed: u64) -> Observations {
    let dev = Deviations {
        blow: -cut,
        ..Deviations::default()
    };
    let (t, x) = record(&s3(), &dev, 200.0, 0.2, level, seed).unwrap();
    Observations::Series(Series::on_axis(t, x, None).unwrap())
}

/// A record cut 2.5 after its blow, the time given: the Bromwich
/// shortlist's transform of the record lacks the response before its first
/// sample, which the uniform chain now supplies. Before, at 1% noise, the
/// fit found no defect and called the record a `model-mismatch`.
#[test]
fn a_long_cut_with_its_time_given_is_fitted() {
    let opts = FitOptions {
        trigger: TriggerSpec::At(-2.5),
        ..FitOptions::default()
    };
    for seed in [1, 2] {
        let r = fit(&cut_short(2.5, 1e-2, seed), &Model::new(20).unwrap(), &opts).unwrap();
        let what = format!("seed {seed}: {}", r.summary());
        let pos: Vec<usize> = r.defects.iter().map(|d| d.at).collect();
        assert_eq!(pos, [8, 15], "{what}");
        assert_eq!(r.status, Status::Converged, "{what}");
    }
}

/// Records cut 2.5 and 3.0 after their blow, by default: the uniform
/// chain's best match before the record can be a period away from the blow
/// (a defect's echo has reached the comparison window), and the fit then
/// tries the comparison's other minima, keeping the first time whose fit
/// explains the record. Before, such records were placed wrong and called
/// `model-mismatch`.
#[test]
fn a_long_cut_is_fitted_by_default() {
    for cut in [2.5, 3.0] {
        cut_is_fitted_by_default(cut, 1e-2, 1);
    }
}

/// System 3 cut `cut` after its blow (noise `level`, `seed`), fitted with
/// the defaults: both masses found, `converged`, the blow detected within
/// 4 of its standard errors.
fn cut_is_fitted_by_default(cut: f64, level: f64, seed: u64) {
    let r = fit(
        &cut_short(cut, level, seed),
        &Model::new(20).unwrap(),
        &FitOptions::default(),
    )
    .unwrap();
    let what = format!("cut {cut}, seed {seed}: {}", r.summary());
    let pos: Vec<usize> = r.defects.iter().map(|d| d.at).collect();
    assert_eq!(pos, [8, 15], "{what}");
    assert_eq!(r.status, Status::Converged, "{what}");
    let tr = r.trigger.expect("re-timed");
    assert!(tr.detected && (tr.time + cut).abs() < 4.0 * tr.se, "{what}");
}

/// A record cut 1.0 after its blow starts on the flat top of the first
/// swing: its first samples stay within the noise of the first, like a
/// lead-in at an offset. The blow is sought both inside that start and
/// before the record; before it is (the lead-in reading found nothing,
/// and the fit was a `model-mismatch` at the record's own axis).
#[test]
fn a_cut_on_the_first_swings_flat_top_is_found() {
    for seed in [1, 2] {
        cut_is_fitted_by_default(1.0, 1e-3, seed);
    }
}

#[test]
fn a_record_that_starts_with_its_blow_is_not_re_timed() {
    for seed in [1, 2, 3] {
        let r = fitted(&Deviations::default(), 1e-2, seed);
        assert!(r.trigger.is_none(), "{:?}", r.trigger);
    }
}

#[test]
fn the_cli_converts_units_and_finds_the_blow() {
    // the same record in mm and ms with a pre-trigger segment, by the CLI
    let dev = Deviations::named("pre-trigger", 1.0).unwrap();
    let (t, x) = record(&s3(), &dev, 200.0, 0.2, 1e-3, 9).unwrap();
    let dir = std::env::temp_dir().join(format!("springmass-trigger-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("mm.csv");
    let mut text = String::from("t [ms],x1 [mm]\n");
    for (ti, xi) in t.iter().zip(&x) {
        text.push_str(&format!("{},{}\n", ti * 1e3, xi * 1e3));
    }
    std::fs::write(&path, text).unwrap();
    let out = fit_cli(&path, &["--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let pos: Vec<u64> = v["defects"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| d["at"].as_u64().unwrap())
        .collect();
    assert_eq!(pos, [8, 15]);
    let time = v["trigger"]["time"].as_f64().unwrap();
    assert!((time - 10.07).abs() < 0.01, "{time}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("converted"), "{err}");
    // a unit that contradicts the observable: refused, nothing written
    let plot = dir.join("never.svg");
    let out = fit_cli(
        &path,
        &[
            "--observe-kind",
            "acceleration",
            "--plot",
            plot.to_str().unwrap(),
        ],
    );
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("x1"));
    assert!(!plot.exists());
    std::fs::remove_dir_all(&dir).ok();
}

/// `springmass fit --data PATH --n 20 EXTRA...`.
fn fit_cli(path: &std::path::Path, extra: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_springmass"))
        .args(["fit", "--data", path.to_str().unwrap(), "--n", "20"])
        .args(extra)
        .output()
        .unwrap()
}
