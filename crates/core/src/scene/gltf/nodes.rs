//! The scene's node tree walked, meshes placed, cameras and lights found.

use super::*;

/// Where a node puts what it holds in strahl's space: the node's world matrix after glTF's
/// mirror of z (`m`), then the scene file's placement.
pub(super) struct NodeSpace<'a> {
    m: DMat4,
    placement: &'a Transform,
}

impl NodeSpace<'_> {
    fn point(&self, p: DVec3) -> V3<f64> {
        let q = self.m.transform_point3(p);
        self.placement.apply(V3::new(q.x, q.y, q.z))
    }
}
impl Reader<'_> {
    /// Walks the default scene (else the first; else every root node) and places its meshes,
    /// cameras and lights.
    pub(super) fn scene(&mut self, placement: &Transform, triangle_limit: usize) -> Res<()> {
        let roots: Vec<usize> = match self.doc.default_scene().or_else(|| self.doc.scenes().next()) {
            Some(s) => s.nodes().map(|n| n.index()).collect(),
            None => {
                let mut child = vec![false; self.doc.nodes().len()];
                for n in self.doc.nodes() {
                    for c in n.children() {
                        child[c.index()] = true;
                    }
                }
                (0..child.len()).filter(|&i| !child[i]).collect()
            }
        };
        // Triangles counted from the accessors of every placed primitive, before reading any.
        let mut instances: Vec<(usize, DMat4)> = Vec::new();
        let mut on_path = vec![false; self.doc.nodes().len()];
        for r in roots {
            self.collect(r, DMat4::IDENTITY, 0, &mut on_path, &mut instances)?;
        }
        let mut total: u64 = 0;
        for (node, _) in &instances {
            let Some(mesh) = self.doc.nodes().nth(*node).and_then(|n| n.mesh()) else { continue };
            for p in mesh.primitives() {
                let n = p.indices().or_else(|| p.get(&gltf::Semantic::Positions)).map_or(0, |a| a.count()) as u64;
                total += match p.mode() {
                    gltf::mesh::Mode::Triangles => n / 3,
                    gltf::mesh::Mode::TriangleStrip | gltf::mesh::Mode::TriangleFan => n.saturating_sub(2),
                    _ => 0,
                };
            }
            if total > triangle_limit as u64 {
                return Err(format!("more than {triangle_limit} triangles, the most accepted here"));
            }
        }
        let mut cache: HashMap<(usize, usize), Option<PrimitiveData>> = HashMap::new();
        for (node, world) in instances {
            self.place_node(node, &world, placement, &mut cache)?;
        }
        Ok(())
    }

    /// Collects (node, world matrix) for `node` and its descendants.
    pub(super) fn collect(
        &mut self,
        node: usize,
        parent: DMat4,
        depth: usize,
        on_path: &mut [bool],
        out: &mut Vec<(usize, DMat4)>,
    ) -> Res<()> {
        let at = format!("nodes[{node}]");
        if on_path[node] {
            return Err(format!("{at}: the node hierarchy has a cycle through this node"));
        }
        if depth > MAX_NODE_DEPTH {
            return Err(format!("{at}: the node hierarchy is deeper than {MAX_NODE_DEPTH}"));
        }
        let n = self.doc.nodes().nth(node).expect("validated node index");
        let local = DMat4::from_cols_array_2d(&n.transform().matrix().map(|c| c.map(|v| v as f64)));
        if !local.is_finite() {
            return Err(format!("{at}: its transform is not finite"));
        }
        let world = parent * local;
        if n.skin().is_some() {
            self.warn("skins are not read: skinned meshes are drawn in their bind pose".into());
        }
        out.push((node, world));
        on_path[node] = true;
        for c in n.children() {
            self.collect(c.index(), world, depth + 1, on_path, out)?;
        }
        on_path[node] = false;
        Ok(())
    }

    pub(super) fn place_node(
        &mut self,
        node: usize,
        world: &DMat4,
        placement: &Transform,
        cache: &mut HashMap<(usize, usize), Option<PrimitiveData>>,
    ) -> Res<()> {
        let n = self.doc.nodes().nth(node).expect("validated node index");
        // strahl = placement ∘ mirror(z) ∘ world.
        let mirror = DMat4::from_scale(DVec3::new(1.0, 1.0, -1.0));
        let space = NodeSpace { m: mirror * *world, placement };
        if let Some(mesh) = n.mesh() {
            self.place_mesh(node, &mesh, &space, cache)?;
        }
        if let Some(cam) = n.camera() {
            self.place_camera(node, &cam, &space)?;
        }
        self.place_light(node, &n, &space)
    }

    /// The triangles of `mesh`'s primitives, with their attributes, placed by `space`.
    fn place_mesh(
        &mut self,
        node: usize,
        mesh: &gltf::Mesh,
        space: &NodeSpace,
        cache: &mut HashMap<(usize, usize), Option<PrimitiveData>>,
    ) -> Res<()> {
        let flip = (DMat3::from_mat4(space.m).determinant() < 0.0) != space.placement.mirrors();
        for p in mesh.primitives() {
            let key = (mesh.index(), p.index());
            if let std::collections::hash_map::Entry::Vacant(slot) = cache.entry(key) {
                slot.insert(self.read_primitive(mesh, &p)?);
            }
            let Some(data) = &cache[&key] else { continue };
            let placed: Vec<V3<f64>> = data.positions.iter().map(|&v| space.point(v)).collect();
            if let Some(bad) = placed.iter().position(|v| !v.is_finite()) {
                return Err(format!(
                    "nodes[{node}]: vertex {bad} of meshes[{}] is not finite once placed",
                    mesh.index()
                ));
            }
            // Normals by the inverse transpose of the node's (mirrored) matrix, then the
            // placement's.
            let normal_matrix = DMat3::from_mat4(space.m).inverse().transpose();
            let normals: Option<Vec<[f32; 3]>> = data.normals.as_ref().map(|ns| {
                ns.iter()
                    .map(|&n| {
                        let q = normal_matrix * n;
                        space.placement.apply_normal(V3::new(q.x, q.y, q.z)).cast::<f32>().to_array()
                    })
                    .collect()
            });
            let n = self.out.triangles.len();
            let attrs = &mut self.out.attrs;
            // A list that earlier triangles lacked starts with defaults for them: texel
            // (0, 0), the face's normal (zero), white.
            pub(super) fn open<T: Copy>(list: &mut Vec<[T; 3]>, here: bool, n: usize, default: T) -> bool {
                if (here || !list.is_empty()) && list.len() < n {
                    list.resize(n, [default; 3]);
                }
                here || !list.is_empty()
            }
            let with_uvs = open(&mut attrs.uvs, data.uvs.is_some(), n, [0.0; 2]);
            let with_uvs1 = open(&mut attrs.uvs1, data.uvs1.is_some(), n, [0.0; 2]);
            let with_normals = open(&mut attrs.normals, normals.is_some(), n, [0.0; 3]);
            let with_colors = open(&mut attrs.colors, data.colors.is_some(), n, [1.0; 4]);
            pub(super) fn corners<T: Copy>(list: &Option<Vec<T>>, t: &[u32; 3], default: T, flip: bool) -> [T; 3] {
                let mut c = list.as_ref().map_or([default; 3], |l| t.map(|i| l[i as usize]));
                if flip {
                    c.swap(1, 2);
                }
                c
            }
            for t in &data.triangles {
                let mut v = t.map(|i| placed[i as usize]);
                if flip {
                    v.swap(1, 2);
                }
                self.out.triangles.push(Triangle { v });
                self.out.triangle_materials.push(data.material);
                let attrs = &mut self.out.attrs;
                if with_uvs {
                    attrs.uvs.push(corners(&data.uvs, t, [0.0; 2], flip));
                }
                if with_uvs1 {
                    attrs.uvs1.push(corners(&data.uvs1, t, [0.0; 2], flip));
                }
                if with_normals {
                    attrs.normals.push(corners(&normals, t, [0.0; 3], flip));
                }
                if with_colors {
                    attrs.colors.push(corners(&data.colors, t, [1.0; 4], flip));
                }
            }
        }
        Ok(())
    }

    /// A perspective camera `cam` placed by `space` (an orthographic one is left out with a
    /// warning).
    fn place_camera(&mut self, node: usize, cam: &gltf::Camera, space: &NodeSpace) -> Res<()> {
        match cam.projection() {
            gltf::camera::Projection::Perspective(p) => {
                let eye = space.point(DVec3::ZERO);
                let ahead = space.point(DVec3::new(0.0, 0.0, -1.0));
                let above = space.point(DVec3::new(0.0, 1.0, 0.0));
                let fov_y = (p.yfov() as f64).to_degrees();
                let camera = Camera { eye, look_at: ahead, up: above - eye, fov_y };
                let at = format!("cameras[{}]", cam.index());
                if !(fov_y > 0.0 && fov_y < 180.0) {
                    return Err(format!("{at}.perspective.yfov: {} radians is not a field of view", p.yfov()));
                }
                if (ahead - eye).length() == 0.0
                    || (above - eye).cross(ahead - eye).length()
                        <= 1e-9 * (above - eye).length() * (ahead - eye).length()
                {
                    return Err(format!("nodes[{node}]: the transform of {at} is degenerate"));
                }
                let aspect = p.aspect_ratio().map(|a| a as f64).filter(|a| *a > 0.0 && a.is_finite());
                self.out.cameras.push(PlacedCamera {
                    index: cam.index(),
                    name: cam.name().map(String::from),
                    camera,
                    aspect,
                });
            }
            gltf::camera::Projection::Orthographic(_) => {
                self.warn(format!("cameras[{}]: orthographic cameras are not read", cam.index()));
            }
        }
        Ok(())
    }

    /// The punctual light of node `n`, if any, placed by `space`.
    fn place_light(&mut self, node: usize, n: &gltf::Node, space: &NodeSpace) -> Res<()> {
        let known_type = |i: usize| {
            let json = self.doc.as_json().extensions.as_ref().and_then(|e| e.khr_lights_punctual.as_ref());
            json.and_then(|l| l.lights.get(i))
                .is_some_and(|l| matches!(l.type_, gltf::json::validation::Checked::Valid(_)))
        };
        if let Some(light) = n.light()
            && !known_type(light.index())
        {
            self.warn(format!(
                "KHR_lights_punctual.lights[{}]: a light type glTF does not define: skipped",
                light.index()
            ));
        } else if let Some(light) = n.light() {
            let c = light.color();
            let intensity = c.map(|c| (c as f64 * light.intensity() as f64).max(0.0));
            let at = format!("KHR_lights_punctual.lights[{}]", light.index());
            match light.kind() {
                gltf::khr_lights_punctual::Kind::Point => {
                    let position = space.point(DVec3::ZERO);
                    let range = light.range().map_or(0.0, |r| r as f64).max(0.0);
                    self.out.lights.push(Light::Point { position, intensity, range });
                }
                gltf::khr_lights_punctual::Kind::Directional => {
                    let d = space.point(DVec3::new(0.0, 0.0, -1.0)) - space.point(DVec3::ZERO);
                    if d.length() > 0.0 && d.is_finite() {
                        self.out.lights.push(Light::Directional { direction: d.normalize(), intensity });
                    } else {
                        return Err(format!("nodes[{node}]: the transform of {at} is degenerate"));
                    }
                }
                gltf::khr_lights_punctual::Kind::Spot { inner_cone_angle, outer_cone_angle } => {
                    let position = space.point(DVec3::ZERO);
                    let d = space.point(DVec3::new(0.0, 0.0, -1.0)) - position;
                    if !(d.length() > 0.0 && d.is_finite()) {
                        return Err(format!("nodes[{node}]: the transform of {at} is degenerate"));
                    }
                    // The extension's bounds: 0 <= inner < outer <= pi/2.
                    let outer = (outer_cone_angle as f64).clamp(0.0, std::f64::consts::FRAC_PI_2);
                    let inner = (inner_cone_angle as f64).clamp(0.0, outer);
                    if (inner, outer) != (inner_cone_angle as f64, outer_cone_angle as f64) {
                        self.warn(format!(
                            "{at}: spot cone angles {inner_cone_angle} and {outer_cone_angle} are outside \
                             0 <= inner <= outer <= pi/2: {inner} and {outer} are used"
                        ));
                    }
                    let range = light.range().map_or(0.0, |r| r as f64).max(0.0);
                    self.out.lights.push(Light::Spot {
                        position,
                        direction: d.normalize(),
                        intensity,
                        inner,
                        outer,
                        range,
                    });
                }
            }
        }
        Ok(())
    }

    /// The data of one mesh primitive, or None (with a warning) when it is not made of
    /// triangles.
    pub(super) fn read_primitive(&mut self, mesh: &gltf::Mesh, p: &gltf::Primitive) -> Res<Option<PrimitiveData>> {
        let at = format!("meshes[{}].primitives[{}]", mesh.index(), p.index());
        let named = match mesh.name() {
            Some(n) => format!("{at} (mesh \"{n}\")"),
            None => at.clone(),
        };
        let mode = p.mode();
        if !matches!(
            mode,
            gltf::mesh::Mode::Triangles | gltf::mesh::Mode::TriangleStrip | gltf::mesh::Mode::TriangleFan
        ) {
            self.warn(format!("{named}: mode {mode:?} is not triangles: skipped"));
            return Ok(None);
        }
        if p.morph_targets().len() > 0 {
            self.warn(format!("{named}: morph targets are not read: the base shape is drawn"));
        }
        let Some(pos_acc) = p.get(&gltf::Semantic::Positions) else {
            self.warn(format!("{named}: no POSITION: skipped"));
            return Ok(None);
        };
        let pos = self.read_accessor(&pos_acc, &format!("{at}.attributes.POSITION"), &[Dimensions::Vec3])?;
        let positions: Vec<DVec3> = pos.chunks_exact(3).map(|c| DVec3::new(c[0], c[1], c[2])).collect();
        let nv = positions.len();
        let attribute = |this: &mut Self, semantic: gltf::Semantic, dims: &[Dimensions]| -> Res<Option<Vec<f64>>> {
            let Some(acc) = p.get(&semantic) else { return Ok(None) };
            let what = format!("{at}.attributes.{}", semantic.to_string());
            let values = this.read_accessor(&acc, &what, dims)?;
            let width = values.len().checked_div(nv).unwrap_or(0);
            if acc.count() != nv {
                return Err(format!("{what}: {} elements for {nv} vertices", acc.count()));
            }
            Ok(Some(if width == 3 && dims.contains(&Dimensions::Vec4) {
                // RGB colours: opaque.
                values.chunks_exact(3).flat_map(|c| [c[0], c[1], c[2], 1.0]).collect()
            } else {
                values
            }))
        };
        let pairs = |v: Vec<f64>| -> Vec<[f32; 2]> { v.chunks_exact(2).map(|c| [c[0] as f32, c[1] as f32]).collect() };
        let uvs = attribute(self, gltf::Semantic::TexCoords(0), &[Dimensions::Vec2])?.map(pairs);
        let uvs1 = attribute(self, gltf::Semantic::TexCoords(1), &[Dimensions::Vec2])?.map(pairs);
        let normals = attribute(self, gltf::Semantic::Normals, &[Dimensions::Vec3])?
            .map(|v| v.chunks_exact(3).map(|c| DVec3::new(c[0], c[1], c[2])).collect());
        let colors = attribute(self, gltf::Semantic::Colors(0), &[Dimensions::Vec3, Dimensions::Vec4])?.map(|v| {
            v.chunks_exact(4)
                .map(|c| [c[0] as f32, c[1] as f32, c[2] as f32, c[3] as f32].map(|x| x.clamp(0.0, 1.0)))
                .collect()
        });
        let indices: Vec<u32> = match p.indices() {
            Some(acc) => {
                let what = format!("{at}.indices");
                if !matches!(acc.data_type(), DataType::U8 | DataType::U16 | DataType::U32) {
                    return Err(format!("{what} (accessors[{}]): indices must be unsigned integers", acc.index()));
                }
                let raw = self.read_accessor(&acc, &what, &[Dimensions::Scalar])?;
                let mut out = Vec::with_capacity(raw.len());
                for (k, &i) in raw.iter().enumerate() {
                    if i as usize >= nv {
                        return Err(format!("{what}: index {i} at position {k} is out of range ({nv} vertices)"));
                    }
                    out.push(i as u32);
                }
                out
            }
            None => (0..nv as u32).collect(),
        };
        let triangles: Vec<[u32; 3]> = match mode {
            gltf::mesh::Mode::Triangles => {
                if !indices.len().is_multiple_of(3) {
                    self.warn(format!(
                        "{named}: {} indices are not a whole number of triangles: the rest is skipped",
                        indices.len()
                    ));
                }
                indices.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
            }
            // Strips alternate their winding so that every triangle faces the same way.
            gltf::mesh::Mode::TriangleStrip => (2..indices.len())
                .map(|k| {
                    if k % 2 == 0 {
                        [indices[k - 2], indices[k - 1], indices[k]]
                    } else {
                        [indices[k - 1], indices[k - 2], indices[k]]
                    }
                })
                .collect(),
            _ => (2..indices.len()).map(|k| [indices[0], indices[k - 1], indices[k]]).collect(),
        };
        let material = match p.material().index() {
            Some(i) => i as u32,
            None => (self.out.materials.len() - 1) as u32,
        };
        Ok(Some(PrimitiveData { positions, uvs, uvs1, normals, colors, triangles, material }))
    }
}
