//! The adaptive renderer of Hochstetter et al. 2016 on the GPU (wgpu compute, WGSL): every
//! stage of [`fluidcast_render::render_adaptive`], in single precision, with the CPU crates as
//! its mirror.
//!
//! | stage | shader | CPU mirror |
//! |---|---|---|
//! | particles to view space, depth range | `grid.wgsl: view` | `fluidcast_grid::view_particles` |
//! | (cell, particle) pairs with the merge bit | `grid.wgsl: footprint, emit` + `scan.wgsl` | `PerspectiveGrid::build` |
//! | radix sort of the pairs | `sort.wgsl` | the counting sort + per-bundle sort there |
//! | cells and bundle cell ranges | `grid.wgsl: cell_starts, make_cells, bundle_ranges` | `PerspectiveGrid::cells` |
//! | error analysis per cell | `plan.wgsl: analyse` | `fluidcast_plan` `cell_bounds` |
//! | greedy levels, super-pixels, merging per bundle | `plan.wgsl: greedy` | `plan_bundle` |
//! | bundle-coherent ray casting (Alg. 2) | `raycast.wgsl` | `render_adaptive`'s caster |
//! | iso-surfaces: crossings refined on the exact sum, shaded ([`Gpu::render_surfaces`]) | `surface.wgsl` (on the grid above) | `render_reference`'s surface walk |
//! | the RBF field's passes ([`Gpu::render_rbf`]) | `rbf.wgsl` | `render_rbf` |
//!
//! The depth range and the sample depths are found on the host in f64, exactly as the CPU
//! renderer finds them ([`fluidcast_grid::support_depth_range`]); the host reads back two
//! numbers on the way (the pair count and the cell count, to size buffers and dispatches).
//! Buffers are kept between frames and grow only when a frame needs more. [`Gpu::render_planned`] runs the last stage alone on a grid and plan
//! built on the CPU, and [`Gpu::render_with_dump`] returns the GPU's grid and plan, so each
//! stage can be tested against its mirror.
//!
//! Runs headless on any wgpu adapter, Mesa's lavapipe (CPU Vulkan) included; [`Gpu::new`]
//! says why when there is none, and [`Gpu::open`] takes an [`AdapterChoice`].
//!
//! Modules mirror the CPU crates stage by stage: `grid` (fluidcast-grid), `sort` (its counting
//! sort), `plan` (fluidcast-plan), `raycast` (fluidcast-render's caster), `surface` (its
//! surface walk), `rbf` (its RBF march), with `frame`
//! running them in order, `layout` holding the structs the host shares with the WGSL (size and
//! offsets checked against naga's layout) and `pass` the pipelines, whose bindings are looked
//! up by the WGSL global's name.
#![warn(missing_docs)]

mod adapter;
mod frame;
mod grid;
mod layout;
mod pass;
mod plan;
mod raycast;
mod rbf;
mod sort;
mod surface;

use std::collections::HashMap;
use std::sync::Mutex;

use bytemuck::Pod;
use fluidcast_render::{RenderError, RenderStats, Transfers};
use pass::{Pipe, Shader};

pub use adapter::{list_adapters, AdapterChoice, ADAPTER_ENV};
pub use frame::GpuDump;

/// Why the GPU path could not run.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    /// No wgpu adapter at all (no GPU driver, no lavapipe).
    #[error("no GPU adapter found (wgpu: {0}); on a machine without a GPU install Mesa's lavapipe (Debian: mesa-vulkan-drivers)")]
    NoAdapter(String),
    /// `auto` found only software adapters.
    #[error("no hardware GPU (adapters: {0})")]
    NoHardware(String),
    /// No adapter's name contains the one asked for (the name, the adapters).
    #[error("no GPU adapter's name contains '{0}' (adapters: {1})")]
    NoSuchAdapter(String, String),
    /// The adapter would not give a device, or the device was lost.
    #[error("GPU device: {0}")]
    Device(String),
    /// A ray bundle larger than the GPU's 8x8 pixels.
    #[error("the GPU renderer supports ray bundles of at most 8x8 pixels (--bundle {0})")]
    BundleTooLarge(u32),
    /// An image whose RGBA floats exceed one storage binding (width, height, most pixels).
    #[error("a {0}x{1} image is more than the GPU's buffers take ({2} pixels at most); render a smaller image or use --backend cpu")]
    ImageTooLarge(u32, u32, u64),
    /// More particle–cell pairs than the GPU's buffers take (pairs, limit).
    #[error("the view needs {0} particle-cell pairs, more than the GPU renderer's limit of {1}; render a smaller image, fewer particles or use --backend cpu")]
    TooManyPairs(u64, u64),
    /// More non-empty cells than the GPU's buffers take (cells, limit).
    #[error("the view has {0} non-empty cells, more than the GPU renderer's limit of {1}; render a smaller image or use --backend cpu")]
    TooManyCells(u64, u64),
    /// Bundles × cells beyond the 32-bit cell keys (bundles, cells per bundle).
    #[error("the view has {0} bundles x {1} cells, too many for the GPU grid's 32-bit cell keys; render a smaller image or lower --sampling")]
    GridTooLarge(u64, u64),
    /// More particles than the GPU takes (particles, limit).
    #[error("{0} particles are more than the GPU renderer takes ({1})")]
    TooManyParticles(usize, u64),
    /// A software driver's loop limit would end a shader invocation early: refused, never drawn wrong.
    #[error("{adapter} is a software driver (Mesa llvmpipe/lavapipe), which silently ends every shader invocation after 65535 loop iterations, and {stage} of this view needs more in one ray bundle; render with --backend cpu (auto does), at a larger image size or on a hardware GPU")]
    LoopLimit {
        /// The adapter's name.
        adapter: String,
        /// The stage that needs more iterations.
        stage: &'static str,
    },
    /// More iso values than the GPU's surfaces take.
    #[error("{0} iso values: the GPU draws at most {max} iso-surfaces at once; render with --backend cpu or give fewer values", max = layout::MAX_ISO_VALUES)]
    IsoValues(usize),
    /// A transfer function with more control points than the shader's table.
    #[error("the transfer function has {0} control points; the GPU renderer takes at most {max} per table", max = MAX_TF_POINTS)]
    TransferFunction(usize),
    /// What the CPU renderer's checks refuse (shared parameters).
    #[error(transparent)]
    Render(#[from] RenderError),
}

impl GpuError {
    /// For a view whose particle–cell pairs or cells do not fit one buffer binding
    /// ([`GpuError::TooManyPairs`], [`GpuError::TooManyCells`]): what it needs and the
    /// limit. Screen tiles with fewer particles each need less (the backend renders such a
    /// view in tiles).
    pub fn buffer_overflow(&self) -> Option<(u64, u64)> {
        match self {
            GpuError::TooManyPairs(n, limit) | GpuError::TooManyCells(n, limit) => {
                Some((*n, *limit))
            }
            _ => None,
        }
    }
}

/// The compute pipelines, one per shader entry point, each stage's next to its shader.
struct Pipelines {
    view: Pipe,
    footprint: Pipe,
    emit: Pipe,
    cell_starts: Pipe,
    make_cells: Pipe,
    bundle_ranges: Pipe,
    scan_blocks: Pipe,
    add_sums: Pipe,
    histogram: Pipe,
    scatter: Pipe,
    analyse: Pipe,
    greedy: Pipe,
    raycast: Pipe,
    rbf: Pipe,
    surface: Pipe,
    pack_half: Pipe,
}

impl Pipelines {
    /// Compiles the shaders: the Rust-owned constants and common.wgsl, then each stage's; the
    /// scans and the sort's ranks with subgroup operations where `subgroups` (the device has
    /// the feature), else in workgroup memory alone.
    fn new(device: &wgpu::Device, subgroups: bool) -> Result<Pipelines, GpuError> {
        let common = format!(
            "{}{}",
            layout::wgsl_prelude(),
            include_str!("shaders/common.wgsl")
        );
        let staged = |name: &str, src: &str| Shader::new(device, name, &format!("{common}\n{src}"));
        let grid = staged("grid", include_str!("shaders/grid.wgsl"))?;
        let plan = staged("plan", include_str!("shaders/plan.wgsl"))?;
        let raycast = staged("raycast", include_str!("shaders/raycast.wgsl"))?;
        let rbf_src = format!(
            "{}{}",
            layout::rbf_prelude(),
            include_str!("shaders/rbf.wgsl")
        );
        let rbf = staged("rbf", &rbf_src)?;
        let surface_src = format!(
            "{}{}",
            layout::surface_prelude(),
            include_str!("shaders/surface.wgsl")
        );
        let surface = staged("surface", &surface_src)?;
        let prefix = match subgroups {
            true => include_str!("shaders/prefix_subgroups.wgsl"),
            false => include_str!("shaders/prefix_barriers.wgsl"),
        };
        let prefixed =
            |name: &str, src: &str| Shader::new(device, name, &format!("{prefix}\n{src}"));
        let scan = prefixed("scan", include_str!("shaders/scan.wgsl"))?;
        let sort = prefixed("sort", include_str!("shaders/sort.wgsl"))?;
        let readback = Shader::new(device, "readback", include_str!("shaders/readback.wgsl"))?;
        Ok(Pipelines {
            view: grid.pipe(device, "view"),
            footprint: grid.pipe(device, "footprint"),
            emit: grid.pipe(device, "emit"),
            cell_starts: grid.pipe(device, "cell_starts"),
            make_cells: grid.pipe(device, "make_cells"),
            bundle_ranges: grid.pipe(device, "bundle_ranges"),
            scan_blocks: scan.pipe(device, "scan_blocks"),
            add_sums: scan.pipe(device, "add_sums"),
            histogram: sort.pipe(device, "histogram"),
            scatter: sort.pipe(device, "scatter"),
            analyse: plan.pipe(device, "analyse"),
            greedy: plan.pipe(device, "greedy"),
            raycast: raycast.pipe(device, "main"),
            rbf: rbf.pipe(device, "main"),
            surface: surface.pipe(device, "main"),
            pack_half: readback.pipe(device, "pack_half"),
        })
    }
}

/// A wgpu device with the renderer's pipelines compiled, and the buffers it keeps between
/// frames.
pub struct Gpu {
    device: wgpu::Device,
    queue: wgpu::Queue,
    pipes: Pipelines,
    /// The scans and the sort use subgroup operations (`prefix_subgroups.wgsl`).
    subgroups: bool,
    /// Adapter name and backend, for messages ("llvmpipe (Vulkan)").
    pub adapter: String,
    /// GPU-side durations from timestamp queries, where the adapter supports them.
    timestamps: Option<wgpu::QuerySet>,
    /// Buffers kept between frames, by role; replaced only when too small.
    buffers: Mutex<HashMap<&'static str, wgpu::Buffer>>,
    /// One frame at a time: the kept buffers are shared.
    frame_lock: Mutex<()>,
    /// The current frame's traffic between host and device (reset when a frame starts).
    traffic: Mutex<Transfers>,
    /// A fingerprint of the particles in the "world particles" buffer, which a frame of the
    /// same particles uses again without uploading them ([`grid::particles_key`]).
    world_key: Mutex<Option<u128>>,
    /// The last frame's cell count, from which the next frame sizes its plan without waiting
    /// for its own ([`Gpu::cell_capacity`]).
    cells_hint: Mutex<u32>,
    /// Largest storage buffer binding (bytes).
    max_binding: u64,
    /// Loop iterations a shader invocation may run (`SOFTWARE_LOOP_LIMIT` on CPU adapters,
    /// unlimited on hardware unless [`Gpu::with_loop_limit`] bounds it).
    loop_limit: u32,
    /// A CPU adapter (Mesa's lavapipe or llvmpipe).
    software: bool,
}

/// Whether the scans and the sort may use subgroup operations on `adapter`: it has them, with
/// subgroups of 4 to 256 invocations (prefix_subgroups.wgsl), and `FLUIDCAST_GPU_SUBGROUPS`
/// is not `0`.
fn subgroups_usable(adapter: &wgpu::Adapter) -> bool {
    let info = adapter.get_info();
    let sizes = info.subgroup_min_size >= 4 && info.subgroup_max_size <= 256;
    let off = std::env::var("FLUIDCAST_GPU_SUBGROUPS").is_ok_and(|v| v.trim() == "0");
    adapter.features().contains(wgpu::Features::SUBGROUP) && sizes && !off
}

/// The pipelines, with a compilation error reported as one (not a panic in wgpu's handler).
fn compile(device: &wgpu::Device, subgroups: bool) -> Result<Pipelines, GpuError> {
    let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let pipes = Pipelines::new(device, subgroups)?;
    if let Some(e) = pollster::block_on(scope.pop()) {
        return Err(GpuError::Device(format!("compiling the shaders: {e}")));
    }
    Ok(pipes)
}

/// Most control points per transfer function table (colour, opacity) the shaders search
/// (`table_at` in common.wgsl probes from 2048 down).
pub const MAX_TF_POINTS: usize = 4096;

/// Loop iterations one shader invocation may run on a software driver: Mesa's gallivm ends
/// all loops of an invocation after 65535 (LP_MAX_TGSI_LOOP_ITERATIONS); the shaders count
/// theirs with a bound a little above the driver's own count, so this leaves a margin.
const SOFTWARE_LOOP_LIMIT: u32 = 60_000;

/// Most timestamp queries one frame writes (two per timed pass).
const QUERIES: u32 = 32;

/// Storage that shaders write and the host may fill or read back.
const RW: wgpu::BufferUsages = wgpu::BufferUsages::STORAGE
    .union(wgpu::BufferUsages::COPY_DST)
    .union(wgpu::BufferUsages::COPY_SRC);

impl Gpu {
    /// Opens the adapter named by `FLUIDCAST_ADAPTER` if set, else the best one of any kind
    /// (see [`AdapterChoice::Any`]), and compiles the shaders.
    pub fn new() -> Result<Gpu, GpuError> {
        Gpu::open(&AdapterChoice::from_env().unwrap_or(AdapterChoice::Any))
    }

    /// Opens the adapter `choice` picks and compiles the shaders. Where the adapter has
    /// subgroup operations (and `FLUIDCAST_GPU_SUBGROUPS` is not `0`), the scans and the sort
    /// use them once a scan and a sort on the device agree with the host's
    /// ([`Gpu::check_prefix_sums`]); otherwise, or when they do not, they run in workgroup
    /// memory alone.
    pub fn open(choice: &AdapterChoice) -> Result<Gpu, GpuError> {
        let adapter = adapter::pick(choice)?;
        let info = adapter.get_info();
        let timestamps = adapter.features().contains(wgpu::Features::TIMESTAMP_QUERY);
        let subgroups = subgroups_usable(&adapter);
        let limits = adapter.limits();
        let mut required_features = wgpu::Features::empty();
        required_features.set(wgpu::Features::TIMESTAMP_QUERY, timestamps);
        required_features.set(wgpu::Features::SUBGROUP, subgroups);
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("fluidcast"),
            required_limits: limits.clone(),
            required_features,
            ..Default::default()
        }))
        .map_err(|e| GpuError::Device(e.to_string()))?;
        // A driver or shader compiler that fails the subgroup variant gets the other.
        let (pipes, subgroups) = match subgroups.then(|| compile(&device, true)) {
            Some(Ok(p)) => (p, true),
            _ => (compile(&device, false)?, false),
        };
        let timestamps = timestamps.then(|| {
            device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("stage timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count: QUERIES,
            })
        });
        let gpu = Gpu {
            device,
            queue,
            pipes,
            subgroups,
            adapter: adapter::name(&adapter),
            timestamps,
            buffers: Default::default(),
            frame_lock: Mutex::new(()),
            traffic: Default::default(),
            world_key: Default::default(),
            cells_hint: Default::default(),
            max_binding: limits
                .max_storage_buffer_binding_size
                .min(limits.max_buffer_size),
            loop_limit: if info.device_type == wgpu::DeviceType::Cpu {
                SOFTWARE_LOOP_LIMIT
            } else {
                u32::MAX
            },
            software: info.device_type == wgpu::DeviceType::Cpu,
        };
        match gpu.subgroups && !gpu.check_prefix_sums()? {
            true => gpu.without_subgroups(),
            false => Ok(gpu),
        }
    }

    /// This GPU with the scans and the sort in workgroup memory alone, not with subgroup
    /// operations (the same results: both are exact integer sums).
    pub fn without_subgroups(mut self) -> Result<Gpu, GpuError> {
        if self.subgroups {
            self.pipes = compile(&self.device, false)?;
            self.subgroups = false;
        }
        Ok(self)
    }

    /// True when the scans and the sort use subgroup operations.
    pub fn uses_subgroups(&self) -> bool {
        self.subgroups
    }

    /// True on a software driver (a CPU adapter: Mesa's lavapipe or llvmpipe), whose loop limit
    /// the shaders guard (see `GpuError::LoopLimit`).
    pub fn is_software(&self) -> bool {
        self.software
    }

    /// This GPU with at most `iterations` loop iterations per shader invocation (never more
    /// than a software driver allows): the ray casters then split their work into more
    /// dispatches, each invocation's bounded, so that no dispatch runs long (a desktop driver
    /// resets a GPU whose dispatch runs for seconds). The image is the same.
    pub fn with_loop_limit(mut self, iterations: u32) -> Gpu {
        self.loop_limit = self.loop_limit.min(iterations);
        self
    }

    /// This GPU with storage bindings of at most `bytes` (never more than the adapter's): a
    /// view whose particle–cell pairs or cells need more is refused with
    /// [`GpuError::buffer_overflow`], which the backend renders in screen tiles. For tests on
    /// small scenes, and for drivers whose largest bindings are slow.
    pub fn with_binding_limit(mut self, bytes: u64) -> Gpu {
        self.max_binding = self.max_binding.min(bytes);
        self
    }

    /// The image's RGBA floats (16 bytes a pixel) must fit one storage binding.
    fn check_image(&self, width: u32, height: u32) -> Result<(), GpuError> {
        if 16 * u64::from(width) * u64::from(height) > self.max_binding {
            return Err(GpuError::ImageTooLarge(
                width,
                height,
                self.max_binding / 16,
            ));
        }
        Ok(())
    }

    /// True where a loop limit bounds the invocations (software drivers, `with_loop_limit`):
    /// work that may stop and resume keeps its state between dispatches.
    fn bounded(&self) -> bool {
        self.loop_limit != u32::MAX
    }

    /// A buffer for work that stops at the loop limit and resumes in the next dispatch:
    /// `bytes` where a limit can stop the work and they fit one binding and `most`, else 16
    /// (the shaders then see it too short to resume in, stop nothing, and the loop guard
    /// refuses what passes the limit).
    fn resume_buffer(&self, role: &'static str, bytes: u64, most: u64) -> wgpu::Buffer {
        let fits = self.bounded() && bytes <= most.min(self.max_binding);
        self.buffer(role, if fits { bytes } else { 16 }, RW, None)
    }

    /// Rows of bundles a band of work that stops and resumes covers: where a loop limit can
    /// stop the work, as many of `rows` as keep what it keeps (`per_row` bytes a row) within
    /// one binding and `most` (at least one: a row that does not fit gets no room, and what
    /// passes the limit is refused); else all of them.
    fn band_rows(&self, per_row: u64, most: u64, rows: u32) -> u32 {
        if !self.bounded() {
            return rows;
        }
        let fit = (self.max_binding.min(most) / per_row.max(1)).max(1);
        fit.min(u64::from(rows)) as u32
    }

    /// The loop budget of one invocation of a shader whose invocations loop independently
    /// (the RBF march: each pixel its own number of samples and queries). Mesa's gallivm runs
    /// invocations side by side in the lanes of a vector and counts a loop's iterations while
    /// any lane runs it, so a batch of lanes counts up to the sum of its lanes' iterations: each
    /// lane gets the limit over the lanes (8 for the "256 bits" in llvmpipe's adapter name,
    /// 16 where the name says nothing). With the whole limit per lane, lavapipe silently cut
    /// shadow rays of a 3000-particle cloud (tests/rbf.rs). Uniform loops (the bundle ray
    /// caster, whose invocations share their bounds) keep the whole limit.
    fn divergent_loop_limit(&self) -> u32 {
        if !self.bounded() {
            return u32::MAX;
        }
        self.loop_limit / simd_lanes(&self.adapter)
    }

    /// True when the adapter reports GPU-side timings (timestamp queries): stages named
    /// `gpu_*` in the stats.
    pub fn has_timestamps(&self) -> bool {
        self.timestamps.is_some()
    }

    /// The buffer kept for `role`, at least `size` bytes, holding `data` (when given). Reused
    /// across calls; replaced (grown by 1.5x) only when too small.
    fn buffer(
        &self,
        role: &'static str,
        size: u64,
        usage: wgpu::BufferUsages,
        data: Option<&[u8]>,
    ) -> wgpu::Buffer {
        let size = size.max(16).next_multiple_of(16);
        let mut cache = self
            .buffers
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        let fits = cache.get(role).is_some_and(|b| b.size() >= size);
        if !fits {
            let grown = (size + size / 2)
                .min(self.max_binding.max(size))
                .next_multiple_of(16);
            let b = self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(role),
                size: grown,
                usage,
                mapped_at_creation: false,
            });
            cache.insert(role, b);
        }
        let b = cache[role].clone();
        drop(cache);
        if let Some(d) = data {
            self.write(&b, d);
        }
        b
    }

    /// Writes `data` at the start of `b` (counted as uploaded).
    fn write(&self, b: &wgpu::Buffer, data: &[u8]) {
        if !data.is_empty() {
            self.queue.write_buffer(b, 0, data);
            self.count(|t| t.uploaded_bytes += data.len() as u64);
        }
    }

    /// Submits `enc`'s commands (counted).
    fn submit(&self, enc: wgpu::CommandEncoder) {
        self.queue.submit([enc.finish()]);
        self.count(|t| t.submits += 1);
    }

    fn count(&self, f: impl FnOnce(&mut Transfers)) {
        f(&mut self
            .traffic
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner));
    }

    /// The traffic counted since the last call, which starts a new count (a frame's start
    /// and end).
    fn take_traffic(&self) -> Transfers {
        std::mem::take(
            &mut self
                .traffic
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner),
        )
    }

    /// A storage buffer for `role` holding `data`.
    fn upload<T: Pod>(&self, role: &'static str, data: &[T]) -> wgpu::Buffer {
        let bytes: &[u8] = bytemuck::cast_slice(data);
        self.buffer(role, bytes.len() as u64, RW, Some(bytes))
    }

    /// Bytes of GPU buffers held between frames.
    pub fn memory_bytes(&self) -> u64 {
        let cache = self
            .buffers
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        cache.values().map(|b| b.size()).sum()
    }

    /// Copies the first `bytes` of each buffer back to the host, in one submission.
    fn fetch(&self, parts: &[(&wgpu::Buffer, u64)]) -> Result<Vec<Vec<u8>>, GpuError> {
        self.fetch_with(parts, |got| got.iter().map(|b| b.to_vec()).collect())
    }

    /// As [`Gpu::fetch`], handing `read` the mapped bytes themselves (no intermediate copy:
    /// a 1024x1024 frame reads back 20 MB).
    fn fetch_with<R>(
        &self,
        parts: &[(&wgpu::Buffer, u64)],
        read: impl FnOnce(&[&[u8]]) -> R,
    ) -> Result<R, GpuError> {
        let mut offsets = Vec::with_capacity(parts.len());
        let mut total = 0u64;
        for (_, bytes) in parts {
            offsets.push(total);
            total += bytes.next_multiple_of(256);
        }
        let staging = self.buffer(
            "readback",
            total,
            wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            None,
        );
        let mut enc = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        for ((b, bytes), off) in parts.iter().zip(&offsets) {
            if *bytes > 0 {
                enc.copy_buffer_to_buffer(b, 0, &staging, *off, bytes.next_multiple_of(4));
            }
        }
        self.submit(enc);
        let bytes: u64 = parts.iter().map(|p| p.1).sum();
        self.count(|t| (t.readback_bytes, t.waits) = (t.readback_bytes + bytes, t.waits + 1));
        let slice = staging.slice(..total.max(8));
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| GpuError::Device(e.to_string()))?;
        rx.recv()
            .map_err(|e| GpuError::Device(e.to_string()))?
            .map_err(|e| GpuError::Device(e.to_string()))?;
        let view = slice
            .get_mapped_range()
            .map_err(|e| GpuError::Device(e.to_string()))?;
        let slices: Vec<&[u8]> = parts
            .iter()
            .zip(&offsets)
            .map(|((_, bytes), off)| &view[*off as usize..(*off + *bytes) as usize])
            .collect();
        let out = read(&slices);
        drop(slices);
        drop(view);
        staging.unmap();
        Ok(out)
    }
}

/// Reinterprets fetched bytes.
fn cast<T: Pod>(bytes: &[u8]) -> Vec<T> {
    bytemuck::pod_collect_to_vec(bytes)
}

/// Stage timings of a frame, with the GPU's own where the adapter has timestamps.
fn push_stage(stats: &mut RenderStats, name: &'static str, ms: f64) {
    match stats.stages.iter_mut().find(|s| s.0 == name) {
        Some(s) => s.1 += ms,
        None => stats.stages.push((name, ms)),
    }
}

/// f32 lanes of a software driver's vectors, from its adapter name ("llvmpipe (LLVM 15.0.6,
/// 256 bits)": 8); 16 (512 bits) where the name gives none.
fn simd_lanes(adapter: &str) -> u32 {
    adapter
        .split(['(', ',', ')'])
        .find_map(|part| part.trim().strip_suffix(" bits")?.parse::<u32>().ok())
        .map_or(16, |bits| (bits / 32).clamp(1, 64))
}

#[cfg(test)]
mod lanes_tests {
    use super::simd_lanes;

    #[test]
    fn lanes_from_the_adapter_name() {
        assert_eq!(
            simd_lanes("llvmpipe (LLVM 15.0.6, 256 bits) (Vulkan, software)"),
            8
        );
        assert_eq!(simd_lanes("llvmpipe (LLVM 17.0.0, 512 bits)"), 16);
        assert_eq!(simd_lanes("llvmpipe (LLVM 15.0.6, 128 bits)"), 4);
        assert_eq!(simd_lanes("some software adapter"), 16);
    }
}
