//! The residual of one position set at every node of a
//! [`Misfit`](super::Misfit) ([`SetTable`]): the gathered Green's entries
//! with a pivoted `k x k` solve per node (the general path, [`Num`] over
//! `f64` and `Complex64`), and the folded form of one or two defects on the
//! real axis (a ratio of bilinear forms per node, over independent lanes).

use crate::detect::misfit::quadrature::GreenTable;
use num_complex::Complex64;
use std::ops::{Add, Div, Mul, Neg, Sub};

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

/// Structure-of-arrays Green's entries of one position set at every node,
/// padded to a multiple of 4 nodes (padding has weight 0).
#[derive(Clone, Debug)]
pub(super) struct Gathered<T> {
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
    pub(super) fn new(
        g: &GreenTable<T>,
        s2: &[T],
        d: &[T],
        w: &[f64],
        pos: &[usize],
    ) -> Gathered<T> {
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

/// Largest `n * nodes` for which [`Misfit::new`](super::Misfit::new) tables `G_1j` and `G_jj`
/// at every node (two arrays of that many values, 16 MB at the limit):
/// gathering a folded set then reads them instead of forming them from the
/// Green's table.
const MAX_ROWS: usize = 1 << 20;

/// `G_1j(s_q)` and `G_jj(s_q)`, `[(j - 1) * nodes + q]`, and the roots
/// `(sqrt(w_q), w_q^(1/4))` of the weights.
#[derive(Clone, Debug)]
pub(super) struct Rows {
    g1: Vec<f64>,
    gd: Vec<f64>,
    roots: Vec<(f64, f64)>,
}

impl Rows {
    pub(super) fn new(g: &GreenTable<f64>, w: &[f64]) -> Option<Rows> {
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
pub(super) struct Folded {
    k: usize,
    np: usize,
    gamma: f64,
    /// `c[row * np + q]`, rows as the constants above.
    c: Vec<f64>,
}

/// `G_11, G_1a, G_aa, G_1b, G_bb` per node for the positions `a` and `b`
/// of a [`Folded`] set: slices of the tabled rows, else gathered from the
/// table into `store`; the `b` columns zero for one defect.
fn green_columns<'a>(
    g: &GreenTable<f64>,
    rows: Option<&'a Rows>,
    a: usize,
    b: Option<usize>,
    store: &'a mut Vec<f64>,
) -> [&'a [f64]; 5] {
    let nq = g.len();
    match rows {
        Some(r) => {
            let column = |j: usize| -> (&'a [f64], &'a [f64]) {
                (&r.g1[(j - 1) * nq..j * nq], &r.gd[(j - 1) * nq..j * nq])
            };
            let (g11, _) = column(1);
            let (g1a, gaa) = column(a);
            let (g1b, gbb) = match b {
                Some(b) => column(b),
                None => {
                    store.resize(nq, 0.0);
                    let zeros: &'a Vec<f64> = store;
                    (&zeros[..], &zeros[..])
                }
            };
            [g11, g1a, gaa, g1b, gbb]
        }
        None => {
            let col = |i: usize, j: usize| (0..nq).map(move |q| g.entry(q, i, j));
            store.extend(col(1, 1));
            store.extend(col(1, a));
            store.extend(col(a, a));
            match b {
                Some(b) => {
                    store.extend(col(1, b));
                    store.extend(col(b, b));
                }
                None => store.resize(5 * nq, 0.0),
            }
            let v: &'a Vec<f64> = store;
            let part = |i: usize| &v[i * nq..(i + 1) * nq];
            [part(0), part(1), part(2), part(3), part(4)]
        }
    }
}

impl Folded {
    pub(super) fn new(
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
        let mut store = Vec::new();
        let [g11, g1a, gaa, g1b, gbb] = green_columns(g, rows, a, b, &mut store);
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
/// [`Gathered::eval_general`]: the same elimination (and the same pivot
/// step, `crate::linalg::pivot`) as
/// [`crate::linalg::solve_in_place`] (same pivots; the result agrees to
/// rounding, each pivot being divided once and its reciprocal multiplied),
/// kept separate because it is the inner loop of every residual with
/// `k >= 3` or on the Bromwich line: over [`Num`] (`Copy`, squared modulus
/// for the pivot search, no zero-multiplier branch, one complex division
/// per pivot instead of one per row) it is faster than the shared `Scalar`
/// version (`cargo bench --bench fit -- residual_general`).
fn small_solve<T: Num>(a: &mut [T], b: &mut [T], k: usize) -> bool {
    for col in 0..k {
        if !crate::linalg::pivot(a, b, k, col, |v: &T| v.norm2()) {
            return false;
        }
        // one division per pivot: its reciprocal serves the rows below and
        // the back substitution (the diagonal then holds it)
        let inv = T::re(1.0) / a[col * k + col];
        a[col * k + col] = inv;
        for r in col + 1..k {
            let f = a[r * k + col] * inv;
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
        b[row] = acc * a[row * k + row];
    }
    true
}

#[derive(Clone, Debug)]
pub(super) enum Body {
    Folded(Folded),
    Real(Gathered<f64>),
    Complex(Gathered<Complex64>),
}

/// The Green's entries of one position set at every node of a [`Misfit`](super::Misfit):
/// evaluating the residual for given masses costs only the `k x k` solves
/// (one or two defects on the real axis: one ratio of bilinear forms per node).
#[derive(Clone, Debug)]
pub struct SetTable {
    pub(super) body: Body,
    /// Slot whose position is the observed mass 1 (then `X_1 = gamma z_l`).
    pub(super) obs: Option<usize>,
    pub(super) gamma: f64,
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
    /// [`Misfit::set`](super::Misfit::set)) rather than on the general path.
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
impl SetTable {
    /// The mass changes `dm1 = -1 / D1` (the other mass unchanged) at which
    /// each node's folded denominator vanishes; `None` on the general path.
    pub(super) fn folded_poles(&self) -> Option<Vec<f64>> {
        let Body::Folded(f) = &self.body else {
            return None;
        };
        Some((0..f.np).map(|q| -1.0 / f.c[D1 * f.np + q]).collect())
    }
}
