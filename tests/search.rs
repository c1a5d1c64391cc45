//! Integration tests of the optimizers (`src/detect/search`): recovery of the
//! paper's Table 1 systems from exact-model data, determinism (seed, thread
//! count), evaluation counting and budgets, candidates always inside the
//! space, traces, bad input, non-finite objectives.

use proptest::prelude::*;
use springmass::detect::data::exact::Data;
use springmass::detect::fit::paper::MisfitObjective;
use springmass::detect::misfit::{Misfit, MisfitSpec};
use springmass::detect::search::{minimize, Candidate, FitMethod, Objective, SearchOptions, Space};
use springmass::detect::unknowns::{DefectUnknown, MassUnknowns};
use springmass::forward::response;
use springmass::{scenes, Chain, Defect, Error};
use std::sync::atomic::{AtomicUsize, Ordering};

/// The library's residual (default 80-node rule) against exact-model data of
/// `truth`, with `k` unknown defects of masses in [0.1, 20] (owns what
/// [`MisfitObjective`] borrows).
struct Exact {
    misfit: Misfit,
    unknowns: MassUnknowns,
    space: Space,
}

impl Exact {
    fn new(truth: &Chain, k: usize) -> Exact {
        let misfit = Misfit::new(truth, &Data::exact(truth), &MisfitSpec::default()).unwrap();
        let unknowns =
            MassUnknowns::new(truth.n(), vec![DefectUnknown::free(0.1, 20.0); k]).unwrap();
        let space = Space::for_masses(&unknowns);
        Exact {
            misfit,
            unknowns,
            space,
        }
    }
}

impl Objective for Exact {
    fn space(&self) -> &Space {
        &self.space
    }
    fn cost(&self, c: &Candidate) -> f64 {
        MisfitObjective::new(&self.misfit, &self.unknowns).cost(c)
    }
}

/// System `sys` of Table 1 and its true defects as a candidate.
fn table1(sys: usize) -> (Exact, Candidate) {
    let chain = scenes::table1(sys).unwrap();
    let (positions, values) = scenes::truth(&format!("S{sys}"))
        .unwrap()
        .into_iter()
        .unzip();
    (Exact::new(&chain, 2), Candidate { positions, values })
}

fn recovered(best: &Candidate, truth: &Candidate, rel: f64) -> bool {
    best.positions == truth.positions
        && best
            .values
            .iter()
            .zip(&truth.values)
            .all(|(x, y)| ((x - y) / y).abs() < rel)
}

/// Counts evaluations and candidates outside the space; delegates the cost.
struct Audit<'a> {
    inner: &'a dyn Objective,
    calls: AtomicUsize,
    outside: AtomicUsize,
}

impl<'a> Audit<'a> {
    fn new(inner: &'a dyn Objective) -> Self {
        Audit {
            inner,
            calls: AtomicUsize::new(0),
            outside: AtomicUsize::new(0),
        }
    }
}

impl Objective for Audit<'_> {
    fn space(&self) -> &Space {
        self.inner.space()
    }
    fn cost(&self, c: &Candidate) -> f64 {
        self.calls.fetch_add(1, Ordering::SeqCst);
        if !self.space().contains(c) {
            self.outside.fetch_add(1, Ordering::SeqCst);
        }
        self.inner.cost(c)
    }
}

/// A synthetic mixed problem with known optimum: 2 unknown positions in
/// 1..=12 (5 and 9 excluded), each with a log-scaled value and a linear one,
/// plus one free (known-position) value. Unique minimum 0 at positions
/// {3, 10} with pairs (3: 2.0, 0.25), (10: 0.5, -0.5), free value 0.7.
struct Synthetic(Space);

impl Synthetic {
    fn new() -> Self {
        Synthetic(Space {
            n: 12,
            n_positions: 2,
            excluded: vec![5, 9],
            bounds: vec![
                (0.1, 10.0),
                (0.1, 10.0),
                (-1.0, 1.0),
                (-1.0, 1.0),
                (0.0, 1.0),
            ],
            log_scale: vec![true, true, false, false, false],
            pairing: vec![Some(0), Some(1), Some(0), Some(1), None],
        })
    }
    fn truth() -> Candidate {
        Candidate {
            positions: vec![3, 10],
            values: vec![2.0, 0.5, 0.25, -0.5, 0.7],
        }
    }
}

impl Objective for Synthetic {
    fn space(&self) -> &Space {
        &self.0
    }
    fn cost(&self, c: &Candidate) -> f64 {
        let c = self.0.canonicalize(c);
        let (p, v) = (&c.positions, &c.values);
        // position misfit dominates far away, value misfit is smooth
        let pos = (p[0] as f64 - 3.0).abs() + (p[1] as f64 - 10.0).abs();
        let val = (v[0] / 2.0).ln().powi(2)
            + (v[1] / 0.5).ln().powi(2)
            + (v[2] - 0.25).powi(2)
            + (v[3] + 0.5).powi(2)
            + (v[4] - 0.7).powi(2);
        0.1 * pos + val * (1.0 + pos)
    }
}

#[test]
fn exact_objective_matches_forward_model() {
    // the library residual (tabled Woodbury) equals the quadrature of the
    // forward model's responses on the same rule
    let (obj, _) = table1(3);
    let chain = Chain::paper(20)
        .unwrap()
        .with_defects([
            Defect::Mass { at: 4, m: 0.3 },
            Defect::Mass { at: 17, m: 7.0 },
        ])
        .unwrap();
    let c = Candidate {
        positions: vec![4, 17],
        values: vec![0.3, 7.0],
    };
    let s3 = scenes::table1(3).unwrap();
    let rule = obj.misfit.rule();
    assert_eq!(rule.nodes.len(), 80);
    let want: f64 = rule
        .nodes
        .iter()
        .zip(&rule.weights)
        .map(|(&s, w)| {
            let e = response(&chain, s, 1).unwrap() - response(&s3, s, 1).unwrap();
            w * e * e
        })
        .sum();
    let got = obj.cost(&c);
    assert!((got - want).abs() <= 1e-12 * want, "r = {got} vs {want}");
    // the truth has (numerically) zero residual, a far guess does not
    let (obj, truth) = table1(1);
    assert!(obj.cost(&truth) < 1e-28);
    let far = Candidate {
        positions: vec![1, 5],
        values: vec![10.0, 0.2],
    };
    assert!(obj.cost(&far) > 1e-6);
}

#[test]
fn every_method_recovers_table1_systems_with_exact_data() {
    for sys in [1, 3, 4] {
        let (obj, truth) = table1(sys);
        for method in FitMethod::stochastic_all() {
            for seed in 0..2 {
                let opts = SearchOptions {
                    max_evals: 30_000,
                    seed,
                    ..Default::default()
                };
                let r = minimize(method, &obj, &opts).unwrap();
                assert!(
                    recovered(&r.best, &truth, 1e-3),
                    "system {sys}, {method:?}, seed {seed}: {:?} r = {:e}",
                    r.best,
                    r.cost
                );
                assert!(r.cost < 1e-20, "{method:?}: r = {:e}", r.cost);
            }
        }
    }
}

#[test]
fn same_seed_same_result_different_seed_differs() {
    let (obj, _) = table1(2);
    for method in FitMethod::stochastic_all() {
        let opts = |seed| SearchOptions {
            max_evals: 3000,
            seed,
            trace: true,
            ..Default::default()
        };
        let a = minimize(method, &obj, &opts(7)).unwrap();
        let b = minimize(method, &obj, &opts(7)).unwrap();
        assert_eq!(a, b, "{method:?}");
        let c = minimize(method, &obj, &opts(8)).unwrap();
        assert_ne!(
            a.trace, c.trace,
            "{method:?}: seeds 7 and 8 gave the same run"
        );
    }
}

#[test]
fn parallel_swarm_is_independent_of_thread_count() {
    let (obj, _) = table1(2);
    let mut opts = SearchOptions {
        max_evals: 4000,
        seed: 5,
        trace: true,
        ..Default::default()
    };
    opts.pso.parallel = true;
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| minimize(FitMethod::Pso, &obj, &opts).unwrap())
    };
    let one = run(1);
    assert_eq!(one, run(3));
    opts.pso.parallel = false;
    assert_eq!(one, minimize(FitMethod::Pso, &obj, &opts).unwrap());
}

#[test]
fn parallel_genetic_is_independent_of_thread_count() {
    let (obj, _) = table1(3);
    let mut opts = SearchOptions {
        max_evals: 4000,
        seed: 3,
        trace: true,
        ..Default::default()
    };
    opts.genetic.parallel = true;
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| minimize(FitMethod::Ga, &obj, &opts).unwrap())
    };
    let one = run(1);
    assert_eq!(one, run(2));
    assert_eq!(one, run(4));
    opts.genetic.parallel = false;
    assert_eq!(one, minimize(FitMethod::Ga, &obj, &opts).unwrap());
}

#[test]
fn evaluations_are_counted_and_budget_is_kept() {
    let (obj, _) = table1(3);
    for method in FitMethod::stochastic_all() {
        for budget in [1, 50, 700, 2500] {
            let audit = Audit::new(&obj);
            let opts = SearchOptions {
                max_evals: budget,
                seed: 1,
                ..Default::default()
            };
            let r = minimize(method, &audit, &opts).unwrap();
            assert_eq!(
                r.evaluations,
                audit.calls.load(Ordering::SeqCst),
                "{method:?}"
            );
            // overshoot: at most one generation / one swarm sweep / one simplex step
            let slack = 40 + 3;
            assert!(
                r.evaluations <= budget + slack,
                "{method:?}: {} evaluations for a budget of {budget}",
                r.evaluations
            );
            assert!(
                r.evaluations >= budget.min(40),
                "{method:?} stopped at {}",
                r.evaluations
            );
        }
    }
}

#[test]
fn candidates_stay_in_space_and_pairs_stay_together() {
    let syn = Synthetic::new();
    syn.0.validate().unwrap();
    for method in FitMethod::stochastic_all() {
        for seed in 0..3 {
            let audit = Audit::new(&syn);
            let opts = SearchOptions {
                max_evals: 20_000,
                seed,
                trace: true,
                ..Default::default()
            };
            let r = minimize(method, &audit, &opts).unwrap();
            assert_eq!(
                audit.outside.load(Ordering::SeqCst),
                0,
                "{method:?} left the space"
            );
            assert!(syn.0.contains(&r.best));
            assert!(r.best.positions.windows(2).all(|w| w[0] < w[1]));
            let t = Synthetic::truth();
            assert_eq!(
                r.best.positions, t.positions,
                "{method:?} seed {seed}: {:?}",
                r.best
            );
            for (x, y) in r.best.values.iter().zip(&t.values) {
                assert!((x - y).abs() < 1e-3, "{method:?} seed {seed}: {:?}", r.best);
            }
            // trace: strictly decreasing cost at increasing evaluation counts, ending at the result
            assert!(!r.trace.is_empty());
            assert!(r
                .trace
                .windows(2)
                .all(|w| w[0].0 < w[1].0 && w[0].1 > w[1].1));
            let last = *r.trace.last().unwrap();
            assert_eq!(last.1, r.cost);
            assert!(last.0 <= r.evaluations);
            assert_eq!(syn.cost(&r.best), r.cost);
        }
    }
}

#[test]
fn single_defect_and_three_defects() {
    // k = 1: one defect (n = 10, at 6, m = 0.4)
    let chain = Chain::paper(10)
        .unwrap()
        .with_defect(Defect::Mass { at: 6, m: 0.4 })
        .unwrap();
    let obj = Exact::new(&chain, 1);
    let truth = Candidate {
        positions: vec![6],
        values: vec![0.4],
    };
    for method in FitMethod::stochastic_all() {
        let r = minimize(
            method,
            &obj,
            &SearchOptions {
                max_evals: 10_000,
                ..Default::default()
            },
        )
        .unwrap();
        assert!(recovered(&r.best, &truth, 1e-4), "{method:?}: {:?}", r.best);
    }
    // k = 3 on a short chain (shallow defects are resolvable)
    let chain = Chain::paper(6)
        .unwrap()
        .with_defects([
            Defect::Mass { at: 1, m: 2.0 },
            Defect::Mass { at: 3, m: 0.5 },
            Defect::Mass { at: 4, m: 3.0 },
        ])
        .unwrap();
    let obj = Exact::new(&chain, 3);
    let truth = Candidate {
        positions: vec![1, 3, 4],
        values: vec![2.0, 0.5, 3.0],
    };
    for method in FitMethod::stochastic_all() {
        let r = minimize(
            method,
            &obj,
            &SearchOptions {
                max_evals: 40_000,
                seed: 2,
                ..Default::default()
            },
        )
        .unwrap();
        assert!(
            recovered(&r.best, &truth, 1e-2),
            "{method:?}: {:?} r = {:e}",
            r.best,
            r.cost
        );
    }
}

#[test]
fn target_cost_stops_early() {
    let syn = Synthetic::new();
    for method in FitMethod::stochastic_all() {
        let opts = SearchOptions {
            max_evals: 100_000,
            target_cost: 1e-2,
            ..Default::default()
        };
        let r = minimize(method, &syn, &opts).unwrap();
        assert!(r.cost <= 1e-2);
        assert!(r.evaluations < 100_000, "{method:?}");
    }
}

/// An objective that misbehaves: NaN and +inf on part of the space.
struct Nasty(Space);
impl Objective for Nasty {
    fn space(&self) -> &Space {
        &self.0
    }
    fn cost(&self, c: &Candidate) -> f64 {
        match c.positions[0] % 3 {
            0 => f64::NAN,
            1 => f64::INFINITY,
            _ => (c.values[0] - 1.0).powi(2) + c.positions[0] as f64,
        }
    }
}

#[test]
fn non_finite_costs_never_reach_the_optimizers() {
    let nasty = Nasty(Space::masses(10, 1, (0.1, 10.0)));
    for method in FitMethod::stochastic_all() {
        let r = minimize(
            method,
            &nasty,
            &SearchOptions {
                max_evals: 3000,
                ..Default::default()
            },
        )
        .unwrap();
        assert!(r.cost.is_finite());
        // a finite-cost position (2, 5 or 8: isolated by non-finite walls, so a
        // local method may stop at 5 or 8), with its value fitted
        assert_eq!(r.best.positions[0] % 3, 2, "{method:?}");
        // (fits stop at a relative cost tolerance: with a cost offset of 8, |v - 1| ~ 0.03)
        assert!(
            (r.best.values[0] - 1.0).abs() < 0.1,
            "{method:?}: {:?}",
            r.best
        );
        if method != FitMethod::NelderMead {
            assert_eq!(r.best.positions, vec![2], "{method:?}");
        }
    }
}

#[test]
fn bad_input_gives_typed_errors() {
    let (obj, _) = table1(1);
    let field = |e: Error| match e {
        Error::InvalidParameter { field, .. } => field,
        e => panic!("unexpected {e}"),
    };
    let o = SearchOptions {
        max_evals: 0,
        ..Default::default()
    };
    assert_eq!(
        field(minimize(FitMethod::Ga, &obj, &o).unwrap_err()),
        "max_evals"
    );
    let mut o = SearchOptions::default();
    o.genetic.population = 2;
    assert_eq!(
        field(minimize(FitMethod::Ga, &obj, &o).unwrap_err()),
        "genetic.population"
    );
    let mut o = SearchOptions::default();
    o.pso.particles = 1;
    assert_eq!(
        field(minimize(FitMethod::Pso, &obj, &o).unwrap_err()),
        "pso.particles"
    );
    let mut o = SearchOptions::default();
    o.nelder_mead.step = 0.0;
    assert_eq!(
        field(minimize(FitMethod::NelderMead, &obj, &o).unwrap_err()),
        "nelder_mead.step"
    );
    // a space with more defects than free positions
    let mut s = Synthetic::new();
    s.0.n_positions = 11;
    assert_eq!(
        field(minimize(FitMethod::NelderMead, &s, &SearchOptions::default()).unwrap_err()),
        "space.n_positions"
    );
    let mut s = Synthetic::new();
    s.0.bounds[2] = (1.0, -1.0);
    assert_eq!(
        field(minimize(FitMethod::Pso, &s, &SearchOptions::default()).unwrap_err()),
        "space.bounds[2]"
    );
    assert!("simplex".parse::<FitMethod>().is_err());
    assert_eq!("pso".parse::<FitMethod>().unwrap(), FitMethod::Pso);
    assert_eq!(
        serde_json::to_string(&FitMethod::NelderMead).unwrap(),
        "\"nelder-mead\""
    );
}

proptest! {
    #[test]
    fn canonicalize_is_idempotent_and_keeps_pairs(
        perm in Just(vec![0usize, 1, 2]).prop_shuffle(),
        pos in proptest::sample::subsequence((1usize..=15).collect::<Vec<_>>(), 3),
        vals in proptest::collection::vec(0.1f64..10.0, 7),
    ) {
        let space = Space {
            n: 15,
            n_positions: 3,
            excluded: vec![],
            bounds: vec![(0.1, 10.0); 7],
            log_scale: vec![false; 7],
            pairing: vec![Some(0), Some(1), Some(2), Some(0), Some(1), Some(2), None],
        };
        let positions: Vec<usize> = perm.iter().map(|&p| pos[p]).collect();
        let c = Candidate { positions, values: vals.clone() };
        let k = space.canonicalize(&c);
        prop_assert!(k.positions.windows(2).all(|w| w[0] < w[1]));
        prop_assert_eq!(space.canonicalize(&k), k.clone());
        // each defect keeps its two values
        for p in 0..3 {
            let q = k.positions.iter().position(|&x| x == c.positions[p]).unwrap();
            prop_assert_eq!(k.values[q], c.values[p]);
            prop_assert_eq!(k.values[q + 3], c.values[p + 3]);
        }
        prop_assert_eq!(k.values[6], c.values[6]);
    }

    #[test]
    fn rounding_gives_distinct_free_positions(
        n in 3usize..30,
        xs in proptest::collection::vec(-5.0f64..40.0, 1..4),
        excl in proptest::collection::vec(1usize..30, 0..3),
    ) {
        let mut excluded: Vec<usize> = excl.into_iter().filter(|&e| e <= n).collect();
        excluded.sort();
        excluded.dedup();
        let mut space = Space::masses(n, xs.len(), (0.1, 1.0));
        space.excluded = excluded;
        prop_assume!(space.validate().is_ok());
        let r = space.round_positions(&xs);
        let c = Candidate { positions: r, values: vec![0.5; xs.len()] };
        prop_assert!(space.contains(&c), "{:?}", c);
    }
}

/// Positions only (known masses) or values only (known positions).
struct Degenerate(Space);
impl Objective for Degenerate {
    fn space(&self) -> &Space {
        &self.0
    }
    fn cost(&self, c: &Candidate) -> f64 {
        let p: f64 = c
            .positions
            .iter()
            .zip([4.0, 11.0])
            .map(|(&p, q)| (p as f64 - q).powi(2))
            .sum();
        let v: f64 = c.values.iter().map(|v| (v - 0.3).powi(2)).sum();
        p + v
    }
}

#[test]
fn positions_only_and_values_only_spaces() {
    let pos_only = Degenerate(Space {
        n: 15,
        n_positions: 2,
        excluded: vec![],
        bounds: vec![],
        log_scale: vec![],
        pairing: vec![],
    });
    let val_only = Degenerate(Space {
        n: 15,
        n_positions: 0,
        excluded: vec![3],
        bounds: vec![(0.0, 1.0); 3],
        log_scale: vec![false; 3],
        pairing: vec![None; 3],
    });
    for method in FitMethod::stochastic_all() {
        let opts = SearchOptions {
            max_evals: 5000,
            ..Default::default()
        };
        let r = minimize(method, &pos_only, &opts).unwrap();
        assert_eq!(r.best.positions, vec![4, 11], "{method:?}");
        let r = minimize(method, &val_only, &opts).unwrap();
        assert!(r.best.positions.is_empty());
        assert!(r.cost < 1e-8, "{method:?}: {:?} {:e}", r.best, r.cost);
    }
}
