//! What a data-first fit looks for and how ([`FitOptions`]: the number of
//! defects, their kinds, the noise level, the misfit, the search), and the
//! [`Model`] and [`FitOptions`] built from the options a front end receives
//! as text (`springmass fit --data ...`, the Python package's
//! `springmass.fit(...)`), built in one place so that every front end fits
//! the same data alike.
//!
//! Each field is `None` (or empty) for "the default": [`Model::new`] for the
//! chain (k = 1, d = 0.1, gamma = 1, unit masses), [`FitOptions::default`]
//! for the search. The text forms are those of the command line:
//!
//! | field | form | parsed by |
//! |---|---|---|
//! | `defects` | `auto`, `auto:KMAX`, `K` | [`DefectCount::parse`] |
//! | `kinds` | `mass`, `spring`, `damper`, `ground`, `any` (default), `mass-or-spring` | [`parse_kinds`] |
//! | `slot_kinds` | one kind per defect | [`parse_kinds`] each |
//! | `noise` | `auto` or a standard deviation | [`NoiseSpec::parse`] |
//! | `misfit` | `time`, `bromwich`, `real-axis` | [`MisfitKind::parse`] |
//! | `method` | `enumerate`, `greedy`, `relax`, `ga`, `nelder-mead`, `pso` (default enumerate; greedy when enumeration would exceed `max_sets` sets) | [`FitMethod::parse`] |
//! | `criterion` | `bic`, `aic`, `chi2`, `chi2:ALPHA` | [`Criterion::parse`] |
//! | `fit` | comma-separated subset of `d,gamma,k,mass` | [`parse_params`] |
//! | `known` | `kind:at:value` each | [`Defect::parse`] |
//! | `trigger` | `auto` or the blow's time on the record's axis | [`TriggerSpec::parse`] |
//! | `force_window` | `auto`, `none` or `T0:T1` | [`ForceWindow::parse`] |
//! | `noise_model` | `auto`, `white`, `ar`, `ar:P` | [`NoiseModelChoice::parse`](super::record::NoiseModelChoice::parse) |
//! | `nuisance` | `auto`, `none`, `offset`, `offset+drift` | [`NuisanceChoice::parse`](super::record::NuisanceChoice::parse) |
//!
//! ```
//! use springmass::detect::fit::options::FitSpec;
//! use springmass::detect::fit::{DefectCount, NoiseSpec};
//! let spec = FitSpec {
//!     defects: Some("auto:3".into()),
//!     noise: Some("2e-3".into()),
//!     ..FitSpec::new(10)
//! };
//! let (model, opts) = spec.build()?;
//! assert_eq!(model.n(), 10);
//! assert_eq!(opts.defects, DefectCount::Auto { k_max: 3 });
//! assert_eq!(opts.noise.known(), Some(2e-3));
//! assert!(FitSpec { kinds: Some("atom".into()), ..FitSpec::new(10) }.build().is_err());
//! # Ok::<(), springmass::Error>(())
//! ```

use super::model::{parse_params, Model};
use super::select::Criterion;
use crate::chain::{Boundary, Defect};
pub use crate::detect::data::force_window::ForceWindow;
use crate::detect::data::measurement::{Measurement, Sensor};
use crate::detect::data::observations::{Observations, Series};
pub use crate::detect::data::trigger::TriggerSpec;
use crate::detect::misfit::MisfitKind;
use crate::detect::search::FitMethod;
use crate::detect::unknowns::{DefectKind, KindChoice};
use crate::error::{Error, Result};
use crate::forward::Observable;
use serde::Serialize;

mod default_search;

/// How many defects to look for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum DefectCount {
    /// Exactly this many.
    Exactly(usize),
    /// Choose among `0..=k_max` by the criterion.
    Auto {
        /// Largest number tried.
        k_max: usize,
    },
}

impl DefectCount {
    /// `auto` (k_max 4, or n when smaller), `auto:K`, or a number.
    ///
    /// # Errors
    /// [`Error::Parse`] naming the forms.
    pub fn parse(text: &str) -> Result<DefectCount> {
        let t = text.trim();
        let bad = || {
            Error::parse(
                "defects",
                text,
                "expected auto, auto:K_MAX or a number of defects",
            )
        };
        if t == "auto" {
            return Ok(DefectCount::Auto {
                k_max: DEFAULT_K_MAX,
            });
        }
        if let Some(k) = t.strip_prefix("auto:") {
            return Ok(DefectCount::Auto {
                k_max: k.parse().map_err(|_| bad())?,
            });
        }
        t.parse().map(DefectCount::Exactly).map_err(|_| bad())
    }
}

/// Default largest number of defects tried by `defects = auto`.
pub const DEFAULT_K_MAX: usize = 4;

/// The noise level of the data.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub enum NoiseSpec {
    /// Estimate it (see the module docs).
    Auto,
    /// Known standard deviation of the samples (absolute).
    Sigma(f64),
}

impl NoiseSpec {
    /// `auto` or a positive number.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming `noise`.
    pub fn parse(text: &str) -> Result<NoiseSpec> {
        let t = text.trim();
        if t == "auto" {
            return Ok(NoiseSpec::Auto);
        }
        let v: f64 = t
            .parse()
            .map_err(|_| Error::invalid("noise", t, "auto or a standard deviation > 0"))?;
        if !(v.is_finite() && v > 0.0) {
            return Err(Error::invalid(
                "noise",
                t,
                "auto or a finite standard deviation > 0",
            ));
        }
        Ok(NoiseSpec::Sigma(v))
    }
}

/// What to look for and how (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct FitOptions {
    /// Number of defects (default `auto`, `k_max = 4`).
    pub defects: DefectCount,
    /// Their kinds (default any: mass, spring or damper; the stochastic
    /// searches and the relaxation take one kind; [`FitSpec`] seeks masses
    /// with another search than the enumeration and in long chains when
    /// no kind is asked for).
    pub kinds: KindChoice,
    /// One kind per free defect, overriding `kinds` (empty: every defect of
    /// kind `kinds`); needs `defects` = exactly that many.
    pub slot_kinds: Vec<KindChoice>,
    /// Noise level (default estimated).
    pub noise: NoiseSpec,
    /// Misfit (default: `time` for a series, the nodes' chi-square for Laplace values).
    pub misfit: Option<MisfitKind>,
    /// Search (default enumeration).
    pub method: FitMethod,
    /// Criterion of `defects = auto` (default BIC).
    pub criterion: Criterion,
    /// Seed of the stochastic searches.
    pub seed: u64,
    /// Evaluation budget of the stochastic searches (default 20 000).
    pub max_evals: usize,
    /// Alternatives reported, at most (default 5). With the time misfit only
    /// the sets refitted in the time domain are ranked: the Bromwich line's
    /// best two and those within its chi-square slack
    /// ([`crate::detect::fit::general::Setup::time_slack`]).
    pub alternatives: usize,
    /// Fit hypotheses in parallel; the result does not depend on it.
    pub parallel: bool,
    /// Largest number of hypotheses enumerated (default 200 000).
    pub max_sets: usize,
    /// With the number of defects left to the criterion, search every set
    /// at every `k` (default false: from `k = 3` the sets are nested in the
    /// best answers of one defect fewer, and a search over every kind tries
    /// the kinds each position's sensitivity points to;
    /// `detect::fit::narrow`).
    pub exhaustive: bool,
    /// How hard the search for an unknown number of defects works (default
    /// normal; [`super::effort`]): `high` also searches every set at each
    /// `k` where there are at most `max_sets`.
    pub effort: super::effort::Effort,
    /// The blow's time on a record's axis (default detected,
    /// [`crate::detect::data::trigger`]).
    pub trigger: TriggerSpec,
    /// The record's noise model (default auto: white unless the white
    /// fit's residual fails the whiteness test and AR wins by the criterion;
    /// [`super::record`]).
    pub noise_model: super::record::NoiseModelChoice,
    /// The sensor's offset and drift (default auto, as `noise_model`).
    pub nuisance: super::record::NuisanceChoice,
    /// The level of the intervals (default 0.9; [`super::intervals`]).
    pub level: f64,
    /// The prior of the probabilities over hypotheses
    /// ([`super::posterior`]).
    pub prior: super::prior::Prior,
    /// Compute the intervals and the probabilities over hypotheses
    /// (default true).
    pub uncertainty: bool,
    /// A screening fit, compared with others by its criterion only (the
    /// damping choice's candidates, [`super::damping::fit_choosing`]): no
    /// search of every set when the narrowed answer does not explain the
    /// record, and, unless it explains the record, an estimated noise level
    /// not settled (the fits are not made again at the largest model's
    /// estimate: the criterion is the residual's, which the level does not
    /// enter) and no intervals. A screening fit that explains the record is
    /// the fit a full one would be, and may be the answer
    /// ([`FitReport::screened`](super::FitReport::screened) false) (default
    /// false).
    pub screen: bool,
    /// Fit only this set: each defect's kind and position, its value
    /// free, with `defects` the set's size (the damping choice's check of
    /// the other models at the answer's positions,
    /// [`super::damping::fit_choosing`]); empty (the default): search the
    /// positions.
    pub set: Vec<(DefectKind, usize)>,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            defects: DefectCount::Auto {
                k_max: DEFAULT_K_MAX,
            },
            kinds: KindChoice::Any,
            slot_kinds: Vec::new(),
            noise: NoiseSpec::Auto,
            misfit: None,
            method: FitMethod::Enumerate,
            criterion: Criterion::Bic,
            seed: 0,
            max_evals: 20_000,
            alternatives: 5,
            parallel: true,
            max_sets: 200_000,
            exhaustive: false,
            effort: Default::default(),
            trigger: TriggerSpec::Auto,
            noise_model: Default::default(),
            nuisance: Default::default(),
            level: super::intervals::DEFAULT_LEVEL,
            prior: Default::default(),
            uncertainty: true,
            screen: false,
            set: Vec::new(),
        }
    }
}

impl FitOptions {
    /// Check the options against the model and the data, before any work.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming `defects` (k > n), `k_max`
    /// (k_max > n), `method` (a stochastic search for other kinds than mass
    /// or with chain parameters fitted), `misfit` (`time` with Laplace values),
    /// `max_evals` (0), `max_sets` (0).
    pub fn validate(&self, obs: &Observations, model: &Model) -> Result<()> {
        let n = model.n();
        match self.defects {
            DefectCount::Exactly(k) if k > n => {
                return Err(Error::invalid("defects", k, format!("<= n = {n}")))
            }
            DefectCount::Auto { k_max } if k_max > n => {
                return Err(Error::invalid("k_max", k_max, format!("<= n = {n}")))
            }
            _ => {}
        }
        if !self.slot_kinds.is_empty()
            && self.defects != DefectCount::Exactly(self.slot_kinds.len())
        {
            return Err(Error::invalid(
                "kinds",
                format!("{} kinds", self.slot_kinds.len()),
                "one kind per defect: as many kinds as defects, with a given number of defects",
            ));
        }
        self.validate_set(n)?;
        let all_mass = self.kinds == KindChoice::Mass
            && self.slot_kinds.iter().all(|k| *k == KindChoice::Mass);
        if !matches!(
            self.method,
            FitMethod::Enumerate | FitMethod::Greedy | FitMethod::Relax
        ) && (!all_mass || !model.fitted().is_empty())
        {
            return Err(Error::invalid(
                "method",
                self.method.name(),
                "enumerate, greedy or relax for spring, damper or any-kind defects and for fitted chain parameters (ga, nelder-mead and pso search mass defects only)",
            ));
        }
        if self.method == FitMethod::Relax {
            let one = |k: KindChoice| matches!(k, KindChoice::Mass | KindChoice::Spring);
            let kinds_ok = if self.slot_kinds.is_empty() {
                one(self.kinds)
            } else {
                one(self.slot_kinds[0]) && self.slot_kinds.iter().all(|k| *k == self.slot_kinds[0])
            };
            if !kinds_ok {
                return Err(Error::invalid(
                    "kinds",
                    self.kinds.name(),
                    "mass or spring, one kind for every defect, with the relax method (the relaxation frees every mass or every spring)",
                ));
            }
        }
        if self.method == FitMethod::Greedy && self.slot_kinds.windows(2).any(|w| w[0] != w[1]) {
            return Err(Error::invalid(
                "kinds",
                "a different kind per defect",
                "one kind for every defect with the greedy search (or the enumeration)",
            ));
        }
        match obs {
            Observations::Series(s) => {
                for o in s.sensors() {
                    o.measurement().sensor().check(n)?;
                }
                self.validate_sensors(s)?;
            }
            Observations::Laplace(l) => l.sensor().check(n)?,
        }
        self.validate_misfit(obs, model)?;
        self.validate_record(obs)?;
        if self.max_evals == 0 {
            return Err(Error::invalid("max_evals", 0, ">= 1"));
        }
        if self.max_sets == 0 {
            return Err(Error::invalid("max_sets", 0, ">= 1"));
        }
        Ok(())
    }
}

impl FitOptions {
    /// A given set ([`FitOptions::set`]): as many defects as its entries,
    /// each position within the chain, no position of a kind twice.
    fn validate_set(&self, n: usize) -> Result<()> {
        if self.set.is_empty() {
            return Ok(());
        }
        if self.defects != DefectCount::Exactly(self.set.len()) {
            return Err(Error::invalid(
                "defects",
                format!("{:?}", self.defects),
                format!("{} (the given set's size)", self.set.len()),
            ));
        }
        for (i, &(kind, at)) in self.set.iter().enumerate() {
            if !(1..=n).contains(&at) {
                return Err(Error::invalid("set", at, format!("a position in 1..={n}")));
            }
            if self.set[..i].contains(&(kind, at)) {
                return Err(Error::invalid(
                    "set",
                    format!("{} {at} twice", kind.name()),
                    "each kind and position once",
                ));
            }
        }
        Ok(())
    }

    /// The misfit the data and the model allow: the time misfit needs a
    /// sampled series; the modal damping model is fitted from a sampled
    /// record by the time misfit, by the enumeration or a stochastic search
    /// (its `C` is not tridiagonal: its exact response is a modal sum in
    /// time).
    fn validate_misfit(&self, obs: &Observations, model: &Model) -> Result<()> {
        if matches!(obs, Observations::Laplace(_)) && self.misfit == Some(MisfitKind::Time) {
            return Err(Error::invalid(
                "misfit",
                "time",
                "real-axis or bromwich for Laplace values (the time misfit needs a sampled series)",
            ));
        }
        if model.chain().damping().is_modal()
            && (matches!(obs, Observations::Laplace(_))
                || self.misfit.is_some_and(|m| m != MisfitKind::Time)
                || matches!(self.method, FitMethod::Greedy | FitMethod::Relax))
        {
            return Err(Error::invalid(
                "damping",
                "modal",
                "a sampled record fitted by the time misfit with the enumeration or a stochastic search (the modal model's C is not tridiagonal: its exact response is a modal sum in time)",
            ));
        }
        if model.chain().damping().is_modal() && model.chain().d() != 0.0 {
            // a searched mass defect would make grounded dampers
            // non-proportional, which the modal sum cannot take
            return Err(Error::invalid(
                "d",
                model.chain().d(),
                "0 beside the modal damping model in a fit (its damping is zeta alone)",
            ));
        }
        Ok(())
    }

    /// A record of several sensors is fitted by the time misfit with white
    /// noise, by the enumeration or a stochastic search (the greedy
    /// search's rank-one scores and the relaxation's profile read one
    /// sensor).
    fn validate_sensors(&self, s: &Series) -> Result<()> {
        use super::record::forced;
        if s.others().is_empty() {
            return Ok(());
        }
        let sensors = format!(
            "{} {}",
            s.sensors().count(),
            if s.separate_records() {
                "records"
            } else {
                "sensors"
            }
        );
        if self.misfit.is_some_and(|m| m != MisfitKind::Time) {
            return Err(Error::invalid(
                "misfit",
                self.misfit.map_or("", |m| m.name()),
                format!("time with {sensors} (one joint time-domain fit)"),
            ));
        }
        if matches!(self.method, FitMethod::Greedy | FitMethod::Relax) {
            return Err(Error::invalid(
                "method",
                self.method.name(),
                format!("enumerate, ga, nelder-mead or pso with {sensors}"),
            ));
        }
        if forced(self.noise_model, self.nuisance) {
            return Err(Error::invalid(
                "noise_model",
                "ar, offset or drift",
                format!(
                    "white noise and no nuisance with {sensors} (each sensor's level is estimated)"
                ),
            ));
        }
        Ok(())
    }

    /// A record model asked for (an AR noise model, an offset or a drift)
    /// needs the time misfit of a sampled series.
    fn validate_record(&self, obs: &Observations) -> Result<()> {
        use super::record::{forced, NoiseModelChoice};
        let time = matches!(obs, Observations::Series(_))
            && self.misfit.is_none_or(|m| m == MisfitKind::Time);
        if forced(self.noise_model, self.nuisance) && !time {
            let (field, value) = match self.noise_model {
                NoiseModelChoice::Ar(_) => ("noise_model", "ar"),
                _ => ("nuisance", "offset or drift"),
            };
            return Err(Error::invalid(
                field,
                value,
                "white / none unless the misfit is the time misfit of a sampled series",
            ));
        }
        Ok(())
    }
}

/// The options of a data-first fit as a front end receives them (see the
/// module docs); `None` or empty means the default. Read from TOML by the
/// study kinds with the same names (unknown names refused).
#[derive(Clone, Debug, Default, PartialEq, Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FitSpec {
    /// Number of masses.
    pub n: usize,
    /// Uniform damping (known, or the starting value when fitted) [default 0.1].
    pub d: Option<f64>,
    /// Uniform stiffness [default 1].
    pub k: Option<f64>,
    /// Uniform mass [default 1].
    pub mass: Option<f64>,
    /// Impulse on mass 1 (with a measured force: the force's scale) [default 1].
    pub gamma: Option<f64>,
    /// Left end: `fixed` or `free` [default fixed].
    pub left: Option<String>,
    /// Right end: `fixed` or `free` [default fixed].
    pub right: Option<String>,
    /// The observed mass [default 1].
    pub observe: Option<usize>,
    /// `displacement`, `velocity` or `acceleration` [default displacement].
    pub observe_kind: Option<String>,
    /// Several sensors: every observed mass, one value column each in
    /// order, fitted jointly (empty: the one sensor `observe`; when given,
    /// `observe` is unused) [default empty].
    pub sensors: Vec<usize>,
    /// What each of `sensors` measured: one kind for every sensor, or one
    /// per sensor (empty: `observe_kind` for every one) [default empty].
    pub sensor_kinds: Vec<String>,
    /// Chain parameters fitted too: `d,gamma,k,mass` (any subset) [default none].
    pub fit: Option<String>,
    /// Known defects, `kind:at:value` each.
    pub known: Vec<String>,
    /// Number of defects: `auto`, `auto:KMAX` or `K` [default auto].
    pub defects: Option<String>,
    /// Kind of every defect sought [default any; mass with another search
    /// than the enumeration, and where an enumeration of every kind would
    /// pass `max_sets` (long chains)].
    pub kinds: Option<String>,
    /// One kind per defect (overrides `kinds`; needs `defects = K` with as many).
    pub slot_kinds: Vec<String>,
    /// `auto` or the samples' noise standard deviation [default auto].
    pub noise: Option<String>,
    /// `time`, `bromwich` or `real-axis` [default time for a series].
    pub misfit: Option<String>,
    /// `enumerate`, `greedy`, `relax`, `ga`, `nelder-mead` or `pso` [default
    /// enumerate, or greedy when the position sets of the largest k exceed
    /// `max_sets`, 200 000: a long chain].
    pub method: Option<String>,
    /// Criterion of `defects = auto`: `bic`, `aic`, `chi2`, `chi2:ALPHA` [default bic].
    pub criterion: Option<String>,
    /// Seed of the stochastic searches [default 0].
    pub seed: Option<u64>,
    /// Evaluation budget of the stochastic searches [default 20 000].
    pub max_evals: Option<usize>,
    /// `auto` or the time of the blow on the record's axis [default auto].
    pub trigger: Option<String>,
    /// The window of a measured force: `auto` (the detected pulse), `none`,
    /// or `T0:T1` [default auto].
    pub force_window: Option<String>,
    /// The record's noise model: `auto`, `white`, `ar`, `ar:P` [default auto].
    pub noise_model: Option<String>,
    /// The sensor's nuisances: `auto`, `none`, `offset`, `offset+drift` [default auto].
    pub nuisance: Option<String>,
    /// Damping model `MODEL[:P1[:P2]]`: `grounded` (the chain's `d`),
    /// `between[:c]`, `rayleigh[:a:b]`; parameters not given are fitted
    /// with `fit = d` (an error otherwise). Default: grounded, or with
    /// `fit = d` every model, the criterion choosing
    /// ([`crate::detect::fit::damping`]).
    pub damping: Option<String>,
    /// A measured profile: the path of a baseline table (CSV, see
    /// [`crate::chain::Baseline`]) or the table inline
    /// (`{ mass = [...], spring = [...] }`); its rows give `n` and the
    /// ends, and defects are reported relative to it [default none: uniform].
    pub baseline: Option<crate::chain::BaselineSpec>,
    /// The level of the intervals, `0 < level < 1` [default 0.9].
    pub level: Option<f64>,
    /// The prior over the number of defects: `uniform` or `site:P` (each
    /// site defective with probability `P`) [default uniform].
    pub prior_k: Option<String>,
    /// The prior range of a defect's value, `LO:HI` times the value it
    /// replaces [default the search range of its kind].
    pub prior_range: Option<String>,
    /// Compute the intervals and the probabilities over hypotheses
    /// [default true].
    pub uncertainty: Option<bool>,
    /// Search every set at every number of defects [default false: from
    /// three defects on, the sets are nested in the best answers of one
    /// fewer; see [`FitOptions::exhaustive`]].
    pub exhaustive: Option<bool>,
    /// `low`, `normal` or `high`: the search's speed against its accuracy
    /// [default normal; see [`super::effort`]].
    pub effort: Option<String>,
}

impl FitSpec {
    /// Every option at its default for a chain of `n` masses.
    pub fn new(n: usize) -> FitSpec {
        FitSpec {
            n,
            ..FitSpec::default()
        }
    }

    /// The search options, parsed before anything else.
    ///
    /// # Errors
    /// The parse errors of the fields (see the module docs), each naming its
    /// field.
    pub fn options(&self) -> Result<FitOptions> {
        let mut opts = FitOptions::default();
        if let Some(d) = &self.defects {
            opts.defects = DefectCount::parse(d)?;
        }
        if opts.defects
            == (DefectCount::Auto {
                k_max: DEFAULT_K_MAX,
            })
            && self.defects.as_deref().is_none_or(|d| d.trim() == "auto")
        {
            // the default tries at most what the chain holds (a 3-mass
            // chain: 0..=3); an explicit `auto:K` above n stays an error
            opts.defects = DefectCount::Auto {
                k_max: DEFAULT_K_MAX.min(self.n),
            };
        }
        if let Some(e) = self.exhaustive {
            opts.exhaustive = e;
        }
        if let Some(e) = &self.effort {
            opts.effort = super::effort::Effort::parse(e)?;
        }
        opts.slot_kinds = self
            .slot_kinds
            .iter()
            .map(|k| parse_kinds(k))
            .collect::<Result<_>>()?;
        if let Some(x) = &self.noise {
            opts.noise = NoiseSpec::parse(x)?;
        }
        if let Some(m) = &self.misfit {
            opts.misfit = Some(MisfitKind::parse(m)?);
        }
        self.kinds_and_method(&mut opts)?;
        if let Some(c) = &self.criterion {
            opts.criterion = Criterion::parse(c)?;
        }
        if let Some(s) = self.seed {
            opts.seed = s;
        }
        if let Some(m) = self.max_evals {
            opts.max_evals = m;
        }
        if let Some(t) = &self.trigger {
            opts.trigger = TriggerSpec::parse(t)?;
        }
        self.force_window()?;
        if let Some(m) = &self.noise_model {
            opts.noise_model = super::record::NoiseModelChoice::parse(m)?;
        }
        if let Some(m) = &self.nuisance {
            opts.nuisance = super::record::NuisanceChoice::parse(m)?;
        }
        if let Some(l) = self.level {
            opts.level = super::intervals::check_level(l)?;
        }
        opts.prior =
            super::prior::Prior::parse(self.prior_k.as_deref(), self.prior_range.as_deref())?;
        if let Some(u) = self.uncertainty {
            opts.uncertainty = u;
        }
        Ok(opts)
    }

    /// The window of a measured force ([`ForceWindow::parse`]).
    ///
    /// # Errors
    /// As [`ForceWindow::parse`] (field `force_window`).
    pub fn force_window(&self) -> Result<ForceWindow> {
        self.force_window
            .as_deref()
            .map_or(Ok(ForceWindow::Auto), ForceWindow::parse)
    }

    /// The measurement with the force `f` at the record's times `t`
    /// windowed ([`crate::detect::data::force_window`]); as
    /// [`FitSpec::measurement`] without a force.
    ///
    /// # Errors
    /// As [`FitSpec::measurement`] and [`crate::detect::data::force_window::apply`].
    pub fn measurement_at(&self, t: &[f64], force: Option<Vec<f64>>) -> Result<Measurement> {
        let Some(f) = force else {
            return self.measurement(None);
        };
        let (g, window) = crate::detect::data::force_window::apply(t, &f, self.force_window()?)?;
        Ok(self.measurement(Some(g))?.with_force_window(window))
    }

    /// What is known of the chain.
    ///
    /// # Errors
    /// As [`Model::new`], [`Model::with_d`], [`Model::with_gamma`],
    /// [`Defect::parse`], [`Model::with_known`], [`parse_params`] and
    /// [`Model::fitting`].
    pub fn model(&self) -> Result<Model> {
        let mut model = Model::new(self.n)?;
        if let Some(d) = self.d {
            model = model.with_d(d)?;
        }
        if let Some(k) = self.k {
            model = model.with_k(k)?;
        }
        if let Some(m) = self.mass {
            model = model.with_mass(m)?;
        }
        if let Some(g) = self.gamma {
            // issue 32 item 11: a zero (or subnormal) impulse gives a zero
            // response, which constrains nothing ("+- NaN")
            if g == 0.0 || crate::io::check_magnitude("gamma", g).is_err() {
                return Err(Error::invalid(
                    "gamma",
                    g,
                    "a non-zero impulse of magnitude 1e-300..=1e300 (the data are the response to it)",
                ));
            }
            model = model.with_gamma(g)?;
        }
        if self.left.is_some() || self.right.is_some() {
            let end = |field: &str, v: &Option<String>| -> Result<Boundary> {
                v.as_deref().map_or(Ok(Boundary::Fixed), |x| {
                    x.parse()
                        .map_err(|_| Error::invalid(field, x, "fixed or free"))
                })
            };
            model = model.with_ends(end("left", &self.left)?, end("right", &self.right)?)?;
        }
        if let Some(spec) = &self.baseline {
            model = model.with_baseline(self.read_baseline(spec)?)?;
        }
        for k in &self.known {
            model = model.with_known(Defect::parse(k)?)?;
        }
        if let Some(f) = &self.fit {
            model = model.fitting(&parse_params(f)?)?;
        }
        model = match &self.damping {
            Some(text) => model.with_damping_spec(text, self.d)?,
            None => model.choosing_damping(),
        };
        Ok(model)
    }

    /// The baseline table of `spec`, checked against `n` and the ends
    /// given.
    ///
    /// # Errors
    /// As [`crate::chain::BaselineSpec::load`] and
    /// [`crate::chain::Baseline::check_agrees`].
    fn read_baseline(&self, spec: &crate::chain::BaselineSpec) -> Result<crate::chain::Baseline> {
        let b = spec.load()?;
        let end = |v: &Option<String>| v.as_deref().and_then(|x| x.parse::<Boundary>().ok());
        b.check_agrees(Some(self.n), end(&self.left), end(&self.right))?;
        Ok(b)
    }

    /// What the record measured: the sensor (`observe`, `observe_kind`),
    /// driven by the measured `force` on mass 1 (samples at the record's
    /// times) or by the impulse (`None`).
    ///
    /// # Errors
    /// `observe_kind` not a known observable, `observe` not a mass of the
    /// chain (field `observe`), a bad force ([`Measurement::with_force`]).
    pub fn measurement(&self, force: Option<Vec<f64>>) -> Result<Measurement> {
        let kind: Observable = self
            .observe_kind
            .as_deref()
            .unwrap_or("displacement")
            .parse()?;
        let sensor = Sensor {
            at: self.observe.unwrap_or(1),
            kind,
        };
        sensor.check(self.n)?;
        let m = Measurement::paper().with_sensor(sensor);
        match force {
            Some(f) => m.with_force(f),
            None => Ok(m),
        }
    }

    /// What every sensor of the record measured, driven by `force` (as
    /// [`FitSpec::measurement`]): one measurement per mass of `sensors`
    /// (the kind of `sensor_kinds`, one for all or one each), or the one
    /// sensor's when `sensors` is empty.
    ///
    /// ```
    /// use springmass::detect::fit::options::FitSpec;
    /// let spec = FitSpec { sensors: vec![1, 30, 60], ..FitSpec::new(60) };
    /// assert_eq!(spec.measurements(None)?.len(), 3);
    /// let twice = FitSpec { sensors: vec![1, 30, 30], ..FitSpec::new(60) };
    /// assert!(twice.measurements(None).is_err());
    /// # Ok::<(), springmass::Error>(())
    /// ```
    ///
    /// # Errors
    /// [`Error::InvalidParameter`]: a mass outside the chain or observed
    /// twice (field `observe`), a kinds list of another length than the
    /// sensors or an unknown kind (field `observe_kind`); as
    /// [`FitSpec::measurement`].
    pub fn measurements(&self, force: Option<Vec<f64>>) -> Result<Vec<Measurement>> {
        if self.sensors.is_empty() {
            return Ok(vec![self.measurement(force)?]);
        }
        let kinds: Vec<String> = match self.sensor_kinds.len() {
            0 => {
                vec![self.observe_kind.clone().unwrap_or("displacement".into()); self.sensors.len()]
            }
            1 => vec![self.sensor_kinds[0].clone(); self.sensors.len()],
            m if m == self.sensors.len() => self.sensor_kinds.clone(),
            m => {
                return Err(Error::invalid(
                    "observe_kind",
                    format!("{m} kinds for {} sensors", self.sensors.len()),
                    "one kind for every sensor, or one per sensor",
                ))
            }
        };
        for (i, at) in self.sensors.iter().enumerate() {
            if self.sensors[..i].contains(at) {
                return Err(Error::invalid(
                    "observe",
                    format!("{:?}", self.sensors),
                    format!("each mass once (mass {at} is listed twice)"),
                ));
            }
        }
        self.sensors
            .iter()
            .zip(kinds)
            .map(|(&at, kind)| {
                FitSpec {
                    observe: Some(at),
                    observe_kind: Some(kind),
                    ..self.clone()
                }
                .measurement(force.clone())
            })
            .collect()
    }

    /// [`FitSpec::measurements`] with the force `f` at the record's times
    /// `t` windowed, as [`FitSpec::measurement_at`].
    ///
    /// # Errors
    /// As [`FitSpec::measurements`] and [`FitSpec::measurement_at`].
    pub fn measurements_at(&self, t: &[f64], force: Option<Vec<f64>>) -> Result<Vec<Measurement>> {
        let Some(f) = force else {
            return self.measurements(None);
        };
        let (g, window) = crate::detect::data::force_window::apply(t, &f, self.force_window()?)?;
        Ok(self
            .measurements(Some(g))?
            .into_iter()
            .map(|m| m.with_force_window(window))
            .collect())
    }

    /// The model and the options: the options are parsed first, then the
    /// model, all before any data are read. Check them against the data with
    /// [`FitOptions::validate`].
    ///
    /// # Errors
    /// As [`FitSpec::options`] and [`FitSpec::model`].
    pub fn build(&self) -> Result<(Model, FitOptions)> {
        // issue 32 item 7: the memory of the fit, before the model is built
        crate::io::check_fit_memory(self.n, false)?;
        let opts = self.options()?;
        Ok((self.model()?, opts))
    }
}

/// `mass`, `spring`, `damper` or `any` (surrounding blanks ignored).
///
/// # Errors
/// [`Error::InvalidParameter`] naming `kinds`.
///
/// ```
/// use springmass::detect::fit::options::parse_kinds;
/// use springmass::detect::unknowns::KindChoice;
/// assert_eq!(parse_kinds(" spring ")?, KindChoice::Spring);
/// assert!(parse_kinds("atom").is_err());
/// # Ok::<(), springmass::Error>(())
/// ```
pub fn parse_kinds(text: &str) -> Result<KindChoice> {
    match text.trim() {
        "any" => Ok(KindChoice::Any),
        "mass-or-spring" => Ok(KindChoice::MassOrSpring),
        name => DefectKind::from_name(name)
            .map(KindChoice::from)
            .ok_or_else(|| {
                let names: Vec<&str> = DefectKind::ALL.iter().map(|k| k.name()).collect();
                Error::invalid(
                    "kinds",
                    text,
                    format!("{}, any or mass-or-spring", names.join(", ")),
                )
            }),
    }
}

impl NoiseSpec {
    /// The known standard deviation (`None` when it is to be estimated): what
    /// the data's [`crate::detect::data::observations::Series`] is told.
    pub fn known(self) -> Option<f64> {
        match self {
            NoiseSpec::Sigma(s) => Some(s),
            NoiseSpec::Auto => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sensitivity::Param;

    fn field(e: Error) -> String {
        match e {
            Error::InvalidParameter { field, .. } => field,
            Error::Parse { what, .. } => what,
            e => panic!("unexpected {e}"),
        }
    }

    #[test]
    fn a_given_set_is_checked() {
        let model = Model::new(5).unwrap();
        let t: Vec<f64> = (0..50).map(|i| 0.5 * i as f64).collect();
        let x = t.iter().map(|t| (0.3 * t).sin()).collect();
        let obs = Observations::Series(Series::new(t, x, None).unwrap());
        let with = |defects, set: Vec<(DefectKind, usize)>| FitOptions {
            defects,
            set,
            ..FitOptions::default()
        };
        let field = |o: FitOptions| match o.validate(&obs, &model) {
            Err(Error::InvalidParameter { field, .. }) => field,
            other => panic!("{other:?}"),
        };
        let two = vec![(DefectKind::Mass, 2), (DefectKind::Spring, 4)];
        assert!(with(DefectCount::Exactly(2), two.clone())
            .validate(&obs, &model)
            .is_ok());
        assert_eq!(field(with(DefectCount::Exactly(1), two)), "defects");
        assert_eq!(
            field(with(DefectCount::Exactly(1), vec![(DefectKind::Mass, 6)])),
            "set"
        );
        assert_eq!(
            field(with(DefectCount::Exactly(1), vec![(DefectKind::Mass, 0)])),
            "set"
        );
        let twice = vec![(DefectKind::Mass, 2), (DefectKind::Mass, 2)];
        assert_eq!(field(with(DefectCount::Exactly(2), twice)), "set");
    }

    #[test]
    fn the_default_number_of_defects_is_capped_at_n() {
        for n in 1..=5 {
            let opts = FitSpec::new(n).options().unwrap();
            let want = DefectCount::Auto { k_max: n.min(4) };
            assert_eq!(opts.defects, want, "n = {n}");
            let spec = FitSpec {
                defects: Some(" auto ".into()),
                ..FitSpec::new(n)
            };
            assert_eq!(spec.options().unwrap().defects, want, "n = {n}, auto");
        }
        // an explicit k_max above n stays the user's error
        let spec = FitSpec {
            defects: Some("auto:4".into()),
            ..FitSpec::new(3)
        };
        assert_eq!(
            spec.options().unwrap().defects,
            DefectCount::Auto { k_max: 4 }
        );
    }

    #[test]
    fn defaults_are_the_library_defaults() {
        let (model, opts) = FitSpec::new(7).build().unwrap();
        assert_eq!(model, Model::new(7).unwrap());
        assert_eq!(opts, FitOptions::default());
    }

    #[test]
    fn every_field_reaches_the_model_or_the_options() {
        let spec = FitSpec {
            d: Some(0.2),
            gamma: Some(2.0),
            fit: Some("d, k".into()),
            known: vec!["spring:0:3".into()],
            defects: Some("2".into()),
            kinds: Some("any".into()),
            slot_kinds: vec!["mass".into(), "damper".into()],
            noise: Some("0.5".into()),
            misfit: Some("bromwich".into()),
            method: Some("enumerate".into()),
            criterion: Some("chi2:0.05".into()),
            seed: Some(9),
            max_evals: Some(77),
            ..FitSpec::new(6)
        };
        let (model, opts) = spec.build().unwrap();
        assert_eq!(model.chain().d(), 0.2);
        assert_eq!(model.chain().gamma(), 2.0);
        assert_eq!(model.fitted(), &[Param::D, Param::K]);
        assert_eq!(model.chain().defects(), &[Defect::Spring { at: 0, k: 3.0 }]);
        assert_eq!(opts.defects, DefectCount::Exactly(2));
        assert_eq!(opts.kinds, KindChoice::Any);
        assert_eq!(opts.slot_kinds, vec![KindChoice::Mass, KindChoice::Damper]);
        assert_eq!(opts.noise, NoiseSpec::Sigma(0.5));
        assert_eq!(opts.noise.known(), Some(0.5));
        assert_eq!(opts.misfit, Some(MisfitKind::Bromwich));
        assert_eq!(opts.criterion, Criterion::ChiSquare { alpha: 0.05 });
        assert_eq!((opts.seed, opts.max_evals), (9, 77));
    }

    #[test]
    fn record_model_fields() {
        use super::super::record::{NoiseModelChoice, NuisanceChoice};
        use crate::detect::data::nuisance::Nuisance;
        let spec = FitSpec {
            noise_model: Some("ar:2".into()),
            nuisance: Some("offset+drift".into()),
            ..FitSpec::new(5)
        };
        let opts = spec.options().unwrap();
        assert_eq!(opts.noise_model, NoiseModelChoice::Ar(Some(2)));
        assert_eq!(opts.nuisance, NuisanceChoice::Fixed(Nuisance::OffsetDrift));
        let bad = |spec: FitSpec| field(spec.build().unwrap_err());
        assert_eq!(
            bad(FitSpec {
                noise_model: Some("pink".into()),
                ..FitSpec::new(5)
            }),
            "noise_model"
        );
        assert_eq!(
            bad(FitSpec {
                nuisance: Some("tilt".into()),
                ..FitSpec::new(5)
            }),
            "nuisance"
        );
        // an AR model or a nuisance needs the time misfit of a series
        let t: Vec<f64> = (0..32).map(|i| i as f64).collect();
        let obs = Observations::Series(
            crate::detect::data::observations::Series::new(t.clone(), t, None).unwrap(),
        );
        let model = Model::new(5).unwrap();
        let with = |misfit: Option<MisfitKind>| FitOptions {
            misfit,
            ..opts.clone()
        };
        assert!(with(None).validate(&obs, &model).is_ok());
        let e = with(Some(MisfitKind::Bromwich)).validate(&obs, &model);
        assert_eq!(field(e.unwrap_err()), "noise_model");
    }

    #[test]
    fn bad_fields_are_named() {
        let bad = |spec: FitSpec| field(spec.build().unwrap_err());
        let base = || FitSpec::new(5);
        assert_eq!(bad(FitSpec { n: 0, ..base() }), "n");
        assert_eq!(
            bad(FitSpec {
                kinds: Some("atom".into()),
                ..base()
            }),
            "kinds"
        );
        assert_eq!(
            bad(FitSpec {
                slot_kinds: vec!["mass".into(), "x".into()],
                ..base()
            }),
            "kinds"
        );
        assert_eq!(
            bad(FitSpec {
                defects: Some("many".into()),
                ..base()
            }),
            "defects"
        );
        assert_eq!(
            bad(FitSpec {
                noise: Some("-1".into()),
                ..base()
            }),
            "noise"
        );
        assert_eq!(
            bad(FitSpec {
                d: Some(f64::NAN),
                ..base()
            }),
            "d"
        );
        assert_eq!(
            bad(FitSpec {
                fit: Some("d,q".into()),
                ..base()
            }),
            "fit"
        );
        assert_eq!(
            bad(FitSpec {
                known: vec!["mass:9".into()],
                ..base()
            }),
            "defect"
        );
        // the options are checked before the model
        assert_eq!(
            bad(FitSpec {
                n: 0,
                misfit: Some("l2".into()),
                ..base()
            }),
            "misfit"
        );
    }
}
