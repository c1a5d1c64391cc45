//! The number of defects chosen by the criterion (`--defects auto`): the
//! chi-square never rises with `k` (the fit at `k + 1` is never worse than
//! the fit at `k`), and the noise level, hence every standard error, does
//! not depend on the largest `k` tried.

use springmass::detect::data::observations::{Observations, Series};
use springmass::detect::data::series::TimeData;
use springmass::detect::fit::{fit, DefectCount, FitOptions, FitReport, Model};
use springmass::detect::unknowns::KindChoice;
use springmass::noise::NoiseLevel;
use springmass::{Chain, Defect};

/// A record of `truth`'s first mass on `[0, t_end]` with relative noise `level`.
fn record(truth: &Chain, t_end: f64, dt: f64, level: f64, seed: u64) -> Observations {
    let d = TimeData::simulate(truth, t_end, dt, NoiseLevel::RelativeMax(level), seed).unwrap();
    Observations::Series(Series::new(d.t().to_vec(), d.y().to_vec(), None).unwrap())
}

/// The suite's records for the criterion: a name, the record, n and the
/// kinds sought.
fn records() -> Vec<(&'static str, Observations, usize, KindChoice)> {
    let chain =
        |n: usize, defects: Vec<Defect>| Chain::paper(n).unwrap().with_defects(defects).unwrap();
    let masses = chain(
        10,
        vec![
            Defect::Mass { at: 3, m: 3.0 },
            Defect::Mass { at: 7, m: 0.5 },
        ],
    );
    let three = chain(
        12,
        vec![
            Defect::Mass { at: 2, m: 2.0 },
            Defect::Mass { at: 6, m: 0.6 },
            Defect::Mass { at: 9, m: 1.8 },
        ],
    );
    let mixed = chain(
        8,
        vec![
            Defect::Spring { at: 3, k: 0.5 },
            Defect::Mass { at: 6, m: 2.0 },
        ],
    );
    vec![
        (
            "two masses, 1%",
            record(&masses, 100.0, 0.25, 1e-2, 1),
            10,
            KindChoice::Mass,
        ),
        (
            "two masses, 0.1%",
            record(&masses, 100.0, 0.25, 1e-3, 2),
            10,
            KindChoice::Mass,
        ),
        (
            "three masses, 1%",
            record(&three, 120.0, 0.25, 1e-2, 3),
            12,
            KindChoice::Mass,
        ),
        (
            "spring and mass as mass, 1%",
            record(&mixed, 100.0, 0.25, 1e-2, 4),
            8,
            KindChoice::Mass,
        ),
        (
            "spring and mass, any kind, 1%",
            record(&mixed, 100.0, 0.25, 1e-2, 5),
            8,
            KindChoice::Any,
        ),
    ]
}

fn fit_auto(obs: &Observations, n: usize, kinds: KindChoice, defects: DefectCount) -> FitReport {
    let opts = FitOptions {
        defects,
        kinds,
        parallel: false,
        ..FitOptions::default()
    };
    fit(obs, &Model::new(n).unwrap(), &opts).unwrap()
}

#[test]
fn chi_square_never_rises_with_the_number_of_defects() {
    for (name, obs, n, kinds) in records() {
        let r = fit_auto(&obs, n, kinds, DefectCount::Auto { k_max: 4 });
        let rows = &r.k_selection;
        assert!(rows.len() >= 3, "{name}: {rows:?}");
        for w in rows.windows(2) {
            assert_eq!(w[1].k, w[0].k + 1, "{name}");
            assert!(
                w[1].chi2 <= w[0].chi2 * (1.0 + 1e-12),
                "{name}: chi2 at k = {} is {} above k = {}'s {}",
                w[1].k,
                w[1].chi2,
                w[0].k,
                w[0].chi2
            );
        }
    }
}

#[test]
fn noise_level_does_not_depend_on_the_largest_k_tried() {
    let mut compared = 0;
    for (name, obs, n, kinds) in records() {
        let all = fit_auto(&obs, n, kinds, DefectCount::Auto { k_max: 4 });
        let three = fit_auto(&obs, n, kinds, DefectCount::Auto { k_max: 3 });
        let k = all.defects.len();
        // where the white fit passes (else a record model is chosen from
        // the residual of the white fit's choice of k, which may differ)
        let white = |r: &FitReport| r.noise_model.as_ref().is_none_or(|m| m.iterations == 0);
        if !white(&all) || !white(&three) {
            continue;
        }
        {
            let given = fit_auto(&obs, n, kinds, DefectCount::Exactly(k));
            assert_eq!(given.noise_sigma, all.noise_sigma, "{name}: k = {k} given");
            for (a, b) in all.defects.iter().zip(&given.defects) {
                assert_eq!((a.at, a.value, a.se), (b.at, b.value, b.se), "{name}");
            }
        }
        if three.defects.len() == k {
            assert_eq!(three.noise_sigma, all.noise_sigma, "{name}: auto:3");
            compared += 1;
        }
    }
    assert!(compared >= 3, "{compared} records compared");
}
