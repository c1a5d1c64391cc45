//! The paper's Table 1, rerun with every optimizer.
//!
//! `cargo bench --bench table1 [-- --seeds 20 --budget 20000 --only ga,pso
//!  --systems 1,3 --data exact|pipeline --t-end 400 --dt 0.05 --verbose
//!  --scene-only --reps 200]`
//!
//! First, per system, the cost of the scene path's enumeration
//! (`detect::fit::paper::fit` on the system's synthetic scene: exact-model
//! data, the default 80-node real-axis rule, masses in [0.1, 100], keep 5,
//! single thread): median thread CPU time and wall time over `--reps` fits
//! (default 200), the Woodbury tables and the refit of the kept sets
//! included. `--scene-only` stops after it.
//!
//! Systems 1-4 (n = 5, 10, 20, 20; two mass defects; k = 1, d = 0.1); the
//! unknowns are 2 positions and 2 masses in [0.1, 20] (log scale). The
//! library's residual (`detect::misfit::Misfit`, default rule: 80
//! Gauss-Legendre nodes on log-graded panels of [0, 300]) wrapped as
//! `detect::search::MisfitObjective`, against the exact model's data
//! (`Data::exact`, default) or the paper's pipeline (`--data pipeline`,
//! `Data::simulated`: simulated x_1(t), Laplace-transformed). Systems and the
//! paper's GA row from `springmass::scenes`. For each system and optimizer, over the seeds:
//! success rate (both positions exact, both masses within 1%), median
//! estimates, median evaluations, median wall time (single thread), next to
//! the paper's GA row. The header of each system gives the residual gap
//! between the truth and the best wrong position set (masses refitted), the
//! quantity that limits every method.

use springmass::detect::data::exact::Data;
use springmass::detect::fit::paper;
use springmass::detect::misfit::{Misfit, MisfitSpec};
use springmass::detect::scene::FitScene;
use springmass::detect::search::nelder_mead::{polish, Positions};
use springmass::detect::search::pso::Finish;
use springmass::detect::search::MisfitObjective;
use springmass::detect::search::{
    minimize, Candidate, FitMethod, Objective, SearchOptions, Tracked,
};
use springmass::detect::unknowns::{DefectUnknown, MassUnknowns};
use springmass::scenes;
use std::time::Instant;

struct Variant {
    name: &'static str,
    method: FitMethod,
    tweak: fn(&mut SearchOptions),
}

fn variants() -> Vec<Variant> {
    vec![
        Variant {
            name: "ga",
            method: FitMethod::Ga,
            tweak: |_| {},
        },
        Variant {
            name: "ga-no-polish",
            method: FitMethod::Ga,
            tweak: |o| {
                o.genetic.polish = false;
                o.final_polish = false;
            },
        },
        Variant {
            name: "nelder-mead",
            method: FitMethod::NelderMead,
            tweak: |_| {},
        },
        Variant {
            name: "nm-relax-round",
            method: FitMethod::NelderMead,
            tweak: |o| {
                o.nelder_mead.positions = Positions::RelaxRound;
                o.final_polish = false;
            },
        },
        Variant {
            name: "pso",
            method: FitMethod::Pso,
            tweak: |_| {},
        },
        Variant {
            name: "pso-no-finish",
            method: FitMethod::Pso,
            tweak: |o| {
                o.pso.finish = Finish::None;
                o.final_polish = false;
            },
        },
    ]
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        return f64::NAN;
    }
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Best residual over position sets other than the truth (masses refitted by
/// Nelder-Mead from the true masses), and the truth's own residual.
fn gap(obj: &dyn Objective, truth: &Candidate) -> (f64, f64, Vec<usize>) {
    let n = obj.space().n;
    let opts = SearchOptions {
        max_evals: usize::MAX,
        ..Default::default()
    };
    let t = Tracked::new(obj, &opts);
    let mut nm = opts.nelder_mead.clone();
    nm.max_iters_per_fit = 2000;
    // the true positions with masses refitted (differs from r at the true
    // masses when the data carry errors)
    let (_, r_truth) = polish(&t, truth, 5000, &nm).unwrap();
    let mut best = (f64::INFINITY, vec![]);
    for a in 1..=n {
        for b in a + 1..=n {
            if [a, b] == truth.positions[..] {
                continue;
            }
            let start = Candidate {
                positions: vec![a, b],
                values: truth.values.clone(),
            };
            let (_, v) = polish(&t, &start, 5000, &nm).unwrap();
            if v < best.0 {
                best = (v, vec![a, b]);
            }
        }
    }
    (r_truth, best.0, best.1)
}

/// This thread's CPU time, seconds (Linux `CLOCK_THREAD_CPUTIME_ID`).
fn thread_cpu_s() -> f64 {
    #[repr(C)]
    struct Timespec {
        tv_sec: i64,
        tv_nsec: i64,
    }
    extern "C" {
        fn clock_gettime(clk: i32, tp: *mut Timespec) -> i32;
    }
    let mut t = Timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes one timespec; 3 = CLOCK_THREAD_CPUTIME_ID on Linux.
    let rc = unsafe { clock_gettime(3, &mut t) };
    assert_eq!(rc, 0, "clock_gettime(CLOCK_THREAD_CPUTIME_ID) failed");
    t.tv_sec as f64 + 1e-9 * t.tv_nsec as f64
}

/// The scene path's enumeration per system (module docs): median CPU and
/// wall milliseconds per fit, with the answer.
fn scene_enumeration(systems: &[usize], reps: usize) {
    println!(
        "Scene path, enumerate (paper::fit, exact-model data, 80-node real-axis rule, keep 5, one thread), median over {reps} fits:"
    );
    println!(
        "  {:<8} {:>6} {:>10} {:>10}  answer",
        "system", "sets", "cpu ms", "wall ms"
    );
    for &sys in systems {
        let chain = scenes::table1(sys).expect("Table 1 system");
        let mut scene = FitScene::synthetic(&chain);
        scene.search.parallel = false;
        let data = scene.data().expect("scene data");
        let opts = scene.options();
        let (mut cpu, mut wall) = (Vec::with_capacity(reps), Vec::with_capacity(reps));
        let mut last = None;
        for _ in 0..reps.max(1) {
            let (c0, t0) = (thread_cpu_s(), Instant::now());
            let r = paper::fit(&scene, &data, &opts).expect("scene fit");
            cpu.push((thread_cpu_s() - c0) * 1e3);
            wall.push(t0.elapsed().as_secs_f64() * 1e3);
            last = Some(r);
        }
        let r = last.expect("one fit");
        let answer: Vec<String> = r
            .defects
            .iter()
            .map(|d| format!("({}, {:.6})", d.at(), d.value()))
            .collect();
        println!(
            "  {:<8} {:>6} {:>10.3} {:>10.3}  {}",
            sys,
            r.sets.unwrap_or(0),
            median(cpu),
            median(wall),
            answer.join(", ")
        );
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let get = |flag: &str| {
        args.iter()
            .position(|a| a == flag)
            .and_then(|i| args.get(i + 1).cloned())
    };
    let seeds: u64 = get("--seeds").and_then(|s| s.parse().ok()).unwrap_or(20);
    let budget: usize = get("--budget")
        .and_then(|s| s.parse().ok())
        .unwrap_or(20_000);
    let only: Option<Vec<String>> = get("--only").map(|s| s.split(',').map(String::from).collect());
    let systems: Vec<usize> = get("--systems")
        .map(|s| s.split(',').filter_map(|x| x.parse().ok()).collect())
        .unwrap_or(vec![1, 2, 3, 4]);
    let reps: usize = get("--reps").and_then(|s| s.parse().ok()).unwrap_or(200);
    scene_enumeration(&systems, reps);
    if args.iter().any(|a| a == "--scene-only") {
        return;
    }
    let spec = MisfitSpec::default();
    let pipeline = get("--data").is_some_and(|d| d == "pipeline");
    let t_end: f64 = get("--t-end").and_then(|s| s.parse().ok()).unwrap_or(400.0);
    let dt: f64 = get("--dt").and_then(|s| s.parse().ok()).unwrap_or(0.05);
    println!(
        "Table 1 rerun: {} data, {} nodes ({}); \
         unknowns 2 positions + 2 masses in [0.1, 20]; budget {budget} evaluations; {seeds} seeds; success = positions exact and masses within 1%",
        if pipeline { "time-series pipeline" } else { "exact-model" },
        spec.rule().expect("default rule").nodes.len(),
        spec.rule().expect("default rule").name
    );
    for sys in systems {
        let chain = scenes::table1(sys).expect("Table 1 system");
        let n = chain.n();
        let d = scenes::truth(&format!("S{sys}")).expect("Table 1 defects");
        let data = if pipeline {
            Data::simulated(&chain, t_end, dt, 0.0, 0).expect("pipeline data")
        } else {
            Data::exact(&chain)
        };
        let misfit = Misfit::new(&chain, &data, &spec).expect("misfit");
        if pipeline {
            let nodes = &misfit.rule().nodes;
            let sm = data.sample(nodes).expect("data at the nodes");
            let (mut max_dev, mut rel) = (0.0f64, 0.0f64);
            for ((&s, x), e) in nodes.iter().zip(&sm.values).zip(&sm.sigma) {
                let exact = springmass::forward::response(&chain, s, 1).unwrap();
                max_dev = max_dev.max(((x - exact) / exact).abs());
                rel = rel.max(e / x.abs());
            }
            println!(
                "\nSystem {sys} data: simulated x_1 on [0, {t_end}], dt = {dt}, Laplace-transformed; \
                 largest relative error vs exact model {max_dev:.1e} (transform's own estimate {rel:.1e})"
            );
        }
        let unknowns =
            MassUnknowns::new(n, vec![DefectUnknown::free(0.1, 20.0); 2]).expect("unknowns");
        let obj = MisfitObjective::new(&misfit, &unknowns);
        let truth = Candidate {
            positions: vec![d[0].0, d[1].0],
            values: vec![d[0].1, d[1].1],
        };
        let (r_truth, r_wrong, wrong) = gap(&obj, &truth);
        println!();
        println!(
            "System {sys}: n = {n}, truth ({}, {}), ({}, {}); r(true positions, masses refitted) = {r_truth:.2e}, best wrong position set {wrong:?} r = {r_wrong:.2e}",
            d[0].0, d[0].1, d[1].0, d[1].1
        );
        println!(
            "  {:<15} {:>7} {:>6} {:>30} {:>10} {:>10} {:>10}",
            "method", "success", "pos ok", "median estimate", "med evals", "med ms", "med r"
        );
        println!("  {:<15} {:>7} {:>6} {:>30}", "paper GA", "-", "-", {
            let [(j1, m1), (j2, m2)] = scenes::TABLE1_PAPER_GA[sys - 1];
            format!("({j1}, {m1:.4}), ({j2}, {m2:.4})")
        });
        for v in variants() {
            if let Some(o) = &only {
                if !o.iter().any(|x| x == v.name) {
                    continue;
                }
            }
            let mut ok = 0;
            let mut pos_ok = 0;
            let (mut j1, mut m1, mut j2, mut m2) = (vec![], vec![], vec![], vec![]);
            let (mut evals, mut ms, mut rs) = (vec![], vec![], vec![]);
            for seed in 0..seeds {
                let mut opts = SearchOptions {
                    max_evals: budget,
                    seed,
                    ..Default::default()
                };
                (v.tweak)(&mut opts);
                let t0 = Instant::now();
                let r = minimize(v.method, &obj, &opts).expect("search");
                ms.push(t0.elapsed().as_secs_f64() * 1e3);
                let b = &r.best;
                let hit = b.positions == truth.positions
                    && b.values
                        .iter()
                        .zip(&truth.values)
                        .all(|(x, y)| ((x - y) / y).abs() < 0.01);
                ok += hit as usize;
                pos_ok += (b.positions == truth.positions) as usize;
                if !hit && args.iter().any(|a| a == "--verbose") {
                    println!(
                        "    miss {} seed {seed}: {:?} r = {:.2e} evals {}",
                        v.name, b, r.cost, r.evaluations
                    );
                }
                j1.push(b.positions[0] as f64);
                j2.push(b.positions[1] as f64);
                m1.push(b.values[0]);
                m2.push(b.values[1]);
                evals.push(r.evaluations as f64);
                rs.push(r.cost);
            }
            let est = format!(
                "({}, {:.4}), ({}, {:.4})",
                median(j1),
                median(m1),
                median(j2),
                median(m2)
            );
            println!(
                "  {:<15} {:>6.0}% {:>5.0}% {:>30} {:>10.0} {:>10.2} {:>10.1e}",
                v.name,
                100.0 * ok as f64 / seeds as f64,
                100.0 * pos_ok as f64 / seeds as f64,
                est,
                median(evals),
                median(ms),
                median(rs)
            );
        }
    }
}
