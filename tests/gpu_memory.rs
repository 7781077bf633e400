//! Resident memory stays flat over many GPU sample passes: the viewer and `strahl render`
//! run the same dispatches for hours. lavapipe 22.3 compiled a fresh copy of the shader at every
//! pipeline bind while per-dispatch parameters were a uniform buffer, and kept it: 1.4 MB per
//! sample pass of the seed scene (1.5 GB at 1024 passes of a 4×4 image).

mod common;

use std::path::Path;
use std::sync::Arc;
use strahl_core::render::Prepared;
use strahl_core::scene::{RenderMode, Scene};
use strahl_gpu::{PathAccumulator, SceneBuffers, render};

/// Resident set size of this process in KiB (Linux).
fn rss_kib() -> u64 {
    let status = std::fs::read_to_string("/proc/self/status").expect("/proc/self/status");
    let line = status.lines().find(|l| l.starts_with("VmRSS:")).expect("VmRSS line");
    line.split_whitespace().nth(1).and_then(|v| v.parse().ok()).expect("VmRSS value")
}

/// Growth allowed over the measured passes: allocator noise, not a per-pass leak (a leak of
/// 32 KiB per pass would exceed it).
const ALLOWED_GROWTH_KIB: u64 = 32 * 1024;

#[test]
fn memory_stays_flat_over_thousands_of_sample_passes() {
    let Some(ctx) = common::gpu() else { return };
    let ctx = Arc::new(ctx);
    let seed = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes/seed.toml");
    let prep = Prepared::new(Scene::load(&seed).unwrap());
    let frame = prep.frame(4, 4);

    // Progressive path tracing (the viewer's and converge's passes): 1024 passes measured
    // after a warm-up that compiles the pipeline and fills the allocators.
    let buffers = SceneBuffers::upload(&ctx, &prep.flat).unwrap();
    let mut p = PathAccumulator::new(ctx.clone(), buffers, frame).unwrap();
    p.add_samples(64).unwrap();
    let before = rss_kib();
    for _ in 0..16 {
        p.add_samples(64).unwrap();
    }
    let growth = rss_kib().saturating_sub(before);
    eprintln!("path, 1024 passes: resident memory grew by {growth} KiB");
    assert!(growth < ALLOWED_GROWTH_KIB, "1024 path passes grew resident memory by {growth} KiB");
    assert_eq!(p.image().unwrap().non_finite_count(), 0);

    // `strahl render` in Whitted mode: one sample pass per sample, with timestamp queries.
    let buffers = SceneBuffers::upload(&ctx, &prep.flat).unwrap();
    let whitted = |spp: u32| {
        let f = strahl_core::layout::FrameParams { spp, ..frame };
        render(&ctx, &buffers, &f, RenderMode::Whitted, buffers.key, &|_, _| {}).unwrap()
    };
    whitted(64);
    let before = rss_kib();
    let (_, stats) = whitted(1024);
    let growth = rss_kib().saturating_sub(before);
    eprintln!("whitted, {} passes: resident memory grew by {growth} KiB", stats.dispatches);
    assert_eq!(stats.dispatches, 1024);
    assert!(growth < ALLOWED_GROWTH_KIB, "1024 Whitted passes grew resident memory by {growth} KiB");
}
