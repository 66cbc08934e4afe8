//! Iso-surfaces against analytic shapes and a brute-force sum over all particles.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly

use std::sync::Arc;

use glam::DVec3;

use fluidcast_render::{render_reference, IsoField, RenderParams, Surfaces};
use fluidcast_sph::{Kernel, Particles};
use fluidcast_view::{Camera, TransferFunction};

/// A ball of radius `r` filled with particles of spacing about `s` on concentric shells at
/// radii (k + ½)·s, each shell a Fibonacci (golden-angle) spiral of about 4πr²/s² points, so
/// that the particles follow the sphere instead of a lattice's facets. Each particle's volume
/// and mass is its share of its shell's volume (the shells fill the ball exactly); support
/// radius `h`; value x.
fn ball(r: f32, s: f32, h: f32) -> Particles {
    let mut p = Particles::default();
    let shells = (r / s).round() as usize;
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    for k in 0..shells {
        let rk = (k as f64 + 0.5) * s as f64;
        let count = (4.0 * std::f64::consts::PI * rk * rk / (s as f64 * s as f64))
            .round()
            .max(1.0) as usize;
        let shell = 4.0 / 3.0
            * std::f64::consts::PI
            * (s as f64).powi(3)
            * (((k + 1) as f64).powi(3) - (k as f64).powi(3));
        for i in 0..count {
            let y = 1.0 - 2.0 * (i as f64 + 0.5) / count as f64;
            let ring = (1.0 - y * y).sqrt();
            let phi = golden * i as f64;
            let x = [ring * phi.cos(), y, ring * phi.sin()].map(|c| (c * rk) as f32);
            p.positions.push(x);
            p.radii.push(h);
            p.volumes.push((shell / count as f64) as f32);
            p.masses.push((shell / count as f64) as f32);
            p.values.push(x[0]);
        }
    }
    p
}

fn tf() -> TransferFunction {
    let mut tf = TransferFunction::preset("viridis")
        .unwrap()
        .with_range(-1.0, 1.0)
        .unwrap();
    tf.unit_distance = 0.1;
    tf
}

fn params(size: u32, kernel: Kernel, surfaces: Surfaces) -> RenderParams {
    RenderParams {
        width: size,
        height: size,
        kernel,
        surfaces: Some(Arc::new(surfaces)),
        ..Default::default()
    }
}

/// The world point at view depth `z` on pixel (i, j)'s ray.
fn world_point(cam: &Camera, size: u32, (i, j): (u32, u32), z: f64) -> [f64; 3] {
    let frame = cam.frame(size, size).unwrap();
    let (o, d) = frame.ray(i, j);
    (o + d * z).to_array()
}

fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// The sums `[Σ V A W, Σ V W, Σ m W]` at `x`, summed over every particle (no grid, no
/// culling): the oracle the renderer's level sets and gradients are held to.
fn brute(p: &Particles, kernel: Kernel, x: [f64; 3]) -> [f64; 3] {
    let mut s = [0.0; 3];
    for j in 0..p.len() {
        let c = p.positions[j];
        let r = norm([0, 1, 2].map(|a| x[a] - c[a] as f64));
        let w = kernel.eval(r, p.radii[j] as f64);
        let v = p.volumes[j] as f64;
        s[0] += v * p.values[j] as f64 * w;
        s[1] += v * w;
        s[2] += p.masses[j] as f64 * w;
    }
    s
}

/// The unit vector against the gradient of `f` at `x` (central differences, step `e`): the
/// outward normal of a level set of a field that grows inward.
fn descent(f: impl Fn([f64; 3]) -> f64, x: [f64; 3], e: f64) -> [f64; 3] {
    let g = [0, 1, 2].map(|a| {
        let (mut u, mut v) = (x, x);
        u[a] += e;
        v[a] -= e;
        -(f(u) - f(v)) / (2.0 * e)
    });
    g.map(|c| c / norm(g))
}

fn angle_deg(a: [f64; 3], b: [f64; 3]) -> f64 {
    let cos = (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]) / (norm(a) * norm(b));
    cos.clamp(-1.0, 1.0).acos().to_degrees()
}

/// The colour field's 0.5 level of a particle ball lies at the ball's radius within half a
/// spacing, in perspective and in parallel projection, for kernels and support radii of 2 to
/// 4 spacings; every normal is the brute-force gradient's direction within 0.5 degrees, and
/// points radially within 2 degrees once the support spans 4 spacings (with 2–3 the
/// particles' own arrangement bends the level set by up to 8 degrees near the shells'
/// poles, which the brute-force gradient shows as well).
#[test]
fn ball_surface_lies_at_its_radius_with_radial_normals() {
    let (r, s) = (0.5f32, 0.05f32);
    for kernel in [Kernel::CubicSpline, Kernel::WendlandC2] {
        for spacings in [2.0, 3.0, 4.0] {
            let p = ball(r, s, spacings * s);
            for parallel in [false, true] {
                let label = format!("{kernel} H={spacings} spacings parallel={parallel}");
                let hits = check_ball(
                    &p,
                    kernel,
                    parallel,
                    (r as f64, s as f64),
                    spacings >= 4.0,
                    &label,
                );
                assert!(hits > 1000, "{label}: {hits} pixels see the ball");
            }
        }
    }
}

/// Renders `p` (a ball of radius and spacing `rs`) and checks every surface pixel; returns
/// their number.
fn check_ball(
    p: &Particles,
    kernel: Kernel,
    parallel: bool,
    (r, s): (f64, f64),
    radial: bool,
    label: &str,
) -> usize {
    let mut cam = Camera::default();
    cam.reset([-0.6; 3], [0.6; 3]);
    cam.azimuth(30.0);
    cam.elevation(20.0);
    cam.orthogonalize_view_up();
    cam.parallel_projection = parallel;
    let size = 96;
    let (img, _) =
        render_reference(p, &cam, &tf(), &params(size, kernel, Surfaces::default())).unwrap();
    let names: Vec<&str> = img.aovs.iter().map(|a| a.0.as_str()).collect();
    assert_eq!(names, ["normal_x", "normal_y", "normal_z"]);
    let (mut hits, mut worst_r, mut worst_radial, mut worst_fd) = (0, 0.0f64, 0.0f64, 0.0f64);
    for j in 0..size {
        for i in 0..size {
            let k = img.index(i, j);
            let z = img.depth[k];
            if !z.is_finite() {
                assert_eq!(img.rgba[k][3], 0.0, "{label}: no surface, no colour");
                continue;
            }
            hits += 1;
            assert!(
                (img.rgba[k][3] - 1.0).abs() < 1e-6,
                "{label}: an opaque surface"
            );
            let x = world_point(&cam, size, (i, j), z as f64);
            worst_r = worst_r.max((norm(x) - r).abs());
            let n = [0, 1, 2].map(|a| img.aovs[a].1[k] as f64);
            worst_radial = worst_radial.max(angle_deg(n, x));
            if hits % 5 == 0 {
                let fd = descent(|y| brute(p, kernel, y)[1], x, 1e-6);
                worst_fd = worst_fd.max(angle_deg(n, fd));
            }
        }
    }
    eprintln!("{label}: {hits} hits, |r - R| <= {worst_r:.5}, radial within {worst_radial:.3} deg, brute-force gradient within {worst_fd:.4} deg");
    assert!(worst_r <= 0.5 * s, "{label}: radius off by {worst_r}");
    assert!(
        worst_fd <= 0.5,
        "{label}: normal {worst_fd} degrees from the gradient"
    );
    if radial {
        assert!(
            worst_radial <= 2.0,
            "{label}: normal {worst_radial} degrees from radial"
        );
    }
    hits
}

/// Particle sheets parallel to z = 0 at these depths: each a 25 × 25 lattice of spacing 0.05
/// centred on the z axis, support radius 0.1 (2 spacings), volume one lattice cell, value 1.
fn sheets(zs: &[f32]) -> Particles {
    let (s, h) = (0.05f32, 0.1f32);
    let mut p = Particles::default();
    for i in -12..=12 {
        for j in -12..=12 {
            for &z in zs {
                p.positions.push([i as f32 * s, j as f32 * s, z]);
                p.radii.push(h);
                p.volumes.push(s * s * s);
                p.masses.push(1.0);
                p.values.push(1.0);
            }
        }
    }
    p
}

/// The brute-force colour field on the plane z = 0 over one lattice cell of [`sheets`]
/// (21 × 21 points): where a sheet at 0 peaks, or a gap around 0 dips.
fn middle_plane(p: &Particles, kernel: Kernel) -> impl Iterator<Item = f64> + '_ {
    (0..=20)
        .flat_map(|a| (0..=20).map(move |b| [a as f64 * 0.0025, b as f64 * 0.0025, 0.0]))
        .map(move |x| brute(p, kernel, x)[1])
}

/// The pixels (i, j) of a `size`² view whose rays cross the plane z = 0 within `half` of
/// the z axis (away from the sheets' edges), with each ray's origin and direction.
fn rays_through_plane(cam: &Camera, size: u32, half: f64) -> Vec<(u32, u32, DVec3, DVec3)> {
    let frame = cam.frame(size, size).unwrap();
    (0..size)
        .flat_map(|j| (0..size).map(move |i| (i, j)))
        .filter_map(|(i, j)| {
            let (o, d) = frame.ray(i, j);
            let at = o + d * (-o.z / d.z);
            (at.x.abs() <= half && at.y.abs() <= half).then_some((i, j, o, d))
        })
        .collect()
}

/// The first depth along `o + z d` in `[near, far]` where `field` crosses `iso`, marching in
/// `steps` equal steps and bisecting the first step whose ends (both defined) lie on either
/// side, over the particles `near_ray` only (those whose support the ray passes).
fn brute_crossing(
    field: impl Fn([f64; 3]) -> Option<f64>,
    (o, d): ([f64; 3], [f64; 3]),
    (near, far): (f64, f64),
    iso: f64,
    steps: usize,
) -> Option<f64> {
    let at = |z: f64| field([0, 1, 2].map(|a| o[a] + z * d[a]));
    let dz = (far - near) / steps as f64;
    let mut prev = (near, at(near));
    for k in 1..=steps {
        let z = near + k as f64 * dz;
        let cur = (z, at(z));
        if let ((mut a, Some(fa)), (mut b, Some(fb))) = (prev, cur) {
            if (fa >= iso) != (fb >= iso) {
                for _ in 0..60 {
                    let m = 0.5 * (a + b);
                    match at(m) {
                        Some(fm) if (fm >= iso) == (fa >= iso) => a = m,
                        _ => b = m,
                    }
                }
                return Some(0.5 * (a + b));
            }
        }
        prev = cur;
    }
    None
}

/// On a random cloud of overlapping particles of varied radii and volumes, the surface's
/// depth in every pixel is the first crossing of the brute-force field along that pixel's
/// ray (a march 10x finer than the renderer's samples, then bisection), for the colour field
/// and for the CSPH attribute (the quotient's gradient): equal to 1e-6 of the depth wherever
/// both find one, and the renderer finds no crossing the march does not. The march may find
/// more: a crossing between two of the renderer's samples that no sample's extremum shows
/// (measured: none for the colour field, 2 of 120 pixels for the attribute, where the
/// quotient is undefined in gaps between particles; 1 for the colour field before the
/// renderer searched around local extrema). Each
/// normal is the brute-force gradient's direction (facing the eye) within 0.5 degrees.
#[test]
fn surface_depth_is_the_brute_force_first_crossing() {
    let p = fluidcast_testkit::cloud(300, 7, (0.12, 0.1));
    let kernel = Kernel::CubicSpline;
    for (field, iso) in [(IsoField::Colour, 0.35), (IsoField::Attribute(None), 0.3)] {
        let mut cam = Camera::default();
        cam.reset([-0.7; 3], [0.7; 3]);
        cam.azimuth(25.0);
        cam.elevation(-15.0);
        cam.orthogonalize_view_up();
        let size = 120;
        let surfaces = Surfaces {
            field: field.clone(),
            values: vec![iso],
            ..Default::default()
        };
        let (img, stats) =
            render_reference(&p, &cam, &tf(), &params(size, kernel, surfaces)).unwrap();
        let frame = cam.frame(size, size).unwrap();
        let value = |s: [f64; 3]| match field {
            IsoField::Colour => Some(s[1]),
            _ => (s[1] > 0.0).then(|| s[0] / s[1]),
        };
        let steps = 10 * stats.depth_samples;
        let (mut both, mut equal, mut only_brute, mut worst_normal) = (0, 0, 0, 0.0f64);
        for j in (0..size).step_by(3) {
            for i in (0..size).step_by(3) {
                let (o, d) = frame.ray(i, j);
                let (o, d) = (o.to_array(), d.to_array());
                let z = img.depth[img.index(i, j)] as f64;
                let want = brute_crossing(
                    |x| value(brute(&p, kernel, x)),
                    (o, d),
                    (stats.near, stats.far),
                    iso,
                    steps,
                );
                match (z.is_finite(), want) {
                    (true, Some(zb)) => {
                        both += 1;
                        // Single-precision Z: equal to its rounding.
                        if (z - zb).abs() <= 1e-6 * zb {
                            equal += 1;
                            let x = [0, 1, 2].map(|a| o[a] + zb * d[a]);
                            let down =
                                descent(|y| value(brute(&p, kernel, y)).unwrap_or(0.0), x, 1e-7);
                            let facing = if down[0] * d[0] + down[1] * d[1] + down[2] * d[2] < 0.0 {
                                1.0
                            } else {
                                -1.0
                            };
                            let n = [0, 1, 2].map(|a| img.aovs[a].1[img.index(i, j)] as f64);
                            worst_normal = worst_normal.max(angle_deg(n, down.map(|c| facing * c)));
                        }
                        assert!(
                            z >= zb - 1e-6 * zb,
                            "{i},{j}: {z} in front of the first crossing {zb}"
                        );
                        let on =
                            value(brute(&p, kernel, [0, 1, 2].map(|a| o[a] + zb * d[a]))).unwrap();
                        assert!(
                            (on - iso).abs() < 1e-9,
                            "{i},{j}: brute force {on} at its crossing"
                        );
                    }
                    (true, None) => {
                        panic!("{i},{j}: a surface at {z} the brute force does not cross")
                    }
                    (false, Some(_)) => only_brute += 1,
                    (false, None) => {}
                }
            }
        }
        let label = field.name();
        eprintln!("{label} {iso}: {both} pixels cross in both ({equal} at the same depth, normals within {worst_normal:.4} deg of the brute-force gradient), {only_brute} in the brute force only");
        assert!(
            worst_normal <= 0.5,
            "{label}: a normal {worst_normal} degrees off"
        );
        assert!(both > 100, "{label}: {both} pixels with a surface");
        assert!(
            equal as f64 >= 0.97 * both as f64,
            "{label}: {equal} of {both} at the brute-force depth"
        );
        assert!(
            only_brute as f64 <= 0.02 * both as f64,
            "{label}: {only_brute} crossings missed"
        );
    }
}

/// An opaque surface over the volume: each pixel is the volume in front of the surface
/// (rendered alone, stopped at the surface's depth as opaque geometry stops it) over the
/// surface's shaded colour (rendered alone); where no surface is met, the volume alone.
#[test]
fn an_opaque_surface_hides_the_volume_behind_it() {
    let p = fluidcast_testkit::cloud(300, 11, (0.12, 0.1));
    let mut cam = Camera::default();
    cam.reset([-0.7; 3], [0.7; 3]);
    cam.azimuth(-40.0);
    cam.orthogonalize_view_up();
    let size = 64;
    let kernel = Kernel::WendlandC2;
    let with = |volume: bool| Surfaces {
        values: vec![0.6],
        volume,
        ..Default::default()
    };
    let mut tf = tf();
    tf.unit_distance = 1.0; // a volume the surface shows through
    let (mixed, _) = render_reference(&p, &cam, &tf, &params(size, kernel, with(true))).unwrap();
    let (alone, _) = render_reference(&p, &cam, &tf, &params(size, kernel, with(false))).unwrap();
    let front_params = RenderParams {
        depth_limit: Some(alone.depth.iter().copied().collect()),
        ..params(size, kernel, with(false))
    };
    let front_params = RenderParams {
        surfaces: None,
        ..front_params
    };
    let (front, _) = render_reference(&p, &cam, &tf, &front_params).unwrap();
    let (mut surfaced, mut worst) = (0, 0.0f32);
    for k in 0..mixed.rgba.len() {
        let (f, s) = (front.rgba[k], alone.rgba[k]);
        let want: [f32; 4] = if alone.depth[k].is_finite() {
            surfaced += 1;
            [0, 1, 2, 3].map(|c| f[c] + (1.0 - f[3]) * s[c])
        } else {
            f
        };
        for (got, want) in mixed.rgba[k].iter().zip(want) {
            worst = worst.max((got - want).abs());
        }
        assert_eq!(
            mixed.depth[k].to_bits(),
            alone.depth[k].to_bits(),
            "Z is the surface's"
        );
    }
    assert!(surfaced > 500, "{surfaced} pixels with a surface");
    assert!(
        front.rgba.iter().any(|c| c[3] > 0.05),
        "some volume in front"
    );
    assert!(
        worst < 1e-5,
        "mixed differs from front-over-surface by {worst}"
    );
}

/// Renderers that do not draw surfaces say so instead of drawing the volume alone, and bad
/// surface parameters are refused by name.
#[test]
fn surfaces_are_refused_where_not_drawn_and_checked() {
    let p = fluidcast_testkit::cloud(50, 3, (0.12, 0.1));
    let mut cam = Camera::default();
    cam.reset([-0.7; 3], [0.7; 3]);
    let ok = params(32, Kernel::CubicSpline, Surfaces::default());
    let e = fluidcast_render::render_adaptive(&p, None, &cam, &tf(), &ok).unwrap_err();
    assert!(
        e.to_string()
            .contains("adaptive grid renderer does not draw iso-surfaces"),
        "{e}"
    );
    let e = fluidcast_render::render_object_space(&p, &cam, &tf(), &ok).unwrap_err();
    assert!(
        e.to_string()
            .contains("object-space renderer does not draw"),
        "{e}"
    );
    let bad = [
        (
            Surfaces {
                values: vec![],
                ..Default::default()
            },
            "no iso value",
        ),
        (
            Surfaces {
                values: vec![f64::NAN],
                ..Default::default()
            },
            "not finite",
        ),
        (
            Surfaces {
                opacity: 0.0,
                ..Default::default()
            },
            "opacity 0",
        ),
        (
            Surfaces {
                colour: Some([2.0, 0.0, 0.0]),
                ..Default::default()
            },
            "colour",
        ),
        (
            Surfaces {
                field: IsoField::Attribute(Some(vec![1.0; 49].into())),
                ..Default::default()
            },
            "49 values for 50 particles",
        ),
    ];
    for (s, want) in bad {
        let e = render_reference(&p, &cam, &tf(), &params(32, Kernel::CubicSpline, s)).unwrap_err();
        assert!(e.to_string().contains(want), "{e} lacks {want}");
    }
}

/// A sheet one particle thick seen face on, at an iso value just below the colour field's
/// smallest peak across it: the field exceeds the value over a span thinner than a depth
/// sample, so on many rays no two samples straddle it. Every ray through the sheet's
/// interior still shows the surface (found around the samples' local maximum), at a depth
/// where the brute-force field equals the value, on the camera's side of the sheet. (Without
/// the search around local extrema 252 of the 572 rays showed it.)
#[test]
fn a_sheet_thinner_than_a_depth_sample_is_not_missed() {
    let p = sheets(&[0.0]);
    let kernel = Kernel::CubicSpline;
    // The smallest peak over the interior (on the plane, where the field is largest).
    let peak = middle_plane(&p, kernel).fold(f64::INFINITY, f64::min);
    let iso = 0.99 * peak;
    let mut cam = Camera::default();
    cam.reset([-0.7, -0.7, -0.1], [0.7, 0.7, 0.1]);
    cam.azimuth(20.0); // the sheet's depth varies across the image: samples at every phase
    let size = 64;
    let surfaces = Surfaces {
        values: vec![iso],
        ..Default::default()
    };
    let (img, stats) = render_reference(&p, &cam, &tf(), &params(size, kernel, surfaces)).unwrap();
    let step = (stats.far - stats.near) / stats.depth_samples as f64;
    let (mut interior, mut shown) = (0, 0);
    for (i, j, o, d) in rays_through_plane(&cam, size, 0.4) {
        interior += 1;
        let z = img.depth[img.index(i, j)] as f64;
        if z.is_finite() {
            shown += 1;
            let y = (o + d * z).to_array();
            let f = brute(&p, kernel, y)[1];
            assert!(
                (f - iso).abs() < 1e-6 * iso,
                "{i},{j}: field {f} at the surface, iso {iso}"
            );
            assert!(y[2] > 0.0, "{i},{j}: the far side of the sheet ({})", y[2]);
        }
    }
    eprintln!("sheet: {shown} of {interior} interior pixels show it; iso {iso:.5} (peak {peak:.5}); depth step {step:.4}");
    assert!(interior > 500, "{interior} interior pixels");
    assert_eq!(
        shown, interior,
        "rays through the sheet that show no surface"
    );
}

/// Shaded volume rendering: a lattice block whose attribute is x + y has the CSPH gradient
/// (1, 1, 0) inside, across the view (along −z, parallel projection). Volume lighting is
/// two-sided (VTK's |n·l|, |n·h|): a directional light along ±(1, 1, 0) meets every sample's
/// normal head on, colour × (ambient + diffuse) plus the white highlight 0.2 (n·h)^10 with
/// n·h = cos 45 degrees, times the sample's opacity, which lighting leaves alone; a light
/// along (1, −1, 0) or the headlight (along z) is perpendicular to it and leaves the
/// ambient part (0.1) and, for the headlight, no highlight either (n·h = 0). So an interior
/// pixel's colour is 0.8 × the unlit one's + 0.2 c^10 × its alpha, or 0.1 × it: a gradient
/// along the wrong axis swaps the cases. Measured within 0.0005 and 0.019 of the unlit colour
/// (the perpendicular cases see the CSPH gradient's small deviations from (1, 1, 0) between
/// lattice points); allowed 0.03.
#[test]
fn shaded_volume_lights_samples_by_the_field_gradient() {
    let s = 0.05f32;
    let mut p = Particles::default();
    for i in -10..=10 {
        for j in -10..=10 {
            for k in -10..=10 {
                let x = [i as f32 * s, j as f32 * s, k as f32 * s];
                p.positions.push(x);
                p.radii.push(2.5 * s);
                p.volumes.push(s * s * s);
                p.masses.push(1.0);
                p.values.push(x[0] + x[1]);
            }
        }
    }
    let mut cam = Camera::default();
    cam.reset([-0.6, -0.6, -0.6], [0.6, 0.6, 0.6]);
    cam.parallel_projection = true;
    let mut tf = tf();
    tf.unit_distance = 2.0;
    let base = RenderParams {
        width: 48,
        height: 48,
        kernel: Kernel::WendlandC2,
        ..Default::default()
    };
    let (unlit, _) = render_reference(&p, &cam, &tf, &base).unwrap();
    let c = 0.5f64.sqrt();
    let mut lit_params = base.clone();
    let spec = 0.2 * c.powi(10);
    use fluidcast_view::Light::{Directional, Headlight};
    let cases = [
        (Directional([-1.0, -1.0, 0.0]), 0.8, spec),
        (Directional([1.0, 1.0, 0.0]), 0.8, spec),
        (Directional([1.0, -1.0, 0.0]), 0.1, 0.0),
        (Headlight, 0.1, 0.0),
    ];
    for (light, diffuse, specular) in cases {
        lit_params.volume_lighting = Some(fluidcast_view::Lighting {
            light,
            ..Default::default()
        });
        let (lit, _) = render_reference(&p, &cam, &tf, &lit_params).unwrap();
        let (mut checked, mut worst) = (0, 0.0f64);
        for j in 16..32 {
            for i in 16..32 {
                let k = unlit.index(i, j);
                let (u, l) = (unlit.rgba[k], lit.rgba[k]);
                assert!(u[3] > 0.05, "{i},{j}: the block is there");
                assert_eq!(u[3], l[3], "lighting leaves opacity alone");
                for ch in 0..3 {
                    let want = diffuse * u[ch] as f64 + specular * u[3] as f64;
                    worst = worst.max((l[ch] as f64 - want).abs() / u[ch] as f64);
                }
                checked += 1;
            }
        }
        eprintln!("shaded volume, {light:?}: {checked} interior pixels within {worst:.4} of the analytic lighting (relative to the unlit colour)");
        assert!(worst < 0.03, "lit colour off by {worst}");
    }
    let e = fluidcast_render::render_adaptive(&p, None, &cam, &tf, &lit_params).unwrap_err();
    assert!(
        e.to_string().contains("does not draw a shaded volume"),
        "{e}"
    );
}

/// Two slabs one particle spacing apart, seen face on through translucent surfaces: the
/// colour field dips below the iso value in the gap over a span thinner than a depth sample,
/// so no two samples straddle the gap's crossings. Each interior ray still composites four
/// surfaces (in, out of the gap, back in, out), found around the samples' local minimum in
/// the gap: alpha 1 − (1 − 0.5)⁴, where missing the gap gives 1 − (1 − 0.5)². (Without the
/// search around local minima 82 of the 416 rays did; `cargo mutants` had left that search
/// untested.)
#[test]
fn a_gap_thinner_than_a_depth_sample_shows_both_its_walls() {
    let p = sheets(&[-4, -3, -2, 2, 3, 4].map(|k| k as f32 * 0.04));
    let kernel = Kernel::CubicSpline;
    // The iso value: just above the field's largest value in the gap's middle plane, so the
    // gap is thin; below the field inside the slabs.
    let dip = middle_plane(&p, kernel).fold(0.0, f64::max);
    let iso = 1.02 * dip;
    assert!(
        brute(&p, kernel, [0.0, 0.0, 0.12])[1] > iso,
        "the slabs are above the value"
    );
    let mut cam = Camera::default();
    cam.reset([-0.7, -0.7, -0.3], [0.7, 0.7, 0.3]);
    cam.azimuth(15.0);
    let size = 64;
    let surfaces = Surfaces {
        values: vec![iso],
        opacity: 0.5,
        ..Default::default()
    };
    let (img, _) = render_reference(&p, &cam, &tf(), &params(size, kernel, surfaces)).unwrap();
    let (mut interior, mut four) = (0, 0);
    for (i, j, _, _) in rays_through_plane(&cam, size, 0.35) {
        interior += 1;
        let alpha = img.rgba[img.index(i, j)][3] as f64;
        four += usize::from((alpha - 0.9375).abs() < 1e-6);
    }
    eprintln!("gap: {four} of {interior} interior rays composite four surfaces (iso {iso:.4}, gap's largest value {dip:.4})");
    assert!(interior > 400);
    assert_eq!(four, interior, "rays that miss the gap's walls");
}
