//! What the tests of several crates share: the scenes shipped in the repository, small
//! images made in code, and the χ² test of sampled directions against their density
//! ([`chi2_sphere`], which the BSDFs' tests run on the CPU and the GPU). (Compiled into the
//! library, where it costs nothing, so that every crate's tests reach it.)

mod chi2;

pub use chi2::{
    Chi2, MIN_EXPECTED, PHI_CELLS, SUB_PHI, SUB_THETA, THETA_CELLS, chi2_direction_count, chi2_directions, chi2_sphere,
    chi2_sphere_fn,
};
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

/// A torus about the z axis (ring radius `big`, tube radius `small`), `nu` quads around the
/// ring by `nv` around the tube, each cut into two triangles that face outward: its vertices
/// and faces.
pub fn torus_mesh(big: f64, small: f64, nu: usize, nv: usize) -> (Vec<crate::math::V3<f64>>, Vec<[usize; 3]>) {
    use std::f64::consts::TAU;
    let mut vertices = Vec::with_capacity(nu * nv);
    for i in 0..nu {
        let u = TAU * i as f64 / nu as f64;
        for j in 0..nv {
            let v = TAU * j as f64 / nv as f64;
            let rho = big + small * v.cos();
            vertices.push(crate::math::V3::new(rho * u.cos(), rho * u.sin(), small * v.sin()));
        }
    }
    let at = |i: usize, j: usize| (i % nu) * nv + j % nv;
    let mut faces = Vec::with_capacity(2 * nu * nv);
    for i in 0..nu {
        for j in 0..nv {
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            faces.push([a, b, c]);
            faces.push([a, c, d]);
        }
    }
    (vertices, faces)
}

/// [`torus_mesh`] as the primitives of one scene object.
pub fn torus_triangles(big: f64, small: f64, nu: usize, nv: usize) -> crate::primitives::Primitives<f64> {
    use crate::primitives::{Primitives, Tag, Tagged};
    let (v, faces) = torus_mesh(big, small, nu, nv);
    let mut p = Primitives::default();
    for (k, f) in faces.iter().enumerate() {
        let tag = Tag { object: 0, face: k as u32, material: 0 };
        p.triangles.push(Tagged { shape: crate::geometry::Triangle { v: f.map(|i| v[i]) }, tag });
    }
    p
}

/// The test of a table stored with the code: with `STRAHL_BLESS=1` the `computed` table is
/// written to `file` (relative to this crate's root) under the comment `header`, eight numbers
/// a row; else every entry of `stored` must equal `computed`'s bit for bit.
pub fn bless_or_check(stored: &[f32], computed: &[f32], file: &str, header: &str) {
    if std::env::var("STRAHL_BLESS").is_ok_and(|v| v == "1") {
        let rows: Vec<String> = computed
            .chunks(8)
            .map(|c| format!("    {},", c.iter().map(|v| format!("{v:?}")).collect::<Vec<_>>().join(", ")))
            .collect();
        let text = format!("// {header}\n[\n{}\n]\n", rows.join("\n"));
        std::fs::write(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(file), text).expect("writes the table");
        return;
    }
    assert_eq!(stored.len(), computed.len(), "{file}: the table's length changed; write it anew with STRAHL_BLESS=1");
    for (k, (&got, &want)) in stored.iter().zip(computed).enumerate() {
        assert_eq!(
            got.to_bits(),
            want.to_bits(),
            "{file}: entry {k}: stored {got}, integral {want}; write it anew with STRAHL_BLESS=1"
        );
    }
}
