//! Output-only (ambient) fits against a generator of their own: the exact
//! discretisation of the continuous state-space model under white forces
//! (matrix exponential of the dense state matrix, the discrete noise
//! covariance by Van Loan's method), independent of the fitted model's
//! tridiagonal frequency-domain path; bad records refused.

use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use springmass::chain::{Chain, Defect};
use springmass::detect::data::ambient::AmbientRecord;
use springmass::detect::fit::ambient::{fit_ambient, AmbientOptions, AmbientTarget};
use springmass::forward::Observable;
use springmass::time::modal::natural_modes;

use nalgebra::DMatrix;

/// The state matrix `[[0, I], [-M^-1 K, -M^-1 D]]` and the force input
/// `[0; M^-1 E_on]`, assembled densely from the chain's coefficient lists.
fn state_space(chain: &Chain, on: &[usize]) -> (DMatrix<f64>, DMatrix<f64>) {
    let n = chain.n();
    let c = chain.coefficients();
    let mut k = DMatrix::zeros(n, n);
    let mut d = DMatrix::zeros(n, n);
    for i in 0..n {
        k[(i, i)] = c.g[i] + c.k[i] + c.k[i + 1];
        d[(i, i)] = c.d[i] + c.c[i] + c.c[i + 1];
        if i + 1 < n {
            k[(i, i + 1)] = -c.k[i + 1];
            k[(i + 1, i)] = -c.k[i + 1];
            d[(i, i + 1)] = -c.c[i + 1];
            d[(i + 1, i)] = -c.c[i + 1];
        }
    }
    let minv = DMatrix::from_diagonal(&nalgebra::DVector::from_iterator(
        n,
        c.m.iter().map(|m| 1.0 / m),
    ));
    let mut a = DMatrix::zeros(2 * n, 2 * n);
    a.view_mut((0, n), (n, n)).fill_with_identity();
    a.view_mut((n, 0), (n, n)).copy_from(&(-&minv * k));
    a.view_mut((n, n), (n, n)).copy_from(&(-&minv * d));
    let mut b = DMatrix::zeros(2 * n, on.len());
    for (j, &m) in on.iter().enumerate() {
        b[(n + m - 1, j)] = minv[(m - 1, m - 1)];
    }
    (a, b)
}

/// `Phi = e^{A h}` and a square root of `Q_d = int_0^h e^{A t} B B^T e^{A^T t} dt`
/// (unit force intensity) by Van Loan's block exponential.
fn discretise(a: &DMatrix<f64>, b: &DMatrix<f64>, h: f64) -> (DMatrix<f64>, DMatrix<f64>) {
    let s = a.nrows();
    let mut c = DMatrix::zeros(2 * s, 2 * s);
    c.view_mut((0, 0), (s, s)).copy_from(&(-a * h));
    c.view_mut((0, s), (s, s))
        .copy_from(&(b * b.transpose() * h));
    c.view_mut((s, s), (s, s)).copy_from(&(a.transpose() * h));
    let e = c.exp();
    let phi = e.view((s, s), (s, s)).transpose();
    let q = &phi * e.view((0, s), (s, s));
    let q = (&q + q.transpose()) * 0.5;
    let eig = q.symmetric_eigen();
    let root = DMatrix::from_diagonal(&eig.eigenvalues.map(|v| v.max(0.0).sqrt()));
    (phi, &eig.eigenvectors * root)
}

/// A record of `samples` at step `dt`: `sub` exact steps per sample; the
/// channels at `observe` (displacement, velocity, or acceleration as the
/// mean over the last sub-step, what a sensor with a short averaging time
/// records), plus white sensor noise of `noise` times each channel's std.
#[allow(clippy::too_many_arguments)]
fn generate(
    chain: &Chain,
    observe: &[usize],
    kind: Observable,
    dt: f64,
    sub: usize,
    samples: usize,
    noise: f64,
    seed: u64,
) -> AmbientRecord {
    let n = chain.n();
    let on: Vec<usize> = (1..=n).collect();
    let (a, b) = state_space(chain, &on);
    let h = dt / sub as f64;
    let (phi, root) = discretise(&a, &b, h);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut z = nalgebra::DVector::<f64>::zeros(2 * n);
    let mut step = |z: &nalgebra::DVector<f64>| {
        let xi = nalgebra::DVector::from_fn(2 * n, |_, _| StandardNormal.sample(&mut rng));
        &phi * z + &root * xi
    };
    for _ in 0..20 * sub * 50 {
        z = step(&z); // settle into the stationary state
    }
    let mut ch = vec![Vec::with_capacity(samples); observe.len()];
    for _ in 0..samples {
        let mut prev = z.clone();
        for _ in 0..sub {
            prev = z.clone();
            z = step(&z);
        }
        for (c, &o) in ch.iter_mut().zip(observe) {
            let i = o - 1;
            c.push(match kind {
                Observable::Displacement => z[i],
                Observable::Velocity => z[n + i],
                Observable::Acceleration => (z[n + i] - prev[n + i]) / h,
            });
        }
    }
    add_sensor_noise(&mut ch, noise, seed);
    AmbientRecord::new(dt, observe.to_vec(), kind, ch).unwrap()
}

#[test]
fn one_weak_storey_of_an_8_mass_chain_is_found_from_three_displacement_channels() {
    let nominal = Chain::paper(8).unwrap();
    let truth = nominal
        .clone()
        .with_defect(Defect::Spring { at: 3, k: 0.8 })
        .unwrap();
    let rec = generate(
        &truth,
        &[1, 5, 8],
        Observable::Displacement,
        0.5,
        2,
        6000,
        0.1,
        7,
    );
    let opts = AmbientOptions {
        target: AmbientTarget::Defects { k_min: 0, k_max: 1 },
        ..AmbientOptions::default()
    };
    let r = fit_ambient(&nominal, &rec, &opts).unwrap();
    assert_eq!(r.status, "converged", "{}", r.summary());
    assert_eq!(r.k, 1, "{}", r.summary());
    let f = &r.factors[0];
    assert_eq!((f.kind, f.at), ("spring", 3), "{}", r.summary());
    let se = f.se.unwrap();
    assert!((f.factor - 0.8).abs() < 3.0 * se, "{}", r.summary());
    assert!(se < 0.05, "{}", r.summary());
    let (d, dse) = r.d;
    assert!((d - 0.1).abs() < 3.0 * dse.unwrap(), "{}", r.summary());
    // the first modes' frequency and damping within 3 SE of the truth
    let true_modes = natural_modes(&truth).unwrap();
    for m in r.modes.iter().take(3) {
        let t = &true_modes[m.mode - 1];
        assert!(
            (m.omega - t.omega).abs() < 3.0 * m.omega_se.unwrap(),
            "mode {}: {} vs {}\n{}",
            m.mode,
            m.omega,
            t.omega,
            r.summary()
        );
        assert!(
            (m.zeta - t.zeta.unwrap()).abs() < 3.0 * m.zeta_se.unwrap(),
            "{}",
            r.summary()
        );
    }
}

/// White sensor noise of `noise` times each channel's standard deviation.
fn add_sensor_noise(ch: &mut [Vec<f64>], noise: f64, seed: u64) {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed ^ 0x5eed);
    for c in ch.iter_mut() {
        let mean = c.iter().sum::<f64>() / c.len() as f64;
        let sd = (c.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / c.len() as f64).sqrt();
        for v in c.iter_mut() {
            let e: f64 = StandardNormal.sample(&mut rng);
            *v += noise * sd * e;
        }
    }
}

/// A record of `samples` at step `dt` under a band-limited force on mass 1:
/// a flat spectrum over `0..w_b` and none above, made as a sum of cosines
/// at every `dw = 2 pi / (record length)` below `w_b` with random phases
/// (a stationary Gaussian process to the record's resolution), held over
/// each of the `sub` exact sub-steps per sample (zero-order hold:
/// `z <- Phi z + A^-1 (Phi - I) B f`); displacement channels at `observe`
/// plus white sensor noise of `noise` times each channel's std.
fn generate_band_limited(
    chain: &Chain,
    observe: &[usize],
    w_b: f64,
    (dt, sub, samples): (f64, usize, usize),
    noise: f64,
    seed: u64,
) -> AmbientRecord {
    let n = chain.n();
    let (a, b) = state_space(chain, &[1]);
    let h = dt / sub as f64;
    let phi = (&a * h).exp();
    let ident = DMatrix::<f64>::identity(2 * n, 2 * n);
    let gamma = a.clone().lu().solve(&((&phi - ident) * &b)).unwrap();
    let settle = 400.0;
    let length = settle + samples as f64 * dt;
    let dw = 2.0 * std::f64::consts::PI / length;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let tones: Vec<(f64, f64)> = (0..)
        .map(|j| (j as f64 + 0.5) * dw)
        .take_while(|&w| w < w_b)
        .map(|w| {
            let u: f64 = rand::Rng::random(&mut rng);
            (w, 2.0 * std::f64::consts::PI * u)
        })
        .collect();
    let amp = (2.0 * dw).sqrt();
    let force = |t: f64| -> f64 { tones.iter().map(|&(w, p)| amp * (w * t + p).cos()).sum() };
    let mut z = nalgebra::DVector::<f64>::zeros(2 * n);
    let mut t = 0.0;
    let settle_steps = (settle / h).round() as usize;
    for _ in 0..settle_steps {
        z = &phi * &z + &gamma * force(t + 0.5 * h);
        t += h;
    }
    let mut ch = vec![Vec::with_capacity(samples); observe.len()];
    for _ in 0..samples {
        for _ in 0..sub {
            z = &phi * &z + &gamma * force(t + 0.5 * h);
            t += h;
        }
        for (c, &o) in ch.iter_mut().zip(observe) {
            c.push(z[o - 1]);
        }
    }
    add_sensor_noise(&mut ch, noise, seed);
    AmbientRecord::new(dt, observe.to_vec(), Observable::Displacement, ch).unwrap()
}

#[test]
fn a_band_limited_force_is_modelled_when_its_band_is_given() {
    // an 8-mass chain (modes at 0.35, 0.68, 1.00, 1.29, .., 1.97 rad/time)
    // shaken on mass 1 by a force flat up to 1.15 and absent above: only
    // the first three modes are excited
    let nominal = Chain::paper(8).unwrap();
    let truth = nominal
        .clone()
        .with_defect(Defect::Spring { at: 3, k: 0.8 })
        .unwrap();
    let rec = generate_band_limited(&truth, &[1, 5, 8], 1.15, (0.5, 2, 6000), 0.05, 5);
    let band = AmbientOptions {
        ambient_on: Some(vec![1]),
        force_band: Some((0.0, 1.15)),
        target: AmbientTarget::Defects { k_min: 0, k_max: 1 },
        ..AmbientOptions::default()
    };
    let r = fit_ambient(&nominal, &rec, &band).unwrap();
    assert_eq!(r.status, "converged", "{}", r.summary());
    assert_eq!(r.k, 1, "{}", r.summary());
    let f = &r.factors[0];
    assert_eq!((f.kind, f.at), ("spring", 3), "{}", r.summary());
    assert!(
        (f.factor - 0.8).abs() < 3.0 * f.se.unwrap(),
        "{}",
        r.summary()
    );
    assert_eq!(r.force_band, Some((0.0, 1.15)));
    assert!(r.summary().contains("force band"), "{}", r.summary());
    // the same record taken for white forces: the unexcited modes are
    // predicted where the record shows only the sensors' noise, and the
    // fit says that it does not explain the record
    let white = AmbientOptions {
        force_band: None,
        ..band.clone()
    };
    let w = fit_ambient(&nominal, &rec, &white).unwrap();
    assert!(!w.resolved && w.status != "converged", "{}", w.summary());
    // a band outside every used bin, or upside down, names the field
    for bad in [(2.0, 1.0), (-1.0, 1.0), (1.0, f64::NAN), (100.0, 200.0)] {
        let opts = AmbientOptions {
            force_band: Some(bad),
            ..band.clone()
        };
        let e = fit_ambient(&nominal, &rec, &opts).unwrap_err().to_string();
        assert!(e.contains("ambient_band"), "{bad:?}: {e}");
    }
}

/// The nominal 30-mass chain of the acceptance case.
fn thirty() -> Chain {
    Chain::new(30).unwrap().with_d(0.02).unwrap()
}

/// The acceptance case: a 30-mass chain, accelerometers on masses 1, 15
/// and 30, storey springs 10 and 20 weakened by 10%, sensor noise at 10% of
/// each channel's std, 10,000 samples at `dt = 1`; damping `d = 0.02`
/// (10% of critical at the first mode, 0.5% at the last). Returns whether both defects were
/// found with values within 3 SE, and the report.
fn thirty_mass_case(seed: u64) -> (bool, springmass::detect::fit::ambient::AmbientReport, f64) {
    let nominal = thirty();
    let truth = nominal
        .clone()
        .with_defects([
            Defect::Spring { at: 10, k: 0.9 },
            Defect::Spring { at: 20, k: 0.9 },
        ])
        .unwrap();
    let rec = generate(
        &truth,
        &[1, 15, 30],
        Observable::Acceleration,
        1.0,
        16,
        10_000,
        0.1,
        seed,
    );
    let clock = std::time::Instant::now();
    let r = fit_ambient(&nominal, &rec, &AmbientOptions::default()).unwrap();
    let seconds = clock.elapsed().as_secs_f64();
    let found = r.k == 2
        && r.factors.iter().all(|f| {
            f.kind == "spring"
                && [10, 20].contains(&f.at)
                && f.se.is_some_and(|se| (f.factor - 0.9).abs() < 3.0 * se)
        });
    (found, r, seconds)
}

#[test]
fn two_weak_storeys_of_a_30_mass_chain_from_three_accelerometers() {
    let (found, r, _) = thirty_mass_case(1);
    assert!(found, "{}", r.summary());
    assert_eq!(r.status, "converged", "{}", r.summary());
    assert!(modes_within_3_se(&r), "{}", r.summary());
}

/// Whether the first three modes' frequency and damping ratio are within
/// 3 SE of the truth of the 30-mass case.
fn modes_within_3_se(r: &springmass::detect::fit::ambient::AmbientReport) -> bool {
    let truth = thirty()
        .with_defects([
            Defect::Spring { at: 10, k: 0.9 },
            Defect::Spring { at: 20, k: 0.9 },
        ])
        .unwrap();
    let true_modes = natural_modes(&truth).unwrap();
    r.modes.iter().take(3).all(|m| {
        let t = &true_modes[m.mode - 1];
        m.omega_se
            .is_some_and(|se| (m.omega - t.omega).abs() < 3.0 * se)
            && m.zeta_se
                .is_some_and(|se| (m.zeta - t.zeta.unwrap()).abs() < 3.0 * se)
    })
}

/// The seed study of the acceptance case (20 seeds): run with
/// `cargo test --release --test all ambient::seed_study -- --ignored --nocapture`.
#[test]
#[ignore = "20 fits of the 30-mass case: a seed study, run on demand"]
fn seed_study_of_the_30_mass_case() {
    let seeds: u64 = std::env::var("AMBIENT_SEEDS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(20);
    let (mut hits, mut modes_ok) = (0, 0);
    for seed in 1..=seeds {
        let (found, r, seconds) = thirty_mass_case(seed);
        let set: Vec<String> = r
            .factors
            .iter()
            .map(|f| {
                format!(
                    "{} {} {:.4}+-{:.4}",
                    f.kind,
                    f.at,
                    f.factor,
                    f.se.unwrap_or(f64::NAN)
                )
            })
            .collect();
        println!(
            "seed {seed}: found {found}, status {}, k {}, [{}], chi2 {:.1}/{}, fit {seconds:.2} s",
            r.status,
            r.k,
            set.join(", "),
            r.chi2,
            r.dof,
        );
        hits += usize::from(found);
        modes_ok += usize::from(modes_within_3_se(&r));
    }
    println!("first three modes' omega and zeta within 3 SE in {modes_ok} of {seeds} seeds");
    println!("both defects within 3 SE in {hits} of {seeds} seeds");
    assert!(10 * hits >= 9 * seeds as usize, "{hits} of {seeds}");
}

#[test]
fn a_record_too_short_for_the_first_mode_is_refused() {
    let nominal = Chain::paper(30).unwrap();
    let rec = generate(
        &nominal,
        &[1, 15, 30],
        Observable::Acceleration,
        0.5,
        1,
        2000,
        0.1,
        3,
    );
    let e = fit_ambient(&nominal, &rec, &AmbientOptions::default()).unwrap_err();
    assert!(
        e.to_string().contains("samples") && e.to_string().contains("first mode"),
        "{e}"
    );
    // a nominal chain with modal damping: refused naming the field
    let modal = nominal
        .with_d(0.0)
        .and_then(|c| c.with_damping(springmass::chain::Damping::modal(0.02)))
        .unwrap();
    match fit_ambient(&modal, &rec, &AmbientOptions::default()) {
        Err(springmass::Error::InvalidParameter { field, .. }) => assert_eq!(field, "damping"),
        other => panic!("{:?}", other.map(|_| ())),
    }
}

#[test]
fn a_constant_channel_is_refused_naming_it() {
    let mut text = String::from("t,a1,a15\n");
    for i in 0..3000 {
        let v = ((i * 7919) % 101) as f64 / 101.0;
        text.push_str(&format!("{},{v},0.25\n", i as f64 * 0.5));
    }
    let ts = springmass::series::TimeSeries::from_csv_str(&text).unwrap();
    let e = AmbientRecord::from_series(&ts, vec![1, 15], Observable::Acceleration).unwrap_err();
    assert!(
        e.to_string().contains("channel 2 (mass 15)") && e.to_string().contains("constant"),
        "{e}"
    );
}

#[test]
fn sampling_too_coarse_for_the_highest_mode_is_refused() {
    let nominal = Chain::paper(30).unwrap();
    // omega_max ~ 2: dt = 1.5 puts the Nyquist frequency at 2.1
    let rec = generate(
        &nominal,
        &[1, 15, 30],
        Observable::Acceleration,
        1.5,
        2,
        6000,
        0.1,
        4,
    );
    let e = fit_ambient(&nominal, &rec, &AmbientOptions::default()).unwrap_err();
    assert!(
        e.to_string().contains("dt") && e.to_string().contains("highest mode"),
        "{e}"
    );
}

/// Write a record as the CLI reads it: `t` and one column per channel.
fn write_csv(rec: &AmbientRecord, path: &std::path::Path) {
    let mut text = String::from("t");
    for o in &rec.observe {
        text.push_str(&format!(",a{o}"));
    }
    text.push('\n');
    for i in 0..rec.len() {
        text.push_str(&format!("{}", i as f64 * rec.dt));
        for c in &rec.channels {
            text.push_str(&format!(",{:.9e}", c[i]));
        }
        text.push('\n');
    }
    std::fs::write(path, text).unwrap();
}

#[test]
fn the_cli_fits_an_ambient_record() {
    let nominal = Chain::paper(8).unwrap();
    let truth = nominal
        .clone()
        .with_defect(Defect::Spring { at: 3, k: 0.8 })
        .unwrap();
    let rec = generate(
        &truth,
        &[1, 5, 8],
        Observable::Velocity,
        0.5,
        2,
        6000,
        0.1,
        11,
    );
    let dir = std::env::temp_dir().join(format!("springmass-ambient-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("ambient.csv");
    write_csv(&rec, &path);
    let run_on = |file: &std::path::Path, extra: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_springmass"))
            .args(["fit", "--data"])
            .arg(file)
            .args([
                "--n",
                "8",
                "--observe",
                "1,5,8",
                "--observe-kind",
                "velocity",
                "--excitation",
                "ambient",
                "--defects",
                "auto:1",
                "--fit",
                "d",
                "--json",
            ])
            .args(extra)
            .output()
            .unwrap()
    };
    let run = |extra: &[&str]| run_on(&path, extra);
    let out = run(&[]);
    // a force band over every fitted frequency: the white model's answer
    let banded = run(&["--ambient-band", "0:10"]);
    let bad = run(&["--ambient-band", "1"]);
    // a record with another column (a temperature) before the channels:
    // --column picks the channels (it was refused as too many columns)
    let text = std::fs::read_to_string(&path).unwrap();
    let extra: String = text
        .lines()
        .enumerate()
        .map(|(i, l)| {
            let (t, rest) = l.split_once(',').unwrap();
            match i {
                0 => format!("{t},temp,{rest}\n"),
                _ => format!("{t},{}.5,{rest}\n", i % 7),
            }
        })
        .collect();
    let extra_path = dir.join("extra.csv");
    std::fs::write(&extra_path, extra).unwrap();
    let picked = run_on(&extra_path, &["--column", "a1,a5,a8"]);
    let unpicked = run_on(&extra_path, &[]);
    let short = run_on(&extra_path, &["--column", "a1,a5"]);
    let _ = std::fs::remove_dir_all(&dir);
    let p: serde_json::Value = serde_json::from_slice(&picked.stdout)
        .unwrap_or_else(|_| panic!("{}", String::from_utf8_lossy(&picked.stderr)));
    assert!(!unpicked.status.success());
    assert!(String::from_utf8_lossy(&unpicked.stderr).contains("--column"));
    assert!(!short.status.success());
    assert!(String::from_utf8_lossy(&short.stderr).contains("invalid column"));
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["status"], "converged", "{v}");
    assert_eq!(v["factors"][0]["at"], 3, "{v}");
    assert_eq!(v["factors"][0]["kind"], "spring", "{v}");
    assert!(v.get("force_band").is_none(), "{v}");
    let b: serde_json::Value = serde_json::from_slice(&banded.stdout).unwrap();
    assert_eq!(b["force_band"], serde_json::json!([0.0, 10.0]), "{b}");
    assert_eq!(b["factors"], v["factors"]);
    assert_eq!(p["factors"], v["factors"], "{p}");
    assert!(!bad.status.success());
    assert!(
        String::from_utf8_lossy(&bad.stderr).contains("ambient_band"),
        "{}",
        String::from_utf8_lossy(&bad.stderr)
    );
}

#[test]
fn monitor_flags_the_output_only_records_after_a_storey_weakened() {
    // a 6-mass chain in service: a reference record, then 8 records of
    // which the last 3 have spring 3 at 0.85 (the test's own generator)
    let nominal = Chain::paper(6).unwrap();
    let weak = nominal
        .clone()
        .with_defect(Defect::Spring { at: 3, k: 0.85 })
        .unwrap();
    let dir = std::env::temp_dir().join(format!("springmass-ambient-mon-{}", std::process::id()));
    let records = dir.join("records");
    std::fs::create_dir_all(&records).unwrap();
    let record = |chain: &Chain, seed: u64| {
        generate(
            chain,
            &[1, 4, 6],
            Observable::Displacement,
            0.5,
            2,
            4000,
            0.05,
            seed,
        )
    };
    write_csv(&record(&nominal, 100), &dir.join("base.csv"));
    for r in 0..8u64 {
        let chain = if r >= 5 { &weak } else { &nominal };
        write_csv(
            &record(chain, 200 + r),
            &records.join(format!("day-{r}.csv")),
        );
    }
    let cli = || std::process::Command::new(env!("CARGO_BIN_EXE_springmass"));
    let common = ["--n", "6", "--observe", "1,4,6", "--excitation", "ambient"];
    let base = cli()
        .args(["fit", "--data"])
        .arg(dir.join("base.csv"))
        .args(common)
        .args(["--profile", "springs", "--json"])
        .output()
        .unwrap();
    assert!(
        base.status.success(),
        "{}",
        String::from_utf8_lossy(&base.stderr)
    );
    let base_json = dir.join("base.json");
    std::fs::write(&base_json, &base.stdout).unwrap();
    let table = dir.join("trend.jsonl");
    let out = cli()
        .arg("monitor")
        .arg("--baseline")
        .arg(&base_json)
        .args(common)
        .arg(&records)
        .arg("--jsonl")
        .arg(&table)
        .output()
        .unwrap();
    let text = std::fs::read_to_string(&table).unwrap_or_default();
    // an impulse monitor given several sensors is refused naming the field
    let bad = cli()
        .args(["monitor", "--baseline"])
        .arg(&base_json)
        .args(["--n", "6", "--observe", "1,4,6"])
        .arg(&records)
        .output()
        .unwrap();
    // a damping model without its parameter: refused, not sent to --fit d
    // (which fits only the grounded d of an output-only record)
    let between = cli()
        .args(["fit", "--data"])
        .arg(dir.join("base.csv"))
        .args(common)
        .args(["--fit", "d", "--damping", "between"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&between.stderr);
    assert!(
        !between.status.success() && err.contains("between:0.05"),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(&dir);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let rows: Vec<serde_json::Value> = text
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(rows.len(), 8, "{text}");
    for (r, row) in rows.iter().enumerate() {
        if r < 5 {
            assert_eq!(row["status"], "ok", "record {r}: {row}");
        } else {
            assert_eq!(row["status"], "changed", "record {r}: {row}");
            assert_eq!(row["changed"][0], "spring 3", "record {r}: {row}");
        }
    }
    assert!(!bad.status.success());
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(err.contains("observe"), "{err}");
}

/// Write the guide's 30-mass record (the acceptance case, seed 1) to the
/// path in `AMBIENT_CSV`: `AMBIENT_CSV=ambient.csv cargo test --test all
/// ambient::write_the_guide_record -- --ignored`.
#[test]
#[ignore = "writes a file for the guide's worked example"]
fn write_the_guide_record() {
    let path = std::env::var("AMBIENT_CSV").expect("AMBIENT_CSV=path");
    let truth = thirty()
        .with_defects([
            Defect::Spring { at: 10, k: 0.9 },
            Defect::Spring { at: 20, k: 0.9 },
        ])
        .unwrap();
    let rec = generate(
        &truth,
        &[1, 15, 30],
        Observable::Acceleration,
        1.0,
        16,
        10_000,
        0.1,
        1,
    );
    write_csv(&rec, std::path::Path::new(&path));
}
