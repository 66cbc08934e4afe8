// Exclusive prefix sums over a workgroup of 256 invocations with subgroup operations (naga takes
// them where the device has wgpu's SUBGROUP feature, without WGSL's `enable subgroups`): each
// subgroup's own scan (subgroupExclusiveAdd), then the totals of the subgroups before it from
// workgroup memory (2 barriers instead of prefix_barriers.wgsl's 16). An invocation holds the
// element of its subgroup's place, subgroup by subgroup, so that subgroup order is element order
// whichever invocations the driver puts in a subgroup. Needs full subgroups of 4 to 256
// invocations; the Rust side checks the result on the device before it uses this variant.

// The builtins an invocation's element and the prefix sums read.
struct Lane {
    @builtin(subgroup_id) sg: u32,
    @builtin(subgroup_invocation_id) lane: u32,
    @builtin(subgroup_size) size: u32,
};

// The element of its workgroup's block of 256 that the invocation holds.
fn element(l: Lane) -> u32 {
    return l.sg * l.size + l.lane;
}

// Each subgroup's total (at most 64 subgroups of at least 4).
var<workgroup> prefix_totals: array<vec4<u32>, 64>;

// The sum of `v` over the invocations holding the elements before this one's (u32 arithmetic,
// wrapping). Called by every invocation of the workgroup (it has barriers).
fn prefix_v4(v: vec4<u32>, l: Lane) -> vec4<u32> {
    let own = subgroupExclusiveAdd(v);
    if (l.lane + 1u == l.size && l.sg < 64u) {
        prefix_totals[l.sg] = own + v;
    }
    workgroupBarrier();
    var before = vec4<u32>(0u);
    for (var k = 0u; k < min(l.sg, 64u); k = k + 1u) {
        before = before + prefix_totals[k];
    }
    // The totals are read before any later call writes them again.
    workgroupBarrier();
    return before + own;
}
