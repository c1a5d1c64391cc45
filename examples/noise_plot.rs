//! Redraw the README's success-against-noise figure from its table,
//! `docs/noise-success.csv` (written by the command-line study that
//! `springmass noise-study misfits` replaces), as
//! small multiples: one panel per system, one line per misfit, success rate
//! on [0, 1] with its 95% Wilson interval against the noise level on a log
//! axis, the misfits side by side (lines at 1 would hide each other).
//!
//! ```sh
//! cargo run --example noise_plot            # writes out/examples/noise-success.svg
//! cargo run --example noise_plot -- docs/noise-success.csv docs/img/noise-success.svg
//! ```

use springmass::plot::{Line, LinePlot};
use springmass::study::report::wilson_interval;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let input = args
        .first()
        .map_or("docs/noise-success.csv", |s| s.as_str());
    let output = args
        .get(1)
        .map_or("out/examples/noise-success.svg", |s| s.as_str());
    let text = std::fs::read_to_string(input).map_err(|e| format!("{input}: {e}"))?;
    // system,misfit,level,runs,successes,positions_ok
    type Cell = (String, String, f64, f64, (f64, f64));
    let mut cells: Vec<Cell> = Vec::new();
    for (i, line) in text.lines().enumerate().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        if f.len() != 6 {
            return Err(format!("{input} line {}: expected 6 fields", i + 1).into());
        }
        let (runs, ok): (f64, f64) = (f[3].parse()?, f[4].parse()?);
        let ci = wilson_interval(ok, runs);
        cells.push((f[0].into(), f[1].into(), f[2].parse()?, ok / runs, ci));
    }
    let order = |pick: fn(&Cell) -> &String| {
        let mut v: Vec<String> = Vec::new();
        for c in &cells {
            if !v.contains(pick(c)) {
                v.push(pick(c).clone());
            }
        }
        v
    };
    let (systems, misfits) = (order(|c| &c.0), order(|c| &c.1));
    let runs = text
        .lines()
        .nth(1)
        .and_then(|l| l.split(',').nth(3))
        .unwrap_or("?");
    let mut plot = LinePlot::new(
        format!(
            "Positions exact and masses within 5% ({runs} seeds per point; bars: 95% Wilson interval)"
        ),
        "noise level (relative to max |x_1|)",
        "fraction recovered",
    )
    .log_x(true)
    .rate();
    for s in &systems {
        for (i, m) in misfits.iter().enumerate() {
            // side by side: 0.03 decades apart
            let shift = 10f64.powf(0.03 * (i as f64 - (misfits.len() as f64 - 1.0) / 2.0));
            let of: Vec<&Cell> = cells.iter().filter(|c| &c.0 == s && &c.1 == m).collect();
            let pts = of.iter().map(|c| (c.2 * shift, c.3)).collect();
            let bars = of.iter().map(|c| c.4).collect();
            plot = plot.line(Line::new(m.clone(), pts).errors(bars).panel(s.clone()));
        }
    }
    if let Some(dir) = std::path::Path::new(output).parent() {
        std::fs::create_dir_all(dir)?;
    }
    plot.write_svg(output)?;
    println!(
        "wrote {output}: {} systems x {} misfits",
        systems.len(),
        misfits.len()
    );
    Ok(())
}
