//! The checks: every value of the scene file validated and turned into the [`Scene`]: the
//! values themselves, camera, image, render settings, lights and environment here; objects
//! (with their meshes and glTF files) and materials in their own files. Every check carries
//! its own located message.

use super::*;

mod materials;
mod objects;

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
        if tname != "spot" {
            for (key, span) in [
                ("inner_angle", d.inner_angle.as_ref().map(|v| v.span())),
                ("outer_angle", d.outer_angle.as_ref().map(|v| v.span())),
            ] {
                if let Some(span) = span {
                    return Err(not_a_field(key, span));
                }
            }
        }
        if tname == "directional"
            && let Some(v) = &d.range
        {
            return Err(not_a_field("range", v.span()));
        }
        // A point or spot light's reach (KHR_lights_punctual's `range`; 0: unlimited).
        let range = || -> Res<f64> {
            let Some(v) = &d.range else { return Ok(0.0) };
            let range = self.number(v, &format!("{field}.range"))?;
            if !(range > 0.0) {
                return Err(self.at(v.span(), format!("{field}.range"), format!("must be > 0, got {range}")));
            }
            Ok(range)
        };
        match tname {
            "spot" => {
                let position = self.vec3(&require(&d.position, "position")?, &format!("{field}.position"))?;
                let direction = self.direction(&require(&d.direction, "direction")?, &format!("{field}.direction"))?;
                // Half-angles of the cone in degrees, KHR_lights_punctual's defaults.
                let angle = |v: &Option<Spanned<f64>>, key: &str, default: f64| -> Res<f64> {
                    let Some(v) = v else { return Ok(default) };
                    let x = self.number(v, &format!("{field}.{key}"))?;
                    if !(0.0..=90.0).contains(&x) {
                        return Err(self.at(
                            v.span(),
                            format!("{field}.{key}"),
                            format!("must be in [0, 90] degrees, got {x}"),
                        ));
                    }
                    Ok(x)
                };
                let inner = angle(&d.inner_angle, "inner_angle", 0.0)?;
                let outer = angle(&d.outer_angle, "outer_angle", 45.0)?;
                if inner >= outer {
                    let span = d.inner_angle.as_ref().map_or(l.span(), |v| v.span());
                    return Err(self.at(
                        span,
                        format!("{field}.inner_angle"),
                        format!("must be less than outer_angle ({outer}), got {inner}"),
                    ));
                }
                Ok(Light::Spot {
                    position,
                    direction,
                    intensity: intensity(self)?,
                    inner: inner.to_radians(),
                    outer: outer.to_radians(),
                    range: range()?,
                })
            }
            "point" => {
                if let Some(v) = &d.direction {
                    return Err(not_a_field("direction", v.span()));
                }
                let position = self.vec3(&require(&d.position, "position")?, &format!("{field}.position"))?;
                Ok(Light::Point { position, intensity: intensity(self)?, range: range()? })
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
                format!("unknown light type \"{tname}\"; known: point, directional, spot"),
            )),
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
