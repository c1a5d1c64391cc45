//! Cancellation-free O(k) evaluation of `X_o(s)` for any observed mass: Thomas
//! elimination of the tridiagonal system in which every uniform run of the
//! chain is crossed in closed form.
//!
//! # Why a second evaluator
//!
//! The Woodbury form `X_o = gamma (G_o1 - (G U)_o C z)` subtracts two nearly equal
//! numbers when defects between mass 1 and mass `o` block the wave (the 2x2
//! minors of the semiseparable `G` vanish, so the transmitted part is exactly
//! a difference of products): for a heavy mass between source and observer the
//! relative error grows like the blocking factor `1 + G_jj c_j` (1e-10 for
//! `m = 1e6`). `X_1`, the paper's observable, is not affected. This module
//! computes every `X_o` without such differences.
//!
//! # Method
//!
//! `K(s)` has diagonal `a_i = m_i s^2 + d_i s + kappa_{i-1} + kappa_i` and
//! off-diagonal `-kappa_i`. Eliminating from the right gives effective diagonals
//! `D_i = a_i - kappa_i^2 / D_{i+1}`; we carry the *excess stiffness*
//! `E_i = D_i - kappa_{i-1}`, which obeys
//!
//! `E_i = m_i s^2 + d_i s + kappa_i E_{i+1} / (E_{i+1} + kappa_i)`   (`E_{n+1}/D_{n+1} = 1` at the wall),
//!
//! a sum of positive terms for real `s` (springs in series at `s = 0`). On a
//! uniform run `[l, r]` the recurrence has the closed form, with
//! `q = e^{-lambda}`, `p = r + 1 - i`,
//!
//! `E_i = k expm1(lambda) (1 + psi q^{2p+1}) / B(p)`, `B(p) = 1 - psi q^{2p} = (1 - q^{2p}) + (1 - psi) q^{2p}`,
//!
//! where `1 - psi = (1 - q^2) / (rho - q^2)`, `rho - q^2 = E_{r+1}/(k e^lambda) + q (1 - q)`
//! (`psi = 1` at the wall). Substitution forward, `X_1 = gamma / D_1`,
//! `X_{i+1} = kappa_i X_i / D_{i+1}`, crosses a run with
//! `X_o / X_l = e^{-(o - l) lambda} B(p_o) / B(p_l)`. All of it costs O(number of
//! defects) per `s`, whatever `n`.
//!
//! A free end is a wall spring of 0: the end mass becomes a special mass
//! with `kappa_0 = 0` (or `kappa_n = 0`), so the runs' closed form is the
//! fixed-end one and nothing else changes. Mass 1 is always a special mass,
//! which gives the impedance it sees as a plain sum ([`Transfer::eval_parts`]).

use crate::chain::{Chain, Probe};
use crate::scalar::Scalar;

/// One piece of the chain, in increasing position.
#[derive(Clone, Debug, PartialEq)]
enum Seg {
    /// A mass whose own parameters or adjacent springs differ from uniform.
    Special {
        i: usize,
        m: f64,
        d: f64,
        /// stiffness to the ground besides the two springs
        g: f64,
        /// spring to the left (`kappa_{i-1}`)
        kl: f64,
        /// spring to the right (`kappa_i`)
        kr: f64,
    },
    /// Uniform masses `l..=r` whose springs on both sides are uniform.
    Run { l: usize, r: usize },
}

/// The chain split into special masses and uniform runs (computed once per chain).
#[derive(Clone, Debug)]
pub struct Transfer {
    n: usize,
    k: f64,
    mass: f64,
    d: f64,
    gamma: f64,
    segs: Vec<Seg>,
}

/// Buffers of a sweep, reused across the sweeps of many `s`
/// ([`Transfer::eval_sites_into`]): no allocation per sweep once grown.
#[derive(Debug)]
pub struct SweepWork<T> {
    swept: Vec<Swept<T>>,
    out: Vec<T>,
}

impl<T> Default for SweepWork<T> {
    fn default() -> Self {
        SweepWork {
            swept: Vec::new(),
            out: Vec::new(),
        }
    }
}

impl<T> SweepWork<T> {
    /// `X` at the sites of the last sweep.
    pub fn out(&self) -> &[T] {
        &self.out
    }
}

/// Per-`s` state of one segment after the backward sweep.
#[derive(Debug)]
struct Swept<T> {
    /// `E` at the segment's left index, as `e_num / e_den` (a run's
    /// division is left to its consumers, which fold it into their own:
    /// `e_den = 1` for a special mass and in the static limit).
    e_num: T,
    e_den: T,
    /// For runs: `1 - psi` (in the static limit: `k / E_{r+1}`).
    one_m_psi: T,
}

impl Transfer {
    /// Split `chain` into special masses and uniform runs. O(n_defects log n_defects).
    pub fn new(chain: &Chain) -> Transfer {
        let n = chain.n();
        let mut special: Vec<usize> = Vec::new();
        for d in chain.defects() {
            special.extend(d.site().probe.entries(n).map(|(i, _)| i));
        }
        // mass 1 is always its own segment: its local sum gives the
        // impedance `Z_1` behind the acceleration of mass 1 without
        // cancellation ([`Transfer::eval_parts`]); a free end is a special
        // mass whose wall spring is 0.
        special.push(1);
        if chain.right().is_free() {
            special.push(n);
        }
        special.sort_unstable();
        special.dedup();
        // (m, d, g, kl, kr) of mass i: the uniform values, then the
        // defects' sites (a point site's power picks m, d or g; a spring
        // site is the spring left or right of its masses)
        let value = |i: usize| -> (f64, f64, f64, f64, f64) {
            let mut pt = [0.0, chain.d(), chain.mass()];
            let (mut kl, mut kr) = (chain.k(), chain.k());
            for def in chain.defects() {
                let site = def.site();
                match site.probe {
                    Probe::Point(at) if at == i => pt[site.power as usize] = def.value(),
                    Probe::Diff(at) if at + 1 == i => kl = def.value(),
                    Probe::Diff(at) if at == i => kr = def.value(),
                    _ => {}
                }
            }
            let [g, dd, m] = pt;
            if i == 1 && chain.left().is_free() {
                kl = 0.0;
            }
            if i == n && chain.right().is_free() {
                kr = 0.0;
            }
            (m, dd, g, kl, kr)
        };
        let mut segs = Vec::with_capacity(2 * special.len() + 1);
        let mut next = 1;
        for &i in &special {
            if i > next {
                segs.push(Seg::Run { l: next, r: i - 1 });
            }
            let (m, d, g, kl, kr) = value(i);
            segs.push(Seg::Special { i, m, d, g, kl, kr });
            next = i + 1;
        }
        if next <= n {
            segs.push(Seg::Run { l: next, r: n });
        }
        Transfer {
            n,
            k: chain.k(),
            mass: chain.mass(),
            d: chain.d(),
            gamma: chain.gamma(),
            segs,
        }
    }

    /// `X_o(s)` (1-based `o`, unchecked: validate `s` and `o` first). Returns a
    /// non-finite value only at a pole of the response.
    pub fn eval<T: Scalar>(&self, s: &T, o: usize) -> T {
        self.eval_parts(s, o, self.gamma).0
    }

    /// `X` at every index of `sites` (increasing, each in `1..=n`) in one
    /// sweep, the powers computed as [`Transfer::eval`] computes them.
    /// Unchecked, as [`Transfer::eval`].
    pub fn eval_sites_direct<T: Scalar>(&self, s: &T, sites: &[usize], gamma: f64) -> Vec<T> {
        let pw = Direct::new(s, self.k, self.mass, self.d);
        self.sweep(s, &pw, sites, gamma).0
    }

    /// `(X_o(s), Z_1(s))` for an impulse `gamma` on mass 1, where
    /// `Z_1 = D_1 - m_1 s^2 = d_1 s + kappa_0 + kappa_1 E_2 / (E_2 + kappa_1)` is
    /// the impedance mass 1 sees (its damper, its wall spring and the chain
    /// behind it), formed as a sum (no cancellation for real `s`). With it
    /// the acceleration of mass 1 after the impulse is
    /// `s^2 X_1 - gamma/m_1 = -Z_1 X_1 / m_1`. Unchecked, as [`Transfer::eval`].
    pub fn eval_parts<T: Scalar>(&self, s: &T, o: usize, gamma: f64) -> (T, T) {
        let pw = Direct::new(s, self.k, self.mass, self.d);
        let (x, z1) = self.sweep(s, &pw, &[o], gamma);
        (x[0].clone(), z1)
    }

    /// `X` at every index of `sites` (increasing, each in `1..=n`) and `Z_1`,
    /// in one sweep, with the powers of `q = e^{-lambda}` from `table` (built
    /// once per `s` for this chain's uniform `k`, `mass`, `d`: [`SweepTable`]).
    /// Unchecked, as [`Transfer::eval`]; a site out of order or range gives NaN.
    pub fn eval_sites<T: Scalar>(
        &self,
        s: &T,
        table: &SweepTable<T>,
        sites: &[usize],
        gamma: f64,
    ) -> (Vec<T>, T) {
        self.sweep(s, table, sites, gamma)
    }

    /// [`Transfer::eval_sites`] into `work` (`X` at the sites in
    /// [`SweepWork::out`]), returning `Z_1`: the same values, without
    /// allocating once `work` has grown.
    pub fn eval_sites_into<T: Scalar>(
        &self,
        s: &T,
        table: &SweepTable<T>,
        sites: &[usize],
        gamma: f64,
        work: &mut SweepWork<T>,
    ) -> T {
        self.sweep_into(s, table, sites, gamma, work)
    }

    /// Whether `table` was built for this chain's uniform part.
    pub fn fits<T: Scalar>(&self, table: &SweepTable<T>) -> bool {
        table.key == (self.k.to_bits(), self.mass.to_bits(), self.d.to_bits())
            && table.q.len() > 2 * self.n + 1
    }

    fn sweep<T: Scalar, P: Powers<T>>(
        &self,
        s: &T,
        pw: &P,
        sites: &[usize],
        gamma: f64,
    ) -> (Vec<T>, T) {
        let mut work = SweepWork {
            swept: Vec::with_capacity(self.segs.len()),
            out: Vec::with_capacity(sites.len()),
        };
        let z1 = self.sweep_into(s, pw, sites, gamma, &mut work);
        (work.out, z1)
    }

    fn sweep_into<T: Scalar, P: Powers<T>>(
        &self,
        s: &T,
        pw: &P,
        sites: &[usize],
        gamma: f64,
        work: &mut SweepWork<T>,
    ) -> T {
        let z1 = self.backward(s, pw, &mut work.swept);
        self.forward(pw, sites, gamma, &work.swept, &mut work.out);
        z1
    }

    /// The backward sweep: `E` at each segment's left index into `swept`
    /// (in the order of the segments); returns `Z_1`.
    #[inline]
    fn backward<T: Scalar, P: Powers<T>>(&self, s: &T, pw: &P, swept: &mut Vec<Swept<T>>) -> T {
        let k = self.k;
        let mut z1 = T::zero();
        let stat = pw.lam().is_zero();
        let one_m_q = pw.one_m_q(1);
        let one_m_q2 = pw.one_m_q(2);
        let em1k = pw.em1().scale(k);
        let ek = pw.e_lam().scale(k);
        let q = pw.q(1);
        // 1 - psi = (1 - q^2) / (E_{r+1} / (k e^lambda) + q (1 - q))
        //         = (1 - q^2) k e^lambda / (E_{r+1} + k e^lambda q (1 - q)):
        // one division, a sum of positive terms for real s
        let omp_num = one_m_q2.clone() * ek.clone();
        let omp_shift = ek * q.clone() * one_m_q;
        let s2 = s.clone() * s.clone();
        let local = |m: f64, d: f64| -> T { s2.scale(m) + s.scale(d) };
        swept.clear();
        // `E_{i+1}` of the index right of the current segment as a fraction
        // `(num, den)`; None at the wall.
        let mut right: Option<(T, T)> = None;
        for seg in self.segs.iter().rev() {
            match *seg {
                Seg::Special { i, m, d, g, kl, kr } => {
                    // kr E / (E + kr) with E = num / den: kr num / (num + kr den)
                    let tail = match &right {
                        None => T::from_f64(kr),
                        Some((en, ed)) => en.scale(kr) / (en.clone() + ed.scale(kr)),
                    };
                    if i == 1 {
                        z1 = s.scale(d) + T::from_f64(g + kl) + tail.clone();
                    }
                    let e = local(m, d) + T::from_f64(g) + tail;
                    swept.push(Swept {
                        e_num: e.clone(),
                        e_den: T::one(),
                        one_m_psi: T::zero(),
                    });
                    right = Some((e, T::one()));
                }
                Seg::Run { l, r } => {
                    let p = r + 1 - l;
                    let (en, ed, omp) = if stat {
                        // springs in series: E_l = 1 / (p/k + 1/E_{r+1})
                        let inv_right = match &right {
                            None => T::zero(),
                            Some((en, ed)) => ed.clone() / en.clone(),
                        };
                        let e = T::one() / (T::from_f64(p as f64 / k) + inv_right.clone());
                        // store c0 = k / E_{r+1} in `one_m_psi` for the static ratio
                        (e, T::one(), inv_right.scale(k))
                    } else {
                        let omp = match &right {
                            None => T::zero(),
                            // a special mass to the right: its E is a value
                            Some((e, _)) => omp_num.clone() / (e.clone() + omp_shift.clone()),
                        };
                        let psi = T::one() - omp.clone();
                        let num = T::one() + psi * pw.q(2 * p + 1);
                        (em1k.clone() * num, big_b(pw, p, &omp), omp)
                    };
                    swept.push(Swept {
                        e_num: en.clone(),
                        e_den: ed.clone(),
                        one_m_psi: omp,
                    });
                    right = Some((en, ed));
                }
            }
        }
        swept.reverse();
        z1
    }

    /// The forward substitution through the sites: `X` at each site into
    /// `out` (NaN for sites out of order or beyond `n`).
    #[inline]
    fn forward<T: Scalar, P: Powers<T>>(
        &self,
        pw: &P,
        sites: &[usize],
        gamma: f64,
        swept: &[Swept<T>],
        out: &mut Vec<T>,
    ) {
        let k = self.k;
        let stat = pw.lam().is_zero();
        out.clear();
        let mut next = 0;
        // X at the last index crossed, as `x / x_den` (a run without sites
        // leaves its division to the next special mass)
        let mut x = T::zero();
        let mut x_den = T::one();
        let mut kappa_left = 0.0; // spring joining the previous index to this segment
        for (idx, seg) in self.segs.iter().enumerate() {
            if next == sites.len() {
                break;
            }
            let sw = &swept[idx];
            match *seg {
                Seg::Special { i, kl, kr, .. } => {
                    let dd = sw.e_num.clone() + T::from_f64(kl);
                    x = if i == 1 {
                        T::from_f64(gamma) / dd
                    } else {
                        x.scale(kappa_left) / (x_den * dd)
                    };
                    x_den = T::one();
                    while next < sites.len() && sites[next] == i {
                        out.push(x.clone());
                        next += 1;
                    }
                    kappa_left = kr;
                }
                Seg::Run { l, r } => {
                    let inside = next < sites.len() && sites[next] >= l && sites[next] <= r;
                    if !stat && !inside && l != 1 {
                        (x, x_den) = cross_run(pw, k, sw, l, r, x.scale(kappa_left), x_den);
                        kappa_left = k;
                        continue;
                    }
                    // x_den is 1 here: runs follow special masses
                    let dd = sw.e_num.clone() / sw.e_den.clone() + T::from_f64(k);
                    let xl = if l == 1 {
                        T::from_f64(gamma) / dd
                    } else {
                        x.scale(kappa_left) / dd
                    };
                    while next < sites.len() && sites[next] >= l && sites[next] <= r {
                        out.push(xl.clone() * run_ratio(pw, stat, sw, l, r, sites[next]));
                        next += 1;
                    }
                    if next < sites.len() {
                        x = xl * run_ratio(pw, stat, sw, l, r, r);
                    }
                    kappa_left = k;
                }
            }
        }
        // sites out of order or beyond n
        out.resize(sites.len(), T::from_f64(f64::NAN));
    }
}

/// `B(p) = (1 - q^{2p}) + (1 - psi) q^{2p}`.
#[inline]
fn big_b<T: Scalar, P: Powers<T>>(pw: &P, p: usize, omp: &T) -> T {
    pw.one_m_q(2 * p) + omp.clone() * pw.q(2 * p)
}

/// Across a run `l..=r` without sites (not at the wall, `s` not static),
/// from `X_{l-1} kappa = xk` (over `x_den`): `X_r = X_{l-1} kappa q^{r-l}
/// B(1) / (D_l B(p_l))`, `D_l = E_l + k = (e_num + k e_den) / e_den`, as a
/// fraction: no division.
#[inline]
fn cross_run<T: Scalar, P: Powers<T>>(
    pw: &P,
    k: f64,
    sw: &Swept<T>,
    l: usize,
    r: usize,
    xk: T,
    x_den: T,
) -> (T, T) {
    let dd = sw.e_num.clone() + sw.e_den.scale(k);
    let mut xn = xk * sw.e_den.clone();
    let mut xd = x_den * dd;
    if r > l {
        xn = xn * pw.q(r - l) * big_b(pw, 1, &sw.one_m_psi);
        xd = xd * big_b(pw, r + 1 - l, &sw.one_m_psi);
    }
    (xn, xd)
}

/// `X_target / X_l` inside a run `l..=r`.
#[inline]
fn run_ratio<T: Scalar, P: Powers<T>>(
    pw: &P,
    stat: bool,
    sw: &Swept<T>,
    l: usize,
    r: usize,
    target: usize,
) -> T {
    let pl = r + 1 - l;
    let pt = r + 1 - target;
    if stat {
        // static displacement is linear: Y ~ p + k / E_{r+1}
        let c0 = sw.one_m_psi.clone();
        (T::from_f64(pt as f64) + c0.clone()) / (T::from_f64(pl as f64) + c0)
    } else if target == l {
        T::one()
    } else {
        pw.q(target - l) * big_b(pw, pt, &sw.one_m_psi) / big_b(pw, pl, &sw.one_m_psi)
    }
}

/// The powers of `q = e^{-lambda}` a sweep needs at one `s`.
trait Powers<T> {
    /// `lambda` (0 in the static limit).
    fn lam(&self) -> T;
    /// `q^j`.
    fn q(&self, j: usize) -> T;
    /// `1 - q^j`, without cancellation.
    fn one_m_q(&self, j: usize) -> T;
    /// `e^lambda - 1`.
    fn em1(&self) -> T;
    /// `e^lambda`.
    fn e_lam(&self) -> T;
}

/// `lambda(s)` of the uniform chain, as in `green.rs`.
fn lambda_of<T: Scalar>(s: &T, k: f64, mass: f64, d: f64) -> T {
    let inner = (s.scale(mass) + T::from_f64(d)).scale(1.0 / k);
    (s.sqrt() * inner.sqrt()).scale(0.5).asinh().scale(2.0)
}

/// Powers computed when asked (one exponential each).
struct Direct<T> {
    lam: T,
}

impl<T: Scalar> Direct<T> {
    fn new(s: &T, k: f64, mass: f64, d: f64) -> Direct<T> {
        Direct {
            lam: lambda_of(s, k, mass, d),
        }
    }
}

impl<T: Scalar> Powers<T> for Direct<T> {
    fn lam(&self) -> T {
        self.lam.clone()
    }
    fn q(&self, j: usize) -> T {
        self.lam.scale(-(j as f64)).exp()
    }
    fn one_m_q(&self, j: usize) -> T {
        -(self.lam.scale(-(j as f64))).expm1()
    }
    fn em1(&self) -> T {
        self.lam.expm1()
    }
    fn e_lam(&self) -> T {
        self.lam.exp()
    }
}

/// The powers `q^j` and `1 - q^j`, `j = 0..=2n+1`, of one `s` for a chain's
/// uniform `k`, `mass`, `d`, tabulated once so that every sweep at that `s`
/// (every candidate chain of a fit) is free of transcendental functions.
/// `q^j` by repeated multiplication (relative error about `j eps`), `1 - q^j`
/// by `(1 - q^j) + q^j (1 - q)`, a sum without cancellation for real `s`.
/// Memory: `2 (2n + 2)` values per `s`.
#[derive(Clone, Debug)]
pub struct SweepTable<T> {
    key: (u64, u64, u64),
    lam: T,
    em1: T,
    e_lam: T,
    q: Vec<T>,
    omq: Vec<T>,
}

impl<T: Scalar> SweepTable<T> {
    /// The table of `chain`'s uniform part at `s`.
    ///
    /// ```
    /// use springmass::{Chain, Defect, Complex64};
    /// use springmass::forward::transfer::{SweepTable, Transfer};
    /// let c = Chain::paper(30)?.with_defects([Defect::Mass { at: 4, m: 3.0 }, Defect::Spring { at: 20, k: 0.5 }])?;
    /// let s = Complex64::new(0.05, 0.8);
    /// let t = Transfer::new(&c);
    /// let table = SweepTable::new(&c, s);
    /// let (x, _) = t.eval_sites(&s, &table, &[1, 4, 21], 1.0);
    /// for (xi, o) in x.iter().zip([1, 4, 21]) {
    ///     assert!((xi - t.eval(&s, o)).norm() < 1e-12 * xi.norm());
    /// }
    /// # Ok::<(), springmass::Error>(())
    /// ```
    pub fn new(chain: &Chain, s: T) -> SweepTable<T> {
        let (k, mass, d) = (chain.k(), chain.mass(), chain.d());
        let lam = lambda_of(&s, k, mass, d);
        let jmax = 2 * chain.n() + 1;
        let q1 = lam.scale(-1.0).exp();
        let omq1 = -(lam.scale(-1.0)).expm1();
        let mut q = Vec::with_capacity(jmax + 1);
        let mut omq = Vec::with_capacity(jmax + 1);
        q.push(T::one());
        omq.push(T::zero());
        for j in 1..=jmax {
            // re-anchor every 64 powers with the exact exponential
            if j % 64 == 0 {
                q.push(lam.scale(-(j as f64)).exp());
                omq.push(-(lam.scale(-(j as f64))).expm1());
            } else {
                let (qp, op) = (q[j - 1].clone(), omq[j - 1].clone());
                omq.push(op + qp.clone() * omq1.clone());
                q.push(qp * q1.clone());
            }
        }
        SweepTable {
            key: (k.to_bits(), mass.to_bits(), d.to_bits()),
            em1: lam.expm1(),
            e_lam: lam.exp(),
            lam,
            q,
            omq,
        }
    }
}

impl<T: Scalar> Powers<T> for SweepTable<T> {
    fn lam(&self) -> T {
        self.lam.clone()
    }
    fn q(&self, j: usize) -> T {
        match self.q.get(j) {
            Some(v) => v.clone(),
            None => self.lam.scale(-(j as f64)).exp(),
        }
    }
    fn one_m_q(&self, j: usize) -> T {
        match self.omq.get(j) {
            Some(v) => v.clone(),
            None => -(self.lam.scale(-(j as f64))).expm1(),
        }
    }
    fn em1(&self) -> T {
        self.em1.clone()
    }
    fn e_lam(&self) -> T {
        self.e_lam.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::forward::tridiag;
    use crate::scenes;
    use crate::Defect;
    use num_complex::Complex64;

    #[test]
    fn tabulated_sweep_matches_the_direct_one_at_every_site() {
        use crate::chain::Boundary;
        let mut chains = vec![
            Chain::paper(1).unwrap(),
            scenes::paper_with(300, "mass:1:1e3 mass:150:1e-3 spring:299:3 damper:77:2").unwrap(),
            Chain::paper(20)
                .unwrap()
                .with_d(0.0)
                .unwrap()
                .with_defect(Defect::Mass { at: 8, m: 5.0 })
                .unwrap(),
        ];
        chains.push(
            chains[1]
                .clone()
                .with_boundaries(Boundary::Free, Boundary::Free)
                .unwrap(),
        );
        let nodes = [
            Complex64::new(1e-6, 0.0),
            Complex64::new(0.3, 0.0),
            Complex64::new(0.05, 1.7),
            Complex64::new(2.0, -40.0),
            Complex64::new(1e4, 3.0),
        ];
        for c in &chains {
            let t = Transfer::new(c);
            let sites: Vec<usize> = (1..=c.n()).collect();
            for &s in &nodes {
                let table = SweepTable::new(c, s);
                assert!(t.fits(&table));
                let (x, z1) = t.eval_sites(&s, &table, &sites, c.gamma());
                let (_, z1d) = t.eval_parts(&s, 1, c.gamma());
                assert!((z1 - z1d).norm() <= 1e-12 * z1d.norm() + 1e-300);
                for (o, xo) in sites.iter().zip(&x) {
                    let d = t.eval(&s, *o);
                    if !d.is_finite() || d.norm() < 1e-280 {
                        continue;
                    }
                    assert!(
                        (xo - d).norm() <= 1e-11 * d.norm(),
                        "n = {}, s = {s}, o = {o}: {xo} vs {d}",
                        c.n()
                    );
                }
            }
        }
    }

    #[test]
    fn matches_tridiagonal_everywhere_small() {
        let chains = [
            Chain::paper(1).unwrap(),
            Chain::paper(7).unwrap(),
            scenes::paper_with(
                9,
                "mass:1:1e6 spring:0:0.2 spring:4:3 damper:5:0 mass:9:1e-3 spring:9:50",
            )
            .unwrap(),
            Chain::new(2)
                .unwrap()
                .with_defect(Defect::Mass { at: 1, m: 1e6 })
                .unwrap(),
        ];
        for c in &chains {
            for s in [0.0, 1e-7, 0.3, 7.0, 1e4] {
                matches_tridiagonal_at(c, s, 1e-13);
            }
            for s in [
                Complex64::new(0.5, 2.0),
                Complex64::new(0.01, 1.1),
                Complex64::new(3.0, -80.0),
            ] {
                matches_tridiagonal_at(c, s, 1e-11);
            }
        }
    }

    /// `Transfer::eval` at every mass of `c` against the tridiagonal solve
    /// at `s`, within `rel` relative (plus 1e-300).
    fn matches_tridiagonal_at<T: Scalar + std::fmt::Display>(c: &Chain, s: T, rel: f64) {
        let r = tridiag::solve_all(c, s.clone()).unwrap();
        let t = Transfer::new(c);
        for (o, ro) in (1..=c.n()).zip(&r) {
            let x = t.eval(&s, o);
            assert!(
                (x.clone() - ro.clone()).magnitude() <= rel * ro.magnitude() + 1e-300,
                "{c:?} s={s} o={o}: {x} vs {ro}"
            );
        }
    }
}
