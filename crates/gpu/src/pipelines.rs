//! Pipelines specialised by a key and cached: one shader module per (program, [`FeatureKey`])
//! and one pipeline per (program, key, entry point), each compiled once per device on first
//! use; the scene's bind group layouts by the bindings a variant declares; which path tracer a
//! device runs ([`PathKernels`]).

// (GpuContext, GpuError and SceneBuffers by the crate's own names: the context's module holds
// this module's caches.)
use crate::{FeatureKey, GpuContext, GpuError, IN_BROWSER, Program, SceneBuffers, shaders, wavefront};
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::Duration;
use web_time::Instant;

/// How path tracing runs on a device: one kernel per sample pass that follows each path to its
/// end (`megakernel.wgsl`), or separate kernels over queues of paths (`wavefront.wgsl`, see
/// [`wavefront`]). Both compute the same image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PathKernels {
    Megakernel,
    Wavefront,
}

/// The environment variable that overrides [`GpuContext::path_kernels`].
pub const PATH_KERNELS_VAR: &str = "STRAHL_PATH_KERNELS";

/// A pipeline is specialised by its program, the scene's features and its entry point.
pub(crate) type PipelineKey = (Program, FeatureKey, &'static str);
/// A cache entry: empty until its pipeline is compiled, locked while it compiles, so that a
/// second thread asking for the same variant waits for it instead of compiling it again.
pub(crate) type PipelineSlot = Arc<Mutex<Option<Arc<CachedPipeline>>>>;
/// A variant's shader module, shared by the pipelines of its entry points (so composed and
/// validated once), filled and locked like a [`PipelineSlot`].
pub(crate) type ShaderSlot = Arc<Mutex<Option<(wgpu::ShaderModule, SceneBindings)>>>;
/// The group-0 bindings a variant declares, in increasing order: its pipelines' scene layout,
/// and the scene buffers its bind group holds.
pub type SceneBindings = Arc<[u32]>;

/// A compiled pipeline and what compiling it cost.
pub struct CachedPipeline {
    pub pipeline: wgpu::ComputePipeline,
    /// The variant compiled: the scene's key with the device's flags ([`FeatureKey::DEVICE`]).
    pub key: FeatureKey,
    /// Composition (naga_oil) and shader module creation, where this was the variant's first
    /// entry point, plus pipeline creation (driver compile).
    pub compile_time: Duration,
    /// The scene bindings (group 0) the pipeline's layout has.
    pub scene_bindings: SceneBindings,
}

impl GpuContext {
    /// How many pipelines this context has compiled.
    pub fn pipelines_compiled(&self) -> u32 {
        self.compiled.load(Ordering::Relaxed)
    }

    /// The pipeline for `entry` of `program` specialised to `key`, compiled on first use.
    pub fn pipeline(
        &self,
        program: Program,
        key: FeatureKey,
        entry: &'static str,
    ) -> Result<Arc<CachedPipeline>, GpuError> {
        let key = self.variant(program, key);
        let slot =
            self.pipelines.lock().expect("pipeline cache lock").entry((program, key, entry)).or_default().clone();
        let mut slot = slot.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(p) = &*slot {
            return Ok(p.clone());
        }
        let cached = Arc::new(self.compile(program, key, entry)?);
        self.compiled.fetch_add(1, Ordering::Relaxed);
        *slot = Some(cached.clone());
        Ok(cached)
    }

    /// The shader module of the variant `key` of `program`, composed on first use. wgpu
    /// validates the composed module when it makes the shader module (the one validation on
    /// this path; the tests validate every variant), so once per variant and device.
    fn shader_module(
        &self,
        program: Program,
        key: FeatureKey,
    ) -> Result<(wgpu::ShaderModule, SceneBindings), GpuError> {
        let slot =
            self.shader_modules.lock().expect("shader module cache lock").entry((program, key)).or_default().clone();
        let mut slot = slot.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(m) = &*slot {
            return Ok(m.clone());
        }
        let module = shaders::compose(program, key)?;
        let bindings = shaders::group_bindings(&module, 0).into();
        let label = format!("{program:?}");
        // A browser compiles WGSL text; naga's spelling of some f32 literals is not what its
        // compiler accepts, so the text is written as `shaders::wgsl` writes it.
        let source = if IN_BROWSER {
            let info = shaders::validate(program, key, &module)?;
            wgpu::ShaderSource::Wgsl(shaders::write_wgsl(program, key, &module, &info)?.into())
        } else {
            wgpu::ShaderSource::Naga(std::borrow::Cow::Owned(module))
        };
        let shader = self.scoped(&format!("the {program:?} shader for {}", key.label()), || {
            self.device.create_shader_module(wgpu::ShaderModuleDescriptor { label: Some(&label), source })
        })?;
        let entry = (shader, bindings);
        *slot = Some(entry.clone());
        Ok(entry)
    }

    /// Compiles the pipeline of `entry` for the variant `key`.
    fn compile(&self, program: Program, key: FeatureKey, entry: &'static str) -> Result<CachedPipeline, GpuError> {
        let start = Instant::now();
        let (shader, scene_bindings) = self.shader_module(program, key)?;
        let what = format!("the {program:?} shader {entry} for {}", key.label());
        let io_layout = match program {
            Program::Whitted | Program::Path | Program::View | Program::Aov => &self.render_layout,
            Program::Trace => &self.trace_layout,
            Program::Closest => &self.closest_layout,
            Program::Wavefront => &self.wavefront_layout,
        };
        let scene_layout = self.scene_layout(&scene_bindings);
        let pipeline =
            self.compute_pipeline(&format!("the pipeline of {what}"), &shader, entry, &scene_layout, io_layout)?;
        Ok(CachedPipeline { pipeline, key, compile_time: start.elapsed(), scene_bindings })
    }

    /// The compute pipeline of `entry` in `shader` over the scene's bind group (`scene_layout`,
    /// group 0) and its program's (`io_layout`, group 1), in an error scope named `what`.
    pub(crate) fn compute_pipeline(
        &self,
        what: &str,
        shader: &wgpu::ShaderModule,
        entry: &'static str,
        scene_layout: &wgpu::BindGroupLayout,
        io_layout: &wgpu::BindGroupLayout,
    ) -> Result<wgpu::ComputePipeline, GpuError> {
        self.scoped(what, || {
            let layout = self.device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some(entry),
                bind_group_layouts: &[Some(scene_layout), Some(io_layout)],
                immediate_size: 0,
            });
            self.device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: Some(&layout),
                module: shader,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
        })
    }

    /// The layout of group 0 with `bindings`, read-only storage buffers all (binding 0, the
    /// frame, too: see shaders/modules/bindings.wgsl).
    pub(crate) fn scene_layout(&self, bindings: &SceneBindings) -> wgpu::BindGroupLayout {
        let mut layouts = self.scene_layouts.lock().expect("scene layout lock");
        let layout = layouts.entry(bindings.clone()).or_insert_with(|| {
            let entries: Vec<_> = bindings.iter().map(|&b| storage_entry(b, true)).collect();
            self.device
                .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some("scene"), entries: &entries })
        });
        layout.clone()
    }

    /// The pipeline for `entry` of `program` specialised to `key` if it was compiled already
    /// (None while another thread compiles it: this never waits).
    pub fn cached_pipeline(
        &self,
        program: Program,
        key: FeatureKey,
        entry: &'static str,
    ) -> Option<Arc<CachedPipeline>> {
        let key = self.variant(program, key);
        let slot = self.pipelines.lock().expect("pipeline cache lock").get(&(program, key, entry)).cloned()?;
        slot.try_lock().ok()?.clone()
    }

    /// The path tracer this device runs best for `scene` (`strahl bench` times both): on
    /// lavapipe before Mesa 25, which executes both sides of every branch for all eight lanes of
    /// its SIMD programs, the wavefront tracer, whose kernels carry only the code of their stage;
    /// everywhere else the megakernel (Mesa 25 skips branches no lane takes). The runs are in
    /// the book's performance chapter ("Megakernel and wavefront"). The environment variable
    /// [`PATH_KERNELS_VAR`] (`megakernel` or `wavefront`) overrides the choice. A scene whose
    /// arrays take more bindings than the device has beside the wavefront tracer's runs the
    /// megakernel.
    pub fn path_kernels(&self, scene: &SceneBuffers) -> Result<PathKernels, GpuError> {
        if let Some(v) = std::env::var_os(PATH_KERNELS_VAR) {
            return match v.to_str() {
                Some("megakernel") => Ok(PathKernels::Megakernel),
                Some("wavefront") if self.has_wavefront(scene) => Ok(PathKernels::Wavefront),
                Some("wavefront") => Err(GpuError::Device(format!(
                    "{PATH_KERNELS_VAR}=wavefront: this device binds too few storage buffers per stage for it"
                ))),
                _ => Err(GpuError::Device(format!(
                    "{PATH_KERNELS_VAR} must be megakernel or wavefront, not {}",
                    v.to_string_lossy()
                ))),
            };
        }
        let info = &self.adapter_info;
        let old_lavapipe = info.driver == "llvmpipe" && mesa_major(&info.driver_info).is_some_and(|m| m < 25);
        Ok(if old_lavapipe && self.has_wavefront(scene) { PathKernels::Wavefront } else { PathKernels::Megakernel })
    }

    /// Whether this device binds enough storage buffers per stage for the wavefront path tracer
    /// on `scene`.
    pub fn has_wavefront(&self, scene: &SceneBuffers) -> bool {
        self.limits.max_storage_buffers_per_shader_stage >= scene.bindings() + wavefront::BINDINGS
    }

    /// The variant of `program` this device compiles for a scene needing `key`.
    pub fn variant(&self, program: Program, key: FeatureKey) -> FeatureKey {
        (key.for_program(program) - FeatureKey::DEVICE) | self.device_flags
    }

    /// The output bind group (group 1) of the render and view programs over `buffer`, an
    /// `array<vec4<f32>>` storage buffer of one image band.
    pub fn output_bind_group(&self, buffer: &wgpu::Buffer) -> wgpu::BindGroup {
        self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("render output"),
            layout: &self.render_layout,
            entries: &[wgpu::BindGroupEntry { binding: 0, resource: buffer.as_entire_binding() }],
        })
    }
}

/// The major version in a Mesa driver description such as "Mesa 22.3.6 (LLVM 15.0.6)".
fn mesa_major(driver_info: &str) -> Option<u32> {
    let rest = driver_info.split("Mesa ").nth(1)?;
    rest.split(|c: char| !c.is_ascii_digit()).next()?.parse().ok()
}

/// A storage buffer binding of the compute stage.
pub(crate) fn storage_entry(binding: u32, read_only: bool) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mesa_versions_read_from_driver_descriptions() {
        assert_eq!(mesa_major("Mesa 22.3.6 (LLVM 15.0.6)"), Some(22));
        assert_eq!(mesa_major("Mesa 25.0.7-2~bpo12+1 (LLVM 15.0.6)"), Some(25));
        assert_eq!(mesa_major("570.124.04"), None);
    }
}
