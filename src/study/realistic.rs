//! Records as they come off a real test, generated independently of the
//! fit's model: the deviations of issue-style realism studies (damping that
//! is not the paper's, coloured noise, a sensor offset and drift, a blow
//! that is not at the record's start) on any chain.
//!
//! **Independent of the fit's code path.** The record is the dense
//! state-space solution `z' = A z`, `A = [[0, I], [-M^-1 K, -M^-1 C]]`,
//! `z(0+) = (0, gamma/m_1 e_1)`, propagated exactly by the matrix
//! exponential (`nalgebra`'s Pade scaling-and-squaring) from sample to
//! sample; `M`, `K` and `C` are assembled here densely from the chain's
//! masses, springs and dampers and the damping model's definition (Rayleigh
//! `C = a M + b K`, dampers between neighbours `c` times the springs'
//! Laplacian, modal `C = M Phi diag(2 zeta omega) Phi^T M` from `nalgebra`'s
//! symmetric eigensolver). The fit computes its model by modal sums, Woodbury updates of
//! the closed-form Green's function, or sparse stepping: none of that is
//! used here.
//!
//! ```
//! use springmass::study::realistic::{record, Colour, Deviations, Damping};
//! let chain = springmass::scenes::by_name("S3")?;
//! let dev = Deviations { damping: Damping::Rayleigh { a: 0.05, b: 0.05 }, colour: Colour::Ar1(0.9), ..Deviations::default() };
//! let (t, x) = record(&chain, &dev, 200.0, 0.2, 1e-3, 7)?;
//! assert_eq!((t.len(), x.len()), (1001, 1001));
//! # Ok::<(), springmass::Error>(())
//! ```

use crate::chain::Chain;
use crate::error::{Error, Result};
use nalgebra::{DMatrix, DVector};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// How the chain is damped in the record.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Damping {
    /// The chain's own dampers to the ground (the paper's model).
    Grounded,
    /// `C = a M + b K` (no grounded dampers).
    Rayleigh {
        /// Mass-proportional coefficient.
        a: f64,
        /// Stiffness-proportional coefficient.
        b: f64,
    },
    /// A damper `c` parallel to every spring (walls included), none to the
    /// ground: a building's storeys.
    Between {
        /// Damping of each storey.
        c: f64,
    },
    /// Every undamped mode damped with its ratio, no grounded dampers.
    Modal {
        /// The damping ratios of modes 1, 2 and of modes 3 and higher.
        zeta: [f64; 3],
    },
}

/// The colour of the sensor noise.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Colour {
    /// Independent samples.
    White,
    /// `e_i = rho e_{i-1} + w_i`, stationary.
    Ar1(f64),
}

/// What differs from the paper's idealised record.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Deviations {
    /// The damping model.
    pub damping: Damping,
    /// The noise's colour (its standard deviation is the record's level).
    pub colour: Colour,
    /// A constant sensor offset, relative to the record's peak.
    pub offset: f64,
    /// A linear drift reaching this much of the peak at the record's end.
    pub drift: f64,
    /// The blow's time on the record's axis (the record starts at
    /// `start`; samples before the blow are the chain at rest).
    pub blow: f64,
    /// The record's first time.
    pub start: f64,
}

impl Default for Deviations {
    fn default() -> Self {
        Deviations {
            damping: Damping::Grounded,
            colour: Colour::White,
            offset: 0.0,
            drift: 0.0,
            blow: 0.0,
            start: 0.0,
        }
    }
}

impl Deviations {
    /// A named deviation, as the realism study sweeps them: `none`,
    /// `rayleigh`, `between`, `modal` (every mode's ratio 2%), `modal-modes`
    /// (ratios 1%, 3% and 2% for modes 1, 2 and the rest), `ar1-0.9`, `ar1-0.99`, `offset-drift`,
    /// `pre-trigger` (10 time units at rest before the blow), `late-clock`
    /// (an axis that reads 12.4 at the first sample, the blow at 12.53).
    /// Time-like values are in units of `time_unit` (the period scale
    /// `sqrt(mass / k)` of the chain).
    ///
    /// Several joined by `+` combine (`rayleigh+ar1-0.9+offset-drift`):
    /// each part sets what it names, and no two parts may set the same
    /// thing (the damping, the colour, the offset and drift, the blow).
    ///
    /// # Errors
    /// An unknown name (field `deviation`, listing the names); two parts
    /// that set the same thing (field `deviation`).
    pub fn named(name: &str, time_unit: f64) -> Result<Deviations> {
        if name.contains('+') {
            return Self::combined(name, time_unit);
        }
        Self::one(name.trim(), time_unit)
    }

    /// The parts of `name` joined by `+`, each set once.
    fn combined(name: &str, time_unit: f64) -> Result<Deviations> {
        let d = Deviations::default();
        let mut out = d;
        let mut set: Vec<(&str, &str)> = Vec::new();
        for part in name.split('+').map(str::trim) {
            let p = Self::one(part, time_unit)?;
            let aspects = [
                ("damping", p.damping != d.damping),
                ("noise colour", p.colour != d.colour),
                (
                    "offset and drift",
                    p.offset != d.offset || p.drift != d.drift,
                ),
                ("blow time", p.blow != d.blow || p.start != d.start),
            ];
            for (aspect, _) in aspects.iter().filter(|(_, on)| *on) {
                if let Some((_, first)) = set.iter().find(|(a, _)| a == aspect) {
                    return Err(Error::invalid(
                        "deviation",
                        name,
                        format!("parts that set different things: {first} and {part} both set the {aspect}"),
                    ));
                }
                set.push((aspect, part));
            }
            if p.damping != d.damping {
                out.damping = p.damping;
            }
            if p.colour != d.colour {
                out.colour = p.colour;
            }
            if p.offset != d.offset || p.drift != d.drift {
                (out.offset, out.drift) = (p.offset, p.drift);
            }
            if p.blow != d.blow || p.start != d.start {
                (out.blow, out.start) = (p.blow, p.start);
            }
        }
        Ok(out)
    }

    /// One named deviation.
    fn one(name: &str, time_unit: f64) -> Result<Deviations> {
        let d = Deviations::default();
        Ok(match name {
            "none" => d,
            "rayleigh" => Deviations {
                damping: Damping::Rayleigh {
                    a: 0.05 / time_unit,
                    b: 0.05 * time_unit,
                },
                ..d
            },
            "between" => Deviations {
                damping: Damping::Between { c: 0.1 },
                ..d
            },
            "modal" => Deviations {
                damping: Damping::Modal { zeta: [0.02; 3] },
                ..d
            },
            "modal-modes" => Deviations {
                damping: Damping::Modal {
                    zeta: [0.01, 0.03, 0.02],
                },
                ..d
            },
            "ar1-0.9" => Deviations {
                colour: Colour::Ar1(0.9),
                ..d
            },
            "ar1-0.99" => Deviations {
                colour: Colour::Ar1(0.99),
                ..d
            },
            "offset-drift" => Deviations {
                offset: 0.02,
                drift: 0.01,
                ..d
            },
            "pre-trigger" => Deviations {
                blow: 10.07 * time_unit,
                ..d
            },
            "late-clock" => Deviations {
                blow: 12.53 * time_unit,
                start: 12.4 * time_unit,
                ..d
            },
            _ => return Err(Error::invalid("deviation", name, NAMES.join(", "))),
        })
    }
}

/// The named deviations of [`Deviations::named`].
pub const NAMES: &[&str] = &[
    "none",
    "rayleigh",
    "between",
    "modal",
    "modal-modes",
    "ar1-0.9",
    "ar1-0.99",
    "offset-drift",
    "pre-trigger",
    "late-clock",
];

/// Dense `M`, `K`, `C` of `chain` under `damping`.
fn matrices(chain: &Chain, damping: Damping) -> (DMatrix<f64>, DMatrix<f64>, DMatrix<f64>) {
    let n = chain.n();
    let (m, k, g) = (chain.masses(), chain.springs(), chain.grounds());
    let laplacian = |w: &[f64]| {
        DMatrix::from_fn(n, n, |i, j| {
            if i == j {
                w[i] + w[i + 1]
            } else if i + 1 == j {
                -w[j]
            } else if j + 1 == i {
                -w[i]
            } else {
                0.0
            }
        })
    };
    let mm = DMatrix::from_diagonal(&DVector::from_vec(m));
    let kk = laplacian(&k) + DMatrix::from_diagonal(&DVector::from_vec(g));
    let cc = match damping {
        Damping::Grounded => DMatrix::from_diagonal(&DVector::from_vec(chain.dampers())),
        Damping::Rayleigh { a, b } => &mm * a + &kk * b,
        Damping::Between { c } => {
            let mut w = vec![c; n + 1];
            let free = chain.springs();
            for (wi, ki) in w.iter_mut().zip(&free) {
                if *ki == 0.0 {
                    *wi = 0.0; // a free end has no storey below it
                }
            }
            laplacian(&w)
        }
        Damping::Modal { zeta } => {
            // M^-1/2 K M^-1/2 = Q diag(omega^2) Q^T, Phi = M^-1/2 Q
            let mh = DMatrix::from_diagonal(&mm.diagonal().map(|v| 1.0 / v.sqrt()));
            let eig = (&mh * &kk * &mh).symmetric_eigen();
            let phi = &mh * &eig.eigenvectors;
            // each mode's ratio by the rank of its frequency
            let mut rank: Vec<usize> = (0..n).collect();
            rank.sort_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]));
            let mut w = eig.eigenvalues.clone();
            for (r, &i) in rank.iter().enumerate() {
                w[i] = 2.0 * zeta[r.min(2)] * eig.eigenvalues[i].max(0.0).sqrt();
            }
            &mm * &phi * DMatrix::from_diagonal(&w) * phi.transpose() * &mm
        }
    };
    (mm, kk, cc)
}

/// The record of mass 1's displacement at `start, start + dt, ...` up to
/// `start + t_end`, with the deviations, and noise of standard deviation
/// `level` times the clean record's peak drawn with `seed`. Returns the
/// times and the values.
///
/// # Errors
/// `t_end`, `dt` or `level` out of range (fields named), more than 10^6
/// samples or a chain of more than 400 masses (field `n`: the state space
/// is dense).
pub fn record(
    chain: &Chain,
    dev: &Deviations,
    t_end: f64,
    dt: f64,
    level: f64,
    seed: u64,
) -> Result<(Vec<f64>, Vec<f64>)> {
    crate::error::check_f64("dt", dt, dt > 0.0, "> 0")?;
    crate::error::check_f64(
        "t_end",
        t_end,
        t_end > 0.0 && t_end / dt <= 1e6,
        "> 0, at most 1e6 samples",
    )?;
    crate::error::check_f64("level", level, (0.0..=1.0).contains(&level), "in [0, 1]")?;
    if chain.n() > 400 {
        return Err(Error::invalid(
            "n",
            chain.n(),
            "<= 400 (a dense state space)",
        ));
    }
    let t: Vec<f64> = (0..=(t_end / dt).round() as usize)
        .map(|i| dev.start + dt * i as f64)
        .collect();
    let clean = clean_record(chain, dev.damping, &t, dev.blow, dt);
    let peak = clean.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let noise = coloured_noise(t.len(), dev.colour, level * peak, seed);
    let x = t
        .iter()
        .zip(&clean)
        .zip(&noise)
        .map(|((&ti, c), e)| c + e + peak * (dev.offset + dev.drift * (ti - dev.start) / t_end))
        .collect();
    Ok((t, x))
}

/// Mass 1's displacement at times `t` (uniform step `dt`) after a blow at
/// `blow`, zero before it.
fn clean_record(chain: &Chain, damping: Damping, t: &[f64], blow: f64, dt: f64) -> Vec<f64> {
    let n = chain.n();
    let (mm, kk, cc) = matrices(chain, damping);
    let minv = DMatrix::from_diagonal(&mm.diagonal().map(|v| 1.0 / v));
    let mut a = DMatrix::zeros(2 * n, 2 * n);
    a.view_mut((0, n), (n, n)).fill_with_identity();
    a.view_mut((n, 0), (n, n)).copy_from(&(-(&minv * &kk)));
    a.view_mut((n, n), (n, n)).copy_from(&(-(&minv * &cc)));
    let step = (&a * dt).exp();
    let mut z0 = DVector::zeros(2 * n);
    z0[n] = chain.gamma() / mm[(0, 0)];
    let mut out = vec![0.0; t.len()];
    let Some(first) = t.iter().position(|&v| v >= blow) else {
        return out;
    };
    let mut z = (&a * (t[first] - blow)).exp() * z0;
    for o in out.iter_mut().skip(first) {
        *o = z[0];
        z = &step * z;
    }
    out
}

/// `len` samples of zero-mean noise of standard deviation `sigma`.
fn coloured_noise(len: usize, colour: Colour, sigma: f64, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut z = || -> f64 { StandardNormal.sample(&mut rng) };
    match colour {
        Colour::White => (0..len).map(|_| sigma * z()).collect(),
        Colour::Ar1(rho) => {
            let w = sigma * (1.0 - rho * rho).sqrt();
            let mut e = sigma * z();
            (0..len)
                .map(|_| {
                    let out = e;
                    e = rho * e + w * z();
                    out
                })
                .collect()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::time::modal::ModalResponse;

    #[test]
    fn the_paper_record_matches_the_modal_sum() {
        // the one case both methods share: grounded damping, white, at 0
        let chain = crate::scenes::mixed(7).unwrap();
        let (t, x) = record(&chain, &Deviations::default(), 60.0, 0.1, 0.0, 1).unwrap();
        let u = ModalResponse::impulse(&chain, 1).unwrap();
        let peak = x.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        for (ti, xi) in t.iter().zip(&x) {
            assert!((u.eval(*ti) - xi).abs() < 1e-10 * peak, "t {ti}");
        }
    }

    #[test]
    fn rayleigh_with_proportional_coefficients_is_grounded_damping() {
        // on a uniform-mass chain without spring changes, C = a M is the
        // grounded d = a m
        let chain = Chain::paper(6).unwrap().with_d(0.2).unwrap();
        let ray = Deviations {
            damping: Damping::Rayleigh { a: 0.2, b: 0.0 },
            ..Deviations::default()
        };
        let (_, a) = record(&chain, &ray, 30.0, 0.1, 0.0, 1).unwrap();
        let (_, b) = record(&chain, &Deviations::default(), 30.0, 0.1, 0.0, 1).unwrap();
        for (p, q) in a.iter().zip(&b) {
            assert!((p - q).abs() < 1e-12);
        }
    }

    #[test]
    fn deviations_do_what_they_say() {
        let chain = crate::scenes::by_name("S1").unwrap();
        let late = Deviations::named("pre-trigger", 1.0).unwrap();
        let (t, x) = record(&chain, &late, 50.0, 0.2, 0.0, 1).unwrap();
        assert!(x.iter().zip(&t).all(|(v, ti)| *ti >= 10.07 || *v == 0.0));
        assert!(x[51] > 0.0);
        let od = Deviations::named("offset-drift", 1.0).unwrap();
        let (_, y) = record(&chain, &od, 50.0, 0.2, 0.0, 1).unwrap();
        let (_, y0) = record(&chain, &Deviations::default(), 50.0, 0.2, 0.0, 1).unwrap();
        let peak = y0.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        assert!((y[0] - y0[0] - 0.02 * peak).abs() < 1e-12);
        assert!((y[250] - y0[250] - 0.03 * peak).abs() < 1e-12);
        // AR(1) noise: lag-1 correlation near rho
        let e = coloured_noise(20000, Colour::Ar1(0.9), 1.0, 3);
        let r1: f64 =
            e.windows(2).map(|w| w[0] * w[1]).sum::<f64>() / e.iter().map(|v| v * v).sum::<f64>();
        assert!((r1 - 0.9).abs() < 0.02, "{r1}");
        // parts joined by `+` combine; two that set the same thing do not
        let both = Deviations::named("rayleigh + ar1-0.9+offset-drift", 2.0).unwrap();
        let ray = Deviations::named("rayleigh", 2.0).unwrap();
        assert_eq!(both.damping, ray.damping);
        assert_eq!(both.colour, Colour::Ar1(0.9));
        assert_eq!((both.offset, both.drift), (od.offset, od.drift));
        assert_eq!((both.blow, both.start), (0.0, 0.0));
        let e = Deviations::named("rayleigh+modal", 1.0)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("deviation") && e.contains("both set the damping"),
            "{e}"
        );
        assert!(Deviations::named("pre-trigger+late-clock", 1.0).is_err());
        assert!(Deviations::named("none+wobbly", 1.0).is_err());
        assert!(Deviations::named("wobbly", 1.0)
            .unwrap_err()
            .to_string()
            .contains("rayleigh"));
        // modal, one ratio and a ratio per mode: the dense record is the
        // library's modal sum of the chain with the modal damping model (two
        // independent paths)
        for (name, zeta) in [
            ("modal", vec![0.02]),
            ("modal-modes", vec![0.01, 0.03, 0.02]),
        ] {
            let dev = Deviations::named(name, 1.0).unwrap();
            let (t, x) = record(&chain, &dev, 100.0, 0.25, 0.0, 1).unwrap();
            let lib = chain
                .clone()
                .with_d(0.0)
                .unwrap()
                .with_damping(crate::chain::Damping::Modal { zeta })
                .unwrap();
            let want = crate::time::modal::ModalResponse::impulse(&lib, 1)
                .unwrap()
                .eval_many(&t);
            let peak = want.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            for (g, w) in x.iter().zip(&want) {
                assert!((g - w).abs() < 1e-10 * peak, "{name}: {g} vs {w}");
            }
        }
    }
}
