//! Linear-float RGB images and their files: PNG (8-bit sRGB) or EXR (linear f32), by
//! extension; [`Region`]s of an image, and EXR files that hold one ([`write_exr`],
//! [`read_exr`]: the data window says where the pixels lie in the whole image).

use anyhow::{Context, Result, bail, ensure};
use std::collections::BTreeMap;
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
    code8(linear_to_srgb(v))
}

/// The nearest 8-bit code of a display-encoded value, clamped to [0, 1].
pub fn code8(encoded: f32) -> u8 {
    (encoded.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
}

/// Whether `path` names an EXR file (by its extension, in any case).
pub fn is_exr_path(path: &Path) -> bool {
    path.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr"))
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
            Some("exr") => write_exr(path, self, &ExrPlacement::whole(self.width, self.height)),
            _ => bail!("{}: unknown image format; use a .png or .exr file name", path.display()),
        }
    }

    /// Reads an EXR (linear) or PNG (sRGB, converted to linear) file. An EXR file must hold
    /// its whole image: a part of a split render (a smaller data window) is refused.
    pub fn load(path: &Path) -> Result<Image> {
        if is_exr_path(path) {
            let exr = read_exr(path)?;
            let (w, h) = exr.placement.full;
            ensure!(
                exr.placement.region == Region::whole(w, h),
                "{}: holds only the region {} of a {w}x{h} image (a part of a split render); \
                 assemble the parts with `strahl merge` first",
                path.display(),
                exr.placement.region
            );
            return Ok(exr.image);
        }
        let img = image::open(path).with_context(|| format!("cannot read image {}", path.display()))?;
        let rgb = img.to_rgb32f();
        let (width, height) = rgb.dimensions();
        let pixels = rgb.pixels().map(|p| p.0.map(srgb_to_linear)).collect();
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

/// A rectangle of pixels of an image: columns `x0..x1` and rows `y0..y1` (the ends
/// excluded), row 0 at the top.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Region {
    pub x0: u32,
    pub y0: u32,
    pub x1: u32,
    pub y1: u32,
}

impl Region {
    /// Every pixel of a `width`×`height` image.
    pub fn whole(width: u32, height: u32) -> Self {
        Self { x0: 0, y0: 0, x1: width, y1: height }
    }

    /// Band `k` of `n` (0-based) of a `width`×`height` image: rows `⌊k·height/n⌋` to
    /// `⌊(k+1)·height/n⌋`, every column. The `n` bands cover the image once; each holds
    /// `⌊height/n⌋` or `⌈height/n⌉` rows (none when `n` > `height`).
    pub fn band(k: u32, n: u32, width: u32, height: u32) -> Self {
        assert!(k < n, "band {k} of {n}");
        let row = |i: u32| (i as u64 * height as u64 / n as u64) as u32;
        Self { x0: 0, y0: row(k), x1: width, y1: row(k + 1) }
    }

    pub fn width(&self) -> u32 {
        self.x1 - self.x0
    }

    pub fn height(&self) -> u32 {
        self.y1 - self.y0
    }

    pub fn pixel_count(&self) -> u64 {
        self.width() as u64 * self.height() as u64
    }

    pub fn is_empty(&self) -> bool {
        self.x0 >= self.x1 || self.y0 >= self.y1
    }

    /// Whether the region lies inside a `width`×`height` image.
    pub fn fits(&self, width: u32, height: u32) -> bool {
        self.x0 <= self.x1 && self.y0 <= self.y1 && self.x1 <= width && self.y1 <= height
    }

    /// The pixels both regions hold, if any.
    pub fn intersection(&self, o: &Region) -> Option<Region> {
        let r = Region { x0: self.x0.max(o.x0), y0: self.y0.max(o.y0), x1: self.x1.min(o.x1), y1: self.y1.min(o.y1) };
        (!r.is_empty()).then_some(r)
    }
}

/// `X0,Y0,X1,Y1`, the form `--region` takes.
impl std::fmt::Display for Region {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{},{},{},{}", self.x0, self.y0, self.x1, self.y1)
    }
}

/// Where an EXR file's pixels lie and what it records: the whole image's size (the EXR
/// display window), the region its pixels cover (the data window) and text attributes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ExrPlacement {
    pub full: (u32, u32),
    pub region: Region,
    pub attributes: BTreeMap<String, String>,
}

impl ExrPlacement {
    /// A whole `width`×`height` image, no attributes.
    pub fn whole(width: u32, height: u32) -> Self {
        Self { full: (width, height), region: Region::whole(width, height), attributes: BTreeMap::new() }
    }
}

/// An EXR file's pixels (the data window's) and their placement.
pub struct ExrFile {
    pub image: Image,
    pub placement: ExrPlacement,
}

/// Writes `img`, the pixels of `placement.region`, as a linear f32 RGB OpenEXR file (ZIP,
/// lossless) whose data window is that region of a display window of `placement.full`,
/// with `placement.attributes` as text attributes; atomically. Attribute names and values
/// must be Latin-1 (other characters are written as `?`).
pub fn write_exr(path: &Path, img: &Image, placement: &ExrPlacement) -> Result<()> {
    write_exr_with(path, img, placement, &[])
}

/// [`write_exr`] with more channels beside R, G and B: `(name, one value a pixel of the
/// region)`, such as the output variables' (`albedo.R`, `depth.Z`: [`crate::render::aov`]).
pub fn write_exr_with(path: &Path, img: &Image, placement: &ExrPlacement, extra: &[(&str, Vec<f32>)]) -> Result<()> {
    use exr::prelude::{
        AnyChannel, AnyChannels, AttributeValue, Encoding, FlatSamples, ImageAttributes, IntegerBounds, Layer,
        LayerAttributes, SpecificChannels, Vec2, WritableImage,
    };
    let r = placement.region;
    ensure!(
        (img.width, img.height) == (r.width(), r.height()) && r.fits(placement.full.0, placement.full.1),
        "{}: a {}x{} image cannot be the region {r} of a {}x{} image",
        path.display(),
        img.width,
        img.height,
        placement.full.0,
        placement.full.1
    );
    let w = img.width as usize;
    let channels = SpecificChannels::rgb(|p: Vec2<usize>| {
        let [r, g, b] = img.pixels[p.y() * w + p.x()];
        (r, g, b)
    });
    let mut attributes = LayerAttributes {
        layer_position: Vec2(r.x0 as i32, r.y0 as i32),
        software_name: Some(latin1(concat!("strahl ", env!("CARGO_PKG_VERSION")))),
        ..Default::default()
    };
    // Attributes of the header's own (reading puts every attribute it does not know there).
    for (k, v) in &placement.attributes {
        attributes.other.insert(latin1(k), AttributeValue::Text(latin1(v)));
    }
    let size = (r.width() as usize, r.height() as usize);
    let display = IntegerBounds::from_dimensions((placement.full.0 as usize, placement.full.1 as usize));
    if extra.is_empty() {
        let layer = Layer::new(size, attributes, Encoding::SMALL_LOSSLESS, channels);
        let image = exr::image::Image::new(ImageAttributes::new(display), layer);
        return crate::output::write_atomic(path, |out| Ok(image.write().to_buffered(out)?));
    }
    let n = img.pixels.len();
    let mut list: Vec<AnyChannel<FlatSamples>> = (0..3)
        .map(|c| {
            let values = img.pixels.iter().map(|p| p[c]).collect();
            AnyChannel::new(["R", "G", "B"][c], FlatSamples::F32(values))
        })
        .collect();
    for (name, values) in extra {
        ensure!(values.len() == n, "{}: channel {name} has {} values for {n} pixels", path.display(), values.len());
        list.push(AnyChannel::new(*name, FlatSamples::F32(values.clone())));
    }
    let layer = Layer::new(size, attributes, Encoding::SMALL_LOSSLESS, AnyChannels::sort(list.into()));
    let image = exr::image::Image::new(ImageAttributes::new(display), layer);
    crate::output::write_atomic(path, |out| Ok(image.write().to_buffered(out)?))
}

/// `s` as an EXR text: characters outside Latin-1 become `?`.
fn latin1(s: &str) -> exr::meta::attribute::Text {
    let s: String = s.chars().map(|c| if (c as u32) < 256 { c } else { '?' }).collect();
    exr::meta::attribute::Text::new_or_panic(s)
}

/// The placement recorded in the EXR file at `path`, from its header alone; fails unless it
/// is a flat, single-part image whose data window lies in a display window starting at (0, 0)
/// of at most [`crate::scene::file::MAX_IMAGE_PIXELS`] pixels. Reading it allocates nothing
/// in proportion to the pixels.
pub fn read_exr_placement(path: &Path) -> Result<ExrPlacement> {
    let meta = exr::meta::MetaData::read_from_file(path, false)
        .map_err(|e| anyhow::anyhow!("{}: not a readable OpenEXR file: {e}", path.display()))?;
    let [header] = meta.headers.as_slice() else {
        bail!("{}: has {} layers; strahl reads single-layer EXR images", path.display(), meta.headers.len());
    };
    ensure!(!header.deep, "{}: holds deep data; strahl reads flat images", path.display());
    let display = header.shared_attributes.display_window;
    ensure!(
        display.position.x() == 0 && display.position.y() == 0,
        "{}: the display window starts at ({}, {}), not at (0, 0)",
        path.display(),
        display.position.x(),
        display.position.y()
    );
    let max = crate::scene::file::MAX_IMAGE_PIXELS;
    let (fw, fh) = (display.size.width() as u64, display.size.height() as u64);
    ensure!(
        fw * fh <= max && fw <= u32::MAX as u64 && fh <= u32::MAX as u64,
        "{}: a {fw}x{fh} image is more than {max} pixels",
        path.display()
    );
    let pos = header.own_attributes.layer_position;
    let size = header.layer_size;
    let fits = pos.x() >= 0
        && pos.y() >= 0
        && pos.x() as u64 + size.width() as u64 <= fw
        && pos.y() as u64 + size.height() as u64 <= fh;
    ensure!(
        fits,
        "{}: the data window ({}, {}) + {}x{} lies outside the {fw}x{fh} display window",
        path.display(),
        pos.x(),
        pos.y(),
        size.width(),
        size.height()
    );
    let (x0, y0) = (pos.x() as u32, pos.y() as u32);
    let region = Region { x0, y0, x1: x0 + size.width() as u32, y1: y0 + size.height() as u32 };
    let mut attributes = BTreeMap::new();
    for (k, v) in header.own_attributes.other.iter().chain(&header.shared_attributes.other) {
        if let exr::meta::attribute::AttributeValue::Text(t) = v {
            attributes.insert(t_string(k), t_string(t));
        }
    }
    Ok(ExrPlacement { full: (fw as u32, fh as u32), region, attributes })
}

fn t_string(t: &exr::meta::attribute::Text) -> String {
    t.as_slice().iter().map(|&b| b as char).collect()
}

/// Reads the EXR file at `path`: its placement ([`read_exr_placement`], checked before the
/// pixels are read) and the R, G, B channels of its data window as linear f32.
pub fn read_exr(path: &Path) -> Result<ExrFile> {
    use exr::prelude::{ReadChannels, ReadLayers, Vec2};
    let placement = read_exr_placement(path)?;
    let r = placement.region;
    let w = r.width() as usize;
    let read = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .rgb_channels(
            |size, _| vec![[0f32; 3]; size.area()],
            move |px: &mut Vec<[f32; 3]>, p: Vec2<usize>, (r, g, b): (f32, f32, f32)| px[p.y() * w + p.x()] = [r, g, b],
        )
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .map_err(|e| anyhow::anyhow!("cannot read image {}: {e}", path.display()))?;
    let pixels = read.layer_data.channel_data.pixels;
    ensure!(pixels.len() as u64 == r.pixel_count(), "{}: the pixels do not fill the data window", path.display());
    Ok(ExrFile { image: Image { width: r.width(), height: r.height(), pixels }, placement })
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
    fn bands_cover_the_image_once_whatever_the_count() {
        for (h, n) in [(480, 7), (5, 5), (1, 1), (481, 3), (16384, 1000)] {
            let mut next = 0;
            for k in 0..n {
                let b = Region::band(k, n, 640, h);
                assert_eq!((b.x0, b.x1, b.y0), (0, 640, next), "band {k} of {n}, height {h}");
                assert!(b.height() == h / n || b.height() == h.div_ceil(n));
                next = b.y1;
            }
            assert_eq!(next, h);
        }
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
