//! The Laplace-domain model of one defect position set as a rational
//! function of its defect values, for fitting many sets against the same
//! data cheaply (the screens and the coarse pass of
//! `detect::fit::general`).
//!
//! With `G = Z_0(s)^{-1}` the uniform chain's Green's function and the set's
//! defects `c_l(s) = (v_l - u_l) s^{p_l}` on probes `p_l` (the Woodbury form
//! of [`crate::forward`], `A_lm = p_l^T G p_m`, `a_l = p_l^T G e_o`,
//! `b_l = p_l^T G e_1` for the observed mass `o`),
//!
//! `X_o = gamma (G_o1 - a^T C (I + A C)^{-1} b) = gamma num(c) / den(c)`,
//!
//! `den = det(I + A C)` and `num = det [[G_o1, a^T C], [b, I + A C]]`, both
//! multilinear in the `c_l`: `den = sum_S det(A_SS) prod_{l in S} c_l` over
//! the subsets `S` of the set, `num` the same with the bordered minors
//! `det [[G_o1, a_S^T], [b_S, A_SS]]`. Per node the `2 * 2^k` coefficients
//! (the powers `s^{p_l}`, `gamma` and the observable's factor folded in)
//! are formed once per set; a residual then costs `2^k` products per node
//! and the whitening, and its Jacobian in the values is the quotient rule
//! of the same sums. The general path ([`LaplaceObs::residuals`], one
//! transfer sweep per node and evaluation) gives the same values to rounding
//! (unit tests); being a ratio of determinants the form loses relative
//! accuracy only where `den` nearly vanishes (a pole of the set's chain at
//! a node), which a whitened misfit of noisy data does not resolve anyway.
//!
//! Applies to data whose model is the tabulated observable
//! (displacement or velocity after the impulse,
//! any observable with a measured force) and sets of at most [`MAX_K`]
//! defects.

use crate::chain::{Chain, Probe, Site};
use crate::detect::data::laplace::LaplaceObs;
use crate::error::{Error, Result};
use crate::green::{Green, ProbeFactors};
use crate::time::series::stacked_rows;
use nalgebra::DMatrix;
use num_complex::Complex64;
use std::collections::HashMap;

/// Largest set handled (`2^k` coefficients per node for num and den).
pub const MAX_K: usize = 4;

/// Per-node Green's data of the uniform chain shared by every set fitted to
/// one [`LaplaceObs`]: each probe's factors and its entries with the
/// observed mass and mass 1.
pub struct SetTables<'a> {
    obs: &'a LaplaceObs,
    greens: Vec<Green<Complex64>>,
    /// `gamma` times the observable's factor at each node.
    scale: Vec<Complex64>,
    /// `G_o1` at each node.
    g_o1: Vec<Complex64>,
    probes: HashMap<Probe, usize>,
    data: Vec<ProbeData>,
    /// `p_i^T G p_j` of every pair of tabled probes at every node,
    /// `[(q P + i) P + j]` for `P` probes, when small enough
    /// ([`MAX_PAIR_TABLE`]; otherwise formed per set).
    pairs: Option<Vec<Complex64>>,
    /// The stacked real layout of the residual ([`stacked_rows`]).
    rows: Vec<(usize, bool)>,
    /// `s_q^p` for the powers of the sites, `[p * nq + q]`, `p = 0..=2`.
    powers: Vec<Complex64>,
    /// `sqrt(w_q)`: the factors of the residuals of unwhitened data.
    root_weights: Vec<f64>,
    /// The observed mass.
    at: usize,
}

/// Largest pair table of [`SetTables`] (entries; 16 bytes each).
const MAX_PAIR_TABLE: usize = 1 << 21;

/// One probe at every node: its factors, `p^T G e_o`, `p^T G e_1`, `p^T G p`.
struct ProbeData {
    factors: Vec<ProbeFactors<Complex64>>,
    a: Vec<Complex64>,
    b: Vec<Complex64>,
    diag: Vec<Complex64>,
}

impl<'a> SetTables<'a> {
    /// The tables of `obs` for the uniform part of `chain` and the probes of
    /// `sites`; `None` when the form does not apply (the observable is not
    /// the tabulated one, or a node is singular for the uniform chain).
    /// `pair_uses`: how many probe pairs the sets to come hold in all (the
    /// table of every pair is built when that is more than the pairs of
    /// distinct probes; otherwise each set forms its own).
    pub fn new(
        obs: &'a LaplaceObs,
        chain: &Chain,
        sites: impl IntoIterator<Item = Probe>,
        pair_uses: usize,
    ) -> Option<SetTables<'a>> {
        if !obs.tabulable() || !obs.others().is_empty() {
            return None;
        }
        let uniform = chain.uniform();
        let at = obs.sensor().at;
        let n = uniform.n();
        if at == 0 || at > n {
            return None;
        }
        let s = obs.nodes();
        let greens: Vec<Green<Complex64>> =
            s.iter().map(|&z| Green::of_chain(&uniform, z)).collect();
        if greens.iter().any(|g| g.is_singular()) {
            return None;
        }
        let gamma = uniform.gamma();
        let scale = (0..s.len()).map(|q| obs.factor(q) * gamma).collect();
        let e_o: Vec<ProbeFactors<Complex64>> =
            greens.iter().map(|g| g.factors(Probe::Point(at))).collect();
        let e_1: Vec<ProbeFactors<Complex64>> =
            greens.iter().map(|g| g.factors(Probe::Point(1))).collect();
        let g_o1 = greens
            .iter()
            .zip(e_o.iter().zip(&e_1))
            .map(|(g, (o, one))| g.pair(o, one))
            .collect();
        let (probes, data) = probe_data(&greens, sites, &e_o, &e_1, at);
        let pairs = pair_table(&greens, &data, pair_uses);
        Some(SetTables {
            obs,
            greens,
            scale,
            g_o1,
            probes,
            data,
            pairs,
            rows: stacked_rows(s),
            root_weights: obs.weights().iter().map(|w| w.sqrt()).collect(),
            powers: (0..=2)
                .flat_map(|p| s.iter().map(move |z| z.powu(p)))
                .collect(),
            at,
        })
    }

    /// The model of one set: `sites[l]` with its uniform value `uniform[l]`;
    /// the values of the slots with `fixed[l] = Some(v)` are held, the others
    /// are the parameters in slot order. `None` for a probe not tabled, more
    /// than [`MAX_K`] sites, or a coefficient that overflows.
    #[allow(clippy::needless_range_loop)] // bit loops over the slots
    pub fn set(
        &self,
        sites: &[Site],
        uniform: &[f64],
        fixed: &[Option<f64>],
    ) -> Option<SetModel<'_>> {
        let k = sites.len();
        if k == 0
            || k > MAX_K
            || uniform.len() != k
            || fixed.len() != k
            || sites.iter().any(|st| st.power > 2)
        {
            return None;
        }
        let idx: Vec<usize> = sites
            .iter()
            .map(|st| self.probes.get(&st.probe).copied())
            .collect::<Option<_>>()?;
        let data: Vec<&ProbeData> = idx.iter().map(|&i| &self.data[i]).collect();
        let nq = self.greens.len();
        let np = self.data.len();
        let subsets = 1usize << k;
        let mut num = vec![Complex64::new(0.0, 0.0); subsets * nq];
        let mut den = vec![Complex64::new(0.0, 0.0); subsets * nq];
        let zero = Complex64::new(0.0, 0.0);
        let mut a = [zero; MAX_K * MAX_K];
        let mut pw = [zero; MAX_K];
        for q in 0..nq {
            for l in 0..k {
                a[l * k + l] = data[l].diag[q];
                for m in l + 1..k {
                    let v = match &self.pairs {
                        Some(t) => t[(q * np + idx[l]) * np + idx[m]],
                        None => self.greens[q].pair(&data[l].factors[q], &data[m].factors[q]),
                    };
                    a[l * k + m] = v;
                    a[m * k + l] = v;
                }
                pw[l] = if sites[l].is_monomial() {
                    self.powers[sites[l].power as usize * nq + q]
                } else {
                    sites[l].poly_at(&self.obs.nodes()[q])
                };
            }
            self.subset_minors(q, &a[..k * k], &pw[..k], &data, &mut num, &mut den);
        }
        if num
            .iter()
            .chain(&den)
            .any(|z| !(z.re.is_finite() && z.im.is_finite()))
        {
            return None;
        }
        let free: Vec<usize> = (0..k).filter(|&l| fixed[l].is_none()).collect();
        Some(SetModel {
            tables: self,
            k,
            nq,
            num,
            den,
            uniform: uniform.to_vec(),
            fixed: fixed.to_vec(),
            free,
        })
    }

    /// At node `q`, for every subset `S` of the `k` sites (capacitance
    /// `a`, `k x k`; `pw` the sites' `s^p`): the denominator `det(A_SS)` and
    /// the numerator, the bordered determinant
    /// `[[G_o1, a_S^T], [b_S, A_SS]]`, each times the product of the
    /// members' `s^p` (the numerator also times the node's scale), into
    /// `num[set * nq + q]`, `den[set * nq + q]`.
    #[inline]
    fn subset_minors(
        &self,
        q: usize,
        a: &[Complex64],
        pw: &[Complex64],
        data: &[&ProbeData],
        num: &mut [Complex64],
        den: &mut [Complex64],
    ) {
        let k = pw.len();
        let nq = self.greens.len();
        let zero = Complex64::new(0.0, 0.0);
        let mut minor = [zero; MAX_K * MAX_K];
        let mut bordered = [zero; (MAX_K + 1) * (MAX_K + 1)];
        let mut members = [0usize; MAX_K];
        for set in 0..1usize << k {
            let mut m = 0;
            let mut factor = Complex64::new(1.0, 0.0);
            for (l, &p) in pw.iter().enumerate() {
                if set >> l & 1 == 1 {
                    members[m] = l;
                    m += 1;
                    factor *= p;
                }
            }
            let members = &members[..m];
            let b = m + 1;
            bordered[0] = self.g_o1[q];
            for (i, &l) in members.iter().enumerate() {
                bordered[i + 1] = data[l].a[q];
                bordered[(i + 1) * b] = data[l].b[q];
                for (j, &r) in members.iter().enumerate() {
                    minor[i * m + j] = a[l * k + r];
                    bordered[(i + 1) * b + j + 1] = a[l * k + r];
                }
            }
            den[set * nq + q] = det(&mut minor[..m * m], m) * factor;
            num[set * nq + q] = det(&mut bordered[..b * b], b) * factor * self.scale[q];
        }
    }

    /// The observed mass.
    pub fn observed(&self) -> usize {
        self.at
    }
}

/// The data of every distinct probe of `sites` at every node, and each
/// probe's index in them.
fn probe_data(
    greens: &[Green<Complex64>],
    sites: impl IntoIterator<Item = Probe>,
    e_o: &[ProbeFactors<Complex64>],
    e_1: &[ProbeFactors<Complex64>],
    at: usize,
) -> (HashMap<Probe, usize>, Vec<ProbeData>) {
    let mut probes = HashMap::new();
    let mut data = Vec::new();
    for p in sites {
        if probes.contains_key(&p) {
            continue;
        }
        let factors: Vec<ProbeFactors<Complex64>> = greens.iter().map(|g| g.factors(p)).collect();
        let pair = |other: &[ProbeFactors<Complex64>]| -> Vec<Complex64> {
            greens
                .iter()
                .zip(factors.iter().zip(other))
                .map(|(g, (f, o))| g.pair(f, o))
                .collect()
        };
        let a = pair(e_o);
        let b = if at == 1 { a.clone() } else { pair(e_1) };
        let diag = pair(&factors);
        probes.insert(p, data.len());
        data.push(ProbeData {
            factors,
            a,
            b,
            diag,
        });
    }
    (probes, data)
}

/// `p_i^T G p_j` of every probe pair at every node, `[(q * np + i) * np + j]`,
/// when the sets to come use more pairs (`pair_uses`) than the distinct
/// probes have and the table fits [`MAX_PAIR_TABLE`].
fn pair_table(
    greens: &[Green<Complex64>],
    data: &[ProbeData],
    pair_uses: usize,
) -> Option<Vec<Complex64>> {
    let np = data.len();
    let nq = greens.len();
    if !(np * np * nq <= MAX_PAIR_TABLE && pair_uses > np * np.saturating_sub(1) / 2) {
        return None;
    }
    let mut t = vec![Complex64::new(0.0, 0.0); np * np * nq];
    for (q, g) in greens.iter().enumerate() {
        for i in 0..np {
            t[(q * np + i) * np + i] = data[i].diag[q];
            for j in i + 1..np {
                let v = g.pair(&data[i].factors[q], &data[j].factors[q]);
                t[(q * np + i) * np + j] = v;
                t[(q * np + j) * np + i] = v;
            }
        }
    }
    Some(t)
}

/// Determinant of the `m x m` row-major `a`: by the cofactor formulas up to
/// `m = 3`, by Gaussian elimination with partial pivoting beyond (destroys
/// `a`); 1 for `m = 0`.
fn det(a: &mut [Complex64], m: usize) -> Complex64 {
    match m {
        0 => Complex64::new(1.0, 0.0),
        1 => a[0],
        2 => a[0] * a[3] - a[1] * a[2],
        3 => {
            a[0] * (a[4] * a[8] - a[5] * a[7]) - a[1] * (a[3] * a[8] - a[5] * a[6])
                + a[2] * (a[3] * a[7] - a[4] * a[6])
        }
        _ => det_elimination(a, m),
    }
}

/// Determinant by Gaussian elimination with partial pivoting (destroys `a`).
fn det_elimination(a: &mut [Complex64], m: usize) -> Complex64 {
    let mut d = Complex64::new(1.0, 0.0);
    for c in 0..m {
        let mut piv = c;
        for r in c + 1..m {
            if a[r * m + c].norm_sqr() > a[piv * m + c].norm_sqr() {
                piv = r;
            }
        }
        if a[piv * m + c] == Complex64::new(0.0, 0.0) {
            return Complex64::new(0.0, 0.0);
        }
        if piv != c {
            for j in 0..m {
                a.swap(c * m + j, piv * m + j);
            }
            d = -d;
        }
        let p = a[c * m + c];
        d *= p;
        for r in c + 1..m {
            let f = a[r * m + c] / p;
            for j in c + 1..m {
                let v = a[c * m + j];
                a[r * m + j] -= f * v;
            }
        }
    }
    d
}

/// One position set's model on its [`SetTables`]: the residuals of
/// [`LaplaceObs::residuals`] (whitened, or weighted by the nodes' weights)
/// and their Jacobian as functions of the values of its free slots.
pub struct SetModel<'t> {
    tables: &'t SetTables<'t>,
    k: usize,
    nq: usize,
    /// `num[S * nq + q]`, `den[S * nq + q]`: the coefficient of subset `S`
    /// (bit `l` for slot `l`) at node `q`.
    num: Vec<Complex64>,
    den: Vec<Complex64>,
    uniform: Vec<f64>,
    fixed: Vec<Option<f64>>,
    free: Vec<usize>,
}

impl SetModel<'_> {
    /// The value changes `v_l - u_l` of every slot for the parameters `theta`.
    fn deltas(&self, theta: &[f64]) -> Result<Vec<f64>> {
        if theta.len() != self.free.len() {
            return Err(Error::invalid(
                "theta",
                theta.len(),
                format!("{} values", self.free.len()),
            ));
        }
        let mut it = theta.iter();
        Ok(self
            .fixed
            .iter()
            .zip(&self.uniform)
            .map(|(fixed, u)| fixed.unwrap_or_else(|| *it.next().expect("one per free slot")) - u)
            .collect())
    }

    /// `prod_{l in S} delta_l` for every subset `S`.
    fn products(&self, delta: &[f64]) -> Vec<f64> {
        let subsets = 1usize << self.k;
        let mut p = vec![1.0; subsets];
        for (set, v) in p.iter_mut().enumerate().skip(1) {
            let low = set.trailing_zeros() as usize;
            // the product of the subset without its lowest slot, times it
            *v = delta[low];
            let rest = set & (set - 1);
            if rest != 0 {
                *v *= products_of(delta, rest);
            }
        }
        p
    }

    /// `num` and `den` at every node.
    fn num_den(&self, prod: &[f64]) -> (Vec<Complex64>, Vec<Complex64>) {
        let nq = self.nq;
        let mut num = self.num[..nq].to_vec();
        let mut den = self.den[..nq].to_vec();
        for (set, &p) in prod.iter().enumerate().skip(1) {
            let (cn, cd) = (
                &self.num[set * nq..(set + 1) * nq],
                &self.den[set * nq..(set + 1) * nq],
            );
            for q in 0..nq {
                num[q] += cn[q] * p;
                den[q] += cd[q] * p;
            }
        }
        (num, den)
    }

    /// The stacked residual vector of model values `x` (the layout of
    /// [`LaplaceObs::residuals`]), whitened or weighted.
    fn residual_of(&self, x: &[Complex64], columns: usize) -> Vec<f64> {
        let obs = self.tables.obs;
        let s = obs.nodes();
        match obs.whitener() {
            Some(w) => {
                let rows = &self.tables.rows;
                let mut stacked = Vec::with_capacity(rows.len() * columns);
                for c in 0..columns {
                    let col = &x[c * self.nq..(c + 1) * self.nq];
                    stacked.extend(
                        rows.iter()
                            .map(|&(q, im)| if im { col[q].im } else { col[q].re }),
                    );
                }
                w.apply(&stacked, columns)
            }
            None => {
                let mut out = Vec::new();
                for c in 0..columns {
                    let col = &x[c * self.nq..(c + 1) * self.nq];
                    for (q, e) in col.iter().enumerate() {
                        let e = e * self.tables.root_weights[q];
                        out.push(e.re);
                        if s[q].im != 0.0 {
                            out.push(e.im);
                        }
                    }
                }
                out
            }
        }
    }
}

/// `prod_{l in set} delta_l`.
fn products_of(delta: &[f64], set: usize) -> f64 {
    let mut p = 1.0;
    for (l, d) in delta.iter().enumerate() {
        if set >> l & 1 == 1 {
            p *= d;
        }
    }
    p
}

impl SetModel<'_> {
    /// The residuals of [`LaplaceObs::residuals`] for the set with the values
    /// `theta` of its free slots (slot order).
    ///
    /// # Errors
    /// `theta` of another length than the free slots.
    pub fn residuals(&self, theta: &[f64]) -> Result<Vec<f64>> {
        let delta = self.deltas(theta)?;
        let (num, den) = self.num_den(&self.products(&delta));
        let values = self.tables.obs.values();
        let diff: Vec<Complex64> = (0..self.nq).map(|q| num[q] / den[q] - values[q]).collect();
        Ok(self.residual_of(&diff, 1))
    }

    /// Their Jacobian in `theta` (one column per free slot).
    ///
    /// # Errors
    /// As [`SetModel::residuals`].
    pub fn jacobian(&self, theta: &[f64]) -> Result<DMatrix<f64>> {
        let delta = self.deltas(theta)?;
        let prod = self.products(&delta);
        let (num, den) = self.num_den(&prod);
        let nq = self.nq;
        let p = self.free.len();
        let mut cols = vec![Complex64::new(0.0, 0.0); p * nq];
        for (c, &l) in self.free.iter().enumerate() {
            let bit = 1usize << l;
            let col = &mut cols[c * nq..(c + 1) * nq];
            // d/d delta_l: the subsets holding l, their product without l
            for set in (0..1usize << self.k).filter(|s| s & bit != 0) {
                let w = prod[set & !bit];
                let (cn, cd) = (
                    &self.num[set * nq..(set + 1) * nq],
                    &self.den[set * nq..(set + 1) * nq],
                );
                for q in 0..nq {
                    // accumulate d num den - num d den
                    col[q] += (cn[q] * den[q] - num[q] * cd[q]) * w;
                }
            }
            for q in 0..nq {
                col[q] /= den[q] * den[q];
            }
        }
        let r = self.residual_of(&cols, p);
        let m = r.len() / p.max(1);
        Ok(DMatrix::from_vec(m, p, r))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chain::{Boundary, Defect};
    use crate::detect::data::measurement::Sensor;
    use crate::forward::Observable;

    /// Whitened and weighted observations of `truth` at mixed nodes.
    fn observations(truth: &Chain, whitened: bool) -> LaplaceObs {
        let s: Vec<Complex64> = (0..12)
            .map(|q| {
                if q % 3 == 0 {
                    Complex64::new(0.05 + 0.4 * q as f64, 0.0)
                } else {
                    Complex64::new(0.05, 0.35 * q as f64)
                }
            })
            .collect();
        let obs = LaplaceObs::exact(truth, s.clone(), vec![1.0; s.len()]).unwrap();
        if !whitened {
            return obs;
        }
        let m = crate::time::series::stacked_rows(&s).len();
        // a dense, well-conditioned whitening matrix
        let w = DMatrix::from_fn(m, m, |i, j| {
            if i == j {
                2.0
            } else {
                0.3 / (1.0 + (i as f64 - j as f64).abs())
            }
        });
        LaplaceObs::whitened(s, obs.values().to_vec(), w).unwrap()
    }

    fn check(truth: &Chain, base: &Chain, sets: &[Vec<Defect>], obs: &LaplaceObs) {
        // with the table of every pair and with pairs formed per set
        for uses in [0, usize::MAX] {
            let probes = sets.iter().flatten().map(|d| base.site(d).probe);
            let tables = SetTables::new(obs, base, probes, uses).expect("applies");
            assert_eq!(tables.pairs.is_some(), uses > 0);
            check_sets(truth, base, sets, obs, &tables);
        }
    }

    fn check_sets(
        truth: &Chain,
        base: &Chain,
        sets: &[Vec<Defect>],
        obs: &LaplaceObs,
        tables: &SetTables<'_>,
    ) {
        for defects in sets {
            let sites: Vec<Site> = defects.iter().map(|d| base.site(d)).collect();
            let uniform: Vec<f64> = defects.iter().map(|d| d.base_value(base)).collect();
            let fixed = vec![None; defects.len()];
            let model = tables.set(&sites, &uniform, &fixed).expect("a model");
            let theta: Vec<f64> = defects.iter().map(|d| d.value()).collect();
            let chain = base.uniform().with_defects(defects.clone()).unwrap();
            let want = obs.residuals(&chain).unwrap();
            let got = model.residuals(&theta).unwrap();
            let scale = want.iter().fold(1e-300f64, |a, v| a.max(v.abs()));
            for (g, w) in got.iter().zip(&want) {
                assert!(
                    (g - w).abs() <= 1e-10 * scale,
                    "{defects:?} (truth {:?}): {g} vs {w}",
                    truth.defects()
                );
            }
            assert_eq!(got.len(), want.len());
            // the Jacobian against the general path's
            let params: Vec<crate::sensitivity::Param> = (0..defects.len())
                .map(crate::sensitivity::Param::Defect)
                .collect();
            let jw = obs.jacobian(&chain, &params).unwrap();
            let jg = model.jacobian(&theta).unwrap();
            assert_eq!(jw.shape(), jg.shape());
            let js = jw.iter().fold(1e-300f64, |a, v| a.max(v.abs()));
            for (g, w) in jg.iter().zip(jw.iter()) {
                assert!(
                    (g - w).abs() <= 1e-9 * js,
                    "{defects:?} jacobian {g} vs {w}"
                );
            }
        }
    }

    #[test]
    fn equals_the_general_path_for_every_kind() {
        let truth = crate::scenes::paper_with(9, "mass:3:2.5 spring:6:0.6").unwrap();
        let base = truth.uniform();
        let sets = vec![
            vec![Defect::Mass { at: 1, m: 3.0 }],
            vec![Defect::Mass { at: 9, m: 0.4 }],
            crate::scenes::defects("mass:3:2.0 mass:7:0.5").unwrap(),
            crate::scenes::defects("mass:7:2.0 mass:3:0.5").unwrap(),
            crate::scenes::defects("spring:0:1.7 mass:5:4.0").unwrap(),
            crate::scenes::defects("spring:9:0.2 spring:4:3.0").unwrap(),
            crate::scenes::defects("damper:2:0.9 spring:2:1.3").unwrap(),
            crate::scenes::defects("ground:8:0.3 mass:1:0.2").unwrap(),
            crate::scenes::defects("mass:2:5.0 spring:5:0.5 damper:9:1.0").unwrap(),
            crate::scenes::defects("mass:2:5.0 mass:4:0.3 spring:6:2.0 ground:9:0.7").unwrap(),
        ];
        for whitened in [true, false] {
            let obs = observations(&truth, whitened);
            check(&truth, &base, &sets, &obs);
        }
        // another chain: free left end, damped, gamma != 1, velocity sensor at 4
        let other = Chain::new(7)
            .unwrap()
            .with_k(2.0)
            .unwrap()
            .with_mass(0.7)
            .unwrap()
            .with_d(0.4)
            .unwrap()
            .with_gamma(1.5)
            .unwrap()
            .with_boundaries(Boundary::Free, Boundary::Fixed)
            .unwrap();
        let truth2 = other
            .clone()
            .with_defect(Defect::Mass { at: 4, m: 2.0 })
            .unwrap();
        let sensor = Sensor {
            at: 4,
            kind: Observable::Velocity,
        };
        let obs = observations(&truth2, true);
        let s = obs.nodes().to_vec();
        let values: Vec<Complex64> = s
            .iter()
            .map(|&z| {
                crate::detect::data::measurement::laplace_model(
                    sensor,
                    &crate::forward::Forward::new(&truth2),
                    z,
                    None,
                )
                .unwrap()
            })
            .collect();
        let obs2 = LaplaceObs::whitened(s, values, obs.whitening().unwrap().clone())
            .unwrap()
            .with_measurement(sensor, None)
            .unwrap();
        let sets2 = vec![
            vec![Defect::Mass { at: 4, m: 2.5 }],
            crate::scenes::defects("mass:1:0.5 spring:1:1.0").unwrap(),
            crate::scenes::defects("damper:7:2.0 mass:4:3.0").unwrap(),
        ];
        check(&truth2, &other, &sets2, &obs2);
    }

    #[test]
    fn equals_the_general_path_in_every_damping_model() {
        use crate::chain::Damping;
        for damping in [
            Damping::Between { c: 0.08 },
            Damping::Rayleigh { a: 0.03, b: 0.05 },
        ] {
            let base = Chain::paper(8)
                .unwrap()
                .with_d(0.0)
                .unwrap()
                .with_damping(damping)
                .unwrap();
            let truth = base
                .clone()
                .with_defects(crate::scenes::defects("mass:3:2.5 spring:6:0.6").unwrap())
                .unwrap();
            let sets = vec![
                crate::scenes::defects("mass:3:2.0 mass:7:0.5").unwrap(),
                crate::scenes::defects("spring:0:1.7 mass:5:4.0").unwrap(),
                crate::scenes::defects("damper:2:0.3 spring:2:1.3").unwrap(),
                crate::scenes::defects("ground:8:0.3 mass:1:0.2").unwrap(),
            ];
            for whitened in [true, false] {
                check(&truth, &base, &sets, &observations(&truth, whitened));
            }
        }
    }

    #[test]
    fn cofactor_determinants_equal_elimination() {
        for m in 1..=3usize {
            for seed in 0..20u64 {
                let a: Vec<Complex64> = (0..m * m)
                    .map(|i| {
                        let x = (seed * 31 + i as u64 * 17) as f64;
                        Complex64::new((x * 0.37).sin() * 3.0, (x * 0.91).cos())
                    })
                    .collect();
                let want = det_elimination(&mut a.clone(), m);
                let got = det(&mut a.clone(), m);
                assert!(
                    (got - want).norm() <= 1e-13 * (1.0 + want.norm()),
                    "{m}: {got} vs {want}"
                );
            }
        }
    }

    #[test]
    fn held_values_and_refusals() {
        let truth = crate::scenes::paper_with(6, "mass:2:2.0 mass:5:3.0").unwrap();
        let base = truth.uniform();
        let obs = observations(&truth, true);
        let defs = [
            Defect::Mass { at: 2, m: 2.0 },
            Defect::Mass { at: 5, m: 3.0 },
        ];
        let sites: Vec<Site> = defs.iter().map(|d| d.site()).collect();
        let tables = SetTables::new(&obs, &base, sites.iter().map(|s| s.probe), 0).unwrap();
        // the second value held at the truth: zero residual at the first's truth
        let model = tables.set(&sites, &[1.0, 1.0], &[None, Some(3.0)]).unwrap();
        let r = model.residuals(&[2.0]).unwrap();
        assert!(r.iter().all(|v| v.abs() < 1e-9), "{r:?}");
        assert_eq!(model.jacobian(&[2.0]).unwrap().ncols(), 1);
        assert!(model.residuals(&[2.0, 3.0]).is_err());
        // a probe not tabled, too many sites
        let other = Defect::Mass { at: 4, m: 1.0 }.site();
        assert!(tables.set(&[other], &[1.0], &[None]).is_none());
        assert!(tables.set(&[sites[0]; 5], &[1.0; 5], &[None; 5]).is_none());
        // the acceleration after the impulse is not the tabulated observable
        let acc = Sensor {
            at: 1,
            kind: Observable::Acceleration,
        };
        let obs_acc = observations(&truth, true)
            .with_measurement(acc, None)
            .unwrap();
        assert!(SetTables::new(&obs_acc, &base, sites.iter().map(|s| s.probe), 0).is_none());
    }
}
