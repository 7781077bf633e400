//! A scene file's materials and the textures they name.

use super::*;

impl Cx<'_> {
    /// Textures that cannot show: on objects that are not meshes, or meshes without texture
    /// coordinates.
    pub(crate) fn texture_warnings(&self, objects: &[Object], materials: &[Material], warnings: &mut Vec<String>) {
        for (i, o) in objects.iter().enumerate() {
            let m = &materials[o.material as usize];
            if m.color_texture.is_none() && m.radiance_texture.is_none() {
                continue;
            }
            match &o.geometry {
                Geometry::Mesh { attrs, materials: per_triangle, .. }
                    if attrs.uvs.is_empty() && per_triangle.is_empty() =>
                {
                    warnings.push(format!(
                        "{}: objects[{i}]: material \"{}\" has a texture but the mesh has no texture coordinates (vt): \
                         it reads the texel at (0, 0)",
                        self.path.display(),
                        m.name
                    ))
                }
                Geometry::Mesh { .. } => {}
                g => warnings.push(format!(
                    "{}: objects[{i}]: material \"{}\" has a texture, which only meshes show (this is a {})",
                    self.path.display(),
                    m.name,
                    g.kind().name()
                )),
            }
        }
    }

    /// `[environment]`: exactly one of `radiance` and `file`.
    pub(crate) fn environment(&self, e: &Spanned<EnvironmentDef>, warnings: &mut Vec<String>) -> Res<Environment> {
        let d = e.get_ref();
        let mut env = match (&d.radiance, &d.file) {
            (Some(r), None) => Environment::constant(self.rgb(r, "environment.radiance", None)?),
            (None, Some(f)) => {
                if f.get_ref().is_empty() {
                    return Err(self.at(f.span(), "environment.file", "must not be empty"));
                }
                let path = self.base_dir.join(f.get_ref());
                let mut map = Texture::load(&path, ImageKind::Radiance)
                    .map_err(|m| self.at(f.span(), "environment.file", format!("{}: {m}", path.display())))?;
                while map.width as u64 * map.height as u64 > MAX_ENVIRONMENT_TEXELS {
                    let (w, h) = (map.width, map.height);
                    map = map.halved();
                    warnings.push(format!(
                        "{}: environment.file: {}: {w} x {h} texels halved to {} x {} (at most {MAX_ENVIRONMENT_TEXELS} \
                         texels are rendered)",
                        self.path.display(),
                        path.display(),
                        map.width,
                        map.height
                    ));
                }
                map.wrap = [texture::Wrap::Repeat, texture::Wrap::Clamp];
                Environment { map: Some(map), ..Environment::constant([1.0; 3]) }
            }
            (Some(_), Some(f)) => {
                return Err(self.at(f.span(), "environment.file", "give either radiance or file, not both"));
            }
            (None, None) => {
                return Err(self.at(e.span(), "environment", "needs radiance = [r, g, b] or file = \"map.exr\""));
            }
        };
        if let Some(s) = &d.strength {
            env.strength = self.number(s, "environment.strength")?;
            if env.strength < 0.0 {
                return Err(self.at(s.span(), "environment.strength", format!("must be >= 0, got {}", env.strength)));
            }
        }
        if let Some(r) = &d.rotation {
            env.rotation_deg = self.number(r, "environment.rotation")?;
        }
        Ok(env)
    }

    /// The image file `name` (relative to the scene's folder) as a colour texture: its index
    /// in `textures`, each file decoded once.
    pub(crate) fn color_texture(
        &self,
        name: &Spanned<String>,
        field: &str,
        textures: &mut Vec<Texture>,
        files: &mut HashMap<std::path::PathBuf, u32>,
    ) -> Res<u32> {
        if name.get_ref().is_empty() {
            return Err(self.at(name.span(), field, "must not be empty"));
        }
        let path = self.base_dir.join(name.get_ref());
        if let Some(&k) = files.get(&path) {
            return Ok(k);
        }
        if textures.len() >= texture::MAX_TEXTURES {
            return Err(self.at(name.span(), field, format!("more than {} textures", texture::MAX_TEXTURES)));
        }
        let t = Texture::load(&path, ImageKind::Color)
            .map_err(|m| self.at(name.span(), field, format!("{}: {m}", path.display())))?;
        let k = textures.len() as u32;
        textures.push(t);
        files.insert(path, k);
        Ok(k)
    }

    pub(crate) fn material(
        &self,
        m: &Spanned<MaterialDef>,
        field: &str,
        textures: &mut Vec<Texture>,
        files: &mut HashMap<std::path::PathBuf, u32>,
    ) -> Res<Material> {
        let d = m.get_ref();
        let name = d.name.get_ref();
        if name.is_empty() {
            return Err(self.at(d.name.span(), format!("{field}.name"), "must not be empty"));
        }
        let tname = d.kind.get_ref().as_str();
        let Some(kind) = MaterialKind::ALL.into_iter().find(|k| k.name() == tname) else {
            return Err(self.at(
                d.kind.span(),
                format!("{field}.type"),
                format!(
                    "unknown material type \"{tname}\"; known: {}",
                    known_list(MaterialKind::ALL.iter().map(|k| k.name()))
                ),
            ));
        };
        let not_a_field = |key: &str, span: Range<usize>| {
            self.at(span, format!("{field}.{key}"), format!("not a field of a {tname} material"))
        };
        // Keys only some kinds of material take, in the order they are checked.
        use MaterialKind::{Dielectric, Emissive, Mirror, Pbr};
        let own_keys: [(&[MaterialKind], &str, _); 15] = [
            (&[Dielectric, Pbr], "ior", d.ior.as_ref().map(|v| v.span())),
            (&[Emissive, Pbr], "radiance", d.radiance.as_ref().map(|v| v.span())),
            (&[Emissive, Pbr], "two_sided", d.two_sided.as_ref().map(|v| v.span())),
            (&[Mirror, Pbr, Dielectric], "roughness", d.roughness.as_ref().map(|v| v.span())),
            (&[Pbr], "metallic", d.metallic.as_ref().map(|v| v.span())),
            (&[Emissive, Pbr], "radiance_texture", d.radiance_texture.as_ref().map(|v| v.span())),
            (&[Dielectric, Pbr], "absorption", d.absorption.as_ref().map(|v| v.span())),
            (&[Pbr], "transmission", d.transmission.as_ref().map(|v| v.span())),
            (&[Dielectric, Pbr], "single_scattering", d.single_scattering.as_ref().map(|v| v.span())),
            (&[Pbr], "specular", d.specular.as_ref().map(|v| v.span())),
            (&[Pbr], "specular_color", d.specular_color.as_ref().map(|v| v.span())),
            (&[Pbr], "clearcoat", d.clearcoat.as_ref().map(|v| v.span())),
            (&[Pbr], "clearcoat_roughness", d.clearcoat_roughness.as_ref().map(|v| v.span())),
            (&[Pbr], "sheen_color", d.sheen_color.as_ref().map(|v| v.span())),
            (&[Pbr], "sheen_roughness", d.sheen_roughness.as_ref().map(|v| v.span())),
        ];
        for (owners, key, span) in own_keys {
            if !owners.contains(&kind)
                && let Some(span) = span
            {
                return Err(not_a_field(key, span));
            }
        }
        let color_texture = match &d.texture {
            Some(t) => Some(self.color_texture(t, &format!("{field}.texture"), textures, files)?),
            None => None,
        };
        let radiance_texture = match &d.radiance_texture {
            Some(t) => Some(self.color_texture(t, &format!("{field}.radiance_texture"), textures, files)?),
            None => None,
        };
        // An emissive surface reflects like a diffuse one of albedo `color`: black by default,
        // a pure light.
        let default_color = match kind {
            MaterialKind::Dielectric => [1.0; 3],
            MaterialKind::Emissive => [0.0; 3],
            _ => [0.7; 3],
        };
        let max = Some(1.0);
        let color = match &d.color {
            Some(c) => self.rgb(c, &format!("{field}.color"), max)?,
            None => default_color,
        };
        let mut ior = 1.0;
        if matches!(kind, Dielectric | Pbr) {
            ior = 1.5;
            if let Some(v) = &d.ior {
                ior = self.number(v, &format!("{field}.ior"))?;
                if ior <= 0.0 {
                    return Err(self.at(
                        v.span(),
                        format!("{field}.ior"),
                        format!("must be > 0 and finite, got {ior}"),
                    ));
                }
            }
        }
        let mut radiance = [0.0; 3];
        if kind == MaterialKind::Pbr
            && let Some(r) = &d.radiance
        {
            radiance = self.rgb(r, &format!("{field}.radiance"), None)?;
        }
        if kind == MaterialKind::Emissive {
            let Some(r) = &d.radiance else {
                return Err(self.at(
                    m.span(),
                    format!("{field}.radiance"),
                    "missing (an emissive material needs radiance)",
                ));
            };
            radiance = self.rgb(r, &format!("{field}.radiance"), None)?;
        }
        let mut roughness = 0.0;
        if let Some(v) = &d.roughness {
            roughness = self.number(v, &format!("{field}.roughness"))?;
            if !(0.0..=1.0).contains(&roughness) {
                return Err(self.at(
                    v.span(),
                    format!("{field}.roughness"),
                    if kind == MaterialKind::Pbr {
                        format!("must be in [0, 1] (perceptual: GGX alpha is its square), got {roughness}")
                    } else {
                        format!("must be in [0, 1] (GGX alpha), got {roughness}")
                    },
                ));
            }
        } else if kind == MaterialKind::Pbr {
            roughness = 0.5;
        }
        let mut metallic = 0.0;
        if let Some(v) = &d.metallic {
            metallic = self.number(v, &format!("{field}.metallic"))?;
            if !(0.0..=1.0).contains(&metallic) {
                return Err(self.at(
                    v.span(),
                    format!("{field}.metallic"),
                    format!("must be in [0, 1], got {metallic}"),
                ));
            }
        }
        let two_sided = d.two_sided.as_ref().is_some_and(|v| *v.get_ref());
        let (absorption, transmission) = self.glass_keys(d, field)?;
        let layers = self.layer_keys(d, field)?;
        Ok(Material {
            name: name.clone(),
            kind,
            color,
            ior,
            radiance,
            roughness,
            metallic,
            two_sided,
            color_texture,
            radiance_texture,
            absorption,
            transmission,
            single_scattering: d.single_scattering.as_ref().is_some_and(|v| *v.get_ref()),
            ..layers
        })
    }

    /// A pbr material's specular and layer keys (glTF's `KHR_materials_specular`,
    /// `_clearcoat` and `_sheen`), each factor and the sheen colour in [0, 1], on the default
    /// grey material.
    fn layer_keys(&self, d: &MaterialDef, field: &str) -> Res<Material> {
        let unit = |v: &Option<Spanned<f64>>, key: &str, default: f64| -> Res<f64> {
            let Some(v) = v else { return Ok(default) };
            let x = self.number(v, &format!("{field}.{key}"))?;
            if !(0.0..=1.0).contains(&x) {
                return Err(self.at(v.span(), format!("{field}.{key}"), format!("must be in [0, 1], got {x}")));
            }
            Ok(x)
        };
        // (A specular colour may exceed 1: it multiplies the index's F0, and the product is
        // clamped to 1.)
        let color = |v: &Option<SVec>, key: &str, default: [f64; 3], max: Option<f64>| -> Res<[f64; 3]> {
            match v {
                Some(c) => self.rgb(c, &format!("{field}.{key}"), max),
                None => Ok(default),
            }
        };
        Ok(Material {
            specular: unit(&d.specular, "specular", 1.0)?,
            specular_color: color(&d.specular_color, "specular_color", [1.0; 3], None)?,
            clearcoat: unit(&d.clearcoat, "clearcoat", 0.0)?,
            clearcoat_roughness: unit(&d.clearcoat_roughness, "clearcoat_roughness", 0.0)?,
            sheen_color: color(&d.sheen_color, "sheen_color", [0.0; 3], Some(1.0))?,
            sheen_roughness: unit(&d.sheen_roughness, "sheen_roughness", 0.0)?,
            ..Material::default_grey()
        })
    }

    /// A material's glass keys: `absorption` per unit length (any size: a path keeps
    /// exp(−absorption × distance)) and a pbr material's `transmission` in [0, 1].
    fn glass_keys(&self, d: &MaterialDef, field: &str) -> Res<([f64; 3], f64)> {
        let absorption = match &d.absorption {
            Some(a) => self.rgb(a, &format!("{field}.absorption"), None)?,
            None => [0.0; 3],
        };
        let mut transmission = 0.0;
        if let Some(v) = &d.transmission {
            transmission = self.number(v, &format!("{field}.transmission"))?;
            if !(0.0..=1.0).contains(&transmission) {
                return Err(self.at(
                    v.span(),
                    format!("{field}.transmission"),
                    format!("must be in [0, 1], got {transmission}"),
                ));
            }
        }
        Ok((absorption, transmission))
    }
}
