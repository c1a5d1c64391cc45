//! The physical model: a chain of `n` masses in series, each end fixed to a
//! wall by a spring or free ([`Boundary`]).
//!
//! ```text
//! wall ─k_0─ m_1 ─k_1─ m_2 ─ ... ─ m_n ─k_n─ wall      (each mass also has a damper d_i to ground)
//! ```
//!
//! A free end has no wall spring (`k_0 = 0` on the left, `k_n = 0` on the
//! right): the roof of a shear building or the tip of a cantilever. With
//! both ends free the chain has a rigid-body mode (a pole of every response at
//! `s = 0`).
//!
//! Equations of motion (impulse `gamma * delta(t)` on mass 1, zero initial state):
//!
//! `m_i x_i'' + d_i x_i' + (k_{i-1} + k_i) x_i - k_{i-1} x_{i-1} - k_i x_{i+1} = gamma delta(t) [i = 1]`
//!
//! The *uniform* chain has `m_i = mass`, `k_i = k`, `d_i = d`; a [`Defect`] changes one
//! mass, one spring or one damper. The paper's chain is `mass = 1, k = 1, d = 0.1, gamma = 1`
//! ([`Chain::paper`]).

use crate::error::{check_f64, Error, Result};
use serde::{Deserialize, Serialize};

mod baseline;
mod baseline_csv;
mod damping;
#[cfg(test)]
pub(crate) mod dense_ref;
mod spec;
mod with_baseline;
pub use baseline::{Baseline, BaselineSpec};
pub(crate) use damping::closed_theta;
pub use damping::Damping;
pub use spec::{ChainSpec, Units};
use std::sync::Arc;

/// How one end of the chain is held.
///
/// `Fixed` (the default, the paper's setup): a wall spring `k_0` (left) or
/// `k_n` (right) of the uniform stiffness, changeable by a spring defect at
/// index `0` or `n`. `Free`: no wall spring; spring index `0` (or `n`) does
/// not exist.
///
/// ```
/// use springmass::chain::Boundary;
/// assert_eq!("free".parse::<Boundary>().unwrap(), Boundary::Free);
/// assert_eq!(Boundary::default(), Boundary::Fixed);
/// ```
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Boundary {
    /// Attached to a wall by a spring.
    #[default]
    Fixed,
    /// No wall spring.
    Free,
}

impl Boundary {
    /// `fixed` or `free`.
    pub fn name(self) -> &'static str {
        match self {
            Boundary::Fixed => "fixed",
            Boundary::Free => "free",
        }
    }
    /// `true` for [`Boundary::Free`].
    pub fn is_free(self) -> bool {
        self == Boundary::Free
    }
}

impl std::fmt::Display for Boundary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Boundary {
    type Err = Error;
    fn from_str(s: &str) -> Result<Boundary> {
        match s.trim().to_ascii_lowercase().as_str() {
            "fixed" | "wall" | "clamped" => Ok(Boundary::Fixed),
            "free" => Ok(Boundary::Free),
            _ => Err(Error::invalid("boundary", s, "fixed or free")),
        }
    }
}

/// Largest chain length accepted (the closed-form model is O(1) in `n`; the
/// O(n) reference solver and the simulator are not).
pub const MAX_N: usize = 1_000_000_000;

/// A vector the Green's function is applied to: a point load `e_j` (mass
/// and damper defects, observations) or a strain `e_i - e_{i+1}` (spring `i`,
/// `0..=n`, with `e_0 = e_{n+1} = 0`; spring `0` and `n` exist only at a
/// fixed end).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Probe {
    /// `e_j`, `1 <= j <= n`.
    Point(usize),
    /// `e_i - e_{i+1}`, `0 <= i <= n`.
    Diff(usize),
}

impl Probe {
    /// The first and last mass index the probe touches (`0` and `n + 1`
    /// stand for the walls).
    pub fn span(self) -> (usize, usize) {
        match self {
            Probe::Point(j) => (j, j),
            Probe::Diff(i) => (i, i + 1),
        }
    }

    /// `(mass index, weight)` of the probe's nonzero entries inside `1..=n`.
    pub fn entries(self, n: usize) -> impl Iterator<Item = (usize, f64)> {
        let (a, b) = match self {
            Probe::Point(j) => ((j, 1.0), None),
            Probe::Diff(i) => ((i, 1.0), Some((i + 1, -1.0))),
        };
        std::iter::once(a)
            .chain(b)
            .filter(move |&(i, _)| i >= 1 && i <= n)
    }
}

/// Where a defect enters the equations of motion `(M s^2 + D s + K) x = f`:
/// the rank-one update `u (value - uniform) p(s) u^T` with `u = probe` and
/// the polynomial `p(s) = poly[0] + poly[1] s + poly[2] s^2`. `power` is
/// the kind's own power of `s` (2: a mass, 1: a damper, 0: a stiffness), and
/// `p(s) = s^power` in the grounded model; a damping model adds terms (a
/// Rayleigh mass defect has `p(s) = s^2 + a s`, see [`Chain::site`]).
/// Every kernel reads `p(s)` through [`Site::poly_at`] or `poly`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Site {
    /// The vector `u`.
    pub probe: Probe,
    /// The kind's power of `s` (which coefficient array the value sits in).
    pub power: u32,
    /// The coefficients of `p(s)`, lowest power first.
    pub poly: [f64; 3],
}

impl Site {
    /// The site of the grounded model: `p(s) = s^power`.
    pub fn monomial(probe: Probe, power: u32) -> Site {
        let mut poly = [0.0; 3];
        poly[power.min(2) as usize] = 1.0;
        Site { probe, power, poly }
    }

    /// `p(s)` is `s^power` alone (the grounded model's form).
    pub fn is_monomial(&self) -> bool {
        *self == Site::monomial(self.probe, self.power)
    }

    /// `p(s)`.
    pub fn poly_at<T: crate::scalar::Scalar>(&self, s: &T) -> T {
        let mut out = T::from_f64(self.poly[0]);
        if self.poly[1] != 0.0 {
            out = out + s.scale(self.poly[1]);
        }
        if self.poly[2] != 0.0 {
            out = out + (s.clone() * s.clone()).scale(self.poly[2]);
        }
        out
    }
}

/// The coefficient arrays of a chain's equations of motion
/// `m_i x_i'' + d_i x_i' + (g_i + k_{i-1} + k_i) x_i - k_{i-1} x_{i-1} - k_i x_{i+1} = f_i`
/// ([`Chain::coefficients`]); every solver that assembles the matrices
/// reads them from here.
#[derive(Clone, Debug, PartialEq)]
pub struct Coefficients {
    /// `n` masses (0-based).
    pub m: Vec<f64>,
    /// `n` dampers to the ground (0-based).
    pub d: Vec<f64>,
    /// `n` ground stiffnesses (0-based; zero in the uniform chain).
    pub g: Vec<f64>,
    /// `n + 1` springs, `k[i]` between mass `i` and `i + 1` (`0` at a free end).
    pub k: Vec<f64>,
    /// `n + 1` dampers parallel to the springs, `c[i]` beside `k[i]` (zero
    /// in the grounded model and at a free end): `D = diag(d) + Lap(c)`.
    pub c: Vec<f64>,
}

/// One place where the chain differs from the uniform chain.
///
/// Each defect is a rank-1 update `u c(s) u^T` of the uniform chain's dynamic
/// stiffness `K(s) = M s^2 + D s + K_spring`:
///
/// | defect | `u` | `c(s)` |
/// |---|---|---|
/// | `Mass { at: j, m }` | `e_j` | `(m - mass) s^2` |
/// | `Damper { at: j, d }` | `e_j` | `(d - d_uniform) s` |
/// | `Spring { at: i, k }` | `e_i - e_{i+1}` (`e_0 = e_{n+1} = 0`) | `k - k_uniform` |
/// | `Ground { at: j, g }` | `e_j` | `g` (the uniform chain has no spring from a mass to the ground) |
///
/// Positions are 1-based (`1..=n`) for masses and dampers; springs are numbered
/// `0..=n`, spring `i` joining mass `i` and mass `i+1`, springs `0` and `n`
/// being the ones attached to the walls.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum Defect {
    /// Mass `m` at mass position `at` (1-based).
    Mass {
        /// Position, `1..=n`.
        at: usize,
        /// Mass, `> 0`.
        m: f64,
    },
    /// Stiffness `k` of spring `at` (`0..=n`).
    Spring {
        /// Spring index, `0..=n`.
        at: usize,
        /// Stiffness, `> 0`.
        k: f64,
    },
    /// Damping `d` on mass `at` (1-based).
    Damper {
        /// Position, `1..=n`.
        at: usize,
        /// Damping, `>= 0`.
        d: f64,
    },
    /// A spring of stiffness `g` from mass `at` (1-based) to the ground: an
    /// elastic support or a stray contact. (At mass 1 it acts as a change of
    /// the left wall spring, at mass `n` of the right one: the data cannot
    /// tell those apart.)
    Ground {
        /// Position, `1..=n`.
        at: usize,
        /// Stiffness, `>= 0`.
        g: f64,
    },
}

impl Coefficients {
    /// The diagonal of `K`: `g_i + k_{i-1} + k_i` (0-based).
    pub fn k_diag(&self) -> Vec<f64> {
        (0..self.m.len())
            .map(|i| self.g[i] + self.k[i] + self.k[i + 1])
            .collect()
    }

    /// The diagonal of `D`: `d_i + c_{i-1} + c_i` (0-based).
    pub fn d_diag(&self) -> Vec<f64> {
        (0..self.m.len())
            .map(|i| self.d[i] + self.c[i] + self.c[i + 1])
            .collect()
    }

    /// Any spring-parallel damper (`D` not diagonal).
    pub fn has_spring_dampers(&self) -> bool {
        self.c.iter().any(|&c| c != 0.0)
    }
}

impl Defect {
    /// Every kind's name, in the order of [`Defect::KINDS`]'s variants.
    pub const KINDS: [&'static str; 4] = ["mass", "spring", "damper", "ground"];

    /// `mass`, `spring` or `damper`.
    pub fn kind(&self) -> &'static str {
        match self {
            Defect::Mass { .. } => "mass",
            Defect::Spring { .. } => "spring",
            Defect::Damper { .. } => "damper",
            Defect::Ground { .. } => "ground",
        }
    }

    /// The defect of kind `kind` (a name of [`Defect::KINDS`]) at `at` with
    /// value `value`; `None` for an unknown name. Not validated (see
    /// [`Chain::with_defect`]).
    pub fn of_kind(kind: &str, at: usize, value: f64) -> Option<Defect> {
        Some(match kind {
            "mass" => Defect::Mass { at, m: value },
            "spring" => Defect::Spring { at, k: value },
            "damper" => Defect::Damper { at, d: value },
            "ground" => Defect::Ground { at, g: value },
            _ => return None,
        })
    }

    /// The position (mass index or spring index).
    pub fn at(&self) -> usize {
        match *self {
            Defect::Mass { at, .. }
            | Defect::Spring { at, .. }
            | Defect::Damper { at, .. }
            | Defect::Ground { at, .. } => at,
        }
    }

    /// Kind and position, as reports name a defect: `mass@8`.
    ///
    /// ```
    /// use springmass::Defect;
    /// assert_eq!(Defect::Spring { at: 3, k: 0.5 }.place(), "spring@3");
    /// ```
    pub fn place(&self) -> String {
        format!("{}@{}", self.kind(), self.at())
    }

    /// A set of defects as reports name it: `mass@8, mass@15`, or `no
    /// defect`.
    ///
    /// ```
    /// use springmass::Defect;
    /// assert_eq!(Defect::places(&[Defect::Mass { at: 8, m: 5.0 }]), "mass@8");
    /// assert_eq!(Defect::places(&[]), "no defect");
    /// ```
    pub fn places(defects: &[Defect]) -> String {
        if defects.is_empty() {
            return "no defect".into();
        }
        let d: Vec<String> = defects.iter().map(Defect::place).collect();
        d.join(", ")
    }

    /// The defect's value (mass, stiffness or damping).
    pub fn value(&self) -> f64 {
        match *self {
            Defect::Mass { m, .. } => m,
            Defect::Spring { k, .. } => k,
            Defect::Damper { d, .. } => d,
            Defect::Ground { g, .. } => g,
        }
    }

    /// Where the defect enters the equations of motion of the grounded
    /// model: its probe `u` and the power of `s` in `c(s)` (the table
    /// above). A chain with another damping model moves or extends it: read
    /// a defect of a chain through [`Chain::site`], which every kernel that
    /// is not specific to one kind does.
    pub fn site(&self) -> Site {
        match *self {
            Defect::Mass { at, .. } => Site::monomial(Probe::Point(at), 2),
            Defect::Damper { at, .. } => Site::monomial(Probe::Point(at), 1),
            Defect::Spring { at, .. } => Site::monomial(Probe::Diff(at), 0),
            Defect::Ground { at, .. } => Site::monomial(Probe::Point(at), 0),
        }
    }

    /// The value the chain without defects has where this defect sits
    /// (its `c(s) = (value - base) s^power`): the uniform value, or the
    /// [`Baseline`]'s value at the defect's site.
    pub fn base_value(&self, chain: &Chain) -> f64 {
        let at = self.at();
        match self {
            Defect::Mass { .. } => chain.base_mass(at),
            Defect::Spring { .. } => chain.base_spring(at),
            Defect::Damper { .. } => chain.base_damper(at),
            Defect::Ground { .. } => 0.0,
        }
    }

    /// The value's name in scene files (`m`, `k`, `d`) and its allowed
    /// range: `(name, value is allowed, range in words)`.
    fn value_rule(&self) -> (&'static str, bool, &'static str) {
        let v = self.value();
        match self {
            Defect::Mass { .. } => ("m", v > 0.0, "m > 0 and finite"),
            Defect::Spring { .. } => ("k", v > 0.0, "k > 0 and finite"),
            Defect::Damper { .. } => ("d", v >= 0.0, "d >= 0 and finite"),
            Defect::Ground { .. } => ("g", v >= 0.0, "g >= 0 and finite"),
        }
    }

    /// Whether a value of zero is allowed (a damper may vanish; a mass or a
    /// spring may not).
    pub fn may_vanish(&self) -> bool {
        self.with_value(0.0).value_rule().1
    }

    /// The same kind and position with value `value`.
    pub fn with_value(self, value: f64) -> Defect {
        Defect::of_kind(self.kind(), self.at(), value).unwrap_or(self)
    }

    /// The same kind and value at position `at`.
    pub fn with_at(self, at: usize) -> Defect {
        Defect::of_kind(self.kind(), at, self.value()).unwrap_or(self)
    }

    /// Parse the CLI form `kind:at:value`, for example `mass:8:5`,
    /// `spring:3:0.5`, `damper:4:0.3`.
    ///
    /// # Errors
    /// [`Error::Parse`] with the expected form.
    ///
    /// ```
    /// use springmass::Defect;
    /// assert_eq!(Defect::parse("mass:8:5").unwrap(), Defect::Mass { at: 8, m: 5.0 });
    /// assert!(Defect::parse("mass:8").is_err());
    /// ```
    pub fn parse(text: &str) -> Result<Defect> {
        let bad = |why: &str| {
            Error::parse(
                "defect",
                text,
                format!(
                    "{why}; expected kind:at:value with kind {}, e.g. mass:8:5",
                    Defect::KINDS.join("|")
                ),
            )
        };
        let parts: Vec<&str> = text.trim().split(':').collect();
        if parts.len() != 3 {
            return Err(bad("need three fields"));
        }
        let at: usize = parts[1]
            .trim()
            .parse()
            .map_err(|_| bad("position is not a non-negative integer"))?;
        let v: f64 = parts[2]
            .trim()
            .parse()
            .map_err(|_| bad("value is not a number"))?;
        let name = parts[0].trim().to_ascii_lowercase();
        let name = match name.as_str() {
            "m" => "mass",
            "k" => "spring",
            "d" => "damper",
            other => other,
        };
        Defect::of_kind(name, at, v).ok_or_else(|| bad("unknown kind"))
    }
}

impl std::fmt::Display for Defect {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}:{}:{}", self.kind(), self.at(), self.value())
    }
}

/// A validated chain: uniform parameters plus defects.
///
/// Construct with [`Chain::new`] (then the `with_*` builders) or
/// [`Chain::paper`]; every constructor validates, so a `Chain` in hand is
/// always physical.
///
/// ```
/// use springmass::{Chain, Defect};
/// let chain = Chain::paper(20)?
///     .with_defect(Defect::Mass { at: 8, m: 5.0 })?
///     .with_defect(Defect::Mass { at: 15, m: 2.0 })?;
/// assert_eq!(chain.n(), 20);
/// assert_eq!(chain.masses()[7], 5.0);
/// # Ok::<(), springmass::Error>(())
/// ```
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Chain {
    n: usize,
    k: f64,
    d: f64,
    gamma: f64,
    mass: f64,
    defects: Vec<Defect>,
    /// Left end (default fixed).
    #[serde(default)]
    left: Boundary,
    /// Right end (default fixed).
    #[serde(default)]
    right: Boundary,
    /// Damping model (default grounded: the chain's `d`).
    #[serde(default, skip_serializing_if = "Damping::is_grounded")]
    damping: Damping,
    /// A measured profile the defects sit on (default none: uniform).
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        with = "baseline::serde_arc"
    )]
    baseline: Option<Arc<Baseline>>,
}

impl Chain {
    /// A uniform chain of `n` unit masses with `k = 1`, `d = 0`, `gamma = 1`.
    ///
    /// # Errors
    /// `n` outside `1..=MAX_N`.
    pub fn new(n: usize) -> Result<Chain> {
        if n == 0 || n > MAX_N {
            return Err(Error::invalid("n", n, format!("1 <= n <= {MAX_N}")));
        }
        Ok(Chain {
            n,
            k: 1.0,
            d: 0.0,
            gamma: 1.0,
            mass: 1.0,
            defects: Vec::new(),
            left: Boundary::Fixed,
            right: Boundary::Fixed,
            damping: Damping::Grounded,
            baseline: None,
        })
    }

    /// The paper's chain: `n` unit masses, `k = 1`, `d = 0.1`, `gamma = 1`.
    pub fn paper(n: usize) -> Result<Chain> {
        Chain::new(n)?.with_d(0.1)
    }

    /// Uniform spring constant, `k > 0`.
    pub fn with_k(mut self, k: f64) -> Result<Chain> {
        self.k = check_f64("k", k, k > 0.0, "k > 0 and finite")?;
        Ok(self)
    }

    /// Uniform damping, `d >= 0`.
    pub fn with_d(mut self, d: f64) -> Result<Chain> {
        self.d = check_f64("d", d, d >= 0.0, "d >= 0 and finite")?;
        Ok(self)
    }

    /// Impulse on mass 1, finite.
    pub fn with_gamma(mut self, gamma: f64) -> Result<Chain> {
        self.gamma = check_f64("gamma", gamma, true, "finite")?;
        Ok(self)
    }

    /// Uniform mass, `> 0` (the paper uses 1).
    pub fn with_mass(mut self, mass: f64) -> Result<Chain> {
        self.mass = check_f64("mass", mass, mass > 0.0, "mass > 0 and finite")?;
        Ok(self)
    }

    /// The ends of the chain: `left` holds mass 1, `right` mass `n`.
    ///
    /// # Errors
    /// A spring defect on a wall spring that a free end removes (spring `0`
    /// with a free left end, spring `n` with a free right end), field
    /// `defects[i].at`; ends other than a [`Baseline`]'s (field `left` or
    /// `right`).
    ///
    /// ```
    /// use springmass::{Chain, chain::Boundary};
    /// // a shear building seen from its roof: mass 1 at the free end
    /// let c = Chain::paper(5)?.with_boundaries(Boundary::Free, Boundary::Fixed)?;
    /// assert_eq!(c.springs(), vec![0.0, 1.0, 1.0, 1.0, 1.0, 1.0]);
    /// # Ok::<(), springmass::Error>(())
    /// ```
    pub fn with_boundaries(mut self, left: Boundary, right: Boundary) -> Result<Chain> {
        if let Some(b) = &self.baseline {
            b.check_agrees(None, Some(left), Some(right))?;
        }
        self.left = left;
        self.right = right;
        for (idx, d) in self.defects.iter().enumerate() {
            if let Probe::Diff(at) = self.site(d).probe {
                self.check_spring_at(idx, at)?;
            }
        }
        Ok(self)
    }

    /// The damping model (see [`Damping`]); the chain's `d` stays a
    /// grounded damper on every mass in every model.
    ///
    /// # Errors
    /// A negative or non-finite parameter (`damping.c`, `damping.a`,
    /// `damping.b`); a damper defect whose position the model does not have
    /// (`defects[i].at`: spring indices `0..=n` in `between`).
    pub fn with_damping(mut self, damping: Damping) -> Result<Chain> {
        damping.check()?;
        self.damping = damping;
        let defects = std::mem::take(&mut self.defects);
        self.with_defects(defects)
    }

    /// The damping model.
    pub fn damping(&self) -> &Damping {
        &self.damping
    }

    /// Where `defect` enters this chain's equations of motion: the
    /// grounded site ([`Defect::site`]) moved or extended by the damping
    /// model. `between`: a damper defect sits on spring `at`
    /// (`u = e_at - e_at+1`). `rayleigh`: a mass defect has
    /// `p(s) = s^2 + a s`, a spring or ground spring defect `1 + b s`.
    pub fn site(&self, defect: &Defect) -> Site {
        let mut site = defect.site();
        match (self.tridiagonal_damping(), defect) {
            (Damping::Between { .. }, Defect::Damper { at, .. }) => {
                site.probe = Probe::Diff(*at);
            }
            (Damping::Rayleigh { a, .. }, Defect::Mass { .. }) => site.poly[1] = a,
            (Damping::Rayleigh { b, .. }, Defect::Spring { .. } | Defect::Ground { .. }) => {
                site.poly[1] = b
            }
            _ => {}
        }
        site
    }

    /// Left end (mass 1's side).
    pub fn left(&self) -> Boundary {
        self.left
    }
    /// Right end (mass `n`'s side).
    pub fn right(&self) -> Boundary {
        self.right
    }
    /// Refuse a chain with a free end where a method is derived for walls
    /// at both ends (the explicit locators, the mass-only Woodbury kernel).
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming `boundaries` and `what`.
    pub fn require_fixed_ends(&self, what: &str) -> Result<()> {
        if self.is_fixed_fixed() {
            Ok(())
        } else {
            Err(Error::invalid(
                "boundaries",
                format!("left = {:?}, right = {:?}", self.left, self.right),
                format!("fixed at both ends for {what}"),
            ))
        }
    }
    /// Refuse a chain whose damping model is not grounded where a kernel
    /// is derived for grounded dampers only (the mass-only Woodbury
    /// kernel, the greedy search's rank-one scores, the sparse screen).
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming `damping` and `what`.
    pub fn require_grounded(&self, what: &str) -> Result<()> {
        if self.damping.is_grounded() {
            Ok(())
        } else {
            Err(Error::invalid(
                "damping",
                self.damping.name(),
                format!("grounded for {what}"),
            ))
        }
    }
    /// Both ends fixed (the paper's setup).
    pub fn is_fixed_fixed(&self) -> bool {
        self.left == Boundary::Fixed && self.right == Boundary::Fixed
    }
    /// Both ends free: a rigid-body mode, a pole at `s = 0`.
    pub fn is_free_free(&self) -> bool {
        self.left == Boundary::Free && self.right == Boundary::Free
    }
    /// The range of spring indices that exist: `lo..=hi` (`0..=n` with both
    /// ends fixed; `1` and `n - 1` at free ends). Empty (`lo > hi`) for a
    /// single mass with both ends free.
    pub fn spring_range(&self) -> (usize, usize) {
        let lo = usize::from(self.left.is_free());
        let hi = if self.right.is_free() {
            self.n.wrapping_sub(1)
        } else {
            self.n
        };
        (lo, hi)
    }

    fn check_spring_at(&self, idx: usize, at: usize) -> Result<()> {
        let (lo, hi) = self.spring_range();
        let field = format!("defects[{idx}].at");
        if self.n == 1 && self.is_free_free() {
            return Err(Error::invalid(
                field,
                at,
                "no spring exists: a single mass with both ends free",
            ));
        }
        if at < lo || at > hi {
            let why = match (
                self.left.is_free() && at == 0,
                self.right.is_free() && at == self.n,
            ) {
                (true, _) => " (the left end is free: spring 0 does not exist)",
                (_, true) => " (the right end is free: spring n does not exist)",
                _ => "",
            };
            return Err(Error::invalid(
                field,
                at,
                format!("{lo} <= spring index <= {hi}{why}"),
            ));
        }
        Ok(())
    }

    /// Add one defect, validated against `n`, the boundaries and the defects
    /// already present.
    ///
    /// # Errors
    /// Position out of range (a spring index that a free end removes
    /// included), value out of range, or a second defect of the same kind at
    /// the same place.
    pub fn with_defect(mut self, defect: Defect) -> Result<Chain> {
        let idx = self.defects.len();
        let n = self.n;
        // a valid defect at a mass is checked without formatting the field
        // names (the fits rebuild chains at every evaluation)
        let (name, ok, range) = defect.value_rule();
        let site = self.site(&defect);
        let plain = matches!(site.probe, Probe::Point(at) if (1..=n).contains(&at))
            && ok
            && defect.value().is_finite();
        if !plain {
            let field = format!("defects[{idx}].at");
            match site.probe {
                Probe::Point(at) => {
                    check_pos(&field, at, 1, n)?;
                }
                Probe::Diff(at) => {
                    check_pos(&field, at, 0, n)?;
                    self.check_spring_at(idx, at)?;
                }
            }
            check_f64(&format!("defects[{idx}].{name}"), defect.value(), ok, range)?;
        }
        if matches!(
            (defect, &self.damping),
            (Defect::Damper { .. }, Damping::Modal { .. })
        ) {
            return Err(Error::invalid(
                format!("defects[{idx}]"),
                defect,
                "a mass, spring or ground defect: the modal damping model has no dampers (its damping is a ratio per mode)",
            ));
        }
        if self
            .defects
            .iter()
            .any(|e| e.kind() == defect.kind() && e.at() == defect.at())
        {
            return Err(Error::DuplicateDefect {
                kind: defect.kind(),
                at: defect.at(),
            });
        }
        self.defects.push(defect);
        Ok(self)
    }

    /// Add several defects (see [`Chain::with_defect`]).
    pub fn with_defects(self, defects: impl IntoIterator<Item = Defect>) -> Result<Chain> {
        defects.into_iter().try_fold(self, |c, d| c.with_defect(d))
    }

    /// The same chain without its `i`-th defect (the others in order; the
    /// chain itself for an index out of range).
    pub fn without_defect(&self, i: usize) -> Chain {
        let mut c = self.clone();
        if i < c.defects.len() {
            c.defects.remove(i);
        }
        c
    }

    /// The same chain without defects.
    pub fn uniform(&self) -> Chain {
        Chain {
            defects: Vec::new(),
            ..self.clone()
        }
    }

    /// Number of masses.
    pub fn n(&self) -> usize {
        self.n
    }
    /// Uniform spring constant.
    pub fn k(&self) -> f64 {
        self.k
    }
    /// Uniform damping.
    pub fn d(&self) -> f64 {
        self.d
    }
    /// Impulse on mass 1.
    pub fn gamma(&self) -> f64 {
        self.gamma
    }
    /// Uniform mass.
    pub fn mass(&self) -> f64 {
        self.mass
    }
    /// The uniform chain's band `2 sqrt(k / mass)`: every undamped natural
    /// frequency of the uniform chain lies below it, whatever its ends.
    pub fn uniform_band(&self) -> f64 {
        2.0 * (self.k / self.mass).sqrt()
    }
    /// The defects, in the order given.
    pub fn defects(&self) -> &[Defect] {
        &self.defects
    }

    /// The diagonal of the matrix that multiplies `s^power` (`power` 2: the
    /// masses, 1: the dampers; 0: the stiffness that ties each mass to the
    /// ground beside its springs, zero in the uniform chain), 0-based,
    /// `base` where no defect sits. O(n) memory.
    fn point_values(&self, power: u32, base: Vec<f64>) -> Vec<f64> {
        let mut v = base;
        for d in &self.defects {
            let site = self.site(d);
            if let (Probe::Point(at), true) = (site.probe, site.power == power) {
                v[at - 1] = d.value();
            }
        }
        v
    }

    /// All `n` masses (0-based vector: `masses()[i-1] = m_i`). O(n) memory.
    pub fn masses(&self) -> Vec<f64> {
        let base = match &self.baseline {
            Some(b) => b.masses().to_vec(),
            None => vec![self.mass; self.n],
        };
        self.point_values(2, base)
    }

    /// The mass of mass `i` (1-based), O(number of defects); the base
    /// mass ([`Chain::base_mass`]) where no defect sits.
    pub fn mass_at(&self, i: usize) -> f64 {
        self.defects
            .iter()
            .find_map(|d| (d.site() == Site::monomial(Probe::Point(i), 2)).then(|| d.value()))
            .unwrap_or_else(|| self.base_mass(i))
    }

    /// All `n + 1` spring constants, `springs()[i]` joining mass `i` and `i+1`
    /// (`springs()[0]` and `springs()[n]` attach to the walls; `0` at a free end).
    pub fn springs(&self) -> Vec<f64> {
        let mut v = match &self.baseline {
            Some(b) => b.springs().to_vec(),
            None => vec![self.k; self.n + 1],
        };
        for d in &self.defects {
            let site = d.site();
            if let (Probe::Diff(at), 0) = (site.probe, site.power) {
                v[at] = d.value();
            }
        }
        if self.left.is_free() {
            v[0] = 0.0;
        }
        if self.right.is_free() {
            v[self.n] = 0.0;
        }
        v
    }

    /// All `n` dampers to the ground (0-based vector): the chain's `d`
    /// and the damper defects at masses; in the Rayleigh model also
    /// `a m_i + b g_i`, the part of `a M + b K` on the diagonal beside the
    /// springs (so that `D = diag(dampers) + Lap(spring_dampers)`).
    pub fn dampers(&self) -> Vec<f64> {
        let base = match (&self.damping, self.baseline_dampers()) {
            (Damping::Between { .. }, _) | (_, None) => vec![self.d; self.n],
            (_, Some(b)) => b[..self.n].to_vec(),
        };
        let mut d = self.point_values(1, base);
        if let Damping::Rayleigh { a, b } = self.tridiagonal_damping() {
            let (m, g) = (self.masses(), self.grounds());
            for i in 0..self.n {
                d[i] += a * m[i] + b * g[i];
            }
        }
        d
    }

    /// All `n + 1` dampers parallel to the springs (0-based like
    /// [`Chain::springs`]; zero at a free end and in the grounded model):
    /// `c` and the damper defects (`between`), `b k_i` (`rayleigh`).
    pub fn spring_dampers(&self) -> Vec<f64> {
        let mut v = match self.tridiagonal_damping() {
            Damping::Grounded | Damping::Modal { .. } => return vec![0.0; self.n + 1],
            Damping::Between { c } => {
                let mut v = match self.baseline_dampers() {
                    Some(b) => b.to_vec(),
                    None => vec![c; self.n + 1],
                };
                for d in &self.defects {
                    if let (Defect::Damper { at, d }, Probe::Diff(_)) = (d, self.site(d).probe) {
                        v[*at] = *d;
                    }
                }
                v
            }
            Damping::Rayleigh { b, .. } => self.springs().iter().map(|k| b * k).collect(),
        };
        if self.left.is_free() {
            v[0] = 0.0;
        }
        if self.right.is_free() {
            v[self.n] = 0.0;
        }
        v
    }

    /// The uniform part's damping as `(diagonal per mass, parallel to every
    /// spring)`: `(d, 0)` grounded, `(d, c)` between, `(d + a mass, b k)`
    /// Rayleigh. The uniform dynamic stiffness is
    /// `(mass s^2 + d_u s) I + (k + c_u s) Lap`.
    pub fn uniform_damping(&self) -> (f64, f64) {
        match self.tridiagonal_damping() {
            // (never modal: its stand-in is Rayleigh)
            Damping::Grounded | Damping::Modal { .. } => (self.d, 0.0),
            Damping::Between { c } => (self.d, c),
            Damping::Rayleigh { a, b } => (self.d + a * self.mass, b * self.k),
        }
    }

    /// All `n` ground stiffnesses: the stiffness that holds mass `i` to the
    /// ground besides its two springs (0-based; zero in the uniform chain).
    pub fn grounds(&self) -> Vec<f64> {
        self.point_values(0, vec![0.0; self.n])
    }

    /// The coefficients of the equations of motion, the one place the
    /// matrices are assembled from the defects' [`Site`]s: `M = diag(m)`,
    /// `D = diag(d) + ` the spring-parallel dampers' Laplacian,
    /// `K = diag(g) + ` the springs' Laplacian.
    pub fn coefficients(&self) -> Coefficients {
        Coefficients {
            m: self.masses(),
            d: self.dampers(),
            g: self.grounds(),
            k: self.springs(),
            c: self.spring_dampers(),
        }
    }

    /// Check a 1-based observed mass index.
    pub fn check_observe(&self, i: usize) -> Result<usize> {
        check_pos("observe", i, 1, self.n)
    }
}

fn check_pos(field: &str, at: usize, lo: usize, hi: usize) -> Result<usize> {
    if at < lo || at > hi {
        Err(Error::invalid(
            field,
            at,
            format!("{lo} <= {field} <= {hi}"),
        ))
    } else {
        Ok(at)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn validation_names_fields() {
        assert!(
            matches!(Chain::new(0), Err(Error::InvalidParameter { field, .. }) if field == "n")
        );
        let c = Chain::paper(5).unwrap();
        for (bad, field) in [
            (Defect::Mass { at: 0, m: 1.0 }, "defects[0].at"),
            (Defect::Mass { at: 6, m: 1.0 }, "defects[0].at"),
            (Defect::Mass { at: 2, m: 0.0 }, "defects[0].m"),
            (Defect::Mass { at: 2, m: f64::NAN }, "defects[0].m"),
            (Defect::Spring { at: 6, k: 1.0 }, "defects[0].at"),
            (Defect::Spring { at: 0, k: -1.0 }, "defects[0].k"),
            (Defect::Damper { at: 1, d: -0.1 }, "defects[0].d"),
        ] {
            match c.clone().with_defect(bad) {
                Err(Error::InvalidParameter { field: f, .. }) => assert_eq!(f, field),
                other => panic!("{bad:?} gave {other:?}"),
            }
        }
        assert!(c.clone().with_k(0.0).is_err());
        assert!(c.clone().with_d(-1.0).is_err());
        assert!(c.clone().with_d(f64::INFINITY).is_err());
        assert!(c.clone().with_gamma(f64::NAN).is_err());
        let c2 = c.with_defect(Defect::Mass { at: 2, m: 3.0 }).unwrap();
        assert!(matches!(
            c2.clone().with_defect(Defect::Mass { at: 2, m: 4.0 }),
            Err(Error::DuplicateDefect {
                kind: "mass",
                at: 2
            })
        ));
        // a damper at the same place is a different kind: allowed
        assert!(c2.with_defect(Defect::Damper { at: 2, d: 1.0 }).is_ok());
    }

    #[test]
    fn profiles() {
        let c =
            crate::scenes::paper_with(4, "mass:4:2 spring:0:3 spring:4:5 damper:1:0.7").unwrap();
        assert_eq!(c.masses(), vec![1.0, 1.0, 1.0, 2.0]);
        assert_eq!(c.springs(), vec![3.0, 1.0, 1.0, 1.0, 5.0]);
        assert_eq!(c.dampers(), vec![0.7, 0.1, 0.1, 0.1]);
    }

    #[test]
    fn boundaries_validate_wall_springs() {
        use Boundary::*;
        let c = Chain::paper(4).unwrap();
        let ff = c.clone().with_boundaries(Free, Fixed).unwrap();
        assert!(matches!(
            ff.clone().with_defect(Defect::Spring { at: 0, k: 2.0 }),
            Err(Error::InvalidParameter { field, .. }) if field == "defects[0].at"
        ));
        assert!(ff
            .clone()
            .with_defect(Defect::Spring { at: 4, k: 2.0 })
            .is_ok());
        let fr = c.clone().with_boundaries(Fixed, Free).unwrap();
        assert!(fr
            .clone()
            .with_defect(Defect::Spring { at: 4, k: 2.0 })
            .is_err());
        assert!(fr.with_defect(Defect::Spring { at: 0, k: 2.0 }).is_ok());
        // a wall-spring defect present before the end is freed
        let w = c.with_defect(Defect::Spring { at: 0, k: 2.0 }).unwrap();
        assert!(w.with_boundaries(Free, Fixed).is_err());
        let one = Chain::paper(1)
            .unwrap()
            .with_boundaries(Free, Free)
            .unwrap();
        assert_eq!(one.springs(), vec![0.0, 0.0]);
        assert!(one.with_defect(Defect::Spring { at: 0, k: 1.0 }).is_err());
        assert_eq!("FREE".parse::<Boundary>().unwrap(), Free);
        assert!("loose".parse::<Boundary>().is_err());
    }

    #[test]
    fn boundaries_default_in_toml_and_json() {
        let spec: ChainSpec = toml::from_str("n = 3").unwrap();
        assert_eq!((spec.left, spec.right), (Boundary::Fixed, Boundary::Fixed));
        let spec: ChainSpec = toml::from_str("n = 3\nleft = \"free\"").unwrap();
        let c = spec.build().unwrap();
        assert_eq!(c.left(), Boundary::Free);
        assert_eq!(ChainSpec::from(&c), spec);
        let json = r#"{"n":2,"k":1.0,"d":0.1,"gamma":1.0,"mass":1.0,"defects":[]}"#;
        let c: Chain = serde_json::from_str(json).unwrap();
        assert!(c.is_fixed_fixed());
        assert!(toml::from_str::<ChainSpec>("n = 3\nleft = \"loose\"").is_err());
    }

    #[test]
    fn units_scale_every_parameter() {
        let c = crate::scenes::paper_with(3, "mass:2:2 spring:3:0.5 damper:1:0.3")
            .unwrap()
            .with_boundaries(Boundary::Free, Boundary::Fixed)
            .unwrap();
        let si = c.to_si(&Units::new(10.0, 100.0, 1000.0).unwrap()).unwrap();
        assert_eq!(si.masses(), vec![10.0, 20.0, 10.0]);
        assert_eq!(si.springs(), vec![0.0, 100.0, 100.0, 50.0]);
        assert_eq!(si.dampers(), vec![300.0, 100.0, 100.0]);
        assert_eq!(si.left(), Boundary::Free);
        assert_eq!(c.to_si(&Units::default()).unwrap(), c);
        assert!(Units::new(0.0, 1.0, 1.0).is_err());
    }

    #[test]
    fn spec_roundtrip_toml() {
        let text = r#"
            n = 20
            defects = [ { kind = "mass", at = 8, m = 5.0 }, { kind = "spring", at = 0, k = 2.0 } ]
        "#;
        let spec: ChainSpec = toml::from_str(text).unwrap();
        let c = spec.build().unwrap();
        assert_eq!(c.d(), 0.1);
        assert_eq!(c.defects().len(), 2);
        assert!(toml::from_str::<ChainSpec>("n = 3\nkk = 1").is_err());
    }
}
