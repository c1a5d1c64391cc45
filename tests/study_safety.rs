//! Regression tests of the study engine's hardening (issues 17, 12, 13):
//! `config check` in one pass with plain messages, fit scenes recognised,
//! skipped apart from failed, no duplicate column, safe output folders,
//! validated thread counts, `--shard auto` from Slurm, and seeds that follow
//! the values of the swept fields (a subset of a sweep reproduces its cells).

use springmass::study::check::{check, check_file, FileKind};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

const BIN: &str = env!("CARGO_BIN_EXE_springmass");

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("springmass-safety-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn run(args: &[&str], envs: &[(&str, &str)]) -> Output {
    let mut c = Command::new(BIN);
    c.args(args).stdin(Stdio::null());
    for v in springmass::study::shard::SLURM_VARS {
        c.env_remove(v);
    }
    for (k, v) in envs {
        c.env(k, v);
    }
    c.output().unwrap()
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// A forward study of 4 cheap cases; the axis `chain.n` is named `n`, like
/// the forward kind's metric `n`.
const SMALL: &str = r#"[study]
name = "small"
kind = "forward"
seed = 3
timings = false

[scene]
chain = { n = 5, d = 0.1 }
s = { from = 0.1, to = 1.0, count = 3 }
timing = { min_seconds = 0.0 }

[[sweep]]
path = "chain.n"
name = "n"
values = [4, 6, 8, 10]
"#;

#[test]
fn config_check_reports_every_table_in_one_pass_with_plain_messages() {
    let bad = r#"[study]
name = "bad"
kind = "forward"
seed = -1

[scene]
chain = { n = 10, nn = 3 }

[[sweep]]
path = "chain.nq"
values = [1, 2]

[[sweep]]
path = "chain.n"
values = [-3, 4]

[[report.plot]]
x = "chain.n"
y = "no_such_metric"
"#;
    let p = check(bad);
    let find = |path: &str| {
        p.iter()
            .find(|x| x.path == path)
            .unwrap_or_else(|| panic!("{path} missing from {p:#?}"))
    };
    // [study]: the field path, the line, a plain message
    let seed = find("study.seed");
    assert_eq!(seed.line, Some(4));
    assert_eq!(seed.message, "seed must be an integer >= 0, got -1");
    // [scene]: an unknown field with a suggestion
    let nn = find("scene.chain.nn");
    assert_eq!(nn.line, Some(7));
    assert_eq!(nn.message, "unknown field 'nn' (did you mean 'n'?)");
    // [[sweep]]: a bad path at the sweep's own line, not the scene's
    let nq = find("scene.chain.nq");
    assert_eq!(nq.line, Some(10), "{nq:?}");
    assert!(nq.message.starts_with("unknown field 'nq'"), "{nq:?}");
    // a case-level problem of a swept field, at the sweep's values
    let n = find("scene.chain.n");
    assert_eq!(n.line, Some(15), "{n:?}");
    assert!(
        n.message.starts_with("n must be an integer >= 1, got -3"),
        "{n:?}"
    );
    assert!(n.message.contains("2 of 4 cases"), "{n:?}");
    // [report]: checked too, in the same pass
    let y = find("report.plot[0].y");
    assert_eq!(y.line, Some(19));
    // nothing else (no follow-on "missing field" for the removed n)
    assert_eq!(p.len(), 5, "{p:#?}");
    // in file order
    let lines: Vec<usize> = p.iter().map(|x| x.line.unwrap()).collect();
    let mut sorted = lines.clone();
    sorted.sort();
    assert_eq!(lines, sorted);
}

#[test]
fn config_check_reports_type_errors_even_when_invalid_cases_skip() {
    let f = r#"[study]
name = "t"
kind = "fit"
invalid_cases = "skip"
[scene]
chain = { n = 10, defects = [ { kind = "mass", at = 3, m = 2.0 } ] }
unknowns = { defects = [ { m = "abc" } ] }
"#;
    let p = check(f);
    assert_eq!(p.len(), 1, "{p:#?}");
    assert_eq!(p[0].path, "scene.unknowns.defects[0].m");
    assert_eq!(p[0].line, Some(7));
    assert_eq!(p[0].message, "m must be a float, got \"abc\"");
    // a range problem is what `skip` skips: no problem then
    let f = f.replace("{ m = \"abc\" }", "{ m = 2.0 }").replace(
        "[scene]",
        "[[sweep]]\npath = \"chain.n\"\nvalues = [2, 10]\n[scene]",
    );
    assert_eq!(check(&f), vec![]);
}

#[test]
fn config_check_says_which_kind_of_file_and_checks_fit_scenes() {
    let dir = tmp("kind");
    let root = env!("CARGO_MANIFEST_DIR");
    // a shipped fit scene
    let scene = Path::new(root).join("configs/scenes/table1-system3.toml");
    assert!(scene.is_file(), "missing {}", scene.display());
    let o = run(&["config", "check", scene.to_str().unwrap()], &[]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(
        text(&o).contains("this is a fit scene; run `springmass fit --scene"),
        "{}",
        text(&o)
    );
    // a broken fit scene: every problem, with paths and lines
    let bad = "[chain]\nn = 5\nnn = 3\n[data]\nnoise = -1.0\n";
    let (kind, p) = check_file(bad);
    assert_eq!(kind, FileKind::FitScene);
    let paths: Vec<&str> = p.iter().map(|x| x.path.as_str()).collect();
    assert!(paths.contains(&"chain.nn"), "{p:#?}");
    assert!(paths.contains(&"data.noise"), "{p:#?}");
    let nn = p.iter().find(|x| x.path == "chain.nn").unwrap();
    assert_eq!(nn.line, Some(3));
    assert_eq!(nn.message, "unknown field 'nn' (did you mean 'n'?)");
    let file = dir.join("scene.toml");
    std::fs::write(&file, bad).unwrap();
    let o = run(&["config", "check", file.to_str().unwrap()], &[]);
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).contains("line 3: chain.nn"), "{}", text(&o));
    assert!(text(&o).contains("this is a fit scene"), "{}", text(&o));
    // a study file says so
    let study = dir.join("study.toml");
    std::fs::write(&study, SMALL).unwrap();
    let (kind, p) = check_file(SMALL);
    assert_eq!((kind, p), (FileKind::Study, vec![]));
    let o = run(&["config", "check", study.to_str().unwrap()], &[]);
    assert!(o.status.success(), "{}", text(&o));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn skipped_cases_are_counted_alike_on_the_console_and_in_the_report() {
    let dir = tmp("skip");
    let f = dir.join("skip.toml");
    // n = 2 puts the defect at 3 off the chain: 2 of 4 cases are skipped
    let study = SMALL
        .replace(
            "timings = false",
            "timings = false\ninvalid_cases = \"skip\"",
        )
        .replace(
            "chain = { n = 5, d = 0.1 }",
            "chain = { n = 5, d = 0.1, defects = [ { kind = \"mass\", at = 3, m = 2.0 } ] }",
        )
        .replace("values = [4, 6, 8, 10]", "values = [1, 2, 8, 10]");
    std::fs::write(&f, study).unwrap();
    let out = dir.join("out");
    let o = run(
        &[
            "study",
            f.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--quiet",
        ],
        &[],
    );
    assert!(o.status.success(), "{}", text(&o));
    assert!(
        text(&o).contains("0 failed, 2 skipped"),
        "console: {}",
        text(&o)
    );
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(md.contains("4 (2 ok, 0 failed, 2 skipped)"), "{md}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn summary_csv_has_no_duplicate_column() {
    let dir = tmp("dup");
    let f = dir.join("small.toml");
    std::fs::write(&f, SMALL).unwrap();
    let out = dir.join("out");
    let o = run(
        &[
            "study",
            f.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--quiet",
        ],
        &[],
    );
    assert!(o.status.success(), "{}", text(&o));
    let csv = std::fs::read_to_string(out.join("summary.csv")).unwrap();
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    let mut unique = header.clone();
    unique.sort();
    unique.dedup();
    assert_eq!(unique.len(), header.len(), "{header:?}");
    assert!(
        header.contains(&"n") && header.contains(&"metric_n"),
        "{header:?}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn study_out_never_overwrites_results_it_did_not_write() {
    let dir = tmp("out");
    let f = dir.join("small.toml");
    std::fs::write(&f, SMALL).unwrap();
    // a folder holding someone else's results
    let foreign = dir.join("foreign");
    std::fs::create_dir_all(&foreign).unwrap();
    std::fs::write(foreign.join("results.jsonl"), "precious\n").unwrap();
    std::fs::write(foreign.join("summary.csv"), "a,b\n1,2\n").unwrap();
    let o = run(
        &[
            "study",
            f.to_str().unwrap(),
            "--out",
            foreign.to_str().unwrap(),
            "--quiet",
        ],
        &[],
    );
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    let msg = text(&o);
    assert!(msg.contains(foreign.to_str().unwrap()), "{msg}");
    assert!(msg.contains("choose another --out"), "{msg}");
    assert_eq!(
        std::fs::read_to_string(foreign.join("results.jsonl")).unwrap(),
        "precious\n"
    );
    assert_eq!(
        std::fs::read_to_string(foreign.join("summary.csv")).unwrap(),
        "a,b\n1,2\n"
    );
    assert!(!foreign.join("manifest.json").exists());
    // a file is not a folder
    let o = run(
        &[
            "study",
            f.to_str().unwrap(),
            "--out",
            f.to_str().unwrap(),
            "--quiet",
        ],
        &[],
    );
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    // an empty folder is fine, and so is our own folder (resume)
    let ours = dir.join("ours");
    std::fs::create_dir_all(&ours).unwrap();
    for _ in 0..2 {
        let o = run(
            &[
                "study",
                f.to_str().unwrap(),
                "--out",
                ours.to_str().unwrap(),
                "--quiet",
            ],
            &[],
        );
        assert!(o.status.success(), "{}", text(&o));
    }
    // another study's folder is refused (run and merge alike)
    let other = dir.join("other.toml");
    std::fs::write(&other, SMALL.replace("seed = 3", "seed = 4")).unwrap();
    let before = std::fs::read(ours.join("results.jsonl")).unwrap();
    let o = run(
        &[
            "study",
            other.to_str().unwrap(),
            "--out",
            ours.to_str().unwrap(),
            "--quiet",
        ],
        &[],
    );
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    let other_out = dir.join("other-out");
    let o = run(
        &[
            "study",
            other.to_str().unwrap(),
            "--out",
            other_out.to_str().unwrap(),
            "--quiet",
        ],
        &[],
    );
    assert!(o.status.success(), "{}", text(&o));
    let o = run(
        &[
            "study",
            "merge",
            other_out.to_str().unwrap(),
            "--out",
            ours.to_str().unwrap(),
        ],
        &[],
    );
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    let o = run(
        &[
            "study",
            "merge",
            other_out.to_str().unwrap(),
            "--out",
            foreign.to_str().unwrap(),
        ],
        &[],
    );
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert_eq!(std::fs::read(ours.join("results.jsonl")).unwrap(), before);
    assert_eq!(
        std::fs::read_to_string(foreign.join("results.jsonl")).unwrap(),
        "precious\n"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn thread_counts_are_checked_before_any_work() {
    let dir = tmp("threads");
    let f = dir.join("small.toml");
    std::fs::write(&f, SMALL).unwrap();
    for bad in ["0", "1025", "4294967296"] {
        let out = dir.join(format!("out-{bad}"));
        let o = run(
            &[
                "study",
                f.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
                "--threads",
                bad,
            ],
            &[],
        );
        assert_eq!(o.status.code(), Some(2), "{bad}: {}", text(&o));
        assert!(text(&o).contains("threads"), "{}", text(&o));
        assert!(!out.exists(), "{bad}: the output folder was created");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn shard_auto_reads_the_slurm_array_variables() {
    let dir = tmp("slurm");
    let f = dir.join("small.toml");
    std::fs::write(&f, SMALL).unwrap();
    let mut folders = Vec::new();
    // --array=0-1: tasks 0 and 1 of 2
    for id in ["0", "1"] {
        let out = dir.join(format!("task{id}"));
        let o = run(
            &[
                "study",
                f.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
                "--shard",
                "auto",
                "--quiet",
            ],
            &[
                ("SLURM_ARRAY_TASK_ID", id),
                ("SLURM_ARRAY_TASK_COUNT", "2"),
                ("SLURM_ARRAY_TASK_MIN", "0"),
            ],
        );
        assert!(o.status.success(), "{}", text(&o));
        let m = std::fs::read_to_string(out.join("manifest.json")).unwrap();
        let want = format!("\"shard\": \"{}/2\"", id.parse::<usize>().unwrap() + 1);
        assert!(m.contains(&want), "{m}");
        folders.push(out);
    }
    let merged = dir.join("merged");
    let o = run(
        &[
            "study",
            "merge",
            folders[0].to_str().unwrap(),
            folders[1].to_str().unwrap(),
            "--out",
            merged.to_str().unwrap(),
        ],
        &[],
    );
    assert!(o.status.success(), "{}", text(&o));
    let single = dir.join("single");
    let o = run(
        &[
            "study",
            f.to_str().unwrap(),
            "--out",
            single.to_str().unwrap(),
            "--quiet",
        ],
        &[],
    );
    assert!(o.status.success(), "{}", text(&o));
    assert_eq!(
        std::fs::read(merged.join("results.jsonl")).unwrap(),
        std::fs::read(single.join("results.jsonl")).unwrap()
    );
    // outside a job array, and with inconsistent variables: typed errors
    for (envs, want) in [
        (vec![], "SLURM_ARRAY_TASK_ID"),
        (vec![("SLURM_ARRAY_TASK_ID", "0")], "SLURM_ARRAY_TASK_COUNT"),
        (
            vec![
                ("SLURM_ARRAY_TASK_ID", "2"),
                ("SLURM_ARRAY_TASK_COUNT", "2"),
            ],
            "inconsistent",
        ),
        (
            vec![
                ("SLURM_ARRAY_TASK_ID", "x"),
                ("SLURM_ARRAY_TASK_COUNT", "2"),
            ],
            "SLURM_ARRAY_TASK_ID",
        ),
    ] {
        let out = dir.join("never");
        let o = run(
            &[
                "study",
                f.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
                "--shard",
                "auto",
            ],
            &envs,
        );
        assert_eq!(o.status.code(), Some(2), "{envs:?}: {}", text(&o));
        assert!(text(&o).contains(want), "{envs:?}: {}", text(&o));
        assert!(!out.exists());
    }
    // the docs show the job-array script and the merge step
    let doc = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/config.md"))
        .unwrap();
    assert!(
        doc.contains("sbatch --array=0-"),
        "docs/config.md: no job array"
    );
    assert!(
        doc.contains("--shard auto"),
        "docs/config.md: no --shard auto"
    );
    assert!(
        doc.contains("springmass study merge"),
        "docs/config.md: no merge"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A noisy fit study over noise levels `levels` (timings off).
fn noise_study(levels: &str) -> String {
    format!(
        r#"[study]
name = "levels"
kind = "fit"
seed = 11
timings = false
repeats = 2

[scene]
chain = {{ n = 5, d = 0.1, defects = [ {{ kind = "mass", at = 2, m = 3.0 }} ] }}
data = {{ source = "exact", noise = 0.0 }}
unknowns = {{ k = 1 }}
search = {{ method = "enumerate", parallel = false }}

[[sweep]]
path = "data.noise"
name = "level"
values = {levels}
"#
    )
}

/// The lines of a `results.jsonl` by their parameters and repeat, without
/// the case id (the position in the expansion).
fn records_by_cell(path: &Path) -> std::collections::BTreeMap<String, String> {
    let text = std::fs::read_to_string(path).unwrap();
    text.lines()
        .map(|l| {
            let mut v: serde_json::Value = serde_json::from_str(l).unwrap();
            let cell = format!("{} {}", v["params"], v["repeat"]);
            v.as_object_mut().unwrap().remove("id");
            (cell, serde_json::to_string(&v).unwrap())
        })
        .collect()
}

#[test]
fn a_subset_of_a_sweep_reproduces_the_full_sweeps_cells() {
    let dir = tmp("subset");
    let mut got = Vec::new();
    for (name, levels) in [("full", "[1e-4, 1e-3, 1e-2]"), ("sub", "[1e-3]")] {
        let f = dir.join(format!("{name}.toml"));
        std::fs::write(&f, noise_study(levels)).unwrap();
        let out = dir.join(name);
        let o = run(
            &[
                "study",
                f.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
                "--quiet",
            ],
            &[],
        );
        assert!(o.status.success(), "{}", text(&o));
        got.push(records_by_cell(&out.join("results.jsonl")));
    }
    let (full, sub) = (&got[0], &got[1]);
    assert_eq!(full.len(), 6);
    assert_eq!(sub.len(), 2);
    for (cell, line) in sub {
        // the same record, byte for byte (the id apart): same seed, same
        // noise draw, same fit
        assert_eq!(full.get(cell), Some(line), "{cell}");
    }
    // the seeds differ between cells (so equal records are no accident)
    let seeds: std::collections::BTreeSet<String> = full
        .values()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap()["seed"].to_string())
        .collect();
    assert_eq!(seeds.len(), 6);
    let _ = std::fs::remove_dir_all(&dir);
}
