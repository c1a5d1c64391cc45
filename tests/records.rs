//! Several records of the same chain, one joint fit (issue 28, item 5):
//! `--data` repeated, `Series::with_records`, Python `fit(records=...)`.
//!
//! The records come from the tests' dense state-space generator
//! (`tests/common/dense.rs`: the matrix exponential of the first-order
//! system, not the modal sum the fit uses), each at its own sampling and
//! length, with its own noise level from its own seeded ChaCha8 stream.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use springmass::detect::data::observations::{Observations, Series};
use springmass::detect::fit::options::FitSpec;
use springmass::detect::fit::{fit, FitReport, Status};
use springmass::{scenes, Chain, Error};

/// Displacement of mass 1 after the impulse, on `0, dt, ..., t_end`, with
/// white noise of `level` times its peak.
fn record(truth: &Chain, t_end: f64, dt: f64, level: f64, seed: u64) -> Series {
    let (t, mut x) = crate::dense::records(truth, &[1], t_end, dt);
    let x = x.remove(0);
    let peak = x.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let noise = Normal::new(0.0, level * peak).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let y = x.iter().map(|v| v + noise.sample(&mut rng)).collect();
    Series::new(t, y, None).unwrap()
}

fn joint(records: Vec<Series>, n: usize) -> FitReport {
    let mut it = records.into_iter();
    let first = it.next().unwrap();
    let obs = Observations::Series(first.with_records(it.collect()).unwrap());
    let (model, opts) = FitSpec::new(n).build().unwrap();
    opts.validate(&obs, &model).unwrap();
    fit(&obs, &model, &opts).unwrap()
}

fn system3() -> Chain {
    scenes::paper_with(20, "mass:8:5 mass:15:2").unwrap()
}

/// Two hits of System 3, sampled differently and at different noise
/// levels: the joint answer is right, each record's level is its own.
#[test]
fn two_records_are_fitted_jointly_each_at_its_own_level() {
    let truth = system3();
    let r = joint(
        vec![
            record(&truth, 200.0, 0.2, 0.01, 1),
            record(&truth, 150.0, 0.1, 0.03, 2),
        ],
        20,
    );
    let at: Vec<usize> = r.defects.iter().map(|d| d.at).collect();
    assert_eq!(at, vec![8, 15], "{}", r.summary());
    for (d, want) in r.defects.iter().zip([5.0, 2.0]) {
        assert!((d.value - want).abs() < 3.0 * d.se, "{}", r.summary());
    }
    assert_eq!(r.status, Status::Converged, "{}", r.summary());
    let records: Vec<usize> = r.sensors.iter().map(|s| s.record).collect();
    assert_eq!(records, vec![1, 2]);
    assert_eq!((r.sensors[0].samples, r.sensors[1].samples), (1001, 1501));
    // the second record's level is three times the first's (of a peak
    // within a few percent of the first's)
    let ratio = r.sensors[1].sigma / r.sensors[0].sigma;
    assert!((2.5..3.5).contains(&ratio), "{ratio}: {}", r.summary());
    assert!(r.sensors.iter().all(|s| s.fits_data), "{}", r.summary());
    assert!(r.summary().contains("records: record 1"), "{}", r.summary());
}

/// A record of another chain among them is named, and the fit is a
/// model mismatch, not an answer.
#[test]
fn a_record_of_another_chain_is_flagged() {
    let truth = system3();
    let other = scenes::paper_with(20, "mass:8:5 mass:12:3").unwrap();
    let r = joint(
        vec![
            record(&truth, 200.0, 0.2, 0.01, 1),
            record(&truth, 150.0, 0.1, 0.01, 2),
            record(&other, 200.0, 0.2, 0.01, 3),
        ],
        20,
    );
    assert_eq!(r.status, Status::ModelMismatch, "{}", r.summary());
    assert!(!r.resolved);
    let bad: Vec<usize> = r
        .sensors
        .iter()
        .filter(|s| !s.fits_data)
        .map(|s| s.record)
        .collect();
    assert_eq!(bad, vec![3], "{}", r.summary());
    assert!(r.message.contains("record 3"), "{}", r.message);
}

/// Records that hold sensors of their own, or a blow time, are refused
/// with the field named.
#[test]
fn bad_record_sets_are_refused() {
    let truth = system3();
    let a = record(&truth, 100.0, 0.2, 0.01, 1);
    let b = record(&truth, 100.0, 0.2, 0.01, 2);
    let with_sensor = a
        .clone()
        .with_sensors(vec![b
            .clone()
            .with_measurement(springmass::detect::data::measurement::Measurement::new(
                5,
                springmass::forward::Observable::Displacement,
            ))
            .unwrap()])
        .unwrap();
    match b.clone().with_records(vec![with_sensor]) {
        Err(Error::InvalidParameter { field, .. }) => assert_eq!(field, "records"),
        other => panic!("{other:?}"),
    }
    let obs = Observations::Series(a.with_records(vec![b]).unwrap());
    let spec = FitSpec {
        trigger: Some("5.0".into()),
        ..FitSpec::new(20)
    };
    let (model, opts) = spec.build().unwrap();
    match fit(&obs, &model, &opts) {
        Err(Error::InvalidParameter { field, .. }) => assert_eq!(field, "trigger"),
        other => panic!("{:?}", other.map(|r| r.summary())),
    }
}
