//! WGSL sources, composed per scene with naga_oil: a scene's [`FeatureKey`] picks the shader
//! defs, so a variant contains only the primitive, material and light code the scene uses.
//!
//! The sources have one template syntax besides the preprocessor's `#ifdef NAME` and
//! `#if NAME > N`: `#{NAME}` stands for a value. Values the shaders share with the host are
//! the same in every variant and are written into the texts once, before the composer reads
//! them ([`crate::shared`]); a value of the variant (the elements per part of an array split
//! across bindings, [`crate::split`]) is a shader def of its key ([`FeatureKey::shader_defs`]),
//! which naga_oil writes in where it composes that variant.
//!
//! One composer serves the process ([`compose()`]): the modules are added once, and naga_oil
//! keeps each module's variants by the defs it reads.

mod compose;
mod feature_key;
#[cfg(test)]
mod tests;
mod wgsl;

pub use compose::{compose, compose_diagnostic};
pub use feature_key::FeatureKey;
pub use wgsl::{exact_f32_literals, wgsl, write_wgsl};

/// The shared modules, in import order (each may import only those before it).
pub const MODULES: &[(&str, &str)] = &[
    ("shaders/modules/types.wgsl", include_str!("../shaders/modules/types.wgsl")),
    ("shaders/modules/bindings.wgsl", include_str!("../shaders/modules/bindings.wgsl")),
    ("shaders/modules/roots.wgsl", include_str!("../shaders/modules/roots.wgsl")),
    ("shaders/modules/sphere.wgsl", include_str!("../shaders/modules/sphere.wgsl")),
    ("shaders/modules/cylinder.wgsl", include_str!("../shaders/modules/cylinder.wgsl")),
    ("shaders/modules/plane.wgsl", include_str!("../shaders/modules/plane.wgsl")),
    ("shaders/modules/triangle.wgsl", include_str!("../shaders/modules/triangle.wgsl")),
    ("shaders/modules/traverse.wgsl", include_str!("../shaders/modules/traverse.wgsl")),
    ("shaders/modules/closest.wgsl", include_str!("../shaders/modules/closest.wgsl")),
    ("shaders/modules/spawn.wgsl", include_str!("../shaders/modules/spawn.wgsl")),
    ("shaders/modules/camera.wgsl", include_str!("../shaders/modules/camera.wgsl")),
    ("shaders/modules/texture.wgsl", include_str!("../shaders/modules/texture.wgsl")),
    ("shaders/modules/surface.wgsl", include_str!("../shaders/modules/surface.wgsl")),
    ("shaders/modules/microfacet.wgsl", include_str!("../shaders/modules/microfacet.wgsl")),
    ("shaders/modules/pbr.wgsl", include_str!("../shaders/modules/pbr.wgsl")),
    ("shaders/modules/environment.wgsl", include_str!("../shaders/modules/environment.wgsl")),
    ("shaders/modules/shade.wgsl", include_str!("../shaders/modules/shade.wgsl")),
    ("shaders/modules/sampler.wgsl", include_str!("../shaders/modules/sampler.wgsl")),
    ("shaders/modules/dielectric.wgsl", include_str!("../shaders/modules/dielectric.wgsl")),
    ("shaders/modules/sheen.wgsl", include_str!("../shaders/modules/sheen.wgsl")),
    ("shaders/modules/layers.wgsl", include_str!("../shaders/modules/layers.wgsl")),
    ("shaders/modules/bsdf.wgsl", include_str!("../shaders/modules/bsdf.wgsl")),
    ("shaders/modules/emitters.wgsl", include_str!("../shaders/modules/emitters.wgsl")),
    ("shaders/modules/path.wgsl", include_str!("../shaders/modules/path.wgsl")),
];

/// The shaders that import no module and are not composed per scene, only given the shared
/// values ([`crate::shared::substitute`]): the denoiser's.
pub const STANDALONE: &[(&str, &str)] = &[("shaders/denoise.wgsl", DENOISE_WGSL)];

/// The denoiser's shader (`crate::denoise`), before the shared values are substituted.
pub const DENOISE_WGSL: &str = include_str!("../shaders/denoise.wgsl");

/// The test and diagnostic programs: composed per scene like the [`Program`]s
/// ([`compose_diagnostic`], with the scene's whole key), but never used to render, so not
/// among them.
pub const DIAGNOSTIC: &[(&str, &str)] = &[BSDF_PROBE];

/// The BSDF probe (`crate::bsdf_probe`): the shaders' BSDFs sampled and evaluated for inputs
/// the host chooses.
pub const BSDF_PROBE: (&str, &str) = ("shaders/bsdf_probe.wgsl", include_str!("../shaders/bsdf_probe.wgsl"));

/// A top-level shader and its entry points.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Program {
    /// `whitted.wgsl`: Whitted image, one invocation per pixel.
    Whitted,
    /// `megakernel.wgsl`: one path-traced sample per pixel (progressive passes).
    Path,
    /// `trace.wgsl`: ray queries.
    Trace,
    /// `wavefront.wgsl`: path tracing as separate kernels over queues of paths.
    Wavefront,
    /// `view.wgsl`: the viewer's debug images (normals, depth, BVH cost) of primary rays;
    /// composed with `COUNT_VISITS`, which makes the traversal count its work.
    View,
    /// `aov.wgsl`: the output variables besides radiance (albedo, normal, depth, position,
    /// object, material), one camera ray per pixel and dispatch.
    Aov,
    /// `closest.wgsl`: closest-point queries, the nearest surface point of each query point.
    Closest,
}

impl Program {
    pub const ALL: [Program; 7] = [
        Program::Whitted,
        Program::Path,
        Program::Wavefront,
        Program::Trace,
        Program::View,
        Program::Aov,
        Program::Closest,
    ];

    pub fn source(self) -> (&'static str, &'static str) {
        match self {
            Program::Whitted => ("shaders/whitted.wgsl", include_str!("../shaders/whitted.wgsl")),
            Program::Path => ("shaders/megakernel.wgsl", include_str!("../shaders/megakernel.wgsl")),
            Program::Trace => ("shaders/trace.wgsl", include_str!("../shaders/trace.wgsl")),
            Program::Wavefront => ("shaders/wavefront.wgsl", include_str!("../shaders/wavefront.wgsl")),
            Program::View => ("shaders/view.wgsl", include_str!("../shaders/view.wgsl")),
            Program::Aov => ("shaders/aov.wgsl", include_str!("../shaders/aov.wgsl")),
            Program::Closest => ("shaders/closest.wgsl", include_str!("../shaders/closest.wgsl")),
        }
    }
}

/// What the shaders may use beyond core WGSL: 64-bit integers, in LOAD64 variants only (which
/// run on devices with `SHADER_INT64`).
const CAPABILITIES: naga::valid::Capabilities = naga::valid::Capabilities::SHADER_INT64;

#[derive(Clone, Debug, thiserror::Error)]
pub enum ShaderError {
    #[error("composing {file}: {message}")]
    Compose { file: String, message: String },
    #[error("validating the {program:?} shader for {key}: {message}")]
    Validate { program: Program, key: String, message: String },
    #[error("writing the {program:?} shader for {key} as WGSL: {message}")]
    Write { program: Program, key: String, message: String },
}

/// Validates a composed module with every check naga has; returns its module info.
pub fn validate(
    program: Program,
    key: FeatureKey,
    module: &naga::Module,
) -> Result<naga::valid::ModuleInfo, ShaderError> {
    naga::valid::Validator::new(naga::valid::ValidationFlags::all(), CAPABILITIES)
        .validate(module)
        .map_err(|e| ShaderError::Validate { program, key: key.label(), message: format!("{:?}", e.into_inner()) })
}

/// The composed module as WGSL text (for inspection in tests).
#[cfg(test)]
pub fn to_wgsl(module: &naga::Module, info: &naga::valid::ModuleInfo) -> String {
    naga::back::wgsl::write_string(module, info, naga::back::wgsl::WriterFlags::empty())
        .unwrap_or_else(|e| format!("// cannot print this module as WGSL: {e}"))
}

/// The bindings of bind group `group` that `module` declares, in increasing order.
pub fn group_bindings(module: &naga::Module, group: u32) -> Vec<u32> {
    let mut bindings: Vec<u32> = module
        .global_variables
        .iter()
        .filter_map(|(_, v)| v.binding.as_ref())
        .filter(|b| b.group == group)
        .map(|b| b.binding)
        .collect();
    bindings.sort_unstable();
    bindings.dedup();
    bindings
}
