//! The judge of a fit: one function, [`judge`], sets the report's
//! `status`, `resolved` and message, for the data-first path
//! ([`crate::detect::fit::fit`]) and the scene path
//! ([`crate::detect::fit::paper::fit`]) alike.
//!
//! The evidence ([`Evidence`]) is what the search and the fit say about the
//! best answer: whether a stochastic search used its whole budget, whether
//! the value fit converged, whether a value ended on a bound, the gap to the
//! runner-up, the identifiability of each defect, and whether the residual is
//! consistent with the data's errors. The bar ([`Bar`]) is what a gap must
//! exceed: the chi-square threshold of the data path, or the scene data's
//! error floor on the paper's residual.
//!
//! The status is the first that applies of: budget exhausted, stalled,
//! model mismatch (on the data path: the residual is not noise, so no
//! answer of this model explains the data; on the scene path's floor: the
//! residual is more than 4 times the floor, so the answer lacks a defect
//! or the search missed the truth), value at bound, not
//! identifiable (a defect flagged, or the runner-up within the bar),
//! converged. `resolved` is, on the data path, converged
//! with the runner-up above the bar, every defect identifiable and the
//! residual consistent with noise; on the scene path's floor, the
//! runner-up above the floor and the residual within 4 floors.
//!
//! ```
//! use springmass::detect::fit::judge::{judge, Bar, Evidence};
//! use springmass::detect::fit::report::Status;
//! let e = Evidence { k: 2, runner_up_gap: Some(40.0), ..Evidence::default() };
//! let v = judge(&e, Bar::ChiSquare(9.0));
//! assert_eq!(v.status, Status::Converged);
//! assert!(v.resolved);
//! let v = judge(&Evidence { runner_up_gap: Some(4.0), ..e }, Bar::ChiSquare(9.0));
//! assert_eq!(v.status, Status::NotIdentifiable);
//! assert!(!v.resolved);
//! ```

use super::report::{FitReport, Status};

/// What the search and the fit say about the best answer.
#[derive(Clone, Debug, PartialEq)]
pub struct Evidence<'a> {
    /// Defects fitted (known ones excluded).
    pub k: usize,
    /// `Some(max_evals)` when a stochastic search used its whole budget.
    pub budget_exhausted: Option<usize>,
    /// The value fit of the best answer met its tolerance.
    pub converged: bool,
    /// A fitted value (defect or chain parameter) ended on a bound of its range.
    pub at_bound: bool,
    /// Every defect is identifiable (see [`crate::detect::fit::identify`]).
    pub all_identifiable: bool,
    /// Why the first defect that is not identifiable is not (when known).
    pub unidentified: Option<&'a str>,
    /// `chi2 (or residual) of the runner-up - the best's`; `None` without a runner-up.
    pub runner_up_gap: Option<f64>,
    /// The residual is consistent with the data's errors.
    pub fits_data: bool,
    /// What a residual that is not noise suggests (a trend, colour, an
    /// early misfit), for the model-mismatch message.
    pub mismatch_hint: Option<&'a str>,
    /// The search tried one defect kind only (`--kinds mass`, or masses by
    /// default with another search or in a long chain): a
    /// model mismatch or a value at a bound may be a defect of another
    /// kind, and their messages say how to search for it.
    pub one_kind: bool,
}

impl Default for Evidence<'_> {
    /// A converged fit of no defect, nothing flagged.
    fn default() -> Self {
        Evidence {
            k: 0,
            budget_exhausted: None,
            converged: true,
            at_bound: false,
            all_identifiable: true,
            unidentified: None,
            runner_up_gap: None,
            fits_data: true,
            mismatch_hint: None,
            one_kind: false,
        }
    }
}

/// What a gap to the runner-up must exceed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Bar {
    /// The data path: a chi-square gap threshold
    /// ([`crate::detect::fit::identify::DEFAULT_THRESHOLD`]).
    ChiSquare(f64),
    /// The scene path: the data's error floor on the paper's residual.
    Floor(f64),
}

/// The judgement.
#[derive(Clone, Debug, PartialEq)]
pub struct Verdict {
    /// How the fit ended.
    pub status: Status,
    /// Whether the data resolve the answer (see the module doc).
    pub resolved: bool,
    /// One line on the status.
    pub message: String,
}

/// Judge the evidence against the bar (see the module doc).
pub fn judge(e: &Evidence<'_>, bar: Bar) -> Verdict {
    let (threshold, floor) = match bar {
        Bar::ChiSquare(t) => (t, false),
        Bar::Floor(f) => (f, true),
    };
    let gap_ok = e.runner_up_gap.is_none_or(|g| g > threshold);
    let (status, message) = status(e, gap_ok, threshold, floor);
    let resolved = if floor {
        gap_ok && e.fits_data
    } else {
        status == Status::Converged && gap_ok && e.all_identifiable && e.fits_data
    };
    Verdict {
        status,
        resolved,
        message,
    }
}

/// What a mismatch or a value at a bound adds when one defect kind was
/// searched: a defect of another kind fits neither.
const OTHER_KINDS: &str = "; or a defect of a kind the search left out: try --kinds any";

/// The status and its message: the first cause that applies.
fn status(e: &Evidence<'_>, gap_ok: bool, threshold: f64, floor: bool) -> (Status, String) {
    if let Some(budget) = e.budget_exhausted {
        return (
            Status::BudgetExhausted,
            format!("the search used its whole budget of {budget} evaluations; raise max_evals or use enumerate"),
        );
    }
    if !e.converged {
        return (
            Status::Stalled,
            "the value fit of the best hypothesis stopped at its iteration limit without meeting its tolerance: the values may not be at the minimum".to_string(),
        );
    }
    if !floor && !e.fits_data {
        let mut message = "the best answer does not explain the data: its residual is not noise (see fits_data and its p-value); the chain, damping or noise model, or the record (an offset, a drift, a late trigger), differs from the data's".to_string();
        if let Some(h) = e.mismatch_hint {
            message.push_str(&format!("; the residual shows {h}"));
        }
        if e.one_kind {
            message.push_str(OTHER_KINDS);
        }
        return (Status::ModelMismatch, message);
    }
    if floor && !e.fits_data {
        return (
            Status::ModelMismatch,
            format!("the answer does not explain the data: its residual is far above the data's error floor {threshold:.3e}; a defect missing from the unknowns, or the search missed the truth (try the enumeration)"),
        );
    }
    if e.at_bound {
        let mut message = "a fitted value ended on a bound of its range: a wrong basin, or a defect outside the range searched".to_string();
        if e.one_kind {
            message.push_str(OTHER_KINDS);
        }
        return (Status::ValueAtBound, message);
    }
    let gap = e.runner_up_gap.unwrap_or(0.0);
    if floor && !gap_ok {
        return (
            Status::NotIdentifiable,
            format!("the runner-up fits within the data's error floor: residual gap {gap:.3e} <= floor {threshold:.3e}"),
        );
    }
    if !e.all_identifiable || !gap_ok {
        let why = e.unidentified.map(str::to_string).unwrap_or_else(|| {
            format!("the runner-up fits within a chi-square gap of {gap:.3} < {threshold}")
        });
        return (Status::NotIdentifiable, why);
    }
    if e.k == 0 {
        return (
            Status::Converged,
            "no defect: the uniform chain explains the data".to_string(),
        );
    }
    let what = if floor { "residual" } else { "chi-square" };
    (
        Status::Converged,
        format!(
            "every defect identifiable; the runner-up is worse by {what} {}",
            e.runner_up_gap
                .map_or("(none)".into(), |g| format!("{g:.3e}"))
        ),
    )
}

/// The evidence a data-first report carries, for a judge against another
/// bar (the scene path's floor): its status says whether the search used its
/// budget (`max_evals`) and whether the value fit stalled (the statuses come
/// in the judge's order, so what a status hides does not change the
/// judgement); the scene's floor replaces the chi-square identifiability.
pub fn evidence_of(r: &FitReport, max_evals: usize) -> Evidence<'static> {
    Evidence {
        k: r.k,
        budget_exhausted: (r.status == Status::BudgetExhausted).then_some(max_evals),
        converged: r.status != Status::Stalled,
        at_bound: r.defects.iter().any(|d| d.at_bound) || r.params.iter().any(|p| p.at_bound),
        all_identifiable: true,
        unidentified: None,
        runner_up_gap: r.alternatives.first().map(|a| a.gap),
        fits_data: r.fits_data,
        mismatch_hint: None,
        one_kind: false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_first_cause_wins_and_resolved_follows_the_bar() {
        let ok = Evidence {
            k: 1,
            runner_up_gap: Some(20.0),
            ..Evidence::default()
        };
        let v = judge(&ok, Bar::ChiSquare(9.0));
        assert_eq!((v.status, v.resolved), (Status::Converged, true));
        assert!(v.message.contains("2.000e1"), "{}", v.message);
        // budget before stall before bound
        let e = Evidence {
            budget_exhausted: Some(100),
            converged: false,
            at_bound: true,
            ..ok.clone()
        };
        let v = judge(&e, Bar::ChiSquare(9.0));
        assert_eq!((v.status, v.resolved), (Status::BudgetExhausted, false));
        assert!(v.message.contains("100 evaluations"));
        let v = judge(
            &Evidence {
                budget_exhausted: None,
                ..e.clone()
            },
            Bar::ChiSquare(9.0),
        );
        assert_eq!(v.status, Status::Stalled);
        let v = judge(
            &Evidence {
                budget_exhausted: None,
                converged: true,
                ..e
            },
            Bar::ChiSquare(9.0),
        );
        assert_eq!(v.status, Status::ValueAtBound);
        // a flagged defect gives its reason
        let v = judge(
            &Evidence {
                all_identifiable: false,
                unidentified: Some("too close"),
                ..ok.clone()
            },
            Bar::ChiSquare(9.0),
        );
        assert_eq!(
            (v.status, v.message.as_str()),
            (Status::NotIdentifiable, "too close")
        );
        // not consistent with noise: a model mismatch, never resolved, and
        // before a value on a bound (often its consequence)
        let misfit = Evidence {
            fits_data: false,
            ..ok.clone()
        };
        let v = judge(
            &Evidence {
                at_bound: true,
                ..misfit.clone()
            },
            Bar::ChiSquare(9.0),
        );
        assert_eq!((v.status, v.resolved), (Status::ModelMismatch, false));
        assert!(v.message.contains("not noise"), "{}", v.message);
        // the scene's floor: a residual far above it is a mismatch (a
        // missing defect or a missed truth), never resolved
        let v = judge(&misfit, Bar::Floor(1.0));
        assert_eq!((v.status, v.resolved), (Status::ModelMismatch, false));
        assert!(v.message.contains("error floor"), "{}", v.message);
        let v = judge(&ok, Bar::Floor(30.0));
        assert_eq!((v.status, v.resolved), (Status::NotIdentifiable, false));
        assert!(v.message.contains("floor"));
        // no defect, no runner-up
        let v = judge(&Evidence::default(), Bar::ChiSquare(9.0));
        assert_eq!((v.status, v.resolved), (Status::Converged, true));
        assert!(v.message.starts_with("no defect"));
    }

    #[test]
    fn a_mismatch_says_what_the_residual_suggests() {
        let e = Evidence {
            k: 1,
            fits_data: false,
            runner_up_gap: Some(20.0),
            mismatch_hint: Some("a trend (a sensor offset or drift): try --nuisance offset+drift"),
            ..Evidence::default()
        };
        let v = judge(&e, Bar::ChiSquare(9.0));
        assert_eq!((v.status, v.resolved), (Status::ModelMismatch, false));
        assert!(
            v.message
                .ends_with("the residual shows a trend (a sensor offset or drift): try --nuisance offset+drift"),
            "{}",
            v.message
        );
    }
}
