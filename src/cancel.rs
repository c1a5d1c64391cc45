//! Cancellation of long library calls (fits, searches) from another thread.
//!
//! One process-wide flag: a front end that wants to stop a running fit (the
//! Python package on Ctrl-C) calls [`request`]; the long loops of the
//! library (every Levenberg-Marquardt iteration, each stage of a fit) call
//! [`check`], which then returns [`Error::Cancelled`], and the call returns
//! that error promptly. The front end calls [`reset`] once the call has
//! returned. The flag is shared by every call in the process: a request
//! stops every fit running at that moment.
//!
//! ```
//! use springmass::{cancel, Error};
//! assert!(cancel::check().is_ok());
//! cancel::request();
//! assert_eq!(cancel::check(), Err(Error::Cancelled));
//! cancel::reset();
//! assert!(cancel::check().is_ok());
//! ```

use crate::error::{Error, Result};
use std::sync::atomic::{AtomicBool, Ordering};

static REQUESTED: AtomicBool = AtomicBool::new(false);

/// Ask every running fit to stop with [`Error::Cancelled`].
pub fn request() {
    REQUESTED.store(true, Ordering::Relaxed);
}

/// Clear a request (after the cancelled call has returned).
pub fn reset() {
    REQUESTED.store(false, Ordering::Relaxed);
}

/// Whether a stop was requested.
pub fn requested() -> bool {
    REQUESTED.load(Ordering::Relaxed)
}

/// `Err(Error::Cancelled)` when a stop was requested, else `Ok(())`.
///
/// # Errors
/// [`Error::Cancelled`] after [`request`] (until [`reset`]).
pub fn check() -> Result<()> {
    if requested() {
        Err(Error::Cancelled)
    } else {
        Ok(())
    }
}

/// `r`, or [`Error::Cancelled`] when a stop was requested (so that a stage
/// whose inner fits were cancelled reports the cancellation, not the
/// failure it caused).
///
/// # Errors
/// [`Error::Cancelled`], or the error of `r`.
pub fn checked<T>(r: Result<T>) -> Result<T> {
    check()?;
    r
}
