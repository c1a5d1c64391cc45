//! The prior of the posterior over defect hypotheses
//! ([`super::posterior`]): over the number of defects and their positions,
//! and over each defect's value; parsed from `--prior-k` and
//! `--prior-range`.

use crate::error::{Error, Result};

/// The prior over the number of defects.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub enum KPrior {
    /// Every number of defects searched equally probable, every position
    /// set of a number equally probable (default).
    #[default]
    Uniform,
    /// Every site (and kind) defective with probability `P`, independently.
    Site(f64),
}

/// The prior of the posterior over hypotheses.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Prior {
    /// Over the number of defects and positions.
    pub k: KPrior,
    /// Each defect value uniform over `[lo, hi]` times the value it
    /// replaces (default: the search's range of its kind).
    pub range: Option<(f64, f64)>,
}

impl Prior {
    /// Parse the prior over `k` (`uniform`, `site:P`) and the value range
    /// (`LO:HI`, multiples of the value a defect replaces).
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming `prior_k` or `prior_range`.
    pub fn parse(k: Option<&str>, range: Option<&str>) -> Result<Prior> {
        let kp = match k.map(str::trim) {
            None | Some("uniform") => KPrior::Uniform,
            Some(t) => {
                let bad = || {
                    Error::invalid(
                        "prior_k",
                        t,
                        "uniform or site:P with 0 < P < 1 (each site defective with probability P)",
                    )
                };
                let p: f64 = t
                    .strip_prefix("site:")
                    .ok_or_else(bad)?
                    .parse()
                    .map_err(|_| bad())?;
                if !(p > 0.0 && p < 1.0) {
                    return Err(bad());
                }
                KPrior::Site(p)
            }
        };
        let range = match range.map(str::trim) {
            None => None,
            Some(t) => {
                let bad = || {
                    Error::invalid(
                        "prior_range",
                        t,
                        "LO:HI with 0 <= LO < HI finite (multiples of the value a defect replaces)",
                    )
                };
                let (a, b) = t.split_once(':').ok_or_else(bad)?;
                let lo: f64 = a.trim().parse().map_err(|_| bad())?;
                let hi: f64 = b.trim().parse().map_err(|_| bad())?;
                if !(lo >= 0.0 && hi > lo && hi.is_finite()) {
                    return Err(bad());
                }
                Some((lo, hi))
            }
        };
        Ok(Prior { k: kp, range })
    }

    /// The prior in words, for the report.
    pub fn describe(&self) -> String {
        let k = match self.k {
            KPrior::Uniform => {
                "k uniform over the counts searched, positions uniform given k".to_string()
            }
            KPrior::Site(p) => format!("each site defective with probability {p}"),
        };
        let v = match self.range {
            None => "values uniform over the search range of their kind".to_string(),
            Some((lo, hi)) => {
                format!("values uniform over [{lo}, {hi}] times the value they replace")
            }
        };
        format!("{k}; {v}")
    }
}
