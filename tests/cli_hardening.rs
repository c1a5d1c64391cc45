//! Regression tests for the CLI and I/O findings of issue 17: special files
//! never replaced, pipes and full outputs, exit codes, limits checked before
//! any work, negative numbers, overflow, completions and man page, and CSV
//! forms read by `laplace`.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

const BIN: &str = env!("CARGO_BIN_EXE_springmass");

fn run_env(args: &[&str], env: &[(&str, &str)]) -> (i32, String, String) {
    let mut cmd = Command::new(BIN);
    cmd.args(args);
    for (k, v) in env {
        cmd.env(k, v);
    }
    let out = cmd.output().unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn run(args: &[&str]) -> (i32, String, String) {
    run_env(args, &[])
}

fn tmpdir(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("springmass-hard-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn no_panic(err: &str) {
    assert!(!err.contains("panicked"), "{err}");
}

#[cfg(unix)]
fn mkfifo(path: &Path) {
    assert!(Command::new("mkfifo").arg(path).status().unwrap().success());
}

#[cfg(unix)]
#[test]
fn out_on_fifo_symlink_and_folder_is_refused_or_followed() {
    use std::os::unix::fs::FileTypeExt;
    let d = tmpdir("out");
    let fifo = d.join("p.csv");
    mkfifo(&fifo);
    let sim = [
        "simulate", "--n", "3", "--t-end", "1", "--dt", "0.5", "--out",
    ];
    let (code, _, err) = run(&[&sim[..], &[s(&fifo)]].concat());
    assert_eq!(code, 3, "{err}");
    assert!(err.contains(s(&fifo)) && err.contains("FIFO"), "{err}");
    assert!(std::fs::symlink_metadata(&fifo)
        .unwrap()
        .file_type()
        .is_fifo());
    // a folder
    let (code, _, err) = run(&[&sim[..], &[s(&d)]].concat());
    assert_eq!(code, 3, "{err}");
    assert!(err.contains("directory"), "{err}");
    // a device
    let (code, _, err) = run(&[&sim[..], &["/dev/null"]].concat());
    assert_eq!(code, 3, "{err}");
    assert!(err.contains("/dev/null"), "{err}");
    // a symlink to a regular file: the target is written, the link stays
    let target = d.join("target.csv");
    std::fs::write(&target, "old").unwrap();
    let link = d.join("link.csv");
    std::os::unix::fs::symlink("target.csv", &link).unwrap();
    let (code, _, err) = run(&[&sim[..], &[s(&link)]].concat());
    assert_eq!(code, 0, "{err}");
    assert!(std::fs::symlink_metadata(&link)
        .unwrap()
        .file_type()
        .is_symlink());
    assert!(std::fs::read_to_string(&target)
        .unwrap()
        .starts_with("t,x1"));
    // a symlink to the FIFO: refused, both stay
    let lf = d.join("lf.csv");
    std::os::unix::fs::symlink("p.csv", &lf).unwrap();
    let (code, _, err) = run(&[&sim[..], &[s(&lf)]].concat());
    assert_eq!(code, 3, "{err}");
    assert!(std::fs::symlink_metadata(&lf)
        .unwrap()
        .file_type()
        .is_symlink());
    assert!(std::fs::symlink_metadata(&fifo)
        .unwrap()
        .file_type()
        .is_fifo());
    // surface: both outputs checked before the work
    let scene = d.join("scene.toml");
    std::fs::write(
        &scene,
        "[chain]\nn = 4\ndefects = [{ kind = \"mass\", at = 2, m = 3.0 }]\n",
    )
    .unwrap();
    let svg_fifo = d.join("surf.svg");
    mkfifo(&svg_fifo);
    let (code, _, err) = run(&[
        "surface",
        "--scene",
        s(&scene),
        "--kind",
        "jm",
        "--m-steps",
        "3",
        "--out",
        s(&d.join("surf")),
    ]);
    assert_eq!(code, 3, "{err}");
    assert!(
        !d.join("surf.csv").exists(),
        "csv written before the svg was checked"
    );
    assert!(std::fs::symlink_metadata(&svg_fifo)
        .unwrap()
        .file_type()
        .is_fifo());
    std::fs::remove_dir_all(&d).ok();
}

#[cfg(unix)]
#[test]
fn full_stdout_is_an_io_error_and_closed_pipes_are_quiet() {
    let full = std::fs::OpenOptions::new()
        .write(true)
        .open("/dev/full")
        .unwrap();
    let out = Command::new(BIN)
        .args(["response", "--n", "5", "--s", "1", "--json"])
        .stdout(full)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "{err}");
    no_panic(&err);
    assert!(err.contains("stdout"), "{err}");
    // closed stdout or stderr pipe: killed by SIGPIPE (141 in a shell), no panic
    use std::os::unix::process::ExitStatusExt;
    for closed in ["stdout", "stderr"] {
        let mut cmd = Command::new(BIN);
        cmd.args(["simulate", "--n", "20", "--t-end", "200", "--dt", "0.01"]);
        if closed == "stdout" {
            cmd.stdout(Stdio::piped()).stderr(Stdio::null());
        } else {
            // stdout is a file (no CSV on the pipe); the report line goes to stderr
            cmd.stdout(Stdio::null()).stderr(Stdio::piped());
        }
        let mut child = cmd.spawn().unwrap();
        drop(child.stdout.take());
        drop(child.stderr.take());
        let st = child.wait().unwrap();
        assert_eq!(st.signal(), Some(libc_sigpipe()), "{closed}: {st:?}");
    }
}

fn libc_sigpipe() -> i32 {
    13
}

#[test]
fn exit_codes_by_class() {
    assert_eq!(run(&["--help"]).0, 0);
    let (_, help, _) = run(&["--help"]);
    assert!(
        help.contains("Exit status") && help.contains("SPRINGMASS_MEMORY_BUDGET"),
        "{help}"
    );
    assert_eq!(run(&["response", "--bogus"]).0, 2);
    assert_eq!(run(&["response", "--n", "0", "--s", "1"]).0, 2);
    let (code, _, err) = run(&["laplace", "--series", "no-such-file.csv", "--s", "1"]);
    assert_eq!(code, 3, "{err}");
}

#[test]
fn negative_numbers_in_every_form() {
    for g in ["-1e-3", "-0.001", "-1E-3"] {
        let (code, _, err) = run(&["response", "--n", "3", "--s", "1", "--gamma", g, "--json"]);
        assert_eq!(code, 0, "--gamma {g}: {err}");
    }
}

#[test]
fn overflow_is_not_a_pole() {
    let (code, _, err) = run(&[
        "response",
        "--n",
        "3",
        "--s",
        "1+5i",
        "--gamma",
        "1.7976931348623157e308",
    ]);
    assert_eq!(code, 4, "{err}");
    assert!(err.contains("overflows") && !err.contains("pole"), "{err}");
    // a true pole stays a pole (undamped chain on the imaginary axis)
    let (code, _, err) = run(&[
        "response",
        "--n",
        "1",
        "--d",
        "0",
        "--s",
        "0+1.4142135623730951i",
    ]);
    assert!(code == 2 || code == 0, "{err}");
}

fn series_file(d: &Path, t0: f64) -> PathBuf {
    let p = d.join(format!("series{t0}.csv"));
    let mut text = String::from("t,x1\n");
    for i in 0..80 {
        let t = t0 + i as f64 * 0.1;
        text.push_str(&format!("{t},{}\n", (-0.5 * t).exp() * t.sin()));
    }
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn laplace_refuses_negative_times_and_unrepresentable_results() {
    let d = tmpdir("laplace");
    let neg = series_file(&d, -1.0);
    let (code, _, err) = run(&["laplace", "--series", s(&neg), "--s", "1"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("t >= 0"), "{err}");
    let pos = series_file(&d, 0.0);
    let (code, out, err) = run(&[
        "laplace",
        "--series",
        s(&pos),
        "--s",
        "1e308+1e308i",
        "--json",
    ]);
    assert_ne!(code, 0, "{out} {err}");
    assert!(!out.contains("null"), "{out}");
    no_panic(&err);
    std::fs::remove_dir_all(&d).ok();
}

#[cfg(unix)]
#[test]
fn inputs_are_read_with_a_cap() {
    let (code, _, err) = run_env(
        &["laplace", "--series", "/dev/urandom", "--s", "1"],
        &[("SPRINGMASS_MAX_INPUT", "64K")],
    );
    assert_eq!(code, 3, "{err}");
    assert!(err.contains("input cap"), "{err}");
    // without the variable the default cap (256 MiB) applies: /dev/zero stops too
    let (code, _, err) = run(&["response", "--scene", "/dev/zero", "--s", "1"]);
    assert_ne!(code, 0, "{err}");
    no_panic(&err);
}

#[test]
fn limits_are_checked_before_work() {
    let (code, _, err) = run(&[
        "simulate",
        "--n",
        "1000000000",
        "--t-end",
        "1",
        "--dt",
        "0.5",
    ]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("SPRINGMASS_MEMORY_BUDGET"), "{err}");
    // the budget is an override: a tiny budget refuses a small job
    let (code, _, err) = run_env(
        &["simulate", "--n", "30", "--t-end", "10", "--dt", "0.1"],
        &[("SPRINGMASS_MEMORY_BUDGET", "1K")],
    );
    assert_eq!(code, 2, "{err}");
    let (code, _, err) = run_env(
        &["simulate", "--n", "3", "--t-end", "1", "--dt", "0.5"],
        &[("SPRINGMASS_MEMORY_BUDGET", "lots")],
    );
    assert_eq!(code, 2, "{err}");
    let d = tmpdir("limits");
    let (code, _, err) = run(&[
        "suppress",
        "--n",
        "3",
        "--t-end",
        "2",
        "--robust-delays",
        "1e308",
        "--out-dir",
        s(&d.join("sup")),
    ]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("--robust-delays"), "{err}");
    let scene = d.join("scene.toml");
    std::fs::write(
        &scene,
        "[chain]\nn = 4\ndefects = [{ kind = \"mass\", at = 2, m = 3.0 }]\n",
    )
    .unwrap();
    for range in [["1e-320", "10"], ["0.1", "1e308"]] {
        let (code, _, err) = run(&[
            "surface",
            "--scene",
            s(&scene),
            "--kind",
            "jm",
            "--m-range",
            range[0],
            range[1],
            "--out",
            s(&d.join("surf")),
        ]);
        assert_eq!(code, 2, "{range:?}: {err}");
        assert!(err.contains("--m-range"), "{err}");
    }
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn completions_and_man_page() {
    for shell in ["bash", "zsh", "fish"] {
        let (code, out, err) = run(&["completions", shell]);
        assert_eq!(code, 0, "{err}");
        assert!(
            out.contains("springmass") && out.contains("simulate"),
            "{shell}"
        );
    }
    let (code, out, err) = run(&["man"]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains(".TH") && out.contains("springmass"), "{out}");
    assert_eq!(run(&["completions", "tcsh"]).0, 2);
}

#[test]
fn laplace_reads_logger_and_pandas_csv() {
    let d = tmpdir("forms");
    let rows: Vec<(f64, f64)> = (0..80)
        .map(|i| {
            let t = i as f64 * 0.1;
            (t, (-0.5 * t).exp() * t.sin())
        })
        .collect();
    let plain: String = std::iter::once("t,x1\n".to_string())
        .chain(rows.iter().map(|(t, x)| format!("{t},{x}\n")))
        .collect();
    let forms = [
        (
            "quoted",
            std::iter::once("\"t\",\"x1\"\n".to_string())
                .chain(rows.iter().map(|(t, x)| format!("{t},{x}\n")))
                .collect::<String>(),
        ),
        (
            "units",
            std::iter::once("time [s],x1 [m]\n".to_string())
                .chain(rows.iter().map(|(t, x)| format!("{t},{x}\n")))
                .collect(),
        ),
        (
            "semicolon",
            std::iter::once("t;x1\n".to_string())
                .chain(rows.iter().map(|(t, x)| format!("{t};{x}\n")))
                .collect(),
        ),
        (
            "tab",
            std::iter::once("t\tx1\n".to_string())
                .chain(rows.iter().map(|(t, x)| format!("{t}\t{x}\n")))
                .collect(),
        ),
        (
            "trailing",
            std::iter::once("t,x1,\n".to_string())
                .chain(rows.iter().map(|(t, x)| format!("{t},{x},\n")))
                .collect(),
        ),
        (
            "pandas",
            std::iter::once(",t,x1\n".to_string())
                .chain(
                    rows.iter()
                        .enumerate()
                        .map(|(i, (t, x))| format!("{i},{t},{x}\n")),
                )
                .collect(),
        ),
        (
            "comments",
            std::iter::once("# logger\nt,x1\n".to_string())
                .chain(rows.iter().map(|(t, x)| format!("{t},{x}\n")))
                .collect(),
        ),
    ];
    let ref_path = d.join("plain.csv");
    std::fs::write(&ref_path, plain).unwrap();
    let (code, want, err) = run(&[
        "laplace",
        "--series",
        s(&ref_path),
        "--s",
        "0.5,1+2i",
        "--json",
    ]);
    assert_eq!(code, 0, "{err}");
    for (name, text) in forms {
        let p = d.join(format!("{name}.csv"));
        std::fs::write(&p, text).unwrap();
        let (code, out, err) = run(&[
            "laplace",
            "--series",
            s(&p),
            "--s",
            "0.5,1+2i",
            "--json",
            "--column",
            "1",
        ]);
        assert_eq!(code, 0, "{name}: {err}");
        assert_eq!(out, want, "{name}");
    }
    let bad = d.join("bad.csv");
    std::fs::write(&bad, "t,x1\n0,1\n0.1,oops\n").unwrap();
    let (code, _, err) = run(&["laplace", "--series", s(&bad), "--s", "1"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("row 2 (line 3), column 2 `x1`"), "{err}");
    std::fs::remove_dir_all(&d).ok();
}
