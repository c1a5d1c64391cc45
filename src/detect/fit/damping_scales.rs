//! Starting values and bounds of the damping models' parameters in a
//! data-first fit ([`crate::chain::Damping`]), scaled from the chain's
//! natural frequencies (never a bound made for unit masses).
//!
//! # Scales
//!
//! With `omega_min`, `omega_max` the uniform chain's lowest and highest
//! natural frequencies and `omega_ref = sqrt(omega_min omega_max)`, the
//! damping ratio of mode `omega` is `d / (2 mass omega)` (grounded),
//! `c omega / (2 k)` (between), `a / (2 omega) + b omega / 2` (Rayleigh)
//! and `zeta` itself (modal).
//!
//! * **Starting values**: the damping of the chain's `d` (the user's, or the
//!   paper's 0.1) at `omega_ref`, i.e. `c = d k / (mass omega_ref^2)`,
//!   `a = d / (2 mass)`, `b = d / (2 mass omega_ref^2)`,
//!   `zeta = d / (2 mass omega_ref)` (a ratio of 2% at `omega_ref` when `d`
//!   is 0).
//! * **Bounds**: from 0 to a damping ratio of 1 at `omega_min` for each
//!   parameter alone: `c <= 2 k / omega_min`, `a <= 2 omega_min`,
//!   `b <= 2 / omega_min`.
//!

use crate::chain::{Chain, Damping};
use crate::error::{Error, Result};
use crate::sensitivity::Param;

/// Damping ratio of the starting value when the chain's `d` is 0.
const START_RATIO: f64 = 0.02;

/// The lowest positive and the highest natural frequency of `chain`'s
/// uniform part (closed form).
///
/// # Errors
/// As [`crate::time::modal::natural_modes`].
pub fn omega_range(chain: &Chain) -> Result<(f64, f64)> {
    let modes = crate::time::modal::natural_modes(&chain.uniform().with_d(0.0)?)?;
    let lo = modes
        .iter()
        .map(|m| m.omega)
        .filter(|&w| w > 0.0)
        .fold(f64::INFINITY, f64::min);
    let hi = modes.iter().map(|m| m.omega).fold(0.0, f64::max);
    if !(lo.is_finite() && hi > 0.0) {
        return Err(Error::invalid(
            "chain",
            "no vibrating mode",
            "a chain with a positive natural frequency",
        ));
    }
    Ok((lo, hi))
}

/// The model `name` with starting values scaled from `chain` (module docs).
///
/// # Errors
/// An unknown name (field `damping`); as [`omega_range`].
pub fn start(chain: &Chain, name: &str) -> Result<Damping> {
    let model: Damping = name.parse()?;
    if model.is_grounded() {
        return Ok(model);
    }
    let (lo, hi) = omega_range(chain)?;
    let w2 = lo * hi;
    let (m, k) = (chain.mass(), chain.k());
    let d = if chain.d() > 0.0 {
        chain.d()
    } else {
        2.0 * m * w2.sqrt() * START_RATIO
    };
    let out = match model {
        Damping::Between { .. } => Damping::Between {
            c: d * k / (m * w2),
        },
        Damping::Modal { .. } => Damping::modal(d / (2.0 * m * w2.sqrt())),
        _ => Damping::Rayleigh {
            a: d / (2.0 * m),
            b: d / (2.0 * m * w2),
        },
    };
    // inside the bounds
    let values: Vec<f64> = out
        .params()
        .iter()
        .zip(Param::of_damping(&out))
        .map(|((_, v), p)| bounds(chain, p).map_or(*v, |(lo, hi)| v.clamp(lo, 0.5 * hi)))
        .collect();
    Ok(out.with_params(&values))
}

/// The bounds of a damping model's parameter `p` for `chain` (module
/// docs); `None` for any other parameter or when the chain has no
/// vibrating mode.
pub fn bounds(chain: &Chain, p: Param) -> Option<(f64, f64)> {
    if matches!(p, Param::Zeta { .. }) {
        return Some((0.0, 1.0));
    }
    if !matches!(p, Param::C | Param::A | Param::B) {
        return None;
    }
    let (lo, _) = omega_range(chain).ok()?;
    match p {
        Param::C => Some((0.0, 2.0 * chain.k() / lo)),
        Param::A => Some((0.0, 2.0 * lo)),
        Param::B => Some((0.0, 2.0 / lo)),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn starts_and_bounds_scale_with_the_chain() {
        let c = Chain::paper(20).unwrap();
        let (lo, hi) = omega_range(&c).unwrap();
        assert!((lo - 2.0 * (std::f64::consts::PI / 42.0).sin()).abs() < 1e-14);
        let Damping::Rayleigh { a, b } = start(&c, "rayleigh").unwrap() else {
            panic!()
        };
        // the same damping ratio as d = 0.1 at omega_ref
        let w = (lo * hi).sqrt();
        assert!((a / (2.0 * w) + b * w / 2.0 - 0.1 / (2.0 * w)).abs() < 1e-14);
        // SI: masses 1000 kg, springs 1e6 N/m: frequencies 31.6 times higher
        let si = c
            .to_si(&crate::chain::Units::new(1000.0, 1e6, 1000.0).unwrap())
            .unwrap();
        let (lo_si, _) = omega_range(&si).unwrap();
        assert!((lo_si / lo - 1e3_f64.sqrt()).abs() < 1e-9);
        let (_, c_hi) = bounds(&si, Param::C).unwrap();
        assert!((c_hi - 2.0 * 1e6 / lo_si).abs() < 1e-6 * c_hi);
        let Damping::Between { c: c0 } = start(&si, "between").unwrap() else {
            panic!()
        };
        assert!(c0 > 0.0 && c0 < c_hi);
        assert!(start(&c, "viscous").is_err());
    }
}
