//! The data-first fit's report, assembled from the chosen [`KFit`]: the
//! answer's defects and chain parameters with their errors and flags, the
//! alternatives, the goodness of fit, the judge's verdict
//! ([`super::judge`]), the fitted chain's modes and the predicted series.

use super::chainfit::default_bounds;
use super::engine::{Engine, KFit, MODES_MAX_N};
use super::general::{self, identify_general, Hypothesis};
use super::goodness::{exact_record, FITS_DATA_P};
use super::identify::Identifiability;
use super::judge::{judge, Bar, Evidence};
use super::report::Unseen;
use super::report::{
    Alternative, DefectEstimate, FitReport, KRow, ModeEstimate, ParamEstimate, Predicted,
    SensorEstimate,
};
use super::{identify, noise, select};
use crate::chain::Chain;
use crate::detect::data::observations::Observations;
use crate::detect::unknowns::{DefectKind, KindBounds};
use crate::error::Result;
use std::time::Instant;

impl Engine<'_> {
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
        let ranked = rescaled(&f.ranked, scale);
        let best = &ranked[0];
        let ident = identify_general(&ranked, self.model.chain(), sigma, None).ok();
        let defects = self.defect_estimates(best, ident.as_ref());
        let params = self.param_estimates(best);
        let alternatives = self.alternatives_of(&ranked);
        let sensors = self.sensor_estimates(f, sigma, estimated);
        let (fits_data, p, hint) = self.data_fit(f, chi2_final, estimated, &sensors);
        let unseen = self.unseen_of(f, best, scale);
        let k_margin = self.k_caveat(&rows, f.k, &criterion, unseen.as_ref());
        let verdict = judge(
            &Evidence {
                k: f.k,
                budget_exhausted: f.budget_exhausted.then_some(self.opts.max_evals),
                converged: best.converged,
                at_bound: defects.iter().any(|d| d.at_bound) || params.iter().any(|p| p.at_bound),
                all_identifiable: defects.iter().all(|d| d.identifiable) && k_margin.is_none(),
                unidentified: first_unidentified(ident.as_ref()).or(k_margin.as_deref()),
                runner_up_gap: alternatives.first().map(|a| a.gap),
                fits_data,
                mismatch_hint: hint.as_deref(),
                one_kind: self.searched_one_kind(),
            },
            Bar::ChiSquare(identify::DEFAULT_THRESHOLD),
        );
        Ok(FitReport {
            defects,
            k: f.k,
            params,
            noise_sigma: sigma,
            noise_estimated: estimated,
            sensors,
            chi2: chi2_final,
            dof: f.dof,
            status: verdict.status,
            message: verdict.message,
            resolved: verdict.resolved,
            fits_data,
            fit_p_value: p,
            alternatives,
            k_selection: rows,
            criterion,
            misfit: f.misfit_name.clone(),
            setup: self.setup_line(),
            method: f.method_name.clone(),
            evaluations,
            sets_fitted: f.hypotheses,
            exhaustive: f.exhaustive,
            trace: f.trace.clone(),
            wall_time_s: t0.elapsed().as_secs_f64(),
            screened: false,
            predicted: self.predicted(f),
            modes: fitted_modes(best, self.model.chain()),
            trigger: None,
            identifiability: ident,
            visibility: None,
            unseen,
            noise_model: self.noise_model_report(sigma),
            whiteness_p: self.whiteness_p(f),
            nuisance: self.nuisance_estimates(best, sigma).unwrap_or_default(),
            damping: None,
            baseline: self.baseline_source(),
            level: self.opts.level,
            posterior: None,
        })
    }

    /// Where the model's measured baseline came from, if it has one.
    fn baseline_source(&self) -> Option<String> {
        let baseline = self.model.chain().baseline();
        baseline.map(|b| b.source().to_string())
    }

    /// The runners-up of `ranked` (after its best), at most the options'
    /// count, with their gaps to the best.
    fn alternatives_of(&self, ranked: &[Hypothesis]) -> Vec<Alternative> {
        ranked[1..]
            .iter()
            .take(self.opts.alternatives)
            .map(|h| Alternative::new(h.defects.clone(), h.chi2, ranked[0].chi2))
            .collect()
    }

    /// Why the number of defects `k` is not settled, if it is not: the
    /// criterion's margin or the largest count searched chosen, and a
    /// further defect the data would not show ([`Unseen`]).
    fn k_caveat(
        &self,
        rows: &[KRow],
        k: usize,
        criterion: &str,
        unseen: Option<&Unseen>,
    ) -> Option<String> {
        let first = self
            .k_margin(rows, k, criterion)
            .or_else(|| self.k_at_limit(rows, k));
        let hidden = unseen.filter(|u| !u.elements.is_empty()).map(Unseen::line);
        match (first, hidden) {
            (Some(a), Some(b)) => Some(format!("{a}; {b}")),
            (a, b) => a.or(b),
        }
    }

    /// When the criterion chose the largest number of defects searched
    /// (`auto:K`, with fewer than `n`): more may be there, or the chain
    /// differs from the model everywhere (a measured baseline?).
    fn k_at_limit(&self, rows: &[KRow], k: usize) -> Option<String> {
        let super::options::DefectCount::Auto { k_max } = self.opts.defects else {
            return None;
        };
        let searched = rows.iter().map(|r| r.k).max()?;
        (k == k_max && searched == k_max && k_max > 0 && k_max < self.model.chain().n()).then(|| {
            format!(
                "the criterion chose the largest number of defects searched (k = {k_max}): the record may hold more changes (try --defects auto:{}), or the chain differs from the model everywhere (a measured profile: --baseline)",
                k_max + 2
            )
        })
    }

    /// The best answer's defects with their standard errors, bound and
    /// identifiability flags (known defects flagged, with no error).
    fn defect_estimates(
        &self,
        best: &Hypothesis,
        ident: Option<&identify::Identifiability>,
    ) -> Vec<DefectEstimate> {
        let base = self.model.chain();
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
            let rep = ident.and_then(|r| r.defects.iter().find(|x| x.at == d.at()));
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
                baseline: base.baseline().map(|_| d.base_value(base)),
                identifiable: is_known || rep.is_some_and(|r| r.identifiable),
                interval: is_known.then_some([v, v]),
                interval_method: is_known.then_some("known"),
            });
        }
        defects
    }

    /// The best answer's fitted chain parameters, flagged on their bounds.
    fn param_estimates(&self, best: &Hypothesis) -> Vec<ParamEstimate> {
        let cb = default_bounds(self.model.chain(), self.model.fitted());
        best.chain
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
                    interval: None,
                    interval_method: None,
                }
            })
            .collect()
    }

    /// Whether the answer explains the data, the goodness-of-fit p-value,
    /// and the mismatch message's hint: the residual is noise
    /// ([`goodness_of_fit`]), every sensor or record agrees
    /// ([`Engine::disagreeing`]) and a coloured noise model settled
    /// ([`RecordModel::unsettled`](super::record::RecordModel::unsettled)).
    fn data_fit(
        &self,
        f: &KFit,
        chi2_final: f64,
        estimated: bool,
        sensors: &[SensorEstimate],
    ) -> (bool, f64, Option<String>) {
        let disagree = self.disagreeing(sensors);
        let (fits_data, p) = goodness_of_fit(f, chi2_final, estimated);
        let unsettled = self.record.unsettled();
        let fits_data = fits_data && disagree.is_none() && unsettled.is_none();
        let hint = disagree
            .or(unsettled)
            .or_else(|| (!fits_data).then(|| self.mismatch_hint(f)).flatten());
        (fits_data, p, hint)
    }

    /// The sensors or records of a joint fit whose own residual is not
    /// noise ([`SensorEstimate::fits_data`]), as the mismatch message's
    /// hint; `None` when every one agrees.
    fn disagreeing(&self, sensors: &[SensorEstimate]) -> Option<String> {
        let records = matches!(self.obs, Observations::Series(s) if s.separate_records());
        let bad: Vec<String> = sensors
            .iter()
            .enumerate()
            .filter(|(_, e)| !e.fits_data)
            .map(|(j, e)| match records {
                true => format!("record {} (p = {:.1e})", j + 1, e.whiteness_p),
                false => format!("the sensor at mass {} (p = {:.1e})", e.at, e.whiteness_p),
            })
            .collect();
        (!bad.is_empty()).then(|| {
            format!(
                "that the joint answer does not explain {}: its own residual is not noise (Ljung-Box), so it disagrees with the others (another chain, or a fault of that test)",
                bad.join(", ")
            )
        })
    }

    /// Every sensor of a record of several with its noise level: its
    /// residual's estimate, or the given level (empty for one sensor).
    fn sensor_estimates(&self, f: &KFit, sigma: f64, estimated: bool) -> Vec<SensorEstimate> {
        let Observations::Series(s) = self.obs else {
            return Vec::new();
        };
        if s.others().is_empty() {
            return Vec::new();
        }
        let levels = f.sensor_levels();
        s.sensors()
            .enumerate()
            .map(|(j, o)| {
                let scale = match j {
                    0 => 1.0,
                    j => self.record.scales.get(j - 1).copied().unwrap_or(1.0),
                };
                let whiteness_p = f.sensors.get(j).map_or(f64::NAN, |r| r.2);
                // an exact record's residual is its rounding (as for one
                // sensor, [`goodness_of_fit`])
                let exact = f
                    .sensors
                    .get(j)
                    .is_some_and(|&(rss, n, _)| estimated && exact_record(rss, n, o.max_abs()));
                SensorEstimate {
                    record: if s.separate_records() { j + 1 } else { 0 },
                    at: o.measurement().sensor().at,
                    kind: o.measurement().sensor().kind.name().to_string(),
                    samples: o.x().len(),
                    sigma: match levels.get(j) {
                        Some(&l) if estimated => l,
                        _ => sigma * scale,
                    },
                    whiteness_p,
                    fits_data: whiteness_p.is_nan() || whiteness_p >= FITS_DATA_P || exact,
                }
            })
            .collect()
    }

    /// The predicted series next to the observed one (series data only).
    fn predicted(&self, f: &KFit) -> Option<Predicted> {
        match (self.obs, &f.predicted) {
            (Observations::Series(s), Some((model, r))) => Some(Predicted {
                t: s.t().to_vec(),
                observed: s.x().to_vec(),
                model: model.clone(),
                residual: r.clone(),
            }),
            _ => None,
        }
    }

    /// What the data measured and the chain's ends.
    fn setup_line(&self) -> String {
        let base = self.model.chain();
        format!(
            "{}; ends {}-{}",
            match self.obs {
                Observations::Series(s) if !s.others().is_empty() => {
                    let d: Vec<String> = s.sensors().map(|o| o.measurement().describe()).collect();
                    d.join("; ")
                }
                Observations::Series(s) => s.measurement().describe(),
                Observations::Laplace(l) => format!(
                    "{} of mass {} (Laplace values)",
                    l.sensor().kind.name(),
                    l.sensor().at
                ),
            },
            base.left(),
            base.right()
        )
    }
}

/// The hypotheses with their chi-squares and standard errors at a noise
/// level `scale` times the one they were fitted at.
fn rescaled(ranked: &[Hypothesis], scale: f64) -> Vec<Hypothesis> {
    ranked
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
        .collect()
}

/// Whether the residual is consistent with noise, and the p-value: the
/// Ljung-Box whiteness test of the time residual when sigma was estimated,
/// the chi-square test otherwise. An estimated residual below
/// [`EXACT_RECORD_RESIDUAL`](super::goodness::EXACT_RECORD_RESIDUAL) of
/// the record's peak fits (an exact record: the residual is its
/// rounding), with the test's p-value still reported.
fn goodness_of_fit(f: &KFit, chi2_final: f64, estimated: bool) -> (bool, f64) {
    match (&f.predicted, estimated) {
        (Some((model, r)), true) => {
            // under a record model: the whitened residual's whiteness
            let p = noise::ljung_box(f.whitened.as_deref().unwrap_or(r), 20).1;
            let peak = model.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            let rss = r.iter().map(|v| v * v).sum::<f64>();
            (p >= FITS_DATA_P || exact_record(rss, r.len(), peak), p)
        }
        _ => {
            let p = select::chi2_sf(chi2_final, f.dof.max(1) as f64);
            (p >= FITS_DATA_P, p)
        }
    }
}

/// [`goodness_of_fit`] of `f` at the final noise level `sigma`.
pub(super) fn fits_data(f: &KFit, sigma: f64, estimated: bool) -> bool {
    let scale = sigma / f.sigma_fit;
    goodness_of_fit(f, f.chi2 / (scale * scale), estimated).0
}

/// The fitted chain's natural modes (none when the eigen solver refuses, or
/// for a non-uniform chain above [`MODES_MAX_N`]: the dense eigen solver is
/// O(n^3) and would dominate the fit).
fn fitted_modes(best: &Hypothesis, base: &Chain) -> Vec<ModeEstimate> {
    best.to_chain(base)
        .and_then(|c| {
            if c.n() > MODES_MAX_N && !c.defects().is_empty() {
                return Ok(Vec::new());
            }
            crate::time::modal::natural_modes(&c)
        })
        .map(|v| {
            v.iter()
                .map(|m| ModeEstimate {
                    omega: m.omega,
                    frequency: m.frequency,
                    zeta: m.zeta.unwrap_or(f64::NAN),
                })
                .collect()
        })
        .unwrap_or_default()
}

/// The reason of the first defect the identifiability report flags.
fn first_unidentified(ident: Option<&Identifiability>) -> Option<&str> {
    ident.and_then(|r| {
        r.defects
            .iter()
            .find(|d| !d.identifiable)
            .map(|d| d.reason.as_str())
    })
}
