use std::time::Instant;

use fluidcast_image::Image;
use fluidcast_sph::{FieldKind, Kernel, Particles};
use fluidcast_view::{Camera, CameraError, TransferFunction, ViewFrame};
use glam::DVec3;
use rayon::prelude::*;

/// Largest image side and pixel count the renderer accepts.
pub const MAX_SIDE: u32 = 16384;
const MAX_PIXELS: u64 = 1 << 27;
const MAX_SAMPLES: usize = 1 << 17;
const TILE: u32 = 8;

/// Parameters of a rendering, shared by every renderer.
#[derive(Debug, Clone)]
pub struct RenderParams {
    /// Image size in pixels.
    pub width: u32,
    pub height: u32,
    pub kernel: Kernel,
    pub field: FieldKind,
    /// Multiplies the number of depth samples (1 = depth step equals the pixel footprint).
    pub sampling_scale: f64,
    /// A ray stops once its transmittance drops below this.
    pub min_transmittance: f64,
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
        }
    }
}

/// Why a rendering could not be made.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error("camera: {0}")]
    Camera(#[from] CameraError),
    #[error("image size {0}x{1} is out of range (each side 1..={MAX_SIDE}, at most {MAX_PIXELS} pixels)")]
    ImageSize(u32, u32),
    #[error("sampling scale {0} must be finite and > 0")]
    SamplingScale(f64),
    #[error("the view needs {0} samples per ray (more than {MAX_SAMPLES}): the near plane is too close to the camera relative to the data; move the camera or lower the sampling scale")]
    TooManySamples(usize),
}

/// Timings and counts of one rendering.
#[derive(Debug, Clone, Default)]
pub struct RenderStats {
    /// (stage, milliseconds) in order.
    pub stages: Vec<(&'static str, f64)>,
    pub particles: usize,
    /// Particles whose support intersects the view frustum.
    pub particles_visible: usize,
    /// Samples with at least one contributing particle that were composited.
    pub samples: u64,
    /// Depth samples per ray (N) and the view-depth range [near, far].
    pub depth_samples: usize,
    pub near: f64,
    pub far: f64,
    pub width: u32,
    pub height: u32,
}

/// The sample depths shared by all rays: `z[i]` for i = 0..=N (z[N] = far).
#[derive(Debug, Clone)]
pub struct SampleDepths {
    pub z: Vec<f64>,
    pub near: f64,
    pub far: f64,
    /// Logarithmic (perspective) or uniform (parallel projection).
    pub logarithmic: bool,
}

impl SampleDepths {
    /// Depth planes for a view-depth range; see the crate docs for the choice of N.
    pub fn new(
        frame: &ViewFrame,
        near: f64,
        far: f64,
        scale: f64,
    ) -> Result<SampleDepths, RenderError> {
        let (n, logarithmic) = match frame.parallel {
            Some(_) => (
                ((far - near) / frame.pixel_size_at(1.0) * scale).ceil(),
                false,
            ),
            None => {
                let sigma = 2.0 * frame.tan_half / frame.height as f64;
                let t = frame.tan_half;
                let lambda = (1.0 + (t * frame.aspect).powi(2) + t * t).sqrt();
                (((far / near).ln() / sigma * lambda * scale).ceil(), true)
            }
        };
        if !n.is_finite() || n > MAX_SAMPLES as f64 {
            return Err(RenderError::TooManySamples(if n.is_finite() {
                n as usize
            } else {
                usize::MAX
            }));
        }
        let n = (n as usize).max(1);
        let z = (0..=n)
            .map(|i| {
                let t = i as f64 / n as f64;
                if logarithmic {
                    near * (far / near).powf(t)
                } else {
                    near + (far - near) * t
                }
            })
            .collect();
        Ok(SampleDepths {
            z,
            near,
            far,
            logarithmic,
        })
    }

    /// Number of samples N.
    pub fn len(&self) -> usize {
        self.z.len() - 1
    }

    /// True when there are no samples (never for a constructed value).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Indices of the samples whose depth lies in [z0, z1], as a half-open range.
    pub fn indices_within(&self, z0: f64, z1: f64) -> std::ops::Range<usize> {
        let n = self.len();
        let pos = |z: f64| -> f64 {
            if self.logarithmic {
                n as f64 * (z / self.near).ln() / (self.far / self.near).ln()
            } else {
                n as f64 * (z - self.near) / (self.far - self.near)
            }
        };
        let mut lo = pos(z0.max(self.near)).ceil().max(0.0) as usize;
        let mut hi = (pos(z1).floor() + 1.0).clamp(0.0, n as f64) as usize;
        // Guard the rounding of ln/pow at the ends.
        while lo > 0 && self.z[lo - 1] >= z0 {
            lo -= 1;
        }
        while lo < hi && self.z[lo] < z0 {
            lo += 1;
        }
        while hi < n && self.z[hi] <= z1 {
            hi += 1;
        }
        while hi > lo && self.z[hi - 1] > z1 {
            hi -= 1;
        }
        lo..hi.max(lo)
    }
}

/// One tile's output: tile index, (premultiplied RGBA, depth) per pixel, samples taken.
type TileResult = (u32, Vec<([f32; 4], f32)>, u64);

/// A particle in view space, as the tiles hold it.
#[derive(Clone, Copy)]
struct ViewParticle {
    c: [f64; 3],
    h: f64,
    v: f64,
    a: f64,
    m: f64,
}

/// Renders `particles` with the reference renderer. The image holds premultiplied RGBA and
/// per-pixel depth (see [`Image`]).
pub fn render_reference(
    particles: &Particles,
    camera: &Camera,
    tf: &TransferFunction,
    params: &RenderParams,
) -> Result<(Image, RenderStats), RenderError> {
    let t0 = Instant::now();
    let (w, h) = (params.width, params.height);
    if w == 0 || h == 0 || w > MAX_SIDE || h > MAX_SIDE || (w as u64 * h as u64) > MAX_PIXELS {
        return Err(RenderError::ImageSize(w, h));
    }
    if !(params.sampling_scale.is_finite() && params.sampling_scale > 0.0) {
        return Err(RenderError::SamplingScale(params.sampling_scale));
    }
    let frame = camera.frame(w, h)?;
    let mut stats = RenderStats {
        particles: particles.len(),
        width: w,
        height: h,
        ..Default::default()
    };
    let mut image = Image::new(w, h);

    // View-space particles and the depth range they occupy.
    let vps: Vec<ViewParticle> = (0..particles.len())
        .map(|j| {
            let p = particles.positions[j];
            let v = frame.to_view(DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64));
            ViewParticle {
                c: v.to_array(),
                h: particles.radii[j] as f64,
                v: particles.volumes[j] as f64,
                a: particles.values[j] as f64,
                m: particles.masses[j] as f64,
            }
        })
        .collect();
    let zmax = vps
        .iter()
        .map(|p| p.c[2] + p.h)
        .fold(f64::NEG_INFINITY, f64::max);
    let zmin = vps
        .iter()
        .map(|p| p.c[2] - p.h)
        .fold(f64::INFINITY, f64::min);
    let perspective = frame.parallel.is_none();
    if vps.is_empty() || (perspective && zmax <= 0.0) {
        stats.stages.push(("total", ms(t0)));
        return Ok((image, stats)); // everything behind the camera
    }
    let far = zmax;
    let near = if perspective {
        zmin.max(far * 1e-4)
    } else {
        zmin
    };
    let depths = SampleDepths::new(&frame, near, far, params.sampling_scale)?;
    stats.depth_samples = depths.len();
    stats.near = near;
    stats.far = far;

    // Bin particles into screen tiles by a conservative screen-space bound of their support.
    let tiles_x = w.div_ceil(TILE);
    let tiles_y = h.div_ceil(TILE);
    let mut bins: Vec<Vec<u32>> = vec![Vec::new(); (tiles_x * tiles_y) as usize];
    let (sx, sy) = match frame.parallel {
        Some(s) => (s * frame.aspect, s),
        None => (frame.tan_half * frame.aspect, frame.tan_half),
    };
    for (j, p) in vps.iter().enumerate() {
        let [x, y, z] = p.c;
        if z + p.h < near || z - p.h > far {
            continue;
        }
        let (x0, x1, y0, y1) = if perspective {
            if z - p.h <= near * 0.5 {
                (-f64::INFINITY, f64::INFINITY, -f64::INFINITY, f64::INFINITY)
            } else {
                // x/z over the box [x±h]×[z±h] (z > 0) is extreme at its corners.
                let zs = [z - p.h, z + p.h];
                let ext = |c: f64| {
                    let v = [
                        (c - p.h) / zs[0],
                        (c - p.h) / zs[1],
                        (c + p.h) / zs[0],
                        (c + p.h) / zs[1],
                    ];
                    (
                        v.iter().copied().fold(f64::INFINITY, f64::min),
                        v.iter().copied().fold(f64::NEG_INFINITY, f64::max),
                    )
                };
                let (a, b) = ext(x);
                let (c, d) = ext(y);
                (a, b, c, d)
            }
        } else {
            (x - p.h, x + p.h, y - p.h, y + p.h)
        };
        // NDC → pixel columns/rows (rows from the top).
        let px0 = ((x0 / sx + 1.0) * 0.5 * w as f64).floor().max(0.0);
        let px1 = ((x1 / sx + 1.0) * 0.5 * w as f64).ceil().min(w as f64);
        let py0 = ((1.0 - y1 / sy) * 0.5 * h as f64).floor().max(0.0);
        let py1 = ((1.0 - y0 / sy) * 0.5 * h as f64).ceil().min(h as f64);
        if px0 >= px1 || py0 >= py1 {
            continue;
        }
        stats.particles_visible += 1;
        let (tx0, tx1) = (px0 as u32 / TILE, (px1 as u32 - 1) / TILE);
        let (ty0, ty1) = (py0 as u32 / TILE, (py1 as u32 - 1) / TILE);
        for ty in ty0..=ty1 {
            for tx in tx0..=tx1 {
                bins[(ty * tiles_x + tx) as usize].push(j as u32);
            }
        }
    }
    stats.stages.push(("bin", ms(t0)));

    // Ray cast tile by tile.
    let t1 = Instant::now();
    let results: Vec<TileResult> = bins
        .par_iter()
        .enumerate()
        .map(|(t, list)| {
            let (tx, ty) = (t as u32 % tiles_x, t as u32 / tiles_x);
            let local: Vec<ViewParticle> = list.iter().map(|&j| vps[j as usize]).collect();
            let mut acc = Accumulator::new(depths.len());
            let mut out = Vec::with_capacity((TILE * TILE) as usize);
            let mut samples = 0u64;
            for j in ty * TILE..((ty + 1) * TILE).min(h) {
                for i in tx * TILE..((tx + 1) * TILE).min(w) {
                    let (px, n) = cast_ray(&frame, i, j, &local, &depths, &mut acc, tf, params);
                    samples += n;
                    out.push(px);
                }
            }
            (t as u32, out, samples)
        })
        .collect();
    for (t, px, n) in results {
        stats.samples += n;
        let (tx, ty) = (t % tiles_x, t / tiles_x);
        let mut k = 0;
        for j in ty * TILE..((ty + 1) * TILE).min(h) {
            for i in tx * TILE..((tx + 1) * TILE).min(w) {
                let idx = image.index(i, j);
                image.rgba[idx] = px[k].0;
                image.depth[idx] = px[k].1;
                k += 1;
            }
        }
    }
    stats.stages.push(("raycast", ms(t1)));
    stats.stages.push(("total", ms(t0)));
    Ok((image, stats))
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// Per-ray sample sums, reused across the rays of a tile.
struct Accumulator {
    weighted: Vec<f64>,
    shepard: Vec<f64>,
    density: Vec<f64>,
}

impl Accumulator {
    fn new(n: usize) -> Self {
        Accumulator {
            weighted: vec![0.0; n],
            shepard: vec![0.0; n],
            density: vec![0.0; n],
        }
    }
}

#[allow(clippy::too_many_arguments)]
fn cast_ray(
    frame: &ViewFrame,
    i: u32,
    j: u32,
    particles: &[ViewParticle],
    depths: &SampleDepths,
    acc: &mut Accumulator,
    tf: &TransferFunction,
    params: &RenderParams,
) -> (([f32; 4], f32), u64) {
    // Ray in view space: point at depth z is o + z·d.
    let (x, y) = frame.ndc(i as f64, j as f64);
    let (o, d) = match frame.parallel {
        Some(s) => ([x * s * frame.aspect, y * s, 0.0], [0.0, 0.0, 1.0]),
        None => (
            [0.0; 3],
            [x * frame.tan_half * frame.aspect, y * frame.tan_half, 1.0],
        ),
    };
    let dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    let dlen = dd.sqrt();
    let (mut lo, mut hi) = (usize::MAX, 0usize);
    for p in particles {
        // |o + z d − c|² < h² ⇔ dd z² + 2 (d·(o−c)) z + |o−c|² − h² < 0.
        let oc = [o[0] - p.c[0], o[1] - p.c[1], o[2] - p.c[2]];
        let b = d[0] * oc[0] + d[1] * oc[1] + d[2] * oc[2];
        let c = oc[0] * oc[0] + oc[1] * oc[1] + oc[2] * oc[2] - p.h * p.h;
        let disc = b * b - dd * c;
        if disc <= 0.0 {
            continue;
        }
        let sq = disc.sqrt();
        let range = depths.indices_within((-b - sq) / dd, (-b + sq) / dd);
        if range.is_empty() {
            continue;
        }
        lo = lo.min(range.start);
        hi = hi.max(range.end);
        for k in range {
            let z = depths.z[k];
            let q = [
                o[0] + z * d[0] - p.c[0],
                o[1] + z * d[1] - p.c[1],
                o[2] + z * d[2] - p.c[2],
            ];
            let r = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt();
            let wgt = params.kernel.eval(r, p.h);
            if wgt > 0.0 {
                acc.weighted[k] += p.v * p.a * wgt;
                acc.shepard[k] += p.v * wgt;
                acc.density[k] += p.m * wgt;
            }
        }
    }
    let mut color = [0.0f64; 3];
    let mut trans = 1.0f64;
    let mut depth = f32::INFINITY;
    let mut samples = 0u64;
    if lo < hi {
        let mut k = lo;
        while k < hi {
            let s = acc.shepard[k];
            if s > 0.0 {
                samples += 1;
                let q = match params.field {
                    FieldKind::Csph => acc.weighted[k] / s,
                    FieldKind::Sph => acc.weighted[k],
                    FieldKind::Density => acc.density[k],
                };
                let (rgb, alpha) = tf.eval(q);
                let a = tf.step_alpha(alpha, (depths.z[k + 1] - depths.z[k]) * dlen);
                for c in 0..3 {
                    color[c] += trans * a * rgb[c];
                }
                trans *= 1.0 - a;
                if trans < 0.5 && depth.is_infinite() {
                    depth = depths.z[k] as f32;
                }
                if trans < params.min_transmittance {
                    break;
                }
            }
            k += 1;
        }
        for k in lo..hi {
            acc.weighted[k] = 0.0;
            acc.shepard[k] = 0.0;
            acc.density[k] = 0.0;
        }
    }
    (
        (
            [
                color[0] as f32,
                color[1] as f32,
                color[2] as f32,
                (1.0 - trans) as f32,
            ],
            depth,
        ),
        samples,
    )
}
