//! The report's damping model and its parameters (the model chosen by
//! [`crate::detect::fit::damping`]).

use super::FitReport;
use crate::detect::fit::model::Model;
use serde::Serialize;
use std::collections::BTreeMap;

/// One candidate model of a fit that chose the damping model, as its
/// screening fit ([`crate::detect::fit::damping::screen_options`]) left it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DampingCandidate {
    /// `grounded`, `between` or `rayleigh`.
    pub model: String,
    /// Its criterion value (smaller is better; `NaN` when its fit failed).
    pub criterion: f64,
    /// Its number of defects.
    pub k: usize,
    /// Its positions.
    pub positions: Vec<usize>,
    /// Whether its positions were searched; `false`: fitted at the chosen
    /// model's set only, which explains the record and where this model
    /// does no better ([`crate::detect::fit::damping::fit_choosing`]).
    pub searched: bool,
}

/// The damping model of a fit and its parameters with standard errors:
/// JSON `{"model": "rayleigh", "a": .., "b": .., "se": {"a": .., "b": ..},
/// "fitted": true, "candidates": [..]}`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DampingEstimate {
    /// `grounded`, `between` or `rayleigh`.
    pub model: String,
    /// Its parameters (`d` for grounded; `c`; `a`, `b`).
    #[serde(flatten)]
    pub values: BTreeMap<String, f64>,
    /// Their standard errors (0 for a parameter not fitted).
    pub se: BTreeMap<String, f64>,
    /// Whether they were fitted.
    pub fitted: bool,
    /// Every model fitted when the fit chose the model; with
    /// [`DampingEstimate::checked`], the models a given one was checked
    /// against; empty otherwise.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub candidates: Vec<DampingCandidate>,
    /// The model was given, and its fit, which needed coloured noise, was
    /// checked against the `candidates` fitted with white noise
    /// ([`crate::detect::fit::damping::check_given`]).
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub checked: bool,
}

impl DampingEstimate {
    /// The entry of a report fitted with `model`'s damping model.
    pub fn of(report: &FitReport, model: &Model) -> DampingEstimate {
        let chain = model.chain();
        let damping = chain.damping();
        let mut names: Vec<(String, f64)> = damping.params();
        if damping.is_grounded() {
            names = vec![("d".into(), chain.d())];
        }
        let mut values = BTreeMap::new();
        let mut se = BTreeMap::new();
        let mut fitted = false;
        for (name, v) in names {
            match report.params.iter().find(|p| p.name == name) {
                Some(p) => {
                    values.insert(name.to_string(), p.value);
                    se.insert(name.to_string(), p.se);
                    fitted = true;
                }
                None => {
                    values.insert(name.to_string(), v);
                    se.insert(name.to_string(), 0.0);
                }
            }
        }
        DampingEstimate {
            model: damping.name().to_string(),
            values,
            se,
            fitted,
            candidates: Vec::new(),
            checked: false,
        }
    }

    /// One line for the text report.
    pub fn line(&self) -> String {
        let vals: Vec<String> = self
            .values
            .iter()
            .map(|(k, v)| format!("{k} = {v:.4e} +- {:.2e}", self.se.get(k).unwrap_or(&0.0)))
            .collect();
        let mut out = format!("damping model: {} ({})", self.model, vals.join(", "));
        if !self.candidates.is_empty() {
            let c: Vec<String> = self
                .candidates
                .iter()
                .map(|c| format!("{} {:.1}", c.model, c.criterion))
                .collect();
            if self.checked {
                out.push_str(&format!(
                    "; given, and checked against {} (BIC with white noise)",
                    c.join(", ")
                ));
            } else if self.candidates.iter().all(|c| c.searched) {
                out.push_str(&format!("; chosen by BIC among {}", c.join(", ")));
            } else {
                out.push_str(&format!(
                    "; chosen: it explains the record and no other model does better at its set (BIC {}; --effort high searches every model)",
                    c.join(", ")
                ));
            }
        }
        out
    }
}
