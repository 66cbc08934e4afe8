//! The sampling plan on the GPU (plan.wgsl, Sec. 4–6.2), mirroring
//! `fluidcast_plan::SamplingPlan::build`: the error analysis per cell (`analyse`, skipped at
//! full rate) and the greedy choice of levels and super-pixels with cell merging per bundle
//! (`greedy`), which writes the spans the ray caster reads. With the probe, both run twice:
//! for the probe's bundles, then for the others, which the shaders analyse only where the
//! probe's work sums (atomics in `plan_stats`) say that it pays.

use bytemuck::Zeroable;
use fluidcast_plan::BundleSummary;
use fluidcast_render::{plan_surface, RenderParams, RenderStats};
use fluidcast_sph::Particles;
use fluidcast_view::TransferFunction;

use crate::frame::FrameCtx;
use crate::grid::{Grid, BOUND_BYTES};
use crate::layout::{GridCounters, PlanCounters};
use crate::{cast, Gpu, GpuError, RW};

/// The plan of one frame.
pub(crate) struct Plan {
    pub(crate) tf: wgpu::Buffer,
    /// Chosen level per cell (255: super-pixel).
    pub(crate) levels: wgpu::Buffer,
    /// Bundle b's spans start at its first cell (`Span` in common.wgsl).
    pub(crate) spans: wgpu::Buffer,
    pub(crate) span_count: wgpu::Buffer,
    /// Per bundle: predicted error, mean level, shares at full rate, adapted, super-pixel.
    pub(crate) summaries: wgpu::Buffer,
    /// `PlanCounters`.
    pub(crate) counters: wgpu::Buffer,
}

/// The error analysis' per-cell results, and the greedy's front composites.
struct Analysis {
    bounds: wgpu::Buffer,
    info: wgpu::Buffer,
    front: wgpu::Buffer,
}

impl Gpu {
    /// Stage 4: bundle cell ranges, the error analysis, greedy levels and merging.
    pub(crate) fn plan(
        &self,
        ctx: &mut FrameCtx,
        grid: &Grid,
        particles: &Particles,
        surface: Option<&[bool]>,
        tf: &TransferFunction,
        params: &RenderParams,
    ) -> Result<Plan, GpuError> {
        let (nc, nb) = (u64::from(grid.cell_capacity), ctx.bundles as u64);
        if nc * BOUND_BYTES > self.max_binding {
            return Err(GpuError::TooManyCells(nc, self.max_binding / BOUND_BYTES));
        }
        let flags: Vec<u32> = match plan_surface(particles, surface, &params.adaptive) {
            Some(s) if params.adaptive.uses_surface_cells() => {
                s.iter().map(|&f| f as u32).collect()
            }
            _ => vec![0],
        };
        let surface = self.upload("surface flags", &flags);
        let stops: Vec<f32> = match params.bundle_stops() {
            // f32 is exact here: the stops are minima of the f32 depth limits.
            Some(s) => s.iter().map(|&z| z as f32).collect(),
            None => vec![f32::INFINITY],
        };
        let stops = self.upload("bundle stops", &stops);
        let a = Analysis {
            bounds: self.buffer("cell bounds", BOUND_BYTES * nc, RW, None),
            info: self.buffer("cell info", 4 * nc, RW, None),
            front: self.buffer("front bounds", 32 * nc, RW, None),
        };
        let plan = Plan {
            tf: self.tf_buffer(tf),
            levels: self.buffer("levels", 4 * nc, RW, None),
            spans: self.buffer("spans", 48 * nc, RW, None),
            span_count: self.buffer("span counts", 4 * nb, RW, None),
            summaries: self.buffer("bundle summaries", 32 * nb, RW, None),
            counters: self.upload("plan stats", &[PlanCounters::zeroed()]),
        };
        let mut enc = self.encoder();
        let mut pass = ctx.timer.pass(&mut enc, "gpu_grid");
        self.bundle_ranges(&mut pass, ctx, grid)?;
        drop(pass);
        let mut pass = ctx.timer.pass(&mut enc, "gpu_adapt");
        // The probe's bundles first, then the others (`SamplingPlan::build`): phase 1 and 2
        // of plan.wgsl; phase 0 plans every bundle at once.
        let phases: &[u32] = match params.adaptive.tolerance {
            Some(_) if params.adaptive.probe => &[1, 2],
            _ => &[0],
        };
        for &p in phases {
            let phase = self.small_uniform([p, 0, 0, 0]);
            if params.adaptive.tolerance.is_some() {
                self.analyse(&mut pass, ctx, grid, &plan, [&surface, &stops, &phase], &a)?;
            }
            self.greedy(&mut pass, ctx, grid, &plan, &a, &phase)?;
        }
        drop(pass);
        self.submit(enc);
        Ok(plan)
    }

    fn analyse(
        &self,
        pass: &mut wgpu::ComputePass,
        ctx: &FrameCtx,
        grid: &Grid,
        plan: &Plan,
        [surface, stops, phase]: [&wgpu::Buffer; 3],
        a: &Analysis,
    ) -> Result<(), GpuError> {
        let binds = [
            ("phase", phase),
            ("plan_stats", &plan.counters),
            ("stops", stops),
            ("P", &ctx.frame_buf),
            ("tf", &plan.tf),
            ("vparts", &grid.vparts),
            ("depths", &grid.depths),
            ("cells", &grid.cells),
            ("refs", &grid.refs),
            ("surface", surface),
            ("bounds", &a.bounds),
            ("info", &a.info),
            ("guard", &ctx.guard),
        ];
        // One workgroup a cell the buffers hold; those past the count return at once.
        self.dispatch(pass, &self.pipes.analyse, &binds, grid.cell_capacity)
    }

    fn greedy(
        &self,
        pass: &mut wgpu::ComputePass,
        ctx: &FrameCtx,
        grid: &Grid,
        plan: &Plan,
        a: &Analysis,
        phase: &wgpu::Buffer,
    ) -> Result<(), GpuError> {
        let binds = [
            ("phase", phase),
            ("P", &ctx.frame_buf),
            ("cells", &grid.cells),
            ("bounds", &a.bounds),
            ("info", &a.info),
            ("bundle_cells", &grid.bundle_cells),
            ("front", &a.front),
            ("levels", &plan.levels),
            ("spans", &plan.spans),
            ("span_count", &plan.span_count),
            ("summaries", &plan.summaries),
            ("plan_stats", &plan.counters),
        ];
        self.dispatch(pass, &self.pipes.greedy, &binds, ctx.bundles.div_ceil(64))
    }

    /// The grid's cell count, the plan's statistics (into `ctx`) and its per-bundle summaries
    /// (none without a tolerance), in a round trip of their own; `None` where the cells
    /// overflowed the plan's capacity ([`Gpu::cells_read`]).
    pub(crate) fn plan_results(
        &self,
        ctx: &mut FrameCtx,
        grid: &Grid,
        plan: &Plan,
        params: &RenderParams,
    ) -> Result<Option<Vec<BundleSummary>>, GpuError> {
        let mut parts = plan.results(ctx.bundles).to_vec();
        parts.extend(grid.count_part());
        let got = self.fetch(&parts)?;
        let Some(cells) = self.cells_read(ctx, grid, got.get(2))? else {
            return Ok(None);
        };
        Ok(Some(plan_read(&mut ctx.stats, &got, cells, params)))
    }

    /// The cell count: the grid's, or where the grid did not wait for it, from grid.wgsl's
    /// counters read back (`bytes`, [`Grid::count_part`]): `None` where it passed the plan's
    /// capacity (the frame is to be made again, with the count known), else the count, as
    /// [`Gpu::cells_counted`] takes it.
    pub(crate) fn cells_read(
        &self,
        ctx: &mut FrameCtx,
        grid: &Grid,
        bytes: Option<&Vec<u8>>,
    ) -> Result<Option<u32>, GpuError> {
        if let Some(n) = grid.cells_n {
            return Ok(Some(n));
        }
        let bytes = bytes.ok_or_else(|| GpuError::Device("the cell count was not read".into()))?;
        let counters: GridCounters = bytemuck::pod_read_unaligned(bytes);
        self.cells_counted(ctx, counters.cells)?;
        Ok((counters.cells <= grid.cell_capacity).then_some(counters.cells))
    }
}

impl Plan {
    /// What [`plan_read`] reads back of the plan of a frame of `bundles` bundles: its
    /// counters and summaries, and their bytes.
    pub(crate) fn results(&self, bundles: u32) -> [(&wgpu::Buffer, u64); 2] {
        let size = std::mem::size_of::<PlanCounters>() as u64;
        [
            (&self.counters, size),
            (&self.summaries, 32 * u64::from(bundles)),
        ]
    }
}

/// The plan's statistics (into `stats`) and per-bundle summaries (none without a tolerance)
/// from the bytes of [`Plan::results`] read back, for `cells` cells.
pub(crate) fn plan_read(
    stats: &mut RenderStats,
    got: &[Vec<u8>],
    cells: u32,
    params: &RenderParams,
) -> Vec<BundleSummary> {
    let counters: PlanCounters = bytemuck::pod_read_unaligned(&got[0]);
    stats.plan = Some(counters.stats(cells as u64));
    if params.adaptive.tolerance.is_none() {
        return Vec::new();
    }
    let s: Vec<[f32; 8]> = cast(&got[1]);
    s.iter()
        .map(|v| BundleSummary {
            predicted_error: v[0],
            mean_level: v[1],
            full: v[2],
            adapted: v[3],
            superpixel: v[4],
            front_sampled: v[5],
        })
        .collect()
}
