//! The particle hierarchy and its cuts, against sums taken here over each node's full-detail
//! descendants, and rendered against full detail.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly

use fluidcast_lod::{LodError, LodHierarchy};
use fluidcast_sph::Particles;
use fluidcast_testkit::{cloud, rng};
use fluidcast_view::{Camera, ViewFrame};
use glam::DVec3;

/// A jittered `n`³ lattice of spacing `s` at the origin (support 2 spacings, volume one
/// cell, mass 1000 cells), valued by a smooth function; jitter 0 is a perfect lattice.
fn block(n: usize, s: f32, jitter: f32) -> Particles {
    let mut rnd = rng(7);
    let mut p = Particles::default();
    for i in 0..n {
        for j in 0..n {
            for k in 0..n {
                let mut x = [i, j, k].map(|c| c as f32 * s);
                for c in &mut x {
                    *c += jitter * s * (rnd() - 0.5);
                }
                p.positions.push(x);
                p.radii.push(2.0 * s);
                p.volumes.push(s * s * s);
                p.masses.push(1000.0 * s * s * s);
                p.values.push((3.0 * x[0]).sin() + x[1] * x[2]);
            }
        }
    }
    p
}

fn pos(p: &Particles, i: usize) -> DVec3 {
    DVec3::from(p.positions[i].map(f64::from))
}

/// The full-detail particles under node `i` of `level`.
fn descendants(h: &LodHierarchy, level: usize, i: usize) -> Vec<usize> {
    match h.children(level, i) {
        None => vec![i],
        Some(r) => r.flat_map(|c| descendants(h, level - 1, c)).collect(),
    }
}

/// `n` random particles in the unit cube (`fluidcast_testkit::cloud`), their volumes scaled
/// to fill it (mean 1/n), so that their size is their spacing.
fn filled_cloud(n: usize, seed: u32, radius: (f32, f32)) -> Particles {
    let mut p = cloud(n, seed, radius);
    let scale = 1.0 / (n as f32 * 0.002);
    for v in &mut p.volumes {
        *v *= scale;
    }
    p
}

fn close(a: f64, b: f64, rel: f64) -> bool {
    (a - b).abs() <= rel * a.abs().max(b.abs()).max(1e-30)
}

#[test]
fn merges_keep_volume_mass_and_weighted_mean_and_cover_every_descendant() {
    let mut p = filled_cloud(4000, 11, (0.08, 0.04));
    // Spread volumes so that volume weighting differs from a plain mean.
    for (i, v) in p.volumes.iter_mut().enumerate() {
        *v *= 1.0 + (i % 7) as f32;
    }
    let h = LodHierarchy::build(p).unwrap();
    assert!(h.levels() >= 3, "{} levels", h.levels());
    let full = h.full_detail().clone();
    let mut merged = 0;
    for l in 1..h.levels() {
        for i in 0..h.level_len(l) {
            let q = h.node(l, i).unwrap();
            let d = descendants(&h, l, i);
            let v: f64 = d.iter().map(|&j| f64::from(full.volumes[j])).sum();
            let m: f64 = d.iter().map(|&j| f64::from(full.masses[j])).sum();
            let va: f64 = d
                .iter()
                .map(|&j| f64::from(full.volumes[j]) * f64::from(full.values[j]))
                .sum();
            assert!(close(f64::from(q.volume), v, 1e-5), "volume");
            assert!(close(f64::from(q.mass), m, 1e-5), "mass");
            assert!(
                (f64::from(q.value) - va / v).abs() < 1e-5,
                "value {} vs {}",
                q.value,
                va / v
            );
            let c = DVec3::from(q.position.map(f64::from));
            for &j in &d {
                let reach = pos(&full, j).distance(c) + f64::from(full.radii[j]);
                assert!(
                    reach <= f64::from(q.radius),
                    "level {l} node {i}: a descendant's support reaches {reach} > {}",
                    q.radius
                );
            }
            assert_eq!(h.made_at(l, i) == Some(0), d.len() == 1);
            if d.len() > 1 {
                merged += 1;
                // The smallest cover: the farthest child's support touches the boundary.
                let far = h
                    .children(l, i)
                    .unwrap()
                    .map(|j| {
                        let b = h.node(l - 1, j).unwrap();
                        DVec3::from(b.position.map(f64::from)).distance(c) + f64::from(b.radius)
                    })
                    .fold(0.0, f64::max);
                assert!(f64::from(q.radius) <= far * (1.0 + 1e-6));
            }
        }
    }
    assert!(merged > 100, "{merged} merged nodes");
}

fn sums(p: &Particles) -> [f64; 3] {
    let mut s = [0.0; 3];
    for i in 0..p.len() {
        s[0] += f64::from(p.volumes[i]);
        s[1] += f64::from(p.masses[i]);
        s[2] += f64::from(p.volumes[i]) * f64::from(p.values[i]);
    }
    s
}

fn frame(azimuth: f64, parallel: bool, zoom: f64, size: u32) -> ViewFrame {
    let mut cam = Camera::default();
    cam.reset([-0.5; 3], [0.5; 3]);
    cam.azimuth(azimuth);
    cam.elevation(20.0);
    cam.parallel_projection = parallel;
    cam.zoom(zoom);
    cam.frame(size, size).unwrap()
}

#[test]
fn every_cut_stands_for_each_particle_once() {
    let p = filled_cloud(6000, 3, (0.08, 0.04));
    let h = LodHierarchy::build(p).unwrap();
    let want = sums(h.full_detail());
    let mut counts = Vec::new();
    for (az, parallel, zoom) in [(0.0, false, 1.0), (70.0, true, 1.0), (30.0, false, 4.0)] {
        let f = frame(az, parallel, zoom, 200);
        for tol in [0.0, 0.5, 2.0, 8.0, 1e9] {
            let c = h.cut(&f, tol).unwrap();
            assert_eq!(c.per_level.iter().sum::<usize>(), c.particles.len());
            let got = sums(&c.particles);
            for k in 0..3 {
                assert!(
                    close(got[k], want[k], 1e-5),
                    "{tol} px: sum {k} {got:?} vs {want:?}"
                );
            }
            counts.push((tol, c.particles.len()));
        }
    }
    // Coarser tolerances take fewer particles, down to the top level's.
    for w in counts.windows(2) {
        if w[1].0 > w[0].0 {
            assert!(w[1].1 <= w[0].1, "{counts:?}");
        }
    }
    assert!(
        counts.iter().any(|&(t, n)| t == 1e9 && n < 6000 / 2),
        "{counts:?}"
    );
    // Zoomed in, what lies outside the view is taken coarse even at 0 pixels.
    assert!(counts[10].1 < 6000, "{counts:?}");
}

#[test]
fn a_cut_at_zero_pixels_is_full_detail() {
    let h = LodHierarchy::build(filled_cloud(3000, 5, (0.08, 0.04))).unwrap();
    let c = h.cut(&frame(10.0, false, 1.0, 300), 0.0).unwrap();
    let f = h.full_detail();
    assert_eq!(c.particles.positions, f.positions);
    assert_eq!(c.particles.radii, f.radii);
    assert_eq!(c.particles.volumes, f.volumes);
    assert_eq!(c.particles.values, f.values);
    assert_eq!(c.per_level[0], f.len());
    assert!(c.is_full_detail());
    assert!(!h
        .cut(&frame(10.0, false, 1.0, 300), 1e9)
        .unwrap()
        .is_full_detail());
}

#[test]
fn a_parallel_view_takes_the_level_whose_cells_fit_the_tolerance() {
    // A perfect lattice: every level-1 block interior to the particles merges 8 particles.
    let n = 24;
    let h = LodHierarchy::build(block(n, 0.01, 0.0)).unwrap();
    assert!(h.levels() >= 3);
    let mut cam = Camera::default();
    cam.reset([0.0; 3], [0.24; 3]);
    cam.parallel_projection = true;
    let f = cam.frame(256, 256).unwrap();
    let px = f.pixel_size_at(1.0);
    // Level 1's cells fit 1.01 of their own size, level 2's do not.
    let tol = 1.01 * h.cell_size(1) / px;
    let c = h.cut(&f, tol).unwrap();
    assert!(c.per_level[1] > 0, "{:?}", c.per_level);
    assert!(
        c.per_level[2..].iter().all(|&k| k == 0),
        "{:?}",
        c.per_level
    );
    // Just below, nothing is merged.
    let c = h.cut(&f, 0.99 * h.cell_size(1) / px).unwrap();
    assert_eq!(c.per_level[0], n * n * n, "{:?}", c.per_level);
    let c = h.cut(&f, 1.01 * h.cell_size(2) / px).unwrap();
    assert!(c.per_level[2] > 0, "{:?}", c.per_level);
}

#[test]
fn the_edge_of_the_particles_does_not_move() {
    let full = block(20, 0.01, 0.3);
    let bounds = full.support_bounds();
    let h = LodHierarchy::build(full).unwrap();
    let c = h.cut(&frame(0.0, true, 1.0, 64), 1e9).unwrap();
    assert!(
        c.particles.len() < 20 * 20 * 20 * 3 / 5,
        "{}",
        c.particles.len()
    );
    let got = c.particles.support_bounds();
    for k in 0..3 {
        assert!(
            (got.0[k] - bounds.0[k]).abs() < 1e-6 && (got.1[k] - bounds.1[k]).abs() < 1e-6,
            "axis {k}: {got:?} vs {bounds:?}"
        );
    }
}

#[test]
fn large_and_lone_particles_are_copied_up_unchanged() {
    let mut p = block(12, 0.01, 0.2);
    // A droplet far away and a coarse particle of another phase inside the block.
    let far = [3.0f32, 0.0, 0.0];
    p.positions.push(far);
    p.radii.push(0.02);
    p.volumes.push(1e-6);
    p.masses.push(1e-3);
    p.values.push(42.0);
    p.positions.push([0.06; 3]);
    p.radii.push(0.2);
    p.volumes.push(1e-3);
    p.masses.push(1.0);
    p.values.push(-7.0);
    let h = LodHierarchy::build(p).unwrap();
    let c = h.cut(&frame(0.0, true, 1.0, 64), 1e9).unwrap();
    for (x, v, r) in [(far, 42.0, 0.02), ([0.06; 3], -7.0, 0.2)] {
        let i = c
            .particles
            .positions
            .iter()
            .position(|&q| q == x)
            .unwrap_or_else(|| panic!("{x:?} not in the cut"));
        assert_eq!((c.particles.values[i], c.particles.radii[i]), (v, r));
    }
}

#[test]
fn far_outliers_widen_the_grid_instead_of_failing() {
    let mut p = filled_cloud(2000, 9, (0.08, 0.04));
    p.positions[17] = [1e7, -1e7, 3.0];
    let want = sums(&p);
    let h = LodHierarchy::build(p).unwrap();
    let c = h.cut(&frame(0.0, false, 1.0, 100), 4.0).unwrap();
    let got = sums(&c.particles);
    for k in 0..3 {
        assert!(close(got[k], want[k], 1e-5));
    }
    // Level 0's cells widened to span 2e7 in 2^21 cells, not the median size.
    assert!(h.cell_size(0) > 1.0, "{}", h.cell_size(0));
}

#[test]
fn bad_input_is_refused_with_the_reason() {
    assert_eq!(
        LodHierarchy::build(Particles::default()).unwrap_err(),
        LodError::Empty
    );
    let mut p = cloud(10, 1, (0.1, 0.0));
    p.positions[3][1] = f32::NAN;
    assert!(matches!(
        LodHierarchy::build(p).unwrap_err(),
        LodError::NotFinite {
            index: 3,
            what: "position",
            ..
        }
    ));
    let mut p = cloud(10, 1, (0.1, 0.0));
    p.radii[4] = f32::INFINITY;
    let e = LodHierarchy::build(p).unwrap_err();
    assert!(e.to_string().contains("particle 4: support radius"), "{e}");
    let h = LodHierarchy::build(cloud(10, 1, (0.1, 0.0))).unwrap();
    let f = frame(0.0, false, 1.0, 32);
    for t in [-1.0, f64::NAN, f64::INFINITY] {
        assert!(matches!(h.cut(&f, t), Err(LodError::BadTolerance(_))));
    }
}

/// The lower corner of the particles' bounds (as the hierarchy's grid takes it).
fn lower_corner(p: &Particles) -> [f64; 3] {
    let mut lo = [f64::INFINITY; 3];
    for x in &p.positions {
        for k in 0..3 {
            lo[k] = lo[k].min(f64::from(x[k]));
        }
    }
    lo
}

/// Level 0's cell of each particle, as integer coordinates.
fn cells0(p: &Particles, lo: [f64; 3], c0: f64) -> Vec<[u64; 3]> {
    p.positions
        .iter()
        .map(|x| [0, 1, 2].map(|k| ((f64::from(x[k]) - lo[k]) / c0).floor().max(0.0) as u64))
        .collect()
}

#[test]
fn merged_nodes_are_the_interior_blocks_of_their_level() {
    let full = block(16, 0.01, 0.4);
    let h = LodHierarchy::build(full).unwrap();
    let full = h.full_detail().clone();
    // Level 0's cells: the median particle size (every volume is one cell here).
    assert_eq!(h.cell_size(0), f64::from(0.01f32 * 0.01 * 0.01).cbrt());
    let lo = lower_corner(&full);
    let c0 = h.cell_size(0);
    let cells = cells0(&full, lo, c0);
    let mut merged = 0;
    for l in 1..h.levels() {
        let k = (h.cell_size(l) / c0).log2().round() as u32;
        assert_eq!(h.cell_size(l), c0 * f64::powi(2.0, k as i32));
        let occupied: std::collections::HashSet<[u64; 3]> =
            cells.iter().map(|c| c.map(|v| v >> k)).collect();
        for i in 0..h.level_len(l) {
            if h.made_at(l, i) != Some(l) {
                continue;
            }
            merged += 1;
            let d = descendants(&h, l, i);
            let cell = cells[d[0]].map(|v| v >> k);
            for &j in &d {
                assert_eq!(
                    cells[j].map(|v| v >> k),
                    cell,
                    "level {l} node {i}: two cells"
                );
            }
            for axis in 0..3 {
                for step in [-1i64, 1] {
                    let mut n = cell;
                    let v = n[axis] as i64 + step;
                    assert!(v >= 0, "level {l} node {i} merged at the grid's edge");
                    n[axis] = v as u64;
                    assert!(
                        occupied.contains(&n),
                        "level {l} node {i} merged at an edge"
                    );
                }
            }
        }
        assert_eq!(h.node(l, h.level_len(l)), None);
        assert_eq!(h.made_at(l, h.level_len(l)), None);
    }
    assert!(merged > 50, "{merged}");
}

#[test]
fn particles_without_volume_merge_to_plain_means_sized_by_their_radius() {
    let mut p = block(10, 0.01, 0.3);
    for v in &mut p.volumes {
        *v = 0.0;
    }
    let h = LodHierarchy::build(p).unwrap();
    // Size: half the support radius (2 spacings here).
    assert!((h.cell_size(0) - 0.01).abs() < 1e-9, "{}", h.cell_size(0));
    let mut checked = 0;
    for l in 1..h.levels() {
        for i in 0..h.level_len(l) {
            let c: Vec<_> = h
                .children(l, i)
                .unwrap()
                .map(|j| h.node(l - 1, j).unwrap())
                .collect();
            if c.len() < 2 {
                continue;
            }
            // No volume to weigh by: the children's plain means.
            let q = h.node(l, i).unwrap();
            let n = c.len() as f64;
            let a: f64 = c.iter().map(|b| f64::from(b.value)).sum::<f64>() / n;
            assert!((f64::from(q.value) - a).abs() < 1e-5, "{} vs {a}", q.value);
            for k in 0..3 {
                let x: f64 = c.iter().map(|b| f64::from(b.position[k])).sum::<f64>() / n;
                assert!((f64::from(q.position[k]) - x).abs() < 1e-6);
            }
            checked += 1;
        }
    }
    assert!(checked > 0);
}

#[test]
fn memory_counts_every_level() {
    let h = LodHierarchy::build(block(12, 0.01, 0.3)).unwrap();
    let n = h.full_detail().len();
    let mut want = 28 * n;
    for l in 1..h.levels() {
        let made_here = (0..h.level_len(l))
            .filter(|&i| h.made_at(l, i) == Some(l))
            .count();
        want += 13 * h.level_len(l) + 28 * made_here;
    }
    assert_eq!(h.memory_bytes(), want);
}

/// The cut written out here: top down, a node at level l >= 1 that is not a carried
/// full-detail particle is taken when it lies wholly outside the view or its level's cells fit
/// `tol` pixels at its nearest depth.
fn cut_here(h: &LodHierarchy, f: &ViewFrame, tol: f64) -> Vec<usize> {
    let mut per_level = vec![0; h.levels()];
    let mut stack: Vec<(usize, usize)> = (0..h.level_len(h.levels() - 1))
        .map(|i| (h.levels() - 1, i))
        .collect();
    while let Some((l, i)) = stack.pop() {
        let made = h.made_at(l, i).unwrap();
        let q = h.node(l, i).unwrap();
        let v = f.to_view(DVec3::from(q.position.map(f64::from)));
        let r = f64::from(q.radius);
        let (outside, fits) = match f.parallel {
            Some(s) => (
                v.x.abs() > s * f.aspect + r || v.y.abs() > s + r,
                h.cell_size(l) <= tol * 2.0 * s / f64::from(f.height),
            ),
            None => {
                let tx = f.tan_half * f.aspect;
                let ty = f.tan_half;
                let near = v.z - r;
                (
                    v.z < -r
                        || v.x.abs() - v.z * tx > r * (1.0 + tx * tx).sqrt()
                        || v.y.abs() - v.z * ty > r * (1.0 + ty * ty).sqrt(),
                    near > 0.0
                        && h.cell_size(l) <= tol * 2.0 * near * f.tan_half / f64::from(f.height),
                )
            }
        };
        if made == 0 || l == 0 || outside || fits {
            per_level[made] += 1;
        } else {
            stack.extend(h.children(l, i).unwrap().map(|c| (l - 1, c)));
        }
    }
    per_level
}

#[test]
fn perspective_cuts_judge_each_node_at_its_nearest_depth() {
    // A deep block seen end-on from close by: its near and far ends differ in pixel size.
    let mut p = block(14, 0.01, 0.3);
    for x in &mut p.positions {
        x[2] *= 6.0;
    }
    for v in &mut p.volumes {
        *v *= 6.0;
    }
    let h = LodHierarchy::build(p).unwrap();
    let mut cam = Camera {
        position: [0.065, 0.065, 1.2],
        focal_point: [0.065, 0.065, 0.0],
        ..Camera::default()
    };
    cam.view_angle = 40.0;
    let mut differ = false;
    for (size, tol) in [(40, 2.0), (40, 3.0), (60, 3.0), (30, 2.5)] {
        let f = cam.frame(size, size).unwrap();
        let want = cut_here(&h, &f, tol);
        let got = h.cut(&f, tol).unwrap().per_level;
        assert_eq!(got, want, "{size} px, {tol}");
        differ |= want[1..].iter().any(|&k| k > 0) && want[0] > h.level_len(0) / 10;
    }
    assert!(differ, "no view mixes levels");
    // Views that leave much of the block outside: off to one side, below, looking away,
    // and parallel views zoomed in; at a tolerance that merges nothing inside the view.
    let mut outside_merged = 0;
    for (pos, focal, parallel, scale) in [
        ([0.2, 0.065, 0.5], [0.3, 0.065, 0.0], false, 1.0),
        ([0.065, -0.1, 0.4], [0.065, -0.2, 0.0], false, 1.0),
        ([0.065, 0.065, 0.3], [0.065, 0.065, 1.0], false, 1.0),
        ([0.0, 0.0, 2.0], [0.0, 0.0, 0.0], true, 0.03),
        ([0.13, 0.05, 2.0], [0.13, 0.05, 0.0], true, 0.02),
    ] {
        let c = Camera {
            position: pos,
            focal_point: focal,
            parallel_projection: parallel,
            parallel_scale: scale,
            ..Camera::default()
        };
        for aspect in [(200, 100), (100, 200)] {
            let f = c.frame(aspect.0, aspect.1).unwrap();
            let want = cut_here(&h, &f, 0.0);
            assert_eq!(
                h.cut(&f, 0.0).unwrap().per_level,
                want,
                "{pos:?} {aspect:?}"
            );
            outside_merged += want[1..].iter().sum::<usize>();
        }
    }
    assert!(outside_merged > 100, "{outside_merged}");
}

#[test]
fn the_grid_starts_at_the_particles_lower_corner_and_uses_their_median_size() {
    let mut p = block(12, 0.01, 0.4);
    for (i, x) in p.positions.iter_mut().enumerate() {
        for c in x.iter_mut() {
            *c += 0.537;
        }
        p.volumes[i] *= 0.5 + (i % 5) as f32 * 0.3;
    }
    let mut sizes: Vec<f64> = p.volumes.iter().map(|&v| f64::from(v).cbrt()).collect();
    sizes.sort_by(f64::total_cmp);
    let median = sizes[sizes.len() / 2];
    let h = LodHierarchy::build(p).unwrap();
    assert_eq!(h.cell_size(0), median);
    let full = h.full_detail().clone();
    let lo = lower_corner(&full);
    let cells = cells0(&full, lo, median);
    let mut merged = 0;
    for l in 1..h.levels() {
        let k = (h.cell_size(l) / median).log2().round() as u32;
        for i in (0..h.level_len(l)).filter(|&i| h.made_at(l, i) == Some(l)) {
            let d = descendants(&h, l, i);
            let cell = cells[d[0]].map(|v| v >> k);
            assert!(d.iter().all(|&j| cells[j].map(|v| v >> k) == cell));
            merged += 1;
        }
    }
    assert!(merged > 10, "{merged}");
}
