//! `render_in_tiles`: a view rendered in screen tiles, each with only the particles that
//! reach it, is the image of one render of everything, bit for bit (what `--memory-limit`
//! promises), for every renderer.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly
mod common;

use std::sync::Arc;

use common::{cloud, cloud_view};
use fluidcast_image::Image;
use fluidcast_render::{
    render_adaptive, render_in_tiles, render_perspective_grid, render_reference, tile_margin,
    IsoField, PlanParams, RenderError, RenderParams, RenderStats, Surfaces,
};
use fluidcast_sph::{FieldKind, Particles};
use fluidcast_view::{Camera, TransferFunction};

#[derive(Clone, Copy, Debug)]
enum Renderer {
    Reference,
    Adaptive(Option<f64>),
    PerspectiveGrid(u32),
}

fn render(
    r: Renderer,
    p: &Particles,
    surface: Option<&[bool]>,
    cam: &Camera,
    tf: &TransferFunction,
    prm: &RenderParams,
) -> Result<(Image, RenderStats), RenderError> {
    match r {
        Renderer::Reference => render_reference(p, cam, tf, prm),
        Renderer::Adaptive(tolerance) => {
            let prm = RenderParams {
                // Every bundle analysed: with the probe, each tile takes the probe's decision
                // from its own bundles (tiles.rs), and the bits may differ where tiles decide
                // differently.
                adaptive: PlanParams {
                    tolerance,
                    probe: false,
                    ..prm.adaptive
                },
                ..prm.clone()
            };
            render_adaptive(p, surface, cam, tf, &prm).map(|r| (r.image, r.stats))
        }
        Renderer::PerspectiveGrid(cell) => render_perspective_grid(p, cam, tf, prm, cell),
    }
}

/// The largest difference of any colour, depth or AOV value (depths: equal infinities
/// count as equal).
fn max_diff(a: &Image, b: &Image) -> f32 {
    let rgba = a
        .rgba
        .iter()
        .zip(&b.rgba)
        .flat_map(|(x, y)| x.iter().zip(y).map(|(u, v)| (u - v).abs()))
        .fold(0.0, f32::max);
    let depth = a
        .depth
        .iter()
        .zip(&b.depth)
        .map(|(u, v)| if u == v { 0.0 } else { (u - v).abs() })
        .fold(0.0, f32::max);
    assert_eq!(a.aovs.len(), b.aovs.len());
    let aovs = a
        .aovs
        .iter()
        .zip(&b.aovs)
        .flat_map(|((_, x), (_, y))| x.iter().zip(y).map(|(u, v)| (u - v).abs()))
        .fold(0.0, f32::max);
    rgba.max(depth).max(aovs)
}

fn params(w: u32, h: u32) -> RenderParams {
    RenderParams {
        width: w,
        height: h,
        ..Default::default()
    }
}

#[test]
fn tiles_give_the_image_of_one_render() {
    let p = cloud(3000, 5);
    let renderers = [
        Renderer::Reference,
        Renderer::Adaptive(None),
        Renderer::Adaptive(Some(0.004)),
        Renderer::Adaptive(Some(0.05)),
        Renderer::PerspectiveGrid(1),
        Renderer::PerspectiveGrid(3),
    ];
    for (azimuth, elevation, parallel) in [(30.0, 20.0, false), (-120.0, -35.0, true)] {
        let (cam, tf) = cloud_view(azimuth, elevation, parallel, FieldKind::Csph);
        // Not a multiple of the bundle size, so that the last tiles are cut.
        let prm = params(70, 53);
        for r in renderers {
            let (whole, _) = render(r, &p, None, &cam, &tf, &prm).unwrap();
            let margin = match r {
                Renderer::PerspectiveGrid(cell) => tile_margin(cell),
                _ => 0,
            };
            for tiles in [2, 5, 9] {
                let (tiled, stats) =
                    render_in_tiles(&p, None, &cam, &prm, (tiles, margin), |q, s, prm| {
                        render(r, q, s, &cam, &tf, prm)
                    })
                    .unwrap();
                let d = max_diff(&whole, &tiled);
                assert_eq!(
                    d, 0.0,
                    "{r:?}, {tiles} tiles, azimuth {azimuth}: differs by {d}"
                );
                assert_eq!(stats.particles, p.len());
                assert!(stats.stage("split").is_some());
            }
        }
    }
}

/// Each tile really renders only part of the particles (else tiles would save nothing), and
/// leaving a particle out of the tile it reaches changes the image (the equality above can
/// fail).
#[test]
fn tiles_render_parts_and_every_reaching_particle_counts() {
    let p = cloud(3000, 5);
    let (cam, tf) = cloud_view(30.0, 20.0, false, FieldKind::Csph);
    let prm = params(64, 64);
    let (whole, _) = render_reference(&p, &cam, &tf, &prm).unwrap();
    let mut sizes = Vec::new();
    let max = p.len() / 4;
    let (tiled, _) = render_in_tiles(&p, None, &cam, &prm, (max, 0), |q, s, prm| {
        sizes.push(q.len());
        let _ = s;
        render_reference(q, &cam, &tf, prm)
    })
    .unwrap();
    assert_eq!(max_diff(&whole, &tiled), 0.0);
    // Tiles hold parts. These particles are large (a fifth of the view), so splitting stops
    // where most would be in both halves: above the asked quarter, below 60 %.
    assert!(sizes.len() >= 4, "{sizes:?}");
    assert!(
        sizes.iter().all(|&n| n > 0 && n < p.len() * 6 / 10),
        "{sizes:?}"
    );
    // Dropping each tile's last particle shows.
    let (short, _) = render_in_tiles(&p, None, &cam, &prm, (max, 0), |q, _, prm| {
        let keep: Vec<usize> = (0..q.len() - 1).collect();
        render_reference(&q.select(&keep), &cam, &tf, prm)
    })
    .unwrap();
    assert!(max_diff(&whole, &short) > 0.0);
}

/// Iso-surfaces of another attribute: its per-particle values are cut to each tile's
/// particles with them.
#[test]
fn tiles_keep_iso_surfaces_of_another_attribute() {
    let p = cloud(3000, 5);
    let (cam, tf) = cloud_view(30.0, 20.0, false, FieldKind::Csph);
    let other: Arc<[f32]> = p.positions.iter().map(|x| x[2] + 0.5 * x[0]).collect();
    let prm = RenderParams {
        surfaces: Some(Arc::new(Surfaces {
            field: IsoField::Attribute(Some(other)),
            values: vec![0.1],
            opacity: 0.6,
            volume: true,
            ..Default::default()
        })),
        ..params(60, 44)
    };
    let (whole, _) = render_reference(&p, &cam, &tf, &prm).unwrap();
    let (tiled, _) = render_in_tiles(&p, None, &cam, &prm, (p.len() / 6, 0), |q, _, prm| {
        render_reference(q, &cam, &tf, prm)
    })
    .unwrap();
    assert_eq!(max_diff(&whole, &tiled), 0.0);
    assert!(whole.aovs.iter().any(|(n, _)| n == "normal_x"));
}
