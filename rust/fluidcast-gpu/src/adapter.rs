//! Choosing the wgpu adapter: hardware GPUs before software drivers, or one by name.
//!
//! `Instance::default()` with `request_adapter` takes whatever the platform lists first; on a
//! machine with a GPU and Mesa's lavapipe installed that can be the software driver. Here all
//! adapters are listed and ranked: discrete GPU, integrated, virtual, other, then CPU
//! (software); among equals Vulkan, Metal, DX12, then OpenGL.

use crate::GpuError;

/// Environment variable naming the adapter to use, as `--adapter` does (a case-insensitive
/// part of its name: `nvidia`, `llvmpipe`, …).
pub const ADAPTER_ENV: &str = "FLUIDCAST_ADAPTER";

/// Which adapter [`crate::Gpu::open`] takes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum AdapterChoice {
    /// The best hardware GPU; [`GpuError::NoHardware`] when there are only software drivers.
    Hardware,
    /// The best adapter of any kind, software drivers (lavapipe, llvmpipe) last.
    Any,
    /// The best adapter whose name contains this, case-insensitively.
    Named(String),
}

impl AdapterChoice {
    /// [`AdapterChoice::Named`] from `FLUIDCAST_ADAPTER`, when it is set and not empty.
    pub fn from_env() -> Option<AdapterChoice> {
        std::env::var(ADAPTER_ENV)
            .ok()
            .filter(|v| !v.trim().is_empty())
            .map(|v| AdapterChoice::Named(v.trim().to_string()))
    }
}

/// An instance of only these APIs: an instance of all would start OpenGL/EGL too, which probes
/// for a display and prints warnings on a headless machine even when Vulkan serves.
fn instance(backends: wgpu::Backends) -> wgpu::Instance {
    let mut desc = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
    desc.backends = backends;
    wgpu::Instance::new(desc)
}

/// Smaller is better: device kind, then graphics API.
fn rank(info: &wgpu::AdapterInfo) -> (u8, u8) {
    let kind = match info.device_type {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Other => 3,
        wgpu::DeviceType::Cpu => 4,
    };
    let api = match info.backend {
        wgpu::Backend::Vulkan => 0,
        wgpu::Backend::Metal => 1,
        wgpu::Backend::Dx12 => 2,
        _ => 3,
    };
    (kind, api)
}

fn describe(info: &wgpu::AdapterInfo) -> String {
    let kind = match info.device_type {
        wgpu::DeviceType::Cpu => ", software",
        _ => "",
    };
    format!("{} ({:?}{kind})", info.name, info.backend)
}

/// Every adapter wgpu finds, best first, as "name (API[, software])": those of the primary
/// APIs (Vulkan, Metal, DX12), or OpenGL's when there are none.
pub fn list_adapters() -> Vec<String> {
    ranked().iter().map(|a| describe(&a.get_info())).collect()
}

/// Adapters best first: of the primary APIs, falling back to OpenGL only when they have none.
/// A name is looked up among these too: probing OpenGL/EGL prints warnings on headless Linux,
/// and inside a process that holds an OpenGL context of its own (ParaView, a VTK window) wgpu's
/// EGL probe panics (BadAccess), which a misspelt adapter name then reached.
fn ranked() -> Vec<wgpu::Adapter> {
    let list = |b| pollster::block_on(instance(b).enumerate_adapters(b));
    let mut found = list(wgpu::Backends::PRIMARY);
    if found.is_empty() {
        found = list(wgpu::Backends::SECONDARY);
    }
    found.sort_by_key(|a| rank(&a.get_info()));
    found
}

/// The adapter `choice` picks (an adapter by name among those [`list_adapters`] gives).
pub(crate) fn pick(choice: &AdapterChoice) -> Result<wgpu::Adapter, GpuError> {
    let all = ranked();
    let names = || {
        let v: Vec<String> = all.iter().map(|a| describe(&a.get_info())).collect();
        if v.is_empty() {
            "none".to_string()
        } else {
            v.join(", ")
        }
    };
    let found = match choice {
        AdapterChoice::Any => all.first(),
        AdapterChoice::Hardware => all
            .iter()
            .find(|a| a.get_info().device_type != wgpu::DeviceType::Cpu),
        AdapterChoice::Named(n) => {
            let n = n.to_lowercase();
            all.iter()
                .find(|a| a.get_info().name.to_lowercase().contains(&n))
        }
    };
    match (found, choice) {
        (Some(a), _) => Ok(a.clone()),
        (None, AdapterChoice::Named(n)) => Err(GpuError::NoSuchAdapter(n.clone(), names())),
        (None, AdapterChoice::Hardware) if !all.is_empty() => Err(GpuError::NoHardware(names())),
        (None, _) => Err(GpuError::NoAdapter("no adapter listed".into())),
    }
}

/// The name and kind of an opened adapter, for messages ("NVIDIA H200 (Vulkan)").
pub(crate) fn name(adapter: &wgpu::Adapter) -> String {
    describe(&adapter.get_info())
}
