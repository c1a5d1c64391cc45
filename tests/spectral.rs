//! The spectral start end to end: modes of mass 1 (from the exact modal sum
//! of an undamped chain) written as a CSV, read by `springmass spectral`,
//! against the library and the truth; bad files get exit 2 naming the field.

use springmass::detect::fit::spectral::{masses_from_spectrum, Spectrum};
use springmass::time::modal::ModalResponse;
use springmass::{Chain, Defect};
use std::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_springmass");

fn truth() -> Chain {
    Chain::paper(8)
        .unwrap()
        .with_d(0.0)
        .unwrap()
        .with_k(2.0)
        .unwrap()
        .with_defects([
            Defect::Mass { at: 3, m: 2.5 },
            Defect::Mass { at: 6, m: 0.7 },
        ])
        .unwrap()
}

fn write(name: &str, text: &str) -> std::path::PathBuf {
    let p = std::env::temp_dir().join(format!("springmass-spectral-{}-{name}", std::process::id()));
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn cli_rebuilds_the_masses_from_a_modes_file() {
    let c = truth();
    let spec =
        Spectrum::from_poles(&ModalResponse::impulse(&c, 1).unwrap().poles(), c.gamma()).unwrap();
    let mut csv = String::from("# modes of mass 1\nomega,residue\n");
    for (l, r) in spec.lambda.iter().zip(&spec.residue) {
        csv.push_str(&format!("{:.17e},{:.17e}\n", l.sqrt(), r));
    }
    let path = write("modes.csv", &csv);
    let out = Command::new(BIN)
        .args(["spectral", "--n", "8", "--k", "2", "--json", "--modes"])
        .arg(&path)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let masses: Vec<f64> = v["masses"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    let lib = masses_from_spectrum(&c.springs(), &spec).unwrap();
    for ((m, l), t) in masses.iter().zip(&lib.masses).zip(c.masses()) {
        assert!((m / t - 1.0).abs() < 1e-10, "{m} vs {t}");
        assert!((m / l - 1.0).abs() < 1e-14, "CLI {m} vs library {l}");
    }
    assert_eq!(v["resolved"], true);
    // the text output leads with the masses
    let out = Command::new(BIN)
        .args(["spectral", "--n", "8", "--k", "2", "--modes"])
        .arg(&path)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("m_3 = 2.5000000000"), "{text}");
    let _ = std::fs::remove_file(&path);
}

#[test]
fn bad_modes_files_exit_2_naming_the_problem() {
    for (name, text, args, needle) in [
        ("nocol.csv", "w,residue\n1,1\n", &["--n", "1"][..], "omega"),
        (
            "nan.csv",
            "omega,residue\n1,x\n",
            &["--n", "1"][..],
            "residue",
        ),
        (
            "short.csv",
            "omega,residue\n1,1\n",
            &["--n", "3"][..],
            "spectrum",
        ),
        (
            "neg.csv",
            "omega,residue\n1,-1\n",
            &["--n", "1"][..],
            "spectrum",
        ),
        (
            "k.csv",
            "omega,residue\n1,1\n",
            &["--n", "1", "--k=-1"][..],
            "k",
        ),
    ] {
        let path = write(name, text);
        let out = Command::new(BIN)
            .arg("spectral")
            .args(args)
            .arg("--modes")
            .arg(&path)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{name}: {err}");
        assert!(err.contains(needle), "{name}: {err}");
        let _ = std::fs::remove_file(&path);
    }
}
