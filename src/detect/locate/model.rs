//! The single-mass-defect response written as a function of a *real*
//! position `j`, so that locators can solve for `j` continuously.
//!
//! With `q = exp(-lambda)`, `N = n + 1` and `E(p) = 1 - q^{2p}` (taken as
//! `-expm1(-2 p lambda)`, no cancellation), the uniform chain's Green's function
//! entries used by the paper's (4.7) are, for real `0 < j < N`,
//!
//! `G_11 = q E(n) / (k E(N))`,
//! `G_1j = q^j E(N-j) / (k E(N))`,
//! `G_jj = q E(j) E(N-j) / (k E(1) E(N))`,
//!
//! which agree with [`crate::green::Green`] at integer `j` (tested). A mass
//! defect `m` at `j` adds `c = (m - mass) s^2` at `(j, j)`, and
//!
//! `X_1 = gamma [G_11 - f(j)]`, `f(j) = c G_1j^2 / (1 + c G_jj)`    (4.7)
//!
//! (`f` is what a locator compares with the measured defect signal
//! `D = G_11 - X_1 / gamma`). Logarithms of `f` are formed term by term, so the
//! comparison `ln f(j) = ln D` has no overflow or underflow for any `n` or `s`.

use crate::chain::Chain;
use crate::error::{Error, Result};
use crate::precision::RealScalar;

/// The uniform chain `(n, k, mass, d, gamma)` in the number type `T`.
///
/// Parameters are carried in `T`, so a decimal parameter such as `d = 0.1`
/// can be represented to the working precision rather than as the nearest
/// `f64` (see [`crate::precision::RealScalar::parse_decimal`]).
#[derive(Clone, Debug)]
pub struct Model<T> {
    n: usize,
    k: T,
    mass: T,
    d: T,
    gamma: T,
}

impl<T: RealScalar> Model<T> {
    /// A validated model.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] for `n = 0`, `k <= 0`, `mass <= 0`, `d < 0`,
    /// `gamma = 0` or a non-finite value.
    pub fn new(n: usize, k: T, mass: T, d: T, gamma: T) -> Result<Model<T>> {
        if n == 0 || n >= (1usize << 52) {
            return Err(Error::invalid("n", n, "1 <= n < 2^52"));
        }
        let z = T::zero();
        let chk = |field: &str, v: &T, ok: bool, allowed: &str| -> Result<()> {
            if v.is_finite() && ok {
                Ok(())
            } else {
                Err(Error::invalid(field, v.to_f64(), allowed))
            }
        };
        chk("k", &k, k > z, "k > 0 and finite")?;
        chk("mass", &mass, mass > z, "mass > 0 and finite")?;
        chk("d", &d, d >= z, "d >= 0 and finite")?;
        chk("gamma", &gamma, !gamma.is_zero(), "gamma != 0 and finite")?;
        Ok(Model {
            n,
            k,
            mass,
            d,
            gamma,
        })
    }

    /// The uniform part of a chain (its defects are ignored), in `T`.
    pub fn from_chain(chain: &Chain) -> Model<T> {
        Model {
            n: chain.n(),
            k: T::from_f64(chain.k()),
            mass: T::from_f64(chain.mass()),
            d: T::from_f64(chain.d()),
            gamma: T::from_f64(chain.gamma()),
        }
    }

    /// The same model rounded to `f64` (for root isolation).
    pub fn to_f64(&self) -> Model<f64> {
        Model {
            n: self.n,
            k: self.k.to_f64(),
            mass: self.mass.to_f64(),
            d: self.d.to_f64(),
            gamma: self.gamma.to_f64(),
        }
    }

    /// Number of masses.
    pub fn n(&self) -> usize {
        self.n
    }

    /// Uniform mass.
    pub fn mass(&self) -> &T {
        &self.mass
    }

    /// Uniform damping.
    pub fn d(&self) -> &T {
        &self.d
    }

    /// Impulse.
    pub fn gamma(&self) -> &T {
        &self.gamma
    }

    /// Spring constant.
    pub fn k(&self) -> &T {
        &self.k
    }

    /// Everything that depends only on `s` (`s > 0`).
    pub fn at(&self, s: &T) -> AtS<T> {
        // lambda = 2 asinh( sqrt(s (mass s + d) / k) / 2 )
        let inner = (self.mass.clone() * s.clone() + self.d.clone()) / self.k.clone();
        let root = s.sqrt() * inner.sqrt();
        let lambda = root.scale(0.5).asinh().scale(2.0);
        let big_n = T::from_f64((self.n + 1) as f64);
        let e = |p: &T| -(lambda.clone() * p.clone()).scale(-2.0).expm1();
        let e1 = e(&T::one());
        let en1 = e(&big_n);
        let en = e(&T::from_f64(self.n as f64));
        let q = (-lambda.clone()).exp();
        let g11 = q.clone() * en / (self.k.clone() * en1.clone());
        let cosh = T::one()
            + (self.mass.clone() * s.clone() + self.d.clone()) * s.clone()
                / self.k.clone().scale(2.0);
        AtS {
            s: s.clone(),
            s2: s.clone() * s.clone(),
            ln_k_en1: (self.k.clone() * en1.clone()).ln(),
            ln_k_e1_en1: (self.k.clone() * e1.clone() * en1).ln(),
            lambda,
            big_n,
            q,
            e1,
            g11,
            cosh,
            k: self.k.clone(),
            mass: self.mass.clone(),
        }
    }

    /// `X_1(s)` of the chain with one mass defect `m` at integer `j`, by (4.7)
    /// (for synthetic data and checks; `j = 1` uses `gamma G_11 / (1 + c G_11)`).
    ///
    /// # Errors
    /// `j` outside `1..=n`, `m <= 0`, `s <= 0`.
    pub fn x1(&self, s: &T, j: usize, m: &T) -> Result<T> {
        if j == 0 || j > self.n {
            return Err(Error::invalid("j", j, format!("1 <= j <= n = {}", self.n)));
        }
        if !(m.is_finite() && *m > T::zero()) {
            return Err(Error::invalid("m", m.to_f64(), "m > 0 and finite"));
        }
        if !(s.is_finite() && *s > T::zero()) {
            return Err(Error::invalid("s", s.to_f64(), "s > 0 and finite"));
        }
        let at = self.at(s);
        let c = at.c(m);
        let jt = T::from_f64(j as f64);
        let x = if j == 1 {
            at.g11.clone() / (T::one() + c * at.g11.clone())
        } else {
            let g1j = at.ln_g1j(&jt).exp();
            at.g11.clone() - c.clone() * g1j.clone() * g1j / (T::one() + c * at.gjj(&jt))
        };
        Ok(x * self.gamma.clone())
    }
}

/// The `s`-dependent part of [`Model`]: `lambda`, `q = e^{-lambda}`, `G_11`
/// and the normalisations of `G_1j` and `G_jj`.
#[derive(Clone, Debug)]
pub struct AtS<T> {
    /// The Laplace variable.
    pub s: T,
    /// `s^2`.
    pub s2: T,
    /// `lambda(s)`.
    pub lambda: T,
    /// `q = exp(-lambda)`.
    pub q: T,
    /// `cosh(lambda) = 1 + (mass s^2 + d s) / (2k)`.
    pub cosh: T,
    /// `G_11` of the uniform chain.
    pub g11: T,
    /// `E(1) = 1 - q^2`.
    pub e1: T,
    big_n: T,
    ln_k_en1: T,
    ln_k_e1_en1: T,
    k: T,
    mass: T,
}

impl<T: RealScalar> AtS<T> {
    /// `E(p) = 1 - q^{2p}`.
    pub fn e(&self, p: &T) -> T {
        -(self.lambda.clone() * p.clone()).scale(-2.0).expm1()
    }

    /// `ln G_1j = -j lambda + ln E(N - j) - ln(k E(N))`, real `0 < j < N`.
    pub fn ln_g1j(&self, j: &T) -> T {
        -(self.lambda.clone() * j.clone()) + self.e(&(self.big_n.clone() - j.clone())).ln()
            - self.ln_k_en1.clone()
    }

    /// `G_jj = q E(j) E(N - j) / (k E(1) E(N))`, real `0 < j < N`.
    pub fn gjj(&self, j: &T) -> T {
        let ln = -self.lambda.clone()
            + (self.e(j) * self.e(&(self.big_n.clone() - j.clone()))).ln()
            - self.ln_k_e1_en1.clone();
        ln.exp()
    }

    /// `c = (m - mass) s^2`.
    pub fn c(&self, m: &T) -> T {
        (m.clone() - self.mass.clone()) * self.s2.clone()
    }

    /// `ln |f(j)|` of the exact relation (4.7): `ln|c| + 2 ln G_1j - ln(1 + c G_jj)`
    /// (NaN where `1 + c G_jj <= 0`).
    pub fn ln_f_exact(&self, j: &T, c: &T) -> T {
        let den = T::one() + c.clone() * self.gjj(j);
        c.abs().ln() + self.ln_g1j(j).scale(2.0) - den.ln()
    }

    /// `ln |h(j)|` of the asymptotic relation (4.10):
    /// `h = ((m - mass)/m) G_1j^2 / G_jj`, i.e. `ln|ratio| + 2 ln G_1j - ln G_jj`.
    pub fn ln_f_asymptotic(&self, j: &T, ratio: &T) -> T {
        ratio.abs().ln() + self.ln_g1j(j).scale(2.0) - self.gjj(j).ln()
    }

    /// `2 sinh(lambda) = E(1) / q`.
    pub fn two_sinh(&self) -> T {
        self.e1.clone() / self.q.clone()
    }

    /// `k`.
    pub fn k(&self) -> &T {
        &self.k
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chain::Defect;
    use crate::forward::response;
    use crate::green::Green;

    #[test]
    fn continuous_forms_match_green_at_integers() {
        for &(n, k, mass, d) in &[
            (20usize, 1.0, 1.0, 0.1),
            (7, 2.5, 0.3, 0.0),
            (1, 1.0, 1.0, 0.1),
        ] {
            let model = Model::new(n, k, mass, d, 1.0).unwrap();
            for &s in &[1e-3, 0.1, 1.0, 7.0, 50.0] {
                let at = model.at(&s);
                let g = Green::new(n, k, mass, d, s);
                assert!((at.g11 - g.entry(1, 1)).abs() <= 1e-13 * g.entry(1, 1));
                for j in 1..=n {
                    let jt = j as f64;
                    let g1j = g.entry(1, j);
                    if g1j > 1e-300 {
                        assert!(
                            (at.ln_g1j(&jt) - g1j.ln()).abs() < 1e-12,
                            "n={n} s={s} j={j}"
                        );
                    }
                    let gjj = g.entry(j, j);
                    assert!((at.gjj(&jt) - gjj).abs() <= 1e-12 * gjj);
                }
            }
        }
    }

    #[test]
    fn x1_matches_forward_model() {
        for &(n, j, m) in &[
            (20usize, 15usize, 1.01),
            (5, 3, 4.0),
            (20, 1, 100.0),
            (5, 5, 0.5),
        ] {
            let chain = Chain::paper(n)
                .unwrap()
                .with_defect(Defect::Mass { at: j, m })
                .unwrap();
            let model: Model<f64> = Model::from_chain(&chain);
            for &s in &[1e-3, 0.3, 2.0, 20.0] {
                let a = model.x1(&s, j, &m).unwrap();
                let b = response(&chain, s, 1).unwrap();
                assert!(
                    (a - b).abs() <= 1e-13 * b,
                    "n={n} j={j} m={m} s={s}: {a} vs {b}"
                );
            }
        }
        let model: Model<f64> = Model::new(5, 1.0, 1.0, 0.1, 1.0).unwrap();
        assert!(model.x1(&1.0, 0, &2.0).is_err());
        assert!(model.x1(&1.0, 6, &2.0).is_err());
        assert!(model.x1(&1.0, 2, &-2.0).is_err());
        assert!(model.x1(&0.0, 2, &2.0).is_err());
        assert!(Model::new(0, 1.0, 1.0, 0.1, 1.0).is_err());
        assert!(Model::new(3, -1.0, 1.0, 0.1, 1.0).is_err());
        assert!(Model::new(3, 1.0, 1.0, f64::NAN, 1.0).is_err());
    }
}
