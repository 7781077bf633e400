//! The Vulkan instance strahl computes on: headless, without window-system surface extensions.
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
//! strahl never presents (the viewer opens its own instance through eframe), so these
//! extensions are left out and the layer connects to nothing.

use super::GpuError;
use std::ffi::CStr;

/// The instance extensions of window systems that compute needs none of.
const WINDOW_SYSTEM_SURFACES: [&CStr; 3] = [c"VK_KHR_xlib_surface", c"VK_KHR_xcb_surface", c"VK_KHR_wayland_surface"];

/// A Vulkan-only wgpu instance without window-system surface extensions. Its flags come from
/// the environment as wgpu's own (`WGPU_DEBUG`, `WGPU_VALIDATION`, ...).
pub fn headless_instance() -> Result<wgpu::Instance, GpuError> {
    use wgpu::hal::vulkan;
    let env = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
    let desc = wgpu::hal::InstanceDescriptor {
        name: "strahl",
        flags: env.flags,
        memory_budget_thresholds: env.memory_budget_thresholds,
        backend_options: env.backend_options,
        telemetry: None,
        display: None,
    };
    let drop_surfaces: Box<vulkan::CreateInstanceCallback> = Box::new(|args: vulkan::CreateInstanceCallbackArgs| {
        args.extensions.retain(|e| !WINDOW_SYSTEM_SURFACES.contains(e));
    });
    // SAFETY: wgpu-hal documents that the callback should only add extensions, because it
    // trusts the list it is left with. Removing these three is sound: that list becomes the
    // instance's enabled extensions (`InstanceShared::extensions`), and wgpu-hal 30 consults
    // it before it touches any of them (`create_surface_from_xlib`, `_xcb`, `_wayland` fail
    // with "Vulkan driver does not support ..." when it lacks theirs); nothing else uses them.
    // strahl never creates a surface on this instance. Everything else is as `wgpu::Instance::new`
    // makes it (the same descriptor, the same `init`).
    let hal = unsafe { vulkan::Instance::init_with_callback(&desc, Some(drop_surfaces)) }
        // No loader or no driver: the same answer as an instance without adapters.
        .map_err(|_| GpuError::NoAdapter)?;
    // SAFETY: `hal` is a valid Vulkan instance just created, owned by the wgpu instance from here.
    Ok(unsafe { wgpu::Instance::from_hal::<wgpu::hal::api::Vulkan>(hal) })
}

/// The Vulkan adapter strahl uses: a discrete GPU preferred, a software device (lavapipe) last.
pub fn request_adapter() -> Result<wgpu::Adapter, GpuError> {
    let instance = headless_instance()?;
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
