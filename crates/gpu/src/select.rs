//! Which backend runs a job when the user does not force one (`--backend auto`, the default;
//! `STRAHL_BACKEND` sets the default for scripts).
//!
//! A hardware GPU always wins. Where the only Vulkan device is a software rasteriser (lavapipe,
//! which reports the CPU device type), the shaders run on the same cores as the CPU backend, and
//! which of the two is faster depends on the work: [`on_software_device`] says, per
//! [`Workload`], from measurements. Choosing the CPU there probes the adapter only: no device is
//! opened and no pipeline is compiled.

use crate::{GpuContext, GpuError, instance};

/// What the user asked for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Choice {
    /// A hardware GPU if there is one; else the faster of lavapipe and the CPU backend for the
    /// work at hand; the CPU backend without any Vulkan adapter.
    Auto,
    /// WGSL compute shaders through wgpu (Vulkan); an error without an adapter.
    Gpu,
    /// The CPU reference (f32 mirror of the GPU, rayon over all cores).
    Cpu,
}

/// The environment variable that sets the default [`Choice`].
pub const ENV: &str = "STRAHL_BACKEND";

impl Choice {
    /// `auto`, `gpu` or `cpu` (any case, surrounding spaces ignored).
    pub fn parse(s: &str) -> Option<Self> {
        match s.trim().to_ascii_lowercase().as_str() {
            "auto" => Some(Self::Auto),
            "gpu" => Some(Self::Gpu),
            "cpu" => Some(Self::Cpu),
            _ => None,
        }
    }

    /// The default from [`ENV`]: `Ok(None)` where it is unset or empty, an error naming the
    /// variable where it holds anything but `auto`, `gpu` or `cpu`.
    pub fn from_env() -> Result<Option<Self>, String> {
        match std::env::var(ENV) {
            Err(std::env::VarError::NotPresent) => Ok(None),
            Ok(v) if v.trim().is_empty() => Ok(None),
            Ok(v) => Self::parse(&v).map(Some).ok_or_else(|| format!("{ENV}={v:?}: use auto, gpu or cpu")),
            Err(std::env::VarError::NotUnicode(v)) => Err(format!("{ENV}={v:?}: use auto, gpu or cpu")),
        }
    }
}

/// The kinds of work whose faster backend on a software Vulkan device is measured apart.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Workload {
    /// `strahl render --mode whitted`.
    Whitted,
    /// `strahl render --mode path`, `strahl converge`.
    Path,
    /// `strahl trace` (f32 ray queries, nearest or every hit).
    Trace,
}

impl Workload {
    pub fn describe(self) -> &'static str {
        match self {
            Self::Whitted => "whitted rendering",
            Self::Path => "path tracing",
            Self::Trace => "ray queries",
        }
    }
}

/// A backend.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Backend {
    Gpu,
    Cpu,
}

/// The faster backend for `w` where the only Vulkan device is a software one, decided by whole
/// runs of `strahl render` and `strahl trace` (what a user waits for: device, pipeline, render
/// and file), lavapipe against the CPU backend on the same cores: the book's performance
/// chapter ("Choosing the backend") has the runs. The CPU backend was as fast (within the
/// spread of the runs) or faster for every workload, and compiles nothing, so it is chosen for
/// all three. Revise a row when the shaders get faster (and the expectation of
/// `tests/backend_choice.rs`, which states it apart).
pub fn on_software_device(w: Workload) -> Backend {
    match w {
        Workload::Whitted => Backend::Cpu,
        Workload::Path => Backend::Cpu,
        Workload::Trace => Backend::Cpu,
    }
}

/// What `auto` takes for `workload`, and why: `adapter` is the adapter found (None: none),
/// `software_table` the faster backend per workload where it is a software device
/// ([`on_software_device`] in strahl; any table in tests).
pub fn decide(
    adapter: Option<&wgpu::AdapterInfo>,
    workload: Workload,
    software_table: impl Fn(Workload) -> Backend,
) -> (Backend, String) {
    let Some(info) = adapter else {
        return (Backend::Cpu, "no GPU adapter found".into());
    };
    if !instance::is_software(info) {
        return (Backend::Gpu, format!("{}, a {:?}", info.name, info.device_type));
    }
    match software_table(workload) {
        Backend::Cpu => (
            Backend::Cpu,
            format!(
                "the only Vulkan device is a software one, {}, slower here for {}; --backend gpu uses it",
                info.name,
                workload.describe()
            ),
        ),
        Backend::Gpu => (
            Backend::Gpu,
            format!(
                "{}, a software Vulkan device, faster here than the cpu backend for {}",
                info.name,
                workload.describe()
            ),
        ),
    }
}

/// The backend chosen for a job, opened.
pub enum Selected {
    Gpu(Box<GpuContext>),
    Cpu,
}

/// A [`Selected`] backend and, for `auto`, the one line that says which and why.
pub struct Selection {
    pub selected: Selected,
    pub note: Option<String>,
}

/// Opens the backend `choice` means for `workload`. `Gpu` fails without a usable adapter;
/// `Auto` never fails: without an adapter, or where the device cannot be opened, it takes the
/// CPU and says why in its note.
pub fn select(choice: Choice, workload: Workload) -> Result<Selection, GpuError> {
    let cpu = |why: String| Selection { selected: Selected::Cpu, note: Some(format!("backend: cpu ({why})")) };
    match choice {
        Choice::Cpu => Ok(Selection { selected: Selected::Cpu, note: None }),
        Choice::Gpu => Ok(Selection { selected: Selected::Gpu(Box::new(GpuContext::new()?)), note: None }),
        Choice::Auto => {
            // A bad WGPU_BACKEND or WGPU_ADAPTER_NAME is the user's mistake, said, not a reason
            // to take the CPU quietly.
            let adapter = match instance::request_adapter() {
                Err(e @ GpuError::Environment { .. }) => return Err(e),
                r => r.ok(),
            };
            let info = adapter.as_ref().map(|a| a.get_info());
            let (backend, why) = decide(info.as_ref(), workload, on_software_device);
            let (Backend::Gpu, Some(adapter), Some(info)) = (backend, adapter, info) else {
                return Ok(cpu(why));
            };
            Ok(match GpuContext::from_adapter(&adapter) {
                Ok(ctx) => {
                    Selection { selected: Selected::Gpu(Box::new(ctx)), note: Some(format!("backend: gpu ({why})")) }
                }
                Err(e) => cpu(format!("{} could not be opened: {e}", info.name)),
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn choices_parse_in_any_case_and_nothing_else() {
        assert_eq!(Choice::parse("auto"), Some(Choice::Auto));
        assert_eq!(Choice::parse(" GPU "), Some(Choice::Gpu));
        assert_eq!(Choice::parse("Cpu"), Some(Choice::Cpu));
        assert_eq!(Choice::parse("both"), None);
        assert_eq!(Choice::parse(""), None);
    }

    fn adapter(name: &str, device_type: wgpu::DeviceType) -> wgpu::AdapterInfo {
        wgpu::AdapterInfo { name: name.into(), ..wgpu::AdapterInfo::new(device_type, wgpu::Backend::Vulkan) }
    }

    #[test]
    fn auto_decides_by_the_adapter_and_the_software_table() {
        use Workload::*;
        let gpu_everywhere = |_| Backend::Gpu;
        let cpu_everywhere = |_| Backend::Cpu;
        // No adapter: the cpu, whatever the table says.
        assert_eq!(decide(None, Path, gpu_everywhere), (Backend::Cpu, "no GPU adapter found".into()));
        // A hardware GPU always wins.
        let hw = adapter("RTX", wgpu::DeviceType::DiscreteGpu);
        for w in [Whitted, Path, Trace] {
            assert_eq!(decide(Some(&hw), w, cpu_everywhere), (Backend::Gpu, "RTX, a DiscreteGpu".into()));
        }
        // A software device: the table's row for the workload, either way.
        let sw = adapter("llvmpipe", wgpu::DeviceType::Cpu);
        let only_trace_on_gpu = |w| if w == Trace { Backend::Gpu } else { Backend::Cpu };
        let (b, why) = decide(Some(&sw), Trace, only_trace_on_gpu);
        assert_eq!(b, Backend::Gpu);
        assert_eq!(why, "llvmpipe, a software Vulkan device, faster here than the cpu backend for ray queries");
        let (b, why) = decide(Some(&sw), Whitted, only_trace_on_gpu);
        assert_eq!(b, Backend::Cpu);
        assert!(
            why.starts_with("the only Vulkan device is a software one, llvmpipe, slower here for whitted"),
            "{why}"
        );
    }
}
