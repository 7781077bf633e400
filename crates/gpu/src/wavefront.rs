//! Wavefront path tracing on the GPU (`shaders/wavefront.wgsl`; Laine, Karras & Aila 2013):
//! each sample pass of a band of pixels runs as separate kernels over queues of paths in
//! storage buffers (generate; per segment extend, shade, size the next dispatches, shadow;
//! finish), sized by atomic counters and dispatched indirectly, so that every invocation of a
//! kernel does the same kind of work. It computes what the megakernel (`megakernel.wgsl`) computes,
//! the same sums in the same order: the two images agree to rounding (a test checks it).
//!
//! Which one is faster depends on the device (the book's performance chapter has the runs);
//! `strahl bench` measures both, with the time of each kernel.

use super::stage_frame;
use super::timing::{RenderStats, Timer};
use super::{CachedPipeline, FeatureKey, GpuContext, GpuError, Program, SceneBuffers};
use std::sync::Arc;
use std::time::Duration;
use strahl_core::image::{Image, Region};
use strahl_core::layout::{FRAME_ACCUMULATE, FrameParams};
use web_time::Instant;

/// Invocations of a wavefront workgroup (`WAVEFRONT_WORKGROUP` in the shader).
pub const WORKGROUP: u32 = 64;
/// Storage buffers of bind group 1: paths, hits, pending, two queues, shadow rays, counters,
/// output.
pub const BINDINGS: u32 = 8;

/// Words of the counters buffer (`counters` in the shader), read and written by the kernels;
/// the indirect dispatch arguments (x, 1, 1) sit at [`ARGS_PATHS`](counter::ARGS_PATHS) and
/// [`ARGS_SHADOWS`](counter::ARGS_SHADOWS).
pub mod counter {
    /// Paths in the input queue (extend, shade).
    pub const PATHS_IN: u32 = 0;
    /// Paths wf_shade queued for the next segment.
    pub const PATHS_OUT: u32 = 1;
    /// Shadow rays wf_shade queued.
    pub const SHADOWS_OUT: u32 = 2;
    /// Shadow rays wf_shadow traces.
    pub const SHADOWS_IN: u32 = 3;
    /// Workgroups of extend and shade, then 1, 1.
    pub const ARGS_PATHS: u32 = 4;
    /// Workgroups of shadow, then 1, 1.
    pub const ARGS_SHADOWS: u32 = 7;
    /// Words in all.
    pub const WORDS: usize = 10;
}

/// Bytes of the two indirect argument triples (paths, then shadows).
const ARGS_BYTES: u64 = 4 * (counter::WORDS as u64 - counter::ARGS_PATHS as u64);

/// The kernels, in `Wavefront::pipelines` order.
const ENTRIES: [&str; 6] = ["wf_generate", "wf_extend", "wf_shade", "wf_args", "wf_shadow", "wf_finish"];
const GENERATE: usize = 0;
const EXTEND: usize = 1;
const SHADE: usize = 2;
const ARGS: usize = 3;
const SHADOW: usize = 4;
const FINISH: usize = 5;

/// Bytes of state per path of a band, by buffer: path 64, hit 32, pending 16, two queue
/// entries 4 each, a shadow ray 32 (and 16 of output).
const PATH_BYTES: [(&str, u64); 6] =
    [("path states", 64), ("hits", 32), ("pending light", 16), ("queue", 4), ("queue", 4), ("shadow rays", 32)];

/// The wavefront tracer's kernels and buffers, for bands of up to `band_rows` rows of a region
/// of the image (every method takes the context the tracer was made with).
pub struct Wavefront {
    scene: SceneBuffers,
    frame: FrameParams,
    /// The pixels rendered: the whole image, or a part of a split render.
    region: Region,
    pipelines: Vec<Arc<CachedPipeline>>,
    /// Time spent creating the kernels' pipelines here (zero for those already cached).
    compile_time: Duration,
    band_rows: u32,
    counters: wgpu::Buffer,
    /// The indirect dispatch arguments, copied out of `counters` between kernels (a buffer bound
    /// for storage cannot also be a dispatch's argument buffer).
    args: wgpu::Buffer,
    output: wgpu::Buffer,
    /// Bind group 1 with the queues one way round and the other (segments alternate).
    groups: [wgpu::BindGroup; 2],
}

impl Wavefront {
    /// Compiles (or takes from the cache) the kernels for `key` (which must contain the scene's
    /// features, [`SceneBuffers::runs_with`]) and allocates the queues for `frame` (whole
    /// image; its `spp` and `sample_base` are ignored) in bands of as many rows as one storage
    /// binding holds. Fails, before allocating, where a single row does not fit or the device
    /// binds too few storage buffers.
    pub fn new(ctx: &GpuContext, scene: SceneBuffers, key: FeatureKey, frame: FrameParams) -> Result<Self, GpuError> {
        Self::for_region(ctx, scene, key, frame, Region::whole(frame.width, frame.height))
    }

    /// [`Wavefront::new`] for the pixels of `region` of the image only: each computed as in a
    /// render of the whole image (paths are started from their pixel's place in the image).
    pub fn for_region(
        ctx: &GpuContext,
        scene: SceneBuffers,
        key: FeatureKey,
        frame: FrameParams,
        region: Region,
    ) -> Result<Self, GpuError> {
        assert!(region.fits(frame.width, frame.height), "region {region} of a {}x{} image", frame.width, frame.height);
        if !ctx.has_wavefront(&scene) {
            return Err(GpuError::Device(format!(
                "the wavefront path tracer needs {} storage buffers per shader stage, this device offers {}",
                scene.bindings() + BINDINGS,
                ctx.limits.max_storage_buffers_per_shader_stage
            )));
        }
        let w = region.width() as u64;
        // wf_finish stores pixel (x, y) at (y − out_first_row) · out_pitch + x (raygen's
        // output_index): with the region's width as the pitch, the output starts with x0
        // pixels nothing writes, and is read back from there.
        let lead = 16 * region.x0 as u64;
        let limit = ctx.max_binding_bytes();
        let widest = PATH_BYTES.iter().map(|&(_, b)| b).max().unwrap_or(1).max(16);
        ctx.check_binding_size(&format!("the wavefront state of one {w}-pixel row"), lead + widest * w)?;
        let band_rows = (((limit - lead) / (widest * w)) as u32).min(region.height());
        let paths = band_rows as u64 * w;
        let mut compile_time = Duration::ZERO;
        let mut pipelines = Vec::with_capacity(ENTRIES.len());
        for e in ENTRIES {
            let cached = ctx.cached_pipeline(Program::Wavefront, key, e).is_some();
            let p = ctx.pipeline(Program::Wavefront, key, e)?;
            if !cached {
                compile_time += p.compile_time;
            }
            pipelines.push(p);
        }
        let storage = |label: &str, bytes: u64, extra: wgpu::BufferUsages| {
            ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes.max(16),
                usage: wgpu::BufferUsages::STORAGE | extra,
                mapped_at_creation: false,
            })
        };
        let state: Vec<wgpu::Buffer> =
            PATH_BYTES.iter().map(|&(label, b)| storage(label, b * paths, wgpu::BufferUsages::empty())).collect();
        let counters = storage(
            "wavefront counters",
            4 * counter::WORDS as u64,
            wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
        );
        let args = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("wavefront dispatch arguments"),
            size: ARGS_BYTES,
            usage: wgpu::BufferUsages::INDIRECT | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let output = storage("wavefront output", lead + 16 * paths, wgpu::BufferUsages::COPY_SRC);
        let group = |queue_in: &wgpu::Buffer, queue_out: &wgpu::Buffer| {
            let buffers = [&state[0], &state[1], &state[2], queue_in, queue_out, &state[5], &counters, &output];
            let entries: Vec<_> = buffers
                .iter()
                .enumerate()
                .map(|(i, b)| wgpu::BindGroupEntry { binding: i as u32, resource: b.as_entire_binding() })
                .collect();
            ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("wavefront queues"),
                layout: &pipelines[GENERATE].pipeline.get_bind_group_layout(1),
                entries: &entries,
            })
        };
        let groups = [group(&state[3], &state[4]), group(&state[4], &state[3])];
        Ok(Self { scene, frame, region, pipelines, compile_time, band_rows, counters, args, output, groups })
    }

    /// The variant the kernels were compiled as.
    pub fn key(&self) -> FeatureKey {
        self.pipelines[GENERATE].key
    }

    /// Records one sample pass (sample `sample`) over the rows `rows` of the region, adding to
    /// the output with `accumulate`; with a timer, kernel `k` of the pass writes timestamp pair
    /// `first + k`. Returns the kernels recorded, in order.
    fn record_pass(
        &self,
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
        rows: std::ops::Range<u32>,
        (sample, accumulate): (u32, bool),
        timer: Option<(&Timer, u32)>,
    ) -> Vec<usize> {
        let (first_row, rows) = (rows.start, rows.end - rows.start);
        let w = self.region.width();
        let n = w * rows;
        let band = FrameParams {
            tile_origin: [self.region.x0, first_row],
            tile_size: [w, rows],
            spp: 1,
            sample_base: sample,
            out_pitch: w,
            out_first_row: first_row,
            flags: (self.frame.flags & !FRAME_ACCUMULATE) | if accumulate { FRAME_ACCUMULATE } else { 0 },
            ..self.frame
        };
        stage_frame(ctx, enc, &self.scene, &band);
        let mut start = [0u32; counter::WORDS];
        start[counter::PATHS_IN as usize] = n;
        start[counter::ARGS_PATHS as usize] = n.div_ceil(WORKGROUP);
        start[counter::ARGS_PATHS as usize + 1] = 1;
        start[counter::ARGS_PATHS as usize + 2] = 1;
        start[counter::ARGS_SHADOWS as usize + 1] = 1;
        start[counter::ARGS_SHADOWS as usize + 2] = 1;
        let staging = wgpu::util::DeviceExt::create_buffer_init(
            &ctx.device,
            &wgpu::util::BufferInitDescriptor {
                label: Some("wavefront counters"),
                contents: bytemuck::cast_slice(&start),
                usage: wgpu::BufferUsages::COPY_SRC,
            },
        );
        enc.copy_buffer_to_buffer(&staging, 0, &self.counters, 0, 4 * counter::WORDS as u64);
        let copy_args = |enc: &mut wgpu::CommandEncoder, from: &wgpu::Buffer| {
            enc.copy_buffer_to_buffer(from, 4 * counter::ARGS_PATHS as u64, &self.args, 0, ARGS_BYTES);
        };
        copy_args(enc, &staging);
        let mut kernels = Vec::new();
        let mut dispatch = |enc: &mut wgpu::CommandEncoder, k: usize, group: usize, size: Dispatch| {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some(ENTRIES[k]),
                timestamp_writes: timer.map(|(t, first)| t.writes(first + kernels.len() as u32)),
            });
            pass.set_pipeline(&self.pipelines[k].pipeline);
            pass.set_bind_group(0, &self.scene.bind_group(ctx, &self.pipelines[k]), &[]);
            pass.set_bind_group(1, &self.groups[group], &[]);
            match size {
                Dispatch::Direct(x) => pass.dispatch_workgroups(x, 1, 1),
                Dispatch::Indirect(word) => {
                    pass.dispatch_workgroups_indirect(&self.args, 4 * (word - counter::ARGS_PATHS) as u64)
                }
            }
            drop(pass);
            kernels.push(k);
        };
        dispatch(enc, GENERATE, 0, Dispatch::Direct(n.div_ceil(WORKGROUP)));
        for seg in 0..self.frame.max_depth {
            let g = seg as usize % 2;
            dispatch(enc, EXTEND, g, Dispatch::Indirect(counter::ARGS_PATHS));
            dispatch(enc, SHADE, g, Dispatch::Indirect(counter::ARGS_PATHS));
            dispatch(enc, ARGS, g, Dispatch::Direct(1));
            copy_args(enc, &self.counters);
            dispatch(enc, SHADOW, g, Dispatch::Indirect(counter::ARGS_SHADOWS));
        }
        dispatch(enc, FINISH, 0, Dispatch::Direct(n.div_ceil(WORKGROUP)));
        kernels
    }

    /// Kernels one pass records: generate, four per segment, finish.
    fn kernels_per_pass(&self) -> u32 {
        2 + 4 * self.frame.max_depth
    }

    /// Renders the region at `frame.spp` samples per pixel (band by band, one pass per sample),
    /// with the GPU time of each kernel where the adapter has timestamp queries.
    /// `progress(done, total)` is called after each sample pass of each band.
    pub fn render(&self, ctx: &GpuContext, progress: &dyn Fn(u64, u64)) -> Result<(Image, RenderStats), GpuError> {
        let start = Instant::now();
        let r = self.region;
        let w = r.width();
        let timer = ctx.timestamps.then(|| Timer::new(ctx, self.kernels_per_pass()));
        let mut kernel_ns = [0.0f64; ENTRIES.len()];
        let mut img = Image::new(w, r.height());
        let mut stats = RenderStats { key: self.key(), compile_time: self.compile_time, ..Default::default() };
        let total = r.height().div_ceil(self.band_rows) as u64 * self.frame.spp as u64;
        let mut row0 = r.y0;
        while row0 < r.y1 {
            let rows = self.band_rows.min(r.y1 - row0);
            for s in 0..self.frame.spp {
                let mut enc = ctx.device.create_command_encoder(&Default::default());
                let timing = timer.as_ref().map(|t| (t, 0));
                let kernels =
                    self.record_pass(ctx, &mut enc, row0..row0 + rows, (self.frame.sample_base + s, s > 0), timing);
                if let Some(t) = &timer {
                    t.resolve(&mut enc, kernels.len() as u32);
                }
                ctx.submit("a wavefront sample pass", enc)?;
                if let Some(t) = &timer {
                    for (k, ns) in kernels.iter().zip(t.read_each(ctx, kernels.len() as u32)?) {
                        kernel_ns[*k] += ns;
                    }
                }
                if stats.passes == 0 {
                    // Wait for the first pass alone: where the driver compiles at the first
                    // dispatch, this is where the compile shows.
                    ctx.wait()?;
                    stats.first_pass = start.elapsed();
                }
                stats.passes += 1;
                stats.dispatches += kernels.len() as u32;
                progress(stats.passes as u64, total);
            }
            let lead = r.x0 as usize;
            let px: Vec<[f32; 4]> = ctx.read_pod(&self.output, lead + (rows * w) as usize)?;
            let spp = self.frame.spp as f32;
            let at = (row0 - r.y0) as usize * w as usize;
            for (i, p) in px[lead..].iter().enumerate() {
                img.pixels[at + i] = [p[0] / spp, p[1] / spp, p[2] / spp];
            }
            row0 += rows;
        }
        stats.wall = start.elapsed();
        if timer.is_some() {
            stats.kernel_times =
                ENTRIES.iter().zip(kernel_ns).map(|(e, ns)| (*e, Duration::from_nanos(ns as u64))).collect();
            stats.gpu_time = Some(stats.kernel_times.iter().map(|(_, t)| *t).sum());
        }
        Ok((img, stats))
    }

    /// Fails unless the whole image fits one band (progressive rendering keeps all its sums).
    pub fn check_whole_image(&self, ctx: &GpuContext) -> Result<(), GpuError> {
        if self.band_rows < self.frame.height {
            let widest = PATH_BYTES.iter().map(|&(_, b)| b).max().unwrap_or(1);
            return Err(ctx.too_large(
                format!("the wavefront state of the {}x{} image", self.frame.width, self.frame.height),
                widest * self.frame.width as u64 * self.frame.height as u64,
            ));
        }
        Ok(())
    }

    /// Submits sample passes `first .. first + n` over the whole image (one band), adding to
    /// the sums unless `first` is 0; does not wait.
    pub fn submit_passes(&self, ctx: &GpuContext, first: u32, n: u32) -> Result<(), GpuError> {
        for s in first..first + n {
            let mut enc = ctx.device.create_command_encoder(&Default::default());
            self.record_pass(ctx, &mut enc, 0..self.frame.height, (s, s > 0), None);
            ctx.submit("a wavefront sample pass", enc)?;
        }
        Ok(())
    }

    /// The whole image's sums (one band).
    pub fn output(&self) -> &wgpu::Buffer {
        &self.output
    }
}

/// How a kernel's workgroups are counted: directly, or from the counters buffer at a word.
#[derive(Clone, Copy)]
enum Dispatch {
    Direct(u32),
    Indirect(u32),
}
