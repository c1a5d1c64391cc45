//! Simulator and exact residue sums against each other, against the Laplace
//! model and against the independent reference vectors in
//! `tests/data/time_*.json` (see tests/data/README.md).

use num_complex::Complex64;
use springmass::forward::response;
use springmass::time::modal::{ModalResponse, Modes};
use springmass::time::simulate::{
    simulate, simulate_forced, Force, Forcing, Method, SimOptions, Trajectory,
};
use springmass::{scenes, Chain, Defect};

fn max_diff(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

fn paper(n: usize, defects: &[(usize, f64)]) -> Chain {
    Chain::paper(n)
        .unwrap()
        .with_defects(defects.iter().map(|&(at, m)| Defect::Mass { at, m }))
        .unwrap()
}

fn reference_path(scene: &str) -> Option<std::path::PathBuf> {
    let name = format!("time_{scene}.json");
    let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(&name);
    p.exists().then_some(p)
}

#[test]
fn matches_reference_time_series_for_all_scenes() {
    let mut worst = 0.0_f64;
    for scene in ["P1", "P2", "P3", "P4", "S1", "S2", "S3", "S4"] {
        let path = reference_path(scene)
            .unwrap_or_else(|| panic!("reference time_{scene}.json not found"));
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
        let n = v["n"].as_u64().unwrap() as usize;
        let d = v["d"].as_f64().unwrap();
        let defects: Vec<(usize, f64)> = v["defects"]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| (p[0].as_u64().unwrap() as usize, p[1].as_f64().unwrap()))
            .collect();
        let chain = paper(n, &defects).with_d(d).unwrap();
        let col = |k: &str| -> Vec<f64> {
            v[k].as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_f64().unwrap())
                .collect()
        };
        let t = col("t");
        assert_eq!(t[1], 0.5);
        let (x1, xn) = (col("x1_expm"), col("xn_expm"));
        let (x1b, xnb) = (col("x1"), col("xn"));
        for method in [Method::Expm, Method::Rk, Method::Modal] {
            let opts = SimOptions::new(200.0, 0.5)
                .with_observe(vec![1, n])
                .with_method(method);
            let tr = simulate(&chain, &opts).unwrap();
            assert_eq!(tr.t, t);
            let e1 = max_diff(tr.x(1).unwrap(), &x1);
            let en = max_diff(tr.x(n).unwrap(), &xn);
            let e1b = max_diff(tr.x(1).unwrap(), &x1b);
            let enb = max_diff(tr.x(n).unwrap(), &xnb);
            println!(
                "{scene} {method:>5}: |x1 - ref_expm| {e1:.2e} |xn - ref_expm| {en:.2e} |x1 - ref_dop853| {e1b:.2e} |xn - ref_dop853| {enb:.2e}"
            );
            worst = worst.max(e1).max(en);
            assert!(e1 < 1e-12 && en < 1e-12, "{scene} {method}: {e1:e} {en:e}");
            assert!(
                e1b < 1e-12 && enb < 1e-12,
                "{scene} {method}: {e1b:e} {enb:e}"
            );
        }
    }
    println!("worst difference from the reference: {worst:.2e}");
}

#[test]
fn three_paths_agree_to_1e_10_on_0_300_for_n_20() {
    for chain in [
        scenes::by_name("P1").unwrap(),
        scenes::by_name("P3").unwrap(),
        Chain::paper(20).unwrap(),
        Chain::new(20)
            .unwrap()
            .with_defect(Defect::Damper { at: 7, d: 0.5 })
            .unwrap(),
    ] {
        let opts = SimOptions::new(300.0, 0.1).with_observe(vec![1, 20]);
        let run = |m| simulate(&chain, &opts.clone().with_method(m)).unwrap();
        let (e, r, m) = (run(Method::Expm), run(Method::Rk), run(Method::Modal));
        let exact = ModalResponse::impulse(&chain, 1).unwrap();
        let ex = exact.eval_many(&e.t);
        let d_em = max_diff(e.x(1).unwrap(), &ex);
        let d_rm = max_diff(r.x(1).unwrap(), &ex);
        let d_er = max_diff(e.x(1).unwrap(), r.x(1).unwrap());
        let d_n = max_diff(e.x(20).unwrap(), m.x(20).unwrap());
        println!(
            "n=20 {:?}: expm-modal {d_em:.2e} rk-modal {d_rm:.2e} expm-rk {d_er:.2e} x20 expm-modal {d_n:.2e} (modal bound {:.1e})",
            chain.defects(),
            exact.error_bound()
        );
        assert!(d_em < 1e-10 && d_rm < 1e-10 && d_er < 1e-10 && d_n < 1e-10);
    }
}

/// Composite Simpson of `e^{-st} x(t)` on the simulated samples, with one
/// Richardson step (`(16 S_h - S_2h) / 15`, order 6).
fn simpson_laplace(tr: &Trajectory, s: f64) -> f64 {
    let x = tr.x(1).unwrap();
    let h = tr.t[1] - tr.t[0];
    let m = (x.len() - 1) / 4 * 4;
    let f = |k: usize| (-s * tr.t[k]).exp() * x[k];
    let simpson = |stride: usize| {
        let mut sum = f(0) + f(m);
        for (j, k) in (stride..m).step_by(stride).enumerate() {
            sum += if j % 2 == 0 { 4.0 } else { 2.0 } * f(k);
        }
        sum * h * stride as f64 / 3.0
    };
    (16.0 * simpson(1) - simpson(2)) / 15.0
}

#[test]
fn transform_of_simulation_matches_laplace_model() {
    let chain = scenes::by_name("P1").unwrap();
    let tr = simulate(&chain, &SimOptions::new(100.0, 0.01)).unwrap();
    for s in [0.5, 1.0, 2.0] {
        let want = response(&chain, s, 1).unwrap();
        let got = simpson_laplace(&tr, s);
        println!("s={s}: Simpson of simulated x1 {got:.15e}, X_1(s) {want:.15e}");
        assert!((got - want).abs() < 1e-11, "s={s}: {got} vs {want}");
    }
    // the residue sum's own transform, at complex s
    let modal = ModalResponse::impulse(&chain, 1).unwrap();
    for s in [
        Complex64::new(0.05, 0.3),
        Complex64::new(0.1, 0.7),
        Complex64::new(1.0, 5.0),
    ] {
        let d = (modal.laplace(s) - response(&chain, s, 1).unwrap()).norm();
        assert!(d < 1e-11, "s={s}: {d:e}");
    }
}

/// Exact forced response: `x_i = G_ij * f` for `f(t) = Re(A e^{q t})`, by
/// convolving each pole term `r e^{pt}` with `e^{qt}` analytically.
fn exact_forced(chain: &Chain, i: usize, j: usize, amp: Complex64, q: Complex64, t: f64) -> f64 {
    let g = Modes::new(chain).unwrap().response(i, j, 1.0).unwrap();
    let free = ModalResponse::impulse(chain, i).unwrap().eval(t);
    let mut forced = Complex64::new(0.0, 0.0);
    for pr in g.poles() {
        assert_eq!(pr.order, 1);
        // Re(A e^{qt}) = (A e^{qt} + conj(A) e^{conj(q) t}) / 2
        for (a, qq) in [(amp, q), (amp.conj(), q.conj())] {
            let conv = ((qq * t).exp() - (pr.pole * t).exp()) / (qq - pr.pole);
            forced += pr.residue * a * 0.5 * conv;
        }
    }
    free + forced.re
}

#[test]
fn forced_paths_match_exact_convolution() {
    let chain = paper(12, &[(4, 3.0)]);
    let (amp, q) = (Complex64::new(0.2, -0.1), Complex64::new(-0.05, 0.8));
    let f = move |t: f64| (amp * (q * t).exp()).re;
    let forcing = Forcing::new().on(12, f);
    let opts = SimOptions::new(60.0, 0.25).with_observe(vec![1, 12]);
    for method in [Method::Expm, Method::Rk] {
        let tr = simulate_forced(&chain, &opts.clone().with_method(method), &forcing).unwrap();
        for obs in [1, 12] {
            let ex: Vec<f64> =
                tr.t.iter()
                    .map(|&t| exact_forced(&chain, obs, 12, amp, q, t))
                    .collect();
            let e = max_diff(tr.x(obs).unwrap(), &ex);
            println!("forced {method}: x{obs} max error {e:.2e}");
            assert!(e < 1e-11, "{method} x{obs}: {e:e}");
        }
    }
    // the force matters: the forced and free runs differ at mass 12
    let free = simulate(&chain, &opts).unwrap();
    let forced = simulate_forced(&chain, &opts, &forcing).unwrap();
    assert!(max_diff(free.x(12).unwrap(), forced.x(12).unwrap()) > 1e-2);
}

#[test]
fn polynomial_forces_are_integrated_exactly() {
    // a cubic force on two masses; q = 8 nodes integrate it exactly, so the
    // result is independent of the step and of the method
    let chain = paper(6, &[(2, 2.0)]);
    let forcing = Forcing::new()
        .on(6, |t| 0.3 + 0.2 * t - 0.01 * t * t + 1e-4 * t * t * t)
        .on(3, |t| -0.1 * t);
    let coarse = SimOptions::new(20.0, 1.0).with_observe(vec![1, 3, 6]);
    let a = simulate_forced(&chain, &coarse.clone().with_method(Method::Expm), &forcing).unwrap();
    let b = simulate_forced(
        &chain,
        &coarse.clone().with_method(Method::Expm).with_substeps(7),
        &forcing,
    )
    .unwrap();
    let c = simulate_forced(&chain, &coarse.clone().with_method(Method::Rk), &forcing).unwrap();
    for i in [1, 3, 6] {
        let (ab, ac) = (
            max_diff(a.x(i).unwrap(), b.x(i).unwrap()),
            max_diff(a.x(i).unwrap(), c.x(i).unwrap()),
        );
        assert!(ab < 1e-11 && ac < 1e-11, "x{i}: {ab:e} {ac:e}");
    }
}

#[test]
fn sampled_force_matches_closure_to_interpolation_accuracy() {
    let chain = paper(8, &[]);
    let f = |t: f64| 0.1 * (0.6 * t).sin() * (-0.02 * t).exp();
    let ts: Vec<f64> = (0..=400).map(|k| k as f64 * 0.05).collect();
    let fs: Vec<f64> = ts.iter().map(|&t| f(t)).collect();
    let opts = SimOptions::new(20.0, 0.05).with_observe(vec![8]);
    let exact = simulate_forced(&chain, &opts, &Forcing::new().on(8, f)).unwrap();
    let mut prev = f64::INFINITY;
    for order in [1, 3, 5] {
        let sampled =
            Forcing::new().with(8, Force::sampled(ts.clone(), fs.clone(), order).unwrap());
        let tr = simulate_forced(&chain, &opts, &sampled).unwrap();
        let e = max_diff(tr.x(8).unwrap(), exact.x(8).unwrap());
        println!("sampled force, order {order}: max error {e:.2e}");
        assert!(e < prev, "order {order} not better: {e:e}");
        prev = e;
    }
    assert!(prev < 1e-9);
}

#[test]
fn static_limit_of_a_constant_force() {
    // x(inf) = K^{-1} f for f = e_3; with d = 0.5 the transient is gone by t = 400
    let chain = Chain::new(5)
        .unwrap()
        .with_d(0.5)
        .unwrap()
        .with_gamma(0.0)
        .unwrap();
    let tr = simulate_forced(
        &chain,
        &SimOptions::new(400.0, 1.0).with_observe(vec![1, 2, 3, 4, 5]),
        &Forcing::new().on(3, |_| 1.0),
    )
    .unwrap();
    // K = tridiag(-1, 2, -1), n = 5: column 3 of K^{-1} = (1, 2, 3, 2, 1) / 2
    for (i, want) in [0.5, 1.0, 1.5, 1.0, 0.5].iter().enumerate() {
        let got = *tr.x(i + 1).unwrap().last().unwrap();
        assert!((got - want).abs() < 1e-12, "x{} = {got}", i + 1);
    }
}

#[test]
fn large_chain_rk_matches_closed_form_modes() {
    let n = 10_000;
    let chain = Chain::paper(n).unwrap();
    let opts = SimOptions::new(30.0, 0.5).with_observe(vec![1, 2, 40]);
    let tr = simulate(&chain, &opts).unwrap();
    assert_eq!(tr.method, Method::Rk);
    let modes = Modes::new(&chain).unwrap();
    for i in [1, 2, 40] {
        let ex = modes.response(i, 1, 1.0).unwrap().eval_many(&tr.t);
        let e = max_diff(tr.x(i).unwrap(), &ex);
        println!("n = 10^4 rk vs closed-form modes: x{i} {e:.2e}");
        assert!(e < 1e-12, "x{i}: {e:e}");
    }
}

#[test]
fn bad_input_gives_clear_errors() {
    let chain = Chain::paper(5).unwrap();
    let err = |o: SimOptions| simulate(&chain, &o).unwrap_err().to_string();
    assert!(err(SimOptions::new(10.0, 0.0)).contains("dt"));
    assert!(err(SimOptions::new(10.0, -1.0)).contains("dt"));
    assert!(err(SimOptions::new(10.0, f64::NAN)).contains("dt"));
    assert!(err(SimOptions::new(0.0, 0.1)).contains("t_end"));
    assert!(err(SimOptions::new(-5.0, 0.1)).contains("t_end"));
    assert!(err(SimOptions::new(1e9, 1e-3)).contains("stored values"));
    assert!(err(SimOptions::new(10.0, 0.1).with_observe(vec![6])).contains("observe"));
    assert!(err(SimOptions::new(10.0, 0.1).with_observe(vec![0])).contains("observe"));
    assert!(err(SimOptions::new(10.0, 0.1).with_observe(vec![])).contains("observe"));
    assert!(err(SimOptions::new(10.0, 0.1).with_force_nodes(0)).contains("force_nodes"));
    let opts = SimOptions::new(10.0, 0.1);
    let e = simulate_forced(&chain, &opts, &Forcing::new().on(9, |_| 1.0)).unwrap_err();
    assert!(e.to_string().contains("forcing[0].at"), "{e}");
    let e = simulate_forced(
        &chain,
        &opts.clone().with_method(Method::Modal),
        &Forcing::new().on(2, |_| 1.0),
    )
    .unwrap_err();
    assert!(e.to_string().contains("modal"), "{e}");
    let e = simulate_forced(
        &chain,
        &opts,
        &Forcing::new().on(2, |t| 1.0 / (t - 5.0).abs().min(0.0)),
    )
    .unwrap_err();
    assert!(e.to_string().contains("mass 2"), "{e}");
    assert!(Force::sampled(vec![0.0, 0.0], vec![1.0, 2.0], 1).is_err());
    assert!(Force::sampled(vec![0.0, 1.0], vec![1.0, 2.0], 0).is_err());
    assert!("euler".parse::<Method>().is_err());
}

// ---------------------------------------------------------------- the CLI

fn cli(args: &[&str]) -> (i32, String, String) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_springmass"))
        .arg("simulate")
        .args(args)
        .output()
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn tmp_dir(tag: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("springmass-sim-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn cli_reproduces_paper_figures_10_12_14() {
    let dir = tmp_dir("figs");
    for (fig, n, defect) in [
        (10, "20", "mass:15:1.01"),
        (12, "5", "mass:3:4"),
        (14, "20", "mass:3:5"),
    ] {
        let svg = dir.join(format!("fig{fig}.svg"));
        let csv = dir.join(format!("fig{fig}.csv"));
        let (code, _, err) = cli(&[
            "--n",
            n,
            "--defect",
            defect,
            "--t-end",
            "200",
            "--dt",
            "0.05",
            "--out",
            csv.to_str().unwrap(),
            "--plot",
            svg.to_str().unwrap(),
        ]);
        assert_eq!(code, 0, "{err}");
        let text = std::fs::read_to_string(&svg).unwrap();
        assert!(text.contains("<svg") && text.contains("x_1"), "fig {fig}");
        // the CSV is the exact x_1 (residue sum) to 1e-12
        let ts = springmass::series::TimeSeries::read_csv(&csv).unwrap();
        let (j, m): (usize, f64) = {
            let p: Vec<&str> = defect.split(':').collect();
            (p[1].parse().unwrap(), p[2].parse().unwrap())
        };
        let chain = paper(n.parse().unwrap(), &[(j, m)]);
        let ex = ModalResponse::impulse(&chain, 1).unwrap().eval_many(ts.t());
        assert_eq!(ts.len(), 4001);
        assert!(max_diff(ts.column("x1").unwrap(), &ex) < 1e-12, "fig {fig}");
    }
}

#[test]
fn cli_noise_is_seeded_and_forces_are_read() {
    let base = [
        "--n",
        "6",
        "--t-end",
        "5",
        "--dt",
        "0.5",
        "--observe",
        "1,6",
    ];
    let with = |extra: &[&str]| {
        let mut v: Vec<&str> = base.to_vec();
        v.extend_from_slice(extra);
        let (code, out, err) = cli(&v);
        assert_eq!(code, 0, "{err}");
        springmass::series::TimeSeries::from_csv_str(&out).unwrap()
    };
    let clean = with(&[]);
    let a = with(&["--noise", "0.01", "--seed", "7"]);
    let b = with(&["--noise", "0.01", "--seed", "7"]);
    let c = with(&["--noise", "0.01", "--seed", "8"]);
    assert_eq!(a, b);
    assert_ne!(a, c);
    let d = max_diff(a.column("x6").unwrap(), clean.column("x6").unwrap());
    assert!(d > 1e-4 && d < 0.1, "{d}");
    let e = with(&["--noise", "snr:40", "--seed", "7"]);
    assert_ne!(e, clean);
    assert_eq!(e, with(&["--noise", "snr:40", "--seed", "7"]));
    // a force file: f6 acts on mass 6
    let dir = tmp_dir("force");
    let f = dir.join("f.csv");
    let ts: Vec<f64> = (0..=50).map(|k| k as f64 * 0.1).collect();
    let fs: Vec<f64> = ts.iter().map(|t| 0.5 * t).collect();
    springmass::series::TimeSeries::new(ts, vec![("f6".into(), fs)])
        .unwrap()
        .write_csv(&f)
        .unwrap();
    let forced = with(&["--force", f.to_str().unwrap(), "--force-order", "1"]);
    let lib = simulate_forced(
        &Chain::paper(6).unwrap(),
        &SimOptions::new(5.0, 0.5).with_observe(vec![1, 6]),
        &Forcing::new().on(6, |t| 0.5 * t),
    )
    .unwrap();
    assert!(max_diff(forced.column("x6").unwrap(), lib.x(6).unwrap()) < 1e-12);
    // a badly named force column
    std::fs::write(dir.join("g.csv"), "t,force6\n0,1\n1,2\n").unwrap();
    let (code, _, err) = cli(&["--n", "6", "--force", dir.join("g.csv").to_str().unwrap()]);
    assert_eq!(code, 2);
    assert!(err.contains("f<j>"), "{err}");
}

#[test]
fn cli_bad_input() {
    for (args, needle) in [
        (vec!["--n", "5", "--dt", "0"], "dt"),
        (vec!["--n", "5", "--dt", "-0.1"], "dt"),
        (vec!["--n", "5", "--t-end", "0"], "t_end"),
        (
            vec!["--n", "5", "--t-end", "1e9", "--dt", "1e-3"],
            "stored values",
        ),
        (vec!["--n", "5", "--observe", "1,6"], "observe"),
        (vec!["--n", "5", "--noise", "-1"], "noise"),
        (vec!["--n", "5", "--noise", "loud:3"], "noise"),
        (vec!["--n", "5", "--method", "euler"], "method"),
        (
            vec!["--n", "5", "--force", "/nonexistent/f.csv"],
            "/nonexistent/f.csv",
        ),
    ] {
        let (code, _, err) = cli(&args);
        // a missing file is an I/O error (exit 3), the rest invalid input (2)
        let want = if args.contains(&"--force") { 3 } else { 2 };
        assert_eq!(code, want, "{args:?}");
        assert!(
            err.contains(needle) && err.lines().count() == 1,
            "{args:?}: {err}"
        );
    }
}

// ---------------------------------------------------------------- property tests

mod props {
    use super::*;
    use proptest::prelude::*;

    fn arb_chain() -> impl Strategy<Value = Chain> {
        (
            1usize..=14,
            prop_oneof![Just(0.0), 0.001f64..0.05, 0.05f64..3.0],
            0.3f64..4.0,
            0.3f64..4.0,
            proptest::collection::vec((0u8..4, 0usize..15, 0.05f64..12.0), 0..4),
        )
            .prop_map(|(n, d, k, mass, defs)| {
                let mut c = Chain::new(n)
                    .unwrap()
                    .with_d(d)
                    .unwrap()
                    .with_k(k)
                    .unwrap()
                    .with_mass(mass)
                    .unwrap();
                for (kind, at, v) in defs {
                    let def = match kind {
                        0 => Defect::Mass {
                            at: 1 + at % n,
                            m: v,
                        },
                        1 => Defect::Spring {
                            at: at % (n + 1),
                            k: v,
                        },
                        2 => Defect::Damper {
                            at: 1 + at % n,
                            d: v,
                        },
                        _ => Defect::Ground {
                            at: 1 + at % n,
                            g: v,
                        },
                    };
                    if let Ok(c2) = c.clone().with_defect(def) {
                        c = c2;
                    }
                }
                c
            })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(96))]

        /// The residue sum's transform is the forward model, and the
        /// simulator (both stepping methods) matches the residue sum.
        #[test]
        fn modal_simulator_and_laplace_model_agree(chain in arb_chain()) {
            let n = chain.n();
            let modal = ModalResponse::impulse(&chain, n).unwrap();
            for s in [Complex64::new(0.3, 0.9), Complex64::new(1.0, 0.0), Complex64::new(0.05, 2.0)] {
                let want = response(&chain, s, n).unwrap();
                let got = modal.laplace(s);
                prop_assert!((got - want).norm() <= 1e-9 * want.norm() + 1e3 * modal.error_bound(),
                    "{chain:?} s={s}: {got} vs {want}");
            }
            let opts = SimOptions::new(40.0, 0.5).with_observe(vec![n]);
            let ex = modal.eval_many(&opts.samples(&chain).map(|k| (0..k).map(|i| i as f64 * 0.5).collect::<Vec<_>>()).unwrap());
            let scale = ex.iter().fold(1e-3_f64, |a, b| a.max(b.abs()));
            for m in [Method::Expm, Method::Rk] {
                let tr = simulate(&chain, &opts.clone().with_method(m)).unwrap();
                let e = max_diff(tr.x(n).unwrap(), &ex);
                prop_assert!(e <= 1e-11 * scale + 10.0 * modal.error_bound(),
                    "{chain:?} {m}: {e:e} (scale {scale:e}, bound {:e})", modal.error_bound());
            }
        }
    }
}

#[test]
fn large_chain_forced_rk_matches_exact_convolution() {
    // n = 10^4 (closed-form modes), a damped oscillating force on mass 5
    let n = 10_000;
    let chain = Chain::paper(n).unwrap();
    let (amp, q) = (Complex64::new(0.3, 0.2), Complex64::new(-0.1, 1.3));
    let forcing = Forcing::new().on(5, move |t| (amp * (q * t).exp()).re);
    let opts = SimOptions::new(15.0, 0.5).with_observe(vec![1, 5]);
    let tr = simulate_forced(&chain, &opts, &forcing).unwrap();
    assert_eq!(tr.method, Method::Rk);
    for obs in [1, 5] {
        let ex: Vec<f64> =
            tr.t.iter()
                .map(|&t| exact_forced(&chain, obs, 5, amp, q, t))
                .collect();
        let e = max_diff(tr.x(obs).unwrap(), &ex);
        println!("n = 10^4 forced rk: x{obs} max error {e:.2e}");
        assert!(e < 1e-12, "x{obs}: {e:e}");
    }
}
