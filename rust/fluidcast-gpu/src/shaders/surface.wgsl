// Iso-surfaces of the SPH sum found exactly along each ray (fluidcast_render's surface.rs
// walk, in single precision): one invocation a pixel, one workgroup a ray bundle. The ray's
// iso field is summed at the frame's depth samples from its bundle's grid cells (every
// particle whose support reaches a sample is in that sample's cell); where consecutive
// samples lie on either side of an iso value the crossing is refined on the exact sum
// (Illinois regula falsi), where a sample is a local extremum short of a value the extremum
// between its neighbours is searched (golden section) for crossings hidden between samples,
// and each crossing is shaded with the analytic gradient and composited front to back.
// Surfaces only: the volume in front of opaque surfaces is the adaptive renderer's.
// Prepended: the ISO_* constants and MAX_ISO_VALUES (from Rust) and common.wgsl.

struct Surf {
    values: vec4<f32>,    // the iso values (the first n_values)
    colour: vec4<f32>,    // a solid colour (w = 1), or the transfer function's (w = 0)
    light: vec4<f32>,     // toward the light (world, unit; w = 1), or a headlight (w = 0)
    ambient: f32,
    diffuse: f32,
    specular: f32,
    specular_power: f32,
    n_values: u32,
    iso: u32,             // ISO_COLOUR, ISO_DENSITY or ISO_ATTRIBUTE
    has_b: u32,           // 1: the iso attribute from `iso_b`, else the rendered one
    opacity: f32,
    round: u32,           // dispatches of this band before this one (see `resume`)
    band_y0: u32,         // the band's first row of bundles (dispatches cover bands of rows)
    band_rows: u32,       // its rows of bundles
    scatter: u32,         // common.wgsl's scattered_bundle
};

@group(0) @binding(2) var<uniform> S: Surf;
@group(0) @binding(3) var<storage, read> particles: array<vec4<f32>>; // view space: (c.xyz, h), (v, a, m, 0)
@group(0) @binding(4) var<storage, read> depths: array<f32>;
@group(0) @binding(5) var<storage, read> cells: array<Cell>;
@group(0) @binding(6) var<storage, read> refs: array<u32>;
@group(0) @binding(7) var<storage, read> bundle_cells: array<u32>;
@group(0) @binding(8) var<storage, read> iso_b: array<f32>;
// The far depth of every pixel, then the near one (P.has_limit bit 0).
@group(0) @binding(9) var<storage, read> depth_limit: array<f32>;
// Per pixel: premultiplied RGBA, the first surface's depth (1e30: none) and world normal.
@group(0) @binding(10) var<storage, read_write> out_rgba: array<vec4<f32>>;
@group(0) @binding(11) var<storage, read_write> out_depth: array<f32>;
@group(0) @binding(12) var<storage, read_write> out_normal: array<vec4<f32>>;
// [0]: set when a pixel could not take one step within P.loop_limit (the host refuses).
@group(0) @binding(13) var<storage, read_write> guard: array<atomic<u32>>;
// A pixel whose walk would pass P.loop_limit (a software driver's limit) in one invocation
// stops before the field evaluation that would pass it and resumes there in the host's next
// dispatch of its band (S.round > 0), the image unchanged: its walk at
// resume[p], p its index within the band; stopped[0] the pixels that stopped
// in this dispatch.
@group(0) @binding(14) var<storage, read_write> resume: array<Walk>;
@group(0) @binding(15) var<storage, read_write> stopped: array<atomic<u32>>;

const PENDING: u32 = 5u * MAX_ISO_VALUES; // crossings found but not yet composited
const UNDEF: f32 = -3.0e38;   // a CSPH quotient where no particle reaches
const GOLDEN: f32 = 0.618033988749895;
const REFINE_ITERATIONS: u32 = 40u;
const GOLDEN_ITERATIONS: u32 = 30u;
// What a pixel's walk does next.
const PH_EVAL: u32 = 0u;    // sum the field at sample k
const PH_CROSS: u32 = 1u;   // crossings of step k - 2, value vi
const PH_REFINE: u32 = 2u;  // one iteration of a crossing's refinement
const PH_HIDDEN: u32 = 3u;  // is sample k - 1 an extremum short of a value?
const PH_GOLDEN: u32 = 4u;  // one evaluation of the extremum's search
const PH_BEYOND: u32 = 5u;  // refine the crossings on either side of the extremum
const PH_SHADE: u32 = 6u;   // composite the crossings before sample k - 1
const PH_DONE: u32 = 7u;

/// The walk of one ray: where it is, the field at the last three samples (f[k-3], f[k-2],
/// f[k-1]), the refinement and the extremum search under way, the crossings pending (by
/// depth; bit i of `rising` for pend[i]) and the compositing state.
struct Walk {
    phase: u32,
    k: u32,
    vi: u32,
    ret: u32,
    fa: f32,
    fb: f32,
    fc: f32,
    flags: u32,        // bit 0: the extremum is a maximum; bit 1: its right side next; bit 2: rising
    ra: f32,           // refinement: bracket (ra, rga) .. (rb, rgb), its start and end, value
    rga: f32,
    rb: f32,
    rgb: f32,
    rz0: f32,
    rz1: f32,
    rv: f32,
    rit: u32,          // iterations, and which end was kept (bits 8..)
    ga: f32,           // golden section: a, b, c, d, f(c), f(d), iteration; extremum (ze, fe)
    gb: f32,
    gc: f32,
    gd: f32,
    gfc: f32,
    gfd: f32,
    git: u32,
    ze: f32,
    fe: f32,
    np: u32,
    rising: u32,
    colour: vec3<f32>,
    trans: f32,
    normal: vec3<f32>, // (after colour and trans: 16-byte aligned without padding)
    zfirst: f32,
    pend: array<f32, PENDING>,
};

/// The sums at one point: the iso field's numerator and the Shepard sum with their view-space
/// gradients, and the rendered field's numerator.
struct Sums {
    iso: f32,
    shep: f32,
    rend: f32,
    g_iso: vec3<f32>,
    g_shep: vec3<f32>,
};

/// norm(H): the kernel is norm(H) shape(q) (fluidcast_sph::Kernel::norm).
fn kernel_norm(h: f32) -> f32 {
    let h3 = h * h * h;
    switch P.kernel {
        case KERNEL_CUBIC: { return 8.0 / (PI * h3); }
        case KERNEL_QUINTIC: { return 27.0 / (120.0 * PI * h3); }
        case KERNEL_WENDLAND_C2: { return 21.0 / (2.0 * PI * h3); }
        case KERNEL_WENDLAND_C4: { return 495.0 / (32.0 * PI * h3); }
        case KERNEL_POLY6: { return 315.0 / (64.0 * PI * h3); }
        default: { return 27.0 / (P.gauss_norm * h3); } // σ = H/3
    }
}

/// d shape / dq (fluidcast_sph::Kernel::shape_slope), for q in [0, 1).
fn shape_slope(q: f32) -> f32 {
    let t = 1.0 - q;
    switch P.kernel {
        case KERNEL_CUBIC: {
            if (q <= 0.5) { return 18.0 * q * q - 12.0 * q; }
            return -6.0 * t * t;
        }
        case KERNEL_QUINTIC: {
            let s = 3.0 * q;
            let a = max(3.0 - s, 0.0);
            let b = max(2.0 - s, 0.0);
            let c = max(1.0 - s, 0.0);
            return -15.0 * (a * a * a * a - 6.0 * b * b * b * b + 15.0 * c * c * c * c);
        }
        case KERNEL_WENDLAND_C2: { return -20.0 * q * t * t * t; }
        case KERNEL_WENDLAND_C4: {
            let t2 = t * t;
            return -56.0 / 3.0 * q * t2 * t2 * t * (1.0 + 5.0 * q);
        }
        case KERNEL_POLY6: {
            let d = 1.0 - q * q;
            return -6.0 * q * d * d;
        }
        default: { return -9.0 * q * exp(-4.5 * q * q); }
    }
}

/// Cell index of bundle b at depth slab `slab`, or 0xffffffff where it has none (a binary
/// search over the bundle's cells, which are sorted by depth).
fn cell_at(b: u32, slab: u32) -> u32 {
    var lo = bundle_cells[b];
    var hi = bundle_cells[b + 1u];
    loop {
        if (!take_iteration() || lo >= hi) { break; }
        let m = (lo + hi) / 2u;
        if (cells[m].z < slab) { lo = m + 1u; } else { hi = m; }
    }
    if (lo < bundle_cells[b + 1u] && cells[lo].z == slab) {
        return lo;
    }
    return 0xffffffffu;
}

/// The first slab at or after `slab` where bundle b has a cell (0xffffffff: none).
fn next_slab(b: u32, slab: u32) -> u32 {
    var lo = bundle_cells[b];
    var hi = bundle_cells[b + 1u];
    loop {
        if (!take_iteration() || lo >= hi) { break; }
        let m = (lo + hi) / 2u;
        if (cells[m].z < slab) { lo = m + 1u; } else { hi = m; }
    }
    if (lo < bundle_cells[b + 1u]) {
        return cells[lo].z;
    }
    return 0xffffffffu;
}

/// Adds refs [first, end) at view point x to `s` (gradients when `grad`); false when the budget
/// ran out on the way.
fn add_refs(first: u32, end: u32, x: vec3<f32>, grad: bool, s: ptr<function, Sums>) -> bool {
    var r = first;
    loop {
        if (!take_iteration()) { return false; }
        if (r >= end) { break; }
        let j = refs[r];
        r = r + 1u;
        let p = particles[2u * j];
        let dx = x - p.xyz;
        let dist = length(dx);
        let h = p.w;
        if (dist >= h) { continue; }
        let w = particles[2u * j + 1u];
        let k = kernel_w(dist, h);
        var b = w.x; // ISO_COLOUR: V
        if (S.iso == ISO_DENSITY) {
            b = w.z;
        } else if (S.iso == ISO_ATTRIBUTE) {
            b = w.x * select(w.y, iso_b[j], S.has_b == 1u);
        }
        (*s).iso += b * k;
        (*s).shep += w.x * k;
        (*s).rend += select(w.x * w.y, w.z, P.field == FIELD_DENSITY) * k;
        if (grad && dist > 0.0) {
            let f = kernel_norm(h) * shape_slope(dist / h) / (h * dist);
            (*s).g_iso += (b * f) * dx;
            (*s).g_shep += (w.x * f) * dx;
        }
    }
    return true;
}

/// The sums at view depth z on the ray (o, d) of bundle b, where z lies in sample k's step
/// [depths[k], depths[k + 1]]: the cell of k's slab, and that of the next slab where z lies
/// past the sample and the step crosses into it (its shared references counted once);
/// `ok` false when the budget ran out.
struct Eval {
    s: Sums,
    ok: bool,
};

fn sums_at(b: u32, k: u32, z: f32, o: vec3<f32>, d: vec3<f32>, grad: bool) -> Eval {
    var s = Sums(0.0, 0.0, 0.0, vec3<f32>(0.0), vec3<f32>(0.0));
    let x = o + z * d;
    let slab = k / P.dz;
    let ca = cell_at(b, slab);
    var cb = 0xffffffffu;
    if (z > depths[k] && k + 1u < P.n_depths && (k + 1u) / P.dz != slab) {
        cb = cell_at(b, slab + 1u);
    }
    var ok = !out_of_budget;
    if (ok && ca != 0xffffffffu) {
        let c = cells[ca];
        ok = add_refs(c.start, select(c.end, c.unique_end, cb != 0xffffffffu), x, grad, &s);
    }
    if (ok && cb != 0xffffffffu) {
        let c = cells[cb];
        ok = add_refs(c.start, c.end, x, grad, &s);
    }
    return Eval(s, ok);
}

/// The iso field of `s` (UNDEF: a CSPH quotient where no particle reaches).
fn iso_value(s: Sums) -> f32 {
    if (S.iso != ISO_ATTRIBUTE) {
        return s.iso;
    }
    if (s.shep > 0.0) {
        return s.iso / s.shep;
    }
    return UNDEF;
}

fn defined(f: f32) -> bool {
    return f > -1.0e38;
}

/// A value of the field where no cell of the bundle reaches.
fn empty_value() -> f32 {
    return select(0.0, UNDEF, S.iso == ISO_ATTRIBUTE);
}

fn is_empty(f: f32) -> bool {
    return f == empty_value();
}

/// The step a depth in [depths[s], depths[s + 2]] lies in.
fn step_of(s: u32, z: f32) -> u32 {
    return select(s + 1u, s, z < depths[s + 1u]);
}

/// The iso field at depth z near step s (UNDEF where undefined); `ok` false when the budget
/// ran out.
struct Value {
    f: f32,
    ok: bool,
};

fn value_at(b: u32, s: u32, z: f32, o: vec3<f32>, d: vec3<f32>) -> Value {
    let e = sums_at(b, step_of(s, z), z, o, d, false);
    return Value(iso_value(e.s), e.ok);
}

/// The regula falsi point of the bracket (a, ga) .. (b, gb), or its middle.
fn falsi(a: f32, ga: f32, b: f32, gb: f32) -> f32 {
    let z = (a * gb - b * ga) / (gb - ga);
    if (z > a && z < b) {
        return z;
    }
    return 0.5 * (a + b);
}

/// Starts refining the crossing of value v between (za, fa) and (zb, fb); the walk goes on at
/// phase `ret` once it is found, with `rising` for its direction.
fn start_refine(w: ptr<function, Walk>, v: f32, za: f32, fa: f32, zb: f32, fb: f32, rising: bool,
                ret: u32) {
    (*w).ra = za;
    (*w).rga = fa - v;
    (*w).rb = zb;
    (*w).rgb = fb - v;
    (*w).rz0 = za;
    (*w).rz1 = zb;
    (*w).rv = v;
    (*w).rit = 0u;
    (*w).flags = ((*w).flags & 3u) | select(0u, 4u, rising);
    (*w).ret = ret;
    (*w).phase = PH_REFINE;
}

/// Inserts the crossing at depth z (rising or not) into the pending list, by depth.
fn push_pending(w: ptr<function, Walk>, z: f32, rising: bool) {
    let n = (*w).np;
    if (n >= PENDING) {
        return; // cannot happen: at most 5 per value are pending at once
    }
    var i = n;
    loop {
        tick(1u); // bounded by PENDING: counted, never stopped half-way
        if (i == 0u || (*w).pend[i - 1u] <= z) { break; }
        (*w).pend[i] = (*w).pend[i - 1u];
        i = i - 1u;
    }
    (*w).pend[i] = z;
    let low = (*w).rising & ((1u << i) - 1u);
    let high = ((*w).rising >> i) << (i + 1u);
    (*w).rising = low | high | (select(0u, 1u, rising) << i);
    (*w).np = n + 1u;
}

/// Removes the nearest pending crossing.
fn pop_pending(w: ptr<function, Walk>) {
    var i = 1u;
    loop {
        tick(1u);
        if (i >= (*w).np) { break; }
        (*w).pend[i - 1u] = (*w).pend[i];
        i = i + 1u;
    }
    (*w).np = (*w).np - 1u;
    (*w).rising = (*w).rising >> 1u;
}

/// What a ray's steps read: its bundle, origin and direction per unit depth (view space), and
/// the depths between which it composites.
struct RayCtx {
    b: u32,
    o: vec3<f32>,
    d: vec3<f32>,
    limit: f32,
    near: f32,
};

/// PH_EVAL: the field at sample k into the window, then step k - 2's crossings. A sample in a
/// slab without a cell is empty; a run of empty steps with nothing pending is skipped (they
/// find no crossing), and the walk ends after the bundle's last cell.
fn eval_step(w: ptr<function, Walk>, r: RayCtx) -> bool {
    let k = (*w).k;
    let n = P.n_depths;
    if (k >= n + 2u) {
        (*w).phase = PH_DONE;
        return true;
    }
    var f = empty_value();
    if (k < n) {
        let slab = k / P.dz;
        let cell = cell_at(r.b, slab);
        if (out_of_budget) { return false; }
        if (cell != 0xffffffffu) {
            let v = value_at(r.b, k, depths[k], r.o, r.d);
            if (!v.ok) { return false; }
            f = v.f;
        } else if (is_empty((*w).fb) && is_empty((*w).fc) && (*w).np == 0u) {
            let next = next_slab(r.b, slab);
            if (out_of_budget) { return false; }
            if (next == 0xffffffffu) {
                (*w).phase = PH_DONE;
                return true;
            }
            if (k + 2u < next * P.dz) {
                (*w).k = next * P.dz - 2u;
                return true;
            }
        }
    }
    (*w).fa = (*w).fb;
    (*w).fb = (*w).fc;
    (*w).fc = f;
    if (k < 2u) {
        (*w).k = k + 1u;
        return true;
    }
    if (depths[k - 2u] >= r.limit) {
        (*w).phase = PH_DONE; // every surface from here on lies behind the ray's limit
        return true;
    }
    (*w).vi = 0u;
    (*w).phase = PH_CROSS;
    return true;
}

/// PH_CROSS: starts refining the next value that step s = k - 2 crosses (Walk::crossings).
fn cross_step(w: ptr<function, Walk>) -> bool {
    let s = (*w).k - 2u;
    let fa = (*w).fa;
    let fb = (*w).fb;
    loop {
        tick(1u); // at most MAX_ISO_VALUES
        if (s + 1u >= P.n_depths || (*w).vi >= S.n_values || !defined(fa) || !defined(fb)) {
            (*w).phase = PH_HIDDEN;
            return true;
        }
        let v = S.values[(*w).vi];
        (*w).vi = (*w).vi + 1u;
        if ((fa >= v) != (fb >= v)) {
            start_refine(w, v, depths[s], fa, depths[s + 1u], fb, fb >= v, PH_CROSS);
            return true;
        }
    }
    return true;
}

/// PH_REFINE: one Illinois iteration on the exact sum (Walk::refine); the crossing found
/// goes to the pending list, none where the field is undefined on the way.
fn refine_step(w: ptr<function, Walk>, r: RayCtx) -> bool {
    let s = (*w).k - 2u;
    let a = (*w).ra;
    let ga = (*w).rga;
    let b = (*w).rb;
    let gb = (*w).rgb;
    let z = falsi(a, ga, b, gb);
    let it = (*w).rit & 255u;
    // Done at 1e-5 of the bracket it started from, or where f32 cannot split it further
    // (two units in the last place).
    let tol = max(1.0e-5 * ((*w).rz1 - (*w).rz0), 2.4e-7 * abs(b));
    if (b - a <= tol || it >= REFINE_ITERATIONS) {
        push_pending(w, z, ((*w).flags & 4u) != 0u);
        (*w).phase = (*w).ret;
        return true;
    }
    let v = value_at(r.b, s, z, r.o, r.d);
    if (!v.ok) { return false; }
    if (!defined(v.f)) {
        (*w).phase = (*w).ret; // a gap no particle reaches: the field jumps, no surface
        return true;
    }
    let g = v.f - (*w).rv;
    var kept = (*w).rit >> 8u; // 1: a stayed last time, 2: b did (Illinois halves the other)
    if ((g >= 0.0) == (ga >= 0.0)) {
        (*w).ra = z;
        (*w).rga = g;
        if (kept == 1u) { (*w).rgb = 0.5 * gb; }
        kept = 1u;
    } else {
        (*w).rb = z;
        (*w).rgb = g;
        if (kept == 2u) { (*w).rga = 0.5 * ga; }
        kept = 2u;
    }
    (*w).rit = (it + 1u) | (kept << 8u);
    return true;
}

/// PH_HIDDEN: whether sample m = k - 1 is a maximum below a value or a minimum above it,
/// within the samples' own swing (Walk::hidden); if so the extremum's search starts.
fn hidden_step(w: ptr<function, Walk>) -> bool {
    let s = (*w).k - 2u;
    (*w).phase = PH_SHADE;
    let a = (*w).fa;
    let f = (*w).fb;
    let b = (*w).fc;
    if (s + 2u >= P.n_depths || !defined(a) || !defined(f) || !defined(b)) {
        return true;
    }
    let swing = max(abs(f - a), abs(f - b));
    var below = false;
    var above = false;
    for (var i = 0u; i < S.n_values; i = i + 1u) {
        tick(1u);
        let v = S.values[i];
        let near = abs(v - f) <= swing;
        below = below || (f < v && near);
        above = above || (f >= v && near);
    }
    let mx = f >= a && f >= b && below;
    let mn = f <= a && f <= b && above;
    if (!(mx || mn)) {
        return true;
    }
    let za = depths[s];
    let zb = depths[s + 2u];
    (*w).ga = za;
    (*w).gb = zb;
    (*w).gc = zb - GOLDEN * (zb - za);
    (*w).gd = za + GOLDEN * (zb - za);
    (*w).git = 0u;
    (*w).flags = select(0u, 1u, mx);
    (*w).phase = PH_GOLDEN;
    return true;
}

/// PH_GOLDEN: one evaluation of the golden-section search for the extremum (Walk::extremum):
/// the first two points, GOLDEN_ITERATIONS narrowings, then the middle of the bracket.
fn golden_step(w: ptr<function, Walk>, r: RayCtx) -> bool {
    let s = (*w).k - 2u;
    let sign = select(-1.0, 1.0, ((*w).flags & 1u) != 0u);
    let it = (*w).git;
    var a = (*w).ga;
    var b = (*w).gb;
    var c = (*w).gc;
    var d = (*w).gd;
    var fc = (*w).gfc;
    var fd = (*w).gfd;
    var z = 0.5 * (a + b);
    var left = false;
    if (it == 0u) {
        z = c;
    } else if (it == 1u) {
        z = d;
    } else if (it < 2u + GOLDEN_ITERATIONS) {
        if (fc > fd) {
            b = d;
            d = c;
            fd = fc;
            c = b - GOLDEN * (b - a);
            z = c;
            left = true;
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + GOLDEN * (b - a);
            z = d;
        }
    }
    let v = value_at(r.b, s, z, r.o, r.d);
    if (!v.ok) { return false; }
    if (!defined(v.f)) {
        (*w).phase = PH_SHADE;
        return true;
    }
    if (it >= 2u + GOLDEN_ITERATIONS) {
        (*w).ze = z;
        (*w).fe = v.f;
        (*w).vi = 0u;
        (*w).flags = (*w).flags & 1u;
        (*w).phase = PH_BEYOND;
        return true;
    }
    if (it == 0u) {
        (*w).gfc = sign * v.f;
    } else if (it == 1u) {
        (*w).gfd = sign * v.f;
    } else {
        if (left) { fc = sign * v.f; } else { fd = sign * v.f; }
        (*w).ga = a;
        (*w).gb = b;
        (*w).gc = c;
        (*w).gd = d;
        (*w).gfc = fc;
        (*w).gfd = fd;
    }
    (*w).git = it + 1u;
    return true;
}

/// PH_BEYOND: for each value the extremum passes, refines the crossing left of it, then the
/// one right of it.
fn beyond_step(w: ptr<function, Walk>) -> bool {
    let s = (*w).k - 2u;
    let mx = ((*w).flags & 1u) != 0u;
    let f = (*w).fb;
    let fe = (*w).fe;
    loop {
        tick(1u); // at most MAX_ISO_VALUES
        if ((*w).vi >= S.n_values) {
            (*w).phase = PH_SHADE;
            return true;
        }
        let v = S.values[(*w).vi];
        let beyond = select(f >= v && fe < v, f < v && fe >= v, mx);
        if (!beyond) {
            (*w).vi = (*w).vi + 1u;
            continue;
        }
        if (((*w).flags & 2u) == 0u) {
            (*w).flags = (*w).flags | 2u;
            start_refine(w, v, depths[s], (*w).fa, (*w).ze, fe, mx, PH_BEYOND);
        } else {
            (*w).flags = (*w).flags & 1u;
            (*w).vi = (*w).vi + 1u;
            start_refine(w, v, (*w).ze, fe, depths[s + 2u], (*w).fc, !mx, PH_BEYOND);
        }
        return true;
    }
    return true;
}

/// A view-space direction in world space.
fn to_world(v: vec3<f32>) -> vec3<f32> {
    return v.x * P.right.xyz + v.y * P.up.xyz + v.z * P.forward.xyz;
}

/// Lighting::shade: ambient, diffuse and specular (Blinn) of base colour c, normal n facing
/// the eye (world space).
fn light(c: vec3<f32>, n0: vec3<f32>, to_eye: vec3<f32>) -> vec3<f32> {
    var n = n0;
    if (dot(n, to_eye) < 0.0) {
        n = -n;
    }
    let headlight = S.light.w == 0.0;
    var l = -P.forward.xyz;
    if (!headlight) {
        l = S.light.xyz;
    }
    let diffuse = S.diffuse * max(dot(n, l), 0.0);
    let hv = l + to_eye;
    var h = vec3<f32>(0.0);
    if (length(hv) > 0.0) {
        h = normalize(hv);
    }
    let nh = max(dot(n, h), 0.0);
    var spec = 0.0;
    if (diffuse > 0.0 || headlight) {
        if (S.specular_power == 0.0) {
            spec = S.specular;
        } else if (nh > 0.0) {
            spec = S.specular * pow(nh, S.specular_power);
        }
    }
    return (S.ambient + diffuse) * c + vec3<f32>(spec);
}

/// Shades the surface at depth z (rising: the field grows past it) from the sums there and
/// composites it (SurfaceCaster::shade); the first one is the pixel's depth and normal.
fn shade(w: ptr<function, Walk>, r: RayCtx, z: f32, rising: bool, s: Sums) {
    var g = s.g_iso;
    if (S.iso == ISO_ATTRIBUTE) {
        g = vec3<f32>(0.0);
        if (s.shep > 0.0) {
            g = (s.g_iso * s.shep - s.iso * s.g_shep) / (s.shep * s.shep);
        }
    }
    let to_eye_v = -r.d / length(r.d);
    var nv = to_eye_v;
    let len = length(g);
    if (len > 0.0) {
        nv = g * select(1.0 / len, -1.0 / len, rising);
    }
    let n = to_world(nv);
    var base = S.colour.xyz;
    if (S.colour.w == 0.0) {
        var q = s.rend;
        var known = true;
        if (P.field == FIELD_CSPH) {
            known = s.shep > 0.0;
            q = select(0.0, s.rend / max(s.shep, 1.0e-30), known);
        }
        base = select(vec3<f32>(0.8), tf_eval(q).xyz, known);
    }
    let rgb = light(base, n, to_world(to_eye_v));
    let a = S.opacity;
    (*w).colour = (*w).colour + (*w).trans * a * rgb;
    (*w).trans = (*w).trans * (1.0 - a);
    if ((*w).zfirst >= 1.0e30) {
        (*w).zfirst = z;
        (*w).normal = n;
    }
}

/// PH_SHADE: composites the pending crossings before sample k - 1 in depth order, then the
/// walk moves on to the next sample.
fn shade_step(w: ptr<function, Walk>, r: RayCtx) -> bool {
    let s = (*w).k - 2u;
    loop {
        tick(1u); // at most PENDING
        if ((*w).np == 0u || (*w).pend[0] >= depths[s + 1u]) {
            (*w).k = (*w).k + 1u;
            (*w).phase = PH_EVAL;
            return true;
        }
        let z = (*w).pend[0];
        if (z >= r.limit) {
            (*w).phase = PH_DONE; // behind opaque geometry or past the ray's region
            return true;
        }
        if (z > r.near) {
            let e = sums_at(r.b, step_of(s, z), z, r.o, r.d, true);
            if (!e.ok) { return false; }
            shade(w, r, z, ((*w).rising & 1u) != 0u, e.s);
        }
        pop_pending(w);
        if ((*w).trans < P.min_transmittance) {
            (*w).phase = PH_DONE;
            return true;
        }
    }
    return true;
}

/// One step of the walk; false when the loop budget ran out before it could be taken (the
/// walk is then as before it).
fn walk_step(w: ptr<function, Walk>, r: RayCtx) -> bool {
    switch (*w).phase {
        case PH_EVAL: { return eval_step(w, r); }
        case PH_CROSS: { return cross_step(w); }
        case PH_REFINE: { return refine_step(w, r); }
        case PH_HIDDEN: { return hidden_step(w); }
        case PH_GOLDEN: { return golden_step(w, r); }
        case PH_BEYOND: { return beyond_step(w); }
        case PH_SHADE: { return shade_step(w, r); }
        default: { return true; }
    }
}

/// A walk from the bundle's first cell (done at once where it has none).
fn fresh_walk(b: u32) -> Walk {
    var w: Walk;
    w.phase = PH_DONE;
    let c0 = bundle_cells[b];
    if (c0 < bundle_cells[b + 1u]) {
        w.phase = PH_EVAL;
        w.k = cells[c0].z * P.dz;
    }
    w.fa = empty_value();
    w.fb = empty_value();
    w.fc = empty_value();
    w.trans = 1.0;
    w.zfirst = 1.0e30;
    return w;
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>,
        @builtin(num_workgroups) nw: vec3<u32>) {
    let q = scattered_bundle(wg.y * nw.x + wg.x, S.band_rows * P.bundles_x, S.scatter);
    let bx = q % P.bundles_x;
    let by = q / P.bundles_x + S.band_y0;
    let b = by * P.bundles_x + bx;
    let i = bx * P.bundle + lid.x;
    let j = by * P.bundle + lid.y;
    if (q == 0xffffffffu || lid.x >= P.bundle || lid.y >= P.bundle || i >= P.width || j >= P.height) {
        return;
    }
    // The ray through pixel (i, j), as Ray::through_pixel (view space, d.z = 1).
    let x = 2.0 * (f32(i) + 0.5) / f32(P.width) - 1.0;
    let y = 1.0 - 2.0 * (f32(j) + 0.5) / f32(P.height);
    var o = vec3<f32>(0.0, 0.0, 0.0);
    var d = vec3<f32>(x * P.tan_half * P.aspect, y * P.tan_half, 1.0);
    if (P.parallel_scale > 0.0) {
        o = vec3<f32>(x * P.parallel_scale * P.aspect, y * P.parallel_scale, 0.0);
        d = vec3<f32>(0.0, 0.0, 1.0);
    }
    let px = j * P.width + i;
    var limit = 3.0e38;
    var near = -3.0e38;
    if (P.has_limit != 0u) {
        limit = depth_limit[px];
        near = depth_limit[P.width * P.height + px];
    }
    // The pixel's index within its band, where its walk is kept.
    let rp = (j - S.band_y0 * P.bundle) * P.width + i;
    let resumable = arrayLength(&resume) >= S.band_rows * P.bundle * P.width;
    var w: Walk;
    if (S.round == 0u) {
        w = fresh_walk(b);
        if (limit <= near) {
            w.phase = PH_DONE; // an empty range composites nothing (Compositor::between)
        }
    } else {
        w = resume[rp];
        if (w.phase == PH_DONE) {
            return;
        }
    }
    let r = RayCtx(b, o, d, limit, near);
    var steps = 0u;
    loop {
        if (w.phase == PH_DONE) {
            break;
        }
        if (!take_iteration() || !walk_step(&w, r)) {
            if (steps == 0u || !resumable) {
                // Not one step fits the driver's limit: refused (the host reads the guard).
                atomicStore(&guard[0], 1u);
            }
            if (resumable) {
                resume[rp] = w;
            }
            atomicAdd(&stopped[0], 1u);
            return;
        }
        steps = steps + 1u;
    }
    out_rgba[px] = vec4<f32>(w.colour, 1.0 - w.trans);
    out_depth[px] = w.zfirst;
    out_normal[px] = vec4<f32>(w.normal, 0.0);
    if (resumable && P.loop_limit != 0xffffffffu) {
        resume[rp].phase = PH_DONE;
    }
}
