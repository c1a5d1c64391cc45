//! Scenes and studies take the data forms of the fit (issue 28, item 6):
//! several sensors (`observe = [..]`, one column each), several records
//! (`path = [..]`, or `records = N` simulated) and modal data
//! (`source = "modes"`, a modes CSV or simulated modes).
//!
//! The records of the `series` scenes come from the tests' dense
//! state-space generator (`tests/common/dense.rs`, the matrix exponential,
//! not the fit's modal sum), with noise from the test's own seeded ChaCha8
//! streams; the modes CSV from a dense eigen-solve assembled here.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use springmass::chain::Boundary;
use springmass::detect::fit::fit_scene;
use springmass::detect::fit::Status;
use springmass::detect::scene::FitScene;
use springmass::study::kinds::Kind;
use springmass::{Chain, Defect, Error};
use std::path::{Path, PathBuf};
use std::process::Command;

fn temp_dir(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!(
        "springmass-scene-data-{tag}-{}",
        std::process::id()
    ));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The paper's 8-mass chain with a mass of 2 at 6.
fn truth() -> Chain {
    Chain::paper(8)
        .unwrap()
        .with_defect(Defect::Mass { at: 6, m: 2.0 })
        .unwrap()
}

/// A CSV `t,x{m}...` of the displacements of `truth` at masses `at`, each
/// with noise of `level` times its own peak from stream `seed`.
fn write_record(path: &Path, truth: &Chain, at: &[usize], level: f64, seed: u64) {
    let (t, clean) = crate::dense::records(truth, at, 120.0, 0.25);
    let noisy: Vec<Vec<f64>> = clean
        .iter()
        .enumerate()
        .map(|(j, x)| {
            let peak = x.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            let mut rng = ChaCha8Rng::seed_from_u64(100 * seed + j as u64);
            let noise = Normal::new(0.0, level * peak).unwrap();
            x.iter().map(|v| v + noise.sample(&mut rng)).collect()
        })
        .collect();
    let mut text = String::from("t");
    for m in at {
        text.push_str(&format!(",x{m}"));
    }
    text.push('\n');
    for (i, ti) in t.iter().enumerate() {
        text.push_str(&format!("{ti}"));
        for x in &noisy {
            text.push_str(&format!(",{:.12e}", x[i]));
        }
        text.push('\n');
    }
    std::fs::write(path, text).unwrap();
}

fn series_scene(data: &str) -> FitScene {
    FitScene::from_toml(&format!(
        "[truth]\nn = 8\ndefects = [{{ kind = \"mass\", at = 6, m = 2.0 }}]\n[data]\nsource = \"series\"\n{data}\n[unknowns]\nk = 1\n"
    ))
    .unwrap()
}

/// The answer is mass 6 with its value within 3 standard errors.
fn assert_found(r: &springmass::detect::fit::paper::SceneReport) {
    assert_eq!(r.status, Status::Converged, "{}", r.message);
    assert_eq!(r.defects.len(), 1, "{:?}", r.defects);
    assert_eq!(
        r.defects[0],
        Defect::Mass {
            at: 6,
            m: r.defects[0].value()
        }
    );
    let z = (r.defects[0].value() - 2.0).abs() / r.std_errors[0];
    assert!(z < 3.0, "{:?} +- {:?}", r.defects, r.std_errors);
}

#[test]
fn a_series_scene_reads_one_column_per_sensor() {
    let dir = temp_dir("sensors");
    let csv = dir.join("three.csv");
    write_record(&csv, &truth(), &[1, 4, 8], 0.01, 1);
    let p = csv.display();
    // default columns x{mass}, and the same columns named
    for data in [
        format!("path = \"{p}\"\nobserve = [1, 4, 8]"),
        format!("path = \"{p}\"\nobserve = [1, 4, 8]\ncolumn = [\"x1\", \"x4\", \"x8\"]"),
    ] {
        let r = fit_scene(&series_scene(&data)).unwrap();
        assert_found(&r);
        assert!(r.misfit.contains("3 sensors"), "{}", r.misfit);
    }
    // a sensor list whose columns hold another mass's record is a mismatch
    // the fit must not call converged
    let swapped = format!("path = \"{p}\"\nobserve = [1, 4, 8]\ncolumn = [\"x1\", \"x8\", \"x4\"]");
    let r = fit_scene(&series_scene(&swapped)).unwrap();
    assert_ne!(r.status, Status::Converged, "{}", r.message);
}

#[test]
fn a_series_scene_joins_several_record_files() {
    let dir = temp_dir("records");
    let (a, b) = (dir.join("hit1.csv"), dir.join("hit2.csv"));
    write_record(&a, &truth(), &[1], 0.01, 2);
    write_record(&b, &truth(), &[1], 0.03, 3);
    let data = format!("path = [\"{}\", \"{}\"]", a.display(), b.display());
    let r = fit_scene(&series_scene(&data)).unwrap();
    assert_found(&r);
    assert!(r.misfit.contains("2 records"), "{}", r.misfit);
}

#[test]
fn simulated_scenes_take_sensors_and_records_with_their_own_noise() {
    let base = "[truth]\nn = 8\ndefects = [{ kind = \"mass\", at = 6, m = 2.0 }]\n[data]\nsource = \"simulated\"\nt_end = 120\ndt = 0.25\nnoise = 0.01\nrelative = true\n";
    let sensors = FitScene::from_toml(&format!("{base}observe = [1, 8]\n")).unwrap();
    let records = FitScene::from_toml(&format!("{base}records = 3\n")).unwrap();
    // each sensor and each record has its own noise stream
    let noise = |s: &FitScene, sensor, record| {
        let clean = FitScene {
            data: springmass::detect::scene::DataSpec {
                noise: 0.0,
                ..s.data.clone()
            },
            ..s.clone()
        };
        let x = s.record_of(sensor, record).unwrap();
        let c = clean.record_of(sensor, record).unwrap();
        x.y()
            .iter()
            .zip(c.y())
            .map(|(a, b)| a - b)
            .take(50)
            .collect::<Vec<_>>()
    };
    assert_ne!(noise(&records, 0, 0), noise(&records, 0, 1));
    assert_ne!(noise(&records, 0, 1), noise(&records, 0, 2));
    assert_ne!(noise(&sensors, 0, 0), noise(&sensors, 1, 0));
    for s in [&sensors, &records] {
        let r = fit_scene(s).unwrap();
        assert_found(&r);
    }
    // the same scene twice gives the same numbers
    assert_eq!(
        fit_scene(&records).unwrap().defects,
        fit_scene(&records).unwrap().defects
    );
}

/// The lowest `count` modes of `chain` by a dense symmetric eigen-solve
/// of `M^-1/2 K M^-1/2` assembled here, as a modes CSV at masses `floors`.
fn modes_csv(chain: &Chain, count: usize, floors: &[usize]) -> String {
    let n = chain.n();
    let (m, springs) = (chain.masses(), chain.springs());
    let mut k = nalgebra::DMatrix::<f64>::zeros(n, n);
    for (j, &kj) in springs.iter().enumerate() {
        // spring j joins masses j and j + 1 (0 and n + 1 are the walls)
        if j >= 1 {
            k[(j - 1, j - 1)] += kj;
        }
        if j < n {
            k[(j, j)] += kj;
        }
        if (1..n).contains(&j) {
            k[(j - 1, j)] -= kj;
            k[(j, j - 1)] -= kj;
        }
    }
    let a = nalgebra::DMatrix::from_fn(n, n, |i, j| k[(i, j)] / (m[i] * m[j]).sqrt());
    let eig = a.symmetric_eigen();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&x, &y| eig.eigenvalues[x].total_cmp(&eig.eigenvalues[y]));
    let mut text = String::from("frequency");
    for f in floors {
        text.push_str(&format!(",phi_{f}"));
    }
    text.push('\n');
    for &c in order.iter().take(count) {
        text.push_str(&format!(
            "{:.15e}",
            eig.eigenvalues[c].sqrt() / std::f64::consts::TAU
        ));
        for &f in floors {
            text.push_str(&format!(
                ",{:.15e}",
                eig.eigenvectors[(f - 1, c)] / m[f - 1].sqrt()
            ));
        }
        text.push('\n');
    }
    text
}

#[test]
fn a_modes_scene_locates_a_storey_from_a_modes_file_and_in_a_study() {
    let frame = Chain::new(6)
        .unwrap()
        .with_boundaries(Boundary::Fixed, Boundary::Free)
        .unwrap();
    let truth = frame
        .clone()
        .with_defect(Defect::Spring { at: 4, k: 0.75 })
        .unwrap();
    let dir = temp_dir("modes");
    let csv = dir.join("modes.csv");
    std::fs::write(&csv, modes_csv(&truth, 3, &[2, 4, 6])).unwrap();
    let scene = format!(
        "[truth]\nn = 6\nright = \"free\"\ndefects = [{{ kind = \"spring\", at = 4, k = 0.75 }}]\n[data]\nsource = \"modes\"\npath = \"{}\"\n[unknowns]\nkind = \"spring\"\n",
        csv.display()
    );
    let r = fit_scene(&FitScene::from_toml(&scene).unwrap()).unwrap();
    assert_eq!(r.status, Status::Converged, "{}", r.message);
    assert_eq!(r.defects.len(), 1);
    assert_eq!(r.defects[0].at(), 4);
    assert!(
        (r.defects[0].value() - 0.75).abs() < 1e-8,
        "{:?}",
        r.defects
    );
    // the modal dynamic residual gives the same storey and value
    let dynamic = FitScene::from_toml(&scene.replace(
        "source = \"modes\"",
        "source = \"modes\"\nmodal_residual = \"dynamic\"",
    ))
    .unwrap();
    let rd = fit_scene(&dynamic).unwrap();
    assert_eq!(rd.defects.len(), 1);
    assert_eq!(rd.defects[0].at(), 4);
    assert!(
        (rd.defects[0].value() - 0.75).abs() < 1e-8,
        "{:?}",
        rd.defects
    );
    assert!(rd.misfit.contains("dynamic-residual"), "{}", rd.misfit);
    // a study case of kind `fit` scores the modal answer like a record's
    let value: toml::Value = toml::from_str(&scene).unwrap(); // `[truth]` as in a scene file
    let out = Kind::Fit.run(&value, 0).unwrap();
    assert_eq!(out.metrics["success"], true, "{:?}", out.metrics);
    assert_eq!(out.metrics["found"], "spring:4");
    // simulated noisy modes at three floors, the same answer within its errors
    let noisy = FitScene::from_toml(
        "[truth]\nn = 6\nright = \"free\"\ndefects = [{ kind = \"spring\", at = 4, k = 0.75 }]\n[data]\nsource = \"modes\"\nmodes = 3\nfloors = [2, 4, 6]\nfrequency_noise = 0.002\nshape_noise = 0.01\nseed = 9\n[unknowns]\nkind = \"spring\"\n",
    )
    .unwrap();
    let r = fit_scene(&noisy).unwrap();
    assert_eq!(r.defects[0].at(), 4, "{}", r.message);
    assert!(
        (r.defects[0].value() - 0.75).abs() < 3.0 * r.std_errors[0],
        "{:?} +- {:?}",
        r.defects,
        r.std_errors
    );
}

fn field_of(e: Error) -> String {
    match e {
        Error::InvalidParameter { field, .. } => field,
        other => panic!("{other:?}"),
    }
}

#[test]
fn bad_scene_data_forms_name_their_field() {
    let dir = temp_dir("bad");
    let csv = dir.join("one.csv");
    write_record(&csv, &truth(), &[1, 4], 0.01, 4);
    let p = csv.display();
    let cases = [
        (format!("path = \"{p}\"\nobserve = [1, 4]\nobserve_kind = [\"displacement\", \"velocity\", \"velocity\"]"), "data.observe_kind"),
        (format!("path = \"{p}\"\nobserve = [1, 4]\ncolumn = [\"x1\"]"), "data.column"),
        (format!("path = \"{p}\"\nobserve = [1, 4]\ncolumn = [\"x1\", \"x9\"]"), "data.column"),
        (format!("path = \"{p}\"\nrecords = 2"), "data.records"),
        (format!("path = \"{p}\"\nobserve = [1, 9]"), "data.observe"),
        (format!("path = [\"{p}\", \"{p}\"]\nobserve = [1, 4]"), "data.path"),
        (format!("path = \"{p}\"\nobserve = []"), "data.observe"),
        (format!("path = \"{p}\"\nobserve = [4, 4]"), "observe"),
    ];
    for (data, want) in cases {
        let e = fit_scene(&series_scene(&data)).unwrap_err();
        let f = match &e {
            Error::InvalidParameter { field, .. } => field.clone(),
            other => other.to_string(),
        };
        assert!(f.contains(want), "{data}: {e}");
    }
    let sim = "[truth]\nn = 4\n[data]\nsource = \"simulated\"\nobserve = [1, 4]\nrecords = 2\n";
    assert_eq!(
        field_of(fit_scene(&FitScene::from_toml(sim).unwrap()).unwrap_err()),
        "data.records"
    );
    let modes = "[truth]\nn = 4\nright = \"free\"\n[data]\nsource = \"modes\"\n[unknowns]\nkind = \"spring\"\nk = 1\n[search]\nmethod = \"ga\"\n";
    let energy = "[truth]\nn = 4\nright = \"free\"\n[data]\nsource = \"modes\"\nmodal_residual = \"energy\"\n[unknowns]\nkind = \"spring\"\nk = 1\n";
    assert_eq!(
        field_of(fit_scene(&FitScene::from_toml(energy).unwrap()).unwrap_err()),
        "data.modal_residual"
    );
    assert_eq!(
        field_of(fit_scene(&FitScene::from_toml(modes).unwrap()).unwrap_err()),
        "search.method"
    );
    // `config check` lists the problem of a study scene too
    let value: toml::Value = toml::from_str(sim).unwrap();
    assert_eq!(
        field_of(Kind::Fit.run(&value, 0).unwrap_err()),
        "data.records"
    );
}

#[test]
fn cli_fits_a_modes_scene_and_updates_it_with_a_profile() {
    let dir = temp_dir("cli");
    let scene = dir.join("modal.toml");
    std::fs::write(
        &scene,
        "[truth]\nn = 5\nright = \"free\"\ndefects = [{ kind = \"spring\", at = 2, k = 0.8 }]\n[data]\nsource = \"modes\"\nmodes = 3\nfloors = [1, 3, 5]\n[unknowns]\nkind = \"spring\"\n",
    )
    .unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_springmass"))
        .args(["fit", "--json", "--scene"])
        .arg(&scene)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["status"], "converged");
    assert_eq!(v["defects"][0]["at"], 2);
    let out = Command::new(env!("CARGO_BIN_EXE_springmass"))
        .args(["fit", "--profile", "springs", "--scene"])
        .arg(&scene)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(text.contains("status:"), "{text}");
    assert!(text.contains("spring"), "{text}");
}
