//! Kind `forward`: the Woodbury closed form against the O(n) tridiagonal
//! reference.
//!
//! For a chain with defects (given explicitly, drawn at random with the
//! case's seed, or both), evaluate `X_observe(s)` on an `s` grid by
//!
//! - the closed-form Green's function plus a `k x k` Woodbury solve
//!   ([`crate::forward::Forward::eval_with`]), O(k^3) per `s` whatever `n`, and
//! - the pivoted O(n) tridiagonal solve ([`crate::forward::tridiag::solve`]),
//!   the reference, and
//! - the O(k) cancellation-free transfer sweep
//!   ([`crate::forward::transfer::Transfer`], behind `Forward::eval`),
//!
//! and record the largest relative difference of each fast path to the
//! reference together with the measured time per `s` of each path. Points where the reference is not
//! resolvable in f64 (zero, subnormal or not finite) are counted in
//! `unresolved` and left out of the differences.
//!
//! ```
//! use springmass::study::kinds::{forward, Kind};
//! let scene: toml::Value = toml::from_str(r#"
//!     chain = { n = 50 }
//!     random_defects = { count = 3 }
//!     s = { count = 8 }
//! "#).unwrap();
//! let out = Kind::Forward.run(&scene, 42)?;
//! assert_eq!(out.metrics["defects"], 3);
//! assert!(out.metrics["max_rel_diff"].as_f64().unwrap() < 1e-10);
//! # Ok::<(), springmass::Error>(())
//! ```

use super::case::{prefix_chain, CaseOutput, KindScene};
use crate::chain::{ChainSpec, Defect};
use crate::error::{check_f64, Error, Result};
use crate::forward::transfer::Transfer;
use crate::forward::{tridiag, Forward};
use crate::scalar::Scalar;
use crate::study::schema::FieldDoc;
use num_complex::Complex64;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::hint::black_box;
use std::time::Instant;

/// One paragraph for the schema page.
pub const SUMMARY: &str = "Evaluates X_observe(s) on an s grid for a chain with defects by the Woodbury closed form and by the O(n) tridiagonal reference; records their largest relative difference and the measured time per s of each path.";

/// The scene of a `forward` case.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// The chain, with its explicit defects.
    pub chain: ChainSpec,
    /// Defects drawn at random with the case's seed, added to `chain.defects`.
    #[serde(default)]
    pub random_defects: RandomDefects,
    /// The grid of `s`.
    #[serde(default)]
    pub s: Grid,
    /// Observed mass, 1-based (default 1).
    #[serde(default = "one")]
    pub observe: usize,
    /// Timing control.
    #[serde(default)]
    pub timing: Timing,
}

/// Random defects: distinct positions, log-uniform values.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RandomDefects {
    /// How many (default 0).
    #[serde(default)]
    pub count: usize,
    /// `mass`, `spring` or `damper` (default `mass`).
    #[serde(default = "default_kind")]
    pub kind: String,
    /// Smallest value (default 0.5).
    #[serde(default = "half")]
    pub min: f64,
    /// Largest value (default 5).
    #[serde(default = "five")]
    pub max: f64,
}

impl Default for RandomDefects {
    fn default() -> Self {
        RandomDefects {
            count: 0,
            kind: default_kind(),
            min: half(),
            max: five(),
        }
    }
}

/// A grid of `s`: real `s = t`, or the vertical line `s = sigma + i t`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Grid {
    /// First `t` (default 0.01).
    #[serde(default = "default_from")]
    pub from: f64,
    /// Last `t` (default 10).
    #[serde(default = "default_to")]
    pub to: f64,
    /// Number of points (default 32).
    #[serde(default = "default_count")]
    pub count: usize,
    /// `log` (default) or `linear`.
    #[serde(default = "default_spacing")]
    pub spacing: String,
    /// If given, `s = sigma + i t` (complex); otherwise `s = t` (real).
    #[serde(default)]
    pub sigma: Option<f64>,
}

impl Default for Grid {
    fn default() -> Self {
        Grid {
            from: default_from(),
            to: default_to(),
            count: default_count(),
            spacing: default_spacing(),
            sigma: None,
        }
    }
}

/// Timing control.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Timing {
    /// Time budget per path (default 0.002 s): five rounds of passes over the
    /// grid, each at least `min_seconds / 5` long; the fastest round counts.
    #[serde(default = "default_min_seconds")]
    pub min_seconds: f64,
}

impl Default for Timing {
    fn default() -> Self {
        Timing {
            min_seconds: default_min_seconds(),
        }
    }
}

serde_defaults! {
    fn one() -> usize = 1;
    fn default_kind() -> String = "mass".into();
    fn half() -> f64 = 0.5;
    fn five() -> f64 = 5.0;
    fn default_from() -> f64 = 0.01;
    fn default_to() -> f64 = 10.0;
    fn default_count() -> usize = 32;
    fn default_spacing() -> String = "log".into();
    fn default_min_seconds() -> f64 = 0.002;
}

/// Largest grid.
pub const MAX_POINTS: usize = 100_000;

/// Every scene field of kind `forward`.
pub const FIELDS: &[FieldDoc] = &[
    FieldDoc::new("chain", "table", "required", "The chain (as the `[chain]` table of a scene file)."),
    FieldDoc::new("chain.n", "integer >= 1", "required", "Number of masses."),
    FieldDoc::new("chain.k", "float > 0", "1", "Uniform spring constant."),
    FieldDoc::new("chain.d", "float >= 0", "0.1", "Uniform damping (the paper's 0.1)."),
    FieldDoc::new("chain.gamma", "float", "1", "Impulse on mass 1."),
    FieldDoc::new("chain.mass", "float > 0", "1", "Uniform mass."),
    FieldDoc::new("chain.defects", "array of tables", "[]", "Explicit defects, e.g. `{ kind = \"mass\", at = 8, m = 5.0 }`."),
    FieldDoc::new("chain.defects[].kind", "\"mass\" | \"spring\" | \"damper\"", "required", "What differs."),
    FieldDoc::new("chain.defects[].at", "integer", "required", "Position: masses and dampers 1..=n, springs 0..=n (spring i joins masses i and i+1)."),
    FieldDoc::new("chain.defects[].m", "float > 0", "required for mass", "The mass (kind `mass`)."),
    FieldDoc::new("chain.defects[].k", "float > 0", "required for spring", "The stiffness (kind `spring`)."),
    FieldDoc::new("chain.defects[].d", "float >= 0", "required for damper", "The damping (kind `damper`)."),
    FieldDoc::new("random_defects", "table", "{}", "Defects drawn with the case's seed and added to `chain.defects`."),
    FieldDoc::new("random_defects.count", "integer >= 0", "0", "How many (distinct positions, none where `chain.defects` has one of the same kind)."),
    FieldDoc::new("random_defects.kind", "\"mass\" | \"spring\" | \"damper\"", "\"mass\"", "Kind of the random defects."),
    FieldDoc::new("random_defects.min", "float > 0", "0.5", "Smallest value (values are log-uniform in [min, max])."),
    FieldDoc::new("random_defects.max", "float >= min", "5", "Largest value."),
    FieldDoc::new("s", "table", "{}", "The s grid."),
    FieldDoc::new("s.from", "float >= 0", "0.01", "First grid parameter t."),
    FieldDoc::new("s.to", "float >= from", "10", "Last grid parameter t."),
    FieldDoc::new("s.count", "integer in 1..=100000", "32", "Number of points."),
    FieldDoc::new("s.spacing", "\"log\" | \"linear\"", "\"log\"", "Spacing of t (`log` needs from > 0)."),
    FieldDoc::new("s.sigma", "float >= 0", "none (real s = t)", "If given, s = sigma + i t on a vertical (Bromwich) line; otherwise s = t on the real axis."),
    FieldDoc::new("observe", "integer in 1..=n", "1", "Observed mass."),
    FieldDoc::new("timing", "table", "{}", "Timing control."),
    FieldDoc::new("timing.min_seconds", "float in [0, 60]", "0.002", "Time budget per path: five rounds, each repeating the pass over the grid for min_seconds / 5 (at least once); the fastest round is reported (longer = steadier timings)."),
];

/// Every metric and timing of kind `forward`.
pub const METRICS: &[(&str, &str)] = &[
    ("n", "number of masses"),
    ("defects", "number of defects k (explicit plus random)"),
    ("points", "number of s points"),
    ("unresolved", "points where the O(n) reference is zero, subnormal or not finite in f64 (left out of the differences)"),
    ("woodbury_nonfinite", "resolved points where the closed form gave a non-finite value"),
    ("max_rel_diff", "largest |X_woodbury - X_reference| / |X_reference| over resolved points"),
    ("max_rel_diff_transfer", "largest |X_transfer - X_reference| / |X_reference| over resolved points (the O(k) cancellation-free sweep behind `Forward::eval`)"),
    ("rms_rel_diff", "root mean square of the relative differences over resolved points"),
    ("x_min", "smallest |X_reference| over resolved points"),
    ("x_max", "largest |X_reference| over resolved points"),
    ("t_woodbury", "measured seconds per s of the closed form + Woodbury path"),
    ("t_reference", "measured seconds per s of the O(n) tridiagonal path"),
    ("t_transfer", "measured seconds per s of the O(k) transfer sweep"),
    ("t_speedup", "t_reference / t_woodbury"),
];

impl KindScene for Scene {
    const FIELDS: &'static [FieldDoc] = FIELDS;

    fn problems(&self) -> Vec<Error> {
        let r = &self.random_defects;
        let g = &self.s;
        let checks: [&dyn Fn() -> Result<()>; 6] = [
            &|| {
                let chain = self.chain.build().map_err(prefix_chain)?;
                chain.check_observe(self.observe).map(|_| ())
            },
            &|| {
                defect_kind(&r.kind)?;
                check_f64(
                    "random_defects.min",
                    r.min,
                    r.min > 0.0,
                    "min > 0 and finite",
                )?;
                check_f64(
                    "random_defects.max",
                    r.max,
                    r.max >= r.min,
                    "max >= min and finite",
                )?;
                let free = free_positions(&self.chain, &r.kind);
                if r.count > free {
                    return Err(Error::invalid(
                        "random_defects.count",
                        r.count,
                        format!("at most {free} (free {} positions of the chain)", r.kind),
                    ));
                }
                Ok(())
            },
            &|| {
                check_f64("s.from", g.from, g.from >= 0.0, "from >= 0 and finite")?;
                check_f64("s.to", g.to, g.to >= g.from, "to >= from and finite")?;
                match g.spacing.as_str() {
                    "linear" => Ok(()),
                    "log" => check_f64("s.from", g.from, g.from > 0.0, "from > 0 with log spacing")
                        .map(|_| ()),
                    other => Err(Error::invalid("s.spacing", other, "\"log\" or \"linear\"")),
                }
            },
            &|| {
                if g.count == 0 || g.count > MAX_POINTS {
                    return Err(Error::invalid(
                        "s.count",
                        g.count,
                        format!("1 <= count <= {MAX_POINTS}"),
                    ));
                }
                Ok(())
            },
            &|| match g.sigma {
                Some(sig) => {
                    check_f64("s.sigma", sig, sig >= 0.0, "sigma >= 0 and finite").map(|_| ())
                }
                None => Ok(()),
            },
            &|| {
                let t = self.timing.min_seconds;
                check_f64(
                    "timing.min_seconds",
                    t,
                    (0.0..=60.0).contains(&t),
                    "0 <= min_seconds <= 60",
                )
                .map(|_| ())
            },
        ];
        checks.iter().filter_map(|c| c().err()).collect()
    }
}

impl Scene {
    /// The grid parameters `t`.
    pub fn grid(&self) -> Vec<f64> {
        let g = &self.s;
        let c = g.count;
        (0..c)
            .map(|i| {
                if c == 1 {
                    return g.from;
                }
                if i == c - 1 {
                    return g.to;
                }
                let f = i as f64 / (c - 1) as f64;
                if g.spacing == "log" {
                    (g.from.ln() + (g.to.ln() - g.from.ln()) * f).exp()
                } else {
                    g.from + (g.to - g.from) * f
                }
            })
            .collect()
    }

    /// The chain spec with the random defects drawn from `seed` appended.
    ///
    /// # Errors
    /// As [`Scene::check`].
    pub fn chain_with_random(&self, seed: u64) -> Result<ChainSpec> {
        let mut spec = self.chain.clone();
        let r = &self.random_defects;
        let kind = defect_kind(&r.kind)?;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let (lo, hi) = if spring_like(kind) {
            (0, spec.n)
        } else {
            (1, spec.n)
        };
        for _ in 0..r.count {
            // rejection sampling: count <= free positions (checked)
            let at = loop {
                let at = rng.random_range(lo..=hi);
                if !spec
                    .defects
                    .iter()
                    .any(|d| d.kind() == kind && d.at() == at)
                {
                    break at;
                }
            };
            let u: f64 = rng.random();
            let v = (r.min.ln() + u * (r.max.ln() - r.min.ln())).exp();
            // `kind` is one of Defect::KINDS (checked by `defect_kind`)
            spec.defects
                .extend(Defect::of_kind(kind, at, v).or(Some(Defect::Mass { at, m: v })));
        }
        Ok(spec)
    }
}

fn defect_kind(kind: &str) -> Result<&'static str> {
    Defect::KINDS
        .into_iter()
        .find(|k| *k == kind)
        .ok_or_else(|| {
            Error::invalid(
                "random_defects.kind",
                kind,
                format!("one of {}", Defect::KINDS.join(", ")),
            )
        })
}

/// Whether defects of `kind` sit on springs (positions `0..=n`) rather
/// than on masses (`1..=n`).
fn spring_like(kind: &str) -> bool {
    Defect::of_kind(kind, 1, 1.0)
        .is_some_and(|d| matches!(d.site().probe, crate::chain::Probe::Diff(_)))
}

fn free_positions(spec: &ChainSpec, kind: &str) -> usize {
    let total = if spring_like(kind) {
        spec.n + 1
    } else {
        spec.n
    };
    let mut used: Vec<usize> = spec
        .defects
        .iter()
        .filter(|d| d.kind() == kind)
        .map(|d| d.at())
        .collect();
    used.sort_unstable();
    used.dedup();
    total.saturating_sub(used.len())
}

/// Run one `forward` case.
///
/// # Errors
/// An invalid scene; [`Error::Singular`] from the reference at a pole.
pub fn run(scene: &Scene, seed: u64) -> Result<CaseOutput> {
    scene.check()?;
    let spec = scene.chain_with_random(seed)?;
    let chain = spec.build().map_err(prefix_chain)?;
    let ts = scene.grid();
    let min_t = scene.timing.min_seconds;
    let obs = scene.observe;
    let m = match scene.s.sigma {
        None => measure(&chain, &ts, obs, min_t, |t| t)?,
        Some(sig) => measure(&chain, &ts, obs, min_t, |t| Complex64::new(sig, t))?,
    };
    let mut out = CaseOutput::default();
    out.metrics.insert("n".into(), chain.n().into());
    out.metrics
        .insert("defects".into(), chain.defects().len().into());
    out.metrics.insert("points".into(), ts.len().into());
    out.metrics.insert("unresolved".into(), m.unresolved.into());
    out.metrics
        .insert("woodbury_nonfinite".into(), m.nonfinite.into());
    out.metric("max_rel_diff", m.max_rel);
    out.metric("max_rel_diff_transfer", m.max_rel_transfer);
    out.metric("rms_rel_diff", m.rms_rel);
    out.metric("x_min", m.x_min);
    out.metric("x_max", m.x_max);
    out.timing("t_woodbury", m.t_woodbury);
    out.timing("t_reference", m.t_reference);
    out.timing("t_transfer", m.t_transfer);
    out.timing("t_speedup", m.t_reference / m.t_woodbury);
    Ok(out)
}

struct Measured {
    unresolved: usize,
    nonfinite: usize,
    max_rel: f64,
    max_rel_transfer: f64,
    rms_rel: f64,
    x_min: f64,
    x_max: f64,
    t_woodbury: f64,
    t_reference: f64,
    t_transfer: f64,
}

/// Seconds per call of `pass`: the best of five rounds, each repeating
/// `pass` until it has run `min_t / 5` seconds (at least once). Taking the
/// best round filters out preemption by other threads and processes.
fn time_per_pass(min_t: f64, mut pass: impl FnMut()) -> f64 {
    let round_t = min_t / 5.0;
    let mut best = f64::INFINITY;
    for _ in 0..5 {
        let start = Instant::now();
        let mut reps = 0u64;
        loop {
            pass();
            reps += 1;
            let el = start.elapsed().as_secs_f64();
            if el >= round_t || reps >= 1_000_000 {
                best = best.min(el / reps as f64);
                break;
            }
        }
    }
    best
}

/// The accuracy of the Woodbury values `xw` and the transfer values `xt`
/// against the reference `xr` (times left at zero).
fn compare<T: Scalar>(xw: &[T], xr: &[T], xt: &[T]) -> Measured {
    let mut m = Measured {
        unresolved: 0,
        nonfinite: 0,
        max_rel: 0.0,
        max_rel_transfer: 0.0,
        rms_rel: 0.0,
        x_min: f64::INFINITY,
        x_max: 0.0,
        t_woodbury: 0.0,
        t_reference: 0.0,
        t_transfer: 0.0,
    };
    let mut sum2 = 0.0;
    let mut resolved = 0usize;
    for ((w, r), t) in xw.iter().zip(xr).zip(xt) {
        let mag = r.magnitude();
        if !(mag.is_finite() && mag >= f64::MIN_POSITIVE) {
            m.unresolved += 1;
            continue;
        }
        resolved += 1;
        m.x_min = m.x_min.min(mag);
        m.x_max = m.x_max.max(mag);
        let rel_t = (t.clone() - r.clone()).magnitude() / mag;
        m.max_rel_transfer = if rel_t.is_nan() {
            f64::INFINITY
        } else {
            m.max_rel_transfer.max(rel_t)
        };
        if !w.is_finite() {
            m.nonfinite += 1;
            m.max_rel = f64::INFINITY;
            continue;
        }
        let rel = (w.clone() - r.clone()).magnitude() / mag;
        m.max_rel = m.max_rel.max(rel);
        sum2 += rel * rel;
    }
    if resolved == 0 {
        m.max_rel = f64::NAN;
        m.max_rel_transfer = f64::NAN;
        m.rms_rel = f64::NAN;
        m.x_min = f64::NAN;
        m.x_max = f64::NAN;
    } else {
        m.rms_rel = (sum2 / resolved as f64).sqrt();
    }
    m
}

fn measure<T: Scalar>(
    chain: &crate::Chain,
    ts: &[f64],
    observe: usize,
    min_t: f64,
    make: impl Fn(f64) -> T,
) -> Result<Measured> {
    chain.require_grounded(
        "the transfer sweep's timing (its closed form is the grounded model's)",
    )?;
    let pts: Vec<T> = ts.iter().map(|&t| make(t)).collect();
    for s in &pts {
        crate::forward::check_s(s)?;
    }
    let fwd = Forward::new(chain);
    let mut xw: Vec<T> = vec![T::zero(); pts.len()];
    let t_w = time_per_pass(min_t, || {
        for (x, s) in xw.iter_mut().zip(&pts) {
            let g = fwd.green(black_box(s.clone()));
            *x = fwd.eval_with(&g, s, observe);
        }
        black_box(&xw);
    });
    let mut xt: Vec<T> = vec![T::zero(); pts.len()];
    let tr = Transfer::new(chain);
    let t_t = time_per_pass(min_t, || {
        for (x, s) in xt.iter_mut().zip(&pts) {
            *x = tr.eval(black_box(s), observe);
        }
        black_box(&xt);
    });
    let mut xr: Vec<T> = vec![T::zero(); pts.len()];
    let mut err: Option<Error> = None;
    let t_r = time_per_pass(min_t, || {
        for (x, s) in xr.iter_mut().zip(&pts) {
            match tridiag::solve(chain, black_box(s.clone()), observe) {
                Ok(v) => *x = v,
                Err(e) => {
                    err.get_or_insert(e);
                }
            }
        }
        black_box(&xr);
    });
    if let Some(e) = err {
        return Err(e);
    }
    let mut m = compare(&xw, &xr, &xt);
    m.t_woodbury = t_w / pts.len() as f64;
    m.t_reference = t_r / pts.len() as f64;
    m.t_transfer = t_t / pts.len() as f64;
    Ok(m)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::study::kinds::Kind;

    fn scene(text: &str) -> toml::Value {
        toml::from_str(text).unwrap()
    }

    #[test]
    fn agrees_with_reference_real_and_complex() {
        for text in [
            "chain = { n = 20, defects = [ { kind = \"mass\", at = 8, m = 5.0 }, { kind = \"mass\", at = 15, m = 2.0 } ] }\ntiming = { min_seconds = 0.0 }",
            "chain = { n = 300 }\nrandom_defects = { count = 4, kind = \"spring\" }\ns = { sigma = 0.05, from = 0.0, to = 20, spacing = \"linear\", count = 17 }\ntiming = { min_seconds = 0.0 }",
            "chain = { n = 7 }\nrandom_defects = { count = 7, kind = \"damper\" }\nobserve = 7\ntiming = { min_seconds = 0.0 }",
        ] {
            let out = Kind::Forward.run(&scene(text), 3).unwrap();
            let d = out.metrics["max_rel_diff"].as_f64().unwrap();
            assert!(d < 1e-11, "{text}: {d}");
            let dt = out.metrics["max_rel_diff_transfer"].as_f64().unwrap();
            assert!(dt < 1e-11, "{text}: {dt}");
            assert_eq!(out.metrics["unresolved"], 0);
            assert!(out.timings["t_woodbury"].as_f64().unwrap() > 0.0);
        }
    }

    #[test]
    fn random_defects_follow_the_seed() {
        let s = Scene::from_value(&scene(
            "chain = { n = 100 }\nrandom_defects = { count = 4 }",
        ))
        .unwrap();
        let a = s.chain_with_random(5).unwrap();
        assert_eq!(a, s.chain_with_random(5).unwrap());
        assert_ne!(a, s.chain_with_random(6).unwrap());
        assert!(a.build().is_ok());
        for d in &a.defects {
            assert!((0.5..=5.0).contains(&d.value()));
        }
    }

    #[test]
    fn unresolvable_points_are_counted() {
        // X_n of a long damped chain underflows to zero in f64
        let out = Kind::Forward
            .run(
                &scene("chain = { n = 5000 }\nobserve = 5000\ns = { from = 1, to = 10, count = 4 }\ntiming = { min_seconds = 0.0 }"),
                1,
            )
            .unwrap();
        assert_eq!(out.metrics["unresolved"], 4);
        assert!(out.metrics["max_rel_diff"].is_null());
    }

    #[test]
    fn bad_scenes_name_fields() {
        for (text, field) in [
            (
                "chain = { n = 5 }\nrandom_defects = { count = 6 }",
                "random_defects.count",
            ),
            ("chain = { n = 5 }\nobserve = 6", "observe"),
            ("chain = { n = 5, d = -1.0 }", "chain.d"),
            ("chain = { n = 5 }\ns = { spacing = \"lin\" }", "s.spacing"),
            ("chain = { n = 5 }\ns = { from = 0.0 }", "s.from"),
            ("chain = { n = 5 }\ns = { count = 0 }", "s.count"),
            (
                "chain = { n = 5 }\nrandom_defects = { kind = \"mas\" }",
                "random_defects.kind",
            ),
            (
                "chain = { n = 5 }\ntiming = { min_secs = 1 }",
                "timing.min_secs",
            ),
            ("chain = { n = 5 }\ns = { sigma = -1.0 }", "s.sigma"),
            (
                "chain = { n = 5, defects = [ { kind = \"mass\", at = 9, m = 1.0 } ] }",
                "chain.defects[0].at",
            ),
        ] {
            match Kind::Forward.validate(&scene(text)) {
                Err(Error::InvalidParameter { field: f, .. }) => assert_eq!(f, field, "{text}"),
                other => panic!("{text}: {other:?}"),
            }
        }
    }
}
