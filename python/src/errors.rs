//! The library's typed errors as Python exceptions, with the same messages.
//!
//! | [`springmass::Error`] | Python |
//! |---|---|
//! | `InvalidParameter`, `Parse`, `DuplicateDefect`, `Singular`, `ResourceLimit` | `ValueError` |
//! | `Unresolvable` | `springmass.UnresolvableError` (a `ValueError`) |
//! | `Io`, `UnsafeOutput` | `OSError` |
//! | `Numerical` | `springmass.NumericalError` (a `RuntimeError`) |
//!
//! Every exception carries `kind` (the variant's name); an invalid parameter
//! also `field`, `value` and `allowed`, a parse error `field` (what was
//! parsed), `value` (the input) and `allowed` (the reason).

use pyo3::create_exception;
use pyo3::exceptions::{PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use springmass::Error;

create_exception!(
    springmass,
    UnresolvableError,
    PyValueError,
    "The data cannot resolve the requested result (a signal below the rounding or noise floor)."
);
create_exception!(
    springmass,
    NumericalError,
    PyRuntimeError,
    "A numerical method could not reach the requested accuracy."
);

/// The variant's name.
fn kind(e: &Error) -> &'static str {
    match e {
        Error::InvalidParameter { .. } => "InvalidParameter",
        Error::DuplicateDefect { .. } => "DuplicateDefect",
        Error::Parse { .. } => "Parse",
        Error::Singular { .. } => "Singular",
        Error::Unresolvable { .. } => "Unresolvable",
        Error::Numerical { .. } => "Numerical",
        Error::Io { .. } => "Io",
        Error::UnsafeOutput { .. } => "UnsafeOutput",
        Error::ResourceLimit { .. } => "ResourceLimit",
        Error::Cancelled => "Cancelled",
    }
}

/// The Python exception for a library error (message unchanged).
pub fn to_py(e: Error) -> PyErr {
    let msg = e.to_string();
    let err = match &e {
        Error::Io { .. } | Error::UnsafeOutput { .. } => PyOSError::new_err(msg),
        Error::Unresolvable { .. } => UnresolvableError::new_err(msg),
        Error::Numerical { .. } => NumericalError::new_err(msg),
        _ => PyValueError::new_err(msg),
    };
    Python::attach(|py| {
        let v = err.value(py);
        // attributes are a convenience: a failure to set one keeps the error
        let _ = v.setattr("kind", kind(&e));
        let fields = match &e {
            Error::InvalidParameter {
                field,
                value,
                allowed,
            } => Some((field, value, allowed)),
            Error::Parse {
                what,
                input,
                reason,
            } => Some((what, input, reason)),
            _ => None,
        };
        if let Some((field, value, allowed)) = fields {
            let _ = v.setattr("field", field);
            let _ = v.setattr("value", value);
            let _ = v.setattr("allowed", allowed);
        }
    });
    err
}

/// `Result<T, springmass::Error>` into `PyResult<T>`.
pub trait IntoPy<T> {
    /// Map the error with [`to_py`].
    fn py_err(self) -> PyResult<T>;
}

impl<T> IntoPy<T> for Result<T, Error> {
    fn py_err(self) -> PyResult<T> {
        self.map_err(to_py)
    }
}
