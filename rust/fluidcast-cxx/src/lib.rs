//! The C++ face of fluidcast: a [`cxx`] bridge used by `vtkFluidCastVolumeMapper`
//! (`cpp_bridge/`) and through it by the ParaView plugin.
//!
//! The C++ side hands over a particle set (points and point arrays as slices over the
//! `vtkDataArray` buffers, `float` or `double`, no copy on the C++ side), the camera (vtkCamera's
//! fields), the transfer function (sampled from `vtkColorTransferFunction` +
//! `vtkPiecewiseFunction`), the kernel, radius and error tolerance, and the view depth of
//! opaque geometry already drawn. It gets back premultiplied RGBA floats and depth.
//!
//! Data flows as in the CLI: the arrays become a [`fluidcast_io::Dataset`], which
//! [`Particles::from_dataset`] turns into the renderer's single-precision layout with the
//! same rules as `fluidcast render` (radius from `SupportRadius`, a radius array, the data's
//! `support_radius` field data or the particle spacing; volume from mass/density arrays).
//! That conversion runs once per change of data or settings, not per frame.
//!
//! Every entry point returns `Result`: C++ sees a `rust::Error` exception carrying the
//! message. Panics are caught and turned into errors; none crosses the boundary.
#![warn(missing_docs)]

mod plan;
mod reader;

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use fluidcast_backend::{Backend, IsoField, Rendered, Scene, Surfaces};
use fluidcast_io::{DataArray, Dataset, DatasetKind, ScalarType};
use fluidcast_sph::{
    Component, FieldSample, Kernel, ParticleSource, ParticleSpec, Particles, Quantity,
    RadiusSource, VolumeSource,
};
use fluidcast_view::{Camera, Light, Lighting, TransferFunction};
use plan::{field_names, plan_of};
pub use reader::refusal as mesh_refusal;
use reader::{particle_reader_claims, read_particle_file, read_series, ParticleFile};

#[allow(
    unsafe_code,
    reason = "cxx generates the FFI shims of this module; everything else in the crate is safe"
)]
#[cxx::bridge(namespace = "fluidcast")]
mod ffi {
    /// vtkCamera's fields (world space; `view_angle` vertical, degrees).
    #[derive(Debug, Clone)]
    struct CameraDesc {
        /// The eye (world units).
        position: [f64; 3],
        /// The point looked at.
        focal_point: [f64; 3],
        /// The up direction.
        view_up: [f64; 3],
        /// Vertical view angle, degrees (perspective).
        view_angle: f64,
        /// Parallel instead of perspective projection.
        parallel_projection: bool,
        /// Half the view's height, world units (parallel projection).
        parallel_scale: f64,
    }

    /// How to reconstruct the field.
    #[derive(Debug, Clone)]
    struct Settings {
        /// Point array rendered ("" = the particle density, value 1 everywhere).
        scalars: String,
        /// -2: the array's single component or a vector's magnitude (ParaView's default);
        /// -1: magnitude; k >= 0: component k.
        component: i32,
        /// Constant support radius H (world units); <= 0: from `radius_array`, else the
        /// data's `support_radius` field data, else 2 x mean particle spacing.
        support_radius: f64,
        /// Per-particle radius array ("" = none); H = `radius_scale` x value.
        radius_array: String,
        /// Factor from `radius_array`'s values to support radii.
        radius_scale: f64,
        /// Kernel name as the CLI's `--kernel` (cubic, quintic, wendland-c2, ...).
        kernel: String,
        /// Field as the CLI's `--field` (csph, sph, density).
        field: String,
        /// Screen-space error tolerance E_I (0..1); <= 0 renders every cell at full rate.
        error_tolerance: f64,
        /// Where frames render: an index into `backend_names()` (0 auto, 1 cpu, 2 gpu).
        backend: i32,
        /// A GPU adapter by a part of its name ("" = the best; FLUIDCAST_ADAPTER applies).
        adapter: String,
        /// Most memory (MiB) a render may take beyond the particles it holds: the view is
        /// rendered in screen tiles to stay within it, to the same image (the plan's probe
        /// decided per tile: within the plan's error); <= 0: no limit.
        memory_limit_mib: f64,
        /// The most kernel evaluations a frame may be estimated to take before it runs
        /// (fluidcast_backend::work); above it the render is refused. 0: the default, 5e10.
        work_limit: f64,
        /// Particle level of detail (Fraedrich et al. 2010): each part of the view is drawn
        /// at the coarsest level of merged particles whose cells are at most this many pixels
        /// at its depth; <= 0: every particle. The hierarchy is built once per data set.
        lod_tolerance: f64,
        /// `field` "rbf" (Morrical et al. 2023's field, the transfer function's opacity as
        /// the density map): "post" (blend the attribute, then colour it) or "pre" (colour
        /// each particle, then blend).
        rbf_classification: String,
        /// RBF radius (world units) of every particle; <= 0: each particle's support radius.
        rbf_radius: f64,
        /// RBF: jittered passes each render adds.
        samples_per_pixel: u32,
        /// RBF: the most passes averaged over renders of an unchanged view (camera, size,
        /// transfer function, settings and data); at most `samples_per_pixel`: none.
        progressive_passes: u32,
        /// RBF: single scattering with volumetric shadows toward a directional light.
        shadows: bool,
        /// RBF shadows: the world direction toward the light; all 0: from above and behind
        /// the camera (the CLI's default).
        light: [f64; 3],
        /// RBF shadows: the light a fully shadowed point still receives (0..1).
        shadow_ambient: f64,
        /// RBF: the radius map, pairs of position on the colour map's range (0..1) and
        /// radius factor (>= 0; 0 hides); empty: 1 everywhere. A change refits the BVH.
        radius_map: Vec<f64>,
        /// The mode as the CLI's `--mode` ("" or "auto": the library's choice; adaptive,
        /// reference, perspective-grid).
        mode: String,
        /// Perspective grid: pixels per grid column side (the CLI's `--grid-cell`, 1..=64).
        grid_cell: u32,
        /// The adaptive plan's switches, as the CLI's `--no-probe`, `--no-superpixels`,
        /// `--no-surface-cells` and `--no-interpolation` turn them off.
        probe: bool,
        /// See `probe`.
        superpixels: bool,
        /// See `probe`.
        surface_cells: bool,
        /// See `probe`.
        interpolate: bool,
        /// Render each view in at least this many screen tiles (the CLI's `--tiles`; 0: as
        /// the memory limit needs).
        tiles: u32,
        /// The relaxation E_relax in [0, 1] (the CLI's `--relax`; 1: the default).
        relax: f64,
        /// The strict bound: no relaxation, super-pixels or interpolation (`--strict`).
        strict: bool,
        /// Ray bundle side D_xy, pixels (`--bundle`, 1..=64; 8: the default).
        bundle: u32,
        /// Depth samples per cell D_z (`--depth-samples`, a power of two in 1..=64; 16).
        depth_samples: u32,
        /// Depth samples per ray relative to the default (`--sampling-scale`, > 0; 1).
        sampling_scale: f64,
        /// Perspective grid: skip tiles no marching pixel reads (off:
        /// `--no-occlusion-culling`, the same image, slower).
        occlusion_culling: bool,
        /// RBF: the jitter's noise, "blue" (default) or "white" (`--noise`).
        rbf_noise: String,
        /// RBF: seed of the per-pixel jitter (`--seed`).
        rbf_seed: u32,
        /// RBF: particles per BVH leaf (`--leaf-size`, 1..=64).
        rbf_leaf_size: u32,
        /// RBF: the step along each ray, world units; <= 0: automatic (`--rbf-step`).
        rbf_step: f64,
        /// RBF shadows: shadow rays per pixel and pass (`--shadow-samples`, 1..=1024).
        shadow_samples: u32,
        /// Light the volume itself (Blinn–Phong with the volume property's coefficients
        /// and a headlight; the CLI's `--shade-volume`): drawn by the reference caster.
        shade_volume: bool,
    }

    /// Iso-surfaces the renders that follow draw (`vtkFluidCastVolumeMapper`'s iso-surface
    /// blend mode, with the volume property's iso values and lighting).
    #[derive(Debug, Clone)]
    struct SurfaceSettings {
        /// Iso values; empty: no surfaces (the volume alone).
        iso_values: Vec<f64>,
        /// "colour" (Σ V W), "density" (Σ m W) or a point array's name (its CSPH field; the
        /// rendered array's component rules when it is the rendered array).
        iso_field: String,
        /// Opacity of the surfaces, (0, 1].
        opacity: f64,
        /// Also composite the volume, in depth order with the surfaces.
        with_volume: bool,
        /// Blinn–Phong lighting with a headlight (vtkVolumeProperty's Shade); off: flat.
        shade: bool,
        /// Ambient share of the lighting (0..1).
        ambient: f64,
        /// Diffuse share (0..1).
        diffuse: f64,
        /// Specular share (0..1).
        specular: f64,
        /// Specular exponent.
        specular_power: f64,
    }

    /// What a render did (for the mapper's messages and tests).
    #[derive(Debug, Clone, Default)]
    struct RenderInfo {
        /// Particles rendered.
        particles: u64,
        /// Points left out for NaN/Inf coordinates.
        skipped_nonfinite: u64,
        /// Smallest support radius (world units).
        radius_min: f64,
        /// Largest support radius (world units).
        radius_max: f64,
        /// Smallest value of the rendered array.
        value_min: f64,
        /// Largest value of the rendered array.
        value_max: f64,
        /// Depth samples composited.
        samples: u64,
        /// Milliseconds the call took.
        total_ms: f64,
        /// How radius and volumes were chosen (one line each), and why `auto` rendered on
        /// the CPU when it did.
        notes: String,
        /// Where the frame rendered: "CPU (N threads)" or "GPU: <adapter>".
        device: String,
        /// Screen tiles the view rendered in (0: one render).
        tiles: u64,
    }

    /// One time step of a `.pvd` series (`vtkFluidCastReader`'s time steps).
    #[derive(Debug, Clone)]
    struct SeriesStep {
        /// The `timestep` attribute (simulation time; 0 when absent).
        time: f64,
        /// The data sets the `.pvd` lists for this time, in its order, resolved against its
        /// folder: one data set, their particles appended.
        files: Vec<String>,
    }

    extern "Rust" {
        /// A particle file read by fluidcast's checked reader (`vtkFluidCastReader`).
        type ParticleFile;

        /// The time steps of a `.pvd` collection, in time order, each with its data sets
        /// (fluidcast-io's `Collection::steps`); the files are not opened. The error names the
        /// `.pvd` and the problem.
        fn read_series(path: &str) -> Result<Vec<SeriesStep>>;

        /// Reads a `.vtu`, `.vtp` or legacy `.vtk` file with every check of `fluidcast
        /// info`; the error names the file and the problem. A file with cells other than
        /// vertices or with cell data (a mesh) is refused by name: the reader hands on
        /// points, vertices, point and field data, and would drop the rest.
        fn read_particle_file(path: &str) -> Result<Box<ParticleFile>>;
        /// Whether fluidcast's particle reader takes `path` (`vtkFluidCastReader::CanReadFile`):
        /// a `.vtu`, `.vtp`, legacy `.vtk` or `.pvd` whose data sets (a `.pvd`'s first time's)
        /// hold particles only, or that is damaged (the reader then says what is wrong).
        /// Not a mesh, a structured grid, another kind of file or a missing one.
        fn particle_reader_claims(path: &str) -> bool;
        /// Point coordinates, x y z per point (world space).
        fn points(self: &ParticleFile) -> &[f64];
        /// Number of point-data (`field_data` false) or field-data arrays.
        fn array_count(self: &ParticleFile, field_data: bool) -> usize;
        fn array_name(self: &ParticleFile, field_data: bool, i: usize) -> &str;
        /// The VTK XML type name the array had in the file (`Float32`, `Int64`, ...).
        fn array_type(self: &ParticleFile, field_data: bool, i: usize) -> &str;
        fn array_components(self: &ParticleFile, field_data: bool, i: usize) -> usize;
        /// Values, tuple after tuple.
        fn array_values(self: &ParticleFile, field_data: bool, i: usize) -> &[f64];

        /// The backend names `Settings::backend` indexes: auto, cpu, gpu.
        fn backend_names() -> Vec<String>;
        /// `Settings::field`'s names in the order of ParaView's FluidCastField enumeration.
        fn field_names() -> Vec<String>;
        /// `Settings::rbf_classification`'s names in the order of ParaView's
        /// FluidCastRBFClassification enumeration.
        fn rbf_classification_names() -> Vec<String>;
        /// `Settings::mode`'s names in the order of ParaView's FluidCastMode enumeration.
        fn mode_names() -> Vec<String>;
        /// `Settings::rbf_noise`'s names in the order of ParaView's FluidCastRBFNoise.
        fn rbf_noise_names() -> Vec<String>;
        /// The kernel names `Settings::kernel` takes, in the order of ParaView's
        /// `FluidCastKernel` (cubic, quintic, wendland-c2, wendland-c4, poly6, gaussian).
        fn kernel_names() -> Vec<String>;
        /// Refuses `value` for the mapper/ParaView property `property` (SupportRadius,
        /// ErrorTolerance, ...) where the library's one table of settings does: the error
        /// says what the property takes. The mapper's setters call it.
        fn check_setting(property: &str, value: f64) -> Result<()>;
        /// Refuses a name the mapper's named property (Kernel, Field, Mode,
        /// RBFClassification, RBFNoise) does not take, as `configure` would.
        fn check_name(property: &str, value: &str) -> Result<()>;

        /// The renderer: holds the particle data, settings, camera and transfer function,
        /// and the opened backend (a GPU device lives as long as the renderer).
        type Renderer;

        fn new_renderer() -> Box<Renderer>;
        /// Starts a new particle set; `name` appears in error messages.
        fn begin_data(self: &mut Renderer, name: &str);
        fn set_points_f32(self: &mut Renderer, xyz: &[f32]) -> Result<()>;
        fn set_points_f64(self: &mut Renderer, xyz: &[f64]) -> Result<()>;
        fn add_point_array_f32(
            self: &mut Renderer,
            name: &str,
            components: usize,
            values: &[f32],
        ) -> Result<()>;
        fn add_point_array_f64(
            self: &mut Renderer,
            name: &str,
            components: usize,
            values: &[f64],
        ) -> Result<()>;
        /// A field-data value such as `support_radius`.
        fn add_field_scalar(self: &mut Renderer, name: &str, value: f64);
        fn configure(self: &mut Renderer, settings: &Settings) -> Result<()>;
        fn set_camera(self: &mut Renderer, camera: &CameraDesc) -> Result<()>;
        /// `rgb` (3 per entry) and `opacity` (per `unit_distance` world units) sampled at
        /// evenly spaced values from `lo` to `hi`.
        fn set_transfer_function(
            self: &mut Renderer,
            lo: f64,
            hi: f64,
            rgb: &[f64],
            opacity: &[f64],
            unit_distance: f64,
        ) -> Result<()>;
        /// The iso-surfaces of the renders that follow (checked here; an iso field that is
        /// another point array must have been added with the data).
        fn set_surfaces(self: &mut Renderer, surfaces: &SurfaceSettings) -> Result<()>;
        /// Builds the particles now (normally done by `render`) and reports them.
        fn prepare(self: &mut Renderer) -> Result<RenderInfo>;
        /// Empty, or a warning for a colour map whose range is a single value that hides
        /// the particles held (a series' first step at rest; the text says what to do).
        fn colour_range_warning(self: &Renderer) -> String;
        /// The smallest and largest view depth of any particle's support for the camera set
        /// (`[zmin, zmax]`, empty without particles in front of it): what MPI ranks reduce
        /// over all of them and pass to `set_part` as `support_depths`.
        fn support_depths(self: &mut Renderer) -> Result<Vec<f64>>;
        /// The part of a data set these particles are, for the renders that follow (an MPI
        /// rank's): `crop` is empty or a world-space box (xmin, xmax, ymin, ymax, zmin, zmax,
        /// as vtkVolumeMapper's CroppingRegionPlanes) outside which nothing is composited;
        /// `support_depths` is empty or `[zmin, zmax]` of the whole data set, over which the
        /// depth samples are placed (RenderParams::support_depths). Empty both: the whole.
        fn set_part(self: &mut Renderer, crop: &[f64], support_depths: &[f64]) -> Result<()>;
        /// Renders a `width x height` image, rows top first. `depth_limit` is empty or one
        /// view depth per pixel (+inf = nothing opaque). Writes premultiplied RGBA
        /// (`4 * width * height`) and the view depth where opacity passed 1/2 (+inf never).
        /// On the GPU backend the colour is read back in half precision and the depth is
        /// not read back (+inf everywhere): a window shows neither more.
        fn render(
            self: &mut Renderer,
            width: u32,
            height: u32,
            depth_limit: &[f32],
            rgba: &mut [f32],
            depth: &mut [f32],
        ) -> Result<RenderInfo>;

        /// A render's progress and a request to stop it, shared with the thread that
        /// renders: the mapper renders on a worker thread and, on its own, polls VTK's abort
        /// check and reports progress.
        type RenderControl;
        fn new_render_control() -> Box<RenderControl>;
        /// The renders that follow report to `control` and stop when it is cancelled.
        fn set_render_control(self: &mut Renderer, control: &RenderControl);
        /// Asks the render to stop (it returns an error saying it was cancelled).
        fn cancel(self: &RenderControl);
        /// Whether `cancel` was called.
        fn cancelled(self: &RenderControl) -> bool;
        /// The share of the ray cast done, 0..=1.
        fn fraction(self: &RenderControl) -> f64;
    }
}

pub use ffi::{CameraDesc, RenderInfo, Settings, SurfaceSettings};

/// [`fluidcast_backend::Progress`] behind the C++ side's handle.
pub struct RenderControl(Arc<fluidcast_backend::Progress>);

fn new_render_control() -> Box<RenderControl> {
    Box::new(RenderControl(Arc::default()))
}

impl RenderControl {
    /// Asks the render to stop.
    pub fn cancel(&self) {
        self.0.cancel();
    }

    fn cancelled(&self) -> bool {
        self.0.cancelled()
    }

    fn fraction(&self) -> f64 {
        self.0.fraction()
    }
}

/// Particle data, settings and view state behind one `vtkFluidCastVolumeMapper`.
pub struct Renderer {
    data: Dataset,
    settings: Option<ffi::Settings>,
    prepared: Option<Prepared>,
    camera: Option<Camera>,
    tf: Option<TransferFunction>,
    /// The backend opened for (backend, adapter), kept across frames.
    backend: Option<OpenBackend>,
    part: Part,
    /// What `set_surfaces` said (no iso values: none).
    surfaces: Option<ffi::SurfaceSettings>,
    /// Where renders report progress and look for a cancel (`set_render_control`).
    control: Option<Arc<fluidcast_backend::Progress>>,
    /// Whether the particles came from `prepare_source` rather than from `data`.
    external: bool,
    /// With `external`: the iso-surfaces' point array (name, values at the particles).
    iso_attribute: Option<(String, Arc<[f32]>)>,
}

/// What `set_part` said: the crop box (min and max corners) and the whole's support depths.
#[derive(Default, Clone, Copy)]
struct Part {
    crop: Option<([f64; 3], [f64; 3])>,
    support_depths: Option<(f64, f64)>,
}

struct OpenBackend {
    backend: Backend,
    adapter: String,
    renderer: fluidcast_backend::Renderer,
}

fn check_name(property: &str, value: &str) -> Result<(), String> {
    guarded("check_name", || plan::check_name(property, value))
}

fn check_setting(property: &str, value: f64) -> Result<(), String> {
    guarded("check_setting", || {
        fluidcast_backend::check_property(property, value).map_err(|e| e.to_string())
    })
}

fn kernel_names() -> Vec<String> {
    Kernel::ALL.iter().map(|k| k.name().to_string()).collect()
}

fn rbf_noise_names() -> Vec<String> {
    plan::NOISE_NAMES.map(str::to_string).to_vec()
}

fn mode_names() -> Vec<String> {
    fluidcast_backend::Mode::NAMES.map(str::to_string).to_vec()
}

fn rbf_classification_names() -> Vec<String> {
    plan::CLASSIFICATION_NAMES.map(str::to_string).to_vec()
}

fn backend_names() -> Vec<String> {
    Backend::NAMES.iter().map(|n| n.to_string()).collect()
}

/// The backend `Settings::backend` names.
fn backend_of(index: i32) -> Result<Backend, String> {
    usize::try_from(index)
        .ok()
        .and_then(|i| Backend::NAMES.get(i))
        .ok_or_else(|| format!("backend {index}: expected 0 (auto), 1 (cpu) or 2 (gpu)"))?
        .parse()
        .map_err(|e: fluidcast_backend::BackendError| e.to_string())
}

/// The scene built from the current data and settings (particles; what renders of them
/// reuse), and what preparing them said.
struct Prepared {
    scene: Scene,
    info: ffi::RenderInfo,
}

/// A renderer with no data, settings, camera or transfer function yet.
impl Prepared {
    /// A scene of `particles` and what they are, for the render line.
    fn of(particles: Particles) -> Result<Prepared, String> {
        let (vlo, vhi) = particles.value_range();
        let (rlo, rhi) = particles
            .radii
            .iter()
            .fold((f32::INFINITY, 0f32), |(a, b), &r| (a.min(r), b.max(r)));
        let info = ffi::RenderInfo {
            particles: particles.len() as u64,
            skipped_nonfinite: particles.skipped_nonfinite as u64,
            radius_min: rlo as f64,
            radius_max: rhi as f64,
            value_min: vlo as f64,
            value_max: vhi as f64,
            notes: particles.notes.join("\n"),
            ..Default::default()
        };
        // The camera and transfer function are set before each render.
        let tf = TransferFunction::preset("viridis").map_err(|e| e.to_string())?;
        let scene = Scene::new(particles, Camera::default(), tf);
        Ok(Prepared { scene, info })
    }
}

/// How settings `s` build particles: the rendered array and component, the radius (constant,
/// an array, or the data's), the volumes from the data's arrays.
pub fn particle_spec(s: &Settings) -> ParticleSpec {
    let quantity = (!s.scalars.is_empty()).then(|| Quantity {
        array: s.scalars.clone(),
        component: match s.component {
            k if k >= 0 => Component::Index(k as usize),
            -1 => Component::Magnitude,
            _ => Component::Auto,
        },
    });
    let radius = if s.support_radius > 0.0 {
        RadiusSource::Constant(s.support_radius)
    } else if !s.radius_array.is_empty() {
        RadiusSource::Array {
            name: s.radius_array.clone(),
            scale: s.radius_scale,
        }
    } else {
        RadiusSource::Auto
    };
    ParticleSpec {
        quantity,
        radius,
        volume: VolumeSource::Auto,
        mass: None,
    }
}

/// A renderer with no data, settings, camera or transfer function yet.
pub fn new_renderer() -> Box<Renderer> {
    Box::new(Renderer {
        data: empty_dataset(""),
        settings: None,
        prepared: None,
        camera: None,
        tf: None,
        backend: None,
        part: Part::default(),
        surfaces: None,
        control: None,
        external: false,
        iso_attribute: None,
    })
}

fn empty_dataset(name: &str) -> Dataset {
    Dataset {
        path: PathBuf::from(name),
        kind: DatasetKind::PolyData,
        points: Vec::new(),
        point_data: Vec::new(),
        field_data: Vec::new(),
        undecoded: Vec::new(),
        cells: fluidcast_io::Cells::default(),
    }
}

/// Runs `f`, turning a panic into an error message.
pub(crate) fn guarded<T>(what: &str, f: impl FnOnce() -> Result<T, String>) -> Result<T, String> {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(r) => r,
        Err(p) => {
            let msg = p
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_else(|| "unknown panic".into());
            Err(format!("fluidcast: internal error in {what}: {msg}"))
        }
    }
}

impl Renderer {
    fn name(&self) -> String {
        self.data.path.display().to_string()
    }

    /// Starts a new particle set; `name` appears in error messages (the bridge's `begin_data`).
    pub fn begin_data(&mut self, name: &str) {
        self.data = empty_dataset(name);
        self.prepared = None;
        self.external = false;
        self.iso_attribute = None;
    }

    fn set_points<T: Copy + Into<f64>>(&mut self, xyz: &[T]) -> Result<(), String> {
        if !xyz.len().is_multiple_of(3) {
            return Err(format!(
                "{}: {} point coordinates is not a multiple of 3",
                self.name(),
                xyz.len()
            ));
        }
        self.data.points = xyz
            .chunks_exact(3)
            .map(|c| [c[0].into(), c[1].into(), c[2].into()])
            .collect();
        self.prepared = None;
        Ok(())
    }

    /// The particles' points, x y z per point (world space).
    pub fn set_points_f32(&mut self, xyz: &[f32]) -> Result<(), String> {
        guarded("set_points", || self.set_points(xyz))
    }

    /// The particles' points, x y z per point (world space).
    pub fn set_points_f64(&mut self, xyz: &[f64]) -> Result<(), String> {
        guarded("set_points", || self.set_points(xyz))
    }

    fn add_point_array<T: Copy + Into<f64>>(
        &mut self,
        name: &str,
        components: usize,
        values: &[T],
        scalar_type: ScalarType,
    ) -> Result<(), String> {
        let n = self.data.points.len();
        if components == 0 || values.len() != n * components {
            return Err(format!(
                "{}: point array '{name}' has {} values, expected {n} points x {components} components",
                self.name(),
                values.len()
            ));
        }
        self.data.point_data.retain(|a| a.name != name);
        self.data.point_data.push(DataArray {
            name: name.into(),
            scalar_type,
            num_components: components,
            values: values.iter().map(|&v| v.into()).collect(),
        });
        self.prepared = None;
        Ok(())
    }

    /// A point array of `components` values per point, tuple after tuple.
    pub fn add_point_array_f32(
        &mut self,
        name: &str,
        components: usize,
        values: &[f32],
    ) -> Result<(), String> {
        guarded("add_point_array", || {
            self.add_point_array(name, components, values, ScalarType::F32)
        })
    }

    /// A point array of `components` values per point, tuple after tuple.
    pub fn add_point_array_f64(
        &mut self,
        name: &str,
        components: usize,
        values: &[f64],
    ) -> Result<(), String> {
        guarded("add_point_array", || {
            self.add_point_array(name, components, values, ScalarType::F64)
        })
    }

    /// A field-data value such as `support_radius`.
    pub fn add_field_scalar(&mut self, name: &str, value: f64) {
        self.data.field_data.retain(|a| a.name != name);
        self.data.field_data.push(DataArray {
            name: name.into(),
            scalar_type: ScalarType::F64,
            num_components: 1,
            values: vec![value],
        });
        self.prepared = None;
    }

    /// The settings of the renders that follow, checked as the mapper's setters check them.
    pub fn configure(&mut self, s: &ffi::Settings) -> Result<(), String> {
        guarded("configure", || {
            s.kernel
                .parse::<Kernel>()
                .map_err(|e| format!("kernel: {e}"))?;
            plan::check_field(&s.field)?;
            plan::check_sampling(s)?;
            backend_of(s.backend)?;
            let same_particles = self.settings.as_ref().is_some_and(|o| {
                o.scalars == s.scalars
                    && o.component == s.component
                    && o.support_radius == s.support_radius
                    && o.radius_array == s.radius_array
                    && o.radius_scale == s.radius_scale
            });
            if !same_particles {
                self.prepared = None;
            }
            self.settings = Some(s.clone());
            Ok(())
        })
    }

    /// The view of the renders that follow (refused when it cannot see).
    pub fn set_camera(&mut self, c: &ffi::CameraDesc) -> Result<(), String> {
        guarded("set_camera", || {
            let cam = Camera {
                position: c.position,
                focal_point: c.focal_point,
                view_up: c.view_up,
                view_angle: c.view_angle,
                parallel_projection: c.parallel_projection,
                parallel_scale: c.parallel_scale,
            };
            cam.frame(1, 1).map_err(|e| e.to_string())?;
            self.camera = Some(cam);
            Ok(())
        })
    }

    /// The transfer function from tables sampled evenly over `lo..hi` ([`transfer_function`]).
    pub fn set_transfer_function(
        &mut self,
        lo: f64,
        hi: f64,
        rgb: &[f64],
        opacity: &[f64],
        unit_distance: f64,
    ) -> Result<(), String> {
        guarded("set_transfer_function", || {
            self.tf = Some(transfer_function(lo, hi, rgb, opacity, unit_distance)?);
            Ok(())
        })
    }

    /// The iso-surfaces of the renders that follow.
    pub fn set_surfaces(&mut self, s: &ffi::SurfaceSettings) -> Result<(), String> {
        guarded("set_surfaces", || {
            let keep = self.surfaces.take();
            self.surfaces = Some(s.clone());
            if let Err(e) = self.surfaces_now("") {
                self.surfaces = keep;
                return Err(e);
            }
            Ok(())
        })
    }

    /// The iso-surfaces `set_surfaces` asked for, for the data now held (`scalars`: the
    /// rendered array's name); `None` without iso values.
    fn surfaces_now(&self, scalars: &str) -> Result<Option<Arc<Surfaces>>, String> {
        let Some(s) = self.surfaces.as_ref().filter(|s| !s.iso_values.is_empty()) else {
            return Ok(None);
        };
        let field = match s.iso_field.to_ascii_lowercase().as_str() {
            "" | "colour" | "color" => IsoField::Colour,
            "density" => IsoField::Density,
            _ if s.iso_field == scalars => IsoField::Attribute(None),
            _ if self.external => match &self.iso_attribute {
                Some((name, v)) if *name == s.iso_field => IsoField::Attribute(Some(v.clone())),
                _ => {
                    return Err(format!(
                        "iso-surfaces of point array '{}': not given with the particles",
                        s.iso_field
                    ))
                }
            },
            _ if self.data.points.is_empty() => IsoField::Attribute(None), // no data yet
            _ => {
                let q = Quantity {
                    array: s.iso_field.clone(),
                    component: Component::Auto,
                };
                let v = Particles::values_of(&self.data, &q).map_err(|e| e.to_string())?;
                IsoField::Attribute(Some(v.into()))
            }
        };
        let lighting = lighting_of(s);
        let surfaces = Surfaces {
            field,
            values: s.iso_values.clone(),
            opacity: s.opacity,
            colour: None,
            lighting,
            volume: s.with_volume,
        };
        let n = match &surfaces.field {
            IsoField::Attribute(Some(v)) => v.len(),
            _ => 0,
        };
        surfaces
            .validate(n)
            .map_err(|e| format!("iso-surfaces: {e}"))?;
        Ok(Some(Arc::new(surfaces)))
    }

    /// Builds the particles now (normally done by `render`) and reports them.
    pub fn prepare(&mut self) -> Result<ffi::RenderInfo, String> {
        guarded("prepare", || self.prepared().map(|p| p.info.clone()))
    }

    /// [`fluidcast_backend::defaults::single_value_range`] for the prepared particles'
    /// attribute and the transfer function's range; empty when it says nothing, before both
    /// are set, or for a field that sums the particles (its values are not the attribute's).
    pub fn colour_range_warning(&self) -> String {
        let (Some(p), Some(tf), Some(s)) = (&self.prepared, &self.tf, &self.settings) else {
            return String::new();
        };
        if !(plan::is_rbf(&s.field)
            || plan::parse_field(&s.field) == Ok(fluidcast_sph::FieldKind::Csph))
        {
            return String::new();
        }
        let values = (p.info.value_min, p.info.value_max);
        fluidcast_backend::defaults::single_value_range(values, tf.range).unwrap_or_default()
    }

    fn set_part(&mut self, crop: &[f64], support_depths: &[f64]) -> Result<(), String> {
        guarded("set_part", || {
            let crop = match crop {
                [] => None,
                [x0, x1, y0, y1, z0, z1] => Some(([*x0, *y0, *z0], [*x1, *y1, *z1])),
                _ => return Err(format!("crop box has {} values, not 6", crop.len())),
            };
            let support_depths = match support_depths {
                [] => None,
                [lo, hi] if lo.is_finite() && hi.is_finite() && lo <= hi => Some((*lo, *hi)),
                [lo, hi] => return Err(format!("support depths {lo}..{hi} are not a range")),
                _ => {
                    let n = support_depths.len();
                    return Err(format!("support depths: {n} values, not 2"));
                }
            };
            self.part = Part {
                crop,
                support_depths,
            };
            Ok(())
        })
    }

    fn support_depths(&mut self) -> Result<Vec<f64>, String> {
        guarded("support_depths", || {
            let camera = self.camera.clone().ok_or("fluidcast: no camera set")?;
            let frame = camera.frame(1, 1).map_err(|e| e.to_string())?;
            let p = self.prepared()?;
            Ok(
                fluidcast_backend::support_depth_extent(p.scene.particles(), &frame)
                    .map_or(Vec::new(), |(lo, hi)| vec![lo, hi]),
            )
        })
    }

    fn prepared(&mut self) -> Result<&Prepared, String> {
        if self.prepared.is_none() {
            if self.external {
                return Err(format!(
                    "{}: the particles given with prepare_source were dropped by a change of \
                     the settings they depend on; give them again",
                    self.name()
                ));
            }
            let s = self
                .settings
                .as_ref()
                .ok_or("fluidcast: configure() was not called")?;
            let particles = Particles::from_dataset(&self.data, &particle_spec(s))
                .map_err(|e| e.to_string())?;
            self.prepared = Some(Prepared::of(particles)?);
        }
        self.prepared
            .as_ref()
            .ok_or_else(|| "fluidcast: particles missing".to_string())
    }

    /// Builds the particles from `src` (arrays the caller holds, read in place where they are
    /// double precision) with the configured settings, instead of from the data set given
    /// with `set_points`/`add_point_array` (which is emptied): what the Python module does with
    /// numpy arrays.
    pub fn prepare_source(&mut self, src: &impl ParticleSource) -> Result<ffi::RenderInfo, String> {
        guarded("prepare_source", || {
            let s = self
                .settings
                .as_ref()
                .ok_or("fluidcast: configure() was not called")?;
            let particles =
                Particles::from_source(src, &particle_spec(s)).map_err(|e| e.to_string())?;
            self.data = empty_dataset(&src.path().display().to_string());
            self.external = true;
            let p = Prepared::of(particles)?;
            let info = p.info.clone();
            self.prepared = Some(p);
            Ok(info)
        })
    }

    /// The backend for (backend, adapter), opened on first use and when either changes.
    fn open_backend(&mut self, backend: Backend, adapter: &str) -> Result<(), String> {
        let same = self
            .backend
            .as_ref()
            .is_some_and(|b| b.backend == backend && b.adapter == adapter);
        if !same {
            self.backend = None;
            let adapter_opt = (!adapter.is_empty()).then_some(adapter);
            let renderer = fluidcast_backend::Renderer::open(backend, adapter_opt)
                .map_err(|e| format!("backend {backend}: {e}"))?;
            self.backend = Some(OpenBackend {
                backend,
                adapter: adapter.to_string(),
                renderer,
            });
        }
        Ok(())
    }

    /// The renders that follow report to `control` and stop when it is cancelled.
    pub fn set_render_control(&mut self, control: &RenderControl) {
        self.control = Some(control.0.clone());
    }

    /// Renders `width x height`, rows top first, into premultiplied RGBA and view depth (see the bridge's `render`).
    pub fn render(
        &mut self,
        width: u32,
        height: u32,
        depth_limit: &[f32],
        rgba: &mut [f32],
        depth: &mut [f32],
    ) -> Result<ffi::RenderInfo, String> {
        guarded("render", || {
            let n = width as usize * height as usize;
            if rgba.len() != 4 * n || depth.len() != n {
                return Err(format!(
                    "output buffers hold {} RGBA and {} depth values for a {width}x{height} image",
                    rgba.len(),
                    depth.len()
                ));
            }
            let camera = self.camera.clone().ok_or("fluidcast: no camera set")?;
            let tf = self
                .tf
                .clone()
                .ok_or("fluidcast: no transfer function set")?;
            let s = self
                .settings
                .clone()
                .ok_or("fluidcast: configure() was not called")?;
            let name = self.name();
            let mut plan = plan_of(&s, (width, height), depth_limit, &camera)?;
            // The window shows colour at 8 bits and the mapper draws no depth: the GPU reads
            // back half-precision colour only (the CPU fills in everything anyway).
            plan.params.output = fluidcast_backend::ImageOutput::DISPLAY;
            plan.params.support_depths = self.part.support_depths;
            plan.params.progress = self.control.clone();
            if let Some((lo, hi)) = self.part.crop {
                fluidcast_backend::crop_to_box(&mut plan.params, &camera, lo, hi)
                    .map_err(|e| format!("{name}: {e}"))?;
            }
            let t = Instant::now();
            self.prepared()?;
            plan.params.surfaces = self.surfaces_now(&s.scalars)?;
            if s.shade_volume {
                let shading = self.surfaces.as_ref().map(lighting_of);
                plan.params.volume_lighting = Some(shading.unwrap_or_default());
            }
            self.open_backend(backend_of(s.backend)?, &s.adapter)?;
            let (Some(p), Some(b)) = (&mut self.prepared, &self.backend) else {
                return Err("fluidcast: particles or backend missing".into());
            };
            p.scene.camera = camera;
            p.scene.tf = tf;
            let r = b.renderer.render(&mut p.scene, &plan).map_err(|e| {
                let property = plan::property(&e, &s).map_or(String::new(), |p| format!("{p}: "));
                format!("{name} ({}): {property}{e}", b.renderer.device())
            })?;
            Ok(finish(&r, (rgba, depth), t, &p.info))
        })
    }
}

impl Renderer {
    /// The transfer function of the renders that follow, as given (a CLI preset or a
    /// ParaView preset file read by [`TransferFunction`]).
    pub fn set_transfer(&mut self, tf: TransferFunction) {
        self.tf = Some(tf);
    }

    /// The particles the data and settings make (built now if they were not).
    pub fn particles(&mut self) -> Result<&Particles, String> {
        Ok(self.prepared()?.scene.particles())
    }

    /// With particles from `prepare_source`: the values at the particles of point array
    /// `name`, for iso-surfaces of it (`SurfaceSettings::iso_field`).
    pub fn set_iso_attribute(&mut self, name: &str, values: Vec<f32>) {
        self.iso_attribute = Some((name.to_string(), Arc::from(values)));
    }

    /// The field sums of the particles (as the settings build them) at `points` (world
    /// space), with the settings' kernel: what `fluidcast probe` writes.
    pub fn interpolate(&mut self, points: &[[f64; 3]]) -> Result<Vec<FieldSample>, String> {
        guarded("interpolate", || {
            let s = self
                .settings
                .as_ref()
                .ok_or("fluidcast: configure() was not called")?;
            let kernel: Kernel = s.kernel.parse()?;
            let p = self.prepared()?;
            Ok(p.scene.particles().sample_many(kernel, points))
        })
    }
}

/// No iso-surfaces, and for those asked for later: the colour field, opaque, lit with
/// vtkVolumeProperty's default coefficients (pyvista's `add_volume` defaults).
pub fn default_surfaces() -> SurfaceSettings {
    SurfaceSettings {
        iso_values: Vec::new(),
        iso_field: "colour".into(),
        opacity: 1.0,
        with_volume: false,
        shade: true,
        ambient: 0.1,
        diffuse: 0.7,
        specular: 0.2,
        specular_power: 10.0,
    }
}

/// The settings a new mapper has (vtkFluidCastVolumeMapper's defaults, the CLI's): the
/// particle density (no array) with the data's radius, cubic kernel, CSPH, error tolerance
/// 0.004, backend auto, the plan's defaults.
pub fn default_settings() -> Settings {
    Settings {
        scalars: String::new(),
        component: -2,
        support_radius: 0.0,
        radius_array: String::new(),
        radius_scale: 1.0,
        kernel: "cubic".into(),
        field: "csph".into(),
        error_tolerance: 0.004,
        backend: 0,
        adapter: String::new(),
        memory_limit_mib: 0.0,
        work_limit: 0.0,
        lod_tolerance: 0.0,
        rbf_classification: "post".into(),
        rbf_radius: 0.0,
        samples_per_pixel: 1,
        progressive_passes: 1,
        shadows: false,
        light: [0.0; 3],
        shadow_ambient: 0.25,
        radius_map: Vec::new(),
        mode: String::new(),
        grid_cell: 1,
        probe: true,
        superpixels: true,
        surface_cells: true,
        interpolate: true,
        tiles: 0,
        relax: 1.0,
        strict: false,
        bundle: 8,
        depth_samples: 16,
        sampling_scale: 1.0,
        occlusion_culling: true,
        rbf_noise: "blue".into(),
        rbf_seed: 0,
        rbf_leaf_size: fluidcast_backend::DEFAULT_LEAF_SIZE as u32,
        rbf_step: 0.0,
        shadow_samples: 1,
        shade_volume: false,
    }
}

/// The lighting the volume property asks for: Blinn–Phong with a headlight when it shades,
/// else flat (ambient 1).
fn lighting_of(s: &ffi::SurfaceSettings) -> Lighting {
    if s.shade {
        Lighting {
            ambient: s.ambient,
            diffuse: s.diffuse,
            specular: s.specular,
            specular_power: s.specular_power,
            light: Light::Headlight,
        }
    } else {
        Lighting {
            ambient: 1.0,
            diffuse: 0.0,
            specular: 0.0,
            ..Default::default()
        }
    }
}

/// Copies a frame into the caller's buffers and says what it did.
fn finish(
    r: &Rendered,
    (rgba, depth): (&mut [f32], &mut [f32]),
    started: Instant,
    info: &ffi::RenderInfo,
) -> ffi::RenderInfo {
    let notes: Vec<&str> = std::iter::once(info.notes.as_str())
        .chain(r.notes.iter().map(String::as_str))
        .filter(|n| !n.is_empty())
        .collect();
    for (k, px) in r.image.rgba.iter().enumerate() {
        rgba[4 * k..4 * k + 4].copy_from_slice(px);
    }
    depth.copy_from_slice(&r.image.depth);
    ffi::RenderInfo {
        samples: r.stats.samples,
        tiles: r.stats.tiles as u64,
        total_ms: started.elapsed().as_secs_f64() * 1e3,
        notes: notes.join("\n"),
        device: r.device.clone(),
        ..info.clone()
    }
}

/// A transfer function from tables sampled evenly over [lo, hi] (what the C++ side reads off
/// `vtkColorTransferFunction::GetTable` and `vtkPiecewiseFunction::GetTable`).
pub fn transfer_function(
    lo: f64,
    hi: f64,
    rgb: &[f64],
    opacity: &[f64],
    unit_distance: f64,
) -> Result<TransferFunction, String> {
    let n = opacity.len();
    if n < 2 || rgb.len() != 3 * n {
        return Err(format!(
            "transfer function tables: {} colour values and {n} opacities (need 3 per entry, at least 2 entries)",
            rgb.len()
        ));
    }
    if !(unit_distance.is_finite() && unit_distance > 0.0) {
        return Err(format!(
            "scalar opacity unit distance {unit_distance} must be > 0"
        ));
    }
    if rgb.iter().chain(opacity).any(|v| !v.is_finite()) {
        return Err("transfer function tables hold NaN or infinite values".into());
    }
    let x = |k: usize| k as f64 / (n - 1) as f64;
    let tf = TransferFunction {
        name: "vtkVolumeProperty".into(),
        colors: (0..n)
            .map(|k| (x(k), [rgb[3 * k], rgb[3 * k + 1], rgb[3 * k + 2]]))
            .collect(),
        opacity: (0..n).map(|k| (x(k), opacity[k].clamp(0.0, 1.0))).collect(),
        range: (0.0, 1.0),
        unit_distance,
    };
    let (lo, hi) = if hi > lo { (lo, hi) } else { (lo, lo + 1.0) };
    tf.with_range(lo, hi).map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;
    use fluidcast_lod::LodHierarchy;
    use fluidcast_render::{PlanParams, RenderParams, SURFACE_THRESHOLD};

    fn cube(n: usize, spacing: f64) -> Vec<f64> {
        let mut v = Vec::new();
        for i in 0..n {
            for j in 0..n {
                for k in 0..n {
                    v.extend([i as f64 * spacing, j as f64 * spacing, k as f64 * spacing]);
                }
            }
        }
        v
    }

    fn settings() -> ffi::Settings {
        ffi::Settings {
            scalars: "value".into(),
            support_radius: 0.2,
            backend: 1,
            ..default_settings()
        }
    }

    /// A 30° perspective camera at `position` looking at the test cube's centre, y up.
    fn cube_camera(position: [f64; 3]) -> ffi::CameraDesc {
        ffi::CameraDesc {
            position,
            focal_point: [0.25, 0.25, 0.25],
            view_up: [0.0, 1.0, 0.0],
            view_angle: 30.0,
            parallel_projection: false,
            parallel_scale: 1.0,
        }
    }

    fn ready(r: &mut Renderer) {
        let xyz = cube(6, 0.1);
        r.begin_data("test cube");
        r.set_points_f64(&xyz).unwrap();
        let vals: Vec<f32> = (0..xyz.len() / 3).map(|i| (i % 7) as f32).collect();
        r.add_point_array_f32("value", 1, &vals).unwrap();
        r.configure(&settings()).unwrap();
        r.set_camera(&cube_camera([0.25, 0.25, 3.0])).unwrap();
        r.set_transfer_function(0.0, 6.0, &[0.0, 0.0, 1.0, 1.0, 0.0, 0.0], &[0.2, 0.8], 0.1)
            .unwrap();
    }

    fn surfaces(values: &[f64], field: &str) -> ffi::SurfaceSettings {
        ffi::SurfaceSettings {
            iso_values: values.to_vec(),
            iso_field: field.into(),
            ..default_surfaces()
        }
    }

    /// A renderer holding a 59^3 lattice cube of support radius 0.02 valued by `value`
    /// (index -> value), its settings and the number of particles.
    fn big_cube(value: impl Fn(usize) -> f32) -> (Box<Renderer>, ffi::Settings, usize) {
        let mut r = new_renderer();
        ready(&mut r);
        let xyz = cube(59, 0.5 / 58.0);
        let n = xyz.len() / 3;
        r.begin_data("big cube");
        r.set_points_f64(&xyz).unwrap();
        let vals: Vec<f32> = (0..n).map(value).collect();
        r.add_point_array_f32("value", 1, &vals).unwrap();
        let mut s = settings();
        s.support_radius = 0.02;
        r.configure(&s).unwrap();
        (r, s, n)
    }

    type Frame = (Vec<f32>, Vec<f32>, ffi::RenderInfo);

    /// A 40x30 render: (RGBA, depth, info).
    fn render_40x30(r: &mut Renderer) -> Result<Frame, String> {
        let mut rgba = vec![0f32; 4 * 40 * 30];
        let mut depth = vec![0f32; 40 * 30];
        r.render(40, 30, &[], &mut rgba, &mut depth)
            .map(|info| (rgba, depth, info))
    }

    /// A colour map whose range is one value (ParaView's at a series' first step at rest)
    /// is reported for the attribute it misrepresents, and not for a field that sums the
    /// particles (its values are not the attribute's) or a range of real width.
    #[test]
    fn a_single_value_colour_range_is_reported_for_the_attribute() {
        let (mut r, mut s, _) = big_cube(|i| (i % 7) as f32);
        let rgb = [0.0, 0.0, 1.0, 1.0, 0.0, 0.0];
        assert_eq!(r.colour_range_warning(), "", "nothing prepared yet");
        r.prepare().unwrap();
        r.set_transfer_function(0.0, 6.0, &rgb, &[0.2, 0.8], 0.1)
            .unwrap();
        assert_eq!(r.colour_range_warning(), "");
        r.set_transfer_function(3.0, 3.000001, &rgb, &[0.2, 0.8], 0.1)
            .unwrap();
        let w = r.colour_range_warning();
        assert!(w.contains("[0.000000, 6.000000] saturate"), "{w}");
        for (field, said) in [("rbf", true), ("density", false), ("sph", false)] {
            s.field = field.into();
            r.configure(&s).unwrap();
            r.prepare().unwrap();
            assert_eq!(!r.colour_range_warning().is_empty(), said, "{field}");
        }
    }

    /// Particles built from a caller's source (`prepare_source`, what the Python module
    /// does) render as the data set they came from; a change of the settings they depend on
    /// drops them with a message, and iso-surfaces of another array need its values.
    #[test]
    fn particles_from_a_source_render_as_the_data_set() {
        let (mut a, s, _) = big_cube(|i| (i % 7) as f32);
        let want = render_40x30(&mut a).unwrap();
        let mut b = new_renderer();
        ready(&mut b);
        b.configure(&s).unwrap();
        b.prepare_source(&a.data).unwrap();
        let got = render_40x30(&mut b).unwrap();
        assert!(want.0.iter().any(|&v| v > 0.1));
        assert_eq!((got.0, got.1), (want.0, want.1));
        assert_eq!(got.2.particles, want.2.particles);
        let e = b.set_surfaces(&surfaces(&[0.5], "other")).unwrap_err();
        assert!(e.contains("point array 'other': not given"), "{e}");
        b.set_iso_attribute("other", vec![0.0; got.2.particles as usize]);
        b.set_surfaces(&surfaces(&[0.5], "other")).unwrap();
        b.set_surfaces(&surfaces(&[], "colour")).unwrap();
        let mut t = s.clone();
        t.support_radius = 0.03;
        b.configure(&t).unwrap();
        let e = render_40x30(&mut b).unwrap_err();
        assert!(e.contains("give them again"), "{e}");
    }

    /// MemoryLimit: a limit that tiles the view renders the same image; one too small for
    /// any tile is an error naming the limit, and the next render without it works.
    #[test]
    fn memory_limits_tile_the_view_to_the_same_image() {
        let (mut r, mut s, n) = big_cube(|i| (i % 7) as f32);
        let (w, h) = (40u32, 30u32);
        let render = |r: &mut Renderer| render_40x30(r).map(|(rgba, depth, _)| (rgba, depth));
        let whole = render(&mut r).unwrap();
        // Room for the image, 9 bytes a particle and a minimal tile: fewer than n per tile.
        let fixed = (w * h) as f64 * 64.0 + n as f64 * 9.0;
        s.memory_limit_mib = (fixed + fluidcast_render::MIN_TILE_BYTES as f64) / 1048576.0 + 0.5;
        assert!(fluidcast_render::tile_particles_within(
            n,
            w,
            h,
            (s.memory_limit_mib * 1048576.0) as u64
        )
        .unwrap()
        .is_some());
        r.configure(&s).unwrap();
        let tiled = render(&mut r).unwrap();
        assert_eq!(whole, tiled);
        s.memory_limit_mib = 1.0;
        r.configure(&s).unwrap();
        let e = render(&mut r).unwrap_err();
        assert!(
            e.contains("MemoryLimit 1 MiB") && e.contains("too small"),
            "{e}"
        );
        s.memory_limit_mib = 0.0;
        r.configure(&s).unwrap();
        assert_eq!(render(&mut r).unwrap(), whole);
    }

    /// LODTolerance: the bridge draws the library's cut of its particles for the view (the
    /// same image as rendering that cut directly), says how many it drew, and draws every
    /// particle again at 0; the RBF field refuses it.
    #[test]
    fn level_of_detail_draws_the_cut_of_the_view() {
        let (mut r, mut s, n) = big_cube(|i| (i as f32 * 0.37).sin());
        let (w, h) = (40u32, 30u32);
        let render = render_40x30;
        let (whole, _, _) = render(&mut r).unwrap();
        s.lod_tolerance = 2.0;
        r.configure(&s).unwrap();
        let (rgba, depth, info) = render(&mut r).unwrap();
        // The library's cut of the same particles, rendered directly.
        let p = r.prepared().unwrap().scene.particles().clone();
        let cam = r.camera.clone().unwrap();
        let hier = LodHierarchy::build(p).unwrap();
        let cut = hier.cut(&cam.frame(w, h).unwrap(), 2.0).unwrap();
        assert!(
            cut.particles.len() * 4 < n,
            "{} of {n}",
            cut.particles.len()
        );
        let flags = cut.particles.surface_flags(SURFACE_THRESHOLD);
        let tf = r.tf.clone().unwrap();
        let params = RenderParams {
            width: w,
            height: h,
            adaptive: PlanParams {
                tolerance: Some(0.004),
                ..Default::default()
            },
            ..Default::default()
        };
        let want =
            fluidcast_render::render_adaptive(&cut.particles, Some(&flags), &cam, &tf, &params)
                .unwrap();
        let want_rgba: Vec<f32> = want.image.rgba.iter().flatten().copied().collect();
        assert_eq!(rgba, want_rgba);
        assert_eq!(depth, want.image.depth);
        assert_ne!(rgba, whole);
        // The same view again takes the kept cut; another view its own, as a renderer that
        // never saw the first view makes it.
        assert_eq!(render(&mut r).unwrap().0, rgba);
        let turned = cube_camera([1.6, 0.9, 2.4]);
        r.set_camera(&turned).unwrap();
        let (mut fresh, _, _) = big_cube(|i| (i as f32 * 0.37).sin());
        fresh.configure(&s).unwrap();
        fresh.set_camera(&turned).unwrap();
        let there = render(&mut r).unwrap().0;
        assert_eq!(there, render(&mut fresh).unwrap().0);
        assert_ne!(there, rgba);
        r.set_camera(&cube_camera([0.25, 0.25, 3.0])).unwrap();
        let says = format!("of {n} particles");
        assert!(
            info.notes.contains("level of detail 2 px") && info.notes.contains(&says),
            "{}",
            info.notes
        );
        s.lod_tolerance = 0.0;
        r.configure(&s).unwrap();
        assert_eq!(render(&mut r).unwrap().0, whole);
        // A tolerance that merges nothing draws the particles as without it.
        s.lod_tolerance = 1e-3;
        r.configure(&s).unwrap();
        let (same, _, info) = render(&mut r).unwrap();
        assert_eq!(same, whole);
        assert!(!info.notes.contains("level of detail"), "{}", info.notes);
        s.lod_tolerance = 2.0;
        s.field = "rbf".into();
        r.configure(&s).unwrap();
        let e = render(&mut r).unwrap_err();
        assert!(e.contains("LODTolerance"), "{e}");
        s.lod_tolerance = f64::NAN;
        let e = r.configure(&s).unwrap_err();
        assert!(
            e.contains("LODTolerance must be") && e.ends_with("not NaN"),
            "{e}"
        );
    }

    /// With iso values the bridge draws surfaces (on the CPU unless the backend is GPU) exactly
    /// as the library's reference renderer does for the same particles; bad settings are
    /// refused and the previous ones kept; no iso values: the volume again.
    #[test]
    fn surfaces_render_as_the_library_draws_them() {
        let mut r = new_renderer();
        ready(&mut r);
        let (w, h) = (40u32, 30u32);
        let mut volume = vec![0f32; 4 * 40 * 30];
        let mut depth = vec![0f32; 40 * 30];
        r.render(w, h, &[], &mut volume, &mut depth).unwrap();
        for field in ["colour", "value"] {
            r.set_surfaces(&surfaces(&[0.5], field)).unwrap();
            let mut rgba = vec![0f32; 4 * 40 * 30];
            let info = r.render(w, h, &[], &mut rgba, &mut depth).unwrap();
            assert!(
                info.notes.contains("reference ray caster"),
                "{}",
                info.notes
            );
            let p = r.prepared().unwrap().scene.particles().clone();
            let params = RenderParams {
                width: w,
                height: h,
                surfaces: r.surfaces_now("value").unwrap(),
                ..Default::default()
            };
            let (img, _) = fluidcast_render::render_reference(
                &p,
                r.camera.as_ref().unwrap(),
                r.tf.as_ref().unwrap(),
                &params,
            )
            .unwrap();
            let want: Vec<f32> = img.rgba.iter().flatten().copied().collect();
            assert_eq!(rgba, want, "{field}");
            assert_ne!(rgba, volume, "{field}: surfaces drawn");
            assert!(
                depth.iter().any(|z| z.is_finite()),
                "{field}: Z of the surface"
            );
        }
        let bad = [
            (surfaces(&[f64::NAN], "colour"), "not finite"),
            (surfaces(&[0.5], "nosuch"), "nosuch"),
            (
                ffi::SurfaceSettings {
                    opacity: 2.0,
                    ..surfaces(&[0.5], "colour")
                },
                "opacity",
            ),
        ];
        for (s, want) in bad {
            let e = r.set_surfaces(&s).unwrap_err();
            assert!(e.contains(want), "{e}");
        }
        assert_eq!(r.surfaces.as_ref().unwrap().iso_field, "value", "kept");
        r.set_surfaces(&surfaces(&[], "colour")).unwrap();
        let mut again = vec![0f32; 4 * 40 * 30];
        r.render(w, h, &[], &mut again, &mut depth).unwrap();
        assert_eq!(again, volume, "no iso values: the volume");
    }

    #[test]
    fn rbf_still_renders_accumulate_passes_up_to_the_limit() {
        let mut r = new_renderer();
        ready(&mut r);
        let s = ffi::Settings {
            field: "rbf".into(),
            progressive_passes: 4,
            ..settings()
        };
        r.configure(&s).unwrap();
        let (w, h) = (40u32, 30u32);
        let n = (w * h) as usize;
        let frame = |r: &mut Renderer| {
            let (mut rgba, mut depth) = (vec![0f32; 4 * n], vec![0f32; n]);
            let info = r.render(w, h, &[], &mut rgba, &mut depth).unwrap();
            (rgba, info.samples)
        };
        let renders: Vec<(Vec<f32>, u64)> = (0..5).map(|_| frame(&mut r)).collect();
        // The library's render of 1 and of 4 passes, from the bridge's own particles, camera
        // and transfer function: the first render is one pass, the fourth the mean of four.
        let p = r.prepared.as_ref().unwrap().scene.particles();
        let (cam, tf) = (r.camera.clone().unwrap(), r.tf.clone().unwrap());
        let field = fluidcast_rbf::RbfField::build(p, &tf, &Default::default()).unwrap();
        let prm = RenderParams {
            width: w,
            height: h,
            ..Default::default()
        };
        let lib = |spp| {
            let rp = fluidcast_render::RbfRenderParams {
                spp,
                ..Default::default()
            };
            let img = fluidcast_render::render_rbf(&field, &cam, &tf, &prm, &rp)
                .unwrap()
                .0;
            img.rgba.concat()
        };
        let close = |a: &[f32], b: &[f32]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-6);
        assert!(
            close(&renders[0].0, &lib(1)),
            "first still render: one pass"
        );
        assert!(!close(&renders[0].0, &renders[3].0), "passes were added");
        assert!(
            close(&renders[3].0, &lib(4)),
            "fourth: the mean of four passes"
        );
        assert!(renders[3].1 > 0);
        assert_eq!(
            renders[4].0, renders[3].0,
            "the limit reached: the same image"
        );
        assert_eq!(renders[4].1, 0, "and no new samples");
        // Another view starts again from one pass.
        let mut c = r.camera.clone().unwrap();
        c.azimuth(10.0);
        r.camera = Some(c);
        let moved = frame(&mut r);
        assert!(moved.1 > 0 && moved.0 != renders[3].0);
        // The radius map refits the tree: factor 0 everywhere hides every particle, and
        // back to 1 the first image returns.
        let hidden = ffi::Settings {
            radius_map: vec![0.0, 0.0, 1.0, 0.0],
            ..s.clone()
        };
        r.configure(&hidden).unwrap();
        r.camera = Some(cam.clone());
        let none = frame(&mut r);
        assert!(none.0.iter().all(|&v| v == 0.0), "all hidden");
        r.configure(&s).unwrap();
        assert_eq!(
            frame(&mut r).0,
            renders[0].0,
            "radius map 1 again: the first render"
        );
        let odd = ffi::Settings {
            radius_map: vec![0.0, 1.0, 1.0],
            ..s.clone()
        };
        r.configure(&odd).unwrap();
        let (mut rgba, mut depth) = (vec![0f32; 4 * n], vec![0f32; n]);
        let e = r.render(w, h, &[], &mut rgba, &mut depth).unwrap_err();
        assert!(e.contains("pairs"), "{e}");
        // Bad RBF settings are errors naming them.
        let bad = ffi::Settings {
            rbf_classification: "sideways".into(),
            ..s.clone()
        };
        r.configure(&bad).unwrap();
        let (mut rgba, mut depth) = (vec![0f32; 4 * n], vec![0f32; n]);
        let e = r.render(w, h, &[], &mut rgba, &mut depth).unwrap_err();
        assert!(e.contains("classification"), "{e}");
        let shadows = ffi::Settings {
            shadows: true,
            shadow_ambient: 3.0,
            ..s
        };
        let e = r.configure(&shadows).unwrap_err();
        assert!(e.contains("ShadowAmbient"), "{e}");
    }

    /// The mapper's worker thread and its poll of VTK's abort check meet in a
    /// `RenderControl`: a render reports all of its cast done, and a cancelled one stops
    /// with an error that says so.
    #[test]
    fn a_render_control_sees_progress_and_cancels() {
        let mut r = new_renderer();
        ready(&mut r);
        let (w, h) = (40u32, 30u32);
        let n = (w * h) as usize;
        let (mut rgba, mut depth) = (vec![0f32; 4 * n], vec![0f32; n]);
        let control = new_render_control();
        r.set_render_control(&control);
        r.render(w, h, &[], &mut rgba, &mut depth).unwrap();
        assert_eq!(control.fraction(), 1.0);
        let stop = new_render_control();
        stop.cancel();
        r.set_render_control(&stop);
        let e = r.render(w, h, &[], &mut rgba, &mut depth).unwrap_err();
        assert!(stop.cancelled() && e.contains("cancelled"), "{e}");
    }

    #[test]
    fn renders_and_matches_the_library_call() {
        let mut r = new_renderer();
        ready(&mut r);
        let (w, h) = (40u32, 30u32);
        let mut rgba = vec![0f32; 4 * 40 * 30];
        let mut depth = vec![0f32; 40 * 30];
        let info = r.render(w, h, &[], &mut rgba, &mut depth).unwrap();
        assert_eq!(info.particles, 216);
        // The cube (0..0.5, support 0.2) seen from z = 3: supports from 2.3 to 3.2 deep.
        let d = r.support_depths().unwrap();
        assert!(
            (d[0] - 2.3).abs() < 1e-6 && (d[1] - 3.2).abs() < 1e-6,
            "{d:?}"
        );
        assert!(info.samples > 0);
        assert!(rgba.chunks(4).any(|p| p[3] > 0.5));
        // Same as the renderer given the same raw arrays another way: as an ASCII .vtu read by
        // fluidcast's reader, with the settings, camera and transfer function written out
        // here (not the bridge's converted particles, camera or tables).
        let xyz = cube(6, 0.1);
        let pts: Vec<String> = xyz.iter().map(|v| v.to_string()).collect();
        let vals: Vec<String> = (0..216).map(|i| (i % 7).to_string()).collect();
        let vtu = format!(
            r#"<VTKFile type="PolyData" version="1.0" byte_order="LittleEndian"><PolyData>
<Piece NumberOfPoints="216"><PointData><DataArray type="Float32" Name="value" format="ascii">{}
</DataArray></PointData><Points><DataArray type="Float64" NumberOfComponents="3" format="ascii">{}
</DataArray></Points></Piece></PolyData></VTKFile>"#,
            vals.join(" "),
            pts.join(" ")
        );
        let ds =
            fluidcast_io::parse_dataset(vtu.as_bytes(), std::path::Path::new("cube.vtp")).unwrap();
        let spec = ParticleSpec {
            quantity: Some("value".parse().unwrap()),
            radius: RadiusSource::Constant(0.2),
            volume: VolumeSource::Auto,
            mass: None,
        };
        let p = Particles::from_dataset(&ds, &spec).unwrap();
        let cam = Camera {
            position: [0.25, 0.25, 3.0],
            focal_point: [0.25, 0.25, 0.25],
            view_up: [0.0, 1.0, 0.0],
            view_angle: 30.0,
            parallel_projection: false,
            parallel_scale: 1.0,
        };
        let tf = TransferFunction {
            name: "blue to red".into(),
            colors: vec![(0.0, [0.0, 0.0, 1.0]), (1.0, [1.0, 0.0, 0.0])],
            opacity: vec![(0.0, 0.2), (1.0, 0.8)],
            range: (0.0, 1.0),
            unit_distance: 0.1,
        }
        .with_range(0.0, 6.0)
        .unwrap();
        let params = RenderParams {
            width: w,
            height: h,
            ..Default::default()
        };
        let direct = fluidcast_render::render_adaptive(&p, None, &cam, &tf, &params).unwrap();
        for (k, px) in direct.image.rgba.iter().enumerate() {
            assert_eq!(&rgba[4 * k..4 * k + 4], px, "pixel {k}");
            assert_eq!(depth[k], direct.image.depth[k], "depth {k}");
        }
    }

    /// The GPU backend through the bridge: the CPU's image within the GPU tests' tolerance,
    /// the device opened once and kept across frames, and bad backends refused.
    #[test]
    fn gpu_backend_renders_the_cpu_image_and_keeps_its_device() {
        let mut r = new_renderer();
        ready(&mut r);
        let (w, h) = (40u32, 30u32);
        let mut cpu = vec![0f32; 4 * 40 * 30];
        let mut depth = vec![0f32; 40 * 30];
        let info = r.render(w, h, &[], &mut cpu, &mut depth).unwrap();
        assert!(info.device.starts_with("CPU"), "{}", info.device);
        let mut s = settings();
        s.backend = 2;
        r.configure(&s).unwrap();
        let mut gpu = vec![0f32; 4 * 40 * 30];
        let info = match r.render(w, h, &[], &mut gpu, &mut depth) {
            Ok(i) => i,
            Err(e) if std::env::var("FLUIDCAST_REQUIRE_GPU").as_deref() != Ok("1") => {
                return eprintln!("SKIPPED: {e}");
            }
            Err(e) => panic!("FLUIDCAST_REQUIRE_GPU=1 but: {e}"),
        };
        assert!(info.device.starts_with("GPU: "), "{}", info.device);
        let max = cpu
            .iter()
            .zip(&gpu)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f32::max);
        assert!(max <= 1e-3, "GPU vs CPU through the bridge: max abs {max}");
        let held = |r: &Renderer| {
            let b = r.backend.as_ref().unwrap();
            b.renderer.gpu().unwrap() as *const fluidcast_backend::Gpu
        };
        let first = held(&r);
        r.render(w, h, &[], &mut gpu, &mut depth).unwrap();
        assert_eq!(first, held(&r), "the GPU was reopened for the second frame");
        // The RBF field and iso-surfaces follow the backend, as in the CLI: on the GPU, and
        // within the GPU's rounding of what the CPU draws.
        let on = |r: &mut Renderer, backend: i32, field: &str| {
            let mut depth = vec![0f32; 40 * 30];
            let mut s = settings();
            (s.backend, s.field) = (backend, field.into());
            r.configure(&s).unwrap();
            let mut rgba = vec![0f32; 4 * 40 * 30];
            let info = r.render(w, h, &[], &mut rgba, &mut depth).unwrap();
            (rgba, info)
        };
        let (rbf_cpu, info) = on(&mut r, 1, "rbf");
        assert!(info.device.starts_with("CPU"), "{}", info.device);
        let (rbf_gpu, info) = on(&mut r, 2, "rbf");
        assert!(info.device.starts_with("GPU: "), "RBF: {}", info.device);
        let max = rbf_cpu
            .iter()
            .zip(&rbf_gpu)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f32::max);
        assert!(
            max <= 2e-3,
            "RBF GPU vs CPU through the bridge: max abs {max}"
        );
        assert!(rbf_cpu.iter().any(|&v| v > 0.01), "the RBF image is empty");
        r.set_surfaces(&surfaces(&[0.5], "value")).unwrap();
        let (_, info) = on(&mut r, 2, "csph");
        assert!(info.device.starts_with("GPU: "), "iso: {}", info.device);
        assert!(!info.notes.contains("reference"), "{}", info.notes);
        r.set_surfaces(&surfaces(&[], "value")).unwrap();
        s.backend = 7;
        let e = r.configure(&s).unwrap_err();
        assert!(e.contains("backend 7"), "{e}");
        assert_eq!(backend_names(), ["auto", "cpu", "gpu"]);
        for (i, k) in kernel_names().iter().enumerate() {
            assert_eq!(k.parse::<Kernel>().unwrap(), Kernel::ALL[i]);
        }
    }

    #[test]
    fn bad_input_is_an_error_naming_the_data() {
        let mut r = new_renderer();
        ready(&mut r);
        let mut s = settings();
        s.scalars = "nope".into();
        r.configure(&s).unwrap();
        let mut rgba = vec![0f32; 4];
        let mut depth = vec![0f32; 1];
        let e = r.render(1, 1, &[], &mut rgba, &mut depth).unwrap_err();
        assert!(e.contains("test cube") && e.contains("nope"), "{e}");

        let mut r = new_renderer();
        ready(&mut r);
        let radii = vec![f32::NAN; 216];
        r.add_point_array_f32("h", 1, &radii).unwrap();
        let mut s = settings();
        s.support_radius = 0.0;
        s.radius_array = "h".into();
        r.configure(&s).unwrap();
        let e = r.render(1, 1, &[], &mut rgba, &mut depth).unwrap_err();
        assert!(e.contains("support radius") && e.contains("NaN"), "{e}");

        let mut r = new_renderer();
        r.begin_data("empty");
        r.set_points_f32(&[]).unwrap();
        r.configure(&settings()).unwrap();
        assert!(r.prepare().unwrap_err().contains("no points"));
        assert!(r.add_point_array_f32("v", 1, &[1.0]).is_err());
        assert!(r.set_points_f32(&[1.0, 2.0]).is_err());

        let mut r = new_renderer();
        ready(&mut r);
        let mut s = settings();
        s.kernel = "bogus".into();
        assert!(r.configure(&s).unwrap_err().contains("bogus"));
        assert!(r
            .render(2, 2, &[1.0], &mut [0.0; 16], &mut [0.0; 4])
            .unwrap_err()
            .contains("depth limit"));
        let part_error =
            |r: &mut Renderer, crop: &[f64], depths: &[f64]| r.set_part(crop, depths).unwrap_err();
        assert!(part_error(&mut r, &[1.0; 3], &[]).contains("crop box has 3 values"));
        assert!(part_error(&mut r, &[], &[1.0]).contains("support depths: 1 values"));
        assert!(part_error(&mut r, &[], &[2.0, f64::NAN]).contains("not a range"));
        assert!(part_error(&mut r, &[], &[3.0, 2.0]).contains("not a range"));
        // A crop box that is not a box fails at the render, which names it.
        let mut r = new_renderer();
        ready(&mut r);
        r.set_part(&[0.0, 1.0, 0.0, f64::NAN, 0.0, 1.0], &[])
            .unwrap();
        assert!(r
            .render(2, 2, &[], &mut [0.0; 16], &mut [0.0; 4])
            .unwrap_err()
            .contains("crop box"));
    }

    #[test]
    fn sampled_transfer_function_interpolates_the_table() {
        let tf =
            transfer_function(10.0, 20.0, &[0., 0., 0., 1., 0.5, 0.], &[0.0, 1.0], 2.0).unwrap();
        let (c, a) = tf.eval(15.0);
        assert!((c[0] - 0.5).abs() < 1e-12 && (c[1] - 0.25).abs() < 1e-12);
        assert!((a - 0.5).abs() < 1e-12);
        assert!(transfer_function(0.0, 1.0, &[0.0; 3], &[0.0], 1.0).is_err());
        assert!(transfer_function(0.0, 1.0, &[0.0; 6], &[0.0; 2], 0.0).is_err());
    }

    #[test]
    fn a_series_lists_its_time_steps_in_order_with_their_files_resolved_against_its_folder() {
        let dir = std::env::temp_dir().join(format!("fluidcast_cxx_series_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let pvd = dir.join("s.pvd");
        std::fs::write(
            &pvd,
            r#"<VTKFile type="Collection"><Collection>
            <DataSet timestep="0.2" part="1" file="b1.vtu"/>
            <DataSet timestep="0.1" file="sub/a.vtu"/>
            <DataSet timestep="0.2" part="0" file="b0.vtu"/>
            </Collection></VTKFile>"#,
        )
        .unwrap();
        let path = pvd.to_str().unwrap();
        let s = read_series(path).unwrap();
        let got: Vec<(f64, Vec<String>)> = s.iter().map(|e| (e.time, e.files.clone())).collect();
        let at = |f: &str| dir.join(f).to_str().unwrap().to_owned();
        assert_eq!(
            got,
            [
                (0.1, vec![at("sub/a.vtu")]),
                (0.2, vec![at("b1.vtu"), at("b0.vtu")])
            ]
        );
        std::fs::write(&pvd, "<VTKFile type=\"Collection\"><Collection>").unwrap();
        let e = read_series(path).unwrap_err();
        assert!(e.contains("s.pvd") && e.contains("</Collection>"), "{e}");
        assert!(read_series(dir.join("none.pvd").to_str().unwrap())
            .unwrap_err()
            .contains("none.pvd"));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
