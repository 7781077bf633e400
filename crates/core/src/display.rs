//! View transforms: from scene-referred linear radiance (what the renderers compute and EXR
//! files keep) to the 8-bit sRGB codes of a PNG. `standard` clips each channel at 1 (a bright
//! orange light turns white); the others compress highlights so that colour survives:
//!
//! - **AgX** (Troy Sobotka, 2023; Blender's default since 4.0): an inset of the primaries
//!   towards white, a log2 encoding of [2^-12.47393, 2^4.026069] (middle grey 0.18 at −10 and
//!   +6.5 stops from the ends), a sigmoid, and the inverse inset. The sigmoid is Benjamin
//!   Wrensch's 6th-degree polynomial fit of AgX's base contrast curve ("Minimal AgX
//!   implementation", iolite engine, 2023), whose output is display-encoded: it is written as
//!   the code value, without a further sRGB curve. How far the fit lies from Blender's own
//!   lookup table is not measured here (Blender's OCIO configuration is not installed).
//! - **Khronos PBR Neutral** (Emmett Lalish, Khronos 3D Commerce, 2024,
//!   KhronosGroup/ToneMapping `PBR_Neutral`): base colours up to 0.76 pass unchanged (less
//!   a small offset near black), brighter ones are compressed towards a peak of 1 and
//!   desaturated towards white by 15 % of the compression. The output is display-linear,
//!   then sRGB-encoded.
//! - **ACES** (Stephen Hill's fit of the ACES 1.0 RRT and sRGB ODT, "BakingLab", 2016, which
//!   three.js uses): Hill's input matrix, the rational fit
//!   (x(x + 0.0245786) − 0.000090537) / (x(0.983729x + 0.432951) + 0.238081), his output
//!   matrix; display-linear, then sRGB-encoded.
//!
//! Exposure multiplies the radiance by 2^EV before any of them. Each transform is a few
//! multiply-adds and a log or power per channel in f32, a few ulps from the same formula in
//! f64: far below the 1/255 of an 8-bit code, so only a value within that of a rounding
//! boundary can land one code off.

use crate::image::{Image, code8, linear_to_srgb, save_encoded};
use anyhow::{Context, Result};
use std::path::Path;

/// How linear radiance becomes a displayed colour (`--view`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ViewTransform {
    /// Each channel clipped to [0, 1], then the sRGB curve: what strahl always wrote.
    #[default]
    Standard,
    /// Troy Sobotka's AgX (Blender's default).
    Agx,
    /// Khronos PBR Neutral (for product renders; the glTF sample viewer offers it).
    Neutral,
    /// Stephen Hill's fit of ACES 1.0 (three.js's `ACESFilmicToneMapping`).
    Aces,
}

impl ViewTransform {
    pub const ALL: [ViewTransform; 4] = [Self::Standard, Self::Agx, Self::Neutral, Self::Aces];

    pub fn name(self) -> &'static str {
        match self {
            Self::Standard => "standard",
            Self::Agx => "agx",
            Self::Neutral => "neutral",
            Self::Aces => "aces",
        }
    }

    /// Display-encoded value in [0, 1] per channel of the linear colour `rgb` scaled by
    /// 2^`exposure` (NaN and negative inputs count as 0; values above 1e18, infinity
    /// included, as 1e18, which every transform shows as white and whose square f32 still
    /// holds).
    pub fn encode(self, rgb: [f32; 3], exposure: f32) -> [f32; 3] {
        let scale = exposure.exp2();
        let c = rgb.map(|v| if v > 0.0 { (v * scale).min(1e18) } else { 0.0 });
        match self {
            Self::Standard => c.map(linear_to_srgb),
            Self::Agx => agx(c),
            Self::Neutral => pbr_neutral(c).map(linear_to_srgb),
            Self::Aces => aces_hill(c).map(linear_to_srgb),
        }
    }

    /// The 8-bit code of each channel.
    pub fn encode8(self, rgb: [f32; 3], exposure: f32) -> [u8; 3] {
        self.encode(rgb, exposure).map(code8)
    }
}

impl std::str::FromStr for ViewTransform {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Self::ALL.into_iter().find(|v| v.name().eq_ignore_ascii_case(s)).ok_or_else(|| {
            let names: Vec<_> = Self::ALL.iter().map(|v| v.name()).collect();
            format!("unknown view transform {s:?}: use one of {}", names.join(", "))
        })
    }
}

impl Image {
    /// The image as 8-bit display codes, row-major RGB.
    pub fn to_display8(&self, view: ViewTransform, exposure: f32) -> Vec<u8> {
        self.pixels.iter().flat_map(|&p| view.encode8(p, exposure)).collect()
    }
}

/// Writes `image` as an 8-bit sRGB PNG through `view` at `exposure` stops, atomically.
pub fn save_png(image: &Image, path: &Path, view: ViewTransform, exposure: f32) -> Result<()> {
    let png = ::image::RgbImage::from_raw(image.width, image.height, image.to_display8(view, exposure))
        .context("image buffer size mismatch")?;
    save_encoded(&png, ::image::ImageFormat::Png, path)
}

/// `m` (row-major) times the column vector `v`.
fn mul(m: &[[f32; 3]; 3], v: [f32; 3]) -> [f32; 3] {
    m.map(|r| r[0] * v[0] + r[1] * v[1] + r[2] * v[2])
}

/// AgX's inset: each primary moved towards white (rows sum to 1, so greys stay grey).
const AGX_INSET: [[f32; 3]; 3] = [
    [0.842_479_06, 0.078_433_6, 0.079_223_745],
    [0.042_328_242, 0.878_468_6, 0.079_166_13],
    [0.042_375_655, 0.078_433_6, 0.879_143],
];

/// Its inverse, applied after the sigmoid.
const AGX_OUTSET: [[f32; 3]; 3] = [
    [1.196_879, -0.098_020_88, -0.099_029_74],
    [-0.052_896_85, 1.151_903_1, -0.098_961_18],
    [-0.052_971_635, -0.098_043_45, 1.151_073_7],
];

const AGX_MIN_EV: f32 = -12.473_93;
const AGX_MAX_EV: f32 = 4.026_069;

/// Wrensch's polynomial fit of AgX's base contrast on the normalised log value `x` in [0, 1].
fn agx_contrast(x: f32) -> f32 {
    let x2 = x * x;
    let x4 = x2 * x2;
    15.5 * x4 * x2 - 40.14 * x4 * x + 31.96 * x4 - 6.868 * x2 * x + 0.4298 * x2 + 0.1191 * x - 0.00232
}

fn agx(c: [f32; 3]) -> [f32; 3] {
    let log = mul(&AGX_INSET, c).map(|v| {
        // log2(0) is −∞: the clamp takes it to the bottom of the range.
        let ev = v.max(f32::MIN_POSITIVE).log2().clamp(AGX_MIN_EV, AGX_MAX_EV);
        agx_contrast((ev - AGX_MIN_EV) / (AGX_MAX_EV - AGX_MIN_EV))
    });
    mul(&AGX_OUTSET, log).map(|v| v.clamp(0.0, 1.0))
}

/// Khronos PBR Neutral on a display-linear colour, as its reference GLSL writes it.
fn pbr_neutral(mut c: [f32; 3]) -> [f32; 3] {
    const START_COMPRESSION: f32 = 0.8 - 0.04;
    const DESATURATION: f32 = 0.15;
    let x = c[0].min(c[1]).min(c[2]);
    let offset = if x < 0.08 { x - 6.25 * x * x } else { 0.04 };
    c = c.map(|v| v - offset);
    let peak = c[0].max(c[1]).max(c[2]);
    if peak < START_COMPRESSION {
        return c;
    }
    let d = 1.0 - START_COMPRESSION;
    let new_peak = 1.0 - d * d / (peak + d - START_COMPRESSION);
    c = c.map(|v| v * new_peak / peak);
    let g = 1.0 - 1.0 / (DESATURATION * (peak - new_peak) + 1.0);
    c.map(|v| v + (new_peak - v) * g)
}

const ACES_IN: [[f32; 3]; 3] =
    [[0.597_19, 0.354_58, 0.048_23], [0.076_00, 0.908_34, 0.015_66], [0.028_40, 0.133_83, 0.837_77]];
const ACES_OUT: [[f32; 3]; 3] =
    [[1.604_75, -0.531_08, -0.073_67], [-0.102_08, 1.108_13, -0.006_05], [-0.003_27, -0.072_76, 1.076_02]];

fn aces_hill(c: [f32; 3]) -> [f32; 3] {
    let fit = mul(&ACES_IN, c)
        .map(|v| (v * (v + 0.024_578_6) - 0.000_090_537) / (v * (0.983_729 * v + 0.432_951) + 0.238_081));
    mul(&ACES_OUT, fit).map(|v| v.clamp(0.0, 1.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: [f32; 3], b: [f32; 3], tol: f32) -> bool {
        (0..3).all(|i| (a[i] - b[i]).abs() <= tol)
    }

    #[test]
    fn standard_is_the_clipped_srgb_curve() {
        assert_eq!(ViewTransform::Standard.encode8([0.0, 0.5, 1.0], 0.0), [0, 188, 255]);
        // The orange lamp of radiance (50, 12, 2): white.
        assert_eq!(ViewTransform::Standard.encode8([50.0, 12.0, 2.0], 0.0), [255, 255, 255]);
        // One stop down halves the radiance.
        assert_eq!(
            ViewTransform::Standard.encode8([1.0, 1.0, 1.0], -1.0),
            ViewTransform::Standard.encode8([0.5; 3], 0.0)
        );
    }

    /// AgX's published anchors: the log range puts middle grey (0.18) at the normalised value
    /// 10/16.5, which the contrast curve takes to about 0.5 on the display (Blender shows
    /// 0.18 as code 127); black stays black, and greys stay grey through the inset, whose rows
    /// sum to 1.
    #[test]
    fn agx_takes_middle_grey_to_half_and_keeps_greys_grey() {
        let grey = agx([0.18; 3]);
        assert!(close(grey, [0.4968; 3], 2e-3), "{grey:?}");
        assert!((grey[0] - grey[1]).abs() < 1e-3 && (grey[1] - grey[2]).abs() < 1e-3);
        assert!(agx([0.0; 3]).iter().all(|&v| v < 0.002), "{:?}", agx([0.0; 3]));
        for m in [AGX_INSET, AGX_OUTSET] {
            for r in m {
                assert!((r.iter().sum::<f32>() - 1.0).abs() < 2e-4, "{r:?}");
            }
        }
        // The outset undoes the inset.
        let v = mul(&AGX_OUTSET, mul(&AGX_INSET, [0.3, 0.6, 0.1]));
        assert!(close(v, [0.3, 0.6, 0.1], 1e-4), "{v:?}");
        // The top of the range: 2^4.026 ≈ 16.3 and above reach (nearly) display white.
        assert!(agx([100.0; 3]).iter().all(|&v| v > 0.99), "{:?}", agx([100.0; 3]));
    }

    /// PBR Neutral's stated properties: below the compression start a colour passes unchanged
    /// but for the offset (0.04 when every channel is above 0.08); above it the peak is mapped
    /// to 1 − d²/(peak + d − 0.76) with d = 0.24, and the hue of an orange light survives.
    #[test]
    fn neutral_passes_base_colours_and_compresses_highlights() {
        let c = [0.5, 0.3, 0.1];
        assert!(close(pbr_neutral(c), [0.46, 0.26, 0.06], 1e-6), "{:?}", pbr_neutral(c));
        // Near black the offset is x − 6.25x²: (0.02, 0.5, 0.5) loses 0.0175.
        assert!(close(pbr_neutral([0.02, 0.5, 0.5]), [0.0025, 0.4825, 0.4825], 1e-6));
        // Grey 4: peak 3.96 after the offset, new peak 1 − 0.0576/3.44.
        let g = pbr_neutral([4.0; 3]);
        assert!(close(g, [1.0 - 0.0576 / 3.44; 3], 1e-6), "{g:?}");
        let lamp = ViewTransform::Neutral.encode8([50.0, 12.0, 2.0], 0.0);
        assert!(lamp[0] > lamp[1] && lamp[1] > lamp[2] && lamp[2] < 255, "{lamp:?}");
    }

    /// Hill's fit: black maps to black (the fit's −0.00038 is clipped), middle grey 0.18 to
    /// (0.18 · 0.2045786 − 0.000090537) / (0.18 · 0.6100222 + 0.238081) = 0.10559 display-linear
    /// (ACES's output puts middle grey near 10 % of display white; the matrices' rows sum to 1,
    /// so greys pass them unchanged), and it saturates towards 1.
    #[test]
    fn aces_fit_keeps_its_anchor_points() {
        assert!(aces_hill([0.0; 3]).iter().all(|&v| v == 0.0));
        let grey = aces_hill([0.18; 3]);
        assert!(grey.iter().all(|&v| (v - 0.10559).abs() < 1e-4), "{grey:?}");
        assert!(aces_hill([1e3; 3]).iter().all(|&v| v > 0.98), "{:?}", aces_hill([1e3; 3]));
    }

    /// Every transform is monotonic on greys, stays in [0, 1], turns NaN and negative input
    /// into black and infinite input into white, never into a NaN code.
    #[test]
    fn every_transform_is_monotonic_bounded_and_total() {
        for v in ViewTransform::ALL {
            let mut last = 0.0f32;
            for i in 0..2000 {
                let x = (i as f32 * 0.01 - 10.0).exp2();
                let e = v.encode([x; 3], 0.0)[1];
                assert!((0.0..=1.0).contains(&e), "{v:?} {x}: {e}");
                assert!(e >= last - 1e-6, "{v:?} not monotonic at {x}: {e} < {last}");
                last = e;
            }
            assert_eq!(v.encode8([f32::NAN, -1.0, 0.0], 0.0), v.encode8([0.0; 3], 0.0));
            let white = v.encode([f32::INFINITY, f32::MAX, 1e18], 30.0);
            assert!(white.iter().all(|&e| e > 0.99), "{v:?}: {white:?}");
        }
    }

    #[test]
    fn names_parse_and_unknown_ones_are_refused() {
        for v in ViewTransform::ALL {
            assert_eq!(v.name().parse::<ViewTransform>(), Ok(v));
        }
        let e = "filmic".parse::<ViewTransform>().unwrap_err();
        assert!(e.contains("filmic") && e.contains("agx, neutral"), "{e}");
    }
}
