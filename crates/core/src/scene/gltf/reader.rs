//! The reader over one document: accessors read and checked, warnings gathered.

use super::*;

/// One primitive's data as read, before placement.
pub(super) struct PrimitiveData {
    pub(super) positions: Vec<DVec3>,
    pub(super) uvs: Option<Vec<[f32; 2]>>,
    pub(super) uvs1: Option<Vec<[f32; 2]>>,
    pub(super) normals: Option<Vec<DVec3>>,
    pub(super) colors: Option<Vec<[f32; 4]>>,
    /// Vertex indices of the triangles.
    pub(super) triangles: Vec<[u32; 3]>,
    pub(super) material: u32,
}

/// A material's reference to a texture: which, through which texture coordinates, and the
/// `KHR_texture_transform` of them.
pub(super) struct TextureUse {
    pub(super) texture: usize,
    pub(super) texcoord: u32,
    pub(super) transform: [f32; 6],
}

/// What makes two uses the same: texture, coordinates, transform bits, data or colour.
pub(super) type TextureKey = (usize, u32, [u32; 6], bool);

impl TextureUse {
    pub(super) fn of_info(info: gltf::texture::Info) -> TextureUse {
        let mut u = TextureUse { texture: info.texture().index(), texcoord: info.tex_coord(), transform: IDENTITY_UV };
        if let Some(t) = info.texture_transform() {
            u.transform = uv_transform(t.offset(), t.rotation(), t.scale());
            if let Some(c) = t.tex_coord() {
                u.texcoord = c;
            }
        }
        u
    }

    pub(super) fn of_normal(n: &gltf::material::NormalTexture) -> TextureUse {
        let mut u = TextureUse { texture: n.texture().index(), texcoord: n.tex_coord(), transform: IDENTITY_UV };
        if let Some(t) = n.extension_value("KHR_texture_transform") {
            let pair = |key: &str, default: [f32; 2]| {
                t.get(key).and_then(|v| v.as_array()).map_or(default, |a| {
                    [0, 1].map(|k| a.get(k).and_then(|x| x.as_f64()).map_or(default[k], |x| x as f32))
                })
            };
            let rotation = t.get("rotation").and_then(|v| v.as_f64()).unwrap_or(0.0) as f32;
            u.transform = uv_transform(pair("offset", [0.0; 2]), rotation, pair("scale", [1.0; 2]));
            if let Some(c) = t.get("texCoord").and_then(|v| v.as_u64()) {
                u.texcoord = c as u32;
            }
        }
        u
    }
}

/// `KHR_texture_transform`'s offset · rotation · scale as [a, b, c, d, e, f] of
/// (a·u + b·v + c, d·u + e·v + f); the rotation turns the coordinates counter-clockwise as
/// the extension's matrix does (u' = cos·u + sin·v, v' = −sin·u + cos·v, v running down).
pub(super) fn uv_transform(offset: [f32; 2], rotation: f32, scale: [f32; 2]) -> [f32; 6] {
    let (s, c) = rotation.sin_cos();
    [c * scale[0], s * scale[1], offset[0], -s * scale[0], c * scale[1], offset[1]]
}

pub(super) struct Reader<'a> {
    pub(super) doc: &'a gltf::Document,
    /// Each buffer's bytes, or why it has none (an error only where a view reads it).
    pub(super) buffers: Vec<Res<Vec<u8>>>,
    /// Each image decoded once, shared by its uses.
    pub(super) images: HashMap<usize, (u32, u32, Arc<Texels>)>,
    pub(super) dir: PathBuf,
    pub(super) out: Import,
    /// Warnings already given (each once).
    pub(super) warned: BTreeSet<String>,
}

/// The value of component `c` of a glTF accessor element as glTF defines it: floats as they
/// are, normalised integers mapped to [0, 1] or [−1, 1], other integers as integers.
pub(super) fn component(bytes: &[u8], ty: DataType, normalized: bool) -> f64 {
    match ty {
        DataType::F32 => f32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]) as f64,
        DataType::U32 => u32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]) as f64,
        DataType::U8 => {
            let v = bytes[0] as f64;
            if normalized { v / 255.0 } else { v }
        }
        DataType::I8 => {
            let v = bytes[0] as i8 as f64;
            if normalized { (v / 127.0).max(-1.0) } else { v }
        }
        DataType::U16 => {
            let v = u16::from_le_bytes([bytes[0], bytes[1]]) as f64;
            if normalized { v / 65535.0 } else { v }
        }
        DataType::I16 => {
            let v = i16::from_le_bytes([bytes[0], bytes[1]]) as f64;
            if normalized { (v / 32767.0).max(-1.0) } else { v }
        }
    }
}

pub(super) fn type_name(d: Dimensions) -> &'static str {
    match d {
        Dimensions::Scalar => "SCALAR",
        Dimensions::Vec2 => "VEC2",
        Dimensions::Vec3 => "VEC3",
        Dimensions::Vec4 => "VEC4",
        Dimensions::Mat2 => "MAT2",
        Dimensions::Mat3 => "MAT3",
        Dimensions::Mat4 => "MAT4",
    }
}

impl Reader<'_> {
    pub(super) fn warn(&mut self, message: String) {
        if self.warned.insert(message.clone()) {
            self.out.warnings.push(message);
        }
    }

    pub(super) fn unsupported_extensions(&mut self) {
        let ignored: Vec<&str> = self.doc.extensions_used().filter(|e| !SUPPORTED_EXTENSIONS.contains(e)).collect();
        if !ignored.is_empty() {
            self.warn(format!("extensionsUsed: ignored (not read by strahl): {}", ignored.join(", ")));
        }
    }

    /// The bytes of buffer view `view`, checked to lie inside its buffer.
    pub(super) fn view_bytes(&self, view: &gltf::buffer::View) -> Res<&[u8]> {
        let buf =
            self.buffers[view.buffer().index()].as_ref().map_err(|m| format!("bufferViews[{}]: {m}", view.index()))?;
        let (start, len) = (view.offset(), view.length());
        match start.checked_add(len) {
            Some(end) if end <= buf.len() => Ok(&buf[start..end]),
            _ => Err(format!(
                "bufferViews[{}]: bytes {start}..{} lie outside buffers[{}] ({} bytes)",
                view.index(),
                start as u128 + len as u128,
                view.buffer().index(),
                buf.len()
            )),
        }
    }

    /// `count` elements of `n` components from `bytes` at `offset` with `stride`, each checked
    /// to lie inside `bytes` before anything is read.
    pub(super) fn elements(
        bytes: &[u8],
        offset: usize,
        stride: usize,
        count: usize,
        n: usize,
        ty: DataType,
        normalized: bool,
    ) -> Option<Vec<f64>> {
        let size = ty.size() * n;
        if count > 0 {
            let last = (count - 1).checked_mul(stride)?.checked_add(offset)?.checked_add(size)?;
            if last > bytes.len() {
                return None;
            }
        }
        let mut out = Vec::with_capacity(count * n);
        for i in 0..count {
            let base = offset + i * stride;
            for c in 0..n {
                let at = base + c * ty.size();
                out.push(component(&bytes[at..at + ty.size()], ty, normalized));
            }
        }
        Some(out)
    }

    /// Accessor `acc` (used as `what`) as a flat list of its components, after checking its
    /// type is one of `dims`; sparse substitutions applied.
    pub(super) fn read_accessor(&self, acc: &gltf::Accessor, what: &str, dims: &[Dimensions]) -> Res<Vec<f64>> {
        let at = format!("{what} (accessors[{}])", acc.index());
        if !matches!(self.doc.as_json().accessors[acc.index()].type_, gltf::json::validation::Checked::Valid(_)) {
            return Err(format!("{at}: type is not one glTF defines"));
        }
        if !dims.contains(&acc.dimensions()) {
            let want: Vec<&str> = dims.iter().map(|&d| type_name(d)).collect();
            return Err(format!("{at}: type {} where {} is expected", type_name(acc.dimensions()), want.join(" or ")));
        }
        let n = acc.dimensions().multiplicity();
        let (ty, normalized, count) = (acc.data_type(), acc.normalized(), acc.count());
        let elem = ty.size() * n;
        let mut values = match acc.view() {
            None => vec![0.0; count * n],
            Some(view) => {
                let bytes = self.view_bytes(&view).map_err(|m| format!("{at}: {m}"))?;
                let stride = view.stride().unwrap_or(elem);
                if stride < elem {
                    return Err(format!(
                        "{at}: bufferViews[{}].byteStride {stride} is shorter than one element ({elem} bytes)",
                        view.index()
                    ));
                }
                Self::elements(bytes, acc.offset(), stride, count, n, ty, normalized).ok_or_else(|| {
                    format!(
                        "{at}: {count} elements of {elem} bytes from byteOffset {} (stride {stride}) do not fit bufferViews[{}] ({} bytes)",
                        acc.offset(),
                        view.index(),
                        bytes.len()
                    )
                })?
            }
        };
        if let Some(sparse) = acc.sparse() {
            let k = sparse.count();
            let iv = sparse.indices();
            let ity = match iv.index_type() {
                gltf::accessor::sparse::IndexType::U8 => DataType::U8,
                gltf::accessor::sparse::IndexType::U16 => DataType::U16,
                gltf::accessor::sparse::IndexType::U32 => DataType::U32,
            };
            let ibytes = self.view_bytes(&iv.view()).map_err(|m| format!("{at}.sparse.indices: {m}"))?;
            let idx = Self::elements(ibytes, iv.offset(), ity.size(), k, 1, ity, false)
                .ok_or_else(|| format!("{at}.sparse.indices: {k} indices do not fit their buffer view"))?;
            let vv = sparse.values();
            let vbytes = self.view_bytes(&vv.view()).map_err(|m| format!("{at}.sparse.values: {m}"))?;
            let vals = Self::elements(vbytes, vv.offset(), elem, k, n, ty, normalized)
                .ok_or_else(|| format!("{at}.sparse.values: {k} values do not fit their buffer view"))?;
            for (j, &i) in idx.iter().enumerate() {
                let i = i as usize;
                if i >= count {
                    return Err(format!("{at}.sparse.indices: index {i} out of range ({count} elements)"));
                }
                values[i * n..(i + 1) * n].copy_from_slice(&vals[j * n..(j + 1) * n]);
            }
        }
        if let Some(bad) = values.iter().position(|v| !v.is_finite()) {
            return Err(format!("{at}: element {} is not finite", bad / n));
        }
        Ok(values)
    }
}
