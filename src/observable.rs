//! What a sensor measures at a mass: the displacement, the velocity or the
//! acceleration ([`Observable`]), shared by the Laplace-domain forward
//! model ([`crate::forward`]) and the time responses ([`crate::time`]).

use crate::error::{Error, Result};
use crate::scalar::Scalar;

/// What is measured at a mass.
///
/// ```
/// use springmass::forward::Observable;
/// assert_eq!("acceleration".parse::<Observable>()?, Observable::Acceleration);
/// assert_eq!(Observable::Velocity.power(), 1);
/// # Ok::<(), springmass::Error>(())
/// ```
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum Observable {
    /// `x(t)`, transform `X(s)` (the paper's observable; the default).
    #[default]
    Displacement,
    /// `x'(t)`, transform `s X(s)`.
    Velocity,
    /// `x''(t)` for `t > 0`, transform `s^2 X(s) - x'(0+)`.
    Acceleration,
}

impl Observable {
    /// `displacement`, `velocity` or `acceleration`.
    pub fn name(self) -> &'static str {
        match self {
            Observable::Displacement => "displacement",
            Observable::Velocity => "velocity",
            Observable::Acceleration => "acceleration",
        }
    }
    /// The number of time derivatives: 0, 1 or 2.
    pub fn power(self) -> u32 {
        match self {
            Observable::Displacement => 0,
            Observable::Velocity => 1,
            Observable::Acceleration => 2,
        }
    }
    /// The column prefix used in series: `x`, `v` or `a`.
    pub fn prefix(self) -> &'static str {
        match self {
            Observable::Displacement => "x",
            Observable::Velocity => "v",
            Observable::Acceleration => "a",
        }
    }

    /// The observable's transform from the displacement's, `X_at(s)`, for
    /// the impulse `gamma` on mass 1 (`m1` the mass of mass 1):
    /// `X`, `s X`, or `s^2 X - [at = 1] gamma/m1`.
    ///
    /// For the acceleration of mass 1 this subtraction loses about
    /// `log10(m1 |s|^2 / |Z_1|)` digits at large `|s|` (`Z_1` the impedance
    /// behind mass 1; 4 digits at `|s| = 100` for the paper's chain);
    /// [`crate::forward::Forward::observe`] avoids it. For a force input use
    /// `gamma = 0` here (no jump) with `x = H F`.
    pub fn from_displacement<T: Scalar>(self, x: T, s: &T, at: usize, gamma: f64, m1: f64) -> T {
        match self {
            Observable::Displacement => x,
            Observable::Velocity => s.clone() * x,
            Observable::Acceleration => {
                let a = s.clone() * s.clone() * x;
                if at == 1 && gamma != 0.0 {
                    a - T::from_f64(gamma / m1)
                } else {
                    a
                }
            }
        }
    }
}

impl std::fmt::Display for Observable {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Observable {
    type Err = Error;
    fn from_str(s: &str) -> Result<Observable> {
        match s.trim().to_ascii_lowercase().as_str() {
            "displacement" | "x" | "disp" => Ok(Observable::Displacement),
            "velocity" | "v" | "vel" => Ok(Observable::Velocity),
            "acceleration" | "a" | "acc" => Ok(Observable::Acceleration),
            _ => Err(Error::invalid(
                "observe_kind",
                s,
                "displacement, velocity or acceleration",
            )),
        }
    }
}
