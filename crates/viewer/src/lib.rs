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

/// The camera the viewer moves (strahl-core's, shared with the web page).
pub use strahl_core::render::view_camera as camera;
mod compare;
pub mod gpu;
mod jobs;
mod pacing;
mod panel;
mod reload;
pub mod runtime_libs;
mod screenshot;

use anyhow::{Context as _, Result, anyhow};
use camera::ViewCamera;
use compare::{Comparison, ComparisonView};
use eframe::egui;
use eframe::egui_wgpu;
use gpu::{PresentParams, ViewMode, ViewRenderer};
use jobs::{Job, Watcher};
use pacing::Pacer;
use reload::Loaded;
use screenshot::Shot;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use strahl_core::layout::FrameParams;
use strahl_core::render::Prepared;
use strahl_gpu::{CachedPipeline, FeatureKey, GpuContext, Program, SceneBuffers};

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
    runtime_libs::check().map_err(|e| anyhow!(e))?;
    let prep = reload::load(&opts.scene).map_err(|e| anyhow!(e))?;
    eprintln!(
        "scene: {} objects, {} triangles, BVH {} nodes built in {:.3} s, prepared in {:.3} s",
        prep.scene.objects.len(),
        prep.prims.triangles.len(),
        prep.bvh.nodes.len(),
        prep.build_time.as_secs_f64(),
        prep.prepare_time.as_secs_f64()
    );
    let mut setup = egui_wgpu::WgpuSetupCreateNew::without_display_handle();
    // Vulkan unless WGPU_BACKEND says otherwise: lavapipe's GL adapter renders slightly
    // differently, and GL through a window is untested here. WGPU_ADAPTER_NAME and strahl's
    // ranking choose the adapter, as for every other subcommand.
    use strahl_gpu::instance;
    setup.instance_descriptor.backends = match std::env::var_os(instance::BACKEND_VAR) {
        Some(_) => instance::backends_from_env()?,
        None => wgpu::Backends::VULKAN,
    };
    setup.native_adapter_selector = Some(Arc::new(|adapters, surface| {
        let want = std::env::var(instance::ADAPTER_NAME_VAR).ok().map(|w| w.to_lowercase());
        let mut fit: Vec<&wgpu::Adapter> = adapters
            .iter()
            .filter(|a| surface.is_none_or(|s| a.is_surface_supported(s)))
            .filter(|a| want.as_ref().is_none_or(|w| a.get_info().name.to_lowercase().contains(w)))
            .collect();
        fit.sort_by_key(|a| instance::rank(&a.get_info(), &a.limits()));
        fit.first().map(|a| (*a).clone()).ok_or_else(|| match &want {
            Some(w) => {
                format!("{}={w}: no adapter that can draw to the window has it in its name", instance::ADAPTER_NAME_VAR)
            }
            None => "no adapter can draw to the window".to_string(),
        })
    }));
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

/// Compiling a pipeline on a worker thread (the error as text).
type CompileJob = Job<Result<(), String>>;

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
    accumulating: Option<(FrameParams, u64)>,
    present_dirty: bool,
    pacer: Pacer,
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
    /// UI frames run (--frames).
    frames_run: u32,
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
        let buffers = SceneBuffers::upload(&ctx, &prep.flat)?;
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
            pacer: Pacer::default(),
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

    /// Takes in a pipeline compiled on a worker thread, or its error.
    fn poll_compile(&mut self) {
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
    }

    /// The frame parameters of the current view at `w`×`h` (one sample per pass).
    fn frame(&self, w: u32, h: u32) -> FrameParams {
        let mut f = self.prep.frame_from(&self.camera.to_camera(), w, h);
        f.max_depth = self.max_depth;
        f.spp = 1;
        // The mode's flags, keeping the scene's (FRAME_ENVIRONMENT).
        f.flags = self.mode.flags() | (f.flags & strahl_core::layout::FRAME_ENVIRONMENT);
        f
    }

    /// Distances from the eye to the nearest and farthest point of the bounded geometry.
    fn depth_range(&self) -> (f32, f32) {
        use strahl_core::math::V3;
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
        let moving = self.pacer.camera_moving(&self.camera, Instant::now());
        let scale = if moving && !self.whole_passes() {
            let rays = pw as f64 * ph as f64 * (self.scale as f64).powi(2);
            self.scale / pacing::preview_factor(rays, pacing::timing_summary(self.gpu.timings.iter()).1)
        } else {
            self.scale
        };
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
        self.pacer.worked_last_frame = false;
        if self.gpu.target.is_some()
            && let Some(pipe) = self.pipeline()
        {
            let band = self.gpu.target.as_ref().expect("target").band();
            if self.gpu.acc.samples < self.max_samples {
                let budget = if self.whole_passes() {
                    band.tile_count() - self.gpu.acc.next_tile
                } else {
                    self.pacer.budget.round().max(1.0) as u32
                };
                let params = self.present_params();
                let n = self.gpu.step(&self.buffers, &pipe, &frame, budget, self.max_samples, params);
                self.pacer.worked_last_frame = n > 0;
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

    fn save(&mut self) {
        let path = PathBuf::from(self.save_path.trim());
        let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        let result: Result<()> = match ext.as_deref() {
            Some("png") => self.gpu.read_display().map_err(anyhow::Error::from).and_then(|img| {
                let rgb = image::DynamicImage::ImageRgba8(img).to_rgb8();
                strahl_core::image::save_encoded(&rgb, image::ImageFormat::Png, &path)
            }),
            Some("exr") => self.gpu.read_mean().map_err(anyhow::Error::from).and_then(|img| img.save(&path)),
            _ => Err(anyhow!("use a .png (what the window shows) or .exr (linear values) file name")),
        };
        self.save_status = Some(match result {
            Ok(()) => format!("saved {} ({} samples)", path.display(), self.gpu.acc.samples),
            Err(e) => format!("cannot save {}: {e:#}", path.display()),
        });
    }
}

impl eframe::App for Viewer {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        let ctx = ui.ctx().clone();
        self.pacer.frame_started(Instant::now(), self.gpu.timings.back());
        self.gpu.poll_timings();
        // The frames' work is submitted unscoped; what the device reported of it shows here.
        if let Err(e) = self.gpu.ctx.check() {
            self.gpu_error = Some(e.to_string());
        }
        self.poll_reload();
        self.poll_compile();
        self.poll_comparison(&ctx);
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
        if self.pacer.worked_last_frame || (self.gpu.acc.samples < self.max_samples && self.gpu_error.is_none()) {
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
