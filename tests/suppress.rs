//! Integration tests of the suppression scheme (Theorem 3.1, Corollary 3.2):
//! exact controls against the independent reference (80-digit residue sums),
//! and time-domain verification by simulation.

mod common;

use springmass::control::exact::Modes;
use springmass::control::{Signal, Suppression};

fn controls_json() -> serde_json::Value {
    let p = common::reference_dir().join("controls.json");
    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
}

#[test]
fn exact_controls_match_reference_residue_sums() {
    let v = controls_json();
    let t: Vec<f64> = v["t"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    for n in [4usize, 19] {
        let sup = Suppression::paper(n).unwrap();
        for (key, sig) in [("f", Signal::F), ("g", Signal::G), ("f1", Signal::F1)] {
            let case = &v["cases"][format!("n={n}")][key];
            let modes = Modes::new(&sup, sig);
            let want: Vec<f64> = case["residue_str"]
                .as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_str().unwrap().parse().unwrap())
                .collect();
            let scale = case["max_abs_value"].as_f64().unwrap();
            let mut worst = 0.0_f64;
            for (ti, wi) in t.iter().zip(&want) {
                worst = worst.max((modes.eval(*ti) - wi).abs());
            }
            assert!(
                worst <= 1e-13 * scale.max(1.0),
                "n={n} {key}: max abs error {worst:e}"
            );
        }
    }
}

use springmass::control::verify::{verify, Input, VerifyOptions};
use springmass::control::Scheme;

fn check(sup: &Suppression, t_end: f64, dt: f64, tol: f64) -> (f64, f64) {
    let opts = VerifyOptions::new(t_end, dt).unwrap();
    let c = verify(sup, Scheme::Cloak, &Input::Impulse, &opts)
        .unwrap()
        .metrics;
    eprintln!("n={} d={} cloak: {c:?}", sup.n(), sup.d());
    assert!(c.rel_x_end <= tol && c.rel_x1_minus_y1 <= tol, "{c:?}");
    assert!(c.sim_vs_exact_y1 <= tol && c.sim_vs_exact_x1.unwrap() <= tol);
    let s = verify(sup, Scheme::Single, &Input::Impulse, &opts)
        .unwrap()
        .metrics;
    eprintln!("n={} d={} single: {s:?}", sup.n(), sup.d());
    assert!(
        s.rel_x_end <= tol && s.max_abs_x_n / s.max_abs_y1 <= tol,
        "{s:?}"
    );
    assert!(s.sim_vs_exact_x1.unwrap() <= tol);
    (c.rel_x_end_vs_uncontrolled, s.rel_x1_minus_y1)
}

#[test]
fn paper_systems_verified_by_simulation() {
    for n in [4usize, 19] {
        let (_, visible) = check(&Suppression::paper(n).unwrap(), 60.0, 0.01, 1e-8);
        // the single control is visible at mass 1
        assert!(visible > 0.05, "n={n}: {visible}");
    }
}

#[test]
fn long_undamped_and_overdamped_chains_verified() {
    check(&Suppression::paper(200).unwrap(), 300.0, 0.05, 1e-8);
    check(
        &Suppression::new(19, 1.0, 0.0, 1.0, 1.0).unwrap(),
        60.0,
        0.01,
        1e-8,
    );
    check(
        &Suppression::new(19, 1.0, 5.0, 1.0, 1.0).unwrap(),
        60.0,
        0.01,
        1e-8,
    );
    check(
        &Suppression::new(7, 2.5, 0.3, 0.5, -2.0).unwrap(),
        60.0,
        0.01,
        1e-8,
    );
}

#[test]
fn critically_damped_mode_verified_by_simulation() {
    // d = sqrt(8 (1 - cos(2 pi / 6))) = 2: the j = 2 mode of U_5 is critically damped
    let d = (8.0 * (1.0 - (2.0 * std::f64::consts::PI / 6.0).cos())).sqrt();
    check(
        &Suppression::new(4, 1.0, d, 1.0, 1.0).unwrap(),
        40.0,
        0.01,
        1e-8,
    );
}

fn pulse(h: f64, len: usize) -> springmass::series::TimeSeries {
    // a smooth-ish two-bump disturbance, zero after t = 8
    let t: Vec<f64> = (0..len).map(|i| i as f64 * h).collect();
    let u: Vec<f64> = t
        .iter()
        .map(|&t| {
            if t < 8.0 {
                (std::f64::consts::PI * t / 8.0).sin().powi(2) * (1.0 + 0.5 * (1.3 * t).sin())
            } else {
                0.0
            }
        })
        .collect();
    springmass::series::TimeSeries::new(t, vec![("u".into(), u)]).unwrap()
}

#[test]
fn sampled_disturbance_verified_by_simulation() {
    let input = Input::from_series(&pulse(0.05, 801)).unwrap();
    for n in [4usize, 19] {
        let sup = Suppression::paper(n).unwrap();
        let opts = VerifyOptions::new(60.0, 0.05).unwrap();
        for scheme in [Scheme::Cloak, Scheme::Single] {
            let m = verify(&sup, scheme, &input, &opts).unwrap().metrics;
            eprintln!("disturbance n={n} {scheme:?}: {m:?}");
            assert!(m.rel_x_end <= 1e-8 && m.sim_vs_exact_y1 <= 1e-8, "{m:?}");
            assert!(m.sim_vs_exact_x1.unwrap() <= 1e-8);
            match scheme {
                Scheme::Cloak => assert!(m.rel_x1_minus_y1 <= 1e-8),
                Scheme::Single => assert!(m.rel_x1_minus_y1 > 1e-2),
            }
        }
    }
    // the simulator step must divide the disturbance step
    let sup = Suppression::paper(4).unwrap();
    let e = verify(
        &sup,
        Scheme::Cloak,
        &input,
        &VerifyOptions::new(10.0, 0.03).unwrap(),
    );
    assert!(e.is_err());
}
