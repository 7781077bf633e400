//! Arbitrary output variables (AOVs): what a pixel's camera rays see besides radiance
//! (`aov.wgsl` is the twin; `strahl-cpu`'s `aov.rs` and `strahl-gpu`'s `aov.rs` drive them).
//!
//! Two kinds, as OIDN's guide images and Mitsuba's `aov` integrator define them:
//!
//! - **Guides** ([`Aov::Albedo`], [`Aov::Normal`]), what a denoiser needs: the albedo and the
//!   shading normal of the *first non-specular surface* along the camera ray, as Intel's Open
//!   Image Denoise asks for them ("for perfect specular surfaces ... use the albedo and normal
//!   of the next hit"). A ray that meets smooth glass or a smooth mirror goes on in the
//!   direction [`bsdf::sample`] gives with the fixed numbers ½ (for glass the likelier of
//!   reflection and refraction, by Fresnel), its albedo multiplied by that sample's weight, for
//!   at most [`AOV_CHAIN`] surfaces. Where the ray leaves the scene the albedo is the
//!   background clamped to [0, 1] and the normal 0. Both are averaged over the pixel's first
//!   [`aov_samples`] camera rays (the R2 offsets of [`super::camera::sample_offset`]), so that
//!   they are antialiased as the image is.
//! - **First hit** ([`Aov::Depth`], [`Aov::Position`], [`Aov::Object`], [`Aov::Material`]): the
//!   distance along the ray, the point, the object's and the material's index where the ray
//!   through the pixel's centre first stops (alpha cut-outs below half coverage let it
//!   through; glass and mirrors do not). A pixel whose ray misses has depth and position 0 and
//!   indices −1. Not averaged: a mean of two objects' indices or depths names neither.
//!
//! The values are f32 computed by the same operations on both backends; they are written as
//! named channels of the render's EXR file ([`Aov::channels`]).

use super::bsdf;
use super::environment;
use super::spawn::spawn_origin;
use super::surface::{self, Surface};
use crate::layout::{FlatMaterial, FlatScene, FrameParams, MATERIAL_ALPHA};
use crate::math::{Ray, V3};
use crate::primitives::Hit;
use crate::scene::MaterialKind;

/// Specular surfaces (and alpha cut-outs) a guide ray goes on through before it gives up
/// (albedo and normal 0).
pub const AOV_CHAIN: u32 = 8;
/// The most camera rays a pixel's guides average: past this, their antialiasing is as good as
/// the eye can tell, and the guides' cost stays a fraction of the render's.
pub const AOV_SAMPLES_MAX: u32 = 64;

/// Where the GPU's AOV program (`aov.wgsl`) finds which pass it computes in
/// [`FrameParams::flags`] (the pass shifted left by this), and the passes.
pub const AOV_PASS_SHIFT: u32 = 8;
/// Albedo of the first non-specular surface (r, g, b).
pub const AOV_PASS_ALBEDO: u32 = 1;
/// Shading normal of the first non-specular surface (x, y, z).
pub const AOV_PASS_NORMAL: u32 = 2;
/// Depth, object index and material index of the centre ray's first hit.
pub const AOV_PASS_FIRST_HIT: u32 = 3;
/// Position of the centre ray's first hit (x, y, z).
pub const AOV_PASS_POSITION: u32 = 4;

/// One output variable.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Aov {
    Albedo,
    Normal,
    Depth,
    Position,
    Object,
    Material,
}

impl Aov {
    pub const ALL: [Aov; 6] = [Aov::Albedo, Aov::Normal, Aov::Depth, Aov::Position, Aov::Object, Aov::Material];

    /// The name `--aov` takes.
    pub fn name(self) -> &'static str {
        match self {
            Aov::Albedo => "albedo",
            Aov::Normal => "normal",
            Aov::Depth => "depth",
            Aov::Position => "position",
            Aov::Object => "object",
            Aov::Material => "material",
        }
    }

    /// Its channels in an EXR file, layer-dot-channel as Cycles and Mitsuba name them.
    pub fn channels(self) -> &'static [&'static str] {
        match self {
            Aov::Albedo => &["albedo.R", "albedo.G", "albedo.B"],
            Aov::Normal => &["normal.X", "normal.Y", "normal.Z"],
            Aov::Depth => &["depth.Z"],
            Aov::Position => &["position.X", "position.Y", "position.Z"],
            Aov::Object => &["object.id"],
            Aov::Material => &["material.id"],
        }
    }

    /// The pass that computes it, and which of the pass's three values are its channels.
    pub fn pass(self) -> (u32, std::ops::Range<usize>) {
        match self {
            Aov::Albedo => (AOV_PASS_ALBEDO, 0..3),
            Aov::Normal => (AOV_PASS_NORMAL, 0..3),
            Aov::Depth => (AOV_PASS_FIRST_HIT, 0..1),
            Aov::Object => (AOV_PASS_FIRST_HIT, 1..2),
            Aov::Material => (AOV_PASS_FIRST_HIT, 2..3),
            Aov::Position => (AOV_PASS_POSITION, 0..3),
        }
    }

    /// A comma-separated list of names (`albedo,normal`), each once, in the order given.
    pub fn parse_list(s: &str) -> Result<Vec<Aov>, String> {
        let mut out = Vec::new();
        for name in s.split(',').map(str::trim) {
            let Some(a) = Aov::ALL.into_iter().find(|a| a.name() == name) else {
                let names: Vec<&str> = Aov::ALL.iter().map(|a| a.name()).collect();
                return Err(format!("unknown output variable {name:?}; choose from {}", names.join(", ")));
            };
            if out.contains(&a) {
                return Err(format!("{name} is named twice"));
            }
            out.push(a);
        }
        Ok(out)
    }
}

/// The passes that compute `aovs`, each once, in increasing order.
pub fn passes(aovs: &[Aov]) -> Vec<u32> {
    let mut p: Vec<u32> = aovs.iter().map(|a| a.pass().0).collect();
    p.sort_unstable();
    p.dedup();
    p
}

/// How many camera rays a pixel's guides average for a render of `spp` samples: as many, up
/// to [`AOV_SAMPLES_MAX`]. The first-hit passes take one ray, the pixel's centre (sample 0).
pub fn aov_samples(pass: u32, spp: u32) -> u32 {
    if matches!(pass, AOV_PASS_ALBEDO | AOV_PASS_NORMAL) { spp.clamp(1, AOV_SAMPLES_MAX) } else { 1 }
}

/// The albedo a guide records for a non-specular surface: the material's colour with textures
/// and vertex colours applied, clamped to [0, 1]; an emitter's radiance clamped to [0, 1].
#[inline]
pub fn albedo(m: &FlatMaterial) -> V3<f32> {
    let c = if m.kind() == MaterialKind::Emissive { m.radiance } else { m.color };
    V3::from_array(c.map(|v| v.clamp(0.0, 1.0)))
}

/// Whether the ray passes an alpha surface here: its coverage is below one half.
#[inline]
fn passes_through(s: &Surface) -> bool {
    s.m.flags & MATERIAL_ALPHA != 0 && surface::coverage(&s.m, s.alpha) < 0.5
}

/// The ray on past `hit`, in `dir`, from the side of the surface `dir` leaves by.
#[inline]
fn onward(ray: &Ray<f32>, hit: &Hit<f32>, dir: V3<f32>) -> Ray<f32> {
    let side = if dir.dot(hit.normal) >= 0.0 { hit.normal } else { -hit.normal };
    Ray::new(spawn_origin(ray, hit.t, side), dir)
}

/// The albedo and the normal the guide passes record for `ray` (the two passes' values,
/// found by one walk; `aov.wgsl`'s `aov_value` for those passes), with `nearest` the scene's
/// nearest-hit walk (the CPU backend's).
pub fn guides(
    g: &FlatScene,
    f: &FrameParams,
    ray: Ray<f32>,
    nearest: impl Fn(&Ray<f32>) -> Option<Hit<f32>>,
) -> ([f32; 3], [f32; 3]) {
    let mut ray = ray;
    let mut tint = V3::splat(1.0f32);
    for _ in 0..AOV_CHAIN {
        let Some(hit) = nearest(&ray) else {
            let bg = environment::background(g, f, ray.dir).to_array().map(|v| v.clamp(0.0, 1.0));
            return (tint.mul_elem(V3::from_array(bg)).to_array(), [0.0; 3]);
        };
        let untextured = &g.materials[hit.tag.material as usize];
        let s = surface::surface(g, untextured, hit.prim_ref, ray.at(hit.t), hit.normal);
        if passes_through(&s) {
            ray = onward(&ray, &hit, ray.dir);
            continue;
        }
        let m = &s.m;
        let wo = -ray.dir;
        let front = ray.dir.dot(hit.normal) < 0.0;
        let (_, ns) = surface::shading_frame(m, front, hit.normal, s.normal, wo);
        if !bsdf::is_specular(m) {
            return (tint.mul_elem(albedo(m)).to_array(), ns.to_array());
        }
        let Some(b) = bsdf::sample(m, wo, ns, front, [0.5; 3]) else {
            return ([0.0; 3], [0.0; 3]);
        };
        tint = tint.mul_elem(b.weight);
        ray = onward(&ray, &hit, b.dir);
    }
    ([0.0; 3], [0.0; 3])
}

/// The value of a first-hit pass ([`AOV_PASS_FIRST_HIT`]: depth, object, material;
/// [`AOV_PASS_POSITION`]: the point) for `ray` (`aov_value` for those passes).
pub fn first_hit(g: &FlatScene, pass: u32, ray: Ray<f32>, nearest: impl Fn(&Ray<f32>) -> Option<Hit<f32>>) -> [f32; 3] {
    let mut ray = ray;
    // The distance travelled before this ray, for the depth past cut-outs.
    let mut travelled = 0.0f32;
    for _ in 0..AOV_CHAIN {
        let Some(hit) = nearest(&ray) else { break };
        let untextured = &g.materials[hit.tag.material as usize];
        let s = surface::surface(g, untextured, hit.prim_ref, ray.at(hit.t), hit.normal);
        if passes_through(&s) {
            travelled += hit.t;
            ray = onward(&ray, &hit, ray.dir);
            continue;
        }
        if pass == AOV_PASS_POSITION {
            return ray.at(hit.t).to_array();
        }
        return [travelled + hit.t, hit.tag.object as f32, hit.tag.material as f32];
    }
    if pass == AOV_PASS_FIRST_HIT { [0.0, -1.0, -1.0] } else { [0.0; 3] }
}

/// The requested AOVs of an image region, each with its channels interleaved per pixel,
/// row-major over the region (as [`crate::image::Image`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AovImages {
    pub width: u32,
    pub height: u32,
    pub layers: Vec<(Aov, Vec<f32>)>,
}

impl AovImages {
    /// Picks `aovs` out of the passes' images (`passes[k]` computed pass `pass_ids[k]`, three
    /// values a pixel).
    pub fn from_passes(width: u32, height: u32, aovs: &[Aov], pass_ids: &[u32], passes: &[Vec<[f32; 3]>]) -> Self {
        let layers = aovs
            .iter()
            .map(|&a| {
                let (pass, range) = a.pass();
                let k = pass_ids.iter().position(|&p| p == pass).expect("every AOV's pass was computed");
                let data = passes[k].iter().flat_map(|v| v[range.clone()].iter().copied()).collect();
                (a, data)
            })
            .collect();
        Self { width, height, layers }
    }

    /// The values of `aov`, if requested.
    pub fn get(&self, aov: Aov) -> Option<&[f32]> {
        self.layers.iter().find(|(a, _)| *a == aov).map(|(_, d)| d.as_slice())
    }

    /// The denoiser's guides, where both were computed.
    pub fn guides(&self) -> Option<crate::denoise::Guides<'_>> {
        let three = |a| self.get(a).map(bytemuck::cast_slice::<f32, [f32; 3]>);
        Some(crate::denoise::Guides { albedo: three(Aov::Albedo)?, normal: three(Aov::Normal)? })
    }

    /// Named EXR channels: (name, one value a pixel).
    pub fn channels(&self) -> Vec<(&'static str, Vec<f32>)> {
        let mut out = Vec::new();
        for (a, data) in &self.layers {
            let names = a.channels();
            for (c, name) in names.iter().enumerate() {
                out.push((*name, data.iter().skip(c).step_by(names.len()).copied().collect()));
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lists_parse_in_order_and_refuse_unknown_or_repeated_names() {
        assert_eq!(Aov::parse_list("normal, albedo").unwrap(), vec![Aov::Normal, Aov::Albedo]);
        let all: Vec<&str> = Aov::ALL.iter().map(|a| a.name()).collect();
        assert_eq!(Aov::parse_list(&all.join(",")).unwrap(), Aov::ALL.to_vec());
        assert!(Aov::parse_list("albedo,colour").unwrap_err().contains("\"colour\""));
        assert!(Aov::parse_list("depth,depth").unwrap_err().contains("twice"));
        assert!(Aov::parse_list("").is_err());
    }

    #[test]
    fn every_channel_belongs_to_its_pass() {
        for a in Aov::ALL {
            let (pass, range) = a.pass();
            assert_eq!(range.len(), a.channels().len(), "{a:?}");
            assert!((1..=4).contains(&pass));
        }
        assert_eq!(passes(&[Aov::Object, Aov::Depth, Aov::Albedo]), vec![AOV_PASS_ALBEDO, AOV_PASS_FIRST_HIT]);
        assert_eq!(aov_samples(AOV_PASS_ALBEDO, 4096), AOV_SAMPLES_MAX);
        assert_eq!(aov_samples(AOV_PASS_NORMAL, 3), 3);
        assert_eq!(aov_samples(AOV_PASS_FIRST_HIT, 16), 1);
    }
}
