//! The setup of a noisy fit ([`Setup`]: rules, screen, shortlist, slack,
//! weighting) and the Laplace data it fits ([`laplace_obs`]: the record's
//! transform at the rule's nodes, whitened or weighted).
//!
//! **Weighting** ([`Setup::weighting`]): the noise level belongs to the data.
//! By default ([`Weighting::Whitened`](crate::detect::data::whiten::Weighting::Whitened)) a Laplace misfit is a true chi-square:
//! the transformed values at the nodes carry the noise covariance
//! `C = sigma^2 B B^T` of the series transform ([`SeriesTransform`], `B` the
//! stacked real and imaginary transform weights) plus its model-error
//! estimate, and the residual is whitened by `C^{-1/2}` on the components
//! `f64` resolves ([`crate::detect::data::whiten`]), so `chi2 ~ chi-square(dof)`.
//! The real-axis data of a 1001-sample record hold only about 24-30
//! independent components whatever the number of nodes; the Bromwich line
//! keeps all 160. [`Weighting::Diagonal`](crate::detect::data::whiten::Weighting::Diagonal) (the earlier weighting) weights node
//! `q` by `w_q / v_q` (rule weight over the node's variance): it ignores the
//! strong correlation between nodes, is not chi-square distributed, and
//! recovers deep defects less often.
//!

use crate::chain::Chain;
use crate::detect::data::laplace::LaplaceObs;
use crate::detect::data::noise_model::NoiseModel;
use crate::detect::data::series::TimeData;
use crate::detect::misfit::quadrature::Rule;
#[cfg(doc)]
use crate::detect::misfit::time::TimeMisfit;
use crate::detect::misfit::MisfitKind;
use crate::error::{Error, Result};
use crate::time::modal::ModalResponse;
use crate::time::series::{LaplaceValue, SeriesTransform, TransformOptions};
use num_complex::Complex64;

/// Settings of a noisy fit.
#[derive(Clone, Debug)]
pub struct Setup {
    /// Real-axis rule.
    pub real_rule: Rule,
    /// Bromwich abscissa `sigma_B`.
    pub bromwich_sigma: f64,
    /// Bromwich rule in `omega`.
    pub bromwich_rule: Rule,
    /// Sets kept after the coarse pass (with a time misfit, each is
    /// refitted in the time domain).
    pub shortlist: usize,
    /// LM iterations of the coarse pass.
    pub coarse_iter: usize,
    /// Weighting of the Laplace misfits (used by [`laplace_obs`]).
    pub weighting: crate::detect::data::whiten::Weighting,
    /// Nodes of the screening observation ([`LaplaceObs::screen`]: every
    /// `Q / screen_nodes`-th node of the whitened data, whitened by its
    /// marginal covariance); 0 for none.
    pub screen_nodes: usize,
    /// Hypotheses kept by the screen for the coarse pass proper, at least
    /// (and one in 20 of them when there are more; the screen runs only
    /// when there are more hypotheses than this); 0: no screen.
    pub screen_keep: usize,
    /// Levenberg-Marquardt iterations per hypothesis on the screen.
    pub screen_iter: usize,
    /// Retry a screened hypothesis from heavier starts when a value ends on
    /// a bound, as the coarse pass proper does (default false: the retry
    /// is left to the coarse pass of the sets the screen keeps; it doubled
    /// the screen's cost on wrong sets, most of which end on a bound).
    pub screen_retry: bool,
    /// With the time misfit, the shortlist's sets refitted in the time
    /// domain: the best two on the Laplace line and every set whose Laplace
    /// chi-square is within `time_slack` of the best (default 25; see
    /// [`fit_general`](crate::detect::fit::general::fit_general)); `f64::INFINITY`: every set of the shortlist. The
    /// sets left out are not ranked: the runner-up is the best refitted
    /// set, and when it is more than the slack behind, a set left out may
    /// be closer (never within the slack).
    pub time_slack: f64,
    /// Fit the screen's and the coarse pass's sets on the rational form of
    /// their Laplace model ([`SetTables`](crate::detect::misfit::laplace_sets::SetTables), default true) where it applies;
    /// `false`: a transfer sweep per node and evaluation.
    pub rational_sets: bool,
    /// Time-domain Jacobian exact where it applies
    /// ([`TimeMisfit::jacobian`]); `false`: central differences throughout.
    pub exact_time_jacobian: bool,
    /// Fit every shortlisted set of the Laplace fine pass from its second
    /// start too (default false: ahead of a time-domain refit, only where
    /// the fit from the coarse values does not explain the whitened
    /// values, a chi-square above `K + 3 sqrt(2 K)` or below `K / 4`; see
    /// `explained_chi2`
    /// in [`fit_general`](crate::detect::fit::general::fit_general)'s
    /// source).
    pub every_second_start: bool,
}

impl Setup {
    /// Defaults (see the module docs): the real axis of the paper's
    /// residual (`MisfitSpec::default()`'s rule: 10 log-graded panels of 8
    /// points on [0, 300]); the Bromwich line of a record of the paper's
    /// chain ([`Setup::for_record`] without a record: `sigma_B = 0.05`,
    /// 10 x 8 points on `omega in [0, 4]`); shortlist 8,
    /// 12 coarse iterations. The value bounds are the unknowns' own
    /// ([`crate::detect::unknowns::KindBounds`]).
    ///
    /// # Errors
    /// Never in practice (fixed valid rules).
    pub fn new() -> Result<Setup> {
        Ok(Setup {
            real_rule: crate::detect::misfit::MisfitSpec::default().rule()?,
            bromwich_sigma: 0.05,
            bromwich_rule: Rule::gauss_legendre_uniform(0.0, 4.0, 10, 8)?,
            shortlist: 8,
            coarse_iter: 12,
            weighting: crate::detect::data::whiten::Weighting::default(),
            screen_nodes: 20,
            screen_keep: 40,
            screen_iter: 4,
            screen_retry: false,
            time_slack: 25.0,
            rational_sets: true,
            exact_time_jacobian: true,
            every_second_start: false,
        })
    }

    /// The setup of a record of length `t_end` (`None`: no record) of a
    /// chain like `chain`. The Bromwich line of sampled data is chosen from
    /// the record, not fixed as a scene's (`MisfitSpec`: `sigma = 0.1`, 40 x 8
    /// points, for exact-model values): its abscissa `sigma_B = max(10 /
    /// t_end, 0.05)` weighs the unrecorded tail by `e^{-10}` (a smaller one
    /// would see the truncation, a larger one less of the late echoes of
    /// deep defects), and its 80 nodes cover `omega` up to twice the chain's
    /// band `2 sqrt(k / mass)` (at least 4).
    ///
    /// # Errors
    /// Never in practice (valid rules).
    pub fn for_record(t_end: Option<f64>, chain: &Chain) -> Result<Setup> {
        let mut setup = Setup::new()?;
        if let Some(t) = t_end {
            setup.bromwich_sigma = (10.0 / t).max(0.05);
        }
        let band = chain.uniform_band();
        let w = (2.0 * band).max(4.0);
        if (w - 4.0).abs() > 1e-12 {
            setup.bromwich_rule = Rule::gauss_legendre_uniform(0.0, w, 10, 8)?;
        }
        Ok(setup)
    }

    /// The earlier path, kept as a baseline for benchmarks and tests: no
    /// screen (every hypothesis through the full coarse pass), each set's
    /// model by transfer sweeps, every set of the shortlist refitted in the
    /// time domain, time-domain Jacobians by central differences, every
    /// second start of the fine pass fitted. The defaults otherwise.
    ///
    /// # Errors
    /// As [`Setup::new`].
    pub fn reference() -> Result<Setup> {
        Ok(Setup {
            screen_nodes: 0,
            screen_keep: 0,
            time_slack: f64::INFINITY,
            rational_sets: false,
            exact_time_jacobian: false,
            every_second_start: true,
            ..Setup::new()?
        })
    }
}

/// The screening observation of whitened Laplace data: `count` nodes spread
/// evenly over the `s.len()` nodes, their rows and columns of the stacked
/// covariance `cov` (the marginal covariance of a subset is exact), whitened
/// with the default cutoff.
fn screen_obs(
    s: &[num_complex::Complex64],
    values: &[num_complex::Complex64],
    cov: &nalgebra::DMatrix<f64>,
    force_hat: Option<&[num_complex::Complex64]>,
    sensor: crate::detect::data::measurement::Sensor,
    count: usize,
) -> Result<LaplaceObs> {
    let q = s.len();
    let idx: Vec<usize> = (0..count)
        .map(|j| ((2 * j + 1) * q) / (2 * count))
        .collect();
    // stacked row of (node, im) in the full layout
    let rows = crate::time::series::stacked_rows(s);
    let row_of = |node: usize, im: bool| rows.iter().position(|&r| r == (node, im));
    let sub_s: Vec<_> = idx.iter().map(|&i| s[i]).collect();
    let sub_rows: Vec<usize> = crate::time::series::stacked_rows(&sub_s)
        .into_iter()
        .map(|(j, im)| row_of(idx[j], im).expect("a row of every node"))
        .collect();
    let m = sub_rows.len();
    let sub_cov = nalgebra::DMatrix::from_fn(m, m, |a, b| cov[(sub_rows[a], sub_rows[b])]);
    let wh = crate::detect::data::whiten::Whitening::new(
        &sub_cov,
        crate::detect::data::whiten::DEFAULT_CUTOFF,
    )?;
    let sub_values = idx.iter().map(|&i| values[i]).collect();
    LaplaceObs::whitened(sub_s, sub_values, wh.matrix().clone())?.with_measurement(
        sensor,
        force_hat.map(|f| idx.iter().map(|&i| f[i]).collect()),
    )
}

/// `int_0^{t_0} u(t) e^{-s t} dt` at the nodes `s`, with `u` the observed
/// response of `uniform` to the impulse and `t_0` the record's first time:
/// the transform of the part of the response before the record (`None`
/// when the record starts at the blow, `t_0 <= 0`, or is driven by a
/// measured force, whose record is not re-timed). Composite Gauss-Legendre
/// (8 points per panel, each panel at most 1.5 radians of the fastest
/// oscillation of `u e^{-s t}`). Exact for a defect whose echo reaches the
/// sensor after `t_0`; the head is a screening value for the shortlist
/// (the time refits compare the samples themselves).
///
/// # Errors
/// The uniform chain's modal errors.
fn head(data: &TimeData, uniform: &Chain, s: &[Complex64]) -> Result<Option<Vec<Complex64>>> {
    let t0 = data.t()[0];
    let m = data.measurement();
    if t0.is_nan() || t0 <= 0.0 || m.force().is_some() {
        return Ok(None);
    }
    let sensor = m.sensor();
    let u = ModalResponse::impulse_observable(uniform, sensor.at, sensor.kind)?;
    let band = uniform.uniform_band();
    let fastest = band + s.iter().fold(0.0f64, |a, z| a.max(z.norm()));
    let panels = ((t0 * fastest / 1.5).ceil() as usize).clamp(1, 1 << 20);
    let rule = Rule::gauss_legendre_uniform(0.0, t0, panels, 8)?;
    let x = u.eval_many(&rule.nodes);
    Ok(Some(
        s.iter()
            .map(|&z| {
                rule.nodes
                    .iter()
                    .zip(&rule.weights)
                    .zip(&x)
                    .map(|((&t, &w), &v)| w * v * (-z * t).exp())
                    .sum()
            })
            .collect(),
    ))
}

/// The record's transform at the nodes `s`, with the values' covariance
/// when `whitened` (one pass of the weights; under `noise` when it is
/// coloured), and the part before the first sample from `uniform`
/// ([`head`]) added to the values.
///
/// # Errors
/// As [`SeriesTransform`]; the uniform chain's modal errors.
fn record_transform(
    data: &TimeData,
    s: &[Complex64],
    whitened: bool,
    noise: &NoiseModel,
    uniform: Option<&Chain>,
) -> Result<(Vec<LaplaceValue>, Option<nalgebra::DMatrix<f64>>)> {
    let opts = TransformOptions {
        noise_sigma: Some(data.sigma()),
        ..TransformOptions::default()
    };
    let tr = SeriesTransform::new(data.t(), data.y(), &opts)?;
    let (mut vals, cov) = if !noise.is_white() {
        let (v, c) = tr.eval_with_coloured_covariance(s, &|a| noise.covariance_root_t(a))?;
        (v, whitened.then_some(c))
    } else if whitened {
        let (v, c) = tr.eval_with_covariance(s)?;
        (v, Some(c))
    } else {
        (tr.eval_many(s)?, None)
    };
    if let Some(head) = uniform.map(|c| head(data, c, s)).transpose()?.flatten() {
        for (v, h) in vals.iter_mut().zip(head) {
            v.value += h;
        }
    }
    Ok((vals, cov))
}

/// Laplace data at the nodes of `choice` (real axis or Bromwich) from the
/// sampled series of `data`, weighted as `setup.weighting` says:
///
/// * [`Weighting::Diagonal`](crate::detect::data::whiten::Weighting::Diagonal)(crate::detect::data::whiten::Weighting::Diagonal): node
///   `q` by the rule's weight over the node's variance, `w_q / v_q` (not a
///   chi-square: the transformed noise is correlated between nodes);
/// * [`Weighting::Whitened`](crate::detect::data::whiten::Weighting::Whitened)(crate::detect::data::whiten::Weighting::Whitened): the
///   full covariance of the transformed data
///   ([`SeriesTransform::data_covariance`], formed in one pass with the values by
///   [`SeriesTransform::eval_with_covariance`], plus `(1e-15 |X(s_q)|)^2` on the
///   diagonal for the rounding of the model), whitened with the default
///   cutoff ([`crate::detect::data::whiten`]): `chi^2` with [`LaplaceObs::dof`]
///   degrees of freedom at the true chain.
///
/// # Errors
/// [`Error::InvalidParameter`] for [`MisfitKind::Time`]; as [`SeriesTransform`].
pub fn laplace_obs(data: &TimeData, choice: MisfitKind, setup: &Setup) -> Result<LaplaceObs> {
    laplace_obs_under(data, choice, setup, &NoiseModel::White, None)
}

/// [`laplace_obs`] when the record's noise follows `noise` (`data`'s
/// sigma its innovation standard deviation): the values' covariance is
/// that of the coloured noise ([`NoiseModel::covariance_root_t`]), so the
/// whitened Laplace chi-square is a chi-square under the record model and
/// the time-domain refits keep their slack ([`Setup::time_slack`]).
/// With `uniform`, a record that starts after the blow (first sample at
/// `t_0 > 0`: cut short, or re-timed to a blow between two samples) has the
/// part of its transform before `t_0` taken from that chain (by composite Gauss-Legendre):
/// the model's transform is the whole response's.
///
/// # Errors
/// As [`laplace_obs`].
pub fn laplace_obs_under(
    data: &TimeData,
    choice: MisfitKind,
    setup: &Setup,
    noise: &NoiseModel,
    uniform: Option<&Chain>,
) -> Result<LaplaceObs> {
    let (s, w) = choice
        .laplace_nodes(&setup.real_rule, setup.bromwich_sigma, &setup.bromwich_rule)
        .ok_or_else(|| {
            Error::invalid(
                "misfit",
                choice.name(),
                "a Laplace misfit (real-axis or bromwich)",
            )
        })?;
    let whitened = setup.weighting == crate::detect::data::whiten::Weighting::Whitened;
    let (vals, cov) = record_transform(data, &s, whitened, noise, uniform)?;
    // a measured force: its transform by the same rule (noise-free input)
    let m = data.measurement();
    let force_hat = match m.force() {
        Some(f) => Some(
            SeriesTransform::new(data.t(), f, &TransformOptions::default())?
                .eval_many(&s)?
                .iter()
                .map(|v| v.value)
                .collect::<Vec<_>>(),
        ),
        None => None,
    };
    if let Some(mut cov) = cov {
        for (r, (q, _)) in crate::time::series::stacked_rows(&s)
            .into_iter()
            .enumerate()
        {
            cov[(r, r)] = (cov[(r, r)] + (1e-15 * vals[q].value.norm()).powi(2)).max(1e-300);
        }
        let wh = crate::detect::data::whiten::Whitening::new(
            &cov,
            crate::detect::data::whiten::DEFAULT_CUTOFF,
        )?;
        let values: Vec<_> = vals.iter().map(|v| v.value).collect();
        let screen = if setup.screen_nodes > 0 && setup.screen_nodes < s.len() {
            Some(screen_obs(
                &s,
                &values,
                &cov,
                force_hat.as_deref(),
                m.sensor(),
                setup.screen_nodes,
            )?)
        } else {
            None
        };
        let obs = LaplaceObs::whitened(s, values, wh.matrix().clone())?
            .with_measurement(m.sensor(), force_hat)?;
        return Ok(match screen {
            Some(sc) => obs.with_screen(sc),
            None => obs,
        });
    }
    let (values, weights) = diagonal_weights(&vals, &w);
    LaplaceObs::new(s, values, weights)?.with_measurement(m.sensor(), force_hat)
}

/// The values and their diagonal weights `w_q / v_q` (the rule's weight
/// over the node's noise and error variance, floored at the value's
/// rounding).
fn diagonal_weights(vals: &[LaplaceValue], w: &[f64]) -> (Vec<num_complex::Complex64>, Vec<f64>) {
    vals.iter()
        .zip(w)
        .map(|(v, wq)| {
            let var = v.noise_var.unwrap_or(0.0) + v.err * v.err;
            let var = var.max((1e-15 * v.value.norm()).powi(2)).max(1e-300);
            (v.value, wq / var)
        })
        .unzip()
}
