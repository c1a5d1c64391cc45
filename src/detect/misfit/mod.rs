//! L2 residuals between the model `X_1(s; defects)` and observed data, on a
//! fixed quadrature rule with tabled Green's functions.
//!
//! Two kinds, one interface ([`Misfit`]):
//!
//! * **real axis** (the paper's (4.18)): `r = int_0^{s_max} |X_1(s) - X_1*(s)|^2 ds`,
//!   `s_max = 300` by default;
//! * **Bromwich line** `s = sigma + i omega`:
//!   `r = int_0^{W} |X_1(sigma + i omega) - X_1*(sigma + i omega)|^2 d omega`
//!   (by Parseval this weights the time-domain misfit by `exp(-2 sigma t)`,
//!   which keeps the time-domain conditioning; docs/paper-notes.md).
//!
//! Both are `r = sum_q w_q |X_1(s_q) - d_q|^2` with data `d_q` sampled at the
//! same nodes as the model, so a rule's quadrature error never moves the zero
//! of `r` at the truth (data and model are consistent).
//!
//! For mass defects at positions `J` with changes `dm_l = m_l - mass`, per node
//! `c_l = dm_l s^2`, `z` solves `(I + G_JJ C) z = G_J1` and
//! `X_1 = gamma (G_11 - sum_l G_1 j_l c_l z_l)` (Woodbury), and
//! `dX_1/dm_l = -gamma s^2 z_l^2`. A [`SetTable`] gathers the Green's entries a
//! position set needs from the [`GreenTable`] once, so that a residual
//! evaluation is only the `k x k` solves and a weighted sum. One or two
//! defects on the real axis are *folded*: by Cramer's rule `X_1` at a node is
//! a ratio of bilinear forms in the mass changes,
//! `(N0 + N1 dm1 + N2 dm2 + N12 dm1 dm2) / (1 + D1 dm1 + D2 dm2 + D12 dm1 dm2)`,
//! whose seven coefficients (with `s^2` and `gamma` folded in) are computed
//! once per set, so that a residual is one division and a few multiply-adds
//! per node, over independent accumulators. Other sets (three or more
//! defects, the Bromwich line) take the general path
//! ([`Misfit::set_general`] forces it, the reference in tests).
//!
//! ```
//! use springmass::{Chain, Defect};
//! use springmass::detect::{data::exact::Data, misfit::{Misfit, MisfitSpec}};
//! let truth = Chain::paper(20)?.with_defects([
//!     Defect::Mass { at: 8, m: 5.0 }, Defect::Mass { at: 15, m: 2.0 }])?;
//! let misfit = Misfit::new(&truth.uniform(), &Data::exact(&truth), &MisfitSpec::default())?;
//! assert!(misfit.residual(&[(8, 5.0), (15, 2.0)]) < 1e-28);
//! assert!(misfit.residual(&[(8, 5.0), (16, 2.0)]) > 1e-15);
//! # Ok::<(), springmass::Error>(())
//! ```

pub mod laplace_sets;
pub mod quadrature;
pub mod time;
pub mod time_screen;

use crate::chain::Chain;
use crate::detect::data::exact::Data;
use crate::detect::misfit::quadrature::{Adaptive, AdaptiveOutput, GreenTable, Rule};
use crate::error::{Error, Result};
use crate::forward::{woodbury, Update};
use crate::green::{Green, Probe};
use num_complex::Complex64;
use serde::{Deserialize, Serialize};
use std::ops::{Add, Div, Mul, Neg, Sub};

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
#[serde(deny_unknown_fields)]
pub struct MisfitSpec {
    /// `real-axis`, `bromwich` or `time`.
    #[serde(default)]
    pub kind: MisfitKind,
    /// `gl-log` or `gl-uniform` (default by kind).
    #[serde(default)]
    pub rule: Option<RuleKind>,
    /// Number of panels (default 10 real axis, 40 Bromwich).
    #[serde(default)]
    pub panels: Option<usize>,
    /// Gauss points per panel (default 8).
    #[serde(default)]
    pub per_panel: Option<usize>,
    /// End of the first log-graded panel (default 0.05).
    #[serde(default)]
    pub first: Option<f64>,
    /// Upper limit of the real-axis integral (default 300).
    #[serde(default = "default_s_max")]
    pub s_max: f64,
    /// Abscissa of the Bromwich line (default 0.1).
    #[serde(default = "default_sigma")]
    pub sigma: f64,
    /// Upper limit of `omega` on the Bromwich line (default 4).
    #[serde(default = "default_omega_max")]
    pub omega_max: f64,
}

fn default_s_max() -> f64 {
    300.0
}
fn default_sigma() -> f64 {
    0.1
}
fn default_omega_max() -> f64 {
    4.0
}

impl Default for MisfitSpec {
    fn default() -> Self {
        MisfitSpec {
            kind: MisfitKind::RealAxis,
            rule: None,
            panels: None,
            per_panel: None,
            first: None,
            s_max: default_s_max(),
            sigma: default_sigma(),
            omega_max: default_omega_max(),
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
        match self.kind {
            MisfitKind::RealAxis => {
                if !(self.s_max.is_finite() && self.s_max > 0.0) {
                    return Err(Error::invalid("misfit.s_max", self.s_max, "> 0 and finite"));
                }
                match self.rule.unwrap_or(RuleKind::GlLog) {
                    RuleKind::GlLog => Rule::gauss_legendre_log(
                        0.0,
                        self.s_max,
                        self.panels.unwrap_or(10),
                        per,
                        self.first.unwrap_or(0.05),
                    ),
                    RuleKind::GlUniform => Rule::gauss_legendre_uniform(
                        0.0,
                        self.s_max,
                        self.panels.unwrap_or(40),
                        per,
                    ),
                }
            }
            MisfitKind::Bromwich => {
                if !(self.sigma.is_finite() && self.sigma > 0.0) {
                    return Err(Error::invalid("misfit.sigma", self.sigma, "> 0 and finite"));
                }
                if !(self.omega_max.is_finite() && self.omega_max > 0.0) {
                    return Err(Error::invalid(
                        "misfit.omega_max",
                        self.omega_max,
                        "> 0 and finite",
                    ));
                }
                match self.rule.unwrap_or(RuleKind::GlUniform) {
                    RuleKind::GlUniform => Rule::gauss_legendre_uniform(
                        0.0,
                        self.omega_max,
                        self.panels.unwrap_or(40),
                        per,
                    ),
                    RuleKind::GlLog => Rule::gauss_legendre_log(
                        0.0,
                        self.omega_max,
                        self.panels.unwrap_or(10),
                        per,
                        self.first.unwrap_or(0.05),
                    ),
                }
            }
            MisfitKind::Time => Err(time_has_no_rule()),
        }
    }
}

fn time_has_no_rule() -> Error {
    Error::invalid(
        "misfit.kind",
        "time",
        "real-axis or bromwich here (the time misfit is fitted by detect::fit::general::fit_general)",
    )
}

/// Minimal number interface of the kernels (`f64` and [`Complex64`]).
pub trait Num:
    Copy
    + Send
    + Sync
    + std::fmt::Debug
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + 'static
{
    /// Embed a real.
    fn re(x: f64) -> Self;
    /// `|x|^2`.
    fn norm2(self) -> f64;
    /// `Re(conj(a) b)`.
    fn dot_re(a: Self, b: Self) -> f64;
}

impl Num for f64 {
    #[inline(always)]
    fn re(x: f64) -> Self {
        x
    }
    #[inline(always)]
    fn norm2(self) -> f64 {
        self * self
    }
    #[inline(always)]
    fn dot_re(a: Self, b: Self) -> f64 {
        a * b
    }
}

impl Num for Complex64 {
    #[inline(always)]
    fn re(x: f64) -> Self {
        Complex64::new(x, 0.0)
    }
    #[inline(always)]
    fn norm2(self) -> f64 {
        self.norm_sqr()
    }
    #[inline(always)]
    fn dot_re(a: Self, b: Self) -> f64 {
        a.re * b.re + a.im * b.im
    }
}

#[derive(Clone, Debug)]
enum Tab {
    Real {
        g: GreenTable<f64>,
        d: Vec<f64>,
        /// `G_1j` and `G_jj` at every node for the folded sets (when small
        /// enough, [`MAX_ROWS`]).
        rows: Option<Rows>,
    },
    Complex {
        g: GreenTable<Complex64>,
        d: Vec<Complex64>,
    },
}

/// A residual on a fixed rule: nodes, weights, tabled Green's function and
/// data, built once per study.
#[derive(Clone, Debug)]
pub struct Misfit {
    spec: MisfitSpec,
    rule: Rule,
    chain: Chain,
    data: Data,
    w: Vec<f64>,
    sigma: Vec<f64>,
    tab: Tab,
}

impl Misfit {
    /// Build the residual of the uniform chain `model` (its `n, k, d, gamma,
    /// mass`; its defects are ignored) against `data`.
    ///
    /// # Errors
    /// Bad `spec` (fields `misfit.*`); a chain too long to table.
    pub fn new(model: &Chain, data: &Data, spec: &MisfitSpec) -> Result<Misfit> {
        model.require_fixed_ends(
            "the mass-only Woodbury kernel of the paper's residual (the data-first fit handles free ends)",
        )?;
        let rule = spec.rule()?;
        let chain = model.uniform();
        let (tab, sigma) = match spec.kind {
            MisfitKind::RealAxis => {
                let g = GreenTable::new(&chain, &rule.nodes)?;
                let sm = data.sample(&rule.nodes)?;
                let rows = Rows::new(&g, &rule.weights);
                (
                    Tab::Real {
                        g,
                        d: sm.values,
                        rows,
                    },
                    sm.sigma,
                )
            }
            MisfitKind::Bromwich => {
                let s: Vec<Complex64> = rule
                    .nodes
                    .iter()
                    .map(|&om| Complex64::new(spec.sigma, om))
                    .collect();
                let g = GreenTable::new(&chain, &s)?;
                let sm = data.sample(&s)?;
                (Tab::Complex { g, d: sm.values }, sm.sigma)
            }
            MisfitKind::Time => return Err(time_has_no_rule()),
        };
        Ok(Misfit {
            spec: spec.clone(),
            w: rule.weights.clone(),
            rule,
            chain,
            data: data.clone(),
            sigma,
            tab,
        })
    }

    /// The chi-square of mass defects against Laplace values given at fixed
    /// nodes (`data` from [`Data::at_nodes`]): `sum_q |X_1(s_q) - d_q|^2 /
    /// sigma_q^2`, on the same tables and kernels as the paper's residual.
    /// The data-first fit takes it for mass defects when the unknowns allow
    /// ([`crate::detect::fit`]).
    ///
    /// # Errors
    /// `data` not given at nodes (field `data`); nodes mixing real and
    /// complex values are tabled as complex; as [`Misfit::new`].
    pub fn at_nodes(model: &Chain, data: &Data) -> Result<Misfit> {
        model.require_fixed_ends("the mass-only Woodbury kernel")?;
        let (s, values, sigma) = match data.source() {
            crate::detect::data::exact::Source::Values { s, values, sigma } => (s, values, sigma),
            _ => {
                return Err(Error::invalid(
                    "data",
                    "not values at nodes",
                    "Laplace values at given nodes (Data::at_nodes)",
                ))
            }
        };
        let chain = model.uniform();
        let real = s.iter().chain(values.iter()).all(|z| z.im == 0.0);
        let w: Vec<f64> = sigma.iter().map(|e| 1.0 / (e * e)).collect();
        let coord: Vec<f64> = s.iter().map(|z| if real { z.re } else { z.im }).collect();
        let (lo, hi) = coord
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        let rule = Rule {
            name: format!("{} given nodes", s.len()),
            nodes: coord,
            weights: w.clone(),
            a: lo,
            b: hi,
        };
        let tab = if real {
            let nodes: Vec<f64> = s.iter().map(|z| z.re).collect();
            let g = GreenTable::new(&chain, &nodes)?;
            let rows = Rows::new(&g, &w);
            Tab::Real {
                g,
                d: values.iter().map(|z| z.re).collect(),
                rows,
            }
        } else {
            Tab::Complex {
                g: GreenTable::new(&chain, s)?,
                d: values.clone(),
            }
        };
        Ok(Misfit {
            spec: MisfitSpec {
                kind: if real {
                    MisfitKind::RealAxis
                } else {
                    MisfitKind::Bromwich
                },
                ..MisfitSpec::default()
            },
            rule,
            chain,
            data: data.clone(),
            w,
            sigma: sigma.clone(),
            tab,
        })
    }

    /// The spec.
    pub fn spec(&self) -> &MisfitSpec {
        &self.spec
    }

    /// The rule (nodes in the integration variable).
    pub fn rule(&self) -> &Rule {
        &self.rule
    }

    /// Number of nodes.
    pub fn nodes(&self) -> usize {
        self.rule.len()
    }

    /// The uniform model chain.
    pub fn chain(&self) -> &Chain {
        &self.chain
    }

    /// The data.
    pub fn data(&self) -> &Data {
        &self.data
    }

    /// `sum_q w_q sigma_q^2`: the expected residual at the truth caused by
    /// the data's error (rounding and noise). Residual gaps below it are not
    /// resolved by these data.
    pub fn floor(&self) -> f64 {
        self.w.iter().zip(&self.sigma).map(|(w, s)| w * s * s).sum()
    }

    /// Gather the Green's entries of the position set `positions` (1-based,
    /// distinct, in `1..=n`; checked by debug asserts only). One or two
    /// defects on the real axis are folded (per node a ratio of bilinear forms
    /// in the mass changes, precomputed here); other sets keep the entries
    /// for the per-node `k x k` solves.
    pub fn set(&self, positions: &[usize]) -> SetTable {
        match &self.tab {
            Tab::Real { g, d, rows } if matches!(positions.len(), 1 | 2) => SetTable {
                body: Body::Folded(Folded::new(
                    g,
                    rows.as_ref(),
                    d,
                    &self.w,
                    positions,
                    self.chain.gamma(),
                )),
                obs: positions.iter().position(|&p| p == 1),
                gamma: self.chain.gamma(),
            },
            _ => self.set_general(positions),
        }
    }

    /// [`Misfit::set`] without the folded form: the general path (per node a
    /// pivoted `k x k` solve) for every set, the reference of the folded
    /// kernels in tests and benches.
    pub fn set_general(&self, positions: &[usize]) -> SetTable {
        let obs = positions.iter().position(|&p| p == 1);
        let gamma = self.chain.gamma();
        match &self.tab {
            Tab::Real { g, d, .. } => {
                let s2: Vec<f64> = g.s().iter().map(|s| s * s).collect();
                SetTable {
                    body: Body::Real(Gathered::new(g, &s2, d, &self.w, positions)),
                    obs,
                    gamma,
                }
            }
            Tab::Complex { g, d } => {
                let s2: Vec<Complex64> = g.s().iter().map(|s| s * s).collect();
                SetTable {
                    body: Body::Complex(Gathered::new(g, &s2, d, &self.w, positions)),
                    obs,
                    gamma,
                }
            }
        }
    }

    /// `r` for mass defects `(position, mass)` (positions distinct in `1..=n`).
    pub fn residual(&self, defects: &[(usize, f64)]) -> f64 {
        let pos: Vec<usize> = defects.iter().map(|d| d.0).collect();
        let dm: Vec<f64> = defects.iter().map(|d| d.1 - self.chain.mass()).collect();
        self.set(&pos).residual(&dm)
    }

    /// The same residual integrated by the adaptive reference against the
    /// noiseless data (the model evaluated afresh at every `s`).
    ///
    /// The integrand `|X - X*|^2` is known only to about `8 eps |X| |X - X*|`
    /// (each `X` to a few ulps), so its integral only to about
    /// `8 eps sqrt(r int |X*|^2)` (Cauchy-Schwarz); the absolute tolerance is
    /// raised to that floor when `adaptive.abs_tol` is below it (for the
    /// paper's System 3 runner-up, `r = 1.4e-13`, the floor is `6e-22`, a
    /// relative `4e-9`: no f64 quadrature of this integrand does better).
    ///
    /// # Errors
    /// Positions out of range; the adaptive rule not reaching its tolerance.
    pub fn reference(
        &self,
        defects: &[(usize, f64)],
        adaptive: &Adaptive,
    ) -> Result<AdaptiveOutput> {
        let c = &self.chain;
        for (i, &(at, m)) in defects.iter().enumerate() {
            if at == 0 || at > c.n() {
                return Err(Error::invalid(
                    format!("defects[{i}].at"),
                    at,
                    format!("1 <= at <= {}", c.n()),
                ));
            }
            if !(m.is_finite() && m > 0.0) {
                return Err(Error::invalid(
                    format!("defects[{i}].m"),
                    m,
                    "> 0 and finite",
                ));
            }
        }
        let x2: f64 = match &self.tab {
            Tab::Real { d, .. } => d.iter().zip(&self.w).map(|(d, w)| w * d * d).sum(),
            Tab::Complex { d, .. } => d.iter().zip(&self.w).map(|(d, w)| w * d.norm_sqr()).sum(),
        };
        let floor = 8.0 * f64::EPSILON * (self.residual(defects).max(0.0) * x2).sqrt();
        let adaptive = &Adaptive {
            abs_tol: adaptive.abs_tol.max(floor),
            ..adaptive.clone()
        };
        let updates: Vec<Update> = defects
            .iter()
            .map(|&(at, m)| Update {
                probe: Probe::Point(at),
                dm: m - c.mass(),
                dd: 0.0,
                dk: 0.0,
            })
            .collect();
        match self.spec.kind {
            MisfitKind::RealAxis => {
                let f = |s: f64| {
                    let g = Green::new(c.n(), c.k(), c.mass(), c.d(), s);
                    let x = woodbury(&g, &s, &updates, c.gamma(), 1);
                    let d = self.data.value(s).unwrap_or(f64::NAN);
                    (x - d) * (x - d)
                };
                adaptive.integrate(f, 0.0, self.spec.s_max)
            }
            MisfitKind::Bromwich => {
                let f = |om: f64| {
                    let s = Complex64::new(self.spec.sigma, om);
                    let g = Green::new(c.n(), c.k(), c.mass(), c.d(), s);
                    let x = woodbury(&g, &s, &updates, c.gamma(), 1);
                    let d = self.data.value(s).unwrap_or(Complex64::new(f64::NAN, 0.0));
                    (x - d).norm_sqr()
                };
                adaptive.integrate(f, 0.0, self.spec.omega_max)
            }
            MisfitKind::Time => Err(time_has_no_rule()),
        }
    }
}

/// Structure-of-arrays Green's entries of one position set at every node,
/// padded to a multiple of 4 nodes (padding has weight 0).
#[derive(Clone, Debug)]
struct Gathered<T> {
    k: usize,
    np: usize,
    w: Vec<f64>,
    s2: Vec<T>,
    d: Vec<T>,
    g11: Vec<T>,
    /// `g1[l * np + q] = G_{1 j_l}(s_q)`
    g1: Vec<T>,
    /// `gjj[(l * k + m) * np + q] = G_{j_l j_m}(s_q)`
    gjj: Vec<T>,
}

impl<T: Num + crate::scalar::Scalar> Gathered<T> {
    fn new(g: &GreenTable<T>, s2: &[T], d: &[T], w: &[f64], pos: &[usize]) -> Gathered<T> {
        let nq = g.len();
        let np = nq.div_ceil(4) * 4;
        let k = pos.len();
        let pad = |v: &mut Vec<T>, z: T| v.resize(np, z);
        let mut ww = w.to_vec();
        ww.resize(np, 0.0);
        let mut ss = s2.to_vec();
        pad(&mut ss, T::re(0.0));
        let mut dd = d.to_vec();
        pad(&mut dd, T::re(0.0));
        let mut g11: Vec<T> = (0..nq).map(|q| g.entry(q, 1, 1)).collect();
        pad(&mut g11, T::re(0.0));
        let mut g1 = Vec::with_capacity(k * np);
        for &j in pos {
            g1.extend((0..nq).map(|q| g.entry(q, 1, j)));
            g1.resize(g1.len() + np - nq, T::re(0.0));
        }
        let mut gjj = Vec::with_capacity(k * k * np);
        for &a in pos {
            for &b in pos {
                gjj.extend((0..nq).map(|q| g.entry(q, a, b)));
                gjj.resize(gjj.len() + np - nq, T::re(0.0));
            }
        }
        Gathered {
            k,
            np,
            w: ww,
            s2: ss,
            d: dd,
            g11,
            g1,
            gjj,
        }
    }
}

impl<T: Num> Gathered<T> {
    /// Any `k`: per node a pivoted `k x k` solve. Returns `r`, and when
    /// `jac` is given accumulates the Gauss-Newton gradient `sum w Re(conj(J) e)`
    /// and matrix `sum w Re(conj(J_l) J_m)` in `dm`.
    fn eval_general(
        &self,
        dm: &[f64],
        gamma: f64,
        obs: Option<usize>,
        mut jac: Option<(&mut [f64], &mut [f64])>,
    ) -> f64 {
        let k = self.k;
        let np = self.np;
        let mut a = vec![T::re(0.0); k * k];
        let mut z = vec![T::re(0.0); k];
        let mut c = vec![T::re(0.0); k];
        let mut jv = vec![T::re(0.0); k];
        if let Some((g, h)) = jac.as_mut() {
            g.iter_mut().for_each(|x| *x = 0.0);
            h.iter_mut().for_each(|x| *x = 0.0);
        }
        let mut r = 0.0;
        for q in 0..np {
            let w = self.w[q];
            if w == 0.0 {
                continue;
            }
            let s2 = self.s2[q];
            for l in 0..k {
                c[l] = s2 * T::re(dm[l]);
            }
            for l in 0..k {
                for m in 0..k {
                    let v = self.gjj[(l * k + m) * np + q] * c[m];
                    a[l * k + m] = if l == m { v + T::re(1.0) } else { v };
                }
                z[l] = self.g1[l * np + q];
            }
            if !small_solve(&mut a, &mut z, k) {
                return f64::MAX;
            }
            let x = match obs {
                Some(l) => z[l] * T::re(gamma),
                None => {
                    let mut corr = T::re(0.0);
                    for l in 0..k {
                        corr = corr + self.g1[l * np + q] * c[l] * z[l];
                    }
                    (self.g11[q] - corr) * T::re(gamma)
                }
            };
            let e = x - self.d[q];
            r += w * e.norm2();
            if let Some((g, h)) = jac.as_mut() {
                for l in 0..k {
                    jv[l] = -(s2 * z[l] * z[l] * T::re(gamma));
                }
                for l in 0..k {
                    g[l] += w * T::dot_re(jv[l], e);
                    for m in 0..k {
                        h[l * k + m] += w * T::dot_re(jv[l], jv[m]);
                    }
                }
            }
        }
        if r.is_finite() {
            r
        } else {
            f64::MAX
        }
    }
}

/// Lanes of the folded kernels (independent accumulators); [`Folded`] pads
/// its nodes to a multiple of it with weight 0.
const LANES: usize = 8;

/// Coefficient rows of [`Folded`]: numerator `N0 N1 N2 N12`, denominator
/// `D1 D2 D12`, the Jacobian factors `A0 A2` (of `z_1`) and `B0 B1` (of
/// `z_2`), and the datum.
const N0: usize = 0;
const N1: usize = 1;
const N2: usize = 2;
const N12: usize = 3;
const D1: usize = 4;
const D2: usize = 5;
const D12: usize = 6;
const A0: usize = 7;
const A2: usize = 8;
const B0: usize = 9;
const B1: usize = 10;
const DATA: usize = 11;
const ROWS: usize = 12;

/// Largest `n * nodes` for which [`Misfit::new`] tables `G_1j` and `G_jj`
/// at every node (two arrays of that many values, 16 MB at the limit):
/// gathering a folded set then reads them instead of forming them from the
/// Green's table.
const MAX_ROWS: usize = 1 << 20;

/// `G_1j(s_q)` and `G_jj(s_q)`, `[(j - 1) * nodes + q]`, and the roots
/// `(sqrt(w_q), w_q^(1/4))` of the weights.
#[derive(Clone, Debug)]
struct Rows {
    g1: Vec<f64>,
    gd: Vec<f64>,
    roots: Vec<(f64, f64)>,
}

impl Rows {
    fn new(g: &GreenTable<f64>, w: &[f64]) -> Option<Rows> {
        let (n, nq) = (g.n(), g.len());
        if n.saturating_mul(nq) > MAX_ROWS {
            return None;
        }
        let roots = w.iter().map(|w| (w.sqrt(), w.sqrt().sqrt())).collect();
        let mut g1 = Vec::with_capacity(n * nq);
        let mut gd = Vec::with_capacity(n * nq);
        for j in 1..=n {
            g1.extend((0..nq).map(|q| g.entry(q, 1, j)));
            gd.extend((0..nq).map(|q| g.entry(q, j, j)));
        }
        Some(Rows { g1, gd, roots })
    }
}

/// One or two mass defects on the real axis, folded: per node the Cramer
/// solution of the `2 x 2` capacitance system written as a ratio of bilinear
/// forms in the mass changes,
///
/// `X_1 = (N0 + N1 dm1 + N2 dm2 + N12 dm1 dm2) / (1 + D1 dm1 + D2 dm2 + D12 dm1 dm2)`,
///
/// with `s^2` and `gamma` folded into the coefficients, and
/// `s z_1 = (A0 + A2 dm2) / den`, `s z_2 = (B0 + B1 dm1) / den` for the
/// Jacobian `dX_1/dm_l = -gamma (s z_l)^2`. With `G` the Green's entries at
/// the node (`1` the observed mass, `a, b` the positions) and
/// `Delta = G_aa G_bb - G_ab^2`: `N0 = gamma G_11`,
/// `N1 = gamma s^2 (G_11 G_aa - G_1a^2)`, `N2` alike in `b`,
/// `N12 = gamma s^4 det G_{1ab}` (the `3 x 3` minor), `D1 = s^2 G_aa`,
/// `D2 = s^2 G_bb`, `D12 = s^4 Delta`, `A0 = s G_1a`,
/// `A2 = s^3 (G_1a G_bb - G_ab G_1b)`, `B0, B1` alike. When a position is
/// the observed mass 1 the terms that vanish identically (`N1, N12` for
/// `a = 1`) are set to zero rather than left to rounding. `k = 1` is the
/// same form with the `b` rows zero. The weights are folded in too: the
/// numerator and the datum carry `sqrt(w_q)`, `A` and `B` carry `w_q^(1/4)`,
/// so that `r = sum_q (X~_q - d~_q)^2` and the Gauss-Newton sums need no
/// weight.
#[derive(Clone, Debug)]
struct Folded {
    k: usize,
    np: usize,
    gamma: f64,
    /// `c[row * np + q]`, rows as the constants above.
    c: Vec<f64>,
}

impl Folded {
    fn new(
        g: &GreenTable<f64>,
        rows: Option<&Rows>,
        d: &[f64],
        w: &[f64],
        pos: &[usize],
        gamma: f64,
    ) -> Folded {
        debug_assert!(pos.len() == 1 || pos.len() == 2);
        let nq = g.len();
        let np = nq.div_ceil(LANES) * LANES;
        let k = pos.len();
        let a = pos[0];
        let b = pos.get(1).copied();
        let obs_a = a == 1;
        let obs_b = b == Some(1);
        // G_1j and G_jj per node: the tabled rows, else gathered from the
        // table; the b columns zero for one defect
        let gathered;
        let column = |j: usize| -> (&[f64], &[f64]) {
            let r = rows.expect("tabled rows");
            (&r.g1[(j - 1) * nq..j * nq], &r.gd[(j - 1) * nq..j * nq])
        };
        let zeros = vec![0.0; if b.is_none() { 2 * nq } else { 0 }];
        let ((g11, g1a, gaa), (g1b, gbb)) = match rows {
            Some(_) => {
                let (g11, _) = column(1);
                let (g1a, gaa) = column(a);
                let bb = match b {
                    Some(b) => column(b),
                    None => zeros.split_at(nq),
                };
                ((g11, g1a, gaa), bb)
            }
            None => {
                let col = |i: usize, j: usize| (0..nq).map(move |q| g.entry(q, i, j));
                let mut v: Vec<f64> = col(1, 1).collect();
                v.extend(col(1, a));
                v.extend(col(a, a));
                match b {
                    Some(b) => {
                        v.extend(col(1, b));
                        v.extend(col(b, b));
                    }
                    None => v.resize(5 * nq, 0.0),
                }
                gathered = v;
                let (x, y) = gathered.split_at(3 * nq);
                let (g11, x) = x.split_at(nq);
                let (g1a, gaa) = x.split_at(nq);
                ((g11, g1a, gaa), y.split_at(nq))
            }
        };
        let mut c = vec![0.0; ROWS * np];
        {
            let mut it = c.chunks_exact_mut(np).map(|r| &mut r[..nq]);
            let mut next = || it.next().expect("ROWS rows");
            let (n0, n1, n2, n12) = (next(), next(), next(), next());
            let (d1, d2, d12) = (next(), next(), next());
            let (a0, a2, b0, b1) = (next(), next(), next(), next());
            let data = next();
            let s = g.s();
            let (d, w) = (&d[..nq], &w[..nq]);
            for q in 0..nq {
                let s = s[q];
                let s2 = s * s;
                let (g11, g1a, gaa, g1b, gbb) = (g11[q], g1a[q], gaa[q], g1b[q], gbb[q]);
                let gab = match b {
                    Some(b) => g.entry(q, a, b),
                    None => 0.0,
                };
                let delta = gaa * gbb - gab * gab;
                let minor3 =
                    g11 * delta - g1a * g1a * gbb - g1b * g1b * gaa + 2.0 * g1a * g1b * gab;
                // sqrt(w) on X and the datum, w^(1/4) on s z_l
                let (sw, qw) = match rows {
                    Some(r) => r.roots[q],
                    None => (w[q].sqrt(), w[q].sqrt().sqrt()),
                };
                let gs2 = sw * gamma * s2;
                let qs = qw * s;
                // the terms that vanish identically when a position is the
                // observed mass stay zero
                n0[q] = sw * gamma * g11;
                if !obs_a {
                    n1[q] = gs2 * (g11 * gaa - g1a * g1a);
                }
                if !obs_b {
                    n2[q] = gs2 * (g11 * gbb - g1b * g1b);
                }
                if !(obs_a || obs_b) {
                    n12[q] = gs2 * s2 * minor3;
                }
                d1[q] = s2 * gaa;
                d2[q] = s2 * gbb;
                d12[q] = s2 * s2 * delta;
                a0[q] = qs * g1a;
                a2[q] = qs * s2 * (g1a * gbb - gab * g1b);
                b0[q] = qs * g1b;
                b1[q] = qs * s2 * (g1b * gaa - gab * g1a);
                data[q] = sw * d[q];
            }
        }
        Folded { k, np, gamma, c }
    }

    #[inline(always)]
    fn row(&self, r: usize) -> &[f64] {
        &self.c[r * self.np..(r + 1) * self.np]
    }

    /// `r`, eight independent accumulators (`dm2 = 0` for `k = 1`).
    #[inline]
    #[allow(clippy::needless_range_loop)] // lane loops: indexed form vectorises
    fn residual(&self, dm1: f64, dm2: f64) -> f64 {
        let dm12 = dm1 * dm2;
        let (n0, n1, n2, n12) = (self.row(N0), self.row(N1), self.row(N2), self.row(N12));
        let (d1, d2, d12) = (self.row(D1), self.row(D2), self.row(D12));
        let d = self.row(DATA);
        let mut acc = [0.0f64; LANES];
        for q0 in (0..self.np).step_by(LANES) {
            // fixed-size views: one bounds check per chunk, none in the lanes
            let v = |a: &[f64]| -> [f64; LANES] {
                a[q0..q0 + LANES].try_into().expect("padded to LANES")
            };
            let (n0, n1, n2, n12) = (v(n0), v(n1), v(n2), v(n12));
            let (d1, d2, d12, d) = (v(d1), v(d2), v(d12), v(d));
            for l in 0..LANES {
                let num = n0[l] + n1[l] * dm1 + n2[l] * dm2 + n12[l] * dm12;
                let den = 1.0 + d1[l] * dm1 + d2[l] * dm2 + d12[l] * dm12;
                let e = num / den - d[l];
                acc[l] += e * e;
            }
        }
        ((acc[0] + acc[1]) + (acc[2] + acc[3])) + ((acc[4] + acc[5]) + (acc[6] + acc[7]))
    }

    /// The mass changes of the linearised fit (as [`SetTable::linearized`]).
    #[allow(clippy::needless_range_loop)] // lane loops: indexed form vectorises
    fn linearized(&self) -> Option<[f64; 2]> {
        let (n0, n1, n2, n12) = (self.row(N0), self.row(N1), self.row(N2), self.row(N12));
        let (d1, d2, d12) = (self.row(D1), self.row(D2), self.row(D12));
        let d = self.row(DATA);
        // normal equations of a_q . x = b_q, x = (dm1, dm2, dm1 dm2): the
        // weighted numerator minus the weighted datum times the denominator
        // (the padding rows are zero and add nothing); per lane, then summed
        const L: usize = 4;
        let mut acc = [[0.0f64; L]; 9];
        for q0 in (0..self.np).step_by(L) {
            let v = |a: &[f64]| -> [f64; L] { a[q0..q0 + L].try_into().expect("padded") };
            let (n0, n1, n2, n12) = (v(n0), v(n1), v(n2), v(n12));
            let (d1, d2, d12, d) = (v(d1), v(d2), v(d12), v(d));
            for l in 0..L {
                let a0 = n1[l] - d[l] * d1[l];
                let a1 = n2[l] - d[l] * d2[l];
                let a2 = n12[l] - d[l] * d12[l];
                let b = d[l] - n0[l];
                acc[0][l] += a0 * a0;
                acc[1][l] += a0 * a1;
                acc[2][l] += a0 * a2;
                acc[3][l] += a1 * a1;
                acc[4][l] += a1 * a2;
                acc[5][l] += a2 * a2;
                acc[6][l] += a0 * b;
                acc[7][l] += a1 * b;
                acc[8][l] += a2 * b;
            }
        }
        let sum: [f64; 9] = std::array::from_fn(|i| {
            let a = acc[i];
            (a[0] + a[1]) + (a[2] + a[3])
        });
        let (m, r) = (&sum[..6], &sum[6..]);
        let x = if self.k == 1 {
            [r[0] / m[0], 0.0]
        } else {
            // scaled to a unit diagonal: the rows grow like s^2 and s^4
            let sc = [m[0].sqrt(), m[3].sqrt(), m[5].sqrt()];
            if !sc.iter().all(|v| *v > 0.0 && v.is_finite()) {
                return None;
            }
            let full = [m[0], m[1], m[2], m[1], m[3], m[4], m[2], m[4], m[5]];
            let mut a: [f64; 9] = std::array::from_fn(|ij| full[ij] / (sc[ij / 3] * sc[ij % 3]));
            let mut b: [f64; 3] = std::array::from_fn(|i| r[i] / sc[i]);
            if !small_solve(&mut a, &mut b, 3) {
                return None;
            }
            [b[0] / sc[0], b[1] / sc[1]]
        };
        x.iter().all(|v| v.is_finite()).then_some(x)
    }

    /// `r` and the Gauss-Newton pieces (as [`SetTable::gauss_newton`]).
    #[inline]
    #[allow(clippy::needless_range_loop)] // lane loops: indexed form vectorises
    fn gauss_newton(&self, dm1: f64, dm2: f64, grad: &mut [f64], hess: &mut [f64]) -> f64 {
        const L: usize = 4;
        let dm12 = dm1 * dm2;
        let (n0, n1, n2, n12) = (self.row(N0), self.row(N1), self.row(N2), self.row(N12));
        let (d1, d2, d12) = (self.row(D1), self.row(D2), self.row(D12));
        let (a0, a2, b0, b1) = (self.row(A0), self.row(A2), self.row(B0), self.row(B1));
        let d = self.row(DATA);
        // per lane: r, sum u1 e, sum u2 e, sum u1^2, sum u1 u2, sum u2^2 with
        // the weighted e = sqrt(w) (X - d) and u_l = sqrt(w) (s z_l)^2 = -sqrt(w) J_l / gamma
        let mut acc = [[0.0f64; L]; 6];
        for q0 in (0..self.np).step_by(L) {
            let v = |a: &[f64]| -> [f64; L] { a[q0..q0 + L].try_into().expect("padded") };
            let (n0, n1, n2, n12) = (v(n0), v(n1), v(n2), v(n12));
            let (d1, d2, d12, d) = (v(d1), v(d2), v(d12), v(d));
            let (a0, a2, b0, b1) = (v(a0), v(a2), v(b0), v(b1));
            for l in 0..L {
                let num = n0[l] + n1[l] * dm1 + n2[l] * dm2 + n12[l] * dm12;
                let den = 1.0 + d1[l] * dm1 + d2[l] * dm2 + d12[l] * dm12;
                let inv = 1.0 / den;
                let e = num * inv - d[l];
                let t1 = (a0[l] + a2[l] * dm2) * inv;
                let t2 = (b0[l] + b1[l] * dm1) * inv;
                let (u1, u2) = (t1 * t1, t2 * t2);
                acc[0][l] += e * e;
                acc[1][l] += u1 * e;
                acc[2][l] += u2 * e;
                acc[3][l] += u1 * u1;
                acc[4][l] += u1 * u2;
                acc[5][l] += u2 * u2;
            }
        }
        let sum = |a: [f64; L]| (a[0] + a[1]) + (a[2] + a[3]);
        let g = -self.gamma;
        let g2 = self.gamma * self.gamma;
        if self.k == 1 {
            grad[0] = g * sum(acc[1]);
            hess[0] = g2 * sum(acc[3]);
        } else {
            grad[0] = g * sum(acc[1]);
            grad[1] = g * sum(acc[2]);
            hess[0] = g2 * sum(acc[3]);
            hess[1] = g2 * sum(acc[4]);
            hess[2] = hess[1];
            hess[3] = g2 * sum(acc[5]);
        }
        sum(acc[0])
    }
}

/// Pivoted `k x k` solve for the per-node capacitance systems of
/// [`Gathered::eval_general`]: the same elimination as
/// [`crate::linalg::solve_in_place`] (same pivots, same result for finite
/// entries), kept separate because it is the inner loop of every residual
/// with `k >= 3` or on the Bromwich line: over [`Num`] (`Copy`, squared
/// modulus for the pivot search, no zero-multiplier branch) it is faster
/// than the shared `Scalar` version (`cargo bench --bench fit --
/// residual_general`: thread CPU time 2.83 us here against 3.26 us with
/// `solve_in_place`, +14%).
fn small_solve<T: Num>(a: &mut [T], b: &mut [T], k: usize) -> bool {
    for col in 0..k {
        let mut piv = col;
        let mut best = a[col * k + col].norm2();
        for r in col + 1..k {
            let m = a[r * k + col].norm2();
            if m > best {
                best = m;
                piv = r;
            }
        }
        if best == 0.0 || !best.is_finite() {
            return false;
        }
        if piv != col {
            for c in 0..k {
                a.swap(col * k + c, piv * k + c);
            }
            b.swap(col, piv);
        }
        let p = a[col * k + col];
        for r in col + 1..k {
            let f = a[r * k + col] / p;
            for c in col + 1..k {
                let v = a[col * k + c];
                a[r * k + c] = a[r * k + c] - f * v;
            }
            let bc = b[col];
            b[r] = b[r] - f * bc;
        }
    }
    for row in (0..k).rev() {
        let mut acc = b[row];
        for c in row + 1..k {
            acc = acc - a[row * k + c] * b[c];
        }
        b[row] = acc / a[row * k + row];
    }
    true
}

#[derive(Clone, Debug)]
enum Body {
    Folded(Folded),
    Real(Gathered<f64>),
    Complex(Gathered<Complex64>),
}

/// The Green's entries of one position set at every node of a [`Misfit`]:
/// evaluating the residual for given masses costs only the `k x k` solves
/// (one or two defects on the real axis: one ratio of bilinear forms per node).
#[derive(Clone, Debug)]
pub struct SetTable {
    body: Body,
    /// Slot whose position is the observed mass 1 (then `X_1 = gamma z_l`).
    obs: Option<usize>,
    gamma: f64,
}

impl SetTable {
    /// Number of defects in the set.
    pub fn k(&self) -> usize {
        match &self.body {
            Body::Folded(f) => f.k,
            Body::Real(g) => g.k,
            Body::Complex(g) => g.k,
        }
    }

    /// Whether the set is folded (one or two defects on the real axis, from
    /// [`Misfit::set`]) rather than on the general path.
    pub fn is_folded(&self) -> bool {
        matches!(self.body, Body::Folded(_))
    }

    /// `r` for mass changes `dm_l = m_l - mass`, one per position of the set.
    /// A singular node (a capacitance matrix that cannot be solved) or an
    /// overflow gives `f64::MAX`, never NaN.
    #[inline]
    pub fn residual(&self, dm: &[f64]) -> f64 {
        debug_assert_eq!(dm.len(), self.k());
        let r = match &self.body {
            Body::Folded(f) => f.residual(dm[0], if f.k == 2 { dm[1] } else { 0.0 }),
            Body::Real(g) => g.eval_general(dm, self.gamma, self.obs, None),
            Body::Complex(g) => g.eval_general(dm, self.gamma, self.obs, None),
        };
        if r.is_finite() {
            r
        } else {
            f64::MAX
        }
    }

    /// The mass changes of a folded set (one or two defects on the real
    /// axis) in closed form, a starting point for their fit: `X_1 = d`
    /// multiplied by the folded form's denominator is, per node, linear in
    /// `(dm1, dm2, dm1 dm2)`; the least-squares solution of these equations
    /// (weighted as the residual, the product a third free unknown) gives
    /// `(dm1, dm2)` (`dm2 = 0` for one defect), exact for noiseless data of
    /// the set's own model and near the residual's minimum for data close
    /// to it. Costs about one residual evaluation. `None` for a set on the
    /// general path or when the equations are singular.
    pub fn linearized(&self) -> Option<[f64; 2]> {
        match &self.body {
            Body::Folded(f) => f.linearized(),
            _ => None,
        }
    }

    /// `r` and the Gauss-Newton pieces in `dm`: `grad[l] = sum_q w_q Re(conj(J_ql) e_q)`
    /// (half the gradient of `r`) and `hess[l k + m] = sum_q w_q Re(conj(J_ql) J_qm)`,
    /// with `e_q = X_1(s_q) - d_q` and `J_ql = dX_1/dm_l = -gamma s_q^2 z_l^2`.
    /// `r = f64::MAX` as for [`SetTable::residual`] (the pieces are then
    /// meaningless).
    pub fn gauss_newton(&self, dm: &[f64], grad: &mut [f64], hess: &mut [f64]) -> f64 {
        debug_assert_eq!(dm.len(), self.k());
        let r = match &self.body {
            Body::Folded(f) => {
                let dm2 = if f.k == 2 { dm[1] } else { 0.0 };
                f.gauss_newton(dm[0], dm2, grad, hess)
            }
            Body::Real(g) => g.eval_general(dm, self.gamma, self.obs, Some((grad, hess))),
            Body::Complex(g) => g.eval_general(dm, self.gamma, self.obs, Some((grad, hess))),
        };
        if r.is_finite() {
            r
        } else {
            f64::MAX
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chain::Defect;
    use crate::forward::response;

    fn chain_with(n: usize, defs: &[(usize, f64)]) -> Chain {
        Chain::paper(n)
            .unwrap()
            .with_defects(defs.iter().map(|&(at, m)| Defect::Mass { at, m }))
            .unwrap()
    }

    #[test]
    fn kernels_agree_with_forward_model() {
        // residual against data = 0 gives sum w X^2: compare with the forward model
        let truth = chain_with(12, &[(4, 2.0)]);
        let spec = MisfitSpec::real_axis(6, 5);
        let mis = Misfit::new(&truth.uniform(), &Data::exact(&truth), &spec).unwrap();
        for defs in [
            vec![(1usize, 3.0)],
            vec![(5, 0.3)],
            vec![(2, 4.0), (9, 0.7)],
            vec![(1, 4.0), (9, 0.7)],
            vec![(9, 0.7), (1, 4.0)],
            vec![(3, 2.0), (7, 5.0), (12, 0.2)],
        ] {
            let model = chain_with(12, &defs);
            let direct: f64 = mis
                .rule()
                .nodes
                .iter()
                .zip(&mis.rule().weights)
                .map(|(&s, &w)| {
                    let e = response(&model, s, 1).unwrap() - response(&truth, s, 1).unwrap();
                    w * e * e
                })
                .sum();
            let pos: Vec<usize> = defs.iter().map(|d| d.0).collect();
            let dm: Vec<f64> = defs.iter().map(|d| d.1 - 1.0).collect();
            let set = mis.set(&pos);
            assert_eq!(set.is_folded(), pos.len() <= 2);
            let fast = set.residual(&dm);
            let gen = mis.set_general(&pos).residual(&dm);
            let (gn, _, _) = pieces(&set, &dm);
            for v in [fast, gen, gn, mis.residual(&defs)] {
                assert!(
                    (v - direct).abs() <= 1e-12 * direct,
                    "{defs:?}: {v} vs {direct}"
                );
            }
        }
    }

    /// `(r, grad, hess)` of a set at `dm` by [`SetTable::gauss_newton`].
    fn pieces(set: &SetTable, dm: &[f64]) -> (f64, Vec<f64>, Vec<f64>) {
        let k = dm.len();
        let (mut g, mut h) = (vec![0.0; k], vec![0.0; k * k]);
        let r = set.gauss_newton(dm, &mut g, &mut h);
        (r, g, h)
    }

    #[test]
    fn folded_equals_general_path() {
        use rand::{Rng, SeedableRng};
        use rand_chacha::ChaCha8Rng;
        let mut rng = ChaCha8Rng::seed_from_u64(13);
        // the paper's System 3 on the default rule, and a chain with another
        // gamma, damping and spring constant on a coarser rule
        let s3 = chain_with(20, &[(8, 5.0), (15, 2.0)]);
        let other = Chain::new(9)
            .and_then(|c| c.with_k(2.5))
            .and_then(|c| c.with_d(0.7))
            .and_then(|c| c.with_gamma(-1.7))
            .unwrap()
            .with_defects([
                Defect::Mass { at: 1, m: 3.0 },
                Defect::Mass { at: 6, m: 0.4 },
            ])
            .unwrap();
        let mut compared = 0;
        for (truth, spec) in [
            (s3, MisfitSpec::default()),
            (other, MisfitSpec::real_axis(6, 6)),
        ] {
            let n = truth.n();
            let mis = Misfit::new(&truth.uniform(), &Data::exact(&truth), &spec).unwrap();
            for trial in 0..400 {
                let k = 1 + trial % 2;
                let a = rng.random_range(1..=n);
                let pos = if k == 1 {
                    vec![a]
                } else {
                    let mut b = rng.random_range(1..=n);
                    while b == a {
                        b = rng.random_range(1..=n);
                    }
                    vec![a, b]
                };
                // masses log-uniform in [1e-2, 1e3] (below, the conditioning
                // ~ 1 / m of both paths takes more digits than 1e-12 leaves)
                let dm: Vec<f64> = (0..k)
                    .map(|_| 10f64.powf(rng.random_range(-2.0..3.0)) - 1.0)
                    .collect();
                let set = mis.set(&pos);
                let gen = mis.set_general(&pos);
                assert!(set.is_folded() && !gen.is_folded());
                let (rf, gf, hf) = pieces(&set, &dm);
                let (rg, gg, hg) = pieces(&gen, &dm);
                let tag = format!("{pos:?} {dm:?}");
                assert!((rf - rg).abs() <= 1e-12 * rg, "{tag}: r {rf} vs {rg}");
                // the same sum over other accumulators (and X by a reciprocal)
                assert!(
                    (set.residual(&dm) - rf).abs() <= 1e-12 * rf,
                    "{tag}: {} vs {rf} vs {rg}",
                    set.residual(&dm)
                );
                for l in 0..k {
                    // |grad_l| <= sqrt(r hess_ll) (Cauchy-Schwarz) bounds the
                    // cancellation of the gradient's sum
                    let scale = (rg * hg[l * k + l]).sqrt();
                    assert!(
                        (gf[l] - gg[l]).abs() <= 1e-12 * scale,
                        "{tag}: grad {l} {} {} {scale}",
                        gf[l],
                        gg[l]
                    );
                    for m in 0..k {
                        let scale = (hg[l * k + l] * hg[m * k + m]).sqrt();
                        let (x, y) = (hf[l * k + m], hg[l * k + m]);
                        assert!((x - y).abs() <= 1e-12 * scale, "{tag}: hess {l}{m}");
                    }
                }
                compared += 1;
            }
            // near and at the truth (the observed mass 1 among the positions
            // of the second chain)
            let defs: Vec<(usize, f64)> = truth
                .defects()
                .iter()
                .map(|d| match d {
                    Defect::Mass { at, m } => (*at, *m),
                    _ => unreachable!(),
                })
                .collect();
            let pos = [defs[0].0, defs[1].0];
            // there `r` is known only to about `eps sqrt(r x2)` (each `X` to a
            // few ulps, as the data): both paths within that of each other
            let x2: f64 = match &mis.tab {
                Tab::Real { d, .. } => d.iter().zip(&mis.w).map(|(d, w)| w * d * d).sum(),
                Tab::Complex { .. } => unreachable!(),
            };
            let ulps = 16.0 * f64::EPSILON;
            for rel in [0.0, 1e-9, 1e-6, 1e-3] {
                let dm = [defs[0].1 * (1.0 + rel) - 1.0, defs[1].1 * (1.0 - rel) - 1.0];
                let (rf, gf, hf) = pieces(&mis.set(&pos), &dm);
                let (rg, gg, hg) = pieces(&mis.set_general(&pos), &dm);
                let tol = 1e-12 * rg + ulps * (rg * x2).sqrt();
                assert!((rf - rg).abs() <= tol, "{rel}: {rf} vs {rg}");
                if rel == 0.0 {
                    assert!(rf <= 1e-28 && rg <= 1e-28, "{rf} {rg}");
                }
                for l in 0..2 {
                    let h = hg[3 * l];
                    let tol = 1e-12 * (rg * h).sqrt() + ulps * (h * x2).sqrt();
                    assert!((gf[l] - gg[l]).abs() <= tol, "{rel}: grad {l}");
                }
                for i in 0..4 {
                    assert!((hf[i] - hg[i]).abs() <= 1e-12 * (hg[0] * hg[3]).sqrt());
                }
            }
        }
        assert_eq!(compared, 800);
    }

    #[test]
    fn folded_never_nan_near_singular_capacitance() {
        let truth = chain_with(10, &[(3, 3.0), (7, 2.0)]);
        let mis = Misfit::new(
            &truth.uniform(),
            &Data::exact(&truth),
            &MisfitSpec::default(),
        )
        .unwrap();
        for pos in [vec![3], vec![1], vec![3, 7], vec![1, 7], vec![7, 1]] {
            let set = mis.set(&pos);
            let Body::Folded(f) = &set.body else {
                panic!("not folded")
            };
            // each node's denominator vanishes at dm = -1 / D1 (the other mass
            // unchanged): an infinite residual, reported as f64::MAX
            let mut singular = vec![-1.0, -1.0 - 1e-12, -2.0, -1e300, f64::INFINITY, f64::NAN];
            singular.extend((0..f.np).map(|q| -1.0 / f.c[D1 * f.np + q]));
            for dm1 in singular {
                let mut dm = vec![dm1; pos.len()];
                if pos.len() == 2 {
                    dm[1] = 0.0;
                }
                let r = set.residual(&dm);
                let (rg, _, _) = pieces(&set, &dm);
                assert!(!r.is_nan() && r >= 0.0, "{pos:?} {dm1}: {r}");
                assert!(!rg.is_nan() && rg >= 0.0, "{pos:?} {dm1}: {rg}");
                if dm1.is_nan() || dm1.is_infinite() {
                    assert_eq!(r, f64::MAX);
                }
            }
        }
    }

    #[test]
    fn linearized_start_is_exact_for_the_sets_own_model() {
        // noiseless data of the set's own model: the linearised equations
        // hold exactly, their solution is the truth (to rounding)
        for (defs, pos) in [
            (vec![(3, 2.5), (7, 0.4)], vec![3, 7]),
            (vec![(1, 4.0), (12, 1.5)], vec![1, 12]),
            (vec![(6, 0.3)], vec![6]),
        ] {
            let truth = chain_with(12, &defs);
            let mis = Misfit::new(
                &truth.uniform(),
                &Data::exact(&truth),
                &MisfitSpec::default(),
            )
            .unwrap();
            let x = mis.set(&pos).linearized().unwrap();
            for (l, &(_, m)) in defs.iter().enumerate() {
                assert!((x[l] - (m - 1.0)).abs() < 1e-6 * m, "{defs:?}: {x:?}");
            }
            if defs.len() == 1 {
                assert_eq!(x[1], 0.0);
            }
            // a wrong set: a finite start; the general path has none
            assert!(mis.set(&[2, 9]).linearized().is_some());
            assert!(mis.set(&[2, 5, 9]).linearized().is_none());
            assert!(mis.set_general(&pos).linearized().is_none());
        }
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        for kind in [MisfitKind::RealAxis, MisfitKind::Bromwich] {
            let truth = chain_with(10, &[(3, 3.0), (7, 2.0)]);
            let spec = MisfitSpec {
                kind,
                panels: Some(8),
                ..MisfitSpec::default()
            };
            let mis = Misfit::new(&truth.uniform(), &Data::exact(&truth), &spec).unwrap();
            let set = mis.set(&[3, 6]);
            let dm = [1.7, 0.4];
            let (mut g, mut h) = ([0.0; 2], [0.0; 4]);
            set.gauss_newton(&dm, &mut g, &mut h);
            for l in 0..2 {
                let hstep = 1e-6;
                let mut p = dm;
                p[l] += hstep;
                let mut m = dm;
                m[l] -= hstep;
                let fd = (set.residual(&p) - set.residual(&m)) / (2.0 * hstep);
                // d r / d m = 2 grad
                assert!(
                    (fd - 2.0 * g[l]).abs() <= 1e-6 * fd.abs(),
                    "{kind:?} {l}: {fd} vs {}",
                    2.0 * g[l]
                );
            }
            assert!(h[1] == h[2] && h[0] > 0.0 && h[0] * h[3] >= h[1] * h[1]);
        }
    }

    #[test]
    fn bromwich_matches_complex_forward() {
        let truth = chain_with(8, &[(2, 3.0), (6, 0.5)]);
        let spec = MisfitSpec {
            kind: MisfitKind::Bromwich,
            panels: Some(10),
            ..MisfitSpec::default()
        };
        let mis = Misfit::new(&truth.uniform(), &Data::exact(&truth), &spec).unwrap();
        let model = chain_with(8, &[(3, 3.0), (6, 0.5)]);
        let direct: f64 = mis
            .rule()
            .nodes
            .iter()
            .zip(&mis.rule().weights)
            .map(|(&om, &w)| {
                let s = Complex64::new(0.1, om);
                w * (response(&model, s, 1).unwrap() - response(&truth, s, 1).unwrap()).norm_sqr()
            })
            .sum();
        let r = mis.residual(&[(3, 3.0), (6, 0.5)]);
        assert!((r - direct).abs() <= 1e-12 * direct);
        assert!(mis.residual(&[(2, 3.0), (6, 0.5)]) < 1e-25);
    }

    #[test]
    fn never_nan() {
        let truth = chain_with(6, &[(2, 3.0)]);
        let mis = Misfit::new(
            &truth.uniform(),
            &Data::exact(&truth),
            &MisfitSpec::default(),
        )
        .unwrap();
        for dm in [-1.0, -0.999_999, 1e300, f64::INFINITY, f64::NAN] {
            let r = mis.set(&[2]).residual(&[dm]);
            assert!(!r.is_nan(), "{dm}");
            let r = mis.set(&[2, 4]).residual(&[dm, dm]);
            assert!(!r.is_nan(), "{dm}");
        }
    }
}
