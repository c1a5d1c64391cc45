//! A hypothesis of the general fit: its fitted defects and chain parameters
//! ([`Hypothesis`], [`FittedParam`]), their names, and the ranking of
//! hypotheses.

use crate::chain::{Chain, Defect};
use crate::detect::search::lsq::LmFit;
use crate::detect::unknowns::{DefectKind, KindPositions};
use crate::error::{Error, Result};
use crate::sensitivity::Param;
use serde::Serialize;

/// A fitted uniform chain parameter.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FittedParam {
    /// `d`, `gamma`, `k` or `mass`.
    pub name: String,
    /// Fitted value.
    pub value: f64,
    /// Gauss-Newton standard error (NaN when unconstrained).
    pub std_error: f64,
}

/// One hypothesis: the defects (kind, position, fitted value), the fitted
/// chain parameters, the chi-square and the standard errors of every fitted
/// value.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Hypothesis {
    /// The defects. Mass-only fits: increasing positions; general fits: in
    /// the order of the unknowns' slots.
    pub defects: Vec<Defect>,
    /// Standard errors of the defect values, in the order of `defects` (NaN
    /// when unconstrained; 0 for a known value).
    pub std_errors: Vec<f64>,
    /// Fitted chain parameters (empty when none were fitted).
    pub chain: Vec<FittedParam>,
    /// Misfit value.
    pub chi2: f64,
    /// Whether the value fit met its tolerance (`false`: it stopped at its
    /// iteration limit, and the values may not be at the minimum).
    pub converged: bool,
}

impl Hypothesis {
    /// A hypothesis from its parts (defects, their standard errors, fitted
    /// chain parameters, misfit value).
    pub fn from_parts(
        defects: Vec<Defect>,
        std_errors: Vec<f64>,
        chain: Vec<FittedParam>,
        chi2: f64,
    ) -> Hypothesis {
        Hypothesis {
            defects,
            std_errors,
            chain,
            chi2,
            converged: true,
        }
    }

    /// The hypothesis of a Levenberg-Marquardt fit `lm` over `params` whose
    /// chain is `fitted`, with `n_defects` defects: each fitted defect's
    /// standard error (0 for one not among `params`), the other parameters
    /// as fitted chain parameters named by `name`; `converged` as the fit's.
    pub(crate) fn from_fit(
        params: &[Param],
        lm: &LmFit,
        fitted: &Chain,
        n_defects: usize,
        name: impl Fn(&Param) -> String,
    ) -> Hypothesis {
        let se = lm
            .std_errors()
            .unwrap_or_else(|_| vec![f64::NAN; params.len()]);
        let mut std_errors = vec![0.0; n_defects];
        let mut chain = Vec::new();
        for (j, p) in params.iter().enumerate() {
            match p {
                Param::Defect(i) => std_errors[*i] = se[j],
                _ => chain.push(FittedParam {
                    name: name(p),
                    value: lm.theta[j],
                    std_error: se[j],
                }),
            }
        }
        Hypothesis {
            defects: fitted.defects().to_vec(),
            std_errors,
            chain,
            chi2: lm.chi2,
            converged: lm.converged,
        }
    }

    /// The positions of the defects.
    pub fn positions(&self) -> Vec<usize> {
        self.defects.iter().map(Defect::at).collect()
    }

    /// The fitted values of the defects (masses for a mass-only fit).
    pub fn masses(&self) -> Vec<f64> {
        self.defects.iter().map(Defect::value).collect()
    }

    /// `(kind, position)` of every defect.
    pub fn key(&self) -> KindPositions {
        self.defects.iter().map(DefectKind::key_of).collect()
    }

    /// The start of a fit of one defect more: this hypothesis's pairs and
    /// values, then `(kind, at)` at its value in `start` (a defect of
    /// vanishing size: the uniform value, or the baseline's there).
    pub fn extended(
        &self,
        (kind, at): (DefectKind, usize),
        start: &Chain,
    ) -> (KindPositions, Vec<f64>) {
        let (mut pairs, mut values) = (self.key(), self.masses());
        pairs.push((kind, at));
        values.push(kind.base_at(start, at));
        (pairs, values)
    }

    /// The fitted chain parameter `name` (`d`, `gamma`, `k`, `mass`).
    pub fn param(&self, name: &str) -> Option<&FittedParam> {
        self.chain.iter().find(|p| p.name == name)
    }

    /// Whether a fitted chain parameter lies more than `ses` of its
    /// standard errors from its value in `base` (a parameter without a
    /// finite standard error: when it differs at all).
    ///
    /// # Errors
    /// A parameter name `base` does not know.
    pub fn chain_moved_from(&self, base: &Chain, ses: f64) -> Result<bool> {
        for p in &self.chain {
            let was = chain_param(&p.name, base)?.get(base)?;
            let room = if p.std_error.is_finite() {
                ses * p.std_error
            } else {
                0.0
            };
            if (p.value - was).abs() > room {
                return Ok(true);
            }
        }
        Ok(false)
    }

    /// The chain this hypothesis describes: `base` with the fitted chain
    /// parameters and the defects.
    ///
    /// # Errors
    /// As the chain's builders.
    pub fn to_chain(&self, base: &Chain) -> Result<Chain> {
        let mut c = base.uniform();
        for p in &self.chain {
            c = chain_param(&p.name, &c)?.set(&c, p.value)?;
        }
        c.with_defects(self.defects.iter().copied())
    }

    /// The same `(kind, position)` pairs as `truth`'s defects (in any order)
    /// and every value within `rel` (relative).
    pub fn matches(&self, truth: &Chain, rel: f64) -> bool {
        let mut t: Vec<(DefectKind, usize, f64)> = truth
            .defects()
            .iter()
            .map(|d| (DefectKind::of(d), d.at(), d.value()))
            .collect();
        let mut h: Vec<(DefectKind, usize, f64)> = self
            .defects
            .iter()
            .map(|d| (DefectKind::of(d), d.at(), d.value()))
            .collect();
        t.sort_by_key(|x| (x.0, x.1));
        h.sort_by_key(|x| (x.0, x.1));
        t.len() == h.len()
            && t.iter().zip(&h).all(|(a, b)| {
                a.0 == b.0 && a.1 == b.1 && (a.2 - b.2).abs() <= rel * a.2.abs().max(1e-12)
            })
    }

    /// The same `(kind, position)` pairs as `truth`'s defects (in any order).
    pub fn positions_match(&self, truth: &Chain) -> bool {
        let mut t: KindPositions = truth.defects().iter().map(DefectKind::key_of).collect();
        let mut h = self.key();
        t.sort_unstable();
        h.sort_unstable();
        t == h
    }
}

/// The name of a uniform chain parameter (`d`, `gamma`, `k`, `mass`, the
/// damping model's `c`, `a`, `b`, `zeta` or `zeta_J`) as the fitted
/// parameters carry it.
pub fn param_name(p: &Param) -> String {
    match p {
        Param::D => "d".into(),
        Param::Gamma => "gamma".into(),
        Param::K => "k".into(),
        Param::Mass => "mass".into(),
        Param::Defect(_) => "defect".into(),
        Param::C => "c".into(),
        Param::A => "a".into(),
        Param::B => "b".into(),
        Param::Zeta { index, of } => crate::chain::Damping::ratio_name(*index, *of),
    }
}

/// The chain parameter `name` ([`param_name`]) of `chain` (whose damping
/// model gives the number of modal ratios).
pub(super) fn chain_param(name: &str, chain: &Chain) -> Result<Param> {
    let of = match chain.damping() {
        crate::chain::Damping::Modal { zeta } => zeta.len(),
        _ => 1,
    };
    let ratio = name
        .strip_prefix("zeta_")
        .and_then(|j| j.parse::<usize>().ok())
        .filter(|j| (1..=of).contains(j) && of > 1);
    match (name, ratio) {
        ("d", _) => Ok(Param::D),
        ("gamma", _) => Ok(Param::Gamma),
        ("k", _) => Ok(Param::K),
        ("mass", _) => Ok(Param::Mass),
        ("c", _) => Ok(Param::C),
        ("a", _) => Ok(Param::A),
        ("b", _) => Ok(Param::B),
        ("zeta", _) if of == 1 => Ok(Param::Zeta { index: 0, of }),
        (_, Some(j)) => Ok(Param::Zeta { index: j - 1, of }),
        _ => Err(Error::invalid(
            "param",
            name,
            "d, gamma, k, mass, c, a, b, zeta or zeta_J (a modal ratio of the chain's model)",
        )),
    }
}

/// Rank best first: by chi-square, then by the hypothesis (so that the order
/// does not depend on the order of the input, nor on the thread count).
pub(super) fn rank(mut v: Vec<Hypothesis>) -> Vec<Hypothesis> {
    v.sort_by(|a, b| {
        a.chi2
            .total_cmp(&b.chi2)
            .then_with(|| a.key().cmp(&b.key()))
    });
    v
}
