//! Images as the scene holds them, decoded once when the scene is loaded: colour textures
//! (PNG, JPEG: 8-bit sRGB, as glTF stores base colour and emission) and radiance maps (OpenEXR,
//! Radiance HDR: linear floats) for `[environment] file`.
//!
//! What the renderers read is built from these in [`crate::layout`] (texels packed into one
//! storage buffer) and sampled by `render::texture` / `shaders/modules/texture.wgsl`.

use std::io::Cursor;
use std::path::Path;
use std::sync::Arc;

/// Largest accepted image side, in pixels.
pub const MAX_TEXTURE_SIDE: u32 = 16384;
/// Largest accepted image, in pixels (8192 × 8192).
pub const MAX_TEXTURE_PIXELS: u64 = 67_108_864;
/// Largest image file read.
pub const MAX_TEXTURE_FILE_BYTES: u64 = 1 << 30;
/// Most images one scene holds.
pub const MAX_TEXTURES: usize = 4096;

/// What happens to texture coordinates outside [0, 1] (glTF's sampler wrap modes).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[repr(u32)]
pub enum Wrap {
    #[default]
    Repeat = 0,
    Clamp = 1,
    Mirror = 2,
}

/// The pixels of an image, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub enum Texels {
    /// 8-bit RGBA codes (PNG, JPEG): colour codes sRGB-encoded, read through the exact
    /// sRGB → linear table [`srgb_to_linear`], unless the texture holds data
    /// ([`Texture::data`]: code / 255); alpha is linear.
    Rgba8(Vec<[u8; 4]>),
    /// Linear RGB (radiance maps).
    Linear(Vec<[f32; 3]>),
}

/// One use of an image: its texels (shared between uses, packed once), the sampler, and how
/// the material reads it.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    /// Where it came from, for messages: a file, or a glTF path such as `images[2]`.
    pub name: String,
    pub width: u32,
    pub height: u32,
    pub texels: Arc<Texels>,
    /// Wrap modes along u and v.
    pub wrap: [Wrap; 2],
    /// Nearest-texel lookups (glTF `magFilter` NEAREST) instead of bilinear filtering.
    pub nearest: bool,
    /// The codes are data (metalness, roughness, normals: code / 255), not sRGB colour.
    pub data: bool,
    /// Which texture coordinates it reads (0: `TEXCOORD_0`, 1: `TEXCOORD_1`).
    pub texcoord: u32,
    /// `KHR_texture_transform` as the affine map (u, v) → (a·u + b·v + c, d·u + e·v + f),
    /// row by row: [a, b, c, d, e, f]; [`IDENTITY_UV`] without one.
    pub transform: [f32; 6],
}

/// The identity texture-coordinate transform.
pub const IDENTITY_UV: [f32; 6] = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0];

/// The sRGB transfer function's inverse (IEC 61966-2-1) for an 8-bit code, computed in f64
/// and rounded once: both backends read these values from one table.
pub fn srgb_to_linear(code: u8) -> f32 {
    let c = code as f64 / 255.0;
    (if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }) as f32
}

/// Which kind of image a file must hold.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageKind {
    /// PNG or JPEG, 8-bit RGBA (16-bit PNGs are rounded to 8 bits; opaque without alpha).
    Color,
    /// OpenEXR or Radiance HDR, linear RGB.
    Radiance,
}

impl Texture {
    /// The linear value of texel (x, y).
    pub fn texel(&self, x: u32, y: u32) -> [f32; 3] {
        let i = y as usize * self.width as usize + x as usize;
        match &*self.texels {
            Texels::Rgba8(t) if self.data => [0, 1, 2].map(|c| t[i][c] as f32 / 255.0),
            Texels::Rgba8(t) => [0, 1, 2].map(|c| srgb_to_linear(t[i][c])),
            Texels::Linear(t) => t[i],
        }
    }

    /// The mean linear value over all texels.
    pub fn mean(&self) -> [f64; 3] {
        let mut sum = [0.0f64; 3];
        for y in 0..self.height {
            for x in 0..self.width {
                let t = self.texel(x, y);
                for c in 0..3 {
                    sum[c] += t[c] as f64;
                }
            }
        }
        let n = (self.width as f64 * self.height as f64).max(1.0);
        sum.map(|s| s / n)
    }

    /// The image at half the size (each side rounded up), each texel the mean of the 2 × 2
    /// (at an odd edge 2 × 1 or 1 × 1) texels it covers, in linear values.
    pub fn halved(&self) -> Texture {
        let (w, h) = (self.width.div_ceil(2), self.height.div_ceil(2));
        let mut out = Vec::with_capacity(w as usize * h as usize);
        for y in 0..h {
            for x in 0..w {
                let mut sum = [0.0f64; 3];
                let mut n = 0.0;
                for (sx, sy) in [(2 * x, 2 * y), (2 * x + 1, 2 * y), (2 * x, 2 * y + 1), (2 * x + 1, 2 * y + 1)] {
                    if sx < self.width && sy < self.height {
                        let t = self.texel(sx, sy);
                        for c in 0..3 {
                            sum[c] += t[c] as f64;
                        }
                        n += 1.0;
                    }
                }
                out.push(sum.map(|s| (s / n) as f32));
            }
        }
        Texture {
            name: self.name.clone(),
            width: w,
            height: h,
            texels: Arc::new(Texels::Linear(out)),
            wrap: self.wrap,
            nearest: self.nearest,
            data: self.data,
            texcoord: self.texcoord,
            transform: self.transform,
        }
    }

    /// A texture of `texels` (`width` × `height`), repeating, bilinear, as colour, read
    /// through `TEXCOORD_0` untransformed.
    pub fn new(name: impl Into<String>, width: u32, height: u32, texels: Texels) -> Texture {
        Texture {
            name: name.into(),
            width,
            height,
            texels: Arc::new(texels),
            wrap: [Wrap::Repeat; 2],
            nearest: false,
            data: false,
            texcoord: 0,
            transform: IDENTITY_UV,
        }
    }

    /// Decodes an image file of `kind`. The message names no file: callers add it.
    pub fn load(path: &Path, kind: ImageKind) -> Result<Texture, String> {
        let bytes = crate::input::read_bytes(path, MAX_TEXTURE_FILE_BYTES).map_err(|e| match e {
            crate::input::ReadError::Io(e) => format!("cannot open: {e}"),
            e => format!("cannot read: {e}"),
        })?;
        let mut t = Self::decode(&bytes, kind)?;
        t.name = path.display().to_string();
        Ok(t)
    }

    /// Decodes image `bytes` of `kind` (the format is found from the contents). Its size is
    /// checked against [`MAX_TEXTURE_SIDE`] and [`MAX_TEXTURE_PIXELS`] before the pixels are
    /// decoded.
    pub fn decode(bytes: &[u8], kind: ImageKind) -> Result<Texture, String> {
        let reader = || {
            image::ImageReader::new(Cursor::new(bytes))
                .with_guessed_format()
                .map_err(|e| format!("cannot read the image: {e}"))
        };
        let format = reader()?.format().ok_or("not an image strahl reads (PNG, JPEG, OpenEXR or Radiance HDR)")?;
        let allowed: &[image::ImageFormat] = match kind {
            ImageKind::Color => &[image::ImageFormat::Png, image::ImageFormat::Jpeg],
            ImageKind::Radiance => &[image::ImageFormat::OpenExr, image::ImageFormat::Hdr],
        };
        if !allowed.contains(&format) {
            let want = match kind {
                ImageKind::Color => "a colour texture must be PNG or JPEG",
                ImageKind::Radiance => "an environment map must be OpenEXR (.exr) or Radiance HDR (.hdr)",
            };
            return Err(format!("{format:?} image: {want}"));
        }
        let (w, h) = reader()?.into_dimensions().map_err(|e| format!("cannot read the image: {e}"))?;
        if w == 0 || h == 0 {
            return Err(format!("the image is empty ({w} x {h})"));
        }
        if w > MAX_TEXTURE_SIDE || h > MAX_TEXTURE_SIDE || w as u64 * h as u64 > MAX_TEXTURE_PIXELS {
            return Err(format!(
                "the image is {w} x {h} pixels, more than accepted (sides up to {MAX_TEXTURE_SIDE}, \
                 {MAX_TEXTURE_PIXELS} pixels)"
            ));
        }
        let img = reader()?.decode().map_err(|e| format!("cannot decode the image: {e}"))?;
        let texels = match kind {
            ImageKind::Color => Texels::Rgba8(img.to_rgba8().pixels().map(|p| p.0).collect()),
            ImageKind::Radiance => {
                let rgb = img.to_rgb32f();
                let mut out = Vec::with_capacity(w as usize * h as usize);
                for (i, p) in rgb.pixels().enumerate() {
                    if p.0.iter().any(|c| !c.is_finite()) {
                        let (x, y) = (i as u32 % w, i as u32 / w);
                        return Err(format!("texel ({x}, {y}) is not finite: {:?}", p.0));
                    }
                    // Radiance is not negative; filtered maps can hold tiny negative values.
                    out.push(p.0.map(|c| c.max(0.0)));
                }
                Texels::Linear(out)
            }
        };
        Ok(Texture::new(String::new(), w, h, texels))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_table_has_the_standard_values() {
        assert_eq!(srgb_to_linear(0), 0.0);
        assert_eq!(srgb_to_linear(255), 1.0);
        // Code 10 is on the linear segment: 10/255/12.92.
        assert!((srgb_to_linear(10) as f64 - 10.0 / 255.0 / 12.92).abs() < 1e-9);
        // Mid grey, code 188 ≈ 0.5029 linear.
        assert!((srgb_to_linear(188) - 0.5029).abs() < 1e-3);
        // The inverse of the output side's encoding: every code round-trips.
        for c in 0..=255u8 {
            assert_eq!(crate::image::to_srgb8(srgb_to_linear(c)), c);
        }
    }

    #[test]
    fn images_decode_by_kind_and_refuse_the_other_kind() {
        let dir = tempfile::tempdir().unwrap();
        let png = dir.path().join("t.png");
        image::RgbImage::from_fn(3, 2, |x, y| image::Rgb([x as u8 * 100, y as u8 * 200, 7])).save(&png).unwrap();
        let t = Texture::load(&png, ImageKind::Color).unwrap();
        assert_eq!((t.width, t.height), (3, 2));
        assert_eq!(
            *t.texels,
            Texels::Rgba8(vec![
                [0, 0, 7, 255],
                [100, 0, 7, 255],
                [200, 0, 7, 255],
                [0, 200, 7, 255],
                [100, 200, 7, 255],
                [200, 200, 7, 255]
            ])
        );
        assert!(Texture::load(&png, ImageKind::Radiance).unwrap_err().contains("OpenEXR"));
        let exr = dir.path().join("t.exr");
        image::Rgb32FImage::from_fn(2, 1, |x, _| image::Rgb([x as f32 * 3.5, 1.0, -1e-3])).save(&exr).unwrap();
        let t = Texture::load(&exr, ImageKind::Radiance).unwrap();
        assert_eq!(*t.texels, Texels::Linear(vec![[0.0, 1.0, 0.0], [3.5, 1.0, 0.0]]));
        assert!(Texture::load(&exr, ImageKind::Color).unwrap_err().contains("PNG or JPEG"));
        std::fs::write(dir.path().join("junk.png"), b"not an image").unwrap();
        assert!(Texture::load(&dir.path().join("junk.png"), ImageKind::Color).is_err());
        assert!(Texture::load(&dir.path().join("missing.png"), ImageKind::Color).unwrap_err().contains("cannot open"));
        let nan = dir.path().join("nan.exr");
        image::Rgb32FImage::from_fn(1, 1, |_, _| image::Rgb([f32::NAN, 0.0, 0.0])).save(&nan).unwrap();
        assert!(Texture::load(&nan, ImageKind::Radiance).unwrap_err().contains("not finite"));
    }

    #[test]
    fn halving_averages_blocks_and_keeps_odd_edges() {
        let t =
            Texture::new("t", 3, 2, Texels::Linear(vec![[1.0; 3], [3.0; 3], [5.0; 3], [1.0; 3], [3.0; 3], [7.0; 3]]));
        let h = t.halved();
        assert_eq!((h.width, h.height), (2, 1));
        assert_eq!(*h.texels, Texels::Linear(vec![[2.0; 3], [6.0; 3]]));
    }
}
