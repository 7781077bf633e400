//! The CPU's lane path tracer (`lanes/`) against its reference, the one-path-at-a-time
//! tracer (`path.rs`): the same image bit for bit, with every lane set this processor
//! runs and each walk of the rays after the camera's (bundles, one ray at a time, measured),
//! on every shipped scene and on the golden scenes (area lights, glass, smooth and rough
//! mirrors, textures, an emissive texture, an environment map), and on sample counts and row
//! widths that leave batches and bundles part full.

use std::path::{Path, PathBuf};
use strahl_core::image::Region;
use strahl_core::render::Prepared;
use strahl_core::scene::{RenderMode, Scene};
use strahl_core::testutil::{png, shipped_scenes};
use strahl_cpu::accel::bundle::Isa;
use strahl_cpu::lanes::Walk;
use strahl_cpu::{self as cpu, PathTracer};

fn prepared(path: &Path) -> Prepared {
    Prepared::new(Scene::load(path).unwrap_or_else(|e| panic!("{}: {e}", path.display())))
}

/// Renders `prep` in `mode` at `w`×`h`, `spp` samples from sample `base`, with `tracer`; the
/// pixels' bits.
fn bits(prep: &Prepared, mode: RenderMode, w: u32, h: u32, spp: u32, base: u32, tracer: PathTracer) -> Vec<[u32; 3]> {
    let mut frame = prep.frame(w, h);
    frame.spp = spp;
    frame.sample_base = base;
    frame.seed = 7;
    let img = cpu::render_region_with(&cpu::CpuScene::new(prep), &frame, mode, Region::whole(w, h), tracer, &|_| {});
    img.pixels.iter().map(|p| p.map(f32::to_bits)).collect()
}

/// How many of the pixels `bits` are lit (some channel above 0).
fn lit(bits: &[[u32; 3]]) -> usize {
    bits.iter().filter(|p| p.iter().any(|&c| f32::from_bits(c) > 0.0)).count()
}

/// Every lane set gives the one-by-one image, bit for bit; returns the pixels compared.
fn check(name: &str, prep: &Prepared, w: u32, h: u32, spp: u32, base: u32) -> usize {
    let want = bits(prep, RenderMode::Path, w, h, spp, base, PathTracer::OneByOne);
    for isa in Isa::available() {
        for tracer in [
            PathTracer::Lanes(isa),
            PathTracer::LanesWalking(isa, Walk::Bundles),
            PathTracer::LanesWalking(isa, Walk::OneRay),
        ] {
            let got = bits(prep, RenderMode::Path, w, h, spp, base, tracer);
            let differ = want.iter().zip(&got).filter(|(a, b)| a != b).count();
            assert_eq!(differ, 0, "{name} ({w}x{h}, {spp} spp from {base}): {differ} pixels differ with {tracer:?}");
        }
    }
    // The image is not black: the comparison judged light transport.
    let n_lit = lit(&want);
    assert!(n_lit * 4 > want.len(), "{name}: only {n_lit} of {} pixels lit", want.len());
    want.len()
}

fn root() -> PathBuf {
    strahl_core::testutil::repo_root()
}

#[test]
fn lanes_equal_the_one_by_one_tracer_on_the_shipped_scenes() {
    let mut pixels = 0;
    for path in shipped_scenes() {
        let prep = prepared(&path);
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        // 37 columns: rows that fill no bundle evenly; 3 samples from sample 5.
        pixels += check(&name, &prep, 37, 23, 3, 5);
    }
    assert!(pixels > 5_000);
}

#[test]
fn lanes_equal_the_one_by_one_tracer_on_the_golden_scenes() {
    for (scene, spp) in [("cornell.toml", 9), ("textured.toml", 5)] {
        let prep = prepared(&root().join("tests/golden").join(scene));
        check(scene, &prep, 48, 36, spp, 0);
    }
    // More samples per pixel than a batch holds: a pixel's samples span batches.
    let seed = prepared(&root().join("assets/scenes/seed.toml"));
    check("seed.toml", &seed, 3, 2, 300, 0);
}

/// The progressive accumulation (`strahl converge`, the viewer's CPU side) adds the same
/// samples in the same order with either tracer: 2 then 3 samples, bit for bit.
#[test]
fn progressive_accumulations_are_equal() {
    let prep = std::sync::Arc::new(prepared(&root().join("tests/golden/cornell.toml")));
    let frame = prep.frame(29, 17);
    let run = |tracer| {
        let mut p = cpu::PathAccumulator::with_tracer(prep.clone(), frame, tracer);
        p.add_samples(2);
        p.add_samples(3);
        p.image().pixels.iter().map(|c| c.map(f32::to_bits)).collect::<Vec<_>>()
    };
    let want = run(PathTracer::OneByOne);
    for isa in Isa::available() {
        assert!(run(PathTracer::Lanes(isa)) == want, "{isa:?} lanes accumulate another image");
    }
}

/// A glTF scene in `dir` under the golden environment map: a glowing sphere of a
/// metallic-roughness material with a colour and a metallic-roughness texture (an area light
/// next-event estimation samples beside the map), on a ground of a rough dielectric
/// one whose texture mirrors and clamps, both with vertex normals (what the lanes shade), and
/// a small sphere whose texture is read nearest and which has a normal map (what they leave to
/// the one-path code). Returns the scene file.
fn pbr_scene(dir: &Path) -> PathBuf {
    use base64::Engine;
    let (mut pos, mut nrm, mut uv, mut prims) = (vec![], vec![], vec![], vec![]);
    // UV spheres: 24 × 12 quads of two triangles.
    let sphere = |c: [f32; 3], r: f32, pos: &mut Vec<f32>, nrm: &mut Vec<f32>, uv: &mut Vec<f32>| {
        let base = pos.len() as u32 / 3;
        let (nu, nv) = (24u32, 12u32);
        for j in 0..=nv {
            for i in 0..=nu {
                let (a, b) =
                    (2.0 * std::f32::consts::PI * i as f32 / nu as f32, std::f32::consts::PI * j as f32 / nv as f32);
                let n = [b.sin() * a.cos(), b.cos(), b.sin() * a.sin()];
                pos.extend((0..3).map(|k| c[k] + r * n[k]));
                nrm.extend(n);
                uv.extend([2.0 * i as f32 / nu as f32, j as f32 / nv as f32]);
            }
        }
        let mut idx = vec![];
        for j in 0..nv {
            for i in 0..nu {
                let a = base + j * (nu + 1) + i;
                let (b, c, d) = (a + 1, a + nu + 1, a + nu + 2);
                idx.extend([a, b, c, b, d, c]);
            }
        }
        idx
    };
    prims.push(sphere([0.0, 0.6, 0.0], 0.6, &mut pos, &mut nrm, &mut uv));
    prims.push(sphere([0.9, 0.25, -0.6], 0.25, &mut pos, &mut nrm, &mut uv));
    let base = pos.len() as u32 / 3;
    pos.extend([-3.0, 0.0, -3.0, 3.0, 0.0, -3.0, 3.0, 0.0, 3.0, -3.0, 0.0, 3.0]);
    nrm.extend([0.0, 1.0, 0.0].repeat(4));
    uv.extend([-1.5, -1.5, 2.5, -1.5, 2.5, 2.5, -1.5, 2.5]);
    prims.push(vec![base, base + 2, base + 1, base, base + 3, base + 2]);
    let mut bin: Vec<u8> = vec![];
    let (mut views, mut accessors) = (vec![], vec![]);
    let mut add = |bytes: Vec<u8>, count: usize, ty: &str, component: u32, extra: String| {
        views.push(format!(r#"{{"buffer": 0, "byteOffset": {}, "byteLength": {}}}"#, bin.len(), bytes.len()));
        accessors.push(format!(
            r#"{{"bufferView": {}, "componentType": {component}, "count": {count}, "type": "{ty}"{extra}}}"#,
            views.len() - 1
        ));
        bin.extend(bytes);
    };
    let bytes = |v: &[f32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    let n = pos.len() / 3;
    let lo: Vec<f32> = (0..3).map(|k| pos.iter().skip(k).step_by(3).copied().fold(f32::INFINITY, f32::min)).collect();
    let hi: Vec<f32> =
        (0..3).map(|k| pos.iter().skip(k).step_by(3).copied().fold(f32::NEG_INFINITY, f32::max)).collect();
    add(bytes(&pos), n, "VEC3", 5126, format!(r#", "min": {lo:?}, "max": {hi:?}"#));
    add(bytes(&nrm), n, "VEC3", 5126, String::new());
    add(bytes(&uv), n, "VEC2", 5126, String::new());
    for p in &prims {
        add(p.iter().flat_map(|i| i.to_le_bytes()).collect(), p.len(), "SCALAR", 5125, String::new());
    }
    let primitive = |k: usize| {
        format!(
            r#"{{"attributes": {{"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2}}, "indices": {}, "material": {k}}}"#,
            3 + k
        )
    };
    let images = [
        png(16, 16, |x, y| if (x / 4 + y / 4) % 2 == 0 { [220, 180, 40] } else { [40, 90, 200] }),
        png(8, 8, |x, y| [0, (40 + x * 25) as u8, (y * 36) as u8]),
        png(4, 4, |x, y| [(x * 60) as u8, 200, (y * 60) as u8]),
        png(4, 4, |x, y| [(100 + x * 20) as u8, (150 - y * 20) as u8, 230]),
    ];
    let b64 = |b: &[u8]| base64::engine::general_purpose::STANDARD.encode(b);
    let json = format!(
        r#"{{"asset": {{"version": "2.0"}}, "scene": 0, "scenes": [{{"nodes": [0]}}], "nodes": [{{"mesh": 0}}],
  "meshes": [{{"primitives": [{}, {}, {}]}}],
  "materials": [
    {{"pbrMetallicRoughness": {{"baseColorTexture": {{"index": 0}}, "metallicFactor": 0.8, "roughnessFactor": 0.7, "metallicRoughnessTexture": {{"index": 1}}}}, "emissiveFactor": [0.3, 0.2, 0.1]}},
    {{"pbrMetallicRoughness": {{"baseColorTexture": {{"index": 2}}, "roughnessFactor": 0.4}}, "normalTexture": {{"index": 3}}}},
    {{"pbrMetallicRoughness": {{"baseColorTexture": {{"index": 4}}, "baseColorFactor": [0.8, 0.8, 0.8, 1], "metallicFactor": 0.0, "roughnessFactor": 0.9}}}}
  ],
  "textures": [{{"source": 0, "sampler": 0}}, {{"source": 1, "sampler": 0}}, {{"source": 2, "sampler": 1}}, {{"source": 3, "sampler": 0}}, {{"source": 0, "sampler": 2}}],
  "samplers": [{{"wrapS": 10497, "wrapT": 10497}}, {{"magFilter": 9728}}, {{"wrapS": 33648, "wrapT": 33071}}],
  "images": [{}],
  "buffers": [{{"uri": "data:application/octet-stream;base64,{}", "byteLength": {}}}],
  "bufferViews": [{}], "accessors": [{}]}}"#,
        primitive(0),
        primitive(1),
        primitive(2),
        images
            .iter()
            .map(|i| format!(r#"{{"uri": "data:image/png;base64,{}"}}"#, b64(i)))
            .collect::<Vec<_>>()
            .join(", "),
        b64(&bin),
        bin.len(),
        views.join(", "),
        accessors.join(", "),
    );
    std::fs::write(dir.join("pbr.gltf"), json).unwrap();
    std::fs::copy(root().join("tests/golden/sky.exr"), dir.join("sky.exr")).unwrap();
    let toml = r#"
[camera]
eye = [0.3, 1.6, -3.0]
look_at = [0.0, 0.4, 0.0]
up = [0.0, 1.0, 0.0]
fov_y = 45.0
[image]
width = 40
height = 30
[render]
mode = "path"
max_depth = 6
[environment]
file = "sky.exr"
rotation = 40.0
[[objects]]
type = "gltf"
file = "pbr.gltf"
"#;
    std::fs::write(dir.join("pbr.toml"), toml).unwrap();
    dir.join("pbr.toml")
}

/// glTF's metallic-roughness material with colour and metallic-roughness textures and vertex
/// normals, under an environment map: the lanes shade it (and leave the nearest-filtered,
/// normal-mapped material to the one-path code), and the image is the one-path tracer's.
#[test]
fn lanes_equal_the_one_by_one_tracer_on_a_textured_gltf_under_a_map() {
    let dir = tempfile::tempdir().unwrap();
    let prep = prepared(&pbr_scene(dir.path()));
    let frame = prep.frame(40, 30);
    let facts = strahl_cpu::lanes::Facts::new(&prep.flat, frame.num_lights, None);
    let lanes: Vec<bool> = facts.materials.iter().map(Option::is_some).collect();
    // (After the file's three, the scene's default material.)
    assert_eq!(lanes[..3], [true, false, true], "which materials the lanes shade");
    assert!(frame.num_emitters > 0, "the glowing sphere is an area light");
    assert!(facts.lanes_ok && facts.rich && !prep.flat.environment.is_empty() && !prep.flat.triangle_attrs.is_empty());
    check("pbr.toml", &prep, 40, 30, 6, 3);
}

/// Whitted with the camera rays walked as bundles (`lanes/whitted.rs`) gives the image
/// of one ray tree at a time, bit for bit, with every lane set, on every shipped scene (point
/// and area lights, glass, mirrors), the golden scenes (textures, an environment map) and the
/// textured glTF; rows and sample counts that leave bundles part full.
#[test]
fn whitted_with_bundled_camera_rays_equals_one_ray_at_a_time() {
    let dir = tempfile::tempdir().unwrap();
    let mut scenes = shipped_scenes();
    scenes.extend(["cornell.toml", "textured.toml"].map(|s| root().join("tests/golden").join(s)));
    scenes.push(pbr_scene(dir.path()));
    let (mut pixels, mut lit_pixels) = (0, 0);
    for path in &scenes {
        let prep = prepared(path);
        let want = bits(&prep, RenderMode::Whitted, 37, 23, 3, 0, PathTracer::OneByOne);
        for isa in Isa::available() {
            let got = bits(&prep, RenderMode::Whitted, 37, 23, 3, 0, PathTracer::Lanes(isa));
            let differ = want.iter().zip(&got).filter(|(a, b)| a != b).count();
            assert_eq!(differ, 0, "{}: {differ} pixels differ with {isa:?}", path.display());
        }
        pixels += want.len();
        lit_pixels += lit(&want);
    }
    // The images are not black: the comparison judged the ray trees' light.
    assert!(lit_pixels * 2 > pixels, "only {lit_pixels} of {pixels} pixels lit");
}
