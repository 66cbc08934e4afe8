//! fluidcast's one render API: a [`Scene`], a [`RenderPlan`] and [`Renderer::render`].
//!
//! Every front-end (the CLI, the VTK mapper and ParaView through the C++ bridge, Python)
//! builds a [`Scene`] (particles, camera, transfer function) and a [`RenderPlan`] (mode,
//! field, tolerance and plan switches, tiles, level of detail, the RBF march and its passes)
//! and calls [`Renderer::render`], which returns a [`Rendered`]: image, statistics, the
//! device and notes. A feature written here reaches them all.
//!
//! A [`Renderer`] is opened once for a [`Backend`] (cpu, gpu or auto) and kept: on the GPU it
//! holds the wgpu device, its compiled pipelines and the buffers that frames reuse. A
//! [`Scene`] keeps what renders of its particles reuse (surface flags, the level-of-detail
//! hierarchy and cut, the RBF field's BVH, accumulated passes). `auto` takes a hardware GPU
//! when there is one and otherwise renders on the CPU with a note: a software driver (Mesa's
//! lavapipe or llvmpipe) is slower than the CPU renderer, so it is used only when asked for
//! (`gpu`, or an adapter by name).
#![warn(missing_docs)]

use std::fmt;
use std::str::FromStr;

pub mod defaults;
mod frame;
mod march;
mod plan;
mod scene;
pub mod settings;
pub mod work;

pub use frame::{tile_particles, Rendered};

pub use plan::{
    device_note, March, Marched, Mode, RenderPlan, Tiles, REFERENCE_FOR_SURFACES, SURFACES_ON_GPU,
    SURFACES_OVER_ADAPTIVE,
};
pub use scene::{LodReport, Scene};
pub use settings::{check_property, Setting, SettingError, SETTINGS};

pub use fluidcast_gpu::{list_adapters, AdapterChoice, Gpu, GpuError, ADAPTER_ENV};
/// What a plan is made of, from the crates that draw it: front-ends name these here.
pub use fluidcast_rbf::{
    AttributeMap, Colouring, RbfError, RbfOptions, DEFAULT_LEAF_SIZE, MAX_LEAF_SIZE,
};
pub use fluidcast_render::{
    crop_to_box, support_depth_extent, GridParams, ImageOutput, IsoField, Noise, PlanParams,
    Progress, RbfRenderParams, RbfShadows, RenderError, RenderParams, RenderStats, Surfaces,
    Transfers, MAX_CELL, MAX_SIDE, MIN_TILE_BYTES,
};

/// Where the adaptive renderer runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Backend {
    /// The CPU renderer (rayon, f64).
    Cpu,
    /// Every stage on a wgpu adapter (f32): the best one, or the one named.
    Gpu,
    /// A hardware GPU if there is one, else the CPU (with a note).
    #[default]
    Auto,
}

impl Backend {
    /// The names [`Backend::from_str`] takes, in the order of ParaView's `FluidCastBackend`.
    pub const NAMES: [&'static str; 3] = ["auto", "cpu", "gpu"];
}

impl FromStr for Backend {
    type Err = BackendError;
    fn from_str(s: &str) -> Result<Backend, BackendError> {
        match s.trim().to_ascii_lowercase().as_str() {
            "cpu" => Ok(Backend::Cpu),
            "gpu" => Ok(Backend::Gpu),
            "auto" | "" => Ok(Backend::Auto),
            _ => Err(BackendError::Name(s.to_string())),
        }
    }
}

impl fmt::Display for Backend {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Backend::Cpu => "cpu",
            Backend::Gpu => "gpu",
            Backend::Auto => "auto",
        })
    }
}

/// Why a backend could not be opened or a frame not rendered.
#[derive(Debug, thiserror::Error)]
pub enum BackendError {
    /// A backend name other than auto, cpu or gpu.
    #[error("backend '{0}': expected auto, cpu or gpu")]
    Name(String),
    /// The GPU could not be opened or could not draw the frame.
    #[error(transparent)]
    Gpu(#[from] GpuError),
    /// A CPU renderer refused the frame (parameters, surfaces, memory budget).
    #[error(transparent)]
    Render(#[from] RenderError),
    /// The RBF field could not be built (radii, attribute, leaf size).
    #[error(transparent)]
    Rbf(#[from] RbfError),
    /// The level-of-detail hierarchy or cut could not be made.
    #[error("level of detail: {0}")]
    Lod(#[from] fluidcast_lod::LodError),
    /// The camera cannot see (a degenerate or non-finite view).
    #[error("{0}")]
    Camera(#[from] fluidcast_view::CameraError),
    /// A plan the renderer cannot draw (a combination not supported yet), said in words;
    /// `item` says which part of the plan, for a front-end to name its option or property.
    #[error("{why}")]
    Refused {
        /// The part of the plan refused.
        item: PlanItem,
        /// Why, for the user.
        why: String,
    },
    /// A state the renderer should never be in (a bug), said in words.
    #[error("{0}")]
    Plan(String),
}

/// A part of a [`RenderPlan`], as a refusal names it ([`BackendError::item`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlanItem {
    /// [`RenderPlan::mode`].
    Mode,
    /// [`RenderPlan::tiles`]: a tile count or memory budget.
    Tiles,
    /// [`RenderPlan::lod`].
    Lod,
    /// Iso-surfaces or the shaded volume in [`RenderParams`].
    Surfaces,
    /// [`RenderPlan::work_limit`]: the frame's estimated work is above it.
    Work,
}

impl BackendError {
    /// Whether a memory budget was too small for even one screen tile.
    pub fn is_memory_budget(&self) -> bool {
        matches!(self, BackendError::Render(RenderError::MemoryBudget { .. }))
    }

    /// The part of the plan that was refused, if one was.
    pub fn item(&self) -> Option<PlanItem> {
        match self {
            BackendError::Refused { item, .. } => Some(*item),
            e if e.is_memory_budget() => Some(PlanItem::Tiles),
            BackendError::Lod(_) => Some(PlanItem::Lod),
            _ => None,
        }
    }
}

/// An opened backend: the CPU, or a GPU device kept for every frame it renders.
pub struct Renderer {
    /// The backend asked for (the library's choice of mode depends on it).
    requested: Backend,
    gpu: Option<Gpu>,
    note: Option<String>,
}

impl Renderer {
    /// The CPU renderer.
    pub fn cpu() -> Renderer {
        Renderer {
            requested: Backend::Cpu,
            gpu: None,
            note: None,
        }
    }

    /// Opens `backend`. `adapter` (or else `FLUIDCAST_ADAPTER`) names a wgpu adapter by part
    /// of its name; with `auto` a named adapter is used even if it is a software driver.
    pub fn open(backend: Backend, adapter: Option<&str>) -> Result<Renderer, BackendError> {
        let named = adapter
            .filter(|a| !a.trim().is_empty())
            .map(|a| AdapterChoice::Named(a.trim().to_string()))
            .or_else(AdapterChoice::from_env);
        match backend {
            Backend::Cpu => Ok(Renderer::cpu()),
            Backend::Gpu => {
                let choice = named.unwrap_or(AdapterChoice::Any);
                Ok(Renderer {
                    requested: backend,
                    gpu: Some(Gpu::open(&choice)?),
                    note: None,
                })
            }
            Backend::Auto => {
                let choice = named.unwrap_or(AdapterChoice::Hardware);
                match Gpu::open(&choice) {
                    Ok(g) => Ok(Renderer {
                        requested: backend,
                        gpu: Some(g),
                        note: None,
                    }),
                    Err(e) => Ok(Renderer {
                        requested: backend,
                        gpu: None,
                        note: Some(format!("backend auto: {e}; rendering on the CPU")),
                    }),
                }
            }
        }
    }

    /// Frames on `gpu`, opened (and limited: [`Gpu::with_loop_limit`],
    /// [`Gpu::with_binding_limit`]) by the caller.
    pub fn with_gpu(gpu: Gpu) -> Renderer {
        Renderer {
            requested: Backend::Gpu,
            gpu: Some(gpu),
            note: None,
        }
    }

    /// The GPU, when frames render on one.
    pub fn gpu(&self) -> Option<&Gpu> {
        self.gpu.as_ref()
    }

    /// Where frames render: "CPU (N threads)" or the adapter, "NVIDIA H200 (Vulkan)".
    pub fn device(&self) -> String {
        match &self.gpu {
            Some(g) => format!("GPU: {}", g.adapter),
            None => format!("CPU ({} threads)", rayon::current_num_threads()),
        }
    }

    /// The backend asked for.
    pub fn backend(&self) -> Backend {
        self.requested
    }

    /// Why `auto` fell back to the CPU, if it did.
    pub fn note(&self) -> Option<&str> {
        self.note.as_deref()
    }
}
