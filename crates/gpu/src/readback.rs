//! Results read back from the device, blocking or not.
//!
//! Reading a result back waits for the GPU. A native program may block for it; a web page may
//! not (its GPU work completes only when control returns to the event loop), so each readback
//! has an async form and the blocking one is that form run to completion ([`block_on`]), which
//! in a browser is an error ([`GpuError::Blocking`]).

use super::{GpuContext, GpuError};
use std::future::Future;

/// Whether this build runs in a browser (wasm32, WebGPU): no blocking waits, no error scopes
/// waited for.
pub const IN_BROWSER: bool = cfg!(target_arch = "wasm32");

/// Runs `work`, a readback's async form, to completion on this thread: native programs only.
/// In a browser the GPU's answer arrives only after control returns to the event loop, so
/// this fails with [`GpuError::Blocking`] naming `what` instead of waiting forever.
pub fn block_on<T>(what: &'static str, work: impl Future<Output = Result<T, GpuError>>) -> Result<T, GpuError> {
    if IN_BROWSER {
        return Err(GpuError::Blocking(what));
    }
    pollster::block_on(work)
}

impl GpuContext {
    /// Copies the first `count` elements of `src`, an array of `T`, to the host (blocking: not
    /// in a browser, see [`GpuContext::read_pod_async`]). The bytes land in a `Vec<T>`,
    /// aligned for `T`; `count` may be 0.
    pub fn read_pod<T: bytemuck::Pod>(&self, src: &wgpu::Buffer, count: usize) -> Result<Vec<T>, GpuError> {
        block_on("reading back a result", self.read_pod_async(src, count))
    }

    /// [`GpuContext::read_pod`] without blocking.
    pub async fn read_pod_async<T: bytemuck::Pod>(&self, src: &wgpu::Buffer, count: usize) -> Result<Vec<T>, GpuError> {
        let bytes = self.read_buffer_async(src, (count * std::mem::size_of::<T>()) as u64).await?;
        Ok(bytemuck::pod_collect_to_vec(&bytes))
    }

    /// Copies `size` bytes of `src` to the host (blocking: not in a browser); nothing for
    /// `size` 0.
    pub fn read_buffer(&self, src: &wgpu::Buffer, size: u64) -> Result<Vec<u8>, GpuError> {
        block_on("reading back a result", self.read_buffer_async(src, size))
    }

    /// [`GpuContext::read_buffer`] without blocking: the copy is submitted, and the future
    /// completes when the buffer is mapped (natively during [`GpuContext::wait`], so at once).
    pub async fn read_buffer_async(&self, src: &wgpu::Buffer, size: u64) -> Result<Vec<u8>, GpuError> {
        if size == 0 {
            return Ok(Vec::new());
        }
        let staging = self.copy_for_reading(src, size)?;
        self.map_read(staging).await
    }

    /// Submits a copy of the first `size` bytes (not 0) of `src` into a new buffer the host can
    /// map ([`GpuContext::map_read`]): the copy sees the work submitted before it, whatever is
    /// submitted while the host waits.
    pub(crate) fn copy_for_reading(&self, src: &wgpu::Buffer, size: u64) -> Result<wgpu::Buffer, GpuError> {
        let staging = self.scoped("the readback buffer", || {
            self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("readback"),
                size,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        })?;
        let mut enc = self.device.create_command_encoder(&Default::default());
        enc.copy_buffer_to_buffer(src, 0, &staging, 0, size);
        self.submit("reading back a result", enc)?;
        Ok(staging)
    }

    /// The bytes of `staging`, a buffer of [`GpuContext::copy_for_reading`], once the GPU has
    /// written them.
    pub(crate) async fn map_read(&self, staging: wgpu::Buffer) -> Result<Vec<u8>, GpuError> {
        let slice = staging.slice(..);
        let (done, mapped) = futures_channel::oneshot::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = done.send(r);
        });
        self.wait()?;
        let result = mapped.await;
        // In a browser, errors of the work before arrive by now (GpuContext::scoped).
        self.faults.check()?;
        result
            .map_err(|_| GpuError::Wgpu("the buffer's mapping was dropped unanswered".into()))?
            .map_err(|e| GpuError::Wgpu(e.to_string()))?;
        let data = slice.get_mapped_range().map_err(|e| GpuError::Wgpu(e.to_string()))?.to_vec();
        staging.unmap();
        Ok(data)
    }
}
