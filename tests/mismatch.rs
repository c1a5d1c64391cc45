//! Records with what the paper's model leaves out: the fit must not call a
//! best answer `converged` when its residual is not noise; the status is
//! `model-mismatch` and the answer is not `resolved`. The records are
//! Table 1's System 2 by the time stepper (`TimeData::simulate`, not the
//! fit's modal sum), noise-free, with the deviations and the noise added
//! here by their own seeded generator.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use springmass::detect::data::observations::{Observations, Series};
use springmass::detect::data::series::TimeData;
use springmass::detect::fit::{fit, FitOptions, FitReport, Model, Status};
use springmass::noise::NoiseLevel;
use springmass::scenes;

/// System 2's clean record of mass 1 (t = 0..150, dt = 0.25) and its peak.
fn clean() -> (Vec<f64>, Vec<f64>, f64) {
    let truth = scenes::table1(2).unwrap();
    let d = TimeData::simulate(&truth, 150.0, 0.25, NoiseLevel::Absolute(0.0), 0).unwrap();
    let peak = d.y().iter().fold(0.0f64, |a, v| a.max(v.abs()));
    (d.t().to_vec(), d.y().to_vec(), peak)
}

/// Gaussian noise of standard deviation `sd`, AR(1) with coefficient `rho`
/// (0: white), stationary from the first sample.
fn noise(len: usize, sd: f64, rho: f64, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let innov = Normal::new(0.0, sd * (1.0 - rho * rho).sqrt()).unwrap();
    let mut e = Normal::new(0.0, sd).unwrap().sample(&mut rng);
    (0..len)
        .map(|_| {
            let v = e;
            e = rho * e + innov.sample(&mut rng);
            v
        })
        .collect()
}

fn fit_defaults(t: &[f64], x: &[f64]) -> FitReport {
    let obs = Observations::Series(Series::new(t.to_vec(), x.to_vec(), None).unwrap());
    fit(&obs, &Model::new(10).unwrap(), &FitOptions::default()).unwrap()
}

#[test]
fn white_noise_record_converges_and_fits() {
    let (t, x, peak) = clean();
    let e = noise(x.len(), 0.01 * peak, 0.0, 3);
    let y: Vec<f64> = x.iter().zip(&e).map(|(a, b)| a + b).collect();
    let r = fit_defaults(&t, &y);
    assert!(r.fits_data, "{}", r.summary());
    assert_eq!(r.status, Status::Converged, "{}", r.summary());
    let at: Vec<usize> = r.defects.iter().map(|d| d.at).collect();
    assert_eq!(at, vec![3, 7], "{}", r.summary());
}

#[test]
fn offset_and_drift_are_a_model_mismatch() {
    let (t, x, peak) = clean();
    let e = noise(x.len(), 0.01 * peak, 0.0, 3);
    let t_end = t[t.len() - 1];
    let y: Vec<f64> = x
        .iter()
        .zip(&e)
        .zip(&t)
        .map(|((a, b), ti)| a + b + 0.02 * peak * (1.0 + ti / t_end))
        .collect();
    let r = fit_defaults(&t, &y);
    assert!(!r.fits_data, "{}", r.summary());
    assert_eq!(r.status, Status::ModelMismatch, "{}", r.summary());
    assert!(!r.resolved);
    assert!(r.message.contains("not noise"), "{}", r.message);
}

#[test]
fn strongly_coloured_noise_is_a_model_mismatch() {
    let (t, x, peak) = clean();
    let e = noise(x.len(), 0.01 * peak, 0.99, 5);
    let y: Vec<f64> = x.iter().zip(&e).map(|(a, b)| a + b).collect();
    let r = fit_defaults(&t, &y);
    assert_eq!(r.status, Status::ModelMismatch, "{}", r.summary());
    assert!(!r.resolved);
}
