//! Whole scenes far from the origin and scaled by 10⁻⁶ … 10⁶: rendered images against the
//! same scene at the origin and at scale 1.

use super::*;
use strahl_core::geometry::{Cylinder, Sphere, Triangle};
use strahl_core::scene::{RenderMode, Scene};
use strahl_gpu::{GpuError, SceneBuffers};

/// A small scene, as is and translated by (1e5, 1e5, 1e5).
pub fn scene_at(offset: f64) -> Scene {
    let text = format!(
        r#"
[camera]
eye = [{o}, {y3}, {zm9}]
look_at = [{o}, {y12}, {o}]
up = [0, 1, 0]
fov_y = 40
[image]
width = 160
height = 120
[[materials]]
name = "clay"
type = "diffuse"
color = [0.8, 0.6, 0.4]
[[materials]]
name = "chrome"
type = "mirror"
color = [0.9, 0.9, 0.9]
[[objects]]
type = "plane"
point = [{o}, {o}, {o}]
normal = [0, 1, 0]
[[objects]]
type = "sphere"
center = [{o}, {y15}, {o}]
radius = 1.5
material = "clay"
[[objects]]
type = "sphere"
center = [{x3}, {y1}, {zm1}]
radius = 1.0
material = "chrome"
[[objects]]
type = "cylinder"
p1 = [{xm3}, {o}, {z1}]
p2 = [{xm3}, {y3}, {z1}]
radius = 0.7
material = "clay"
[[lights]]
type = "point"
position = [{xm5}, {y8}, {zm6}]
intensity = [300, 300, 300]
"#,
        o = offset,
        y3 = offset + 3.0,
        zm9 = offset - 9.0,
        y12 = offset + 1.2,
        y15 = offset + 1.5,
        x3 = offset + 3.0,
        y1 = offset + 1.0,
        zm1 = offset - 1.0,
        xm3 = offset - 3.0,
        z1 = offset + 1.0,
        xm5 = offset - 5.0,
        y8 = offset + 8.0,
        zm6 = offset - 6.0,
    );
    strahl_core::scene::file::parse(&text, std::path::Path::new("far.toml"), std::path::Path::new("."))
        .expect("valid scene")
}

/// `scene` with every position and length multiplied by `s`: the camera, the objects and the
/// point lights, whose intensities are multiplied by s² so that the irradiance they give is
/// unchanged (emissive radiance and directional irradiance do not depend on the scale). Up to
/// rounding it renders the same image at any scale.
pub fn scaled(scene: &Scene, s: f64) -> Scene {
    use strahl_core::scene::{Geometry, Light};
    let tri = |t: &Triangle<f64>| Triangle { v: t.v.map(|p| p * s) };
    let mut out = scene.clone();
    out.camera.eye = scene.camera.eye * s;
    out.camera.look_at = scene.camera.look_at * s;
    for o in &mut out.objects {
        o.geometry = match &o.geometry {
            Geometry::Sphere(sp) => Geometry::Sphere(Sphere { center: sp.center * s, radius: sp.radius * s }),
            Geometry::Cylinder(c) => {
                Geometry::Cylinder(Cylinder { p1: c.p1 * s, p2: c.p2 * s, radius: c.radius * s, ..*c })
            }
            Geometry::Plane(p) => {
                Geometry::Plane(strahl_core::geometry::Plane { point: p.point * s, normal: p.normal })
            }
            Geometry::Triangle(t) => Geometry::Triangle(tri(t)),
            Geometry::Polygon { vertices, triangles } => Geometry::Polygon {
                vertices: vertices.iter().map(|&v| v * s).collect(),
                triangles: triangles.iter().map(tri).collect(),
            },
            Geometry::Mesh { file, triangles, attrs, materials } => Geometry::Mesh {
                file: file.clone(),
                triangles: triangles.iter().map(tri).collect(),
                attrs: attrs.clone(),
                materials: materials.clone(),
            },
        };
    }
    for l in &mut out.lights {
        if let Light::Point { position, intensity, range } = l {
            *range *= s;
            *position = *position * s;
            *intensity = intensity.map(|i| i * s * s);
        }
    }
    out
}

/// Acne (a lit pixel rendered much darker: the surface shadows itself) and holes (background
/// where there is geometry, or the reverse) of a render against the reference.
pub fn acne_and_holes(
    reference: &strahl_core::image::Image,
    test: &strahl_core::image::Image,
    background: [f32; 3],
) -> usize {
    let lum = |p: &[f32; 3]| 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
    reference
        .pixels
        .iter()
        .zip(&test.pixels)
        .filter(|(r, t)| {
            let hole = (**r == background) != (**t == background);
            let acne = lum(r) > 0.05 && lum(t) < 0.7 * lum(r);
            hole || acne
        })
        .count()
}

/// The Whitted image of `prep` on the robust `variant` (None for the textbook one, which
/// renders nothing).
fn render_on(
    variant: Variant,
    prep: &strahl_core::render::Prepared,
    frame: &strahl_core::layout::FrameParams,
    opt: &Options,
) -> Result<Option<strahl_core::image::Image>, GpuError> {
    Ok(match variant {
        Variant::Cpu => Some(strahl_cpu::render(&strahl_cpu::CpuScene::new(prep), frame, RenderMode::Whitted, &|_| {})),
        Variant::Gpu => {
            let ctx = opt.gpu.expect("gpu");
            let b = SceneBuffers::upload(ctx, &prep.flat)?;
            Some(strahl_gpu::tiles::render(ctx, &b, frame, RenderMode::Whitted, b.key, &|_, _| {})?.0)
        }
        Variant::Textbook => None,
    })
}

/// The scene translated by 1e5 must render as it does at the origin: no acne, no holes.
pub fn far_from_origin(opt: &Options) -> Result<Vec<Row>, GpuError> {
    let near = strahl_core::render::Prepared::new(scene_at(0.0));
    let far = strahl_core::render::Prepared::new(scene_at(1e5));
    let frame_near = near.frame(160, 120);
    let frame_far = far.frame(160, 120);
    let reference = strahl_cpu::render(&strahl_cpu::CpuScene::new(&near), &frame_near, RenderMode::Whitted, &|_| {});
    let bg = near.scene.render.background.map(|c| c as f32);
    each_variant(opt, |variant| {
        let Some(img) = render_on(variant, &far, &frame_far, opt)? else { return Ok(None) };
        Ok(Some(Row {
            case: "scene translated by 1e5 (160x120 render vs at the origin)".into(),
            rays: 160 * 120,
            fails: acne_and_holes(&reference, &img, bg) + img.non_finite_count(),
            fail_kind: "acne/hole/NaN pixels",
            ..Row::default()
        }))
    })
}

/// Pixels of two images whose 8-bit sRGB codes differ by more than `codes` in some channel.
pub fn pixels_off_by_more_than(a: &strahl_core::image::Image, b: &strahl_core::image::Image, codes: u8) -> usize {
    let (a, b) = (a.to_srgb8(), b.to_srgb8());
    a.chunks(3).zip(b.chunks(3)).filter(|(p, q)| p.iter().zip(q.iter()).any(|(x, y)| x.abs_diff(*y) > codes)).count()
}

/// Scales of [`scaled_scenes`].
pub const SCALES: [f64; 4] = [1e-6, 1e-3, 1e3, 1e6];

/// The scene of [`far_from_origin`] scaled by 10⁻⁶ … 10⁶ (camera, objects and light
/// together, [`scaled`]) must render as at scale 1: a fail is a pixel more than 2 codes off,
/// or not finite. Fixed offsets near the origin made the small scales lose shadows and
/// reflections (and glass, in the seed scene).
pub fn scaled_scenes(opt: &Options) -> Result<Vec<Row>, GpuError> {
    let (w, h) = (160, 120);
    let base = strahl_core::render::Prepared::new(scene_at(0.0));
    let reference =
        strahl_cpu::render(&strahl_cpu::CpuScene::new(&base), &base.frame(w, h), RenderMode::Whitted, &|_| {});
    let mut rows = Vec::new();
    for s in SCALES {
        let prep = strahl_core::render::Prepared::new(scaled(&base.scene, s));
        let frame = prep.frame(w, h);
        rows.extend(each_variant(opt, |variant| {
            let Some(img) = render_on(variant, &prep, &frame, opt)? else { return Ok(None) };
            Ok(Some(Row {
                case: format!("scene scaled by {s:e} ({w}x{h} render vs at scale 1)"),
                rays: (w * h) as usize,
                fails: pixels_off_by_more_than(&reference, &img, 2) + img.non_finite_count(),
                fail_kind: "pixels > 2 codes off",
                ..Row::default()
            }))
        })?);
    }
    Ok(rows)
}
