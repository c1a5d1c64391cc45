//! What a first user meets on the command line: a short chain fitted with
//! the defaults, and fits whose bounds and difference steps once leaked
//! into the error message (values the user never gave).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const BIN: &str = env!("CARGO_BIN_EXE_springmass");

/// A noisy record of mass 1 (`springmass simulate`, t_end 50, dt 0.2, seed
/// 3) of a uniform chain of `n` masses with the extra options `chain`, in a
/// fresh folder.
fn record(name: &str, n: usize, chain: &[&str]) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("springmass-first-use-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    let o = Command::new(BIN)
        .args([
            "simulate",
            "--n",
            &n.to_string(),
            "--t-end",
            "50",
            "--dt",
            "0.2",
        ])
        .args([
            "--noise",
            "rel:1e-3",
            "--seed",
            "3",
            "--out",
            path.to_str().unwrap(),
        ])
        .args(chain)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    path
}

fn fit(data: &Path, n: usize, extra: &[&str]) -> Output {
    Command::new(BIN)
        .args([
            "fit",
            "--data",
            data.to_str().unwrap(),
            "--n",
            &n.to_string(),
        ])
        .args(extra)
        .output()
        .unwrap()
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

#[test]
fn a_three_mass_chain_fits_with_the_defaults() {
    let data = record("n3.csv", 3, &[]);
    let o = fit(&data, 3, &[]);
    assert!(o.status.success(), "{}", text(&o));
    // an explicit k_max above n stays an error naming it
    let o = fit(&data, 3, &["--defects", "auto:4"]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("k_max"), "{}", text(&o));
}

#[test]
fn damping_fitted_to_zero_is_not_an_error_about_a_negative_d() {
    let data = record("d0.csv", 5, &["--d", "0"]);
    let o = fit(&data, 5, &["--fit", "d", "--defects", "0"]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(!text(&o).contains("-0.000000001"), "{}", text(&o));
}

#[test]
fn a_tiny_uniform_mass_is_not_an_error_about_a_negative_defect() {
    let data = record("m.csv", 5, &["--defect", "mass:2:2"]);
    let o = fit(&data, 5, &["--mass", "1e-9", "--defects", "1"]);
    assert!(
        !text(&o).contains("invalid defects[0].m = -"),
        "{}",
        text(&o)
    );
    assert!(o.status.success(), "{}", text(&o));
}
