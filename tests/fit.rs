//! Integration tests of defect fitting: the paper's Table 1 systems, bad
//! scenes, determinism, and the fixed rules against the adaptive reference.

use springmass::detect::data::exact::Data;
use springmass::detect::fit::paper::fit;
use springmass::detect::fit::FitMethod;
use springmass::detect::misfit::quadrature::Adaptive;
use springmass::detect::misfit::{Misfit, MisfitKind, MisfitSpec};
use springmass::detect::scene::FitScene;
use springmass::detect::search::enumerate::{enumerate, EnumerateOptions};
use springmass::detect::unknowns::{DefectUnknown, MassUnknowns};
use springmass::{scenes, Chain, Error};

/// System `sys` (1..=4) of the paper's Table 1 (docs/paper-notes.md): n, the chain and
/// the true (j, m) pairs.
fn table1(sys: usize) -> (usize, Chain, Vec<(usize, f64)>) {
    let chain = scenes::table1(sys).unwrap();
    let defs = scenes::truth(&format!("S{sys}")).unwrap();
    (chain.n(), chain, defs)
}

#[test]
fn enumeration_recovers_every_table1_system_exactly() {
    for kind in [MisfitKind::RealAxis, MisfitKind::Bromwich] {
        for sys in 1..=4 {
            let (n, chain, defs) = table1(sys);
            let mut scene = FitScene::synthetic(&chain);
            scene.misfit.kind = kind;
            let report = fit(&scene, &scene.data().unwrap(), &scene.options()).unwrap();
            let got: Vec<(usize, f64)> =
                report.defects.iter().map(|d| (d.at(), d.value())).collect();
            for (g, t) in got.iter().zip(&defs) {
                assert_eq!(g.0, t.0, "{kind:?} system {sys}: {got:?}");
                assert!(
                    (g.1 - t.1).abs() < 1e-7 * t.1,
                    "{kind:?} system {sys}: {got:?}"
                );
            }
            assert!(report.residual < 1e-26, "{}", report.residual);
            assert!(report.resolved && report.fits_data);
            let gap = report.runners_up[0].gap;
            assert!(gap > 1e3 * report.floor, "system {sys}: gap {gap:e}");
            assert_eq!(report.sets, Some(n * (n - 1) / 2));
            println!(
                "{kind:?} system {sys}: runner-up {:?} gap {gap:.3e}, floor {:.1e}, {} evaluations, {:.2} ms",
                report.runners_up[0].defects.iter().map(|d| d.at()).collect::<Vec<_>>(),
                report.floor,
                report.evaluations,
                report.wall_time_s * 1e3
            );
        }
    }
}

#[test]
fn bad_scenes_are_typed_errors_naming_the_field() {
    let cases = [
        ("[chain]\nn = 3\n[unknowns]\nk = 4\n", "unknowns.k"),
        ("[chain]\nn = 3\n[unknowns]\nk = 1\nmass_bounds = [2.0, 1.0]\n", "unknowns.mass_bounds"),
        (
            "[chain]\nn = 3\n[unknowns]\nk = 1\n[[unknowns.defects]]\nbounds = [1.0, 1.0]\n",
            "unknowns.defects[0].bounds",
        ),
        ("[chain]\nn = 3\n[unknowns]\nk = 1\n[[unknowns.defects]]\nat = 4\n", "unknowns.defects[0].at"),
        (
            "[chain]\nn = 3\n[unknowns]\nk = 2\n[[unknowns.defects]]\nat = 1\n[[unknowns.defects]]\nat = 1\n",
            "unknowns.defects[1].at",
        ),
        ("[chain]\nn = 3\n[unknowns]\nk = 1\n[misfit]\nper_panel = 0\n", "misfit.per_panel"),
        ("[chain]\nn = 3\n[unknowns]\nk = 1\n[misfit]\ns_max = -1\n", "misfit.s_max"),
        ("[chain]\nn = 0\n[unknowns]\nk = 1\n", "n"),
    ];
    for (text, field) in cases {
        let scene = FitScene::from_toml(text).unwrap();
        let data = Data::exact(&Chain::paper(3).unwrap());
        match fit(&scene, &data, &scene.options()) {
            Err(Error::InvalidParameter { field: f, .. }) => assert_eq!(f, field, "{text}"),
            other => panic!("{text}: {other:?}"),
        }
    }
    // unknown fields and kinds are parse errors
    for text in [
        "[chain]\nn = 3\n[unknowns]\nkk = 1\n",
        "[chain]\nn = 3\n[search]\nmethod = \"sa\"\n",
    ] {
        assert!(
            matches!(FitScene::from_toml(text), Err(Error::Parse { .. })),
            "{text}"
        );
    }
}

#[test]
fn bromwich_line_resolves_system3_where_the_real_axis_cannot() {
    // 1e-4 relative noise: the real-axis residual cannot see the second
    // defect (gap 1.4e-13 against a floor of 5e-9); on the Bromwich line the
    // gap is 6.8e-7 (Parseval: time-domain conditioning) and the truth is found
    let chain = scenes::table1(3).unwrap();
    let mut scene = FitScene::synthetic(&chain);
    scene.data.noise = 1e-4;
    scene.misfit.kind = MisfitKind::Bromwich;
    let report = fit(&scene, &scene.data().unwrap(), &scene.options()).unwrap();
    let pos: Vec<usize> = report.defects.iter().map(|d| d.at()).collect();
    assert_eq!(pos, vec![8, 15], "{report:?}");
    assert!(report.resolved && report.fits_data);
    assert!((report.defects[1].value() - 2.0).abs() < 0.05);
}

#[test]
fn a_model_missing_a_defect_does_not_fit_the_data() {
    let chain = scenes::table1(2).unwrap();
    let mut scene = FitScene::synthetic(&chain);
    scene.unknowns.k = Some(1);
    let report = fit(&scene, &scene.data().unwrap(), &scene.options()).unwrap();
    assert_eq!(report.defects.len(), 1);
    assert_eq!(report.defects[0].at(), 3);
    assert!(!report.fits_data, "{report:?}");
}

#[test]
fn beam_search_reports_its_cost_and_finds_table1_system3() {
    let chain = scenes::table1(3).unwrap();
    let mut scene = FitScene::synthetic(&chain);
    scene.search.max_sets = 50; // force the beam search
    let report = fit(&scene, &scene.data().unwrap(), &scene.options()).unwrap();
    assert_eq!(report.exhaustive, Some(false));
    let pos: Vec<usize> = report.defects.iter().map(|d| d.at()).collect();
    assert_eq!(pos, vec![8, 15]);
    assert!(report.fits_data);
}

#[test]
fn enumeration_is_deterministic_across_threads() {
    let chain = scenes::table1(2).unwrap();
    let mis = Misfit::new(
        &chain.uniform(),
        &Data::exact(&chain).with_noise(1e-6, 3).unwrap(),
        &MisfitSpec::default(),
    )
    .unwrap();
    let u = MassUnknowns::new(10, vec![DefectUnknown::free(0.1, 100.0); 2]).unwrap();
    let ser = enumerate(
        &mis,
        &u,
        &EnumerateOptions {
            parallel: false,
            ..Default::default()
        },
    )
    .unwrap();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(3)
        .build()
        .unwrap();
    let par = pool.install(|| enumerate(&mis, &u, &EnumerateOptions::default()).unwrap());
    assert_eq!(ser, par);
}

#[test]
fn noise_above_the_gap_is_flagged_unresolved() {
    // System 3's runner-up is 1.6e-13 above the truth in r: 1e-4 noise hides it
    let chain = scenes::table1(3).unwrap();
    let mut scene = FitScene::synthetic(&chain);
    scene.data.noise = 1e-4;
    scene.data.seed = 11;
    let report = fit(&scene, &scene.data().unwrap(), &scene.options()).unwrap();
    assert!(!report.resolved, "{report:?}");
    assert!(report.floor > 1e-12);
}

#[test]
fn stochastic_methods_run_seeded_through_fit() {
    let chain = scenes::table1(1).unwrap();
    let mut scene = FitScene::synthetic(&chain);
    scene.search.max_evals = 3000;
    scene.search.trace = true;
    let data = scene.data().unwrap();
    for m in [FitMethod::Ga, FitMethod::NelderMead, FitMethod::Pso] {
        let mut opts = scene.options();
        opts.method = m;
        opts.seed = 5;
        let a = fit(&scene, &data, &opts).unwrap();
        let b = fit(&scene, &data, &opts).unwrap();
        assert_eq!(a.defects, b.defects, "{m:?} not reproducible");
        assert_eq!(a.evaluations, b.evaluations);
        assert!(a.residual.is_finite() && a.residual >= 0.0);
        assert!(
            a.evaluations > 0 && a.evaluations <= 3000 + 500,
            "{m:?}: {}",
            a.evaluations
        );
        assert!(!a.trace.is_empty());
        assert!(!a.runners_up.is_empty());
    }
    // the optimizers' spaces are unordered: distinct known masses need enumerate
    let text = "[chain]\nn = 8\n[unknowns]\nk = 2\n[[unknowns.defects]]\nm = 3.0\n[[unknowns.defects]]\nm = 7.0\n[search]\nmethod = \"ga\"\n";
    let sc = FitScene::from_toml(text).unwrap();
    match fit(&sc, &Data::exact(&Chain::paper(8).unwrap()), &sc.options()) {
        Err(Error::InvalidParameter { field, .. }) => assert_eq!(field, "search.method"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn enumeration_recovers_table1_from_simulated_time_series() {
    // the paper's pipeline: simulate x_1(t) on [0, 300] (dt 0.05), transform
    for sys in 1..=4 {
        let (_, chain, defs) = table1(sys);
        let mut scene = FitScene::synthetic(&chain);
        scene.data.source = springmass::detect::scene::DataSourceKind::Simulated;
        let report = fit(&scene, &scene.data().unwrap(), &scene.options()).unwrap();
        for (g, t) in report.defects.iter().zip(&defs) {
            assert_eq!(g.at(), t.0, "{defs:?}: {:?}", report.defects);
            assert!(
                (g.value() - t.1).abs() < 1e-3 * t.1,
                "{defs:?}: {:?}",
                report.defects
            );
        }
    }
}

/// Each fixed rule's error in r against the adaptive reference, at the truth's
/// runner-up hypotheses, and whether enumeration still recovers the truth.
#[test]
fn fixed_rules_against_the_adaptive_reference() {
    let rules = [(5usize, 8usize), (10, 8), (20, 8), (10, 4)];
    let adaptive = Adaptive::default();
    for sys in 1..=4 {
        let (n, chain, defs) = table1(sys);
        let data = Data::exact(&chain);
        for &(panels, per) in &rules {
            let spec = MisfitSpec::real_axis(panels, per);
            let mis = Misfit::new(&chain.uniform(), &data, &spec).unwrap();
            let u = MassUnknowns::new(n, vec![DefectUnknown::free(0.1, 100.0); 2]).unwrap();
            let e = enumerate(&mis, &u, &EnumerateOptions::default()).unwrap();
            let best = &e.ranked[0];
            let ok = best.defects.iter().zip(&defs).all(|(g, t)| g.0 == t.0);
            let runner = &e.ranked[1];
            let fixed = runner.residual;
            let reference = mis.reference(&runner.defects, &adaptive).unwrap();
            let rel = (fixed - reference.value).abs() / reference.value;
            println!(
                "n={n} {defs:?} rule {panels}x{per} ({} nodes): truth found {ok}, runner-up {:?} r_fixed {fixed:.6e} r_ref {:.6e} (+-{:.1e}, {} evals) rel err {rel:.1e}",
                mis.nodes(),
                runner.defects.iter().map(|d| d.0).collect::<Vec<_>>(),
                reference.value,
                reference.error,
                reference.evaluations
            );
            assert!(ok);
            if panels * per >= 80 {
                assert!(rel < 1e-2, "rule {panels}x{per}: rel err {rel:e}");
            }
        }
        // the Bromwich line's default rule (40 x 8 on omega in [0, 4], sigma 0.1)
        let spec = MisfitSpec {
            kind: MisfitKind::Bromwich,
            ..MisfitSpec::default()
        };
        let mis = Misfit::new(&chain.uniform(), &data, &spec).unwrap();
        let u = MassUnknowns::new(n, vec![DefectUnknown::free(0.1, 100.0); 2]).unwrap();
        let e = enumerate(&mis, &u, &EnumerateOptions::default()).unwrap();
        let runner = &e.ranked[1];
        let reference = mis.reference(&runner.defects, &adaptive).unwrap();
        let rel = (runner.residual - reference.value).abs() / reference.value;
        println!(
            "n={n} {defs:?} bromwich {} nodes: runner-up {:?} r_fixed {:.6e} r_ref {:.6e} rel err {rel:.1e}",
            mis.nodes(),
            runner.defects.iter().map(|d| d.0).collect::<Vec<_>>(),
            runner.residual,
            reference.value
        );
        assert!(rel < 1e-3);
    }
}

#[test]
fn cli_fit_and_surface() {
    let exe = env!("CARGO_BIN_EXE_springmass");
    let root = env!("CARGO_MANIFEST_DIR");
    let out = std::process::Command::new(exe)
        .args([
            "fit",
            "--scene",
            &format!("{root}/configs/scenes/table1-system3.toml"),
            "--json",
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let d = v["defects"].as_array().unwrap();
    assert_eq!(
        (d[0]["at"].as_u64(), d[1]["at"].as_u64()),
        (Some(8), Some(15))
    );
    assert_eq!(v["nodes"].as_u64(), Some(80));
    assert!(v["runners_up"][0]["gap"].as_f64().unwrap() > 1e-14);

    let dir = std::env::temp_dir().join(format!("springmass-fit-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bad = dir.join("bad.toml");
    std::fs::write(&bad, "[chain]\nn = 3\n[unknowns]\nk = 4\n").unwrap();
    let out = std::process::Command::new(exe)
        .args(["fit", "--scene", bad.to_str().unwrap()])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let msg = String::from_utf8_lossy(&out.stderr);
    assert!(msg.contains("unknowns.k"), "{msg}");

    for (cfg, kind) in [("figure16", "jm"), ("figure17", "pair")] {
        let prefix = dir.join(cfg);
        let out = std::process::Command::new(exe)
            .args([
                "surface",
                "--scene",
                &format!("{root}/configs/scenes/{cfg}.toml"),
                "--kind",
                kind,
                "--out",
                prefix.to_str().unwrap(),
            ])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let csv = std::fs::read_to_string(prefix.with_extension("csv")).unwrap();
        // the minimum of the surface is the truth
        let best = csv
            .lines()
            .skip(1)
            .map(|l| {
                l.split(',')
                    .map(|x| x.parse::<f64>().unwrap())
                    .collect::<Vec<_>>()
            })
            .min_by(|a, b| a[2].total_cmp(&b[2]))
            .unwrap();
        match kind {
            "jm" => assert_eq!(best[0], 3.0),
            _ => assert_eq!((best[0], best[1]), (10.0, 15.0)),
        }
        assert!(std::fs::read_to_string(prefix.with_extension("svg"))
            .unwrap()
            .contains("<svg"));
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn measured_csv_series_through_the_scene() {
    use springmass::time::simulate::{simulate, SimOptions};
    let chain = scenes::table1(2).unwrap();
    let n = chain.n();
    let traj = simulate(&chain, &SimOptions::new(300.0, 0.05)).unwrap();
    let dir = std::env::temp_dir().join(format!("springmass-fit-csv-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let csv = dir.join("x1.csv");
    traj.to_series().unwrap().write_csv(&csv).unwrap();
    let text = format!(
        "[chain]\nn = {n}\n[data]\nsource = \"series\"\npath = {:?}\ncolumn = \"x1\"\n[unknowns]\nk = 2\n",
        csv.display().to_string()
    );
    let scene = FitScene::from_toml(&text).unwrap();
    let report = fit(&scene, &scene.data().unwrap(), &scene.options()).unwrap();
    let pos: Vec<usize> = report.defects.iter().map(|d| d.at()).collect();
    assert_eq!(pos, vec![3, 7], "{report:?}");
    // a missing column names the columns present
    let bad = FitScene::from_toml(&text.replace("column = \"x1\"", "column = \"x9\"")).unwrap();
    assert!(bad.data().is_err());
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn objective_penalises_invalid_candidates_finitely() {
    use springmass::detect::fit::paper::MisfitObjective;
    use springmass::detect::search::{Candidate, Objective};
    use springmass::detect::unknowns::PENALTY;
    let chain = scenes::table1(1).unwrap();
    let n = chain.n();
    let mis = Misfit::new(
        &chain.uniform(),
        &Data::exact(&chain),
        &MisfitSpec::default(),
    )
    .unwrap();
    let u = MassUnknowns::new(n, vec![DefectUnknown::free(0.1, 100.0); 2]).unwrap();
    let obj = MisfitObjective::new(&mis, &u);
    let ok = obj.cost(&Candidate {
        positions: vec![4, 2],
        values: vec![0.5, 3.0],
    });
    assert!(ok < 1e-25, "{ok}");
    for c in [
        Candidate {
            positions: vec![2, 2],
            values: vec![3.0, 0.5],
        },
        Candidate {
            positions: vec![0, 6],
            values: vec![3.0, 0.5],
        },
        Candidate {
            positions: vec![2, 4],
            values: vec![f64::NAN, 0.5],
        },
        Candidate {
            positions: vec![2, 4],
            values: vec![-1.0, 1e300],
        },
        Candidate {
            positions: vec![2],
            values: vec![3.0],
        },
    ] {
        let p = obj.cost(&c);
        assert!(p.is_finite() && p >= PENALTY, "{c:?}: {p}");
    }
}

#[test]
fn general_scene_with_laplace_data_finds_a_spring_and_fits_gamma() {
    // exact Laplace data (no series), Bromwich misfit, spring defect at an
    // unknown position, gamma unknown (start 1, truth 1.2): routed to the
    // general noisy fit by `fit`
    let text = r#"
[chain]
n = 6
d = 0.1
gamma = 1.2
defects = [ { kind = "spring", at = 3, k = 0.4 } ]
[data]
source = "exact"
noise = 1e-6
[unknowns]
kind = "spring"
chain = ["gamma"]
chain_start = { gamma = 1.0 }
[misfit]
kind = "bromwich"
panels = 10
"#;
    let scene = springmass::detect::scene::FitScene::from_toml(text).unwrap();
    let report =
        springmass::detect::fit::paper::fit(&scene, &scene.data().unwrap(), &scene.options())
            .unwrap();
    assert_eq!(report.defects.len(), 1);
    assert_eq!(
        (report.defects[0].kind(), report.defects[0].at()),
        ("spring", 3)
    );
    assert!((report.defects[0].value() - 0.4).abs() < 1e-4, "{report:?}");
    let g = &report.chain_params[0];
    assert_eq!(g.name, "gamma");
    assert!(
        (g.value - 1.2).abs() < 1e-4 && (g.value - 1.2).abs() < 5.0 * g.std_error.max(1e-9),
        "{g:?}"
    );
    assert_eq!(report.sets, Some(7));
    assert!(report.resolved && report.runners_up[0].gap > 9.0);
    // the optimizers are refused on this path, naming the field
    let mut s2 = scene.clone();
    s2.search.method = springmass::detect::fit::FitMethod::Ga;
    match springmass::detect::fit::paper::fit(&s2, &s2.data().unwrap(), &s2.options()) {
        Err(springmass::Error::InvalidParameter { field, .. }) => {
            assert_eq!(field, "search.method")
        }
        other => panic!("{other:?}"),
    }
}

/// A noisy simulated series fitted on the Bromwich line: the transformed data
/// are whitened by their noise covariance, so the residual is a chi-square
/// near its degrees of freedom at the answer, and every general fit carries
/// an identifiability report.
#[test]
fn general_scene_with_a_noisy_series_is_a_whitened_chi_square() {
    let scene = FitScene::from_toml(
        r#"
        [chain]
        n = 8
        defects = [ { kind = "damper", at = 3, d = 0.8 } ]
        [data]
        source = "simulated"
        t_end = 200.0
        dt = 0.2
        noise = 0.001
        relative = true
        seed = 4
        [unknowns]
        kind = "any"
        [misfit]
        kind = "bromwich"
        rule = "gl-uniform"
        panels = 10
        per_panel = 8
        sigma = 0.05
        omega_max = 4.0
        [search]
        parallel = false
        "#,
    )
    .unwrap();
    let r = fit(&scene, &scene.data().unwrap(), &scene.options()).unwrap();
    assert_eq!(r.defects.len(), 1);
    assert_eq!((r.defects[0].kind(), r.defects[0].at()), ("damper", 3));
    assert!((r.defects[0].value() - 0.8).abs() < 4.0 * r.std_errors[0]);
    // chi-square with `nodes` = dof (160 on the Bromwich line): within 5 sigma
    let dof = r.nodes as f64;
    assert!(
        (r.residual - dof).abs() < 5.0 * (2.0 * dof).sqrt(),
        "chi2 {} for {dof} dof ({})",
        r.residual,
        r.misfit
    );
    assert!(r.fits_data && r.resolved);
    let id = r
        .identifiability
        .expect("general fits report identifiability");
    assert!(id.all_identifiable(), "{id:?}");
    assert!(id.sigma_indistinguishable.unwrap() > id.sigma);
}
