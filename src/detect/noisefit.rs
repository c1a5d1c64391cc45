//! Fitting defects to a noisy sampled series `y_i = x_1(t_i) + sigma z_i`, with
//! one of three misfits, and the pieces of the noise study.
//!
//! * [`MisfitChoice::RealAxis`]: the paper's residual on `[0, 300]` (80-node
//!   `gl-log` rule of [`crate::detect::quadrature`]), the data being the
//!   Laplace transform of the series ([`crate::time::series`]) at the nodes;
//! * [`MisfitChoice::Bromwich`]: the same on the line `s = sigma_B + i omega`,
//!   `omega in [0, W]` (default `sigma_B = 0.05`, a few over the record length
//!   `T = 200` so that the unrecorded tail weighs `e^{-sigma_B T}`; `W = 4`, above
//!   the chain's band `2 sqrt(k/mass)`), 80 nodes (`gl-uniform` 10x8);
//! * [`MisfitChoice::Time`]: the time-domain chi-square ([`TimeMisfit`]).
//!
//! Laplace misfits weight node `q` by `w_q / v_q`, with `w_q` the rule's weight
//! and `v_q` the variance of the transformed data (white noise through the
//! transform, `sigma^2 sum |w_i(s_q)|^2`, plus the squared error estimate of the
//! transform): the noise level belongs to the data.
//!
//! **Search.** Laplace misfits: every position set is fitted by
//! Levenberg-Marquardt over its masses (analytic Jacobian, O(k) per node)
//! for a few iterations from `m = 2`, the best `shortlist` sets are then fitted
//! to convergence from that point and from `m = 0.5`, and ranked. The time
//! misfit costs a modal decomposition per evaluation (about 1.5 ms for `n = 20`),
//! so it refines the Bromwich shortlist: each of its position sets is refitted
//! in the time domain and the sets are re-ranked by their time-domain
//! chi-square. Cost: `C(n, k)` short fits plus `shortlist` full fits.

use crate::chain::{Chain, Defect};
use crate::detect::chainfit::{fit_chain, LaplaceObs, Obs};
use crate::detect::identify::{identify, Alternative, FittedDefect, Identifiability};
use crate::detect::lsq::{levenberg_marquardt, LmOptions};
use crate::detect::misfit_time::{TimeData, TimeMisfit};
use crate::detect::quadrature::Rule;
use crate::error::{Error, Result};
use crate::sensitivity::Param;
use crate::time::series::{SeriesTransform, TransformOptions};
use num_complex::Complex64;
use serde::Serialize;

/// Which misfit.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub enum MisfitChoice {
    /// Paper's real-axis residual on `[0, 300]`.
    RealAxis,
    /// Bromwich line `sigma_B + i omega`.
    Bromwich,
    /// Time-domain chi-square.
    Time,
}

impl MisfitChoice {
    /// All three.
    pub const ALL: [MisfitChoice; 3] = [
        MisfitChoice::RealAxis,
        MisfitChoice::Bromwich,
        MisfitChoice::Time,
    ];

    /// `real`, `bromwich`, `time`.
    pub fn name(self) -> &'static str {
        match self {
            MisfitChoice::RealAxis => "real",
            MisfitChoice::Bromwich => "bromwich",
            MisfitChoice::Time => "time",
        }
    }

    /// Parse a name.
    ///
    /// # Errors
    /// [`Error::Parse`].
    pub fn parse(text: &str) -> Result<MisfitChoice> {
        match text.trim() {
            "real" => Ok(MisfitChoice::RealAxis),
            "bromwich" => Ok(MisfitChoice::Bromwich),
            "time" => Ok(MisfitChoice::Time),
            _ => Err(Error::parse(
                "misfit",
                text,
                "expected real, bromwich or time",
            )),
        }
    }
}

/// Settings of a noisy fit.
#[derive(Clone, Debug)]
pub struct Setup {
    /// Real-axis rule.
    pub real_rule: Rule,
    /// Bromwich abscissa `sigma_B`.
    pub bromwich_sigma: f64,
    /// Bromwich rule in `omega`.
    pub bromwich_rule: Rule,
    /// Mass bounds of the search.
    pub mass_bounds: (f64, f64),
    /// Sets kept after the coarse pass.
    pub shortlist: usize,
    /// Bromwich sets refitted in the time domain.
    pub time_shortlist: usize,
    /// LM iterations of the coarse pass.
    pub coarse_iter: usize,
    /// Weighting of the Laplace misfits (used by [`laplace_obs`]).
    pub weighting: crate::detect::whiten::Weighting,
}

impl Setup {
    /// Defaults (see the module docs): mass bounds `[0.1, 50]`, shortlist 8,
    /// time shortlist 5, 12 coarse iterations.
    ///
    /// # Errors
    /// Never in practice (fixed valid rules).
    pub fn new() -> Result<Setup> {
        Ok(Setup {
            real_rule: Rule::gauss_legendre_log(0.0, 300.0, 10, 8, 0.05)?,
            bromwich_sigma: 0.05,
            bromwich_rule: Rule::gauss_legendre_uniform(0.0, 4.0, 10, 8)?,
            mass_bounds: (0.1, 50.0),
            shortlist: 8,
            time_shortlist: 5,
            coarse_iter: 12,
            weighting: crate::detect::whiten::Weighting::default(),
        })
    }
}

/// Laplace data at the nodes of `choice` (real axis or Bromwich) from the
/// sampled series of `data`, weighted as `setup.weighting` says:
///
/// * [`Weighting::Diagonal`](crate::detect::whiten::Weighting::Diagonal): node
///   `q` by the rule's weight over the node's variance, `w_q / v_q` (not a
///   chi-square: the transformed noise is correlated between nodes);
/// * [`Weighting::Whitened`](crate::detect::whiten::Weighting::Whitened): the
///   full covariance of the transformed data
///   ([`SeriesTransform::data_covariance`], plus `(1e-15 |X(s_q)|)^2` on the
///   diagonal for the rounding of the model), whitened with the default
///   cutoff ([`crate::detect::whiten`]): `chi^2` with [`LaplaceObs::dof`]
///   degrees of freedom at the true chain.
///
/// # Errors
/// [`Error::InvalidParameter`] for [`MisfitChoice::Time`]; as [`SeriesTransform`].
pub fn laplace_obs(data: &TimeData, choice: MisfitChoice, setup: &Setup) -> Result<LaplaceObs> {
    let (s, w): (Vec<Complex64>, Vec<f64>) = match choice {
        MisfitChoice::RealAxis => (
            setup
                .real_rule
                .nodes
                .iter()
                .map(|&x| Complex64::new(x, 0.0))
                .collect(),
            setup.real_rule.weights.clone(),
        ),
        MisfitChoice::Bromwich => (
            setup
                .bromwich_rule
                .nodes
                .iter()
                .map(|&w| Complex64::new(setup.bromwich_sigma, w))
                .collect(),
            setup.bromwich_rule.weights.clone(),
        ),
        MisfitChoice::Time => {
            return Err(Error::invalid(
                "misfit",
                "time",
                "a Laplace misfit (real or bromwich)",
            ))
        }
    };
    let opts = TransformOptions {
        noise_sigma: Some(data.sigma()),
        ..TransformOptions::default()
    };
    let tr = SeriesTransform::new(data.t(), data.y(), &opts)?;
    let vals = tr.eval_many(&s)?;
    if setup.weighting == crate::detect::whiten::Weighting::Whitened {
        let mut cov = tr.data_covariance(&vals)?;
        for (r, (q, _)) in crate::time::series::stacked_rows(&s)
            .into_iter()
            .enumerate()
        {
            cov[(r, r)] += (1e-15 * vals[q].value.norm()).powi(2);
        }
        let wh =
            crate::detect::whiten::Whitening::new(&cov, crate::detect::whiten::DEFAULT_CUTOFF)?;
        let values = vals.iter().map(|v| v.value).collect();
        return LaplaceObs::whitened(s, values, wh.matrix().clone());
    }
    let mut values = Vec::with_capacity(s.len());
    let mut weights = Vec::with_capacity(s.len());
    for (v, wq) in vals.iter().zip(&w) {
        let var = v.noise_var.unwrap_or(0.0) + v.err * v.err;
        let var = var.max((1e-15 * v.value.norm()).powi(2)).max(1e-300);
        values.push(v.value);
        weights.push(wq / var);
    }
    LaplaceObs::new(s, values, weights)
}

/// One hypothesis: positions (sorted), fitted masses, chi-square.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Hypothesis {
    /// Positions, increasing.
    pub positions: Vec<usize>,
    /// Fitted masses, in the order of `positions`.
    pub masses: Vec<f64>,
    /// Misfit value.
    pub chi2: f64,
    /// Gauss-Newton standard errors of the masses (NaN when unconstrained).
    pub std_errors: Vec<f64>,
}

impl Hypothesis {
    /// The defects.
    pub fn defects(&self) -> Vec<Defect> {
        self.positions
            .iter()
            .zip(&self.masses)
            .map(|(&at, &m)| Defect::Mass { at, m })
            .collect()
    }

    /// Positions equal to those of `truth`'s mass defects and every mass within
    /// `rel` (relative).
    pub fn matches(&self, truth: &Chain, rel: f64) -> bool {
        let mut t: Vec<(usize, f64)> = truth
            .defects()
            .iter()
            .filter_map(|d| match *d {
                Defect::Mass { at, m } => Some((at, m)),
                _ => None,
            })
            .collect();
        t.sort_by_key(|x| x.0);
        t.len() == self.positions.len()
            && t.iter()
                .zip(self.positions.iter().zip(&self.masses))
                .all(|((ta, tm), (a, m))| ta == a && (m - tm).abs() <= rel * tm.abs())
    }

    /// Positions equal to those of `truth`'s mass defects.
    pub fn positions_match(&self, truth: &Chain) -> bool {
        let mut t: Vec<usize> = truth.defects().iter().map(|d| d.at()).collect();
        t.sort_unstable();
        t == self.positions
    }
}

/// All `k`-subsets of `1..=n`, increasing, in lexicographic order.
pub fn combinations(n: usize, k: usize) -> Vec<Vec<usize>> {
    let mut out = Vec::new();
    if k > n {
        return out;
    }
    let mut c: Vec<usize> = (1..=k).collect();
    loop {
        out.push(c.clone());
        let mut i = k;
        loop {
            if i == 0 {
                return out;
            }
            i -= 1;
            if c[i] < n - (k - 1 - i) {
                c[i] += 1;
                for j in i + 1..k {
                    c[j] = c[j - 1] + 1;
                }
                break;
            }
        }
    }
}

fn with_masses(base: &Chain, positions: &[usize], masses: &[f64]) -> Result<Chain> {
    base.uniform().with_defects(
        positions
            .iter()
            .zip(masses)
            .map(|(&at, &m)| Defect::Mass { at, m }),
    )
}

fn fit_set(
    base: &Chain,
    positions: &[usize],
    start: &[f64],
    obs: Obs<'_>,
    setup: &Setup,
    max_iter: usize,
) -> Result<Hypothesis> {
    let chain = with_masses(base, positions, start)?;
    let params = Param::defects(&chain);
    let problem = crate::detect::chainfit::ChainProblem::new(&chain, &params, obs)?;
    let bounds = vec![setup.mass_bounds; positions.len()];
    let opts = LmOptions {
        max_iter,
        ..LmOptions::default()
    };
    let lm = levenberg_marquardt(&problem, start, &bounds, &opts)?;
    let std_errors = match lm.std_errors() {
        Ok(v) => v,
        Err(_) => vec![f64::NAN; positions.len()],
    };
    Ok(Hypothesis {
        positions: positions.to_vec(),
        masses: lm.theta.clone(),
        chi2: lm.chi2,
        std_errors,
    })
}

fn rank(mut v: Vec<Hypothesis>) -> Vec<Hypothesis> {
    v.sort_by(|a, b| a.chi2.total_cmp(&b.chi2));
    v
}

/// Ranked hypotheses for `k` mass defects of `base` (its uniform part) against
/// Laplace observations (coarse pass over all sets, then the shortlist to
/// convergence). `k = 0` gives the uniform chain.
///
/// # Errors
/// `k > n` (field `k`); as the model.
pub fn enumerate_laplace(
    base: &Chain,
    obs: &LaplaceObs,
    k: usize,
    setup: &Setup,
) -> Result<Vec<Hypothesis>> {
    let n = base.n();
    if k > n {
        return Err(Error::invalid("k", k, format!("<= n = {n}")));
    }
    if k == 0 {
        let r = obs.residuals(&base.uniform())?;
        return Ok(vec![Hypothesis {
            positions: vec![],
            masses: vec![],
            chi2: r.iter().map(|v| v * v).sum(),
            std_errors: vec![],
        }]);
    }
    let sets = combinations(n, k);
    let coarse: Vec<Hypothesis> = sets
        .iter()
        .filter_map(|p| {
            fit_set(
                base,
                p,
                &vec![2.0; k],
                Obs::Laplace(obs),
                setup,
                setup.coarse_iter,
            )
            .ok()
        })
        .collect();
    let coarse = rank(coarse);
    let mut fine = Vec::new();
    for h in coarse.iter().take(setup.shortlist) {
        let a = fit_set(base, &h.positions, &h.masses, Obs::Laplace(obs), setup, 100);
        let b = fit_set(
            base,
            &h.positions,
            &vec![0.5; k],
            Obs::Laplace(obs),
            setup,
            100,
        );
        let best = match (a, b) {
            (Ok(a), Ok(b)) => {
                if b.chi2 < a.chi2 {
                    b
                } else {
                    a
                }
            }
            (Ok(a), Err(_)) => a,
            (Err(_), Ok(b)) => b,
            (Err(e), Err(_)) => return Err(e),
        };
        fine.push(best);
    }
    // the rest keep their coarse values (ranked after)
    let mut out = rank(fine);
    out.extend(coarse.into_iter().skip(setup.shortlist));
    Ok(out)
}

/// Refit each hypothesis of `shortlist` in the time domain (masses from its
/// values) and rank by the time-domain chi-square.
///
/// # Errors
/// As [`TimeMisfit`].
pub fn refine_time(
    base: &Chain,
    misfit: &TimeMisfit,
    shortlist: &[Hypothesis],
    setup: &Setup,
) -> Result<Vec<Hypothesis>> {
    let mut out = Vec::with_capacity(shortlist.len());
    for h in shortlist {
        if h.positions.is_empty() {
            let chi2 = misfit.chi2(&base.uniform())?;
            out.push(Hypothesis { chi2, ..h.clone() });
            continue;
        }
        out.push(fit_set(
            base,
            &h.positions,
            &h.masses,
            Obs::Time(misfit),
            setup,
            100,
        )?);
    }
    Ok(rank(out))
}

/// Fit `k` mass defects to the noisy series `data` with the chosen misfit;
/// returns the ranked hypotheses (best first).
///
/// # Errors
/// As [`laplace_obs`], [`enumerate_laplace`], [`refine_time`].
pub fn fit_noisy(
    base: &Chain,
    data: &TimeData,
    k: usize,
    choice: MisfitChoice,
    setup: &Setup,
) -> Result<Vec<Hypothesis>> {
    match choice {
        MisfitChoice::RealAxis | MisfitChoice::Bromwich => {
            let obs = laplace_obs(data, choice, setup)?;
            enumerate_laplace(base, &obs, k, setup)
        }
        MisfitChoice::Time => {
            let obs = laplace_obs(data, MisfitChoice::Bromwich, setup)?;
            let ranked = enumerate_laplace(base, &obs, k, setup)?;
            time_from_bromwich(base, data, &ranked, setup)
        }
    }
}

/// The time-domain ranking from a Bromwich ranking (its first
/// `setup.time_shortlist` sets refitted by [`refine_time`]).
///
/// # Errors
/// As [`refine_time`].
pub fn time_from_bromwich(
    base: &Chain,
    data: &TimeData,
    bromwich: &[Hypothesis],
    setup: &Setup,
) -> Result<Vec<Hypothesis>> {
    let n = setup.time_shortlist.min(bromwich.len());
    refine_time(base, &TimeMisfit::new(data.clone()), &bromwich[..n], setup)
}

/// The identifiability report of a ranked list (best first), for the data's
/// noise level `sigma` (see [`crate::detect::identify`]). `uniform` is the
/// uniform mass.
///
/// # Errors
/// An empty list; as [`identify`].
pub fn identify_ranked(
    ranked: &[Hypothesis],
    uniform: f64,
    sigma: f64,
    threshold: Option<f64>,
) -> Result<Identifiability> {
    let best = ranked
        .first()
        .ok_or_else(|| Error::invalid("ranked", 0, "at least one hypothesis"))?;
    let defects: Vec<FittedDefect> = best
        .positions
        .iter()
        .zip(&best.masses)
        .zip(&best.std_errors)
        .map(|((&at, &value), &std_error)| FittedDefect {
            at,
            value,
            std_error,
            uniform,
        })
        .collect();
    let alts: Vec<Alternative> = ranked[1..]
        .iter()
        .map(|h| Alternative {
            positions: h.positions.clone(),
            chi2: h.chi2,
        })
        .collect();
    identify(&defects, best.chi2, &alts, sigma, threshold)
}

/// Fit the chain's damping `d` (and the masses) at the positions of `hyp` in
/// the time domain; returns the report (values: masses then `d`).
///
/// # Errors
/// As [`fit_chain`].
pub fn fit_damping(
    base: &Chain,
    data: &TimeData,
    hyp: &Hypothesis,
) -> Result<crate::detect::chainfit::ChainFitReport> {
    let chain = with_masses(base, &hyp.positions, &hyp.masses)?;
    let mut params = Param::defects(&chain);
    params.push(Param::D);
    let misfit = TimeMisfit::new(data.clone());
    fit_chain(&chain, &params, &Obs::Time(&misfit), None)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::noise::NoiseLevel;

    #[test]
    fn combinations_count_and_order() {
        assert_eq!(combinations(5, 2).len(), 10);
        assert_eq!(combinations(20, 3).len(), 1140);
        assert_eq!(combinations(3, 3), vec![vec![1, 2, 3]]);
        assert_eq!(combinations(3, 0), vec![Vec::<usize>::new()]);
        assert!(combinations(2, 3).is_empty());
        let c = combinations(6, 3);
        assert!(c.windows(2).all(|w| w[0] < w[1]));
    }

    #[test]
    fn system1_with_noise_every_misfit() {
        let truth = Chain::paper(5)
            .unwrap()
            .with_defects([
                Defect::Mass { at: 2, m: 3.0 },
                Defect::Mass { at: 4, m: 0.5 },
            ])
            .unwrap();
        let data =
            TimeData::simulate(&truth, 200.0, 0.2, NoiseLevel::RelativeMax(1e-3), 3).unwrap();
        let setup = Setup::new().unwrap();
        for choice in [MisfitChoice::Bromwich, MisfitChoice::Time] {
            let r = fit_noisy(&truth.uniform(), &data, 2, choice, &setup).unwrap();
            assert!(r[0].matches(&truth, 0.05), "{choice:?}: {:?}", r[0]);
        }
        // the real axis cannot see the light mass at 4 through 1e-3 noise
        // (NOTES.md): its best set has a chi-square no worse than the truth's
        let obs = laplace_obs(&data, MisfitChoice::RealAxis, &setup).unwrap();
        let r = enumerate_laplace(&truth.uniform(), &obs, 2, &setup).unwrap();
        let t: f64 = obs.residuals(&truth).unwrap().iter().map(|v| v * v).sum();
        eprintln!("real axis: best {:?}, truth chi2 {t}", r[0]);
        assert!(r[0].chi2 <= t * (1.0 + 1e-9));
    }
}
