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
    query_bound: u32,     // loop iterations one point query may take at most (its exits too)
    shadows: u32,         // 1: single scattering with shadows
    shadow_samples: u32,
    light: vec4<f32>,     // toward the light (unit, world)
    ambient: f32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
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

/// Marcher::offset: the offset of pixel (i, j) in a pass for a random stream.
fn offset(i: u32, j: u32, pass_index: u32, stream: u32) -> f32 {
    if (R.noise == NOISE_WHITE) {
        return white_offset(i, j, pass_index, R.seed ^ stream);
    }
    return blue_offset(i, j, pass_index, R.seed ^ stream);
}

/// Phi (x) and the sums of phi theta (yzw) at x: the Gaussians of the particles whose
/// spheres hold x, found by a depth-first walk of the boxes that hold it. Its loops are not
/// counted one by one: on a software driver the loop limit counts a SIMD batch's iterations,
/// which lanes walking different paths do not bound; the callers charge every query the
/// most any query can take (R.query_bound), the same for every lane, before they run it.
fn field_at(x: vec3<f32>) -> vec4<f32> {
    var acc = vec4<f32>(0.0);
    var stack: array<u32, 40>;
    var top = 0u;
    var node = 1u;
    loop {
        let lo = boxes[2u * node].xyz;
        let hi = boxes[2u * node + 1u].xyz;
        if (all(x >= lo) && all(x <= hi)) {
            if (node >= R.first_leaf) {
                let first = (node - R.first_leaf) * R.leaf_size;
                let last = min(first + R.leaf_size, R.n_slots);
                for (var s = first; s < last; s = s + 1u) {
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

/// Where the ray o + t d crosses the root box, from t = 0 on (t0 > t1: it misses).
fn root_span(o: vec3<f32>, d: vec3<f32>) -> vec2<f32> {
    let inv = 1.0 / d;
    let a0 = (R.root_lo.xyz - o) * inv;
    let a1 = (R.root_hi.xyz - o) * inv;
    let t0 = max(max(max(min(a0.x, a1.x), min(a0.y, a1.y)), min(a0.z, a1.z)), 0.0);
    let t1 = min(min(max(a0.x, a1.x), max(a0.y, a1.y)), max(a0.z, a1.z));
    return vec2<f32>(t0, t1);
}

/// One emission-absorption pass (Marcher::march): colour, transmittance, the view depth
/// where the transmittance fell below 1/2, and, when `stop_at` >= 0, the first sample whose
/// accumulated opacity reaches it (else the last composited one): its t and colour.
struct Pass {
    c: vec3<f32>,
    tr: f32,
    z: f32,
    shade_t: f32,
    shade_rgb: vec3<f32>,
};

fn march(o: vec3<f32>, d: vec3<f32>, span: vec2<f32>, xi: f32, stop_at: f32) -> Pass {
    var out = Pass(vec3<f32>(0.0), 1.0, 1.0e30, 0.0, vec3<f32>(0.0));
    let dt = R.step / length(d);
    var k = ceil(span.x / dt - xi);
    loop {
        let t = (k + xi) * dt;
        if (t > span.y) {
            break;
        }
        if (over_budget(R.query_bound + 1u)) {
            atomicStore(&guard[0], 1u);
            break;
        }
        tick(R.query_bound + 1u);
        let s = field_at(o + t * d);
        if (s.x > 0.0) {
            let m = classify(s);
            let st = exp(-m.w * R.step);
            out.c = out.c + out.tr * (1.0 - st) * m.xyz;
            out.tr = out.tr * st;
            out.shade_t = t;
            out.shade_rgb = m.xyz;
            if (out.tr < 0.5 && out.z > 1.0e29) {
                out.z = t - 0.5 * dt;
            }
            if (out.tr < P.min_transmittance || (stop_at >= 0.0 && 1.0 - out.tr >= stop_at)) {
                break;
            }
        }
        k = k + 1.0;
    }
    return out;
}

/// The transmittance from x toward the light (Marcher::transmittance): a jittered march of
/// the optical depth, stopped once it passes MAX_OPTICAL_DEPTH.
fn transmittance(x: vec3<f32>, xi: f32) -> f32 {
    let l = R.light.xyz;
    let span = root_span(x, l);
    var tau = 0.0;
    var k = 0.0;
    loop {
        let t = (k + xi) * R.step;
        if (t > span.y || span.x > span.y) {
            break;
        }
        if (over_budget(R.query_bound + 1u)) {
            atomicStore(&guard[0], 1u);
            break;
        }
        tick(R.query_bound + 1u);
        let s = field_at(x + t * l);
        if (s.x > 0.0) {
            tau = tau + classify(s).w * R.step;
            if (tau >= MAX_OPTICAL_DEPTH) {
                break;
            }
        }
        k = k + 1.0;
    }
    return exp(-tau);
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
    let span = root_span(o, d);
    let px = j * P.width + i;
    var sum = vec4<f32>(0.0);
    var z = 1.0e30;
    for (var pi = R.first_pass; pi < R.first_pass + R.spp && span.x <= span.y; pi = pi + 1u) {
        var p = march(o, d, span, offset(i, j, pi, 0u), -1.0);
        let opacity = 1.0 - p.tr;
        if (R.shadows != 0u && opacity > 0.0) {
            // Single scattering (Marcher::lit_pass): the shade point where the accumulated
            // opacity reaches a random share of the pass's, lit through shadow rays.
            let pick = offset(i, j, pi, PICK_STREAM) * opacity;
            let sp = march(o, d, span, offset(i, j, pi, 0u), pick);
            let x = o + sp.shade_t * d;
            var lit = 0.0;
            for (var s = 0u; s < R.shadow_samples; s = s + 1u) {
                let xs = offset(i, j, pi * R.shadow_samples + s, SHADOW_STREAM);
                lit = lit + transmittance(x, xs);
            }
            lit = lit / f32(R.shadow_samples);
            p.c = opacity * sp.shade_rgb * (R.ambient + (1.0 - R.ambient) * lit);
        }
        if (pi == R.first_pass) {
            z = p.z;
        }
        sum = sum + vec4<f32>(p.c, opacity);
    }
    image[px] = sum / f32(R.spp);
    depth[px] = z;
}
