//! The Green's function of a nonuniform chain (a [`crate::chain::Baseline`])
//! from the two recurrence solutions of its tridiagonal dynamic stiffness.
//!
//! With `p_i = m_i s^2 + d_i s + g_i` (what mass `i` holds besides its
//! springs) and `kappa_i = k_i + c_i s` (spring `i` and the damper beside
//! it), row `i` of `K(s) x = 0` reads
//! `-kappa_{i-1} x_{i-1} + (p_i + kappa_{i-1} + kappa_i) x_i - kappa_i x_{i+1} = 0`.
//! The left solution `L` starts at `L_0 = 0`, `L_1 = 1` (the left end
//! condition: a fixed end has `x_0 = 0`, a free end `kappa_0 = 0`), the
//! right one at `R_{n+1} = 0`, `R_n = 1`. Both are carried in transfer
//! form, displacement and spring force together:
//!
//! `D_i = D_{i-1} + p_i L_i`, `L_{i+1} = L_i + D_i / kappa_i`, `D_0 = kappa_0`,
//!
//! (`D_i = kappa_i (L_{i+1} - L_i)`, and mirrored for `R` with
//! `E_j = kappa_j (R_j - R_{j+1})`), so that for real `s > 0` every term is
//! positive and the strain differences `L_i - L_{i+1} = -D_i / kappa_i` are
//! formed without cancellation. Then for `i <= j`
//!
//! `G_ij = L_i R_j / W`, `W = D_j R_j + L_j E_j` (constant in `j`),
//!
//! the structure of the uniform chain's closed form (module docs of
//! [`crate::green`]). Every stored value is a mantissa with its own binary
//! exponent (the running pair is rescaled by `2^-256` whenever it grows
//! past `2^256`), so nothing overflows for any `n`; an entry costs one
//! product and one `2^e` scaling after the O(n) sweep per `s`.

use crate::chain::{Chain, Coefficients};
use crate::scalar::Scalar;

/// A value `mant * 2^exp2`.
#[derive(Clone, Debug)]
pub(super) struct Scaled<T> {
    pub mant: T,
    pub exp2: i32,
}

/// Rescaling step of the sweeps (a power of two: exact).
const STEP: i32 = 256;

/// The two sweeps of one chain at one `s`.
#[derive(Clone, Debug)]
pub(super) struct ProfileGreen<T> {
    /// `L_i`, `i = 0..=n`.
    l: Vec<Scaled<T>>,
    /// `L_i - L_{i+1}`, `i = 0..=n` (zero where spring `i` is absent).
    ld: Vec<Scaled<T>>,
    /// `R_j`, `j = 1..=n + 1` (index `j - 1`).
    r: Vec<Scaled<T>>,
    /// `R_j - R_{j+1}`, `j = 0..=n` (zero where spring `j` is absent).
    rd: Vec<Scaled<T>>,
    /// The Casoratian `W`.
    w: Scaled<T>,
}

/// Rescale the running pair `(x, f)` so that neither exceeds `2^STEP` nor
/// (unless both vanish) falls below `2^-STEP`.
fn renorm<T: Scalar>(x: &mut T, f: &mut T, e: &mut i32) {
    let big = x.magnitude().max(f.magnitude());
    let up = 2f64.powi(STEP);
    if big > up {
        *x = x.scale(1.0 / up);
        *f = f.scale(1.0 / up);
        *e += STEP;
    } else if big > 0.0 && big < 1.0 / up {
        *x = x.scale(up);
        *f = f.scale(up);
        *e -= STEP;
    }
}

/// One sweep from an end: `x` (displacements at `0..=n`, `x_0` the start,
/// `x_1 = 1`) and `-dx` (`x_i - x_{i+1}`), over the springs `kappa` and
/// point terms `p` given in sweep order; `f0` is the first spring's
/// force. Returns `(x, x_i - x_{i+1}, last force)`.
fn sweep<T: Scalar>(p: &[T], kappa: &[T], f0: T) -> (Vec<Scaled<T>>, Vec<Scaled<T>>, Scaled<T>) {
    let n = p.len();
    let zero = || Scaled {
        mant: T::zero(),
        exp2: 0,
    };
    let mut x_out = vec![zero()];
    let mut dx = vec![Scaled {
        mant: T::from_f64(-1.0),
        exp2: 0,
    }];
    let (mut x, mut f, mut e) = (T::one(), f0, 0i32);
    for i in 1..=n {
        x_out.push(Scaled {
            mant: x.clone(),
            exp2: e,
        });
        f = f + p[i - 1].clone() * x.clone();
        if kappa[i].is_zero() {
            dx.push(zero());
        } else {
            let step = f.clone() / kappa[i].clone();
            dx.push(Scaled {
                mant: -step.clone(),
                exp2: e,
            });
            x = x + step;
        }
        renorm(&mut x, &mut f, &mut e);
    }
    (x_out, dx, Scaled { mant: f, exp2: e })
}

impl<T: Scalar> ProfileGreen<T> {
    /// The sweeps of the chain with coefficients `c` at `s`.
    pub fn new(c: &Coefficients, s: &T) -> ProfileGreen<T> {
        let n = c.m.len();
        let p: Vec<T> = (0..n)
            .map(|i| (s.clone() * s.clone()).scale(c.m[i]) + s.scale(c.d[i]) + T::from_f64(c.g[i]))
            .collect();
        let kappa: Vec<T> = (0..=n)
            .map(|i| T::from_f64(c.k[i]) + s.scale(c.c[i]))
            .collect();
        let (l, ld, dn) = sweep(&p, &kappa, kappa[0].clone());
        let p_rev: Vec<T> = p.iter().rev().cloned().collect();
        let kappa_rev: Vec<T> = kappa.iter().rev().cloned().collect();
        let (mut r, rd_rev, _) = sweep(&p_rev, &kappa_rev, kappa[n].clone());
        // sweep order is n + 1 - j: R_{n+1} first; rd_rev[q] = R_{n+1-q} - R_{n-q}
        r.reverse();
        let rd: Vec<Scaled<T>> = rd_rev
            .into_iter()
            .rev()
            .map(|v| Scaled {
                mant: -v.mant,
                exp2: v.exp2,
            })
            .collect();
        // W = D_n R_n + L_n E_n with R_n = 1, E_n = kappa_n
        let ln = &l[n];
        let mant = dn.mant + ln.mant.clone() * kappa[n].clone().scale(2f64.powi(ln.exp2 - dn.exp2));
        let w = Scaled {
            mant,
            exp2: dn.exp2,
        };
        ProfileGreen { l, ld, r, rd, w }
    }

    /// The sweeps of `chain` without its defects at `s`.
    pub fn of_chain(chain: &Chain, s: &T) -> ProfileGreen<T> {
        ProfileGreen::new(&chain.uniform().coefficients(), s)
    }

    /// `W == 0`: a pole (the rigid-body mode of a free-free chain at `s = 0`).
    pub fn is_singular(&self) -> bool {
        self.w.mant.is_zero()
    }
    /// `L_a`, `a = 0..=n`.
    pub fn left_point(&self, a: usize) -> Scaled<T> {
        self.l[a].clone()
    }
    /// `R_b`, `b = 1..=n + 1`.
    pub fn right_point(&self, b: usize) -> Scaled<T> {
        self.r[b - 1].clone()
    }
    /// `L_i - L_{i+1}`.
    pub fn left_diff(&self, i: usize) -> Scaled<T> {
        self.ld[i].clone()
    }
    /// `R_j - R_{j+1}`.
    pub fn right_diff(&self, j: usize) -> Scaled<T> {
        self.rd[j].clone()
    }
    /// `l r / W`.
    pub fn combine(&self, l: &T, le: i32, r: &T, re: i32) -> T {
        let e = (le + re - self.w.exp2).clamp(-1100, 1100);
        let v = l.clone() * r.clone() / self.w.mant.clone();
        if e == 0 {
            v
        } else if e < -1000 {
            // 2^e in two steps (2^-1100 is below the f64 range)
            v.scale(2f64.powi(e / 2)).scale(2f64.powi(e - e / 2))
        } else {
            v.scale(2f64.powi(e))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::{Green, Probe};
    use crate::chain::dense_ref::{self, baseline_chain};
    use crate::chain::{Baseline, Boundary, Chain, Damping};
    use num_complex::Complex64;
    use Boundary::*;

    const ENDS: [(Boundary, Boundary); 4] =
        [(Fixed, Fixed), (Free, Fixed), (Fixed, Free), (Free, Free)];

    fn grid() -> Vec<Complex64> {
        [
            (1e-3, 0.0),
            (0.5, 0.0),
            (40.0, 0.0),
            (0.05, 1.3),
            (0.2, 0.7),
            (1.0, -5.0),
            (0.01, 30.0),
        ]
        .iter()
        .map(|&(a, b)| Complex64::new(a, b))
        .collect()
    }

    /// The largest error of every entry and strain pair of `chain`'s
    /// Green's function against the dense inverse at `s`, relative to the
    /// largest entry.
    fn error_vs_dense(chain: &Chain, s: Complex64) -> f64 {
        let d = dense_ref::assemble(chain);
        let n = chain.n();
        let a = nalgebra::DMatrix::from_fn(n, n, |i, j| {
            s * s * d.m[(i, j)] + s * d.c[(i, j)] + Complex64::new(d.k[(i, j)], 0.0)
        });
        let inv = a.lu().try_inverse().expect("regular");
        let g = Green::of_chain(chain, s);
        let scale = inv.iter().map(|z| z.norm()).fold(0.0, f64::max);
        let (lo, hi) = chain.spring_range();
        let probes: Vec<Probe> = (lo..=hi)
            .map(Probe::Diff)
            .chain((1..=n).map(Probe::Point))
            .collect();
        let mut worst = 0.0f64;
        for &u in &probes {
            let fu = g.factors(u);
            for &v in &probes {
                let mut want = Complex64::new(0.0, 0.0);
                for (i, wi) in u.entries(n) {
                    for (j, wj) in v.entries(n) {
                        want += inv[(i - 1, j - 1)] * (wi * wj);
                    }
                }
                let got = g.bilinear(u, v);
                let paired = g.pair(&fu, &g.factors(v));
                worst = worst
                    .max((got - want).norm() / scale)
                    .max((paired - want).norm() / scale);
            }
        }
        worst
    }

    #[test]
    fn nonuniform_matches_dense_inverse() {
        let mut worst = 0.0f64;
        for ends in ENDS {
            for n in [1usize, 2, 3, 8, 40, 120] {
                if n == 1 && ends == (Free, Free) {
                    continue;
                }
                for dampers in [false, true] {
                    let c = baseline_chain(n, ends, dampers);
                    let between = c
                        .clone()
                        .with_damping(Damping::Between { c: 0.05 })
                        .unwrap();
                    for s in grid() {
                        worst = worst.max(error_vs_dense(&c, s));
                        if n <= 40 {
                            worst = worst.max(error_vs_dense(&between, s));
                        }
                    }
                }
            }
        }
        eprintln!("baseline Green vs dense: max error / max |G| = {worst:.2e}");
        assert!(worst < 1e-10, "{worst}");
    }

    #[test]
    fn uniform_baseline_is_the_closed_form() {
        let mut worst = 0.0f64;
        for ends in ENDS {
            for n in [1usize, 5, 30, 300] {
                if n == 1 && ends == (Free, Free) {
                    continue;
                }
                let mut spring = vec![1.3; n + 1];
                spring[0] = if ends.0.is_free() { 0.0 } else { 1.3 };
                spring[n] = if ends.1.is_free() { 0.0 } else { 1.3 };
                let b = Baseline::new(vec![0.7; n], spring, None, "").unwrap();
                let c = Chain::paper(n).unwrap().with_baseline(b).unwrap();
                let u = c.without_baseline();
                for s in grid() {
                    let (gp, gu) = (Green::of_chain(&c, s), Green::of_chain(&u, s));
                    for (i, j) in [
                        (1, 1),
                        (1, n),
                        (n / 2 + 1, n),
                        (n, n),
                        (2.min(n), (n / 3).max(1)),
                    ] {
                        let (p, q) = (gp.entry(i, j), gu.entry(i, j));
                        if q.norm() > 1e-250 {
                            // both forms round about n eps on an entry that
                            // decays like e^{-n lambda} across the chain
                            let r = (p - q).norm() / q.norm();
                            worst = worst.max(r / (n as f64 / 100.0).max(1.0));
                        } else {
                            // the closed form underflows: so must this
                            assert!(p.norm() < 1e-240, "{p} vs {q}");
                        }
                    }
                }
            }
        }
        eprintln!(
            "baseline Green vs the closed form (uniform table): max relative error / max(1, n/100) = {worst:.2e}"
        );
        assert!(worst < 1e-12, "{worst}");
    }

    #[test]
    fn long_chains_never_overflow() {
        let n = 100_000;
        let b = Baseline::new(
            (0..n)
                .map(|i| 1.0 + 0.3 * ((i as f64) * 0.37).sin())
                .collect(),
            (0..=n)
                .map(|i| 1.0 + 0.3 * ((i as f64) * 0.11).cos())
                .collect(),
            None,
            "",
        )
        .unwrap();
        let c = Chain::paper(n).unwrap().with_baseline(b).unwrap();
        for s in [
            Complex64::new(1e-6, 0.0),
            Complex64::new(3.0, 0.0),
            Complex64::new(1e4, 0.0),
            Complex64::new(0.1, 2.0),
        ] {
            let g = Green::of_chain(&c, s);
            for (i, j) in [(1, 1), (1, n), (n / 2, n / 2 + 7), (n, n)] {
                let e = g.entry(i, j);
                assert!(e.re.is_finite() && e.im.is_finite(), "s={s} ({i},{j}) {e}");
            }
            let d = g.bilinear(Probe::Diff(n / 2), Probe::Diff(n / 2));
            assert!(d.re.is_finite() && d.norm() > 0.0);
            if s.im == 0.0 {
                // a positive definite K(s): the diagonal is positive
                assert!(g.entry(n / 2, n / 2).re > 0.0);
            }
        }
    }
}
