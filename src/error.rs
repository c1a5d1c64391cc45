//! One error type for the whole library.
//!
//! Every variant that comes from user input names the offending field and the
//! allowed range, so that the CLI can print it as a one-line message and a
//! library caller can match on it.

use thiserror::Error;

/// Errors returned by the springmass library. The library never panics on
/// user input: every invalid parameter ends here.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum Error {
    /// A parameter is outside its allowed range (or is NaN / infinite).
    #[error("invalid {field} = {value}: allowed {allowed}")]
    InvalidParameter {
        /// Dotted path of the field, for example `defects[2].m` or `s`.
        field: String,
        /// The offending value as the user gave it.
        value: String,
        /// The allowed range in words, for example `m > 0 and finite`.
        allowed: String,
    },

    /// Two defects of one kind at one place.
    #[error("duplicate {kind} defect at position {at}: at most one of each kind per place")]
    DuplicateDefect {
        /// `mass`, `spring` or `damper`.
        kind: &'static str,
        /// The 1-based mass index (or spring index 0..=n).
        at: usize,
    },

    /// A textual input (defect spec, complex number, CSV line, TOML) could not be parsed.
    #[error("cannot parse {what} {input:?}: {reason}")]
    Parse {
        /// What was being parsed, for example `defect` or `s` or `line 17`.
        what: String,
        /// The input text.
        input: String,
        /// Why it failed, including the expected form.
        reason: String,
    },

    /// The value is a pole of the response (resonance of an undamped chain on the
    /// imaginary axis): the Laplace transform does not exist there.
    #[error("s = {s} is a pole of the response (singular system); move s off the imaginary axis or add damping")]
    Singular {
        /// The offending s, formatted.
        s: String,
    },

    /// f64 (or the chosen precision) cannot resolve the requested quantity:
    /// the signal lies below the rounding or data-error floor.
    #[error("not resolvable at this precision: {reason}")]
    Unresolvable {
        /// What could not be resolved and why.
        reason: String,
    },

    /// A numerical method could not reach the requested accuracy.
    #[error("numerical method {method} failed: {reason}")]
    Numerical {
        /// Name of the method.
        method: String,
        /// What went wrong.
        reason: String,
    },

    /// An I/O problem (reading or writing a file).
    #[error("i/o error on {path}: {reason}")]
    Io {
        /// The file.
        path: String,
        /// The OS message.
        reason: String,
    },

    /// An output path that must not be written: a directory, a device, a FIFO,
    /// a socket, or a symbolic link to one of them (see [`crate::io::write_atomic`]).
    #[error("refusing to write {path}: {reason}")]
    UnsafeOutput {
        /// The path as given.
        path: String,
        /// What it is and what is allowed.
        reason: String,
    },

    /// A job whose estimated memory exceeds the budget (see [`crate::io::check_alloc`]).
    #[error("{what} needs about {need} of memory, above the budget of {budget}")]
    ResourceLimit {
        /// The job and the parameters that drive its size.
        what: String,
        /// The estimate.
        need: String,
        /// The budget, and how to change it.
        budget: String,
    },

    /// The call was stopped by [`crate::cancel::request`] (Ctrl-C in the
    /// Python package) before it finished.
    #[error("cancelled: the call was interrupted before it finished")]
    Cancelled,
}

/// Process exit statuses of the `springmass` command, one per class of error
/// ([`Error::exit_code`]).
pub mod exit {
    /// Success.
    pub const OK: i32 = 0;
    /// Anything else (a numerical method that failed, an internal error).
    pub const OTHER: i32 = 1;
    /// Usage error or invalid input (bad option, value out of range, unparsable
    /// file, a job above the memory budget).
    pub const USAGE: i32 = 2;
    /// Input/output error (a file that cannot be read or written, an output
    /// path that is a device, FIFO, socket or directory, a full disk or stdout).
    pub const IO: i32 = 3;
    /// The data cannot resolve the requested result (signal below the
    /// rounding or noise floor).
    pub const UNRESOLVABLE: i32 = 4;
    /// Interrupted ([`super::Error::Cancelled`]; 128 + SIGINT, as a shell reports it).
    pub const INTERRUPTED: i32 = 130;
}

impl Error {
    /// The process exit status for this error (see [`exit`]): 2 for invalid
    /// input (parameters, parse errors, duplicates, poles, limits), 3 for I/O,
    /// 4 for [`Error::Unresolvable`], 1 for [`Error::Numerical`].
    ///
    /// ```
    /// use springmass::Error;
    /// assert_eq!(Error::invalid("n", 0, ">= 1").exit_code(), 2);
    /// assert_eq!(Error::io("a.csv", "denied").exit_code(), 3);
    /// assert_eq!(Error::Unresolvable { reason: "floor".into() }.exit_code(), 4);
    /// ```
    pub fn exit_code(&self) -> i32 {
        match self {
            Error::InvalidParameter { .. }
            | Error::DuplicateDefect { .. }
            | Error::Parse { .. }
            | Error::Singular { .. }
            | Error::ResourceLimit { .. } => exit::USAGE,
            Error::Io { .. } | Error::UnsafeOutput { .. } => exit::IO,
            Error::Unresolvable { .. } => exit::UNRESOLVABLE,
            Error::Numerical { .. } => exit::OTHER,
            Error::Cancelled => exit::INTERRUPTED,
        }
    }

    /// Shorthand for [`Error::InvalidParameter`].
    pub fn invalid(
        field: impl Into<String>,
        value: impl ToString,
        allowed: impl Into<String>,
    ) -> Self {
        Error::InvalidParameter {
            field: field.into(),
            value: clip_echo(value.to_string()),
            allowed: allowed.into(),
        }
    }

    /// Shorthand for [`Error::Parse`].
    pub fn parse(
        what: impl Into<String>,
        input: impl Into<String>,
        reason: impl Into<String>,
    ) -> Self {
        Error::Parse {
            what: what.into(),
            input: clip_echo(input.into()),
            reason: reason.into(),
        }
    }

    /// Shorthand for [`Error::Io`].
    pub fn io(path: impl AsRef<std::path::Path>, err: impl ToString) -> Self {
        Error::Io {
            path: path.as_ref().display().to_string(),
            reason: err.to_string(),
        }
    }
}

/// Longest echoed input in an error message, in bytes.
pub const MAX_ECHO: usize = 200;

/// Cut an echoed input to [`MAX_ECHO`] bytes (at a character boundary), saying
/// how long it was, so that a 10 MB line is not printed back whole.
///
/// ```
/// let long = "x".repeat(10_000);
/// let cut = springmass::error::clip_echo(long);
/// assert!(cut.len() < 300 && cut.contains("10000 bytes"));
/// ```
pub fn clip_echo(text: String) -> String {
    if text.len() <= MAX_ECHO {
        return text;
    }
    let mut end = MAX_ECHO;
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    format!("{}... ({} bytes in all)", &text[..end], text.len())
}

/// Result alias used throughout the crate.
pub type Result<T> = std::result::Result<T, Error>;

/// Check that `value` is finite and satisfies `ok`, or return an
/// [`Error::InvalidParameter`] naming `field` and `allowed`.
pub fn check_f64(field: &str, value: f64, ok: bool, allowed: &str) -> Result<f64> {
    if value.is_finite() && ok {
        Ok(value)
    } else {
        Err(Error::invalid(field, value, allowed))
    }
}
