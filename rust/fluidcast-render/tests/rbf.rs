//! The RBF ray marcher against the analytic integral of one Gaussian, against a marcher
//! written here on point range queries, and its progressive accumulation's convergence.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly

use fluidcast_image::Image;
use fluidcast_rbf::{Colouring, RbfField, RbfOptions};
use fluidcast_render::{render_rbf, white_offset, Noise, RbfRenderParams, RenderParams};
use fluidcast_sph::Particles;
use fluidcast_testkit::cloud;
use fluidcast_view::{Camera, TransferFunction};

/// White, fully weighted at every value: the image is the opacity.
fn white_tf(unit: f64) -> TransferFunction {
    let mut tf = TransferFunction::preset("Grayscale")
        .unwrap()
        .with_range(0.0, 1.0)
        .unwrap();
    tf.colors = vec![(0.0, [1.0; 3]), (1.0, [1.0; 3])];
    tf.opacity = vec![(0.0, 1.0), (1.0, 1.0)];
    tf.unit_distance = unit;
    tf
}

fn params(w: u32, h: u32) -> RenderParams {
    RenderParams {
        width: w,
        height: h,
        min_transmittance: 0.0,
        ..Default::default()
    }
}

fn camera(parallel: bool, scale: f64) -> Camera {
    let mut c = Camera {
        parallel_projection: parallel,
        ..Default::default()
    };
    c.reset([-scale; 3], [scale; 3]);
    c
}

/// erf by Abramowitz–Stegun 7.1.26 (error below 1.5e-7).
fn erf(x: f64) -> f64 {
    let t = 1.0 / (1.0 + 0.327_591_1 * x.abs());
    let y = 1.0
        - (((((1.061_405_429 * t - 1.453_152_027) * t) + 1.421_413_741) * t - 0.284_496_736) * t
            + 0.254_829_592)
            * t
            * (-x * x).exp();
    y.copysign(x)
}

#[test]
fn a_lone_particle_absorbs_its_analytic_optical_depth() {
    let r = 0.5;
    let mut p = Particles::default();
    p.positions.push([0.1, -0.05, 0.2]);
    p.radii.push(r as f32);
    p.volumes.push(1.0);
    p.masses.push(1.0);
    p.values.push(1.0);
    let unit = 0.8;
    let tf = white_tf(unit);
    let field = RbfField::build(&p, &tf, &RbfOptions::default()).unwrap();
    let rbf = RbfRenderParams {
        spp: 16,
        ..Default::default()
    };
    for parallel in [true, false] {
        let cam = camera(parallel, 0.6);
        let prm = params(40, 30);
        let (img, _) = render_rbf(&field, &cam, &tf, &prm, &rbf).unwrap();
        let frame = cam.frame(prm.width, prm.height).unwrap();
        let c = glam::DVec3::new(0.1, -0.05, 0.2);
        let mut inside = 0;
        for j in 0..prm.height {
            for i in 0..prm.width {
                // The ray's closest approach b to the centre; the optical depth of the
                // chord through exp(−½(3ρ/r)²)/unit: exp(−½(3b/r)²)·σ√(2π)·erf(L/(σ√2))/unit
                // with half chord L = √(r² − b²), σ = r/3.
                let (o, d) = frame.ray(i, j);
                let d = d.normalize();
                let b = (c - o - d * (c - o).dot(d)).length();
                let want = if b < r {
                    let s = r / 3.0;
                    let half = (r * r - b * b).sqrt();
                    let tau = (-0.5 * (b / s).powi(2)).exp()
                        * s
                        * (2.0 * std::f64::consts::PI).sqrt()
                        * erf(half / (s * std::f64::consts::SQRT_2))
                        / unit;
                    inside += 1;
                    1.0 - (-tau).exp()
                } else {
                    0.0
                };
                let got = img.rgba[img.index(i, j)];
                assert!(
                    (f64::from(got[3]) - want).abs() < 2e-3,
                    "parallel {parallel}, pixel ({i}, {j}), b {b:.3}: alpha {} vs {want}",
                    got[3]
                );
                assert!(
                    (got[0] - got[3]).abs() < 1e-6,
                    "white: premultiplied colour = alpha"
                );
            }
        }
        assert!(inside > 100, "{inside} pixels see the particle");
    }
}

fn rmse(a: &Image, b: &Image) -> f64 {
    let s: f64 = a
        .rgba
        .iter()
        .zip(&b.rgba)
        .map(|(x, y)| (0..4).map(|k| f64::from(x[k] - y[k]).powi(2)).sum::<f64>())
        .sum();
    (s / (4 * a.rgba.len()) as f64).sqrt()
}

fn cloud_scene() -> (Particles, TransferFunction) {
    let p = cloud(600, 3, (0.12, 0.08));
    let (lo, hi) = p.value_range();
    let mut tf = TransferFunction::preset("Cool to Warm")
        .unwrap()
        .with_range(f64::from(lo), f64::from(hi))
        .unwrap();
    tf.opacity = vec![(0.0, 0.3), (1.0, 1.0)];
    tf.unit_distance = 0.3;
    (p, tf)
}

#[test]
fn progressive_accumulation_converges_like_one_over_the_root_of_the_passes() {
    let (p, tf) = cloud_scene();
    let field = RbfField::build(&p, &tf, &RbfOptions::default()).unwrap();
    let cam = camera(false, 0.6);
    let prm = params(48, 36);
    // A coarse step (about one a particle radius, 3 standard deviations), so that one pass
    // is visibly noisy: at steps under a standard deviation, Gaussian sums hardly depend on
    // the offset.
    let step = Some(0.15);
    let render_with = |spp, first_pass, noise| {
        let rbf = RbfRenderParams {
            spp,
            first_pass,
            step,
            noise,
            ..Default::default()
        };
        render_rbf(&field, &cam, &tf, &prm, &rbf).unwrap().0
    };
    let render = |spp, first_pass| render_with(spp, first_pass, Noise::White);
    // The converged image from passes the tested renders never draw.
    let truth = render(512, 1 << 20);
    let e1 = rmse(&render(1, 0), &truth);
    assert!(e1 > 2e-3, "one pass should be noisy: RMSE {e1}");
    for spp in [4u32, 16, 64] {
        let e = rmse(&render(spp, 0), &truth);
        let ratio = e * f64::from(spp).sqrt() / e1;
        eprintln!("{spp} passes: RMSE {e:.5}, {ratio:.3} × e(1)/√spp (e(1) = {e1:.5})");
        // Monte Carlo: e(spp) = e(1)/√spp. The stated factor: within 0.6..1.5 of it (the
        // truth's own noise, e(1)/√512, adds under 7 % at 64 passes).
        assert!(
            (0.6..1.5).contains(&ratio),
            "{spp} passes: RMSE {e} = {ratio:.2} × e(1)/√spp"
        );
    }
    // Blue noise (a golden-ratio sequence of offsets per pixel) converges faster: at 16
    // passes its error is below white noise's by more than the √ law's spread.
    let (w16, b16) = (
        rmse(&render(16, 0), &truth),
        rmse(&render_with(16, 0, Noise::Blue), &truth),
    );
    eprintln!("16 passes: white RMSE {w16:.5}, blue {b16:.5}");
    assert!(b16 < 0.6 * w16, "blue {b16} vs white {w16}");
    // Two renders of 8 passes each, the second continuing the first, average to 16 passes.
    let (a, b, both) = (render(8, 0), render(8, 8), render(16, 0));
    for k in 0..a.rgba.len() {
        for c in 0..4 {
            let mean = 0.5 * (a.rgba[k][c] + b.rgba[k][c]);
            assert!((mean - both.rgba[k][c]).abs() < 1e-6);
        }
    }
}

#[test]
fn marching_the_gathered_spheres_equals_marching_point_queries() {
    let (p, tf) = cloud_scene();
    for colouring in [Colouring::Post, Colouring::Pre, Colouring::Density] {
        let field = RbfField::build(
            &p,
            &tf,
            &RbfOptions {
                colouring,
                leaf_size: 4,
                ..Default::default()
            },
        )
        .unwrap();
        let cam = camera(false, 0.6);
        let mut prm = params(24, 18);
        prm.min_transmittance = 0.02;
        let rbf = RbfRenderParams {
            spp: 2,
            seed: 5,
            noise: Noise::White,
            ..Default::default()
        };
        let (img, stats) = render_rbf(&field, &cam, &tf, &prm, &rbf).unwrap();
        assert!(stats.samples > 1000);
        let step = rbf.step_for(&field, &prm).unwrap();
        let frame = cam.frame(prm.width, prm.height).unwrap();
        let mut covered = 0;
        for j in 0..prm.height {
            for i in 0..prm.width {
                let (o, d) = frame.ray(i, j);
                let dt = step / d.length();
                let mut sum = [0.0f64; 4];
                for pass in 0..2 {
                    let xi = white_offset(i, j, pass, 5);
                    let (mut c, mut t_) = ([0.0f64; 3], 1.0f64);
                    // Every sample from the eye to beyond the cloud, each by a point query.
                    for k in 0..(6.0 / dt) as i64 {
                        let t = (k as f64 + xi) * dt;
                        let s = field.sample((o + d * t).to_array());
                        if s.density <= 0.0 {
                            continue;
                        }
                        let (rgb, mu) = match colouring {
                            Colouring::Post => (
                                tf.eval(s.weighted[0] / s.density).0,
                                s.density / tf.unit_distance,
                            ),
                            Colouring::Pre => (
                                s.weighted.map(|w| w / s.density),
                                s.density / tf.unit_distance,
                            ),
                            Colouring::Density => {
                                let (rgb, a) = tf.eval(s.density);
                                (rgb, -(1.0 - a).ln() / tf.unit_distance)
                            }
                        };
                        let a = 1.0 - (-mu * step).exp();
                        for q in 0..3 {
                            c[q] += t_ * a * rgb[q];
                        }
                        t_ *= 1.0 - a;
                        if t_ < prm.min_transmittance {
                            break;
                        }
                    }
                    for q in 0..3 {
                        sum[q] += 0.5 * c[q];
                    }
                    sum[3] += 0.5 * (1.0 - t_);
                }
                let got = img.rgba[img.index(i, j)];
                covered += usize::from(sum[3] > 0.01);
                for q in 0..4 {
                    assert!(
                        (f64::from(got[q]) - sum[q]).abs() < 1e-5,
                        "{colouring:?} ({i}, {j}) channel {q}: {} vs {}",
                        got[q],
                        sum[q]
                    );
                }
            }
        }
        assert!(covered > 100, "{colouring:?}: {covered} pixels covered");
    }
}

#[test]
fn bad_requests_are_refused() {
    let (p, tf) = cloud_scene();
    let field = RbfField::build(&p, &tf, &RbfOptions::default()).unwrap();
    let cam = camera(false, 0.6);
    let prm = params(8, 8);
    let zero = RbfRenderParams {
        spp: 0,
        ..Default::default()
    };
    assert!(render_rbf(&field, &cam, &tf, &prm, &zero).is_err());
    let tiny = RbfRenderParams {
        step: Some(1e-9),
        ..Default::default()
    };
    let e = render_rbf(&field, &cam, &tf, &prm, &tiny).unwrap_err();
    assert!(e.to_string().contains("samples a ray"), "{e}");
    // Nothing visible: an empty image, not an error.
    let none = RbfField::build(&Particles::default(), &tf, &RbfOptions::default()).unwrap();
    let (img, _) = render_rbf(&none, &cam, &tf, &prm, &RbfRenderParams::default()).unwrap();
    assert!(img.rgba.iter().all(|p| p[3] == 0.0));
}

/// Layers of particles on a square lattice of spacing `s`, radius `r`, attribute 1, over
/// `|x|, |z| <= half`, at the heights `ys`.
fn slab(s: f64, r: f32, half: f64, ys: &[f64], p: &mut Particles) {
    let n = (half / s).round() as i64;
    for &y in ys {
        for a in -n..=n {
            for b in -n..=n {
                p.positions
                    .push([(a as f64 * s) as f32, y as f32, (b as f64 * s) as f32]);
                p.radii.push(r);
                p.volumes.push(1.0);
                p.masses.push(1.0);
                p.values.push(1.0);
            }
        }
    }
}

/// Mean red channel over the pixels whose rays cross the heights `y0..y1`.
fn band_mean(img: &Image, frame: &fluidcast_view::ViewFrame, (y0, y1): (f64, f64)) -> f64 {
    let mut sum = 0.0;
    let mut n = 0;
    for j in 0..img.height {
        for i in 0..img.width {
            let y = frame.ray(i, j).0.y;
            if (y0..y1).contains(&y) {
                sum += f64::from(img.rgba[img.index(i, j)][0]);
                n += 1;
            }
        }
    }
    assert!(n > 50, "{n} pixels in the band");
    sum / n as f64
}

#[test]
fn a_slab_between_the_light_and_another_darkens_it_by_its_optical_depth() {
    let (s, r) = (0.05, 0.1f32);
    let unit = 0.5;
    let tf = white_tf(unit);
    // The receiver: two layers at y = 0 and 0.05, |x|, |z| <= 0.3.
    let mut alone = Particles::default();
    slab(s, r, 0.3, &[0.0, 0.05], &mut alone);
    // The occluder above it, wider by more than a radius: two layers at 0.55 and 0.6.
    let mut both = alone.clone();
    slab(s, r, 0.6, &[0.55, 0.6], &mut both);
    // Its optical depth straight up, away from its edges: per layer, a Gaussian's integral
    // over its ball, V = (2π)^{3/2} σ³ P(χ₃ <= 3), spread over a lattice cell s²; the
    // lattice's ripple is below 1e-3 at s = 1.5 σ.
    let sigma = f64::from(r) / 3.0;
    let chi3 = erf(3.0 / std::f64::consts::SQRT_2)
        - (2.0 / std::f64::consts::PI).sqrt() * 3.0 * (-4.5f64).exp();
    let v = (2.0 * std::f64::consts::PI).powf(1.5) * sigma.powi(3) * chi3;
    let tau = 2.0 * v / (s * s) / unit;
    let shadows = fluidcast_render::RbfShadows::new([0.0, 1.0, 0.0], 0.0, 2).unwrap();
    let rbf = RbfRenderParams {
        spp: 32,
        shadows: Some(shadows),
        ..Default::default()
    };
    // Looking along −z (parallel rays): the receiver's band of pixels sees it alone.
    let mut cam = Camera {
        parallel_projection: true,
        ..Default::default()
    };
    cam.reset([-0.4, -0.2, -0.4], [0.4, 0.8, 0.4]);
    let prm = params(40, 50);
    let frame = cam.frame(prm.width, prm.height).unwrap();
    let band = (-0.02, 0.07);
    let lit = |p: &Particles| {
        let field = RbfField::build(p, &tf, &RbfOptions::default()).unwrap();
        let (img, _) = render_rbf(&field, &cam, &tf, &prm, &rbf).unwrap();
        band_mean(&img, &frame, band)
    };
    let (bright, dark) = (lit(&alone), lit(&both));
    let want = (-tau).exp();
    let got = dark / bright;
    eprintln!("tau {tau:.4}: exp(-tau) {want:.4}, receiver darkened to {got:.4}");
    assert!(bright > 0.1, "the receiver is lit: {bright}");
    // Stated tolerance: 2 % of exp(−τ) (jitter noise over 32 passes and the lattice ripple).
    assert!(
        (got / want - 1.0).abs() < 0.02,
        "{got} vs exp(-{tau}) = {want}"
    );
}

/// Two translucent sheets facing the camera (which looks along −z): attribute 0 (blue) at
/// z = 0.2 in front of attribute 1 (red) at z = −0.2.
fn two_sheets() -> Particles {
    let mut p = Particles::default();
    for (z, v) in [(0.2f32, 0.0f32), (-0.2, 1.0)] {
        for a in -8..=8 {
            for b in -8..=8 {
                p.positions.push([a as f32 * 0.05, b as f32 * 0.05, z]);
                p.radii.push(0.1);
                p.volumes.push(1.0);
                p.masses.push(1.0);
                p.values.push(v);
            }
        }
    }
    p
}

#[test]
fn full_ambient_light_makes_the_lit_image_the_emission_absorption_one() {
    let p = two_sheets();
    let mut tf = TransferFunction::preset("Cool to Warm")
        .unwrap()
        .with_range(0.0, 1.0)
        .unwrap();
    tf.opacity = vec![(0.0, 1.0), (1.0, 1.0)];
    tf.unit_distance = 0.3;
    let field = RbfField::build(&p, &tf, &RbfOptions::default()).unwrap();
    let cam = camera(true, 0.5);
    let prm = params(32, 24);
    let ea = RbfRenderParams {
        spp: 4,
        ..Default::default()
    };
    let lit = RbfRenderParams {
        spp: 256,
        shadows: Some(fluidcast_render::RbfShadows::new([1.0, 1.0, 0.0], 1.0, 1).unwrap()),
        ..ea.clone()
    };
    let (a, _) = render_rbf(&field, &cam, &tf, &prm, &ea).unwrap();
    let (b, _) = render_rbf(&field, &cam, &tf, &prm, &lit).unwrap();
    // One shade point a pass, chosen by where light scatters, estimates the composite
    // without bias: the mean of 256 passes is close to it, in the blue of the front sheet
    // and the red of the one behind it alike.
    let mean = |img: &Image, c: usize| {
        img.rgba.iter().map(|p| f64::from(p[c])).sum::<f64>() / img.rgba.len() as f64
    };
    for c in [0, 2] {
        let (ma, mb) = (mean(&a, c), mean(&b, c));
        assert!((mb / ma - 1.0).abs() < 0.01, "channel {c}: {mb} vs {ma}");
    }
    assert!(rmse(&a, &b) < 0.01, "RMSE {}", rmse(&a, &b));
    assert!(a.rgba.iter().any(|p| p[3] > 0.5));
    // Alpha is the emission–absorption one, pass by pass.
    for (p, q) in a.rgba.iter().zip(&b.rgba) {
        assert!((p[3] - q[3]).abs() < 1e-3);
    }
    assert!(fluidcast_render::RbfShadows::new([0.0; 3], 0.5, 1).is_err());
    assert!(fluidcast_render::RbfShadows::new([0.0, 1.0, 0.0], 1.5, 1).is_err());
    assert!(fluidcast_render::RbfShadows::new([0.0, 1.0, 0.0], 0.5, 0).is_err());
}

/// An SPH field marched by the stochastic renderer (what `--shadows` draws for SPH fields)
/// against the reference renderer of the same field: unlit, the mean of 64 jittered passes
/// is the reference's image but for the two samplings' discretisation (measured RMSE 0.006
/// for CSPH, 0.010 for the density; stated 0.015).
#[test]
fn an_sph_field_marched_stochastically_is_the_reference_image() {
    use fluidcast_sph::FieldKind;
    let p = cloud(600, 3, (0.12, 0.08));
    let (lo, hi) = p.value_range();
    let cam = camera(false, 0.6);
    for (field, range) in [
        (FieldKind::Csph, (f64::from(lo), f64::from(hi))),
        (FieldKind::Density, (0.0, 2000.0)),
    ] {
        let mut tf = TransferFunction::preset("Viridis")
            .unwrap()
            .with_range(range.0, range.1)
            .unwrap();
        tf.unit_distance = 0.3;
        let prm = RenderParams {
            width: 48,
            height: 36,
            field,
            ..Default::default()
        };
        let (reference, _) = fluidcast_render::render_reference(&p, &cam, &tf, &prm).unwrap();
        let sph = RbfField::from_sph(&p, prm.kernel, field, 8).unwrap();
        let rbf = RbfRenderParams {
            spp: 64,
            ..Default::default()
        };
        let (ours, _) = render_rbf(&sph, &cam, &tf, &prm, &rbf).unwrap();
        let e = rmse(&reference, &ours);
        eprintln!("{field:?}: RMSE {e:.5}");
        assert!(
            reference.rgba.iter().any(|q| q[3] > 0.3),
            "{field:?} drew something"
        );
        assert!(e < 0.015, "{field:?}: RMSE {e}");
    }
}

#[test]
fn an_sph_slab_between_the_light_and_another_darkens_it_by_its_optical_depth() {
    // Constant attribute 1 with opacity 0.5 per 0.2 world units: wherever a support reaches,
    // the CSPH value is 1 and the extinction ln 2 / 0.2. A layer of supports H = 0.1 on a
    // lattice of spacing 0.02 covers a band 2H thick (to within s²/4H = 0.001).
    let (s, h) = (0.02, 0.1f32);
    let mut tf = white_tf(0.2);
    tf.opacity = vec![(0.0, 0.5), (1.0, 0.5)];
    let mut alone = Particles::default();
    slab(s, h, 0.2, &[0.0], &mut alone);
    let mut both = alone.clone();
    slab(s, h, 0.5, &[0.6], &mut both);
    let tau = (2.0f64).ln() / 0.2 * 2.0 * f64::from(h);
    let shadows = fluidcast_render::RbfShadows::new([0.0, 1.0, 0.0], 0.0, 1).unwrap();
    let rbf = RbfRenderParams {
        spp: 16,
        shadows: Some(shadows),
        ..Default::default()
    };
    let mut cam = Camera {
        parallel_projection: true,
        ..Default::default()
    };
    cam.reset([-0.3, -0.2, -0.3], [0.3, 0.8, 0.3]);
    let prm = params(30, 50);
    let frame = cam.frame(prm.width, prm.height).unwrap();
    let lit = |p: &Particles| {
        let field = RbfField::from_sph(p, prm.kernel, fluidcast_sph::FieldKind::Csph, 8).unwrap();
        let (img, _) = render_rbf(&field, &cam, &tf, &prm, &rbf).unwrap();
        band_mean(&img, &frame, (-0.05, 0.05))
    };
    let (bright, dark) = (lit(&alone), lit(&both));
    let (want, got) = ((-tau).exp(), dark / bright);
    eprintln!("SPH slab: tau {tau:.4}, exp(-tau) {want:.4}, receiver darkened to {got:.4}");
    assert!(bright > 0.1);
    // Stated tolerance: 2 % (the band's edge within s²/4H and the jittered steps).
    assert!((got / want - 1.0).abs() < 0.02, "{got} vs {want}");
}
