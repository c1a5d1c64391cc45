//! `springmass fit --data`: a CSV the test writes (simulated, noisy), fitted
//! with nothing known but n and d; and every bad input refused with a
//! one-line message naming the field and exit status 2.

use springmass::detect::data::series::TimeData;
use springmass::noise::NoiseLevel;
use springmass::series::TimeSeries;
use springmass::{Chain, Defect};
use std::path::{Path, PathBuf};
use std::process::Command;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_springmass"))
}

/// Run the command; it must succeed and print JSON.
fn json_of(cmd: &mut Command) -> serde_json::Value {
    let out = cmd.output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

/// The positions of a JSON report's defects.
fn positions(v: &serde_json::Value) -> Vec<u64> {
    v["defects"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| d["at"].as_u64().unwrap())
        .collect()
}

fn temp_dir(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("springmass-cli-fit-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The paper's chain of 10 masses with masses 3 at 3 and 2 at 7.
fn two_defects() -> Chain {
    Chain::paper(10)
        .unwrap()
        .with_defects([
            Defect::Mass { at: 3, m: 3.0 },
            Defect::Mass { at: 7, m: 2.0 },
        ])
        .unwrap()
}

fn write_record(path: &Path, level: f64) {
    write_series(path, &two_defects(), 150.0, level, 21);
}

/// `x_1` of `truth` on `[0, t_end]` every 0.25 with noise `level` of max |x_1|, as a CSV.
fn write_series(path: &Path, truth: &Chain, t_end: f64, level: f64, seed: u64) {
    let d = TimeData::simulate(truth, t_end, 0.25, NoiseLevel::RelativeMax(level), seed).unwrap();
    TimeSeries::new(d.t().to_vec(), vec![("x1".into(), d.y().to_vec())])
        .unwrap()
        .write_csv(path)
        .unwrap();
}

#[test]
fn fit_data_recovers_both_defects_from_n_and_d_only() {
    let dir = temp_dir("ok");
    let csv = dir.join("x1.csv");
    write_record(&csv, 1e-3);
    let v = json_of(
        bin()
            .args(["fit", "--data"])
            .arg(&csv)
            .args(["--n", "10", "--d", "0.1", "--json", "--plot"])
            .arg(dir.join("fit.svg"))
            .arg("--out-csv")
            .arg(dir.join("fit.csv")),
    );
    assert_eq!(v["k"], 2, "{v}");
    let at = positions(&v);
    assert_eq!(at, vec![3, 7]);
    for (d, truth) in v["defects"].as_array().unwrap().iter().zip([3.0, 2.0]) {
        let (val, se) = (d["value"].as_f64().unwrap(), d["se"].as_f64().unwrap());
        assert!((val - truth).abs() < 4.0 * se && se > 0.0, "{d}");
    }
    assert_eq!(v["noise_estimated"], true);
    assert_eq!(v["status"], "converged");
    assert!(v["k_selection"].as_array().unwrap().len() >= 3);
    let svg = std::fs::read_to_string(dir.join("fit.svg")).unwrap();
    assert!(svg.contains("<svg"));
    let table = TimeSeries::read_csv(dir.join("fit.csv")).unwrap();
    assert!(table.column("residual").is_some() && table.column("model").is_some());
    // the library gives the same answer on the same file
    let obs = springmass::detect::data::observations::Observations::Series(
        springmass::detect::data::observations::Series::from_csv(&csv, Some("x1"), None).unwrap(),
    );
    let r = springmass::detect::fit::fit(
        &obs,
        &springmass::detect::fit::Model::new(10).unwrap(),
        &springmass::detect::fit::FitOptions::default(),
    )
    .unwrap();
    for (d, j) in r.defects.iter().zip(v["defects"].as_array().unwrap()) {
        assert_eq!(d.value, j["value"].as_f64().unwrap());
    }
    std::fs::remove_dir_all(&dir).ok();
}

fn refused(args: &[&str], dir: &Path, field: &str) {
    let out = bin().args(args).current_dir(dir).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
    assert!(err.contains(field), "{args:?}: expected {field:?} in {err}");
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "one line: {err}");
}

#[test]
fn bad_input_exits_2_naming_the_field() {
    let dir = temp_dir("bad");
    write_record(&dir.join("ok.csv"), 1e-3);
    let rows = |f: &dyn Fn(usize) -> String, n: usize| {
        let mut s = String::from("t,x1\n");
        for i in 0..n {
            s.push_str(&f(i));
            s.push('\n');
        }
        s
    };
    std::fs::write(
        dir.join("nan.csv"),
        rows(
            &|i| {
                if i == 5 {
                    format!("{i},NaN")
                } else {
                    format!("{i},0.1")
                }
            },
            40,
        ),
    )
    .unwrap();
    std::fs::write(
        dir.join("inf.csv"),
        rows(
            &|i| {
                if i == 5 {
                    format!("{i},inf")
                } else {
                    format!("{i},0.1")
                }
            },
            40,
        ),
    )
    .unwrap();
    std::fs::write(dir.join("short.csv"), rows(&|i| format!("{i},0.1"), 10)).unwrap();
    std::fs::write(
        dir.join("back.csv"),
        rows(&|i| format!("{},0.1", if i == 7 { 3 } else { i }), 40),
    )
    .unwrap();
    let fit = |file: &str, extra: &[&str]| {
        let mut v = vec!["fit", "--data", file, "--n", "10"];
        v.extend_from_slice(extra);
        v.into_iter().map(String::from).collect::<Vec<_>>()
    };
    let cases: Vec<(Vec<String>, &str)> = vec![
        (fit("nan.csv", &[]), "x"),
        (fit("inf.csv", &[]), "x"),
        (fit("short.csv", &[]), "samples"),
        (fit("back.csv", &[]), "time"),
        (fit("ok.csv", &["--column", "x9"]), "column"),
        (fit("ok.csv", &["--defects", "11"]), "defects"),
        (fit("ok.csv", &["--defects", "auto:11"]), "k_max"),
        (fit("ok.csv", &["--noise", "0"]), "noise"),
        (fit("ok.csv", &["--noise", "-1e-3"]), "noise"),
        (
            fit("ok.csv", &["--kinds", "spring", "--method", "ga"]),
            "method",
        ),
        (fit("ok.csv", &["--method", "simplex"]), "method"),
        (fit("ok.csv", &["--misfit", "l1"]), "misfit"),
        (vec!["fit".into(), "--data".into(), "ok.csv".into()], "n"),
    ];
    for (args, field) in cases {
        let a: Vec<&str> = args.iter().map(String::as_str).collect();
        refused(&a, &dir, field);
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// A hammer test from a logger's file: columns `t`, the force `f` and the
/// acceleration `a1` of a chain with a free left end; the CLI takes the
/// force column, the observable and the ends.
#[test]
fn fit_data_hammer_test_with_force_column_acceleration_and_free_end() {
    use springmass::chain::Boundary;
    use springmass::detect::data::measurement::{hammer, Sensor};
    use springmass::forward::Observable;
    let truth = Chain::paper(6)
        .unwrap()
        .with_boundaries(Boundary::Free, Boundary::Fixed)
        .unwrap()
        .with_defect(Defect::Mass { at: 4, m: 2.0 })
        .unwrap();
    let sensor = Sensor {
        at: 1,
        kind: Observable::Acceleration,
    };
    let rec = TimeData::simulate_measured(
        &truth,
        40.0,
        0.005,
        sensor,
        Some(hammer(0.05, 1.0).unwrap()),
        NoiseLevel::Absolute(5e-3),
        3,
    )
    .unwrap();
    let dir = temp_dir("hammer");
    let csv = dir.join("hammer.csv");
    let f = rec.measurement().force().unwrap().to_vec();
    TimeSeries::new(
        rec.t().to_vec(),
        vec![("f".into(), f), ("a1".into(), rec.y().to_vec())],
    )
    .unwrap()
    .write_csv(&csv)
    .unwrap();
    let run = |extra: &[&str]| {
        bin()
            .args(["fit", "--data"])
            .arg(&csv)
            .args(["--n", "6", "--defects", "1", "--json"])
            .args(extra)
            .output()
            .unwrap()
    };
    let out = run(&[
        "--left",
        "free",
        "--observe-kind",
        "acceleration",
        "--force-column",
        "f",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let d = &v["defects"][0];
    assert_eq!(d["at"], 4, "{v}");
    let (m, se) = (d["value"].as_f64().unwrap(), d["se"].as_f64().unwrap());
    assert!((m - 2.0).abs() < 3.0 * se, "{m} +- {se}");
    let setup = v["setup"].as_str().unwrap();
    assert!(
        setup.contains("acceleration")
            && setup.contains("measured force")
            && setup.contains("free-fixed"),
        "{setup}"
    );
    // bad setups: a named error and exit status 2
    for (args, field) in [
        (vec!["--left", "loose"], "left"),
        (vec!["--observe-kind", "jerk"], "observe_kind"),
        (vec!["--force-column", "g"], "force_column"),
        (vec!["--observe", "9"], "observe"),
    ] {
        let out = run(&args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(field), "{args:?}: {err}");
    }
}

/// `--profile masses`: every mass of the ten-mass chain free, from the same
/// record; the two defects stand out (the estimates within 5 SE of the
/// truth, every other mass within 5 SE of 1), the CSV holds one row per mass
/// and the plot is written; bad profile options are refused by name.
#[test]
fn fit_data_profile_of_every_mass() {
    let dir = temp_dir("profile");
    let csv = dir.join("x1.csv");
    write_record(&csv, 1e-3);
    let v = json_of(
        bin()
            .args(["fit", "--data"])
            .arg(&csv)
            .args(["--n", "10", "--d", "0.1", "--profile", "masses", "--json"])
            .arg("--plot")
            .arg(dir.join("profile.svg"))
            .arg("--out-csv")
            .arg(dir.join("profile.csv")),
    );
    let elems = v["elements"].as_array().unwrap();
    assert_eq!(elems.len(), 10, "{v}");
    for e in elems {
        let at = e["at"].as_u64().unwrap();
        let truth = match at {
            3 => 3.0,
            7 => 2.0,
            _ => 1.0,
        };
        let (value, se) = (e["value"].as_f64().unwrap(), e["se"].as_f64().unwrap());
        assert_eq!(e["visible"], true, "{v}");
        assert!(
            (value - truth).abs() < 5.0 * se,
            "mass {at}: {value} +- {se}"
        );
    }
    assert_eq!(v["noise_estimated"], true);
    let table = std::fs::read_to_string(dir.join("profile.csv")).unwrap();
    assert_eq!(table.lines().count(), 11, "{table}");
    assert!(table.starts_with("kind,at,value,se,uniform,visible,depth"));
    let svg = std::fs::read_to_string(dir.join("profile.svg")).unwrap();
    assert!(svg.contains("<svg"));
    refused(
        &["fit", "--data", "x1.csv", "--n", "10", "--profile", "all"],
        &dir,
        "profile",
    );
    refused(
        &[
            "fit",
            "--data",
            "x1.csv",
            "--n",
            "10",
            "--profile",
            "masses",
            "--profile-change",
            "0",
        ],
        &dir,
        "profile_change",
    );
    refused(
        &[
            "fit",
            "--data",
            "x1.csv",
            "--n",
            "10",
            "--profile",
            "masses",
            "--penalty",
            "-1",
        ],
        &dir,
        "penalty",
    );
}

/// A scene's `[profile]` table (the shipped `configs/scenes/profile-masses.toml`):
/// every mass of its 30-mass chain from the simulated record, compared with
/// the scene's truth; `--profile` on the command line overrides the table;
/// bad profile settings in a scene, and `--plot` with a defect-fit scene,
/// are refused by name.
#[test]
fn fit_scene_profile_of_every_mass() {
    let scene = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/configs/scenes/profile-masses.toml"
    );
    let dir = temp_dir("scene-profile");
    let v = json_of(bin().args(["fit", "--scene", scene, "--json"]));
    let elems = v["elements"].as_array().unwrap();
    assert_eq!(elems.len(), 30, "{v}");
    let mut within = 0;
    let mut visible = 0;
    for e in elems.iter().filter(|e| e["visible"] == true) {
        let truth = match e["at"].as_u64().unwrap() {
            4 => 1.5,
            9 => 0.7,
            20 => 1.3,
            _ => 1.0,
        };
        let (value, se) = (e["value"].as_f64().unwrap(), e["se"].as_f64().unwrap());
        visible += 1;
        within += usize::from((value - truth).abs() <= 2.0 * se);
    }
    assert!(
        visible >= 20 && within * 10 >= visible * 8,
        "{within} of {visible}: {v}"
    );
    let out = bin().args(["fit", "--scene", scene]).output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && text.contains("truth ([chain]): "),
        "{text}"
    );
    // --profile overrides the table; a defect-fit scene refuses --plot
    let spring_scene = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/configs/scenes/table1-system3.toml"
    );
    let v = json_of(bin().args([
        "fit",
        "--scene",
        spring_scene,
        "--profile",
        "masses",
        "--json",
    ]));
    assert_eq!(v["elements"].as_array().unwrap().len(), 20, "{v}");
    refused(
        &["fit", "--scene", spring_scene, "--plot", "p.svg"],
        &dir,
        "plot",
    );
    for (table, field) in [
        ("mode = \"all\"", "profile"),
        ("mode = \"masses\"\nchange = 0", "profile.change"),
        ("mode = \"masses\"\npenalty = -1", "profile.penalty"),
    ] {
        let text = std::fs::read_to_string(scene).unwrap();
        let bad = text.replace(
            "[profile]\nmode = \"masses\"",
            &format!("[profile]\n{table}"),
        );
        std::fs::write(dir.join("bad.toml"), bad).unwrap();
        refused(&["fit", "--scene", "bad.toml"], &dir, field);
    }
    // an unknown field of the table: the TOML parser's message names it
    let text = std::fs::read_to_string(scene).unwrap();
    std::fs::write(
        dir.join("bad.toml"),
        text.replace("mode = \"masses\"", "mood = \"masses\""),
    )
    .unwrap();
    let out = bin()
        .args(["fit", "--scene", "bad.toml"])
        .current_dir(&dir)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.code() == Some(2) && err.contains("mood"),
        "{err}"
    );
}

/// A 1000-mass record fitted with the defaults: enumeration of every set of
/// up to four positions would pass `max_sets`, so the greedy search is
/// chosen (and named); both defects are found within 3 SE.
#[test]
#[ignore = "heavy (long chains): run by .ci/run; cargo test --test all -- --ignored heavy"]
fn heavy_fit_data_of_a_long_chain_with_the_defaults_searches_greedily() {
    let dir = temp_dir("long");
    let truth = Chain::paper(1000)
        .unwrap()
        .with_defects([
            Defect::Mass { at: 5, m: 2.0 },
            Defect::Mass { at: 30, m: 0.6 },
        ])
        .unwrap();
    let csv = dir.join("x1000.csv");
    write_series(&csv, &truth, 300.0, 1e-3, 1);
    let v = json_of(
        bin()
            .args(["fit", "--data"])
            .arg(&csv)
            .args(["--n", "1000", "--json"]),
    );
    assert!(
        v["method"].as_str().unwrap().contains("greedy"),
        "{}",
        v["method"]
    );
    let found: Vec<(u64, f64, f64)> = v["defects"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| {
            (
                e["at"].as_u64().unwrap(),
                e["value"].as_f64().unwrap(),
                e["se"].as_f64().unwrap(),
            )
        })
        .collect();
    assert_eq!(
        found.iter().map(|f| f.0).collect::<Vec<_>>(),
        vec![5, 30],
        "{v}"
    );
    for ((_, value, se), truth) in found.iter().zip([2.0, 0.6]) {
        assert!(
            (value - truth).abs() < 3.0 * se,
            "{value} +- {se} vs {truth}"
        );
    }
}

/// `--data` repeated: two records of the same chain (different lengths
/// and noise) fitted jointly, each listed with its own level; the options
/// that read one record are refused naming the field.
#[test]
fn fit_data_of_several_records() {
    let dir = temp_dir("records");
    let truth = two_defects();
    write_series(&dir.join("a.csv"), &truth, 150.0, 1e-3, 31);
    write_series(&dir.join("b.csv"), &truth, 100.0, 3e-3, 32);
    let v = json_of(
        bin()
            .args([
                "fit", "--data", "a.csv", "--data", "b.csv", "--n", "10", "--json",
            ])
            .current_dir(&dir),
    );
    let at = positions(&v);
    assert_eq!(at, vec![3, 7], "{v}");
    let recs = v["sensors"].as_array().unwrap();
    assert_eq!(recs.len(), 2, "{v}");
    assert_eq!(
        (recs[0]["record"].as_u64(), recs[1]["samples"].as_u64()),
        (Some(1), Some(401))
    );
    assert!(recs.iter().all(|r| r["fits_data"] == true), "{v}");
    let both = ["fit", "--data", "a.csv", "--data", "b.csv", "--n", "10"];
    for (flag, value, field) in [
        ("--observe", "1,2", "observe"),
        ("--method", "greedy", "method"),
        ("--profile", "masses", "profile"),
        ("--excitation", "ambient", "data"),
    ] {
        refused(&[&both[..], &[flag, value]].concat(), &dir, field);
    }
}

#[test]
fn fit_data_with_modal_damping() {
    let dir = temp_dir("modal");
    // System {2: 3, 4: 0.5} of 5 masses, modally damped, into `out`
    let simulate = |damping: &str, noise: &str, seed: &str, out: &str| {
        let sim = bin()
            .args([
                "simulate",
                "--n",
                "5",
                "--defect",
                "mass:2:3",
                "--defect",
                "mass:4:0.5",
            ])
            .args(["--damping", damping, "--t-end", "120", "--dt", "0.5"])
            .args(["--noise", noise, "--seed", seed, "--out", out])
            .current_dir(&dir)
            .output()
            .unwrap();
        assert!(
            sim.status.success(),
            "{}",
            String::from_utf8_lossy(&sim.stderr)
        );
    };
    simulate("modal:0.03", "rel:1e-2", "3", "x1.csv");
    let fit = [
        "fit",
        "--data",
        "x1.csv",
        "--n",
        "5",
        "--damping",
        "modal",
        "--fit",
        "d",
    ];
    let v = json_of(bin().current_dir(&dir).args(fit).arg("--json"));
    let at = positions(&v);
    assert_eq!(at, [2, 4], "{v}");
    let damping = &v["damping"];
    assert_eq!(damping["model"], "modal", "{damping}");
    let (zeta, se) = (
        damping["zeta"].as_f64().unwrap(),
        damping["se"]["zeta"].as_f64().unwrap(),
    );
    assert!(se > 0.0 && (zeta - 0.03).abs() < 3.0 * se, "{damping}");
    // what the modal model cannot take, refused naming the field
    refused(
        &[&fit[..], &["--method", "greedy"]].concat(),
        &dir,
        "damping",
    );
    refused(
        &[
            "simulate",
            "--n",
            "5",
            "--damping",
            "modal:0.03",
            "--defect",
            "damper:2:0.3",
        ],
        &dir,
        "defects[0]",
    );
    refused(
        &["simulate", "--n", "5", "--damping", "modal:9"],
        &dir,
        "damping.zeta",
    );
    refused(
        &["simulate", "--n", "5", "--damping", "modal:0.01,9"],
        &dir,
        "damping.zeta[1]",
    );
    // a ratio per mode (modes 1, 2 and the rest), fitted from 3% each
    simulate("modal:0.01,0.05,0.02", "rel:1e-3", "4", "x2.csv");
    let mut per_mode = fit.to_vec();
    per_mode[2] = "x2.csv";
    per_mode[6] = "modal:0.03,0.03,0.03";
    let v = json_of(bin().current_dir(&dir).args(&per_mode).arg("--json"));
    assert_eq!(positions(&v), [2, 4], "{v}");
    for (name, truth) in [("zeta_1", 0.01), ("zeta_2", 0.05), ("zeta_3", 0.02)] {
        let (z, se) = (
            v["damping"][name].as_f64().unwrap(),
            v["damping"]["se"][name].as_f64().unwrap(),
        );
        assert!(se > 0.0 && (z - truth).abs() < 3.0 * se, "{name}: {v}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// A fit whose best model by the criterion holds a defect at the uniform
/// value within its standard error is not called `converged` (n = 23,
/// masses 2.787 at 3, 2.949 at 4, 0.471 at 9 and 0.57 at 18, 1% noise: the
/// nested search's best four were 3, 4, 6 and 9 with 6 at 0.51 standard
/// errors from 1, and the answer 3, 4, 6 came back `converged` without the
/// intervals; then the answer was the four, with mass 6 flagged). The set
/// without the null defect, 3, 4 and 9, is now refitted from the four's
/// values, and the search at four defects searched again from it
/// (`fit::searched_again`): the answer holds 3, 4 and 9, and a fourth
/// defect that the data do not place for sure is not called `converged`
/// unless it is the truth's (a step down to another answer, with its
/// doubt, is `stages::tests`).
#[test]
fn a_step_down_past_a_null_defect_to_another_answer_is_not_converged() {
    let dir = temp_dir("null-step");
    let csv = dir.join("r.csv");
    let mut sim = bin();
    sim.args(["simulate", "--n", "23", "--t-end", "200", "--dt", "0.2"])
        .args(["--noise", "0.01", "--seed", "4522"])
        .args(["--defect", "mass:3:2.787", "--defect", "mass:4:2.949"])
        .args(["--defect", "mass:9:0.471", "--defect", "mass:18:0.570"])
        .arg("--out")
        .arg(&csv);
    assert!(sim.output().unwrap().status.success());
    let r = json_of(bin().args(["fit", "--data"]).arg(&csv).args([
        "--n",
        "23",
        "--kinds",
        "mass",
        "--no-uncertainty",
        "--json",
        "--threads",
        "1",
    ]));
    let at = positions(&r);
    assert!(at.starts_with(&[3, 4]) && at.contains(&9), "{r}");
    assert!(!at.contains(&6), "{r}");
    if at != [3, 4, 9, 18] {
        assert_eq!(r["status"], "not-identifiable", "{r}");
        assert_eq!(r["resolved"], false, "{r}");
    }
    std::fs::remove_dir_all(&dir).ok();
}
