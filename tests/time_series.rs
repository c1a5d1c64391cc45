//! Laplace transform of sampled series against the forward model.
//!
//! The series is the exact impulse response of a uniform chain (modal sum:
//! `x_1(t) = Σ_k (2/(n+1)) sin^2(k pi/(n+1)) e^{-d t/2} sin(w_k t)/w_k`,
//! `w_k^2 = 2 - 2 cos(k pi/(n+1)) - d^2/4`), sampled at dt = 0.01 on [0, 300],
//! and its transform is compared with the closed-form `X_1(s)` of `Forward`.

use springmass::forward::Forward;
use springmass::series::TimeSeries;
use springmass::time::series::{SeriesTransform, Tail, TransformOptions};
use springmass::{Chain, Complex64, Error};

/// Exact x_1(t) of a uniform chain (k = 1, unit masses, gamma = 1, damping d, underdamped).
fn x1_uniform(n: usize, d: f64, t: f64) -> f64 {
    let np1 = (n + 1) as f64;
    (1..=n)
        .map(|k| {
            let th = k as f64 * std::f64::consts::PI / np1;
            let amp = 2.0 / np1 * th.sin().powi(2);
            let w = (2.0 - 2.0 * th.cos() - 0.25 * d * d).sqrt();
            amp * (-0.5 * d * t).exp() * (w * t).sin() / w
        })
        .sum()
}

fn sampled(n: usize, d: f64, dt: f64, t_end: f64) -> (Vec<f64>, Vec<f64>) {
    let m = (t_end / dt).round() as usize;
    let t: Vec<f64> = (0..=m).map(|i| i as f64 * dt).collect();
    let x = t.iter().map(|&t| x1_uniform(n, d, t)).collect();
    (t, x)
}

fn s_grid() -> Vec<Complex64> {
    let mut s = Vec::new();
    // real s, log-spaced on [0.05, 300]
    for i in 0..=40 {
        let v = 0.05 * (300.0f64 / 0.05).powf(i as f64 / 40.0);
        s.push(Complex64::new(v, 0.0));
    }
    // Bromwich line s = 0.05 + i w, w in [0, 3]
    for i in 0..=60 {
        s.push(Complex64::new(0.05, 3.0 * i as f64 / 60.0));
    }
    s
}

#[test]
fn acceptance_dt_001_on_0_300_matches_forward_model() {
    let n = 20;
    let chain = Chain::paper(n).unwrap();
    let fwd = Forward::new(&chain);
    let (t, x) = sampled(n, chain.d(), 0.01, 300.0);
    let tr = SeriesTransform::new(&t, &x, &TransformOptions::default()).unwrap();
    let mut worst_rel: f64 = 0.0;
    let mut worst_ratio: f64 = 0.0;
    for s in s_grid() {
        let exact = fwd.eval(s, 1).unwrap();
        let v = tr.eval(s).unwrap();
        let err = (v.value - exact).norm();
        let rel = err / exact.norm();
        worst_rel = worst_rel.max(rel);
        worst_ratio = worst_ratio.max(err / v.err);
        assert!(rel < 1e-8, "s = {s}: rel error {rel:.3e}");
        assert!(
            err <= v.err,
            "s = {s}: error {err:.3e} above estimate {:.3e}",
            v.err
        );
    }
    println!(
        "n=20 dt=0.01 [0,300]: max relative error {worst_rel:.3e}, max true/estimated error {worst_ratio:.3e}"
    );
}

#[test]
fn error_estimate_bounds_truncation_down_to_s_0001() {
    let n = 20;
    let chain = Chain::paper(n).unwrap();
    let fwd = Forward::new(&chain);
    let (t, x) = sampled(n, chain.d(), 0.01, 300.0);
    let tr = SeriesTransform::new(&t, &x, &TransformOptions::default()).unwrap();
    for &s in &[
        Complex64::new(0.001, 0.0),
        Complex64::new(0.003, 0.0),
        Complex64::new(0.01, 0.0),
        Complex64::new(0.02, 0.0),
        Complex64::new(0.001, 0.5),
        Complex64::new(0.001, 1.3),
        Complex64::new(0.01, 2.0),
    ] {
        let exact = fwd.eval(s, 1).unwrap();
        let v = tr.eval(s).unwrap();
        let err = (v.value - exact).norm();
        println!(
            "s = {s}: true error {err:.3e}, estimate {:.3e} (trunc {:.3e}, disc {:.3e})",
            v.err, v.err_trunc, v.err_disc
        );
        assert!(
            err <= v.err,
            "s = {s}: error {err:.3e} above estimate {:.3e}",
            v.err
        );
        assert!(
            v.err_trunc > v.err_disc,
            "truncation should dominate at s = {s}"
        );
    }
}

#[test]
fn short_records_truncation_dominates_and_is_bounded() {
    // A record that stops early (t_end = 60): the tail is large; the bound must hold.
    for &n in &[3usize, 8] {
        let chain = Chain::paper(n).unwrap();
        let fwd = Forward::new(&chain);
        let (t, x) = sampled(n, chain.d(), 0.05, 60.0);
        let tr = SeriesTransform::new(&t, &x, &TransformOptions::default()).unwrap();
        for s in [0.001, 0.01, 0.05, 0.2, 1.0]
            .map(|v| Complex64::new(v, 0.0))
            .into_iter()
            .chain([0.3, 0.9, 1.7].map(|w| Complex64::new(0.02, w)))
        {
            let exact = fwd.eval(s, 1).unwrap();
            let v = tr.eval(s).unwrap();
            let err = (v.value - exact).norm();
            assert!(
                err <= v.err,
                "n={n} s = {s}: error {err:.3e} above estimate {:.3e}",
                v.err
            );
        }
    }
}

#[test]
fn coarse_and_nonuniform_sampling_estimate_still_bounds() {
    let n = 5;
    let chain = Chain::paper(n).unwrap();
    let fwd = Forward::new(&chain);
    for &dt in &[0.02, 0.1, 0.3] {
        // nonuniform: a smooth stretch of a uniform grid
        let m = (300.0 / dt) as usize;
        let t: Vec<f64> = (0..=m)
            .map(|i| {
                let u = i as f64 / m as f64;
                300.0 * (u + 0.05 * (std::f64::consts::PI * u).sin().powi(2) * (1.0 - u))
            })
            .collect();
        let x: Vec<f64> = t.iter().map(|&t| x1_uniform(n, chain.d(), t)).collect();
        let tr = SeriesTransform::new(&t, &x, &TransformOptions::default()).unwrap();
        for s in s_grid() {
            let exact = fwd.eval(s, 1).unwrap();
            let v = tr.eval(s).unwrap();
            let err = (v.value - exact).norm();
            assert!(
                err <= v.err,
                "dt={dt} s = {s}: error {err:.3e} above estimate {:.3e}",
                v.err
            );
        }
    }
}

#[test]
fn noise_variance_matches_monte_carlo() {
    use springmass::noise::{add_noise, NoiseLevel};
    let n = 5;
    let chain = Chain::paper(n).unwrap();
    let (t, x) = sampled(n, chain.d(), 0.05, 100.0);
    let sigma = 1e-3;
    let opts = TransformOptions {
        noise_sigma: Some(sigma),
        tail: Tail::Zero,
        ..Default::default()
    };
    let s = Complex64::new(0.2, 1.0);
    let clean = SeriesTransform::new(&t, &x, &opts)
        .unwrap()
        .eval(s)
        .unwrap();
    let var = clean.noise_var.unwrap();
    let trials = 200;
    let mut acc = 0.0;
    for seed in 0..trials {
        let (noisy, _) = add_noise(&x, NoiseLevel::Absolute(sigma), seed).unwrap();
        let v = SeriesTransform::new(&t, &noisy, &opts)
            .unwrap()
            .eval(s)
            .unwrap();
        acc += (v.value - clean.value).norm_sqr();
    }
    let emp = acc / trials as f64;
    // chi-square with ~2*200 degrees of freedom: within 25 %
    assert!(
        (emp / var - 1.0).abs() < 0.25,
        "empirical {emp:.3e} vs predicted {var:.3e}"
    );
}

#[test]
fn transform_from_csv_column() {
    let n = 4;
    let chain = Chain::paper(n).unwrap();
    let fwd = Forward::new(&chain);
    let (t, x) = sampled(n, chain.d(), 0.01, 300.0);
    let ts = TimeSeries::new(t, vec![("x1".into(), x)]).unwrap();
    let back = TimeSeries::from_csv_str(&ts.to_csv_string()).unwrap();
    let tr = SeriesTransform::from_series(&back, "x1", &TransformOptions::default()).unwrap();
    let s = Complex64::new(0.5, 0.0);
    let v = tr.eval(s).unwrap();
    let exact = fwd.eval(s, 1).unwrap();
    assert!((v.value - exact).norm() <= v.err);
    let e = SeriesTransform::from_series(&back, "x7", &TransformOptions::default()).unwrap_err();
    assert!(matches!(e, Error::InvalidParameter { .. }));
    assert!(
        e.to_string().contains("x7") && e.to_string().contains("x1"),
        "{e}"
    );
}

#[test]
fn bad_input_names_field_or_line() {
    let o = TransformOptions::default();
    let cases: Vec<(Vec<f64>, Vec<f64>, &str)> = vec![
        (vec![0.0, 2.0, 1.0, 3.0], vec![0.0; 4], "t[2]"),
        (vec![0.0, 1.0, 1.0, 3.0], vec![0.0; 4], "t[2]"),
        (
            vec![0.0, 1.0, 2.0, 3.0],
            vec![0.0, 0.0, 0.0, f64::NAN],
            "x[3]",
        ),
        (vec![0.0, f64::INFINITY, 2.0, 3.0], vec![0.0; 4], "t[1]"),
        (vec![0.0, 1.0, 2.0, 3.0], vec![0.0; 3], "x.len"),
    ];
    for (t, x, needle) in cases {
        let e = SeriesTransform::new(&t, &x, &o).unwrap_err().to_string();
        assert!(e.contains(needle), "{needle}: {e}");
    }
    for dt in [0.0, -1.0, f64::NAN] {
        let e = SeriesTransform::uniform(0.0, dt, &[0.0; 10], &o)
            .unwrap_err()
            .to_string();
        assert!(e.contains("dt"), "{e}");
    }
    // CSV problems name the line (TimeSeries), consistent with the above
    for (text, needle) in [
        ("t,x1\n0,1\n1\n", "line 3"),
        ("t,x1\n0,1\n1,nan\n", "line 3"),
        ("t,x1\n0,1\n0,2\n", "line 3"),
    ] {
        let e = TimeSeries::from_csv_str(text).unwrap_err().to_string();
        assert!(e.contains(needle), "{e}");
    }
    let bad = TransformOptions {
        degree: 12,
        ..Default::default()
    };
    let e = SeriesTransform::new(&[0.0, 1.0, 2.0, 3.0], &[0.0; 4], &bad)
        .unwrap_err()
        .to_string();
    assert!(e.contains("degree"), "{e}");
}

#[test]
fn cli_laplace_text_json_and_errors() {
    use std::process::Command;
    let n = 4;
    let chain = Chain::paper(n).unwrap();
    let fwd = Forward::new(&chain);
    let (t, x) = sampled(n, chain.d(), 0.01, 300.0);
    let ts = TimeSeries::new(t, vec![("x1".into(), x)]).unwrap();
    let dir = std::env::temp_dir().join(format!("springmass-laplace-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let csv = dir.join("x1.csv");
    ts.write_csv(&csv).unwrap();
    let bin = env!("CARGO_BIN_EXE_springmass");
    let out = Command::new(bin)
        .args([
            "laplace",
            "--series",
            csv.to_str().unwrap(),
            "--s",
            "0.5,0.05+1i",
            "--json",
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let pts = v["points"].as_array().unwrap();
    assert_eq!(pts.len(), 2);
    for p in pts {
        let s = Complex64::new(p["s"][0].as_f64().unwrap(), p["s"][1].as_f64().unwrap());
        let x = Complex64::new(p["x"][0].as_f64().unwrap(), p["x"][1].as_f64().unwrap());
        let err = p["err"].as_f64().unwrap();
        let exact = fwd.eval(s, 1).unwrap();
        assert!(
            (x - exact).norm() <= err && err < 1e-9,
            "{s}: {x} vs {exact}, err {err}"
        );
    }
    // text output has a header and one row per s
    let out = Command::new(bin)
        .args([
            "laplace",
            "--series",
            csv.to_str().unwrap(),
            "--column",
            "x1",
            "--s",
            "1,2,3",
        ])
        .output()
        .unwrap();
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    assert_eq!(
        text.lines().filter(|l| !l.starts_with('#')).count(),
        4,
        "{text}"
    );
    // the mode-fit tail: fitted for this 4-mass record, and accurate at small s
    let out = Command::new(bin)
        .args([
            "laplace",
            "--series",
            csv.to_str().unwrap(),
            "--s",
            "0.001",
            "--tail",
            "modes",
            "--json",
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let x = v["points"][0]["x"][0].as_f64().unwrap();
    let err = v["points"][0]["err"].as_f64().unwrap();
    let exact = fwd.eval(0.001, 1).unwrap();
    assert!(
        (x - exact).abs() <= err && err < 1e-12,
        "{x} vs {exact}, err {err}"
    );
    // errors: missing column, bad CSV (duplicate time, naming the line), bad s
    let bad = dir.join("bad.csv");
    std::fs::write(&bad, "t,x1\n0,0\n0.5,1\n0.5,2\n1,3\n").unwrap();
    for (args, needle) in [
        (
            vec![
                "--series",
                csv.to_str().unwrap(),
                "--column",
                "x9",
                "--s",
                "1",
            ],
            "x9",
        ),
        (
            vec!["--series", bad.to_str().unwrap(), "--s", "1"],
            "line 4",
        ),
        (
            vec!["--series", csv.to_str().unwrap(), "--s", "1+zi"],
            "1+zi",
        ),
    ] {
        let out = Command::new(bin)
            .arg("laplace")
            .args(&args)
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(2));
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(needle) && err.lines().count() == 1, "{err}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn defect_chains_from_the_modal_sum_match_the_forward_model() {
    use springmass::time::modal::ModalResponse;
    use springmass::Defect;
    // P2 (n=5, mass 4 at 3), S3 (n=20, masses 5 at 8 and 2 at 15), and a
    // spring + damper defect chain; dt = 0.01 on [0, 300].
    let chains = [
        Chain::paper(5)
            .unwrap()
            .with_defect(Defect::Mass { at: 3, m: 4.0 })
            .unwrap(),
        Chain::paper(20)
            .unwrap()
            .with_defect(Defect::Mass { at: 8, m: 5.0 })
            .unwrap()
            .with_defect(Defect::Mass { at: 15, m: 2.0 })
            .unwrap(),
        Chain::paper(8)
            .unwrap()
            .with_defect(Defect::Spring { at: 4, k: 0.5 })
            .unwrap()
            .with_defect(Defect::Damper { at: 6, d: 0.4 })
            .unwrap(),
    ];
    for chain in chains {
        let fwd = Forward::new(&chain);
        let modal = ModalResponse::impulse(&chain, 1).unwrap();
        let t: Vec<f64> = (0..=30000).map(|i| i as f64 * 0.01).collect();
        let x = modal.eval_many(&t);
        let tr = SeriesTransform::new(&t, &x, &TransformOptions::default()).unwrap();
        let mut worst: f64 = 0.0;
        for s in s_grid() {
            let exact = fwd.eval(s, 1).unwrap();
            let v = tr.eval(s).unwrap();
            let err = (v.value - exact).norm();
            worst = worst.max(err / exact.norm());
            assert!(
                err / exact.norm() < 1e-8,
                "{:?} s = {s}: rel {:.3e}",
                chain.defects(),
                err / exact.norm()
            );
            assert!(
                err <= v.err,
                "{:?} s = {s}: {err:.3e} > est {:.3e}",
                chain.defects(),
                v.err
            );
        }
        for s in [0.001, 0.01].map(|v| Complex64::new(v, 0.0)) {
            let v = tr.eval(s).unwrap();
            let err = (v.value - fwd.eval(s, 1).unwrap()).norm();
            assert!(
                err <= v.err,
                "{:?} s = {s}: {err:.3e} > est {:.3e}",
                chain.defects(),
                v.err
            );
        }
        println!("{:?}: max relative error {worst:.2e}", chain.defects());
    }
}

#[test]
fn mode_fit_tail_correction_small_s() {
    let opts = TransformOptions {
        tail: Tail::Modes,
        ..Default::default()
    };
    for (n, t_end) in [(4usize, 300.0), (20, 300.0), (8, 100.0), (20, 60.0)] {
        let chain = Chain::paper(n).unwrap();
        let fwd = Forward::new(&chain);
        let (t, x) = sampled(n, chain.d(), 0.01, t_end);
        let tr = SeriesTransform::new(&t, &x, &opts).unwrap();
        let env = SeriesTransform::new(&t, &x, &TransformOptions::default()).unwrap();
        let fit = tr.mode_fit().map(|f| (f.poles.len(), f.residual));
        for s in [0.001, 0.01, 0.05]
            .map(|v| Complex64::new(v, 0.0))
            .into_iter()
            .chain([Complex64::new(0.001, 1.0)])
        {
            let exact = fwd.eval(s, 1).unwrap();
            let v = tr.eval(s).unwrap();
            let e = env.eval(s).unwrap();
            let err = (v.value - exact).norm();
            println!(
                "n={n} T={t_end} fit={fit:?} s={s}: modes err {err:.2e} est {:.2e} | envelope err {:.2e} est {:.2e}",
                v.err,
                (e.value - exact).norm(),
                e.err
            );
            assert!(err <= v.err, "n={n} s={s}: {err:.3e} > {:.3e}", v.err);
            if n <= 8 {
                // the fit is accepted for these few-mode records and beats the bound
                assert!(fit.is_some(), "n={n}: no mode fit");
                assert!(err < 1e-9, "n={n} s={s}: {err:.3e}");
            }
        }
    }
    // a defect chain (different decay rates per mode), from the modal sum
    use springmass::time::modal::ModalResponse;
    let chain = Chain::paper(5)
        .unwrap()
        .with_defect(springmass::Defect::Mass { at: 3, m: 4.0 })
        .unwrap();
    let fwd = Forward::new(&chain);
    let t: Vec<f64> = (0..=15000).map(|i| i as f64 * 0.01).collect();
    let x = ModalResponse::impulse(&chain, 1).unwrap().eval_many(&t);
    let tr = SeriesTransform::new(&t, &x, &opts).unwrap();
    // accepted or not (then the envelope bound is used), the estimate must hold
    for s in [0.001, 0.01, 0.1].map(|v| Complex64::new(v, 0.0)) {
        let v = tr.eval(s).unwrap();
        let err = (v.value - fwd.eval(s, 1).unwrap()).norm();
        assert!(err <= v.err, "P2 s={s}: {err:.3e} est {:.3e}", v.err);
        println!(
            "P2 fit accepted: {} s={s}: err {err:.2e} est {:.2e}",
            tr.mode_fit().is_some(),
            v.err
        );
    }
}
