//! `springmass._core`: the native part of the Python package `springmass`.
//!
//! Thin bindings of the Rust library: arrays arrive as `float64` (or
//! `complex128`) numpy arrays already checked for shape by the Python layer
//! (`springmass/__init__.py`), options arrive in the text forms of the
//! command line, every check and every number comes from the library, and
//! every library error becomes a Python exception with the same message
//! ([`errors`]). Long computations (fits, simulations, transforms, locators)
//! run with the GIL released.

mod errors;

use errors::{IntoPy, NumericalError, UnresolvableError};
use num_complex::Complex64;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArrayDyn};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use springmass::chain::{Boundary, ChainSpec};
use springmass::control::exact::Modes;
use springmass::control::{Signal, Suppression};
use springmass::detect::data::observations::{Observations, Series};
use springmass::detect::fit::options::FitSpec;
use springmass::detect::locate::{self as locator, default_grid, LaplaceData, SChoice};
use springmass::forward::{Forward, Observable};
use springmass::noise::{add_noise, NoiseLevel};
use springmass::time::series::{SeriesTransform, Tail, TransformOptions};
use springmass::time::simulate::{simulate_forced, Forcing, Method, SimOptions};
use springmass::{Chain, Defect, Error, Result};

/// A chain as the Python layer describes it (a dict with these keys).
#[derive(FromPyObject)]
#[pyo3(from_item_all)]
struct ChainArgs {
    n: usize,
    k: f64,
    /// `None`: 0.1 for the grounded model, 0 with another
    d: Option<f64>,
    gamma: f64,
    mass: f64,
    defects: Vec<String>,
    left: String,
    right: String,
    /// `MODEL[:P1[:P2]]` ([`springmass::chain::Damping::parse_complete`])
    damping: Option<String>,
}

impl ChainArgs {
    /// Validate and build (defects in the form `kind:at:value`).
    fn build(&self) -> Result<Chain> {
        let end = |field: &str, text: &str| {
            text.parse::<Boundary>()
                .map_err(|_| Error::invalid(field, text, "fixed or free"))
        };
        let damping = match &self.damping {
            Some(t) => springmass::chain::Damping::parse_complete(t)?,
            None => Default::default(),
        };
        let d = self
            .d
            .unwrap_or(if damping.is_grounded() { 0.1 } else { 0.0 });
        ChainSpec {
            n: self.n,
            k: self.k,
            d,
            gamma: self.gamma,
            mass: self.mass,
            defects: self
                .defects
                .iter()
                .map(|t| Defect::parse(t))
                .collect::<Result<_>>()?,
            left: end("left", &self.left)?,
            right: end("right", &self.right)?,
            damping,
            baseline: None,
        }
        .build()
    }
}

/// A baseline as Python gives it: a table's path, or a dict of lists
/// `{"mass": [...], "spring": [...], "damper": [...] or None}` (`spring`
/// has `n + 1` values, 0 for a free end's wall spring).
#[derive(FromPyObject)]
enum BaselineArg {
    Path(std::path::PathBuf),
    #[pyo3(from_item_all)]
    Table {
        mass: Vec<f64>,
        spring: Vec<f64>,
        #[pyo3(default)]
        damper: Option<Vec<f64>>,
    },
}

impl BaselineArg {
    fn spec(self) -> Result<springmass::chain::BaselineSpec> {
        use springmass::chain::{Baseline, BaselineSpec};
        Ok(match self {
            BaselineArg::Path(p) => BaselineSpec::Path(p.display().to_string()),
            BaselineArg::Table {
                mass,
                spring,
                damper,
            } => BaselineSpec::Table(Baseline::new(mass, spring, damper, "")?),
        })
    }
}

/// The values of a read-only 1-D array (any strides).
fn values(a: &PyReadonlyArray1<'_, f64>) -> Vec<f64> {
    a.as_array().iter().copied().collect()
}

/// `job` without the GIL on a helper thread, interruptible: the calling
/// thread waits for it without the GIL, and every 50 ms takes the GIL and runs Python's signal handlers
/// (`Python::check_signals`); when one raises (Ctrl-C: KeyboardInterrupt),
/// the library is asked to stop ([`springmass::cancel`]), the job returns
/// promptly and the handler's exception is raised.
fn interruptible<T: Send>(py: Python<'_>, job: impl FnOnce() -> Result<T> + Send) -> PyResult<T> {
    use std::sync::mpsc::RecvTimeoutError;
    let (out, raised) = std::thread::scope(|scope| {
        // the worker says when it is done: the wait ends then, not at the
        // next 50 ms tick (a short fit would otherwise take 50 ms at least)
        let (done_tx, done_rx) = std::sync::mpsc::channel::<()>();
        let worker = scope.spawn(move || {
            let out = job();
            let _ = done_tx.send(());
            out
        });
        let mut raised = None;
        let tick = std::time::Duration::from_millis(50);
        let mut rx = done_rx;
        loop {
            // (the receiver is not Sync: it goes into the GIL-free closure
            // and comes back)
            let (wait, back) = py.detach(move || (rx.recv_timeout(tick), rx));
            rx = back;
            // a panic drops the sender: Disconnected ends the wait too
            if !matches!(wait, Err(RecvTimeoutError::Timeout)) {
                break;
            }
            if raised.is_none() {
                if let Err(e) = py.check_signals() {
                    springmass::cancel::request();
                    raised = Some(e);
                }
            }
        }
        let out = worker
            .join()
            .unwrap_or_else(|p| std::panic::resume_unwind(p));
        (out, raised)
    });
    if let Some(e) = raised {
        springmass::cancel::reset();
        return Err(e);
    }
    out.py_err()
}

/// The record `(t, x)` as observations: the sensor and the measured force
/// of `spec`, the noise level when known; with several sensors
/// (`spec.sensors`) `x` is the first's record and `more` the others', in
/// order.
fn series_obs(
    spec: &FitSpec,
    t: Vec<f64>,
    x: Vec<f64>,
    more: Vec<Vec<f64>>,
    force: Option<Vec<f64>>,
    sigma: Option<f64>,
) -> Result<Observations> {
    if spec.sensors.is_empty() && more.is_empty() {
        let measurement = spec.measurement_at(&t, force)?;
        return Ok(Observations::Series(
            Series::on_axis(t, x, sigma)?.with_measurement(measurement)?,
        ));
    }
    let measurements = spec.measurements_at(&t, force)?;
    if measurements.len() != more.len() + 1 {
        return Err(Error::invalid(
            "observe",
            format!(
                "{} sensors for {} columns of x",
                measurements.len(),
                more.len() + 1
            ),
            "one observed mass per column of x",
        ));
    }
    let mut all = std::iter::once(x)
        .chain(more)
        .zip(measurements)
        .map(|(x, m)| Series::on_axis(t.clone(), x, sigma)?.with_measurement(m));
    let first = all.next().expect("at least one sensor")?;
    Ok(Observations::Series(
        first.with_sensors(all.collect::<Result<_>>()?)?,
    ))
}

/// One further record of the same chain: times, values, measured force.
type Record = (Vec<f64>, Vec<f64>, Option<Vec<f64>>);

/// `obs` joined by further records of the same chain (each with its own
/// times and measured force, or the impulse), as `--data` repeated.
fn with_records(
    spec: &FitSpec,
    obs: Observations,
    records: Vec<Record>,
    sigma: Option<f64>,
) -> Result<Observations> {
    if records.is_empty() {
        return Ok(obs);
    }
    let Observations::Series(first) = obs else {
        return Ok(obs);
    };
    let rest = records
        .into_iter()
        .map(|(t, x, f)| {
            let m = spec.measurement_at(&t, f)?;
            Series::on_axis(t, x, sigma)?.with_measurement(m)
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(Observations::Series(first.with_records(rest)?))
}

/// The data-first fit (`springmass::detect::fit::fit`) of a series; the
/// options are those of `springmass fit --data` ([`FitSpec`]). Returns the
/// report as the CLI's JSON (without the predicted series) and the predicted
/// series as arrays.
#[pyfunction]
#[pyo3(signature = (t, x, *, n, d=None, gamma=None, fit=None, known=Vec::new(), defects=None,
    kinds=None, slot_kinds=Vec::new(), noise=None, misfit=None, method=None, criterion=None,
    seed=None, max_evals=None, k=None, mass=None, left=None, right=None, observe=None,
    observe_kind=None, force=None, trigger=None, noise_model=None, nuisance=None, damping=None, force_window=None,
    baseline=None, level=None, prior_k=None, prior_range=None, uncertainty=None, exhaustive=None, effort=None,
    sensors=Vec::new(), sensor_kinds=Vec::new(), more=Vec::new(), record_t=Vec::new(),
    record_x=Vec::new(), record_force=Vec::new()))]
#[allow(clippy::too_many_arguments)]
fn fit<'py>(
    py: Python<'py>,
    t: PyReadonlyArray1<'py, f64>,
    x: PyReadonlyArray1<'py, f64>,
    n: usize,
    d: Option<f64>,
    gamma: Option<f64>,
    fit: Option<String>,
    known: Vec<String>,
    defects: Option<String>,
    kinds: Option<String>,
    slot_kinds: Vec<String>,
    noise: Option<String>,
    misfit: Option<String>,
    method: Option<String>,
    criterion: Option<String>,
    seed: Option<u64>,
    max_evals: Option<usize>,
    k: Option<f64>,
    mass: Option<f64>,
    left: Option<String>,
    right: Option<String>,
    observe: Option<usize>,
    observe_kind: Option<String>,
    force: Option<PyReadonlyArray1<'py, f64>>,
    trigger: Option<String>,
    noise_model: Option<String>,
    nuisance: Option<String>,
    damping: Option<String>,
    force_window: Option<String>,
    baseline: Option<BaselineArg>,
    level: Option<f64>,
    prior_k: Option<String>,
    prior_range: Option<String>,
    uncertainty: Option<bool>,
    exhaustive: Option<bool>,
    effort: Option<String>,
    sensors: Vec<usize>,
    sensor_kinds: Vec<String>,
    more: Vec<PyReadonlyArray1<'py, f64>>,
    record_t: Vec<PyReadonlyArray1<'py, f64>>,
    record_x: Vec<PyReadonlyArray1<'py, f64>>,
    record_force: Vec<Option<PyReadonlyArray1<'py, f64>>>,
) -> PyResult<Bound<'py, PyDict>> {
    let baseline = baseline.map(BaselineArg::spec).transpose().py_err()?;
    let spec = FitSpec {
        sensors,
        sensor_kinds,
        level,
        prior_k,
        prior_range,
        uncertainty,
        exhaustive,
        effort,
        d,
        k,
        mass,
        gamma,
        left,
        right,
        observe,
        observe_kind,
        fit,
        known,
        defects,
        kinds,
        slot_kinds,
        noise,
        misfit,
        method,
        criterion,
        seed,
        max_evals,
        trigger,
        noise_model,
        nuisance,
        damping,
        force_window,
        baseline,
        ..FitSpec::new(n)
    };
    let (t, x) = (values(&t), values(&x));
    let more: Vec<Vec<f64>> = more.iter().map(values).collect();
    let force = force.as_ref().map(values);
    let records: Vec<Record> = record_t
        .iter()
        .zip(&record_x)
        .zip(record_force.iter().chain(std::iter::repeat(&None)))
        .map(|((t, x), f)| (values(t), values(x), f.as_ref().map(values)))
        .collect();
    let report = interruptible(py, move || -> Result<_> {
        let (model, opts) = spec.build()?;
        let obs = series_obs(&spec, t, x, more, force, opts.noise.known())?;
        let obs = with_records(&spec, obs, records, opts.noise.known())?;
        opts.validate(&obs, &model)?;
        springmass::detect::fit::fit(&obs, &model, &opts)
    })?;
    let mut json = serde_json::to_value(&report)
        .map_err(|e| NumericalError::new_err(format!("the fit report cannot be written: {e}")))?;
    if let Some(o) = json.as_object_mut() {
        o.remove("predicted");
    }
    let out = PyDict::new(py);
    out.set_item("report", json.to_string())?;
    out.set_item("summary", report.summary())?;
    if let Some(p) = report.predicted {
        out.set_item("t", p.t.into_pyarray(py))?;
        out.set_item("observed", p.observed.into_pyarray(py))?;
        out.set_item("model", p.model.into_pyarray(py))?;
        out.set_item("residual", p.residual.into_pyarray(py))?;
    }
    Ok(out)
}

/// `(t_end, dt)` of a uniform grid `0, dt, 2 dt, ...` given as its times.
fn grid(t: &[f64]) -> Result<(f64, f64)> {
    let allowed =
        "uniformly spaced times 0, dt, 2 dt, ... (at least 2; the simulator's output grid)";
    if t.len() < 2 {
        return Err(Error::invalid("t", format!("{} times", t.len()), allowed));
    }
    springmass::series::check_times(t)?;
    if t[0] != 0.0 {
        return Err(Error::invalid("t[0]", t[0], allowed));
    }
    let dt = t[1];
    for (i, &ti) in t.iter().enumerate() {
        let expect = i as f64 * dt;
        if (ti - expect).abs() > 1e-9 * expect.max(dt) {
            return Err(Error::invalid(format!("t[{i}]"), ti, allowed));
        }
    }
    Ok((t[t.len() - 1], dt))
}

/// Refuse a simulation whose working memory would exceed the library's
/// budget ([`springmass::io::check_alloc`], `SPRINGMASS_MEMORY_BUDGET`):
/// about 16 state vectors of `2n` values, the dense `(2n)^2` matrices
/// (about 8) when the method may be `expm`, and three copies of the
/// output (trajectory, noisy copy, numpy array).
fn check_simulation_memory(
    n: usize,
    samples: usize,
    observed: usize,
    method: Method,
) -> Result<()> {
    let two_n = 2.0 * n as f64;
    let dense = match method {
        Method::Rk => 0.0,
        Method::Auto if n > springmass::time::simulate::MAX_N_EXPM => 0.0,
        _ => 8.0 * 8.0 * two_n * two_n,
    };
    let bytes = 8.0 * 16.0 * two_n + dense + 3.0 * 8.0 * samples as f64 * observed as f64;
    springmass::io::check_alloc(
        &format!("simulate (n = {n}, {samples} samples of {observed} masses)"),
        bytes,
    )
}

/// A noise level: a bare number is an absolute standard deviation, else
/// `abs:SIGMA`, `snr:DB` or `rel:R` (as `springmass simulate --noise`).
fn noise_level(text: &str) -> Result<NoiseLevel> {
    let level = match text.trim().parse::<f64>() {
        Ok(v) => NoiseLevel::Absolute(v),
        Err(_) => NoiseLevel::parse(text)?,
    };
    level.sigma(&[])?; // validates the level (sign, finiteness)
    Ok(level)
}

/// Simulate the observed masses of a chain on a uniform grid; row `c` is
/// mass `observe[c]`, its noise drawn with seed `seed + c` (as the CLI).
#[pyfunction]
#[pyo3(signature = (chain, t, *, observe, observe_kind, noise, seed, method))]
#[allow(clippy::too_many_arguments)]
fn simulate<'py>(
    py: Python<'py>,
    chain: ChainArgs,
    t: PyReadonlyArray1<'py, f64>,
    observe: Vec<usize>,
    observe_kind: String,
    noise: Option<String>,
    seed: u64,
    method: String,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let t = values(&t);
    let rows = py
        .detach(move || -> Result<Vec<Vec<f64>>> {
            let chain = chain.build()?;
            let kind: Observable = observe_kind.parse()?;
            let method: Method = method.parse()?;
            let level = noise.as_deref().map(noise_level).transpose()?;
            let (t_end, dt) = grid(&t)?;
            let opts = SimOptions::new(t_end, dt)
                .with_observe(observe)
                .with_method(method)
                .with_observe_kind(kind);
            let samples = opts.samples(&chain)?;
            if samples != t.len() {
                return Err(Error::invalid(
                    "t",
                    format!("{} times", t.len()),
                    format!("the {samples} times 0, dt, ..., t_end of the grid"),
                ));
            }
            check_simulation_memory(chain.n(), samples, opts.observe.len(), method)?;
            let traj = simulate_forced(&chain, &opts, &Forcing::new())?;
            match level {
                None => Ok(traj.x),
                Some(l) => traj
                    .x
                    .iter()
                    .enumerate()
                    .map(|(c, x)| add_noise(x, l, seed.wrapping_add(c as u64)).map(|r| r.0))
                    .collect(),
            }
        })
        .py_err()?;
    PyArray2::from_vec2(py, &rows)
        .map_err(|e| NumericalError::new_err(format!("simulated rows of unequal length: {e}")))
}

/// The transform of the observed quantity at real `s` (any shape).
#[pyfunction]
#[pyo3(signature = (s, chain, *, observe, observe_kind))]
fn response_real<'py>(
    py: Python<'py>,
    s: PyReadonlyArrayDyn<'py, f64>,
    chain: ChainArgs,
    observe: usize,
    observe_kind: String,
) -> PyResult<Bound<'py, PyAny>> {
    observe_at(py, s, chain, observe, observe_kind)
}

/// The transform of the observed quantity at complex `s` (any shape).
#[pyfunction]
#[pyo3(signature = (s, chain, *, observe, observe_kind))]
fn response_complex<'py>(
    py: Python<'py>,
    s: PyReadonlyArrayDyn<'py, Complex64>,
    chain: ChainArgs,
    observe: usize,
    observe_kind: String,
) -> PyResult<Bound<'py, PyAny>> {
    observe_at(py, s, chain, observe, observe_kind)
}

/// The observed quantity's transform at every `s` of an array (real or
/// complex), with the GIL released.
fn observe_at<'py, T>(
    py: Python<'py>,
    s: PyReadonlyArrayDyn<'py, T>,
    chain: ChainArgs,
    observe: usize,
    observe_kind: String,
) -> PyResult<Bound<'py, PyAny>>
where
    T: springmass::scalar::Scalar + numpy::Element + Copy + Send + Sync,
{
    let arr = s.as_array().to_owned();
    let out = py
        .detach(move || -> Result<_> {
            let fwd = Forward::new(&chain.build()?);
            let kind: Observable = observe_kind.parse()?;
            let mut out = arr.clone();
            for (o, &z) in out.iter_mut().zip(arr.iter()) {
                *o = fwd.observe(z, observe, kind)?;
            }
            Ok(out)
        })
        .py_err()?;
    Ok(out.into_pyarray(py).into_any())
}

/// The suppression controls `f`, `g` (Theorem 3.1) and `f1` (Corollary 3.2)
/// at the times `t`, exact (sums of damped modes).
#[pyfunction]
#[pyo3(signature = (n, t, *, k, d, mass, gamma))]
fn controls<'py>(
    py: Python<'py>,
    n: usize,
    t: PyReadonlyArray1<'py, f64>,
    k: f64,
    d: f64,
    mass: f64,
    gamma: f64,
) -> PyResult<Bound<'py, PyDict>> {
    let t = values(&t);
    let cols = py
        .detach(move || -> Result<Vec<(&'static str, Vec<f64>)>> {
            for (i, &ti) in t.iter().enumerate() {
                springmass::error::check_f64(&format!("t[{i}]"), ti, true, "finite")?;
            }
            let sup = Suppression::new(n, k, d, mass, gamma)?;
            // three signals of about n modes (24 bytes each) and their values
            springmass::io::check_alloc(
                &format!("controls (n = {n}, {} times)", t.len()),
                3.0 * (24.0 * (n as f64 + 2.0) + 8.0 * t.len() as f64),
            )?;
            Ok([Signal::F, Signal::G, Signal::F1]
                .iter()
                .map(|&sig| (sig.name(), Modes::new(&sup, sig).eval_many(&t)))
                .collect())
        })
        .py_err()?;
    let out = PyDict::new(py);
    for (name, v) in cols {
        out.set_item(name, v.into_pyarray(py))?;
    }
    Ok(out)
}

/// The transform options from their Python form.
fn transform_options(
    degree: usize,
    noise_sigma: Option<f64>,
    tail: &str,
) -> Result<TransformOptions> {
    let tail = match tail.trim() {
        "envelope" => Tail::Envelope,
        "modes" => Tail::Modes,
        "zero" => Tail::Zero,
        _ => return Err(Error::invalid("tail", tail, "envelope, modes or zero")),
    };
    Ok(TransformOptions {
        degree,
        noise_sigma,
        tail,
    })
}

/// The Laplace transform of a sampled series at complex `s` with its error
/// budget: `(value, err, err_disc, err_trunc, err_round, noise_std)`.
#[pyfunction]
#[pyo3(signature = (t, x, s, *, degree, noise_sigma, tail))]
#[allow(clippy::type_complexity)]
fn laplace<'py>(
    py: Python<'py>,
    t: PyReadonlyArray1<'py, f64>,
    x: PyReadonlyArray1<'py, f64>,
    s: PyReadonlyArray1<'py, Complex64>,
    degree: usize,
    noise_sigma: Option<f64>,
    tail: String,
) -> PyResult<Bound<'py, PyDict>> {
    let (t, x) = (values(&t), values(&x));
    let s: Vec<Complex64> = s.as_array().iter().copied().collect();
    let rows = py
        .detach(move || -> Result<_> {
            let opts = transform_options(degree, noise_sigma, &tail)?;
            let tr = SeriesTransform::new(&t, &x, &opts)?;
            let rows = tr.eval_many(&s)?;
            // as `springmass laplace`: a value or error beyond f64 is refused
            for v in &rows {
                if !v.is_finite() {
                    return Err(Error::Unresolvable {
                        reason: format!(
                            "X({}{:+}i) or its error estimate is not representable in f64 (got {} {:+}i, err {})",
                            v.s.re, v.s.im, v.value.re, v.value.im, v.err
                        ),
                    });
                }
            }
            Ok(rows)
        })
        .py_err()?;
    let out = PyDict::new(py);
    let col = |f: &dyn Fn(&springmass::time::series::LaplaceValue) -> f64| {
        rows.iter().map(f).collect::<Vec<f64>>()
    };
    out.set_item(
        "value",
        rows.iter()
            .map(|v| v.value)
            .collect::<Vec<Complex64>>()
            .into_pyarray(py),
    )?;
    out.set_item("err", col(&|v| v.err).into_pyarray(py))?;
    out.set_item("err_disc", col(&|v| v.err_disc).into_pyarray(py))?;
    out.set_item("err_trunc", col(&|v| v.err_trunc).into_pyarray(py))?;
    out.set_item("err_round", col(&|v| v.err_round).into_pyarray(py))?;
    if noise_sigma.is_some() {
        out.set_item(
            "noise_std",
            col(&|v| v.noise_var.map_or(f64::NAN, f64::sqrt)).into_pyarray(py),
        )?;
    }
    Ok(out)
}

/// Where the locator's data come from.
enum LocateData {
    /// A sampled series, transformed at the grid.
    Series { t: Vec<f64>, x: Vec<f64> },
    /// `X_1(s)` at the grid with absolute errors.
    Laplace { values: Vec<f64>, err: Vec<f64> },
}

/// One mass defect located by the explicit relations of section 4.1 (f64).
#[pyfunction]
#[pyo3(signature = (chain, *, grid, t=None, x=None, values=None, err=None, method=None, m=None,
    at=None, noise_sigma=None))]
#[allow(clippy::too_many_arguments)]
fn locate<'py>(
    py: Python<'py>,
    chain: ChainArgs,
    grid: Option<PyReadonlyArray1<'py, f64>>,
    t: Option<PyReadonlyArray1<'py, f64>>,
    x: Option<PyReadonlyArray1<'py, f64>>,
    values: Option<PyReadonlyArray1<'py, f64>>,
    err: Option<PyReadonlyArray1<'py, f64>>,
    method: Option<String>,
    m: Option<f64>,
    at: Option<f64>,
    noise_sigma: Option<f64>,
) -> PyResult<Bound<'py, PyDict>> {
    let s_grid = grid.as_ref().map(self::values);
    let data = match (t, x, values) {
        (Some(t), Some(x), None) => LocateData::Series {
            t: self::values(&t),
            x: self::values(&x),
        },
        (None, None, Some(v)) => {
            if let Some(sigma) = noise_sigma {
                // the Laplace values carry their own errors (`err`): a noise
                // level given beside them would be ignored without a word
                return Err(errors::to_py(Error::invalid(
                    "noise_sigma",
                    sigma,
                    "None with Laplace values (give their errors as err); a noise level applies to a series (t, x)",
                )));
            }
            let v = self::values(&v);
            let e = match &err {
                Some(e) => self::values(e),
                None => vec![0.0; v.len()],
            };
            LocateData::Laplace { values: v, err: e }
        }
        _ => {
            return Err(errors::to_py(Error::invalid(
                "data",
                "(t, x) and values both or neither given",
                "a series (t and x) or Laplace values (s and values), not both",
            )))
        }
    };
    let loc = py
        .detach(move || -> Result<_> {
            let chain = chain.build()?;
            chain.require_fixed_ends("the explicit locators of section 4.1")?;
            let name =
                method
                    .as_deref()
                    .unwrap_or(if m.is_some() { "exact" } else { "unknown-mass" });
            let method = locator::Method::from_name(name, || {
                m.ok_or_else(|| {
                    Error::invalid("m", "None", format!("the defect mass for method {name}"))
                })
            })?;
            let data: LaplaceData<f64> = match data {
                LocateData::Series { t, x } => {
                    let tr = SeriesTransform::new(
                        &t,
                        &x,
                        &TransformOptions {
                            noise_sigma,
                            ..TransformOptions::default()
                        },
                    )?;
                    let s = s_grid.unwrap_or_else(default_grid);
                    LaplaceData::from_transform("series (Laplace-transformed)", &tr, &s)?
                }
                LocateData::Laplace { values, err } => {
                    let s = s_grid.ok_or_else(|| {
                        Error::invalid("s", "None", "the nodes of the Laplace values")
                    })?;
                    LaplaceData::from_f64("Laplace values", &s, &values, &err)?
                }
            };
            let choice = at.map_or(SChoice::Auto, SChoice::At);
            locator::locate(&locator::Model::from_chain(&chain), &data, method, choice)
        })
        .py_err()?;
    let out = PyDict::new(py);
    out.set_item("position", loc.position)?;
    out.set_item("j", loc.j)?;
    out.set_item("sigma", loc.sigma)?;
    out.set_item("model_error", loc.bias)?;
    out.set_item("s", loc.s)?;
    out.set_item("used_s", PyArray1::from_vec(py, loc.used))?;
    out.set_item("mass", loc.mass)?;
    out.set_item("raw_j", loc.raw_j)?;
    out.set_item("method", loc.method.name())?;
    Ok(out)
}

/// A CSV time series (`t` and value columns; units, a pandas index and `#`
/// comments accepted): `{"t": ndarray, "columns": {name: ndarray}}`.
#[pyfunction]
fn read_csv<'py>(py: Python<'py>, path: std::path::PathBuf) -> PyResult<Bound<'py, PyDict>> {
    let ts = py
        .detach(move || springmass::series::TimeSeries::read_csv(&path))
        .py_err()?;
    let columns = PyDict::new(py);
    for (i, name) in ts.names().iter().enumerate() {
        let col = ts.column_at(i).unwrap_or_default();
        columns.set_item(name, PyArray1::from_slice(py, col))?;
    }
    let out = PyDict::new(py);
    out.set_item("t", PyArray1::from_slice(py, ts.t()))?;
    out.set_item("columns", columns)?;
    Ok(out)
}

/// A reference scene of the paper (`P1`..`P4`, `S1`..`S4`) as the chain's
/// parameters and defects (`kind:at:value`).
#[pyfunction]
fn scene<'py>(py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyDict>> {
    let c = springmass::scenes::by_name(name).py_err()?;
    let out = PyDict::new(py);
    out.set_item("n", c.n())?;
    out.set_item("k", c.k())?;
    out.set_item("d", c.d())?;
    out.set_item("gamma", c.gamma())?;
    out.set_item("mass", c.mass())?;
    let defects: Vec<(&str, usize, f64)> = c
        .defects()
        .iter()
        .map(|d| (d.kind(), d.at(), d.value()))
        .collect();
    out.set_item("defects", defects)?;
    Ok(out)
}

/// The whole-profile inversion (`springmass::detect::fit::profile`) of a
/// series: every mass, spring or both free; the model options are those of
/// `springmass fit --data ... --profile MODE` ([`FitSpec`]). Returns the
/// report as the CLI's JSON.
#[pyfunction]
#[pyo3(signature = (t, x, *, n, profile, d=None, gamma=None, fit=None, noise=None, k=None,
    mass=None, left=None, right=None, observe=None, observe_kind=None, force=None,
    change=None, penalty=None))]
#[allow(clippy::too_many_arguments)]
fn fit_profile<'py>(
    py: Python<'py>,
    t: PyReadonlyArray1<'py, f64>,
    x: PyReadonlyArray1<'py, f64>,
    n: usize,
    profile: String,
    d: Option<f64>,
    gamma: Option<f64>,
    fit: Option<String>,
    noise: Option<String>,
    k: Option<f64>,
    mass: Option<f64>,
    left: Option<String>,
    right: Option<String>,
    observe: Option<usize>,
    observe_kind: Option<String>,
    force: Option<PyReadonlyArray1<'py, f64>>,
    change: Option<f64>,
    penalty: Option<f64>,
) -> PyResult<Bound<'py, PyDict>> {
    use springmass::detect::fit::profile::{ProfileMode, ProfileOptions};
    let spec = FitSpec {
        d,
        k,
        mass,
        gamma,
        left,
        right,
        observe,
        observe_kind,
        fit,
        noise,
        ..FitSpec::new(n)
    };
    let (t, x) = (values(&t), values(&x));
    let force = force.as_ref().map(values);
    let report = interruptible(py, move || -> Result<_> {
        let mode = ProfileMode::parse(&profile)?;
        let (model, opts) = spec.build()?;
        let obs = series_obs(&spec, t, x, Vec::new(), force, opts.noise.known())?;
        let mut po = ProfileOptions::new(mode);
        po.noise = opts.noise;
        if let Some(c) = change {
            po.change = c;
        }
        po.lambda = penalty;
        springmass::detect::fit::fit_profile(&obs, &model, &po)
    })?;
    let json = serde_json::to_value(&report).map_err(|e| {
        NumericalError::new_err(format!("the profile report cannot be written: {e}"))
    })?;
    let out = PyDict::new(py);
    out.set_item("report", json.to_string())?;
    out.set_item("summary", report.summary())?;
    Ok(out)
}

/// Every mass of a chain from the modes of mass 1: natural frequencies
/// `omega` (rad/s) and residues `r_j` of `X_1(s) / gamma = sum_j r_j /
/// (s^2 + omega_j^2)`, uniform springs `k`; see
/// `springmass::detect::fit::spectral`.
#[pyfunction]
#[pyo3(signature = (omega, residue, *, k, left, right))]
fn spectral<'py>(
    py: Python<'py>,
    omega: PyReadonlyArray1<'py, f64>,
    residue: PyReadonlyArray1<'py, f64>,
    k: f64,
    left: String,
    right: String,
) -> PyResult<Bound<'py, PyDict>> {
    let (om, re) = (omega.as_array().to_vec(), residue.as_array().to_vec());
    let s = py
        .detach(move || -> Result<_> {
            let chain = Chain::paper(om.len())?
                .with_k(k)?
                .with_boundaries(left.parse()?, right.parse()?)?;
            let spec = springmass::detect::fit::spectral::Spectrum {
                lambda: om.iter().map(|w| w * w).collect(),
                residue: re,
            };
            springmass::detect::fit::spectral::masses_from_spectrum(&chain.springs(), &spec)
        })
        .py_err()?;
    let out = PyDict::new(py);
    out.set_item("consistency", s.consistency)?;
    out.set_item("masses", s.masses.into_pyarray(py))?;
    Ok(out)
}

/// Structural model updating from measured modes
/// (`springmass::detect::fit::modal_update`): `modes` is the CSV text of
/// `springmass fit --modes FILE`. Returns the report as the CLI's JSON and
/// its text summary.
#[pyfunction]
#[pyo3(signature = (modes, *, n, mass, k, d, left, right, profile, hold_out, starts, seed,
    baseline=None, modal_residual=None, damping=None, defects=None, kinds=None))]
#[allow(clippy::too_many_arguments)]
fn fit_modes<'py>(
    py: Python<'py>,
    modes: String,
    n: usize,
    mass: f64,
    k: f64,
    d: f64,
    left: String,
    right: String,
    profile: String,
    hold_out: Vec<usize>,
    starts: usize,
    seed: u64,
    baseline: Option<BaselineArg>,
    modal_residual: Option<String>,
    damping: Option<String>,
    defects: Option<String>,
    kinds: Option<String>,
) -> PyResult<Bound<'py, PyDict>> {
    use springmass::detect::fit::modal_update::{
        update_from_modes, ModalFormulation, ModalUpdateOptions,
    };
    let mut spec = nominal_spec(n, mass, k, d, left, right, baseline)?;
    spec.damping = damping;
    if let Some(text) = defects {
        return locate_modes(py, modes, &spec, &text, kinds, modal_residual);
    }
    if let Some(k) = kinds {
        return Err(Error::invalid(
            "kinds",
            k,
            "kinds with defects (the defect search); the update frees profile's kind",
        ))
        .py_err();
    }
    let report = interruptible(py, move || -> Result<_> {
        let data = springmass::detect::data::modes::MeasuredModes::from_csv_str(&modes)?;
        let opts = ModalUpdateOptions {
            mode: springmass::detect::fit::profile::ProfileMode::parse(&profile)?,
            hold_out,
            starts,
            seed,
            formulation: match &modal_residual {
                Some(f) => ModalFormulation::parse(f)?,
                None => ModalFormulation::default(),
            },
            ..Default::default()
        };
        update_from_modes(spec.model()?.chain(), data, &opts)
    })?;
    report_dict(py, &report, report.summary(), "modal update")
}

/// `fit_modes` with `defects`: which elements changed
/// (`springmass::detect::fit::modal_locate`, `springmass fit --modes FILE
/// --defects`).
fn locate_modes<'py>(
    py: Python<'py>,
    modes: String,
    spec: &FitSpec,
    defects: &str,
    kinds: Option<String>,
    modal_residual: Option<String>,
) -> PyResult<Bound<'py, PyDict>> {
    use springmass::detect::fit::modal_locate::{
        locate_from_modes, parse_defect_count, parse_kinds, ModalLocateOptions,
    };
    use springmass::detect::fit::modal_update::ModalFormulation;
    let nominal = spec.model().py_err()?.chain().clone();
    let (k_min, k_max) = parse_defect_count(defects).py_err()?;
    let report = interruptible(py, move || -> Result<_> {
        let data = springmass::detect::data::modes::MeasuredModes::from_csv_str(&modes)?;
        let mut opts = ModalLocateOptions {
            k_min,
            k_max,
            extend: defects.trim() == "auto",
            formulation: match &modal_residual {
                Some(f) => ModalFormulation::parse(f)?,
                None => ModalFormulation::default(),
            },
            ..Default::default()
        };
        let kinds = kinds.as_deref().unwrap_or("default");
        (opts.kinds, opts.dampers) = parse_kinds(kinds, &nominal, &data)?;
        locate_from_modes(&nominal, data, &opts)
    })?;
    report_dict(py, &report, report.summary(), "modal defect search")
}

/// A fit scene (`springmass fit --scene`, `springmass::detect::fit::fit_scene`):
/// `text` is the scene's TOML (its data exact, simulated, series with one
/// or several sensors and records, or modes). Returns the report as the
/// CLI's JSON and its text summary.
#[pyfunction]
fn fit_scene<'py>(py: Python<'py>, text: String) -> PyResult<Bound<'py, PyDict>> {
    let report = interruptible(py, move || -> Result<_> {
        let scene = springmass::detect::scene::FitScene::from_toml(&text)?;
        springmass::detect::fit::fit_scene(&scene)
    })?;
    report_dict(py, &report, report.summary(), "scene fit")
}

/// Output-only (ambient) fit (`springmass::detect::fit::ambient`): `t` and
/// one channel per observed mass. Returns the report as the CLI's JSON and
/// its text summary.
#[pyfunction]
#[pyo3(signature = (t, channels, *, observe, observe_kind, n, mass, k, d, left, right,
    ambient_on, k_min, k_max, kinds, profile, fit_d, baseline=None, ambient_band=None))]
#[allow(clippy::too_many_arguments)]
fn fit_ambient<'py>(
    py: Python<'py>,
    t: Vec<f64>,
    channels: Vec<Vec<f64>>,
    observe: Vec<usize>,
    observe_kind: String,
    n: usize,
    mass: f64,
    k: f64,
    d: f64,
    left: String,
    right: String,
    ambient_on: Option<Vec<usize>>,
    k_min: usize,
    k_max: usize,
    kinds: String,
    profile: bool,
    fit_d: bool,
    baseline: Option<BaselineArg>,
    ambient_band: Option<(f64, f64)>,
) -> PyResult<Bound<'py, PyDict>> {
    use springmass::detect::data::ambient::AmbientRecord;
    use springmass::detect::fit::ambient::{fit_ambient, AmbientOptions, AmbientTarget};
    let spec = nominal_spec(n, mass, k, d, left, right, baseline)?;
    let report = interruptible(py, move || -> Result<_> {
        let cols = channels
            .into_iter()
            .enumerate()
            .map(|(i, c)| (format!("y{}", i + 1), c))
            .collect();
        let ts = springmass::series::TimeSeries::new(t, cols)?;
        let rec = AmbientRecord::from_series(&ts, observe, observe_kind.parse()?)?;
        let opts = AmbientOptions {
            ambient_on,
            force_band: ambient_band,
            fit_d,
            target: if profile {
                AmbientTarget::Profile
            } else {
                AmbientTarget::Defects { k_min, k_max }
            },
            kinds: springmass::detect::fit::profile::ProfileMode::parse(&kinds)?,
            ..Default::default()
        };
        fit_ambient(spec.model()?.chain(), &rec, &opts)
    })?;
    report_dict(py, &report, report.summary(), "ambient")
}

/// The nominal chain of the modal update and the ambient fit: uniform from
/// `mass`, `k`, `d` and the ends, or a baseline table.
#[allow(clippy::too_many_arguments)]
fn nominal_spec(
    n: usize,
    mass: f64,
    k: f64,
    d: f64,
    left: String,
    right: String,
    baseline: Option<BaselineArg>,
) -> PyResult<FitSpec> {
    let baseline = baseline.map(BaselineArg::spec).transpose().py_err()?;
    Ok(FitSpec {
        baseline,
        d: Some(d),
        k: Some(k),
        mass: Some(mass),
        left: Some(left),
        right: Some(right),
        ..FitSpec::new(n)
    })
}

/// `{"report": JSON text, "summary": text}` of a report named `what`.
fn report_dict<'py>(
    py: Python<'py>,
    report: &impl serde::Serialize,
    summary: String,
    what: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let json = serde_json::to_value(report).map_err(|e| {
        NumericalError::new_err(format!("the {what} report cannot be written: {e}"))
    })?;
    let out = PyDict::new(py);
    out.set_item("report", json.to_string())?;
    out.set_item("summary", summary)?;
    Ok(out)
}

/// The search registry (`springmass::detect::search::SEARCHES`): one dict
/// per search with its name, aliases, help, the defect kinds it places,
/// whether the scene's general fit accepts it and whether it is stochastic.
#[pyfunction]
fn searches(py: Python<'_>) -> PyResult<Vec<Bound<'_, PyDict>>> {
    use springmass::detect::search::registry::Kinds;
    springmass::detect::search::SEARCHES
        .iter()
        .map(|s| {
            let d = PyDict::new(py);
            d.set_item("name", s.name)?;
            d.set_item("aliases", s.aliases.to_vec())?;
            d.set_item("help", s.help)?;
            d.set_item(
                "kinds",
                match s.kinds {
                    Kinds::Every => "every",
                    Kinds::MassOrSpring => "mass-or-spring",
                    Kinds::MassOnly => "mass-only",
                },
            )?;
            d.set_item("general_scene", s.general_scene)?;
            d.set_item("stochastic", s.stochastic())?;
            d.set_item("optimizer", s.optimizer.map(|o| o.module))?;
            Ok(d)
        })
        .collect()
}

/// Ask every running fit to stop (`springmass::cancel::request`: they
/// return promptly with an error), or with `stop = false` clear the
/// request. `fit_many` calls it on Ctrl-C: its fits run on worker threads,
/// where Python delivers no signal.
#[pyfunction]
fn cancel(stop: bool) {
    if stop {
        springmass::cancel::request();
    } else {
        springmass::cancel::reset();
    }
}

/// The native module.
#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("UnresolvableError", m.py().get_type::<UnresolvableError>())?;
    m.add("NumericalError", m.py().get_type::<NumericalError>())?;
    m.add_function(wrap_pyfunction!(fit, m)?)?;
    m.add_function(wrap_pyfunction!(simulate, m)?)?;
    m.add_function(wrap_pyfunction!(response_real, m)?)?;
    m.add_function(wrap_pyfunction!(response_complex, m)?)?;
    m.add_function(wrap_pyfunction!(controls, m)?)?;
    m.add_function(wrap_pyfunction!(laplace, m)?)?;
    m.add_function(wrap_pyfunction!(locate, m)?)?;
    m.add_function(wrap_pyfunction!(scene, m)?)?;
    m.add_function(wrap_pyfunction!(read_csv, m)?)?;
    m.add_function(wrap_pyfunction!(spectral, m)?)?;
    m.add_function(wrap_pyfunction!(fit_profile, m)?)?;
    m.add_function(wrap_pyfunction!(fit_modes, m)?)?;
    m.add_function(wrap_pyfunction!(fit_scene, m)?)?;
    m.add_function(wrap_pyfunction!(fit_ambient, m)?)?;
    m.add_function(wrap_pyfunction!(searches, m)?)?;
    m.add_function(wrap_pyfunction!(cancel, m)?)?;
    Ok(())
}
