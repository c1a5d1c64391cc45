//! Fit two mass defects to a measured series read from a CSV file.
//!
//! Makes its own "measurement" first: `x_1(t)` of Table 1's System 1
//! (n = 5, defects (2, 3.0) and (4, 0.5), d = 0.1) on [0, 300], step 0.05,
//! with seeded white noise of 1e-6 of its largest value, written to
//! `out/examples/fit_csv-x1.csv`. Then reads the file back and fits both
//! positions and masses with the paper's real-axis residual.
//!
//! ```sh
//! cargo run --release --example fit_csv
//! ```

use springmass::detect::{data::Data, fit::fit, scene::FitScene};
use springmass::noise::{add_noise, NoiseLevel};
use springmass::series::TimeSeries;
use springmass::time::simulate::{simulate, SimOptions};
use springmass::{Chain, Defect};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // 1. the measurement (in practice: your sensor's CSV with columns t, x1)
    let truth = Chain::paper(5)?
        .with_defect(Defect::Mass { at: 2, m: 3.0 })?
        .with_defect(Defect::Mass { at: 4, m: 0.5 })?;
    let run = simulate(&truth, &SimOptions::new(300.0, 0.05).with_observe(vec![1]))?;
    let clean = run.x(1).ok_or("no x_1 in the simulation")?;
    let (x1, sigma) = add_noise(clean, NoiseLevel::parse("rel:1e-6")?, 7)?;
    std::fs::create_dir_all("out/examples")?;
    let csv = "out/examples/fit_csv-x1.csv";
    TimeSeries::new(run.t.clone(), vec![("x1".into(), x1)])?.write_csv(csv)?;

    // 2. what we know: a 5-mass chain with d = 0.1 and two unknown defects
    let scene = FitScene::from_toml(
        r#"
[chain]
n = 5
d = 0.1
[unknowns]
k = 2
mass_bounds = [0.1, 100.0]
"#,
    )?;
    let data = Data::from_csv(csv, "x1", Some(sigma))?;
    let report = fit(&scene, &data, &scene.options())?;
    println!("read {csv} (noise sigma {sigma:.2e})");
    println!("found: {:?}", report.defects);
    println!("truth: {:?}", truth.defects());
    println!(
        "residual {:.2e}, data floor {:.2e}, resolved: {}",
        report.residual, report.floor, report.resolved
    );
    Ok(())
}
