//! The denoiser (`strahl-gpu`'s `shaders/denoise.wgsl` is the twin, by the same operations):
//! an edge-avoiding à-trous wavelet filter (Dammertz, Sewtz, Hanika and Lensch 2010,
//! "Edge-Avoiding À-Trous Wavelet Transform for fast Global Illumination Filtering") with the
//! luminance weight scaled by an estimate of the noise, as SVGF does (Schied et al. 2017,
//! "Spatiotemporal Variance-Guided Filtering", §4.3–4.4, with the spatial variance estimate it
//! uses where a pixel has no history, since a still render has none).
//!
//! 1. **Demodulate** ([`prepare`]): the radiance is divided by the albedo guide (plus
//!    [`ALBEDO_EPS`], so that black surfaces divide by something), so that the filter smooths
//!    lighting and leaves texture alone; the luminance variance of each pixel's 3×3
//!    neighbourhood estimates its noise.
//! 2. **Filter** ([`atrous`]) [`ITERATIONS`] times, the taps 2^k pixels apart in pass k
//!    (3×3 taps of the kernel (¼, ½, ¼)², 31 pixels across after four passes). A tap's weight
//!    is the kernel's times exp(−(Δl / (σ_l √var + ε) + |Δn|² / σ_n² + |Δa|² / σ_a²)): Δl the
//!    difference of the demodulated luminance, Δn of the normal guides, Δa of the albedo guides.
//!    The variance is filtered alongside with the squared weights (SVGF eq. 6), so that the
//!    luminance weight tightens as the noise goes.
//! 3. **Remodulate** ([`finish`]): times (albedo + [`ALBEDO_EPS`]).
//!
//! Why this method: it runs in a few milliseconds per pass on any GPU and in the browser, its
//! CPU twin can do the same operations, and it needs only the guides strahl's AOV pass writes
//! ([`crate::render::aov`]). A regression denoiser (NFOR) or a neural one (OIDN) would denoise
//! better at a given sample count; the book's denoising chapter has the measurement.
//!
//! f32 throughout. The GPU's `exp` and `sqrt` may differ from the CPU's by a few ulp, so the
//! two agree to within rounding, not bit for bit (tests/denoise.rs measures the difference in
//! 8-bit codes).

use crate::image::Image;
use rayon::prelude::*;

// The parameters were chosen by the mean FLIP of 16-spp renders denoised against 2048-spp
// references of the seed scene (640x480) and the Cornell box (384x288), over iterations 3-6,
// σ_l 1-10^9, σ_n² 0.002-0.5, σ_a² 0.003-0.2 (the book's denoising chapter has the figures).

/// Filter passes (taps 1, 2, 4, 8 pixels apart: 31 pixels across).
pub const ITERATIONS: u32 = 4;
/// σ_l: how many standard deviations of the (spatially estimated) noise a luminance difference
/// may span and still count. SVGF takes 4 with a per-pixel variance; the spatial estimate is
/// smaller where the image is flat and noisy, and 12 measured best here (8 on the Cornell box,
/// 16 on the seed scene).
pub const SIGMA_L: f32 = 12.0;
/// σ_n²: normal guides this far apart (squared distance; 0.02 is about 8° between unit
/// normals) weigh e^-1 of equal ones.
pub const SIGMA_N2: f32 = 0.02;
/// σ_a²: albedo guides this far apart (squared distance) weigh e^-1 of equal ones.
pub const SIGMA_A2: f32 = 0.003;
/// Added to the albedo before dividing by it and after filtering.
pub const ALBEDO_EPS: f32 = 0.001;
/// Keeps the luminance weight's denominator above 0 where a neighbourhood is flat.
pub const VARIANCE_EPS: f32 = 1e-4;
/// The kernel (¼, ½, ¼), by tap offset −1, 0, 1.
pub const KERNEL: [f32; 3] = [0.25, 0.5, 0.25];

/// What the filter reads besides the image: the albedo and normal guides of its pixels.
pub struct Guides<'a> {
    pub albedo: &'a [[f32; 3]],
    pub normal: &'a [[f32; 3]],
}

/// A pixel during filtering: the demodulated radiance and its luminance variance.
pub type Work = [f32; 4];

#[inline]
fn luminance(c: [f32; 3]) -> f32 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

#[inline]
fn dist2(a: [f32; 3], b: [f32; 3]) -> f32 {
    let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
}

/// The filter's parameters: the shaders' are [`Params::DEFAULT`] (tuning experiments vary them
/// on the CPU).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Params {
    pub iterations: u32,
    pub sigma_l: f32,
    pub sigma_n2: f32,
    pub sigma_a2: f32,
}

impl Params {
    pub const DEFAULT: Params =
        Params { iterations: ITERATIONS, sigma_l: SIGMA_L, sigma_n2: SIGMA_N2, sigma_a2: SIGMA_A2 };
}

/// Denoises `img` with its guides: [`prepare`], [`ITERATIONS`] × [`atrous`], [`finish`].
pub fn denoise(img: &Image, guides: &Guides) -> Image {
    denoise_with(img, guides, &Params::DEFAULT)
}

/// [`denoise`] with other parameters (the shaders take [`Params::DEFAULT`]).
pub fn denoise_with(img: &Image, guides: &Guides, params: &Params) -> Image {
    let (w, h) = (img.width, img.height);
    assert_eq!(guides.albedo.len(), img.pixels.len());
    assert_eq!(guides.normal.len(), img.pixels.len());
    let mut work = prepare(w, h, &img.pixels, guides.albedo);
    for k in 0..params.iterations {
        work = atrous(w, h, &work, guides, 1 << k, params);
    }
    Image { width: w, height: h, pixels: finish(&work, guides.albedo) }
}

/// Step 1: the demodulated radiance of each pixel, and the luminance variance of its 3×3
/// neighbourhood (the pixels inside the image): the spatial estimate SVGF falls back on where a
/// pixel has no history. It counts edges as noise, which only loosens the luminance weight
/// there; the normal and albedo weights still stop the filter at edges.
pub fn prepare(w: u32, h: u32, color: &[[f32; 3]], albedo: &[[f32; 3]]) -> Vec<Work> {
    let demod: Vec<[f32; 3]> = color
        .par_iter()
        .zip(albedo)
        .map(|(c, a)| [c[0] / (a[0] + ALBEDO_EPS), c[1] / (a[1] + ALBEDO_EPS), c[2] / (a[2] + ALBEDO_EPS)])
        .collect();
    let lum: Vec<f32> = demod.iter().map(|&d| luminance(d)).collect();
    let mut out = vec![[0.0f32; 4]; demod.len()];
    out.par_chunks_mut(w as usize).enumerate().for_each(|(y, row)| {
        let y = y as i32;
        for (x, o) in row.iter_mut().enumerate() {
            let x = x as i32;
            let (mut s1, mut s2, mut n) = (0.0f32, 0.0f32, 0.0f32);
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let (qx, qy) = (x + dx, y + dy);
                    if qx < 0 || qy < 0 || qx >= w as i32 || qy >= h as i32 {
                        continue;
                    }
                    let l = lum[qy as usize * w as usize + qx as usize];
                    s1 += l;
                    s2 += l * l;
                    n += 1.0;
                }
            }
            let mean = s1 / n;
            let d = demod[y as usize * w as usize + x as usize];
            *o = [d[0], d[1], d[2], (s2 / n - mean * mean).max(0.0)];
        }
    });
    out
}

/// Step 2: one pass of the filter with its taps `step` pixels apart.
pub fn atrous(w: u32, h: u32, work: &[Work], guides: &Guides, step: i32, params: &Params) -> Vec<Work> {
    let mut out = vec![[0.0f32; 4]; work.len()];
    out.par_chunks_mut(w as usize).enumerate().for_each(|(y, row)| {
        let y = y as i32;
        for (x, o) in row.iter_mut().enumerate() {
            *o = atrous_pixel(w, h, work, guides, (step, params), x as i32, y);
        }
    });
    out
}

/// One pixel of [`atrous`] (`atrous` in `denoise.wgsl`).
#[inline]
fn atrous_pixel(w: u32, h: u32, work: &[Work], guides: &Guides, (step, k): (i32, &Params), x: i32, y: i32) -> Work {
    let p = y as usize * w as usize + x as usize;
    let c = work[p];
    let lp = luminance([c[0], c[1], c[2]]);
    let (np, ap) = (guides.normal[p], guides.albedo[p]);
    let scale = 1.0 / (k.sigma_l * c[3].sqrt() + VARIANCE_EPS);
    let mut sum = [0.0f32; 3];
    let (mut sum_w, mut sum_var) = (0.0f32, 0.0f32);
    for (j, kj) in KERNEL.iter().enumerate() {
        for (i, ki) in KERNEL.iter().enumerate() {
            let (qx, qy) = (x + (i as i32 - 1) * step, y + (j as i32 - 1) * step);
            if qx < 0 || qy < 0 || qx >= w as i32 || qy >= h as i32 {
                continue;
            }
            let q = qy as usize * w as usize + qx as usize;
            let d = work[q];
            let dl = (luminance([d[0], d[1], d[2]]) - lp).abs() * scale;
            let e = dl + dist2(guides.normal[q], np) / k.sigma_n2 + dist2(guides.albedo[q], ap) / k.sigma_a2;
            let wq = ki * kj * (-e).exp();
            sum[0] += wq * d[0];
            sum[1] += wq * d[1];
            sum[2] += wq * d[2];
            sum_w += wq;
            sum_var += wq * wq * d[3];
        }
    }
    // The centre tap's weight is the kernel's alone (e = 0), so sum_w ≥ 1/4.
    [sum[0] / sum_w, sum[1] / sum_w, sum[2] / sum_w, sum_var / (sum_w * sum_w)]
}

/// Step 3: the filtered radiance times the albedo it was divided by.
pub fn finish(work: &[Work], albedo: &[[f32; 3]]) -> Vec<[f32; 3]> {
    work.iter()
        .zip(albedo)
        .map(|(d, a)| [d[0] * (a[0] + ALBEDO_EPS), d[1] * (a[1] + ALBEDO_EPS), d[2] * (a[2] + ALBEDO_EPS)])
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn guides_of(n: usize, albedo: [f32; 3], normal: [f32; 3]) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
        (vec![albedo; n], vec![normal; n])
    }

    #[test]
    fn a_flat_image_stays_what_it_is() {
        let mut img = Image::new(37, 23);
        img.pixels.iter_mut().for_each(|p| *p = [0.3, 0.6, 0.9]);
        let (a, n) = guides_of(img.pixels.len(), [0.5, 0.5, 0.5], [0.0, 0.0, 1.0]);
        let out = denoise(&img, &Guides { albedo: &a, normal: &n });
        for p in &out.pixels {
            for c in 0..3 {
                assert!((p[c] - img.pixels[0][c]).abs() < 1e-5, "{p:?}");
            }
        }
    }

    /// Noise on a flat surface goes; an edge between two surfaces whose normals differ stays.
    #[test]
    fn noise_goes_and_a_normal_edge_stays() {
        let (w, h) = (64u32, 32u32);
        let mut rng = crate::rng::SplitMix64(7);
        let mut img = Image::new(w, h);
        let mut normal = vec![[0.0f32, 0.0, 1.0]; (w * h) as usize];
        for y in 0..h {
            for x in 0..w {
                let i = (y * w + x) as usize;
                let base = if x < w / 2 { 0.2 } else { 0.8 };
                if x >= w / 2 {
                    normal[i] = [1.0, 0.0, 0.0];
                }
                let v = base * (0.5 + rng.unit() as f32);
                img.pixels[i] = [v, v, v];
            }
        }
        let albedo = vec![[1.0f32; 3]; (w * h) as usize];
        let out = denoise(&img, &Guides { albedo: &albedo, normal: &normal });
        let err = |im: &Image, lo: u32, hi: u32, want: f32| {
            let mut e = 0.0f64;
            let mut n = 0;
            for y in 0..h {
                for x in lo..hi {
                    e += (im.get(x, y)[0] as f64 - want as f64).powi(2);
                    n += 1;
                }
            }
            (e / n as f64).sqrt()
        };
        let (before, after) = (err(&img, 0, w / 2, 0.2), err(&out, 0, w / 2, 0.2));
        assert!(after < before / 4.0, "left half: rms error {before} before, {after} after");
        let (before, after) = (err(&img, w / 2, w, 0.8), err(&out, w / 2, w, 0.8));
        assert!(after < before / 4.0, "right half: rms error {before} before, {after} after");
        // The columns at the edge keep their side's level.
        let mean_col = |x: u32| (0..h).map(|y| out.get(x, y)[0]).sum::<f32>() / h as f32;
        assert!((mean_col(w / 2 - 1) - 0.2).abs() < 0.02, "{}", mean_col(w / 2 - 1));
        assert!((mean_col(w / 2) - 0.8).abs() < 0.05, "{}", mean_col(w / 2));
    }

    #[test]
    fn texture_survives_demodulation() {
        // A checkerboard albedo under constant light: the image is the albedo, and the filter
        // leaves it, though the albedo weight alone would let some blur through.
        let (w, h) = (32u32, 32u32);
        let albedo: Vec<[f32; 3]> =
            (0..w * h).map(|i| if ((i % w) / 4 + (i / w) / 4) % 2 == 0 { [0.9; 3] } else { [0.1; 3] }).collect();
        let normal = vec![[0.0f32, 1.0, 0.0]; (w * h) as usize];
        let img = Image { width: w, height: h, pixels: albedo.clone() };
        let out = denoise(&img, &Guides { albedo: &albedo, normal: &normal });
        for (o, a) in out.pixels.iter().zip(&albedo) {
            assert!((o[0] - a[0]).abs() < 1e-4, "{o:?} for albedo {a:?}");
        }
    }
}
