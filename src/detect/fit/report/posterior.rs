//! The report's posterior over defect hypotheses (computed by
//! [`crate::detect::fit::posterior`]): the hypotheses with their
//! probabilities, those of each number of defects and of a defect at each
//! site, and their lines in the text report.

use crate::chain::Defect;
use serde::Serialize;

/// Hypotheses listed in the report, at most.
pub const TOP: usize = 10;

/// One hypothesis and its probability.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct HypothesisProbability {
    /// Its defects (fitted values; known defects left out).
    pub defects: Vec<Defect>,
    /// Number of defects.
    pub k: usize,
    /// Its chi-square at the report's noise level.
    pub chi2: f64,
    /// Laplace log-evidence (natural log, up to a constant shared by all).
    pub log_evidence: f64,
    /// Posterior probability among the hypotheses refitted.
    pub probability: f64,
}

/// The probability of one number of defects.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct KProbability {
    /// Number of defects.
    pub k: usize,
    /// Its posterior probability.
    pub probability: f64,
}

/// The marginal probability of a defect at one site.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PositionProbability {
    /// `mass`, `spring`, `damper`.
    pub kind: &'static str,
    /// Position.
    pub at: usize,
    /// Probability that a defect of this kind is there.
    pub probability: f64,
}

/// The posterior over the hypotheses of a fit.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Posterior {
    /// The prior, in words.
    pub prior: String,
    /// The most probable hypotheses, best first (at most [`TOP`]).
    pub hypotheses: Vec<HypothesisProbability>,
    /// The probability of each number of defects searched.
    pub k_probability: Vec<KProbability>,
    /// The probability of a defect at each site that any refitted
    /// hypothesis holds (every other site: at most `pruned_bound`), by kind
    /// and position.
    pub position_probability: Vec<PositionProbability>,
    /// The probability of the reported answer.
    pub answer_probability: f64,
    /// Hypotheses refitted (the ones the probabilities are over).
    pub refitted: usize,
    /// Hypotheses of the searched counts not refitted (pruned by the
    /// screen or never visited by the search).
    pub pruned: f64,
    /// The largest share of probability the pruned hypotheses could hold
    /// (each bounded by the worst refitted one of its count).
    pub pruned_bound: f64,
}

impl Posterior {
    /// The report's lines.
    pub fn lines(&self) -> String {
        let mut out = String::new();
        let ks: Vec<String> = self
            .k_probability
            .iter()
            .map(|k| format!("P(k={}) {}", k.k, relation(k.probability)))
            .collect();
        out.push_str(&format!(
            "probability of the answer {}; {}{}\n",
            prob(self.answer_probability),
            ks.join(", "),
            if self.pruned_bound > 1e-3 {
                format!(
                    " (hypotheses not refitted could hold up to {})",
                    prob(self.pruned_bound)
                )
            } else {
                String::new()
            }
        ));
        let top: Vec<String> = self
            .hypotheses
            .iter()
            .take(3)
            .map(|h| {
                let name = Defect::places(&h.defects);
                format!("{name} ({})", prob(h.probability))
            })
            .collect();
        out.push_str(&format!("most probable: {}\n", top.join("; ")));
        out
    }
}

/// `= 0.123`, `> 0.999` or `< 0.001`.
fn relation(p: f64) -> String {
    let s = prob(p);
    if s.starts_with(['<', '>']) {
        s
    } else {
        format!("= {s}")
    }
}

/// A probability for people: `0.999+` above 0.999, else three decimals.
fn prob(p: f64) -> String {
    if p > 0.999 {
        "> 0.999".to_string()
    } else if p < 1e-3 && p > 0.0 {
        "< 0.001".to_string()
    } else {
        format!("{p:.3}")
    }
}
