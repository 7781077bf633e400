//! The scene file's shape: the serde structs TOML is read into, every value `Spanned` so that
//! a check can point at it, and the keys each object and light type takes.

use super::*;

pub(super) type SVec = Spanned<Vec<Spanned<f64>>>;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct SceneDef {
    pub(super) camera: Spanned<CameraDef>,
    pub(super) image: Spanned<ImageDef>,
    #[serde(default)]
    pub(super) render: Option<Spanned<RenderDef>>,
    #[serde(default)]
    pub(super) materials: Vec<Spanned<MaterialDef>>,
    #[serde(default)]
    pub(super) objects: Vec<Spanned<ObjectDef>>,
    #[serde(default)]
    pub(super) lights: Vec<Spanned<LightDef>>,
    #[serde(default)]
    pub(super) environment: Option<Spanned<EnvironmentDef>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct EnvironmentDef {
    pub(super) radiance: Option<SVec>,
    pub(super) file: Option<Spanned<String>>,
    pub(super) strength: Option<Spanned<f64>>,
    pub(super) rotation: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct CameraDef {
    pub(super) eye: SVec,
    pub(super) look_at: SVec,
    pub(super) up: SVec,
    pub(super) fov_y: Spanned<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ImageDef {
    pub(super) width: Spanned<i64>,
    pub(super) height: Spanned<i64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RenderDef {
    pub(super) mode: Option<Spanned<String>>,
    pub(super) max_depth: Option<Spanned<i64>>,
    pub(super) spp: Option<Spanned<i64>>,
    pub(super) background: Option<SVec>,
    pub(super) ambient: Option<SVec>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct MaterialDef {
    pub(super) name: Spanned<String>,
    #[serde(rename = "type")]
    pub(super) kind: Spanned<String>,
    pub(super) color: Option<SVec>,
    pub(super) ior: Option<Spanned<f64>>,
    pub(super) radiance: Option<SVec>,
    pub(super) roughness: Option<Spanned<f64>>,
    pub(super) metallic: Option<Spanned<f64>>,
    pub(super) two_sided: Option<Spanned<bool>>,
    pub(super) texture: Option<Spanned<String>>,
    pub(super) radiance_texture: Option<Spanned<String>>,
    pub(super) absorption: Option<SVec>,
    pub(super) transmission: Option<Spanned<f64>>,
    pub(super) single_scattering: Option<Spanned<bool>>,
    pub(super) specular: Option<Spanned<f64>>,
    pub(super) specular_color: Option<SVec>,
    pub(super) clearcoat: Option<Spanned<f64>>,
    pub(super) clearcoat_roughness: Option<Spanned<f64>>,
    pub(super) sheen_color: Option<SVec>,
    pub(super) sheen_roughness: Option<Spanned<f64>>,
}

/// Every key any object type has; which belong to which type is checked in `object`.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ObjectDef {
    #[serde(rename = "type")]
    pub(super) kind: Spanned<String>,
    pub(super) material: Option<Spanned<String>>,
    pub(super) center: Option<SVec>,
    pub(super) radius: Option<Spanned<f64>>,
    pub(super) p1: Option<SVec>,
    pub(super) p2: Option<SVec>,
    pub(super) caps: Option<Spanned<bool>>,
    pub(super) point: Option<SVec>,
    pub(super) normal: Option<SVec>,
    pub(super) vertices: Option<Spanned<Vec<SVec>>>,
    pub(super) file: Option<Spanned<String>>,
    pub(super) translate: Option<SVec>,
    pub(super) scale: Option<Spanned<ScaleDef>>,
    pub(super) rotate: Option<SVec>,
}

impl ObjectDef {
    /// The optional keys present, with their spans, in file order.
    pub(super) fn present(&self) -> Vec<(&'static str, Range<usize>)> {
        fn s<T>(v: &Option<Spanned<T>>) -> Option<Range<usize>> {
            v.as_ref().map(Spanned::span)
        }
        let mut keys: Vec<_> = [
            ("material", s(&self.material)),
            ("center", s(&self.center)),
            ("radius", s(&self.radius)),
            ("p1", s(&self.p1)),
            ("p2", s(&self.p2)),
            ("caps", s(&self.caps)),
            ("point", s(&self.point)),
            ("normal", s(&self.normal)),
            ("vertices", s(&self.vertices)),
            ("file", s(&self.file)),
            ("translate", s(&self.translate)),
            ("scale", s(&self.scale)),
            ("rotate", s(&self.rotate)),
        ]
        .into_iter()
        .filter_map(|(k, sp)| sp.map(|sp| (k, sp)))
        .collect();
        keys.sort_by_key(|(_, sp)| sp.start);
        keys
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct LightDef {
    #[serde(rename = "type")]
    pub(super) kind: Spanned<String>,
    pub(super) position: Option<SVec>,
    pub(super) direction: Option<SVec>,
    pub(super) intensity: Option<SVec>,
    pub(super) inner_angle: Option<Spanned<f64>>,
    pub(super) outer_angle: Option<Spanned<f64>>,
    pub(super) range: Option<Spanned<f64>>,
}

/// A mesh's `scale`: one number for all axes, or `[x, y, z]`.
pub(super) enum ScaleDef {
    Uniform(f64),
    PerAxis(Vec<Spanned<f64>>),
}

impl<'de> Deserialize<'de> for ScaleDef {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Visit;
        impl<'de> serde::de::Visitor<'de> for Visit {
            type Value = ScaleDef;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a number or an array [x, y, z]")
            }
            fn visit_i64<E>(self, v: i64) -> Result<ScaleDef, E> {
                Ok(ScaleDef::Uniform(v as f64))
            }
            fn visit_u64<E>(self, v: u64) -> Result<ScaleDef, E> {
                Ok(ScaleDef::Uniform(v as f64))
            }
            fn visit_f64<E>(self, v: f64) -> Result<ScaleDef, E> {
                Ok(ScaleDef::Uniform(v))
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut seq: A) -> Result<ScaleDef, A::Error> {
                let mut out = Vec::new();
                while let Some(x) = seq.next_element::<Spanned<f64>>()? {
                    out.push(x);
                }
                Ok(ScaleDef::PerAxis(out))
            }
        }
        d.deserialize_any(Visit)
    }
}

pub(super) const LIGHT_TYPES: [(&str, &[&str]); 3] = [
    ("point", &["position", "intensity"]),
    ("directional", &["direction", "intensity"]),
    ("spot", &["position", "direction", "intensity", "inner_angle", "outer_angle", "range"]),
];

pub(super) const OBJECT_TYPES: [(&str, &[&str]); 7] = [
    ("sphere", &["center", "radius", "material"]),
    ("cylinder", &["p1", "p2", "radius", "caps", "material"]),
    ("plane", &["point", "normal", "material"]),
    ("triangle", &["vertices", "material"]),
    ("polygon", &["vertices", "material"]),
    ("mesh", &["file", "translate", "scale", "rotate", "material"]),
    ("gltf", &["file", "translate", "scale", "rotate"]),
];
