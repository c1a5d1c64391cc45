//! The data-first fit's machinery behind [`super::fit`]: the observations
//! prepared once per noise level, the fits for one number of defects
//! ([`KFit`]), and the report built from the chosen one.

use super::chainfit::{default_bounds, fit_chain};
use super::effort::Effort;
use super::general::{self, fit_general, laplace_obs_under, GeneralOptions, Hypothesis, Setup};
use super::model::Model;
use super::options::FitOptions;
use super::report::KRow;
use crate::chain::{Chain, Defect};
use crate::detect::data::laplace::LaplaceObs;
use crate::detect::data::noise_model::NoiseModel;
use crate::detect::data::observations::{Observations, Series};
use crate::detect::misfit::time::TimeMisfit;
use crate::detect::misfit::{Misfit, MisfitKind};
use crate::detect::model::MeasurementModel;
use crate::detect::search::enumerate::EnumerateOptions;
use crate::detect::search::parallel::MIN_SETS;
use crate::detect::search::FitMethod;
use crate::detect::search::{
    minimize, Candidate, MisfitObjective, Objective, SearchOptions, SearchResult, Space,
};
use crate::detect::unknowns::{
    DefectKind, KindBounds, KindChoice, KindPositions, MassUnknowns, Slot, Unknowns,
};
use crate::error::{Error, Result};

mod kernel;
mod nested;
mod room;

/// Stop the `auto` loop when more defects have not lowered the time-domain
/// residual by more than noise would (a BIC step of `2 ln N` per defect at
/// the current noise estimate), in as many steps in a row as `effort` asks
/// (two by default; never at effort high).
pub(super) fn stop_early(fits: &[KFit], n: usize, effort: Effort) -> bool {
    let Some(steps) = effort.stop_after() else {
        return false;
    };
    if fits.len() < steps + 1 {
        return false;
    }
    let s = fits[fits.len() - 1].sigma_hat.max(f64::MIN_POSITIVE);
    let pen = 2.0 * (n as f64).ln();
    let c = |f: &KFit| f.rss / (s * s);
    fits[fits.len() - steps - 1..]
        .windows(2)
        .all(|w| c(&w[0]) - c(&w[1]) < pen)
}

pub(super) fn krow(f: &KFit, sigma: f64, estimated: bool, criterion: f64) -> KRow {
    KRow {
        k: f.k,
        chi2: f.chi2_at(sigma, estimated),
        params: f.params,
        criterion,
        positions: f.ranked.first().map(|h| h.positions()).unwrap_or_default(),
    }
}

/// The best fits with `k` defects at one noise level.
pub(super) struct KFit {
    pub(super) k: usize,
    /// Position (and kind) sets fitted.
    pub(super) hypotheses: usize,
    pub(super) ranked: Vec<Hypothesis>,
    pub(super) evaluations: usize,
    /// Residual sum of squares of the best fit in the time domain (series),
    /// or its unweighted Laplace chi-square (Laplace values without errors).
    pub(super) rss: f64,
    /// Data points behind `rss`.
    pub(super) n_data: usize,
    /// Free parameters (2 per defect of unknown position, 1 per known position, chain parameters).
    pub(super) params: usize,
    /// `sqrt(rss / (n_data - params))`, for a series at least
    /// [`super::SIGMA_FLOOR`] times its largest `|x|`.
    pub(super) sigma_hat: f64,
    /// The misfit's own chi-square and dof at the sigma of the fit.
    pub(super) chi2: f64,
    /// The noise level the fit was made at.
    pub(super) sigma_fit: f64,
    pub(super) dof: usize,
    pub(super) misfit_name: String,
    pub(super) method_name: String,
    pub(super) budget_exhausted: bool,
    pub(super) predicted: Option<(Vec<f64>, Vec<f64>)>,
    /// The residual whitened by the record model (`None`: white noise, no
    /// nuisance, where it is `predicted`'s residual).
    pub(super) whitened: Option<Vec<f64>>,
    /// Every position set was ranked (false: the Woodbury kernel's beam search).
    pub(super) exhaustive: bool,
    /// The narrowed unknowns whose every set the search ranked, when it
    /// was narrowed from the fit at `k - 1` ([`super::narrow`]).
    pub(super) searched: Option<Unknowns>,
    /// The Laplace ranking's best sets before the time-domain refits, best
    /// first (empty where the search does not keep one).
    pub(super) shortlist: Vec<KindPositions>,
    /// The stochastic search's trace, when asked for.
    pub(super) trace: Option<Vec<(usize, f64)>>,
    /// Per sensor of a record of several: the residual sum of squares at
    /// the best answer in the sensor's own units, and its samples (empty
    /// for one sensor).
    pub(super) sensors: Vec<SensorRss>,
}

/// One sensor's residual sum of squares (in its own units), samples and
/// the Ljung-Box p-value of its own residual.
pub(super) type SensorRss = (f64, usize, f64);

/// What a caller that has already built its unknowns gives the engine
/// beyond [`FitOptions`]: the scene path ([`super::paper`]) passes its
/// `[unknowns]` (known positions with free values and per-defect bounds,
/// which a [`Model`] and [`FitOptions`] do not describe), the enumeration's
/// tuning of its `[search]` (starts, beam) and whether to trace the search.
#[derive(Clone)]
pub(super) struct Given {
    /// The unknowns, used for every k (the caller fits one k).
    pub(super) unknowns: Unknowns,
    /// Options of the Woodbury kernel's enumeration (`keep` is
    /// `FitOptions::alternatives + 1`, `parallel` and `max_sets` those of
    /// the options).
    pub(super) enumerate: EnumerateOptions,
    /// Record the stochastic search's trace.
    pub(super) trace: bool,
}

impl KFit {
    /// Each sensor's noise level from its residual at the answer,
    /// `sqrt(RSS_j / (N_j (1 - p / N)))` with `N` the samples of every sensor
    /// and `p` the fit's parameters (empty for one sensor).
    pub(super) fn sensor_levels(&self) -> Vec<f64> {
        let total: usize = self.sensors.iter().map(|s| s.1).sum();
        let keep = 1.0 - self.params as f64 / total.max(1) as f64;
        self.sensors
            .iter()
            .map(|&(rss, n, _)| {
                (rss / (n as f64 * keep.max(1e-12)))
                    .sqrt()
                    .max(f64::MIN_POSITIVE)
            })
            .collect()
    }

    /// The chi-square used to compare numbers of defects: the time-domain
    /// `RSS / sigma^2` for series data, the misfit's own otherwise.
    pub(super) fn chi2_at(&self, sigma: f64, estimated: bool) -> f64 {
        if estimated || self.predicted.is_some() {
            self.rss / (sigma * sigma)
        } else {
            self.chi2
        }
    }
}

/// What a search found for one number of defects, before it is measured
/// against the data ([`KFit`]).
struct Found {
    ranked: Vec<Hypothesis>,
    evaluations: usize,
    /// Position (and kind) sets fitted.
    hypotheses: usize,
    method_name: String,
    /// Every position set was ranked (false: the Woodbury kernel's beam search).
    exhaustive: bool,
    /// The narrowed unknowns the search ranked ([`KFit::searched`]).
    searched: Option<Unknowns>,
    /// [`KFit::shortlist`].
    shortlist: Vec<KindPositions>,
    budget_exhausted: bool,
    trace: Option<Vec<(usize, f64)>>,
}

impl Found {
    fn new(ranked: Vec<Hypothesis>, evaluations: usize, hypotheses: usize, method: &str) -> Found {
        Found {
            ranked,
            evaluations,
            hypotheses,
            method_name: method.to_string(),
            exhaustive: true,
            searched: None,
            shortlist: Vec::new(),
            budget_exhausted: false,
            trace: None,
        }
    }
}

/// The observations and options every search of [`Engine::search`] fits on.
struct Inputs<'a> {
    coarse: &'a LaplaceObs,
    fine: Option<&'a TimeMisfit>,
    setup: &'a Setup,
    gopts: &'a GeneralOptions,
}

/// Largest non-uniform chain whose natural modes the report lists (the
/// dense eigen solver is O(n^3): 9 s of a 10 s fit at n = 2000).
pub const MODES_MAX_N: usize = 400;

pub(super) struct Engine<'a> {
    pub(super) obs: &'a Observations,
    pub(super) model: &'a Model,
    pub(super) opts: &'a FitOptions,
    pub(super) misfit: MisfitKind,
    /// The observations prepared at the last noise level (the transform,
    /// its covariance and whitening do not depend on k).
    pub(super) prepared: std::sync::Mutex<Option<(u64, Prepared)>>,
    /// Unknowns and search details given by the caller (the scene path).
    pub(super) given: Option<Given>,
    /// The `relax` method's support: the profile's positions, farthest
    /// from uniform first (computed once per fit).
    pub(super) support: std::sync::Mutex<Option<Vec<usize>>>,
    /// The record's noise model and nuisances (time misfit of a series).
    pub(super) record: super::record::RecordModel,
}

/// The coarse (Laplace) and fine (time) observations, the misfit's name and
/// the Laplace setup.
type Prepared = (LaplaceObs, Option<TimeMisfit>, String, Setup);

impl Engine<'_> {
    fn unknowns(&self, k: usize) -> Result<Option<Unknowns>> {
        if let Some(g) = &self.given {
            return Ok(Some(g.unknowns.clone()));
        }
        let known = self.model.chain().defects();
        if k == 0 && known.is_empty() {
            return Ok(None);
        }
        let mut slots: Vec<Slot> = known
            .iter()
            .map(|d| Slot {
                kind: KindChoice::from(DefectKind::of(d)),
                at: Some(d.at()),
                known: Some(d.value()),
                bounds: None,
            })
            .collect();
        if !self.opts.set.is_empty() {
            slots.extend(self.opts.set.iter().map(|&(kind, at)| Slot {
                at: Some(at),
                ..Slot::free(KindChoice::from(kind))
            }));
        } else {
            // the kinds the damping model takes (no damper under modal damping)
            let damping = self.model.chain().damping();
            let free = |kind: KindChoice| Slot::free(kind.under(damping));
            if self.opts.slot_kinds.len() == k && k > 0 {
                slots.extend(self.opts.slot_kinds.iter().map(|&kind| free(kind)));
            } else {
                slots.extend((0..k).map(|_| free(self.opts.kinds)));
            }
        }
        Ok(Some(Unknowns::new(
            self.model.n(),
            slots,
            self.model.fitted().to_vec(),
            KindBounds::for_chain(self.model.chain()),
        )?))
    }

    /// Observations in the forms the misfits use, at noise level `sigma`.
    /// The observations prepared last and the noise level they are at.
    pub(super) fn last_prepared(&self) -> Option<(f64, Prepared)> {
        let guard = self.prepared.lock().ok()?;
        guard.as_ref().map(|(k, p)| (f64::from_bits(*k), p.clone()))
    }

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
                let mut setup = Setup::for_record(s.t().last().copied(), self.model.chain())?;
                let td = self.record.time_data(s, sigma)?;
                // the time misfit refines a shortlist of the Bromwich line's
                let coarse_kind = match self.misfit {
                    MisfitKind::Time => MisfitKind::Bromwich,
                    laplace => laplace,
                };
                let uniform = self.model.chain().uniform();
                let head = Some(&uniform);
                let coarse = match self.record.screen_data(&td)? {
                    Some(screen) => {
                        laplace_obs_under(&screen, coarse_kind, &setup, &self.record.noise, head)?
                    }
                    None => laplace_obs_under(&td, coarse_kind, &setup, &NoiseModel::White, head)?,
                };
                // further sensors: each sensor's transform at its own level
                let coarse = match td.others() {
                    [] => coarse,
                    others => coarse.with_others(
                        others
                            .iter()
                            .map(|o| {
                                laplace_obs_under(o, coarse_kind, &setup, &NoiseModel::White, head)
                            })
                            .collect::<Result<_>>()?,
                    ),
                };
                self.opts.effort.adjust(&mut setup);
                let name = self.misfit_name(&td, s.separate_records(), &coarse, &setup);
                let fine = match self.misfit {
                    MisfitKind::Time => Some(self.record.misfit(td)?),
                    _ => None,
                };
                Ok((coarse, fine, name, setup))
            }
            Observations::Laplace(l) => {
                let obs = l.obs(sigma)?;
                let name = format!(
                    "{} (chi-square at {} given nodes)",
                    self.misfit.name(),
                    l.s().len()
                );
                Ok((
                    obs,
                    None,
                    name,
                    Setup::for_record(None, self.model.chain())?,
                ))
            }
        }
    }

    /// The misfit's line in the report.
    fn misfit_name(
        &self,
        td: &crate::detect::data::series::TimeData,
        records: bool,
        coarse: &LaplaceObs,
        setup: &Setup,
    ) -> String {
        match self.misfit {
            MisfitKind::Time => format!(
                "time (chi-square of {} samples{}{}; shortlist from the whitened Bromwich line, sigma_B = {})",
                td.len() + td.others().iter().map(|o| o.len()).sum::<usize>(),
                match (td.others().len(), records) {
                    (0, _) => String::new(),
                    (m, false) => format!(" of {} sensors", m + 1),
                    (m, true) => format!(" of {} records", m + 1),
                },
                self.record.describe(),
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
        }
    }

    /// The measurement model the fits at noise level `sigma` ranked their
    /// hypotheses on: the time misfit of a series (with the record model),
    /// else the Laplace values.
    ///
    /// # Errors
    /// As the observations' preparation.
    pub(super) fn measurement_at(&self, sigma: f64) -> Result<Box<dyn MeasurementModel>> {
        let (coarse, fine, ..) = self.prepared(sigma)?;
        Ok(match fine {
            Some(t) => Box::new(t),
            None => Box::new(coarse),
        })
    }

    /// How many position (and kind) sets `k` free defects can take (1
    /// without any).
    ///
    /// # Errors
    /// As the unknowns' construction.
    pub(super) fn space_size(&self, k: usize) -> Result<f64> {
        Ok(self.unknowns(k)?.map_or(1.0, |u| set_count(&u)))
    }

    /// The fit of `k` defects at noise level `sigma`; `previous` is the fit
    /// at `k - 1`, whose answers narrow the kinds of a search over every
    /// kind and, from three defects on, nest its sets ([`super::narrow`];
    /// not with `FitOptions::exhaustive`, at effort high where every set
    /// is within `max_sets`, with a scene's unknowns or another search than
    /// enumeration).
    pub(super) fn fit_k(&self, k: usize, sigma: f64, previous: Option<&KFit>) -> Result<KFit> {
        self.fit_k_after(k, sigma, previous, true)
    }

    /// [`Self::fit_k`] after `previous`, the fit at `k - 1`: its best
    /// answer's fitted chain parameters start the search's (a warm start:
    /// the damping of a record barely moves with one more defect), and,
    /// with `narrow`, its answers narrow the search as in [`Self::fit_k`].
    pub(super) fn fit_k_after(
        &self,
        k: usize,
        sigma: f64,
        previous: Option<&KFit>,
        narrow: bool,
    ) -> Result<KFit> {
        let (coarse, fine, misfit_name, setup) = self.prepared(sigma)?;
        let Some(unknowns) = self.unknowns(k)? else {
            let (ranked, evaluations) = self.fit_uniform(&coarse, fine.as_ref())?;
            let found = Found::new(ranked, evaluations, 1, self.opts.method.name());
            return self.measured(k, sigma, found, &coarse, fine.as_ref(), misfit_name);
        };
        // narrowed from the answers at k - 1: the kinds per position, then
        // the sets nested in the best answers ([`super::narrow`])
        let every_set = self.opts.exhaustive
            || (self.opts.effort.every_set() && set_count(&unknowns) <= self.opts.max_sets as f64);
        let from = previous.filter(|_| {
            narrow && self.given.is_none() && self.opts.method == FitMethod::Enumerate && !every_set
        });
        let start = match previous.and_then(|p| p.ranked.first()) {
            Some(best) if !self.model.fitted().is_empty() => {
                Some(best.to_chain(self.model.chain())?)
            }
            _ => None,
        };
        let (mut unknowns, mut notes, mut spent) = (unknowns, Vec::new(), 0);
        if let Some(p) = from {
            let effort = self.opts.effort;
            let answers =
                super::narrow::previous_sets(&p.ranked, &p.shortlist, effort.nest_previous());
            // nested over every (kind, position) pair where it applies
            // (from three defects on, the general search); the kinds
            // narrowed per position otherwise, keeping every pair of the
            // best answers at k - 1
            let nested = match self.woodbury(&unknowns)? {
                None => super::narrow::nest(&unknowns, &answers)?,
                Some(_) => None,
            };
            if let Some((nested, (sets, full))) = nested {
                notes.push(format!(
                    "nested in the best {} answers at k = {}: {sets} of {full} sets",
                    answers.len(),
                    k - 1
                ));
                unknowns = nested;
            } else if let Some(nw) =
                super::narrow::narrow(self.model.chain(), &unknowns, &p.ranked, &answers, &coarse)?
            {
                notes.push(format!(
                    "kinds narrowed per position: {} of {} pairs",
                    nw.kept.0, nw.kept.1
                ));
                spent += nw.evaluations;
                unknowns = nw.unknowns;
            }
        }
        let mut found =
            self.search_prepared(k, sigma, &unknowns, (&coarse, fine.as_ref()), setup, start)?;
        if !notes.is_empty() {
            found.evaluations += spent;
            found.exhaustive = false;
            found.searched = Some(unknowns);
            found.method_name = format!("{} ({})", found.method_name, notes.join("; "));
        }
        self.measured(k, sigma, found, &coarse, fine.as_ref(), misfit_name)
    }

    /// [`Self::search`] for `unknowns` on the prepared observations.
    fn search_prepared(
        &self,
        k: usize,
        sigma: f64,
        unknowns: &Unknowns,
        (coarse, fine): (&LaplaceObs, Option<&TimeMisfit>),
        mut setup: Setup,
        start: Option<Chain>,
    ) -> Result<Found> {
        // a small fit runs on one thread (search::parallel)
        let large = set_count(unknowns) >= MIN_SETS as f64;
        let gopts = GeneralOptions {
            parallel: self.opts.parallel && large,
            max_sets: self.opts.max_sets,
            start,
            ..GeneralOptions::default()
        };
        setup.shortlist = setup.shortlist.max(self.opts.alternatives + 1);
        let inputs = Inputs {
            coarse,
            fine,
            setup: &setup,
            gopts: &gopts,
        };
        self.search(unknowns, k, sigma, &inputs)
    }

    /// Run the options' search for the unknowns of `k` defects.
    fn search(&self, unknowns: &Unknowns, k: usize, sigma: f64, x: &Inputs<'_>) -> Result<Found> {
        let kernel = self.woodbury(unknowns)?;
        let enumerated = self.opts.method == FitMethod::Enumerate || k == 0;
        let mut found = match (&kernel, self.opts.method) {
            (Some((misfit, mass)), FitMethod::Enumerate) => {
                self.search_kernel(unknowns, misfit, mass, sigma, x)?
            }
            (_, FitMethod::Enumerate) => self.search_general(unknowns, x)?,
            _ if k == 0 => self.search_general(unknowns, x)?,
            (_, FitMethod::Relax) => self.search_relax(unknowns, x)?,
            (_, FitMethod::Greedy) => self.search_greedy(unknowns, x)?,
            _ => self.search_stochastic(unknowns, kernel.as_ref(), x)?,
        };
        // a search that does not enumerate ranks some sets only
        found.exhaustive &= enumerated;
        Ok(found)
    }

    /// Mass defects on Laplace values: the paper's Woodbury kernel ranks
    /// every position set; the best are refitted.
    fn search_kernel(
        &self,
        unknowns: &Unknowns,
        misfit: &Misfit,
        mass: &MassUnknowns,
        sigma: f64,
        x: &Inputs<'_>,
    ) -> Result<Found> {
        let (sets, screened, all, spent) = self.woodbury_sets(misfit, mass)?;
        let (r, e) = self.refit_from_kernel(
            unknowns, &sets, misfit, mass, sigma, x.coarse, x.fine, x.setup, x.gopts,
        )?;
        let mut found = Found::new(r, e + spent, screened, "enumerate (Woodbury kernel)");
        found.exhaustive = all;
        Ok(found)
    }

    /// Every position (and kind) set fitted by the general fit.
    fn search_general(&self, unknowns: &Unknowns, x: &Inputs<'_>) -> Result<Found> {
        let g = fit_general(
            self.model.chain(),
            unknowns,
            x.coarse,
            x.fine,
            x.setup,
            x.gopts,
        )?;
        let mut found = Found::new(g.ranked, g.evaluations, g.hypotheses, "enumerate");
        found.shortlist = g.shortlist;
        Ok(found)
    }

    /// The continuous relaxation's support seeds the discrete fit: the f
    /// positions farthest from uniform, refitted with their neighbours (each
    /// moved by +-1, +-2).
    fn search_relax(&self, unknowns: &Unknowns, x: &Inputs<'_>) -> Result<Found> {
        let support = self.support(unknowns)?;
        let taken: Vec<usize> = unknowns.slots().iter().filter_map(|s| s.at).collect();
        let free = unknowns.slots().iter().filter(|s| s.at.is_none()).count();
        let start: Vec<usize> = support
            .into_iter()
            .filter(|p| !taken.contains(p))
            .take(free)
            .collect();
        if start.len() < free {
            return Err(Error::invalid(
                "method",
                "relax",
                format!("{free} free positions in the profile's support"),
            ));
        }
        let sets = neighbour_sets(unknowns, &start);
        let (r, e) = self.refit_sets(unknowns, &sets, x.coarse, x.fine, x.setup, x.gopts)?;
        Ok(Found::new(
            r,
            e,
            sets.len(),
            "relax (the profile's support, refitted with its neighbours)",
        ))
    }

    /// The greedy search with moves (`fit::greedy`).
    fn search_greedy(&self, unknowns: &Unknowns, x: &Inputs<'_>) -> Result<Found> {
        let g = super::greedy::fit_greedy(
            self.model.chain(),
            unknowns,
            x.coarse,
            x.fine,
            x.setup,
            &super::greedy::GreedyOptions {
                parallel: self.opts.parallel,
                ..Default::default()
            },
        )?;
        Ok(Found::new(
            g.ranked,
            g.evaluations + g.scored,
            g.hypotheses,
            self.opts.method.name(),
        ))
    }

    /// A stochastic optimizer, then its best set and the set's neighbours
    /// (each position moved by +-1, +-2) refitted like enumeration's.
    fn search_stochastic(
        &self,
        unknowns: &Unknowns,
        kernel: Option<&(Misfit, MassUnknowns)>,
        x: &Inputs<'_>,
    ) -> Result<Found> {
        let res = self.stochastic(unknowns, kernel, x.coarse)?;
        let sets = neighbour_sets(unknowns, &res.best.positions);
        let (r, e) = self.refit_sets(unknowns, &sets, x.coarse, x.fine, x.setup, x.gopts)?;
        let mut found = Found::new(r, e + res.evaluations, sets.len(), self.opts.method.name());
        found.budget_exhausted = res.evaluations >= self.opts.max_evals;
        if self.given.as_ref().is_some_and(|g| g.trace) {
            found.trace = Some(res.trace);
        }
        Ok(found)
    }

    /// The fit of `k` defects from what the search found: its best answer's
    /// residual in the data's own terms (the time-domain RSS for series
    /// data), degrees of freedom and noise estimate.
    fn measured(
        &self,
        k: usize,
        sigma: f64,
        found: Found,
        coarse: &LaplaceObs,
        fine: Option<&TimeMisfit>,
        misfit_name: String,
    ) -> Result<KFit> {
        let best = found.ranked.first().ok_or_else(|| Error::Numerical {
            method: "fit".into(),
            reason: "no hypothesis".into(),
        })?;
        let params = 2 * k + self.model.fitted().len();
        let mut sensors = Vec::new();
        let (rss, n_data, predicted, chi2, dof, whitened) = match self.obs {
            Observations::Series(s) => {
                let chain = best.to_chain(self.model.chain())?;
                let tm = self.record.misfit(self.record.time_data(s, sigma)?)?;
                let (model, r, mut whitened) = self.record.measured(&tm, &chain, s.x())?;
                if !s.others().is_empty() {
                    let (w, per) = self.sensor_residuals(&tm, &chain, s, &r)?;
                    (whitened, sensors) = (Some(w), per);
                }
                let rss = match &whitened {
                    Some(w) => w.iter().map(|v| v * v).sum(),
                    None => r.iter().map(|v| v * v).sum(),
                };
                let n = s.sensors().map(|o| o.x().len()).sum::<usize>() - self.record.lost();
                let dof = match fine {
                    Some(_) => n.saturating_sub(params),
                    None => coarse.dof().saturating_sub(params),
                };
                (rss, n, Some((model, r)), best.chi2, dof, whitened)
            }
            Observations::Laplace(l) => {
                let rss = best.chi2 * sigma * sigma;
                let m = crate::time::series::stacked_rows(l.s()).len();
                (rss, m, None, best.chi2, m.saturating_sub(params), None)
            }
        };
        let floor = match self.obs {
            Observations::Series(s) => super::SIGMA_FLOOR * s.max_abs(),
            Observations::Laplace(_) => 0.0,
        };
        let sigma_hat = (rss / (n_data.saturating_sub(params).max(1)) as f64)
            .sqrt()
            .max(floor);
        Ok(KFit {
            k,
            hypotheses: found.hypotheses,
            ranked: found.ranked,
            evaluations: found.evaluations,
            rss,
            n_data,
            params,
            sigma_hat,
            chi2,
            sigma_fit: sigma,
            dof,
            misfit_name,
            method_name: found.method_name,
            budget_exhausted: found.budget_exhausted,
            predicted,
            whitened,
            exhaustive: found.exhaustive,
            searched: found.searched,
            shortlist: found.shortlist,
            trace: found.trace,
            sensors,
        })
    }

    /// The residuals of a record of several sensors at `chain`: every
    /// sensor's `x - model` in turn, each divided by its noise scale (so
    /// that all are at the first sensor's level: the residual the noise
    /// estimate and the whiteness test read), and per sensor its residual
    /// sum of squares in its own units and its samples. `first` is the
    /// first sensor's residual.
    ///
    /// # Errors
    /// As the time misfit's model.
    fn sensor_residuals(
        &self,
        tm: &TimeMisfit,
        chain: &Chain,
        s: &Series,
        first: &[f64],
    ) -> Result<(Vec<f64>, Vec<SensorRss>)> {
        let mut stacked = first.to_vec();
        let lb = |r: &[f64]| super::noise::ljung_box(r, 20).1;
        let mut per = vec![(first.iter().map(|v| v * v).sum(), first.len(), lb(first))];
        for (j, (o, m)) in s.others().iter().zip(tm.others()).enumerate() {
            let scale = self.record.scales.get(j).copied().unwrap_or(1.0);
            let r: Vec<f64> = o
                .x()
                .iter()
                .zip(m.model(chain)?)
                .map(|(a, b)| a - b)
                .collect();
            per.push((r.iter().map(|v| v * v).sum(), r.len(), lb(&r)));
            stacked.extend(r.iter().map(|v| v / scale));
        }
        Ok((stacked, per))
    }

    /// No defect of unknown position: the chain (with its known defects) as
    /// it is, its fitted uniform parameters by LM if any.
    fn fit_uniform(
        &self,
        coarse: &LaplaceObs,
        fine: Option<&TimeMisfit>,
    ) -> Result<(Vec<Hypothesis>, usize)> {
        let chain_bounds = default_bounds(self.model.chain(), self.model.fitted());
        // the uniform chain, chain parameters fitted if any
        let obs: &dyn MeasurementModel = match fine {
            Some(t) => t,
            None => coarse,
        };
        let base = self.model.chain().uniform();
        if self.model.fitted().is_empty() {
            let r = obs.residuals(&base)?;
            Ok((
                vec![Hypothesis::from_parts(
                    Vec::new(),
                    Vec::new(),
                    Vec::new(),
                    r.iter().map(|v| v * v).sum(),
                )],
                1,
            ))
        } else {
            let f = fit_chain(&base, self.model.fitted(), obs, Some(&chain_bounds))?;
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
            Ok((
                vec![Hypothesis::from_parts(
                    Vec::new(),
                    Vec::new(),
                    params,
                    f.lm.chi2,
                )],
                f.lm.evaluations,
            ))
        }
    }

    /// The hypotheses fitted, best first (ties by positions), with the
    /// evaluations spent; an error when none could be fitted.
    fn ranked(&self, mut all: Vec<Hypothesis>, spent: usize) -> Result<(Vec<Hypothesis>, usize)> {
        if all.is_empty() {
            return Err(Error::Numerical {
                method: self.opts.method.name().into(),
                reason: "no position set could be fitted".into(),
            });
        }
        all.sort_by(|a, b| {
            a.chi2
                .total_cmp(&b.chi2)
                .then_with(|| a.key().cmp(&b.key()))
        });
        Ok((all, spent))
    }

    /// The unknowns with their unknown-position slots placed at `q` (in
    /// slot order).
    fn placed(&self, unknowns: &Unknowns, q: &[usize]) -> Result<Unknowns> {
        let mut slots = unknowns.slots().to_vec();
        let mut at = q.iter();
        for slot in slots.iter_mut().filter(|s| s.at.is_none()) {
            slot.at = at.next().copied();
        }
        Unknowns::new(
            self.model.n(),
            slots,
            unknowns.chain().to_vec(),
            *unknowns.kind_bounds(),
        )
    }

    /// Fit every position set of `sets` (the positions of the unknowns'
    /// unknown-position slots, in slot order: values, chain parameters,
    /// standard errors) as the enumeration does; ranked by chi-square.
    fn refit_sets(
        &self,
        unknowns: &Unknowns,
        sets: &[Vec<usize>],
        coarse: &LaplaceObs,
        fine: Option<&TimeMisfit>,
        setup: &Setup,
        gopts: &GeneralOptions,
    ) -> Result<(Vec<Hypothesis>, usize)> {
        let mut all = Vec::new();
        let mut spent = 0;
        for q in sets {
            let u = self.placed(unknowns, q)?;
            if let Ok(g) = fit_general(self.model.chain(), &u, coarse, fine, setup, gopts) {
                spent += g.evaluations;
                all.extend(g.ranked);
            }
        }
        self.ranked(all, spent)
    }

    /// The `relax` method's support: the whole-profile inversion of the
    /// observations ([`super::profile::fit_profile_with`], every mass or
    /// every spring as the unknowns' one kind, without its restart from a
    /// defect fit) and its positions ordered visible first, then by
    /// standard errors from uniform, then position; once per fit.
    fn support(&self, unknowns: &Unknowns) -> Result<Vec<usize>> {
        use super::profile::{fit_profile_with, ProfileMode, ProfileOptions};
        let mut cached = self.support.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(s) = cached.as_ref() {
            return Ok(s.clone());
        }
        let kinds: Vec<DefectKind> = unknowns
            .slots()
            .iter()
            .filter(|s| s.at.is_none())
            .flat_map(|s| s.kind.kinds().iter().copied())
            .collect();
        let mode = match kinds.first() {
            Some(DefectKind::Mass) if kinds.iter().all(|k| *k == DefectKind::Mass) => ProfileMode::Masses,
            Some(DefectKind::Spring) if kinds.iter().all(|k| *k == DefectKind::Spring) => {
                ProfileMode::Springs
            }
            _ => {
                return Err(Error::invalid(
                    "method",
                    "relax",
                    "mass or spring defects of one kind (the relaxation frees every mass or every spring)",
                ))
            }
        };
        let popts = ProfileOptions {
            noise: self.opts.noise,
            ..ProfileOptions::new(mode)
        };
        let p = fit_profile_with(self.obs, self.model, &popts, None)?;
        let mut els: Vec<_> = p.elements.iter().collect();
        els.sort_by(|a, b| {
            b.visible
                .cmp(&a.visible)
                .then(b.significance().total_cmp(&a.significance()))
                .then(a.at.cmp(&b.at))
        });
        let s: Vec<usize> = els.iter().map(|e| e.at).collect();
        *cached = Some(s.clone());
        Ok(s)
    }

    /// A stochastic search over the positions and values of mass defects:
    /// on the Woodbury kernel when it applies ([`MisfitObjective`], the
    /// unknowns' own space), else on the Laplace chi-square of the coarse
    /// observations (free masses in the kind's bounds, the model's known
    /// defects excluded).
    fn stochastic(
        &self,
        unknowns: &Unknowns,
        kernel: Option<&(Misfit, MassUnknowns)>,
        coarse: &LaplaceObs,
    ) -> Result<SearchResult> {
        // minimize refuses a search with no optimizer behind it
        let method = self.opts.method;
        let sopts = SearchOptions {
            max_evals: self.opts.max_evals,
            seed: self.opts.seed,
            trace: self.given.as_ref().is_some_and(|g| g.trace),
            ..SearchOptions::default()
        };
        if let Some((misfit, mass)) = kernel {
            return minimize(method, &MisfitObjective::new(misfit, mass), &sopts);
        }
        let mut space = Space::masses(
            self.model.n(),
            unknowns.k(),
            KindBounds::for_chain(self.model.chain()).mass,
        );
        space.excluded = self
            .model
            .chain()
            .defects()
            .iter()
            .map(Defect::at)
            .filter(|&a| a >= 1)
            .collect();
        let obj = LaplaceObjective {
            space,
            base: self.model.chain(),
            obs: coarse,
        };
        minimize(method, &obj, &sopts)
    }
}

/// How many position (and kind) sets the unknowns hold, about: the
/// placements of their free slots on the positions not already taken,
/// times the kinds each may take (the work of one enumeration, which
/// decides whether it is shared among threads).
fn set_count(unknowns: &Unknowns) -> f64 {
    let slots = unknowns.slots();
    let free: Vec<&Slot> = slots.iter().filter(|s| s.at.is_none()).collect();
    if let Some(sets) = unknowns.sets() {
        return sets.len() as f64;
    }
    if let Some(c) = unknowns.candidates() {
        let m = c.len() as f64;
        return (0..free.len())
            .fold(1.0, |c, i| c * (m - i as f64) / (i + 1) as f64)
            .max(0.0);
    }
    let open = unknowns.n().saturating_sub(slots.len() - free.len()) as f64;
    let kinds: f64 = free.iter().map(|s| s.kind.kinds().len() as f64).product();
    let places = (0..free.len()).fold(1.0, |c, i| c * (open - i as f64) / (i + 1) as f64);
    places.max(0.0) * kinds
}

/// The position set a stochastic search found (`positions` of the unknowns'
/// unknown-position slots, in slot order) and its neighbours: each position
/// moved by one or two to a place that is free (in `1..=n`, not a known position,
/// not another defect's). Interchangeable sets are sorted, and every set is
/// listed once.
fn neighbour_sets(unknowns: &Unknowns, positions: &[usize]) -> Vec<Vec<usize>> {
    let taken: Vec<usize> = unknowns.slots().iter().filter_map(|s| s.at).collect();
    let interchangeable = unknowns.to_mass().is_ok_and(|m| m.interchangeable());
    let norm = |mut q: Vec<usize>| {
        if interchangeable {
            q.sort_unstable();
        }
        q
    };
    let mut sets = vec![norm(positions.to_vec())];
    for i in 0..positions.len() {
        for delta in [-2i64, -1, 1, 2] {
            let p = positions[i] as i64 + delta;
            if p < 1 || p as usize > unknowns.n() {
                continue;
            }
            let p = p as usize;
            if positions.contains(&p) || taken.contains(&p) {
                continue;
            }
            let mut q = positions.to_vec();
            q[i] = p;
            let q = norm(q);
            if !sets.contains(&q) {
                sets.push(q);
            }
        }
    }
    sets
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::data::observations::LaplaceValues;
    use crate::detect::fit::DefectCount;
    use num_complex::Complex64;

    /// A fit at `k + 1` worse than the fit at `k` (here a hand-made wrong
    /// answer) is replaced by the refit from the `k` answer plus a
    /// vanishing defect: never worse than `k`; a fit that is not worse is
    /// kept as it is.
    #[test]
    fn a_worse_fit_at_k_plus_one_restarts_from_k() {
        use crate::detect::data::observations::Series;
        use crate::detect::data::series::TimeData;
        use crate::noise::NoiseLevel;
        let truth = crate::scenes::paper_with(8, "mass:3:3.0 mass:6:0.5").unwrap();
        let rec =
            TimeData::simulate(&truth, 100.0, 0.25, NoiseLevel::RelativeMax(1e-3), 1).unwrap();
        let obs =
            Observations::Series(Series::new(rec.t().to_vec(), rec.y().to_vec(), None).unwrap());
        let model = Model::new(8).unwrap();
        let opts = FitOptions {
            parallel: false,
            ..FitOptions::default()
        };
        let engine = Engine {
            obs: &obs,
            model: &model,
            opts: &opts,
            misfit: MisfitKind::Time,
            prepared: std::sync::Mutex::new(None),
            given: None,
            support: std::sync::Mutex::new(None),
            record: Default::default(),
        };
        let sigma = 1e-3 * rec.y().iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let prev = engine.fit_k(1, sigma, None).unwrap();
        let good = engine.fit_k(2, sigma, None).unwrap();
        assert!(good.rss <= prev.rss);
        let (rss, sets) = (good.rss, good.hypotheses);
        let kept = engine.monotone(&prev, good, sigma).unwrap();
        assert_eq!((kept.rss.to_bits(), kept.hypotheses), (rss.to_bits(), sets));
        let wrong = Hypothesis::from_parts(
            vec![
                Defect::Mass { at: 1, m: 1.5 },
                Defect::Mass { at: 8, m: 0.7 },
            ],
            vec![0.1, 0.1],
            Vec::new(),
            f64::INFINITY,
        );
        let (coarse, fine, name, _) = engine.prepared(sigma).unwrap();
        let found = Found::new(vec![wrong], 0, 1, "enumerate");
        let worse = engine
            .measured(2, sigma, found, &coarse, fine.as_ref(), name)
            .unwrap();
        assert!(worse.rss > prev.rss, "{} vs {}", worse.rss, prev.rss);
        let fixed = engine.monotone(&prev, worse, sigma).unwrap();
        assert!(fixed.rss <= prev.rss, "{} vs {}", fixed.rss, prev.rss);
        let held = prev.ranked[0].positions();
        assert!(fixed.ranked[0].positions().contains(&held[0]));
        assert_eq!(fixed.ranked[0].defects.len(), 2);
    }

    /// The Woodbury path's hypotheses (best two refitted from the kernel's
    /// values, the others the kernel's fits) against the full refit of the
    /// same sets: same ranking, chi-squares, values and standard errors, with
    /// and without errors on the values, at two noise levels.
    #[test]
    fn kernel_hypotheses_match_the_full_refit() {
        let truth = crate::scenes::paper_with(5, "mass:2:3.0 mass:4:0.5").unwrap();
        let s: Vec<Complex64> = (1..=40)
            .map(|i| Complex64::new(0.1, 0.05 * i as f64))
            .collect();
        let fwd = crate::forward::Forward::new(&truth);
        // data off the model by a relative 1e-6, so that every set has a
        // chi-square well above rounding
        let values: Vec<Complex64> = s
            .iter()
            .enumerate()
            .map(|(i, z)| fwd.eval(*z, 1).unwrap() * (1.0 + 1e-6 * ((i * 7 % 5) as f64 - 2.0)))
            .collect();
        let model = Model::new(5).unwrap();
        let opts = FitOptions {
            defects: DefectCount::Exactly(2),
            // masses: the Woodbury kernel's kind
            kinds: KindChoice::Mass,
            alternatives: 4,
            parallel: false,
            ..FitOptions::default()
        };
        for errors in [None, Some(vec![1e-3; s.len()])] {
            for sigma in [1.0, 1e-6] {
                let obs = Observations::Laplace(
                    LaplaceValues::new(s.clone(), values.clone(), errors.clone()).unwrap(),
                );
                let engine = Engine {
                    obs: &obs,
                    model: &model,
                    opts: &opts,
                    misfit: MisfitKind::Bromwich,
                    prepared: std::sync::Mutex::new(None),
                    given: None,
                    support: std::sync::Mutex::new(None),
                    record: Default::default(),
                };
                let fast = engine.fit_k(2, sigma, None).unwrap();
                let (coarse, fine, _, mut setup) = engine.prepared(sigma).unwrap();
                setup.shortlist = setup.shortlist.max(5);
                let unknowns = engine.unknowns(2).unwrap().unwrap();
                let (misfit, mass) = engine.woodbury(&unknowns).unwrap().unwrap();
                let (sets, ..) = engine.woodbury_sets(&misfit, &mass).unwrap();
                let free: Vec<Vec<usize>> = sets.iter().map(|s| s.free.clone()).collect();
                let gopts = GeneralOptions {
                    parallel: false,
                    ..GeneralOptions::default()
                };
                let (full, _) = engine
                    .refit_sets(&unknowns, &free, &coarse, fine.as_ref(), &setup, &gopts)
                    .unwrap();
                let case = format!("errors {:?}, sigma {sigma}", errors.is_some());
                assert_eq!(fast.ranked.len(), full.len(), "{case}");
                for (a, b) in fast.ranked.iter().zip(&full) {
                    assert_eq!(a.positions(), b.positions(), "{case}");
                    assert!(
                        (a.chi2 - b.chi2).abs() <= 1e-6 * b.chi2,
                        "{case}: {a:?} vs {b:?}"
                    );
                    // equal within the fits' tolerance: they stop at a
                    // relative chi-square change of 1e-9, and along a bound
                    // or a flat valley the values move more than that
                    for (x, y) in a.masses().iter().zip(b.masses()) {
                        assert!((x - y).abs() <= 1e-4 * y, "{case}: {a:?} vs {b:?}");
                    }
                    for (x, y) in a.std_errors.iter().zip(&b.std_errors) {
                        assert!((x - y).abs() <= 1e-3 * y, "{case}: {a:?} vs {b:?}");
                    }
                }
            }
        }
    }
}
