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
    round: u32,           // dispatches of this render before this one (see `resume`)
    shadows: u32,         // 1: single scattering with shadows
    shadow_samples: u32,
    light: vec4<f32>,     // toward the light (unit, world)
    ambient: f32,
    scatter: u32,         // common.wgsl's scattered_bundle, over the 8 x 8 tiles
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
// A pixel whose queries would pass P.loop_limit (a software driver's limit) in one invocation
// stops before the query and resumes there in the host's next dispatch (R.round > 0), the
// image unchanged: its work (see `Work`) at resume[RESUME_VEC4S px ..]; stopped[0] the pixels
// that stopped in this dispatch.
@group(0) @binding(10) var<storage, read_write> resume: array<vec4<f32>>;
@group(0) @binding(11) var<storage, read_write> stopped: array<atomic<u32>>;

const RESUME_VEC4S: u32 = 6u;
// What a pixel does next: its pass's march, the march to the shade point, a shadow ray; done.
const PH_MARCH: u32 = 0u;
const PH_PICK: u32 = 1u;
const PH_SHADOW: u32 = 2u;
const PH_DONE: u32 = 3u;

// Point queries completed by this invocation (a query that ran out of budget, see
// `take_iteration` in common.wgsl, has its sum unused).
var<private> queries_done: u32 = 0u;

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

/// The field's sums at `x`: (Σ φ, Σ φ θ) over the spheres that hold it, a BVH point query.
/// Every loop iteration (and each loop's exit) is taken from the invocation's budget; where
/// it runs out the query stops with out_of_budget set, to be run again in the next dispatch.
fn field_at(x: vec3<f32>) -> vec4<f32> {
    var acc = vec4<f32>(0.0);
    var stack: array<u32, 40>;
    var top = 0u;
    var node = 1u;
    if (!take_iteration()) { // the loop's exit
        return acc;
    }
    loop {
        if (!take_iteration()) {
            return acc;
        }
        let lo = boxes[2u * node].xyz;
        let hi = boxes[2u * node + 1u].xyz;
        if (all(x >= lo) && all(x <= hi)) {
            if (node >= R.first_leaf) {
                let first = (node - R.first_leaf) * R.leaf_size;
                let last = min(first + R.leaf_size, R.n_slots);
                if (!take_iteration()) { // the leaf loop's exit
                    return acc;
                }
                for (var s = first; s < last; s = s + 1u) {
                    if (!take_iteration()) {
                        return acc;
                    }
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
    queries_done = queries_done + 1u;
    return acc;
}

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

/// A march in progress (Marcher::march): colour, transmittance, the view depth where the
/// transmittance fell below 1/2, the last composited sample's t and colour (with a `stop_at`,
/// the shade point), and the index k of the next sample, at t_k = (k + xi) dt.
struct March {
    c: vec3<f32>,
    tr: f32,
    z: f32,
    shade_t: f32,
    shade_rgb: vec3<f32>,
    k: f32,
};

fn march_start(d: vec3<f32>, span: vec2<f32>, xi: f32) -> March {
    let dt = R.step / length(d);
    return March(vec3<f32>(0.0), 1.0, 1.0e30, 0.0, vec3<f32>(0.0), ceil(span.x / dt - xi));
}

/// Continues `m` along o + t d up to span.y, or until the transmittance falls below the
/// minimum, or (`stop_at` >= 0) the accumulated opacity reaches `stop_at`: true when done,
/// false when the loop budget ran out before a sample (resume at m.k).
fn march(o: vec3<f32>, d: vec3<f32>, span: vec2<f32>, xi: f32, stop_at: f32,
         m: ptr<function, March>) -> bool {
    let dt = R.step / length(d);
    loop {
        let t = ((*m).k + xi) * dt;
        if (t > span.y) {
            return true;
        }
        if (!take_iteration()) {
            return false;
        }
        let s = field_at(o + t * d);
        if (out_of_budget) {
            return false;
        }
        if (s.x > 0.0) {
            let c = classify(s);
            let st = exp(-c.w * R.step);
            (*m).c = (*m).c + (*m).tr * (1.0 - st) * c.xyz;
            (*m).tr = (*m).tr * st;
            (*m).shade_t = t;
            (*m).shade_rgb = c.xyz;
            if ((*m).tr < 0.5 && (*m).z > 1.0e29) {
                (*m).z = t - 0.5 * dt;
            }
            if ((*m).tr < P.min_transmittance || (stop_at >= 0.0 && 1.0 - (*m).tr >= stop_at)) {
                return true;
            }
        }
        (*m).k = (*m).k + 1.0;
    }
    return true;
}

/// Continues the optical depth `tau` from x toward the light (Marcher::transmittance: a
/// jittered march, stopped once it passes MAX_OPTICAL_DEPTH) from sample `k`: true when
/// done, false when the loop budget ran out (resume at k).
fn transmittance(x: vec3<f32>, xi: f32, tau: ptr<function, f32>, k: ptr<function, f32>) -> bool {
    let l = R.light.xyz;
    let span = root_span(x, l);
    loop {
        let t = (*k + xi) * R.step;
        if (t > span.y || span.x > span.y) {
            return true;
        }
        if (!take_iteration()) {
            return false;
        }
        let s = field_at(x + t * l);
        if (out_of_budget) {
            return false;
        }
        if (s.x > 0.0) {
            *tau = *tau + classify(s).w * R.step;
            if (*tau >= MAX_OPTICAL_DEPTH) {
                return true;
            }
        }
        *k = *k + 1.0;
    }
    return true;
}

/// A pixel's work in progress: pass `pi`, what it does next (`phase`), the march running
/// (its k also that of shadow ray `s`), the pass's opacity, the shadow ray's optical depth
/// and the transmittances summed, the passes' sum and the first pass's depth.
struct Work {
    pi: u32,
    phase: u32,
    s: u32,
    m: March,
    opacity: f32,
    tau: f32,
    lit: f32,
    sum: vec4<f32>,
    zfirst: f32,
};

fn save_work(px: u32, w: Work) {
    let r = RESUME_VEC4S * px;
    resume[r] = vec4<f32>(bitcast<f32>(w.pi), bitcast<f32>(w.phase), bitcast<f32>(w.s), w.m.k);
    resume[r + 1u] = vec4<f32>(w.m.c, w.m.tr);
    resume[r + 2u] = vec4<f32>(w.m.z, w.m.shade_t, w.tau, w.lit);
    resume[r + 3u] = vec4<f32>(w.m.shade_rgb, w.opacity);
    resume[r + 4u] = w.sum;
    resume[r + 5u] = vec4<f32>(w.zfirst, 0.0, 0.0, 0.0);
}

fn load_work(px: u32) -> Work {
    let r = RESUME_VEC4S * px;
    let a = resume[r];
    let b = resume[r + 1u];
    let c = resume[r + 2u];
    let e = resume[r + 3u];
    let m = March(b.xyz, b.w, c.x, c.y, e.xyz, a.w);
    return Work(bitcast<u32>(a.x), bitcast<u32>(a.y), bitcast<u32>(a.z), m, e.w, c.z, c.w,
                resume[r + 4u], resume[r + 5u].x);
}

/// Ends pass w.pi with colour `c` (the pass's opacity from its first march) and starts the next.
fn next_pass(w: ptr<function, Work>, c: vec3<f32>, d: vec3<f32>, span: vec2<f32>, i: u32,
             j: u32) {
    (*w).sum = (*w).sum + vec4<f32>(c, (*w).opacity);
    (*w).pi = (*w).pi + 1u;
    (*w).phase = PH_MARCH;
    (*w).m = march_start(d, span, offset(i, j, (*w).pi, 0u));
}

/// Runs the pixel's passes from where `w` is (Marcher's passes, shade points and shadow rays,
/// in the CPU's order): true when all are done, false when the loop budget ran out.
fn run(w: ptr<function, Work>, o: vec3<f32>, d: vec3<f32>, span: vec2<f32>, i: u32,
       j: u32) -> bool {
    loop {
        let pi = (*w).pi;
        if (pi >= R.first_pass + R.spp || span.x > span.y) {
            return true;
        }
        let xi = offset(i, j, pi, 0u);
        var m = (*w).m;
        if ((*w).phase == PH_MARCH) {
            let done = march(o, d, span, xi, -1.0, &m);
            (*w).m = m;
            if (!done) {
                return false;
            }
            (*w).opacity = 1.0 - m.tr;
            if (pi == R.first_pass) {
                (*w).zfirst = m.z;
            }
            if (R.shadows != 0u && (*w).opacity > 0.0) {
                // Single scattering (Marcher::lit_pass): the shade point where the accumulated
                // opacity reaches a random share of the pass's, lit through shadow rays.
                (*w).phase = PH_PICK;
                (*w).m = march_start(d, span, xi);
            } else {
                next_pass(w, m.c, d, span, i, j);
            }
            continue;
        }
        if ((*w).phase == PH_PICK) {
            let pick = offset(i, j, pi, PICK_STREAM) * (*w).opacity;
            let done = march(o, d, span, xi, pick, &m);
            (*w).m = m;
            if (!done) {
                return false;
            }
            (*w).phase = PH_SHADOW;
            (*w).s = 0u;
            (*w).lit = 0.0;
            (*w).tau = 0.0;
            (*w).m.k = 0.0;
            continue;
        }
        if ((*w).s < R.shadow_samples) {
            let x = o + m.shade_t * d;
            let xs = offset(i, j, pi * R.shadow_samples + (*w).s, SHADOW_STREAM);
            var tau = (*w).tau;
            var k = m.k;
            let done = transmittance(x, xs, &tau, &k);
            (*w).tau = tau;
            (*w).m.k = k;
            if (!done) {
                return false;
            }
            (*w).lit = (*w).lit + exp(-tau);
            (*w).s = (*w).s + 1u;
            (*w).tau = 0.0;
            (*w).m.k = 0.0;
            continue;
        }
        let lit = (*w).lit / f32(R.shadow_samples);
        next_pass(w, (*w).opacity * m.shade_rgb * (R.ambient + (1.0 - R.ambient) * lit), d,
                  span, i, j);
    }
    return true;
}

@compute @workgroup_size(8, 8)
fn main(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>,
        @builtin(num_workgroups) nw: vec3<u32>) {
    let tiles_x = (P.width + 7u) / 8u;
    let tiles = tiles_x * ((P.height + 7u) / 8u);
    let q = scattered_bundle(wg.y * nw.x + wg.x, tiles, R.scatter);
    let i = (q % tiles_x) * 8u + lid.x;
    let j = (q / tiles_x) * 8u + lid.y;
    if (q == 0xffffffffu || i >= P.width || j >= P.height) {
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
    var w: Work;
    if (R.round == 0u) {
        let m = march_start(d, span, offset(i, j, R.first_pass, 0u));
        w = Work(R.first_pass, PH_MARCH, 0u, m, 0.0, 0.0, 0.0, vec4<f32>(0.0), 1.0e30);
    } else {
        w = load_work(px);
        if (w.phase == PH_DONE) {
            return;
        }
    }
    if (!run(&w, o, d, span, i, j)) {
        let resumable = arrayLength(&resume) / RESUME_VEC4S >= P.width * P.height;
        if (queries_done == 0u || !resumable) {
            // Not one query fits the driver's limit: refused (the host reads the guard).
            atomicStore(&guard[0], 1u);
        }
        save_work(px, w);
        atomicAdd(&stopped[0], 1u);
        return;
    }
    image[px] = w.sum / f32(R.spp);
    depth[px] = w.zfirst;
    if (P.loop_limit != 0xffffffffu) {
        resume[RESUME_VEC4S * px + 0u].y = bitcast<f32>(PH_DONE);
    }
}
