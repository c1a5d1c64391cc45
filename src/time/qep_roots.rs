//! The poles of a damped chain without a dense eigensolver: the `2n` roots
//! of `det(M p^2 + C p + K) = 0` by the Aberth-Ehrlich simultaneous Newton
//! iteration, started from the undamped modes with their first-order
//! damping. Each step costs `O(n)` per root (the logarithmic derivative of
//! the tridiagonal determinant by the pivot recursion), so all poles cost
//! `O(n^2)` per step against the `O(n^3)` of a Schur form of the `2n x 2n`
//! companion matrix; from these starts a few steps suffice.
//!
//! The iteration is trusted only when it is sure: every root's last Newton
//! correction below [`TOL`] of its size, the roots pairwise apart by far
//! more than that, the complex ones off the real axis. Otherwise it returns
//! `None` and the caller takes the Schur form. The roots are kept in
//! conjugate pairs by construction (one representative per pair), so the
//! poles come out exactly symmetric about the real axis.

use nalgebra::{DMatrix, SymmetricEigen};
use num_complex::Complex64;

/// Relative size of the last Newton correction of a converged root.
const TOL: f64 = 1e-13;

/// Most Aberth steps before giving up.
const MAX_STEPS: usize = 40;

/// The chain's quadratic eigenproblem in its coefficients: masses `m`,
/// springs `k` (`n + 1`, walls included), grounded dampers `d`, ground
/// springs `g`, and dampers parallel to the springs `c` (`n + 1`).
pub(crate) struct Tridiagonal<'a> {
    pub m: &'a [f64],
    pub k: &'a [f64],
    pub d: &'a [f64],
    pub g: &'a [f64],
    pub c: &'a [f64],
}

impl Tridiagonal<'_> {
    fn n(&self) -> usize {
        self.m.len()
    }

    /// The Newton correction `det Q / det' Q` at `p`, `Q(p) = M p^2 + C p +
    /// K`, from the logarithmic derivative by the pivots of the unpivoted
    /// elimination `r_i = a_i - b_{i-1}^2 / r_{i-1}` and their derivatives:
    /// 0 when the last pivot vanishes (`p` a root), `None` when another
    /// one does.
    fn newton(&self, p: Complex64) -> Option<Complex64> {
        let (m, k, d, g, c) = (self.m, self.k, self.d, self.g, self.c);
        let mut sum = Complex64::new(0.0, 0.0);
        let mut r_prev = Complex64::new(1.0, 0.0);
        let mut dr_prev = Complex64::new(0.0, 0.0);
        for i in 0..self.n() {
            let damp = d[i] + c[i] + c[i + 1];
            let a = p * p * m[i] + p * damp + (g[i] + k[i] + k[i + 1]);
            let da = p * (2.0 * m[i]) + damp;
            let (r, dr) = if i == 0 {
                (a, da)
            } else {
                let b = -(p * c[i] + k[i]);
                let db = Complex64::new(-c[i], 0.0);
                let q = b / r_prev;
                (a - b * q, da - q * (db * 2.0 - q * dr_prev))
            };
            let zero = r.re == 0.0 && r.im == 0.0;
            if zero && i + 1 == self.n() {
                return Some(Complex64::new(0.0, 0.0));
            }
            if zero || !r.is_finite() {
                return None;
            }
            sum += dr / r;
            r_prev = r;
            dr_prev = dr;
        }
        let w = 1.0 / sum;
        w.is_finite().then_some(w)
    }

    /// Starting poles: the undamped frequencies `omega_j` of `M^{-1/2} K
    /// M^{-1/2}` with each mode's damping `c_j = u^T C u` (`u` the
    /// mass-normalised shape): `-c_j / 2 +- i sqrt(omega_j^2 - c_j^2 / 4)`,
    /// or the two real roots when the mode is overdamped. Returns the
    /// representatives: the upper member of each complex pair, and the
    /// real poles.
    fn starts(&self) -> Option<Vec<Complex64>> {
        let (m, k, d, g, c) = (self.m, self.k, self.d, self.g, self.c);
        let n = self.n();
        let mut a = DMatrix::<f64>::zeros(n, n);
        for i in 0..n {
            a[(i, i)] = (g[i] + k[i] + k[i + 1]) / m[i];
            if i + 1 < n {
                let v = -k[i + 1] / (m[i] * m[i + 1]).sqrt();
                a[(i, i + 1)] = v;
                a[(i + 1, i)] = v;
            }
        }
        let eig = SymmetricEigen::try_new(a, f64::EPSILON, 1000 * n.max(1))?;
        let mut out = Vec::with_capacity(2 * n);
        for j in 0..n {
            let w2 = eig.eigenvalues[j];
            let phi = eig.eigenvectors.column(j);
            let u = |i: usize| phi[i] / m[i].sqrt();
            let mut cj: f64 = (0..n).map(|i| d[i] * u(i) * u(i)).sum();
            for (e, &ce) in c.iter().enumerate().take(n + 1) {
                if ce != 0.0 {
                    let left = if e == 0 { 0.0 } else { u(e - 1) };
                    let right = if e == n { 0.0 } else { u(e) };
                    cj += ce * (left - right) * (left - right);
                }
            }
            let disc = w2 - 0.25 * cj * cj;
            if w2.is_nan() || w2 <= 0.0 || !disc.is_finite() {
                return None;
            }
            if disc > 0.0 {
                out.push(Complex64::new(-0.5 * cj, disc.sqrt()));
            } else {
                let h = (-disc).sqrt();
                out.push(Complex64::new(-0.5 * cj + h, 0.0));
                out.push(Complex64::new(-0.5 * cj - h, 0.0));
            }
        }
        Some(out)
    }
}

/// The `2n` poles (conjugate pairs exact), or `None` when the iteration is
/// not sure of them (see the module's note).
pub(crate) fn aberth_poles(q: &Tridiagonal) -> Option<Vec<Complex64>> {
    let n = q.n();
    if n == 0 || q.m.iter().any(|&m| m.is_nan() || m <= 0.0) {
        return None;
    }
    let mut reps = q.starts()?;
    let real: Vec<bool> = reps.iter().map(|z| z.im == 0.0).collect();
    let mut done = false;
    for _ in 0..MAX_STEPS {
        let mut worst = 0.0f64;
        for i in 0..reps.len() {
            let p = reps[i];
            let newton = q.newton(p)?;
            // repulsion from every other root: the other representatives,
            // the conjugates of the complex ones, and p's own conjugate
            let mut rep = Complex64::new(0.0, 0.0);
            for (j, &z) in reps.iter().enumerate() {
                if j != i {
                    rep += 1.0 / (p - z);
                }
                if !real[j] && j != i {
                    rep += 1.0 / (p - z.conj());
                }
            }
            if !real[i] {
                rep += 1.0 / (p - p.conj());
            }
            let mut w = newton / (1.0 - newton * rep);
            if real[i] {
                w = Complex64::new(w.re, 0.0);
            }
            if !w.is_finite() {
                return None;
            }
            let next = p - w;
            if !real[i] && next.im <= 0.0 {
                return None;
            }
            worst = worst.max(w.norm() / next.norm().max(f64::MIN_POSITIVE));
            reps[i] = next;
        }
        if worst <= TOL {
            done = true;
            break;
        }
    }
    if !done {
        return None;
    }
    let mut all: Vec<Complex64> = Vec::with_capacity(2 * n);
    for (z, &r) in reps.iter().zip(&real) {
        all.push(*z);
        if !r {
            all.push(z.conj());
        }
    }
    if all.len() != 2 * n {
        return None;
    }
    // pairwise apart: far beyond the corrections' size
    for i in 0..all.len() {
        for j in i + 1..all.len() {
            let scale = all[i].norm().max(all[j].norm());
            if (all[i] - all[j]).norm() <= 1e-6 * scale {
                return None;
            }
        }
    }
    Some(all)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The poles by the dense companion matrix's eigenvalues, the
    /// independent reference.
    fn dense(q: &Tridiagonal) -> Vec<Complex64> {
        let n = q.n();
        let mut l = DMatrix::<f64>::zeros(2 * n, 2 * n);
        for i in 0..n {
            l[(i, n + i)] = 1.0;
            l[(n + i, i)] = -(q.g[i] + q.k[i] + q.k[i + 1]) / q.m[i];
            l[(n + i, n + i)] = -(q.d[i] + q.c[i] + q.c[i + 1]) / q.m[i];
            if i + 1 < n {
                l[(n + i, i + 1)] = q.k[i + 1] / q.m[i];
                l[(n + i + 1, i)] = q.k[i + 1] / q.m[i + 1];
                l[(n + i, n + i + 1)] = q.c[i + 1] / q.m[i];
                l[(n + i + 1, n + i)] = q.c[i + 1] / q.m[i + 1];
            }
        }
        l.complex_eigenvalues().iter().copied().collect()
    }

    fn matches(a: &[Complex64], b: &[Complex64]) -> f64 {
        assert_eq!(a.len(), b.len());
        a.iter()
            .map(|z| {
                b.iter()
                    .map(|w| (z - w).norm() / z.norm())
                    .fold(f64::INFINITY, f64::min)
            })
            .fold(0.0, f64::max)
    }

    #[test]
    fn roots_match_the_dense_eigenvalues_over_chains_and_damping() {
        let mut checked = 0;
        for n in [1usize, 2, 5, 20, 60] {
            for (dl, cl) in [(0.0, 0.0), (0.1, 0.0), (0.5, 0.0), (0.0, 0.05), (0.02, 0.3)] {
                let m: Vec<f64> = (0..n)
                    .map(|i| 1.0 + 4.0 * ((i * 7 % 5) as f64 / 4.0))
                    .collect();
                let k: Vec<f64> = (0..=n).map(|i| 1.0 + 0.5 * ((i * 3 % 4) as f64)).collect();
                let d = vec![dl; n];
                let g = vec![0.0; n];
                let c = vec![cl; n + 1];
                let q = Tridiagonal {
                    m: &m,
                    k: &k,
                    d: &d,
                    g: &g,
                    c: &c,
                };
                let got = aberth_poles(&q);
                if let Some(p) = got {
                    let err = matches(&p, &dense(&q));
                    assert!(err < 1e-9, "n={n} d={dl} c={cl}: {err}");
                    for z in &p {
                        assert!(p.contains(&z.conj()));
                    }
                    checked += usize::from(n <= 20);
                }
            }
        }
        // every chain up to n = 20 takes the fast path; at n = 60 this
        // periodic pattern has pole pairs 1e-9 apart, refused (Schur's)
        assert_eq!(checked, 20);
    }

    #[test]
    fn extreme_masses_and_heavy_damping_are_right_or_refused() {
        let mut fast = 0;
        for scale in [1e-3, 1.0, 1e6] {
            for dl in [0.0, 1e-6, 0.3, 3.0, 30.0] {
                let n = 12;
                let m: Vec<f64> = (0..n).map(|i| scale * (1.0 + (i % 3) as f64)).collect();
                let k: Vec<f64> = (0..=n).map(|i| 1.0 + (i % 2) as f64).collect();
                let d: Vec<f64> = (0..n)
                    .map(|i| dl * scale.sqrt() * (1.0 + 0.1 * i as f64))
                    .collect();
                let z = vec![0.0; n + 1];
                let q = Tridiagonal {
                    m: &m,
                    k: &k,
                    d: &d,
                    g: &z[..n],
                    c: &z,
                };
                let got = aberth_poles(&q);
                if let Some(p) = got {
                    let err = matches(&p, &dense(&q));
                    assert!(err < 1e-8, "scale={scale} d={dl}: {err}");
                    fast += 1;
                }
            }
        }
        assert!(fast >= 9, "{fast}");
    }

    #[test]
    fn unsure_cases_are_refused() {
        // a massless entry, and a near-double pole pair (two identical,
        // uncoupled masses)
        let m = [1.0, 0.0];
        let k = [1.0, 1.0, 1.0];
        let z = [0.0; 3];
        let q = Tridiagonal {
            m: &m,
            k: &k,
            d: &z[..2],
            g: &z[..2],
            c: &z,
        };
        assert!(aberth_poles(&q).is_none());
        let m = [1.0, 1.0];
        let k = [1.0, 0.0, 1.0];
        let q = Tridiagonal {
            m: &m,
            k: &k,
            d: &[0.1, 0.1],
            g: &z[..2],
            c: &z,
        };
        assert!(aberth_poles(&q).is_none());
    }
}
