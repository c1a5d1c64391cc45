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
                worst <= 5e-15 * scale.max(1.0),
                "n={n} {key}: max abs error {worst:e}"
            );
            eprintln!("reference n={n} {key}: max |exact - residue80| = {worst:.2e} (max |value| {scale:.3})");
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

// ---------------------------------------------------------------- CLI

fn cli(args: &[&str]) -> (i32, String, String) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_springmass"))
        .args(args)
        .output()
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn tmpdir(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("springmass-suppress-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn cli_writes_series_figures_summary_and_robustness() {
    let dir = tmpdir("ok");
    let out = dir.join("n4");
    let (code, stdout, err) = cli(&[
        "suppress",
        "--n",
        "4",
        "--t-end",
        "30",
        "--dt",
        "0.02",
        "--robust-delays",
        "0,0.01,0.1",
        "--robust-gains",
        "0,0.01,0.1",
        "--out-dir",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(stdout.contains("f and g"), "{stdout}");
    for f in [
        "timeseries.csv",
        "summary.json",
        "robustness.csv",
        "fig_controls.svg",
        "fig_x1_f_alone.svg",
        "fig_x1_cloak.svg",
        "fig_x_end.svg",
        "robust_delay.svg",
        "robust_gain.svg",
    ] {
        assert!(out.join(f).exists(), "{f} missing");
    }
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert!(s["exact_controls"]["rel_x_end"].as_f64().unwrap() < 1e-8);
    assert!(s["exact_controls"]["rel_x1_minus_y1"].as_f64().unwrap() < 1e-8);
    assert!(
        s["single_control_f1_alone"]["rel_x1_minus_y1"]
            .as_f64()
            .unwrap()
            > 0.5
    );
    // Theorem 3.1's f without g does not keep mass n+1 still
    assert!(
        s["theorem_f_without_g"]["rel_x_end_vs_uncontrolled"]
            .as_f64()
            .unwrap()
            > 0.1
    );
    let rob = &s["robustness"]["gain_all"];
    assert!((rob[2]["rel_x_end_vs_uncontrolled"].as_f64().unwrap() - 0.1).abs() < 1e-6);
    let ts = springmass::series::TimeSeries::read_csv(out.join("timeseries.csv")).unwrap();
    for c in ["f_on_4", "g_on_3", "y1", "x1", "x5", "y5", "x1_f1_alone"] {
        assert!(ts.column(c).is_some(), "column {c}");
    }

    // single control, a disturbance, a delay
    let csv = dir.join("u.csv");
    pulse(0.05, 401).write_csv(&csv).unwrap();
    let out2 = dir.join("single");
    let (code, _, err) = cli(&[
        "suppress",
        "--n",
        "6",
        "--single",
        "--t-end",
        "20",
        "--dt",
        "0.05",
        "--disturbance",
        csv.to_str().unwrap(),
        "--delay",
        "0.1",
        "--robust-delays",
        "0,0.1",
        "--robust-gains",
        "0,0.1",
        "--out-dir",
        out2.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(out2.join("fig_single.svg").exists());
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out2.join("summary.json")).unwrap()).unwrap();
    assert!(s["exact_controls"]["rel_x_end"].as_f64().unwrap() < 1e-8);
    assert!(
        s["applied_controls"]["metrics"]["rel_x_end"]
            .as_f64()
            .unwrap()
            > 1e-3
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn cli_bad_input_is_a_clear_error() {
    let dir = tmpdir("bad");
    let o = dir.join("o");
    let o = o.to_str().unwrap();
    let (code, _, err) = cli(&["suppress", "--n", "1", "--out-dir", o]);
    assert_eq!(code, 2);
    assert!(
        err.contains("invalid n = 1") && err.contains("2 <= n"),
        "{err}"
    );
    let (code, _, err) = cli(&["suppress", "--n", "4", "--delay", "-0.5", "--out-dir", o]);
    assert_eq!(code, 2);
    assert!(
        err.contains("invalid delay = -0.5") && err.contains(">= 0"),
        "{err}"
    );
    let (code, _, err) = cli(&["suppress", "--n", "4", "--gain-error", "3", "--out-dir", o]);
    assert_eq!(code, 2);
    assert!(err.contains("gain_error"), "{err}");
    let nan = dir.join("nan.csv");
    std::fs::write(&nan, "t,u\n0,0\n0.1,NaN\n0.2,1\n").unwrap();
    let (code, _, err) = cli(&[
        "suppress",
        "--n",
        "4",
        "--disturbance",
        nan.to_str().unwrap(),
        "--out-dir",
        o,
    ]);
    assert_eq!(code, 2);
    assert!(err.contains("NaN") && err.contains("line 3"), "{err}");
    let late = dir.join("late.csv");
    std::fs::write(&late, "t,u\n1,0\n1.1,1\n").unwrap();
    let (code, _, err) = cli(&[
        "suppress",
        "--n",
        "4",
        "--disturbance",
        late.to_str().unwrap(),
        "--out-dir",
        o,
    ]);
    assert_eq!(code, 2);
    assert!(err.contains("t[0]"), "{err}");
    let (code, _, err) = cli(&["suppress", "--n", "4", "--d", "-1", "--out-dir", o]);
    assert_eq!(code, 2);
    assert!(err.contains("invalid d = -1"), "{err}");
    assert!(!err.contains("panicked"));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn exact_displacements_match_the_chain_modal_sums() {
    // y_1, y_{n+1} of the (n+1)-chain and x_1 of the (n-1)-chain (what mass 1
    // sees under f1) from time::modal's eigen-decomposition of the chain
    use springmass::time::modal::ModalResponse;
    for &(n, k, d, m) in &[
        (4usize, 1.0, 0.1, 1.0),
        (19, 2.0, 0.0, 0.5),
        (12, 1.0, 5.0, 1.0),
    ] {
        let sup = Suppression::new(n, k, d, m, 1.0).unwrap();
        let chain = sup.chain();
        let small = springmass::Chain::new(n - 1)
            .unwrap()
            .with_k(k)
            .unwrap()
            .with_d(d)
            .unwrap()
            .with_mass(m)
            .unwrap();
        let pairs = [
            (Signal::Y1, ModalResponse::impulse(chain, 1).unwrap()),
            (Signal::YEnd, ModalResponse::impulse(chain, n + 1).unwrap()),
            (Signal::X1Single, ModalResponse::impulse(&small, 1).unwrap()),
        ];
        for (sig, modal) in pairs {
            let ours = Modes::new(&sup, sig);
            for i in 0..=400 {
                let t = i as f64 * 0.25;
                let (a, b) = (ours.eval(t), modal.eval(t));
                assert!(
                    (a - b).abs() < 1e-12,
                    "n={n} d={d} {sig:?} t={t}: {a} vs {b}"
                );
            }
        }
    }
}

mod props {
    use super::*;
    use nalgebra::{DMatrix, DVector};
    use proptest::prelude::*;
    use springmass::Complex64;

    fn dense(
        n1: usize,
        k: f64,
        m: f64,
        d: f64,
        s: Complex64,
        loads: &[(usize, Complex64)],
    ) -> DVector<Complex64> {
        let mut a = DMatrix::<Complex64>::zeros(n1, n1);
        for i in 0..n1 {
            a[(i, i)] = s * s * m + s * d + 2.0 * k;
            if i + 1 < n1 {
                a[(i, i + 1)] = (-k).into();
                a[(i + 1, i)] = (-k).into();
            }
        }
        let mut b = DVector::<Complex64>::zeros(n1);
        for &(at, v) in loads {
            b[at - 1] += v;
        }
        a.lu().solve(&b).unwrap()
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(200))]
        /// Theorem 3.1 and Corollary 3.2 hold for any n, k, m, d, gamma and s
        /// (dense solve of the (n+1)-mass system with the controls as loads),
        /// and the modal partial fractions equal the closed form.
        #[test]
        fn schemes_hold_on_wide_grid(
            n in 2usize..60,
            lk in -2.0f64..2.0, lm in -2.0f64..2.0, d in 0.0f64..6.0,
            gamma in -3.0f64..3.0,
            sr in 0.0f64..3.0, si in -6.0f64..6.0,
        ) {
            let (k, m) = (10f64.powf(lk), 10f64.powf(lm));
            let sup = Suppression::new(n, k, d, m, gamma).unwrap();
            let s = Complex64::new(sr + 0.05, si);
            let ev = |sig| sup.ratio(sig).eval(&sup, s).unwrap();
            let y = dense(n + 1, k, m, d, s, &[(1, gamma.into())]);
            let scale = y.iter().map(|z| z.norm()).fold(0.0, f64::max);
            let x = dense(n + 1, k, m, d, s, &[(1, gamma.into()), (n, ev(Signal::F)), (n - 1, ev(Signal::G))]);
            prop_assert!(x[n].norm() <= 1e-9 * scale);
            prop_assert!((x[0] - y[0]).norm() <= 1e-9 * scale);
            let x1 = dense(n + 1, k, m, d, s, &[(1, gamma.into()), (n, ev(Signal::F1))]);
            prop_assert!(x1[n].norm() <= 1e-9 * scale && x1[n - 1].norm() <= 1e-9 * scale);
            for sig in [Signal::F, Signal::G, Signal::F1] {
                let e = ev(sig);
                let pf = Modes::new(&sup, sig).laplace(s);
                prop_assert!((e - pf).norm() <= 1e-9 * e.norm().max(gamma.abs() * 1e-3));
            }
        }
    }
}

#[test]
fn exact_controls_match_numerical_inverse_laplace() {
    // time::inverse (two de Hoog runs + Talbot check) returns a value only
    // where it trusts it; there the exact modal sums must agree to 1e-8.
    use springmass::time::inverse::{invert, InverseOptions};
    use springmass::Complex64;
    let opts = InverseOptions::default();
    // the last case has a critically damped mode (j = 2 of U_5)
    let d_crit = (8.0 * (1.0 - (2.0 * std::f64::consts::PI / 6.0).cos())).sqrt();
    for &(n, d) in &[(4usize, 0.1), (19, 0.1), (19, 5.0), (6, 0.0), (4, d_crit)] {
        let sup = Suppression::new(n, 1.0, d, 1.0, 1.0).unwrap();
        for sig in [Signal::F, Signal::G, Signal::F1] {
            let r = sup.ratio(sig);
            let lap = |s: Complex64| -> Complex64 {
                r.eval(&sup, s)
                    .unwrap_or(Complex64::new(f64::NAN, f64::NAN))
            };
            let modes = Modes::new(&sup, sig);
            let (mut resolved, mut worst, mut last_ok) = (0, 0.0_f64, 0.0);
            for i in 1..=120 {
                let t = i as f64 * 0.5;
                if let Ok(inv) = invert(&lap, t, &opts) {
                    let e = (modes.eval(t) - inv.value).abs();
                    assert!(
                        e <= 1e-8,
                        "n={n} d={d} {sig:?} t={t}: {e:e} (est {:e})",
                        inv.err
                    );
                    worst = worst.max(e);
                    resolved += 1;
                    last_ok = t;
                }
            }
            eprintln!(
                "inverse n={n} d={d} {sig:?}: resolved {resolved}/120 points (last t = {last_ok}), max |exact - inverse| = {worst:.2e}"
            );
            // at least the early times (the controls' onset) are resolved
            assert!(
                resolved >= 20,
                "n={n} d={d} {sig:?}: only {resolved} points resolved"
            );
        }
    }
}
