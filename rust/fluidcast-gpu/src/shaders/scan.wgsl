// Exclusive prefix sum of u32 in place, 256 elements per workgroup (Hillis–Steele in workgroup
// memory). `scan_blocks` scans each block and writes its total to `sums`; the Rust side scans
// `sums` the same way (recursively) and `add_sums` adds each block's offset back.

struct ScanParams {
    n: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
};

@group(0) @binding(0) var<uniform> S: ScanParams;
@group(0) @binding(1) var<storage, read_write> data: array<u32>;
@group(0) @binding(2) var<storage, read_write> sums: array<u32>;

var<workgroup> tmp: array<u32, 256>;

@compute @workgroup_size(256)
fn scan_blocks(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) nw: vec3<u32>,
               @builtin(local_invocation_index) li: u32) {
    let g = wg.y * nw.x + wg.x;
    let i = g * 256u + li;
    var v = 0u;
    if (i < S.n) {
        v = data[i];
    }
    tmp[li] = v;
    workgroupBarrier();
    for (var o = 1u; o < 256u; o = o * 2u) {
        var t = 0u;
        if (li >= o) {
            t = tmp[li - o];
        }
        workgroupBarrier();
        tmp[li] = tmp[li] + t;
        workgroupBarrier();
    }
    if (i < S.n) {
        data[i] = tmp[li] - v;
    }
    if (li == 255u && g * 256u < S.n) {
        sums[g] = tmp[255];
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
