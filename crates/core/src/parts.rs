//! Renders split across machines. Each machine renders a [`Region`] of the image into an EXR
//! part file whose data window is that region and whose attributes describe the render
//! ([`describe`]); [`merge`] assembles the parts into the whole image. Every pixel is computed
//! as in a render of the whole image (rays and random numbers depend on the pixel's place in
//! the whole image only), so the merged image equals a whole render on the same backend bit
//! for bit. Parts that overlap, leave pixels out, or come from different renders are refused
//! before any pixel is read.

use crate::image::{ExrPlacement, Image, Region, read_exr, read_exr_placement};
use crate::layout::FrameParams;
use crate::render::Prepared;
use crate::scene::RenderMode;
use anyhow::{Result, bail, ensure};
use std::collections::BTreeMap;
use std::hash::Hasher;
use std::path::{Path, PathBuf};

/// Attributes that must be equal in every part of one image, with what each means in an error.
const MUST_MATCH: [(&str, &str); 6] = [
    ("strahl.mode", "mode"),
    ("strahl.spp", "samples per pixel"),
    ("strahl.max_depth", "max depth"),
    ("strahl.seed", "seed"),
    ("strahl.backend", "backend"),
    ("strahl.fingerprint", "scene (geometry, materials, lights, camera, background)"),
];

/// What identifies a render, for the attributes of its EXR files.
pub struct Description<'a> {
    /// The scene file's name (informative: not compared).
    pub scene: &'a Path,
    pub mode: RenderMode,
    /// "cpu" or "gpu".
    pub backend: &'static str,
    /// The device it ran on (informative: not compared).
    pub device: String,
    /// `Some((k, n))` for band `k` of `n` (`strahl render --tile k/n`): recorded so that a merge
    /// can name the bands that are missing.
    pub tile: Option<(u32, u32)>,
}

/// The attributes recorded in every EXR file `strahl render` writes: the mode, samples per
/// pixel, max depth, seed and backend, a fingerprint of everything the pixels depend on besides
/// (the flattened geometry, materials, lights and emitters, and the frame: camera, image size,
/// background, ambient), and for information the scene's file name, the device and, for a
/// band, which band of how many it is.
pub fn describe(d: &Description, prep: &Prepared, frame: &FrameParams) -> BTreeMap<String, String> {
    let name = d.scene.file_name().map_or_else(|| d.scene.display().to_string(), |n| n.to_string_lossy().into_owned());
    let mut attributes = BTreeMap::from([
        ("strahl.scene".to_string(), name),
        ("strahl.mode".to_string(), d.mode.name().to_string()),
        ("strahl.spp".to_string(), frame.spp.to_string()),
        ("strahl.max_depth".to_string(), frame.max_depth.to_string()),
        ("strahl.seed".to_string(), frame.seed.to_string()),
        ("strahl.backend".to_string(), d.backend.to_string()),
        ("strahl.device".to_string(), d.device.clone()),
        ("strahl.fingerprint".to_string(), format!("{:016x}", fingerprint(prep, frame))),
    ]);
    if let Some((k, n)) = d.tile {
        attributes.insert(TILE.to_string(), format!("{k}/{n}"));
    }
    attributes
}

/// The attribute of a band's part file: `k/n`.
const TILE: &str = "strahl.tile";

/// The band `(k, n)` a part says it is, if it says so and the band is one of `n`.
fn band_of(part: &Part) -> Option<(u32, u32)> {
    let (k, n) = part.placement.attributes.get(TILE)?.split_once('/')?;
    let (k, n) = (k.parse().ok()?, n.parse().ok()?);
    (k < n).then_some((k, n))
}

/// Where every part is a band of the same `n` (`--tile k/n`), the bands of `n` that no part is.
fn missing_bands(parts: &[Part]) -> Option<(Vec<u32>, u32)> {
    let bands: Vec<(u32, u32)> = parts.iter().map(band_of).collect::<Option<_>>()?;
    let n = bands.first()?.1;
    if bands.iter().any(|b| b.1 != n) {
        return None;
    }
    Some(((0..n).filter(|k| !bands.iter().any(|b| b.0 == *k)).collect(), n))
}

/// FNV-1a (64 bits) over the bytes the pixels of a render depend on, besides the mode and the
/// backend: the flattened scene as both backends read it (not the BVH, which only speeds the
/// search) and the whole image's frame. Equal renders give equal fingerprints on any machine
/// (the bytes are little-endian f32 and u32 from the same scene file and code).
pub fn fingerprint(prep: &Prepared, frame: &FrameParams) -> u64 {
    let g = &prep.flat;
    let whole = FrameParams {
        tile_origin: [0, 0],
        tile_size: [frame.width, frame.height],
        sample_base: 0,
        out_pitch: frame.width,
        out_first_row: 0,
        flags: 0,
        ..*frame
    };
    let mut h = fnv::FnvHasher::default();
    for bytes in [
        bytemuck::cast_slice::<_, u8>(&g.spheres),
        bytemuck::cast_slice(&g.cylinders),
        bytemuck::cast_slice(&g.planes),
        bytemuck::cast_slice(&g.triangles),
        bytemuck::cast_slice(&g.materials),
        bytemuck::cast_slice(&g.lights),
        bytemuck::cast_slice(&g.emitters),
        bytemuck::bytes_of(&whole),
    ] {
        // The length first, so that bytes cannot move from one array to the next unseen.
        h.write(&(bytes.len() as u64).to_le_bytes());
        h.write(bytes);
    }
    h.finish()
}

/// One part file: its path and what its header says.
struct Part {
    path: PathBuf,
    placement: ExrPlacement,
}

/// Assembles the EXR parts at `paths` into the whole image. Checks the headers first: every
/// part must describe the same image (size and [`describe`]'s compared attributes), no two
/// may share a pixel and together they must cover every pixel; each failure names the files
/// and pixels at fault. Returns the image and its placement (the whole image, with the parts'
/// compared attributes and scene name).
pub fn merge(paths: &[PathBuf]) -> Result<(Image, ExrPlacement)> {
    ensure!(!paths.is_empty(), "no parts to merge");
    let parts: Vec<Part> =
        paths.iter().map(|p| Ok(Part { path: p.clone(), placement: read_exr_placement(p)? })).collect::<Result<_>>()?;
    let first = &parts[0];
    let (w, h) = first.placement.full;
    for p in &parts[1..] {
        ensure!(
            p.placement.full == (w, h),
            "{} is a part of a {}x{} image, {} of a {w}x{h} one: parts of one image come from one render",
            p.path.display(),
            p.placement.full.0,
            p.placement.full.1,
            first.path.display()
        );
        for (key, what) in MUST_MATCH {
            let (a, b) = (first.placement.attributes.get(key), p.placement.attributes.get(key));
            if a != b {
                let show = |v: Option<&String>| v.map_or("not recorded".to_string(), |v| v.to_string());
                bail!(
                    "{} and {} come from different renders: {what} {} against {}; render every part with the \
                     same scene, --mode, --spp, --max-depth, --seed and backend",
                    first.path.display(),
                    p.path.display(),
                    show(a),
                    show(b)
                );
            }
        }
    }
    check_tiling(&parts, w, h)?;
    let mut img = Image::new(w, h);
    for p in &parts {
        let part = read_exr(&p.path)?;
        ensure!(part.placement == p.placement, "{}: changed while it was being merged", p.path.display());
        let r = part.placement.region;
        for (dy, row) in part.image.pixels.chunks_exact(r.width().max(1) as usize).enumerate() {
            let at = (r.y0 as usize + dy) * w as usize + r.x0 as usize;
            img.pixels[at..at + row.len()].copy_from_slice(row);
        }
    }
    let mut placement = ExrPlacement::whole(w, h);
    for (k, v) in &first.placement.attributes {
        if k == "strahl.scene" || MUST_MATCH.iter().any(|(m, _)| m == k) {
            placement.attributes.insert(k.clone(), v.clone());
        }
    }
    Ok((img, placement))
}

/// Fails unless the parts' regions cover the `w`×`h` image exactly once.
fn check_tiling(parts: &[Part], w: u32, h: u32) -> Result<()> {
    for (i, a) in parts.iter().enumerate() {
        for b in &parts[i + 1..] {
            if let Some(o) = a.placement.region.intersection(&b.placement.region) {
                bail!(
                    "{} (region {}) and {} (region {}) overlap in {} pixels, region {o}: each pixel must come \
                     from one part",
                    a.path.display(),
                    a.placement.region,
                    b.path.display(),
                    b.placement.region,
                    o.pixel_count()
                );
            }
        }
    }
    let covered: u64 = parts.iter().map(|p| p.placement.region.pixel_count()).sum();
    let all = w as u64 * h as u64;
    if covered < all {
        if let Some((missing, n)) = missing_bands(parts).filter(|(m, _)| !m.is_empty()) {
            let list = missing.iter().map(u32::to_string).collect::<Vec<_>>().join(", ");
            let (what, first) = (if missing.len() == 1 { "band" } else { "bands" }, missing[0]);
            bail!(
                "{what} {list} of {n} missing: the parts leave {} of the {w}x{h} image's pixels uncovered; render \
                 each missing band with --tile K/{n} (as --tile {first}/{n})",
                all - covered
            );
        }
        let gap = uncovered(parts.iter().map(|p| p.placement.region), w, h);
        let hint =
            if gap.pixel_count() == all - covered { format!("; render it with --region {gap}") } else { String::new() };
        bail!(
            "the parts leave {} of the {w}x{h} image's pixels uncovered, within the region {gap}{hint}",
            all - covered
        );
    }
    Ok(())
}

/// The bounding region of the pixels of a `w`×`h` image that no region of `regions` (which do
/// not overlap) covers; at least one pixel must be uncovered.
fn uncovered(regions: impl Iterator<Item = Region> + Clone, w: u32, h: u32) -> Region {
    let mut gap: Option<Region> = None;
    let mut add = |x0: u32, x1: u32, y: u32| {
        let r = Region { x0, y0: y, x1, y1: y + 1 };
        gap = Some(match gap {
            None => r,
            Some(g) => Region { x0: g.x0.min(x0), y0: g.y0.min(y), x1: g.x1.max(x1), y1: g.y1.max(y + 1) },
        });
    };
    for y in 0..h {
        let mut spans: Vec<(u32, u32)> =
            regions.clone().filter(|r| r.y0 <= y && y < r.y1 && !r.is_empty()).map(|r| (r.x0, r.x1)).collect();
        spans.sort_unstable();
        let mut x = 0;
        for (x0, x1) in spans {
            if x0 > x {
                add(x, x0, y);
            }
            x = x.max(x1);
        }
        if x < w {
            add(x, w, y);
        }
    }
    gap.expect("some pixel is uncovered")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_uncovered_pixels_are_bounded_exactly() {
        let r = |x0, y0, x1, y1| Region { x0, y0, x1, y1 };
        // A 10x6 image: two bands of three, the second missing its right half.
        let regions = [r(0, 0, 10, 3), r(0, 3, 5, 6)];
        assert_eq!(uncovered(regions.iter().copied(), 10, 6), r(5, 3, 10, 6));
        // Two holes far apart: their bounding region.
        let regions = [r(1, 0, 10, 1), r(0, 1, 10, 5), r(0, 5, 9, 6)];
        assert_eq!(uncovered(regions.iter().copied(), 10, 6), r(0, 0, 10, 6));
    }

    #[test]
    fn the_missing_bands_are_named_where_every_part_is_a_band() {
        let part = |tile: Option<&str>| {
            let mut placement = ExrPlacement::whole(4, 4);
            if let Some(t) = tile {
                placement.attributes.insert(TILE.to_string(), t.to_string());
            }
            Part { path: PathBuf::from("p.exr"), placement }
        };
        let bands = |tiles: &[Option<&str>]| missing_bands(&tiles.iter().map(|t| part(*t)).collect::<Vec<_>>());
        assert_eq!(bands(&[Some("0/4"), Some("3/4"), Some("1/4")]), Some((vec![2], 4)));
        assert_eq!(bands(&[Some("1/3")]), Some((vec![0, 2], 3)));
        assert_eq!(bands(&[Some("0/2"), Some("1/2")]), Some((vec![], 2)));
        // A part that is no band, bands of different counts, or a band out of its count: none named.
        assert_eq!(bands(&[Some("0/4"), None]), None);
        assert_eq!(bands(&[Some("0/4"), Some("1/3")]), None);
        assert_eq!(bands(&[Some("4/4")]), None);
        assert_eq!(bands(&[Some("x/4")]), None);
    }
}
