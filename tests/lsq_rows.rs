//! Issue 32, item 6: the covariance of the bounded least squares indexed
//! `p` singular values of a Jacobian with fewer rows than parameters ("Matrix
//! index out of bounds", exit 101). The root is fixed in
//! `detect::search::lsq::covariance` (a typed error naming the rows and the
//! parameters; reproduced by its unit tests); this is the command
//! line, kept as a regression guard: a burst of samples 1 ns apart, a gap,
//! then one sample per second.

use std::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_springmass");

#[test]
fn too_few_residuals_for_the_parameters_is_an_error_not_a_panic() {
    let dir = std::env::temp_dir().join(format!("springmass-lsq-rows-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    // 200 samples at t = i * 1e-9, then 200 at t = 10..209
    let mut csv = String::from("t,x1\n");
    for i in 0..200 {
        let t = i as f64 * 1e-9;
        csv.push_str(&format!("{t:e},{}\n", 0.5 * t));
    }
    for i in 0..200 {
        let t = 10.0 + i as f64;
        csv.push_str(&format!(
            "{t},{}\n",
            0.1 * (0.3 * t).sin() * (-0.01 * t).exp()
        ));
    }
    let file = dir.join("burst.csv");
    std::fs::write(&file, csv).unwrap();
    let out = Command::new(BIN)
        .args([
            "fit",
            "--data",
            file.to_str().unwrap(),
            "--n",
            "10",
            "--defects",
            "2",
        ])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    let _ = std::fs::remove_dir_all(&dir);
    assert!(!err.contains("panicked"), "{err}");
    assert_ne!(out.status.code(), Some(101), "{err}");
    // an answer, or a typed error (exit 1 or 2) saying what is wrong
    match out.status.code() {
        Some(0) => assert!(String::from_utf8_lossy(&out.stdout).contains("mass at")),
        code => {
            assert!(matches!(code, Some(1 | 2)), "{code:?}: {err}");
            assert!(err.starts_with("error:"), "{err}");
        }
    }
}
