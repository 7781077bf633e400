//! The wgpu instance strahl computes on, and the adapter it takes.
//!
//! The instance takes every backend wgpu was built with (Vulkan, Metal, DX12, GL: those the
//! target has), and wgpu's own environment variables choose among them as in wgpu's examples:
//! [`BACKEND_VAR`] (`WGPU_BACKEND`, a comma-separated list of `vulkan`, `metal`, `dx12`, `gl`)
//! the backends, [`ADAPTER_NAME_VAR`] (`WGPU_ADAPTER_NAME`, part of the adapter's name, in any
//! case) the adapter. Unlike wgpu's helpers, which warn about a name they do not know and
//! panic on a name that matches nothing, both are errors here that say what was set. Without
//! them strahl takes the best adapter it can run on ([`rank`]).
//!
//! On Vulkan:
//!
//! wgpu enables every surface extension the loader offers (`VK_KHR_xlib_surface`,
//! `VK_KHR_xcb_surface`, `VK_KHR_wayland_surface`). Mesa's device-selection layer
//! (`VK_LAYER_MESA_device_select`, an implicit layer installed with `mesa-vulkan-drivers`)
//! takes an enabled Wayland or XCB surface extension as a sign that the program will present
//! to that display server, and at `vkEnumeratePhysicalDevices` connects to it to find the
//! compositor's GPU. Without a session (a server, a batch node, a container) libwayland then
//! prints `error: XDG_RUNTIME_DIR is invalid or not set in the environment.` on standard error,
//! once per enumeration (wgpu enumerates twice): the layer of Mesa 22.3 always does, Mesa 25's
//! where `WAYLAND_DISPLAY` is set; an XCB connection to an unreachable `DISPLAY` can stall.
//!
//! wgpu-hal offers no supported way to leave those extensions out (its instance callback may
//! only add to them). What is supported is the layer's own switch, which the Vulkan loader
//! reads when the instance is created: an implicit layer is disabled by the environment
//! variable named in its manifest, `NODEVICE_SELECT=1` for this one. The layer only orders
//! the devices, and strahl chooses its adapter itself, so the `strahl` binary sets
//! [`DISABLE_DEVICE_SELECT`] at the start of `main`, before any thread exists, unless the
//! user configures the layer (`MESA_VK_DEVICE_SELECT`) or the variable already; the viewer,
//! which presents, keeps the layer. Other programs using this library without a display can
//! set it the same way.

use super::GpuError;

/// The environment variable that disables Mesa's device-selection layer, with its value.
pub const DISABLE_DEVICE_SELECT: (&str, &str) = ("NODEVICE_SELECT", "1");

/// Whether a headless program should set [`DISABLE_DEVICE_SELECT`] in an environment where
/// `get` reads the variables: not where the user set it, or chose a device through the layer.
pub fn should_disable_device_select(get: impl Fn(&str) -> Option<std::ffi::OsString>) -> bool {
    get(DISABLE_DEVICE_SELECT.0).is_none() && get("MESA_VK_DEVICE_SELECT").is_none()
}

/// The variable that names the backends to search, as in wgpu's examples.
pub const BACKEND_VAR: &str = "WGPU_BACKEND";
/// The variable that names (part of) the adapter to take, as in wgpu's examples.
pub const ADAPTER_NAME_VAR: &str = "WGPU_ADAPTER_NAME";

/// The backends a [`BACKEND_VAR`] value names: a comma-separated list, in any case, of the
/// names wgpu's `Backends::from_comma_list` takes (`vulkan`/`vk`, `metal`/`mtl`,
/// `dx12`/`d3d12`, `gl`/`gles`/`opengl`, `webgpu`). Unlike that function, a name it does not
/// know is an error, not a warning: a misspelt backend would otherwise search every backend.
pub fn parse_backends(value: &str) -> Result<wgpu::Backends, GpuError> {
    let bad = |why: String| GpuError::Environment { var: BACKEND_VAR, value: value.to_string(), why };
    let mut backends = wgpu::Backends::empty();
    for name in value.split(',').map(str::trim) {
        backends |= match name.to_lowercase().as_str() {
            "vulkan" | "vk" => wgpu::Backends::VULKAN,
            "metal" | "mtl" => wgpu::Backends::METAL,
            "dx12" | "d3d12" => wgpu::Backends::DX12,
            "gl" | "gles" | "opengl" => wgpu::Backends::GL,
            "webgpu" => wgpu::Backends::BROWSER_WEBGPU,
            _ => return Err(bad(format!("`{name}` is not a backend; use vulkan, metal, dx12 or gl, comma-separated"))),
        };
    }
    Ok(backends)
}

/// The backends to search: those [`BACKEND_VAR`] names where it is set, else all.
pub fn backends_from_env() -> Result<wgpu::Backends, GpuError> {
    match std::env::var_os(BACKEND_VAR) {
        None => Ok(wgpu::Backends::all()),
        Some(v) => match v.to_str() {
            Some(s) => parse_backends(s),
            None => Err(GpuError::Environment {
                var: BACKEND_VAR,
                value: v.to_string_lossy().into_owned(),
                why: "not UTF-8".into(),
            }),
        },
    }
}

/// A wgpu instance over `backends` without a display (GL through EGL's surfaceless platform).
/// Its flags come from the environment as wgpu's own (`WGPU_DEBUG`, `WGPU_VALIDATION`, ...).
pub fn headless_instance(backends: wgpu::Backends) -> wgpu::Instance {
    let desc = wgpu::InstanceDescriptor { backends, ..wgpu::InstanceDescriptor::new_without_display_handle_from_env() };
    wgpu::Instance::new(desc)
}

/// Every adapter of the backends [`backends_from_env`] gives, best first ([`rank`]).
pub fn adapters() -> Result<Vec<wgpu::Adapter>, GpuError> {
    Ok(adapters_of(backends_from_env()?))
}

/// Every adapter of `backends`, best first.
fn adapters_of(backends: wgpu::Backends) -> Vec<wgpu::Adapter> {
    let instance = headless_instance(backends);
    let mut all = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()));
    all.sort_by_key(|a| rank(&a.get_info(), &a.limits()));
    all
}

/// How good an adapter is for strahl, smaller first: one strahl can run on
/// ([`crate::unmet_requirement`]) before one it cannot; then a discrete GPU, an integrated one,
/// a virtual one, an unknown kind, a software rasteriser; then a native API before GL, which
/// wgpu offers with fewer features.
pub fn rank(info: &wgpu::AdapterInfo, limits: &wgpu::Limits) -> (bool, u8, bool) {
    let kind = match info.device_type {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Other => 3,
        wgpu::DeviceType::Cpu => 4,
    };
    (crate::unmet_requirement(limits).is_some(), kind, info.backend == wgpu::Backend::Gl)
}

/// The adapter strahl uses: the first of [`adapters`] whose name contains [`ADAPTER_NAME_VAR`]
/// (in any case) where that is set, else the first. Without that variable GL is searched only
/// where no other backend has an adapter strahl runs on: GL ranks after them anyway, and
/// opening a GL adapter creates a context, which on Mesa compiles (and caches) its own shaders,
/// work a render that takes another adapter, or the CPU, should not do.
pub fn request_adapter() -> Result<wgpu::Adapter, GpuError> {
    let backends = backends_from_env()?;
    let Some(want) = std::env::var_os(ADAPTER_NAME_VAR) else {
        let native = backends - wgpu::Backends::GL;
        if !native.is_empty() && backends.contains(wgpu::Backends::GL) {
            let first = adapters_of(native).into_iter().next();
            if let Some(a) = first.filter(|a| crate::unmet_requirement(&a.limits()).is_none()) {
                return Ok(a);
            }
        }
        return adapters_of(backends).into_iter().next().ok_or(GpuError::NoAdapter);
    };
    let all = adapters_of(backends);
    let want = want.to_string_lossy().into_owned();
    let names: Vec<String> = all.iter().map(|a| describe(&a.get_info())).collect();
    all.into_iter().find(|a| a.get_info().name.to_lowercase().contains(&want.to_lowercase())).ok_or_else(|| {
        GpuError::Environment {
            var: ADAPTER_NAME_VAR,
            value: want.clone(),
            why: if names.is_empty() {
                "no adapter was found at all".into()
            } else {
                format!("no adapter's name contains it; the adapters here: {}", names.join(", "))
            },
        }
    })
}

/// The adapter to open without blocking: in a browser the one WebGPU offers
/// (`navigator.gpu.requestAdapter`, high performance preferred), natively
/// [`request_adapter`]'s.
pub async fn request_adapter_async() -> Result<wgpu::Adapter, GpuError> {
    if !crate::IN_BROWSER {
        return request_adapter();
    }
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
        backends: wgpu::Backends::BROWSER_WEBGPU,
        ..wgpu::InstanceDescriptor::new_without_display_handle()
    });
    let options =
        wgpu::RequestAdapterOptions { power_preference: wgpu::PowerPreference::HighPerformance, ..Default::default() };
    instance.request_adapter(&options).await.map_err(|e| {
        GpuError::Device(format!(
            "this browser offers no WebGPU adapter ({e}): strahl needs a browser with WebGPU (Chrome or \
             Edge 113 and later, Safari 26, Firefox 141 on Windows)"
        ))
    })
}

/// An adapter in a few words: its name and backend, e.g. `llvmpipe (LLVM 19.1.7, 256 bits) on Vulkan`.
pub fn describe(info: &wgpu::AdapterInfo) -> String {
    format!("{} on {}", info.name, info.backend)
}

/// Whether `info` describes a software rasteriser rather than a GPU: lavapipe (llvmpipe) and
/// SwiftShader report the CPU device type.
pub fn is_software(info: &wgpu::AdapterInfo) -> bool {
    info.device_type == wgpu::DeviceType::Cpu
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn backend_lists_parse_as_wgpu_spells_them_and_anything_else_is_an_error() {
        assert_eq!(parse_backends("vulkan").unwrap(), wgpu::Backends::VULKAN);
        assert_eq!(parse_backends(" GL , vk").unwrap(), wgpu::Backends::GL | wgpu::Backends::VULKAN);
        assert_eq!(parse_backends("metal,dx12").unwrap(), wgpu::Backends::METAL | wgpu::Backends::DX12);
        for bad in ["nonsense", "vulkan,", "", "vulkan,metl"] {
            let e = parse_backends(bad).unwrap_err().to_string();
            assert!(e.starts_with(&format!("WGPU_BACKEND={bad}: `")) && e.contains("is not a backend"), "{e}");
        }
    }

    #[test]
    fn adapters_rank_usable_first_then_by_kind_then_native_before_gl() {
        let info = |t, b| wgpu::AdapterInfo::new(t, b);
        let ok = wgpu::Limits { max_storage_buffers_per_shader_stage: 64, ..wgpu::Limits::default() };
        let short = wgpu::Limits { max_storage_buffers_per_shader_stage: 4, ..wgpu::Limits::default() };
        use wgpu::{Backend::*, DeviceType::*};
        let mut v = [
            (info(DiscreteGpu, Vulkan), &short),
            (info(Cpu, Gl), &ok),
            (info(Cpu, Vulkan), &ok),
            (info(IntegratedGpu, Gl), &ok),
            (info(DiscreteGpu, Dx12), &ok),
        ];
        v.sort_by_key(|(i, l)| rank(i, l));
        let order: Vec<_> = v.iter().map(|(i, _)| (i.device_type, i.backend)).collect();
        assert_eq!(order, [(DiscreteGpu, Dx12), (IntegratedGpu, Gl), (Cpu, Vulkan), (Cpu, Gl), (DiscreteGpu, Vulkan)]);
    }
}
