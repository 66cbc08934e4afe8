//! Iso-surfaces on the GPU (surface.wgsl), the mirror of the reference caster's surfaces
//! ([`fluidcast_render::render_reference`] with [`fluidcast_render::Surfaces`] and no volume):
//! the GPU's own perspective grid (grid.rs) gives each ray bundle the particles that reach
//! each depth slab, and each ray walks its samples, refines the crossings on the exact sum
//! and shades them with the analytic gradient, in single precision.

use std::time::Instant;

use fluidcast_image::Image;
use fluidcast_render::{
    add_normal_aovs, check_weights, ms, validate, IsoField, RenderError, RenderParams, RenderStats,
    SurfaceError, Surfaces,
};
use fluidcast_sph::Particles;
use fluidcast_view::{Camera, Light, TransferFunction};

use crate::frame::{check_supported, FrameCtx};
use crate::layout::{iso_code, SurfaceUniform, MAX_ISO_VALUES};
use crate::pass::Timer;
use crate::raycast::depth_limits;
use crate::{cast, push_stage, Gpu, GpuError, RW};

/// Bytes of a pixel's walk in progress (surface.wgsl's `Walk`: 36 words and the pending
/// crossings, 5 per iso value; its size is checked against naga's layout in layout.rs).
pub(crate) const WALK_BYTES: u64 = 4 * (36 + 5 * MAX_ISO_VALUES as u64);

/// The most bytes of walks in progress kept at once (a band of rows of bundles).
const MAX_RESUME_BYTES: u64 = 256 << 20;

/// The surfaces to draw, or why the GPU does not draw them: surfaces alone (the volume in
/// front of opaque ones is the adaptive renderer's, [`fluidcast_render::render_over_surfaces`]),
/// without a shaded volume, at most [`MAX_ISO_VALUES`] values.
fn surfaces_of<'a>(
    particles: &Particles,
    params: &'a RenderParams,
) -> Result<&'a Surfaces, GpuError> {
    validate(params)?;
    let Some(s) = params.surfaces.as_deref() else {
        return Err(RenderError::Rbf("no iso-surfaces to draw".into()).into());
    };
    s.validate(particles.len()).map_err(RenderError::from)?;
    if params.volume_lighting.is_some() {
        return Err(RenderError::VolumeLighting("the GPU's iso-surfaces").into());
    }
    if s.volume {
        return Err(RenderError::from(SurfaceError::Unsupported(
            "the GPU's iso-surfaces with the volume composited between them",
        ))
        .into());
    }
    if s.values.len() > MAX_ISO_VALUES {
        return Err(GpuError::IsoValues(s.values.len()));
    }
    check_weights(particles, params.kernel)?;
    Ok(s)
}

/// surface.wgsl's uniform for `s`.
fn surface_uniform(s: &Surfaces) -> SurfaceUniform {
    let mut values = [0.0f32; 4];
    for (v, x) in values.iter_mut().zip(&s.values) {
        *v = *x as f32;
    }
    let colour = s
        .colour
        .map_or([0.0; 4], |c| [c[0] as f32, c[1] as f32, c[2] as f32, 1.0]);
    let l = &s.lighting;
    let light = match l.light {
        Light::Headlight => [0.0; 4],
        Light::Directional(d) => {
            let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            [(d[0] / n) as f32, (d[1] / n) as f32, (d[2] / n) as f32, 1.0]
        }
    };
    SurfaceUniform {
        values,
        colour,
        light,
        ambient: l.ambient as f32,
        diffuse: l.diffuse as f32,
        specular: l.specular as f32,
        specular_power: l.specular_power as f32,
        n_values: s.values.len() as u32,
        iso: iso_code(&s.field),
        has_b: u32::from(matches!(s.field, IsoField::Attribute(Some(_)))),
        opacity: s.opacity as f32,
        round: 0,
        band_y0: 0,
        band_rows: 0,
        scatter: 1,
    }
}

/// surface.wgsl's buffers of one frame (see [`Gpu::surface_buffers`]).
struct SurfaceBuffers {
    frame: wgpu::Buffer,
    tf: wgpu::Buffer,
    uniform: wgpu::Buffer,
    iso_b: wgpu::Buffer,
    limit: wgpu::Buffer,
    rgba: wgpu::Buffer,
    depth: wgpu::Buffer,
    normal: wgpu::Buffer,
    resume: wgpu::Buffer,
    stopped: wgpu::Buffer,
    guard: wgpu::Buffer,
}

impl Gpu {
    /// Renders `params.surfaces` alone as [`fluidcast_render::render_reference`] does
    /// (premultiplied RGBA, the first surface's depth, its world normal as the AOVs
    /// `normal_x`, `normal_y`, `normal_z`), on the GPU in single precision. Stages: `grid`,
    /// `surfaces` (wall clock), `gpu_surfaces` where the adapter has timestamps.
    pub fn render_surfaces(
        &self,
        particles: &Particles,
        camera: &Camera,
        tf: &TransferFunction,
        params: &RenderParams,
    ) -> Result<(Image, RenderStats), GpuError> {
        let surfaces = surfaces_of(particles, params)?;
        check_supported(params, tf)?;
        self.check_image(params.width, params.height)?;
        let _frame = self
            .frame_lock
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        let (w, h) = (params.width, params.height);
        let frame = camera.frame(w, h).map_err(RenderError::from)?;
        let n = particles.len();
        if n as u64 * 32 > self.max_binding {
            return Err(GpuError::TooManyParticles(n, self.max_binding / 32));
        }
        let mut ctx = self.frame_ctx(&frame, params, tf, n);
        let mut image = Image::new(w, h);
        let n_px = u64::from(w) * u64::from(h);
        let Some(grid) = self.grid(&mut ctx, particles, &frame, (params, false))? else {
            add_normal_aovs(&mut image, &vec![[0.0; 3]; n_px as usize]);
            return Ok((image, self.finish(ctx, Image::new(0, 0))?.stats));
        };
        let t = Instant::now();
        let mut su = surface_uniform(surfaces);
        // The walks in progress of a row of bundles.
        let per_row = WALK_BYTES * u64::from(w) * u64::from(params.grid.bundle);
        su.band_rows = self.band_rows(per_row, MAX_RESUME_BYTES, ctx.u.bundles_y);
        let io = self.surface_buffers(&ctx, &su, params, tf, n_px);
        let binds = [
            ("P", &io.frame),
            ("tf", &io.tf),
            ("S", &io.uniform),
            ("particles", &grid.vparts),
            ("depths", &grid.depths),
            ("cells", &grid.cells),
            ("refs", &grid.refs),
            ("bundle_cells", &grid.bundle_cells),
            ("iso_b", &io.iso_b),
            ("depth_limit", &io.limit),
            ("out_rgba", &io.rgba),
            ("out_depth", &io.depth),
            ("out_normal", &io.normal),
            ("guard", &io.guard),
            ("resume", &io.resume),
            ("stopped", &io.stopped),
        ];
        let mut enc = self.encoder();
        let mut pass = ctx.timer.pass(&mut enc, "gpu_surfaces");
        self.bundle_ranges(&mut pass, &ctx, &grid)?;
        drop(pass);
        self.submit(enc);
        let bundles = (ctx.u.bundles_x, ctx.u.bundles_y);
        let flags = (&io.stopped, &io.guard);
        ctx.stats.dispatches = self.walk_bands(&mut ctx.timer, bundles, &binds, flags, su)?;
        let refused = self.read_surfaces(&io, &ctx.guard, &mut image)?;
        push_stage(&mut ctx.stats, "surfaces", ms(t));
        if let Some(stage) = refused {
            return Err(self.loop_limit_error(stage));
        }
        ctx.stats.plan = None;
        let stats = self.finish(ctx, Image::new(0, 0))?.stats;
        Ok((image, stats))
    }

    /// Walks the rays band by band of `su.band_rows` rows of bundles, each band dispatched
    /// until none of its walks stopped; returns the dispatches.
    fn walk_bands(
        &self,
        timer: &mut Timer,
        (bundles_x, bundles_y): (u32, u32),
        binds: &[(&str, &wgpu::Buffer)],
        flags: (&wgpu::Buffer, &wgpu::Buffer),
        mut su: SurfaceUniform,
    ) -> Result<u64, GpuError> {
        let Some(&(_, uniform)) = binds.iter().find(|b| b.0 == "S") else {
            return Err(GpuError::Device(
                "the surfaces' uniform is not bound".into(),
            ));
        };
        let stage = (
            &self.pipes.surface,
            "the iso-surfaces' field sums",
            "gpu_surfaces",
        );
        let (rows, mut dispatches) = (su.band_rows.max(1), 0);
        for y0 in (0..bundles_y).step_by(rows as usize) {
            (su.band_y0, su.round) = (y0, 0);
            // Every band takes `rows` rows: the last one's rows past the image return at once.
            let (scatter, groups) = self.scattered_groups(rows * bundles_x);
            su.scatter = scatter;
            self.write(uniform, bytemuck::bytes_of(&su));
            dispatches += self.dispatch_until_done(timer, stage, binds, groups, flags, |n| {
                su.round = n as u32;
                self.write(uniform, bytemuck::bytes_of(&su));
            })?;
        }
        Ok(dispatches)
    }

    /// What surface.wgsl binds besides the grid: the frame's uniform with each lane's share
    /// of the loop limit (the walks loop independently per pixel), the surfaces' uniform `su`,
    /// the iso attribute, the depth limits, the outputs and the resume state.
    fn surface_buffers(
        &self,
        ctx: &FrameCtx,
        su: &SurfaceUniform,
        params: &RenderParams,
        tf: &TransferFunction,
        n_px: u64,
    ) -> SurfaceBuffers {
        let mut u = ctx.u;
        u.loop_limit = self.divergent_loop_limit();
        let band_px = u64::from(su.band_rows) * u64::from(u.bundle) * u64::from(u.width);
        let band_bytes = WALK_BYTES * band_px.min(n_px);
        let iso_b: Vec<f32> = match params.surfaces.as_deref().map(|s| &s.field) {
            Some(IsoField::Attribute(Some(b))) => b.to_vec(),
            _ => vec![0.0],
        };
        SurfaceBuffers {
            frame: self.frame_buffer(&u),
            tf: self.tf_buffer(tf),
            uniform: self.buffer(
                "surfaces",
                std::mem::size_of::<SurfaceUniform>() as u64,
                wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                Some(bytemuck::bytes_of(su)),
            ),
            iso_b: self.upload("iso attribute", &iso_b),
            limit: self.upload("depth limit", &depth_limits(params, n_px as usize)),
            rgba: self.buffer("rgba", 16 * n_px, RW, None),
            depth: self.buffer("depth", 4 * n_px, RW, None),
            normal: self.buffer("normals", 16 * n_px, RW, None),
            resume: self.resume_buffer("surface resume", band_bytes, MAX_RESUME_BYTES),
            stopped: self.upload("surface stopped", &[0u32; 4]),
            guard: self.upload("surface guard", &[0u32; 4]),
        }
    }

    /// Reads the surfaces' image back into `image` (depth: no surface at infinity) with the
    /// normal AOVs; the stage whose loop guard fired, if one did (the grid's, on `grid_guard`,
    /// or the surfaces' own).
    fn read_surfaces(
        &self,
        io: &SurfaceBuffers,
        grid_guard: &wgpu::Buffer,
        image: &mut Image,
    ) -> Result<Option<&'static str>, GpuError> {
        let n_px = image.rgba.len() as u64;
        let parts = [
            (&io.rgba, 16 * n_px),
            (&io.depth, 4 * n_px),
            (&io.normal, 16 * n_px),
            (grid_guard, 4),
            (&io.guard, 4),
        ];
        let (normals, refused) = self.fetch_with(&parts, |got| {
            image.rgba = cast(got[0]);
            image.depth = cast::<f32>(got[1]);
            for z in image.depth.iter_mut().filter(|z| **z > 1e29) {
                *z = f32::INFINITY;
            }
            let normals: Vec<[f32; 4]> = cast(got[2]);
            let normals: Vec<[f32; 3]> = normals.iter().map(|n| [n[0], n[1], n[2]]).collect();
            let refused = if cast::<u32>(got[3])[0] != 0 {
                Some("the grid (a particle's cells)")
            } else if cast::<u32>(got[4])[0] != 0 {
                Some("the iso-surfaces' field sums")
            } else {
                None
            };
            (normals, refused)
        })?;
        add_normal_aovs(image, &normals);
        Ok(refused)
    }
}
