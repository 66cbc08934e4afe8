// Bundle-coherent ray casting (Hochstetter et al. 2016, Alg. 2) of a sampling plan (built by
// plan.wgsl, or on the CPU and uploaded): one workgroup per ray bundle, one invocation per ray. For each span of the
// bundle's plan (front to back) the span's particles are loaded into workgroup memory in
// chunks and every ray scatters them into its samples; then the samples are composited.
// Mirrors fluidcast-render's CPU caster (raycast.rs / adaptive.rs) in single precision.

@group(0) @binding(3) var<storage, read> particles: array<vec4<f32>>; // view space: (c.xyz, h), (v, a, m, 0)
@group(0) @binding(4) var<storage, read> depths: array<f32>;
@group(0) @binding(5) var<storage, read> spans: array<Span>;        // bundle b's at bundle_cells[b]..
@group(0) @binding(6) var<storage, read> span_count: array<u32>;
@group(0) @binding(7) var<storage, read> bundle_cells: array<u32>;
@group(0) @binding(8) var<storage, read> cells: array<Cell>;
@group(0) @binding(9) var<storage, read> refs: array<u32>;
@group(0) @binding(10) var<storage, read_write> out_rgba: array<vec4<f32>>;
@group(0) @binding(11) var<storage, read_write> out_depth: array<f32>;
@group(0) @binding(12) var<storage, read_write> out_samples: array<u32>; // per bundle
@group(0) @binding(13) var<storage, read> depth_limit: array<f32>;
// [0]: 1 when an invocation passed P.loop_limit (see `tick` in common.wgsl).
@group(0) @binding(14) var<storage, read_write> guard: array<atomic<u32>>;
// A bundle whose spans would pass P.loop_limit in one invocation (a software driver's limit)
// stops before a span and resumes there in the host's next dispatch of this stage, the image
// unchanged: its rays' compositing state at ray_state[2 (64 b + li)] (colour, T) and
// (depth at half opacity, samples as bits, done, 0); resume[1 + b] the span to resume at
// (RESUME_FRESH before the first dispatch, RESUME_DONE once the bundle's pixels are written)
// and resume[1 + B + b] the chunk of its particles (B bundles; 0: the span's start);
// resume[0] the bundles that stopped in this dispatch. A dispatch covers a band of rows of
// bundles (from band.x, the rows the host fits chunk_sums with); where chunk_sums holds the
// band's rays' span sums (2 MAXS floats at (64 b' + li) 2 MAXS, b' the bundle within the
// band), a bundle may stop between two chunks of a span too, so that no span is too long for
// one invocation; elsewhere only before a span.
@group(0) @binding(15) var<storage, read_write> ray_state: array<vec4<f32>>;
@group(0) @binding(16) var<storage, read_write> resume: array<atomic<u32>>;
@group(0) @binding(17) var<storage, read_write> chunk_sums: array<f32>;
// The band: x its first row of bundles, y its rows, z the scatter (common.wgsl's
// scattered_bundle), w: 1 where a bundle whose first span is too long for one invocation
// leaves it to the host's banded dispatches (see defer_span).
@group(0) @binding(18) var<uniform> band: vec4<u32>;

const MAXS: u32 = MAX_SPAN_SAMPLES;   // samples per span (D_z * merged cells / 2^level)
const CHUNK: u32 = 64u;  // particles per workgroup load (one per invocation)
const RESUME_FRESH: u32 = 0xffffffffu;
const RESUME_DONE: u32 = 0xfffffffeu;

var<workgroup> cache_a: array<vec4<f32>, 64>;
var<workgroup> cache_b: array<vec4<f32>, 64>;
// Per cached particle: the samples [m0, m1) of its depth slab, found once by the invocation
// that loads it instead of by all 64.
var<workgroup> cache_m: array<vec2<u32>, 64>;
// The span's sample depths (n + 1 <= 65), read from workgroup memory in the inner loops.
var<workgroup> span_z: array<f32, 65>;
// Samples composited by the workgroup's rays.
var<workgroup> wg_samples: atomic<u32>;
var<workgroup> all_done: atomic<u32>;
var<workgroup> done_flag: u32;
var<workgroup> wg_resume: u32;
var<workgroup> wg_resume_chunk: u32;

/// The t-th particle reference of a span: the merged cells' references, each particle once
/// (a cell's references with the merge bit set are repeated by the next cell).
/// Loops `count` times at most: the caller ticks.
fn span_ref(first: u32, count: u32, t: u32) -> u32 {
    var rest = t;
    for (var i = 0u; i < count; i = i + 1u) {
        let c = cells[first + i];
        let len = select(c.unique_end, c.end, i + 1u == count) - c.start;
        if (rest < len) {
            return refs[c.start + rest];
        }
        rest = rest - len;
    }
    return 0u;
}

/// Number of particle references of a span (GridPlan::merged_refs).
fn span_refs(first: u32, count: u32) -> u32 {
    tick(count + 1u);
    var n = 0u;
    for (var i = 0u; i < count; i = i + 1u) {
        let c = cells[first + i];
        n = n + select(c.unique_end, c.end, i + 1u == count) - c.start;
    }
    return n;
}

/// Loop iterations, at most, that an invocation spends on a sampled span as `main` ticks
/// them, in parts that every invocation of the workgroup computes alike (so that all stop at
/// the same place): `span_head` before its chunks (the initial sums, span_refs), `chunk_cost`
/// per chunk of `cn` particles (its loads, loop and samples), `span_tail` after them (the
/// compositing, and what the loop guard reserves before a chunk for the rest of the span).
fn span_head(span: Span) -> u32 {
    return (span.n + 1u) + (span.count + 2u);
}

fn chunk_cost(span: Span, cn: u32) -> u32 {
    return (span.count + 3u) + cn * (span.n + 2u);
}

fn span_tail(span: Span) -> u32 {
    return (span.n + 1u) + (2u * span.n + 2u * span.count + 20u);
}

/// Iterations of all the chunks of a span of `ref_count` particle references.
fn chunks_cost(span: Span, ref_count: u32) -> u32 {
    return ((ref_count + CHUNK - 1u) / CHUNK) * (span.count + 3u) + ref_count * (span.n + 2u);
}

/// How many of the span's first n (<= 64) samples, at span_z[m], lie below z (or at or below
/// it, when `or_at`): a binary search written out without a loop.
fn samples_below(n: u32, z: f32, or_at: bool) -> u32 {
    var lo = 0u;
    lo = below_probe(n, z, or_at, lo, 64u);
    lo = below_probe(n, z, or_at, lo, 32u);
    lo = below_probe(n, z, or_at, lo, 16u);
    lo = below_probe(n, z, or_at, lo, 8u);
    lo = below_probe(n, z, or_at, lo, 4u);
    lo = below_probe(n, z, or_at, lo, 2u);
    lo = below_probe(n, z, or_at, lo, 1u);
    return lo;
}

fn below_probe(n: u32, z: f32, or_at: bool, lo: u32, by: u32) -> u32 {
    let m = lo + by;
    if (m <= n) {
        let zm = span_z[m - 1u];
        if (zm < z || (or_at && zm == z)) {
            return m;
        }
    }
    return lo;
}

/// Stops the bundle before chunk `c0` of span `s` (0: the span's start): its ray's state
/// saved, the place noted once for the workgroup, and counted.
fn suspend(st: u32, color: vec3<f32>, trans: f32, depth_half: f32, samples: u32, done: bool,
           guarded: bool, li: u32, b: u32, nb: u32, s: u32, c0: u32) {
    save_ray(st, color, trans, depth_half, samples, done);
    if (li == 0u) {
        atomicStore(&resume[1u + b], s);
        atomicStore(&resume[1u + nb + b], c0);
        atomicAdd(&resume[0], 1u);
    }
    if (guarded) {
        atomicOr(&guard[0], 1u);
    }
}

/// Leaves span `s`, too long for one invocation where bundles cannot stop between its chunks,
/// to the host's banded dispatches that follow (band.w): the ray's state saved, the place
/// noted, and counted in guard[1], not among the bundles to resume in this band.
fn defer_span(st: u32, color: vec3<f32>, trans: f32, depth_half: f32, samples: u32, done: bool,
              li: u32, b: u32, nb: u32, s: u32) {
    save_ray(st, color, trans, depth_half, samples, done);
    if (li == 0u) {
        atomicStore(&resume[1u + b], s);
        atomicStore(&resume[1u + nb + b], 0u);
        atomicAdd(&guard[1], 1u);
    }
}

fn save_ray(st: u32, color: vec3<f32>, trans: f32, depth_half: f32, samples: u32, done: bool) {
    ray_state[st] = vec4<f32>(color, trans);
    ray_state[st + 1u] = vec4<f32>(depth_half, bitcast<f32>(samples), select(0.0, 1.0, done),
                                   0.0);
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>,
        @builtin(local_invocation_index) li: u32, @builtin(num_workgroups) nw: vec3<u32>) {
    let k = wg.y * nw.x + wg.x;
    let band_bundles = band.y * P.bundles_x;
    let q = scattered_bundle(k, band_bundles, band.z); // the bundle within the band
    if (q == 0xffffffffu) {
        return;
    }
    let bx = q % P.bundles_x;
    let by = band.x + q / P.bundles_x;
    let b = by * P.bundles_x + bx;
    let i = bx * P.bundle + lid.x;
    let j = by * P.bundle + lid.y;
    let in_image = lid.x < P.bundle && lid.y < P.bundle && i < P.width && j < P.height;

    // The ray through pixel (i, j), as Ray::through_pixel.
    let x = 2.0 * (f32(i) + 0.5) / f32(P.width) - 1.0;
    let y = 1.0 - 2.0 * (f32(j) + 0.5) / f32(P.height);
    var o = vec3<f32>(0.0, 0.0, 0.0);
    var d = vec3<f32>(x * P.tan_half * P.aspect, y * P.tan_half, 1.0);
    if (P.parallel_scale > 0.0) {
        o = vec3<f32>(x * P.parallel_scale * P.aspect, y * P.parallel_scale, 0.0);
        d = vec3<f32>(0.0, 0.0, 1.0);
    }
    let dd = dot(d, d);
    let dlen = sqrt(dd);

    var color = vec3<f32>(0.0);
    var trans = 1.0;
    var depth_half = 1.0e30;
    var done = !in_image;
    var samples = 0u;
    // Rays composite only from `near` (RenderParams::depth_near, a cropping region's start)
    // to `limit` (RenderParams::depth_limit: opaque geometry or the region's end), as the CPU
    // Compositor: depth_limit holds the far depths of all pixels, then the near ones.
    var limit = 3.0e38;
    var near = 0.0;
    if (P.has_limit != 0u && in_image) {
        limit = depth_limit[j * P.width + i];
        near = depth_limit[(P.height + j) * P.width + i];
        // An empty range composites nothing: done before it starts (Compositor::between).
        done = limit <= near;
    }

    // Per sample of the span: Σ V A W (or Σ m W for the density field) and Σ V W.
    var weighted: array<f32, MAXS>;
    var shepard: array<f32, MAXS>;
    let is_density = P.field == FIELD_DENSITY;

    var guarded = false;
    let s1 = bundle_cells[b] + span_count[b];
    // Where this dispatch starts: the first span, or where an earlier dispatch stopped.
    let nb = P.bundles_x * P.bundles_y;
    if (li == 0u) {
        wg_resume = atomicLoad(&resume[1u + b]);
        wg_resume_chunk = atomicLoad(&resume[1u + nb + b]);
    }
    let resume_at = workgroupUniformLoad(&wg_resume);
    let resume_chunk = workgroupUniformLoad(&wg_resume_chunk);
    // What the host could keep: the rays' state (else nothing stops; the guard refuses), and
    // the span sums (else bundles stop only before spans).
    // (Divided, not multiplied: nb 128 MAXS passes 32 bits from about 8K x 8K on.)
    let resumable = arrayLength(&ray_state) / 128u >= nb;
    let chunked = resumable && arrayLength(&chunk_sums) / (128u * MAXS) >= band_bundles;
    let sums_at = (q * 64u + li) * 2u * MAXS;
    if (resume_at == RESUME_DONE) {
        return;
    }
    var s0 = bundle_cells[b];
    let st = 2u * (b * 64u + li);
    if (resume_at != RESUME_FRESH) {
        s0 = resume_at;
        let a = ray_state[st];
        let c = ray_state[st + 1u];
        color = a.xyz;
        trans = a.w;
        depth_half = c.x;
        samples = bitcast<u32>(c.y);
        done = c.z != 0.0;
    }
    tick(1u);
    var budget = 1u; // the ticks of the spans begun, bounded alike in every invocation
    for (var s = s0; s < s1; s = s + 1u) {
        tick(1u);
        budget = budget + 1u;
        if (li == 0u) {
            atomicStore(&all_done, 0u);
        }
        workgroupBarrier();
        if (done) {
            atomicAdd(&all_done, 1u);
        }
        workgroupBarrier();
        if (li == 0u) {
            done_flag = atomicLoad(&all_done);
        }
        let n_done = workgroupUniformLoad(&done_flag);
        if (n_done == 64u) {
            break;
        }
        let span = spans[s];
        var ref_count = 0u;
        // The chunk this invocation starts the span at: where an earlier one stopped in it.
        var c_start = 0u;
        if (s == s0 && resume_at != RESUME_FRESH) {
            c_start = resume_chunk;
        }
        if (span.superpixel == 0u) {
            ref_count = span_refs(span.first, span.count);
            let whole = span_head(span) + chunks_cost(span, ref_count) + span_tail(span);
            if (resumable && !chunked && budget + whole > P.loop_limit) {
                if (s > s0) {
                    // Stop before this span; the next dispatch resumes here.
                    suspend(st, color, trans, depth_half, samples, done, guarded, li, b, nb, s,
                            0u);
                    return;
                }
                if (band.w != 0u) {
                    defer_span(st, color, trans, depth_half, samples, done, li, b, nb, s);
                    return;
                }
            }
            budget = budget + span_head(span);
        }
        if (span.superpixel == 1u) {
            if (!done) {
                let z0 = depths[span.k0];
                let z1 = depths[span.k0 + span.n * span.step];
                var it = span.sp;
                if (z0 >= limit) {
                    done = true;
                } else if (z1 > near) {
                    let za = max(z0, near);
                    let zb = min(z1, limit);
                    if (za > z0 || zb < z1) {
                        // Cut as a homogeneous segment: T^f, I (1 - T^f) / (1 - T).
                        let f = (zb - za) / (z1 - z0);
                        let t = pow(it.w, f);
                        var sc = f;
                        if (it.w < 1.0) { sc = (1.0 - t) / (1.0 - it.w); }
                        it = vec4<f32>(it.xyz * sc, t);
                        done = zb < z1;
                    }
                    color = color + trans * it.xyz;
                    trans = trans * it.w;
                    if (trans < 0.5 && depth_half > 1.0e29) {
                        depth_half = za;
                    }
                    if (trans < P.min_transmittance) {
                        done = true;
                    }
                }
            }
            continue;
        }
        let n = span.n;
        workgroupBarrier(); // the previous span's span_z is read no more
        if (li <= n) {
            span_z[li] = depths[span.k0 + li * span.step];
        }
        if (li == 0u && n == 64u) {
            span_z[64] = depths[span.k0 + 64u * span.step];
        }
        tick(n + 1u);
        for (var m = 0u; m < n; m = m + 1u) { // only samples 0..n are used
            weighted[m] = 0.0;
            shepard[m] = 0.0;
            if (c_start > 0u) {
                weighted[m] = chunk_sums[sums_at + m];
                shepard[m] = chunk_sums[sums_at + MAXS + m];
            }
        }
        tick(1u);
        for (var c0 = c_start; c0 < ref_count; c0 = c0 + CHUNK) {
            let cn = min(CHUNK, ref_count - c0);
            let progress = s > s0 || c0 > c_start;
            if (chunked && progress && budget + chunk_cost(span, cn) + span_tail(span) > P.loop_limit) {
                // Stop before this chunk, keeping the span's sums; the next dispatch resumes.
                for (var m = 0u; m < n; m = m + 1u) {
                    chunk_sums[sums_at + m] = weighted[m];
                    chunk_sums[sums_at + MAXS + m] = shepard[m];
                }
                suspend(st, color, trans, depth_half, samples, done, guarded, li, b, nb, s, c0);
                return;
            }
            budget = budget + chunk_cost(span, cn);
            tick(2u); // this loop and the exit of the k loop
            workgroupBarrier();
            tick(span.count + 1u); // span_ref, in the invocations that load
            if (li < cn) {
                let pid = span_ref(span.first, span.count, c0 + li);
                let pa = particles[2u * pid];
                cache_a[li] = pa;
                cache_b[li] = particles[2u * pid + 1u];
                // Every ray's support interval lies in the slab of view depths
                // [c.z - H, c.z + H] (padded for rounding), so the samples to visit are the
                // same for all rays of the bundle: a uniform loop, short and countable.
                let pad = 1.0e-4 * pa.w + 1.0e-6 * abs(pa.z);
                cache_m[li] = vec2<u32>(samples_below(n, pa.z - pa.w - pad, false),
                                        samples_below(n, pa.z + pa.w + pad, true));
            }
            workgroupBarrier();
            // The chunk, then the rest of the span, at most: stop before the driver would.
            if (!done && over_budget(cn * (n + 2u) + 2u * n + 2u * span.count + 16u)) {
                guarded = true;
                done = true;
            }
            if (!done) {
                for (var k = 0u; k < cn; k = k + 1u) {
                    let pa = cache_a[k];
                    let pb = cache_b[k];
                    let m0 = cache_m[k].x;
                    let m1 = cache_m[k].y;
                    tick(2u + m1 - m0); // the k loop and the m loop, which also counts its exit
                    // The support interval from the closest approach (Ray::passage):
                    // no h² − |o − c|² cancellation, so f32 loses only ~1e-5 H at the edge.
                    let oc = pa.xyz - o;
                    let tc = dot(d, oc) / dd;
                    let perp = oc - tc * d;
                    let r2 = dot(perp, perp);
                    let h2 = pa.w * pa.w;
                    let hits = r2 < h2;
                    let half = sqrt(max(h2 - r2, 0.0) / dd);
                    let z0 = tc - half;
                    let z1 = tc + half;
                    for (var m = m0; m < m1; m = m + 1u) {
                        let z = span_z[m];
                        if (!hits || z < z0 || z > z1) {
                            continue;
                        }
                        let dz = z - tc;
                        let w = kernel_w(sqrt(r2 + dd * dz * dz), pa.w);
                        if (w > 0.0) {
                            weighted[m] = weighted[m] + select(pb.x * pb.y, pb.z, is_density) * w;
                            shepard[m] = shepard[m] + pb.x * w;
                        }
                    }
                }
            }
        }
        budget = budget + n + 1u;
        tick(n + 1u); // compositing, at most n samples
        if (!done) {
            for (var m = 0u; m < n; m = m + 1u) {
                if (shepard[m] <= 0.0) {
                    continue;
                }
                var q = weighted[m] / shepard[m];
                if (P.field == FIELD_SPH) { q = weighted[m]; }
                if (is_density) { q = weighted[m]; }
                if (span_z[m] >= limit) {
                    done = true;
                    break;
                }
                if (span_z[m + 1u] <= near) {
                    continue;
                }
                let za = max(span_z[m], near);
                let zb = min(span_z[m + 1u], limit);
                let ca = tf_eval(q);
                samples = samples + 1u;
                var a = 1.0;
                if (ca.w < 1.0) {
                    a = 1.0 - pow(1.0 - ca.w, (zb - za) * dlen / P.unit_distance);
                }
                color = color + trans * a * ca.xyz;
                trans = trans * (1.0 - a);
                if (trans < 0.5 && depth_half > 1.0e29) {
                    depth_half = za;
                }
                if (trans < P.min_transmittance) {
                    done = true;
                    break;
                }
            }
        }
    }
    if (guarded) {
        atomicOr(&guard[0], 1u);
    }
    if (in_image) {
        let idx = j * P.width + i;
        out_rgba[idx] = vec4<f32>(color, 1.0 - trans);
        out_depth[idx] = depth_half;
    }
    // The bundle's sample count, summed in workgroup memory (one value read back per bundle).
    if (li == 0u) {
        atomicStore(&wg_samples, 0u);
    }
    workgroupBarrier();
    atomicAdd(&wg_samples, samples);
    workgroupBarrier();
    if (li == 0u) {
        out_samples[b] = atomicLoad(&wg_samples);
        atomicStore(&resume[1u + b], RESUME_DONE);
    }
}
