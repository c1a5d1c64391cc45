//! What a data-first fit knows of the chain ([`Model`]): its uniform
//! parameters, ends and known defects, and which uniform parameters to fit.

use crate::chain::{Boundary, Chain, Damping, Defect};
use crate::error::{Error, Result};
use crate::sensitivity::Param;

/// What is known of the chain, and which of its uniform parameters to fit.
#[derive(Clone, Debug, PartialEq)]
pub struct Model {
    chain: Chain,
    fit: Vec<Param>,
    /// The chain parameters asked for (`D` standing for the damping model's
    /// parameters), before [`Model::fitted`]'s expansion.
    asked: Vec<Param>,
    /// Choose the damping model by the criterion (`--fit d` without
    /// `--damping`: [`crate::detect::fit::damping`]).
    choose_damping: bool,
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
            asked: Vec::new(),
            choose_damping: false,
        })
    }

    /// The uniform parameters of `chain`; its defects become known defects.
    pub fn from_chain(chain: &Chain) -> Model {
        Model {
            chain: chain.clone(),
            fit: Vec::new(),
            asked: Vec::new(),
            choose_damping: false,
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

    /// The measured profile the defects sit on ([`Chain::with_baseline`]):
    /// its `n` and ends replace the model's.
    ///
    /// # Errors
    /// As [`Chain::with_baseline`]; `k` or `mass` fitted (field `fit`: the
    /// profile gives every mass and spring).
    pub fn with_baseline(mut self, baseline: crate::chain::Baseline) -> Result<Model> {
        self.chain = self.chain.with_baseline(baseline)?;
        self.check_baseline_params()?;
        Ok(self)
    }

    /// With a baseline, `k` and `mass` are not chain parameters.
    fn check_baseline_params(&self) -> Result<()> {
        match self.chain.baseline() {
            Some(b)
                if self
                    .asked
                    .iter()
                    .any(|p| matches!(p, Param::K | Param::Mass)) =>
            {
                Err(crate::error::Error::invalid(
                    "fit",
                    "k or mass",
                    format!(
                        "d and gamma only with a baseline ({} gives every mass and spring)",
                        b.source()
                    ),
                ))
            }
            _ => Ok(()),
        }
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
        crate::detect::unknowns::check_chain_params("fit", params)?;
        self.asked = params.to_vec();
        self.fit = self.expanded();
        self.check_baseline_params()?;
        Ok(self)
    }

    /// The parameters asked for with `D` standing for the damping model's
    /// own (`c` of `between`, `a` and `b` of `rayleigh`).
    fn expanded(&self) -> Vec<Param> {
        let own = Param::damping(&self.chain);
        let mut out = Vec::with_capacity(self.asked.len() + 1);
        for &p in &self.asked {
            if p == Param::D && !own.is_empty() {
                out.extend(own.iter().copied());
            } else {
                out.push(p);
            }
        }
        out
    }

    /// The damping model (see [`Damping`]); with `D` fitted its parameters
    /// are fitted instead of the grounded `d`, from these values.
    ///
    /// # Errors
    /// As [`Chain::with_damping`].
    pub fn with_damping(mut self, damping: Damping) -> Result<Model> {
        self.chain = self.chain.with_damping(damping)?;
        self.fit = self.expanded();
        Ok(self)
    }

    /// The damping model from the text `MODEL[:P1[:P2]]`
    /// ([`Damping::parse_spec`]), after [`Model::fitting`]: a parameter not
    /// given starts from a value scaled from the chain when `d` is fitted
    /// ([`crate::detect::fit::damping::start`]), else it is an error. The
    /// grounded `d` of a `between` or `rayleigh` model is `d_extra` (0 when
    /// not given).
    ///
    /// # Errors
    /// As [`Damping::parse_spec`]; a parameter the model needs that is
    /// neither given nor fitted (field `damping`, naming it).
    pub fn with_damping_spec(self, text: &str, d_extra: Option<f64>) -> Result<Model> {
        let (damping, missing) = Damping::parse_spec(text)?;
        if !missing.is_empty() && !self.asked.contains(&Param::D) {
            return Err(Error::invalid(
                "damping",
                text,
                format!(
                    "the {} model needs {} {}: give {} ({}) or fit {} (--fit d)",
                    damping.name(),
                    if missing.len() > 1 {
                        "its parameters"
                    } else {
                        "its parameter"
                    },
                    missing.join(" and "),
                    if missing.len() > 1 { "them" } else { "it" },
                    match &damping {
                        Damping::Between { .. } => "between:C",
                        Damping::Modal { .. } => "modal:ZETA",
                        _ => "rayleigh:A:B",
                    },
                    if missing.len() > 1 { "them" } else { "it" },
                ),
            ));
        }
        if damping.is_grounded() {
            return Ok(self);
        }
        let start = crate::detect::fit::damping_scales::start(&self.chain, damping.name())?;
        // the given values, a missing one from the start (a modal model
        // keeps as many ratios as given)
        let from_start = start.params();
        let values: Vec<f64> = damping
            .params()
            .iter()
            .enumerate()
            .map(|(i, (name, v))| match from_start.get(i) {
                Some(s) if missing.contains(&name.as_str()) => s.1,
                _ => *v,
            })
            .collect();
        let d = d_extra.unwrap_or(0.0);
        let mut m = self.with_d(d)?;
        m = m.with_damping(start.with_params(&values))?;
        Ok(m)
    }

    /// Choose among the damping models (grounded, between, Rayleigh,
    /// modal) and report the one the criterion prefers
    /// ([`crate::detect::fit::damping::fit_choosing`]); meaningful with `D`
    /// fitted.
    pub fn choosing_damping(mut self) -> Model {
        self.choose_damping = self.fits_damping();
        self
    }

    /// Whether the damping parameters are fitted (`d` asked for: `--fit d`).
    pub fn fits_damping(&self) -> bool {
        self.asked.contains(&Param::D)
    }

    /// Whether the fit chooses the damping model.
    pub fn chooses_damping(&self) -> bool {
        self.choose_damping
    }

    /// The same model with the damping model `name` at starting values
    /// scaled from the chain, fitted in place of `d` (one candidate of
    /// [`Model::chooses_damping`]; `grounded` is the model itself).
    ///
    /// # Errors
    /// An unknown name (field `damping`).
    pub fn candidate(&self, name: &str) -> Result<Model> {
        let mut m = self.clone();
        m.choose_damping = false;
        if name == "grounded" {
            return Ok(m);
        }
        let start = crate::detect::fit::damping_scales::start(&self.chain, name)?;
        m.with_d(0.0)?.with_damping(start)
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
