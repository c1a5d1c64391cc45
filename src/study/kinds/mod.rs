//! Case kinds: what one case of a study does.
//!
//! Each kind lives in its own file and provides a scene schema (a serde type
//! with `deny_unknown_fields` plus its [`FieldDoc`] list), the list of the
//! metrics it records, and `run(scene, seed) -> CaseOutput`. A case never
//! prints; it returns numbers. Adding a kind is one new file and one arm in
//! each `match` below.

pub mod case;
pub mod fit;
pub mod forward;
pub mod locate;
pub mod noise;
pub mod realism;
pub mod suppress;

use crate::error::{Error, Result};
use crate::study::schema::FieldDoc;
pub use case::{
    chain_problems, from_scene, prefix_chain, prefix_field, typed_scene, unknown_errors,
    unknown_fields, CaseOutput, CasePlot, KindScene,
};
use serde::{Deserialize, Serialize};

/// The case kinds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Kind {
    /// Forward-model accuracy and speed: Woodbury closed form against the
    /// O(n) tridiagonal reference on an s grid.
    Forward,
    /// Active suppression (Theorem 3.1, Corollary 3.2) verified by simulation.
    Suppress,
    /// Defect detection by fitting (`detect::fit` on a `FitScene`).
    Fit,
    /// Explicit single-defect locators (section 4.1).
    Locate,
    /// The data-first fit of a noisy record of a reference system, scored
    /// against its truth (the noise study).
    Noise,
    /// The data-first fit of a record with a real test's deviations,
    /// generated independently of the fit's model.
    Realism,
}

/// Every kind, in documentation order.
pub const ALL: &[Kind] = &[
    Kind::Forward,
    Kind::Suppress,
    Kind::Fit,
    Kind::Locate,
    Kind::Noise,
    Kind::Realism,
];

impl Kind {
    /// The name used in `study.kind`.
    pub fn name(&self) -> &'static str {
        match self {
            Kind::Forward => "forward",
            Kind::Suppress => "suppress",
            Kind::Fit => "fit",
            Kind::Noise => "noise",
            Kind::Locate => "locate",
            Kind::Realism => "realism",
        }
    }

    /// Parse a kind name.
    ///
    /// # Errors
    /// A message listing the kinds.
    pub fn from_name(name: &str) -> std::result::Result<Kind, String> {
        ALL.iter()
            .copied()
            .find(|k| k.name() == name)
            .ok_or_else(|| {
                format!(
                    "unknown kind {name:?}; kinds: {}",
                    ALL.iter().map(|k| k.name()).collect::<Vec<_>>().join(", ")
                )
            })
    }

    /// One paragraph on what a case of this kind does.
    pub fn summary(&self) -> &'static str {
        match self {
            Kind::Forward => forward::SUMMARY,
            Kind::Suppress => suppress::SUMMARY,
            Kind::Fit => fit::SUMMARY,
            Kind::Noise => noise::SUMMARY,
            Kind::Locate => locate::SUMMARY,
            Kind::Realism => realism::SUMMARY,
        }
    }

    /// The scene fields (paths relative to `[scene]`).
    pub fn schema(&self) -> &'static [FieldDoc] {
        match self {
            Kind::Forward => forward::FIELDS,
            Kind::Suppress => suppress::FIELDS,
            Kind::Fit => fit::FIELDS,
            Kind::Noise => noise::FIELDS,
            Kind::Locate => locate::FIELDS,
            Kind::Realism => realism::FIELDS,
        }
    }

    /// `(column, meaning)` of every metric and timing the kind records.
    pub fn metrics(&self) -> &'static [(&'static str, &'static str)] {
        match self {
            Kind::Forward => forward::METRICS,
            Kind::Suppress => suppress::METRICS,
            Kind::Fit => fit::METRICS,
            Kind::Noise => noise::METRICS,
            Kind::Locate => locate::METRICS,
            Kind::Realism => realism::METRICS,
        }
    }

    /// Check a resolved scene without running it: unknown fields, types,
    /// ranges.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming the field (relative to `[scene]`).
    pub fn validate(&self, scene: &toml::Value) -> Result<()> {
        match self {
            Kind::Forward => forward::Scene::from_value(scene).map(|_| ()),
            Kind::Suppress => suppress::Scene::from_value(scene).map(|_| ()),
            Kind::Fit => fit::scene(scene).map(|_| ()),
            Kind::Noise => noise::Scene::from_value(scene).map(|_| ()),
            Kind::Locate => locate::Scene::from_value(scene).map(|_| ()),
            Kind::Realism => realism::Scene::from_value(scene).map(|_| ()),
        }
    }

    /// Every problem of a resolved scene: every unknown field, every type
    /// error, and every failed range check of the fields that have the right
    /// type ([`KindScene::all_problems`]).
    pub fn validate_all(&self, scene: &toml::Value) -> Vec<Error> {
        match self {
            Kind::Forward => forward::Scene::all_problems(scene),
            Kind::Suppress => suppress::Scene::all_problems(scene),
            Kind::Fit => crate::detect::scene::FitScene::all_problems(scene),
            Kind::Noise => noise::Scene::all_problems(scene),
            Kind::Locate => locate::Scene::all_problems(scene),
            Kind::Realism => realism::Scene::all_problems(scene),
        }
    }

    /// Run one case.
    ///
    /// # Errors
    /// Whatever the case's computation reports; the runner records it as a
    /// failed case.
    pub fn run(&self, scene: &toml::Value, seed: u64) -> Result<CaseOutput> {
        match self {
            Kind::Forward => forward::run(&forward::Scene::from_value(scene)?, seed),
            Kind::Suppress => suppress::run(&suppress::Scene::from_value(scene)?, seed),
            Kind::Fit => fit::run(scene, seed),
            Kind::Noise => noise::run(&noise::Scene::from_value(scene)?, seed),
            Kind::Locate => locate::run(&locate::Scene::from_value(scene)?, seed),
            Kind::Realism => realism::run(&realism::Scene::from_value(scene)?, seed),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kinds_roundtrip_names() {
        for k in ALL {
            assert_eq!(Kind::from_name(k.name()), Ok(*k));
            assert!(!k.schema().is_empty());
            assert!(!k.metrics().is_empty());
        }
        assert!(Kind::from_name("fwd").unwrap_err().contains("forward"));
    }

    #[test]
    fn type_errors_name_the_field() {
        let v: toml::Value = toml::from_str("chain = { n = 5.5 }").unwrap();
        let e = Kind::Forward.validate(&v).unwrap_err();
        match e {
            Error::InvalidParameter { field, .. } => assert_eq!(field, "chain.n"),
            other => panic!("{other:?}"),
        }
        let v: toml::Value = toml::from_str("chain = { n = 5 }\ns = { count = \"x\" }").unwrap();
        match Kind::Forward.validate(&v).unwrap_err() {
            Error::InvalidParameter { field, .. } => assert_eq!(field, "s.count"),
            other => panic!("{other:?}"),
        }
    }
}
