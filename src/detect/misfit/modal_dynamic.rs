//! The modal dynamic residual (MDR) of structural model updating: a chain
//! against measured modes through the equations of motion themselves, one
//! [`MeasurementModel`] beside the modal-property difference
//! ([`super::modal::ModalMisfit`]).
//!
//! A measured mode `j` (circular frequency `w_j = 2 pi f_j`, shape `b` at
//! the measured masses `m`) satisfies `(K - w_j^2 M) phi_j = 0` for the
//! true chain, where `phi_j` is `b` at `m` and unknown at the other masses
//! `u`. The residual `A_m b + A_u phi_u` (`A = K - w_j^2 M`, `A_m`, `A_u`
//! its columns at `m` and `u`) is minimised over `phi_u` in closed form (a
//! least-squares solve: variable projection), leaving
//! `r_j = (I - P_u) A_m b` with `P_u` the projector onto the columns `A_u`.
//! No eigen-solve and no mode pairing: each measured mode tests the chain
//! directly, and `n - |u|` = (measured masses) independent equations
//! remain per mode.
//!
//! The residual is whitened by its covariance propagated to first order
//! from the data's errors: a frequency error `se_w` moves it by
//! `-2 w M phi_j se_w`, a shape error `se_b` by `A_m se_b`, both projected
//! by `I - P_u`; `chi^2 = r^T C^+ r` (Cholesky of `C + a P_u`, which equals
//! the pseudo-inverse on the residual's subspace), so that at the true
//! chain `chi^2` follows a chi-square law with [`MeasurementModel::dof`]
//! degrees of freedom. Standard errors come from the table or the
//! [`ModalWeights`], as for the property difference; any scaling of a
//! shape gives the same `chi^2` (its errors scale with it).
//!
//! ```
//! use springmass::{Chain, Defect, chain::Boundary, time::modal::undamped_modes};
//! use springmass::detect::data::modes::{MeasuredMode, MeasuredModes, ShapeEntry};
//! use springmass::detect::misfit::{modal::ModalWeights, modal_dynamic::ModalDynamicResidual};
//! use springmass::detect::model::MeasurementModel;
//! let frame = Chain::new(4)?.with_boundaries(Boundary::Fixed, Boundary::Free)?;
//! let truth = frame.clone().with_defect(Defect::Spring { at: 2, k: 0.6 })?;
//! let m = undamped_modes(&truth)?;
//! let mode = |j: usize| MeasuredMode {
//!     frequency: m.omega[j] / std::f64::consts::TAU, frequency_se: None, damping: None, damping_se: None,
//!     shape: [1, 4].iter().map(|&i| ShapeEntry { mass: i, value: 3.0 * m.shapes[(i - 1, j)], se: None }).collect() };
//! let mdr = ModalDynamicResidual::new(MeasuredModes::new(vec![mode(0), mode(1)])?, 4, ModalWeights::default())?;
//! assert!(mdr.chi2(&truth)? < 1e-16);                     // the truth fits exactly
//! assert!(mdr.chi2(&frame)? > 1.0);                       // the nominal frame does not
//! assert_eq!(mdr.dof(), 4);                                // two measured masses per mode
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::chain::Chain;
use crate::detect::data::modes::MeasuredModes;
use crate::detect::misfit::modal::{targets, ModalWeights, Target};
use crate::detect::model::MeasurementModel;
use crate::error::{Error, Result};
use crate::sensitivity::Param;
use crate::time::modal::MAX_N_SYMMETRIC;
use nalgebra::{DMatrix, DVector};
use std::f64::consts::TAU;

/// Measured modes as the modal dynamic residual (see the module docs).
#[derive(Clone, Debug)]
pub struct ModalDynamicResidual {
    targets: Vec<Target>,
    n: usize,
    given_errors: bool,
}

impl ModalDynamicResidual {
    /// The residual of `data` against `n`-mass chains.
    ///
    /// # Errors
    /// `n` above [`MAX_N_SYMMETRIC`] (field `n`); a shape at a mass beyond
    /// `n` (field `modes.phi_J`); more modes than
    /// the chain has (field `modes`); a mode without any shape component
    /// (field `modes[i].phi`: the dynamic residual needs the shape); bad
    /// `weights`.
    pub fn new(data: MeasuredModes, n: usize, weights: ModalWeights) -> Result<Self> {
        if n > MAX_N_SYMMETRIC {
            return Err(Error::invalid(
                "n",
                n,
                format!(
                    "n <= {MAX_N_SYMMETRIC} for the modal dynamic residual (dense n x n solves)"
                ),
            ));
        }
        let (targets, given_errors) = targets(&data, n, weights)?;
        if let Some(i) = targets.iter().position(|t| t.shape.is_empty()) {
            return Err(Error::invalid(
                format!("modes[{i}].phi"),
                "no shape component",
                "at least one measured component per mode for the dynamic residual (the property difference takes frequencies alone)",
            ));
        }
        Ok(ModalDynamicResidual {
            targets,
            n,
            given_errors,
        })
    }

    /// Whether every standard error came from the table.
    pub fn errors_given(&self) -> bool {
        self.given_errors
    }
}

/// The chain's stiffness matrix (springs and grounds; spring `i` joins
/// masses `i` and `i + 1`, the walls at `0` and `n + 1`) and masses.
fn stiffness_and_masses(chain: &Chain) -> (DMatrix<f64>, Vec<f64>) {
    let (springs, grounds) = (chain.springs(), chain.grounds());
    let k = DMatrix::from_fn(chain.n(), chain.n(), |i, j| {
        if i == j {
            grounds[i] + springs[i] + springs[i + 1]
        } else if i.abs_diff(j) == 1 {
            -springs[i.max(j)]
        } else {
            0.0
        }
    });
    (k, chain.masses())
}

/// The whitened residual of one mode (see the module docs), appended to `out`.
fn mode_residuals(k: &DMatrix<f64>, mass: &[f64], t: &Target, out: &mut Vec<f64>) -> Result<()> {
    let n = mass.len();
    let (omega, omega_se) = (TAU * t.frequency, TAU * t.frequency_se);
    let w2 = omega * omega;
    let a = DMatrix::from_fn(n, n, |i, j| {
        k[(i, j)] - if i == j { w2 * mass[i] } else { 0.0 }
    });
    let mut measured = vec![false; n];
    for &(i, ..) in &t.shape {
        measured[i] = true;
    }
    let u: Vec<usize> = (0..n).filter(|&i| !measured[i]).collect();
    // A_m b, and A_m diag(se_b^2) A_m^T
    let mut v = DVector::<f64>::zeros(n);
    let mut x = DMatrix::<f64>::zeros(n, n);
    for &(i, b, se) in &t.shape {
        let col = a.column(i);
        v += col * b;
        x += (col * col.transpose()) * (se * se);
    }
    // the unmeasured components by least squares, and the projector P_u
    let mut phi = DVector::<f64>::zeros(n);
    for &(i, b, _) in &t.shape {
        phi[i] = b;
    }
    let p = if u.is_empty() {
        DMatrix::<f64>::zeros(n, n)
    } else {
        let au = a.select_columns(&u);
        let svd = au.clone().svd(true, true);
        let tol = 1e-12 * svd.singular_values.max().max(f64::MIN_POSITIVE);
        let phi_u = svd.solve(&(-&v), tol).map_err(|e| Error::Numerical {
            method: "modal dynamic residual".into(),
            reason: format!("the unmeasured components: {e}"),
        })?;
        for (c, &i) in u.iter().enumerate() {
            phi[i] = phi_u[c];
        }
        let uu = svd.u.expect("computed");
        let keep: Vec<usize> = (0..svd.singular_values.len())
            .filter(|&c| svd.singular_values[c] > tol)
            .collect();
        let ur = uu.select_columns(&keep);
        &ur * ur.transpose()
    };
    let q = DMatrix::<f64>::identity(n, n) - &p;
    // the least-squares residual A phi = (I - P_u) A_m b
    let r = &q * &v;
    // the frequency's effect: d/dw of -(w^2) M phi
    let g = DVector::from_iterator(n, (0..n).map(|i| 2.0 * omega * mass[i] * phi[i]));
    x += (&g * g.transpose()) * (omega_se * omega_se);
    let c = &q * x * &q;
    let rank = n - u.len();
    let alpha = (c.trace() / rank.max(1) as f64).max(f64::MIN_POSITIVE);
    let c_reg = c + p * alpha;
    let l = c_reg
        .clone()
        .cholesky()
        .or_else(|| (c_reg + DMatrix::identity(n, n) * (1e-12 * alpha)).cholesky())
        .ok_or_else(|| Error::Numerical {
            method: "modal dynamic residual".into(),
            reason: "the residual's covariance is not positive definite".into(),
        })?;
    let white = l
        .l()
        .solve_lower_triangular(&r)
        .ok_or_else(|| Error::Numerical {
            method: "modal dynamic residual".into(),
            reason: "the whitening solve failed".into(),
        })?;
    out.extend(white.iter());
    Ok(())
}

impl MeasurementModel for ModalDynamicResidual {
    fn name(&self) -> &'static str {
        "modal-dynamic"
    }

    /// One equation per measured component of each mode.
    fn dof(&self) -> usize {
        self.targets.iter().map(|t| t.shape.len()).sum()
    }

    fn residuals(&self, chain: &Chain) -> Result<Vec<f64>> {
        if chain.n() != self.n {
            return Err(Error::invalid(
                "n",
                chain.n(),
                format!("the data's n = {}", self.n),
            ));
        }
        let (k, mass) = stiffness_and_masses(chain);
        let mut out = Vec::with_capacity(self.n * self.targets.len());
        for t in &self.targets {
            mode_residuals(&k, &mass, t, &mut out)?;
        }
        Ok(out)
    }

    fn jacobian(&self, _chain: &Chain, _params: &[Param]) -> Result<Option<DMatrix<f64>>> {
        Ok(None)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chain::{Boundary, Defect};
    use crate::detect::data::modes::{MeasuredMode, ShapeEntry};
    use crate::time::modal::undamped_modes;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, StandardNormal};

    fn frame() -> Chain {
        Chain::new(6)
            .unwrap()
            .with_boundaries(Boundary::Fixed, Boundary::Free)
            .unwrap()
            .with_defects([
                Defect::Spring { at: 2, k: 0.7 },
                Defect::Mass { at: 5, m: 1.4 },
            ])
            .unwrap()
    }

    /// Modes `which` of `chain` at masses `at`, with relative noise
    /// `(fn, sn)` from `rng` (and the noise levels as the table's errors).
    fn measured(
        chain: &Chain,
        which: &[usize],
        at: &[usize],
        noise: Option<(f64, f64, &mut ChaCha8Rng)>,
    ) -> MeasuredModes {
        let m = undamped_modes(chain).unwrap();
        let mut noise = noise;
        let mut modes = Vec::new();
        for &j in which {
            let f = m.omega[j] / TAU;
            let top = at
                .iter()
                .map(|&i| m.shapes[(i - 1, j)].abs())
                .fold(0.0, f64::max);
            let (mut df, mut ds) = (vec![0.0], vec![0.0; at.len()]);
            let (mut fse, mut sse) = (None, None);
            if let Some((fr, sr, rng)) = noise.as_mut() {
                let z: f64 = StandardNormal.sample(*rng);
                df[0] = *fr * f * z;
                for d in &mut ds {
                    let z: f64 = StandardNormal.sample(*rng);
                    *d = *sr * top * z;
                }
                fse = Some(*fr * f);
                sse = Some(*sr * top);
            }
            modes.push(MeasuredMode {
                frequency: f + df[0],
                frequency_se: fse,
                damping: None,
                damping_se: None,
                shape: at
                    .iter()
                    .zip(&ds)
                    .map(|(&i, d)| ShapeEntry {
                        mass: i,
                        value: m.shapes[(i - 1, j)] + d,
                        se: sse,
                    })
                    .collect(),
            });
        }
        MeasuredModes::new(modes).unwrap()
    }

    #[test]
    fn the_truth_fits_exactly_and_a_change_shows() {
        let truth = frame();
        for at in [&[1usize, 2, 3, 4, 5, 6][..], &[2, 4, 6], &[6]] {
            let mdr = ModalDynamicResidual::new(
                measured(&truth, &[0, 1, 2], at, None),
                6,
                ModalWeights::default(),
            )
            .unwrap();
            assert!(mdr.chi2(&truth).unwrap() < 1e-18, "{at:?}");
            let other = truth
                .clone()
                .with_defect(Defect::Spring { at: 4, k: 0.9 })
                .unwrap();
            assert!(mdr.chi2(&other).unwrap() > 1e-3, "{at:?}");
            assert_eq!(mdr.dof(), 3 * at.len());
        }
    }

    #[test]
    fn chi_square_at_the_truth_follows_its_law() {
        // 400 noisy data sets: the mean chi2 / dof is 1 within its spread
        let truth = frame();
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let (mut sum, reps) = (0.0, 400);
        let mut dof = 0;
        for _ in 0..reps {
            let data = measured(&truth, &[0, 1, 2], &[1, 3, 6], Some((1e-4, 1e-3, &mut rng)));
            let mdr = ModalDynamicResidual::new(data, 6, ModalWeights::default()).unwrap();
            dof = mdr.dof();
            sum += mdr.chi2(&truth).unwrap();
        }
        let mean = sum / (reps * dof) as f64;
        // sd of the mean of chi2/dof: sqrt(2 / (reps dof)) = 0.0236
        assert!((mean - 1.0).abs() < 0.1, "mean chi2/dof {mean}");
    }

    #[test]
    fn bad_data_are_refused_naming_the_field() {
        let truth = frame();
        let field = |r: Result<ModalDynamicResidual>| match r {
            Err(Error::InvalidParameter { field, .. }) => field,
            other => panic!("{other:?}"),
        };
        let data = measured(&truth, &[0, 1], &[2, 6], None);
        assert_eq!(
            field(ModalDynamicResidual::new(data, 5, ModalWeights::default())),
            "modes.phi_6"
        );
        let no_shape = MeasuredModes::new(vec![MeasuredMode {
            frequency: 0.1,
            frequency_se: None,
            damping: None,
            damping_se: None,
            shape: vec![],
        }])
        .unwrap();
        assert_eq!(
            field(ModalDynamicResidual::new(
                no_shape,
                6,
                ModalWeights::default()
            )),
            "modes[0].phi"
        );
        let data = measured(&truth, &[0], &[2], None);
        let mdr = ModalDynamicResidual::new(data, 6, ModalWeights::default()).unwrap();
        assert!(mdr.residuals(&Chain::new(5).unwrap()).is_err());
        let data = measured(&truth, &[0], &[2], None);
        assert_eq!(
            field(ModalDynamicResidual::new(
                data,
                1_000_000,
                ModalWeights::default()
            )),
            "n"
        );
    }
}
