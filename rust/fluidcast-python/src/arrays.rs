//! numpy arrays as slices: float32 and float64 read in place, anything else refused here
//! (the Python layer converts other dtypes once, with `numpy.ascontiguousarray`).

use std::borrow::Cow;
use std::path::{Path, PathBuf};

use fluidcast_io::{DataArray, ScalarType};
use fluidcast_sph::{ParticleError, ParticleSource};
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

/// Particles as numpy arrays, read in place: a [`ParticleSource`] whose points and arrays are
/// borrowed for the build of the renderer's particles (float64 points are read as they are;
/// float32 ones and every array are converted one at a time and dropped after use).
pub(crate) struct NumpySource<'py> {
    /// The name errors give.
    pub path: PathBuf,
    /// N×3 points.
    pub points: Floats<'py>,
    /// Point arrays: name, values, components.
    pub arrays: Vec<(String, Floats<'py>, usize)>,
    /// Field-data values (`support_radius`).
    pub field: Vec<(String, f64)>,
}

impl NumpySource<'_> {
    fn convert(v: Values<'_>) -> Vec<f64> {
        match v {
            Values::F32(s) => s.iter().map(|&x| f64::from(x)).collect(),
            Values::F64(s) => s.to_vec(),
        }
    }

    fn error(&self, e: PyErr) -> ParticleError {
        ParticleError::Other {
            file: self.path.clone(),
            message: e.to_string(),
        }
    }
}

impl ParticleSource for NumpySource<'_> {
    fn path(&self) -> &Path {
        &self.path
    }
    fn num_points(&self) -> usize {
        self.points.rows().0
    }
    fn field_scalar(&self, name: &str) -> Option<f64> {
        self.field.iter().find(|(n, _)| n == name).map(|(_, v)| *v)
    }
    fn arrays(&self) -> Vec<(String, usize)> {
        self.arrays
            .iter()
            .map(|(n, _, k)| (n.clone(), *k))
            .collect()
    }
    fn points(&self) -> Result<Cow<'_, [f64]>, ParticleError> {
        match self.points.slice("points").map_err(|e| self.error(e))? {
            Values::F64(s) => Ok(Cow::Borrowed(s)),
            v => Ok(Cow::Owned(Self::convert(v))),
        }
    }
    fn array(&self, name: &str) -> Result<Option<Cow<'_, DataArray>>, ParticleError> {
        let Some((n, a, k)) = self.arrays.iter().find(|(n, _, _)| n == name) else {
            return Ok(None);
        };
        let v = a.slice(n).map_err(|e| self.error(e))?;
        let scalar_type = match v {
            Values::F32(_) => ScalarType::F32,
            Values::F64(_) => ScalarType::F64,
        };
        Ok(Some(Cow::Owned(DataArray {
            name: n.clone(),
            scalar_type,
            num_components: *k,
            values: Self::convert(v),
        })))
    }
}
