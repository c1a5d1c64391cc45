//! What the inverse side starts from: observations and their noise model.
//!
//! | module | what |
//! |---|---|
//! | [`measurement`] | what a record measured (displacement, velocity or acceleration of a mass) and what drove it (the impulse or a measured force) |
//! | [`observations`] | the data-first entry: a sampled series (`t`, `x`, optional noise sigma) or Laplace values with errors |
//! | [`series`] | a sampled series with its white-noise level ([`series::TimeData`]) |
//! | [`laplace`] | Laplace-domain values at nodes, weighted or whitened ([`laplace::LaplaceObs`]) |
//! | [`modes`] | measured modes (frequencies, damping ratios, mode shapes at a few masses) from an experimental modal analysis |
//! | [`force_window`] | the force window of modal testing: a measured force zeroed outside its pulse |
//! | [`exact`] | values of `X_1` at any node for the mass-only Woodbury kernel ([`exact::Data`]) |
//! | [`trigger`] | when the blow came: the impulse's time on the record's axis, detected, and the record re-timed to it |
//! | [`noise_model`] | the record's noise model: white or AR(p), its prediction-error whitening, Burg's estimate and the order by BIC |
//! | [`nuisance`] | the sensor's offset and drift, profiled out by projection |
//! | [`whiten`] | whitening of the correlated Laplace-domain noise of a transformed series |
//! | [`whitener`] | the whitening product `W X`, with `W` rotated to zeros before its diagonal that the product skips |

pub mod ambient;
pub mod exact;
pub mod force_window;
pub mod laplace;
pub mod measurement;
pub mod modes;
pub mod noise_model;
pub mod nuisance;
pub mod observations;
pub mod series;
pub mod trigger;
pub mod whiten;
pub mod whitener;

/// Laplace values at nodes: `nodes` nodes, `values` values and as many of a
/// third array (`third = (its length, its name)`), at least one node; else
/// [`crate::Error::InvalidParameter`] on `field` with the lengths and
/// `allowed`.
pub(crate) fn check_lengths(
    field: &str,
    nodes: usize,
    values: usize,
    third: (usize, &str),
    allowed: &str,
) -> crate::Result<()> {
    if nodes == 0 || values != nodes || third.0 != nodes {
        return Err(crate::Error::invalid(
            field,
            format!("{nodes} nodes, {values} values, {} {}", third.0, third.1),
            allowed,
        ));
    }
    Ok(())
}
