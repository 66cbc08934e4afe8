// Shared by the grid, plan and ray casting shaders (prepended by the Rust side): the frame's
// uniform parameters, the transfer function, the SPH kernels and the interval arithmetic of the
// error analysis. Mirrors the f64 CPU code in single precision.

struct Frame {
    eye: vec4<f32>,      // camera position (world)
    right: vec4<f32>,    // view-space axes in world coordinates
    up: vec4<f32>,
    forward: vec4<f32>,
    width: u32,
    height: u32,
    bundles_x: u32,
    bundles_y: u32,
    bundle: u32,         // D_xy (pixels)
    dz: u32,             // D_z (depth samples per cell)
    cells_z: u32,        // cells along depth, N / D_z
    n_depths: u32,       // N
    aspect: f32,
    tan_half: f32,
    parallel_scale: f32, // > 0: parallel projection with this scale
    min_transmittance: f32,
    field: u32,          // FIELD_* (written by the Rust side from fluidcast_sph::FieldKind)
    kernel: u32,         // KERNEL_* (from fluidcast_sph::Kernel)
    gauss_norm: f32,     // the Gaussian kernel's normalisation constant c (see kernel.rs)
    n_colors: u32,
    n_opacity: u32,
    tf_lo: f32,
    tf_hi: f32,
    unit_distance: f32,
    has_limit: u32,      // bit 0: a far depth per pixel (opaque geometry); bit 1: a near one
    n_particles: u32,
    near: f32,
    far: f32,
    tolerance: f32,      // E_I, or < 0 for no adaptivity
    relax: f32,          // E_relax
    budget: f32,         // E_I - min_transmittance
    superpixels: u32,
    surface_rule: u32,   // 1: PlanParams::uses_surface_cells
    max_level: u32,      // log2 D_z
    n_pairs: u32,
    n_cells: u32,
    loop_limit: u32,     // loop iterations one invocation may run (see `tick`)
    pad0: u32,
    pad1: u32,
    pad2: u32,
};

/// A non-empty grid cell (fluidcast_grid::Cell) and its bundle.
struct Cell {
    z: u32,
    start: u32,
    unique_end: u32, // refs start..unique_end are not referenced by the cell at z + 1
    end: u32,
    bundle: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
};

/// A run of `count` cells of one bundle sampled every `step` depth samples, or one cell drawn
/// as a super-pixel (fluidcast_plan::Span, with the depth samples it covers).
struct Span {
    first: u32,      // first cell
    count: u32,
    level: u32,
    superpixel: u32, // 1: composite `sp` (I rgb, T) instead of sampling
    k0: u32,         // first depth index
    n: u32,          // samples: depths k0 + m * step, m = 0..n (n + 1 depths bound n steps)
    step: u32,
    pad: u32,
    sp: vec4<f32>,
};

@group(0) @binding(0) var<uniform> P: Frame;
// The transfer function's control points: P.n_colors colour points (x, r, g, b), then
// P.n_opacity opacity points (x, alpha, 0, 0); x is the map position in [0, 1].
@group(0) @binding(1) var<storage, read> tf: array<vec4<f32>>;

const PI: f32 = 3.14159265358979;
const LEVELS: u32 = 7u;
// Stands for an infinite extinction (alpha = 1): exp(-K_INF * ds) is 0 for any step.
const K_INF: f32 = 1.0e30;

/// Mesa's software drivers (llvmpipe, lavapipe) end every loop of a shader invocation once the
/// invocation has run LP_MAX_TGSI_LOOP_ITERATIONS (65535) iterations of all its loops
/// together (a loop of n iterations counts n + 1: the pass that exits counts too), silently: the rest of the work, stores included, is skipped and the image is
/// wrong. Shaders that can loop long count their iterations (`tick`, with a bound that is the
/// same for every invocation of a SIMD batch, so it bounds the driver's count) and, *before* a
/// loop that would take the count past P.loop_limit (u32::MAX on hardware GPUs), raise their
/// guard flag and skip the work (`over_budget`); the host then refuses the frame.
var<private> ticks: u32 = 0u;

fn tick(n: u32) {
    ticks = ticks + n;
}

/// True when `next` more iterations would pass P.loop_limit.
fn over_budget(next: u32) -> bool {
    return next > P.loop_limit - min(ticks, P.loop_limit);
}

// Set when `take_iteration` found the budget spent: the work under way stops unfinished.
var<private> out_of_budget: bool = false;

/// The bundle (row by row) that workgroup `k` of a dispatch over `n` bundles casts, consecutive
/// workgroups `scatter` apart: with m = ceil(n / scatter), (k mod scatter) m + k / scatter, a
/// bijection of [0, scatter m); 0xffffffff for the dispatch's padding. llvmpipe hands each of
/// its threads one contiguous range of a dispatch's workgroups, so on a software driver this
/// gives every thread bundles from all over the image, not one region's (scatter = 1 on
/// hardware, whose scheduler balances: bundle k).
fn scattered_bundle(k: u32, n: u32, scatter: u32) -> u32 {
    let m = (n + scatter - 1u) / scatter;
    let q = (k % scatter) * m + k / scatter;
    if (k >= scatter * m || q >= n) {
        return 0xffffffffu;
    }
    return q;
}

/// One more loop iteration, or false (and out_of_budget) when the invocation has none left:
/// for loops whose trip count is only known as they run (the RBF march's queries, the
/// surface walk's sums).
fn take_iteration() -> bool {
    if (over_budget(1u)) {
        out_of_budget = true;
        return false;
    }
    tick(1u);
    return true;
}

/// Index of this workgroup in a dispatch that may be folded into two dimensions.
fn group_index(wg: vec3<u32>, nw: vec3<u32>) -> u32 {
    return wg.y * nw.x + wg.x;
}

fn kernel_w(r: f32, h: f32) -> f32 {
    let q = r / h;
    if (q >= 1.0) {
        return 0.0;
    }
    let h3 = h * h * h;
    switch P.kernel {
        case KERNEL_CUBIC: {
            let k = 8.0 / (PI * h3);
            if (q <= 0.5) {
                return k * (6.0 * q * q * q - 6.0 * q * q + 1.0);
            }
            let t = 1.0 - q;
            return k * 2.0 * t * t * t;
        }
        case KERNEL_QUINTIC: {
            let s = 3.0 * q;
            let hh = h / 3.0;
            let a = max(3.0 - s, 0.0);
            let b = max(2.0 - s, 0.0);
            let c = max(1.0 - s, 0.0);
            let p = a * a * a * a * a - 6.0 * b * b * b * b * b + 15.0 * c * c * c * c * c;
            return p / (120.0 * PI * hh * hh * hh);
        }
        case KERNEL_WENDLAND_C2: {
            let t = 1.0 - q;
            return 21.0 / (2.0 * PI * h3) * t * t * t * t * (1.0 + 4.0 * q);
        }
        case KERNEL_WENDLAND_C4: {
            let t = 1.0 - q;
            let t2 = t * t;
            return 495.0 / (32.0 * PI * h3) * t2 * t2 * t2 * (1.0 + 6.0 * q + 35.0 / 3.0 * q * q);
        }
        case KERNEL_POLY6: {
            let d = 1.0 - q * q;
            return 315.0 / (64.0 * PI * h3) * d * d * d;
        }
        default: { // KERNEL_GAUSSIAN
            let sigma = h / 3.0;
            return exp(-(r * r) / (2.0 * sigma * sigma)) / (P.gauss_norm * sigma * sigma * sigma);
        }
    }
}

/// Map position t in [0, 1] of data value q (TransferFunction::normalised); NaN maps to -1.
fn tf_t(q: f32) -> f32 {
    if (q != q) {
        return -1.0;
    }
    return clamp((q - P.tf_lo) / (P.tf_hi - P.tf_lo), 0.0, 1.0);
}

/// The piecewise-linear table tf[first..first + n] at map position t: clamped to its end
/// points, linear between them. A binary search written out without a loop (tables of up to
/// MAX_TF_POINTS points; see `tick`): between point i - 1 and the first point i with t <= x_i.
fn table_at(first: u32, n: u32, t: f32) -> vec3<f32> {
    if (t <= tf[first].x) {
        return tf[first].yzw;
    }
    let last = first + n - 1u;
    if (t > tf[last].x) {
        return tf[last].yzw;
    }
    var lo = 0u; // x_lo < t
    lo = tf_probe(first, n, t, lo, 2048u);
    lo = tf_probe(first, n, t, lo, 1024u);
    lo = tf_probe(first, n, t, lo, 512u);
    lo = tf_probe(first, n, t, lo, 256u);
    lo = tf_probe(first, n, t, lo, 128u);
    lo = tf_probe(first, n, t, lo, 64u);
    lo = tf_probe(first, n, t, lo, 32u);
    lo = tf_probe(first, n, t, lo, 16u);
    lo = tf_probe(first, n, t, lo, 8u);
    lo = tf_probe(first, n, t, lo, 4u);
    lo = tf_probe(first, n, t, lo, 2u);
    lo = tf_probe(first, n, t, lo, 1u);
    let a = tf[first + lo];
    let b = tf[first + lo + 1u];
    let d = b.x - a.x;
    var f = 1.0;
    if (d > 0.0) { f = (t - a.x) / d; }
    return mix(a.yzw, b.yzw, f);
}

/// One step of table_at's search: lo + step when that point still lies below t.
fn tf_probe(first: u32, n: u32, t: f32, lo: u32, step: u32) -> u32 {
    let m = lo + step;
    if (m < n && tf[first + m].x < t) {
        return m;
    }
    return lo;
}

/// Colour and opacity per unit distance at map position t (TransferFunction::eval_normalised).
fn tf_at(t: f32) -> vec4<f32> {
    return vec4<f32>(table_at(0u, P.n_colors, t), table_at(P.n_colors, P.n_opacity, t).x);
}

fn tf_eval(q: f32) -> vec4<f32> {
    return tf_at(tf_t(q));
}

/// Bounds on a composited segment (fluidcast_plan::Bound): xyz premultiplied irradiance,
/// w transparency.
struct Bound {
    lo: vec4<f32>,
    hi: vec4<f32>,
};

fn bound_empty() -> Bound {
    return Bound(vec4<f32>(0.0, 0.0, 0.0, 1.0), vec4<f32>(0.0, 0.0, 0.0, 1.0));
}

/// f in front of b (Bound::over).
fn over(f: Bound, b: Bound) -> Bound {
    return Bound(vec4<f32>(f.lo.xyz + f.lo.w * b.lo.xyz, f.lo.w * b.lo.w),
                 vec4<f32>(f.hi.xyz + f.hi.w * b.hi.xyz, f.hi.w * b.hi.w));
}

fn width(b: Bound) -> f32 {
    let d = b.hi - b.lo;
    return max(max(d.x, d.y), max(d.z, max(d.w, 0.0)));
}
