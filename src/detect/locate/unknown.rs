//! Unknown mass: the exact relation (4.7) at several `s` fixes both `j` and `m`.
//!
//! For a trial mass `m` every datum gives a position `j_i(m)` (the exact
//! known-mass locator); the true mass is the one at which they agree. With
//! weights `w_i = 1 / sigma_i^2` the misfit
//!
//! `Phi(m) = sum_i w_i (j_i(m) - jbar(m))^2`, `jbar = sum w_i j_i / sum w_i`
//!
//! is a chi-square in one parameter, minimised over `t = ln|ln(m / mass)|`
//! (so that both `m = 1.01` and `m = 100` are well resolved) by a scan and a
//! golden-section search. The side `m > mass` or `m < mass` is read from the
//! sign of the defect signal. The uncertainty of `jbar` combines the weighted
//! mean's and that of the mass (from the curvature of `Phi`).

use super::data::LaplaceData;
use super::known::signal;
use super::model::Model;
use super::solve::{golden, near, roots};
use super::{root_tol, scan_points, Location, Method};
use crate::error::{Error, Result};
use crate::precision::RealScalar;

/// Minimum signal-to-floor ratio of a datum used by the fit.
const MIN_SNR: f64 = 1e3;
/// At most this many data are used (spread over the usable range of `s`).
const MAX_POINTS: usize = 8;

/// A usable datum. Only `D` needs the working precision; the fit itself runs
/// in `f64` on `ln|D|` (well conditioned, see `known::solve_at`).
struct Datum {
    at: super::model::AtS<f64>,
    ln_d: f64,
    rel: f64,
    s: f64,
}

pub(crate) fn fit<T: RealScalar>(model: &Model<T>, data: &LaplaceData<T>) -> Result<Location<T>> {
    let n = model.n();
    let (picked, heavy) = usable_data(model, data)?;
    let trial = Trial {
        picked: &picked,
        heavy,
        mass: model.mass().to_f64(),
        tol: root_tol::<f64>(n),
        hi: n as f64 + 0.5,
        n,
    };
    let mut guess = vec![f64::NAN; picked.len()];
    // t = ln|u|, u = ln(m / mass): |u| from 1e-7 to 25 (heavy: m up to 7e10 mass;
    // light: m down to 1.4e-11 mass)
    let (t0, t1) = (1e-7f64.ln(), 25f64.ln());
    let k = 60;
    let ts: Vec<f64> = (0..=k)
        .map(|i| t0 + (t1 - t0) * i as f64 / k as f64)
        .collect();
    let phis: Vec<f64> = ts.iter().map(|&t| trial.phi(t, &mut guess)).collect();
    let (ib, _) =
        phis.iter().enumerate().fold(
            (0, f64::INFINITY),
            |acc, (i, &p)| if p < acc.1 { (i, p) } else { acc },
        );
    if !phis[ib].is_finite() {
        return Err(Error::Unresolvable {
            reason: "unknown-mass locator: no trial mass places the defect inside 1..n at every usable s".into(),
        });
    }
    let a = ts[ib.saturating_sub(1)];
    let b = ts[(ib + 1).min(k)];
    let mut g2 = vec![f64::NAN; picked.len()];
    let _ = trial.positions(ts[ib], &mut g2);
    let (tb, _) = golden(|t| trial.phi(t, &mut g2), a, b, 50);
    let js = trial
        .positions(tb, &mut g2)
        .ok_or_else(|| Error::Unresolvable {
            reason: "unknown-mass locator: the fit left the range 1..n".into(),
        })?;
    let (mean, phi, sw) = stats(&js);
    let sigma = trial.sigma(tb, &g2, phi, sw);
    let bias = (phi / sw).sqrt();
    let m = trial.mass_of(tb);
    let s_used: Vec<f64> = picked.iter().map(|d| d.s).collect();
    let last = *s_used.last().unwrap_or(&f64::NAN);
    Location {
        method: Method::UnknownMass,
        n,
        j: T::from_f64(mean),
        position: mean.round().max(0.0) as usize,
        s: last,
        sigma,
        bias,
        mass: Some(m),
        raw_j: None,
        used: s_used,
    }
    .check()
}

/// The data whose defect signal is above `MIN_SNR` times its error floor
/// (at most `MAX_POINTS`, spread over `s`), and whether the defect is
/// heavy (the signal's sign, the same at every datum).
fn usable_data<T: RealScalar>(
    model: &Model<T>,
    data: &LaplaceData<T>,
) -> Result<(Vec<Datum>, bool)> {
    let mut usable: Vec<(Datum, bool)> = Vec::new();
    let model64 = model.to_f64();
    for p in data.points() {
        let at = model.at(&p.s);
        let (d, floor) = signal(model, &at, p);
        let da = d.abs().to_f64();
        if da > MIN_SNR * floor && !d.is_zero() {
            let positive = d > T::zero();
            usable.push((
                Datum {
                    ln_d: d.ln_abs_f64(),
                    rel: floor / da,
                    s: p.s.to_f64(),
                    at: model64.at(&p.s.to_f64()),
                },
                positive,
            ));
        }
    }
    if usable.len() < 2 {
        return Err(Error::Unresolvable {
            reason: format!(
                "unknown-mass locator needs the defect signal above {MIN_SNR:.0e} times the error floor at two or more s; {} of {} points qualify (defect too deep or too light to see at this precision)",
                usable.len(),
                data.points().len()
            ),
        });
    }
    let heavy = usable.iter().filter(|u| u.1).count();
    if heavy != 0 && heavy != usable.len() {
        return Err(Error::Unresolvable {
            reason: "the defect signal changes sign with s: the data are not those of a single mass defect".into(),
        });
    }
    let heavy = heavy != 0;
    // spread over s
    let picked: Vec<Datum> = if usable.len() <= MAX_POINTS {
        usable.into_iter().map(|u| u.0).collect()
    } else {
        let k = usable.len();
        let idx: Vec<usize> = (0..MAX_POINTS)
            .map(|i| (i * (k - 1)) / (MAX_POINTS - 1))
            .collect();
        usable
            .into_iter()
            .enumerate()
            .filter(|(i, _)| idx.contains(i))
            .map(|(_, u)| u.0)
            .collect()
    };
    Ok((picked, heavy))
}

/// The one-parameter problem in `t = ln|ln(m / mass)|`.
struct Trial<'a> {
    picked: &'a [Datum],
    heavy: bool,
    mass: f64,
    tol: f64,
    /// The right end of the positions' range, `n + 0.5`.
    hi: f64,
    n: usize,
}

impl Trial<'_> {
    /// The trial mass at `t`.
    fn mass_of(&self, t: f64) -> f64 {
        let u = if self.heavy { t.exp() } else { -t.exp() };
        self.mass * u.exp()
    }

    /// The position of every datum for the trial mass at `t`, with its
    /// standard deviation; warm-started from the previous trial (`guess`).
    fn positions(&self, t: f64, guess: &mut [f64]) -> Option<Vec<(f64, f64)>> {
        let m = self.mass_of(t);
        let n = self.n;
        let mut out = Vec::with_capacity(self.picked.len());
        for (i, dm) in self.picked.iter().enumerate() {
            let c = dm.at.c(&m);
            let g = |j: &f64| dm.at.ln_f_exact(j, &c) - dm.ln_d;
            let j = if guess[i].is_finite() {
                near(&g, guess[i], 0.5, self.hi, scan_points(n), self.tol)
            } else {
                roots(&g, 0.5, self.hi, scan_points(n), self.tol)
                    .into_iter()
                    .next()
            }?;
            let jf = j;
            let h = 1e-4;
            let slope = ((dm.at.ln_f_exact(&(jf + h), &c) - dm.at.ln_f_exact(&(jf - h), &c))
                / (2.0 * h))
                .abs();
            guess[i] = jf;
            out.push((jf, dm.rel / slope.max(f64::MIN_POSITIVE)));
        }
        Some(out)
    }

    /// `Phi` at `t` (infinite where a datum has no position; the guesses
    /// are then reset).
    fn phi(&self, t: f64, guess: &mut [f64]) -> f64 {
        match self.positions(t, guess) {
            Some(js) => {
                let (_, phi, _) = stats(&js);
                if phi.is_finite() {
                    phi
                } else {
                    f64::INFINITY
                }
            }
            None => {
                guess.iter_mut().for_each(|g| *g = f64::NAN);
                f64::INFINITY
            }
        }
    }

    /// The standard deviation of `jbar` at the minimiser `tb` (where `Phi =
    /// phi` and the weights sum to `sw`): the weighted mean's combined with
    /// that of the mass, from the curvature of `Phi` in `t` and `d jbar / dt`.
    fn sigma(&self, tb: f64, guess: &[f64], phi: f64, sw: f64) -> f64 {
        let h = 1e-3;
        let jp = self.positions(tb + h, &mut guess.to_vec());
        let jm = self.positions(tb - h, &mut guess.to_vec());
        let (Some(jp), Some(jm)) = (jp, jm) else {
            return f64::INFINITY;
        };
        let sigma = (1.0 / sw).sqrt();
        let (mp, pp, _) = stats(&jp);
        let (mm, pm, _) = stats(&jm);
        let curv = (pp - 2.0 * phi + pm) / (h * h);
        let dj = (mp - mm) / (2.0 * h);
        let dt = if curv > 0.0 {
            (2.0 / curv).sqrt()
        } else {
            f64::INFINITY
        };
        (sigma * sigma + (dj * dt).powi(2)).sqrt()
    }
}

/// The weighted mean of positions `(j, sigma)`, their `Phi` and the sum of
/// the weights.
fn stats(js: &[(f64, f64)]) -> (f64, f64, f64) {
    let sw: f64 = js.iter().map(|&(_, s)| 1.0 / (s * s)).sum();
    let mean = js.iter().map(|&(j, s)| j / (s * s)).sum::<f64>() / sw;
    let phi = js
        .iter()
        .map(|&(j, s)| (j - mean).powi(2) / (s * s))
        .sum::<f64>();
    (mean, phi, sw)
}
