//! The values the shaders share with the host, written once, in Rust: every `#{NAME}` in a
//! shader source whose NAME is a value below is replaced by its WGSL literal when the composer
//! reads the source. So a material kind, a flag bit, a stack depth or a tolerance has one
//! definition that the CPU twin and the GPU both read, instead of two kept in step by comments.
//!
//! `#{NAME}` is the shaders' one template syntax ([`crate::shaders`]): a NAME that is not
//! shared here is a value of the variant, a shader def of its key (the elements per part of a
//! split array, [`crate::split::SplitArray::defs`]), which naga_oil writes in per variant.

use strahl_core::math::Real;

/// A shared value and the WGSL literal it becomes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shared {
    U32(u32),
    F32(f32),
    /// A table: the comma-separated literals of its values (for an `array<f32, N>(...)`).
    F32s(&'static [f32]),
}

impl Shared {
    /// The WGSL literal: `7u`, or an f32 as an exact hexadecimal float (`0x1.000000p-1f`), which
    /// no decimal rounding can change.
    pub fn literal(self) -> String {
        match self {
            Shared::U32(v) => format!("{v}u"),
            Shared::F32(v) => hex_float(v),
            Shared::F32s(v) => v.iter().map(|&x| hex_float(x)).collect::<Vec<_>>().join(", "),
        }
    }
}

/// `v` (finite) as a WGSL hexadecimal float literal with an `f` suffix.
pub(crate) fn hex_float(v: f32) -> String {
    assert!(v.is_finite(), "shared floats are finite");
    let bits = v.to_bits();
    let sign = if bits >> 31 != 0 { "-" } else { "" };
    let exp = ((bits >> 23) & 0xff) as i32;
    let mantissa = (bits & 0x7f_ffff) << 1; // 24 bits: six hexadecimal digits
    match exp {
        0 if mantissa == 0 => format!("{sign}0.0f"),
        0 => format!("{sign}0x0.{mantissa:06x}p-126f"),
        _ => format!("{sign}0x1.{mantissa:06x}p{}f", exp - 127),
    }
}

/// Side of the denoiser's workgroups in invocations (`crate::denoise`).
pub const DENOISE_WORKGROUP: u32 = 8;

/// Every shared value, by the name the shaders use.
pub fn constants() -> Vec<(&'static str, Shared)> {
    use Shared::{F32, F32s, U32};
    use strahl_core::accel::gpu_bvh as bvh;
    use strahl_core::geometry::Part;
    use strahl_core::layout as g;
    use strahl_core::primitives::{PrimKind, PrimRef};
    use strahl_core::render::{aov, bsdf, dielectric, limits, microfacet, pbr, sampler, sheen, spawn};
    use strahl_core::scene::MaterialKind;
    use strahl_core::scene::texture::Wrap;
    let mut values = vec![
        // Primitive references (primitives::PrimRef) and the parts of a surface.
        ("KIND_SPHERE", U32(PrimKind::Sphere as u32)),
        ("KIND_CYLINDER", U32(PrimKind::Cylinder as u32)),
        ("KIND_TRIANGLE", U32(PrimKind::Triangle as u32)),
        ("KIND_PLANE", U32(PrimKind::Plane as u32)),
        ("INDEX_BITS", U32(PrimRef::INDEX_BITS)),
        ("INDEX_MASK", U32(PrimRef::MAX_INDEX)),
        ("PART_SURFACE", U32(Part::Surface as u32)),
        ("PART_CAP_P1", U32(Part::CapP1 as u32)),
        ("PART_CAP_P2", U32(Part::CapP2 as u32)),
        // Materials, lights, emitters and buffer flags (layout).
        ("MAT_MIRROR", U32(MaterialKind::Mirror as u32)),
        ("MAT_DIELECTRIC", U32(MaterialKind::Dielectric as u32)),
        ("MAT_EMISSIVE", U32(MaterialKind::Emissive as u32)),
        ("MAT_PBR", U32(MaterialKind::Pbr as u32)),
        ("MATERIAL_TWO_SIDED", U32(g::MATERIAL_TWO_SIDED)),
        ("MATERIAL_UNLIT", U32(g::MATERIAL_UNLIT)),
        ("MATERIAL_ALPHA_MASK", U32(g::MATERIAL_ALPHA_MASK)),
        ("MATERIAL_ALPHA_BLEND", U32(g::MATERIAL_ALPHA_BLEND)),
        ("MATERIAL_SINGLE_SCATTERING", U32(g::MATERIAL_SINGLE_SCATTERING)),
        ("MATERIAL_ALPHA", U32(g::MATERIAL_ALPHA)),
        ("LIGHT_POINT", U32(g::LIGHT_POINT)),
        ("LIGHT_STAND_IN", U32(g::LIGHT_STAND_IN)),
        ("LIGHT_SPOT", U32(g::LIGHT_SPOT)),
        ("FRAME_ACCUMULATE", U32(g::FRAME_ACCUMULATE)),
        ("VIEW_MODE_SHIFT", U32(g::VIEW_MODE_SHIFT)),
        ("VIEW_NORMALS", U32(g::VIEW_NORMALS)),
        ("VIEW_DEPTH", U32(g::VIEW_DEPTH)),
        ("VIEW_COST", U32(g::VIEW_COST)),
        ("FRAME_ENVIRONMENT", U32(g::FRAME_ENVIRONMENT)),
        ("QUERY_FOUND", U32(g::QUERY_FOUND)),
        ("QUERY_ENTER", U32(g::QUERY_ENTER)),
        // Textures and the environment (layout, scene::texture::Wrap). The environment's flags
        // are not called ENV_MAP: that name is a feature's shader def.
        ("TEXTURE_WRAP_U_SHIFT", U32(g::TEXTURE_WRAP_U_SHIFT)),
        ("TEXTURE_WRAP_V_SHIFT", U32(g::TEXTURE_WRAP_V_SHIFT)),
        ("TEXTURE_NEAREST", U32(g::TEXTURE_NEAREST)),
        ("TEXTURE_LINEAR_RGB", U32(g::TEXTURE_LINEAR_RGB)),
        ("TEXTURE_DATA", U32(g::TEXTURE_DATA)),
        ("TEXTURE_UV1", U32(g::TEXTURE_UV1)),
        ("ATTR_NORMALS", U32(g::ATTR_NORMALS)),
        ("ATTR_COLORS", U32(g::ATTR_COLORS)),
        ("WRAP_REPEAT", U32(Wrap::Repeat as u32)),
        ("WRAP_CLAMP", U32(Wrap::Clamp as u32)),
        ("WRAP_MIRROR", U32(Wrap::Mirror as u32)),
        ("ENV_FLAG_MAP", U32(g::ENV_MAP)),
        ("ENV_FLAG_UNIFORM", U32(g::ENV_UNIFORM)),
        // The GPU BVH layout (accel::gpu_bvh) and its traversal stack.
        ("LINK_LEAF", U32(bvh::LINK_LEAF)),
        ("LINK_SHAPES", U32(bvh::LINK_SHAPES)),
        ("LINK_COUNT_SHIFT", U32(bvh::LINK_COUNT_SHIFT)),
        ("LINK_FIRST_MASK", U32(bvh::LINK_FIRST_MASK)),
        ("LINK_EMPTY", U32(bvh::LINK_EMPTY)),
        ("GPU_STACK", U32(bvh::MAX_DEPTH)),
        // 1 + 2γ(3), the far-distance growth of the slab test (accel::slab::slab).
        ("SLAB_GROW", F32(1.0 + 2.0 * <f32 as Real>::gamma_bound(3))),
        // Closest points: the growth of the best squared distance a box is pruned against
        // (accel::gpu_bvh::closest_grow); the square of the sine below which a triangle is its
        // edges, γ(16)·γ(16) rounded in f32 as geometry::closest's Triangle::closest rounds its
        // `g * g` (shared squared: a product of two constants would be folded in the shader,
        // leaving no constant of the shared name); the PrimRef of no primitive.
        ("CLOSEST_GROW", F32(bvh::closest_grow())),
        ("CLOSEST_SLIVER_SQ", F32(<f32 as Real>::gamma_bound(16) * <f32 as Real>::gamma_bound(16))),
        ("CLOSEST_NONE", U32(super::closest::NONE)),
        // Shading and sampling (render::*).
        ("WHITTED_STACK", U32(limits::WHITTED_STACK as u32)),
        ("SHADOW_PASSES", U32(limits::SHADOW_PASSES)),
        ("SHADOW_REACH", F32(limits::SHADOW_REACH)),
        ("MIN_ROUGHNESS", F32(bsdf::MIN_ROUGHNESS)),
        ("MIN_PBR_ALPHA", F32(pbr::MIN_PBR_ALPHA)),
        ("PBR_F0", F32(pbr::PBR_F0)),
        ("GGX_ROUGHNESS_STEPS", U32(microfacet::ROUGHNESS_STEPS as u32)),
        ("GGX_COS_STEPS", U32(microfacet::COS_STEPS as u32)),
        ("GGX_ALBEDO", F32s(microfacet::table())),
        ("GGX_ALBEDO_LEN", U32(microfacet::table().len() as u32)),
        ("SHEEN_ROUGHNESS_STEPS", U32(sheen::ROUGHNESS_STEPS as u32)),
        ("SHEEN_COS_STEPS", U32(sheen::COS_STEPS as u32)),
        ("SHEEN_MIN_ALPHA", F32(sheen::MIN_ALPHA)),
        ("SHEEN_ALBEDO", F32s(sheen::table())),
        ("SHEEN_ALBEDO_LEN", U32(sheen::table().len() as u32)),
        ("DIELECTRIC_ROUGH_STEPS", U32(dielectric::ROUGH_STEPS as u32)),
        ("DIELECTRIC_COS_STEPS", U32(dielectric::COS_STEPS as u32)),
        ("DIELECTRIC_ETA_STEPS", U32(dielectric::ETA_STEPS as u32)),
        ("DIELECTRIC_LN_ETA_MAX", F32(dielectric::ETA_MAX.ln())),
        ("MIN_ULP", F32(spawn::MIN_ULP)),
        ("PCG_MULT", U32(sampler::PCG_MULT)),
        ("PCG_INC", U32(sampler::PCG_INC)),
        ("F32_MAX", F32(f32::MAX)),
        // The output variables' passes (render::aov).
        ("AOV_CHAIN", U32(aov::AOV_CHAIN)),
        ("AOV_PASS_SHIFT", U32(aov::AOV_PASS_SHIFT)),
        ("AOV_PASS_ALBEDO", U32(aov::AOV_PASS_ALBEDO)),
        ("AOV_PASS_FIRST_HIT", U32(aov::AOV_PASS_FIRST_HIT)),
        ("AOV_PASS_POSITION", U32(aov::AOV_PASS_POSITION)),
        // The denoiser's parameters (denoise).
        ("DENOISE_SIGMA_L", F32(strahl_core::denoise::SIGMA_L)),
        ("DENOISE_SIGMA_N2", F32(strahl_core::denoise::SIGMA_N2)),
        ("DENOISE_SIGMA_A2", F32(strahl_core::denoise::SIGMA_A2)),
        ("DENOISE_ALBEDO_EPS", F32(strahl_core::denoise::ALBEDO_EPS)),
        ("DENOISE_VARIANCE_EPS", F32(strahl_core::denoise::VARIANCE_EPS)),
        ("DENOISE_WORKGROUP", U32(DENOISE_WORKGROUP)),
        // Workgroup sizes the host dispatches by.
        ("TILE_WORKGROUP", U32(super::tiles::WORKGROUP)),
        ("TRACE_WORKGROUP", U32(super::trace::WORKGROUP as u32)),
        ("CLOSEST_WORKGROUP", U32(super::closest::WORKGROUP as u32)),
        ("PROBE_WORKGROUP", U32(super::bsdf_probe::WORKGROUP)),
        ("WAVEFRONT_WORKGROUP", U32(super::wavefront::WORKGROUP)),
        // The wavefront tracer's counters (backend::gpu::wavefront::counter).
        ("WF_PATHS_IN", U32(super::wavefront::counter::PATHS_IN)),
        ("WF_PATHS_OUT", U32(super::wavefront::counter::PATHS_OUT)),
        ("WF_SHADOWS_OUT", U32(super::wavefront::counter::SHADOWS_OUT)),
        ("WF_SHADOWS_IN", U32(super::wavefront::counter::SHADOWS_IN)),
        ("WF_ARGS_PATHS", U32(super::wavefront::counter::ARGS_PATHS)),
        ("WF_ARGS_SHADOWS", U32(super::wavefront::counter::ARGS_SHADOWS)),
    ];
    // Where the arrays of the packed objects buffer start, and their counts (objects::ObjectsHeader).
    values.extend(super::objects::ObjectsHeader::slots().map(|(name, slot)| (name, U32(slot))));
    values
}

/// `source` with every `#{NAME}` of a shared value replaced by its literal.
pub fn substitute(source: &str) -> String {
    let mut out = source.to_string();
    for (name, value) in constants() {
        out = out.replace(&format!("#{{{name}}}"), &value.literal());
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hex_floats_are_exact() {
        for v in [1.0f32, 0.5, -2.75, f32::MAX, f32::MIN_POSITIVE, 1e-40, 0.999_755_86, 1.000_000_4, 0.0] {
            let lit = hex_float(v);
            // Parse the literal back: sign, mantissa digits, binary exponent.
            let body = lit.trim_start_matches('-').trim_end_matches('f');
            let parsed = if body == "0.0" {
                0.0
            } else {
                let (m, e) = body.trim_start_matches("0x").split_once('p').unwrap();
                let (int, frac) = m.split_once('.').unwrap();
                let mant = int.parse::<f64>().unwrap() + u32::from_str_radix(frac, 16).unwrap() as f64 / 16f64.powi(6);
                mant * 2f64.powi(e.parse().unwrap())
            };
            let parsed = if lit.starts_with('-') { -parsed } else { parsed };
            assert_eq!(parsed as f32, v, "{lit}");
        }
    }

    /// Every `#{NAME}` is a shared value or a value of the variant, every shared value is used,
    /// and the shaders write no value in naga_oil's other form, `#NAME`.
    #[test]
    fn every_placeholder_in_the_shaders_is_a_shared_value_or_a_value_of_the_variant() {
        use crate::split::SplitArray;
        let sources = crate::shaders::MODULES
            .iter()
            .copied()
            .chain(crate::Program::ALL.map(|p| p.source()))
            .chain(crate::shaders::STANDALONE.iter().copied())
            .chain(crate::shaders::DIAGNOSTIC.iter().copied());
        let of_variant: Vec<&str> = SplitArray::ALL.iter().map(|a| a.defs().1).collect();
        let directives = ["#define_import_path", "#import", "#ifdef", "#ifndef", "#if", "#else", "#endif"];
        let mut used = std::collections::HashSet::new();
        for (file, src) in sources {
            let out = substitute(src);
            for (_, rest) in out.match_indices("#{").map(|(i, _)| out.split_at(i + 2)) {
                let name = &rest[..rest.find('}').expect("a closing brace")];
                assert!(of_variant.contains(&name), "{file}: #{{{name}}} is neither shared nor of the variant");
            }
            for line in src.lines().map(|l| l.split("//").next().unwrap().trim_start()) {
                for (i, _) in line.match_indices('#').filter(|(i, _)| !line[i + 1..].starts_with('{')) {
                    let word = line[i..].split(|c: char| c.is_whitespace()).next().unwrap();
                    assert!(i == 0 && directives.contains(&word), "{file}: {line}: #NAME is written #{{NAME}} here");
                }
            }
            for (name, _) in constants() {
                if src.contains(&format!("#{{{name}}}")) {
                    used.insert(name);
                }
            }
        }
        let unused: Vec<_> = constants().into_iter().map(|(n, _)| n).filter(|n| !used.contains(n)).collect();
        assert!(unused.is_empty(), "shared values no shader uses: {unused:?}");
        let clashes: Vec<_> = constants().into_iter().map(|(n, _)| n).filter(|n| of_variant.contains(n)).collect();
        assert!(clashes.is_empty(), "shared values named like values of the variant: {clashes:?}");
    }
}
