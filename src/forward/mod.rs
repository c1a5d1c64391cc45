//! Forward model: `X_i(s)` of a chain with defects, by low-rank updates of the
//! closed-form Green's function.
//!
//! The chain's dynamic stiffness is `K(s) = K_0(s) + U C(s) U^T`, with `K_0` the
//! uniform chain ([`crate::green`]) and one column `u_l` and coefficient
//! `c_l(s) = dm_l s^2 + dd_l s + dk_l` per [`Update`] (a mass and a damper defect at
//! the same place share one column). With `G = K_0^{-1}` and `b = gamma e_1`,
//!
//! `z = U^T X` solves `(I + (U^T G U) C) z = gamma U^T G e_1`, and
//! `X_o = gamma G_{o1} - (G U)_o C z`,
//!
//! a `k x k` solve per `s`: O(k^3) whatever `n` (Sherman-Morrison for `k = 1`,
//! which is the paper's (4.6)). When the observed mass carries a point update,
//! `X_o = z_l` is read directly, which avoids the cancellation
//! `G_oo - G_oo c G_oo / (1 + G_oo c)` for heavy defects at the observed mass.
//!
//! # Three evaluators
//!
//! | path | cost per `s` | use |
//! |---|---|---|
//! | [`woodbury`] | O(k^3), Green's entries tabulable per `s` | `X_1` in fitting (hot path) |
//! | [`transfer::Transfer`] | O(k) | [`Forward::eval`]: any observed mass, no cancellation |
//! | [`tridiag`] | O(n) | independent reference, fallback |
//!
//! Woodbury is exact algebra but, for a mass `o` *behind* a heavy defect, the
//! transmitted wave is a difference of nearly equal terms (relative error of
//! order `1e-16 (1 + G_jj |c_j|)`, 1e-10 for a 1e6 mass): for `X_1` (the
//! paper's observable) this does not occur, so the fitting code keeps
//! Woodbury, while [`Forward::eval`] uses the cancellation-free
//! [`transfer`] sweep. The two are tested against each other and against
//! [`tridiag`] over the whole grid of extremes (`tests/forward.rs`).
//!
//! # Boundaries, observables, excitations
//!
//! Every path honours the chain's ends ([`crate::chain::Boundary`]): the
//! Green's function has a closed form for each of the four cases
//! ([`crate::green`]), the transfer sweep and the O(n) solver treat a free end
//! as a wall spring of 0. With both ends free `s = 0` is the rigid-body pole:
//! [`Error::Singular`] there, ordinary values at every `s != 0`.
//!
//! [`Observable`]: the displacement `X`, the velocity `V = s X` or the
//! acceleration `A = s^2 X - s x(0) - x'(0+)` of any mass. `x(0) = 0`, and
//! the impulse `gamma delta(t)` on mass 1 makes `x_1'(0+) = gamma/m_1`: the
//! acceleration series sampled at `t > 0` excludes the delta, and its
//! transform is `s^2 X_1 - gamma/m_1` ([`observe`], computed as
//! `-Z_1 X_1/m_1` without cancellation). For a force `f(t)` on mass 1
//! instead of the impulse, `X_o(s) = H_o(s) F(s)` with the transfer function
//! `H_o` ([`transfer_function`], the response to a unit impulse) and no jump:
//! `V = s H F`, `A = s^2 H F`.
//!
//! ```
//! use springmass::{Chain, Defect, forward::Forward};
//! let chain = Chain::paper(20)?.with_defect(Defect::Mass { at: 8, m: 5.0 })?;
//! let fwd = Forward::new(&chain);
//! let x1 = fwd.eval(0.5_f64, 1)?;
//! let reference = springmass::forward::tridiag::solve(&chain, 0.5_f64, 1)?;
//! assert!((x1 - reference).abs() < 1e-14 * reference);
//! # Ok::<(), springmass::Error>(())
//! ```

pub mod transfer;
pub mod tridiag;

use transfer::Transfer;

use crate::chain::Chain;
use crate::error::{Error, Result};
use crate::green::{Green, Probe};
use crate::linalg::solve_in_place;
pub use crate::observable::Observable;
use crate::scalar::Scalar;

/// Largest `n` for which a singular closed form falls back to the O(n) solver.
const FALLBACK_MAX_N: usize = 10_000_000;

/// Sites from which [`Forward::eval_many`] of a chain the transfer takes
/// sweeps once for all of them rather than once each.
pub const MANY_SITES: usize = 8;

/// Chains of a damping model the transfer sweep does not take are solved
/// by the O(n) solver up to this many masses (cheaper than the Green's
/// function's transcendentals there), by Woodbury above.
const GENERAL_SOLVE_MAX_N: usize = 64;

/// Largest `|s|` accepted (beyond it `mass s^2` leaves the f64 range for any
/// physical mass; the spec asks for `|s| <= 1e4`).
pub const MAX_ABS_S: f64 = 1e100;

/// One rank-1 update `u c(s) u^T`, `c(s) = dm s^2 + dd s + dk`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Update {
    /// The column `u`.
    pub probe: Probe,
    /// Change of mass.
    pub dm: f64,
    /// Change of damping.
    pub dd: f64,
    /// Change of stiffness.
    pub dk: f64,
}

impl Update {
    /// `c(s) = dm s^2 + dd s + dk`.
    #[inline]
    pub fn coeff<T: Scalar>(&self, s: &T) -> T {
        let mut c = T::from_f64(self.dk);
        if self.dm != 0.0 {
            c = c + (s.clone() * s.clone()).scale(self.dm);
        }
        if self.dd != 0.0 {
            c = c + s.scale(self.dd);
        }
        c
    }
}

/// The updates of a chain's defects, merged per column.
pub fn updates(chain: &Chain) -> Vec<Update> {
    let mut out: Vec<Update> = Vec::with_capacity(chain.defects().len());
    for d in chain.defects() {
        let site = chain.site(d);
        // [dk, dd, dm]: the change times s^0, s^1, s^2
        let delta = d.value() - d.base_value(chain);
        let c = site.poly.map(|p| if p == 0.0 { 0.0 } else { delta * p });
        let (probe, [dk, dd, dm]) = (site.probe, c);
        if let Some(u) = out.iter_mut().find(|u| u.probe == probe) {
            u.dm += dm;
            u.dd += dd;
            u.dk += dk;
        } else {
            out.push(Update { probe, dm, dd, dk });
        }
    }
    out
}

/// Check a Laplace variable: finite, `Re s >= 0`.
///
/// # Errors
/// [`Error::InvalidParameter`] naming `s`.
pub fn check_s<T: Scalar>(s: &T) -> Result<()> {
    let z = s.to_c64();
    if !(z.re.is_finite() && z.im.is_finite()) || z.re < 0.0 || z.norm() > MAX_ABS_S {
        return Err(Error::invalid(
            "s",
            format!("{z}"),
            "finite with Re s >= 0 and |s| <= 1e100",
        ));
    }
    Ok(())
}

/// The forward model of one chain, ready to be evaluated at many `s`.
#[derive(Clone, Debug)]
pub struct Forward {
    chain: Chain,
    updates: Vec<Update>,
    transfer: Transfer,
    /// A damping model the transfer sweep does not take (spring-parallel
    /// dampers, Rayleigh): every value by Woodbury on the generalised
    /// Green's function, the O(n) solver where that is not finite.
    general: bool,
    /// The modes of a chain with `modal` damping (`None` otherwise, or when
    /// they cannot be computed: its values then give that error): its
    /// [`Forward::eval`], [`Forward::observe`] and
    /// [`Forward::transfer_function`] are the exact modal sums
    /// ([`modal_sum`]); the Green's function and the Woodbury updates
    /// ([`Forward::green`], [`Forward::eval_with`], [`Forward::sites_with`])
    /// are those of its tridiagonal Rayleigh stand-in (the fit's screens).
    modes: Option<std::sync::Arc<crate::time::modal::Modes>>,
}

impl Forward {
    /// Prepare the updates of `chain` (validated by construction).
    pub fn new(chain: &Chain) -> Forward {
        let modes = chain
            .damping()
            .is_modal()
            .then(|| {
                crate::time::modal::Modes::new(chain)
                    .ok()
                    .map(std::sync::Arc::new)
            })
            .flatten();
        Forward {
            chain: chain.clone(),
            updates: updates(chain),
            transfer: Transfer::new(chain),
            general: !chain.damping().is_grounded() || chain.baseline().is_some(),
            modes,
        }
    }

    /// The exact modal sum ([`modal_sum`]) when the chain has `modal`
    /// damping, `None` otherwise.
    fn modal<T: Scalar>(
        &self,
        s: &T,
        at: usize,
        obs: Observable,
        transfer: bool,
    ) -> Option<Result<T>> {
        if !self.chain.damping().is_modal() {
            return None;
        }
        Some(match &self.modes {
            Some(m) => modal_sum(m, &self.chain, s.clone(), at, obs, transfer),
            // the modes could not be computed: say why
            None => crate::time::modal::Modes::new(&self.chain)
                .and_then(|m| modal_sum(&m, &self.chain, s.clone(), at, obs, transfer)),
        })
    }

    /// The chain.
    pub fn chain(&self) -> &Chain {
        &self.chain
    }

    /// The merged rank-1 updates.
    pub fn updates(&self) -> &[Update] {
        &self.updates
    }

    /// Green's function of the underlying uniform chain (with the chain's
    /// ends) at `s`.
    pub fn green<T: Scalar>(&self, s: T) -> Green<T> {
        Green::of_chain(&self.chain, s)
    }

    /// The observable `obs` of mass `at` after the impulse `gamma` on mass 1
    /// (module docs): `X`, `s X` or `s^2 X - [at = 1] gamma/m_1`, by the
    /// cancellation-free transfer sweep.
    ///
    /// # Errors
    /// As [`Forward::eval`].
    ///
    /// ```
    /// use springmass::{Chain, forward::{Forward, Observable}};
    /// let c = Chain::paper(10)?;
    /// let f = Forward::new(&c);
    /// let s = 30.0_f64;
    /// let x = f.eval(s, 1)?;
    /// let a = f.observe(s, 1, Observable::Acceleration)?;
    /// assert!((a - (s * s * x - 1.0)).abs() < 1e-10 * a.abs());
    /// # Ok::<(), springmass::Error>(())
    /// ```
    pub fn observe<T: Scalar>(&self, s: T, at: usize, obs: Observable) -> Result<T> {
        self.observe_scaled(s, at, obs, self.chain.gamma())
    }

    /// The transfer function `H^obs_at(s)` from a force on mass 1 to the
    /// observable of mass `at`: `s^p X_at(s) / gamma` computed with a unit
    /// impulse (no jump term: a force has no delta). The response to a
    /// force with transform `F(s)` is `H F`.
    ///
    /// # Errors
    /// As [`Forward::eval`].
    pub fn transfer_function<T: Scalar>(&self, s: T, at: usize, obs: Observable) -> Result<T> {
        if let Some(x) = self.modal(&s, at, obs, true) {
            return x;
        }
        check_s(&s)?;
        self.chain.check_observe(at)?;
        let x = if self.general {
            let unit = Forward::new(&self.chain.clone().with_gamma(1.0)?);
            unit.eval_with(&unit.green(s.clone()), &s, at)
        } else {
            self.transfer.eval_parts(&s, at, 1.0).0
        };
        let x = self.finish_unit(x, s.clone(), at)?;
        Ok(Observable::from_displacement(obs, x, &s, at, 0.0, 1.0))
    }

    fn finish_unit<T: Scalar>(&self, x: T, s: T, at: usize) -> Result<T> {
        if x.is_finite() {
            return Ok(x);
        }
        let unit = self.chain.clone().with_gamma(1.0)?;
        if unit.n() <= FALLBACK_MAX_N {
            return tridiag::solve(&unit, s, at);
        }
        Err(Error::Singular {
            s: format!("{}", s.to_c64()),
        })
    }

    fn observe_scaled<T: Scalar>(&self, s: T, at: usize, obs: Observable, gamma: f64) -> Result<T> {
        if gamma == self.chain.gamma() {
            if let Some(x) = self.modal(&s, at, obs, false) {
                return x;
            }
        }
        check_s(&s)?;
        self.chain.check_observe(at)?;
        let m1 = self.chain.mass_at(1);
        if self.general {
            let x = woodbury(&self.green(s.clone()), &s, &self.updates, gamma, at);
            let x = self.finish_gamma(x, s.clone(), at, gamma)?;
            return Ok(obs.from_displacement(x, &s, at, gamma, m1));
        }
        let (x, z1) = self.transfer.eval_parts(&s, at, gamma);
        if obs == Observable::Acceleration && at == 1 && x.is_finite() && z1.is_finite() {
            // s^2 X_1 - gamma/m_1 = -Z_1 X_1 / m_1
            return Ok(-(z1 * x).scale(1.0 / m1));
        }
        let x = self.finish(x, s.clone(), at)?;
        Ok(obs.from_displacement(x, &s, at, gamma, m1))
    }

    /// `X_observe(s)` by the cancellation-free transfer sweep (O(k) per `s`).
    ///
    /// # Errors
    /// `s` not finite, `Re s < 0` or `|s| > 1e100`; `observe` outside `1..=n`;
    /// [`Error::Singular`] at a pole (undamped chain on the imaginary axis).
    pub fn eval<T: Scalar>(&self, s: T, observe: usize) -> Result<T> {
        if let Some(x) = self.modal(&s, observe, Observable::Displacement, false) {
            return x;
        }
        check_s(&s)?;
        self.chain.check_observe(observe)?;
        if self.general {
            if self.chain.n() <= GENERAL_SOLVE_MAX_N {
                return tridiag::solve(&self.chain, s, observe);
            }
            return self.eval_woodbury(s, observe);
        }
        let x = self.transfer.eval(&s, observe);
        self.finish(x, s, observe)
    }

    /// `X` at the increasing `sites` in one transfer sweep with the powers
    /// of [`transfer::SweepTable`] `table` (built for this chain's uniform
    /// part at `s`); `None` when the table is for another uniform part or a
    /// value is not finite (a pole, or a removable singularity the direct
    /// evaluation resolves). Unchecked `s` and sites: the caller validated them.
    pub fn sites_with<T: Scalar>(
        &self,
        s: &T,
        table: &transfer::SweepTable<T>,
        sites: &[usize],
    ) -> Option<Vec<T>> {
        if self.general || !self.transfer.fits(table) {
            return None;
        }
        let (x, _) = self
            .transfer
            .eval_sites(s, table, sites, self.chain.gamma());
        x.iter().all(|v| v.is_finite()).then_some(x)
    }

    /// [`Forward::sites_with`] into `work` (`X` at the sites in
    /// [`transfer::SweepWork::out`]): true when the table applies and every
    /// value is finite. No allocation once `work` has grown.
    pub fn sites_into<T: Scalar>(
        &self,
        s: &T,
        table: &transfer::SweepTable<T>,
        sites: &[usize],
        work: &mut transfer::SweepWork<T>,
    ) -> bool {
        if self.general || !self.transfer.fits(table) {
            return false;
        }
        self.transfer
            .eval_sites_into(s, table, sites, self.chain.gamma(), work);
        work.out().iter().all(|v| v.is_finite())
    }

    /// `X` at every mass of `sites` (1-based), as [`Forward::eval`] each:
    /// for a damping model the transfer sweep does not take, one Green's
    /// function for all of them; for [`MANY_SITES`] increasing sites or
    /// more, one transfer sweep (O(n) for all, not for each).
    ///
    /// # Errors
    /// As [`Forward::eval`].
    pub fn eval_many<T: Scalar>(&self, s: T, sites: &[usize]) -> Result<Vec<T>> {
        if !self.general {
            let increasing = sites.windows(2).all(|w| w[0] < w[1]);
            if sites.len() < MANY_SITES || !increasing || self.chain.damping().is_modal() {
                return sites.iter().map(|&i| self.eval(s.clone(), i)).collect();
            }
            check_s(&s)?;
            for &i in sites {
                self.chain.check_observe(i)?;
            }
            let x = self
                .transfer
                .eval_sites_direct(&s, sites, self.chain.gamma());
            return x
                .into_iter()
                .zip(sites)
                .map(|(x, &i)| self.finish(x, s.clone(), i))
                .collect();
        }
        check_s(&s)?;
        if self.chain.n() <= GENERAL_SOLVE_MAX_N {
            for &i in sites {
                self.chain.check_observe(i)?;
            }
            let x = tridiag::solve_all(&self.chain, s)?;
            return Ok(sites.iter().map(|&i| x[i - 1].clone()).collect());
        }
        let g = self.green(s.clone());
        sites
            .iter()
            .map(|&i| {
                self.chain.check_observe(i)?;
                let x = self.eval_with(&g, &s, i);
                self.finish(x, s.clone(), i)
            })
            .collect()
    }

    /// `X_observe(s)` by Woodbury on the closed-form Green's function (checked).
    /// Accurate to rounding for `observe = 1` and at defect sites; see the
    /// module docs for masses behind heavy defects.
    pub fn eval_woodbury<T: Scalar>(&self, s: T, observe: usize) -> Result<T> {
        check_s(&s)?;
        self.chain.check_observe(observe)?;
        let g = self.green(s.clone());
        let x = self.eval_with(&g, &s, observe);
        self.finish(x, s, observe)
    }

    /// [`Forward::finish`] for an impulse `gamma` other than the chain's.
    fn finish_gamma<T: Scalar>(&self, x: T, s: T, observe: usize, gamma: f64) -> Result<T> {
        if gamma == self.chain.gamma() || x.is_finite() {
            return self.finish(x, s, observe);
        }
        Forward::new(&self.chain.clone().with_gamma(gamma)?).finish(x, s, observe)
    }

    fn finish<T: Scalar>(&self, x: T, s: T, observe: usize) -> Result<T> {
        if x.is_finite() {
            return Ok(x);
        }
        // A removable singularity of the closed form (lambda = i pi with d = 0),
        // or a true pole: decide with the O(n) solver.
        if self.chain.n() <= FALLBACK_MAX_N {
            return tridiag::solve(&self.chain, s, observe);
        }
        Err(Error::Singular {
            s: format!("{}", s.to_c64()),
        })
    }

    /// `X_observe(s)` for a prepared Green's function; unchecked (the caller
    /// validated `s` and `observe`). May return a non-finite value at a pole.
    pub fn eval_with<T: Scalar>(&self, g: &Green<T>, s: &T, observe: usize) -> T {
        woodbury(g, s, &self.updates, self.chain.gamma(), observe)
    }
}

/// The Woodbury response for explicit updates (used by the fitting code,
/// which varies the updates at fixed `s`).
pub fn woodbury<T: Scalar>(
    g: &Green<T>,
    s: &T,
    updates: &[Update],
    gamma: f64,
    observe: usize,
) -> T {
    let src = g.factors(Probe::Point(1));
    let k = updates.len();
    if k == 0 {
        return g.entry(observe, 1).scale(gamma);
    }
    // factors once per probe; A = U^T G U is symmetric
    let fu: Vec<_> = updates.iter().map(|u| g.factors(u.probe)).collect();
    let c: Vec<T> = updates.iter().map(|u| u.coeff(s)).collect();
    let mut gu = vec![T::zero(); k * k];
    for l in 0..k {
        for m in l..k {
            let v = g.pair(&fu[l], &fu[m]);
            gu[m * k + l] = v.clone();
            gu[l * k + m] = v;
        }
    }
    let mut a: Vec<T> = Vec::with_capacity(k * k);
    for l in 0..k {
        for m in 0..k {
            let mut v = gu[l * k + m].clone() * c[m].clone();
            if l == m {
                v = v + T::one();
            }
            a.push(v);
        }
    }
    let rhs: Vec<T> = fu.iter().map(|f| g.pair(f, &src)).collect();
    let mut z = rhs.clone();
    if !solve_in_place(&mut a, &mut z, k) {
        return T::from_f64(f64::NAN);
    }
    let obs = Probe::Point(observe);
    if let Some(l) = updates.iter().position(|u| u.probe == obs) {
        return z[l].scale(gamma);
    }
    let (base, h) = if observe == 1 {
        // G e_1 is the right-hand side itself
        (g.pair(&src, &src), rhs)
    } else {
        let fo = g.factors(obs);
        (
            g.pair(&fo, &src),
            fu.iter().map(|f| g.pair(&fo, f)).collect(),
        )
    };
    let mut corr = T::zero();
    for l in 0..k {
        corr = corr + h[l].clone() * c[l].clone() * z[l].clone();
    }
    (base - corr).scale(gamma)
}

/// `X_observe(s)` of `chain` (see [`Forward::eval`]; a chain with
/// `modal` damping by its exact modal sum).
///
/// ```
/// use springmass::{Chain, chain::Damping, forward::response};
/// let c = Chain::paper(1)?.with_d(0.0)?.with_damping(Damping::modal(0.1))?;
/// // one mass, two unit springs: omega^2 = 2
/// let s = 0.7_f64;
/// let want = 1.0 / (s * s + 2.0 * 0.1 * 2f64.sqrt() * s + 2.0);
/// assert!((response(&c, s, 1)? - want).abs() < 1e-15);
/// # Ok::<(), springmass::Error>(())
/// ```
pub fn response<T: Scalar>(chain: &Chain, s: T, observe: usize) -> Result<T> {
    Forward::new(chain).eval(s, observe)
}

/// The Laplace transform of a chain with `modal` damping
/// ([`crate::chain::Damping::Modal`]), whose `C` is not tridiagonal: the
/// exact sum over its undamped modes
/// `X_at(s) = amp sum_j phi_at,j phi_1,j / (s^2 + 2 zeta omega_j s + omega_j^2)`
/// ([`crate::time::modal::Modes`]), then the observable (`transfer`: per
/// unit force, no jump term). [`Forward::eval`], [`Forward::observe`] and
/// [`Forward::transfer_function`] (and the free functions of this module)
/// take it for such a chain; the Green's function and Woodbury updates of
/// a [`Forward`] are its tridiagonal Rayleigh stand-in's (the fit's
/// screens).
fn modal_sum<T: Scalar>(
    modes: &crate::time::modal::Modes,
    chain: &Chain,
    s: T,
    at: usize,
    obs: Observable,
    transfer: bool,
) -> Result<T> {
    check_s(&s)?;
    chain.check_observe(at)?;
    let gamma = if transfer { 1.0 } else { chain.gamma() };
    let z = s.to_c64();
    let x = modes.response(at, 1, gamma)?.laplace(z);
    let x = if z.im == 0.0 {
        T::from_f64(x.re)
    } else {
        T::from_c64(x).ok_or_else(|| Error::invalid("s", format!("{z}"), "a real s"))?
    };
    let (jump, m1) = if transfer {
        (0.0, 1.0)
    } else {
        (gamma, chain.mass_at(1))
    };
    Ok(obs.from_displacement(x, &s, at, jump, m1))
}

/// The observable `obs` of mass `at` after the impulse on mass 1 (see
/// [`Forward::observe`]).
///
/// # Errors
/// As [`Forward::eval`].
pub fn observe<T: Scalar>(chain: &Chain, s: T, at: usize, obs: Observable) -> Result<T> {
    Forward::new(chain).observe(s, at, obs)
}

/// The transfer function from a force on mass 1 to the observable `obs` of
/// mass `at` (see [`Forward::transfer_function`]).
///
/// # Errors
/// As [`Forward::eval`].
///
/// ```
/// use springmass::{Chain, forward::{transfer_function, response, Observable}};
/// let c = Chain::paper(8)?.with_gamma(2.5)?;
/// let h = transfer_function(&c, 0.4_f64, 3, Observable::Displacement)?;
/// assert!((2.5 * h - response(&c, 0.4_f64, 3)?).abs() < 1e-15);
/// # Ok::<(), springmass::Error>(())
/// ```
pub fn transfer_function<T: Scalar>(chain: &Chain, s: T, at: usize, obs: Observable) -> Result<T> {
    Forward::new(chain).transfer_function(s, at, obs)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chain::Defect;
    use num_complex::Complex64;

    /// Many sites in one sweep give each site's own evaluation (and the
    /// dense solve's), on chains with defects of every kind, for real and
    /// complex `s`, small and large.
    #[test]
    fn many_sites_in_one_sweep_match_each_site_alone() {
        for (n, defects) in [
            (30usize, "mass:3:2 spring:7:0.5 damper:9:0.4"),
            (40, "mass:1:1e3 mass:20:1e-3"),
            (300, "spring:150:3 mass:299:0.2"),
        ] {
            let chain = crate::scenes::paper_with(n, defects).unwrap();
            let fwd = Forward::new(&chain);
            let sites: Vec<usize> = (1..=n).step_by(3).collect();
            assert!(sites.len() >= MANY_SITES);
            for s in [
                Complex64::new(1e-6, 0.0),
                Complex64::new(0.05, 0.7),
                Complex64::new(3.0, -40.0),
                Complex64::new(1e4, 0.0),
            ] {
                let many = fwd.eval_many(s, &sites).unwrap();
                let dense = crate::forward::tridiag::solve_all(&chain, s).unwrap();
                for (&i, x) in sites.iter().zip(&many) {
                    let alone = fwd.eval(s, i).unwrap();
                    let scale = alone.norm().max(1e-300);
                    assert!((x - alone).norm() <= 1e-12 * scale, "n {n} s {s} site {i}");
                    let d = dense[i - 1];
                    assert!(
                        (x - d).norm() <= 1e-8 * d.norm().max(1e-300),
                        "n {n} s {s} site {i}"
                    );
                }
            }
        }
    }

    #[test]
    fn single_defect_is_papers_formula_4_7() {
        // X_1 = -R_11 + R_1j (1-m) s^2 R_j1 / (1 + R_jj (1-m) s^2), R = -G (k = 1)
        for &(n, j, m) in &[
            (20usize, 15usize, 1.01),
            (5, 3, 4.0),
            (20, 3, 5.0),
            (7, 1, 0.5),
            (7, 7, 30.0),
        ] {
            let chain = Chain::paper(n)
                .unwrap()
                .with_defect(Defect::Mass { at: j, m })
                .unwrap();
            for &s in &[0.05, 0.7, 2.0, 9.0] {
                let g: Green<f64> = Green::new(n, 1.0, 1.0, 0.1, s);
                let (r11, r1j, rjj) = (-g.entry(1, 1), -g.entry(1, j), -g.entry(j, j));
                let e = (1.0 - m) * s * s;
                let paper = -r11 + r1j * e * r1j / (1.0 + rjj * e);
                let x = response(&chain, s, 1).unwrap();
                assert!(
                    (x - paper).abs() <= 1e-13 * paper.abs(),
                    "n={n} j={j} m={m} s={s}"
                );
            }
        }
    }

    #[test]
    fn uniform_x1_closed_form() {
        for &n in &[1usize, 2, 5, 20, 1000] {
            for &s in &[0.01, 0.3, 1.0, 4.0] {
                let x = response(&Chain::paper(n).unwrap(), s, 1).unwrap();
                let lam = (1.0 + (s * s + 0.1 * s) / 2.0).acosh();
                let expect = (n as f64 * lam).sinh() / ((n as f64 + 1.0) * lam).sinh();
                if expect.is_finite() {
                    assert!((x - expect).abs() < 1e-12 * expect, "n={n} s={s}");
                }
            }
        }
    }

    #[test]
    fn mass_and_damper_at_one_place_merge() {
        let c = Chain::paper(6)
            .unwrap()
            .with_defects([
                Defect::Mass { at: 3, m: 2.0 },
                Defect::Damper { at: 3, d: 1.0 },
            ])
            .unwrap();
        assert_eq!(updates(&c).len(), 1);
        let s = Complex64::new(0.4, 1.1);
        let x = response(&c, s, 2).unwrap();
        let r = tridiag::solve(&c, s, 2).unwrap();
        assert!((x - r).norm() < 1e-13 * r.norm());
    }

    #[test]
    fn bad_s_and_observe() {
        let c = Chain::paper(3).unwrap();
        assert!(
            matches!(response(&c, -1.0, 1), Err(Error::InvalidParameter { field, .. }) if field == "s")
        );
        assert!(response(&c, f64::NAN, 1).is_err());
        assert!(response(&c, Complex64::new(-0.1, 2.0), 1).is_err());
        assert!(
            matches!(response(&c, 1.0, 4), Err(Error::InvalidParameter { field, .. }) if field == "observe")
        );
        assert!(response(&c, 1.0, 0).is_err());
    }
}

#[cfg(test)]
mod damping_tests {
    use super::*;
    use crate::chain::dense_ref;
    use num_complex::Complex64;

    #[test]
    fn every_damping_model_matches_the_dense_solve() {
        for chain in dense_ref::model_chains() {
            let fwd = Forward::new(&chain);
            for s in [
                Complex64::new(0.3, 0.0),
                Complex64::new(0.2, 1.3),
                Complex64::new(1.0, 9.0),
            ] {
                for o in 1..=chain.n() {
                    let want = dense_ref::solve(&chain, s, o);
                    let tol = 1e-11 * dense_ref::solve(&chain, s, 1).norm().max(want.norm());
                    for got in [fwd.eval(s, o).unwrap(), fwd.eval_woodbury(s, o).unwrap()] {
                        assert!(
                            (got - want).norm() <= tol,
                            "{} s={s} o={o}",
                            chain.damping()
                        );
                    }
                    let v = fwd.observe(s, o, Observable::Velocity).unwrap();
                    assert!((v - s * want).norm() <= tol * s.norm());
                    let h = fwd
                        .transfer_function(s, o, Observable::Displacement)
                        .unwrap();
                    assert!((h * chain.gamma() - want).norm() <= tol);
                }
                let a = fwd.observe(s, 1, Observable::Acceleration).unwrap();
                let want =
                    s * s * dense_ref::solve(&chain, s, 1) - chain.gamma() / chain.mass_at(1);
                assert!((a - want).norm() <= 1e-10 * want.norm().max(1.0));
            }
        }
    }
}
