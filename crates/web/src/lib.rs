//! strahl in a browser: the GPU renderer on WebGPU, for the page `tools/build-web` writes
//! (`www/`). This file is the JavaScript interface (wasm-bindgen); what it calls is in
//! [`session`], which the native tests run.
//!
//! From JavaScript (the page's `strahl.js` wraps it as `window.strahl`):
//!
//! ```js
//! const renderer = await Renderer.open();          // WebGPU's adapter and device
//! hold_file("meshes/bumpy_torus.obj", objBytes);  // the files the scene refers to
//! const scene = renderer.load("scenes/seed.toml", bytes); // TOML, .gltf or .glb; throws with strahl's message
//! release_files();
//! const frame = await renderer.render(scene, "path", 16, 640, 480, 0, undefined);
//! frame.width, frame.height, frame.rgba            // Uint8Array, sRGB as in strahl's PNG
//! const view = renderer.progressive(scene, 640, 480, 5);
//! view.add_samples(4); const rgba = await view.rgba();
//! const hits = await renderer.trace(scene, new Float64Array([0, 0, -10, 0, 0, 1, 0, Infinity]), false);
//! hits.ray_splits, hits.t, hits.object, hits.face, hits.primitive, hits.enter, hits.normal
//! ```
//!
//! A browser cannot wait for the GPU: every readback returns a Promise, and the blocking
//! forms of strahl-gpu are not called here.

pub mod session;

use session::{Loaded, Options, Request};
use std::cell::RefCell;
use std::rc::Rc;
use std::sync::Arc;
use strahl_core::render::view_camera::ViewCamera;
use strahl_core::scene::Camera;
use strahl_gpu::GpuContext;
use strahl_gpu::tiles::PathAccumulator;
use wasm_bindgen::prelude::*;

/// Panics (strahl's own asserts) reach the console with their message.
#[wasm_bindgen(start)]
pub fn start() {
    std::panic::set_hook(Box::new(|info| web_sys::console::error_1(&JsValue::from_str(&info.to_string()))));
}

/// Holds `bytes` as the file at `path` (relative to the page, as a scene file refers to it)
/// for the scenes loaded until [`release_files`]: a page has no file system, so the meshes,
/// buffers and images a scene names are handed over with it.
#[wasm_bindgen]
pub fn hold_file(path: &str, bytes: Vec<u8>) {
    strahl_core::input::hold_file(std::path::Path::new(path), bytes);
}

/// Lets go of every file [`hold_file`] held.
#[wasm_bindgen]
pub fn release_files() {
    strahl_core::input::release_files();
}

fn js(message: impl std::fmt::Display) -> JsValue {
    JsError::new(&message.to_string()).into()
}

/// The WebGPU device strahl renders on.
#[wasm_bindgen]
pub struct Renderer {
    ctx: Arc<GpuContext>,
}

#[wasm_bindgen]
impl Renderer {
    /// Opens the adapter and device WebGPU offers; fails where the browser has no WebGPU or
    /// the device binds fewer storage buffers than strahl needs.
    pub async fn open() -> Result<Renderer, JsValue> {
        // wgpu's web types are neither Send nor Sync; the Arc is for PathAccumulator, which
        // takes one (a page has one thread).
        #[allow(clippy::arc_with_non_send_sync)]
        let ctx = Arc::new(GpuContext::new_async().await.map_err(js)?);
        Ok(Renderer { ctx })
    }

    /// The adapter: name, backend, driver.
    #[wasm_bindgen(getter)]
    pub fn adapter(&self) -> String {
        self.ctx.adapter_name()
    }

    /// The device's storage buffers per shader stage and largest storage binding, in bytes.
    #[wasm_bindgen(getter)]
    pub fn limits(&self) -> String {
        let l = &self.ctx.limits;
        format!(
            "{} storage buffers per stage, {} MiB per binding",
            l.max_storage_buffers_per_shader_stage,
            self.ctx.max_binding_bytes() >> 20
        )
    }

    /// Loads the file `name` (by its extension: `.gltf`, `.glb`, else TOML) with contents
    /// `bytes`, prepares it and uploads it.
    pub fn load(&self, name: &str, bytes: &[u8]) -> Result<Scene, JsValue> {
        let loaded = Loaded::new(&self.ctx, name, bytes).map_err(js)?;
        let view = RefCell::new(ViewCamera::from_scene(&loaded.prep.scene.camera));
        Ok(Scene { loaded: Rc::new(loaded), view })
    }

    /// Renders `scene` as `strahl render --backend gpu` would with these options (each
    /// `undefined` for the scene's own): a Promise of a [`Frame`].
    #[allow(clippy::too_many_arguments)]
    pub fn render(
        &self,
        scene: &Scene,
        mode: Option<String>,
        spp: Option<f64>,
        width: Option<f64>,
        height: Option<f64>,
        seed: Option<f64>,
        max_depth: Option<f64>,
    ) -> js_sys::Promise {
        self.render_promise(scene, Options { mode, spp, width, height, seed, max_depth }, None)
    }

    /// [`Renderer::render`] in Whitted mode from the scene's moved camera ([`Scene::orbit`]
    /// and the others), as the view shows it.
    pub fn render_view(&self, scene: &Scene, width: f64, height: f64, max_depth: f64) -> js_sys::Promise {
        let options = Options {
            mode: Some("whitted".into()),
            width: Some(width),
            height: Some(height),
            max_depth: Some(max_depth),
            ..Default::default()
        };
        self.render_promise(scene, options, Some(scene.view.borrow().to_camera()))
    }

    /// Answers `rays` (a Float64Array, 8 numbers per ray: ox, oy, oz, dx, dy, dz, tmin, tmax)
    /// on `scene` as `strahl trace --backend gpu` does, every hit with `all`, else the
    /// nearest: a Promise of [`Hits`].
    pub fn trace(&self, scene: &Scene, rays: &[f64], all: bool) -> js_sys::Promise {
        let (ctx, loaded) = (self.ctx.clone(), scene.loaded.clone());
        let rays = session::rays(rays);
        wasm_bindgen_futures::future_to_promise(async move {
            let rays = rays.map_err(js)?;
            Ok(Hits(session::trace(&ctx, &loaded, &rays, all).await.map_err(js)?).into())
        })
    }

    /// A progressive path-traced view of `scene` from its moved camera at `width`×`height`.
    pub fn progressive(&self, scene: &Scene, width: u32, height: u32, max_depth: u32) -> Result<Progressive, JsValue> {
        let view = scene.view.borrow().to_camera();
        let acc = session::progressive(self.ctx.clone(), &scene.loaded, &view, width, height, max_depth).map_err(js)?;
        Ok(Progressive { acc: Rc::new(RefCell::new(acc)) })
    }
}

impl Renderer {
    /// A Promise of the [`Frame`] of `options` on `scene`, from `view` where given instead of
    /// the scene's camera.
    fn render_promise(&self, scene: &Scene, options: Options, view: Option<Camera>) -> js_sys::Promise {
        let (ctx, loaded) = (self.ctx.clone(), scene.loaded.clone());
        wasm_bindgen_futures::future_to_promise(async move {
            let request = Request::new(&loaded.prep.scene, &options).map_err(js)?;
            let image = session::render(&ctx, &loaded, &request, view.as_ref()).await.map_err(js)?;
            Ok(Frame { width: image.width, height: image.height, rgba: session::rgba8(&image) }.into())
        })
    }
}

/// A scene loaded on a [`Renderer`]'s device, and the camera the view moves over it (the
/// scene's at first; [`Renderer::render`] always takes the scene's own).
#[wasm_bindgen]
pub struct Scene {
    loaded: Rc<Loaded>,
    view: RefCell<ViewCamera>,
}

#[wasm_bindgen]
impl Scene {
    /// Turns the view's eye about its target as `strahl view`'s left drag does: `yaw` radians
    /// about the world up, `pitch` radians about the view's right axis.
    pub fn orbit(&self, yaw: f64, pitch: f64) {
        self.view.borrow_mut().orbit(yaw, pitch);
    }
    /// Slides the view by `dx`, `dy` pixels of a `height_px`-high image (the right drag).
    pub fn pan(&self, dx: f64, dy: f64, height_px: f64) {
        self.view.borrow_mut().pan(dx, dy, height_px);
    }
    /// Multiplies the eye's distance to the target by `factor` (the wheel).
    pub fn zoom(&self, factor: f64) {
        self.view.borrow_mut().zoom(factor);
    }
    /// The view's vertical field of view in degrees.
    #[wasm_bindgen(getter)]
    pub fn fov_y(&self) -> f64 {
        self.view.borrow().fov_y
    }
    #[wasm_bindgen(setter)]
    pub fn set_fov_y(&self, degrees: f64) {
        self.view.borrow_mut().fov_y = degrees.clamp(1.0, 170.0);
    }
    /// Back to the scene file's camera.
    pub fn reset_camera(&self) {
        *self.view.borrow_mut() = ViewCamera::from_scene(&self.loaded.prep.scene.camera);
    }
    #[wasm_bindgen(getter)]
    pub fn width(&self) -> u32 {
        self.loaded.prep.scene.image.width
    }
    #[wasm_bindgen(getter)]
    pub fn height(&self) -> u32 {
        self.loaded.prep.scene.image.height
    }
    /// "whitted" or "path".
    #[wasm_bindgen(getter)]
    pub fn mode(&self) -> String {
        self.loaded.prep.scene.render.mode.name().to_string()
    }
    #[wasm_bindgen(getter)]
    pub fn spp(&self) -> u32 {
        self.loaded.prep.scene.render.spp
    }
    #[wasm_bindgen(getter)]
    pub fn max_depth(&self) -> u32 {
        self.loaded.prep.scene.render.max_depth
    }
    #[wasm_bindgen(getter)]
    pub fn summary(&self) -> String {
        self.loaded.summary()
    }
    /// What was read but not used, one line each.
    #[wasm_bindgen(getter)]
    pub fn warnings(&self) -> Vec<String> {
        self.loaded.prep.scene.warnings.clone()
    }
}

/// A rendered image: `width`×`height` pixels of 8-bit sRGB RGBA.
#[wasm_bindgen]
pub struct Frame {
    width: u32,
    height: u32,
    rgba: Vec<u8>,
}

#[wasm_bindgen]
impl Frame {
    #[wasm_bindgen(getter)]
    pub fn width(&self) -> u32 {
        self.width
    }
    #[wasm_bindgen(getter)]
    pub fn height(&self) -> u32 {
        self.height
    }
    /// A copy of the pixels, row by row from the top.
    #[wasm_bindgen(getter)]
    pub fn rgba(&self) -> Vec<u8> {
        self.rgba.clone()
    }
}

/// The answers of a ray query as columns ([`session::Hits`]): ray `i`'s hits are entries
/// `ray_splits[i] .. ray_splits[i + 1]`, nearest first.
#[wasm_bindgen]
pub struct Hits(session::Hits);

#[wasm_bindgen]
impl Hits {
    #[wasm_bindgen(getter)]
    pub fn ray_splits(&self) -> Vec<u32> {
        self.0.ray_splits.clone()
    }
    #[wasm_bindgen(getter)]
    pub fn t(&self) -> Vec<f32> {
        self.0.t.clone()
    }
    #[wasm_bindgen(getter)]
    pub fn object(&self) -> Vec<u32> {
        self.0.object.clone()
    }
    #[wasm_bindgen(getter)]
    pub fn face(&self) -> Vec<u32> {
        self.0.face.clone()
    }
    #[wasm_bindgen(getter)]
    pub fn primitive(&self) -> Vec<u32> {
        self.0.primitive.clone()
    }
    #[wasm_bindgen(getter)]
    pub fn enter(&self) -> Vec<u8> {
        self.0.enter.clone()
    }
    /// Three numbers per hit.
    #[wasm_bindgen(getter)]
    pub fn normal(&self) -> Vec<f32> {
        self.0.normal.clone()
    }
}

/// Path tracing that adds samples on request; the mean so far can be read at any time.
#[wasm_bindgen]
pub struct Progressive {
    acc: Rc<RefCell<PathAccumulator>>,
}

#[wasm_bindgen]
impl Progressive {
    /// Submits `n` more sample passes (returns at once; the GPU works on them meanwhile).
    pub fn add_samples(&self, n: u32) -> Result<(), JsValue> {
        self.acc.borrow_mut().add_samples(n).map_err(js)
    }

    /// Samples per pixel submitted so far.
    #[wasm_bindgen(getter)]
    pub fn samples(&self) -> u32 {
        self.acc.borrow().samples()
    }

    /// Starts again from zero samples.
    pub fn reset(&self) -> Result<(), JsValue> {
        self.acc.borrow_mut().reset();
        Ok(())
    }

    /// A Promise of the mean of the samples submitted so far, as 8-bit sRGB RGBA (a
    /// Uint8Array).
    pub fn rgba(&self) -> js_sys::Promise {
        let read = self.acc.borrow().image_async();
        wasm_bindgen_futures::future_to_promise(async move {
            let image = read.await.map_err(js)?;
            Ok(js_sys::Uint8Array::from(session::rgba8(&image).as_slice()).into())
        })
    }
}
