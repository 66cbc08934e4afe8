// Exclusive prefix sum of u32 in place, 256 elements per workgroup (`prefix_v4`, from
// prefix_barriers.wgsl or prefix_subgroups.wgsl, prepended). `scan_blocks` scans each block and
// writes its total to `sums`; the Rust side scans `sums` the same way (recursively) and
// `add_sums` adds each block's offset back.

struct ScanParams {
    n: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
};

@group(0) @binding(0) var<uniform> S: ScanParams;
@group(0) @binding(1) var<storage, read_write> data: array<u32>;
@group(0) @binding(2) var<storage, read_write> sums: array<u32>;

@compute @workgroup_size(256)
fn scan_blocks(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) nw: vec3<u32>,
               lane: Lane) {
    let g = wg.y * nw.x + wg.x;
    let e = element(lane);
    let i = g * 256u + e;
    var v = 0u;
    if (i < S.n) {
        v = data[i];
    }
    let before = prefix_v4(vec4<u32>(v, 0u, 0u, 0u), lane).x;
    if (i < S.n) {
        data[i] = before;
    }
    if (e == 255u && g * 256u < S.n) {
        sums[g] = before + v;
    }
}

@compute @workgroup_size(256)
fn add_sums(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) nw: vec3<u32>,
            @builtin(local_invocation_index) li: u32) {
    let g = wg.y * nw.x + wg.x;
    let i = g * 256u + li;
    if (i < S.n) {
        data[i] = data[i] + sums[g];
    }
}
