//! Real assets on both backends: glTF scenes (`.gltf` with embedded buffers and an external
//! image, `.glb`), image textures, environment lighting (constant and `.exr`/`.hdr` maps). The
//! tests write their own small files.

mod common;

use common::{cpu_path_image, gpu, gpu_path_image, mean_and_error};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use strahl_core::image::Image;
use strahl_core::render::Prepared;
use strahl_core::scene::texture::srgb_to_linear;
use strahl_core::scene::{EnvSampling, RenderMode, Scene};
use strahl_cpu as cpu;
use strahl_gpu::{GpuContext, SceneBuffers, render};

// ---------------------------------------------------------------------------------------
// Asset writers.

/// The test texture, 64 × 64 in four quadrants of 8-bit sRGB codes: top left red, top right
/// green, bottom left blue, bottom right white (as stored: row 0 at the top).
const QUADRANTS: [[u8; 3]; 4] = [[200, 30, 30], [30, 200, 30], [30, 30, 200], [230, 230, 230]];

fn checker_png() -> Vec<u8> {
    let img =
        image::RgbImage::from_fn(64, 64, |x, y| image::Rgb(QUADRANTS[(x >= 32) as usize + 2 * (y >= 32) as usize]));
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png).unwrap();
    out.into_inner()
}

/// A 2 × 2 quad in the z = 0 plane facing +z (counter-clockwise seen from +z), its texture
/// upright as seen from +z (glTF's uv (0, 0) is the image's top-left texel), a camera on +z
/// looking at it along −z (the file's camera, or `camera: false` for none) and, with `light`,
/// a directional light along −z of intensity π (a white diffuse surface facing it then has
/// radiance 1). Its material is unlit (`KHR_materials_unlit`): it shows exactly its texels,
/// lit or not. Positions, texture coordinates and indices as one binary buffer.
struct Quad {
    camera: bool,
    light: bool,
}

fn quad_buffer() -> Vec<u8> {
    let pos: [[f32; 3]; 4] = [[-1.0, 1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, -1.0, 0.0], [1.0, -1.0, 0.0]];
    let uv: [[f32; 2]; 4] = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]];
    // Bottom-left, bottom-right, top-right; bottom-left, top-right, top-left.
    let idx: [u16; 6] = [2, 3, 1, 2, 1, 0];
    let mut b = Vec::new();
    pos.iter().flatten().for_each(|v| b.extend(v.to_le_bytes()));
    uv.iter().flatten().for_each(|v| b.extend(v.to_le_bytes()));
    idx.iter().for_each(|v| b.extend(v.to_le_bytes()));
    b
}

impl Quad {
    /// The JSON; `buffer_uri`: the buffer's uri (None: the GLB chunk); `image`: the image's
    /// uri, else a buffer view of `png_len` bytes after the geometry.
    fn json(&self, buffer_uri: Option<&str>, image_uri: Option<&str>, png_len: usize) -> String {
        let geometry = quad_buffer().len();
        let total = geometry + if image_uri.is_none() { png_len } else { 0 };
        let uri = buffer_uri.map_or(String::new(), |u| format!(r#""uri": "{u}", "#));
        let (image, image_view) = match image_uri {
            Some(u) => (format!(r#"{{"uri": "{u}"}}"#), String::new()),
            None => (
                r#"{"bufferView": 3, "mimeType": "image/png"}"#.to_string(),
                format!(r#", {{"buffer": 0, "byteOffset": {geometry}, "byteLength": {png_len}}}"#),
            ),
        };
        let mut nodes = vec![r#"{"mesh": 0, "name": "quad"}"#.to_string()];
        let mut extensions = String::new();
        let mut used = r#", "extensionsUsed": ["KHR_materials_unlit"]"#.to_string();
        if self.camera {
            nodes.push(r#"{"camera": 0, "translation": [0, 0, 3]}"#.into());
        }
        if self.light {
            nodes.push(r#"{"extensions": {"KHR_lights_punctual": {"light": 0}}}"#.into());
            extensions = r#", "extensions": {"KHR_lights_punctual": {"lights": [{"type": "directional", "intensity": 3.14159265358979}]}}"#.into();
            used = r#", "extensionsUsed": ["KHR_materials_unlit", "KHR_lights_punctual"]"#.into();
        }
        let roots: Vec<String> = (0..nodes.len()).map(|i| i.to_string()).collect();
        format!(
            r#"{{
  "asset": {{"version": "2.0"}}{used},
  "scene": 0,
  "scenes": [{{"nodes": [{roots}]}}],
  "nodes": [{nodes}],
  "cameras": [{{"type": "perspective", "perspective": {{"yfov": 0.8, "aspectRatio": 1.0, "znear": 0.01}}}}],
  "meshes": [{{"name": "quad", "primitives": [{{"attributes": {{"POSITION": 0, "TEXCOORD_0": 1}}, "indices": 2, "material": 0}}]}}],
  "materials": [{{"name": "checker", "pbrMetallicRoughness": {{"baseColorTexture": {{"index": 0}}}}, "extensions": {{"KHR_materials_unlit": {{}}}}}}],
  "textures": [{{"source": 0, "sampler": 0}}],
  "samplers": [{{"magFilter": 9728, "wrapS": 33071, "wrapT": 33071}}],
  "images": [{image}],
  "buffers": [{{{uri}"byteLength": {total}}}],
  "bufferViews": [
    {{"buffer": 0, "byteOffset": 0, "byteLength": 48}},
    {{"buffer": 0, "byteOffset": 48, "byteLength": 32}},
    {{"buffer": 0, "byteOffset": 80, "byteLength": 12}}{image_view}
  ],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [-1, -1, 0], "max": [1, 1, 0]}},
    {{"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"}},
    {{"bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR"}}
  ]{extensions}
}}"#,
            roots = roots.join(", "),
            nodes = nodes.join(", "),
        )
    }

    /// `.gltf` with the buffer embedded as a base64 data: URI and the image in a file beside it.
    fn write_gltf(&self, dir: &Path) -> PathBuf {
        use base64::Engine;
        let data = base64::engine::general_purpose::STANDARD.encode(quad_buffer());
        std::fs::write(dir.join("checker.png"), checker_png()).unwrap();
        let json = self.json(Some(&format!("data:application/octet-stream;base64,{data}")), Some("checker.png"), 0);
        let path = dir.join("quad.gltf");
        std::fs::write(&path, json).unwrap();
        path
    }

    /// `.glb` with the geometry and the image in its binary chunk.
    fn write_glb(&self, dir: &Path) -> PathBuf {
        let png = checker_png();
        let mut bin = quad_buffer();
        bin.extend(&png);
        let path = dir.join("quad.glb");
        std::fs::write(&path, glb(&self.json(None, None, png.len()), &bin)).unwrap();
        path
    }
}

/// A GLB container of `json` and `bin`.
fn glb(json: &str, bin: &[u8]) -> Vec<u8> {
    let mut j = json.as_bytes().to_vec();
    while !j.len().is_multiple_of(4) {
        j.push(b' ');
    }
    let mut b = bin.to_vec();
    while !b.len().is_multiple_of(4) {
        b.push(0);
    }
    let total = 12 + 8 + j.len() + 8 + b.len();
    let mut out = Vec::new();
    out.extend(b"glTF");
    out.extend(2u32.to_le_bytes());
    out.extend((total as u32).to_le_bytes());
    out.extend((j.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(j);
    out.extend((b.len() as u32).to_le_bytes());
    out.extend(b"BIN\0");
    out.extend(b);
    out
}

// ---------------------------------------------------------------------------------------
// glTF scenes and textures.

fn whitted(prep: &Prepared, w: u32, h: u32) -> Image {
    let frame = prep.frame(w, h);
    cpu::render(&cpu::CpuScene::new(prep), &frame, RenderMode::Whitted, &|_| {})
}

fn gpu_whitted(ctx: &GpuContext, prep: &Prepared, w: u32, h: u32) -> Image {
    let frame = prep.frame(w, h);
    let buffers = SceneBuffers::upload(ctx, &prep.flat).unwrap();
    let (img, _) = render(ctx, &buffers, &frame, RenderMode::Whitted, buffers.key, &|_, _| {}).unwrap();
    img
}

/// The quad file lit only by its directional light (no ambient term), in Whitted mode.
fn quad_scene(path: &Path) -> Prepared {
    let mut scene = Scene::load(path).unwrap_or_else(|e| panic!("{e}"));
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    scene.render.mode = RenderMode::Whitted;
    scene.render.ambient = [0.0; 3];
    scene.render.background = [0.0; 3];
    Prepared::new(scene)
}

/// The pixel at the centre of each quarter of the quad's image: the camera (yfov 0.8 rad, 3
/// away) sees the quad's ±1 as ±1/(3 tan 0.4) of the half-height, so the quarter centres ±0.5
/// lie at ±0.3943 of it.
fn quadrant_pixels(img: &Image) -> [[f32; 3]; 4] {
    let (w, h) = (img.width as f64, img.height as f64);
    let off = 0.5 / (3.0 * 0.4f64.tan());
    let at = |sx: f64, sy: f64| {
        let x = ((0.5 + 0.5 * sx * off) * w) as u32;
        let y = ((0.5 - 0.5 * sy * off) * h) as u32;
        img.get(x, y)
    };
    [at(-1.0, 1.0), at(1.0, 1.0), at(-1.0, -1.0), at(1.0, -1.0)]
}

/// Texels land where the texture coordinates say, upright and not mirrored: the image shows the
/// texture's top-left quadrant (red) at the top left, as a glTF viewer does from the file's
/// camera, each quadrant with exactly its texel's linear value (the unlit material shows it).
fn check_quadrants(what: &str, img: &Image) {
    let got = quadrant_pixels(img);
    for (k, (g, code)) in got.iter().zip(QUADRANTS).enumerate() {
        let want = code.map(srgb_to_linear);
        for c in 0..3 {
            assert!((g[c] - want[c]).abs() < 1e-4, "{what}: quadrant {k}: got {g:?}, want {want:?} (codes {code:?})");
        }
    }
    // Outside the quad: the background (black here).
    assert_eq!(img.get(0, 0), [0.0; 3], "{what}: corner");
}

#[test]
fn gltf_and_glb_textures_land_where_the_uvs_say_on_both_backends() {
    let dir = tempfile::tempdir().unwrap();
    let quad = Quad { camera: true, light: true };
    let files = [quad.write_gltf(dir.path()), quad.write_glb(dir.path())];
    let ctx = gpu();
    for path in &files {
        let prep = quad_scene(path);
        assert_eq!(prep.scene.camera.eye.z, -3.0, "the camera at +z in the file is at -z in strahl's space");
        let cpu_img = whitted(&prep, 96, 96);
        check_quadrants(&format!("{} on the cpu", path.display()), &cpu_img);
        if let Some(ctx) = &ctx {
            let gpu_img = gpu_whitted(ctx, &prep, 96, 96);
            check_quadrants(&format!("{} on the gpu", path.display()), &gpu_img);
            let a = strahl_metrics::agreement(&cpu_img, &gpu_img, 1);
            assert!(a.within_tolerance >= 0.999, "{}: {a:?}", path.display());
        }
    }
}

/// Path tracing of the textured quad (diffuse, a directional light, bilinear filtering in the
/// `.glb` variant's clamped texture) on both backends: the same paths for the same samples.
#[test]
fn textured_path_traced_images_match_on_both_backends() {
    let Some(ctx) = gpu() else { return };
    let ctx = Arc::new(ctx);
    let dir = tempfile::tempdir().unwrap();
    let path = Quad { camera: true, light: true }.write_glb(dir.path());
    let mut scene = Scene::load(&path).unwrap();
    // Bilinear instead of nearest, and a constant sky as well: textures and environment.
    scene.textures[0].nearest = false;
    scene.environment = Some(strahl_core::scene::Environment::constant([0.2, 0.3, 0.4]));
    let prep = Arc::new(Prepared::new(scene));
    let frame = prep.frame(48, 48);
    let c = cpu_path_image(&prep, frame, 8);
    let g = gpu_path_image(&ctx, &prep, frame, 8);
    let a = strahl_metrics::agreement(&c, &g, 1);
    eprintln!("textured quad, path, 8 spp: {a:?}");
    assert!(a.within_tolerance >= 0.99, "{a:?}");
    assert!(a.mean_flip < 0.005, "{a:?}");
}

/// `strahl render model.glb -o out.png` with no scene file: the file's camera and light; and a
/// file with neither gets a camera that frames it and a white sky. `--camera 1` of a file with
/// one camera is an error naming the cameras there are.
#[test]
fn render_command_takes_a_glb_alone() {
    let dir = tempfile::tempdir().unwrap();
    let bin = env!("CARGO_BIN_EXE_strahl");
    let run = |args: &[&str]| std::process::Command::new(bin).args(args).output().unwrap();
    for (quad, name) in [(Quad { camera: true, light: true }, "lit"), (Quad { camera: false, light: false }, "bare")] {
        let sub = dir.path().join(name);
        std::fs::create_dir_all(&sub).unwrap();
        let glb = quad.write_glb(&sub);
        let out = sub.join("out.png");
        let o = run(&[
            "render",
            glb.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--backend",
            "cpu",
            "--spp",
            "4",
            "--width",
            "64",
            "--height",
            "64",
        ]);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{name}: {stderr}");
        let img = image::open(&out).unwrap().to_rgb8();
        // The quad's top-left quarter is red and its top-right green, in either framing.
        let centre = img.get_pixel(32, 32).0;
        let left = img.get_pixel(24, 24).0;
        let right = img.get_pixel(40, 24).0;
        assert!(left[0] > 2 * left[1] && right[1] > 2 * right[0], "{name}: {left:?} {right:?} (centre {centre:?})");
        if name == "bare" {
            assert!(stderr.contains("no perspective camera") && stderr.contains("white sky"), "{stderr}");
            // The sky is the background: radiance 1, white.
            assert_eq!(img.get_pixel(0, 0).0, [255, 255, 255]);
        }
    }
    let glb = dir.path().join("lit/quad.glb");
    let out = dir.path().join("x.png");
    let o = run(&["render", glb.to_str().unwrap(), "-o", out.to_str().unwrap(), "--camera", "1", "--backend", "cpu"]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("quad.glb: --camera 1: no perspective camera 1") && stderr.contains("placed: 0"),
        "{stderr}"
    );
}

/// A glTF object in a scene file, placed by translate and scale, next to a TOML material with
/// an image texture on an OBJ mesh with `vt`: both show their textures.
#[test]
fn gltf_objects_and_obj_textures_in_a_scene_file() {
    let dir = tempfile::tempdir().unwrap();
    Quad { camera: true, light: false }.write_glb(dir.path());
    std::fs::write(dir.path().join("checker.png"), checker_png()).unwrap();
    // An OBJ quad at x in [1, 3] with the texture upright (OBJ's v runs upwards).
    std::fs::write(
        dir.path().join("quad.obj"),
        "v 1 -1 0\nv 3 -1 0\nv 3 1 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n",
    )
    .unwrap();
    let toml = r#"
[camera]
eye = [0.0, 0.0, -6.0]
look_at = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
fov_y = 60.0
[image]
width = 120
height = 60
[render]
ambient = [0.0, 0.0, 0.0]
background = [0.0, 0.0, 0.0]
[[materials]]
name = "checker"
type = "diffuse"
color = [1.0, 1.0, 1.0]
texture = "checker.png"
[[objects]]
type = "gltf"
file = "quad.glb"
translate = [-2.0, 0.0, 0.0]
[[objects]]
type = "mesh"
file = "quad.obj"
material = "checker"
[[lights]]
type = "directional"
direction = [0.0, 0.0, 1.0]
intensity = [3.14159265, 3.14159265, 3.14159265]
"#;
    let path = dir.path().join("scene.toml");
    std::fs::write(&path, toml).unwrap();
    let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(scene.objects.len(), 2);
    assert_eq!(scene.textures.len(), 2, "the glTF's image and the TOML's");
    let prep = Prepared::new(scene);
    let img = whitted(&prep, 120, 60);
    // The camera at −z looks along +z: +x is on the right. The glTF quad spans x ∈ [−3, −1],
    // the OBJ quad x ∈ [1, 3]; both show red at their top left and white at their bottom right.
    let px = |x: f64, y: f64| {
        let half_h = (30f64.to_radians()).tan() * 6.0;
        let half_w = half_h * 2.0;
        img.get(((0.5 + 0.5 * x / half_w) * 120.0) as u32, ((0.5 - 0.5 * y / half_h) * 60.0) as u32)
    };
    let red = QUADRANTS[0].map(srgb_to_linear);
    let white = QUADRANTS[3].map(srgb_to_linear);
    for (x0, what) in [(-2.0, "glTF"), (2.0, "OBJ")] {
        let tl = px(x0 - 0.5, 0.5);
        let br = px(x0 + 0.5, -0.5);
        assert!((tl[0] - red[0]).abs() < 1e-3 && (tl[1] - red[1]).abs() < 1e-3, "{what}: top left {tl:?}");
        assert!((br[2] - white[2]).abs() < 1e-3, "{what}: bottom right {br:?}");
    }
}

/// An emitter with a uniform grey emission texture is the same light as an untextured one of
/// the texture's value times its radiance: path tracing gives the same image for the same random
/// numbers (one emitter, so both are sampled with the same density), on both backends. A diffuse
/// floor sees the emitter both through light samples and through BSDF samples: the MIS weight of
/// the latter must use the density the light was sampled with (by its untextured radiance), or
/// the two weights no longer sum to one and the image comes out brighter.
#[test]
fn a_textured_emitter_is_lit_like_its_untextured_twin() {
    let dir = tempfile::tempdir().unwrap();
    image::RgbImage::from_pixel(2, 2, image::Rgb([188, 188, 188])).save(dir.path().join("grey.png")).unwrap();
    std::fs::write(
        dir.path().join("panel.obj"),
        "v -1 1 -1\nv 1 1 -1\nv 1 1 1\nv -1 1 1\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n",
    )
    .unwrap();
    let grey = srgb_to_linear(188) as f64;
    let scene = |emission: &str| {
        let toml = format!(
            r#"
[camera]
eye = [0.0, 1.5, -3.0]
look_at = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
fov_y = 60.0
[image]
width = 16
height = 16
[render]
mode = "path"
max_depth = 3
background = [0.0, 0.0, 0.0]
[[materials]]
name = "floor"
type = "diffuse"
color = [0.8, 0.8, 0.8]
[[materials]]
name = "panel"
type = "emissive"
two_sided = true
{emission}
[[objects]]
type = "plane"
point = [0.0, 0.0, 0.0]
normal = [0.0, 1.0, 0.0]
material = "floor"
[[objects]]
type = "mesh"
file = "panel.obj"
material = "panel"
"#
        );
        let path = dir.path().join("emitter.toml");
        std::fs::write(&path, toml).unwrap();
        Arc::new(Prepared::new(Scene::load(&path).unwrap_or_else(|e| panic!("{e}"))))
    };
    let textured = scene("radiance = [4.0, 4.0, 4.0]\nradiance_texture = \"grey.png\"");
    let plain = scene(&format!("radiance = [{0}, {0}, {0}]", 4.0 * grey));
    // Each scene's own frame: it holds the emitters' normalisation.
    let (ft, fp) = (textured.frame(16, 16), plain.frame(16, 16));
    let mut images = vec![("cpu", cpu_path_image(&textured, ft, 16), cpu_path_image(&plain, fp, 16))];
    if let Some(ctx) = gpu().map(Arc::new) {
        images.push(("gpu", gpu_path_image(&ctx, &textured, ft, 16), gpu_path_image(&ctx, &plain, fp, 16)));
    }
    for (backend, a, b) in images {
        let (mut sum_a, mut worst) = (0.0f64, 0.0f64);
        for (p, q) in a.pixels.iter().zip(&b.pixels) {
            for c in 0..3 {
                sum_a += p[c] as f64;
                worst = worst.max((p[c] as f64 - q[c] as f64).abs() / (q[c] as f64).max(1e-3));
            }
        }
        assert!(sum_a > 0.0, "{backend}: the floor is lit");
        assert!(worst < 1e-4, "{backend}: textured and plain emitters differ by up to {worst:.2e} (relative)");
    }
}

/// The quad's JSON (camera and light) with its buffer and image as files beside it in `dir`,
/// which the JSON names: cases of a `.gltf` file are this text, changed.
fn write_quad_files(dir: &Path) -> String {
    std::fs::write(dir.join("checker.png"), checker_png()).unwrap();
    std::fs::write(dir.join("quad.bin"), quad_buffer()).unwrap();
    Quad { camera: true, light: true }.json(Some("quad.bin"), Some("checker.png"), 0)
}

/// Bad files: an error naming the file and the glTF path, never a panic.
#[test]
fn bad_gltf_files_name_the_file_and_the_path() {
    let dir = tempfile::tempdir().unwrap();
    let good = write_quad_files(dir.path());
    let cases: Vec<(&str, String, &str)> = vec![
        ("ok", good.clone(), ""),
        ("missing buffer", good.replace("quad.bin", "gone.bin"), "buffers[0].uri: \""),
        (
            "required extension",
            good.replace(r#""asset""#, r#""extensionsRequired": ["KHR_draco_mesh_compression"], "asset""#),
            "extensionsRequired[0]",
        ),
        ("broken JSON", good[..good.len() / 2].to_string(), "broken JSON"),
        (
            "accessor past its view",
            good.replace(r#""count": 4, "type": "VEC2""#, r#""count": 5, "type": "VEC2""#),
            "meshes[0].primitives[0].attributes.TEXCOORD_0 (accessors[1]): 5 elements",
        ),
        (
            "view past its buffer",
            good.replace(r#""byteOffset": 80, "byteLength": 12"#, r#""byteOffset": 80, "byteLength": 40"#),
            "bufferViews[2]: bytes 80..120 lie outside buffers[0]",
        ),
        (
            "no such mesh",
            good.replace(r#""mesh": 0, "name""#, r#""mesh": 7, "name""#),
            "nodes[0].mesh: index out of range",
        ),
        (
            "cycle",
            good.replace(r#""mesh": 0, "name": "quad""#, r#""mesh": 0, "name": "quad", "children": [0]"#),
            "cycle",
        ),
    ];
    for (what, json, expect) in cases {
        let path = dir.path().join("bad.gltf");
        std::fs::write(&path, &json).unwrap();
        let r = Scene::load(&path);
        if what == "ok" {
            r.unwrap_or_else(|e| panic!("{e}"));
            continue;
        }
        let e = r.err().unwrap_or_else(|| panic!("{what}: loaded")).to_string();
        assert!(e.starts_with(&path.display().to_string()), "{what}: {e}");
        assert!(e.contains(expect), "{what}: {e}");
    }
    // An index past the vertices, in a buffer of its own.
    let mut bin = quad_buffer();
    bin[80..82].copy_from_slice(&9u16.to_le_bytes());
    std::fs::write(dir.path().join("quad.bin"), &bin).unwrap();
    std::fs::write(dir.path().join("bad.gltf"), &good).unwrap();
    let e = Scene::load(dir.path().join("bad.gltf")).unwrap_err().to_string();
    assert!(e.contains("meshes[0].primitives[0].indices: index 9 at position 0 is out of range (4 vertices)"), "{e}");
    // In a scene file the error also names the object.
    let toml = "[camera]\neye = [0, 0, -5]\nlook_at = [0, 0, 0]\nup = [0, 1, 0]\nfov_y = 40\n[image]\nwidth = 8\nheight = 8\n\
                [[objects]]\ntype = \"gltf\"\nfile = \"bad.gltf\"\n";
    std::fs::write(dir.path().join("s.toml"), toml).unwrap();
    let e = Scene::load(dir.path().join("s.toml")).unwrap_err().to_string();
    assert!(e.contains("s.toml:11:8: objects[0].file: mesh ") && e.contains("indices: index 9"), "{e}");
    let toml = toml.replace("bad.gltf\"\n", "bad.gltf\"\nmaterial = \"x\"\n");
    std::fs::write(dir.path().join("s.toml"), toml).unwrap();
    let e = Scene::load(dir.path().join("s.toml")).unwrap_err().to_string();
    assert!(e.contains("objects[0].material: not a field of a gltf") && e.contains("its own materials"), "{e}");
}

/// What the specification allows and strahl's or the gltf crate's strict reading refused: an
/// accessor without `bufferView` (its values are zeros), a texture without `source` (an
/// extension gives the image: the material is untextured, with a warning), an unused buffer
/// without uri, and an animation channel without a node.
#[test]
fn gltf_files_the_specification_allows_load() {
    let dir = tempfile::tempdir().unwrap();
    let good = write_quad_files(dir.path());
    let load = |json: String| {
        let path = dir.path().join("allowed.gltf");
        std::fs::write(&path, json).unwrap();
        Scene::load(&path).unwrap_or_else(|e| panic!("{e}"))
    };
    let zeros = load(good.replace(
        r#"{"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"}"#,
        r#"{"componentType": 5126, "count": 4, "type": "VEC2"}"#,
    ));
    let uvs: Vec<_> = zeros
        .objects
        .iter()
        .flat_map(|o| match &o.geometry {
            strahl_core::scene::Geometry::Mesh { attrs, .. } => attrs.uvs.clone(),
            _ => Vec::new(),
        })
        .collect();
    assert!(!uvs.is_empty() && uvs.iter().flatten().all(|uv| uv.iter().all(|&c| c == 0.0)), "{uvs:?}");
    let sourceless =
        load(good.replace(r#""textures": [{"source": 0, "sampler": 0}]"#, r#""textures": [{"sampler": 0}]"#));
    assert!(sourceless.materials.iter().all(|m| m.color_texture.is_none()));
    assert!(sourceless.warnings.iter().any(|w| w.contains("textures[0] has no source")), "{:?}", sourceless.warnings);
    // An animation whose channel names no node (an extension would say what it animates),
    // which strahl does not read.
    let animation = r#""animations": [{"channels": [{"sampler": 0, "target": {"path": "translation"}}],
        "samplers": [{"input": 0, "output": 0}]}], "asset""#;
    assert!(!load(good.replace(r#""asset""#, animation)).objects.is_empty());
    // A buffer without uri (and no GLB chunk to be) is valid while nothing reads it.
    let unused = good.replace("}],\n  \"bufferViews\"", "}, {\"byteLength\": 16}],\n  \"bufferViews\"");
    assert_ne!(unused, good, "the buffers array moved: update this test");
    assert!(!load(unused.clone()).objects.is_empty());
    let path = dir.path().join("read.gltf");
    let read = unused.replace(
        r#"{"buffer": 0, "byteOffset": 80, "byteLength": 12}"#,
        r#"{"buffer": 1, "byteOffset": 0, "byteLength": 12}"#,
    );
    std::fs::write(&path, read).unwrap();
    let e = Scene::load(&path).unwrap_err().to_string();
    assert!(e.contains("bufferViews[2]: buffers[1]: has no uri"), "{e}");
    // So is one whose URI strahl does not read (a URL).
    let url = good.replace(
        "}],\n  \"bufferViews\"",
        "}, {\"uri\": \"http://example.invalid/b.bin\", \"byteLength\": 16}],\n  \"bufferViews\"",
    );
    assert!(!load(url).objects.is_empty());
    // Integers written as floats (the specification allows `1.0`), a scene without `nodes`
    // beside the one used, a required KHR_mesh_quantization (strahl reads integer attributes
    // anyway), a light type glTF does not define (skipped, with a warning), and a primitive
    // without POSITION (skipped, with a warning).
    let floats = good.replace(
        r#""bufferView": 2, "componentType": 5123, "count": 6"#,
        r#""bufferView": 2.0, "componentType": 5123.0, "count": 6e0"#,
    );
    assert_ne!(floats, good, "the index accessor moved: update this test");
    assert_eq!(load(floats).triangle_count(), 2);
    let scenes = good
        .replace(r#""scenes": [{"nodes""#, r#""scenes": [{"name": "empty"}, {"nodes""#)
        .replace(r#""scene": 0"#, r#""scene": 1"#);
    assert_ne!(scenes, good);
    assert_eq!(load(scenes).triangle_count(), 2);
    let quantized = good.replace(
        r#""asset""#,
        r#""extensionsUsed": ["KHR_mesh_quantization"], "extensionsRequired": ["KHR_mesh_quantization"], "asset""#,
    );
    assert_eq!(load(quantized).triangle_count(), 2);
    let spherical = good.replace(r#""type": "directional""#, r#""type": "spherical""#);
    assert_ne!(spherical, good);
    let s = load(spherical);
    assert!(s.lights.is_empty() && s.warnings.iter().any(|w| w.contains("light type")), "{:?}", s.warnings);
    let headless = good.replace(
        r#""primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2, "material": 0}]"#,
        r#""primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2, "material": 0}, {"attributes": {"TEXCOORD_0": 1}}]"#,
    );
    assert_ne!(headless, good);
    let s = load(headless);
    assert!(s.triangle_count() == 2 && s.warnings.iter().any(|w| w.contains("no POSITION")), "{:?}", s.warnings);
}

/// A GLB followed by bytes its header's length does not cover loads, with a warning; a length
/// shorter than the header is an error.
#[test]
fn glb_files_with_trailing_bytes_load() {
    let dir = tempfile::tempdir().unwrap();
    let mut bytes = std::fs::read(Quad { camera: true, light: true }.write_glb(dir.path())).unwrap();
    bytes.extend([0u8; 5]);
    let path = dir.path().join("trailing.glb");
    std::fs::write(&path, &bytes).unwrap();
    let s = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    assert!(s.warnings.iter().any(|w| w.contains("5 bytes after the GLB")), "{:?}", s.warnings);
    bytes[8..12].copy_from_slice(&4u32.to_le_bytes());
    std::fs::write(&path, &bytes).unwrap();
    let e = Scene::load(&path).unwrap_err().to_string();
    assert!(e.contains("length of 4 bytes"), "{e}");
}

/// Every prefix of a valid `.glb` and every byte of it replaced by a few others: an error or a
/// scene, never a panic.
#[test]
fn mangled_glb_files_never_panic() {
    let dir = tempfile::tempdir().unwrap();
    let good = std::fs::read(Quad { camera: true, light: true }.write_glb(dir.path())).unwrap();
    let path = dir.path().join("m.glb");
    let mut errors = 0;
    let mut check = |bytes: &[u8]| {
        std::fs::write(&path, bytes).unwrap();
        if let Err(e) = Scene::load(&path) {
            assert!(e.to_string().starts_with(&path.display().to_string()), "{e}");
            errors += 1;
        }
    };
    for end in (0..good.len()).step_by(7) {
        check(&good[..end]);
    }
    for i in 0..good.len() {
        for b in [0u8, 0xFF, b'9', b'"'] {
            let mut m = good.clone();
            m[i] = b;
            check(&m);
        }
    }
    assert!(errors > 100);
}

// ---------------------------------------------------------------------------------------
// Environment lighting.

/// A diffuse sphere of albedo 0.5 filling the middle of the view, under `[environment]`
/// `env` (TOML lines), path traced to at most 3 segments.
fn furnace_scene(dir: &Path, env: &str, mode: &str) -> Scene {
    let toml = format!(
        r#"
[camera]
eye = [0.0, 0.0, -4.0]
look_at = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
fov_y = 30.0
[image]
width = 24
height = 24
[render]
mode = "{mode}"
max_depth = 3
[[materials]]
name = "grey"
type = "diffuse"
color = [0.5, 0.5, 0.5]
[[objects]]
type = "sphere"
center = [0.0, 0.0, 0.0]
radius = 1.0
material = "grey"
[environment]
{env}
"#
    );
    let path = dir.join("furnace.toml");
    std::fs::write(&path, toml).unwrap();
    Scene::load(&path).unwrap_or_else(|e| panic!("{e}"))
}

/// The furnace's central pixels (well inside the sphere's outline, which spans ±0.98 of the
/// half-height): their channel means.
fn centre_values(img: &Image) -> Vec<f64> {
    let mut v = Vec::new();
    for y in 6..18 {
        for x in 6..18 {
            let p = img.get(x, y);
            v.push((p[0] as f64 + p[1] as f64 + p[2] as f64) / 3.0);
        }
    }
    v
}

/// Writes a constant map of radiance 1 as OpenEXR and as Radiance HDR.
fn constant_maps(dir: &Path) -> [&'static str; 2] {
    image::Rgb32FImage::from_fn(32, 16, |_, _| image::Rgb([1.0, 1.0, 1.0])).save(dir.join("one.exr")).unwrap();
    let hdr = image::Rgb32FImage::from_fn(32, 16, |_, _| image::Rgb([1.0, 1.0, 1.0]));
    let file = std::fs::File::create(dir.join("one.hdr")).unwrap();
    image::codecs::hdr::HdrEncoder::new(file)
        .encode(hdr.as_raw().chunks(3).map(|c| image::Rgb([c[0], c[1], c[2]])).collect::<Vec<_>>().as_slice(), 32, 16)
        .unwrap();
    ["file = \"one.exr\"", "file = \"one.hdr\""]
}

/// The environment furnace: a convex diffuse object of albedo ρ under a constant sky of
/// radiance 1 reflects ρ everywhere (one bounce; it never sees itself). Path tracing must give
/// ρ within its Monte Carlo error (computed from the pixels' spread) on both backends, for a
/// constant `radiance` and for maps read from `.exr` and `.hdr` files.
#[test]
fn environment_furnace_holds_on_both_backends() {
    let dir = tempfile::tempdir().unwrap();
    let [exr, hdr] = constant_maps(dir.path());
    let ctx = gpu().map(Arc::new);
    for env in ["radiance = [1.0, 1.0, 1.0]", exr, hdr] {
        let prep = Arc::new(Prepared::new(furnace_scene(dir.path(), env, "path")));
        let frame = prep.frame(24, 24);
        let mut images = vec![("cpu", cpu_path_image(&prep, frame, 64))];
        if let Some(ctx) = &ctx {
            images.push(("gpu", gpu_path_image(ctx, &prep, frame, 64)));
        }
        for (backend, img) in images {
            assert_eq!(img.non_finite_count(), 0);
            let (mean, se) = mean_and_error(&centre_values(&img));
            eprintln!("furnace, {env}, {backend}: {mean:.5} ± {se:.5} (expected 0.5)");
            assert!(se < 0.01, "{env}, {backend}: standard error {se} too large to test anything");
            assert!((mean - 0.5).abs() < 5.0 * se + 1e-4, "{env}, {backend}: {mean} ± {se}, expected 0.5");
            // The background is the sky itself.
            assert!((img.get(0, 0)[1] - 1.0).abs() < 1e-4, "{env}, {backend}: {:?}", img.get(0, 0));
        }
        // Whitted: the unshadowed diffuse light of a constant sky is exact.
        let whitted_prep = Prepared::new(furnace_scene(dir.path(), env, "whitted"));
        let mut images = vec![("cpu", whitted(&whitted_prep, 24, 24))];
        if let Some(ctx) = &ctx {
            images.push(("gpu", gpu_whitted(ctx, &whitted_prep, 24, 24)));
        }
        for (backend, img) in images {
            for v in centre_values(&img) {
                // Maps: the projection's quadrature over 32 × 16 texels is within 0.5 %.
                assert!((v - 0.5).abs() < 3e-3, "whitted, {env}, {backend}: {v}");
            }
        }
    }
}

/// Importance sampling a small bright sun in a map against sampling the sphere uniformly, at
/// equal samples per pixel: the RMSE against a 2048-spp reference must be several times
/// smaller.
#[test]
fn importance_sampling_a_sun_beats_uniform_sampling() {
    let dir = tempfile::tempdir().unwrap();
    // A dim sky (0.2) with a sun of 2 × 2 texels of radiance 4000, 40° above the horizon.
    let sun = |x: u32, y: u32| if (40..42).contains(&x) && (11..13).contains(&y) { 4000.0 } else { 0.2 };
    image::Rgb32FImage::from_fn(128, 64, |x, y| image::Rgb([sun(x, y); 3])).save(dir.path().join("sun.exr")).unwrap();
    let mut scene = furnace_scene(dir.path(), "file = \"sun.exr\"", "path");
    scene.render.max_depth = 2;
    let rmse = |a: &Image, b: &Image| {
        let se: f64 = a
            .pixels
            .iter()
            .zip(&b.pixels)
            .flat_map(|(p, q)| (0..3).map(move |c| (p[c] as f64 - q[c] as f64).powi(2)))
            .sum();
        (se / (3 * a.pixels.len()) as f64).sqrt()
    };
    let render = |sampling: EnvSampling, spp: u32, seed: u32| {
        let mut s = scene.clone();
        s.environment.as_mut().unwrap().sampling = sampling;
        let prep = Arc::new(Prepared::new(s));
        let mut frame = prep.frame(24, 24);
        frame.seed = seed;
        cpu_path_image(&prep, frame, spp)
    };
    let reference = render(EnvSampling::Importance, 2048, 99);
    let importance = render(EnvSampling::Importance, 16, 1);
    let uniform = render(EnvSampling::Uniform, 16, 1);
    let (ri, ru) = (rmse(&importance, &reference), rmse(&uniform, &reference));
    eprintln!("sun map, 16 spp: RMSE importance {ri:.4}, uniform {ru:.4} ({:.1}x)", ru / ri);
    assert!(ri * 4.0 < ru, "importance {ri} vs uniform {ru}");
    // Both converge to the same image: their means over the sphere agree.
    let mean = |img: &Image| centre_values(img).iter().sum::<f64>() / 144.0;
    let more_uniform = render(EnvSampling::Uniform, 2048, 7);
    let (a, b) = (mean(&more_uniform), mean(&reference));
    eprintln!("mean over the sphere at 2048 spp: uniform {a:.4}, importance {b:.4}");
    assert!((a - b).abs() < 0.15 * b, "uniform {a} vs importance {b}");
}
