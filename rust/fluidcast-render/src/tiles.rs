//! Rendering a view in screen tiles, so that the per-view working memory (view-space
//! particles, the grid's particle–cell pairs, the plan) holds one tile's particles at a time
//! (issue 17, `--memory-limit`).
//!
//! Each tile renders the whole image with the particles whose support reaches the tile
//! (grown by a margin), and keeps the tile's pixels. What makes that the same image as one
//! render of everything, bit for bit:
//! * every tile samples the same depths: the whole set's support depths are handed down
//!   ([`RenderParams::support_depths`]), as MPI ranks do;
//! * the particles a pixel's result depends on are all in its tile's set: the tiles' edges
//!   lie on ray-bundle edges (a bundle is planned and cast from its own cells), and the
//!   margin covers the perspective grid's neighbouring columns;
//! * a subset keeps the particles' order, so every sum adds the same terms in the same order;
//! * what is decided over all particles is decided once, before the tiles: the surface
//!   particles of the adaptive plan.
//!
//! Except the plan's probe ([`crate::PlanParams::probe`], on by default): each tile takes its
//! decision from the probe bundles it holds, so where tiles decide differently from one
//! render the images differ, each pixel still as the plan allows against full rate. Without
//! the probe (and, in the relaxed mode, without image-space interpolation) the image is the
//! same bit for bit. (A decision over the whole view would need every tile's probe planned
//! before the first tile is cast: a second grid per tile.)

use std::sync::Arc;
use std::time::Instant;

use fluidcast_grid::{screen_rect, support_depth_extent, view_particle};
use fluidcast_image::Image;
use fluidcast_sph::Particles;
use fluidcast_view::{Camera, ViewFrame};
use rayon::prelude::*;

use crate::adaptive::plan_surface;
use crate::{ms, IsoField, RenderError, RenderParams, RenderStats, Surfaces};

/// Bytes of per-view working memory a tile's particle costs the adaptive CPU renderer where
/// its support covers a few cells (view-space particle 56, its particle–cell pairs 3 × 12,
/// the subset copy 20, the plan and allocator slack): how many particles a tile may take
/// under a memory limit. Measured on 14.5M particles at 1024x1024: limits of 820 MiB and
/// 1200 MiB held to 1 %.
pub const VIEW_BYTES_PER_PARTICLE: u64 = 128;

/// Bytes per particle of the whole set that rendering in tiles holds throughout: each
/// particle's screen rectangle (8) and surface flag (1).
pub const TILING_BYTES_PER_PARTICLE: u64 = 9;

/// Less room than this for the tiles' working memory is refused: tiles of fewer than about
/// 8000 particles would take far longer than they save.
pub const MIN_TILE_BYTES: u64 = 1 << 20;

/// The most particles a screen tile may hold so that rendering `particles` particles at
/// `width × height` in tiles takes at most `budget` bytes beyond the particles themselves
/// (the image planes, what tiling keeps of every particle, one tile's working memory):
/// `None` when one render fits. Too small a budget is [`RenderError::MemoryBudget`].
pub fn tile_particles_within(
    particles: usize,
    width: u32,
    height: u32,
    budget: u64,
) -> Result<Option<usize>, RenderError> {
    // The image, its depth and AOV planes, and a tile's own image.
    let image = u64::from(width) * u64::from(height) * 2 * 32;
    let whole = particles as u64 * TILING_BYTES_PER_PARTICLE;
    let fixed = image + whole;
    let spare = budget.saturating_sub(fixed);
    if spare < MIN_TILE_BYTES {
        return Err(RenderError::MemoryBudget {
            budget,
            needed: fixed + MIN_TILE_BYTES,
        });
    }
    let most = usize::try_from(spare / VIEW_BYTES_PER_PARTICLE).unwrap_or(usize::MAX);
    Ok((most < particles).then_some(most))
}

/// The tiles: `rect` (pixels `[x0, x1, y0, y1]`, ends exclusive), split in two across its
/// longer side at a multiple of `align` pixels, and so on, until each holds at most
/// `max_particles` particles (or is one `align` square, or most of its particles, 90 %,
/// would be in both halves). Tiles no particle reaches are left out (their pixels stay
/// empty).
fn split_rects(
    count: &impl Fn([u32; 4]) -> usize,
    rect: [u32; 4],
    max_particles: usize,
    align: u32,
    out: &mut Vec<[u32; 4]>,
) {
    split_counted(count, (rect, count(rect)), max_particles, align, out);
}

/// [`split_rects`] of `rect` holding `n` particles (each rectangle is counted once).
fn split_counted(
    count: &impl Fn([u32; 4]) -> usize,
    (rect, n): ([u32; 4], usize),
    max_particles: usize,
    align: u32,
    out: &mut Vec<[u32; 4]>,
) {
    if n > max_particles {
        if let Some((a, b)) = halves(rect, align) {
            let (na, nb) = (count(a), count(b));
            // Where most particles reach both halves (particles larger than the tile),
            // splitting on would only multiply the renders, not shed particles.
            if (na + nb) * 10 <= n * 18 {
                split_counted(count, (a, na), max_particles, align, out);
                split_counted(count, (b, nb), max_particles, align, out);
                return;
            }
        }
    }
    if n > 0 {
        out.push(rect);
    }
}

/// `rect` cut in two across its longer side at a multiple of `align` pixels; `None` for a
/// rectangle of one `align` square.
fn halves(rect: [u32; 4], align: u32) -> Option<([u32; 4], [u32; 4])> {
    let (w, h) = (rect[1] - rect[0], rect[3] - rect[2]);
    if w <= align && h <= align {
        return None;
    }
    let cut = |lo: u32, hi: u32| ((lo + hi) / 2 / align).max(lo / align + 1) * align;
    Some(if w >= h {
        let x = cut(rect[0], rect[1]);
        (
            [rect[0], x, rect[2], rect[3]],
            [x, rect[1], rect[2], rect[3]],
        )
    } else {
        let y = cut(rect[2], rect[3]);
        (
            [rect[0], rect[1], rect[2], y],
            [rect[0], rect[1], y, rect[3]],
        )
    })
}

/// Each particle's support on screen, `[x0, x1, y0, y1]` in pixels (ends exclusive), found
/// once per view; `[0; 4]` for particles outside `[near, far]` or off screen. 8 bytes a
/// particle: the tiles are split and filled by comparisons alone.
const _: () = assert!(
    crate::MAX_SIDE <= u16::MAX as u32,
    "pixel rectangles are u16"
);
fn screen_rects(
    particles: &Particles,
    frame: &ViewFrame,
    (near, far): (f64, f64),
) -> Vec<[u16; 4]> {
    (0..particles.len())
        .into_par_iter()
        .map(|j| {
            screen_rect(frame, &view_particle(particles, frame, j), near, far)
                .map_or([0; 4], |r| r.map(|v| v as u16))
        })
        .collect()
}

/// The particles (indices, in order) whose screen rectangle meets `rect` grown by `margin`
/// pixels.
fn particles_reaching(rects: &[[u16; 4]], rect: [u32; 4], margin: u32) -> Vec<usize> {
    let [x0, x1, y0, y1] = grow(rect, margin);
    (0..rects.len())
        .into_par_iter()
        .filter(|&j| meets(rects[j], [x0, x1, y0, y1]))
        .collect()
}

fn grow(rect: [u32; 4], margin: u32) -> [u32; 4] {
    [
        rect[0].saturating_sub(margin),
        rect[1].saturating_add(margin),
        rect[2].saturating_sub(margin),
        rect[3].saturating_add(margin),
    ]
}

fn meets(r: [u16; 4], [x0, x1, y0, y1]: [u32; 4]) -> bool {
    let r = r.map(u32::from);
    r[0] < r[1] && r[0] < x1 && r[1] > x0 && r[2] < y1 && r[3] > y0
}

/// The iso-surface settings with an attribute array cut down to `keep`.
fn surfaces_of(s: &Option<Arc<Surfaces>>, keep: &[usize]) -> Option<Arc<Surfaces>> {
    let s = s.as_ref()?;
    Some(match &s.field {
        IsoField::Attribute(Some(values)) => Arc::new(Surfaces {
            field: IsoField::Attribute(Some(keep.iter().map(|&j| values[j]).collect())),
            ..(**s).clone()
        }),
        _ => s.clone(),
    })
}

/// The depth limit of a tile's render: the caller's inside `rect`, 0 outside, so that no ray
/// outside the tile samples anything (the border particles of a tile reach bundles around
/// it, whose pixels are thrown away) and its plan leaves those bundles out.
fn limit_to(params: &RenderParams, rect: [u32; 4]) -> Arc<[f32]> {
    let w = params.width;
    (0..params.height)
        .flat_map(|j| (0..w).map(move |i| (i, j)))
        .map(|(i, j)| {
            let inside = i >= rect[0] && i < rect[1] && j >= rect[2] && j < rect[3];
            if inside {
                params.depth_limit_at(i, j) as f32
            } else {
                0.0
            }
        })
        .collect()
}

/// Copies the pixels of `rect` (colour, depth and every AOV) from `tile` into `image`.
fn paste(image: &mut Image, tile: &Image, rect: [u32; 4]) {
    for (name, _) in &tile.aovs {
        if !image.aovs.iter().any(|(n, _)| n == name) {
            let n = image.rgba.len();
            image.aovs.push((name.clone(), vec![0.0; n]));
        }
    }
    for j in rect[2]..rect[3] {
        let a = image.index(rect[0], j);
        let b = image.index(rect[1], j);
        image.rgba[a..b].copy_from_slice(&tile.rgba[a..b]);
        image.depth[a..b].copy_from_slice(&tile.depth[a..b]);
        for (name, plane) in &tile.aovs {
            if let Some((_, out)) = image.aovs.iter_mut().find(|(n, _)| n == name) {
                out[a..b].copy_from_slice(&plane[a..b]);
            }
        }
    }
}

/// Adds a tile's statistics to the whole view's: counts and stage times add up.
fn add_stats(total: &mut RenderStats, tile: &RenderStats) {
    total.samples += tile.samples;
    total.pairs += tile.pairs;
    total.culled += tile.culled;
    total.interpolated += tile.interpolated;
    total.cells += tile.cells;
    total.dispatches += tile.dispatches;
    total.transfers += tile.transfers;
    total.depth_samples = tile.depth_samples;
    total.near = tile.near;
    total.far = tile.far;
    total.bundles = tile.bundles;
    total.gpu_memory_bytes = total.gpu_memory_bytes.max(tile.gpu_memory_bytes);
    for &(name, v) in &tile.stages {
        match total.stages.iter_mut().find(|s| s.0 == name) {
            Some(s) => s.1 += v,
            None => total.stages.push((name, v)),
        }
    }
    match (&mut total.plan, &tile.plan) {
        (Some(t), Some(p)) => t.add(p),
        (t @ None, Some(p)) => *t = Some(p.clone()),
        _ => {}
    }
}

/// Renders the view in screen tiles of at most `max_particles` particles each (see the
/// module's documentation; a tile of one ray bundle may hold more) with `render`, which is
/// handed each tile's particles, their surface flags and the parameters to use. `surface`:
/// the surface flags of all particles, if the caller has them. `margin`: pixels around each
/// tile whose particles the tile also takes (what a pixel's neighbours add: the perspective
/// grid's columns). The statistics count the tiles in `tiles`.
pub fn render_in_tiles<E: From<RenderError>>(
    particles: &Particles,
    surface: Option<&[bool]>,
    camera: &Camera,
    params: &RenderParams,
    (max_particles, margin): (usize, u32),
    mut render: impl FnMut(
        &Particles,
        Option<&[bool]>,
        &RenderParams,
    ) -> Result<(Image, RenderStats), E>,
) -> Result<(Image, RenderStats), E> {
    let t0 = Instant::now();
    let frame = camera
        .frame(params.width, params.height)
        .map_err(RenderError::from)?;
    let mut params = params.clone();
    params.support_depths = params
        .support_depths
        .or_else(|| support_depth_extent(particles, &frame));
    let mut image = Image::new(params.width, params.height);
    let mut stats = RenderStats {
        particles: particles.len(),
        width: params.width,
        height: params.height,
        ..Default::default()
    };
    let Some(range) = fluidcast_grid::sampled_range(&frame, params.support_depths, || None) else {
        return render(particles, surface, &params);
    };
    let flags = plan_surface(particles, surface, &params.adaptive);
    let rects = screen_rects(particles, &frame, range);
    stats.particles_visible = rects.par_iter().filter(|r| r[0] < r[1]).count();
    let reach = |rect| particles_reaching(&rects, rect, margin);
    let mut tiles = Vec::new();
    let whole = [0, params.width, 0, params.height];
    let count = |rect| {
        let g = grow(rect, margin);
        rects.par_iter().filter(|&&r| meets(r, g)).count()
    };
    split_rects(
        &count,
        whole,
        max_particles.max(1),
        params.grid.bundle.max(1),
        &mut tiles,
    );
    stats.tiles = tiles.len();
    let split_ms = ms(t0);
    for rect in tiles {
        let keep = reach(rect);
        let part = particles.select(&keep);
        let part_flags: Option<Vec<bool>> =
            flags.as_ref().map(|f| keep.iter().map(|&j| f[j]).collect());
        let mut p = params.clone();
        p.surfaces = surfaces_of(&params.surfaces, &keep);
        p.depth_limit = Some(limit_to(&params, rect));
        drop(keep);
        let (tile, tile_stats) = render(&part, part_flags.as_deref(), &p)?;
        add_stats(&mut stats, &tile_stats);
        paste(&mut image, &tile, rect);
    }
    stats.stages.insert(0, ("split", split_ms));
    Ok((image, stats))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The tiles cover the image exactly once (less tiles nothing reaches), their edges lie on
    /// multiples of the bundle size, and each holds at most the limit unless it is one bundle,
    /// also where the points crowd into one corner (most of a tile's points in one half).
    #[test]
    fn split_tiles_cover_the_image_once_on_bundle_edges() {
        // Points crowded towards the bottom left, as fluid at the bottom of a view.
        let pts: Vec<[u32; 2]> = (0..4000u32)
            .map(|k| {
                [
                    (k * 7919 % 997) * 70 / 997 / (1 + k % 3),
                    53 - (k * 104_729 % 991) * 53 / 991 / (1 + k % 4) - 1,
                ]
            })
            .collect();
        let count = |r: [u32; 4]| {
            pts.iter()
                .filter(|p| p[0] >= r[0] && p[0] < r[1] && p[1] >= r[2] && p[1] < r[3])
                .count()
        };
        for (max, align) in [(4000, 8), (500, 8), (100, 4), (1, 8)] {
            let mut tiles = Vec::new();
            split_rects(&count, [0, 70, 0, 53], max, align, &mut tiles);
            let mut covered = vec![0u8; 70 * 53];
            for r in &tiles {
                assert!(r[0] % align == 0 && r[2] % align == 0, "{r:?}");
                // Points lie in one half or the other, never both: a tile holds more than
                // `max` only when it is one `align` square.
                let n = count(*r);
                assert!(
                    n <= max || halves(*r, align).is_none(),
                    "{r:?}: {n} > {max}"
                );
                for j in r[2]..r[3] {
                    for i in r[0]..r[1] {
                        covered[(j * 70 + i) as usize] += 1;
                    }
                }
            }
            assert!(covered.iter().all(|&c| c <= 1));
            for p in &pts {
                assert_eq!(covered[(p[1] * 70 + p[0]) as usize], 1, "max {max}: {p:?}");
            }
            assert_eq!(tiles.len() == 1, max >= pts.len(), "max {max}");
        }
    }
}
