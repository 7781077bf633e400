//! What the tests of several crates share: the scenes shipped in the repository and small
//! images made in code. (Compiled into the library, where it costs nothing, so that every
//! crate's tests reach it.)

use std::path::PathBuf;

/// The repository's root (this crate is `crates/core` in it).
pub fn repo_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Every scene shipped in assets/scenes, sorted.
pub fn shipped_scenes() -> Vec<PathBuf> {
    let dir = repo_root().join("assets/scenes");
    let mut v: Vec<PathBuf> = std::fs::read_dir(&dir)
        .expect("assets/scenes")
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    v.sort();
    assert!(v.len() >= 8, "expected the shipped scenes in {}", dir.display());
    v
}

/// A PNG of `w` × `h` RGB codes given per texel (row 0 at the top).
pub fn png(w: u32, h: u32, f: impl Fn(u32, u32) -> [u8; 3]) -> Vec<u8> {
    let img = image::RgbImage::from_fn(w, h, |x, y| image::Rgb(f(x, y)));
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png).unwrap();
    out.into_inner()
}
