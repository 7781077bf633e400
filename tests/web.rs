//! strahl's web page (crates/web, built by tools/build-web): its render path natively, and
//! the page itself in headless Chromium's WebGPU (SwiftShader, through tools/browser/page.js)
//! against the CPU reference, within the GPU-vs-CPU tolerance of tests/gpu_vs_cpu.rs.

mod common;

use common::{cpu_path_image, gpu, same_hit, shipped_scenes, skip, test_rays};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use strahl_core::image::Image;
use strahl_core::math::V3;
use strahl_core::primitives::Hit;
use strahl_core::render::Prepared;
use strahl_core::scene::{RenderMode, Scene};
use strahl_web::session::{self, Loaded, Options, Request};

/// The CPU reference image of `request` on `prep`: Whitted by `cpu::render`, path tracing by
/// the CPU's accumulator, the same samples as the GPU's.
fn cpu_image(prep: &Arc<Prepared>, request: &Request) -> Image {
    let frame = request.frame(prep, None);
    match request.mode {
        RenderMode::Whitted => {
            strahl_cpu::render(&strahl_cpu::CpuScene::new(prep), &frame, RenderMode::Whitted, &|_| {})
        }
        RenderMode::Path => cpu_path_image(prep, frame, request.spp),
    }
}

/// At least `min_within` of the pixels within one 8-bit code per channel of the reference,
/// and a mean FLIP below 0.005: the GPU-vs-CPU tolerance (0.999 for Whitted images, 0.99 for
/// path-traced ones, where a sample's path can branch differently on a rounding).
fn assert_close(what: &str, want: &[u8], got: &[u8], width: u32, height: u32, min_within: f64) {
    assert_eq!(want.len(), got.len(), "{what}: sizes");
    let n = want.len() / 3;
    let within = want.chunks(3).zip(got.chunks(3)).filter(|(a, b)| a.iter().zip(*b).all(|(x, y)| x.abs_diff(*y) <= 1));
    let within = within.count() as f64 / n as f64;
    let flip = {
        let r = nv_flip::FlipImageRgb8::with_data(width, height, want);
        let t = nv_flip::FlipImageRgb8::with_data(width, height, got);
        nv_flip::FlipPool::from_image(&nv_flip::flip(r, t, nv_flip::DEFAULT_PIXELS_PER_DEGREE)).mean()
    };
    eprintln!("{what}: {:.4} % within one code, mean FLIP {flip:.5}", within * 100.0);
    assert!(within >= min_within && flip < 0.005, "{what}: {within} within one code, mean FLIP {flip}");
}

fn min_within(mode: RenderMode) -> f64 {
    match mode {
        RenderMode::Whitted => 0.999,
        RenderMode::Path => 0.99,
    }
}

fn asset(path: &str) -> Vec<u8> {
    std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join("assets").join(path)).unwrap()
}

/// The seed scene as a page loads it: from its bytes as `scenes/seed.toml`, its mesh held as
/// `meshes/bumpy_torus.obj` (which it names as ../meshes/bumpy_torus.obj).
fn seed_as_a_page_loads_it(ctx: &strahl_gpu::GpuContext) -> Loaded {
    strahl_core::input::hold_file(Path::new("meshes/bumpy_torus.obj"), asset("meshes/bumpy_torus.obj"));
    let loaded = Loaded::new(ctx, "scenes/seed.toml", &asset("scenes/seed.toml"));
    strahl_core::input::release_files();
    loaded.unwrap()
}

/// The page's render path (a scene from a file's bytes, a request as a script passes it, the
/// async render and readback) run natively: the seed scene as the CPU renders it.
#[test]
fn the_pages_render_path_matches_the_cpu_natively() {
    let Some(ctx) = gpu() else { return };
    let loaded = seed_as_a_page_loads_it(&ctx);
    assert_eq!(
        loaded.prep.prims.triangles.len(),
        Prepared::new(Scene::load(Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes/seed.toml")).unwrap())
            .prims
            .triangles
            .len()
    );
    for (mode, spp) in [("whitted", None), ("path", Some(4.0))] {
        let o = Options {
            mode: Some(mode.into()),
            spp,
            width: Some(160.0),
            height: Some(120.0),
            seed: Some(3.0),
            ..Default::default()
        };
        let request = Request::new(&loaded.prep.scene, &o).unwrap();
        let got = pollster::block_on(session::render(&ctx, &loaded, &request, None)).unwrap();
        assert_eq!(got.non_finite_count(), 0);
        let want = cpu_image(&loaded.prep, &request);
        let rgb = |i: &Image| i.to_srgb8();
        assert_close(&format!("seed.toml, {mode}"), &rgb(&want), &rgb(&got), 160, 120, min_within(request.mode));
        // The bytes a script gets are the PNG's pixels with alpha.
        let rgba = session::rgba8(&got);
        assert!(rgba.chunks(4).zip(rgb(&got).chunks(3)).all(|(a, b)| a[..3] == *b && a[3] == 255));
    }
}

/// Bad input through the page's interface is an error naming it, as on the command line.
#[test]
fn the_page_names_bad_files_and_options() {
    let Some(ctx) = gpu() else { return };
    let e = Loaded::new(
        &ctx,
        "seed.toml",
        b"[camera]\neye = [0, 0]\nlook_at = [0, 0, 1]\nup = [0, 1, 0]\nfov_y = 45\n[image]\nwidth = 8\nheight = 8\n",
    )
    .err()
    .unwrap();
    assert!(e.starts_with("seed.toml:2:") && e.contains("eye"), "{e}");
    let e = Loaded::new(&ctx, "model.glb", b"glTF\x02\0\0\0").err().unwrap();
    assert!(e.contains("model.glb"), "{e}");
    // The seed scene without its mesh: the error names the file it lacks.
    let e = Loaded::new(&ctx, "scenes/seed.toml", &asset("scenes/seed.toml")).err().unwrap();
    assert!(e.contains("../meshes/bumpy_torus.obj"), "{e}");
    let loaded = seed_as_a_page_loads_it(&ctx);
    let o = Options { spp: Some(-3.0), ..Default::default() };
    assert!(Request::new(&loaded.prep.scene, &o).unwrap_err().starts_with("spp: -3 is not an integer"));
}

/// The hits per ray of page.js's columns (`session::Hits`).
fn hits_of(c: &serde_json::Value) -> Vec<Vec<strahl_core::primitives::Hit<f32>>> {
    use strahl_core::primitives::{Hit, PrimRef, Tag};
    let col = |k: &str| -> Vec<f64> { c[k].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect() };
    let (splits, t, object, face, prim, enter, normal) =
        (col("ray_splits"), col("t"), col("object"), col("face"), col("primitive"), col("enter"), col("normal"));
    splits
        .windows(2)
        .map(|w| {
            (w[0] as usize..w[1] as usize)
                .map(|k| Hit {
                    t: t[k] as f32,
                    normal: strahl_core::math::V3::new(
                        normal[3 * k] as f32,
                        normal[3 * k + 1] as f32,
                        normal[3 * k + 2] as f32,
                    ),
                    prim_ref: PrimRef(prim[k] as u32),
                    part: strahl_core::geometry::Part::Surface,
                    tag: Tag { object: object[k] as u32, face: face[k] as u32, material: 0 },
                    enter: enter[k] != 0.0,
                })
                .collect()
        })
        .collect()
}

/// The built page (STRAHL_WEB_DIR, default target/web) and what drives it, or why not.
fn page_tools() -> Result<(PathBuf, PathBuf), String> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = std::env::var_os("STRAHL_WEB_DIR").map_or_else(|| root.join("target/web"), PathBuf::from);
    if !dir.join("index.html").is_file() || !dir.join("pkg/strahl_web_bg.wasm").is_file() {
        return Err(format!("no web page in {}: build it with tools/build-web {}", dir.display(), dir.display()));
    }
    let package = root.join("tools/browser");
    if !package.join("node_modules/playwright-core").is_dir() {
        return Err(format!("playwright-core is not installed: npm ci in {}", package.display()));
    }
    if std::process::Command::new("node").arg("--version").output().is_err() {
        return Err("no node".into());
    }
    let chromium = std::env::var_os("CHROMIUM").map_or_else(|| PathBuf::from("/usr/bin/chromium"), PathBuf::from);
    if !chromium.is_file() {
        return Err(format!("no Chromium at {} (Debian: apt-get install chromium)", chromium.display()));
    }
    Ok((dir, package.join("page.js")))
}

/// One job for page.js: a render or a ray query of a scene's text.
enum Job {
    Render(Options),
    Trace { rays: Vec<strahl_core::query::RayQuery>, all: bool, check: Check },
}

/// How a ray query's answers must match the CPU's, as in tests/gpu_vs_cpu.rs.
#[derive(Clone, Copy)]
enum Check {
    /// The same hits but for 0.1 % of the rays (within a rounding of an edge).
    Agree,
    /// The same rows bit for bit: t, object, face, normal, side.
    Exact,
    /// At most one row of the seed floor (object 4) per ray, and as many as the CPU's: rays
    /// at the edge its two triangles share.
    OneFloorRow,
}

/// In headless Chromium, through `window.strahl.render` and `window.strahl.trace`, what
/// tests/gpu_vs_cpu.rs runs natively: every shipped scene rendered in Whitted mode, and its ray
/// queries (4000 camera and random rays, nearest and every hit), the seed scene path traced at
/// a fixed seed, and the ray-query edge cases (below), each within the GPU-vs-CPU tolerance of
/// the CPU's answer to the same file and options.
#[test]
fn the_page_in_chromium_renders_and_traces_as_the_cpu_does() {
    let (dir, script) = match page_tools() {
        Ok(t) => t,
        Err(why) => return skip(&why),
    };
    // Each scene as the page serves it (tools/build-web copies assets/scenes and assets/meshes),
    // fetched there with the meshes it names, as the view loads a URL.
    let mut jobs = Vec::new();
    for path in shipped_scenes() {
        let name = path.file_name().unwrap().to_str().unwrap().to_string();
        jobs.push((name.clone(), Job::Render(Options { mode: Some("whitted".into()), ..Default::default() })));
        if name == "seed.toml" {
            let o = Options { mode: Some("path".into()), spp: Some(4.0), seed: Some(11.0), ..Default::default() };
            jobs.push((name.clone(), Job::Render(o)));
        }
        let rays = test_rays(&Prepared::new(Scene::load(&path).unwrap()), 4000, 17);
        for all in [false, true] {
            jobs.push((name.clone(), Job::Trace { rays: rays.clone(), all, check: Check::Agree }));
        }
    }
    // tests/gpu_vs_cpu.rs's edge cases: the lecture's worked example; a ray from 1e38 away
    // through spheres without a BVH (the lecture) and with one (the seed scene); no rays, and
    // rays that hit nothing; 20000 rays at the seed floor's shared diagonal.
    let ray = |o: [f64; 3], d: [f64; 3]| strahl_core::query::RayQuery {
        origin: V3::from_array(o),
        dir: V3::from_array(d),
        tmin: 0.0,
        tmax: f64::INFINITY,
    };
    let exact = |name: &str, rays: Vec<_>| {
        [false, true].map(|all| (name.to_string(), Job::Trace { rays: rays.clone(), all, check: Check::Exact }))
    };
    jobs.extend(exact("lecture.toml", vec![ray([0.0; 3], [0.0, 0.0, 1.0])]));
    for name in ["lecture.toml", "seed.toml"] {
        jobs.extend(exact(name, vec![ray([1e38, 0.0, 8.0], [-1.0, 0.0, 0.0])]));
    }
    jobs.extend(exact("lecture.toml", Vec::new()));
    jobs.extend(exact("lecture.toml", vec![ray([0.0, 20.0, 0.0], [0.0, 0.0, 1.0]); 2]));
    let edge_rays = common::shared_edge_rays(20_000, 5);
    jobs.push(("seed.toml".into(), Job::Trace { rays: edge_rays, all: true, check: Check::OneFloorRow }));
    let json: Vec<serde_json::Value> = jobs
        .iter()
        .enumerate()
        .map(|(i, (name, job))| {
            let url = format!("scenes/{name}");
            match job {
                Job::Render(o) => serde_json::json!({
                    "name": format!("job{i}"),
                    "url": url,
                    "opts": { "mode": o.mode, "spp": o.spp, "seed": o.seed },
                }),
                Job::Trace { rays, all, .. } => {
                    // serde_json writes an infinite tmax as null, which page.js reads as Infinity.
                    let numbers: Vec<f64> = rays
                        .iter()
                        .flat_map(|r| [r.origin.x, r.origin.y, r.origin.z, r.dir.x, r.dir.y, r.dir.z, r.tmin, r.tmax])
                        .collect();
                    serde_json::json!({ "name": format!("job{i}"), "url": url, "rays": numbers, "opts": { "all": all } })
                }
            }
        })
        .collect();
    let work = tempfile::tempdir().unwrap();
    let jobs_file = work.path().join("jobs.json");
    std::fs::write(&jobs_file, serde_json::to_string(&json).unwrap()).unwrap();
    let out = std::process::Command::new("node")
        .arg(&script)
        .args(["render".as_ref(), dir.as_os_str(), jobs_file.as_os_str(), work.path().as_os_str()])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "page.js failed ({}): {stderr}", out.status);
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    eprintln!("browser {}, adapter {}, page errors {}", report["browser"], report["adapter"], report["pageErrors"]);
    assert_eq!(report["pageErrors"].as_array().map(Vec::len), Some(0), "{report}");
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes");
    for (i, (name, job)) in jobs.iter().enumerate() {
        let r = &report["jobs"][i];
        assert!(r["error"].is_null(), "{name}: {}", r["error"]);
        let scene = Scene::load(scenes.join(name)).unwrap();
        let o = match job {
            Job::Render(o) => o,
            Job::Trace { rays, all, check } => {
                let columns = std::fs::read_to_string(work.path().join(format!("job{i}.json"))).unwrap();
                let got = hits_of(&serde_json::from_str(&columns).unwrap());
                let want = strahl_cpu::trace::<f32>(&scene, rays, *all);
                assert_eq!(got.len(), want.len(), "{name}: rays answered");
                match check {
                    Check::Agree => {}
                    Check::Exact => {
                        let rows = |h: &[Hit<f32>]| -> Vec<_> {
                            h.iter().map(|h| (h.t, h.tag.object, h.tag.face, h.normal.to_array(), h.enter)).collect()
                        };
                        for (k, (w, g)) in want.iter().zip(&got).enumerate() {
                            assert_eq!(rows(g), rows(w), "{name}, ray {k} (all: {all}): {:?}", rays[k]);
                        }
                        eprintln!("{name}: {} rays answered bit for bit (all: {all})", rays.len());
                        continue;
                    }
                    Check::OneFloorRow => {
                        let floor_rows = |h: &[Hit<f32>]| h.iter().filter(|h| h.tag.object == 4).count();
                        for (k, (w, g)) in want.iter().zip(&got).enumerate() {
                            let (nw, ng) = (floor_rows(w), floor_rows(g));
                            assert!(
                                nw <= 1 && ng == nw,
                                "ray {k} {:?}: {nw} floor rows on the cpu, {ng} in Chromium",
                                rays[k]
                            );
                        }
                        let hits: usize = got.iter().map(|g| floor_rows(g)).sum();
                        eprintln!("{name}: {} rays at the shared edge, {hits} floor rows, never two", rays.len());
                        continue;
                    }
                }
                let disagree = want
                    .iter()
                    .zip(&got)
                    .filter(|(w, g)| w.len() != g.len() || !w.iter().zip(g.iter()).all(|(a, b)| same_hit(a, b)))
                    .count();
                let hits: usize = want.iter().map(Vec::len).sum();
                eprintln!("{name}: {hits} hits (all: {all}), {disagree} rays disagree, {} ms", r["ms"]);
                // As in tests/gpu_vs_cpu.rs: rays within a rounding of an edge may differ.
                assert!(
                    disagree <= rays.len() / 1000,
                    "{name} (all: {all}): {disagree} of {} rays disagree",
                    rays.len()
                );
                continue;
            }
        };
        let prep = Arc::new(Prepared::new(scene));
        let request = Request::new(&prep.scene, o).unwrap();
        let (w, h) = (request.width, request.height);
        assert_eq!((r["width"].as_u64(), r["height"].as_u64()), (Some(w as u64), Some(h as u64)), "{name}");
        let rgba = std::fs::read(work.path().join(format!("job{i}.rgba"))).unwrap();
        assert_eq!(rgba.len(), (w * h * 4) as usize, "{name}");
        assert!(rgba.chunks(4).all(|p| p[3] == 255), "{name}: alpha");
        let got: Vec<u8> = rgba.chunks(4).flat_map(|p| [p[0], p[1], p[2]]).collect();
        let want = cpu_image(&prep, &request).to_srgb8();
        eprintln!("{name}: {} ms in the browser", r["ms"]);
        assert_close(&format!("{name} in Chromium"), &want, &got, w, h, min_within(request.mode));
    }
}
