//! Fitting the defect values of one position set: the short coarse fit
//! of the screen and the coarse pass, on the rational form of the set's
//! Laplace model where it applies (else the chain), and the fit to
//! convergence from two starts.

use super::Hypothesis;
use crate::chain::{Chain, Defect};
use crate::detect::data::laplace::LaplaceObs;
use crate::detect::fit::chainfit::ChainProblem;
use crate::detect::misfit::laplace_sets::{SetModel, SetTables};
use crate::detect::model::MeasurementModel;
use crate::detect::search::lsq::{levenberg_marquardt, LeastSquares, LmOptions};
use crate::detect::unknowns::{DefectKind, Unknowns};
use crate::error::{Error, Result};
use crate::sensitivity::Param;

/// Starting values of a defect value of `kind` on `base`, heavier (or
/// stiffer) and lighter than the uniform value: the coarse pass starts
/// from each, the second is also the alternative start of the fine pass.
pub(super) fn starts(kind: DefectKind, base: &Chain) -> [f64; 2] {
    [kind.start(base), kind.alt_start(base)]
}

/// How far a value fit goes ([`fit_pairs`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Tol {
    /// The driver's defaults (relative chi-square decrease `1e-10`).
    Full,
    /// The fits whose values only rank a hypothesis or start a later fit
    /// (the screen, the coarse pass, the Laplace fine pass ahead of a
    /// time-domain refit) and the time-domain refit itself: stop at a
    /// relative chi-square decrease of `1e-8`, of the last step or the one
    /// the Gauss-Newton model predicts for the next
    /// ([`LmOptions::predicted_stop`]). The chi-square is then within about
    /// `1e-8` relative of its minimum (`6e-5` for a time chi-square of 6000
    /// samples: far below one, the scale on which hypotheses differ), the
    /// values within a few thousandths of their standard errors of it; the
    /// last Gauss-Newton steps, each a residual and a Jacobian (in the time
    /// domain a modal decomposition each), are saved.
    Seed,
}

impl Tol {
    fn options(self, max_iter: usize) -> LmOptions {
        match self {
            Tol::Full => LmOptions {
                max_iter,
                ..LmOptions::default()
            },
            Tol::Seed => LmOptions {
                max_iter,
                rtol: 1e-8,
                predicted_stop: true,
                ..LmOptions::default()
            },
        }
    }
}

/// The coarse fit of one hypothesis: [`fit_pairs`] from `values`; when a
/// fitted value ends on a bound of its range (the mark of a wrong basin:
/// from too light a start the Levenberg-Marquardt path can drive a deep
/// defect to its bound while a shallower one compensates), once more from
/// 2.5 times heavier starts, keeping the lower chi-square. Measured on the
/// noise study's System 2 at 1e-6 noise: one seed in 20 lost the truth this
/// way on the Bromwich line (chi2 6.9e10 against 71 at the truth).
pub(super) fn fit_pairs_coarse(
    unknowns: &Unknowns,
    pairs: &[(DefectKind, usize)],
    values: &[f64],
    fit: impl Fn(&[f64]) -> Result<Fitted>,
) -> Result<Fitted> {
    let first = fit(values);
    let on_bound = |f: &Fitted| {
        f.hyp.defects.iter().enumerate().any(|(i, d)| {
            unknowns.slots()[i].known.is_none() && {
                let (lo, hi) = unknowns.bounds(i, pairs[i].0);
                let v = d.value();
                let tol = 1e-9 * hi.abs().max(1.0);
                v <= lo + tol || v >= hi - tol
            }
        })
    };
    match first {
        Ok(f) if !on_bound(&f) => Ok(f),
        first => {
            let heavier: Vec<f64> = values.iter().map(|v| 2.5 * v).collect();
            match (first, fit(&heavier)) {
                // the heavier retry's error, as before, when both fail
                (Err(_), Err(e)) => Err(e),
                (a, b) => better(a, b),
            }
        }
    }
}

/// The better of two fits of one hypothesis (the lower chi-square; the first
/// on a tie), charged with the evaluations of both; the first error when
/// neither succeeded.
pub(super) fn better(a: Result<Fitted>, b: Result<Fitted>) -> Result<Fitted> {
    match (a, b) {
        (Ok(a), Ok(b)) => {
            let evaluations = a.evaluations + b.evaluations;
            let mut best = if b.hyp.chi2 < a.hyp.chi2 { b } else { a };
            best.evaluations = evaluations;
            Ok(best)
        }
        (Ok(a), Err(_)) => Ok(a),
        (Err(_), Ok(b)) => Ok(b),
        (Err(e), Err(_)) => Err(e),
    }
}

/// A set's rational model as a least-squares problem.
pub(super) struct Rational<'t>(SetModel<'t>);

impl LeastSquares for Rational<'_> {
    fn residuals(&self, theta: &[f64]) -> Result<Vec<f64>> {
        self.0.residuals(theta)
    }

    fn jacobian(&self, theta: &[f64]) -> Result<nalgebra::DMatrix<f64>> {
        self.0.jacobian(theta)
    }
}

/// [`fit_pairs`] of the defect values alone (chain parameters held) on the
/// rational form of the set's Laplace model ([`SetTables`]): the same
/// residuals and Jacobian to rounding, a few products per node instead of a
/// transfer sweep. `None` when the form does not apply to the set. The
/// hypothesis carries no standard errors (NaN): the coarse pass ranks and
/// seeds, it does not report.
pub(super) fn fit_pairs_fast(
    tables: &SetTables<'_>,
    base: &Chain,
    unknowns: &Unknowns,
    pairs: &[(DefectKind, usize)],
    values: &[f64],
    max_iter: usize,
    tol: Tol,
) -> Option<Result<Fitted>> {
    let slots = unknowns.slots();
    let mut sites = Vec::with_capacity(pairs.len());
    let mut uniform = Vec::with_capacity(pairs.len());
    let mut fixed = Vec::with_capacity(pairs.len());
    let mut theta0 = Vec::new();
    let mut bounds = Vec::new();
    for (i, (&(kind, at), &v)) in pairs.iter().zip(values).enumerate() {
        sites.push(kind.site_in(base, at));
        uniform.push(kind.base_at(base, at));
        fixed.push(slots[i].known);
        if slots[i].known.is_none() {
            let b = unknowns.bounds(i, kind);
            theta0.push(v.clamp(b.0, b.1));
            bounds.push(b);
        }
    }
    let model = tables.set(&sites, &uniform, &fixed)?;
    let defects_at = |theta: &[f64]| -> Vec<Defect> {
        let mut it = theta.iter();
        pairs
            .iter()
            .zip(&fixed)
            .map(|(&(kind, at), known)| {
                kind.defect(
                    at,
                    known.unwrap_or_else(|| *it.next().expect("one per slot")),
                )
            })
            .collect()
    };
    if theta0.is_empty() {
        return Some(
            model
                .residuals(&[])
                .map(|r| Fitted::held(defects_at(&[]), &r)),
        );
    }
    Some(
        levenberg_marquardt(&Rational(model), &theta0, &bounds, &tol.options(max_iter)).map(|lm| {
            Fitted {
                hyp: Hypothesis {
                    defects: defects_at(&lm.theta),
                    std_errors: vec![f64::NAN; pairs.len()],
                    chain: Vec::new(),
                    chi2: lm.chi2,
                    converged: lm.converged,
                },
                evaluations: lm.evaluations,
                m: lm.m,
            }
        }),
    )
}

/// The values of one fully placed hypothesis (every slot of `unknowns` at a
/// position) refitted on `obs` by Levenberg-Marquardt to convergence from
/// `values` (one per slot, in slot order; known values override), with the
/// unknowns' chain parameters from `base`'s values: what the fine pass of
/// [`fit_general`](super::fit_general) does for one start. Returns the hypothesis and the
/// residual evaluations spent.
///
/// For a start already at the minimum (the Woodbury kernel's fit of the same
/// chi-square) it converges in a few evaluations.
///
/// # Errors
/// An unknown-position slot in `unknowns` (field `unknowns`); as the fit.
pub(crate) fn fit_placed_from(
    base: &Chain,
    unknowns: &Unknowns,
    values: &[f64],
    obs: &LaplaceObs,
    max_iter: usize,
) -> Result<(Hypothesis, usize)> {
    if unknowns.slots().iter().any(|s| s.at.is_none()) || values.len() != unknowns.k() {
        return Err(Error::invalid(
            "unknowns",
            "a slot without a position",
            "every slot placed, one start value per slot",
        ));
    }
    let hyps = unknowns.hypotheses(1)?;
    let pairs = hyps.first().ok_or_else(|| Error::Numerical {
        method: "fit_placed_from".into(),
        reason: "no hypothesis".into(),
    })?;
    fit_pairs_from(
        &base.uniform(),
        unknowns,
        pairs,
        values,
        obs,
        max_iter,
        true,
    )
}

/// Fit the `(kind, position)` pairs `pairs` of `unknowns` (one per slot, in
/// slot order) on any measurement model `obs`, from `values` and the chain
/// parameters of `base` (fitted too `with_chain`, else held), to full
/// tolerance: a warm start (the fit at `k + 1` defects from the fit at
/// `k`). Levenberg-Marquardt accepts only steps that lower the chi-square,
/// so the answer is never worse than the start.
///
/// # Errors
/// A pair count other than the unknowns' slot count; as the fit.
pub(crate) fn fit_pairs_from(
    base: &Chain,
    unknowns: &Unknowns,
    pairs: &[(DefectKind, usize)],
    values: &[f64],
    obs: &dyn MeasurementModel,
    max_iter: usize,
    with_chain: bool,
) -> Result<(Hypothesis, usize)> {
    if pairs.len() != unknowns.k() || values.len() != pairs.len() {
        return Err(Error::invalid(
            "pairs",
            pairs.len(),
            format!("{} pairs and values, one per slot", unknowns.k()),
        ));
    }
    let chain_bounds = crate::detect::fit::chainfit::default_bounds(base, unknowns.chain());
    let f = fit_pairs(
        base,
        unknowns,
        pairs,
        values,
        &chain_bounds,
        with_chain,
        obs,
        max_iter,
        Tol::Full,
    )?;
    Ok((f.hyp, f.evaluations))
}

/// One fitted hypothesis and what it cost.
#[derive(Clone)]
pub(super) struct Fitted {
    pub(super) hyp: Hypothesis,
    pub(super) evaluations: usize,
    pub(super) m: usize,
}

impl Fitted {
    /// A hypothesis with every value held (nothing to fit): its residuals
    /// `r`, one evaluation.
    fn held(defects: Vec<Defect>, r: &[f64]) -> Fitted {
        Fitted {
            hyp: Hypothesis {
                std_errors: vec![0.0; defects.len()],
                defects,
                chain: Vec::new(),
                chi2: r.iter().map(|v| v * v).sum(),
                converged: true,
            },
            evaluations: 1,
            m: r.len(),
        }
    }
}

/// Fit the values of the hypothesis `pairs` of `unknowns` (and, with
/// `with_chain`, its chain parameters) on `base` (whose uniform parameters
/// are the current chain estimates), from `values` (one per slot; known
/// values override), within the bounds (`chain_bounds` per chain parameter).
#[allow(clippy::too_many_arguments)]
pub(super) fn fit_pairs(
    base: &Chain,
    unknowns: &Unknowns,
    pairs: &[(DefectKind, usize)],
    values: &[f64],
    chain_bounds: &[(f64, f64)],
    with_chain: bool,
    obs: &dyn MeasurementModel,
    max_iter: usize,
    tol: Tol,
) -> Result<Fitted> {
    let slots = unknowns.slots();
    let mut theta0 = Vec::new();
    let mut bounds = Vec::new();
    let mut params = Vec::new();
    let mut defects = Vec::with_capacity(pairs.len());
    for (i, (&(kind, at), &v)) in pairs.iter().zip(values).enumerate() {
        let b = unknowns.bounds(i, kind);
        match slots[i].known {
            Some(known) => defects.push(kind.defect(at, known)),
            None => {
                let v = v.clamp(b.0, b.1);
                defects.push(kind.defect(at, v));
                params.push(Param::Defect(i));
                theta0.push(v);
                bounds.push(b);
            }
        }
    }
    if with_chain {
        for (p, b) in unknowns.chain().iter().zip(chain_bounds) {
            params.push(*p);
            theta0.push(p.get(base)?.clamp(b.0, b.1));
            bounds.push(*b);
        }
    }
    let chain = base.uniform().with_defects(defects)?;
    if params.is_empty() {
        let r = obs.residuals(&chain)?;
        return Ok(Fitted::held(chain.defects().to_vec(), &r));
    }
    let problem = ChainProblem::new(&chain, &params, obs)?;
    let lm = levenberg_marquardt(&problem, &theta0, &bounds, &tol.options(max_iter))?;
    let fitted = problem.chain(&lm.theta)?;
    Ok(Fitted {
        hyp: Hypothesis::from_fit(&params, &lm, &fitted, pairs.len(), |p| p.name(&fitted)),
        evaluations: lm.evaluations,
        m: lm.m,
    })
}
