//! The adaptive grid renderer against the reference renderer and against its own bounds.
//!
//! * `--error-tolerance off` samples the reference's positions with its arithmetic (in single
//!   precision): the same images to f32 rounding.
//! * Strict mode: no pixel differs from the full-rate grid rendering by more than E_I, over
//!   synthetic scenes (the paper's radial concentration with a high-frequency transfer
//!   function) and every shared dataset, on an orbit of 8 views.
//! * Every full-rate pixel lies inside its bundle's full-rate bound, and every strict
//!   adaptive pixel inside the bound of the chosen plan (property test).
//! * The default (relaxed, super-pixels): at most 0.05 % of pixels above E_I.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly

use std::path::PathBuf;

use fluidcast_image::{compare, Image};
use fluidcast_render::{
    render_adaptive, render_reference, GridParams, PlanParams, RenderParams, MAX_SPAN_SAMPLES,
};
use fluidcast_sph::{
    FieldKind, Kernel, ParticleSpec, Particles, Quantity, RadiusSource, VolumeSource,
};
use fluidcast_view::{Camera, TransferFunction};
use proptest::prelude::*;

mod common;
use common::{cloud, rng};

/// The paper's radial concentration (Fig. 3): a jittered block of fluid whose value grows
/// with the distance from one corner.
fn radial(spacing: f32) -> Particles {
    let mut rnd = rng(99);
    let n = (1.0 / spacing).round() as i32;
    let mut p = Particles::default();
    for i in 0..n {
        for j in 0..n {
            for k in 0..n {
                let x = [i, j, k]
                    .map(|c| (c as f32 + 0.5) * spacing - 0.5 + 0.2 * spacing * (rnd() - 0.5));
                let d = ((x[0] - 0.5).powi(2) + (x[1] - 0.5).powi(2) + (x[2] - 0.5).powi(2)).sqrt();
                p.positions.push(x);
                p.radii.push(2.5 * spacing);
                p.volumes.push(spacing.powi(3));
                p.masses.push(spacing.powi(3));
                p.values.push(d);
            }
        }
    }
    p
}

/// A transfer function with many narrow opacity and colour bands.
fn banded(range: (f64, f64), bands: usize, unit: f64) -> TransferFunction {
    let mut tf = TransferFunction::preset("Viridis").unwrap();
    let n = 2 * bands + 1;
    tf.opacity = (0..n)
        .map(|i| {
            (
                i as f64 / (n - 1) as f64,
                if i % 2 == 0 { 0.05 } else { 0.7 },
            )
        })
        .collect();
    tf.colors = (0..n)
        .map(|i| {
            let t = i as f64 / (n - 1) as f64;
            (
                t,
                if i % 2 == 0 {
                    [0.9, 0.8 * t, 0.1]
                } else {
                    [0.1, 0.3, 1.0 - 0.5 * t]
                },
            )
        })
        .collect();
    let mut tf = tf.with_range(range.0, range.1).unwrap();
    tf.unit_distance = unit;
    tf
}

fn camera_for(p: &Particles, azimuth: f64, elevation: f64, parallel: bool) -> Camera {
    let (lo, hi) = p.support_bounds();
    let mut c = Camera {
        parallel_projection: parallel,
        ..Default::default()
    };
    c.reset(lo.map(f64::from), hi.map(f64::from));
    c.azimuth(azimuth);
    c.elevation(elevation);
    c.orthogonalize_view_up();
    c.zoom(1.2);
    c
}

fn max_abs(a: &Image, b: &Image) -> f64 {
    compare(a, b, 1.0).unwrap().0.max_abs
}

/// Pixels of `b` further than `e` from `a` in some channel, and the pixel count.
fn count_above(a: &Image, b: &Image, e: f64) -> (u64, u64) {
    let n = a.rgba.len() as u64;
    let c = compare(a, b, e).unwrap().0;
    ((c.frac_above * n as f64).round() as u64, n)
}

fn params(w: u32, h: u32, tolerance: Option<f64>) -> RenderParams {
    RenderParams {
        width: w,
        height: h,
        adaptive: PlanParams {
            tolerance,
            ..Default::default()
        },
        ..Default::default()
    }
}

#[test]
fn off_equals_reference_at_the_same_samples() {
    let p = cloud(150, 11);
    let tf = {
        let mut t = TransferFunction::preset("Cool to Warm")
            .unwrap()
            .with_range(-0.5, 1.0)
            .unwrap();
        t.unit_distance = 0.3;
        t
    };
    for (parallel, field, kernel, grid) in [
        (
            false,
            FieldKind::Csph,
            Kernel::CubicSpline,
            GridParams::default(),
        ),
        (
            true,
            FieldKind::Sph,
            Kernel::WendlandC2,
            GridParams::default(),
        ),
        (
            false,
            FieldKind::Density,
            Kernel::Quintic,
            GridParams {
                bundle: 3,
                depth_samples: 4,
            },
        ),
        (
            false,
            FieldKind::Csph,
            Kernel::Gaussian,
            GridParams {
                bundle: 16,
                depth_samples: 32,
            },
        ),
        // Every kernel's lane form (span.rs) against the scalar one; bundles of one lane
        // group and a half, and of one.
        (
            true,
            FieldKind::Csph,
            Kernel::WendlandC4,
            GridParams {
                bundle: 12,
                depth_samples: 16,
            },
        ),
        (
            false,
            FieldKind::Sph,
            Kernel::Poly6,
            GridParams {
                bundle: 1,
                depth_samples: 8,
            },
        ),
    ] {
        let cam = camera_for(&p, 35.0, 20.0, parallel);
        let mut prm = params(61, 47, None);
        prm.field = field;
        prm.kernel = kernel;
        prm.grid = grid;
        let tf = match field {
            FieldKind::Csph => tf.clone(),
            _ => {
                // Map the field's range at the particles.
                let (lo, hi) = field_range(&p, kernel, field);
                tf.clone().with_range(lo, hi).unwrap()
            }
        };
        let (r, rs) = render_reference(&p, &cam, &tf, &prm).unwrap();
        let a = render_adaptive(&p, None, &cam, &tf, &prm).unwrap();
        assert_eq!(rs.depth_samples, a.stats.depth_samples);
        let covered = r.rgba.iter().filter(|c| c[3] > 0.01).count();
        assert!(
            covered > 300,
            "{parallel} {field:?}: scene too empty: {covered} pixels"
        );
        let m = max_abs(&r, &a.image);
        // The grid renderer's lane loops (span.rs) do the reference's arithmetic in its order
        // in single precision (the reference: double), so the images agree to f32 rounding:
        // a few ulps of the colour, far below an 8-bit step (3.9e-3).
        assert!(m <= 2e-6, "{parallel} {field:?} {kernel:?}: max abs {m}");
        let dz = compare(&r, &a.image, 1.0).unwrap().0.depth_max_abs;
        assert!(
            dz == 0.0,
            "{parallel} {field:?} {kernel:?}: depth differs by {dz}"
        );
        assert_eq!(rs.samples, a.stats.samples, "same samples composited");
        // At full rate every span (a run of up to MAX_SPAN_SAMPLES depths) reads each
        // particle of its cells once: the distinct particles of each span's cells.
        let distinct: usize = (0..a.grid.bundle_count())
            .flat_map(|b| a.plan.bundle_spans(b).iter())
            .map(|s| {
                let cells = &a.grid.cells[s.first as usize..(s.first + s.count) as usize];
                let refs = cells
                    .iter()
                    .flat_map(|c| &a.grid.refs[c.start as usize..c.end as usize]);
                refs.collect::<std::collections::BTreeSet<_>>().len()
            })
            .sum();
        let plan = a.stats.plan.as_ref().unwrap();
        assert_eq!(plan.refs_sampled, distinct as u64);
        assert!(plan.merged_cells > 0 && plan.refs_sampled < a.stats.pairs);
    }
}

/// `../shared/data/` beside the repository (see `fluidcast_testkit::shared_data`).
fn shared(rel: &str) -> Option<PathBuf> {
    fluidcast_testkit::shared_data(rel)
}

/// The shared datasets with an attribute, as a user would render them.
fn shared_scenes() -> Vec<(String, Particles)> {
    let mut out = Vec::new();
    for (file, array) in [
        (
            "splash_doubledambreak/DoubleDamBreak_r0.0125_0011.vtu",
            "velocity:mag",
        ),
        (
            "splash_doubledambreak/DoubleDamBreak_r0.0125_0011.vtu",
            "object_id",
        ),
        (
            "pysph_dambreak3d/dam_break_3d_fluid_01180.vtu",
            "velocity:mag",
        ),
        ("pysph_dambreak3d/dam_break_3d_fluid_01180.vtu", "p"),
    ] {
        let Some(path) = shared(file) else {
            continue;
        };
        let ds = fluidcast_io::read_dataset(&path).unwrap();
        let spec = ParticleSpec {
            quantity: Some(array.parse::<Quantity>().unwrap()),
            radius: RadiusSource::Auto,
            volume: VolumeSource::Auto,
            mass: None,
        };
        out.push((
            format!("{file} {array}"),
            Particles::from_dataset(&ds, &spec).unwrap(),
        ));
    }
    out
}

fn data_tf(p: &Particles) -> TransferFunction {
    let (lo, hi) = p.value_range();
    let (blo, bhi) = p.support_bounds();
    let diag = (0..3)
        .map(|k| ((bhi[k] - blo[k]) as f64).powi(2))
        .sum::<f64>()
        .sqrt();
    let mut tf = TransferFunction::preset("Viridis")
        .unwrap()
        .with_range(lo as f64, (hi as f64).max(lo as f64 + 1e-6))
        .unwrap();
    tf.unit_distance = diag / (p.len() as f64).cbrt();
    tf
}

/// Orbit of 8 views, each at E_I = 0.001, 0.004 and 0.01: strict never above E_I (and never
/// interpolates); returns the relaxed renders' pixels above E_I, pixels, and pixels
/// interpolated.
fn check_scene(
    name: &str,
    p: &Particles,
    tf: &TransferFunction,
    size: (u32, u32),
) -> (u64, u64, u64) {
    let surface = p.surface_flags(fluidcast_render::SURFACE_THRESHOLD);
    let (mut above, mut total, mut interpolated) = (0u64, 0u64, 0u64);
    for v in 0..8 {
        let cam = camera_for(p, 45.0 * v as f64, 25.0 - 10.0 * (v % 3) as f64, false);
        let off =
            render_adaptive(p, Some(&surface), &cam, tf, &params(size.0, size.1, None)).unwrap();
        for e in [0.001, 0.004, 0.01] {
            let mut prm = params(size.0, size.1, Some(e));
            prm.adaptive = prm.adaptive.strict();
            let s = render_adaptive(p, Some(&surface), &cam, tf, &prm).unwrap();
            assert_eq!(
                s.stats.interpolated, 0,
                "{name}, view {v}: strict interpolated"
            );
            let m = max_abs(&off.image, &s.image);
            assert!(
                m <= e,
                "{name}, view {v}, strict E_I = {e}: max abs error {m}"
            );
            let r = render_adaptive(
                p,
                Some(&surface),
                &cam,
                tf,
                &params(size.0, size.1, Some(e)),
            )
            .unwrap();
            let (a, t) = count_above(&off.image, &r.image, e);
            above += a;
            total += t;
            interpolated += r.stats.interpolated;
        }
    }
    eprintln!("{name}: {above} of {total} pixels above E_I, {interpolated} interpolated");
    (above, total, interpolated)
}

/// The relaxed share must bite on image-space interpolation too: the relaxed renders of
/// `check_scene` interpolated a real part of their pixels (at least `share` of all pixels,
/// background included: 6–14 % measured where the plan leaves bundles at full rate).
fn assert_interpolates(name: &str, (_, total, interpolated): (u64, u64, u64), share: f64) {
    assert!(
        interpolated as f64 >= share * total as f64,
        "{name}: only {interpolated} of {total} pixels interpolated"
    );
}

#[test]
fn strict_bound_and_relaxed_share_on_radial_concentration() {
    let p = radial(1.0 / 18.0);
    let tf = banded((0.0, 1.8), 12, 0.15);
    let counts = check_scene("radial", &p, &tf, (192, 144));
    assert_interpolates("radial", counts, 0.04);
    let (above, total, _) = counts;
    let share = above as f64 / total as f64;
    assert!(
        share <= 0.0005,
        "relaxed: {above} of {total} pixels above E_I"
    );
}

/// The paper's Checker Board: blocks of constant value. Cells inside a block have
/// zero-width bounds, so even the strict plan adapts, and the bound is tested where levels
/// change.
#[test]
fn strict_plan_adapts_on_a_checker_board() {
    let mut p = radial(1.0 / 24.0);
    for (x, v) in p.positions.iter().zip(p.values.iter_mut()) {
        let b = x.map(|c| ((c + 0.5) * 2.0).floor().clamp(0.0, 1.0) as i32);
        *v = (b[0] + 2 * b[1] + 4 * b[2]) as f32;
    }
    // Blocks 0–3 transparent, 4–7 banded: bundles that see only transparent blocks adapt
    // even under the strict bound (every other bundle crosses a block boundary somewhere
    // along its rays, which alone exceeds E_I).
    let mut tf = banded((0.0, 7.0), 4, 0.3);
    tf.opacity = vec![(0.0, 0.0), (0.49, 0.0), (0.51, 0.6), (1.0, 0.3)];
    let counts = check_scene("checker board", &p, &tf, (256, 192));
    assert_interpolates("checker board", counts, 0.04);
    let (above, total, _) = counts;
    assert!(
        above as f64 <= 0.0005 * total as f64,
        "relaxed: {above} of {total} pixels above E_I"
    );
    let cam = camera_for(&p, 30.0, 20.0, false);
    let mut prm = params(128, 96, Some(0.01));
    prm.adaptive = prm.adaptive.strict();
    let s = render_adaptive(&p, None, &cam, &tf, &prm).unwrap();
    let st = s.stats.plan.unwrap();
    assert!(st.level_cells[1..].iter().sum::<u64>() > 0, "{st:?}");
}

#[test]
fn strict_bound_and_relaxed_share_on_shared_data() {
    let (mut above, mut total) = (0, 0);
    for (name, p) in shared_scenes() {
        let tf = data_tf(&p);
        let (a, t, _) = check_scene(&name, &p, &tf, (96, 72));
        above += a;
        total += t;
    }
    if total > 0 {
        let share = above as f64 / total as f64;
        assert!(
            share <= 0.0005,
            "relaxed: {above} of {total} pixels above E_I"
        );
    }
}

/// The relaxed promise where image-space interpolation bites on real data: the shared
/// scenes at 800 × 600 (supports several pixels wide), two views each, the default relaxed
/// plan at E_I = 0.004 against full rate: at most 0.05 % of the pixels above E_I, with a
/// real share of them interpolated.
#[test]
fn relaxed_share_with_interpolation_on_shared_data() {
    let (w, h) = (800, 600);
    let (mut above, mut total, mut interpolated) = (0, 0, 0);
    let scenes = shared_scenes();
    assert!(!scenes.is_empty(), "no shared data");
    for (name, p) in scenes {
        let tf = data_tf(&p);
        for v in 0..2 {
            let cam = camera_for(&p, 35.0 + 60.0 * v as f64, 20.0, false);
            let off = render_adaptive(&p, None, &cam, &tf, &params(w, h, None)).unwrap();
            let r = render_adaptive(&p, None, &cam, &tf, &params(w, h, Some(0.004))).unwrap();
            let (a, t) = count_above(&off.image, &r.image, 0.004);
            eprintln!(
                "{name}, view {v}: {a} of {t} above E_I, {} interpolated",
                r.stats.interpolated
            );
            (above, total, interpolated) =
                (above + a, total + t, interpolated + r.stats.interpolated);
        }
    }
    assert!(
        above as f64 <= 0.0005 * total as f64,
        "relaxed: {above} of {total} pixels above E_I"
    );
    assert_interpolates("shared data", (above, total, interpolated), 0.04);
}

/// Full rate sums in single precision, the reference in double: on real data (the shared
/// frames, PySPH's with its own per-particle smoothing lengths and Wendland C2, where
/// particles of different sizes meet at support edges) every pixel that differs by more
/// than 1e-3 must be an edge or an opaque sample of `precision::f32_explanation` (recast in
/// f64), and few may differ at all; also seen from far away.
#[test]
fn full_rate_differs_from_the_reference_only_by_f32_rounding() {
    let scenes = [
        (
            "splash_doubledambreak/DoubleDamBreak_r0.0125_0011.vtu",
            RadiusSource::Auto,
            Kernel::CubicSpline,
        ),
        (
            "pysph_dambreak3d/dam_break_3d_fluid_01180.vtu",
            RadiusSource::Array {
                name: "h".into(),
                scale: 2.0,
            },
            Kernel::WendlandC2,
        ),
    ];
    for (file, radius, kernel) in scenes {
        let Some(path) = shared(file) else {
            continue;
        };
        let ds = fluidcast_io::read_dataset(&path).unwrap();
        let spec = ParticleSpec {
            quantity: Some("velocity:mag".parse::<Quantity>().unwrap()),
            radius,
            volume: VolumeSource::Auto,
            mass: None,
        };
        let p = Particles::from_dataset(&ds, &spec).unwrap();
        let tf = data_tf(&p);
        let (mut differ, mut px) = (0, 0);
        for v in 0..4 {
            let mut cam = camera_for(&p, 60.0 * v as f64, 30.0 - 15.0 * v as f64, v >= 2);
            if v == 3 {
                // A parallel view from 1000 times as far: the same image, at depths of ~1e5
                // support radii, where single precision is kept only by measuring depths
                // from the span's first sample.
                for k in 0..3 {
                    cam.position[k] =
                        cam.focal_point[k] + 1000.0 * (cam.position[k] - cam.focal_point[k]);
                }
            }
            let mut prm = params(256, 192, None);
            prm.kernel = kernel;
            let (r, _) = render_reference(&p, &cam, &tf, &prm).unwrap();
            let a = render_adaptive(&p, None, &cam, &tf, &prm).unwrap();
            let planned = fluidcast_render::plan_adaptive(&p, None, &cam, &tf, &prm).unwrap();
            let pixels = fluidcast_render::precision::differing_pixels(&r, &a.image);
            for &(i, j) in &pixels {
                let (edge, opaque) =
                    fluidcast_render::precision::f32_explanation(&planned, &tf, kernel, i, j);
                let k = (j * prm.width + i) as usize;
                assert!(
                    edge || opaque,
                    "{file} view {v}: pixel ({i}, {j}) differs (reference {:?}, full rate {:?}) \
                     with neither an edge nor an opaque sample on its ray",
                    r.rgba[k],
                    a.image.rgba[k]
                );
            }
            differ += pixels.len();
            px += r.rgba.len();
        }
        assert!(
            differ * 2000 <= px,
            "{file}: {differ} of {px} pixels differ"
        );
    }
}

/// A particle whose kernel weight single precision cannot sum (a volume of 1 with H = 1e-12:
/// V·W(0) ≈ 2.5e36) is refused naming it and the weight, before anything is rendered; the
/// same particle with a volume to match its size renders.
#[test]
fn weights_beyond_single_precision_are_refused() {
    let mut p = cloud(60, 5);
    let cam = camera_for(&p, 30.0, 20.0, false);
    let tf = TransferFunction::preset("Viridis")
        .unwrap()
        .with_range(-0.5, 1.0)
        .unwrap();
    p.radii[7] = 1e-12;
    for (field, volume, mass) in [
        (FieldKind::Csph, 1.0, 1e-36),
        (FieldKind::Density, 1e-36, 1.0),
    ] {
        p.volumes[7] = volume;
        p.masses[7] = mass;
        let mut prm = params(40, 30, Some(0.004));
        prm.field = field;
        let err = render_adaptive(&p, None, &cam, &tf, &prm).unwrap_err();
        let msg = err.to_string();
        assert!(
            matches!(err, fluidcast_render::RenderError::Weight { index: 7, .. })
                && msg.contains("particle 7")
                && msg.contains("single precision can sum"),
            "{msg}"
        );
    }
    p.volumes[7] = 1e-36;
    p.masses[7] = 1e-36;
    let a = render_adaptive(&p, None, &cam, &tf, &params(40, 30, Some(0.004))).unwrap();
    assert!(a.image.rgba.iter().flatten().all(|c| c.is_finite()));
}

fn pixel_it(c: [f32; 4]) -> [f64; 4] {
    [c[0] as f64, c[1] as f64, c[2] as f64, 1.0 - c[3] as f64]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, .. ProptestConfig::default() })]

    /// Every pixel of a bundle lies inside the bundle's bounds: full-rate pixels inside the
    /// full-rate bound, strict adaptive pixels inside the bound of the chosen plan.
    #[test]
    fn pixels_lie_inside_their_bundle_bounds(
        seed in 1u32..10_000,
        n in 20usize..120,
        azimuth in -180.0f64..180.0,
        elevation in -60.0f64..60.0,
        parallel in any::<bool>(),
        bands in 1usize..10,
        unit in 0.05f64..1.0,
        e in prop::sample::select(vec![0.001, 0.004, 0.01, 0.05]),
    ) {
        let p = cloud(n, seed);
        let tf = banded((-0.5, 1.0), bands, unit);
        let cam = camera_for(&p, azimuth, elevation, parallel);
        let mut prm = params(40, 30, Some(e));
        prm.adaptive = prm.adaptive.strict();
        prm.min_transmittance = 0.0;
        let s = render_adaptive(&p, None, &cam, &tf, &prm).unwrap();
        let mut off_prm = prm.clone();
        off_prm.adaptive.tolerance = None;
        let off = render_adaptive(&p, None, &cam, &tf, &off_prm).unwrap();
        for b in 0..s.grid.bundle_count() {
            let [x0, x1, y0, y1] = s.grid.bundle(b).pixels;
            for j in y0..y1 {
                for i in x0..x1 {
                    let idx = s.image.index(i, j);
                    let full = pixel_it(off.image.rgba[idx]);
                    let adapted = pixel_it(s.image.rgba[idx]);
                    prop_assert!(s.plan.full_bounds[b].contains(full, 1e-5),
                        "full-rate pixel ({i},{j}) {full:?} outside {:?}", s.plan.full_bounds[b]);
                    prop_assert!(s.plan.plan_bounds[b].contains(adapted, 1e-5),
                        "adaptive pixel ({i},{j}) {adapted:?} outside {:?}", s.plan.plan_bounds[b]);
                    prop_assert!(s.plan.plan_bounds[b].contains(full, 1e-5));
                }
            }
        }
    }
}

/// The strict guarantee where the strict plan does adapt: one half of a block holds a gentle
/// ramp under a faint part of the transfer function, the other an oscillating field under an
/// opaque part; looking along the oscillation, the bundles that see only the gentle half
/// coarsen (15–40 % of all cells here) and change the image, and no pixel moves by more than
/// E_I. (The depth-ramp test below is the one that catches a level bound without its
/// coarse-sampling term.)
#[test]
fn strict_plan_adapts_a_real_share_within_e_i() {
    let mut p = radial(1.0 / 20.0);
    for (x, v) in p.positions.iter().zip(p.values.iter_mut()) {
        *v = if x[0] < 0.0 {
            0.5 * (x[0] + x[1]) + 0.5
        } else {
            2.0 + 0.5 * (30.0 * x[2]).sin() * (20.0 * x[1]).cos()
        };
    }
    let mut tf = TransferFunction::preset("Viridis")
        .unwrap()
        .with_range(-2.0, 3.0)
        .unwrap();
    tf.opacity = vec![
        (0.0, 0.02),
        (0.6, 0.05),
        (0.7, 0.5),
        (0.9, 0.95),
        (1.0, 0.95),
    ];
    tf.unit_distance = 5.0;
    for (v, e) in [(0, 0.004), (1, 0.01), (2, 0.02)] {
        // Looking along z (the oscillation's direction), so that most bundles see one half.
        let cam = camera_for(&p, 8.0 * v as f64 - 8.0, 10.0, v == 2);
        let mut prm = params(96, 72, Some(e));
        prm.adaptive = prm.adaptive.strict();
        adapts_within_e_i(&p, &tf, &cam, &prm, 0.15, &format!("strict, view {v}"));
    }
}

/// Renders `p` at full rate and with `prm` (E_I its tolerance): at least `share` of the
/// cells adapt in depth, the image changes, and no pixel moves by more than E_I.
fn adapts_within_e_i(
    p: &Particles,
    tf: &TransferFunction,
    cam: &Camera,
    prm: &RenderParams,
    share: f64,
    what: &str,
) {
    let e = prm.adaptive.tolerance.expect("an adaptive plan");
    let mut full = prm.clone();
    full.adaptive.tolerance = None;
    let off = render_adaptive(p, None, cam, tf, &full).unwrap();
    let s = render_adaptive(p, None, cam, tf, prm).unwrap();
    let st = s.stats.plan.clone().unwrap();
    let adapted = st.level_cells[1..].iter().sum::<u64>();
    let m = max_abs(&off.image, &s.image);
    assert!(
        adapted as f64 >= share * st.cells as f64,
        "{what}, E_I = {e}: only {adapted} of {} cells adapt",
        st.cells
    );
    assert!(m > 0.0, "{what}, E_I = {e}: adapting changed nothing");
    assert!(m <= e, "{what}, E_I = {e}: max abs error {m}");
}

/// The strict guarantee where a coarse sample stands for values far from its own
/// ([`fluidcast_testkit::depth_ramp`]: the field grows along the view direction, 64 depth
/// samples per cell): about half the cells coarsen and change the image, within E_I. A level
/// bound without the coarse sample's term (`cell_bounds`' union) adapts as many cells but
/// misses by 2.4 E_I here.
#[test]
fn strict_plan_bounds_coarse_samples_along_a_depth_ramp() {
    let p = fluidcast_testkit::depth_ramp(20);
    for (alpha, e, azimuth, parallel) in fluidcast_testkit::DEPTH_RAMP_CASES {
        let tf = fluidcast_testkit::depth_ramp_tf(alpha);
        let cam = camera_for(&p, azimuth, 3.0, parallel);
        let mut prm = params(96, 72, None);
        prm.grid.depth_samples = 64;
        let off = render_adaptive(&p, None, &cam, &tf, &prm).unwrap();
        prm.adaptive = PlanParams {
            tolerance: Some(e),
            ..Default::default()
        }
        .strict();
        let s = render_adaptive(&p, None, &cam, &tf, &prm).unwrap();
        let st = s.stats.plan.clone().unwrap();
        let adapted = st.level_cells[1..].iter().sum::<u64>() as f64 / st.cells as f64;
        let m = max_abs(&off.image, &s.image);
        let what = format!("alpha {alpha}, azimuth {azimuth}, parallel {parallel}, E_I {e}");
        // The share is of every cell the grid has, each at one level.
        assert_eq!(st.cells, s.grid.cells.len() as u64, "{what}");
        let levels: u64 = st.level_cells.iter().sum::<u64>() + st.superpixel_cells;
        assert_eq!(levels, st.cells, "{what}: every cell has one level");
        assert!(
            adapted >= 0.3,
            "{what}: only {adapted:.3} of the cells adapt"
        );
        assert!(m > 0.0, "{what}: adapting changed nothing");
        assert!(m <= e, "{what}: strict max abs error {m} above E_I");
        // Early termination at transmittance t may move a pixel by t, so a bundle that adapts
        // must keep its plan's bound within E_I - t (here t = E_I / 5).
        prm.min_transmittance = e / 5.0;
        let s = render_adaptive(&p, None, &cam, &tf, &prm).unwrap();
        let adapting = s.plan.summaries.iter().filter(|b| b.adapted > 0.0);
        let worst = adapting
            .clone()
            .map(|b| b.predicted_error)
            .fold(0.0f32, f32::max);
        assert!(
            adapting.count() > 0,
            "{what}: nothing adapts with early termination"
        );
        assert!(worst as f64 <= 0.8 * e + 1e-6, "{what}: predicted {worst}");
        prm.min_transmittance = RenderParams::default().min_transmittance;
    }
}

/// The cap of a cell's level sees the fluid in front of it: behind a front that hides all
/// but a few per cent, the relaxed plan (no super-pixels, so that only depth levels count)
/// coarsens a quarter of the cells although each back cell's own bound is wider than E_I
/// (a cap that takes the front as transparent adapts 17 of 233 cells here), and no pixel
/// moves by more than E_I,
/// in both projections. (A strict plan adapts nothing here: the strict bound of the front's
/// face, where some rays may still miss the fluid, is wider than E_I by itself.)
#[test]
fn relaxed_plan_coarsens_what_the_front_hides() {
    let (p, tf) = fluidcast_testkit::behind_a_front();
    let e = 0.01;
    for parallel in [false, true] {
        let cam = camera_for(&p, 5.0, 3.0, parallel);
        let mut prm = params(96, 72, Some(e));
        prm.adaptive.superpixels = false;
        // The plan's cap alone (interpolation is measured by `check_scene`'s share).
        prm.adaptive.interpolate = false;
        adapts_within_e_i(&p, &tf, &cam, &prm, 0.2, &format!("parallel {parallel}"));
    }
}

/// Cell merging (Sec. 6.2) joins only what samples alike, and all of it: each bundle's spans
/// cover its cells in order; a span is one cell, or 2^k consecutive cells of one level l
/// (full rate included) that sample at most `MAX_SPAN_SAMPLES` depths (2^k · D_z / 2^l), its
/// first cell's depth index a multiple of 2^k; a super-pixel stands alone; and no two
/// neighbouring spans could still be joined (same level and size, aligned, adjacent, within
/// the samples). Strict and relaxed plans on the depth ramp, where many cells coarsen.
#[test]
fn merged_spans_are_aligned_runs_of_one_level_and_maximal() {
    let mut merged = 0;
    for (what, a) in ramp_plans() {
        let m = check_spans(&a.grid, &a.plan);
        eprintln!("{what}: {m} of {} cells merged", a.grid.cells.len());
        merged += m;
    }
    eprintln!("cells merged into a neighbour: {merged}");
    assert!(merged > 100, "merging hardly happens: {merged}");
}

/// Strict and relaxed plans of the depth ramp's views at D_z = 8 and 16, and relaxed ones
/// without super-pixels (in front of which coarser levels are not relaxed): many cells per
/// bundle, many of them coarsened.
fn ramp_plans() -> Vec<(String, fluidcast_render::AdaptivePlan)> {
    let p = fluidcast_testkit::depth_ramp(20);
    let mut out = Vec::new();
    for (alpha, e, azimuth, parallel) in fluidcast_testkit::DEPTH_RAMP_CASES {
        let tf = fluidcast_testkit::depth_ramp_tf(alpha);
        let cam = camera_for(&p, azimuth, 3.0, parallel);
        let plans = [
            (8, true, true),
            (16, true, true),
            (8, false, true),
            (16, false, true),
            (16, false, false),
        ];
        for (dz, strict, sp) in plans {
            let mut prm = params(96, 72, Some(e));
            prm.grid.depth_samples = dz;
            prm.adaptive.superpixels = sp;
            if strict {
                prm.adaptive = prm.adaptive.strict();
            }
            let a = fluidcast_render::plan_adaptive(&p, None, &cam, &tf, &prm).unwrap();
            out.push((
                format!("azimuth {azimuth}, D_z {dz}, strict {strict}, super-pixels {sp}"),
                a,
            ));
        }
    }
    out
}

/// Each bundle's summary counts its own cells: the shares at full rate, adapted in depth and
/// drawn as super-pixels, and the mean level of the sampled ones (what the AOVs show).
#[test]
fn bundle_summaries_count_their_cells() {
    let mut mixed = 0;
    for (what, a) in ramp_plans() {
        for (b, s) in a.plan.summaries.iter().enumerate() {
            let want = counted_summary(bundle_levels(&a.grid, &a.plan, b));
            let got = [s.full, s.adapted, s.superpixel, s.mean_level];
            for (g, w) in got.iter().zip(want) {
                assert!(
                    (g - w).abs() < 1e-6,
                    "{what}, bundle {b}: {got:?} vs {want:?}"
                );
            }
            mixed += usize::from(want[0] > 0.0 && want[1] > 0.0);
        }
    }
    eprintln!("bundles that mix full-rate and adapted cells: {mixed}");
    assert!(
        mixed > 20,
        "only {mixed} bundles mix full-rate and adapted cells"
    );
}

/// The levels the plan chose for bundle `b`'s cells.
fn bundle_levels<'a>(
    grid: &fluidcast_grid::PerspectiveGrid,
    plan: &'a fluidcast_render::SamplingPlan,
    b: usize,
) -> &'a [u8] {
    let first = grid.bundle_first_cell(b);
    &plan.cell_levels[first..first + grid.bundle_cells(b).len()]
}

/// A bundle's summary counted from its cells' levels: the shares at full rate, adapted and
/// super-pixels, and the mean level of the sampled cells.
fn counted_summary(levels: &[u8]) -> [f32; 4] {
    let sp = fluidcast_render::SamplingPlan::SUPERPIXEL;
    let n = levels.len().max(1) as f32;
    let count = |f: &dyn Fn(u8) -> bool| levels.iter().filter(|&&l| f(l)).count();
    let (full, sps) = (count(&|l| l == 0), count(&|l| l == sp));
    let adapted = levels.len() - full - sps;
    let lsum: u32 = levels.iter().filter(|&&l| l != sp).map(|&l| l as u32).sum();
    let mean = lsum as f32 / (full + adapted).max(1) as f32;
    [full as f32 / n, adapted as f32 / n, sps as f32 / n, mean]
}

/// Checks [`merged_spans_are_aligned_runs_of_one_level_and_maximal`]'s rules on every
/// bundle of a plan; returns the number of cells merged into a neighbour.
/// Whether merging the run of `a.1` cells from cell `a.0` with the run `b` behind it pays:
/// the particles of `a`'s last cell that `b` also holds (what the merge saves reading again)
/// are at least `b`'s other distinct particles (what it may read in vain). Counted from the
/// cells' references, without their merge bits.
fn pays(grid: &fluidcast_grid::PerspectiveGrid, a: (usize, usize), b: (usize, usize)) -> bool {
    use std::collections::BTreeSet;
    let refs = |c: &fluidcast_grid::Cell| &grid.refs[c.start as usize..c.end as usize];
    let last: BTreeSet<u32> = refs(&grid.cells[a.0 + a.1 - 1]).iter().copied().collect();
    let behind: BTreeSet<u32> = grid.cells[b.0..b.0 + b.1]
        .iter()
        .flat_map(refs)
        .copied()
        .collect();
    let shared = last.intersection(&behind).count();
    shared >= behind.len() - shared
}

fn check_spans(
    grid: &fluidcast_grid::PerspectiveGrid,
    plan: &fluidcast_render::SamplingPlan,
) -> u64 {
    let sp_level = fluidcast_render::SamplingPlan::SUPERPIXEL;
    let mut merged = 0u64;
    for b in 0..grid.bundle_count() {
        let first = grid.bundle_first_cell(b);
        let n = grid.bundle_cells(b).len();
        let spans = plan.bundle_spans(b);
        let mut next = first;
        for (k, s) in spans.iter().enumerate() {
            let (f, c) = (s.first as usize, s.count as usize);
            assert_eq!(f, next, "bundle {b}: spans out of order");
            next += c;
            assert!(c.is_power_of_two());
            let z0 = grid.cells[f].z as usize;
            for i in 0..c {
                assert_eq!(grid.cells[f + i].z as usize, z0 + i, "bundle {b}: a gap");
            }
            if s.superpixel.is_some() {
                assert_eq!(c, 1);
                assert_eq!(plan.cell_levels[f], sp_level);
                continue;
            }
            assert!(plan.cell_levels[f..f + c].iter().all(|&l| l == s.level));
            let dz = grid.params.depth_samples as usize;
            let fits = |cells: usize| (cells * dz) >> s.level <= MAX_SPAN_SAMPLES as usize;
            assert!(c == 1 || fits(c), "bundle {b}: {s:?}");
            // A span beyond D_z samples merged two halves where that pays.
            let within_dz = |cells: usize| (cells * dz) >> s.level <= dz;
            let h = c / 2;
            assert!(
                c == 1 || within_dz(c) || pays(grid, (f, h), (f + h, h)),
                "bundle {b}: {s:?} merged where it does not pay"
            );
            assert_eq!(z0 % c, 0, "bundle {b}: {s:?} not aligned");
            merged += (c - 1) as u64;
            if let Some(t) = spans.get(k + 1) {
                let joinable = t.superpixel.is_none()
                    && t.level == s.level
                    && t.count as usize == c
                    && fits(2 * c)
                    && z0.is_multiple_of(2 * c)
                    && grid.cells[t.first as usize].z as usize == z0 + c
                    && (within_dz(2 * c) || pays(grid, (f, c), (t.first as usize, c)));
                assert!(!joinable, "bundle {b}: {s:?} and {t:?} left apart");
            }
        }
        assert_eq!(next, first + n, "bundle {b}: spans miss cells");
    }
    assert_eq!(plan.stats.merged_cells, merged);
    merged
}

/// The AOVs hold the plan's numbers at the right pixels: in strict mode every pixel's error
/// against full rate lies within its `error_bound`; `level` is the mean level of the pixel's
/// bundle's sampled cells and `superpixel` their share drawn as super-pixels, counted here
/// from the plan's cell levels and the bundle's pixel rectangle. (The relaxed plan runs on
/// the same block with one constant value, where every cell that adapts becomes a
/// super-pixel.)
#[test]
fn aovs_hold_each_bundles_bound_level_and_superpixel_share() {
    let ramp = fluidcast_testkit::depth_ramp(20);
    let mut constant = ramp.clone();
    constant.values.iter_mut().for_each(|v| *v = 0.1);
    let (alpha, e, azimuth, parallel) = fluidcast_testkit::DEPTH_RAMP_CASES[0];
    let tf = fluidcast_testkit::depth_ramp_tf(alpha);
    let cam = camera_for(&ramp, azimuth, 3.0, parallel);
    let mut prm = params(90, 70, None);
    prm.grid.depth_samples = 64;
    let aov = |img: &Image, name: &str| -> Vec<f32> {
        let a = img.aovs.iter().find(|(n, _)| n == name);
        a.unwrap_or_else(|| panic!("no AOV {name}")).1.clone()
    };
    let strict = PlanParams {
        tolerance: Some(e),
        ..Default::default()
    };
    // Every bundle analysed: the probe would find that the relaxed block, with few bundles,
    // does not pay (probe_plans_the_rest_at_full_rate_where_adapting_does_not_pay).
    let relaxed = PlanParams {
        probe: false,
        ..Default::default()
    };
    for (mode, p, plan) in [
        ("strict", &ramp, strict.strict()),
        ("relaxed", &constant, relaxed),
    ] {
        prm.adaptive.tolerance = None;
        let off = render_adaptive(p, None, &cam, &tf, &prm).unwrap();
        prm.adaptive = plan;
        let s = render_adaptive(p, None, &cam, &tf, &prm).unwrap();
        let (bound, level, sp) = (
            aov(&s.image, "error_bound"),
            aov(&s.image, "level"),
            aov(&s.image, "superpixel"),
        );
        let mut seen = [0usize; 3];
        for b in 0..s.grid.bundle_count() {
            let [_, _, share, mean] = counted_summary(bundle_levels(&s.grid, &s.plan, b));
            let [x0, x1, y0, y1] = s.grid.bundle(b).pixels;
            for j in y0..y1 {
                for i in x0..x1 {
                    let k = s.image.index(i, j);
                    assert!(
                        (level[k] - mean).abs() < 1e-6,
                        "{mode} ({i},{j}): level {} vs {mean}",
                        level[k]
                    );
                    assert!(
                        (sp[k] - share).abs() < 1e-6,
                        "{mode} ({i},{j}): superpixel {} vs {share}",
                        sp[k]
                    );
                    let err = (0..4)
                        .map(|c| (s.image.rgba[k][c] - off.image.rgba[k][c]).abs())
                        .fold(0.0f32, f32::max);
                    if mode == "strict" {
                        assert!(
                            err <= bound[k] + 1e-5,
                            "({i},{j}): error {err} above its bound {}",
                            bound[k]
                        );
                    }
                    seen[0] += usize::from(bound[k] > 0.0);
                    seen[1] += usize::from(level[k] > 0.0);
                    seen[2] += usize::from(sp[k] > 0.0);
                }
            }
        }
        eprintln!("{mode}: pixels with a bound, an adapted level, super-pixels: {seen:?}");
        // Levels show in the strict plan; the relaxed one draws every cell it can coarsen as
        // a super-pixel, the cheapest option.
        assert!(seen[0] > 0, "{mode}: {seen:?}");
        assert_eq!(mode == "strict", seen[1] > 0, "{mode}: levels {seen:?}");
        assert!(
            (mode == "relaxed") == (seen[2] > 0),
            "{mode}: super-pixels {seen:?}"
        );
    }
}

/// The probe ([`PlanParams::probe`]): its bundles are planned exactly as without it (each
/// bundle is planned on its own). Where it pays, so is every other bundle; where it does not,
/// the others are at full rate, counted as not analysed, and their pixels are the full-rate
/// image's, bit for bit. On the depth ramp the relaxed plan (its surface cells at full rate)
/// does not pay, the strict one (a third of the cells adapt) does.
#[test]
fn probe_plans_the_rest_at_full_rate_where_adapting_does_not_pay() {
    let p = fluidcast_testkit::depth_ramp(20);
    let (alpha, e, azimuth, parallel) = fluidcast_testkit::DEPTH_RAMP_CASES[0];
    let tf = fluidcast_testkit::depth_ramp_tf(alpha);
    let cam = camera_for(&p, azimuth, 3.0, parallel);
    let mut paid = Vec::new();
    for strict in [false, true] {
        let mut prm = params(96, 72, Some(e));
        prm.grid.depth_samples = 64;
        prm.adaptive.interpolate = false;
        if strict {
            prm.adaptive = prm.adaptive.strict();
        }
        let with = render_adaptive(&p, None, &cam, &tf, &prm).unwrap();
        prm.adaptive.probe = false;
        let without = render_adaptive(&p, None, &cam, &tf, &prm).unwrap();
        prm.adaptive.tolerance = None;
        let off = render_adaptive(&p, None, &cam, &tf, &prm).unwrap();
        let g = &with.grid;
        let in_probe = |b: usize| {
            let (x, y) = (b as u32 % g.bundles_x, b as u32 / g.bundles_x);
            (x + fluidcast_plan::PROBE_ROW_SHIFT * y).is_multiple_of(fluidcast_plan::PROBE_STRIDE)
        };
        let nb = g.bundle_count();
        let probe = (0..nb).filter(|&b| in_probe(b)).count();
        assert!(
            probe > 4 && probe < nb / 4,
            "{probe} of {nb} bundles in the probe"
        );
        for b in (0..nb).filter(|&b| in_probe(b)) {
            let (a, z) = (&with, &without);
            let want = bundle_levels(&z.grid, &z.plan, b);
            assert_eq!(bundle_levels(&a.grid, &a.plan, b), want, "probe bundle {b}");
        }
        let skipped = with.plan.stats.unanalysed_bundles;
        paid.push(skipped == 0);
        if skipped == 0 {
            assert_eq!(with.plan.cell_levels, without.plan.cell_levels);
            assert_eq!(with.image.rgba, without.image.rgba);
            continue;
        }
        let rest = (0..nb).filter(|&b| !in_probe(b) && !g.bundle_cells(b).is_empty());
        assert_eq!(skipped as usize, rest.count(), "strict {strict}");
        for b in (0..nb).filter(|&b| !in_probe(b)) {
            let got = bundle_levels(&with.grid, &with.plan, b);
            assert!(got.iter().all(|&l| l == 0), "bundle {b}");
            assert_eq!(with.plan.summaries[b].full, 1.0);
            let [x0, x1, y0, y1] = g.bundle(b).pixels;
            for (i, j) in (y0..y1).flat_map(|j| (x0..x1).map(move |i| (i, j))) {
                let k = with.image.index(i, j);
                assert_eq!(with.image.rgba[k], off.image.rgba[k], "({i},{j})");
            }
        }
        let adapted = |r: &fluidcast_render::AdaptiveRender| {
            r.plan.cell_levels.iter().filter(|&&l| l != 0).count()
        };
        assert!(adapted(&without) > adapted(&with), "strict {strict}");
    }
    assert_eq!(paid, [false, true], "relaxed, strict");
}

/// The plan's counts are those of its cells, summed over every bundle: cells per level and
/// super-pixels as `cell_levels` holds them, and surface cells (forced to full rate) present
/// with the surface rule, absent without it. A block of one constant value: its inside
/// becomes super-pixels, its boundary particles are surface particles.
#[test]
fn plan_stats_count_the_cells_of_each_kind() {
    let mut block = fluidcast_testkit::depth_ramp(20);
    block.values.iter_mut().for_each(|v| *v = 0.1);
    let (alpha, _, azimuth, parallel) = fluidcast_testkit::DEPTH_RAMP_CASES[0];
    let tf = fluidcast_testkit::depth_ramp_tf(alpha);
    let cam = camera_for(&block, azimuth, 3.0, parallel);
    let mut prm = params(90, 70, Some(0.004));
    prm.grid.depth_samples = 64;
    // Every bundle analysed (the probe finds that this small block does not pay).
    prm.adaptive.probe = false;
    let mut counts = Vec::new();
    for surface_rule in [true, false] {
        prm.adaptive.surface_cells = surface_rule;
        let a = fluidcast_render::plan_adaptive(&block, None, &cam, &tf, &prm).unwrap();
        let (levels, st) = (&a.plan.cell_levels, &a.plan.stats);
        assert!(a.grid.bundle_count() > 1);
        assert_eq!(st.cells, levels.len() as u64);
        for (l, &n) in st.level_cells.iter().enumerate() {
            let want = levels.iter().filter(|&&x| x as usize == l).count() as u64;
            assert_eq!(n, want, "level {l}");
        }
        let sp = levels
            .iter()
            .filter(|&&x| x == fluidcast_render::SamplingPlan::SUPERPIXEL)
            .count() as u64;
        assert_eq!(st.superpixel_cells, sp);
        assert!(sp > 0, "the block's inside becomes super-pixels");
        assert!(st.surface_cells <= st.level_cells[0]);
        assert_eq!(st.surface_cells > 0, surface_rule, "{st:?}");
        counts.push(st.clone());
    }
    eprintln!("with and without the surface rule: {counts:?}");
    assert!(counts[0].level_cells[0] > counts[1].level_cells[0]);
}

/// The transfer-function range of a field over the particles (CSPH: the values; SPH and
/// density: the field sampled at the particles).
fn field_range(p: &Particles, kernel: Kernel, field: FieldKind) -> (f64, f64) {
    if field == FieldKind::Csph {
        let (lo, hi) = p.value_range();
        return (lo as f64, hi as f64);
    }
    let pos: Vec<[f64; 3]> = p.positions.iter().map(|x| x.map(f64::from)).collect();
    let v: Vec<f64> = p
        .sample_many(kernel, &pos)
        .iter()
        .filter_map(|s| s.value(field))
        .collect();
    let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    (lo, hi.max(lo + 1e-9))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, .. ProptestConfig::default() })]

    /// The strict guarantee over scenes (the depth ramp, layers with gaps, a lateral ramp), kernels, field
    /// kinds, bundle sizes, depth samples per cell, projections and opaque geometry, with E_I
    /// chosen where the plan must adapt (twice the median full-rate bound): every case adapts
    /// some cells, no pixel moves by more than E_I, and every pixel, adaptive and full-rate,
    /// lies inside its bundle's plan bound.
    #[test]
    fn strict_plans_adapt_and_hold_everywhere(
        scene in 0..3usize,
        kernel in prop::sample::select(Kernel::ALL.to_vec()),
        field in prop::sample::select(vec![FieldKind::Csph, FieldKind::Sph, FieldKind::Density]),
        bundle in prop::sample::select(vec![1u32, 2, 3, 5, 8, 12, 16]),
        depth_samples in prop::sample::select(vec![4u32, 8, 16, 32, 64]),
        azimuth in -20.0f64..20.0,
        elevation in -20.0f64..20.0,
        parallel in any::<bool>(),
        alpha in 0.005f64..0.03,
        limit in prop::option::of((0.2f64..0.9, 0.3f64..1.0)),
    ) {
        // The depth ramp, layers with gaps, or the block with a lateral ramp (x): pixels then
        // differ across the image, which the SPH and density sums' bounds must follow.
        let p = match scene {
            0 => fluidcast_testkit::depth_ramp(10),
            1 => fluidcast_testkit::layers(3, 0.5, 0.1),
            _ => {
                let mut p = fluidcast_testkit::depth_ramp(10);
                for (x, v) in p.positions.iter().zip(p.values.iter_mut()) {
                    *v = x[0];
                }
                p
            }
        };
        let mut tf = fluidcast_testkit::depth_ramp_tf(alpha);
        let (lo, hi) = field_range(&p, kernel, field);
        tf = tf.with_range(lo, hi).unwrap();
        let cam = camera_for(&p, azimuth, elevation, parallel);
        let (w, h) = (40u32, 30u32);
        let mut prm = params(w, h, None);
        prm.kernel = kernel;
        prm.field = field;
        prm.grid = GridParams { bundle, depth_samples };
        // No early termination: its allowance would leave no budget at the smallest E_I.
        prm.min_transmittance = 0.0;
        let mut off = render_adaptive(&p, None, &cam, &tf, &prm).unwrap();
        if let Some((depth, share)) = limit {
            // An opaque wall over the left part of the image, at a depth inside the data.
            let z = (off.stats.near + depth * (off.stats.far - off.stats.near)) as f32;
            let cut = (share * w as f64) as u32;
            let d: Vec<f32> = (0..w * h)
                .map(|k| if k % w < cut { z } else { f32::INFINITY })
                .collect();
            prm.depth_limit = Some(std::sync::Arc::from(d));
            off = render_adaptive(&p, None, &cam, &tf, &prm).unwrap();
        }
        // Without the probe: it may (rightly) leave every bundle unanalysed where its eighth
        // predicts too small a saving (the layers seen nearly edge-on, bundle 5, depth 4:
        // 22 bundles), and this property is about plans that adapt.
        prm.adaptive = PlanParams { tolerance: Some(1.0), probe: false, ..Default::default() }.strict();
        let probe = render_adaptive(&p, None, &cam, &tf, &prm).unwrap();
        // Twice the median full-rate bound of the bundles that see particles.
        let mut widths: Vec<f64> = probe.plan.full_bounds.iter().map(|b| b.width()).filter(|&w| w > 0.0).collect();
        widths.sort_by(f64::total_cmp);
        prop_assert!(!widths.is_empty(), "no bundle sees the particles");
        let e = (2.0 * widths[widths.len() / 2]).min(0.5);
        prm.adaptive.tolerance = Some(e);
        let s = render_adaptive(&p, None, &cam, &tf, &prm).unwrap();
        let st = s.stats.plan.clone().unwrap();
        let adapted = st.level_cells[1..].iter().sum::<u64>();
        prop_assert!(adapted > 0, "E_I {e}: nothing adapted of {} cells", st.cells);
        let m = max_abs(&off.image, &s.image);
        prop_assert!(m <= e + 1e-6, "E_I {e}: max abs error {m}");
        for b in 0..s.grid.bundle_count() {
            let [x0, x1, y0, y1] = s.grid.bundle(b).pixels;
            for j in y0..y1 {
                for i in x0..x1 {
                    let k = s.image.index(i, j);
                    for (what, px) in [("adaptive", s.image.rgba[k]), ("full-rate", off.image.rgba[k])] {
                        let px = pixel_it(px);
                        prop_assert!(s.plan.plan_bounds[b].contains(px, 1e-5),
                            "{what} ({i},{j}) {px:?} outside {:?}", s.plan.plan_bounds[b]);
                    }
                }
            }
        }
    }
}

/// The default relaxed plan where it bites: on the depth ramp and on layers with gaps, under
/// faint transfer functions, a real share of the cells coarsens or becomes super-pixels
/// (>= 20 % over all views), no pixel moves by more than 2 E_I, and at most 0.05 % of all
/// pixels move by more than E_I (the relaxed promise; measured: 39 of 110,592, 28 % of cells
/// adapted).
#[test]
fn relaxed_plan_adapts_and_caps_its_excess() {
    let scenes = [
        ("ramp", fluidcast_testkit::depth_ramp(20)),
        ("layers", fluidcast_testkit::layers(3, 0.5, 0.05)),
    ];
    let (mut above, mut pixels, mut adapted, mut cells) = (0u64, 0u64, 0u64, 0u64);
    for (name, p) in &scenes {
        for alpha in [0.01, 0.05] {
            let tf = fluidcast_testkit::depth_ramp_tf(alpha)
                .with_range(-0.5, 2.5)
                .unwrap();
            for azimuth in [5.0, -10.0] {
                let cam = camera_for(p, azimuth, 3.0, false);
                let off = render_adaptive(p, None, &cam, &tf, &params(96, 72, None)).unwrap();
                for e in [0.004, 0.01] {
                    // The plan's relaxed cap alone (interpolation is measured by
                    // `check_scene`'s share).
                    let mut prm = params(96, 72, Some(e));
                    prm.adaptive.interpolate = false;
                    let s = render_adaptive(p, None, &cam, &tf, &prm).unwrap();
                    let st = s.stats.plan.clone().unwrap();
                    adapted += st.level_cells[1..].iter().sum::<u64>() + st.superpixel_cells;
                    cells += st.cells;
                    let (a, n) = count_above(&off.image, &s.image, e);
                    above += a;
                    pixels += n;
                    let m = max_abs(&off.image, &s.image);
                    assert!(
                        m <= 2.0 * e,
                        "{name}, alpha {alpha}, azimuth {azimuth}, E_I {e}: max abs {m}"
                    );
                }
            }
        }
    }
    eprintln!("relaxed: {adapted} of {cells} cells adapted, {above} of {pixels} pixels above E_I");
    assert!(
        adapted as f64 >= 0.2 * cells as f64,
        "only {adapted} of {cells} cells adapted"
    );
    assert!(
        above as f64 <= 0.0005 * pixels as f64,
        "{above} of {pixels} pixels above E_I"
    );
}
