//! Linear-float RGB images and their files: PNG (8-bit sRGB) or EXR (linear f32), by
//! extension.

use anyhow::{Context, Result, bail};
use std::path::Path;

#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    /// Row-major, row 0 at the top, linear radiance.
    pub pixels: Vec<[f32; 3]>,
}

/// The sRGB transfer function (IEC 61966-2-1) on a linear value clamped to [0, 1].
pub fn linear_to_srgb(v: f32) -> f32 {
    let v = v.clamp(0.0, 1.0);
    if v <= 0.003_130_8 { 12.92 * v } else { 1.055 * v.powf(1.0 / 2.4) - 0.055 }
}

/// 8-bit sRGB code of a linear value (NaN maps to 0).
pub fn to_srgb8(v: f32) -> u8 {
    if v.is_nan() {
        return 0;
    }
    (linear_to_srgb(v) * 255.0 + 0.5) as u8
}

impl Image {
    pub fn new(width: u32, height: u32) -> Self {
        Self { width, height, pixels: vec![[0.0; 3]; width as usize * height as usize] }
    }

    pub fn get(&self, x: u32, y: u32) -> [f32; 3] {
        self.pixels[y as usize * self.width as usize + x as usize]
    }

    pub fn to_srgb8(&self) -> Vec<u8> {
        self.pixels.iter().flat_map(|p| p.map(to_srgb8)).collect()
    }

    /// Number of pixels with a NaN or infinite channel.
    pub fn non_finite_count(&self) -> usize {
        self.pixels.iter().filter(|p| p.iter().any(|c| !c.is_finite())).count()
    }

    /// Writes a PNG (`.png`) or EXR (`.exr`) file, atomically ([`crate::output::write_atomic`]).
    pub fn save(&self, path: &Path) -> Result<()> {
        let ext = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase());
        match ext.as_deref() {
            Some("png") => {
                let img = image::RgbImage::from_raw(self.width, self.height, self.to_srgb8())
                    .context("image buffer size mismatch")?;
                save_encoded(&img, image::ImageFormat::Png, path)
            }
            Some("exr") => {
                let data: Vec<f32> = self.pixels.iter().flatten().copied().collect();
                let img = image::Rgb32FImage::from_raw(self.width, self.height, data)
                    .context("image buffer size mismatch")?;
                save_encoded(&img, image::ImageFormat::OpenExr, path)
            }
            _ => bail!("{}: unknown image format; use a .png or .exr file name", path.display()),
        }
    }

    /// Reads an EXR (linear) or PNG (sRGB, converted to linear) file.
    pub fn load(path: &Path) -> Result<Image> {
        let img = image::open(path).with_context(|| format!("cannot read image {}", path.display()))?;
        let is_exr = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr"));
        let rgb = img.to_rgb32f();
        let (width, height) = rgb.dimensions();
        let pixels = rgb.pixels().map(|p| if is_exr { p.0 } else { p.0.map(srgb_to_linear) }).collect();
        Ok(Image { width, height, pixels })
    }
}

/// Encodes `img` as `format` into `path`, atomically.
pub fn save_encoded<P, C>(img: &image::ImageBuffer<P, C>, format: image::ImageFormat, path: &Path) -> Result<()>
where
    P: image::PixelWithColorType,
    [P::Subpixel]: image::EncodableLayout,
    C: std::ops::Deref<Target = [P::Subpixel]>,
{
    crate::output::write_atomic(path, |w| Ok(img.write_to(w, format)?))
}

fn srgb_to_linear(v: f32) -> f32 {
    if v <= 0.040_45 { v / 12.92 } else { ((v + 0.055) / 1.055).powf(2.4) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_round_trips_through_png_and_exr_keeps_floats() {
        let dir = tempfile::tempdir().unwrap();
        let mut img = Image::new(3, 2);
        img.pixels[1] = [0.5, 2.0, -1.0];
        img.pixels[5] = [0.25, 0.75, 1.0];
        let exr = dir.path().join("a.exr");
        img.save(&exr).unwrap();
        assert_eq!(Image::load(&exr).unwrap(), img);
        let png = dir.path().join("a.png");
        img.save(&png).unwrap();
        let back = Image::load(&png).unwrap();
        assert!((back.get(2, 1)[0] - 0.25).abs() < 0.01 && back.get(1, 0)[1] == 1.0);
        assert!(img.save(&dir.path().join("a.bmp")).is_err());
    }

    #[test]
    fn srgb_encoding_hits_its_anchor_points() {
        assert_eq!(to_srgb8(0.0), 0);
        assert_eq!(to_srgb8(1.0), 255);
        assert_eq!(to_srgb8(0.215_861), 128);
        assert_eq!(to_srgb8(0.212), 127);
        assert_eq!(to_srgb8(f32::NAN), 0);
    }
}
