//! The RBF field and its BVH against brute force over every particle (formulas written out
//! here, not taken from the crate).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly
#![allow(clippy::needless_range_loop)] // channels and axes by index, as the formulas write them

use fluidcast_rbf::{AttributeMap, ClusterBvh, Colouring, RbfError, RbfField, RbfOptions};
use fluidcast_sph::Particles;
use fluidcast_testkit::{cloud, rng};
use fluidcast_view::TransferFunction;

fn d2(a: [f32; 3], x: [f64; 3]) -> f64 {
    (0..3).map(|k| (x[k] - f64::from(a[k])).powi(2)).sum()
}

/// The particles whose sphere holds `x`, by looking at each one.
fn brute_within(c: &[[f32; 3]], r: &[f32], x: [f64; 3]) -> Vec<u32> {
    (0..c.len() as u32)
        .filter(|&i| {
            r[i as usize] > 0.0 && d2(c[i as usize], x) <= f64::from(r[i as usize]).powi(2)
        })
        .collect()
}

fn bvh_within(bvh: &ClusterBvh, x: [f64; 3]) -> Vec<u32> {
    let mut v = Vec::new();
    bvh.for_each_within(x, |s| v.push(bvh.particle(s)));
    v.sort_unstable();
    v
}

/// Random radii in [0, 0.2), a fifth of them 0 (hidden).
fn random_radii(n: usize, seed: u32) -> Vec<f32> {
    let mut rnd = rng(seed);
    (0..n)
        .map(|_| {
            let (a, b) = (rnd(), rnd());
            if a < 0.2 {
                0.0
            } else {
                0.2 * b
            }
        })
        .collect()
}

fn points(n: usize, seed: u32) -> Vec<[f64; 3]> {
    let mut rnd = rng(seed);
    (0..n)
        .map(|_| [0, 1, 2].map(|_| 1.4 * f64::from(rnd()) - 0.7))
        .collect()
}

#[test]
fn range_queries_return_exactly_the_particles_in_range_before_and_after_refit() {
    let p = cloud(3000, 7, (0.01, 0.15));
    let radii = random_radii(p.len(), 3);
    let xs = points(400, 11);
    for leaf in [1, 3, 8, 64] {
        let mut bvh = ClusterBvh::build(&p.positions, &p.radii, leaf).unwrap();
        let mut found = 0;
        for &x in &xs {
            let want = brute_within(&p.positions, &p.radii, x);
            found += want.len();
            assert_eq!(bvh_within(&bvh, x), want, "leaf {leaf}, {x:?}");
        }
        assert!(found > 2000, "the queries must find particles: {found}");
        // New radii (some zero): the same topology, refit boxes.
        bvh.refit(&radii).unwrap();
        for &x in &xs {
            assert_eq!(
                bvh_within(&bvh, x),
                brute_within(&p.positions, &radii, x),
                "refit, leaf {leaf}, {x:?}"
            );
        }
    }
}

/// Points exactly on a sphere's extreme (centre ± radius along an axis, exact in double
/// precision) are in range, so the single-precision boxes must be rounded outward.
#[test]
fn points_on_a_spheres_extreme_are_found() {
    let mut rnd = rng(77);
    let mut found = 0;
    for _ in 0..2000 {
        let c = [0, 1, 2].map(|_| 10.0 * rnd() - 5.0);
        let r = 0.001 + 0.3 * rnd();
        let bvh = ClusterBvh::build(&[c], &[r], 1).unwrap();
        for a in 0..3 {
            for sign in [-1.0, 1.0] {
                let mut x = c.map(f64::from);
                x[a] += sign * f64::from(r);
                // |x - c| is r exactly here: the sphere holds x.
                assert_eq!((x[a] - f64::from(c[a])).abs(), f64::from(r));
                let mut hit = false;
                bvh.for_each_within(x, |_| hit = true);
                assert!(hit, "centre {c:?}, radius {r}, axis {a}, side {sign}");
                found += 1;
            }
        }
    }
    assert_eq!(found, 12000);
}

#[test]
fn ray_queries_return_every_sphere_the_ray_crosses_and_where() {
    let p = cloud(2000, 5, (0.02, 0.1));
    let bvh = ClusterBvh::build(&p.positions, &p.radii, 8).unwrap();
    let mut rnd = rng(9);
    for q in 0..200 {
        let o = [0, 1, 2].map(|_| 3.0 * f64::from(rnd()) - 1.5);
        let mut d = [0, 1, 2].map(|_| f64::from(rnd()) - 0.5);
        if q % 10 == 0 {
            d = [0.0, 0.0, 1.0]; // parallel to two slabs
        }
        let range = (-1.0, 2.0);
        let mut got = Vec::new();
        bvh.for_each_on_ray(o, d, range, |h| {
            got.push((bvh.particle(h.slot), h.t_in, h.t_out))
        });
        got.sort_by_key(|g| g.0);
        // Brute force: the closest approach of the line within r, by the quadratic.
        let mut want = Vec::new();
        for (i, c) in p.positions.iter().enumerate() {
            let oc: Vec<f64> = (0..3).map(|k| o[k] - f64::from(c[k])).collect();
            let a: f64 = d.iter().map(|v| v * v).sum();
            let b: f64 = 2.0 * (0..3).map(|k| d[k] * oc[k]).sum::<f64>();
            let cc: f64 = oc.iter().map(|v| v * v).sum::<f64>() - f64::from(p.radii[i]).powi(2);
            let disc = b * b - 4.0 * a * cc;
            if disc < 0.0 {
                continue;
            }
            let (t0, t1) = (
                (-b - disc.sqrt()) / (2.0 * a),
                (-b + disc.sqrt()) / (2.0 * a),
            );
            let (t0, t1) = (t0.max(range.0), t1.min(range.1));
            if t0 <= t1 {
                want.push((i as u32, t0, t1));
            }
        }
        assert_eq!(got.len(), want.len(), "ray {q}");
        for (g, w) in got.iter().zip(&want) {
            assert_eq!(g.0, w.0, "ray {q}");
            assert!(
                (g.1 - w.1).abs() < 1e-9 && (g.2 - w.2).abs() < 1e-9,
                "ray {q}: {g:?} vs {w:?}"
            );
        }
    }
}

#[test]
fn frustum_queries_keep_every_sphere_not_wholly_outside_a_plane() {
    let p = cloud(3000, 13, (0.01, 0.1));
    let radii = random_radii(p.len(), 21);
    let mut rnd = rng(31);
    for leaf in [1, 8] {
        let bvh = ClusterBvh::build(&p.positions, &radii, leaf).unwrap();
        let mut total = 0;
        for q in 0..60 {
            // Four random planes through points near the cloud (a frustum-like wedge).
            let planes: Vec<[f64; 4]> = (0..4)
                .map(|_| {
                    let n: Vec<f64> = (0..3).map(|_| f64::from(rnd()) - 0.5).collect();
                    let len = n.iter().map(|v| v * v).sum::<f64>().sqrt().max(1e-9);
                    let n: Vec<f64> = n.iter().map(|v| v / len).collect();
                    let at: Vec<f64> = (0..3).map(|_| 0.6 * f64::from(rnd()) - 0.3).collect();
                    let d = -(0..3).map(|k| n[k] * at[k]).sum::<f64>();
                    [n[0], n[1], n[2], d]
                })
                .collect();
            let mut got = Vec::new();
            bvh.for_each_in_planes(&planes, |s| got.push(bvh.particle(s)));
            got.sort_unstable();
            // The rule, particle by particle: visible, and on the inner side of every plane
            // within its radius.
            let want: Vec<u32> = (0..p.len() as u32)
                .filter(|&i| {
                    let (c, r) = (p.positions[i as usize], f64::from(radii[i as usize]));
                    r > 0.0
                        && planes.iter().all(|pl| {
                            (0..3).map(|k| pl[k] * f64::from(c[k])).sum::<f64>() + pl[3] >= -r
                        })
                })
                .collect();
            assert_eq!(got, want, "leaf {leaf}, query {q}");
            total += want.len();
        }
        assert!(total > 1000, "the queries must keep particles: {total}");
    }
}

/// `Σ φ_i` and `Σ φ_i θ_i` at `x` over all particles, with the paper's Eq. 1–2 written out.
fn brute_sums(
    p: &Particles,
    radius: &dyn Fn(usize) -> f64,
    weight_theta: &dyn Fn(usize) -> (f64, [f64; 3]),
    x: [f64; 3],
) -> (f64, [f64; 3]) {
    let mut phi_sum = 0.0;
    let mut th = [0.0; 3];
    for i in 0..p.len() {
        let d = d2(p.positions[i], x).sqrt();
        let r = radius(i);
        if r > 0.0 && d <= r {
            let (w, theta) = weight_theta(i);
            let phi = w * (-0.5 * (3.0 * d / r).powi(2)).exp();
            phi_sum += phi;
            for k in 0..3 {
                th[k] += phi * theta[k];
            }
        }
    }
    (phi_sum, th)
}

fn tf(lo: f64, hi: f64) -> TransferFunction {
    let mut tf = TransferFunction::preset("Cool to Warm")
        .unwrap()
        .with_range(lo, hi)
        .unwrap();
    // A density map that is not constant: opacity ramps 0.2 → 1 over the range.
    tf.opacity = vec![(0.0, 0.2), (1.0, 1.0)];
    tf
}

#[test]
fn the_field_matches_a_brute_force_sum_over_all_particles() {
    let p = cloud(4000, 21, (0.05, 0.1));
    let (lo, hi) = p.value_range();
    let tf = tf(f64::from(lo), f64::from(hi));
    let map = AttributeMap::parse("0,0.5,0.5,1,1,0.25").unwrap();
    let t = |i: usize| tf.normalised(f64::from(p.values[i])).unwrap();
    for colouring in [Colouring::Post, Colouring::Pre, Colouring::Density] {
        let opts = RbfOptions {
            radius: Some(0.12),
            radius_map: map.clone(),
            colouring,
            leaf_size: 8,
        };
        let field = RbfField::build(&p, &tf, &opts).unwrap();
        let radius = |i: usize| match colouring {
            Colouring::Density => 0.12f32 as f64,
            _ => f64::from((f64::from(0.12f32) * map.eval(f64::from(t(i) as f32))) as f32),
        };
        let wt = |i: usize| match colouring {
            Colouring::Density => (1.0, [0.0; 3]),
            Colouring::Pre => {
                let (c, o) = tf.eval(f64::from(p.values[i]));
                (f64::from(o as f32), c.map(|v| f64::from(v as f32)))
            }
            Colouring::Post => {
                let o = tf.eval(f64::from(p.values[i])).1;
                (f64::from(o as f32), [f64::from(p.values[i]), 0.0, 0.0])
            }
        };
        let mut nonzero = 0;
        for x in points(300, 4) {
            let s = field.sample(x);
            let (phi, th) = brute_sums(&p, &radius, &wt, x);
            let tol = 1e-5 * phi.abs().max(1.0);
            assert!(
                (s.density - phi).abs() <= tol,
                "{colouring:?} {x:?}: {} vs {phi}",
                s.density
            );
            for k in 0..3 {
                assert!(
                    (s.weighted[k] - th[k]).abs() <= 1e-5 * th[k].abs().max(1.0),
                    "{colouring:?}"
                );
            }
            nonzero += usize::from(phi > 0.0);
        }
        assert!(
            nonzero > 100,
            "{colouring:?}: {nonzero} points inside the cloud"
        );
    }
}

/// Two particles of the two ends of a diverging map, overlapping at their midpoint.
fn pair(a: f32, b: f32) -> Particles {
    let mut p = Particles::default();
    for (x, v) in [(-0.05f32, a), (0.05, b)] {
        p.positions.push([x, 0.0, 0.0]);
        p.radii.push(0.2);
        p.volumes.push(1.0);
        p.masses.push(1.0);
        p.values.push(v);
    }
    p
}

#[test]
fn pre_and_post_classification_differ_where_classes_mix_and_agree_on_a_constant() {
    let mut tf = tf(0.0, 1.0);
    // Every class at full weight: the two particles weigh the same at their midpoint.
    tf.opacity = vec![(0.0, 1.0), (1.0, 1.0)];
    let colour = |field: &RbfField, x: [f64; 3]| -> [f64; 3] {
        let a = field.sample(x).attribute().unwrap();
        match field.colouring() {
            Colouring::Pre => a,
            _ => tf.eval(a[0]).0,
        }
    };
    let build = |p: &Particles, colouring| {
        let opts = RbfOptions {
            colouring,
            ..Default::default()
        };
        RbfField::build(p, &tf, &opts).unwrap()
    };
    // Classes 0 (blue) and 1 (red): pre-classification mixes their colours (purple), post
    // blends the attribute to 0.5, the map's light middle.
    let two = pair(0.0, 1.0);
    let (pre, post) = (build(&two, Colouring::Pre), build(&two, Colouring::Post));
    let mid = [0.0, 0.0, 0.0];
    let (cp, cq) = (colour(&pre, mid), colour(&post, mid));
    let (blue, red, middle) = (tf.eval(0.0).0, tf.eval(1.0).0, tf.eval(0.5).0);
    // At the midpoint both weigh the same: pre is the colours' mean (purple), post the
    // middle colour (light grey).
    for k in 0..3 {
        let mean = 0.5 * (blue[k] + red[k]);
        assert!((cp[k] - mean).abs() < 1e-6, "pre {cp:?} vs {mean}");
        assert!(
            (cq[k] - middle[k]).abs() < 1e-6,
            "post {cq:?} vs {middle:?}"
        );
    }
    let diff = (0..3).map(|k| (cp[k] - cq[k]).abs()).fold(0.0, f64::max);
    assert!(
        diff > 0.2,
        "pre {cp:?} and post {cq:?} should differ where classes mix"
    );
    // Near one particle's far side only it reaches: both give its class's colour.
    let side = [-0.2, 0.0, 0.0];
    for k in 0..3 {
        assert!((colour(&pre, side)[k] - blue[k]).abs() < 1e-6);
        assert!((colour(&post, side)[k] - blue[k]).abs() < 1e-6);
    }
    // A constant attribute: pre and post agree everywhere.
    let same = pair(0.3, 0.3);
    let (pre, post) = (build(&same, Colouring::Pre), build(&same, Colouring::Post));
    for x in points(50, 8) {
        if pre.sample(x).density > 0.0 {
            let (a, b) = (colour(&pre, x), colour(&post, x));
            for k in 0..3 {
                assert!((a[k] - b[k]).abs() < 1e-6, "{x:?}: {a:?} vs {b:?}");
            }
        }
    }
}

#[test]
fn the_radius_map_hides_particles_by_refitting() {
    let tf = tf(0.0, 1.0);
    let mut field = RbfField::build(&pair(0.0, 1.0), &tf, &RbfOptions::default()).unwrap();
    let right = [0.2, 0.0, 0.0];
    assert!(field.sample(right).density > 0.0);
    // Factor 1 at class 0, 0 at class 1: the second particle disappears.
    field
        .set_radius_map(&AttributeMap::parse("0,1,1,0").unwrap())
        .unwrap();
    assert_eq!(field.sample(right).density, 0.0);
    assert!(field.sample([-0.2, 0.0, 0.0]).density > 0.0);
    // Half the radius at class 1: reaches 0.15 but not 0.2 from x = 0.05.
    field
        .set_radius_map(&AttributeMap::parse("0,1,1,0.5").unwrap())
        .unwrap();
    assert_eq!(field.sample(right).neighbours, 0);
    assert_eq!(field.sample([0.14, 0.0, 0.0]).neighbours, 2);
}

#[test]
fn bad_particles_are_refused_naming_the_particle() {
    let tf = tf(0.0, 1.0);
    let mut p = pair(0.0, 1.0);
    p.radii[1] = f32::NAN;
    let e = RbfField::build(&p, &tf, &RbfOptions::default()).unwrap_err();
    assert!(matches!(e, RbfError::Radius { index: 1, .. }), "{e}");
    let mut p = pair(0.0, 1.0);
    p.positions[0][2] = f32::INFINITY;
    let e = RbfField::build(&p, &tf, &RbfOptions::default()).unwrap_err();
    assert!(matches!(e, RbfError::Centre { index: 0, .. }), "{e}");
    let mut p = pair(0.0, 1.0);
    p.values[1] = f32::NAN;
    let e = RbfField::build(&p, &tf, &RbfOptions::default()).unwrap_err();
    assert!(e.to_string().contains("particle 1"), "{e}");
    let bad_leaf = RbfOptions {
        leaf_size: 0,
        ..Default::default()
    };
    assert!(RbfField::build(&pair(0.0, 1.0), &tf, &bad_leaf).is_err());
    let bad_radius = RbfOptions {
        radius: Some(-1.0),
        ..Default::default()
    };
    assert!(RbfField::build(&pair(0.0, 1.0), &tf, &bad_radius).is_err());
    for s in ["", "0,1,1", "0,-1", "2,1", "a,b"] {
        assert!(AttributeMap::parse(s).is_err(), "{s}");
    }
    // No particles: an empty field, zero everywhere.
    let empty = RbfField::build(&Particles::default(), &tf, &RbfOptions::default()).unwrap();
    assert_eq!(empty.sample([0.0; 3]).density, 0.0);
}

/// What the GPU uploads (the heap-ordered boxes, the first leaf, the Hilbert-ordered spheres,
/// the leaf size) answers a point query as the library does: a walk written here over the
/// public layout.
#[test]
fn the_public_layout_walks_to_the_same_particles() {
    let p = cloud(1500, 41, (0.02, 0.1));
    let radii = random_radii(p.len(), 43);
    for leaf in [1, 5, 16] {
        let bvh = ClusterBvh::build(&p.positions, &radii, leaf).unwrap();
        let (boxes, spheres) = (bvh.boxes(), bvh.spheres());
        assert_eq!(bvh.len(), p.len());
        assert!(!bvh.is_empty());
        assert_eq!(bvh.leaf_size(), leaf);
        assert_eq!(bvh.clusters(), p.len().div_ceil(leaf));
        assert_eq!(boxes.len(), 2 * bvh.first_leaf());
        assert!(bvh.first_leaf() >= bvh.clusters() && bvh.first_leaf() < 2 * bvh.clusters());
        assert_eq!(
            bvh.memory_bytes(),
            4 * p.len() + 16 * spheres.len() + 24 * boxes.len(),
            "order, spheres and boxes"
        );
        for x in points(100, 47) {
            let mut got = Vec::new();
            let mut stack = vec![1usize];
            while let Some(k) = stack.pop() {
                let b = boxes[k];
                let inside =
                    (0..3).all(|a| f64::from(b.lo[a]) <= x[a] && x[a] <= f64::from(b.hi[a]));
                if !inside {
                    continue;
                }
                if k >= bvh.first_leaf() {
                    let c = k - bvh.first_leaf();
                    for slot in (c * leaf..((c + 1) * leaf).min(spheres.len())).map(|s| s as u32) {
                        let s = spheres[slot as usize];
                        let r = f64::from(s[3]);
                        if r > 0.0 && d2([s[0], s[1], s[2]], x) <= r * r {
                            got.push(bvh.particle(slot));
                        }
                    }
                } else {
                    stack.extend([2 * k, 2 * k + 1]);
                }
            }
            got.sort_unstable();
            assert_eq!(got, brute_within(&p.positions, &radii, x), "leaf {leaf}");
        }
    }
    assert!(ClusterBvh::build(&[], &[], 8).unwrap().is_empty());
}

/// Hilbert clusters are compact: on a uniform cloud, the mean diagonal of a leaf's box (of
/// centres) is far below that of clusters of the same size in the input order.
#[test]
fn hilbert_clusters_are_compact() {
    // Far from the origin and 50 units across, so that the lattice's offset and scale count.
    let mut p = cloud(8000, 51, (0.0, 0.0));
    for c in &mut p.positions {
        *c = c.map(|v| 1000.0 + 50.0 * v);
    }
    let zero = vec![1e-6f32; p.len()];
    let bvh = ClusterBvh::build(&p.positions, &zero, 8).unwrap();
    let diag = |ids: &[u32]| {
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for &i in ids {
            for a in 0..3 {
                lo[a] = lo[a].min(p.positions[i as usize][a]);
                hi[a] = hi[a].max(p.positions[i as usize][a]);
            }
        }
        (0..3)
            .map(|a| f64::from(hi[a] - lo[a]).powi(2))
            .sum::<f64>()
            .sqrt()
    };
    let mean =
        |order: &[u32]| order.chunks(8).map(diag).sum::<f64>() / order.len().div_ceil(8) as f64;
    let input: Vec<u32> = (0..p.len() as u32).collect();
    let (sorted, unsorted) = (mean(bvh.order()), mean(&input));
    // 8 random points of the cube span about 0.6 of its side; 8 neighbours of 8,000 about 0.08.
    assert!(
        sorted < 0.25 * unsorted,
        "Hilbert {sorted} vs input order {unsorted}"
    );
}

#[test]
fn edge_cases_of_the_queries_and_the_input() {
    // A hidden particle is not found even at its exact centre, by a point or a ray, though
    // its cluster's box (made by a visible neighbour) holds it.
    let c = [[0.1f32, 0.2, 0.3], [0.1, 0.2, 0.35]];
    let bvh = ClusterBvh::build(&c, &[0.0, 0.2], 8).unwrap();
    let centre = c[0].map(f64::from);
    assert_eq!(bvh_within(&bvh, centre), vec![1]);
    let mut hits = 0;
    let o = [centre[0], centre[1], -1.0];
    bvh.for_each_on_ray(o, [0.0, 0.0, 1.0], (0.0, 9.0), |h| {
        assert_eq!(bvh.particle(h.slot), 1);
        hits += 1;
    });
    assert_eq!(hits, 1);
    hits = 0;
    // A ray without a direction finds nothing (and does not divide by it).
    bvh.for_each_on_ray([0.5, 0.5, 0.5], [0.0; 3], (0.0, 9.0), |_| hits += 1);
    assert_eq!(hits, 0);
    // The Gaussian ends at its radius; a radius of 0 has none.
    assert_eq!(fluidcast_rbf::rbf(0.2 * 1.0001, 0.2, 1.0), 0.0);
    assert!(fluidcast_rbf::rbf(0.2, 0.2, 1.0) > 0.0);
    assert_eq!(fluidcast_rbf::rbf(0.0, 0.0, 1.0), 0.0);
    // Bad input: lengths, negative or infinite radii.
    assert!(matches!(
        ClusterBvh::build(&c, &[0.1], 1),
        Err(RbfError::Length {
            got: 1,
            expected: 2,
            ..
        })
    ));
    for bad in [-0.1f32, f32::INFINITY] {
        assert!(matches!(
            ClusterBvh::build(&c, &[0.1, bad], 1),
            Err(RbfError::Radius { index: 1, .. })
        ));
    }
}

#[test]
fn attribute_maps_interpolate_between_their_points_and_clamp_beyond() {
    let m = AttributeMap::parse("0,1,1,0.5").unwrap();
    for (t, want) in [
        (-1.0, 1.0),
        (0.0, 1.0),
        (0.5, 0.75),
        (0.8, 0.6),
        (1.0, 0.5),
        (2.0, 0.5),
    ] {
        assert!(
            (m.eval(t) - want).abs() < 1e-12,
            "{t}: {} vs {want}",
            m.eval(t)
        );
    }
    // Unsorted points are sorted; a repeated position is a step.
    let step = AttributeMap::parse("1,0,0,1,0.5,1,0.5,0").unwrap();
    assert_eq!(step.eval(0.25), 1.0);
    assert_eq!(step.eval(0.75), 0.0);
    let three = AttributeMap::parse("0.2,2,0.6,4,1,0").unwrap();
    assert!((three.eval(0.4) - 3.0).abs() < 1e-12 && (three.eval(0.8) - 2.0).abs() < 1e-12);
    assert_eq!(three.eval(0.1), 2.0);
    assert_eq!(AttributeMap::constant(0.3).eval(0.9), 0.3);
    assert_eq!(Colouring::Pre.name(), "pre");
    assert_eq!(
        Colouring::ALL.map(Colouring::name),
        ["post", "pre", "density"],
        "the GPU's constants are named after these"
    );
}

/// `RbfField::from_sph` holds the SPH field: its sums equal fluidcast-sph's own (Σ V A W,
/// Σ V W; Σ m W) at random points.
#[test]
fn sph_fields_sum_as_the_sph_crate_does() {
    use fluidcast_sph::{FieldKind, Kernel};
    let p = cloud(2000, 61, (0.08, 0.08));
    let grid = p.neighbour_grid();
    for kernel in [Kernel::CubicSpline, Kernel::WendlandC2] {
        for kind in [FieldKind::Csph, FieldKind::Density] {
            let field = RbfField::from_sph(&p, kernel, kind, 8).unwrap();
            assert_eq!(field.profile(), fluidcast_rbf::Profile::Sph(kernel, kind));
            let mut inside = 0;
            for x in points(200, 67) {
                let (ours, theirs) = (field.sample(x), p.sample(&grid, kernel, x));
                let (a, b) = match kind {
                    FieldKind::Density => (ours.density, theirs.density),
                    _ => (ours.weighted[0], theirs.weighted),
                };
                assert!(
                    (a - b).abs() <= 1e-9 * b.abs().max(1.0),
                    "{kernel} {kind:?}: {a} vs {b}"
                );
                if kind == FieldKind::Csph {
                    assert!(
                        (ours.density - theirs.shepard).abs() <= 1e-9 * theirs.shepard.max(1.0)
                    );
                }
                inside += usize::from(b != 0.0);
            }
            assert!(inside > 50, "{inside}");
        }
    }
}

#[test]
fn field_statistics_and_options() {
    let tf = tf(0.0, 1.0);
    let mut p = pair(0.0, 1.0);
    p.radii = vec![0.1, 0.3];
    // Five visible radii (median 0.2) and two hidden ones, which do not count.
    for (k, r) in [0.2f32, 0.05, 0.4, 0.0, 0.0].into_iter().enumerate() {
        p.positions.push([1.0, 1.0, k as f32]);
        p.radii.push(r);
        p.volumes.push(1.0);
        p.masses.push(1.0);
        p.values.push(0.5);
    }
    let field = RbfField::build(&p, &tf, &RbfOptions::default()).unwrap();
    assert_eq!(field.median_radius(), f64::from(0.2f32));
    assert_eq!(
        field.memory_bytes(),
        field.bvh().memory_bytes() + 7 * (4 + 12 + 4 + 4),
        "the tree, and per particle weight, theta, base radius and map position"
    );
    // No particle: no attribute (not NaN).
    let empty = RbfField::build(&Particles::default(), &tf, &RbfOptions::default()).unwrap();
    assert_eq!(empty.sample([0.0; 3]).attribute(), None);
    assert_eq!(empty.median_radius(), 0.0);
    // The global radius must be positive and finite.
    for bad in [0.0, -1.0, f64::INFINITY, f64::NAN] {
        let o = RbfOptions {
            radius: Some(bad),
            ..Default::default()
        };
        assert!(
            matches!(RbfField::build(&p, &tf, &o), Err(RbfError::GlobalRadius(_))),
            "{bad}"
        );
    }
    // One bit a side: the curve is the Gray code through the cube's corners, from the origin
    // (key = x·4 + (x⊕y)·2 + (x⊕y⊕z), inverted here cell by cell).
    let gray = [
        [0, 0, 0],
        [0, 0, 1],
        [0, 1, 1],
        [0, 1, 0],
        [1, 1, 0],
        [1, 1, 1],
        [1, 0, 1],
        [1, 0, 0],
    ];
    for (k, c) in gray.iter().enumerate() {
        assert_eq!(fluidcast_rbf::hilbert_key(*c, 1), k as u64, "{c:?}");
    }
    assert_eq!(
        fluidcast_rbf::hilbert_key([0; 3], 16),
        0,
        "the curve starts at the origin"
    );
    // Hilbert keys ignore bits above the lattice's.
    for x in [[1u32, 2, 3], [7, 0, 5]] {
        let high = x.map(|c| c + (1 << 3));
        assert_eq!(
            fluidcast_rbf::hilbert_key(high, 3),
            fluidcast_rbf::hilbert_key(x, 3)
        );
    }
}
