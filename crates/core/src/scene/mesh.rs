//! Triangle meshes: OBJ loading (through `tobj`), placement transforms, and the seed
//! scene's procedural bumpy torus.

use crate::geometry::Triangle;
use crate::math::V3;
use std::io::{BufReader, Write};
use std::path::Path;

/// The most triangles one mesh file may hold.
pub const MAX_MESH_TRIANGLES: usize = 16_000_000;
/// Largest mesh file read (16 million triangles with their vertices take about 700 MB of
/// OBJ text; texture and normal indices add more).
pub const MAX_MESH_FILE_BYTES: u64 = 2 << 30;

/// Placement of a mesh: scale, then rotate about X, then Y, then Z (degrees, right-handed),
/// then translate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transform {
    pub translate: [f64; 3],
    pub scale: [f64; 3],
    pub rotate_deg: [f64; 3],
}

impl Default for Transform {
    fn default() -> Self {
        Self { translate: [0.0; 3], scale: [1.0; 3], rotate_deg: [0.0; 3] }
    }
}

impl Transform {
    pub fn apply(&self, p: V3<f64>) -> V3<f64> {
        let [sx, sy, sz] = self.scale;
        let (mut x, mut y, mut z) = (p.x * sx, p.y * sy, p.z * sz);
        let [rx, ry, rz] = self.rotate_deg;
        if rx != 0.0 {
            let (s, c) = rx.to_radians().sin_cos();
            (y, z) = (c * y - s * z, s * y + c * z);
        }
        if ry != 0.0 {
            let (s, c) = ry.to_radians().sin_cos();
            (x, z) = (c * x + s * z, -s * x + c * z);
        }
        if rz != 0.0 {
            let (s, c) = rz.to_radians().sin_cos();
            (x, y) = (c * x - s * y, s * x + c * y);
        }
        let [tx, ty, tz] = self.translate;
        V3::new(x + tx, y + ty, z + tz)
    }

    /// A normal carried by the transform: scaled by the inverse of the scale (the inverse
    /// transpose of the linear part), rotated as points are, normalised. Zero stays zero.
    pub fn apply_normal(&self, n: V3<f64>) -> V3<f64> {
        let [sx, sy, sz] = self.scale;
        let p = Transform { translate: [0.0; 3], scale: [1.0 / sx, 1.0 / sy, 1.0 / sz], ..*self }.apply(n);
        let l = p.length();
        if l > 0.0 && l.is_finite() { p / l } else { V3::zero() }
    }

    /// Whether the transform mirrors space (an odd number of negative scale factors), which
    /// reverses the winding of every triangle.
    pub fn mirrors(&self) -> bool {
        self.scale[0] * self.scale[1] * self.scale[2] < 0.0
    }
}

/// Triangles the faces of an OBJ text fan into, counted from its `f` lines alone, up to the
/// first count above `limit` (then the file is refused without being parsed).
fn face_triangles(text: &str, limit: usize) -> usize {
    let mut count = 0usize;
    for line in text.lines() {
        let mut words = line.split_whitespace();
        if words.next() == Some("f") {
            count += words.count().saturating_sub(2);
            if count > limit {
                break;
            }
        }
    }
    count
}

/// Loads every face of every model in an OBJ file as triangles (polygons are fanned by
/// tobj), placed by `transform`; at most `limit` (≤ [`MAX_MESH_TRIANGLES`]) triangles, checked
/// before the file is parsed. A mirroring transform (negative scale product) swaps each
/// triangle's last two vertices so front faces stay front faces.
pub fn load_obj(path: &Path, transform: &Transform, limit: usize) -> Result<Vec<Triangle<f64>>, String> {
    load_obj_with_uvs(path, transform, limit).map(|(t, _)| t)
}

/// Triangles and what the file gives at their vertices (texture coordinates, normals).
pub type TexturedTriangles = (Vec<Triangle<f64>>, crate::scene::MeshAttributes);

/// [`load_obj`] with the texture coordinates (`vt`) of each triangle's vertices, in the order
/// of its vertices, flipped to strahl's convention (v = 0 is the top row of an image; OBJ's
/// v = 0 is the bottom row). Empty when the file has no `vt` for some face.
pub fn load_obj_with_uvs(path: &Path, transform: &Transform, limit: usize) -> Result<TexturedTriangles, String> {
    let limit = limit.min(MAX_MESH_TRIANGLES);
    let text = crate::input::read_text(path, MAX_MESH_FILE_BYTES).map_err(|e| match e {
        crate::input::ReadError::Io(e) => format!("cannot open: {e}"),
        e => format!("cannot read: {e}"),
    })?;
    if face_triangles(&text, limit) > limit {
        return Err(format!("more than {limit} triangles, the most accepted here"));
    }
    let mut reader = BufReader::new(text.as_bytes());
    // The struct update keeps this compiling if tobj's optional fields are switched on.
    #[allow(clippy::needless_update)]
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: false,
        ignore_points: true,
        ignore_lines: true,
        ..Default::default()
    };
    // Materials are not ours to read: refuse every mtllib instead of opening it. tobj indexes
    // with unchecked arithmetic in a few places (overflowing relative indices), so a panic in
    // it is turned into an error too.
    let loaded = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        tobj::load_obj_buf(&mut reader, &options, |_| Err(tobj::LoadError::OpenFileFailed))
    }));
    let models = match loaded {
        Ok(Ok((models, _materials))) => models,
        Ok(Err(e)) => return Err(format!("OBJ parse error: {e}")),
        Err(_) => return Err("OBJ parse error: malformed file".into()),
    };

    let mut count: usize = 0;
    for m in &models {
        if m.mesh.indices.len() % 3 != 0 {
            return Err(format!("model {:?}: face index count is not a multiple of 3", m.name));
        }
        count = count.saturating_add(m.mesh.indices.len() / 3);
    }
    if count == 0 {
        return Err("no faces".into());
    }
    if count > limit {
        return Err(format!("{count} triangles exceed the limit of {limit}"));
    }

    let mirror = transform.mirrors();
    // Texture coordinates and normals only when every face has them.
    let with_uvs = models.iter().all(|m| m.mesh.texcoord_indices.len() == m.mesh.indices.len());
    let with_normals = models.iter().all(|m| m.mesh.normal_indices.len() == m.mesh.indices.len());
    let mut tris = Vec::with_capacity(count);
    let mut attrs = crate::scene::MeshAttributes::default();
    attrs.uvs.reserve(if with_uvs { count } else { 0 });
    attrs.normals.reserve(if with_normals { count } else { 0 });
    for m in &models {
        let pos = &m.mesh.positions;
        let nverts = pos.len() / 3;
        let mut placed = Vec::with_capacity(nverts);
        for i in 0..nverts {
            let p = V3::new(pos[3 * i] as f64, pos[3 * i + 1] as f64, pos[3 * i + 2] as f64);
            if !p.is_finite() {
                return Err(format!("vertex {} is not finite: ({}, {}, {})", i + 1, p.x, p.y, p.z));
            }
            let q = transform.apply(p);
            if !q.is_finite() {
                return Err(format!("vertex {} is not finite after the transform", i + 1));
            }
            placed.push(q);
        }
        let tc = &m.mesh.texcoords;
        for (k, f) in m.mesh.indices.chunks_exact(3).enumerate() {
            let mut v = [V3::zero(); 3];
            for (j, &ix) in f.iter().enumerate() {
                v[j] = *placed
                    .get(ix as usize)
                    .ok_or_else(|| format!("face vertex index {} out of range (1..={nverts})", ix as u64 + 1))?;
            }
            let mut uv = [[0.0f32; 2]; 3];
            if with_uvs {
                for (j, &ix) in m.mesh.texcoord_indices[3 * k..3 * k + 3].iter().enumerate() {
                    let ix = ix as usize;
                    if 2 * ix + 1 >= tc.len() {
                        return Err(format!("face texture index {} out of range (1..={})", ix + 1, tc.len() / 2));
                    }
                    let (u, w) = (tc[2 * ix], tc[2 * ix + 1]);
                    if !(u.is_finite() && w.is_finite()) {
                        return Err(format!("texture coordinate {} is not finite", ix + 1));
                    }
                    uv[j] = [u, 1.0 - w];
                }
            }
            let mut ns = [[0.0f32; 3]; 3];
            if with_normals {
                let vn = &m.mesh.normals;
                for (j, &ix) in m.mesh.normal_indices[3 * k..3 * k + 3].iter().enumerate() {
                    let ix = ix as usize;
                    if 3 * ix + 2 >= vn.len() {
                        return Err(format!("face normal index {} out of range (1..={})", ix + 1, vn.len() / 3));
                    }
                    let n = V3::new(vn[3 * ix] as f64, vn[3 * ix + 1] as f64, vn[3 * ix + 2] as f64);
                    if !n.is_finite() {
                        return Err(format!("normal {} is not finite", ix + 1));
                    }
                    // A zero normal stays zero: shading falls back to the face's normal there.
                    ns[j] = transform.apply_normal(n).cast::<f32>().to_array();
                }
            }
            if mirror {
                v.swap(1, 2);
                uv.swap(1, 2);
                ns.swap(1, 2);
            }
            tris.push(Triangle { v });
            if with_uvs {
                attrs.uvs.push(uv);
            }
            if with_normals {
                attrs.normals.push(ns);
            }
        }
    }
    Ok((tris, attrs))
}

/// The seed scene's bumpy torus, mirroring `torus_mesh()` of the Mitsuba anchor script:
/// nu × nv vertices, vertex (i, j) at index i·nv + j with u = 2πi/nu around the ring and
/// v = 2πj/nv around the tube, tube radius r·(1 + 0.08 sin 12u sin 8v); 2·nu·nv faces, first
/// all [a, c, b], then all [a, d, c], wound so (v1 − v0) × (v2 − v0) points outward.
pub fn bumpy_torus(nu: usize, nv: usize, major: f64, minor: f64) -> (Vec<V3<f64>>, Vec<[u32; 3]>) {
    use std::f64::consts::TAU;
    let (du, dv) = (TAU / nu as f64, TAU / nv as f64);
    let mut verts = Vec::with_capacity(nu * nv);
    for i in 0..nu {
        let u = i as f64 * du;
        for j in 0..nv {
            let v = j as f64 * dv;
            let rr = minor * (1.0 + 0.08 * (12.0 * u).sin() * (8.0 * v).sin());
            let ring = major + rr * v.cos();
            verts.push(V3::new(ring * u.cos(), rr * v.sin(), ring * u.sin()));
        }
    }
    let idx = |i: usize, j: usize| (i * nv + j) as u32;
    let quad = |i: usize, j: usize| {
        let (i1, j1) = ((i + 1) % nu, (j + 1) % nv);
        (idx(i, j), idx(i1, j), idx(i1, j1), idx(i, j1))
    };
    let mut faces = Vec::with_capacity(2 * nu * nv);
    for i in 0..nu {
        for j in 0..nv {
            let (a, b, c, _) = quad(i, j);
            faces.push([a, c, b]);
        }
    }
    for i in 0..nu {
        for j in 0..nv {
            let (a, _, c, d) = quad(i, j);
            faces.push([a, d, c]);
        }
    }
    (verts, faces)
}

/// Writes vertices and 0-based faces as an OBJ file (1-based indices); floats are written
/// with Rust's shortest round-trip formatting.
pub fn write_obj(w: &mut impl Write, vertices: &[V3<f64>], faces: &[[u32; 3]]) -> std::io::Result<()> {
    for v in vertices {
        writeln!(w, "v {} {} {}", v.x, v.y, v.z)?;
    }
    for f in faces {
        writeln!(w, "f {} {} {}", f[0] as u64 + 1, f[1] as u64 + 1, f[2] as u64 + 1)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: V3<f64>, b: V3<f64>) -> bool {
        (a - b).length() < 1e-12
    }

    #[test]
    fn transform_order_is_scale_rotate_xyz_translate() {
        let t = Transform { translate: [1.0, 2.0, 3.0], scale: [2.0, 1.0, 1.0], rotate_deg: [0.0, 0.0, 90.0] };
        // (1,0,0) → scale (2,0,0) → rot Z 90° (0,2,0) → translate (1,4,3).
        assert!(close(t.apply(V3::new(1.0, 0.0, 0.0)), V3::new(1.0, 4.0, 3.0)));
        let rx = Transform { rotate_deg: [90.0, 0.0, 0.0], ..Default::default() };
        assert!(close(rx.apply(V3::new(0.0, 1.0, 0.0)), V3::new(0.0, 0.0, 1.0)));
        let ry = Transform { rotate_deg: [0.0, 90.0, 0.0], ..Default::default() };
        assert!(close(ry.apply(V3::new(0.0, 0.0, 1.0)), V3::new(1.0, 0.0, 0.0)));
        // X first, then Y: (0,1,0) → X 90° → (0,0,1) → Y 90° → (1,0,0).
        let xy = Transform { rotate_deg: [90.0, 90.0, 0.0], ..Default::default() };
        assert!(close(xy.apply(V3::new(0.0, 1.0, 0.0)), V3::new(1.0, 0.0, 0.0)));
        assert_eq!(Transform::default().apply(V3::new(1.5, -2.0, 3.0)), V3::new(1.5, -2.0, 3.0));
    }

    #[test]
    fn torus_matches_the_anchor_script_and_faces_outward() {
        let (nu, nv) = (25, 20);
        let (v, f) = bumpy_torus(nu, nv, 2.0, 0.8);
        assert_eq!(v.len(), nu * nv);
        assert_eq!(f.len(), 2 * nu * nv);
        // Vertex (i=0, j=0): u = v = 0 → (R + r, 0, 0).
        assert!(close(v[0], V3::new(2.8, 0.0, 0.0)));
        // First face [a, c, b] for (0,0): a=0, c=1*nv+1, b=1*nv.
        assert_eq!(f[0], [0, nv as u32 + 1, nv as u32]);
        // First of the second half: [a, d, c] for (0,0).
        assert_eq!(f[nu * nv], [0, 1, nv as u32 + 1]);
        for t in &f {
            let p = [v[t[0] as usize], v[t[1] as usize], v[t[2] as usize]];
            let n = (p[1] - p[0]).cross(p[2] - p[0]);
            let c = (p[0] + p[1] + p[2]) / 3.0;
            let axis = V3::new(c.x, 0.0, c.z).normalize() * 2.0;
            assert!(n.dot(c - axis) > 0.0, "face {t:?} points inward");
        }
    }

    #[test]
    fn obj_round_trip() {
        let (v, f) = bumpy_torus(8, 6, 2.0, 0.8);
        let mut buf = Vec::new();
        write_obj(&mut buf, &v, &f).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.obj");
        std::fs::write(&path, &buf).unwrap();
        let t = Transform { translate: [1.0, 0.0, 0.0], ..Default::default() };
        let tris = load_obj(&path, &t, MAX_MESH_TRIANGLES).unwrap();
        assert_eq!(tris.len(), f.len());
        for (tri, face) in tris.iter().zip(&f) {
            for k in 0..3 {
                let want = t.apply(v[face[k] as usize]);
                assert!((tri.v[k] - want).length() < 1e-5, "{tri:?}");
            }
        }
    }

    #[test]
    fn mirroring_scale_keeps_fronts() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("tri.obj");
        std::fs::write(&path, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
        let t = Transform { scale: [-1.0, 1.0, 1.0], ..Default::default() };
        let tris = load_obj(&path, &t, MAX_MESH_TRIANGLES).unwrap();
        assert!(tris[0].face_normal().z > 0.0);
        // Quads are split into two triangles.
        std::fs::write(&path, "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n").unwrap();
        assert_eq!(load_obj(&path, &Transform::default(), MAX_MESH_TRIANGLES).unwrap().len(), 2);
    }

    /// `vn` normals follow their vertices, carried by the placement's inverse transpose (a
    /// scale stretches them the other way) and swapped with the vertices when it mirrors.
    #[test]
    fn normals_follow_their_vertices_and_the_inverse_transpose() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("vn.obj");
        std::fs::write(&path, "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nvn 1 0 1\nvn 0 1 0\nf 1//1 2//2 3//3\n").unwrap();
        let (_, a) = load_obj_with_uvs(&path, &Transform::default(), MAX_MESH_TRIANGLES).unwrap();
        let h = 0.5f32.sqrt();
        assert_eq!(a.normals.len(), 1);
        for (got, want) in a.normals[0].iter().zip([[0.0, 0.0, 1.0], [h, 0.0, h], [0.0, 1.0, 0.0]]) {
            assert!(got.iter().zip(want).all(|(g, w)| (g - w).abs() < 1e-6), "{got:?} vs {want:?}");
        }
        // Scaling x by 2 halves the normal's x before normalising; mirroring (x by -2) also
        // swaps the last two vertices' normals with their vertices.
        let t = Transform { scale: [-2.0, 1.0, 1.0], ..Default::default() };
        let (_, a) = load_obj_with_uvs(&path, &t, MAX_MESH_TRIANGLES).unwrap();
        let n = a.normals[0][2];
        let l = (0.25f32 + 1.0).sqrt();
        assert!((n[0] + 0.5 / l).abs() < 1e-6 && (n[2] - 1.0 / l).abs() < 1e-6, "{n:?}");
        assert_eq!(a.normals[0][1], [0.0, 1.0, 0.0]);
    }

    /// `vt` coordinates follow their vertices, flipped so v = 0 is an image's top row; a
    /// mirroring placement swaps them with the vertices.
    #[test]
    fn texture_coordinates_follow_their_vertices() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("uv.obj");
        std::fs::write(&path, "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 0.25\nf 1/1 2/2 3/3\n").unwrap();
        let uvs = load_obj_with_uvs(&path, &Transform::default(), MAX_MESH_TRIANGLES).unwrap().1.uvs;
        assert_eq!(uvs, vec![[[0.0, 1.0], [1.0, 1.0], [0.0, 0.75]]]);
        let t = Transform { scale: [-1.0, 1.0, 1.0], ..Default::default() };
        let (tris, attrs) = load_obj_with_uvs(&path, &t, MAX_MESH_TRIANGLES).unwrap();
        let uvs = attrs.uvs;
        assert_eq!(tris[0].v[1], V3::new(0.0, 1.0, 0.0));
        assert_eq!(uvs, vec![[[0.0, 1.0], [0.0, 0.75], [1.0, 1.0]]]);
        // Without vt on every face: none.
        std::fs::write(&path, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
        assert!(load_obj_with_uvs(&path, &Transform::default(), MAX_MESH_TRIANGLES).unwrap().1.uvs.is_empty());
    }

    #[test]
    fn bad_obj_files() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bad.obj");
        let err = |src: &str| {
            std::fs::write(&path, src).unwrap();
            load_obj(&path, &Transform::default(), MAX_MESH_TRIANGLES).unwrap_err()
        };
        assert!(err("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n").contains("out of"));
        assert!(err("v 0 0 0\nv 1 0 0\nv 0 1 0\n").contains("no faces"));
        assert!(err("v 0 0 x\nf 1 2 3\n").contains("parse"));
        assert!(err("v 0 0 inf\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").contains("not finite"));
        assert!(err("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -9223372036854775808\n").contains("OBJ"));
        assert!(err("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n").contains("out of"));
        // Counted from the face lines before parsing: a quad is two triangles.
        std::fs::write(&path, "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\nf 1 2 3\n").unwrap();
        let e = load_obj(&path, &Transform::default(), 2).unwrap_err();
        assert!(e.contains("more than 2 triangles"), "{e}");
        assert_eq!(load_obj(&path, &Transform::default(), 3).unwrap().len(), 3);
        assert!(err("\0").contains("not a text file"));
        let missing = dir.path().join("nope.obj");
        assert!(load_obj(&missing, &Transform::default(), MAX_MESH_TRIANGLES).unwrap_err().contains("cannot open"));
    }
}
