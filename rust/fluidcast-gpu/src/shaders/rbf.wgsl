// The attribute-aware RBF field, ray marched (fluidcast_render::render_rbf's emission-
// absorption passes, in single precision): one invocation a pixel, its passes' samples at
// t_k = (k + xi) dt along the ray, each a point range query through the BVH of Hilbert-ordered
// clusters (fluidcast_rbf::ClusterBvh::for_each_within) summing the truncated Gaussians
// (fluidcast_rbf::rbf). Prepended: the RBF_*, NOISE_* and HASH_* constants (from the Rust
// enums and constants) and common.wgsl (the frame P, the transfer function, the loop guard).

struct Rbf {
    root_lo: vec4<f32>,   // the BVH's root box (world)
    root_hi: vec4<f32>,
    step: f32,            // world step along the rays
    first_leaf: u32,      // node index of cluster 0 (heap order: children 2k, 2k + 1)
    n_slots: u32,         // particles (slots in Hilbert order)
    leaf_size: u32,
    spp: u32,
    first_pass: u32,
    seed: u32,
    colouring: u32,       // RBF_POST, RBF_PRE or RBF_DENSITY
    noise: u32,           // NOISE_BLUE or NOISE_WHITE
    query_bound: u32,     // loop iterations one point query may take at most
    pad0: u32,
    pad1: u32,
};

@group(0) @binding(2) var<uniform> R: Rbf;
// Per node: lo (xyz), then hi (xyz); an empty box has lo > hi.
@group(0) @binding(3) var<storage, read> boxes: array<vec4<f32>>;
// Per slot: centre (xyz) and radius (w), world units.
@group(0) @binding(4) var<storage, read> spheres: array<vec4<f32>>;
// Per slot: the weight w (x) and theta (yzw: the attribute, or its colour).
@group(0) @binding(5) var<storage, read> attrs: array<vec4<f32>>;
// The blue-noise mask, BLUE_SIDE x BLUE_SIDE values in [0, 1), row-major.
@group(0) @binding(6) var<storage, read> blue: array<f32>;
// Per pixel, premultiplied RGBA (the mean of the passes), then the first pass's depth.
@group(0) @binding(7) var<storage, read_write> image: array<vec4<f32>>;
@group(0) @binding(8) var<storage, read_write> depth: array<f32>;
// [0]: set when a pixel stopped at the loop limit (the host refuses the frame).
@group(0) @binding(9) var<storage, read_write> guard: array<atomic<u32>>;

fn mix32(x0: u32) -> u32 {
    var x = x0;
    x = x ^ (x >> 16u);
    x = x * HASH_MUL0;
    x = x ^ (x >> 15u);
    x = x * HASH_MUL1;
    return x ^ (x >> 16u);
}

fn white_offset(i: u32, j: u32, pass_index: u32, seed: u32) -> f32 {
    var h = seed ^ HASH_SEED;
    h = mix32(h ^ (i * HASH_IN));
    h = mix32(h ^ (j * HASH_IN));
    h = mix32(h ^ (pass_index * HASH_IN));
    return f32(h >> 8u) / 16777216.0;
}

fn blue_offset(i: u32, j: u32, pass_index: u32, stream: u32) -> f32 {
    let h = mix32(stream);
    let x = (i + h % BLUE_SIDE) % BLUE_SIDE;
    let y = (j + (h >> 16u) % BLUE_SIDE) % BLUE_SIDE;
    let v = blue[y * BLUE_SIDE + x] + fract(f32(pass_index) * GOLDEN);
    return fract(v);
}

fn offset(i: u32, j: u32, pass_index: u32) -> f32 {
    if (R.noise == NOISE_WHITE) {
        return white_offset(i, j, pass_index, R.seed);
    }
    return blue_offset(i, j, pass_index, R.seed);
}

/// Phi (x) and the sums of phi theta (yzw) at x: the Gaussians of the particles whose
/// spheres hold x, found by a depth-first walk of the boxes that hold it.
fn field_at(x: vec3<f32>) -> vec4<f32> {
    var acc = vec4<f32>(0.0);
    var stack: array<u32, 40>;
    var top = 0u;
    var node = 1u;
    loop {
        tick(1u);
        let lo = boxes[2u * node].xyz;
        let hi = boxes[2u * node + 1u].xyz;
        if (all(x >= lo) && all(x <= hi)) {
            if (node >= R.first_leaf) {
                let first = (node - R.first_leaf) * R.leaf_size;
                let last = min(first + R.leaf_size, R.n_slots);
                for (var s = first; s < last; s = s + 1u) {
                    tick(1u);
                    let sp = spheres[s];
                    let d = distance(x, sp.xyz);
                    if (sp.w > 0.0 && d <= sp.w) {
                        let u = SIGMAS * d / sp.w;
                        let a = attrs[s];
                        let phi = a.x * exp(-0.5 * u * u);
                        acc = acc + phi * vec4<f32>(1.0, a.yzw);
                    }
                }
            } else if (top < 40u) {
                stack[top] = 2u * node + 1u;
                top = top + 1u;
                node = 2u * node;
                continue;
            }
        }
        if (top == 0u) {
            break;
        }
        top = top - 1u;
        node = stack[top];
    }
    return acc;
}

/// A sample's colour (rgb) and extinction per world unit (w), as Marcher::classify.
fn classify(s: vec4<f32>) -> vec4<f32> {
    if (R.colouring == RBF_POST) {
        return vec4<f32>(tf_eval(s.y / s.x).xyz, s.x / P.unit_distance);
    }
    if (R.colouring == RBF_PRE) {
        return vec4<f32>(s.yzw / s.x, s.x / P.unit_distance);
    }
    let c = tf_eval(s.x);
    var k = K_INF;
    if (c.w < 1.0) {
        k = -log(1.0 - c.w) / P.unit_distance;
    }
    return vec4<f32>(c.xyz, k);
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    let j = gid.y;
    if (i >= P.width || j >= P.height) {
        return;
    }
    // ViewFrame::ray: the ray through the pixel centre, with d . forward = 1.
    let nx = 2.0 * (f32(i) + 0.5) / f32(P.width) - 1.0;
    let ny = 1.0 - 2.0 * (f32(j) + 0.5) / f32(P.height);
    var o = P.eye.xyz;
    var d = P.forward.xyz;
    if (P.parallel_scale > 0.0) {
        o = o + P.right.xyz * (nx * P.parallel_scale * P.aspect) + P.up.xyz * (ny * P.parallel_scale);
    } else {
        d = d + P.right.xyz * (nx * P.tan_half * P.aspect) + P.up.xyz * (ny * P.tan_half);
    }
    // Where the ray crosses the root box, in front of the eye.
    let inv = 1.0 / d;
    let a0 = (R.root_lo.xyz - o) * inv;
    let a1 = (R.root_hi.xyz - o) * inv;
    let t0 = max(max(max(min(a0.x, a1.x), min(a0.y, a1.y)), min(a0.z, a1.z)), 0.0);
    let t1 = min(min(max(a0.x, a1.x), max(a0.y, a1.y)), max(a0.z, a1.z));
    let px = j * P.width + i;
    var sum = vec4<f32>(0.0);
    var z = 1.0e30;
    let dt = R.step / length(d);
    for (var pass_index = R.first_pass; pass_index < R.first_pass + R.spp && t0 <= t1; pass_index = pass_index + 1u) {
        let xi = offset(i, j, pass_index);
        var k = ceil(t0 / dt - xi);
        var c = vec3<f32>(0.0);
        var tr = 1.0;
        loop {
            let t = (k + xi) * dt;
            if (t > t1) {
                break;
            }
            if (over_budget(R.query_bound + 1u)) {
                atomicStore(&guard[0], 1u);
                break;
            }
            tick(1u);
            let s = field_at(o + t * d);
            if (s.x > 0.0) {
                let m = classify(s);
                let st = exp(-m.w * R.step);
                c = c + tr * (1.0 - st) * m.xyz;
                tr = tr * st;
                if (pass_index == R.first_pass && tr < 0.5 && z > 1.0e29) {
                    z = t - 0.5 * dt;
                }
                if (tr < P.min_transmittance) {
                    break;
                }
            }
            k = k + 1.0;
        }
        sum = sum + vec4<f32>(c, 1.0 - tr);
    }
    image[px] = sum / f32(R.spp);
    depth[px] = z;
}
