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

use std::sync::Arc;
use std::time::Instant;

use fluidcast_grid::{screen_rect, support_depth_extent, view_particle};
use fluidcast_image::Image;
use fluidcast_sph::Particles;
use fluidcast_view::{Camera, ViewFrame};
use rayon::prelude::*;

use crate::adaptive::SURFACE_THRESHOLD;
use crate::{ms, IsoField, RenderError, RenderParams, RenderStats, Surfaces};

/// Bytes of per-view working memory one visible particle costs the adaptive CPU renderer at
/// most where its support covers about one cell (view-space particle 56, its footprint's
/// particle–cell pairs 3 × 12, the subset copy 20), used to choose the tile count.
pub const VIEW_BYTES_PER_PARTICLE: u64 = 112;

/// The tiles' pixel rectangles `[x0, x1, y0, y1]` (ends exclusive): `count` tiles or more,
/// in a grid of rows and columns whose edges lie on multiples of `align` pixels.
pub fn tile_rects(width: u32, height: u32, count: u32, align: u32) -> Vec<[u32; 4]> {
    let align = align.max(1);
    let (bx, by) = (width.div_ceil(align), height.div_ceil(align));
    // As square as the image allows: columns ∝ width.
    let count = count.clamp(1, bx * by);
    let cols = (((count as f64) * bx as f64 / by as f64).sqrt().round() as u32).clamp(1, bx);
    let rows = count.div_ceil(cols).clamp(1, by);
    let cut = |n: u32, parts: u32, k: u32, end: u32| ((n * k / parts) * align).min(end);
    let mut rects = Vec::new();
    for r in 0..rows {
        for c in 0..cols {
            let rect = [
                cut(bx, cols, c, width),
                cut(bx, cols, c + 1, width),
                cut(by, rows, r, height),
                cut(by, rows, r + 1, height),
            ];
            if rect[0] < rect[1] && rect[2] < rect[3] {
                rects.push(rect);
            }
        }
    }
    rects
}

/// The particles (indices, in order) whose support's screen rectangle meets `rect` grown by
/// `margin` pixels, among those within `[near, far]`.
fn particles_reaching(
    particles: &Particles,
    frame: &ViewFrame,
    (near, far): (f64, f64),
    rect: [u32; 4],
    margin: u32,
) -> Vec<usize> {
    let [x0, x1, y0, y1] = [
        rect[0].saturating_sub(margin),
        rect[1].saturating_add(margin),
        rect[2].saturating_sub(margin),
        rect[3].saturating_add(margin),
    ];
    (0..particles.len())
        .into_par_iter()
        .filter(|&j| {
            let p = view_particle(particles, frame, j);
            screen_rect(frame, &p, near, far)
                .is_some_and(|r| r[0] < x1 && r[1] > x0 && r[2] < y1 && r[3] > y0)
        })
        .collect()
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
    total.cells += tile.cells;
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

/// Renders the view in `tiles` screen tiles (see the module's documentation) with `render`,
/// which is handed each tile's particles, their surface flags and the parameters to use.
/// `surface`: the surface flags of all particles, if the caller has them. `margin`: pixels
/// around each tile whose particles the tile also takes (what a pixel's neighbours add:
/// the perspective grid's columns).
pub fn render_in_tiles<E: From<RenderError>>(
    particles: &Particles,
    surface: Option<&[bool]>,
    camera: &Camera,
    params: &RenderParams,
    (tiles, margin): (u32, u32),
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
    let flags = match surface {
        Some(s) => Some(std::borrow::Cow::Borrowed(s)),
        None if params.adaptive.uses_surface_cells() => Some(std::borrow::Cow::Owned(
            particles.surface_flags(SURFACE_THRESHOLD),
        )),
        None => None,
    };
    stats.particles_visible = (0..particles.len())
        .into_par_iter()
        .filter(|&j| {
            screen_rect(
                &frame,
                &view_particle(particles, &frame, j),
                range.0,
                range.1,
            )
            .is_some()
        })
        .count();
    let split_ms = ms(t0);
    for rect in tile_rects(params.width, params.height, tiles, params.grid.bundle) {
        let keep = particles_reaching(particles, &frame, range, rect, margin);
        let part = particles.select(&keep);
        let part_flags: Option<Vec<bool>> =
            flags.as_ref().map(|f| keep.iter().map(|&j| f[j]).collect());
        let mut p = params.clone();
        p.surfaces = surfaces_of(&params.surfaces, &keep);
        drop(keep);
        let (tile, tile_stats) = render(&part, part_flags.as_deref(), &p)?;
        add_stats(&mut stats, &tile_stats);
        paste(&mut image, &tile, rect);
    }
    stats.stages.insert(0, ("split", split_ms));
    Ok((image, stats))
}
