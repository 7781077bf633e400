//! The Vulkan instance strahl computes on.
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

/// A Vulkan-only wgpu instance. Its flags come from the environment as wgpu's own
/// (`WGPU_DEBUG`, `WGPU_VALIDATION`, ...).
pub fn headless_instance() -> wgpu::Instance {
    let desc = wgpu::InstanceDescriptor {
        backends: wgpu::Backends::VULKAN,
        ..wgpu::InstanceDescriptor::new_without_display_handle_from_env()
    };
    wgpu::Instance::new(desc)
}

/// The Vulkan adapter strahl uses: a discrete GPU preferred, a software device (lavapipe) last.
pub fn request_adapter() -> Result<wgpu::Adapter, GpuError> {
    let instance = headless_instance();
    pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
        power_preference: wgpu::PowerPreference::HighPerformance,
        ..Default::default()
    }))
    .map_err(|_| GpuError::NoAdapter)
}

/// Whether `info` describes a software rasteriser rather than a GPU: lavapipe (llvmpipe) and
/// SwiftShader report the CPU device type.
pub fn is_software(info: &wgpu::AdapterInfo) -> bool {
    info.device_type == wgpu::DeviceType::Cpu
}
