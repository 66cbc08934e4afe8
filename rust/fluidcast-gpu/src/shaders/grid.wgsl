// The sparse perspective grid on the GPU (Hochstetter et al. 2016, Sec. 6.1), mirroring
// fluidcast_grid::PerspectiveGrid::build: particles to view space (`view`; the depth range
// and so the sample depths come from the host, in f64 as the CPU finds them), each particle's
// bundle rectangle and cell depth range and its number of (cell, particle) pairs (`footprint`), the pairs with their keys (`emit`; the key is
// ((bundle * cells_z + z) << 1) | merge bit, the value the particle), and after the radix sort
// the cells (`cell_starts`, `cells`) and each bundle's cell range (`bundle_ranges`).

@group(0) @binding(3) var<storage, read> world: array<vec4<f32>>;        // (x, y, z, H), (V, q, m, 0)
@group(0) @binding(4) var<storage, read_write> vparts: array<vec4<f32>>; // the same in view space
// [visible particles, sum of pairs / 256, sum of pairs % 256, cells] (layout.rs: GridCounters)
@group(0) @binding(5) var<storage, read_write> counters: array<atomic<u32>>;
@group(0) @binding(6) var<storage, read> depths: array<f32>;
@group(0) @binding(7) var<storage, read_write> foot: array<vec4<u32>>;   // (bx0, bx1, by0, by1), (z0, z1, -, -)
@group(0) @binding(8) var<storage, read_write> counts: array<u32>;       // pairs per particle, then their offsets
@group(0) @binding(9) var<storage, read_write> keys: array<u32>;
@group(0) @binding(10) var<storage, read_write> vals: array<u32>;
@group(0) @binding(11) var<storage, read_write> starts: array<u32>;      // cell-start flags, then their scan
@group(0) @binding(12) var<storage, read_write> cells: array<Cell>;
@group(0) @binding(13) var<storage, read_write> bundle_cells: array<u32>;
@group(0) @binding(14) var<storage, read> sorted_keys: array<u32>;
// [0]: 1 when an invocation passed P.loop_limit (see `tick` in common.wgsl).
@group(0) @binding(15) var<storage, read_write> guard: array<atomic<u32>>;

@compute @workgroup_size(256)
fn view(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) nw: vec3<u32>,
        @builtin(local_invocation_index) li: u32) {
    let j = group_index(wg, nw) * 256u + li;
    if (j < P.n_particles) {
        let a = world[2u * j];
        let d = a.xyz - P.eye.xyz;
        let c = vec3<f32>(dot(d, P.right.xyz), dot(d, P.up.xyz), dot(d, P.forward.xyz));
        vparts[2u * j] = vec4<f32>(c, a.w);
        vparts[2u * j + 1u] = world[2u * j + 1u];
    }
}

/// First index k in [0, N) with depths[k] >= z (strict: > z).
fn lower_bound(z: f32, strict: bool) -> u32 {
    var lo = 0u;
    var hi = P.n_depths;
    while (lo < hi) {
        let m = (lo + hi) / 2u;
        let v = depths[m];
        if (v < z || (strict && v == z)) {
            lo = m + 1u;
        } else {
            hi = m;
        }
    }
    return lo;
}

/// fluidcast_grid::screen_rect: pixel columns/rows [x0, x1) × [y0, y1) that may see the
/// support, or x0 >= x1 when none.
fn screen_rect(c: vec3<f32>, h: f32) -> vec4<u32> {
    let w = f32(P.width);
    let ht = f32(P.height);
    var sx = P.tan_half * P.aspect;
    var sy = P.tan_half;
    var x0 = c.x - h;
    var x1 = c.x + h;
    var y0 = c.y - h;
    var y1 = c.y + h;
    if (P.parallel_scale > 0.0) {
        sx = P.parallel_scale * P.aspect;
        sy = P.parallel_scale;
    } else if (c.z - h <= P.near * 0.5) {
        return vec4<u32>(0u, P.width, 0u, P.height);
    } else {
        let za = 1.0 / (c.z - h);
        let zb = 1.0 / (c.z + h);
        x0 = min(min((c.x - h) * za, (c.x - h) * zb), min((c.x + h) * za, (c.x + h) * zb));
        x1 = max(max((c.x - h) * za, (c.x - h) * zb), max((c.x + h) * za, (c.x + h) * zb));
        y0 = min(min((c.y - h) * za, (c.y - h) * zb), min((c.y + h) * za, (c.y + h) * zb));
        y1 = max(max((c.y - h) * za, (c.y - h) * zb), max((c.y + h) * za, (c.y + h) * zb));
    }
    let px0 = max(floor((x0 / sx + 1.0) * 0.5 * w), 0.0);
    let px1 = min(ceil((x1 / sx + 1.0) * 0.5 * w), w);
    let py0 = max(floor((1.0 - y1 / sy) * 0.5 * ht), 0.0);
    let py1 = min(ceil((1.0 - y0 / sy) * 0.5 * ht), ht);
    if (px0 >= px1 || py0 >= py1) {
        return vec4<u32>(1u, 0u, 1u, 0u);
    }
    return vec4<u32>(u32(px0), u32(px1), u32(py0), u32(py1));
}

/// Particle j's bundle rectangle and cell depth range into foot, its pair count into counts;
/// returns the count (0 when its support misses every cell).
fn particle_footprint(j: u32) -> u32 {
    counts[j] = 0u;
    let a = vparts[2u * j];
    let c = a.xyz;
    let h = a.w;
    if (c.z + h < P.near || c.z - h > P.far) {
        return 0u;
    }
    let r = screen_rect(c, h);
    if (r.x >= r.y || r.z >= r.w) {
        return 0u;
    }
    let k0 = lower_bound(c.z - h, false);
    let k1 = lower_bound(c.z + h, true);
    if (k0 >= k1) {
        return 0u;
    }
    let d = P.bundle;
    let f = vec4<u32>(r.x / d, (r.y - 1u) / d, r.z / d, (r.w - 1u) / d);
    let z0 = k0 / P.dz;
    let z1 = (k1 - 1u) / P.dz;
    foot[2u * j] = f;
    foot[2u * j + 1u] = vec4<u32>(z0, z1, 0u, 0u);
    let n = (f.y - f.x + 1u) * (f.w - f.z + 1u) * (z1 - z0 + 1u);
    counts[j] = n;
    return n;
}

// Per workgroup: visible particles, sum of pairs / 256, sum of pairs % 256 (added to the
// global counters once per workgroup, not once per particle).
var<workgroup> wg_sums: array<atomic<u32>, 3>;

@compute @workgroup_size(256)
fn footprint(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) nw: vec3<u32>,
             @builtin(local_invocation_index) li: u32) {
    if (li < 3u) {
        atomicStore(&wg_sums[li], 0u);
    }
    workgroupBarrier();
    let j = group_index(wg, nw) * 256u + li;
    if (j < P.n_particles) {
        let n = particle_footprint(j);
        if (n > 0u) {
            atomicAdd(&wg_sums[0], 1u);
            atomicAdd(&wg_sums[1], n >> 8u);
            atomicAdd(&wg_sums[2], n & 255u);
        }
    }
    workgroupBarrier();
    if (li < 3u) {
        atomicAdd(&counters[li], atomicLoad(&wg_sums[li]));
    }
}

@compute @workgroup_size(256)
fn emit(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) nw: vec3<u32>,
        @builtin(local_invocation_index) li: u32) {
    let j = group_index(wg, nw) * 256u + li;
    if (j >= P.n_particles) {
        return;
    }
    var i = counts[j]; // the exclusive scan of the pair counts
    let end = select(P.n_pairs, counts[j + 1u], j + 1u < P.n_particles);
    if (i == end) {
        return;
    }
    let f = foot[2u * j];
    let fz = foot[2u * j + 1u];
    // One loop over the particle's pairs (x fastest after z), so each invocation loops exactly
    // its pair count and the longest one bounds its SIMD batch.
    let nz = fz.y - fz.x + 1u;
    let nx = f.y - f.x + 1u;
    let n = end - i;
    if (over_budget(n + 1u)) {
        atomicOr(&guard[0], 1u);
        return;
    }
    for (var t = 0u; t < n; t = t + 1u) {
        let z = fz.x + t % nz;
        let xy = t / nz;
        let b = (f.z + xy / nx) * P.bundles_x + f.x + xy % nx;
        keys[i + t] = ((b * P.cells_z + z) << 1u) | select(0u, 1u, z < fz.y);
        vals[i + t] = j;
    }
}

@compute @workgroup_size(256)
fn cell_starts(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) nw: vec3<u32>,
               @builtin(local_invocation_index) li: u32) {
    if (li == 0u) {
        atomicStore(&wg_sums[0], 0u);
    }
    workgroupBarrier();
    let i = group_index(wg, nw) * 256u + li;
    if (i < P.n_pairs) {
        let first = i == 0u || (sorted_keys[i] >> 1u) != (sorted_keys[i - 1u] >> 1u);
        starts[i] = select(0u, 1u, first);
        if (first) {
            atomicAdd(&wg_sums[0], 1u);
        }
    }
    workgroupBarrier();
    if (li == 0u) {
        atomicAdd(&counters[3], atomicLoad(&wg_sums[0]));
    }
}

@compute @workgroup_size(256)
fn make_cells(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) nw: vec3<u32>,
              @builtin(local_invocation_index) li: u32) {
    let i = group_index(wg, nw) * 256u + li;
    if (i >= P.n_pairs) {
        return;
    }
    let k = sorted_keys[i];
    let first = i == 0u || (k >> 1u) != (sorted_keys[i - 1u] >> 1u);
    let last = i + 1u == P.n_pairs || (k >> 1u) != (sorted_keys[i + 1u] >> 1u);
    // starts holds the exclusive scan of the start flags: cells begun before i.
    let c = select(starts[i] - 1u, starts[i], first);
    let bit = k & 1u;
    if (first) {
        cells[c].z = (k >> 1u) % P.cells_z;
        cells[c].bundle = (k >> 1u) / P.cells_z;
        cells[c].start = i;
    }
    if (last) {
        cells[c].end = i + 1u;
    }
    // References with the merge bit clear come first within a cell.
    if (bit == 0u && (last || (sorted_keys[i + 1u] & 1u) == 1u)) {
        cells[c].unique_end = i + 1u;
    }
    if (bit == 1u && first) {
        cells[c].unique_end = i;
    }
}

@compute @workgroup_size(256)
fn bundle_ranges(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) nw: vec3<u32>,
                 @builtin(local_invocation_index) li: u32) {
    // One invocation per bundle (and one past the last): the first cell of bundle bb or a
    // later one, by a binary search over the cells (sorted by bundle). At most 33 iterations
    // whatever the view, where a cell filling the run of empty bundles before it looped over
    // every one of them (more than a software driver allows at 1920 x 1080).
    let bb = group_index(wg, nw) * 256u + li;
    if (bb > P.bundles_x * P.bundles_y) {
        return;
    }
    var lo = 0u;
    var hi = P.n_cells;
    loop {
        if (lo >= hi) {
            break;
        }
        let mid = lo + (hi - lo) / 2u;
        if (cells[mid].bundle < bb) {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    bundle_cells[bb] = lo;
}
