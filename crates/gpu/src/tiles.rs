//! Rendering on the GPU: the image is split into bands that fit one storage binding, each band
//! into tiles of at most [`TILE`]×[`TILE`] pixels, one dispatch per tile and sample pass, so
//! no dispatch runs for long.

use super::timing::{RenderStats, Timer};
use super::wavefront::Wavefront;
use super::{
    CachedPipeline, FeatureKey, GpuContext, GpuError, PathKernels, Program, SceneBuffers, block_on, stage_frame,
};
use std::sync::Arc;
use std::time::Duration;
use strahl_core::image::{Image, Region};
use strahl_core::layout::{FRAME_ACCUMULATE, FrameParams};
use strahl_core::scene::RenderMode;
use web_time::Instant;

/// Tile side in pixels.
pub const TILE: u32 = 128;
/// Side of a render workgroup in invocations (`TILE_WORKGROUP` in the shaders).
pub const WORKGROUP: u32 = 8;
const PIXEL_BYTES: u64 = 16;

/// The program and entry point that render in `mode`.
pub fn program_for(mode: RenderMode) -> (Program, &'static str) {
    match mode {
        RenderMode::Whitted => (Program::Whitted, "render"),
        RenderMode::Path => (Program::Path, "render_path"),
    }
}

/// Renders `frame` (whole image; `spp` samples, one pass per sample) in `mode` with the
/// pipeline for `key`, which must contain the scene's features ([`SceneBuffers::runs_with`]).
/// `progress(done, total)` is called after each sample pass of each band.
pub fn render(
    ctx: &GpuContext,
    scene: &SceneBuffers,
    frame: &FrameParams,
    mode: RenderMode,
    key: FeatureKey,
    progress: &dyn Fn(u64, u64),
) -> Result<(Image, RenderStats), GpuError> {
    render_region(ctx, scene, frame, mode, key, Region::whole(frame.width, frame.height), progress)
}

/// Renders the pixels of `region` of the image `frame` describes, as [`render`] does the whole
/// image: every pixel is computed as in a render of the whole image (the shaders index pixels,
/// rays and random numbers by their place in the whole image), only the tiles cover the region.
pub fn render_region(
    ctx: &GpuContext,
    scene: &SceneBuffers,
    frame: &FrameParams,
    mode: RenderMode,
    key: FeatureKey,
    region: Region,
    progress: &dyn Fn(u64, u64),
) -> Result<(Image, RenderStats), GpuError> {
    block_on("rendering", render_region_async(ctx, scene, frame, mode, key, region, progress))
}

/// [`render_region`] without blocking, as a web page renders. (The wavefront tracer, which
/// only old lavapipe runs by default, blocks.)
pub async fn render_region_async(
    ctx: &GpuContext,
    scene: &SceneBuffers,
    frame: &FrameParams,
    mode: RenderMode,
    key: FeatureKey,
    region: Region,
    progress: &dyn Fn(u64, u64),
) -> Result<(Image, RenderStats), GpuError> {
    assert!(scene.runs_with(key), "variant {} cannot render a scene needing {}", key.label(), scene.key.label());
    if mode == RenderMode::Path && ctx.path_kernels(scene)? == PathKernels::Wavefront {
        let wf = Wavefront::for_region(ctx, scene.clone(), key, *frame, region)?;
        return wf.render(ctx, progress);
    }
    render_tiles_async(ctx, scene, frame, mode, key, region, progress).await
}

/// [`render_region`] by tiles: one dispatch of the mode's single kernel (for path tracing the
/// megakernel) per tile and sample pass.
pub fn render_tiles(
    ctx: &GpuContext,
    scene: &SceneBuffers,
    frame: &FrameParams,
    mode: RenderMode,
    key: FeatureKey,
    region: Region,
    progress: &dyn Fn(u64, u64),
) -> Result<(Image, RenderStats), GpuError> {
    block_on("rendering", render_tiles_async(ctx, scene, frame, mode, key, region, progress))
}

/// [`render_tiles`] without blocking.
pub async fn render_tiles_async(
    ctx: &GpuContext,
    scene: &SceneBuffers,
    frame: &FrameParams,
    mode: RenderMode,
    key: FeatureKey,
    region: Region,
    progress: &dyn Fn(u64, u64),
) -> Result<(Image, RenderStats), GpuError> {
    render_program_async(ctx, scene, frame, program_for(mode), key, region, progress).await
}

/// [`render_tiles_async`] with any program of the render programs' bindings (one output
/// buffer of a vec4 a pixel, three values of which are the image): `frame.spp` passes of
/// `entry`, sample `frame.sample_base + s` in pass s, their sum divided by `frame.spp`.
pub async fn render_program_async(
    ctx: &GpuContext,
    scene: &SceneBuffers,
    frame: &FrameParams,
    (program, entry): (Program, &'static str),
    key: FeatureKey,
    region: Region,
    progress: &dyn Fn(u64, u64),
) -> Result<(Image, RenderStats), GpuError> {
    assert!(region.fits(frame.width, frame.height), "region {region} of a {}x{} image", frame.width, frame.height);
    let was_cached = ctx.cached_pipeline(program, key, entry).is_some();
    let pipe = ctx.pipeline(program, key, entry)?;
    let start = Instant::now();
    let (w, h) = (region.width(), region.height());
    let mut img = Image::new(w, h);
    let mut stats = RenderStats { key: pipe.key, dispatches: 0, ..Default::default() };
    if img.pixels.is_empty() {
        return Ok((img, stats));
    }
    let row_bytes = w as u64 * PIXEL_BYTES;
    // The shaders store pixel (x, y) at (y − out_first_row) · out_pitch + x. With the region's
    // width as the pitch, its first column x0 lands x0 pixels into the buffer: the buffer
    // starts with x0 pixels nothing writes, and is read back from there.
    let lead = region.x0 as u64 * PIXEL_BYTES;
    let limit = ctx.max_binding_bytes();
    if row_bytes + lead > limit {
        return Err(ctx.too_large(format!("one {w}-pixel image row"), row_bytes + lead));
    }
    let mut band_rows = ((limit - lead) / row_bytes).min(h as u64) as u32;
    if band_rows < h && band_rows >= TILE {
        band_rows -= band_rows % TILE;
    }
    let output = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("render output"),
        size: lead + band_rows as u64 * row_bytes,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let out_group = ctx.output_bind_group(&output);
    let tiles_x = w.div_ceil(TILE);
    let max_tiles = tiles_x * band_rows.div_ceil(TILE);
    let timer = ctx.timestamps.then(|| Timer::new(ctx, max_tiles));
    let mut gpu_ns = 0.0f64;
    let total_steps = h.div_ceil(band_rows) as u64 * frame.spp as u64;
    let mut step = 0u64;
    let mut row0 = region.y0;
    while row0 < region.y1 {
        let rows = band_rows.min(region.y1 - row0);
        let band = Band { width: w, first_col: region.x0, first_row: row0, rows, tile: TILE };
        for s in 0..frame.spp {
            let mut enc = ctx.device.create_command_encoder(&Default::default());
            let pass_frame = FrameParams { sample_base: frame.sample_base + s, ..*frame };
            let accumulate = s > 0;
            let n_tiles = band.tile_count();
            let pass = Pass { scene, pipeline: &pipe, output: &out_group, frame: &pass_frame, accumulate };
            record_pass(ctx, &mut enc, &pass, &band, 0..n_tiles, timer.as_ref().map(|t| (t, 0)));
            if let Some(t) = &timer {
                t.resolve(&mut enc, n_tiles);
            }
            ctx.submit("a sample pass", enc)?;
            if let Some(t) = &timer {
                gpu_ns += t.read_async(ctx, n_tiles).await?;
            }
            if step == 0 {
                // Wait for the first pass alone: where the driver compiles at the first
                // dispatch, this is where the compile shows.
                ctx.wait()?;
                stats.first_pass = start.elapsed();
            }
            stats.dispatches += n_tiles;
            stats.passes += 1;
            step += 1;
            progress(step, total_steps);
        }
        let first = region.x0 as usize;
        let px: Vec<[f32; 4]> = ctx.read_pod_async(&output, first + rows as usize * w as usize).await?;
        let spp = frame.spp as f32;
        let at = (row0 - region.y0) as usize * w as usize;
        for (i, p) in px[first..].iter().enumerate() {
            img.pixels[at + i] = [p[0] / spp, p[1] / spp, p[2] / spp];
        }
        row0 += rows;
    }
    stats.wall = start.elapsed();
    stats.gpu_time = timer.map(|_| Duration::from_nanos(gpu_ns as u64));
    stats.kernel_times = stats.gpu_time.map(|t| (entry, t)).into_iter().collect();
    stats.compile_time = if was_cached { Duration::ZERO } else { pipe.compile_time };
    Ok((img, stats))
}

/// PathAccumulator path tracing on the GPU: the whole image's sums live in one output buffer that
/// each sample pass adds to, so the image can be read at any time. The passes run as the
/// megakernel (one dispatch per tile) or as the wavefront tracer, whichever
/// [`GpuContext::path_kernels`] picks for the device.
pub struct PathAccumulator {
    ctx: Arc<GpuContext>,
    frame: FrameParams,
    kernels: AccumulatorKernels,
    samples: u32,
    /// The scene, for the denoiser's guides (`Progressive::denoised`, `progressive.rs`).
    scene: SceneBuffers,
}

enum AccumulatorKernels {
    Megakernel { scene: SceneBuffers, pipeline: Arc<CachedPipeline>, output: wgpu::Buffer, out_group: wgpu::BindGroup },
    Wavefront(Box<Wavefront>),
}

impl PathAccumulator {
    /// Compiles (or takes from the cache) the path kernels for the scene's key and allocates
    /// the sums for `frame` (whole image; its `spp` and `sample_base` are ignored), with the
    /// kernels this device runs best. Fails, before allocating, when the image does not fit one
    /// storage binding.
    pub fn new(ctx: Arc<GpuContext>, scene: SceneBuffers, frame: FrameParams) -> Result<Self, GpuError> {
        let kernels = ctx.path_kernels(&scene)?;
        Self::with_kernels(ctx, scene, frame, kernels)
    }

    /// [`PathAccumulator::new`] with the given kernels.
    pub fn with_kernels(
        ctx: Arc<GpuContext>,
        scene: SceneBuffers,
        frame: FrameParams,
        kernels: PathKernels,
    ) -> Result<Self, GpuError> {
        let bytes = frame.width as u64 * frame.height as u64 * PIXEL_BYTES;
        ctx.check_binding_size(&format!("the {}x{} accumulation buffer", frame.width, frame.height), bytes)?;
        let kept = scene.clone();
        let kernels = match kernels {
            PathKernels::Wavefront => {
                let key = scene.key;
                let wf = Wavefront::new(&ctx, scene, key, frame)?;
                wf.check_whole_image(&ctx)?;
                AccumulatorKernels::Wavefront(Box::new(wf))
            }
            PathKernels::Megakernel => {
                let (program, entry) = program_for(RenderMode::Path);
                let pipeline = ctx.pipeline(program, scene.key, entry)?;
                let output = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("accumulation"),
                    size: bytes,
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                    mapped_at_creation: false,
                });
                let out_group = ctx.output_bind_group(&output);
                AccumulatorKernels::Megakernel { scene, pipeline, output, out_group }
            }
        };
        Ok(Self { ctx, frame, kernels, samples: 0, scene: kept })
    }

    /// The scene it renders.
    pub fn scene(&self) -> &SceneBuffers {
        &self.scene
    }

    /// The frame it renders (one sample a pixel per pass).
    pub fn frame(&self) -> &FrameParams {
        &self.frame
    }

    pub fn context(&self) -> &GpuContext {
        &self.ctx
    }

    /// The kernels the passes run as.
    pub fn kernels(&self) -> PathKernels {
        match self.kernels {
            AccumulatorKernels::Megakernel { .. } => PathKernels::Megakernel,
            AccumulatorKernels::Wavefront(_) => PathKernels::Wavefront,
        }
    }

    /// Adds samples `samples() .. samples() + n` to every pixel and waits for the GPU.
    pub fn add_samples(&mut self, n: u32) -> Result<(), GpuError> {
        match &self.kernels {
            AccumulatorKernels::Wavefront(wf) => wf.submit_passes(&self.ctx, self.samples, n)?,
            AccumulatorKernels::Megakernel { scene, pipeline, out_group, .. } => {
                let band = Band::whole(self.frame.width, self.frame.height, TILE);
                for k in 0..n {
                    let mut enc = self.ctx.device.create_command_encoder(&Default::default());
                    let frame = FrameParams { sample_base: self.samples + k, ..self.frame };
                    let accumulate = self.samples + k > 0;
                    let pass = Pass { scene, pipeline, output: out_group, frame: &frame, accumulate };
                    record_pass(&self.ctx, &mut enc, &pass, &band, 0..band.tile_count(), None);
                    self.ctx.submit("a sample pass", enc)?;
                }
            }
        }
        self.ctx.wait()?;
        self.samples += n;
        Ok(())
    }

    pub fn samples(&self) -> u32 {
        self.samples
    }

    /// Starts over from zero samples (the next pass overwrites the sums).
    pub fn reset(&mut self) {
        self.samples = 0;
    }

    /// The mean of the samples so far (black before the first).
    pub fn image(&self) -> Result<Image, GpuError> {
        block_on("reading the image", self.image_async())
    }

    /// [`PathAccumulator::image`] without blocking. The sums are copied when this is called
    /// and the future holds the copy, not `self`: samples added while it waits do not reach
    /// it.
    pub fn image_async(&self) -> impl std::future::Future<Output = Result<Image, GpuError>> + 'static {
        let ctx = self.ctx.clone();
        let (width, height, samples) = (self.frame.width, self.frame.height, self.samples);
        let output = match &self.kernels {
            AccumulatorKernels::Megakernel { output, .. } => output,
            AccumulatorKernels::Wavefront(wf) => wf.output(),
        };
        let bytes = width as u64 * height as u64 * PIXEL_BYTES;
        let copy = (samples > 0).then(|| ctx.copy_for_reading(output, bytes));
        async move {
            let mut img = Image::new(width, height);
            let Some(copy) = copy else { return Ok(img) };
            let px: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(&ctx.map_read(copy?).await?);
            let k = 1.0 / samples as f32;
            for (p, s) in img.pixels.iter_mut().zip(px) {
                *p = [s[0] * k, s[1] * k, s[2] * k];
            }
            Ok(img)
        }
    }
}

/// The pixels of the image one output buffer holds, `rows` rows of `width` columns from
/// (`first_col`, `first_row`), cut into tiles of `tile`×`tile` pixels (row-major order: tile
/// `i` is column `i % tiles_x`, row `i / tiles_x` of the band).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Band {
    /// Columns in the band (also the output buffer's row pitch): the image width unless only
    /// a region is rendered.
    pub width: u32,
    /// First image column of the band (0 unless only a region is rendered).
    pub first_col: u32,
    /// First image row of the band (row 0 of the output buffer).
    pub first_row: u32,
    pub rows: u32,
    /// Tile side in pixels.
    pub tile: u32,
}

impl Band {
    /// The whole `width`×`height` image as one band (one output buffer).
    pub fn whole(width: u32, height: u32, tile: u32) -> Self {
        Self { width, first_col: 0, first_row: 0, rows: height, tile }
    }

    pub fn tiles_x(&self) -> u32 {
        self.width.div_ceil(self.tile)
    }

    pub fn tile_count(&self) -> u32 {
        self.tiles_x() * self.rows.div_ceil(self.tile)
    }

    /// Origin (image pixels) and size of tile `i`.
    pub fn tile_rect(&self, i: u32) -> ([u32; 2], [u32; 2]) {
        let tx = self.first_col + (i % self.tiles_x()) * self.tile;
        let ty = self.first_row + (i / self.tiles_x()) * self.tile;
        let end = (self.first_col + self.width, self.first_row + self.rows);
        ([tx, ty], [self.tile.min(end.0 - tx), self.tile.min(end.1 - ty)])
    }
}

/// What one sample pass (sample `frame.sample_base`, one sample per pixel) dispatches: `pipeline`
/// over `scene`, writing into the output buffer bound by `output` (group 1:
/// `array<vec4<f32>>`, [`GpuContext::output_bind_group`]), overwriting, or with `accumulate`
/// adding to what it holds.
pub struct Pass<'a> {
    pub scene: &'a SceneBuffers,
    pub pipeline: &'a CachedPipeline,
    pub output: &'a wgpu::BindGroup,
    pub frame: &'a FrameParams,
    pub accumulate: bool,
}

/// Records into `enc` the dispatches of tiles `tiles` of `pass` over `band`. No readback: the
/// caller submits `enc` and decides what happens to the buffer. With `timer: (t, first)`,
/// dispatch `k` of this call writes timestamp pair `first + k` of `t`. Returns the number of
/// dispatches recorded.
pub fn record_pass(
    ctx: &GpuContext,
    enc: &mut wgpu::CommandEncoder,
    pass: &Pass,
    band: &Band,
    tiles: std::ops::Range<u32>,
    timer: Option<(&Timer, u32)>,
) -> u32 {
    let Pass { scene, pipeline, output, frame, accumulate } = *pass;
    let scene_group = scene.bind_group(ctx, pipeline);
    let mut n = 0u32;
    for i in tiles.start..tiles.end.min(band.tile_count()) {
        let (origin, size) = band.tile_rect(i);
        let tile = FrameParams {
            tile_origin: origin,
            tile_size: size,
            spp: 1,
            out_pitch: band.width,
            out_first_row: band.first_row,
            flags: (frame.flags & !FRAME_ACCUMULATE) | if accumulate { FRAME_ACCUMULATE } else { 0 },
            ..*frame
        };
        stage_frame(ctx, enc, scene, &tile);
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("render tile"),
            timestamp_writes: timer.map(|(t, first)| t.writes(first + n)),
        });
        pass.set_pipeline(&pipeline.pipeline);
        pass.set_bind_group(0, &scene_group, &[]);
        pass.set_bind_group(1, output, &[]);
        pass.dispatch_workgroups(size[0].div_ceil(WORKGROUP), size[1].div_ceil(WORKGROUP), 1);
        drop(pass);
        n += 1;
    }
    n
}
