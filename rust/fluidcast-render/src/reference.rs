use std::ops::Range;
use std::time::Instant;

use fluidcast_grid::{screen_rect, view_particles, GridError, Ray, SampleDepths, ViewParticle};
use fluidcast_image::Image;
use fluidcast_sph::Particles;
use fluidcast_view::{Camera, TfLookup, TransferFunction, ViewFrame};
use rayon::prelude::*;

use crate::raycast::{Compositor, Sums};
use crate::surface::{
    add_normal_aovs, IsoField, SurfaceCaster, SurfaceError, SurfaceScratch, Surfaces,
};
use crate::{ms, validate, RenderError, RenderParams, RenderStats};

const TILE: u32 = 8;

/// One pixel's output: premultiplied RGBA, depth, and the world-space normal of its first
/// iso-surface (zero where it has none, or without surfaces).
#[derive(Debug, Clone, Copy)]
struct Pixel {
    rgba: [f32; 4],
    depth: f32,
    normal: [f32; 3],
}

/// One tile's output: tile index, its pixels row by row, samples taken.
type TileResult = (u32, Vec<Pixel>, u64);

/// What casting a tile's rays needs: the frame's parameters, sample depths and, with
/// iso-surfaces, their caster and the iso attribute per particle.
struct TileCaster<'a> {
    params: &'a RenderParams,
    frame: &'a ViewFrame,
    tf: &'a TfLookup<'a>,
    depths: &'a SampleDepths,
    surfaces: Option<SurfaceCaster<'a>>,
    iso_values: Option<&'a [f32]>,
}

impl<'a> TileCaster<'a> {
    fn new(
        params: &'a RenderParams,
        frame: &'a ViewFrame,
        tf: &'a TfLookup<'a>,
        depths: &'a SampleDepths,
        (particles, lit_volume): (&'a Particles, &'a Surfaces),
    ) -> Result<TileCaster<'a>, RenderError> {
        if let Some(s) = params.surfaces.as_deref() {
            s.validate(particles.len())?;
        }
        if let Some(l) = &params.volume_lighting {
            l.validate().map_err(SurfaceError::from)?;
        }
        // A shaded volume is cast as surfaces are (each ray's passes at hand), with no iso
        // value when none is drawn.
        let lit = params.volume_lighting.is_some().then_some(lit_volume);
        let surfaces = params.surfaces.as_deref().or(lit);
        let iso_values = match surfaces.map(|s| &s.field) {
            Some(IsoField::Attribute(Some(v))) => Some(&v[..]),
            _ => None,
        };
        Ok(TileCaster {
            params,
            frame,
            tf,
            depths,
            surfaces: surfaces.map(|surfaces| SurfaceCaster {
                surfaces,
                params,
                frame,
                tf,
                zs: &depths.z[..depths.len() + 1],
            }),
            iso_values,
        })
    }

    /// Casts the rays of pixels `(columns, rows)` through the particles `list` (indices
    /// into `vps`); returns the pixels row by row and the samples composited.
    fn tile(
        &self,
        list: &[u32],
        vps: &[ViewParticle],
        (columns, rows): (Range<u32>, Range<u32>),
    ) -> (Vec<Pixel>, u64) {
        let n = self.depths.len();
        let mut sums = Sums::new(n);
        let mut out = Vec::with_capacity((TILE * TILE) as usize);
        let mut samples = 0u64;
        let Some(surfaces) = &self.surfaces else {
            let local: Vec<ViewParticle> = list.iter().map(|&j| vps[j as usize]).collect();
            for j in rows {
                for i in columns.clone() {
                    let comp = self.volume_ray(&local, &mut sums, i, j);
                    samples += comp.samples;
                    let (rgba, depth) = comp.pixel();
                    out.push(Pixel {
                        rgba,
                        depth,
                        normal: [0.0; 3],
                    });
                }
            }
            return (out, samples);
        };
        let local: Vec<(ViewParticle, f64)> = list
            .iter()
            .map(|&j| {
                let p = vps[j as usize];
                (p, self.iso_values.map_or(p.a(), |v| v[j as usize] as f64))
            })
            .collect();
        let mut scratch = SurfaceScratch::new(n);
        for j in rows {
            for i in columns.clone() {
                let ray = Ray::through_pixel(self.frame, i, j);
                let r = surfaces.cast(&ray, &local, &mut scratch, &mut sums, (i, j));
                samples += r.comp.samples;
                let (rgba, half) = r.comp.pixel();
                // Z: the first surface (with surfaces), else the ½-opacity depth.
                let none = if self.params.surfaces.is_some() {
                    f32::INFINITY
                } else {
                    half
                };
                out.push(match r.first {
                    Some((depth, normal)) => Pixel {
                        rgba,
                        depth,
                        normal,
                    },
                    None => Pixel {
                        rgba,
                        depth: none,
                        normal: [0.0; 3],
                    },
                });
            }
        }
        (out, samples)
    }

    /// Pixel (i, j)'s emission–absorption ray: every particle of `local` scattered into its
    /// samples, then composited front to back.
    fn volume_ray(&self, local: &[ViewParticle], sums: &mut Sums, i: u32, j: u32) -> Compositor {
        let (params, depths) = (self.params, self.depths);
        let zs = &depths.z[..depths.len()];
        let ray = Ray::through_pixel(self.frame, i, j);
        let (lo, hi) = local
            .iter()
            .filter_map(|p| sums.scatter(&ray, p, zs, params.kernel))
            .fold((usize::MAX, 0), |(a, b), r| (a.min(r.start), b.max(r.end)));
        let mut comp = Compositor::for_pixel(params, i, j);
        for k in lo..hi {
            if let Some(q) = sums.value(k, params.field) {
                let z = (depths.z[k], depths.z[k + 1]);
                comp.sample(self.tf, q, z, ray.dlen, params.min_transmittance);
                if comp.done {
                    break;
                }
            }
        }
        if lo < hi {
            sums.clear(lo..hi);
        }
        comp
    }
}

/// What the renderers that cast every pixel's ray (reference, object space) start from: the
/// checked parameters' view frame, stats and an empty image, the particles in view space and
/// the sample depths over their depth range (`None` when everything lies behind the camera).
pub(crate) struct RayView {
    pub frame: ViewFrame,
    pub stats: RenderStats,
    pub image: Image,
    pub particles: Vec<ViewParticle>,
    pub depths: Option<SampleDepths>,
}

impl RayView {
    pub fn new(
        particles: &Particles,
        camera: &Camera,
        params: &RenderParams,
    ) -> Result<RayView, RenderError> {
        validate(params)?;
        let (w, h) = (params.width, params.height);
        let frame = camera.frame(w, h)?;
        let mut stats = RenderStats {
            particles: particles.len(),
            width: w,
            height: h,
            ..Default::default()
        };
        let mut vp = view_particles(particles, &frame);
        let own = vp.range;
        vp.range = fluidcast_grid::sampled_range(&frame, params.support_depths, || own);
        let depths = match vp.range {
            Some((near, far)) => {
                let d = SampleDepths::new(
                    &frame,
                    near,
                    far,
                    params.sampling_scale,
                    params.grid.depth_samples as usize,
                )?;
                stats.depth_samples = d.len();
                stats.near = near;
                stats.far = far;
                Some(d)
            }
            None => None,
        };
        Ok(RayView {
            frame,
            stats,
            image: Image::new(w, h),
            particles: vp.list,
            depths,
        })
    }
}

/// The particles (indices into `vps`) whose support's screen rectangle meets each screen tile
/// of `TILE` pixels, and how many reach the image at all. Refused before allocating when the
/// references would not fit the memory budget.
fn bin_particles(
    frame: &ViewFrame,
    vps: &[ViewParticle],
    (near, far): (f64, f64),
    (w, h): (u32, u32),
) -> Result<(Vec<Vec<u32>>, usize), RenderError> {
    let (tiles_x, tiles_y) = (w.div_ceil(TILE), h.div_ceil(TILE));
    let rects: Vec<Option<[u32; 4]>> = vps
        .iter()
        .map(|p| screen_rect(frame, p, near, far))
        .collect();
    let refs: u64 = rects
        .iter()
        .flatten()
        .map(|r| {
            u64::from((r[1] - 1) / TILE - r[0] / TILE + 1)
                * u64::from((r[3] - 1) / TILE - r[2] / TILE + 1)
        })
        .sum();
    fluidcast_mem::check(
        || format!("binning {refs} particle–tile references at {w}x{h}"),
        refs.saturating_mul(4),
    )
    .map_err(GridError::from)?;
    let mut bins: Vec<Vec<u32>> = vec![Vec::new(); (tiles_x * tiles_y) as usize];
    let mut visible = 0;
    for (j, rect) in rects.iter().enumerate() {
        let Some([px0, px1, py0, py1]) = *rect else {
            continue;
        };
        visible += 1;
        for ty in py0 / TILE..=(py1 - 1) / TILE {
            for tx in px0 / TILE..=(px1 - 1) / TILE {
                bins[(ty * tiles_x + tx) as usize].push(j as u32);
            }
        }
    }
    Ok((bins, visible))
}

/// Pastes the tiles' pixels into `image` (and, `with_normals`, the surface normals as AOVs);
/// returns the samples they took.
fn paste_tiles(
    image: &mut Image,
    results: Vec<TileResult>,
    tiles_x: u32,
    with_normals: bool,
) -> u64 {
    let (w, h) = (image.width, image.height);
    let mut samples = 0;
    let mut normals = vec![[0.0f32; 3]; if with_normals { image.rgba.len() } else { 0 }];
    for (t, px, n) in results {
        samples += n;
        let (tx, ty) = (t % tiles_x, t / tiles_x);
        let mut k = 0;
        for j in ty * TILE..((ty + 1) * TILE).min(h) {
            for i in tx * TILE..((tx + 1) * TILE).min(w) {
                let idx = image.index(i, j);
                image.rgba[idx] = px[k].rgba;
                image.depth[idx] = px[k].depth;
                if with_normals {
                    normals[idx] = px[k].normal;
                }
                k += 1;
            }
        }
    }
    if with_normals {
        add_normal_aovs(image, &normals);
    }
    samples
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
    let RayView {
        frame,
        mut stats,
        mut image,
        particles: vps,
        depths,
    } = RayView::new(particles, camera, params)?;
    let Some(depths) = depths else {
        stats.stages.push(("total", ms(t0)));
        return Ok((image, stats)); // everything behind the camera
    };
    let (near, far) = (depths.near, depths.far);

    // Bin particles into screen tiles by a conservative screen-space bound of their support.
    let tiles_x = w.div_ceil(TILE);
    let (bins, visible) = bin_particles(&frame, &vps, (near, far), (w, h))?;
    stats.particles_visible += visible;
    stats.stages.push(("bin", ms(t0)));

    // Ray cast tile by tile.
    let t1 = Instant::now();
    let tf = &TfLookup::new(tf);
    let lit_volume = Surfaces {
        values: Vec::new(),
        volume: true,
        ..Default::default()
    };
    let caster = TileCaster::new(params, &frame, tf, &depths, (particles, &lit_volume))?;
    let progress = params.progress.as_deref();
    crate::progress::start(progress, bins.len());
    let results: Vec<TileResult> = bins
        .par_iter()
        .enumerate()
        .filter(|_| crate::progress::next(progress))
        .map(|(t, list)| {
            let (tx, ty) = (t as u32 % tiles_x, t as u32 / tiles_x);
            let pixels = (
                tx * TILE..((tx + 1) * TILE).min(w),
                ty * TILE..((ty + 1) * TILE).min(h),
            );
            let (out, samples) = caster.tile(list, &vps, pixels);
            (t as u32, out, samples)
        })
        .collect();
    if crate::progress::cancelled(progress) {
        return Err(RenderError::Cancelled);
    }
    stats.samples += paste_tiles(&mut image, results, tiles_x, params.surfaces.is_some());
    stats.stages.push(("raycast", ms(t1)));
    stats.stages.push(("total", ms(t0)));
    Ok((image, stats))
}
