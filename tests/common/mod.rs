//! Shared helpers of the integration tests.
#![allow(dead_code)]

use std::path::PathBuf;
use strahl::backend::gpu::GpuContext;

/// The GPU context for GPU tests: lavapipe in CI. Without any Vulkan adapter the test fails
/// with the install hint, unless STRAHL_SKIP_GPU_TESTS=1 asks to skip (returns None).
pub fn gpu() -> Option<GpuContext> {
    match GpuContext::new() {
        Ok(ctx) => Some(ctx),
        Err(e) if std::env::var("STRAHL_SKIP_GPU_TESTS").is_ok_and(|v| v == "1") => {
            eprintln!("skipping a GPU test: {e}");
            None
        }
        Err(e) => panic!("{e} (set STRAHL_SKIP_GPU_TESTS=1 to skip GPU tests)"),
    }
}

/// Every scene shipped in assets/scenes, sorted.
pub fn shipped_scenes() -> Vec<PathBuf> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("assets/scenes");
    let mut v: Vec<PathBuf> = std::fs::read_dir(&dir)
        .expect("assets/scenes")
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    v.sort();
    assert!(v.len() >= 8, "expected the shipped scenes in {}", dir.display());
    v
}

/// SplitMix64: deterministic test randomness.
pub struct Rng(pub u64);
impl Rng {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }
}
