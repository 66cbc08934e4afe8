//! The sparse perspective view-aligned grid of Hochstetter et al. 2016 (Sec. 3, 6.1): the
//! particle access structure that both the grid renderer and its error analysis walk.
//!
//! Conventions: view space has the eye at the origin, +z along the camera's forward axis
//! (depths are positive), +x to the right and +y up (see [`fluidcast_view::ViewFrame`]).
//! The image is split into *ray bundles* of `D_xy × D_xy` pixels (bundle (0, 0) is the
//! top-left one); each bundle's frustum is cut along view depth into *cells* of `D_z`
//! consecutive depth samples of [`SampleDepths`] (logarithmically spaced, Eq. 8), which
//! makes cell `z` cover samples `z·D_z .. (z+1)·D_z`. A particle is referenced by every cell
//! whose bundle its screen-space support bound touches and whose depth samples its support
//! spans; only cells with at least one reference exist (implicit frustum culling).
//!
//! References are sorted by (bundle, cell depth, merge bit), where the merge bit (Sec. 6.2)
//! says the particle is referenced by the next cell in depth as well; a cell's references
//! with the bit clear come first, so the references of merged cells are contiguous runs.
#![warn(missing_docs)]

mod depths;
mod pairs;
mod sort;

use fluidcast_sph::Particles;
use fluidcast_view::ViewFrame;
use glam::DVec3;
use rayon::prelude::*;
use std::ops::Range;

use pairs::{bundle_offsets, chunk_count, Foot, Footprint};
use sort::sorted_cells;

pub use depths::{within, SampleDepths, MAX_SAMPLES};

/// Peak bytes per particle–cell pair while the grid is built (sort keys, references, the
/// sorted cells).
pub const PAIR_BYTES: u64 = 24;

/// Why a grid could not be built.
#[derive(Debug, thiserror::Error)]
pub enum GridError {
    /// A sampling scale that is not a finite number > 0.
    #[error("sampling scale {0} must be finite and > 0")]
    SamplingScale(f64),
    /// More depth samples per ray than the grid takes.
    #[error("the view needs {0} samples per ray (more than {MAX_SAMPLES}): the near plane is too close to the camera relative to the data; move the camera or lower the sampling scale")]
    TooManySamples(usize),
    /// A bundle size D_xy out of 1..=64 pixels.
    #[error("bundle size {0} must be 1..=64 pixels")]
    BundleSize(u32),
    /// D_z not a power of two in 1..=64.
    #[error("depth samples per cell {0} must be a power of two in 1..=64")]
    DepthSamples(u32),
    /// The grid would exceed the memory budget.
    #[error("{0}; use a smaller image or fewer, smaller particles in view")]
    Memory(#[from] fluidcast_mem::MemError),
    /// An image too large for 16-bit pixel rectangles (width, height).
    #[error("image size {0}x{1}: the grid holds pixel rectangles in 16 bits, at most {max} pixels a side", max = u16::MAX)]
    ImageSize(u32, u32),
}

/// A particle in view space (world units), as the renderers read it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViewParticle {
    /// Centre in view space.
    pub c: [f64; 3],
    /// Support radius H (the kernel is zero beyond it), volume V = m/ρ, the rendered
    /// quantity q and the mass m (for the density field): single precision as the particles
    /// hold them (16 bytes a particle less than doubles), read as doubles.
    pub h32: f32,
    /// See `h32`.
    pub v32: f32,
    /// See `h32`.
    pub a32: f32,
    /// See `h32`.
    pub m32: f32,
}

impl ViewParticle {
    /// A view-space particle from doubles (rounded to single precision, as particles are).
    pub fn new(c: [f64; 3], h: f64, v: f64, a: f64, m: f64) -> ViewParticle {
        ViewParticle {
            c,
            h32: h as f32,
            v32: v as f32,
            a32: a as f32,
            m32: m as f32,
        }
    }
    /// Support radius H (world units).
    #[inline]
    pub fn h(&self) -> f64 {
        f64::from(self.h32)
    }
    /// Volume V = m/ρ (world units³).
    #[inline]
    pub fn v(&self) -> f64 {
        f64::from(self.v32)
    }
    /// The rendered quantity q.
    #[inline]
    pub fn a(&self) -> f64 {
        f64::from(self.a32)
    }
    /// Mass m.
    #[inline]
    pub fn m(&self) -> f64 {
        f64::from(self.m32)
    }
}

/// All particles in view space and the depth range their supports occupy.
#[derive(Debug, Clone)]
pub struct ViewParticles {
    /// The particles in front of the camera, in view space.
    pub list: Vec<ViewParticle>,
    /// `[near, far]` in view depth, or `None` when nothing lies in front of the camera.
    pub range: Option<(f64, f64)>,
}

/// Particle `j` in view space.
pub fn view_particle(particles: &Particles, frame: &ViewFrame, j: usize) -> ViewParticle {
    let p = particles.positions[j];
    let v = frame.to_view(DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64));
    ViewParticle {
        c: v.to_array(),
        h32: particles.radii[j],
        v32: particles.volumes[j],
        a32: particles.values[j],
        m32: particles.masses[j],
    }
}

/// Transforms particles to view space and finds near/far: far is the largest depth of any
/// support, near the smallest (clamped to far·10⁻⁴ for a perspective view so that the log
/// spacing stays finite).
pub fn view_particles(particles: &Particles, frame: &ViewFrame) -> ViewParticles {
    let list: Vec<ViewParticle> = (0..particles.len())
        .into_par_iter()
        .map(|j| view_particle(particles, frame, j))
        .collect();
    let (zmin, zmax) = list
        .iter()
        .map(|p| (p.c[2] - p.h(), p.c[2] + p.h()))
        .fold((f64::INFINITY, f64::NEG_INFINITY), extent);
    let range = if list.is_empty() {
        None
    } else {
        depth_range(zmin, zmax, frame.parallel.is_none())
    };
    ViewParticles { list, range }
}

fn extent(a: (f64, f64), b: (f64, f64)) -> (f64, f64) {
    (a.0.min(b.0), a.1.max(b.1))
}

/// `[near, far]` of the particles' supports as [`view_particles`] finds it (the same f64
/// arithmetic, so the same sample depths), without keeping the view-space particles: what the
/// GPU grid places its depth samples by.
pub fn support_depth_range(particles: &Particles, frame: &ViewFrame) -> Option<(f64, f64)> {
    let (zmin, zmax) = support_depth_extent(particles, frame)?;
    depth_range(zmin, zmax, frame.parallel.is_none())
}

/// `[near, far]` the depth samples cover: over `support_depths` (`(zmin, zmax)` of a whole
/// data set these particles are part of, as [`support_depth_extent`] finds them, clamped as
/// [`depth_range`] clamps) when given, else `own()` (these particles' own range). One rule for
/// the CPU grid, the reference renderer and the GPU grid, which must sample alike.
pub fn sampled_range(
    frame: &ViewFrame,
    support_depths: Option<(f64, f64)>,
    own: impl FnOnce() -> Option<(f64, f64)>,
) -> Option<(f64, f64)> {
    match support_depths {
        Some((zmin, zmax)) => depth_range(zmin, zmax, frame.parallel.is_none()),
        None => own(),
    }
}

/// The smallest and largest view depth of any particle's support, `(zmin, zmax)` (the same f64
/// arithmetic as [`view_particles`]), before [`depth_range`] clamps them; `None` without
/// particles. Renderers that hold parts of one data set (MPI ranks) reduce these over all
/// parts and pass the result as `support_depths` so that all sample the same depths.
pub fn support_depth_extent(particles: &Particles, frame: &ViewFrame) -> Option<(f64, f64)> {
    if particles.is_empty() {
        return None;
    }
    let extent_of = (0..particles.len())
        .into_par_iter()
        .map(|j| {
            let p = particles.positions[j];
            let v = frame.to_view(DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64));
            let h = particles.radii[j] as f64;
            (v.z - h, v.z + h)
        })
        .reduce(|| (f64::INFINITY, f64::NEG_INFINITY), extent);
    Some(extent_of)
}

/// The pixels `[x0, x1, y0, y1]` (ends exclusive) of ray bundle `b` when a `width × height`
/// image is tiled row-major into bundles of `size × size` pixels, the last row and column
/// cut at the image's edge: the grid's, the plan's AOVs' and the depth stops' one layout.
pub fn bundle_pixels(width: u32, height: u32, size: u32, b: usize) -> [u32; 4] {
    let across = width.div_ceil(size).max(1);
    let (bx, by) = (b as u32 % across, b as u32 / across);
    [
        bx * size,
        ((bx + 1) * size).min(width),
        by * size,
        ((by + 1) * size).min(height),
    ]
}

/// The ray bundle that holds pixel (i, j) of a `width`-pixel-wide image tiled into bundles of
/// `size × size` pixels, as [`bundle_pixels`] lays them out.
pub fn bundle_of(width: u32, size: u32, i: u32, j: u32) -> usize {
    let size = size.max(1);
    (j / size * width.div_ceil(size) + i / size) as usize
}

/// `[near, far]` from the smallest and largest view depth of any support (`zmin`, `zmax`):
/// `None` when a perspective view has nothing in front of the camera; near is clamped to
/// far·10⁻⁴ for a perspective view so that the log spacing stays finite. Shared with the GPU
/// grid, which reduces zmin/zmax on the device.
pub fn depth_range(zmin: f64, zmax: f64, perspective: bool) -> Option<(f64, f64)> {
    if !(zmin.is_finite() && zmax.is_finite()) || (perspective && zmax <= 0.0) {
        None
    } else if perspective {
        Some((zmin.max(zmax * 1e-4), zmax))
    } else {
        Some((zmin, zmax))
    }
}

/// Pixel rectangle `[x0, x1) × [y0, y1)` (rows from the top) that contains every pixel
/// centre whose ray can pass through the particle's support, or `None` when the support is
/// off screen or outside `[near, far]`. Conservative: the support sphere's bounding box is
/// projected at its nearest and farthest depth ([`screen_extent`]), rounded out to whole
/// pixels.
pub fn screen_rect(frame: &ViewFrame, p: &ViewParticle, near: f64, far: f64) -> Option<[u32; 4]> {
    covering_rect(frame, screen_extent(frame, p, near, far)?)
}

/// [`screen_rect`] of a particle whose [`screen_extent`] is `extent`.
pub(crate) fn covering_rect(frame: &ViewFrame, [x0, x1, y0, y1]: [f64; 4]) -> Option<[u32; 4]> {
    let (w, h) = (frame.width as f64, frame.height as f64);
    let px0 = x0.floor().max(0.0);
    let px1 = x1.ceil().min(w);
    let py0 = y0.floor().max(0.0);
    let py1 = y1.ceil().min(h);
    if px0 >= px1 || py0 >= py1 {
        return None;
    }
    Some([px0 as u32, px1 as u32, py0 as u32, py1 as u32])
}

/// The pixels `[x0, x1) × [y0, y1)` whose centre lies in [`screen_extent`] (widened by a
/// millionth of a pixel against rounding): those whose ray can pass through the support, a
/// pixel's width tighter on each side than [`screen_rect`]. `None` where there are none.
pub fn centre_rect(frame: &ViewFrame, p: &ViewParticle, near: f64, far: f64) -> Option<[u32; 4]> {
    centres_in(frame, screen_extent(frame, p, near, far)?)
}

/// [`centre_rect`] of a particle whose [`screen_extent`] is `extent`.
fn centres_in(frame: &ViewFrame, [x0, x1, y0, y1]: [f64; 4]) -> Option<[u32; 4]> {
    const SLACK: f64 = 1e-6;
    let (w, h) = (frame.width as f64, frame.height as f64);
    // Pixel i's centre is i + ½: the first at or after e − ½ and the last at or before.
    let first = |e: f64, n: f64| (e - 0.5 - SLACK).ceil().clamp(0.0, n);
    let end = |e: f64, n: f64| ((e - 0.5 + SLACK).floor() + 1.0).clamp(0.0, n);
    let (px0, px1, py0, py1) = (first(x0, w), end(x1, w), first(y0, h), end(y1, h));
    if px0 >= px1 || py0 >= py1 {
        return None;
    }
    Some([px0 as u32, px1 as u32, py0 as u32, py1 as u32])
}

/// [`centre_rect`] as [`PerspectiveGrid::rects`] holds it: 16 bits a coordinate (the grid
/// refuses frames wider or taller than that), all zero where there are no pixels.
pub fn stored_rect(frame: &ViewFrame, p: &ViewParticle, near: f64, far: f64) -> [u16; 4] {
    stored(centre_rect(frame, p, near, far))
}

/// [`stored_rect`] of a particle whose [`screen_extent`] is `extent` (`None`: outside
/// `[near, far]`).
pub(crate) fn stored_centres(frame: &ViewFrame, extent: Option<[f64; 4]>) -> [u16; 4] {
    stored(extent.and_then(|e| centres_in(frame, e)))
}

fn stored(rect: Option<[u32; 4]>) -> [u16; 4] {
    rect.map_or([0; 4], |r| r.map(|v| v.min(u32::from(u16::MAX)) as u16))
}

/// The extent `[x0, x1] × [y0, y1]` in image coordinates (pixel units from the top-left
/// corner, unbounded) of a particle's support: its bounding box projected at its nearest
/// and farthest depth; infinite for a perspective view where the support reaches within
/// half the near depth of the eye. `None` when the support lies outside `[near, far]`.
pub fn screen_extent(frame: &ViewFrame, p: &ViewParticle, near: f64, far: f64) -> Option<[f64; 4]> {
    let [x, y, z] = p.c;
    if z + p.h() < near || z - p.h() > far {
        return None;
    }
    let (w, h) = (frame.width, frame.height);
    let (sx, sy) = match frame.parallel {
        Some(s) => (s * frame.aspect, s),
        None => (frame.tan_half * frame.aspect, frame.tan_half),
    };
    let (x0, x1, y0, y1) = match frame.parallel {
        None if z - p.h() <= near * 0.5 => {
            (-f64::INFINITY, f64::INFINITY, -f64::INFINITY, f64::INFINITY)
        }
        None => {
            // x/z over the box [x±h]×[z±h] (z > 0) is extreme at its corners.
            let zs = [z - p.h(), z + p.h()];
            let ext = |c: f64| {
                let v = [
                    (c - p.h()) / zs[0],
                    (c - p.h()) / zs[1],
                    (c + p.h()) / zs[0],
                    (c + p.h()) / zs[1],
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
        Some(_) => (x - p.h(), x + p.h(), y - p.h(), y + p.h()),
    };
    // NDC → pixel columns/rows (rows from the top).
    Some([
        (x0 / sx + 1.0) * 0.5 * w as f64,
        (x1 / sx + 1.0) * 0.5 * w as f64,
        (1.0 - y1 / sy) * 0.5 * h as f64,
        (1.0 - y0 / sy) * 0.5 * h as f64,
    ])
}

/// A viewing ray through a pixel centre, in view space: the point at view depth `z` is
/// `o + z·d` (d has a z component of 1, so `z` is depth, not distance).
#[derive(Debug, Clone, Copy)]
pub struct Ray {
    /// The ray's point at depth 0 (view space).
    pub o: [f64; 3],
    /// Direction per unit of depth (z component 1).
    pub d: [f64; 3],
    /// |d|², and |d| (world length of a unit of depth along the ray).
    pub dd: f64,
    /// See `dd`.
    pub dlen: f64,
}

impl Ray {
    /// The ray through the centre of pixel (i, j), j = 0 the top row.
    pub fn through_pixel(frame: &ViewFrame, i: u32, j: u32) -> Ray {
        Ray::through_point(frame, i as f64 + 0.5, j as f64 + 0.5)
    }

    /// The ray through image point (x, y) in pixel units from the top-left corner (the
    /// centre of pixel (i, j) is (i + ½, j + ½)).
    pub fn through_point(frame: &ViewFrame, x: f64, y: f64) -> Ray {
        let (x, y) = frame.ndc(x - 0.5, y - 0.5);
        let (o, d) = match frame.parallel {
            Some(s) => ([x * s * frame.aspect, y * s, 0.0], [0.0, 0.0, 1.0]),
            None => (
                [0.0; 3],
                [x * frame.tan_half * frame.aspect, y * frame.tan_half, 1.0],
            ),
        };
        let dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        Ray {
            o,
            d,
            dd,
            dlen: dd.sqrt(),
        }
    }

    /// The ray's closest approach to the particle centre: the view depth `t` where it is
    /// nearest and the squared distance `r²` there. Computed from the perpendicular offset,
    /// not from `|o − c|² − h²`, so it loses no digits to cancellation (the GPU's f32 mirror in
    /// raycast.wgsl uses the same form).
    #[inline]
    pub fn closest_approach(&self, p: &ViewParticle) -> (f64, f64) {
        let (o, d) = (self.o, self.d);
        let oc = [p.c[0] - o[0], p.c[1] - o[1], p.c[2] - o[2]];
        let t = (d[0] * oc[0] + d[1] * oc[1] + d[2] * oc[2]) / self.dd;
        let q = [oc[0] - t * d[0], oc[1] - t * d[1], oc[2] - t * d[2]];
        (t, q[0] * q[0] + q[1] * q[1] + q[2] * q[2])
    }

    /// The ray's passage through the particle's support, if it has one: the depth interval
    /// inside and the distances to the centre along it (the form raycast.wgsl mirrors).
    #[inline]
    pub fn passage(&self, p: &ViewParticle) -> Option<Passage> {
        let (t, r2) = self.closest_approach(p);
        let h2 = p.h() * p.h();
        if r2 >= h2 {
            return None;
        }
        let half = ((h2 - r2) / self.dd).sqrt();
        Some(Passage {
            z0: t - half,
            z1: t + half,
            t,
            r2,
            dd: self.dd,
        })
    }

    /// Distance from the ray's point at depth `z` to the particle centre.
    #[inline]
    pub fn distance_at(&self, z: f64, p: &ViewParticle) -> f64 {
        let q = [
            self.o[0] + z * self.d[0] - p.c[0],
            self.o[1] + z * self.d[1] - p.c[1],
            self.o[2] + z * self.d[2] - p.c[2],
        ];
        (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt()
    }
}

/// A ray inside a particle's support: from view depth `z0` to `z1`, nearest the centre at
/// depth `t` (squared distance `r2` there).
#[derive(Debug, Clone, Copy)]
pub struct Passage {
    /// View depth where the ray enters the support.
    pub z0: f64,
    /// View depth where it leaves.
    pub z1: f64,
    /// View depth of the closest approach to the centre.
    pub t: f64,
    /// Squared distance to the centre there (world units²).
    pub r2: f64,
    /// |d|² of the ray.
    dd: f64,
}

impl Passage {
    /// Distance from the ray's point at depth `z` to the particle centre.
    #[inline]
    pub fn distance_at(&self, z: f64) -> f64 {
        let dz = z - self.t;
        (self.r2 + self.dd * dz * dz).sqrt()
    }
}

/// The pixels of one ray bundle and the extent of its rays.
#[derive(Debug, Clone, Copy)]
pub struct Bundle {
    /// Pixel columns `[x0, x1)` and rows `[y0, y1)` (rows from the top).
    pub pixels: [u32; 4],
    /// Extremes of the ray parameters over the bundle's pixel centres: for a perspective
    /// view the direction's x and y (the point at depth z is (x·z, y·z, z)); for a parallel
    /// view the origin's x and y (the point is (x, y, z)).
    pub x: [f64; 2],
    /// See `x` (rows).
    pub y: [f64; 2],
    /// Whether the view is a parallel projection.
    pub parallel: bool,
    /// Smallest and largest |d| of the bundle's rays (world length per unit of depth).
    pub dlen: [f64; 2],
}

impl Bundle {
    /// The rays through the centres of pixels `[x0, x1) × [y0, y1)` (non-empty).
    pub fn from_pixels(f: &ViewFrame, px: [u32; 4]) -> Bundle {
        // Pixel-centre NDC extremes; j grows downwards, so y0 comes from the last row.
        let (nx0, ny1) = f.ndc(px[0] as f64, px[2] as f64);
        let (nx1, ny0) = f.ndc((px[1] - 1) as f64, (px[3] - 1) as f64);
        let (sx, sy) = match f.parallel {
            Some(s) => (s * f.aspect, s),
            None => (f.tan_half * f.aspect, f.tan_half),
        };
        let x = [nx0 * sx, nx1 * sx];
        let y = [ny0 * sy, ny1 * sy];
        let dlen = if f.parallel.is_some() {
            [1.0, 1.0]
        } else {
            let near = |r: [f64; 2]| {
                if r[0] <= 0.0 && r[1] >= 0.0 {
                    0.0
                } else {
                    r[0].abs().min(r[1].abs())
                }
            };
            let far = |r: [f64; 2]| r[0].abs().max(r[1].abs());
            [
                (1.0 + near(x).powi(2) + near(y).powi(2)).sqrt(),
                (1.0 + far(x).powi(2) + far(y).powi(2)).sqrt(),
            ]
        };
        Bundle {
            pixels: px,
            x,
            y,
            parallel: f.parallel.is_some(),
            dlen,
        }
    }

    /// Splits the bundle into up to `g × g` sub-bundles of whole pixels (fewer when it is
    /// narrower), row-major.
    pub fn split(&self, f: &ViewFrame, g: u32) -> Vec<Bundle> {
        let [x0, x1, y0, y1] = self.pixels;
        let (gx, gy) = (g.min(x1 - x0), g.min(y1 - y0));
        let cut = |a: u32, n: u32, g: u32, i: u32| a + i * n / g;
        let mut out = Vec::with_capacity((gx * gy) as usize);
        for v in 0..gy {
            for u in 0..gx {
                out.push(Bundle::from_pixels(
                    f,
                    [
                        cut(x0, x1 - x0, gx, u),
                        cut(x0, x1 - x0, gx, u + 1),
                        cut(y0, y1 - y0, gy, v),
                        cut(y0, y1 - y0, gy, v + 1),
                    ],
                ));
            }
        }
        out
    }

    /// The rectangle `[x0, x1] × [y0, y1]` in the plane of view depth `z` that holds the
    /// points of all the bundle's rays at that depth.
    #[inline]
    pub fn rect_at(&self, z: f64) -> [f64; 4] {
        if self.parallel {
            [self.x[0], self.x[1], self.y[0], self.y[1]]
        } else {
            [self.x[0] * z, self.x[1] * z, self.y[0] * z, self.y[1] * z]
        }
    }

    /// True when every ray of the bundle is strictly inside the particle's support at depth
    /// `z`, so a sample there is never empty. The support's cross-section is a disc and the
    /// bundle's a rectangle: both convex, so testing the four corners suffices.
    #[inline]
    pub fn covered_by(&self, p: &ViewParticle, z: f64) -> bool {
        let [x0, x1, y0, y1] = self.rect_at(z);
        let dz = z - p.c[2];
        let lim = (p.h() * p.h() - dz * dz) * COVER_MARGIN;
        if lim <= 0.0 {
            return false;
        }
        let fx = (x0 - p.c[0]).abs().max((x1 - p.c[0]).abs());
        let fy = (y0 - p.c[1]).abs().max((y1 - p.c[1]).abs());
        fx * fx + fy * fy < lim
    }
}

/// The share of a particle's squared disc radius (at a depth) within which a ray counts as
/// covered ([`Bundle::covered_by`], and the sampling plan's coverage test): a relative margin
/// of 1e-9, so that rounding never claims a covered ray that is not.
pub const COVER_MARGIN: f64 = 1.0 - 1e-9;

/// A non-empty cell: its depth index and its references into [`PerspectiveGrid::refs`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Cell {
    /// Cell depth index: the cell covers samples `z·D_z .. (z+1)·D_z`.
    pub z: u32,
    /// References `start..end`; those in `unique_end..end` are also referenced by the cell
    /// at depth `z + 1` of the same bundle (the merge bit is set).
    pub start: u32,
    /// See `start`.
    pub unique_end: u32,
    /// See `start`.
    pub end: u32,
}

/// The ranges of [`PerspectiveGrid::refs`] a run of consecutive cells `cells` reads as one
/// ([`PerspectiveGrid::merged_refs`]): each cell's, less the references the next cell
/// repeats (the merge bit).
pub fn merged_ranges(cells: &[Cell]) -> impl Iterator<Item = Range<usize>> + '_ {
    let last = cells.len().saturating_sub(1);
    cells.iter().enumerate().map(move |(i, c)| {
        let end = if i == last { c.end } else { c.unique_end };
        c.start as usize..end as usize
    })
}

/// How many references [`PerspectiveGrid::merged_refs`] yields for `cells`, without reading
/// them.
pub fn merged_ref_count(cells: &[Cell]) -> usize {
    merged_ranges(cells).map(|r| r.len()).sum()
}

/// Grid resolution: bundle size D_xy in pixels and depth samples per cell D_z.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GridParams {
    /// Bundle side D_xy, pixels (1..=64).
    pub bundle: u32,
    /// Depth samples per cell D_z (a power of two, 1..=64).
    pub depth_samples: u32,
}

impl Default for GridParams {
    /// The paper's D_xy = 8, D_z = 16.
    fn default() -> Self {
        GridParams {
            bundle: 8,
            depth_samples: 16,
        }
    }
}

impl GridParams {
    /// Checks the ranges; D_z must be a power of two (sampling levels halve it).
    pub fn validate(&self) -> Result<(), GridError> {
        if !(1..=64).contains(&self.bundle) {
            return Err(GridError::BundleSize(self.bundle));
        }
        if !(1..=64).contains(&self.depth_samples) || !self.depth_samples.is_power_of_two() {
            return Err(GridError::DepthSamples(self.depth_samples));
        }
        Ok(())
    }

    /// The coarsest sampling level, log2 D_z.
    pub fn max_level(&self) -> u32 {
        self.depth_samples.trailing_zeros()
    }
}

/// The sparse perspective grid of one view.
#[derive(Debug, Clone)]
pub struct PerspectiveGrid {
    /// The view the grid was built for.
    pub frame: ViewFrame,
    /// Bundle size and depth samples per cell.
    pub params: GridParams,
    /// Depth samples; `None` when nothing is in front of the camera (then there are no cells).
    pub depths: Option<SampleDepths>,
    /// Bundles across and down (M_x, M_y) and cells along depth (M_z).
    pub bundles_x: u32,
    /// See `bundles_x`.
    pub bundles_y: u32,
    /// See `bundles_x`.
    pub cells_z: u32,
    /// The particles in view space; references index them.
    pub particles: Vec<ViewParticle>,
    /// Per particle, the pixels whose ray can enter its support, `[x0, x1) × [y0, y1)`
    /// ([`stored_rect`]; all zero where there are none). The ray caster cuts a bundle's
    /// columns and rows out of it (integer work) instead of projecting the support onto the
    /// bundle's rays for every bundle, span and pass.
    pub rects: Vec<[u16; 4]>,
    /// Particles whose support touches at least one cell.
    pub particles_visible: usize,
    /// Particle indices, grouped by cell.
    pub refs: Vec<u32>,
    /// Non-empty cells, grouped by bundle, front to back within a bundle.
    pub cells: Vec<Cell>,
    /// Bundle `b`'s cells are `cells[bundle_cells[b]..bundle_cells[b+1]]` (the first/last cell
    /// table of Sec. 6.1).
    bundle_cells: Vec<u32>,
}

impl PerspectiveGrid {
    /// Builds the grid from raw particles for one view (Sec. 6.1). `sampling_scale`
    /// multiplies the number of depth samples (see [`SampleDepths::new`]).
    pub fn build(
        particles: &Particles,
        frame: &ViewFrame,
        params: GridParams,
        sampling_scale: f64,
    ) -> Result<PerspectiveGrid, GridError> {
        PerspectiveGrid::build_within(particles, frame, params, sampling_scale, None)
    }

    /// The grid of `particles` for `frame` with no cells yet (and no depths: nothing reaches
    /// a depth sample until they are placed).
    fn empty(
        frame: &ViewFrame,
        params: GridParams,
        particles: Vec<ViewParticle>,
    ) -> PerspectiveGrid {
        let d = params.bundle;
        let (bx, by) = (frame.width.div_ceil(d), frame.height.div_ceil(d));
        let nb = (bx * by) as usize;
        PerspectiveGrid {
            frame: *frame,
            params,
            depths: None,
            bundles_x: bx,
            bundles_y: by,
            cells_z: 0,
            particles,
            rects: Vec::new(),
            particles_visible: 0,
            refs: Vec::new(),
            cells: Vec::new(),
            bundle_cells: vec![0; nb + 1],
        }
    }

    /// [`PerspectiveGrid::build`] with the depth samples placed over `support_depths`
    /// (`(zmin, zmax)` as [`support_depth_extent`] finds them, of a whole data set these
    /// particles are part of) instead of over these particles' own.
    pub fn build_within(
        particles: &Particles,
        frame: &ViewFrame,
        params: GridParams,
        sampling_scale: f64,
        support_depths: Option<(f64, f64)>,
    ) -> Result<PerspectiveGrid, GridError> {
        params.validate()?;
        if frame.width > u32::from(u16::MAX) || frame.height > u32::from(u16::MAX) {
            return Err(GridError::ImageSize(frame.width, frame.height));
        }
        let mut vp = view_particles(particles, frame);
        let own = vp.range;
        vp.range = sampled_range(frame, support_depths, || own);
        let d = params.bundle;
        let mut grid = PerspectiveGrid::empty(frame, params, vp.list);
        let (bx, nb) = (grid.bundles_x, grid.bundle_count());
        let Some((near, far)) = vp.range else {
            return Ok(grid);
        };
        let dz = params.depth_samples as usize;
        let depths = SampleDepths::new(frame, near, far, sampling_scale, dz)?;
        grid.cells_z = (depths.len() / dz) as u32;
        let fp = Footprint {
            frame,
            depths: &depths,
            range: (near, far),
            bundle: d,
            dz,
            bundles_x: bx,
        };
        // Each particle's stored pixel rectangle and footprint, from one projection.
        let (rects, feet): (Vec<[u16; 4]>, Vec<Foot>) =
            grid.particles.par_iter().map(|p| fp.place(p)).unzip();
        grid.rects = rects;
        // Counting sort of the (bundle, cell, merge bit, particle) pairs by bundle, the
        // particles in chunks counted in parallel: each chunk writes its pairs from its own
        // start in each bundle, so the pairs lie in particle order as a sequential pass puts
        // them.
        let n = grid.particles.len();
        let chunk_len = n.div_ceil(chunk_count(n, nb)).max(1);
        let (counts, visible) = fp.count(&feet, chunk_len, nb);
        grid.particles_visible = visible;
        let offsets = bundle_offsets(&counts, nb);
        // Keys now, then references and the sorted copy: refused before allocating when the
        // view's particle–cell pairs would not fit.
        let pairs = offsets[nb] as u64;
        fluidcast_mem::check(
            || {
                format!(
                    "the perspective grid's {pairs} particle–cell pairs at {}x{}",
                    frame.width, frame.height
                )
            },
            pairs.saturating_mul(PAIR_BYTES),
        )?;
        let mut keys = fp.keys(&feet, chunk_len, counts, offsets[nb]);
        drop(feet);
        let per_bundle = sorted_cells(&mut keys, &offsets);
        grid.refs = keys.iter().map(|&k| k as u32).collect();
        grid.cells.reserve(per_bundle.iter().map(Vec::len).sum());
        for (b, c) in per_bundle.into_iter().enumerate() {
            grid.cells.extend(c);
            grid.bundle_cells[b + 1] = grid.cells.len() as u32;
        }
        grid.depths = Some(depths);
        Ok(grid)
    }

    /// Number of ray bundles (M_x · M_y).
    pub fn bundle_count(&self) -> usize {
        (self.bundles_x * self.bundles_y) as usize
    }

    /// Bundle `b`'s pixels and ray extents.
    pub fn bundle(&self, b: usize) -> Bundle {
        let (w, h) = (self.frame.width, self.frame.height);
        Bundle::from_pixels(&self.frame, bundle_pixels(w, h, self.params.bundle, b))
    }

    /// The cells of bundle `b`, front to back.
    pub fn bundle_cells(&self, b: usize) -> &[Cell] {
        &self.cells[self.bundle_cells[b] as usize..self.bundle_cells[b + 1] as usize]
    }

    /// Index in [`PerspectiveGrid::cells`] of bundle `b`'s first cell.
    pub fn bundle_first_cell(&self, b: usize) -> usize {
        self.bundle_cells[b] as usize
    }

    /// The particles referenced by a run of consecutive cells `cells` (a merged cell),
    /// each once: the merge bit drops the references the next cell repeats.
    pub fn merged_refs<'a>(&'a self, cells: &'a [Cell]) -> impl Iterator<Item = u32> + 'a {
        merged_ranges(cells).flat_map(move |r| self.refs[r].iter().copied())
    }

    /// Total particle–cell pairs.
    pub fn pairs(&self) -> usize {
        self.refs.len()
    }
}

#[cfg(test)]
mod tests;
