//! `validate` accepts exactly the documented ranges, at their edges, and says which value is
//! wrong; `depth_limit_at` reads pixel (i, j) of a row-major, top-row-first buffer.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly

use std::sync::Arc;

use fluidcast_render::{validate, GridError, RenderError, RenderParams, MAX_SIDE};

fn size(width: u32, height: u32) -> RenderParams {
    RenderParams {
        width,
        height,
        ..Default::default()
    }
}

/// Not rejected for its size (it may still be too large for this machine's memory budget).
fn size_ok(width: u32, height: u32) -> bool {
    !matches!(
        validate(&size(width, height)),
        Err(RenderError::ImageSize(..))
    )
}

#[test]
fn image_sides_and_pixel_count_have_inclusive_limits() {
    assert!(validate(&size(1, 1)).is_ok());
    assert!(validate(&size(MAX_SIDE, 1)).is_ok());
    assert!(validate(&size(1, MAX_SIDE)).is_ok());
    for (w, h) in [(0, 1), (1, 0), (0, 0), (MAX_SIDE + 1, 1), (1, MAX_SIDE + 1)] {
        assert!(!size_ok(w, h), "{w}x{h} must be rejected");
    }
    // 2^27 pixels is the limit: 16384 x 8192 passes the size check, one row more does not.
    assert!(size_ok(MAX_SIDE, 8192));
    assert!(size_ok(8192, MAX_SIDE));
    assert!(!size_ok(MAX_SIDE, 8193));
    assert!(!size_ok(8193, MAX_SIDE));
    let e = validate(&size(0, 3)).unwrap_err().to_string();
    assert!(e.contains("0x3"), "{e}");
}

#[test]
fn min_transmittance_lies_in_zero_to_one() {
    let with = |t: f64| RenderParams {
        min_transmittance: t,
        ..size(4, 4)
    };
    for t in [0.0, 1e-4, 0.999] {
        assert!(validate(&with(t)).is_ok(), "{t}");
    }
    for t in [1.0, -1e-9, f64::NAN, f64::INFINITY] {
        assert!(
            matches!(validate(&with(t)), Err(RenderError::MinTransmittance(_))),
            "{t}"
        );
    }
}

#[test]
fn sampling_scale_is_finite_and_positive() {
    let with = |s: f64| RenderParams {
        sampling_scale: s,
        ..size(4, 4)
    };
    for s in [1e-6, 1.0, 64.0] {
        assert!(validate(&with(s)).is_ok(), "{s}");
    }
    for s in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert!(
            matches!(
                validate(&with(s)),
                Err(RenderError::Grid(GridError::SamplingScale(_)))
            ),
            "{s}"
        );
    }
}

#[test]
fn bad_grid_parameters_are_errors() {
    let mut p = size(4, 4);
    p.grid.bundle = 0;
    assert!(matches!(validate(&p), Err(RenderError::Grid(_))));
}

#[test]
fn depth_limits_must_cover_the_image_with_non_negative_depths() {
    type Slot = fn(&mut RenderParams) -> &mut Option<Arc<[f32]>>;
    let slots: [(&str, Slot); 2] = [
        ("depth limit", |p| &mut p.depth_limit),
        ("depth near", |p| &mut p.depth_near),
    ];
    for (name, slot) in slots {
        let with = |d: Vec<f32>| {
            let mut p = size(3, 2);
            *slot(&mut p) = Some(Arc::from(d));
            p
        };
        assert!(validate(&with(vec![0.0, 1.0, 2.0, 3.0, f32::INFINITY, 0.5])).is_ok());
        for n in [5, 7, 2] {
            assert!(matches!(
                validate(&with(vec![1.0; n])),
                Err(RenderError::DepthLimitSize(w, m, 3, 2)) if m == n && w == name
            ));
        }
        for bad in [f32::NAN, -0.5] {
            let mut d = vec![1.0; 6];
            d[5] = bad;
            assert!(
                matches!(validate(&with(d)), Err(RenderError::DepthLimitValue(w)) if w == name),
                "{name} {bad}"
            );
        }
    }
}

#[test]
fn depth_limit_at_reads_row_major_pixels() {
    let (w, h) = (5u32, 3u32);
    let d: Vec<f32> = (0..w * h).map(|k| k as f32).collect();
    let p = RenderParams {
        depth_limit: Some(Arc::from(d)),
        ..size(w, h)
    };
    for j in 0..h {
        for i in 0..w {
            assert_eq!(p.depth_limit_at(i, j), (j * w + i) as f64, "({i}, {j})");
        }
    }
    assert_eq!(size(w, h).depth_limit_at(2, 1), f64::INFINITY);
}

#[test]
fn plan_tolerance_and_relaxation_lie_in_zero_to_one() {
    use fluidcast_render::{PlanError, PlanParams};
    let plan = |tolerance, relax| PlanParams {
        tolerance,
        relax,
        ..Default::default()
    };
    for (e, r) in [(None, 0.0), (Some(0.0), 1.0), (Some(1.0), 0.5), (None, 1.0)] {
        assert!(plan(e, r).validate().is_ok(), "{e:?} {r}");
    }
    for e in [1.5, -0.01, f64::NAN] {
        assert!(matches!(
            plan(Some(e), 1.0).validate(),
            Err(PlanError::Tolerance(_))
        ));
    }
    for r in [1.01, -0.5, f64::NAN] {
        assert!(matches!(plan(None, r).validate(), Err(PlanError::Relax(_))));
    }
    // The renderer refuses them too, naming the value.
    let p = fluidcast_testkit::depth_ramp(4);
    let tf = fluidcast_testkit::depth_ramp_tf(0.2);
    let cam = fluidcast_view::Camera::default();
    let prm = RenderParams {
        adaptive: plan(Some(1.5), 1.0),
        ..size(8, 8)
    };
    let e = fluidcast_render::render_adaptive(&p, None, &cam, &tf, &prm)
        .err()
        .map(|e| e.to_string());
    assert!(e.as_deref().is_some_and(|e| e.contains("1.5")), "{e:?}");
}
