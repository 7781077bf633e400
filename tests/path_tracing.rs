//! The path tracer against analytic answers (white furnace) and the GPU against the CPU
//! reference, statistically: runs on lavapipe in CI.

mod common;

use common::gpu;
use std::path::Path;
use std::sync::Arc;
use strahl_core::image::{Image, Region};
use strahl_core::layout::FrameParams;
use strahl_core::render::Prepared;
use strahl_core::scene::{RenderMode, Scene, file::parse};
use strahl_cpu as cpu;
use strahl_gpu::{GpuContext, PathAccumulator, SceneBuffers};

fn scene(src: &str) -> Scene {
    parse(src, Path::new("test.toml"), Path::new(".")).unwrap_or_else(|e| panic!("{e}"))
}

/// The camera inside a closed sphere that reflects diffusely with albedo 0.8 and emits
/// radiance 1 from its inside: every path sees L = Σ_{k<D} 0.8^k for paths of at most D
/// segments, 5 (1 − 0.8^D), whichever direction it starts in.
fn furnace(max_depth: u32) -> (Prepared, f64) {
    let src = format!(
        r#"
[camera]
eye = [0.0, 0.0, 0.0]
look_at = [0.0, 0.0, 1.0]
up = [0.0, 1.0, 0.0]
fov_y = 90.0
[image]
width = 24
height = 16
[render]
mode = "path"
max_depth = {max_depth}
background = [0.0, 0.0, 0.0]
[[materials]]
name = "furnace"
type = "emissive"
color = [0.8, 0.8, 0.8]
radiance = [1.0, 1.0, 1.0]
two_sided = true
[[objects]]
type = "sphere"
center = [0.3, -0.2, 0.5]
radius = 3.0
material = "furnace"
"#
    );
    let expected = 5.0 * (1.0 - 0.8f64.powi(max_depth as i32));
    (Prepared::new(scene(&src)), expected)
}

/// Mean over pixels and channels, and its standard error from the spread of pixel means
/// (pixels are independent estimates).
fn mean_and_error(img: &Image) -> (f64, f64) {
    let v: Vec<f64> = img.pixels.iter().map(|p| (p[0] as f64 + p[1] as f64 + p[2] as f64) / 3.0).collect();
    common::mean_and_error(&v)
}

use common::{cpu_path_image as cpu_image, gpu_path_image as gpu_image};

fn check_furnace(what: &str, img: &Image, expected: f64) {
    assert_eq!(img.non_finite_count(), 0);
    let (mean, se) = mean_and_error(img);
    eprintln!("{what}: mean {mean:.5} ± {se:.5}, expected {expected:.5}");
    // The test has power: its standard error is far below the value it checks.
    assert!(se < 0.01 * expected, "{what}: standard error {se} too large to test anything");
    // 5 standard errors (a false alarm once in ~2 million runs), plus f32 accumulation slack.
    assert!((mean - expected).abs() < 5.0 * se + 1e-4 * expected, "{what}: {mean} ± {se}, expected {expected}");
}

#[test]
fn white_furnace_converges_to_the_analytic_value_on_the_cpu() {
    for (depth, spp) in [(2, 64), (5, 64), (64, 128)] {
        let (prep, expected) = furnace(depth);
        let prep = Arc::new(prep);
        let frame = prep.frame(prep.scene.image.width, prep.scene.image.height);
        check_furnace(&format!("cpu, max_depth {depth}"), &cpu_image(&prep, frame, spp), expected);
    }
}

#[test]
fn white_furnace_converges_to_the_analytic_value_on_the_gpu() {
    let Some(ctx) = gpu() else { return };
    let ctx = Arc::new(ctx);
    for (depth, spp) in [(2, 64), (5, 64), (64, 128)] {
        let (prep, expected) = furnace(depth);
        let frame = prep.frame(prep.scene.image.width, prep.scene.image.height);
        check_furnace(&format!("gpu, max_depth {depth}"), &gpu_image(&ctx, &prep, frame, spp), expected);
    }
}

/// Every material and light kind the path tracer has: diffuse, smooth and rough conductor,
/// glass, a one-sided emissive quad, an emissive sphere, an emissive cylinder (found only by
/// BSDF sampling), point and directional lights, a plane and a triangle mesh of a polygon.
const MIXED: &str = r#"
[camera]
eye = [0.0, 1.5, -7.0]
look_at = [0.0, 0.5, 0.0]
up = [0.0, 1.0, 0.0]
fov_y = 50.0
[image]
width = 48
height = 36
[render]
mode = "path"
max_depth = 6
background = [0.05, 0.06, 0.08]
[[materials]]
name = "white"
type = "diffuse"
color = [0.7, 0.7, 0.7]
[[materials]]
name = "red"
type = "diffuse"
color = [0.8, 0.2, 0.1]
[[materials]]
name = "chrome"
type = "mirror"
color = [0.9, 0.9, 0.9]
[[materials]]
name = "brushed"
type = "mirror"
color = [1.0, 0.8, 0.4]
roughness = 0.3
[[materials]]
name = "glass"
type = "dielectric"
ior = 1.5
[[materials]]
name = "panel"
type = "emissive"
radiance = [6.0, 6.0, 5.0]
[[materials]]
name = "bulb"
type = "emissive"
radiance = [3.0, 1.0, 0.5]
[[objects]]
type = "plane"
point = [0.0, -1.0, 0.0]
normal = [0.0, 1.0, 0.0]
material = "white"
[[objects]]
type = "sphere"
center = [-1.8, 0.0, 0.5]
radius = 1.0
material = "red"
[[objects]]
type = "sphere"
center = [0.4, 0.0, 1.0]
radius = 1.0
material = "brushed"
[[objects]]
type = "sphere"
center = [1.6, -0.4, -1.0]
radius = 0.6
material = "glass"
[[objects]]
type = "sphere"
center = [-0.5, -0.6, -1.5]
radius = 0.4
material = "chrome"
[[objects]]
type = "sphere"
center = [2.2, 1.8, 1.5]
radius = 0.3
material = "bulb"
[[objects]]
type = "cylinder"
p1 = [-3.0, -1.0, 3.0]
p2 = [-3.0, 2.0, 3.0]
radius = 0.2
caps = true
material = "bulb"
[[objects]]
type = "polygon"
vertices = [[-1.0, 3.5, -1.0], [1.0, 3.5, -1.0], [1.0, 3.5, 1.0], [-1.0, 3.5, 1.0]]
material = "panel"
[[lights]]
type = "point"
position = [3.0, 3.0, -3.0]
intensity = [4.0, 4.0, 4.0]
[[lights]]
type = "directional"
direction = [0.3, -1.0, 0.4]
intensity = [0.3, 0.3, 0.35]
"#;

#[test]
fn gpu_and_cpu_draw_the_same_paths_for_the_same_samples() {
    let Some(ctx) = gpu() else { return };
    let ctx = Arc::new(ctx);
    let prep = Arc::new(Prepared::new(scene(MIXED)));
    let frame = prep.frame(48, 36);
    let spp = 8;
    let c = cpu_image(&prep, frame, spp);
    let g = gpu_image(&ctx, &prep, frame, spp);
    // Same pixel, same sample index, same seed: the same random numbers, so the same paths.
    let frac = common::agreeing_fraction(&c, &g);
    eprintln!("pixels equal to 1e-3: {:.2} %", 100.0 * frac);
    assert!(frac > 0.95, "only {:.2} % of pixels agree", 100.0 * frac);
}

/// Independent renders (different seeds) of each backend: per region of the image and per
/// channel, the difference of the two backends' means is compared with the Monte Carlo error
/// estimated from the spread of B independent batches.
#[test]
fn gpu_and_cpu_images_agree_within_monte_carlo_error() {
    let Some(ctx) = gpu() else { return };
    let ctx = Arc::new(ctx);
    let prep = Arc::new(Prepared::new(scene(MIXED)));
    let (w, h) = (48u32, 36u32);
    const BATCHES: u32 = 6;
    const SPP: u32 = 4;
    const REGIONS: u32 = 4; // per side
    let region_means = |img: &Image| -> Vec<f64> {
        let mut sums = vec![0.0f64; (REGIONS * REGIONS * 3) as usize];
        for y in 0..h {
            for x in 0..w {
                let r = ((y * REGIONS / h) * REGIONS + x * REGIONS / w) as usize;
                for c in 0..3 {
                    sums[r * 3 + c] += img.get(x, y)[c] as f64;
                }
            }
        }
        let per = (w * h / (REGIONS * REGIONS)) as f64;
        sums.iter().map(|s| s / per).collect()
    };
    let stats = |gpu_side: bool| -> Vec<(f64, f64)> {
        let batches: Vec<Vec<f64>> = (0..BATCHES)
            .map(|b| {
                let mut frame = prep.frame(w, h);
                frame.seed = if gpu_side { 1000 + b } else { 2000 + b };
                let img = if gpu_side { gpu_image(&ctx, &prep, frame, SPP) } else { cpu_image(&prep, frame, SPP) };
                assert_eq!(img.non_finite_count(), 0);
                region_means(&img)
            })
            .collect();
        (0..batches[0].len())
            .map(|k| {
                let xs: Vec<f64> = batches.iter().map(|b| b[k]).collect();
                let m = xs.iter().sum::<f64>() / BATCHES as f64;
                let var = xs.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (BATCHES - 1) as f64;
                (m, (var / BATCHES as f64).sqrt())
            })
            .collect()
    };
    let g = stats(true);
    let c = stats(false);
    let mut worst = 0.0f64;
    let mut lit = 0;
    for (k, ((mg, sg), (mc, sc))) in g.iter().zip(&c).enumerate() {
        let se = (sg * sg + sc * sc).sqrt();
        // Regions that see only the background have no noise; they must agree to rounding.
        let z = (mg - mc).abs() / (se + 1e-5 * mc.abs().max(1e-3));
        worst = worst.max(z);
        lit += (*mc > 0.1) as usize;
        // With 6 batches the studentised difference has heavy tails (t with ~10 degrees of
        // freedom): 6 is beyond its 99.99th percentile over 48 comparisons.
        assert!(z < 6.0, "region {} channel {}: gpu {mg:.4} ± {sg:.4}, cpu {mc:.4} ± {sc:.4}", k / 3, k % 3);
    }
    eprintln!("largest |difference| / MC error over {} region channels: {worst:.2}", g.len());
    assert!(lit > g.len() / 2, "the test scene must be lit: {lit} of {} region channels", g.len());
}

#[test]
fn path_mode_renders_every_shipped_scene_without_non_finite_pixels_on_the_cpu() {
    for path in common::shipped_scenes() {
        let mut s = Scene::load(&path).unwrap();
        s.render.mode = RenderMode::Path;
        let prep = Arc::new(Prepared::new(s));
        let frame = prep.frame(40, 30);
        let img = cpu_image(&prep, frame, 2);
        assert_eq!(img.non_finite_count(), 0, "{}", path.display());
        assert!(img.pixels.iter().all(|p| p.iter().all(|&c| c >= 0.0)), "{}: negative radiance", path.display());
    }
}

/// Root mean square difference of two images' 8-bit sRGB codes, over all channels.
fn rms_codes(a: &Image, b: &Image) -> f64 {
    let (a, b) = (a.to_srgb8(), b.to_srgb8());
    let se: f64 = a.iter().zip(&b).map(|(x, y)| (*x as f64 - *y as f64).powi(2)).sum();
    (se / a.len() as f64).sqrt()
}

/// `plane.toml` (a point and a directional light over an infinite plane) at 64 spp with two
/// seeds: the noise, not just the mean, is small. Chosen by power with the area lights, the
/// directional light's power came from the bounded objects' cross-section (radius 1 beside an
/// infinite plane): drawn once in ~700 vertices and weighted ~700x, it covered the image in
/// white speckles (the two seeds differed by 32 codes rms; 0.9 with the point light alone).
#[test]
fn point_and_directional_lights_together_converge_without_fireflies() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes/plane.toml");
    let mut scene = Scene::load(&path).unwrap();
    scene.render.mode = RenderMode::Path;
    let prep = Arc::new(Prepared::new(scene));
    let ctx = gpu().map(Arc::new);
    for backend in ["cpu", "gpu"] {
        let image = |seed: u32| {
            let mut frame = prep.frame(160, 120);
            frame.seed = seed;
            match (backend, &ctx) {
                ("cpu", _) => Some(cpu_image(&prep, frame, 64)),
                (_, Some(ctx)) => Some(gpu_image(ctx, &prep, frame, 64)),
                _ => None,
            }
        };
        let (Some(a), Some(b)) = (image(0), image(1)) else { continue };
        let rms = rms_codes(&a, &b);
        eprintln!("{backend}: plane.toml, 64 spp, seeds 0 and 1 differ by {rms:.2} codes rms");
        assert!(rms <= 3.0, "{backend}: seeds differ by {rms:.2} codes rms");
        // Lit at all: the directional light reaches the plane (its mean is well above black).
        let mean = a.pixels.iter().map(|p| p[1] as f64).sum::<f64>() / a.pixels.len() as f64;
        assert!(mean > 0.05, "{backend}: mean {mean}");
    }
}

/// Direct light only (max_depth 2), no background and no ambient: the path tracer's mean is
/// Whitted's image (both sum f·cos·E over the lights with a shadow ray each), so evaluating
/// the point and directional lights at every vertex is unbiased.
#[test]
fn direct_light_from_point_and_directional_lights_equals_whitted() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes/plane.toml");
    let mut scene = Scene::load(&path).unwrap();
    scene.render.background = [0.0; 3];
    scene.render.ambient = [0.0; 3];
    scene.render.max_depth = 2;
    let prep = Arc::new(Prepared::new(scene));
    let mut frame = prep.frame(160, 120);
    let path_img = cpu_image(&prep, frame, 64);
    frame.spp = 64;
    let whitted = cpu::render(&cpu::CpuScene::new(&prep), &frame, RenderMode::Whitted, &|_| {});
    let rms = rms_codes(&path_img, &whitted);
    eprintln!("plane.toml, direct light, 64 spp: path and Whitted differ by {rms:.2} codes rms");
    assert!(rms < 1.0, "path and Whitted differ by {rms:.2} codes rms");
}

/// The wavefront path tracer computes what the megakernel computes, the same sums in the same
/// order: the same image, bit for bit, progressive and one-shot (several sample passes, paths
/// of every length up to max_depth), for a scene of every material kind and for one lit by an
/// environment map (sampled by next-event estimation beside a textured area light) with image
/// textures.
#[test]
fn wavefront_and_megakernel_render_the_same_image() {
    let Some(ctx) = gpu() else { return };
    let ctx = Arc::new(ctx);
    let dir = tempfile::tempdir().unwrap();
    for (what, scene) in [("mixed", scene(MIXED)), ("environment and textures", env_textured_scene(dir.path()))] {
        let prep = Prepared::new(scene);
        if what != "mixed" {
            assert!(
                !prep.flat.environment.is_empty()
                    && !prep.flat.triangle_attrs.is_empty()
                    && !prep.flat.emitters.is_empty()
            );
        }
        let frame = FrameParams { spp: 5, ..prep.frame(40, 30) };
        assert_wavefront_is_megakernel(&ctx, &prep, frame, what);
    }
}

fn assert_wavefront_is_megakernel(ctx: &Arc<GpuContext>, prep: &Prepared, frame: FrameParams, what: &str) {
    use strahl_gpu::{PathKernels, render_tiles, wavefront::Wavefront};
    let same = |how: &str, a: &Image, b: &Image| {
        assert_eq!(a.non_finite_count(), 0, "{what}, {how}");
        let differing = a.pixels.iter().zip(&b.pixels).filter(|(x, y)| x != y).count();
        assert_eq!(differing, 0, "{what}, {how}: {differing} of {} pixels differ", a.pixels.len());
        let lit = a.pixels.iter().filter(|p| p.iter().any(|&c| c > 0.0)).count();
        assert!(lit > a.pixels.len() / 2, "{what}, {how}: only {lit} pixels lit");
    };
    let buffers = SceneBuffers::upload(ctx, &prep.flat).unwrap();
    let mut wf = PathAccumulator::with_kernels(ctx.clone(), buffers.clone(), frame, PathKernels::Wavefront).unwrap();
    assert_eq!(wf.kernels(), PathKernels::Wavefront);
    wf.add_samples(2).unwrap();
    wf.add_samples(3).unwrap();
    let mut mega = PathAccumulator::with_kernels(ctx.clone(), buffers.clone(), frame, PathKernels::Megakernel).unwrap();
    mega.add_samples(5).unwrap();
    same("progressive", &wf.image().unwrap(), &mega.image().unwrap());
    let (one_shot, _) =
        Wavefront::new(ctx, buffers.clone(), buffers.key, frame).unwrap().render(ctx, &|_, _| {}).unwrap();
    let whole = Region::whole(frame.width, frame.height);
    let (reference, _) = render_tiles(ctx, &buffers, &frame, RenderMode::Path, buffers.key, whole, &|_, _| {}).unwrap();
    same("one-shot", &one_shot, &reference);
    // A part of a split render: the region's pixels of the whole render, from both tracers.
    let region = Region { x0: 7, y0: 3, x1: 33, y1: 29 };
    let crop = Image {
        width: region.width(),
        height: region.height(),
        pixels: (region.y0..region.y1)
            .flat_map(|y| (region.x0..region.x1).map(move |x| (x, y)))
            .map(|(x, y)| reference.pixels[(y * frame.width + x) as usize])
            .collect(),
    };
    let (part, _) = Wavefront::for_region(ctx, buffers.clone(), buffers.key, frame, region)
        .unwrap()
        .render(ctx, &|_, _| {})
        .unwrap();
    same("wavefront region", &part, &crop);
    let (part, _) = render_tiles(ctx, &buffers, &frame, RenderMode::Path, buffers.key, region, &|_, _| {}).unwrap();
    same("megakernel region", &part, &crop);
}

/// A textured floor (an OBJ mesh with `vt`), a glass sphere and a two-sided emissive panel with
/// an emission texture, under an environment map (a gradient sky with a small bright sun,
/// rotated): written to `dir`.
fn env_textured_scene(dir: &Path) -> Scene {
    image::RgbImage::from_fn(8, 8, |x, y| image::Rgb(if (x + y) % 2 == 0 { [230, 200, 40] } else { [20, 60, 220] }))
        .save(dir.join("checker.png"))
        .unwrap();
    let sky = |x: u32, y: u32| {
        if (5..7).contains(&x) && y == 3 { [900.0, 800.0, 600.0] } else { [0.2, 0.3, 0.1 + y as f32 * 0.05] }
    };
    image::Rgb32FImage::from_fn(32, 16, |x, y| image::Rgb(sky(x, y))).save(dir.join("sky.exr")).unwrap();
    let quad = |name: &str, v: [[f32; 3]; 4]| {
        let mut obj = String::new();
        for p in v {
            obj += &format!("v {} {} {}\n", p[0], p[1], p[2]);
        }
        obj += "vt 0 0\nvt 3 0\nvt 3 3\nvt 0 3\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n";
        std::fs::write(dir.join(name), obj).unwrap();
    };
    quad("floor.obj", [[-3.0, 0.0, -3.0], [-3.0, 0.0, 3.0], [3.0, 0.0, 3.0], [3.0, 0.0, -3.0]]);
    quad("panel.obj", [[-1.5, 0.2, 1.5], [1.5, 0.2, 1.5], [1.5, 1.7, 1.5], [-1.5, 1.7, 1.5]]);
    let toml = r#"
[camera]
eye = [0.0, 1.6, -4.0]
look_at = [0.0, 0.5, 0.0]
up = [0.0, 1.0, 0.0]
fov_y = 55.0
[image]
width = 40
height = 30
[render]
mode = "path"
max_depth = 5
[[materials]]
name = "floor"
type = "diffuse"
color = [0.9, 0.9, 0.9]
texture = "checker.png"
[[materials]]
name = "glow"
type = "emissive"
radiance = [3.0, 3.0, 3.0]
radiance_texture = "checker.png"
two_sided = true
[[materials]]
name = "glass"
type = "dielectric"
[[objects]]
type = "mesh"
file = "floor.obj"
material = "floor"
[[objects]]
type = "mesh"
file = "panel.obj"
material = "glow"
[[objects]]
type = "sphere"
center = [0.6, 0.5, 0.0]
radius = 0.5
material = "glass"
[environment]
file = "sky.exr"
strength = 0.8
rotation = 30.0
"#;
    let path = dir.join("env.toml");
    std::fs::write(&path, toml).unwrap();
    let s = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    s
}
