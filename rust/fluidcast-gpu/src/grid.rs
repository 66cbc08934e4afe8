//! The sparse perspective grid on the GPU (grid.wgsl, Sec. 6.1 of Hochstetter et al. 2016),
//! mirroring `fluidcast_grid::PerspectiveGrid::build`: particles to view space (`view`; the
//! depth range and the sample depths are the CPU's, in f64, with no round trip), footprints and pair counts (`footprint`, then a scan), the (cell, particle)
//! pairs with their merge bits (`emit`), the radix sort, and the cells (`cell_starts`,
//! `make_cells`); `bundle_ranges` runs at the head of the plan's pass.

use std::time::Instant;

use bytemuck::Zeroable;
use fluidcast_grid::{sampled_range, support_depth_range, SampleDepths};
use fluidcast_render::{ms, RenderError, RenderParams};
use fluidcast_sph::Particles;
use fluidcast_view::ViewFrame;

use crate::frame::FrameCtx;
use crate::layout::{FrameUniform, GridCounters};
use crate::plan::Plan;
use crate::raycast::Casting;
use crate::{push_stage, Gpu, GpuError, RW};

/// Bytes per cell of the error analysis' bounds: (lo, hi) vec4 for 7 levels.
pub(crate) const BOUND_BYTES: u64 = 7 * 32;

/// The grid of one frame, as the plan and the ray caster read it.
pub(crate) struct Grid {
    /// Particles in view space: (c.xyz, H), (V, q, m, 0).
    pub(crate) vparts: wgpu::Buffer,
    /// The sample depths (f32).
    pub(crate) depths: wgpu::Buffer,
    /// Non-empty cells, by bundle and depth (`Cell` in common.wgsl).
    pub(crate) cells: wgpu::Buffer,
    /// Their number, where it was read back before the plan (see [`Gpu::grid`]).
    pub(crate) cells_n: Option<u32>,
    /// The most cells the plan's buffers hold: the count where it is known, else a capacity
    /// from the last frame's count, which the frame checks when it reads the count back.
    pub(crate) cell_capacity: u32,
    /// grid.wgsl's counters (`GridCounters`).
    pub(crate) counters: wgpu::Buffer,
    /// Particle indices grouped by cell.
    pub(crate) refs: wgpu::Buffer,
    pub(crate) pairs: u64,
    /// Bundle b's cells are `bundle_cells[b]..bundle_cells[b + 1]` (filled by `bundle_ranges`).
    pub(crate) bundle_cells: wgpu::Buffer,
}

impl Grid {
    /// The counters' bytes to read back with what a frame reads next, for [`Gpu::cells_read`]:
    /// none where the grid read the cell count already.
    pub(crate) fn count_part(&self) -> Option<(&wgpu::Buffer, u64)> {
        let size = std::mem::size_of::<GridCounters>() as u64;
        self.cells_n.is_none().then_some((&self.counters, size))
    }

    /// What the ray caster reads of this grid and `plan`, with the frame's uniform and
    /// loop guard.
    pub(crate) fn casting<'a>(
        &'a self,
        plan: &'a Plan,
        frame: &'a wgpu::Buffer,
        guard: &'a wgpu::Buffer,
    ) -> Casting<'a> {
        Casting {
            frame,
            tf: &plan.tf,
            vparts: &self.vparts,
            depths: &self.depths,
            cells: &self.cells,
            refs: &self.refs,
            bundle_cells: &self.bundle_cells,
            spans: &plan.spans,
            span_count: &plan.span_count,
            guard,
        }
    }
}

/// Each particle's footprint (bundle rectangle, cell range) and the prefix sum of their pair
/// counts: where `emit` writes each particle's pairs.
struct Footprints {
    foot: wgpu::Buffer,
    counts: wgpu::Buffer,
    pairs: u64,
}

/// The particles in world space as grid.wgsl's `world`: (x, y, z, H), (V, q, m, 0).
fn world(particles: &Particles) -> Vec<[f32; 4]> {
    (0..particles.len())
        .flat_map(|j| {
            let p = particles.positions[j];
            let (v, q, m) = (
                particles.volumes[j],
                particles.values[j],
                particles.masses[j],
            );
            [[p[0], p[1], p[2], particles.radii[j]], [v, q, m, 0.0]]
        })
        .collect()
}

/// A fingerprint of the particles `world` uploads (XXH3, 128 bits, over their count and
/// every array the shaders read): a frame whose particles have the one already on the
/// device does not upload them again.
pub(crate) fn particles_key(p: &Particles) -> u128 {
    let mut h = twox_hash::XxHash3_128::new();
    h.write(&(p.len() as u64).to_le_bytes());
    h.write(bytemuck::cast_slice(&p.positions));
    for a in [&p.radii, &p.volumes, &p.values, &p.masses] {
        h.write(bytemuck::cast_slice(a));
    }
    h.finish_128()
}

impl Gpu {
    /// Builds the grid; `None` when nothing is in view (the image stays empty). With
    /// `defer_count`, where an earlier frame's cell count gives a capacity
    /// ([`Gpu::cell_capacity`]), the cell count is not waited for: the device copies it into
    /// the frame's uniform (`n_cells`) and the caller reads it back later
    /// ([`Gpu::cells_counted`]).
    pub(crate) fn grid(
        &self,
        ctx: &mut FrameCtx,
        particles: &Particles,
        frame: &ViewFrame,
        (params, defer_count): (&RenderParams, bool),
    ) -> Result<Option<Grid>, GpuError> {
        let t = Instant::now();
        let n = particles.len() as u32;
        if n == 0 {
            return Ok(None);
        }
        let counters = self.upload("counters", &[GridCounters::zeroed()]);
        let vparts = self.view(ctx, particles)?;
        let Some(zs) = self.sample_depths(ctx, particles, frame, params)? else {
            push_stage(&mut ctx.stats, "grid", ms(t));
            return Ok(None);
        };
        let depths = self.upload("depths", &zs);
        let fp = self.footprints(ctx, &vparts, &counters, &depths, n)?;
        if fp.pairs == 0 {
            push_stage(&mut ctx.stats, "grid", ms(t));
            return Ok(None);
        }
        let pairs = fp.pairs;
        let (cells, refs) = self.cells(ctx, &counters, &fp, n)?;
        let capacity = self.cell_capacity(pairs).filter(|_| defer_count);
        let (cells_n, cell_capacity) = match capacity {
            Some(c) => (None, c),
            None => {
                let count = self.counters(&counters)?.cells;
                self.cells_counted(ctx, count)?;
                (Some(count), count)
            }
        };
        push_stage(&mut ctx.stats, "grid", ms(t));
        let bundle_cells = self.buffer("bundle cells", 4 * (ctx.bundles as u64 + 1), RW, None);
        Ok(Some(Grid {
            vparts,
            depths,
            cells,
            cells_n,
            cell_capacity,
            counters,
            refs,
            pairs,
            bundle_cells,
        }))
    }

    /// Stage 1: particles to view space.
    fn view(&self, ctx: &mut FrameCtx, particles: &Particles) -> Result<wgpu::Buffer, GpuError> {
        let n = particles.len() as u32;
        let t = Instant::now();
        let world = self.world_particles(particles);
        push_stage(&mut ctx.stats, "upload", ms(t));
        let vparts = self.buffer("view particles", 32 * n as u64, RW, None);
        let binds = [
            ("P", &ctx.frame_buf),
            ("world", &world),
            ("vparts", &vparts),
        ];
        self.submit_pass(&mut ctx.timer, "gpu_grid", |pass| {
            self.dispatch(pass, &self.pipes.view, &binds, n.div_ceil(256))
        })?;
        Ok(vparts)
    }

    /// The "world particles" buffer holding `particles`, uploaded only when the buffer
    /// holds others (by [`particles_key`]).
    fn world_particles(&self, particles: &Particles) -> wgpu::Buffer {
        let key = particles_key(particles);
        let bytes = 32 * particles.len() as u64;
        let mut held = self
            .world_key
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        if *held == Some(key) {
            // The buffer was made for these particles and no other role writes it.
            return self.buffer("world particles", bytes, RW, None);
        }
        *held = None;
        let b = self.upload("world particles", &world(particles));
        *held = Some(key);
        b
    }

    /// The sample depths, found and placed in f64 exactly as the CPU renderer finds and
    /// places them ([`support_depth_range`], [`SampleDepths`]), in f32; `None` when nothing
    /// lies in front of the camera.
    fn sample_depths(
        &self,
        ctx: &mut FrameCtx,
        particles: &Particles,
        frame: &ViewFrame,
        params: &RenderParams,
    ) -> Result<Option<Vec<f32>>, GpuError> {
        let own = || support_depth_range(particles, frame);
        let Some((near, far)) = sampled_range(frame, params.support_depths, own) else {
            return Ok(None);
        };
        let dz = params.grid.depth_samples;
        let depths = SampleDepths::new(frame, near, far, params.sampling_scale, dz as usize)
            .map_err(RenderError::from)?;
        let cells_z = (depths.len() / dz as usize) as u64;
        let nb = ctx.bundles as u64;
        if nb * cells_z * 2 > u32::MAX as u64 {
            return Err(GpuError::GridTooLarge(nb, cells_z));
        }
        self.check_loop_bounds(cells_z)?;
        ctx.stats.depth_samples = depths.len();
        ctx.stats.near = near;
        ctx.stats.far = far;
        ctx.u.near = near as f32;
        ctx.u.far = far as f32;
        ctx.u.n_depths = depths.len() as u32;
        ctx.u.cells_z = cells_z as u32;
        ctx.update(self);
        Ok(Some(depths.z.iter().map(|&z| z as f32).collect()))
    }

    /// Stage 2: each particle's bundle rectangle and cell range, its pair count and their prefix
    /// sum.
    fn footprints(
        &self,
        ctx: &mut FrameCtx,
        vparts: &wgpu::Buffer,
        counters: &wgpu::Buffer,
        depths: &wgpu::Buffer,
        n: u32,
    ) -> Result<Footprints, GpuError> {
        let foot = self.buffer("footprints", 32 * n as u64, RW, None);
        let counts = self.buffer("pair counts", 4 * n as u64, RW, None);
        let binds = [
            ("P", &ctx.frame_buf),
            ("vparts", vparts),
            ("counters", counters),
            ("depths", depths),
            ("foot", &foot),
            ("counts", &counts),
        ];
        self.submit_pass(&mut ctx.timer, "gpu_grid", |pass| {
            self.dispatch(pass, &self.pipes.footprint, &binds, n.div_ceil(256))?;
            self.scan(pass, &counts, n, 0)
        })?;
        let c = self.counters(counters)?;
        ctx.stats.particles_visible = c.visible as usize;
        let pairs = c.pairs();
        ctx.stats.pairs = pairs;
        let limit = (self.max_binding / 4).min(u32::MAX as u64 / 2);
        if pairs > limit {
            return Err(GpuError::TooManyPairs(pairs, limit));
        }
        ctx.u.n_pairs = pairs as u32;
        ctx.update(self);
        Ok(Footprints {
            foot,
            counts,
            pairs,
        })
    }

    /// Stage 3: the pairs, sorted by (bundle, depth, merge bit), and the cells, whose count the
    /// device copies into the frame's uniform; returns the cells and the particle references.
    fn cells(
        &self,
        ctx: &mut FrameCtx,
        counters: &wgpu::Buffer,
        fp: &Footprints,
        n: u32,
    ) -> Result<(wgpu::Buffer, wgpu::Buffer), GpuError> {
        let pairs = fp.pairs;
        let np = pairs as u32;
        let keys = self.buffer("keys", 4 * pairs, RW, None);
        let vals = self.buffer("values", 4 * pairs, RW, None);
        let starts = self.buffer("cell starts", 4 * pairs, RW, None);
        let cells = self.buffer("cells", (32 * pairs).min(self.max_binding), RW, None);
        let frame = &ctx.frame_buf;
        let mut enc = self.encoder();
        let mut pass = ctx.timer.pass(&mut enc, "gpu_grid");
        let binds = [
            ("P", frame),
            ("foot", &fp.foot),
            ("counts", &fp.counts),
            ("keys", &keys),
            ("vals", &vals),
            ("guard", &ctx.guard),
        ];
        self.dispatch(&mut pass, &self.pipes.emit, &binds, n.div_ceil(256))?;
        drop(pass);
        let mut pass = ctx.timer.pass(&mut enc, "gpu_sort");
        let bits = 64 - (ctx.bundles as u64 * ctx.u.cells_z as u64 * 2 - 1).leading_zeros();
        let (sorted_keys, refs) = self.sort(&mut pass, &keys, &vals, np, bits)?;
        drop(pass);
        let mut pass = ctx.timer.pass(&mut enc, "gpu_grid");
        let binds = [
            ("P", frame),
            ("counters", counters),
            ("starts", &starts),
            ("sorted_keys", &sorted_keys),
        ];
        self.dispatch(&mut pass, &self.pipes.cell_starts, &binds, np.div_ceil(256))?;
        self.scan(&mut pass, &starts, np, 0)?;
        let binds = [
            ("P", frame),
            ("starts", &starts),
            ("cells", &cells),
            ("sorted_keys", &sorted_keys),
        ];
        self.dispatch(&mut pass, &self.pipes.make_cells, &binds, np.div_ceil(256))?;
        drop(pass);
        let (from, to) = (
            std::mem::offset_of!(GridCounters, cells) as u64,
            std::mem::offset_of!(FrameUniform, n_cells) as u64,
        );
        enc.copy_buffer_to_buffer(counters, from, frame, to, 4);
        self.submit(enc);
        Ok((cells, refs))
    }

    /// The cells a frame's plan buffers hold without waiting for the count: half as many again
    /// as the last frame's and 1024 more (an orbit's views, a ParaView camera move, a series'
    /// next time step differ by less), at most `pairs`, within a binding of the plan's cell
    /// bounds; `None` before any frame, or past the binding.
    pub(crate) fn cell_capacity(&self, pairs: u64) -> Option<u32> {
        let last = *self
            .cells_hint
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        let capacity = (u64::from(last) * 3 / 2 + 1024).min(pairs);
        let fits = capacity * BOUND_BYTES <= self.max_binding && capacity * 32 <= self.max_binding;
        (last > 0 && fits).then_some(capacity as u32)
    }

    /// The frame's cell count, read back: into the statistics, the uniform's host copy and the
    /// next frame's capacity; refused where the cells overflow one binding.
    pub(crate) fn cells_counted(&self, ctx: &mut FrameCtx, count: u32) -> Result<(), GpuError> {
        *self
            .cells_hint
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner) = count;
        ctx.stats.cells = u64::from(count);
        // The cells themselves (32 bytes each); the plan's analysis checks its own buffers.
        if u64::from(count) * 32 > self.max_binding {
            return Err(GpuError::TooManyCells(
                u64::from(count),
                self.max_binding / 32,
            ));
        }
        ctx.u.n_cells = count;
        Ok(())
    }

    /// Each bundle's cell range (`bundle_ranges`), recorded into the plan's first pass.
    pub(crate) fn bundle_ranges(
        &self,
        pass: &mut wgpu::ComputePass,
        ctx: &FrameCtx,
        grid: &Grid,
    ) -> Result<(), GpuError> {
        let binds = [
            ("P", &ctx.frame_buf),
            ("cells", &grid.cells),
            ("bundle_cells", &grid.bundle_cells),
        ];
        // One invocation per bundle and one past the last.
        let bundles = ctx.u.bundles_x * ctx.u.bundles_y;
        self.dispatch(
            pass,
            &self.pipes.bundle_ranges,
            &binds,
            (bundles + 1).div_ceil(256),
        )
    }

    /// grid.wgsl's counters, read back.
    pub(crate) fn counters(&self, b: &wgpu::Buffer) -> Result<GridCounters, GpuError> {
        let size = std::mem::size_of::<GridCounters>() as u64;
        self.fetch_with(&[(b, size)], |got| bytemuck::pod_read_unaligned(got[0]))
    }
}
