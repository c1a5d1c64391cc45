//! Fitting defects to a user's observations: `fit(&Observations, &Model,
//! &FitOptions) -> FitReport`.
//!
//! The data come first ([`crate::detect::data::observations`]): a sampled
//! record of the observed mass, or Laplace values; nothing here knows a
//! truth. The [`Model`] says what is known of the chain (n, k, d, gamma,
//! uniform mass, known defects) and which chain parameters to fit; the
//! [`FitOptions`] say what to look for and how:
//!
//! * **misfit** ([`MisfitKind`]): for a sampled series the default is the
//!   time-domain chi-square (`time`): in the 20-seed noise study it recovers
//!   both positions and values most often at every noise level (at 1% noise
//!   S3: 0.70 against 0.45 for the Bromwich line and 0.00 for the real axis,
//!   see `docs/noise-study.md`); its shortlist comes from the whitened
//!   Bromwich chi-square. `bromwich` and `real-axis` are the whitened
//!   Laplace chi-squares of the transformed series ([`general::laplace_obs`]).
//!   For Laplace values the misfit is the chi-square at the given nodes.
//! * **noise** ([`NoiseSpec`]): given, or estimated (`auto`): a first guess
//!   from the record's finest scales ([`noise::high_frequency_sigma`]), then
//!   the best fit's residual `sqrt(RSS / (N - p))` ([`noise::residual_sigma`]),
//!   refitting when the two differ by more than a factor 2. Standard errors
//!   are then those of the estimated sigma.
//! * **number of defects** ([`DefectCount`]): given, or `auto`: every `k` in
//!   `0..=k_max` is fitted and the criterion ([`Criterion`], BIC by default)
//!   chooses; the table is in the report.
//! * **kinds** ([`KindChoice`]): mass, spring, damper or any.
//! * **method** ([`FitMethod`]): `enumerate` (every position set, values by
//!   bounded Levenberg-Marquardt) works for every kind; `greedy`
//!   ([`crate::detect::search::greedy`]: one defect at a time, candidates
//!   scored by rank-one updates, then moves, restarts) too, for long chains
//!   and many defects; `ga`, `nelder-mead` and `pso` search mass defects
//!   (and refuse other kinds with a typed error); their best position set is
//!   then refitted like enumeration's.
//!
//! ```
//! use springmass::{Chain, Defect, noise::NoiseLevel};
//! use springmass::detect::data::observations::{Observations, Series};
//! use springmass::detect::fit::{fit, DefectCount, FitOptions, Model};
//! // a "measured" record (here simulated with 0.1% noise; the fit is not told)
//! let truth = Chain::paper(6)?.with_defect(Defect::Mass { at: 3, m: 3.0 })?;
//! let rec = springmass::detect::data::series::TimeData::simulate(&truth, 100.0, 0.25, NoiseLevel::RelativeMax(1e-3), 1)?;
//! let obs = Observations::Series(Series::new(rec.t().to_vec(), rec.y().to_vec(), None)?);
//! let report = fit(&obs, &Model::new(6)?, &FitOptions { defects: DefectCount::Exactly(1), ..FitOptions::default() })?;
//! assert_eq!(report.defects[0].at, 3);
//! assert!((report.defects[0].value - 3.0).abs() < 4.0 * report.defects[0].se);
//! assert!(report.noise_estimated);
//! # Ok::<(), springmass::Error>(())
//! ```

pub mod chainfit;
pub mod general;
pub mod identify;
pub mod noise;
pub mod options;
pub mod paper;
pub mod report;
pub mod select;

pub use crate::detect::search::FitMethod;
pub use report::{
    Alternative, DefectEstimate, FitReport, KRow, ModeEstimate, ParamEstimate, Predicted, Status,
};
pub use select::Criterion;

use crate::chain::{Boundary, Chain, Defect};
use crate::detect::data::laplace::LaplaceObs;
use crate::detect::data::observations::{Observations, Series};
use crate::detect::fit::chainfit::{default_bounds, fit_chain, Obs};
use crate::detect::fit::general::{
    fit_general, identify_general, laplace_obs, GeneralOptions, Hypothesis, Setup,
};
use crate::detect::misfit::quadrature::Rule;
use crate::detect::misfit::time::TimeMisfit;
use crate::detect::misfit::MisfitKind;
use crate::detect::search::{minimize, Candidate, Objective, SearchOptions, Space};
use crate::detect::unknowns::{DefectKind, KindBounds, KindChoice, Slot, Unknowns};
use crate::error::{Error, Result};
use crate::sensitivity::Param;
use serde::Serialize;
use std::time::Instant;

/// What is known of the chain, and which of its uniform parameters to fit.
#[derive(Clone, Debug, PartialEq)]
pub struct Model {
    chain: Chain,
    fit: Vec<Param>,
}

impl Model {
    /// The paper's chain of `n` masses (k = 1, d = 0.1, gamma = 1, mass 1),
    /// nothing fitted but the defects.
    ///
    /// # Errors
    /// `n = 0` or too large (field `n`).
    pub fn new(n: usize) -> Result<Model> {
        Ok(Model {
            chain: Chain::paper(n)?,
            fit: Vec::new(),
        })
    }

    /// The uniform parameters of `chain`; its defects become known defects.
    pub fn from_chain(chain: &Chain) -> Model {
        Model {
            chain: chain.clone(),
            fit: Vec::new(),
        }
    }

    /// Damping `d` (a starting value when fitted).
    ///
    /// # Errors
    /// As [`Chain::with_d`].
    pub fn with_d(mut self, d: f64) -> Result<Model> {
        self.chain = self.chain.with_d(d)?;
        Ok(self)
    }

    /// Uniform stiffness `k` (the data's units: N/m for SI data).
    ///
    /// # Errors
    /// As [`Chain::with_k`].
    pub fn with_k(mut self, k: f64) -> Result<Model> {
        self.chain = self.chain.with_k(k)?;
        Ok(self)
    }

    /// Uniform mass (the data's units: kg for SI data).
    ///
    /// # Errors
    /// As [`Chain::with_mass`].
    pub fn with_mass(mut self, mass: f64) -> Result<Model> {
        self.chain = self.chain.with_mass(mass)?;
        Ok(self)
    }

    /// Impulse `gamma`.
    ///
    /// # Errors
    /// As [`Chain::with_gamma`].
    pub fn with_gamma(mut self, gamma: f64) -> Result<Model> {
        self.chain = self.chain.with_gamma(gamma)?;
        Ok(self)
    }

    /// The ends of the chain: each fixed to a wall or free (a shear frame
    /// seen from its roof is `Free, Fixed`).
    ///
    /// # Errors
    /// As [`Chain::with_boundaries`].
    pub fn with_ends(mut self, left: Boundary, right: Boundary) -> Result<Model> {
        self.chain = self.chain.with_boundaries(left, right)?;
        Ok(self)
    }

    /// A known defect.
    ///
    /// # Errors
    /// As [`Chain::with_defect`].
    pub fn with_known(mut self, defect: Defect) -> Result<Model> {
        self.chain = self.chain.with_defect(defect)?;
        Ok(self)
    }

    /// Fit these chain parameters too (`D`, `Gamma`, `K`, `Mass`; at most three).
    ///
    /// # Errors
    /// A defect parameter, a repeat, or all four (field `fit`).
    pub fn fitting(mut self, params: &[Param]) -> Result<Model> {
        for (i, p) in params.iter().enumerate() {
            if matches!(p, Param::Defect(_)) || params[..i].contains(p) {
                return Err(Error::invalid(
                    "fit",
                    format!("{p:?}"),
                    "distinct names among d, gamma, k, mass",
                ));
            }
        }
        if params.len() == 4 {
            return Err(Error::invalid(
                "fit",
                "d, gamma, k, mass",
                "at most three: scaling every mass, spring, damper and gamma together leaves x_1(t) unchanged",
            ));
        }
        self.fit = params.to_vec();
        Ok(self)
    }

    /// The chain (uniform parameters and known defects).
    pub fn chain(&self) -> &Chain {
        &self.chain
    }

    /// Chain parameters fitted.
    pub fn fitted(&self) -> &[Param] {
        &self.fit
    }

    /// Number of masses.
    pub fn n(&self) -> usize {
        self.chain.n()
    }
}

/// Parse `d,gamma,k,mass` (any subset, comma separated) into chain parameters.
///
/// # Errors
/// An unknown name (field `fit`).
pub fn parse_params(text: &str) -> Result<Vec<Param>> {
    text.split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| match s {
            "d" => Ok(Param::D),
            "gamma" => Ok(Param::Gamma),
            "k" => Ok(Param::K),
            "mass" => Ok(Param::Mass),
            _ => Err(Error::invalid(
                "fit",
                s,
                "a comma-separated list of d, gamma, k, mass",
            )),
        })
        .collect()
}

/// How many defects to look for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum DefectCount {
    /// Exactly this many.
    Exactly(usize),
    /// Choose among `0..=k_max` by the criterion.
    Auto {
        /// Largest number tried.
        k_max: usize,
    },
}

impl DefectCount {
    /// `auto` (k_max 4, or n when smaller), `auto:K`, or a number.
    ///
    /// # Errors
    /// [`Error::Parse`] naming the forms.
    pub fn parse(text: &str) -> Result<DefectCount> {
        let t = text.trim();
        let bad = || {
            Error::parse(
                "defects",
                text,
                "expected auto, auto:K_MAX or a number of defects",
            )
        };
        if t == "auto" {
            return Ok(DefectCount::Auto {
                k_max: DEFAULT_K_MAX,
            });
        }
        if let Some(k) = t.strip_prefix("auto:") {
            return Ok(DefectCount::Auto {
                k_max: k.parse().map_err(|_| bad())?,
            });
        }
        t.parse().map(DefectCount::Exactly).map_err(|_| bad())
    }
}

/// Default largest number of defects tried by `defects = auto`.
pub const DEFAULT_K_MAX: usize = 4;

/// The noise level of the data.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub enum NoiseSpec {
    /// Estimate it (see the module docs).
    Auto,
    /// Known standard deviation of the samples (absolute).
    Sigma(f64),
}

impl NoiseSpec {
    /// `auto` or a positive number.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming `noise`.
    pub fn parse(text: &str) -> Result<NoiseSpec> {
        let t = text.trim();
        if t == "auto" {
            return Ok(NoiseSpec::Auto);
        }
        let v: f64 = t
            .parse()
            .map_err(|_| Error::invalid("noise", t, "auto or a standard deviation > 0"))?;
        if !(v.is_finite() && v > 0.0) {
            return Err(Error::invalid(
                "noise",
                t,
                "auto or a finite standard deviation > 0",
            ));
        }
        Ok(NoiseSpec::Sigma(v))
    }
}

/// What to look for and how (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct FitOptions {
    /// Number of defects (default `auto`, `k_max = 4`).
    pub defects: DefectCount,
    /// Their kinds (default mass).
    pub kinds: KindChoice,
    /// One kind per free defect, overriding `kinds` (empty: every defect of
    /// kind `kinds`); needs `defects` = exactly that many.
    pub slot_kinds: Vec<KindChoice>,
    /// Noise level (default estimated).
    pub noise: NoiseSpec,
    /// Misfit (default: `time` for a series, the nodes' chi-square for Laplace values).
    pub misfit: Option<MisfitKind>,
    /// Search (default enumeration).
    pub method: FitMethod,
    /// Criterion of `defects = auto` (default BIC).
    pub criterion: Criterion,
    /// Seed of the stochastic searches.
    pub seed: u64,
    /// Evaluation budget of the stochastic searches (default 20 000).
    pub max_evals: usize,
    /// Alternatives reported (default 5).
    pub alternatives: usize,
    /// Fit hypotheses in parallel; the result does not depend on it.
    pub parallel: bool,
    /// Largest number of hypotheses enumerated (default 200 000).
    pub max_sets: usize,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            defects: DefectCount::Auto {
                k_max: DEFAULT_K_MAX,
            },
            kinds: KindChoice::Mass,
            slot_kinds: Vec::new(),
            noise: NoiseSpec::Auto,
            misfit: None,
            method: FitMethod::Enumerate,
            criterion: Criterion::Bic,
            seed: 0,
            max_evals: 20_000,
            alternatives: 5,
            parallel: true,
            max_sets: 200_000,
        }
    }
}

impl FitOptions {
    /// Check the options against the model and the data, before any work.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming `defects` (k > n), `k_max`
    /// (k_max > n), `method` (a stochastic search for other kinds than mass
    /// or with chain parameters fitted), `misfit` (`time` with Laplace values),
    /// `max_evals` (0), `max_sets` (0).
    pub fn validate(&self, obs: &Observations, model: &Model) -> Result<()> {
        let n = model.n();
        match self.defects {
            DefectCount::Exactly(k) if k > n => {
                return Err(Error::invalid("defects", k, format!("<= n = {n}")))
            }
            DefectCount::Auto { k_max } if k_max > n => {
                return Err(Error::invalid("k_max", k_max, format!("<= n = {n}")))
            }
            _ => {}
        }
        if !self.slot_kinds.is_empty()
            && self.defects != DefectCount::Exactly(self.slot_kinds.len())
        {
            return Err(Error::invalid(
                "kinds",
                format!("{} kinds", self.slot_kinds.len()),
                "one kind per defect: as many kinds as defects, with a given number of defects",
            ));
        }
        let all_mass = self.kinds == KindChoice::Mass
            && self.slot_kinds.iter().all(|k| *k == KindChoice::Mass);
        if !matches!(self.method, FitMethod::Enumerate | FitMethod::Greedy)
            && (!all_mass || !model.fit.is_empty())
        {
            return Err(Error::invalid(
                "method",
                self.method.name(),
                "enumerate or greedy for spring, damper or any-kind defects and for fitted chain parameters (ga, nelder-mead and pso search mass defects only)",
            ));
        }
        if self.method == FitMethod::Greedy && self.slot_kinds.windows(2).any(|w| w[0] != w[1]) {
            return Err(Error::invalid(
                "kinds",
                "a different kind per defect",
                "one kind for every defect with the greedy search (or the enumeration)",
            ));
        }
        match obs {
            Observations::Series(s) => s.measurement().sensor().check(n)?,
            Observations::Laplace(l) => l.sensor().check(n)?,
        }
        if matches!(obs, Observations::Laplace(_)) && self.misfit == Some(MisfitKind::Time) {
            return Err(Error::invalid(
                "misfit",
                "time",
                "real-axis or bromwich for Laplace values (the time misfit needs a sampled series)",
            ));
        }
        if self.max_evals == 0 {
            return Err(Error::invalid("max_evals", 0, ">= 1"));
        }
        if self.max_sets == 0 {
            return Err(Error::invalid("max_sets", 0, ">= 1"));
        }
        Ok(())
    }
}

/// Fit defects to `obs` (see the module docs).
///
/// # Errors
/// Invalid options ([`FitOptions::validate`]); too many hypotheses
/// (`max_sets`); a numerical failure of every hypothesis.
pub fn fit(obs: &Observations, model: &Model, opts: &FitOptions) -> Result<FitReport> {
    opts.validate(obs, model)?;
    let t0 = Instant::now();
    let misfit = match obs {
        Observations::Series(_) => opts.misfit.unwrap_or(MisfitKind::Time),
        Observations::Laplace(l) => {
            if l.s().iter().all(|z| z.im == 0.0) {
                MisfitKind::RealAxis
            } else {
                MisfitKind::Bromwich
            }
        }
    };
    let ks: Vec<usize> = match opts.defects {
        DefectCount::Exactly(k) => vec![k],
        DefectCount::Auto { k_max } => (0..=k_max).collect(),
    };
    let engine = Engine {
        obs,
        model,
        opts,
        misfit,
        prepared: std::sync::Mutex::new(None),
    };
    // the noise level: given, or a first guess then the residual estimate
    let (mut sigma, estimated) = match (obs, opts.noise) {
        (_, NoiseSpec::Sigma(s)) => (s, false),
        (Observations::Series(s), NoiseSpec::Auto) => {
            let hf = noise::high_frequency_sigma(s.x());
            (hf.max(1e-12 * s.max_abs()).max(1e-300), true)
        }
        (Observations::Laplace(_), NoiseSpec::Auto) => (1.0, true),
    };
    let mut evaluations = 0;
    let mut fits: Vec<KFit> = Vec::with_capacity(ks.len());
    for &k in &ks {
        let f = engine.fit_k(k, sigma)?;
        evaluations += f.evaluations;
        fits.push(f);
        if let DefectCount::Auto { .. } = opts.defects {
            if stop_early(&fits, obs.len()) {
                break;
            }
        }
    }
    // the estimate of sigma from the largest model fitted (it holds every
    // defect the others hold), then the final chi-squares at that sigma
    if estimated {
        let largest = fits.last().expect("at least one k");
        let s_hat = largest.sigma_hat;
        if s_hat > 0.0 && !(0.5..=2.0).contains(&(s_hat / sigma)) {
            sigma = s_hat;
            let mut refit = Vec::with_capacity(fits.len());
            for f in &fits {
                let g = engine.fit_k(f.k, sigma)?;
                evaluations += g.evaluations;
                refit.push(g);
            }
            fits = refit;
        }
        sigma = fits
            .last()
            .expect("at least one k")
            .sigma_hat
            .max(f64::MIN_POSITIVE);
    }
    // choose k
    let n_data = fits[0].n_data;
    let (chosen, rows, criterion_name) = if fits.len() == 1 {
        (
            0,
            vec![krow(&fits[0], sigma, estimated, f64::NAN)],
            "given".to_string(),
        )
    } else {
        let mf: Vec<select::ModelFit> = fits
            .iter()
            .map(|f| select::ModelFit::new(f.k, f.chi2_at(sigma, estimated), f.params))
            .collect();
        let sel = select::select(&mf, n_data, opts.criterion)?;
        let value = |e: &select::Evidence| match opts.criterion {
            Criterion::Aic => e.aic,
            Criterion::Bic => e.bic,
            Criterion::ChiSquare { .. } => e.p_value,
        };
        let rows = fits
            .iter()
            .zip(&sel.evidence)
            .map(|(f, e)| krow(f, sigma, estimated, value(e)))
            .collect();
        let i = fits
            .iter()
            .position(|f| f.k == sel.chosen)
            .expect("chosen among the fits");
        let name = match opts.criterion {
            Criterion::Aic => "aic",
            Criterion::Bic => "bic",
            Criterion::ChiSquare { .. } => "chi2 p-value",
        };
        (i, rows, name.to_string())
    };
    let best_fit = &fits[chosen];
    engine.report(
        best_fit,
        sigma,
        estimated,
        rows,
        criterion_name,
        evaluations,
        t0,
    )
}

/// Stop the `auto` loop when two more defects in a row have not lowered the
/// time-domain residual by more than noise would (a BIC step of `2 ln N`
/// per defect at the current noise estimate).
fn stop_early(fits: &[KFit], n: usize) -> bool {
    if fits.len() < 3 {
        return false;
    }
    let s = fits[fits.len() - 1].sigma_hat.max(f64::MIN_POSITIVE);
    let pen = 2.0 * (n as f64).ln();
    let c = |f: &KFit| f.rss / (s * s);
    let a = &fits[fits.len() - 3];
    let b = &fits[fits.len() - 2];
    let l = &fits[fits.len() - 1];
    c(a) - c(b) < pen && c(b) - c(l) < pen
}

fn krow(f: &KFit, sigma: f64, estimated: bool, criterion: f64) -> KRow {
    KRow {
        k: f.k,
        chi2: f.chi2_at(sigma, estimated),
        params: f.params,
        criterion,
        positions: f.ranked.first().map(|h| h.positions()).unwrap_or_default(),
    }
}

/// The best fits with `k` defects at one noise level.
struct KFit {
    k: usize,
    /// Position (and kind) sets fitted.
    hypotheses: usize,
    ranked: Vec<Hypothesis>,
    evaluations: usize,
    /// Residual sum of squares of the best fit in the time domain (series),
    /// or its unweighted Laplace chi-square (Laplace values without errors).
    rss: f64,
    /// Data points behind `rss`.
    n_data: usize,
    /// Free parameters (2 per defect of unknown position, 1 per known position, chain parameters).
    params: usize,
    /// `sqrt(rss / (n_data - params))`.
    sigma_hat: f64,
    /// The misfit's own chi-square and dof at the sigma of the fit.
    chi2: f64,
    /// The noise level the fit was made at.
    sigma_fit: f64,
    dof: usize,
    misfit_name: String,
    method_name: String,
    budget_exhausted: bool,
    predicted: Option<(Vec<f64>, Vec<f64>)>,
}

impl KFit {
    /// The chi-square used to compare numbers of defects: the time-domain
    /// `RSS / sigma^2` for series data, the misfit's own otherwise.
    fn chi2_at(&self, sigma: f64, estimated: bool) -> f64 {
        if estimated || self.predicted.is_some() {
            self.rss / (sigma * sigma)
        } else {
            self.chi2
        }
    }
}

struct Engine<'a> {
    obs: &'a Observations,
    model: &'a Model,
    opts: &'a FitOptions,
    misfit: MisfitKind,
    /// The observations prepared at the last noise level (the transform,
    /// its covariance and whitening do not depend on k).
    prepared: std::sync::Mutex<Option<(u64, Prepared)>>,
}

/// The coarse (Laplace) and fine (time) observations, the misfit's name and
/// the Laplace setup.
type Prepared = (LaplaceObs, Option<TimeMisfit>, String, Setup);

/// The Laplace setup for a record: the Bromwich line's abscissa a few over
/// the record length (the unrecorded tail weighs `e^{-10}`), its range above
/// the chain's band.
fn setup_for(series: Option<&Series>, model: &Model) -> Result<Setup> {
    let mut setup = Setup::new()?;
    if let Some(s) = series {
        let t_end = *s.t().last().expect("validated, non-empty");
        setup.bromwich_sigma = (10.0 / t_end).max(0.05);
    }
    let c = model.chain();
    let band = 2.0 * (c.k() / c.mass()).sqrt();
    let w = (2.0 * band).max(4.0);
    if (w - 4.0).abs() > 1e-12 {
        setup.bromwich_rule = Rule::gauss_legendre_uniform(0.0, w, 10, 8)?;
    }
    Ok(setup)
}

impl Engine<'_> {
    fn unknowns(&self, k: usize) -> Result<Option<Unknowns>> {
        let known = self.model.chain.defects();
        if k == 0 && known.is_empty() {
            return Ok(None);
        }
        let mut slots: Vec<Slot> = known
            .iter()
            .map(|d| Slot {
                kind: match DefectKind::of(d) {
                    DefectKind::Mass => KindChoice::Mass,
                    DefectKind::Spring => KindChoice::Spring,
                    DefectKind::Damper => KindChoice::Damper,
                },
                at: Some(d.at()),
                known: Some(d.value()),
                bounds: None,
            })
            .collect();
        if self.opts.slot_kinds.len() == k && k > 0 {
            slots.extend(self.opts.slot_kinds.iter().map(|&kind| Slot::free(kind)));
        } else {
            slots.extend((0..k).map(|_| Slot::free(self.opts.kinds)));
        }
        Ok(Some(Unknowns::new(
            self.model.n(),
            slots,
            self.model.fit.clone(),
            KindBounds::for_chain(&self.model.chain),
        )?))
    }

    /// Observations in the forms the misfits use, at noise level `sigma`.
    fn prepared(&self, sigma: f64) -> Result<Prepared> {
        let key = sigma.to_bits();
        if let Ok(guard) = self.prepared.lock() {
            if let Some((k, p)) = guard.as_ref() {
                if *k == key {
                    return Ok(p.clone());
                }
            }
        }
        let p = self.prepare(sigma)?;
        if let Ok(mut guard) = self.prepared.lock() {
            *guard = Some((key, p.clone()));
        }
        Ok(p)
    }

    fn prepare(&self, sigma: f64) -> Result<Prepared> {
        match self.obs {
            Observations::Series(s) => {
                let setup = setup_for(Some(s), self.model)?;
                let td = s.time_data(sigma)?;
                // the time misfit refines a shortlist of the Bromwich line's
                let coarse_kind = match self.misfit {
                    MisfitKind::Time => MisfitKind::Bromwich,
                    laplace => laplace,
                };
                let coarse = laplace_obs(&td, coarse_kind, &setup)?;
                let name = match self.misfit {
                    MisfitKind::Time => format!(
                        "time (chi-square of {} samples; shortlist from the whitened Bromwich line, sigma_B = {})",
                        td.len(),
                        setup.bromwich_sigma
                    ),
                    MisfitKind::Bromwich => format!(
                        "bromwich (whitened chi-square, sigma_B = {}, {} dof)",
                        setup.bromwich_sigma,
                        coarse.dof()
                    ),
                    laplace => format!(
                        "{} (whitened chi-square, {} dof)",
                        laplace.name(),
                        coarse.dof()
                    ),
                };
                let fine = (self.misfit == MisfitKind::Time).then(|| TimeMisfit::new(td));
                Ok((coarse, fine, name, setup))
            }
            Observations::Laplace(l) => {
                let w: Vec<f64> = match l.sigma() {
                    Some(sg) => sg.iter().map(|v| 1.0 / (v * v)).collect(),
                    None => vec![1.0 / (sigma * sigma); l.s().len()],
                };
                let obs = LaplaceObs::new(l.s().to_vec(), l.values().to_vec(), w)?
                    .with_measurement(l.sensor(), None)?;
                let name = format!(
                    "{} (chi-square at {} given nodes)",
                    self.misfit.name(),
                    l.s().len()
                );
                Ok((obs, None, name, setup_for(None, self.model)?))
            }
        }
    }

    fn fit_k(&self, k: usize, sigma: f64) -> Result<KFit> {
        let (coarse, fine, misfit_name, setup) = self.prepared(sigma)?;
        let chain_bounds = default_bounds(&self.model.chain, &self.model.fit);
        let known_positions = self.model.chain.defects().len();
        let mut budget_exhausted = false;
        let mut method_name = self.opts.method.name().to_string();
        let mut hypotheses = 1;
        let (ranked, evaluations) = match self.unknowns(k)? {
            None => {
                // the uniform chain, chain parameters fitted if any
                let obs = match &fine {
                    Some(t) => Obs::Time(t),
                    None => Obs::Laplace(&coarse),
                };
                let base = self.model.chain.uniform();
                if self.model.fit.is_empty() {
                    let r = match obs {
                        Obs::Time(t) => t.residuals(&base)?,
                        Obs::Laplace(l) => l.residuals(&base)?,
                    };
                    (
                        vec![Hypothesis::from_parts(
                            Vec::new(),
                            Vec::new(),
                            Vec::new(),
                            r.iter().map(|v| v * v).sum(),
                        )],
                        1,
                    )
                } else {
                    let f = fit_chain(&base, &self.model.fit, &obs, Some(&chain_bounds))?;
                    let params = f
                        .names
                        .iter()
                        .zip(&f.values)
                        .zip(&f.std_errors)
                        .map(|((name, &value), &std_error)| general::FittedParam {
                            name: name.clone(),
                            value,
                            std_error,
                        })
                        .collect();
                    (
                        vec![Hypothesis::from_parts(
                            Vec::new(),
                            Vec::new(),
                            params,
                            f.lm.chi2,
                        )],
                        f.lm.evaluations,
                    )
                }
            }
            Some(unknowns) => {
                let gopts = GeneralOptions {
                    parallel: self.opts.parallel,
                    max_sets: self.opts.max_sets,
                    ..GeneralOptions::default()
                };
                let mut setup = setup;
                setup.shortlist = setup.shortlist.max(self.opts.alternatives + 1);
                if self.opts.method == FitMethod::Enumerate || k == 0 {
                    method_name = "enumerate".into();
                    let g = fit_general(
                        &self.model.chain,
                        &unknowns,
                        &coarse,
                        fine.as_ref(),
                        &setup,
                        &gopts,
                    )?;
                    hypotheses = g.hypotheses;
                    (g.ranked, g.evaluations)
                } else if self.opts.method == FitMethod::Greedy {
                    // greedy search with moves (search::greedy)
                    let g = crate::detect::search::greedy::fit_greedy(
                        &self.model.chain,
                        &unknowns,
                        &coarse,
                        fine.as_ref(),
                        &setup,
                        &crate::detect::search::greedy::GreedyOptions {
                            parallel: self.opts.parallel,
                            ..Default::default()
                        },
                    )?;
                    hypotheses = g.hypotheses;
                    (g.ranked, g.evaluations + g.scored)
                } else {
                    let (positions, evals, exhausted) = self.stochastic(k, &coarse)?;
                    budget_exhausted = exhausted;
                    // refit the best set and its neighbours like enumeration
                    let mut sets = vec![positions.clone()];
                    for i in 0..positions.len() {
                        for delta in [-1i64, 1] {
                            let p = positions[i] as i64 + delta;
                            if p >= 1
                                && p as usize <= self.model.n()
                                && !positions.contains(&(p as usize))
                            {
                                let mut q = positions.clone();
                                q[i] = p as usize;
                                q.sort_unstable();
                                if !sets.contains(&q)
                                    && !q.iter().any(|x| {
                                        self.model.chain.defects().iter().any(|d| d.at() == *x)
                                    })
                                {
                                    sets.push(q);
                                }
                            }
                        }
                    }
                    let mut all = Vec::new();
                    let mut spent = evals;
                    hypotheses = sets.len();
                    for q in sets {
                        let mut slots = unknowns.slots().to_vec();
                        for (slot, &at) in slots[known_positions..].iter_mut().zip(&q) {
                            slot.at = Some(at);
                        }
                        let u = Unknowns::new(
                            self.model.n(),
                            slots,
                            self.model.fit.clone(),
                            KindBounds::for_chain(&self.model.chain),
                        )?;
                        if let Ok(g) = fit_general(
                            &self.model.chain,
                            &u,
                            &coarse,
                            fine.as_ref(),
                            &setup,
                            &gopts,
                        ) {
                            spent += g.evaluations;
                            all.extend(g.ranked);
                        }
                    }
                    if all.is_empty() {
                        return Err(Error::Numerical {
                            method: method_name,
                            reason: "no position set could be fitted".into(),
                        });
                    }
                    all.sort_by(|a, b| {
                        a.chi2
                            .total_cmp(&b.chi2)
                            .then_with(|| a.key().cmp(&b.key()))
                    });
                    (all, spent)
                }
            }
        };
        let best = ranked.first().ok_or_else(|| Error::Numerical {
            method: "fit".into(),
            reason: "no hypothesis".into(),
        })?;
        let params = 2 * k + self.model.fit.len();
        let (rss, n_data, predicted, chi2, dof) = match self.obs {
            Observations::Series(s) => {
                let chain = best.to_chain(&self.model.chain)?;
                let td = s.time_data(sigma)?;
                let model = TimeMisfit::new(td).model(&chain)?;
                let r: Vec<f64> = s.x().iter().zip(&model).map(|(a, b)| a - b).collect();
                let rss = r.iter().map(|v| v * v).sum();
                let dof = match &fine {
                    Some(_) => s.x().len().saturating_sub(params),
                    None => coarse.dof().saturating_sub(params),
                };
                (rss, s.x().len(), Some((model, r)), best.chi2, dof)
            }
            Observations::Laplace(l) => {
                let rss = best.chi2 * sigma * sigma;
                let m = crate::time::series::stacked_rows(l.s()).len();
                (rss, m, None, best.chi2, m.saturating_sub(params))
            }
        };
        let sigma_hat = (rss / (n_data.saturating_sub(params).max(1)) as f64).sqrt();
        Ok(KFit {
            k,
            hypotheses,
            ranked,
            evaluations,
            rss,
            n_data,
            params,
            sigma_hat,
            chi2,
            sigma_fit: sigma,
            dof,
            misfit_name,
            method_name,
            budget_exhausted,
            predicted,
        })
    }

    /// A stochastic search over mass positions and values on the Laplace
    /// chi-square: the best position set, the evaluations, and whether the
    /// budget ran out.
    fn stochastic(&self, k: usize, coarse: &LaplaceObs) -> Result<(Vec<usize>, usize, bool)> {
        let method = self
            .opts
            .method
            .stochastic()
            .ok_or_else(|| Error::Numerical {
                method: self.opts.method.name().into(),
                reason: "enumeration is not a stochastic search".into(),
            })?;
        let mut space = Space::masses(
            self.model.n(),
            k,
            KindBounds::for_chain(&self.model.chain).mass,
        );
        space.excluded = self
            .model
            .chain
            .defects()
            .iter()
            .map(Defect::at)
            .filter(|&a| a >= 1)
            .collect();
        let obj = LaplaceObjective {
            space,
            base: &self.model.chain,
            obs: coarse,
        };
        let sopts = SearchOptions {
            max_evals: self.opts.max_evals,
            seed: self.opts.seed,
            ..SearchOptions::default()
        };
        let res = minimize(method, &obj, &sopts)?;
        let mut p = res.best.positions.clone();
        p.sort_unstable();
        Ok((p, res.evaluations, res.evaluations >= self.opts.max_evals))
    }

    #[allow(clippy::too_many_arguments)]
    fn report(
        &self,
        f: &KFit,
        sigma: f64,
        estimated: bool,
        rows: Vec<KRow>,
        criterion: String,
        evaluations: usize,
        t0: Instant,
    ) -> Result<FitReport> {
        // the fit was made at f.sigma_fit: chi-squares and standard errors at the final sigma
        let scale = sigma / f.sigma_fit;
        let chi2_final = f.chi2 / (scale * scale);
        let ranked: Vec<Hypothesis> = f
            .ranked
            .iter()
            .map(|h| {
                let mut h = h.clone();
                h.chi2 /= scale * scale;
                for se in &mut h.std_errors {
                    *se *= scale;
                }
                for p in &mut h.chain {
                    p.std_error *= scale;
                }
                h
            })
            .collect();
        let best = &ranked[0];
        let base = &self.model.chain;
        let ident = identify_general(&ranked, base, sigma, None).ok();
        let bounds = KindBounds::for_chain(base);
        let known: Vec<(usize, DefectKind)> = base
            .defects()
            .iter()
            .map(|d| (d.at(), DefectKind::of(d)))
            .collect();
        let mut defects = Vec::with_capacity(best.defects.len());
        for (i, d) in best.defects.iter().enumerate() {
            let kind = DefectKind::of(d);
            let is_known = known.contains(&(d.at(), kind));
            let (lo, hi) = bounds.of(kind);
            let v = d.value();
            let tol = 1e-6 * hi.abs().max(1.0);
            let rep = ident
                .as_ref()
                .and_then(|r| r.defects.iter().find(|x| x.at == d.at()));
            defects.push(DefectEstimate {
                kind: kind.name(),
                at: d.at(),
                value: v,
                se: if is_known {
                    0.0
                } else {
                    best.std_errors.get(i).copied().unwrap_or(f64::NAN)
                },
                at_bound: !is_known && (v <= lo + tol || v >= hi - tol),
                known: is_known,
                significance: rep.map_or(f64::NAN, |r| r.significance),
                identifiable: is_known || rep.is_some_and(|r| r.identifiable),
            });
        }
        let cb = default_bounds(base, &self.model.fit);
        let params: Vec<ParamEstimate> = best
            .chain
            .iter()
            .map(|p| {
                let b = self
                    .model
                    .fit
                    .iter()
                    .position(|q| general::param_name(q) == p.name)
                    .map(|i| cb[i])
                    .unwrap_or((f64::NEG_INFINITY, f64::INFINITY));
                let tol = 1e-6 * b.1.abs().max(1.0);
                ParamEstimate {
                    name: p.name.clone(),
                    value: p.value,
                    se: p.std_error,
                    at_bound: p.value <= b.0 + tol || p.value >= b.1 - tol,
                }
            })
            .collect();
        let alternatives: Vec<Alternative> = ranked[1..]
            .iter()
            .take(self.opts.alternatives)
            .map(|h| Alternative {
                defects: h.defects.clone(),
                chi2: h.chi2,
                gap: h.chi2 - best.chi2,
            })
            .collect();
        // goodness of fit
        let (fits_data, p) = match (&f.predicted, estimated) {
            (Some((_, r)), true) => {
                let (_, p) = noise::ljung_box(r, 20);
                (p >= 0.001, p)
            }
            _ => {
                let p = select::chi2_sf(chi2_final, f.dof.max(1) as f64);
                (p >= 0.001, p)
            }
        };
        let threshold = identify::DEFAULT_THRESHOLD;
        let gap_ok = alternatives.first().is_none_or(|a| a.gap > threshold);
        let all_ident = defects.iter().all(|d| d.identifiable);
        let any_bound = defects.iter().any(|d| d.at_bound) || params.iter().any(|p| p.at_bound);
        let (status, message) = if f.budget_exhausted {
            (
                Status::BudgetExhausted,
                format!("the search used its whole budget of {} evaluations; raise max_evals or use enumerate", self.opts.max_evals),
            )
        } else if !best.converged {
            (
                Status::Stalled,
                "the value fit of the best hypothesis stopped at its iteration limit without meeting its tolerance: the values may not be at the minimum".to_string(),
            )
        } else if any_bound {
            (
                Status::ValueAtBound,
                "a fitted value ended on a bound of its range: a wrong basin, or a defect outside the range searched".to_string(),
            )
        } else if !all_ident || !gap_ok {
            let why = ident
                .as_ref()
                .and_then(|r| {
                    r.defects
                        .iter()
                        .find(|d| !d.identifiable)
                        .map(|d| d.reason.clone())
                })
                .unwrap_or_else(|| {
                    format!(
                        "the runner-up fits within a chi-square gap of {:.3} < {threshold}",
                        alternatives.first().map_or(0.0, |a| a.gap)
                    )
                });
            (Status::NotIdentifiable, why)
        } else if f.k == 0 {
            (
                Status::Converged,
                "no defect: the uniform chain explains the data".to_string(),
            )
        } else {
            (
                Status::Converged,
                format!(
                    "every defect identifiable; the runner-up is worse by chi-square {}",
                    alternatives
                        .first()
                        .map_or("(none)".into(), |a| format!("{:.3e}", a.gap))
                ),
            )
        };
        // the fitted chain's modes (none when the eigen solver refuses: a
        // non-uniform chain above its size limit)
        let modes = best
            .to_chain(base)
            .and_then(|c| crate::time::modal::natural_modes(&c))
            .map(|v| {
                v.iter()
                    .map(|m| ModeEstimate {
                        omega: m.omega,
                        frequency: m.frequency,
                        zeta: m.zeta.unwrap_or(f64::NAN),
                    })
                    .collect()
            })
            .unwrap_or_default();
        let predicted = match (self.obs, &f.predicted) {
            (Observations::Series(s), Some((model, r))) => Some(Predicted {
                t: s.t().to_vec(),
                observed: s.x().to_vec(),
                model: model.clone(),
                residual: r.clone(),
            }),
            _ => None,
        };
        Ok(FitReport {
            defects,
            k: f.k,
            params,
            noise_sigma: sigma,
            noise_estimated: estimated,
            chi2: chi2_final,
            dof: f.dof,
            status,
            message,
            resolved: status == Status::Converged && gap_ok && all_ident,
            fits_data,
            fit_p_value: p,
            alternatives,
            k_selection: rows,
            criterion,
            misfit: f.misfit_name.clone(),
            setup: format!(
                "{}; ends {}-{}",
                match self.obs {
                    Observations::Series(s) => s.measurement().describe(),
                    Observations::Laplace(l) => format!(
                        "{} of mass {} (Laplace values)",
                        l.sensor().kind.name(),
                        l.sensor().at
                    ),
                },
                base.left(),
                base.right()
            ),
            method: f.method_name.clone(),
            evaluations,
            hypotheses: f.hypotheses,
            wall_time_s: t0.elapsed().as_secs_f64(),
            predicted,
            identifiability: ident,
            modes,
        })
    }
}

/// The Laplace chi-square of mass defects as a search objective (invalid
/// candidates cost a large finite penalty).
struct LaplaceObjective<'a> {
    space: Space,
    base: &'a Chain,
    obs: &'a LaplaceObs,
}

impl Objective for LaplaceObjective<'_> {
    fn space(&self) -> &Space {
        &self.space
    }
    fn cost(&self, c: &Candidate) -> f64 {
        let chain = self.base.clone().with_defects(
            c.positions
                .iter()
                .zip(&c.values)
                .map(|(&at, &m)| Defect::Mass { at, m }),
        );
        match chain.and_then(|ch| self.obs.chi2(&ch)) {
            Ok(v) if v.is_finite() => v,
            _ => 1e300,
        }
    }
}
