//! The checks: every value of the scene file validated and turned into the [`Scene`], objects
//! (with their meshes and glTF files), materials, lights, camera, image, render settings and
//! environment. One file for one purpose; it is long because every check carries its own
//! located message.

use super::*;

impl Cx<'_> {
    pub(super) fn number(&self, v: &Spanned<f64>, field: &str) -> Res<f64> {
        let x = *v.get_ref();
        if x.is_finite() { Ok(x) } else { Err(self.at(v.span(), field, format!("must be finite, got {}", num(x)))) }
    }

    pub(super) fn vec3(&self, v: &SVec, field: &str) -> Res<V3<f64>> {
        let comps = v.get_ref();
        if comps.len() != 3 {
            return Err(self.at(v.span(), field, format!("must have 3 components [x, y, z], got {}", comps.len())));
        }
        let mut out = [0.0; 3];
        for (k, c) in comps.iter().enumerate() {
            out[k] = self.number(c, &format!("{field}[{k}]"))?;
        }
        Ok(V3::from_array(out))
    }

    /// A colour or intensity: three finite components ≥ 0, and ≤ `max` if given.
    pub(super) fn rgb(&self, v: &SVec, field: &str, max: Option<f64>) -> Res<[f64; 3]> {
        let c = self.vec3(v, field)?.to_array();
        for (k, &x) in c.iter().enumerate() {
            let span = v.get_ref()[k].span();
            if x < 0.0 {
                return Err(self.at(span, format!("{field}[{k}]"), format!("must be >= 0, got {x}")));
            }
            if let Some(m) = max
                && x > m
            {
                return Err(self.at(span, format!("{field}[{k}]"), format!("must be <= {m}, got {x}")));
            }
        }
        Ok(c)
    }

    /// A non-zero direction, normalised.
    pub(super) fn direction(&self, v: &SVec, field: &str) -> Res<V3<f64>> {
        let d = self.vec3(v, field)?;
        unit(d).ok_or_else(|| self.at(v.span(), field, "must be non-zero"))
    }

    pub(super) fn int_in(&self, v: &Spanned<i64>, field: &str, lo: i64, hi: i64) -> Res<i64> {
        let x = *v.get_ref();
        if (lo..=hi).contains(&x) {
            Ok(x)
        } else {
            Err(self.at(v.span(), field, format!("must be an integer in {lo}..={hi}, got {x}")))
        }
    }

    pub(super) fn build(&self, def: SceneDef) -> Res<Scene> {
        // Sizes first, before anything is allocated for them.
        let image = self.image(&def.image)?;
        if def.materials.len() > MAX_MATERIALS {
            return Err(
                self.too_large(format!("too many materials: {} (at most {MAX_MATERIALS})", def.materials.len()))
            );
        }
        if def.objects.len() > MAX_OBJECTS {
            return Err(self.too_large(format!("too many objects: {} (at most {MAX_OBJECTS})", def.objects.len())));
        }
        if def.lights.len() > MAX_LIGHTS {
            return Err(self.too_large(format!("too many lights: {} (at most {MAX_LIGHTS})", def.lights.len())));
        }

        let camera = self.camera(def.camera.get_ref())?;
        let mut textures: Vec<Texture> = Vec::new();
        let mut texture_files: HashMap<std::path::PathBuf, u32> = HashMap::new();
        let mut warnings = Vec::new();
        let environment = match &def.environment {
            Some(e) => Some(self.environment(e, &mut warnings)?),
            None => None,
        };
        let render = match &def.render {
            Some(r) => self.render(r.get_ref(), environment.is_some())?,
            None => {
                RenderSettings { ambient: Self::default_ambient(environment.is_some()), ..RenderSettings::default() }
            }
        };

        let mut materials = Vec::with_capacity(def.materials.len() + 1);
        let mut by_name: HashMap<&str, usize> = HashMap::new();
        for (i, m) in def.materials.iter().enumerate() {
            let field = format!("materials[{i}]");
            let mat = self.material(m, &field, &mut textures, &mut texture_files)?;
            let name = m.get_ref().name.get_ref().as_str();
            if let Some(&first) = by_name.get(name) {
                return Err(self.at(
                    m.get_ref().name.span(),
                    format!("{field}.name"),
                    format!("duplicate material name \"{name}\" (also materials[{first}])"),
                ));
            }
            by_name.insert(name, i);
            materials.push(mat);
        }

        // Check the light list before loading any mesh: it is cheap.
        let mut lights = def
            .lights
            .iter()
            .enumerate()
            .map(|(i, l)| self.light(l, &format!("lights[{i}]")))
            .collect::<Res<Vec<_>>>()?;

        // Objects without a material get the grey default, appended after every other
        // material (glTF files add theirs as they load): its index is patched in at the end.
        const DEFAULT: u32 = u32::MAX;
        let mut triangles: usize = 0;
        let mut objects = Vec::with_capacity(def.objects.len());
        for (i, o) in def.objects.iter().enumerate() {
            let field = format!("objects[{i}]");
            let budget = MAX_SCENE_TRIANGLES - triangles;
            let (geometry, material) = if o.get_ref().kind.get_ref() == "gltf" {
                let mut loaded = GltfLoaded {
                    materials: &mut materials,
                    textures: &mut textures,
                    lights: &mut lights,
                    warnings: &mut warnings,
                };
                self.gltf_object(o, &field, budget, &mut loaded)?
            } else {
                let geometry = self.object(o, &field, budget)?;
                let material = match &o.get_ref().material {
                    Some(name) => match by_name.get(name.get_ref().as_str()) {
                        Some(&m) => m as u32,
                        None => {
                            return Err(self.at(
                                name.span(),
                                format!("{field}.material"),
                                format!(
                                    "unknown material \"{}\"; known: {}",
                                    name.get_ref(),
                                    known_list(def.materials.iter().map(|m| m.get_ref().name.get_ref().as_str()))
                                ),
                            ));
                        }
                    },
                    None => DEFAULT,
                };
                (geometry, material)
            };
            triangles += match &geometry {
                Geometry::Triangle(_) => 1,
                Geometry::Polygon { triangles, .. } | Geometry::Mesh { triangles, .. } => triangles.len(),
                _ => 0,
            };
            if triangles > MAX_SCENE_TRIANGLES {
                return Err(self.too_large(format!(
                    "the scene has more than {MAX_SCENE_TRIANGLES} triangles (reached at {field})"
                )));
            }
            if materials.len() > MAX_MATERIALS {
                return Err(self.too_large(format!(
                    "too many materials: more than {MAX_MATERIALS} (reached at {field}, a glTF file's materials count)"
                )));
            }
            objects.push(Object { geometry, material });
        }
        if objects.iter().any(|o| o.material == DEFAULT) {
            let index = materials.len() as u32;
            materials.push(Material::default_grey());
            for o in objects.iter_mut().filter(|o| o.material == DEFAULT) {
                o.material = index;
            }
        }
        self.texture_warnings(&objects, &materials, &mut warnings);

        Ok(Scene { camera, image, render, materials, objects, lights, textures, environment, warnings })
    }

    /// Textures that cannot show: on objects that are not meshes, or meshes without texture
    /// coordinates.
    pub(super) fn texture_warnings(&self, objects: &[Object], materials: &[Material], warnings: &mut Vec<String>) {
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
    pub(super) fn environment(&self, e: &Spanned<EnvironmentDef>, warnings: &mut Vec<String>) -> Res<Environment> {
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
    pub(super) fn color_texture(
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

    /// `[[objects]] type = "gltf"`: the file's triangles with their materials (appended to
    /// `loaded.materials`, their textures to `loaded.textures`) and its punctual lights, placed
    /// by the object's transform. Its cameras are not used (the scene file has its own).
    pub(super) fn gltf_object(
        &self,
        o: &Spanned<ObjectDef>,
        field: &str,
        triangle_budget: usize,
        loaded: &mut GltfLoaded,
    ) -> Res<(Geometry, u32)> {
        let d = o.get_ref();
        let allowed = OBJECT_TYPES.iter().find(|(t, _)| *t == "gltf").expect("gltf is an object type").1;
        for (key, span) in d.present() {
            if !allowed.contains(&key) {
                let hint = if key == "material" { " (a glTF file brings its own materials)" } else { "" };
                return Err(self.at(
                    span,
                    format!("{field}.{key}"),
                    format!("not a field of a gltf (its fields: type, {}){hint}", allowed.join(", ")),
                ));
            }
        }
        let Some(file) = &d.file else {
            return Err(self.at(o.span(), format!("{field}.file"), "missing (a gltf needs file)"));
        };
        if file.get_ref().is_empty() {
            return Err(self.at(file.span(), format!("{field}.file"), "must not be empty"));
        }
        let t = self.placement(d, field)?;
        let path = self.base_dir.join(file.get_ref());
        let mesh_error = |mut message: String| {
            if triangle_budget < mesh::MAX_MESH_TRIANGLES && message.starts_with("more than") {
                message += &format!(" (a scene holds at most {MAX_SCENE_TRIANGLES} triangles in all)");
            }
            let (line, column) = self.line_col(file.span().start);
            SceneError::Mesh {
                path: self.path.to_path_buf(),
                line,
                column,
                field: format!("{field}.file"),
                mesh: path.clone(),
                message,
            }
        };
        let imp =
            crate::scene::gltf::import(&path, &t, triangle_budget.min(mesh::MAX_MESH_TRIANGLES)).map_err(mesh_error)?;
        if loaded.textures.len() + imp.textures.len() > texture::MAX_TEXTURES {
            return Err(mesh_error(format!("more than {} textures in the scene", texture::MAX_TEXTURES)));
        }
        let (m0, t0) = (loaded.materials.len() as u32, loaded.textures.len() as u32);
        let stem = path.file_name().map_or_else(|| path.display().to_string(), |f| f.to_string_lossy().into_owned());
        for mut m in imp.materials {
            m.name = format!("{stem}: {}", m.name);
            for t in [&mut m.color_texture, &mut m.radiance_texture, &mut m.metal_rough_texture, &mut m.normal_texture]
            {
                *t = t.map(|k| k + t0);
            }
            loaded.materials.push(m);
        }
        loaded.textures.extend(imp.textures);
        loaded.lights.extend(imp.lights);
        loaded
            .warnings
            .extend(imp.warnings.into_iter().map(|w| format!("{}: {field}: {stem}: {w}", self.path.display())));
        let materials: Vec<u32> = imp.triangle_materials.iter().map(|&m| m + m0).collect();
        let material = materials.first().copied().unwrap_or(m0);
        Ok((Geometry::Mesh { file: path, triangles: imp.triangles, attrs: imp.attrs, materials }, material))
    }

    /// A mesh's or glTF object's `translate`, `rotate`, `scale`.
    pub(super) fn placement(&self, d: &ObjectDef, field: &str) -> Res<Transform> {
        let mut t = Transform::default();
        if let Some(v) = &d.translate {
            t.translate = self.vec3(v, &format!("{field}.translate"))?.to_array();
        }
        if let Some(v) = &d.rotate {
            t.rotate_deg = self.vec3(v, &format!("{field}.rotate"))?.to_array();
        }
        if let Some(s) = &d.scale {
            t.scale = self.scale(s, &format!("{field}.scale"))?;
        }
        Ok(t)
    }

    /// `[render] ambient` when the file gives none: with an environment, none (it lights
    /// Whitted's diffuse surfaces itself).
    pub(super) fn default_ambient(environment: bool) -> [f64; 3] {
        if environment { [0.0; 3] } else { RenderSettings::default().ambient }
    }

    pub(super) fn image(&self, im: &Spanned<ImageDef>) -> Res<ImageSize> {
        let d = im.get_ref();
        let w = self.int_in(&d.width, "image.width", 1, MAX_IMAGE_SIDE)?;
        let h = self.int_in(&d.height, "image.height", 1, MAX_IMAGE_SIDE)?;
        let pixels = (w as u64) * (h as u64);
        if pixels > MAX_IMAGE_PIXELS {
            return Err(self.at(
                im.span(),
                "image",
                format!("{w} × {h} = {pixels} pixels exceeds the limit of {MAX_IMAGE_PIXELS}"),
            ));
        }
        Ok(ImageSize { width: w as u32, height: h as u32 })
    }

    pub(super) fn camera(&self, c: &CameraDef) -> Res<Camera> {
        let eye = self.vec3(&c.eye, "camera.eye")?;
        let look_at = self.vec3(&c.look_at, "camera.look_at")?;
        let up = self.vec3(&c.up, "camera.up")?;
        let fov_y = self.number(&c.fov_y, "camera.fov_y")?;
        if !(fov_y > 0.0 && fov_y < 180.0) {
            return Err(self.at(c.fov_y.span(), "camera.fov_y", format!("must be in (0, 180) degrees, got {fov_y}")));
        }
        let view = look_at - eye;
        if !view.is_finite() {
            return Err(self.at(c.look_at.span(), "camera.look_at", "is too far from eye (overflow)"));
        }
        let Some(view) = unit(view) else {
            return Err(self.at(c.look_at.span(), "camera.look_at", "must differ from eye"));
        };
        let Some(u) = unit(up) else {
            return Err(self.at(c.up.span(), "camera.up", "must be non-zero"));
        };
        if u.cross(view).length() <= 1e-9 {
            return Err(self.at(
                c.up.span(),
                "camera.up",
                "must not be parallel to the view direction (look_at - eye)",
            ));
        }
        Ok(Camera { eye, look_at, up, fov_y })
    }

    /// `[render]`; with an `[environment]` (`environment`), `background` is the environment and
    /// `ambient` defaults to none.
    pub(super) fn render(&self, r: &RenderDef, environment: bool) -> Res<RenderSettings> {
        let mut s = RenderSettings { ambient: Self::default_ambient(environment), ..RenderSettings::default() };
        if let Some(v) = &r.mode {
            let name = v.get_ref().as_str();
            s.mode = RenderMode::ALL.into_iter().find(|m| m.name() == name).ok_or_else(|| {
                self.at(
                    v.span(),
                    "render.mode",
                    format!(
                        "unknown render mode \"{name}\"; known: {}",
                        known_list(RenderMode::ALL.iter().map(|m| m.name()))
                    ),
                )
            })?;
        }
        if let Some(v) = &r.max_depth {
            s.max_depth = self.int_in(v, "render.max_depth", 0, MAX_DEPTH)? as u32;
        }
        if let Some(v) = &r.spp {
            s.spp = self.int_in(v, "render.spp", 1, MAX_SPP)? as u32;
        }
        if let Some(v) = &r.background {
            if environment {
                return Err(self.at(
                    v.span(),
                    "render.background",
                    "not used with [environment]: the environment is what rays that leave the scene see",
                ));
            }
            s.background = self.rgb(v, "render.background", None)?;
        }
        if let Some(v) = &r.ambient {
            s.ambient = self.rgb(v, "render.ambient", None)?;
        }
        Ok(s)
    }

    pub(super) fn material(
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
        let own_keys: [(&[MaterialKind], &str, _); 6] = [
            (&[Dielectric], "ior", d.ior.as_ref().map(|v| v.span())),
            (&[Emissive, Pbr], "radiance", d.radiance.as_ref().map(|v| v.span())),
            (&[Emissive, Pbr], "two_sided", d.two_sided.as_ref().map(|v| v.span())),
            (&[Mirror, Pbr], "roughness", d.roughness.as_ref().map(|v| v.span())),
            (&[Pbr], "metallic", d.metallic.as_ref().map(|v| v.span())),
            (&[Emissive, Pbr], "radiance_texture", d.radiance_texture.as_ref().map(|v| v.span())),
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
        if kind == MaterialKind::Dielectric {
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
            ..Material::default_grey()
        })
    }

    pub(super) fn light(&self, l: &Spanned<LightDef>, field: &str) -> Res<Light> {
        let d = l.get_ref();
        let tname = d.kind.get_ref().as_str();
        let require = |v: &Option<SVec>, key: &str| -> Res<SVec> {
            v.clone().ok_or_else(|| {
                self.at(l.span(), format!("{field}.{key}"), format!("missing (a {tname} light needs {key})"))
            })
        };
        let not_a_field = |key: &str, span: Range<usize>| {
            self.at(span, format!("{field}.{key}"), format!("not a field of a {tname} light"))
        };
        let intensity = |this: &Self| -> Res<[f64; 3]> {
            this.rgb(&require(&d.intensity, "intensity")?, &format!("{field}.intensity"), None)
        };
        match tname {
            "point" => {
                if let Some(v) = &d.direction {
                    return Err(not_a_field("direction", v.span()));
                }
                let position = self.vec3(&require(&d.position, "position")?, &format!("{field}.position"))?;
                Ok(Light::Point { position, intensity: intensity(self)? })
            }
            "directional" => {
                if let Some(v) = &d.position {
                    return Err(not_a_field("position", v.span()));
                }
                let direction = self.direction(&require(&d.direction, "direction")?, &format!("{field}.direction"))?;
                Ok(Light::Directional { direction, intensity: intensity(self)? })
            }
            _ => Err(self.at(
                d.kind.span(),
                format!("{field}.type"),
                format!("unknown light type \"{tname}\"; known: point, directional"),
            )),
        }
    }

    /// Object `o`; a mesh may add at most `triangle_budget` triangles to the scene.
    pub(super) fn object(&self, o: &Spanned<ObjectDef>, field: &str, triangle_budget: usize) -> Res<Geometry> {
        let d = o.get_ref();
        let tname = d.kind.get_ref().as_str();
        let Some((_, allowed)) = OBJECT_TYPES.iter().find(|(t, _)| *t == tname) else {
            return Err(self.at(
                d.kind.span(),
                format!("{field}.type"),
                format!("unknown object type \"{tname}\"; known: {}", known_list(OBJECT_TYPES.iter().map(|(t, _)| *t))),
            ));
        };
        for (key, span) in d.present() {
            if !allowed.contains(&key) {
                return Err(self.at(
                    span,
                    format!("{field}.{key}"),
                    format!("not a field of a {tname} (its fields: type, {})", allowed.join(", ")),
                ));
            }
        }
        let f = |key: &str| format!("{field}.{key}");
        let missing = |key: &str| {
            let needs: Vec<&str> = allowed
                .iter()
                .copied()
                .filter(|k| !matches!(*k, "material" | "caps" | "translate" | "scale" | "rotate"))
                .collect();
            self.at(o.span(), f(key), format!("missing (a {tname} needs {})", needs.join(", ")))
        };
        let req_vec = |v: &Option<SVec>, key: &str| -> Res<V3<f64>> {
            match v {
                Some(v) => self.vec3(v, &f(key)),
                None => Err(missing(key)),
            }
        };
        let radius = || -> Res<f64> {
            let Some(r) = &d.radius else {
                return Err(missing("radius"));
            };
            let x = self.number(r, &f("radius"))?;
            if x > 0.0 {
                Ok(x)
            } else {
                Err(self.at(r.span(), f("radius"), format!("must be > 0 and finite, got {x}")))
            }
        };
        let vertices = || -> Res<(Vec<V3<f64>>, Range<usize>)> {
            let Some(vs) = &d.vertices else {
                return Err(missing("vertices"));
            };
            let pts = vs
                .get_ref()
                .iter()
                .enumerate()
                .map(|(k, v)| self.vec3(v, &format!("{}[{k}]", f("vertices"))))
                .collect::<Res<Vec<_>>>()?;
            Ok((pts, vs.span()))
        };
        match tname {
            "sphere" => {
                let center = req_vec(&d.center, "center")?;
                let radius = radius()?;
                Ok(Geometry::Sphere(Sphere { center, radius }))
            }
            "cylinder" => {
                let p1 = req_vec(&d.p1, "p1")?;
                let p2 = req_vec(&d.p2, "p2")?;
                let radius = radius()?;
                let axis = p2 - p1;
                let p2_span = d.p2.as_ref().map_or(o.span(), Spanned::span);
                if axis == V3::zero() {
                    return Err(self.at(p2_span, f("p2"), "must differ from p1 (the cylinder has no axis)"));
                }
                if !axis.is_finite() {
                    return Err(self.at(p2_span, f("p2"), "is too far from p1 (overflow)"));
                }
                let caps = d.caps.as_ref().is_none_or(|c| *c.get_ref());
                Ok(Geometry::Cylinder(Cylinder { p1, p2, radius, caps }))
            }
            "plane" => {
                let point = req_vec(&d.point, "point")?;
                let Some(n) = &d.normal else {
                    return Err(missing("normal"));
                };
                let normal = self.direction(n, &f("normal"))?;
                Ok(Geometry::Plane(Plane { point, normal }))
            }
            "triangle" => {
                let (v, span) = vertices()?;
                if v.len() != 3 {
                    return Err(self.at(
                        span,
                        f("vertices"),
                        format!("a triangle needs exactly 3 vertices, got {}", v.len()),
                    ));
                }
                let longest = (v[1] - v[0])
                    .length_squared()
                    .max((v[2] - v[1]).length_squared())
                    .max((v[0] - v[2]).length_squared());
                let cross = (v[1] - v[0]).cross(v[2] - v[0]).length();
                if !longest.is_finite() || !cross.is_finite() {
                    return Err(self.at(span, f("vertices"), "the triangle is too large (overflow)"));
                }
                if cross.is_nan() || cross <= 1e-12 * longest {
                    return Err(self.at(span, f("vertices"), "degenerate triangle: its vertices are collinear"));
                }
                Ok(Geometry::Triangle(Triangle { v: [v[0], v[1], v[2]] }))
            }
            "polygon" => {
                let (vertices, span) = vertices()?;
                let triangles = polygon::triangulate(&vertices).map_err(|m| self.at(span, f("vertices"), m))?;
                Ok(Geometry::Polygon { vertices, triangles })
            }
            "mesh" => {
                let Some(file) = &d.file else {
                    return Err(missing("file"));
                };
                if file.get_ref().is_empty() {
                    return Err(self.at(file.span(), f("file"), "must not be empty"));
                }
                let t = self.placement(d, field)?;
                let mesh_path = self.base_dir.join(file.get_ref());
                let (triangles, attrs) =
                    mesh::load_obj_with_uvs(&mesh_path, &t, triangle_budget).map_err(|mut message| {
                        if triangle_budget < mesh::MAX_MESH_TRIANGLES {
                            message += &format!(" (a scene holds at most {MAX_SCENE_TRIANGLES} triangles in all)");
                        }
                        let (line, column) = self.line_col(file.span().start);
                        SceneError::Mesh {
                            path: self.path.to_path_buf(),
                            line,
                            column,
                            field: f("file"),
                            mesh: mesh_path.clone(),
                            message,
                        }
                    })?;
                Ok(Geometry::Mesh { file: mesh_path, triangles, attrs, materials: Vec::new() })
            }
            _ => unreachable!("object types are checked above"),
        }
    }

    pub(super) fn scale(&self, s: &Spanned<ScaleDef>, field: &str) -> Res<[f64; 3]> {
        let check = |x: f64, span: Range<usize>, field: &str| -> Res<f64> {
            if !x.is_finite() {
                Err(self.at(span, field, format!("must be finite, got {}", num(x))))
            } else if x == 0.0 {
                Err(self.at(span, field, "must be non-zero and finite, got 0"))
            } else {
                Ok(x)
            }
        };
        match s.get_ref() {
            ScaleDef::Uniform(x) => {
                let x = check(*x, s.span(), field)?;
                Ok([x; 3])
            }
            ScaleDef::PerAxis(v) => {
                if v.len() != 3 {
                    return Err(self.at(
                        s.span(),
                        field,
                        format!("must be a number or have 3 components [x, y, z], got {}", v.len()),
                    ));
                }
                let mut out = [0.0; 3];
                for (k, c) in v.iter().enumerate() {
                    out[k] = check(*c.get_ref(), c.span(), &format!("{field}[{k}]"))?;
                }
                Ok(out)
            }
        }
    }
}

/// A number as TOML spells it (`nan`, not Rust's `NaN`).
pub(super) fn num(x: f64) -> String {
    if x.is_nan() { "nan".to_string() } else { x.to_string() }
}

/// v / |v|, computed without overflow; None for the zero vector.
pub(super) fn unit(v: V3<f64>) -> Option<V3<f64>> {
    let m = v.abs().max_component();
    if m.is_nan() || m <= 0.0 || !m.is_finite() {
        return None;
    }
    let w = v / m;
    Some(w / w.length())
}
