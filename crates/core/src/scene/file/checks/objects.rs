//! A scene file's objects: each kind of geometry, glTF files placed, scales.

use super::*;

impl Cx<'_> {
    /// `[[objects]] type = "gltf"`: the file's triangles with their materials (appended to
    /// `loaded.materials`, their textures to `loaded.textures`) and its punctual lights, placed
    /// by the object's transform. Its cameras are not used (the scene file has its own).
    pub(crate) fn gltf_object(
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
    pub(crate) fn placement(&self, d: &ObjectDef, field: &str) -> Res<Transform> {
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

    /// Object `o`; a mesh may add at most `triangle_budget` triangles to the scene.
    pub(crate) fn object(&self, o: &Spanned<ObjectDef>, field: &str, triangle_budget: usize) -> Res<Geometry> {
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

    pub(crate) fn scale(&self, s: &Spanned<ScaleDef>, field: &str) -> Res<[f64; 3]> {
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
