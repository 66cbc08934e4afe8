// Exclusive prefix sums over a workgroup of 256 invocations, in workgroup memory (Hillis–Steele:
// 8 rounds, 16 barriers): for adapters without subgroup operations. prefix_subgroups.wgsl is
// the other variant; the Rust side prepends one of the two to scan.wgsl and sort.wgsl, which
// read an invocation's element of its block through `element` and sum through `prefix_v4`.

// The builtins an invocation's element and the prefix sums read.
struct Lane {
    @builtin(local_invocation_index) li: u32,
};

// The element of its workgroup's block of 256 that the invocation holds.
fn element(l: Lane) -> u32 {
    return l.li;
}

var<workgroup> prefix_tmp: array<vec4<u32>, 256>;

// The sum of `v` over the invocations holding the elements before this one's (u32 arithmetic,
// wrapping). Called by every invocation of the workgroup (it has barriers).
fn prefix_v4(v: vec4<u32>, l: Lane) -> vec4<u32> {
    prefix_tmp[l.li] = v;
    workgroupBarrier();
    for (var o = 1u; o < 256u; o = o * 2u) {
        var t = vec4<u32>(0u);
        if (l.li >= o) {
            t = prefix_tmp[l.li - o];
        }
        workgroupBarrier();
        prefix_tmp[l.li] = prefix_tmp[l.li] + t;
        workgroupBarrier();
    }
    return prefix_tmp[l.li] - v;
}
