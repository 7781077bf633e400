//! The BSDF probe, a **test and diagnostic stage** that renders nothing
//! (`shaders/bsdf_probe.wgsl`): the shaders' own `bsdf_sample` and `bsdf_eval`
//! (`shaders/modules/bsdf.wgsl`) run on the materials of an uploaded scene, read by
//! `load_material` from its objects buffer as the path tracer reads them, for inputs the host
//! chooses. With it a test holds the device's BSDFs against their CPU twin
//! ([`strahl_core::render::bsdf`]), runs a white furnace on the device, and a χ² test of the
//! device's sampling against its own density ([`strahl_core::testutil::chi2_sphere`]).
//!
//! The program is composed ([`crate::shaders::compose_diagnostic`]) with the scene's key less
//! the flags that select no BSDF code ([`probe_key`]), so the material code a render of the
//! scene runs (MIRROR, DIELECTRIC, PBR, ROUGH_GLASS, ...) is on, and the probe binds only the
//! frame and the objects buffer of the scene's group 0. It is not a [`crate::Program`]: no
//! render uses it, and its pipelines are kept by the [`BsdfProbe`] rather than the context's
//! cache. Its results are read back blocking (not in a web page).

use crate::pipelines::storage_entry;
use crate::trace::{dispatch_query, rw_buffer};
use crate::{CachedPipeline, FeatureKey, GpuContext, GpuError, SceneBindings, SceneBuffers, shaders};
use bytemuck::{Pod, Zeroable};
use strahl_core::layout::FrameParams;
use strahl_core::math::V3;
use web_time::Instant;

/// Invocations of a probe workgroup (`PROBE_WORKGROUP` in `shaders/bsdf_probe.wgsl`).
pub const WORKGROUP: u32 = 64;

/// The flags the probe's key leaves out: those that add only primitives, lights, images,
/// alpha, emission, the device's 64-bit loads or split arrays, none of which the probe reads.
/// With them it would declare the bindings of group 0 they bring, as many as a render program
/// binds, and with its own two more than the 8 storage buffers WebGPU guarantees. Every other
/// flag, each that selects BSDF code among them (and any added later), is the scene's.
pub const NOT_READ: FeatureKey = FeatureKey::GEOMETRY
    .union(FeatureKey::POINT_LIGHTS)
    .union(FeatureKey::DIRECTIONAL_LIGHTS)
    .union(FeatureKey::EMISSIVE)
    .union(FeatureKey::TEXTURES)
    .union(FeatureKey::ENVIRONMENT)
    .union(FeatureKey::ENV_MAP)
    .union(FeatureKey::ALPHA);

/// The key the probe is composed with for a scene whose key is `key`.
pub fn probe_key(key: FeatureKey) -> FeatureKey {
    key - NOT_READ
}

/// One input as the shader reads it, 48 bytes (`ProbeInput` in `shaders/bsdf_probe.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuProbeInput {
    /// Towards the viewer, unit.
    pub wo: [f32; 3],
    /// The material's index in the scene.
    pub material: u32,
    /// The shading normal on `wo`'s side, unit.
    pub ns: [f32; 3],
    /// 1: `wo` lies on the front face's side.
    pub front: u32,
    /// Sampling: the three uniform numbers; evaluation: the direction wi.
    pub v: [f32; 3],
    pub _pad: u32,
}

/// One answer as the shader writes it, 64 bytes (`ProbeOutput`); flags are 0 or 1.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuProbeOutput {
    pub dir: [f32; 3],
    pub pdf: f32,
    pub weight: [f32; 3],
    pub valid: u32,
    pub f_cos: [f32; 3],
    pub eval_pdf: f32,
    pub density: f32,
    pub specular: u32,
    pub through: u32,
    pub _pad: u32,
}

/// Where a BSDF is probed: a material of the scene, the direction towards the viewer, the
/// shading normal on its side (both unit), and whether that is the front face's side (which
/// way a dielectric's index ratio goes).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProbePoint {
    pub material: u32,
    pub wo: V3<f32>,
    pub ns: V3<f32>,
    pub front: bool,
}

/// What the device's `bsdf_sample` chose at a [`ProbePoint`] for three uniform numbers, and
/// what `bsdf_eval` says of its direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProbeSample {
    /// false: the path would end here (the other fields are then 0).
    pub valid: bool,
    pub dir: V3<f32>,
    /// f·|cos θ_i| / pdf.
    pub weight: V3<f32>,
    /// The density `bsdf_sample` reports (0 for a specular choice).
    pub pdf: f32,
    pub specular: bool,
    /// Refracted through the surface.
    pub through: bool,
    /// `bsdf_eval`'s f·cos θ_i at `dir` (0 through the surface: it gives reflection only).
    pub f_cos: V3<f32>,
    /// `bsdf_eval`'s density at `dir`.
    pub eval_pdf: f32,
    /// The density of `dir` over the whole sphere ([`ProbeEval::density`]).
    pub density: f32,
}

/// What the device's `bsdf_eval` says of a direction wi at a [`ProbePoint`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProbeEval {
    /// f·cos θ_i: reflection only, as the path tracer's light samples use it.
    pub f_cos: V3<f32>,
    /// The density `bsdf_eval` gives (0 below the surface).
    pub pdf: f32,
    /// The density with which `bsdf_sample` chooses wi, on either side of the surface: `pdf`
    /// above it; below it the rough dielectric lobe's transmission weighed by the material's
    /// glass share (0 for materials that transmit nothing or only specularly).
    pub density: f32,
}

const INPUT_BYTES: u64 = std::mem::size_of::<GpuProbeInput>() as u64;
const OUTPUT_BYTES: u64 = std::mem::size_of::<GpuProbeOutput>() as u64;

/// The probe's two pipelines for one scene's key, and the layout of its inputs and outputs
/// (group 1).
pub struct BsdfProbe {
    sample: CachedPipeline,
    eval: CachedPipeline,
    io_layout: wgpu::BindGroupLayout,
}

impl BsdfProbe {
    /// Composes and compiles the probe for `scene` ([`probe_key`] of its key).
    pub fn new(ctx: &GpuContext, scene: &SceneBuffers) -> Result<Self, GpuError> {
        let start = Instant::now();
        let key = probe_key(scene.key);
        let module = shaders::compose_diagnostic(shaders::BSDF_PROBE, key)?;
        let scene_bindings: SceneBindings = shaders::group_bindings(&module, 0).into();
        let what = format!("the BSDF probe for {}", key.label());
        let shader = ctx.scoped(&what, || {
            ctx.device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("bsdf probe"),
                source: wgpu::ShaderSource::Naga(std::borrow::Cow::Owned(module)),
            })
        })?;
        let io_layout = ctx.scoped(&what, || {
            ctx.device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("bsdf probe io"),
                entries: &[storage_entry(0, true), storage_entry(1, false)],
            })
        })?;
        let scene_layout = ctx.scene_layout(&scene_bindings);
        let pipeline = |entry: &'static str| {
            let pipeline = ctx.compute_pipeline(
                &format!("the pipeline of {what}, {entry}"),
                &shader,
                entry,
                &scene_layout,
                &io_layout,
            )?;
            Ok::<_, GpuError>(CachedPipeline {
                pipeline,
                key,
                compile_time: start.elapsed(),
                scene_bindings: scene_bindings.clone(),
            })
        };
        let sample = pipeline("probe_sample")?;
        let eval = pipeline("probe_eval")?;
        Ok(Self { sample, eval, io_layout })
    }

    /// The key the probe was composed with ([`probe_key`]).
    pub fn key(&self) -> FeatureKey {
        self.sample.key
    }

    /// `bsdf_sample` at each point for its three uniform numbers, and `bsdf_eval` at the
    /// direction chosen, on the device; `scene` is the one the probe was made for.
    pub fn sample(
        &self,
        ctx: &GpuContext,
        scene: &SceneBuffers,
        inputs: &[(ProbePoint, [f32; 3])],
    ) -> Result<Vec<ProbeSample>, GpuError> {
        let gpu: Vec<GpuProbeInput> = inputs.iter().map(|(p, u)| to_gpu(p, *u)).collect();
        let out = self.run(ctx, scene, &self.sample, &gpu)?;
        Ok(out
            .iter()
            .map(|o| ProbeSample {
                valid: o.valid != 0,
                dir: V3::from_array(o.dir),
                weight: V3::from_array(o.weight),
                pdf: o.pdf,
                specular: o.specular != 0,
                through: o.through != 0,
                f_cos: V3::from_array(o.f_cos),
                eval_pdf: o.eval_pdf,
                density: o.density,
            })
            .collect())
    }

    /// `bsdf_eval` at each point for its direction wi, and the density of wi over the whole
    /// sphere, on the device; `scene` is the one the probe was made for.
    pub fn eval(
        &self,
        ctx: &GpuContext,
        scene: &SceneBuffers,
        inputs: &[(ProbePoint, V3<f32>)],
    ) -> Result<Vec<ProbeEval>, GpuError> {
        let gpu: Vec<GpuProbeInput> = inputs.iter().map(|(p, wi)| to_gpu(p, wi.to_array())).collect();
        let out = self.run(ctx, scene, &self.eval, &gpu)?;
        Ok(out
            .iter()
            .map(|o| ProbeEval { f_cos: V3::from_array(o.f_cos), pdf: o.eval_pdf, density: o.density })
            .collect())
    }

    /// Runs `pipeline` over `inputs`, in batches whose inputs and outputs each fit one
    /// binding and whose workgroups fit one dimension.
    fn run(
        &self,
        ctx: &GpuContext,
        scene: &SceneBuffers,
        pipeline: &CachedPipeline,
        inputs: &[GpuProbeInput],
    ) -> Result<Vec<GpuProbeOutput>, GpuError> {
        if probe_key(scene.key) != pipeline.key {
            return Err(GpuError::Device(format!(
                "the BSDF probe compiled for {} cannot run on a scene of {}",
                pipeline.key.label(),
                scene.key.label()
            )));
        }
        // The program reads no frame fields, but the frame buffer must hold valid data.
        ctx.queue.write_buffer(&scene.frame, 0, bytemuck::bytes_of(&FrameParams::default()));
        let max_batch = (ctx.max_binding_bytes() / INPUT_BYTES.max(OUTPUT_BYTES))
            .min(ctx.limits.max_compute_workgroups_per_dimension as u64 * WORKGROUP as u64)
            .max(1) as usize;
        let mut out = Vec::with_capacity(inputs.len());
        for batch in inputs.chunks(max_batch) {
            let n = batch.len() as u64;
            let input_buf = ctx.storage_buffer("BSDF probe inputs", batch)?;
            let output_buf = rw_buffer(ctx, "BSDF probe outputs", n * OUTPUT_BYTES)?;
            let io = ctx.scoped("the BSDF probe's bind group", || {
                ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("bsdf probe io"),
                    layout: &self.io_layout,
                    entries: &[
                        wgpu::BindGroupEntry { binding: 0, resource: input_buf.as_entire_binding() },
                        wgpu::BindGroupEntry { binding: 1, resource: output_buf.as_entire_binding() },
                    ],
                })
            })?;
            let groups = n.div_ceil(WORKGROUP as u64) as u32;
            dispatch_query(ctx, pipeline, scene, &io, groups, "the BSDF probe")?;
            out.extend(ctx.read_pod::<GpuProbeOutput>(&output_buf, n as usize)?);
        }
        Ok(out)
    }
}

/// `p` and the three numbers `v` (uniform numbers or a direction) as the shader reads them.
fn to_gpu(p: &ProbePoint, v: [f32; 3]) -> GpuProbeInput {
    GpuProbeInput { wo: p.wo.to_array(), material: p.material, ns: p.ns.to_array(), front: p.front as u32, v, _pad: 0 }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::mem::{offset_of, size_of};

    /// The WGSL structs of the probe's inputs and outputs have the size and member offsets of
    /// their Rust twins, as naga lays them out in a composed variant.
    #[test]
    fn wgsl_structs_equal_the_rust_structs() {
        let key = FeatureKey::SPHERES | FeatureKey::PBR | FeatureKey::ROUGH_GLASS | FeatureKey::MIRROR;
        let m = shaders::compose_diagnostic(shaders::BSDF_PROBE, key).unwrap();
        let mut layouter = naga::proc::Layouter::default();
        layouter.update(m.to_ctx()).unwrap();
        let wgsl = |name: &str| {
            m.types
                .iter()
                .find_map(|(h, ty)| match &ty.inner {
                    naga::TypeInner::Struct { members, .. }
                        if ty.name.as_deref()?.split("X_naga_oil_mod_X").next()? == name =>
                    {
                        let fields: Vec<(String, usize)> =
                            members.iter().map(|f| (f.name.clone().unwrap_or_default(), f.offset as usize)).collect();
                        Some((layouter[h].size as usize, fields))
                    }
                    _ => None,
                })
                .unwrap_or_else(|| panic!("struct {name} not found"))
        };
        let input = [
            ("wo", offset_of!(GpuProbeInput, wo)),
            ("material", offset_of!(GpuProbeInput, material)),
            ("ns", offset_of!(GpuProbeInput, ns)),
            ("front", offset_of!(GpuProbeInput, front)),
            ("v", offset_of!(GpuProbeInput, v)),
            ("pad", offset_of!(GpuProbeInput, _pad)),
        ];
        let output = [
            ("dir", offset_of!(GpuProbeOutput, dir)),
            ("pdf", offset_of!(GpuProbeOutput, pdf)),
            ("weight", offset_of!(GpuProbeOutput, weight)),
            ("valid", offset_of!(GpuProbeOutput, valid)),
            ("f_cos", offset_of!(GpuProbeOutput, f_cos)),
            ("eval_pdf", offset_of!(GpuProbeOutput, eval_pdf)),
            ("density", offset_of!(GpuProbeOutput, density)),
            ("specular", offset_of!(GpuProbeOutput, specular)),
            ("through", offset_of!(GpuProbeOutput, through)),
            ("pad", offset_of!(GpuProbeOutput, _pad)),
        ];
        for (name, size, fields) in [
            ("ProbeInput", size_of::<GpuProbeInput>(), &input[..]),
            ("ProbeOutput", size_of::<GpuProbeOutput>(), &output),
        ] {
            let (wgsl_size, members) = wgsl(name);
            assert_eq!(wgsl_size, size, "size of {name}");
            let want: Vec<(String, usize)> = fields.iter().map(|&(f, o)| (f.to_string(), o)).collect();
            assert_eq!(members, want, "members of {name} and their offsets");
        }
    }
}
