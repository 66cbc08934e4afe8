//! One frame on the GPU: checks, then the stages in order (grid.rs, plan.rs, raycast.rs), the
//! few numbers read back on the way, and the image and statistics at the end.

use std::time::Instant;

use fluidcast_grid::Cell;
use fluidcast_image::Image;
use fluidcast_plan::{BundleSummary, PlanError, PlanStats};
use fluidcast_render::{
    interpolate, ms, validate, ImageOutput, RenderError, RenderParams, RenderStats, Rendered,
};
use fluidcast_sph::Particles;
use fluidcast_view::{Camera, TransferFunction, ViewFrame};

use crate::grid::Grid;
use crate::layout::{frame_uniform, FrameUniform, GpuCell};
use crate::pass::Timer;
use crate::plan::{plan_read, Plan};
use crate::{cast, push_stage, Gpu, GpuError};

/// The GPU's grid and plan of one frame, read back to compare with the CPU's
/// ([`fluidcast_grid::PerspectiveGrid`], [`fluidcast_plan::SamplingPlan`]).
#[derive(Debug, Clone, Default)]
pub struct GpuDump {
    /// Cells in GPU order (by bundle, then depth), with their bundle.
    pub cells: Vec<Cell>,
    /// The bundle of each cell of `cells`.
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

/// What every stage of a frame shares: the uniform (and its buffer), the loop guard, the
/// timestamps and the statistics being filled in.
pub(crate) struct FrameCtx<'g> {
    pub(crate) u: FrameUniform,
    pub(crate) frame_buf: wgpu::Buffer,
    pub(crate) guard: wgpu::Buffer,
    pub(crate) timer: Timer<'g>,
    pub(crate) stats: RenderStats,
    /// Ray bundles across and down the image.
    pub(crate) bundles: u32,
    pub(crate) t0: Instant,
}

impl FrameCtx<'_> {
    /// Writes the uniform again after a stage filled in more of it.
    pub(crate) fn update(&self, g: &Gpu) {
        g.write(&self.frame_buf, bytemuck::bytes_of(&self.u));
    }
}

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

    /// The frame's context, for `n` particles seen through `frame`.
    pub(crate) fn frame_ctx(
        &self,
        frame: &ViewFrame,
        params: &RenderParams,
        tf: &TransferFunction,
        n: usize,
    ) -> FrameCtx<'_> {
        // The frame's traffic counts from here.
        self.take_traffic();
        let u = frame_uniform(frame, params, tf, n, self.loop_limit);
        let d = params.grid.bundle;
        let bundles = params.width.div_ceil(d) * params.height.div_ceil(d);
        FrameCtx {
            frame_buf: self.frame_buffer(&u),
            u,
            guard: self.upload("loop guard", &[0u32; 4]),
            timer: Timer::new(self.timestamps.as_ref()),
            stats: RenderStats {
                particles: n,
                width: params.width,
                height: params.height,
                bundles: bundles as u64,
                plan: Some(PlanStats::default()),
                ..Default::default()
            },
            bundles,
            t0: Instant::now(),
        }
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
        let _frame = self
            .frame_lock
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        check_frame(particles, surface, tf, params)?;
        self.check_image(params.width, params.height)?;
        let frame = camera
            .frame(params.width, params.height)
            .map_err(RenderError::from)?;
        let n = particles.len();
        if n as u64 * 32 > self.max_binding {
            return Err(GpuError::TooManyParticles(n, self.max_binding / 32));
        }
        // Without waiting for the cell count where an earlier frame's gives a capacity; made
        // again with the count known where the cells passed it.
        let scene = (particles, surface, tf);
        if let Some(done) = self.frame_once(scene, &frame, params, (dump, true))? {
            return Ok(done);
        }
        let again = self.frame_once(scene, &frame, params, (dump, false))?;
        again.ok_or_else(|| GpuError::Device("the cell count changed between two runs".into()))
    }

    /// One run of a frame; `None` where, with `defer_count`, the cells passed the capacity
    /// the plan was given ([`Gpu::grid`]).
    fn frame_once(
        &self,
        (particles, surface, tf): (&Particles, Option<&[bool]>, &TransferFunction),
        frame: &ViewFrame,
        params: &RenderParams,
        (dump, defer_count): (bool, bool),
    ) -> Result<Option<(Rendered, Option<GpuDump>)>, GpuError> {
        let mut ctx = self.frame_ctx(frame, params, tf, particles.len());
        let mut image = Image::new(params.width, params.height);
        let Some(grid) = self.grid(&mut ctx, particles, frame, (params, defer_count))? else {
            return Ok(Some((
                self.finish(ctx, image)?,
                dump.then(GpuDump::default),
            )));
        };
        let t1 = Instant::now();
        let plan = self.plan(&mut ctx, &grid, particles, surface, tf, params)?;
        push_stage(&mut ctx.stats, "adapt", ms(t1));
        let refine = match params.adaptive.tolerance {
            Some(e) if interpolate::applies(particles, frame, params) => Some(e),
            _ => None,
        };
        let t2 = Instant::now();
        let summaries = match refine {
            Some(e) => self.refine(&mut ctx, (&grid, &plan), (frame, params, e), &mut image)?,
            None => {
                // One round trip after the plan and the ray caster: the image, with the cell
                // count, the plan's statistics and summaries and the timestamps.
                let casting = grid.casting(&plan, &ctx.frame_buf, &ctx.guard);
                let (timer, stats) = (&mut ctx.timer, &mut ctx.stats);
                let mut also = plan.results(ctx.bundles).to_vec();
                also.extend(grid.count_part());
                let got = self.raycast(&casting, params, (timer, stats), &mut image, &also)?;
                self.cells_read(&mut ctx, &grid, got.get(2))?
                    .map(|cells| plan_read(&mut ctx.stats, &got, cells, params))
            }
        };
        let Some(summaries) = summaries else {
            return Ok(None);
        };
        push_stage(&mut ctx.stats, "raycast", ms(t2));
        let (d, w, h) = (params.grid.bundle, params.width, params.height);
        image.aovs = fluidcast_render::bundle_aovs(&summaries, d, w, h);
        let cells = ctx.u.n_cells;
        let dumped = match dump {
            true => Some(self.dump(&grid, &plan, (ctx.bundles, cells))?),
            false => None,
        };
        Ok(Some((self.finish(ctx, image)?, dumped)))
    }

    /// The relaxed mode's image-space refinement ([`interpolate::cast_refined`]): the plan's
    /// summaries (which bundles to refine) read back first, then each pass cast on the GPU and
    /// read back at full precision, from which the host decides. Returns the summaries; `None`
    /// where the cells passed the plan's capacity (see [`Gpu::plan_results`]).
    fn refine(
        &self,
        ctx: &mut FrameCtx,
        (grid, plan): (&Grid, &Plan),
        (frame, params, e): (&ViewFrame, &RenderParams, f64),
        image: &mut Image,
    ) -> Result<Option<Vec<BundleSummary>>, GpuError> {
        let Some(summaries) = self.plan_results(ctx, grid, plan, params)? else {
            return Ok(None);
        };
        // The passes give each pixel a depth range in the depth-limit buffer, which the
        // shader reads with bit 0 set (the plan, which reads it too, has run).
        ctx.u.has_limit |= 1;
        ctx.update(self);
        let casting = grid.casting(plan, &ctx.frame_buf, &ctx.guard);
        let (timer, stats) = (&mut ctx.timer, &mut ctx.stats);
        let mut samples = 0;
        // A pass reads back a whole image: its pixels go into the refined one, which decides
        // on their full-precision colour and depth.
        let mut cast = |p: &RenderParams, into: &mut Image| {
            let mut pass = Image::new(p.width, p.height);
            let p = &RenderParams {
                output: ImageOutput::FULL,
                ..p.clone()
            };
            self.raycast(&casting, p, (&mut *timer, &mut *stats), &mut pass, &[])?;
            interpolate::keep_cast_pixels(p, &pass, into);
            samples += stats.samples;
            Ok::<_, GpuError>(())
        };
        let bundles = interpolate::refined_bundles(&summaries);
        let counts = interpolate::cast_refined(params, frame, e, &bundles, image, &mut cast)?;
        (stats.samples, stats.interpolated) = (samples, counts.interpolated);
        stats.stages.extend(counts.stages);
        Ok(Some(summaries))
    }

    /// Timestamps, memory and the total time into the statistics.
    pub(crate) fn finish(&self, mut ctx: FrameCtx, image: Image) -> Result<Rendered, GpuError> {
        self.finish_timers(&mut ctx.timer, &mut ctx.stats)?;
        ctx.stats.gpu_memory_bytes = self.memory_bytes();
        ctx.stats.transfers = self.take_traffic();
        push_stage(&mut ctx.stats, "total", ms(ctx.t0));
        Ok(Rendered {
            image,
            stats: ctx.stats,
        })
    }

    /// The grid and plan as the GPU built them.
    fn dump(
        &self,
        grid: &Grid,
        plan: &Plan,
        (bundles, cells): (u32, u32),
    ) -> Result<GpuDump, GpuError> {
        let (nc, nb) = (u64::from(cells), u64::from(bundles));
        let got = self.fetch(&[
            (&grid.cells, 32 * nc),
            (&grid.refs, 4 * grid.pairs),
            (&grid.bundle_cells, 4 * (nb + 1)),
            (&plan.levels, 4 * nc),
            (&plan.span_count, 4 * nb),
        ])?;
        let cells: Vec<GpuCell> = cast(&got[0]);
        Ok(GpuDump {
            cells: cells.iter().map(GpuCell::cell).collect(),
            cell_bundles: cells.iter().map(|c| c.bundle).collect(),
            refs: cast(&got[1]),
            bundle_cells: cast(&got[2]),
            levels: cast::<u32>(&got[3]).iter().map(|&l| l as u8).collect(),
            span_counts: cast(&got[4]),
        })
    }

    pub(crate) fn frame_buffer(&self, u: &FrameUniform) -> wgpu::Buffer {
        self.buffer(
            "frame",
            std::mem::size_of::<FrameUniform>() as u64,
            wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            Some(bytemuck::bytes_of(u)),
        )
    }

    /// The transfer function's control points, as common.wgsl's `tf`: colour (x, r, g, b),
    /// then opacity (x, α, 0, 0).
    pub(crate) fn tf_buffer(&self, tf: &TransferFunction) -> wgpu::Buffer {
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

    /// The stages without a guard of their own loop a number of times that the host can bound:
    /// `greedy` about 27 times the cells along a bundle (see plan.wgsl). On a software driver
    /// this must stay under its loop limit.
    pub(crate) fn check_loop_bounds(&self, cells_z: u64) -> Result<(), GpuError> {
        let limit = self.loop_limit as u64;
        if cells_z * 27 + 21 > limit {
            return Err(self.loop_limit_error("the greedy plan"));
        }
        Ok(())
    }

    pub(crate) fn loop_limit_error(&self, stage: &'static str) -> GpuError {
        GpuError::LoopLimit {
            adapter: self.adapter.clone(),
            stage,
        }
    }
}

/// The parameters and inputs the CPU renderer would refuse, and what only the GPU can't take.
fn check_frame(
    particles: &Particles,
    surface: Option<&[bool]>,
    tf: &TransferFunction,
    params: &RenderParams,
) -> Result<(), GpuError> {
    validate(params)?;
    fluidcast_render::refuse_surfaces(params, "the GPU backend")?;
    fluidcast_render::check_weights(particles, params.kernel)?;
    check_supported(params, tf)?;
    params
        .adaptive
        .validate()
        .map_err(|e| GpuError::Render(e.into()))?;
    match surface {
        Some(s) if s.len() != particles.len() => {
            let e = PlanError::SurfaceFlags(s.len(), particles.len());
            Err(GpuError::Render(e.into()))
        }
        _ => Ok(()),
    }
}

/// What the shaders take: bundles of at most 8x8 rays, transfer function tables of at most
/// MAX_TF_POINTS points.
pub(crate) fn check_supported(
    params: &RenderParams,
    tf: &TransferFunction,
) -> Result<(), GpuError> {
    if params.grid.bundle > 8 {
        return Err(GpuError::BundleTooLarge(params.grid.bundle));
    }
    let points = tf.colors.len().max(tf.opacity.len());
    if points > crate::MAX_TF_POINTS {
        return Err(GpuError::TransferFunction(points));
    }
    Ok(())
}
