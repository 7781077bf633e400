//! `[environment]`: light arriving from infinitely far away in every direction, a constant
//! radiance or an equirectangular map. How it is looked up and sampled is in
//! `render::environment` (twin of `shaders/modules/environment.wgsl`).

use super::Texture;

/// How path tracing's next-event estimation picks directions towards the environment.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum EnvSampling {
    /// In proportion to the map's radiance (a piecewise-constant distribution over its
    /// texels); a constant sky is sampled uniformly, which is the same thing.
    #[default]
    Importance,
    /// Uniformly over the sphere whatever the map holds: only for measuring what importance
    /// sampling gains (not offered in scene files).
    Uniform,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Environment {
    /// The constant radiance (`radiance`), or [1, 1, 1] for a map.
    pub radiance: [f64; 3],
    /// The equirectangular map (`file`): +y up, linear radiance, [`super::texture::Texels::Linear`].
    pub map: Option<Texture>,
    /// Multiplies the radiance or the map.
    pub strength: f64,
    /// Degrees about +y: with 90 the map's centre, otherwise seen along +z, lies along +x.
    pub rotation_deg: f64,
    pub sampling: EnvSampling,
}

impl Environment {
    /// A constant sky of `radiance`.
    pub fn constant(radiance: [f64; 3]) -> Self {
        Self { radiance, map: None, strength: 1.0, rotation_deg: 0.0, sampling: EnvSampling::Importance }
    }
}
