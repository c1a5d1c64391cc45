//! The report's time of the blow (fitted by [`crate::detect::fit::trigger`]).

use super::fmt_g;
use serde::Serialize;

/// The blow's time as the report gives it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct TriggerEstimate {
    /// The blow's time on the record's own axis.
    pub time: f64,
    /// Its standard error (NaN where not computed, see the module docs).
    pub se: f64,
    /// Samples before the blow, left out of the fit.
    pub dropped: usize,
    /// Detected from the record (`false`: given by the user).
    pub detected: bool,
    /// Refits at a refined time (0 to 3: the time is refined again with
    /// each refit's chain until it stays within its standard error).
    pub refits: usize,
}

impl TriggerEstimate {
    /// One line for the report: `blow at t = 10.07 +- 2e-4 on the record's
    /// axis (detected; 51 samples before it left out)`.
    pub fn line(&self) -> String {
        format!(
            "blow at t = {} +- {} on the record's axis ({}; {} samples before it left out{})",
            fmt_g(self.time),
            fmt_g(self.se),
            if self.detected { "detected" } else { "given" },
            self.dropped,
            match self.refits {
                0 => String::new(),
                1 => ", refitted at the refined time".into(),
                r => format!(", refitted {r} times as the time was refined with each fit's chain"),
            },
        )
    }
}
