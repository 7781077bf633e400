//! glTF materials and their textures, as strahl's materials.

use super::*;

impl Reader<'_> {
    /// Every material of the file, mapped onto strahl's kinds (see the book's glTF chapter), with the
    /// textures they use; then the grey default for primitives without a material.
    pub(super) fn materials(&mut self) -> Res<()> {
        let mut textures: HashMap<TextureKey, u32> = HashMap::new();
        let docs: Vec<gltf::Material> = self.doc.materials().collect();
        for m in docs {
            let i = m.index().expect("listed materials have an index");
            let at = format!("materials[{i}]");
            let pbr = m.pbr_metallic_roughness();
            let base = pbr.base_color_factor();
            let color = [base[0], base[1], base[2]].map(|c| (c as f64).clamp(0.0, 1.0));
            let strength = m.emissive_strength().unwrap_or(1.0) as f64;
            let radiance = m.emissive_factor().map(|c| (c as f64 * strength).max(0.0));
            let transmission = m.transmission().map_or(0.0, |t| t.transmission_factor() as f64).clamp(0.0, 1.0);
            if m.transmission().is_some_and(|t| t.transmission_texture().is_some()) {
                self.warn(format!(
                    "{at}: KHR_materials_transmission.transmissionTexture is not read: transmissionFactor {transmission} \
                     holds everywhere"
                ));
            }
            let kind = if m.unlit() { MaterialKind::Emissive } else { MaterialKind::Pbr };
            let mut ior = m.ior().unwrap_or(1.5) as f64;
            if !(ior >= 1.0 && ior.is_finite()) {
                self.warn(format!("{at}: KHR_materials_ior ior {ior} is not a refractive index: 1.5 is used"));
                ior = 1.5;
            }
            let absorption = match m.volume() {
                Some(v) if transmission > 0.0 => self.absorption(&v, &at),
                _ => [0.0; 3],
            };
            let mut tex = |this: &mut Self, info: Option<TextureUse>, what: &str, data: bool| -> Res<Option<u32>> {
                match info {
                    Some(u) => this.texture(&u, &format!("{at}.{what}"), data, &mut textures),
                    None => Ok(None),
                }
            };
            let color_texture = tex(
                self,
                pbr.base_color_texture().map(TextureUse::of_info),
                "pbrMetallicRoughness.baseColorTexture",
                false,
            )?;
            let name = match m.name() {
                Some(n) => format!("{at} \"{n}\""),
                None => at.clone(),
            };
            let alpha_mode = match m.alpha_mode() {
                gltf::material::AlphaMode::Opaque => AlphaMode::Opaque,
                gltf::material::AlphaMode::Mask => AlphaMode::Mask(m.alpha_cutoff().unwrap_or(0.5) as f64),
                gltf::material::AlphaMode::Blend => AlphaMode::Blend,
            };
            let alpha = (base[3] as f64).clamp(0.0, 1.0);
            let mut out = Material {
                name,
                kind,
                color,
                ior,
                alpha,
                alpha_mode,
                transmission,
                absorption,
                ..Material::default_grey()
            };
            match kind {
                MaterialKind::Emissive => {
                    // KHR_materials_unlit: the base colour shown as it is, from both sides.
                    // (The colour texture stays for its alpha; the colour it multiplies is black.)
                    out.color = [0.0; 3];
                    out.radiance = color;
                    out.radiance_texture = color_texture;
                    out.color_texture = color_texture;
                    out.two_sided = true;
                    out.unlit = true;
                    out.transmission = 0.0;
                    out.absorption = [0.0; 3];
                }
                _ => {
                    out.color_texture = color_texture;
                    out.metallic = (pbr.metallic_factor() as f64).clamp(0.0, 1.0);
                    out.roughness = (pbr.roughness_factor() as f64).clamp(0.0, 1.0);
                    out.radiance = radiance;
                    out.two_sided = m.double_sided();
                    if radiance.iter().any(|&c| c > 0.0) {
                        out.radiance_texture =
                            tex(self, m.emissive_texture().map(TextureUse::of_info), "emissiveTexture", false)?;
                    }
                    out.metal_rough_texture = tex(
                        self,
                        pbr.metallic_roughness_texture().map(TextureUse::of_info),
                        "pbrMetallicRoughness.metallicRoughnessTexture",
                        true,
                    )?;
                    if let Some(n) = m.normal_texture() {
                        out.normal_scale = n.scale() as f64;
                        out.normal_texture = tex(self, Some(TextureUse::of_normal(&n)), "normalTexture", true)?;
                    }
                    self.layers(&m, &at, &mut out);
                }
            }
            self.out.materials.push(out);
        }
        self.out.materials.push(Material::default_grey());
        Ok(())
    }

    /// `KHR_materials_specular`, `KHR_materials_clearcoat` and `KHR_materials_sheen` of `m`
    /// into `out`: their factors (the layers of [`crate::render::layers`]); their textures are
    /// not read, which a warning names.
    fn layers(&mut self, m: &gltf::Material, at: &str, out: &mut Material) {
        if let Some(sp) = m.specular() {
            out.specular = (sp.specular_factor() as f64).clamp(0.0, 1.0);
            out.specular_color = sp.specular_color_factor().map(|c| (c as f64).max(0.0));
            for (what, has) in [
                ("specularTexture", sp.specular_texture().is_some()),
                ("specularColorTexture", sp.specular_color_texture().is_some()),
            ] {
                self.unread_texture(at, "KHR_materials_specular", what, has);
            }
        }
        let ext = |name: &str| m.extensions().and_then(|e| e.get(name)).and_then(|v| v.as_object());
        let number = |o: &serde_json::Map<String, serde_json::Value>, key: &str, default: f64| {
            o.get(key).and_then(|v| v.as_f64()).filter(|v| v.is_finite()).unwrap_or(default)
        };
        if let Some(c) = ext("KHR_materials_clearcoat") {
            out.clearcoat = number(c, "clearcoatFactor", 0.0).clamp(0.0, 1.0);
            out.clearcoat_roughness = number(c, "clearcoatRoughnessFactor", 0.0).clamp(0.0, 1.0);
            for what in ["clearcoatTexture", "clearcoatRoughnessTexture", "clearcoatNormalTexture"] {
                self.unread_texture(at, "KHR_materials_clearcoat", what, c.contains_key(what));
            }
        }
        if let Some(sh) = ext("KHR_materials_sheen") {
            let color = sh.get("sheenColorFactor").and_then(|v| v.as_array());
            let channel = |i: usize| color.and_then(|a| a.get(i)).and_then(|v| v.as_f64()).unwrap_or(0.0);
            out.sheen_color = [0, 1, 2].map(|i| channel(i).clamp(0.0, 1.0));
            out.sheen_roughness = number(sh, "sheenRoughnessFactor", 0.0).clamp(0.0, 1.0);
            for what in ["sheenColorTexture", "sheenRoughnessTexture"] {
                self.unread_texture(at, "KHR_materials_sheen", what, sh.contains_key(what));
            }
        }
    }

    /// The warning that texture `what` of extension `ext` is not read (where `has`).
    fn unread_texture(&mut self, at: &str, ext: &str, what: &str, has: bool) {
        if has {
            self.warn(format!("{at}: {ext}.{what} is not read: its factor holds everywhere"));
        }
    }

    /// `KHR_materials_volume` as an absorption coefficient per unit length: −ln(attenuationColor)
    /// / attenuationDistance (world units, as the extension states). A thin-walled material
    /// (thicknessFactor 0) has no volume; the thickness texture is not needed (strahl measures
    /// the path inside) and is not read.
    fn absorption(&mut self, v: &gltf::material::Volume, at: &str) -> [f64; 3] {
        let distance = v.attenuation_distance() as f64;
        if v.thickness_factor() <= 0.0 || !(distance > 0.0) || distance.is_infinite() {
            return [0.0; 3];
        }
        let c = v.attenuation_color();
        if c.iter().any(|&x| !(0.0..=1.0).contains(&x)) {
            self.warn(format!("{at}: KHR_materials_volume.attenuationColor {c:?} is clamped to [0, 1]"));
        }
        // A channel that keeps nothing absorbs within a millionth of the distance.
        c.map(|x| -((x as f64).clamp(1e-6, 1.0)).ln() / distance)
    }

    /// The local index of the texture use `u` (an image with its sampler, texture coordinates
    /// and transform; `data`: read linearly), made on first use, its image decoded once; None
    /// (with a warning) for a texture without `source`, which the specification allows where an
    /// extension strahl does not read gives the image.
    pub(super) fn texture(
        &mut self,
        u: &TextureUse,
        at: &str,
        data: bool,
        cache: &mut HashMap<TextureKey, u32>,
    ) -> Res<Option<u32>> {
        let mut texcoord = u.texcoord;
        if texcoord > 1 {
            self.warn(format!("{at}: texCoord {texcoord} is not read (TEXCOORD_0 and _1 are): TEXCOORD_0 is used"));
            texcoord = 0;
        }
        let tex = self.doc.textures().nth(u.texture).ok_or_else(|| format!("{at}.index: out of range"))?;
        let key = (u.texture, texcoord, u.transform.map(f32::to_bits), data);
        if let Some(&k) = cache.get(&key) {
            return Ok(Some(k));
        }
        let Some(image) = tex.source() else {
            self.warn(format!(
                "{at}: textures[{}] has no source (an extension gives its image, which strahl does not read): \
                 the material is untextured",
                tex.index()
            ));
            return Ok(None);
        };
        let image_index = image.index();
        let (width, height, texels) = match self.images.get(&image_index) {
            Some(found) => found.clone(),
            None => {
                let decoded = self.decode_image(image_index)?;
                self.images.insert(image_index, decoded.clone());
                decoded
            }
        };
        let sampler = tex.sampler();
        let wrap = |w: gltf::texture::WrappingMode| match w {
            gltf::texture::WrappingMode::ClampToEdge => Wrap::Clamp,
            gltf::texture::WrappingMode::MirroredRepeat => Wrap::Mirror,
            gltf::texture::WrappingMode::Repeat => Wrap::Repeat,
        };
        let t = Texture {
            name: format!("images[{image_index}]"),
            width,
            height,
            texels,
            wrap: [wrap(sampler.wrap_s()), wrap(sampler.wrap_t())],
            nearest: sampler.mag_filter() == Some(gltf::texture::MagFilter::Nearest),
            data,
            texcoord,
            transform: u.transform,
        };
        let k = self.out.textures.len() as u32;
        self.out.textures.push(t);
        cache.insert(key, k);
        Ok(Some(k))
    }

    /// Image `image_index` decoded: its size and texels.
    pub(super) fn decode_image(&mut self, image_index: usize) -> Res<(u32, u32, Arc<Texels>)> {
        let iat = format!("images[{image_index}]");
        let json = &self.doc.as_json().images[image_index];
        let bytes = match (&json.buffer_view, &json.uri) {
            (Some(view), _) => {
                let view = self
                    .doc
                    .views()
                    .nth(view.value())
                    .ok_or_else(|| format!("{iat}.bufferView: index out of range"))?;
                self.view_bytes(&view).map_err(|m| format!("{iat}: {m}"))?.to_vec()
            }
            (None, Some(uri)) => read_uri(uri, &self.dir, crate::scene::texture::MAX_TEXTURE_FILE_BYTES)
                .map_err(|m| format!("{iat}.uri: {m}"))?,
            (None, None) => return Err(format!("{iat}: neither uri nor bufferView")),
        };
        let t = Texture::decode(&bytes, ImageKind::Color).map_err(|m| format!("{iat}: {m}"))?;
        Ok((t.width, t.height, t.texels))
    }
}
