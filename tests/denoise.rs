//! Output variables (`strahl render --aov`) and the denoiser (`--denoise`): analytic AOV values
//! on a plane, the GPU's AOVs and denoised images against the CPU's, the denoiser lowering the
//! error of a noisy render, and the command line's files and refusals.

mod common;

use common::gpu;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Arc;
use strahl_core::denoise::denoise;
use strahl_core::image::{Image, Region, to_srgb8};
use strahl_core::render::Prepared;
use strahl_core::render::aov::{Aov, AovImages};
use strahl_core::scene::{RenderMode, Scene};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn cpu_aovs(prep: &Prepared, w: u32, h: u32, spp: u32, aovs: &[Aov]) -> AovImages {
    let cpu = strahl_cpu::CpuScene::new(prep);
    let mut frame = prep.frame(w, h);
    frame.spp = spp;
    strahl_cpu::aov::render_aovs(&cpu.inputs(&frame), Region::whole(w, h), aovs)
}

/// A diffuse plane z = 5 facing a camera at the origin looking down +z, under a sky of
/// (2, 0.5, 0.25): the albedo, normal, depth, position and indices are known in closed form.
const PLANE: &str = r#"
[camera]
eye = [0.0, 0.0, 0.0]
look_at = [0.0, 0.0, 1.0]
up = [0.0, 1.0, 0.0]
fov_y = 60.0

[image]
width = 33
height = 21

[render]
background = [2.0, 0.5, 0.25]

[[materials]]
name = "wall"
type = "diffuse"
color = [0.5, 0.25, 0.125]

[[objects]]
type = "polygon"
vertices = [[-1.0, -1.0, 5.0], [1.0, -1.0, 5.0], [1.0, 1.0, 5.0], [-1.0, 1.0, 5.0]]
material = "wall"
"#;

#[test]
fn aovs_of_a_plane_are_its_closed_form_values() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("plane.toml");
    std::fs::write(&path, PLANE).unwrap();
    let prep = Prepared::new(Scene::load(&path).unwrap());
    let (w, h) = (33u32, 21u32);
    let v = cpu_aovs(&prep, w, h, 4, &Aov::ALL);
    let at = |a: Aov, x: u32, y: u32| -> Vec<f32> {
        let n = a.channels().len();
        let i = (y * w + x) as usize * n;
        v.get(a).unwrap()[i..i + n].to_vec()
    };
    // The centre pixel looks straight at the wall's centre.
    let (cx, cy) = (w / 2, h / 2);
    assert_eq!(at(Aov::Albedo, cx, cy), vec![0.5, 0.25, 0.125]);
    let n = at(Aov::Normal, cx, cy);
    assert!((n[2] + 1.0).abs() < 1e-6 && n[0].abs() < 1e-6 && n[1].abs() < 1e-6, "normal {n:?}");
    assert!((at(Aov::Depth, cx, cy)[0] - 5.0).abs() < 1e-5);
    let p = at(Aov::Position, cx, cy);
    assert!((p[2] - 5.0).abs() < 1e-5 && p[0].abs() < 1e-5 && p[1].abs() < 1e-5, "position {p:?}");
    assert_eq!(at(Aov::Object, cx, cy), vec![0.0]);
    assert_eq!(at(Aov::Material, cx, cy), vec![0.0]);
    // A corner pixel sees the sky (the wall spans ±0.2 rad about the axis; the corner ±0.5).
    assert_eq!(at(Aov::Albedo, 0, 0), vec![1.0, 0.5, 0.25], "the sky, clamped to [0, 1]");
    assert_eq!(at(Aov::Normal, 0, 0), vec![0.0; 3]);
    assert_eq!(at(Aov::Depth, 0, 0), vec![0.0]);
    assert_eq!(at(Aov::Object, 0, 0), vec![-1.0]);
    assert_eq!(at(Aov::Material, 0, 0), vec![-1.0]);
    // A pixel off the centre: depth along its own ray, 5 / cos θ.
    let p = at(Aov::Position, cx + 2, cy);
    let d = at(Aov::Depth, cx + 2, cy)[0];
    let len = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
    assert!((d - len).abs() < 1e-4 && (p[2] - 5.0).abs() < 1e-5, "depth {d}, position {p:?}");
}

/// Glass and mirrors are seen through: the seed scene's glass sphere shows, in the albedo
/// guide, what lies behind and under it, not black (the guide of a surface that stopped there).
#[test]
fn guides_see_through_smooth_glass() {
    let prep = Prepared::new(Scene::load(root().join("assets/scenes/seed.toml")).unwrap());
    let glass = prep.scene.materials.iter().position(|m| m.kind == strahl_core::scene::MaterialKind::Dielectric);
    let glass = glass.expect("the seed scene has a glass material") as f32;
    let (w, h) = (160u32, 120u32);
    let v = cpu_aovs(&prep, w, h, 1, &[Aov::Albedo, Aov::Material]);
    let (albedo, material) = (v.get(Aov::Albedo).unwrap(), v.get(Aov::Material).unwrap());
    let seen: Vec<usize> = (0..(w * h) as usize).filter(|&i| material[i] == glass).collect();
    assert!(seen.len() > 50, "{} glass pixels", seen.len());
    let lit = seen.iter().filter(|&&i| albedo[3 * i..3 * i + 3].iter().any(|&c| c > 0.05)).count();
    // The rest see the black sky through the glass (88 % have an albedo when this was written).
    assert!(lit * 4 > seen.len() * 3, "{lit} of {} glass pixels have an albedo", seen.len());
}

/// The GPU's output variables equal the CPU's on every shipped scene and the textured golden
/// scene: the same rays and the same f32 operations (a value may differ by rounding where a
/// ray grazes an edge: 0.1 % of pixels are allowed).
#[test]
fn gpu_aovs_equal_the_cpus() {
    let Some(ctx) = gpu() else { return };
    let mut scenes = common::shipped_scenes();
    scenes.push(root().join("tests/golden/textured.toml"));
    scenes.push(root().join("tests/golden/cornell.toml"));
    for path in scenes {
        let prep = Prepared::new(Scene::load(&path).unwrap());
        let (w, h) = (64u32, 48u32);
        let want = cpu_aovs(&prep, w, h, 4, &Aov::ALL);
        let buffers = strahl_gpu::SceneBuffers::upload(&ctx, &prep.flat).unwrap();
        let mut frame = prep.frame(w, h);
        frame.spp = 4;
        let got = strahl_gpu::aov::render_aovs(&ctx, &buffers, &frame, Region::whole(w, h), &Aov::ALL).unwrap();
        for a in Aov::ALL {
            let (x, y) = (want.get(a).unwrap(), got.get(a).unwrap());
            let n = a.channels().len();
            let differ = (0..(w * h) as usize)
                .filter(|&i| (0..n).any(|c| (x[i * n + c] - y[i * n + c]).abs() > 1e-4 * (1.0 + x[i * n + c].abs())))
                .count();
            assert!(differ * 1000 <= (w * h) as usize, "{}: {a:?} differs at {differ} pixels", path.display());
        }
    }
}

fn seed_with_guides(w: u32, h: u32, spp: u32) -> (Arc<Prepared>, Image, AovImages) {
    let prep = Arc::new(Prepared::new(Scene::load(root().join("assets/scenes/seed.toml")).unwrap()));
    let cpu = strahl_cpu::CpuScene::new(&prep);
    let mut frame = prep.frame(w, h);
    frame.spp = spp;
    let img = strahl_cpu::render(&cpu, &frame, RenderMode::Path, &|_| {});
    let guides = strahl_cpu::aov::render_aovs(&cpu.inputs(&frame), Region::whole(w, h), &[Aov::Albedo, Aov::Normal]);
    (prep, img, guides)
}

/// The GPU's denoiser equals the CPU's within rounding: 99.9 % of the 8-bit codes within one.
#[test]
fn gpu_denoiser_equals_the_cpus() {
    let Some(ctx) = gpu() else { return };
    let (_, img, aovs) = seed_with_guides(160, 120, 4);
    let guides = aovs.guides().unwrap();
    let want = denoise(&img, &guides);
    let denoiser = strahl_gpu::denoise::Denoiser::new(&ctx).unwrap();
    let (got, _) = denoiser.denoise(&ctx, &img, &guides).unwrap();
    let codes = |im: &Image| im.pixels.iter().flat_map(|p| p.map(to_srgb8)).collect::<Vec<u8>>();
    let (a, b) = (codes(&want), codes(&got));
    let off = a.iter().zip(&b).filter(|(x, y)| x.abs_diff(**y) > 1).count();
    assert!(off * 1000 <= a.len(), "{off} of {} codes differ by more than one", a.len());
    // And it did something: the denoised image is not the noisy one.
    let changed = a.iter().zip(&codes(&img)).filter(|(x, y)| x.abs_diff(**y) > 2).count();
    assert!(changed * 4 > a.len(), "only {changed} of {} codes changed", a.len());
}

/// Denoising brings a 4-spp render of the seed scene closer to a 256-spp one than the raw
/// 16-spp render is (clamped RMSE, as images are displayed).
#[test]
fn denoising_beats_four_times_the_samples() {
    let (w, h) = (160u32, 120u32);
    let (prep, img, aovs) = seed_with_guides(w, h, 4);
    let reference = common::cpu_path_image(&prep, prep.frame(w, h), 256);
    let raw16 = common::cpu_path_image(&prep, prep.frame(w, h), 16);
    let denoised = denoise(&img, &aovs.guides().unwrap());
    let rmse = |x: &Image| strahl_metrics::errors(&reference, x).unwrap().rmse_clamped;
    let (r4, r16, d4) = (rmse(&img), rmse(&raw16), rmse(&denoised));
    eprintln!("clamped RMSE against 256 spp: raw 4 spp {r4:.4}, raw 16 spp {r16:.4}, denoised 4 spp {d4:.4}");
    assert!(d4 < r16, "denoised 4 spp {d4} against raw 16 spp {r16}");
    assert_eq!(denoised.non_finite_count(), 0);
}

fn strahl(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_strahl")).current_dir(root()).args(args).output().unwrap()
}

fn exr_channels(path: &Path) -> Vec<String> {
    let meta = exr::meta::MetaData::read_from_file(path, false).unwrap();
    meta.headers[0].channels.list.iter().map(|c| c.name.to_string()).collect()
}

#[test]
fn render_writes_the_named_channels_and_refuses_what_it_cannot_do() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("seed.exr");
    let o = out.to_str().unwrap();
    let args = ["render", "assets/scenes/seed.toml", "--width", "48", "--height", "36", "--spp", "2"];
    let run =
        strahl(&[&args[..], &["--backend", "cpu", "--mode", "path", "-o", o, "--aov", "depth,albedo,object"]].concat());
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let mut names = exr_channels(&out);
    names.sort();
    assert_eq!(names, ["B", "G", "R", "albedo.B", "albedo.G", "albedo.R", "depth.Z", "object.id"]);
    // The RGB channels still read as the image.
    assert_eq!(Image::load(&out).unwrap().width, 48);

    // --denoise writes the denoised image and, unasked, no guides.
    let den = dir.path().join("denoised.exr");
    let run = strahl(
        &[&args[..], &["--backend", "cpu", "--mode", "path", "-o", den.to_str().unwrap(), "--denoise"]].concat(),
    );
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    assert_eq!(exr_channels(&den).len(), 3);
    assert!(String::from_utf8_lossy(&run.stdout).contains("denoised on the cpu"));

    let refused = |extra: &[&str], says: &str| {
        let png = dir.path().join("x.png");
        let run = strahl(&[&args[..], &["--backend", "cpu", "-o", png.to_str().unwrap()], extra].concat());
        let err = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(2), "{extra:?}: {err}");
        assert!(err.contains(says) && !err.contains("panicked"), "{extra:?}: {err}");
        assert!(!png.exists(), "{extra:?} wrote a file");
    };
    refused(&["--aov", "albedo"], "channels of an EXR file");
    refused(&["--aov", "albedo,shadow"], "\"shadow\"");
    refused(&["--aov", "depth,depth"], "twice");
    refused(&["--denoise", "--tile", "0/2"], "seams");
    refused(&["--denoise", "--region", "0,0,8,8"], "seams");
}
