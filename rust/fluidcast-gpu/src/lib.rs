//! The adaptive renderer's ray casting stage on the GPU (wgpu compute, WGSL).
//!
//! Status: only the last stage runs on the GPU. The sparse perspective grid and the sampling
//! plan are built on the CPU ([`fluidcast_render::plan_adaptive`]); this crate uploads the
//! view-space particles, the sample depths, each bundle's spans with their merged particle
//! lists and the transfer function, and casts one workgroup per ray bundle, one invocation
//! per ray, the span's particles cached in workgroup memory (Hochstetter et al. 2016,
//! Alg. 2). It mirrors `fluidcast-render`'s CPU caster in single precision, so the two can be
//! compared image to image.
//!
//! Runs headless on any wgpu adapter, Mesa's lavapipe (CPU Vulkan) included; [`Gpu::new`]
//! says why when there is none.

use std::time::Instant;

use bytemuck::{Pod, Zeroable};
use fluidcast_image::Image;
use fluidcast_render::{ms, plan_adaptive, plan_aovs, AdaptiveRender, RenderError, RenderParams};
use fluidcast_sph::{FieldKind, Kernel, Particles};
use fluidcast_view::{Camera, TransferFunction};

/// Why the GPU path could not run.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    #[error("no GPU adapter found (wgpu: {0}); on a machine without a GPU install Mesa's lavapipe (Debian: mesa-vulkan-drivers)")]
    NoAdapter(String),
    #[error("GPU device: {0}")]
    Device(String),
    #[error("the GPU ray caster supports ray bundles of at most 8x8 pixels (--bundle {0})")]
    BundleTooLarge(u32),
    #[error(transparent)]
    Render(#[from] RenderError),
}

/// A wgpu device with the ray casting pipeline compiled.
pub struct Gpu {
    device: wgpu::Device,
    queue: wgpu::Queue,
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    /// Adapter name and backend, for messages ("llvmpipe (Vulkan)").
    pub adapter: String,
    /// GPU-side durations from timestamp queries, where the adapter supports them.
    timestamps: Option<wgpu::QuerySet>,
    /// Buffers kept between frames, by role; replaced only when too small.
    buffers: std::sync::Mutex<std::collections::HashMap<&'static str, wgpu::Buffer>>,
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Params {
    width: u32,
    height: u32,
    bundles_x: u32,
    bundle: u32,
    aspect: f32,
    tan_half: f32,
    parallel_scale: f32,
    min_transmittance: f32,
    field: u32,
    kernel: u32,
    gauss_norm: f32,
    n_colors: u32,
    n_opacity: u32,
    tf_lo: f32,
    tf_hi: f32,
    unit_distance: f32,
    has_limit: u32,
    pad: [u32; 3],
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct GpuSpan {
    k0: u32,
    n: u32,
    step: u32,
    ref_start: u32,
    ref_count: u32,
    superpixel: u32,
    pad: [u32; 2],
    sp: [f32; 4],
}

impl Gpu {
    /// Opens the default adapter (high performance preferred) and compiles the shader.
    pub fn new() -> Result<Gpu, GpuError> {
        let instance = wgpu::Instance::default();
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            ..Default::default()
        }))
        .map_err(|e| GpuError::NoAdapter(e.to_string()))?;
        let info = adapter.get_info();
        let timestamps = adapter.features().contains(wgpu::Features::TIMESTAMP_QUERY);
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("fluidcast"),
            required_limits: adapter.limits(),
            required_features: if timestamps {
                wgpu::Features::TIMESTAMP_QUERY
            } else {
                wgpu::Features::empty()
            },
            ..Default::default()
        }))
        .map_err(|e| GpuError::Device(e.to_string()))?;
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("raycast"),
            source: wgpu::ShaderSource::Wgsl(include_str!("raycast.wgsl").into()),
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("raycast"),
            layout: None,
            module: &module,
            entry_point: Some("main"),
            compilation_options: Default::default(),
            cache: None,
        });
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(GpuError::Device(format!(
                "compiling the ray casting shader: {e}"
            )));
        }
        let layout = pipeline.get_bind_group_layout(0);
        let timestamps = timestamps.then(|| {
            device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("raycast timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count: 2,
            })
        });
        Ok(Gpu {
            device,
            queue,
            pipeline,
            layout,
            adapter: format!("{} ({:?})", info.name, info.backend),
            timestamps,
            buffers: Default::default(),
        })
    }

    /// True when the adapter reports GPU-side timings (timestamp queries): stage
    /// `gpu_raycast` in the stats.
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
        let mut cache = self.buffers.lock().expect("buffer cache");
        let fits = cache.get(role).is_some_and(|b| b.size() >= size);
        if !fits {
            let b = self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(role),
                size: size + size / 2,
                usage,
                mapped_at_creation: false,
            });
            cache.insert(role, b);
        }
        let b = cache[role].clone();
        if let Some(d) = data {
            if !d.is_empty() {
                self.queue.write_buffer(&b, 0, d);
            }
        }
        b
    }

    /// Bytes of GPU buffers held between frames.
    pub fn memory_bytes(&self) -> u64 {
        let cache = self.buffers.lock().expect("buffer cache");
        cache.values().map(|b| b.size()).sum()
    }

    /// Renders like [`fluidcast_render::render_adaptive`]: grid and plan on the CPU, ray
    /// casting here. Stage timings: `grid`, `adapt`, `upload`, `raycast` (dispatch to
    /// read-back), `total`.
    pub fn render_adaptive(
        &self,
        particles: &Particles,
        surface: Option<&[bool]>,
        camera: &Camera,
        tf: &TransferFunction,
        params: &RenderParams,
    ) -> Result<AdaptiveRender, GpuError> {
        if params.grid.bundle > 8 {
            return Err(GpuError::BundleTooLarge(params.grid.bundle));
        }
        let t0 = Instant::now();
        let planned = plan_adaptive(particles, surface, camera, tf, params)?;
        let (grid, plan, mut stats) = (planned.grid, planned.plan, planned.stats);
        let (w, h) = (params.width, params.height);
        let mut image = Image::new(w, h);
        let Some(depths) = &grid.depths else {
            stats.stages.push(("total", ms(t0)));
            return Ok(AdaptiveRender {
                image,
                stats,
                grid,
                plan,
            });
        };

        // Upload: view-space particles, depths, spans with their merged particle lists.
        let t1 = Instant::now();
        let parts: Vec<[f32; 4]> = grid
            .particles
            .iter()
            .flat_map(|p| {
                [
                    [p.c[0] as f32, p.c[1] as f32, p.c[2] as f32, p.h as f32],
                    [p.v as f32, p.a as f32, p.m as f32, 0.0],
                ]
            })
            .collect();
        let zs: Vec<f32> = depths.z.iter().map(|&z| z as f32).collect();
        let dz = grid.params.depth_samples;
        let mut spans = Vec::new();
        let mut refs: Vec<u32> = Vec::new();
        let mut bundle_spans = Vec::with_capacity(grid.bundle_count() + 1);
        for b in 0..grid.bundle_count() {
            bundle_spans.push(spans.len() as u32);
            for span in plan.bundle_spans(b) {
                let first = span.first as usize;
                let cells = &grid.cells[first..first + span.count as usize];
                let step = 1u32 << span.level;
                let ref_start = refs.len() as u32;
                if span.superpixel.is_none() {
                    refs.extend(grid.merged_refs(cells));
                }
                spans.push(GpuSpan {
                    k0: grid.cells[first].z * dz,
                    n: span.count * dz / step,
                    step,
                    ref_start,
                    ref_count: refs.len() as u32 - ref_start,
                    superpixel: span.superpixel.is_some() as u32,
                    pad: [0; 2],
                    sp: span.superpixel.unwrap_or([0.0; 4]),
                });
            }
        }
        bundle_spans.push(spans.len() as u32);
        let colors: Vec<[f32; 4]> = tf
            .colors
            .iter()
            .map(|(x, c)| [*x as f32, c[0] as f32, c[1] as f32, c[2] as f32])
            .collect();
        let opacity: Vec<[f32; 2]> = tf
            .opacity
            .iter()
            .map(|(x, a)| [*x as f32, *a as f32])
            .collect();
        let frame = grid.frame;
        let uniforms = Params {
            width: w,
            height: h,
            bundles_x: grid.bundles_x,
            bundle: grid.params.bundle,
            aspect: frame.aspect as f32,
            tan_half: frame.tan_half as f32,
            parallel_scale: frame.parallel.unwrap_or(0.0) as f32,
            min_transmittance: params.min_transmittance as f32,
            field: match params.field {
                FieldKind::Csph => 0,
                FieldKind::Sph => 1,
                FieldKind::Density => 2,
            },
            kernel: match params.kernel {
                Kernel::CubicSpline => 0,
                Kernel::Quintic => 1,
                Kernel::WendlandC2 => 2,
                Kernel::WendlandC4 => 3,
                Kernel::Poly6 => 4,
                Kernel::Gaussian => 5,
            },
            gauss_norm: gaussian_norm() as f32,
            n_colors: colors.len() as u32,
            n_opacity: opacity.len() as u32,
            tf_lo: tf.range.0 as f32,
            tf_hi: tf.range.1 as f32,
            unit_distance: tf.unit_distance as f32,
            has_limit: params.depth_limit.is_some() as u32,
            pad: [0; 3],
        };
        let n_px = w as u64 * h as u64;
        let input = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST;
        let storage = |role: &'static str, bytes: &[u8]| {
            self.buffer(role, bytes.len() as u64, input, Some(bytes))
        };
        let uniform = self.buffer(
            "params",
            std::mem::size_of::<Params>() as u64,
            wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            Some(bytemuck::bytes_of(&uniforms)),
        );
        let b_parts = storage("particles", bytemuck::cast_slice(&parts));
        let b_depths = storage("depths", bytemuck::cast_slice(&zs));
        let b_spans = storage("spans", bytemuck::cast_slice(&spans));
        let b_bspans = storage("bundle spans", bytemuck::cast_slice(&bundle_spans));
        let b_refs = storage("refs", bytemuck::cast_slice(&refs));
        let b_colors = storage("colors", bytemuck::cast_slice(&colors));
        let b_opacity = storage("opacity", bytemuck::cast_slice(&opacity));
        // f32::INFINITY is fine in WGSL storage (the shader only compares against it).
        let limits: &[f32] = params.depth_limit.as_deref().unwrap_or(&[]);
        let b_limit = storage("depth limit", bytemuck::cast_slice(limits));
        let out = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC;
        let read = wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST;
        let b_rgba = self.buffer("rgba", 16 * n_px, out, None);
        let b_depth = self.buffer("depth", 4 * n_px, out, None);
        let b_samples = self.buffer("samples", 4 * n_px, out, None);
        let r_rgba = self.buffer("rgba readback", 16 * n_px, read, None);
        let r_depth = self.buffer("depth readback", 4 * n_px, read, None);
        let r_samples = self.buffer("samples readback", 4 * n_px, read, None);
        let entries: Vec<wgpu::BindGroupEntry> = [
            &uniform, &b_parts, &b_depths, &b_spans, &b_bspans, &b_refs, &b_colors, &b_opacity,
            &b_rgba, &b_depth, &b_samples, &b_limit,
        ]
        .iter()
        .enumerate()
        .map(|(k, b)| wgpu::BindGroupEntry {
            binding: k as u32,
            resource: b.as_entire_binding(),
        })
        .collect();
        let bind = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("raycast"),
            layout: &self.layout,
            entries: &entries,
        });
        stats.stages.push(("upload", ms(t1)));

        let t2 = Instant::now();
        let mut enc = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("raycast"),
                timestamp_writes: self.timestamps.as_ref().map(|q| {
                    wgpu::ComputePassTimestampWrites {
                        query_set: q,
                        beginning_of_pass_write_index: Some(0),
                        end_of_pass_write_index: Some(1),
                    }
                }),
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups(grid.bundles_x, grid.bundles_y, 1);
        }
        let ts = self.timestamps.as_ref().map(|q| {
            let resolve = self.buffer(
                "timestamps",
                16,
                wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                None,
            );
            let r = self.buffer("timestamps readback", 16, read, None);
            enc.resolve_query_set(q, 0..2, &resolve, 0);
            enc.copy_buffer_to_buffer(&resolve, 0, &r, 0, 16);
            r
        });
        enc.copy_buffer_to_buffer(&b_rgba, 0, &r_rgba, 0, 16 * n_px);
        enc.copy_buffer_to_buffer(&b_depth, 0, &r_depth, 0, 4 * n_px);
        enc.copy_buffer_to_buffer(&b_samples, 0, &r_samples, 0, 4 * n_px);
        self.queue.submit([enc.finish()]);
        let rgba: Vec<[f32; 4]> = read_back(&self.device, &r_rgba, 16 * n_px)?;
        let depth: Vec<f32> = read_back(&self.device, &r_depth, 4 * n_px)?;
        let samples: Vec<u32> = read_back(&self.device, &r_samples, 4 * n_px)?;
        stats.stages.push(("raycast", ms(t2)));
        if let Some(r) = ts {
            let t: Vec<u64> = read_back(&self.device, &r, 16)?;
            let period = self.queue.get_timestamp_period() as f64;
            let ns = t[1].saturating_sub(t[0]) as f64 * period;
            stats.stages.push(("gpu_raycast", ns * 1e-6));
        }
        stats.gpu_memory_bytes = self.memory_bytes();

        // Bundles with no cells were not written by the shader: transparent, depth +inf.
        for b in 0..grid.bundle_count() {
            if grid.bundle_cells(b).is_empty() {
                continue;
            }
            let [x0, x1, y0, y1] = grid.bundle(b).pixels;
            for j in y0..y1 {
                for i in x0..x1 {
                    let k = image.index(i, j);
                    image.rgba[k] = rgba[k];
                    stats.samples += samples[k] as u64;
                    image.depth[k] = if depth[k] > 1e29 {
                        f32::INFINITY
                    } else {
                        depth[k]
                    };
                }
            }
        }
        image.aovs = plan_aovs(&grid, &plan, w, h);
        stats.stages.push(("total", ms(t0)));
        Ok(AdaptiveRender {
            image,
            stats,
            grid,
            plan,
        })
    }
}

/// The first `bytes` of a mappable buffer (buffers are reused, so they may be larger).
fn read_back<T: Pod>(
    device: &wgpu::Device,
    buf: &wgpu::Buffer,
    bytes: u64,
) -> Result<Vec<T>, GpuError> {
    let slice = buf.slice(..bytes);
    let (tx, rx) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| GpuError::Device(e.to_string()))?;
    rx.recv()
        .map_err(|e| GpuError::Device(e.to_string()))?
        .map_err(|e| GpuError::Device(e.to_string()))?;
    let view = slice
        .get_mapped_range()
        .map_err(|e| GpuError::Device(e.to_string()))?;
    let out = bytemuck::cast_slice(&view).to_vec();
    drop(view);
    buf.unmap();
    Ok(out)
}

/// The Gaussian kernel's normalisation constant c (`fluidcast_sph::Kernel::eval`): W(0, H) =
/// 1 / (c σ³) with σ = H/3.
fn gaussian_norm() -> f64 {
    let h = 3.0; // σ = 1
    1.0 / Kernel::Gaussian.eval(0.0, h)
}
