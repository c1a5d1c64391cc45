//! The search registry: every search over defect positions, registered once.
//!
//! [`SEARCHES`] lists each search with its name, aliases, one-line help,
//! the defect kinds it searches, whether it is stochastic and the optimizer
//! behind it. Parsing ([`FitMethod::parse`], the scene's and the study's
//! `search.method`), [`FitMethod::name`], the command line's help, the
//! validation messages and the Python package's `searches()` all read this
//! table. Adding a search is its file plus one variant and one line here.
//!
//! ```
//! use springmass::detect::search::{FitMethod, SEARCHES};
//! assert_eq!(FitMethod::parse("genetic")?, FitMethod::Ga);
//! assert_eq!(FitMethod::Ga.name(), "ga");
//! assert!(SEARCHES.iter().any(|s| s.method == FitMethod::Pso && s.stochastic()));
//! # Ok::<(), springmass::Error>(())
//! ```

use super::{genetic, nelder_mead, pso, SearchOptions, Tracked};
use crate::detect::unknowns::KindChoice;
use crate::error::{Error, Result};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// The searches over defect positions (one per line of [`SEARCHES`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum FitMethod {
    /// Exhaustive enumeration of position sets with a value fit per set.
    #[default]
    Enumerate,
    /// Greedy placement with moves and restarts (`detect::fit::greedy`).
    Greedy,
    /// The continuous relaxation's support, refitted with its neighbours.
    Relax,
    /// Genetic algorithm ([`genetic`]).
    Ga,
    /// Nelder-Mead with positions fixed per run ([`nelder_mead`]).
    NelderMead,
    /// Particle swarm with relax-and-round positions ([`pso`]).
    Pso,
}

/// The defect kinds a search can place.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Kinds {
    /// Every kind (mass, spring, damper, ground, any), and fitted chain
    /// parameters.
    Every,
    /// Mass or spring defects, one kind for every defect.
    MassOrSpring,
    /// Mass defects only, no fitted chain parameter.
    MassOnly,
}

/// A stochastic optimizer behind a search: its module, its run on a
/// [`Tracked`] objective and the check of its block of [`SearchOptions`].
#[derive(Clone, Copy)]
pub struct Optimizer {
    /// The module that implements it.
    pub module: &'static str,
    pub(crate) run: fn(&Tracked<'_>, &SearchOptions) -> Result<()>,
    pub(crate) validate: fn(&SearchOptions) -> Result<()>,
}

impl std::fmt::Debug for Optimizer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.module)
    }
}

/// One registered search.
#[derive(Clone, Copy, Debug)]
pub struct Search {
    /// Its variant.
    pub method: FitMethod,
    /// Canonical name (command line, TOML, Python, reports).
    pub name: &'static str,
    /// Other accepted names.
    pub aliases: &'static [&'static str],
    /// One line of help.
    pub help: &'static str,
    /// The defect kinds it places.
    pub kinds: Kinds,
    /// Accepted by the scene path's general fit (defects of other kinds,
    /// chain parameters, the time misfit).
    pub general_scene: bool,
    /// The stochastic optimizer behind it (`None`: a deterministic search
    /// of the fit layer).
    pub optimizer: Option<Optimizer>,
}

impl Search {
    /// Whether it is a seeded stochastic optimizer (with an evaluation budget).
    pub fn stochastic(&self) -> bool {
        self.optimizer.is_some()
    }

    /// The defect kinds a data-first fit by this search seeks when none is
    /// asked for: any kind with the enumeration, else masses (the
    /// stochastic searches and the relaxation place one kind; the greedy
    /// search over every kind misses where it finds masses, as on a record
    /// of three masses in a chain of 120).
    pub fn default_kinds(&self) -> KindChoice {
        match (self.method, self.kinds) {
            (FitMethod::Enumerate, Kinds::Every) => KindChoice::Any,
            _ => KindChoice::Mass,
        }
    }
}

/// Every search, in the order the help lists them.
pub const SEARCHES: &[Search] = &[
    Search {
        method: FitMethod::Enumerate,
        name: "enumerate",
        aliases: &["enum"],
        help: "every position set, values by bounded Levenberg-Marquardt (the default)",
        kinds: Kinds::Every,
        general_scene: true,
        optimizer: None,
    },
    Search {
        method: FitMethod::Greedy,
        name: "greedy",
        aliases: &[],
        help: "one defect at a time scored by rank-one updates, then moves and restarts (long chains, many defects)",
        kinds: Kinds::Every,
        general_scene: true,
        optimizer: None,
    },
    Search {
        method: FitMethod::Relax,
        name: "relax",
        aliases: &[],
        help: "every mass or spring free under a sparsity penalty; its support refitted with its neighbours",
        kinds: Kinds::MassOrSpring,
        general_scene: false,
        optimizer: None,
    },
    Search {
        method: FitMethod::Ga,
        name: "ga",
        aliases: &["genetic"],
        help: "mixed-integer genetic algorithm (seeded, max_evals)",
        kinds: Kinds::MassOnly,
        general_scene: false,
        optimizer: Some(Optimizer {
            module: "genetic",
            run: genetic::run,
            validate: |o| o.genetic.validate(),
        }),
    },
    Search {
        method: FitMethod::NelderMead,
        name: "nelder-mead",
        aliases: &["nm"],
        help: "Nelder-Mead on the values, discrete descent over positions (seeded, max_evals)",
        kinds: Kinds::MassOnly,
        general_scene: false,
        optimizer: Some(Optimizer {
            module: "nelder_mead",
            run: nelder_mead::run,
            validate: |o| o.nelder_mead.validate(),
        }),
    },
    Search {
        method: FitMethod::Pso,
        name: "pso",
        aliases: &["particle-swarm"],
        help: "particle swarm with relax-and-round positions (seeded, max_evals)",
        kinds: Kinds::MassOnly,
        general_scene: false,
        optimizer: Some(Optimizer {
            module: "pso",
            run: pso::run,
            validate: |o| o.pso.validate(),
        }),
    },
];

/// The scene and study schema's type of `search.method`: every name of
/// [`SEARCHES`] in TOML syntax (checked against the table by a unit test;
/// the schema's strings are constants).
pub const METHOD_TYPE: &str =
    "\"enumerate\" | \"greedy\" | \"relax\" | \"ga\" | \"nelder-mead\" | \"pso\"";

impl FitMethod {
    /// Every search, in table order.
    pub fn all() -> impl Iterator<Item = FitMethod> {
        SEARCHES.iter().map(|s| s.method)
    }

    /// The stochastic optimizers (`ga`, `nelder-mead`, `pso`), in table order.
    pub fn stochastic_all() -> impl Iterator<Item = FitMethod> {
        SEARCHES.iter().filter(|s| s.stochastic()).map(|s| s.method)
    }

    /// Its registry entry.
    pub fn search(self) -> &'static Search {
        SEARCHES
            .iter()
            .find(|s| s.method == self)
            .expect("every FitMethod is registered in SEARCHES")
    }

    /// The canonical name.
    pub fn name(self) -> &'static str {
        self.search().name
    }

    /// Whether it is a seeded stochastic optimizer.
    pub fn is_stochastic(self) -> bool {
        self.search().stochastic()
    }

    /// The optimizer behind a stochastic search (`None` for the fit layer's
    /// deterministic searches).
    pub fn optimizer(self) -> Option<Optimizer> {
        self.search().optimizer
    }

    /// Parse a name or alias of [`SEARCHES`] (case-insensitive, trimmed).
    ///
    /// # Errors
    /// [`Error::Parse`] listing the allowed names.
    pub fn parse(text: &str) -> Result<FitMethod> {
        let t = text.trim().to_ascii_lowercase();
        SEARCHES
            .iter()
            .find(|s| s.name == t || s.aliases.contains(&t.as_str()))
            .map(|s| s.method)
            .ok_or_else(|| {
                Error::parse(
                    "method",
                    text,
                    format!("expected {}", names(|_| true, "or")),
                )
            })
    }
}

impl std::fmt::Display for FitMethod {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for FitMethod {
    type Err = Error;
    fn from_str(s: &str) -> Result<FitMethod> {
        FitMethod::parse(s)
    }
}

impl Serialize for FitMethod {
    fn serialize<S: Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

impl<'de> Deserialize<'de> for FitMethod {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<FitMethod, D::Error> {
        let text = String::deserialize(d)?;
        FitMethod::parse(&text).map_err(serde::de::Error::custom)
    }
}

/// The names of the searches that `keep`, in table order, as `a, b or c`
/// (`last` is the final conjunction), for help texts and error messages.
pub fn names(keep: impl Fn(&Search) -> bool, last: &str) -> String {
    let v: Vec<&str> = SEARCHES
        .iter()
        .filter(|s| keep(s))
        .map(|s| s.name)
        .collect();
    match v.split_last() {
        None => String::new(),
        Some((l, [])) => (*l).to_string(),
        Some((l, rest)) => format!("{} {last} {l}", rest.join(", ")),
    }
}

/// The command line's help of `--method`: one line per search.
pub fn cli_help() -> String {
    let mut out = String::from(
        "The search over positions [default: enumerate; greedy for chains too long to \
         enumerate and for 3 defects or more told in a chain of 40 masses or more]:",
    );
    for s in SEARCHES {
        out.push_str(&format!("\n  {}: {}", s.name, s.help));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_method_is_registered_once_and_parses_back() {
        let all = [
            FitMethod::Enumerate,
            FitMethod::Greedy,
            FitMethod::Relax,
            FitMethod::Ga,
            FitMethod::NelderMead,
            FitMethod::Pso,
        ];
        assert_eq!(SEARCHES.len(), all.len());
        for m in all {
            assert_eq!(SEARCHES.iter().filter(|s| s.method == m).count(), 1);
            assert_eq!(FitMethod::parse(m.name()).unwrap(), m);
            for a in m.search().aliases {
                assert_eq!(FitMethod::parse(a).unwrap(), m);
            }
            let json = serde_json::to_string(&m).unwrap();
            assert_eq!(json, format!("\"{}\"", m.name()));
            assert_eq!(serde_json::from_str::<FitMethod>(&json).unwrap(), m);
        }
        assert_eq!(FitMethod::parse(" Genetic ").unwrap(), FitMethod::Ga);
        let e = FitMethod::parse("annealing").unwrap_err().to_string();
        assert!(
            e.contains("enumerate, greedy, relax, ga, nelder-mead or pso"),
            "{e}"
        );
    }

    #[test]
    fn the_schema_type_lists_every_name() {
        let v: Vec<String> = SEARCHES.iter().map(|s| format!("\"{}\"", s.name)).collect();
        assert_eq!(METHOD_TYPE, v.join(" | "));
    }

    #[test]
    fn names_and_help() {
        assert_eq!(names(|s| s.stochastic(), "and"), "ga, nelder-mead and pso");
        assert_eq!(names(|s| s.general_scene, "or"), "enumerate or greedy");
        assert_eq!(names(|s| s.name == "ga", "or"), "ga");
        let h = cli_help();
        assert!(SEARCHES.iter().all(|s| h.contains(s.help)));
        assert_eq!(
            FitMethod::stochastic_all().collect::<Vec<_>>(),
            [FitMethod::Ga, FitMethod::NelderMead, FitMethod::Pso]
        );
    }
}
