//! Active vibration suppression (section 3 of the paper): the controls of
//! Theorem 3.1 and Corollary 3.2, in the Laplace domain, in the time domain,
//! and checked by simulation.
//!
//! # The scheme
//!
//! A uniform chain of `n + 1` masses (mass `m`, springs `k`, dampers `d`,
//! walls at both ends) is hit by an impulse `gamma delta(t)` on mass 1.
//!
//! * **Theorem 3.1 (cloak)**: a force `f` on mass `n` and a force `g` on mass
//!   `n - 1` keep mass `n + 1` still *and* leave `x_1` exactly as without
//!   controls:
//!   `F(s) = -gamma sinh(3 lambda) / sinh((n+2) lambda)`,
//!   `G(s) =  gamma sinh(2 lambda) / sinh((n+2) lambda)`.
//! * **Corollary 3.2 (single control)**: a force `f1` on mass `n` alone keeps
//!   masses `n` and `n + 1` still, but mass 1 then sees the chain of `n - 1`
//!   masses: `F1(s) = -gamma sinh(lambda) / sinh(n lambda)`.
//!
//! with `cosh(lambda) = 1 + (m s^2 + d s) / (2k)`.
//!
//! ## General `k` and `m` (derived here, tested in [`laplace`])
//!
//! Dividing the equations of motion by `k` gives `T X = b / k` with
//! `T = tridiag(-1, 2 cosh(lambda), -1)`: every displacement carries a factor
//! `1/k`, while the impulse and the controls are all *forces* on the right
//! side. The conditions `X_{n+1} = 0` and `X_1 = Y_1` are linear and
//! homogeneous in the forces, so `k` cancels: **the force laws above hold for
//! every `k` and `m` unchanged**, with `k` and `m` entering only through
//! `lambda`. The displacements do scale: `Y_1 = (gamma/k) sinh((n+1)l)/sinh((n+2)l)`.
//!
//! ## Which `n` are valid
//!
//! `n >= 2` for both schemes. Theorem 3.1 needs mass `n - 1 >= 1` for `g`.
//! For Corollary 3.2 with `n = 1` the law is `F1 = -gamma`, a counter-impulse
//! on the struck mass itself: not a control force but the cancellation of
//! the input. Every other `n` up to [`crate::chain::MAX_N`]` - 1` is accepted.
//!
//! ## Chebyshev form
//!
//! With `c = cosh(lambda)`, `sinh((p+1) lambda) / sinh(lambda) = U_p(c)`, so
//! every signal of the scheme is `coef * U_a(c) / U_b(c)` with `a < b`
//! ([`URatio`]): a proper rational function of `s` whose poles are the
//! roots of `m s^2 + d s + 2k (1 - cos(j pi/(b+1))) = 0`. That makes the
//! time-domain signals finite sums of damped modes ([`exact`]).
//!
//! ```
//! use springmass::control::{Suppression, Signal};
//! let sup = Suppression::paper(4)?;            // 5 masses, d = 0.1
//! let f = sup.ratio(Signal::F);
//! let s = 0.7_f64;
//! let lam = springmass::control::laplace::lambda(1.0, 1.0, 0.1, s);
//! let expect = -(3.0 * lam).sinh() / (6.0 * lam).sinh();
//! assert!((f.eval(&sup, s)? - expect).abs() < 1e-14);
//! # Ok::<(), springmass::Error>(())
//! ```

pub mod exact;
pub mod laplace;
pub mod verify;

pub use laplace::URatio;

use crate::chain::{Chain, MAX_N};
use crate::error::{Error, Result};

/// Which of the two schemes of section 3.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Scheme {
    /// Theorem 3.1: `f` on mass `n`, `g` on mass `n - 1`; mass `n+1` still, mass 1 unaware.
    Cloak,
    /// Corollary 3.2: `f1` on mass `n` alone; masses `n` and `n+1` still.
    Single,
}

/// A signal of the suppression scheme with a closed form `coef U_a(c) / U_b(c)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Signal {
    /// Theorem 3.1 control on mass `n`: `-gamma sinh(3l)/sinh((n+2)l)`.
    F,
    /// Theorem 3.1 control on mass `n-1`: `gamma sinh(2l)/sinh((n+2)l)`.
    G,
    /// Corollary 3.2 control on mass `n`: `-gamma sinh(l)/sinh(n l)`.
    F1,
    /// Uncontrolled `x_1` (and `x_1` under both controls): `(gamma/k) sinh((n+1)l)/sinh((n+2)l)`.
    Y1,
    /// Uncontrolled `x_{n+1}`: `(gamma/k) sinh(l)/sinh((n+2)l)`.
    YEnd,
    /// `x_1` under `f1` alone (= `x_1` of the `(n-1)`-mass chain): `(gamma/k) sinh((n-1)l)/sinh(n l)`.
    X1Single,
}

impl Signal {
    /// Short name used in CSV headers.
    pub fn name(self) -> &'static str {
        match self {
            Signal::F => "f",
            Signal::G => "g",
            Signal::F1 => "f1",
            Signal::Y1 => "y1",
            Signal::YEnd => "y_end",
            Signal::X1Single => "x1_single",
        }
    }
}

/// A validated suppression problem: the uniform `(n+1)`-mass chain and `n`.
#[derive(Clone, Debug, PartialEq)]
pub struct Suppression {
    n: usize,
    chain: Chain,
}

impl Suppression {
    /// The paper's setting: `n + 1` unit masses, `k = 1`, `d = 0.1`, `gamma = 1`.
    ///
    /// # Errors
    /// `n < 2` or `n + 1 > MAX_N` ([`Error::InvalidParameter`] on `n`).
    pub fn paper(n: usize) -> Result<Suppression> {
        Self::check_n(n)?;
        Self::from_chain(&Chain::paper(n + 1)?)
    }

    /// A suppression problem on `n + 1` masses with the given parameters.
    ///
    /// # Errors
    /// `n < 2`; `k <= 0`, `d < 0`, `mass <= 0`, non-finite values.
    pub fn new(n: usize, k: f64, d: f64, mass: f64, gamma: f64) -> Result<Suppression> {
        Self::check_n(n)?;
        let chain = Chain::new(n + 1)?
            .with_k(k)?
            .with_d(d)?
            .with_mass(mass)?
            .with_gamma(gamma)?;
        Self::from_chain(&chain)
    }

    /// The scheme on a given chain of `n + 1 >= 3` masses.
    ///
    /// # Errors
    /// Fewer than 3 masses; an end that is not fixed (field `boundaries`);
    /// a chain with defects (the closed forms are for the uniform chain
    /// between two walls).
    pub fn from_chain(chain: &Chain) -> Result<Suppression> {
        if chain.n() < 3 {
            return Err(Error::invalid(
                "n",
                chain.n().saturating_sub(1),
                "n >= 2 (the chain has n+1 masses; g acts on mass n-1 >= 1)",
            ));
        }
        chain.require_grounded("the suppression laws (derived for grounded dampers)")?;
        if !chain.is_fixed_fixed() {
            return Err(Error::invalid(
                "boundaries",
                format!("left {}, right {}", chain.left(), chain.right()),
                "left fixed and right fixed: the suppression laws (Theorem 3.1, \
                 Corollary 3.2) are derived for a chain between two walls",
            ));
        }
        if !chain.defects().is_empty() {
            return Err(Error::invalid(
                "defects",
                chain.defects().len(),
                "none: the suppression laws are derived for the uniform chain",
            ));
        }
        Ok(Suppression {
            n: chain.n() - 1,
            chain: chain.clone(),
        })
    }

    fn check_n(n: usize) -> Result<()> {
        if !(2..MAX_N).contains(&n) {
            return Err(Error::invalid(
                "n",
                n,
                format!(
                    "2 <= n <= {} (the chain has n+1 masses; g acts on mass n-1 >= 1)",
                    MAX_N - 1
                ),
            ));
        }
        Ok(())
    }

    /// The same problem with another impulse (for example `1` for kernels).
    pub fn with_gamma(&self, gamma: f64) -> Result<Suppression> {
        Ok(Suppression {
            n: self.n,
            chain: self.chain.clone().with_gamma(gamma)?,
        })
    }

    /// `n`: `f` acts on mass `n`; the chain has `n + 1` masses.
    pub fn n(&self) -> usize {
        self.n
    }
    /// The `(n+1)`-mass chain.
    pub fn chain(&self) -> &Chain {
        &self.chain
    }
    /// Spring constant.
    pub fn k(&self) -> f64 {
        self.chain.k()
    }
    /// Damping per mass.
    pub fn d(&self) -> f64 {
        self.chain.d()
    }
    /// Mass.
    pub fn mass(&self) -> f64 {
        self.chain.mass()
    }
    /// Impulse on mass 1.
    pub fn gamma(&self) -> f64 {
        self.chain.gamma()
    }

    /// The closed form `coef U_a(c)/U_b(c)` of a signal.
    pub fn ratio(&self, signal: Signal) -> URatio {
        let n = self.n;
        let g = self.gamma();
        let gk = g / self.k();
        let (a, b, coef) = match signal {
            Signal::F => (2, n + 1, -g),
            Signal::G => (1, n + 1, g),
            Signal::F1 => (0, n - 1, -g),
            Signal::Y1 => (n, n + 1, gk),
            Signal::YEnd => (0, n + 1, gk),
            Signal::X1Single => (n - 2, n - 1, gk),
        };
        URatio { a, b, coef }
    }

    /// The control forces of a scheme as `(mass index, signal)` pairs.
    pub fn controls(&self, scheme: Scheme) -> Vec<(usize, Signal)> {
        match scheme {
            Scheme::Cloak => vec![(self.n, Signal::F), (self.n - 1, Signal::G)],
            Scheme::Single => vec![(self.n, Signal::F1)],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refuses_small_n_and_defects() {
        for n in [0, 1] {
            let e = Suppression::paper(n).unwrap_err();
            assert!(matches!(e, Error::InvalidParameter { ref field, .. } if field == "n"));
        }
        assert!(Suppression::paper(2).is_ok());
        assert!(Suppression::new(3, 0.0, 0.1, 1.0, 1.0).is_err());
        assert!(Suppression::new(3, 1.0, -0.1, 1.0, 1.0).is_err());
        let c = Chain::paper(6)
            .unwrap()
            .with_defect(crate::Defect::Mass { at: 2, m: 3.0 })
            .unwrap();
        assert!(Suppression::from_chain(&c).is_err());
        assert!(Suppression::from_chain(&Chain::paper(2).unwrap()).is_err());
        for (l, r) in [
            (crate::chain::Boundary::Free, crate::chain::Boundary::Fixed),
            (crate::chain::Boundary::Fixed, crate::chain::Boundary::Free),
        ] {
            let c = Chain::paper(6).unwrap().with_boundaries(l, r).unwrap();
            assert!(matches!(
                Suppression::from_chain(&c),
                Err(Error::InvalidParameter { ref field, .. }) if field == "boundaries"
            ));
        }
        assert_eq!(
            Suppression::from_chain(&Chain::paper(6).unwrap())
                .unwrap()
                .n(),
            5
        );
    }
}
