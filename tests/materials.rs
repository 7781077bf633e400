//! glTF's metallic-roughness materials as strahl reads them, on both backends: the
//! metallic-roughness texture, vertex colours, shading normals (glTF `NORMAL`, OBJ `vn`) and
//! normal maps in glTF's tangent frame, a second set of texture coordinates,
//! `KHR_texture_transform`, `KHR_materials_unlit`; and GPU = CPU on all of it together. The
//! tests write their own small files: a 2 × 2 quad in the file's z = 0 plane facing +z, seen by
//! a camera 3 away on +z (as in `tests/assets.rs`).

mod common;

use common::{cpu_path_image, gpu, gpu_path_image, png};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use strahl_core::image::Image;
use strahl_core::render::Prepared;
use strahl_core::scene::{RenderMode, Scene};
use strahl_cpu as cpu;
use strahl_gpu::{GpuContext, SceneBuffers, render};

/// One primitive's vertex data; the quad's unless changed.
#[derive(Clone)]
struct Mesh {
    positions: Vec<[f32; 3]>,
    normals: Option<Vec<[f32; 3]>>,
    uv0: Option<Vec<[f32; 2]>>,
    uv1: Option<Vec<[f32; 2]>>,
    colors: Option<Vec<[f32; 4]>>,
    indices: Vec<u16>,
}

fn quad() -> Mesh {
    Mesh {
        positions: vec![[-1.0, 1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, -1.0, 0.0], [1.0, -1.0, 0.0]],
        normals: None,
        uv0: Some(vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]]),
        uv1: None,
        colors: None,
        indices: vec![2, 3, 1, 2, 1, 0],
    }
}

/// The four-quadrant texture of `tests/assets.rs`: red, green / blue, white.
const QUADRANTS: [[u8; 3]; 4] = [[200, 30, 30], [30, 200, 30], [30, 30, 200], [230, 230, 230]];

fn quadrants_png() -> Vec<u8> {
    png(64, 64, |x, y| QUADRANTS[(x >= 32) as usize + 2 * (y >= 32) as usize])
}

/// A glTF file of `mesh` with material `material` (JSON), the images `images` (PNG, as data
/// URIs; texture i uses image i with a nearest, repeating sampler), the file's camera, and a
/// directional light travelling along `light` (the file's axes, intensity π) or none.
fn write_gltf(
    dir: &Path,
    name: &str,
    mesh: &Mesh,
    material: &str,
    images: &[Vec<u8>],
    light: Option<[f32; 3]>,
) -> PathBuf {
    use base64::Engine;
    let b64 = |b: &[u8]| base64::engine::general_purpose::STANDARD.encode(b);
    let mut bin: Vec<u8> = Vec::new();
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    let mut attributes = Vec::new();
    let mut add = |bin: &mut Vec<u8>, bytes: Vec<u8>, count: usize, ty: &str, component: u32, extra: &str| {
        views.push(format!(r#"{{"buffer": 0, "byteOffset": {}, "byteLength": {}}}"#, bin.len(), bytes.len()));
        accessors.push(format!(
            r#"{{"bufferView": {}, "componentType": {component}, "count": {count}, "type": "{ty}"{extra}}}"#,
            views.len() - 1
        ));
        bin.extend(bytes);
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        accessors.len() - 1
    };
    let floats = |v: &[f32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    let n = mesh.positions.len();
    let flat3: Vec<f32> = mesh.positions.iter().flatten().copied().collect();
    let (lo, hi) = (0..3).fold((vec![], vec![]), |(mut lo, mut hi), k| {
        lo.push(mesh.positions.iter().map(|p| p[k]).fold(f32::INFINITY, f32::min));
        hi.push(mesh.positions.iter().map(|p| p[k]).fold(f32::NEG_INFINITY, f32::max));
        (lo, hi)
    });
    let p = add(&mut bin, floats(&flat3), n, "VEC3", 5126, &format!(r#", "min": {lo:?}, "max": {hi:?}"#));
    attributes.push(format!(r#""POSITION": {p}"#));
    if let Some(v) = &mesh.normals {
        let a = add(&mut bin, floats(&v.iter().flatten().copied().collect::<Vec<_>>()), n, "VEC3", 5126, "");
        attributes.push(format!(r#""NORMAL": {a}"#));
    }
    for (set, uv) in [(0, &mesh.uv0), (1, &mesh.uv1)] {
        if let Some(v) = uv {
            let a = add(&mut bin, floats(&v.iter().flatten().copied().collect::<Vec<_>>()), n, "VEC2", 5126, "");
            attributes.push(format!(r#""TEXCOORD_{set}": {a}"#));
        }
    }
    if let Some(v) = &mesh.colors {
        let a = add(&mut bin, floats(&v.iter().flatten().copied().collect::<Vec<_>>()), n, "VEC4", 5126, "");
        attributes.push(format!(r#""COLOR_0": {a}"#));
    }
    let idx: Vec<u8> = mesh.indices.iter().flat_map(|i| i.to_le_bytes()).collect();
    let indices = add(&mut bin, idx, mesh.indices.len(), "SCALAR", 5123, "");
    let mut nodes = vec![r#"{"mesh": 0}"#.to_string(), r#"{"camera": 0, "translation": [0, 0, 3]}"#.to_string()];
    let mut extensions = String::new();
    if let Some(d) = light {
        // A directional light shines along the node's −z: rotate −z onto d.
        let d = glam::Vec3::from(d).normalize();
        let q = glam::Quat::from_rotation_arc(glam::Vec3::NEG_Z, d);
        nodes.push(format!(
            r#"{{"rotation": [{}, {}, {}, {}], "extensions": {{"KHR_lights_punctual": {{"light": 0}}}}}}"#,
            q.x, q.y, q.z, q.w
        ));
        extensions = r#", "extensions": {"KHR_lights_punctual": {"lights": [{"type": "directional", "intensity": 3.14159265358979}]}}"#.into();
    }
    let roots: Vec<String> = (0..nodes.len()).map(|i| i.to_string()).collect();
    let textures: Vec<String> = (0..images.len()).map(|i| format!(r#"{{"source": {i}, "sampler": 0}}"#)).collect();
    let image_list: Vec<String> =
        images.iter().map(|b| format!(r#"{{"uri": "data:image/png;base64,{}"}}"#, b64(b))).collect();
    let json = format!(
        r#"{{
  "asset": {{"version": "2.0"}},
  "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_unlit", "KHR_texture_transform"],
  "scene": 0,
  "scenes": [{{"nodes": [{roots}]}}],
  "nodes": [{nodes}],
  "cameras": [{{"type": "perspective", "perspective": {{"yfov": 0.8, "aspectRatio": 1.0, "znear": 0.01}}}}],
  "meshes": [{{"primitives": [{{"attributes": {{{attributes}}}, "indices": {indices}, "material": 0}}]}}],
  "materials": [{material}],
  "textures": [{textures}],
  "samplers": [{{"magFilter": 9728, "wrapS": 10497, "wrapT": 10497}}],
  "images": [{image_list}],
  "buffers": [{{"uri": "data:application/octet-stream;base64,{data}", "byteLength": {len}}}],
  "bufferViews": [{views}],
  "accessors": [{accessors}]{extensions}
}}"#,
        roots = roots.join(", "),
        nodes = nodes.join(", "),
        attributes = attributes.join(", "),
        textures = textures.join(", "),
        image_list = image_list.join(", "),
        data = b64(&bin),
        len = bin.len(),
        views = views.join(", "),
        accessors = accessors.join(", "),
    );
    let path = dir.join(name);
    std::fs::write(&path, json).unwrap();
    path
}

/// The file as a scene: its camera, lit by its light alone (no ambient term, black
/// background) or, without one, the white sky strahl gives it.
fn prepared(path: &Path) -> Arc<Prepared> {
    let mut scene = Scene::load(path).unwrap_or_else(|e| panic!("{e}"));
    scene.render.ambient = [0.0; 3];
    scene.render.background = [0.0; 3];
    Arc::new(Prepared::new(scene))
}

fn whitted(prep: &Prepared, size: u32) -> Image {
    cpu::render(&cpu::CpuScene::new(prep), &prep.frame(size, size), RenderMode::Whitted, &|_| {})
}

fn gpu_whitted(ctx: &GpuContext, prep: &Prepared, size: u32) -> Image {
    let buffers = SceneBuffers::upload(ctx, &prep.flat).unwrap();
    let (img, _) =
        render(ctx, &buffers, &prep.frame(size, size), RenderMode::Whitted, buffers.key, &|_, _| {}).unwrap();
    img
}

fn path(prep: &Arc<Prepared>, size: u32, spp: u32) -> Image {
    cpu_path_image(prep, prep.frame(size, size), spp)
}

/// The image's centre pixel.
fn centre(img: &Image) -> [f32; 3] {
    img.get(img.width / 2, img.height / 2)
}

/// The pixel at the centre of each quarter of the quad (top left, top right, bottom left,
/// bottom right as seen), as in `tests/assets.rs`.
fn quadrant_pixels(img: &Image) -> [[f32; 3]; 4] {
    let (w, h) = (img.width as f64, img.height as f64);
    let off = 0.5 / (3.0 * 0.4f64.tan());
    let at = |sx: f64, sy: f64| img.get(((0.5 + 0.5 * sx * off) * w) as u32, ((0.5 - 0.5 * sy * off) * h) as u32);
    [at(-1.0, 1.0), at(1.0, 1.0), at(-1.0, -1.0), at(1.0, -1.0)]
}

fn pixels(img: &Image) -> Vec<[f32; 3]> {
    (0..img.height).flat_map(|y| (0..img.width).map(move |x| img.get(x, y))).collect()
}

/// The image of `ctx`'s backend agrees with the CPU's.
fn assert_backends_agree(what: &str, cpu_img: &Image, gpu_img: &Image) {
    let a = strahl_metrics::agreement(cpu_img, gpu_img, 1);
    eprintln!("{what}: {a:?}");
    assert!(a.within_tolerance >= 0.99, "{what}: {a:?}");
}

/// A metallic-roughness texture multiplies the factors: blue the metalness, green the
/// roughness. Metal 1 × texel blue 0 renders exactly as metal 0, roughness 1 × green 128
/// exactly as roughness 128/255: the asset that leaves metallicFactor at its default of 1 is
/// not a mirror where its texture says dielectric.
#[test]
fn the_metallic_roughness_texture_scales_the_factors() {
    let dir = tempfile::tempdir().unwrap();
    let base = r#""baseColorFactor": [0.8, 0.5, 0.3, 1.0]"#;
    let textured = write_gltf(
        dir.path(),
        "textured.gltf",
        &quad(),
        &format!(
            r#"{{"pbrMetallicRoughness": {{{base}, "metallicFactor": 1.0, "roughnessFactor": 1.0, "metallicRoughnessTexture": {{"index": 0}}}}}}"#
        ),
        &[png(1, 1, |_, _| [0, 128, 0])],
        None,
    );
    let rough = 128.0f32 / 255.0;
    let plain = write_gltf(
        dir.path(),
        "plain.gltf",
        &quad(),
        &format!(r#"{{"pbrMetallicRoughness": {{{base}, "metallicFactor": 0.0, "roughnessFactor": {rough:?}}}}}"#),
        &[],
        None,
    );
    let mirror = write_gltf(
        dir.path(),
        "metal.gltf",
        &quad(),
        &format!(r#"{{"pbrMetallicRoughness": {{{base}, "metallicFactor": 1.0, "roughnessFactor": {rough:?}}}}}"#),
        &[],
        None,
    );
    let (a, b, m) = (prepared(&textured), prepared(&plain), prepared(&mirror));
    for mode in ["whitted", "path"] {
        let render = |p: &Arc<Prepared>| if mode == "whitted" { whitted(p, 24) } else { path(p, 24, 4) };
        let (ia, ib, im) = (render(&a), render(&b), render(&m));
        assert_eq!(pixels(&ia), pixels(&ib), "{mode}: the texture's metal 0 and roughness 128/255");
        assert_ne!(pixels(&ia), pixels(&im), "{mode}: a metal renders otherwise");
    }
}

/// Vertex colours multiply the base colour; an unlit material shows exactly that product
/// (8-bit codes of the colour: within half a code), on both backends.
#[test]
fn vertex_colours_multiply_the_base_colour() {
    let dir = tempfile::tempdir().unwrap();
    let mut mesh = quad();
    mesh.colors = Some(vec![[1.0, 0.5, 0.25, 1.0]; 4]);
    let file = write_gltf(
        dir.path(),
        "coloured.gltf",
        &mesh,
        r#"{"pbrMetallicRoughness": {"baseColorFactor": [0.5, 1.0, 1.0, 1.0]}, "extensions": {"KHR_materials_unlit": {}}}"#,
        &[],
        None,
    );
    let prep = prepared(&file);
    let want = [0.5, 0.5, 0.25];
    let ctx = gpu();
    let mut images = vec![("cpu whitted", whitted(&prep, 16)), ("cpu path", path(&prep, 16, 2))];
    if let Some(ctx) = &ctx {
        images.push(("gpu whitted", gpu_whitted(ctx, &prep, 16)));
    }
    for (what, img) in &images {
        let got = centre(img);
        for c in 0..3 {
            assert!((got[c] - want[c]).abs() < 0.5 / 255.0 + 1e-6, "{what}: {got:?} vs {want:?}");
        }
    }
}

/// Interpolated OBJ `vn` normals shade a flat quad as the surface they describe: under a
/// directional light of irradiance π a white diffuse surface whose normal leans 60° away from
/// the light shows cos 60° = ½; light from below the face reaches none of it, even where the
/// leaning normal faces it (no leak), on both backends.
#[test]
fn vertex_normals_shade_and_do_not_leak() {
    let dir = tempfile::tempdir().unwrap();
    // A quad in z = 0 facing −z (towards the camera), every vn leaning 60° towards +x.
    let (s, c) = (60f64.to_radians().sin(), 60f64.to_radians().cos());
    std::fs::write(
        dir.path().join("quad.obj"),
        format!("v -1 -1 0\nv -1 1 0\nv 1 1 0\nv 1 -1 0\nvn {s} 0 {}\nf 1//1 2//1 3//1\nf 1//1 3//1 4//1\n", -c),
    )
    .unwrap();
    let scene = |light: [f64; 3]| {
        let text = format!(
            "[camera]\neye = [0.0, 0.0, -3.0]\nlook_at = [0.0, 0.0, 0.0]\nup = [0.0, 1.0, 0.0]\nfov_y = 30.0\n\
             [image]\nwidth = 16\nheight = 16\n[render]\nambient = [0.0, 0.0, 0.0]\nbackground = [0.0, 0.0, 0.0]\n\
             [[materials]]\nname = \"white\"\ntype = \"diffuse\"\ncolor = [1.0, 1.0, 1.0]\n\
             [[objects]]\ntype = \"mesh\"\nfile = \"quad.obj\"\nmaterial = \"white\"\n\
             [[lights]]\ntype = \"directional\"\ndirection = {light:?}\nintensity = [3.14159265358979, 3.14159265358979, 3.14159265358979]\n"
        );
        let path = dir.path().join("scene.toml");
        std::fs::write(&path, text).unwrap();
        Arc::new(Prepared::new(Scene::load(&path).unwrap_or_else(|e| panic!("{e}"))))
    };
    let ctx = gpu();
    // Light along +z, onto the front face: the normal leans 60° from it.
    let lit = scene([0.0, 0.0, 1.0]);
    // Light arriving 10° below the face from the +x side: 40° from the leaning normal.
    let (s10, c10) = (10f64.to_radians().sin(), 10f64.to_radians().cos());
    let below = scene([-c10, 0.0, -s10]);
    for (prep, want) in [(&lit, 0.5f32), (&below, 0.0)] {
        let mut images = vec![whitted(prep, 16)];
        if let Some(ctx) = &ctx {
            images.push(gpu_whitted(ctx, prep, 16));
        }
        images.push(path(prep, 16, 1));
        for img in &images {
            let got = centre(img);
            assert!((got[0] - want).abs() < 2e-3, "{got:?}, want {want}");
        }
    }
}

/// A normal map tilts the shading normal in glTF's tangent frame: red along +u, green up the
/// image (−v), in the file's space, also after strahl mirrors it. A map leaning 30° towards
/// +u (+x) seen under light from the +x side is brighter than one leaning towards −u, by the
/// ratio of the cosines; green behaves so under light from above; a flat map changes nothing
/// (within its 8-bit codes).
#[test]
fn normal_maps_follow_gltfs_tangent_frame() {
    let dir = tempfile::tempdir().unwrap();
    let material =
        r#"{"pbrMetallicRoughness": {"metallicFactor": 0.0, "roughnessFactor": 1.0}, "normalTexture": {"index": 0}}"#;
    let code = |v: f32| ((v + 1.0) * 0.5 * 255.0).round() as u8;
    let (s, c) = (0.5f32, 0.75f32.sqrt());
    let brightness = |texel: [u8; 3], light: [f32; 3], name: &str| {
        let file = write_gltf(dir.path(), name, &quad(), material, &[png(1, 1, |_, _| texel)], Some(light));
        centre(&whitted(&prepared(&file), 16))[1]
    };
    let decode = |k: u8| 2.0 * k as f32 / 255.0 - 1.0;
    for (axis, light) in [(0usize, [-1.0f32, 0.0, -1.0]), (1, [0.0, -1.0, -1.0])] {
        let mut towards = [128u8, 128, code(c)];
        let mut away = towards;
        towards[axis] = code(s);
        away[axis] = code(-s);
        let t = brightness(towards, light, "towards.gltf");
        let a = brightness(away, light, "away.gltf");
        let l = std::f32::consts::FRAC_1_SQRT_2;
        let cos = |k: [u8; 3]| {
            (decode(k[axis]) * l + decode(k[2]) * l) / (decode(k[axis]).powi(2) + decode(k[2]).powi(2)).sqrt()
        };
        let want = cos(towards) / cos(away);
        assert!(t > a, "axis {axis}: leaning towards the light {t} must be brighter than away {a}");
        assert!((t / a / want - 1.0).abs() < 0.01, "axis {axis}: ratio {} vs cosines' {want}", t / a);
    }
    let flat = brightness([128, 128, 255], [-1.0, 0.0, -1.0], "flat.gltf");
    let file = write_gltf(
        dir.path(),
        "none.gltf",
        &quad(),
        r#"{"pbrMetallicRoughness": {"metallicFactor": 0.0, "roughnessFactor": 1.0}}"#,
        &[],
        Some([-1.0, 0.0, -1.0]),
    );
    let none = centre(&whitted(&prepared(&file), 16))[1];
    assert!((flat / none - 1.0).abs() < 0.01, "flat map {flat} vs none {none}");
}

/// A texture that reads `TEXCOORD_1` renders as the same texture through `TEXCOORD_0` when the
/// two sets are swapped; `KHR_texture_transform`'s offset moves the image (half a repeat
/// swaps the quadrants left for right) and its scale stretches it.
#[test]
fn second_texture_coordinates_and_transforms_read_where_they_say() {
    let dir = tempfile::tempdir().unwrap();
    let unlit = |tex: &str| {
        format!(
            r#"{{"pbrMetallicRoughness": {{"baseColorTexture": {tex}}}, "extensions": {{"KHR_materials_unlit": {{}}}}}}"#
        )
    };
    let image = [quadrants_png()];
    let reference = write_gltf(dir.path(), "ref.gltf", &quad(), &unlit(r#"{"index": 0}"#), &image, None);
    let mut swapped = quad();
    swapped.uv1 = swapped.uv0.take();
    swapped.uv0 = Some(vec![[0.9, 0.9]; 4]);
    let second = write_gltf(dir.path(), "uv1.gltf", &swapped, &unlit(r#"{"index": 0, "texCoord": 1}"#), &image, None);
    let shifted = write_gltf(
        dir.path(),
        "offset.gltf",
        &quad(),
        &unlit(r#"{"index": 0, "extensions": {"KHR_texture_transform": {"offset": [0.5, 0.0]}}}"#),
        &image,
        None,
    );
    let scaled = write_gltf(
        dir.path(),
        "scale.gltf",
        &quad(),
        &unlit(r#"{"index": 0, "extensions": {"KHR_texture_transform": {"scale": [0.5, 0.5]}}}"#),
        &image,
        None,
    );
    let linear = |k: usize| QUADRANTS[k].map(strahl_core::scene::texture::srgb_to_linear);
    let ctx = gpu();
    let render = |p: &Path| {
        let prep = prepared(p);
        let cpu_img = whitted(&prep, 48);
        if let Some(ctx) = &ctx {
            assert_backends_agree(&p.display().to_string(), &cpu_img, &gpu_whitted(ctx, &prep, 48));
        }
        cpu_img
    };
    // Texel values up to an ulp of the image's arithmetic.
    let same = |got: [[f32; 3]; 4], want: [[f32; 3]; 4], what: &str| {
        let ok = got.iter().flatten().zip(want.iter().flatten()).all(|(g, w)| (g - w).abs() <= 1e-6 * w.max(1e-3));
        assert!(ok, "{what}: {got:?} vs {want:?}");
    };
    let r = render(&reference);
    same(quadrant_pixels(&r), [0, 1, 2, 3].map(linear), "the reference shows the texture upright");
    assert_eq!(pixels(&render(&second)), pixels(&r), "TEXCOORD_1");
    same(quadrant_pixels(&render(&shifted)), [1, 0, 3, 2].map(linear), "offset by half");
    // Scale ½: the quad shows the texture's top-left quarter, red in every quadrant.
    same(quadrant_pixels(&render(&scaled)), [0, 0, 0, 0].map(linear), "scaled by a half");
}

/// Everything at once on both backends: a pbr material with base colour, metallic-roughness
/// and normal textures (one through TEXCOORD_1, one transformed), vertex normals and colours,
/// blending by the vertex alpha, under a sky and a light, Whitted and path traced: GPU = CPU.
#[test]
fn every_material_path_agrees_on_both_backends() {
    let Some(ctx) = gpu() else { return };
    let ctx = Arc::new(ctx);
    let dir = tempfile::tempdir().unwrap();
    // A bent quad: two triangles meeting at a fold along x = 0, normals interpolated across.
    let mut mesh = quad();
    mesh.positions =
        vec![[-1.0, 1.0, 0.4], [1.0, 1.0, 0.4], [-1.0, -1.0, 0.4], [1.0, -1.0, 0.4], [0.0, 1.0, 0.0], [0.0, -1.0, 0.0]];
    mesh.uv0 = Some(vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [0.5, 0.0], [0.5, 1.0]]);
    mesh.uv1 = Some(vec![[0.0, 1.0], [1.0, 1.0], [0.0, 0.0], [1.0, 0.0], [0.5, 1.0], [0.5, 0.0]]);
    let h = 0.5f32.sqrt();
    mesh.normals = Some(vec![[-h, 0.0, h], [h, 0.0, h], [-h, 0.0, h], [h, 0.0, h], [0.0, 0.0, 1.0], [0.0, 0.0, 1.0]]);
    // Vertex alpha from 0.3 to 1: the material blends by it.
    mesh.colors = Some(vec![
        [1.0, 0.8, 0.6, 1.0],
        [0.6, 1.0, 0.8, 0.5],
        [0.8, 0.6, 1.0, 0.8],
        [1.0, 1.0, 1.0, 0.3],
        [0.9, 0.9, 0.9, 0.9],
        [0.7, 0.7, 0.7, 0.6],
    ]);
    mesh.indices = vec![2, 5, 4, 2, 4, 0, 5, 3, 1, 5, 1, 4];
    let material = r#"{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0, "extensions": {"KHR_texture_transform": {"offset": [0.1, 0.2], "rotation": 0.3, "scale": [1.5, 1.5]}}},
        "metallicFactor": 1.0, "roughnessFactor": 1.0, "metallicRoughnessTexture": {"index": 1, "texCoord": 1}},
        "normalTexture": {"index": 2, "scale": 0.8}, "emissiveFactor": [0.1, 0.05, 0.0], "alphaMode": "BLEND"}"#;
    let images = [
        quadrants_png(),
        png(8, 8, |x, y| [0, (x * 32) as u8, (y * 32) as u8]),
        png(8, 8, |x, y| [(96 + x * 8) as u8, (160 - y * 8) as u8, 230]),
    ];
    let file = write_gltf(dir.path(), "all.gltf", &mesh, material, &images, Some([0.3, -0.5, -1.0]));
    let mut scene = Scene::load(&file).unwrap_or_else(|e| panic!("{e}"));
    scene.environment = Some(strahl_core::scene::Environment::constant([0.3, 0.35, 0.4]));
    scene.render.ambient = [0.0; 3];
    let prep = Arc::new(Prepared::new(scene));
    assert!(!prep.flat.triangle_attrs.is_empty());
    let size = 40;
    assert_backends_agree("all, whitted", &whitted(&prep, size), &gpu_whitted(&ctx, &prep, size));
    let frame = prep.frame(size, size);
    let c = cpu_path_image(&prep, frame, 8);
    let g = gpu_path_image(&ctx, &prep, frame, 8);
    assert_backends_agree("all, path", &c, &g);
}

/// Alpha MASK: where the colour texture's alpha is under the cut-off rays pass (the sky shows
/// there), elsewhere the surface; a cut-off above the material's alpha makes all of it pass.
/// Alpha BLEND: Whitted blends the surface over what lies behind it by alpha exactly, path
/// tracing converges to the same (rays pass with probability 1 − alpha); both backends.
#[test]
fn alpha_masks_cut_and_blends_mix() {
    let dir = tempfile::tempdir().unwrap();
    // Left half transparent, right half opaque, as seen from the camera.
    let mut img = image::RgbaImage::new(2, 1);
    img.put_pixel(0, 0, image::Rgba([255, 255, 255, 0]));
    img.put_pixel(1, 0, image::Rgba([255, 255, 255, 255]));
    let mut cut = std::io::Cursor::new(Vec::new());
    img.write_to(&mut cut, image::ImageFormat::Png).unwrap();
    let colour = [0.2f32, 0.4, 0.6];
    let unlit = |rest: &str| {
        format!(
            r#"{{"pbrMetallicRoughness": {{"baseColorFactor": [0.2, 0.4, 0.6, {rest}}}, "extensions": {{"KHR_materials_unlit": {{}}}}"#
        )
    };
    let masked = write_gltf(
        dir.path(),
        "mask.gltf",
        &quad(),
        &format!(
            r#"{}, "alphaMode": "MASK", "alphaCutoff": 0.5}}"#,
            unlit(r#"1.0], "baseColorTexture": {"index": 0}"#)
        ),
        &[cut.into_inner()],
        None,
    );
    let all_pass = write_gltf(
        dir.path(),
        "pass.gltf",
        &quad(),
        &format!(r#"{}, "alphaMode": "MASK", "alphaCutoff": 0.5}}"#, unlit("0.4]")),
        &[],
        None,
    );
    let blend = write_gltf(
        dir.path(),
        "blend.gltf",
        &quad(),
        &format!(r#"{}, "alphaMode": "BLEND"}}"#, unlit("0.25]")),
        &[],
        None,
    );
    let ctx = gpu();
    let close = |got: [f32; 3], want: [f32; 3], tol: f32, what: &str| {
        assert!((0..3).all(|c| (got[c] - want[c]).abs() <= tol), "{what}: {got:?} vs {want:?}");
    };
    let sky = [1.0f32; 3];
    let p = prepared(&masked);
    let mut images = vec![("cpu whitted", whitted(&p, 48)), ("cpu path", path(&p, 48, 2))];
    if let Some(ctx) = &ctx {
        images.push(("gpu whitted", gpu_whitted(ctx, &p, 48)));
    }
    for (what, img) in &images {
        let q = quadrant_pixels(img);
        close(q[0], sky, 1e-5, &format!("{what}: the cut-out half shows the sky"));
        close(q[1], colour, 1e-5, &format!("{what}: the opaque half shows the surface"));
    }
    let p = prepared(&all_pass);
    close(centre(&whitted(&p, 16)), sky, 1e-5, "alpha 0.4 under the cut-off 0.5");
    let p = prepared(&blend);
    let want: [f32; 3] = [0, 1, 2].map(|c| 0.25 * colour[c] + 0.75);
    close(centre(&whitted(&p, 16)), want, 1e-5, "whitted blends by alpha");
    if let Some(ctx) = &ctx {
        close(centre(&gpu_whitted(ctx, &p, 16)), want, 1e-5, "gpu whitted blends by alpha");
    }
    // Path tracing: each sample shows the surface or the sky; the mean over the quad's centre
    // (16 × 16 pixels, 64 samples each) within 5 standard errors of the blend.
    let img = path(&p, 32, 64);
    let mut sum = 0.0f64;
    for y in 8..24 {
        for x in 8..24 {
            sum += img.get(x, y)[0] as f64;
        }
    }
    let mean = sum / 256.0;
    let sigma = (0.25f64 * 0.75 * (1.0 - 0.2f64).powi(2) / (256.0 * 64.0)).sqrt();
    assert!((mean - want[0] as f64).abs() < 5.0 * sigma, "path blend {mean} vs {} (σ {sigma})", want[0]);
}

/// A BLEND surface of alpha ¼ casts a shadow of ¾ of a directional light onto a white diffuse
/// plane behind it, in Whitted and path mode (whose shadow rays towards point and directional
/// lights see alpha), on both backends; outside the shadow the plane shows the full light.
#[test]
fn alpha_surfaces_cast_shadows_in_proportion() {
    let dir = tempfile::tempdir().unwrap();
    write_gltf(
        dir.path(),
        "veil.gltf",
        &quad(),
        r#"{"pbrMetallicRoughness": {"baseColorFactor": [0.0, 0.0, 0.0, 0.25]}, "alphaMode": "BLEND", "extensions": {"KHR_materials_unlit": {}}}"#,
        &[],
        None,
    );
    // The veil at z = 0 spans x in [-1, 1]; the plane at z = 1 faces the camera at z = -6; the
    // light travels along (1, 0, 2): the veil's shadow on the plane spans x in [-0.5, 1.5].
    let text = "[camera]\neye = [0.0, 0.0, -6.0]\nlook_at = [0.0, 0.0, 1.0]\nup = [0.0, 1.0, 0.0]\nfov_y = 40.0\n\
                [image]\nwidth = 70\nheight = 70\n[render]\nambient = [0.0, 0.0, 0.0]\nbackground = [0.0, 0.0, 0.0]\n\
                [[materials]]\nname = \"white\"\ntype = \"diffuse\"\ncolor = [1.0, 1.0, 1.0]\n\
                [[objects]]\ntype = \"gltf\"\nfile = \"veil.gltf\"\n\
                [[objects]]\ntype = \"plane\"\npoint = [0.0, 0.0, 1.0]\nnormal = [0.0, 0.0, -1.0]\nmaterial = \"white\"\n\
                [[lights]]\ntype = \"directional\"\ndirection = [1.0, 0.0, 2.0]\nintensity = [3.14159265358979, 3.14159265358979, 3.14159265358979]\n";
    let path_ = dir.path().join("shadow.toml");
    std::fs::write(&path_, text).unwrap();
    let prep = Arc::new(Prepared::new(Scene::load(&path_).unwrap_or_else(|e| panic!("{e}"))));
    // Pixels looking at the plane at x = 1.25 (in the shadow, beside the veil as seen) and at
    // x = 2 (lit): the ray through (x, 0, 1) from the eye, on a 70-pixel image of 40°.
    let column = |x: f64| {
        let half = (20f64.to_radians()).tan() * 7.0;
        ((0.5 + 0.5 * x / half) * 70.0) as u32
    };
    let cos = 2.0 / 5f32.sqrt();
    let ctx = gpu();
    let mut images = vec![("cpu whitted", whitted(&prep, 70)), ("cpu path", path(&prep, 70, 1))];
    if let Some(ctx) = &ctx {
        images.push(("gpu whitted", gpu_whitted(ctx, &prep, 70)));
        let ctx = Arc::new(gpu().unwrap());
        images.push(("gpu path", gpu_path_image(&ctx, &prep, prep.frame(70, 70), 1)));
    }
    for (what, img) in &images {
        let shadowed = img.get(column(1.25), 35)[0];
        let lit = img.get(column(2.0), 35)[0];
        assert!((lit - cos).abs() < 1e-4, "{what}: lit {lit} vs cos {cos}");
        assert!((shadowed - 0.75 * cos).abs() < 1e-4, "{what}: shadowed {shadowed} vs {}", 0.75 * cos);
    }
}

/// `KHR_materials_transmission`, `_ior` and `_volume` become a pbr material's glass share,
/// index and absorption (−ln(attenuationColor) / attenuationDistance per unit length), a
/// `thicknessFactor` of 0 is thin-walled (no absorption), and a `KHR_lights_punctual` spot
/// light keeps its cone, range and axis (mirrored into strahl's space as everything is).
#[test]
fn transmission_volume_and_spot_lights_are_read() {
    let dir = tempfile::tempdir().unwrap();
    let glass = r#"{"pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 1], "metallicFactor": 0, "roughnessFactor": 0.2},
        "extensions": {"KHR_materials_transmission": {"transmissionFactor": 0.7}, "KHR_materials_ior": {"ior": 1.4},
        "KHR_materials_volume": {"thicknessFactor": 1, "attenuationDistance": 2, "attenuationColor": [0.5, 1, 0.25]}}}"#;
    let d = [0.3f32, -1.0, 0.2];
    let path = write_gltf(dir.path(), "glass.gltf", &quad(), glass, &[], Some(d));
    let json = std::fs::read_to_string(&path).unwrap().replace(
        r#"{"type": "directional", "intensity": 3.14159265358979}"#,
        r#"{"type": "spot", "intensity": 5, "range": 7, "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.6}}"#,
    );
    std::fs::write(&path, json).unwrap();
    let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    let m = &scene.materials[0];
    assert_eq!(m.kind, strahl_core::scene::MaterialKind::Pbr);
    assert!((m.transmission - 0.7).abs() < 1e-6 && (m.ior - 1.4).abs() < 1e-6, "{m:?}");
    let want = [0.5f64, 1.0, 0.25].map(|c| -c.ln() / 2.0);
    for (got, want) in m.absorption.iter().zip(want) {
        assert!((got - want).abs() < 1e-6, "{:?} vs {want:?}", m.absorption);
    }
    let strahl_core::scene::Light::Spot { direction, intensity, inner, outer, range, .. } = scene.lights[0] else {
        panic!("{:?}", scene.lights[0])
    };
    let d = glam::DVec3::new(d[0] as f64, d[1] as f64, -(d[2] as f64)).normalize();
    assert!((glam::DVec3::from(direction.to_array()) - d).length() < 1e-5, "{direction:?} vs {d:?}");
    assert_eq!(intensity, [5.0; 3]);
    assert!((inner - 0.2).abs() < 1e-6 && (outer - 0.6).abs() < 1e-6 && (range - 7.0).abs() < 1e-6);
    // Thin-walled: no volume.
    let thin = glass.replace(r#""thicknessFactor": 1"#, r#""thicknessFactor": 0"#);
    let path = write_gltf(dir.path(), "thin.gltf", &quad(), &thin, &[], None);
    assert_eq!(Scene::load(&path).unwrap().materials[0].absorption, [0.0; 3]);
}

/// `KHR_materials_clearcoat`, `_sheen` and `_specular` become the pbr material's layers and
/// dielectric reflectance, their textures are named as not read, none of them is named as an
/// ignored extension any more, and a file may require them.
#[test]
fn clearcoat_sheen_and_specular_are_read() {
    let dir = tempfile::tempdir().unwrap();
    let layered = r#"{"pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1], "metallicFactor": 0, "roughnessFactor": 0.4},
        "extensions": {"KHR_materials_clearcoat": {"clearcoatFactor": 0.75, "clearcoatRoughnessFactor": 0.2, "clearcoatTexture": {"index": 0}},
        "KHR_materials_sheen": {"sheenColorFactor": [0.9, 0.4, 0.1], "sheenRoughnessFactor": 0.6},
        "KHR_materials_specular": {"specularFactor": 0.5, "specularColorFactor": [1, 0.5, 2]},
        "KHR_materials_ior": {"ior": 2.0}}}"#;
    let path = write_gltf(dir.path(), "layered.gltf", &quad(), layered, &[], None);
    let json = std::fs::read_to_string(&path).unwrap().replace(
        r#""KHR_texture_transform"]"#,
        r#""KHR_texture_transform", "KHR_materials_clearcoat", "KHR_materials_sheen", "KHR_materials_specular"],
            "extensionsRequired": ["KHR_materials_clearcoat", "KHR_materials_sheen"]"#,
    );
    std::fs::write(&path, json).unwrap();
    let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    let m = &scene.materials[0];
    assert!((m.clearcoat - 0.75).abs() < 1e-6 && (m.clearcoat_roughness - 0.2).abs() < 1e-6, "{m:?}");
    assert!((m.sheen_roughness - 0.6).abs() < 1e-6, "{m:?}");
    for (got, want) in m.sheen_color.iter().zip([0.9, 0.4, 0.1]) {
        assert!((got - want).abs() < 1e-6, "{m:?}");
    }
    assert!((m.specular - 0.5).abs() < 1e-6 && m.specular_color == [1.0, 0.5, 2.0], "{m:?}");
    let warnings = scene.warnings.join("\n");
    assert!(warnings.contains("KHR_materials_clearcoat.clearcoatTexture is not read"), "{warnings}");
    assert!(!warnings.contains("ignored"), "{warnings}");
    // F0 = ((2 − 1)/(2 + 1))² = 1/9, tinted (the blue channel's product clamped to 1 before the
    // factor) and scaled by 0.5; F90 = 0.5.
    let prep = strahl_core::render::Prepared::new(scene);
    let f = &prep.flat.materials[0];
    let f0 = 1.0f32 / 9.0;
    for (got, want) in f.spec_at_normal.iter().zip([f0 * 0.5, f0 * 0.25, f0 * 2.0 * 0.5]) {
        assert!((got - want).abs() < 1e-6, "{:?}", f.spec_at_normal);
    }
    assert_eq!(f.spec_at_grazing, 0.5);
}
