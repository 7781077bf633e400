//! What a GPU render measured, and the timestamp queries that measure it.

use super::{FeatureKey, GpuContext, GpuError};
use std::time::Duration;

/// GPU time per kernel (entry point name), from timestamp queries.
pub type KernelTimes = Vec<(&'static str, Duration)>;

/// What a GPU render measured.
#[derive(Clone, Debug, Default)]
pub struct RenderStats {
    /// Wall time of the dispatches and readback.
    pub wall: Duration,
    /// Sum of per-dispatch GPU times from timestamp queries, if the adapter has them.
    pub gpu_time: Option<Duration>,
    /// The same sum per kernel (entry point), where the adapter has timestamp queries.
    pub kernel_times: KernelTimes,
    pub dispatches: u32,
    /// Time spent composing the shader and creating the pipeline (zero when it was cached).
    /// Drivers that compile at the first dispatch (lavapipe) do so in [`Self::first_pass`].
    pub compile_time: Duration,
    pub key: FeatureKey,
    /// Wall time from the start of the render to the completion of its first sample pass
    /// (of the first band). Drivers that compile at the first dispatch (lavapipe) compile here,
    /// and lavapipe's timestamp queries count that compile as GPU time.
    pub first_pass: Duration,
    /// Sample passes run (over all bands).
    pub passes: u32,
}

/// Timestamp queries around each dispatch of one submission.
pub struct Timer {
    set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    period_ns: f64,
}

impl Timer {
    pub fn new(ctx: &GpuContext, max_passes: u32) -> Self {
        let count = 2 * max_passes.max(1);
        Self {
            set: ctx.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("dispatch timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count,
            }),
            resolve: ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timestamps"),
                size: count as u64 * 8,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
            period_ns: ctx.queue.get_timestamp_period() as f64,
        }
    }

    pub fn writes(&self, pass: u32) -> wgpu::ComputePassTimestampWrites<'_> {
        wgpu::ComputePassTimestampWrites {
            query_set: &self.set,
            beginning_of_pass_write_index: Some(2 * pass),
            end_of_pass_write_index: Some(2 * pass + 1),
        }
    }

    pub fn resolve(&self, enc: &mut wgpu::CommandEncoder, passes: u32) {
        enc.resolve_query_set(&self.set, 0..2 * passes, &self.resolve, 0);
    }

    /// Nanoseconds of each of the `passes` dispatches just submitted (blocking).
    pub fn read_each(&self, ctx: &GpuContext, passes: u32) -> Result<Vec<f64>, GpuError> {
        super::block_on("reading timestamps", self.read_each_async(ctx, passes))
    }

    /// [`Timer::read_each`] without blocking.
    pub async fn read_each_async(&self, ctx: &GpuContext, passes: u32) -> Result<Vec<f64>, GpuError> {
        let ts: Vec<u64> = ctx.read_pod_async(&self.resolve, 2 * passes as usize).await?;
        Ok(ts.chunks(2).map(|p| p[1].saturating_sub(p[0]) as f64 * self.period_ns).collect())
    }

    /// Total nanoseconds of the `passes` dispatches just submitted (blocking).
    pub fn read(&self, ctx: &GpuContext, passes: u32) -> Result<f64, GpuError> {
        Ok(self.read_each(ctx, passes)?.iter().sum())
    }

    /// [`Timer::read`] without blocking.
    pub async fn read_async(&self, ctx: &GpuContext, passes: u32) -> Result<f64, GpuError> {
        Ok(self.read_each_async(ctx, passes).await?.iter().sum())
    }
}
