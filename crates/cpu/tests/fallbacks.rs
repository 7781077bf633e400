//! The lane tracer counts the path vertices it leaves to the one-path code, and the count
//! names why: none on a scene every material of which the lanes shade, a material's own where
//! the lanes do not shade it, and every vertex where the scene has point lights.

use std::path::PathBuf;
use strahl_core::image::Region;
use strahl_core::render::Prepared;
use strahl_core::scene::{AlphaMode, RenderMode, Scene};
use strahl_cpu::{CpuScene, PathTracer, render_region_reported};

fn scene(path: &str) -> Scene {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    Scene::load(root.join(path)).unwrap()
}

fn fallbacks(scene: Scene) -> (strahl_cpu::lanes::Fallbacks, Option<String>) {
    let prep = Prepared::new(scene);
    let mut frame = prep.frame(48, 36);
    frame.spp = 2;
    let cpu = CpuScene::new(&prep);
    let whole = Region::whole(48, 36);
    let tracer = PathTracer::Lanes(strahl_cpu::accel::bundle::Isa::detect());
    let (_, report) = render_region_reported(&cpu, &frame, RenderMode::Path, whole, tracer, false, &|_| {});
    let line = report.fallbacks.summary(&prep.scene.materials);
    (report.fallbacks, line)
}

#[test]
fn vertices_shaded_one_path_at_a_time_are_counted_and_named() {
    let cornell = scene("tests/golden/cornell.toml");
    let (f, line) = fallbacks(cornell.clone());
    assert!(f.lanes > 0 && f.total() == 0 && line.is_none(), "{f:?}");

    // The red wall blended by alpha: the lanes leave its vertices to the one-path code.
    let mut blended = cornell;
    let red = blended.materials.iter().position(|m| m.name == "red").unwrap();
    blended.materials[red].alpha = 0.5;
    blended.materials[red].alpha_mode = AlphaMode::Blend;
    let (f, line) = fallbacks(blended);
    let line = line.expect("a summary line");
    assert!(f.materials[red] > 0 && f.total() == f.materials[red] && f.lanes > 0, "{f:?}");
    assert!(line.contains("of material 'red'") && line.contains("one path at a time"), "{line}");

    // Point lights: every vertex.
    let (f, line) = fallbacks(scene("assets/scenes/spheres.toml"));
    assert!(f.lanes == 0 && f.delta_lights > 0 && f.total() == f.delta_lights, "{f:?}");
    assert!(line.unwrap().contains("point or directional lights"));
}
