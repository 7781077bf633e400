//! The denoiser on the GPU (`shaders/denoise.wgsl`; its CPU twin, and the method, in
//! [`strahl_core::denoise`]): prepare, [`ITERATIONS`] à-trous passes between two work buffers,
//! finish, in one submission.

use super::{GpuContext, GpuError, block_on};
use std::time::Duration;
use strahl_core::denoise::{Guides, ITERATIONS};
use strahl_core::image::Image;
use web_time::Instant;

use crate::pipelines::storage_entry;
use crate::shaders::DENOISE_WGSL;
use crate::shared::DENOISE_WORKGROUP as WORKGROUP;

/// The denoiser's pipelines on one device: build once, denoise as often as needed.
pub struct Denoiser {
    layout: wgpu::BindGroupLayout,
    prepare: wgpu::ComputePipeline,
    atrous: wgpu::ComputePipeline,
    finish: wgpu::ComputePipeline,
}

impl Denoiser {
    pub fn new(ctx: &GpuContext) -> Result<Self, GpuError> {
        let device = &ctx.device;
        let module = ctx.scoped("the denoiser's shader", || {
            device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("denoise"),
                source: wgpu::ShaderSource::Wgsl(crate::shared::substitute(DENOISE_WGSL).into()),
            })
        })?;
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("denoise"),
            entries: &[
                storage_entry(0, true),
                storage_entry(1, true),
                storage_entry(2, true),
                storage_entry(3, true),
                storage_entry(4, true),
                storage_entry(5, false),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("denoise"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = |entry: &'static str| {
            ctx.scoped(&format!("the denoiser's {entry} pipeline"), || {
                device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(entry),
                    layout: Some(&pipeline_layout),
                    module: &module,
                    entry_point: Some(entry),
                    compilation_options: Default::default(),
                    cache: None,
                })
            })
        };
        Ok(Self { prepare: pipeline("prepare")?, atrous: pipeline("atrous")?, finish: pipeline("finish")?, layout })
    }

    /// Denoises `img` with its guides; also returns the GPU work's wall time (upload to
    /// readback).
    pub fn denoise(&self, ctx: &GpuContext, img: &Image, guides: &Guides) -> Result<(Image, Duration), GpuError> {
        block_on("denoising", self.denoise_async(ctx, img, guides))
    }

    /// [`Denoiser::denoise`] without blocking, as a web page runs it.
    pub async fn denoise_async(
        &self,
        ctx: &GpuContext,
        img: &Image,
        guides: &Guides<'_>,
    ) -> Result<(Image, Duration), GpuError> {
        let start = Instant::now();
        let (w, h) = (img.width, img.height);
        let n = img.pixels.len();
        assert_eq!(guides.albedo.len(), n);
        assert_eq!(guides.normal.len(), n);
        let what = format!("the denoiser's {w}x{h} buffers");
        ctx.check_binding_size(&what, n as u64 * 16)?;
        let vec4 = |v: &[[f32; 3]]| -> Vec<[f32; 4]> { v.iter().map(|p| [p[0], p[1], p[2], 0.0]).collect() };
        let color = ctx.storage_buffer("denoise: colour", &vec4(&img.pixels))?;
        let albedo = ctx.storage_buffer("denoise: albedo", &vec4(guides.albedo))?;
        let normal = ctx.storage_buffer("denoise: normal", &vec4(guides.normal))?;
        let work = |label: &str| {
            ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: (n as u64 * 16).max(16),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            })
        };
        let (a, b) = (work("denoise: work a"), work("denoise: work b"));
        let group = |params: &wgpu::Buffer, src: &wgpu::Buffer, dst: &wgpu::Buffer| {
            let entries: Vec<wgpu::BindGroupEntry> = [params, &color, &albedo, &normal, src, dst]
                .iter()
                .enumerate()
                .map(|(i, buf)| wgpu::BindGroupEntry { binding: i as u32, resource: buf.as_entire_binding() })
                .collect();
            ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("denoise"),
                layout: &self.layout,
                entries: &entries,
            })
        };
        let params = |step: u32| ctx.storage_buffer("denoise: parameters", &[w, h, step, 0]);
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        let groups = (w.div_ceil(WORKGROUP), h.div_ceil(WORKGROUP));
        let mut dispatch = |pipeline: &wgpu::ComputePipeline, bind: &wgpu::BindGroup| {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, bind, &[]);
            pass.dispatch_workgroups(groups.0, groups.1, 1);
        };
        // prepare: → a; atrous k: a → b for even k, b → a for odd k; finish: the last → the other.
        dispatch(&self.prepare, &group(&params(0)?, &b, &a));
        for k in 0..ITERATIONS {
            let (src, dst) = if k.is_multiple_of(2) { (&a, &b) } else { (&b, &a) };
            dispatch(&self.atrous, &group(&params(1 << k)?, src, dst));
        }
        let (last, out) = if ITERATIONS.is_multiple_of(2) { (&a, &b) } else { (&b, &a) };
        dispatch(&self.finish, &group(&params(0)?, last, out));
        ctx.submit("denoising", enc)?;
        let px: Vec<[f32; 4]> = ctx.read_pod_async(out, n).await?;
        let pixels = px.iter().map(|p| [p[0], p[1], p[2]]).collect();
        Ok((Image { width: w, height: h, pixels }, start.elapsed()))
    }
}
