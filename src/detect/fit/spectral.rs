//! Spectral start: the mass profile of a chain from the poles and residues
//! of `X_1(s)` (an inverse eigenvalue problem solved by Lanczos, after
//! Gladwell's *Inverse Problems in Vibration*).
//!
//! For an undamped chain with known springs `kappa_0..kappa_n` (the walls'
//! included, `0` at a free end) and unknown masses `m_i`,
//!
//! `X_1(s) = gamma sum_j r_j / (s^2 + lambda_j)`, `r_j = v_{1j}^2 / m_1`,
//!
//! where `lambda_j`, `v_j` are the eigenpairs of the Jacobi matrix
//! `J = M^{-1/2} K M^{-1/2}` (diagonal `(kappa_{i-1} + kappa_i) / m_i`,
//! off-diagonal `-kappa_i / sqrt(m_i m_{i+1})`). So `sum_j r_j = 1 / m_1`, the
//! weights `w_j = m_1 r_j = v_{1j}^2` sum to one, and the Lanczos process on
//! `diag(lambda)` from the start vector `sqrt(w)` rebuilds `J` row by row
//! (full reorthogonalisation); each mass is then read off the diagonal,
//! `m_i = (kappa_{i-1} + kappa_i) / J_ii`, without a recursion along the
//! chain. The off-diagonal gives a second value of every product
//! `m_i m_{i+1}`; their disagreement ([`SpectralStart::consistency`]) says how
//! many digits the reconstruction kept.
//!
//! **From poles and residues** ([`Spectrum::from_poles`]): a pole `p` of
//! `X_1` with residue `c` gives `lambda = |p|^2` and `r = Re(2 p c) / gamma`:
//! exact for an undamped chain (and for one mass with any damping), a start
//! for a lightly damped one (with dampers on the masses the modes are
//! complex and the formula holds to first order in the damping).
//!
//! **Where it loses digits.** Every mode is needed: a spectrum of `K < n`
//! modes gives the `K x K` chain with the same `K` modes, not the first `K`
//! masses (refused with a typed error). The Lanczos recursion is
//! ill-conditioned when a weight `w_j` falls below f64's resolution, and
//! that is physics, not the algorithm: a mass lighter than its neighbours
//! binds a mode above the band, localised around it, whose first component
//! decays exponentially with its depth; a profile drawn at random localises
//! most modes (Anderson localisation). The masses beyond are then lost, and
//! [`SpectralStart::consistency`] says so. Measured by this module's tests
//! (worst relative mass error, with the spectrum from a symmetric eigensolver):
//! three heavy defects (3, 1.5, 2) at n = 20, 60, 100: 5e-14, 3e-13, 2e-12;
//! a light mass 0.4 at depth 10 of 20: 8e-11, at depth 30 of 60: lost
//! (error 1.8, consistency 0.65); masses drawn in `[0.3, 5]`: 3e-13 at
//! n = 10, lost at n = 40 (consistency 1.7). With damping `d = 0.01` on
//! every mass (n = 12, poles of the damped `X_1`) the start is within 5%.
//!
//! ```
//! use springmass::{Chain, Defect};
//! use springmass::detect::fit::spectral::{masses_from_spectrum, Spectrum};
//! let truth = Chain::paper(8)?.with_d(0.0)?.with_defects([
//!     Defect::Mass { at: 3, m: 2.5 }, Defect::Mass { at: 6, m: 0.4 }])?;
//! let poles = springmass::time::modal::ModalResponse::impulse(&truth, 1)?.poles();
//! let spec = Spectrum::from_poles(&poles, truth.gamma())?;
//! let start = masses_from_spectrum(&truth.springs(), &spec)?;
//! assert!((start.masses[2] - 2.5).abs() < 1e-10 && (start.masses[5] - 0.4).abs() < 1e-10);
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::error::{Error, Result};
use crate::time::modal::PoleResidue;

/// The undamped spectral data of `X_1`: `X_1(s) / gamma = sum_j r_j / (s^2 + lambda_j)`.
#[derive(Clone, Debug, PartialEq)]
pub struct Spectrum {
    /// `lambda_j = omega_j^2 > 0`, distinct.
    pub lambda: Vec<f64>,
    /// `r_j > 0`.
    pub residue: Vec<f64>,
}

impl Spectrum {
    /// From the poles of `X_1` in the upper half plane (conjugates and real
    /// poles are skipped) and their residues, for impulse `gamma`.
    ///
    /// # Errors
    /// `gamma` not positive and finite (field `gamma`); no oscillatory pole
    /// (field `poles`).
    pub fn from_poles(poles: &[PoleResidue], gamma: f64) -> Result<Spectrum> {
        if !(gamma.is_finite() && gamma > 0.0) {
            return Err(Error::invalid("gamma", gamma, "> 0 and finite"));
        }
        let mut modes: Vec<(f64, f64)> = poles
            .iter()
            .filter(|p| p.order == 1 && p.pole.im > 0.0)
            .map(|p| (p.pole.norm_sqr(), (2.0 * p.pole * p.residue).re / gamma))
            .collect();
        if modes.is_empty() {
            return Err(Error::invalid(
                "poles",
                0,
                "at least one pole with a positive imaginary part",
            ));
        }
        modes.sort_by(|a, b| a.0.total_cmp(&b.0));
        Ok(Spectrum {
            lambda: modes.iter().map(|m| m.0).collect(),
            residue: modes.iter().map(|m| m.1).collect(),
        })
    }
}

/// The reconstructed mass profile.
#[derive(Clone, Debug, PartialEq)]
pub struct SpectralStart {
    /// `m_1..m_n` (0-based vector).
    pub masses: Vec<f64>,
    /// Largest relative disagreement between `m_i m_{i+1}` from the diagonal
    /// and from the off-diagonal of the rebuilt Jacobi matrix: about the
    /// relative error of the masses (`1e-12`: twelve digits kept).
    pub consistency: f64,
}

/// Rebuild the masses from `spectrum` and the springs `kappa_0..kappa_n`
/// (as [`crate::Chain::springs`] gives them; `0` at a free end).
///
/// # Errors
/// [`Error::InvalidParameter`]: `springs` with fewer than 2 entries or a
/// negative or non-finite one, or an inner spring that is zero (field
/// `springs`); `spectrum` with a length other than `n`, unequal lengths, a
/// non-positive or non-finite value, or repeated eigenvalues (field
/// `spectrum`). [`Error::Numerical`] when the Lanczos recursion breaks down
/// (a weight too small for f64) or gives a non-positive diagonal.
pub fn masses_from_spectrum(springs: &[f64], spectrum: &Spectrum) -> Result<SpectralStart> {
    check_springs(springs)?;
    let n = springs.len() - 1;
    let (lam, res) = (&spectrum.lambda, &spectrum.residue);
    check_spectrum(lam, res, n)?;
    let total: f64 = res.iter().sum();
    let m1 = 1.0 / total;
    let (diag, off) = lanczos(lam, res.iter().map(|r| (r / total).sqrt()).collect())?;
    let masses: Vec<f64> = diag
        .iter()
        .enumerate()
        .map(|(i, &a)| (springs[i] + springs[i + 1]) / a)
        .collect();
    if masses.iter().any(|m| !(m.is_finite() && *m > 0.0)) {
        return Err(Error::Numerical {
            method: "spectral start (Lanczos)".into(),
            reason: "a non-positive diagonal: the spectrum is not an undamped chain's with these springs".into(),
        });
    }
    // m_1 twice (residue sum, diagonal) and every product twice
    let mut consistency = (masses[0] / m1 - 1.0).abs();
    for (i, &b) in off.iter().enumerate() {
        let prod = springs[i + 1] * springs[i + 1] / (b * b);
        consistency = consistency.max((prod / (masses[i] * masses[i + 1]) - 1.0).abs());
    }
    Ok(SpectralStart {
        masses,
        consistency,
    })
}

/// `springs`: at least 2, finite, `>= 0`, the inner ones `> 0`.
fn check_springs(springs: &[f64]) -> Result<()> {
    if springs.len() < 2 || springs.iter().any(|k| !(k.is_finite() && *k >= 0.0)) {
        return Err(Error::invalid(
            "springs",
            format!("{} values", springs.len()),
            "n + 1 >= 2 finite values >= 0 (the wall springs included)",
        ));
    }
    if springs[1..springs.len() - 1].contains(&0.0) {
        return Err(Error::invalid(
            "springs",
            "an inner spring of 0",
            "inner springs > 0 (a connected chain)",
        ));
    }
    Ok(())
}

/// `n` eigenvalues and residues, positive and finite, the eigenvalues distinct.
fn check_spectrum(lam: &[f64], res: &[f64], n: usize) -> Result<()> {
    if lam.len() != n || res.len() != n {
        return Err(Error::invalid(
            "spectrum",
            format!("{} eigenvalues, {} residues", lam.len(), res.len()),
            format!("all n = {n} modes (a truncated spectrum determines a shorter chain)"),
        ));
    }
    if lam
        .iter()
        .chain(res.iter())
        .any(|v| !(v.is_finite() && *v > 0.0))
    {
        return Err(Error::invalid(
            "spectrum",
            "a value <= 0 or not finite",
            "eigenvalues and residues > 0 and finite (an undamped chain fixed at one end at least)",
        ));
    }
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| lam[a].total_cmp(&lam[b]));
    if order.windows(2).any(|w| lam[w[0]] == lam[w[1]]) {
        return Err(Error::invalid(
            "spectrum",
            "repeated eigenvalue",
            "distinct eigenvalues (a chain's are)",
        ));
    }
    Ok(())
}

/// Lanczos on `diag(lam)` from the unit vector `q` (the square roots of the
/// weights), full reorthogonalisation (twice): the Jacobi matrix's diagonal
/// and off-diagonal.
///
/// # Errors
/// [`Error::Numerical`] when the recursion breaks down.
fn lanczos(lam: &[f64], mut q: Vec<f64>) -> Result<(Vec<f64>, Vec<f64>)> {
    let n = lam.len();
    let mut qs: Vec<Vec<f64>> = Vec::with_capacity(n);
    let mut diag = Vec::with_capacity(n);
    let mut off = Vec::with_capacity(n.saturating_sub(1));
    let scale = lam.iter().fold(0.0f64, |m, v| m.max(*v));
    for i in 0..n {
        let mut z: Vec<f64> = lam.iter().zip(&q).map(|(l, x)| l * x).collect();
        let a: f64 = q.iter().zip(&z).map(|(x, y)| x * y).sum();
        diag.push(a);
        qs.push(q.clone());
        if i + 1 == n {
            break;
        }
        for _ in 0..2 {
            for p in &qs {
                let c: f64 = p.iter().zip(&z).map(|(x, y)| x * y).sum();
                for (zv, pv) in z.iter_mut().zip(p) {
                    *zv -= c * pv;
                }
            }
        }
        let b = z.iter().map(|v| v * v).sum::<f64>().sqrt();
        if !(b.is_finite() && b > 1e3 * f64::EPSILON * scale) {
            return Err(Error::Numerical {
                method: "spectral start (Lanczos)".into(),
                reason: format!(
                    "the recursion broke down at row {}: a weight or a gap below f64 resolution",
                    i + 1
                ),
            });
        }
        off.push(b);
        q = z.iter().map(|v| v / b).collect();
    }
    Ok((diag, off))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chain::{Boundary, Chain, Defect};
    use crate::time::modal::ModalResponse;

    /// An undamped chain with masses drawn in [0.3, 5] (seeded LCG).
    fn chain(n: usize, seed: u64, free_left: bool) -> Chain {
        let mut x = seed.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut next = || {
            x = x
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (x >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut c = Chain::paper(n).unwrap().with_d(0.0).unwrap();
        if free_left {
            c = c.with_boundaries(Boundary::Free, Boundary::Fixed).unwrap();
        }
        c.with_defects((1..=n).map(|at| Defect::Mass {
            at,
            m: 0.3 + 4.7 * next(),
        }))
        .unwrap()
    }

    /// The spectrum by an independent route: the symmetric eigenproblem of
    /// the Jacobi matrix (nalgebra).
    fn spectrum_of(c: &Chain) -> Spectrum {
        let (m, k, n) = (c.masses(), c.springs(), c.n());
        let j = nalgebra::DMatrix::from_fn(n, n, |a, b| {
            if a == b {
                (k[a] + k[a + 1]) / m[a]
            } else if a.abs_diff(b) == 1 {
                -k[a.max(b)] / (m[a] * m[b]).sqrt()
            } else {
                0.0
            }
        });
        let e = nalgebra::SymmetricEigen::new(j);
        Spectrum {
            lambda: e.eigenvalues.iter().copied().collect(),
            residue: (0..n)
                .map(|c| e.eigenvectors[(0, c)].powi(2) / m[0])
                .collect(),
        }
    }

    fn worst(c: &Chain, s: &SpectralStart) -> f64 {
        c.masses()
            .iter()
            .zip(&s.masses)
            .map(|(t, m)| (m / t - 1.0).abs())
            .fold(0.0, f64::max)
    }

    #[test]
    fn rebuilds_fixed_and_free_chains_from_eigenpairs_and_from_poles() {
        for (n, seed, free) in [(1, 1, false), (2, 2, false), (7, 3, true), (10, 4, false)] {
            let c = chain(n, seed, free);
            let s = masses_from_spectrum(&c.springs(), &spectrum_of(&c)).unwrap();
            assert!(worst(&c, &s) < 1e-11, "n = {n}: {}", worst(&c, &s));
            assert!(s.consistency < 1e-10, "{}", s.consistency);
            let poles = ModalResponse::impulse(&c, 1).unwrap().poles();
            let p = masses_from_spectrum(
                &c.springs(),
                &Spectrum::from_poles(&poles, c.gamma()).unwrap(),
            )
            .unwrap();
            assert!(worst(&c, &p) < 1e-9, "poles, n = {n}: {}", worst(&c, &p));
        }
    }

    #[test]
    fn lightly_damped_data_give_a_start() {
        // d = 0.01 on every mass: the undamped formula is a first-order start
        let c = chain(12, 9, false).with_d(0.01).unwrap();
        let poles = ModalResponse::impulse(&c, 1).unwrap().poles();
        let s = masses_from_spectrum(
            &c.springs(),
            &Spectrum::from_poles(&poles, c.gamma()).unwrap(),
        )
        .unwrap();
        assert!(worst(&c, &s) < 0.05, "{}", worst(&c, &s));
    }

    #[test]
    fn loses_digits_with_n() {
        // measured loss (quoted in the module docs). Heavy defects in a
        // uniform chain keep every mode extended; a light mass binds a mode
        // above the band, localised around it, whose first component falls
        // below f64 with depth; a profile drawn at random localises modes
        // (Anderson) and loses the far end
        let sparse = |n: usize, light: f64| {
            Chain::paper(n)
                .unwrap()
                .with_d(0.0)
                .unwrap()
                .with_defects([
                    Defect::Mass { at: n / 5, m: 3.0 },
                    Defect::Mass {
                        at: n / 2,
                        m: light,
                    },
                    Defect::Mass {
                        at: 4 * n / 5,
                        m: 2.0,
                    },
                ])
                .unwrap()
        };
        // (label, chain, resolvable in f64)
        let cases = [
            ("heavy defects, n = 20", sparse(20, 1.5), true),
            ("heavy defects, n = 60", sparse(60, 1.5), true),
            ("heavy defects, n = 100", sparse(100, 1.5), true),
            ("light mass 0.4 at 10 of 20", sparse(20, 0.4), true),
            ("light mass 0.4 at 30 of 60", sparse(60, 0.4), false),
            ("random profile, n = 10", chain(10, 100, false), true),
            ("random profile, n = 40", chain(40, 102, false), false),
        ];
        for (what, c, ok) in &cases {
            match masses_from_spectrum(&c.springs(), &spectrum_of(c)) {
                Ok(s) => {
                    let w = worst(c, &s);
                    eprintln!(
                        "{what}: worst relative mass error {w:.1e}, consistency {:.1e}",
                        s.consistency
                    );
                    if *ok {
                        assert!(w < 1e-8, "{what}: {w}");
                    }
                    // the consistency check sees the loss
                    assert!(w <= 1e3 * s.consistency.max(1e-14), "{what}");
                    assert_eq!(*ok, s.consistency < 1e-6, "{what}: {}", s.consistency);
                }
                Err(e) => {
                    eprintln!("{what}: {e}");
                    assert!(!ok, "{what}: {e}");
                }
            }
        }
    }

    #[test]
    fn bad_input_is_a_typed_error() {
        let c = chain(5, 1, false);
        let s = spectrum_of(&c);
        let field = |r: Result<SpectralStart>| match r {
            Err(Error::InvalidParameter { field, .. }) => field,
            other => panic!("{other:?}"),
        };
        let short = Spectrum {
            lambda: s.lambda[..4].to_vec(),
            residue: s.residue[..4].to_vec(),
        };
        assert_eq!(
            field(masses_from_spectrum(&c.springs(), &short)),
            "spectrum"
        );
        let mut neg = s.clone();
        neg.residue[2] = -1.0;
        assert_eq!(field(masses_from_spectrum(&c.springs(), &neg)), "spectrum");
        let mut rep = s.clone();
        rep.lambda[1] = rep.lambda[0];
        assert_eq!(field(masses_from_spectrum(&c.springs(), &rep)), "spectrum");
        assert_eq!(field(masses_from_spectrum(&[1.0], &s)), "springs");
        assert_eq!(
            field(masses_from_spectrum(&[1.0, 0.0, 1.0, 1.0, 1.0, 1.0], &s)),
            "springs"
        );
        assert!(Spectrum::from_poles(&[], 1.0).is_err());
        assert!(Spectrum::from_poles(&[], 0.0).is_err());
    }
}
