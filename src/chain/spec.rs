//! A chain in physical units ([`Units`], [`Chain::to_si`]) and as scene
//! files write it ([`ChainSpec`]).

use super::*;

/// Physical scales of a chain given in the user's units: one unit of mass is
/// `mass_kg` kg, one unit of stiffness `stiffness_n_per_m` N/m, one unit of
/// damping `damping_n_s_per_m` N s/m (the impulse `gamma` is in N s).
///
/// [`Chain::to_si`] multiplies every mass, spring and damper by its scale;
/// the equations of motion are dimensionally homogeneous, so the SI chain's
/// time is in seconds, `s` in 1/s, natural frequencies in rad/s
/// ([`crate::time::modal::natural_modes`]) and displacements in metres.
/// The default (all scales 1) leaves the chain unchanged: the dimensionless
/// paper setup, read as SI with unit values.
///
/// ```
/// use springmass::{Chain, chain::Units};
/// // masses in tonnes, stiffness in kN/m, damping in kN s/m
/// let u = Units::new(1000.0, 1000.0, 1000.0)?;
/// let si = Chain::paper(3)?.to_si(&u)?;
/// assert_eq!((si.mass(), si.k(), si.d()), (1000.0, 1000.0, 100.0));
/// # Ok::<(), springmass::Error>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Units {
    /// kg per unit of mass (default 1).
    #[serde(default = "one")]
    pub mass_kg: f64,
    /// N/m per unit of stiffness (default 1).
    #[serde(default = "one")]
    pub stiffness_n_per_m: f64,
    /// N s/m per unit of damping (default 1).
    #[serde(default = "one")]
    pub damping_n_s_per_m: f64,
}

impl Default for Units {
    fn default() -> Self {
        Units {
            mass_kg: 1.0,
            stiffness_n_per_m: 1.0,
            damping_n_s_per_m: 1.0,
        }
    }
}

impl Units {
    /// Validated scales.
    ///
    /// # Errors
    /// A scale that is not finite and `> 0` (fields `mass_kg`,
    /// `stiffness_n_per_m`, `damping_n_s_per_m`).
    pub fn new(mass_kg: f64, stiffness_n_per_m: f64, damping_n_s_per_m: f64) -> Result<Units> {
        let u = Units {
            mass_kg,
            stiffness_n_per_m,
            damping_n_s_per_m,
        };
        u.check()?;
        Ok(u)
    }

    /// Check every scale is finite and `> 0`.
    ///
    /// # Errors
    /// As [`Units::new`].
    pub fn check(&self) -> Result<()> {
        for (f, v) in [
            ("mass_kg", self.mass_kg),
            ("stiffness_n_per_m", self.stiffness_n_per_m),
            ("damping_n_s_per_m", self.damping_n_s_per_m),
        ] {
            check_f64(f, v, v > 0.0, "> 0 and finite")?;
        }
        Ok(())
    }

    /// All scales 1.
    pub fn is_identity(&self) -> bool {
        *self == Units::default()
    }
}

impl Chain {
    /// The chain in SI units (see [`Units`]): masses times `mass_kg`, springs
    /// times `stiffness_n_per_m`, dampers times `damping_n_s_per_m`.
    ///
    /// # Errors
    /// Invalid scales; a product that leaves the f64 range.
    pub fn to_si(&self, units: &Units) -> Result<Chain> {
        units.check()?;
        let (ms, ks, ds) = (
            units.mass_kg,
            units.stiffness_n_per_m,
            units.damping_n_s_per_m,
        );
        let defects: Vec<Defect> = self
            .defects
            .iter()
            .map(|d| {
                let scale = [ks, ds, ms][d.site().power as usize];
                d.with_value(d.value() * scale)
            })
            .collect();
        let chain = Chain::new(self.n)?
            .with_k(self.k * ks)?
            .with_d(self.d * ds)?
            .with_mass(self.mass * ms)?
            .with_gamma(self.gamma)?
            .with_boundaries(self.left, self.right)?
            .with_damping(match &self.damping {
                Damping::Grounded => Damping::Grounded,
                Damping::Between { c } => Damping::Between { c: c * ds },
                Damping::Rayleigh { a, b } => Damping::Rayleigh {
                    a: a * ds / ms,
                    b: b * ds / ks,
                },
                // ratios: the same in every unit system
                modal @ Damping::Modal { .. } => modal.clone(),
            })?;
        match &self.baseline {
            Some(b) => chain
                .with_baseline(b.scaled(ms, ks, ds)?)?
                .with_defects(defects),
            None => chain.with_defects(defects),
        }
    }
}

/// A plain, serialisable description of a chain, as it appears in scene files.
/// Convert with [`ChainSpec::build`], which validates.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ChainSpec {
    /// Number of masses.
    pub n: usize,
    /// Uniform spring constant (default 1).
    #[serde(default = "one")]
    pub k: f64,
    /// Uniform damping (default 0.1, the paper's).
    #[serde(default = "paper_d")]
    pub d: f64,
    /// Impulse on mass 1 (default 1).
    #[serde(default = "one")]
    pub gamma: f64,
    /// Uniform mass (default 1).
    #[serde(default = "one")]
    pub mass: f64,
    /// Defects (default none).
    #[serde(default)]
    pub defects: Vec<Defect>,
    /// Left end, `fixed` or `free` (default fixed).
    #[serde(default)]
    pub left: Boundary,
    /// Right end, `fixed` or `free` (default fixed).
    #[serde(default)]
    pub right: Boundary,
    /// Damping model, e.g. `damping = { model = "rayleigh", a = 0.01, b = 0.05 }`
    /// (default grounded, the chain's `d`).
    #[serde(default, skip_serializing_if = "Damping::is_grounded")]
    pub damping: Damping,
    /// A measured profile (see [`Baseline`]), inline
    /// `baseline = { mass = [2, 1, 1.5], spring = [3, 2, 2, 0] }` or the
    /// path of a CSV table, `baseline = "frame.csv"`; `n` must equal its
    /// number of masses and its wall springs set the ends (default none:
    /// the uniform chain).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub baseline: Option<BaselineSpec>,
}

fn one() -> f64 {
    1.0
}
fn paper_d() -> f64 {
    0.1
}

impl ChainSpec {
    /// Validate and build.
    pub fn build(&self) -> Result<Chain> {
        let chain = Chain::new(self.n)?
            .with_k(self.k)?
            .with_d(self.d)?
            .with_gamma(self.gamma)?
            .with_mass(self.mass)?
            .with_boundaries(self.left, self.right)?
            .with_damping(self.damping.clone())?;
        let chain = match &self.baseline {
            Some(spec) => {
                let b = spec.load()?;
                b.check_agrees(Some(self.n), None, None)?;
                chain.with_baseline(b)?
            }
            None => chain,
        };
        chain.with_defects(self.defects.iter().copied())
    }
}

impl From<&Chain> for ChainSpec {
    fn from(c: &Chain) -> Self {
        ChainSpec {
            n: c.n,
            k: c.k,
            d: c.d,
            gamma: c.gamma,
            mass: c.mass,
            defects: c.defects.clone(),
            left: c.left,
            right: c.right,
            damping: c.damping.clone(),
            baseline: c.baseline.as_deref().cloned().map(BaselineSpec::Table),
        }
    }
}
