// The sampling plan on the GPU (Hochstetter et al. 2016, Sec. 4–6.2), mirroring
// fluidcast_plan::SamplingPlan::build in single precision:
// * `analyse`: one workgroup per cell, one invocation per depth sample: quantity bounds from the
//   cell's particles, coverage by 4 × 4 sub-bundles, colour/opacity bounds from exact transfer
//   function extremes, then one invocation per sampling level composites the cell's bound.
// * `greedy`: one invocation per bundle: relaxed bounds, the back-to-front greedy choice of
//   level or super-pixel under E_I, cell merging, the spans the ray caster reads, statistics.

@group(0) @binding(3) var<storage, read> vparts: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> depths: array<f32>;
@group(0) @binding(5) var<storage, read> cells: array<Cell>;
@group(0) @binding(6) var<storage, read> refs: array<u32>;
@group(0) @binding(7) var<storage, read> surface: array<u32>;
@group(0) @binding(8) var<storage, read_write> bounds: array<vec4<f32>>; // (lo, hi) per cell and level
@group(0) @binding(9) var<storage, read_write> info: array<u32>;         // 1: coverage gap, 2: surface particle
@group(0) @binding(10) var<storage, read> bundle_cells: array<u32>;
@group(0) @binding(11) var<storage, read_write> front: array<vec4<f32>>;
@group(0) @binding(12) var<storage, read_write> levels: array<u32>;      // chosen level, 255 super-pixel
@group(0) @binding(13) var<storage, read_write> spans: array<Span>;      // bundle b's at bundle_cells[b]..
@group(0) @binding(14) var<storage, read_write> span_count: array<u32>;
@group(0) @binding(15) var<storage, read_write> summaries: array<vec4<f32>>;
// [cells per level 0..7, super-pixel cells, surface cells, merged cells, refs sampled,
//  the probe's full-rate and planned cast work (u64 each, low word first), unanalysed bundles]
@group(0) @binding(16) var<storage, read_write> plan_stats: array<atomic<u32>>;
// [0]: 1 when an invocation passed P.loop_limit (see `tick` in common.wgsl).
@group(0) @binding(17) var<storage, read_write> guard: array<atomic<u32>>;
// Per bundle: the nearest view depth at which opaque geometry stops one of its rays (read
// only when bit 0 of P.has_limit is set; RenderParams::bundle_stops).
@group(0) @binding(18) var<storage, read> stops: array<f32>;
// x: which bundles this dispatch plans: 0 all, 1 the probe's, 2 the others (analysed only
// where the probe pays). fluidcast_plan::SamplingPlan::build's probe.
@group(0) @binding(19) var<uniform> phase: vec4<u32>;

fn is_probe(b: u32) -> bool {
    return (b % P.bundles_x + PROBE_ROW_SHIFT * (b / P.bundles_x)) % PROBE_STRIDE == 0u;
}

/// Whether this dispatch plans bundle b.
fn in_phase(b: u32) -> bool {
    return phase.x == 0u || (phase.x == 1u) == is_probe(b);
}

/// x · k for a u64 x = (low, high) below 2^61 and k < 2^16.
fn mul64(x: vec2<u32>, k: u32) -> vec2<u32> {
    let p0 = (x.x & 0xffffu) * k;
    let p1 = (x.x >> 16u) * k + (p0 >> 16u);
    return vec2<u32>((p0 & 0xffffu) | (p1 << 16u), x.y * k + (p1 >> 16u));
}

fn stat64(i: u32) -> vec2<u32> {
    return vec2<u32>(atomicLoad(&plan_stats[i]), atomicLoad(&plan_stats[i + 1u]));
}

/// fluidcast_plan's `probe_pays`, exactly: (den − num) · full ≥ den · planned.
fn probe_pays() -> bool {
    let a = mul64(stat64(11u), PROBE_SAVING_DEN - PROBE_SAVING_NUM);
    let b = mul64(stat64(13u), PROBE_SAVING_DEN);
    return a.y > b.y || (a.y == b.y && a.x >= b.x);
}

/// Whether bundle b gets the error analysis (in an adaptive plan).
fn analysed(b: u32) -> bool {
    return phase.x != 2u || probe_pays();
}

fn add64(i: u32, v: vec2<u32>) {
    let old = atomicAdd(&plan_stats[i], v.x);
    atomicAdd(&plan_stats[i + 1u], v.y + select(0u, 1u, old + v.x < old));
}

/// fluidcast_plan's `cast_work` of a cell, as a u64.
fn cast_work(refs: u32, level: u32) -> vec2<u32> {
    if (level == 255u) {
        return vec2<u32>(0u);
    }
    let s = LEVELS - 1u - level;
    return vec2<u32>(refs << s, select(refs >> (32u - s), 0u, s == 0u));
}

fn sum64(a: vec2<u32>, b: vec2<u32>) -> vec2<u32> {
    let lo = a.x + b.x;
    return vec2<u32>(lo, a.y + b.y + select(0u, 1u, lo < a.x));
}

/// A bundle's rays: extremes of the direction's (perspective) or origin's (parallel) x and y
/// over its pixel centres, and of |d| (fluidcast_grid::Bundle).
struct Rays {
    x: vec2<f32>,
    y: vec2<f32>,
    dlen: vec2<f32>,
};

fn ndc(i: u32, j: u32) -> vec2<f32> {
    return vec2<f32>(2.0 * (f32(i) + 0.5) / f32(P.width) - 1.0,
                     1.0 - 2.0 * (f32(j) + 0.5) / f32(P.height));
}

fn bundle_pixels(b: u32) -> vec4<u32> {
    let bx = b % P.bundles_x;
    let by = b / P.bundles_x;
    let d = P.bundle;
    return vec4<u32>(bx * d, min((bx + 1u) * d, P.width), by * d, min((by + 1u) * d, P.height));
}

fn near_abs(r: vec2<f32>) -> f32 {
    if (r.x <= 0.0 && r.y >= 0.0) {
        return 0.0;
    }
    return min(abs(r.x), abs(r.y));
}

fn rays_of(px: vec4<u32>) -> Rays {
    let a = ndc(px.x, px.z);
    let b = ndc(px.y - 1u, px.w - 1u);
    var s = vec2<f32>(P.tan_half * P.aspect, P.tan_half);
    if (P.parallel_scale > 0.0) {
        s = vec2<f32>(P.parallel_scale * P.aspect, P.parallel_scale);
    }
    let x = vec2<f32>(a.x * s.x, b.x * s.x);
    let y = vec2<f32>(b.y * s.y, a.y * s.y);
    var dl = vec2<f32>(1.0, 1.0);
    if (P.parallel_scale <= 0.0) {
        let nx = near_abs(x);
        let ny = near_abs(y);
        let fx = max(abs(x.x), abs(x.y));
        let fy = max(abs(y.x), abs(y.y));
        dl = vec2<f32>(sqrt(1.0 + nx * nx + ny * ny), sqrt(1.0 + fx * fx + fy * fy));
    }
    return Rays(x, y, dl);
}

/// Every ray of the bundle strictly inside the particle's support at depth z (Bundle::covered_by;
/// the margin is wider than the CPU's for single precision, which only makes it more cautious).
fn covered(r: Rays, c: vec3<f32>, h: f32, z: f32) -> bool {
    var rx = r.x;
    var ry = r.y;
    if (P.parallel_scale <= 0.0) {
        rx = rx * z;
        ry = ry * z;
    }
    let dz = z - c.z;
    let lim = (h * h - dz * dz) * (1.0 - 1.0e-5);
    if (lim <= 0.0) {
        return false;
    }
    let fx = max(abs(rx.x - c.x), abs(rx.y - c.x));
    let fy = max(abs(ry.x - c.y), abs(ry.y - c.y));
    return fx * fx + fy * fy < lim;
}

/// Per-sample colour and extinction bounds (the CPU's ValueBound).
struct ValueBound {
    empty: bool,
    may_be_empty: bool,
    rgb_lo: vec3<f32>,
    rgb_hi: vec3<f32>,
    k: vec2<f32>, // extinction per world unit, (lo, hi)
};

fn vb_union(a: ValueBound, b: ValueBound) -> ValueBound {
    if (a.empty) {
        var r = b;
        r.may_be_empty = true;
        return r;
    }
    if (b.empty) {
        var r = a;
        r.may_be_empty = true;
        return r;
    }
    return ValueBound(false, a.may_be_empty || b.may_be_empty, min(a.rgb_lo, b.rgb_lo),
                      max(a.rgb_hi, b.rgb_hi), vec2<f32>(min(a.k.x, b.k.x), max(a.k.y, b.k.y)));
}

/// Bound of one step of world length in [ds0, ds1] (ValueBound::step).
fn vb_step(v: ValueBound, ds0: f32, ds1: f32) -> Bound {
    if (v.empty) {
        return bound_empty();
    }
    // As on the CPU (fluidcast_plan::transmittance): no extinction over any step, even an
    // infinitely long one from a far outlier, lets everything through.
    let t_lo = select(exp(-v.k.y * ds1), 1.0, v.k.y == 0.0 || ds1 == 0.0);
    let t_hi = select(exp(-v.k.x * ds0), 1.0, v.k.x == 0.0 || ds0 == 0.0);
    let a_lo = 1.0 - t_hi;
    let a_hi = 1.0 - t_lo;
    var lo = vec4<f32>(a_lo * v.rgb_lo, t_lo);
    var hi = vec4<f32>(a_hi * v.rgb_hi, t_hi);
    if (v.may_be_empty) {
        lo = vec4<f32>(0.0, 0.0, 0.0, t_lo);
        hi.w = 1.0;
    }
    return Bound(lo, hi);
}

fn extinction(alpha: f32) -> f32 {
    if (alpha >= 1.0) {
        return K_INF;
    }
    return -log(1.0 - alpha) / P.unit_distance;
}

/// Extremes of the table tf[first..first + n] over its control points strictly inside (t0, t1).
struct Extremes {
    lo: vec3<f32>,
    hi: vec3<f32>,
};

fn table_extremes(first: u32, n: u32, t0: f32, t1: f32) -> Extremes {
    tick(n + 1u);
    var e = Extremes(vec3<f32>(3.0e38), vec3<f32>(-3.0e38));
    for (var i = first; i < first + n; i = i + 1u) {
        let p = tf[i];
        if (p.x >= t1) {
            break;
        }
        if (p.x > t0) {
            e.lo = min(e.lo, p.yzw);
            e.hi = max(e.hi, p.yzw);
        }
    }
    return e;
}

/// Exact colour/opacity extremes over the data values [q0, q1] (TfBounds::range): the ends and
/// the control points strictly inside.
fn tf_range(q0: f32, q1: f32) -> ValueBound {
    var t0 = tf_t(q0);
    var t1 = tf_t(q1);
    if (t0 < 0.0 || t1 < 0.0) {
        t0 = 0.0;
        t1 = 1.0;
    } else {
        let a = min(t0, t1);
        t1 = max(t0, t1);
        t0 = a;
    }
    let e0 = tf_at(t0);
    let e1 = tf_at(t1);
    let c = table_extremes(0u, P.n_colors, t0, t1);
    let o = table_extremes(P.n_colors, P.n_opacity, t0, t1);
    let lo = vec4<f32>(min(min(e0.xyz, e1.xyz), c.lo), min(min(e0.w, e1.w), o.lo.x));
    let hi = vec4<f32>(max(max(e0.xyz, e1.xyz), c.hi), max(max(e0.w, e1.w), o.hi.x));
    return ValueBound(false, false, lo.xyz, hi.xyz, vec2<f32>(extinction(lo.w), extinction(hi.w)));
}

var<workgroup> parts: array<Rays, 16>;
var<workgroup> vbs: array<ValueBound, 64>;
var<workgroup> cell_flags: atomic<u32>;
var<workgroup> skip_cell: bool;
// Per invocation: what its share of the cell's references gave its depth sample.
var<workgroup> g_q: array<vec4<f32>, 64>;   // (qlo, qhi, slo, shi)
var<workgroup> g_any: array<u32, 64>;
var<workgroup> g_cover: array<u32, 64>;

/// The sample bounds of one depth sample from a share of a cell's references.
struct Share {
    q: vec4<f32>, // (qlo, qhi, slo, shi)
    any: bool,
    cover: u32,
};

fn cut(a: u32, n: u32, g: u32, i: u32) -> u32 {
    return a + i * n / g;
}

@compute @workgroup_size(64)
fn analyse(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) nw: vec3<u32>,
           @builtin(local_invocation_index) li: u32) {
    let c = group_index(wg, nw);
    if (c >= P.n_cells) {
        return;
    }
    let cell = cells[c];
    if (li == 0u) {
        skip_cell = !in_phase(cell.bundle) || !analysed(cell.bundle);
    }
    if (workgroupUniformLoad(&skip_cell)) {
        return;
    }
    let px = bundle_pixels(cell.bundle);
    let rays = rays_of(px);
    let gx = min(4u, px.y - px.x);
    let gy = min(4u, px.w - px.z);
    let np = gx * gy;
    if (li < np) {
        let u = li % gx;
        let v = li / gx;
        parts[li] = rays_of(vec4<u32>(cut(px.x, px.y - px.x, gx, u), cut(px.x, px.y - px.x, gx, u + 1u),
                                      cut(px.z, px.w - px.z, gy, v), cut(px.z, px.w - px.z, gy, v + 1u)));
    }
    if (li == 0u) {
        atomicStore(&cell_flags, 0u);
    }
    workgroupBarrier();
    let full = (1u << np) - 1u;
    var part_r2 = 3.0e38;
    tick(np + 1u);
    for (var s = 0u; s < np; s = s + 1u) {
        let p = parts[s];
        part_r2 = min(part_r2, 0.25 * ((p.x.y - p.x.x) * (p.x.y - p.x.x) + (p.y.y - p.y.x) * (p.y.y - p.y.x)));
    }
    let k0 = cell.z * P.dz;
    // All 64 invocations work: invocation li takes depth sample li % D_z and every G-th of the
    // cell's references (G = 64 / D_z groups), which keeps each one's loop short.
    let groups = 64u / P.dz;
    let share = analyse_share(cell, rays, full, np, part_r2, depths[k0 + li % P.dz],
                              cell.start + li / P.dz, groups);
    g_q[li] = share.q;
    g_any[li] = u32(share.any);
    g_cover[li] = share.cover;
    workgroupBarrier();
    if (li < P.dz) {
        var q = vec4<f32>(3.0e38, -3.0e38, 0.0, 0.0);
        var any = false;
        var cover = 0u;
        tick(groups + 1u);
        for (var g = 0u; g < groups; g = g + 1u) {
            let k = g * P.dz + li;
            q = vec4<f32>(min(q.x, g_q[k].x), max(q.y, g_q[k].y), q.z + g_q[k].z, q.w + g_q[k].w);
            any = any || g_any[k] != 0u;
            cover = cover | g_cover[k];
        }
        var vb = ValueBound(true, true, vec3<f32>(0.0), vec3<f32>(0.0), vec2<f32>(0.0));
        if (any) {
            if (P.field == FIELD_CSPH) {
                vb = tf_range(q.x, q.y);
            } else {
                vb = tf_range(q.z, q.w);
            }
            // A step that ends past the bundle's nearest stop may be cut short or skipped
            // for some ray: "nothing" is one of its values, as for a coverage gap.
            let stopped = (P.has_limit & 1u) == 1u && depths[k0 + li + 1u] > stops[cell.bundle];
            vb.may_be_empty = cover != full || stopped;
            if (cover != full) {
                atomicOr(&cell_flags, 1u);
            }
        }
        vbs[li] = vb;
    }
    if (P.surface_rule == 1u) {
        tick((cell.end - cell.start + 63u) / 64u + 1u);
        for (var r = cell.start + li; r < cell.end; r = r + 64u) {
            if (surface[refs[r]] != 0u) {
                atomicOr(&cell_flags, 2u);
                break;
            }
        }
    }
    workgroupBarrier();
    if (li <= P.max_level) {
        // Level l: sample k is drawn with the value of sample floor(k / 2^l) 2^l over its own
        // step, so step k's bound is the union of both samples' bounds.
        let step = 1u << li;
        var acc = bound_empty();
        tick(P.dz + 1u);
        for (var k = 0u; k < P.dz; k = k + 1u) {
            var u = vbs[k];
            if (k % step != 0u) {
                u = vb_union(vbs[k / step * step], u);
            }
            let ds = depths[k0 + k + 1u] - depths[k0 + k];
            acc = over(acc, vb_step(u, ds * rays.dlen.x, ds * rays.dlen.y));
        }
        bounds[(c * LEVELS + li) * 2u] = acc.lo;
        bounds[(c * LEVELS + li) * 2u + 1u] = acc.hi;
    }
    if (li == 0u) {
        info[c] = atomicLoad(&cell_flags);
    }
}

/// Quantity bounds and coverage at depth z from the references r0, r0 + step, … of a cell.
fn analyse_share(cell: Cell, rays: Rays, full: u32, np: u32, part_r2: f32, z: f32, r0: u32,
                 step: u32) -> Share {
    var out = Share(vec4<f32>(3.0e38, -3.0e38, 0.0, 0.0), false, 0u);
    // Same count in every invocation: the number of references, each with its coverage loop,
    // and what analyse loops after this (a reduction, a transfer function range, a bound).
    let count = (cell.end - cell.start + step - 1u) / step * (2u + np) + 1u;
    if (over_budget(count + 70u + P.n_colors + P.n_opacity + 2u * P.dz + cell.end - cell.start)) {
        atomicOr(&guard[0], 1u);
        return out;
    }
    tick(count);
    for (var r = r0; r < cell.end; r = r + step) {
        let j = refs[r];
        let a = vparts[2u * j];
        if (z < a.z - a.w || z > a.z + a.w) {
            continue;
        }
        let pb = vparts[2u * j + 1u];
        let wmax = kernel_w(0.0, a.w);
        out.any = true;
        out.q.x = min(out.q.x, pb.y);
        out.q.y = max(out.q.y, pb.y);
        if (P.field == FIELD_SPH) {
            let s = pb.y * pb.x * wmax;
            out.q.z = out.q.z + min(s, 0.0);
            out.q.w = out.q.w + max(s, 0.0);
        } else if (P.field == FIELD_DENSITY) {
            out.q.w = out.q.w + pb.z * wmax;
        }
        if (out.cover != full) {
            // The disc must at least reach over a sub-bundle's half diagonal.
            let dzk = z - a.z;
            let lim = a.w * a.w - dzk * dzk;
            var scale = z * z;
            if (P.parallel_scale > 0.0) {
                scale = 1.0;
            }
            if (lim <= part_r2 * scale) {
                continue;
            }
            if (covered(rays, a.xyz, a.w, z)) {
                out.cover = full;
            } else {
                for (var s = 0u; s < np; s = s + 1u) {
                    if ((out.cover & (1u << s)) == 0u && covered(parts[s], a.xyz, a.w, z)) {
                        out.cover = out.cover | (1u << s);
                    }
                }
            }
        }
    }
    return out;
}

fn bound_at(c: u32, l: u32) -> Bound {
    return Bound(bounds[(c * LEVELS + l) * 2u], bounds[(c * LEVELS + l) * 2u + 1u]);
}

/// Sec. 5.1: lower bounds move up by E_relax × the level-0 width.
fn relaxed(c: u32, l: u32) -> Bound {
    let bl = bound_at(c, l);
    let b0 = bound_at(c, 0u);
    let lo0 = b0.hi - (1.0 - P.relax) * (b0.hi - b0.lo);
    return Bound(min(max(lo0 + (bl.lo - b0.lo), vec4<f32>(0.0)), bl.hi), bl.hi);
}

/// The most a cell's own change of level can move a pixel (the CPU's `level_error`):
/// F_T·(w(C_I) + w(C_T)·B_I) in colour, F_T·w(C_T)·B_T in alpha.
fn level_error(front_t: f32, cell: Bound, back: Bound) -> f32 {
    let w = cell.hi - cell.lo;
    let colour = w.xyz + w.w * back.hi.xyz;
    return front_t * max(max(colour.x, colour.y), max(colour.z, w.w * back.hi.w));
}

/// References a run of cells reads, each particle once (the CPU's `merge_runs`' `reads`).
fn run_reads(first: u32, count: u32) -> u32 {
    var n = 0u;
    for (var c = first; c < first + count; c = c + 1u) {
        let cl = cells[c];
        n = n + select(cl.unique_end, cl.end, c + 1u == first + count) - cl.start;
    }
    return n;
}

/// Whether merging run `a` with the run `b` behind it pays (the CPU's `merge_runs`' `pays`):
/// a merge within D_z samples always; a longer one where the references it saves (those of
/// a's last cell that b's first repeats) are at least those it may read in vain (b's others,
/// should the rays stop inside a).
fn merge_pays(a: Span, b: Span) -> bool {
    let last = cells[a.first + a.count - 1u];
    let repeated = last.end - last.unique_end;
    let others = max(run_reads(b.first, b.count), repeated) - repeated;
    return ((2u * a.count * P.dz) >> a.level) <= P.dz || repeated >= others;
}

fn span_of(c: u32, level: u32) -> Span {
    let sp = level == 255u;
    return Span(c, 1u, select(level, 0u, sp), select(0u, 1u, sp), 0u, 0u, 0u, 0u, vec4<f32>(0.0));
}

@compute @workgroup_size(64)
fn greedy(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) nw: vec3<u32>,
          @builtin(local_invocation_index) li: u32) {
    let b = group_index(wg, nw) * 64u + li;
    if (b >= P.bundles_x * P.bundles_y || !in_phase(b)) {
        return;
    }
    let c0 = bundle_cells[b];
    let c1 = bundle_cells[b + 1u];
    let n = c1 - c0;
    summaries[2u * b] = vec4<f32>(0.0);
    summaries[2u * b + 1u] = vec4<f32>(0.0);
    span_count[b] = 0u;
    if (n == 0u) {
        return;
    }
    var level_cells: array<u32, 7>;
    for (var l = 0u; l < LEVELS; l = l + 1u) {
        level_cells[l] = 0u;
    }
    var n_sp = 0u;
    var n_surface = 0u;
    var back = bound_empty();
    let adapt = P.tolerance >= 0.0 && analysed(b);
    if (!adapt) {
        // No adaptivity, or the probe found it does not pay: every cell at full rate.
        for (var c = c0; c < c1; c = c + 1u) {
            levels[c] = 0u;
        }
        level_cells[0] = n;
        if (P.tolerance >= 0.0) {
            atomicAdd(&plan_stats[15], 1u);
        }
    } else {
        // Front composites of the relaxed full-rate bounds (cells c0..c).
        var f = bound_empty();
        for (var c = c0; c < c1; c = c + 1u) {
            front[2u * c] = f.lo;
            front[2u * c + 1u] = f.hi;
            f = over(f, relaxed(c, 0u));
        }
        // Greedy, back to front (Sec. 4.4, 5.3): the cheapest option (the highest level, a
        // super-pixel cheapest of all) whose composited bound stays under the budget, as the
        // CPU's `choose_levels`; full rate where none does. In front of a super-pixel a
        // coarser level is held to its unrelaxed bound (the CPU's `choose_level`).
        var superpixel_behind = false;
        var c = c1;
        while (c > c0) {
            c = c - 1u;
            let is_surface = P.surface_rule == 1u && (info[c] & 3u) == 3u;
            let fr = Bound(front[2u * c], front[2u * c + 1u]);
            var lmax = 0u;
            if (is_surface) {
                n_surface = n_surface + 1u;
            } else {
                while (lmax < P.max_level
                       && level_error(fr.hi.w, bound_at(c, lmax + 1u), back) < P.tolerance) {
                    lmax = lmax + 1u;
                }
            }
            var best = relaxed(c, 0u);
            var best_key = 0u;
            for (var l = 1u; l <= lmax; l = l + 1u) {
                var cb: Bound;
                if (superpixel_behind) {
                    cb = bound_at(c, l);
                } else {
                    cb = relaxed(c, l);
                }
                if (width(over(fr, over(cb, back))) < P.budget) {
                    best = cb;
                    best_key = l;
                }
            }
            if (P.superpixels == 1u && !is_surface) {
                let cb = bound_at(c, 0u);
                if (width(over(fr, over(cb, back))) < P.budget) {
                    best = cb;
                    best_key = 255u;
                }
            }
            levels[c] = best_key;
            if (best_key == 255u) {
                superpixel_behind = true;
                n_sp = n_sp + 1u;
            } else {
                level_cells[best_key] = level_cells[best_key] + 1u;
            }
            back = over(best, back);
        }
    }
    // Cell merging (Sec. 6.2): pairs of aligned runs of equal size and level, level by level,
    // while the span samples at most MAX_SPAN_SAMPLES depths (the CPU's `merge_runs`).
    for (var c = c0; c < c1; c = c + 1u) {
        spans[c] = span_of(c, levels[c]);
    }
    var cnt = n;
    for (var m = 0u; m < P.max_level; m = m + 1u) {
        let size = 1u << m;
        var i = 0u;
        var k = 0u;
        while (i < cnt) {
            var a = spans[c0 + i];
            var step = 1u;
            if (i + 1u < cnt) {
                let bs = spans[c0 + i + 1u];
                let za = cells[a.first].z;
                let zb = cells[bs.first].z;
                if (a.superpixel == 0u && bs.superpixel == 0u && a.level == bs.level
                    && ((2u * size * P.dz) >> a.level) <= MAX_SPAN_SAMPLES
                    && a.count == size && bs.count == size && za % (2u * size) == 0u && zb == za + size
                    && merge_pays(a, bs)) {
                    a.count = 2u * size;
                    step = 2u;
                }
            }
            spans[c0 + k] = a;
            k = k + 1u;
            i = i + step;
        }
        cnt = k;
    }
    // What the ray caster reads: depth samples of each span, super-pixel values.
    var n_merged = 0u;
    var n_refs = 0u;
    for (var s = 0u; s < cnt; s = s + 1u) {
        var sp = spans[c0 + s];
        sp.step = 1u << sp.level;
        sp.k0 = cells[sp.first].z * P.dz;
        sp.n = sp.count * P.dz / sp.step;
        if (sp.superpixel == 1u) {
            let b0 = bound_at(sp.first, 0u);
            sp.sp = 0.5 * (b0.lo + b0.hi);
        } else {
            n_merged = n_merged + sp.count - 1u;
            for (var i = 0u; i < sp.count; i = i + 1u) {
                let cl = cells[sp.first + i];
                n_refs = n_refs + select(cl.unique_end, cl.end, i + 1u == sp.count) - cl.start;
            }
        }
        spans[c0 + s] = sp;
    }
    span_count[b] = cnt;
    var lsum = 0u;
    for (var l = 0u; l < LEVELS; l = l + 1u) {
        lsum = lsum + l * level_cells[l];
        if (level_cells[l] > 0u) {
            atomicAdd(&plan_stats[l], level_cells[l]);
        }
    }
    atomicAdd(&plan_stats[7], n_sp);
    atomicAdd(&plan_stats[8], n_surface);
    atomicAdd(&plan_stats[9], n_merged);
    atomicAdd(&plan_stats[10], n_refs);
    let nn = f32(n);
    let sampled = n - n_sp;
    let adapted = sampled - level_cells[0];
    var predicted = 0.0;
    if (adapt) {
        predicted = width(back);
    }
    if (phase.x == 1u) {
        var work = array<vec2<u32>, 2>(vec2<u32>(0u), vec2<u32>(0u));
        for (var c = c0; c < c1; c = c + 1u) {
            let r = cells[c].end - cells[c].start;
            work[0] = sum64(work[0], cast_work(r, 0u));
            work[1] = sum64(work[1], cast_work(r, levels[c]));
        }
        add64(11u, work[0]);
        add64(13u, work[1]);
    }
    summaries[2u * b] = vec4<f32>(predicted, f32(lsum) / f32(max(sampled, 1u)),
                                  f32(level_cells[0]) / nn, f32(adapted) / nn);
    // BundleSummary::front_sampled: the first cell is sampled, not a super-pixel.
    let front = select(0.0, 1.0, cnt > 0u && spans[c0].superpixel == 0u);
    summaries[2u * b + 1u] = vec4<f32>(f32(n_sp) / nn, front, 0.0, 0.0);
}
