//! The device and what strahl asks of it ([`GpuContext`]): opening it, its limits and
//! features, error scopes around device work, submission and waiting, and storage buffers
//! checked against the binding limit before they are made. Its pipelines are
//! [`crate::pipelines`]'.

use crate::error::{Faults, GpuError};
use crate::pipelines::{PipelineKey, PipelineSlot, SceneBindings, ShaderSlot, storage_entry};
use crate::{FeatureKey, IN_BROWSER, Program, instance, split, wavefront};
use std::collections::HashMap;
use std::sync::atomic::AtomicU32;
use std::sync::{Arc, Mutex};
use wgpu::util::DeviceExt;

/// The most storage buffers per shader stage a pipeline binds for a scene whose arrays fit one
/// binding each: WebGPU's guaranteed `maxStorageBuffersPerShaderStage`, so that strahl runs
/// on any device wgpu offers. The render programs bind the scene's [`SCENE_BINDINGS`] and
/// their output; the trace program the frame, the objects and the three arrays of triangles
/// and the BVH, and its rays, hits and offsets (`shaders::tests` checks every variant). The
/// wavefront path tracer needs [`wavefront::BINDINGS`] beside the scene's, and runs only where
/// a device offers them ([`GpuContext::has_wavefront`]).
pub const MIN_STORAGE_BUFFERS: u32 = 8;
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
    pub(crate) scene_layouts: Mutex<HashMap<SceneBindings, wgpu::BindGroupLayout>>,
    pub(crate) render_layout: wgpu::BindGroupLayout,
    pub(crate) trace_layout: wgpu::BindGroupLayout,
    /// Group 1 of the closest-point program: its points (read) and answers.
    pub(crate) closest_layout: wgpu::BindGroupLayout,
    pub(crate) wavefront_layout: wgpu::BindGroupLayout,
    pub(crate) pipelines: Mutex<HashMap<PipelineKey, PipelineSlot>>,
    pub(crate) shader_modules: Mutex<HashMap<(Program, FeatureKey), ShaderSlot>>,
    /// Pipelines compiled so far.
    pub(crate) compiled: AtomicU32,
    pub(crate) faults: Arc<Faults>,
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
        let closest_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("closest io"),
            entries: &[storage_entry(0, true), storage_entry(1, false)],
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
            closest_layout,
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

    /// "name (backend, driver)".
    pub fn adapter_name(&self) -> String {
        let i = &self.adapter_info;
        format!("{} ({:?}, {} {})", i.name, i.backend, i.driver, i.driver_info)
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
    pub(crate) fn storage_bytes(&self, what: &str, bytes: &[u8], element: usize) -> wgpu::Buffer {
        let empty = vec![0xFF; element.max(4)];
        self.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(what),
            contents: if bytes.is_empty() { &empty } else { bytes },
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        })
    }
}
