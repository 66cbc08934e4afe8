//! What the host and the shaders share: the uniform and storage structs (`Pod`, with their
//! sizes checked at compile time and against the WGSL by naga in the tests), the counters the
//! host reads back by name, and the codes of kernels and fields. The Rust enums are the one
//! source: [`wgsl_prelude`] writes them into every shader as constants.

use bytemuck::{Pod, Zeroable};
use fluidcast_grid::Cell;
use fluidcast_rbf::Colouring;
use fluidcast_render::{IsoField, Noise, RenderParams};
use fluidcast_sph::{FieldKind, Kernel};
use fluidcast_view::{TransferFunction, ViewFrame};

use crate::MAX_TF_POINTS;

/// The frame's uniform parameters (`Frame` in common.wgsl; same field order).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub(crate) struct FrameUniform {
    pub(crate) eye: [f32; 4],
    pub(crate) right: [f32; 4],
    pub(crate) up: [f32; 4],
    pub(crate) forward: [f32; 4],
    pub(crate) width: u32,
    pub(crate) height: u32,
    pub(crate) bundles_x: u32,
    pub(crate) bundles_y: u32,
    pub(crate) bundle: u32,
    pub(crate) dz: u32,
    pub(crate) cells_z: u32,
    pub(crate) n_depths: u32,
    pub(crate) aspect: f32,
    pub(crate) tan_half: f32,
    pub(crate) parallel_scale: f32,
    pub(crate) min_transmittance: f32,
    pub(crate) field: u32,
    pub(crate) kernel: u32,
    pub(crate) gauss_norm: f32,
    pub(crate) n_colors: u32,
    pub(crate) n_opacity: u32,
    pub(crate) tf_lo: f32,
    pub(crate) tf_hi: f32,
    pub(crate) unit_distance: f32,
    pub(crate) has_limit: u32,
    pub(crate) n_particles: u32,
    pub(crate) near: f32,
    pub(crate) far: f32,
    pub(crate) tolerance: f32,
    pub(crate) relax: f32,
    pub(crate) budget: f32,
    pub(crate) superpixels: u32,
    pub(crate) surface_rule: u32,
    pub(crate) max_level: u32,
    pub(crate) n_pairs: u32,
    pub(crate) n_cells: u32,
    pub(crate) loop_limit: u32,
    pub(crate) pad: [u32; 3],
}

/// A grid cell and its bundle (`Cell` in common.wgsl).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub(crate) struct GpuCell {
    pub(crate) z: u32,
    pub(crate) start: u32,
    pub(crate) unique_end: u32,
    pub(crate) end: u32,
    pub(crate) bundle: u32,
    pub(crate) pad: [u32; 3],
}

impl GpuCell {
    /// The CPU grid's cell `c` of bundle `bundle`.
    pub(crate) fn new(c: &Cell, bundle: u32) -> GpuCell {
        GpuCell {
            z: c.z,
            start: c.start,
            unique_end: c.unique_end,
            end: c.end,
            bundle,
            pad: [0; 3],
        }
    }

    /// The cell as the CPU grid has it (without its bundle).
    pub(crate) fn cell(&self) -> Cell {
        Cell {
            z: self.z,
            start: self.start,
            unique_end: self.unique_end,
            end: self.end,
        }
    }
}

/// A span of the plan (`Span` in common.wgsl).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub(crate) struct GpuSpan {
    pub(crate) first: u32,
    pub(crate) count: u32,
    pub(crate) level: u32,
    pub(crate) superpixel: u32,
    pub(crate) k0: u32,
    pub(crate) n: u32,
    pub(crate) step: u32,
    pub(crate) pad: u32,
    pub(crate) sp: [f32; 4],
}

// The sizes the WGSL structs have (std430 / uniform layout; checked by naga in the tests).
const _: () = assert!(std::mem::size_of::<FrameUniform>() == 208);
const _: () = assert!(std::mem::size_of::<GpuCell>() == 32);
const _: () = assert!(std::mem::size_of::<GpuSpan>() == 48);
const _: () = assert!(std::mem::size_of::<GridCounters>() == 32);
const _: () = assert!(std::mem::size_of::<PlanCounters>() == 64);

/// grid.wgsl's `counters`, by name: what `footprint` and `cell_starts` accumulate and the
/// host reads.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable, Debug)]
pub(crate) struct GridCounters {
    /// Particles whose support touches a cell.
    pub(crate) visible: u32,
    /// The pair count as `pairs_hi` × 256 + `pairs_lo` (no 32-bit overflow while summing).
    pub(crate) pairs_hi: u32,
    pub(crate) pairs_lo: u32,
    /// Non-empty cells.
    pub(crate) cells: u32,
    pub(crate) pad: [u32; 4],
}

impl GridCounters {
    pub(crate) fn pairs(&self) -> u64 {
        self.pairs_hi as u64 * 256 + self.pairs_lo as u64
    }
}

/// plan.wgsl's `plan_stats`, by name (atomic sums over the bundles).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable, Debug)]
pub(crate) struct PlanCounters {
    /// Cells sampled at each level 0..7.
    pub(crate) level_cells: [u32; 7],
    pub(crate) superpixel_cells: u32,
    pub(crate) surface_cells: u32,
    pub(crate) merged_cells: u32,
    pub(crate) refs_sampled: u32,
    /// The probe bundles' cast work at full rate and as planned, each a u64 as (low, high)
    /// words (`fluidcast_plan::SamplingPlan::build`'s probe).
    pub(crate) probe_work: [u32; 4],
    pub(crate) unanalysed_bundles: u32,
}

impl PlanCounters {
    pub(crate) fn stats(&self, cells: u64) -> fluidcast_plan::PlanStats {
        fluidcast_plan::PlanStats {
            cells,
            level_cells: self.level_cells.map(u64::from),
            superpixel_cells: self.superpixel_cells as u64,
            surface_cells: self.surface_cells as u64,
            merged_cells: self.merged_cells as u64,
            refs_sampled: self.refs_sampled as u64,
            unanalysed_bundles: self.unanalysed_bundles as u64,
        }
    }
}

/// A kernel's code in the shaders (`KERNEL_*`): its index in [`Kernel::ALL`].
pub(crate) fn kernel_code(k: Kernel) -> u32 {
    Kernel::ALL.iter().position(|&x| x == k).unwrap_or(0) as u32
}

/// A field's code in the shaders (`FIELD_*`): its index in [`FieldKind::ALL`].
pub(crate) fn field_code(f: FieldKind) -> u32 {
    FieldKind::ALL.iter().position(|&x| x == f).unwrap_or(0) as u32
}

fn wgsl_name(prefix: &str, name: &str) -> String {
    format!("{prefix}_{}", name.to_ascii_uppercase().replace('-', "_"))
}

/// Constants the Rust side owns, prepended to every shader: the transfer-function size limit,
/// the sampling plan's probe (which bundles, and the saving that pays) and longest span, and
/// the kernel and field codes.
pub(crate) fn wgsl_prelude() -> String {
    use fluidcast_plan::{
        MAX_SPAN_SAMPLES, PROBE_ROW_SHIFT, PROBE_SAVING_DEN, PROBE_SAVING_NUM, PROBE_STRIDE,
    };
    let mut s = format!("const MAX_TF_POINTS: u32 = {MAX_TF_POINTS}u;\n");
    s += &format!("const MAX_SPAN_SAMPLES: u32 = {MAX_SPAN_SAMPLES}u;\n");
    s += &format!("const PROBE_STRIDE: u32 = {PROBE_STRIDE}u;\n");
    s += &format!("const PROBE_ROW_SHIFT: u32 = {PROBE_ROW_SHIFT}u;\n");
    s += &format!("const PROBE_SAVING_NUM: u32 = {PROBE_SAVING_NUM}u;\n");
    s += &format!("const PROBE_SAVING_DEN: u32 = {PROBE_SAVING_DEN}u;\n");
    for k in Kernel::ALL {
        s += &format!(
            "const {}: u32 = {}u;\n",
            wgsl_name("KERNEL", k.name()),
            kernel_code(k)
        );
    }
    for f in FieldKind::ALL {
        s += &format!(
            "const {}: u32 = {}u;\n",
            wgsl_name("FIELD", f.name()),
            field_code(f)
        );
    }
    s
}

/// rbf.wgsl's uniform `R` (same field order).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub(crate) struct RbfUniform {
    pub(crate) root_lo: [f32; 4],
    pub(crate) root_hi: [f32; 4],
    pub(crate) step: f32,
    pub(crate) first_leaf: u32,
    pub(crate) n_slots: u32,
    pub(crate) leaf_size: u32,
    pub(crate) spp: u32,
    pub(crate) first_pass: u32,
    pub(crate) seed: u32,
    pub(crate) colouring: u32,
    pub(crate) noise: u32,
    /// Dispatches of this render before this one (rbf.wgsl's `resume`).
    pub(crate) round: u32,
    pub(crate) shadows: u32,
    pub(crate) shadow_samples: u32,
    pub(crate) light: [f32; 4],
    pub(crate) ambient: f32,
    /// Consecutive workgroups take 8 x 8 tiles this far apart (common.wgsl's
    /// `scattered_bundle`).
    pub(crate) scatter: u32,
    pub(crate) pad: [u32; 2],
}

const _: () = assert!(std::mem::size_of::<RbfUniform>() == 112);

/// surface.wgsl's uniform `S` (same field order).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub(crate) struct SurfaceUniform {
    /// The iso values (the first `n_values`).
    pub(crate) values: [f32; 4],
    /// A solid linear RGB colour (w = 1), or the transfer function's (w = 0).
    pub(crate) colour: [f32; 4],
    /// Toward the light (world, unit; w = 1), or a headlight (w = 0).
    pub(crate) light: [f32; 4],
    pub(crate) ambient: f32,
    pub(crate) diffuse: f32,
    pub(crate) specular: f32,
    pub(crate) specular_power: f32,
    pub(crate) n_values: u32,
    /// `ISO_*`: [`iso_code`].
    pub(crate) iso: u32,
    /// 1: the iso attribute is bound as its own array, else it is the rendered one.
    pub(crate) has_b: u32,
    pub(crate) opacity: f32,
    /// Dispatches of this band before this one (surface.wgsl's `resume`).
    pub(crate) round: u32,
    /// The band's first row of bundles, and its rows (the dispatches cover a band at a time,
    /// so that the walks in progress fit one binding).
    pub(crate) band_y0: u32,
    pub(crate) band_rows: u32,
    /// Consecutive workgroups take bundles this far apart (common.wgsl's `scattered_bundle`).
    pub(crate) scatter: u32,
}

const _: () = assert!(std::mem::size_of::<SurfaceUniform>() == 96);

/// Most iso values the GPU's surfaces take (surface.wgsl's `S.values`, a vec4).
pub const MAX_ISO_VALUES: usize = 4;

/// The code of an iso field (`ISO_*`).
pub(crate) fn iso_code(f: &IsoField) -> u32 {
    match f {
        IsoField::Colour => 0,
        IsoField::Density => 1,
        IsoField::Attribute(_) => 2,
    }
}

/// Constants surface.wgsl shares with the host: the iso field codes by their names, and the
/// most iso values.
pub(crate) fn surface_prelude() -> String {
    let mut s = format!("const MAX_ISO_VALUES: u32 = {MAX_ISO_VALUES}u;\n");
    for f in [
        IsoField::Colour,
        IsoField::Density,
        IsoField::Attribute(None),
    ] {
        s += &format!(
            "const {}: u32 = {}u;\n",
            wgsl_name("ISO", f.name()),
            iso_code(&f)
        );
    }
    s
}

/// The code of an RBF colouring (`RBF_*`): its index in [`Colouring::ALL`].
pub(crate) fn colouring_code(c: Colouring) -> u32 {
    Colouring::ALL.iter().position(|&x| x == c).unwrap_or(0) as u32
}

/// The code of a noise (`NOISE_*`).
pub(crate) fn noise_code(n: Noise) -> u32 {
    match n {
        Noise::Blue => 0,
        Noise::White => 1,
    }
}

/// Constants rbf.wgsl shares with the CPU renderer, written from the Rust ones: colouring
/// and noise codes, the offset hash, the blue-noise mask's side and temporal step, and the
/// Gaussian's truncation in standard deviations.
pub(crate) fn rbf_prelude() -> String {
    let mut s = String::new();
    for c in Colouring::ALL {
        s += &format!(
            "const {}: u32 = {}u;\n",
            wgsl_name("RBF", c.name()),
            colouring_code(c)
        );
    }
    for (n, name) in [(Noise::Blue, "BLUE"), (Noise::White, "WHITE")] {
        s += &format!("const NOISE_{name}: u32 = {}u;\n", noise_code(n));
    }
    s += &format!(
        "const HASH_SEED: u32 = {}u;\nconst HASH_IN: u32 = {}u;\nconst HASH_MUL0: u32 = {}u;\nconst HASH_MUL1: u32 = {}u;\n",
        fluidcast_render::HASH_SEED,
        fluidcast_render::HASH_IN,
        fluidcast_render::HASH_MUL[0],
        fluidcast_render::HASH_MUL[1]
    );
    s += &format!(
        "const PICK_STREAM: u32 = {}u;\nconst SHADOW_STREAM: u32 = {}u;\nconst MAX_OPTICAL_DEPTH: f32 = {:?};\n",
        fluidcast_render::PICK_STREAM,
        fluidcast_render::SHADOW_STREAM,
        fluidcast_render::MAX_OPTICAL_DEPTH as f32
    );
    s += &format!(
        "const BLUE_SIDE: u32 = {}u;\nconst GOLDEN: f32 = {:?};\nconst SIGMAS: f32 = {:?};\n",
        fluidcast_render::bluenoise::MASK_SIDE,
        fluidcast_render::bluenoise::GOLDEN as f32,
        fluidcast_rbf::SIGMAS as f32
    );
    s
}

pub(crate) fn frame_uniform(
    frame: &ViewFrame,
    params: &RenderParams,
    tf: &TransferFunction,
    n: usize,
    loop_limit: u32,
) -> FrameUniform {
    let v4 = |v: glam::DVec3| [v.x as f32, v.y as f32, v.z as f32, 0.0];
    let d = params.grid.bundle;
    let a = &params.adaptive;
    FrameUniform {
        eye: v4(frame.eye),
        right: v4(frame.right),
        up: v4(frame.up),
        forward: v4(frame.forward),
        width: frame.width,
        height: frame.height,
        bundles_x: frame.width.div_ceil(d),
        bundles_y: frame.height.div_ceil(d),
        bundle: d,
        dz: params.grid.depth_samples,
        cells_z: 0,
        n_depths: 0,
        aspect: frame.aspect as f32,
        tan_half: frame.tan_half as f32,
        parallel_scale: frame.parallel.unwrap_or(0.0) as f32,
        min_transmittance: params.min_transmittance as f32,
        field: field_code(params.field),
        kernel: kernel_code(params.kernel),
        gauss_norm: gaussian_norm() as f32,
        n_colors: tf.colors.len() as u32,
        n_opacity: tf.opacity.len() as u32,
        tf_lo: tf.range.0 as f32,
        tf_hi: tf.range.1 as f32,
        unit_distance: tf.unit_distance as f32,
        has_limit: params.depth_limit.is_some() as u32 | (params.depth_near.is_some() as u32) << 1,
        n_particles: n as u32,
        near: 0.0,
        far: 0.0,
        tolerance: a.tolerance.map_or(-1.0, |e| e as f32),
        relax: a.relax as f32,
        budget: a
            .tolerance
            .map_or(0.0, |e| (e - params.min_transmittance.max(0.0)) as f32),
        superpixels: a.superpixels as u32,
        surface_rule: a.uses_surface_cells() as u32,
        max_level: params.grid.max_level(),
        n_pairs: 0,
        n_cells: 0,
        loop_limit,
        pad: [0; 3],
    }
}

/// The Gaussian kernel's normalisation constant c (`fluidcast_sph::Kernel::eval`): W(0, H) =
/// 1 / (c σ³) with σ = H/3.
fn gaussian_norm() -> f64 {
    let h = 3.0; // σ = 1
    1.0 / Kernel::Gaussian.eval(0.0, h)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::mem::{offset_of, size_of};

    /// The WGSL struct `name`: its size and its members' offsets, as naga lays them out.
    fn wgsl_layout(name: &str) -> (u32, Vec<(String, u32)>) {
        let shader = match name {
            "Surf" | "Walk" => format!(
                "{}{}",
                surface_prelude(),
                include_str!("shaders/surface.wgsl")
            ),
            _ => format!("{}{}", rbf_prelude(), include_str!("shaders/rbf.wgsl")),
        };
        let src = format!(
            "{}{}{}",
            wgsl_prelude(),
            include_str!("shaders/common.wgsl"),
            shader
        );
        let module = naga::front::wgsl::parse_str(&src).unwrap();
        let mut layouter = naga::proc::Layouter::default();
        layouter.update(module.to_ctx()).unwrap();
        let (handle, ty) = module
            .types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some(name))
            .unwrap_or_else(|| panic!("no struct {name} in common.wgsl"));
        let naga::TypeInner::Struct { members, .. } = &ty.inner else {
            panic!("{name} is not a struct");
        };
        let members = members
            .iter()
            .map(|m| (m.name.clone().unwrap_or_default(), m.offset))
            .collect();
        (layouter[handle].size, members)
    }

    /// Each named Rust field sits where the WGSL member of the same name does, and the
    /// structs have the same size.
    macro_rules! same_layout {
        ($rust:ty, $wgsl:literal, [$($field:ident),* $(,)?]) => {{
            let (size, members) = wgsl_layout($wgsl);
            assert_eq!(size as usize, size_of::<$rust>(), "size of {}", $wgsl);
            let mut checked = 0;
            $(
                let name = stringify!($field);
                let wgsl = members.iter().find(|m| m.0 == name)
                    .unwrap_or_else(|| panic!("{}.{name} is not in the WGSL", $wgsl));
                assert_eq!(wgsl.1 as usize, offset_of!($rust, $field), "{}.{name}", $wgsl);
                checked += 1;
            )*
            // Every WGSL member but padding has a Rust field.
            let real = members.iter().filter(|m| !m.0.starts_with("pad")).count();
            assert_eq!(checked, real, "{} has members without a Rust field", $wgsl);
        }};
    }

    /// The host sizes the buffer of walks in progress by surface.wgsl's `Walk` (no padding).
    #[test]
    fn a_walk_in_progress_is_as_large_as_the_host_allots() {
        let (size, _) = wgsl_layout("Walk");
        assert_eq!(u64::from(size), crate::surface::WALK_BYTES);
    }

    #[test]
    fn host_structs_match_the_wgsl_layout() {
        same_layout!(
            FrameUniform,
            "Frame",
            [
                eye,
                right,
                up,
                forward,
                width,
                height,
                bundles_x,
                bundles_y,
                bundle,
                dz,
                cells_z,
                n_depths,
                aspect,
                tan_half,
                parallel_scale,
                min_transmittance,
                field,
                kernel,
                gauss_norm,
                n_colors,
                n_opacity,
                tf_lo,
                tf_hi,
                unit_distance,
                has_limit,
                n_particles,
                near,
                far,
                tolerance,
                relax,
                budget,
                superpixels,
                surface_rule,
                max_level,
                n_pairs,
                n_cells,
                loop_limit
            ]
        );
        same_layout!(GpuCell, "Cell", [z, start, unique_end, end, bundle]);
        same_layout!(
            RbfUniform,
            "Rbf",
            [
                root_lo,
                root_hi,
                step,
                first_leaf,
                n_slots,
                leaf_size,
                spp,
                first_pass,
                seed,
                colouring,
                noise,
                round,
                shadows,
                shadow_samples,
                light,
                ambient,
                scatter
            ]
        );
        same_layout!(
            SurfaceUniform,
            "Surf",
            [
                values,
                colour,
                light,
                ambient,
                diffuse,
                specular,
                specular_power,
                n_values,
                iso,
                has_b,
                opacity,
                round,
                band_y0,
                band_rows,
                scatter
            ]
        );
        same_layout!(
            GpuSpan,
            "Span",
            [first, count, level, superpixel, k0, n, step, sp]
        );
    }

    #[test]
    fn kernel_and_field_codes_reach_the_shaders() {
        let p = wgsl_prelude();
        for (k, name) in [
            (Kernel::CubicSpline, "KERNEL_CUBIC"),
            (Kernel::WendlandC2, "KERNEL_WENDLAND_C2"),
            (Kernel::Gaussian, "KERNEL_GAUSSIAN"),
        ] {
            assert!(
                p.contains(&format!("const {name}: u32 = {}u;", kernel_code(k))),
                "{p}"
            );
        }
        assert!(p.contains(&format!(
            "const FIELD_DENSITY: u32 = {}u;",
            field_code(FieldKind::Density)
        )));
        let codes: std::collections::BTreeSet<u32> =
            Kernel::ALL.iter().map(|&k| kernel_code(k)).collect();
        assert_eq!(codes.len(), Kernel::ALL.len());
    }
}
