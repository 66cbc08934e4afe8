//! Coverage geometry: whether each sub-bundle's cross-section at a sample depth lies inside
//! one particle's support, so that no ray's sample there can be empty.

use crate::analyse::Reacher;
use fluidcast_grid::{Bundle, ViewParticle, COVER_MARGIN};

/// Sub-bundles per side for the coverage test (2×2 rays each for D_xy = 8).
pub(crate) const COVER_SPLIT: u32 = 4;

/// Most sub-bundle columns (and rows) of the coverage test.
pub(crate) const SIDE: usize = COVER_SPLIT as usize;

/// A bundle's sub-bundles for the coverage test, a `cols × rows` grid (as
/// [`Bundle::split`] cuts it, row-major): the rays' x extremes per column and y extremes per
/// row ([`Bundle::x`], [`Bundle::y`]), which the parts of a column (row) share.
pub(crate) struct Parts {
    pub(crate) x: [[f64; 2]; SIDE],
    pub(crate) y: [[f64; 2]; SIDE],
    pub(crate) cols: usize,
    pub(crate) rows: usize,
    pub(crate) parallel: bool,
    /// Bit s set for each part.
    pub(crate) all: u64,
    /// Smallest squared half diagonal of a part (at unit depth for a perspective view).
    pub(crate) r2_min: f64,
}

impl Parts {
    /// From `parts` of [`Bundle::split`] with `COVER_SPLIT`: `cols` parts share the first
    /// row's y extremes.
    pub(crate) fn new(parts: &[Bundle]) -> Parts {
        let cols = parts
            .iter()
            .take_while(|b| parts.first().is_some_and(|f| b.y == f.y))
            .count()
            .clamp(1, SIDE);
        let rows = (parts.len() / cols).min(SIDE);
        let mut out = Parts {
            x: [[0.0; 2]; SIDE],
            y: [[0.0; 2]; SIDE],
            cols,
            rows,
            parallel: parts.first().is_some_and(|b| b.parallel),
            all: (1u64 << (cols * rows)) - 1,
            r2_min: parts
                .iter()
                .map(|b| 0.25 * ((b.x[1] - b.x[0]).powi(2) + (b.y[1] - b.y[0]).powi(2)))
                .fold(f64::INFINITY, f64::min),
        };
        for (x, b) in out.x.iter_mut().zip(parts) {
            *x = b.x;
        }
        for (y, b) in out.y.iter_mut().zip(parts.iter().step_by(cols)).take(rows) {
            *y = b.y;
        }
        out
    }

    /// The parts in the plane of view depth `z` (see [`PartsAt`]).
    #[inline(always)]
    pub(crate) fn at(&self, z: f64) -> PartsAt {
        let at = |v: f64| if self.parallel { v } else { v * z };
        let side = |e: &[[f64; 2]; SIDE], n: usize| {
            std::array::from_fn(|u| match u < n {
                true => e[u].map(at),
                false => [f64::INFINITY; 2],
            })
        };
        let (x, y) = (side(&self.x, self.cols), side(&self.y, self.rows));
        let hull = |e: &[[f64; 2]; SIDE], n: usize| {
            e[..n]
                .iter()
                .fold([f64::INFINITY, f64::NEG_INFINITY], |h, e| {
                    [h[0].min(e[0]).min(e[1]), h[1].max(e[0]).max(e[1])]
                })
        };
        PartsAt {
            z,
            hull_x: hull(&x, self.cols),
            hull_y: hull(&y, self.rows),
            x,
            y,
            cols: self.cols,
            wide: self.r2_min * if self.parallel { 1.0 } else { z * z },
        }
    }
}

/// [`Parts`] in the plane of one sample depth `z`: the rays' x extremes per column and y
/// extremes per row there (infinitely far beyond the grid, so that fixed-size loops over
/// [`SIDE`] find nothing there), and the smallest squared half diagonal of a part, below
/// which a particle's disc covers none.
pub(crate) struct PartsAt {
    pub(crate) z: f64,
    pub(crate) x: [[f64; 2]; SIDE],
    pub(crate) y: [[f64; 2]; SIDE],
    /// The smallest and largest x (y) of all parts' rays.
    pub(crate) hull_x: [f64; 2],
    pub(crate) hull_y: [f64; 2],
    pub(crate) cols: usize,
    pub(crate) wide: f64,
}

/// The distance from `c` to the farther of the extremes `e` along one axis.
#[inline(always)]
pub(crate) fn far(e: [f64; 2], c: f64) -> f64 {
    (e[0] - c).abs().max((e[1] - c).abs())
}

/// The squared radius of the disc of a particle centred at depth `cz` with support radius `h`
/// in the plane of `at`, less the relative margin [`COVER_MARGIN`], or −∞ where the
/// particle does not reach the sample (`reaches`) or its disc is too small to cover any part.
#[inline(always)]
pub(crate) fn disc_limit(at: &PartsAt, (cz, h): (f64, f64), reaches: bool) -> f64 {
    let dz = at.z - cz;
    let lim = h * h - dz * dz;
    match reaches && lim > at.wide {
        true => lim * COVER_MARGIN,
        false => f64::NEG_INFINITY,
    }
}

/// The parts of `at` covered by the disc of squared radius `lim` (from [`disc_limit`])
/// around `(cx, cy)`: bit `v·cols + u` when every ray of part (u, v) is strictly inside it
/// ([`Bundle::covered_by`] of the part, by the same arithmetic). Only the bits of `want` are
/// sure to be found: a disc that covers the rectangle of all parts covers each (the far
/// corner of a part is no farther, rounded, than that of the rectangle), and at most
/// [`FEW_PARTS`] parts are tested one by one, more all at once.
#[inline(always)]
pub(crate) fn disc_cover(at: &PartsAt, (cx, cy): (f64, f64), lim: f64, want: u64, all: u64) -> u64 {
    if lim == f64::NEG_INFINITY {
        return 0;
    }
    let (fx, fy) = (far(at.hull_x, cx), far(at.hull_y, cy));
    if fx * fx + fy * fy < lim {
        return all;
    }
    match want.count_ones() <= FEW_PARTS {
        true => disc_few(at, (cx, cy), lim, want),
        false => disc_each(at, (cx, cy), lim),
    }
}

/// Whether the disc of squared radius `lim` around `(cx, cy)` covers part `s` of `at`.
#[inline(always)]
pub(crate) fn disc_covers(at: &PartsAt, (cx, cy): (f64, f64), lim: f64, s: usize) -> bool {
    let (fx, fy) = (far(at.x[s % at.cols], cx), far(at.y[s / at.cols], cy));
    fx * fx + fy * fy < lim
}

/// The parts of `want` covered by the disc of squared radius `lim` around `(cx, cy)` at
/// `at`, one by one.
#[inline(always)]
pub(crate) fn disc_few(at: &PartsAt, c: (f64, f64), lim: f64, want: u64) -> u64 {
    let mut bits = 0u64;
    let mut todo = want;
    while todo != 0 {
        let s = todo.trailing_zeros() as usize;
        todo &= todo - 1;
        bits |= u64::from(disc_covers(at, c, lim, s)) << s;
    }
    bits
}

/// The parts covered by the disc of squared radius `lim` around `(cx, cy)` at `at`, all
/// at once: the far-corner offsets once per column and row, in loops of fixed length.
#[inline(always)]
pub(crate) fn disc_each(at: &PartsAt, (cx, cy): (f64, f64), lim: f64) -> u64 {
    let (fx, fy) = (at.x.map(|e| far(e, cx)), at.y.map(|e| far(e, cy)));
    let nearest = |f: &[f64; SIDE]| f.iter().fold(f64::INFINITY, |a, &b| a.min(b));
    let (mx, my) = (nearest(&fx), nearest(&fy));
    if mx * mx + my * my >= lim {
        return 0; // not even the nearest column and row
    }
    let (fx2, fy2) = (fx.map(|x| x * x), fy.map(|y| y * y));
    let mut bits = 0u64;
    for (v, y2) in fy2.iter().enumerate() {
        let row = fx2
            .iter()
            .enumerate()
            .fold(0u64, |m, (u, x2)| m | (u64::from(x2 + y2 < lim) << u));
        bits |= row << (v * at.cols);
    }
    bits
}

/// The most open parts that [`disc_cover`] tests one by one rather than all at once (a
/// part alone costs about a sixth of all of them).
pub(crate) const FEW_PARTS: u32 = 3;

/// How many particles the coverage test takes at once.
pub(crate) const LANE_WIDTH: usize = 4;

/// [`LANE_WIDTH`] particles of [`Lanes`]: centres in view space, support radii, and the cell's
/// samples each reaches (none for a lane not filled).
#[derive(Clone, Copy)]
pub(crate) struct LaneChunk {
    pub(crate) cx: [f64; LANE_WIDTH],
    pub(crate) cy: [f64; LANE_WIDTH],
    pub(crate) cz: [f64; LANE_WIDTH],
    pub(crate) h: [f64; LANE_WIDTH],
    pub(crate) samples: [u64; LANE_WIDTH],
}

impl LaneChunk {
    const EMPTY: LaneChunk = LaneChunk {
        cx: [0.0; LANE_WIDTH],
        cy: [0.0; LANE_WIDTH],
        cz: [0.0; LANE_WIDTH],
        h: [0.0; LANE_WIDTH],
        samples: [0; LANE_WIDTH],
    };

    /// Per lane, [`disc_limit`] at sample `k`.
    #[inline(always)]
    pub(crate) fn limits(&self, at: &PartsAt, k: usize) -> [f64; LANE_WIDTH] {
        std::array::from_fn(|l| {
            disc_limit(at, (self.cz[l], self.h[l]), self.samples[l] >> k & 1 != 0)
        })
    }

    /// Whether some particle of the chunk that reaches sample `k` covers part `s` at `at`:
    /// bit `s` of [`disc_cover`] alone ([`disc_covers`] in every lane, without a branch).
    #[inline(always)]
    pub(crate) fn covers_part(&self, at: &PartsAt, k: usize, s: usize) -> bool {
        let lim = self.limits(at, k);
        (0..LANE_WIDTH).fold(false, |hit, l| {
            hit | disc_covers(at, (self.cx[l], self.cy[l]), lim[l], s)
        })
    }
}

/// Particles of a cell that reach some of its samples, [`LANE_WIDTH`] at a time, one array
/// per coordinate, for the coverage test's one-part tests: where a sample keeps a coverage
/// gap, every particle that reaches it is tested against one part, and reading them in order,
/// without looking each up by index and without a branch per particle, took the coverage
/// test from 0.94 G to 0.72 G instructions of a default render of a 254k-particle double dam
/// break.
#[derive(Default)]
pub(crate) struct Lanes {
    pub(crate) chunks: Vec<LaneChunk>,
    pub(crate) len: usize,
}

impl Lanes {
    pub(crate) fn clear(&mut self) {
        self.chunks.clear();
        self.len = 0;
    }

    /// The particles of `reaching`, in its order.
    pub(crate) fn fill(&mut self, reaching: &[Reacher], particles: &[ViewParticle]) {
        self.clear();
        for r in reaching {
            self.push(&particles[r.j as usize], r.samples);
        }
    }

    /// Adds `p`, which reaches the cell's `samples` (bit k for sample k).
    #[inline(always)]
    pub(crate) fn push(&mut self, p: &ViewParticle, samples: u64) {
        let lane = self.len % LANE_WIDTH;
        if lane == 0 {
            self.chunks.push(LaneChunk::EMPTY);
        }
        if let Some(c) = self.chunks.last_mut() {
            c.cx[lane] = p.c[0];
            c.cy[lane] = p.c[1];
            c.cz[lane] = p.c[2];
            c.h[lane] = p.h();
            c.samples[lane] = samples;
        }
        self.len += 1;
    }
}

/// True when `p`'s support reaches within half its radius of the bundle's middle ray
/// (`(mx, my)`, its x and y at unit depth, or in the view plane for a parallel view). Such
/// particles cover most of the bundle, so the coverage test takes them first.
#[inline]
pub(crate) fn covers_middle(p: &ViewParticle, (mx, my): (f64, f64), parallel: bool) -> bool {
    let s = if parallel { 1.0 } else { p.c[2] };
    let (dx, dy) = (mx * s - p.c[0], my * s - p.c[1]);
    4.0 * (dx * dx + dy * dy) < p.h() * p.h()
}

/// The coverage test of one cell (Sec. 4.2, see [`Parts`]): at each sample that a particle
/// reaches, whether every sub-bundle's rays are inside some particle's support.
pub(crate) struct Coverage<'a> {
    pub(crate) parts: &'a Parts,
    pub(crate) particles: &'a [ViewParticle],
    /// The particles that reach some sample, central ones first.
    pub(crate) reaching: &'a [Reacher],
    /// The cell's sample depths.
    pub(crate) zs: &'a [f64],
}

impl Coverage<'_> {
    /// The samples of `any` left open: some sub-bundle's rays are inside no particle's
    /// support there. A sample with a gap keeps it over neighbouring samples: one sub-bundle
    /// left open at the sample before is tested alone first, and where no particle covers it
    /// the sample is open without testing the others (3 in 4 tests on a 227k-particle dam
    /// break were on samples that stayed open). `lanes` holds the particles for those
    /// one-part tests, filled at the first.
    pub(crate) fn of(&self, any: u64, lanes: &mut Lanes) -> u64 {
        let all = self.parts.all;
        lanes.clear();
        let mut open = any;
        let mut gap: Option<usize> = None;
        let mut todo = any;
        while todo != 0 {
            let k = todo.trailing_zeros() as usize;
            todo &= todo - 1;
            let at = self.parts.at(self.zs[k]);
            if let Some(g) = gap {
                if lanes.len == 0 {
                    lanes.fill(self.reaching, self.particles);
                }
                if !lanes.chunks.iter().any(|c| c.covers_part(&at, k, g)) {
                    continue;
                }
            }
            // The sub-bundles covered at sample k.
            let mut cover = 0u64;
            for r in self.reaching.iter().filter(|r| r.samples >> k & 1 != 0) {
                let p = &self.particles[r.j as usize];
                let lim = disc_limit(&at, (p.c[2], p.h()), true);
                cover |= disc_cover(&at, (p.c[0], p.c[1]), lim, all & !cover, all);
                if cover == all {
                    open &= !(1u64 << k);
                    break;
                }
            }
            // The lowest sub-bundle left open, if any.
            let left = all & !cover;
            gap = (left != 0).then(|| left.trailing_zeros() as usize);
        }
        open
    }
}
