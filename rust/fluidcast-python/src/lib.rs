//! `fluidcast._core`: the Python extension module on fluidcast's Rust library, with no VTK.
//!
//! It reads particle files into numpy arrays ([`read`]), and renders and interpolates
//! particles given as numpy arrays ([`render::PyRenderer`]) through the same engine the VTK
//! mapper and ParaView use (`fluidcast_cxx::Renderer`, which builds the library's one
//! [`fluidcast_backend::RenderPlan`]): the same settings, checks and image. The package's
//! Python layer (`python/fluidcast/api.py`) gives it pyvista's argument names.
//!
//! Arrays cross without copies where they can: float32 and float64 arrays are read in place
//! (the particles' own single-precision store is the one copy a render keeps), images and
//! read arrays are handed to numpy as the vectors the library made. Every error is a
//! `ValueError` carrying the library's message; no panic crosses into Python (PyO3 turns one
//! into `PanicException`, and the library's entry points catch their own).
#![warn(missing_docs)]

mod arrays;
mod render;

use std::path::Path;

use fluidcast_io::{Arrays, DataArray, Input};
use numpy::{IntoPyArray, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

/// A `ValueError` with `message`.
pub(crate) fn value_error(message: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(message.to_string())
}

/// Reads one frame of a particle file: a `.vtu`, `.vtp`, legacy `.vtk`, `.pvtu`/`.pvtp`
/// (with its pieces) or a `.pvd` series' time step `step` (0: the first; its data sets
/// appended). Returns a dict: `points` (N×3 float64, world space), `point_data` and
/// `field_data` ({name: array}, N×k for k > 1 components), `path`, `time` (None for a single
/// file) and `times` (every time step's time, a `.pvd`'s; [] otherwise).
/// `arrays`: the point arrays to decode (None: every one); the rest are not read.
#[pyfunction]
#[pyo3(signature = (path, step = 0, arrays = None))]
fn read<'py>(
    py: Python<'py>,
    path: &str,
    step: usize,
    arrays: Option<Vec<String>>,
) -> PyResult<Bound<'py, PyDict>> {
    let which = arrays.map_or(Arrays::All, Arrays::Named);
    let (ds, time, times) = py
        .detach(|| read_frame(Path::new(path), step, &which))
        .map_err(value_error)?;
    let out = PyDict::new(py);
    let points: Vec<f64> = ds.points.iter().flatten().copied().collect();
    let n = ds.points.len();
    out.set_item("points", points.into_pyarray(py).reshape([n, 3])?)?;
    out.set_item("point_data", arrays_dict(py, ds.point_data)?)?;
    out.set_item("field_data", arrays_dict(py, ds.field_data)?)?;
    out.set_item("path", ds.path.display().to_string())?;
    out.set_item("time", time)?;
    out.set_item("times", times)?;
    Ok(out)
}

/// The data set of frame `step` of `path`, its time and every frame's time.
fn read_frame(
    path: &Path,
    step: usize,
    arrays: &Arrays,
) -> Result<(fluidcast_io::Dataset, Option<f64>, Vec<f64>), String> {
    let input = Input::open(path).map_err(|e| e.to_string())?;
    let frames = input.frames();
    let frame = frames.get(step).ok_or_else(|| {
        format!(
            "{}: time step {step}, but it has {} (0 to {})",
            path.display(),
            frames.len(),
            frames.len().saturating_sub(1)
        )
    })?;
    let ds = input.read_frame(frame, arrays).map_err(|e| e.to_string())?;
    if let Some(dropped) = ds.cells.dropped() {
        return Err(fluidcast_cxx::mesh_refusal(
            &ds.path.display().to_string(),
            &dropped,
        ));
    }
    let times = frames.iter().filter_map(|f| f.0).collect();
    Ok((ds, frame.0, times))
}

/// `arrays` as {name: numpy array}, N×k for arrays of k > 1 components.
fn arrays_dict(py: Python<'_>, arrays: Vec<DataArray>) -> PyResult<Bound<'_, PyDict>> {
    let d = PyDict::new(py);
    for a in arrays {
        let k = a.num_components.max(1);
        let n = a.values.len() / k;
        let values = a.values.into_pyarray(py);
        if k == 1 {
            d.set_item(a.name, values)?;
        } else {
            d.set_item(a.name, values.reshape([n, k])?)?;
        }
    }
    Ok(d)
}

/// The time steps of a `.pvd` series in time order: a list of (time, [files]), the files
/// resolved against its folder and not opened.
#[pyfunction]
fn series(py: Python<'_>, path: &str) -> PyResult<Vec<(f64, Vec<String>)>> {
    let c = py
        .detach(|| fluidcast_io::read_collection(path))
        .map_err(value_error)?;
    Ok(c.steps()
        .map(|step| {
            let time = step.first().map_or(0.0, |e| e.timestep);
            let files = step.iter().map(|e| e.file.display().to_string()).collect();
            (time, files)
        })
        .collect())
}

/// Refuses `value` for setting `property` (the mapper's and ParaView's property name,
/// e.g. "SupportRadius") as every front-end does: returns the reason, or None when taken.
#[pyfunction]
fn check_setting(property: &str, value: f64) -> Option<String> {
    fluidcast_backend::check_property(property, value)
        .err()
        .map(|e| e.to_string())
}

/// The numeric settings' table: (property, CLI flag, Python argument, meaning) each.
#[pyfunction]
fn settings_table() -> Vec<(&'static str, &'static str, &'static str, &'static str)> {
    fluidcast_backend::SETTINGS
        .iter()
        .map(|s| (s.property, s.flag, s.python, s.meaning))
        .collect()
}

/// The names the library takes: kernels, fields, modes, backends, transfer-function presets.
#[pyfunction]
fn names(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    let d = PyDict::new(py);
    let kernels: Vec<&str> = fluidcast_sph::Kernel::ALL
        .iter()
        .map(|k| k.name())
        .collect();
    d.set_item("kernels", PyList::new(py, kernels)?)?;
    let fields: Vec<&str> = fluidcast_sph::FieldKind::ALL
        .iter()
        .map(|f| f.name())
        .collect();
    d.set_item("fields", PyList::new(py, fields)?)?;
    d.set_item("modes", PyList::new(py, fluidcast_backend::Mode::NAMES)?)?;
    d.set_item(
        "backends",
        PyList::new(py, fluidcast_backend::Backend::NAMES)?,
    )?;
    let volume_arrays: Vec<&str> = [
        fluidcast_sph::MASS_NAMES,
        fluidcast_sph::DENSITY_NAMES,
        fluidcast_sph::VOLUME_NAMES,
    ]
    .concat();
    d.set_item("volume_arrays", PyList::new(py, volume_arrays)?)?;
    let presets = fluidcast_view::TransferFunction::builtin_names();
    d.set_item("presets", PyList::new(py, presets)?)?;
    Ok(d)
}

/// Writes a rendered image by extension: `.png` (8-bit RGB over `background`, as `fluidcast
/// render` writes it; sRGB-encoded when `srgb`) or `.exr` (float RGBA premultiplied + Z).
/// `rgba`: H×W×4 premultiplied float32; `depth`: H×W float32.
#[pyfunction]
#[pyo3(signature = (path, rgba, depth, background = [1.0, 1.0, 1.0], srgb = false))]
fn save_image(
    path: &str,
    rgba: numpy::PyReadonlyArray3<'_, f32>,
    depth: numpy::PyReadonlyArray2<'_, f32>,
    background: [f32; 3],
    srgb: bool,
) -> PyResult<()> {
    let shape = rgba.shape().to_vec();
    let (h, w) = (shape[0], shape[1]);
    if shape[2] != 4 || depth.shape() != [h, w] {
        return Err(value_error(format!(
            "{path}: rgba of shape {shape:?} and depth of shape {:?}; expected (H, W, 4) and (H, W)",
            depth.shape()
        )));
    }
    let px = rgba.as_slice().map_err(value_error)?;
    let mut image = fluidcast_image::Image::new(
        u32::try_from(w).map_err(value_error)?,
        u32::try_from(h).map_err(value_error)?,
    );
    for (p, c) in image.rgba.iter_mut().zip(px.chunks_exact(4)) {
        p.copy_from_slice(c);
    }
    image.depth = depth.as_slice().map_err(value_error)?.to_vec();
    let encoding = if srgb {
        fluidcast_image::PngEncoding::Srgb
    } else {
        fluidcast_image::PngEncoding::Vtk
    };
    image
        .save(Path::new(path), background, encoding)
        .map_err(value_error)
}

/// A transfer-function preset (a built-in name or a ParaView preset file) sampled at `n`
/// evenly spaced points of its range: (colours n×3, opacities n).
#[pyfunction]
fn preset_table<'py>(
    py: Python<'py>,
    name: &str,
    n: usize,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let tf = render::preset(name)?;
    let n = n.clamp(2, 1 << 16);
    let (mut rgb, mut alpha) = (Vec::with_capacity(3 * n), Vec::with_capacity(n));
    for k in 0..n {
        let (c, a) = tf.eval_normalised(k as f64 / (n - 1) as f64);
        rgb.extend(c);
        alpha.push(a);
    }
    let rgb = rgb.into_pyarray(py).reshape([n, 3])?.into_any();
    Ok((rgb, alpha.into_pyarray(py).into_any()))
}

/// The module `fluidcast._core`.
#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(read, m)?)?;
    m.add_function(wrap_pyfunction!(series, m)?)?;
    m.add_function(wrap_pyfunction!(check_setting, m)?)?;
    m.add_function(wrap_pyfunction!(settings_table, m)?)?;
    m.add_function(wrap_pyfunction!(names, m)?)?;
    m.add_function(wrap_pyfunction!(save_image, m)?)?;
    m.add_function(wrap_pyfunction!(preset_table, m)?)?;
    m.add_class::<render::PyRenderer>()?;
    Ok(())
}
