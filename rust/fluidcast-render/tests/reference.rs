#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly
mod common;
use common::{cloud, cloud_view};
use fluidcast_render::{render_reference, RenderParams, SampleDepths};
use fluidcast_sph::{FieldKind, Kernel, Particles};
use fluidcast_view::{Camera, TransferFunction};

/// Independent oracle: world-space rays from the camera, every particle at every sample.
/// Per pixel: premultiplied RGBA and the depth of the first sample after which the ray's
/// transmittance is below 1/2 (`+∞` if it never is).
fn brute_force(
    p: &Particles,
    cam: &Camera,
    tf: &TransferFunction,
    prm: &RenderParams,
    depths: &SampleDepths,
) -> Vec<([f64; 4], f64)> {
    let f = cam.frame(prm.width, prm.height).unwrap();
    let mut out = Vec::new();
    for j in 0..prm.height {
        for i in 0..prm.width {
            let (o, d) = f.ray(i, j);
            let (mut c, mut t, mut half) = ([0.0f64; 3], 1.0f64, f64::INFINITY);
            for k in 0..depths.len() {
                let x = o + d * depths.z[k];
                let (mut wa, mut ws, mut wm) = (0.0, 0.0, 0.0);
                for q in 0..p.len() {
                    let pp = p.positions[q];
                    let r = ((x.x - pp[0] as f64).powi(2)
                        + (x.y - pp[1] as f64).powi(2)
                        + (x.z - pp[2] as f64).powi(2))
                    .sqrt();
                    let w = prm.kernel.eval(r, p.radii[q] as f64);
                    wa += p.volumes[q] as f64 * p.values[q] as f64 * w;
                    ws += p.volumes[q] as f64 * w;
                    wm += p.masses[q] as f64 * w;
                }
                if ws <= 0.0 {
                    continue;
                }
                let v = match prm.field {
                    FieldKind::Csph => wa / ws,
                    FieldKind::Sph => wa,
                    FieldKind::Density => wm,
                };
                let (rgb, a) = tf.eval(v);
                let a = tf.step_alpha(a, (depths.z[k + 1] - depths.z[k]) * d.length());
                for m in 0..3 {
                    c[m] += t * a * rgb[m];
                }
                t *= 1.0 - a;
                if t < 0.5 && half.is_infinite() {
                    half = depths.z[k];
                }
            }
            out.push(([c[0], c[1], c[2], 1.0 - t], half));
        }
    }
    out
}

#[test]
fn reference_equals_brute_force() {
    let p = cloud(60, 7);
    for (parallel, field, kernel) in [
        (false, FieldKind::Csph, Kernel::CubicSpline),
        (true, FieldKind::Sph, Kernel::WendlandC2),
        (false, FieldKind::Density, Kernel::Quintic),
    ] {
        let (cam, tf) = cloud_view(25.0, -15.0, parallel, field);
        let prm = RenderParams {
            width: 24,
            height: 18,
            kernel,
            field,
            min_transmittance: 0.0,
            ..Default::default()
        };
        let (img, stats) = render_reference(&p, &cam, &tf, &prm).unwrap();
        let f = cam.frame(prm.width, prm.height).unwrap();
        let depths = SampleDepths::new(
            &f,
            stats.near,
            stats.far,
            1.0,
            prm.grid.depth_samples as usize,
        )
        .unwrap();
        let bf = brute_force(&p, &cam, &tf, &prm, &depths);
        let mut max = 0.0f64;
        for (a, (b, _)) in img.rgba.iter().zip(&bf) {
            for k in 0..4 {
                max = max.max((a[k] as f64 - b[k]).abs());
            }
        }
        assert!(max < 1e-5, "parallel={parallel} {field:?}: max abs {max}");
        // Depth: the same sample plane (as f32), and some pixels have one.
        let depth_ok = img.depth.iter().zip(&bf).all(|(&z, &(_, h))| z == h as f32);
        assert!(depth_ok, "parallel={parallel} {field:?}: depth differs");
        assert!(img.depth.iter().filter(|z| z.is_finite()).count() > 10);
        assert!(img.rgba.iter().any(|p| p[3] > 0.05), "nothing rendered");
    }
}

#[test]
fn uniform_slab_transmittance_is_exponential() {
    // A lattice slab with a constant attribute: the CSPH field is constant (exactly)
    // wherever a particle reaches, i.e. on the central ray from z = -H to d + H.
    let (spacing, h) = (0.05f32, 0.1f32);
    let nz = 9; // z = 0 .. 0.4
    let p = common::slab(nz);
    let thickness = (nz - 1) as f64 * spacing as f64 + 2.0 * h as f64;
    let (cam, tf, sigma) = common::slab_scene();
    let prm = RenderParams {
        width: 2,
        height: 2,
        sampling_scale: 10.0,
        min_transmittance: 0.0,
        ..Default::default()
    };
    let (img, stats) = render_reference(&p, &cam, &tf, &prm).unwrap();
    assert!(stats.depth_samples > 1000);
    let t = 1.0 - img.rgba[0][3] as f64;
    let expected = (-sigma * thickness).exp();
    assert!(
        (t - expected).abs() < 1e-3,
        "T = {t}, exp(-σd) = {expected}"
    );
    // Emission: constant colour c with opacity: premultiplied colour = c·(1 − T).
    let c = tf.eval(0.7).0[0];
    assert!((img.rgba[0][0] as f64 - c * (1.0 - t)).abs() < 1e-5);
    // Depth: the ray enters the support at view depth 3 − (0.4 + H) and is half transparent
    // ln 2 / σ later; the image holds the front of the step that crosses 1/2, and the first
    // step may start up to one step behind the support's edge (steps are 1e-4 long here).
    let enter = 3.0 - ((nz - 1) as f64 * spacing as f64 + h as f64);
    let half = enter + std::f64::consts::LN_2 / sigma;
    let z = img.depth[0] as f64;
    assert!(
        (z - half).abs() <= 1e-3,
        "depth {z}, half transparent at {half}"
    );
}

#[test]
fn sample_index_ranges_are_exact() {
    let cam = Camera::default();
    let f = cam.frame(100, 80).unwrap();
    let d = SampleDepths::new(&f, 0.5, 3.0, 1.0, 1).unwrap();
    for (z0, z1) in [
        (0.4, 0.6),
        (1.0, 1.0001),
        (2.5, 3.5),
        (0.51, 0.52),
        (d.z[10], d.z[20]),
    ] {
        let r = d.indices_within(z0, z1);
        for k in 0..d.len() {
            assert_eq!(
                r.contains(&k),
                d.z[k] >= z0 && d.z[k] <= z1,
                "k={k} z={} in [{z0},{z1}]",
                d.z[k]
            );
        }
    }
}
