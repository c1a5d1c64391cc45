//! The search and the kinds sought when the user did not ask
//! ([`FitSpec::kinds_and_method`]): the enumeration ranks every set where
//! it can; a chain too long to enumerate, or many defects told in a long
//! chain, is searched greedily.

use super::{parse_kinds, DefectCount, FitMethod, FitOptions, FitSpec};
use crate::detect::fit::effort::Effort;
use crate::detect::unknowns::KindChoice;
use crate::error::{Error, Result};

impl FitSpec {
    /// The kinds sought and the search, into `opts` (whose number of
    /// defects, effort and exhaustiveness are set). Not asked for: every
    /// kind with the enumeration, masses with another search
    /// ([`crate::detect::search::Search::default_kinds`]) and where an
    /// enumeration of every kind would pass `max_sets`; and the
    /// enumeration, unless the chain is too long to enumerate or many
    /// defects are told in a long chain ([`greedy_by_default`]).
    ///
    /// # Errors
    /// The parse errors of `kinds` and `method`.
    pub(super) fn kinds_and_method(&self, opts: &mut FitOptions) -> Result<()> {
        let asked = self.method.as_deref().map(FitMethod::parse).transpose()?;
        opts.kinds = match &self.kinds {
            Some(k) => parse_kinds(k)?,
            None => asked.unwrap_or_default().search().default_kinds(),
        };
        if self.kinds.is_none() && asked.is_none() && enumeration_too_large(self.n, opts) {
            opts.kinds = KindChoice::Mass;
        }
        if let Some(m) = asked {
            opts.method = m;
        } else if !opts.exhaustive
            && (enumeration_too_large(self.n, opts) || greedy_by_default(self.n, opts))
            && self.sensors.len() <= 1
        {
            // not asked for: a chain too long to enumerate, or many
            // defects told in a long chain, is searched greedily (the
            // report's method line says so and its `exhaustive` is false;
            // the greedy search reads one sensor: several are enumerated,
            // or refused beyond `max_sets`)
            opts.method = FitMethod::Greedy;
        }
        // every set asked for: enumerated, or refused here when the sets
        // are too many (rather than searched greedily, or refused only at
        // the number of defects that passes `max_sets`, after the fits of
        // fewer)
        if opts.exhaustive
            && opts.method == FitMethod::Enumerate
            && enumeration_too_large(self.n, opts)
        {
            let k = match opts.defects {
                DefectCount::Exactly(k) | DefectCount::Auto { k_max: k } => k,
            };
            return Err(Error::invalid(
                "exhaustive",
                format!(
                    "every set of up to {} defects on n = {} (about {:.0} sets)",
                    k,
                    self.n,
                    largest_search(self.n, opts)
                ),
                format!(
                    "at most max_sets = {} sets: fewer defects (defects = auto:K), or \
                     the default search without exhaustive",
                    opts.max_sets
                ),
            ));
        }
        Ok(())
    }
}

/// Whether enumerating the position sets of the largest number of defects
/// `opts` may try would exceed `opts.max_sets` (about `C(P, k)` sets for `P`
/// positions of the allowed kinds), with one kind choice for every defect
/// (what the greedy search needs). With every kind sought and the number
/// of defects left to the criterion, the searches from three defects on
/// are nested in the answers at one fewer (unless `exhaustive`; effort
/// high nests only searches beyond `max_sets`): such a search is enumerated
/// where one kind's would be and its largest search in full stays within
/// `max_sets`.
fn enumeration_too_large(n: usize, opts: &FitOptions) -> bool {
    same_kinds(opts) && largest_search(n, opts) > opts.max_sets as f64
}

/// The sets of the largest search an enumeration would make (see
/// [`enumeration_too_large`]).
fn largest_search(n: usize, opts: &FitOptions) -> f64 {
    let per = opts
        .slot_kinds
        .first()
        .copied()
        .unwrap_or(opts.kinds)
        .kinds()
        .len();
    let sets = |positions: usize, k: usize| {
        (0..k).fold(1.0, |c, i| {
            c * (positions as f64 - i as f64) / (i + 1) as f64
        })
    };
    match opts.defects {
        DefectCount::Exactly(k) => sets((n + 1) * per, k),
        DefectCount::Auto { k_max } if per > 1 && !opts.exhaustive => {
            let full = k_max.min(crate::detect::fit::narrow::NEST_FROM - 1);
            sets(n + 1, k_max).max(sets((n + 1) * per, full))
        }
        DefectCount::Auto { k_max } => sets((n + 1) * per, k_max),
    }
}

/// Chains from this many masses on are searched greedily when told
/// [`GREEDY_FROM_K`] defects or more ([`greedy_by_default`]).
pub const GREEDY_FROM_N: usize = 40;

/// See [`GREEDY_FROM_N`].
pub const GREEDY_FROM_K: usize = 3;

/// Whether a number of defects told, at least [`GREEDY_FROM_K`], in a
/// chain of at least [`GREEDY_FROM_N`] masses is searched greedily rather
/// than by enumeration: `C(n + 1, k)` sets (35 990 for `n = 60`, `k = 3`,
/// 1.6 s on a 1% record) against a few hundred refits (0.45 s, the same
/// answer; `tests/long_search.rs`). Not where every set is asked for
/// (`exhaustive`, effort high), nor where the defects' kinds differ
/// (the greedy search takes one kind choice for all of them).
fn greedy_by_default(n: usize, opts: &FitOptions) -> bool {
    matches!(opts.defects, DefectCount::Exactly(k) if k >= GREEDY_FROM_K)
        && n >= GREEDY_FROM_N
        && !opts.exhaustive
        && opts.effort != Effort::High
        && same_kinds(opts)
}

/// One kind choice for every defect (what the greedy search takes).
fn same_kinds(opts: &FitOptions) -> bool {
    opts.slot_kinds.windows(2).all(|w| w[0] == w[1])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every kind by default where the enumeration can take it; masses with
    /// another search, and where an enumeration of every kind would pass
    /// `max_sets` (the search is then greedy, as for masses); a kind asked
    /// for is kept.
    #[test]
    fn the_default_kinds_follow_the_search() {
        let kinds = |n: usize, method: Option<&str>, kinds: Option<&str>| {
            let o = FitSpec {
                method: method.map(str::to_string),
                kinds: kinds.map(str::to_string),
                ..FitSpec::new(n)
            }
            .options()
            .unwrap();
            (o.kinds, o.method)
        };
        use FitMethod::*;
        use KindChoice::{Any, Mass, Spring};
        assert_eq!(kinds(20, None, None), (Any, Enumerate));
        assert_eq!(kinds(47, None, None), (Any, Enumerate));
        for m in ["greedy", "relax", "ga", "nelder-mead", "pso"] {
            let method = FitMethod::parse(m).unwrap();
            assert_eq!(kinds(20, Some(m), None), (Mass, method), "{m}");
        }
        assert_eq!(kinds(20, Some("greedy"), Some("any")), (Any, Greedy));
        assert_eq!(kinds(20, None, Some("spring")), (Spring, Enumerate));
        // four of n + 1 positions pass max_sets from n = 48 on: masses,
        // greedily, as before every kind was the default
        assert_eq!(kinds(48, None, None), (Mass, Greedy));
        assert_eq!(kinds(48, None, Some("any")), (Any, Greedy));
        assert_eq!(kinds(1000, None, None), (Mass, Greedy));
        // three defects or more told in a chain of 40 or more: greedily,
        // unless every set is asked for (or the kinds differ per defect)
        let told = |n: usize, k: &str, exhaustive: Option<bool>, effort: Option<&str>| {
            FitSpec {
                defects: Some(k.to_string()),
                exhaustive,
                effort: effort.map(str::to_string),
                ..FitSpec::new(n)
            }
            .options()
            .unwrap()
            .method
        };
        assert_eq!(told(40, "3", None, None), Greedy);
        assert_eq!(told(39, "3", None, None), Enumerate);
        assert_eq!(told(60, "2", None, None), Enumerate);
        assert_eq!(told(60, "3", Some(true), None), Enumerate);
        assert_eq!(told(60, "3", None, Some("high")), Enumerate);
        let mixed = FitSpec {
            defects: Some("3".into()),
            slot_kinds: vec!["mass".into(), "spring".into(), "mass".into()],
            ..FitSpec::new(60)
        };
        assert!(!greedy_by_default(60, &mixed.options().unwrap()));
        // every set asked for where the sets are too many: refused at once,
        // with the count, not searched greedily (n = 60, up to four
        // defects: 521 855 sets); with fewer defects, enumerated
        let every = |n: usize, k: &str| {
            FitSpec {
                defects: Some(k.to_string()),
                exhaustive: Some(true),
                ..FitSpec::new(n)
            }
            .options()
        };
        let e = every(60, "auto").unwrap_err().to_string();
        assert!(
            e.contains("exhaustive") && e.contains("about 521855 sets"),
            "{e}"
        );
        assert!(e.contains("auto:K"), "{e}");
        assert_eq!(every(60, "auto:3").unwrap().method, Enumerate);
        assert_eq!(every(20, "auto").unwrap().method, Enumerate);
        assert!(every(1000, "3").is_err());
        // every choice's name parses back to it
        for k in [Any, Mass, Spring, KindChoice::MassOrSpring] {
            assert_eq!(parse_kinds(k.name()).unwrap(), k);
        }
    }
}
