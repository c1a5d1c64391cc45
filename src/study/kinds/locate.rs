//! Kind `locate`: the explicit single-defect locators of section 4.1
//! ([`crate::detect::locate::locate`]), in `f64` or in extended precision
//! ([`crate::precision::BigReal`] at `precision` bits), on data of a chain with one
//! mass defect: exact closed-form `X_1(s)`, or the paper's pipeline (a
//! simulated `x_1(t)`, Laplace-transformed).
//!
//! An unresolvable defect is a result, not a failure: `resolved = false` and
//! the reason in `status`. With `plots = true` the case draws its `j(s)`
//! curve (the paper's Figures 11, 13 and 15).
//!
//! With `precision = 256` (any number of bits in `64..=4096`) the data, the
//! model and the locator all run in [`crate::precision::BigReal`] at that
//! precision (the same generic locator as `springmass locate --precision`);
//! `j_error` and `digits` are computed at the working precision, so they show
//! what the extra bits buy, and `t_locate` what they cost.
//!
//! ```
//! use springmass::study::kinds::Kind;
//! let scene: toml::Value = toml::from_str(
//!     "chain = { n = 20, defects = [ { kind = \"mass\", at = 15, m = 1.01 } ] }").unwrap();
//! let out = Kind::Locate.run(&scene, 0)?;
//! assert_eq!(out.metrics["position"], 15);
//! assert_eq!(out.metrics["success"], true);
//! # Ok::<(), springmass::Error>(())
//! ```

use super::case::{
    chain_problems, num, prefix_chain, range_problems, CaseOutput, CasePlot, KindScene,
};
use crate::chain::{Chain, ChainSpec, Defect};
use crate::detect::locate::{curve, default_grid, locate, LaplaceData, Method, Model, SChoice};
use crate::error::{check_f64, Error, Result};
use crate::plot::{Line, LinePlot};
use crate::precision::RealScalar;
#[cfg(feature = "bigfloat")]
use crate::precision::{with_precision, BigReal};
use crate::study::schema::FieldDoc;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// One paragraph for the schema page.
pub const SUMMARY: &str = "Locates one mass defect from X_1(s) with the section 4.1 locators (exact (4.7), asymptotic (4.10), large-defect (4.17) stable or as printed, unknown mass), in f64 or extended precision, on exact or simulated data; an unresolvable defect is reported as such.";

/// The scene of a `locate` case.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// The chain with exactly one mass defect (the truth).
    pub chain: ChainSpec,
    /// `exact` (default), `asymptotic`, `large`, `large-paper`, `unknown-mass`.
    #[serde(default = "default_method")]
    pub method: String,
    /// Assumed defect mass of `exact` / `asymptotic` (default: the true one).
    #[serde(default)]
    pub m: Option<f64>,
    /// A fixed `s` (default: automatic choice over the default grid).
    #[serde(default)]
    pub s: Option<f64>,
    /// `exact` (default) or `simulated`.
    #[serde(default = "default_source")]
    pub data: String,
    /// `simulated`: end of the record (default 300).
    #[serde(default = "default_t_end")]
    pub t_end: f64,
    /// `simulated`: sampling step (default 0.05).
    #[serde(default = "default_dt")]
    pub dt: f64,
    /// Draw the `j(s)` curve (default false).
    #[serde(default)]
    pub plots: bool,
    /// Working precision: `"f64"` (default) or a number of bits.
    #[serde(default)]
    pub precision: Precision,
}

/// Smallest number of bits of `precision`.
pub const MIN_PRECISION_BITS: i64 = 64;
/// Largest number of bits of `precision` (a study case must stay cheap;
/// `springmass locate --precision` goes further).
pub const MAX_PRECISION_BITS: i64 = 4096;

/// The working precision of a `locate` case: `"f64"` or a number of bits
/// ([`MIN_PRECISION_BITS`]`..=`[`MAX_PRECISION_BITS`]) of
/// [`crate::precision::BigReal`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Precision {
    /// A number of bits.
    Bits(i64),
    /// A name: only `"f64"` is allowed.
    Name(String),
}

impl Default for Precision {
    fn default() -> Self {
        Precision::Name("f64".into())
    }
}

impl Precision {
    /// `None` for `f64`, `Some(bits)` for extended precision.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] on field `precision` for any other name or
    /// a number of bits outside `64..=4096`.
    pub fn bits(&self) -> Result<Option<usize>> {
        const ALLOWED: &str = "\"f64\" or a number of bits 64..=4096 (e.g. 128, 256, 512)";
        match self {
            Precision::Name(n) if n == "f64" => Ok(None),
            Precision::Name(n) => Err(Error::invalid("precision", format!("{n:?}"), ALLOWED)),
            Precision::Bits(b) if (MIN_PRECISION_BITS..=MAX_PRECISION_BITS).contains(b) => {
                Ok(Some(*b as usize))
            }
            Precision::Bits(b) => Err(Error::invalid("precision", b, ALLOWED)),
        }
    }

    /// `f64` or `<bits> bits`.
    pub fn label(&self) -> String {
        match self {
            Precision::Bits(b) => format!("{b} bits"),
            Precision::Name(n) => n.clone(),
        }
    }
}

serde_defaults! {
    fn default_method() -> String = "exact".into();
    fn default_source() -> String = "exact".into();
    fn default_t_end() -> f64 = 300.0;
    fn default_dt() -> f64 = 0.05;
}

/// Every scene field of kind `locate`.
pub const FIELDS: &[FieldDoc] = &[
    FieldDoc::new("chain", "table", "required", "The chain, with exactly one mass defect: the truth that makes the data."),
    FieldDoc::new("chain.n", "integer >= 1", "required", "Number of masses."),
    FieldDoc::new("chain.k", "float > 0", "1", "Uniform spring constant."),
    FieldDoc::new("chain.d", "float >= 0", "0.1", "Uniform damping."),
    FieldDoc::new("chain.gamma", "float", "1", "Impulse on mass 1."),
    FieldDoc::new("chain.mass", "float > 0", "1", "Uniform mass."),
    FieldDoc::new("chain.defects", "array of tables", "required", "Exactly one `{ kind = \"mass\", at, m }`."),
    FieldDoc::new("chain.defects[].kind", "\"mass\"", "required", "The defect kind (mass)."),
    FieldDoc::new("chain.defects[].at", "integer", "required", "Its position (the answer sought)."),
    FieldDoc::new("chain.defects[].m", "float > 0", "required", "Its mass."),
    FieldDoc::new("chain.defects[].k", "float > 0", "none", "Not used (spring defects are not located)."),
    FieldDoc::new("chain.defects[].d", "float >= 0", "none", "Not used (damper defects are not located)."),
    FieldDoc::new("method", "\"exact\" | \"asymptotic\" | \"large\" | \"large-paper\" | \"unknown-mass\"", "\"exact\"", "Relation solved for j: (4.7); (4.10); (4.17) rewritten stably and extrapolated; (4.17) as printed; (4.7) at several s with the mass fitted."),
    FieldDoc::new("m", "float > 0", "the true mass", "Assumed defect mass of `exact` and `asymptotic` (a wrong m measures the sensitivity)."),
    FieldDoc::new("s", "float > 0", "automatic", "A fixed s; default: every s of the default grid (1e-3 ... 1e2) and the best resolved estimate."),
    FieldDoc::new("data", "\"exact\" | \"simulated\"", "\"exact\"", "X_1(s) from the closed form, or from x_1(t) simulated on [0, t_end] and Laplace-transformed (the paper's pipeline)."),
    FieldDoc::new("t_end", "float > 0", "300", "`simulated`: end of the record."),
    FieldDoc::new("dt", "float > 0", "0.05", "`simulated`: sampling step."),
    FieldDoc::new("plots", "bool", "false", "Draw this case's j(s) curve into `cases/<id>-js.svg`."),
    FieldDoc::new("precision", "\"f64\" | integer 64..=4096", "\"f64\"", "Working precision of data, model and locator: `f64`, or that many bits of extended precision (BigReal, as `springmass locate --precision`). Sweep it to trade time for digits: `values = [\"f64\", 128, 256, 512]`."),
];

/// Every metric and timing of kind `locate`.
pub const METRICS: &[(&str, &str)] = &[
    ("truth", "true position of the defect"),
    (
        "resolved",
        "the locator returned a position (not unresolvable at this precision with this data)",
    ),
    ("bits", "working precision in bits (53 for f64)"),
    ("success", "the position returned is the true one"),
    ("position", "position returned (empty when unresolved)"),
    ("j", "real-valued estimate of j before rounding"),
    (
        "j_error",
        "|j - true position|, computed at the working precision",
    ),
    (
        "digits",
        "correct significant digits of j: -log10(j_error / truth), at most the precision's",
    ),
    ("sigma", "its uncertainty from the data's error"),
    ("bias", "its model error (asymptotics, extrapolation)"),
    ("s_used", "the s of the answer"),
    ("mass_fitted", "the fitted mass (unknown-mass locator)"),
    ("status", "`ok` or why the defect could not be located"),
    ("t_locate", "measured seconds of data and locator"),
];

impl KindScene for Scene {
    const FIELDS: &'static [FieldDoc] = FIELDS;

    /// Every failed check, each naming its field: the chain and its one
    /// defect, the method and its mass, `s`, the data source and its
    /// sampling, the precision.
    fn problems(&self) -> Vec<Error> {
        let mut out = chain_problems(&self.chain);
        if out.is_empty() {
            if let Err(e) = self.truth() {
                out.push(e);
            }
        }
        if let Some(m) = self.m {
            if let Err(e) = check_f64("m", m, m > 0.0, "m > 0 and finite") {
                out.push(e);
            }
        }
        if let Err(e) = method_of(&self.method, 1.0) {
            out.push(e);
        }
        if let Some(s) = self.s {
            if let Err(e) = check_f64("s", s, s > 0.0, "s > 0 and finite") {
                out.push(e);
            }
        }
        match self.data.as_str() {
            "exact" => {}
            "simulated" => out.extend(range_problems(&[
                (
                    "t_end",
                    self.t_end,
                    self.t_end > 0.0,
                    "t_end > 0 and finite",
                ),
                (
                    "dt",
                    self.dt,
                    self.dt > 0.0 && self.dt <= self.t_end && self.t_end / self.dt <= 2e6,
                    "0 < dt <= t_end, at most 2e6 steps",
                ),
            ])),
            other => out.push(Error::invalid("data", other, "\"exact\" or \"simulated\"")),
        }
        if let Err(e) = self.precision.bits() {
            out.push(e);
        }
        out
    }
}

/// The locator named `name`, with the known mass `m` of `exact` /
/// `asymptotic`.
fn method_of(name: &str, m: f64) -> Result<Method> {
    Method::from_name(name, || Ok(m))
}

impl Scene {
    /// Deserialize and check a resolved scene (the first problem).
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming the field.
    pub fn from_value(value: &toml::Value) -> Result<Scene> {
        <Scene as KindScene>::from_value(value)
    }

    /// The true chain and its defect `(at, m)`.
    fn truth(&self) -> Result<(Chain, usize, f64)> {
        let chain = self.chain.build().map_err(prefix_chain)?;
        match chain.defects() {
            [Defect::Mass { at, m }] => Ok((chain.clone(), *at, *m)),
            d => Err(Error::invalid(
                "chain.defects",
                format!("{} defects", d.len()),
                "exactly one mass defect",
            )),
        }
    }

    fn method(&self) -> Result<Method> {
        let m = match self.m {
            Some(m) => check_f64("m", m, m > 0.0, "m > 0 and finite")?,
            None => self.truth()?.2,
        };
        method_of(&self.method, m)
    }
}

/// Run one `locate` case, in `f64` or, with `precision = BITS`, in
/// [`BigReal`] at that many bits (data, model and locator alike).
///
/// # Errors
/// An invalid scene; data that cannot be made (simulator failures).
pub fn run(scene: &Scene, seed: u64) -> Result<CaseOutput> {
    match scene.precision.bits()? {
        None => run_in::<f64>(scene, seed, 53),
        #[cfg(feature = "bigfloat")]
        Some(bits) => with_precision(bits, || run_in::<BigReal>(scene, seed, bits)),
        #[cfg(not(feature = "bigfloat"))]
        Some(bits) => Err(crate::precision::unavailable(bits)),
    }
}

fn run_in<T: RealScalar>(scene: &Scene, _seed: u64, bits: usize) -> Result<CaseOutput> {
    let (chain, at, _) = scene.truth()?;
    let method = scene.method()?;
    let large = matches!(method, Method::Large | Method::LargePaper);
    let (grid, choice) = match scene.s {
        None => (default_grid(), SChoice::Auto),
        Some(s) if large => (vec![s / 2.0, s / 2f64.sqrt(), s], SChoice::At(s)),
        Some(s) => (vec![s], SChoice::At(s)),
    };
    // warm the thread's constant cache of the number type (a one-off per
    // worker thread, not a cost of this case)
    let _ = T::from_f64(2.0).ln();
    chain.require_fixed_ends("the explicit locators of section 4.1")?;
    chain.require_uniform("the explicit locators of section 4.1")?;
    let start = Instant::now();
    let data: LaplaceData<T> = match scene.data.as_str() {
        "simulated" => LaplaceData::from_simulation(&chain, scene.t_end, scene.dt, &grid)?,
        _ => LaplaceData::from_chain(&chain, &grid)?,
    };
    let model: Model<T> = Model::from_chain(&chain);
    let result = locate(&model, &data, method, choice);
    let t = start.elapsed().as_secs_f64();
    let mut out = CaseOutput::default();
    let m = &mut out.metrics;
    m.insert("truth".into(), at.into());
    m.insert("bits".into(), bits.into());
    match result {
        Ok(loc) => {
            // the error of the real estimate, computed in T (it can be far
            // below f64's epsilon at extended precision)
            let err = (loc.j.clone() - T::from_f64(at as f64)).abs().to_f64();
            let max_digits = bits as f64 * std::f64::consts::LOG10_2;
            let digits = if err > 0.0 {
                (-(err / at as f64).log10()).clamp(0.0, max_digits)
            } else {
                max_digits
            };
            m.insert("resolved".into(), true.into());
            m.insert("success".into(), (loc.position == at).into());
            m.insert("position".into(), loc.position.into());
            m.insert("j".into(), num(loc.j.to_f64()));
            m.insert("j_error".into(), num(err));
            m.insert("digits".into(), num(digits));
            m.insert("sigma".into(), num(loc.sigma));
            m.insert("bias".into(), num(loc.bias));
            m.insert("s_used".into(), num(loc.s));
            m.insert(
                "mass_fitted".into(),
                loc.mass.map_or(serde_json::Value::Null, num),
            );
            m.insert("status".into(), "ok".into());
        }
        Err(e @ Error::Unresolvable { .. }) => {
            m.insert("resolved".into(), false.into());
            m.insert("success".into(), false.into());
            m.insert("status".into(), e.to_string().into());
        }
        Err(e) => return Err(e),
    }
    out.timing("t_locate", t);
    if scene.plots {
        if let Some(plot) = js_plot(scene, &model, &data, method, at)? {
            out.plots.push(plot);
        }
    }
    Ok(out)
}

/// The plot of the estimates `j(s)` against the true position `at`.
fn js_plot<T: RealScalar>(
    scene: &Scene,
    model: &Model<T>,
    data: &LaplaceData<T>,
    method: Method,
    at: usize,
) -> Result<Option<CasePlot>> {
    let est = curve(model, data, method)?;
    let pts: Vec<(f64, f64)> = est.iter().map(|e| (e.s, e.j_f64())).collect();
    let truth: Vec<(f64, f64)> = est.iter().map(|e| (e.s, at as f64)).collect();
    let chart = LinePlot::new(
        format!(
            "j(s), {} locator, {}, true j = {at}",
            method.name(),
            scene.precision.label()
        ),
        "s",
        "j(s)",
    )
    .log_x(true)
    .line(Line::new("j(s)", pts))
    .line(Line::new("true j", truth).dashed());
    Ok(CasePlot::of_lines("js", &chart).ok())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::study::kinds::Kind;

    #[test]
    fn locates_and_reports_unresolvable() {
        let v: toml::Value = toml::from_str(
            "chain = { n = 5, defects = [ { kind = \"mass\", at = 3, m = 4.0 } ] }\nmethod = \"large\"\nplots = true",
        )
        .unwrap();
        let out = Kind::Locate.run(&v, 0).unwrap();
        assert_eq!(out.metrics["truth"], 3);
        assert!(out.metrics["resolved"].is_boolean());
        assert_eq!(out.plots.len(), 1);
        for (text, field) in [
            ("chain = { n = 5 }", "chain.defects"),
            ("chain = { n = 5, defects = [ { kind = \"mass\", at = 3, m = 4.0 } ] }\nmethod = \"big\"", "method"),
            ("chain = { n = 5, defects = [ { kind = \"mass\", at = 3, m = 4.0 } ] }\ndata = \"measured\"", "data"),
        ] {
            let v: toml::Value = toml::from_str(text).unwrap();
            match Kind::Locate.validate(&v) {
                Err(Error::InvalidParameter { field: f, .. }) => assert_eq!(f, field, "{text}"),
                other => panic!("{text}: {other:?}"),
            }
        }
    }

    #[test]
    #[cfg(feature = "bigfloat")]
    fn extended_precision_buys_digits() {
        let base =
            "chain = { n = 20, defects = [ { kind = \"mass\", at = 15, m = 1.01 } ] }\ns = 0.3\n";
        let f64_out = Kind::Locate.run(&toml::from_str(base).unwrap(), 0).unwrap();
        let big: toml::Value = toml::from_str(&format!("{base}precision = 256")).unwrap();
        let big_out = Kind::Locate.run(&big, 0).unwrap();
        assert_eq!(f64_out.metrics["bits"], 53);
        assert_eq!(big_out.metrics["bits"], 256);
        assert_eq!(big_out.metrics["success"], true);
        let d = |o: &CaseOutput| o.metrics["digits"].as_f64().unwrap();
        assert!(d(&f64_out) > 8.0 && d(&f64_out) < 16.0, "{f64_out:?}");
        assert!(d(&big_out) > 60.0, "{big_out:?}");
        // the precision left at its default on this thread
        assert_eq!(
            crate::precision::precision(),
            crate::precision::DEFAULT_BITS
        );
        for bad in ["precision = 8", "precision = \"double\"", "precision = 1e3"] {
            let v: toml::Value = toml::from_str(&format!("{base}{bad}")).unwrap();
            let errs = Kind::Locate.validate_all(&v);
            assert_eq!(errs.len(), 1, "{bad}: {errs:?}");
            assert!(
                matches!(&errs[0], Error::InvalidParameter { field, .. } if field == "precision"),
                "{bad}: {errs:?}"
            );
        }
    }
}
