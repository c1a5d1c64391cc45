//! The number types the model is written over.
//!
//! The Green's function, the forward response and the locators are generic over
//! [`Scalar`], so the same code runs in `f64` (fast), in [`Complex64`] (for
//! Bromwich-line misfits and inverse Laplace transforms) and in an
//! arbitrary-precision real type (for locators that need more than 16 digits).
//!
//! Only what the model needs is required: field arithmetic, `sqrt`, `exp`,
//! `expm1`, `asinh`, and a way back to `f64`/[`Complex64`] for reporting.

use num_complex::Complex64;
use std::fmt::Debug;
use std::ops::{Add, Div, Mul, Neg, Sub};

/// A real or complex field element the model can be evaluated in.
///
/// Branches: for complex arguments `sqrt` and `asinh` are the principal
/// branches, which map `Re z >= 0` to `Re >= 0`; the Green's function relies
/// on that to keep `|exp(-lambda)| <= 1`.
pub trait Scalar:
    Clone
    + Debug
    + PartialEq
    + Send
    + Sync
    + 'static
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    /// Embed a real `f64`.
    fn from_f64(x: f64) -> Self;
    /// Embed a complex value; `None` for a real type given a non-zero imaginary part.
    fn from_c64(z: Complex64) -> Option<Self>;
    /// Round to a complex `f64` (for reporting and checks).
    fn to_c64(&self) -> Complex64;
    /// Real part, rounded to `f64`.
    fn re_f64(&self) -> f64 {
        self.to_c64().re
    }
    /// Modulus, rounded to `f64`.
    fn magnitude(&self) -> f64 {
        self.to_c64().norm()
    }
    /// Principal square root.
    fn sqrt(&self) -> Self;
    /// Exponential.
    fn exp(&self) -> Self;
    /// `exp(x) - 1` without cancellation for small `x`.
    fn expm1(&self) -> Self;
    /// Principal inverse hyperbolic sine, accurate for small arguments.
    fn asinh(&self) -> Self;
    /// Exact zero test.
    fn is_zero(&self) -> bool;
    /// No NaN or infinity in any component.
    fn is_finite(&self) -> bool;
    /// Zero.
    fn zero() -> Self {
        Self::from_f64(0.0)
    }
    /// One.
    fn one() -> Self {
        Self::from_f64(1.0)
    }
    /// Multiply by an `f64` constant.
    fn scale(&self, x: f64) -> Self {
        self.clone() * Self::from_f64(x)
    }
}

impl Scalar for f64 {
    #[inline]
    fn from_f64(x: f64) -> Self {
        x
    }
    #[inline]
    fn from_c64(z: Complex64) -> Option<Self> {
        (z.im == 0.0).then_some(z.re)
    }
    #[inline]
    fn to_c64(&self) -> Complex64 {
        Complex64::new(*self, 0.0)
    }
    #[inline]
    fn re_f64(&self) -> f64 {
        *self
    }
    #[inline]
    fn magnitude(&self) -> f64 {
        self.abs()
    }
    #[inline]
    fn sqrt(&self) -> Self {
        f64::sqrt(*self)
    }
    #[inline]
    fn exp(&self) -> Self {
        f64::exp(*self)
    }
    #[inline]
    fn expm1(&self) -> Self {
        f64::exp_m1(*self)
    }
    #[inline]
    fn asinh(&self) -> Self {
        f64::asinh(*self)
    }
    #[inline]
    fn is_zero(&self) -> bool {
        *self == 0.0
    }
    #[inline]
    fn is_finite(&self) -> bool {
        f64::is_finite(*self)
    }
    #[inline]
    fn scale(&self, x: f64) -> Self {
        self * x
    }
}

impl Scalar for Complex64 {
    #[inline]
    fn from_f64(x: f64) -> Self {
        Complex64::new(x, 0.0)
    }
    #[inline]
    fn from_c64(z: Complex64) -> Option<Self> {
        Some(z)
    }
    #[inline]
    fn to_c64(&self) -> Complex64 {
        *self
    }
    #[inline]
    fn sqrt(&self) -> Self {
        Complex64::sqrt(*self)
    }
    #[inline]
    fn exp(&self) -> Self {
        Complex64::exp(*self)
    }
    /// `exp(z) - 1 = expm1(x) cos y - 2 sin^2(y/2) + i e^x sin y`, accurate near 0.
    #[inline]
    fn expm1(&self) -> Self {
        let (x, y) = (self.re, self.im);
        if y == 0.0 {
            return Complex64::new(x.exp_m1(), 0.0);
        }
        let h = (0.5 * y).sin();
        Complex64::new(x.exp_m1() * y.cos() - 2.0 * h * h, x.exp() * y.sin())
    }
    /// Principal branch; uses the real `asinh` on the real axis and a series
    /// near zero so that small arguments keep full relative accuracy.
    #[inline]
    fn asinh(&self) -> Self {
        if self.im == 0.0 {
            return Complex64::new(self.re.asinh(), 0.0);
        }
        let z = *self;
        if z.norm() < 1e-4 {
            // asinh z = z - z^3/6 + 3 z^5/40 - 15 z^7/336
            let z2 = z * z;
            return z * (1.0 - z2 * (1.0 / 6.0 - z2 * (3.0 / 40.0 - z2 * (15.0 / 336.0))));
        }
        if z.norm() > 1e8 {
            // asinh z = ln(2z) + 1/(4 z^2) + O(z^-4), principal for Re z >= 0;
            // avoids the overflow of z*z inside the library formula.
            return (2.0 * z).ln() + 0.25 / (z * z);
        }
        Complex64::asinh(z)
    }
    #[inline]
    fn is_zero(&self) -> bool {
        self.re == 0.0 && self.im == 0.0
    }
    #[inline]
    fn is_finite(&self) -> bool {
        self.re.is_finite() && self.im.is_finite()
    }
    #[inline]
    fn scale(&self, x: f64) -> Self {
        self * x
    }
}

/// Parse a real or complex number: `0.5`, `1e-3`, `1+5i`, `2-0.5i`, `3i`, `-i`.
///
/// # Errors
/// [`crate::Error::Parse`] naming the text and the expected form.
///
/// ```
/// use springmass::scalar::parse_complex;
/// let z = parse_complex("1+5i").unwrap();
/// assert_eq!((z.re, z.im), (1.0, 5.0));
/// assert_eq!(parse_complex("0.5").unwrap().im, 0.0);
/// ```
pub fn parse_complex(text: &str) -> crate::Result<Complex64> {
    let bad = || {
        crate::Error::parse(
            "complex number",
            text,
            "expected a real number (0.5, 1e-3) or a+bi (1+5i, 2-0.5i, 3i)",
        )
    };
    let t: String = text.chars().filter(|c| !c.is_whitespace()).collect();
    if t.is_empty() {
        return Err(bad());
    }
    let real = |s: &str| -> crate::Result<f64> {
        let v: f64 = s.parse().map_err(|_| bad())?;
        if v.is_finite() {
            Ok(v)
        } else {
            Err(bad())
        }
    };
    if let Some(body) = t.strip_suffix(['i', 'j']) {
        // Find the split between real and imaginary parts: the last '+' or '-'
        // that is not at position 0 and does not follow an exponent marker.
        let bytes = body.as_bytes();
        let mut split = None;
        for idx in (1..bytes.len()).rev() {
            let c = bytes[idx];
            if (c == b'+' || c == b'-') && !matches!(bytes[idx - 1], b'e' | b'E') {
                split = Some(idx);
                break;
            }
        }
        let imag = |s: &str| -> crate::Result<f64> {
            match s {
                "" | "+" => Ok(1.0),
                "-" => Ok(-1.0),
                _ => real(s),
            }
        };
        match split {
            Some(k) => Ok(Complex64::new(real(&body[..k])?, imag(&body[k..])?)),
            None => Ok(Complex64::new(0.0, imag(body)?)),
        }
    } else {
        Ok(Complex64::new(real(&t)?, 0.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn complex_expm1_is_accurate_near_zero() {
        let z = Complex64::new(1e-10, 2e-10);
        let e = Scalar::expm1(&z);
        let series = z + z * z / 2.0 + z * z * z / 6.0;
        assert!((e - series).norm() < 1e-16 * z.norm(), "{e} vs {series}");
        let w = Complex64::new(0.3, -1.2);
        let direct = w.exp() - 1.0;
        assert!((Scalar::expm1(&w) - direct).norm() < 1e-15);
    }

    #[test]
    fn complex_asinh_small_and_branch() {
        let z = Complex64::new(1e-9, 3e-9);
        assert!((Scalar::asinh(&z) - z).norm() < 1e-25);
        for &(re, im) in &[(0.0, 5.0), (0.1, -7.0), (2.0, 0.5), (1e-3, 1e3)] {
            let a = Scalar::asinh(&Complex64::new(re, im));
            assert!(a.re >= 0.0, "branch for {re}+{im}i gave {a}");
            assert!((a.sinh() - Complex64::new(re, im)).norm() < 1e-12 * (1.0 + im.abs()));
        }
    }

    #[test]
    fn parse_forms() {
        let cases = [
            ("0.5", (0.5, 0.0)),
            ("1+5i", (1.0, 5.0)),
            ("2-0.5i", (2.0, -0.5)),
            ("3i", (0.0, 3.0)),
            ("-i", (0.0, -1.0)),
            ("1e-3+2e+1i", (1e-3, 20.0)),
            (" 0.1 + 0.7i ", (0.1, 0.7)),
        ];
        for (t, (re, im)) in cases {
            let z = parse_complex(t).unwrap();
            assert_eq!((z.re, z.im), (re, im), "{t}");
        }
        for t in ["", "abc", "1+", "nan", "inf", "1+xi"] {
            assert!(parse_complex(t).is_err(), "{t}");
        }
    }
}
