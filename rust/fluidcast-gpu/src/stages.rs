//! One frame on the GPU: the stages in order, the buffers between them, the few numbers read
//! back on the way, and the image and statistics at the end.

use std::time::Instant;

use bytemuck::Zeroable;
use fluidcast_grid::{depth_range, Cell, SampleDepths};
use fluidcast_image::Image;
use fluidcast_plan::{BundleSummary, PlanError, PlanStats};
use fluidcast_render::{
    bundle_aovs, ms, plan_surface, validate, AdaptivePlan, RenderError, RenderParams, RenderStats,
    Rendered,
};
use fluidcast_sph::Particles;
use fluidcast_view::{Camera, TransferFunction};
use wgpu::util::DeviceExt;

use crate::layout::{frame_uniform, FrameUniform, GpuCell, GpuSpan, GridCounters, PlanCounters};
use crate::{cast, push_stage, Gpu, GpuError, QUERIES, RW};

/// Bytes per cell of the error analysis' bounds: (lo, hi) vec4 for 7 levels.
const BOUND_BYTES: u64 = 7 * 32;

/// The GPU's grid and plan of one frame, read back to compare with the CPU's
/// ([`fluidcast_grid::PerspectiveGrid`], [`fluidcast_plan::SamplingPlan`]).
#[derive(Debug, Clone, Default)]
pub struct GpuDump {
    /// Cells in GPU order (by bundle, then depth), with their bundle.
    pub cells: Vec<Cell>,
    pub cell_bundles: Vec<u32>,
    /// Particle indices grouped by cell.
    pub refs: Vec<u32>,
    /// Bundle b's cells are `bundle_cells[b]..bundle_cells[b + 1]`.
    pub bundle_cells: Vec<u32>,
    /// Chosen level per cell (`SamplingPlan::SUPERPIXEL` for super-pixels), as
    /// `SamplingPlan::cell_levels`.
    pub levels: Vec<u8>,
    /// Spans per bundle after merging.
    pub span_counts: Vec<u32>,
}

/// Timestamp queries around compute passes, summed by stage name.
struct Timer<'q> {
    queries: Option<&'q wgpu::QuerySet>,
    names: Vec<&'static str>,
}

impl<'q> Timer<'q> {
    fn pass<'e>(
        &mut self,
        enc: &'e mut wgpu::CommandEncoder,
        name: &'static str,
    ) -> wgpu::ComputePass<'e> {
        let writes = match self.queries {
            Some(q) if 2 * (self.names.len() as u32 + 1) <= QUERIES => {
                let i = 2 * self.names.len() as u32;
                self.names.push(name);
                Some(wgpu::ComputePassTimestampWrites {
                    query_set: q,
                    beginning_of_pass_write_index: Some(i),
                    end_of_pass_write_index: Some(i + 1),
                })
            }
            _ => None,
        };
        enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some(name),
            timestamp_writes: writes,
        })
    }
}

/// Roles of the partial-sum buffers of a scan, one per level of recursion (256^5 > 2^32).
const SUMS: [&str; 5] = [
    "scan sums 0",
    "scan sums 1",
    "scan sums 2",
    "scan sums 3",
    "scan sums 4",
];

impl Gpu {
    /// Renders like [`fluidcast_render::render_adaptive`], every stage on the GPU. Stage
    /// timings: wall-clock `grid`, `adapt`, `raycast`, `total`, and the GPU's own `gpu_grid`,
    /// `gpu_sort`, `gpu_adapt`, `gpu_raycast` where the adapter has timestamp queries.
    pub fn render_adaptive(
        &self,
        particles: &Particles,
        surface: Option<&[bool]>,
        camera: &Camera,
        tf: &TransferFunction,
        params: &RenderParams,
    ) -> Result<Rendered, GpuError> {
        Ok(self.run(particles, surface, camera, tf, params, false)?.0)
    }

    /// As [`Gpu::render_adaptive`], and reads back the GPU's grid and plan.
    pub fn render_with_dump(
        &self,
        particles: &Particles,
        surface: Option<&[bool]>,
        camera: &Camera,
        tf: &TransferFunction,
        params: &RenderParams,
    ) -> Result<(Rendered, GpuDump), GpuError> {
        let (r, d) = self.run(particles, surface, camera, tf, params, true)?;
        Ok((r, d.unwrap_or_default()))
    }

    /// Casts the rays of a grid and plan built on the CPU ([`fluidcast_render::plan_adaptive`]):
    /// the ray casting stage alone, to test it against the CPU's caster on the same input.
    pub fn render_planned(
        &self,
        planned: &AdaptivePlan,
        tf: &TransferFunction,
        params: &RenderParams,
    ) -> Result<Rendered, GpuError> {
        let _frame = self.frame_lock.lock().expect("frame lock");
        let t0 = Instant::now();
        check_supported(params, tf)?;
        let (grid, plan) = (&planned.grid, &planned.plan);
        let mut stats = planned.stats.clone();
        let mut image = Image::new(params.width, params.height);
        let Some(depths) = &grid.depths else {
            return Ok(Rendered { image, stats });
        };
        let mut timer = Timer {
            queries: self.timestamps.as_ref(),
            names: Vec::new(),
        };
        let mut u = frame_uniform(
            &grid.frame,
            params,
            tf,
            grid.particles.len(),
            self.loop_limit,
        );
        u.n_depths = depths.len() as u32;
        u.n_cells = grid.cells.len() as u32;
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
        let nb = grid.bundle_count();
        let mut cells = Vec::with_capacity(grid.cells.len());
        let mut bundle_cells = Vec::with_capacity(nb + 1);
        let mut spans = Vec::with_capacity(grid.cells.len());
        let mut span_count = Vec::with_capacity(nb);
        let dz = grid.params.depth_samples;
        for b in 0..nb {
            bundle_cells.push(cells.len() as u32);
            cells.extend(grid.bundle_cells(b).iter().map(|c| GpuCell {
                z: c.z,
                start: c.start,
                unique_end: c.unique_end,
                end: c.end,
                bundle: b as u32,
                pad: [0; 3],
            }));
            let bs = plan.bundle_spans(b);
            span_count.push(bs.len() as u32);
            spans.extend(bs.iter().map(|s| {
                let step = 1u32 << s.level;
                GpuSpan {
                    first: s.first,
                    count: s.count,
                    level: s.level as u32,
                    superpixel: s.superpixel.is_some() as u32,
                    k0: grid.cells[s.first as usize].z * dz,
                    n: s.count * dz / step,
                    step,
                    pad: 0,
                    sp: s.superpixel.unwrap_or([0.0; 4]),
                }
            }));
            // Bundle b's spans start at its first cell, as the GPU plan writes them.
            spans.resize(cells.len(), GpuSpan::zeroed());
        }
        bundle_cells.push(cells.len() as u32);
        let zs: Vec<f32> = depths.z.iter().map(|&z| z as f32).collect();
        let b = Buffers {
            frame: self.frame_buffer(&u),
            tf: self.tf_buffer(tf),
            vparts: self.upload("view particles", &parts),
            depths: self.upload("depths", &zs),
            cells: self.upload("cells", &cells),
            refs: self.upload("refs", &grid.refs),
            bundle_cells: self.upload("bundle cells", &bundle_cells),
            spans: self.upload("spans", &spans),
            span_count: self.upload("span counts", &span_count),
            guard: self.upload("loop guard", &[0u32; 4]),
        };
        let t1 = Instant::now();
        self.raycast(&b, params, &mut timer, &mut image, &mut stats)?;
        push_stage(&mut stats, "raycast", ms(t1));
        self.finish_timers(&timer, &mut stats)?;
        stats.gpu_memory_bytes = self.memory_bytes();
        image.aovs = fluidcast_render::plan_aovs(grid, plan, params.width, params.height);
        push_stage(&mut stats, "total", ms(t0));
        Ok(Rendered { image, stats })
    }

    fn run(
        &self,
        particles: &Particles,
        surface: Option<&[bool]>,
        camera: &Camera,
        tf: &TransferFunction,
        params: &RenderParams,
        dump: bool,
    ) -> Result<(Rendered, Option<GpuDump>), GpuError> {
        let _frame = self.frame_lock.lock().expect("frame lock");
        let t0 = Instant::now();
        validate(params)?;
        check_supported(params, tf)?;
        params
            .adaptive
            .validate()
            .map_err(|e| GpuError::Render(e.into()))?;
        if let Some(s) = surface {
            if s.len() != particles.len() {
                let e = PlanError::SurfaceFlags(s.len(), particles.len());
                return Err(GpuError::Render(e.into()));
            }
        }
        let (w, h) = (params.width, params.height);
        let frame = camera.frame(w, h).map_err(RenderError::from)?;
        let n = particles.len();
        if n as u64 * 32 > self.max_binding {
            return Err(GpuError::TooManyParticles(n, self.max_binding / 32));
        }
        let d = params.grid.bundle;
        let (bx, by) = (w.div_ceil(d), h.div_ceil(d));
        let nb = bx * by;
        let mut stats = RenderStats {
            particles: n,
            width: w,
            height: h,
            bundles: nb as u64,
            plan: Some(PlanStats::default()),
            ..Default::default()
        };
        let mut image = Image::new(w, h);
        let mut timer = Timer {
            queries: self.timestamps.as_ref(),
            names: Vec::new(),
        };
        let empty = |mut stats: RenderStats, image: Image| {
            stats.gpu_memory_bytes = self.memory_bytes();
            stats.stages.push(("total", ms(t0)));
            Ok((Rendered { image, stats }, dump.then(GpuDump::default)))
        };
        if n == 0 {
            return empty(stats, image);
        }
        let mut u = frame_uniform(&frame, params, tf, n, self.loop_limit);

        // 1. Particles to view space; their depth range.
        let world: Vec<[f32; 4]> = (0..n)
            .flat_map(|j| {
                let p = particles.positions[j];
                [
                    [p[0], p[1], p[2], particles.radii[j]],
                    [
                        particles.volumes[j],
                        particles.values[j],
                        particles.masses[j],
                        0.0,
                    ],
                ]
            })
            .collect();
        let b_frame = self.frame_buffer(&u);
        let b_world = self.upload("world particles", &world);
        let b_vparts = self.buffer("view particles", 32 * n as u64, RW, None);
        let b_counters = self.upload("counters", &[GridCounters::START]);
        let b_guard = self.upload("loop guard", &[0u32; 4]);
        let n32 = n as u32;
        self.submit_pass(&mut timer, "gpu_grid", |pass| {
            self.dispatch(
                pass,
                &self.pipes.view,
                &[
                    (0, &b_frame),
                    (3, &b_world),
                    (4, &b_vparts),
                    (5, &b_counters),
                ],
                n32.div_ceil(256),
            );
        });
        let (zmin, zmax) = self.counters(&b_counters)?.depth_range();
        let Some((near, far)) = depth_range(zmin, zmax, frame.parallel.is_none()) else {
            push_stage(&mut stats, "grid", ms(t0));
            return empty(stats, image);
        };
        let dz = params.grid.depth_samples;
        let depths = SampleDepths::new(&frame, near, far, params.sampling_scale, dz as usize)
            .map_err(RenderError::from)?;
        let cells_z = (depths.len() / dz as usize) as u64;
        if nb as u64 * cells_z * 2 > u32::MAX as u64 {
            return Err(GpuError::GridTooLarge(nb as u64, cells_z));
        }
        self.check_loop_bounds(nb as u64, cells_z)?;
        stats.depth_samples = depths.len();
        stats.near = near;
        stats.far = far;
        u.near = near as f32;
        u.far = far as f32;
        u.n_depths = depths.len() as u32;
        u.cells_z = cells_z as u32;

        // 2. Footprints and pair counts, their prefix sum.
        self.queue.write_buffer(&b_frame, 0, bytemuck::bytes_of(&u));
        let zs: Vec<f32> = depths.z.iter().map(|&z| z as f32).collect();
        let b_depths = self.upload("depths", &zs);
        let b_foot = self.buffer("footprints", 32 * n as u64, RW, None);
        let b_counts = self.buffer("pair counts", 4 * n as u64, RW, None);
        self.submit_pass(&mut timer, "gpu_grid", |pass| {
            self.dispatch(
                pass,
                &self.pipes.footprint,
                &[
                    (0, &b_frame),
                    (4, &b_vparts),
                    (5, &b_counters),
                    (6, &b_depths),
                    (7, &b_foot),
                    (8, &b_counts),
                ],
                n32.div_ceil(256),
            );
            self.scan(pass, &b_counts, n32, 0);
        });
        let c = self.counters(&b_counters)?;
        stats.particles_visible = c.visible as usize;
        let pairs = c.pairs();
        stats.pairs = pairs;
        if pairs == 0 {
            push_stage(&mut stats, "grid", ms(t0));
            return empty(stats, image);
        }
        let limit = (self.max_binding / 4).min(u32::MAX as u64 / 2);
        if pairs > limit {
            return Err(GpuError::TooManyPairs(pairs, limit));
        }
        let np = pairs as u32;
        u.n_pairs = np;

        // 3. The pairs, sorted by (bundle, depth, merge bit), and the cells.
        self.queue.write_buffer(&b_frame, 0, bytemuck::bytes_of(&u));
        let b_keys = self.buffer("keys", 4 * pairs, RW, None);
        let b_vals = self.buffer("values", 4 * pairs, RW, None);
        let b_starts = self.buffer("cell starts", 4 * pairs, RW, None);
        let b_cells = self.buffer("cells", (32 * pairs).min(self.max_binding), RW, None);
        let mut enc = self.encoder();
        let (_, refs) = {
            let mut pass = timer.pass(&mut enc, "gpu_grid");
            self.dispatch(
                &mut pass,
                &self.pipes.emit,
                &[
                    (0, &b_frame),
                    (7, &b_foot),
                    (8, &b_counts),
                    (9, &b_keys),
                    (10, &b_vals),
                    (15, &b_guard),
                ],
                n32.div_ceil(256),
            );
            drop(pass);
            let mut pass = timer.pass(&mut enc, "gpu_sort");
            let bits = 64 - (nb as u64 * cells_z * 2 - 1).leading_zeros();
            let sorted = self.sort(&mut pass, &b_keys, &b_vals, np, bits);
            drop(pass);
            let mut pass = timer.pass(&mut enc, "gpu_grid");
            self.dispatch(
                &mut pass,
                &self.pipes.cell_starts,
                &[
                    (0, &b_frame),
                    (5, &b_counters),
                    (11, &b_starts),
                    (14, &sorted.0),
                ],
                np.div_ceil(256),
            );
            self.scan(&mut pass, &b_starts, np, 0);
            self.dispatch(
                &mut pass,
                &self.pipes.make_cells,
                &[
                    (0, &b_frame),
                    (11, &b_starts),
                    (12, &b_cells),
                    (14, &sorted.0),
                ],
                np.div_ceil(256),
            );
            sorted
        };
        self.queue.submit([enc.finish()]);
        let ncells = self.counters(&b_counters)?.cells;
        stats.cells = ncells as u64;
        if ncells as u64 * BOUND_BYTES > self.max_binding {
            return Err(GpuError::TooManyCells(
                ncells as u64,
                self.max_binding / BOUND_BYTES,
            ));
        }
        push_stage(&mut stats, "grid", ms(t0));

        // 4. Bundle cell ranges, error analysis, greedy levels and merging.
        let t1 = Instant::now();
        u.n_cells = ncells;
        self.queue.write_buffer(&b_frame, 0, bytemuck::bytes_of(&u));
        let nc = ncells as u64;
        let b_bcells = self.buffer("bundle cells", 4 * (nb as u64 + 1), RW, None);
        let flags: Vec<u32> = match plan_surface(particles, surface, &params.adaptive) {
            Some(s) if params.adaptive.uses_surface_cells() => {
                s.iter().map(|&f| f as u32).collect()
            }
            _ => vec![0],
        };
        let b_surface = self.upload("surface flags", &flags);
        let b_bounds = self.buffer("cell bounds", BOUND_BYTES * nc, RW, None);
        let b_info = self.buffer("cell info", 4 * nc, RW, None);
        let b_front = self.buffer("front bounds", 32 * nc, RW, None);
        let b_levels = self.buffer("levels", 4 * nc, RW, None);
        let b_spans = self.buffer("spans", 48 * nc, RW, None);
        let b_span_count = self.buffer("span counts", 4 * nb as u64, RW, None);
        let b_summaries = self.buffer("bundle summaries", 32 * nb as u64, RW, None);
        let b_plan_stats = self.upload("plan stats", &[PlanCounters::zeroed()]);
        let tfb = self.tf_buffer(tf);
        let mut enc = self.encoder();
        {
            let mut pass = timer.pass(&mut enc, "gpu_grid");
            self.dispatch(
                &mut pass,
                &self.pipes.bundle_ranges,
                &[(0, &b_frame), (12, &b_cells), (13, &b_bcells)],
                ncells.div_ceil(256),
            );
            drop(pass);
            let mut pass = timer.pass(&mut enc, "gpu_adapt");
            if params.adaptive.tolerance.is_some() {
                self.dispatch(
                    &mut pass,
                    &self.pipes.analyse,
                    &[
                        (0, &b_frame),
                        (1, &tfb),
                        (3, &b_vparts),
                        (4, &b_depths),
                        (5, &b_cells),
                        (6, &refs),
                        (7, &b_surface),
                        (8, &b_bounds),
                        (9, &b_info),
                        (17, &b_guard),
                    ],
                    ncells,
                );
            }
            self.dispatch(
                &mut pass,
                &self.pipes.greedy,
                &[
                    (0, &b_frame),
                    (5, &b_cells),
                    (8, &b_bounds),
                    (9, &b_info),
                    (10, &b_bcells),
                    (11, &b_front),
                    (12, &b_levels),
                    (13, &b_spans),
                    (14, &b_span_count),
                    (15, &b_summaries),
                    (16, &b_plan_stats),
                ],
                nb.div_ceil(64),
            );
        }
        self.queue.submit([enc.finish()]);
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| GpuError::Device(e.to_string()))?;
        push_stage(&mut stats, "adapt", ms(t1));

        // 5. Ray casting.
        let t2 = Instant::now();
        let b = Buffers {
            frame: b_frame,
            tf: tfb,
            vparts: b_vparts,
            depths: b_depths,
            cells: b_cells,
            refs,
            bundle_cells: b_bcells,
            spans: b_spans,
            span_count: b_span_count,
            guard: b_guard,
        };
        self.raycast(&b, params, &mut timer, &mut image, &mut stats)?;
        push_stage(&mut stats, "raycast", ms(t2));
        let got = self.fetch(&[(&b_plan_stats, 64), (&b_summaries, 32 * nb as u64)])?;
        let ps: PlanCounters = bytemuck::pod_read_unaligned(&got[0]);
        stats.plan = Some(ps.stats(ncells as u64));
        if params.adaptive.tolerance.is_some() {
            let s: Vec<[f32; 8]> = cast(&got[1]);
            let summaries: Vec<BundleSummary> = s
                .iter()
                .map(|v| BundleSummary {
                    predicted_error: v[0],
                    mean_level: v[1],
                    full: v[2],
                    adapted: v[3],
                    superpixel: v[4],
                })
                .collect();
            image.aovs = bundle_aovs(&summaries, d, w, h);
        }
        let dumped = if dump {
            let got = self.fetch(&[
                (&b.cells, 32 * nc),
                (&b.refs, 4 * pairs),
                (&b.bundle_cells, 4 * (nb as u64 + 1)),
                (&b_levels, 4 * nc),
                (&b.span_count, 4 * nb as u64),
            ])?;
            let cells: Vec<GpuCell> = cast(&got[0]);
            Some(GpuDump {
                cells: cells
                    .iter()
                    .map(|c| Cell {
                        z: c.z,
                        start: c.start,
                        unique_end: c.unique_end,
                        end: c.end,
                    })
                    .collect(),
                cell_bundles: cells.iter().map(|c| c.bundle).collect(),
                refs: cast(&got[1]),
                bundle_cells: cast(&got[2]),
                levels: cast::<u32>(&got[3]).iter().map(|&l| l as u8).collect(),
                span_counts: cast(&got[4]),
            })
        } else {
            None
        };
        self.finish_timers(&timer, &mut stats)?;
        stats.gpu_memory_bytes = self.memory_bytes();
        push_stage(&mut stats, "total", ms(t0));
        Ok((Rendered { image, stats }, dumped))
    }

    /// grid.wgsl's counters, read back.
    fn counters(&self, b: &wgpu::Buffer) -> Result<GridCounters, GpuError> {
        let size = std::mem::size_of::<GridCounters>();
        self.fetch_with(&[(b, size as u64)], |got| {
            bytemuck::pod_read_unaligned(got[0])
        })
    }

    fn encoder(&self) -> wgpu::CommandEncoder {
        self.device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None })
    }

    /// Records one timed compute pass with `f` and submits it.
    fn submit_pass(
        &self,
        timer: &mut Timer,
        name: &'static str,
        f: impl FnOnce(&mut wgpu::ComputePass),
    ) {
        let mut enc = self.encoder();
        {
            let mut pass = timer.pass(&mut enc, name);
            f(&mut pass);
        }
        self.queue.submit([enc.finish()]);
    }

    fn frame_buffer(&self, u: &FrameUniform) -> wgpu::Buffer {
        self.buffer(
            "frame",
            std::mem::size_of::<FrameUniform>() as u64,
            wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            Some(bytemuck::bytes_of(u)),
        )
    }

    /// The transfer function's control points, as common.wgsl's `tf`: colour (x, r, g, b),
    /// then opacity (x, α, 0, 0).
    fn tf_buffer(&self, tf: &TransferFunction) -> wgpu::Buffer {
        let points: Vec<[f32; 4]> = tf
            .colors
            .iter()
            .map(|(x, c)| [*x as f32, c[0] as f32, c[1] as f32, c[2] as f32])
            .chain(
                tf.opacity
                    .iter()
                    .map(|(x, a)| [*x as f32, *a as f32, 0.0, 0.0]),
            )
            .collect();
        self.upload("transfer function", &points)
    }

    /// Runs `pipe` over `groups` workgroups (folded into two dimensions past 32768), with
    /// the given buffers at their bindings (exactly those the entry point uses).
    fn dispatch(
        &self,
        pass: &mut wgpu::ComputePass,
        pipe: &wgpu::ComputePipeline,
        binds: &[(u32, &wgpu::Buffer)],
        groups: u32,
    ) {
        if groups == 0 {
            return;
        }
        let x = groups.min(32768);
        self.dispatch_2d(pass, pipe, binds, (x, groups.div_ceil(x)));
    }

    fn dispatch_2d(
        &self,
        pass: &mut wgpu::ComputePass,
        pipe: &wgpu::ComputePipeline,
        binds: &[(u32, &wgpu::Buffer)],
        groups: (u32, u32),
    ) {
        let entries: Vec<wgpu::BindGroupEntry> = binds
            .iter()
            .map(|(k, b)| wgpu::BindGroupEntry {
                binding: *k,
                resource: b.as_entire_binding(),
            })
            .collect();
        let bind = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &pipe.get_bind_group_layout(0),
            entries: &entries,
        });
        pass.set_pipeline(pipe);
        pass.set_bind_group(0, &bind, &[]);
        pass.dispatch_workgroups(groups.0, groups.1, 1);
    }

    /// A small uniform buffer made for one dispatch (each dispatch of a pass sees its own).
    fn small_uniform(&self, v: [u32; 4]) -> wgpu::Buffer {
        self.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: None,
                contents: bytemuck::cast_slice(&v),
                usage: wgpu::BufferUsages::UNIFORM,
            })
    }

    /// Exclusive prefix sum of the first `n` (> 0) u32 of `data`, in place.
    fn scan(&self, pass: &mut wgpu::ComputePass, data: &wgpu::Buffer, n: u32, level: usize) {
        let blocks = n.div_ceil(256);
        let sums = self.buffer(SUMS[level], 4 * blocks as u64, RW, None);
        let u = self.small_uniform([n, 0, 0, 0]);
        let binds = [(0, &u), (1, data), (2, &sums)];
        self.dispatch(pass, &self.pipes.scan_blocks, &binds, blocks);
        if blocks > 1 {
            self.scan(pass, &sums, blocks, level + 1);
            self.dispatch(pass, &self.pipes.add_sums, &binds, blocks);
        }
    }

    /// Stable radix sort of `n` (key, value) pairs by the low `bits` of the key; returns the
    /// buffers holding the result (the inputs or their partners).
    fn sort(
        &self,
        pass: &mut wgpu::ComputePass,
        keys: &wgpu::Buffer,
        vals: &wgpu::Buffer,
        n: u32,
        bits: u32,
    ) -> (wgpu::Buffer, wgpu::Buffer) {
        let blocks = n.div_ceil(256);
        let hist = self.buffer("histogram", 64 * blocks as u64, RW, None);
        let mut a = (keys.clone(), vals.clone());
        let mut b = (
            self.buffer("keys (sort)", 4 * n as u64, RW, None),
            self.buffer("values (sort)", 4 * n as u64, RW, None),
        );
        for p in 0..bits.div_ceil(4) {
            let u = self.small_uniform([n, 4 * p, blocks, 0]);
            self.dispatch(
                pass,
                &self.pipes.histogram,
                &[(0, &u), (1, &a.0), (5, &hist)],
                blocks,
            );
            self.scan(pass, &hist, 16 * blocks, 0);
            self.dispatch(
                pass,
                &self.pipes.scatter,
                &[
                    (0, &u),
                    (1, &a.0),
                    (2, &a.1),
                    (3, &b.0),
                    (4, &b.1),
                    (5, &hist),
                ],
                blocks,
            );
            std::mem::swap(&mut a, &mut b);
        }
        a
    }

    /// The ray casting stage on `b`, the image and sample count read back into `image` and
    /// `stats`.
    fn raycast(
        &self,
        b: &Buffers,
        params: &RenderParams,
        timer: &mut Timer,
        image: &mut Image,
        stats: &mut RenderStats,
    ) -> Result<(), GpuError> {
        let (w, h) = (params.width, params.height);
        let n_px = w as u64 * h as u64;
        // f32::INFINITY is fine in WGSL storage (the shader only compares against it).
        let limits: &[f32] = params.depth_limit.as_deref().unwrap_or(&[]);
        let b_limit = self.upload("depth limit", limits);
        let b_rgba = self.buffer("rgba", 16 * n_px, RW, None);
        let b_depth = self.buffer("depth", 4 * n_px, RW, None);
        let d = params.grid.bundle;
        let bundles = (w.div_ceil(d) * h.div_ceil(d)) as u64;
        let b_samples = self.buffer("samples", 4 * bundles, RW, None);
        self.submit_pass(timer, "gpu_raycast", |pass| {
            self.dispatch_2d(
                pass,
                &self.pipes.raycast,
                &[
                    (0, &b.frame),
                    (1, &b.tf),
                    (3, &b.vparts),
                    (4, &b.depths),
                    (5, &b.spans),
                    (6, &b.span_count),
                    (7, &b.bundle_cells),
                    (8, &b.cells),
                    (9, &b.refs),
                    (10, &b_rgba),
                    (11, &b_depth),
                    (12, &b_samples),
                    (13, &b_limit),
                    (14, &b.guard),
                ],
                (w.div_ceil(d), h.div_ceil(d)),
            );
        });
        let parts = [
            (&b_rgba, 16 * n_px),
            (&b_depth, 4 * n_px),
            (&b_samples, 4 * bundles),
            (&b.guard, 4),
        ];
        let guarded = self.fetch_with(&parts, |got| {
            image.rgba = cast(got[0]);
            image.depth = cast::<f32>(got[1]);
            for z in image.depth.iter_mut().filter(|z| **z > 1e29) {
                *z = f32::INFINITY;
            }
            stats.samples = cast::<u32>(got[2]).iter().map(|&s| s as u64).sum();
            cast::<u32>(got[3])[0] != 0
        })?;
        if guarded {
            return Err(self.loop_limit_error("the grid, the error analysis or the ray casting"));
        }
        Ok(())
    }

    /// Reads the timestamp queries of the frame into `gpu_*` stages (milliseconds).
    fn finish_timers(&self, timer: &Timer, stats: &mut RenderStats) -> Result<(), GpuError> {
        let (Some(q), false) = (timer.queries, timer.names.is_empty()) else {
            return Ok(());
        };
        let count = 2 * timer.names.len() as u32;
        let resolve = self.buffer(
            "timestamps",
            8 * QUERIES as u64,
            wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
            None,
        );
        let mut enc = self.encoder();
        enc.resolve_query_set(q, 0..count, &resolve, 0);
        self.queue.submit([enc.finish()]);
        let t: Vec<u64> = cast(&self.fetch(&[(&resolve, 8 * count as u64)])?[0]);
        let period = self.queue.get_timestamp_period() as f64;
        for (k, name) in timer.names.iter().enumerate() {
            let ns = t[2 * k + 1].saturating_sub(t[2 * k]) as f64 * period;
            push_stage(stats, name, ns * 1e-6);
        }
        Ok(())
    }
}

/// The buffers the ray caster reads.
struct Buffers {
    frame: wgpu::Buffer,
    tf: wgpu::Buffer,
    vparts: wgpu::Buffer,
    depths: wgpu::Buffer,
    cells: wgpu::Buffer,
    refs: wgpu::Buffer,
    bundle_cells: wgpu::Buffer,
    spans: wgpu::Buffer,
    span_count: wgpu::Buffer,
    /// Set by any stage of the frame whose loops ran past `Gpu::loop_limit`.
    guard: wgpu::Buffer,
}

impl Gpu {
    /// The stages without a guard of their own loop a number of times that the host can bound:
    /// `bundle_ranges` at most twice the bundle count, `greedy` about 26 times the cells along
    /// a bundle (see plan.wgsl). On a software driver these must stay under its loop limit.
    fn check_loop_bounds(&self, bundles: u64, cells_z: u64) -> Result<(), GpuError> {
        let limit = self.loop_limit as u64;
        if 2 * bundles + 2 > limit {
            return Err(self.loop_limit_error("the bundle table"));
        }
        if cells_z * 26 + 20 > limit {
            return Err(self.loop_limit_error("the greedy plan"));
        }
        Ok(())
    }

    fn loop_limit_error(&self, stage: &'static str) -> GpuError {
        GpuError::LoopLimit {
            adapter: self.adapter.clone(),
            stage,
        }
    }
}

/// What the shaders take: bundles of at most 8x8 rays, transfer function tables of at most
/// MAX_TF_POINTS points.
fn check_supported(params: &RenderParams, tf: &TransferFunction) -> Result<(), GpuError> {
    if params.grid.bundle > 8 {
        return Err(GpuError::BundleTooLarge(params.grid.bundle));
    }
    let points = tf.colors.len().max(tf.opacity.len());
    if points > crate::MAX_TF_POINTS {
        return Err(GpuError::TransferFunction(points));
    }
    Ok(())
}
