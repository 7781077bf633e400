//! BVH build time and nearest-hit traversal speed on the bumpy torus of the Embree anchor
//! (`embree_bench.py`, the Embree 4 comparison): the same generator, the same sizes (250 × 200 quads =
//! 100k triangles, 1000 × 500 = 1M) and the same two ray sets (`strahl_core::raysets`).
//!
//! `cargo bench --bench bvh_build`. Groups:
//! - `bvh_build/{100k,1M}`: `Bvh::build` and its collapse into the CPU's 8-wide tree
//!   (rayon over all cores), mesh already flattened; throughput in triangles.
//! - `trace/*`: nearest hits on the 100k mesh, 100k rays per iteration; throughput in rays.
//!   `random` rays start on a sphere around the mesh and aim at random points of its box
//!   (incoherent), `camera` rays are the anchor's pinhole primary rays (coherent);
//!   `1thread` traces one ray at a time on one core (compare with Embree's 1-thread column),
//!   `batch` is the batch query (`nearest_many`) on one core, `rayon` uses all cores.
//!
//! `strahl bench rays` measures the same against the anchor's own meshes in one run.

use criterion::{Criterion, SamplingMode, Throughput, criterion_group, criterion_main};
use rayon::prelude::*;
use std::hint::black_box;
use std::time::Duration;
use strahl_core::accel::Bvh;
use strahl_core::math::{Ray, V3};
use strahl_core::primitives::Primitives;
use strahl_core::raysets;
use strahl_core::scene::procedural::torus_scene;
use strahl_cpu::accel::{WideBvh, wide_traverse};

const RAYS: usize = 100_000;

fn torus(ntris: usize) -> Primitives<f32> {
    Primitives::from_scene(&torus_scene(ntris))
}

fn count_hits(w: &WideBvh, prims: &Primitives<f32>, rays: &[Ray<f32>]) -> usize {
    rays.iter().filter(|r| wide_traverse::nearest(w, prims, r, 0.0, f32::INFINITY).is_some()).count()
}

fn count_hits_batch(w: &WideBvh, prims: &Primitives<f32>, rays: &[Ray<f32>]) -> usize {
    let mut out = vec![None; rays.len()];
    wide_traverse::nearest_many(w, prims, rays, 0.0, f32::INFINITY, &mut out);
    out.iter().filter(|h| h.is_some()).count()
}

fn bvh_build(c: &mut Criterion) {
    let mut g = c.benchmark_group("bvh_build");
    // One build per sample: the 1M build takes a few tenths of a second.
    g.sampling_mode(SamplingMode::Flat)
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(3));
    for (name, ntris) in [("100k", 100_000), ("1M", 1_000_000)] {
        let prims = torus(ntris);
        g.throughput(Throughput::Elements(prims.triangles.len() as u64));
        g.bench_function(name, |b| {
            b.iter(|| {
                let bvh = Bvh::build(black_box(&prims));
                WideBvh::new(&bvh, &prims)
            })
        });
    }
    g.finish();
}

fn trace(c: &mut Criterion) {
    let scene = torus_scene(100_000);
    let prims = Primitives::<f32>::from_scene(&scene);
    let bvh = Bvh::build(&prims);
    let wide = WideBvh::new(&bvh, &prims);
    let (lo, hi) = (V3::from_array(bvh.nodes[0].bmin).to_f64(), V3::from_array(bvh.nodes[0].bmax).to_f64());
    let (w, h) = raysets::camera_size(RAYS as u64, 4.0 / 3.0);
    let sets =
        [("random", raysets::random_rays(RAYS, lo, hi, 1)), ("camera", raysets::camera_rays(&scene.camera, w, h))];
    for (name, rays) in &sets {
        let hits = count_hits(&wide, &prims, rays);
        assert_eq!(hits, count_hits_batch(&wide, &prims, rays));
        eprintln!(
            "trace/{name}: {} rays, {:.1}% hit; 8-wide tree of {} nodes, {:.1} bytes per triangle",
            rays.len(),
            100.0 * hits as f64 / rays.len() as f64,
            wide.node_count(),
            wide.bytes() as f64 / prims.triangles.len() as f64
        );
    }
    let mut g = c.benchmark_group("trace");
    g.sampling_mode(SamplingMode::Flat)
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2));
    for (name, rays) in &sets {
        g.throughput(Throughput::Elements(rays.len() as u64));
        g.bench_function(format!("{name}/1thread"), |b| b.iter(|| count_hits(&wide, &prims, black_box(rays))));
        g.bench_function(format!("{name}/batch"), |b| b.iter(|| count_hits_batch(&wide, &prims, black_box(rays))));
        g.bench_function(format!("{name}/rayon"), |b| {
            b.iter(|| {
                black_box(rays).par_chunks(1024).map(|chunk| count_hits_batch(&wide, &prims, chunk)).sum::<usize>()
            })
        });
    }
    g.finish();
}

criterion_group!(benches, bvh_build, trace);
criterion_main!(benches);
