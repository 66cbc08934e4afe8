//! Bundle-coherent ray casting on the GPU (raycast.wgsl, Alg. 2): one workgroup per ray
//! bundle casts a plan's spans, from the GPU's own grid and plan or from the CPU's
//! ([`Gpu::render_planned`], which tests this stage alone against the CPU caster).

use std::time::Instant;

use bytemuck::Zeroable;
use fluidcast_grid::PerspectiveGrid;
use fluidcast_image::Image;
use fluidcast_plan::SamplingPlan;
use fluidcast_render::{ms, AdaptivePlan, ImageOutput, RenderParams, RenderStats, Rendered};
use fluidcast_view::TransferFunction;

use crate::frame::check_supported;
use crate::layout::{GpuCell, GpuSpan};
use crate::pass::Timer;
use crate::{cast, push_stage, Gpu, GpuError, RW};

/// What the ray caster reads (raycast.wgsl's inputs, by their WGSL names).
pub(crate) struct Casting<'a> {
    pub(crate) frame: &'a wgpu::Buffer,
    pub(crate) tf: &'a wgpu::Buffer,
    pub(crate) vparts: &'a wgpu::Buffer,
    pub(crate) depths: &'a wgpu::Buffer,
    pub(crate) cells: &'a wgpu::Buffer,
    pub(crate) refs: &'a wgpu::Buffer,
    pub(crate) bundle_cells: &'a wgpu::Buffer,
    pub(crate) spans: &'a wgpu::Buffer,
    pub(crate) span_count: &'a wgpu::Buffer,
    pub(crate) guard: &'a wgpu::Buffer,
}

/// A CPU grid and plan in the GPU's layout: cells and spans by bundle (a bundle's spans start
/// at its first cell, as plan.wgsl writes them).
struct Uploaded {
    parts: Vec<[f32; 4]>,
    cells: Vec<GpuCell>,
    bundle_cells: Vec<u32>,
    spans: Vec<GpuSpan>,
    span_count: Vec<u32>,
}

fn gpu_layout(grid: &PerspectiveGrid, plan: &SamplingPlan) -> Uploaded {
    let nb = grid.bundle_count();
    let dz = grid.params.depth_samples;
    let mut up = Uploaded {
        parts: grid
            .particles
            .iter()
            .flat_map(|p| {
                let c = p.c.map(|v| v as f32);
                [
                    [c[0], c[1], c[2], p.h() as f32],
                    [p.v() as f32, p.a() as f32, p.m() as f32, 0.0],
                ]
            })
            .collect(),
        cells: Vec::with_capacity(grid.cells.len()),
        bundle_cells: Vec::with_capacity(nb + 1),
        spans: Vec::with_capacity(grid.cells.len()),
        span_count: Vec::with_capacity(nb),
    };
    for b in 0..nb {
        up.bundle_cells.push(up.cells.len() as u32);
        up.cells.extend(
            grid.bundle_cells(b)
                .iter()
                .map(|c| GpuCell::new(c, b as u32)),
        );
        let bs = plan.bundle_spans(b);
        up.span_count.push(bs.len() as u32);
        up.spans.extend(bs.iter().map(|s| {
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
        up.spans.resize(up.cells.len(), GpuSpan::zeroed());
    }
    up.bundle_cells.push(up.cells.len() as u32);
    up
}

/// What the ray caster wrote on the device: RGBA (f32) and depth of `n_px` pixels, the
/// samples of `bundles` bundles.
struct CastOut {
    rgba: wgpu::Buffer,
    depth: wgpu::Buffer,
    samples: wgpu::Buffer,
    n_px: u64,
    bundles: u64,
}

/// `resume[1 + b]` before bundle b's first dispatch (raycast.wgsl's RESUME_FRESH).
const RESUME_FRESH: u32 = u32::MAX;

/// Samples per span (raycast.wgsl's MAXS).
const MAXS: u64 = fluidcast_plan::MAX_SPAN_SAMPLES as u64;

/// The most bytes of span sums kept so that bundles can stop between chunks of a span
/// (raycast.wgsl's `chunk_sums`: 2 MAXS floats per ray, for one band of rows of bundles):
/// 8192 bundles, about 512 × 512 pixels. Larger images are cast in bands that fit.
const MAX_CHUNK_SUMS_BYTES: u64 = 256 << 20;

/// Bytes of `chunk_sums` per bundle.
const CHUNK_SUMS_PER_BUNDLE: u64 = 4 * 128 * MAXS;

impl Gpu {
    /// Casts the rays of a grid and plan built on the CPU ([`fluidcast_render::plan_adaptive`]):
    /// the ray casting stage alone, to test it against the CPU's caster on the same input.
    pub fn render_planned(
        &self,
        planned: &AdaptivePlan,
        tf: &TransferFunction,
        params: &RenderParams,
    ) -> Result<Rendered, GpuError> {
        let _frame = self
            .frame_lock
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        check_supported(params, tf)?;
        self.check_image(params.width, params.height)?;
        let (grid, plan) = (&planned.grid, &planned.plan);
        let mut ctx = self.frame_ctx(&grid.frame, params, tf, grid.particles.len());
        ctx.stats = planned.stats.clone();
        let mut image = Image::new(params.width, params.height);
        let Some(depths) = &grid.depths else {
            return Ok(Rendered {
                image,
                stats: ctx.stats,
            });
        };
        ctx.u.n_depths = depths.len() as u32;
        ctx.u.n_cells = grid.cells.len() as u32;
        ctx.update(self);
        let up = gpu_layout(grid, plan);
        let zs: Vec<f32> = depths.z.iter().map(|&z| z as f32).collect();
        let (tfb, vparts, depths) = (
            self.tf_buffer(tf),
            self.upload("view particles", &up.parts),
            self.upload("depths", &zs),
        );
        let (cells, refs) = (
            self.upload("cells", &up.cells),
            self.upload("refs", &grid.refs),
        );
        let bundle_cells = self.upload("bundle cells", &up.bundle_cells);
        let spans = self.upload("spans", &up.spans);
        let span_count = self.upload("span counts", &up.span_count);
        let t1 = Instant::now();
        let casting = Casting {
            frame: &ctx.frame_buf,
            tf: &tfb,
            vparts: &vparts,
            depths: &depths,
            cells: &cells,
            refs: &refs,
            bundle_cells: &bundle_cells,
            spans: &spans,
            span_count: &span_count,
            guard: &ctx.guard,
        };
        let (stats, timer) = (&mut ctx.stats, &mut ctx.timer);
        self.raycast(&casting, params, (timer, stats), &mut image, &[])?;
        push_stage(&mut ctx.stats, "raycast", ms(t1));
        image.aovs = fluidcast_render::plan_aovs(grid, plan, params.width, params.height);
        self.finish(ctx, image)
    }

    /// raycast.wgsl's `ray_state`, `chunk_sums` and `resume` for `bundles` bundles. A bundle's
    /// rays keep their compositing state between dispatches (two vec4 each) only where a loop
    /// limit can stop them and the state fits one binding (else the shader stops nothing, and
    /// the loop guard refuses what passes the limit); the span's sums too, to stop between
    /// chunks of a span, where they are small enough.
    fn bundle_resume_buffers(&self, bundles: u64, band_bundles: u64) -> [wgpu::Buffer; 3] {
        let sums = CHUNK_SUMS_PER_BUNDLE * band_bundles;
        [
            self.resume_buffer("ray state", 2 * 16 * 64 * bundles, u64::MAX),
            self.resume_buffer("chunk sums", sums, MAX_CHUNK_SUMS_BYTES),
            self.upload("resume", &fresh_resume(bundles as usize)),
        ]
    }

    /// Dispatches the ray caster over the whole image, each dispatch until none of its
    /// bundles stopped; where bundles cannot stop between the chunks of a span there (their
    /// sums do not fit one binding), a bundle whose next span is too long for one invocation
    /// defers it, and the deferred bundles are then cast band by band of `rows` rows of
    /// bundles, whose sums fit. Returns the dispatches.
    fn cast_bands(
        &self,
        timer: &mut Timer,
        binds: &[(&str, &wgpu::Buffer)],
        (groups, rows): ((u32, u32), u32),
        flags: (&wgpu::Buffer, &wgpu::Buffer),
    ) -> Result<u64, GpuError> {
        let banded = rows < groups.1;
        let mut dispatches = self.cast_band(timer, binds, groups, (0, groups.1, banded), flags)?;
        if !banded {
            return Ok(dispatches);
        }
        // guard[0]: refused (the caller reports it); guard[1]: bundles deferred.
        let guard = self.fetch_with(&[(flags.1, 8)], |got| cast::<u32>(got[0]))?;
        if guard[0] != 0 || guard[1] == 0 {
            return Ok(dispatches);
        }
        // Counted: the count starts again for the next pass of the frame.
        self.write(flags.1, bytemuck::bytes_of(&[0u32; 2]));
        for y0 in (0..groups.1).step_by(rows.max(1) as usize) {
            let band = (y0, rows.min(groups.1 - y0), false);
            dispatches += self.cast_band(timer, binds, groups, band, flags)?;
        }
        Ok(dispatches)
    }

    /// Dispatches the ray caster over `rows` rows of bundles from `y0` (raycast.wgsl's
    /// `band`), with `defer` set where long spans are left to banded dispatches, until none
    /// of its bundles stopped.
    fn cast_band(
        &self,
        timer: &mut Timer,
        binds: &[(&str, &wgpu::Buffer)],
        groups: (u32, u32),
        (y0, rows, defer): (u32, u32, bool),
        flags: (&wgpu::Buffer, &wgpu::Buffer),
    ) -> Result<u64, GpuError> {
        let pipe = (&self.pipes.raycast, "the ray casting", "gpu_raycast");
        let (s, g) = self.scattered_groups(rows * groups.0);
        let band = self.small_uniform([y0, rows, s, u32::from(defer)]);
        let mut banded = binds.to_vec();
        banded.push(("band", &band));
        self.dispatch_until_done(timer, pipe, &banded, g, flags, |_| {})
    }

    /// Stage 5: casts the rays of `b`; the image and the sample count are read back into `image`
    /// and `stats`, in one round trip with the timestamps of the passes so far (into `stats`)
    /// and with `also` (buffers and bytes), whose bytes are returned.
    pub(crate) fn raycast(
        &self,
        b: &Casting,
        params: &RenderParams,
        (timer, stats): (&mut Timer, &mut RenderStats),
        image: &mut Image,
        also: &[(&wgpu::Buffer, u64)],
    ) -> Result<Vec<Vec<u8>>, GpuError> {
        let (w, h, d) = (params.width, params.height, params.grid.bundle);
        let n_px = w as u64 * h as u64;
        let groups = (w.div_ceil(d), h.div_ceil(d));
        let bundles = groups.0 as u64 * groups.1 as u64;
        let limit = self.upload("depth limit", &depth_limits(params, n_px as usize));
        let rgba = self.buffer("rgba", 16 * n_px, RW, None);
        let depth = self.buffer("depth", 4 * n_px, RW, None);
        let samples = self.buffer("samples", 4 * bundles, RW, None);
        // The rows of bundles whose span sums fit (see `cast_bands`).
        let per_row = CHUNK_SUMS_PER_BUNDLE * u64::from(groups.0);
        let rows = self.band_rows(per_row, MAX_CHUNK_SUMS_BYTES, groups.1);
        let band_bundles = u64::from(rows) * u64::from(groups.0);
        let [state, sums, resume] = self.bundle_resume_buffers(bundles, band_bundles);
        let binds = [
            ("P", b.frame),
            ("tf", b.tf),
            ("particles", b.vparts),
            ("depths", b.depths),
            ("spans", b.spans),
            ("span_count", b.span_count),
            ("bundle_cells", b.bundle_cells),
            ("cells", b.cells),
            ("refs", b.refs),
            ("out_rgba", &rgba),
            ("out_depth", &depth),
            ("out_samples", &samples),
            ("depth_limit", &limit),
            ("guard", b.guard),
            ("ray_state", &state),
            ("resume", &resume),
            ("chunk_sums", &sums),
        ];
        let flags = (&resume, b.guard);
        stats.dispatches += self.cast_bands(timer, &binds, (groups, rows), flags)?;
        let cast_out = CastOut {
            rgba,
            depth,
            samples,
            n_px,
            bundles,
        };
        self.read_back(
            cast_out,
            (b.guard, params.output),
            (timer, stats),
            image,
            also,
        )
    }

    /// The ray caster's image, sample counts and loop guard (`guard`) read back into `image`
    /// and `stats`, as `out` asks, in one round trip with the timestamps of the passes so far
    /// and with `also`, whose bytes are returned.
    fn read_back(
        &self,
        cast_out: CastOut,
        (guard, out): (&wgpu::Buffer, ImageOutput),
        (timer, stats): (&mut Timer, &mut RenderStats),
        image: &mut Image,
        also: &[(&wgpu::Buffer, u64)],
    ) -> Result<Vec<Vec<u8>>, GpuError> {
        let CastOut {
            rgba,
            depth,
            samples,
            n_px,
            bundles,
        } = cast_out;
        let t = Instant::now();
        let colour = match out.half_colour {
            true => (self.pack_half(timer, &rgba, n_px)?, 8 * n_px),
            false => (rgba, 16 * n_px),
        };
        let depth_bytes = if out.depth { 4 * n_px } else { 0 };
        let stamps = self.resolve_timers(timer);
        let mut parts = vec![
            (&colour.0, colour.1),
            (&depth, depth_bytes),
            (&samples, 4 * bundles),
            (guard, 4),
        ];
        parts.extend(stamps.iter().map(|(buf, bytes)| (buf, *bytes)));
        parts.extend_from_slice(also);
        let (guarded, stamped, extra) = self.fetch_with(&parts, |got| {
            image.rgba = match out.half_colour {
                true => unpack_half(got[0]),
                false => cast(got[0]),
            };
            if out.depth {
                image.depth = cast::<f32>(got[1]);
                for z in image.depth.iter_mut().filter(|z| **z > 1e29) {
                    *z = f32::INFINITY;
                }
            }
            stats.samples = cast::<u32>(got[2]).iter().map(|&s| s as u64).sum();
            let (stamped, extra) = got[4..].split_at(usize::from(stamps.is_some()));
            let extra: Vec<Vec<u8>> = extra.iter().map(|b| b.to_vec()).collect();
            (
                cast::<u32>(got[3])[0] != 0,
                stamped.first().map(|b| b.to_vec()),
                extra,
            )
        })?;
        if let Some(bytes) = stamped {
            self.read_timers(timer, &bytes, stats);
        }
        // Waiting for the ray caster, then copying the image back (included in `raycast`).
        push_stage(stats, "readback", ms(t));
        if guarded {
            return Err(self.loop_limit_error("the grid, the error analysis or the ray casting"));
        }
        Ok(extra)
    }
}

impl Gpu {
    /// readback.wgsl's `pack_half` over the first `n_px` pixels of `rgba`: the buffer of
    /// their colours in half precision.
    fn pack_half(
        &self,
        timer: &mut Timer,
        rgba: &wgpu::Buffer,
        n_px: u64,
    ) -> Result<wgpu::Buffer, GpuError> {
        let half = self.buffer("half rgba", 8 * n_px, RW, None);
        let count = self.small_uniform([n_px as u32, 0, 0, 0]);
        let binds = [("K", &count), ("rgba", rgba), ("half_rgba", &half)];
        let groups = n_px.div_ceil(256) as u32;
        self.submit_pass(timer, "gpu_pack", |pass| {
            self.dispatch(pass, &self.pipes.pack_half, &binds, groups)
        })?;
        Ok(half)
    }
}

/// The colours `pack_half` packed (two u32 a pixel, each two binary16), as f32.
fn unpack_half(bytes: &[u8]) -> Vec<[f32; 4]> {
    let bits: Vec<u16> = bytemuck::pod_collect_to_vec(bytes);
    bits.chunks_exact(4)
        .map(|c| [0, 1, 2, 3].map(|k| half::f16::from_bits(c[k]).to_f32()))
        .collect()
}

/// raycast.wgsl's `depth_limit`: the far depths of all `n` pixels, then the near ones, when
/// either is given (empty otherwise). f32::INFINITY is fine in WGSL storage (the shader only
/// compares against it).
pub(crate) fn depth_limits(params: &RenderParams, n: usize) -> Vec<f32> {
    match (&params.depth_limit, &params.depth_near) {
        (None, None) => Vec::new(),
        (far, near) => {
            let far = far
                .as_deref()
                .map_or(vec![f32::INFINITY; n], <[f32]>::to_vec);
            let near = near.as_deref().map_or(vec![0.0; n], <[f32]>::to_vec);
            [far, near].concat()
        }
    }
}

/// raycast.wgsl's `resume` before the first dispatch: no bundle stopped, every bundle fresh,
/// every chunk 0.
fn fresh_resume(bundles: usize) -> Vec<u32> {
    let mut fresh = vec![RESUME_FRESH; bundles + 1];
    fresh[0] = 0;
    fresh.resize(2 * bundles + 1, 0);
    fresh
}
