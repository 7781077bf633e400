//! The viewer's GPU side, all on eframe's device: progressive sample passes into an
//! accumulation buffer ([`record_pass`], a bounded number of tiles per UI frame), the present
//! pass (`shaders/present.wgsl`) that turns the sums into the rgba8unorm texture egui shows,
//! and the GPU time of each frame's work, taken without blocking the UI. Nothing goes back to the CPU per frame;
//! readbacks happen only when the user saves or compares.

use eframe::egui;
use eframe::egui_wgpu;
use std::collections::VecDeque;
use std::sync::Arc;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::{Duration, Instant};
use strahl_core::image::Image;
use strahl_core::layout::{self as g, FrameParams};
use strahl_gpu::tiles::{Band, Pass, record_pass};
use strahl_gpu::{CachedPipeline, GpuContext, GpuError, Program, SceneBuffers};

/// Tile side of the viewer's dispatches, as for `strahl render`. Smaller tiles make the UI
/// only somewhat smoother: a dispatch's fixed cost on lavapipe makes whole passes slower.
pub const VIEW_TILE: u32 = strahl_gpu::tiles::TILE;
/// The present shader (standalone WGSL, before the shared values are substituted).
pub const PRESENT_WGSL: &str = include_str!("../../gpu/shaders/present.wgsl");

/// The present shader as compiled: [`PRESENT_WGSL`] with the shared values in.
fn present_source() -> String {
    strahl_gpu::shared::substitute(PRESENT_WGSL)
}

/// What the image shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, clap::ValueEnum)]
pub enum ViewMode {
    /// Whitted ray tracing (the render program).
    Whitted = g::VIEW_WHITTED as isize,
    /// Front-face normals of the primary hits, as 0.5 + 0.5·n.
    Normals = g::VIEW_NORMALS as isize,
    /// Distance to the primary hit, white (near) to black (far).
    Depth = g::VIEW_DEPTH as isize,
    /// BVH nodes visited plus primitives tested per primary ray, as a heat map.
    Cost = g::VIEW_COST as isize,
    /// Monte Carlo path tracing (the path program), converging as samples accumulate.
    Path = g::VIEW_PATH as isize,
}

impl ViewMode {
    pub const ALL: [ViewMode; 5] = [Self::Whitted, Self::Path, Self::Normals, Self::Depth, Self::Cost];

    pub fn label(self) -> &'static str {
        match self {
            Self::Whitted => "Whitted",
            Self::Normals => "normals",
            Self::Depth => "depth",
            Self::Cost => "BVH cost",
            Self::Path => "path",
        }
    }

    /// The program and entry point: the renderer's for the image modes, `view.wgsl`'s else.
    pub fn program(self) -> (Program, &'static str) {
        self.render_mode().map_or((Program::View, "view"), strahl_gpu::tiles::program_for)
    }

    /// The light transport of an image mode (None for the debug views).
    pub fn render_mode(self) -> Option<strahl_core::scene::RenderMode> {
        match self {
            Self::Whitted => Some(strahl_core::scene::RenderMode::Whitted),
            Self::Path => Some(strahl_core::scene::RenderMode::Path),
            _ => None,
        }
    }

    /// The frame flags that select this mode in `view.wgsl` (none for the image modes).
    pub fn flags(self) -> u32 {
        if self.render_mode().is_some() { 0 } else { (self as u32) << g::VIEW_MODE_SHIFT }
    }
}

/// The parameters of `present.wgsl` (`Present`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct PresentParams {
    pub width: u32,
    pub height: u32,
    pub samples: u32,
    pub next_tile: u32,
    pub tiles_x: u32,
    pub tile: u32,
    pub mode: u32,
    pub _pad0: u32,
    pub near: f32,
    pub far: f32,
    pub heat_max: f32,
    pub _pad1: f32,
}

/// How far the accumulation has come: `samples` complete passes, and the first `next_tile`
/// tiles of the next one.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Accumulation {
    pub samples: u32,
    pub next_tile: u32,
}

impl Accumulation {
    /// Samples held by pixel (x, y) of a `band` (tiles in [`Band`] order).
    pub fn samples_at(&self, band: &Band, x: u32, y: u32) -> u32 {
        let tile = (y / band.tile) * band.tiles_x() + x / band.tile;
        self.samples + (tile < self.next_tile) as u32
    }
}

/// The size-dependent resources: accumulation buffer and display texture.
pub struct Target {
    pub width: u32,
    pub height: u32,
    pub filter: wgpu::FilterMode,
    accum: wgpu::Buffer,
    out_group: wgpu::BindGroup,
    texture: wgpu::Texture,
    present_group: wgpu::BindGroup,
    pub texture_id: egui::TextureId,
}

impl Target {
    pub fn band(&self) -> Band {
        Band::whole(self.width, self.height, VIEW_TILE)
    }
}

/// GPU time of one UI frame's submission: from submission (or the end of the work queued
/// before it) to completion, as the host sees it, within about a millisecond. (Per-dispatch timestamp queries were tried: lavapipe
/// writes them when its queue flushes, not around the dispatch, when the dispatches of a
/// frame are not waited on one by one.)
#[derive(Clone, Copy, Debug)]
pub struct GpuTiming {
    pub at: Instant,
    pub gpu: Duration,
    /// Primary rays (pixel samples) those dispatches traced.
    pub rays: u64,
}

/// Most dispatches one UI frame records.
pub const MAX_TILES_PER_FRAME: u32 = 2048;

/// A submission whose completion time is awaited.
struct InFlight {
    submitted: Instant,
    rays: u64,
    /// When the work queued before it was done.
    before: Arc<Mutex<Option<Instant>>>,
    done: Arc<Mutex<Option<Instant>>>,
}

/// Polls the device about every millisecond while submissions are in flight, so that their
/// completion callbacks run (and take their time) promptly, off the UI thread.
struct Poller {
    in_flight: Arc<AtomicUsize>,
    stop: Arc<AtomicBool>,
}

impl Poller {
    fn spawn(device: wgpu::Device) -> Self {
        let in_flight = Arc::new(AtomicUsize::new(0));
        let stop = Arc::new(AtomicBool::new(false));
        let (n, halt) = (in_flight.clone(), stop.clone());
        std::thread::spawn(move || {
            while !halt.load(Ordering::Acquire) {
                if n.load(Ordering::Acquire) > 0 {
                    let _ = device.poll(wgpu::PollType::Poll);
                    std::thread::sleep(Duration::from_millis(1));
                } else {
                    std::thread::sleep(Duration::from_millis(10));
                }
            }
        });
        Self { in_flight, stop }
    }
}

impl Drop for Poller {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Release);
    }
}

pub struct ViewRenderer {
    pub ctx: Arc<GpuContext>,
    render_state: egui_wgpu::RenderState,
    present_pipeline: wgpu::ComputePipeline,
    present_layout: wgpu::BindGroupLayout,
    present_params: wgpu::Buffer,
    pub target: Option<Target>,
    pub acc: Accumulation,
    in_flight: VecDeque<InFlight>,
    poller: Poller,
    /// Recent GPU timings, oldest first.
    pub timings: VecDeque<GpuTiming>,
}

fn layout_entry(binding: u32, ty: wgpu::BindingType) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry { binding, visibility: wgpu::ShaderStages::COMPUTE, ty, count: None }
}

impl ViewRenderer {
    pub fn new(ctx: Arc<GpuContext>, render_state: egui_wgpu::RenderState) -> Self {
        let device = &ctx.device;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("present"),
            source: wgpu::ShaderSource::Wgsl(present_source().into()),
        });
        let present_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("present"),
            entries: &[
                layout_entry(
                    0,
                    wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Storage { read_only: true },
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                ),
                layout_entry(
                    1,
                    wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Storage { read_only: true },
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                ),
                layout_entry(
                    2,
                    wgpu::BindingType::StorageTexture {
                        access: wgpu::StorageTextureAccess::WriteOnly,
                        format: wgpu::TextureFormat::Rgba8Unorm,
                        view_dimension: wgpu::TextureViewDimension::D2,
                    },
                ),
            ],
        });
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("present"),
            bind_group_layouts: &[Some(&present_layout)],
            immediate_size: 0,
        });
        let present_pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("present"),
            layout: Some(&layout),
            module: &module,
            entry_point: Some("present"),
            compilation_options: Default::default(),
            cache: None,
        });
        let present_params = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("present params"),
            size: std::mem::size_of::<PresentParams>() as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let device = ctx.device.clone();
        Self {
            ctx,
            render_state,
            present_pipeline,
            present_layout,
            present_params,
            target: None,
            acc: Accumulation::default(),
            in_flight: VecDeque::new(),
            poller: Poller::spawn(device.clone()),
            timings: VecDeque::new(),
        }
    }

    /// Makes the accumulation buffer and texture `width`×`height`; returns true when they
    /// were (re)created, which restarts the accumulation.
    pub fn ensure_target(&mut self, width: u32, height: u32, filter: wgpu::FilterMode) -> Result<bool, GpuError> {
        if let Some(t) = &self.target
            && (t.width, t.height) == (width, height)
        {
            if t.filter != filter {
                let view = t.texture.create_view(&Default::default());
                self.render_state.renderer.write().update_egui_texture_from_wgpu_texture(
                    &self.ctx.device,
                    &view,
                    filter,
                    t.texture_id,
                );
                self.target.as_mut().expect("target").filter = filter;
            }
            return Ok(false);
        }
        let device = &self.ctx.device;
        let bytes = width as u64 * height as u64 * 16;
        self.ctx.check_binding_size("the viewer's accumulation buffer", bytes)?;
        let accum = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("viewer accumulation"),
            size: bytes,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("viewer image"),
            size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba8Unorm,
            usage: wgpu::TextureUsages::STORAGE_BINDING
                | wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let view = texture.create_view(&Default::default());
        let present_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("present"),
            layout: &self.present_layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: self.present_params.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: accum.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: wgpu::BindingResource::TextureView(&view) },
            ],
        });
        let mut renderer = self.render_state.renderer.write();
        let texture_id = match self.target.take() {
            Some(old) => {
                renderer.update_egui_texture_from_wgpu_texture(device, &view, filter, old.texture_id);
                old.texture_id
            }
            None => renderer.register_native_texture(device, &view, filter),
        };
        drop(renderer);
        self.target = Some(Target {
            width,
            height,
            filter,
            out_group: self.ctx.output_bind_group(&accum),
            accum,
            texture,
            present_group,
            texture_id,
        });
        self.acc = Accumulation::default();
        Ok(true)
    }

    /// Dispatches up to `budget` tiles of sample passes of `pipeline` (stopping at
    /// `max_samples` complete passes), then the present pass, in one submission. Returns the
    /// tiles dispatched.
    pub fn step(
        &mut self,
        scene: &SceneBuffers,
        pipeline: &CachedPipeline,
        frame: &FrameParams,
        budget: u32,
        max_samples: u32,
        present: PresentParams,
    ) -> u32 {
        if self.target.is_none() {
            return 0;
        }
        let budget = budget.min(MAX_TILES_PER_FRAME);
        let Some(target) = &self.target else { return 0 };
        let band = target.band();
        let total = band.tile_count();
        let mut enc = self.ctx.device.create_command_encoder(&Default::default());
        let mut left = budget;
        let mut done = 0u32;
        let mut rays = 0u64;
        while left > 0 && self.acc.samples < max_samples {
            let take = left.min(total - self.acc.next_tile);
            let range = self.acc.next_tile..self.acc.next_tile + take;
            for i in range.clone() {
                let (_, size) = band.tile_rect(i);
                rays += size[0] as u64 * size[1] as u64;
            }
            let pass_frame = FrameParams { sample_base: self.acc.samples, ..*frame };
            let accumulate = self.acc.samples > 0;
            let pass = Pass { scene, pipeline, output: &target.out_group, frame: &pass_frame, accumulate };
            record_pass(&self.ctx, &mut enc, &pass, &band, range, None);
            self.acc.next_tile += take;
            if self.acc.next_tile == total {
                self.acc.samples += 1;
                self.acc.next_tile = 0;
            }
            left -= take;
            done += take;
        }
        self.record_present(&mut enc, present);
        if done == 0 {
            self.ctx.queue.submit([enc.finish()]);
            return 0;
        }
        // Completion of what was queued before (egui's last frame), then of this work.
        let stamp = |queue: &wgpu::Queue| {
            let slot: Arc<Mutex<Option<Instant>>> = Arc::default();
            let at = slot.clone();
            queue.on_submitted_work_done(move || {
                *at.lock().expect("timing lock") = Some(Instant::now());
            });
            slot
        };
        self.poller.in_flight.fetch_add(1, Ordering::AcqRel);
        let before = stamp(&self.ctx.queue);
        let submitted = Instant::now();
        self.ctx.queue.submit([enc.finish()]);
        let after = stamp(&self.ctx.queue);
        self.in_flight.push_back(InFlight { submitted, rays, before, done: after });
        done
    }

    /// Records the present pass with `params` (sizes and tile filled in here).
    fn record_present(&self, enc: &mut wgpu::CommandEncoder, mut params: PresentParams) {
        let Some(target) = &self.target else { return };
        let band = target.band();
        params.width = target.width;
        params.height = target.height;
        params.samples = self.acc.samples;
        params.next_tile = self.acc.next_tile;
        params.tiles_x = band.tiles_x();
        params.tile = band.tile;
        self.ctx.queue.write_buffer(&self.present_params, 0, bytemuck::bytes_of(&params));
        let mut pass =
            enc.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("present"), timestamp_writes: None });
        pass.set_pipeline(&self.present_pipeline);
        pass.set_bind_group(0, &target.present_group, &[]);
        pass.dispatch_workgroups(target.width.div_ceil(8), target.height.div_ceil(8), 1);
    }

    /// Presents again without new samples (a display setting changed).
    pub fn represent(&self, params: PresentParams) {
        let mut enc = self.ctx.device.create_command_encoder(&Default::default());
        self.record_present(&mut enc, params);
        self.ctx.queue.submit([enc.finish()]);
    }

    /// Collects the GPU times of finished submissions (never blocks): from submission, or
    /// from the end of the work queued before it if that was still running, to completion.
    pub fn poll_timings(&mut self) {
        let _ = self.ctx.device.poll(wgpu::PollType::Poll);
        while let Some(f) = self.in_flight.front() {
            let Some(done) = *f.done.lock().expect("timing lock") else { break };
            let before = f.before.lock().expect("timing lock").unwrap_or(f.submitted);
            let start = before.max(f.submitted);
            self.timings.push_back(GpuTiming { at: done, gpu: done.saturating_duration_since(start), rays: f.rays });
            self.in_flight.pop_front();
            self.poller.in_flight.fetch_sub(1, Ordering::AcqRel);
        }
        while self.timings.len() > 256 {
            self.timings.pop_front();
        }
    }

    /// Sum of sample values and per-pixel sample counts → the mean image (linear).
    pub fn read_mean(&self) -> Result<Image, GpuError> {
        let target = self.target.as_ref().ok_or_else(|| GpuError::Wgpu("no image yet".into()))?;
        let px: Vec<[f32; 4]> = self.ctx.read_pod(&target.accum, (target.accum.size() / 16) as usize)?;
        let band = target.band();
        let mut img = Image::new(target.width, target.height);
        for y in 0..target.height {
            for x in 0..target.width {
                let i = (y * target.width + x) as usize;
                let n = self.acc.samples_at(&band, x, y);
                if n > 0 {
                    let p = px[i];
                    img.pixels[i] = [p[0] / n as f32, p[1] / n as f32, p[2] / n as f32];
                }
            }
        }
        Ok(img)
    }

    /// The texture egui shows, as 8-bit RGBA rows.
    pub fn read_display(&self) -> Result<image::RgbaImage, GpuError> {
        let target = self.target.as_ref().ok_or_else(|| GpuError::Wgpu("no image yet".into()))?;
        let (w, h) = (target.width, target.height);
        let padded = (w * 4).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
        let buf = self.ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("viewer image readback"),
            size: padded as u64 * h as u64,
            usage: wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut enc = self.ctx.device.create_command_encoder(&Default::default());
        enc.copy_texture_to_buffer(
            target.texture.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &buf,
                layout: wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(padded), rows_per_image: Some(h) },
            },
            wgpu::Extent3d { width: w, height: h, depth_or_array_layers: 1 },
        );
        self.ctx.submit("reading the display", enc)?;
        let bytes = self.ctx.read_buffer(&buf, buf.size())?;
        let mut rows = Vec::with_capacity((w * h * 4) as usize);
        for y in 0..h as usize {
            rows.extend_from_slice(&bytes[y * padded as usize..][..w as usize * 4]);
        }
        // Pixels never rendered are transparent in the texture; save them opaque.
        for p in rows.chunks_mut(4) {
            p[3] = 255;
        }
        image::RgbaImage::from_raw(w, h, rows).ok_or_else(|| GpuError::Wgpu("image size".into()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_present_shader_validates_and_its_parameters_match() {
        let module = naga::front::wgsl::parse_str(&present_source()).expect("present.wgsl parses");
        naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::default())
            .validate(&module)
            .expect("present.wgsl validates");
        let mut layouter = naga::proc::Layouter::default();
        layouter.update(module.to_ctx()).unwrap();
        let (h, ty) = module.types.iter().find(|(_, t)| t.name.as_deref() == Some("Present")).expect("Present");
        assert_eq!(layouter[h].size as usize, std::mem::size_of::<PresentParams>());
        // Every member, in order and at the offset of the Rust field of the same name (Rust's
        // padding is `_pad0`, WGSL's `pad0`); the Rust fields as written in this file.
        let naga::TypeInner::Struct { members, .. } = &ty.inner else { panic!("Present is a struct") };
        let source = include_str!("gpu.rs");
        let body = source.split_once("pub struct PresentParams {").expect("PresentParams").1;
        let body = &body[..body.find("\n}").expect("closing brace")];
        let rust: Vec<&str> =
            body.lines().filter_map(|l| l.trim().strip_prefix("pub ")?.split_once(':')).map(|(f, _)| f).collect();
        let wgsl: Vec<&str> = members.iter().map(|m| m.name.as_deref().unwrap_or("")).collect();
        assert_eq!(rust.iter().map(|f| f.trim_start_matches('_')).collect::<Vec<_>>(), wgsl);
        use std::mem::offset_of;
        let offsets = [
            offset_of!(PresentParams, width),
            offset_of!(PresentParams, height),
            offset_of!(PresentParams, samples),
            offset_of!(PresentParams, next_tile),
            offset_of!(PresentParams, tiles_x),
            offset_of!(PresentParams, tile),
            offset_of!(PresentParams, mode),
            offset_of!(PresentParams, _pad0),
            offset_of!(PresentParams, near),
            offset_of!(PresentParams, far),
            offset_of!(PresentParams, heat_max),
            offset_of!(PresentParams, _pad1),
        ];
        assert_eq!(offsets.len(), members.len());
        for (m, o) in members.iter().zip(offsets) {
            assert_eq!(m.offset as usize, o, "offset of Present.{:?}", m.name);
        }
        // A uniform here would leak on lavapipe 22 (see shaders/modules/bindings.wgsl).
        assert!(module.global_variables.iter().all(|(_, g)| g.space != naga::AddressSpace::Uniform));
    }

    #[test]
    fn a_pixel_counts_the_tiles_done_of_the_pass_in_progress() {
        let band = Band::whole(200, 100, 64);
        assert_eq!((band.tiles_x(), band.tile_count()), (4, 8));
        let acc = Accumulation { samples: 2, next_tile: 5 };
        assert_eq!(acc.samples_at(&band, 199, 63), 3, "tile 3");
        assert_eq!(acc.samples_at(&band, 64, 64), 2, "tile 5 is not done yet");
        assert_eq!(acc.samples_at(&band, 63, 64), 3, "tile 4");
        assert_eq!(acc.samples_at(&band, 128, 99), 2, "tile 6");
    }
}
