// Stable LSD radix sort of (key, value) u32 pairs, 4 bits per pass, 256 elements per workgroup:
// `histogram` counts each block's digits into hist[digit * blocks + block], the Rust side scans
// hist (so digit-major order gives every block its output offset per digit), and `scatter`
// ranks each element among the block's equal digits before it (a prefix sum of one-hot digit
// counters packed 4 × 8 bits per u32: `prefix_v4`, prepended as in scan.wgsl) and writes it to
// its place.

struct SortParams {
    n: u32,
    shift: u32,
    blocks: u32,
    pad: u32,
};

@group(0) @binding(0) var<uniform> R: SortParams;
@group(0) @binding(1) var<storage, read> keys_in: array<u32>;
@group(0) @binding(2) var<storage, read> vals_in: array<u32>;
@group(0) @binding(3) var<storage, read_write> keys_out: array<u32>;
@group(0) @binding(4) var<storage, read_write> vals_out: array<u32>;
@group(0) @binding(5) var<storage, read_write> hist: array<u32>;

var<workgroup> wcount: array<atomic<u32>, 16>;

@compute @workgroup_size(256)
fn histogram(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) nw: vec3<u32>,
             @builtin(local_invocation_index) li: u32) {
    let g = wg.y * nw.x + wg.x;
    if (li < 16u) {
        atomicStore(&wcount[li], 0u);
    }
    workgroupBarrier();
    let i = g * 256u + li;
    if (i < R.n) {
        atomicAdd(&wcount[(keys_in[i] >> R.shift) & 15u], 1u);
    }
    workgroupBarrier();
    if (li < 16u && g < R.blocks) {
        hist[li * R.blocks + g] = atomicLoad(&wcount[li]);
    }
}

@compute @workgroup_size(256)
fn scatter(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) nw: vec3<u32>,
           lane: Lane) {
    let g = wg.y * nw.x + wg.x;
    let i = g * 256u + element(lane);
    let valid = i < R.n;
    var key = 0u;
    var d = 0u;
    var own = vec4<u32>(0u);
    if (valid) {
        key = keys_in[i];
        d = (key >> R.shift) & 15u;
        own[d / 4u] = 1u << (8u * (d % 4u));
    }
    // Exclusive count (< 256, so it fits its byte; u32 arithmetic is exact mod 2^32).
    let ex = prefix_v4(own, lane);
    if (valid) {
        let rank = (ex[d / 4u] >> (8u * (d % 4u))) & 255u;
        let dst = hist[d * R.blocks + g] + rank;
        keys_out[dst] = key;
        vals_out[dst] = vals_in[i];
    }
}
