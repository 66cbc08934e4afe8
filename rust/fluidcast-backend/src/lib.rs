//! Where frames render, and the one call that renders them.
//!
//! A [`Renderer`] is opened once for a [`Backend`] (cpu, gpu or auto) and kept: on the GPU it
//! holds the wgpu device, its compiled pipelines and the buffers that frames reuse, so a VTK
//! mapper or a CLI series pays for them once. [`Renderer::render`] runs the adaptive renderer
//! (Hochstetter et al. 2016) there and returns the same [`Rendered`] (image and statistics)
//! either way. `auto` takes a hardware GPU when there is one and otherwise renders on the CPU
//! with a note: a software driver (Mesa's lavapipe or llvmpipe) is slower than the CPU
//! renderer, so it is used only when asked for (`gpu`, or an adapter by name).

use std::fmt;
use std::str::FromStr;

pub use fluidcast_gpu::{list_adapters, AdapterChoice, Gpu, GpuError, ADAPTER_ENV};
pub use fluidcast_render::Rendered;
use fluidcast_render::{render_adaptive, render_over_surfaces, RenderError, RenderParams};
use fluidcast_sph::Particles;
use fluidcast_view::{Camera, TransferFunction};

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
    #[error("backend '{0}': expected auto, cpu or gpu")]
    Name(String),
    #[error(transparent)]
    Gpu(#[from] GpuError),
    #[error(transparent)]
    Render(#[from] RenderError),
}

/// An opened backend: the CPU, or a GPU device kept for every frame it renders.
pub struct Renderer {
    gpu: Option<Gpu>,
    note: Option<String>,
}

impl Renderer {
    /// The CPU renderer.
    pub fn cpu() -> Renderer {
        Renderer {
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
                    gpu: Some(Gpu::open(&choice)?),
                    note: None,
                })
            }
            Backend::Auto => {
                let choice = named.unwrap_or(AdapterChoice::Hardware);
                match Gpu::open(&choice) {
                    Ok(g) => Ok(Renderer {
                        gpu: Some(g),
                        note: None,
                    }),
                    Err(e) => Ok(Renderer {
                        gpu: None,
                        note: Some(format!("backend auto: {e}; rendering on the CPU")),
                    }),
                }
            }
        }
    }

    /// Renders one frame with the adaptive renderer, on this backend's device. Iso-surfaces
    /// (opaque over the volume) are found on the CPU by the reference caster and stop the
    /// adaptive volume as opaque geometry does ([`render_over_surfaces`]).
    pub fn render(
        &self,
        particles: &Particles,
        surface: Option<&[bool]>,
        camera: &Camera,
        tf: &TransferFunction,
        params: &RenderParams,
    ) -> Result<Rendered, BackendError> {
        if params.surfaces.is_none() {
            return self.render_volume(particles, surface, camera, tf, params);
        }
        let what = match self.gpu {
            Some(_) => "the GPU backend",
            None => "the adaptive grid renderer",
        };
        let (image, stats) = render_over_surfaces(particles, camera, tf, params, what, |p| {
            self.render_volume(particles, surface, camera, tf, p)
                .map(|r| (r.image, r.stats))
        })?;
        Ok(Rendered { image, stats })
    }

    /// The adaptive volume alone, on this backend's device.
    fn render_volume(
        &self,
        particles: &Particles,
        surface: Option<&[bool]>,
        camera: &Camera,
        tf: &TransferFunction,
        params: &RenderParams,
    ) -> Result<Rendered, BackendError> {
        match &self.gpu {
            Some(g) => Ok(g.render_adaptive(particles, surface, camera, tf, params)?),
            None => {
                let r = render_adaptive(particles, surface, camera, tf, params)?;
                Ok(Rendered {
                    image: r.image,
                    stats: r.stats,
                })
            }
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

    /// Why `auto` fell back to the CPU, if it did.
    pub fn note(&self) -> Option<&str> {
        self.note.as_deref()
    }
}
