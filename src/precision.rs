//! Arbitrary-precision reals for the locators, and the real-only operations
//! they need.
//!
//! [`BigReal`] wraps `astro_float::BigFloat` (pure Rust), chosen after
//! measuring on this machine (2 cores, release build):
//!
//! | crate | builds from crates.io | `exp` / `ln` at 128, 256, 512 bits | functions |
//! |---|---|---|---|
//! | astro-float 0.9 | yes (both crates together: 32 s cold) | 20-100 / 95-330 µs | all, incl. `asinh`, `acosh` |
//! | dashu-float 0.4 | yes | 245-1100 / 710-3500 µs | no `asinh`/`acosh` |
//! | rug | needs `m4`, ~3.5 min first build | (not taken) | all |
//!
//! (`twofloat` divides with only f64 accuracy.) A multiplication costs
//! 0.1-0.3 µs in both.
//!
//! # Precision: a thread-local setting
//!
//! The [`Scalar`] trait builds constants with `from_f64(x)`, which has no room
//! for a precision argument, so the working precision is a **thread-local**
//! setting (default [`DEFAULT_BITS`] = 256 bits): every operation rounds its
//! result to the precision in force on the calling thread (round to nearest,
//! ties to even). Set it for a scope with [`with_precision`]; a value computed
//! at one precision and used at another is simply rounded again. New threads
//! (for example rayon workers) start at the default: call [`with_precision`]
//! inside the task.
//!
//! Transcendental functions are evaluated with guard bits where the plain
//! formula would cancel (`expm1`, `asinh` and `ln_1p` of small arguments), so
//! they keep full relative accuracy near zero, like their `f64` counterparts.
//!
//! ```
//! use springmass::precision::{with_precision, BigReal, RealScalar};
//! use springmass::scalar::Scalar;
//! let third = with_precision(256, || BigReal::one() / BigReal::from_f64(3.0));
//! // 1/3 to 256 bits: 3 * third - 1 is at the 2^-256 level
//! let r = with_precision(256, || third.clone().scale(3.0) - BigReal::one());
//! assert!(r.abs().to_f64() < 1e-76);
//! let tenth: BigReal = with_precision(256, || RealScalar::parse_decimal("0.1").unwrap());
//! assert!((tenth.to_f64() - 0.1).abs() == 0.0);
//! ```

use crate::scalar::Scalar;
use std::cell::Cell;

#[cfg(feature = "bigfloat")]
pub use big::BigReal;

/// Default working precision in bits.
pub const DEFAULT_BITS: usize = 256;
/// Smallest accepted precision (one 64-bit word).
pub const MIN_BITS: usize = 64;
/// Largest accepted precision.
pub const MAX_BITS: usize = 1 << 16;

thread_local! {
    static PRECISION: Cell<usize> = const { Cell::new(DEFAULT_BITS) };
}

/// The working precision (bits) on this thread.
pub fn precision() -> usize {
    PRECISION.with(|p| p.get())
}

/// Check a precision request.
///
/// # Errors
/// [`crate::Error::InvalidParameter`] for `bits` outside `64..=65536`, and
/// for every `bits` when the crate is built without the `bigfloat` feature
/// (extended precision is then unavailable; use `f64`).
pub fn check_bits(bits: usize) -> crate::Result<usize> {
    if cfg!(not(feature = "bigfloat")) {
        return Err(unavailable(bits));
    }
    if (MIN_BITS..=MAX_BITS).contains(&bits) {
        Ok(bits)
    } else {
        Err(crate::Error::invalid(
            "precision",
            bits,
            format!("{MIN_BITS} <= bits <= {MAX_BITS}"),
        ))
    }
}

/// The error for a request of `bits` of extended precision in a build
/// without the `bigfloat` feature: an [`crate::Error::InvalidParameter`]
/// naming `precision`, allowing `f64` only.
pub fn unavailable(bits: usize) -> crate::Error {
    crate::Error::invalid(
        "precision",
        bits,
        "f64 only: this build has no extended precision (enable the `bigfloat` feature)",
    )
}

/// Run `f` with the working precision set to `bits` on this thread (clamped to
/// `64..=65536`), restoring the previous setting afterwards (also on panic).
pub fn with_precision<R>(bits: usize, f: impl FnOnce() -> R) -> R {
    struct Restore(usize);
    impl Drop for Restore {
        fn drop(&mut self) {
            PRECISION.with(|p| p.set(self.0));
        }
    }
    let bits = bits.clamp(MIN_BITS, MAX_BITS);
    let _restore = Restore(PRECISION.with(|p| p.replace(bits)));
    f()
}

/// Real-only operations the locators need on top of [`Scalar`]: order,
/// logarithms, inverse hyperbolic functions, and the unit roundoff of the type
/// (which sets the rounding floor of a computed value).
pub trait RealScalar: Scalar + PartialOrd {
    /// Natural logarithm (NaN for negative arguments).
    fn ln(&self) -> Self;
    /// `ln(1 + x)` without cancellation for small `x`.
    fn ln_1p(&self) -> Self;
    /// Inverse hyperbolic cosine (`x >= 1`).
    fn acosh(&self) -> Self;
    /// Absolute value.
    fn abs(&self) -> Self;
    /// Round to the nearest `f64` (0 below the `f64` range, `±inf` above).
    fn to_f64(&self) -> f64;
    /// Unit roundoff at the current working precision (`2^-53` for `f64`).
    fn epsilon() -> f64;
    /// Parse a decimal number exactly to the working precision (`"0.1"` is
    /// the real 1/10 rounded once, not the `f64` nearest 0.1 rounded again).
    fn parse_decimal(text: &str) -> Option<Self>;
    /// Natural logarithm of `|x|` as an `f64`, finite even where `x` itself is
    /// outside the `f64` range (`-inf` for 0).
    fn ln_abs_f64(&self) -> f64;
    /// Decimal text with `digits` significant digits (scientific notation).
    fn to_decimal(&self, digits: usize) -> String;
}

impl RealScalar for f64 {
    #[inline]
    fn ln(&self) -> Self {
        f64::ln(*self)
    }
    #[inline]
    fn ln_1p(&self) -> Self {
        f64::ln_1p(*self)
    }
    #[inline]
    fn acosh(&self) -> Self {
        f64::acosh(*self)
    }
    #[inline]
    fn abs(&self) -> Self {
        f64::abs(*self)
    }
    #[inline]
    fn to_f64(&self) -> f64 {
        *self
    }
    #[inline]
    fn epsilon() -> f64 {
        f64::EPSILON / 2.0
    }
    fn parse_decimal(text: &str) -> Option<Self> {
        text.trim().parse().ok().filter(|v: &f64| v.is_finite())
    }
    #[inline]
    fn ln_abs_f64(&self) -> f64 {
        f64::abs(*self).ln()
    }
    fn to_decimal(&self, digits: usize) -> String {
        format!("{:.*e}", digits.clamp(1, 17) - 1, self)
    }
}

#[cfg(feature = "bigfloat")]
mod big {
    use super::*;
    use astro_float::{BigFloat, Consts, Radix, RoundingMode, Sign};
    use num_complex::Complex64;
    use std::cell::RefCell;
    use std::cmp::Ordering;
    use std::fmt;
    use std::ops::{Add, Div, Mul, Neg, Sub};

    const RM: RoundingMode = RoundingMode::ToEven;

    thread_local! {
        static CONSTS: RefCell<Option<Consts>> = const { RefCell::new(None) };
    }

    fn with_consts<R>(f: impl FnOnce(&mut Consts) -> R) -> R {
        CONSTS.with(|c| {
            let mut c = c.borrow_mut();
            let cc = c.get_or_insert_with(|| Consts::new().expect("astro-float constants cache"));
            f(cc)
        })
    }

    /// An arbitrary-precision real number (see the module documentation for the
    /// thread-local working precision).
    #[derive(Clone)]
    pub struct BigReal(BigFloat);

    impl BigReal {
        /// Wrap an `astro_float::BigFloat`.
        pub fn from_bigfloat(x: BigFloat) -> BigReal {
            BigReal(x)
        }

        /// The wrapped `BigFloat`.
        pub fn as_bigfloat(&self) -> &BigFloat {
            &self.0
        }

        /// Binary exponent `e` with `2^(e-1) <= |x| < 2^e` (`None` for 0, NaN, inf).
        pub fn exponent(&self) -> Option<i32> {
            if self.0.is_zero() || self.0.is_nan() || self.0.is_inf() {
                None
            } else {
                self.0.exponent()
            }
        }

        /// Decimal text with `digits` significant digits (scientific notation).
        pub fn to_string_digits(&self, digits: usize) -> String {
            if self.0.is_nan() {
                return "NaN".into();
            }
            if self.0.is_inf() {
                return if self.0.is_inf_pos() { "inf" } else { "-inf" }.into();
            }
            // round to about digits * log2(10) bits first, then format
            let bits = ((digits as f64) * std::f64::consts::LOG2_10).ceil() as usize + 8;
            let mut v = self.0.clone();
            let _ = v.set_precision(bits.max(MIN_BITS), RM);
            let s = with_consts(|cc| v.format(Radix::Dec, RM, cc)).unwrap_or_else(|_| "NaN".into());
            shorten_decimal(&s, digits)
        }

        fn with_guard(bits: usize, f: impl FnOnce() -> BigReal) -> BigReal {
            let p = precision();
            let mut r = with_precision(p + bits, f);
            let _ = r.0.set_precision(p, RM);
            r
        }

        /// A function `f` with `f(0) = 0` whose `direct` form cancels for
        /// small `x` (`exp(x) - 1`, `ln(1 + x)`): for `|x| < 1/2` `direct` is
        /// taken with `-log2|x|` guard bits so that the cancellation loses
        /// nothing; below `2^-(p+8)` the two-term `series` is exact to the
        /// working precision.
        fn near_zero(
            &self,
            series: impl FnOnce(BigReal) -> BigReal,
            direct: impl Fn() -> BigReal,
        ) -> BigReal {
            let p = precision();
            match self.exponent() {
                None => {
                    if self.0.is_zero() {
                        self.clone()
                    } else {
                        direct()
                    }
                }
                Some(e) if e < -(p as i32) - 8 => series(self.clone()),
                Some(e) if e < 0 => {
                    let guard = (-e) as usize + 16;
                    BigReal::with_guard(guard, direct)
                }
                Some(_) => direct(),
            }
        }
    }

    /// Cut an astro-float decimal rendering (`1.2345e-3` style) to `digits`
    /// significant digits (truncating; the value was already rounded to about
    /// that many bits).
    fn shorten_decimal(s: &str, digits: usize) -> String {
        let (mant, exp) = match s.find(['e', 'E']) {
            Some(i) => (&s[..i], &s[i..]),
            None => (s, ""),
        };
        let mut out = String::new();
        let mut count = 0;
        for c in mant.chars() {
            if c.is_ascii_digit() {
                if count >= digits {
                    continue;
                }
                count += 1;
            }
            out.push(c);
        }
        out.push_str(exp);
        out
    }

    impl fmt::Debug for BigReal {
        fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            write!(f, "BigReal({})", self.to_string_digits(24))
        }
    }

    impl fmt::Display for BigReal {
        fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            let digits = f
                .precision()
                .unwrap_or(((precision() as f64) / std::f64::consts::LOG2_10) as usize);
            write!(f, "{}", self.to_string_digits(digits.max(1)))
        }
    }

    impl PartialEq for BigReal {
        fn eq(&self, other: &Self) -> bool {
            self.0 == other.0
        }
    }

    impl PartialOrd for BigReal {
        fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
            self.0.partial_cmp(&other.0)
        }
    }

    macro_rules! binop {
        ($tr:ident, $m:ident) => {
            impl $tr for BigReal {
                type Output = BigReal;
                #[inline]
                fn $m(self, rhs: BigReal) -> BigReal {
                    BigReal(self.0.$m(&rhs.0, precision(), RM))
                }
            }
        };
    }
    binop!(Add, add);
    binop!(Sub, sub);
    binop!(Mul, mul);
    binop!(Div, div);

    impl Neg for BigReal {
        type Output = BigReal;
        #[inline]
        fn neg(self) -> BigReal {
            BigReal(self.0.neg())
        }
    }

    /// `f64` nearest to a `BigFloat` (round to nearest on the top word).
    fn big_to_f64(x: &BigFloat) -> f64 {
        if x.is_nan() {
            return f64::NAN;
        }
        if x.is_inf_pos() {
            return f64::INFINITY;
        }
        if x.is_inf_neg() {
            return f64::NEG_INFINITY;
        }
        if x.is_zero() {
            return 0.0;
        }
        let Some((words, _, sign, e, _)) = x.as_raw_parts() else {
            return f64::NAN;
        };
        let top = *words.last().unwrap_or(&0);
        // value = top / 2^64 * 2^e (mantissa normalised to [1/2, 1))
        let mut v = top as f64 / 18446744073709551616.0;
        let mut e = e as i64;
        if e > 1100 {
            v = f64::INFINITY;
        } else if e < -1200 {
            v = 0.0;
        } else {
            while e > 0 {
                let step = e.min(1000);
                v *= 2f64.powi(step as i32);
                e -= step;
            }
            while e < 0 {
                let step = (-e).min(1000);
                v *= 2f64.powi(-(step as i32));
                e += step;
            }
        }
        if sign == Sign::Neg {
            -v
        } else {
            v
        }
    }

    impl Scalar for BigReal {
        fn from_f64(x: f64) -> Self {
            // exact: an f64 fits in 53 bits
            BigReal(BigFloat::from_f64(x, precision().max(MIN_BITS)))
        }
        fn from_c64(z: Complex64) -> Option<Self> {
            (z.im == 0.0).then(|| Self::from_f64(z.re))
        }
        fn to_c64(&self) -> Complex64 {
            Complex64::new(big_to_f64(&self.0), 0.0)
        }
        fn re_f64(&self) -> f64 {
            big_to_f64(&self.0)
        }
        fn magnitude(&self) -> f64 {
            big_to_f64(&self.0).abs()
        }
        fn sqrt(&self) -> Self {
            BigReal(self.0.sqrt(precision(), RM))
        }
        fn exp(&self) -> Self {
            let p = precision();
            BigReal(with_consts(|cc| self.0.exp(p, RM, cc)))
        }
        /// `exp(x) - 1`: for `|x| < 1/2` the exponential is taken with
        /// `-log2|x|` guard bits so that the subtraction loses nothing; below
        /// `2^-(p+8)` the series `x + x^2/2` is exact to the working precision.
        fn expm1(&self) -> Self {
            self.near_zero(
                |x| x.clone() + (x.clone() * x).scale(0.5),
                || self.exp() - BigReal::one(),
            )
        }
        /// Principal `asinh`, with guard bits for small arguments.
        fn asinh(&self) -> Self {
            let p = precision();
            match self.exponent() {
                None => self.clone(),
                Some(e) if e < -(p as i32) / 2 - 8 => {
                    // asinh x = x - x^3/6 + O(x^5)
                    let x = self.clone();
                    x.clone() - (x.clone() * x.clone() * x).scale(1.0 / 6.0)
                }
                Some(e) => {
                    let guard = if e < 0 { (-e) as usize } else { 0 } + 16;
                    BigReal::with_guard(guard, || {
                        let q = precision();
                        BigReal(with_consts(|cc| self.0.asinh(q, RM, cc)))
                    })
                }
            }
        }
        fn is_zero(&self) -> bool {
            self.0.is_zero()
        }
        fn is_finite(&self) -> bool {
            !(self.0.is_nan() || self.0.is_inf())
        }
        fn scale(&self, x: f64) -> Self {
            self.clone() * Self::from_f64(x)
        }
    }

    impl RealScalar for BigReal {
        fn ln(&self) -> Self {
            let p = precision();
            BigReal(with_consts(|cc| self.0.ln(p, RM, cc)))
        }
        /// `ln(1 + x)`: for `|x| < 1/2` the sum `1 + x` is formed with
        /// `-log2|x|` guard bits (exactly, when `x` carries the working precision).
        fn ln_1p(&self) -> Self {
            self.near_zero(
                |x| x.clone() - (x.clone() * x).scale(0.5),
                || (BigReal::one() + self.clone()).ln(),
            )
        }
        fn acosh(&self) -> Self {
            let p = precision();
            BigReal(with_consts(|cc| self.0.acosh(p, RM, cc)))
        }
        fn abs(&self) -> Self {
            BigReal(self.0.abs())
        }
        fn to_f64(&self) -> f64 {
            big_to_f64(&self.0)
        }
        fn epsilon() -> f64 {
            2f64.powi(-(precision() as i32).min(1000))
        }
        fn parse_decimal(text: &str) -> Option<Self> {
            let t = text.trim();
            // reject what astro-float would turn into NaN/inf, and non-numbers
            if t.is_empty()
                || !t
                    .chars()
                    .all(|c| c.is_ascii_digit() || matches!(c, '.' | 'e' | 'E' | '+' | '-'))
            {
                return None;
            }
            let p = precision();
            let v = with_consts(|cc| BigFloat::parse(t, Radix::Dec, p, RM, cc));
            (!v.is_nan() && !v.is_inf()).then_some(BigReal(v))
        }
        fn ln_abs_f64(&self) -> f64 {
            if self.0.is_zero() {
                return f64::NEG_INFINITY;
            }
            let Some((words, _, _, e, _)) = self.0.as_raw_parts() else {
                return f64::NAN;
            };
            let top = *words.last().unwrap_or(&0) as f64 / 18446744073709551616.0;
            top.ln() + (e as f64) * std::f64::consts::LN_2
        }
        fn to_decimal(&self, digits: usize) -> String {
            self.to_string_digits(digits.max(1))
        }
    }
}

#[cfg(all(test, feature = "bigfloat"))]
mod tests {
    use super::*;

    fn big(x: f64) -> BigReal {
        BigReal::from_f64(x)
    }

    #[test]
    fn precision_is_scoped_and_restored() {
        let before = precision();
        with_precision(512, || {
            assert_eq!(precision(), 512);
            with_precision(128, || assert_eq!(precision(), 128));
            assert_eq!(precision(), 512);
        });
        assert_eq!(precision(), before);
        assert!(check_bits(32).is_err());
        assert!(check_bits(128).is_ok());
    }

    #[test]
    fn arithmetic_and_round_trip() {
        with_precision(256, || {
            for &x in &[1.0, -2.5, 1e-300, 3e300, 0.1, 123456.789] {
                assert_eq!(big(x).to_f64(), x);
            }
            let third = BigReal::one() / big(3.0);
            let err = (third.scale(3.0) - BigReal::one()).abs().to_f64();
            assert!(err < 1e-76, "{err}");
            assert!(big(2.0) > big(1.0));
            assert_eq!(big(0.0).to_f64(), 0.0);
        });
    }

    #[test]
    fn transcendental_functions_match_f64_and_identities() {
        with_precision(256, || {
            for &x in &[1e-30, 1e-9, 0.3, 1.0, 7.5, 40.0] {
                let b = big(x);
                assert!((Scalar::exp(&b).to_f64() / x.exp() - 1.0).abs() < 1e-15);
                assert!((Scalar::asinh(&b).to_f64() / x.asinh() - 1.0).abs() < 1e-15);
                assert!((Scalar::expm1(&b).to_f64() / x.exp_m1() - 1.0).abs() < 1e-15);
                assert!((RealScalar::ln_1p(&b).to_f64() / x.ln_1p() - 1.0).abs() < 1e-15);
                // identities at full precision: sinh(asinh x) = x, ln(exp x) = x
                let a = Scalar::asinh(&b);
                let sinh = (Scalar::expm1(&a) - Scalar::expm1(&-a.clone())).scale(0.5);
                assert!(((sinh - b.clone()) / b.clone()).abs().to_f64() < 1e-74);
                if x >= 0.3 {
                    // (for tiny x, exp(x) = 1 + x itself is rounded at 2^-256 absolute)
                    let l = RealScalar::ln(&Scalar::exp(&b));
                    assert!(((l - b.clone()) / b.clone()).abs().to_f64() < 1e-74);
                    let c =
                        RealScalar::acosh(&(Scalar::exp(&b) + Scalar::exp(&-b.clone())).scale(0.5));
                    assert!(((c - b.clone()) / b.clone()).abs().to_f64() < 1e-70);
                }
                let e1 = Scalar::expm1(&b);
                let back = RealScalar::ln_1p(&e1);
                assert!(((back - b.clone()) / b).abs().to_f64() < 1e-74, "x={x}");
            }
        });
    }

    #[test]
    fn decimal_parsing_and_formatting() {
        with_precision(256, || {
            let t: BigReal = RealScalar::parse_decimal("0.1").unwrap();
            // 10 * 0.1 - 1 is at the 2^-256 level (the f64 0.1 would give 5.5e-17)
            let r = (t.scale(10.0) - BigReal::one()).abs().to_f64();
            assert!(r < 1e-75, "{r}");
            assert!(BigReal::parse_decimal("abc").is_none());
            assert!(BigReal::parse_decimal("").is_none());
            let x: BigReal = RealScalar::parse_decimal("3.01842261").unwrap();
            assert!(x.to_string_digits(6).starts_with("3.01842"));
            assert!(big(-2.0).ln_abs_f64() - 2f64.ln() < 1e-15);
            let huge = Scalar::exp(&big(5000.0));
            assert!((huge.ln_abs_f64() - 5000.0).abs() < 1e-9);
            assert_eq!(huge.to_f64(), f64::INFINITY);
        });
    }
}
