//! The unknowns of a fit: `k` mass defects, each with its position known or
//! unknown and its mass known or unknown within bounds.
//!
//! Positions are distinct integers in `1..=n`. Unknown positions never take a
//! known defect's position. When every defect with an unknown position also
//! has an unknown mass with the same bounds, the defects are interchangeable
//! and a hypothesis is a *set* of positions (order does not matter);
//! otherwise it is an ordered assignment.
//!
//! [`Unknowns::space`] is the search [`Space`] for the optimizers: one integer
//! per unknown position, one log-scaled real per unknown mass,
//! `pairing[v] = Some(p)` when mass `v` belongs to the defect of unknown
//! position `p`; known positions are `excluded`.
//!
//! ```
//! use springmass::detect::space::{DefectUnknown, MassUnknown, Unknowns};
//! let u = Unknowns::new(20, vec![DefectUnknown::free(0.1, 100.0); 2])?;
//! assert_eq!(u.space().n_positions, 2);
//! assert!(u.interchangeable());
//! assert!(Unknowns::new(20, vec![DefectUnknown::free(5.0, 1.0)]).is_err());
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::detect::search::{Candidate, Space};
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};

/// A defect's mass in a fit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MassUnknown {
    /// Known mass.
    Known(f64),
    /// Unknown, in `[lo, hi]`, `0 < lo < hi`.
    Free {
        /// Lower bound.
        lo: f64,
        /// Upper bound.
        hi: f64,
    },
}

/// One defect of a fit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DefectUnknown {
    /// Known position, or `None`.
    pub at: Option<usize>,
    /// The mass.
    pub mass: MassUnknown,
}

impl DefectUnknown {
    /// Position and mass unknown, mass in `[lo, hi]`.
    pub fn free(lo: f64, hi: f64) -> DefectUnknown {
        DefectUnknown {
            at: None,
            mass: MassUnknown::Free { lo, hi },
        }
    }
}

/// Penalty floor for invalid candidates (any valid residual is far below).
pub const PENALTY: f64 = 1e6;

/// Validated unknowns of a fit.
#[derive(Clone, Debug, PartialEq)]
pub struct Unknowns {
    n: usize,
    defects: Vec<DefectUnknown>,
    /// Indices of defects with an unknown position.
    free_pos: Vec<usize>,
    /// Indices of defects with an unknown mass.
    free_mass: Vec<usize>,
    space: Space,
}

impl Unknowns {
    /// Validate the unknowns of a chain of `n` masses.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming the field: `unknowns.k` when there
    /// are no defects or more than `n`; `unknowns.defects[i].at` for a known
    /// position outside `1..=n` or equal to another known position;
    /// `unknowns.defects[i].m` for a known mass that is not positive and finite;
    /// `unknowns.defects[i].bounds` for bounds that are not `0 < lo < hi`, finite.
    pub fn new(n: usize, defects: Vec<DefectUnknown>) -> Result<Unknowns> {
        let k = defects.len();
        if k == 0 || k > n {
            return Err(Error::invalid(
                "unknowns.k",
                k,
                format!("1 <= k <= n = {n}"),
            ));
        }
        for (i, d) in defects.iter().enumerate() {
            if let Some(at) = d.at {
                if at == 0 || at > n {
                    return Err(Error::invalid(
                        format!("unknowns.defects[{i}].at"),
                        at,
                        format!("1 <= at <= n = {n}"),
                    ));
                }
                if let Some(j) = defects[..i].iter().position(|e| e.at == Some(at)) {
                    return Err(Error::invalid(
                        format!("unknowns.defects[{i}].at"),
                        at,
                        format!("distinct from unknowns.defects[{j}].at"),
                    ));
                }
            }
            match d.mass {
                MassUnknown::Known(m) => {
                    if !(m.is_finite() && m > 0.0) {
                        return Err(Error::invalid(
                            format!("unknowns.defects[{i}].m"),
                            m,
                            "m > 0 and finite",
                        ));
                    }
                }
                MassUnknown::Free { lo, hi } => {
                    if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && lo < hi) {
                        return Err(Error::invalid(
                            format!("unknowns.defects[{i}].bounds"),
                            format!("[{lo}, {hi}]"),
                            "0 < lo < hi, finite",
                        ));
                    }
                }
            }
        }
        let free_pos: Vec<usize> = (0..k).filter(|&i| defects[i].at.is_none()).collect();
        let free_mass: Vec<usize> = (0..k)
            .filter(|&i| matches!(defects[i].mass, MassUnknown::Free { .. }))
            .collect();
        let mut excluded: Vec<usize> = defects.iter().filter_map(|d| d.at).collect();
        excluded.sort_unstable();
        let space = Space {
            n,
            n_positions: free_pos.len(),
            excluded,
            bounds: free_mass
                .iter()
                .map(|&i| match defects[i].mass {
                    MassUnknown::Free { lo, hi } => (lo, hi),
                    MassUnknown::Known(_) => unreachable!(),
                })
                .collect(),
            log_scale: vec![true; free_mass.len()],
            pairing: free_mass
                .iter()
                .map(|&i| free_pos.iter().position(|&p| p == i))
                .collect(),
        };
        Ok(Unknowns {
            n,
            defects,
            free_pos,
            free_mass,
            space,
        })
    }

    /// Number of masses of the chain.
    pub fn n(&self) -> usize {
        self.n
    }

    /// Number of defects.
    pub fn k(&self) -> usize {
        self.defects.len()
    }

    /// The defects.
    pub fn defects(&self) -> &[DefectUnknown] {
        &self.defects
    }

    /// Indices of the defects whose position is unknown.
    pub fn free_positions(&self) -> &[usize] {
        &self.free_pos
    }

    /// Indices of the defects whose mass is unknown.
    pub fn free_masses(&self) -> &[usize] {
        &self.free_mass
    }

    /// The search space.
    pub fn space(&self) -> &Space {
        &self.space
    }

    /// Positions that unknown positions may take (`1..=n` minus known positions).
    pub fn allowed_positions(&self) -> Vec<usize> {
        (1..=self.n)
            .filter(|p| self.space.excluded.binary_search(p).is_err())
            .collect()
    }

    /// Whether the defects with unknown positions are interchangeable (all
    /// with unknown masses of equal bounds, or all with one known mass).
    pub fn interchangeable(&self) -> bool {
        let first = match self.free_pos.first() {
            Some(&i) => self.defects[i].mass,
            None => return true,
        };
        self.free_pos.iter().all(|&i| self.defects[i].mass == first)
    }

    /// The full defect list `(position, mass)` in defect order from the
    /// unknown positions (in [`Unknowns::free_positions`] order) and the
    /// unknown masses (in [`Unknowns::free_masses`] order). Unchecked.
    pub fn assemble(&self, positions: &[usize], masses: &[f64]) -> Vec<(usize, f64)> {
        let mut pi = positions.iter();
        let mut mi = masses.iter();
        self.defects
            .iter()
            .map(|d| {
                let at =
                    d.at.unwrap_or_else(|| *pi.next().expect("one per unknown position"));
                let m = match d.mass {
                    MassUnknown::Known(m) => m,
                    MassUnknown::Free { .. } => *mi.next().expect("one per unknown mass"),
                };
                (at, m)
            })
            .collect()
    }

    /// Map a candidate of [`Unknowns::space`] to defects, or return a finite
    /// penalty `>= PENALTY` growing with the size of the violation (wrong
    /// lengths, positions out of range, repeated or excluded, masses outside
    /// their bounds or not finite).
    pub fn decode(&self, c: &Candidate) -> std::result::Result<Vec<(usize, f64)>, f64> {
        if c.positions.len() != self.free_pos.len() || c.values.len() != self.free_mass.len() {
            return Err(PENALTY * 10.0);
        }
        let mut viol = 0.0;
        for (i, &p) in c.positions.iter().enumerate() {
            if p == 0 || p > self.n {
                viol += 1.0 + p.abs_diff(self.n.min(p.max(1))) as f64;
            } else if self.space.excluded.binary_search(&p).is_ok() || c.positions[..i].contains(&p)
            {
                viol += 1.0;
            }
        }
        for (v, &(lo, hi)) in c.values.iter().zip(&self.space.bounds) {
            if !v.is_finite() {
                viol += 10.0;
            } else if *v < lo || *v > hi {
                viol += 1.0 + ((v / lo).ln().abs().min((v / hi).ln().abs())).min(1e3);
            }
        }
        if viol > 0.0 {
            return Err(PENALTY * (1.0 + viol));
        }
        Ok(self.assemble(&c.positions, &c.values))
    }
}

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
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UnknownsSpec {
    /// Number of defects (default: the number of defects of the true chain).
    #[serde(default)]
    pub k: Option<usize>,
    /// Default bounds of unknown masses (default `[0.1, 100]`).
    #[serde(default = "default_bounds")]
    pub mass_bounds: [f64; 2],
    /// Per-defect information (default none: all free).
    #[serde(default)]
    pub defects: Vec<DefectUnknownSpec>,
}

/// One `[[unknowns.defects]]` entry.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DefectUnknownSpec {
    /// Known position.
    #[serde(default)]
    pub at: Option<usize>,
    /// Known mass.
    #[serde(default)]
    pub m: Option<f64>,
    /// Bounds of the unknown mass (default `mass_bounds`).
    #[serde(default)]
    pub bounds: Option<[f64; 2]>,
}

fn default_bounds() -> [f64; 2] {
    [0.1, 100.0]
}

impl Default for UnknownsSpec {
    fn default() -> Self {
        UnknownsSpec {
            k: None,
            mass_bounds: default_bounds(),
            defects: Vec::new(),
        }
    }
}

impl UnknownsSpec {
    /// Validate against a chain of `n` masses; `default_k` is used when `k`
    /// is not given.
    ///
    /// # Errors
    /// As [`Unknowns::new`]; also `unknowns.defects` when more entries than
    /// `k`, `unknowns.mass_bounds` for bad default bounds, and
    /// `unknowns.defects[i].bounds` when bounds are given with a known mass.
    pub fn build(&self, n: usize, default_k: usize) -> Result<Unknowns> {
        let k = self.k.unwrap_or(default_k.max(self.defects.len()));
        if k == 0 || k > n {
            return Err(Error::invalid(
                "unknowns.k",
                k,
                format!("1 <= k <= n = {n}"),
            ));
        }
        if self.defects.len() > k {
            return Err(Error::invalid(
                "unknowns.defects",
                format!("{} entries", self.defects.len()),
                format!("at most k = {k} entries"),
            ));
        }
        let [lo, hi] = self.mass_bounds;
        if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && lo < hi) {
            return Err(Error::invalid(
                "unknowns.mass_bounds",
                format!("[{lo}, {hi}]"),
                "0 < lo < hi, finite",
            ));
        }
        let mut out = Vec::with_capacity(k);
        for (i, d) in self.defects.iter().enumerate() {
            let mass = match (d.m, d.bounds) {
                (Some(_), Some(b)) => {
                    return Err(Error::invalid(
                        format!("unknowns.defects[{i}].bounds"),
                        format!("{b:?}"),
                        "only with an unknown mass (omit m)",
                    ))
                }
                (Some(m), None) => MassUnknown::Known(m),
                (None, Some([lo, hi])) => MassUnknown::Free { lo, hi },
                (None, None) => MassUnknown::Free { lo, hi },
            };
            out.push(DefectUnknown { at: d.at, mass });
        }
        out.resize(k, DefectUnknown::free(lo, hi));
        Unknowns::new(n, out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn field(r: Result<Unknowns>) -> String {
        match r {
            Err(Error::InvalidParameter { field, .. }) => field,
            other => panic!("expected an invalid-parameter error, got {other:?}"),
        }
    }

    #[test]
    fn bad_unknowns_name_the_field() {
        let f = DefectUnknown::free(0.1, 10.0);
        assert_eq!(field(Unknowns::new(3, vec![f; 4])), "unknowns.k");
        assert_eq!(field(Unknowns::new(3, vec![])), "unknowns.k");
        let known = |at| DefectUnknown {
            at: Some(at),
            mass: MassUnknown::Known(2.0),
        };
        assert_eq!(
            field(Unknowns::new(5, vec![f, known(6)])),
            "unknowns.defects[1].at"
        );
        assert_eq!(
            field(Unknowns::new(5, vec![known(0)])),
            "unknowns.defects[0].at"
        );
        assert_eq!(
            field(Unknowns::new(5, vec![known(2), f, known(2)])),
            "unknowns.defects[2].at"
        );
        assert_eq!(
            field(Unknowns::new(5, vec![DefectUnknown::free(3.0, 3.0)])),
            "unknowns.defects[0].bounds"
        );
        assert_eq!(
            field(Unknowns::new(5, vec![DefectUnknown::free(-1.0, 3.0)])),
            "unknowns.defects[0].bounds"
        );
        assert_eq!(
            field(Unknowns::new(
                5,
                vec![DefectUnknown {
                    at: None,
                    mass: MassUnknown::Known(f64::NAN)
                }]
            )),
            "unknowns.defects[0].m"
        );
        let spec = UnknownsSpec {
            mass_bounds: [2.0, 1.0],
            ..UnknownsSpec::default()
        };
        assert_eq!(field(spec.build(5, 2)), "unknowns.mass_bounds");
        let spec = UnknownsSpec {
            k: Some(6),
            ..UnknownsSpec::default()
        };
        assert_eq!(field(spec.build(5, 2)), "unknowns.k");
    }

    #[test]
    fn space_and_decode() {
        let u = Unknowns::new(
            10,
            vec![
                DefectUnknown {
                    at: Some(3),
                    mass: MassUnknown::Free { lo: 1.0, hi: 9.0 },
                },
                DefectUnknown::free(0.1, 10.0),
                DefectUnknown {
                    at: None,
                    mass: MassUnknown::Known(7.0),
                },
            ],
        )
        .unwrap();
        let sp = u.space();
        assert_eq!(sp.n_positions, 2);
        assert_eq!(sp.excluded, vec![3]);
        assert_eq!(sp.bounds, vec![(1.0, 9.0), (0.1, 10.0)]);
        assert_eq!(sp.pairing, vec![None, Some(0)]);
        assert!(!u.interchangeable());
        let c = Candidate {
            positions: vec![5, 9],
            values: vec![2.0, 0.5],
        };
        assert_eq!(u.decode(&c).unwrap(), vec![(3, 2.0), (5, 0.5), (9, 7.0)]);
        for bad in [
            Candidate {
                positions: vec![3, 9],
                values: vec![2.0, 0.5],
            },
            Candidate {
                positions: vec![9, 9],
                values: vec![2.0, 0.5],
            },
            Candidate {
                positions: vec![0, 11],
                values: vec![2.0, 0.5],
            },
            Candidate {
                positions: vec![5, 9],
                values: vec![f64::NAN, 0.5],
            },
            Candidate {
                positions: vec![5, 9],
                values: vec![2.0, 50.0],
            },
            Candidate {
                positions: vec![5],
                values: vec![2.0, 0.5],
            },
        ] {
            let p = u.decode(&bad).unwrap_err();
            assert!(p.is_finite() && p >= PENALTY, "{bad:?} {p}");
        }
    }

    #[test]
    fn spec_from_toml() {
        let s: UnknownsSpec =
            toml::from_str("k = 3\nmass_bounds = [0.5, 20]\n[[defects]]\nat = 4\nm = 2.0\n")
                .unwrap();
        let u = s.build(10, 2).unwrap();
        assert_eq!(u.k(), 3);
        assert_eq!(u.free_positions(), &[1, 2]);
        assert_eq!(u.space().bounds, vec![(0.5, 20.0); 2]);
        assert!(toml::from_str::<UnknownsSpec>("kk = 3").is_err());
    }
}
