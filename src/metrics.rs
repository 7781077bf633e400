//! Image comparison: how far one rendering is from another.

use crate::image::Image;

/// Agreement of two images as 8-bit sRGB, the form a viewer sees.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Agreement {
    /// Fraction of pixels whose every channel differs by at most `tolerance` codes.
    pub within_tolerance: f64,
    /// Largest difference of any channel, in 8-bit codes.
    pub max_code_diff: u8,
    /// Mean FLIP error (Andersson et al. 2020, via nv-flip) at the default viewing distance
    /// (67 pixels per degree): 0 for identical images, 1 for the most visible difference.
    pub mean_flip: f32,
}

/// Compares `test` with `reference`.
pub fn agreement(reference: &Image, test: &Image, tolerance: u8) -> Agreement {
    assert_eq!((reference.width, reference.height), (test.width, test.height), "image sizes differ");
    let a = reference.to_srgb8();
    let b = test.to_srgb8();
    let mut ok = 0usize;
    let mut max = 0u8;
    for (pa, pb) in a.chunks(3).zip(b.chunks(3)) {
        let d = pa.iter().zip(pb).map(|(x, y)| x.abs_diff(*y)).max().unwrap_or(0);
        max = max.max(d);
        ok += (d <= tolerance) as usize;
    }
    Agreement {
        within_tolerance: ok as f64 / (a.len() / 3).max(1) as f64,
        max_code_diff: max,
        mean_flip: mean_flip(reference, test),
    }
}

/// Mean FLIP error of `test` against `reference` (LDR FLIP on the 8-bit sRGB images).
pub fn mean_flip(reference: &Image, test: &Image) -> f32 {
    let r = nv_flip::FlipImageRgb8::with_data(reference.width, reference.height, &reference.to_srgb8());
    let t = nv_flip::FlipImageRgb8::with_data(test.width, test.height, &test.to_srgb8());
    let err = nv_flip::flip(r, t, nv_flip::DEFAULT_PIXELS_PER_DEGREE);
    nv_flip::FlipPool::from_image(&err).mean()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identical_images_agree_and_a_changed_one_does_not() {
        let mut a = Image::new(32, 32);
        for (i, p) in a.pixels.iter_mut().enumerate() {
            *p = [(i % 32) as f32 / 32.0, 0.5, (i / 32) as f32 / 32.0];
        }
        let same = agreement(&a, &a.clone(), 0);
        assert_eq!((same.within_tolerance, same.max_code_diff, same.mean_flip), (1.0, 0, 0.0));
        let mut b = a.clone();
        for p in &mut b.pixels[..64] {
            *p = [1.0, 0.0, 1.0];
        }
        let diff = agreement(&a, &b, 1);
        assert!((diff.within_tolerance - (1.0 - 64.0 / 1024.0)).abs() < 1e-9);
        assert!(diff.mean_flip > 0.01, "flip {}", diff.mean_flip);
    }
}
