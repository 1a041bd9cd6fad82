//! The library's errors as Python exceptions, with the message the command line prints.

use pyo3::exceptions::{
    PyException, PyFileExistsError, PyFileNotFoundError, PyIsADirectoryError, PyNotADirectoryError,
    PyOSError, PyPermissionError, PyValueError,
};
use pyo3::PyErr;
use std::io::ErrorKind;

pyo3::create_exception!(
    solidsynth,
    Error,
    PyException,
    "A failure that is not the caller's input (no GPU, a GPU error or timeout, an internal \
     error). Bad input raises ValueError (or an OSError for a file that cannot be read); the \
     message is the one the command line prints."
);

/// The exception for `e`: the caller's input (the CLI's exit code 2) is a `ValueError`, a file
/// that cannot be read or written the matching `OSError`, anything else `solidsynth.Error`. The
/// message is the error and its causes (`Error::report`), as the CLI prints them after
/// "error: ".
pub fn engine_err(e: solidsynth::Error) -> PyErr {
    let message = e.report();
    match &e {
        solidsynth::Error::InvalidInput { .. } | solidsynth::Error::CorruptFile { .. } => {
            PyValueError::new_err(message)
        }
        solidsynth::Error::Io { source, .. } => match source.kind() {
            ErrorKind::NotFound => PyFileNotFoundError::new_err(message),
            ErrorKind::PermissionDenied => PyPermissionError::new_err(message),
            ErrorKind::IsADirectory => PyIsADirectoryError::new_err(message),
            ErrorKind::NotADirectory => PyNotADirectoryError::new_err(message),
            ErrorKind::AlreadyExists => PyFileExistsError::new_err(message),
            _ => PyOSError::new_err(message),
        },
        _ => Error::new_err(message),
    }
}

/// Shorthand for an invalid-input error named as the command line names the value.
pub fn invalid(what: impl Into<String>, problem: impl Into<String>) -> PyErr {
    engine_err(solidsynth::Error::invalid(what, problem))
}
