//! The scene's small arrays packed into one storage buffer, and the texels with the
//! environment map's distribution after them.
//!
//! WebGPU guarantees 8 storage buffers per shader stage (`maxStorageBuffersPerShaderStage`),
//! and so do the defaults of every backend wgpu has. A binding has one element type, so a
//! scene of sixteen typed arrays took sixteen bindings. Here every array that does not grow with
//! the triangle count (spheres, cylinders, planes, shape references, materials, lights,
//! emitters, the texture table, the environment, and the rough dielectric's albedo table where
//! a material needs it) goes into one array of 16-byte words, each
//! array starting at a word the [`ObjectsHeader`] at the front names, and the shaders read an
//! element word by word (`load_sphere` and the others in `shaders/modules/bindings.wgsl`). Every
//! element of these arrays is a whole number of words, so each is written as its own bytes.
//!
//! The three arrays that grow with the triangles stay typed bindings of their own, because they
//! may need splitting across bindings ([`crate::split`]); so do the texels (images can be large)
//! and the triangle attributes.

use bytemuck::{Pod, Zeroable};
use strahl_core::layout::FlatScene;

/// One 16-byte word of the objects buffer (`vec4<u32>` in the shaders).
pub type Word = [u32; 4];
const WORD: usize = size_of::<Word>();

/// Where each array of the objects buffer starts, in words from the buffer's start, and the
/// counts the shaders loop over. Its fields are read by the shaders at the slots
/// [`ObjectsHeader::slots`] names (`OBJ_*`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct ObjectsHeader {
    pub spheres: u32,
    pub cylinders: u32,
    pub planes: u32,
    pub shape_refs: u32,
    pub materials: u32,
    pub lights: u32,
    pub emitters: u32,
    pub textures: u32,
    pub environment: u32,
    /// In texels (32-bit words of the texels binding), not in words of this buffer.
    pub env_distribution: u32,
    pub sphere_count: u32,
    pub cylinder_count: u32,
    pub plane_count: u32,
    /// The rough dielectric's albedo table (`render::dielectric::table`), f32 values from this
    /// word on; present only where a material is rough glass (a constant array in the shader
    /// took lavapipe 30 s to compile).
    pub glass_table: u32,
    pub _pad: [u32; 2],
}

/// Words the header takes.
const HEADER_WORDS: usize = size_of::<ObjectsHeader>() / WORD;
const _: () = assert!(size_of::<ObjectsHeader>().is_multiple_of(WORD));

macro_rules! slot {
    ($field:ident) => {
        (std::mem::offset_of!(ObjectsHeader, $field) / size_of::<u32>()) as u32
    };
}

impl ObjectsHeader {
    /// The shaders' names of the header's fields and their 32-bit slots (shared values,
    /// [`crate::shared`]).
    pub fn slots() -> [(&'static str, u32); 14] {
        [
            ("OBJ_SPHERES", slot!(spheres)),
            ("OBJ_CYLINDERS", slot!(cylinders)),
            ("OBJ_PLANES", slot!(planes)),
            ("OBJ_SHAPE_REFS", slot!(shape_refs)),
            ("OBJ_MATERIALS", slot!(materials)),
            ("OBJ_LIGHTS", slot!(lights)),
            ("OBJ_EMITTERS", slot!(emitters)),
            ("OBJ_TEXTURES", slot!(textures)),
            ("OBJ_ENVIRONMENT", slot!(environment)),
            ("OBJ_ENV_DISTRIBUTION", slot!(env_distribution)),
            ("OBJ_SPHERE_COUNT", slot!(sphere_count)),
            ("OBJ_CYLINDER_COUNT", slot!(cylinder_count)),
            ("OBJ_PLANE_COUNT", slot!(plane_count)),
            ("OBJ_GLASS_TABLE", slot!(glass_table)),
        ]
    }
}

/// The arrays of the objects buffer as bytes, in the order they are laid out.
fn parts(g: &FlatScene) -> [&[u8]; 10] {
    use bytemuck::cast_slice as b;
    let glass = g.materials.iter().any(strahl_core::render::bsdf::is_rough_glass);
    [
        b(&g.spheres),
        b(&g.cylinders),
        b(&g.planes),
        b(&g.shape_refs),
        b(&g.materials),
        b(&g.lights),
        b(&g.emitters),
        b(&g.textures),
        b(&g.environment),
        if glass { b(strahl_core::render::dielectric::table()) } else { &[] },
    ]
}

/// Bytes of `g`'s objects buffer, known before anything is packed (to check the binding
/// limit before allocating).
pub fn objects_bytes(g: &FlatScene) -> u64 {
    let words: usize = parts(g).iter().map(|p| p.len().div_ceil(WORD)).sum();
    ((HEADER_WORDS + words) * WORD) as u64
}

/// `g`'s objects buffer: the header, then each array from a word boundary (the last word of
/// the shape references zero-padded).
pub fn pack_objects(g: &FlatScene) -> Vec<Word> {
    let mut words: Vec<Word> = Vec::with_capacity(objects_bytes(g) as usize / WORD);
    words.resize(HEADER_WORDS, [0; 4]);
    let mut starts = [0u32; 10];
    for (start, bytes) in starts.iter_mut().zip(parts(g)) {
        *start = words.len() as u32;
        for chunk in bytes.chunks(WORD) {
            let mut w = [0u8; WORD];
            w[..chunk.len()].copy_from_slice(chunk);
            words.push(bytemuck::cast(w));
        }
    }
    let [spheres, cylinders, planes, shape_refs, materials, lights, emitters, textures, environment, glass_table] =
        starts;
    let header = ObjectsHeader {
        spheres,
        cylinders,
        planes,
        shape_refs,
        materials,
        lights,
        emitters,
        textures,
        environment,
        env_distribution: g.texels.len() as u32,
        sphere_count: g.spheres.len() as u32,
        cylinder_count: g.cylinders.len() as u32,
        plane_count: g.planes.len() as u32,
        glass_table,
        _pad: [0; 2],
    };
    words[..HEADER_WORDS].copy_from_slice(bytemuck::cast_slice(bytemuck::bytes_of(&header)));
    words
}

/// Bytes of the texels binding: the texels and the environment map's distribution.
pub fn texels_bytes(g: &FlatScene) -> u64 {
    ((g.texels.len() + g.env_distribution.len()) * size_of::<u32>()) as u64
}

/// The texels binding: `g`'s texels, then its environment map's distribution as f32 bits
/// (at [`ObjectsHeader::env_distribution`]).
pub fn pack_texels(g: &FlatScene) -> Vec<u32> {
    let mut texels = Vec::with_capacity(texels_bytes(g) as usize / size_of::<u32>());
    texels.extend_from_slice(&g.texels);
    texels.extend(g.env_distribution.iter().map(|v| v.to_bits()));
    texels
}

#[cfg(test)]
mod tests {
    use super::*;
    use strahl_core::layout::{
        FlatCylinder, FlatEmitter, FlatEnvironment, FlatLight, FlatMaterial, FlatPlane, FlatSphere, FlatTexture,
    };

    /// Every element type of the objects buffer is whole words, so its elements are read at
    /// `start + size / 16 * i` (the strides `shaders/modules/bindings.wgsl` uses, checked too).
    #[test]
    fn every_element_is_whole_words_with_the_shaders_stride() {
        let bindings = include_str!("../shaders/modules/bindings.wgsl");
        for (name, size, slot) in [
            ("load_sphere", size_of::<FlatSphere>(), "OBJ_SPHERES"),
            ("load_cylinder", size_of::<FlatCylinder>(), "OBJ_CYLINDERS"),
            ("load_plane", size_of::<FlatPlane>(), "OBJ_PLANES"),
            ("load_material", size_of::<FlatMaterial>(), "OBJ_MATERIALS"),
            ("load_light", size_of::<FlatLight>(), "OBJ_LIGHTS"),
            ("load_texture", size_of::<FlatTexture>(), "OBJ_TEXTURES"),
        ] {
            assert_eq!(size % WORD, 0, "{name}");
            let want = format!("object_slot({slot}) + {}u * i;", size / WORD);
            let body = bindings.split(&format!("fn {name}(")).nth(1).expect(name);
            assert!(body.lines().nth(1).unwrap().contains(&want), "{name} reads with stride {}: {want}", size / WORD);
        }
        assert_eq!(size_of::<FlatEmitter>(), WORD);
        assert_eq!(size_of::<FlatEnvironment>(), 12 * WORD);
    }

    #[test]
    fn arrays_start_where_the_header_says_and_hold_their_bytes() {
        let g = FlatScene {
            spheres: vec![FlatSphere { center: [1.0, 2.0, 3.0], radius: 0.5, object: 7, ..Default::default() }; 3],
            planes: vec![FlatPlane { normal: [0.0, 1.0, 0.0], material: 2, ..Default::default() }],
            shape_refs: vec![11, 12, 13, 14, 15],
            materials: vec![FlatMaterial::default(); 2],
            texels: vec![9; 6],
            env_distribution: vec![0.25, 1.0],
            ..Default::default()
        };
        let words = pack_objects(&g);
        assert_eq!((words.len() * WORD) as u64, objects_bytes(&g));
        let h: ObjectsHeader = bytemuck::pod_read_unaligned(bytemuck::cast_slice(&words[..HEADER_WORDS]));
        assert_eq!((h.sphere_count, h.cylinder_count, h.plane_count), (3, 0, 1));
        assert_eq!(h.spheres as usize, HEADER_WORDS);
        assert_eq!((h.cylinders, h.planes), (h.spheres + 6, h.spheres + 6));
        assert_eq!(h.shape_refs, h.planes + 2);
        assert_eq!(h.materials, h.shape_refs + 2, "five references take two words");
        let sphere: FlatSphere =
            bytemuck::pod_read_unaligned(bytemuck::cast_slice(&words[h.spheres as usize + 4..][..2]));
        assert_eq!(sphere, g.spheres[2]);
        assert_eq!(words[h.shape_refs as usize + 1], [15, 0, 0, 0]);
        let texels = pack_texels(&g);
        assert_eq!(h.env_distribution, 6);
        assert_eq!(f32::from_bits(texels[h.env_distribution as usize + 1]), 1.0);
        assert_eq!((texels.len() * 4) as u64, texels_bytes(&g));
    }

    #[test]
    fn the_slots_are_the_fields_in_order() {
        let slots = ObjectsHeader::slots();
        assert!(slots.iter().enumerate().all(|(i, (_, s))| *s == i as u32));
    }
}
