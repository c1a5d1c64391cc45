//! Shared helpers for the integration tests: the paper's reference scenes and
//! the independent test vectors in `tests/data/` (see its README.md).
#![allow(dead_code)]

use num_complex::Complex64;
use springmass::{Chain, Defect};
use std::path::PathBuf;

/// Relative error `|a - b| / |b|`.
pub fn rel_err(a: Complex64, b: Complex64) -> f64 {
    (a - b).norm() / b.norm()
}

/// Folder of the independent reference vectors (`tests/data/`, in the repository).
///
/// # Panics
/// When the folder or its README is missing: a test without its input must fail.
pub fn reference_dir() -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data");
    assert!(
        dir.join("README.md").exists(),
        "reference vectors missing: {} (see tests/data/README.md)",
        dir.display()
    );
    dir
}

pub struct Point {
    pub s: Complex64,
    pub x1: Complex64,
    pub xn: Complex64,
}

pub struct RefScene {
    pub name: String,
    pub chain: Chain,
    pub real: Vec<Point>,
    pub complex: Vec<Point>,
}

fn num(v: &serde_json::Value) -> f64 {
    v.as_f64()
        .unwrap_or_else(|| v.as_str().unwrap().parse().unwrap())
}

fn cnum(v: &serde_json::Value) -> Complex64 {
    match v {
        serde_json::Value::Array(a) => Complex64::new(num(&a[0]), num(&a[1])),
        other => Complex64::new(num(other), 0.0),
    }
}

/// The chain of a reference JSON (fields n, d, gamma, defects [[j, m], ...]).
pub fn chain_of(v: &serde_json::Value) -> Chain {
    let n = num(&v["n"]) as usize;
    let d = num(&v["d"]);
    let gamma = num(&v["gamma"]);
    let defects: Vec<Defect> = match &v["defects"] {
        serde_json::Value::Array(a) => a
            .iter()
            .map(|p| Defect::Mass {
                at: num(&p[0]) as usize,
                m: num(&p[1]),
            })
            .collect(),
        serde_json::Value::String(s) => serde_json::from_str::<Vec<(usize, f64)>>(s)
            .unwrap()
            .into_iter()
            .map(|(at, m)| Defect::Mass { at, m })
            .collect(),
        _ => vec![],
    };
    Chain::new(n)
        .unwrap()
        .with_d(d)
        .unwrap()
        .with_gamma(gamma)
        .unwrap()
        .with_defects(defects)
        .unwrap()
}

pub const SCENES: [&str; 8] = ["P1", "P2", "P3", "P4", "S1", "S2", "S3", "S4"];

/// All eight Laplace-domain reference scenes.
pub fn reference_scenes() -> Vec<RefScene> {
    SCENES
        .iter()
        .map(|name| {
            let path = reference_dir().join(format!("laplace_{name}.json"));
            let v: serde_json::Value =
                serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
            let pts = |key: &str| -> Vec<Point> {
                v[key]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|p| Point {
                        s: cnum(&p["s"]),
                        x1: cnum(&p["X1"]),
                        xn: cnum(&p["Xn"]),
                    })
                    .collect()
            };
            RefScene {
                name: name.to_string(),
                chain: chain_of(&v),
                real: pts("real_s"),
                complex: pts("complex_s"),
            }
        })
        .collect()
}
