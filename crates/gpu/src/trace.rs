//! Ray queries on the GPU (`strahl trace --backend gpu`), in f32, in batches that fit the
//! adapter's buffer limits and dispatch size.

use super::{CachedPipeline, GpuContext, GpuError, Program, SceneBuffers, block_on};
use strahl_core::geometry::Part;
use strahl_core::layout::{FrameParams, GpuQueryHit, GpuQueryRay, QUERY_ENTER, QUERY_FOUND};
use strahl_core::math::V3;
use strahl_core::primitives::{Hit, PrimRef, Tag};
use strahl_core::query::RayQuery;

/// Invocations of a trace workgroup (`TRACE_WORKGROUP` in `shaders/trace.wgsl`).
pub const WORKGROUP: u64 = 64;
const HIT_BYTES: u64 = std::mem::size_of::<GpuQueryHit>() as u64;

fn to_gpu(q: &RayQuery) -> GpuQueryRay {
    let r = q.ray::<f32>();
    GpuQueryRay { origin: r.origin.to_array(), tmin: q.tmin as f32, dir: r.dir.to_array(), tmax: q.tmax as f32 }
}

fn from_gpu(h: &GpuQueryHit) -> Hit<f32> {
    let part = match (h.flags >> 8) & 0xff {
        1 => Part::CapP1,
        2 => Part::CapP2,
        _ => Part::Surface,
    };
    Hit {
        t: h.t,
        normal: V3::from_array(h.normal),
        prim_ref: PrimRef(h.prim_ref),
        part,
        // The material is not part of a query's answer.
        tag: Tag { object: h.object, face: h.face, material: 0 },
        enter: h.flags & QUERY_ENTER != 0,
    }
}

/// Answers `rays` on the GPU: per ray the nearest hit, or with `all` every hit sorted by t.
/// The same answers as `backend::cpu::trace::<f32>` (up to the GPU's float rounding).
pub fn trace(
    ctx: &GpuContext,
    scene: &SceneBuffers,
    rays: &[RayQuery],
    all: bool,
) -> Result<Vec<Vec<Hit<f32>>>, GpuError> {
    block_on("a ray query", trace_async(ctx, scene, rays, all))
}

/// [`trace`] without blocking, as a web page queries.
pub async fn trace_async(
    ctx: &GpuContext,
    scene: &SceneBuffers,
    rays: &[RayQuery],
    all: bool,
) -> Result<Vec<Vec<Hit<f32>>>, GpuError> {
    let key = scene.key;
    let entry = if all { "trace_count" } else { "trace_nearest" };
    let first = ctx.pipeline(Program::Trace, key, entry)?;
    let write_all = if all { Some(ctx.pipeline(Program::Trace, key, "trace_all")?) } else { None };
    // The trace program reads no frame fields, but the frame buffer must hold valid data.
    ctx.queue.write_buffer(&scene.frame, 0, bytemuck::bytes_of(&FrameParams::default()));
    let limit = ctx.max_binding_bytes();
    let max_batch =
        (limit / HIT_BYTES).min(ctx.limits.max_compute_workgroups_per_dimension as u64 * WORKGROUP).max(1) as usize;
    let mut out = Vec::with_capacity(rays.len());
    let mut pending: Vec<&[RayQuery]> = rays.chunks(max_batch).rev().collect();
    while let Some(batch) = pending.pop() {
        let gpu_rays: Vec<GpuQueryRay> = batch.iter().map(to_gpu).collect();
        let ray_buf = ctx.storage_buffer("query rays", &gpu_rays)?;
        let n = batch.len() as u64;
        if let Some(write_all) = &write_all {
            // Pass 1: count, then exclusive offsets on the host.
            let counts_buf = rw_buffer(ctx, "hit counts", n * 4)?;
            let dummy = rw_buffer(ctx, "no hits", HIT_BYTES)?;
            dispatch(ctx, &first, scene, &ray_buf, &dummy, &counts_buf, n)?;
            let counts: Vec<u32> = ctx.read_pod_async(&counts_buf, n as usize).await?;
            let total: u64 = counts.iter().map(|&c| c as u64).sum();
            if total * HIT_BYTES > limit {
                if batch.len() == 1 {
                    return Err(ctx.too_large("the hits of one ray", total * HIT_BYTES));
                }
                let (a, b) = batch.split_at(batch.len() / 2);
                pending.push(b);
                pending.push(a);
                continue;
            }
            let mut offsets = Vec::with_capacity(counts.len());
            let mut acc = 0u32;
            for &c in &counts {
                offsets.push(acc);
                acc += c;
            }
            ctx.queue.write_buffer(&counts_buf, 0, bytemuck::cast_slice(&offsets));
            let hits_buf = rw_buffer(ctx, "hits", (total * HIT_BYTES).max(HIT_BYTES))?;
            dispatch(ctx, write_all, scene, &ray_buf, &hits_buf, &counts_buf, n)?;
            let hits: Vec<GpuQueryHit> = ctx.read_pod_async(&hits_buf, total as usize).await?;
            for (i, &c) in counts.iter().enumerate() {
                let o = offsets[i] as usize;
                out.push(hits[o..o + c as usize].iter().map(from_gpu).collect());
            }
        } else {
            let hits_buf = rw_buffer(ctx, "hits", n * HIT_BYTES)?;
            let dummy = rw_buffer(ctx, "no offsets", 4)?;
            dispatch(ctx, &first, scene, &ray_buf, &hits_buf, &dummy, n)?;
            let hits: Vec<GpuQueryHit> = ctx.read_pod_async(&hits_buf, n as usize).await?;
            out.extend(hits.iter().map(|h| if h.flags & QUERY_FOUND != 0 { vec![from_gpu(h)] } else { Vec::new() }));
        }
    }
    Ok(out)
}

/// A storage buffer the shader writes and the host reads back, of `size` bytes, checked
/// against the binding limit before it is made (also the closest-point queries').
pub(crate) fn rw_buffer(ctx: &GpuContext, what: &str, size: u64) -> Result<wgpu::Buffer, GpuError> {
    ctx.check_binding_size(what, size)?;
    ctx.scoped(what, || {
        ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(what),
            size,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    })
}

fn dispatch(
    ctx: &GpuContext,
    pipeline: &CachedPipeline,
    scene: &SceneBuffers,
    rays: &wgpu::Buffer,
    hits: &wgpu::Buffer,
    offsets: &wgpu::Buffer,
    n: u64,
) -> Result<(), GpuError> {
    let io = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("trace io"),
        layout: &ctx.trace_layout,
        entries: &[
            wgpu::BindGroupEntry { binding: 0, resource: rays.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 1, resource: hits.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 2, resource: offsets.as_entire_binding() },
        ],
    });
    dispatch_query(ctx, pipeline, scene, &io, n.div_ceil(WORKGROUP) as u32, "a ray query")
}

/// Submits one dispatch of a query program: the scene's bind group, the query's own `io`
/// (group 1), `groups` workgroups; `what` names it in errors.
pub(crate) fn dispatch_query(
    ctx: &GpuContext,
    pipeline: &CachedPipeline,
    scene: &SceneBuffers,
    io: &wgpu::BindGroup,
    groups: u32,
    what: &str,
) -> Result<(), GpuError> {
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    {
        let mut pass = enc.begin_compute_pass(&Default::default());
        pass.set_pipeline(&pipeline.pipeline);
        pass.set_bind_group(0, &scene.bind_group(ctx, pipeline), &[]);
        pass.set_bind_group(1, io, &[]);
        pass.dispatch_workgroups(groups, 1, 1);
    }
    ctx.submit(what, enc).map(|_| ())
}

/// Spawned rays on the GPU, the twin of [`strahl_cpu::trace_spawn`]: per pair, the
/// first hit and the nearest hit of the ray spawned from it.
pub fn trace_spawn(
    ctx: &GpuContext,
    scene: &SceneBuffers,
    pairs: &[(strahl_core::math::Ray<f32>, V3<f32>)],
) -> Result<Vec<strahl_core::SpawnHits>, GpuError> {
    let pipe = ctx.pipeline(Program::Trace, scene.key, "trace_spawn")?;
    ctx.queue.write_buffer(&scene.frame, 0, bytemuck::bytes_of(&FrameParams::default()));
    let max_pairs = (ctx.max_binding_bytes() / (2 * HIT_BYTES))
        .min(ctx.limits.max_compute_workgroups_per_dimension as u64 * WORKGROUP)
        .max(1) as usize;
    let mut out = Vec::with_capacity(pairs.len());
    for batch in pairs.chunks(max_pairs) {
        let rays: Vec<GpuQueryRay> = batch
            .iter()
            .flat_map(|(r, d2)| {
                [
                    GpuQueryRay { origin: r.origin.to_array(), tmin: 0.0, dir: r.dir.to_array(), tmax: f32::INFINITY },
                    GpuQueryRay { origin: [0.0; 3], tmin: 0.0, dir: d2.to_array(), tmax: f32::INFINITY },
                ]
            })
            .collect();
        let n = 2 * batch.len() as u64;
        let ray_buf = ctx.storage_buffer("spawn rays", &rays)?;
        let hits_buf = rw_buffer(ctx, "spawn hits", n * HIT_BYTES)?;
        let dummy = rw_buffer(ctx, "no offsets", 4)?;
        dispatch(ctx, &pipe, scene, &ray_buf, &hits_buf, &dummy, batch.len() as u64)?;
        let hits: Vec<GpuQueryHit> = ctx.read_pod(&hits_buf, n as usize)?;
        let get = |h: &GpuQueryHit| (h.flags & QUERY_FOUND != 0).then(|| from_gpu(h));
        out.extend(hits.chunks(2).map(|p| (get(&p[0]), get(&p[1]))));
    }
    Ok(out)
}
