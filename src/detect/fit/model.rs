//! What a data-first fit knows of the chain ([`Model`]): its uniform
//! parameters, ends and known defects, and which uniform parameters to fit.

use crate::chain::{Boundary, Chain, Defect};
use crate::error::{Error, Result};
use crate::sensitivity::Param;

/// What is known of the chain, and which of its uniform parameters to fit.
#[derive(Clone, Debug, PartialEq)]
pub struct Model {
    chain: Chain,
    fit: Vec<Param>,
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
        })
    }

    /// The uniform parameters of `chain`; its defects become known defects.
    pub fn from_chain(chain: &Chain) -> Model {
        Model {
            chain: chain.clone(),
            fit: Vec::new(),
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
        self.fit = params.to_vec();
        Ok(self)
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
