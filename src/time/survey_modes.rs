//! The modes a modal survey measures, of any chain: the natural frequency
//! `|p| / (2 pi)`, the damping ratio `-Re p / |p|` and a real shape, from
//! each oscillating pole `p` of `det(M p^2 + D p + K) = 0`.
//!
//! * **Undamped chain**: the undamped modes ([`undamped_modes`], the same
//!   numbers), ratios 0.
//! * **Proportional damping** (`D = alpha M + beta K`, and the `modal`
//!   model): the undamped frequencies and shapes are exact (`|p| = omega`);
//!   the ratios are [`natural_modes`]'s, exact there too.
//! * **Any other damping** (dampers between storeys that differ, a damper
//!   changed, grounded dampers not proportional to the masses): the
//!   quadratic eigenproblem's poles and complex shapes
//!   ([`Modes::quadratic`]). Each complex shape `psi` is turned to be as
//!   real as it can be (by the phase `-arg(sum_i psi_i^2) / 2`, which
//!   maximises the norm of its real part) and its real part taken, the
//!   real mode an experimental modal analysis reports; other ways of
//!   realising a complex mode differ from it by the square of its
//!   imaginary part, as the real part differs from the undamped shape.
//!
//! Modes that do not oscillate (real poles, near-critical pairs) are not
//! what a survey measures and are left out, so a heavily damped chain has
//! fewer than `n` survey modes.
//!
//! ```
//! use springmass::{Chain, Defect, chain::Damping, time::survey_modes::survey_modes};
//! let nominal = Chain::new(6)?.with_damping(Damping::Between { c: 0.05 })?;
//! let m = survey_modes(&nominal)?;                   // stiffness-proportional: zeta = c omega / (2 k)
//! assert!((m.zeta[0] - 0.05 * m.omega[0] / 2.0).abs() < 1e-12);
//! let changed = nominal.with_defect(Defect::Damper { at: 2, d: 0.5 })?;
//! let c = survey_modes(&changed)?;                   // a damper changed: complex modes
//! assert!(c.zeta[0] > m.zeta[0] && (c.omega[0] / m.omega[0] - 1.0).abs() < 0.05);
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::chain::{Chain, Damping};
use crate::error::{Error, Result};
use crate::time::modal::{
    natural_modes, proportional_damping, undamped_modes, Modes, UndampedModes,
};
use nalgebra::DMatrix;
use num_complex::Complex64;

/// A chain's survey modes, in increasing natural frequency.
#[derive(Clone, Debug, PartialEq)]
pub struct SurveyModes {
    /// Natural frequency `|p|` (rad per unit of time), increasing.
    pub omega: Vec<f64>,
    /// Damping ratio `-Re p / |p|` (0 undamped).
    pub zeta: Vec<f64>,
    /// Column `j` is mode `j`'s real shape, row `i` mass `i + 1` (any scale).
    pub shapes: DMatrix<f64>,
    /// The complex shapes the real ones were realised from (the quadratic
    /// path; `None` where the modes are real), same layout: a survey that
    /// realised them otherwise (normalised to a reference mass, say) is
    /// compared with them.
    pub complex_shapes: Option<DMatrix<Complex64>>,
}

impl SurveyModes {
    /// Number of modes.
    pub fn len(&self) -> usize {
        self.omega.len()
    }

    /// Whether there is none.
    pub fn is_empty(&self) -> bool {
        self.omega.is_empty()
    }
}

/// Whether `chain` has any damping (a damper or the modal model's ratios).
pub fn is_damped(chain: &Chain) -> bool {
    chain.damping().is_modal()
        || chain
            .dampers()
            .iter()
            .chain(&chain.spring_dampers())
            .any(|&d| d != 0.0)
}

/// The survey modes of `chain` (see the module docs).
///
/// # Errors
/// The eigen solvers' errors and size limits; a chain without an
/// oscillating mode.
pub fn survey_modes(chain: &Chain) -> Result<SurveyModes> {
    let damped = is_damped(chain);
    let modal = matches!(chain.damping(), Damping::Modal { .. });
    if damped && !modal && proportional_damping(chain).is_none() {
        return complex_survey_modes(chain);
    }
    let m = undamped_modes(chain)?;
    let zeta = if !damped {
        vec![0.0; m.omega.len()]
    } else if modal {
        natural_modes(chain)?
            .iter()
            .map(|z| z.zeta.unwrap_or(0.0))
            .collect()
    } else {
        proportional_ratios(chain, &m)
    };
    Ok(SurveyModes {
        zeta,
        omega: m.omega,
        shapes: m.shapes,
        complex_shapes: None,
    })
}

/// The damping ratios `phi^T D phi / (2 omega)` of proportionally damped
/// modes from their mass-normalised shapes (exact there; no second eigen
/// solve), 0 for a rigid-body mode.
fn proportional_ratios(chain: &Chain, m: &UndampedModes) -> Vec<f64> {
    let c = chain.coefficients();
    let n = chain.n();
    let top = m.omega.iter().fold(0.0_f64, |a, &w| a.max(w * w));
    (0..m.omega.len())
        .map(|j| {
            let w = m.omega[j];
            if w * w <= 64.0 * f64::EPSILON * top {
                return 0.0;
            }
            let x = |i: usize| {
                if i == 0 || i > n {
                    0.0
                } else {
                    m.shapes[(i - 1, j)]
                }
            };
            let grounded: f64 = (1..=n).map(|i| c.d[i - 1] * x(i) * x(i)).sum();
            let between: f64 = (0..=n).map(|k| c.c[k] * (x(k) - x(k + 1)).powi(2)).sum();
            (grounded + between) / (2.0 * w)
        })
        .collect()
}

/// The quadratic path's oscillating modes, realised.
fn complex_survey_modes(chain: &Chain) -> Result<SurveyModes> {
    let modes = Modes::quadratic(chain)?;
    let (poles, vecs) = modes
        .quadratic_poles()
        .expect("the quadratic path keeps its poles");
    let mut order: Vec<usize> = (0..poles.len()).filter(|&j| poles[j].im > 0.0).collect();
    if order.is_empty() {
        return Err(Error::Numerical {
            method: "survey modes".into(),
            reason: "the chain has no oscillating mode (every mode overdamped)".into(),
        });
    }
    order.sort_by(|&a, &b| poles[a].norm().total_cmp(&poles[b].norm()));
    let n = chain.n();
    let mut shapes = DMatrix::zeros(n, order.len());
    let mut complex = DMatrix::zeros(n, order.len());
    for (col, &j) in order.iter().enumerate() {
        let real = realise(&vecs[j]);
        for (i, v) in real.into_iter().enumerate() {
            shapes[(i, col)] = v;
            complex[(i, col)] = vecs[j][i];
        }
    }
    Ok(SurveyModes {
        omega: order.iter().map(|&j| poles[j].norm()).collect(),
        zeta: order
            .iter()
            .map(|&j| -poles[j].re / poles[j].norm())
            .collect(),
        shapes,
        complex_shapes: Some(complex),
    })
}

/// The real part of `psi` turned by the phase that maximises it.
fn realise(psi: &[Complex64]) -> Vec<f64> {
    let sum: Complex64 = psi.iter().map(|z| z * z).sum();
    let turn = Complex64::from_polar(1.0, -0.5 * sum.arg());
    psi.iter().map(|z| (z * turn).re).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chain::{Boundary, Defect};

    #[test]
    fn an_undamped_chain_gives_its_undamped_modes() {
        let c = Chain::new(5)
            .unwrap()
            .with_boundaries(Boundary::Fixed, Boundary::Free)
            .unwrap()
            .with_defect(Defect::Spring { at: 2, k: 0.7 })
            .unwrap();
        let s = survey_modes(&c).unwrap();
        let u = undamped_modes(&c).unwrap();
        assert!(s.complex_shapes.is_none());
        assert_eq!((s.omega, s.shapes), (u.omega, u.shapes));
        assert!(s.zeta.iter().all(|&z| z == 0.0));
    }

    #[test]
    fn proportional_damping_keeps_the_undamped_shapes() {
        let c = Chain::new(4)
            .unwrap()
            .with_d(0.2)
            .unwrap()
            .with_defect(Defect::Mass { at: 2, m: 2.0 })
            .unwrap()
            .with_defect(Defect::Damper { at: 2, d: 0.4 })
            .unwrap();
        let s = survey_modes(&c).unwrap();
        let u = undamped_modes(&c).unwrap();
        assert_eq!(s.shapes, u.shapes);
        for j in 0..4 {
            // d / m = 0.2 everywhere: zeta = 0.2 / (2 omega)
            assert!((s.zeta[j] - 0.1 / s.omega[j]).abs() < 1e-12);
        }
    }

    /// The poles of `[[0, I], [-M^-1 K, -M^-1 D]]` by a Schur form and the
    /// real shapes by a dense complex solve of `Q(p) psi = 0` with
    /// `psi_1 = 1`: a second method.
    #[test]
    fn complex_modes_match_a_dense_state_space_solve() {
        let c = Chain::new(6)
            .unwrap()
            .with_damping(Damping::Between { c: 0.03 })
            .unwrap()
            .with_defect(Defect::Damper { at: 2, d: 0.6 })
            .unwrap()
            .with_defect(Defect::Spring { at: 4, k: 0.7 })
            .unwrap();
        let s = survey_modes(&c).unwrap();
        let dense = crate::chain::dense_ref::assemble(&c);
        let (m, k, d) = (dense.m, dense.k, dense.c);
        let n = 6;
        let mut a = DMatrix::<f64>::zeros(2 * n, 2 * n);
        let minv = m.clone().try_inverse().unwrap();
        a.view_mut((0, n), (n, n)).fill_with_identity();
        a.view_mut((n, 0), (n, n)).copy_from(&(-&minv * &k));
        a.view_mut((n, n), (n, n)).copy_from(&(-&minv * &d));
        let mut ev: Vec<Complex64> = a
            .complex_eigenvalues()
            .iter()
            .copied()
            .filter(|z| z.im > 0.0)
            .collect();
        ev.sort_by(|x, y| x.norm().total_cmp(&y.norm()));
        assert_eq!(ev.len(), s.len());
        for (j, p) in ev.iter().enumerate() {
            assert!((p.norm() - s.omega[j]).abs() < 1e-10 * p.norm());
            assert!((-p.re / p.norm() - s.zeta[j]).abs() < 1e-10);
            let q = DMatrix::from_fn(n, n, |r, col| {
                Complex64::from(m[(r, col)]) * p * p
                    + Complex64::from(d[(r, col)]) * p
                    + Complex64::from(k[(r, col)])
            });
            // rows 2..n of Q psi = 0 with psi_1 = 1
            let sub = q.view((1, 1), (n - 1, n - 1)).into_owned();
            let rhs = -q.view((1, 0), (n - 1, 1)).into_owned();
            let rest = sub.lu().solve(&rhs).unwrap();
            let psi: Vec<Complex64> = std::iter::once(Complex64::from(1.0))
                .chain(rest.iter().copied())
                .collect();
            let real = realise(&psi);
            let col: Vec<f64> = s.shapes.column(j).iter().copied().collect();
            // the same real shape up to scale (sign included)
            let dot: f64 = real.iter().zip(&col).map(|(x, y)| x * y).sum();
            let scale = dot / col.iter().map(|y| y * y).sum::<f64>();
            for (x, y) in real.iter().zip(&col) {
                assert!(
                    (x - scale * y).abs() < 1e-8,
                    "mode {j}: {real:?} vs {col:?}"
                );
            }
        }
    }

    #[test]
    fn an_overdamped_chain_has_fewer_modes() {
        let c = Chain::new(3)
            .unwrap()
            .with_damping(Damping::Between { c: 0.01 })
            .unwrap()
            .with_defect(Defect::Damper { at: 0, d: 30.0 })
            .unwrap();
        let s = survey_modes(&c).unwrap();
        assert!(s.len() < 3 && !s.is_empty(), "{} modes", s.len());
    }
}
