//! A bounding volume hierarchy over Hilbert-ordered clusters of particle spheres, for range
//! queries (Morrical et al. 2023, Sec. 3.1.3 and 3.2).
//!
//! The paper hands particle boxes to the GPU's ray-tracing tree builder; here the tree is
//! built in software, the way its Sec. 3.2.3 clusters particles: sort them along a Hilbert
//! curve, cut the sorted list into clusters of `leaf_size` consecutive particles, and box
//! each cluster. Because the curve keeps neighbours together, a complete binary tree over
//! the clusters in curve order (node k's children are 2k and 2k + 1) is a good hierarchy,
//! and it needs no split search: building is a sort and one bottom-up pass of box unions,
//! and a change of radii alone (the radius map) only redoes that pass ([`ClusterBvh::refit`]).

use rayon::prelude::*;

use crate::hilbert::hilbert_key;
use crate::RbfError;

/// Largest number of particles per cluster (leaf).
pub const MAX_LEAF_SIZE: usize = 64;

/// Bits per axis of the lattice the Hilbert sort quantises centres to (65,536 cells a side:
/// finer than any ordering needs).
const SORT_BITS: u32 = 16;

/// An axis-aligned box (world units); empty when `lo > hi` (the box of no particle).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    /// Lowest corner.
    pub lo: [f32; 3],
    /// Highest corner.
    pub hi: [f32; 3],
}

impl Aabb {
    /// The box of nothing (lo > hi): the identity of a union.
    pub const EMPTY: Aabb = Aabb {
        lo: [f32::INFINITY; 3],
        hi: [f32::NEG_INFINITY; 3],
    };

    /// The box of a sphere, rounded outward so that it holds every point of the sphere
    /// computed in double precision.
    fn of_sphere(s: [f32; 4]) -> Aabb {
        let r = f64::from(s[3]);
        Aabb {
            lo: [0, 1, 2].map(|a| down(f64::from(s[a]) - r)),
            hi: [0, 1, 2].map(|a| up(f64::from(s[a]) + r)),
        }
    }

    fn union(self, o: Aabb) -> Aabb {
        let mut b = self;
        for a in 0..3 {
            b.lo[a] = b.lo[a].min(o.lo[a]);
            b.hi[a] = b.hi[a].max(o.hi[a]);
        }
        b
    }

    fn is_empty(&self) -> bool {
        self.lo[0] > self.hi[0]
    }

    /// Whether the box lies wholly on the negative side of plane `n·x + d = 0`.
    fn outside(&self, p: &[f64; 4]) -> bool {
        let far: f64 = (0..3)
            .map(|a| p[a] * f64::from(if p[a] >= 0.0 { self.hi[a] } else { self.lo[a] }))
            .sum();
        far + p[3] < 0.0
    }

    fn contains(&self, x: [f64; 3]) -> bool {
        (0..3).all(|a| f64::from(self.lo[a]) <= x[a] && x[a] <= f64::from(self.hi[a]))
    }

    /// The parameter interval `[t0, t1]` (within `range`) where the line `o + t·inv⁻¹`
    /// crosses the box (slab test with the direction's reciprocal), if any.
    fn ray_interval(&self, o: [f64; 3], inv: [f64; 3], range: (f64, f64)) -> Option<(f64, f64)> {
        let (mut t0, mut t1) = range;
        for a in 0..3 {
            let (lo, hi) = (f64::from(self.lo[a]), f64::from(self.hi[a]));
            if inv[a].is_infinite() {
                // Parallel to the slab: inside it or never.
                if o[a] < lo || o[a] > hi {
                    return None;
                }
                continue;
            }
            let (a0, a1) = ((lo - o[a]) * inv[a], (hi - o[a]) * inv[a]);
            t0 = t0.max(a0.min(a1));
            t1 = t1.min(a0.max(a1));
        }
        (t0 <= t1).then_some((t0, t1))
    }
}

/// The largest f32 at or below `x`.
fn down(x: f64) -> f32 {
    let f = x as f32;
    if f64::from(f) > x {
        f.next_down()
    } else {
        f
    }
}

/// The smallest f32 at or above `x`.
fn up(x: f64) -> f32 {
    let f = x as f32;
    if f64::from(f) < x {
        f.next_up()
    } else {
        f
    }
}

/// Where a ray `o + t·d` crosses a particle's sphere: the particle's slot, the ray
/// parameters of entry and exit (clipped to the query's range) and of the closest approach
/// to the centre, and the squared distance there (world units²).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RayHit {
    /// The particle's slot in the tree.
    pub slot: u32,
    /// Ray parameter of entry.
    pub t_in: f64,
    /// Ray parameter of exit.
    pub t_out: f64,
    /// Ray parameter of the closest approach.
    pub closest: f64,
    /// Squared distance from the centre at the closest approach.
    pub miss2: f64,
}

/// Particle spheres in Hilbert order, clustered, under a complete binary tree of boxes.
///
/// A *slot* is a particle's place in Hilbert order; [`ClusterBvh::particle`] gives the
/// caller's index of the particle in a slot. Radii are world units; a particle of radius 0
/// is hidden (in no box and no query), as the paper's radius map hides particles.
#[derive(Debug, Clone)]
pub struct ClusterBvh {
    /// Per slot, the caller's particle index.
    order: Vec<u32>,
    /// Per slot: centre x, y, z and radius (world units).
    spheres: Vec<[f32; 4]>,
    leaf_size: usize,
    /// Heap-indexed boxes: node 1 is the root, node k's children are 2k and 2k + 1, and the
    /// clusters are the leaves from `first_leaf` on (those past the last cluster are empty).
    /// Entry 0 is unused.
    boxes: Vec<Aabb>,
    first_leaf: usize,
}

impl ClusterBvh {
    /// Sorts the particles (centres and radii, world units) along a Hilbert curve and
    /// builds the tree over clusters of `leaf_size` of them.
    pub fn build(
        centres: &[[f32; 3]],
        radii: &[f32],
        leaf_size: usize,
    ) -> Result<ClusterBvh, RbfError> {
        if !(1..=MAX_LEAF_SIZE).contains(&leaf_size) {
            return Err(RbfError::LeafSize(leaf_size));
        }
        check_lengths("radii", radii.len(), centres.len())?;
        let n = u32::try_from(centres.len()).map_err(|_| RbfError::TooMany(centres.len()))?;
        if let Some(index) = centres
            .iter()
            .position(|c| !c.iter().all(|v| v.is_finite()))
        {
            return Err(RbfError::Centre {
                index,
                centre: centres[index],
            });
        }
        check_radii(radii)?;
        let order = hilbert_order(centres, n);
        let spheres = order
            .par_iter()
            .map(|&i| {
                let c = centres[i as usize];
                [c[0], c[1], c[2], radii[i as usize]]
            })
            .collect();
        let clusters = centres.len().div_ceil(leaf_size);
        let first_leaf = clusters.next_power_of_two();
        let mut bvh = ClusterBvh {
            order,
            spheres,
            leaf_size,
            boxes: vec![Aabb::EMPTY; 2 * first_leaf],
            first_leaf,
        };
        bvh.fit_boxes();
        Ok(bvh)
    }

    /// New radii (per caller index, world units) with the tree's topology kept: boxes are
    /// recomputed bottom up (the paper's refit when the radius map changes).
    pub fn refit(&mut self, radii: &[f32]) -> Result<(), RbfError> {
        check_lengths("radii", radii.len(), self.order.len())?;
        check_radii(radii)?;
        self.spheres
            .par_iter_mut()
            .zip(self.order.par_iter())
            .for_each(|(s, &i)| s[3] = radii[i as usize]);
        self.fit_boxes();
        Ok(())
    }

    /// Leaf boxes from the spheres, then each level's unions, bottom up.
    fn fit_boxes(&mut self) {
        let (leaf_size, spheres) = (self.leaf_size, &self.spheres);
        let (upper, leaves) = self.boxes.split_at_mut(self.first_leaf);
        leaves.par_iter_mut().enumerate().for_each(|(c, b)| {
            let start = (c * leaf_size).min(spheres.len());
            let end = (start + leaf_size).min(spheres.len());
            *b = spheres[start..end]
                .iter()
                .filter(|s| s[3] > 0.0)
                .fold(Aabb::EMPTY, |b, &s| b.union(Aabb::of_sphere(s)));
        });
        let mut children: &[Aabb] = leaves;
        let mut rest = upper;
        let mut level = self.first_leaf / 2;
        while level >= 1 {
            let (above, this) = rest.split_at_mut(level);
            this.par_iter_mut()
                .enumerate()
                .for_each(|(k, b)| *b = children[2 * k].union(children[2 * k + 1]));
            children = this;
            rest = above;
            level /= 2;
        }
    }

    /// Number of particles (hidden ones included).
    pub fn len(&self) -> usize {
        self.order.len()
    }

    /// Whether the tree holds no particle.
    pub fn is_empty(&self) -> bool {
        self.order.is_empty()
    }

    /// The caller's index of the particle in `slot`.
    #[inline]
    pub fn particle(&self, slot: u32) -> u32 {
        self.order[slot as usize]
    }

    /// Per slot, the caller's particle index (the Hilbert order).
    pub fn order(&self) -> &[u32] {
        &self.order
    }

    /// Centre and radius (world units) of the particle in `slot`.
    #[inline]
    pub fn sphere(&self, slot: u32) -> [f32; 4] {
        self.spheres[slot as usize]
    }

    /// Clusters (leaves holding particles) and tree nodes.
    pub fn clusters(&self) -> usize {
        self.order.len().div_ceil(self.leaf_size)
    }

    /// Particles per leaf (cluster).
    pub fn leaf_size(&self) -> usize {
        self.leaf_size
    }

    /// The boxes, heap-indexed (entry 0 unused, node k's children 2k and 2k + 1), for a
    /// traversal elsewhere (the GPU's).
    pub fn boxes(&self) -> &[Aabb] {
        &self.boxes
    }

    /// The node index of the first leaf (cluster 0); leaves hold `leaf_size` slots each.
    pub fn first_leaf(&self) -> usize {
        self.first_leaf
    }

    /// Per slot, centre and radius (world units).
    pub fn spheres(&self) -> &[[f32; 4]] {
        &self.spheres
    }

    /// The box of every visible particle (empty when none is).
    pub fn bounds(&self) -> Aabb {
        self.boxes[1]
    }

    /// Bytes the structure holds: the order (4 a particle), the sorted spheres (16) and the
    /// boxes (24 a node).
    pub fn memory_bytes(&self) -> usize {
        self.order.len() * 4 + self.spheres.len() * 16 + self.boxes.len() * 24
    }

    /// The particles of cluster `c`, as a slot range.
    fn cluster_slots(&self, c: usize) -> std::ops::Range<u32> {
        let start = (c * self.leaf_size).min(self.spheres.len());
        let end = (start + self.leaf_size).min(self.spheres.len());
        start as u32..end as u32
    }

    /// Depth-first walk: descends into every node whose box `enter` accepts and hands each
    /// accepted leaf's slots to `leaf`.
    fn walk(&self, enter: impl Fn(&Aabb) -> bool, mut leaf: impl FnMut(std::ops::Range<u32>)) {
        let mut stack = [0usize; 64];
        let mut top = 0;
        let mut node = 1;
        loop {
            let b = &self.boxes[node];
            if !b.is_empty() && enter(b) {
                if node >= self.first_leaf {
                    leaf(self.cluster_slots(node - self.first_leaf));
                } else {
                    stack[top] = 2 * node + 1;
                    top += 1;
                    node *= 2;
                    continue;
                }
            }
            if top == 0 {
                return;
            }
            top -= 1;
            node = stack[top];
        }
    }

    /// Calls `f(slot)` for every visible particle whose sphere holds `x` (distance to the
    /// centre at most the radius, in double precision): a radius range query.
    pub fn for_each_within(&self, x: [f64; 3], mut f: impl FnMut(u32)) {
        self.walk(
            |b| b.contains(x),
            |slots| {
                for slot in slots.filter(|&s| holds(self.spheres[s as usize], x)) {
                    f(slot);
                }
            },
        );
    }

    /// Calls `f(slot)` for every visible particle whose sphere reaches the convex region
    /// where `n·x + d >= 0` for every plane `[n, d]` (`|n| = 1`) of `planes`, and possibly for
    /// some that only come close to it (a sphere is kept unless it lies wholly outside one
    /// plane): the candidates of the rays of a frustum.
    pub fn for_each_in_planes(&self, planes: &[[f64; 4]], mut f: impl FnMut(u32)) {
        let reaches = |s: [f32; 4]| {
            let r = f64::from(s[3]);
            r > 0.0
                && planes.iter().all(|p| {
                    let d: f64 = (0..3).map(|a| p[a] * f64::from(s[a])).sum();
                    d + p[3] >= -r
                })
        };
        self.walk(
            |b| !planes.iter().any(|p| b.outside(p)),
            |slots| {
                for slot in slots.filter(|&s| reaches(self.spheres[s as usize])) {
                    f(slot);
                }
            },
        );
    }

    /// Calls `f` for every visible particle whose sphere the ray `origin + t·dir` crosses
    /// for some `t` in `range`, with the crossing clipped to `range`.
    pub fn for_each_on_ray(
        &self,
        origin: [f64; 3],
        dir: [f64; 3],
        range: (f64, f64),
        mut f: impl FnMut(RayHit),
    ) {
        let inv = dir.map(|d| 1.0 / d);
        let dd: f64 = dir.iter().map(|d| d * d).sum();
        if !(dd > 0.0 && dd.is_finite()) {
            return;
        }
        self.walk(
            |b| b.ray_interval(origin, inv, range).is_some(),
            |slots| {
                for slot in slots {
                    let s = self.spheres[slot as usize];
                    if let Some(hit) = sphere_crossing(s, slot, (origin, dir, dd), range) {
                        f(hit);
                    }
                }
            },
        );
    }
}

/// Whether visible sphere `s` holds point `x` (double precision).
#[inline]
pub fn holds(s: [f32; 4], x: [f64; 3]) -> bool {
    let r = f64::from(s[3]);
    let d2: f64 = (0..3).map(|a| (x[a] - f64::from(s[a])).powi(2)).sum();
    r > 0.0 && d2 <= r * r
}

/// Where the line `o + t·d` (`dd = d·d`) crosses visible sphere `s` (in `slot`), clipped to
/// `range`; `None` if it misses it there. From the closest approach, which keeps precision
/// when the sphere is small and far from the origin.
#[inline]
pub fn sphere_crossing(
    s: [f32; 4],
    slot: u32,
    (o, d, dd): ([f64; 3], [f64; 3], f64),
    range: (f64, f64),
) -> Option<RayHit> {
    let r = f64::from(s[3]);
    if r <= 0.0 {
        return None;
    }
    let oc = [
        f64::from(s[0]) - o[0],
        f64::from(s[1]) - o[1],
        f64::from(s[2]) - o[2],
    ];
    let tc = (oc[0] * d[0] + oc[1] * d[1] + oc[2] * d[2]) / dd;
    let miss2: f64 = (0..3).map(|a| (tc * d[a] - oc[a]).powi(2)).sum();
    if miss2 > r * r {
        return None;
    }
    let half = ((r * r - miss2) / dd).sqrt();
    let (t_in, t_out) = ((tc - half).max(range.0), (tc + half).min(range.1));
    (t_in <= t_out).then_some(RayHit {
        slot,
        t_in,
        t_out,
        closest: tc,
        miss2,
    })
}

fn check_lengths(what: &'static str, got: usize, expected: usize) -> Result<(), RbfError> {
    if got == expected {
        Ok(())
    } else {
        Err(RbfError::Length {
            what,
            got,
            expected,
        })
    }
}

fn check_radii(radii: &[f32]) -> Result<(), RbfError> {
    match radii.iter().position(|r| !(r.is_finite() && *r >= 0.0)) {
        Some(index) => Err(RbfError::Radius {
            index,
            radius: radii[index],
        }),
        None => Ok(()),
    }
}

/// Particle indices sorted by the Hilbert key of their centres on a lattice over their
/// bounds (ties by index, so the order is deterministic).
fn hilbert_order(centres: &[[f32; 3]], n: u32) -> Vec<u32> {
    let (lo, hi) = centres.iter().fold(
        ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]),
        |(mut lo, mut hi), c| {
            for a in 0..3 {
                lo[a] = lo[a].min(f64::from(c[a]));
                hi[a] = hi[a].max(f64::from(c[a]));
            }
            (lo, hi)
        },
    );
    let cells = f64::from((1u32 << SORT_BITS) - 1);
    let scale = (0..3)
        .map(|a| hi[a] - lo[a])
        .fold(0.0, f64::max)
        .max(f64::MIN_POSITIVE);
    let mut keyed: Vec<(u64, u32)> = (0..n)
        .into_par_iter()
        .map(|i| {
            let c = centres[i as usize];
            let q = [0, 1, 2].map(|a| ((f64::from(c[a]) - lo[a]) / scale * cells) as u32);
            (hilbert_key(q, SORT_BITS), i)
        })
        .collect();
    keyed.par_sort_unstable();
    keyed.into_iter().map(|(_, i)| i).collect()
}
