//! The data-first fit's machinery behind [`super::fit`]: the observations
//! prepared once per noise level, the fits for one number of defects
//! ([`KFit`]), and the report built from the chosen one.

use super::{
    chainfit::{default_bounds, fit_chain, Obs},
    general::{
        self, fit_general, identify_general, laplace_obs, GeneralOptions, Hypothesis, Setup,
    },
    identify, noise, select, Alternative, DefectEstimate, FitMethod, FitOptions, FitReport, KRow,
    ModeEstimate, Model, ParamEstimate, Predicted, Status,
};
use crate::chain::{Chain, Defect};
use crate::detect::data::laplace::LaplaceObs;
use crate::detect::data::observations::Observations;
use crate::detect::misfit::time::TimeMisfit;
use crate::detect::misfit::{Misfit, MisfitKind};
use crate::detect::search::enumerate::{enumerate, EnumerateOptions};
use crate::detect::search::{
    minimize, Candidate, MisfitObjective, Objective, SearchOptions, SearchResult, Space,
};
use crate::detect::unknowns::{DefectKind, KindBounds, KindChoice, MassUnknowns, Slot, Unknowns};
use crate::error::{Error, Result};
use std::time::Instant;

/// Stop the `auto` loop when two more defects in a row have not lowered the
/// time-domain residual by more than noise would (a BIC step of `2 ln N`
/// per defect at the current noise estimate).
pub(super) fn stop_early(fits: &[KFit], n: usize) -> bool {
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
    /// `sqrt(rss / (n_data - params))`.
    pub(super) sigma_hat: f64,
    /// The misfit's own chi-square and dof at the sigma of the fit.
    chi2: f64,
    /// The noise level the fit was made at.
    pub(super) sigma_fit: f64,
    pub(super) dof: usize,
    pub(super) misfit_name: String,
    pub(super) method_name: String,
    pub(super) budget_exhausted: bool,
    pub(super) predicted: Option<(Vec<f64>, Vec<f64>)>,
    /// Every position set was ranked (false: the Woodbury kernel's beam search).
    pub(super) exhaustive: bool,
    /// The stochastic search's trace, when asked for.
    pub(super) trace: Option<Vec<(usize, f64)>>,
}

/// What a caller that has already built its unknowns gives the engine
/// beyond [`FitOptions`]: the scene path ([`super::paper`]) passes its
/// `[unknowns]` (known positions with free values and per-defect bounds,
/// which a [`Model`] and [`FitOptions`] do not describe), the enumeration's
/// tuning of its `[search]` (starts, beam) and whether to trace the search.
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
        if self.opts.slot_kinds.len() == k && k > 0 {
            slots.extend(self.opts.slot_kinds.iter().map(|&kind| Slot::free(kind)));
        } else {
            slots.extend((0..k).map(|_| Slot::free(self.opts.kinds)));
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
                let setup = Setup::for_record(s.t().last().copied(), self.model.chain())?;
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
                Ok((
                    obs,
                    None,
                    name,
                    Setup::for_record(None, self.model.chain())?,
                ))
            }
        }
    }

    pub(super) fn fit_k(&self, k: usize, sigma: f64) -> Result<KFit> {
        let (coarse, fine, misfit_name, setup) = self.prepared(sigma)?;
        let mut budget_exhausted = false;
        let mut method_name = self.opts.method.name().to_string();
        let mut hypotheses = 1;
        let mut exhaustive = true;
        let mut trace = None;
        let (ranked, evaluations) = match self.unknowns(k)? {
            None => self.fit_uniform(&coarse, fine.as_ref())?,
            Some(unknowns) => {
                let gopts = GeneralOptions {
                    parallel: self.opts.parallel,
                    max_sets: self.opts.max_sets,
                    ..GeneralOptions::default()
                };
                let mut setup = setup;
                setup.shortlist = setup.shortlist.max(self.opts.alternatives + 1);
                let kernel = self.woodbury(&unknowns)?;
                if let (Some((misfit, mass)), FitMethod::Enumerate) = (&kernel, self.opts.method) {
                    // mass defects on Laplace values: the paper's Woodbury
                    // kernel ranks every position set; the best are refitted
                    method_name = "enumerate (Woodbury kernel)".into();
                    let (sets, screened, all, spent) = self.woodbury_sets(misfit, mass)?;
                    hypotheses = screened;
                    exhaustive = all;
                    let (r, e) =
                        self.refit_sets(&unknowns, &sets, &coarse, fine.as_ref(), &setup, &gopts)?;
                    (r, e + spent)
                } else if self.opts.method == FitMethod::Enumerate || k == 0 {
                    method_name = "enumerate".into();
                    let g = fit_general(
                        self.model.chain(),
                        &unknowns,
                        &coarse,
                        fine.as_ref(),
                        &setup,
                        &gopts,
                    )?;
                    hypotheses = g.hypotheses;
                    (g.ranked, g.evaluations)
                } else if self.opts.method == FitMethod::Greedy {
                    // greedy search with moves (fit::greedy)
                    let g = super::greedy::fit_greedy(
                        self.model.chain(),
                        &unknowns,
                        &coarse,
                        fine.as_ref(),
                        &setup,
                        &super::greedy::GreedyOptions {
                            parallel: self.opts.parallel,
                            ..Default::default()
                        },
                    )?;
                    hypotheses = g.hypotheses;
                    (g.ranked, g.evaluations + g.scored)
                } else {
                    let res = self.stochastic(&unknowns, kernel.as_ref(), &coarse)?;
                    budget_exhausted = res.evaluations >= self.opts.max_evals;
                    if self.given.as_ref().is_some_and(|g| g.trace) {
                        trace = Some(res.trace.clone());
                    }
                    // refit the best set and its neighbours (each position moved by
                    // +-1, +-2) like enumeration
                    let sets = neighbour_sets(&unknowns, &res.best.positions);
                    hypotheses = sets.len();
                    let (r, e) =
                        self.refit_sets(&unknowns, &sets, &coarse, fine.as_ref(), &setup, &gopts)?;
                    (r, e + res.evaluations)
                }
            }
        };
        let best = ranked.first().ok_or_else(|| Error::Numerical {
            method: "fit".into(),
            reason: "no hypothesis".into(),
        })?;
        let params = 2 * k + self.model.fitted().len();
        let (rss, n_data, predicted, chi2, dof) = match self.obs {
            Observations::Series(s) => {
                let chain = best.to_chain(self.model.chain())?;
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
            exhaustive,
            trace,
        })
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
        let obs = match fine {
            Some(t) => Obs::Time(t),
            None => Obs::Laplace(coarse),
        };
        let base = self.model.chain().uniform();
        if self.model.fitted().is_empty() {
            let r = match obs {
                Obs::Time(t) => t.residuals(&base)?,
                Obs::Laplace(l) => l.residuals(&base)?,
            };
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
            let f = fit_chain(&base, self.model.fitted(), &obs, Some(&chain_bounds))?;
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

    /// The paper's mass-only Woodbury kernel when the unknowns and data
    /// allow it: mass defects (free or known values and positions, no chain
    /// parameter) on Laplace values of the paper's setup (fixed ends,
    /// displacement of mass 1 after the impulse, no known defect in the
    /// model's chain): the chi-square of the values at their nodes
    /// ([`Misfit::at_nodes`]) and the unknowns in the kernel's form.
    fn woodbury(&self, unknowns: &Unknowns) -> Result<Option<(Misfit, MassUnknowns)>> {
        let Observations::Laplace(l) = self.obs else {
            return Ok(None);
        };
        let chain = self.model.chain();
        let paper_sensor = l.sensor() == crate::detect::data::measurement::Sensor::PAPER;
        if unknowns.k() == 0
            || !chain.defects().is_empty()
            || chain.left().is_free()
            || chain.right().is_free()
            || !paper_sensor
        {
            return Ok(None);
        }
        let Ok(mass) = unknowns.to_mass() else {
            return Ok(None);
        };
        let sigma: Vec<f64> = match l.sigma() {
            Some(sg) => sg.to_vec(),
            None => vec![1.0; l.s().len()],
        };
        let data =
            crate::detect::data::exact::Data::at_nodes(l.s().to_vec(), l.values().to_vec(), sigma)?;
        Ok(Some((Misfit::at_nodes(chain, &data)?, mass)))
    }

    /// The Woodbury kernel's enumeration ranks every position set (beam
    /// search beyond `max_sets`) by the chi-square; returns the positions of
    /// the unknown-position defects (in slot order) of the `alternatives +
    /// 1` best sets, the number of sets ranked, whether the ranking was
    /// exhaustive, and the kernel's residual evaluations.
    fn woodbury_sets(
        &self,
        misfit: &Misfit,
        mass: &MassUnknowns,
    ) -> Result<(Vec<Vec<usize>>, usize, bool, usize)> {
        let base = match &self.given {
            Some(g) => g.enumerate.clone(),
            None => EnumerateOptions::default(),
        };
        let e = enumerate(
            misfit,
            mass,
            &EnumerateOptions {
                parallel: self.opts.parallel,
                max_sets: self.opts.max_sets,
                keep: self.opts.alternatives + 1,
                ..base
            },
        )?;
        let free = mass.free_positions();
        let sets = e
            .ranked
            .iter()
            .map(|h| free.iter().map(|&i| h.defects[i].0).collect())
            .collect();
        Ok((sets, e.sets, e.exhaustive, e.evaluations))
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
            let mut slots = unknowns.slots().to_vec();
            let mut at = q.iter();
            for slot in slots.iter_mut().filter(|s| s.at.is_none()) {
                slot.at = at.next().copied();
            }
            let u = Unknowns::new(
                self.model.n(),
                slots,
                unknowns.chain().to_vec(),
                *unknowns.kind_bounds(),
            )?;
            if let Ok(g) = fit_general(self.model.chain(), &u, coarse, fine, setup, gopts) {
                spent += g.evaluations;
                all.extend(g.ranked);
            }
        }
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
        let method = self
            .opts
            .method
            .stochastic()
            .ok_or_else(|| Error::Numerical {
                method: self.opts.method.name().into(),
                reason: "enumeration is not a stochastic search".into(),
            })?;
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

    #[allow(clippy::too_many_arguments)]
    pub(super) fn report(
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
        let base = self.model.chain();
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
        let cb = default_bounds(base, self.model.fitted());
        let params: Vec<ParamEstimate> = best
            .chain
            .iter()
            .map(|p| {
                let b = self
                    .model
                    .fitted()
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
            resolved: status == Status::Converged && gap_ok && all_ident && fits_data,
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
            exhaustive: f.exhaustive,
            trace: f.trace.clone(),
            wall_time_s: t0.elapsed().as_secs_f64(),
            predicted,
            identifiability: ident,
            modes,
            visibility: None,
        })
    }
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
