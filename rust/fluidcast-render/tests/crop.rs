//! `crop_to_box`: rays cropped to boxes that partition space, composited in visibility
//! order, give the image of the whole (what each MPI rank renders of the region it owns).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly
mod common;

use common::{cloud, cloud_view, composite_under, max_channel_diff};
use fluidcast_render::{
    crop_to_box, render_adaptive, render_reference, support_depth_extent, PlanParams, RenderError,
    RenderParams,
};
use fluidcast_sph::{FieldKind, Particles};
use fluidcast_view::{Camera, TransferFunction};

type Box3 = ([f64; 3], [f64; 3]);

/// Three boxes of a kd-tree over the field's extent: split at x = `cx`, the upper half split
/// at y = `cy`; listed in visibility order for `cam` (the side holding the eye first; for a
/// parallel view the side facing the viewer).
fn kd_boxes(cam: &Camera, cx: f64, cy: f64) -> Vec<Box3> {
    let (lo, hi) = ([-1.0; 3], [1.0; 3]);
    let left = (lo, [cx, hi[1], hi[2]]);
    let low = ([cx, lo[1], lo[2]], [hi[0], cy, hi[2]]);
    let high = ([cx, cy, lo[2]], hi);
    let dir = |k: usize| cam.focal_point[k] - cam.position[k];
    let first = |k: usize, c: f64| {
        if cam.parallel_projection {
            dir(k) > 0.0
        } else {
            cam.position[k] < c
        }
    };
    let right = if first(1, cy) {
        vec![low, high]
    } else {
        vec![high, low]
    };
    if first(0, cx) {
        [vec![left], right].concat()
    } else {
        [right, vec![left]].concat()
    }
}

/// 48×40 pixels at full rate, no early ray termination (a region behind cannot know how
/// opaque the ones in front are).
fn full_rate() -> RenderParams {
    RenderParams {
        width: 48,
        height: 40,
        min_transmittance: 0.0,
        adaptive: PlanParams {
            tolerance: None,
            ..Default::default()
        },
        ..Default::default()
    }
}

fn render(
    p: &Particles,
    cam: &Camera,
    tf: &TransferFunction,
    prm: &RenderParams,
    adaptive: bool,
) -> fluidcast_image::Image {
    if adaptive {
        render_adaptive(p, None, cam, tf, prm).unwrap().image
    } else {
        render_reference(p, cam, tf, prm).unwrap().0
    }
}

#[test]
fn boxes_that_partition_space_composite_to_the_whole_image() {
    let p = cloud(2500, 11);
    for (azimuth, elevation, parallel) in [(30.0, 20.0, false), (-120.0, -35.0, true)] {
        let (cam, tf) = cloud_view(azimuth, elevation, parallel, FieldKind::Csph);
        let base = full_rate();
        for adaptive in [false, true] {
            let whole = render(&p, &cam, &tf, &base, adaptive);
            let mut over = vec![[0.0f32; 4]; whole.rgba.len()];
            for (lo, hi) in kd_boxes(&cam, 0.1, -0.2) {
                let mut prm = base.clone();
                crop_to_box(&mut prm, &cam, lo, hi).unwrap();
                let img = render(&p, &cam, &tf, &prm, adaptive);
                let covered = img.rgba.iter().filter(|px| px[3] > 0.05).count();
                assert!(covered > 20, "box {lo:?}..{hi:?} shows {covered} pixels");
                composite_under(&mut over, &img.rgba);
            }
            let max = max_channel_diff(&over, &whole.rgba);
            assert!(
                max <= 2e-6,
                "azimuth {azimuth}, parallel {parallel}, adaptive {adaptive}: {max}"
            );
        }
    }
}

/// The particles of `p` within `halo` of the box (its own and its neighbours' halo).
fn part(p: &Particles, (lo, hi): Box3, halo: f32) -> Particles {
    let keep: Vec<usize> = (0..p.len())
        .filter(|&j| {
            let x = p.positions[j];
            let d2: f32 = (0..3)
                .map(|k| {
                    (lo[k] as f32 - x[k])
                        .max(x[k] - hi[k] as f32)
                        .max(0.0)
                        .powi(2)
                })
                .sum();
            d2 <= halo * halo
        })
        .collect();
    let pick = |v: &[f32]| keep.iter().map(|&j| v[j]).collect::<Vec<f32>>();
    Particles {
        positions: keep.iter().map(|&j| p.positions[j]).collect(),
        radii: pick(&p.radii),
        volumes: pick(&p.volumes),
        values: pick(&p.values),
        masses: pick(&p.masses),
        ..p.clone()
    }
}

/// What an MPI rank renders: only the particles in and near its box (a halo of 2 H), cropped
/// to the box, with the whole data set's support depths. The ranks' images composite to the
/// image of all particles; without the whole's support depths each part places its samples
/// over its own particles' depths and they do not.
#[test]
fn parts_with_halos_and_the_wholes_support_depths_composite_to_the_whole_image() {
    // Radii 0.06..0.08 in the unit cube: a halo of 2 H holds a part of the others' particles.
    let p = fluidcast_testkit::cloud(6000, 11, (0.06, 0.02));
    let halo = 2.0 * p.radii.iter().copied().fold(0.0f32, f32::max);
    let (cam, tf) = cloud_view(30.0, 20.0, false, FieldKind::Csph);
    let base = full_rate();
    let frame = cam.frame(base.width, base.height).unwrap();
    let whole_depths = support_depth_extent(&p, &frame).unwrap();
    for adaptive in [false, true] {
        let whole = render(&p, &cam, &tf, &base, adaptive);
        let mut errors = Vec::new();
        for shared in [true, false] {
            let mut over = vec![[0.0f32; 4]; whole.rgba.len()];
            for (lo, hi) in kd_boxes(&cam, 0.1, -0.2) {
                // Outer faces far out: only shared faces cut (as the ParaView representation).
                let far = |v: f64, edge: f64| if v.abs() == 1.0 { edge } else { v };
                let lo = lo.map(|v| far(v, -1e30));
                let hi = hi.map(|v| far(v, 1e30));
                let mine = part(&p, (lo, hi), halo);
                assert!(mine.len() < p.len(), "the halo holds everything");
                let mut prm = RenderParams {
                    support_depths: shared.then_some(whole_depths),
                    ..base.clone()
                };
                crop_to_box(&mut prm, &cam, lo, hi).unwrap();
                let img = render(&mine, &cam, &tf, &prm, adaptive);
                composite_under(&mut over, &img.rgba);
            }
            let max = max_channel_diff(&over, &whole.rgba);
            errors.push(max);
        }
        assert!(
            errors[0] <= 2e-6,
            "adaptive {adaptive}: parts differ by {}",
            errors[0]
        );
        assert!(
            errors[1] > 1e-3,
            "adaptive {adaptive}: own depths agree too ({}): the scene tests nothing",
            errors[1]
        );
    }
}

#[test]
fn cropping_keeps_a_lower_depth_limit_and_rejects_bad_boxes() {
    let (cam, _) = cloud_view(0.0, 0.0, false, FieldKind::Csph);
    let mut prm = RenderParams {
        width: 4,
        height: 3,
        depth_limit: Some(vec![0.5f32; 12].into()),
        ..Default::default()
    };
    let before = prm.clone();
    crop_to_box(&mut prm, &cam, [-1.0; 3], [1.0; 3]).unwrap();
    let (near, far) = (
        prm.depth_near.clone().unwrap(),
        prm.depth_limit.clone().unwrap(),
    );
    // The box's near face is far beyond the limit 0.5: the limit stays.
    assert!(near.iter().all(|&z| z > 1.0), "{near:?}");
    assert!(far.iter().all(|&z| z == 0.5), "{far:?}");
    for (lo, hi) in [
        ([0.0, 0.0, f64::NAN], [1.0; 3]),
        ([0.0, 2.0, 0.0], [1.0; 3]),
    ] {
        let mut p = before.clone();
        assert!(matches!(
            crop_to_box(&mut p, &cam, lo, hi),
            Err(RenderError::CropBox(..))
        ));
    }
    // A box the view misses composites nothing.
    let mut p = before.clone();
    crop_to_box(&mut p, &cam, [50.0; 3], [51.0; 3]).unwrap();
    let (n, f) = (p.depth_near.unwrap(), p.depth_limit.unwrap());
    assert!(n.iter().zip(f.iter()).all(|(a, b)| a >= b));
}
