//! Derivatives of the response `X_o(s)` with respect to every model parameter:
//! defect values (masses, springs, dampers), the uniform `d`, `k`, `mass`, and
//! the impulse `gamma`, at real or complex `s`.
//!
//! # Formula (reciprocity)
//!
//! `K(s) X = gamma e_1` with `K` symmetric, so for any parameter `theta` on
//! which `K` depends,
//!
//! `dX_o/dtheta = -gamma (G e_o)^T (dK/dtheta) (G e_1)`,  `G = K(s)^{-1}`,
//!
//! and `dX_o/dgamma = X_o / gamma`. For `o = 1` this is the classical
//! `dX_1/dtheta = -(1/gamma) X^T (dK/dtheta) X`. `dK/dtheta` is
//!
//! | parameter | `dK/dtheta` | `dX_1/dtheta` |
//! |---|---|---|
//! | mass `m_j` | `s^2 e_j e_j^T` | `-s^2 X_j^2 / gamma` |
//! | damper `d_j` | `s e_j e_j^T` | `-s X_j^2 / gamma` |
//! | spring `k_j` (joins `j`, `j+1`) | `(e_j - e_{j+1})(e_j - e_{j+1})^T` | `-(X_j - X_{j+1})^2 / gamma` |
//! | uniform `mass` | sum of the above over masses without a mass defect | |
//! | uniform `d`, `k` | likewise over dampers / springs without a defect | |
//!
//! ([`X_0 = X_{n+1} = 0`] at the walls.)
//!
//! # Cost
//!
//! [`gradient`] needs the whole columns `G e_1` and `G e_o`: O(n) per `s` by
//! [`green_column`] (elimination in excess-stiffness form from both ends, no
//! subtraction of nearly equal terms for real `s`). [`defect_gradient`]
//! (observable `X_1`, defect parameters only) needs `X` only at the defect
//! sites, which the cancellation-free [`crate::forward::transfer`] sweep gives
//! in O(k) each: O(k^2) per `s`, whatever `n`.
//!
//! ```
//! use springmass::{Chain, Defect, sensitivity::{gradient, Param}};
//! let chain = Chain::paper(20)?.with_defect(Defect::Mass { at: 8, m: 5.0 })?;
//! let params = Param::all(&chain);
//! let g = gradient(&chain, 0.7_f64, 1, &params)?;
//! // d X_1 / d m_8 = -s^2 X_8^2 / gamma < 0: a heavier mass lowers X_1
//! assert!(g.grad[0] < 0.0);
//! // central difference check
//! let h = 1e-5;
//! let up = springmass::forward::response(&params[0].set(&chain, 5.0 + h)?, 0.7, 1)?;
//! let dn = springmass::forward::response(&params[0].set(&chain, 5.0 - h)?, 0.7, 1)?;
//! assert!(((up - dn) / (2.0 * h) - g.grad[0]).abs() < 1e-7 * g.value);
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::chain::{Chain, Coefficients, Damping, Defect, Probe, Site};
use crate::error::{Error, Result};
use crate::forward::{check_s, Forward, Observable};
use crate::scalar::Scalar;

/// One model parameter of a chain.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Param {
    /// The value of `chain.defects()[i]` (its mass `m`, spring `k` or damper `d`).
    Defect(usize),
    /// Uniform damping `d` (every mass without a damper defect).
    D,
    /// Uniform spring constant `k` (every spring without a spring defect).
    K,
    /// Uniform mass (every mass without a mass defect).
    Mass,
    /// Impulse scale `gamma`.
    Gamma,
    /// `c` of the `between` damping model (every spring's damper without a
    /// damper defect).
    C,
    /// `a` of the `rayleigh` damping model (`C = a M + b K`).
    A,
    /// `b` of the `rayleigh` damping model.
    B,
    /// Ratio `index` of the `of` ratios of the `modal` damping model
    /// (`zeta` when `of` is 1: every mode's; else `zeta_{index+1}`, the
    /// ratio of mode `index + 1`, the last one also of every higher mode).
    Zeta {
        /// 0-based.
        index: usize,
        /// How many ratios the model has.
        of: usize,
    },
}

impl Param {
    /// Whether this is a damping parameter: the grounded `d` or a damping
    /// model's own.
    pub fn is_damping(&self) -> bool {
        matches!(
            self,
            Param::D | Param::C | Param::A | Param::B | Param::Zeta { .. }
        )
    }

    /// Every parameter of `chain`: its defects in order, then `D`, `K`, `Mass`, `Gamma`.
    pub fn all(chain: &Chain) -> Vec<Param> {
        let mut v: Vec<Param> = (0..chain.defects().len()).map(Param::Defect).collect();
        v.extend([Param::D, Param::K, Param::Mass, Param::Gamma]);
        v
    }

    /// The parameters of `chain`'s damping model (none for `grounded`).
    pub fn damping(chain: &Chain) -> Vec<Param> {
        Param::of_damping(chain.damping())
    }

    /// The parameters of the damping model `d`, in the order of
    /// [`Damping::params`] (none for `grounded`).
    pub fn of_damping(d: &Damping) -> Vec<Param> {
        match d {
            Damping::Grounded => vec![],
            Damping::Between { .. } => vec![Param::C],
            Damping::Rayleigh { .. } => vec![Param::A, Param::B],
            Damping::Modal { zeta } => (0..zeta.len())
                .map(|index| Param::Zeta {
                    index,
                    of: zeta.len(),
                })
                .collect(),
        }
    }

    /// The index of a damping parameter in [`Damping::params`] of
    /// `chain`'s model; `None` for another parameter or model.
    fn damping_index(&self, chain: &Chain) -> Option<usize> {
        match (*self, chain.damping()) {
            (Param::C, Damping::Between { .. }) | (Param::A, Damping::Rayleigh { .. }) => Some(0),
            (Param::B, Damping::Rayleigh { .. }) => Some(1),
            (Param::Zeta { index, of }, Damping::Modal { zeta }) if of == zeta.len() => Some(index),
            _ => None,
        }
    }

    /// The defect parameters of `chain`, in order.
    pub fn defects(chain: &Chain) -> Vec<Param> {
        (0..chain.defects().len()).map(Param::Defect).collect()
    }

    /// A short name: `mass@8`, `spring@3`, `damper@4`, `d`, `k`, `mass`, `gamma`.
    pub fn name(&self, chain: &Chain) -> String {
        match *self {
            Param::Defect(i) => match chain.defects().get(i) {
                Some(d) => d.place(),
                None => format!("defect[{i}]"),
            },
            Param::D => "d".into(),
            Param::K => "k".into(),
            Param::Mass => "mass".into(),
            Param::Gamma => "gamma".into(),
            Param::C => "c".into(),
            Param::A => "a".into(),
            Param::B => "b".into(),
            Param::Zeta { index, of } => Damping::ratio_name(index, of),
        }
    }

    /// The parameter's current value in `chain`.
    ///
    /// # Errors
    /// A defect index out of range (field `param`).
    pub fn get(&self, chain: &Chain) -> Result<f64> {
        Ok(match *self {
            Param::Defect(i) => self.defect(chain, i)?.value(),
            Param::D => chain.d(),
            Param::K => chain.k(),
            Param::Mass => chain.mass(),
            Param::Gamma => chain.gamma(),
            Param::C | Param::A | Param::B | Param::Zeta { .. } => {
                let i = self.damping_index(chain).ok_or_else(|| {
                    Error::invalid(
                        "param",
                        self.name(chain),
                        format!(
                            "a parameter of the {} damping model",
                            chain.damping().name()
                        ),
                    )
                })?;
                chain.damping().params()[i].1
            }
        })
    }

    fn defect<'a>(&self, chain: &'a Chain, i: usize) -> Result<&'a Defect> {
        chain.defects().get(i).ok_or_else(|| {
            Error::invalid(
                "param",
                format!("defect[{i}]"),
                format!("defect index < {}", chain.defects().len()),
            )
        })
    }

    /// A copy of `chain` with this parameter set to `value` (validated as the
    /// chain's builders validate it).
    ///
    /// # Errors
    /// The value is out of the parameter's range, or the defect index is out of range.
    pub fn set(&self, chain: &Chain, value: f64) -> Result<Chain> {
        let mut defects = chain.defects().to_vec();
        let (mut d, mut k, mut mass, mut gamma) =
            (chain.d(), chain.k(), chain.mass(), chain.gamma());
        let mut damping = chain.damping().clone();
        match *self {
            Param::Defect(i) => {
                let old = *self.defect(chain, i)?;
                defects[i] = old.with_value(value);
            }
            Param::D => d = value,
            Param::K => k = value,
            Param::Mass => mass = value,
            Param::Gamma => gamma = value,
            Param::C | Param::A | Param::B | Param::Zeta { .. } => {
                self.get(chain)?;
                let i = self.damping_index(chain).unwrap_or(0);
                let mut v: Vec<f64> = damping.params().iter().map(|p| p.1).collect();
                v[i] = value;
                damping = damping.with_params(&v);
            }
        }
        Chain::new(chain.n())?
            .with_d(d)?
            .with_k(k)?
            .with_mass(mass)?
            .with_gamma(gamma)?
            .with_boundaries(chain.left(), chain.right())?
            .with_damping(damping)?
            .with_defects(defects)
            .map(|c| c.with_baseline_from(chain))
    }
}

/// A response value with its derivatives, in the order of the parameters asked for.
#[derive(Clone, Debug, PartialEq)]
pub struct Gradient<T> {
    /// `X_o(s)`.
    pub value: T,
    /// `dX_o/dtheta` per parameter.
    pub grad: Vec<T>,
}

/// Column `o` of `G = K(s)^{-1}` (0-based vector, `G_{io}` at index `i - 1`), for
/// any mass, spring and damper profile. O(n).
///
/// Method: excess stiffnesses from the right, `E^R_i = l_i + kappa_i E^R_{i+1} / (E^R_{i+1} + kappa_i)`,
/// and from the left, `E^L_i = l_i + kappa_{i-1} E^L_{i-1} / (E^L_{i-1} + kappa_{i-1})`,
/// `l_i = m_i s^2 + d_i s + g_i` (walls: the tail is the wall spring); then
/// `G_oo = 1 / (E^R_o + E^L_o - l_o)`, and moving away from `o`,
/// `G_{i+1,o} = kappa_i G_io / (E^R_{i+1} + kappa_i)`, `G_{i-1,o} = kappa_{i-1} G_io / (E^L_{i-1} + kappa_{i-1})`.
/// For real `s >= 0` every term is positive.
///
/// # Errors
/// `s` invalid (as [`check_s`]), `o` outside `1..=n`, [`Error::Singular`] when an
/// elimination pivot vanishes (a pole of the response).
pub fn green_column<T: Scalar>(chain: &Chain, s: T, o: usize) -> Result<Vec<T>> {
    green_column_with(chain, &chain.coefficients(), s, o)
}

/// [`green_column`] from the chain's coefficients `c`
/// ([`Chain::coefficients`], taken once for many `s`). The excess
/// stiffnesses from the right are needed from mass `o` on, those from the
/// left up to it: only those are computed.
fn green_column_with<T: Scalar>(chain: &Chain, c: &Coefficients, s: T, o: usize) -> Result<Vec<T>> {
    check_s(&s)?;
    chain.check_observe(o)?;
    let n = chain.n();
    let (m, kap, dmp, gnd) = (&c.m, &c.k, &c.d, &c.g);
    if c.c.iter().any(|&v| v != 0.0) {
        return green_column_general(c, s, o);
    }
    let oi = o - 1;
    let s2 = s.clone() * s.clone();
    let local: Vec<T> = (0..n)
        .map(|i| s2.scale(m[i]) + s.scale(dmp[i]) + T::from_f64(gnd[i]))
        .collect();
    // tails: tr[i] = contribution from the right of mass i+1 (0-based i), tl likewise.
    let mut er: Vec<T> = vec![T::zero(); n];
    let mut tail_r: Vec<T> = vec![T::zero(); n];
    for i in (oi..n).rev() {
        let kr = kap[i + 1];
        let t = if i + 1 == n {
            T::from_f64(kr)
        } else {
            er[i + 1].clone().scale(kr) / (er[i + 1].clone() + T::from_f64(kr))
        };
        er[i] = local[i].clone() + t.clone();
        tail_r[i] = t;
    }
    let mut el: Vec<T> = vec![T::zero(); n];
    let mut tail_l: Vec<T> = vec![T::zero(); n];
    for i in 0..=oi {
        let kl = kap[i];
        let t = if i == 0 {
            T::from_f64(kl)
        } else {
            el[i - 1].clone().scale(kl) / (el[i - 1].clone() + T::from_f64(kl))
        };
        el[i] = local[i].clone() + t.clone();
        tail_l[i] = t;
    }
    let mut g = vec![T::zero(); n];
    g[oi] = T::one() / (local[oi].clone() + tail_r[oi].clone() + tail_l[oi].clone());
    for i in oi + 1..n {
        g[i] = g[i - 1].clone().scale(kap[i]) / (er[i].clone() + T::from_f64(kap[i]));
    }
    for i in (0..oi).rev() {
        g[i] = g[i + 1].clone().scale(kap[i + 1]) / (el[i].clone() + T::from_f64(kap[i + 1]));
    }
    if g.iter().all(|v| v.is_finite()) {
        Ok(g)
    } else {
        Err(Error::Singular {
            s: format!("{}", s.to_c64()),
        })
    }
}

/// [`green_column`] with spring-parallel dampers (`kappa_i = k_i + c_i s`):
/// the O(n) solver of the transposed column (`G` is symmetric).
fn green_column_general<T: Scalar>(c: &Coefficients, s: T, o: usize) -> Result<Vec<T>> {
    // G e_o = K^{-1} e_o: the impulse on mass o of the mirrored chain is not
    // at hand, so solve with a unit impulse on mass 1 when o = 1 and by the
    // symmetric identity G e_o = (row o of G) otherwise: one solve per mass
    // would be O(n^2); instead eliminate the general system directly.
    let n = c.m.len();
    let s2 = s.clone() * s.clone();
    let dd = c.d_diag();
    let kd = c.k_diag();
    let diag: Vec<T> = (0..n)
        .map(|i| s2.scale(c.m[i]) + s.scale(dd[i]) + T::from_f64(kd[i]))
        .collect();
    let off: Vec<T> = (1..n)
        .map(|i| -(T::from_f64(c.k[i]) + s.scale(c.c[i])))
        .collect();
    let mut b = vec![T::zero(); n];
    b[o - 1] = T::one();
    crate::forward::tridiag::solve_general(diag, off, b).ok_or_else(|| Error::Singular {
        s: format!("{}", s.to_c64()),
    })
}

/// `X_o(s)` and its derivatives with respect to `params`, by reciprocity
/// (module docs). O(n + number of parameters) per `s` (O(n) each for the
/// uniform parameters `D`, `K`, `Mass`).
///
/// # Errors
/// As [`green_column`]; a defect index out of range.
pub fn gradient<T: Scalar>(
    chain: &Chain,
    s: T,
    observe: usize,
    params: &[Param],
) -> Result<Gradient<T>> {
    Gradients::new(chain).at(s, observe, params)
}

/// [`gradient`] at many `s` of one chain: the chain's coefficients and its
/// defects' sites taken once (the same values as [`gradient`]).
pub struct Gradients<'a> {
    chain: &'a Chain,
    coeffs: Coefficients,
    sites: DefectSites,
}

impl<'a> Gradients<'a> {
    /// For `chain`.
    pub fn new(chain: &'a Chain) -> Gradients<'a> {
        Gradients {
            chain,
            coeffs: chain.coefficients(),
            sites: DefectSites::of(chain),
        }
    }

    /// [`gradient`] of the chain at `s`.
    ///
    /// # Errors
    /// As [`gradient`].
    pub fn at<T: Scalar>(&self, s: T, observe: usize, params: &[Param]) -> Result<Gradient<T>> {
        let chain = self.chain;
        let gamma = chain.gamma();
        let g1 = green_column_with(chain, &self.coeffs, s.clone(), 1)?;
        let go = if observe == 1 {
            None
        } else {
            Some(green_column_with(chain, &self.coeffs, s.clone(), observe)?)
        };
        let go_ref: &[T] = go.as_deref().unwrap_or(&g1);
        let value = g1[observe - 1].scale(gamma);
        let forms = Forms {
            go: go_ref,
            g1: &g1,
            n: chain.n(),
        };
        let mut grad = Vec::with_capacity(params.len());
        for p in params {
            // b = (G e_o)^T dK (G e_1); derivative = -gamma b
            match forms.form(chain, p, &self.sites, &s)? {
                Some(b) => grad.push(-b.scale(gamma)),
                None => grad.push(go_ref[0].clone()),
            }
        }
        Ok(Gradient { value, grad })
    }
}

/// The bilinear forms of [`gradient`] between the Green columns of the
/// observed mass (`go`) and of mass 1 (`g1`).
struct Forms<'a, T> {
    go: &'a [T],
    g1: &'a [T],
    n: usize,
}

/// The sites a defect takes over from the uniform parameters: masses,
/// dampers (1-based) and springs (0-based).
struct DefectSites {
    mass: Vec<bool>,
    damp: Vec<bool>,
    spring: Vec<bool>,
    /// spring-parallel dampers taken by a damper defect (`between`)
    spring_damp: Vec<bool>,
}

impl DefectSites {
    fn of(chain: &Chain) -> DefectSites {
        let n = chain.n();
        let mut out = DefectSites {
            mass: vec![false; n + 1],
            damp: vec![false; n + 1],
            spring: vec![false; n + 1],
            spring_damp: vec![false; n + 1],
        };
        for site in chain.defects().iter().map(|d| chain.site(d)) {
            match (site.probe, site.power) {
                (Probe::Point(at), 2) => out.mass[at] = true,
                (Probe::Point(at), 1) => out.damp[at] = true,
                (Probe::Diff(at), 0) => out.spring[at] = true,
                (Probe::Diff(at), 1) => out.spring_damp[at] = true,
                _ => {}
            }
        }
        out
    }
}

impl<T: Scalar> Forms<'_, T> {
    /// Entry `i` (1-based) of `v`, zero at the walls (`0` and `n + 1`).
    fn at(&self, v: &[T], i: usize) -> T {
        if i == 0 || i > self.n {
            T::zero()
        } else {
            v[i - 1].clone()
        }
    }

    /// The form of point `p` (1-based).
    fn point(&self, p: usize) -> T {
        self.at(self.go, p) * self.at(self.g1, p)
    }

    /// The form of spring `j` (joins `j`, `j + 1`; `0` and `n` the walls).
    fn spring(&self, j: usize) -> T {
        (self.at(self.go, j) - self.at(self.go, j + 1))
            * (self.at(self.g1, j) - self.at(self.g1, j + 1))
    }

    /// `b = (G e_o)^T dK (G e_1)` of parameter `p` (`None` for `Gamma`,
    /// whose derivative is `X_o / gamma`, not of this form).
    fn form(&self, chain: &Chain, p: &Param, sites: &DefectSites, s: &T) -> Result<Option<T>> {
        let s2 = s.clone() * s.clone();
        let b = match *p {
            Param::Defect(i) => {
                let site = chain.site(p.defect(chain, i)?);
                let u = match site.probe {
                    Probe::Point(at) => self.point(at),
                    Probe::Diff(at) => self.spring(at),
                };
                let s_pow = if site.is_monomial() {
                    match site.power {
                        0 => T::one(),
                        1 => s.clone(),
                        _ => s2,
                    }
                } else {
                    site.poly_at(s)
                };
                s_pow * u
            }
            Param::Mass => match chain.tridiagonal_damping() {
                Damping::Rayleigh { a, .. } => (s2 + s.scale(a)) * self.points(&sites.mass),
                _ => s2 * self.points(&sites.mass),
            },
            Param::D => s.clone() * self.points(&sites.damp),
            Param::K => match chain.tridiagonal_damping() {
                Damping::Rayleigh { b, .. } => {
                    (T::one() + s.scale(b)) * self.springs(chain, &sites.spring)
                }
                _ => self.springs(chain, &sites.spring),
            },
            Param::Gamma => return Ok(None),
            Param::C | Param::A | Param::B => {
                p.get(chain)?;
                match p {
                    Param::C => s.clone() * self.springs(chain, &sites.spring_damp),
                    Param::A => s.clone() * self.weighted_points(&chain.masses()),
                    _ => s.clone() * self.stiffness(chain),
                }
            }
            // the modal model's tridiagonal stand-in a M + b K is linear in
            // the ratios wherever the same terms are kept
            // ([`Damping::tridiagonal`]): d/dzeta_j = (da M + db K) s, da and
            // db the change of a and b over a step h of zeta_j, exact on
            // that linear piece
            Param::Zeta { index, .. } => {
                let z = p.get(chain)?;
                let omegas = chain.uniform_omegas();
                let h = 1e-3 * z.abs().max(1e-2);
                let stand_in = |v: f64| {
                    let mut zeta: Vec<f64> = chain.damping().params().iter().map(|q| q.1).collect();
                    zeta[index] = v;
                    Damping::Modal { zeta }.tridiagonal(&omegas)
                };
                let (Damping::Rayleigh { a: a0, b: b0 }, Damping::Rayleigh { a: a1, b: b1 }) =
                    (stand_in(z), stand_in(z + h))
                else {
                    return Ok(None);
                };
                let (a, b) = ((a1 - a0) / h, (b1 - b0) / h);
                s.clone()
                    * (self.weighted_points(&chain.masses()).scale(a)
                        + self.stiffness(chain).scale(b))
            }
        };
        Ok(Some(b))
    }

    /// `K`'s form: every spring and ground spring weighted by its
    /// stiffness (`d(b K)/db`).
    fn stiffness(&self, chain: &Chain) -> T {
        let k = chain.springs();
        let (lo, hi) = chain.spring_range();
        let mut acc = self.weighted_points(&chain.grounds());
        for (j, &kj) in k.iter().enumerate().take(hi + 1).skip(lo) {
            acc = acc + self.spring(j).scale(kj);
        }
        acc
    }

    /// The sum of the spring forms of the springs that exist (a free end
    /// has no wall spring) and are not `taken`.
    fn springs(&self, chain: &Chain, taken: &[bool]) -> T {
        let (lo, hi) = chain.spring_range();
        let mut acc = T::zero();
        for (j, _) in taken
            .iter()
            .enumerate()
            .filter(|(j, d)| !**d && *j >= lo && *j <= hi)
        {
            acc = acc + self.spring(j);
        }
        acc
    }

    /// `sum_i w_i` (point form of mass `i`), `w` 0-based.
    fn weighted_points(&self, w: &[f64]) -> T {
        let mut acc = T::zero();
        for (i, &wi) in w.iter().enumerate().filter(|(_, w)| **w != 0.0) {
            acc = acc + self.point(i + 1).scale(wi);
        }
        acc
    }

    /// The sum of the point forms of the masses not taken by a defect.
    fn points(&self, taken: &[bool]) -> T {
        let mut acc = T::zero();
        for (i, _) in taken.iter().enumerate().skip(1).filter(|(_, d)| !**d) {
            acc = acc + self.point(i);
        }
        acc
    }
}

/// `dK(s)/dtheta` of parameter `p` as weighted sites,
/// `sum_r w_r p_r(s) u_r u_r^T` (`(site, w_r)`; `K(s) = M s^2 + D s + K`):
/// the same terms [`gradient`]'s forms sum, for a kernel that needs them
/// one by one ([`crate::time::modal::Modes::sites_derivative`]). A defect
/// is its own site; `D`, `Mass`, `K` and `c` the sites of every element
/// no defect takes (with the Rayleigh model's terms), `a` and `b` every
/// mass and spring weighted by its value.
///
/// Under the `modal` damping model these are the changes of `M` and `K`
/// alone: its damping matrix follows the modes, whose change
/// [`crate::time::modal::Modes::modal_derivative`] takes from them.
///
/// `Ok(None)` for `gamma` (not a stiffness) and the modal model's ratios.
///
/// # Errors
/// A defect index out of range; `c`, `a` or `b` of another damping model.
pub fn stiffness_terms(chain: &Chain, p: &Param) -> Result<Option<Vec<(Site, f64)>>> {
    let n = chain.n();
    let sites = DefectSites::of(chain);
    let rayleigh = match chain.damping() {
        Damping::Rayleigh { a, b } => (*a, *b),
        _ => (0.0, 0.0),
    };
    let site = |probe: Probe, power: u32, poly: [f64; 3]| Site { probe, power, poly };
    let points = |taken: &[bool], power: u32, poly: [f64; 3]| -> Vec<(Site, f64)> {
        (1..=n)
            .filter(|&i| !taken[i])
            .map(|i| (site(Probe::Point(i), power, poly), 1.0))
            .collect()
    };
    let (lo, hi) = chain.spring_range();
    let springs = |taken: &[bool], power: u32, poly: [f64; 3]| -> Vec<(Site, f64)> {
        (lo..=hi)
            .filter(|&j| !taken[j])
            .map(|j| (site(Probe::Diff(j), power, poly), 1.0))
            .collect()
    };
    let weighted = |w: &[f64]| -> Vec<(Site, f64)> {
        w.iter()
            .enumerate()
            .filter(|(_, w)| **w != 0.0)
            .map(|(i, &w)| (site(Probe::Point(i + 1), 1, [0.0, 1.0, 0.0]), w))
            .collect()
    };
    let terms = match *p {
        Param::Defect(i) => vec![(chain.site(p.defect(chain, i)?), 1.0)],
        Param::Mass => points(&sites.mass, 2, [0.0, rayleigh.0, 1.0]),
        Param::D => points(&sites.damp, 1, [0.0, 1.0, 0.0]),
        Param::K => springs(&sites.spring, 0, [1.0, rayleigh.1, 0.0]),
        Param::Gamma | Param::Zeta { .. } => return Ok(None),
        Param::C | Param::A | Param::B => {
            p.get(chain)?;
            match p {
                Param::C => springs(&sites.spring_damp, 1, [0.0, 1.0, 0.0]),
                Param::A => weighted(&chain.masses()),
                _ => {
                    let mut t = weighted(&chain.grounds());
                    let k = chain.springs();
                    t.extend(
                        (lo..=hi)
                            .filter(|&j| k[j] != 0.0)
                            .map(|j| (site(Probe::Diff(j), 1, [0.0, 1.0, 0.0]), k[j])),
                    );
                    t
                }
            }
        }
    };
    Ok(Some(terms))
}

/// Does `param` change the mass of mass 1?
fn moves_m1(chain: &Chain, param: &Param) -> bool {
    let m1 = Site::monomial(Probe::Point(1), 2);
    let defect_at_1 = chain.defects().iter().any(|d| d.site() == m1);
    match *param {
        Param::Mass => !defect_at_1,
        Param::Defect(i) => chain.defects().get(i).is_some_and(|d| d.site() == m1),
        _ => false,
    }
}

/// Turn a displacement gradient into the gradient of `obs` (impulse
/// `gamma` on mass 1): `V = s X`, `A = s^2 X - [at = 1] gamma/m_1`, so
/// `dA/dm_1 = s^2 dX/dm_1 + gamma/m_1^2` and `dA/dgamma = s^2 dX/dgamma - 1/m_1`.
/// `value`, if given, replaces the value (a cancellation-free one).
fn to_observable<T: Scalar>(
    chain: &Chain,
    s: &T,
    at: usize,
    obs: Observable,
    params: &[Param],
    g: Gradient<T>,
    value: Option<T>,
) -> Gradient<T> {
    let gamma = chain.gamma();
    let m1 = chain.mass_at(1);
    let sp = match obs.power() {
        0 => return g,
        1 => s.clone(),
        _ => s.clone() * s.clone(),
    };
    let jump = obs == Observable::Acceleration && at == 1;
    let value = value.unwrap_or_else(|| obs.from_displacement(g.value, s, at, gamma, m1));
    let grad = params
        .iter()
        .zip(g.grad)
        .map(|(p, d)| {
            let mut v = sp.clone() * d;
            if jump && moves_m1(chain, p) {
                v = v + T::from_f64(gamma / (m1 * m1));
            }
            if jump && *p == Param::Gamma {
                v = v - T::from_f64(1.0 / m1);
            }
            v
        })
        .collect();
    Gradient { value, grad }
}

/// The observable `obs` of mass `at` (see [`crate::forward::Observable`])
/// and its derivatives with respect to `params`: the function a misfit on
/// velocity or acceleration data calls. The value is the cancellation-free
/// [`Forward::observe`]; derivatives by reciprocity ([`gradient`]) times
/// `s^p`, plus the derivative of the jump `gamma/m_1` for the acceleration of
/// mass 1. O(n) per `s`.
///
/// # Errors
/// As [`gradient`].
///
/// ```
/// use springmass::{Chain, Defect, forward::Observable};
/// use springmass::sensitivity::{observe_gradient, Param};
/// let c = Chain::paper(6)?.with_defect(Defect::Mass { at: 1, m: 2.0 })?;
/// let g = observe_gradient(&c, 0.8_f64, 1, Observable::Acceleration, &[Param::Defect(0)])?;
/// let h = 1e-6;
/// let a = |m: f64| springmass::forward::observe(
///     &Param::Defect(0).set(&c, m).unwrap(), 0.8_f64, 1, Observable::Acceleration).unwrap();
/// assert!(((a(2.0 + h) - a(2.0 - h)) / (2.0 * h) - g.grad[0]).abs() < 1e-7);
/// # Ok::<(), springmass::Error>(())
/// ```
pub fn observe_gradient<T: Scalar>(
    chain: &Chain,
    s: T,
    at: usize,
    obs: Observable,
    params: &[Param],
) -> Result<Gradient<T>> {
    let g = gradient(chain, s.clone(), at, params)?;
    let value = if obs == Observable::Displacement {
        None
    } else {
        Some(Forward::new(chain).observe(s.clone(), at, obs)?)
    };
    Ok(to_observable(chain, &s, at, obs, params, g, value))
}

/// [`defect_gradient_with`] for another observable of mass 1: the value
/// and its derivatives with respect to every defect value, O(k^2) per `s`.
///
/// # Errors
/// As [`Forward::eval`].
pub fn observe_defect_gradient_with<T: Scalar>(
    fwd: &Forward,
    s: T,
    obs: Observable,
) -> Result<Gradient<T>> {
    let g = defect_gradient_with(fwd, s.clone())?;
    let chain = fwd.chain();
    let params = Param::defects(chain);
    let value = if obs == Observable::Displacement {
        None
    } else {
        Some(fwd.observe(s.clone(), 1, obs)?)
    };
    Ok(to_observable(chain, &s, 1, obs, &params, g, value))
}

/// `X_1(s)` and its derivatives with respect to every defect value of `chain`
/// (in `chain.defects()` order), from `X` at the defect sites only: O(k) per
/// site by the transfer sweep, O(k^2) per `s` whatever `n`, and one sweep
/// for every site from [`crate::forward::MANY_SITES`] sites on (O(k)).
///
/// # Errors
/// As [`Forward::eval`].
pub fn defect_gradient<T: Scalar>(chain: &Chain, s: T) -> Result<Gradient<T>> {
    let fwd = Forward::new(chain);
    defect_gradient_with(&fwd, s)
}

/// [`defect_gradient`] for a prepared forward model.
///
/// # Errors
/// As [`Forward::eval`].
pub fn defect_gradient_with<T: Scalar>(fwd: &Forward, s: T) -> Result<Gradient<T>> {
    let chain = fwd.chain();
    let n = chain.n();
    // every site at once: one Green's function for a damping model the
    // transfer sweep does not take, one sweep for many sites, else each
    let mut sites: Vec<usize> = vec![1];
    for d in chain.defects() {
        sites.extend(chain.site(d).probe.entries(n).map(|(i, _)| i));
    }
    sites.sort_unstable();
    sites.dedup();
    let x = fwd.eval_many(s.clone(), &sites)?;
    defect_gradient_from(chain, &s, |i: usize| -> Result<T> {
        Ok(sites.binary_search(&i).map_or(T::zero(), |j| x[j].clone()))
    })
}

/// `X_1(s)` and its derivatives with respect to every defect value of
/// `chain` from `x(i) = X_i(s)` at mass 1 and the defect sites (`x(0)` and
/// `x(n + 1)` must be 0): `dX_1/dv = -B / gamma` with `B = s^2 X_a^2` for a
/// mass, `s X_a^2` for a damper, `(X_a - X_{a+1})^2` for a spring
/// (reciprocity). Shared by [`defect_gradient_with`] and the tabulated sweep
/// of the Laplace misfits.
///
/// # Errors
/// As `x`.
pub fn defect_gradient_from<T: Scalar>(
    chain: &Chain,
    s: &T,
    x: impl Fn(usize) -> Result<T>,
) -> Result<Gradient<T>> {
    let gamma = chain.gamma();
    let value = x(1)?;
    let inv = if gamma == 0.0 { 0.0 } else { 1.0 / gamma };
    let mut grad = Vec::with_capacity(chain.defects().len());
    for d in chain.defects() {
        let site = chain.site(d);
        let u = match site.probe {
            Probe::Point(at) => x(at)?,
            Probe::Diff(at) => x(at)? - x(at + 1)?,
        };
        let mut b = u.clone() * u;
        if site.is_monomial() {
            for _ in 0..site.power {
                b = s.clone() * b;
            }
        } else {
            b = site.poly_at(s) * b;
        }
        grad.push(-b.scale(inv));
    }
    Ok(Gradient { value, grad })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::forward::{response, tridiag};
    use crate::scenes;
    use num_complex::Complex64;

    fn chains() -> Vec<Chain> {
        vec![
            scenes::paper_with(5, "mass:2:3 mass:4:0.5").unwrap(),
            Chain::new(9)
                .unwrap()
                .with_d(0.3)
                .unwrap()
                .with_k(2.0)
                .unwrap()
                .with_mass(0.7)
                .unwrap()
                .with_gamma(1.7)
                .unwrap()
                .with_defects(
                    scenes::defects(
                        "mass:1:4 spring:0:0.5 spring:4:3 damper:5:0.05 mass:9:0.2 spring:9:1.5 damper:1:0.9",
                    )
                    .unwrap(),
                )
                .unwrap(),
            Chain::paper(1).unwrap(),
            Chain::paper(2)
                .unwrap()
                .with_defect(Defect::Spring { at: 1, k: 4.0 })
                .unwrap(),
        ]
    }

    #[test]
    fn column_matches_reference_solvers() {
        for c in chains() {
            for s in [0.0, 1e-6, 0.3, 2.0, 40.0] {
                let x = tridiag::solve_all(&c, s).unwrap();
                let g1 = green_column(&c, s, 1).unwrap();
                for i in 0..c.n() {
                    assert!((g1[i] * c.gamma() - x[i]).abs() <= 1e-13 * x[i].abs() + 1e-300);
                }
                // symmetry: G_{1o} = X_o / gamma
                for o in 1..=c.n() {
                    let go = green_column(&c, s, o).unwrap();
                    let xo = response(&c, s, o).unwrap();
                    assert!((go[0] * c.gamma() - xo).abs() <= 1e-12 * xo.abs() + 1e-300);
                }
            }
            for s in [Complex64::new(0.4, 1.3), Complex64::new(0.02, 0.9)] {
                for o in 1..=c.n() {
                    let go = green_column(&c, s, o).unwrap();
                    let xo = response(&c, s, o).unwrap();
                    assert!((go[0] * c.gamma() - xo).norm() <= 1e-11 * xo.norm());
                }
            }
        }
    }

    fn fd<T: Scalar>(c: &Chain, p: Param, s: T, o: usize) -> T {
        let v = p.get(c).unwrap();
        let h = 1e-5 * v.abs().max(1e-2);
        let up = response(&p.set(c, v + h).unwrap(), s.clone(), o).unwrap();
        let dn = response(&p.set(c, v - h).unwrap(), s, o).unwrap();
        (up - dn).scale(0.5 / h)
    }

    #[test]
    fn gradient_matches_central_differences() {
        for c in chains() {
            let params = Param::all(&c);
            for s in [1e-3, 0.1, 0.7, 3.0] {
                for o in [1, c.n()] {
                    let g = gradient(&c, s, o, &params).unwrap();
                    for (p, gv) in params.iter().zip(&g.grad) {
                        let f = fd(&c, *p, s, o);
                        let scale = g.value.abs().max(gv.abs());
                        assert!(
                            (f - gv).abs() <= 1e-6 * scale,
                            "{c:?} s={s} o={o} {}: {gv} vs {f}",
                            p.name(&c)
                        );
                    }
                }
            }
            for s in [Complex64::new(0.1, 0.8), Complex64::new(1.0, 5.0)] {
                let g = gradient(&c, s, 1, &params).unwrap();
                for (p, gv) in params.iter().zip(&g.grad) {
                    let f = fd(&c, *p, s, 1);
                    let scale = g.value.norm().max(gv.norm());
                    assert!((f - gv).norm() <= 1e-6 * scale, "{} {s}", p.name(&c));
                }
            }
        }
    }

    #[test]
    fn defect_gradient_agrees_with_full() {
        for c in chains() {
            let params = Param::defects(&c);
            for s in [0.05, 1.0, 9.0] {
                let a = defect_gradient(&c, s).unwrap();
                let b = gradient(&c, s, 1, &params).unwrap();
                for (x, y) in a.grad.iter().zip(&b.grad) {
                    assert!(
                        (x - y).abs() <= 1e-12 * (x.abs() + b.value.abs() * 1e-300),
                        "{x} {y}"
                    );
                }
            }
            let s = Complex64::new(0.2, 1.7);
            let a = defect_gradient(&c, s).unwrap();
            let b = gradient(&c, s, 1, &params).unwrap();
            for (x, y) in a.grad.iter().zip(&b.grad) {
                assert!((x - y).norm() <= 1e-10 * x.norm().max(1e-300));
            }
        }
    }

    #[test]
    fn boundaries_and_observables_match_central_differences() {
        use crate::chain::Boundary::*;
        use crate::forward::observe;
        for (l, r) in [(Free, Fixed), (Fixed, Free), (Free, Free)] {
            let c = crate::scenes::three_kinds(6, [1, 3, 5])
                .unwrap()
                .with_boundaries(l, r)
                .unwrap()
                .with_gamma(1.3)
                .unwrap();
            let params = Param::all(&c);
            for obs in [
                Observable::Displacement,
                Observable::Velocity,
                Observable::Acceleration,
            ] {
                for s in [0.05, 0.9, 4.0] {
                    for at in [1, 4] {
                        let g = observe_gradient(&c, s, at, obs, &params).unwrap();
                        let direct = observe(&c, s, at, obs).unwrap();
                        assert!((g.value - direct).abs() <= 1e-12 * direct.abs());
                        for (p, gv) in params.iter().zip(&g.grad) {
                            let v = p.get(&c).unwrap();
                            let h = 1e-5 * v.abs().max(1e-2);
                            let f = |x: f64| observe(&p.set(&c, x).unwrap(), s, at, obs).unwrap();
                            let fd = (f(v + h) - f(v - h)) / (2.0 * h);
                            let scale = g.value.abs().max(gv.abs());
                            assert!(
                                (fd - gv).abs() <= 1e-6 * scale,
                                "{l:?}-{r:?} {obs} s={s} at={at} {}: {gv} vs {fd}",
                                p.name(&c)
                            );
                        }
                    }
                }
                let fwd = Forward::new(&c);
                let a = observe_defect_gradient_with(&fwd, 0.7, obs).unwrap();
                let b = observe_gradient(&c, 0.7, 1, obs, &Param::defects(&c)).unwrap();
                for (x, y) in a.grad.iter().zip(&b.grad) {
                    assert!((x - y).abs() <= 1e-12 * x.abs().max(1e-300), "{x} {y}");
                }
            }
        }
    }

    #[test]
    fn set_validates_and_round_trips() {
        let c = chains().remove(1);
        for p in Param::all(&c) {
            let v = p.get(&c).unwrap();
            assert_eq!(p.set(&c, v).unwrap(), c);
        }
        assert!(Param::D.set(&c, -1.0).is_err());
        assert!(Param::Defect(0).set(&c, 0.0).is_err());
        assert!(Param::Defect(99).get(&c).is_err());
        assert!(gradient(&c, -1.0, 1, &[Param::D]).is_err());
        assert!(green_column(&c, 1.0, 0).is_err());
    }
}

#[cfg(test)]
mod damping_tests {
    use super::*;
    use crate::chain::dense_ref;
    use num_complex::Complex64;

    #[test]
    fn every_damping_parameter_matches_a_dense_difference() {
        for chain in dense_ref::model_chains() {
            let mut params = Param::all(&chain);
            params.extend(Param::damping(&chain));
            for s in [Complex64::new(0.7, 0.0), Complex64::new(0.3, 1.1)] {
                for o in [1, 5] {
                    let g = gradient(&chain, s, o, &params).unwrap();
                    let x = |c: &Chain| dense_ref::solve(c, s, o);
                    assert!((g.value - x(&chain)).norm() <= 1e-12 * g.value.norm());
                    for (p, d) in params.iter().zip(&g.grad) {
                        let v = p.get(&chain).unwrap();
                        let h = 1e-6 * v.abs().max(1e-2);
                        let at = |v: f64| x(&p.set(&chain, v).unwrap());
                        let fd = if v - h < 0.0 {
                            // a parameter at its bound 0: one-sided, second order
                            (at(v + h) * 4.0 - at(v) * 3.0 - at(v + 2.0 * h)) / (2.0 * h)
                        } else {
                            (at(v + h) - at(v - h)) / (2.0 * h)
                        };
                        assert!(
                            (fd - d).norm() <= 1e-6 * (fd.norm() + g.value.norm() * 1e-3),
                            "{} {} s={s} o={o}: {d} vs {fd}",
                            chain.damping(),
                            p.name(&chain)
                        );
                    }
                    if o == 1 {
                        let dg = defect_gradient(&chain, s).unwrap();
                        for (a, b) in dg.grad.iter().zip(&g.grad) {
                            assert!((a - b).norm() <= 1e-9 * b.norm().max(1e-9));
                        }
                    }
                }
            }
        }
    }
}
