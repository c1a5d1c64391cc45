//! What a [`Misfit`](super::Misfit) compares and on which rule: the
//! residual's kind ([`MisfitKind`]), its quadrature rule ([`RuleKind`]) and
//! the settings of both ([`MisfitSpec`], the `misfit.*` fields), validated
//! when the rule is built.

use crate::detect::misfit::quadrature::Rule;
use crate::error::{Error, Result};
use num_complex::Complex64;
use serde::{Deserialize, Serialize};

/// Which residual.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MisfitKind {
    /// `int_0^{s_max} |X - X*|^2 ds` on the real axis (the paper's).
    #[default]
    #[serde(alias = "real")]
    RealAxis,
    /// `int_0^W |X - X*|^2 d omega` on `s = sigma + i omega`.
    Bromwich,
    /// The time-domain chi-square against the sampled series
    /// ([`crate::detect::misfit::time`]); no quadrature rule: a fit scene with
    /// it is fitted by [`crate::detect::fit::general::fit_general`].
    Time,
}

impl MisfitKind {
    /// All three, in table order.
    pub const ALL: [MisfitKind; 3] = [MisfitKind::RealAxis, MisfitKind::Bromwich, MisfitKind::Time];

    /// `real-axis`, `bromwich`, `time`.
    pub fn name(self) -> &'static str {
        match self {
            MisfitKind::RealAxis => "real-axis",
            MisfitKind::Bromwich => "bromwich",
            MisfitKind::Time => "time",
        }
    }

    /// The Laplace nodes and quadrature weights of a Laplace-domain misfit:
    /// `real_rule`'s nodes on the real axis, or `sigma_b + i omega` at
    /// `bromwich_rule`'s nodes; `None` for the time misfit.
    pub fn laplace_nodes(
        self,
        real_rule: &Rule,
        sigma_b: f64,
        bromwich_rule: &Rule,
    ) -> Option<(Vec<Complex64>, Vec<f64>)> {
        match self {
            MisfitKind::RealAxis => Some((
                real_rule
                    .nodes
                    .iter()
                    .map(|&x| Complex64::new(x, 0.0))
                    .collect(),
                real_rule.weights.clone(),
            )),
            MisfitKind::Bromwich => Some((
                bromwich_rule
                    .nodes
                    .iter()
                    .map(|&w| Complex64::new(sigma_b, w))
                    .collect(),
                bromwich_rule.weights.clone(),
            )),
            MisfitKind::Time => None,
        }
    }

    /// Parse `real-axis` (or `real`), `bromwich`, `time`.
    ///
    /// # Errors
    /// [`Error::Parse`] naming the allowed names.
    pub fn parse(text: &str) -> Result<MisfitKind> {
        match text.trim().to_ascii_lowercase().as_str() {
            "real-axis" | "real" => Ok(MisfitKind::RealAxis),
            "bromwich" => Ok(MisfitKind::Bromwich),
            "time" => Ok(MisfitKind::Time),
            _ => Err(Error::parse(
                "misfit",
                text,
                "expected real-axis, bromwich or time",
            )),
        }
    }
}

/// Most panels of a fixed rule (`misfit.panels`): 10 000 panels of 8
/// points are 80 000 nodes, far beyond any accuracy need, and a bounded
/// allocation.
pub const MAX_PANELS: usize = 10_000;

/// Most Gauss points per panel (`misfit.per_panel`).
pub const MAX_PER_PANEL: usize = 64;

/// Which fixed rule.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum RuleKind {
    /// Composite Gauss-Legendre on log-graded panels (real-axis default).
    GlLog,
    /// Composite Gauss-Legendre on equal panels (Bromwich default).
    GlUniform,
}

/// The `[misfit]` table of a fit scene. Defaults: real axis, `gl-log`, 10
/// panels of 8 points, `first = 0.05`, `s_max = 300`; for the Bromwich line
/// `gl-uniform`, 40 panels of 8 points on `omega in [0, omega_max = 4]`,
/// `sigma = 0.1`. These are the scenes' rules (exact-model values, the
/// paper's pipeline); the data-first fit of a sampled record chooses its
/// Bromwich line from the record
/// ([`crate::detect::fit::general::Setup::for_record`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MisfitSpec {
    /// `real-axis`, `bromwich` or `time`.
    pub kind: MisfitKind,
    /// `gl-log` or `gl-uniform` (default by kind).
    pub rule: Option<RuleKind>,
    /// Number of panels (default 10 real axis, 40 Bromwich).
    pub panels: Option<usize>,
    /// Gauss points per panel (default 8).
    pub per_panel: Option<usize>,
    /// End of the first log-graded panel (default 0.05).
    pub first: Option<f64>,
    /// Upper limit of the real-axis integral (default 300).
    pub s_max: f64,
    /// Abscissa of the Bromwich line (default 0.1).
    pub sigma: f64,
    /// Upper limit of `omega` on the Bromwich line (default 4).
    pub omega_max: f64,
}

impl Default for MisfitSpec {
    fn default() -> Self {
        MisfitSpec {
            kind: MisfitKind::RealAxis,
            rule: None,
            panels: None,
            per_panel: None,
            first: None,
            s_max: 300.0,
            sigma: 0.1,
            omega_max: 4.0,
        }
    }
}

impl MisfitSpec {
    /// A real-axis spec with a `gl-log` rule of `panels x per_panel` nodes.
    pub fn real_axis(panels: usize, per_panel: usize) -> MisfitSpec {
        MisfitSpec {
            panels: Some(panels),
            per_panel: Some(per_panel),
            ..MisfitSpec::default()
        }
    }

    /// The quadrature rule in the integration variable (`s` or `omega`).
    ///
    /// # Errors
    /// Bad rule parameters (fields `misfit.*`).
    pub fn rule(&self) -> Result<Rule> {
        let per = self.per_panel.unwrap_or(8);
        if !(1..=MAX_PER_PANEL).contains(&per) {
            return Err(Error::invalid(
                "misfit.per_panel",
                per,
                format!("1..={MAX_PER_PANEL} Gauss points per panel"),
            ));
        }
        if let Some(p) = self.panels {
            if !(1..=MAX_PANELS).contains(&p) {
                return Err(Error::invalid(
                    "misfit.panels",
                    p,
                    format!("1..={MAX_PANELS} panels"),
                ));
            }
        }
        // the integration variable runs over [0, end]; each kind has its own
        // default rule
        let (field, end, default_rule) = match self.kind {
            MisfitKind::RealAxis => ("misfit.s_max", self.s_max, RuleKind::GlLog),
            MisfitKind::Bromwich => {
                if !(self.sigma.is_finite() && self.sigma > 0.0) {
                    return Err(Error::invalid("misfit.sigma", self.sigma, "> 0 and finite"));
                }
                ("misfit.omega_max", self.omega_max, RuleKind::GlUniform)
            }
            MisfitKind::Time => return Err(time_has_no_rule()),
        };
        if !(end.is_finite() && end > 0.0) {
            return Err(Error::invalid(field, end, "> 0 and finite"));
        }
        match self.rule.unwrap_or(default_rule) {
            RuleKind::GlLog => Rule::gauss_legendre_log(
                0.0,
                end,
                self.panels.unwrap_or(10),
                per,
                self.first.unwrap_or(0.05),
            ),
            RuleKind::GlUniform => {
                Rule::gauss_legendre_uniform(0.0, end, self.panels.unwrap_or(40), per)
            }
        }
    }
}

pub(super) fn time_has_no_rule() -> Error {
    Error::invalid(
        "misfit.kind",
        "time",
        "real-axis or bromwich here (the time misfit is fitted by detect::fit::general::fit_general)",
    )
}
