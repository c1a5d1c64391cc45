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
