//! The speed-accuracy knob of the data-first defaults ([`Effort`]): how
//! hard the search for an unknown number of defects works before it
//! answers. The time-domain refits follow it for a given number too.
//!
//! | level | searches at `k` | time-domain refits | `k` raised until | damping model chosen (`--fit d`) |
//! |---|---|---|---|---|
//! | `low` | from `k = 3` nested in the best 4 answers at `k - 1` | sets within 9 of the Bromwich line's best (3 sigma) | one more defect does not help | as normal |
//! | `normal` (default) | from `k = 3` nested in the best 8 answers | within 25 (5 sigma) | two more in a row do not help | models searched until one explains the record, the rest fitted at its set ([`super::damping::fit_choosing`]) |
//! | `high` | every set at every `k` (as `exhaustive`) where there are at most `max_sets`, else as normal | every set of the shortlist | `k_max` (no early stop) | every model searched |
//!
//! "Does not help": the step lowers the time-domain chi-square by less
//! than noise would (a BIC step of `2 ln N` per defect,
//! the `auto` loop's stop rule). Every level keeps the
//! checks that make an answer honest: the backward rule, the hidden-defect
//! check, the whole search again when a narrowed answer does not explain
//! the record, the status. What `low` gives up: a defect whose first
//! extension does not lower the criterion but whose second does (two
//! defects that mask each other), a set at `k` none of whose subsets is
//! among the best 4 at `k - 1`, and a set whose Laplace misfit is more
//! than 3 sigma behind the best but whose time misfit is better (measured:
//! one record of 420 on masses; with every kind sought, 11 of 120, most of
//! them three defects found together). What
//! `high` buys: the answer exhaustive selection gives, at every `k` up to
//! `k_max`, where every set can be searched; beyond (every kind sought at
//! four defects on a chain of 17 masses or more) the search at that `k`
//! is nested, now in answers at one fewer that were searched in full.
//! Measured in `configs/studies/effort.toml`.
//!
//! ```
//! use springmass::detect::fit::effort::Effort;
//! assert_eq!(Effort::parse("low")?, Effort::Low);
//! assert_eq!(Effort::default().name(), "normal");
//! assert!(Effort::parse("fast").is_err());
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::detect::fit::general::Setup;
use crate::error::{Error, Result};
use serde::Serialize;

/// How hard the defaults search (see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Effort {
    /// Fewer sets and refits, `k` raised while each step helps.
    Low,
    /// The defaults.
    #[default]
    Normal,
    /// Every set at every `k` up to `k_max`, every shortlisted set refitted.
    High,
}

/// The names, in order of effort.
pub const NAMES: [&str; 3] = ["low", "normal", "high"];

impl Effort {
    /// `low`, `normal` or `high`.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming `effort`.
    pub fn parse(text: &str) -> Result<Effort> {
        match text.trim() {
            "low" => Ok(Effort::Low),
            "normal" => Ok(Effort::Normal),
            "high" => Ok(Effort::High),
            t => Err(Error::invalid("effort", t, NAMES.join(", "))),
        }
    }

    /// The level's name.
    pub fn name(self) -> &'static str {
        NAMES[self as usize]
    }

    /// Every set searched at every `k` where there are at most `max_sets`
    /// (the narrowings off there).
    pub fn every_set(self) -> bool {
        self == Effort::High
    }

    /// Steps in a row that do not help before `k` stops rising (`None`:
    /// never, up to `k_max`).
    pub fn stop_after(self) -> Option<usize> {
        match self {
            Effort::Low => Some(1),
            Effort::Normal => Some(2),
            Effort::High => None,
        }
    }

    /// The answers at `k - 1` a nested search extends.
    pub fn nest_previous(self) -> usize {
        match self {
            Effort::Low => 4,
            _ => 8,
        }
    }

    /// The time-domain refits of a search's shortlist: `low` refits the
    /// sets within 9 of the best on the Laplace line, `high` every set.
    pub fn adjust(self, setup: &mut Setup) {
        match self {
            Effort::Low => setup.time_slack = setup.time_slack.min(LOW_SLACK),
            Effort::Normal => {}
            Effort::High => setup.time_slack = f64::INFINITY,
        }
    }
}

/// The time slack of `low`: 3 sigma on the Laplace line's chi-square.
const LOW_SLACK: f64 = 9.0;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_order_by_effort() {
        for (i, name) in NAMES.iter().enumerate() {
            let e = Effort::parse(name).unwrap();
            assert_eq!(e.name(), *name);
            assert_eq!(e as usize, i);
        }
        let err = Effort::parse("max").unwrap_err().to_string();
        assert!(
            err.contains("effort") && err.contains("low, normal, high"),
            "{err}"
        );
    }

    #[test]
    fn more_effort_never_searches_less() {
        let mut last: Option<Effort> = None;
        for e in [Effort::Low, Effort::Normal, Effort::High] {
            let mut s = Setup::new().unwrap();
            e.adjust(&mut s);
            if let Some(p) = last {
                let mut sp = Setup::new().unwrap();
                p.adjust(&mut sp);
                assert!(s.time_slack >= sp.time_slack);
                assert!(e.stop_after().unwrap_or(usize::MAX) >= p.stop_after().unwrap());
                assert!(e.nest_previous() >= p.nest_previous());
            }
            last = Some(e);
        }
        assert!(Effort::High.every_set() && !Effort::Normal.every_set());
    }
}
