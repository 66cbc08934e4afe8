//! The perspective grid renderer of Fraedrich, Auer and Westermann 2010 (Sec. 4–5): per
//! frame, the particles are resampled into a dense view-aligned grid, one column per
//! `cell × cell` pixels and one slice per depth sample (the logarithmic depths of
//! [`SampleDepths`], their m = ln(f/n)/σ·λ), slab by slab from front to back, and every
//! pixel's ray marches the grid, interpolating its four neighbouring columns bilinearly at
//! each slice. Iso-surfaces are found between slices by linear interpolation and lit with
//! perspective-correct central differences: lateral differences between columns at one
//! depth, the along-ray difference between slices, and the ray's direction to turn the
//! latter into ∂f/∂z. A slab holds one slice more on either side for those differences.
//!
//! It is the third way between VTK's world-space grid (resample once, then any view) and the
//! on-the-fly ray casters (no grid): its grid follows the view, and its memory is one slab
//! (`columns × (SLAB + 2) × 8` bytes), not the view volume. With `cell = 1` its columns are
//! the pixels' own rays and it takes the reference renderer's samples.

use std::ops::Range;
use std::time::Instant;

use fluidcast_grid::{screen_rect, Ray, SampleDepths, ViewParticle};
use fluidcast_image::Image;
use fluidcast_sph::{FieldKind, Particles};
use fluidcast_view::{Camera, TfLookup, TransferFunction, ViewFrame};
use rayon::prelude::*;

use crate::raycast::{Compositor, Sums};
use crate::reference::RayView;
use crate::surface::{
    add_normal_aovs, Hit, IsoField, SurfaceCaster, SurfaceError, SurfaceRay, Surfaces,
};
use crate::{ms, RenderError, RenderParams, RenderStats};

/// Depth slices resampled at once.
pub const SLAB: usize = 32;
/// Grid columns per side of a binning tile.
const TILE: u32 = 8;
/// Largest `cell` (pixels per grid column along each side).
pub const MAX_CELL: u32 = 64;

/// The grid's layout: columns, their spacing in pixels, and the frame they follow.
struct Layout<'a> {
    frame: &'a ViewFrame,
    cell: u32,
    cols: u32,
    rows: u32,
}

impl Layout<'_> {
    /// The ray of column (gi, gj): through the middle of its `cell × cell` pixels.
    fn ray(&self, gi: u32, gj: u32) -> Ray {
        let half = 0.5 * self.cell as f64;
        let c = self.cell as f64;
        Ray::through_point(self.frame, gi as f64 * c + half, gj as f64 * c + half)
    }

    /// Continuous column coordinate of pixel centre `i` (clamped to the grid).
    fn coord(&self, i: u32, n: u32) -> f64 {
        let c = self.cell as f64;
        ((i as f64 + 0.5 - 0.5 * c) / c).clamp(0.0, (n - 1) as f64)
    }

    /// View-space distance between neighbouring columns at view depth `z`, along x and y.
    fn spacing(&self, z: f64) -> (f64, f64) {
        let f = self.frame;
        let c = self.cell as f64;
        let (w, h) = (f.width as f64, f.height as f64);
        match f.parallel {
            Some(s) => (c * 2.0 * s * f.aspect / w, c * 2.0 * s / h),
            None => (
                c * 2.0 * f.tan_half * f.aspect / w * z,
                c * 2.0 * f.tan_half / h * z,
            ),
        }
    }
}

/// One slab of the grid: slices `halo` (the slab's own plus one on either side), per column
/// the rendered field (NaN where undefined) and the iso field, stored tile by tile
/// (`TILE × TILE` column slots of `SLAB + 2` slices each) so that each tile writes its own
/// block. Only the slices a particle reaches are written (`touched`); the buffers are kept
/// from slab to slab and never cleared.
struct Slab {
    halo: Range<usize>,
    own: Range<usize>,
    vol: Vec<f32>,
    iso: Vec<f32>,
    /// Per column slot, the slices (absolute) some particle reaches; outside them the
    /// rendered field is undefined and the iso field `iso_empty`.
    touched: Vec<Range<usize>>,
    /// The iso field where no particle reaches: 0 (colour, density) or undefined.
    iso_empty: f32,
    tiles_x: u32,
}

/// Slices per column slot in a slab's buffers.
const SLOT: usize = SLAB + 2;

impl Slab {
    fn new(layout: &Layout, surfaces: Option<&Surfaces>) -> Result<Slab, RenderError> {
        let tiles_x = layout.cols.div_ceil(TILE);
        let slots = (tiles_x * layout.rows.div_ceil(TILE) * TILE * TILE) as usize;
        let fields = 1 + u64::from(surfaces.is_some());
        fluidcast_mem::check(
            || format!("a perspective grid slab of {slots} columns x {SLOT} slices"),
            (slots * SLOT) as u64 * 4 * fields + slots as u64 * 16,
        )
        .map_err(fluidcast_grid::GridError::from)?;
        Ok(Slab {
            halo: 0..0,
            own: 0..0,
            vol: vec![f32::NAN; slots * SLOT],
            iso: vec![f32::NAN; if surfaces.is_some() { slots * SLOT } else { 0 }],
            touched: vec![0..0; slots],
            iso_empty: match surfaces.map(|s| &s.field) {
                Some(IsoField::Colour | IsoField::Density) => 0.0,
                _ => f32::NAN,
            },
            tiles_x,
        })
    }

    /// The slot of column (gi, gj).
    fn slot(&self, (gi, gj): (u32, u32)) -> usize {
        let t = (gj / TILE * self.tiles_x + gi / TILE) as usize;
        t * (TILE * TILE) as usize + (gj % TILE * TILE + gi % TILE) as usize
    }

    /// The rendered (`iso` false) or iso field of column (gi, gj) at slice `s` (absolute).
    fn at(&self, iso: bool, col: (u32, u32), s: usize) -> f32 {
        let k = self.slot(col);
        if !self.touched[k].contains(&s) {
            return if iso { self.iso_empty } else { f32::NAN };
        }
        let field = if iso { &self.iso } else { &self.vol };
        field[k * SLOT + s - self.halo.start]
    }

    /// Bilinear interpolation of `field` at continuous column coordinates (u, v), slice `s`,
    /// over the defined corners (renormalised); `None` where none is.
    fn lerp(&self, iso: bool, layout: &Layout, uv: (f64, f64), s: usize) -> Option<f64> {
        self.lerp_covered(iso, layout, uv, s).map(|(x, _)| x)
    }

    /// [`Slab::lerp`] and the weight of the defined corners (1 inside the field, falling to 0
    /// across the last column at its edge: the share of the medium the pixel sees there).
    fn lerp_covered(
        &self,
        iso: bool,
        layout: &Layout,
        (u, v): (f64, f64),
        s: usize,
    ) -> Option<(f64, f64)> {
        let (u0, v0) = (u.floor() as u32, v.floor() as u32);
        let (u1, v1) = ((u0 + 1).min(layout.cols - 1), (v0 + 1).min(layout.rows - 1));
        let (fu, fv) = (u - u0 as f64, v - v0 as f64);
        let corners = [
            ((u0, v0), (1.0 - fu) * (1.0 - fv)),
            ((u1, v0), fu * (1.0 - fv)),
            ((u0, v1), (1.0 - fu) * fv),
            ((u1, v1), fu * fv),
        ];
        let (mut sum, mut weight) = (0.0, 0.0);
        for (c, w) in corners {
            let x = self.at(iso, c, s);
            if !x.is_nan() && w > 0.0 {
                sum += w * x as f64;
                weight += w;
            }
        }
        (weight > 0.0).then(|| (sum / weight, weight))
    }
}

/// What the perspective grid does not draw, refused before any work: a grid cell out of
/// range, a shaded volume, iso-surfaces of another array.
fn check(particles: &Particles, params: &RenderParams, cell: u32) -> Result<(), RenderError> {
    if !(1..=MAX_CELL).contains(&cell) {
        return Err(RenderError::GridCell(cell));
    }
    if params.volume_lighting.is_some() {
        return Err(RenderError::VolumeLighting("the perspective grid renderer"));
    }
    if let Some(s) = &params.surfaces {
        s.validate(particles.len())?;
        if matches!(s.field, IsoField::Attribute(Some(_))) {
            let what = "the perspective grid renderer (with an iso field of another array)";
            return Err(SurfaceError::Unsupported(what).into());
        }
    }
    Ok(())
}

/// Renders `particles` through a perspective grid of one column per `cell × cell` pixels
/// (see the module documentation).
pub fn render_perspective_grid(
    particles: &Particles,
    camera: &Camera,
    tf: &TransferFunction,
    params: &RenderParams,
    cell: u32,
) -> Result<(Image, RenderStats), RenderError> {
    let t0 = Instant::now();
    check(particles, params, cell)?;
    let RayView {
        frame,
        mut stats,
        mut image,
        particles: vps,
        depths,
    } = RayView::new(particles, camera, params)?;
    let Some(depths) = depths else {
        stats.stages.push(("total", ms(t0)));
        return Ok((image, stats));
    };
    let (w, h) = (params.width, params.height);
    let layout = Layout {
        frame: &frame,
        cell,
        cols: w.div_ceil(cell),
        rows: h.div_ceil(cell),
    };
    let bins = bin(&layout, &vps, &depths, &mut stats)?;
    let tf = &TfLookup::new(tf);
    let caster = params.surfaces.as_deref().map(|surfaces| SurfaceCaster {
        surfaces,
        params,
        frame: &frame,
        tf,
        zs: &depths.z[..depths.len() + 1],
    });
    let march = March {
        layout: &layout,
        params,
        tf,
        depths: &depths,
        caster: caster.as_ref(),
    };
    let mut rays: Vec<SurfaceRay> = (0..h)
        .flat_map(|j| (0..w).map(move |i| (i, j)))
        .map(|(i, j)| SurfaceRay {
            comp: Compositor::for_pixel(params, i, j),
            first: None,
        })
        .collect();
    let (resample_ms, raycast_ms) = march.slabs(&vps, &bins, &mut rays, &mut stats)?;
    finish(&mut image, &mut stats, &rays, params.surfaces.is_some());
    stats.stages.push(("resample", resample_ms));
    stats.stages.push(("raycast", raycast_ms));
    stats.stages.push(("total", ms(t0)));
    Ok((image, stats))
}

/// Columns around a column whose values a pixel may read: bilinear interpolation between
/// its two nearest columns each way, and central differences across them (surface normals).
const READ_REACH: u32 = 3;

/// Pixels around a screen tile whose particles the perspective grid with `cell` pixels per
/// column needs to render the tile's pixels ([`crate::render_in_tiles`]'s margin): the
/// columns its pixels read, [`READ_REACH`] of them.
pub fn tile_margin(cell: u32) -> u32 {
    READ_REACH * cell
}

/// Occlusion culling: per tile of `TILE × TILE` columns, whether every pixel that may read
/// one of its columns (the tile grown by [`READ_REACH`] columns) has stopped. Such a tile
/// need not be resampled: no pixel that still marches reads it. A two-level opacity buffer
/// (pixels, then columns), rebuilt before each slab.
fn occluded_tiles(layout: &Layout, rays: &[SurfaceRay], skip: &mut [bool]) {
    let w = layout.frame.width;
    let (cols, rows, c) = (layout.cols, layout.rows, layout.cell);
    // Columns some pixel of whose cell × cell block still marches.
    let mut open = vec![false; (cols * rows) as usize];
    for (k, r) in rays.iter().enumerate() {
        if !r.comp.done {
            let (i, j) = (k as u32 % w, k as u32 / w);
            open[((j / c).min(rows - 1) * cols + (i / c).min(cols - 1)) as usize] = true;
        }
    }
    let tiles_x = cols.div_ceil(TILE);
    skip.par_iter_mut().enumerate().for_each(|(t, s)| {
        let (bx, by) = (t as u32 % tiles_x, t as u32 / tiles_x);
        let x0 = (bx * TILE).saturating_sub(READ_REACH);
        let x1 = ((bx + 1) * TILE + READ_REACH).min(cols);
        let y0 = (by * TILE).saturating_sub(READ_REACH);
        let y1 = ((by + 1) * TILE + READ_REACH).min(rows);
        *s = !(y0..y1).any(|gj| (x0..x1).any(|gi| open[(gj * cols + gi) as usize]));
    });
}

/// Bins the particles into tiles of `TILE × TILE` columns by their screen rectangles,
/// each tile's list sorted by the particles' nearest depth.
fn bin(
    layout: &Layout,
    vps: &[ViewParticle],
    depths: &SampleDepths,
    stats: &mut RenderStats,
) -> Result<Vec<Vec<u32>>, RenderError> {
    let (tx, ty) = (layout.cols.div_ceil(TILE), layout.rows.div_ceil(TILE));
    let c = layout.cell as f64;
    let to_col = |px: u32, n: u32, up: bool| {
        let x = (px as f64 - 0.5 * c) / c;
        let k = if up { x.ceil() } else { x.floor() };
        k.clamp(0.0, (n - 1) as f64) as u32
    };
    let mut bins: Vec<Vec<u32>> = vec![Vec::new(); (tx * ty) as usize];
    for (k, p) in vps.iter().enumerate() {
        let Some([x0, x1, y0, y1]) = screen_rect(layout.frame, p, depths.near, depths.far) else {
            continue;
        };
        stats.particles_visible += 1;
        let (c0, c1) = (
            to_col(x0, layout.cols, true),
            to_col(x1, layout.cols, false),
        );
        let (r0, r1) = (
            to_col(y0, layout.rows, true),
            to_col(y1, layout.rows, false),
        );
        if c0 > c1 || r0 > r1 {
            continue;
        }
        for by in r0 / TILE..=r1 / TILE {
            for bx in c0 / TILE..=c1 / TILE {
                bins[(by * tx + bx) as usize].push(k as u32);
            }
        }
    }
    let refs: u64 = bins.iter().map(|b| b.len() as u64).sum();
    fluidcast_mem::check(
        || format!("binning {refs} particle-tile references"),
        refs.saturating_mul(4),
    )
    .map_err(fluidcast_grid::GridError::from)?;
    for b in &mut bins {
        b.sort_by(|&a, &b| {
            let (a, b) = (&vps[a as usize], &vps[b as usize]);
            (a.c[2] - a.h()).total_cmp(&(b.c[2] - b.h()))
        });
    }
    Ok(bins)
}

/// Resamples slices `own` (and one more on either side) into every column of `slab`: each
/// tile's particles whose support reaches the slab's depths, scattered into each column's
/// ray, written into the tile's own block.
fn resample(
    slab: &mut Slab,
    (layout, params): (&Layout, &RenderParams),
    vps: &[ViewParticle],
    (bins, skip): (&[Vec<u32>], &[bool]),
    depths: &SampleDepths,
    own: Range<usize>,
) {
    let n = depths.len();
    let halo = own.start.saturating_sub(1)..(own.end + 1).min(n);
    let l = halo.len();
    let zs = &depths.z[halo.clone()];
    let (z_lo, z_hi) = (zs[0], zs[l - 1]);
    let tiles_x = slab.tiles_x;
    let iso_of = params.surfaces.as_deref().map(iso_field);
    let per_tile = (TILE * TILE) as usize;
    let mut iso_blocks: Vec<&mut [f32]> = match iso_of {
        Some(_) => slab.iso.chunks_mut(per_tile * SLOT).collect(),
        None => Vec::new(),
    };
    iso_blocks.resize_with(bins.len(), Default::default);
    slab.vol
        .par_chunks_mut(per_tile * SLOT)
        .zip(iso_blocks.into_par_iter())
        .zip(slab.touched.par_chunks_mut(per_tile))
        .zip(bins.par_iter().zip(skip.par_iter()))
        .enumerate()
        .for_each(|(t, (((vol, iso), touched), (list, &skip)))| {
            if skip {
                // Occluded: nothing a marching pixel reads.
                touched.iter_mut().for_each(|span| *span = 0..0);
                return;
            }
            let (bx, by) = (t as u32 % tiles_x, t as u32 / tiles_x);
            let local: Vec<ViewParticle> = list
                .iter()
                .map(|&k| vps[k as usize])
                .take_while(|p| p.c[2] - p.h() <= z_hi)
                .filter(|p| p.c[2] + p.h() >= z_lo)
                .collect();
            let mut sums = Sums::new(l);
            for (c, span) in touched.iter_mut().enumerate() {
                let (gi, gj) = (bx * TILE + c as u32 % TILE, by * TILE + c as u32 / TILE);
                *span = 0..0;
                if gi >= layout.cols || gj >= layout.rows || local.is_empty() {
                    continue;
                }
                let ray = layout.ray(gi, gj);
                let (lo, hi) = local
                    .iter()
                    .filter_map(|p| sums.scatter(&ray, p, zs, params.kernel))
                    .fold((usize::MAX, 0), |(a, b), r| (a.min(r.start), b.max(r.end)));
                if lo >= hi {
                    continue;
                }
                *span = halo.start + lo..halo.start + hi;
                for k in lo..hi {
                    let v = sums.value(k, params.field);
                    vol[c * SLOT + k] = v.map_or(f32::NAN, |v| v as f32);
                    if let Some(f) = iso_of {
                        iso[c * SLOT + k] = f(&sums, k).map_or(f32::NAN, |v| v as f32);
                    }
                }
                sums.clear(lo..hi);
            }
        });
    slab.halo = halo;
    slab.own = own;
}

/// The iso field of `surfaces` from a column's sums at sample k.
fn iso_field(surfaces: &Surfaces) -> fn(&Sums, usize) -> Option<f64> {
    match surfaces.field {
        IsoField::Colour => |s, k| Some(s.shepard[k]),
        IsoField::Density => |s, k| Some(s.density[k]),
        IsoField::Attribute(_) => |s, k| s.value(k, FieldKind::Csph),
    }
}

/// What marching the pixels' rays through a slab needs.
struct March<'a> {
    layout: &'a Layout<'a>,
    params: &'a RenderParams,
    tf: &'a TfLookup<'a>,
    depths: &'a SampleDepths,
    caster: Option<&'a SurfaceCaster<'a>>,
}

impl March<'_> {
    /// Resamples the particles (`vps`, binned in `bins`) slab by slab and marches every ray
    /// through each slab, until every ray is done; occlusion culling skips the tiles no
    /// marching pixel reads. Returns the milliseconds of resampling and of ray marching.
    fn slabs(
        &self,
        vps: &[ViewParticle],
        bins: &[Vec<u32>],
        rays: &mut [SurfaceRay],
        stats: &mut RenderStats,
    ) -> Result<(f64, f64), RenderError> {
        let (layout, params, depths) = (self.layout, self.params, self.depths);
        let (mut resample_ms, mut raycast_ms) = (0.0, 0.0);
        let mut slab = Slab::new(layout, params.surfaces.as_deref())?;
        let n = depths.len();
        let mut skip = vec![false; bins.len()];
        for s0 in (0..n).step_by(SLAB) {
            if rays.iter().all(|r| r.comp.done) {
                break;
            }
            let t = Instant::now();
            if params.occlusion_culling {
                occluded_tiles(layout, rays, &mut skip);
                stats.culled += skip
                    .iter()
                    .zip(bins)
                    .filter(|(&s, _)| s)
                    .map(|(_, b)| b.len() as u64)
                    .sum::<u64>();
            }
            let own = s0..(s0 + SLAB).min(n);
            resample(&mut slab, (layout, params), vps, (bins, &skip), depths, own);
            resample_ms += ms(t);
            let t = Instant::now();
            rays.par_chunks_mut(params.width as usize)
                .enumerate()
                .for_each(|(j, row)| self.row(&slab, j as u32, row));
            raycast_ms += ms(t);
        }
        Ok((resample_ms, raycast_ms))
    }

    /// Marches row `j`'s rays through the slab's own slices.
    fn row(&self, slab: &Slab, j: u32, rays: &mut [SurfaceRay]) {
        let l = self.layout;
        let v = l.coord(j, l.rows);
        for (i, out) in rays.iter_mut().enumerate() {
            if out.comp.done {
                continue;
            }
            let uv = (l.coord(i as u32, l.cols), v);
            let ray = Ray::through_pixel(l.frame, i as u32, j);
            self.pixel(slab, uv, &ray, out);
        }
    }

    /// The slab's slices that pixel (u, v) needs: where a particle reaches one of its four
    /// columns, and one slice on either side (where the iso field crosses into the body).
    fn slices(&self, slab: &Slab, (u, v): (f64, f64)) -> Range<usize> {
        let l = self.layout;
        let (u0, v0) = (u.floor() as usize, v.floor() as usize);
        let (u1, v1) = (
            (u0 + 1).min(l.cols as usize - 1),
            (v0 + 1).min(l.rows as usize - 1),
        );
        let (mut lo, mut hi) = (usize::MAX, 0);
        for (a, b) in [(u0, v0), (u1, v0), (u0, v1), (u1, v1)] {
            let t = &slab.touched[slab.slot((a as u32, b as u32))];
            if !t.is_empty() {
                (lo, hi) = (lo.min(t.start), hi.max(t.end));
            }
        }
        if lo >= hi {
            return 0..0;
        }
        lo.saturating_sub(1).max(slab.own.start)..(hi + 1).min(slab.own.end)
    }

    /// One ray through the slab: per slice its volume step and the surfaces inside it.
    fn pixel(&self, slab: &Slab, uv: (f64, f64), ray: &Ray, out: &mut SurfaceRay) {
        let (z, params) = (&self.depths.z, self.params);
        let min_t = params.min_transmittance;
        let volume = self.caster.is_none_or(|c| c.surfaces.volume);
        let mut hits = Vec::new();
        for s in self.slices(slab, uv) {
            if let Some(c) = self.caster {
                self.crossings(c, slab, uv, s, &mut hits);
            }
            // The medium where only some corners have one thins out with their weight.
            let q = volume
                .then(|| slab.lerp_covered(false, self.layout, uv, s))
                .flatten();
            let mut z0 = z[s];
            for hit in &hits {
                if let Some((q, cover)) = q {
                    out.comp
                        .sample(self.tf, q, (z0, hit.z), ray.dlen * cover, min_t);
                }
                z0 = hit.z;
                if hit.z >= out.comp.limit || hit.z <= out.comp.near {
                    out.composite_outside(hit.z);
                } else if let Some(c) = self.caster {
                    c.shade(ray, hit, out);
                }
                if out.comp.done {
                    return;
                }
            }
            if let Some((q, cover)) = q {
                out.comp
                    .sample(self.tf, q, (z0, z[s + 1]), ray.dlen * cover, min_t);
            }
            if out.comp.done {
                return;
            }
        }
    }

    /// The surfaces between slices s and s + 1 at (u, v), in depth order: linear
    /// interpolation of the iso field for the depth, the gradient interpolated likewise.
    fn crossings(
        &self,
        c: &SurfaceCaster,
        slab: &Slab,
        uv: (f64, f64),
        s: usize,
        hits: &mut Vec<Hit>,
    ) {
        hits.clear();
        if s + 1 >= slab.halo.end {
            return;
        }
        let f = |s| slab.lerp(true, self.layout, uv, s);
        let (Some(fa), Some(fb)) = (f(s), f(s + 1)) else {
            return;
        };
        let z = &self.depths.z;
        // The ends' gradients and rendered values, found once for all the values crossed.
        let mut ends = None;
        for &value in &c.surfaces.values {
            if (fa >= value) == (fb >= value) {
                continue;
            }
            let t = (value - fa) / (fb - fa);
            let ((ga, gb), (va, vb)) = *ends.get_or_insert_with(|| {
                let vol = |s| slab.lerp(false, self.layout, uv, s);
                let g = (self.gradient(slab, uv, s), self.gradient(slab, uv, s + 1));
                (g, (vol(s), vol(s + 1)))
            });
            hits.push(Hit {
                z: z[s] + t * (z[s + 1] - z[s]),
                gradient: [0, 1, 2].map(|a| ga[a] + t * (gb[a] - ga[a])),
                rising: fb >= value,
                rendered: match (va, vb) {
                    (Some(a), Some(b)) => Some(a + t * (b - a)),
                    (a, b) => a.or(b),
                },
            });
        }
        hits.sort_by(|a, b| a.z.total_cmp(&b.z));
    }

    /// The iso field's view-space gradient at (u, v), slice s: central differences between
    /// neighbouring columns at the slice's depth (x, y) and between neighbouring slices
    /// along the ray, less the lateral part of the ray's direction (z). One-sided at the
    /// grid's and the slab's edges; 0 where a neighbour is undefined.
    fn gradient(&self, slab: &Slab, (u, v): (f64, f64), s: usize) -> [f64; 3] {
        let l = self.layout;
        let f = |uv, s| slab.lerp(true, l, uv, s);
        let z = &self.depths.z;
        let (dx, dy) = l.spacing(z[s]);
        let diff = |a: Option<f64>, b: Option<f64>, span: f64| match (a, b) {
            (Some(a), Some(b)) if span > 0.0 => (b - a) / span,
            _ => 0.0,
        };
        let (ua, ub) = ((u - 1.0).max(0.0), (u + 1.0).min((l.cols - 1) as f64));
        let (va, vb) = ((v - 1.0).max(0.0), (v + 1.0).min((l.rows - 1) as f64));
        let gx = diff(f((ua, v), s), f((ub, v), s), (ub - ua) * dx);
        // Rows grow downward, view y upward.
        let gy = diff(f((u, vb), s), f((u, va), s), (vb - va) * dy);
        let (sa, sb) = (
            s.saturating_sub(1).max(slab.halo.start),
            (s + 1).min(slab.halo.end - 1),
        );
        let along = diff(f((u, v), sa), f((u, v), sb), z[sb] - z[sa]);
        // The column's ray through (u, v): its direction per unit of depth.
        let c = l.cell as f64;
        let ray = Ray::through_point(l.frame, u * c + 0.5 * c, v * c + 0.5 * c);
        [gx, gy, along - ray.d[0] * gx - ray.d[1] * gy]
    }
}

/// Writes the rays' pixels, depths (the first surface's with surfaces) and normals.
fn finish(image: &mut Image, stats: &mut RenderStats, rays: &[SurfaceRay], surfaces: bool) {
    let mut normals = vec![[0.0f32; 3]; if surfaces { rays.len() } else { 0 }];
    for (k, r) in rays.iter().enumerate() {
        let (rgba, depth) = r.comp.pixel();
        stats.samples += r.comp.samples;
        image.rgba[k] = rgba;
        image.depth[k] = depth;
        if surfaces {
            image.depth[k] = r.first.map_or(f32::INFINITY, |f| f.0);
            normals[k] = r.first.map_or([0.0; 3], |f| f.1);
        }
    }
    if surfaces {
        add_normal_aovs(image, &normals);
    }
}
