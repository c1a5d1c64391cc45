//! Modal misfit: a chain against measured modes (the modal-property
//! difference of structural model updating), one [`MeasurementModel`].
//!
//! The chain's survey modes ([`survey_modes`]: the undamped modes of an
//! undamped chain, the damped poles' frequencies, ratios and realised
//! shapes of a damped one) are paired one-to-one
//! with the measured ones by shape first, frequency second
//! ([`ModalMisfit::pairing`]): among the model modes whose shape over the
//! measured masses explains a measured shape about as well as the best
//! one's (at many masses, the mode of highest modal assurance criterion
//! `MAC(a, b) = (a.b)^2 / ((a.a)(b.b))` alone), the one of the smallest
//! whole chi-square; a mode measured at fewer than two masses takes the
//! nearest free frequency. Each pair gives
//!
//! * a frequency residual `(f_j - f_meas) / se_f`, `f_j = omega_j / (2 pi)`
//!   (Hz when the chain is in SI units);
//! * with a damped nominal chain ([`ModalMisfit::with_damping_of`]) and a
//!   measured ratio, a damping residual `(zeta_j - zeta_meas) / se_zeta`
//!   (a damper's change shows there first; an undamped model would take
//!   it up with a spring);
//! * shape residuals `(c a_i - b_i) / se_i` at the measured masses, with the
//!   model's shape `a` scaled by the weighted least-squares factor `c` onto
//!   the measured `b` (any scaling of the data; one degree of freedom per
//!   mode goes to `c`).
//!
//! Standard errors come from the table (`frequency_se`, `damping_se`,
//! `phi_J_se`) or from [`ModalWeights`] (default 1% of the frequency, 25%
//! of the damping ratio and 5% of the mode's largest measured component);
//! a fit without given errors scales its standard errors by its residual.
//!
//! ```
//! use springmass::{Chain, chain::Boundary, time::modal::undamped_modes};
//! use springmass::detect::data::modes::{MeasuredMode, MeasuredModes, ShapeEntry};
//! use springmass::detect::misfit::modal::{ModalMisfit, ModalWeights};
//! use springmass::detect::model::MeasurementModel;
//! let chain = Chain::new(3)?.with_boundaries(Boundary::Fixed, Boundary::Free)?;
//! let m = undamped_modes(&chain)?;
//! let mode = |j: usize| MeasuredMode {
//!     frequency: m.omega[j] / std::f64::consts::TAU, frequency_se: None, damping: None, damping_se: None,
//!     shape: (0..3).map(|i| ShapeEntry { mass: i + 1, value: 2.0 * m.shapes[(i, j)], se: None }).collect() };
//! let data = MeasuredModes::new(vec![mode(0), mode(1)])?;
//! let misfit = ModalMisfit::new(data, 3, ModalWeights::default())?;
//! assert!(misfit.chi2(&chain)? < 1e-20);                  // the truth fits exactly
//! assert_eq!(misfit.dof(), 2 + 2 * (3 - 1));               // one scale per shape
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::chain::Chain;
use crate::detect::data::modes::{MeasuredMode, MeasuredModes};
use crate::detect::model::MeasurementModel;
use crate::error::{Error, Result};
use crate::sensitivity::Param;
use crate::time::survey_modes::{is_damped, survey_modes, SurveyModes};
use nalgebra::DMatrix;
use std::f64::consts::TAU;

/// Standard errors assumed where the table gives none.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModalWeights {
    /// A frequency's standard error relative to it (default 0.01).
    pub frequency_rel: f64,
    /// A shape component's standard error relative to the mode's largest
    /// measured component (default 0.05).
    pub shape_rel: f64,
    /// A damping ratio's standard error relative to it (default 0.25;
    /// ratios below [`DAMPING_FLOOR`] take it of the floor): damping is
    /// the least precise modal property a survey gives.
    pub damping_rel: f64,
}

/// The smallest damping ratio a relative standard error is taken of
/// (0.005): a ratio of 0.001 is not known to 0.00025.
pub const DAMPING_FLOOR: f64 = 0.005;

impl Default for ModalWeights {
    fn default() -> ModalWeights {
        ModalWeights {
            frequency_rel: 0.01,
            shape_rel: 0.05,
            damping_rel: 0.25,
        }
    }
}

impl ModalWeights {
    /// # Errors
    /// A value not in `(0, 1]` (fields `frequency_rel`, `shape_rel`,
    /// `damping_rel`).
    pub fn check(&self) -> Result<()> {
        for (f, v) in [
            ("frequency_rel", self.frequency_rel),
            ("shape_rel", self.shape_rel),
            ("damping_rel", self.damping_rel),
        ] {
            if !(v > 0.0 && v <= 1.0) {
                return Err(Error::invalid(f, v, "a relative standard error in (0, 1]"));
            }
        }
        Ok(())
    }
}

/// One measured mode with its standard errors resolved.
#[derive(Clone, Debug)]
pub(crate) struct Target {
    /// Frequency (Hz).
    pub(crate) frequency: f64,
    /// Its standard error.
    pub(crate) frequency_se: f64,
    /// `(0-based mass, value, se)`.
    pub(crate) shape: Vec<(usize, f64, f64)>,
    /// The damping ratio and its standard error, when measured.
    pub(crate) damping: Option<(f64, f64)>,
    /// Whether the table gave that standard error (or no ratio).
    pub(crate) damping_se_given: bool,
    /// Whether the table gave the frequency's standard error.
    pub(crate) frequency_se_given: bool,
    /// Whether the table gave every shape component's standard error.
    pub(crate) shape_se_given: bool,
}

impl Target {
    fn new(m: &MeasuredMode, w: &ModalWeights) -> Target {
        let top = m.shape.iter().map(|e| e.value.abs()).fold(0.0, f64::max);
        let shape_se = w.shape_rel * if top > 0.0 { top } else { 1.0 };
        Target {
            frequency: m.frequency,
            frequency_se: m.frequency_se.unwrap_or(w.frequency_rel * m.frequency),
            shape: m
                .shape
                .iter()
                .map(|e| (e.mass - 1, e.value, e.se.unwrap_or(shape_se)))
                .collect(),
            damping: m.damping.map(|z| {
                (
                    z,
                    m.damping_se.unwrap_or(w.damping_rel * z.max(DAMPING_FLOOR)),
                )
            }),
            damping_se_given: m.damping.is_none() || m.damping_se.is_some(),
            frequency_se_given: m.frequency_se.is_some(),
            shape_se_given: m.shape.iter().all(|e| e.se.is_some()),
        }
    }

    /// Whether the shape can be compared (two components or more).
    fn has_shape(&self) -> bool {
        self.shape.len() >= 2
    }

    /// The model shape `j` at the measured masses.
    fn model_shape(&self, modes: &SurveyModes, j: usize) -> Vec<f64> {
        self.shape
            .iter()
            .map(|&(i, ..)| modes.shapes[(i, j)])
            .collect()
    }

    /// The shape residuals' chi-square against model mode `j` at its best
    /// scale ([`shape_residuals`]; 0 without a comparable shape).
    fn shape_chi2(&self, modes: &SurveyModes, j: usize) -> f64 {
        if !self.has_shape() {
            return 0.0;
        }
        let mut r = Vec::with_capacity(self.shape.len());
        shape_residuals(&self.model_shape(modes, j), self, &mut r);
        r.iter().map(|v| v * v).sum()
    }
}

/// How much worse (in chi-square) a model mode's shape may explain a
/// measured shape than the best mode's does and still be a candidate
/// partner of it ([`ModalMisfit::pairing`]): 25, five standard errors in
/// one component.
pub const SHAPE_TIE: f64 = 25.0;

/// `(a.b)^2 / ((a.a)(b.b))`, 0 for a zero vector.
pub fn mac(a: &[f64], b: &[f64]) -> f64 {
    let dot = |x: &[f64], y: &[f64]| x.iter().zip(y).map(|(p, q)| p * q).sum::<f64>();
    let den = dot(a, a) * dot(b, b);
    if den > 0.0 {
        dot(a, b).powi(2) / den
    } else {
        0.0
    }
}

/// The measured modes of `data` with their standard errors resolved, and
/// whether the table gave every one; checked against `n`-mass chains.
///
/// # Errors
/// A shape at a mass beyond `n` (field `modes.phi_J`); more modes than
/// the chain has (field `modes`); bad `weights`.
pub(crate) fn targets(
    data: &MeasuredModes,
    n: usize,
    weights: ModalWeights,
) -> Result<(Vec<Target>, bool)> {
    weights.check()?;
    data.check_chain(n)?;
    if data.len() > n {
        return Err(Error::invalid(
            "modes",
            format!("{} modes", data.len()),
            format!("at most n = {n} (an n-mass chain has n modes)"),
        ));
    }
    let given_errors = data
        .modes()
        .iter()
        .all(|m| m.frequency_se.is_some() && m.shape.iter().all(|e| e.se.is_some()));
    let targets = data
        .modes()
        .iter()
        .map(|m| Target::new(m, &weights))
        .collect();
    Ok((targets, given_errors))
}

/// Measured modes as a [`MeasurementModel`] (see the module docs).
#[derive(Clone, Debug)]
pub struct ModalMisfit {
    targets: Vec<Target>,
    n: usize,
    given_errors: bool,
    /// Whether measured damping ratios are compared (a damped nominal).
    damped: bool,
    weights: ModalWeights,
}

impl ModalMisfit {
    /// The misfit of `data` against `n`-mass chains.
    ///
    /// # Errors
    /// A shape at a mass beyond `n` (field `modes.phi_J`); more modes than
    /// the chain has (field `modes`); bad `weights`.
    pub fn new(data: MeasuredModes, n: usize, weights: ModalWeights) -> Result<ModalMisfit> {
        let (targets, given_errors) = targets(&data, n, weights)?;
        Ok(ModalMisfit {
            targets,
            n,
            given_errors,
            damped: false,
            weights,
        })
    }

    /// The standard errors the table does not give and the misfit assumes,
    /// as `(assumed weights, missing columns)`, e.g. `("1% frequency",
    /// "frequency_se")`; `None` when the table gives every one.
    pub fn assumed(&self) -> Option<(String, String)> {
        let w = &self.weights;
        let pct = |v: f64| format!("{}%", 100.0 * v);
        let mut what = Vec::new();
        let mut cols = Vec::new();
        if self.targets.iter().any(|t| !t.frequency_se_given) {
            what.push(format!("{} frequency", pct(w.frequency_rel)));
            cols.push("frequency_se");
        }
        if self
            .targets
            .iter()
            .any(|t| t.has_shape() && !t.shape_se_given)
        {
            what.push(format!("{} shape", pct(w.shape_rel)));
            cols.push("phi_J_se");
        }
        if self.uses_damping() && self.targets.iter().any(|t| !t.damping_se_given) {
            what.push(format!("{} damping ratio", pct(w.damping_rel)));
            cols.push("damping_se");
        }
        (!what.is_empty()).then(|| (what.join(", "), cols.join(", ")))
    }

    /// Compare the measured damping ratios too when `nominal` is damped
    /// (its chains' ratios are then a model of the measured ones; an
    /// undamped nominal says nothing of them, and they are left out).
    pub fn with_damping_of(mut self, nominal: &Chain) -> ModalMisfit {
        self.damped = is_damped(nominal);
        self
    }

    /// Whether measured damping ratios are part of the misfit.
    pub fn uses_damping(&self) -> bool {
        self.damped && self.targets.iter().any(|t| t.damping.is_some())
    }

    /// Whether the table has damping ratios the misfit leaves out (an
    /// undamped nominal chain).
    pub fn ignores_damping(&self) -> bool {
        !self.damped && self.targets.iter().any(|t| t.damping.is_some())
    }

    /// Whether every standard error came from the table (then `chi^2` is a
    /// goodness-of-fit test; otherwise the weights are assumed).
    pub fn errors_given(&self) -> bool {
        self.given_errors
            && (!self.uses_damping() || self.targets.iter().all(|t| t.damping_se_given))
    }

    /// The model mode paired with each measured mode (0-based indices into
    /// `modes`), one-to-one: a measured shape is paired with one of the
    /// model modes whose shape explains it about as well as the best one
    /// does (the shape chi-square at its best scale within [`SHAPE_TIE`]; at many masses
    /// that is the highest-MAC mode alone), choosing among them by the
    /// pair's whole chi-square (frequency and shape), the smallest pairs
    /// first; at two or three masses several modes' shapes agree, and the
    /// frequency tells them apart (pairing by MAC alone took the wrong one,
    /// and exact data were fitted to a wrong chain). A mode left without
    /// one of those, or measured at fewer than two masses, takes the free
    /// mode of the smallest such chi-square (for a bare frequency: the
    /// nearest free frequency).
    pub fn pairing(&self, modes: &SurveyModes) -> Vec<usize> {
        let nm = modes.omega.len();
        let mut pair: Vec<Option<usize>> = vec![None; self.targets.len()];
        let mut taken = vec![false; nm];
        let cost = |t: &Target, j: usize, shape: f64| {
            ((modes.omega[j] / TAU - t.frequency) / t.frequency_se).powi(2) + shape
        };
        // each target's shape chi-square against every model mode (0
        // without a comparable shape)
        let shapes: Vec<Vec<f64>> = self
            .targets
            .iter()
            .map(|t| (0..nm).map(|j| t.shape_chi2(modes, j)).collect())
            .collect();
        let mut cands: Vec<(f64, usize, usize)> = Vec::new();
        for (t, target) in self
            .targets
            .iter()
            .enumerate()
            .filter(|(_, t)| t.has_shape())
        {
            let best = shapes[t].iter().copied().fold(f64::INFINITY, f64::min);
            cands.extend(
                (0..nm)
                    .filter(|&j| shapes[t][j] <= best + SHAPE_TIE)
                    .map(|j| (cost(target, j, shapes[t][j]), t, j)),
            );
        }
        cands.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
        for (_, t, j) in cands {
            if pair[t].is_none() && !taken[j] {
                pair[t] = Some(j);
                taken[j] = true;
            }
        }
        // shaped modes first (their shapes are the surer guide), then the
        // bare frequencies
        let order = (0..self.targets.len()).filter(|&t| self.targets[t].has_shape());
        let order = order.chain((0..self.targets.len()).filter(|&t| !self.targets[t].has_shape()));
        for t in order.collect::<Vec<_>>() {
            if pair[t].is_none() {
                let c = |j: usize| cost(&self.targets[t], j, shapes[t][j]);
                let j = (0..nm)
                    .filter(|&j| !taken[j])
                    .min_by(|&a, &b| c(a).total_cmp(&c(b)))
                    .expect("no more measured modes than model modes");
                pair[t] = Some(j);
                taken[j] = true;
            }
        }
        pair.into_iter()
            .map(|p| p.expect("every mode paired"))
            .collect()
    }

    /// The chain's survey modes ([`survey_modes`]).
    ///
    /// # Errors
    /// A chain of another size than the data's (field `n`); the eigen
    /// solvers' errors; fewer oscillating modes than measured ones (a
    /// heavily damped chain).
    pub fn modes_of(&self, chain: &Chain) -> Result<SurveyModes> {
        if chain.n() != self.n {
            return Err(Error::invalid(
                "n",
                chain.n(),
                format!("the data's n = {}", self.n),
            ));
        }
        let modes = survey_modes(chain)?;
        if modes.len() < self.targets.len() {
            return Err(Error::Numerical {
                method: "modal misfit".into(),
                reason: format!(
                    "the chain has {} oscillating modes for {} measured ones (the others are overdamped)",
                    modes.len(),
                    self.targets.len()
                ),
            });
        }
        Ok(modes)
    }
}

/// The shape residuals of model mode `j` against `target`, its complex
/// shape (a damped chain's, [`SurveyModes::complex_shapes`]) realised as a
/// survey does: turned most real, or normalised to the measured mass where
/// the measured shape is largest (a reference), and its real part taken;
/// whichever explains the measured shape better (the two differ by the
/// square of the mode's complexity, which a precise survey of strongly
/// complex modes sees). A real mode has one realisation.
fn realised_shape_residuals(modes: &SurveyModes, j: usize, target: &Target, out: &mut Vec<f64>) {
    let start = out.len();
    shape_residuals(&target.model_shape(modes, j), target, out);
    let Some(complex) = &modes.complex_shapes else {
        return;
    };
    let Some(&(reference, ..)) = target
        .shape
        .iter()
        .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
    else {
        return;
    };
    let pivot = complex[(reference, j)];
    if pivot.norm() == 0.0 {
        return;
    }
    let other: Vec<f64> = target
        .shape
        .iter()
        .map(|&(i, ..)| (complex[(i, j)] / pivot).re)
        .collect();
    let mut alt = Vec::with_capacity(target.shape.len());
    shape_residuals(&other, target, &mut alt);
    let sq = |r: &[f64]| r.iter().map(|v| v * v).sum::<f64>();
    if sq(&alt) < sq(&out[start..]) {
        out.truncate(start);
        out.extend(alt);
    }
}

/// The weighted scale `c` taking `a` onto `b` and the residuals `(c a - b)/se`.
fn shape_residuals(a: &[f64], target: &Target, out: &mut Vec<f64>) {
    let (mut num, mut den) = (0.0, 0.0);
    for (ai, &(_, b, se)) in a.iter().zip(&target.shape) {
        let w = 1.0 / (se * se);
        num += w * ai * b;
        den += w * ai * ai;
    }
    let c = if den > 0.0 { num / den } else { 0.0 };
    out.extend(
        a.iter()
            .zip(&target.shape)
            .map(|(ai, &(_, b, se))| (c * ai - b) / se),
    );
}

impl MeasurementModel for ModalMisfit {
    fn name(&self) -> &'static str {
        "modal"
    }

    fn dof(&self) -> usize {
        self.targets
            .iter()
            .map(|t| {
                1 + usize::from(self.damped && t.damping.is_some())
                    + if t.has_shape() { t.shape.len() - 1 } else { 0 }
            })
            .sum()
    }

    fn residuals(&self, chain: &Chain) -> Result<Vec<f64>> {
        let modes = self.modes_of(chain)?;
        let pair = self.pairing(&modes);
        let mut r = Vec::with_capacity(self.dof() + self.targets.len());
        for (target, &j) in self.targets.iter().zip(&pair) {
            r.push((modes.omega[j] / TAU - target.frequency) / target.frequency_se);
            if let (true, Some((z, se))) = (self.damped, target.damping) {
                r.push((modes.zeta[j] - z) / se);
            }
            if target.has_shape() {
                realised_shape_residuals(&modes, j, target, &mut r);
            }
        }
        Ok(r)
    }

    fn jacobian(&self, _chain: &Chain, _params: &[Param]) -> Result<Option<DMatrix<f64>>> {
        Ok(None)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chain::{Boundary, Defect};
    use crate::detect::data::modes::ShapeEntry;
    use crate::time::modal::undamped_modes;

    fn measured(chain: &Chain, which: &[usize], at: &[usize]) -> MeasuredModes {
        let m = undamped_modes(chain).unwrap();
        let modes = which
            .iter()
            .map(|&j| MeasuredMode {
                frequency: m.omega[j] / TAU,
                frequency_se: None,
                damping: None,
                damping_se: None,
                shape: at
                    .iter()
                    .map(|&i| ShapeEntry {
                        mass: i,
                        value: -3.0 * m.shapes[(i - 1, j)],
                        se: None,
                    })
                    .collect(),
            })
            .collect();
        MeasuredModes::new(modes).unwrap()
    }

    #[test]
    fn pairing_follows_shapes_not_order() {
        let chain = Chain::new(6).unwrap();
        let data = measured(&chain, &[1, 4], &[1, 2, 3, 4, 5, 6]);
        let misfit = ModalMisfit::new(data, 6, ModalWeights::default()).unwrap();
        let modes = survey_modes(&chain).unwrap();
        assert_eq!(misfit.pairing(&modes), vec![1, 4]);
        assert!(misfit.chi2(&chain).unwrap() < 1e-20);
    }

    #[test]
    fn a_changed_spring_is_seen() {
        let truth = Chain::new(5)
            .unwrap()
            .with_boundaries(Boundary::Fixed, Boundary::Free)
            .unwrap()
            .with_defect(Defect::Spring { at: 2, k: 0.6 })
            .unwrap();
        let data = measured(&truth, &[0, 1], &[1, 3, 5]);
        let misfit = ModalMisfit::new(data, 5, ModalWeights::default()).unwrap();
        let nominal = truth.uniform();
        assert!(misfit.chi2(&truth).unwrap() < 1e-20);
        assert!(misfit.chi2(&nominal).unwrap() > 10.0);
        assert_eq!(misfit.residuals(&truth).unwrap().len(), 2 + 2 * 3);
    }

    #[test]
    fn bad_sizes_are_refused() {
        let chain = Chain::new(3).unwrap();
        let data = measured(&chain, &[0, 1, 2], &[1, 3]);
        assert!(ModalMisfit::new(data.clone(), 2, ModalWeights::default()).is_err());
        let m = ModalMisfit::new(data, 3, ModalWeights::default()).unwrap();
        assert!(m.chi2(&Chain::new(4).unwrap()).is_err());
        let w = ModalWeights {
            frequency_rel: 0.0,
            ..ModalWeights::default()
        };
        assert!(w.check().is_err());
    }
}
