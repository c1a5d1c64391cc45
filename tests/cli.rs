//! The `springmass` binary: outputs and error handling (non-zero exit with a
//! one-line message, never a panic).

use std::process::Command;

fn run(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_springmass"))
        .args(args)
        .output()
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn response_json_matches_library() {
    let (code, out, err) = run(&[
        "response",
        "--n",
        "20",
        "--defect",
        "mass:8:5",
        "--defect",
        "mass:15:2",
        "--s",
        "0.5,1+5i",
        "--json",
    ]);
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    let pts = v["points"].as_array().unwrap();
    assert_eq!(pts.len(), 2);
    // 60-digit reference (shared/reference/laplace_S3.json): X1(1+5i)
    let x = &pts[1]["x"];
    assert!((x[0].as_f64().unwrap() - -0.037_143_191_564_427_58).abs() < 1e-15);
    assert!((x[1].as_f64().unwrap() - -0.017_868_992_431_249_5).abs() < 1e-15);
    assert_eq!(pts[0]["s"][0].as_f64().unwrap(), 0.5);
}

#[test]
fn response_from_scene_file() {
    let dir = std::env::temp_dir().join(format!("springmass-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let scene = dir.join("scene.toml");
    std::fs::write(
        &scene,
        "[chain]\nn = 5\nd = 0.1\ndefects = [{ kind = \"mass\", at = 3, m = 4.0 }]\n",
    )
    .unwrap();
    let (code, out, err) = run(&[
        "response",
        "--scene",
        scene.to_str().unwrap(),
        "--s",
        "1",
        "--observe",
        "5",
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("X_5(s)"), "{out}");
    let bad = dir.join("bad.toml");
    std::fs::write(&bad, "[chain]\nn = 5\ndamping = 0.1\n").unwrap();
    let (code, _, err) = run(&["response", "--scene", bad.to_str().unwrap(), "--s", "1"]);
    assert_eq!(code, 2);
    assert!(err.contains("damping"), "{err}");
}

#[test]
fn bad_input_exits_nonzero_with_one_line() {
    let cases: &[(&[&str], &str)] = &[
        (&["response", "--n", "0", "--s", "1"], "n"),
        (&["response", "--n", "5", "--s", "-1"], "Re s >= 0"),
        (&["response", "--n", "5", "--s", "1+xi"], "complex number"),
        (
            &["response", "--n", "5", "--s", "1", "--defect", "mass:9:2"],
            "defects[0].at",
        ),
        (
            &["response", "--n", "5", "--s", "1", "--defect", "mass:2:0"],
            "defects[0].m",
        ),
        (
            &[
                "response", "--n", "5", "--s", "1", "--defect", "mass:2:2", "--defect", "mass:2:3",
            ],
            "duplicate",
        ),
        (&["response", "--n", "5", "--s", "1", "--k", "0"], "k"),
        (&["response", "--n", "5", "--s", "1", "--d", "-1"], "d"),
        (&["response", "--n", "5", "--s", "nan"], "complex number"),
        (
            &["response", "--n", "5", "--s", "1", "--observe", "6"],
            "observe",
        ),
        (
            &["response", "--n", "5", "--s", "1", "--defect", "bolt:1:2"],
            "unknown kind",
        ),
    ];
    for (args, needle) in cases {
        let (code, _, err) = run(args);
        assert_eq!(code, 2, "{args:?}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{args:?}: {err}");
        assert!(
            err.contains(needle) && !err.contains("panicked"),
            "{args:?}: {err}"
        );
    }
}

#[test]
fn fit_scene_with_spring_and_damper_defects() {
    let scene = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/configs/scenes/fit-spring.toml"
    );
    let (code, out, err) = run(&["fit", "--scene", scene]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("found      (spring 4, 0.5"), "{out}");
    assert!(out.contains("(damper 7, 0.6"), "{out}");
    assert!(out.contains("chain d"), "{out}");
    assert!(out.contains("runners-up"), "{out}");
    let (code, out, err) = run(&["fit", "--scene", scene, "--json"]);
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    let d = &v["chain_params"][0];
    assert_eq!(d["name"], "d");
    assert!((d["value"].as_f64().unwrap() - 0.1).abs() <= 3.0 * d["std_error"].as_f64().unwrap());
}
