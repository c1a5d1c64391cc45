//! Kind `suppress`: the active suppression schemes of section 3, verified by
//! time-domain simulation ([`crate::control::verify::verify`]).
//!
//! A uniform chain of `n + 1` masses is hit on mass 1 (the paper's impulse,
//! or a sampled disturbance); the exact controls of Theorem 3.1 (`cloak`: `f`
//! on mass `n`, `g` on mass `n - 1`) or Corollary 3.2 (`single`: `f1` on
//! mass `n`) are applied, optionally delayed and with a gain error, and the
//! chain is simulated with and without them. Metrics: how still mass `n + 1`
//! is kept and how visible the intervention is at mass 1 (both relative to
//! `max |y_1|`), and the simulator's agreement with the exact responses.
//! With `plots = true` each case also draws its controls and the
//! displacements of masses 1 and `n + 1` with and without control (the
//! paper's Figures 3 to 8).
//!
//! ```
//! use springmass::study::kinds::Kind;
//! let scene: toml::Value = toml::from_str("n = 4\nt_end = 20.0\ndt = 0.1").unwrap();
//! let out = Kind::Suppress.run(&scene, 0)?;
//! assert!(out.metrics["rel_x_end"].as_f64().unwrap() < 1e-8);
//! # Ok::<(), springmass::Error>(())
//! ```

use super::case::{num, CaseOutput, CasePlot, KindScene};
use crate::control::verify::{verify, Input, Perturbation, Run, Target, VerifyOptions};
use crate::control::{Scheme, Suppression};
use crate::error::{check_f64, Error, Result};
use crate::plot::{Line, LinePlot};
use crate::study::schema::FieldDoc;
use crate::time::simulate::Method;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// One paragraph for the schema page.
pub const SUMMARY: &str = "Applies the exact suppression controls (Theorem 3.1 `cloak`, Corollary 3.2 `single`) to a uniform chain of n + 1 masses hit on mass 1, simulates it with and without the controls, and records how still mass n + 1 stays and how visible the intervention is at mass 1.";

/// The scene of a `suppress` case.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// The paper's `n`: the chain has `n + 1` masses.
    pub n: usize,
    /// Spring constant (default 1).
    #[serde(default = "one")]
    pub k: f64,
    /// Damping (default 0.1).
    #[serde(default = "paper_d")]
    pub d: f64,
    /// Mass (default 1).
    #[serde(default = "one")]
    pub mass: f64,
    /// Impulse on mass 1 (default 1).
    #[serde(default = "one")]
    pub gamma: f64,
    /// `cloak` (default) or `single`.
    #[serde(default = "default_scheme")]
    pub scheme: String,
    /// What hits mass 1.
    #[serde(default)]
    pub input: InputSpec,
    /// Simulated horizon (default 100).
    #[serde(default = "default_t_end")]
    pub t_end: f64,
    /// Output step (default 0.05).
    #[serde(default = "default_dt")]
    pub dt: f64,
    /// Simulator: `auto` (default), `expm`, `rk`.
    #[serde(default = "default_method")]
    pub method: String,
    /// Errors of the applied controls.
    #[serde(default)]
    pub perturbation: PerturbationSpec,
    /// Draw this case's controls and displacements (default false).
    #[serde(default)]
    pub plots: bool,
}

/// The disturbance on mass 1.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InputSpec {
    /// `impulse` (default), `sine` or `noise`.
    #[serde(default = "default_input")]
    pub kind: String,
    /// Amplitude of `sine` and `noise` (default 1).
    #[serde(default = "one")]
    pub amplitude: f64,
    /// Angular frequency of `sine` (default 1).
    #[serde(default = "one")]
    pub omega: f64,
    /// Duration of `sine` and `noise` (default 10); zero afterwards.
    #[serde(default = "default_duration")]
    pub duration: f64,
}

impl Default for InputSpec {
    fn default() -> Self {
        InputSpec {
            kind: default_input(),
            amplitude: 1.0,
            omega: 1.0,
            duration: default_duration(),
        }
    }
}

/// Delay and gain error of the applied controls.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PerturbationSpec {
    /// Delay `tau >= 0` (default 0).
    #[serde(default)]
    pub delay: f64,
    /// Relative gain error, `|eps| <= 1` (default 0).
    #[serde(default)]
    pub gain_error: f64,
    /// `all` (default) or `first` (the control on mass n only).
    #[serde(default = "default_target")]
    pub target: String,
}

impl Default for PerturbationSpec {
    fn default() -> Self {
        PerturbationSpec {
            delay: 0.0,
            gain_error: 0.0,
            target: default_target(),
        }
    }
}

serde_defaults! {
    fn one() -> f64 = 1.0;
    fn paper_d() -> f64 = 0.1;
    fn default_scheme() -> String = "cloak".into();
    fn default_input() -> String = "impulse".into();
    fn default_duration() -> f64 = 10.0;
    fn default_t_end() -> f64 = 100.0;
    fn default_dt() -> f64 = 0.05;
    fn default_method() -> String = "auto".into();
    fn default_target() -> String = "all".into();
}

/// Largest number of output samples of one case.
pub const MAX_SAMPLES: f64 = 2.0e6;

/// Every scene field of kind `suppress`.
pub const FIELDS: &[FieldDoc] = &[
    FieldDoc::new("n", "integer >= 2", "required", "The paper's n: the chain has n + 1 masses; f acts on mass n, g on mass n - 1."),
    FieldDoc::new("k", "float > 0", "1", "Spring constant."),
    FieldDoc::new("d", "float >= 0", "0.1", "Damping on every mass."),
    FieldDoc::new("mass", "float > 0", "1", "Every mass."),
    FieldDoc::new("gamma", "float != 0", "1", "Impulse on mass 1 (impulse input)."),
    FieldDoc::new("scheme", "\"cloak\" | \"single\"", "\"cloak\"", "Theorem 3.1 (f and g: mass n + 1 still, mass 1 unaware) or Corollary 3.2 (f1 alone: masses n and n + 1 still)."),
    FieldDoc::new("input", "table", "{}", "What hits mass 1."),
    FieldDoc::new("input.kind", "\"impulse\" | \"sine\" | \"noise\"", "\"impulse\"", "The paper's impulse gamma delta(t), a sine amplitude sin(omega t), or Gaussian white noise of standard deviation amplitude drawn with the case's seed; sine and noise are sampled every dt, linear between samples, for `duration`."),
    FieldDoc::new("input.amplitude", "float", "1", "Amplitude of `sine` and `noise`."),
    FieldDoc::new("input.omega", "float", "1", "Angular frequency of `sine`."),
    FieldDoc::new("input.duration", "float > 0", "10", "How long `sine` and `noise` act (zero afterwards)."),
    FieldDoc::new("t_end", "float > 0", "100", "Simulated horizon."),
    FieldDoc::new("dt", "float in (0, t_end]", "0.05", "Output step (and sample step of sampled inputs); at most 2e6 steps."),
    FieldDoc::new("method", "\"auto\" | \"expm\" | \"rk\"", "\"auto\"", "Simulator: matrix exponential (auto up to 300 masses) or sparse Taylor/Runge-Kutta."),
    FieldDoc::new("perturbation", "table", "{}", "Errors of the applied controls: (1 + gain_error) f(t - delay)."),
    FieldDoc::new("perturbation.delay", "float >= 0", "0", "Delay of the applied controls."),
    FieldDoc::new("perturbation.gain_error", "float in [-1, 1]", "0", "Relative gain error of the applied controls."),
    FieldDoc::new("perturbation.target", "\"all\" | \"first\"", "\"all\"", "Which controls the errors affect: all, or only the one on mass n."),
    FieldDoc::new("plots", "bool", "false", "Draw this case's controls and displacements into `cases/<id>-*.svg` (listed in the report)."),
];

/// Every metric and timing of kind `suppress`.
pub const METRICS: &[(&str, &str)] = &[
    ("masses", "n + 1"),
    ("rel_x_end", "max |x_{n+1}| / max |y_1| with the controls (0: mass n + 1 perfectly still)"),
    ("rel_x1_minus_y1", "max |x_1 - y_1| / max |y_1| (0: the intervention is invisible at mass 1)"),
    ("rel_x_end_vs_uncontrolled", "max |x_{n+1}| / max |y_{n+1}| (residual vibration at the target)"),
    ("max_abs_y1", "max |y_1| without controls"),
    ("max_abs_y_end", "max |y_{n+1}| without controls"),
    ("sim_vs_exact_y1", "simulator check: max |y_1(sim) - y_1(exact)| / max |y_1|"),
    ("sim_vs_exact_x1", "simulator check with exact controls: max |x_1(sim) - x_1(exact)| / max |y_1| (empty with a perturbation)"),
    ("t_verify", "measured seconds of the two simulations and the controls"),
];

impl KindScene for Scene {
    const FIELDS: &'static [FieldDoc] = FIELDS;

    fn problems(&self) -> Vec<Error> {
        let checks: [&dyn Fn() -> Result<()>; 5] = [
            &|| self.suppression().map(|_| ()),
            &|| self.scheme().map(|_| ()),
            &|| self.method().map(|_| ()),
            &|| self.options().map(|_| ()),
            &|| self.check_input(),
        ];
        checks.iter().filter_map(|c| c().err()).collect()
    }
}

impl Scene {
    fn check_input(&self) -> Result<()> {
        let i = &self.input;
        match i.kind.as_str() {
            "impulse" => {}
            "sine" | "noise" => {
                check_f64("input.amplitude", i.amplitude, true, "finite")?;
                check_f64("input.omega", i.omega, true, "finite")?;
                check_f64(
                    "input.duration",
                    i.duration,
                    i.duration > 0.0,
                    "duration > 0 and finite",
                )?;
                if i.amplitude == 0.0 {
                    return Err(Error::invalid(
                        "input.amplitude",
                        0,
                        "non-zero (nothing to suppress)",
                    ));
                }
                if self.dt > 0.0 && i.duration / self.dt > MAX_SAMPLES {
                    return Err(Error::invalid(
                        "input.duration",
                        i.duration,
                        format!("at most {MAX_SAMPLES} samples of dt"),
                    ));
                }
            }
            other => {
                return Err(Error::invalid(
                    "input.kind",
                    other,
                    "\"impulse\", \"sine\" or \"noise\"",
                ))
            }
        }
        Ok(())
    }

    fn suppression(&self) -> Result<Suppression> {
        Suppression::new(self.n, self.k, self.d, self.mass, self.gamma)
    }

    fn scheme(&self) -> Result<Scheme> {
        match self.scheme.as_str() {
            "cloak" => Ok(Scheme::Cloak),
            "single" => Ok(Scheme::Single),
            other => Err(Error::invalid("scheme", other, "\"cloak\" or \"single\"")),
        }
    }

    fn method(&self) -> Result<Method> {
        match self.method.as_str() {
            "auto" => Ok(Method::Auto),
            "expm" => Ok(Method::Expm),
            "rk" => Ok(Method::Rk),
            other => Err(Error::invalid(
                "method",
                other,
                "\"auto\", \"expm\" or \"rk\" (a forced simulation)",
            )),
        }
    }

    fn options(&self) -> Result<VerifyOptions> {
        if self.t_end.is_finite() && self.dt.is_finite() && self.t_end / self.dt > MAX_SAMPLES {
            return Err(Error::invalid(
                "dt",
                self.dt,
                format!("dt >= t_end / {MAX_SAMPLES}"),
            ));
        }
        let p = &self.perturbation;
        let target = match p.target.as_str() {
            "all" => Target::All,
            "first" => Target::First,
            other => {
                return Err(Error::invalid(
                    "perturbation.target",
                    other,
                    "\"all\" or \"first\"",
                ))
            }
        };
        let pert = Perturbation::new(p.delay, p.gain_error, target)
            .map_err(|e| super::prefix_field(e, "perturbation."))?;
        Ok(VerifyOptions::new(self.t_end, self.dt)?
            .with_method(self.method()?)
            .with_perturbation(pert))
    }

    fn input(&self, seed: u64) -> Input {
        let i = &self.input;
        let h = self.dt;
        let count = (i.duration / h).floor() as usize + 1;
        match i.kind.as_str() {
            "sine" => Input::Sampled {
                h,
                u: (0..count)
                    .map(|j| i.amplitude * (i.omega * j as f64 * h).sin())
                    .collect(),
            },
            "noise" => {
                let mut rng = ChaCha8Rng::seed_from_u64(seed);
                Input::Sampled {
                    h,
                    u: (0..count)
                        .map(|_| {
                            let z: f64 = StandardNormal.sample(&mut rng);
                            i.amplitude * z
                        })
                        .collect(),
                }
            }
            _ => Input::Impulse,
        }
    }
}

/// Run one `suppress` case.
///
/// # Errors
/// An invalid scene; simulator failures.
pub fn run(scene: &Scene, seed: u64) -> Result<CaseOutput> {
    scene.check()?;
    let sup = scene.suppression()?;
    let start = Instant::now();
    let run = verify(&sup, scene.scheme()?, &scene.input(seed), &scene.options()?)?;
    let t_verify = start.elapsed().as_secs_f64();
    let m = &run.metrics;
    let mut out = CaseOutput::default();
    out.metrics.insert("masses".into(), (scene.n + 1).into());
    out.metric("rel_x_end", m.rel_x_end);
    out.metric("rel_x1_minus_y1", m.rel_x1_minus_y1);
    out.metric("rel_x_end_vs_uncontrolled", m.rel_x_end_vs_uncontrolled);
    out.metric("max_abs_y1", m.max_abs_y1);
    out.metric("max_abs_y_end", m.max_abs_y_end);
    out.metric("sim_vs_exact_y1", m.sim_vs_exact_y1);
    out.metrics.insert(
        "sim_vs_exact_x1".into(),
        m.sim_vs_exact_x1.map_or(serde_json::Value::Null, num),
    );
    out.timing("t_verify", t_verify);
    if scene.plots {
        out.plots = plots(scene, &run)?;
    }
    Ok(out)
}

fn series(t: &[f64], v: &[f64]) -> Vec<(f64, f64)> {
    t.iter().copied().zip(v.iter().copied()).collect()
}

/// The case's pictures: controls, x_1 and x_{n+1} with and without control.
fn plots(scene: &Scene, run: &Run) -> Result<Vec<CasePlot>> {
    let n = scene.n;
    let mut controls = LinePlot::new(
        format!("controls ({}, n + 1 = {} masses)", scene.scheme, n + 1),
        "t",
        "force",
    );
    for c in &run.controls {
        controls = controls.line(Line::new(
            format!("{} on mass {}", c.signal.name(), c.at),
            series(&run.t, &c.values),
        ));
    }
    let x1 = LinePlot::new(
        format!("x_1 with and without the controls ({})", scene.scheme),
        "t",
        "x_1",
    )
    .line(Line::new("x_1 without controls", series(&run.t, &run.y1)))
    .line(Line::new("x_1 with controls", series(&run.t, &run.x1)).dashed());
    let x_end = LinePlot::new(
        format!(
            "x_{} with and without the controls ({})",
            n + 1,
            scene.scheme
        ),
        "t",
        format!("x_{}", n + 1),
    )
    .line(Line::new("without controls", series(&run.t, &run.y_end)))
    .line(Line::new("with controls", series(&run.t, &run.x_end)).dashed());
    Ok(vec![
        CasePlot::of_lines("controls", &controls)?,
        CasePlot::of_lines("x1", &x1)?,
        CasePlot::of_lines("x_end", &x_end)?,
    ])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::study::kinds::Kind;

    fn scene(text: &str) -> toml::Value {
        toml::from_str(text).unwrap()
    }

    #[test]
    fn cloak_and_single_suppress() {
        let c = Kind::Suppress
            .run(&scene("n = 4\nt_end = 30.0\ndt = 0.1\nplots = true"), 0)
            .unwrap();
        assert!(c.metrics["rel_x_end"].as_f64().unwrap() < 1e-8);
        assert!(c.metrics["rel_x1_minus_y1"].as_f64().unwrap() < 1e-8);
        assert_eq!(c.plots.len(), 3);
        let s = Kind::Suppress
            .run(
                &scene("n = 4\nscheme = \"single\"\nt_end = 30.0\ndt = 0.1"),
                0,
            )
            .unwrap();
        assert!(s.metrics["rel_x_end"].as_f64().unwrap() < 1e-8);
        // f1 alone is visible at mass 1
        assert!(s.metrics["rel_x1_minus_y1"].as_f64().unwrap() > 1e-3);
        assert!(s.plots.is_empty());
    }

    #[test]
    fn noise_input_follows_the_seed() {
        let v =
            scene("n = 3\ninput = { kind = \"noise\", duration = 2.0 }\nt_end = 10.0\ndt = 0.1");
        let a = Kind::Suppress.run(&v, 1).unwrap();
        let b = Kind::Suppress.run(&v, 1).unwrap();
        let c = Kind::Suppress.run(&v, 2).unwrap();
        assert_eq!(a.metrics, b.metrics);
        assert_ne!(a.metrics["max_abs_y1"], c.metrics["max_abs_y1"]);
        assert!(a.metrics["rel_x_end"].as_f64().unwrap() < 1e-6);
    }

    #[test]
    fn bad_scenes_name_fields() {
        for (text, field) in [
            ("n = 1", "n"),
            ("n = 4\nscheme = \"cloack\"", "scheme"),
            ("n = 4\nmethod = \"modal\"", "method"),
            ("n = 4\ndt = 0.0", "dt"),
            (
                "n = 4\nperturbation = { gain_error = 2.0 }",
                "perturbation.gain_error",
            ),
            (
                "n = 4\nperturbation = { target = \"last\" }",
                "perturbation.target",
            ),
            ("n = 4\ninput = { kind = \"step\" }", "input.kind"),
            (
                "n = 4\ninput = { kind = \"sine\", duration = 0.0 }",
                "input.duration",
            ),
            (
                "n = 4\ninput = { kind = \"sine\", amplitud = 1.0 }",
                "input.amplitud",
            ),
            ("n = 4\nd = -1.0", "d"),
        ] {
            match Kind::Suppress.validate(&scene(text)) {
                Err(Error::InvalidParameter { field: f, .. }) => assert_eq!(f, field, "{text}"),
                other => panic!("{text}: {other:?}"),
            }
        }
    }
}
