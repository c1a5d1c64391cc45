//! Regression tests for the fuzz findings of issue 32 (items 6-13): each
//! reproduces a finding over the built `springmass` binary.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_springmass");

struct Out {
    code: i32,
    stdout: String,
    stderr: String,
}

fn run_in(dir: &Path, args: &[&str], env: &[(&str, &str)]) -> Out {
    let mut cmd = Command::new(BIN);
    cmd.args(args).current_dir(dir);
    for (k, v) in env {
        cmd.env(k, v);
    }
    let out = cmd.output().unwrap();
    Out {
        code: out.status.code().unwrap_or(-1),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
    }
}

/// Run with a generous limit (a finding that blocked forever must fail the
/// test, not hang it): kills the child after 120 s.
fn run_bounded(dir: &Path, args: &[&str]) -> Out {
    let mut child = Command::new(BIN)
        .args(args)
        .current_dir(dir)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > Duration::from_secs(120) {
            child.kill().unwrap();
            panic!("springmass {args:?} blocked for 120 s");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let out = child.wait_with_output().unwrap();
    Out {
        code: out.status.code().unwrap_or(-1),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
    }
}

fn tmpdir(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("springmass-hf-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn refused(o: &Out, needle: &str) {
    assert!(!o.stderr.contains("panicked"), "{}", o.stderr);
    assert_ne!(o.code, 0, "exit 0: {} {}", o.stdout, o.stderr);
    assert_ne!(o.code, 101, "{}", o.stderr);
    assert!(
        o.stderr.contains(needle),
        "expected {needle:?} in: {}",
        o.stderr
    );
}

#[cfg(unix)]
fn mkfifo(path: &Path) {
    assert!(Command::new("mkfifo").arg(path).status().unwrap().success());
}

/// A plain record of a damped oscillation, `rows` samples at step 0.25.
fn record(path: &Path, header: &str, rows: usize) {
    let mut text = format!("{header}\n");
    for i in 0..rows {
        let t = i as f64 * 0.25;
        text.push_str(&format!("{t},{}\n", (0.9 * t).sin() * (-0.05 * t).exp()));
    }
    std::fs::write(path, text).unwrap();
}

/// Item 6: 200 samples 1 ns apart then 200 one second apart left the
/// bounded least squares with fewer Jacobian rows than parameters: "Matrix
/// index out of bounds" (exit 101).
#[test]
fn item6_few_jacobian_rows_do_not_panic() {
    let d = tmpdir("i6");
    let mut text = String::from("t,x1\n");
    for i in 0..200 {
        text.push_str(&format!(
            "{:e},{}\n",
            i as f64 * 1e-9,
            0.001 * (i % 7) as f64
        ));
    }
    for i in 0..200 {
        text.push_str(&format!("{},{}\n", 10 + i, 0.001 * (i % 5) as f64));
    }
    let f = d.join("two_scales.csv");
    std::fs::write(&f, text).unwrap();
    let o = run_in(
        &d,
        &["fit", "--data", s(&f), "--n", "10", "--defects", "2"],
        &[],
    );
    assert!(!o.stderr.contains("panicked"), "{}", o.stderr);
    assert_ne!(o.code, 101, "{}", o.stderr);
    std::fs::remove_dir_all(&d).ok();
}

/// Item 8: outputs that are not files.
#[cfg(unix)]
#[test]
fn item8_outputs_that_are_not_files_are_refused() {
    let d = tmpdir("i8");
    let scene = d.join("scene.toml");
    std::fs::write(
        &scene,
        "[chain]\nn = 3\nd = 0.1\n\n[data]\nsource = \"exact\"\n\n[unknowns]\nk = 1\nmass_bounds = [0.5, 10.0]\n",
    )
    .unwrap();
    // surface --out /dev/null would create /dev/null.csv and .svg
    let o = run_in(
        &d,
        &[
            "surface",
            "--scene",
            s(&scene),
            "--kind",
            "jm",
            "--out",
            "/dev/null",
        ],
        &[],
    );
    refused(&o, "/dev/null");
    assert!(!Path::new("/dev/null.csv").exists());
    // --out DIR/ would write DIR.csv beside the folder
    let sub = d.join("sub");
    std::fs::create_dir_all(&sub).unwrap();
    let slash = format!("{}/", sub.display());
    let o = run_in(
        &d,
        &[
            "surface",
            "--scene",
            s(&scene),
            "--kind",
            "jm",
            "--out",
            &slash,
        ],
        &[],
    );
    refused(&o, "prefix");
    assert!(!d.join("sub.csv").exists());
    // suppress --out-dir / writes into the root
    let o = run_in(&d, &["suppress", "--n", "3", "--out-dir", "/"], &[]);
    refused(&o, "root");
    assert!(!Path::new("/timeseries.csv").exists());
    // fit --profile --out-csv FIFO blocked; now refused before the fit
    let rec = d.join("x1.csv");
    record(&rec, "t,x1", 201);
    let fifo = d.join("profile.csv");
    mkfifo(&fifo);
    let o = run_bounded(
        &d,
        &[
            "fit",
            "--data",
            s(&rec),
            "--n",
            "3",
            "--profile",
            "masses",
            "--out-csv",
            s(&fifo),
        ],
    );
    refused(&o, "FIFO");
    std::fs::remove_dir_all(&d).ok();
}

/// Item 8: `fit --profile --out-csv` replaced through the atomic writer: a
/// symbolic link stays a link and a hard link's other name keeps the old text.
#[cfg(unix)]
#[test]
fn item8_profile_csv_is_written_atomically() {
    let d = tmpdir("i8b");
    let rec = d.join("x1.csv");
    record(&rec, "t,x1", 201);
    let old = d.join("old.csv");
    std::fs::write(&old, "old\n").unwrap();
    let hard = d.join("hard.csv");
    std::fs::hard_link(&old, &hard).unwrap();
    let o = run_in(
        &d,
        &[
            "fit",
            "--data",
            s(&rec),
            "--n",
            "3",
            "--profile",
            "masses",
            "--out-csv",
            s(&hard),
        ],
        &[],
    );
    assert_eq!(o.code, 0, "{}", o.stderr);
    assert_eq!(std::fs::read_to_string(&old).unwrap(), "old\n");
    assert!(std::fs::read_to_string(&hard)
        .unwrap()
        .starts_with("kind,at,value"));
    std::fs::remove_dir_all(&d).ok();
}

/// Item 9: the CSV reader must not change data silently.
#[test]
fn item9_csv_that_would_change_data_is_refused() {
    let d = tmpdir("i9");
    let cases: [(&str, &str, &str); 5] = [
        ("extra.csv", "t,x1\n0,1\n19.25,1,5\n", "column 3"),
        (
            "na.csv",
            "t,x1\n0,1\n#N/A,2\n1,3\n",
            "row 2 (line 3), column 1",
        ),
        ("noheader.csv", "0,1\n1,2\n2,3\n", "no header"),
        ("comma.csv", ",\n0,1\n1,2\n", "no column names"),
        ("dup.csv", "t,t,x1\n0,1,2\n1,2,3\n", "same name"),
    ];
    for (name, text, needle) in cases {
        let f = d.join(name);
        std::fs::write(&f, text).unwrap();
        let o = run_in(&d, &["laplace", "--series", s(&f), "--s", "1"], &[]);
        refused(&o, needle);
        assert_eq!(o.code, 2, "{name}: {}", o.stderr);
    }
    std::fs::remove_dir_all(&d).ok();
}

/// Item 9: a FIFO as input blocked forever.
#[cfg(unix)]
#[test]
fn item9_fifo_input_is_refused() {
    let d = tmpdir("i9f");
    let fifo = d.join("in.csv");
    mkfifo(&fifo);
    let o = run_bounded(&d, &["laplace", "--series", s(&fifo), "--s", "1"]);
    refused(&o, "FIFO");
    let o = run_bounded(&d, &["fit", "--data", s(&fifo), "--n", "3"]);
    refused(&o, "FIFO");
    std::fs::remove_dir_all(&d).ok();
}

/// Item 5: `--column "x1 [m]"`, the header's own text, is accepted.
#[test]
fn item5_column_by_its_header_text_with_unit() {
    let d = tmpdir("i5");
    let f = d.join("units.csv");
    record(&f, "t [s],x1 [m]", 81);
    let o = run_in(
        &d,
        &[
            "laplace",
            "--series",
            s(&f),
            "--column",
            "x1 [m]",
            "--s",
            "1",
        ],
        &[],
    );
    assert_eq!(o.code, 0, "{}", o.stderr);
    std::fs::remove_dir_all(&d).ok();
}

/// Item 10: an error does not echo a whole long line.
#[test]
fn item10_long_line_is_not_echoed() {
    let d = tmpdir("i10");
    let f = d.join("long.csv");
    std::fs::write(&f, format!("t,x1\n0,{}z\n", "9".repeat(1 << 20))).unwrap();
    let o = run_in(&d, &["laplace", "--series", s(&f), "--s", "1"], &[]);
    refused(&o, "not a number");
    assert!(o.stderr.len() < 4000, "{} bytes of stderr", o.stderr.len());
    std::fs::remove_dir_all(&d).ok();
}

/// Item 7: memory refused up front with the budget named.
#[test]
fn item7_huge_chains_are_refused_before_allocating() {
    let d = tmpdir("i7");
    let rec = d.join("x1.csv");
    record(&rec, "t,x1", 201);
    let o = run_in(
        &d,
        &[
            "fit",
            "--data",
            s(&rec),
            "--n",
            "1000000000",
            "--defects",
            "1",
        ],
        &[],
    );
    refused(&o, "SPRINGMASS_MEMORY_BUDGET");
    let o = run_in(
        &d,
        &[
            "fit",
            "--data",
            s(&rec),
            "--n",
            "1000000",
            "--profile",
            "masses",
        ],
        &[],
    );
    refused(&o, "SPRINGMASS_MEMORY_BUDGET");
    let modes = d.join("modes.csv");
    std::fs::write(&modes, "omega,residue\n1,0.5\n2,0.5\n").unwrap();
    let o = run_in(
        &d,
        &["spectral", "--modes", s(&modes), "--n", "1000000000"],
        &[],
    );
    refused(&o, "number of modes");
    std::fs::remove_dir_all(&d).ok();
}

/// Item 11: silent accepts.
#[test]
fn item11_zero_impulse_and_negative_omega_are_refused() {
    let d = tmpdir("i11");
    let rec = d.join("x1.csv");
    record(&rec, "t,x1", 201);
    for g in ["0", "5e-324"] {
        let o = run_in(
            &d,
            &["fit", "--data", s(&rec), "--n", "3", "--gamma", g],
            &[],
        );
        refused(&o, "gamma");
        assert!(!o.stdout.contains("NaN"), "{}", o.stdout);
    }
    let modes = d.join("modes.csv");
    std::fs::write(&modes, "omega,residue\n-1,0.5\n2,0.5\n").unwrap();
    let o = run_in(
        &d,
        &["spectral", "--modes", s(&modes), "--n", "2", "--json"],
        &[],
    );
    refused(&o, "omega");
    assert!(!o.stdout.contains("\"resolved\": true"), "{}", o.stdout);
    std::fs::remove_dir_all(&d).ok();
}

/// Item 13: messages that say what in the input causes the failure.
#[test]
fn item13_messages_name_the_cause_in_the_input() {
    let d = tmpdir("i13");
    let cases: [(&str, String, &str); 3] = [
        (
            "zero.csv",
            (0..101)
                .map(|i| format!("{},0\n", i as f64 * 0.25))
                .collect(),
            "every one 0",
        ),
        (
            "huge.csv",
            (0..101)
                .map(|i| format!("{},{:e}\n", i as f64 * 0.25, 1e200 * (i as f64 * 0.3).sin()))
                .collect(),
            "rescale the data",
        ),
        (
            "tiny.csv",
            (0..101)
                .map(|i| format!("{:e},{}\n", i as f64 * 1e-300, (i as f64 * 0.3).sin()))
                .collect(),
            "rescale the times",
        ),
    ];
    for (name, rows, needle) in cases {
        let f = d.join(name);
        std::fs::write(&f, format!("t,x1\n{rows}")).unwrap();
        let o = run_in(&d, &["fit", "--data", s(&f), "--n", "3"], &[]);
        refused(&o, needle);
        assert_eq!(o.code, 2, "{name}: {}", o.stderr);
    }
    std::fs::remove_dir_all(&d).ok();
}

/// Item 12: a second `study` on one `--out` is refused naming the holder.
#[cfg(unix)]
#[test]
fn item12_second_study_on_one_folder_is_refused() {
    let d = tmpdir("i12");
    let out = d.join("out");
    std::fs::create_dir_all(&out).unwrap();
    // this test process stands in for a running study
    std::fs::write(out.join(".lock"), format!("{}\n", std::process::id())).unwrap();
    let o = run_in(
        &d,
        &["study", "--default", "--quiet", "--out", s(&out)],
        &[],
    );
    refused(&o, &format!("process {}", std::process::id()));
    std::fs::remove_dir_all(&d).ok();
}

/// Item 10: `locate --precision` beyond what ends in seconds is refused,
/// naming the cap (65536, the old documented maximum, ran over 300 s).
#[test]
fn item10_locate_precision_is_capped() {
    let d = tmpdir("i10p");
    let o = run_bounded(
        &d,
        &[
            "locate",
            "--n",
            "5",
            "--defect",
            "mass:3:4",
            "--large",
            "--s",
            "50",
            "--precision",
            "65536",
        ],
    );
    refused(&o, "64..=4096");
    std::fs::remove_dir_all(&d).ok();
}

/// Found by the Python API fuzz: a known damping of 1e300 sent the modal
/// time response's SVD (near-double poles) into an endless iteration on
/// non-finite values; it must fail at once with a numerical error.
#[test]
fn huge_known_damping_fails_instead_of_hanging() {
    let d = tmpdir("hugedamping");
    let data = d.join("x.csv");
    record(&data, "t,x1", 40);
    let o = run_bounded(
        &d,
        &[
            "fit",
            "--data",
            s(&data),
            "--n",
            "3",
            "--defects",
            "1",
            "--d",
            "1e300",
        ],
    );
    refused(&o, "beyond f64");
}
