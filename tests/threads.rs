//! The thread policy: the same answer, to the last bit, on one thread and
//! on two, for a small fit (one thread either way) and for one large
//! enough to be shared (over `search::parallel::MIN_SETS` position sets).

use springmass::detect::data::observations::{Observations, Series};
use springmass::detect::data::series::TimeData;
use springmass::detect::fit::{fit, DefectCount, FitOptions, FitReport, Model};
use springmass::detect::search::parallel::MIN_SETS;
use springmass::noise::NoiseLevel;
use springmass::{Chain, Defect};

fn on_threads(threads: usize, obs: &Observations, n: usize, k: usize) -> FitReport {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    let opts = FitOptions {
        defects: DefectCount::Exactly(k),
        ..FitOptions::default()
    };
    pool.install(|| fit(obs, &Model::new(n).unwrap(), &opts).unwrap())
}

fn bits(r: &FitReport) -> Vec<(usize, u64, u64)> {
    r.defects
        .iter()
        .map(|d| (d.at, d.value.to_bits(), d.se.to_bits()))
        .collect()
}

#[test]
fn one_thread_and_two_give_the_same_bits() {
    let cases = [
        (10, vec![(3, 3.0), (7, 0.5)]),
        (24, vec![(4, 2.5), (11, 0.6), (17, 1.8)]),
    ];
    for (n, defects) in cases {
        let truth = Chain::paper(n)
            .unwrap()
            .with_defects(defects.iter().map(|&(at, m)| Defect::Mass { at, m }))
            .unwrap();
        let d = TimeData::simulate(&truth, 150.0, 0.25, NoiseLevel::RelativeMax(1e-3), 7).unwrap();
        let obs = Observations::Series(Series::new(d.t().to_vec(), d.y().to_vec(), None).unwrap());
        let k = defects.len();
        let one = on_threads(1, &obs, n, k);
        let two = on_threads(2, &obs, n, k);
        assert_eq!(bits(&one), bits(&two), "n = {n}");
        assert_eq!(
            one.noise_sigma.to_bits(),
            two.noise_sigma.to_bits(),
            "n = {n}"
        );
        let found: Vec<usize> = one.defects.iter().map(|d| d.at).collect();
        let truth_at: Vec<usize> = defects.iter().map(|d| d.0).collect();
        assert_eq!(found, truth_at, "n = {n}");
    }
}

/// The second case of [`one_thread_and_two_give_the_same_bits`] is large
/// enough to be shared among threads.
const _: () = assert!(24 * 23 * 22 / 6 >= MIN_SETS);
