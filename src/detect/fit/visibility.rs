//! How deep the data see: the standard error of a change of each mass of
//! the chain, one at a time, through the fit's own observations, and the
//! distance from the sensor up to which a given change would show
//! ([`Visibility`], the report of the defects the data cannot see).

use crate::chain::{Chain, Defect};
use crate::detect::data::laplace::LaplaceObs;
use crate::error::Result;
use crate::sensitivity::Param;
use serde::Serialize;

/// How deep the data see a change of one mass (the rest of the chain as
/// fitted): the report of the defects the data cannot see.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Visibility {
    /// The relative change of the uniform mass it is stated for.
    pub change: f64,
    /// The observed mass.
    pub observe: usize,
    /// The largest distance from the observed mass up to which a change of
    /// `change` at any one mass would show at two standard errors (`None`:
    /// not even at the observed mass).
    pub depth: Option<usize>,
    /// The standard error of a change of each mass (`1..=n`), the others
    /// held.
    pub se: Vec<f64>,
    /// Fitted defects beyond `depth` (their positions): the data cannot
    /// tell them from the uniform chain at this noise.
    pub hidden: Vec<usize>,
}

impl Visibility {
    /// One line: how deep the data see, and which defects they do not.
    pub fn line(&self) -> String {
        let n = self.se.len();
        let far = (self.observe - 1).max(n - self.observe);
        let mut s = match self.depth {
            Some(d) if d == far => format!(
                "the data see a {}% mass change at every mass (2 SE)",
                self.change * 100.0
            ),
            Some(d) => format!(
                "the data see a {}% mass change up to {} masses from mass {} (2 SE); a defect beyond would not be seen",
                self.change * 100.0,
                d,
                self.observe
            ),
            None => format!(
                "the data do not see a {}% mass change anywhere (2 SE)",
                self.change * 100.0
            ),
        };
        if !self.hidden.is_empty() {
            s.push_str(&format!(
                "; fitted defects beyond that depth (not resolved): {:?}",
                self.hidden
            ));
        }
        s
    }
}

/// [`Visibility`] of a change of `change` (relative to the uniform mass) at
/// every mass of `chain`, seen through the observations `l` (whitened, or
/// weighted by the data's errors): the standard error of one mass changed
/// alone is `1 / |J_j|` with `J_j` the column of the whitened Jacobian.
/// `defects` are the fitted defects' positions (named when beyond the
/// depth); `scale` multiplies every standard error (the ratio of the noise
/// level to the one `l` is weighted at). O(n) per node.
///
/// # Errors
/// As the forward model at the nodes.
pub fn visibility(
    l: &LaplaceObs,
    chain: &Chain,
    observe: usize,
    change: f64,
    defects: &[usize],
    scale: f64,
) -> Result<Visibility> {
    let n = chain.n();
    let mut probe = chain.clone();
    let mut cols = vec![usize::MAX; n];
    for (i, d) in chain.defects().iter().enumerate() {
        if let Defect::Mass { at, .. } = *d {
            cols[at - 1] = i;
        }
    }
    let mut next = chain.defects().len();
    for (i, c) in cols.iter_mut().enumerate() {
        if *c == usize::MAX {
            probe = probe.with_defect(Defect::Mass {
                at: i + 1,
                m: chain.mass(),
            })?;
            *c = next;
            next += 1;
        }
    }
    let params: Vec<Param> = cols.iter().map(|&c| Param::Defect(c)).collect();
    let j = l.jacobian(&probe, &params)?;
    let se: Vec<f64> = (0..n)
        .map(|c| {
            let norm = j.column(c).norm();
            if norm > 0.0 {
                scale / norm
            } else {
                f64::INFINITY
            }
        })
        .collect();
    let sees = |i: usize| 2.0 * se[i - 1] <= change * chain.mass();
    let far = (observe - 1).max(n - observe);
    let mut depth = None;
    for dist in 0..=far {
        let all = [observe.checked_sub(dist), Some(observe + dist)]
            .into_iter()
            .flatten()
            .filter(|&i| i >= 1 && i <= n)
            .all(sees);
        if !all {
            break;
        }
        depth = Some(dist);
    }
    let hidden = defects
        .iter()
        .copied()
        .filter(|&at| depth.is_none_or(|d| at.abs_diff(observe) > d))
        .collect();
    Ok(Visibility {
        change,
        observe,
        depth,
        se,
        hidden,
    })
}
