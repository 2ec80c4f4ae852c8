//! `ogm-corners info`: the GPU adapters wgpu finds.

use clap::Args;

use ogm_corners::backend::gpu;
use ogm_corners::Result;

use super::{write_stdout, TextOrJson};

#[derive(Args, Debug)]
pub(super) struct InfoArgs {
    /// Output format.
    #[arg(long, value_enum, default_value = "text")]
    format: TextOrJson,
}

pub(super) fn run(a: InfoArgs) -> Result<()> {
    let adapters = gpu::list_adapters();
    write_stdout(|out| {
        if a.format == TextOrJson::Json {
            serde_json::to_writer_pretty(&mut *out, &adapters)?;
            writeln!(out)?;
            return out.flush();
        }
        if adapters.is_empty() {
            writeln!(
                out,
                "no adapters found (WGPU_BACKEND={}); install a Vulkan driver, e.g. mesa-vulkan-drivers",
                std::env::var("WGPU_BACKEND").unwrap_or_else(|_| "unset".into())
            )?;
        }
        for (i, r) in adapters.iter().enumerate() {
            writeln!(out, "adapter {i}: {}", r.name)?;
            writeln!(
                out,
                "  backend: {}, device type: {}",
                r.backend, r.device_type
            )?;
            writeln!(out, "  driver: {}", r.driver)?;
            writeln!(
                out,
                "  max_storage_buffer_binding_size: {} MiB, max_buffer_size: {} MiB",
                r.max_storage_buffer_binding_size >> 20,
                r.max_buffer_size >> 20
            )?;
            writeln!(
                out,
                "  max_compute_workgroups_per_dimension: {}, timestamp queries: {}, shader int64: {}",
                r.max_compute_workgroups_per_dimension, r.timestamp_query, r.shader_int64
            )?;
        }
        out.flush()
    })
}
