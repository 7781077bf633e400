//! `strahl view`: an interactive window (eframe + egui on wgpu) that renders a scene
//! progressively on the GPU.
//!
//! The viewer opens its window through eframe on Vulkan, asking eframe for the device strahl
//! needs ([`GpuContext::device_descriptor`]), and builds strahl's [`GpuContext`] on that same
//! device. Each UI frame dispatches a bounded number of tiles of the current sample pass
//! into an accumulation buffer, then a present pass writes the mean into an rgba8unorm
//! texture that egui draws as a native texture: nothing is read back per frame. Anything
//! that changes the image (camera, mode, depth, size, visibility, a reloaded file) restarts
//! the accumulation; otherwise samples keep adding up to the sample limit.

pub mod camera;
pub mod gpu;
pub mod scene;

use crate::accel::Bvh;
use crate::backend::gpu::{CachedPipeline, FeatureKey, GpuContext, Program, SceneBuffers};
use crate::gpu_types::{GpuFrame, GpuScene};
use crate::metrics::Agreement;
use crate::primitives::Primitives;
use crate::render::Prepared;
use anyhow::{Context as _, Result, anyhow};
use camera::ViewCamera;
use eframe::egui;
use eframe::egui_wgpu;
use gpu::{PresentParams, ViewMode, ViewRenderer};
use scene::{Job, Watcher};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// GPU time per UI frame the progressive passes aim at (ms).
const GPU_MS_PER_FRAME: f64 = 20.0;

/// GPU time of one whole sample pass while the camera moves (ms); see `preview_factor`.
const PREVIEW_PASS_MS: f64 = 40.0;

/// What `strahl view` was asked to do.
#[derive(Clone, Debug)]
pub struct ViewOptions {
    pub scene: PathBuf,
    /// Window inner size in points.
    pub size: [u32; 2],
    /// Render resolution as a fraction of the image area's pixels.
    pub scale: f32,
    pub mode: ViewMode,
    /// Samples accumulated before the viewer stops refining.
    pub max_samples: u32,
    /// Run this many frames, then exit (with `screenshot`: this many full sample passes).
    pub frames: Option<u32>,
    /// Save the window as this PNG after `frames` frames, then exit.
    pub screenshot: Option<PathBuf>,
}

/// Opens the window and runs until it is closed (or, with `frames`, until done).
pub fn run(opts: ViewOptions) -> Result<()> {
    let prep = scene::load(&opts.scene).map_err(|e| anyhow!(e))?;
    eprintln!(
        "scene: {} objects, {} triangles, BVH {} nodes built in {:.3} s",
        prep.scene.objects.len(),
        prep.prims.triangles.len(),
        prep.bvh.nodes.len(),
        prep.build_time.as_secs_f64()
    );
    let mut setup = egui_wgpu::WgpuSetupCreateNew::without_display_handle();
    // Vulkan only, like the rest of strahl (lavapipe's GL adapter renders slightly differently).
    setup.instance_descriptor.backends = wgpu::Backends::VULKAN;
    setup.device_descriptor = Arc::new(|adapter| {
        let mut d = GpuContext::device_descriptor(adapter);
        d.label = Some("strahl view");
        d
    });
    let native = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_inner_size([opts.size[0] as f32, opts.size[1] as f32])
            .with_title(format!("strahl view: {}", opts.scene.display())),
        renderer: eframe::Renderer::Wgpu,
        wgpu_options: egui_wgpu::WgpuConfiguration { wgpu_setup: setup.into(), ..Default::default() },
        // The image must reach the screen as rendered (dithering would add noise to it).
        dithering: false,
        ..Default::default()
    };
    let failure: Arc<Mutex<Option<anyhow::Error>>> = Arc::default();
    let app_failure = failure.clone();
    eframe::run_native(
        "strahl view",
        native,
        Box::new(move |cc| {
            let app = Viewer::new(cc, prep, opts, app_failure).map_err(|e| format!("{e:#}"))?;
            Ok(Box::new(app))
        }),
    )
    .map_err(|e| {
        let e = e.to_string();
        if e.to_ascii_lowercase().contains("wgpu") {
            anyhow!(
                "the viewer window failed: {e} (strahl view needs a Vulkan driver that can draw to the window; on \
                 Debian/Ubuntu the software one is `apt-get install mesa-vulkan-drivers`)"
            )
        } else {
            anyhow!("the viewer window failed: {e}")
        }
    })?;
    match failure.lock().expect("failure lock").take() {
        Some(e) => Err(e),
        None => Ok(()),
    }
}

/// The key of the shader that can render every object of `scene`.
fn full_key(scene: &crate::scene::Scene) -> FeatureKey {
    let prims = Primitives::<f32>::from_scene(scene);
    let mut key = FeatureKey::for_scene(&GpuScene::new(scene, &prims, &Bvh::default()));
    if prims.bounded_count() > FeatureKey::BRUTE_FORCE_MAX {
        key.0 |= FeatureKey::BVH;
    }
    key
}

/// A finished GPU-against-CPU comparison.
struct Comparison {
    samples: u32,
    size: [u32; 2],
    cpu_time: Duration,
    agreement: Agreement,
    /// Largest channel difference per pixel, in 8-bit sRGB codes.
    diff: Vec<u8>,
}

struct ComparisonView {
    c: Comparison,
    texture: egui::TextureHandle,
}

/// Loaded off the UI thread: the prepared scene (hidden objects left out) and the key of
/// the whole scene.
type Loaded = Result<(Prepared, FeatureKey, Vec<bool>), String>;

/// Compiling a pipeline on a worker thread (the error as text).
type CompileJob = Job<Result<(), String>>;

/// Filled by the screenshot callback: whether the PNG was written.
type ShotResult = Arc<Mutex<Option<Result<(), String>>>>;

/// Screenshot mode: where the shot stands.
enum Shot {
    Rendering,
    Requested { at: Instant, result: ShotResult },
    Closing,
}

struct Viewer {
    opts: ViewOptions,
    gpu: ViewRenderer,
    prep: Arc<Prepared>,
    buffers: SceneBuffers,
    full_key: FeatureKey,
    /// Increases whenever the scene buffers change.
    scene_gen: u64,
    visible: Vec<bool>,
    camera: ViewCamera,
    mode: ViewMode,
    max_depth: u32,
    scale: f32,
    max_samples: u32,
    heat_max: f32,
    /// What the accumulation holds: the frame and scene generation it was started with.
    accumulating: Option<(GpuFrame, u64)>,
    present_dirty: bool,
    /// Tiles per UI frame (adapted to keep their GPU time near [`GPU_MS_PER_FRAME`]).
    budget: f64,
    last_ui: Option<Instant>,
    /// Smoothed UI frame interval in ms.
    frame_ms: f64,
    /// Shortest recent UI frame interval (ms), the cost of a frame without samples.
    base_ms: f64,
    /// The camera of the last frame, and until when it counts as moving.
    last_camera: Option<ViewCamera>,
    moving_until: Option<Instant>,
    /// The GPU timing the budget was last adapted to.
    adapted_to: Option<Instant>,
    worked_last_frame: bool,
    load_job: Option<Job<Loaded>>,
    /// Re-preparing with objects hidden, for the scene file loaded as `file_gen`.
    visibility_job: Option<Job<(u64, Prepared)>>,
    /// Increases with every scene file loaded.
    file_gen: u64,
    visibility_dirty: bool,
    compile_job: Option<((Program, FeatureKey), CompileJob)>,
    failed_compile: Option<(Program, FeatureKey)>,
    cpu_job: Option<Job<Comparison>>,
    compare_requested: bool,
    comparison: Option<ComparisonView>,
    watcher: Watcher,
    load_error: Option<String>,
    gpu_error: Option<String>,
    save_path: String,
    save_status: Option<String>,
    shot: Option<Shot>,
    failure: Arc<Mutex<Option<anyhow::Error>>>,
    /// UI frames run, and their intervals and sample counts (--frames).
    frames_run: u32,
    frame_log: Vec<f64>,
    image_rect_px: [u32; 4],
}

impl Viewer {
    fn new(
        cc: &eframe::CreationContext<'_>,
        prep: Prepared,
        opts: ViewOptions,
        failure: Arc<Mutex<Option<anyhow::Error>>>,
    ) -> Result<Self> {
        let rs = cc.wgpu_render_state.clone().context("eframe did not start on wgpu")?;
        let ctx = GpuContext::from_device(rs.device.clone(), rs.queue.clone(), rs.adapter.get_info())?;
        let ctx = Arc::new(ctx);
        eprintln!("adapter: {}", ctx.adapter_name());
        let buffers = SceneBuffers::upload(&ctx, &prep.gpu)?;
        let full_key = buffers.key;
        let save_path = {
            let stem = opts.scene.file_stem().map_or("view".into(), |s| s.to_string_lossy().into_owned());
            format!("{stem}-view.png")
        };
        Ok(Self {
            gpu: ViewRenderer::new(ctx, rs),
            camera: ViewCamera::from_scene(&prep.scene.camera),
            max_depth: prep.scene.render.max_depth,
            visible: vec![true; prep.scene.objects.len()],
            watcher: Watcher::new(&opts.scene, Some(&prep.scene)),
            prep: Arc::new(prep),
            buffers,
            full_key,
            scene_gen: 0,
            mode: opts.mode,
            scale: opts.scale,
            max_samples: if opts.screenshot.is_some() { opts.frames.unwrap_or(1).max(1) } else { opts.max_samples },
            heat_max: 64.0,
            accumulating: None,
            present_dirty: false,
            budget: 4.0,
            last_ui: None,
            frame_ms: 0.0,
            base_ms: f64::INFINITY,
            adapted_to: None,
            last_camera: None,
            moving_until: None,
            worked_last_frame: false,
            load_job: None,
            visibility_job: None,
            file_gen: 0,
            visibility_dirty: false,
            compile_job: None,
            failed_compile: None,
            cpu_job: None,
            compare_requested: false,
            comparison: None,
            load_error: None,
            gpu_error: None,
            save_path,
            save_status: None,
            shot: opts.screenshot.as_ref().map(|_| Shot::Rendering),
            failure,
            frames_run: 0,
            frame_log: Vec::new(),
            image_rect_px: [0; 4],
            opts,
        })
    }

    /// Screenshot mode renders one whole sample pass per frame, so that the image after N
    /// frames holds exactly N samples.
    fn whole_passes(&self) -> bool {
        self.shot.is_some()
    }

    fn pipeline_id(&self) -> (Program, FeatureKey, &'static str) {
        let key = if self.buffers.runs_with(self.full_key) { self.full_key } else { self.buffers.key };
        let (program, entry) = self.mode.program();
        (program, key.for_program(program), entry)
    }

    /// "render SPHERES+POINT_LIGHTS" / "view SPHERES+COUNT_VISITS".
    fn variant_label(&self) -> String {
        let (program, key, entry) = self.pipeline_id();
        let extra = if program == Program::View { "+COUNT_VISITS" } else { "" };
        format!("{entry}: {}{extra}", key.label())
    }

    /// The pipeline of the current mode, or None while it compiles on a worker thread.
    fn pipeline(&mut self) -> Option<Arc<CachedPipeline>> {
        let (program, key, entry) = self.pipeline_id();
        if let Some(p) = self.gpu.ctx.cached_pipeline(program, key, entry) {
            return Some(p);
        }
        if self.failed_compile == Some((program, key)) {
            return None;
        }
        if self.whole_passes() {
            return match self.gpu.ctx.pipeline(program, key, entry) {
                Ok(p) => Some(p),
                Err(e) => {
                    self.gpu_error = Some(e.to_string());
                    self.failed_compile = Some((program, key));
                    None
                }
            };
        }
        if self.compile_job.as_ref().is_none_or(|(id, _)| *id != (program, key)) {
            let ctx = self.gpu.ctx.clone();
            let job = Job::spawn(move || ctx.pipeline(program, key, entry).map(|_| ()).map_err(|e| e.to_string()));
            self.compile_job = Some(((program, key), job));
        }
        None
    }

    fn install(&mut self, prep: Prepared) {
        match SceneBuffers::upload(&self.gpu.ctx, &prep.gpu) {
            Ok(b) => {
                self.buffers = b;
                self.prep = Arc::new(prep);
                self.scene_gen += 1;
                self.gpu_error = None;
            }
            Err(e) => self.gpu_error = Some(e.to_string()),
        }
    }

    fn start_reload(&mut self) {
        if self.load_job.is_some() {
            return;
        }
        let path = self.opts.scene.clone();
        let visible = self.visible.clone();
        self.load_job = Some(Job::spawn(move || {
            let scene = crate::scene::Scene::load(&path).map_err(|e| e.to_string())?;
            let key = full_key(&scene);
            let visible = if visible.len() == scene.objects.len() { visible } else { vec![true; scene.objects.len()] };
            Ok((scene::prepare(scene, &visible), key, visible))
        }));
    }

    fn start_visibility(&mut self) {
        if self.visibility_job.is_some() {
            self.visibility_dirty = true;
            return;
        }
        let scene = self.prep.scene.clone();
        let visible = self.visible.clone();
        let file_gen = self.file_gen;
        self.visibility_job = Some(Job::spawn(move || (file_gen, scene::prepare(scene, &visible))));
    }

    fn poll_jobs(&mut self, ctx: &egui::Context) {
        if let Some(job) = &self.load_job
            && let Some(r) = job.poll()
        {
            self.load_job = None;
            match r {
                Ok(Ok((prep, key, visible))) => {
                    if prep.scene.camera != self.prep.scene.camera {
                        self.camera = ViewCamera::from_scene(&prep.scene.camera);
                    }
                    if prep.scene.render != self.prep.scene.render {
                        self.max_depth = prep.scene.render.max_depth;
                    }
                    self.watcher.watch(&self.opts.scene, Some(&prep.scene));
                    // Checkboxes changed while it loaded: apply them to the new scene next.
                    if self.visible.len() == visible.len() && self.visible != visible {
                        self.visibility_dirty = true;
                    } else {
                        self.visible = visible;
                    }
                    self.full_key = key;
                    self.load_error = None;
                    self.failed_compile = None;
                    self.file_gen += 1;
                    self.install(prep);
                }
                Ok(Err(text)) => self.load_error = Some(text),
                Err(()) => self.load_error = Some("loading the scene failed (the loader thread panicked)".into()),
            }
        }
        if let Some(job) = &self.visibility_job
            && let Some(r) = job.poll()
        {
            self.visibility_job = None;
            match r {
                // Prepared from the file as it is loaded now.
                Ok((file_gen, prep)) if file_gen == self.file_gen => self.install(prep),
                // A reload came in between: it kept the checkboxes; apply them to it.
                Ok(_) => self.visibility_dirty = true,
                Err(()) => {}
            }
        }
        if self.visibility_dirty && self.visibility_job.is_none() && self.load_job.is_none() {
            self.visibility_dirty = false;
            self.start_visibility();
        }
        if let Some((id, job)) = &self.compile_job
            && let Some(r) = job.poll()
        {
            let id = *id;
            self.compile_job = None;
            match r {
                Ok(Ok(())) => {}
                Ok(Err(e)) => {
                    self.gpu_error = Some(e);
                    self.failed_compile = Some(id);
                }
                Err(()) => self.failed_compile = Some(id),
            }
        }
        if let Some(job) = &self.cpu_job
            && let Some(r) = job.poll()
        {
            self.cpu_job = None;
            if let Ok(c) = r {
                let rgb: Vec<u8> = c.diff.iter().flat_map(|&d| diff_colour(d)).collect();
                let image = egui::ColorImage::from_rgb([c.size[0] as usize, c.size[1] as usize], &rgb);
                let texture = ctx.load_texture("gpu-cpu difference", image, egui::TextureOptions::NEAREST);
                self.comparison = Some(ComparisonView { c, texture });
            }
        }
    }

    /// The frame parameters of the current view at `w`×`h` (one sample per pass).
    fn frame(&self, w: u32, h: u32) -> GpuFrame {
        let mut f = self.prep.frame(w, h);
        let c = crate::render::camera::frame(&self.camera.to_camera(), w, h);
        f.eye = c.eye;
        f.forward = c.forward;
        f.right = c.right;
        f.up = c.up;
        f.max_depth = self.max_depth;
        f.spp = 1;
        // The mode's flags, keeping the scene's (FRAME_ENVIRONMENT).
        f.flags = self.mode.flags() | (f.flags & crate::gpu_types::FRAME_ENVIRONMENT);
        f
    }

    /// Distances from the eye to the nearest and farthest point of the bounded geometry.
    fn depth_range(&self) -> (f32, f32) {
        use crate::math::V3;
        let eye = self.camera.eye;
        match self.prep.bvh.nodes.first() {
            Some(root) => {
                let lo = V3::from_array(root.bmin).cast::<f64>();
                let hi = V3::from_array(root.bmax).cast::<f64>();
                let near = (eye - eye.max_elem(lo).min_elem(hi)).length();
                let far = (0..8)
                    .map(|i| {
                        let corner = V3::new(
                            if i & 1 == 0 { lo.x } else { hi.x },
                            if i & 2 == 0 { lo.y } else { hi.y },
                            if i & 4 == 0 { lo.z } else { hi.z },
                        );
                        (corner - eye).length()
                    })
                    .fold(0.0, f64::max);
                (near as f32, far.max(near * (1.0 + 1e-6)).max(f64::from(f32::MIN_POSITIVE)) as f32)
            }
            None => (0.0, (10.0 * self.camera.distance()) as f32),
        }
    }

    fn present_params(&self) -> PresentParams {
        let (near, far) = self.depth_range();
        PresentParams { mode: self.mode as u32, near, far, heat_max: self.heat_max, ..Default::default() }
    }

    fn handle_input(&mut self, ctx: &egui::Context, response: &egui::Response, height_px: f64) {
        let ppp = ctx.pixels_per_point() as f64;
        if response.dragged_by(egui::PointerButton::Primary) {
            let d = response.drag_delta();
            self.camera.orbit(d.x as f64 * 0.01, d.y as f64 * 0.01);
        }
        if response.dragged_by(egui::PointerButton::Secondary) || response.dragged_by(egui::PointerButton::Middle) {
            let d = response.drag_delta();
            self.camera.pan(d.x as f64 * ppp, d.y as f64 * ppp, height_px);
        }
        if response.hovered() {
            let scroll = ctx.input(|i| i.smooth_scroll_delta.y);
            if scroll != 0.0 {
                self.camera.zoom((-scroll as f64 * 0.002).exp());
            }
        }
        if ctx.egui_wants_keyboard_input() {
            return;
        }
        use egui::Key;
        let (dt, down, fast, reset) = ctx.input(|i| {
            let k = |key| if i.key_down(key) { 1.0 } else { 0.0 };
            let down = [k(Key::W) - k(Key::S), k(Key::D) - k(Key::A), k(Key::E) - k(Key::Q)];
            (i.unstable_dt.min(0.1) as f64, down, i.modifiers.shift, i.key_pressed(Key::R))
        });
        if down != [0.0; 3] {
            // In scene units per second, relative to the view: a scene's scale does not matter.
            let speed = self.camera.distance() * 0.6 * if fast { 4.0 } else { 1.0 } * dt;
            self.camera.fly(down[0] * speed, down[1] * speed, down[2] * speed);
            ctx.request_repaint();
        }
        if reset {
            self.camera = ViewCamera::from_scene(&self.prep.scene.camera);
        }
    }

    /// The image area: input, the sample passes of this frame, and the image.
    fn central(&mut self, ui: &mut egui::Ui) {
        let ctx = ui.ctx().clone();
        let rect = ui.max_rect();
        let ppp = ctx.pixels_per_point();
        // The image sits on whole physical pixels, so that at scale 1 one texel is one pixel.
        let x0 = (rect.min.x * ppp).ceil();
        let y0 = (rect.min.y * ppp).ceil();
        let x1 = (rect.max.x * ppp).floor().max(x0 + 1.0);
        let y1 = (rect.max.y * ppp).floor().max(y0 + 1.0);
        let (pw, ph) = ((x1 - x0) as u32, (y1 - y0) as u32);
        let image_rect = egui::Rect::from_min_max(egui::pos2(x0 / ppp, y0 / ppp), egui::pos2(x1 / ppp, y1 / ppp));
        self.image_rect_px = [x0 as u32, y0 as u32, pw, ph];
        let response = ui.interact(rect, ui.scope_id().with("image"), egui::Sense::click_and_drag());
        self.handle_input(&ctx, &response, ph as f64);

        // While the camera moves, a heavy scene renders coarser, so that whole passes keep up.
        if self.last_camera.as_ref() != Some(&self.camera) {
            if self.last_camera.is_some() {
                self.moving_until = Some(Instant::now() + Duration::from_millis(300));
            }
            self.last_camera = Some(self.camera.clone());
        }
        let moving = self.moving_until.is_some_and(|t| Instant::now() < t);
        if self.moving_until.is_some() && !moving {
            self.moving_until = None;
        }
        let scale = if moving { self.scale / self.preview_factor(pw, ph) } else { self.scale };
        let max_side = self.gpu.ctx.limits.max_texture_dimension_2d;
        let w = ((pw as f32 * scale).round() as u32).clamp(1, max_side);
        let h = ((ph as f32 * scale).round() as u32).clamp(1, max_side);
        let filter = if (w, h) == (pw, ph) { wgpu::FilterMode::Nearest } else { wgpu::FilterMode::Linear };
        let mut restart = match self.gpu.ensure_target(w, h, filter) {
            Ok(new) => new,
            Err(e) => {
                self.gpu_error = Some(e.to_string());
                false
            }
        };
        let frame = self.frame(w, h);
        if self.accumulating != Some((frame, self.scene_gen)) {
            restart = true;
        }
        if restart {
            self.gpu.acc = Default::default();
            self.accumulating = Some((frame, self.scene_gen));
            self.present_dirty = true;
        }
        self.worked_last_frame = false;
        if self.gpu.target.is_some()
            && let Some(pipe) = self.pipeline()
        {
            let band = self.gpu.target.as_ref().expect("target").band();
            if self.gpu.acc.samples < self.max_samples {
                let budget = if self.whole_passes() {
                    band.tile_count() - self.gpu.acc.next_tile
                } else {
                    self.budget.round().max(1.0) as u32
                };
                let params = self.present_params();
                let n = self.gpu.step(&self.buffers, &pipe.pipeline, &frame, budget, self.max_samples, params);
                self.worked_last_frame = n > 0;
            } else if self.present_dirty {
                self.gpu.represent(self.present_params());
            }
            self.present_dirty = false;
        }
        self.maybe_start_comparison(&frame);

        let painter = ui.painter();
        painter.rect_filled(rect, 0.0, egui::Color32::from_gray(20));
        if let Some(t) = &self.gpu.target {
            let uv = egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0));
            painter.image(t.texture_id, image_rect, uv, egui::Color32::WHITE);
        }
    }

    /// How much coarser to render while the camera moves: enough that a whole sample pass
    /// takes about [`PREVIEW_PASS_MS`] of GPU time at the measured speed (1: no change).
    fn preview_factor(&self, pw: u32, ph: u32) -> f32 {
        if self.whole_passes() {
            return 1.0;
        }
        let (_, rays_per_s) = self.timing_summary();
        let Some(r) = rays_per_s else { return 1.0 };
        let rays = pw as f64 * ph as f64 * (self.scale as f64).powi(2);
        let pass_ms = rays / r * 1e3;
        (pass_ms / PREVIEW_PASS_MS).sqrt().clamp(1.0, 8.0) as f32
    }

    /// Reads the GPU image back and starts the CPU render of the same samples, once the
    /// accumulation sits on a whole number of passes.
    fn maybe_start_comparison(&mut self, frame: &GpuFrame) {
        let acc = self.gpu.acc;
        if !self.compare_requested || self.cpu_job.is_some() || acc.samples == 0 || acc.next_tile != 0 {
            return;
        }
        self.compare_requested = false;
        let Some(render_mode) = self.mode.render_mode() else {
            return;
        };
        let gpu_image = match self.gpu.read_mean() {
            Ok(i) => i,
            Err(e) => {
                self.gpu_error = Some(e.to_string());
                return;
            }
        };
        let prep = self.prep.clone();
        let frame = GpuFrame { spp: acc.samples, sample_base: 0, flags: 0, ..*frame };
        self.cpu_job = Some(Job::spawn(move || {
            let start = Instant::now();
            let cpu = crate::backend::cpu::render(&prep, &frame, render_mode, &|_| {});
            let cpu_time = start.elapsed();
            let agreement = crate::metrics::agreement(&cpu, &gpu_image, 1);
            let (a, b) = (cpu.to_srgb8(), gpu_image.to_srgb8());
            let diff = a
                .chunks(3)
                .zip(b.chunks(3))
                .map(|(p, q)| p.iter().zip(q).map(|(x, y)| x.abs_diff(*y)).max().unwrap_or(0))
                .collect();
            Comparison { samples: acc.samples, size: [frame.width, frame.height], cpu_time, agreement, diff }
        }));
    }

    fn save(&mut self) {
        let path = PathBuf::from(self.save_path.trim());
        let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        let result: Result<()> = match ext.as_deref() {
            Some("png") => self.gpu.read_display().map_err(anyhow::Error::from).and_then(|img| {
                let rgb = image::DynamicImage::ImageRgba8(img).to_rgb8();
                crate::image::save_encoded(&rgb, image::ImageFormat::Png, &path)
            }),
            Some("exr") => self.gpu.read_mean().map_err(anyhow::Error::from).and_then(|img| img.save(&path)),
            _ => Err(anyhow!("use a .png (what the window shows) or .exr (linear values) file name")),
        };
        self.save_status = Some(match result {
            Ok(()) => format!("saved {} ({} samples)", path.display(), self.gpu.acc.samples),
            Err(e) => format!("cannot save {}: {e:#}", path.display()),
        });
    }

    /// Sets the tiles per UI frame so that their GPU time stays near [`GPU_MS_PER_FRAME`]:
    /// grown or shrunk by the latest measured frame (measured time includes fixed costs
    /// per submission, so it is not assumed proportional to the tiles), or, before any
    /// measurement, so that frames with work last at most a little longer than the
    /// fastest frames seen.
    fn adapt_budget(&mut self, dt_ms: f64) {
        let max = gpu::MAX_TILES_PER_FRAME as f64;
        if let Some(t) = self.gpu.timings.back() {
            if self.adapted_to == Some(t.at) {
                return;
            }
            self.adapted_to = Some(t.at);
            let ms = t.gpu.as_secs_f64() * 1e3;
            let factor = if ms < 0.25 * GPU_MS_PER_FRAME {
                2.0
            } else if ms < 0.8 * GPU_MS_PER_FRAME {
                1.25
            } else if ms > 1.25 * GPU_MS_PER_FRAME {
                0.8
            } else {
                1.0
            };
            self.budget = (self.budget * factor).clamp(1.0, max);
            return;
        }
        self.base_ms = self.base_ms.min(dt_ms).max(1.0) * 1.01;
        if dt_ms > self.base_ms + 2.0 * GPU_MS_PER_FRAME {
            self.budget = (self.budget * 0.75).max(1.0);
        } else if dt_ms < self.base_ms + GPU_MS_PER_FRAME {
            self.budget = (self.budget * 1.25 + 0.25).min(max);
        }
    }

    fn timing_summary(&self) -> (Option<f64>, Option<f64>) {
        // GPU ms per UI frame (median of the recent ones) and primary rays per second.
        let recent: Vec<_> = self.gpu.timings.iter().rev().take(32).collect();
        if recent.is_empty() {
            return (None, None);
        }
        let mut ms: Vec<f64> = recent.iter().map(|t| t.gpu.as_secs_f64() * 1e3).collect();
        ms.sort_by(f64::total_cmp);
        let rays: u64 = recent.iter().map(|t| t.rays).sum();
        let secs: f64 = recent.iter().map(|t| t.gpu.as_secs_f64()).sum();
        (Some(ms[ms.len() / 2]), (secs > 0.0).then(|| rays as f64 / secs))
    }

    fn side_panel(&mut self, ui: &mut egui::Ui) {
        egui::ScrollArea::vertical().id_salt("side").show(ui, |ui| {
            ui.heading("strahl view");
            ui.label(self.opts.scene.display().to_string());
            if let Some(e) = &self.load_error {
                ui.colored_label(egui::Color32::from_rgb(255, 90, 90), format!("reload failed; showing the last good scene:\n{e}"));
            }
            if let Some(e) = &self.gpu_error {
                ui.colored_label(egui::Color32::from_rgb(255, 90, 90), e);
            }
            ui.separator();

            ui.label("mode");
            ui.horizontal_wrapped(|ui| {
                for m in ViewMode::ALL {
                    ui.radio_value(&mut self.mode, m, m.label());
                }
            });
            if self.mode == ViewMode::Cost
                && ui
                    .add(egui::Slider::new(&mut self.heat_max, 1.0..=4096.0).logarithmic(true).text("heat scale"))
                    .changed()
            {
                self.present_dirty = true;
            }
            ui.add_enabled(
                self.mode.render_mode().is_some(),
                egui::Slider::new(&mut self.max_depth, 0..=64).text("max depth"),
            );
            ui.add(egui::Slider::new(&mut self.scale, 0.1..=1.0).text("resolution scale"));
            ui.add(egui::Slider::new(&mut self.max_samples, 1..=4096).logarithmic(true).text("sample limit"));
            let mut fov = self.camera.fov_y;
            if ui.add(egui::Slider::new(&mut fov, 1.0..=170.0).text("field of view °")).changed() {
                self.camera.fov_y = fov;
            }
            if ui.button("reset camera (R)").clicked() {
                self.camera = ViewCamera::from_scene(&self.prep.scene.camera);
            }
            ui.small("left drag: orbit · right/middle drag: pan · wheel: zoom · W A S D Q E: fly (shift: faster)");
            ui.separator();

            let acc = self.gpu.acc;
            let (gpu_ms, rays_per_s) = self.timing_summary();
            egui::Grid::new("stats").num_columns(2).striped(true).show(ui, |ui| {
                let tiles = self.gpu.target.as_ref().map_or(0, |t| t.band().tile_count());
                ui.label("samples");
                let progress = if acc.next_tile > 0 { format!(" (+{}/{} tiles)", acc.next_tile, tiles) } else { String::new() };
                ui.label(format!("{} / {}{progress}", acc.samples, self.max_samples));
                ui.end_row();
                if let Some(t) = &self.gpu.target {
                    ui.label("render size");
                    ui.label(format!("{} × {}", t.width, t.height));
                    ui.end_row();
                }
                ui.label("frame");
                ui.label(if self.frame_ms > 0.0 { format!("{:.1} ms (UI)", self.frame_ms) } else { "idle".into() });
                ui.end_row();
                ui.label("GPU");
                ui.label(gpu_ms.map_or("-".into(), |ms| format!("{ms:.1} ms per frame")))
                    .on_hover_text("submission to completion of this frame's sample tiles");
                ui.end_row();
                ui.label("Mrays/s");
                ui.label(rays_per_s.map_or("-".into(), |r| format!("{:.2} primary", r / 1e6)));
                ui.end_row();
                if let (Some(r), Some(t)) = (rays_per_s, &self.gpu.target) {
                    ui.label("sample pass");
                    ui.label(format!("{:.0} ms", t.width as f64 * t.height as f64 / r * 1e3));
                    ui.end_row();
                }
            });
            let compiling = if self.compile_job.is_some() { " (compiling…)" } else { "" };
            ui.add(egui::Label::new(format!("shader {}{compiling}", self.variant_label())).wrap());
            ui.add(egui::Label::new(format!("adapter {}", self.gpu.ctx.adapter_name())).wrap());
            ui.separator();

            let can_compare = self.mode.render_mode().is_some() && self.cpu_job.is_none() && !self.compare_requested;
            if ui
                .add_enabled(can_compare, egui::Button::new("compare with CPU"))
                .on_hover_text("render this view on the CPU reference with the same samples and show the difference")
                .clicked()
            {
                self.compare_requested = true;
            }
            if self.compare_requested || self.cpu_job.is_some() {
                ui.label("rendering on the CPU…");
            }
            if let Some(v) = &self.comparison {
                let a = &v.c.agreement;
                ui.label(format!(
                    "{}×{}, {} samples, CPU {:.2} s\nwithin 1 code: {:.3} %\nlargest difference: {} codes\nmean FLIP: {:.5}",
                    v.c.size[0],
                    v.c.size[1],
                    v.c.samples,
                    v.c.cpu_time.as_secs_f64(),
                    a.within_tolerance * 100.0,
                    a.max_code_diff,
                    a.mean_flip
                ));
                let width = ui.available_width();
                let size = v.texture.size_vec2();
                ui.image((v.texture.id(), egui::vec2(width, width * size.y / size.x.max(1.0))));
                ui.small("black: equal · grey: 1 code · red: more");
            }
            ui.separator();

            ui.horizontal(|ui| {
                ui.add(egui::TextEdit::singleline(&mut self.save_path).desired_width(170.0));
                if ui.button("save").on_hover_text(".png: what the image area shows; .exr: the linear values").clicked() {
                    self.save();
                }
            });
            if let Some(s) = &self.save_status {
                ui.label(s);
            }
            ui.separator();

            let n = self.visible.len();
            let mut changed = false;
            egui::CollapsingHeader::new(format!("objects ({n})")).default_open(n <= 16).show(ui, |ui| {
                let row = ui.spacing().interact_size.y;
                egui::ScrollArea::vertical().id_salt("objects").max_height(240.0).show_rows(ui, row, n, |ui, rows| {
                    for i in rows {
                        let label = scene::object_label(&self.prep.scene, i);
                        changed |= ui.checkbox(&mut self.visible[i], label).changed();
                    }
                });
            });
            if changed {
                self.start_visibility();
            }
        });
    }

    /// Screenshot mode, after this frame's passes: ask for the shot once the samples are in,
    /// then close when it is saved.
    fn drive_screenshot(&mut self, ctx: &egui::Context) {
        let Some(path) = self.opts.screenshot.clone() else { return };
        if let Some(e) = &self.gpu_error {
            *self.failure.lock().expect("failure lock") = Some(anyhow!("{e}"));
            self.shot = Some(Shot::Closing);
        }
        match &self.shot {
            Some(Shot::Rendering) if self.gpu.acc.samples >= self.max_samples => {
                let [x, y, w, h] = self.image_rect_px;
                let t = self.gpu.target.as_ref().expect("target");
                println!("image_rect {x} {y} {w} {h}");
                println!("render_size {} {}", t.width, t.height);
                println!("samples {}", self.gpu.acc.samples);
                println!("variant {}", self.variant_label());
                println!("adapter {}", self.gpu.ctx.adapter_name());
                let result: ShotResult = Arc::default();
                let slot = result.clone();
                let repaint = ctx.clone();
                ctx.request_screenshot(move |img| {
                    let saved = save_screenshot(&img, &path).map_err(|e| format!("{e:#}"));
                    *slot.lock().expect("screenshot lock") = Some(saved);
                    repaint.request_repaint();
                });
                self.shot = Some(Shot::Requested { at: Instant::now(), result });
            }
            Some(Shot::Requested { at, result }) => {
                let done = result.lock().expect("screenshot lock").take();
                match done {
                    Some(Ok(())) => {
                        println!("wrote {}", path.display());
                        self.print_timings();
                        self.shot = Some(Shot::Closing);
                    }
                    Some(Err(e)) => {
                        *self.failure.lock().expect("failure lock") = Some(anyhow!("saving the screenshot: {e}"));
                        self.shot = Some(Shot::Closing);
                    }
                    None if at.elapsed() > Duration::from_secs(30) => {
                        *self.failure.lock().expect("failure lock") =
                            Some(anyhow!("no screenshot arrived within 30 s"));
                        self.shot = Some(Shot::Closing);
                    }
                    None => ctx.request_repaint_after(Duration::from_millis(20)),
                }
            }
            _ => {}
        }
        if matches!(self.shot, Some(Shot::Closing)) {
            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
        } else {
            ctx.request_repaint();
        }
    }

    fn print_timings(&self) {
        let mut ui_ms = self.frame_log.clone();
        ui_ms.sort_by(f64::total_cmp);
        let median = |v: &[f64]| if v.is_empty() { f64::NAN } else { v[v.len() / 2] };
        let (gpu_ms, rays) = self.timing_summary();
        let (w, h) = self.gpu.target.as_ref().map_or((0, 0), |t| (t.width, t.height));
        println!(
            "timing: {} frames at {w}x{h}, UI frame median {:.1} ms, GPU per frame median {}, {} M primary rays/s, {} samples",
            ui_ms.len(),
            median(&ui_ms),
            gpu_ms.map_or("-".into(), |m| format!("{m:.1} ms")),
            rays.map_or("-".into(), |r| format!("{:.2}", r / 1e6)),
            self.gpu.acc.samples
        );
    }
}

/// Colour of a per-pixel difference of `d` 8-bit codes in the comparison image.
fn diff_colour(d: u8) -> [u8; 3] {
    match d {
        0 => [0, 0, 0],
        1 => [90, 90, 90],
        _ => [(96 + 16 * d as u32).min(255) as u8, 0, 0],
    }
}

fn save_screenshot(img: &egui::ColorImage, path: &Path) -> Result<()> {
    let [w, h] = img.size;
    let rgb: Vec<u8> = img.pixels.iter().flat_map(|c| [c.r(), c.g(), c.b()]).collect();
    let img = image::RgbImage::from_raw(w as u32, h as u32, rgb).context("screenshot size")?;
    crate::image::save_encoded(&img, image::ImageFormat::Png, path)
}

impl eframe::App for Viewer {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        let ctx = ui.ctx().clone();
        let now = Instant::now();
        if let Some(prev) = self.last_ui {
            let dt = (now - prev).as_secs_f64() * 1e3;
            if self.worked_last_frame && dt < 1000.0 {
                self.frame_ms = if self.frame_ms == 0.0 { dt } else { 0.9 * self.frame_ms + 0.1 * dt };
                self.frame_log.push(dt);
                self.adapt_budget(dt);
            } else if !self.worked_last_frame {
                self.frame_ms = 0.0;
            }
        }
        self.last_ui = Some(now);
        self.gpu.poll_timings();
        self.poll_jobs(&ctx);
        if self.watcher.changed() {
            self.start_reload();
        }

        egui::Panel::left("controls")
            .default_size(300.0)
            .min_size(200.0)
            .max_size(600.0)
            .resizable(true)
            .show(ui, |ui| self.side_panel(ui));
        egui::CentralPanel::no_frame().show(ui, |ui| self.central(ui));

        if self.shot.is_some() {
            self.drive_screenshot(&ctx);
            return;
        }
        if let Some(n) = self.opts.frames
            && self.accumulating.is_some()
        {
            self.frames_run += 1;
            if self.frames_run == n {
                self.print_timings();
            }
            if self.frames_run >= n {
                ctx.send_viewport_cmd(egui::ViewportCommand::Close);
            }
            ctx.request_repaint();
        }
        if self.worked_last_frame || (self.gpu.acc.samples < self.max_samples && self.gpu_error.is_none()) {
            ctx.request_repaint();
        }
        let busy = self.load_job.is_some()
            || self.visibility_job.is_some()
            || self.compile_job.is_some()
            || self.cpu_job.is_some()
            || self.compare_requested;
        ctx.request_repaint_after(Duration::from_millis(if busy { 50 } else { 500 }));
    }
}
