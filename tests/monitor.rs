//! `springmass monitor` end to end (issue 29, monitoring): records made by
//! an independent generator (the exact time-domain simulation of
//! `springmass simulate`, not the fit's model path), a common stiffness
//! drift of 0.5% over the whole run, one spring weakened from one record on.
//! The change must be flagged within 5 records, the records before it
//! flagged no more often than the stated false-alarm rate allows, and the
//! drift reported as the common factor, not as a defect.

use std::path::{Path, PathBuf};
use std::process::Command;

fn springmass(args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_springmass"))
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "springmass {}: {}",
        args.join(" "),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn temp_dir(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("springmass-monitor-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The run: `records` records after the baseline, stiffness drift 0.5% over
/// the run, spring `SPRING` weakened by `WEAKER` from record `start` on.
struct Run {
    records: usize,
    start: usize,
    /// Reference records fitted for the baseline (at record 0's state).
    refs: usize,
}

const N: &str = "4";
const SPRING: usize = 2;
const WEAKER: f64 = 0.97;
const DRIFT: f64 = 0.005;

impl Run {
    /// Every spring's stiffness at record `r` (0: the baseline).
    fn k(&self, r: usize) -> f64 {
        1.0 + DRIFT * r as f64 / self.records as f64
    }

    /// Record `r` (simulated, 1% noise, seed `r`) with its time stamp; the
    /// file names do not sort in time order, the `# time:` lines do.
    fn write_record(&self, dir: &Path, r: usize, seed: usize) -> PathBuf {
        let sim = dir.join("sim.csv");
        let k = format!("{}", self.k(r));
        let mut args = vec![
            "simulate", "--n", N, "--k", &k, "--d", "0.1", "--t-end", "60", "--dt", "0.1",
            "--noise", "rel:0.01",
        ];
        let seed = format!("{seed}");
        let defect = format!("spring:{SPRING}:{}", WEAKER * self.k(r));
        args.extend(["--seed", &seed]);
        if r >= self.start {
            args.extend(["--defect", &defect]);
        }
        args.extend(["--out", sim.to_str().unwrap()]);
        springmass(&args);
        let body = std::fs::read_to_string(&sim).unwrap();
        let path = dir.join(format!("rec-{}.csv", (r * 7919) % 10007));
        std::fs::write(&path, format!("# time: {r}\n{body}")).unwrap();
        path
    }

    /// Generate, fit the baseline, monitor; the table's rows.
    fn monitor(&self, tag: &str) -> Vec<csv::StringRecord> {
        let dir = temp_dir(tag);
        let mut args: Vec<String> = vec!["monitor".into(), "--n".into(), N.into()];
        for i in 0..self.refs {
            let base = self.write_record(&dir, 0, 500 + i);
            let base_json = dir.join(format!("base-{i}.json"));
            let data = base.display().to_string();
            let fit = [
                "fit",
                "--data",
                &data,
                "--n",
                N,
                "--profile",
                "springs",
                "--json",
            ];
            std::fs::write(&base_json, springmass(&fit)).unwrap();
            std::fs::remove_file(&base).unwrap();
            args.extend(["--baseline".into(), base_json.display().to_string()]);
        }
        let recs = dir.join("records");
        std::fs::create_dir_all(&recs).unwrap();
        for r in 1..=self.records {
            let p = self.write_record(&dir, r, 1000 + r);
            std::fs::rename(&p, recs.join(p.file_name().unwrap())).unwrap();
        }
        let table = dir.join("trend.csv");
        let svg = dir.join("trend.svg");
        args.push(recs.display().to_string());
        args.extend(["--out".into(), table.display().to_string()]);
        args.extend(["--plot".into(), svg.display().to_string()]);
        let args: Vec<&str> = args.iter().map(|s| s.as_str()).collect();
        springmass(&args);
        assert!(std::fs::metadata(&svg).unwrap().len() > 1000);
        let mut rd = csv::Reader::from_path(&table).unwrap();
        let rows: Vec<_> = rd.records().map(|r| r.unwrap()).collect();
        let _ = std::fs::remove_dir_all(&dir);
        rows
    }

    /// The acceptance checks on the table (columns: time, record, status,
    /// changed, common, common_se, ...).
    fn check(&self, rows: &[csv::StringRecord], max_false: usize) {
        assert_eq!(rows.len(), self.records);
        let f = |r: &csv::StringRecord, i: usize| r[i].parse::<f64>().unwrap();
        for (i, row) in rows.iter().enumerate() {
            // in time order
            assert_eq!(row[0].parse::<usize>().unwrap(), i + 1);
            assert!(!row[2].starts_with("failed"), "{row:?}");
            // the drift is the common factor, within 4 SE, before and after
            let (c, se) = (f(row, 4), f(row, 5));
            assert!(
                (c - self.k(i + 1)).abs() < 4.0 * se,
                "record {}: common {c} +- {se}, truth {}",
                i + 1,
                self.k(i + 1)
            );
        }
        let flagged = |r: &csv::StringRecord| &r[2] == "changed";
        let before = rows[..self.start - 1].iter().filter(|r| flagged(r)).count();
        assert!(
            before <= max_false,
            "{before} false alarms before record {}",
            self.start
        );
        let first = (self.start - 1..rows.len())
            .find(|&i| flagged(&rows[i]))
            .expect("the change is never flagged");
        assert!(first < self.start - 1 + 5, "first flagged at {}", first + 1);
        let after = rows[self.start - 1..].iter().filter(|r| flagged(r)).count();
        eprintln!(
            "{} records: {before} false alarms before record {}, first flagged {}, {after} of {} flagged from it on",
            self.records,
            self.start,
            first + 1,
            self.records + 1 - self.start
        );
        for row in rows[self.start - 1..].iter().filter(|r| flagged(r)) {
            assert_eq!(
                row[3].split(';').next().unwrap(),
                format!("spring {SPRING}"),
                "{row:?}"
            );
        }
    }
}

/// `springmass ARGS`: exit code and stderr.
fn fails(args: &[&str]) -> (i32, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_springmass"))
        .args(args)
        .output()
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn bad_input_is_named_and_a_bad_record_is_a_row() {
    let dir = temp_dir("bad");
    let run = Run {
        records: 2,
        start: 3,
        refs: 1,
    };
    let rec = run.write_record(&dir, 0, 7);
    let base = dir.join("base.json");
    let fit = [
        "fit",
        "--data",
        rec.to_str().unwrap(),
        "--n",
        N,
        "--profile",
        "springs",
        "--json",
    ];
    std::fs::write(&base, springmass(&fit)).unwrap();
    let (b, r) = (base.to_str().unwrap(), rec.to_str().unwrap());
    let (code, err) = fails(&["monitor", "--baseline", b, "--n", N, "--alarm-rate", "0", r]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("alarm_rate"), "{err}");
    let (code, err) = fails(&["monitor", "--baseline", r, "--n", N, r]);
    assert_ne!(code, 0);
    assert!(err.contains("baseline"), "{err}");
    // the baseline's fit says what its sensor measured: records of another
    // kind are refused before any fit (a displacement baseline here)
    let kinds = std::fs::read_to_string(&base).unwrap();
    assert!(
        kinds.contains("\"observe_kind\": \"displacement\""),
        "{kinds}"
    );
    let (code, err) = fails(&[
        "monitor",
        "--baseline",
        b,
        "--n",
        N,
        "--observe-kind",
        "acceleration",
        r,
    ]);
    assert_ne!(code, 0);
    assert!(err.contains("observe_kind"), "{err}");
    let missing = dir.join("nope.csv");
    let (code, err) = fails(&[
        "monitor",
        "--baseline",
        b,
        "--n",
        N,
        missing.to_str().unwrap(),
    ]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("records"), "{err}");
    // a record too short for the profile: its row says failed, the run goes on
    let short = dir.join("short.csv");
    std::fs::write(&short, "t,x1\n0,0\n0.1,0.01\n0.2,0.02\n").unwrap();
    let table = dir.join("t.csv");
    let out = springmass(&[
        "monitor",
        "--baseline",
        b,
        "--n",
        N,
        r,
        short.to_str().unwrap(),
        "--out",
        table.to_str().unwrap(),
    ]);
    assert!(out.contains("1 failed"), "{out}");
    let text = std::fs::read_to_string(&table).unwrap();
    assert!(text.contains("failed: "), "{text}");
    // records of another chain than the baseline's: each row says why, the
    // table is still written (it failed to write after every fit), and a
    // run with no record tested exits with an error
    let other_n = format!("monitor --baseline {b} --n 5 {r} --out {}", table.display());
    let (code, err) = fails(&other_n.split(' ').collect::<Vec<_>>());
    assert_ne!(code, 0, "{err}");
    assert!(err.contains("every record failed"), "{err}");
    let text = std::fs::read_to_string(&table).unwrap();
    assert!(text.contains("the same --n"), "{text}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_weakened_spring_is_flagged_through_a_common_drift() {
    // two reference records averaged for the baseline
    let run = Run {
        records: 24,
        start: 16,
        refs: 2,
    };
    let rows = run.monitor("small");
    // at 0.001 per record, 15 null records: one false alarm has
    // probability 1.5%, two 0.01%
    run.check(&rows, 1);
}

/// The acceptance run of issue 29: 200 records, the change at 120 (about a
/// minute of fits on two cores with an optimized build).
#[test]
#[ignore = "200 records: run with --ignored"]
fn two_hundred_records_change_at_120() {
    let run = Run {
        records: 200,
        start: 120,
        refs: 1,
    };
    let rows = run.monitor("200");
    // 119 null records at 0.001: expected 0.12 false alarms; two or more
    // has probability 0.6%
    run.check(&rows, 1);
}

/// More damping than the model's is not a spring change: the springs'
/// profile of such a record moves every spring to take up the misfit, and
/// its time residual stays coloured. It is now `model-mismatch` (it was
/// `converged`, and monitoring named springs 0 to 2 as changed); records of
/// the model's damping stay `converged`, and so does an exact record.
#[test]
fn a_profile_that_cannot_explain_a_damping_change_says_so() {
    let dir = temp_dir("damping");
    let sim = dir.join("sim.csv");
    let sim = sim.to_str().unwrap();
    let status = |d: &str, noise: &str| {
        let run = |line: String| springmass(&line.split(' ').collect::<Vec<_>>());
        run(format!(
            "simulate --n 6 --d {d} --t-end 80 --dt 0.1 {noise} --out {sim}"
        ));
        let json = run(format!(
            "fit --data {sim} --n 6 --d 0.1 --profile springs --json"
        ));
        let v: serde_json::Value = serde_json::from_str(&json).unwrap();
        v["status"].as_str().unwrap().to_string()
    };
    for seed in ["1", "2"] {
        let noise = format!("--noise rel:0.01 --seed {seed}");
        assert_eq!(status("0.13", &noise), "model-mismatch", "seed {seed}");
        assert_eq!(status("0.1", &noise), "converged", "seed {seed}");
    }
    // an exact record: its residual is rounding, not a misfit
    let exact = "--defect spring:3:0.9";
    assert_eq!(status("0.1", exact), "converged");
    let _ = std::fs::remove_dir_all(&dir);
}
