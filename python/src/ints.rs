//! Python ints of any size as arguments: a value past the engine's integer types is refused
//! with a `ValueError` naming its argument and the range the engine accepts, where PyO3's own
//! conversion raises `OverflowError` naming neither.

use crate::errors::engine_err;
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyInt};

/// An int argument: its value where it fits an i128, and its text for messages.
#[derive(Clone)]
pub struct Int {
    value: Option<i128>,
    text: String,
}

impl Int {
    pub fn of(value: i128) -> Int {
        Int {
            value: Some(value),
            text: value.to_string(),
        }
    }

    /// As the user wrote it (in decimal).
    pub fn text(&self) -> &str {
        &self.text
    }

    /// The value as `T`, or `None` where it does not fit.
    pub fn get<T: TryFrom<i128>>(&self) -> Option<T> {
        self.value.and_then(|v| T::try_from(v).ok())
    }

    /// The value as `T`; where it does not fit, the `ValueError` the engine's own check gives
    /// a value it refuses (`refused`, an error the check returned), with this value's text in
    /// it: the message then states the engine's real range.
    pub fn or_refused<T: TryFrom<i128>>(&self, refused: solidsynth::Error) -> PyResult<T> {
        self.get().ok_or_else(|| match refused {
            solidsynth::Error::InvalidInput { what, problem } => {
                // The flag without the probed value (`--max-group 0` -> `--max-group`).
                let flag = what.split_whitespace().next().unwrap_or(&what).to_string();
                PyValueError::new_err(format!("invalid {flag} {}: {problem}", self.text))
            }
            other => engine_err(other),
        })
    }

    /// The value as `T`, else `ValueError` naming `--name` and `T`'s range.
    pub fn in_range<T: TryFrom<i128> + Bounds>(&self, name: &str) -> PyResult<T> {
        self.get().ok_or_else(|| {
            PyValueError::new_err(format!(
                "invalid --{} {}: must be {}..={}",
                name.replace('_', "-"),
                self.text,
                T::LOW,
                T::HIGH
            ))
        })
    }
}

impl<'a, 'py> FromPyObject<'a, 'py> for Int {
    type Error = PyErr;

    fn extract(obj: Borrowed<'a, 'py, PyAny>) -> PyResult<Int> {
        // Anything with `__index__` (NumPy's integers too) but bool, which is an int in Python
        // but as a number a mistake.
        let int = match obj.is_instance_of::<PyBool>() {
            true => None,
            false => index(&obj),
        };
        let Some(int) = int else {
            return Err(PyTypeError::new_err(format!(
                "expected an int, got {}",
                obj.get_type().name()?
            )));
        };
        Ok(Int {
            value: int.extract::<i128>().ok(),
            text: int.str()?.to_string(),
        })
    }
}

/// `operator.index(obj)`: the Python int an integer-like object stands for.
pub fn index<'py>(obj: &Bound<'py, PyAny>) -> Option<Bound<'py, PyInt>> {
    if obj.is_instance_of::<PyInt>() {
        return obj.cast::<PyInt>().ok().cloned();
    }
    let int = obj.call_method0("__index__").ok()?;
    int.cast_into::<PyInt>().ok()
}

/// The bounds an integer argument is checked against, for messages.
pub trait Bounds {
    const LOW: i128;
    const HIGH: i128;
}

impl Bounds for u32 {
    const LOW: i128 = 0;
    const HIGH: i128 = u32::MAX as i128;
}

impl Bounds for u64 {
    const LOW: i128 = 0;
    const HIGH: i128 = u64::MAX as i128;
}
