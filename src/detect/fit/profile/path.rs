//! The regularisation choice of a whole-profile inversion: the continuation in
//! the penalty weight `lambda` down to the discrepancy target, its restarts
//! from other starts when it ends in a wrong basin, and the visible prefix of
//! the values (steps 2 to 4 of the method in [`super`]).

use super::{
    band_start, bounds_of, check_counts, defect_start, laplace, pre_pass, DefectFitter, Elem,
    Problem, ProfileOptions, Space,
};
use crate::chain::Defect;
use crate::detect::data::laplace::LaplaceObs;
use crate::detect::data::observations::Observations;
use crate::detect::fit::model::Model;
use crate::detect::search::lsq::{covariance, levenberg_marquardt, LmOptions};
use crate::error::Result;
use nalgebra::DMatrix;

/// The regularised profile (the continuation with its restarts) at the
/// noise level `sigma`, or, when it is `estimated`, at the level the
/// residual of a first continuation to its end gives: that level, the
/// Laplace observation and its misfit's name, and the path (its iterations
/// those of both passes).
pub(super) fn regularised_path(
    obs: &Observations,
    model: &Model,
    opts: &ProfileOptions,
    defect_fit: Option<DefectFitter>,
    space: &Space,
    mut sigma: f64,
    estimated: bool,
) -> Result<(f64, LaplaceObs, String, Path)> {
    let (nf, np) = (space.elems.len(), space.params.len());
    let mut iterations = 0usize;
    // the continuation with its restarts on `l` (at noise level `sigma`)
    let restarts = |l: &LaplaceObs, sigma: f64, target: Option<f64>| {
        continuation_restarts(
            l,
            &|| pre_pass(obs, model, sigma, nf),
            &|| band_start(obs, model, sigma, space, opts),
            &|| defect_fit.and_then(|f| defect_start(f, obs, model, space, opts)),
            space,
            opts,
            target,
        )
    };
    // pass 1 (noise unknown): the continuation to its end, sigma from the residual
    if estimated {
        let (l, _) = laplace(obs, model, sigma, nf)?;
        check_counts(&l, nf + np)?;
        let path = restarts(&l, sigma, None)?;
        iterations += path.iterations;
        let chi2 = space.problem(&l).data_chi2(&path.theta)?;
        let dof = l.dof().saturating_sub(nf + np).max(1) as f64;
        let ratio = (chi2 / dof).sqrt();
        if ratio.is_finite() && ratio > 0.0 {
            sigma *= ratio;
        }
    }
    let (l, misfit) = laplace(obs, model, sigma, nf)?;
    check_counts(&l, nf + np)?;
    let dof = l.dof() as f64;
    let target = dof + 2.0 * (2.0 * dof).sqrt();
    let mut path = restarts(&l, sigma, Some(target))?;
    path.iterations += iterations;
    Ok((sigma, l, misfit, path))
}

/// Free values in order of distance from the observed mass (masses first
/// at equal distance).
pub(super) fn depth_order(elems: &[Elem]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..elems.len()).collect();
    order.sort_by(|&a, &b| {
        elems[a]
            .depth
            .total_cmp(&elems[b].depth)
            .then((elems[a].kind as u8).cmp(&(elems[b].kind as u8)))
            .then(a.cmp(&b))
    });
    order
}

/// The result of a continuation: values, final weight, stages, iterations.
pub(super) struct Path {
    pub(super) theta: Vec<f64>,
    pub(super) lambda: f64,
    pub(super) stages: usize,
    pub(super) iterations: usize,
}

/// The continuation (module docs) on `l` from `start`. `target`: stop once
/// the data chi-square is at most this (`None`: run to `lambda_min`).
pub(super) fn continuation(
    l: &LaplaceObs,
    space: &Space,
    opts: &ProfileOptions,
    target: Option<f64>,
    start: Vec<f64>,
) -> Result<Path> {
    let mut theta = start;
    let bounds = bounds_of(space, opts.bound);
    let lm_opts = LmOptions {
        max_iter: opts.max_iter,
        ..LmOptions::default()
    };
    // the first weight: the data chi-square of the start (at least the
    // number of data), so that the penalty holds the first stage near the
    // uniform chain and the continuation follows a path from it
    let chi2_start = space.problem(l).data_chi2(&theta)?;
    let lambda0 = opts
        .lambda
        .unwrap_or_else(|| chi2_start.max(l.dof() as f64));
    let stages_max = if opts.lambda.is_some() {
        1
    } else {
        (1.0 / opts.lambda_min).log10().ceil() as usize + 1
    };
    let mut prob = Problem {
        lambda: lambda0,
        eps: opts.eps,
        ..space.problem(l)
    };
    let mut path = Path {
        theta: Vec::new(),
        lambda: lambda0,
        stages: 0,
        iterations: 0,
    };
    for stage in 0..stages_max {
        path.lambda = lambda0 * 10f64.powi(-(stage as i32));
        prob.lambda = path.lambda;
        let fit = levenberg_marquardt(&prob, &theta, &bounds, &lm_opts)?;
        path.iterations += fit.iterations;
        path.stages += 1;
        theta = fit.theta;
        if let Some(t) = target {
            if prob.data_chi2(&theta)? <= t {
                break;
            }
        }
    }
    path.theta = theta;
    Ok(path)
}

/// Starts of the continuation after the uniform chain (and the pre-pass),
/// as factors on every free value.
pub(super) const RESTART_SCALES: [f64; 4] = [0.7, 1.4, 0.5, 2.0];

/// A data chi-square this many times its target marks a wrong basin.
pub(super) const BASIN_FACTOR: f64 = 3.0;

/// A start grown from the sensor (layer stripping): the continuation with
/// only the nearest 1, 2, 4, ... values free (in [`depth_order`]), the
/// others held at their current values, each warm-started from the last;
/// returns the values and the iterations spent.
pub(super) fn depth_start(
    l: &LaplaceObs,
    space: &Space,
    opts: &ProfileOptions,
    target: Option<f64>,
) -> Result<(Vec<f64>, usize)> {
    let nf = space.elems.len();
    let order = depth_order(&space.elems);
    let mut theta = space.start(1.0);
    let mut iterations = 0;
    let mut len = 1;
    while len < nf {
        let free: Vec<usize> = order[..len].to_vec();
        let held: Vec<Defect> = (0..nf)
            .filter(|i| !free.contains(i))
            .map(|i| space.elems[i].defect(theta[i]))
            .collect();
        let sub = Space {
            base: space.base.clone(),
            fixed: space.fixed.iter().copied().chain(held).collect(),
            elems: free
                .iter()
                .map(|&i| Elem {
                    start: theta[i],
                    ..space.elems[i]
                })
                .collect(),
            params: space.params.clone(),
        };
        let start: Vec<f64> = free
            .iter()
            .map(|&i| theta[i])
            .chain(theta[nf..].iter().copied())
            .collect();
        let path = continuation(l, &sub, opts, target, start)?;
        iterations += path.iterations;
        for (k, &i) in free.iter().enumerate() {
            theta[i] = path.theta[k];
        }
        let np = space.params.len();
        theta[nf..nf + np].copy_from_slice(&path.theta[len..len + np]);
        len *= 2;
    }
    Ok((theta, iterations))
}

/// [`continuation`] from the uniform chain; while the fit stays far from
/// the data (a data chi-square above [`BASIN_FACTOR`] times the target),
/// again from the frequency-continuation start ([`band_start`]), the
/// layer-stripping start ([`depth_start`]), from the answer
/// of the continuation on `pre` (the same data weighted otherwise, see
/// [`pre_pass`]), then from the uniform chain
/// scaled by each of [`RESTART_SCALES`]; the lowest data chi-square wins
/// (its iterations are those of every path run).
pub(super) fn continuation_restarts(
    l: &LaplaceObs,
    pre: &dyn Fn() -> Result<Option<LaplaceObs>>,
    band: &dyn Fn() -> Result<(Vec<f64>, usize)>,
    defects: &dyn Fn() -> Option<Vec<f64>>,
    space: &Space,
    opts: &ProfileOptions,
    target: Option<f64>,
) -> Result<Path> {
    let data_chi2 = |theta: &[f64]| space.problem(l).data_chi2(theta);
    let dof = l.dof() as f64;
    let good = target.unwrap_or(dof + 2.0 * (2.0 * dof).sqrt()) * BASIN_FACTOR;
    let mut best = continuation(l, space, opts, target, space.start(1.0))?;
    let mut best_chi2 = data_chi2(&best.theta)?;
    let mut iterations = best.iterations;
    let mut starts: Vec<Vec<f64>> = Vec::new();
    if best_chi2 > good {
        // frequency continuation: the low frequencies first
        let (theta, it) = band()?;
        iterations += it;
        starts.push(theta);
        // the few-defects answer (the data-first defect fit)
        starts.extend(defects());
        // layer stripping: the values nearest the sensor first
        let (theta, it) = depth_start(l, space, opts, target)?;
        iterations += it;
        starts.push(theta);
    }
    if best_chi2 > good {
        if let Some(p) = pre()? {
            let first = continuation(&p, space, opts, None, space.start(1.0))?;
            iterations += first.iterations;
            starts.push(first.theta);
        }
    }
    starts.extend(RESTART_SCALES.iter().map(|&f| space.start(f)));
    for from in starts {
        if best_chi2 <= good {
            break;
        }
        let c = continuation(l, space, opts, target, from)?;
        iterations += c.iterations;
        let chi2 = data_chi2(&c.theta)?;
        if chi2 < best_chi2 {
            best = c;
            best_chi2 = chi2;
        }
    }
    best.iterations = iterations;
    Ok(best)
}

/// The longest prefix of `order` whose values all have `2 SE <= change
/// max(u, theta)` (a heavy value is judged relative to itself)
/// with the prefix (and the `n_params` chain parameters, the last columns of
/// `jac`) free; by bisection on the prefix length.
pub(super) fn visible_prefix(
    jac: &DMatrix<f64>,
    elems: &[Elem],
    theta: &[f64],
    order: &[usize],
    n_params: usize,
    change: f64,
) -> usize {
    let nf = elems.len();
    let ok = |len: usize| -> bool {
        let cols: Vec<usize> = order[..len]
            .iter()
            .copied()
            .chain(nf..nf + n_params)
            .collect();
        if cols.is_empty() {
            return true;
        }
        let sub = jac.select_columns(&cols);
        let Ok(cov) = covariance(&sub) else {
            return false;
        };
        order[..len].iter().enumerate().all(|(k, &i)| {
            let se = cov[(k, k)].max(0.0).sqrt();
            se.is_finite() && 2.0 * se <= change * elems[i].uniform.max(theta[i])
        })
    };
    if ok(nf) {
        return nf;
    }
    let (mut lo, mut hi) = (0usize, nf);
    while hi - lo > 1 {
        let mid = (lo + hi) / 2;
        if ok(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}
