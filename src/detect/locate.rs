//! Explicit single-defect locators (section 4.1 of the paper), corrected, with
//! error floors, and in any precision.
//!
//! One mass defect `m` at an unknown position `j` changes the observed
//! `X_1(s)` by the *defect signal* `D(s) = G_11(s) - X_1(s)/gamma` (`G` the
//! uniform chain's Green's function, [`model`]). Every locator solves a relation
//! between `D` and `j` for a **real** `j`, rounds it, and attaches an
//! uncertainty propagated from the data's error (its `err`, plus the rounding
//! floor of the number type):
//!
//! | [`Method`] | relation | needs |
//! |---|---|---|
//! | [`Method::Exact`] | (4.7): `D = c G_1j^2 / (1 + c G_jj)`, `c = (m - mass) s^2`, no asymptotics | `m` |
//! | [`Method::Asymptotic`] | (4.10): `D = ((m - mass)/m) G_1j^2 / G_jj` (the paper's printed (4.14) is wrong; this is (4.10) solved for `j`) | `m` |
//! | [`Method::Large`] | (4.17) rewritten as `j = ln(1 + 2 sinh(lambda)/delta) / (2 lambda)`, `delta = e^{-lambda} - k X_1/gamma`, extrapolated in `1/lambda` | nothing (heavy defect) |
//! | [`Method::LargePaper`] | (4.17) as printed, extrapolated like `Large` | nothing (heavy defect) |
//! | [`Method::UnknownMass`] | (4.7) at several `s`, mass fitted | nothing |
//!
//! # Resolvability
//!
//! The relative defect signal decays like `s^{-4(j-1)}` (docs/paper-notes.md): a deep or
//! light defect is invisible at large `s` in `f64`, while small `s` still sees it.
//! Each datum gets an [`Estimate`] with a [`Status`] (`BelowFloor` when the
//! signal is under twice the error floor, never NaN); [`locate`] with
//! [`SChoice::Auto`] takes the estimate with the smallest total uncertainty
//! `3 sigma + bias` and accepts it only if
//!
//! `|j - round(j)| + 3 sigma + bias < 1/2` and `1 <= round(j) <= n`,
//!
//! and every other accepted estimate rounds to the same position; otherwise it
//! returns [`Error::Unresolvable`] saying why. `bias` is the model error: 0 for
//! the exact relations, the distance to the exact locator for (4.10), and the
//! misfit of the `1/lambda` extrapolation at a third `s` for (4.17).
//!
//! # Data sources
//!
//! [`LaplaceData`] holds `X_1(s)` with an absolute error per `s`:
//! [`LaplaceData::from_chain`] (exact closed form, rounding only),
//! [`LaplaceData::from_simulation`] (simulated `x_1(t)`, Laplace-transformed),
//! [`LaplaceData::from_transform`] (any sampled series through
//! [`crate::time::series`], with its discretisation, truncation, rounding and
//! noise estimates), or [`LaplaceData::new`] / [`LaplaceData::from_f64`] for
//! tabulated values.
//!
//! # Precision
//!
//! Everything is generic over [`RealScalar`]: `f64`, or
//! [`crate::precision::BigReal`] at any number of bits (build the data in the
//! same type, e.g. [`LaplaceData::from_chain`]).
//!
//! ```
//! use springmass::{Chain, Defect};
//! use springmass::detect::locate::{locate, default_grid, LaplaceData, Method, Model, SChoice};
//! let chain = Chain::paper(20)?.with_defect(Defect::Mass { at: 15, m: 1.01 })?;
//! let data = LaplaceData::<f64>::from_chain(&chain, &default_grid())?;
//! let model = Model::from_chain(&chain);
//! let loc = locate(&model, &data, Method::Exact { m: 1.01 }, SChoice::Auto)?;
//! assert_eq!(loc.position, 15);
//! assert!(loc.sigma < 1e-3);
//! # Ok::<(), springmass::Error>(())
//! ```

pub mod data;
mod known;
mod large;
pub mod model;
pub mod solve;
mod unknown;

pub use data::{default_grid, LaplaceData, Point};
pub use model::{AtS, Model};

use crate::error::{Error, Result};
use crate::precision::RealScalar;

/// Which relation to solve for `j`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Method {
    /// Known defect mass `m`, exact relation (4.7).
    Exact {
        /// The defect's mass.
        m: f64,
    },
    /// Known defect mass `m`, the paper's asymptotic relation (4.10).
    Asymptotic {
        /// The defect's mass.
        m: f64,
    },
    /// Heavy defect of unknown mass: (4.17) rewritten without the extra
    /// cancellation, bias removed by extrapolation in `1/lambda`.
    Large,
    /// Heavy defect of unknown mass: (4.17) exactly as printed.
    LargePaper,
    /// Unknown mass: (4.7) at two or more `s`, the mass fitted.
    UnknownMass,
}

impl Method {
    /// The locator named `name` (`exact`, `asymptotic`, `large`,
    /// `large-paper`, `unknown-mass`); `m()` gives the known defect mass that
    /// `exact` and `asymptotic` need (called only for them).
    ///
    /// # Errors
    /// An unknown name (field `method`); the error of `m()`.
    pub fn from_name(name: &str, m: impl FnOnce() -> Result<f64>) -> Result<Method> {
        Ok(match name {
            "exact" => Method::Exact { m: m()? },
            "asymptotic" => Method::Asymptotic { m: m()? },
            "large" => Method::Large,
            "large-paper" => Method::LargePaper,
            "unknown-mass" => Method::UnknownMass,
            other => {
                return Err(Error::invalid(
                    "method",
                    other,
                    "exact, asymptotic, large, large-paper or unknown-mass",
                ))
            }
        })
    }

    /// Short name (`exact`, `asymptotic`, `large`, `large-paper`, `unknown-mass`).
    pub fn name(&self) -> &'static str {
        match self {
            Method::Exact { .. } => "exact",
            Method::Asymptotic { .. } => "asymptotic",
            Method::Large => "large",
            Method::LargePaper => "large-paper",
            Method::UnknownMass => "unknown-mass",
        }
    }

    fn check<T: RealScalar>(&self, model: &Model<T>) -> Result<()> {
        if let Method::Exact { m } | Method::Asymptotic { m } = *self {
            if !(m.is_finite() && m > 0.0) {
                return Err(Error::invalid("m", m, "m > 0 and finite"));
            }
            if m == model.mass().to_f64() {
                return Err(Error::invalid(
                    "m",
                    m,
                    "m != the uniform mass (a defect must differ from its neighbours)",
                ));
            }
        }
        Ok(())
    }
}

/// Where to evaluate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SChoice {
    /// Choose the `s` with the smallest uncertainty among the data.
    Auto,
    /// Use the datum at this `s` (for the large-defect methods, also the two
    /// data just below it, for the extrapolation).
    At(f64),
}

/// What happened at one `s`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Status {
    /// A position was found.
    Ok,
    /// The defect signal is below twice the error floor: the defect is too deep
    /// or too light to see at this `s` with this data/precision.
    BelowFloor,
    /// The signal has the wrong sign for the assumed mass (lighter vs heavier
    /// than the uniform mass, or `X_1 > e^{-lambda}/k` for a heavy defect).
    WrongSign,
    /// The relation has no solution with `1/2 <= j <= n + 1/2`.
    OutOfRange,
    /// Several solutions.
    Ambiguous,
    /// The formula as printed returned NaN or infinity.
    NonFinite,
}

impl Status {
    /// Short name.
    pub fn name(&self) -> &'static str {
        match self {
            Status::Ok => "ok",
            Status::BelowFloor => "below-floor",
            Status::WrongSign => "wrong-sign",
            Status::OutOfRange => "out-of-range",
            Status::Ambiguous => "ambiguous",
            Status::NonFinite => "non-finite",
        }
    }
}

/// The locator's answer at one `s`.
#[derive(Clone, Debug)]
pub struct Estimate<T> {
    /// The Laplace variable.
    pub s: f64,
    /// `lambda(s)`.
    pub lambda: f64,
    /// Real position (when a relation could be solved).
    pub j: Option<T>,
    /// Standard uncertainty of `j` from the data error and rounding.
    pub sigma: f64,
    /// Model error of the relation (0 for exact relations).
    pub bias: f64,
    /// Relative defect signal (`|D| / G_11`; for (4.17), `delta / e^{-lambda}`).
    pub signal: f64,
    /// Error floor on the same scale as `signal`.
    pub floor: f64,
    /// Outcome.
    pub status: Status,
}

impl<T: RealScalar> Estimate<T> {
    pub(crate) fn empty(at: &AtS<T>) -> Estimate<T> {
        Estimate {
            s: at.s.to_f64(),
            lambda: at.lambda.to_f64(),
            j: None,
            sigma: f64::INFINITY,
            bias: 0.0,
            signal: 0.0,
            floor: 0.0,
            status: Status::BelowFloor,
        }
    }

    /// `j` as `f64` (NaN when there is none).
    pub fn j_f64(&self) -> f64 {
        self.j.as_ref().map(|j| j.to_f64()).unwrap_or(f64::NAN)
    }

    /// `3 sigma + bias`.
    pub fn total(&self) -> f64 {
        3.0 * self.sigma + self.bias
    }
}

/// A resolved location.
#[derive(Clone, Debug)]
pub struct Location<T> {
    /// The method used.
    pub method: Method,
    /// Number of masses.
    pub n: usize,
    /// Real position (for the large-defect methods: extrapolated).
    pub j: T,
    /// `round(j)`, in `1..=n`.
    pub position: usize,
    /// The `s` of the estimate (the largest one used).
    pub s: f64,
    /// Standard uncertainty of `j`.
    pub sigma: f64,
    /// Model error bound.
    pub bias: f64,
    /// Estimated defect mass (unknown-mass and large-defect methods).
    pub mass: Option<f64>,
    /// `j(s)` before extrapolation (large-defect methods: the paper's number).
    pub raw_j: Option<T>,
    /// Every `s` the answer depends on.
    pub used: Vec<f64>,
}

impl<T: RealScalar> Location<T> {
    /// Accept the location only if its rounding is certain.
    ///
    /// # Errors
    /// [`Error::Unresolvable`] when `|j - round(j)| + 3 sigma + bias >= 1/2`
    /// or `round(j)` is outside `1..=n`.
    pub fn check(mut self) -> Result<Location<T>> {
        let jf = self.j.to_f64();
        let total = 3.0 * self.sigma + self.bias;
        let pos = jf.round();
        if !(jf.is_finite() && total.is_finite()) {
            return Err(Error::Unresolvable {
                reason: format!(
                    "{} locator at s = {}: no finite estimate (defect too deep or too light to see at this precision)",
                    self.method.name(),
                    self.s
                ),
            });
        }
        if (jf - pos).abs() + total >= 0.5 || pos < 1.0 || pos > self.n as f64 {
            return Err(Error::Unresolvable {
                reason: format!(
                    "{} locator: best estimate j = {jf:.6} +- {:.3} (3 sigma) + {:.3} (model error) at s = {:.4}: the nearest integer is not certain",
                    self.method.name(),
                    3.0 * self.sigma,
                    self.bias,
                    self.s
                ),
            });
        }
        self.position = pos as usize;
        Ok(self)
    }

    /// Number of correct significant digits implied by `sigma` (for reporting).
    pub fn digits(&self) -> f64 {
        (self.j.to_f64().abs() / self.sigma.max(f64::MIN_POSITIVE)).log10()
    }
}

/// Scan resolution for root isolation on `[1/2, n + 1/2]`.
pub(crate) fn scan_points(n: usize) -> usize {
    (4 * n + 8).min(256)
}

/// Root tolerance in `j`: a few units of the type's roundoff relative to `n`.
pub(crate) fn root_tol<T: RealScalar>(n: usize) -> f64 {
    (64.0 * T::epsilon() * (n as f64 + 1.0)).max(1e-290)
}

/// The estimate at one datum (no extrapolation, no acceptance test).
///
/// # Errors
/// Invalid `method` parameters; [`Method::UnknownMass`] has no per-point form.
pub fn estimate<T: RealScalar>(
    model: &Model<T>,
    point: &Point<T>,
    method: Method,
) -> Result<Estimate<T>> {
    method.check(model)?;
    Ok(match method {
        Method::Exact { m } => known::exact_point(model, point, &T::from_f64(m)),
        Method::Asymptotic { m } => known::asymptotic_point(model, point, &T::from_f64(m)),
        Method::Large => large::stable_point(model, point),
        Method::LargePaper => large::paper_point(model, point),
        Method::UnknownMass => {
            return Err(Error::invalid(
                "method",
                "unknown-mass",
                "a per-s method (exact, asymptotic, large, large-paper); the unknown-mass locator needs several s",
            ))
        }
    })
}

/// `j(s)` at every datum: the curves of the paper's Figures 11, 13 and 15.
/// For [`Method::UnknownMass`] the mass is fitted first and the curve is that
/// of the exact locator at the fitted mass.
///
/// # Errors
/// Invalid method parameters; for `UnknownMass`, an unresolvable fit.
pub fn curve<T: RealScalar>(
    model: &Model<T>,
    data: &LaplaceData<T>,
    method: Method,
) -> Result<Vec<Estimate<T>>> {
    let method = match method {
        Method::UnknownMass => {
            let fit = unknown::fit(model, data)?;
            Method::Exact {
                m: fit.mass.unwrap_or(f64::NAN),
            }
        }
        m => m,
    };
    data.points()
        .iter()
        .map(|p| estimate(model, p, method))
        .collect()
}

/// Locate the defect, choosing `s` automatically or at a given `s`.
///
/// # Errors
/// - [`Error::InvalidParameter`]: bad method parameters, or `SChoice::At(s)`
///   with no datum at `s` (or too few below it for the large-defect methods).
/// - [`Error::Unresolvable`]: no `s` in the data resolves the defect at this
///   precision and error level, or estimates at different `s` disagree.
pub fn locate<T: RealScalar>(
    model: &Model<T>,
    data: &LaplaceData<T>,
    method: Method,
    choice: SChoice,
) -> Result<Location<T>> {
    method.check(model)?;
    let n = model.n();
    if let Method::UnknownMass = method {
        if let SChoice::At(s) = choice {
            return Err(Error::invalid(
                "s",
                s,
                "auto for the unknown-mass locator (it uses every s in the data; restrict the data instead)",
            ));
        }
        return unknown::fit(model, data);
    }
    let pts = data.points();
    let est: Vec<Estimate<T>> = pts
        .iter()
        .map(|p| estimate(model, p, method))
        .collect::<Result<_>>()?;
    let large = matches!(method, Method::Large | Method::LargePaper);
    let ctx = Ctx {
        n,
        mass: model.mass().to_f64(),
        d: model.d().to_f64(),
        k: model.k().to_f64(),
    };
    let candidates: Vec<Location<T>> = match choice {
        SChoice::At(s) => {
            let i = data.find(s).ok_or_else(|| {
                Error::invalid(
                    "s",
                    s,
                    format!("one of the data's s values ({})", data.label()),
                )
            })?;
            if large {
                if i < 2 {
                    return Err(Error::invalid(
                        "s",
                        s,
                        "an s with two smaller s in the data (the large-defect locator extrapolates from three s)",
                    ));
                }
                vec![extrapolate(
                    method,
                    &ctx,
                    &est[i - 2],
                    &est[i - 1],
                    &est[i],
                )?]
            } else {
                vec![single(method, n, &est[i])?]
            }
        }
        SChoice::Auto => {
            let mut c = Vec::new();
            if large {
                for i in 2..est.len() {
                    if let Ok(l) = extrapolate(method, &ctx, &est[i - 2], &est[i - 1], &est[i]) {
                        c.push(l);
                    }
                }
            } else {
                for e in &est {
                    if let Ok(l) = single(method, n, e) {
                        c.push(l);
                    }
                }
            }
            c
        }
    };
    if candidates.is_empty() {
        let best = est.iter().filter(|e| e.signal > 0.0).max_by(|a, b| {
            (a.signal / a.floor.max(f64::MIN_POSITIVE))
                .partial_cmp(&(b.signal / b.floor.max(f64::MIN_POSITIVE)))
                .unwrap_or(std::cmp::Ordering::Equal)
        });
        let detail = match best {
            Some(e) => format!(
                "; strongest defect signal {:.2e} (relative) against an error floor {:.2e} at s = {:.4} ({})",
                e.signal,
                e.floor,
                e.s,
                e.status.name()
            ),
            None => String::new(),
        };
        return Err(Error::Unresolvable {
            reason: format!(
                "{} locator: no s in the data ({} points, {}) gives a usable estimate: defect too deep or too light to see at this precision{detail}",
                method.name(),
                pts.len(),
                data.label()
            ),
        });
    }
    let best = candidates
        .iter()
        .min_by(|a, b| {
            (3.0 * a.sigma + a.bias)
                .partial_cmp(&(3.0 * b.sigma + b.bias))
                .unwrap_or(std::cmp::Ordering::Equal)
        })
        .cloned()
        .expect("non-empty");
    let accepted = best.check()?;
    // every other confident estimate must round to the same position
    for c in &candidates {
        let jf = c.j.to_f64();
        if 3.0 * c.sigma + c.bias + (jf - jf.round()).abs() < 0.5
            && jf.round() as usize != accepted.position
        {
            return Err(Error::Unresolvable {
                reason: format!(
                    "{} locator: confident estimates disagree (j = {:.4} at s = {:.4}, j = {:.4} at s = {:.4}): the data do not fit a single defect of this kind",
                    method.name(),
                    accepted.j.to_f64(),
                    accepted.s,
                    jf,
                    c.s
                ),
            });
        }
    }
    Ok(accepted)
}

fn single<T: RealScalar>(method: Method, n: usize, e: &Estimate<T>) -> Result<Location<T>> {
    match (&e.j, e.status) {
        (Some(j), Status::Ok) => Ok(Location {
            method,
            n,
            j: j.clone(),
            position: 0,
            s: e.s,
            sigma: e.sigma,
            bias: e.bias,
            mass: None,
            raw_j: None,
            used: vec![e.s],
        }),
        _ => Err(unresolved(method, e)),
    }
}

/// An estimate that is not a location: its status, signal and floor in words.
fn unresolved<T: RealScalar>(method: Method, e: &Estimate<T>) -> Error {
    Error::Unresolvable {
        reason: format!(
            "{} locator at s = {}: {} (relative defect signal {:.2e}, error floor {:.2e})",
            method.name(),
            e.s,
            e.status.name(),
            e.signal,
            e.floor
        ),
    }
}

/// Chain constants the extrapolation's error model needs.
struct Ctx {
    n: usize,
    mass: f64,
    d: f64,
    k: f64,
}

/// Remove the heavy-defect bias `j(s) = j + L/(2 lambda)` with two values of
/// `s` (`b`, `c`) and check the model at a third (`a`).
fn extrapolate<T: RealScalar>(
    method: Method,
    ctx: &Ctx,
    a: &Estimate<T>,
    b: &Estimate<T>,
    c: &Estimate<T>,
) -> Result<Location<T>> {
    let get = |e: &Estimate<T>| match (&e.j, e.status) {
        (Some(j), Status::Ok) => Ok(j.clone()),
        _ => Err(unresolved(method, e)),
    };
    let (ja, jb, jc) = (get(a)?, get(b)?, get(c)?);
    let (ia, ib, ic) = (1.0 / a.lambda, 1.0 / b.lambda, 1.0 / c.lambda);
    let w = ib - ic;
    if w <= 0.0 {
        return Err(Error::Unresolvable {
            reason: "extrapolation needs increasing s".into(),
        });
    }
    // slope A = (jb - jc)/(ib - ic) and intercept, in T for extended precision
    let slope = (jb.clone() - jc.clone()) / T::from_f64(w);
    let jinf = jc.clone() - slope.clone() * T::from_f64(ic);
    let pred = jinf.clone() + slope.clone() * T::from_f64(ia);
    let resid = (ja - pred).abs().to_f64();
    let sigma = (c.sigma * ib + b.sigma * ic) / w;
    let l = 2.0 * slope.to_f64();
    if l < -3.0 * sigma / ic.max(f64::MIN_POSITIVE) && l < -1e-12 {
        return Err(Error::Unresolvable {
            reason: format!(
                "{} locator: j(s) approaches from below (L = {l:.3e} < 0): not a heavy defect",
                method.name()
            ),
        });
    }
    let mass = if l > 0.0 {
        Some(ctx.mass / -(-l).exp_m1())
    } else {
        None
    };
    // Relative size of the terms the 1/lambda model neglects at the smallest s:
    // 1 + c G_jj = (m s^2 + d s + 2k) / (mass s^2 + d s + 2k) deviates from
    // m / mass by O((d s + 2k) / (mass s^2)).
    let eps = (ctx.d * a.s + 2.0 * ctx.k) / (ctx.mass * a.s * a.s);
    let first_order = (jc.clone() - jinf.clone()).abs().to_f64();
    let n = ctx.n;
    Ok(Location {
        method,
        n,
        j: jinf,
        position: 0,
        s: c.s,
        sigma,
        bias: resid + 2.0 * eps * first_order,
        mass,
        raw_j: Some(jc),
        used: vec![a.s, b.s, c.s],
    })
}
