//! BVH build time and nearest-hit traversal speed on the bumpy torus of the Embree anchor
//! (`shared/anchors/embree_bench.py`): the same generator, the same sizes (250 × 200 quads =
//! 100k triangles, 1000 × 500 = 1M) and the same two ray sets.
//!
//! `cargo bench --bench bvh_build`. Groups:
//! - `bvh_build/{100k,1M}`: `Bvh::build` alone (rayon over all cores), mesh already flattened;
//!   throughput in triangles.
//! - `trace/*`: `traverse::nearest` in f32 on the 100k mesh, 100k rays per iteration;
//!   throughput in rays. `random` rays start on a sphere around the mesh and aim at random
//!   points of its box (incoherent), `camera` rays are pinhole primary rays (coherent);
//!   `1thread` is one core (compare with Embree's 1-thread column), `rayon` uses all cores.

use criterion::{Criterion, SamplingMode, Throughput, criterion_group, criterion_main};
use rayon::prelude::*;
use std::hint::black_box;
use std::time::Duration;
use strahl::accel::{Bvh, traverse};
use strahl::geometry::Triangle;
use strahl::math::{Ray, V3};
use strahl::primitives::{Primitives, Tag, Tagged};
use strahl::rng::SplitMix64;
use strahl::scene::mesh::bumpy_torus;

const RAYS: usize = 100_000;

/// The bumpy torus of nu × nv quads (2·nu·nv triangles) as f32 primitives.
fn torus(nu: usize, nv: usize) -> Primitives<f32> {
    let (verts, faces) = bumpy_torus(nu, nv, 2.0, 0.8);
    let triangles = faces
        .iter()
        .enumerate()
        .map(|(i, f)| Tagged {
            shape: Triangle { v: f.map(|k| verts[k as usize]) }.cast(),
            tag: Tag { object: 0, prim: i as u32, material: 0 },
        })
        .collect();
    Primitives { triangles, ..Primitives::default() }
}

/// Bounds of every triangle vertex, in f64.
fn bounds(prims: &Primitives<f32>) -> (V3<f64>, V3<f64>) {
    let mut lo = V3::splat(f64::INFINITY);
    let mut hi = V3::splat(f64::NEG_INFINITY);
    for t in &prims.triangles {
        for v in t.shape.v {
            lo = lo.min_elem(v.to_f64());
            hi = hi.max_elem(v.to_f64());
        }
    }
    (lo, hi)
}

/// The f32 ray strahl would trace: origin rounded, direction rounded and renormalised.
fn ray_f32(o: V3<f64>, d: V3<f64>) -> Ray<f32> {
    Ray::new(o.cast(), d.normalize().cast::<f32>().normalize())
}

/// embree_bench.py's `random_rays`: origins on a sphere of radius 1.5·|box diagonal| around
/// the box centre, aimed at uniform points of the box.
fn random_rays(n: usize, (lo, hi): (V3<f64>, V3<f64>)) -> Vec<Ray<f32>> {
    let mut rng = SplitMix64(1);
    let c = (lo + hi) * 0.5;
    let rad = 1.5 * (hi - lo).length();
    (0..n)
        .map(|_| {
            let o = c + rng.direction() * rad;
            let e = hi - lo;
            let t = lo + V3::new(e.x * rng.unit(), e.y * rng.unit(), e.z * rng.unit());
            ray_f32(o, t - o)
        })
        .collect()
}

/// embree_bench.py's `camera_rays`: a pinhole at c + (0.3, 0.8, −1)·|diagonal| looking at the
/// box centre, 30° vertical field of view, a w × h grid of pixel centres (w·h ≤ n).
fn camera_rays(n: usize, (lo, hi): (V3<f64>, V3<f64>)) -> Vec<Ray<f32>> {
    let c = (lo + hi) * 0.5;
    let ext = (hi - lo).length();
    let w = ((n * 4 / 3) as f64).sqrt() as usize;
    let h = n / w;
    let eye = c + V3::new(0.3, 0.8, -1.0) * ext;
    let fwd = (c - eye).normalize();
    let right = V3::new(0.0, 1.0, 0.0).cross(fwd).normalize();
    let up = fwd.cross(right);
    let tanh = 15f64.to_radians().tan();
    let mut rays = Vec::with_capacity(w * h);
    for y in 0..h {
        for x in 0..w {
            let u = ((x as f64 + 0.5) / w as f64 * 2.0 - 1.0) * tanh;
            let v = ((y as f64 + 0.5) / h as f64 * 2.0 - 1.0) * tanh * h as f64 / w as f64;
            rays.push(ray_f32(eye, fwd + right * u + up * v));
        }
    }
    rays
}

fn count_hits(bvh: &Bvh, prims: &Primitives<f32>, rays: &[Ray<f32>]) -> usize {
    rays.iter().filter(|r| traverse::nearest(bvh, prims, r, 0.0, f32::INFINITY).is_some()).count()
}

fn bvh_build(c: &mut Criterion) {
    let mut g = c.benchmark_group("bvh_build");
    // One build per sample: the 1M build takes about a second.
    g.sampling_mode(SamplingMode::Flat)
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(3));
    for (name, nu, nv) in [("100k", 250, 200), ("1M", 1000, 500)] {
        let prims = torus(nu, nv);
        g.throughput(Throughput::Elements(prims.triangles.len() as u64));
        g.bench_function(name, |b| b.iter(|| Bvh::build(black_box(&prims))));
    }
    g.finish();
}

fn trace(c: &mut Criterion) {
    let prims = torus(250, 200);
    let bvh = Bvh::build(&prims);
    let bb = bounds(&prims);
    let sets = [("random", random_rays(RAYS, bb)), ("camera", camera_rays(RAYS, bb))];
    for (name, rays) in &sets {
        let hits = count_hits(&bvh, &prims, rays);
        eprintln!(
            "trace/{name}: {} rays, {:.1}% hit; BVH {} nodes, depth {}",
            rays.len(),
            100.0 * hits as f64 / rays.len() as f64,
            bvh.nodes.len(),
            bvh.depth
        );
    }
    let mut g = c.benchmark_group("trace");
    g.sampling_mode(SamplingMode::Flat)
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2));
    for (name, rays) in &sets {
        g.throughput(Throughput::Elements(rays.len() as u64));
        g.bench_function(format!("{name}/1thread"), |b| b.iter(|| count_hits(&bvh, &prims, black_box(rays))));
        g.bench_function(format!("{name}/rayon"), |b| {
            b.iter(|| black_box(rays).par_chunks(1024).map(|chunk| count_hits(&bvh, &prims, chunk)).sum::<usize>())
        });
    }
    g.finish();
}

criterion_group!(benches, bvh_build, trace);
criterion_main!(benches);
