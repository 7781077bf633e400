//! glTF's layers (`KHR_materials_clearcoat`, `_sheen`) and specular reflectance
//! (`KHR_materials_specular`) in whole renders on both backends: white furnaces, the GPU
//! against the CPU on the same samples, and what the scene file and the glTF importer read.

mod common;

use common::{cpu_path_image as cpu_image, gpu, gpu_path_image as gpu_image};
use std::path::Path;
use std::sync::Arc;
use strahl_core::render::Prepared;
use strahl_core::scene::{Scene, file::parse};

fn scene(src: &str) -> Scene {
    parse(src, Path::new("test.toml"), Path::new(".")).unwrap_or_else(|e| panic!("{e}"))
}

/// Two spheres of `a` and `b` side by side, filling most of the view, in a uniform white
/// environment of radiance 1.
fn furnace_scene(a: &str, b: &str) -> Scene {
    scene(&format!(
        r#"
[camera]
eye = [0.0, 0.0, -4.0]
look_at = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
fov_y = 30.0
[image]
width = 32
height = 16
[render]
mode = "path"
max_depth = 32
[environment]
radiance = [1.0, 1.0, 1.0]
[[materials]]
name = "a"
type = "pbr"
{a}
[[materials]]
name = "b"
type = "pbr"
{b}
[[objects]]
type = "sphere"
center = [-1.0, 0.0, 0.0]
radius = 0.98
material = "a"
[[objects]]
type = "sphere"
center = [1.0, 0.0, 0.0]
radius = 0.98
material = "b"
"#
    ))
}

/// A white coat over white sheen over a white base, opaque (left) and glass (right), keep
/// all light in a white furnace: every pixel's expected value is 1, to 1 % (the layers'
/// albedo scaling with their tables, `render::layers`), on the CPU and the GPU.
#[test]
fn layers_disappear_in_a_white_furnace_on_both_backends() {
    let opaque = "color = [1.0, 1.0, 1.0]\nroughness = 0.6\nclearcoat = 1.0\nclearcoat_roughness = 0.3\n\
                  sheen_color = [1.0, 1.0, 1.0]\nsheen_roughness = 0.5";
    let glass = "color = [1.0, 1.0, 1.0]\nroughness = 0.3\ntransmission = 1.0\nclearcoat = 0.8\n\
                 clearcoat_roughness = 0.1\nsheen_color = [1.0, 1.0, 1.0]\nsheen_roughness = 0.8";
    let prep = Arc::new(Prepared::new(furnace_scene(opaque, glass)));
    let frame = prep.frame(32, 16);
    let mut images = vec![("cpu", cpu_image(&prep, frame, 256))];
    if let Some(ctx) = gpu() {
        images.push(("gpu", gpu_image(&Arc::new(ctx), &prep, frame, 256)));
    }
    for (backend, img) in images {
        assert_eq!(img.non_finite_count(), 0);
        for (side, xs) in [("opaque", 0..16u32), ("glass", 16..32)] {
            let v: Vec<f64> = xs
                .flat_map(|x| (0..16u32).map(move |y| (x, y)))
                .map(|(x, y)| img.get(x, y).iter().map(|&c| c as f64).sum::<f64>() / 3.0)
                .collect();
            let (mean, se) = common::mean_and_error(&v);
            eprintln!("{backend} {side}: mean {mean:.4} ± {se:.4}");
            assert!(se < 0.005, "{backend}: standard error {se} too large to test 1 %");
            assert!((mean - 1.0).abs() < 0.01 + 4.0 * se, "{backend} {side}: furnace mean {mean} ± {se}");
        }
    }
}

/// The GPU traces the paths the CPU traces through layered materials under a light: a
/// tinted clear coat, a coloured sheen, a coloured specular reflectance and coated glass.
#[test]
fn gpu_and_cpu_trace_the_same_layers() {
    let Some(ctx) = gpu() else { return };
    let prep = Arc::new(Prepared::new(scene(
        r#"
[camera]
eye = [0.0, 1.0, -5.0]
look_at = [0.0, 0.3, 0.0]
up = [0.0, 1.0, 0.0]
fov_y = 40.0
[image]
width = 64
height = 40
[render]
mode = "path"
max_depth = 8
[environment]
radiance = [0.3, 0.35, 0.4]
[[materials]]
name = "car_paint"
type = "pbr"
color = [0.6, 0.05, 0.05]
roughness = 0.5
clearcoat = 1.0
clearcoat_roughness = 0.05
[[materials]]
name = "velvet"
type = "pbr"
color = [0.1, 0.1, 0.4]
roughness = 0.9
sheen_color = [1.0, 0.6, 0.2]
sheen_roughness = 0.4
[[materials]]
name = "tinted_specular"
type = "pbr"
color = [0.2, 0.2, 0.2]
roughness = 0.3
ior = 1.8
specular = 0.8
specular_color = [1.0, 0.5, 0.2]
[[materials]]
name = "coated_glass"
type = "pbr"
color = [0.9, 1.0, 0.9]
roughness = 0.2
transmission = 1.0
clearcoat = 0.5
[[materials]]
name = "floor"
type = "diffuse"
color = [0.5, 0.5, 0.5]
[[materials]]
name = "lamp"
type = "emissive"
radiance = [20.0, 18.0, 15.0]
[[objects]]
type = "sphere"
center = [-1.8, 0.5, 0.0]
radius = 0.5
material = "car_paint"
[[objects]]
type = "sphere"
center = [-0.6, 0.5, 0.0]
radius = 0.5
material = "velvet"
[[objects]]
type = "sphere"
center = [0.6, 0.5, 0.0]
radius = 0.5
material = "tinted_specular"
[[objects]]
type = "sphere"
center = [1.8, 0.5, 0.0]
radius = 0.5
material = "coated_glass"
[[objects]]
type = "plane"
point = [0.0, 0.0, 0.0]
normal = [0.0, 1.0, 0.0]
material = "floor"
[[objects]]
type = "sphere"
center = [0.0, 4.0, -1.0]
radius = 0.5
material = "lamp"
"#,
    )));
    let ctx = Arc::new(ctx);
    let frame = prep.frame(64, 40);
    let (c, g) = (cpu_image(&prep, frame, 4), gpu_image(&ctx, &prep, frame, 4));
    assert_eq!((c.non_finite_count(), g.non_finite_count()), (0, 0));
    let frac = common::agreeing_fraction(&c, &g);
    eprintln!("layers: pixels equal to 1e-3: {:.2} %", 100.0 * frac);
    assert!(frac > 0.99, "only {:.2} % of pixels agree", 100.0 * frac);
}
