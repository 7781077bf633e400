//! Closed meshes shot from inside (no ray may escape) and needle, sliver and degenerate
//! triangles (no false hits, no NaN).

use super::*;
use std::time::Instant;
use strahl_core::accel::Bvh;
use strahl_core::geometry::{Shape, Triangle};
use strahl_core::math::{Ray, V3};
use strahl_core::primitives::{Primitives, Tag, Tagged};
use strahl_core::query::RayQuery;
use strahl_cpu::accel::binary as traverse;
use strahl_gpu::{GpuError, trace};

/// A closed UV sphere: `nu` segments around, `nv` rings, single vertices at the poles.
pub fn uv_sphere(nu: usize, nv: usize, radius: f64, centre: V3<f64>) -> (Vec<V3<f64>>, Vec<[u32; 3]>) {
    let mut v = vec![centre + V3::new(0.0, radius, 0.0)];
    for j in 1..nv {
        let th = std::f64::consts::PI * j as f64 / nv as f64;
        for i in 0..nu {
            let ph = 2.0 * std::f64::consts::PI * i as f64 / nu as f64;
            v.push(centre + V3::new(th.sin() * ph.cos(), th.cos(), th.sin() * ph.sin()) * radius);
        }
    }
    v.push(centre - V3::new(0.0, radius, 0.0));
    let ring = |j: usize, i: usize| (1 + (j - 1) * nu + i % nu) as u32;
    let south = (v.len() - 1) as u32;
    let mut f = Vec::new();
    for i in 0..nu {
        f.push([0, ring(1, i + 1), ring(1, i)]);
        f.push([south, ring(nv - 1, i), ring(nv - 1, i + 1)]);
    }
    for j in 1..nv - 1 {
        for i in 0..nu {
            let (a, b, c, d) = (ring(j, i), ring(j, i + 1), ring(j + 1, i + 1), ring(j + 1, i));
            f.push([a, b, c]);
            f.push([a, c, d]);
        }
    }
    (v, f)
}

/// Closed meshes shot from inside at their vertices, edges and faces: no ray may escape.
/// The textbook variant (Möller–Trumbore) is judged on the triangles around the vertex or
/// edge aimed at, where the ray must cross the surface.
pub fn closed_mesh_leaks(total_rays: usize, opt: &Options, rng: &mut Rng) -> Result<Vec<Row>, GpuError> {
    let centre = V3::new(0.5, -0.25, 0.125);
    let meshes = [
        ("UV sphere", uv_sphere(96, 48, 1.0, centre)),
        ("torus", {
            let (v, f) = strahl_core::scene::mesh::bumpy_torus(160, 80, 2.0, 0.8);
            (v.into_iter().map(|p| p + centre).collect(), f)
        }),
    ];
    let mut rows: Vec<Row> = Vec::new();
    for (name, (verts, faces)) in &meshes {
        let mut prims = Primitives::<f32>::default();
        for (i, f) in faces.iter().enumerate() {
            let tri = Triangle { v: f.map(|k| verts[k as usize]) }.cast::<f32>();
            prims.triangles.push(Tagged { shape: tri, tag: Tag { object: 0, face: i as u32, material: 0 } });
        }
        let bvh = Bvh::build(&prims);
        let mut incident: Vec<Vec<u32>> = vec![Vec::new(); verts.len()];
        for (i, f) in faces.iter().enumerate() {
            for &k in f {
                incident[k as usize].push(i as u32);
            }
        }
        let buffers = match opt.gpu {
            Some(ctx) => Some(upload(ctx, &prims)?),
            None => None,
        };
        let per_mesh = total_rays / meshes.len();
        let mut escapes = [0usize; 3];
        let mut secs = [0f64; 3];
        let chunk = 1 << 20;
        let mut done = 0;
        while done < per_mesh {
            let n = chunk.min(per_mesh - done);
            done += n;
            let mut rays = Vec::with_capacity(n);
            let mut around = Vec::with_capacity(n);
            for i in 0..n {
                let origin = if *name == "torus" {
                    let a = rng.range(0.0, std::f64::consts::TAU);
                    centre + V3::new(2.0 * a.cos(), 0.0, 2.0 * a.sin()) + rng.cube(0.25)
                } else {
                    centre + rng.cube(0.5)
                };
                let f = faces[rng.next_u64() as usize % faces.len()];
                // The triangles hold these same casts, so the targets are exactly their corners.
                let vtx = f.map(|k| verts[k as usize].cast::<f32>());
                let (target, near): (V3<f32>, Vec<u32>) = match i % 5 {
                    0 | 1 => (vtx[0], incident[f[0] as usize].clone()),
                    2 | 3 => {
                        let s = if i % 10 < 5 { 0.5 } else { rng.unit() as f32 };
                        let e = vtx[0] + (vtx[1] - vtx[0]) * s;
                        let shared = incident[f[0] as usize]
                            .iter()
                            .filter(|t| incident[f[1] as usize].contains(t))
                            .copied()
                            .collect();
                        (e, shared)
                    }
                    _ => {
                        let (a, b) = (rng.unit() as f32, rng.unit() as f32);
                        let (a, b) = if a + b > 1.0 { (1.0 - a, 1.0 - b) } else { (a, b) };
                        (vtx[0] + (vtx[1] - vtx[0]) * a + (vtx[2] - vtx[0]) * b, Vec::new())
                    }
                };
                let o = origin.cast::<f32>();
                rays.push(Ray::new(o, (target - o).normalize()));
                around.push(near);
            }
            for (slot, variant) in [Variant::Cpu, Variant::Gpu, Variant::Textbook].into_iter().enumerate() {
                let start = Instant::now();
                match variant {
                    Variant::Cpu if opt.cpu => {
                        use rayon::prelude::*;
                        escapes[slot] += rays
                            .par_iter()
                            .filter(|r| traverse::nearest(&bvh, &prims, r, 0.0, f32::INFINITY).is_none())
                            .count();
                    }
                    Variant::Gpu => {
                        if let (Some(ctx), Some(b)) = (opt.gpu, &buffers) {
                            let qs: Vec<RayQuery> = rays.iter().map(query).collect();
                            escapes[slot] += trace::trace(ctx, b, &qs, false)?.iter().filter(|h| h.is_empty()).count();
                        }
                    }
                    Variant::Textbook if opt.cpu => {
                        for (r, near) in rays.iter().zip(&around) {
                            if !near.is_empty() {
                                let hit = near.iter().any(|&t| {
                                    textbook::triangle_hit(&prims.triangles[t as usize].shape, r, 0.0, f32::INFINITY)
                                        .is_some()
                                });
                                escapes[slot] += !hit as usize;
                            }
                        }
                    }
                    _ => {}
                }
                secs[slot] += start.elapsed().as_secs_f64();
            }
        }
        for (slot, variant) in [Variant::Cpu, Variant::Gpu, Variant::Textbook].into_iter().enumerate() {
            if !opt.variants().contains(&variant) {
                continue;
            }
            let rays = if variant == Variant::Textbook { per_mesh * 4 / 5 } else { per_mesh };
            rows.push(Row {
                case: format!("closed {name} ({} tris), rays from inside at vertices/edges", faces.len()),
                variant: Some(variant),
                rays,
                fails: escapes[slot],
                fail_kind: "escapes",
                ns_per_ray: secs[slot] * 1e9 / rays as f64,
                ..Row::default()
            });
        }
    }
    Ok(rows)
}

/// Needle, sliver and degenerate (collinear, repeated-vertex) triangles: rays at each. A hit
/// the oracle places clearly outside the triangle (or on a degenerate one) is false; no output
/// may be NaN.
pub fn thin_triangles(per_kind: usize, rays: usize, opt: &Options, rng: &mut Rng) -> Result<Vec<Row>, GpuError> {
    let mut prims = Primitives::<f32>::default();
    for k in 0..4 * per_kind {
        let g = V3::new((k % 32) as f64, ((k / 32) % 32) as f64, (k / 1024) as f64) * 100.0;
        let s = 10f64.powf(rng.range(-2.0, 1.0));
        let (a, b) = (rng.direction(), rng.direction());
        let v = match k % 4 {
            // Needle: two vertices 1e-5·s apart.
            0 => [g, g + a * (s * 1e-5), g + b * s],
            // Sliver: the third vertex 1e-6·s off the line of the other two.
            1 => {
                let off = rng.perpendicular(a) * (s * 1e-6);
                [g, g + a * s, g + a * (0.5 * s) + off]
            }
            // Exactly collinear in f32 (axis-aligned, representable).
            2 => [g, g + V3::new(1.0, 0.0, 0.0), g + V3::new(0.5, 0.0, 0.0)],
            // Repeated vertex.
            _ => [g, g + a * s, g + a * s],
        };
        let tri = Triangle { v }.cast::<f32>();
        prims.triangles.push(Tagged { shape: tri, tag: Tag { object: k as u32, face: 0, material: 0 } });
    }
    let mut ray_list = Vec::new();
    for t in &prims.triangles {
        let tri = t.shape.cast::<f64>();
        let (lo, hi) = tri.bounds().expect("triangles are bounded");
        let size = (hi - lo).length().max(1e-3);
        for _ in 0..rays {
            let target = lo + (hi - lo).mul_elem(V3::new(rng.unit(), rng.unit(), rng.unit())) + rng.cube(0.1 * size);
            let o = target + rng.direction() * (3.0 * size);
            ray_list.push((t.tag.object as usize, ray32(o, target - o)));
        }
    }
    let bvh = Bvh::build(&prims);
    let n = ray_list.len();
    let judge = |r: &Ray<f32>, k: usize, t: f32, normal: V3<f32>| -> (usize, usize) {
        if !t.is_finite() || !normal.is_finite() {
            return (1, 0);
        }
        let false_hit = match oracle::triangle(&prims.triangles[k].shape, r) {
            None => true,
            Some((_, margin, inside)) => !inside && margin > 1e-6,
        };
        (0, false_hit as usize)
    };
    each_variant(opt, |variant| {
        let (mut nan, mut false_hits) = (0, 0);
        let mut add = |(a, b): (usize, usize)| {
            nan += a;
            false_hits += b;
        };
        match variant {
            Variant::Cpu => {
                for (_, r) in &ray_list {
                    if let Some(h) = traverse::nearest(&bvh, &prims, r, 0.0, f32::INFINITY) {
                        add(judge(r, h.prim_ref.index(), h.t, h.normal));
                    }
                }
            }
            Variant::Gpu => {
                let ctx = opt.gpu.expect("gpu");
                let buffers = upload(ctx, &prims)?;
                let qs: Vec<RayQuery> = ray_list.iter().map(|(_, r)| query(r)).collect();
                for ((_, r), h) in ray_list.iter().zip(trace::trace(ctx, &buffers, &qs, false)?) {
                    if let Some(h) = h.first() {
                        add(judge(r, h.prim_ref.index(), h.t, h.normal));
                    }
                }
            }
            Variant::Textbook => {
                for (k, r) in &ray_list {
                    let tri = &prims.triangles[*k].shape;
                    if let Some(t) = textbook::triangle_hit(tri, r, 0.0, f32::INFINITY) {
                        add(judge(r, *k, t, tri.face_normal().normalize()));
                    }
                }
            }
        }
        Ok(Some(Row {
            case: format!("needle, sliver, degenerate triangles ({})", prims.triangles.len()),
            rays: n,
            fails: nan + false_hits,
            fail_kind: "NaN or false hits",
            ..Row::default()
        }))
    })
}
