//! Image-space refinement of the relaxed mode (beyond the paper, after Levoy's "Volume
//! rendering by adaptive refinement", 1990): the grid renderer casts every second pixel of
//! every second row first (the lattice, a quarter of the rays), fills the pixels between
//! lattice pixels by interpolation where the image is smooth there, and casts the others.
//!
//! 1. **Lattice.** Pixels with an even column and an even row.
//! 2. **Estimate.** A pixel between lattice pixels takes the cubic (Catmull–Rom) midpoint of
//!    the four lattice pixels on its line, `(−p₀ + 9p₁ + 9p₂ − p₃) / 16`, in both directions
//!    for a pixel between four (bicubic over 4 × 4). It is accepted when, along every line of
//!    its stencil and in every channel, both second differences `p₀ − 2p₁ + p₂` and
//!    `p₁ − 2p₂ + p₃` are at most 8 · [`ESTIMATE_SHARE`] · E_I: the linear midpoint errs by
//!    about an eighth of them on a smooth image, and the cubic by less. A step between p₁ and
//!    p₂ makes both large (their sum, the cubic's correction alone, cancels there). Pixels
//!    are cast at the image's edge, where the depth at half opacity steps between stencil
//!    pixels by more than [`MAX_SLOPE`] lateral pixel footprints per pixel (a grazing
//!    surface) or is reached on one side only (a silhouette), and where a nearest neighbour's
//!    depth range differs (opaque geometry, a cropping box).
//! 3. **Second pass.** The pixels not accepted are cast, and all of a bundle's pixels between
//!    lattice pixels where fewer than [`MIN_ACCEPTED_SHARE`] of them were accepted.
//! 4. **Recheck.** Where a pixel of the second pass misses its own interpolation by more than
//!    its stencil predicted (an eighth of its largest second difference) plus
//!    [`SURPRISE_SHARE`] · E_I, the image holds detail the lattice does not see: the accepted
//!    pixels within [`RECHECK_RADIUS`] are cast in a third pass. (A pixel rejected for a large
//!    second difference misses by about that much: the lattice saw that detail.)
//!
//! The lattice sees only what passes between its pixels' rays: a particle whose projected
//! support is narrower than its spacing can fall between them, so the refinement is off for a
//! view whose smallest projected support radius is below [`MIN_FOOTPRINT_PX`]. It is a
//! heuristic, like the relaxed plan it belongs to: measured against full rate (the 0.05 %
//! rule), not guaranteed; `--strict` never interpolates.
//!
//! The passes run the same ray casting stage (`render_adaptive`'s on the CPU, `fluidcast-gpu`'s
//! on the GPU) on the same grid and plan: a pixel not to be cast gets an empty depth range
//! ([`RenderParams::depth_range_at`]), which both casters skip, and the CPU packs the rays it
//! casts densely into its SIMD lanes, so that a pass costs what its rays cost.

use std::sync::Arc;
use std::time::Instant;

use fluidcast_image::Image;
use fluidcast_sph::Particles;
use fluidcast_view::ViewFrame;
use glam::DVec3;
use rayon::prelude::*;

use crate::RenderParams;

/// The smallest projected support radius, in pixels, of any particle in view for which the
/// refinement runs. A support this wide covers lattice pixels near its centre (the lattice's
/// spacing is 2 pixels). Below it too few pixels are smooth enough to pay for the passes: a
/// 227k-particle dam break at 512 × 384 (3.6 px) took 9.07 G instructions with the refinement
/// and 7.78 G without (callgrind); at 1024 × 768 (7.2 px) 22.3 G against 28.0 G.
pub const MIN_FOOTPRINT_PX: f64 = 5.0;

/// The steepest surface, as depth per lateral distance, between stencil pixels (depths at
/// half opacity) that is interpolated: about 72° from facing the camera. Grazing views of
/// the hard-edged union of supports vary faster than the lattice can see.
pub const MAX_SLOPE: f64 = 3.0;

/// How far, as a share of E_I, a cast pixel's value may miss its interpolation beyond what
/// its stencil predicted before the accepted pixels around it are cast as well. On a
/// 227k-particle dam break (t = 0.4 s, 1024 × 768, velocity), counting the predicted miss
/// as a surprise too rechecked 17,248 pixels and left 0.0036 % of the pixels above E_I;
/// not counting it, 6,738 and 0.012 % (the rule allows 0.05 %).
pub const SURPRISE_SHARE: f64 = 0.5;

/// The distance, in pixels, around a surprise within which accepted pixels are cast.
pub const RECHECK_RADIUS: u32 = 2;

/// The error, as a share of E_I, that the linear midpoint may be estimated to make (an eighth
/// of the largest second difference in the stencil) for the interpolation to be accepted.
/// 0.5 made 0.05 % of the pixels of a 227k-particle dam break miss E_I (and 0.15 % of the
/// checker board test's); 0.25 makes 0.004 % (0.012 %).
pub const ESTIMATE_SHARE: f64 = 0.25;

/// The share of a bundle's pixels between lattice pixels whose estimates must be accepted
/// for any of them to be interpolated; below it the bundle casts them all in the second
/// pass. Where few estimates are accepted the lattice misses detail, and most of those few
/// are cast again by the recheck, in a pass that traverses the bundle's cells for a handful
/// of rays: on a 42k-particle dam break at 1024 × 768, bundles below a quarter accepted 944
/// estimates and rechecked 655 of them; bundles above three quarters rechecked 295 of
/// 11,377. Chosen on the scenes developed on (callgrind, one thread, instructions against
/// no such rule): 42k dam break −1.4 % at 1024 × 768 and −0.9 % at 1920 × 1080, PySPH 24k
/// +0.05 % at 1024 × 768; a share of ½ cost +0.4 %, +1.4 % and +1.6 %.
pub const MIN_ACCEPTED_SHARE: f64 = 0.25;

/// Which bundles to refine, from the plan's summaries: those whose first (front-most) cell is
/// sampled ([`fluidcast_plan::BundleSummary::front_sampled`]). Rays spend their work in the
/// first cells of opaque fluid; where the plan made the front a super-pixel (a uniform phase
/// by `phase_id`, empty space) casting is already cheap and the passes cost more than
/// interpolation saves. The others are cast whole in the first pass. On a 285k-particle
/// three-phase dam break (t = 0.4 s, 1024 × 768, callgrind, full rate 25.8 G instructions by
/// velocity and 21.6 G by `phase_id`): refining every bundle took 19.5 G and 9.18 G, bundles
/// with more than half their cells at full rate 20.0 G and 8.82 G, bundles with a sampled
/// front 18.7 G and 8.47 G.
pub fn refined_bundles(summaries: &[fluidcast_plan::BundleSummary]) -> Vec<bool> {
    summaries.iter().map(|s| s.front_sampled > 0.5).collect()
}

/// What the refinement did, in pixels: cast in the first pass (`lattice`: the lattice, and the
/// bundles not refined), cast in the second and third (of which `rechecked` in the third),
/// and interpolated. They add up to the image. `stages`: milliseconds of each pass and of the
/// interpolation between them (`lattice`, `estimate`, `second`, `recheck`), as
/// [`crate::RenderStats::stages`] lists them.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Refined {
    /// Pixels of the first pass's lattice.
    pub lattice: u64,
    /// Pixels cast in the second pass.
    pub cast: u64,
    /// Interpolated pixels cast again where their neighbours disagreed.
    pub rechecked: u64,
    /// Pixels interpolated.
    pub interpolated: u64,
    /// Milliseconds of each pass (see above).
    pub stages: Vec<(&'static str, f64)>,
}

/// True for the pixels of the first pass: even column and even row.
#[inline]
pub fn on_lattice(i: u32, j: u32) -> bool {
    i.is_multiple_of(2) && j.is_multiple_of(2)
}

/// Whether a view gets the refinement: a relaxed adaptive plan with it on
/// ([`fluidcast_plan::PlanParams::interpolate`]), an image of at least 8 × 8 pixels, and no
/// particle in view whose projected support radius is below [`MIN_FOOTPRINT_PX`].
pub fn applies(particles: &Particles, frame: &ViewFrame, params: &RenderParams) -> bool {
    let a = &params.adaptive;
    let relaxed = a.tolerance.is_some() && a.relax > 0.0 && a.interpolate;
    relaxed
        && params.width >= 8
        && params.height >= 8
        && smallest_footprint_px(particles, frame) >= MIN_FOOTPRINT_PX
}

/// The smallest projected support radius in pixels (at the support's far side) over the
/// particles whose support reaches in front of the camera and into the image; `+∞` when none
/// does.
pub fn smallest_footprint_px(particles: &Particles, frame: &ViewFrame) -> f64 {
    let (w, h) = (f64::from(frame.width), f64::from(frame.height));
    (0..particles.len())
        .into_par_iter()
        .map(|k| {
            let p = DVec3::from(particles.positions[k].map(f64::from));
            let big_h = f64::from(particles.radii[k]);
            let v = frame.to_view(p);
            let far = v.z + big_h;
            if frame.parallel.is_none() && far <= 0.0 {
                return f64::INFINITY;
            }
            let r = big_h / frame.pixel_size_at(far);
            let in_image = frame
                .project_view(v)
                .is_some_and(|(x, y)| x >= -r && x <= w + r && y >= -r && y <= h + r);
            // A support around the eye (centre behind it) is wide on screen, not small.
            if in_image || v.z <= 0.0 {
                r
            } else {
                f64::INFINITY
            }
        })
        .reduce(|| f64::INFINITY, f64::min)
}

/// `params` with every pixel not in `cast` given an empty depth range, so that a ray caster
/// casts exactly the pixels of `cast` (row-major, one per pixel).
pub fn pass_params(params: &RenderParams, cast: &[bool]) -> RenderParams {
    let limits = per_pixel(params.width, params.height, |k, i, j| match cast[k] {
        true => params.depth_limit_at(i, j) as f32,
        false => f32::NEG_INFINITY,
    });
    RenderParams {
        depth_limit: Some(Arc::from(limits)),
        ..params.clone()
    }
}

/// `f(k, i, j)` for every pixel (i, j) of a `w` × `h` image, `k` its row-major index, in
/// row-major order, rows in parallel: the whole-image masks of the passes without the two
/// integer divisions per pixel that finding (i, j) from `k` takes (a third of their time at
/// 1920 × 1080).
fn per_pixel<T: Copy + Default + Send>(
    w: u32,
    h: u32,
    f: impl Fn(usize, u32, u32) -> T + Sync,
) -> Vec<T> {
    let mut out = vec![T::default(); w as usize * h as usize];
    if w == 0 {
        return out;
    }
    out.par_chunks_mut(w as usize)
        .enumerate()
        .for_each(|(j, row)| {
            let k0 = j * w as usize;
            for (i, v) in row.iter_mut().enumerate() {
                *v = f(k0 + i, i as u32, j as u32);
            }
        });
    out
}

/// One lattice line of a stencil: its column (or row), Catmull–Rom weight, and whether it is
/// a nearest neighbour of the pixel.
type Tap = (u32, f64, bool);

/// The lattice lines a pixel at column (or row) `c` of `n` reads: `c` itself on a lattice
/// line, else the two on each side (`None` when they are not all inside the image); the
/// first `len` of the array.
fn taps(c: u32, n: u32) -> Option<([Tap; 4], usize)> {
    if c.is_multiple_of(2) {
        return Some(([(c, 1.0, true); 4], 1));
    }
    let lo = c.checked_sub(3)?;
    (c + 3 < n).then_some((
        [
            (lo, -1.0 / 16.0, false),
            (c - 1, 9.0 / 16.0, true),
            (c + 1, 9.0 / 16.0, true),
            (c + 3, -1.0 / 16.0, false),
        ],
        4,
    ))
}

/// The larger second difference |p₀ − 2p₁ + p₂|, |p₁ − 2p₂ + p₃| of four lattice values
/// along a line, over the channels. The linear midpoint of p₁ and p₂ errs by about an eighth
/// of it on a smooth image; a step between p₁ and p₂ makes both large (their sum, the
/// cubic's correction, cancels there).
fn second_difference(p: [&[f64; 4]; 4]) -> f64 {
    (0..4)
        .map(|c| {
            let d1 = p[0][c] - 2.0 * p[1][c] + p[2][c];
            let d2 = p[1][c] - 2.0 * p[2][c] + p[3][c];
            d1.abs().max(d2.abs())
        })
        .fold(0.0, f64::max)
}

/// A pixel's interpolation from the lattice: premultiplied RGBA and depth, and whether the
/// checks accept it in place of casting.
#[derive(Debug, Clone, Copy)]
struct Estimate {
    rgba: [f32; 4],
    z: f32,
    /// The error the stencil predicts: an eighth of its largest second difference.
    predicted: f64,
    accept: bool,
}

/// A pixel between lattice pixels: its interpolation, or `None` where there is none (the
/// stencil leaves the image, or a neighbour's depth range differs). `first` holds the lattice
/// pixels; `tolerance` is E_I.
fn interpolate(
    first: &Image,
    params: &RenderParams,
    frame: &ViewFrame,
    tolerance: f64,
    (i, j): (u32, u32),
) -> Option<Estimate> {
    let ((xt, nx), (yt, ny)) = (taps(i, first.width)?, taps(j, first.height)?);
    let (xs, ys) = (&xt[..nx], &yt[..ny]);
    let range = params.depth_range_at(i, j);
    // The stencil's lattice values, row by row.
    let mut v = [[[0.0f64; 4]; 4]; 4];
    let mut z = [[0.0f64; 4]; 4];
    let mut cubic = [0.0f64; 4];
    let (mut depth, mut near, mut empty) = (0.0f64, 0u32, 0u32);
    for (r, &(y, cy, near_y)) in ys.iter().enumerate() {
        for (k, &(x, cx, near_x)) in xs.iter().enumerate() {
            let idx = first.index(x, y);
            v[r][k] = first.rgba[idx].map(f64::from);
            z[r][k] = f64::from(first.depth[idx]);
            for c in 0..4 {
                cubic[c] += cx * cy * v[r][k][c];
            }
            if near_x && near_y {
                // A nearest neighbour: it must see the same depth range as the pixel.
                if params.depth_range_at(x, y) != range {
                    return None;
                }
                near += 1;
                match first.depth[idx] {
                    z if z.is_finite() => depth += f64::from(z),
                    _ => empty += 1,
                }
            }
        }
    }
    // The largest second difference along the stencil's rows and columns.
    let along_rows = (0..ys.len())
        .filter(|_| xs.len() == 4)
        .map(|r| second_difference([&v[r][0], &v[r][1], &v[r][2], &v[r][3]]));
    let along_cols = (0..xs.len())
        .filter(|_| ys.len() == 4)
        .map(|k| second_difference([&v[0][k], &v[1][k], &v[2][k], &v[3][k]]));
    let curvature = along_rows.chain(along_cols).fold(0.0, f64::max);
    // Steepness: the largest depth step between neighbouring stencil pixels, in pixel
    // footprints (2 per step at an inclination of 45°); a finite depth next to an infinite one
    // is a silhouette.
    let steps_x = (0..ys.len()).flat_map(|r| (1..xs.len()).map(move |k| (z[r][k - 1], z[r][k])));
    let steps_y = (0..xs.len()).flat_map(|k| (1..ys.len()).map(move |r| (z[r - 1][k], z[r][k])));
    let steep = steps_x
        .chain(steps_y)
        .any(|(a, b)| match (a.is_finite(), b.is_finite()) {
            (true, true) => (b - a).abs() > 2.0 * MAX_SLOPE * frame.pixel_size_at(a.min(b)),
            (false, false) => false,
            _ => true,
        });
    // A steep surface (a silhouette included: half opacity reached on one side only), or an
    // estimate above the share of E_I: cast.
    let curved = curvature / 8.0 > ESTIMATE_SHARE * tolerance;
    let [r, g, b, a] = cubic;
    Some(Estimate {
        rgba: [r.max(0.0), g.max(0.0), b.max(0.0), a.clamp(0.0, 1.0)].map(|v| v as f32),
        z: match empty {
            0 => (depth / f64::from(near)) as f32,
            _ => f32::INFINITY,
        },
        predicted: curvature / 8.0,
        accept: !(steep || curved),
    })
}

/// The pixels the first pass did not cast (`cast`; row-major), each with its interpolation
/// from the lattice pixels of `first` (`None` where there is none), in pixel order: only the
/// pixels between lattice pixels of refined bundles, where one estimate per pixel of the
/// image took 40 bytes a pixel (31 MB at 1024 × 768, written and paged in on every view).
fn estimates(
    first: &Image,
    cast: &[bool],
    params: &RenderParams,
    frame: &ViewFrame,
    tolerance: f64,
) -> Vec<(usize, Option<Estimate>)> {
    let w = first.width as usize;
    cast.par_iter()
        .enumerate()
        .filter(|(_, &c)| !c)
        .map(|(k, _)| {
            let (i, j) = ((k % w) as u32, (k / w) as u32);
            (k, interpolate(first, params, frame, tolerance, (i, j)))
        })
        .collect()
}

/// The pixels whose interpolation is accepted, row-major: those `est` accepts, except in a
/// bundle where they are fewer than [`MIN_ACCEPTED_SHARE`] of its pixels between lattice
/// pixels, which casts them all in the second pass.
fn accepted_in_smooth_bundles(
    est: &[(usize, Option<Estimate>)],
    params: &RenderParams,
    n: usize,
) -> Vec<bool> {
    let (w, size) = (params.width, params.grid.bundle);
    let bundle = |idx: usize| {
        let (i, j) = ((idx % w as usize) as u32, (idx / w as usize) as u32);
        fluidcast_grid::bundle_of(w, size, i, j)
    };
    let last = (w.saturating_sub(1), params.height.saturating_sub(1));
    let bundles = fluidcast_grid::bundle_of(w, size, last.0, last.1) + 1;
    // Per bundle: pixels between lattice pixels, and those accepted.
    let mut counts = vec![(0u32, 0u32); bundles];
    for &(idx, e) in est {
        let c = &mut counts[bundle(idx)];
        c.0 += 1;
        c.1 += u32::from(e.is_some_and(|e| e.accept));
    }
    let mut accepted = vec![false; n];
    for &(idx, e) in est {
        let (all, ok) = counts[bundle(idx)];
        accepted[idx] =
            e.is_some_and(|e| e.accept) && f64::from(ok) >= MIN_ACCEPTED_SHARE * f64::from(all);
    }
    accepted
}

/// Pixels cast in the second pass (`cast`) whose interpolation (`est`) missed their cast
/// value in `image` by more than its stencil predicted plus [`SURPRISE_SHARE`] · E_I in some
/// channel: evidence of detail the lattice does not see. (A pixel rejected for a large
/// second difference was expected to miss by about as much: the lattice saw that detail.)
fn surprises(
    image: &Image,
    cast: &[bool],
    est: &[(usize, Option<Estimate>)],
    tolerance: f64,
) -> Vec<bool> {
    let mut surprise = vec![false; cast.len()];
    for &(idx, e) in est {
        surprise[idx] = cast[idx]
            && e.is_some_and(|e| {
                let limit = e.predicted + SURPRISE_SHARE * tolerance;
                (0..4).any(|c| f64::from((image.rgba[idx][c] - e.rgba[c]).abs()) > limit)
            });
    }
    surprise
}

/// The accepted pixels within [`RECHECK_RADIUS`] (Chebyshev distance) of a surprise.
fn near_surprises(surprise: &[bool], accepted: &[bool], w: u32, h: u32) -> Vec<bool> {
    let r = RECHECK_RADIUS;
    let mut out = vec![false; surprise.len()];
    for (idx, _) in surprise.iter().enumerate().filter(|(_, &s)| s) {
        let (i, j) = ((idx % w as usize) as u32, (idx / w as usize) as u32);
        for y in j.saturating_sub(r)..(j + r + 1).min(h) {
            for x in i.saturating_sub(r)..(i + r + 1).min(w) {
                let k = y as usize * w as usize + x as usize;
                out[k] |= accepted[k];
            }
        }
    }
    out
}

/// Copies the pixels of `from` that `params` casts (those whose depth range is not empty)
/// into `to`: for a ray casting stage that fills a whole image per pass (the GPU's), what
/// [`cast_refined`] asks of a pass.
pub fn keep_cast_pixels(params: &RenderParams, from: &Image, to: &mut Image) {
    let w = params.width as usize;
    to.rgba
        .par_iter_mut()
        .zip(to.depth.par_iter_mut())
        .enumerate()
        .for_each(|(k, (rgba, depth))| {
            let (near, far) = params.depth_range_at((k % w) as u32, (k / w) as u32);
            if near < far {
                (*rgba, *depth) = (from.rgba[k], from.depth[k]);
            }
        });
}

/// Casts a view in up to three passes (see the module) into `image`, empty at the start:
/// `cast` is the ray casting stage for the given parameters, which writes the pixels whose
/// depth range is not empty (it may skip those whose rays meet no particle, which `image`
/// already holds) and leaves the others as they are, so that the passes fill one image;
/// `tolerance` is E_I. Returns what was cast and interpolated.
pub fn cast_refined<E>(
    params: &RenderParams,
    frame: &ViewFrame,
    tolerance: f64,
    refined: &[bool],
    image: &mut Image,
    mut cast: impl FnMut(&RenderParams, &mut Image) -> Result<(), E>,
) -> Result<Refined, E> {
    let (w, h) = (params.width, params.height);
    let n = w as usize * h as usize;
    // The first pass: the lattice, and every pixel of a bundle not refined.
    // The bundle column of each image column (`bundle_of` without its divisions per pixel).
    let d = params.grid.bundle.max(1);
    let (columns, per_row) = ((0..w).map(|i| i / d).collect::<Vec<u32>>(), w.div_ceil(d));
    let in_refined = |i: u32, j: u32| {
        let b = (j / d * per_row + columns[i as usize]) as usize;
        refined.get(b).copied().unwrap_or(false)
    };
    let lattice = per_pixel(w, h, |_, i, j| on_lattice(i, j) || !in_refined(i, j));
    let mut stages = Vec::with_capacity(4);
    let mut t = Instant::now();
    let mut lap = |name: &'static str| {
        stages.push((name, crate::ms(t)));
        t = Instant::now();
    };
    cast(&pass_params(params, &lattice), image)?;
    lap("lattice");
    // Pixels whose rays composite nothing (outside a screen tile, behind geometry at the
    // eye) are neither estimated nor cast again: the lattice pass left them empty.
    let settled = per_pixel(w, h, |k, i, j| {
        let (near, far) = params.depth_range_at(i, j);
        lattice[k] || far <= near.max(0.0)
    });
    let est = estimates(image, &settled, params, frame, tolerance);
    let accepted = accepted_in_smooth_bundles(&est, params, n);
    let rest: Vec<bool> = (0..n)
        .into_par_iter()
        .map(|k| !settled[k] && !accepted[k])
        .collect();
    lap("estimate");
    // The second and third passes fill pixels that no pass has cast yet.
    cast(&pass_params(params, &rest), image)?;
    lap("second");
    let surprise = surprises(image, &rest, &est, tolerance);
    let recheck = near_surprises(&surprise, &accepted, w, h);
    if recheck.iter().any(|&c| c) {
        cast(&pass_params(params, &recheck), image)?;
    }
    lap("recheck");
    for &(idx, e) in &est {
        if let Some(e) = e.filter(|_| accepted[idx] && !recheck[idx]) {
            (image.rgba[idx], image.depth[idx]) = (e.rgba, e.z);
        }
    }
    let count = |m: &[bool]| m.iter().filter(|&&c| c).count() as u64;
    Ok(Refined {
        lattice: count(&lattice),
        cast: count(&rest) + count(&recheck),
        rechecked: count(&recheck),
        interpolated: count(&accepted) - count(&recheck),
        stages,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use fluidcast_view::Camera;

    const E: f64 = 0.004;

    fn frame(w: u32, h: u32) -> ViewFrame {
        Camera::default().frame(w, h).unwrap()
    }

    /// An image of `f(i, j)` in every channel, at view depth `z(i, j)`.
    fn image(w: u32, h: u32, f: impl Fn(u32, u32) -> f64, z: impl Fn(u32, u32) -> f32) -> Image {
        let mut im = Image::new(w, h);
        for j in 0..h {
            for i in 0..w {
                let k = im.index(i, j);
                im.rgba[k] = [f(i, j) as f32; 4];
                im.depth[k] = z(i, j);
            }
        }
        im
    }

    fn params(w: u32, h: u32) -> RenderParams {
        RenderParams {
            width: w,
            height: h,
            ..Default::default()
        }
    }

    /// A bundle interpolates only where at least [`MIN_ACCEPTED_SHARE`] of its pixels
    /// between lattice pixels are accepted: of two 8 × 8 bundles side by side, the one whose
    /// estimates are all accepted but one keeps them, the one with a single accepted
    /// estimate casts it as well.
    #[test]
    fn bundles_with_few_accepted_pixels_cast_them_all() {
        let (w, h) = (16u32, 8u32);
        let p = params(w, h);
        let odd = |i: u32, j: u32| !on_lattice(i, j);
        let est: Vec<(usize, Option<Estimate>)> = (0..h)
            .flat_map(|j| (0..w).map(move |i| (i, j)))
            .filter(|&(i, j)| odd(i, j))
            .map(|(i, j)| {
                // Left bundle: all but pixel (1, 0); right bundle: only pixel (9, 0).
                let accept = if i < 8 {
                    (i, j) != (1, 0)
                } else {
                    (i, j) == (9, 0)
                };
                let e = Estimate {
                    rgba: [0.0; 4],
                    z: 1.0,
                    predicted: 0.0,
                    accept,
                };
                ((j * w + i) as usize, Some(e))
            })
            .collect();
        let accepted = accepted_in_smooth_bundles(&est, &p, (w * h) as usize);
        for j in 0..h {
            for i in 0..w {
                let want = odd(i, j) && i < 8 && (i, j) != (1, 0);
                assert_eq!(accepted[(j * w + i) as usize], want, "pixel ({i}, {j})");
            }
        }
    }

    fn smooth(i: u32, j: u32) -> f64 {
        0.5 + 0.3 * (f64::from(i) / 20.0).sin() * (f64::from(j) / 24.0).cos()
    }

    /// On a smooth image every pixel between lattice pixels, away from the edge, is accepted
    /// and interpolated to within a small share of E_I; at the edge there is no estimate.
    #[test]
    fn smooth_images_are_interpolated_closely() {
        let (w, h) = (40, 32);
        let im = image(w, h, smooth, |_, _| 5.0);
        let (prm, fr) = (params(w, h), frame(w, h));
        let mut accepted = 0;
        for j in 0..h {
            for i in (0..w).filter(|&i| !on_lattice(i, j)) {
                let e = interpolate(&im, &prm, &fr, E, (i, j));
                let inner = (3..w - 3).contains(&i) && (3..h - 3).contains(&j);
                assert_eq!(
                    e.is_some(),
                    inner
                        || (i % 2 == 0 && (3..h - 3).contains(&j))
                        || (j % 2 == 0 && (3..w - 3).contains(&i)),
                    "({i}, {j})"
                );
                if let Some(e) = e {
                    assert!(e.accept, "({i}, {j})");
                    let err = (f64::from(e.rgba[0]) - smooth(i, j)).abs();
                    assert!(err < 0.1 * E, "({i}, {j}): error {err}");
                    assert_eq!(e.z, 5.0);
                    accepted += 1;
                }
            }
        }
        assert!(accepted > 500, "{accepted}");
    }

    /// A step between two lattice rows (or columns) is cast, though the cubic's correction
    /// (the sum of the two second differences) is zero there; a smooth ramp of the same rise
    /// over many pixels is not.
    #[test]
    fn steps_between_lattice_lines_are_cast() {
        let (w, h) = (32, 32);
        let (prm, fr) = (params(w, h), frame(w, h));
        let step = |v: u32| if v <= 15 { 0.2 } else { 0.8 };
        let rows = image(w, h, |_, j| step(j), |_, _| 5.0);
        let cols = image(w, h, |i, _| step(i), |_, _| 5.0);
        for k in [8, 15, 20] {
            let r = interpolate(&rows, &prm, &fr, E, (k, 15)).unwrap();
            let c = interpolate(&cols, &prm, &fr, E, (15, k)).unwrap();
            assert!(!r.accept && !c.accept, "{k}");
        }
        let ramp = image(w, h, |_, j| 0.2 + 0.02 * f64::from(j), |_, _| 5.0);
        assert!(interpolate(&ramp, &prm, &fr, E, (8, 15)).unwrap().accept);
    }

    /// A silhouette (half opacity reached on one side only) and a steep surface are cast; a
    /// neighbour with another depth range has no estimate.
    #[test]
    fn silhouettes_steep_surfaces_and_depth_ranges_are_cast() {
        let (w, h) = (32, 32);
        // A parallel projection: a pixel's footprint is the same at every depth.
        let camera = Camera {
            parallel_projection: true,
            ..Camera::default()
        };
        let (prm, fr) = (params(w, h), camera.frame(w, h).unwrap());
        let flat = |_, _| 0.5;
        let silhouette = image(w, h, flat, |i, _| if i <= 15 { 5.0 } else { f32::INFINITY });
        assert!(
            !interpolate(&silhouette, &prm, &fr, E, (15, 16))
                .unwrap()
                .accept
        );
        // Depth rising by `slope` pixel footprints per pixel: cast above MAX_SLOPE (3).
        let px = fr.pixel_size_at(5.0) as f32;
        for (slope, ok) in [(1.0, true), (2.9, true), (3.2, false), (10.0, false)] {
            let tilted = image(w, h, flat, |i, _| 5.0 + slope * px * i as f32);
            let e = interpolate(&tilted, &prm, &fr, E, (15, 16)).unwrap();
            assert_eq!(e.accept, ok, "slope {slope}");
        }
        let flat_im = image(w, h, flat, |_, _| 5.0);
        let mut limits = vec![f32::INFINITY; (w * h) as usize];
        limits[16 * w as usize + 16] = 7.0;
        let limited = RenderParams {
            depth_limit: Some(Arc::from(limits)),
            ..prm.clone()
        };
        assert!(interpolate(&flat_im, &limited, &fr, E, (15, 16)).is_none());
        assert!(interpolate(&flat_im, &limited, &fr, E, (15, 20)).is_some());
    }

    /// What the image holds before any pass: no pass leaves it anywhere.
    const UNSET: ([f32; 4], f32) = ([-1.0; 4], -1.0);

    /// A fake ray caster over an image function: writes it for the pixels whose depth range
    /// is not empty, records them per pass, and panics on a pixel that a pass cast before.
    fn fake_caster<'a>(
        truth: &'a Image,
        passes: &'a mut Vec<Vec<bool>>,
    ) -> impl FnMut(&RenderParams, &mut Image) -> Result<(), ()> + 'a {
        move |p: &RenderParams, out: &mut Image| {
            let mut cast = vec![false; out.rgba.len()];
            for j in 0..p.height {
                for i in 0..p.width {
                    let (near, far) = p.depth_range_at(i, j);
                    let k = out.index(i, j);
                    if near < far {
                        assert_eq!((out.rgba[k], out.depth[k]), UNSET, "({i}, {j}) cast twice");
                        (out.rgba[k], out.depth[k], cast[k]) =
                            (truth.rgba[k], truth.depth[k], true);
                    }
                }
            }
            passes.push(cast);
            Ok(())
        }
    }

    /// A whole-image pass (the GPU's) gives the refined image exactly the pixels it casts.
    #[test]
    fn keep_cast_pixels_copies_exactly_the_pixels_cast() {
        let (w, h) = (13, 7);
        let from = image(w, h, |i, j| f64::from(i + 13 * j) / 100.0, |_, _| 2.0);
        let mask: Vec<bool> = (0..w * h).map(|k| k % 3 == 1).collect();
        let mut to = Image::new(w, h);
        to.rgba.fill(UNSET.0);
        to.depth.fill(UNSET.1);
        keep_cast_pixels(&pass_params(&params(w, h), &mask), &from, &mut to);
        for (k, &m) in mask.iter().enumerate() {
            let want = if m {
                (from.rgba[k], from.depth[k])
            } else {
                UNSET
            };
            assert_eq!((to.rgba[k], to.depth[k]), want, "pixel {k}");
        }
    }

    /// A cast pixel is a surprise when it misses its interpolation by more than its stencil
    /// predicted plus SURPRISE_SHARE · E_I, in any channel: a pixel rejected for curvature
    /// that misses by about its prediction is not one.
    #[test]
    fn a_surprise_misses_by_more_than_predicted() {
        let est = |predicted: f64| Estimate {
            rgba: [0.5; 4],
            z: 1.0,
            predicted,
            accept: false,
        };
        let cases = [
            (0.0, 0.0015, false),
            (0.0, 0.0025, true),
            (0.01, 0.0115, false),
            (0.01, 0.0125, true),
        ];
        let mut second = Image::new(cases.len() as u32, 1);
        let mut ests = Vec::new();
        for (k, &(predicted, miss, _)) in cases.iter().enumerate() {
            second.rgba[k] = [0.5, 0.5, 0.5 - miss as f32, 0.5];
            ests.push((k, Some(est(predicted))));
        }
        let cast = vec![true; cases.len()];
        let want: Vec<bool> = cases.iter().map(|c| c.2).collect();
        assert_eq!(surprises(&second, &cast, &ests, E), want);
        // Pixels not cast, or without an interpolation, are never surprises.
        ests[1].1 = None;
        let got = surprises(&second, &[true, true, true, false], &ests, E);
        assert_eq!(got, [false, false, false, false]);
    }

    /// The passes: the lattice first; then every other pixel that is not accepted; then the
    /// accepted pixels near a surprise. Here a thin line one pixel wide runs down an odd
    /// column, which the lattice does not see, from a step edge (cast) into a smooth region
    /// (accepted): the pixels of the line next to the edge are surprises, and the recheck
    /// casts the line's pixels within RECHECK_RADIUS of them. Every pixel cast is exact, the
    /// counts add up, and the pixels left interpolated are the line's far part only.
    #[test]
    fn passes_cast_the_lattice_the_rejected_and_what_surprises() {
        let (w, h) = (48, 48);
        let truth_f = |i: u32, j: u32| {
            let base = if j < 20 { 0.2 } else { 0.7 } + 0.001 * f64::from(i);
            base + if i == 23 && j >= 20 { 0.1 } else { 0.0 }
        };
        let truth = image(w, h, truth_f, |_, _| 5.0);
        let prm = RenderParams {
            adaptive: fluidcast_plan::PlanParams::default(),
            ..params(w, h)
        };
        // The refinement over `truth` with the bundles `refined` refined: the image, the
        // counts and the pixels of each pass.
        let run = |refined: &[bool]| {
            let mut passes = Vec::new();
            let caster = fake_caster(&truth, &mut passes);
            let mut got = Image::new(w, h);
            got.rgba.fill(UNSET.0);
            got.depth.fill(UNSET.1);
            let counts = cast_refined(&prm, &frame(w, h), E, refined, &mut got, caster).unwrap();
            // Every pixel was cast or interpolated.
            for k in 0..got.rgba.len() {
                assert_ne!((got.rgba[k], got.depth[k]), UNSET, "pixel {k} left unset");
            }
            (got, counts, passes)
        };
        let (got, refined, passes) = run(&[true; 36]);
        assert_eq!(passes.len(), 3);
        let lattice: Vec<bool> = (0..h)
            .flat_map(|j| (0..w).map(move |i| on_lattice(i, j)))
            .collect();
        assert_eq!(passes[0], lattice);
        let n = (w * h) as u64;
        let count = |m: &Vec<bool>| m.iter().filter(|&&c| c).count() as u64;
        assert_eq!(refined.lattice, n / 4);
        assert_eq!(refined.cast, count(&passes[1]) + count(&passes[2]));
        assert_eq!(refined.rechecked, count(&passes[2]));
        assert_eq!(refined.lattice + refined.cast + refined.interpolated, n);
        let err = |k: usize| (got.rgba[k][0] - truth.rgba[k][0]).abs();
        for (k, _) in passes.iter().flatten().enumerate() {
            let k = k % n as usize;
            if passes.iter().any(|p| p[k]) {
                assert_eq!(err(k), 0.0, "pixel {k} was cast");
            }
        }
        // The line next to the edge (rows 18–23) was cast; far from it, it was interpolated
        // (the lattice cannot see it: the known limit).
        let line = |j: u32| (j * w + 23) as usize;
        for j in 18..24 {
            assert_eq!(err(line(j)), 0.0, "row {j}");
        }
        assert!(
            passes[2][line(22)] || passes[2][line(23)],
            "the recheck cast none of the line"
        );
        assert!(
            err(line(40)) > 0.05,
            "row 40: the line was found without a surprise"
        );

        // Bundles not refined (every other one here) are cast whole in the first pass.
        let half: Vec<bool> = (0..36).map(|b| b % 2 == 0).collect();
        let (got, refined, passes) = run(&half);
        for (k, &c) in passes[0].iter().enumerate() {
            let (i, j) = ((k % w as usize) as u32, (k / w as usize) as u32);
            let b = (j / 8 * 6 + i / 8) as usize;
            assert_eq!(c, on_lattice(i, j) || !half[b], "pixel ({i}, {j})");
            if !half[b] {
                assert_eq!(got.rgba[k], truth.rgba[k]);
            }
        }
        assert_eq!(refined.lattice, count(&passes[0]));
    }
}
