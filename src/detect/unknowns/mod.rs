//! The unknowns of a fit: one type, [`Unknowns`], for every kind of
//! unknown.
//!
//! A fit looks for `k` defects ([`Slot`]s), each of kind mass, spring or
//! damper (or `any` of the three), at an unknown or known position, with an
//! unknown value within per-kind bounds ([`KindBounds`]) or a known value,
//! and optionally the uniform chain parameters (`d`, `gamma`, `k`, `mass`)
//! fitted alongside. Mass and damper positions are `1..=n`, spring positions
//! `0..=n` (spring `i` joins masses `i` and `i + 1`; `0` and `n` are the wall
//! springs). A hypothesis is a set of `(kind, position)` pairs
//! ([`Unknowns::hypotheses`]), fitted by
//! by the fit (`detect::fit`, one layer up) or searched by the greedy
//! search (`detect::fit::greedy`). The scene's `[unknowns]` table
//! ([`UnknownsSpec`]) and the data-first fit's options build it. This module
//! imports nothing above it: the search builds its space from these
//! unknowns (`Space::for_masses`), not the other way round.
//!
//! **Mass defects only** are a special case, not a second set of unknowns:
//! [`Unknowns::to_mass`] gives them in the form the paper's Woodbury kernel
//! and the stochastic searches take ([`MassUnknowns`]); the search's
//! `Space::for_masses` builds their search space from it (one integer per unknown
//! position, one log-scaled real per unknown mass, `pairing[v] = Some(p)`
//! when mass `v` belongs to the defect of unknown position `p`; known
//! positions are `excluded`). When every defect with an unknown position
//! also has an unknown mass with the same bounds, the defects are
//! interchangeable and a hypothesis is a *set* of positions.
//!
//! ```
//! use springmass::detect::unknowns::{KindChoice, Unknowns};
//! let u = Unknowns::free(20, &[KindChoice::Mass; 2], &[])?;
//! let mass = u.to_mass()?;                 // the Woodbury kernel's view
//! assert_eq!(mass.free_positions().len(), 2);
//! assert!(mass.interchangeable());
//! let springs = Unknowns::free(20, &[KindChoice::Spring; 2], &[])?;
//! assert!(springs.to_mass().is_err());     // typed error naming unknowns.kind
//! assert!(Unknowns::free(3, &[KindChoice::Mass; 4], &[]).is_err()); // k > n
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::chain::{Chain, Defect, Probe, Site};
use crate::error::{Error, Result};
use crate::sensitivity::Param;
use serde::{Deserialize, Serialize};

mod spec;
use spec::check_bounds;
pub use spec::{DefectUnknownSpec, UnknownsSpec};

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

/// Mass-only unknowns in the form of the Woodbury kernel and the
/// stochastic searches (from [`Unknowns::to_mass`]; see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct MassUnknowns {
    n: usize,
    defects: Vec<DefectUnknown>,
    /// Indices of defects with an unknown position.
    free_pos: Vec<usize>,
    /// Indices of defects with an unknown mass.
    free_mass: Vec<usize>,
    /// The known positions, sorted.
    excluded: Vec<usize>,
}

impl MassUnknowns {
    /// Validate the unknowns of a chain of `n` masses.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming the field: `unknowns.k` when there
    /// are no defects or more than `n`; `unknowns.defects[i].at` for a known
    /// position outside `1..=n` or equal to another known position;
    /// `unknowns.defects[i].m` for a known mass that is not positive and finite;
    /// `unknowns.defects[i].bounds` for bounds that are not `0 < lo < hi`, finite.
    pub fn new(n: usize, defects: Vec<DefectUnknown>) -> Result<MassUnknowns> {
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
        Ok(MassUnknowns {
            n,
            defects,
            free_pos,
            free_mass,
            excluded,
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

    /// Positions that unknown positions may take (`1..=n` minus known positions).
    pub fn allowed_positions(&self) -> Vec<usize> {
        (1..=self.n)
            .filter(|p| self.excluded.binary_search(p).is_err())
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
    /// unknown positions (in [`MassUnknowns::free_positions`] order) and the
    /// unknown masses (in [`MassUnknowns::free_masses`] order). Unchecked.
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

    /// Map the unknown positions (in [`MassUnknowns::free_positions`]
    /// order) and unknown masses (in [`MassUnknowns::free_masses`] order) of
    /// a search candidate to defects, or return a finite penalty `>= PENALTY`
    /// growing with the size of the violation (wrong lengths, positions out
    /// of range, repeated or known, masses outside their bounds or not
    /// finite). The optimizers' space of these unknowns is
    /// `crate::detect::search::Space::for_masses`.
    pub fn decode(
        &self,
        positions: &[usize],
        masses: &[f64],
    ) -> std::result::Result<Vec<(usize, f64)>, f64> {
        if positions.len() != self.free_pos.len() || masses.len() != self.free_mass.len() {
            return Err(PENALTY * 10.0);
        }
        let mut viol = 0.0;
        for (i, &p) in positions.iter().enumerate() {
            if p == 0 || p > self.n {
                viol += 1.0 + p.abs_diff(self.n.min(p.max(1))) as f64;
            } else if self.excluded.binary_search(&p).is_ok() || positions[..i].contains(&p) {
                viol += 1.0;
            }
        }
        for (v, &i) in masses.iter().zip(&self.free_mass) {
            let MassUnknown::Free { lo, hi } = self.defects[i].mass else {
                continue;
            };
            if !v.is_finite() {
                viol += 10.0;
            } else if *v < lo || *v > hi {
                viol += 1.0 + ((v / lo).ln().abs().min((v / hi).ln().abs())).min(1e3);
            }
        }
        if viol > 0.0 {
            return Err(PENALTY * (1.0 + viol));
        }
        Ok(self.assemble(positions, masses))
    }
}

/// A concrete defect kind.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DefectKind {
    /// A mass (positions `1..=n`).
    Mass,
    /// A spring (positions `0..=n`).
    Spring,
    /// A damper to ground (positions `1..=n`).
    Damper,
    /// A spring from a mass to the ground (positions `1..=n`).
    Ground,
}

impl DefectKind {
    /// Every kind.
    pub const ALL: [DefectKind; 4] = [
        DefectKind::Mass,
        DefectKind::Spring,
        DefectKind::Damper,
        DefectKind::Ground,
    ];

    /// The kinds `any` tries, in this order: the chain's own elements. A
    /// ground spring is fitted only when asked for by name (at mass 1 and
    /// `n` it acts as a change of a wall spring, which `any` already tries).
    pub const ANY: [DefectKind; 3] = [DefectKind::Mass, DefectKind::Spring, DefectKind::Damper];

    /// The kind called `name` ([`DefectKind::name`]).
    pub fn from_name(name: &str) -> Option<DefectKind> {
        DefectKind::ALL.into_iter().find(|k| k.name() == name)
    }

    /// The kind of a defect.
    pub fn of(d: &Defect) -> DefectKind {
        match d {
            Defect::Mass { .. } => DefectKind::Mass,
            Defect::Spring { .. } => DefectKind::Spring,
            Defect::Damper { .. } => DefectKind::Damper,
            Defect::Ground { .. } => DefectKind::Ground,
        }
    }

    /// A defect's kind and position: its key in a hypothesis
    /// ([`KindPositions`]).
    pub fn key_of(d: &Defect) -> (DefectKind, usize) {
        (DefectKind::of(d), d.at())
    }

    /// `mass`, `spring`, `damper`.
    pub fn name(self) -> &'static str {
        match self {
            DefectKind::Mass => "mass",
            DefectKind::Spring => "spring",
            DefectKind::Damper => "damper",
            DefectKind::Ground => "ground",
        }
    }

    /// The positions of this kind in a chain of `n` masses (`0..=n` for a
    /// spring-like site, `1..=n` for a point site; a free end removes spring
    /// `0` or `n`: see [`Chain::spring_range`]).
    pub fn positions(self, n: usize) -> std::ops::RangeInclusive<usize> {
        match self.site(1).probe {
            Probe::Diff(_) => 0..=n,
            Probe::Point(_) => 1..=n,
        }
    }

    /// Where a defect of this kind at `at` enters the equations of motion
    /// ([`Defect::site`]).
    pub fn site(self, at: usize) -> Site {
        self.defect(at, 0.0).site()
    }

    /// Where a defect of this kind at `at` enters `chain`'s equations of
    /// motion, its damping model included ([`Chain::site`]).
    pub fn site_in(self, chain: &Chain, at: usize) -> Site {
        chain.site(&self.defect(at, 0.0))
    }

    /// The defect of this kind at `at` with `value` (unchecked).
    pub fn defect(self, at: usize, value: f64) -> Defect {
        match self {
            DefectKind::Mass => Defect::Mass { at, m: value },
            DefectKind::Spring => Defect::Spring { at, k: value },
            DefectKind::Damper => Defect::Damper { at, d: value },
            DefectKind::Ground => Defect::Ground { at, g: value },
        }
    }

    /// The starting value of an unknown defect of this kind on `chain` (the
    /// coarse start of the searches: twice the uniform mass or spring, a
    /// heavier damper).
    pub fn start(self, chain: &Chain) -> f64 {
        match self {
            DefectKind::Mass => 2.0 * chain.mass(),
            DefectKind::Spring => 2.0 * chain.k(),
            DefectKind::Damper => (5.0 * chain.d()).max(0.5),
            DefectKind::Ground => 0.5 * chain.k(),
        }
    }

    /// The alternative start of the fine pass of the hypothesis fits (a
    /// lighter mass or spring, a lighter damper than [`DefectKind::start`]).
    pub fn alt_start(self, chain: &Chain) -> f64 {
        match self {
            DefectKind::Mass => 0.5 * chain.mass(),
            DefectKind::Spring => 0.5 * chain.k(),
            DefectKind::Damper => 0.2 * chain.d(),
            DefectKind::Ground => 0.05 * chain.k(),
        }
    }

    /// Whether a value of zero is allowed ([`Defect::may_vanish`]).
    pub fn may_vanish(self) -> bool {
        self.defect(1, 1.0).may_vanish()
    }

    /// The uniform chain's value of this kind (`mass`, `k` or `d`; on a
    /// [`crate::chain::Baseline`] the profile's mean, a scale only: a
    /// kernel's reference value is [`DefectKind::base_at`]).
    pub fn uniform(self, chain: &Chain) -> f64 {
        match self {
            DefectKind::Mass => chain.mass(),
            DefectKind::Spring => chain.k(),
            _ => self.defect(1, 0.0).base_value(&chain.without_baseline()),
        }
    }

    /// The value of this kind at `at` in `chain` without defects (the
    /// uniform value, or the baseline's there): the reference a defect's
    /// change is measured from ([`Defect::base_value`]).
    pub fn base_at(self, chain: &Chain, at: usize) -> f64 {
        self.defect(at, 0.0).base_value(chain)
    }
}

/// The kind of an unknown defect, as the scene states it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum KindChoice {
    /// A mass (default).
    #[default]
    Mass,
    /// A spring.
    Spring,
    /// A damper.
    Damper,
    /// A spring to the ground.
    Ground,
    /// Any of mass, spring and damper ([`DefectKind::ANY`]).
    Any,
    /// A mass or a spring: `any` where the damping model takes no damper
    /// defect (modal damping, [`KindChoice::under`]).
    #[serde(rename = "mass-or-spring")]
    MassOrSpring,
}

impl From<DefectKind> for KindChoice {
    /// The choice of exactly this kind.
    fn from(kind: DefectKind) -> KindChoice {
        match kind {
            DefectKind::Mass => KindChoice::Mass,
            DefectKind::Spring => KindChoice::Spring,
            DefectKind::Damper => KindChoice::Damper,
            DefectKind::Ground => KindChoice::Ground,
        }
    }
}

impl KindChoice {
    /// The concrete kinds allowed.
    pub fn kinds(self) -> &'static [DefectKind] {
        match self {
            KindChoice::Mass => &[DefectKind::Mass],
            KindChoice::Spring => &[DefectKind::Spring],
            KindChoice::Damper => &[DefectKind::Damper],
            KindChoice::Ground => &[DefectKind::Ground],
            KindChoice::Any => &DefectKind::ANY,
            KindChoice::MassOrSpring => &[DefectKind::Mass, DefectKind::Spring],
        }
    }

    /// The choice a chain of damping model `damping` can take: `any`
    /// without dampers under modal damping (its damping is a ratio per
    /// mode, and a damper defect would make it non-modal); every other
    /// choice as it is.
    pub fn under(self, damping: &crate::chain::Damping) -> KindChoice {
        match self {
            KindChoice::Any if damping.is_modal() => KindChoice::MassOrSpring,
            k => k,
        }
    }

    /// `mass`, `spring`, `damper`, `ground`, `any`, `mass-or-spring`.
    pub fn name(self) -> &'static str {
        match self {
            KindChoice::Mass => "mass",
            KindChoice::Spring => "spring",
            KindChoice::Damper => "damper",
            KindChoice::Ground => "ground",
            KindChoice::Any => "any",
            KindChoice::MassOrSpring => "mass-or-spring",
        }
    }
}

/// Default value bounds per kind.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KindBounds {
    /// Masses, `0 < lo < hi`.
    pub mass: (f64, f64),
    /// Springs, `0 < lo < hi`.
    pub spring: (f64, f64),
    /// Dampers, `0 <= lo < hi`.
    pub damper: (f64, f64),
    /// Springs to the ground, `0 <= lo < hi`.
    pub ground: (f64, f64),
}

impl Default for KindBounds {
    /// `[0.1, 100]`, `[0.01, 100]`, `[0, 100]`.
    fn default() -> Self {
        KindBounds {
            mass: (0.1, 100.0),
            spring: (0.01, 100.0),
            damper: (0.0, 100.0),
            ground: (0.0, 100.0),
        }
    }
}

impl KindBounds {
    /// The default ranges scaled to `chain`'s uniform values, so that a
    /// chain in physical units (mass 1000 kg, stiffness 2e6 N/m) is searched
    /// as the paper's: mass `[0.1, 100] m`, spring `[0.01, 100] k`, damper
    /// `[0, 100 sqrt(k m)]`; the paper's chain gets [`KindBounds::default`].
    ///
    /// ```
    /// use springmass::{Chain, detect::unknowns::KindBounds};
    /// assert_eq!(KindBounds::for_chain(&Chain::paper(3)?), KindBounds::default());
    /// let si = Chain::paper(3)?.with_mass(1000.0)?.with_k(4e6)?;
    /// assert_eq!(KindBounds::for_chain(&si).mass, (100.0, 1e5));
    /// # Ok::<(), springmass::Error>(())
    /// ```
    pub fn for_chain(chain: &Chain) -> KindBounds {
        let (m, k) = (chain.mass(), chain.k());
        KindBounds {
            mass: (0.1 * m, 100.0 * m),
            spring: (0.01 * k, 100.0 * k),
            damper: (0.0, 100.0 * (k * m).sqrt()),
            ground: (0.0, 100.0 * k),
        }
    }

    /// The bounds of `kind`.
    pub fn of(&self, kind: DefectKind) -> (f64, f64) {
        match kind {
            DefectKind::Mass => self.mass,
            DefectKind::Spring => self.spring,
            DefectKind::Damper => self.damper,
            DefectKind::Ground => self.ground,
        }
    }

    /// Set the bounds of `kind`.
    pub fn set(&mut self, kind: DefectKind, bounds: (f64, f64)) {
        match kind {
            DefectKind::Mass => self.mass = bounds,
            DefectKind::Spring => self.spring = bounds,
            DefectKind::Damper => self.damper = bounds,
            DefectKind::Ground => self.ground = bounds,
        }
    }
}

/// One defect of a general fit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Slot {
    /// Its kind (or `Any`).
    pub kind: KindChoice,
    /// Known position, or `None`.
    pub at: Option<usize>,
    /// Known value, or `None` (fitted).
    pub known: Option<f64>,
    /// Bounds of the fitted value (default: the kind's).
    pub bounds: Option<(f64, f64)>,
}

impl Slot {
    /// Position and value unknown.
    pub fn free(kind: KindChoice) -> Slot {
        Slot {
            kind,
            at: None,
            known: None,
            bounds: None,
        }
    }
}

/// A hypothesis of a general fit: `(kind, position)` per slot.
pub type KindPositions = Vec<(DefectKind, usize)>;

/// Put a set of `(kind, position)` pairs in the order hypotheses are keyed
/// by: position, then kind.
pub fn by_position(set: &mut [(DefectKind, usize)]) {
    set.sort_by_key(|&(kind, at)| (at, kind));
}

/// The checks of slot `i` of `slots` (see [`Unknowns::new`]): its known
/// position distinct and of its kind, its known value in the kind's range,
/// its bounds.
fn check_slot(n: usize, slots: &[Slot], i: usize) -> Result<()> {
    let s = &slots[i];
    if let Some(at) = s.at {
        if let Some(j) = slots[..i]
            .iter()
            .position(|o| o.at == Some(at) && o.kind == s.kind)
        {
            return Err(Error::invalid(
                format!("unknowns.defects[{i}].at"),
                at,
                format!("distinct from unknowns.defects[{j}].at"),
            ));
        }
        if !s.kind.kinds().iter().any(|k| k.positions(n).contains(&at)) {
            return Err(Error::invalid(
                format!("unknowns.defects[{i}].at"),
                at,
                format!(
                    "a {} position of n = {n} (masses and dampers 1..=n, springs 0..=n)",
                    s.kind.name()
                ),
            ));
        }
    }
    if let Some(v) = s.known {
        let ok = match s.kind.kinds() {
            [kind] => v > 0.0 || (v == 0.0 && kind.may_vanish()),
            _ => false,
        };
        if !(v.is_finite() && ok) {
            return Err(Error::invalid(
                format!("unknowns.defects[{i}].m"),
                v,
                "finite, in the kind's range, and a concrete kind",
            ));
        }
    }
    if let Some((lo, hi)) = s.bounds {
        let positive = s.kind.kinds().iter().any(|k| !k.may_vanish());
        check_bounds(&format!("unknowns.defects[{i}].bounds"), [lo, hi], positive)?;
    }
    Ok(())
}

/// Validated unknowns of a fit (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct Unknowns {
    n: usize,
    slots: Vec<Slot>,
    chain: Vec<Param>,
    bounds: KindBounds,
    /// The `(kind, position)` pairs the defects of unknown position may
    /// take (`None`: every pair their kinds allow); see
    /// [`Unknowns::among`].
    candidates: Option<Vec<(DefectKind, usize)>>,
    /// The hypotheses themselves, when the search is nested in the answers
    /// of one defect fewer (`None`: every set of the candidates); see
    /// [`Unknowns::within`].
    sets: Option<Vec<KindPositions>>,
}

impl Unknowns {
    /// Validate.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming the field: `unknowns.k` (no slots);
    /// `unknowns.defects[i].at` (a known position outside the positions of
    /// every allowed kind); `unknowns.defects[i].m` (a known value outside the
    /// kind's range, or with kind `any`); `unknowns.defects[i].bounds`
    /// (not `lo < hi`, finite, inside the kind's range); `unknowns.chain`
    /// (not `D`, `K`, `Mass`, `Gamma`, a repeat, or all four).
    pub fn new(
        n: usize,
        slots: Vec<Slot>,
        chain: Vec<Param>,
        bounds: KindBounds,
    ) -> Result<Unknowns> {
        if slots.is_empty() {
            return Err(Error::invalid("unknowns.k", 0, ">= 1"));
        }
        // as many defects as there are (kind, position) pairs for them
        let mut kinds: Vec<DefectKind> =
            slots.iter().flat_map(|s| s.kind.kinds()).copied().collect();
        kinds.sort_unstable();
        kinds.dedup();
        let pairs: usize = kinds.iter().map(|k| k.positions(n).count()).sum();
        if slots.len() > pairs {
            return Err(Error::invalid(
                "unknowns.k",
                slots.len(),
                format!(
                    "1 <= k <= {pairs}, the (kind, position) pairs of n = {n} (masses and dampers 1..=n, springs 0..=n)"
                ),
            ));
        }
        for i in 0..slots.len() {
            check_slot(n, &slots, i)?;
        }
        check_chain_params("unknowns.chain", &chain)?;
        Ok(Unknowns {
            n,
            slots,
            chain,
            bounds,
            candidates: None,
            sets: None,
        })
    }

    /// The mass-only special case in the form the Woodbury kernel's
    /// enumeration and the stochastic searches take ([`MassUnknowns`]):
    /// every defect a mass (known or bounded), no chain parameter fitted.
    ///
    /// # Errors
    /// A defect of another kind (field `unknowns.kind`) or fitted chain
    /// parameters (field `unknowns.chain`); as [`MassUnknowns::new`].
    pub fn to_mass(&self) -> Result<MassUnknowns> {
        if let Some(s) = self.slots.iter().find(|s| s.kind != KindChoice::Mass) {
            return Err(Error::invalid(
                "unknowns.kind",
                s.kind.name(),
                "mass for the mass-only kernel (the data-first fit takes every kind)",
            ));
        }
        if !self.chain.is_empty() {
            return Err(Error::invalid(
                "unknowns.chain",
                format!("{} parameters", self.chain.len()),
                "none for the mass-only kernel (the data-first fit fits chain parameters)",
            ));
        }
        let defects = (0..self.slots.len())
            .map(|i| {
                let s = &self.slots[i];
                let mass = match s.known {
                    Some(m) => MassUnknown::Known(m),
                    None => {
                        let (lo, hi) = self.bounds(i, DefectKind::Mass);
                        MassUnknown::Free { lo, hi }
                    }
                };
                DefectUnknown { at: s.at, mass }
            })
            .collect();
        MassUnknowns::new(self.n, defects)
    }

    /// `k` free defects of one kind, chain parameters `chain`, default bounds.
    ///
    /// # Errors
    /// As [`Unknowns::new`].
    pub fn free(n: usize, kinds: &[KindChoice], chain: &[Param]) -> Result<Unknowns> {
        Unknowns::new(
            n,
            kinds.iter().map(|&k| Slot::free(k)).collect(),
            chain.to_vec(),
            KindBounds::default(),
        )
    }

    /// Number of masses.
    pub fn n(&self) -> usize {
        self.n
    }
    /// Number of defects sought (known ones included).
    pub fn k(&self) -> usize {
        self.slots.len()
    }
    /// The defects.
    pub fn slots(&self) -> &[Slot] {
        &self.slots
    }
    /// The chain parameters fitted.
    pub fn chain(&self) -> &[Param] {
        &self.chain
    }
    /// The per-kind default bounds.
    pub fn kind_bounds(&self) -> &KindBounds {
        &self.bounds
    }

    /// The same unknowns with the defects of unknown position restricted to
    /// the `(kind, position)` pairs `pairs` (the narrowed search over every
    /// kind, `detect::fit::narrow`); defects of known position are not
    /// restricted. [`Unknowns::hypotheses`] draws from these pairs only.
    pub fn among(&self, pairs: Vec<(DefectKind, usize)>) -> Unknowns {
        Unknowns {
            candidates: Some(pairs),
            ..self.clone()
        }
    }

    /// The pairs of [`Unknowns::among`], if restricted.
    pub fn candidates(&self) -> Option<&[(DefectKind, usize)]> {
        self.candidates.as_deref()
    }

    /// The same unknowns with the hypotheses given: `sets`, each a
    /// `(kind, position)` pair per slot, sorted by position then kind (the
    /// order of [`Unknowns::hypotheses`]), each once (the search nested in
    /// the best answers of one defect fewer, `detect::fit::narrow`). Only
    /// for unknowns whose every slot is free and alike.
    ///
    /// # Errors
    /// Slots of known position or unlike slots (field `unknowns.defects`);
    /// a set of another size, a pair no slot may take, a pair twice, or
    /// unsorted (field `sets`).
    pub fn within(&self, mut sets: Vec<KindPositions>) -> Result<Unknowns> {
        let first = self.slots[0];
        if self.slots.iter().any(|s| s.at.is_some() || *s != first) {
            return Err(Error::invalid(
                "unknowns.defects",
                "known positions or unlike slots",
                "free slots, all alike, for a nested search",
            ));
        }
        let allowed = |&(kind, at): &(DefectKind, usize)| {
            first.kind.kinds().contains(&kind)
                && kind.positions(self.n).contains(&at)
                && self
                    .candidates
                    .as_ref()
                    .is_none_or(|c| c.contains(&(kind, at)))
        };
        for set in &sets {
            let sorted = set.windows(2).all(|w| (w[0].1, w[0].0) < (w[1].1, w[1].0));
            if set.len() != self.slots.len() || !sorted || !set.iter().all(allowed) {
                return Err(Error::invalid(
                    "sets",
                    format!("{set:?}"),
                    format!(
                        "{} distinct (kind, position) pairs the slots allow, sorted by position then kind",
                        self.slots.len()
                    ),
                ));
            }
        }
        sets.sort();
        sets.dedup();
        Ok(Unknowns {
            sets: Some(sets),
            ..self.clone()
        })
    }

    /// Whether the search of these unknowns ranks the set `set` of
    /// `(kind, position)` pairs of free defects (in any order): one of the
    /// sets of [`Unknowns::within`], or every pair among the candidates of
    /// [`Unknowns::among`] and as many pairs as free slots.
    pub fn admits(&self, set: &[(DefectKind, usize)]) -> bool {
        let mut key = set.to_vec();
        by_position(&mut key);
        if let Some(sets) = &self.sets {
            return sets.contains(&key);
        }
        let free: Vec<&Slot> = self.slots.iter().filter(|s| s.at.is_none()).collect();
        key.len() == free.len()
            && key.windows(2).all(|w| w[0] != w[1])
            && key.iter().all(|&(kind, at)| {
                free.iter().any(|s| s.kind.kinds().contains(&kind))
                    && kind.positions(self.n).contains(&at)
                    && self
                        .candidates
                        .as_ref()
                        .is_none_or(|c| c.contains(&(kind, at)))
            })
    }

    /// The hypotheses of [`Unknowns::within`], if given.
    pub fn sets(&self) -> Option<&[KindPositions]> {
        self.sets.as_deref()
    }

    /// Bounds of slot `i` as kind `kind`.
    pub fn bounds(&self, i: usize, kind: DefectKind) -> (f64, f64) {
        self.slots[i].bounds.unwrap_or(self.bounds.of(kind))
    }

    /// The `(kind, position)` sets of `count` interchangeable slots like
    /// `s`: every `count`-subset of its candidate pairs, ordered by position
    /// then kind. Refused before they are drawn when too many (see
    /// [`Unknowns::hypotheses`]).
    ///
    /// # Errors
    /// More than `max` sets even after the other slots took one pair each
    /// (field `search.max_sets`).
    fn group_sets(&self, s: &Slot, count: usize, max: usize) -> Result<Vec<KindPositions>> {
        let mut cands: KindPositions = Vec::new();
        for &k in s.kind.kinds() {
            for at in k.positions(self.n) {
                let allowed = match (s.at, &self.candidates) {
                    (Some(a), _) => a == at,
                    (None, Some(c)) => c.contains(&(k, at)),
                    (None, None) => true,
                };
                if allowed {
                    cands.push((k, at));
                }
            }
        }
        cands.sort_by_key(|&(k, at)| (at, k));
        // refused before the sets are drawn when they are too many (every
        // set of four of 300 masses is 331 million: the process aborted on
        // memory before the count of the whole product was reached): the
        // other slots take at most one pair each, so at least this many
        // hypotheses remain
        let least = binomial(cands.len().saturating_sub(self.slots.len() - count), count);
        if least > max as f64 {
            return Err(Error::invalid(
                "search.max_sets",
                max,
                format!("at least {least:.0} hypotheses (fewer unknowns, or a larger max_sets)"),
            ));
        }
        let all: Vec<usize> = (0..cands.len()).collect();
        Ok(crate::detect::unknowns::subsets(&all, count)
            .into_iter()
            .map(|c| c.into_iter().map(|j| cands[j]).collect())
            .collect())
    }

    /// Every admissible hypothesis, deterministic order: slots with the same
    /// description are interchangeable (their `(kind, position)` pairs form a
    /// set, drawn by [`subsets`] from the
    /// candidates ordered by position then kind); no `(kind, position)`
    /// twice; or the sets of [`Unknowns::within`]. Stops with an error
    /// beyond `max` hypotheses.
    ///
    /// # Errors
    /// More than `max` hypotheses (field `search.max_sets`).
    pub fn hypotheses(&self, max: usize) -> Result<Vec<KindPositions>> {
        if let Some(sets) = &self.sets {
            return match sets.len() > max {
                true => Err(Error::invalid(
                    "search.max_sets",
                    max,
                    format!("at least {} hypotheses (a larger max_sets)", sets.len()),
                )),
                false => Ok(sets.clone()),
            };
        }
        // groups of identical slots, in order of first appearance
        let mut groups: Vec<(Slot, Vec<usize>)> = Vec::new();
        for (i, s) in self.slots.iter().enumerate() {
            match groups.iter_mut().find(|g| g.0 == *s) {
                Some(g) => g.1.push(i),
                None => groups.push((*s, vec![i])),
            }
        }
        let per_group: Vec<Vec<KindPositions>> = groups
            .iter()
            .map(|(s, idx)| self.group_sets(s, idx.len(), max))
            .collect::<Result<_>>()?;
        let mut out: Vec<KindPositions> = vec![vec![(DefectKind::Mass, 0); self.slots.len()]];
        for ((_, idx), choices) in groups.iter().zip(&per_group) {
            let mut next = Vec::with_capacity(out.len() * choices.len());
            for h in &out {
                for c in choices {
                    let mut h2 = h.clone();
                    for (&slot, &pair) in idx.iter().zip(c) {
                        h2[slot] = pair;
                    }
                    next.push(h2);
                }
                if next.len() > max.saturating_mul(4) {
                    break;
                }
            }
            out = next;
        }
        let filled: Vec<usize> = groups.iter().flat_map(|g| g.1.iter().copied()).collect();
        out.retain(|h| {
            filled
                .iter()
                .enumerate()
                .all(|(a, &i)| filled[..a].iter().all(|&j| h[j] != h[i]))
        });
        if out.len() > max {
            return Err(Error::invalid(
                "search.max_sets",
                max,
                format!(
                    "at least {} hypotheses (fewer unknowns, or a larger max_sets)",
                    out.len()
                ),
            ));
        }
        Ok(out)
    }
}

/// `C(n, p)` as a float (exact below 2^53).
fn binomial(n: usize, p: usize) -> f64 {
    if p > n {
        return 0.0;
    }
    (0..p).fold(1.0, |c, i| c * (n - i) as f64 / (i + 1) as f64)
}

/// All `p`-subsets of `allowed`, each in the order of `allowed`, in
/// lexicographic order of their indices (`p = 0`: one empty set; `p >
/// allowed.len()`: none). The position-set generator shared by the
/// enumeration and the general hypothesis fits.
///
/// ```
/// use springmass::detect::unknowns::subsets;
/// assert_eq!(subsets(&[1, 2, 3], 2), vec![vec![1, 2], vec![1, 3], vec![2, 3]]);
/// ```
pub fn subsets(allowed: &[usize], p: usize) -> Vec<Vec<usize>> {
    let mut out = Vec::new();
    gen_sets(allowed, p, true, 0, &mut Vec::with_capacity(p), &mut out);
    out
}

pub(crate) fn gen_sets(
    allowed: &[usize],
    p: usize,
    comb: bool,
    from: usize,
    cur: &mut Vec<usize>,
    out: &mut Vec<Vec<usize>>,
) {
    if cur.len() == p {
        out.push(cur.clone());
        return;
    }
    let start = if comb { from } else { 0 };
    for i in start..allowed.len() {
        let a = allowed[i];
        if !comb && cur.contains(&a) {
            continue;
        }
        cur.push(a);
        gen_sets(allowed, p, comb, i + 1, cur, out);
        cur.pop();
    }
}

/// Chain parameters to fit (field `field`): distinct, none a defect, at
/// most three of the four (`x_1(t)` is unchanged when every mass, damper,
/// spring and gamma are scaled together).
pub(crate) fn check_chain_params(field: &str, params: &[Param]) -> Result<()> {
    for (i, p) in params.iter().enumerate() {
        if matches!(p, Param::Defect(_)) || params[..i].contains(p) {
            return Err(Error::invalid(
                field,
                format!("{p:?}"),
                "distinct names among d, gamma, k, mass",
            ));
        }
    }
    if params.len() == 4 {
        return Err(Error::invalid(
            field,
            "d, gamma, k, mass",
            "at most three: x_1(t) is unchanged when every mass, damper, spring and gamma are scaled together",
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `any` under modal damping is a mass or a spring (the model has no
    /// dampers); every other choice and damping model as it is.
    #[test]
    fn every_kind_under_modal_damping_leaves_out_dampers() {
        use crate::chain::Damping;
        let modal = Damping::parse_complete("modal:0.02").unwrap();
        let grounded = Damping::default();
        assert_eq!(KindChoice::Any.under(&modal), KindChoice::MassOrSpring);
        assert_eq!(KindChoice::Any.under(&grounded), KindChoice::Any);
        assert_eq!(KindChoice::Damper.under(&modal), KindChoice::Damper);
        assert_eq!(
            KindChoice::MassOrSpring.kinds(),
            &[DefectKind::Mass, DefectKind::Spring]
        );
    }

    /// Too many sets are refused before they are drawn (four free masses
    /// of 300: 331 million sets were being drawn when the process aborted
    /// on memory), with a count that is a lower bound of the
    /// hypotheses; a search within `max` is drawn in full.
    #[test]
    fn too_many_sets_are_refused_before_they_are_drawn() {
        let free = |n: usize, k: usize| {
            Unknowns::new(
                n,
                vec![Slot::free(KindChoice::Mass); k],
                vec![],
                KindBounds::default(),
            )
            .unwrap()
        };
        let e = free(300, 4).hypotheses(200_000).unwrap_err().to_string();
        assert!(e.contains("max_sets") && e.contains("330791175"), "{e}");
        // C(300, 3) = 4 455 100
        assert!(free(300, 3).hypotheses(200_000).is_err());
        assert_eq!(free(60, 3).hypotheses(200_000).unwrap().len(), 34_220);
        // a slot at a known position takes one pair: C(59, 3) remain
        let mut slots = vec![Slot::free(KindChoice::Mass); 3];
        slots.push(Slot {
            at: Some(5),
            ..Slot::free(KindChoice::Mass)
        });
        let u = Unknowns::new(60, slots, vec![], KindBounds::default()).unwrap();
        assert_eq!(u.hypotheses(200_000).unwrap().len(), 32_509);
        assert_eq!(binomial(61, 4), 521_855.0);
        assert_eq!(binomial(3, 4), 0.0);
    }

    fn field<T: std::fmt::Debug>(r: Result<T>) -> String {
        match r {
            Err(Error::InvalidParameter { field, .. }) => field,
            other => panic!("expected an invalid-parameter error, got {other:?}"),
        }
    }

    #[test]
    fn bad_unknowns_name_the_field() {
        let f = DefectUnknown::free(0.1, 10.0);
        assert_eq!(field(MassUnknowns::new(3, vec![f; 4])), "unknowns.k");
        assert_eq!(field(MassUnknowns::new(3, vec![])), "unknowns.k");
        let known = |at| DefectUnknown {
            at: Some(at),
            mass: MassUnknown::Known(2.0),
        };
        assert_eq!(
            field(MassUnknowns::new(5, vec![f, known(6)])),
            "unknowns.defects[1].at"
        );
        assert_eq!(
            field(MassUnknowns::new(5, vec![known(0)])),
            "unknowns.defects[0].at"
        );
        assert_eq!(
            field(MassUnknowns::new(5, vec![known(2), f, known(2)])),
            "unknowns.defects[2].at"
        );
        assert_eq!(
            field(MassUnknowns::new(5, vec![DefectUnknown::free(3.0, 3.0)])),
            "unknowns.defects[0].bounds"
        );
        assert_eq!(
            field(MassUnknowns::new(5, vec![DefectUnknown::free(-1.0, 3.0)])),
            "unknowns.defects[0].bounds"
        );
        assert_eq!(
            field(MassUnknowns::new(
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
    fn spec_from_toml() {
        let s: UnknownsSpec =
            toml::from_str("k = 3\nmass_bounds = [0.5, 20]\n[[defects]]\nat = 4\nm = 2.0\n")
                .unwrap();
        let u = s.build(10, 2).unwrap().to_mass().unwrap();
        assert_eq!(u.k(), 3);
        assert_eq!(u.free_positions(), &[1, 2]);
        assert_eq!(u.defects()[1].mass, MassUnknown::Free { lo: 0.5, hi: 20.0 });
        assert!(toml::from_str::<UnknownsSpec>("kk = 3").is_err());
    }
}
