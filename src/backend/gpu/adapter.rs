//! Finding GPU adapters: what `ogm-corners info` lists, and which adapter the backend opens.

use crate::support::error::{Error, Result};

/// What `ogm-corners info` prints about an adapter.
#[derive(Clone, Debug, serde::Serialize)]
pub struct AdapterReport {
    /// Adapter name, e.g. "llvmpipe (LLVM 15.0.6, 256 bits)".
    pub name: String,
    /// Vulkan, Metal, Dx12, Gl.
    pub backend: String,
    /// DiscreteGpu, IntegratedGpu, VirtualGpu, Cpu, Other.
    pub device_type: String,
    /// Driver name and version.
    pub driver: String,
    /// Largest storage buffer binding, bytes: bounds the tile size.
    pub max_storage_buffer_binding_size: u64,
    /// Largest buffer, bytes.
    pub max_buffer_size: u64,
    /// Largest dispatch in one dimension.
    pub max_compute_workgroups_per_dimension: u32,
    /// Whether kernel times can be measured on the GPU itself.
    pub timestamp_query: bool,
    /// Whether 64-bit integers are available in shaders.
    pub shader_int64: bool,
    /// Smallest and largest subgroup the adapter may run (the kernels assume neither).
    pub subgroup_sizes: (u32, u32),
    /// Whether shaders can use subgroup operations (`Features::SUBGROUP`; reported, not used: the OGM
    /// kernel loads the pixels beside its run itself).
    pub subgroups: bool,
}

pub(super) fn report(a: &wgpu::Adapter) -> AdapterReport {
    let info = a.get_info();
    let limits = a.limits();
    let features = a.features();
    AdapterReport {
        name: info.name.clone(),
        backend: format!("{:?}", info.backend),
        device_type: format!("{:?}", info.device_type),
        driver: format!("{} {}", info.driver, info.driver_info)
            .trim()
            .to_string(),
        max_storage_buffer_binding_size: limits.max_storage_buffer_binding_size,
        max_buffer_size: limits.max_buffer_size,
        max_compute_workgroups_per_dimension: limits.max_compute_workgroups_per_dimension,
        timestamp_query: features.contains(wgpu::Features::TIMESTAMP_QUERY),
        shader_int64: features.contains(wgpu::Features::SHADER_INT64),
        subgroup_sizes: (info.subgroup_min_size, info.subgroup_max_size),
        subgroups: features.contains(wgpu::Features::SUBGROUP),
    }
}

fn instance() -> wgpu::Instance {
    wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env())
}

fn enumerate(instance: &wgpu::Instance) -> Vec<wgpu::Adapter> {
    let backends = wgpu::Backends::from_env().unwrap_or(wgpu::Backends::all());
    pollster::block_on(instance.enumerate_adapters(backends))
}

/// Every adapter wgpu finds (honouring `WGPU_BACKEND`).
pub fn list_adapters() -> Vec<AdapterReport> {
    enumerate(&instance()).iter().map(report).collect()
}

/// What the environment asked for, for error messages.
pub(super) fn looked_for() -> String {
    let var = |k: &str| std::env::var(k).unwrap_or_else(|_| "unset".into());
    format!(
        "wgpu adapters on backends {:?} (WGPU_BACKEND={}, WGPU_ADAPTER_NAME={})",
        wgpu::Backends::from_env().unwrap_or(wgpu::Backends::all()),
        var("WGPU_BACKEND"),
        var("WGPU_ADAPTER_NAME")
    )
}

/// Refuses a `WGPU_BACKEND` naming a backend wgpu does not know (wgpu would skip it with a log line
/// nobody sees, and the run would quietly find no GPU).
fn check_backend_env() -> Result<()> {
    const KNOWN: [&str; 10] = [
        "vulkan", "vk", "dx12", "d3d12", "metal", "mtl", "opengl", "gles", "gl", "webgpu",
    ];
    let Ok(v) = std::env::var("WGPU_BACKEND") else {
        return Ok(());
    };
    let lower = v.to_lowercase();
    let unknown: Vec<&str> = lower
        .split(',')
        .map(str::trim)
        .filter(|b| !b.is_empty() && !KNOWN.contains(b) && *b != "noop")
        .collect();
    if unknown.is_empty() {
        return Ok(());
    }
    Err(Error::invalid(format!(
        "WGPU_BACKEND={}: unknown backend {}; use vulkan, metal, dx12 or gl (comma-separated)",
        crate::support::error::one_line(&v),
        crate::support::error::one_line(&unknown.join(", "))
    )))
}

/// Preference order of device types: real GPUs first, software rasterisers last.
fn rank(t: wgpu::DeviceType) -> u8 {
    match t {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Other => 3,
        wgpu::DeviceType::Cpu => 4,
    }
}

/// Picks an adapter: the one `WGPU_ADAPTER_NAME` names (a case-insensitive substring), else the best by
/// device type. With `hardware_only`, a software adapter (lavapipe, WARP) is not chosen unless named.
/// `Ok(None)` when there is none to choose.
pub(super) fn choose(hardware_only: bool) -> Result<Option<(wgpu::Instance, wgpu::Adapter)>> {
    check_backend_env()?;
    let instance = instance();
    let adapters = enumerate(&instance);
    if let Ok(want) = std::env::var("WGPU_ADAPTER_NAME") {
        let want_l = want.to_lowercase();
        return match adapters
            .into_iter()
            .find(|a| a.get_info().name.to_lowercase().contains(&want_l))
        {
            Some(a) => Ok(Some((instance, a))),
            None => Err(Error::Unavailable(format!(
                "no adapter matches WGPU_ADAPTER_NAME={want:?}; `ogm-corners info` lists the adapters"
            ))),
        };
    }
    let best = adapters
        .into_iter()
        .min_by_key(|a| rank(a.get_info().device_type));
    Ok(match best {
        Some(a) if hardware_only && a.get_info().device_type == wgpu::DeviceType::Cpu => None,
        Some(a) => Some((instance, a)),
        None => None,
    })
}
