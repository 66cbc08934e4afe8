//! The sample depths against a deliberately simple second derivation from the camera alone:
//! a perspective view steps so that one step along the image's corner ray is one pixel
//! (its height at that depth, 2 z tan(angle/2) / H) divided by the sampling scale, with
//! depths in geometric progression; a parallel view steps by one pixel (2 · parallel scale
//! / H) divided by the scale.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly

use fluidcast_grid::SampleDepths;
use fluidcast_view::Camera;

fn camera(angle: f64, parallel: bool) -> Camera {
    Camera {
        position: [0.3, -0.2, 4.0],
        focal_point: [0.0; 3],
        view_up: [0.0, 1.0, 0.0],
        view_angle: angle,
        parallel_projection: parallel,
        parallel_scale: 0.7,
    }
}

#[test]
fn perspective_steps_are_one_corner_pixel_in_geometric_progression() {
    for (angle, (w, h), scale, (near, far)) in [
        (30.0, (640, 480), 1.0, (2.0, 6.0)),
        (60.0, (300, 500), 2.0, (0.5, 9.0)),
        (12.0, (800, 200), 0.5, (3.0, 3.5)),
    ] {
        let f = camera(angle, false).frame(w, h).unwrap();
        let d = SampleDepths::new(&f, near, far, scale, 1).unwrap();
        assert!(d.logarithmic);
        assert_eq!((d.z[0], *d.z.last().unwrap()), (near, far));
        let tan = (angle.to_radians() / 2.0).tan();
        let aspect = w as f64 / h as f64;
        let corner = (1.0 + (tan * aspect).powi(2) + tan * tan).sqrt();
        let ratio = d.z[1] / d.z[0];
        for k in 0..d.len() {
            let (z0, z1) = (d.z[k], d.z[k + 1]);
            assert!(
                ((z1 / z0) / ratio - 1.0).abs() < 1e-9,
                "not geometric at {k}"
            );
            let pixel = 2.0 * z0 * tan / h as f64;
            let step = (z1 - z0) * corner;
            let r = step / (pixel / scale);
            // Rounding the count up shortens steps a little; ratio − 1 ≈ ln(ratio) lengthens
            // them by half a step's relative size.
            assert!(
                (0.97..=1.0 + (ratio - 1.0)).contains(&r),
                "angle {angle}, {w}×{h}, scale {scale}: step {k} is {r} corner pixels"
            );
        }
    }
}

#[test]
fn parallel_steps_are_one_pixel_and_counts_round_up_to_the_multiple() {
    for ((w, h), scale, multiple) in [
        ((640, 480), 1.0, 1),
        ((200, 100), 3.0, 16),
        ((90, 300), 0.25, 64),
    ] {
        let f = camera(30.0, true).frame(w, h).unwrap();
        let (near, far) = (1.0, 7.0);
        let d = SampleDepths::new(&f, near, far, scale, multiple).unwrap();
        assert!(!d.logarithmic);
        assert_eq!(d.len() % multiple, 0);
        let pixel = 2.0 * 0.7 / h as f64;
        let fewest = ((far - near) / (pixel / scale)).ceil() as usize;
        assert!(
            d.len() >= fewest && d.len() < fewest + multiple,
            "{} samples",
            d.len()
        );
        for k in 0..d.len() {
            let step = d.z[k + 1] - d.z[k];
            assert!((step - (far - near) / d.len() as f64).abs() < 1e-12);
            assert!(step <= pixel / scale * (1.0 + 1e-12));
        }
    }
}
