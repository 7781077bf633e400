//! Closest-point queries on the GPU: for each query point the nearest point of the scene's
//! surfaces (`shaders/closest.wgsl`), in f32, in batches that fit the adapter's buffer limits
//! and dispatch size. The answers are those of [`strahl_core::accel::gpu_bvh::closest`], the
//! same walk on the CPU, up to the device's rounding of the same operations, and so those of
//! [`strahl_core::proximity::closest`].

use super::trace::{dispatch_query, rw_buffer};
use super::{CachedPipeline, GpuContext, GpuError, Program, SceneBuffers, block_on};
use bytemuck::{Pod, Zeroable};
use strahl_core::geometry::Part;
use strahl_core::geometry::closest::Foot;
use strahl_core::layout::FrameParams;
use strahl_core::math::V3;
use strahl_core::primitives::PrimRef;
use strahl_core::proximity::Closest;

/// Invocations of a closest-point workgroup (`CLOSEST_WORKGROUP` in `shaders/closest.wgsl`).
pub const WORKGROUP: u64 = 64;
/// The PrimRef of an answer without a primitive (an empty scene): `CLOSEST_NONE` in the shader.
pub const NONE: u32 = u32::MAX;

/// One answer as the shader writes it, 32 bytes (`ClosestPoint` in `shaders/closest.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuClosestPoint {
    /// The foot: the nearest surface point.
    pub point: [f32; 3],
    /// Its squared distance from the query point ([`Foot::dist2`]; a WGSL member may not end
    /// in a digit).
    pub dist_sq: f32,
    /// A triangle's barycentric (u, v) of the foot, 0 for other primitives.
    pub uv: [f32; 2],
    /// The [`PrimRef`] of the primitive, [`NONE`] for none.
    pub prim_ref: u32,
    /// The [`Part`] of its surface.
    pub part: u32,
}

/// A query point as the shader reads it (w unused).
fn to_gpu(p: &V3<f32>) -> [f32; 4] {
    [p.x, p.y, p.z, 0.0]
}

fn from_gpu(a: &GpuClosestPoint) -> Option<Closest<f32>> {
    if a.prim_ref == NONE {
        return None;
    }
    let part = match a.part {
        1 => Part::CapP1,
        2 => Part::CapP2,
        _ => Part::Surface,
    };
    let foot = Foot { point: V3::from_array(a.point), dist2: a.dist_sq, uv: a.uv, part };
    Some(Closest { prim_ref: PrimRef(a.prim_ref), foot })
}

const POINT_BYTES: u64 = std::mem::size_of::<[f32; 4]>() as u64;
const ANSWER_BYTES: u64 = std::mem::size_of::<GpuClosestPoint>() as u64;

/// The nearest surface point of `scene` to each of `points` (None for each where the scene
/// has no primitive; an empty Vec for no points), on the GPU.
pub fn closest(
    ctx: &GpuContext,
    scene: &SceneBuffers,
    points: &[V3<f32>],
) -> Result<Vec<Option<Closest<f32>>>, GpuError> {
    block_on("a closest-point query", closest_async(ctx, scene, points))
}

/// [`closest`] without blocking, as a web page queries.
pub async fn closest_async(
    ctx: &GpuContext,
    scene: &SceneBuffers,
    points: &[V3<f32>],
) -> Result<Vec<Option<Closest<f32>>>, GpuError> {
    if points.is_empty() {
        return Ok(Vec::new());
    }
    let pipeline = ctx.pipeline(Program::Closest, scene.key, "closest_points")?;
    // The program reads no frame fields, but the frame buffer must hold valid data.
    ctx.queue.write_buffer(&scene.frame, 0, bytemuck::bytes_of(&FrameParams::default()));
    // A batch's points and answers each fit one binding, and its workgroups one dimension.
    let max_batch = (ctx.max_binding_bytes() / ANSWER_BYTES.max(POINT_BYTES))
        .min(ctx.limits.max_compute_workgroups_per_dimension as u64 * WORKGROUP)
        .max(1) as usize;
    let mut out = Vec::with_capacity(points.len());
    for batch in points.chunks(max_batch) {
        let gpu_points: Vec<[f32; 4]> = batch.iter().map(to_gpu).collect();
        let n = batch.len() as u64;
        let point_buf = ctx.storage_buffer("query points", &gpu_points)?;
        let answer_buf = rw_buffer(ctx, "closest points", n * ANSWER_BYTES)?;
        dispatch(ctx, &pipeline, scene, &point_buf, &answer_buf, n)?;
        let answers: Vec<GpuClosestPoint> = ctx.read_pod_async(&answer_buf, n as usize).await?;
        out.extend(answers.iter().map(from_gpu));
    }
    Ok(out)
}

fn dispatch(
    ctx: &GpuContext,
    pipeline: &CachedPipeline,
    scene: &SceneBuffers,
    points: &wgpu::Buffer,
    answers: &wgpu::Buffer,
    n: u64,
) -> Result<(), GpuError> {
    let io = ctx.scoped("the closest-point bind group", || {
        ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("closest io"),
            layout: &ctx.closest_layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: points.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: answers.as_entire_binding() },
            ],
        })
    })?;
    dispatch_query(ctx, pipeline, scene, &io, n.div_ceil(WORKGROUP) as u32, "a closest-point query")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn answers_decode_to_their_closest_points() {
        let a = GpuClosestPoint { point: [1.0, 2.0, 3.0], dist_sq: 4.0, uv: [0.25, 0.5], prim_ref: 7, part: 2 };
        let c = from_gpu(&a).unwrap();
        assert_eq!((c.prim_ref, c.foot.part, c.foot.dist2, c.foot.uv), (PrimRef(7), Part::CapP2, 4.0, [0.25, 0.5]));
        assert_eq!(c.foot.point, V3::new(1.0, 2.0, 3.0));
        assert!(from_gpu(&GpuClosestPoint { prim_ref: NONE, ..a }).is_none());
        // The parts the shader writes are geometry::Part's numbers.
        assert_eq!((Part::Surface as u32, Part::CapP1 as u32, Part::CapP2 as u32), (0, 1, 2));
    }
}
