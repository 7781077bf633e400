//! What the page asks of strahl, apart from the JavaScript glue (`lib.rs`): a scene loaded
//! from a file's bytes and uploaded, a render request checked field by field, and the image
//! as the bytes of strahl's PNG. Natively these run (and are tested) on any adapter; in a
//! browser on WebGPU.

use std::path::Path;
use std::sync::Arc;
use strahl_core::image::{Image, Region};
use strahl_core::layout::FrameParams;
use strahl_core::math::V3;
use strahl_core::query::{RayQuery, unit_direction};
use strahl_core::render::Prepared;
use strahl_core::scene::file::{MAX_DEPTH, MAX_IMAGE_PIXELS, MAX_IMAGE_SIDE, MAX_SPP};
use strahl_core::scene::{Camera, LoadOptions, RenderMode, Scene};
use strahl_gpu::tiles::{PathAccumulator, render_region_async};
use strahl_gpu::{GpuContext, SceneBuffers};

/// A scene prepared (flattened, its BVH built) and uploaded to the device.
pub struct Loaded {
    pub prep: Arc<Prepared>,
    pub buffers: SceneBuffers,
}

impl Loaded {
    /// The file `name` (its extension says what it is: `.gltf`/`.glb`, else TOML) with
    /// contents `bytes`. Errors name the file and where in it, as `strahl render`'s do.
    pub fn new(ctx: &GpuContext, name: &str, bytes: &[u8]) -> Result<Self, String> {
        let scene = Scene::from_bytes(Path::new(name), bytes, &LoadOptions::default()).map_err(|e| e.to_string())?;
        let prep = Prepared::try_new(scene).map_err(|e| e.to_string())?;
        let buffers = SceneBuffers::upload(ctx, &prep.flat).map_err(|e| e.to_string())?;
        Ok(Self { prep: Arc::new(prep), buffers })
    }

    /// One line on what was loaded, as `strahl render` prints it.
    pub fn summary(&self) -> String {
        let p = &self.prep;
        format!(
            "{} objects, {} triangles, BVH {} nodes; {}x{}, {} at {} spp",
            p.scene.objects.len(),
            p.prims.triangles.len(),
            p.bvh.nodes.len(),
            p.scene.image.width,
            p.scene.image.height,
            p.scene.render.mode.name(),
            p.scene.render.spp
        )
    }
}

/// A render as `strahl render FILE --mode --spp --width --height --seed --max-depth` asks for
/// it; what is not given is the scene's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Request {
    pub mode: RenderMode,
    pub spp: u32,
    pub width: u32,
    pub height: u32,
    pub seed: u32,
    pub max_depth: u32,
}

/// The fields of a request as a script passes them: JavaScript numbers, each maybe absent.
#[derive(Clone, Debug, Default)]
pub struct Options {
    pub mode: Option<String>,
    pub spp: Option<f64>,
    pub width: Option<f64>,
    pub height: Option<f64>,
    pub seed: Option<f64>,
    pub max_depth: Option<f64>,
}

/// `value`, the option `name`, as an integer in `range` (JavaScript has only doubles: 1.5,
/// −1, NaN and 2³² are errors here rather than wrapped or truncated into a u32).
fn integer(name: &str, value: f64, range: std::ops::RangeInclusive<i64>) -> Result<u32, String> {
    if value.fract() != 0.0 || !(*range.start() as f64..=*range.end() as f64).contains(&value) {
        return Err(format!("{name}: {value} is not an integer from {} to {}", range.start(), range.end()));
    }
    Ok(value as u32)
}

impl Request {
    /// `o` over the defaults of `scene`, every field checked against the limits the command
    /// line and scene files have.
    pub fn new(scene: &Scene, o: &Options) -> Result<Self, String> {
        let mode = match o.mode.as_deref() {
            None => scene.render.mode,
            Some("whitted") => RenderMode::Whitted,
            Some("path") => RenderMode::Path,
            Some(m) => return Err(format!("mode: {m:?} is not a render mode; use \"whitted\" or \"path\"")),
        };
        let side = 1..=MAX_IMAGE_SIDE;
        let width = o.width.map_or(Ok(scene.image.width), |v| integer("width", v, side.clone()))?;
        let height = o.height.map_or(Ok(scene.image.height), |v| integer("height", v, side))?;
        if width as u64 * height as u64 > MAX_IMAGE_PIXELS {
            return Err(format!("width, height: {width}x{height} is more than {MAX_IMAGE_PIXELS} pixels"));
        }
        Ok(Self {
            mode,
            width,
            height,
            spp: o.spp.map_or(Ok(scene.render.spp), |v| integer("spp", v, 1..=MAX_SPP))?,
            seed: o.seed.map_or(Ok(0), |v| integer("seed", v, 0..=u32::MAX as i64))?,
            max_depth: o.max_depth.map_or(Ok(scene.render.max_depth), |v| integer("max_depth", v, 0..=MAX_DEPTH))?,
        })
    }

    /// The frame parameters of this request on `prep`, seen from the scene's camera or from
    /// `view`, the page's moved one.
    pub fn frame(&self, prep: &Prepared, view: Option<&Camera>) -> FrameParams {
        let mut frame = match view {
            Some(c) => prep.frame_from(c, self.width, self.height),
            None => prep.frame(self.width, self.height),
        };
        frame.spp = self.spp;
        frame.seed = self.seed;
        frame.max_depth = self.max_depth;
        frame
    }
}

/// Renders `request` of `scene` on `ctx` as `strahl render --backend gpu` does (from `view`
/// where given instead of the scene's camera), without blocking.
pub async fn render(
    ctx: &GpuContext,
    scene: &Loaded,
    request: &Request,
    view: Option<&Camera>,
) -> Result<Image, String> {
    let frame = request.frame(&scene.prep, view);
    let region = Region::whole(request.width, request.height);
    let b = &scene.buffers;
    let (image, _) = render_region_async(ctx, b, &frame, request.mode, b.key, region, &|_, _| {})
        .await
        .map_err(|e| e.to_string())?;
    Ok(image)
}

/// A progressive path-traced view of `scene` from `view` at `width`×`height` (checked as a
/// request's).
pub fn progressive(
    ctx: Arc<GpuContext>,
    scene: &Loaded,
    view: &Camera,
    width: u32,
    height: u32,
    max_depth: u32,
) -> Result<PathAccumulator, String> {
    let o = Options {
        width: Some(width as f64),
        height: Some(height as f64),
        max_depth: Some(max_depth as f64),
        ..Default::default()
    };
    let request = Request::new(&scene.prep.scene, &o)?;
    PathAccumulator::new(ctx, scene.buffers.clone(), request.frame(&scene.prep, Some(view))).map_err(|e| e.to_string())
}

/// Rays as a script passes them: 8 numbers per ray in the columns of `strahl trace`'s CSV
/// (ox, oy, oz, dx, dy, dz, tmin, tmax), checked as the CSV's rows are; errors name the ray.
pub fn rays(values: &[f64]) -> Result<Vec<RayQuery>, String> {
    if !values.len().is_multiple_of(8) {
        return Err(format!(
            "rays: {} numbers, not a multiple of 8 (ox, oy, oz, dx, dy, dz, tmin, tmax)",
            values.len()
        ));
    }
    const NAMES: [&str; 8] = ["ox", "oy", "oz", "dx", "dy", "dz", "tmin", "tmax"];
    values
        .chunks(8)
        .enumerate()
        .map(|(i, v)| {
            if let Some(k) = (0..8).find(|&k| !(v[k].is_finite() || (k == 7 && v[k] == f64::INFINITY))) {
                return Err(format!("ray {i}: {} must be finite, got {}", NAMES[k], v[k]));
            }
            let dir = unit_direction(V3::new(v[3], v[4], v[5]))
                .ok_or_else(|| format!("ray {i}: dx,dy,dz: the direction must be non-zero"))?;
            if !(v[6] >= 0.0 && v[7] > v[6]) {
                return Err(format!("ray {i}: tmin,tmax: need 0 <= tmin < tmax, got {} and {}", v[6], v[7]));
            }
            Ok(RayQuery { origin: V3::new(v[0], v[1], v[2]), dir, tmin: v[6], tmax: v[7] })
        })
        .collect()
}

/// The answers of a ray query as columns: ray `i`'s hits are entries `ray_splits[i] ..
/// ray_splits[i + 1]` (nearest first), as `strahl trace` lists them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Hits {
    pub ray_splits: Vec<u32>,
    pub t: Vec<f32>,
    /// The object's index in the scene file.
    pub object: Vec<u32>,
    pub face: Vec<u32>,
    /// The primitive's reference in the flattened scene.
    pub primitive: Vec<u32>,
    /// 1 where the ray enters the surface (against its normal), else 0.
    pub enter: Vec<u8>,
    /// Three per hit: the unit normal facing the ray's side.
    pub normal: Vec<f32>,
}

/// Answers `rays` on `scene` as `strahl trace --backend gpu` does (every hit with `all`,
/// else the nearest), without blocking.
pub async fn trace(ctx: &GpuContext, scene: &Loaded, rays: &[RayQuery], all: bool) -> Result<Hits, String> {
    let answers = strahl_gpu::trace::trace_async(ctx, &scene.buffers, rays, all).await.map_err(|e| e.to_string())?;
    let mut h = Hits { ray_splits: vec![0], ..Default::default() };
    for hits in &answers {
        for x in hits {
            h.t.push(x.t);
            h.object.push(x.tag.object);
            h.face.push(x.tag.face);
            h.primitive.push(x.prim_ref.0);
            h.enter.push(x.enter as u8);
            h.normal.extend(x.normal.to_array());
        }
        h.ray_splits.push(h.t.len() as u32);
    }
    Ok(h)
}

/// `image` as 8-bit sRGB RGBA, the pixels of strahl's PNG (which is RGB) with alpha 255.
pub fn rgba8(image: &Image) -> Vec<u8> {
    image.to_srgb8().chunks(3).flat_map(|p| [p[0], p[1], p[2], 255]).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn seed_scene() -> (String, Scene) {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/scenes/seed.toml");
        let text = std::fs::read_to_string(&path).unwrap();
        // Named by its path, so that the mesh it names is found beside it.
        let scene = Scene::from_bytes(&path, text.as_bytes(), &LoadOptions::default()).unwrap();
        (text, scene)
    }

    #[test]
    fn a_request_takes_the_scene_defaults_and_checks_what_a_script_passes() {
        let (_, scene) = seed_scene();
        let r = Request::new(&scene, &Options::default()).unwrap();
        assert_eq!((r.mode, r.width, r.height, r.spp, r.seed), (scene.render.mode, 640, 480, scene.render.spp, 0));
        let o = Options { mode: Some("path".into()), spp: Some(4.0), width: Some(32.0), ..Default::default() };
        let r = Request::new(&scene, &o).unwrap();
        assert_eq!((r.mode, r.spp, r.width, r.height), (RenderMode::Path, 4, 32, 480));
        let bad = |o: Options, want: &str| {
            let e = Request::new(&scene, &o).unwrap_err();
            assert!(e.starts_with(want), "{e}");
        };
        bad(Options { mode: Some("raster".into()), ..Default::default() }, "mode: \"raster\" is not a render mode");
        bad(Options { spp: Some(0.0), ..Default::default() }, "spp: 0 is not an integer from 1 to 65536");
        bad(Options { spp: Some(1.5), ..Default::default() }, "spp: 1.5 is not");
        bad(Options { width: Some(f64::NAN), ..Default::default() }, "width: NaN is not");
        bad(Options { seed: Some(-1.0), ..Default::default() }, "seed: -1 is not");
        bad(Options { seed: Some(4294967296.0), ..Default::default() }, "seed: 4294967296 is not");
        bad(Options { max_depth: Some(65.0), ..Default::default() }, "max_depth: 65 is not");
        bad(
            Options { width: Some(16384.0), height: Some(16384.0), ..Default::default() },
            "width, height: 16384x16384",
        );
    }

    #[test]
    fn scene_files_load_from_bytes_with_their_errors_named() {
        let (text, scene) = seed_scene();
        assert_eq!(
            scene.objects.len(),
            Scene::load(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/scenes/seed.toml"))
                .unwrap()
                .objects
                .len()
        );
        let broken = text.replacen("radius = 5.0", "radius = \"five\"", 1);
        let e = Scene::from_bytes(Path::new("seed.toml"), broken.as_bytes(), &LoadOptions::default()).unwrap_err();
        assert!(e.to_string().starts_with("seed.toml:") && e.to_string().contains("radius"), "{e}");
        let e = Scene::from_bytes(Path::new("model.glb"), b"not a glb", &LoadOptions::default()).unwrap_err();
        assert!(e.to_string().contains("model.glb"), "{e}");
    }

    #[test]
    fn rays_are_checked_as_the_csv_rows_are() {
        let good = [0.0, 0.0, -10.0, 0.0, 0.0, 2.0, 0.0, f64::INFINITY];
        let r = rays(&good).unwrap();
        assert_eq!((r[0].dir.z, r[0].tmax), (1.0, f64::INFINITY));
        let bad = |v: &[f64], want: &str| {
            let e = rays(v).unwrap_err();
            assert!(e.starts_with(want), "{e}");
        };
        bad(&good[..7], "rays: 7 numbers, not a multiple of 8");
        let mut v = [good, good].concat();
        v[8 + 4] = f64::NAN;
        bad(&v, "ray 1: dy must be finite, got NaN");
        bad(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0], "ray 0: dx,dy,dz: the direction must be non-zero");
        bad(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 2.0, 1.0], "ray 0: tmin,tmax: need 0 <= tmin < tmax");
        bad(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, f64::INFINITY, 1.0], "ray 0: tmin must be finite");
    }

    #[test]
    fn rgba_is_the_png_pixels_with_opaque_alpha() {
        let mut img = Image::new(2, 1);
        img.pixels = vec![[0.0, 0.5, 1.0], [2.0, f32::NAN, 0.2]];
        let rgb = img.to_srgb8();
        assert_eq!(rgba8(&img), [rgb[0], rgb[1], rgb[2], 255, rgb[3], rgb[4], rgb[5], 255]);
    }
}
