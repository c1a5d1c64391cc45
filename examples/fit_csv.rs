//! Fit two mass defects to a measured series read from a CSV file.
//!
//! Makes its own "measurement" first: `x_1(t)` of Table 1's System 1
//! (n = 5, defects (2, 3.0) and (4, 0.5), d = 0.1) on [0, 100], step 0.1,
//! with seeded white noise of 0.1% of its largest value, written to
//! `out/examples/fit_csv-x1.csv`. Then reads the file back and fits both
//! positions and masses; the fit knows n = 5, d = 0.1 and that there are two
//! defects, not the noise level (it estimates it).
//!
//! ```sh
//! cargo run --release --example fit_csv
//! ```

use springmass::detect::data::observations::{Observations, Series};
use springmass::detect::fit::{fit, DefectCount, FitOptions, Model};
use springmass::noise::{add_noise, NoiseLevel};
use springmass::series::TimeSeries;
use springmass::time::simulate::{simulate, SimOptions};
use springmass::{Chain, Defect};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // 1. the measurement (in practice: your sensor's CSV with columns t, x1)
    let truth = Chain::paper(5)?
        .with_defect(Defect::Mass { at: 2, m: 3.0 })?
        .with_defect(Defect::Mass { at: 4, m: 0.5 })?;
    let run = simulate(&truth, &SimOptions::new(100.0, 0.1).with_observe(vec![1]))?;
    let clean = run.x(1).ok_or("no x_1 in the simulation")?;
    let (x1, _sigma) = add_noise(clean, NoiseLevel::RelativeMax(1e-3), 7)?;
    let csv = "out/examples/fit_csv-x1.csv";
    TimeSeries::new(run.t.clone(), vec![("x1".into(), x1)])?.write_csv(csv)?;

    // 2. read it back and fit: what we know is the chain, not the defects
    let obs = Observations::Series(Series::from_csv(csv, Some("x1"), None)?);
    let model = Model::new(5)?.with_d(0.1)?;
    let opts = FitOptions {
        defects: DefectCount::Exactly(2),
        ..FitOptions::default()
    };
    let report = fit(&obs, &model, &opts)?;
    println!("read {csv}");
    for d in &report.defects {
        println!(
            "found {} at {}: {:.4} +- {:.4}",
            d.kind, d.at, d.value, d.se
        );
    }
    let truth_text: Vec<String> = truth
        .defects()
        .iter()
        .map(|d| format!("{} at {}: {}", d.kind(), d.at(), d.value()))
        .collect();
    println!("truth: {}", truth_text.join(", "));
    println!(
        "noise sigma {:.2e} (estimated: {}), status {}",
        report.noise_sigma,
        report.noise_estimated,
        report.status.name()
    );
    Ok(())
}
