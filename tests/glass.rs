//! Rough and absorbing glass and spot lights on both backends: white furnaces, Beer–Lambert
//! against the analytic chord, the spot cone against its formula, and the GPU against the
//! CPU on `assets/scenes/glass.toml`.

mod common;

use common::{cpu_path_image as cpu_image, gpu, gpu_path_image as gpu_image};
use std::path::Path;
use std::sync::Arc;
use strahl_core::image::Image;
use strahl_core::render::Prepared;
use strahl_core::scene::{RenderMode, Scene, file::parse};

fn scene(src: &str) -> Scene {
    parse(src, Path::new("test.toml"), Path::new(".")).unwrap_or_else(|e| panic!("{e}"))
}

/// A sphere of `material` filling the view in a uniform white environment of radiance 1.
fn furnace_scene(material: &str) -> Scene {
    scene(&format!(
        r#"
[camera]
eye = [0.0, 0.0, -3.0]
look_at = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
fov_y = 36.0
[image]
width = 16
height = 16
[render]
mode = "path"
max_depth = 32
[environment]
radiance = [1.0, 1.0, 1.0]
[[materials]]
name = "glass"
{material}
[[objects]]
type = "sphere"
center = [0.0, 0.0, 0.0]
radius = 1.0
material = "glass"
"#
    ))
}

fn mean_and_error(img: &Image) -> (f64, f64) {
    let v: Vec<f64> = img.pixels.iter().map(|p| (p[0] as f64 + p[1] as f64 + p[2] as f64) / 3.0).collect();
    common::mean_and_error(&v)
}

/// Glass that neither absorbs nor is tinted, rough or smooth, as a scene file's dielectric
/// or a glTF-style pbr material with transmission, disappears in a white furnace: every
/// pixel's expected value is 1 (what enters leaves; radiance compressed by 1/η² on the way in
/// is expanded by η² on the way out), to 1 % (the rough interface's lost energy made up,
/// `render::dielectric`).
#[test]
fn glass_disappears_in_a_white_furnace_on_both_backends() {
    let ctx = gpu().map(Arc::new);
    let materials = [
        "type = \"dielectric\"\nior = 1.5\nroughness = 0.5",
        "type = \"dielectric\"\nior = 1.33\nroughness = 1.0",
        "type = \"pbr\"\ncolor = [1.0, 1.0, 1.0]\nmetallic = 0.0\nroughness = 0.7\ntransmission = 1.0",
        "type = \"pbr\"\ncolor = [1.0, 1.0, 1.0]\nmetallic = 0.0\nroughness = 0.4\ntransmission = 0.5",
    ];
    for (k, m) in materials.into_iter().enumerate() {
        let prep = Arc::new(Prepared::new(furnace_scene(m)));
        let frame = prep.frame(16, 16);
        let mut images = vec![("cpu", cpu_image(&prep, frame, 256))];
        // (lavapipe takes about 40 s a material: two of the four, the scene file's and the
        // mixture, on the GPU.)
        if let Some(ctx) = ctx.as_ref().filter(|_| k % 2 == 1) {
            images.push(("gpu", gpu_image(ctx, &prep, frame, 256)));
        }
        for (backend, img) in images {
            assert_eq!(img.non_finite_count(), 0);
            let (mean, se) = mean_and_error(&img);
            eprintln!("{backend} {}: mean {mean:.4} ± {se:.4}", m.replace('\n', " "));
            assert!(se < 0.004, "{backend}: standard error {se} too large to test 1 %");
            assert!((mean - 1.0).abs() < 0.01 + 4.0 * se, "{backend} {m}: furnace mean {mean} ± {se}");
        }
    }
}

/// Absorbing glass of index 1 bends nothing: a camera ray through a sphere of radius R at
/// distance b from its centre keeps exp(−σ·2√(R² − b²)) of the white environment behind it,
/// per channel. Checked at every pixel whose rays all cross the sphere, on both backends.
#[test]
fn absorption_follows_beer_lambert_along_the_chord() {
    let sigma = [0.9f64, 0.35, 0.05];
    let prep = Arc::new(Prepared::new(furnace_scene(&format!(
        "type = \"dielectric\"\nior = 1.0\nabsorption = [{}, {}, {}]",
        sigma[0], sigma[1], sigma[2]
    ))));
    let frame = prep.frame(16, 16);
    let ctx = gpu().map(Arc::new);
    let mut images = vec![("cpu", cpu_image(&prep, frame, 32))];
    if let Some(ctx) = &ctx {
        images.push(("gpu", gpu_image(ctx, &prep, frame, 32)));
    }
    // The camera at distance 3 looks at the centre; a pixel's centre ray passes the centre at
    // b = 3 sin(angle off the axis).
    let half = (18.0f64).to_radians().tan();
    for (backend, img) in images {
        let mut checked = 0;
        let mut worst = 0.0f64;
        for y in 0..16u32 {
            for x in 0..16u32 {
                let px = ((x as f64 + 0.5) / 8.0 - 1.0) * half;
                let py = ((y as f64 + 0.5) / 8.0 - 1.0) * half;
                let angle = (px * px + py * py).sqrt().atan();
                let b = 3.0 * angle.sin();
                // Pixels well inside the silhouette (the chord varies little across them).
                if b > 0.75 {
                    continue;
                }
                let chord = 2.0 * (1.0 - b * b).sqrt();
                let got = img.get(x, y);
                for c in 0..3 {
                    let want = (-sigma[c] * chord).exp();
                    let rel = (got[c] as f64 - want).abs() / want;
                    worst = worst.max(rel);
                    assert!(rel < 0.02, "{backend} pixel ({x}, {y}) channel {c}: {} vs {want}", got[c]);
                }
                checked += 1;
            }
        }
        eprintln!("{backend}: {checked} pixels, largest relative error {worst:.4}");
        assert!(checked > 50);
    }
}

/// A spot light over a diffuse floor (Whitted, no ambient): a floor point at distance d from
/// the light, θ off its axis, shows albedo/π · I · clamp(cos θ·s + o, 0, 1)² / d² · cos(incidence),
/// with s and o from the cone's angles as KHR_lights_punctual defines them: black outside the
/// outer cone, full inside the inner one. Both backends, at every pixel.
#[test]
fn spot_light_falls_off_as_the_extension_defines() {
    let src = r#"
[camera]
eye = [0.0, 4.0, 0.0]
look_at = [0.0, 0.0, 0.0]
up = [0.0, 0.0, 1.0]
fov_y = 90.0
[image]
width = 40
height = 40
[render]
mode = "whitted"
ambient = [0.0, 0.0, 0.0]
background = [0.0, 0.0, 0.0]
[[materials]]
name = "floor"
type = "diffuse"
color = [0.5, 0.5, 0.5]
[[objects]]
type = "plane"
point = [0.0, 0.0, 0.0]
normal = [0.0, 1.0, 0.0]
material = "floor"
[[lights]]
type = "spot"
position = [0.0, 2.0, 0.0]
direction = [0.0, -1.0, 0.0]
intensity = [10.0, 10.0, 10.0]
inner_angle = 20.0
outer_angle = 40.0
"#;
    let prep = Arc::new(Prepared::new(scene(src)));
    let frame = prep.frame(40, 40);
    let mut frame = frame;
    frame.spp = 1;
    let cpu = strahl_cpu::render(&strahl_cpu::CpuScene::new(&prep), &frame, RenderMode::Whitted, &|_| {});
    let mut images = vec![("cpu", cpu)];
    if let Some(ctx) = gpu() {
        let b = strahl_gpu::SceneBuffers::upload(&ctx, &prep.flat).unwrap();
        images.push((
            "gpu",
            strahl_gpu::tiles::render(&ctx, &b, &frame, RenderMode::Whitted, b.key, &|_, _| {}).unwrap().0,
        ));
    }
    let (ci, co) = (20.0f64.to_radians().cos(), 40.0f64.to_radians().cos());
    let scale = 1.0 / (ci - co);
    let half = (45.0f64).to_radians().tan();
    for (backend, img) in images {
        let (mut dark, mut full) = (0, 0);
        for y in 0..40u32 {
            for x in 0..40u32 {
                // The floor point under the pixel's centre (the camera looks straight down).
                let u = ((x as f64 + 0.5) / 20.0 - 1.0) * half * 4.0;
                let v = ((y as f64 + 0.5) / 20.0 - 1.0) * half * 4.0;
                let d2 = u * u + v * v + 4.0;
                let cos = 2.0 / d2.sqrt();
                let a = (cos * scale - co * scale).clamp(0.0, 1.0);
                let want = 0.5 / std::f64::consts::PI * 10.0 * a * a / d2 * cos;
                let got = img.get(x, y)[0] as f64;
                assert!((got - want).abs() <= 1e-3 * want.max(1e-2), "{backend} ({x}, {y}): {got} vs {want}");
                dark += (a == 0.0) as usize;
                full += (a == 1.0) as usize;
            }
        }
        assert!(dark > 100 && full > 30, "{backend}: {dark} pixels outside the cone, {full} inside the inner one");
    }
}

/// The GPU traces the paths the CPU traces through `glass.toml` (rough glass, absorbing glass,
/// polygons, a mesh): the same samples of the same pixels agree to f32 rounding except where
/// a branch flips on a rounding difference.
#[test]
fn gpu_and_cpu_trace_the_same_glass() {
    let Some(ctx) = gpu() else { return };
    let ctx = Arc::new(ctx);
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes/glass.toml");
    let prep = Arc::new(Prepared::new(Scene::load(&path).unwrap()));
    let frame = prep.frame(64, 48);
    let (c, g) = (cpu_image(&prep, frame, 4), gpu_image(&ctx, &prep, frame, 4));
    let frac = common::agreeing_fraction(&c, &g);
    eprintln!("glass.toml: pixels equal to 1e-3: {:.2} %", 100.0 * frac);
    assert!(frac > 0.95, "only {:.2} % of pixels agree", 100.0 * frac);
}
