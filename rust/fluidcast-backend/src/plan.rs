//! What a frame asks for: the [`RenderPlan`], one struct for every front-end.
//!
//! The CLI fills it from its options, the VTK mapper and ParaView from their properties and
//! Python from its arguments; [`crate::Renderer::render`] draws it. A choice the library
//! makes for the caller (the renderer under iso-surfaces) is made here, once, with the note
//! that says so.

use fluidcast_rbf::RbfOptions;
use fluidcast_render::{RbfRenderParams, RenderParams};

use fluidcast_render::IsoField;

use crate::{Backend, BackendError, PlanItem};

/// How the SPH volume is sampled along the rays.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// The adaptive grid renderer (Hochstetter et al. 2016), on the renderer's backend.
    Adaptive,
    /// The reference renderer: every particle of a tile scattered into every ray (CPU).
    Reference,
    /// The perspective grid of Fraedrich et al. 2010, one column per `cell` pixels (CPU).
    PerspectiveGrid {
        /// Pixels per grid column side (1..=16).
        cell: u32,
    },
    /// The object-space baseline of Hochstetter et al.'s comparison: every sample gathers
    /// its particles from a world-space neighbour grid (CPU; slow, for benchmarks).
    ObjectSpace,
}

impl Mode {
    /// The names front-ends give the mode (the CLI's `--mode`, the mapper's Mode), in the
    /// order of ParaView's `FluidCastMode` after its first entry, "auto" (the library's
    /// choice). The perspective grid takes its cell size apart.
    pub const NAMES: [&'static str; 4] = ["auto", "adaptive", "reference", "perspective-grid"];

    /// The mode `name` names ([`Mode::NAMES`]; "" and "auto": `None`, the library's choice),
    /// with `cell` pixels per perspective-grid column.
    pub fn parse(name: &str, cell: u32) -> Result<Option<Mode>, String> {
        match name.trim().to_ascii_lowercase().as_str() {
            "" | "auto" => Ok(None),
            "adaptive" => Ok(Some(Mode::Adaptive)),
            "reference" => Ok(Some(Mode::Reference)),
            "perspective-grid" => Ok(Some(Mode::PerspectiveGrid { cell })),
            other => Err(format!(
                "mode '{other}': expected one of {}",
                Mode::NAMES.join(", ")
            )),
        }
    }
}

/// Rendering one view in screen tiles, each with only the particles that reach it: the same
/// image in less memory.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Tiles {
    /// At least this many tiles (`None`: as the budget needs).
    pub count: Option<u32>,
    /// The most bytes the render itself may hold (particles copied into tiles, images);
    /// `None`: no limit. Front-ends subtract what their process holds already.
    pub budget_bytes: Option<u64>,
}

/// What the stochastic ray marcher draws instead of the sampled SPH volume.
#[derive(Debug, Clone)]
pub enum Marched {
    /// The attribute-aware RBF field of Morrical et al. 2023 with these options.
    Rbf(RbfOptions),
    /// The SPH field `RenderParams::kernel`/`field` names, lit with shadows (CPU only: the
    /// GPU's march sums Gaussians).
    Sph,
}

/// The stochastic ray march: field, passes and progressive accumulation.
#[derive(Debug, Clone)]
pub struct March {
    /// The field marched.
    pub field: Marched,
    /// Passes per render, seed, step, noise, shadows. `first_pass` is set by the renderer.
    pub params: RbfRenderParams,
    /// Passes accumulated over renders of an unchanged view (ParaView's still renders);
    /// at most `params.spp` means none: every render draws `spp` fresh passes.
    pub progressive_passes: u32,
    /// Also time one refit of the field's BVH to its radius map (stage `refit`).
    pub time_refit: bool,
}

/// Everything a frame asks for besides the scene: one struct for every front-end.
#[derive(Debug, Clone, Default)]
pub struct RenderPlan {
    /// Image size, kernel, field, error tolerance and plan switches, iso-surfaces, lighting,
    /// depth limits: what the renderers share.
    pub params: RenderParams,
    /// `None`: the library's choice ([`RenderPlan::mode_for`]).
    pub mode: Option<Mode>,
    /// Screen tiles under a memory budget.
    pub tiles: Tiles,
    /// Level of detail (Fraedrich et al. 2010): the largest merged cell edge, pixels at its
    /// depth (0: full detail, Morton-ordered); `None`: every particle as given.
    pub lod: Option<f64>,
    /// The stochastic march (RBF field, or shadows) instead of the sampled volume.
    pub march: Option<March>,
    /// The most kernel evaluations a frame may be estimated to take before it runs
    /// ([`crate::work::estimate`]); above it the render is refused with a message.
    /// `None`: [`crate::work::DEFAULT_WORK_LIMIT`]; infinity: no limit.
    pub work_limit: Option<f64>,
}

/// The note [`RenderPlan::mode_for`] gives when iso-surfaces or a shaded volume take the
/// reference renderer.
pub const REFERENCE_FOR_SURFACES: &str = "rendering with the reference ray caster (exact, and it composites translucent surfaces with the volume)";

/// The note [`RenderPlan::mode_for`] gives when iso-surfaces are drawn in the adaptive mode.
pub const SURFACES_OVER_ADAPTIVE: &str = "iso-surfaces are found exactly along each ray on the CPU; the adaptive renderer draws only the volume in front of them (when the volume is asked for)";

/// [`SURFACES_OVER_ADAPTIVE`] where the renderer is on the GPU, which finds the surfaces too.
pub const SURFACES_ON_GPU: &str = "iso-surfaces are found exactly along each ray on the GPU (in single precision); the adaptive renderer draws only the volume in front of them (when the volume is asked for)";

/// The note of [`RenderPlan::mode_for`] for a renderer that is (`on_gpu`) or is not on the
/// GPU: which device finds the surfaces is known once the backend is open.
pub fn device_note(note: Option<&'static str>, on_gpu: bool) -> Option<&'static str> {
    match note {
        Some(SURFACES_OVER_ADAPTIVE) if on_gpu => Some(SURFACES_ON_GPU),
        n => n,
    }
}

impl RenderPlan {
    /// Refuses what the renderer does not draw yet, naming the part of the plan
    /// ([`BackendError::Refused`]): level of detail with iso-surfaces of another array; the
    /// stochastic march with level of detail, tiles, surfaces, a shaded volume or a mode.
    /// [`crate::Renderer::render`] runs it; a front-end runs it early to refuse options
    /// before reading any data.
    pub fn check(&self) -> Result<(), BackendError> {
        check_lod(self)?;
        if self.march.is_some() {
            check_march(self)?;
        }
        Ok(())
    }

    /// The image size, pixels (width, height).
    pub fn size(&self) -> (u32, u32) {
        (self.params.width, self.params.height)
    }

    /// The mode this plan renders in with `backend` asked for, and a note when the library
    /// chose it: iso-surfaces (except on an explicitly asked GPU, whose adaptive volume the
    /// surfaces stop) and a shaded volume take the reference renderer; otherwise adaptive.
    /// The stochastic march has no mode.
    ///
    /// In the adaptive mode (asked for, or on an asked GPU) iso-surfaces are still found by the
    /// exact caster on the CPU, with the adaptive renderer drawing only the volume in front of
    /// them: the note ([`SURFACES_OVER_ADAPTIVE`]) says so rather than let a user think the
    /// surfaces were drawn adaptively.
    pub fn mode_for(&self, backend: Backend) -> (Mode, Option<&'static str>) {
        let surfaces = self.params.surfaces.is_some() && self.march.is_none();
        let mode = match self.mode {
            Some(m) => m,
            None if (surfaces && backend != Backend::Gpu)
                || (self.march.is_none() && self.params.volume_lighting.is_some()) =>
            {
                return (Mode::Reference, Some(REFERENCE_FOR_SURFACES));
            }
            None => Mode::Adaptive,
        };
        let note = (surfaces && mode == Mode::Adaptive).then_some(SURFACES_OVER_ADAPTIVE);
        (mode, note)
    }
}

/// Level of detail merges the rendered attribute only: iso-surfaces of another array are
/// refused with it.
fn check_lod(plan: &RenderPlan) -> Result<(), BackendError> {
    let other = plan
        .params
        .surfaces
        .as_ref()
        .is_some_and(|s| matches!(s.field, IsoField::Attribute(Some(_))));
    if plan.lod.is_some() && other {
        return Err(BackendError::Refused {
            item: PlanItem::Lod,
            why: "level of detail with iso-surfaces of another array: the hierarchy merges the rendered array only; turn level of detail off or draw surfaces of the rendered array".into(),
        });
    }
    Ok(())
}

/// What the stochastic march does not do yet, refused by name.
fn check_march(plan: &RenderPlan) -> Result<(), BackendError> {
    let refuse = |item, why: &str| {
        let why = why.to_string();
        Err(BackendError::Refused { item, why })
    };
    if plan.lod.is_some() {
        return refuse(PlanItem::Lod, "level of detail does not apply to the RBF field and shadows, which have their own cluster hierarchy");
    }
    if plan.tiles != Tiles::default() {
        return refuse(PlanItem::Tiles, "the RBF field and shadows do not render in screen tiles (a memory limit or a tile count) yet");
    }
    if plan.params.surfaces.is_some() || plan.params.volume_lighting.is_some() {
        return refuse(
            PlanItem::Surfaces,
            "the RBF field and shadows draw no iso-surfaces and no shaded volume yet",
        );
    }
    if plan.mode.is_some() {
        return refuse(
            PlanItem::Mode,
            "the RBF field and shadows are drawn by their own ray marcher: no mode applies",
        );
    }
    Ok(())
}
