//! Integration tests of the study machinery through the built binary:
//! interrupt and resume, thread-count independence, shards and merge,
//! `config check`, and a property test of the config parser.

use proptest::prelude::*;
use springmass::study::check::check;
use springmass::study::Study;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_springmass");

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("springmass-it-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Every file of a folder and of its `cases/` subfolder, by relative name.
fn files(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut out = BTreeMap::new();
    for sub in ["", "cases"] {
        let Ok(entries) = std::fs::read_dir(dir.join(sub)) else {
            continue;
        };
        for p in entries.map(|e| e.unwrap().path()).filter(|p| p.is_file()) {
            let name = p.file_name().unwrap().to_string_lossy().to_string();
            let key = if sub.is_empty() {
                name
            } else {
                format!("{sub}/{name}")
            };
            out.insert(key, std::fs::read(&p).unwrap());
        }
    }
    out
}

fn assert_same_files(a: &Path, b: &Path) {
    let (fa, fb) = (files(a), files(b));
    assert_eq!(
        fa.keys().collect::<Vec<_>>(),
        fb.keys().collect::<Vec<_>>(),
        "file lists differ"
    );
    for (name, bytes) in &fa {
        assert!(
            bytes == &fb[name],
            "{name} differs between {} and {}",
            a.display(),
            b.display()
        );
    }
}

fn study(args: &[&str]) -> std::process::Output {
    Command::new(BIN)
        .arg("study")
        .args(args)
        .stdin(Stdio::null())
        .output()
        .unwrap()
}

/// A study of 24 cases with random defects and repeats; each case spends
/// about `5 * 3 * min_seconds` in its timing loops (timings not recorded).
fn study_text(min_seconds: f64) -> String {
    format!(
        r#"
[study]
name = "it"
kind = "forward"
seed = 5
repeats = 2
timings = false

[scene]
chain = {{ n = 10, defects = [ {{ kind = "spring", at = 0, k = 2.0 }} ] }}
random_defects = {{ count = 1, kind = "mass", min = 0.3, max = 30.0 }}
s = {{ from = 0.01, to = 20.0, count = 16 }}
timing = {{ min_seconds = {min_seconds} }}

[[sweep]]
path = "chain.n"
name = "n"
values = [3, 40, 700]

[[sweep]]
path = "random_defects.count"
name = "k"
range = {{ from = 1, to = 3, step = 1, integer = true }}

[[sweep]]
path = "s.sigma"
values = [0.05]

[[report.table]]
rows = ["k"]
metrics = ["max_rel_diff", "max_rel_diff_transfer"]
aggregate = "max"

[[report.plot]]
x = "n"
y = "max_rel_diff"
series = "k"
logx = true
logy = true
"#
    )
}

#[test]
fn threads_1_and_2_give_identical_files() {
    let dir = tmp("threads");
    let file = dir.join("s.toml");
    std::fs::write(&file, study_text(0.0)).unwrap();
    let f = file.to_str().unwrap();
    let (a, b) = (dir.join("a"), dir.join("b"));
    let oa = study(&[f, "--out", a.to_str().unwrap(), "--threads", "1"]);
    assert!(
        oa.status.success(),
        "{}",
        String::from_utf8_lossy(&oa.stderr)
    );
    let ob = study(&[f, "--out", b.to_str().unwrap(), "--threads", "2"]);
    assert!(
        ob.status.success(),
        "{}",
        String::from_utf8_lossy(&ob.stderr)
    );
    assert!(String::from_utf8_lossy(&oa.stdout).contains("report: "));
    assert_same_files(&a, &b);
    let names: Vec<String> = files(&a).into_keys().collect();
    assert_eq!(
        names,
        [
            "manifest.json",
            "max_rel_diff-vs-n.svg",
            "report.md",
            "results.jsonl",
            "study.toml",
            "summary.csv"
        ]
    );
    let csv = std::fs::read_to_string(a.join("summary.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 18);
    // every case succeeded and agrees with the reference
    let s = Study::from_file(&file).unwrap();
    assert_eq!(s.cases.len(), 18);
    for line in std::fs::read_to_string(a.join("results.jsonl"))
        .unwrap()
        .lines()
    {
        let v: serde_json::Value = serde_json::from_str(line).unwrap();
        assert_eq!(v["status"], "ok", "{line}");
        assert!(
            v["metrics"]["max_rel_diff"].as_f64().unwrap() < 1e-9,
            "{line}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn killed_study_resumes_to_identical_outputs() {
    let dir = tmp("resume");
    let file = dir.join("s.toml");
    // about 0.05 s per case: the run takes about a second on one thread
    std::fs::write(&file, study_text(0.02)).unwrap();
    let f = file.to_str().unwrap();
    let (full, cut) = (dir.join("full"), dir.join("cut"));
    let o = study(&[f, "--out", full.to_str().unwrap(), "--threads", "2"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    let mut child = Command::new(BIN)
        .args(["study", f, "--out", cut.to_str().unwrap(), "--threads", "1"])
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let results = cut.join("results.jsonl");
    let start = Instant::now();
    let mut killed_with = 0;
    loop {
        let lines = std::fs::read_to_string(&results)
            .map(|t| t.lines().count())
            .unwrap_or(0);
        if lines >= 3 {
            child.kill().unwrap(); // SIGKILL: no chance to clean up
            killed_with = lines;
            break;
        }
        if child.try_wait().unwrap().is_some() || start.elapsed() > Duration::from_secs(60) {
            break;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    child.wait().unwrap();
    assert!(
        killed_with >= 3,
        "the study finished before it could be killed"
    );
    assert!(!cut.join("report.md").exists(), "killed run wrote a report");
    let done_at_kill = std::fs::read_to_string(&results).unwrap().lines().count();
    assert!(done_at_kill < 18, "{done_at_kill}");
    // simulate a write torn by the kill as well
    let mut t = std::fs::read(&results).unwrap();
    t.extend_from_slice(b"{\"id\":\"c00");
    std::fs::write(&results, t).unwrap();

    let o = study(&[f, "--out", cut.to_str().unwrap(), "--threads", "2"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains(&format!(
            "{} run now, {} resumed",
            18 - done_at_kill,
            done_at_kill
        )),
        "{err}"
    );
    assert_same_files(&full, &cut);
    // a third run has nothing to do and changes nothing
    let o = study(&[f, "--out", cut.to_str().unwrap()]);
    assert!(String::from_utf8_lossy(&o.stderr).contains("0 run now, 18 resumed"));
    assert_same_files(&full, &cut);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn shards_merge_into_the_single_run_report() {
    let dir = tmp("shards");
    let file = dir.join("s.toml");
    std::fs::write(&file, study_text(0.0)).unwrap();
    let f = file.to_str().unwrap();
    let single = dir.join("single");
    assert!(study(&[f, "--out", single.to_str().unwrap()])
        .status
        .success());
    let mut shard_dirs = Vec::new();
    for i in 1..=3 {
        let d = dir.join(format!("shard{i}"));
        let o = study(&[
            f,
            "--out",
            d.to_str().unwrap(),
            "--shard",
            &format!("{i}/3"),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert!(!d.join("report.md").exists());
        assert_eq!(
            std::fs::read_to_string(d.join("results.jsonl"))
                .unwrap()
                .lines()
                .count(),
            6
        );
        shard_dirs.push(d);
    }
    let merged = dir.join("merged");
    let mut args = vec!["merge".to_string()];
    args.extend(shard_dirs.iter().rev().map(|d| d.display().to_string()));
    args.extend(["--out".to_string(), merged.display().to_string()]);
    let args: Vec<&str> = args.iter().map(|s| s.as_str()).collect();
    let o = study(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_same_files(&single, &merged);
    // a missing shard is an error that says how many cases are missing
    let o = study(&[
        "merge",
        shard_dirs[0].to_str().unwrap(),
        "--out",
        dir.join("bad").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("12 of 18 cases missing"));
    // a shard folder is refused for another shard
    let o = study(&[
        f,
        "--out",
        shard_dirs[0].to_str().unwrap(),
        "--shard",
        "2/3",
    ]);
    assert_eq!(o.status.code(), Some(2));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn suppression_shards_with_case_plots_merge_exactly() {
    let dir = tmp("suppress");
    let file = dir.join("s.toml");
    std::fs::write(
        &file,
        r#"
[study]
name = "sup"
kind = "suppress"
timings = false
[scene]
n = 3
t_end = 10.0
dt = 0.1
plots = true
[[sweep]]
path = "scheme"
values = ["cloak", "single"]
[[sweep]]
path = "input.kind"
values = ["impulse", "noise"]
"#,
    )
    .unwrap();
    let f = file.to_str().unwrap();
    let single = dir.join("single");
    let o = study(&[f, "--out", single.to_str().unwrap(), "--threads", "2"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let fs = files(&single);
    assert_eq!(fs.keys().filter(|k| k.starts_with("cases/")).count(), 12);
    let md = String::from_utf8_lossy(&fs["report.md"]).to_string();
    assert!(md.contains("[controls](cases/c0000-controls.svg)"), "{md}");
    let (a, b) = (dir.join("a"), dir.join("b"));
    for (d, s) in [(&a, "1/2"), (&b, "2/2")] {
        let o = study(&[
            f,
            "--out",
            d.to_str().unwrap(),
            "--shard",
            s,
            "--threads",
            "1",
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let merged = dir.join("merged");
    let o = study(&[
        "merge",
        a.to_str().unwrap(),
        b.to_str().unwrap(),
        "--out",
        merged.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_same_files(&single, &merged);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn fit_and_locate_studies_do_not_depend_on_threads() {
    let dir = tmp("fitloc");
    let studies = [
        r#"
[study]
name = "fit"
kind = "fit"
seed = 4
repeats = 2
timings = false
[scene]
chain = { n = 5, defects = [ { kind = "mass", at = 2, m = 3.0 }, { kind = "mass", at = 4, m = 0.5 } ] }
data = { noise = 1e-6 }
search = { max_evals = 3000, parallel = true }
[[sweep]]
path = "search.method"
values = ["enumerate", "ga", "pso"]
[[report.plot]]
x = "repeat"
y = "success"
series = "search.method"
aggregate = "rate"
"#,
        r#"
[study]
name = "loc"
kind = "locate"
timings = false
[scene]
chain = { n = 20, defects = [ { kind = "mass", at = 3, m = 5.0 } ] }
plots = true
[[sweep]]
path = "method"
values = ["exact", "large", "large-paper", "unknown-mass"]
"#,
    ];
    for (i, text) in studies.iter().enumerate() {
        let file = dir.join(format!("s{i}.toml"));
        std::fs::write(&file, text).unwrap();
        let f = file.to_str().unwrap();
        let (a, b) = (dir.join(format!("a{i}")), dir.join(format!("b{i}")));
        for (d, t) in [(&a, "1"), (&b, "2")] {
            let o = study(&[f, "--out", d.to_str().unwrap(), "--threads", t]);
            assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        }
        assert_same_files(&a, &b);
        let csv = std::fs::read_to_string(a.join("summary.csv")).unwrap();
        assert!(csv.lines().skip(1).all(|l| l.contains(",ok,")), "{csv}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A fit study with traced GA runs and a `locate` part sweeping precision.
const TRACE_PARTS: &str = r#"
[study]
name = "traceparts"
kind = "fit"
seed = 3
repeats = 2
timings = false
[scene]
chain = { n = 5, defects = [ { kind = "mass", at = 2, m = 3.0 }, { kind = "mass", at = 4, m = 0.5 } ] }
data = { noise = 1e-6 }
search = { method = "ga", max_evals = 1500, parallel = false, trace = true }
[[sweep]]
path = "search.method"
name = "method"
values = ["ga", "pso"]

[[part]]
name = "precision"
kind = "locate"
scene = { chain = { n = 20, defects = [ { kind = "mass", at = 15, m = 1.01 } ] }, method = "exact", s = 0.3 }
[[part.sweep]]
path = "precision"
name = "bits"
labels = ["53", "256"]
values = ["f64", 256]

[[report.table]]
part = "precision"
rows = ["bits"]
metrics = ["success", "digits", "j_error", "bits"]
[[report.trace]]
file = "trace.svg"
part = "main"
series = ["method"]
[[report.plot]]
part = "precision"
x = "bits"
y = "digits"
"#;

#[test]
fn traces_and_parts_are_deterministic_across_threads_and_shards() {
    let dir = tmp("traceparts");
    let file = dir.join("s.toml");
    std::fs::write(&file, TRACE_PARTS).unwrap();
    let f = file.to_str().unwrap();
    let (a, b) = (dir.join("a"), dir.join("b"));
    for (d, t) in [(&a, "1"), (&b, "2")] {
        let o = study(&[f, "--out", d.to_str().unwrap(), "--threads", t]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    assert_same_files(&a, &b);
    // shards (a resumed or merged run reads the traces from the records)
    let mut shards = Vec::new();
    for i in 1..=2 {
        let d = dir.join(format!("shard{i}"));
        let o = study(&[
            f,
            "--out",
            d.to_str().unwrap(),
            "--shard",
            &format!("{i}/2"),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        shards.push(d.display().to_string());
    }
    let merged = dir.join("merged");
    let o = study(&[
        "merge",
        &shards[0],
        &shards[1],
        "--out",
        merged.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_same_files(&a, &merged);
    // interrupted after 3 cases, then resumed: the same files
    let st = Study::from_text(TRACE_PARTS, f).unwrap();
    let r = dir.join("resumed");
    let mut o = springmass::study::run::RunOptions::new(&r);
    o.progress = false;
    o.max_cases = Some(3);
    o.threads = Some(2);
    assert!(!springmass::study::run::run(&st, &o).unwrap().complete);
    o.max_cases = None;
    let done = springmass::study::run::run(&st, &o).unwrap();
    assert!(done.complete && done.resumed == 3);
    assert_same_files(&a, &r);
    // the trace plot: one line per method, drawn from the records
    let svg = std::fs::read_to_string(a.join("trace.svg")).unwrap();
    assert!(
        svg.contains("method = ga") && svg.contains("method = pso"),
        "{svg}"
    );
    let records = std::fs::read_to_string(a.join("results.jsonl")).unwrap();
    let traced = records
        .lines()
        .filter(|l| l.contains("\"trace\":[["))
        .count();
    assert_eq!(traced, 4, "{records}");
    // the precision part: f64 and 256 bits both locate; 256 bits has far
    // more correct digits
    let csv = std::fs::read_to_string(a.join("summary.csv")).unwrap();
    assert!(csv.lines().skip(1).all(|l| l.contains(",ok,")), "{csv}");
    let md = std::fs::read_to_string(a.join("report.md")).unwrap();
    assert!(md.contains("digits-vs-bits.svg"), "{md}");
    let digits = |bits: &str| -> f64 {
        let row = md
            .lines()
            .find(|l| l.starts_with(&format!("| {bits} | 2 | 0 |")))
            .unwrap_or_else(|| panic!("{md}"));
        row.split('|').nth(5).unwrap().trim().parse().unwrap()
    };
    let (d53, d256) = (digits("53"), digits("256"));
    assert!(d53 > 5.0 && d53 < 16.0, "{d53}");
    assert!(d256 > 60.0, "{d256}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn config_check_lists_every_problem_of_fit_and_locate_scenes() {
    let fit = r#"[study]
name = "badfit"
kind = "fit"
[scene]
chain = { n = 5, d = -1.0, defects = [ { kind = "mass", at = 9, m = 3.0 } ] }
data = { noise = -0.1 }
unknowns = { k = 1, mass_bounds = [5.0, 1.0] }
misfit = { s_max = -3.0, per_panel = "eight" }
search = { method = "ga", max_evals = "many" }
"#;
    let p = check(fit);
    let paths: Vec<&str> = p.iter().map(|p| p.path.as_str()).collect();
    for want in [
        "scene.chain.d",
        "scene.chain.defects[0].at",
        "scene.data.noise",
        "scene.unknowns.mass_bounds",
        "scene.misfit.s_max",
        "scene.misfit.per_panel",
        "scene.search.max_evals",
    ] {
        assert!(paths.contains(&want), "{want} missing from {p:?}");
    }
    assert_eq!(p.len(), 7, "{p:?}");
    assert!(p.iter().all(|p| p.line.is_some()), "{p:?}");
    let by_path = |path: &str| p.iter().find(|x| x.path == path).unwrap();
    assert_eq!(by_path("scene.data.noise").line, Some(6));
    assert_eq!(by_path("scene.misfit.s_max").line, Some(8));
    // the same through the binary, one line per problem
    let dir = tmp("checkfit");
    let file = dir.join("bad.toml");
    std::fs::write(&file, fit).unwrap();
    let o = Command::new(BIN)
        .args(["config", "check", file.to_str().unwrap()])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("line 6: scene.data.noise"), "{out}");
    assert!(out.contains("line 9: scene.search.max_evals"), "{out}");
    assert!(out.contains("line 5: scene.chain.defects[0].at"), "{out}");
    // a locate scene: a bad precision, method and s, all named
    let loc = r#"[study]
name = "badloc"
kind = "locate"
[scene]
chain = { n = 5, defects = [ { kind = "mass", at = 3, m = 4.0 } ] }
method = "big"
precision = 12
s = -1.0
dt = "x"
"#;
    let p = check(loc);
    let paths: Vec<&str> = p.iter().map(|p| p.path.as_str()).collect();
    assert_eq!(
        paths,
        vec!["scene.method", "scene.precision", "scene.s", "scene.dt"],
        "{p:?}"
    );
    assert!(p[1].message.contains("64..=4096"), "{p:?}");
    for bad in ["\"f32\"", "5000", "63", "256.0"] {
        let p = check(
            &loc.replace("precision = 12", &format!("precision = {bad}"))
                .replace("method = \"big\"", "method = \"exact\"")
                .replace("s = -1.0\ndt = \"x\"\n", ""),
        );
        assert_eq!(p.len(), 1, "{bad}: {p:?}");
        assert_eq!(p[0].path, "scene.precision", "{bad}: {p:?}");
    }
    let ok = loc
        .replace("method = \"big\"", "method = \"exact\"")
        .replace("s = -1.0\ndt = \"x\"\n", "");
    for good in ["\"f64\"", "64", "128", "4096"] {
        assert_eq!(
            check(&ok.replace("precision = 12", &format!("precision = {good}"))),
            vec![]
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn default_study_runs_and_says_where_the_report_is() {
    let dir = tmp("default");
    let o = Command::new(BIN)
        .arg("study")
        .current_dir(&dir)
        .stdin(Stdio::null())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("report: out/default/report.md"), "{out}");
    let md = std::fs::read_to_string(dir.join("out/default/report.md")).unwrap();
    assert!(md.contains("# Study `default`"));
    assert!(dir.join("out/default/evaluations.svg").exists());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn config_check_reports_every_problem_with_path_and_line() {
    let dir = tmp("check");
    let bad = dir.join("bad.toml");
    let text = study_text(0.0)
        .replace("seed = 5", "sed = 5")
        .replace("name = \"k\"", "nmae = \"k\"")
        .replace("\ns = {", "\ns = { cout = 3,");
    std::fs::write(&bad, &text).unwrap();
    let o = Command::new(BIN)
        .args(["config", "check", bad.to_str().unwrap()])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        out.contains("line 5: study.sed: unknown field 'sed'"),
        "{out}"
    );
    assert!(out.contains("did you mean 'seed'"), "{out}");
    assert!(
        out.contains("line 12: scene.s.cout: unknown field 'cout'"),
        "{out}"
    );
    assert!(out.contains("did you mean 'count'"), "{out}");
    assert!(out.contains("sweep[1].nmae"), "{out}");
    let good = dir.join("good.toml");
    std::fs::write(&good, study_text(0.0)).unwrap();
    let o = Command::new(BIN)
        .args(["config", "check", good.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(o.status.success());
    assert!(String::from_utf8_lossy(&o.stdout).contains("ok (study \"it\", 18 cases: 18 forward)"));
    // the study command refuses the bad file with the same messages
    let o = study(&[
        bad.to_str().unwrap(),
        "--out",
        dir.join("x").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("study.sed"));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn schema_and_docs_document_every_field() {
    let o = Command::new(BIN)
        .args(["config", "schema"])
        .output()
        .unwrap();
    assert!(o.status.success());
    let schema = String::from_utf8_lossy(&o.stdout);
    let help = Command::new(BIN)
        .args(["config", "--help"])
        .output()
        .unwrap();
    let help = String::from_utf8_lossy(&help.stdout);
    assert!(help.contains("study.seed [0]"), "{help}");
    assert!(help.contains("scene.s.count [32]"), "{help}");
    let docs =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/config.md")).unwrap();
    assert!(
        docs.contains(schema.as_ref()),
        "docs/config.md is out of date: append the output of `springmass config schema`"
    );
    for f in springmass::study::config::STUDY_FIELDS {
        assert!(schema.contains(&format!("`{}`", f.path)), "{}", f.path);
        assert!(
            docs.contains(&format!("`{}`", f.path)),
            "docs/config.md lacks {}",
            f.path
        );
    }
    for k in springmass::study::kinds::ALL {
        for f in k.schema() {
            let p = format!("`scene.{}`", f.path);
            assert!(schema.contains(&p), "{p}");
            assert!(docs.contains(&p), "docs/config.md lacks {p}");
        }
    }
}

const GOOD: &str = r#"[study]
name = "fuzz"
kind = "forward"
seed = 3
[scene]
chain = { n = 6, defects = [ { kind = "mass", at = 2, m = 3.0 } ] }
random_defects = { count = 1 }
s = { count = 3, sigma = 0.1 }
timing = { min_seconds = 0.0 }
[[sweep]]
path = "chain.n"
values = [6, 9]
[[sweep]]
path = "chain.defects[0].m"
range = { from = 0.5, to = 4.0, count = 3, spacing = "log" }
[report]
max_case_rows = 10
[[report.plot]]
x = "chain.n"
y = "max_rel_diff"
"#;

/// Tables of GOOD with a known field list, for inserting unknown fields.
const TABLE_LINES: &[(&str, &str)] = &[
    ("[study]", "study"),
    ("[scene]", "scene"),
    ("[report]", "report"),
    ("[[report.plot]]", "report.plot[0]"),
];

proptest! {
    #![proptest_config(ProptestConfig { cases: 160, ..ProptestConfig::default() })]

    #[test]
    fn random_text_never_panics(text in "\\PC{0,300}") {
        let _ = check(&text);
        let _ = Study::from_text(&text, "fuzz");
    }

    #[test]
    fn mutated_files_never_panic(ops in proptest::collection::vec((0usize..2000, 0u8..3, any::<u8>()), 1..6)) {
        let mut bytes = GOOD.as_bytes().to_vec();
        for (pos, op, b) in ops {
            let p = pos % (bytes.len() + 1);
            match op {
                0 if p < bytes.len() => { bytes.remove(p); }
                1 => bytes.insert(p, b),
                _ if p < bytes.len() => bytes[p] = b,
                _ => {}
            }
        }
        let text = String::from_utf8_lossy(&bytes).into_owned();
        let problems = check(&text);
        let study = Study::from_text(&text, "fuzz");
        // the two agree on whether the file is good
        prop_assert_eq!(problems.is_empty(), study.is_ok(), "{:?}", problems);
    }

    #[test]
    fn unknown_fields_are_named(table in 0usize..4, name in "[a-z][a-z_]{2,8}") {
        let (header, path) = TABLE_LINES[table];
        let known = ["name", "kind", "seed", "description", "repeats", "timings", "chain",
            "random_defects", "s", "observe", "timing", "max_case_rows", "table", "plot",
            "x", "y", "file", "title", "series", "aggregate", "logx", "logy"];
        prop_assume!(!known.contains(&name.as_str()));
        let text = GOOD.replacen(header, &format!("{header}\n{name} = 1"), 1);
        let problems = check(&text);
        let want = format!("{path}.{name}");
        prop_assert!(problems.iter().any(|p| p.path == want && p.message.contains(&name) && p.line.is_some()),
            "{:?}", problems);
        prop_assert!(Study::from_text(&text, "fuzz").unwrap_err().to_string().contains(&want));
    }

    #[test]
    fn misspelled_sweep_paths_are_named(name in "[a-z]{2,6}") {
        prop_assume!(!["n", "k", "d", "gamma", "mass", "defects"].contains(&name.as_str()));
        let text = GOOD.replace("path = \"chain.n\"", &format!("path = \"chain.{name}\""));
        let problems = check(&text);
        prop_assert!(problems.iter().any(|p| p.path == format!("scene.chain.{name}")), "{:?}", problems);
    }
}

/// Every study and scene shipped in `configs/` passes `springmass config
/// check` (the checks of the study engine and of every kind's scene).
#[test]
fn every_shipped_study_and_scene_checks() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("configs");
    let mut seen = 0;
    for dir in ["studies", "scenes"] {
        for entry in std::fs::read_dir(root.join(dir)).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "toml") {
                let text = std::fs::read_to_string(&path).unwrap();
                let (_, problems) = springmass::study::check::check_file(&text);
                assert!(problems.is_empty(), "{}: {problems:?}", path.display());
                seen += 1;
            }
        }
    }
    assert!(seen >= 20, "{seen} files");
}
