//! numpy arrays as slices: float32 and float64 read in place, anything else refused here
//! (the Python layer converts other dtypes once, with `numpy.ascontiguousarray`).

use numpy::{PyReadonlyArrayDyn, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::value_error;

/// A C-contiguous float32 or float64 numpy array, borrowed for the call.
pub(crate) enum Floats<'py> {
    /// float32.
    F32(PyReadonlyArrayDyn<'py, f32>),
    /// float64.
    F64(PyReadonlyArrayDyn<'py, f64>),
}

impl<'py> Floats<'py> {
    /// `obj` as a float array; `what` names it in the error.
    pub fn of(obj: &Bound<'py, PyAny>, what: &str) -> PyResult<Floats<'py>> {
        if let Ok(a) = obj.extract::<PyReadonlyArrayDyn<'py, f32>>() {
            return Ok(Floats::F32(a));
        }
        if let Ok(a) = obj.extract::<PyReadonlyArrayDyn<'py, f64>>() {
            return Ok(Floats::F64(a));
        }
        let kind = match obj.cast::<PyUntypedArray>() {
            Ok(a) => format!("a numpy array of {}", a.dtype().str()?),
            Err(_) => format!("a {}", obj.get_type().name()?),
        };
        Err(value_error(format!(
            "{what}: expected a float32 or float64 numpy array, not {kind}"
        )))
    }

    /// The array's shape.
    pub fn shape(&self) -> Vec<usize> {
        match self {
            Floats::F32(a) => a.shape().to_vec(),
            Floats::F64(a) => a.shape().to_vec(),
        }
    }

    /// Rows (the first axis; 1 for a 0-d array) and values per row.
    pub fn rows(&self) -> (usize, usize) {
        let s = self.shape();
        match s.as_slice() {
            [] => (1, 1),
            [n] => (*n, 1),
            [n, rest @ ..] => (*n, rest.iter().product()),
        }
    }

    /// The values in memory order, or an error naming `what` if not C-contiguous.
    pub fn slice(&self, what: &str) -> PyResult<Values<'_>> {
        let e = |_| value_error(format!("{what}: the array is not C-contiguous"));
        Ok(match self {
            Floats::F32(a) => Values::F32(a.as_slice().map_err(e)?),
            Floats::F64(a) => Values::F64(a.as_slice().map_err(e)?),
        })
    }
}

/// Borrowed values of a [`Floats`].
pub(crate) enum Values<'a> {
    /// float32.
    F32(&'a [f32]),
    /// float64.
    F64(&'a [f64]),
}
