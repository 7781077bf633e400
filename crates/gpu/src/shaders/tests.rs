use super::*;
use std::collections::HashMap;

/// Every key of the flags before [`FeatureKey::ASSETS`] (all programs), and the five valid
/// combinations of the asset flags over the flags whose code the asset code meets
/// (spheres and triangles: emitter sampling and texture lookups; BVH; point lights: the
/// path tracer's light loop; emissive and dielectric: emitters and shadow crossing), for
/// the shading programs that read them: 2048 + 5 × 64 keys instead of 2^14 (the other
/// flags only change traversal and BSDF code, which the asset code does not touch).
fn keys_to_validate() -> Vec<FeatureKey> {
    let below_assets = || (0..1u32 << FeatureKey::ASSETS.bits().trailing_zeros()).map(FeatureKey::from_bits_retain);
    let mut keys: Vec<FeatureKey> = below_assets().collect();
    let met = FeatureKey::SPHERES
        | FeatureKey::TRIANGLES
        | FeatureKey::BVH
        | FeatureKey::POINT_LIGHTS
        | FeatureKey::EMISSIVE
        | FeatureKey::DIELECTRIC;
    for assets in [
        FeatureKey::PBR | FeatureKey::ALPHA | FeatureKey::TEXTURES,
        FeatureKey::ALPHA,
        FeatureKey::PBR,
        FeatureKey::PBR | FeatureKey::TEXTURES,
        FeatureKey::TEXTURES,
        FeatureKey::ENVIRONMENT,
        FeatureKey::ENVIRONMENT | FeatureKey::ENV_MAP,
        FeatureKey::TEXTURES | FeatureKey::ENVIRONMENT,
        FeatureKey::ROUGH_GLASS | FeatureKey::ABSORPTION,
        FeatureKey::PBR | FeatureKey::ROUGH_GLASS | FeatureKey::ABSORPTION,
        FeatureKey::PBR | FeatureKey::LAYERS,
        FeatureKey::PBR | FeatureKey::ROUGH_GLASS | FeatureKey::LAYERS | FeatureKey::TEXTURES,
        FeatureKey::ALL & FeatureKey::ASSETS,
    ] {
        keys.extend(below_assets().filter(|&k| met.contains(k)).map(|k| k | assets));
    }
    keys
}

#[test]
fn every_feature_key_composes_and_validates() {
    use rayon::prelude::*;
    let failures: Vec<String> = keys_to_validate()
        .into_par_iter()
        .flat_map_iter(|key| {
            Program::ALL.into_iter().filter(move |&p| key.for_program(p) == key).filter_map(move |p| {
                match compose(p, key) {
                    Ok(m) => validate(p, key, &m).err().map(|e| e.to_string()),
                    Err(e) => Some(format!("{}: {e}", key.label())),
                }
            })
        })
        .collect();
    assert!(failures.is_empty(), "{} variants fail, first: {}", failures.len(), failures[0]);
}

/// Splits of every array alone into 2, 3 and 4 parts, and of all three into 2 and 4, with
/// the geometry of a mesh and with every feature, with and without 64-bit loads.
fn split_keys() -> Vec<FeatureKey> {
    use crate::split::Split;
    let mut splits = vec![[2, 2, 2], [4, 4, 4]];
    for i in 0..3 {
        splits.extend((2..=4).map(|p| {
            let mut s = [1; 3];
            s[i] = p;
            s
        }));
    }
    let mesh = FeatureKey::TRIANGLES | FeatureKey::BVH | FeatureKey::POINT_LIGHTS;
    let mut keys = Vec::new();
    for parts in splits {
        let split = Split::with_parts(parts, 27).key();
        for base in [mesh, FeatureKey::ALL] {
            keys.extend([base | split, base | split | FeatureKey::LOAD64]);
        }
    }
    keys
}

#[test]
fn every_split_composes_and_validates() {
    use rayon::prelude::*;
    let failures: Vec<String> = split_keys()
        .into_par_iter()
        .flat_map_iter(|key| {
            Program::ALL.into_iter().filter_map(move |p| match compose(p, key) {
                Ok(m) => validate(p, key, &m).err().map(|e| e.to_string()),
                Err(e) => Some(format!("{}: {e}", key.label())),
            })
        })
        .collect();
    assert!(failures.is_empty(), "{} variants fail, first: {}", failures.len(), failures[0]);
}

/// The BSDF probe (`crate::bsdf_probe`, the one [`DIAGNOSTIC`] program) composes and validates
/// for every combination of the flags its key keeps (`NOT_READ`: the others are off); like
/// the render programs it binds no uniform and at most WebGPU's 8 storage buffers, in group 0
/// only the scene's.
#[test]
fn the_bsdf_probe_composes_and_validates_for_every_key() {
    use crate::{MIN_STORAGE_BUFFERS, SCENE_BINDINGS, bsdf_probe::NOT_READ};
    assert_eq!(DIAGNOSTIC, [BSDF_PROBE]);
    let flags: Vec<FeatureKey> = (FeatureKey::ALL - NOT_READ).iter().collect();
    let keys: Vec<FeatureKey> = (0..1u32 << flags.len())
        .map(|set| {
            flags.iter().enumerate().filter(|(i, _)| set >> i & 1 == 1).fold(FeatureKey::empty(), |k, (_, &f)| k | f)
        })
        .collect();
    let failures: Vec<String> = keys
        .iter()
        .filter_map(|&key| {
            let m = match compose_diagnostic(BSDF_PROBE, key) {
                Ok(m) => m,
                Err(e) => return Some(e.to_string()),
            };
            if let Err(e) = naga::valid::Validator::new(naga::valid::ValidationFlags::all(), CAPABILITIES).validate(&m)
            {
                return Some(format!("{}: {:?}", key.label(), e.into_inner()));
            }
            let spaces: Vec<naga::AddressSpace> = m.global_variables.iter().map(|(_, g)| g.space).collect();
            let storage = spaces.iter().filter(|s| matches!(s, naga::AddressSpace::Storage { .. })).count() as u32;
            let scene = group_bindings(&m, 0);
            let fits = storage <= MIN_STORAGE_BUFFERS
                && !spaces.contains(&naga::AddressSpace::Uniform)
                && scene.iter().all(|&b| b < SCENE_BINDINGS);
            (!fits).then(|| format!("{}: {storage} storage buffers, group 0 {scene:?}", key.label()))
        })
        .collect();
    assert!(flags.contains(&FeatureKey::PBR) && flags.contains(&FeatureKey::ROUGH_GLASS), "{flags:?}");
    assert!(failures.is_empty(), "{} of {} keys fail, first: {}", failures.len(), keys.len(), failures[0]);
}

/// A split variant declares each part after the first at the binding the host binds it
/// to (split::extra_binding); an unsplit variant declares none of them. Both read the arrays
/// through the same accessors.
#[test]
fn parts_are_declared_where_the_host_binds_them_and_only_in_split_variants() {
    use crate::split::{MAX_PARTS, Split, SplitArray, extra_binding};
    let names = |a: SplitArray| match a {
        SplitArray::Triangles => "triangles",
        SplitArray::Nodes => "nodes",
        SplitArray::LeafTriangles => "leaf_triangles",
    };
    for load64 in [FeatureKey::empty(), FeatureKey::LOAD64] {
        let split = FeatureKey::ALL | load64 | Split::with_parts([4, 4, 4], 27).key();
        let m = compose(Program::Path, split).unwrap();
        let bindings: HashMap<String, u32> = m
            .global_variables
            .iter()
            .filter_map(|(_, g)| {
                let name = g.name.as_deref()?.split("X_naga_oil_mod_X").next()?.to_string();
                Some((name, g.binding.as_ref()?.binding))
            })
            .collect();
        for array in SplitArray::ALL {
            for p in 1..MAX_PARTS {
                let name = format!("{}_{p}", names(array));
                assert_eq!(bindings.get(&name), Some(&extra_binding(array, p)), "{name}");
            }
        }
        let text = to_wgsl(&m, &validate(Program::Path, split, &m).unwrap());
        let unsplit = FeatureKey::ALL | load64;
        let plain = compose(Program::Path, unsplit).unwrap();
        let plain_text = to_wgsl(&plain, &validate(Program::Path, unsplit, &plain).unwrap());
        for f in ["triangles_1", "nodes_1", "leaf_triangles_1"] {
            assert!(text.contains(f), "{f} missing from the split variant");
            assert!(!plain_text.contains(f), "{f} in the unsplit variant");
        }
        for f in ["fn scene_triangle", "fn node_element", "fn leaf_element"] {
            assert!(text.contains(f) && plain_text.contains(f), "{f} missing from a variant");
        }
    }
}

/// Scenes with what no shipped scene has, written to `dir`: an image texture on a mesh, an
/// emission texture, an environment map, a constant environment, and emissive objects
/// alone (lit in Whitted mode by their stand-in point lights).
fn asset_scenes(dir: &std::path::Path) -> Vec<std::path::PathBuf> {
    image::RgbImage::from_fn(4, 4, |x, y| image::Rgb([(x * 60) as u8, (y * 60) as u8, 90]))
        .save(dir.join("checker.png"))
        .unwrap();
    image::Rgb32FImage::from_fn(8, 4, |x, _| image::Rgb([0.2, 0.3, x as f32])).save(dir.join("sky.exr")).unwrap();
    let obj = "v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n";
    std::fs::write(dir.join("quad.obj"), obj).unwrap();
    let head = "[camera]\neye = [0.0, 1.0, -4.0]\nlook_at = [0.0, 0.0, 0.0]\nup = [0.0, 1.0, 0.0]\nfov_y = 50.0\n\
                [image]\nwidth = 8\nheight = 6\n";
    let sphere = "[[objects]]\ntype = \"sphere\"\ncenter = [0.0, 0.5, 0.0]\nradius = 0.5\nmaterial = \"m\"\n";
    let quad =
        |material: &str| format!("[[objects]]\ntype = \"mesh\"\nfile = \"quad.obj\"\nmaterial = \"{material}\"\n");
    let light = "[[lights]]\ntype = \"point\"\nposition = [0.0, 3.0, 0.0]\nintensity = [5.0, 5.0, 5.0]\n";
    // A glTF triangle whose material blends by alpha (TOML materials have no alpha).
    let positions: Vec<u8> =
        [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]].iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
    use base64::Engine;
    let data = base64::engine::general_purpose::STANDARD.encode(&positions);
    let veil = format!(
        r#"{{"asset": {{"version": "2.0"}}, "scenes": [{{"nodes": [0]}}], "nodes": [{{"mesh": 0}}],
        "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "material": 0}}]}}],
        "materials": [{{"pbrMetallicRoughness": {{"baseColorFactor": [1, 1, 1, 0.5]}}, "alphaMode": "BLEND"}}],
        "buffers": [{{"uri": "data:application/octet-stream;base64,{data}", "byteLength": 36}}],
        "bufferViews": [{{"buffer": 0, "byteLength": 36}}],
        "accessors": [{{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
            "min": [0, 0, 0], "max": [1, 1, 0]}}]}}"#
    );
    std::fs::write(dir.join("veil.gltf"), veil).unwrap();
    let scenes = [
        (
            "textured.toml",
            format!(
                "{head}[[materials]]\nname = \"m\"\ntype = \"diffuse\"\ntexture = \"checker.png\"\n\
                 [[materials]]\nname = \"glow\"\ntype = \"emissive\"\nradiance = [2.0, 2.0, 2.0]\n\
                 radiance_texture = \"checker.png\"\n{}{light}[environment]\nfile = \"sky.exr\"\n",
                quad("m") + &quad("glow")
            ),
        ),
        (
            "constant_sky.toml",
            format!(
                "{head}[[materials]]\nname = \"m\"\ntype = \"mirror\"\n{sphere}{light}[environment]\nradiance = [0.5, 0.6, 0.7]\n"
            ),
        ),
        (
            "pbr.toml",
            format!(
                "{head}[[materials]]\nname = \"m\"\ntype = \"pbr\"\nmetallic = 0.5\nroughness = 0.4\n\
                 radiance = [0.5, 0.5, 0.5]\nclearcoat = 0.5\n{sphere}{light}"
            ),
        ),
        ("alpha.toml", format!("{head}[[objects]]\ntype = \"gltf\"\nfile = \"veil.gltf\"\n{light}")),
        (
            "emitters_only.toml",
            format!(
                "{head}[[materials]]\nname = \"m\"\ntype = \"emissive\"\nradiance = [4.0, 4.0, 4.0]\n{sphere}{}",
                quad("m")
            ),
        ),
    ];
    scenes
        .into_iter()
        .map(|(name, text)| {
            let path = dir.join(name);
            std::fs::write(&path, text).unwrap();
            path
        })
        .collect()
}

/// The key read from a scene equals the key of its flattened buffers, for every shipped
/// scene, for scenes with textures and environments, and for the viewer's way of keying a
/// scene while objects are hidden.
#[test]
fn the_key_of_a_scene_is_the_key_of_its_buffers() {
    let dir = std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../assets/scenes"));
    let assets = tempfile::tempdir().unwrap();
    let mut paths: Vec<_> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().path()).collect();
    paths.extend(asset_scenes(assets.path()));
    let mut seen = 0;
    let mut flags = FeatureKey::empty();
    for path in paths {
        if path.extension().is_none_or(|x| x != "toml") {
            continue;
        }
        let scene = strahl_core::scene::Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
        let prep = strahl_core::render::Prepared::new(scene.clone());
        assert_eq!(FeatureKey::of_scene(&scene, &prep.prims), FeatureKey::for_scene(&prep.flat), "{}", path.display());
        flags |= FeatureKey::for_scene(&prep.flat);
        seen += 1;
    }
    assert!(seen >= 11, "only {seen} scenes");
    // Every scene flag was met by some scene.
    assert!(flags.contains(FeatureKey::ALL), "flags no scene had: {}", (FeatureKey::ALL - flags).label());
}

#[test]
fn a_sphere_only_shader_contains_no_other_primitive_code() {
    let key = FeatureKey::SPHERES | FeatureKey::POINT_LIGHTS;
    let m = compose(Program::Whitted, key).unwrap();
    let text = to_wgsl(&m, &validate(Program::Whitted, key, &m).unwrap());
    assert!(text.contains("sphere_roots"), "the sphere code is there");
    // Case-sensitive identifiers of other primitives' code and types (naga_oil's name
    // decorations are upper-case base32 and cannot spell them).
    let absent_items = [
        "Cylinder",
        "cylinder_roots",
        "cap_root",
        "Triangle",
        "triangle_intersect",
        "Shear",
        "Plane",
        "plane_roots",
        "refract",
        "fresnel",
        "Node",
        "slab",
        "nodes",
        "texture_sample",
        "texels",
        "triangle_attrs",
        "env_background",
        "env_distribution",
        "Environment",
    ];
    for absent in absent_items {
        assert!(!text.contains(absent), "{absent} found in the sphere-only shader");
    }
    let all = compose(Program::Whitted, FeatureKey::ALL).unwrap();
    let all_text = to_wgsl(&all, &validate(Program::Whitted, FeatureKey::ALL, &all).unwrap());
    for present in [
        "cylinder_roots",
        "triangle_intersect",
        "plane_roots",
        "fresnel_dielectric",
        "slab",
        "texture_sample",
        "env_background",
    ] {
        assert!(all_text.contains(present), "{present} missing from the all-features shader");
    }
    assert!(text.len() * 2 < all_text.len(), "{} vs {} bytes", text.len(), all_text.len());
}

/// lavapipe 22 leaks a compiled shader per pipeline bind when a uniform steers control
/// flow (shaders/modules/bindings.wgsl): no program binds a uniform buffer.
#[test]
fn no_program_binds_a_uniform_buffer() {
    for p in Program::ALL {
        let key = FeatureKey::ALL.for_program(p);
        let m = compose(p, key).unwrap();
        let uniforms: Vec<_> = m
            .global_variables
            .iter()
            .filter(|(_, g)| g.space == naga::AddressSpace::Uniform)
            .map(|(_, g)| g.name.clone())
            .collect();
        assert!(uniforms.is_empty(), "{p:?} binds uniforms {uniforms:?}");
    }
}

/// The constants of the composed shaders hold the values the host shares with them
/// (super::shared), as naga evaluated them.
#[test]
fn shared_constants_reach_the_composed_shaders_exactly() {
    use crate::shared::{Shared, constants};
    let shared: HashMap<&str, Shared> = constants().into_iter().collect();
    let mut seen = std::collections::HashSet::new();
    // Without a BVH for the counts of the brute-force loops; and the standalone shaders.
    let keys = [FeatureKey::ALL, FeatureKey::ALL | FeatureKey::LOAD64, FeatureKey::ALL - FeatureKey::BVH];
    let mut modules: Vec<(String, naga::Module)> =
        Program::ALL.into_iter().flat_map(|p| keys.map(|key| (format!("{p:?}"), compose(p, key).unwrap()))).collect();
    for (file, src) in super::STANDALONE {
        modules.push((file.to_string(), naga::front::wgsl::parse_str(&crate::shared::substitute(src)).unwrap()));
    }
    {
        for (p, m) in &modules {
            for (_, c) in m.constants.iter() {
                let Some(name) = c.name.as_deref().and_then(|n| n.split("X_naga_oil_mod_X").next()) else {
                    continue;
                };
                let Some(&want) = shared.get(name) else { continue };
                let literal = |e: &naga::Expression| match *e {
                    naga::Expression::Literal(naga::Literal::U32(v)) => Shared::U32(v),
                    naga::Expression::Literal(naga::Literal::F32(v)) => Shared::F32(v),
                    ref e => panic!("{name}: not a literal: {e:?}"),
                };
                let got = match (&m.global_expressions[c.init], want) {
                    (naga::Expression::Compose { components, .. }, Shared::F32s(values)) => {
                        let found: Vec<Shared> =
                            components.iter().map(|&h| literal(&m.global_expressions[h])).collect();
                        let wanted: Vec<Shared> = values.iter().map(|&v| Shared::F32(v)).collect();
                        assert_eq!(found, wanted, "the table {name} in the {p} shader");
                        want
                    }
                    (e, _) => literal(e),
                };
                assert_eq!(got, want, "{name} in the {p} shader");
                seen.insert(name.to_string());
            }
        }
    }
    // Workgroup sizes are attributes and the stack depth an array length, not constants.
    let m = compose(Program::Path, FeatureKey::ALL).unwrap();
    let stack_len = m.types.iter().find_map(|(_, ty)| match &ty.inner {
        naga::TypeInner::Struct { members, .. } if ty.name.as_deref()?.starts_with("Stack") => {
            match m.types[members[0].ty].inner {
                naga::TypeInner::Array { size: naga::ArraySize::Constant(n), .. } => Some(n.get()),
                _ => None,
            }
        }
        _ => None,
    });
    assert_eq!(stack_len.map(Shared::U32), shared.get("GPU_STACK").copied(), "the traversal stack's length");
    // The table's length is its array's (checked with its values above); its row count, and
    // the dielectric table's count of index ratios, fold into the constant expressions that
    // use them.
    let folded = |n: &str| {
        n.ends_with("WORKGROUP")
            || [
                "GPU_STACK",
                "GGX_ALBEDO_LEN",
                "GGX_ROUGHNESS_STEPS",
                "DIELECTRIC_ETA_STEPS",
                "SHEEN_ALBEDO_LEN",
                "SHEEN_ROUGHNESS_STEPS",
            ]
            .contains(&n)
    };
    let missing: Vec<_> = shared.keys().filter(|n| !seen.contains(**n) && !folded(n)).collect();
    assert!(missing.is_empty(), "not found as constants: {missing:?}");
}

/// Every struct the host writes into a GPU buffer has, in the composed WGSL module, the
/// size and member offsets of its Rust twin (as naga's layouter computes them).
#[test]
fn wgsl_struct_layouts_equal_the_rust_structs() {
    use crate::closest::GpuClosestPoint;
    use std::mem::{offset_of, size_of};
    use strahl_core::accel::gpu_bvh::{GpuLeafTriangle, GpuNode};
    use strahl_core::layout::*;
    macro_rules! layout {
        ($wgsl:literal, $t:ty, [$($f:ident),*]) => {
            ($wgsl, size_of::<$t>(), vec![$((stringify!($f), offset_of!($t, $f))),*])
        };
    }
    let expected = [
        layout!(
            "Frame",
            FrameParams,
            [
                eye,
                width,
                forward,
                height,
                right,
                spp,
                up,
                max_depth,
                background,
                _pad,
                ambient,
                num_lights,
                tile_origin,
                tile_size,
                sample_base,
                out_pitch,
                out_first_row,
                flags,
                num_emitters,
                emitter_norm,
                rr_depth,
                seed
            ]
        ),
        layout!("Sphere", FlatSphere, [center, radius, object, face, material, _pad]),
        layout!("Cylinder", FlatCylinder, [pa, radius, pb, caps, object, face, material, _pad]),
        layout!("Plane", FlatPlane, [point, object, normal, material]),
        layout!("Triangle", FlatTriangle, [va, object, vb, face, vc, material]),
        layout!("Node", GpuNode, [lo_a, link_a, hi_a, link_b, lo_b, _pad_a, hi_b, _pad_b]),
        layout!("LeafTriangle", GpuLeafTriangle, [va, index, vb, material, vc, _pad]),
        layout!(
            "Material",
            FlatMaterial,
            [
                color,
                kind,
                radiance,
                ior,
                roughness,
                flags,
                color_texture,
                radiance_texture,
                metallic,
                metal_rough_texture,
                normal_texture,
                normal_scale,
                alpha,
                alpha_cutoff,
                clearcoat,
                clearcoat_roughness,
                absorption,
                transmission,
                spec_at_normal,
                spec_at_grazing,
                sheen_color,
                sheen_roughness
            ]
        ),
        layout!("TextureInfo", FlatTexture, [width, height, offset, flags, linear, offset_uv, _pad]),
        layout!("TriangleAttrs", FlatTriangleAttrs, [uv, second_uv, normal, color, flags, _pad]),
        layout!(
            "Environment",
            FlatEnvironment,
            [radiance, flags, rot_cos, rot_sin, texture, select_prob, width, height, _pad, sh]
        ),
        layout!("Light", FlatLight, [vector, kind, intensity, flags, axis, cone_scale, cone_offset, range, _pad]),
        layout!("Emitter", FlatEmitter, [source, kind, cdf, pdf]),
        layout!("QueryRay", GpuQueryRay, [origin, tmin, dir, tmax]),
        layout!("QueryHit", GpuQueryHit, [normal, t, object, face, prim_ref, flags]),
        layout!("ClosestPoint", GpuClosestPoint, [point, dist_sq, uv, prim_ref, part]),
    ];
    // Every struct is used by one of these programs in its all-features variant.
    let modules = [
        compose(Program::Whitted, FeatureKey::ALL).unwrap(),
        compose(Program::Path, FeatureKey::ALL).unwrap(),
        compose(Program::Trace, FeatureKey::ALL).unwrap(),
        compose(Program::Closest, FeatureKey::ALL).unwrap(),
    ];
    for (name, size, fields) in expected {
        let found = modules.iter().find_map(|m| {
            let mut layouter = naga::proc::Layouter::default();
            layouter.update(m.to_ctx()).unwrap();
            m.types.iter().find_map(|(h, ty)| {
                let undecorated = ty.name.as_deref()?.split("X_naga_oil_mod_X").next()?;
                match &ty.inner {
                    naga::TypeInner::Struct { members, .. } if undecorated == name => {
                        Some((layouter[h].size, members.clone()))
                    }
                    _ => None,
                }
            })
        });
        let (wgsl_size, members) = found.unwrap_or_else(|| panic!("struct {name} not found in the composed shaders"));
        assert_eq!(wgsl_size as usize, size, "size of {name}");
        // Padding is `_pad` in Rust (unused) and `pad` in WGSL.
        let wgsl_name = |f: &str| f.trim_start_matches('_').to_string();
        // Every member on each side is in the list, so none is checked only through the size.
        let listed: Vec<String> = fields.iter().map(|(f, _)| wgsl_name(f)).collect();
        let in_wgsl: Vec<String> = members.iter().map(|m| m.name.clone().unwrap_or_default()).collect();
        assert_eq!(in_wgsl, listed, "the members of WGSL {name}, in order");
        let rust_name = rust_struct_of(name);
        let in_rust: Vec<String> = rust_fields(rust_name).iter().map(|f| wgsl_name(f)).collect();
        assert_eq!(in_rust, listed, "the fields of {rust_name}, in order");
        for ((field, offset), m) in fields.iter().zip(&members) {
            assert_eq!(m.offset as usize, *offset, "offset of {name}.{field}");
        }
    }
}

/// The Rust struct whose layout WGSL struct `name` shares.
fn rust_struct_of(name: &str) -> &'static str {
    match name {
        "Frame" => "FrameParams",
        "Sphere" => "FlatSphere",
        "Cylinder" => "FlatCylinder",
        "Plane" => "FlatPlane",
        "Triangle" => "FlatTriangle",
        "Node" => "GpuNode",
        "LeafTriangle" => "GpuLeafTriangle",
        "Material" => "FlatMaterial",
        "Light" => "FlatLight",
        "Emitter" => "FlatEmitter",
        "QueryRay" => "GpuQueryRay",
        "QueryHit" => "GpuQueryHit",
        "ClosestPoint" => "GpuClosestPoint",
        "TextureInfo" => "FlatTexture",
        "TriangleAttrs" => "FlatTriangleAttrs",
        "Environment" => "FlatEnvironment",
        _ => panic!("no Rust twin named for WGSL struct {name}"),
    }
}

/// The field names of `pub struct NAME` as written in the source of the buffer layouts,
/// so that a field added to the Rust struct and not to the test's list is caught.
fn rust_fields(name: &str) -> Vec<String> {
    let sources = [
        include_str!("../../../core/src/layout.rs"),
        include_str!("../../../core/src/accel/gpu_bvh.rs"),
        include_str!("../closest.rs"),
    ];
    let start = format!("pub struct {name} {{");
    let text = sources.iter().find_map(|s| s.split_once(&start).map(|(_, rest)| rest));
    let text = text.unwrap_or_else(|| panic!("pub struct {name} not found"));
    let body = &text[..text.find("\n}").expect("the struct's closing brace")];
    body.lines()
        .filter_map(|l| l.trim().strip_prefix("pub ")?.split_once(':').map(|(f, _)| f.trim().to_string()))
        .collect()
}

/// The keys whose translations [`every_backend_translates_and_the_validators_accept`] checks,
/// per program: a deterministic subset of the sweep (all of it, 8220 variants and 13,246 GLSL
/// entry points, passed once in 4.6 min on two cores; these 350 take 10 s): no flag, every
/// flag, every flag with 64-bit loads, each flag alone and every flag but one (each with its
/// implied flags), and the split variants of [`split_keys`].
fn keys_to_translate() -> Vec<(Program, FeatureKey)> {
    let flags: Vec<FeatureKey> = FeatureKey::all().iter().collect();
    // ENV_MAP implies ENVIRONMENT: alone it is the map; without ENVIRONMENT there is neither.
    let alone = |f: FeatureKey| if f == FeatureKey::ENV_MAP { f | FeatureKey::ENVIRONMENT } else { f };
    let but = |f: FeatureKey| {
        let k = FeatureKey::all() - f;
        if f == FeatureKey::ENVIRONMENT { k - FeatureKey::ENV_MAP } else { k }
    };
    let mut keys = vec![FeatureKey::empty(), FeatureKey::ALL, FeatureKey::ALL | FeatureKey::LOAD64];
    keys.extend(flags.iter().map(|&f| alone(f)));
    keys.extend(flags.iter().map(|&f| but(f)));
    let mut out: Vec<(Program, FeatureKey)> = Vec::new();
    for p in Program::ALL {
        for &k in keys.iter().chain(&split_keys()) {
            let k = k.for_program(p);
            if !out.contains(&(p, k)) {
                out.push((p, k));
            }
        }
    }
    out
}

/// An external validator, or a panic naming the Debian package that has it.
fn tool(name: &str, package: &str) -> std::path::PathBuf {
    let found = std::env::var_os("PATH")
        .and_then(|paths| std::env::split_paths(&paths).map(|d| d.join(name)).find(|p| p.is_file()));
    found.unwrap_or_else(|| panic!("{name} not found: install the package {package} (.ci/run does)"))
}

/// Every checked variant ([`keys_to_translate`]) translates to SPIR-V that `spirv-val`
/// accepts for Vulkan 1.1, to GLSL ES 3.10 compute shaders (one per entry point) that
/// `glslangValidator` accepts, and to MSL and HLSL (shader model 6.0) without error: the
/// WGSL is portable to every backend wgpu has, not only to the Vulkan one it runs on.
///
/// Excluded: GLSL for the LOAD64 variants, since GLSL ES has no 64-bit integers (the GL
/// backend could never run them; wgpu adds LOAD64 only on devices with `SHADER_INT64`).
#[test]
fn every_backend_translates_and_the_validators_accept() {
    use naga::back::{glsl, hlsl, msl, spv};
    use rayon::prelude::*;
    let started = std::time::Instant::now();
    let spirv_val = tool("spirv-val", "spirv-tools");
    let glslang = tool("glslangValidator", "glslang-tools");
    let dir = tempfile::tempdir().unwrap();
    let variants = keys_to_translate();
    let results: Vec<(Vec<String>, Vec<std::path::PathBuf>)> = variants
        .par_iter()
        .enumerate()
        .map(|(i, &(p, key))| {
            let name = format!("{p:?} {}", key.label());
            let mut failures = Vec::new();
            let mut glsl_files = Vec::new();
            let m = match compose(p, key) {
                Ok(m) => m,
                Err(e) => return (vec![format!("{name}: {e}")], glsl_files),
            };
            let info = match validate(p, key, &m) {
                Ok(info) => info,
                Err(e) => return (vec![e.to_string()], glsl_files),
            };
            // SPIR-V 1.0, as wgpu writes it by default, validated for Vulkan 1.1.
            match spv::write_vec(&m, &info, &spv::Options::default(), None) {
                Ok(words) => {
                    let path = dir.path().join(format!("{i}.spv"));
                    std::fs::write(&path, words.iter().flat_map(|w| w.to_le_bytes()).collect::<Vec<u8>>()).unwrap();
                    let out = std::process::Command::new(&spirv_val)
                        .args(["--target-env", "vulkan1.1"])
                        .arg(&path)
                        .output()
                        .unwrap();
                    if !out.status.success() {
                        failures.push(format!(
                            "{name}: spirv-val: {}{}",
                            String::from_utf8_lossy(&out.stdout),
                            String::from_utf8_lossy(&out.stderr)
                        ));
                    }
                }
                Err(e) => failures.push(format!("{name}: SPIR-V: {e}")),
            }
            if !key.contains(FeatureKey::LOAD64) {
                for (j, ep) in m.entry_points.iter().enumerate() {
                    let options = glsl::Options { version: glsl::Version::new_gles(310), ..Default::default() };
                    let pipeline = glsl::PipelineOptions {
                        shader_stage: naga::ShaderStage::Compute,
                        entry_point: ep.name.clone(),
                        multiview: None,
                    };
                    let mut text = String::new();
                    let written = glsl::Writer::new(&mut text, &m, &info, &options, &pipeline, Default::default())
                        .and_then(|mut w| w.write());
                    match written {
                        Ok(_) => {
                            let path = dir.path().join(format!("{i}_{j}.comp"));
                            // The variant's name after the text: `#version` must come first.
                            std::fs::write(&path, format!("{text}\n// {name} {}\n", ep.name)).unwrap();
                            glsl_files.push(path);
                        }
                        Err(e) => failures.push(format!("{name} {}: GLSL: {e}", ep.name)),
                    }
                }
            }
            let msl_options = msl::Options { lang_version: (2, 4), ..Default::default() };
            if let Err(e) = msl::write_string(&m, &info, &msl_options, &msl::PipelineOptions::default()) {
                failures.push(format!("{name}: MSL: {e}"));
            }
            let hlsl_options = hlsl::Options { shader_model: hlsl::ShaderModel::V6_0, ..Default::default() };
            let mut text = String::new();
            let pipeline = hlsl::PipelineOptions::default();
            if let Err(e) = hlsl::Writer::new(&mut text, &hlsl_options, &pipeline).write(&m, &info, None) {
                failures.push(format!("{name}: HLSL: {e}"));
            }
            (failures, glsl_files)
        })
        .collect();
    let translated = started.elapsed();
    let mut failures: Vec<String> = results.iter().flat_map(|(f, _)| f.clone()).collect();
    let glsl_files: Vec<&std::path::PathBuf> = results.iter().flat_map(|(_, g)| g).collect();
    // glslangValidator takes many files at once (each compiled alone): a few calls in all.
    failures.par_extend(glsl_files.par_chunks(16).filter_map(|files| {
        let out = std::process::Command::new(&glslang).arg("-S").arg("comp").args(files).output().unwrap();
        (!out.status.success()).then(|| {
            format!(
                "glslangValidator: {}{}",
                String::from_utf8_lossy(&out.stdout),
                String::from_utf8_lossy(&out.stderr)
            )
        })
    }));
    eprintln!(
        "{} variants, {} GLSL entry points: translated and SPIR-V validated in {translated:.1?}, all in {:.1?}",
        variants.len(),
        glsl_files.len(),
        started.elapsed()
    );
    assert!(failures.is_empty(), "{} failures, first: {}", failures.len(), failures[0]);
}

/// No pipeline binds more storage buffers per stage than WebGPU guarantees
/// ([`crate::MIN_STORAGE_BUFFERS`], counted over both groups as every declared binding is in
/// the layout), but for the parts of split arrays, one more each, and for the wavefront path
/// tracer, which runs only where the device has room for its own; the bound is reached (so it
/// says what strahl needs); group 0 holds only the scene's bindings and the parts.
#[test]
fn every_pipeline_fits_the_storage_buffers_webgpu_guarantees() {
    use crate::split::{Split, SplitArray, extra_binding};
    use crate::{MIN_STORAGE_BUFFERS, SCENE_BINDINGS, wavefront};
    let mut most = 0;
    for (p, key) in keys_to_translate() {
        let m = compose(p, key).unwrap();
        let names: Vec<String> = m
            .global_variables
            .iter()
            .filter(|(_, g)| matches!(g.space, naga::AddressSpace::Storage { .. }))
            .map(|(_, g)| g.name.clone().unwrap_or_default())
            .collect();
        let storage = names.len() as u32;
        let split = Split::of_key(key);
        let limit = match p {
            Program::Wavefront => SCENE_BINDINGS + wavefront::BINDINGS,
            _ => MIN_STORAGE_BUFFERS,
        } + split.extra_bindings();
        assert!(storage <= limit, "{p:?} {}: {storage} storage buffers, more than {limit}: {names:?}", key.label());
        if p != Program::Wavefront && !split.is_split() {
            most = most.max(storage);
        }
        let parts: Vec<u32> =
            SplitArray::ALL.iter().flat_map(|&a| (1..split.parts(a)).map(move |i| extra_binding(a, i))).collect();
        for b in group_bindings(&m, 0) {
            assert!(b < SCENE_BINDINGS || parts.contains(&b), "{p:?} {}: scene binding {b}", key.label());
        }
    }
    assert_eq!(most, MIN_STORAGE_BUFFERS, "the most any unsplit pipeline binds");
}

mod tint;

/// The standalone shaders (the denoiser's) parse, validate with every check naga has, and
/// translate to SPIR-V, GLSL ES 3.10, MSL and HLSL without error.
#[test]
fn standalone_shaders_validate_and_translate() {
    use naga::back::{glsl, hlsl, msl, spv};
    for (file, src) in super::STANDALONE {
        let m = naga::front::wgsl::parse_str(&crate::shared::substitute(src)).unwrap_or_else(|e| panic!("{file}: {e}"));
        let info = naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::empty())
            .validate(&m)
            .unwrap_or_else(|e| panic!("{file}: {:?}", e.into_inner()));
        spv::write_vec(&m, &info, &spv::Options::default(), None).unwrap_or_else(|e| panic!("{file}: SPIR-V: {e}"));
        for ep in &m.entry_points {
            let options = glsl::Options { version: glsl::Version::new_gles(310), ..Default::default() };
            let pipeline = glsl::PipelineOptions {
                shader_stage: naga::ShaderStage::Compute,
                entry_point: ep.name.clone(),
                multiview: None,
            };
            let mut text = String::new();
            glsl::Writer::new(&mut text, &m, &info, &options, &pipeline, Default::default())
                .and_then(|mut w| w.write())
                .unwrap_or_else(|e| panic!("{file} {}: GLSL: {e}", ep.name));
        }
        let msl_options = msl::Options { lang_version: (2, 4), ..Default::default() };
        msl::write_string(&m, &info, &msl_options, &msl::PipelineOptions::default())
            .unwrap_or_else(|e| panic!("{file}: MSL: {e}"));
        let mut text = String::new();
        hlsl::Writer::new(&mut text, &hlsl::Options::default(), &hlsl::PipelineOptions::default())
            .write(&m, &info, None)
            .unwrap_or_else(|e| panic!("{file}: HLSL: {e}"));
        assert_eq!(m.entry_points.len(), 3, "{file}: prepare, atrous, finish");
    }
}
