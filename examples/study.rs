//! A study from code: a small sweep written as TOML text, run on all cores
//! into `out/examples/study/` (results.jsonl, summary.csv, report.md and the
//! plot), resumable like `springmass study`.
//!
//! ```sh
//! cargo run --release --example study
//! ```

use springmass::study::run::{run, RunOptions};
use springmass::study::Study;

const STUDY: &str = r#"
[study]
name = "example"
kind = "forward"
description = "Woodbury against the O(n) reference, three chain lengths, one and two random defects."
seed = 1
timings = false

[scene]
chain = { n = 10, d = 0.1 }
random_defects = { count = 1, kind = "mass", min = 0.5, max = 5.0 }
s = { from = 0.01, to = 10.0, count = 16, spacing = "log" }

[[sweep]]
path = "chain.n"
name = "n"
values = [10, 100, 1000]

[[sweep]]
path = "random_defects.count"
name = "k"
values = [1, 2]

[[report.plot]]
file = "accuracy.svg"
title = "max relative difference, Woodbury vs O(n) reference"
x = "n"
y = "max_rel_diff"
series = "k"
logx = true
logy = true
"#;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let study = Study::from_text(STUDY, "examples/study.rs")?;
    let mut opts = RunOptions::new("out/examples/study");
    opts.progress = false;
    let summary = run(&study, &opts)?;
    let report = summary
        .report
        .as_ref()
        .map_or("none".to_string(), |p| p.display().to_string());
    println!(
        "{} cases ({} run now, {} resumed, {} failed); report: {report}",
        summary.total, summary.ran, summary.resumed, summary.failed
    );
    Ok(())
}
