//! The RBF field's passes on the GPU (rbf.wgsl), emission–absorption or lit with shadows,
//! the mirror of [`fluidcast_render::render_rbf`]: the BVH built on the host
//! ([`fluidcast_rbf::ClusterBvh`]) is uploaded as it is (heap-ordered boxes, Hilbert-ordered
//! spheres) and traversed in compute, one point range query per sample. wgpu has no
//! ray-tracing pipelines for custom primitives, so there are no RT cores here: the traversal
//! is the shader's own stack walk.

use std::time::Instant;

use fluidcast_image::Image;
use fluidcast_rbf::{Profile, RbfField};
use fluidcast_render::{
    ms, rbf_step_checked, refuse_surfaces, validate, RbfRenderParams, RenderError, RenderParams,
    RenderStats,
};
use fluidcast_view::{Camera, TransferFunction};

use crate::layout::{colouring_code, frame_uniform, noise_code, RbfUniform};
use crate::{cast, push_stage, Gpu, GpuError, RW};

/// Refuses what the GPU's RBF passes do not draw yet.
fn refuse(field: &RbfField, params: &RenderParams, rbf: &RbfRenderParams) -> Result<(), GpuError> {
    let no = |what: &str| {
        GpuError::Render(RenderError::Rbf(format!(
            "the GPU's RBF field does not draw {what} yet; render with --backend cpu"
        )))
    };
    if field.profile() != Profile::Gaussian {
        return Err(no("SPH fields (its shader sums the RBF field's Gaussians)"));
    }
    if params.depth_limit.is_some() || params.depth_near.is_some() {
        return Err(no("depth limits (opaque geometry, cropping)"));
    }
    if rbf.spp == 0 {
        return Err(RenderError::Rbf("samples per pixel must be at least 1".into()).into());
    }
    Ok(())
}

/// What the GPU's march refuses before any work: bad parameters, surfaces, what [`refuse`]
/// names, a transfer function longer than the shader's table.
fn check_rbf(
    field: &RbfField,
    tf: &TransferFunction,
    params: &RenderParams,
    rbf: &RbfRenderParams,
) -> Result<(), GpuError> {
    validate(params)?;
    refuse_surfaces(params, "the GPU's RBF field")?;
    refuse(field, params, rbf)?;
    let points = tf.colors.len().max(tf.opacity.len());
    if points > crate::MAX_TF_POINTS {
        return Err(GpuError::TransferFunction(points));
    }
    Ok(())
}

/// The march's uniform block (`R` in rbf.wgsl) for `field` marched as `rbf` says, with
/// `step` world units between samples.
fn rbf_uniform(field: &RbfField, rbf: &RbfRenderParams, step: f64) -> RbfUniform {
    let bvh = field.bvh();
    let n = bvh.len();
    let root = bvh.bounds();
    RbfUniform {
        root_lo: [root.lo[0], root.lo[1], root.lo[2], 0.0],
        root_hi: [root.hi[0], root.hi[1], root.hi[2], 0.0],
        step: step as f32,
        first_leaf: bvh.first_leaf() as u32,
        n_slots: n as u32,
        leaf_size: bvh.leaf_size() as u32,
        spp: rbf.spp,
        first_pass: rbf.first_pass,
        seed: rbf.seed,
        colouring: colouring_code(field.colouring()),
        noise: noise_code(rbf.noise),
        round: 0,
        shadows: u32::from(rbf.shadows.is_some()),
        shadow_samples: rbf.shadows.as_ref().map_or(1, |s| s.samples),
        light: rbf.shadows.as_ref().map_or([0.0; 4], |s| {
            [s.light[0] as f32, s.light[1] as f32, s.light[2] as f32, 0.0]
        }),
        ambient: rbf.shadows.as_ref().map_or(1.0, |s| s.ambient as f32),
        scatter: 1,
        pad: [0; 2],
    }
}

/// The BVH's boxes (lower and upper corner, each padded to 4 floats) and each slot's weight
/// and attribute, as the shader reads them.
fn field_arrays(field: &RbfField) -> (Vec<[f32; 4]>, Vec<[f32; 4]>) {
    let bvh = field.bvh();
    let boxes: Vec<[f32; 4]> = bvh
        .boxes()
        .iter()
        .flat_map(|b| {
            [
                [b.lo[0], b.lo[1], b.lo[2], 0.0],
                [b.hi[0], b.hi[1], b.hi[2], 0.0],
            ]
        })
        .collect();
    let attrs: Vec<[f32; 4]> = (0..bvh.len() as u32)
        .map(|s| {
            let (w, t) = field.weight_theta(s);
            [w, t[0], t[1], t[2]]
        })
        .collect();
    (boxes, attrs)
}

/// vec4s a pixel's work in progress takes (rbf.wgsl's RESUME_VEC4S).
const RESUME_VEC4S: u64 = 6;

impl Gpu {
    /// The field as rbf.wgsl binds it: BVH boxes, spheres, attributes, and the blue noise.
    fn field_buffers(&self, field: &RbfField) -> [wgpu::Buffer; 4] {
        let (boxes, attrs) = field_arrays(field);
        [
            self.upload("rbf boxes", &boxes),
            self.upload("rbf spheres", field.bvh().spheres()),
            self.upload("rbf attributes", &attrs),
            self.upload("blue noise", fluidcast_render::bluenoise::mask()),
        ]
    }

    /// rbf.wgsl's `resume` and `stopped` for `n_px` pixels: a pixel keeps its work between
    /// dispatches (RESUME_VEC4S vec4s) only where a loop limit can stop it and the work fits
    /// one binding (else the shader stops nothing, and the guard refuses what passes the
    /// limit).
    fn pixel_resume_buffers(&self, n_px: u64) -> (wgpu::Buffer, wgpu::Buffer) {
        let resume = self.resume_buffer("rbf resume", 16 * RESUME_VEC4S * n_px, u64::MAX);
        (resume, self.upload("rbf stopped", &[0u32; 4]))
    }

    /// Reads the march's image (premultiplied RGBA, depth: empty pixels at infinity) back
    /// into `image`; true when a shader invocation hit the loop guard.
    fn read_image(
        &self,
        (rgba, depth, guard): (&wgpu::Buffer, &wgpu::Buffer, &wgpu::Buffer),
        image: &mut Image,
    ) -> Result<bool, GpuError> {
        let n_px = image.rgba.len() as u64;
        let parts = [(rgba, 16 * n_px), (depth, 4 * n_px), (guard, 4)];
        self.fetch_with(&parts, |got| {
            image.rgba = cast(got[0]);
            image.depth = cast::<f32>(got[1]);
            for z in image.depth.iter_mut().filter(|z| **z > 1e29) {
                *z = f32::INFINITY;
            }
            cast::<u32>(got[2])[0] != 0
        })
    }

    /// rbf.wgsl's uniform `R`, holding `u`.
    fn rbf_buffer(&self, u: &RbfUniform) -> wgpu::Buffer {
        let usage = wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST;
        let size = std::mem::size_of::<RbfUniform>() as u64;
        self.buffer("rbf", size, usage, Some(bytemuck::bytes_of(u)))
    }

    /// Renders `field` as [`fluidcast_render::render_rbf`] does (the same passes, offsets,
    /// shade points and shadow rays), in single precision on the GPU.
    pub fn render_rbf(
        &self,
        field: &RbfField,
        camera: &Camera,
        tf: &TransferFunction,
        params: &RenderParams,
        rbf: &RbfRenderParams,
    ) -> Result<(Image, RenderStats), GpuError> {
        check_rbf(field, tf, params, rbf)?;
        self.check_image(params.width, params.height)?;
        let _frame_lock = self
            .frame_lock
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        let (w, h) = (params.width, params.height);
        let frame = camera.frame(w, h).map_err(RenderError::from)?;
        let bvh = field.bvh();
        let mut stats = RenderStats {
            particles: bvh.len(),
            width: w,
            height: h,
            ..Default::default()
        };
        let mut image = Image::new(w, h);
        let Some(step) = rbf_step_checked(field, params, rbf)? else {
            return Ok((image, stats));
        };
        let t0 = Instant::now();
        self.take_traffic();
        let mut u = rbf_uniform(field, rbf, step);
        let (scatter, groups) = self.scattered_groups(w.div_ceil(8) * h.div_ceil(8));
        u.scatter = scatter;
        let fu = frame_uniform(&frame, params, tf, bvh.len(), self.divergent_loop_limit());
        let frame_buf = self.frame_buffer(&fu);
        let rbf_buf = self.rbf_buffer(&u);
        let tf_buf = self.tf_buffer(tf);
        let [boxes, spheres, attrs, blue] = self.field_buffers(field);
        let n_px = u64::from(w) * u64::from(h);
        let rgba = self.buffer("rgba", 16 * n_px, RW, None);
        let depth = self.buffer("depth", 4 * n_px, RW, None);
        let guard = self.upload("guard", &[0u32; 4]);
        let (resume, stopped) = self.pixel_resume_buffers(n_px);
        push_stage(&mut stats, "upload", ms(t0));
        let binds = [
            ("P", &frame_buf),
            ("tf", &tf_buf),
            ("R", &rbf_buf),
            ("boxes", &boxes),
            ("spheres", &spheres),
            ("attrs", &attrs),
            ("blue", &blue),
            ("image", &rgba),
            ("depth", &depth),
            ("guard", &guard),
            ("resume", &resume),
            ("stopped", &stopped),
        ];
        let mut timer = crate::pass::Timer::new(self.timestamps.as_ref());
        let t = Instant::now();
        let pipe = (&self.pipes.rbf, "the RBF march", "gpu_raycast");
        let flags = (&stopped, &guard);
        stats.dispatches =
            self.dispatch_until_done(&mut timer, pipe, &binds, groups, flags, |n| {
                // The next dispatch resumes the pixels that stopped.
                u.round = n as u32;
                self.write(&rbf_buf, bytemuck::bytes_of(&u));
            })?;
        let guarded = self.read_image((&rgba, &depth, &guard), &mut image)?;
        push_stage(&mut stats, "raycast", ms(t));
        if guarded {
            return Err(self.loop_limit_error("the RBF field's point queries"));
        }
        self.finish_timers(&mut timer, &mut stats)?;
        push_stage(&mut stats, "total", ms(t0));
        stats.gpu_memory_bytes = self.memory_bytes();
        stats.transfers = self.take_traffic();
        Ok((image, stats))
    }
}
