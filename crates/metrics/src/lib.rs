//! Image comparison: how far one rendering is from another.

use anyhow::{Result, bail, ensure};
use strahl_core::image::Image;

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

/// Errors of an image against a reference.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Errors {
    /// Root mean square error over all pixel channels, linear radiance.
    pub rmse: f64,
    /// RMSE of both images clamped to [0, 1], as the `rmse_clamped` of Mitsuba comparisons.
    pub rmse_clamped: f64,
    /// Relative MSE: mean over channels of (x − r)² / (r² + ε), ε = [`REL_MSE_EPSILON`].
    pub rel_mse: f64,
    /// Mean FLIP error of the 8-bit sRGB images ([`mean_flip`]).
    pub mean_flip: f64,
}

/// The ε of the relative MSE, (x − r)² / (r² + ε): 0.01, the usual choice (Rousselle et al.
/// 2011, "Adaptive sampling and reconstruction using greedy error minimization"), which keeps
/// dark pixels from dominating.
pub const REL_MSE_EPSILON: f64 = 0.01;

/// Errors of `test` against `reference`. Fails when the sizes differ or when either image
/// has non-finite pixels (they would make every metric NaN).
pub fn errors(reference: &Image, test: &Image) -> Result<Errors> {
    if (reference.width, reference.height) != (test.width, test.height) {
        bail!("image is {}x{}, the reference is {}x{}", test.width, test.height, reference.width, reference.height);
    }
    ensure!(
        reference.pixels.len() == reference.width as usize * reference.height as usize
            && test.pixels.len() == reference.pixels.len(),
        "image buffers do not hold width x height pixels"
    );
    for (what, img) in [("reference", reference), ("image", test)] {
        let bad = img.non_finite_count();
        ensure!(bad == 0, "the {what} has {bad} non-finite (NaN or infinite) pixels of {}", img.pixels.len());
    }
    let (mut se, mut se_clamped, mut rel) = (0.0f64, 0.0f64, 0.0f64);
    for (r, t) in reference.pixels.iter().flatten().zip(test.pixels.iter().flatten()) {
        let (r, t) = (*r as f64, *t as f64);
        let d = t - r;
        se += d * d;
        let dc = t.clamp(0.0, 1.0) - r.clamp(0.0, 1.0);
        se_clamped += dc * dc;
        rel += d * d / (r * r + REL_MSE_EPSILON);
    }
    let n = (reference.pixels.len() * 3).max(1) as f64;
    Ok(Errors {
        rmse: (se / n).sqrt(),
        rmse_clamped: (se_clamped / n).sqrt(),
        rel_mse: rel / n,
        mean_flip: if reference.pixels.is_empty() { 0.0 } else { mean_flip(reference, test) as f64 },
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A smooth image in [0.3, 0.7].
    pub(crate) fn gradient(w: u32, h: u32) -> Image {
        let mut img = Image::new(w, h);
        for (i, p) in img.pixels.iter_mut().enumerate() {
            let (x, y) = ((i as u32 % w) as f32 / w as f32, (i as u32 / w) as f32 / h as f32);
            *p = [0.3 + 0.4 * x, 0.5, 0.3 + 0.4 * y];
        }
        img
    }

    #[test]
    fn identical_images_have_zero_error() {
        let a = gradient(16, 8);
        let e = errors(&a, &a.clone()).unwrap();
        assert_eq!(e, Errors { rmse: 0.0, rmse_clamped: 0.0, rel_mse: 0.0, mean_flip: 0.0 });
    }

    #[test]
    fn a_constant_offset_gives_the_exact_errors() {
        let mut r = Image::new(4, 4);
        for p in &mut r.pixels {
            *p = [0.5, 0.25, 0.9];
        }
        let mut t = r.clone();
        for p in &mut t.pixels {
            *p = p.map(|c| c + 0.125);
        }
        let e = errors(&r, &t).unwrap();
        assert!((e.rmse - 0.125).abs() < 1e-7, "{e:?}");
        // 0.9 + 0.125 clamps to 1: that channel differs by 0.1 only.
        let clamped = ((2.0 * 0.125f64.powi(2) + 0.1f64.powi(2)) / 3.0).sqrt();
        assert!((e.rmse_clamped - clamped).abs() < 1e-6, "{e:?}");
        let rel = [0.5f64, 0.25, 0.9].iter().map(|r| 0.125f64.powi(2) / (r * r + 0.01)).sum::<f64>() / 3.0;
        assert!((e.rel_mse - rel).abs() < 1e-6, "{e:?}");
        assert!(e.mean_flip > 0.0);
    }

    #[test]
    fn size_mismatch_and_non_finite_pixels_are_errors() {
        let msg = errors(&Image::new(4, 3), &Image::new(3, 4)).unwrap_err().to_string();
        assert!(msg.contains("3x4") && msg.contains("4x3"), "{msg}");
        let mut t = Image::new(4, 3);
        t.pixels[2][1] = f32::NAN;
        t.pixels[5][0] = f32::INFINITY;
        let msg = errors(&Image::new(4, 3), &t).unwrap_err().to_string();
        assert!(msg.contains("2 non-finite"), "{msg}");
        let msg = errors(&t, &Image::new(4, 3)).unwrap_err().to_string();
        assert!(msg.contains("reference has 2"), "{msg}");
    }

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
