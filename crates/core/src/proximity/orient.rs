//! Faces turned back to agree with their neighbours before the winding number is summed:
//! a scan, a CAD export or a game asset often has a few faces whose vertex order is reversed,
//! and each such face subtracts its solid angle where it should add it, so that points just
//! behind it read as outside. The faces of each mesh are walked breadth-first across the edges
//! that join exactly two faces, and a face whose shared edge runs the same way as its
//! neighbour's is marked reversed relative to it (libigl's `bfs_orient`, after Jacobson et al.
//! 2013, §4); each connected patch then keeps the orientation of most of its area, so a mesh
//! that is consistent already is left as it is. Vertices are matched by their exact
//! coordinates within one scene object, so that meshes split at seams (normals, UVs) are
//! joined again; edges shared by three faces or more join nothing.

use crate::math::{Real, V3};
use crate::primitives::Primitives;
use std::collections::VecDeque;

/// For each triangle of `prims.triangles`, whether the winding number counts it reversed.
pub fn reversed_faces<R: Real>(prims: &Primitives<R>) -> Vec<bool> {
    let tris = &prims.triangles;
    let n = tris.len();
    // Vertex ids: equal coordinates within one object share an id.
    let mut ids: fnv::FnvHashMap<(u32, [u64; 3]), u32> = fnv::FnvHashMap::default();
    let key = |object: u32, v: V3<R>| (object, [v.x, v.y, v.z].map(|c| c.to_f64().to_bits()));
    let corners: Vec<[u32; 3]> = tris
        .iter()
        .map(|t| {
            t.shape.v.map(|v| {
                let next = ids.len() as u32;
                *ids.entry(key(t.tag.object, v)).or_insert(next)
            })
        })
        .collect();
    drop(ids);
    // Every directed edge (a → b, a ≠ b) as (min·2³² + max, face, whether it runs min → max).
    let mut edges: Vec<(u64, u32, bool)> = Vec::with_capacity(3 * n);
    for (f, c) in corners.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (c[k], c[(k + 1) % 3]);
            if a != b {
                edges.push(((a.min(b) as u64) << 32 | a.max(b) as u64, f as u32, a < b));
            }
        }
    }
    edges.sort_unstable_by_key(|e| e.0);
    // Faces joined by an edge of exactly two faces, and whether the two run it the same way
    // (then one of them is reversed relative to the other), as lists per face.
    let mut links: Vec<(u32, u32, bool)> = Vec::new();
    let mut i = 0;
    while i < edges.len() {
        let mut j = i + 1;
        while j < edges.len() && edges[j].0 == edges[i].0 {
            j += 1;
        }
        if j - i == 2 && edges[i].1 != edges[i + 1].1 {
            let same = edges[i].2 == edges[i + 1].2;
            links.push((edges[i].1, edges[i + 1].1, same));
            links.push((edges[i + 1].1, edges[i].1, same));
        }
        i = j;
    }
    drop(edges);
    links.sort_unstable_by_key(|l| l.0);
    let mut start = vec![0usize; n + 1];
    for l in &links {
        start[l.0 as usize + 1] += 1;
    }
    for f in 0..n {
        start[f + 1] += start[f];
    }
    let area = |f: usize| {
        let v = tris[f].shape.v.map(|v| v.to_f64());
        (v[1] - v[0]).cross(v[2] - v[0]).length()
    };
    let mut reversed = vec![false; n];
    let mut seen = vec![false; n];
    let mut queue = VecDeque::new();
    let mut patch = Vec::new();
    for seed in 0..n {
        if seen[seed] {
            continue;
        }
        seen[seed] = true;
        queue.push_back(seed);
        patch.clear();
        while let Some(f) = queue.pop_front() {
            patch.push(f);
            for &(_, g, same) in &links[start[f]..start[f + 1]] {
                let g = g as usize;
                if !seen[g] {
                    seen[g] = true;
                    reversed[g] = reversed[f] ^ same;
                    queue.push_back(g);
                }
            }
        }
        let (mut flipped, mut total) = (0.0, 0.0);
        for &f in &patch {
            let a = area(f);
            total += a;
            if reversed[f] {
                flipped += a;
            }
        }
        if flipped > 0.5 * total {
            for &f in &patch {
                reversed[f] = !reversed[f];
            }
        }
    }
    reversed
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Triangle;
    use crate::primitives::{Tag, Tagged};

    /// An octahedron's eight faces, outward, as one object.
    fn octahedron() -> Primitives<f64> {
        let v = [
            V3::new(1.0, 0.0, 0.0),
            V3::new(-1.0, 0.0, 0.0),
            V3::new(0.0, 1.0, 0.0),
            V3::new(0.0, -1.0, 0.0),
            V3::new(0.0, 0.0, 1.0),
            V3::new(0.0, 0.0, -1.0),
        ];
        let faces = [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]];
        let mut p = Primitives::default();
        for (k, f) in faces.iter().enumerate() {
            let tag = Tag { object: 0, face: k as u32, material: 0 };
            p.triangles.push(Tagged { shape: Triangle { v: f.map(|i| v[i]) }, tag });
        }
        p
    }

    #[test]
    fn a_consistent_mesh_is_left_alone_and_flipped_faces_are_found() {
        let mut p = octahedron();
        assert_eq!(reversed_faces(&p), vec![false; 8]);
        for f in [1, 6] {
            p.triangles[f].shape.v.swap(1, 2);
        }
        let r = reversed_faces(&p);
        assert_eq!(r, (0..8).map(|f| f == 1 || f == 6).collect::<Vec<_>>());
        // Turned inside out but for the same two: the patch keeps the orientation of most of
        // its area, so the same two are the odd ones.
        for t in &mut p.triangles {
            t.shape.v.swap(1, 2);
        }
        assert_eq!(reversed_faces(&p), r);
    }

    #[test]
    fn objects_do_not_share_vertices() {
        let mut p = octahedron();
        let mut q = octahedron();
        for t in &mut q.triangles {
            t.tag.object = 1;
            t.shape.v.swap(1, 2);
        }
        p.triangles.extend(q.triangles);
        // Two patches, each consistent on its own: nothing is reversed.
        assert_eq!(reversed_faces(&p), vec![false; 16]);
    }
}
