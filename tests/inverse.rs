//! Numerical inverse Laplace transform against the exact suppression controls
//! of `tests/data/controls.json` (80-digit residue sums; see tests/data/README.md).
//!
//! F = -sinh(3L)/sinh((n+2)L) = -U_2(c)/U_{n+1}(c), G = U_1(c)/U_{n+1}(c),
//! F1 = -sinh(L)/sinh(nL) = -1/U_{n-1}(c), c = cosh L = (s^2 + d s + 2)/2, d = 0.1.
//!
//! Run with `--nocapture` to print the accuracy table (t, evaluations, error).

use springmass::time::inverse::{de_hoog, invert, talbot, DeHoog, InverseOptions};
use springmass::{Complex64, Error};

const D: f64 = 0.1;

fn reference() -> Option<serde_json::Value> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/controls.json");
    let text = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("reference {} missing: {e}", path.display()));
    Some(serde_json::from_str(&text).expect("controls.json is valid JSON"))
}

/// U_a(c) / U_b(c) by the three-term recurrence, rescaled against overflow.
fn u_ratio(c: Complex64, a: usize, b: usize) -> Complex64 {
    let mut prev = Complex64::new(1.0, 0.0); // U_0
    let mut cur = 2.0 * c; // U_1
    let mut ua = if a == 0 {
        Some(prev)
    } else if a == 1 {
        Some(cur)
    } else {
        None
    };
    if b == 0 {
        return ua.unwrap() / prev;
    }
    for k in 2..=b {
        let next = 2.0 * c * cur - prev;
        prev = cur;
        cur = next;
        if k == a {
            ua = Some(cur);
        }
        let m = cur.norm();
        if m > 1e150 {
            prev /= m;
            cur /= m;
            if let Some(u) = ua.as_mut() {
                *u /= m;
            }
        }
    }
    ua.unwrap() / cur
}

fn control(kind: &str, n: usize) -> impl Fn(Complex64) -> Complex64 {
    let kind = kind.to_string();
    move |s: Complex64| {
        let c = (s * s + D * s + 2.0) / 2.0;
        match kind.as_str() {
            "f" => -u_ratio(c, 2, n + 1),
            "g" => u_ratio(c, 1, n + 1),
            "f1" => -u_ratio(c, 0, n - 1),
            _ => unreachable!(),
        }
    }
}

struct Case {
    n: usize,
    kind: &'static str,
    t: Vec<f64>,
    exact: Vec<f64>,
    max_abs: f64,
}

fn cases(refj: &serde_json::Value) -> Vec<Case> {
    let t: Vec<f64> = refj["t"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let mut out = Vec::new();
    for n in [4usize, 19] {
        for kind in ["f", "g", "f1"] {
            let c = &refj["cases"][format!("n={n}")][kind];
            let exact: Vec<f64> = c["residue_str"]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_str().unwrap().parse().unwrap())
                .collect();
            out.push(Case {
                n,
                kind,
                t: t.clone(),
                max_abs: c["max_abs_value"].as_f64().unwrap(),
                exact,
            });
        }
    }
    out
}

const TABLE_T: [f64; 12] = [
    0.5, 1.0, 2.0, 5.0, 10.0, 15.0, 20.0, 28.0, 30.0, 40.0, 50.0, 60.0,
];

#[test]
fn accuracy_table_and_failure_region() {
    let Some(refj) = reference() else {
        panic!("reference controls.json not found");
    };
    let opts = InverseOptions::default();
    println!("# numerical inverse Laplace vs exact residue sums (controls.json), d = 0.1");
    println!(
        "# abs error; columns: Talbot(M) with M evaluations, de Hoog(M) with 2M+1 evaluations"
    );
    println!(
        "# invert(): checked value (de Hoog pairs M/T=2t and 1.5M/T=2.5t, M = 40, 80, 160 until they agree; + Talbot M=24)"
    );
    let talbot_ms = [16usize, 24, 32];
    let dh_ms = [20usize, 40, 60, 80];
    let mut refused = 0;
    let mut accepted = 0;
    let mut talbot_flagged = 0;
    let mut worst_accepted_rel: f64 = 0.0;
    let mut worst_ratio: f64 = 0.0;
    for case in cases(&refj) {
        let f = control(case.kind, case.n);
        println!(
            "\n## n = {}, {}  (max |f| = {:.3})",
            case.n, case.kind, case.max_abs
        );
        let mut head = format!("{:>5}", "t");
        for m in talbot_ms {
            head += &format!(" {:>10}", format!("Tal{m}"));
        }
        for m in dh_ms {
            head += &format!(" {:>10}", format!("dH{}", 2 * m + 1));
        }
        head += &format!(
            " {:>10} {:>10} {:>6} {:>9}",
            "invert", "est", "evals", "Talbot?"
        );
        println!("{head}");
        for &t in &TABLE_T {
            let i = case.t.iter().position(|&v| v == t).unwrap();
            let exact = case.exact[i];
            let mut row = format!("{t:>5}");
            for m in talbot_ms {
                let v = talbot(&f, t, m).unwrap();
                row += &format!(" {:>10.2e}", (v - exact).abs());
            }
            for m in dh_ms {
                let p = DeHoog {
                    m,
                    ..DeHoog::default()
                };
                match de_hoog(&f, t, &p) {
                    Ok(v) => row += &format!(" {:>10.2e}", (v - exact).abs()),
                    Err(_) => row += &format!(" {:>10}", "breakdown"),
                }
            }
            match invert(&f, t, &opts) {
                Ok(r) => {
                    accepted += 1;
                    let err = (r.value - exact).abs();
                    // Contract: an accepted value is within its estimate, itself within tolerance.
                    let tol = opts.atol + opts.rtol * r.value.abs();
                    assert!(r.err <= tol);
                    assert!(
                        err <= r.err,
                        "n={} {} t={t}: accepted value off by {err:.3e} > tol {tol:.3e}",
                        case.n,
                        case.kind
                    );
                    worst_accepted_rel = worst_accepted_rel.max(err / case.max_abs);
                    worst_ratio = worst_ratio.max(err / r.err);
                    let tal = match r.talbot_agrees {
                        Some(true) => "agrees",
                        Some(false) => {
                            talbot_flagged += 1;
                            "FLAGGED"
                        }
                        None => "-",
                    };
                    // A Talbot value that is off must be flagged.
                    if let Some(tv) = r.talbot {
                        if (tv - exact).abs() > 2.0 * (r.err + tol) {
                            assert_eq!(
                                r.talbot_agrees,
                                Some(false),
                                "t={t}: wrong Talbot not flagged"
                            );
                        }
                    }
                    row += &format!(
                        " {err:>10.2e} {:>10.2e} {:>6} {tal:>9}",
                        r.err, r.evaluations
                    );
                }
                Err(e) => {
                    refused += 1;
                    assert!(matches!(e, Error::Numerical { .. }));
                    row += &format!(" {:>10} {:>10} {:>6} {:>9}", "REFUSED", "-", "-", "-");
                }
            }
            println!("{row}");
            // Usefulness: short and moderate times must be resolved.
            if t <= 20.0 {
                assert!(
                    invert(&f, t, &opts).is_ok(),
                    "n={} {} t={t} refused",
                    case.n,
                    case.kind
                );
            }
        }
    }
    println!(
        "\n# invert(): {accepted} accepted (worst error / max|f| = {worst_accepted_rel:.2e}), \
         {refused} refused; Talbot(24) flagged as inconsistent in {talbot_flagged} accepted points; \
         max true error / estimate = {worst_ratio:.2}"
    );
    // The failure region of Talbot at long times exists and is detected.
    assert!(talbot_flagged > 0);
}

#[test]
fn every_reference_time_is_accurate_or_refused() {
    let Some(refj) = reference() else {
        panic!("reference controls.json not found");
    };
    let opts = InverseOptions::default();
    for case in cases(&refj) {
        let f = control(case.kind, case.n);
        for (&t, &exact) in case.t.iter().zip(&case.exact) {
            if let Ok(r) = invert(&f, t, &opts) {
                let err = (r.value - exact).abs();
                assert!(
                    err <= r.err && r.err <= opts.atol + opts.rtol * r.value.abs(),
                    "n={} {} t={t}: {err:.3e} est {:.3e} m {} v {}",
                    case.n,
                    case.kind,
                    r.err,
                    r.m,
                    r.value
                );
            }
        }
    }
}

#[test]
fn talbot_alone_is_wrong_at_long_times() {
    // The reason Talbot is only a cross-check: with f64-sized M it misses
    // the lightly damped modes at long times, and does so smoothly.
    let Some(refj) = reference() else {
        panic!("reference controls.json not found");
    };
    let case = &cases(&refj)[0]; // n = 4, f
    let f = control(case.kind, case.n);
    let i = case.t.iter().position(|&v| v == 40.0).unwrap();
    let v = talbot(&f, 40.0, 24).unwrap();
    assert!((v - case.exact[i]).abs() > 1e-3);
    let r = invert(&f, 40.0, &InverseOptions::default());
    if let Ok(r) = r {
        assert_eq!(r.talbot_agrees, Some(false));
    }
}

#[test]
fn inverse_of_the_forward_model_matches_the_modal_sum() {
    use springmass::forward::Forward;
    use springmass::time::modal::ModalResponse;
    let chain = springmass::scenes::by_name("P2").unwrap();
    let fwd = Forward::new(&chain);
    let modal = ModalResponse::impulse(&chain, 1).unwrap();
    let f = |s: Complex64| fwd.eval(s, 1).unwrap_or(Complex64::new(f64::NAN, 0.0));
    let mut accepted = 0;
    for t in [0.5, 1.0, 3.0, 10.0, 20.0, 30.0, 50.0, 80.0] {
        let exact = modal.eval(t);
        match invert(&f, t, &InverseOptions::default()) {
            Ok(r) => {
                accepted += 1;
                assert!(
                    (r.value - exact).abs() <= r.err,
                    "t={t}: {} vs {exact} (err {})",
                    r.value,
                    r.err
                );
            }
            Err(e) => assert!(
                matches!(e, Error::Numerical { .. }) && t > 20.0,
                "t={t}: {e}"
            ),
        }
    }
    assert!(accepted >= 5);
}
