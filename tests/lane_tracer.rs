//! The CPU's lane path tracer (`render/lanes`) against its reference, the one-path-at-a-time
//! tracer (`render/path`): the same image bit for bit, with every lane set this processor
//! runs and each walk of the rays after the camera's (bundles, one ray at a time, measured), on every shipped scene and on the golden scenes (area lights, glass, smooth and rough
//! mirrors, textures, an emissive texture, an environment map), and on sample counts and row
//! widths that leave batches and bundles part full.

mod common;

use std::path::{Path, PathBuf};
use strahl_core::accel::bundle::Isa;
use strahl_core::cpu::{self, PathTracer};
use strahl_core::image::Region;
use strahl_core::render::Prepared;
use strahl_core::render::lanes::Walk;
use strahl_core::scene::{RenderMode, Scene};

fn prepared(path: &Path) -> Prepared {
    Prepared::new(Scene::load(path).unwrap_or_else(|e| panic!("{}: {e}", path.display())))
}

/// Renders `prep` in path mode at `w`×`h`, `spp` samples from sample `base`, with `tracer`;
/// the pixels' bits.
fn bits(prep: &Prepared, w: u32, h: u32, spp: u32, base: u32, tracer: PathTracer) -> Vec<[u32; 3]> {
    let mut frame = prep.frame(w, h);
    frame.spp = spp;
    frame.sample_base = base;
    frame.seed = 7;
    let img = cpu::render_region_with(prep, &frame, RenderMode::Path, Region::whole(w, h), tracer, &|_| {});
    img.pixels.iter().map(|p| p.map(f32::to_bits)).collect()
}

/// Every lane set gives the one-by-one image, bit for bit; returns the pixels compared.
fn check(name: &str, prep: &Prepared, w: u32, h: u32, spp: u32, base: u32) -> usize {
    let want = bits(prep, w, h, spp, base, PathTracer::OneByOne);
    for isa in Isa::available() {
        for tracer in [
            PathTracer::Lanes(isa),
            PathTracer::LanesWalking(isa, Walk::Bundles),
            PathTracer::LanesWalking(isa, Walk::OneRay),
        ] {
            let got = bits(prep, w, h, spp, base, tracer);
            let differ = want.iter().zip(&got).filter(|(a, b)| a != b).count();
            assert_eq!(differ, 0, "{name} ({w}x{h}, {spp} spp from {base}): {differ} pixels differ with {tracer:?}");
        }
    }
    // The image is not black: the comparison judged light transport.
    let lit = want.iter().filter(|p| p.iter().any(|&c| f32::from_bits(c) > 0.0)).count();
    assert!(lit * 4 > want.len(), "{name}: only {lit} of {} pixels lit", want.len());
    want.len()
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

#[test]
fn lanes_equal_the_one_by_one_tracer_on_the_shipped_scenes() {
    let mut pixels = 0;
    for path in common::shipped_scenes() {
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
