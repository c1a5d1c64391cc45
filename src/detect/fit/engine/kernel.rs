//! The paper's mass-only Woodbury kernel inside the data-first fit: when
//! it applies, every position set is ranked by the kernel's enumeration and
//! the best ones become hypotheses of the shared chi-square.

use super::Engine;
use crate::chain::Defect;
use crate::detect::data::laplace::LaplaceObs;
use crate::detect::data::observations::Observations;
use crate::detect::fit::general::{self, GeneralOptions, Hypothesis, Setup};
use crate::detect::misfit::time::TimeMisfit;
use crate::detect::misfit::Misfit;
use crate::detect::search::enumerate::{enumerate, fit_slots_from, EnumerateOptions};
use crate::detect::unknowns::{DefectKind, MassUnknown, MassUnknowns, Unknowns};
use crate::error::Result;

impl Engine<'_> {
    /// The paper's mass-only Woodbury kernel when the unknowns and data
    /// allow it: mass defects (free or known values and positions, no chain
    /// parameter) on Laplace values of the paper's setup (fixed ends,
    /// displacement of mass 1 after the impulse, no known defect in the
    /// model's chain): the chi-square of the values at their nodes
    /// ([`Misfit::at_nodes`]) and the unknowns in the kernel's form.
    pub(super) fn woodbury(&self, unknowns: &Unknowns) -> Result<Option<(Misfit, MassUnknowns)>> {
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
    /// search beyond `max_sets`) by the chi-square; returns the best
    /// `alternatives + 1` sets as the kernel fitted them, the number of sets ranked,
    /// whether the ranking was exhaustive, and the kernel's residual
    /// evaluations.
    pub(super) fn woodbury_sets(
        &self,
        misfit: &Misfit,
        mass: &MassUnknowns,
    ) -> Result<(Vec<KernelSet>, usize, bool, usize)> {
        let e = enumerate(misfit, mass, &self.enumerate_options())?;
        let free = mass.free_positions();
        let sets = e
            .ranked
            .into_iter()
            .map(|h| KernelSet {
                free: free.iter().map(|&i| h.defects[i].0).collect(),
                defects: h.defects,
                chi2: h.residual,
            })
            .collect();
        Ok((sets, e.sets, e.exhaustive, e.evaluations))
    }

    /// The options of the Woodbury kernel's enumeration.
    fn enumerate_options(&self) -> EnumerateOptions {
        let base = match &self.given {
            Some(g) => g.enumerate.clone(),
            None => EnumerateOptions::default(),
        };
        EnumerateOptions {
            parallel: self.opts.parallel,
            max_sets: self.opts.max_sets,
            keep: self.opts.alternatives + 1,
            ..base
        }
    }

    /// The kernel's fit of one set, also from the starts of the full
    /// refit ([`fit_general`]: every free mass at 2, 5 (its heavier retry)
    /// and 0.5 times the chain's mass), the lowest chi-square kept; and the
    /// kernel's evaluations spent.
    fn kernel_restarts(
        &self,
        misfit: &Misfit,
        mass: &MassUnknowns,
        set: &KernelSet,
    ) -> (KernelSet, usize) {
        let slots: Vec<(usize, MassUnknown)> = set
            .defects
            .iter()
            .zip(mass.defects())
            .map(|(d, u)| (d.0, u.mass))
            .collect();
        let opts = self.enumerate_options();
        let m = misfit.chain().mass();
        let mut best = set.clone();
        let mut spent = 0;
        for m0 in [2.0 * m, 5.0 * m, 0.5 * m] {
            let (defects, chi2, e) = fit_slots_from(misfit, &slots, &vec![m0; slots.len()], &opts);
            spent += e;
            if chi2 < best.chi2 {
                best.defects = defects;
                best.chi2 = chi2;
            }
        }
        (best, spent)
    }

    /// The kernel's best sets as hypotheses of the shared chi-square. The
    /// kernel has fitted every set's masses on the same nodes, weights and
    /// data, so its values are the shared fit's minimum already, once it has
    /// also tried the full refit's starts ([`Self::kernel_restarts`]: the
    /// kernel's grid start and the refit's starts can lead to different
    /// basins):
    ///
    /// * the best `REFIT` sets after the restarts (the answer and the
    ///   runner-up that sets the gap) are refitted by Levenberg-Marquardt on the shared chi-square
    ///   from the kernel's values, which converges in a few evaluations and
    ///   gives the shared fit's values, chi-square, standard errors and
    ///   convergence flag; a set whose fit fails, or ends with a free value
    ///   on a bound (where [`fit_general`]'s other starts might find a better
    ///   basin), also goes through the full [`Self::refit_sets`], the lower
    ///   chi-square kept;
    /// * the others are the kernel's fits as they are (values, chi-square,
    ///   Gauss-Newton standard errors of the kernel's Jacobian), at the
    ///   noise level `sigma` of the shared chi-square (the kernel weighs
    ///   values without errors by 1).
    ///
    /// Ranked by chi-square.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn refit_from_kernel(
        &self,
        unknowns: &Unknowns,
        sets: &[KernelSet],
        misfit: &Misfit,
        mass: &MassUnknowns,
        sigma: f64,
        coarse: &LaplaceObs,
        fine: Option<&TimeMisfit>,
        setup: &Setup,
        gopts: &GeneralOptions,
    ) -> Result<(Vec<Hypothesis>, usize)> {
        /// Sets refitted on the shared chi-square: the best and the runner-up.
        const REFIT: usize = 2;
        let mut all = Vec::with_capacity(sets.len());
        let mut spent = 0;
        // the restarts can reorder the sets: the best two after them are refitted
        let mut sets: Vec<KernelSet> = sets
            .iter()
            .map(|set| {
                let (set, e) = self.kernel_restarts(misfit, mass, set);
                spent += e;
                set
            })
            .collect();
        sets.sort_by(|a, b| a.chi2.total_cmp(&b.chi2));
        for (j, set) in sets.iter().enumerate() {
            let u = self.placed(unknowns, &set.free)?;
            if j >= REFIT {
                if let Ok(h) = self.kernel_hypothesis(&u, set, misfit, sigma) {
                    all.push(h);
                }
                continue;
            }
            let values: Vec<f64> = set.defects.iter().map(|d| d.1).collect();
            let quick = general::fit_placed_from(self.model.chain(), &u, &values, coarse, 100).ok();
            let on_bound = |h: &Hypothesis| {
                h.defects.iter().enumerate().any(|(i, d)| {
                    u.slots()[i].known.is_none() && {
                        let (lo, hi) = u.bounds(i, DefectKind::of(d));
                        let x = d.value();
                        let tol = 1e-9 * hi.abs().max(1.0);
                        x <= lo + tol || x >= hi - tol
                    }
                })
            };
            match quick {
                Some((h, e)) if h.converged && !on_bound(&h) => {
                    spent += e;
                    all.push(h);
                }
                quick => {
                    let (mut full, e) = self
                        .refit_sets(
                            unknowns,
                            std::slice::from_ref(&set.free),
                            coarse,
                            fine,
                            setup,
                            gopts,
                        )
                        .unwrap_or_default();
                    spent += e;
                    if let Some((h, e)) = quick {
                        spent += e;
                        full.push(h);
                    }
                    full.sort_by(|a, b| a.chi2.total_cmp(&b.chi2));
                    all.extend(full.into_iter().take(1));
                }
            }
        }
        self.ranked(all, spent)
    }

    /// One kernel fit as a hypothesis (`u` the unknowns placed at its
    /// positions): its masses and chi-square, and standard errors
    /// `sqrt(diag(H^-1))` of the free masses from the kernel's Gauss-Newton
    /// matrix `H = J^T J` at the fitted masses (NaN when `H` is singular; 0
    /// for a known mass). Values without errors, which the kernel weighs by
    /// 1, are weighed by `1 / sigma^2` in the shared chi-square: the
    /// chi-square and standard errors are scaled to it.
    fn kernel_hypothesis(
        &self,
        u: &Unknowns,
        set: &KernelSet,
        misfit: &Misfit,
        sigma: f64,
    ) -> Result<Hypothesis> {
        // the kernel's errors: the values' own, or 1 (Self::woodbury)
        let scale = match self.obs {
            Observations::Laplace(l) if l.sigma().is_none() => sigma,
            _ => 1.0,
        };
        let positions: Vec<usize> = set.defects.iter().map(|d| d.0).collect();
        let base = misfit.chain().mass();
        let dm: Vec<f64> = set.defects.iter().map(|d| d.1 - base).collect();
        let k = dm.len();
        let (mut g, mut h) = (vec![0.0; k], vec![0.0; k * k]);
        misfit.set(&positions).gauss_newton(&dm, &mut g, &mut h);
        let free: Vec<usize> = (0..k).filter(|&i| u.slots()[i].known.is_none()).collect();
        let hf =
            nalgebra::DMatrix::from_fn(free.len(), free.len(), |a, b| h[free[a] * k + free[b]]);
        let cov = hf.try_inverse();
        let mut std_errors = vec![0.0; k];
        for (a, &i) in free.iter().enumerate() {
            std_errors[i] = cov
                .as_ref()
                .map_or(f64::NAN, |c| c[(a, a)].max(0.0).sqrt() * scale);
        }
        let chain = self
            .model
            .chain()
            .uniform()
            .with_defects(set.defects.iter().map(|&(at, m)| Defect::Mass { at, m }))?;
        Ok(Hypothesis::from_parts(
            chain.defects().to_vec(),
            std_errors,
            Vec::new(),
            set.chi2 / (scale * scale),
        ))
    }
}

/// One position set as the Woodbury kernel's enumeration fitted it.
#[derive(Clone)]
pub(super) struct KernelSet {
    /// Positions of the unknown-position slots, in slot order.
    pub(super) free: Vec<usize>,
    /// `(position, mass)` of every slot, in slot order.
    defects: Vec<(usize, f64)>,
    /// The kernel's chi-square at these masses.
    chi2: f64,
}
