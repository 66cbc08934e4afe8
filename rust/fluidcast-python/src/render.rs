//! `fluidcast._core.Renderer`: particles, settings, camera and transfer function, rendered
//! by the VTK mapper's engine ([`fluidcast_cxx::Renderer`]) with the GIL released.

use fluidcast_backend::defaults;
use fluidcast_cxx::{
    default_settings, default_surfaces, CameraDesc, RenderInfo, Settings, SurfaceSettings,
};
use fluidcast_sph::{Component, FieldKind, Kernel, Particles, Quantity};
use fluidcast_view::TransferFunction;
use numpy::{
    IntoPyArray, PyArray1, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2,
    PyUntypedArrayMethods,
};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::{Floats, NumpySource};
use crate::value_error;

/// A renderer kept across frames: its particles are built once per change of data or of the
/// settings they depend on, and a GPU it opened is kept.
#[pyclass(name = "Renderer", module = "fluidcast._core")]
pub struct PyRenderer {
    inner: Box<fluidcast_cxx::Renderer>,
    settings: Settings,
    data: Option<Held>,
}

/// The numpy arrays of `set_data`, held (not copied) until the particles are built from them.
struct Held {
    name: String,
    points: Py<PyAny>,
    /// Name, array, components.
    arrays: Vec<(String, Py<PyAny>, usize)>,
    field: Vec<(String, f64)>,
    n: usize,
}

impl Held {
    /// The arrays as a particle source, borrowed for the GIL's lifetime `py`.
    fn source<'py>(&self, py: Python<'py>) -> PyResult<NumpySource<'py>> {
        let arrays = self
            .arrays
            .iter()
            .map(|(n, a, k)| Ok((n.clone(), Floats::of(a.bind(py), n)?, *k)))
            .collect::<PyResult<_>>()?;
        Ok(NumpySource {
            path: self.name.clone().into(),
            points: Floats::of(self.points.bind(py), "points")?,
            arrays,
            field: self.field.clone(),
        })
    }
}

/// Sets `s.field` from `value` for each key named among `fields`, or refuses the key.
macro_rules! settings_from {
    ($s:ident, $key:ident, $value:ident, [$($field:ident),* $(,)?]) => {
        match $key.as_str() {
            $(stringify!($field) => {
                $s.$field = $value.extract().map_err(|e| {
                    value_error(format!("setting {}: {e}", stringify!($field)))
                })?
            })*
            other => {
                let known = [$(stringify!($field)),*].join(", ");
                return Err(value_error(format!("no setting '{other}' (settings: {known})")));
            }
        }
    };
}

/// The settings `d` gives over the defaults (keys: `fluidcast_cxx::Settings`' fields).
fn settings_of(d: &Bound<'_, PyDict>) -> PyResult<Settings> {
    let mut s = default_settings();
    for (k, value) in d.iter() {
        let key: String = k.extract()?;
        settings_from!(
            s,
            key,
            value,
            [
                scalars,
                component,
                support_radius,
                radius_array,
                radius_scale,
                kernel,
                field,
                error_tolerance,
                backend,
                adapter,
                memory_limit_mib,
                work_limit,
                lod_tolerance,
                rbf_classification,
                rbf_radius,
                samples_per_pixel,
                progressive_passes,
                shadows,
                light,
                shadow_ambient,
                radius_map,
                mode,
                grid_cell,
                probe,
                superpixels,
                surface_cells,
                interpolate,
                tiles,
                relax,
                strict,
                bundle,
                depth_samples,
                sampling_scale,
                occlusion_culling,
                rbf_noise,
                rbf_seed,
                rbf_leaf_size,
                rbf_step,
                shadow_samples,
                shade_volume,
            ]
        );
    }
    Ok(s)
}

/// The iso-surface settings `d` gives (keys: `fluidcast_cxx::SurfaceSettings`' fields).
fn surfaces_of(d: &Bound<'_, PyDict>) -> PyResult<SurfaceSettings> {
    let mut s = default_surfaces();
    for (k, value) in d.iter() {
        let key: String = k.extract()?;
        settings_from!(
            s,
            key,
            value,
            [
                iso_values,
                iso_field,
                opacity,
                with_volume,
                shade,
                ambient,
                diffuse,
                specular,
                specular_power,
            ]
        );
    }
    Ok(s)
}

/// The transfer function of a built-in preset (any case) or a ParaView preset `.json` file.
pub(crate) fn preset(name: &str) -> PyResult<TransferFunction> {
    let builtin = TransferFunction::builtin_names()
        .iter()
        .find(|b| b.eq_ignore_ascii_case(name.trim()));
    match (builtin, TransferFunction::preset(name)) {
        (Some(b), _) => TransferFunction::preset(b).map_err(value_error),
        (None, Ok(tf)) => Ok(tf),
        (None, Err(_)) if name.to_ascii_lowercase().ends_with(".json") => {
            let text = fluidcast_mem::read_text(std::path::Path::new(name))
                .map_err(|e| value_error(format!("{name}: {e}")))?;
            TransferFunction::from_paraview_json(&text, name).map_err(value_error)
        }
        (None, Err(e)) => Err(value_error(e)),
    }
}

/// What a render or `prepare` did, as a dict.
fn info_dict<'py>(py: Python<'py>, i: &RenderInfo) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("particles", i.particles)?;
    d.set_item("skipped_nonfinite", i.skipped_nonfinite)?;
    d.set_item("radius_min", i.radius_min)?;
    d.set_item("radius_max", i.radius_max)?;
    d.set_item("value_min", i.value_min)?;
    d.set_item("value_max", i.value_max)?;
    d.set_item("samples", i.samples)?;
    d.set_item("total_ms", i.total_ms)?;
    let notes: Vec<&str> = i.notes.lines().filter(|l| !l.is_empty()).collect();
    d.set_item("notes", notes)?;
    d.set_item("device", &i.device)?;
    d.set_item("tiles", i.tiles)?;
    Ok(d)
}

#[pymethods]
impl PyRenderer {
    #[new]
    fn new() -> PyRenderer {
        PyRenderer {
            inner: fluidcast_cxx::new_renderer(),
            settings: default_settings(),
            data: None,
        }
    }

    /// New particles: `points` (N×3 float32/float64, world space), point `arrays` ({name:
    /// N or N×k array of float32/float64}) and `field` data ({name: number}, e.g.
    /// support_radius); `name` appears in error messages. The arrays are checked and held,
    /// not copied: `configure` builds the renderer's particles from them.
    fn set_data(
        &mut self,
        name: &str,
        points: &Bound<'_, PyAny>,
        arrays: &Bound<'_, PyDict>,
        field: &Bound<'_, PyDict>,
    ) -> PyResult<()> {
        self.data = None;
        self.inner.begin_data(name);
        let p = Floats::of(points, "points")?;
        let shape = p.shape();
        if shape.len() != 2 || shape[1] != 3 {
            return Err(value_error(format!(
                "{name}: points of shape {shape:?}; expected (N, 3)"
            )));
        }
        p.slice(&format!("{name}: points"))?;
        let n = shape[0];
        let mut held = Vec::new();
        for (k, v) in arrays.iter() {
            let key: String = k.extract()?;
            let what = format!("{name}: point array '{key}'");
            let a = Floats::of(&v, &what)?;
            let (rows, components) = a.rows();
            if rows != n || a.shape().is_empty() {
                return Err(value_error(format!(
                    "{what} has {} values, expected {n} points x {components} components",
                    rows * components
                )));
            }
            a.slice(&what)?;
            held.push((key, v.clone().unbind(), components));
        }
        let field = field
            .iter()
            .map(|(k, v)| Ok((k.extract::<String>()?, v.extract::<f64>()?)))
            .collect::<PyResult<_>>()?;
        self.data = Some(Held {
            name: name.to_string(),
            points: points.clone().unbind(),
            arrays: held,
            field,
            n,
        });
        Ok(())
    }

    /// The settings of the renders that follow: a dict of `fluidcast_cxx::Settings`' fields
    /// (support_radius, kernel, error_tolerance, ...) over the mapper's defaults.
    /// The particles are built here, from the arrays `set_data` holds (with the GIL held:
    /// they are read in place).
    fn configure(&mut self, py: Python<'_>, settings: &Bound<'_, PyDict>) -> PyResult<()> {
        let s = settings_of(settings)?;
        self.inner.configure(&s).map_err(value_error)?;
        self.settings = s;
        let data = self
            .data
            .as_ref()
            .ok_or_else(|| value_error("no particles: call set_data first"))?;
        let src = data.source(py)?;
        self.inner.prepare_source(&src).map_err(value_error)?;
        Ok(())
    }

    /// The view: vtkCamera's fields (world space; view angle vertical, degrees).
    #[pyo3(signature = (position, focal_point, view_up, view_angle = 30.0,
                        parallel_projection = false, parallel_scale = 1.0))]
    fn set_camera(
        &mut self,
        position: [f64; 3],
        focal_point: [f64; 3],
        view_up: [f64; 3],
        view_angle: f64,
        parallel_projection: bool,
        parallel_scale: f64,
    ) -> PyResult<()> {
        let c = CameraDesc {
            position,
            focal_point,
            view_up,
            view_angle,
            parallel_projection,
            parallel_scale,
        };
        self.inner.set_camera(&c).map_err(value_error)
    }

    /// The transfer function from tables sampled evenly over `lo..hi`: `rgb` (n×3, 0..1)
    /// and `opacity` (n, per `unit_distance` world units).
    fn set_transfer_function(
        &mut self,
        lo: f64,
        hi: f64,
        rgb: PyReadonlyArray2<'_, f64>,
        opacity: PyReadonlyArray1<'_, f64>,
        unit_distance: f64,
    ) -> PyResult<()> {
        let rgb = rgb.as_slice().map_err(value_error)?;
        let opacity = opacity.as_slice().map_err(value_error)?;
        self.inner
            .set_transfer_function(lo, hi, rgb, opacity, unit_distance)
            .map_err(value_error)
    }

    /// The transfer function of a CLI preset or ParaView preset file (`fluidcast render
    /// --tf`), over `lo..hi`, its opacity per `unit_distance` world units.
    fn set_preset(&mut self, name: &str, lo: f64, hi: f64, unit_distance: f64) -> PyResult<()> {
        let tf = preset(name)?;
        let mut tf = tf.with_range(lo, hi).map_err(value_error)?;
        if !(unit_distance.is_finite() && unit_distance > 0.0) {
            return Err(value_error(format!(
                "opacity unit distance {unit_distance} must be > 0"
            )));
        }
        tf.unit_distance = unit_distance;
        self.inner.set_transfer(tf);
        Ok(())
    }

    /// The iso-surfaces of the renders that follow: a dict of `fluidcast_cxx::SurfaceSettings`'
    /// fields (iso_values, iso_field, opacity, with_volume, shade, ...).
    fn set_surfaces(&mut self, py: Python<'_>, surfaces: &Bound<'_, PyDict>) -> PyResult<()> {
        let s = surfaces_of(surfaces)?;
        let named = |d: &Held| d.arrays.iter().any(|(n, _, _)| *n == s.iso_field);
        if let Some(d) = self.data.as_ref().filter(|d| named(d)) {
            if s.iso_field != self.settings.scalars && !s.iso_values.is_empty() {
                let q = Quantity {
                    array: s.iso_field.clone(),
                    component: Component::Auto,
                };
                let v = Particles::values_of(&d.source(py)?, &q).map_err(value_error)?;
                self.inner.set_iso_attribute(&s.iso_field, v);
            }
        }
        self.inner.set_surfaces(&s).map_err(value_error)
    }

    /// Builds the particles now and says what they are (count, radius and value ranges,
    /// notes), with the GIL released.
    fn prepare<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let r = &mut self.inner;
        let info = py.detach(|| r.prepare()).map_err(value_error)?;
        info_dict(py, &info)
    }

    /// Renders `width`×`height` with the GIL released: (premultiplied RGBA, H×W×4 float32;
    /// view depth where the opacity passed 1/2, H×W float32, +inf elsewhere; what it did).
    /// `depth_limit`: None or H×W view depths (world units along the view axis) past which
    /// nothing is composited, +inf where nothing is opaque.
    #[pyo3(signature = (width, height, depth_limit = None))]
    #[allow(clippy::type_complexity, reason = "the tuple is Python's return value")]
    fn render<'py>(
        &mut self,
        py: Python<'py>,
        width: u32,
        height: u32,
        depth_limit: Option<PyReadonlyArray2<'py, f32>>,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>, Bound<'py, PyDict>)> {
        let (w, h) = (width as usize, height as usize);
        let limit: Vec<f32> = match &depth_limit {
            None => Vec::new(),
            Some(d) if d.shape() == [h, w] => d.as_slice().map_err(value_error)?.to_vec(),
            Some(d) => {
                return Err(value_error(format!(
                    "depth_limit of shape {:?} for a {width}x{height} image (expected ({h}, {w}))",
                    d.shape()
                )))
            }
        };
        let n = w
            .checked_mul(h)
            .filter(|&n| n > 0 && n <= 1 << 28)
            .ok_or_else(|| {
                value_error(format!(
                    "image size {width}x{height}: each side 1 or more, at most 2^28 pixels"
                ))
            })?;
        let (mut rgba, mut depth) = (vec![0f32; 4 * n], vec![0f32; n]);
        let r = &mut self.inner;
        let info = py
            .detach(|| r.render(width, height, &limit, &mut rgba, &mut depth))
            .map_err(value_error)?;
        let rgba = rgba.into_pyarray(py).reshape([h, w, 4])?.into_any();
        let depth = depth.into_pyarray(py).reshape([h, w])?.into_any();
        Ok((rgba, depth, info_dict(py, &info)?))
    }

    /// The field at `points` (M×3 float64, world space): a dict of M-arrays `value` (the
    /// configured field: CSPH, SPH or density; NaN where undefined), `shepard` (Σ V W, the
    /// colour field), `density` (Σ m W) and `neighbours` (particles whose support holds the
    /// point), as `fluidcast probe` writes them.
    fn interpolate<'py>(
        &mut self,
        py: Python<'py>,
        points: PyReadonlyArray2<'py, f64>,
    ) -> PyResult<Bound<'py, PyDict>> {
        if points.shape()[1] != 3 {
            return Err(value_error(format!(
                "points of shape {:?}; expected (M, 3)",
                points.shape()
            )));
        }
        let flat = points.as_slice().map_err(value_error)?;
        let pts: Vec<[f64; 3]> = flat.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
        let kind: FieldKind = self.settings.field.parse().map_err(value_error)?;
        let r = &mut self.inner;
        let samples = py.detach(|| r.interpolate(&pts)).map_err(value_error)?;
        let column = |f: &dyn Fn(&fluidcast_sph::FieldSample) -> f64| -> Bound<'py, PyArray1<f64>> {
            samples.iter().map(f).collect::<Vec<f64>>().into_pyarray(py)
        };
        let d = PyDict::new(py);
        d.set_item("value", column(&|s| s.value(kind).unwrap_or(f64::NAN)))?;
        d.set_item("shepard", column(&|s| s.shepard))?;
        d.set_item("density", column(&|s| s.density))?;
        d.set_item("neighbours", column(&|s| s.neighbours as f64))?;
        Ok(d)
    }

    /// What the CLI chooses when not told, for these particles and settings: `camera` (a
    /// dict of vtkCamera's fields: reset on the supports, looking down -z; parallel
    /// projection when `parallel`), `range` (the colour map's: the rendered values', or for
    /// a sum field 0 to its typical value) and `unit_distance` (world units).
    #[pyo3(signature = (parallel = false))]
    fn defaults<'py>(&mut self, py: Python<'py>, parallel: bool) -> PyResult<Bound<'py, PyDict>> {
        let field: FieldKind = match self.settings.field.as_str() {
            f if f.eq_ignore_ascii_case("rbf") => FieldKind::Csph,
            f => f.parse().map_err(value_error)?,
        };
        let kernel: Kernel = self.settings.kernel.parse().map_err(value_error)?;
        let r = &mut self.inner;
        let (c, range, unit) = py
            .detach(|| {
                r.particles().map(|p| {
                    (
                        defaults::auto_camera(p, parallel),
                        defaults::auto_range(p, kernel, field),
                        defaults::auto_unit_distance(p),
                    )
                })
            })
            .map_err(value_error)?;
        let cam = PyDict::new(py);
        cam.set_item("position", c.position)?;
        cam.set_item("focal_point", c.focal_point)?;
        cam.set_item("view_up", c.view_up)?;
        cam.set_item("view_angle", c.view_angle)?;
        cam.set_item("parallel_projection", c.parallel_projection)?;
        cam.set_item("parallel_scale", c.parallel_scale)?;
        let d = PyDict::new(py);
        d.set_item("camera", cam)?;
        d.set_item("range", range)?;
        d.set_item("unit_distance", unit)?;
        Ok(d)
    }

    /// Particles in the last data set given.
    #[getter]
    fn points(&self) -> usize {
        self.data.as_ref().map_or(0, |d| d.n)
    }
}
