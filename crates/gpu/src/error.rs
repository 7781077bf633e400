//! What can go wrong on a device, as one error type ([`GpuError`]), and the faults a device
//! reports outside any error scope ([`Faults`]), kept until the next check.

use crate::shaders;
use std::sync::Mutex;

/// How to get a driver when no adapter is found.
pub const NO_ADAPTER_HINT: &str = "no GPU adapter found. Install a Vulkan driver; on Debian/Ubuntu the \
     software one is `apt-get install mesa-vulkan-drivers` (lavapipe), or use --backend cpu";

#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    #[error("{NO_ADAPTER_HINT}")]
    NoAdapter,
    #[error("cannot open the GPU device: {0}")]
    Device(String),
    #[error("{var}={value}: {why}")]
    Environment { var: &'static str, value: String, why: String },
    #[error(transparent)]
    Shader(#[from] shaders::ShaderError),
    #[error("{what} needs {need} bytes, more than this adapter allows in one buffer ({limit} bytes, its {limit_name})")]
    TooLarge { what: String, need: u64, limit: u64, limit_name: &'static str },
    #[error(
        "{what} needs {need} bytes: {parts} storage bindings of {part_bytes} bytes (the adapter's {limit_name} \
         bounds one), more than the {max_parts} strahl splits one array into"
    )]
    TooManyParts {
        what: &'static str,
        need: u64,
        parts: u64,
        part_bytes: u64,
        max_parts: u32,
        limit_name: &'static str,
    },
    #[error(
        "the scene's arrays, split across {extra} more storage bindings than usual, need {need} storage buffers \
         per shader stage, more than this adapter allows ({limit}, its max_storage_buffers_per_shader_stage)"
    )]
    TooManyBindings { need: u32, extra: u32, limit: u32 },
    #[error("the scene has {count} spheres, cylinders and triangles; the GPU's BVH layout indexes at most {limit}")]
    TooManyPrimitives { count: usize, limit: usize },
    #[error("GPU error: {0}")]
    Wgpu(String),
    #[error("{what}: the GPU ran out of memory")]
    OutOfMemory { what: String },
    #[error("the GPU device was lost: {0}")]
    Lost(String),
    #[error("the scene's BVH has no GPU layout: it is deeper than the GPU's traversal stack holds ({limit} levels)")]
    TooDeep { limit: u32 },
    #[error("{0} waits for the GPU, which a web page cannot do: use its async form")]
    Blocking(&'static str),
}

/// What the device reports outside any error scope, and its loss: recorded here instead of
/// reaching wgpu's default handler, which panics, and returned as an error by the next
/// [`GpuContext::scoped`] call.
#[derive(Default)]
pub(crate) struct Faults {
    pub(crate) uncaptured: Mutex<Option<String>>,
    pub(crate) lost: Mutex<Option<String>>,
}

impl Faults {
    pub(crate) fn record(slot: &Mutex<Option<String>>, message: String) {
        slot.lock().unwrap_or_else(|e| e.into_inner()).get_or_insert(message);
    }

    pub(crate) fn check(&self) -> Result<(), GpuError> {
        if let Some(m) = self.lost.lock().unwrap_or_else(|e| e.into_inner()).clone() {
            return Err(GpuError::Lost(m));
        }
        if let Some(m) = self.uncaptured.lock().unwrap_or_else(|e| e.into_inner()).take() {
            return Err(GpuError::Wgpu(m));
        }
        Ok(())
    }
}
