// The image in fewer bytes for the copy back to the host (RenderParams::output): the ray
// caster's f32 RGBA packed into half precision, 8 bytes a pixel instead of 16.

struct PackParams {
    n: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
};

@group(0) @binding(0) var<uniform> K: PackParams;
@group(0) @binding(1) var<storage, read> rgba: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> half_rgba: array<vec2<u32>>;

@compute @workgroup_size(256)
fn pack_half(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) nw: vec3<u32>,
             @builtin(local_invocation_index) li: u32) {
    let i = (wg.y * nw.x + wg.x) * 256u + li;
    if (i >= K.n) {
        return;
    }
    let c = rgba[i];
    half_rgba[i] = vec2<u32>(pack2x16float(c.xy), pack2x16float(c.zw));
}
