//! The `[unknowns]` table of a fit scene ([`UnknownsSpec`]): what a scene
//! file says of the defects sought, checked and built into [`Unknowns`].

use super::{KindBounds, KindChoice, Slot, Unknowns};
use crate::chain::Chain;
use crate::error::{Error, Result};
use crate::sensitivity::Param;
use serde::{Deserialize, Serialize};

/// The `[unknowns]` table of a fit scene.
///
/// ```toml
/// [unknowns]
/// k = 2                      # default: the number of true defects in [chain]
/// mass_bounds = [0.1, 100]   # default bounds of every unknown mass
/// # optional per-defect entries (the first len(defects) defects; the rest are free)
/// [[unknowns.defects]]
/// at = 8                     # known position (omit: unknown)
/// m = 5.0                    # known mass (omit: unknown)
/// # bounds = [1, 10]         # bounds of this unknown mass
/// ```
///
/// General unknowns (fitted by the general hypothesis fits of `detect::fit`):
///
/// ```toml
/// [unknowns]
/// k = 2
/// kind = "spring"            # "mass" (default) | "spring" | "damper" | "ground" | "any"
/// chain = ["d"]              # chain parameters fitted too: "d", "gamma", "k", "mass" (default [])
/// chain_start = { d = 0.2 }  # their starting values (default: the [chain] values)
/// spring_bounds = [0.01, 100]   # default bounds of unknown springs
/// damper_bounds = [0, 100]      # default bounds of unknown dampers
/// [[unknowns.defects]]
/// kind = "damper"            # per-defect kind (default: the table's kind)
/// # at = 4                   # known position; m = known mass (mass kind only)
/// ```
///
/// `kind = "any"`: each defect may be a mass, a spring or a damper; the
/// hypotheses are sets of `(kind, position)` ranked by chi-square. At most three
/// of the four chain parameters: `x_1(t)` is unchanged when every mass,
/// damper, spring and `gamma` are scaled together.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct UnknownsSpec {
    /// Number of defects (default: the number of defects of the true chain).
    pub k: Option<usize>,
    /// Default bounds of unknown masses (default `[0.1, 100]`).
    pub mass_bounds: [f64; 2],
    /// Per-defect information (default none: all free).
    pub defects: Vec<DefectUnknownSpec>,
    /// Kind of the defects: `mass` (default), `spring`, `damper`, `ground`
    /// (a spring from a mass to the ground) or `any` (mass, spring or damper).
    pub kind: KindChoice,
    /// Uniform chain parameters fitted alongside: `d`, `gamma`, `k`, `mass`
    /// (default none).
    pub chain: Vec<String>,
    /// Default bounds of unknown springs (default `[0.01, 100]`, `lo > 0`).
    pub spring_bounds: [f64; 2],
    /// Default bounds of unknown dampers (default `[0, 100]`, `lo >= 0`).
    pub damper_bounds: [f64; 2],
    /// Starting values of fitted chain parameters, e.g. `{ d = 0.2 }`
    /// (default: the `[chain]` values).
    pub chain_start: std::collections::BTreeMap<String, f64>,
}

/// One `[[unknowns.defects]]` entry.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DefectUnknownSpec {
    /// Known position.
    pub at: Option<usize>,
    /// Known mass.
    pub m: Option<f64>,
    /// Bounds of the unknown value (default `mass_bounds`, `spring_bounds`
    /// or `damper_bounds` by kind).
    pub bounds: Option<[f64; 2]>,
    /// Kind of this defect (default: the table's `kind`).
    pub kind: Option<KindChoice>,
}

impl Default for UnknownsSpec {
    fn default() -> Self {
        UnknownsSpec {
            k: None,
            mass_bounds: [0.1, 100.0],
            defects: Vec::new(),
            kind: KindChoice::Mass,
            chain: Vec::new(),
            spring_bounds: [0.01, 100.0],
            damper_bounds: [0.0, 100.0],
            chain_start: Default::default(),
        }
    }
}

impl UnknownsSpec {
    /// Whether the table asks for more than the mass-only fit can do: a
    /// defect kind other than `mass`, or chain parameters.
    pub fn is_general(&self) -> bool {
        self.kind != KindChoice::Mass
            || !self.chain.is_empty()
            || self
                .defects
                .iter()
                .any(|d| d.kind.is_some_and(|k| k != KindChoice::Mass))
    }

    /// Validate against a chain of `n` masses; `default_k` is used when
    /// `k` is not given. The mass-only kernel takes
    /// [`Unknowns::to_mass`] of the result.
    ///
    /// # Errors
    /// As [`Unknowns::new`]; `unknowns.k`, `unknowns.defects`,
    /// `unknowns.mass_bounds`, `unknowns.spring_bounds`,
    /// `unknowns.damper_bounds`, `unknowns.chain` (an unknown name, a repeat,
    /// or all four), `unknowns.defects[i].m` (a known value of a non-mass
    /// defect).
    pub fn build(&self, n: usize, default_k: usize) -> Result<Unknowns> {
        let k = self.k.unwrap_or(default_k.max(self.defects.len()));
        if k == 0 {
            return Err(Error::invalid("unknowns.k", k, ">= 1"));
        }
        if self.defects.len() > k {
            return Err(Error::invalid(
                "unknowns.defects",
                format!("{} entries", self.defects.len()),
                format!("at most k = {k} entries"),
            ));
        }
        let bounds = KindBounds {
            mass: check_bounds("unknowns.mass_bounds", self.mass_bounds, true)?,
            spring: check_bounds("unknowns.spring_bounds", self.spring_bounds, true)?,
            damper: check_bounds("unknowns.damper_bounds", self.damper_bounds, false)?,
            ground: KindBounds::default().ground,
        };
        let mut chain = Vec::with_capacity(self.chain.len());
        for name in &self.chain {
            let p = match name.trim() {
                "d" => Param::D,
                "gamma" => Param::Gamma,
                "k" => Param::K,
                "mass" => Param::Mass,
                other => {
                    return Err(Error::invalid(
                        "unknowns.chain",
                        other,
                        "\"d\", \"gamma\", \"k\" or \"mass\"",
                    ))
                }
            };
            chain.push(p);
        }
        let mut slots = Vec::with_capacity(k);
        for (i, d) in self.defects.iter().enumerate() {
            let kind = d.kind.unwrap_or(self.kind);
            if d.m.is_some() && kind != KindChoice::Mass {
                return Err(Error::invalid(
                    format!("unknowns.defects[{i}].m"),
                    format!("{:?}", d.m),
                    "a known value only for kind = \"mass\"",
                ));
            }
            if let (Some(_), Some(b)) = (d.m, d.bounds) {
                return Err(Error::invalid(
                    format!("unknowns.defects[{i}].bounds"),
                    format!("{b:?}"),
                    "only with an unknown value (omit m)",
                ));
            }
            slots.push(Slot {
                kind,
                at: d.at,
                known: d.m,
                bounds: d.bounds.map(|[lo, hi]| (lo, hi)),
            });
        }
        slots.resize(
            k,
            Slot {
                kind: self.kind,
                at: None,
                known: None,
                bounds: None,
            },
        );
        Unknowns::new(n, slots, chain, bounds)
    }
}

impl UnknownsSpec {
    /// `model` with the fitted chain parameters at their `chain_start` values.
    ///
    /// # Errors
    /// `unknowns.chain_start` naming a parameter not in `chain`, or a value
    /// out of its range.
    pub fn start_chain(&self, model: &Chain) -> Result<Chain> {
        let mut c = model.uniform();
        for (name, &v) in &self.chain_start {
            if !self.chain.iter().any(|c| c.trim() == name) {
                return Err(Error::invalid(
                    format!("unknowns.chain_start.{name}"),
                    v,
                    "a parameter listed in unknowns.chain",
                ));
            }
            let p = match name.as_str() {
                "d" => Param::D,
                "gamma" => Param::Gamma,
                "k" => Param::K,
                _ => Param::Mass,
            };
            c = p.set(&c, v).map_err(|e| {
                Error::invalid(format!("unknowns.chain_start.{name}"), v, e.to_string())
            })?;
        }
        Ok(c)
    }
}

pub(super) fn check_bounds(field: &str, [lo, hi]: [f64; 2], positive: bool) -> Result<(f64, f64)> {
    let ok_lo = if positive { lo > 0.0 } else { lo >= 0.0 };
    if !(lo.is_finite() && hi.is_finite() && ok_lo && lo < hi) {
        return Err(Error::invalid(
            field,
            format!("[{lo}, {hi}]"),
            if positive {
                "0 < lo < hi, finite"
            } else {
                "0 <= lo < hi, finite"
            },
        ));
    }
    Ok((lo, hi))
}
