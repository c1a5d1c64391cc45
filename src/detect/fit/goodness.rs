//! The bars of "the fit explains its data": the p-value of the residual's
//! test and the residual below which a record is exact to its digits. A
//! leaf that the fit's assembly, the report and the whole-profile fit share.

/// The p-value below which a residual is not noise: the level of the fit's
/// `fits_data` test (chi-square or Ljung-Box), and of each sensor's or
/// record's own residual in a joint fit (one that fails disagrees with the
/// joint answer).
pub const FITS_DATA_P: f64 = 1e-3;

/// Relative residual below which a record counts as exact to its printed
/// digits: no sensor resolves 1e-8 of its range (a 24-bit converter
/// resolves 6e-8), so a smaller residual is the rounding of the file's
/// numbers, which is not random and which no whiteness test can judge.
pub const EXACT_RECORD_RESIDUAL: f64 = 1e-8;

/// Whether a residual of sum of squares `rss` over `n` samples is the
/// rounding of an exact record whose largest `|x|` is `peak`
/// ([`EXACT_RECORD_RESIDUAL`]).
pub fn exact_record(rss: f64, n: usize, peak: f64) -> bool {
    (rss / n.max(1) as f64).sqrt() <= EXACT_RECORD_RESIDUAL * peak
}
