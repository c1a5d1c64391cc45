//! The output spectrum as a measurement model: [`AmbientMisfit`] compares
//! a candidate chain's cross-spectral matrix under white forces with the
//! Welch estimate of a record ([`crate::detect::data::ambient`]).
//!
//! # Model
//!
//! Independent white forces of one unknown level `q` on the masses of the
//! `ambient_on` set (or band-limited: a flat spectrum of level `q` inside a
//! given band `[w_a, w_b]` and none outside it,
//! [`AmbientMisfit::with_force_band`]; `A` below is then zero outside the
//! band), channels observing masses `o_1..o_p` (displacement,
//! velocity or acceleration: `(i w)^P`), white sensor noise of unknown level
//! `nu_c` per channel:
//!
//! `G(w) = q A(w) + diag(nu)`, `A_ab(w) = (i w)^P (-i w)^P sum_{j in on} H_{o_a j}(i w) conj(H_{o_b j}(i w))`,
//!
//! `H(s) = (M s^2 + D s + K)^{-1}` by the O(n) tridiagonal solve at
//! `s = i w` (one solve per observed mass: `H` is symmetric). What the
//! Welch estimate expects is `A` smoothed by the Hann window's spectral
//! kernel `|W(v)|^2` (the trapezoid rule at half-bin steps over +-4 bins: a resonance at
//! least two bins wide, as the segment length ensures, is integrated to
//! about `exp(-4 pi)`), so
//! that a resonance narrower than a few bins is not biased.
//!
//! # Residuals (least squares on the averaged spectra)
//!
//! With `K` averaged segments the estimate `G^` is a complex Wishart with
//! `K` degrees of freedom; to first order `L^-1 (G^ - G) L^-H sqrt(K)` with
//! `L L^H = G^` has independent unit-variance entries (the real diagonal,
//! `sqrt 2` times the real and imaginary parts above it). These `p^2` real
//! numbers per bin are the residuals (weights from the data: the minimum
//! chi-square of Neyman; its bias is a common scale, absorbed by `q` and
//! `nu`). Every second bin is used (the Hann window correlates neighbours).
//! `q` and `nu` enter linearly and are profiled out by linear least squares
//! at every evaluation (variable projection), so the chain's parameters
//! see a chi-square of their own; the Jacobian is left to differences.
//!
//! The absolute scale is not determined: scaling every mass, spring and
//! damper by `c` scales `A` by `c^-2`, which `q` absorbs. The masses are
//! the user's known values.

use crate::chain::Chain;
use crate::detect::data::ambient::{hann, CrossSpectrum};
use crate::detect::model::MeasurementModel;
use crate::error::{Error, Result};
use crate::forward::Observable;
use crate::sensitivity::Param;
use nalgebra::DMatrix;
use num_complex::Complex64;

/// Quadrature points of the window kernel per bin.
const PER_BIN: usize = 2;
/// Half-width of the window kernel in bins.
const HALF_WIDTH: usize = 4;

/// The output spectrum's measurement model (see the module docs).
#[derive(Clone, Debug)]
pub struct AmbientMisfit {
    observe: Vec<usize>,
    kind: Observable,
    on: Vec<usize>,
    /// Used bins (indices into the spectrum).
    bins: Vec<usize>,
    /// `L^-1` per used bin (`L L^H = G^`).
    whiten: Vec<DMatrix<Complex64>>,
    /// `sqrt(K)`, `K` the equivalent number of segments.
    sqrt_k: f64,
    /// The data vector `sqrt(K) vec(I)` per bin.
    data: Vec<f64>,
    /// Every channel's whitened unit noise floor, its Gram matrix and its
    /// product with the data.
    noise: Vec<Vec<f64>>,
    noise_gram: DMatrix<f64>,
    noise_y: Vec<f64>,
    /// The fine grid's frequencies and, per used bin, its (fine index, weight) list.
    fine: Vec<f64>,
    taps: Vec<Vec<(usize, f64)>>,
    p: usize,
    /// The Welch estimate at the used bins.
    g_hat: Vec<DMatrix<Complex64>>,
    /// The share of each fine frequency's cell inside the force's band
    /// ([`band_share`]); empty for white forces (every share 1).
    band_shares: Vec<f64>,
}

/// The fitted nuisance of one evaluation: the force level and the noise floors.
#[derive(Clone, Debug, PartialEq)]
pub struct Nuisance {
    /// White force level `q` (two-sided density per mass).
    pub force_level: f64,
    /// Sensor-noise floor per channel.
    pub noise_floor: Vec<f64>,
}

impl AmbientMisfit {
    /// The model of `spec` over the band `[w_lo, w_hi]` for channels at
    /// `observe` of `kind`, white forces on `on` (1-based masses).
    ///
    /// # Errors
    /// Fewer than `p + 2` bins in the band (field `band`); a matrix the
    /// Cholesky factorisation refuses (field `spectrum`: a channel that is a
    /// copy of another).
    pub fn new(
        spec: &CrossSpectrum,
        observe: Vec<usize>,
        kind: Observable,
        on: Vec<usize>,
        band: (f64, f64),
    ) -> Result<AmbientMisfit> {
        let p = observe.len();
        let bins: Vec<usize> = (2..spec.omega.len() - HALF_WIDTH)
            .step_by(2)
            .filter(|&j| spec.omega[j] >= band.0 && spec.omega[j] <= band.1)
            .collect();
        if bins.len() < p + 2 {
            return Err(Error::invalid(
                "band",
                format!("{:.4}..{:.4}", band.0, band.1),
                format!("at least {} used bins (found {})", p + 2, bins.len()),
            ));
        }
        let g_hat: Vec<DMatrix<Complex64>> = bins.iter().map(|&j| spec.g[j].clone()).collect();
        let (fine, taps) = kernel_grid(spec, &bins);
        let empty = AmbientMisfit {
            observe,
            kind,
            on: on.iter().map(|m| m - 1).collect(),
            bins,
            whiten: Vec::new(),
            sqrt_k: spec.effective_segments().sqrt(),
            data: Vec::new(),
            noise: Vec::new(),
            noise_gram: DMatrix::zeros(0, 0),
            noise_y: Vec::new(),
            fine,
            taps,
            p,
            g_hat: g_hat.clone(),
            band_shares: Vec::new(),
        };
        empty.with_weights(&g_hat)
    }

    /// The same data, with forces whose spectrum is flat inside `band`
    /// (`[w_a, w_b]`, rad per unit time) and zero outside it (the window's
    /// smoothing of the edges is modelled as for the resonances).
    ///
    /// # Errors
    /// A band that is not `0 <= w_a < w_b` and finite, or that holds fewer
    /// than two of the used bins (field `ambient_band`).
    pub fn with_force_band(mut self, band: (f64, f64)) -> Result<AmbientMisfit> {
        let (a, b) = band;
        if !(a >= 0.0 && b > a && b.is_finite()) {
            return Err(Error::invalid(
                "ambient_band",
                format!("{a}:{b}"),
                "LO:HI with 0 <= LO < HI, finite (rad per unit time)",
            ));
        }
        let inside = self.fine.iter().filter(|&&w| w >= a && w <= b).count();
        if inside < 2 * PER_BIN {
            return Err(Error::invalid(
                "ambient_band",
                format!("{a}:{b}"),
                format!(
                    "a band over at least two of the spectrum's bins inside the fitted band (the bins are {:.4e} rad per unit time apart)",
                    self.fine.get(PER_BIN).map_or(0.0, |w| w - self.fine[0])
                ),
            ));
        }
        let step = self.fine[1] - self.fine[0];
        self.band_shares = self
            .fine
            .iter()
            .map(|&w| band_share(w, step, band))
            .collect();
        Ok(self)
    }

    /// The same data weighted by `weights` (one Hermitian positive definite
    /// matrix per used bin, the expected spectrum): the residuals become
    /// `sqrt(K) L^-1 (G^ - G) L^-H` with `L L^H = weights`.
    ///
    /// # Errors
    /// A matrix the Cholesky factorisation refuses (field `spectrum`).
    fn with_weights(mut self, weights: &[DMatrix<Complex64>]) -> Result<AmbientMisfit> {
        let p = self.p;
        self.whiten = Vec::with_capacity(weights.len());
        for (w, &j) in weights.iter().zip(&self.bins) {
            let l = nalgebra::Cholesky::new(w.clone()).ok_or_else(|| {
                Error::invalid(
                    "spectrum",
                    format!("bin {j}"),
                    "a positive definite cross-spectral matrix (channels not copies of one another)",
                )
            })?;
            let inv = l.l().try_inverse().ok_or_else(|| {
                Error::invalid("spectrum", format!("bin {j}"), "a regular matrix")
            })?;
            self.whiten.push(inv);
        }
        let mut data = Vec::new();
        let mut noise = vec![Vec::new(); p];
        for (wm, g) in self.whiten.iter().zip(&self.g_hat) {
            push_hermitian(&mut data, &(wm * g * wm.adjoint()), self.sqrt_k);
            for (c, col) in noise.iter_mut().enumerate() {
                push_hermitian(col, &(wm.column(c) * wm.column(c).adjoint()), self.sqrt_k);
            }
        }
        self.noise_gram = DMatrix::from_fn(p, p, |a, b| dot(&noise[a], &noise[b]));
        self.noise_y = noise.iter().map(|c| dot(c, &data)).collect();
        self.data = data;
        self.noise = noise;
        Ok(self)
    }

    /// The model weighted by the spectrum `chain` predicts (its fitted force
    /// level and noise floors): the weights of the Whittle likelihood's
    /// Fisher scoring, free of the data's noise.
    ///
    /// # Errors
    /// A predicted spectrum that is not positive definite (a negative noise
    /// floor; field `spectrum`); as [`MeasurementModel::residuals`].
    pub fn reweighted(&self, chain: &Chain) -> Result<AmbientMisfit> {
        let (_, c) = self.project(chain)?;
        let weights: Vec<DMatrix<Complex64>> = self
            .smoothed(chain)?
            .into_iter()
            .map(|a| {
                let mut g = a * Complex64::new(c[0], 0.0);
                for k in 0..self.p {
                    g[(k, k)] += c[k + 1];
                }
                g
            })
            .collect();
        self.clone().with_weights(&weights)
    }

    /// Number of used bins.
    pub fn bins(&self) -> usize {
        self.bins.len()
    }

    /// The nuisance (force level, noise floors) fitted at `chain`.
    ///
    /// # Errors
    /// As [`MeasurementModel::residuals`].
    pub fn nuisance(&self, chain: &Chain) -> Result<Nuisance> {
        let (_, c) = self.project(chain)?;
        Ok(Nuisance {
            force_level: c[0],
            noise_floor: c.iter().skip(1).copied().collect(),
        })
    }

    /// `A(w)` (the unit-force spectral matrix, `p x p` row-major) at every
    /// fine frequency.
    fn unit_spectra(&self, chain: &Chain) -> Result<Vec<Complex64>> {
        let c = chain.coefficients();
        let (dd, kd) = (c.d_diag(), c.k_diag());
        let n = chain.n();
        let p = self.p;
        let zero = Complex64::new(0.0, 0.0);
        let mut out = vec![zero; self.fine.len() * p * p];
        let mut rows: Vec<Vec<Complex64>> = Vec::with_capacity(p);
        for (f, &w) in self.fine.iter().enumerate() {
            let share = self.band_shares.get(f).copied().unwrap_or(1.0);
            if share == 0.0 {
                continue; // no force there: A = 0
            }
            let s = Complex64::new(0.0, w);
            let diag: Vec<Complex64> = (0..n).map(|i| s * s * c.m[i] + s * dd[i] + kd[i]).collect();
            let off: Vec<Complex64> = (1..n).map(|i| -(s * c.c[i] + c.k[i])).collect();
            let factor = s.powu(self.kind.power());
            let lu = TriLu::new(diag, off).ok_or_else(|| Error::Singular { s: format!("{s}") })?;
            rows.clear();
            for &o in &self.observe {
                let mut b = vec![zero; n];
                b[o - 1] = factor;
                lu.solve(&mut b);
                rows.push(b);
            }
            let a = &mut out[f * p * p..(f + 1) * p * p];
            for x in 0..p {
                for y in x..p {
                    let v: Complex64 = self
                        .on
                        .iter()
                        .map(|&j| rows[x][j] * rows[y][j].conj())
                        .sum::<Complex64>()
                        * share;
                    a[x * p + y] = v;
                    a[y * p + x] = v.conj();
                }
            }
        }
        Ok(out)
    }

    /// The window-smoothed `A` at every used bin.
    fn smoothed(&self, chain: &Chain) -> Result<Vec<DMatrix<Complex64>>> {
        let fine = self.unit_spectra(chain)?;
        let p = self.p;
        let mut out = Vec::with_capacity(self.bins.len());
        for taps in &self.taps {
            let mut a = DMatrix::<Complex64>::zeros(p, p);
            for &(f, w) in taps {
                let src = &fine[f * p * p..(f + 1) * p * p];
                for x in 0..p {
                    for y in 0..p {
                        a[(x, y)] += src[x * p + y] * w;
                    }
                }
            }
            out.push(a);
        }
        Ok(out)
    }

    /// The column `sqrt(K) vec(L^-1 A L^-H)` of the window-smoothed `A`.
    fn signal_column(&self, chain: &Chain) -> Result<Vec<f64>> {
        let mut col = Vec::with_capacity(self.bins.len() * self.p * self.p);
        for (a, wm) in self.smoothed(chain)?.iter().zip(&self.whiten) {
            push_hermitian(&mut col, &(wm * a * wm.adjoint()), self.sqrt_k);
        }
        Ok(col)
    }

    /// The residuals with `q` and `nu` profiled out, and their values
    /// (normal equations of the `p + 1` linear coefficients; the noise
    /// columns' part is precomputed).
    fn project(&self, chain: &Chain) -> Result<(Vec<f64>, Vec<f64>)> {
        let sig = self.signal_column(chain)?;
        let p = self.p;
        let mut ata = DMatrix::<f64>::zeros(p + 1, p + 1);
        let mut aty = nalgebra::DVector::<f64>::zeros(p + 1);
        ata[(0, 0)] = dot(&sig, &sig);
        aty[0] = dot(&sig, &self.data);
        for c in 0..p {
            let v = dot(&sig, &self.noise[c]);
            ata[(0, c + 1)] = v;
            ata[(c + 1, 0)] = v;
            aty[c + 1] = self.noise_y[c];
            for d in 0..p {
                ata[(c + 1, d + 1)] = self.noise_gram[(c, d)];
            }
        }
        let coef = ata
            .clone()
            .lu()
            .solve(&aty)
            .filter(|c| c.iter().all(|v| v.is_finite()))
            .ok_or_else(|| Error::Numerical {
                method: "ambient nuisance".into(),
                reason:
                    "the force level and noise floors are not separable (singular normal equations)"
                        .into(),
            })?;
        let mut r = self.data.clone();
        for (k, rk) in r.iter_mut().enumerate() {
            *rk -= coef[0] * sig[k];
            for c in 0..p {
                *rk -= coef[c + 1] * self.noise[c][k];
            }
        }
        Ok((r, coef.iter().copied().collect()))
    }
}

/// The share of the fine grid's cell around `w` (half a `step` either
/// side) inside the force band `(a, b)`: a band edge inside the cell weights
/// it by the part inside, so that the kernel's quadrature places the edge
/// where it is, not at the nearest grid point. The two-sided spectrum is
/// even in `w` (the kernel's lowest taps lie at negative frequencies), and
/// a band from 0 has no lower edge.
fn band_share(w: f64, step: f64, (a, b): (f64, f64)) -> f64 {
    let (lo, hi) = (w.abs() - 0.5 * step, w.abs() + 0.5 * step);
    let upper = ((b - lo) / step).clamp(0.0, 1.0);
    let lower = if a > 0.0 {
        ((hi - a) / step).clamp(0.0, 1.0)
    } else {
        1.0
    };
    upper * lower
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Append the `p^2` real coordinates of a Hermitian matrix, scaled: the
/// diagonal, then `sqrt 2` times the real and imaginary parts above it.
fn push_hermitian(out: &mut Vec<f64>, m: &DMatrix<Complex64>, scale: f64) {
    let p = m.nrows();
    for a in 0..p {
        out.push(scale * m[(a, a)].re);
    }
    let r2 = std::f64::consts::SQRT_2 * scale;
    for a in 0..p {
        for b in a + 1..p {
            out.push(r2 * m[(a, b)].re);
            out.push(r2 * m[(a, b)].im);
        }
    }
}

/// The fine frequency grid and every used bin's quadrature of the Hann
/// window's kernel `|W(v)|^2` (normalised to sum 1).
fn kernel_grid(spec: &CrossSpectrum, bins: &[usize]) -> (Vec<f64>, Vec<Vec<(usize, f64)>>) {
    let len = spec.seg_len;
    let w = hann(len);
    let step = spec.bin() / PER_BIN as f64;
    let half = (HALF_WIDTH * PER_BIN) as i64;
    let weights: Vec<f64> = (-half..=half)
        .map(|q| {
            // |W(v)|^2 at v = q step: W(v) = sum w_n e^{-i v n dt}
            let v = q as f64 * step * spec.dt;
            let z: Complex64 = w
                .iter()
                .enumerate()
                .map(|(n, wn)| Complex64::from_polar(*wn, -v * n as f64))
                .sum();
            z.norm_sqr()
        })
        .collect();
    let total: f64 = weights.iter().sum();
    let lo = bins[0] as i64 * PER_BIN as i64 - half;
    let hi = *bins.last().expect("checked non-empty") as i64 * PER_BIN as i64 + half;
    let fine: Vec<f64> = (lo..=hi).map(|i| i as f64 * step).collect();
    let taps = bins
        .iter()
        .map(|&j| {
            let centre = j as i64 * PER_BIN as i64;
            (-half..=half)
                .map(|q| {
                    let idx = (centre + q - lo) as usize;
                    (idx, weights[(q + half) as usize] / total)
                })
                .collect()
        })
        .collect();
    (fine, taps)
}

impl MeasurementModel for AmbientMisfit {
    fn name(&self) -> &'static str {
        "ambient"
    }

    fn dof(&self) -> usize {
        self.bins.len() * self.p * self.p
    }

    fn residuals(&self, chain: &Chain) -> Result<Vec<f64>> {
        let n = chain.n();
        if let Some(&o) = self.observe.iter().find(|&&m| m > n) {
            return Err(Error::invalid("observe", o, format!("1..={n}")));
        }
        if let Some(&o) = self.on.iter().find(|&&m| m >= n) {
            return Err(Error::invalid("ambient_on", o + 1, format!("1..={n}")));
        }
        Ok(self.project(chain)?.0)
    }

    fn jacobian(&self, _chain: &Chain, _params: &[Param]) -> Result<Option<DMatrix<f64>>> {
        Ok(None)
    }
}

/// The LU factorisation with partial pivoting of a complex symmetric
/// tridiagonal matrix (LAPACK `gttrf`), for several right-hand sides
/// (`gttrs`).
struct TriLu {
    dl: Vec<Complex64>,
    d: Vec<Complex64>,
    du: Vec<Complex64>,
    du2: Vec<Complex64>,
    swap: Vec<bool>,
}

impl TriLu {
    /// Factor the matrix of diagonal `d` and off-diagonal `off`; `None`
    /// when it is singular.
    fn new(mut d: Vec<Complex64>, off: Vec<Complex64>) -> Option<TriLu> {
        let n = d.len();
        let (mut dl, mut du) = (off.clone(), off);
        let zero = Complex64::new(0.0, 0.0);
        let mut du2 = vec![zero; n.saturating_sub(2)];
        let mut swap = vec![false; n.saturating_sub(1)];
        for i in 0..n.saturating_sub(1) {
            if d[i].l1_norm() >= dl[i].l1_norm() {
                if d[i] != zero {
                    let fact = dl[i] / d[i];
                    dl[i] = fact;
                    d[i + 1] -= fact * du[i];
                }
            } else {
                let fact = d[i] / dl[i];
                d[i] = dl[i];
                dl[i] = fact;
                let temp = du[i];
                du[i] = d[i + 1];
                d[i + 1] = temp - fact * d[i + 1];
                if i + 2 < n {
                    du2[i] = du[i + 1];
                    du[i + 1] = -fact * du[i + 1];
                }
                swap[i] = true;
            }
        }
        d.iter()
            .all(|v| v.l1_norm() > 0.0 && v.is_finite())
            .then_some(TriLu {
                dl,
                d,
                du,
                du2,
                swap,
            })
    }

    /// Overwrite `b` with the solution.
    fn solve(&self, b: &mut [Complex64]) {
        let n = b.len();
        for i in 0..n.saturating_sub(1) {
            if self.swap[i] {
                let temp = b[i] - self.dl[i] * b[i + 1];
                b[i] = b[i + 1];
                b[i + 1] = temp;
            } else {
                let t = self.dl[i] * b[i];
                b[i + 1] -= t;
            }
        }
        for i in (0..n).rev() {
            let mut v = b[i];
            if i + 1 < n {
                v -= self.du[i] * b[i + 1];
            }
            if i + 2 < n {
                v -= self.du2[i] * b[i + 2];
            }
            b[i] = v / self.d[i];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pivoted_tridiagonal_solve_matches_the_project_solver() {
        let n = 7;
        let diag: Vec<Complex64> = (0..n)
            .map(|i| Complex64::new(0.3 - 0.2 * i as f64, 0.05 * (i + 1) as f64))
            .collect();
        let off: Vec<Complex64> = (1..n)
            .map(|i| Complex64::new(-1.0 - 0.1 * i as f64, 0.0))
            .collect();
        for o in 0..n {
            let mut b = vec![Complex64::new(0.0, 0.0); n];
            b[o] = Complex64::new(1.0, 0.5);
            let want = crate::forward::tridiag::solve_general(diag.clone(), off.clone(), b.clone())
                .unwrap();
            TriLu::new(diag.clone(), off.clone()).unwrap().solve(&mut b);
            for (x, y) in b.iter().zip(&want) {
                assert!((x - y).norm() < 1e-12 * (1.0 + y.norm()), "{x} vs {y}");
            }
        }
    }
}
