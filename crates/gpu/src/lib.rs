//! The GPU backend: WGSL compute shaders through wgpu (Vulkan, Metal, DX12, GL, or WebGPU in
//! a browser).
//!
//! [`GpuContext`] owns the device and caches one pipeline per (program, [`FeatureKey`]);
//! [`SceneBuffers`] holds a scene's storage buffers; [`render`] and [`trace`] dispatch.
//!
//! Every readback has an async form for web pages, which cannot block (`readback.rs`):
//! [`GpuContext::read_buffer_async`], [`tiles::render_region_async`],
//! [`PathAccumulator::image_async`].

pub mod instance;
pub mod objects;
mod readback;
pub mod select;
pub mod shaders;
pub mod shared;
pub mod split;
pub mod tiles;
pub mod timing;
pub mod trace;
pub mod wavefront;

pub use readback::{IN_BROWSER, block_on};
pub use shaders::{FeatureKey, Program};
pub use tiles::{PathAccumulator, render, render_region, render_tiles};

use split::{Split, SplitArray};
use std::collections::HashMap;
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use strahl_core::accel::gpu_bvh::MAX_PRIMS;
use strahl_core::layout::{FlatScene, FrameParams};
use web_time::Instant;
use wgpu::util::DeviceExt;

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
struct Faults {
    uncaptured: Mutex<Option<String>>,
    lost: Mutex<Option<String>>,
}

impl Faults {
    fn record(slot: &Mutex<Option<String>>, message: String) {
        slot.lock().unwrap_or_else(|e| e.into_inner()).get_or_insert(message);
    }

    fn check(&self) -> Result<(), GpuError> {
        if let Some(m) = self.lost.lock().unwrap_or_else(|e| e.into_inner()).clone() {
            return Err(GpuError::Lost(m));
        }
        if let Some(m) = self.uncaptured.lock().unwrap_or_else(|e| e.into_inner()).take() {
            return Err(GpuError::Wgpu(m));
        }
        Ok(())
    }
}

/// The most storage buffers per shader stage a pipeline binds for a scene whose arrays fit one
/// binding each: WebGPU's guaranteed `maxStorageBuffersPerShaderStage`, so that strahl runs
/// on any device wgpu offers. The render programs bind the scene's [`SCENE_BINDINGS`] and
/// their output; the trace program the frame, the objects and the three arrays of triangles
/// and the BVH, and its rays, hits and offsets (`shaders::tests` checks every variant). The
/// wavefront path tracer needs [`wavefront::BINDINGS`] beside the scene's, and runs only where
/// a device offers them ([`GpuContext::has_wavefront`]).
pub const MIN_STORAGE_BUFFERS: u32 = 8;
/// Bindings of group 0 (`shaders/modules/bindings.wgsl`): the frame, the packed objects
/// ([`objects`]), the triangles, BVH nodes and leaf triangles, the texels and the triangle
/// attributes; a scene whose arrays are split across several bindings has
/// [`Split::extra_bindings`] more. A variant declares those its features use.
pub const SCENE_BINDINGS: u32 = 7;

/// What a device with `limits` lacks for strahl, if anything: the storage buffers per stage
/// of [`MIN_STORAGE_BUFFERS`] and the two bind groups (scene, and a program's own).
pub fn unmet_requirement(limits: &wgpu::Limits) -> Option<String> {
    if limits.max_storage_buffers_per_shader_stage < MIN_STORAGE_BUFFERS {
        return Some(format!(
            "strahl needs {MIN_STORAGE_BUFFERS} storage buffers per shader stage, this device offers {}",
            limits.max_storage_buffers_per_shader_stage
        ));
    }
    if limits.max_bind_groups < 2 {
        return Some(format!("strahl needs 2 bind groups, this device offers {}", limits.max_bind_groups));
    }
    None
}

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
type PipelineKey = (Program, FeatureKey, &'static str);
/// A cache entry: empty until its pipeline is compiled, locked while it compiles, so that a
/// second thread asking for the same variant waits for it instead of compiling it again.
type PipelineSlot = Arc<Mutex<Option<Arc<CachedPipeline>>>>;
/// A variant's shader module, shared by the pipelines of its entry points (so composed and
/// validated once), filled and locked like a [`PipelineSlot`].
type ShaderSlot = Arc<Mutex<Option<(wgpu::ShaderModule, SceneBindings)>>>;
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

pub struct GpuContext {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub adapter_info: wgpu::AdapterInfo,
    pub limits: wgpu::Limits,
    /// Whether per-dispatch timestamp queries are available.
    pub timestamps: bool,
    /// [`FeatureKey::DEVICE`] flags this device supports, added to every pipeline's key.
    pub device_flags: FeatureKey,
    /// The layouts of group 0, by the bindings a variant declares.
    scene_layouts: Mutex<HashMap<SceneBindings, wgpu::BindGroupLayout>>,
    render_layout: wgpu::BindGroupLayout,
    trace_layout: wgpu::BindGroupLayout,
    wavefront_layout: wgpu::BindGroupLayout,
    pipelines: Mutex<HashMap<PipelineKey, PipelineSlot>>,
    shader_modules: Mutex<HashMap<(Program, FeatureKey), ShaderSlot>>,
    /// Pipelines compiled so far.
    compiled: AtomicU32,
    faults: Arc<Faults>,
}

fn storage_entry(binding: u32, read_only: bool) -> wgpu::BindGroupLayoutEntry {
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

impl GpuContext {
    /// Opens the adapter [`instance::request_adapter`] takes (a discrete GPU preferred).
    pub fn new() -> Result<Self, GpuError> {
        Self::from_adapter(&instance::request_adapter()?)
    }

    /// What strahl asks of a device on `adapter`: the adapter's own limits (the largest
    /// buffers it allows) and timestamp queries where offered. Also for callers that create
    /// the device themselves (the viewer, through eframe).
    pub fn device_descriptor(adapter: &wgpu::Adapter) -> wgpu::DeviceDescriptor<'static> {
        let timestamps = adapter.features().contains(wgpu::Features::TIMESTAMP_QUERY);
        wgpu::DeviceDescriptor {
            label: Some("strahl"),
            required_features: (if timestamps { wgpu::Features::TIMESTAMP_QUERY } else { wgpu::Features::empty() })
                | (adapter.features() & wgpu::Features::SHADER_INT64),
            required_limits: adapter.limits(),
            ..Default::default()
        }
    }

    pub fn from_adapter(adapter: &wgpu::Adapter) -> Result<Self, GpuError> {
        let (device, queue) = pollster::block_on(adapter.request_device(&Self::device_descriptor(adapter)))
            .map_err(|e| GpuError::Device(e.to_string()))?;
        Self::from_device(device, queue, adapter.get_info())
    }

    /// [`GpuContext::new`] without blocking, as a web page must open its device: in a browser
    /// the adapter WebGPU offers ([`instance::request_adapter_async`]), natively the one
    /// [`GpuContext::new`] takes.
    pub async fn new_async() -> Result<Self, GpuError> {
        let adapter = instance::request_adapter_async().await?;
        let (device, queue) = adapter
            .request_device(&Self::device_descriptor(&adapter))
            .await
            .map_err(|e| GpuError::Device(e.to_string()))?;
        Self::from_device(device, queue, adapter.get_info())
    }

    /// Wraps a device created elsewhere (e.g. eframe's), with the limits and features it has.
    pub fn from_device(
        device: wgpu::Device,
        queue: wgpu::Queue,
        adapter_info: wgpu::AdapterInfo,
    ) -> Result<Self, GpuError> {
        let limits = device.limits();
        if let Some(lacking) = unmet_requirement(&limits) {
            return Err(GpuError::Device(lacking));
        }
        let faults = Arc::new(Faults::default());
        let f = faults.clone();
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| Faults::record(&f.uncaptured, e.to_string())));
        let f = faults.clone();
        device.set_device_lost_callback(move |reason, message| {
            if reason != wgpu::DeviceLostReason::Destroyed {
                Faults::record(&f.lost, message);
            }
        });
        let timestamps = device.features().contains(wgpu::Features::TIMESTAMP_QUERY);
        let device_flags = if device.features().contains(wgpu::Features::SHADER_INT64) {
            FeatureKey::LOAD64
        } else {
            FeatureKey::empty()
        };
        let render_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("render output"),
            entries: &[storage_entry(0, false)],
        });
        let trace_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("trace io"),
            entries: &[storage_entry(0, true), storage_entry(1, false), storage_entry(2, false)],
        });
        let wavefront_entries: Vec<_> = (0..wavefront::BINDINGS).map(|b| storage_entry(b, false)).collect();
        let wavefront_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("wavefront queues"),
            entries: &wavefront_entries,
        });
        Ok(Self {
            device,
            queue,
            adapter_info,
            limits,
            timestamps,
            device_flags,
            scene_layouts: Mutex::new(HashMap::new()),
            render_layout,
            trace_layout,
            wavefront_layout,
            pipelines: Mutex::new(HashMap::new()),
            shader_modules: Mutex::new(HashMap::new()),
            compiled: AtomicU32::new(0),
            faults,
        })
    }

    /// Runs `f`, work on the device, inside error scopes: a validation, out-of-memory or
    /// internal error it causes is returned as the error of `what`, instead of reaching wgpu's
    /// default handler (which panics). A device lost before, or an error reported outside any
    /// scope since the last call, is returned too.
    ///
    /// In a browser a scope's error arrives only after control returns to the event loop, so
    /// there no scope is pushed: errors reach the device's uncaptured-error handler, and the
    /// next check after an await (every readback's) returns them.
    pub fn scoped<T>(&self, what: &str, f: impl FnOnce() -> T) -> Result<T, GpuError> {
        self.faults.check()?;
        if IN_BROWSER {
            return Ok(f());
        }
        let scopes = [wgpu::ErrorFilter::Internal, wgpu::ErrorFilter::OutOfMemory, wgpu::ErrorFilter::Validation]
            .map(|filter| self.device.push_error_scope(filter));
        let out = f();
        // Popped in the reverse order of their pushing; the first error caught is reported.
        let mut caught = None;
        for scope in scopes.into_iter().rev() {
            if let Some(e) = pollster::block_on(scope.pop()) {
                caught.get_or_insert(e);
            }
        }
        match caught {
            Some(wgpu::Error::OutOfMemory { .. }) => Err(GpuError::OutOfMemory { what: what.to_string() }),
            Some(e) => Err(GpuError::Wgpu(format!("{what}: {}", e.to_string().trim_end()))),
            None => self.faults.check().map(|()| out),
        }
    }

    /// The device's loss, or an error it reported outside any scope since the last call (the
    /// viewer's per-frame work, which is not waited for, is checked so).
    pub fn check(&self) -> Result<(), GpuError> {
        self.faults.check()
    }

    /// Submits the commands of `enc` (scoped: see [`GpuContext::scoped`]).
    pub fn submit(&self, what: &str, enc: wgpu::CommandEncoder) -> Result<wgpu::SubmissionIndex, GpuError> {
        self.scoped(what, || self.queue.submit([enc.finish()]))
    }

    /// Waits for the submitted work to finish; a lost device is an error. In a browser this
    /// returns at once (WebGPU has no wait; the work completes on the event loop).
    pub fn wait(&self) -> Result<(), GpuError> {
        let polled = self.device.poll(wgpu::PollType::wait_indefinitely());
        self.faults.check()?;
        polled.map(|_| ()).map_err(|e| GpuError::Wgpu(e.to_string()))
    }

    /// How many pipelines this context has compiled.
    pub fn pipelines_compiled(&self) -> u32 {
        self.compiled.load(Ordering::Relaxed)
    }

    /// "name (backend, driver)".
    pub fn adapter_name(&self) -> String {
        let i = &self.adapter_info;
        format!("{} ({:?}, {} {})", i.name, i.backend, i.driver, i.driver_info)
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
            Program::Whitted | Program::Path | Program::View => &self.render_layout,
            Program::Trace => &self.trace_layout,
            Program::Wavefront => &self.wavefront_layout,
        };
        let scene_layout = self.scene_layout(&scene_bindings);
        let pipeline = self.scoped(&format!("the pipeline of {what}"), || {
            let layout = self.device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some(entry),
                bind_group_layouts: &[Some(&scene_layout), Some(io_layout)],
                immediate_size: 0,
            });
            self.device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: Some(&layout),
                module: &shader,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
        })?;
        Ok(CachedPipeline { pipeline, key, compile_time: start.elapsed(), scene_bindings })
    }

    /// The layout of group 0 with `bindings`, read-only storage buffers all (binding 0, the
    /// frame, too: see shaders/modules/bindings.wgsl).
    fn scene_layout(&self, bindings: &SceneBindings) -> wgpu::BindGroupLayout {
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

    /// The most bytes one storage buffer binding may hold on this adapter.
    pub fn max_binding_bytes(&self) -> u64 {
        split::binding_limit(&self.limits).0
    }

    /// The error for `what`, of `need` bytes, which does not fit one storage binding.
    pub fn too_large(&self, what: impl Into<String>, need: u64) -> GpuError {
        let (limit, limit_name) = split::binding_limit(&self.limits);
        GpuError::TooLarge { what: what.into(), need, limit, limit_name }
    }

    /// Fails with a clear error before allocating when `bytes` exceed one storage binding.
    pub fn check_binding_size(&self, what: &str, bytes: u64) -> Result<(), GpuError> {
        if bytes > self.max_binding_bytes() {
            return Err(self.too_large(what, bytes));
        }
        Ok(())
    }

    /// A storage buffer holding `data`; an empty slice gets a one-element buffer of 0xFF bytes
    /// (NaN floats), which no intersection routine can hit, for variants that still bind it.
    pub fn storage_buffer<T: bytemuck::Pod>(&self, what: &str, data: &[T]) -> Result<wgpu::Buffer, GpuError> {
        self.check_binding_size(what, std::mem::size_of_val(data) as u64)?;
        self.scoped(what, || self.storage_bytes(what, bytemuck::cast_slice(data), std::mem::size_of::<T>()))
    }

    /// [`GpuContext::storage_buffer`] over bytes already checked against the binding limit;
    /// `element`: the size of one element, for the stand-in buffer of an empty array.
    fn storage_bytes(&self, what: &str, bytes: &[u8], element: usize) -> wgpu::Buffer {
        let empty = vec![0xFF; element.max(4)];
        self.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(what),
            contents: if bytes.is_empty() { &empty } else { bytes },
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        })
    }
}

/// The major version in a Mesa driver description such as "Mesa 22.3.6 (LLVM 15.0.6)".
fn mesa_major(driver_info: &str) -> Option<u32> {
    let rest = driver_info.split("Mesa ").nth(1)?;
    rest.split(|c: char| !c.is_ascii_digit()).next()?.parse().ok()
}

/// A scene's storage buffers on the device (bind group 0, without the frame's contents, which
/// change per dispatch). Cloning shares the buffers.
#[derive(Clone)]
pub struct SceneBuffers {
    /// The scene's features and the split of its arrays ([`split`]): the variants it runs
    /// with contain the former and equal the latter ([`SceneBuffers::runs_with`]).
    pub key: FeatureKey,
    pub frame: wgpu::Buffer,
    /// Every buffer of group 0 by its binding: the frame, each array (or part of one).
    buffers: Arc<[(u32, wgpu::Buffer)]>,
    /// Bind groups over `buffers`, one per set of bindings a variant declares.
    bind_groups: Arc<Mutex<HashMap<SceneBindings, wgpu::BindGroup>>>,
    /// Bytes uploaded.
    pub bytes: u64,
    has_bvh: bool,
}

impl SceneBuffers {
    /// Uploads `g`, each array into one storage buffer, or where it exceeds one binding into
    /// parts ([`Split::plan`]). Every size is checked before the first buffer is made, so that
    /// a scene too large for the adapter's limits allocates nothing on the device.
    pub fn upload(ctx: &GpuContext, g: &FlatScene) -> Result<Self, GpuError> {
        if g.bounded_count() > MAX_PRIMS {
            return Err(GpuError::TooManyPrimitives { count: g.bounded_count(), limit: MAX_PRIMS });
        }
        // The only other collapse failure (accel::gpu_bvh::CollapseError): a tree deeper than
        // the shaders' traversal stack, which the build rules out.
        if g.nodes.is_empty() && g.bounded_count() > FeatureKey::BRUTE_FORCE_MAX {
            return Err(GpuError::TooDeep { limit: strahl_core::accel::gpu_bvh::MAX_DEPTH });
        }
        // Sizes first: nothing is packed or allocated for a scene over the limits.
        const OBJECTS: &str =
            "the scene's objects (spheres, cylinders, planes, materials, lights, emitters, texture table, environment)";
        const TEXELS: &str = "texels (every image of the scene: textures and environment map, with its distribution)";
        ctx.check_binding_size(OBJECTS, objects::objects_bytes(g))?;
        ctx.check_binding_size(TEXELS, objects::texels_bytes(g))?;
        let split = Split::plan(
            &ctx.limits,
            [
                std::mem::size_of_val(g.triangles.as_slice()),
                std::mem::size_of_val(g.nodes.as_slice()),
                std::mem::size_of_val(g.leaf_triangles.as_slice()),
            ]
            .map(|b| b as u64),
        )?;
        ctx.check_binding_size("triangle attributes", std::mem::size_of_val(g.triangle_attrs.as_slice()) as u64)?;
        let objects = objects::pack_objects(g);
        let texels = objects::pack_texels(g);
        // In binding order, from 1 (0 is the frame).
        let arrays = [
            pod_array(OBJECTS, &objects),
            split_array(SplitArray::Triangles, &g.triangles),
            split_array(SplitArray::Nodes, &g.nodes),
            split_array(SplitArray::LeafTriangles, &g.leaf_triangles),
            pod_array(TEXELS, &texels),
            pod_array("triangle attributes", &g.triangle_attrs),
        ];
        debug_assert_eq!(arrays.len() as u32 + 1, SCENE_BINDINGS);
        ctx.scoped("uploading the scene", || Self::create(ctx, g, &arrays, split))
    }

    /// The buffers and bind group of [`SceneBuffers::upload`], whose sizes it checked.
    fn create(ctx: &GpuContext, g: &FlatScene, arrays: &[PodArray], split: Split) -> Self {
        let frame = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("frame"),
            size: std::mem::size_of::<FrameParams>() as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        // (binding, buffer): every array's first part (or whole) at its binding, later parts
        // at theirs.
        let mut buffers = vec![(0, frame.clone())];
        for (i, a) in arrays.iter().enumerate() {
            let binding = i as u32 + 1;
            let Some(array) = a.split else {
                buffers.push((binding, ctx.storage_bytes(a.what, a.bytes, a.element)));
                continue;
            };
            for (p, part) in split.cut(array, a.bytes).into_iter().enumerate() {
                let binding = if p == 0 { binding } else { split::extra_binding(array, p as u32) };
                buffers.push((binding, ctx.storage_bytes(a.what, part, a.element)));
            }
        }
        Self {
            key: FeatureKey::for_scene(g) | split.key(),
            frame,
            bytes: buffers[1..].iter().map(|(_, b)| b.size()).sum(),
            buffers: buffers.into(),
            bind_groups: Arc::default(),
            has_bvh: !g.nodes.is_empty(),
        }
    }

    /// The scene's bind group (group 0) for `pipeline`: the buffers at the bindings its variant
    /// declares, made once per set of bindings. A variant that [`SceneBuffers::runs_with`] this
    /// scene declares only bindings the scene has; a binding it lacks would make wgpu report a
    /// validation error, returned by the next [`GpuContext::scoped`] or [`GpuContext::check`].
    pub fn bind_group(&self, ctx: &GpuContext, pipeline: &CachedPipeline) -> wgpu::BindGroup {
        let bindings = &pipeline.scene_bindings;
        let mut groups = self.bind_groups.lock().expect("scene bind group lock");
        let group = groups.entry(bindings.clone()).or_insert_with(|| {
            let entries: Vec<_> = self
                .buffers
                .iter()
                .filter(|(b, _)| bindings.contains(b))
                .map(|(binding, buffer)| wgpu::BindGroupEntry {
                    binding: *binding,
                    resource: buffer.as_entire_binding(),
                })
                .collect();
            ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("scene"),
                layout: &ctx.scene_layout(bindings),
                entries: &entries,
            })
        });
        group.clone()
    }

    /// How the scene's large arrays are split across bindings.
    pub fn split(&self) -> Split {
        Split::of_key(self.key)
    }

    /// Storage buffers group 0 binds for this scene.
    pub fn bindings(&self) -> u32 {
        SCENE_BINDINGS + self.split().extra_bindings()
    }

    /// Whether a variant compiled with `key` can run on this scene: it must contain every
    /// feature the scene uses, read the scene's arrays split as they are, and walk a BVH only
    /// if the scene has one.
    pub fn runs_with(&self, key: FeatureKey) -> bool {
        key.flags().contains(self.key.flags())
            && Split::of_key(key) == self.split()
            && (!key.contains(FeatureKey::BVH) || self.has_bvh)
    }
}

/// One scene array as bytes, named for errors, with its element size, and which it is where
/// it may be split across bindings.
struct PodArray<'a> {
    what: &'static str,
    bytes: &'a [u8],
    element: usize,
    split: Option<SplitArray>,
}

fn pod_array<'a, T: bytemuck::Pod>(what: &'static str, data: &'a [T]) -> PodArray<'a> {
    PodArray { what, bytes: bytemuck::cast_slice(data), element: std::mem::size_of::<T>(), split: None }
}

fn split_array<T: bytemuck::Pod>(array: SplitArray, data: &[T]) -> PodArray<'_> {
    debug_assert_eq!(std::mem::size_of::<T>() as u64, array.element_bytes());
    PodArray { split: Some(array), ..pod_array(array.what(), data) }
}

/// Records into `enc` a copy of `frame` into the scene's frame buffer, so that the dispatches
/// recorded after it (until the next such copy) read it: each tile or pass needs its own frame,
/// in command order (a queue write would land before the whole submission).
pub fn stage_frame(ctx: &GpuContext, enc: &mut wgpu::CommandEncoder, scene: &SceneBuffers, frame: &FrameParams) {
    let staging = wgpu::util::DeviceExt::create_buffer_init(
        &ctx.device,
        &wgpu::util::BufferInitDescriptor {
            label: Some("frame"),
            contents: bytemuck::bytes_of(frame),
            usage: wgpu::BufferUsages::COPY_SRC,
        },
    );
    enc.copy_buffer_to_buffer(&staging, 0, &scene.frame, 0, std::mem::size_of::<FrameParams>() as u64);
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
