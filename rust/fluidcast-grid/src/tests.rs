use super::*;
use crate::sort::{sort_bundle_pairs, SortScratch};
use fluidcast_view::Camera;

fn cloud(n: usize, seed: u32) -> Particles {
    let mut rnd = fluidcast_testkit::rng(seed);
    let mut p = Particles::default();
    for _ in 0..n {
        p.positions.push([rnd() - 0.5, rnd() - 0.5, rnd() - 0.5]);
        p.radii.push(0.05 + 0.15 * rnd());
        p.volumes.push(0.01);
        p.masses.push(1.0);
        p.values.push(rnd());
    }
    p
}

fn frame(parallel: bool, w: u32, h: u32) -> ViewFrame {
    let mut c = Camera {
        parallel_projection: parallel,
        ..Default::default()
    };
    c.reset([-0.7; 3], [0.7; 3]);
    c.azimuth(25.0);
    c.elevation(15.0);
    c.orthogonalize_view_up();
    c.zoom(1.3);
    c.frame(w, h).unwrap()
}

/// Every ray sample inside a particle's support finds that particle in its cell and its
/// pixel in the particle's rectangle, and each cell's merge bits agree with the next cell's
/// references.
#[test]
fn cells_hold_every_contributing_particle() {
    let p = cloud(80, 3);
    for parallel in [false, true] {
        let f = frame(parallel, 37, 29);
        for params in [
            GridParams::default(),
            GridParams {
                bundle: 3,
                depth_samples: 4,
            },
        ] {
            let g = PerspectiveGrid::build(&p, &f, params, 0.5).unwrap();
            let depths = g.depths.as_ref().unwrap();
            assert_eq!(depths.len() % params.depth_samples as usize, 0);
            let mut checked = 0;
            for j in 0..f.height {
                for i in 0..f.width {
                    let b = ((j / params.bundle) * g.bundles_x + i / params.bundle) as usize;
                    let cells = g.bundle_cells(b);
                    let ray = Ray::through_pixel(&f, i, j);
                    for (k, &z) in depths.z[..depths.len()].iter().enumerate() {
                        for (q, vp) in g.particles.iter().enumerate() {
                            if ray.distance_at(z, vp) >= vp.h() {
                                continue;
                            }
                            let cz = (k / params.depth_samples as usize) as u32;
                            let c = cells
                                .iter()
                                .find(|c| c.z == cz)
                                .expect("cell of a contributing sample exists");
                            assert!(g.refs[c.start as usize..c.end as usize].contains(&(q as u32)));
                            // And the pixel lies in the particle's rectangle.
                            let r = g.rects[q].map(u32::from);
                            assert!(
                                (r[0]..r[1]).contains(&i) && (r[2]..r[3]).contains(&j),
                                "pixel ({i}, {j}) outside particle {q}'s rectangle {r:?}"
                            );
                            checked += 1;
                        }
                    }
                }
            }
            assert!(checked > 1000, "{checked}");
            for b in 0..g.bundle_count() {
                let cells = g.bundle_cells(b);
                for w in cells.windows(2) {
                    assert!(w[0].z < w[1].z);
                }
                for c in cells {
                    let next = cells.iter().find(|n| n.z == c.z + 1);
                    for &r in &g.refs[c.unique_end as usize..c.end as usize] {
                        let n = next.expect("merge bit set but no next cell");
                        assert!(g.refs[n.start as usize..n.end as usize].contains(&r));
                    }
                }
                // A merged run references each particle once, and all of them.
                if cells.len() >= 2 && cells[1].z == cells[0].z + 1 {
                    let mut m: Vec<u32> = g.merged_refs(&cells[..2]).collect();
                    let n = m.len();
                    m.sort();
                    m.dedup();
                    assert_eq!(m.len(), n);
                    let mut all: Vec<u32> =
                        g.refs[cells[0].start as usize..cells[1].end as usize].to_vec();
                    all.sort();
                    all.dedup();
                    assert_eq!(all, m);
                }
            }
        }
    }
}

#[test]
fn bundle_rect_and_coverage_hold_the_rays() {
    let f = frame(false, 40, 30);
    let p = cloud(10, 9);
    let g = PerspectiveGrid::build(&p, &f, GridParams::default(), 1.0).unwrap();
    for b in 0..g.bundle_count() {
        let whole = g.bundle(b);
        let parts = whole.split(&f, 3);
        assert_eq!(
            parts
                .iter()
                .map(|p| (p.pixels[1] - p.pixels[0]) * (p.pixels[3] - p.pixels[2]))
                .sum::<u32>(),
            (whole.pixels[1] - whole.pixels[0]) * (whole.pixels[3] - whole.pixels[2])
        );
        for bd in std::iter::once(whole).chain(parts) {
            for j in bd.pixels[2]..bd.pixels[3] {
                for i in bd.pixels[0]..bd.pixels[1] {
                    let r = Ray::through_pixel(&f, i, j);
                    assert!(r.dlen >= bd.dlen[0] - 1e-12 && r.dlen <= bd.dlen[1] + 1e-12);
                    for z in [0.5, 2.0, 7.0] {
                        let [x0, x1, y0, y1] = bd.rect_at(z);
                        let (x, y) = (r.o[0] + z * r.d[0], r.o[1] + z * r.d[1]);
                        assert!(x >= x0 - 1e-12 && x <= x1 + 1e-12);
                        assert!(y >= y0 - 1e-12 && y <= y1 + 1e-12);
                        for vp in &g.particles {
                            if bd.covered_by(vp, z) {
                                assert!(r.distance_at(z, vp) < vp.h());
                            }
                        }
                    }
                }
            }
        }
    }
}

/// Both ways of `within` (counting for up to 64 depths, binary search above), at depths
/// between samples, on samples, outside and reversed.
#[test]
fn within_matches_a_scan() {
    for n in [1, 16, 50, 64, 65, 300] {
        let zs: Vec<f64> = (0..n).map(|i| 1.0 + 0.1 * i as f64).collect();
        let cases = [
            (0.0, 100.0),
            (1.05, 1.3),
            (1.1, 1.1),
            (3.0, 2.0),
            (6.0, 9.0),
            (1.0, 1.0),
        ];
        let edges = [(zs[n - 1], 100.0), (zs[0], zs[0])];
        for (a, b) in cases.into_iter().chain(edges) {
            let r = within(&zs, a, b);
            let want: Vec<usize> = (0..zs.len())
                .filter(|&k| zs[k] >= a && zs[k] <= b)
                .collect();
            assert_eq!(r.collect::<Vec<_>>(), want, "{n} depths, [{a}, {b}]");
        }
    }
}

/// `within` over a ray's hundreds of depths (searched by blocks, then counted) equals the
/// binary searches, at every depth, between depths and outside, for lengths around whole
/// blocks, with repeated depths too.
#[test]
fn within_by_blocks_matches_binary_search() {
    for n in [65, 79, 80, 81, 100, 255, 256, 257, 576, 1000] {
        let plain: Vec<f64> = (0..n).map(|i| 2.0 * (1.01f64).powi(i as i32)).collect();
        let repeated: Vec<f64> = (0..n).map(|i| (i / 7) as f64).collect();
        for zs in [plain, repeated] {
            let mut qs = vec![f64::NEG_INFINITY, -1.0, 1e9, f64::INFINITY];
            for w in zs.windows(2) {
                qs.extend([w[0], 0.5 * (w[0] + w[1])]);
            }
            qs.push(zs[n - 1]);
            for &a in &qs {
                for b in [a, a + 0.3, a * 1.5 + 1.0] {
                    let want = zs.partition_point(|&z| z < a)..zs.partition_point(|&z| z <= b);
                    let want = want.start..want.end.max(want.start);
                    assert_eq!(within(&zs, a, b), want, "{n} depths, [{a}, {b}]");
                }
            }
        }
    }
}

/// The GPU places its depth samples by `support_depth_range`: it must be exactly the range the
/// CPU's `view_particles` finds (same samples on both), and `None` for no particles or nothing
/// in front of a perspective camera.
#[test]
fn support_depth_range_is_the_cpu_range() {
    let p = cloud(300, 9);
    for parallel in [false, true] {
        let f = frame(parallel, 40, 30);
        let range = support_depth_range(&p, &f);
        assert!(range.is_some());
        assert_eq!(range, view_particles(&p, &f).range, "parallel {parallel}");
        // The extremes are reached: the nearest and farthest supports bound the range.
        let (near, far) = range.unwrap();
        let zs: Vec<(f64, f64)> = view_particles(&p, &f)
            .list
            .iter()
            .map(|v| (v.c[2] - v.h(), v.c[2] + v.h()))
            .collect();
        assert_eq!(
            far,
            zs.iter().map(|z| z.1).fold(f64::NEG_INFINITY, f64::max)
        );
        if parallel {
            assert_eq!(near, zs.iter().map(|z| z.0).fold(f64::INFINITY, f64::min));
        }
    }
    assert_eq!(
        support_depth_range(&Particles::default(), &frame(false, 8, 8)),
        None
    );
    let mut behind = cloud(20, 4);
    for x in behind.positions.iter_mut() {
        x[2] += 50.0; // behind the camera, which looks down -z from about z = 2.7
    }
    let f = frame(false, 8, 8);
    assert_eq!(
        support_depth_range(&behind, &f),
        view_particles(&behind, &f).range
    );
}

/// A ray's passage through a support: it enters and leaves at distance H from the centre, is
/// nearest at `t`, and there is none exactly when the ray's closest distance is H or more.
#[test]
fn passage_enters_and_leaves_at_the_support_radius() {
    let p = cloud(200, 17);
    for parallel in [false, true] {
        let f = frame(parallel, 23, 17);
        let vp = view_particles(&p, &f).list;
        let (mut inside, mut outside) = (0, 0);
        for j in 0..17 {
            for i in 0..23 {
                let ray = Ray::through_pixel(&f, i, j);
                for q in &vp {
                    let closest = ray.distance_at(ray.closest_approach(q).0, q);
                    match ray.passage(q) {
                        Some(s) => {
                            inside += 1;
                            for z in [s.z0, s.z1] {
                                assert!((ray.distance_at(z, q) - q.h()).abs() < 1e-9 * q.h());
                                assert!((s.distance_at(z) - q.h()).abs() < 1e-9 * q.h());
                            }
                            assert!(s.z0 <= s.t && s.t <= s.z1 && closest < q.h());
                            assert!((s.distance_at(s.t) - closest).abs() < 1e-9);
                        }
                        None => {
                            outside += 1;
                            assert!(closest >= q.h() * (1.0 - 1e-12), "{closest} < {}", q.h());
                        }
                    }
                }
            }
        }
        assert!(
            inside > 100 && outside > 100,
            "{inside} inside, {outside} outside"
        );
    }
}

/// `bundle_of` inverts `bundle_pixels`: every pixel of bundle b lies in bundle b, for image
/// sizes that cut the last row and column of bundles, and bundles of one pixel.
#[test]
fn bundle_of_finds_the_bundle_whose_pixels_hold_it() {
    for (w, h, size) in [(70u32, 53u32, 8u32), (64, 48, 8), (9, 5, 1), (33, 17, 16)] {
        let bundles = (w.div_ceil(size) * h.div_ceil(size)) as usize;
        let mut seen = 0;
        for b in 0..bundles {
            let [x0, x1, y0, y1] = bundle_pixels(w, h, size, b);
            for j in y0..y1 {
                for i in x0..x1 {
                    assert_eq!(bundle_of(w, size, i, j), b, "{w}x{h} by {size}: ({i}, {j})");
                    seen += 1;
                }
            }
        }
        assert_eq!(seen, w * h);
    }
}

/// The grid holds pixel rectangles in 16 bits: a wider image is refused with an error, not
/// wrapped around.
#[test]
fn images_wider_than_16_bits_are_refused() {
    let p = cloud(10, 1);
    for (w, h) in [(70_000, 2), (2, 70_000)] {
        let f = frame(false, w, h);
        let err = PerspectiveGrid::build(&p, &f, GridParams::default(), 1.0).unwrap_err();
        assert!(
            matches!(err, GridError::ImageSize(a, b) if (a, b) == (w, h)),
            "{err}"
        );
    }
    assert!(
        PerspectiveGrid::build(&p, &frame(false, 65_535, 1), GridParams::default(), 1.0).is_ok()
    );
}

/// The counting sort of a bundle's keys equals a full sort: keys in particle order with
/// cells over a narrow and a wide depth range (the latter sorted), and keys out of particle
/// order (which the counting sort must not take).
#[test]
fn bundle_pairs_sort_as_a_full_sort_does() {
    let mut x = 12345u32;
    let mut rnd = |n: u32| {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        x % n
    };
    let mut scratch = SortScratch::default();
    for (len, depth, shuffle) in [
        (0, 4, false),
        (1, 4, false),
        (500, 3, false),
        (500, 40, false),
        (40, 100_000, false),
        (500, 40, true),
    ] {
        let mut keys = Vec::new();
        let mut j = 0u64;
        while keys.len() < len {
            j += u64::from(rnd(3));
            let z0 = u64::from(rnd(depth));
            let n = 1 + u64::from(rnd(4));
            for z in z0..z0 + n {
                keys.push((z << 33) | (u64::from(z + 1 < z0 + n) << 32) | j);
            }
            j += 1;
        }
        if shuffle {
            keys.reverse();
        }
        let mut want = keys.clone();
        want.sort_unstable();
        sort_bundle_pairs(&mut keys, &mut scratch);
        assert_eq!(keys, want, "{len} keys over {depth} cells");
    }
}
