//! Time-domain simulation of a chain: `x_i(t)` for any masses, the impulse
//! `gamma delta(t)` on mass 1, and optional external forces on any masses.
//!
//! Equations of motion (`M`, `D` diagonal, `K` tridiagonal, see [`Chain`]):
//!
//! ```text
//! M x'' + D x' + K x = gamma delta(t) e_1 + f(t),   x(0) = 0,  x'(0-) = 0
//! ```
//!
//! The impulse is the initial velocity `x_1'(0+) = gamma / m_1`. In state form
//! `y = (x, x')`, `y' = A y + B f(t)` with `A = [[0, I], [-M^-1 K, -M^-1 D]]`.
//! Either end may be free ([`crate::chain::Boundary`]: no wall spring).
//!
//! **Observables** ([`SimOptions::observe_kind`]): the displacement `x`, the
//! velocity `x'` (the second half of the state) or the acceleration
//! `x'' = M^-1 (f(t) - D x' - K x)` from the state and the force at the
//! sample time. The acceleration series is that of `t > 0`: the impulse's
//! delta is not a sample, and the value at `t = 0` is the limit `t -> 0+`
//! (`-d_1 gamma / m_1^2 + f_1(0)/m_1` on mass 1). A hammer test is the
//! impulse replaced by a measured force: `gamma = 0` and a sampled force on
//! mass 1 ([`Force::sampled`]).
//!
//! # Methods ([`Method`])
//!
//! | method | per output step | unforced | forced |
//! |---|---|---|---|
//! | `Expm` | dense `O(n^2)`, setup `O(n^3)` | exact: `y_{k+1} = exp(A dt) y_k` | exponential integrator, exact for a force that is a polynomial of degree `< q` on each step |
//! | `Rk` | sparse `O(n)` | Taylor/RK of adaptive degree on sub-steps with `h ||A|| <= 1.5` | same, on the augmented system |
//! | `Modal` | `O(modes)` per sample | exact residue sum ([`super::modal`]) | not available |
//! | `Auto` | the cheaper of `Expm` and `Rk` by a cost model | | |
//!
//! **Forces.** On each step `[t, t + h]` every force is replaced by the
//! polynomial through its values at `q` Chebyshev nodes of the step
//! (`q = force_nodes`, default 8): the step is then exact for that polynomial
//! (φ-functions from the augmented matrix exponential
//! `exp([[hA, B_F, 0..], [0, J]])`, Al-Mohy & Higham 2011), so the method has
//! order `q` in the force (global error `O(h^q)` times the force's `q`-th
//! derivative) and is exact for polynomial forces of degree `< q`.
//! A force given as samples ([`Force::sampled`]) is a piecewise polynomial
//! interpolant; when the simulator's steps fit between its knots (same `dt`,
//! or `dt` a divisor of the sample spacing) and `q > order`, the interpolant
//! is integrated exactly.
//!
//! **`Rk`.** For a linear constant-coefficient system the stability
//! polynomial of a `p`-stage explicit Runge–Kutta method of order `p` is the
//! degree-`p` Taylor polynomial of `exp(hA)`; `Rk` sums that Taylor series
//! (one sparse matrix-vector product per term, `O(n)`) until two successive
//! terms fall below `2^-53` of the sum, on sub-steps with `h ||A||_inf <= 1.5`
//! (about 20 terms). Stated error: per sub-step truncation below `1e-16 ||y||`
//! plus rounding; measured against `Expm` and the exact residue sum below
//! `1e-12` over `t <= 300` for `n = 20`.
//!
//! # Example: impulse response and a forced run
//!
//! ```
//! use springmass::Chain;
//! use springmass::time::simulate::{simulate, simulate_forced, Forcing, SimOptions};
//! let chain = Chain::paper(20)?;
//! let opts = SimOptions::new(50.0, 0.1).with_observe(vec![1, 20]);
//! let free = simulate(&chain, &opts)?;
//! assert_eq!(free.t.len(), 501);
//! // a sinusoidal force on mass 20, on top of the impulse on mass 1
//! let forcing = Forcing::new().on(20, |t| 0.1 * (0.7 * t).sin());
//! let forced = simulate_forced(&chain, &opts, &forcing)?;
//! assert!(forced.x(20).unwrap()[100] != free.x(20).unwrap()[100]);
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::chain::{Chain, Damping};
use crate::error::{Error, Result};
use crate::forward::Observable;
use crate::series::TimeSeries;
use nalgebra::{DMatrix, DVector};
use std::fmt;
use std::str::FromStr;
use std::sync::Arc;

/// Largest number of stored values (samples times observed masses).
pub const MAX_VALUES: usize = 50_000_000;
/// Largest interpolation order of a sampled force.
pub const MAX_INTERP_ORDER: usize = 7;
/// Largest number of force nodes per step.
pub const MAX_FORCE_NODES: usize = 12;
/// Sub-steps of `Rk` satisfy `h ||A||_inf <= RK_THETA`.
const RK_THETA: f64 = 1.5;
/// Largest chain for the dense `Expm` method (its matrix has `(2n)^2` entries).
pub const MAX_N_EXPM: usize = 2000;

/// An external force on one mass, as a function of time.
#[derive(Clone)]
pub enum Force {
    /// A closure `t -> f(t)`; it must return finite values for `t >= 0`.
    Func(Arc<dyn Fn(f64) -> f64 + Send + Sync>),
    /// Samples with a piecewise polynomial interpolant (see [`Force::sampled`]).
    Sampled(SampledForce),
}

impl fmt::Debug for Force {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Force::Func(_) => write!(f, "Force::Func(<closure>)"),
            Force::Sampled(s) => write!(
                f,
                "Force::Sampled({} samples on [{}, {}], order {})",
                s.t.len(),
                s.t[0],
                s.t[s.t.len() - 1],
                s.order
            ),
        }
    }
}

/// A force known at sample times, interpolated between them.
///
/// On each interval `[t_k, t_{k+1}]` the value is the Lagrange polynomial of
/// degree `order` through the `order + 1` samples around the interval
/// (centred where possible), so the interpolant is a piecewise polynomial
/// with knots at the sample times: `order = 1` is piecewise linear, `3` is
/// piecewise cubic. Outside `[t_0, t_N]` the force is zero.
#[derive(Clone, Debug, PartialEq)]
pub struct SampledForce {
    t: Vec<f64>,
    f: Vec<f64>,
    order: usize,
}

impl SampledForce {
    /// Validate and build.
    ///
    /// # Errors
    /// Fewer than two samples, length mismatch, non-finite or non-increasing
    /// times, non-finite values, `order` outside `1..=MAX_INTERP_ORDER`.
    pub fn new(t: Vec<f64>, f: Vec<f64>, order: usize) -> Result<SampledForce> {
        if !(1..=MAX_INTERP_ORDER).contains(&order) {
            return Err(Error::invalid(
                "force.order",
                order,
                format!("1 <= order <= {MAX_INTERP_ORDER}"),
            ));
        }
        if t.len() < 2 || t.len() != f.len() {
            return Err(Error::invalid(
                "force samples",
                format!("{} times, {} values", t.len(), f.len()),
                "at least 2 samples, as many values as times",
            ));
        }
        // reuse the series validation (sorted, distinct, finite)
        TimeSeries::new(t.clone(), vec![("f".into(), f.clone())])?;
        Ok(SampledForce { t, f, order })
    }

    /// Interpolated value at `t` (zero outside the sampled window).
    pub fn eval(&self, t: f64) -> f64 {
        let n = self.t.len();
        if !(t >= self.t[0] && t <= self.t[n - 1]) {
            return 0.0;
        }
        // interval k with t_k <= t < t_{k+1} (last interval closed)
        let k = (self.t.partition_point(|&s| s <= t).max(1) - 1).min(n - 2);
        let order = self.order.min(n - 1);
        let start = (k + 1).saturating_sub(order.div_ceil(2)).min(n - 1 - order);
        let nodes = &self.t[start..=start + order];
        let vals = &self.f[start..=start + order];
        let mut sum = 0.0;
        for (a, (&ta, &fa)) in nodes.iter().zip(vals).enumerate() {
            let mut l = 1.0;
            for (b, &tb) in nodes.iter().enumerate() {
                if a != b {
                    l *= (t - tb) / (ta - tb);
                }
            }
            sum += l * fa;
        }
        sum
    }
}

impl Force {
    /// A force given by a closure.
    pub fn func(f: impl Fn(f64) -> f64 + Send + Sync + 'static) -> Force {
        Force::Func(Arc::new(f))
    }
    /// A sampled force (see [`SampledForce::new`]).
    ///
    /// # Errors
    /// As [`SampledForce::new`].
    pub fn sampled(t: Vec<f64>, f: Vec<f64>, order: usize) -> Result<Force> {
        Ok(Force::Sampled(SampledForce::new(t, f, order)?))
    }
    /// Value at `t`.
    pub fn eval(&self, t: f64) -> f64 {
        match self {
            Force::Func(f) => f(t),
            Force::Sampled(s) => s.eval(t),
        }
    }
}

/// External forces on the masses of a chain (1-based positions). Several
/// forces on one mass add up.
///
/// ```
/// use springmass::series::TimeSeries;
/// use springmass::time::simulate::{Force, Forcing};
/// // a closure on mass 5 and a sampled, piecewise-cubic force on mass 4
/// let t: Vec<f64> = (0..=100).map(|k| k as f64 * 0.1).collect();
/// let g: Vec<f64> = t.iter().map(|t| (-t).exp()).collect();
/// let forcing = Forcing::new()
///     .on(5, |t| (2.0 * t).cos())
///     .with(4, Force::sampled(t.clone(), g.clone(), 3)?);
/// assert_eq!(forcing.masses(), vec![4, 5]);
/// // the same sampled force from a CSV-style series with a column `f4`
/// let ts = TimeSeries::new(t, vec![("f4".into(), g)])?;
/// assert_eq!(Forcing::from_series(&ts, 3)?.masses(), vec![4]);
/// # Ok::<(), springmass::Error>(())
/// ```
#[derive(Clone, Debug, Default)]
pub struct Forcing {
    terms: Vec<(usize, Force)>,
}

impl Forcing {
    /// No forces.
    pub fn new() -> Forcing {
        Forcing::default()
    }
    /// Add `force` on mass `at` (1-based; checked against the chain when simulating).
    pub fn with(mut self, at: usize, force: Force) -> Forcing {
        self.terms.push((at, force));
        self
    }
    /// Add the closure `f(t)` as a force on mass `at`.
    pub fn on(self, at: usize, f: impl Fn(f64) -> f64 + Send + Sync + 'static) -> Forcing {
        self.with(at, Force::func(f))
    }
    /// Forces from the columns of a series: a column named `f<j>` is the force
    /// on mass `j`, interpolated with the given `order`.
    ///
    /// # Errors
    /// A column not named `f<j>` with `j >= 1`, or an invalid series for
    /// [`SampledForce::new`].
    pub fn from_series(ts: &TimeSeries, order: usize) -> Result<Forcing> {
        let mut out = Forcing::new();
        for (i, name) in ts.names().iter().enumerate() {
            let at = name
                .strip_prefix('f')
                .and_then(|r| r.parse::<usize>().ok())
                .filter(|&j| j >= 1)
                .ok_or_else(|| {
                    Error::invalid(
                        "force column",
                        name,
                        "names f<j> (force on mass j >= 1), for example f20",
                    )
                })?;
            let col = ts.column_at(i).unwrap_or_default().to_vec();
            out = out.with(at, Force::sampled(ts.t().to_vec(), col, order)?);
        }
        Ok(out)
    }
    /// No force at all.
    pub fn is_empty(&self) -> bool {
        self.terms.is_empty()
    }
    /// The forced masses, sorted, without repetition.
    pub fn masses(&self) -> Vec<usize> {
        let mut m: Vec<usize> = self.terms.iter().map(|(j, _)| *j).collect();
        m.sort_unstable();
        m.dedup();
        m
    }
    /// Total force on mass `at` at time `t`.
    pub fn value(&self, at: usize, t: f64) -> f64 {
        self.terms
            .iter()
            .filter(|(j, _)| *j == at)
            .map(|(_, f)| f.eval(t))
            .sum()
    }
    fn check(&self, n: usize) -> Result<()> {
        for (i, (j, _)) in self.terms.iter().enumerate() {
            if *j < 1 || *j > n {
                return Err(Error::invalid(
                    format!("forcing[{i}].at"),
                    j,
                    format!("1 <= at <= {n}"),
                ));
            }
        }
        Ok(())
    }
}

/// Integration method (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Method {
    /// The cheaper of `Expm` and `Rk` (dense setup `O(n^3)` against sparse steps).
    #[default]
    Auto,
    /// Dense matrix exponential stepping (exponential integrator when forced).
    Expm,
    /// Exact residue sum, unforced only.
    Modal,
    /// Sparse `O(n)` Taylor/Runge–Kutta stepping.
    Rk,
}

impl FromStr for Method {
    type Err = Error;
    fn from_str(s: &str) -> Result<Method> {
        match s.trim().to_ascii_lowercase().as_str() {
            "auto" => Ok(Method::Auto),
            "expm" => Ok(Method::Expm),
            "modal" => Ok(Method::Modal),
            "rk" | "taylor" => Ok(Method::Rk),
            _ => Err(Error::invalid("method", s, "auto, expm, modal or rk")),
        }
    }
}

impl fmt::Display for Method {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Method::Auto => "auto",
            Method::Expm => "expm",
            Method::Modal => "modal",
            Method::Rk => "rk",
        })
    }
}

/// What to simulate: output times `0, dt, 2 dt, ..., <= t_end`, observed
/// masses and method.
#[derive(Clone, Debug, PartialEq)]
pub struct SimOptions {
    /// Last time (inclusive if a multiple of `dt`), `> 0`.
    pub t_end: f64,
    /// Output step, `0 < dt <= t_end`.
    pub dt: f64,
    /// Observed masses, 1-based [default: `[1]`].
    pub observe: Vec<usize>,
    /// Method [default: `Auto`].
    pub method: Method,
    /// Force interpolation nodes per step `q` (order `q` in the force) [default 8].
    pub force_nodes: usize,
    /// Internal steps per output step (at least; `Rk` may use more) [default 1].
    pub substeps: usize,
    /// What is recorded: displacement, velocity or acceleration [default displacement].
    pub observe_kind: Observable,
}

impl SimOptions {
    /// Defaults for the given horizon and step.
    pub fn new(t_end: f64, dt: f64) -> SimOptions {
        SimOptions {
            t_end,
            dt,
            observe: vec![1],
            method: Method::Auto,
            force_nodes: 8,
            substeps: 1,
            observe_kind: Observable::Displacement,
        }
    }
    /// What is recorded (see the module docs).
    pub fn with_observe_kind(mut self, kind: Observable) -> SimOptions {
        self.observe_kind = kind;
        self
    }
    /// Observed masses.
    pub fn with_observe(mut self, observe: Vec<usize>) -> SimOptions {
        self.observe = observe;
        self
    }
    /// Method.
    pub fn with_method(mut self, method: Method) -> SimOptions {
        self.method = method;
        self
    }
    /// Force nodes per step.
    pub fn with_force_nodes(mut self, q: usize) -> SimOptions {
        self.force_nodes = q;
        self
    }
    /// Internal steps per output step.
    pub fn with_substeps(mut self, s: usize) -> SimOptions {
        self.substeps = s;
        self
    }

    /// Number of output samples, after validation against `chain`.
    ///
    /// # Errors
    /// `dt`, `t_end` not finite or out of range, more than [`MAX_VALUES`]
    /// values, no observed mass or one out of `1..=n`, `force_nodes` or
    /// `substeps` out of range.
    pub fn samples(&self, chain: &Chain) -> Result<usize> {
        if !(self.t_end.is_finite() && self.t_end > 0.0) {
            return Err(Error::invalid("t_end", self.t_end, "t_end > 0 and finite"));
        }
        if !(self.dt.is_finite() && self.dt > 0.0 && self.dt <= self.t_end) {
            return Err(Error::invalid(
                "dt",
                self.dt,
                format!("0 < dt <= t_end = {}", self.t_end),
            ));
        }
        if self.observe.is_empty() {
            return Err(Error::invalid("observe", "[]", "at least one mass"));
        }
        for &i in &self.observe {
            chain.check_observe(i)?;
        }
        if !(1..=MAX_FORCE_NODES).contains(&self.force_nodes) {
            return Err(Error::invalid(
                "force_nodes",
                self.force_nodes,
                format!("1 <= force_nodes <= {MAX_FORCE_NODES}"),
            ));
        }
        if !(1..=1_000_000).contains(&self.substeps) {
            return Err(Error::invalid(
                "substeps",
                self.substeps,
                "1 <= substeps <= 1000000",
            ));
        }
        let steps = (self.t_end / self.dt * (1.0 + 1e-12)).floor();
        let values = (steps + 1.0) * self.observe.len() as f64;
        if values > MAX_VALUES as f64 {
            return Err(Error::invalid(
                "t_end/dt",
                format!("{} samples x {} masses", steps + 1.0, self.observe.len()),
                format!("at most {MAX_VALUES} stored values: raise dt or shorten t_end"),
            ));
        }
        Ok(steps as usize + 1)
    }
}

/// A simulated trajectory: `x[c][k]` is the observed quantity (see `kind`)
/// of mass `observe[c]` at `t[k]`.
#[derive(Clone, Debug, PartialEq)]
pub struct Trajectory {
    /// Output times `k dt`.
    pub t: Vec<f64>,
    /// Observed masses (1-based).
    pub observe: Vec<usize>,
    /// The observed quantity (displacement, velocity or acceleration), one
    /// vector per observed mass.
    pub x: Vec<Vec<f64>>,
    /// What `x` holds.
    pub kind: Observable,
    /// The method used (never `Auto`).
    pub method: Method,
    /// Internal steps per output step.
    pub substeps: usize,
}

impl Trajectory {
    /// The displacement of mass `i` (1-based), if observed.
    pub fn x(&self, i: usize) -> Option<&[f64]> {
        self.observe
            .iter()
            .position(|&j| j == i)
            .map(|c| self.x[c].as_slice())
    }
    /// As a [`TimeSeries`] with columns `x<i>` (displacement), `v<i>`
    /// (velocity) or `a<i>` (acceleration).
    ///
    /// # Errors
    /// Non-finite values (an unstable or overflowing run).
    pub fn to_series(&self) -> Result<TimeSeries> {
        TimeSeries::new(
            self.t.clone(),
            self.observe
                .iter()
                .zip(&self.x)
                .map(|(i, x)| (format!("{}{i}", self.kind.prefix()), x.clone()))
                .collect(),
        )
    }
}

/// Unforced simulation (impulse `gamma` on mass 1 only).
///
/// # Errors
/// See [`simulate_forced`].
pub fn simulate(chain: &Chain, opts: &SimOptions) -> Result<Trajectory> {
    simulate_forced(chain, opts, &Forcing::new())
}

/// Simulation with the impulse on mass 1 and the external `forcing`.
///
/// # Errors
/// Invalid options ([`SimOptions::samples`]), a forced mass out of range,
/// `Modal` with forces, `Expm` with `n >` [`MAX_N_EXPM`], a force returning a
/// non-finite value ([`Error::Numerical`]), a failed modal decomposition.
pub fn simulate_forced(chain: &Chain, opts: &SimOptions, forcing: &Forcing) -> Result<Trajectory> {
    let samples = opts.samples(chain)?;
    forcing.check(chain.n())?;
    let t: Vec<f64> = (0..samples).map(|k| k as f64 * opts.dt).collect();
    let sys = System::new(chain, forcing, opts)?;
    let method = match opts.method {
        Method::Auto => sys.cheaper(opts, samples),
        m => m,
    };
    let (x, substeps) = match method {
        Method::Modal => {
            if !forcing.is_empty() {
                return Err(Error::invalid(
                    "method",
                    "modal",
                    "unforced simulations only (use expm or rk with forces)",
                ));
            }
            let modes = super::modal::Modes::new(chain)?;
            let x = opts
                .observe
                .iter()
                .map(|&i| {
                    let mut r = modes.response(i, 1, chain.gamma())?;
                    for _ in 0..opts.observe_kind.power() {
                        r = r.derivative();
                    }
                    Ok(r.eval_many(&t))
                })
                .collect::<Result<Vec<_>>>()?;
            (x, 1)
        }
        Method::Expm => {
            if chain.n() > MAX_N_EXPM {
                return Err(Error::invalid(
                    "method",
                    format!("expm with n = {}", chain.n()),
                    format!("n <= {MAX_N_EXPM} (use rk for larger chains)"),
                ));
            }
            (sys.run_expm(opts, samples)?, opts.substeps)
        }
        Method::Rk => sys.run_rk(opts, samples)?,
        Method::Auto => unreachable!("resolved above"),
    };
    Ok(Trajectory {
        t,
        observe: opts.observe.clone(),
        x,
        kind: opts.observe_kind,
        method,
        substeps,
    })
}

/// `sum += term`, returning `(max |term|, max |sum|)`; four independent lanes
/// so that the maxima do not serialise the loop.
fn add_track_max(sum: &mut [f64], term: &[f64]) -> (f64, f64) {
    let (mut t, mut s) = ([0.0_f64; 4], [0.0_f64; 4]);
    let mut sc = sum.chunks_exact_mut(4);
    let mut tc = term.chunks_exact(4);
    for (a, b) in (&mut sc).zip(&mut tc) {
        for j in 0..4 {
            a[j] += b[j];
            t[j] = t[j].max(b[j].abs());
            s[j] = s[j].max(a[j].abs());
        }
    }
    for (a, b) in sc.into_remainder().iter_mut().zip(tc.remainder()) {
        *a += b;
        t[0] = t[0].max(b.abs());
        s[0] = s[0].max(a.abs());
    }
    (
        t[0].max(t[1]).max(t[2].max(t[3])),
        s[0].max(s[1]).max(s[2].max(s[3])),
    )
}

/// The state-space system and the force sampling shared by the steppers.
struct System<'a> {
    n: usize,
    m: Vec<f64>,
    inv_m: Vec<f64>,
    /// per mass: [k_i, -(k_i + k_{i+1} + g_i), k_{i+1}, -d_i] / m_i
    rows: Vec<[f64; 4]>,
    /// the rows of `M^-1 D`'s off-diagonal (spring-parallel dampers):
    /// `[left, right]` per mass; empty without them
    vrows: Vec<[f64; 2]>,
    /// `M^-1 C` of the `modal` damping model (full, `n x n`), beside the
    /// tridiagonal part above (its grounded dampers only)
    modal: Option<DMatrix<f64>>,
    /// spring-parallel dampers (`n + 1`)
    c: Vec<f64>,
    k: Vec<f64>,
    /// Ground stiffness per mass.
    g: Vec<f64>,
    d: Vec<f64>,
    v0: f64,
    forcing: &'a Forcing,
    observe: Vec<usize>,
    kind: Observable,
    dt: f64,
    /// forced masses (1-based)
    fm: Vec<usize>,
    /// Chebyshev nodes on [0, 1]
    nodes: Vec<f64>,
    /// inverse Vandermonde: a_j = sum_m vinv[(j, m)] f(c_m)
    vinv: DMatrix<f64>,
}

impl<'a> System<'a> {
    fn new(chain: &Chain, forcing: &'a Forcing, opts: &SimOptions) -> Result<System<'a>> {
        // the modal model's C is full: M^-1 C = Phi diag(2 zeta_j omega_j) Phi^T M
        // (mass-normalised shapes), the grounded dampers stay tridiagonal
        let grounded;
        let (chain, modal) = match chain.damping() {
            damping @ Damping::Modal { .. } => {
                // the modes in the order of their frequencies
                let modes = super::modal::undamped_modes(chain)?;
                let m = chain.masses();
                let phi = &modes.shapes;
                let mut scaled = phi.clone();
                for (j, w) in modes.omega.iter().enumerate() {
                    scaled
                        .column_mut(j)
                        .scale_mut(2.0 * damping.modal_ratio(j) * w);
                }
                let mut a = scaled * phi.transpose();
                for (i, mi) in m.iter().enumerate() {
                    a.column_mut(i).scale_mut(*mi);
                }
                grounded = chain.clone().with_damping(Damping::Grounded)?;
                (&grounded, Some(a))
            }
            _ => (chain, None),
        };
        let q = opts.force_nodes;
        let m = chain.masses();
        let fm = forcing.masses();
        let q = if fm.is_empty() { 0 } else { q };
        let nodes: Vec<f64> = (0..q)
            .map(|i| {
                0.5 * (1.0 - ((2 * i + 1) as f64 * std::f64::consts::PI / (2 * q) as f64).cos())
            })
            .collect();
        let v = DMatrix::from_fn(q, q, |i, j| nodes[i].powi(j as i32));
        // Chebyshev nodes are distinct: the Vandermonde matrix is invertible
        let vinv = v.try_inverse().unwrap_or_else(|| DMatrix::zeros(q, q));
        let springs = chain.springs();
        let dampers = chain.dampers();
        let grounds = chain.grounds();
        let c = chain.spring_dampers();
        let general = c.iter().any(|&v| v != 0.0);
        Ok(System {
            modal,
            vrows: if general {
                (0..chain.n())
                    .map(|i| [c[i] / m[i], c[i + 1] / m[i]])
                    .collect()
            } else {
                Vec::new()
            },
            n: chain.n(),
            v0: chain.gamma() / m[0],
            inv_m: m.iter().map(|v| 1.0 / v).collect(),
            rows: (0..chain.n())
                .map(|i| {
                    let (k, d) = (&springs, &dampers);
                    [
                        k[i] / m[i],
                        -(k[i] + k[i + 1] + grounds[i]) / m[i],
                        k[i + 1] / m[i],
                        -(d[i] + c[i] + c[i + 1]) / m[i],
                    ]
                })
                .collect(),
            c: c.clone(),
            m,
            k: springs.clone(),
            g: grounds.clone(),
            d: dampers.clone(),
            forcing,
            observe: opts.observe.clone(),
            kind: opts.observe_kind,
            dt: opts.dt,
            fm,
            nodes,
            vinv,
        })
    }

    /// `Expm` or `Rk`, whichever a cost model (calibrated on this code:
    /// about 4 ns per `(2n)^3` of setup and 1 ns per matrix entry per dense
    /// step, 5 ns per mass per Taylor term) says is cheaper.
    fn cheaper(&self, opts: &SimOptions, samples: usize) -> Method {
        let n2 = (2 * self.n) as f64;
        let extra = (self.q() * self.nf()) as f64;
        let steps = samples.saturating_sub(1) as f64;
        let expm = 4.0 * (n2 + extra).powi(3) + steps * opts.substeps as f64 * n2 * (n2 + extra);
        let rk = 5.0 * steps * self.rk_substeps(opts) as f64 * 20.0 * self.n as f64;
        if self.n <= MAX_N_EXPM && expm < rk {
            Method::Expm
        } else {
            Method::Rk
        }
    }

    fn rk_substeps(&self, opts: &SimOptions) -> usize {
        opts.substeps
            .max((opts.dt * self.norm_a() / RK_THETA).ceil() as usize)
    }

    fn nf(&self) -> usize {
        self.fm.len()
    }
    fn q(&self) -> usize {
        self.nodes.len()
    }

    /// Force samples at the nodes of the step `[t, t + h]`: `out[m * nf + l]`.
    fn sample_forces(&self, t: f64, h: f64, out: &mut [f64]) -> Result<()> {
        let nf = self.nf();
        for (mi, c) in self.nodes.iter().enumerate() {
            let tm = t + c * h;
            for (l, &j) in self.fm.iter().enumerate() {
                let v = self.forcing.value(j, tm);
                if !v.is_finite() {
                    return Err(Error::Numerical {
                        method: "simulate".into(),
                        reason: format!("the force on mass {j} is {v} at t = {tm}"),
                    });
                }
                out[mi * nf + l] = v;
            }
        }
        Ok(())
    }

    /// `out = alpha A y` (sparse, O(n)), with the rows of `M^-1 K` and `M^-1 D`
    /// precomputed in `rows`.
    fn apply_a_scaled(&self, y: &[f64], out: &mut [f64], alpha: f64) {
        let n = self.n;
        let (x, v) = y.split_at(n);
        let (ox, ov) = out.split_at_mut(n);
        for (o, vi) in ox.iter_mut().zip(v) {
            *o = alpha * vi;
        }
        let r = &self.rows;
        let row = |i: usize, xl: f64, xr: f64| {
            let [lo, dg, up, dd] = r[i];
            alpha * (lo * xl + dg * x[i] + up * xr + dd * v[i])
        };
        if n == 1 {
            ov[0] = row(0, 0.0, 0.0);
            return;
        }
        ov[0] = row(0, 0.0, x[1]);
        ov[n - 1] = row(n - 1, x[n - 2], 0.0);
        for (((o, w), ri), vi) in ov[1..n - 1]
            .iter_mut()
            .zip(x.windows(3))
            .zip(&r[1..n - 1])
            .zip(&v[1..n - 1])
        {
            let [lo, dg, up, dd] = *ri;
            *o = alpha * (lo * w[0] + dg * w[1] + up * w[2] + dd * vi);
        }
        // spring-parallel dampers: the off-diagonal of M^-1 D
        for (i, [cl, cr]) in self.vrows.iter().enumerate() {
            let vl = if i > 0 { v[i - 1] } else { 0.0 };
            let vr = if i + 1 < n { v[i + 1] } else { 0.0 };
            ov[i] += alpha * (cl * vl + cr * vr);
        }
        if let Some(a) = &self.modal {
            for (i, o) in ov.iter_mut().enumerate() {
                let row: f64 = a.row(i).iter().zip(v).map(|(x, y)| x * y).sum();
                *o -= alpha * row;
            }
        }
    }

    fn norm_a(&self) -> f64 {
        (0..self.n)
            .map(|i| {
                (2.0 * (self.k[i] + self.k[i + 1] + self.c[i] + self.c[i + 1])
                    + self.g[i]
                    + self.d[i])
                    / self.m[i]
                    + self.modal.as_ref().map_or(0.0, |a| a.row(i).abs().sum())
            })
            .fold(1.0, f64::max)
    }

    fn dense_a(&self) -> DMatrix<f64> {
        let n = self.n;
        let mut a = DMatrix::zeros(2 * n, 2 * n);
        for i in 0..n {
            a[(i, n + i)] = 1.0;
            a[(n + i, i)] = -(self.k[i] + self.k[i + 1] + self.g[i]) / self.m[i];
            a[(n + i, n + i)] = self.rows[i][3];
            if i > 0 {
                a[(n + i, i - 1)] = self.k[i] / self.m[i];
                a[(n + i, n + i - 1)] = self.c[i] / self.m[i];
            }
            if i + 1 < n {
                a[(n + i, i + 1)] = self.k[i + 1] / self.m[i];
                a[(n + i, n + i + 1)] = self.c[i + 1] / self.m[i];
            }
        }
        if let Some(c) = &self.modal {
            let mut block = a.view_mut((n, n), (n, n));
            block -= c;
        }
        a
    }

    fn initial(&self) -> Vec<f64> {
        let mut y = vec![0.0; 2 * self.n];
        y[self.n] = self.v0;
        y
    }

    /// Dense stepping: `y <- E y + sum_m Q_m f(t + c_m h)`.
    fn run_expm(&self, opts: &SimOptions, samples: usize) -> Result<Vec<Vec<f64>>> {
        let n2 = 2 * self.n;
        let (nf, q) = (self.nf(), self.q());
        let sub = opts.substeps;
        let h = opts.dt / sub as f64;
        let size = n2 + q * nf;
        let mut z = DMatrix::zeros(size, size);
        z.view_mut((0, 0), (n2, n2))
            .copy_from(&(self.dense_a() * h));
        for (l, &j) in self.fm.iter().enumerate() {
            z[(self.n + j - 1, n2 + l)] = 1.0 / self.m[j - 1];
        }
        for blk in 0..q.saturating_sub(1) {
            for l in 0..nf {
                z[(n2 + blk * nf + l, n2 + (blk + 1) * nf + l)] = 1.0;
            }
        }
        let ez = z.exp();
        if ez.iter().any(|v| !v.is_finite()) {
            return Err(Error::Numerical {
                method: "expm".into(),
                reason: format!("exp(A dt) overflowed for dt = {}", opts.dt),
            });
        }
        let e = ez.view((0, 0), (n2, n2)).into_owned();
        // Q_m = sum_j h j! phi_{j+1}(hA) B_F vinv[(j, m)], columns m * nf + l
        let mut qall = DMatrix::zeros(n2, q * nf);
        let mut fact = 1.0;
        for j in 0..q {
            if j > 0 {
                fact *= j as f64;
            }
            let phi = ez.view((0, n2 + j * nf), (n2, nf));
            for mi in 0..q {
                let w = h * fact * self.vinv[(j, mi)];
                for l in 0..nf {
                    for r in 0..n2 {
                        qall[(r, mi * nf + l)] += w * phi[(r, l)];
                    }
                }
            }
        }
        let mut y = DVector::from_vec(self.initial());
        let mut tmp = DVector::zeros(n2);
        let mut fv = DVector::zeros(q * nf);
        let mut out = self.new_out(samples);
        self.record(y.as_slice(), 0, &mut out);
        for k in 1..samples {
            for s in 0..sub {
                tmp.gemv(1.0, &e, &y, 0.0);
                if nf > 0 {
                    let t0 = (k - 1) as f64 * opts.dt + s as f64 * h;
                    self.sample_forces(t0, h, fv.as_mut_slice())?;
                    tmp.gemv(1.0, &qall, &fv, 1.0);
                }
                std::mem::swap(&mut y, &mut tmp);
            }
            self.record(y.as_slice(), k, &mut out);
        }
        Ok(out)
    }

    /// Sparse Taylor/RK stepping on the augmented system. Returns the
    /// trajectory and the number of sub-steps per output step.
    fn run_rk(&self, opts: &SimOptions, samples: usize) -> Result<(Vec<Vec<f64>>, usize)> {
        const MAX_TERMS: usize = 80;
        let n2 = 2 * self.n;
        let (nf, q) = (self.nf(), self.q());
        let sub = self.rk_substeps(opts);
        let h = opts.dt / sub as f64;
        let mut y = self.initial();
        let mut u = vec![0.0; q * nf];
        let mut fv = vec![0.0; q * nf];
        let (mut ty, mut tu) = (vec![0.0; n2], vec![0.0; q * nf]);
        let (mut ny, mut nu) = (vec![0.0; n2], vec![0.0; q * nf]);
        let mut sum = vec![0.0; n2];
        let mut out = self.new_out(samples);
        self.record(&y, 0, &mut out);
        for k in 1..samples {
            for s in 0..sub {
                if nf > 0 {
                    let t0 = (k - 1) as f64 * opts.dt + s as f64 * h;
                    self.sample_forces(t0, h, &mut fv)?;
                    // u_{j+1} = h j! a_j, a = vinv f
                    let mut fact = 1.0;
                    for j in 0..q {
                        if j > 0 {
                            fact *= j as f64;
                        }
                        for l in 0..nf {
                            let a: f64 =
                                (0..q).map(|mi| self.vinv[(j, mi)] * fv[mi * nf + l]).sum();
                            u[j * nf + l] = h * fact * a;
                        }
                    }
                }
                sum.copy_from_slice(&y);
                ty.copy_from_slice(&y);
                tu.copy_from_slice(&u);
                let mut small = 0;
                let mut terms = 0;
                while small < 2 {
                    terms += 1;
                    if terms > MAX_TERMS {
                        return Err(Error::Numerical {
                            method: "rk".into(),
                            reason: format!("Taylor series did not converge in {MAX_TERMS} terms"),
                        });
                    }
                    // (ny, nu) = Z (ty, tu) / terms
                    let c = 1.0 / terms as f64;
                    self.apply_a_scaled(&ty, &mut ny, h * c);
                    for (l, &j) in self.fm.iter().enumerate() {
                        ny[self.n + j - 1] += c * tu[l] * self.inv_m[j - 1];
                    }
                    let mut umax = 0.0_f64;
                    for i in 0..q * nf {
                        nu[i] = if i + nf < q * nf { c * tu[i + nf] } else { 0.0 };
                        umax = umax.max(nu[i].abs());
                    }
                    std::mem::swap(&mut ty, &mut ny);
                    std::mem::swap(&mut tu, &mut nu);
                    let (tmax, smax) = add_track_max(&mut sum, &ty);
                    if tmax.max(umax) <= f64::EPSILON * 0.5 * smax.max(f64::MIN_POSITIVE) {
                        small += 1;
                    } else {
                        small = 0;
                    }
                }
                std::mem::swap(&mut y, &mut sum);
            }
            if !y.iter().all(|v| v.is_finite()) {
                return Err(Error::Numerical {
                    method: "rk".into(),
                    reason: format!("non-finite state at t = {}", k as f64 * opts.dt),
                });
            }
            self.record(&y, k, &mut out);
        }
        Ok((out, sub))
    }

    fn new_out(&self, samples: usize) -> Vec<Vec<f64>> {
        vec![vec![0.0; samples]; self.observe.len()]
    }
    fn record(&self, y: &[f64], k: usize, out: &mut [Vec<f64>]) {
        let n = self.n;
        for (c, &i) in self.observe.iter().enumerate() {
            out[c][k] = match self.kind {
                Observable::Displacement => y[i - 1],
                Observable::Velocity => y[n + i - 1],
                Observable::Acceleration => {
                    // M^-1 (f - D v - K x) at t = k dt
                    let r = i - 1;
                    let [lo, dg, up, dd] = self.rows[r];
                    let xl = if r > 0 { y[r - 1] } else { 0.0 };
                    let xr = if r + 1 < n { y[r + 1] } else { 0.0 };
                    let f = if self.fm.contains(&i) {
                        self.forcing.value(i, k as f64 * self.dt)
                    } else {
                        0.0
                    };
                    let between = match self.vrows.get(r) {
                        Some([cl, cr]) => {
                            let vl = if r > 0 { y[n + r - 1] } else { 0.0 };
                            let vr = if r + 1 < n { y[n + r + 1] } else { 0.0 };
                            cl * vl + cr * vr
                        }
                        None => 0.0,
                    };
                    lo * xl + dg * y[r] + up * xr + dd * y[n + r] + f * self.inv_m[r] + between
                }
            };
        }
    }
}

/// Test support: the impulse response of `chain` at masses 1 and 6 by
/// `method` (`dt = 0.2`, 301 samples) equals the dense state space's matrix
/// exponential ([`crate::chain::dense_ref::impulse`]) to `tol` times its
/// peak.
#[cfg(test)]
pub(crate) fn matches_the_dense_reference(chain: &Chain, method: Method, tol: f64) {
    let (dt, samples) = (0.2, 301);
    let opts = SimOptions::new(dt * (samples - 1) as f64, dt)
        .with_observe(vec![1, 6])
        .with_method(method);
    let run = simulate(chain, &opts).unwrap();
    for o in [1, 6] {
        let want = crate::chain::dense_ref::impulse(chain, o, dt, samples);
        let scale = want.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        for (g, w) in run.x(o).unwrap().iter().zip(&want) {
            assert!((g - w).abs() <= tol * scale, "{} {method}", chain.damping());
        }
    }
}

#[cfg(test)]
mod damping_tests {
    use super::*;
    use crate::chain::dense_ref;

    #[test]
    fn steppers_match_the_matrix_exponential_in_every_model() {
        for chain in dense_ref::model_chains()
            .into_iter()
            .chain(dense_ref::modal_chains())
        {
            for method in [Method::Expm, Method::Rk, Method::Modal] {
                matches_the_dense_reference(&chain, method, 1e-10);
            }
        }
    }
}
