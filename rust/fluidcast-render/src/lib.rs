//! Emission–absorption ray casting of SPH particle fields.
//!
//! Both renderers sample each pixel's ray at the logarithmically spaced view depths of
//! Hochstetter et al. 2016, Eq. 8 (`z_i = n (f/n)^(i/N)`), with `N` from Fraedrich et al.
//! 2010 (`m = ln(f/n)/σ`, σ the angular pixel size) so that the depth step matches the
//! lateral pixel footprint, scaled by the frustum-corner factor λ and a user factor, and
//! rounded up to a multiple of the grid's samples per cell. Samples lie on planes of constant
//! view depth, shared by all rays. Each sample's field value is the exact kernel sum over all
//! particles whose support contains it.
//!
//! * [`render_reference`] is the oracle every faster path is tested against: particles are
//!   binned into 8×8-pixel tiles and every ray scatters all particles of its tile into its
//!   samples before compositing.
//! * [`render_adaptive`] is the paper's pipeline: the sparse perspective grid
//!   ([`fluidcast_grid`]), the sampling plan ([`fluidcast_plan`]: error analysis, greedy
//!   levels, super-pixels, merging) and bundle-coherent ray casting (Alg. 2) that walks each
//!   bundle's cells front to back and stops once all its rays are opaque. With no error
//!   tolerance it samples exactly the reference's positions.
#![warn(missing_docs)]

mod adaptive;
pub mod bluenoise;
mod crop;
pub mod interpolate;
mod object_space;
mod overlay;
mod perspective;
pub mod precision;
mod progress;
mod raycast;
mod rbf;
mod reference;
mod span;
mod steps;
mod surface;
mod tiles;

use std::sync::Arc;
use std::time::Instant;

pub use adaptive::{
    bundle_aovs, plan_adaptive, plan_aovs, plan_surface, render_adaptive, AdaptivePlan,
    AdaptiveRender, SURFACE_THRESHOLD,
};
pub use crop::crop_to_box;
pub use fluidcast_grid::{support_depth_extent, GridError, GridParams, SampleDepths};
pub use fluidcast_plan::{
    BundleSummary, PlanError, PlanParams, PlanStats, SamplingPlan, MAX_SPAN_SAMPLES,
};
pub use object_space::render_object_space;
pub use overlay::render_over_surfaces;
pub use perspective::{render_perspective_grid, tile_margin, MAX_CELL, SLAB};
pub use progress::Progress;
pub use rbf::{
    mix32, rbf_step_checked, render_rbf, white_offset, Noise, RbfRenderParams, RbfShadows, HASH_IN,
    HASH_MUL, HASH_SEED, MAX_OPTICAL_DEPTH, MAX_RBF_STEPS, PICK_STREAM, SHADOW_STREAM,
};
pub use reference::render_reference;
pub use surface::{add_normal_aovs, IsoField, SurfaceError, Surfaces};
pub use tiles::{
    render_in_tiles, tile_particles_within, MIN_TILE_BYTES, TILING_BYTES_PER_PARTICLE,
    VIEW_BYTES_PER_PARTICLE,
};

use fluidcast_sph::{FieldKind, Kernel, Particles};
use fluidcast_view::{CameraError, Lighting};
use rayon::prelude::*;

/// Largest image side and pixel count the renderer accepts.
pub const MAX_SIDE: u32 = 16384;
const MAX_PIXELS: u64 = 1 << 27;

/// Bytes per pixel the renderers hold whatever the data: the RGBA and depth image, its
/// three plan AOVs, per-pixel depth limits and per-ray state.
pub const IMAGE_BYTES_PER_PIXEL: u64 = 64;

/// Parameters of a rendering, shared by every renderer (and the GPU path).
#[derive(Debug, Clone)]
pub struct RenderParams {
    /// Image size in pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// The smoothing kernel.
    pub kernel: Kernel,
    /// The field reconstructed (CSPH, SPH sum, density).
    pub field: FieldKind,
    /// Multiplies the number of depth samples (1 = depth step equals the pixel footprint).
    pub sampling_scale: f64,
    /// A ray stops once its transmittance drops below this.
    pub min_transmittance: f64,
    /// Bundle size D_xy and depth samples per cell D_z (the reference uses D_z only, to
    /// sample the same depths).
    pub grid: GridParams,
    /// Error tolerance and the optimisations of the adaptive renderer.
    pub adaptive: PlanParams,
    /// Per pixel (row 0 at the top, `width × height` values), the view depth of opaque
    /// geometry drawn before the particles (a VTK depth buffer turned into view depth): each
    /// ray stops there, the last step cut at it, so a volume behind a surface is hidden and
    /// one in front covers it. `+∞` where there is none; `None` for no geometry at all.
    pub depth_limit: Option<Arc<[f32]>>,
    /// Per pixel (as `depth_limit`), the view depth where the ray starts: what lies in front
    /// of it is not composited and a step that straddles it keeps its back part, cut as a
    /// homogeneous segment. With `depth_limit` this crops each ray to a region, e.g. the box a
    /// rank owns under MPI: the images of regions that partition space, composited in
    /// visibility order, equal the image of the whole. `None`: every ray starts at the camera.
    pub depth_near: Option<Arc<[f32]>>,
    /// `(zmin, zmax)`: the smallest and largest view depth of any particle's support in the
    /// whole data set when the particles rendered are only part of it (an MPI rank's, see
    /// [`fluidcast_grid::support_depth_extent`]): the depth samples are placed over it, as
    /// one renderer of all the particles places them, so that the parts' images composite to
    /// the whole's. `None`: over these particles' own.
    pub support_depths: Option<(f64, f64)>,
    /// Iso-surfaces to draw (shaded, in depth order with the volume when they ask for it);
    /// `None`: the emission–absorption volume alone. Drawn by [`render_reference`]; the other
    /// renderers refuse them ([`SurfaceError::Unsupported`]).
    pub surfaces: Option<Arc<Surfaces>>,
    /// Shaded volume rendering: each volume sample's colour lit with these coefficients and
    /// light, its normal the analytic gradient of the rendered field there (facing the eye).
    /// `None`: emission–absorption as the transfer function gives it. Drawn by
    /// [`render_reference`]; the other renderers refuse it.
    pub volume_lighting: Option<Lighting>,
    /// Occlusion culling in the perspective grid renderer (on by default): a tile of grid
    /// columns is not resampled once every pixel that reads it has stopped (early ray
    /// termination at `min_transmittance`), which changes no pixel. Off: for measuring it.
    pub occlusion_culling: bool,
    /// Where the ray cast reports its progress and looks for a request to stop (`None`:
    /// nobody watches). The adaptive and reference renderers on the CPU honour it.
    pub progress: Option<Arc<Progress>>,
    /// What of the image the caller needs back: a GPU renderer copies only this from the
    /// device. Default: depth and colour at full precision.
    pub output: ImageOutput,
}

/// What of a rendered image the caller uses besides its colour. The CPU renderers fill in
/// everything anyway; the GPU backend copies from the device only what is asked for, and its
/// refinement passes (relaxed mode), which decide on full-precision colour and depth, read
/// those back whatever is asked.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImageOutput {
    /// The view depth per pixel ([`fluidcast_image::Image::depth`]). Off: the GPU leaves it
    /// at +∞ and copies 4 bytes a pixel less.
    pub depth: bool,
    /// Colour in half precision (IEEE binary16, rounded to one of the two nearest values as
    /// WGSL allows: relative error below 2⁻¹⁰, for display at 8 or 10 bits): the GPU copies
    /// 8 bytes a pixel instead of 16.
    pub half_colour: bool,
}

impl ImageOutput {
    /// Depth and colour at full precision: what EXR files, compositing and comparisons use.
    pub const FULL: ImageOutput = ImageOutput {
        depth: true,
        half_colour: false,
    };
    /// Colour at half precision and no depth: what a window shows.
    pub const DISPLAY: ImageOutput = ImageOutput {
        depth: false,
        half_colour: true,
    };
}

impl Default for ImageOutput {
    fn default() -> Self {
        ImageOutput::FULL
    }
}

impl RenderParams {
    /// The view depth at which pixel (i, j)'s ray stops (`+∞` without a depth limit).
    #[inline]
    pub fn depth_limit_at(&self, i: u32, j: u32) -> f64 {
        match &self.depth_limit {
            Some(d) => d[j as usize * self.width as usize + i as usize] as f64,
            None => f64::INFINITY,
        }
    }

    /// The view depths (near, far) between which pixel (i, j)'s ray is composited.
    #[inline]
    pub fn depth_range_at(&self, i: u32, j: u32) -> (f64, f64) {
        let near = match &self.depth_near {
            Some(d) => d[j as usize * self.width as usize + i as usize] as f64,
            None => f64::NEG_INFINITY,
        };
        (near, self.depth_limit_at(i, j))
    }

    /// Per bundle of `grid.bundle × grid.bundle` pixels (row-major, the last row and column
    /// cut at the image's edge, as [`fluidcast_grid::PerspectiveGrid::bundle`]), the nearest
    /// view depth at which opaque geometry stops one of its rays (`+∞` where none does);
    /// `None` without a depth limit. The CPU and GPU planners read it
    /// ([`fluidcast_plan::SamplingPlan::build`]'s `stops`).
    pub fn bundle_stops(&self) -> Option<Vec<f64>> {
        self.depth_limit.as_ref()?;
        let (w, h, d) = (self.width, self.height, self.grid.bundle.max(1));
        let stops = (0..(w.div_ceil(d) * h.div_ceil(d)) as usize).map(|b| {
            let [x0, x1, y0, y1] = fluidcast_grid::bundle_pixels(w, h, d, b);
            (y0..y1)
                .flat_map(|j| (x0..x1).map(move |i| (i, j)))
                .map(|(i, j)| self.depth_limit_at(i, j))
                .fold(f64::INFINITY, f64::min)
        });
        Some(stops.collect())
    }
}

impl Default for RenderParams {
    fn default() -> Self {
        RenderParams {
            width: 512,
            height: 512,
            kernel: Kernel::CubicSpline,
            field: FieldKind::Csph,
            sampling_scale: 1.0,
            min_transmittance: 1e-4,
            grid: GridParams::default(),
            adaptive: PlanParams::default(),
            depth_limit: None,
            depth_near: None,
            support_depths: None,
            surfaces: None,
            volume_lighting: None,
            occlusion_culling: true,
            progress: None,
            output: ImageOutput::FULL,
        }
    }
}

/// Why a rendering could not be made.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// The caller cancelled the render ([`Progress::cancel`]).
    #[error("cancelled")]
    Cancelled,
    /// The camera cannot see.
    #[error("camera: {0}")]
    Camera(#[from] CameraError),
    /// An image side out of 1..=MAX_SIDE, or too many pixels.
    #[error("image size {0}x{1} is out of range (each side 1..={MAX_SIDE}, at most {MAX_PIXELS} pixels)")]
    ImageSize(u32, u32),
    /// The perspective grid could not be built.
    #[error(transparent)]
    Grid(#[from] GridError),
    /// The sampling plan could not be made.
    #[error(transparent)]
    Plan(#[from] PlanError),
    /// A minimum transmittance outside [0, 1).
    #[error("minimum transmittance {0} must be in [0, 1)")]
    MinTransmittance(f64),
    /// A depth limit of another size than the image (which, values, width, height).
    #[error("{0} has {1} values for a {2}x{3} image")]
    DepthLimitSize(&'static str, usize, u32, u32),
    /// Support depths that are not a finite range.
    #[error("support depths {0}..{1} are not a finite range")]
    SupportDepths(f64, f64),
    /// A crop box that is not finite, or min > max.
    #[error("crop box {0:?}..{1:?} is not a finite box (each min <= max)")]
    CropBox([f64; 3], [f64; 3]),
    /// A depth limit holding NaN or a negative depth (which).
    #[error("{0} holds NaN or a negative depth")]
    DepthLimitValue(&'static str),
    /// A perspective grid cell out of range, pixels.
    #[error("perspective grid cell {0} pixels: must be 1..={max}", max = perspective::MAX_CELL)]
    GridCell(u32),
    /// A renderer (named) asked for a shaded volume it does not draw.
    #[error("{0} does not draw a shaded volume yet; render it with the reference renderer (CLI: --mode reference, which --shade-volume chooses by default)")]
    VolumeLighting(&'static str),
    /// Iso-surfaces that cannot be drawn.
    #[error("iso-surfaces: {0}")]
    Surface(#[from] SurfaceError),
    /// A particle whose kernel weight single precision cannot sum ([`check_weights`]).
    #[error("particle {index}: its kernel weight {what} x W(0) = {weight:e} is not a number single precision can sum (the grid renderers sum in it): rescale the data (e.g. lengths in other units)")]
    Weight {
        /// The particle.
        index: usize,
        /// What its weight is made of.
        what: &'static str,
        /// The weight.
        weight: f64,
    },
    /// Rendering in screen tiles within a memory budget ([`tile_particles_within`]).
    #[error("a memory limit leaving {} for rendering is too small: it needs at least {} (the image, 9 bytes a particle, and a tile of 1 MiB)", fluidcast_mem::Bytes(*.budget), fluidcast_mem::Bytes(*.needed))]
    MemoryBudget {
        /// The bytes the limit leaves for rendering.
        budget: u64,
        /// The bytes one render in tiles needs at least.
        needed: u64,
    },
    /// The RBF field could not be built.
    #[error("RBF field: {0}")]
    RbfField(#[from] fluidcast_rbf::RbfError),
    /// The RBF march refused its parameters, in words.
    #[error("RBF renderer: {0}")]
    Rbf(String),
}

/// Largest kernel weight the grid renderers accept: single precision's largest number over a
/// million, so that sums of many such weights stay finite.
pub const MAX_WEIGHT: f64 = f32::MAX as f64 / 1e6;

/// Checks that every particle's largest weights at a sample, V·|q|·W(0), V·W(0) and m·W(0)
/// (the rendered and Shepard sums, and the density's), stay below [`MAX_WEIGHT`]: the grid
/// renderers (the CPU's span loop, the GPU) sum them in single precision, where a larger
/// one would become infinite and the sample not a number.
pub fn check_weights(particles: &Particles, kernel: Kernel) -> Result<(), RenderError> {
    let weights = |j: usize| {
        let peak = kernel.eval(0.0, f64::from(particles.radii[j]));
        let v = f64::from(particles.volumes[j]);
        [
            ("V·|q|", v * f64::from(particles.values[j]).abs() * peak),
            ("V", v * peak),
            ("m", f64::from(particles.masses[j]) * peak),
        ]
    };
    // A NaN weight is refused too.
    let too_large = |(_, w): &(&'static str, f64)| w.is_nan() || *w > MAX_WEIGHT;
    let bad = (0..particles.len())
        .into_par_iter()
        .find_first(|&j| weights(j).iter().any(too_large));
    match bad.and_then(|j| weights(j).into_iter().find(too_large).map(|w| (j, w))) {
        Some((index, (what, weight))) => Err(RenderError::Weight {
            index,
            what,
            weight,
        }),
        None => Ok(()),
    }
}

/// A rendered frame: the image and what it took. What every backend returns (the CPU renderers
/// here, `fluidcast-gpu`, and `fluidcast-backend`, which chooses between them).
#[derive(Debug, Clone)]
pub struct Rendered {
    /// Premultiplied RGBA and depth per pixel.
    pub image: fluidcast_image::Image,
    /// Timings and counts.
    pub stats: RenderStats,
}

/// Timings and counts of one rendering.
#[derive(Debug, Clone, Default)]
pub struct RenderStats {
    /// (stage, milliseconds) in order; `total` covers the renderer's own stages.
    pub stages: Vec<(&'static str, f64)>,
    /// Particles given.
    pub particles: usize,
    /// Particles whose support intersects the view frustum.
    pub particles_visible: usize,
    /// Samples with at least one contributing particle that were composited.
    pub samples: u64,
    /// Depth samples per ray (N) and the view-depth range [near, far].
    pub depth_samples: usize,
    /// See `depth_samples`.
    pub near: f64,
    /// See `depth_samples`.
    pub far: f64,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Grid renderer only: ray bundles, non-empty cells, particle–cell pairs and the plan.
    pub bundles: u64,
    /// See `bundles`.
    pub cells: u64,
    /// See `bundles`.
    pub pairs: u64,
    /// See `bundles`.
    pub plan: Option<PlanStats>,
    /// GPU backend only: bytes of GPU buffers held (kept and reused across frames).
    pub gpu_memory_bytes: u64,
    /// Screen tiles the view was rendered in ([`render_in_tiles`]); 0: one render.
    pub tiles: usize,
    /// Perspective grid only: particle references of tiles not resampled because every
    /// pixel they reach had stopped ([`RenderParams::occlusion_culling`]).
    pub culled: u64,
    /// Grid renderer, relaxed mode: pixels filled by interpolation instead of cast
    /// ([`interpolate`]).
    pub interpolated: u64,
    /// GPU backend: dispatches of the ray casting stage, one per pass on hardware; more where
    /// a software driver's loop limit made bundles stop and resume (see docs/gpu.md).
    pub dispatches: u64,
    /// GPU backend: what crossed between host and device, and how often the host waited.
    pub transfers: Transfers,
}

/// GPU backend: the traffic between host and device of one frame. On a hardware GPU each
/// wait is a round trip (submit, run, map) and the bytes cross the PCIe bus, so these counts
/// predict what a frame costs beyond its kernels.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Transfers {
    /// Bytes written into device buffers (particles, sample depths, uniforms, tables).
    pub uploaded_bytes: u64,
    /// Bytes copied back to the host (counts, summaries, the image).
    pub readback_bytes: u64,
    /// Command buffers submitted.
    pub submits: u64,
    /// Times the host waited for the device.
    pub waits: u64,
}

impl std::ops::AddAssign for Transfers {
    fn add_assign(&mut self, o: Transfers) {
        self.uploaded_bytes += o.uploaded_bytes;
        self.readback_bytes += o.readback_bytes;
        self.submits += o.submits;
        self.waits += o.waits;
    }
}

impl RenderStats {
    /// Milliseconds of a stage, if it ran.
    pub fn stage(&self, name: &str) -> Option<f64> {
        self.stages.iter().find(|s| s.0 == name).map(|s| s.1)
    }
}

/// Milliseconds since `t`.
pub fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// Refuses iso-surfaces in a renderer (`what`, e.g. "the adaptive grid renderer") that does
/// not draw them yet.
pub fn refuse_surfaces(params: &RenderParams, what: &'static str) -> Result<(), RenderError> {
    if params.surfaces.is_some() {
        return Err(SurfaceError::Unsupported(what).into());
    }
    if params.volume_lighting.is_some() {
        return Err(RenderError::VolumeLighting(what));
    }
    Ok(())
}

/// Checks the image size and the parameters every renderer shares (the GPU path too).
pub fn validate(params: &RenderParams) -> Result<(), RenderError> {
    let (w, h) = (params.width, params.height);
    if w == 0 || h == 0 || w > MAX_SIDE || h > MAX_SIDE || (w as u64 * h as u64) > MAX_PIXELS {
        return Err(RenderError::ImageSize(w, h));
    }
    if !(0.0..1.0).contains(&params.min_transmittance) {
        return Err(RenderError::MinTransmittance(params.min_transmittance));
    }
    if !(params.sampling_scale.is_finite() && params.sampling_scale > 0.0) {
        return Err(GridError::SamplingScale(params.sampling_scale).into());
    }
    params.grid.validate()?;
    let pixels = w as u64 * h as u64;
    fluidcast_mem::check(
        || format!("a {w}x{h} render"),
        pixels.saturating_mul(IMAGE_BYTES_PER_PIXEL),
    )
    .map_err(GridError::from)?;
    if let Some((lo, hi)) = params.support_depths {
        if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
            return Err(RenderError::SupportDepths(lo, hi));
        }
    }
    let limits = [
        ("depth limit", &params.depth_limit),
        ("depth near", &params.depth_near),
    ];
    for (what, d) in limits {
        let Some(d) = d else { continue };
        if d.len() != w as usize * h as usize {
            return Err(RenderError::DepthLimitSize(what, d.len(), w, h));
        }
        if d.iter().any(|z| z.is_nan() || *z < 0.0) {
            return Err(RenderError::DepthLimitValue(what));
        }
    }
    Ok(())
}
