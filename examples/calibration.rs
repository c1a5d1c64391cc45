//! Read a calibration study's results (`configs/studies/calibration.toml`)
//! and report how well the fit's uncertainty holds: the coverage of its
//! intervals at each level (with a 95% Wilson interval of the rate), and
//! the reliability of the probability it gives its answer (binned: the mean
//! stated probability against the share of answers with the right
//! positions), as a table and a reliability diagram.
//!
//! ```sh
//! springmass study configs/studies/calibration.toml --out out/calibration
//! cargo run --release --example calibration -- out/calibration
//! ```
//!
//! Writes `reliability.svg` and `calibration.md` into the study's folder.

use springmass::plot::{Line, LinePlot};
use springmass::study::records::Record;
use springmass::study::report::wilson_interval;
use std::fmt::Write as _;

/// Bins of the stated probability.
const EDGES: [f64; 8] = [0.0, 0.5, 0.7, 0.8, 0.9, 0.99, 0.999, 1.0 + 1e-12];

/// Cases of a bin below which its rate is not judged.
const MIN_CASES: usize = 30;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "out/calibration".into());
    let path = std::path::Path::new(&dir).join("results.jsonl");
    let text = std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut records = Vec::new();
    for (i, line) in text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
    {
        let r: Record = serde_json::from_str(line)
            .map_err(|e| format!("{} line {}: {e}", path.display(), i + 1))?;
        if r.status == "ok" {
            records.push(r);
        }
    }
    if records.is_empty() {
        return Err(format!("{}: no finished case", path.display()).into());
    }
    let mut md = String::new();
    writeln!(
        md,
        "# Calibration of {} cases ({})\n",
        records.len(),
        path.display()
    )?;
    coverage(&records, &mut md)?;
    let svg = std::path::Path::new(&dir).join("reliability.svg");
    reliability(&records, &mut md, &svg)?;
    let out = std::path::Path::new(&dir).join("calibration.md");
    std::fs::write(&out, &md)?;
    print!("{md}");
    println!("\nwrote {} and {}", out.display(), svg.display());
    Ok(())
}

fn metric(r: &Record, name: &str) -> f64 {
    r.metrics
        .get(name)
        .and_then(serde_json::Value::as_f64)
        .unwrap_or(f64::NAN)
}

/// `none`, or the case's deviation.
fn deviation(r: &Record) -> String {
    r.params
        .iter()
        .find(|p| p.column == "deviation")
        .map_or("none".into(), |p| p.label.clone())
}

/// Coverage per (level, noise level, deviation).
fn coverage(records: &[Record], md: &mut String) -> std::fmt::Result {
    writeln!(md, "## Interval coverage\n")?;
    writeln!(
        md,
        "| interval level | record | values | inside | coverage | 95% interval of the rate |\n|---|---|---|---|---|---|"
    )?;
    let mut groups: Vec<(f64, String)> = Vec::new();
    for r in records {
        let key = (metric(r, "interval_level"), deviation(r));
        if !groups.contains(&key) {
            groups.push(key);
        }
    }
    groups.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    for (level, dev) in groups {
        let (mut n, mut k) = (0.0, 0.0);
        for r in records
            .iter()
            .filter(|r| metric(r, "interval_level") == level && deviation(r) == dev)
        {
            n += metric(r, "values");
            k += metric(r, "in_interval");
        }
        let (lo, hi) = wilson_interval(k, n);
        writeln!(
            md,
            "| {level} | {dev} | {n} | {k} | {:.3} | [{lo:.3}, {hi:.3}] |",
            k / n.max(1.0)
        )?;
    }
    Ok(())
}

/// The reliability table and diagram of the answer's probability.
fn reliability(
    records: &[Record],
    md: &mut String,
    svg: &std::path::Path,
) -> Result<(), Box<dyn std::error::Error>> {
    writeln!(md, "\n## Reliability of the answer's probability\n")?;
    writeln!(
        md,
        "| stated | cases | mean stated | right | share right | 95% interval | judged |\n|---|---|---|---|---|---|---|"
    )?;
    let mut points = Vec::new();
    let mut bars = Vec::new();
    for w in EDGES.windows(2) {
        let cases: Vec<&Record> = records
            .iter()
            .filter(|r| {
                let p = metric(r, "answer_p");
                p >= w[0] && p < w[1]
            })
            .collect();
        if cases.is_empty() {
            continue;
        }
        let n = cases.len() as f64;
        let stated = cases.iter().map(|r| metric(r, "answer_p")).sum::<f64>() / n;
        let right = cases
            .iter()
            .filter(|r| metric(r, "positions_ok") == 1.0)
            .count() as f64;
        let (lo, hi) = wilson_interval(right, n);
        let judged = if cases.len() >= MIN_CASES {
            if (right / n - stated).abs() <= 0.1 {
                "within 0.1"
            } else {
                "OFF by more than 0.1"
            }
        } else {
            "too few cases"
        };
        writeln!(
            md,
            "| [{}, {}) | {} | {stated:.3} | {right} | {:.3} | [{lo:.3}, {hi:.3}] | {judged} |",
            w[0],
            w[1].min(1.0),
            cases.len(),
            right / n
        )?;
        points.push((stated, right / n));
        bars.push((lo, hi));
    }
    LinePlot::new(
        "reliability of the answer's probability (binned; 95% Wilson intervals)",
        "probability the fit states for its answer (bin mean)",
        "share of answers with the right positions",
    )
    .line(Line::new("perfectly calibrated", vec![(0.0, 0.0), (1.0, 1.0)]).dashed())
    .line(Line::new("fits", points).markers().errors(bars))
    .y_range(0.0, 1.02)
    .size(720, 560)
    .write_svg(svg)?;
    Ok(())
}
